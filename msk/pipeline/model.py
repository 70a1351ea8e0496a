"""Stage ``model``: load the model, recognise the marker set, choose the heading, scale (static
trial, else the motion, else the stature) and place the lab markers; then the task trial in the
model frame and the foot joints its markers cannot observe.

Frames (:func:`msk.io.lab_to_model_rotation`, :func:`msk.io.frames.pelvis_heading_rotation`):
lab vertical → the model's up (−gravity) and the walking direction → the model's +x (OpenSim's
convention), or the pelvis markers' heading where the progression disagrees with it by more
than 30° (treadmill, turning, short trials). Marker placement: :func:`msk.scaling.place_markers`
(static trial) or :func:`msk.scaling.place_markers_from_motion`.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from msk.exceptions import ConfigError, KinematicsError, ModelError
from msk.io.frames import lab_to_model_rotation
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.read import ReadResult, read_static_markers

__all__ = [
    "CHOICE_MAX_FRAMES",
    "CHOICE_MISSING_MARKERS",
    "CHOICE_TOLERANCE_M",
    "DESCENT_MAX_ROUNDS",
    "DESCENT_REL_TOLERANCE",
    "HELD_COORDINATE_WEIGHT",
    "STATIC_CHECK_MIN_TASK_S",
    "BuiltModel",
    "choose_placement",
    "continued_placement",
    "held_static_knees",
    "knee_flexion_to_physiological",
    "lab_origin_offset",
    "leg_split",
    "load_model_file",
    "model_frame_columns",
    "placement_cost",
    "placement_determinacy",
    "placement_fit",
    "placement_frames",
    "run",
    "settings",
    "sole_level",
    "without_markers",
]

#: shortest task (s) whose frames seeing a marker pair can show it rigid for the static-label
#: check (:func:`msk.quality.inconsistent_static_markers`): about one step of walking, over
#: which the hip and knee flex and extend by 20–40° (distances across a joint change)
STATIC_CHECK_MIN_TASK_S = 0.5

#: IK weight of the coordinate task holding an unobserved foot joint at 0 rad (weight per rad²,
#: markers per m²: 1° off costs as much as 17 mm of marker error)
HELD_COORDINATE_WEIGHT = 1.0


@dataclass(frozen=True)
class BuiltModel:
    """The scaled model with its placed markers, what was done (``info``: source, marker set,
    heading, scaling, placement — reported in ``summary.json`` ``model``), the lab → model
    rotation, the task trial's markers in the model frame (``trial``: a :class:`msk.trial.Trial`
    without its analog-rate data — no analogs, no plates —, exact-zero samples as gaps) with
    their labels in model names (``labels``), the foot coordinates held near neutral by an IK
    coordinate task (``held``: name → (value rad, weight)) and the lab's up (``lab_up``, the
    read trial's). The analogs and plates stay with :class:`~msk.pipeline.read.ReadResult`
    (the loads and EMG stages read them there): a long trial holds them once, and releases
    them when no later stage reads ``read`` (:func:`msk.pipeline.graph.run_graph`); in a
    session run the markers of ``trial`` are dropped after the kinematics and the step
    ``swapped_markers`` (:func:`without_markers`)."""

    model: Any
    info: Mapping[str, Any]
    rotation: np.ndarray
    rename: Mapping[str, str]
    trial: Any
    labels: tuple[str, ...]
    held: Mapping[str, tuple[float, float]]
    lab_up: np.ndarray


def load_model_file(path: Path, markers: Path | None = None) -> Any:
    """An msk model file or an OpenSim ``.osim`` (with its marker-set ``.xml`` when given)."""
    if path.suffix.lower() == ".osim":
        from msk.osim import load_osim

        return load_osim(path, marker_set=markers)
    from msk.model_files import load_model

    model = load_model(path)
    if markers is not None:
        from msk.osim import read_marker_set

        model = read_marker_set(markers, model)
    return model


def settings(inputs: SessionInputs) -> Any:
    cfg, mc = inputs.cfg, inputs.model_cfg
    assert mc is not None  # a gait stage
    return {
        "model": inputs.hashes["model"],
        "model_markers": inputs.hashes.get("model_markers"),
        "static": inputs.hashes.get("static"),
        "scale": mc.scale,
        "knee": mc.knee,
        "knee_alignment": (mc.knee_alignment, mc.knee_varus_deg, mc.knee_medial_shift_m),
        "mass": cfg.subject.mass_kg,
        "height": cfg.subject.height_m,
        "rename": dict(cfg.marker_rename),
        "move": list(cfg.marker_move),
        # also read by the stage (the key is complete: its result is kept in the cache): the
        # weights (placement without a static; their names checked), the side (knee alignment
        # from markers), the model file's path (summary.json model.source)
        "weights": dict(cfg.marker_weights),
        "side": cfg.subject.side,
        "source": str(inputs.model_source),
    }


def _aligned(inputs: SessionInputs, model: Any, markers: Any, labels: Any) -> Any:
    """The model with the frontal alignment of the side of interest's knee: the configured one,
    or (``knee_alignment = "from_markers"``) the one the trial's epicondyle and malleolus
    markers show against ``model``'s (:func:`msk.alignment.knee_varus_from_markers`, on the
    static trial when there is one, else the task); the model itself without one
    (:func:`msk.alignment.with_knee_alignment`)."""
    mc = inputs.model_cfg
    assert mc is not None  # a gait stage
    from_markers = mc.knee_alignment == "from_markers"
    if from_markers and (mc.knee_varus_deg != 0.0 or mc.knee_medial_shift_m != 0.0):
        raise ConfigError(
            f"{inputs.cfg.path}: model.knee_alignment = 'from_markers' with a given "
            "knee_varus_deg / knee_medial_shift_m: give one or the other"
        )
    if not from_markers and mc.knee_varus_deg == 0.0 and mc.knee_medial_shift_m == 0.0:
        return model
    from msk.alignment import knee_varus_from_markers, with_knee_alignment
    from msk.exceptions import MissingDataError

    joint = f"knee{inputs.sfx}"
    if joint not in {j.name for j in model.joints}:
        raise ConfigError(
            f"{inputs.cfg.path}: model.knee_varus_deg / knee_medial_shift_m: the model has no "
            f"joint {joint!r}"
        )
    varus, shift = np.radians(mc.knee_varus_deg), mc.knee_medial_shift_m
    if from_markers:
        try:
            est = knee_varus_from_markers(model, markers, labels, inputs.cfg.subject.side)
        except (MissingDataError, ModelError) as exc:
            raise ConfigError(f"{inputs.cfg.path}: model.knee_alignment: {exc}") from None
        varus, shift = est.varus_rad, 0.0
    aligned = with_knee_alignment(model, joint, varus_rad=varus, medial_shift_m=shift)
    if from_markers:
        meta = dict(aligned.metadata.get("knee_alignment") or {})
        meta[joint] = {**meta.get(joint, {}), "source": "markers",
                       "subject_rad": est.subject_rad, "model_rad": est.model_rad,
                       "iqr_rad": est.iqr_rad, "frames": est.frames}  # fmt: skip
        aligned = aligned.with_metadata(knee_alignment=meta)
    return aligned


def knee_flexion_to_physiological(model: Any) -> tuple[Any, dict[str, list[float]]]:
    """``model`` whose knees' flexion bound reaches the physiological limit of
    :data:`msk.quality.PHYSIOLOGICAL_RANGES_DEG` (155°: active flexion, Roaas & Andersson 1982,
    + 10°), and the widened ranges (deg). gait2392's knee stops at 120° of flexion, a software
    bound below the joint's: UWA's running swing is pulled past it in 16–19 % of the solved
    frames, and IK, held there, bent the pelvis instead (L.ASIS 49 mm RMS, the worst marker;
    the pelvis residual's fore-aft part 249 N RMS; 153 N with the physiological bound). Only a
    knee whose flexion is negative (gait2392's sign) and whose bound is narrower; the extension
    bound (10°, already past the 0–5° of a normal knee) is kept. A session whose knees never
    reach the model's bound solves the same IK. Applied after scaling and marker placement, whose
    IK passes keep the generic bounds (widened there, UWA fast walking's placement took another
    branch: knees to +9° of hyperextension)."""
    from msk.quality import PHYSIOLOGICAL_RANGES_DEG

    lo_phys = np.radians(PHYSIOLOGICAL_RANGES_DEG["knee_angle"][0])
    out: dict[str, tuple[float, float]] = {}
    for c in model.coordinates:
        stem = c.name[:-2] if c.name.endswith(("_r", "_l")) else c.name
        lo, hi = c.range
        if stem == "knee_angle" and -np.pi / 2 >= lo > lo_phys + 1e-9:
            out[c.name] = (float(lo_phys), float(hi))
    if not out:
        return model, {}
    return model.with_coordinate_ranges(out), {
        k: [float(np.degrees(v)) for v in r] for k, r in out.items()
    }


def _scale_and_place(
    inputs: SessionInputs,
    read: ReadResult,
    functional: Mapping[str, float] | None = None,
    placement: Mapping[str, Any] | None = None,
    continue_from: tuple[Any, Mapping[str, Any]] | None = None,
    workspace: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Scale the model and place the lab's markers (static trial, else the task). ``placement``:
    extra keywords of :func:`msk.scaling.place_markers_from_motion` (``regularize``,
    ``frame_phase``) when there is no static trial (a candidate of :func:`run`).
    ``continue_from`` (no static trial; an earlier motion placement: its model and
    ``info["marker_placement"]``): the placement is one unpulled pass continuing that one — its
    placed markers' state and its moved model markers' offsets — on the model scaled here
    (the split candidates of :func:`choose_placement`). ``workspace``: that of
    :func:`msk.scaling.scale_from_motion` (a new one when None; returned as ``"workspace"``),
    so that scaling the same trial again with a split reuses the pose-matched IK."""
    from msk.hip_centre import no_static_hip_centre, place_hip_centres
    from msk.io.c3d import is_measured_marker
    from msk.io.frames import pelvis_heading_rotation
    from msk.markersets import (
        foot_markers,
        recognise,
        shoulder_girdle_markers,
        zeros_as_gaps,
        zeros_as_gaps_view,
    )
    from msk.quality import inconsistent_static_markers
    from msk.scaling import (
        place_markers,
        place_markers_from_motion,
        scale_from_motion,
        scale_from_static,
    )

    cfg, trial, mc = inputs.cfg, read.trial, inputs.model_cfg
    assert mc is not None and inputs.model_source is not None  # a gait stage
    workspace = {} if workspace is None else workspace
    model = load_model_file(inputs.model_source, mc.markers)
    bodies = [b.name for b in model.bodies]
    info: dict[str, Any] = {"source": str(inputs.model_source), "generic_mass_kg": model.total_mass}
    x_lab = zeros_as_gaps_view(trial.markers)  # not copied unless it has zero samples
    match = recognise(
        trial.marker_labels, model.marker_names, rename=cfg.marker_rename,
        model_bodies=bodies, markers=x_lab,
    )  # fmt: skip
    up = -np.asarray(model.gravity, dtype=float)
    # the static trial, read once: its labels for the checks, its markers for scaling
    static_read = None if inputs.static is None else read_static_markers(inputs.static.file, up)
    labels_all = set(trial.marker_labels)
    if static_read is not None:
        labels_all |= set(static_read[1])
    # names in the configuration that match nothing are errors, not silently ignored (a lab
    # label absent from these trials is a note: rename tables of a protocol list variants a
    # given session may not use)
    absent = sorted(set(cfg.marker_rename.values()) - labels_all)
    unknown = sorted(set(cfg.marker_rename) - set(model.marker_names))
    if unknown:
        raise ConfigError(f"{cfg.path}: markers.rename: the model has no marker {unknown[0]!r}")
    info["marker_set"] = {
        "protocol": match.protocol,
        "matched": dict(match.rename),
        "excluded": dict(match.excluded),
        "notes": list(match.notes)
        + ([f"markers.rename: labels in no trial: {', '.join(absent)}"] if absent else []),
    }
    # heading: the progression where it agrees with the pelvis markers (within 30°), else the
    # pelvis markers (treadmill, turning, short trials), else none
    head = pelvis_heading_rotation(
        trial.up, up, x_lab, trial.marker_labels, model, rename=match.rename
    )
    rot, source = head.rotation, head.source
    prog = head.progression_yaw_deg
    if prog is not None and (
        head.source != "pelvis markers"
        or abs((head.yaw_deg - prog + 180.0) % 360.0 - 180.0) <= 30.0
    ):
        rot, source = lab_to_model_rotation(trial.up, up, trial.markers), "progression"
    info["heading"] = {
        "source": source,
        "pelvis_yaw_deg": head.yaw_deg if head.source == "pelvis markers" else None,
        "progression_yaw_deg": prog,
        "message": head.message,
    }
    report = None
    generic = model
    placement_call: tuple[Any, ...] | None = None
    # a static the task contradicts so much that it cannot be posed (another subject's, or
    # another labelling): the task's own markers scale and place, and the flag says so
    rejected: str | None = None
    if static_read is not None:
        sm, slabels_raw, stime, ssubj, window = static_read
        # the still, double-stance part of the static only (msk.static_window.still_window)
        sm, stime = sm[window.frames], stime[window.frames]
        info["static_window"] = window.summary()
        # the lab's joint widths (Plug-in Gait subject parameters): the static's, else the task's
        subj = ssubj if ssubj is not None and ssubj.widths_m else trial.subject
        widths = dict(getattr(subj, "widths_m", None) or {})
        mdiam = getattr(subj, "marker_diameter_m", None)
        smatch = recognise(
            slabels_raw, model.marker_names, rename=cfg.marker_rename,
            model_bodies=bodies, markers=zeros_as_gaps(sm),
        )  # fmt: skip
        # static labels the task contradicts (mislabelled, swapped, ghost): left out of the
        # static, placed from the task below (msk.quality.inconsistent_static_markers); not
        # checked: markers on no bone of the model (arms) and of the shoulder girdle
        skip = [*shoulder_girdle_markers(list(slabels_raw), bodies), *smatch.excluded,
                *(lab for lab in slabels_raw if not is_measured_marker(lab))]  # fmt: skip
        # rigid pairs over at least a step (0.5 s): over a shorter piece, markers of two
        # segments can keep their distance too (PiG_Motion3 cut to 0.25 s: RPSI "contradicted")
        t_task = np.asarray(trial.time, dtype=float)
        rate = (t_task.size - 1) / (t_task[-1] - t_task[0]) if t_task.size > 1 else 0.0
        bad = inconsistent_static_markers(
            zeros_as_gaps(sm), slabels_raw, x_lab, trial.marker_labels, skip=skip,
            min_frames=max(10, round(STATIC_CHECK_MIN_TASK_S * rate)),
        )  # fmt: skip
        if bad:  # removed from the static (as if the lab had not labelled them)
            kept = [i for i, lab in enumerate(slabels_raw) if lab not in bad]
            sm, slabels_raw = np.asarray(sm)[:, kept], tuple(slabels_raw[i] for i in kept)
        sm, slabels = smatch.apply(sm, slabels_raw)
        if mc.scale:
            static = {lab: sm[:, i] for i, lab in enumerate(slabels)}
            model, report = scale_from_static(
                model, static, height_m=cfg.subject.height_m, body_mass=cfg.subject.mass_kg,
                widths_m=widths, marker_diameter_m=mdiam, functional=functional,
            )  # fmt: skip
        model = _aligned(inputs, model, sm, slabels)
        model, info["hip_centre"] = place_hip_centres(
            model, sm, slabels, method=mc.hip_centre,
            marker_radius_m=0.007 if mdiam is None else 0.5 * float(mdiam),
        )  # fmt: skip
        centres, jc_move = _chord_centres(model, sm, slabels, widths, mdiam)
        try:
            model, placed = place_markers(
                model, sm, slabels, stime,
                move=[*cfg.marker_move, *(m for m in jc_move if m not in cfg.marker_move)],
                hints=smatch.body_hints([b.name for b in model.bodies]), centres=centres,
                coordinate_tasks={
                    **(held_foot_coordinates(model, sm, slabels) if centres else {}),
                    **held_static_knees(model, slabels_raw),
                } or None,
                relocate=[lab for lab in slabels if lab in model.marker_names],
            )  # fmt: skip
        except ModelError as exc:
            raise ConfigError(f"{cfg.path}: markers.move: {exc}") from None
        except KinematicsError as exc:
            if not bad:
                raise
            assert inputs.static is not None and inputs.task is not None
            rejected = (
                f"{inputs.static.file.name} cannot be posed without the markers "
                f"{inputs.task.file.name} contradicts ({', '.join(sorted(bad))}): not the same "
                f"subject or labelling? ({' '.join(str(exc).split())}); the model is scaled "
                "and its markers placed from the task instead"
            )
            model, report = generic, None
            info["static_rejected"] = rejected
            info.pop("static_window", None)
        if rejected is None:
            model, from_task, check, recon = _place_from_task(model, trial, rot, match, bad)
            placed["from_task"] = from_task
            placed["reconstructed_from_task"] = recon
            if check:
                info["static_check"] = check
    if static_read is None or rejected is not None:
        # no static trial: the task trial's own markers scale and place (the segment lengths
        # are constant over a motion; msk.scaling.scale_from_motion)
        xm, mlabels = model_frame_columns(trial, rot, match)
        # where the lab put its origin cannot matter: the markers are translated so that their
        # median sits at the generic model's markers' centroid in its default pose (the
        # inverse kinematics of scaling and placement start from that pose, and the pelvis
        # translations have bounds; scale factors and body-frame offsets are invariant)
        xm = xm - lab_origin_offset(model, xm)
        if mc.scale:
            model, report = scale_from_motion(
                model, xm, mlabels, trial.time, height_m=cfg.subject.height_m,
                body_mass=cfg.subject.mass_kg, functional=functional, workspace=workspace,
            )  # fmt: skip
        model = _aligned(inputs, model, xm, mlabels)
        info["hip_centre"] = no_static_hip_centre(mc.hip_centre)
        # the lab's foot markers: where they sit on the foot is the lab's choice and nothing
        # but the motion tells (msk.markersets.foot_markers), so they are moved too
        present = [mk.name for mk in model.markers if mk.name in set(mlabels)]
        feet = [m for m in foot_markers(present) if m not in cfg.marker_move]
        moved = [*cfg.marker_move, *feet]
        kw: dict[str, Any] = dict(
            move=moved, median_neutral=free_foot_coordinates(model, moved, present),
            hints=match.body_hints([b.name for b in model.bodies]),
        )  # fmt: skip
        placement_call = (model, xm, mlabels, trial.time, kw)
        if continue_from is None:
            model, placed = place_markers_from_motion(
                model, xm, mlabels, trial.time, **kw, **dict(placement or {}), warm={}
            )
        else:
            model, placed = continued_placement(placement_call, *continue_from)
    info["marker_placement"] = placed
    if model.metadata.get("knee_alignment"):
        info["knee_alignment"] = dict(model.metadata["knee_alignment"])
    if report is not None:
        info["scaling"] = report.summary()
        info["scale_ratios"] = dict(model.metadata.get("scale_ratios", {}))
    info["mass_kg"] = model.total_mass
    return {
        "model": model, "info": info, "rotation": rot, "rename": dict(match.rename),
        "placement_call": placement_call, "workspace": workspace,
    }  # fmt: skip


def continued_placement(
    call: tuple[Any, ...], prev_model: Any, prev: Mapping[str, Any]
) -> tuple[Any, dict[str, Any]]:
    """One pass of :func:`msk.scaling.place_markers_from_motion` pulled towards neutral
    (``call``: the model before placement, the markers, labels, time and keywords
    ``_scale_and_place`` placed with) continuing an earlier motion placement (``prev_model``
    and its ``info["marker_placement"]``, possibly on a model scaled otherwise): its placed
    markers' state and its moved model markers' offsets (on the same body) are the pass's
    start; ``"regularized"`` is the earlier one's. Pulled for the reason the pulled start is
    (the weak pull resolves the flat directions of the anatomical markers' IK): unpulled, the
    first pass on UWA fast walking's split model (femur × 1.02–1.04) with the leg factors
    × (1 − 1e-4) lost the thigh clusters (task IK 74.6 mm against 8.96 mm pulled; the
    descent that follows is unpulled)."""
    from msk.scaling import place_markers_from_motion

    base, xm, mlabels, time, kw = call
    was = {mk.name: mk for mk in prev_model.markers if mk.name in prev.get("moved", {})}
    own = [was[mk.name] if mk.name in was and was[mk.name].body == mk.body else mk
           for mk in base.markers]  # fmt: skip
    model, placed = place_markers_from_motion(
        base.with_markers(own), xm, mlabels, time, **kw, regularize=True, iterations=1,
        start=prev["state"],
    )  # fmt: skip
    return model, {**placed, "regularized": prev["regularized"]}


def lab_origin_offset(model: Any, markers: Any) -> np.ndarray:
    """(3,) m to subtract from a motion trial's markers (model frame) so that their median
    (over frames and markers, per axis) sits at the centroid of ``model``'s markers in its
    default pose: the trial then no longer depends on where the lab put its origin (the
    inverse kinematics of :func:`msk.scaling.scale_from_motion` and
    :func:`msk.scaling.place_markers_from_motion` start from the default pose and bound the
    pelvis translations). Zero when no marker is finite."""
    from msk.model import marker_positions

    x = np.asarray(markers, dtype=float)
    finite = np.isfinite(x).all(axis=-1)
    if not finite.any() or not model.markers:
        return np.zeros(3)
    med = np.median(x[finite], axis=0)
    pts = marker_positions(model, model.default_coordinates())[0]
    return np.asarray(med - pts.mean(axis=0), dtype=float)


def model_frame_columns(
    trial: Any, rot: np.ndarray, match: Any
) -> tuple[np.ndarray, tuple[str, ...]]:
    """``match.apply(trial.rotated(rot).markers, trial.marker_labels)`` (the matched columns in
    the model frame, model names, exact zeros as gaps) rotated block by block of
    :data:`msk.pipeline.blocks.FRAME_BLOCK` frames into the one array returned: a long trial's
    markers are not rotated whole first (issue 18). Each frame's values are the whole
    product's."""
    from msk.pipeline.blocks import FRAME_BLOCK

    x = np.asarray(trial.markers, dtype=float)
    r = np.asarray(rot, dtype=float)
    labels = trial.marker_labels
    n = x.shape[0]
    first, names = match.apply(x[:FRAME_BLOCK] @ r.T, labels)
    if n <= FRAME_BLOCK:
        return first, names
    out = np.empty((n, *first.shape[1:]))
    out[:FRAME_BLOCK] = first
    for c0 in range(FRAME_BLOCK, n, FRAME_BLOCK):
        out[c0 : c0 + FRAME_BLOCK] = match.apply(x[c0 : c0 + FRAME_BLOCK] @ r.T, labels)[0]
    return out, names


def _place_from_task(
    model: Any, trial: Any, rot: np.ndarray, match: Any, bad: Mapping[str, float]
) -> tuple[Any, dict[str, float], dict[str, Any], list[str]]:
    """After the static placement, the markers the static cannot place for the task, placed
    from the task (:func:`msk.scaling.place_markers_from_motion` on the task with the model's
    markers and these only):

    * shoulder-girdle markers of a model without that segment (gait2392's acromia on its rigid
      torso, :func:`msk.markersets.shoulder_girdle_markers`): the scapula follows the arms, so
      where the static (arms out) puts them is not where they ride in the task (UNIPD's acromia
      22–26 mm off through the walk when placed from its static, IK 17.5 → 16.3 mm); moved on
      their body to their median position in the task;
    * the static markers the task contradicts (``bad``: lab label → discrepancy m,
      :func:`msk.quality.inconsistent_static_markers`): a model marker moved on its body,
      another marker fixed to its most rigid body;
    * model markers the lab rebuilds from a technical cluster (calibrated anatomical landmarks,
      :func:`msk.markersets.reconstructed_markers`: rigid with another marker to < 0.1 mm
      through the task): they ride the cluster's soft tissue, which sits differently on the
      bone in a standing static and in the task, so they are moved on their body to their
      median position in the task (UNIPD's ASIS/PSIS, GT, epicondyles, HF, TT, malleoli:
      thigh landmarks 9 mm distal and 8–11 mm lateral in the femur frame through Walking1 when
      placed from Static1, IK 16.3 → 14.4 mm).

    Returns the model, marker → displacement (m) of the markers moved, the record for
    ``summary.json`` ``model.static_check`` (empty without ``bad``; its quality flag) and the
    reconstructed markers moved."""
    from msk.markersets import reconstructed_markers, shoulder_girdle_markers
    from msk.scaling import place_markers_from_motion

    xm, mlabels = model_frame_columns(trial, rot, match)
    to_model = dict(match.lab_to_model)
    bad_names = {to_model.get(lab, lab) for lab in bad}
    known = set(model.marker_names)
    girdle = set(shoulder_girdle_markers(list(mlabels), [b.name for b in model.bodies]))
    # landmarks the lab rebuilds from a cluster (rigid with it through the task): placed where
    # the task's reconstruction puts them (msk.markersets.reconstructed_markers)
    recon = {m for m in reconstructed_markers(xm, mlabels) if m in known} - bad_names
    if not bad_names and not recon and not girdle & known:
        return model, {}, {}, []
    keep = [i for i, lab in enumerate(mlabels) if lab not in mlabels[:i] and (
        lab in bad_names or lab in known)]  # fmt: skip
    moved = sorted(n for n in bad_names | recon if n in known)
    new_markers = any(n not in known for n in bad_names)
    xm = xm[:, keep]  # the task's other columns dropped before the placement's passes
    model, placed = place_markers_from_motion(
        model, xm, [mlabels[i] for i in keep], trial.time, move=moved,
        iterations=3 if new_markers else 1,
    )  # fmt: skip
    record = {}
    if bad:
        record = {
            "contradicted_m": dict(bad),
            "moved_from_task_m": {k: v for k, v in placed["moved"].items() if k in bad_names},
            "placed_from_task": {k: v for k, v in placed["placed"].items() if k in bad_names},
        }
    return model, dict(placed["moved"]), record, sorted(recon)


def _chord_centres(
    model: Any, sm: np.ndarray, labels: tuple[str, ...], widths: Mapping[str, float],
    mdiam: float | None,
) -> tuple[dict[str, tuple[str, np.ndarray, np.ndarray]], list[str]]:  # fmt: skip
    """The static pose of a lateral-marker protocol (no medial knee marker) as Plug-in Gait
    defines it (Davis et al. 1991): virtual markers for :func:`msk.scaling.place_markers` at the
    knee and ankle centres of the chord function (:func:`msk.scaling.static_joint_centres`;
    the tibia's and the talus' origins) and the lateral knee marker on the knee flexion axis
    at r = (knee width + marker diameter)/2 from the knee centre; the lateral knee and ankle
    markers are then placed (moved) where the static puts them, not held at the generic
    model's offsets (which differ from the subject's measured widths by 10–20 mm).
    Returns (virtual markers, markers to move)."""
    from msk.markersets import parse_label
    from msk.scaling import static_joint_centres

    if not widths:
        return {}, []
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        means = {lab: np.nanmean(sm[:, i], axis=0) for i, lab in enumerate(labels)}
    md = 0.014 if mdiam is None else float(mdiam)
    out: dict[str, tuple[str, np.ndarray, np.ndarray]] = {}
    move: list[str] = []
    pts_of = static_joint_centres(model, means, widths_m=widths, marker_diameter_m=mdiam)
    for side, pts in pts_of.items():
        p = side.upper()
        knee_lat, ankle_lat = f"{p}.Knee.Lat", f"{p}.Ankle.Lat"
        if f"{p}.Knee.Med" in means or knee_lat not in means or f"{p}.knee" not in widths:
            continue  # epicondyles: the model's own knee markers place the knee
        tibia = f"tibia_{side}"
        axis = _revolute_axis(model, tibia)
        lat = next((mk.offset for mk in model.markers if mk.name == knee_lat), None)
        if axis is None or lat is None:
            continue
        # the flexion axis, pointing to the lateral side (the generic lateral knee marker's)
        knee_in_tibia = np.asarray(lat, dtype=float)  # femur frame ≈ tibia frame at θ = 0
        axis = axis if float(np.dot(axis, knee_in_tibia)) >= 0.0 else -axis
        r = 0.5 * (widths[f"{p}.knee"] + md)
        out[f"{p}.hip_centre"] = (f"femur_{side}", np.zeros(3), pts["hip"])
        out[f"{p}.knee_centre"] = (tibia, np.zeros(3), pts["knee"])
        out[f"{p}.ankle_centre"] = (f"talus_{side}", np.zeros(3), pts["ankle"])
        out[f"{p}.knee_axis"] = (tibia, r * axis, means[knee_lat])
        move += [m for m in (knee_lat, ankle_lat) if m in model.marker_names]
    # the pelvis pose the hip centres came from: the mid-PSIS as the sacral marker (IOR, PiG)
    psis = [lab for lab in means if parse_label(lab).landmark == "psis"]
    sacral = [mk for mk in model.markers if mk.body == "pelvis"
              and parse_label(mk.name).landmark == "sacrum"]  # fmt: skip
    if out and len(psis) == 2 and len(sacral) == 1 and sacral[0].name not in means:
        mid = 0.5 * (means[psis[0]] + means[psis[1]])
        out[f"{sacral[0].name}:mid_psis"] = ("pelvis", np.asarray(sacral[0].offset, float), mid)
    return out, move


def _revolute_axis(model: Any, body: str) -> np.ndarray | None:
    """Unit axis (in ``body``'s frame) of the revolute axis of the joint whose child is
    ``body`` (the knee's flexion axis for a tibia), None without one."""
    for j in model.joints:
        if j.child != body:
            continue
        for ax in j.axes:
            if ax.kind == "revolute":
                v = np.asarray(j.child_offset.rotation, dtype=float) @ np.asarray(ax.axis, float)
                return v / np.linalg.norm(v)
    return None


def free_foot_coordinates(
    model: Any, moved: Sequence[str], present: Sequence[str] | None = None
) -> tuple[str, ...]:
    """Foot coordinates (subtalar, MTP) whose offset a placement from the motion leaves free:
    every model marker distal to the joint that the trial has (``present``; None: every model
    marker) is moved (:func:`msk.scaling.place_markers_from_motion`, ``median_neutral``), and
    there is at least one. A generic marker the trial lacks observes nothing."""
    body_of = {m.name: m.body for m in model.markers}
    out: list[str] = []
    for name, sub in _foot_joints(model):
        distal = [m for m, b in body_of.items() if b in sub and (present is None or m in present)]
        if distal and set(distal) <= set(moved):
            out.append(name)
    return tuple(out)


def _foot_joints(model: Any) -> list[tuple[str, set[str]]]:
    """gait2392's foot coordinates (subtalar, MTP; both sides) the model has, each with the
    bodies distal to its joint."""
    out = []
    for sfx in ("_r", "_l"):
        for coord, child in (("subtalar_angle", "calcn"), ("mtp_angle", "toes")):
            name, body = coord + sfx, child + sfx
            if name in model.coordinate_names and body in model.body_joint:
                out.append((name, set(model.subtree(body))))
    return out


def held_foot_coordinates(
    model: Any, markers: np.ndarray, labels: tuple[str, ...]
) -> dict[str, tuple[float, float]]:
    """Foot joints the markers cannot observe (fewer than 3 markers on the bodies distal to the
    joint: e.g. Plug-in Gait's heel + toe), held near neutral by an IK coordinate task
    (OpenSim's IKCoordinateTask) instead of wandering to −75°. A marker counts when the trial
    tracks it in at least half of the frames the IK solves (those that see
    :data:`msk.pipeline.kinematics.MIN_MARKER_FRACTION` of the most model markers any frame
    sees: metatarsal-head markers lost in most of them do not observe the subtalar). Not the
    frames that track anything: a running trial's unlabelled trajectories (``*33``…) and
    acromia outlast its feet's markers by 150 frames, and the right subtalar of UWA's
    ``Running_1``, whose metatarsal heads are tracked in 93 % of the solved frames, was held
    (issue 15, twelfth pass)."""
    from msk.pipeline.kinematics import MIN_MARKER_FRACTION

    vis = np.isfinite(markers).all(axis=2)
    on_model = np.array([lab in set(model.marker_names) for lab in labels], dtype=bool)
    count = vis[:, on_model].sum(axis=1)
    solved = count >= max(3, MIN_MARKER_FRACTION * count.max()) if count.size else count > 0
    frac = vis[solved].mean(axis=0) if solved.any() else np.zeros(len(labels))
    seen = {
        lab for k, lab in enumerate(labels) if lab in model.marker_names and frac[k] >= 0.5
    }  # fmt: skip
    body_of = {m.name: m.body for m in model.markers}
    return {
        name: (0.0, HELD_COORDINATE_WEIGHT)
        for name, sub in _foot_joints(model)
        if sum(body_of.get(m) in sub for m in seen) < 3
    }


def held_static_knees(model: Any, labels: tuple[str, ...]) -> dict[str, tuple[float, float]]:
    """Knee flexion a static trial's markers cannot observe, held at 0 rad (the anatomical
    standing pose a static is recorded in) by an IK coordinate task in the static pose θ̄ of
    the marker placement (:func:`msk.scaling.place_markers`).

    A side's knee flexion is observed when the static has a femoral epicondyle and a malleolus
    marker of that side (with the pelvis' hip centre: the thigh's and the shank's long axes;
    :func:`msk.markersets.parse_label`). Without them (thigh and shank clusters only: the
    Grand Challenge's JW) θ̄ puts the knee wherever the generic model's cluster offsets fit,
    and every cluster marker placed from that pose carries the error into the motion:
    ``jw_1legstand1`` posed 9.6° hyperextended by its clusters where JW's knee goniometer reads
    5.4° of flexion. Weight :data:`HELD_COORDINATE_WEIGHT`."""
    from msk.markersets import parse_label

    seen = {(p.side, p.landmark) for p in map(parse_label, labels) if p.side and p.landmark}
    held: dict[str, tuple[float, float]] = {}
    for side in ("R", "L"):
        name = f"knee_angle_{side.lower()}"
        knee = {(side, "knee_lat"), (side, "knee_med")} & seen
        ankle = {(side, "ankle_lat"), (side, "ankle_med")} & seen
        if name in model.coordinate_names and not (knee and ankle):
            held[name] = (0.0, HELD_COORDINATE_WEIGHT)
    return held


def _swap_back(read: ReadResult) -> tuple[ReadResult, dict[str, float]]:
    """The task trial with the columns of left/right label pairs that its markers show swapped
    exchanged back (:func:`msk.quality.swapped_label_pairs`: the right-side marker ≥ 3 cm to
    the subject's left in ≥ 80 % of the frames, judged from the pelvis markers, before any
    model sees them), and "right/left" → median signed separation (m) of each pair exchanged
    (``summary.json`` ``model.marker_set.swapped_back``; a quality flag says so)."""
    from msk.markersets import zeros_as_gaps_view
    from msk.quality import swapped_label_pairs

    trial = read.trial
    pairs = swapped_label_pairs(zeros_as_gaps_view(trial.markers), trial.marker_labels, trial.up)
    if not pairs:
        return read, {}
    markers = np.array(trial.markers, dtype=float, copy=True)
    labels = list(trial.marker_labels)
    for r, lft, _ in pairs:
        i, j = labels.index(r), labels.index(lft)
        markers[:, [i, j]] = markers[:, [j, i]]
    fixed = dataclasses.replace(trial, markers=markers)
    return dataclasses.replace(read, trial=fixed), {f"{r}/{lft}": dz for r, lft, dz in pairs}


def leg_split(inputs: SessionInputs, trial: Any, built: Mapping[str, Any]) -> dict[str, Any] | None:
    """The femur : tibia split of each leg scaled by one pelvis-to-heel factor (no knee or
    ankle marker: ``leg_<side>`` among the scaling ratios), from the functional knee and ankle
    centres of the task trial's thigh, shank and calcaneus markers
    (:func:`msk.leg_split.functional_leg_split`) on the model as first scaled and placed
    (``built``); None when no leg was scaled that way. The model stage scales and places again
    with the sides it determines, keeps that model when the lab's markers fit it no worse (the
    placement's marker RMS, :func:`_placement_rms`; else every side keeps its leg factor, and
    says why) and reports every side in ``summary.json`` ``model.leg_split``. A leg the
    scaling reports as not determined by the motion (the stature's leg of a run,
    :func:`msk.scaling.unobserved_leg_starts`) is split by the functional knee and ankle
    (``use_ankle``) where its checks pass."""
    from msk.leg_split import functional_leg_split
    from msk.markersets import zeros_as_gaps

    mc = inputs.model_cfg
    ratios = dict(built["info"].get("scaling", {}).get("ratios", {}))
    legs = {s: float(ratios[f"leg_{s}"]) for s in ("r", "l") if f"leg_{s}" in ratios}
    if mc is None or not mc.scale or not legs:
        return None
    model, rot = built["model"], np.asarray(built["rotation"], dtype=float)
    x = zeros_as_gaps(np.asarray(trial.markers, dtype=float) @ rot.T)
    inv = {v: k for k, v in built["rename"].items()}
    labels = tuple(inv.get(lab, lab) for lab in trial.marker_labels)
    # the markers on each body: the model's, those placed and those placed but too loose for
    # IK (a cluster is posed by its own shape: its markers need only be rigid with each other)
    placed = built["info"].get("marker_placement", {})
    segments: dict[str, list[str]] = {}
    for mk in model.markers:
        segments.setdefault(mk.body, []).append(mk.name)
    for lab, (body, _) in dict(placed.get("too_loose", {})).items():
        segments.setdefault(body, []).append(lab)
    # a leg whose length the motion did not determine (the stature's: msk.scaling.
    # unobserved_leg_starts) has its tibia from the functional ankle, where the checks find it
    # determined — the clusters' only measurement of it — rather than as the rest of a leg the
    # markers did not measure (issue 15, thirteenth pass)
    starts = dict(built["info"].get("scaling", {}).get("leg_starts", {}))
    free = {s: f for s, f in legs.items() if starts.get(f"leg_{s}", {}).get("determined") is False}
    out: dict[str, Any] = {}
    for use_ankle in (False, True):
        sides = {s: f for s, f in legs.items() if (s in free) == use_ankle}
        if sides:
            out.update(
                functional_leg_split(
                    model, x, labels, sides, segments=segments, use_ankle=use_ankle
                )
            )
    return {s: out[s] for s in legs}


def _placement_rms(info: Mapping[str, Any]) -> float:
    """The marker placement's marker RMS (m): the static's IK (``static_marker_rms_m``) or the
    motion's last pass (``ik_marker_rms_m``, median over its frames); NaN without one."""
    mp = dict(info.get("marker_placement", {}))
    v = mp.get("static_marker_rms_m", mp.get("ik_marker_rms_m"))
    return float("nan") if v is None else float(v)


def without_markers(model: BuiltModel) -> BuiltModel:
    """``model`` without the task's model-frame markers (``trial.markers`` a ``(N, 0, 3)``
    array; the labels, gaps, events, time and metadata kept): the kinematics stage and the
    step ``swapped_markers`` are the last to read them, and
    :func:`msk.pipeline.graph.run_graph` drops them after that step (a long trial's markers,
    1.2 kB/frame with 51 markers, are not held through the tail; issue 18)."""
    trial = model.trial
    empty = np.zeros((int(np.shape(trial.markers)[0]), 0, 3))
    return dataclasses.replace(model, trial=dataclasses.replace(trial, markers=empty))


#: relative decrease of the task's IK cost per round below which :func:`choose_placement`
#: stops its descents: 2 % is 0.14–0.3 mm on the shipped walks (7–15 mm), as much as the
#: candidates' costs move under ``scripts/placement_jitter.py``'s perturbations (0.15 mm,
#: tenth pass) and under :data:`CHOICE_TOLERANCE_M` — a smaller gain is not one the choice
#: can tell from those perturbations (the tenth pass's absolute 0.01 mm left DM og1 at its
#: 12-round cap, still falling by 0.06 mm per round)
DESCENT_REL_TOLERANCE = 2e-2

#: most rounds of a descent of :func:`choose_placement` (a safeguard, not the stopping rule)
DESCENT_MAX_ROUNDS = 30

#: how much worse (m) than the least task IK cost a candidate of :func:`choose_placement` may be
#: and still be preferred (the split before the leg factor, the pulled start before the other):
#: the candidates' costs move by up to 0.15 mm under ``scripts/placement_jitter.py``'s
#: perturbations (DM og1), so that a choice by the bare minimum between candidates closer than
#: that flipped the femur and tibia factors from run to run
CHOICE_TOLERANCE_M = 0.0002

#: most task frames the choice among motion placements is judged on (:func:`choose_placement`,
#: :func:`placement_frames`): interleaved evenly over the trial's well-tracked frames
CHOICE_MAX_FRAMES = 120

#: a frame is well tracked (:func:`placement_frames`) when it misses at most this many more
#: markers than the best-tracked frame
CHOICE_MISSING_MARKERS = 2


def placement_frames(markers: Any, max_frames: int = CHOICE_MAX_FRAMES) -> np.ndarray:
    """Indices of at most ``max_frames`` frames of ``markers`` ((N, M, 3), NaN or exact zeros
    for gaps), interleaved evenly over the trial's well-tracked frames — those missing at most
    :data:`CHOICE_MISSING_MARKERS` more markers than the best-tracked frame, widened to the
    ``max_frames`` best-tracked when fewer — so that the frames span every phase of the gait
    cycles the trial holds and no marker's drop-out weighs on the choice. Deterministic:
    every candidate of :func:`choose_placement` is judged on the same frames."""
    x = np.asarray(markers)
    n = x.shape[0]
    if n == 0:
        return np.zeros(0, dtype=int)
    seen = (np.isfinite(x).all(axis=-1) & (x != 0.0).any(axis=-1)).sum(axis=1)
    m = min(max_frames, n)
    k = min(int(seen.max()) - CHOICE_MISSING_MARKERS, int(np.sort(seen)[-m]))
    well = np.flatnonzero(seen >= k)
    return well[np.round(np.linspace(0, well.size - 1, m)).astype(int)]


def placement_fit(
    model: Any, x: np.ndarray, time: np.ndarray, labels: Sequence[str],
    weights: Mapping[str, float], markers: Sequence[str],
    loose: Mapping[str, tuple[str, Sequence[float]]] | None = None,
    initial_q: np.ndarray | None = None,
) -> tuple[np.ndarray, float]:  # fmt: skip
    """The task's inverse kinematics of a placed model on the frames ``x`` (model frame) and
    its cost (m): the kinematics stage's IK (:func:`msk.pipeline.kinematics.solve_trial`: the
    configured marker weights, the held foot coordinates, physiological knee ranges; no filter;
    ``initial_q`` its warm start), then the weighted RMS over ``markers`` of each frame's
    distances, averaged over the frames — the quantity the task's IK minimises, on one marker
    set for every candidate compared. A marker of ``markers`` the model does not carry (left
    out as too loose: ``loose``, name → (body, offset)) is measured at the pose the others
    give, so that dropping a marker does not lower the cost by itself. Returns the poses
    (``q_raw``, NaN rows for frames not solved) and the cost (inf when nothing is solved)."""
    from types import SimpleNamespace

    from msk.model import Marker, frame_placements
    from msk.pipeline.kinematics import solve_trial

    final, _ = knee_flexion_to_physiological(model)
    held = held_foot_coordinates(final, x, tuple(labels))
    kin = solve_trial(
        final, SimpleNamespace(markers=x, time=time), tuple(labels), weights=weights,
        held=held, cutoff_hz=None, initial_q=initial_q,
    )  # fmt: skip
    extra = [Marker(k, b, np.asarray(o, dtype=float)) for k, (b, o) in (loose or {}).items()
             if k not in set(final.marker_names)]  # fmt: skip
    scored = final.with_markers([*final.markers, *extra]) if extra else final
    names = list(scored.marker_names)
    use = [m for m in markers if m in names and m in labels]
    q = np.asarray(kin.q_raw, dtype=float)
    ok = np.isfinite(q).all(axis=1)
    if not use or not ok.any():
        return q, float("inf")
    _, pos = frame_placements(scored, q[ok], [scored.marker_frame[m] for m in use])
    meas = x[ok][:, [list(labels).index(m) for m in use]]
    d2 = ((pos - meas) ** 2).sum(axis=2)
    w = np.array([float(weights.get(m, 1.0)) for m in use])[None, :] * np.isfinite(d2)
    den = w.sum(axis=1)
    fine = den > 0
    per_frame = np.sqrt(np.where(w > 0, np.nan_to_num(d2) * w, 0.0)[fine].sum(axis=1) / den[fine])
    return q, float(per_frame.mean()) if per_frame.size else float("inf")


def placement_cost(
    model: Any, x: np.ndarray, time: np.ndarray, labels: Sequence[str],
    weights: Mapping[str, float], markers: Sequence[str],
    loose: Mapping[str, tuple[str, Sequence[float]]] | None = None,
) -> float:  # fmt: skip
    """The task's inverse kinematics cost of a placed model (m): :func:`placement_fit`'s."""
    return placement_fit(model, x, time, labels, weights, markers, loose)[1]


def choose_placement(
    inputs: SessionInputs, read: ReadResult, built: Mapping[str, Any],
    split_of: Callable[[Mapping[str, Any]], Mapping[str, float] | None] | None = None,
) -> tuple[dict[str, Any], dict[str, Any]]:  # fmt: skip
    """The motion placement (no static trial) of least task IK cost (:func:`placement_cost`,
    one objective on one marker set and the same frames — :func:`placement_frames`, at most
    :data:`CHOICE_MAX_FRAMES` — for every candidate) among a fixed set: the placement as it
    was (``built``: plain, pulled when plain is worse than
    :data:`msk.scaling.PLACEMENT_RETRY_RMS_M`) and the placement pulled towards neutral
    (``regularize=True`` of :func:`msk.scaling.place_markers_from_motion`, on the model
    ``built`` was scaled to; the same placement when ``built`` was itself pulled), each
    continued by :func:`msk.scaling.refine_placement_from_motion` (rounds of squared
    extrapolation of the passes, while a round lowers the cost by more than
    :data:`DESCENT_REL_TOLERANCE` of itself, at most :data:`DESCENT_MAX_ROUNDS` rounds); then,
    when ``split_of`` gives femur and tibia factors for the best of these (the functional leg
    split, :func:`leg_split`), each of the two descended placements continued on the model
    scaled with them (:func:`continued_placement`, then descended the same way) and the split
    model placed anew, pulled towards neutral (descended too). The candidates are then judged
    on every marker any of them places. The first candidate in order of preference — the split
    before the leg factor; the pulled start, then the other, then the split placed anew —
    within :data:`CHOICE_TOLERANCE_M` of the least cost is kept.

    Issue 15, thirteenth pass: the split placed anew and the wider marker set, because the
    continued split placements keep the clusters an unsplit placement lost (UWA running with
    its legs at the stature's length: the left thigh and shank clusters 55–62 mm loose, judged
    on the unsplit starts' markers only, without them, at a lower cost).

    Issue 15, eleventh pass: the split candidates continue the unsplit descents instead of
    starting again from the generic offsets (the femur and tibia change by a few per cent, the
    offsets by millimetres: 1–2 rounds instead of 6–12), the pulled start reuses the scaling,
    and the descents are accelerated — DM og1's model stage 10.5 → ~4 s (docs/validation.md).

    Why. The placement passes are a fixed-point iteration with several basins: which one a run
    landed in moved with perturbations no physical argument can care about (markers + 0.1 mm
    noise, one frame less, leg factors × (1 ± 1e-4): DM og1's task IK 8.5–9.5 mm, UWA fast
    walking's 9.2–10.8 mm; ``scripts/placement_jitter.py``), and so did the plain/pulled and
    split/no-split choices made on the placement's own RMS, and the split's factors measured on
    that placement. The pulled start is unique (the pull resolves the flat directions of the
    anatomical markers' IK) and the descent from it ends where the markers alone put the
    placement; the split is measured on the best of the descended placements. The placement as
    it was is a candidate, so by this objective the choice is never worse than the route
    before it by more than :data:`CHOICE_TOLERANCE_M`.

    Returns the chosen ``_scale_and_place`` result and the record of the choice
    (``summary.json`` ``model.placement_choice``)."""
    from msk.scaling import place_markers_from_motion, refine_placement_from_motion

    x, t, labels = _choice_frames(read.trial, built)
    weights = dict(inputs.cfg.marker_weights)

    def starts() -> list[tuple[dict[str, Any], dict[str, Any]]]:
        # the pulled start places on the model the start as before was scaled to (scaling does
        # not depend on the placement): the scaling is not run twice
        base, xm, mlabels, time, kw = built["placement_call"]
        if built["info"]["marker_placement"]["regularized"] is True:  # the route before pulled
            pulled = built["model"], built["info"]["marker_placement"]
        else:
            pulled = place_markers_from_motion(
                base, xm, mlabels, time, **kw, regularize=True, warm={}
            )
        info = {**built["info"], "marker_placement": pulled[1]}
        return [
            ({"leg_split": False, "start": "as before"}, dict(built)),
            ({"leg_split": False, "start": "pulled"},
             {**built, "model": pulled[0], "info": info}),
        ]  # fmt: skip

    def split_starts(f: Mapping[str, float]) -> list[tuple[dict[str, Any], dict[str, Any]]]:
        # each start's descended placement continued on the split model (scaled once): the
        # femur and tibia change by a few per cent, the markers' offsets by millimetres
        prev = [(r["model"], r["info"]["marker_placement"]) for r in results[:2]]
        split = _scale_and_place(
            inputs, read, f, continue_from=prev[0], workspace=built.get("workspace")
        )
        if prev[1][1] is prev[0][1]:  # the two starts were one (a pulled route before)
            model, placed = split["model"], split["info"]["marker_placement"]
        else:
            model, placed = continued_placement(split["placement_call"], *prev[1])
        # and the split model placed anew, pulled towards neutral (unique, as the pulled start):
        # a continued placement keeps clusters the unsplit model had lost (UWA running, left
        # leg at the stature's length: thigh and shank clusters 55–62 mm loose, continued on
        # the split model as they were; issue 15, thirteenth pass)
        base, xm, mlabels, time, kw = split["placement_call"]
        anew = place_markers_from_motion(base, xm, mlabels, time, **kw, regularize=True, warm={})
        return [
            ({"leg_split": True, "start": "as before"}, split),
            ({"leg_split": True, "start": "pulled"}, {**split, "model": model,
             "info": {**split["info"], "marker_placement": placed}}),
            ({"leg_split": True, "start": "pulled anew"}, {**split, "model": anew[0],
             "info": {**split["info"], "marker_placement": anew[1]}}),
        ]  # fmt: skip

    first = starts()
    # one marker set for all: every marker the two starts place, the model's own included (a
    # candidate that leaves one out as too loose is measured on it at its pose)
    union = set().union(*(set(c["model"].marker_names) for _, c in first))
    markers = sorted(union & set(labels))

    def cost(model: Any, mp: Mapping[str, Any]) -> float:
        state = dict(mp.get("state", {}))
        loose = {k: (str(state[k][0]), state[k][2]) for k in mp.get("too_loose", {}) if k in state}
        return placement_cost(model, x, t, labels, weights, markers, loose)

    records: list[dict[str, Any]] = []
    results: list[dict[str, Any]] = []

    def descend(cands: list[tuple[dict[str, Any], dict[str, Any]]]) -> None:
        done: list[tuple[Any, dict[str, Any]]] = []  # (start placement, descended result)
        for spec, c in cands:
            mp = c["info"]["marker_placement"]
            same = [r for m, r in done if m is mp]  # the same start (a pulled route before)
            if same:
                got_model, got = same[0]["model"], same[0]["info"]["marker_placement"]
            else:
                base, xm, mlabels, time, kw = c["placement_call"]
                got_model, got = refine_placement_from_motion(
                    base, xm, mlabels, time, (c["model"], mp), cost,
                    max_rounds=DESCENT_MAX_ROUNDS, rel_tolerance=DESCENT_REL_TOLERANCE, **kw,
                )  # fmt: skip
            path = got["descent_cost_m"]
            results.append({**c, "model": got_model,
                            "info": {**c["info"], "marker_placement": got}})  # fmt: skip
            done.append((mp, results[-1]))
            records.append({**spec, "cost_m": path[-1], "rounds": len(path) - 1,
                            "stop": got["descent_stop"]})  # fmt: skip

    def pick() -> int:
        costs = [r["cost_m"] for r in records]
        rank = {"pulled": 0, "as before": 1, "pulled anew": 2}
        order = sorted(range(len(records)), key=lambda i: (
            not records[i]["leg_split"], rank[records[i]["start"]]))  # fmt: skip
        return next(i for i in order if costs[i] <= min(costs) + CHOICE_TOLERANCE_M)

    descend(first)
    functional = split_of(results[pick()]) if split_of is not None else None
    if functional:
        descend(split_starts(functional))
    # judged on every marker any candidate places: a marker the unsplit starts left out as too
    # loose that a split candidate places again counts for all (measured at its pose where a
    # candidate left it out), so that losing a cluster does not lower a candidate's cost
    every = set().union(*(set(r["model"].marker_names) for r in results)) & set(labels)
    if every - set(markers):
        markers[:] = sorted(every)
        for rec, res in zip(records, results):
            rec["descent_cost_m"] = rec["cost_m"]
            rec["cost_m"] = cost(res["model"], res["info"]["marker_placement"])
    best = pick()
    record = {
        "objective": "task IK (weights, held feet, no filter): weighted marker RMS over every "
        "marker a candidate places, mean over frames",
        "frames": int(t.size),
        "candidates": records,
        "chosen": best,
    }
    return results[best], record


def _choice_frames(
    trial: Any, built: Mapping[str, Any]
) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """The frames the choice among motion placements is judged on (:func:`placement_frames`)
    in the model frame (exact zeros as gaps), their times and the labels in model names."""
    from msk.markersets import zeros_as_gaps

    idx = placement_frames(trial.markers)
    rot = np.asarray(built["rotation"], dtype=float)
    x = zeros_as_gaps(np.asarray(trial.markers, dtype=float)[idx] @ rot.T)
    t = np.asarray(trial.time, dtype=float)[idx]
    inv = {v: k for k, v in built["rename"].items()}
    return x, t, tuple(inv.get(lab, lab) for lab in trial.marker_labels)


def sole_level(inputs: SessionInputs, read: ReadResult, built: dict[str, Any]) -> dict[str, Any]:
    """The chosen motion placement (no static trial; ``built``) with each ankle's gauge set by
    the prior "sole level at foot flat" (:func:`msk.sole_level.level_sole_gauge`: the foot-flat
    frames of the whole task, fitted as :func:`placement_fit` fits the choice's frames; the
    free markers those the placement placed or moved) — ``built`` with its model replaced and
    ``summary.json`` ``model.sole_level`` (ankle coordinate → what was done or why not)."""
    from msk.markersets import zeros_as_gaps
    from msk.sole_level import level_sole_gauge

    trial = read.trial
    rot = np.asarray(built["rotation"], dtype=float)
    x = zeros_as_gaps(np.asarray(trial.markers, dtype=float) @ rot.T)
    t = np.asarray(trial.time, dtype=float)
    inv = {v: k for k, v in built["rename"].items()}
    labels = tuple(inv.get(lab, lab) for lab in trial.marker_labels)
    weights = dict(inputs.cfg.marker_weights)
    markers = sorted(set(built["model"].marker_names) & set(labels))
    mp = dict(built["info"].get("marker_placement", {}))
    free = [*dict(mp.get("moved", {})), *dict(mp.get("placed", {}))]

    # the foot-flat frames fitted among the choice's (placement_frames: spread over the whole
    # trial), in time order: the IK carries each frame's pose to the next, and the foot-flat
    # frames alone, a stance apart, start cold (DM crouch: 59–87 mm, the knees 7–11° off)
    spread = placement_frames(trial.markers)

    def fit(m: Any, frames: np.ndarray) -> tuple[np.ndarray, float]:
        every = np.union1d(spread, frames)
        q, cost = placement_fit(m, x[every], t[every], labels, weights, markers)
        return q[np.searchsorted(every, frames)], cost

    model, sides = level_sole_gauge(built["model"], x, labels, t, fit, free)
    built["info"]["sole_level"] = {s.coordinate: s.summary() for s in sides}
    return {**built, "model": model}


def placement_determinacy(
    inputs: SessionInputs, read: ReadResult, built: Mapping[str, Any]
) -> dict[str, Any]:
    """What the chosen motion placement (no static trial; ``built``) leaves undetermined:
    :func:`msk.determinacy.placement_profile` of its leg coordinates on the choice's frames
    (:func:`placement_frames`), fitted as :func:`placement_fit` fits them on the markers the
    model carries, the free markers those the placement placed or moved, the cost's resolution
    :data:`CHOICE_TOLERANCE_M` (a cost change the choice itself does not tell from a tie) —
    ``summary.json`` ``model.placement_determinacy`` (its quality flag:
    :func:`msk.quality.model_flags`); ``{"not_run": why}`` when the frames cannot be fitted."""
    from msk.determinacy import placement_profile

    x, t, labels = _choice_frames(read.trial, built)
    weights = dict(inputs.cfg.marker_weights)
    model = built["model"]
    mp = dict(built["info"].get("marker_placement", {}))
    markers = sorted(set(model.marker_names) & set(labels))
    seen = np.isfinite(x).all(axis=-1).any(axis=0)
    observed = [lab for k, lab in enumerate(labels) if seen[k]]

    def fit(m: Any, q0: np.ndarray | None) -> tuple[np.ndarray, float]:
        return placement_fit(m, x, t, labels, weights, markers, initial_q=q0)

    free = [*dict(mp.get("moved", {})), *dict(mp.get("placed", {}))]
    priors = {c: str(v["prior"]) for c, v in dict(built["info"].get("sole_level", {})).items()
              if v.get("status") == "prior"}  # fmt: skip
    try:
        profile = placement_profile(model, fit, free, observed, tolerance_m=CHOICE_TOLERANCE_M)
    except ModelError as exc:  # reported (and flagged), not a failed model stage
        return {"not_run": str(exc)}
    return profile.summary(priors)


def _functional(split: Mapping[str, Any]) -> dict[str, float]:
    """The femur and tibia factors of the sides ``split`` scales by the functional knee."""
    return {
        f"{b}_{side}": f
        for side, sp in split.items() if sp.method != "leg factor"
        for b, f in (("femur", sp.femur_factor), ("tibia", sp.tibia_factor))
    }  # fmt: skip


def _split_refused(split: Mapping[str, Any], note: str) -> dict[str, Any]:
    """Every side of ``split`` back to its leg factor, ``note`` saying why."""
    return {
        side: sp if sp.method == "leg factor" else dataclasses.replace(
            sp, method="leg factor", reason=f"{sp.method}: {note}",
            femur_factor=sp.leg_factor, tibia_factor=sp.leg_factor,
        )
        for side, sp in split.items()
    }  # fmt: skip


def run(inputs: SessionInputs, read: ReadResult) -> BuiltModel:

    cfg = inputs.cfg
    read, swapped = _swap_back(read)
    sacrum = None
    if inputs.static is None and inputs.model_source is not None and inputs.model_cfg:
        # no static: the PSIS midpoint stands for a missing sacral marker (msk.virtual_markers)
        from msk.virtual_markers import with_virtual_sacrum

        vtrial, sacrum = with_virtual_sacrum(
            read.trial, load_model_file(inputs.model_source, inputs.model_cfg.markers)
        )
        read = dataclasses.replace(read, trial=vtrial)
    trial = read.trial
    built = _scale_and_place(inputs, read)
    if sacrum is not None:
        built["info"]["virtual_markers"] = [sacrum]
    split: Mapping[str, Any] | None = None
    if "regularized" in built["info"].get("marker_placement", {}):
        # no static trial: the placement of least task IK cost among fixed candidates, the
        # leg split measured on the best unsplit one (choose_placement)
        measured: dict[str, Any] = {}

        def split_of(b: Mapping[str, Any]) -> dict[str, float] | None:
            measured["split"] = sp = leg_split(inputs, trial, b)
            return (_functional(sp) or None) if sp is not None else None

        built, choice = choose_placement(inputs, read, built, split_of)
        built["info"]["placement_choice"] = choice
        # the ankles' gauge (every foot marker moved: the markers leave their means free) set
        # by the prior "sole level at foot flat" (msk.sole_level)
        built = sole_level(inputs, read, built)
        built["info"]["placement_determinacy"] = placement_determinacy(inputs, read, built)
        split = measured.get("split")
        chosen = choice["candidates"][choice["chosen"]]
        if split is not None and _functional(split) and not chosen["leg_split"]:
            c_split = min(c["cost_m"] for c in choice["candidates"] if c["leg_split"])
            split = _split_refused(split, (
                f"the task's markers fit the split model worse (task IK "
                f"{1000 * chosen['cost_m']:.2f} → {1000 * c_split:.2f} mm at best): leg "
                "factor kept"
            ))  # fmt: skip
    else:
        split = leg_split(inputs, trial, built)
        functional = _functional(split) if split is not None else {}
        if split is not None and functional:
            # kept when the lab's markers fit the split model no worse than the leg-factor one
            # (the placement's marker RMS: the markers' own verdict, not the plates')
            again = _scale_and_place(inputs, read, functional)
            rms0, rms1 = _placement_rms(built["info"]), _placement_rms(again["info"])
            if rms1 <= rms0:
                built = again
            else:
                split = _split_refused(split, (
                    f"the markers fit the split model worse (placement marker RMS "
                    f"{1000 * rms0:.1f} → {1000 * rms1:.1f} mm): leg factor kept"
                ))  # fmt: skip
    if split is not None:
        built["info"]["leg_split"] = {side: sp.summary() for side, sp in split.items()}
    if swapped:
        built["info"]["marker_set"]["swapped_back"] = swapped
    # after scaling and placement (whose passes keep the generic bounds): the task's IK and
    # every later stage
    model, widened = knee_flexion_to_physiological(built["model"])
    if widened:
        built["info"]["widened_ranges_deg"] = widened
    unknown = sorted(set(cfg.marker_weights) - set(model.marker_names) - set(trial.marker_labels))
    if unknown:
        raise ConfigError(f"{cfg.path}: markers.weights: no marker {unknown[0]!r}")
    # the task trial's markers in the model frame (lab up → model up, heading as decided
    # above); exact-zero samples are gaps (TRC writers store missing markers as 0, 0, 0). Its
    # analog-rate data are left out (fresh empty arrays: a view would keep them alive)
    rot = built["rotation"]
    markers_only = dataclasses.replace(
        trial, plates=(), analog_time=np.empty(0),
        analogs=np.empty((0, np.shape(trial.analogs)[1] if np.ndim(trial.analogs) == 2 else 0)),
    )  # fmt: skip
    mtrial = markers_only.rotated(rot)
    # the rotated markers are a fresh array: their gaps set in place (zeros_as_gaps' copy was a
    # second model-frame copy of a long trial's markers at the stage's end, issue 18)
    x = mtrial.markers
    x[(x == 0.0).all(axis=-1)] = np.nan
    inv = {v: k for k, v in built["rename"].items()}
    labels = tuple(inv.get(lab, lab) for lab in trial.marker_labels)
    return BuiltModel(
        model, built["info"], rot, built["rename"], mtrial, labels,
        held_foot_coordinates(model, mtrial.markers, labels), np.asarray(trial.up, dtype=float),
    )  # fmt: skip
