"""Reading FES recordings (goniometer angle, dynamometer torque, stimulation level) from CSV
files or from the analog channels of a :class:`msk.io.Trial`, and writing result tables.

Units in files are named by the caller (``angle_unit="deg"``, ``stim_unit="us"`` or ``"mA"``)
and converted to SI once, here.  The goniometer gives the knee angle ``θ`` (0 = full
extension); the model uses ``θ_r = θ_rest − θ``.
"""

from __future__ import annotations

import csv
import dataclasses
import os
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from msk.exceptions import FileFormatError, MissingDataError, UnitsError
from msk.fes.protocol import DynamicTrial, IsometricTrial, PendulumTrial
from msk.fes.stimulation import StimKind, Stimulation, stimulation_from_profile
from msk.io.tables import Table

__all__ = [
    "FES_PARAMETER_UNITS",
    "FES_STEP_FIGURES",
    "FesRecording",
    "fes_parameters",
    "fes_step_figures",
    "fes_summary",
    "fes_tables",
    "read_fes_csv",
    "recording_from_trial",
    "write_result_csv",
]

F64 = NDArray[np.float64]
_ANGLE = {"deg": np.pi / 180, "rad": 1.0}
_STIM = {"us": (1e-6, "pw"), "s": (1.0, "pw"), "mA": (1e-3, "current"), "A": (1.0, "current")}


@dataclass(frozen=True)
class FesRecording:
    """One recording in SI: ``time`` s, ``knee_angle`` rad, ``torque`` N·m, stimulation level
    (PW s or current A) sampled on ``time``; absent channels are ``None``."""

    source: str
    time: F64
    knee_angle: F64 | None
    torque: F64 | None
    stim_level: F64 | None
    stim_kind: StimKind
    columns: tuple[str, ...] = ("time", "knee_angle", "torque", "stim_level")

    def _need(self, what: str) -> F64:
        v = getattr(self, what)
        if v is None:
            raise MissingDataError(f"{self.source}: no {what} channel")
        return v

    def stimulation(self, *, frequency_hz: float) -> Stimulation:
        """Pulses at ``frequency_hz`` whose levels sample the recorded stimulation channel."""
        lv = self._need("stim_level")
        return stimulation_from_profile(
            self.time, np.clip(lv, 0, None), frequency_hz=frequency_hz, kind=self.stim_kind
        )

    def theta_r(self, theta_rest: float = np.pi / 2) -> F64:
        return theta_rest - self._need("knee_angle")

    def dynamic_trial(self, *, frequency_hz: float, theta_rest: float = np.pi / 2) -> DynamicTrial:
        t = self.time - self.time[0]
        rec = dataclasses.replace(self, time=t)
        return DynamicTrial(t, self.theta_r(theta_rest), rec.stimulation(frequency_hz=frequency_hz))

    def pendulum_trial(self, *, theta_rest: float = np.pi / 2) -> PendulumTrial:
        return PendulumTrial(self.time - self.time[0], self.theta_r(theta_rest))

    def isometric_trial(self, *, knee_angle: float, frequency_hz: float) -> IsometricTrial:
        """The train at ``knee_angle`` (rad); the zero-level pulses after the train's last
        pulse are dropped so that the steady window ends with the train, not the file."""
        t = self.time - self.time[0]
        rec = dataclasses.replace(self, time=t)
        st = rec.stimulation(frequency_hz=frequency_hz)
        on = np.flatnonzero(st.levels > 0)
        if on.size:
            st = Stimulation(st.pulse_times[: on[-1] + 1], st.levels[: on[-1] + 1], st.kind)
        return IsometricTrial(knee_angle, st, t, self._need("torque"))


def _units(angle_unit: str, stim_unit: str) -> tuple[float, float, StimKind]:
    if angle_unit not in _ANGLE:
        raise UnitsError(f"angle unit {angle_unit!r} is not one of {sorted(_ANGLE)}")
    if stim_unit not in _STIM:
        raise UnitsError(f"stimulation unit {stim_unit!r} is not one of {sorted(_STIM)}")
    s, kind = _STIM[stim_unit]
    return _ANGLE[angle_unit], s, kind  # type: ignore[return-value]


def read_fes_csv(
    path: str | Path,
    *,
    time: str = "time",
    angle: str | None = "knee_angle",
    torque: str | None = "torque",
    stimulation: str | None = "stimulation",
    angle_unit: Literal["deg", "rad"] = "deg",
    stim_unit: Literal["us", "s", "mA", "A"] = "us",
) -> FesRecording:
    """Read a CSV with a header row; columns absent from the file may be set to ``None``.

    Raises :class:`FileFormatError` (naming the file, column and row) for a missing column or a
    non-numeric cell, :class:`UnitsError` for an unknown unit.
    """
    a_s, s_s, kind = _units(angle_unit, stim_unit)
    p = Path(path)
    try:
        with p.open(newline="") as fh:
            rows = list(csv.reader(fh))
    except OSError as e:
        raise FileFormatError(f"{p}: cannot read ({e})") from None
    if len(rows) < 2:
        raise FileFormatError(f"{p}: needs a header row and at least one data row")
    header = [h.strip() for h in rows[0]]
    wanted = {"time": time, "angle": angle, "torque": torque, "stim": stimulation}
    cols: dict[str, F64 | None] = {}
    for key, name in wanted.items():
        if name is None:
            cols[key] = None
            continue
        if name not in header:
            if key == "time":
                raise FileFormatError(f"{p}: no column {name!r} (header: {header})")
            cols[key] = None
            continue
        j = header.index(name)
        vals = np.empty(len(rows) - 1)
        for i, row in enumerate(rows[1:], start=2):
            try:
                vals[i - 2] = float(row[j])
            except (ValueError, IndexError):
                cell = row[j] if j < len(row) else "<missing>"
                raise FileFormatError(
                    f"{p}: row {i}, column {name!r}: bad value {cell!r}"
                ) from None
        cols[key] = vals
    t = cols["time"]
    assert t is not None
    if np.any(np.diff(t) <= 0):
        raise FileFormatError(f"{p}: column {time!r} is not strictly increasing")
    ang = None if cols["angle"] is None else cols["angle"] * a_s
    stim = None if cols["stim"] is None else cols["stim"] * s_s
    return FesRecording(str(p), t, ang, cols["torque"], stim, kind)


def recording_from_trial(
    trial: Any,
    *,
    angle: str | None = None,
    torque: str | None = None,
    stimulation: str | None = None,
    angle_unit: Literal["deg", "rad"] = "deg",
    stim_unit: Literal["us", "s", "mA", "A"] = "us",
) -> FesRecording:
    """Build a recording from the analog channels of a :class:`msk.io.Trial` (``read_c3d``).

    Channels are read with ``trial.analog(label)`` on ``trial.analog_time``; the torque channel
    is taken as N·m (convert upstream if the C3D stores volts).
    """
    a_s, s_s, kind = _units(angle_unit, stim_unit)
    t = np.asarray(trial.analog_time, dtype=float)
    ang = None if angle is None else np.asarray(trial.analog(angle), float) * a_s
    tq = None if torque is None else np.asarray(trial.analog(torque), float)
    st = None if stimulation is None else np.asarray(trial.analog(stimulation), float) * s_s
    return FesRecording(str(getattr(trial, "path", "trial")), t, ang, tq, st, kind)


def write_result_csv(result: Any, path: str | Path) -> Path:
    """Write a result dataclass's named columns (its ``columns`` attribute) atomically."""
    cols = getattr(result, "columns", None)
    if cols is None:
        raise FileFormatError(f"{type(result).__name__} has no named columns to write")
    data = np.column_stack([np.asarray(getattr(result, c), dtype=float) for c in cols])
    p = Path(path)
    fd, tmp = tempfile.mkstemp(dir=p.parent, suffix=".tmp")
    try:
        with os.fdopen(fd, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(cols)
            w.writerows(data.tolist())
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return p


#: Units of the identified FES parameters (``fes_parameters.csv`` columns, SI).
FES_PARAMETER_UNITS: dict[str, str] = {
    "geometry.L_ext": "m",
    "geometry.r_q": "m",
    "knee.J": "kg·m²",
    "knee.B": "N·m·s/rad",
    "knee.K": "N·m/rad",
    "muscle.F_cm": "N",
    "muscle.K_cm": "N/m",
    "muscle.L_c0": "m",
    "muscle.b": "1",
    "muscle.k_s": "N/m",
    "muscle.L_s": "m",
    "recruitment.c1": "1",
    "recruitment.c2": "1",
    "recruitment.c3": "1 (PW/PW_max)",
}


#: Figures per protocol step of ``fes_steps.csv`` (Benoussaad et al. 2013, Table 2 rows).
FES_STEP_FIGURES = ("nrmsd_pct", "nrmse_pct")


def fes_parameters(res: Any) -> dict[str, float]:
    """The identified parameters of a :class:`msk.fes.protocol.ProtocolResult` by name
    (:data:`FES_PARAMETER_UNITS`), SI."""
    subj = res.subject
    return {
        name: float(getattr(getattr(subj, name.split(".")[0]), name.split(".")[1]))
        for name in FES_PARAMETER_UNITS
    }


def fes_step_figures(res: Any) -> dict[str, dict[str, float]]:
    """NRMSD and NRMSE (%) of every protocol step of a :class:`msk.fes.protocol.ProtocolResult`."""
    steps = {
        "static_torque": res.static,
        "joint_mechanics": res.pendulum,
        "force_length": res.force_length,
        "recruitment": res.recruitment,
        "nlp_ks": res.series_stiffness,
        "cross_validation_initial": res.cross_validation_initial,
        "cross_validation": res.cross_validation,
    }
    return {k: {"nrmsd_pct": float(v.nrmsd), "nrmse_pct": float(v.nrmse)} for k, v in steps.items()}


def fes_tables(res: Any) -> dict[str, Table]:
    """``fes_parameters`` and ``fes_steps`` (one row, ``time`` = 0: the start of the data they
    were identified from) and ``fes_validation`` (a time series: measured and simulated knee
    angle of the cross-validation trial, rad)."""
    par = fes_parameters(res)
    steps = fes_step_figures(res)
    cols = tuple(f"{k}.{f}" for k in steps for f in FES_STEP_FIGURES)
    vals = [steps[k][f] for k in steps for f in FES_STEP_FIGURES]
    cv, cv0 = res.cross_validation, res.cross_validation_initial
    rest = res.subject.knee.theta_rest
    t0 = np.zeros(1)
    return {
        "fes_parameters": Table(t0, np.array([list(par.values())]), tuple(par), "fes_parameters"),
        "fes_steps": Table(t0, np.array([vals]), cols, "fes_steps"),
        "fes_validation": Table(
            np.asarray(cv.time, dtype=float),
            np.column_stack([rest - cv.theta_r, rest - cv.theta_r_sim, rest - cv0.theta_r_sim]),
            ("knee_angle_measured", "knee_angle_simulated", "knee_angle_simulated_k_s0"),
            "fes_validation",
        ),
    }


def fes_summary(res: Any, options: Any, trials: Sequence[Any]) -> dict[str, Any]:
    """``summary.fes`` of the FES protocol's result (:func:`fes_parameters`): the
    estimated parameters with their units, the initial values, each step's fit
    (:func:`fes_step_figures`), the series-stiffness iterations, the solver status, seconds per
    pass, the ``trials`` (name, protocol step, file) and the ``[fes]`` ``options``."""
    par = fes_parameters(res)
    return {
        "parameters": {k: {"value": v, "unit": FES_PARAMETER_UNITS[k]} for k, v in par.items()},
        "initial_parameters": {
            k: float(getattr(getattr(res.subject_initial, k.split(".")[0]), k.split(".")[1]))
            for k in FES_PARAMETER_UNITS
        },
        "steps": fes_step_figures(res),
        "k_s_history_n_per_m": list(res.k_s_history),
        "solver_status": res.series_stiffness.solver_status,
        "seconds": dict(res.seconds),
        "trials": [{"name": tc.name, "step": tc.fes.step, "file": str(tc.file)} for tc in trials],
        "options": dataclasses.asdict(options),
    }
