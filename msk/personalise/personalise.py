"""The subject's model from a generic one: :func:`personalise` scales it (static trial, else the
motion, else the stature), places the lab's markers (static trial, else chosen among motion
placements by the task's inverse kinematics cost), splits the legs by their functional knees,
sets the soles' gauge by a stated prior, profiles what the markers leave undetermined, and gives
the task trial in the model frame with the foot joints its markers cannot observe.

Frames (:func:`msk.io.lab_to_model_rotation`, :func:`msk.io.frames.pelvis_heading_rotation`):
lab vertical → the model's up (−gravity) and the walking direction → the model's +x (OpenSim's
convention), or the pelvis markers' heading where the progression disagrees with it by more
than 30° (treadmill, turning, short trials). Marker placement:
:func:`msk.personalise.scaling.place_markers` (static trial) or
:func:`msk.personalise.scaling.place_markers_from_motion`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from msk.exceptions import ConfigError, KinematicsError, ModelError
from msk.io.frames import lab_to_model_rotation
from msk.model.core import Model
from msk.personalise.determinacy import PlacementProfile
from msk.personalise.leg_split import LegSplit
from msk.personalise.options import PersonaliseOptions
from msk.personalise.placement import (
    CHOICE_TOLERANCE_M,
    Candidate,
    PlacementCall,
    PlacementChoice,
    choice_frames,
    choose_placement,
    continued_placement,
    placement_fit,
    placement_frames,
)
from msk.personalise.scaling import ScalingReport
from msk.personalise.sole_level import SoleLevel
from msk.personalise.static_trial import StaticTrial
from msk.trial import Trial

__all__ = [
    "Personalisation",
    "measured_leg_split",
    "personalise",
    "placement_determinacy",
    "scale_and_place",
    "sole_level",
]


@dataclass(frozen=True)
class Personalisation:
    """The subject's model and how it was made (:func:`personalise`).

    Attributes:
        model: the scaled model with its placed markers (knees' flexion bound widened to the
            physiological limit).
        info: what was done, as ``summary.json`` ``model`` reports it (source, marker set,
            heading, static window, scaling, placement and its choice, leg split, sole level,
            placement determinacy, knee alignment, widened ranges).
        rotation: (3, 3) lab → model frame.
        rename: model marker name → lab label.
        trial: the task trial's markers in the model frame (a :class:`msk.trial.Trial` without
            its analog-rate data — no analogs, no plates —, exact-zero samples as gaps).
        labels: ``trial``'s labels in model names.
        held: foot coordinates held near neutral by an IK coordinate task (name → (value rad,
            weight); :func:`msk.personalise.coordinates.held_foot_coordinates`).
        lab_up: (3,) the lab's up (the task trial's).
        scaling: the scaling's report (None when the model was not scaled).
        placement_choice: the choice among motion placements (None after a static one).
        leg_split: each leg's femur:tibia split as kept (None when no leg was scaled by one
            pelvis-to-heel factor).
        sole_level: each ankle's gauge set by the prior "sole level at foot flat" (motion
            placement only).
        determinacy: what the chosen motion placement leaves undetermined (None after a
            static placement or when its frames could not be fitted: ``info`` says why).
    """

    model: Model
    info: Mapping[str, Any]
    rotation: NDArray[np.float64]
    rename: Mapping[str, str]
    trial: Trial
    labels: tuple[str, ...]
    held: Mapping[str, tuple[float, float]]
    lab_up: NDArray[np.float64]
    scaling: ScalingReport | None = None
    placement_choice: PlacementChoice | None = None
    leg_split: Mapping[str, LegSplit] | None = None
    sole_level: tuple[SoleLevel, ...] = ()
    determinacy: PlacementProfile | None = None

    @property
    def scale_factors(self) -> Mapping[str, NDArray[np.float64]]:
        """Body → (3,) scale factors applied (empty when not scaled)."""
        return {} if self.scaling is None else self.scaling.factors

    @property
    def scale_methods(self) -> Mapping[str, str]:
        """Body → how it was scaled (empty when not scaled)."""
        return {} if self.scaling is None else self.scaling.methods

    def without_markers(self) -> Personalisation:
        """This personalisation without the task's model-frame markers (``trial.markers`` a
        ``(N, 0, 3)`` array; the labels, gaps, events, time and metadata kept), for a caller
        that no longer reads them (a long trial's markers, 1.2 kB/frame with 51 markers)."""
        trial = self.trial
        empty = np.zeros((int(np.shape(trial.markers)[0]), 0, 3))
        return dataclasses.replace(self, trial=dataclasses.replace(trial, markers=empty))


def _aligned(
    opts: PersonaliseOptions, model: Model, markers: NDArray[np.float64], labels: tuple[str, ...]
) -> Model:
    """The model with the frontal alignment of the side of interest's knee: the configured one,
    or (``knee_alignment.source = "from_markers"``) the one the trial's epicondyle and malleolus
    markers show against ``model``'s (:func:`msk.model.alignment.knee_varus_from_markers`, on the
    static trial when there is one, else the task); the model itself without one
    (:func:`msk.model.alignment.with_knee_alignment`)."""
    ka = opts.knee_alignment
    from_markers = ka.source == "from_markers"
    if from_markers and (ka.varus_deg != 0.0 or ka.medial_shift_m != 0.0):
        raise ConfigError(
            f"{opts.origin}: model.knee_alignment = 'from_markers' with a given "
            "knee_varus_deg / knee_medial_shift_m: give one or the other"
        )
    if not from_markers and ka.varus_deg == 0.0 and ka.medial_shift_m == 0.0:
        return model
    from msk.exceptions import MissingDataError
    from msk.model.alignment import knee_varus_from_markers, with_knee_alignment

    joint = f"knee{opts.sfx}"
    if joint not in {j.name for j in model.joints}:
        raise ConfigError(
            f"{opts.origin}: model.knee_varus_deg / knee_medial_shift_m: the model has no "
            f"joint {joint!r}"
        )
    varus, shift = np.radians(ka.varus_deg), ka.medial_shift_m
    if from_markers:
        try:
            est = knee_varus_from_markers(model, markers, labels, opts.side)
        except (MissingDataError, ModelError) as exc:
            raise ConfigError(f"{opts.origin}: model.knee_alignment: {exc}") from None
        varus, shift = est.varus_rad, 0.0
    aligned = with_knee_alignment(model, joint, varus_rad=varus, medial_shift_m=shift)
    if from_markers:
        meta = dict(aligned.metadata.get("knee_alignment") or {})
        meta[joint] = {**meta.get(joint, {}), "source": "markers",
                       "subject_rad": est.subject_rad, "model_rad": est.model_rad,
                       "iqr_rad": est.iqr_rad, "frames": est.frames}  # fmt: skip
        aligned = aligned.with_metadata(knee_alignment=meta)
    return aligned


def _hip_parameters(static: Any, task: Any) -> Any:
    """The subject whose Plug-in Gait hip parameters (leg lengths, ASIS-to-trochanter and
    inter-ASIS distances) the hip regression takes: the static's, else the task's."""
    if static is not None and getattr(static, "leg_lengths_m", None):
        return static
    return task


def scale_and_place(
    generic: Model, static: StaticTrial | None, task: Trial, opts: PersonaliseOptions, *,
    functional: Mapping[str, float] | None = None,
    placement: Mapping[str, Any] | None = None,
    continue_from: tuple[Model, Mapping[str, Any]] | None = None,
    workspace: dict[str, Any] | None = None,
    hip_trial: Trial | None = None,
) -> Candidate:  # fmt: skip
    """Scale ``generic`` and place the lab's markers (``static`` trial, else the ``task``).
    ``functional``: femur and tibia factors of a functional leg split
    (:func:`measured_leg_split`). ``hip_trial``: a functional trial of the hips (model frame,
    with a static), their centres fitted on it (:func:`msk.personalise.hip_centre.
    place_hip_centres`). ``placement``: extra keywords of
    :func:`msk.personalise.scaling.place_markers_from_motion` (``regularize``, ``frame_phase``)
    when there is no static trial. ``continue_from`` (no static trial; an earlier motion
    placement: its model and ``info["marker_placement"]``): the placement is one pulled pass
    continuing that one — its placed markers' state and its moved model markers' offsets — on
    the model scaled here (the split candidates of
    :func:`msk.personalise.placement.choose_placement`). ``workspace``: that of
    :func:`msk.personalise.scaling.scale_from_motion` (a new one when None; the candidate's),
    so that scaling the same trial again with a split reuses the pose-matched IK."""
    from msk.io.c3d import is_measured_marker
    from msk.io.frames import pelvis_heading_rotation
    from msk.model.markersets import (
        foot_markers,
        recognise,
        shoulder_girdle_markers,
        zeros_as_gaps,
        zeros_as_gaps_view,
    )
    from msk.personalise.coordinates import (
        free_foot_coordinates,
        held_foot_coordinates,
        held_static_knees,
    )
    from msk.personalise.hip_centre import place_hip_centres, place_hip_centres_from_motion
    from msk.personalise.scaling import (
        place_markers,
        place_markers_from_motion,
        scale_from_motion,
        scale_from_static,
    )
    from msk.personalise.static_placement import (
        STATIC_CHECK_MIN_TASK_S,
        chord_centres,
        place_from_task,
    )
    from msk.personalise.task_markers import lab_origin_offset, model_frame_columns
    from msk.quality import inconsistent_static_markers

    trial, marks = task, opts.markers
    workspace = {} if workspace is None else workspace
    model = generic
    bodies = [b.name for b in model.bodies]
    info: dict[str, Any] = {"source": opts.source, "generic_mass_kg": model.total_mass}
    x_lab = zeros_as_gaps_view(trial.markers)  # not copied unless it has zero samples
    match = recognise(
        trial.marker_labels, model.marker_names, rename=marks.rename,
        model_bodies=bodies, markers=x_lab,
    )  # fmt: skip
    up = -np.asarray(model.gravity, dtype=float)
    labels_all = set(trial.marker_labels)
    if static is not None:
        labels_all |= set(static.labels)
    # names in the configuration that match nothing are errors, not silently ignored (a lab
    # label absent from these trials is a note: rename tables of a protocol list variants a
    # given session may not use)
    from msk.model.markersets import as_read

    absent = sorted(v for v in set(marks.rename.values())
                    if as_read(v, tuple(labels_all)) not in labels_all)  # fmt: skip
    unknown = sorted(set(marks.rename) - set(model.marker_names))
    if unknown:
        raise ConfigError(f"{opts.origin}: markers.rename: the model has no marker {unknown[0]!r}")
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
    report: ScalingReport | None = None
    placement_call: PlacementCall | None = None
    placed: dict[str, Any]
    # a static the task contradicts so much that it cannot be posed (another subject's, or
    # another labelling): the task's own markers scale and place, and the flag says so
    rejected: str | None = None
    if static is not None:
        window = static.window
        # the still, double-stance part of the static only
        # (msk.personalise.static_window.still_window)
        sm, stime = static.markers[window.frames], static.time[window.frames]
        slabels_raw, ssubj = static.labels, static.subject
        info["static_window"] = {**window.summary(), "not_judged": list(static.not_judged)}
        # the lab's joint widths (Plug-in Gait subject parameters): the static's, else the task's
        subj = ssubj if ssubj is not None and ssubj.widths_m else trial.subject
        widths = dict(getattr(subj, "widths_m", None) or {})
        mdiam = getattr(subj, "marker_diameter_m", None)
        smatch = recognise(
            slabels_raw, model.marker_names, rename=marks.rename,
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
        if opts.scale:
            static_x = {lab: sm[:, i] for i, lab in enumerate(slabels)}
            model, report = scale_from_static(
                model, static_x, height_m=opts.height_m, body_mass=opts.mass_kg,
                widths_m=widths, marker_diameter_m=mdiam, functional=functional,
            )  # fmt: skip
        model = _aligned(opts, model, sm, slabels)
        fx = None
        if hip_trial is not None:  # its labels in the static's names (the model's)
            back = {lab: mk for mk, lab in smatch.rename.items()}
            fx = (hip_trial.markers, [back.get(lab, lab) for lab in hip_trial.marker_labels])
        model, info["hip_centre"] = place_hip_centres(
            model, sm, slabels, method=opts.hip_centre,
            marker_radius_m=0.007 if mdiam is None else 0.5 * float(mdiam), functional=fx,
            lab=_hip_parameters(ssubj, trial.subject),
        )  # fmt: skip
        centres, jc_move = chord_centres(model, sm, slabels, widths, mdiam)
        try:
            model, placed = place_markers(
                model, sm, slabels, stime,
                move=[*marks.move, *(m for m in jc_move if m not in marks.move)],
                hints=smatch.body_hints([b.name for b in model.bodies]), centres=centres,
                coordinate_tasks={
                    **(held_foot_coordinates(model, sm, slabels) if centres else {}),
                    **held_static_knees(model, slabels_raw),
                } or None,
                relocate=[lab for lab in slabels if lab in model.marker_names],
            )  # fmt: skip
        except ModelError as exc:
            raise ConfigError(f"{opts.origin}: markers.move: {exc}") from None
        except KinematicsError as exc:
            if not bad:
                raise
            rejected = (
                f"{static.name} cannot be posed without the markers "
                f"{trial.path.name} contradicts ({', '.join(sorted(bad))}): not the same "
                f"subject or labelling? ({' '.join(str(exc).split())}); the model is scaled "
                "and its markers placed from the task instead"
            )
            model, report = generic, None
            info["static_rejected"] = rejected
            info.pop("static_window", None)
        if rejected is None:
            model, from_task, check, recon = place_from_task(model, trial, rot, match, bad)
            placed["from_task"] = from_task
            placed["reconstructed_from_task"] = recon
            if check:
                info["static_check"] = check
    if static is None or rejected is not None:
        # no static trial: the task trial's own markers scale and place (the segment lengths
        # are constant over a motion; msk.personalise.scaling.scale_from_motion)
        xm, mlabels = model_frame_columns(trial, rot, match)
        # where the lab put its origin cannot matter: the markers are translated so that their
        # median sits at the generic model's markers' centroid in its default pose (the
        # inverse kinematics of scaling and placement start from that pose, and the pelvis
        # translations have bounds; scale factors and body-frame offsets are invariant)
        xm = xm - lab_origin_offset(model, xm)
        if opts.scale:
            model, report = scale_from_motion(
                model, xm, mlabels, trial.time, height_m=opts.height_m,
                body_mass=opts.mass_kg, functional=functional, workspace=workspace,
            )  # fmt: skip
        model = _aligned(opts, model, xm, mlabels)
        # the regression's hips from the task's pelvis markers, before the placement (which
        # keeps the pelvis markers where this puts them)
        tsubj = trial.subject
        tdiam = getattr(tsubj, "marker_diameter_m", None)
        model, info["hip_centre"] = place_hip_centres_from_motion(
            model, xm, mlabels, method=opts.hip_centre,
            marker_radius_m=0.007 if tdiam is None else 0.5 * float(tdiam), lab=tsubj,
        )  # fmt: skip
        # the lab's foot markers: where they sit on the foot is the lab's choice and nothing
        # but the motion tells (msk.model.markersets.foot_markers), so they are moved too
        present = [mk.name for mk in model.markers if mk.name in set(mlabels)]
        feet = [m for m in foot_markers(present) if m not in marks.move]
        moved = [*marks.move, *feet]
        kw: dict[str, Any] = dict(
            move=moved, median_neutral=free_foot_coordinates(model, moved, present),
            hints=match.body_hints([b.name for b in model.bodies]),
        )  # fmt: skip
        placement_call = PlacementCall(model, xm, mlabels, trial.time, kw)
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
    return Candidate(model, info, rot, dict(match.rename), placement_call, workspace, report)


def measured_leg_split(
    built: Candidate, task: Trial, *, scale: bool = True
) -> dict[str, LegSplit] | None:
    """The femur : tibia split of each leg scaled by one pelvis-to-heel factor (no knee or
    ankle marker: ``leg_<side>`` among the scaling ratios), from the functional knee and ankle
    centres of the task trial's thigh, shank and calcaneus markers
    (:func:`msk.personalise.leg_split.functional_leg_split`) on the model as first scaled and
    placed (``built``); None when the model is not scaled (``scale`` False) or no leg was scaled
    that way. :func:`personalise` scales and places again with the sides it determines, keeps
    that model when the lab's markers fit it no worse (else every side keeps its leg factor,
    and says why) and reports every side in ``summary.json`` ``model.leg_split``. A leg the
    scaling reports as not determined by the motion (the stature's leg of a run,
    :func:`msk.personalise.scaling.unobserved_leg_starts`) is split by the functional knee and
    ankle (``use_ankle``) where its checks pass."""
    from msk.model.markersets import zeros_as_gaps
    from msk.personalise.leg_split import functional_leg_split

    ratios = dict(built.info.get("scaling", {}).get("ratios", {}))
    legs = {s: float(ratios[f"leg_{s}"]) for s in ("r", "l") if f"leg_{s}" in ratios}
    if not scale or not legs:
        return None
    model, rot = built.model, np.asarray(built.rotation, dtype=float)
    x = zeros_as_gaps(np.asarray(task.markers, dtype=float) @ rot.T)
    inv = {v: k for k, v in built.rename.items()}
    labels = tuple(inv.get(lab, lab) for lab in task.marker_labels)
    # the markers on each body: the model's, those placed and those placed but too loose for
    # IK (a cluster is posed by its own shape: its markers need only be rigid with each other)
    placed = built.info.get("marker_placement", {})
    segments: dict[str, list[str]] = {}
    for mk in model.markers:
        segments.setdefault(mk.body, []).append(mk.name)
    for lab, (body, _) in dict(placed.get("too_loose", {})).items():
        segments.setdefault(body, []).append(lab)
    # a leg whose length the motion did not determine (the stature's:
    # msk.personalise.scaling.unobserved_leg_starts) has its tibia from the functional ankle,
    # where the checks find it determined — the clusters' only measurement of it — rather than
    # as the rest of a leg the markers did not measure
    starts = dict(built.info.get("scaling", {}).get("leg_starts", {}))
    free = {s: f for s, f in legs.items() if starts.get(f"leg_{s}", {}).get("determined") is False}
    out: dict[str, LegSplit] = {}
    for use_ankle in (False, True):
        sides = {s: f for s, f in legs.items() if (s in free) == use_ankle}
        if sides:
            out.update(
                functional_leg_split(
                    model, x, labels, sides, segments=segments, use_ankle=use_ankle
                )
            )
    return {s: out[s] for s in legs}


def sole_level(
    built: Candidate, task: Trial, weights: Mapping[str, float]
) -> tuple[Candidate, tuple[SoleLevel, ...]]:
    """The chosen motion placement (no static trial; ``built``) with each ankle's gauge set by
    the prior "sole level at foot flat" (:func:`msk.personalise.sole_level.level_sole_gauge`:
    the foot-flat frames of the whole task, fitted as
    :func:`msk.personalise.placement.placement_fit` fits the choice's frames; the free markers
    those the placement placed or moved) — ``built`` with its model replaced and
    ``summary.json`` ``model.sole_level`` (ankle coordinate → what was done or why not) set in
    its ``info`` — and each side's record."""
    from msk.model.markersets import zeros_as_gaps
    from msk.personalise.sole_level import level_sole_gauge

    rot = np.asarray(built.rotation, dtype=float)
    x = zeros_as_gaps(np.asarray(task.markers, dtype=float) @ rot.T)
    t = np.asarray(task.time, dtype=float)
    inv = {v: k for k, v in built.rename.items()}
    labels = tuple(inv.get(lab, lab) for lab in task.marker_labels)
    w = dict(weights)
    markers = sorted(set(built.model.marker_names) & set(labels))
    mp = dict(built.info.get("marker_placement", {}))
    free = [*dict(mp.get("moved", {})), *dict(mp.get("placed", {}))]

    # the foot-flat frames fitted among the choice's (placement_frames: spread over the whole
    # trial), in time order: the IK carries each frame's pose to the next, and the foot-flat
    # frames alone, a stance apart, start cold (DM crouch: 59–87 mm, the knees 7–11° off)
    spread = placement_frames(task.markers)

    def fit(m: Model, frames: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
        every = np.union1d(spread, frames)
        q, cost = placement_fit(m, x[every], t[every], labels, w, markers)
        return q[np.searchsorted(every, frames)], cost

    model, sides = level_sole_gauge(built.model, x, labels, t, fit, free)
    built.info["sole_level"] = {s.coordinate: s.summary() for s in sides}
    return dataclasses.replace(built, model=model), tuple(sides)


def placement_determinacy(
    built: Candidate, task: Trial, weights: Mapping[str, float]
) -> PlacementProfile | str:
    """What the chosen motion placement (no static trial; ``built``) leaves undetermined:
    :func:`msk.personalise.determinacy.placement_profile` of its leg coordinates on the
    choice's frames (:func:`msk.personalise.placement.placement_frames`), fitted as
    :func:`msk.personalise.placement.placement_fit` fits them on the markers the model
    carries, the free markers those the placement placed or moved, the cost's resolution
    :data:`msk.personalise.placement.CHOICE_TOLERANCE_M` (a cost change the choice itself
    does not tell from a tie) — ``summary.json`` ``model.placement_determinacy`` (its quality
    flag: :func:`msk.quality.model_flags`); why not when the frames cannot be fitted."""
    from msk.personalise.determinacy import pelvis_determinacy, placement_profile

    x, t, labels = choice_frames(task, built)
    w = dict(weights)
    model = built.model
    mp = dict(built.info.get("marker_placement", {}))
    markers = sorted(set(model.marker_names) & set(labels))
    seen = cast("NDArray[np.bool_]", np.isfinite(x).all(axis=-1).any(axis=0))
    observed = [lab for k, lab in enumerate(labels) if seen[k]]

    def fit(m: Model, q0: NDArray[np.float64] | None) -> tuple[NDArray[np.float64], float]:
        return placement_fit(m, x, t, labels, w, markers, initial_q=q0)

    free = [*dict(mp.get("moved", {})), *dict(mp.get("placed", {}))]
    try:
        profile = placement_profile(model, fit, free, observed, tolerance_m=CHOICE_TOLERANCE_M)
        # the pelvis first: the root segment its fixed markers must pose
        return dataclasses.replace(profile, pelvis=pelvis_determinacy(model, free, observed))
    except ModelError as exc:  # reported (and flagged), not a failed personalisation
        return str(exc)


def _functional(split: Mapping[str, LegSplit]) -> dict[str, float]:
    """The femur and tibia factors of the sides ``split`` scales by the functional knee."""
    return {
        f"{b}_{side}": f
        for side, sp in split.items() if sp.method != "leg factor"
        for b, f in (("femur", sp.femur_factor), ("tibia", sp.tibia_factor))
    }  # fmt: skip


def _split_refused(split: Mapping[str, LegSplit], note: str) -> dict[str, LegSplit]:
    """Every side of ``split`` back to its leg factor, ``note`` saying why."""
    return {
        side: sp if sp.method == "leg factor" else dataclasses.replace(
            sp, method="leg factor", reason=f"{sp.method}: {note}",
            femur_factor=sp.leg_factor, tibia_factor=sp.leg_factor,
        )
        for side, sp in split.items()
    }  # fmt: skip


def _placement_rms(info: Mapping[str, Any]) -> float:
    """The marker placement's marker RMS (m): the static's IK (``static_marker_rms_m``) or the
    motion's last pass (``ik_marker_rms_m``, median over its frames); NaN without one."""
    mp = dict(info.get("marker_placement", {}))
    v = mp.get("static_marker_rms_m", mp.get("ik_marker_rms_m"))
    return float("nan") if v is None else float(v)


def personalise(
    model: Model,
    static: StaticTrial | None,
    task: Trial,
    options: PersonaliseOptions,
    *,
    hip_trial: Trial | None = None,
) -> Personalisation:
    """The subject's model from the generic ``model``: scaled and its markers placed from the
    ``static`` trial (markers in the model frame,
    :func:`msk.personalise.static_trial.read_static_trial`) when there is one, else from the
    ``task`` trial (as read, lab frame) — then the placement chosen among candidates
    (:func:`msk.personalise.placement.choose_placement`), the soles'
    gauge set by a prior (:func:`sole_level`) and what the markers leave undetermined profiled
    (:func:`placement_determinacy`); each leg scaled by one pelvis-to-heel factor split by its
    functional knee where the markers fit the split model no worse (:func:`measured_leg_split`);
    the knees' flexion bound widened to the physiological limit
    (:func:`msk.personalise.coordinates.knee_flexion_to_physiological`); the task trial's
    markers in the model frame (left/right label pairs the markers show swapped exchanged back
    first, :func:`msk.personalise.task_markers.swap_back`) and the foot joints they cannot
    observe (:func:`msk.personalise.coordinates.held_foot_coordinates`).

    Raises:
        ConfigError: a marker name of ``options`` matches nothing, markers to move cannot be
            moved, or the knee alignment cannot be made (messages prefixed by
            ``options.origin``).
    """
    from msk.personalise.coordinates import held_foot_coordinates, knee_flexion_to_physiological
    from msk.personalise.task_markers import swap_back
    from msk.personalise.virtual_markers import with_virtual_markers, with_virtual_sacrum

    opts = options
    trial, swapped = swap_back(task)
    # the lab's virtual markers, in the task and the static alike
    # (msk.personalise.virtual_markers)
    virtual = dict(opts.markers.virtual)
    trial, virtual_notes = with_virtual_markers(trial, virtual)
    if static is not None:
        static, _ = with_virtual_markers(static, virtual)
    sacrum = None
    if static is None:
        # no static: the PSIS midpoint stands for a missing sacral marker
        # (msk.personalise.virtual_markers)
        trial, sacrum = with_virtual_sacrum(trial, model)

    def again(
        functional: Mapping[str, float] | None = None,
        continue_from: tuple[Model, Mapping[str, Any]] | None = None,
        workspace: dict[str, Any] | None = None,
    ) -> Candidate:
        return scale_and_place(
            model, static, trial, opts, functional=functional, continue_from=continue_from,
            workspace=workspace, hip_trial=hip_trial,
        )  # fmt: skip

    built = again()
    split: Mapping[str, LegSplit] | None = None
    choice: PlacementChoice | None = None
    soles: tuple[SoleLevel, ...] = ()
    determinacy: PlacementProfile | None = None
    if "regularized" in built.info.get("marker_placement", {}):
        # no static trial: the placement of least task IK cost among fixed candidates, the
        # leg split measured on the best unsplit one (choose_placement)
        measured: dict[str, dict[str, LegSplit] | None] = {}

        def split_of(b: Candidate) -> dict[str, float] | None:
            measured["split"] = sp = measured_leg_split(b, trial, scale=opts.scale)
            return (_functional(sp) or None) if sp is not None else None

        workspace = built.workspace  # the first scaling's: its pose-matched IK reused

        def rescale(f: Mapping[str, float], prev: tuple[Model, Mapping[str, Any]]) -> Candidate:
            return again(f, continue_from=prev, workspace=workspace)

        weights = opts.markers.weights
        built, choice = choose_placement(built, trial, weights, split_of=split_of, rescale=rescale)
        built.info["placement_choice"] = choice.summary()
        # the ankles' gauge (every foot marker moved: the markers leave their means free) set
        # by the prior "sole level at foot flat" (msk.personalise.sole_level)
        built, soles = sole_level(built, trial, weights)
        profile = placement_determinacy(built, trial, weights)
        if isinstance(profile, str):
            built.info["placement_determinacy"] = {"not_run": profile}
        else:
            determinacy = profile
            priors = {c: str(v["prior"]) for c, v in dict(built.info.get("sole_level", {})).items()
                      if v.get("status") == "prior"}  # fmt: skip
            built.info["placement_determinacy"] = profile.summary(priors)
        split = measured.get("split")
        chosen = choice.chosen_candidate
        if split is not None and _functional(split) and not chosen.leg_split:
            c_split = min(c.cost_m for c in choice.candidates if c.leg_split)
            split = _split_refused(split, (
                f"the task's markers fit the split model worse (task IK "
                f"{1000 * chosen.cost_m:.2f} → {1000 * c_split:.2f} mm at best): leg "
                "factor kept"
            ))  # fmt: skip
    else:
        split = measured_leg_split(built, trial, scale=opts.scale)
        functional = _functional(split) if split is not None else {}
        if split is not None and functional:
            # kept when the lab's markers fit the split model no worse than the leg-factor one
            # (the placement's marker RMS: the markers' own verdict, not the plates')
            rescaled = again(functional)
            rms0, rms1 = _placement_rms(built.info), _placement_rms(rescaled.info)
            if rms1 <= rms0:
                built = rescaled
            else:
                split = _split_refused(split, (
                    f"the markers fit the split model worse (placement marker RMS "
                    f"{1000 * rms0:.1f} → {1000 * rms1:.1f} mm): leg factor kept"
                ))  # fmt: skip
    if split is not None:
        built.info["leg_split"] = {side: sp.summary() for side, sp in split.items()}
    if swapped:
        built.info["marker_set"]["swapped_back"] = swapped
    if sacrum is not None or virtual_notes:
        built.info["virtual_markers"] = [*virtual_notes, *([sacrum] if sacrum else [])]
    # after scaling and placement (whose passes keep the generic bounds): the task's IK and
    # every later stage
    final, widened = knee_flexion_to_physiological(built.model)
    if widened:
        built.info["widened_ranges_deg"] = widened
    marks = opts.markers
    unknown = sorted(set(marks.weights) - set(final.marker_names) - set(trial.marker_labels))
    if unknown:
        raise ConfigError(f"{opts.origin}: markers.weights: no marker {unknown[0]!r}")
    # the task trial's markers in the model frame (lab up → model up, heading as decided
    # above); exact-zero samples are gaps (TRC writers store missing markers as 0, 0, 0). Its
    # analog-rate data are left out (fresh empty arrays: a view would keep them alive)
    rot = built.rotation
    markers_only = dataclasses.replace(
        trial, plates=(), analog_time=np.empty(0),
        analogs=np.empty((0, np.shape(trial.analogs)[1] if np.ndim(trial.analogs) == 2 else 0)),
    )  # fmt: skip
    mtrial = markers_only.rotated(rot)
    # the rotated markers are a fresh array: their gaps set in place (a copy would be a second
    # model-frame copy of a long trial's markers)
    x = mtrial.markers
    x[(x == 0.0).all(axis=-1)] = np.nan
    inv = {v: k for k, v in built.rename.items()}
    labels = tuple(inv.get(lab, lab) for lab in trial.marker_labels)
    return Personalisation(
        model=final, info=built.info, rotation=rot, rename=built.rename, trial=mtrial,
        labels=labels, held=held_foot_coordinates(final, mtrial.markers, labels),
        lab_up=np.asarray(trial.up, dtype=float), scaling=built.scaling,
        placement_choice=choice, leg_split=split, sole_level=soles, determinacy=determinacy,
    )  # fmt: skip
