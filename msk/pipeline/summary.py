"""Step ``summary`` (not a recorded stage): ``summary.json`` from the stage results — inputs
with their sha256, settings, subject, model, frame, events, quality figures and gates
(:mod:`msk.quality`), methods, identified parameters with their :mod:`msk.status` words,
comparison, FES. The stage records are added by :func:`msk.pipeline.session.run_session`."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from msk.config import SessionConfig
from msk.dynamics.identification import MassIdentification, applied_segments
from msk.dynamics.inverse import InverseDynamics
from msk.dynamics.loads import ASSIGNMENT_METHOD, peak_measured_force_n
from msk.gait.analysis import GaitAnalysis
from msk.model.anthropometry import model_anthropometry
from msk.muscles.emg import EmgActivations
from msk.optimization.muscle_forces import MuscleForces, frames_solved, optimization_summary
from msk.personalise import Personalisation
from msk.personalise.scaling import DEFAULT_MEASUREMENTS
from msk.pipeline.inputs import SessionInputs, plain_settings
from msk.pipeline.records import (
    FesResult,
    GaitCycle,
    KneeContact,
    Loads,
    StrengthIdentification,
)
from msk.pipeline.runner import file_sha256, versions
from msk.quality import (
    THRESHOLDS,
    Flag,
    body_mass_from_loads,
    dead_plate_flags,
    gait_quality,
    marker_rename_flags,
    plate_edge_flags,
    trial_flags,
    unmeasured_contact_figures,
)
from msk.results.summary import (
    ConfigRef,
    Event,
    Frame,
    Identification,
    InputFile,
    Methods,
    Segment,
    Subject,
)
from msk.strength.diagnosis import joint_strength_or_error, strength_summary

# frames_solved, peak_measured_force_n and strength_summary are their library rooms'
# (msk.optimization.muscle_forces, msk.dynamics.loads, msk.strength.diagnosis)
__all__ = [
    "base_summary",
    "filtering",
    "frames_solved",
    "joint_strength",
    "joint_strength_settings",
    "peak_measured_force_n",
    "run",
    "strength_summary",
    "swapped_markers",
]


def filtering(cfg: SessionConfig) -> str:
    """What was low-passed, in words (``methods.filtering``,
    :meth:`msk.config.options.FilterConfig.description`)."""
    return cfg.filters.description()


def base_summary(inputs: SessionInputs) -> dict[str, Any]:
    """The part of ``summary.json`` every session has (gait or FES only)."""
    cfg = inputs.cfg
    return {
        "session": cfg.subject.name,
        "trial": inputs.task.name if inputs.task is not None else None,
        "created_utc": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "versions": versions(),
        "config": ConfigRef(path=str(cfg.path), sha256=file_sha256(cfg.path)).to_dict(),
        "inputs": [
            InputFile(
                role=k, path=str(p), sha256=inputs.hashes[k], bytes=Path(p).stat().st_size
            ).to_dict()
            for k, p in inputs.files.items()
        ],
        "settings": plain_settings(cfg),
        "subject": Subject(
            name=cfg.subject.name,
            mass_kg=inputs.mass_kg,
            mass_source=inputs.mass.get("mass_source"),
            mass_detail=inputs.mass.get("mass_detail"),
            height_m=cfg.subject.height_m,
            sex=cfg.subject.sex,
            side=inputs.side,
            body_weight_n=inputs.body_weight,
        ).to_dict(),
    }


def joint_strength_settings(inputs: SessionInputs) -> Any:
    return {"side": inputs.sfx, "mass": inputs.cfg.subject.mass_kg}


def joint_strength(
    inputs: SessionInputs,
    model: Personalisation | None,
    strength_identification: StrengthIdentification | None,
) -> dict[str, Any] | None:
    """The summary's ``strength.joint_strength`` (the maximal isometric moment curves of the
    generic and the identified model, :func:`msk.strength.joint_strength_summary`): a step of
    its own so that the stage cache keeps it (a run whose stages all come from the cache does
    not evaluate the muscle geometry over the curves' grids again)."""
    if model is None or strength_identification is None:
        return None
    return joint_strength_or_error(
        strength_identification, model.model, inputs.sfx, inputs.cfg.subject.mass_kg
    )


def swapped_markers(
    inputs: SessionInputs, model: Personalisation, kinematics: Any
) -> tuple[tuple[str, str, float], ...]:
    """Step ``swapped_markers`` (not a recorded stage): the left/right marker pairs of the task
    whose labels look swapped (:func:`msk.quality.swapped_sides` of the model-frame markers and
    the solved poses), for the summary's flags — taken right after the kinematics stage, the
    last stage to read the task's markers, so that a long trial's markers are dropped there
    (:data:`msk.pipeline.graph.TRIMS`)."""
    from msk.quality import swapped_sides

    return tuple(swapped_sides(model.model, kinematics, model.trial.markers, model.labels))


def _knee_loads(contact: KneeContact, body_weight_n: float) -> dict[str, Any]:
    """``knee_loads``: the quadriceps' route and the peak patellofemoral force per variant."""
    peak = {
        v: float(np.nanmax(c.patellofemoral))
        for v, c in contact.variants.items()
        if c.patellofemoral is not None and np.isfinite(c.patellofemoral).any()
    }
    return {
        "joint": contact.joint,
        "patella": contact.plateau.get("patella"),
        "peak_patellofemoral_n": peak or None,
        "peak_patellofemoral_bw": {v: p / body_weight_n for v, p in peak.items()} or None,
    }


def _flags(
    inputs: SessionInputs,
    quality: Mapping[str, Any],
    model: Personalisation,
    kin: Any,
    loads: Loads,
    swapped_pairs: Sequence[tuple[str, str, float]],
    jt: Any,
    sol: MuscleForces | None,
    plate_mass: float | None,
) -> list[Flag]:
    """The task trial's raised gates (:func:`msk.quality.trial_flags`)."""
    cfg, task = inputs.cfg, inputs.task
    assert task is not None  # a gait session
    flags = trial_flags(
        task.name, file_name=task.file.name, quality=quality, model=model.model,
        kinematics=kin, joint_torques=jt, external=loads.external, measured=loads.measured,
        mass_kg=inputs.mass_kg, height_m=cfg.subject.height_m,
        marker_labels=model.trial.marker_labels, optimization=sol, plate_mass_kg=plate_mass,
        held=tuple(model.held), model_info=model.info, swapped_pairs=swapped_pairs,
        static_name=None if inputs.static is None else inputs.static.name,
        emg_channels=cfg.emg.channels, analog_labels=model.trial.analog_labels,
        file_metadata=model.trial.metadata or {},
    )  # fmt: skip
    return list(flags)


def _identification(ident: MassIdentification, inputs: SessionInputs) -> dict[str, Any]:
    """The summary's ``identification``: each segment's figures with its status word and the
    segments whose identified inertia the dynamics used."""
    return Identification(
        segments=tuple(Segment(**s) for s in ident.segments),
        condition_number=ident.condition_number,
        n_frames=ident.n_frames,
        advice=tuple(ident.advice),
        applied_to_dynamics=tuple(applied_segments(ident, by_status=inputs.inertias_by_status)),
    ).to_dict()


def run(
    inputs: SessionInputs,
    model: Personalisation | None,
    kinematics: Any,
    loads: Loads | None,
    mass_identification: MassIdentification | None,
    inverse_dynamics: InverseDynamics | None,
    emg: EmgActivations | None,
    tension_optimization: MuscleForces | None,
    strength_identification: StrengthIdentification | None,
    gait_cycle: GaitCycle | None,
    comparison: Mapping[str, Any] | None,
    fes: FesResult | None,
    swapped_markers: Sequence[tuple[str, str, float]] | None,
    joint_strength: Mapping[str, Any] | None,
    knee_contact: KneeContact | None = None,
    gait_analysis: GaitAnalysis | None = None,
) -> dict[str, Any]:
    """``summary.json`` without the stage records; a pure FES session has the base summary,
    no angle columns, an empty quality block and the ``fes`` section."""
    cfg = inputs.cfg
    fes_part = None
    if fes is not None:  # on use: a gait session does not import the FES package
        from msk.fes.io import fes_summary

        fes_part = fes_summary(fes.result, cfg.fes, inputs.fes_trials)
    if model is None or loads is None or inverse_dynamics is None:
        return {**base_summary(inputs), "angle_columns": [], "quality": {}, "fes": fes_part}
    assert gait_cycle is not None and inputs.task is not None  # derived from the core stages
    mdl, kin, sol = model.model, kinematics, tension_optimization
    ident, strength = mass_identification, strength_identification
    jt = inverse_dynamics.torques
    quality = gait_quality(
        model.trial, kin, jt, loads.external, emg, sol, strength, ident, inputs.body_weight,
        loads.measured, loads.measured_observed, loads.observation,
    )  # fmt: skip
    quality.update(unmeasured_contact_figures(loads, kin.time))
    plate_mass = body_mass_from_loads(mdl, kin, loads.external, loads.measured_observed)
    quality["plate_mass_kg"] = plate_mass
    pairs = () if swapped_markers is None else swapped_markers
    flags = _flags(inputs, quality, model, kin, loads, pairs, jt, sol, plate_mass)
    from msk.kinematics.gait_plausibility import gait_mode, knee_contact_flags, pelvis_tilt_flags

    trial = inputs.task.name
    mode, why = gait_mode(gait_cycle.events, kin, -np.asarray(mdl.gravity, dtype=float))
    if knee_contact is not None:
        bw = {v: np.asarray(c.total, dtype=float) / inputs.body_weight
              for v, c in knee_contact.variants.items()}  # fmt: skip
        flags += knee_contact_flags(trial, bw, mode, why)
    on_pelvis = tuple(m.name for m in mdl.markers if m.body == "pelvis"
                      and m.name in set(model.labels))  # fmt: skip
    # the tilt the report gives (its pelvis frame), else the model's coordinate
    tilt, tilt_frame = (None, "") if gait_analysis is None else gait_analysis.pelvis_tilt_deg()
    flags += pelvis_tilt_flags(trial, kin, mode, on_pelvis, tilt_deg=tilt, frame=tilt_frame)
    flags += plate_edge_flags(trial, loads.external.metadata)
    if emg is not None:  # a glitch in a raw EMG channel, repaired or the channel excluded
        from msk.muscles.emg_faults import fault_flags

        flags += fault_flags(trial, emg.sample_faults)
    flags += marker_rename_flags(trial, model.info)
    flags += dead_plate_flags(trial, getattr(loads, "dead_plates", ()))
    from msk.contact.comparison_check import comparison_flags

    ev = gait_cycle.events
    flags += comparison_flags(
        trial, inputs.task.contact_force, comparison, kin.time, side=inputs.side,
        cycle=gait_cycle.cycle, measured=gait_cycle.measured_contact,
        foot_strikes=ev.foot_strike.get(inputs.side, ()) if ev else (),
    )  # fmt: skip
    quality["flags"] = [f.as_dict() for f in flags]
    quality["thresholds"] = dict(THRESHOLDS)
    quality["held_coordinates"] = sorted(model.held)
    anthro = model_anthropometry(
        (b.name for b in mdl.bodies), cfg.subject.mass_kg, cfg.subject.height_m, cfg.subject.sex
    )
    return {
        **base_summary(inputs),
        "model": {**model.info, "name": mdl.name, "muscles": len(mdl.muscles)},
        "frame": Frame(
            lab_to_model_rotation=tuple(tuple(map(float, row)) for row in model.rotation),
            lab_up=tuple(map(float, model.lab_up)),
        ).to_dict(),
        "events": [Event(**e).to_dict() for e in gait_cycle.as_list()],
        "event_sources": {**dict(ev.source), "notes": list(ev.notes)},
        "gait_cycle_s": list(gait_cycle.cycle) if gait_cycle.cycle else None,
        "gait": None if gait_analysis is None else gait_analysis.summary(),
        "angle_columns": [c for c in kin.coordinate_names if not c.endswith(("_tx", "_ty", "_tz"))],
        "quality": quality,
        "methods": Methods(
            plate_assignment=ASSIGNMENT_METHOD,
            scaling_measurements=tuple(m[0] for m in DEFAULT_MEASUREMENTS),
            task_trial=inputs.task.name,
            filtering=filtering(cfg),
        ).to_dict(),
        "identification": None if ident is None else _identification(ident, inputs),
        "anthropometry": None if anthro is None else anthro.to_dict(),
        "plates": {  # each plate's surface, offset removed, plates left out
            "surfaces": list(loads.external.metadata.get("surfaces", ())),
            "offsets_removed": list(loads.external.metadata.get("plate_offsets", ())),
            "ignored": list(loads.external.metadata.get("ignored_plates", ())),
        },
        "strength": None if strength is None else strength_summary(strength, joint=joint_strength),
        "comparison": comparison,
        "knee_loads": None
        if knee_contact is None
        else _knee_loads(knee_contact, inputs.body_weight),
        "optimization": None if sol is None else optimization_summary(sol, inputs.sfx).to_dict(),
        "fes": fes_part,
    }
