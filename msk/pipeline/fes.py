"""Stage ``fes``: the FES-driven knee model identification protocol on the ``role = "fes"``
trials (:func:`msk.fes.protocol.run_protocol`; Benoussaad et al. 2013, §2.3), its tables and its
``summary.json`` section. Trials are read with :func:`msk.fes.io.read_fes_csv` (CSV) or
:func:`msk.fes.io.recording_from_trial` (C3D analogs). A session may hold only FES trials: the
gait stages are then ``not requested``."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from msk.config import FesTrialConfig, SessionConfig, TrialConfig
from msk.exceptions import ConfigError, MissingDataError
from msk.io.tables import Table
from msk.pipeline.inputs import SessionInputs

__all__ = [
    "FES_PARAMETER_UNITS",
    "FES_STEP_FIGURES",
    "FesResult",
    "fes_recording",
    "fes_session",
    "fes_summary",
    "fes_tables",
    "requested",
    "run",
    "settings",
]


@dataclass(frozen=True)
class FesResult:
    """The :class:`msk.fes.protocol.ProtocolResult` of the session."""

    result: Any


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


def fes_recording(tc: Any) -> Any:
    """One FES trial file as a :class:`msk.fes.io.FesRecording` (SI)."""
    from msk.fes.io import read_fes_csv, recording_from_trial

    f = tc.fes
    chans = {
        "angle": f.angle_channel,
        "torque": f.torque_channel,
        "stimulation": f.stimulation_channel,
        "angle_unit": f.angle_unit,
        "stim_unit": f.stimulation_unit,
    }
    if tc.file.suffix.lower() == ".c3d":
        from msk.io import read_c3d

        trial = read_c3d(tc.file)
        have = set(trial.analog_labels)
        for k in ("angle", "torque", "stimulation"):
            if chans[k] not in have:
                chans[k] = None
        return recording_from_trial(trial, **chans)
    return read_fes_csv(tc.file, time=f.time_column, **chans)


def fes_session(cfg: SessionConfig, trials: Sequence[Any]) -> Any:
    """The :class:`msk.fes.protocol.FesSession` of the ``role = "fes"`` trials."""
    from msk.fes.protocol import FesSession, StaticTrial

    opt = cfg.fes
    rest = np.deg2rad(opt.theta_rest_deg)
    by_step: dict[str, list[tuple[Any, Any]]] = {}
    for tc in trials:
        rec = fes_recording(tc)
        if rec.stim_kind != "pw" and tc.fes.step not in ("static", "pendulum"):
            raise ConfigError(
                f"{cfg.path}: trial {tc.name!r}: stimulation_unit = {tc.fes.stimulation_unit!r} "
                "(current modulation): the protocol of msk run (Benoussaad et al. 2013) identifies "
                "pulse-width modulated sessions only"
            )
        by_step.setdefault(tc.fes.step, []).append((tc, rec))

    def iso(tc: Any, rec: Any) -> Any:
        if tc.fes.knee_angle_deg is not None:
            angle = float(np.deg2rad(tc.fes.knee_angle_deg))
        elif rec.knee_angle is not None:
            angle = float(np.median(rec.knee_angle))
        else:
            raise MissingDataError(
                f"{tc.file}: no angle channel {tc.fes.angle_channel!r} and no knee_angle_deg "
                f"for isometric trial {tc.name!r}"
            )
        return rec.isometric_trial(knee_angle=angle, frequency_hz=opt.frequency_hz)

    ((_, st),) = by_step["static"]
    if st.torque is None:
        tc0 = by_step["static"][0][0]
        raise MissingDataError(
            f"{tc0.file}: no torque channel {tc0.fes.torque_channel!r} in the static trial"
        )
    static = StaticTrial(st.theta_r(rest), st.torque)
    ((_, pd),) = by_step["pendulum"]
    ((_, dy),) = by_step["dynamic"]
    ((_, va),) = by_step["validation"]
    return FesSession(
        cfg.subject.name,
        float(cfg.subject.height_m),  # type: ignore[arg-type]
        float(cfg.subject.mass_kg or np.nan),  # set by session_inputs
        static,
        pd.pendulum_trial(theta_rest=rest),
        tuple(iso(tc, r) for tc, r in by_step["isometric"]),
        tuple(iso(tc, r) for tc, r in by_step["recruitment"]),
        dy.dynamic_trial(frequency_hz=opt.frequency_hz, theta_rest=rest),
        va.dynamic_trial(frequency_hz=opt.frequency_hz, theta_rest=rest),
        opt.frequency_hz,
    )


def _parameters(res: Any) -> dict[str, float]:
    subj = res.subject
    return {
        name: float(getattr(getattr(subj, name.split(".")[0]), name.split(".")[1]))
        for name in FES_PARAMETER_UNITS
    }


def _steps(res: Any) -> dict[str, dict[str, float]]:
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
    par = _parameters(res)
    steps = _steps(res)
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


def fes_summary(res: Any, cfg: SessionConfig, trials: Sequence[Any]) -> dict[str, Any]:
    par = _parameters(res)
    return {
        "parameters": {k: {"value": v, "unit": FES_PARAMETER_UNITS[k]} for k, v in par.items()},
        "initial_parameters": {
            k: float(getattr(getattr(res.subject_initial, k.split(".")[0]), k.split(".")[1]))
            for k in FES_PARAMETER_UNITS
        },
        "steps": _steps(res),
        "k_s_history_n_per_m": list(res.k_s_history),
        "solver_status": res.series_stiffness.solver_status,
        "seconds": dict(res.seconds),
        "trials": [{"name": tc.name, "step": tc.fes.step, "file": str(tc.file)} for tc in trials],
        "options": dataclasses.asdict(cfg.fes),
    }


def _trial_settings(tc: TrialConfig) -> FesTrialConfig:
    """The FES keys of a ``role = "fes"`` trial (``load_config`` always fills them)."""
    if tc.fes is None:
        raise ConfigError(f"trial {tc.name!r}: role 'fes' without its FES settings")
    return tc.fes


def requested(inputs: SessionInputs) -> str | None:
    """Why the stage is not requested (None when it is)."""
    return None if inputs.fes_trials else "no trial with role 'fes' in the configuration"


def settings(inputs: SessionInputs) -> Any:
    cfg = inputs.cfg
    return {
        "files": {tc.name: inputs.hashes[f"fes:{tc.name}"] for tc in inputs.fes_trials},
        "trials": [
            {"name": tc.name, **dataclasses.asdict(_trial_settings(tc))} for tc in inputs.fes_trials
        ],
        "options": dataclasses.asdict(cfg.fes),
        "height": cfg.subject.height_m,
        "mass": cfg.subject.mass_kg,
    }


def run(inputs: SessionInputs) -> FesResult:
    from msk.fes.protocol import run_protocol

    cfg = inputs.cfg
    res = run_protocol(
        fes_session(cfg, inputs.fes_trials),
        fibre_fraction=cfg.fes.fibre_fraction,
        stiffness_ratio=cfg.fes.stiffness_ratio,
        k_s0=cfg.fes.k_s0,
        outer_iterations=cfg.fes.outer_iterations,
        steady_window=cfg.fes.steady_window_s,
        isometric_transients=cfg.fes.isometric_transients,
    )
    return FesResult(res)
