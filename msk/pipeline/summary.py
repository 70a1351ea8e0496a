"""Step ``summary`` (not a recorded stage): ``summary.json`` from the stage results — inputs
with their sha256, settings, subject, model, frame, events, quality figures and gates
(:mod:`msk.quality`), methods, identified parameters with their :mod:`msk.status` words,
comparison, FES. The stage records are added by :func:`msk.pipeline.session.run_session`."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Literal, cast

import numpy as np

from msk.config import SessionConfig
from msk.dynamics.identification import MassIdentification
from msk.dynamics.inverse import InverseDynamics
from msk.dynamics.loads import ASSIGNMENT_METHOD
from msk.exceptions import MskError
from msk.fes.io import FES_PARAMETER_UNITS, fes_parameters, fes_step_figures
from msk.gait.analysis import GaitAnalysis
from msk.metrics import root_mean_square as rms
from msk.muscles.emg import EmgActivations
from msk.optimization.muscle_forces import MuscleForces
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

__all__ = [
    "base_summary",
    "fes_summary",
    "filtering",
    "frames_solved",
    "joint_strength",
    "joint_strength_settings",
    "peak_measured_force_n",
    "run",
    "strength_summary",
    "swapped_markers",
]

_ANTHRO_MAP = {
    "pelvis": ("pelvis",),
    "femur": ("thigh",),
    "tibia": ("shank",),
    "foot": ("foot",),
    "torso": ("head_neck", "thorax", "upper_arm", "forearm", "hand"),
}


def peak_measured_force_n(ext: Any, measured: np.ndarray) -> float:
    """The largest magnitude of the net ground reaction over the ``measured`` frames, as the
    plates **recorded** it (:attr:`msk.dynamics.loads.ExternalLoads.force_recorded`; the low-passed
    force where it is not kept). Hicks et al. 2015 (J Biomech Eng 137:020905) bound
    the residual moment by 1 % of the COM height × the magnitude of the measured external
    force; a 6 Hz low-pass lowers the shipped walks' peaks by 3–13 % (JW 923 → 895 N, Plug-in
    Gait 1005 → 876 N), hence the bound, and had flagged residuals the guideline accepts."""
    f = ext.force_recorded
    net = f[measured] if f is not None else np.nansum(ext.force[measured], axis=1)
    return float(np.nanmax(np.linalg.norm(net, axis=1), initial=0.0))


def filtering(cfg: SessionConfig) -> str:
    """What was low-passed, in words (``methods.filtering``)."""
    f = cfg.filters
    where = (
        "each segment's centre of mass low-passed like the plates for the whole-body "
        "acceleration (the difference taken by the pelvis translations; "
        "msk.kinematics.com_consistency)"
        if f.acceleration_domain == "segment_com"
        else "velocities and accelerations differentiated from the low-passed coordinates"
    )
    return (
        f"joint coordinates low-passed at {f.kinematics_cutoff_hz:g} Hz and ground reactions "
        f"at {cfg.filters.grf_cutoff_used_hz:g} Hz (4th-order Butterworth run forward and "
        "backward: zero "
        f"lag); {where}"
    )


def base_summary(inputs: SessionInputs) -> dict[str, Any]:
    """The part of ``summary.json`` every session has (gait or FES only)."""
    cfg = inputs.cfg
    return {
        "session": cfg.subject.name,
        "trial": inputs.task.name if inputs.task is not None else None,
        "created_utc": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "versions": versions(),
        "config": {"path": str(cfg.path), "sha256": file_sha256(cfg.path)},
        "inputs": [
            {"role": k, "path": str(p), "sha256": inputs.hashes[k], "bytes": Path(p).stat().st_size}
            for k, p in inputs.files.items()
        ],
        "settings": plain_settings(cfg),
        "subject": {
            "name": cfg.subject.name,
            "mass_kg": inputs.mass_kg,
            **inputs.mass,
            "height_m": cfg.subject.height_m,
            "sex": cfg.subject.sex,
            "side": inputs.side,
            "body_weight_n": inputs.body_weight,
        },
    }


def unmeasured_contact_figures(loads: Any, time: Any) -> dict[str, Any]:
    """``quality.unmeasured_contact_frames`` (frames in which a foot stands on a surface no plate
    measures for at least :data:`msk.dynamics.loads.STANDING_S`,
    :meth:`msk.dynamics.loads.FootContact.standing`;
    its leg's joint torques are not written there),
    ``unmeasured_contact_frames_by_foot``, ``unmeasured_contact_raised_frames`` (those off the
    floor's level: a stair's upper steps, a box) and ``unmeasured_contact_inside_pct``: the share
    of the frames between the first and the last measured frame that have one (a walkway's
    steps before and after the plates lie outside; a foot off a plate in the middle of the task
    inside)."""
    contact = getattr(loads, "contact", None)
    if contact is None:
        return {}
    miss = np.asarray(contact.standing(), dtype=bool)
    anym: np.ndarray[Any, np.dtype[np.bool_]] = np.asarray(miss.any(axis=1), dtype=bool)
    meas = np.flatnonzero(np.asarray(loads.measured, dtype=bool))
    inside = None
    span = None
    if meas.size:
        a, b = int(meas[0]), int(meas[-1])
        inside = 100.0 * float(anym[a : b + 1].mean())
        t = np.asarray(time, dtype=float)
        hit = np.flatnonzero(anym[a : b + 1])
        if hit.size:
            span = [float(t[a + hit[0]]), float(t[a + hit[-1]])]
    floor = getattr(contact, "on_floor", None)
    raised = miss & ~np.asarray(floor, dtype=bool) if floor is not None else miss & False
    return {
        "unmeasured_contact_frames": int(anym.sum()),
        "unmeasured_contact_raised_frames": int(raised.any(axis=1).sum()),
        "unmeasured_contact_frames_by_foot": {
            f: int(miss[:, k].sum()) for k, f in enumerate(contact.feet)
        },
        "unmeasured_contact_inside_pct": inside,
        "unmeasured_contact_inside_s": span,
    }


def _mode(names: Sequence[str]) -> str:
    vals = [n for n in names if n]
    return max(set(vals), key=vals.count) if vals else ""


def _quality(
    trial: Any,
    kin: Any,
    jt: Any,
    loads: Any,
    emg: EmgActivations | None,
    sol: MuscleForces | None,
    strength: StrengthIdentification | None,
    ident: MassIdentification | None,
    body_weight: float,
    measured: np.ndarray,
    observed: np.ndarray,
    observation: Any = None,
) -> dict[str, Any]:
    """Data-quality figures; the residuals over the frames whose ground contact the plates
    measure (``measured``, :func:`msk.dynamics.loads.contact_measured`) and the markers observe
    (``observed`` ⊆ ``measured``; ``observation``:
    :func:`msk.kinematics.observation.observed_frames`),
    None when there is none."""
    ok = np.isfinite(jt.residual_force).all(axis=1) & observed
    res_f = rms(jt.residual_force[ok]) if ok.any() else None
    gaps = [
        {"marker": lab, "missing_frames": int(n), "longest_gap_frames": int(g)}
        for lab, n, g in zip(trial.gaps.labels, trial.gaps.n_missing, trial.gaps.longest_gap)
        if n > 0
    ]
    q: dict[str, Any] = {
        "frames": int(kin.time.size),
        "rate_hz": float(trial.point_rate_hz),
        "marker_gaps": gaps,
        "ik_failed_frames": int(kin.failed_frames.size),
        "ik_marker_rms_mean_m": float(np.nanmean(kin.marker_rms)),
        "ik_marker_rms_max_m": float(np.nanmax(kin.marker_rms)),
        "ik_worst_marker": _mode(kin.marker_max_name),
        "contact_measured_frames": int(measured.sum()),
        "observed_measured_frames": int(observed.sum()),
        "unobserved_segment_frames": (
            None if observation is None else {k: int(v) for k, v in observation.short.items()}
        ),
        "residual_force_rms_n": res_f,
        "residual_force_rms_pct_bw": None if res_f is None else 100 * res_f / body_weight,
        "residual_moment_rms_nm": rms(jt.residual_moment[ok]) if ok.any() else None,
        "plate_assignments": [
            {k: getattr(a, k) for k in ("plate", "body", "start_time", "end_time") if hasattr(a, k)}
            for a in getattr(loads, "assignments", ())
        ],
    }
    if emg is not None:
        flat = [emg.sources[k] for k in range(len(emg.muscles)) if not emg.usable[k]]
        q["emg_flat_channels"] = sorted(set(flat))
        q["emg_warnings"] = list(emg.warnings)
        q["emg_normalisation"] = emg.normalisation
    if sol is not None and sol.infeasible_frames is not None:
        q["optimization_infeasible_frames"] = sol.infeasible_frames
    if strength is not None:
        q["strength_fit_r2"] = float(strength.profile.r2)
    if ident is not None:
        q["identification_condition_number"] = ident.condition_number
    return q


def _anthropometry(cfg: SessionConfig, model: Any) -> dict[str, Any] | None:
    """Generic segment masses of the anthropometric table (Dumas et al. 2007) mapped on the
    model's segments (the foot = talus + calcaneus + toes; the torso = trunk, head and arms)."""
    try:
        from msk.model.anthropometry import generic_segments

        # segment masses are fractions of body mass: the stature (default 1.75 m when the
        # config has none) only sets lengths and inertias, which are not reported
        sex = cast(Literal["male", "female"], cfg.subject.sex)
        mass = float(cfg.subject.mass_kg or np.nan)  # set by session_inputs
        segs = generic_segments(mass, cfg.subject.height_m or 1.75, sex=sex)
    except (ImportError, MskError):
        return None
    out = {}
    for body in (b.name for b in model.bodies):
        base, _, sd = body.rpartition("_") if body.endswith(("_l", "_r")) else (body, "", "")
        key = "foot" if base in ("talus", "calcn", "toes") else base
        if key not in _ANTHRO_MAP:
            continue
        total = 0.0
        for s in _ANTHRO_MAP[key]:
            for name, seg in segs.items():
                stem = name[:-2] if name.endswith(("_l", "_r")) else name
                side_ok = not sd or not name.endswith(("_l", "_r")) or name.endswith("_" + sd)
                if stem == s and side_ok:
                    total += seg.mass
        label = f"{key}_{sd}" if sd else key
        out[label] = {"mass_kg": total, "table": "Dumas et al. 2007"}
    return {"segments": out, "table": "Dumas et al. 2007", "sex": cfg.subject.sex}


def _joint_strength(
    strength: StrengthIdentification, model: Any, side: str, mass_kg: float | None
) -> dict[str, Any] | None:
    """The ``joint_strength`` part of :func:`strength_summary` (None without muscles)."""
    if model is None or not model.muscles:
        return None
    from msk.strength import joint_strength_summary

    try:
        return joint_strength_summary(model, strength.profile, side=side, mass_kg=mass_kg)
    except Exception as exc:  # the curves must not cost the run its strength summary
        return {"error": f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}"}


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
    return _joint_strength(
        strength_identification, model.model, inputs.sfx, inputs.cfg.subject.mass_kg
    )


_COMPUTE = object()  # strength_summary's default: compute the joint curves


def strength_summary(
    strength: StrengthIdentification,
    *,
    model: Any = None,
    side: str = "_r",
    mass_kg: float | None = None,
    joint: Any = _COMPUTE,
) -> dict[str, Any]:
    """``identified`` = status "identified" (:mod:`msk.status`); ``gated`` = the group passed
    the correlation gate. With the (generic, scaled) ``model``: ``joint_strength``, the maximal
    isometric moment curves of the generic and the identified model
    (:func:`msk.strength.joint_strength_summary`), N·m and N·m/kg; ``joint``: those already
    computed (:func:`joint_strength`)."""
    from msk.status import STATUS_CODES, STATUS_MEANING, STRENGTH_R2_MIN
    from msk.strength.diagnosis import diagnose

    p = strength.profile
    diag = diagnose(p)
    status = tuple(d.status for d in diag)
    protocols = getattr(strength, "protocols", None) or {}
    if joint is _COMPUTE:
        joint = _joint_strength(strength, model, side, mass_kg)
    return {
        "groups": [
            {
                "group": n,
                "muscles": list(strength.groups.get(n, [])),
                "factor": float(p.factors[g]),
                "ci_low": float(p.ci_low[g]),
                "ci_high": float(p.ci_high[g]),
                "ci_cov_low": float(p.ci_cov_low[g]),
                "ci_cov_high": float(p.ci_cov_high[g]),
                "f_iso_generic_n": float(p.f_iso_generic[g]),
                "f_iso_n": float(p.f_iso[g]),
                "status": status[g],
                "identified": status[g] == "identified",
                "gated": bool(p.identified[g]),
                "reason": diag[g].reason,
                "r2": diag[g].r2 if math.isfinite(diag[g].r2) else None,
                "r2_coordinates": list(diag[g].coordinates),
                "confounded_with": list(diag[g].confounded_with),
                "protocol": protocols.get(n),
            }
            for g, n in enumerate(p.group_names)
        ],
        "r2": float(p.r2),
        "r2_min": STRENGTH_R2_MIN,
        "status_codes": dict(STATUS_CODES),
        "status_meaning": dict(STATUS_MEANING),
        "confidence": float(p.confidence),
        "bounds": list(p.bounds),
        "method": p.method,
        "joint_strength": joint,
        "failed_channels": [
            {
                "group": n,
                "muscles": list(rec.get("muscles", [])),
                "status": "not determined",
                "identified": False,
                "gated": False,
                "reason": rec.get("reason"),
                "protocol": rec.get("protocol"),
            }
            for n, rec in (getattr(strength, "failed", None) or {}).items()
        ],
    }


def frames_solved(sol: MuscleForces) -> dict[str, int]:
    """Per leg (the side suffix ``r``/``l`` of the muscles' names) the frames in which every
    muscle of that leg has a force (the tension stage leaves a leg out where its foot stands
    off the plates, :func:`msk.optimization.muscle_forces.solve_muscle_forces`)."""
    out = {}
    for side in ("r", "l"):
        cols = [k for k, n in enumerate(sol.muscles) if n.endswith(f"_{side}")]
        if cols and sol.forces.shape[1]:
            out[side] = int(np.isfinite(sol.forces[:, cols]).all(axis=1).sum())
    return out


def _optimization_summary(sol: MuscleForces, sfx: str) -> dict[str, Any]:
    from msk.status import gain_status

    extra = {}
    if sol.frontal_reserve_moments is not None:
        from msk.quality import frontal_reserve_figures

        extra["frontal_reserve"] = {
            "id_frontal_moment_peak_nm": sol.id_frontal_moment_peak_nm or 0.0,
            **frontal_reserve_figures(sol),
        }
    return (
        extra
        | {
            "method": sol.method,
            "criterion": sol.criterion,
            "emg_gains": None if sol.emg_gains is None else dict(sol.emg_gains),
            "emg_gain_status": None
            if not sol.emg_gains
            else {c: gain_status(float(g)).value for c, g in sol.emg_gains.items()},
            "infeasible_frames": sol.infeasible_frames,
            "frames_solved": frames_solved(sol),
            "reserve_torque_rms_nm": None
            if sol.reserve_torques is None or sol.reserve_coordinates is None
            else {
                c: float(np.sqrt(np.nanmean(sol.reserve_torques[:, k] ** 2)))
                for k, c in enumerate(sol.reserve_coordinates)
                if c.endswith(sfx)
            },
        }
        | ({} if sol.kkt is None else {"kkt": kkt_summary(sol.kkt)})
    )


def kkt_summary(worst: Any) -> dict[str, Any]:
    """``optimization.kkt`` of a :class:`msk.optimization.muscle_forces.KktWorst`."""
    from msk.quality import THRESHOLDS

    return {
        "frames": int(worst.frames),
        "relative_tolerance": THRESHOLDS["kkt_relative"],
    } | {
        c: {
            "max": float(worst.value[k]),
            "relative_max": float(worst.relative[k]),
            "frame": int(worst.frame[k]),
            "time_s": float(worst.time_s[k]),
        }
        for k, c in enumerate(worst.columns)
    }


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
) -> list[dict[str, Any]]:
    """The quality gates raised (:func:`msk.quality.gait_flags`), swapped left/right labels and
    what the reader noticed in the file (duplicate labels renamed, NaN plate samples…)."""
    from msk.quality import (
        SWAP_MIN_SEPARATION_M,
        THRESHOLDS,
        com_height,
        contact_flags,
        gait_flags,
        model_flags,
    )

    cfg, task, mdl = inputs.cfg, inputs.task, model.model
    assert task is not None  # a gait session
    scaling = model.info.get("scaling", {}).get("bodies", {})
    ext = loads.external
    flags = [
        f.as_dict()
        for f in gait_flags(
            task.name, quality=quality, model=mdl, kinematics=kin, joint_torques=jt,
            mass_kg=inputs.mass_kg, height_m=cfg.subject.height_m,
            marker_labels=model.trial.marker_labels, optimization=sol, plate_mass_kg=plate_mass,
            held=tuple(model.held), scaling_methods={b: v["method"] for b, v in scaling.items()},
            peak_external_force_n=peak_measured_force_n(ext, loads.measured),
            com_height_m=com_height(mdl, kin, loads.measured, floor_m=float(np.median(
                list(ext.metadata.get("surface_heights_m", {}).values()) or [0.0]))),
        )
    ]  # fmt: skip
    flags += [f.as_dict() for f in contact_flags(task.name, ext)]
    flags += [f.as_dict() for f in model_flags(task.name, model.info,
                                               [b.name for b in mdl.bodies])]  # fmt: skip
    for r, lft, dz in swapped_pairs:
        flags.append(
            {"trial": task.name, "quantity": f"{r}/{lft}_swapped", "value": dz,
             "threshold": -SWAP_MIN_SEPARATION_M,
             "message": f"{r} is {-1000 * dz:.0f} mm left of {lft} (the subject's right "
             "from the pelvis): their labels look swapped (a labelling error in the file, or "
             "the wrong side in the config)"}
        )  # fmt: skip
    swapped = dict(model.info.get("marker_set", {}).get("swapped_back", {}))
    if swapped:
        flags.append(
            {"trial": task.name, "quantity": "marker_labels_swapped_back",
             "value": max(-v for v in swapped.values()), "threshold": SWAP_MIN_SEPARATION_M,
             "message": "left/right labels swapped in the file: " + ", ".join(
                 f"{pair} ({-1000 * v:.0f} mm on the wrong side)"
                 for pair, v in sorted(swapped.items()))
             + "; their markers were exchanged back before scaling and IK "
             "(msk.quality.swapped_label_pairs, judged from the pelvis markers)"}
        )  # fmt: skip
    if model.info.get("static_rejected"):
        assert inputs.static is not None
        flags.append(
            {"trial": task.name, "quantity": "static_not_used", "value": 1.0, "threshold": 0.0,
             "message": f"static trial {inputs.static.name!r}: {model.info['static_rejected']}"}
        )  # fmt: skip
    bad = dict(model.info.get("static_check", {}).get("contradicted_m", {}))
    if bad:
        flags.append(
            {"trial": task.name, "quantity": "static_markers_contradicted_m",
             "value": max(bad.values()), "threshold": THRESHOLDS["static_marker_discrepancy_m"],
             "message": "the static trial's " + ", ".join(
                 f"{lab} ({1000 * d:.0f} mm)" for lab, d in sorted(bad.items()))
             + " disagree with their segment's other markers in the task (median distance "
             "difference): mislabelled or ghost markers in the static, placed from the task "
             "instead (msk.quality.inconsistent_static_markers)"}
        )  # fmt: skip
    if cfg.emg.channels:
        from msk.muscles.emg import missing_channels

        _, absent = missing_channels(cfg.emg.channels, model.trial.analog_labels)
        if absent:
            muscles = sorted(m for m, c in cfg.emg.channels.items() if str(c).strip() in absent)
            flags.append(
                {"trial": task.name, "quantity": "emg_channels_missing", "value": len(absent),
                 "threshold": 0,
                 "message": f"{task.file.name} has no analog channel "
                 f"{', '.join(repr(c) for c in absent)} of the configuration's [emg] channels: "
                 f"{', '.join(muscles)} tracked by no EMG in this trial"}
            )  # fmt: skip
    meta = model.trial.metadata or {}
    typed = tuple(meta.get("flags", ()))  # the reader's typed flags keep their quantity
    for f in typed:
        flags.append(
            {"trial": task.name, "quantity": str(f["quantity"]), "value": float(f["value"]),
             "threshold": float(f["threshold"]), "message": f"{task.file.name}: {f['message']}"}
        )  # fmt: skip
    said = {f["message"] for f in typed}
    for w in meta.get("warnings", ()):
        if w in said:
            continue
        flags.append(
            {"trial": task.name, "quantity": "input_file", "value": 1.0,
             "threshold": 0.0, "message": f"{task.file.name}: {w}"}
        )  # fmt: skip
    return flags


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
    from msk.quality import THRESHOLDS, body_mass_from_loads

    cfg = inputs.cfg
    fes_part = None if fes is None else fes_summary(fes.result, cfg, inputs.fes_trials)
    if model is None or loads is None or inverse_dynamics is None:
        return {**base_summary(inputs), "angle_columns": [], "quality": {}, "fes": fes_part}
    assert gait_cycle is not None and inputs.task is not None  # derived from the core stages
    mdl, kin, sol = model.model, kinematics, tension_optimization
    ident, strength = mass_identification, strength_identification
    jt = inverse_dynamics.torques
    quality = _quality(
        model.trial, kin, jt, loads.external, emg, sol, strength, ident, inputs.body_weight,
        loads.measured, loads.measured_observed, loads.observation,
    )  # fmt: skip
    quality.update(unmeasured_contact_figures(loads, kin.time))
    plate_mass = body_mass_from_loads(mdl, kin, loads.external, loads.measured_observed)
    quality["plate_mass_kg"] = plate_mass
    pairs = () if swapped_markers is None else swapped_markers
    quality["flags"] = _flags(inputs, quality, model, kin, loads, pairs, jt, sol, plate_mass)
    from msk.kinematics.gait_plausibility import gait_mode, knee_contact_flags, pelvis_tilt_flags

    mode, why = gait_mode(gait_cycle.events, kin, -np.asarray(mdl.gravity, dtype=float))
    if knee_contact is not None:
        bw = {v: np.asarray(c.total, dtype=float) / inputs.body_weight
              for v, c in knee_contact.variants.items()}  # fmt: skip
        quality["flags"] += [
            f.as_dict() for f in knee_contact_flags(inputs.task.name, bw, mode, why)
        ]
    on_pelvis = tuple(m.name for m in mdl.markers if m.body == "pelvis"
                      and m.name in set(model.labels))  # fmt: skip
    quality["flags"] += [
        f.as_dict() for f in pelvis_tilt_flags(inputs.task.name, kin, mode, on_pelvis)
    ]
    for e in loads.external.metadata.get("plate_edge", ()):
        quality["flags"].append(
            {"trial": inputs.task.name, "quantity": "foot_past_plate_edge_m",
             "value": e["max_outside_m"], "threshold": 0.01,
             "message": f"{e['foot']} straddles the edge of {e['plate']} from "
             f"{e['start_s']:.2f} to {e['end_s']:.2f} s ({e['frames']} frames, up to "
             f"{100 * e['max_outside_m']:.0f} cm past it): part of its ground reaction is "
             "off the plate, so those frames count as an unmeasured contact (no joint "
             "torques of that leg, residual, muscle force or knee contact from them; "
             "msk.dynamics.plate_footprint)"}
        )  # fmt: skip
    if emg is not None:  # a glitch in a raw EMG channel, repaired or the channel excluded
        from msk.muscles.emg_faults import fault_flags

        quality["flags"] += fault_flags(inputs.task.name, emg.sample_faults)
    unmatched = [
        n for n in (model.info.get("marker_set") or {}).get("notes", ())
        if str(n).startswith("markers.rename: labels in no trial")
    ]  # fmt: skip
    for note in unmatched:  # a typo in [markers] rename: the marker it meant is not tracked
        quality["flags"].append(
            {"trial": inputs.task.name, "quantity": "marker_rename_unmatched",
             "value": float(len(str(note).split(":", 2)[-1].split(","))), "threshold": 0.0,
             "message": f"{note} (a typo? the model markers they name are not tracked from "
             "them)"}
        )  # fmt: skip
    for d in getattr(loads, "dead_plates", ()):  # a plate reading nothing under a foot
        quality["flags"].append(
            {"trial": inputs.task.name, "quantity": "plate_dead", "value": d["max_force_n"],
             "threshold": 20.0,
             "message": f"force plate {d['plate']} reads at most {d['max_force_n']:.0f} N while "
             f"{d['foot']} stands on it for {d['seconds']:.2f} s ({d['start_s']:.2f}–"
             f"{d['end_s']:.2f} s): a dead, disconnected or mis-mapped plate; that foot's "
             "ground reaction is missing"}
        )  # fmt: skip
    from msk.contact.comparison_check import comparison_flags

    quality["flags"] += comparison_flags(inputs, gait_cycle, comparison, kin.time)
    quality["thresholds"] = dict(THRESHOLDS)
    quality["held_coordinates"] = sorted(model.held)
    ev = gait_cycle.events
    return {
        **base_summary(inputs),
        "model": {**model.info, "name": mdl.name, "muscles": len(mdl.muscles)},
        "frame": {"lab_to_model_rotation": model.rotation, "lab_up": model.lab_up},
        "events": gait_cycle.as_list(),
        "event_sources": {**dict(ev.source), "notes": list(ev.notes)},
        "gait_cycle_s": list(gait_cycle.cycle) if gait_cycle.cycle else None,
        "gait": None if gait_analysis is None else gait_analysis.summary(),
        "angle_columns": [c for c in kin.coordinate_names if not c.endswith(("_tx", "_ty", "_tz"))],
        "quality": quality,
        "methods": {
            "plate_assignment": ASSIGNMENT_METHOD,
            "scaling_measurements": [m[0] for m in DEFAULT_MEASUREMENTS],
            "task_trial": inputs.task.name,
            "filtering": filtering(cfg),
        },
        "identification": None
        if ident is None
        else {
            "segments": ident.segments,
            "condition_number": ident.condition_number,
            "n_frames": ident.n_frames,
            "advice": ident.advice,
        },
        "anthropometry": _anthropometry(cfg, mdl),
        "plates": {  # each plate's surface, offset removed, plates left out
            "surfaces": list(loads.external.metadata.get("surfaces", ())),
            "offsets_removed": list(loads.external.metadata.get("plate_offsets", ())),
            "ignored": list(loads.external.metadata.get("ignored_plates", ())),
        },
        "strength": None if strength is None else strength_summary(strength, joint=joint_strength),
        "comparison": comparison,
        "optimization": None if sol is None else _optimization_summary(sol, inputs.sfx),
        "fes": fes_part,
    }


def fes_summary(res: Any, cfg: SessionConfig, trials: Sequence[Any]) -> dict[str, Any]:
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
        "options": dataclasses.asdict(cfg.fes),
    }
