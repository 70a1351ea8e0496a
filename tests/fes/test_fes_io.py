"""msk.fes.io: CSV and C3D-analog inputs, result tables."""

from __future__ import annotations

import csv
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from msk.exceptions import FileFormatError, MissingDataError, UnitsError
from msk.fes.identify import cross_validate
from msk.fes.io import read_fes_csv, recording_from_trial, write_result_csv
from msk.fes.model import SEED001_SUBJECT, TABLE3
from msk.fes.protocol import identification_profile
from msk.fes.simulate import simulate
from msk.fes.stimulation import sample_on_grid


def _write(path: Path, header: list[str], rows: np.ndarray) -> None:
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows.tolist())


def test_csv_dynamic_round_trip(tmp_path: Path) -> None:
    """A simulated goniometer + PW channel written in lab units reads back to the same trial."""
    s = TABLE3["S3L"]
    st = identification_profile()
    tr = simulate(s, st, duration=4.0)
    t = tr.time[::5]
    w = sample_on_grid(st, tr.time.size, 2e-3, 0.03, 0.02)
    pw_us = w[0, ::5] * 1e6
    knee_deg = np.rad2deg(tr.knee_angle[::5])
    f = tmp_path / "dyn.csv"
    _write(f, ["time", "knee_angle", "stimulation"], np.column_stack([t, knee_deg, pw_us]))
    rec = read_fes_csv(f, torque=None)
    assert rec.torque is None and rec.stim_kind == "pw"
    trial = rec.dynamic_trial(frequency_hz=20.0)
    assert trial.theta_r == pytest.approx(tr.theta_r[::5], abs=1e-9)
    # the reconstructed pulse train drives the model to the same motion
    cv = cross_validate(trial.time, trial.theta_r, trial.stim, s)
    assert cv.nrmsd < 0.5


def test_csv_errors_name_file_row_and_column(tmp_path: Path) -> None:
    f = tmp_path / "bad.csv"
    f.write_text("time,torque\n0.0,1.0\n0.1,abc\n")
    with pytest.raises(FileFormatError, match=r"bad\.csv: row 3, column 'torque'"):
        read_fes_csv(f)
    g = tmp_path / "notime.csv"
    g.write_text("t,torque\n0.0,1.0\n")
    with pytest.raises(FileFormatError, match="no column 'time'"):
        read_fes_csv(g)
    with pytest.raises(UnitsError):
        read_fes_csv(f, angle_unit="grad")  # type: ignore[arg-type]
    ok = tmp_path / "ok.csv"
    ok.write_text("time,torque\n0.0,1.0\n0.1,2.0\n")
    rec = read_fes_csv(ok)
    with pytest.raises(MissingDataError, match="knee_angle"):
        rec.theta_r()


def test_recording_from_trial_analogs() -> None:
    t = np.arange(0, 1, 0.001)
    labels = ("Goniometer", "Torque", "Stim")
    data = np.column_stack([np.full_like(t, 60.0), 2.0 * t, np.where(t > 0.5, 2.0, 0.0)])
    trial = SimpleNamespace(
        path="x.c3d",
        analog_time=t,
        analog=lambda label: data[:, labels.index(label)],
    )
    rec = recording_from_trial(
        trial, angle="Goniometer", torque="Torque", stimulation="Stim", stim_unit="mA"
    )
    assert rec.stim_kind == "current"
    assert rec.knee_angle == pytest.approx(np.deg2rad(60.0))
    st = rec.stimulation(frequency_hz=31.25)
    assert st.levels.max() == pytest.approx(2e-3)


def test_write_result_csv_atomic(tmp_path: Path) -> None:
    s = TABLE3["S3L"]
    st = identification_profile()
    tr = simulate(s, st, duration=1.0)
    cv = cross_validate(tr.time, tr.theta_r, st, s)
    out = write_result_csv(cv, tmp_path / "cv.csv")
    rows = list(csv.reader(out.open()))
    assert rows[0] == ["time", "theta_r", "theta_r_sim"]
    assert len(rows) == tr.time.size + 1
    assert not list(tmp_path.glob("*.tmp"))


def test_recording_from_a_real_c3d_file(tmp_path: Path) -> None:
    """Round trip through ``msk.io.write_c3d``/``read_c3d``."""
    import msk.io as io

    s = SEED001_SUBJECT
    st = identification_profile(kind="current", level_max=3e-3, frequency_hz=31.25)
    tr = simulate(s, st, duration=4.0)
    n_frames = 400  # 100 Hz points, analogs at 500 Hz (ratio 5) = the 2 ms simulation grid
    w = sample_on_grid(st, 5 * n_frames, 2e-3, s.calcium.tau_c, s.calcium.tau_r)
    analogs = np.column_stack([np.rad2deg(tr.knee_angle[: 5 * n_frames]), w[0] * 1e3])
    path = io.write_c3d(
        tmp_path / "fes.c3d",
        markers=np.zeros((n_frames, 1, 3)),
        marker_labels=["DUMMY"],
        rate_hz=100.0,
        analogs=analogs,
        analog_labels=["GONIO", "STIM"],
        analog_units=["V", "V"],
        analog_ratio=5,
    )
    trial = io.read_c3d(path)
    rec = recording_from_trial(trial, angle="GONIO", stimulation="STIM", stim_unit="mA")
    dyn = rec.dynamic_trial(frequency_hz=31.25)
    cv = cross_validate(dyn.time, dyn.theta_r, dyn.stim, s)
    assert cv.nrmsd < 1.0


def test_isometric_train_ends_with_its_last_pulse(tmp_path: Path) -> None:
    """A dynamometer file with rest after the train: the steady window is the train's end."""
    t = np.arange(0.0, 6.0, 0.002)
    on = (t >= 0.5) & (t < 4.5)
    torque = np.where(on, 20.0, 0.0)
    _write(tmp_path / "iso.csv", ["time", "torque", "pw"], np.column_stack([t, torque, 300 * on]))
    rec = read_fes_csv(tmp_path / "iso.csv", angle=None, stimulation="pw")
    tr = rec.isometric_trial(knee_angle=np.deg2rad(60), frequency_hz=20.0)
    assert tr.stim.end_time == pytest.approx(4.45)
    assert tr.level == pytest.approx(300e-6)
    assert tr.steady_torque() == pytest.approx(20.0)
