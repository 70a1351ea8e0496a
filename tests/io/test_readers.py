"""msk.io.read_trial: one reader per suffix, unknown suffixes named with the known ones."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from msk.exceptions import FileFormatError, MskError
from msk.io import (
    TrialReader,
    read_c3d,
    read_trc_trial,
    read_trial,
    register_trial_reader,
    trial_suffixes,
    write_trc,
)
from msk.io.readers import TRIAL_READERS
from msk.trial import Trial


def test_c3d_and_trc_go_to_their_readers(synth, tmp_path):
    path, _ = synth()
    tr = read_trial(path)
    ref = read_c3d(path)
    assert isinstance(tr, Trial) and tr.marker_labels == ref.marker_labels
    np.testing.assert_array_equal(tr.markers, ref.markers)
    assert len(tr.plates) == len(ref.plates) == 1
    upper = tmp_path / "UPPER.C3D"
    shutil.copy(path, upper)
    np.testing.assert_array_equal(read_trial(upper).markers, ref.markers)

    x = np.random.default_rng(2).uniform(-1, 1, size=(5, 2, 3))
    trc = write_trc(tmp_path / "m.trc", time=np.arange(5) / 50.0, markers=x, labels=["A", "B"])
    t = read_trial(trc)
    np.testing.assert_array_equal(t.markers, read_trc_trial(trc).markers)
    np.testing.assert_array_equal(t.up, [0.0, 1.0, 0.0])


def test_unknown_suffix_names_the_file_and_the_known_suffixes(tmp_path):
    assert {".c3d", ".trc"} <= set(trial_suffixes())
    for name in ("walk.mot", "walk"):
        with pytest.raises(FileFormatError) as err:
            read_trial(tmp_path / name)
        msg = str(err.value)
        assert name in msg and ".c3d" in msg and ".trc" in msg
        assert isinstance(err.value, MskError)


def test_a_registered_reader_is_used(tmp_path, synth, monkeypatch):
    path, _ = synth()
    monkeypatch.setattr("msk.io.readers.TRIAL_READERS", dict(TRIAL_READERS))
    register_trial_reader(TrialReader(".XC3D", read_c3d, "a C3D under another name"))
    other = tmp_path / "t.xc3d"
    shutil.copy(path, other)
    assert ".xc3d" in trial_suffixes()
    np.testing.assert_array_equal(read_trial(other).markers, read_c3d(path).markers)
    with pytest.raises(FileFormatError, match="suffix"):
        register_trial_reader(TrialReader("c3d", read_c3d))
