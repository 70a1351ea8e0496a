"""C3D pre-validation (issue 18): what would crash ezc3d or give silently corrupt values is
refused with one line naming the parameter, channel or label and the value."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from msk.exceptions import C3DError, ForcePlateError, MskError
from msk.io import read_c3d
from tests.support.c3d_mutants import label_width, retype, set_dim, set_text, set_value

MSK = [sys.executable, "-c", "import sys; from msk.cli import main; sys.exit(main())"]
PS = "knee-grand-challenge-gc5/PS_ngait_og_ss1.c3d"
GAIT = "btkdata/Gait.c3d"  # DEC floats, six repeated marker labels


def _mutant(real_dir: Path, tmp_path: Path, name: str, edit) -> Path:
    data = bytearray((real_dir / name).read_bytes())
    edit(data)
    out = tmp_path / "mutant.c3d"
    out.write_bytes(bytes(data))
    return out


SCALARS = [
    ("POINT", "RATE"),
    ("POINT", "USED"),
    ("ANALOG", "RATE"),
    ("ANALOG", "GEN_SCALE"),
    ("FORCE_PLATFORM", "USED"),
    ("ANALOG", "USED"),
    ("POINT", "DATA_START"),
    ("EVENT", "USED"),
]


@pytest.mark.parametrize("key", SCALARS, ids=":".join)
@pytest.mark.parametrize("name", [PS, GAIT])
def test_numeric_parameter_stored_as_text_is_refused(real_dir, tmp_path, name, key):
    """ezc3d segfaults on these (exit 139): they never reach it."""
    try:
        f = _mutant(real_dir, tmp_path, name, lambda d: retype(d, key, -1))
    except KeyError:
        pytest.skip(f"{name} has no {key}")
    # (where the shorter char record leaves a stray description length: a corrupt record)
    with pytest.raises(
        C3DError, match=f"{key[0]}:{key[1]} is stored as text|corrupt parameter '{key[1]}'"
    ):
        read_c3d(f)


def test_text_parameter_stored_as_numbers_is_refused(real_dir, tmp_path):
    f = _mutant(real_dir, tmp_path, PS, lambda d: retype(d, ("POINT", "LABELS"), 1))
    with pytest.raises(C3DError, match="POINT:LABELS is stored as numbers"):
        read_c3d(f)


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        (("ANALOG", "RATE"), 1000.0, r"ANALOG:RATE = 1000 Hz disagrees with the header"),
        (("POINT", "RATE"), 119.88, r"POINT:RATE = 119.88 Hz disagrees"),
        (("POINT", "RATE"), 0.0, r"POINT:RATE = 0 Hz is not positive"),
        (("POINT", "RATE"), float("nan"), r"POINT:RATE\[0\] is nan"),
        (("POINT", "USED"), 60, r"POINT:USED = 60 but the header declares 51"),
        (("ANALOG", "USED"), 40, r"ANALOG:USED = 40 channels"),
        (("ANALOG", "GEN_SCALE"), 0.0, "GEN_SCALE is 0"),
        (("FORCE_PLATFORM", "CORNERS"), float("inf"), r"CORNERS\[0\] is inf"),
        (("ANALOG", "SCALE"), 1e6, r"force platform 1 reads F. = .* beyond 20000 N"),
        (("EVENT", "TIMES"), float("nan"), r"TIMES\[0\] is nan"),
    ],
)
def test_inconsistent_values_are_refused(real_dir, tmp_path, key, value, message):
    f = _mutant(real_dir, tmp_path, PS, lambda d: set_value(d, key, value))
    with pytest.raises(MskError, match=message) as exc:
        read_c3d(f)
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize(
    ("key", "k", "value"),
    [
        (("FORCE_PLATFORM", "CORNERS"), 1, 3),
        (("FORCE_PLATFORM", "ORIGIN"), 0, 2),
    ],
)
def test_plate_parameter_shapes_that_do_not_divide(real_dir, tmp_path, key, k, value):
    f = _mutant(real_dir, tmp_path, PS, lambda d: set_dim(d, key, k, value))
    with pytest.raises(MskError, match=f"{key[1]} holds|corrupt parameter '{key[1]}'"):
        read_c3d(f)


def test_rescaled_markers_beyond_100_m_are_refused(real_dir, tmp_path):
    # an integer-stored file: POINT:SCALE multiplies every coordinate
    f = _mutant(
        real_dir, tmp_path, "btkdata/Eb015pi.c3d", lambda d: set_value(d, ("POINT", "SCALE"), 1e4)
    )
    with pytest.raises(C3DError, match=r"marker '\w+' has [XYZ] = .* beyond 100 m"):
        read_c3d(f)


def test_control_characters_in_a_label(real_dir, tmp_path):
    f = _mutant(real_dir, tmp_path, PS, lambda d: set_text(d, ("POINT", "LABELS"), 1, b"\x07"))
    with pytest.raises(C3DError, match=r"POINT:LABELS\[1\] = 'S\\x07ernum"):
        read_c3d(f)


def test_repeated_labels_keep_the_first_and_warn(real_dir, tmp_path):
    tr = read_c3d(real_dir / GAIT)  # the real file has six repeated labels: it still loads
    assert len(set(tr.marker_labels)) == len(tr.marker_labels) == 33
    assert tr.marker_labels.index("RKNE") < tr.marker_labels.index("RKNE#2")
    assert any("repeated labels RKNE" in w for w in tr.metadata["warnings"])

    def dup(d):
        w = label_width(bytes(d), ("POINT", "LABELS"))
        set_text(d, ("POINT", "LABELS"), w, b"Sternum".ljust(w))

    tr = read_c3d(_mutant(real_dir, tmp_path, PS, dup))
    assert tr.marker_labels[:2] == ("Sternum", "Sternum#2")
    ref = read_c3d(real_dir / PS)
    np.testing.assert_array_equal(tr.marker("Sternum"), ref.marker("Sternum"))


def test_nan_plate_samples_are_a_warning(real_dir):
    tr = read_c3d(real_dir / "biobuddy" / "anat_pose_ECH.c3d")
    assert any("51 of 17500 samples are NaN" in w for w in tr.metadata["warnings"])


def test_msk_info_exits_2_on_a_retyped_rate(real_dir, tmp_path):
    f = _mutant(real_dir, tmp_path, PS, lambda d: retype(d, ("POINT", "RATE"), -1))
    r = subprocess.run(
        [*MSK, "info", str(f)],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "PYTHONIOENCODING": "ascii"},
    )
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and "POINT:RATE is stored as text" in r.stderr


# --- isolation: a native crash or a hang of the reader costs one file, one line ----------------
def test_isolated_read_matches_the_in_process_read(real_dir):
    a = read_c3d(real_dir / GAIT, isolate=True)
    b = read_c3d(real_dir / GAIT)
    np.testing.assert_array_equal(a.markers, b.markers)
    assert a.marker_labels == b.marker_labels and a.metadata == b.metadata


def test_isolated_read_carries_the_typed_error(real_dir, tmp_path):
    f = _mutant(real_dir, tmp_path, PS, lambda d: set_value(d, ("ANALOG", "SCALE"), 1e6))
    with pytest.raises(ForcePlateError, match="beyond 20000 N"):
        read_c3d(f, isolate=True)


def test_a_crashing_or_hanging_reader_is_one_c3d_error(real_dir):
    from msk.io.c3d import _read_isolated
    from tests.support.c3d_mutants import crashing_reader, hanging_reader

    with pytest.raises(C3DError, match=r"crashed \(SIGSEGV\)"):
        _read_isolated(real_dir / PS, 20.0, 60.0, target=crashing_reader)
    with pytest.raises(C3DError, match=r"did not finish in 1 s"):
        _read_isolated(real_dir / PS, 20.0, 1.0, target=hanging_reader)
