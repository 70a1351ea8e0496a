"""Normative bands: the documented file format round-trips; bands from pooled cycles."""

from __future__ import annotations

import numpy as np
import pytest

from msk.exceptions import FileFormatError
from msk.gait.cycles import GaitCycles, SideCycles
from msk.gait.norms import NormativeBands, bands_from_cycles, read_norms, write_norms


def _bands() -> NormativeBands:
    p = np.linspace(0, 100, 101)
    mean = np.column_stack([np.sin(p / 16), np.cos(p / 20)])
    return NormativeBands(("knee_flexion_deg", "hip_flexion_deg"), mean, 0.1 + 0 * mean,
                          "test adults (n = 2)", "synthetic", "CC0-1.0",
                          {"n_subjects": "2"})  # fmt: skip


def test_file_round_trip(tmp_path):
    b = _bands()
    path = write_norms(tmp_path / "bands.csv", b)
    text = path.read_text()
    assert text.startswith("# population: test adults (n = 2)\n# source: synthetic\n")
    assert "variable,percent_cycle,mean,sd\nknee_flexion_deg,0," in text
    r = read_norms(path)
    assert r.variables == b.variables and r.licence == "CC0-1.0"
    assert r.notes == {"n_subjects": "2"}
    assert np.allclose(r.mean, b.mean, rtol=1e-5) and np.allclose(r.sd, b.sd)
    m, s = r.band("hip_flexion_deg")
    assert m.shape == (101,) and np.allclose(s, 0.1)


def test_bad_files_are_refused(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("# population: x\n# source: y\nvariable,percent_cycle,mean,sd\n")
    with pytest.raises(FileFormatError, match="licence"):
        read_norms(p)
    p.write_text("# population: x\n# source: y\n# licence: z\nvariable,percent_cycle,mean,sd\n"
                 "knee_flexion_deg,0,1,1\n")  # fmt: skip
    with pytest.raises(FileFormatError, match="percent_cycle 1"):
        read_norms(p)


def test_bands_from_cycles_pool_sides_and_sessions():
    rng = np.random.default_rng(2)

    def session(n: int) -> GaitCycles:
        def side(s: str) -> SideCycles:
            v = 10.0 + rng.normal(size=(n, 101, 1))
            return SideCycles(s, v, np.arange(n) * 1.0, np.arange(n) + 1.0, np.full(n, 60.0),
                              np.ones(n, bool))  # fmt: skip

        return GaitCycles(("knee_flexion_deg",), side("left"), side("right"))

    sessions = [session(3), session(4)]
    b = bands_from_cycles(sessions, population="p", source="s", licence="l")
    allv = np.concatenate([c.side(s).values for c in sessions for s in ("left", "right")])
    assert allv.shape[0] == 14 and b.notes["n_cycles"] == "14"
    assert np.allclose(b.mean[:, 0], allv[:, :, 0].mean(axis=0))
    assert np.allclose(b.sd[:, 0], allv[:, :, 0].std(axis=0, ddof=1))


def _session_folder(root, name, n, offset):
    from msk.results.folder import SessionResults, write_session

    rng = np.random.default_rng(n)

    def side(s):
        v = offset + rng.normal(size=(n, 101, 1))
        start = np.arange(n) * 1.1
        return SideCycles(s, v, start, start + 1.1, np.full(n, 60.0), np.ones(n, bool))

    cycles = GaitCycles(("knee_flexion_deg",), side("left"), side("right"))
    summary = {
        "session": name, "created_utc": "2026-12-07T00:00:00Z", "versions": {},
        "config": {"path": "x.toml", "sha256": "0"}, "inputs": [], "settings": {},
        "subject": {"name": name}, "quality": {}, "trial": "walk",
    }  # fmt: skip
    write_session(root / name, SessionResults(cycles.to_tables(), summary))
    return cycles


def test_msk_norms_builds_bands_from_a_batch_folder(tmp_path, capsys):
    from msk.cli import main

    a = _session_folder(tmp_path / "batch", "control1", 3, 10.0)
    b = _session_folder(tmp_path / "batch", "control2", 2, 20.0)
    _session_folder(tmp_path / "batch", "patient", 4, 50.0)
    out = tmp_path / "bands.csv"
    argv = ["norms", str(tmp_path / "batch"), "--out", str(out), "--session", "control1",
            "--session", "control2", "--licence", "CC-BY-4.0"]  # fmt: skip
    assert main(argv) == 0
    assert "10 cycles of 2 sessions (control1, control2)" in capsys.readouterr().err
    bands = read_norms(out)
    assert bands.licence == "CC-BY-4.0" and "n = 2: control1, control2" in bands.population
    allv = np.concatenate([c.side(s).values for c in (a, b) for s in ("left", "right")])
    assert np.allclose(bands.mean[:, 0], allv[:, :, 0].mean(axis=0), rtol=1e-5)
    assert main(["norms", str(tmp_path / "batch"), "--out", str(out), "--session", "x"]) == 2
    assert "no session folder 'x'" in capsys.readouterr().err


def test_task_trial_folders_are_read_and_pooled(tmp_path):
    from msk.results.folder import pooled_gait, read_task_trials

    a = _session_folder(tmp_path / "session", "walk1", 2, 10.0)
    b = _session_folder(tmp_path / "session", "walk2", 3, 12.0)
    trials = read_task_trials(tmp_path / "session")
    assert [t.summary.session for t in trials] == ["walk1", "walk2"]
    cycles, strides = pooled_gait(trials)
    assert strides is None and cycles is not None
    assert cycles.left.n_cycles == 5
    allv = np.concatenate([a.left.values, b.left.values])
    assert np.allclose(cycles.mean("left"), allv.mean(axis=0))
    assert len(read_task_trials(tmp_path / "session" / "walk1")) == 1


def test_shipped_bands_read_with_their_licence_and_gait_variables():
    from msk.gait.norms import shipped_norms
    from msk.gait.variables import KINEMATICS, KINETICS

    files = shipped_norms()
    assert "opensim_examples_2_adults" in files
    for path in files.values():
        b = read_norms(path)
        assert b.licence.startswith("Apache-2.0") and "illustrative" in b.population
        assert set(b.variables) <= set(KINEMATICS + KINETICS)
        assert np.isfinite(b.mean).all() and (b.sd >= 0).all()
        knee, _ = b.band("knee_flexion_deg")
        assert 50.0 < knee[55:80].max() < 75.0  # swing-phase knee flexion of healthy walking
