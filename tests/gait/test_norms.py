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


def _session_folder(root, name, n, offset, gait=None):
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
        **({"gait": gait} if gait else {}),
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
        # the spatiotemporal rows, of walking adults
        speed = b.scalar("walking_speed_m_s")
        assert speed is not None and 0.9 < speed[0] < 1.6 and speed[1] > 0
        assert {"cadence_steps_per_min", "stance_pct", "step_width_m"} <= set(b.scalars)
        # the pelvis tilt in Plug-in Gait's frame: the two subjects' markers' ASIS–sacrum line
        # tilts −0.4° / −0.5° (ORIGIN.md); the model body frame's gave ≈ −8°
        tilt, _ = b.band("pelvis_tilt_deg")
        assert -4.0 < float(np.mean(tilt)) < 1.0
        knee, _ = b.band("knee_flexion_deg")
        assert 50.0 < knee[55:80].max() < 75.0  # swing-phase knee flexion of healthy walking


def test_scalar_rows_round_trip_and_are_refused_when_ambiguous(tmp_path):
    """Scalar (spatiotemporal) rows: percent_cycle empty; round-trip with the curves; a
    variable given both ways, or a scalar twice, is refused naming the line."""
    b = NormativeBands(*(getattr(_bands(), f) for f in ("variables", "mean", "sd")),
                       "p", "s", "l", scalars={"walking_speed_m_s": (1.32, 0.14),
                                               "step_width_m": (0.11, float("nan"))})  # fmt: skip
    path = write_norms(tmp_path / "b.csv", b)
    assert "\nwalking_speed_m_s,,1.32,0.14\n" in path.read_text()
    r = read_norms(path)
    assert r.scalar("walking_speed_m_s") == pytest.approx((1.32, 0.14))
    assert np.isnan(r.scalar("step_width_m")[1]) and r.scalar("cadence_steps_per_min") is None
    assert r.variables == b.variables
    only = tmp_path / "only.csv"
    only.write_text("# population: x\n# source: y\n# licence: z\nvariable,percent_cycle,mean,sd\n"
                    "cadence_steps_per_min,,110,8\n")  # fmt: skip
    assert read_norms(only).scalars == {"cadence_steps_per_min": (110.0, 8.0)}
    bad = only.read_text() + "cadence_steps_per_min,,111,8\n"
    only.write_text(bad)
    with pytest.raises(FileFormatError, match=r"line 6.*twice"):
        read_norms(only)
    text = path.read_text() + "knee_flexion_deg,,1,1\n"
    path.write_text(text)
    with pytest.raises(FileFormatError, match="both a curve"):
        read_norms(path)


def _strides(speeds_l, speeds_r):
    from msk.gait.spatiotemporal import PARAMETERS, SideSpatiotemporal, Spatiotemporal

    def side(s, v):
        vals = np.full((len(v), len(PARAMETERS)), np.nan)
        vals[:, PARAMETERS.index("walking_speed_m_s")] = v
        vals[:, PARAMETERS.index("cadence_steps_per_min")] = 100.0 + 10.0 * np.asarray(v)
        return SideSpatiotemporal(s, np.arange(len(v), dtype=float), vals)

    return Spatiotemporal(side("left", speeds_l), side("right", speeds_r))


def test_scalar_norms_are_the_spread_between_sessions():
    """Per session the mean over its strides (both sides), then mean and SD (n − 1) over the
    sessions: sessions at 1.0, 1.2 and 1.4 m/s (each with stride-to-stride scatter) give
    1.2 ± 0.2; one session gives no SD; a parameter no stride has is left out."""
    from msk.gait.norms import scalar_norms

    s = [_strides([0.9, 1.1], [1.0]), _strides([1.2], [1.15, 1.25]), _strides([1.4], [1.4])]
    got = scalar_norms(s)
    assert got["walking_speed_m_s"] == pytest.approx((1.2, 0.2))
    assert got["cadence_steps_per_min"] == pytest.approx((112.0, 2.0))
    assert "step_width_m" not in got
    one = scalar_norms(s[:1])
    assert one["walking_speed_m_s"][0] == pytest.approx(1.0) and np.isnan(
        one["walking_speed_m_s"][1]
    )


def test_msk_norms_writes_the_spatiotemporal_rows(tmp_path, capsys):
    """``msk norms`` on a batch whose sessions have strides: the scalar rows are the spread of
    the session means (two controls at 1.0 and 1.4 m/s: 1.2 ± 0.283)."""
    from msk.cli import main

    for name, v in (("c1", 1.0), ("c2", 1.4)):
        st = _strides([v, v], [v])
        gait = {"spatiotemporal": st.to_summary(), "heel_source": "model"}
        _session_folder(tmp_path / "batch", name, 2, 10.0, gait=gait)
    out = tmp_path / "bands.csv"
    assert main(["norms", str(tmp_path / "batch"), "--out", str(out)]) == 0
    b = read_norms(out)
    assert b.scalar("walking_speed_m_s") == pytest.approx((1.2, 0.4 / np.sqrt(2)), rel=1e-5)
    assert b.notes["n_sessions_spatiotemporal"] == "2"
