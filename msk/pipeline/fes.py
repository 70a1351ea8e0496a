"""Stage ``fes``: the FES-driven knee model identification protocol on the ``role = "fes"``
trials (:func:`msk.fes.protocol.run_protocol`; Benoussaad et al. 2013, §2.3), its tables and its
``summary.json`` section. Trials are read with :func:`msk.fes.io.read_fes_csv` (CSV) or
:func:`msk.fes.io.recording_from_trial` (C3D analogs). A session may hold only FES trials: the
gait stages are then ``not requested``."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from msk.config import FesTrialConfig, SessionConfig, TrialConfig
from msk.exceptions import ConfigError, MissingDataError
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.records import FesResult

__all__ = [
    "fes_recording",
    "fes_session",
    "requested",
    "run",
    "settings",
]


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
