"""Coordinates the markers cannot observe, and how they are held: foot joints held near neutral
by an IK coordinate task, a static's unobserved knee flexion held at 0, the foot joints a
placement from the motion leaves free, and the knees' flexion bound widened to the physiological
limit."""

from __future__ import annotations

from collections.abc import Sequence
from typing import cast

import numpy as np
from numpy.typing import NDArray

from msk.model.core import Model

__all__ = [
    "HELD_COORDINATE_WEIGHT",
    "free_foot_coordinates",
    "held_foot_coordinates",
    "held_static_knees",
    "knee_flexion_to_physiological",
]

#: IK weight of the coordinate task holding an unobserved foot joint at 0 rad (weight per rad²,
#: markers per m²: 1° off costs as much as 17 mm of marker error)
HELD_COORDINATE_WEIGHT = 1.0


def knee_flexion_to_physiological(model: Model) -> tuple[Model, dict[str, list[float]]]:
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
    branch: knees to +9° of hyperextension). The bounds are read in gait2392's sign
    (:func:`msk.model.conventions.reference_sign`): Rajagopal's knee, positive in flexion, has
    its upper bound widened (140° → 155°)."""
    from msk.model.conventions import reference_signs
    from msk.quality import PHYSIOLOGICAL_RANGES_DEG

    lo_phys = np.radians(PHYSIOLOGICAL_RANGES_DEG["knee_angle"][0])
    signs = reference_signs(model)
    out: dict[str, tuple[float, float]] = {}
    for c in model.coordinates:
        stem = c.name[:-2] if c.name.endswith(("_r", "_l")) else c.name
        s = signs.get(c.name, 1.0)
        lo, hi = sorted((s * c.range[0], s * c.range[1]))  # reference sign: flexion negative
        if stem == "knee_angle" and -np.pi / 2 >= lo > lo_phys + 1e-9:
            a, b = sorted((s * float(lo_phys), s * float(hi)))
            out[c.name] = (a, b)
    if not out:
        return model, {}
    return model.with_coordinate_ranges(out), {
        k: [float(np.degrees(v)) for v in r] for k, r in out.items()
    }


def free_foot_coordinates(
    model: Model, moved: Sequence[str], present: Sequence[str] | None = None
) -> tuple[str, ...]:
    """Foot coordinates (subtalar, MTP) whose offset a placement from the motion leaves free:
    every model marker distal to the joint that the trial has (``present``; None: every model
    marker) is moved (:func:`msk.personalise.scaling.place_markers_from_motion`,
    ``median_neutral``), and there is at least one. A generic marker the trial lacks observes
    nothing."""
    body_of = {m.name: m.body for m in model.markers}
    out: list[str] = []
    for name, sub in _foot_joints(model):
        distal = [m for m, b in body_of.items() if b in sub and (present is None or m in present)]
        if distal and set(distal) <= set(moved):
            out.append(name)
    return tuple(out)


def _foot_joints(model: Model) -> list[tuple[str, set[str]]]:
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
    model: Model, markers: NDArray[np.float64], labels: tuple[str, ...]
) -> dict[str, tuple[float, float]]:
    """Foot joints the markers cannot observe (fewer than 3 markers on the bodies distal to the
    joint: e.g. Plug-in Gait's heel + toe), held near neutral by an IK coordinate task
    (OpenSim's IKCoordinateTask) instead of wandering to −75°. A marker counts when the trial
    tracks it in at least half of the frames the IK solves (those that see
    :data:`msk.kinematics.trial.MIN_MARKER_FRACTION` of the most model markers any frame
    sees: metatarsal-head markers lost in most of them do not observe the subtalar). Not the
    frames that track anything: a running trial's unlabelled trajectories (``*33``…) and
    acromia outlast its feet's markers by 150 frames, and the right subtalar of UWA's
    ``Running_1``, whose metatarsal heads are tracked in 93 % of the solved frames, was held
    that way."""
    from msk.kinematics.trial import MIN_MARKER_FRACTION

    vis = cast("NDArray[np.bool_]", np.isfinite(markers).all(axis=2))
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


def held_static_knees(model: Model, labels: tuple[str, ...]) -> dict[str, tuple[float, float]]:
    """Knee flexion a static trial's markers cannot observe, held at 0 rad (the anatomical
    standing pose a static is recorded in) by an IK coordinate task in the static pose θ̄ of
    the marker placement (:func:`msk.personalise.scaling.place_markers`).

    A side's knee flexion is observed when the static has a femoral epicondyle and a malleolus
    marker of that side (with the pelvis' hip centre: the thigh's and the shank's long axes;
    :func:`msk.model.markersets.parse_label`). Without them (thigh and shank clusters only: the
    Grand Challenge's JW) θ̄ puts the knee wherever the generic model's cluster offsets fit,
    and every cluster marker placed from that pose carries the error into the motion:
    ``jw_1legstand1`` posed 9.6° hyperextended by its clusters where JW's knee goniometer reads
    5.4° of flexion. Weight :data:`HELD_COORDINATE_WEIGHT`."""
    from msk.model.markersets import parse_label

    seen = {(p.side, p.landmark) for p in map(parse_label, labels) if p.side and p.landmark}
    held: dict[str, tuple[float, float]] = {}
    for side in ("R", "L"):
        name = f"knee_angle_{side.lower()}"
        knee = {(side, "knee_lat"), (side, "knee_med")} & seen
        ankle = {(side, "ankle_lat"), (side, "ankle_med")} & seen
        if name in model.coordinate_names and not (knee and ankle):
            held[name] = (0.0, HELD_COORDINATE_WEIGHT)
    return held
