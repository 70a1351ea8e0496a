"""Scaling a generic model to a subject from a static trial (as OpenSim's Scale tool does),
and placing the static trial's other markers on the scaled model (:func:`place_markers`).

Scale factors (OpenSim ``ModelScaler``, "measurements" method): for a measurement k with marker
pairs (a_j, b_j) and the static trial averaged over its frames,

    s_k = (1/J) Σ_j ‖x̄_a − x̄_b‖_experimental / ‖x_a(θ₀) − x_b(θ₀)‖_model

with the model in its default pose θ₀ (or ``theta``); s_k applies to the bodies (and axes) the
measurement lists. Manual factors (``scale_factors``) override measured ones; other bodies keep 1.

Applying per-body factors S_b = diag(s_x, s_y, s_z) (:func:`apply_scale_factors`), as OpenSim:

* joint frames: ``parent_offset`` translation × S_parent, ``child_offset`` translation × S_child;
  translation axes of a joint × the parent's factor along the axis (‖S_parent t‖ for unit t):
  a Constant is scaled, any other function f becomes ``Multiplier(f, s)`` (the knee splines of
  a scaled gait2392 read ``MultiplierFunction`` scale 1.14724 in the file);
* bodies: COM c' = S c; inertia about the COM from the second-moment matrix
  J = ½ tr(I) 𝟙 − I (J = Σ m r rᵀ): J' = S J S, I' = tr(J') 𝟙 − J' (exact for a rigid body
  stretched by S; = s² I for uniform s, as OpenSim; for non-uniform S OpenSim 4.6 uses a
  different approximation and its tensors differ, by up to 14 % on Rajagopal's pelvis for
  S = diag(1.05, 1, 1.1)); masses: with ``body_mass`` every segment mass (and its
  inertia) is multiplied by body_mass / model mass ("preserve mass distribution"), so the total
  mass is the subject's and I ∝ m·s²;
* markers, muscle path points (ConditionalPathPoint included) × S_body; MovingPathPoint location
  functions ``Multiplier(f, s_k)``; wrap objects: translation × S, cylinder / sphere radius ×
  the mean of the factors across the surface axis (mean of s_x, s_y for the local z axis; all
  three for a sphere), cylinder length × the factor along the axis, ellipsoid radii × S;
* muscles: the optimal fibre length and tendon slack length are multiplied by the ratio of the
  musculotendon path length after / before scaling, both in the default pose
  (OpenSim ``Muscle::postScale``), wrapping included (:func:`muscle_path_lengths`).
"""

from __future__ import annotations

import itertools
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import FileFormatError, MissingDataError, ModelError, MskError
from msk.model.core import (
    GROUND,
    Axis,
    Body,
    Joint,
    Marker,
    Model,
    forward_kinematics,
    frame_placements,
)
from msk.model.joints import Constant, CoordinateFunction, Multiplier
from msk.model.markersets import is_knee_segment, other_side, parse_label, shoulder_girdle_markers
from msk.muscles.path import ConditionalPathPoint, MovingPathPoint, Muscle, PathPoint, WrapObject
from msk.personalise.functional_joints import segment_poses
from msk.units import Array

__all__ = [
    "DEFAULT_MEASUREMENTS",
    "DESCENT_MAX_STEP",
    "LEG_START_MAX_SHORTFALL",
    "LEG_START_TOLERANCE",
    "LOOSE_KEPT_SPREAD_FACTOR",
    "MODEL_HEIGHT_M",
    "SCALING_METHODS",
    "SEGMENT_MEASUREMENTS",
    "STATIC_POSE_COORDINATES",
    "Measurement",
    "ScaleSetup",
    "ScalingReport",
    "apply_scale_factors",
    "bone_segments",
    "choose_measurements",
    "chord_joint_centre",
    "complete_scale_factors",
    "measure_scale_factors",
    "measure_scale_factors_from_motion",
    "model_height",
    "muscle_path_lengths",
    "place_markers",
    "place_markers_from_motion",
    "point_segment_distance",
    "read_scale_setup",
    "refine_placement_from_motion",
    "scale_from_motion",
    "scale_from_static",
    "scale_inertia",
    "scale_model",
    "static_joint_centres",
    "unobserved_end_rotations",
    "unobserved_knees_flexed",
    "unobserved_leg_starts",
    "usable_measurements",
]


@dataclass(frozen=True)
class Measurement:
    """An OpenSim Scale measurement: marker pairs whose mean distance ratio scales ``bodies``
    along ``axes`` (any of "X", "Y", "Z")."""

    name: str
    marker_pairs: tuple[tuple[str, str], ...]
    bodies: tuple[str, ...]
    axes: str = "XYZ"


def usable_measurements(
    specs: Sequence[Measurement | tuple[str, Sequence[tuple[str, str]], Sequence[str]]],
    markers: Iterable[str],
) -> list[Measurement]:
    """The measurements of ``specs`` (:class:`Measurement` or ``(name, pairs, bodies)``) whose
    every marker pair is in ``markers`` (the markers the model and the static trial share)."""
    have = set(markers)
    out = []
    for sp in specs:
        m = sp if isinstance(sp, Measurement) else Measurement(sp[0], tuple(sp[1]), tuple(sp[2]))
        if all(a in have and b in have for a, b in m.marker_pairs):
            out.append(m)
    return out


@dataclass(frozen=True)
class ScaleSetup:
    """What an OpenSim Scale setup file says: measurements, manual factors, subject mass (kg),
    static-trial time range (s), and the order in which measured / manual factors apply."""

    measurements: tuple[Measurement, ...]
    manual: dict[str, Array]
    mass: float | None
    time_range: tuple[float, float] | None
    order: tuple[str, ...] = ("measurements", "manualScale")


# ------------------------------------------------------------------------------------------
# factors
# ------------------------------------------------------------------------------------------
def _static_means(static_markers: Any) -> dict[str, Array]:
    """Mean position of each marker over the static frames (NaN frames ignored)."""
    if hasattr(static_markers, "labels") and hasattr(static_markers, "markers"):
        arr = np.asarray(static_markers.markers, dtype=float)
        items = {lab: arr[:, i] for i, lab in enumerate(static_markers.labels)}
    else:
        items = dict(static_markers)
    out = {}
    for name, v in items.items():
        a = np.atleast_2d(np.asarray(v, dtype=float))
        ok = np.all(np.isfinite(a), axis=1)
        if ok.any():
            out[name] = a[ok].mean(axis=0)
    return out


def measure_scale_factors(
    model: Model,
    static_markers: Any,
    measurements: Sequence[Measurement],
    *,
    theta: ArrayLike | None = None,
    marker_names: Mapping[str, str] | None = None,
) -> tuple[dict[str, Array], dict[str, float]]:
    """Per-body scale factors (3,) and per-measurement ratios from a static trial.

    ``static_markers``: ``{label: (3,) or (N, 3)}`` in m, or a TRC ``MarkerTable``;
    ``marker_names`` maps model marker names to trial labels when they differ. Bodies a
    measurement lists that the model lacks are skipped (as OpenSim does).
    """
    means = _static_means(static_markers)
    names = dict(marker_names or {})
    th = model.default_coordinates() if theta is None else np.asarray(theta, dtype=float)
    data = model.create_data()
    forward_kinematics(model, data, th)

    def model_pos(mk: str) -> Array:
        if mk not in model.marker_frame:
            raise MissingDataError(f"scaling: model {model.name} has no marker {mk!r}")
        return np.asarray(data.oMf[model.marker_frame[mk]].translation)

    def exp_pos(mk: str) -> Array:
        label = names.get(mk, mk)
        if label not in means:
            raise MissingDataError(f"scaling: static trial has no (valid) marker {label!r}")
        return means[label]

    factors: dict[str, Array] = {}
    ratios: dict[str, float] = {}
    for meas in measurements:
        if not meas.marker_pairs:
            raise ModelError(f"scaling: measurement {meas.name} has no marker pair")
        rs = []
        for a, b in meas.marker_pairs:
            dm = float(np.linalg.norm(model_pos(a) - model_pos(b)))
            if dm < 1e-9:
                raise ModelError(f"scaling: markers {a} and {b} coincide in model {model.name}")
            rs.append(float(np.linalg.norm(exp_pos(a) - exp_pos(b))) / dm)
        ratio = float(np.mean(rs))
        ratios[meas.name] = ratio
        for body in meas.bodies:
            if body not in model.body_joint:  # OpenSim skips bodies the model lacks too
                continue
            f = factors.get(body, np.ones(3)).copy()
            for k, ax in enumerate("XYZ"):
                if ax in meas.axes.upper():
                    f[k] = ratio
            factors[body] = f
    return factors, ratios


# ------------------------------------------------------------------------------------------
# applying factors
# ------------------------------------------------------------------------------------------
def scale_inertia(inertia: ArrayLike, factors: ArrayLike) -> Array:
    """Inertia about the COM of a body stretched by S = diag(factors), same mass:
    J = ½ tr(I) 𝟙 − I, J' = S J S, I' = tr(J') 𝟙 − J'."""
    i = np.asarray(inertia, dtype=float)
    s = np.diag(np.asarray(factors, dtype=float))
    j = 0.5 * np.trace(i) * np.eye(3) - i
    j2 = s @ j @ s
    out = np.trace(j2) * np.eye(3) - j2
    return 0.5 * (out + out.T)


def _scaled_function(f: CoordinateFunction, s: float) -> CoordinateFunction:
    if s == 1.0:
        return f
    if isinstance(f, Constant):
        return Constant(f.value * s)
    if isinstance(f, Multiplier):
        return Multiplier(f.function, f.scale * s)
    return Multiplier(f, s)


def _scale_point(p: PathPoint, s: Array) -> PathPoint:
    if isinstance(p, MovingPathPoint):
        funs = tuple(
            None if f is None else _scaled_function(f, float(s[k]))
            for k, f in enumerate(p.functions)
        )
        return replace(p, location=p.location * s, functions=funs)
    return replace(p, location=p.location * s)


def _scale_wrap(w: WrapObject, s: Array) -> WrapObject:
    r = pin.rpy.rpyToMatrix(0.0, 0.0, 0.0)
    # body-fixed XYZ rotation of the wrap frame; its local z is the cylinder axis
    for k, ang in enumerate(np.asarray(w.xyz_body_rotation, dtype=float)):
        r = r @ pin.AngleAxis(float(ang), np.eye(3)[k]).toRotationMatrix()
    local = np.abs(r)  # |R|: how much of each body axis each local axis holds
    s_local = np.sqrt((local**2).T @ s**2)  # factor along each local axis
    if w.kind == "sphere":
        radius = w.radius * float(np.mean(s))
    else:
        radius = w.radius * float(np.mean(s_local[:2]))
    return replace(
        w,
        translation=w.translation * s,
        radius=radius,
        length=w.length * float(s_local[2]),
        dimensions=w.dimensions * s_local,
    )


def muscle_path_lengths(model: Model, theta: ArrayLike | None = None) -> dict[str, float]:
    """Musculotendon path length (m) of every muscle at θ (default pose).

    Via-point paths: the polyline through the active points. Muscles with wrap objects use
    :func:`msk.muscles.geometry.muscle_geometry` (wrapping included) when it is available, the
    polyline otherwise."""
    th = model.default_coordinates() if theta is None else np.asarray(theta, dtype=float)
    data = model.create_data()
    forward_kinematics(model, data, th)
    out = {}
    for m in model.muscles:
        pts = []
        for p in m.points:
            if isinstance(p, ConditionalPathPoint):
                v = th[model.coordinate_index(p.coordinate)]
                if not (p.range[0] <= v <= p.range[1]):
                    continue
            loc = np.asarray(p.location, dtype=float).copy()
            if isinstance(p, MovingPathPoint):
                for k, (c, f) in enumerate(zip(p.coordinates, p.functions)):
                    if c is not None and f is not None:
                        loc[k] = float(f(th[model.coordinate_index(c)]))
            pts.append(data.oMf[model.body_frame[p.body]].act(loc))
        out[m.name] = float(sum(np.linalg.norm(b - a) for a, b in itertools.pairwise(pts)))
    if any(getattr(m, "wraps", ()) for m in model.muscles):
        try:
            from msk.muscles.geometry import muscle_geometry

            lengths = np.asarray(muscle_geometry(model, th[None]).lengths, dtype=float)[0]
        except (ImportError, MskError):  # pragma: no cover - geometry module optional here
            return out
        for k, m in enumerate(model.muscles):
            if getattr(m, "wraps", ()):
                out[m.name] = float(lengths[k])
    return out


def apply_scale_factors(
    model: Model,
    factors: Mapping[str, ArrayLike],
    *,
    body_mass: float | None = None,
    theta: ArrayLike | None = None,
) -> Model:
    """A new model scaled by per-body factors (see the module docstring); ``model`` unchanged."""
    known = {b.name for b in model.bodies}
    unknown = set(factors) - known
    if unknown:
        raise ModelError(f"scaling: model {model.name} has no bodies {sorted(unknown)}")
    sf: dict[str, Array] = {b.name: np.ones(3) for b in model.bodies}
    sf[GROUND] = np.ones(3)
    for name, f in factors.items():
        v = np.asarray(f, dtype=float).reshape(-1)
        v = np.full(3, v[0]) if v.size == 1 else v
        if v.shape != (3,) or not np.all(np.isfinite(v)) or np.any(v <= 0):
            raise ModelError(f"scaling: body {name}: factors must be 3 positive numbers, got {f!r}")
        sf[name] = v
    if body_mass is not None and (not np.isfinite(body_mass) or body_mass <= 0):
        raise ModelError(f"scaling: subject mass must be > 0 kg, got {body_mass}")
    mass_ratio = 1.0 if body_mass is None else float(body_mass) / model.total_mass

    bodies = [
        Body(
            b.name,
            b.mass * mass_ratio,
            b.com * sf[b.name],
            scale_inertia(b.inertia, sf[b.name]) * mass_ratio,
        )
        for b in model.bodies
    ]
    joints = []
    for j in model.joints:
        sp, sc = sf[j.parent], sf[j.child]
        po = pin.SE3(j.parent_offset.rotation, j.parent_offset.translation * sp)
        co = pin.SE3(j.child_offset.rotation, j.child_offset.translation * sc)
        axes = []
        for ax in j.axes:
            if ax.kind == "prismatic":
                s = float(np.linalg.norm(sp * ax.axis))
                ax = Axis(ax.kind, ax.axis, ax.coordinate, _scaled_function(ax.function, s))
            axes.append(ax)
        joints.append(Joint(j.name, j.parent, j.child, po, co, tuple(axes)))
    markers = [Marker(mk.name, mk.body, mk.offset * sf[mk.body]) for mk in model.markers]
    muscles_in = [
        replace(m, points=tuple(_scale_point(p, sf[p.body]) for p in m.points))
        if isinstance(m, Muscle)
        else m
        for m in model.muscles
    ]
    metadata = dict(model.metadata)
    wraps = metadata.get("wrap_objects")
    if wraps:
        metadata["wrap_objects"] = tuple(_scale_wrap(w, sf[w.body]) for w in wraps)
    metadata["scale_factors"] = {k: v.tolist() for k, v in sf.items() if k != GROUND}
    scaled = Model(
        name=model.name,
        bodies=bodies,
        joints=joints,
        coordinates=model.coordinates,
        markers=markers,
        muscles=muscles_in,
        gravity=model.gravity,
        metadata=metadata,
    )
    if not model.muscles:
        return scaled
    before = muscle_path_lengths(model, theta)
    after = muscle_path_lengths(scaled, theta)
    muscles = []
    for m in scaled.muscles:
        if isinstance(m, Muscle) and before.get(m.name, 0.0) > 0:
            r = after[m.name] / before[m.name]
            m = replace(
                m,
                optimal_fiber_length=m.optimal_fiber_length * r,
                tendon_slack_length=m.tendon_slack_length * r,
            )
        muscles.append(m)
    return scaled.with_muscles(muscles)


def scale_model(
    model: Model,
    static_markers: Any = None,
    *,
    measurements: Sequence[Measurement] = (),
    scale_factors: Mapping[str, ArrayLike] | None = None,
    body_mass: float | None = None,
    theta: ArrayLike | None = None,
    marker_names: Mapping[str, str] | None = None,
) -> Model:
    """Scale ``model`` to a subject: measured factors from ``static_markers`` and
    ``measurements``, then ``scale_factors`` (manual, per body) override them; segment masses
    follow ``body_mass`` (kg). The factors and ratios used are in
    ``metadata["scale_factors"]`` / ``metadata["scale_ratios"]``."""
    factors: dict[str, Array] = {}
    ratios: dict[str, float] = {}
    if measurements:
        if static_markers is None:
            raise MissingDataError("scaling: measurements need a static trial")
        factors, ratios = measure_scale_factors(
            model, static_markers, measurements, theta=theta, marker_names=marker_names
        )
    for name, f in (scale_factors or {}).items():
        v = np.asarray(f, dtype=float).reshape(-1)
        factors[name] = np.full(3, v[0]) if v.size == 1 else v
    out = apply_scale_factors(model, factors, body_mass=body_mass, theta=theta)
    return out.with_metadata(scale_ratios=ratios)


# ------------------------------------------------------------------------------------------
# OpenSim Scale setup files
# ------------------------------------------------------------------------------------------
def read_scale_setup(path: str | Path) -> ScaleSetup:
    """Measurements, manual scales, mass and time range of an OpenSim ``ScaleTool`` setup."""
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as exc:
        raise FileFormatError(f"{path}: cannot read Scale setup: {exc}") from exc

    def txt(el: ET.Element | None, tag: str) -> str:
        c = el.find(tag) if el is not None else None
        return (c.text or "").strip() if c is not None and c.text else ""

    measurements = []
    for m in root.iter("Measurement"):
        if txt(m, "apply").lower() == "false":
            continue
        pairs = []
        for mp in m.iter("MarkerPair"):
            names = txt(mp, "markers").split()
            if len(names) != 2:
                raise FileFormatError(f"{path}: measurement {m.get('name')}: bad pair {names}")
            pairs.append((names[0], names[1]))
        bodies, axes = [], "XYZ"
        for bs in m.iter("BodyScale"):
            bodies.append(bs.get("name", ""))
            axes = "".join(txt(bs, "axes").split()) or "XYZ"
        measurements.append(Measurement(m.get("name", ""), tuple(pairs), tuple(bodies), axes))
    manual: dict[str, Array] = {}
    for sc in root.iter("Scale"):
        if txt(sc, "apply").lower() == "false":
            continue
        seg = txt(sc, "segment")
        vals = np.array([float(v) for v in txt(sc, "scales").split()])
        if seg and vals.size == 3:
            manual[seg] = vals
    tool = root.find(".//ScaleTool")
    mass_t = txt(tool if tool is not None else root, "mass")
    tr = None
    ms = root.find(".//ModelScaler")
    if ms is not None and txt(ms, "time_range"):
        v = [float(x) for x in txt(ms, "time_range").split()]
        tr = (v[0], v[1])
    order = tuple(txt(ms, "scaling_order").split()) if ms is not None else ()
    return ScaleSetup(
        tuple(measurements),
        manual,
        float(mass_t) if mass_t else None,
        tr,
        order or ("measurements", "manualScale"),
    )


# ---------------------------------------------------------------------------------------------
# marker placement (OpenSim Scale's MarkerPlacer step)
# ---------------------------------------------------------------------------------------------
def bone_segments(model: Model, data: pin.Data) -> list[tuple[str, Array, Array]]:
    """Bone segments per body, world frame, from ``data.oMf`` (after forward kinematics):
    ``(body, a, b)`` from the body origin to each child body's origin (a leaf body: from its
    origin to twice its centre of mass)."""
    out: list[tuple[str, Array, Array]] = []
    for b in model.bodies:
        o = data.oMf[model.body_frame[b.name]]
        kids = [j.child for j in model.joints if j.parent == b.name]
        ends = [data.oMf[model.body_frame[c]].translation for c in kids]
        if not ends:
            ends = [o.act(2.0 * np.asarray(b.com, dtype=float))]
        out.extend((b.name, o.translation.copy(), np.array(e, dtype=float)) for e in ends)
    return out


def point_segment_distance(p: ArrayLike, a: ArrayLike, b: ArrayLike) -> float:
    """Distance from the point ``p`` to the segment [a, b]: ‖p − (a + t (b − a))‖ with
    t = clip((p − a)·(b − a) / ‖b − a‖², 0, 1)."""
    p, a, b = (np.asarray(x, dtype=float) for x in (p, a, b))
    d = b - a
    t = float(np.clip((p - a) @ d / max(float(d @ d), 1e-12), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * d)))


def _bone_distances(
    points: Array, seg_a: Array, seg_d: Array, seg_body: NDArray[np.int64], n_bodies: int
) -> Array:
    """(B,) distance from ``points[k]`` (each body's own point, (B, 3)) to the nearest bone
    segment of body k (segments a + t d, t ∈ [0, 1], of body ``seg_body``): the
    :func:`point_segment_distance` of every segment at once."""
    p = points[seg_body] - seg_a
    t = np.clip((p * seg_d).sum(axis=1) / np.maximum((seg_d * seg_d).sum(axis=1), 1e-12), 0, 1)
    d = np.linalg.norm(p - t[:, None] * seg_d, axis=1)
    out = np.full(n_bodies, np.inf)
    np.minimum.at(out, seg_body, d)
    return out


def _girdle_moved(model: Model, labels: Sequence[str], move: Sequence[str]) -> tuple[str, ...]:
    """``move`` plus the model's shoulder-girdle markers in ``labels`` when the model has no
    shoulder-girdle segment (:func:`msk.model.markersets.shoulder_girdle_markers`): gait2392's
    acromion markers sit on its rigid torso where a generic trunk puts them, not on a bone of
    the model, so the subject's are placed like technical markers (their shoulder width and
    the shoulders' position over the pelvis are the subject's: left where the generic torso
    puts them, UWA's acromia stayed 55 mm from the model's through the walk, 10 mm once
    placed)."""
    present = [mk.name for mk in model.markers if mk.name in set(labels)]
    girdle = shoulder_girdle_markers(present, [b.name for b in model.bodies])
    return tuple(move) + tuple(m for m in girdle if m not in move)


#: the coordinates of a static's standing pose kept in ``marker_placement.static_pose_deg``
#: (gait2392 / Rajagopal names): the pelvis' tilt and list, the hips' flexion
STATIC_POSE_COORDINATES = ("pelvis_tilt", "pelvis_list", "hip_flexion_r", "hip_flexion_l")


def place_markers(
    model: Model,
    static_markers: np.ndarray,
    labels: Sequence[str],
    time: np.ndarray,
    *,
    max_distance_m: float = 0.25,
    move: Sequence[str] = (),
    hints: Mapping[str, str] | None = None,
    centres: Mapping[str, tuple[str, ArrayLike, ArrayLike]] | None = None,
    coordinate_tasks: Mapping[str, tuple[float, float]] | None = None,
    relocate: Sequence[str] = (),
) -> tuple[Model, dict[str, Any]]:
    """Add the static trial's non-model markers to ``model`` (OpenSim's MarkerPlacer idea).

    ``centres`` (name → (body, point in the body, its static position), e.g. the knee and
    ankle centres of :func:`static_joint_centres` at the tibia's and talus' origins) are
    virtual markers of the static pose θ̄ only: with lateral markers alone (Plug-in Gait) the
    leg's rotation about its long axis in the static is otherwise set by the generic model's
    lateral-marker offsets, and the wands placed from that pose carry its error into every
    frame of the motion (the knee flexion axis off the subject's: tibia and toe markers 60 mm
    off at 65° of knee flexion on PiG_Motion3, 8 mm in stance). ``coordinate_tasks`` (name →
    (value rad, weight)) hold coordinates the static's model markers do not observe (a foot
    with a heel marker only: subtalar and mtp) near neutral in θ̄, as in the motion's IK.

    ``hints`` (lab label → body, e.g. :meth:`msk.model.markersets.MarkerSetMatch.body_hints`) puts a
    marker of a known bony landmark on its own body when that body is within
    ``max_distance_m``, instead of on the nearest bone.

    The static pose θ̄ is the median of inverse kinematics on up to 9 frames of the static
    trial, with the markers the model already has (``labels`` are in model names where a model
    marker matches; at least 3 per frame); every other static marker (mean position x̄) is
    fixed to the body whose bone segment (:func:`bone_segments`) is nearest, at its measured
    position in that body's frame: ``p_b = (oMf_b(θ̄))⁻¹ x̄``. Points that are not measured
    markers (:func:`msk.io.c3d.is_measured_marker`: unlabelled trajectories ``*N``, Plug-in
    Gait's virtual segment points ``PELO``…) are not placed: a ``*N`` label names another
    point in every trial, and PiG's points follow PiG's own segments, not the subject's bones.
    Nor is a marker farther than ``max_distance_m`` from every bone segment: it sits on a
    segment the model does not have (arm markers on a model without arms would be fixed to the
    torso, and an arm held out in the static trial is ~0.5 m from where it swings in gait). The
    default keeps skin and wand markers (≤ 0.17 m from their bone on the Grand Challenge and
    Plug-in Gait statics) and leaves out elbows and wrists (≥ 0.33 m on subject01's static).

    ``move`` names model markers that are not anatomical (technical clusters: a lab puts them
    where it likes): θ̄ is solved without them and they are moved, on their own body, to where
    the static trial puts them — OpenSim's ``move_model_markers`` restricted to these markers.
    ``relocate`` names model markers that pin θ̄ and are then moved alike (OpenSim's
    MarkerPlacer with these markers not ``fixed``): the static pose is the generic markers'
    best fit, and the subject's landmarks sit where the static puts them relative to it, not
    at the generic offsets (a lateral epicondyle marker 26 mm above gait2392's on UNIPD's
    subject, in the femur frame through the walk; the knee and ankle markers left 34–38 mm
    off by a thigh scaled between joint centres).
    Shoulder-girdle markers of a model without that segment (acromia on gait2392's torso) are
    always moved (:func:`_girdle_moved`).

    Args:
        model: the (scaled) model, in the frame of ``static_markers``.
        static_markers: (N, M, 3) m, NaN gaps.
        labels: the M labels.
        time: (N,) s.
        max_distance_m: largest distance of a placed marker from its bone segment.
        move: model markers to move to their static positions (on their body).
        relocate: model markers that pin θ̄ and are then moved to their static positions.

    Returns:
        The model with the markers added, and ``{"static_marker_rms_m", "static_pose_deg",
        "placed", "not_markers", "too_far", "moved", "relocated"}`` (static_pose_deg: θ̄'s
        :data:`STATIC_POSE_COORDINATES`, deg; placed: marker → body;
        not_markers: the labels left out as not measured markers; too_far: marker → [nearest
        body, distance in m] of the markers left out by ``max_distance_m``; moved, relocated:
        marker → displacement in m).

    Raises:
        ModelError: a ``move`` name is not a model marker.
        KinematicsError: too few markers in every static frame.
        MissingDataError: no static frame could be solved.
    """
    from msk.io.c3d import is_measured_marker
    from msk.kinematics.ik import solve_kinematics

    unknown = sorted(set(move) - set(model.marker_names))
    if unknown:
        raise ModelError(f"model {model.name}: no marker {unknown[0]!r} to move")
    move = _girdle_moved(model, labels, move)
    n = static_markers.shape[0]
    frames = np.unique(np.linspace(0, n - 1, min(n, 9)).round().astype(int))
    base = model.with_markers([m for m in model.markers if m.name not in move]) if move else model
    ik_markers, ik_labels = static_markers, list(labels)
    if centres:
        virt = {k: v for k, v in centres.items() if v[0] in model.body_frame}
        base = base.with_markers(
            [
                *base.markers,
                *(Marker(k, b, np.asarray(o, dtype=float)) for k, (b, o, _) in virt.items()),
            ]
        )
        extra = np.broadcast_to(
            np.array([np.asarray(x, dtype=float) for _, _, x in virt.values()]).reshape(1, -1, 3),
            (n, len(virt), 3),
        )
        ik_markers = np.concatenate([static_markers, extra], axis=1)
        ik_labels += list(virt)
    # the moved markers still pin the pose where the others are too few to determine it
    # (3 coordinates per marker at most; e.g. a static with pelvis markers and feet only)
    seen = {lab for lab in ik_labels if lab in base.marker_names}
    n_free = sum(not c.locked for c in model.coordinates)
    if move and 3 * len(seen) < n_free:
        base = model
        ik_markers, ik_labels = static_markers, list(labels)
    kin = solve_kinematics(
        base, ik_markers[frames], ik_labels, time[frames], cutoff_hz=None, min_markers=3,
        coordinate_tasks=dict(coordinate_tasks) if coordinate_tasks else None,
    )  # fmt: skip
    ok = np.isfinite(kin.q).all(axis=1)
    if not ok.any():
        raise MissingDataError("static trial: no frame could be solved for marker placement")
    theta = np.median(kin.q[ok], axis=0)
    data = model.create_data()
    forward_kinematics(model, data, theta)
    segs = bone_segments(model, data)
    with warnings.catch_warnings():  # a marker never seen: NaN mean, skipped below
        warnings.simplefilter("ignore", RuntimeWarning)
        mean = np.nanmean(static_markers, axis=0)
    known = set(model.marker_names)
    where = {lab: i for i, lab in enumerate(labels)}
    markers = list(model.markers)
    moved: dict[str, float] = {}
    relocated: dict[str, float] = {}
    for k, mk in enumerate(markers):
        i = where.get(mk.name)
        if (
            (mk.name in move or mk.name in relocate)
            and i is not None
            and np.isfinite(mean[i]).all()
        ):
            local = np.asarray(data.oMf[model.body_frame[mk.body]].actInv(mean[i]), dtype=float)
            d = float(np.linalg.norm(local - np.asarray(mk.offset, dtype=float)))
            (moved if mk.name in move else relocated)[mk.name] = d
            markers[k] = Marker(mk.name, mk.body, local)
    added = []
    placed: dict[str, str] = {}
    too_far: dict[str, list[Any]] = {}
    not_markers = [lab for lab in labels if lab not in known and not is_measured_marker(lab)]
    for i, lab in enumerate(labels):
        if lab in known or lab in not_markers or not np.isfinite(mean[i]).all():
            continue
        dist, body = min((point_segment_distance(mean[i], a, b), nm) for nm, a, b in segs)
        hint = (hints or {}).get(lab)
        if hint is not None and hint != body and hint in model.body_frame:
            # the landmark's own body (a PSIS is on the pelvis even where the lumbar spine's
            # bone segment passes nearer), if it is within reach
            d_hint = min(
                (point_segment_distance(mean[i], a, b) for nm, a, b in segs if nm == hint),
                default=np.inf,
            )
            if d_hint <= max_distance_m:
                dist, body = d_hint, hint
        if dist > max_distance_m:
            too_far[lab] = [body, dist]
            continue
        local = data.oMf[model.body_frame[body]].actInv(mean[i])
        added.append(Marker(lab, body, np.asarray(local, dtype=float)))
        placed[lab] = body
    names = model.coordinate_names
    info = {
        "static_marker_rms_m": float(np.nanmean(kin.marker_rms[ok])),
        # the standing pose the placement read the static in (its plausibility gates:
        # msk.quality.model_flags)
        "static_pose_deg": {
            c: float(np.degrees(theta[names.index(c)]))
            for c in STATIC_POSE_COORDINATES
            if c in names
        },
        "placed": placed,
        "not_markers": not_markers,
        "too_far": too_far,
        "moved": moved,
        "relocated": relocated,
    }
    return model.with_markers([*markers, *added]), info


# ---------------------------------------------------------------------------------------------
# scaling without a static trial: motion markers, height, and how each segment was scaled
# ---------------------------------------------------------------------------------------------
#: How a body's scale factors were obtained (``ScalingReport.methods``).
SCALING_METHODS: tuple[str, ...] = (
    "static markers",
    "motion markers",
    "height",
    "unscaled",
    "functional joint centres",
)


def _functional_override(
    measured: dict[str, Array], ratios: dict[str, float], functional: Mapping[str, float] | None
) -> None:
    """Bodies scaled from functional joint centres
    (:func:`msk.personalise.leg_split.functional_leg_split`)
    replace their marker measurement (in place); their method is set after completion."""
    for body, f in (functional or {}).items():
        measured[body] = np.full(3, float(f))
        ratios[f"{body} (functional joint centres)"] = float(f)


def _functional_methods(
    methods: dict[str, str], functional: Mapping[str, float] | None
) -> dict[str, str]:
    return {**methods, **{b: "functional joint centres" for b in (functional or {})}}


#: Stature (m) of generic models whose documentation states it, by model name: gait2392 "about
#: 1.8 m tall and 75.16 kg" (OpenSim documentation, Gait 2392 and 2354 Models).
MODEL_HEIGHT_M: Mapping[str, float] = {"3DGaitModel2392": 1.80, "gait2392": 1.80}


def _m(name: str, pairs: Sequence[tuple[str, str]], bodies: Sequence[str]) -> Measurement:
    return Measurement(name, tuple(pairs), tuple(bodies))


def _sided_alternatives(s: str, side: str) -> list[tuple[str, list[Measurement]]]:
    p = s.upper()
    foot = (f"talus_{side}", f"calcn_{side}", f"toes_{side}")
    leg = (f"femur_{side}", f"tibia_{side}")
    return [
        (
            f"femur_{side}",
            [
                _m(f"femur_{side}", [(f"{p}.ASIS", f"{p}.Knee.Lat")], [f"femur_{side}"]),
                _m(f"femur_{side}", [(f"{p}.ASIS", f"{p}.Knee.Med")], [f"femur_{side}"]),
                # no knee marker (cluster-only and Grand Challenge walks): the whole leg, femur
                # and tibia alike, from the pelvis to the ankle or the heel (pose-matched in a
                # motion trial, so the knee's flexion does not shorten it)
                _m(f"leg_{side}", [(f"{p}.ASIS", f"{p}.Ankle.Lat")], leg),
                _m(f"leg_{side}", [(f"{p}.ASIS", f"{p}.Heel")], leg),
            ],
        ),
        (
            f"tibia_{side}",
            [
                _m(f"tibia_{side}", [(f"{p}.Knee.Lat", f"{p}.Ankle.Lat")], [f"tibia_{side}"]),
                _m(f"tibia_{side}", [(f"{p}.Knee.Med", f"{p}.Ankle.Med")], [f"tibia_{side}"]),
                _m(f"leg_{side}", [(f"{p}.ASIS", f"{p}.Ankle.Lat")], leg),
                _m(f"leg_{side}", [(f"{p}.ASIS", f"{p}.Heel")], leg),
            ],
        ),
        (
            f"foot_{side}",
            [
                _m(f"foot_{side}", [(f"{p}.Heel", f"{p}.Toe.Tip")], foot),
                _m(
                    f"foot_{side}",
                    [(f"{p}.Heel", f"{p}.Toe.Med"), (f"{p}.Heel", f"{p}.Toe.Lat")],
                    foot,
                ),
                _m(f"foot_{side}", [(f"{p}.Heel", f"{p}.Toe.Med")], foot),
                _m(f"foot_{side}", [(f"{p}.Heel", f"{p}.Toe.Lat")], foot),
            ],
        ),
    ]


#: Scaling measurements of gait2392 (name, model marker pairs, bodies): the reference set a
#: session names in ``methods.scaling_measurements``; each is used where both markers exist in
#: the model and (after ``[markers] rename``) in the static trial.
DEFAULT_MEASUREMENTS: tuple[tuple[str, tuple[tuple[str, str], ...], tuple[str, ...]], ...] = (
    ("pelvis", (("R.ASIS", "L.ASIS"),), ("pelvis",)),
    ("femur_r", (("R.ASIS", "R.Knee.Lat"),), ("femur_r",)),
    ("femur_l", (("L.ASIS", "L.Knee.Lat"),), ("femur_l",)),
    ("tibia_r", (("R.Knee.Lat", "R.Ankle.Lat"),), ("tibia_r",)),
    ("tibia_l", (("L.Knee.Lat", "L.Ankle.Lat"),), ("tibia_l",)),
    ("foot_r", (("R.Heel", "R.Toe.Tip"),), ("talus_r", "calcn_r", "toes_r")),
    ("foot_l", (("L.Heel", "L.Toe.Tip"),), ("talus_l", "calcn_l", "toes_l")),
    ("torso", (("V.Sacral", "Sternum"),), ("torso",)),
)

#: gait2392 measurements, per segment the alternatives in order of preference (the first whose
#: markers are all there is used, :func:`choose_measurements`): the pipeline's defaults first,
#: then medial markers (IOR/CAST, Grand Challenge), metatarsal heads for the foot (UWA, IOR).
SEGMENT_MEASUREMENTS: tuple[tuple[str, tuple[Measurement, ...]], ...] = tuple(
    (name, tuple(alts))
    for name, alts in [
        ("pelvis", [_m("pelvis", [("R.ASIS", "L.ASIS")], ["pelvis"])]),
        *_sided_alternatives("r", "r"),
        *_sided_alternatives("l", "l"),
        (
            "torso",
            [
                _m("torso", [("V.Sacral", "Sternum")], ["torso"]),
                _m("torso", [("V.Sacral", "R.Acromium"), ("V.Sacral", "L.Acromium")], ["torso"]),
            ],
        ),
    ]
)


def choose_measurements(
    alternatives: Sequence[tuple[str, Sequence[Measurement]]], markers: Iterable[str]
) -> list[Measurement]:
    """Per segment, the first alternative of ``alternatives`` (e.g. :data:`SEGMENT_MEASUREMENTS`)
    whose marker pairs are all in ``markers`` (model names the trial and the model share)."""
    have = set(markers)
    out = []
    for _, alts in alternatives:
        use = usable_measurements(list(alts), have)
        if use and use[0] not in out:  # a whole-leg measurement serves femur and tibia once
            out.append(use[0])
    return out


def model_height(model: Model) -> tuple[float, str]:
    """The generic model's stature (m) and where it comes from: ``metadata["height_m"]``, then
    :data:`MODEL_HEIGHT_M` by model name, then an estimate — the highest marker above the
    lowest marker or body origin in the default pose (gait2392: 1.67 m against its documented
    1.8 m: a head marker is not at the vertex)."""
    h = model.metadata.get("height_m")
    if h is not None:
        return float(h), "model metadata"
    if model.name in MODEL_HEIGHT_M:
        return MODEL_HEIGHT_M[model.name], f"documented stature of {model.name}"
    data = model.create_data()
    forward_kinematics(model, data, model.default_coordinates())
    up = -np.asarray(model.gravity, dtype=float)
    up = up / np.linalg.norm(up)
    pts = [data.oMf[model.marker_frame[m]].translation for m in model.marker_names]
    pts += [data.oMf[model.body_frame[b.name]].translation for b in model.bodies]
    z = np.asarray(pts, dtype=float) @ up
    return float(z.max() - z.min()), "estimated from the default pose (markers, body origins)"


@dataclass(frozen=True)
class ScalingReport:
    """How a model was scaled.

    Attributes:
        factors: body → (3,) factors applied.
        methods: body → one of :data:`SCALING_METHODS` (every body of the model).
        ratios: measurement → ratio (experimental / model distance).
        details: measurement → {"pairs", "frames", "iqr_ratio"} (motion) or {"pairs"}.
        height_factor: H_subject / H_model when the height was given, else None.
        model_height_m: the model stature used and its source.
        messages: what could not be done (a segment left unscaled, a measurement skipped).
    """

    factors: Mapping[str, Array]
    methods: Mapping[str, str]
    ratios: Mapping[str, float]
    details: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    height_factor: float | None = None
    model_height_m: tuple[float, str] | None = None
    messages: tuple[str, ...] = ()

    def summary(self) -> dict[str, Any]:
        """JSON-ready: per body the method and factors, the ratios and the messages."""
        return {
            "bodies": {
                b: {"method": self.methods[b], "factors": np.asarray(self.factors[b]).tolist()}
                for b in self.methods
            },
            "ratios": dict(self.ratios),
            "height_factor": self.height_factor,
            "model_height_m": None if self.model_height_m is None else self.model_height_m[0],
            "messages": list(self.messages),
            "leg_starts": {k: dict(v["start"]) for k, v in self.details.items() if "start" in v},
        }


def complete_scale_factors(
    model: Model,
    measured: Mapping[str, ArrayLike],
    *,
    source: str,
    height_m: float | None = None,
) -> tuple[dict[str, Array], dict[str, str], float | None, tuple[float, str] | None]:
    """Every body's factors and method: ``measured`` bodies by ``source`` ("static markers" or
    "motion markers"), the others by the stature ratio s = H / H_model (uniform; OpenSim-style
    "scale by height", :func:`model_height`) when ``height_m`` is given, else by the median
    factor of the measured bodies (the subject's size as the markers show it; method
    "height", the returned height factor says which), else 1 ("unscaled", nothing measured).
    Returns (factors, methods, height factor, model height)."""
    if source not in SCALING_METHODS[:2]:
        raise ModelError(f"scaling: source must be one of {SCALING_METHODS[:2]}, got {source!r}")
    hf, mh = None, None
    if height_m is not None:
        if not np.isfinite(height_m) or not 0.5 <= height_m <= 2.5:
            raise ModelError(f"scaling: height {height_m} m is not a plausible stature")
        mh = model_height(model)
        hf = float(height_m) / mh[0]
    elif measured:
        # no stature given: the subject's size from the segments the markers did measure (the
        # median of their factors), rather than a segment left at the generic size
        mh = model_height(model)
        hf = float(
            np.median([np.asarray(v, dtype=float).reshape(-1)[0] for v in measured.values()])
        )
    factors: dict[str, Array] = {}
    methods: dict[str, str] = {}
    for b in model.bodies:
        if b.name in measured:
            v = np.asarray(measured[b.name], dtype=float).reshape(-1)
            factors[b.name] = np.full(3, v[0]) if v.size == 1 else v
            methods[b.name] = source
        elif hf is not None:
            factors[b.name] = np.full(3, hf)
            methods[b.name] = "height"
        else:
            factors[b.name] = np.ones(3)
            methods[b.name] = "unscaled"
    return factors, methods, hf, mh


def _pair_distances(
    markers: Array, col: Mapping[str, int], a: str, b: str
) -> tuple[Array, NDArray[np.bool_]]:
    d = np.linalg.norm(markers[:, col[a]] - markers[:, col[b]], axis=1)
    return d, np.isfinite(d)


def measure_scale_factors_from_motion(
    model: Model,
    markers: ArrayLike,
    labels: Sequence[str],
    measurements: Sequence[Measurement],
    *,
    q: ArrayLike | None = None,
    min_frames: int = 10,
) -> tuple[dict[str, Array], dict[str, float], dict[str, dict[str, Any]]]:
    """Per-body factors from a motion trial (no static): for each marker pair the distance
    d_t = ‖x_a(t) − x_b(t)‖ in every frame where both are tracked, over the model's distance.

    Without ``q`` the ratio is median_t(d_t) / ‖x_a(θ₀) − x_b(θ₀)‖ (default pose): exact for
    two markers on one rigid segment (their distance is constant in any motion). A pair across
    a joint (gait2392's R.ASIS–R.Knee.Lat spans the hip) changes length with the joint angle
    (by ±5 % over a gait cycle), so with ``q`` ((N, n_coords), e.g. inverse kinematics of the
    same frames on this model or a scaled copy: joint angles do not depend on the scale) each
    frame is compared with the model in that frame's pose, r_t = d_t / ‖x_a(q_t) − x_b(q_t)‖,
    and the ratio is median_t(r_t): the measurement a static trial makes, in every frame.
    Medians resist marker swaps and gaps (Hampel's breakdown point 50 %).

    Args:
        model: the generic model (the one to be scaled).
        markers: (N, M, 3) m, NaN gaps, in any frame (distances only).
        labels: the M labels in the model's marker names.
        measurements: as for :func:`measure_scale_factors`.
        q: (N, n_coords) pose per frame (NaN rows skipped), optional.
        min_frames: fewest frames where a pair is tracked.

    Returns:
        (body → (3,) factors, measurement → ratio, measurement → {"pairs", "frames",
        "iqr_ratio": interquartile range of the per-frame ratios / median}).

    Raises:
        MissingDataError: a marker of a measurement is not in ``labels`` or is tracked in fewer
            than ``min_frames`` frames.
    """
    from msk.model.markersets import zeros_as_gaps

    x = zeros_as_gaps(markers)
    labels = tuple(labels)
    if x.ndim != 3 or x.shape[2] != 3 or x.shape[1] != len(labels):
        raise MissingDataError(f"scaling: markers {x.shape} do not match {len(labels)} labels")
    col = {lab: i for i, lab in reversed(list(enumerate(labels)))}
    qq = None if q is None else np.asarray(q, dtype=float)
    if qq is not None and qq.shape != (x.shape[0], model.n_coords):
        raise MissingDataError(f"scaling: q {qq.shape} must be ({x.shape[0]}, {model.n_coords})")
    data = model.create_data()
    forward_kinematics(model, data, model.default_coordinates())
    default = {
        m: np.asarray(data.oMf[model.marker_frame[m]].translation) for m in model.marker_names
    }
    posed: dict[str, Array] = {}
    if qq is not None:
        from msk.model.core import marker_positions

        okq = np.isfinite(qq).all(axis=1)
        pos = np.full((x.shape[0], len(model.marker_names), 3), np.nan)
        if okq.any():
            pos[okq] = marker_positions(model, qq[okq])
        posed = {m: pos[:, i] for i, m in enumerate(model.marker_names)}
    factors: dict[str, Array] = {}
    ratios: dict[str, float] = {}
    details: dict[str, dict[str, Any]] = {}
    for meas in measurements:
        rs, n_min, spread = [], x.shape[0], []
        for a, b in meas.marker_pairs:
            for mk in (a, b):
                if mk not in col:
                    raise MissingDataError(f"scaling: the motion trial has no marker {mk!r}")
                if mk not in default:
                    raise MissingDataError(f"scaling: model {model.name} has no marker {mk!r}")
            d, ok = _pair_distances(x, col, a, b)
            if qq is not None:
                dm = np.linalg.norm(posed[a] - posed[b], axis=1)
                ok &= np.isfinite(dm)
                r = d[ok] / dm[ok]
            else:
                r = d[ok] / float(np.linalg.norm(default[a] - default[b]))
            if r.size < min_frames:
                raise MissingDataError(
                    f"scaling: {a}–{b} tracked together in {r.size} frames (< {min_frames})"
                )
            med = float(np.median(r))
            q1, q3 = np.percentile(r, [25, 75])
            rs.append(med)
            spread.append(float((q3 - q1) / med))
            n_min = min(n_min, int(r.size))
        ratio = float(np.mean(rs))
        ratios[meas.name] = ratio
        details[meas.name] = {
            "pairs": [list(p) for p in meas.marker_pairs],
            "frames": n_min,
            "iqr_ratio": max(spread),
        }
        for body in meas.bodies:
            if body not in model.body_joint:
                continue
            f = factors.get(body, np.ones(3)).copy()
            for k, ax in enumerate("XYZ"):
                if ax in meas.axes.upper():
                    f[k] = ratio
            factors[body] = f
    return factors, ratios, details


#: weight (per rad²; markers per m²) of the pull towards neutral of a placement retried with it
#: (:func:`place_markers_from_motion`): 10° off neutral costs as much as one marker 5.5 mm off,
#: enough to settle rotations the markers leave free (UWA fast walking: placement IK 78 → 19 mm)
NEUTRAL_TASK_WEIGHT = 0.001


#: weight (per rad²) of the pull towards neutral in the pose-matched scaling's inverse kinematics
#: of a trial whose model markers leave the knees unobserved (:func:`scale_from_motion`): 1 rad
#: costs as much as one marker 3 mm off — enough to make the minimum along the flat directions
#: (the leg's swivel about the hip–ankle line) unique, too weak to bend a running knee
#: (:data:`NEUTRAL_TASK_WEIGHT` there moved UWA running's leg factors)
SCALING_NEUTRAL_WEIGHT = 1e-5


#: median marker RMS (m) of a motion placement above which it is retried with the pull towards
#: neutral (a well-tracked gait trial places at 20–25 mm with the generic foot markers)
PLACEMENT_RETRY_RMS_M = 0.030


#: weight (per rad²) of the pull towards neutral in the passes of
#: :func:`refine_placement_from_motion` (the value of :data:`SCALING_NEUTRAL_WEIGHT`, for the same
#: reason): 1 rad costs as much as one marker 3 mm off, which makes each pass's minimum along
#: the flat directions of a cluster-only leg unique (without it UWA fast walking's passes jumped
#: from a task IK cost of 9.9 mm to 40–118 mm in most rounds, and where the descent stopped
#: moved with 1e-4 of its input: 8.4–9.9 mm); it moves a walk's ±8° hip rotation by nothing
#: the markers can see (synthetic: ``tests/personalise/test_scaling.py``)
DESCENT_NEUTRAL_WEIGHT = 1e-5


def _neutral_tasks(
    model: Model, weight: float = NEUTRAL_TASK_WEIGHT
) -> dict[str, tuple[float, float]]:
    """Coordinate tasks pulling every free rotation of ``model`` towards 0 (not translations)
    with ``weight`` (per rad²)."""
    return {
        c.name: (0.0, weight)
        for c in model.coordinates
        if not c.locked and not c.name.endswith(("_tx", "_ty", "_tz"))
    }


def _ik_frames(
    x: Array, labels: Sequence[str], names: Iterable[str], max_frames: int, min_markers: int,
    time: ArrayLike | None = None, max_rate_hz: float = 60.0,
) -> NDArray[np.int64]:  # fmt: skip
    """Up to ``max_frames`` frames with at least ``min_markers`` of ``names``, **consecutive**
    (subsampled to at most ``max_rate_hz``) around the middle of the trial: inverse kinematics
    warm-starts each frame from the previous one, which keeps it on the right branch when few
    markers pin the legs (pelvis and feet only: crouch gait jumped between hip ±120° with
    frames a second apart). When fewer than ``max_frames`` frames remain at that rate, all of
    them at the highest rate that gives at most ``max_frames``: UWA ``Running_1`` tracks its
    markers over ~1 s at 250 Hz, whose middle 120 frames (0.48 s, less than a stride) had
    placed the clusters and measured the legs on one phase of the run (task IK 13.9 mm; over
    the whole window 10.9 mm)."""
    cols = [i for i, lab in enumerate(labels) if lab in set(names)]
    n_seen = np.isfinite(x[:, cols]).all(axis=2).sum(axis=1) if cols else np.zeros(len(x))
    good = np.flatnonzero(n_seen >= min_markers)
    if good.size <= max_frames:
        return good
    step = 1
    if time is not None:
        t = np.asarray(time, dtype=float)
        if t.size > 1 and t[-1] > t[0]:
            rate = (t.size - 1) / (t[-1] - t[0])
            step = max(1, int(np.ceil(rate / max_rate_hz)))
    # a window shorter than max_frames at that rate (a running trial's ~1 s of tracked
    # markers): all of it, at the highest rate that fits, not its middle max_frames frames
    sub = good[::step] if good.size // step >= max_frames else good[:: -(-good.size // max_frames)]
    mid = sub.size // 2
    lo = max(0, min(mid - max_frames // 2, sub.size - max_frames))
    return sub[lo : lo + max_frames]


#: relative difference within which a leg's pose-matched factor is said to be its stature start
#: (:func:`unobserved_leg_starts`): the motion did not lengthen or shorten the stature's leg by
#: more than the 0.5 % (~4 mm of an adult's 0.9 m leg) the measurement's own spread under 0.1 mm
#: of marker noise is below
LEG_START_TOLERANCE = 0.005


#: how far below the stature's leg the default-pose ratio of a leg measured across an
#: unobserved knee must be for :func:`unobserved_leg_starts` to start it from the stature: a
#: walk's ratio is within 5 % of the stature's leg (DM og1 +0.4/+0.6 %, treadmill −0.3/−0.4 %,
#: UWA fast walking −5 %; DM's crouch −7/−9 %), a run's 17–18 % below it (UWA running): 10 %
#: is more than adults' legs differ at one stature, so a ratio that far below it measures a
#: knee flexed through the trial, not a short leg
LEG_START_MAX_SHORTFALL = 0.10


def unobserved_leg_starts(
    ratios: Mapping[str, float], measurements: Sequence[Measurement], height_factor: float | None
) -> dict[str, dict[str, Any]]:
    """The factor each leg measured across a knee no marker observes (``leg_<side>``, the
    pelvis-to-heel pair of :data:`SEGMENT_MEASUREMENTS`) is given before the pose-matched
    inverse kinematics of :func:`scale_from_motion`: the stature ratio ``height_factor`` for
    both legs when either's default-pose ratio is more than :data:`LEG_START_MAX_SHORTFALL`
    below it (a leg whose own ratio is above the stature's keeps its own), else the default-pose
    ratio (as for any other pair; also when no stature is given).

    Why. The default-pose ratio of that pair is the median hip-to-heel distance over the
    standing model's: a lower bound of the leg, by the knee's flexion through the trial (UWA
    running, knee flexed 20–120°: 0.83). A leg scaled that short cannot reach its feet in most
    frames; the IK of pelvis and foot markers then wandered to the hip's ±120° bounds in a third
    of the frames and the left leg's pose-matched factor landed at 0.92–1.05 with 0.1 mm of
    marker noise (a 6 % left/right difference). The pose-matched measurement corrects a leg
    too short (frames it cannot reach lengthen it: DM og1 started at the stature's 0.956 ends at
    0.999 / 0.990, as from its default pose) but not one long enough to reach every foot — a
    flexed knee reaches it with any such length — so a walk (whose default pose is a few per
    cent short) keeps the rule before, and a leg whose default pose measures a knee flexed
    through the trial starts from the stature's leg, the
    anthropometric proportion (segment lengths ∝ stature, Winter 2009, Table 4.1; Dempster
    1955) that is the same for both legs (anatomical leg-length inequality: 5 mm mean, under
    20 mm in ~95 % of adults; Knutson 2005, Chiropr Osteopat 13:11), unless the markers show
    the leg longer (docs/validation.md).

    Returns measurement name → {"default_pose": ratio, "stature": height_factor, "start":
    the factor used, "source": "stature" or "default pose"}."""
    legs = {m.name: float(ratios[m.name]) for m in measurements
            if m.name.startswith("leg_") and m.name in ratios}  # fmt: skip
    # both legs or neither: they ran the same trial (a leg whose default pose is 7 % short
    # beside one 11 % short is a longer leg in the same flexed running, not a walk's)
    flexed = height_factor is not None and any(
        r < (1.0 - LEG_START_MAX_SHORTFALL) * height_factor for r in legs.values()
    )
    out: dict[str, dict[str, Any]] = {}
    for name, r in legs.items():
        start = (
            height_factor if flexed and height_factor is not None and height_factor > r else None
        )
        use_h = start is not None
        out[name] = {
            "default_pose": r,
            "stature": height_factor,
            "start": r if start is None else float(start),
            "source": "stature" if use_h else "default pose",
        }
    return out


def _start_factors(
    starts: Mapping[str, Mapping[str, Any]], measurements: Sequence[Measurement]
) -> dict[str, Array]:
    return {
        b: np.full(3, float(starts[m.name]["start"]))
        for m in measurements if m.name in starts
        for b in m.bodies
    }  # fmt: skip


def _leg_start_notes(
    starts: Mapping[str, Mapping[str, Any]],
    ratios: Mapping[str, float],
    details: dict[str, dict[str, Any]],
) -> list[str]:
    """Record each leg's start in ``details`` and say which legs the motion did not determine
    beyond the stature (their pose-matched factor within :data:`LEG_START_TOLERANCE` of it)."""
    notes = []
    for name, st in starts.items():
        details[name]["start"] = dict(st)
        r = float(ratios[name])
        if st["source"] == "stature" and abs(r / st["start"] - 1.0) <= LEG_START_TOLERANCE:
            details[name]["determined"] = details[name]["start"]["determined"] = False
            notes.append(
                f"{name}: × {r:.3f}, the stature's leg (× {st['start']:.3f}; default pose "
                f"× {st['default_pose']:.3f}): the stature's leg reaches the feet, the motion's "
                "markers do not determine its length"
            )
    return notes


def scale_from_motion(
    model: Model,
    markers: ArrayLike,
    labels: Sequence[str],
    time: ArrayLike,
    *,
    measurements: Sequence[Measurement] | None = None,
    height_m: float | None = None,
    body_mass: float | None = None,
    pose_matched: bool = True,
    max_frames: int = 120,
    min_frames: int = 10,
    functional: Mapping[str, float] | None = None,
    workspace: dict[str, Any] | None = None,
) -> tuple[Model, ScalingReport]:
    """Scale ``model`` from a motion trial (no static), completing with the stature.

    1. measurements: ``measurements`` or, per segment, the first usable alternative of
       :data:`SEGMENT_MEASUREMENTS` (:func:`choose_measurements`) for the markers of
       ``labels`` (model names, e.g. after :func:`msk.model.markersets.recognise`);
    2. factors from per-frame pair distances (:func:`measure_scale_factors_from_motion`);
    3. with ``pose_matched``: inverse kinematics of up to ``max_frames`` frames on the model so
       scaled (model markers only, no filter), then the factors again with each frame compared
       to the generic model in that frame's pose (a pair across a joint is then measured at the
       same joint angles as the trial);
    4. bodies no measurement reaches: the stature ratio when ``height_m`` is given
       (:func:`complete_scale_factors`), else unscaled — said in ``ScalingReport.methods``;
    5. ``functional``: body → factor measured from functional joint centres (a femur and tibia
       split by :func:`msk.personalise.leg_split.functional_leg_split`), replacing the marker
       measurement (method "functional joint centres").

    A measurement whose markers are too seldom tracked is skipped (named in ``messages``) and
    its bodies fall to the height.

    ``workspace``: a dict (empty to begin with) keeping step 3's poses; a later call with the
    same ``model`` and markers — another ``functional`` split, which step 3 does not depend on
    — reuses them instead of solving that IK again (the model stage scales a trial once per
    candidate split, :func:`msk.personalise.placement.choose_placement`).

    Returns:
        (the scaled model, :class:`ScalingReport`).
    """
    from msk.model.markersets import zeros_as_gaps

    x = zeros_as_gaps(markers)  # exact zeros: gaps (TRC writers)
    t = np.asarray(time, dtype=float)
    labels = tuple(labels)
    have = set(labels) & set(model.marker_names)
    meas = (
        choose_measurements(SEGMENT_MEASUREMENTS, have)
        if measurements is None
        else usable_measurements(list(measurements), have)
    )
    messages: list[str] = []
    ok_meas = []
    for m in meas:
        try:
            measure_scale_factors_from_motion(model, x, labels, [m], min_frames=min_frames)
            ok_meas.append(m)
        except MissingDataError as exc:
            messages.append(f"{m.name}: {exc}")
    measured, ratios, details = measure_scale_factors_from_motion(
        model, x, labels, ok_meas, min_frames=min_frames
    )
    if pose_matched and ok_meas:
        from msk.exceptions import KinematicsError
        from msk.kinematics.ik import solve_kinematics

        hf_start = None if height_m is None else float(height_m) / model_height(model)[0]
        starts = unobserved_leg_starts(ratios, ok_meas, hf_start)
        first = apply_scale_factors(model, {**measured, **_start_factors(starts, ok_meas)})
        idx = _ik_frames(x, labels, have, max_frames, 3, t)
        # knees no model marker observes: the flexion branch and a very weak pull towards
        # neutral (SCALING_NEUTRAL_WEIGHT), else the pose each frame is compared in is
        # wherever the solver drifts along the flat directions (UWA fast walking, pelvis and
        # foot markers: the leg factors moved by up to 0.2 with 0.1 mm of marker noise;
        # studies/placement_jitter.py)
        flexed = unobserved_knees_flexed(first, x[idx], labels, min_frames)
        if flexed:
            first = first.with_coordinate_ranges(flexed)
        key = (x.shape, labels, model.name, model.n_coords)
        try:
            if workspace is not None and workspace.get("key") == key:
                q = workspace["q"]
            else:
                kin = solve_kinematics(
                    first, x[idx], labels, t[idx], cutoff_hz=None, min_markers=3,
                    coordinate_tasks={
                        k: (0.0, SCALING_NEUTRAL_WEIGHT) for k in _neutral_tasks(first)
                    } if flexed else None,
                )  # fmt: skip
                q = np.full((x.shape[0], model.n_coords), np.nan)
                q[idx] = kin.q_raw
                if workspace is not None:
                    workspace["key"], workspace["q"] = key, q
            measured, ratios, details = measure_scale_factors_from_motion(
                model, x, labels, ok_meas, q=q, min_frames=min_frames
            )
            messages.extend(_leg_start_notes(starts, ratios, details))
        except (KinematicsError, MissingDataError) as exc:
            messages.append(f"pose-matched measurement not done ({exc}): default pose used")
    _functional_override(measured, ratios, functional)
    factors, methods, hf, mh = complete_scale_factors(
        model, measured, source="motion markers", height_m=height_m
    )
    methods = _functional_methods(methods, functional)
    unscaled = [b for b, m in methods.items() if m == "unscaled"]
    if unscaled:
        messages.append(f"no marker measurement and no height: {unscaled} left unscaled")
    scaled = apply_scale_factors(model, factors, body_mass=body_mass).with_metadata(
        scale_ratios=ratios, scale_methods=methods
    )
    rep = ScalingReport(factors, methods, ratios, details, hf, mh, tuple(messages))
    return scaled, rep


def scale_from_static(
    model: Model,
    static_markers: Any,
    *,
    measurements: Sequence[Measurement] | None = None,
    height_m: float | None = None,
    body_mass: float | None = None,
    marker_names: Mapping[str, str] | None = None,
    widths_m: Mapping[str, float] | None = None,
    marker_diameter_m: float | None = None,
    functional: Mapping[str, float] | None = None,
) -> tuple[Model, ScalingReport]:
    """:func:`measure_scale_factors` on a static trial (``{label: (N, 3)}`` or a TRC table),
    per segment the first usable alternative of :data:`SEGMENT_MEASUREMENTS` when
    ``measurements`` is None, completed by the stature like :func:`scale_from_motion`.

    With ``measurements`` None, a thigh or shank whose joint centres the static trial shows
    (epicondyles and malleoli both sides of the leg, :func:`joint_centre_scale_factors`) is
    scaled by the joint-centre distance instead of the marker pair (Kainz et al. 2017); with
    lateral markers only, the lab's joint widths (``widths_m``, ``marker_diameter_m``) place the
    knee and ankle centres as Plug-in Gait does (:func:`static_joint_centres`). ``functional``
    as for :func:`scale_from_motion`."""
    means = _static_means(static_markers)
    names = dict(marker_names or {})
    have = {mk for mk in model.marker_names if names.get(mk, mk) in means}
    meas = (
        choose_measurements(SEGMENT_MEASUREMENTS, have)
        if measurements is None
        else usable_measurements(list(measurements), have)
    )
    measured, ratios = measure_scale_factors(model, means, meas, marker_names=names)
    details: dict[str, dict[str, Any]] = {
        m.name: {"pairs": [list(p) for p in m.marker_pairs]} for m in meas
    }
    if measurements is None:
        # thigh and shank by joint centres where the static has medial and lateral markers
        pf = float(np.asarray(measured.get("pelvis", np.ones(3)), dtype=float).reshape(-1)[0])
        jc, jc_details = joint_centre_scale_factors(
            model,
            means,
            pelvis_factor=pf,
            marker_names=names,
            widths_m=widths_m,
            marker_diameter_m=marker_diameter_m,
        )
        for body, f in jc.items():
            measured[body] = np.full(3, f)
            ratios[f"{body} (joint centres)"] = f
        details.update(jc_details)
    _functional_override(measured, ratios, functional)
    factors, methods, hf, mh = complete_scale_factors(
        model, measured, source="static markers", height_m=height_m
    )
    methods = _functional_methods(methods, functional)
    messages = []
    unscaled = [b for b, m in methods.items() if m == "unscaled"]
    if unscaled:
        messages.append(f"no marker measurement and no height: {unscaled} left unscaled")
    scaled = apply_scale_factors(model, factors, body_mass=body_mass).with_metadata(
        scale_ratios=ratios, scale_methods=methods
    )
    return scaled, ScalingReport(factors, methods, ratios, details, hf, mh, tuple(messages))


#: a marker too loose for ``max_spread_m`` is still placed when its body has no other marker,
#: up to this multiple of ``max_spread_m`` (the spread the later passes of
#: :func:`place_markers_from_motion` accept for their IK)
LOOSE_KEPT_SPREAD_FACTOR = 3.0


def _tracked(x: Array, min_frames: int) -> bool:
    """A marker column (F, 3) measured in at least ``min_frames`` frames."""
    return int(np.isfinite(x).all(axis=1).sum()) >= min_frames


def unobserved_end_rotations(
    model: Model, markers: Array, labels: Sequence[str], min_frames: int
) -> dict[str, tuple[float, float]]:
    """Rotations of the joints whose child is a terminal body (nothing distal to it: a trunk,
    toes) that its tracked model markers (each seen in ``min_frames`` frames of ``markers``) do
    not pin, as IK coordinate tasks pulling them weakly towards neutral (value 0,
    :data:`NEUTRAL_TASK_WEIGHT`).

    With the joint centre, one marker pins a 1-DOF joint and two a ball joint; a ball joint
    with one marker leaves the rotation about the line from the joint centre to the marker
    free, and IK lets it wander. The Grand Challenge DM trunk has one gait2392 marker
    (``Sternum``, nearly above the lumbar joint: the free rotation is the trunk's axial one;
    its shoulder and neck markers are the lab's own, to be placed): in the placement passes its
    lumbar rotation drifted to −72…+92° through og1's walk, the neck and shoulder markers
    then moved 0.14–0.16 m on every body and were left out, and the whole trial's IK kept the
    trunk turned (og1 lumbar rotation −72…+92°, treadmill −26…+91°, crouch −39…+93°). With
    the pull the first pass holds the trunk near neutral, the lab's trunk markers are placed
    on it, and the later passes (and the trial's own IK) track it with them. A leg gets no pull
    (its joints are not terminal), nor a trunk with both acromia (UWA running: pulling its
    20–40° forward lean towards neutral had put the thigh and shank clusters 50–200 mm loose).
    :func:`place_markers_from_motion` applies it in every pass (reported, for the last pass, as
    ``"unobserved_rotations"``).
    """
    seen = [
        mk.body
        for mk in model.markers
        if mk.name in labels and _tracked(markers[:, list(labels).index(mk.name)], min_frames)
    ]
    coords = {c.name: c for c in model.coordinates}
    out: dict[str, tuple[float, float]] = {}
    for j in model.joints:
        if j.parent == GROUND:
            continue
        if any(jj.parent == j.child for jj in model.joints):
            continue  # not a terminal body
        free = [
            c.name
            for ax in j.axes
            if ax.kind == "revolute"
            and (c := coords.get(ax.coordinate or "")) is not None
            and not c.locked
        ]
        if sum(b == j.child for b in seen) >= min(2, len(free)):
            continue
        out.update({name: (0.0, NEUTRAL_TASK_WEIGHT) for name in free})
    return out


def unobserved_knees_flexed(
    model: Model, markers: Array, labels: Sequence[str], min_frames: int
) -> dict[str, tuple[float, float]]:
    """Knee coordinates (``knee_angle*``) whose joint no tracked model marker observes (none on
    its parent nor on its child body in ``min_frames`` frames of ``markers``), with their range
    restricted to the flexion side of 0 (the side holding most of the range: gait2392's
    [−120°, 10°] → [−120°, 0°], Rajagopal's [0°, 120°] unchanged).

    With pelvis and foot markers only, the knee angle comes from the hip–foot distance, which
    is even about its maximum near full extension: flexed and hyperextended knees give the
    same distance, and IK may take the hyperextended branch to its bound (DM og4, four-bar
    knee: +10° in 93 of 120 placement frames; the thigh and shank clusters were then placed
    10–20° off and the whole trial walked in hyperextension). Healthy and replaced knees walk
    at 0–5° of hyperextension at most (Perry & Burnfield 2010, Gait Analysis, ch. 6), so the
    placement passes take the flexion branch; the trial's own IK keeps the full range.
    """
    observed: set[str] = set()
    for mk in model.markers:
        if mk.name in labels and _tracked(markers[:, list(labels).index(mk.name)], min_frames):
            observed.add(mk.body)
    out: dict[str, tuple[float, float]] = {}
    coords = {c.name: c for c in model.coordinates}
    for j in model.joints:
        for ax in j.axes:
            c = coords.get(ax.coordinate or "")
            if c is None or c.locked or not c.name.startswith("knee_angle") or c.name in out:
                continue
            if j.parent in observed or j.child in observed:
                continue
            lo, hi = c.range
            out[c.name] = (lo, min(hi, 0.0)) if -lo >= hi else (max(lo, 0.0), hi)
    return {k: v for k, v in out.items() if v != coords[k].range}


def place_markers_from_motion(
    model: Model,
    markers: ArrayLike,
    labels: Sequence[str],
    time: ArrayLike,
    *,
    max_spread_m: float = 0.02,
    max_distance_m: float = 0.25,
    max_frames: int = 120,
    min_frames: int = 10,
    min_markers: int = 4,
    iterations: int = 3,
    move: Sequence[str] = (),
    regularize: bool | None = None,
    median_neutral: Sequence[str] = (),
    hints: Mapping[str, str] | None = None,
    start: Mapping[str, Sequence[Any]] | None = None,
    warm: dict[str, Any] | None = None,
    neutral_weight: float = NEUTRAL_TASK_WEIGHT,
) -> tuple[Model, dict[str, Any]]:
    """Add a motion trial's non-model markers to ``model`` when there is no static trial.

    1. Inverse kinematics (:func:`msk.kinematics.ik.solve_kinematics`, no filter) of up to
       ``max_frames`` evenly spread frames with at least ``min_markers`` model markers, with the
       model's markers only (the recognised anatomical ones: ``labels`` in model names);
    2. every other measured marker (not ``*N`` nor a model output,
       :func:`msk.io.c3d.is_measured_marker`) tracked in ``min_frames`` solved frames is
       expressed in each body's frame, p_b(t) = oMf_b(q_t)⁻¹ x(t); its body is the one where
       it moves least — spread σ_b = RMS_t ‖p_b(t) − median_t p_b‖, the rigid-body residual of
       a marker fixed to b (skin motion and a wrong segment both raise it) — among the bodies
       whose bone segment (:func:`bone_segments`, median pose) is within ``max_distance_m``;
       it is fixed there at the median position (component-wise: robust to gaps and swaps);
       near-ties (within 2 mm or 25 % of the smallest spread: a joint the motion hardly moves,
       such as the lumbar joint, leaves a PSIS as rigid on the torso as on the pelvis) go to the
       body of the marker's landmark when ``hints`` (lab label → body,
       :meth:`msk.model.markersets.MarkerSetMatch.body_hints`) names one of them, else to the
       nearest
       bone; a thigh or shank marker (hint on a femur or tibia,
       :data:`msk.model.markersets.KNEE_SEGMENTS`) goes to its hinted body whenever it is rigid
       enough there (σ ≤ ``max_spread_m``, not only in a near-tie), and a
       sided label never to a body of the other side (a synthetic
       DM walk had thigh and shank markers exchanged across the knee, a squat a right foot
       marker on the left toes);
    3. ``iterations`` > 1: inverse kinematics again with the placed markers too (they pin the
       rotations about the long axes that a few anatomical markers leave free, e.g. a thigh
       with no knee marker), and step 2 again from that pose;
    4. a marker whose final spread exceeds ``max_spread_m`` is not placed and is reported
       (``too_loose``), unless no other marker observes its body (no model marker tracked in
       ``min_frames`` solved frames, no other placed marker) and its spread is at most
       :data:`LOOSE_KEPT_SPREAD_FACTOR` × ``max_spread_m``: then it is placed and reported
       (``kept_loose``) — a noisy observation of a segment is better than none;
    5. ``move``: model markers (a lab puts its foot markers where it likes) moved, on their
       own body, to their median body-frame position in the last pass (OpenSim's
       ``move_model_markers`` for these markers, as :func:`place_markers` does on a static);
       shoulder-girdle markers of a model without that segment are always moved;
    6. ``median_neutral``: coordinates whose offset the placed and moved markers leave free
       (every marker distal to the joint placed or moved from this very motion: rotating them
       all on the child body by δ and the joint by −δ fits equally), so the last pass expresses
       the markers in the poses with each such coordinate's median over its solved frames
       subtracted: the motion's median angle becomes the joint's neutral (0), as OpenSim's
       scaling holds the subtalar and MTP angles at 0 in the static pose (gait2392's example
       scale setups). Otherwise the offset is whatever the generic model markers' fit gives:
       DM og1's subtalar at a median of 31° (r) / 24° (l) — gait2392's midfoot markers sit
       41–66 mm from the lab's, and the calcaneus rolls about the subtalar axis to reach them.
       Reported as ``"median_neutral"``: coordinate → the median removed (rad).

    The passes' IK takes the flexion branch of a knee no model marker observes
    (:func:`unobserved_knees_flexed`; reported as ``"knee_flexion_branch"``), and pulls the
    rotations of a terminal body its tracked markers do not pin towards neutral
    (:func:`unobserved_end_rotations`: a trunk with one sternum marker; reported, for the last
    pass, as ``"unobserved_rotations"``).

    ``regularize`` None (default): the passes run without any pull on the coordinates; when
    their final marker RMS exceeds :data:`PLACEMENT_RETRY_RMS_M` (the anatomical markers leave
    the legs free: pelvis and feet only, e.g. UWA's cluster-only set), they are run again with
    every rotation pulled weakly towards neutral (``neutral_weight``, per rad²; default
    :data:`NEUTRAL_TASK_WEIGHT`) and the placement with the lower RMS is kept
    (``info["regularized"]`` says which); True / False: only that.

    ``start`` (``info["state"]`` of an earlier placement: marker → [body, σ, offset]): the
    first pass solves with those markers placed too (those within the later passes' spread
    limit), so the passes continue that placement
    (:func:`msk.personalise.placement.choose_placement` alternates placement and inverse
    kinematics so until the task's fit stops improving).

    ``warm``: a workspace (an empty dict to begin with) in which every pass leaves its IK
    solution (``"frames"``, ``"q"``) and from which the next pass — of this call or of a later
    one on the same frames — starts each frame (:func:`msk.kinematics.ik.solve_kinematics`'s
    per-frame ``initial_q``): the passes of :func:`refine_placement_from_motion` move the
    offsets by millimetres, and each frame's pose from the previous pass is nearer than the
    prediction from the frames before it.

    Returns:
        The model with the markers added, and ``{"placed": marker → body, "spread_m": marker →
        σ (m), "too_loose": marker → [body, σ], "kept_loose": marker → [body, σ],
        "too_far": marker → [body, distance], "not_markers", "unseen", "moved": marker →
        displacement (m), "ik_marker_rms_m" (median over the solved frames, last pass),
        "frames" (solved), "knee_flexion_branch"}``.

    Raises:
        KinematicsError: fewer than 3 model markers in the trial.
        MissingDataError: no frame could be solved.
    """
    if regularize is None:
        args: dict[str, Any] = dict(
            max_spread_m=max_spread_m, max_distance_m=max_distance_m, max_frames=max_frames,
            min_frames=min_frames, min_markers=min_markers, iterations=iterations, move=move,
            median_neutral=median_neutral, hints=hints, start=start,
            neutral_weight=neutral_weight,
        )  # fmt: skip
        plain = place_markers_from_motion(
            model, markers, labels, time, regularize=False, warm=None if warm is None else {},
            **args,
        )  # fmt: skip
        if plain[1]["ik_marker_rms_m"] <= PLACEMENT_RETRY_RMS_M:
            return plain
        pulled = place_markers_from_motion(
            model, markers, labels, time, regularize=True, warm=None if warm is None else {},
            **args,
        )  # fmt: skip
        return pulled if pulled[1]["ik_marker_rms_m"] < plain[1]["ik_marker_rms_m"] else plain
    from msk.io.c3d import is_measured_marker
    from msk.kinematics.ik import solve_kinematics
    from msk.model.markersets import zeros_as_gaps_view

    # exact zeros: gaps (TRC writers); read only, not copied when there are none
    x = zeros_as_gaps_view(np.asarray(markers, dtype=float))
    t = np.asarray(time, dtype=float)
    labels = tuple(labels)
    known = set(model.marker_names)
    unknown = sorted(set(move) - known)
    if unknown:
        raise ModelError(f"model {model.name}: no marker {unknown[0]!r} to move")
    move = _girdle_moved(model, labels, move)
    idx = _ik_frames(x, labels, known, max_frames, min_markers, t)
    if idx.size == 0:
        raise MissingDataError(
            f"motion trial: no frame with {min_markers} model markers for marker placement"
        )
    xs, ts = x[idx], t[idx]
    not_markers = [lab for lab in labels if lab not in known and not is_measured_marker(lab)]
    cand = [
        i
        for i, lab in enumerate(labels)
        if lab not in known and lab not in not_markers and lab not in labels[:i]
    ]
    # bone segments of each body in its own frame (default pose)
    d0 = model.create_data()
    forward_kinematics(model, d0, model.default_coordinates())
    local_segs: dict[str, list[tuple[Array, Array]]] = {b.name: [] for b in model.bodies}
    for nm, a, e in bone_segments(model, d0):
        o = d0.oMf[model.body_frame[nm]]
        local_segs[nm].append((np.asarray(o.actInv(a)), np.asarray(o.actInv(e))))
    # the same, stacked: start, direction and body of every segment
    seg_body = np.array([k for k, b in enumerate(local_segs) for _ in local_segs[b]], dtype=int)
    seg_a = np.array([a for b in local_segs for a, _ in local_segs[b]]).reshape(-1, 3)
    seg_d = np.array([e - a for b in local_segs for a, e in local_segs[b]]).reshape(-1, 3)
    # the knees no model marker observes take the flexion branch in the placement passes
    flexed = unobserved_knees_flexed(model, xs, labels, min_frames)
    solve_on = model.with_coordinate_ranges(flexed) if flexed else model
    base = solve_on
    placed: dict[str, str] = {k: str(v[0]) for k, v in (start or {}).items()}
    spread: dict[str, float] = {k: float(v[1]) for k, v in (start or {}).items()}
    local: dict[str, Array] = {k: np.asarray(v[2], dtype=float) for k, v in (start or {}).items()}
    too_far: dict[str, list[Any]] = {}
    unseen: list[str] = []
    rms = float("nan")
    n_ok = 0
    neutral_shift: dict[str, float] = {}
    unobserved: dict[str, tuple[float, float]] = {}
    for it in range(max(1, iterations)):
        # later passes: IK with the markers placed so far, save the clearly loose ones
        ok_prev = [k for k in placed if spread[k] <= LOOSE_KEPT_SPREAD_FACTOR * max_spread_m]
        ik_model = (
            base
            if it == 0 and not placed
            else solve_on.with_markers(
                [*model.markers, *(Marker(k, placed[k], local[k]) for k in ok_prev)]
            )
        )
        # every pass (the first with the anatomical markers only: pelvis and feet at worst):
        # a weak pull of every rotation towards neutral keeps the unpinned ones (hip rotation
        # with no thigh marker, pelvis tilt with two pelvis markers) from wandering to their
        # bounds, and later passes from diverging (UWA fast walking: 79 → 22 mm at the third)
        unobserved = unobserved_end_rotations(ik_model, xs, labels, min_frames)
        tasks = {
            **unobserved,
            **(_neutral_tasks(model, neutral_weight) if regularize else {}),
        } or None
        q0 = None
        if warm is not None and np.array_equal(warm.get("frames", ()), idx):
            q0 = warm["q"]
        kin = solve_kinematics(
            ik_model, xs, labels, ts, cutoff_hz=None, min_markers=3, coordinate_tasks=tasks,
            initial_q=q0,
        )  # fmt: skip
        if warm is not None:
            warm["frames"], warm["q"] = idx, kin.q_raw
        ok = np.isfinite(kin.q_raw).all(axis=1)
        if not ok.any():
            raise MissingDataError("motion trial: no frame could be solved for marker placement")
        n_ok = int(ok.sum())
        rms = float(np.nanmedian(kin.marker_rms[ok]))
        q = kin.q_raw[ok]
        if it == max(1, iterations) - 1 and median_neutral:
            q = q.copy()
            for c in median_neutral:
                j = model.coordinate_index(c)
                neutral_shift[c] = float(np.median(q[:, j]))
                q[:, j] -= neutral_shift[c]
        xo = xs[ok]
        # body poses per solved frame: rotations (F, B, 3, 3) and translations (F, B, 3)
        names = [b.name for b in model.bodies]
        rot, tra = frame_placements(model, q, [model.body_frame[b] for b in names])
        placed, spread, local, too_far, unseen = {}, {}, {}, {}, []
        for i in cand:
            lab = labels[i]
            seen = np.isfinite(xo[:, i]).all(axis=1)
            if seen.sum() < min_frames:
                unseen.append(lab)
                continue
            p = np.einsum("fbji,fbj->fbi", rot[seen], xo[seen, i][:, None, :] - tra[seen])
            med = np.median(p, axis=0)  # (B, 3)
            sig = np.sqrt(((p - med) ** 2).sum(axis=2).mean(axis=0))  # (B,)
            dist = _bone_distances(med, seg_a, seg_d, seg_body, len(names))
            near = dist <= max_distance_m
            # a sided label is never placed on the other side's body (still feet in a squat are
            # as rigid to either foot: R_Midfoot_Medial went to toes_l)
            near &= ~other_side(lab, names)
            if not near.any():
                k = int(np.argmin(dist))
                too_far[lab] = [names[k], float(dist[k])]
                continue
            # the most rigid body; near-ties (a locked joint, a marker near a joint) go to the
            # nearest bone, as the static placement does
            best = float(sig[near].min())
            tie = near & (sig <= best + max(0.002, 0.25 * best))
            hint = (hints or {}).get(lab)
            if hint in names and (tie[names.index(hint)] or (
                    is_knee_segment(hint) and near[names.index(hint)]
                    and sig[names.index(hint)] <= max_spread_m)):  # fmt: skip
                k = names.index(hint)
            else:
                k = int(np.flatnonzero(tie)[np.argmin(dist[tie])])
            placed[lab], spread[lab], local[lab] = names[k], float(sig[k]), med[k]
    too_loose = {lab: [placed[lab], spread[lab]] for lab in placed if spread[lab] > max_spread_m}
    # a body that no other marker observes keeps its loose markers (those the later passes
    # used, ≤ 3 × max_spread_m): without them its pose comes from the neighbours only, and a
    # thigh with no marker lets IK swing the knee (DM og4, four-bar knee: thigh clusters 20–25
    # mm, dropped, knee in 11.5° hyperextension); cluster markers on the thigh move 10–30 mm on
    # the bone in gait (soft-tissue artefact, Leardini et al. 2005 Gait Posture 21:212–225)
    observed = {mk.body for mk in model.markers if mk.name in labels and _tracked(
        xo[:, labels.index(mk.name)], min_frames)} | {
        placed[lab] for lab in placed if lab not in too_loose}  # fmt: skip
    kept_loose = sorted(
        lab for lab in too_loose
        if placed[lab] not in observed and spread[lab] <= LOOSE_KEPT_SPREAD_FACTOR * max_spread_m
    )  # fmt: skip
    too_loose = {lab: v for lab, v in too_loose.items() if lab not in kept_loose}
    keep = [lab for lab in placed if lab not in too_loose]
    added = [Marker(lab, placed[lab], np.asarray(local[lab], dtype=float)) for lab in keep]
    moved: dict[str, float] = {}
    own = list(model.markers)
    for j, mk in enumerate(own):
        if mk.name not in move or mk.name not in labels:
            continue
        i, k = labels.index(mk.name), names.index(mk.body)
        seen = np.isfinite(xo[:, i]).all(axis=1)
        if seen.sum() < min_frames:
            continue
        p = np.einsum("fji,fj->fi", rot[seen, k], xo[seen, i] - tra[seen, k])
        new = np.median(p, axis=0)
        moved[mk.name] = float(np.linalg.norm(new - np.asarray(mk.offset, dtype=float)))
        own[j] = Marker(mk.name, mk.body, new)
    info = {
        "placed": {lab: placed[lab] for lab in keep},
        "spread_m": dict(spread),
        "too_loose": too_loose,
        "kept_loose": {lab: [placed[lab], spread[lab]] for lab in kept_loose},
        "state": {lab: [placed[lab], spread[lab], local[lab].tolist()] for lab in placed},
        "too_far": too_far,
        "not_markers": not_markers,
        "unseen": unseen,
        "moved": moved,
        "ik_marker_rms_m": rms,
        "frames": n_ok,
        "regularized": regularize,
        "knee_flexion_branch": sorted(flexed),
        "median_neutral": neutral_shift,
        "unobserved_rotations": sorted(unobserved),
    }
    return model.with_markers([*own, *added]), info


# ---------------------------------------------------------------------------------------------
# joint-centre scaling of the leg (static trial with medial and lateral markers)
# ---------------------------------------------------------------------------------------------
#: landmark pairs whose midpoint is a joint centre (gait2392 marker names, side prefix added):
#: knee = femoral epicondyles, ankle = malleoli
JOINT_CENTRE_PAIRS: Mapping[str, tuple[str, str]] = {
    "knee": ("Knee.Lat", "Knee.Med"),
    "ankle": ("Ankle.Lat", "Ankle.Med"),
}


#: largest step length |α| of :func:`refine_placement_from_motion`'s squared extrapolation
#: (Varadhan & Roland 2008's SQUAREM; |α| = 1 is the plain iteration's two passes)
DESCENT_MAX_STEP = 8.0


def _placement_offsets(
    model: Model, info: Mapping[str, Any], own: set[str]
) -> dict[str, tuple[str, Array]]:
    """marker → (body, offset) of a motion placement's state: the model's own markers (those a
    pass moves) and every marker it placed (``info["state"]``, loose ones included)."""
    out = {mk.name: (mk.body, np.asarray(mk.offset, dtype=float)) for mk in model.markers
           if mk.name in own}  # fmt: skip
    for k, v in dict(info.get("state", {})).items():
        out[k] = (str(v[0]), np.asarray(v[2], dtype=float))
    return out


def refine_placement_from_motion(
    model: Model,
    markers: ArrayLike,
    labels: Sequence[str],
    time: ArrayLike,
    placed: tuple[Model, Mapping[str, Any]],
    cost: Callable[[Model, Mapping[str, Any]], float],
    *,
    max_rounds: int = 30,
    rel_tolerance: float = 1e-3,
    accelerate: bool = True,
    **kwargs: Any,
) -> tuple[Model, dict[str, Any]]:
    """Continue a motion placement (``placed``: the result of :func:`place_markers_from_motion`
    on ``model``, the model without the lab's markers) by rounds of passes (``start`` = the
    last state, one pass per call; every rotation pulled towards neutral by
    :data:`DESCENT_NEUTRAL_WEIGHT` only, which leaves the fit to the markers and makes each
    pass's minimum unique — unpulled, the passes of a cluster-only leg (UWA) jumped to another
    basin or diverged, so where the descent stopped was a lottery;
    ``kwargs``: the other keywords it was placed with) for as long as ``cost(model, info)``
    — the fit the placement is for, e.g. the task's own inverse kinematics cost
    (:func:`msk.personalise.placement.placement_cost`) — falls by more than ``rel_tolerance`` of
    itself per round (at most ``max_rounds`` rounds, a safeguard: ``info["descent_stop"]``
    says which rule stopped it).

    Each pass is one block of a block-coordinate descent of the markers' distances over the
    poses (inverse kinematics) and the markers' body-frame offsets (their median position in
    the body), the two-level fit of a subject's model to its motion (Reinbolt et al. 2005,
    J Biomech 38:621–626, the outer level being here the offsets only). That iteration
    x ↦ F(x) of the offsets x converges linearly and slowly along the valley the anatomical
    markers leave (DM og1: the cost still falling 0.06 mm per two passes after 12 rounds), so
    each round is a squared extrapolation (``accelerate``; SQUAREM, Varadhan & Roland 2008,
    Scand J Stat 35:335–353, scheme S3): x₁ = F(x₀), x₂ = F(x₁), r = x₁ − x₀,
    v = x₂ − 2x₁ + x₀, α = −‖r‖/‖v‖ clamped to [−:data:`DESCENT_MAX_STEP`, −1],
    x' = x₀ − 2αr + α²v (their Eq. 9; α = −1 gives x₂), then one more pass from x' (their
    stabilisation step). A marker whose body differs between x₀, x₁, x₂ takes x₂'s offset. The
    round's result is kept only when it lowers the fixed ``cost`` (else x₂, the plain
    iteration's, when that does; else the descent stops), so the result is never worse by it
    than ``placed``.

    Returns the model and the last kept round's ``info`` with ``"descent_cost_m"`` (the cost
    of ``placed``, then of each kept round), ``"descent_stop"`` and the ``"regularized"`` of
    ``placed``."""
    own = set(model.marker_names)
    kw = {**kwargs, "regularize": True, "neutral_weight": DESCENT_NEUTRAL_WEIGHT, "iterations": 1}
    warm: dict[str, Any] = {}  # each pass's IK starts from the previous pass's poses

    def step(m: Model, info: Mapping[str, Any]) -> tuple[Model, dict[str, Any]]:
        return place_markers_from_motion(
            model.with_markers([mk for mk in m.markers if mk.name in own]),
            markers, labels, time, **kw, start=info["state"], warm=warm,
        )  # fmt: skip

    def extrapolated(
        states: list[tuple[Model, dict[str, Any]]],
    ) -> tuple[Model, dict[str, Any]] | None:
        o0, o1, o2 = (_placement_offsets(m, i, own) for m, i in states)
        common = [k for k in o2 if k in o0 and k in o1 and o0[k][0] == o1[k][0] == o2[k][0]]
        if not common:
            return None
        a0, a1, a2 = (np.array([o[k][1] for k in common]) for o in (o0, o1, o2))
        r, v = a1 - a0, a2 - 2.0 * a1 + a0
        nr, nv = float(np.linalg.norm(r)), float(np.linalg.norm(v))
        if nv == 0.0 or nr == 0.0:
            return None
        alpha = float(np.clip(-nr / nv, -DESCENT_MAX_STEP, -1.0))
        new = dict(zip(common, a0 - 2.0 * alpha * r + alpha**2 * v, strict=True))
        m2, i2 = states[2]
        own_markers = [Marker(mk.name, mk.body, new.get(mk.name, mk.offset)) for mk in m2.markers
                       if mk.name in own]  # fmt: skip
        state = {k: [b, s, (new[k].tolist() if k in new else off)]
                 for k, (b, s, off) in dict(i2["state"]).items()}  # fmt: skip
        return model.with_markers(own_markers), {**i2, "state": state}

    cur = (placed[0], dict(placed[1]))
    path = [float(cost(*cur))]
    stop = "max_rounds"
    for _ in range(max(0, max_rounds)):
        x1 = step(*cur)
        x2 = step(*x1)
        best, c_best = x2, float("nan")
        xe = extrapolated([cur, x1, x2]) if accelerate else None
        if xe is not None:
            x3 = step(*xe)
            c3 = float(cost(*x3))
            if c3 < path[-1]:
                best, c_best = x3, c3
        if not c_best < path[-1]:
            best, c_best = x2, float(cost(*x2))
        if not c_best < path[-1]:
            stop = "no decrease"
            break
        decrease = path[-1] - c_best
        path.append(c_best)
        cur = (best[0], {**best[1], "regularized": placed[1]["regularized"]})
        if decrease <= rel_tolerance * c_best:
            stop = "relative decrease"
            break
    return cur[0], {**cur[1], "descent_cost_m": path, "descent_stop": stop}


def _mid_psis(means: Mapping[str, Array]) -> Array | None:
    """The static's mid-PSIS (both PSIS markers), found by landmark."""
    found: dict[tuple[str | None, str], Array] = {}
    for lab, v in means.items():
        p = parse_label(lab)
        if p.landmark == "psis" and p.kind == "landmark":
            found.setdefault((p.side, p.landmark), np.asarray(v, dtype=float))
    if ("R", "psis") in found and ("L", "psis") in found:
        return 0.5 * (found[("R", "psis")] + found[("L", "psis")])
    return None


def chord_joint_centre(proximal: ArrayLike, wand: ArrayLike, lateral: ArrayLike, r: float) -> Array:
    """Plug-in Gait's "chord function" (Davis et al. 1991, Hum Mov Sci 10:575-587; Vicon
    Plug-in Gait reference guide): the joint centre J in the plane of the proximal joint
    centre P, the wand marker W and the lateral marker L, at distance ``r`` (half the joint
    width plus half the marker diameter) from L with the angle P–J–L a right angle (J on the
    circle of diameter PL, Thales), on the side of the line PL away from the wand:
    J = L + r (cos β (P − L)/‖P − L‖ − sin β w), cos β = r/‖P − L‖, w the unit in-plane normal to
    PL pointing to W."""
    p, w_, lat = (np.asarray(v, dtype=float) for v in (proximal, wand, lateral))
    d = float(np.linalg.norm(p - lat))
    u = (p - lat) / d
    w = (w_ - lat) - np.dot(w_ - lat, u) * u
    w /= np.linalg.norm(w)
    cb = min(r / d, 1.0)
    return lat + r * (cb * u - np.sqrt(1.0 - cb * cb) * w)


def static_hip_centres(
    model: Model, means: Mapping[str, Array], *, pelvis_factor: float = 1.0,
    marker_names: Mapping[str, str] | None = None,
) -> dict[str, Array]:  # fmt: skip
    """``{"r"|"l": hip centre}`` in a static trial: the model's, carried by its pelvis (scaled
    by ``pelvis_factor``) fitted rigidly to the pelvis markers (≥ 3 model markers on the
    pelvis; the mid-PSIS stands in for a missing sacral marker: IOR/CAST sets have PSIS, no
    sacrum). Empty when the pelvis is not determined."""
    names = dict(marker_names or {})

    def exp(mk: str) -> Array | None:
        v = means.get(names.get(mk, mk))
        return None if v is None else np.asarray(v, dtype=float)

    data = model.create_data()
    forward_kinematics(model, data, model.default_coordinates())
    pelvis_pts = {
        mk.name: (np.asarray(mk.offset, dtype=float), exp(mk.name))
        for mk in model.markers
        if mk.body == "pelvis" and exp(mk.name) is not None
    }
    sacral = [
        mk for mk in model.markers
        if mk.body == "pelvis" and parse_label(mk.name).landmark == "sacrum"
    ]  # fmt: skip
    mid = _mid_psis(means)
    if len(sacral) == 1 and sacral[0].name not in pelvis_pts and mid is not None:
        pelvis_pts[sacral[0].name] = (np.asarray(sacral[0].offset, dtype=float), mid)
    if len(pelvis_pts) < 3 or "pelvis" not in model.body_frame:
        return {}
    local = np.array([v[0] for v in pelvis_pts.values()]) * pelvis_factor
    world = np.array([v[1] for v in pelvis_pts.values()])
    if np.linalg.matrix_rank(local - local.mean(axis=0), tol=1e-3) < 2:
        return {}
    pose = segment_poses(local, world[None])
    rot, tr = pose.rotation[0], pose.origin[0]
    o_p = data.oMf[model.body_frame["pelvis"]]
    out = {}
    for side in ("r", "l"):
        if f"femur_{side}" in model.body_frame:
            o_f = np.asarray(data.oMf[model.body_frame[f"femur_{side}"]].translation, dtype=float)
            loc = np.asarray(o_p.actInv(o_f), dtype=float)
            out[side] = rot @ (loc * pelvis_factor) + tr
    return out


def _wand(means: Mapping[str, Array], side: str, landmark: str) -> Array | None:
    for lab, v in means.items():
        p = parse_label(lab)
        if p.side == side and p.landmark == landmark and np.isfinite(v).all():
            return np.asarray(v, dtype=float)
    return None


def static_joint_centres(
    model: Model,
    means: Mapping[str, Array],
    *,
    pelvis_factor: float = 1.0,
    marker_names: Mapping[str, str] | None = None,
    widths_m: Mapping[str, float] | None = None,
    marker_diameter_m: float | None = None,
) -> dict[str, dict[str, Array]]:
    """``{"r"|"l": {"hip", "knee", "ankle": centre}}`` in a static trial (sides with all three).

    Hip: :func:`static_hip_centres`. Knee and ankle: the midpoint of the epicondyle and of the
    malleolus markers (ISB, Wu et al. 2002, J Biomech 35:543-548) where the static has medial
    and lateral markers; else, for a lateral-marker protocol with wands (Plug-in Gait: KNE +
    THI, ANK + TIB) whose joint widths the lab measured (``widths_m`` ``"R.knee"``…, the C3D's
    subject parameters), Plug-in Gait's chord function (:func:`chord_joint_centre`, Davis et al.
    1991) with r = (width + marker diameter)/2 (14 mm, Vicon's default, when not given): the
    knee from hip, THI, KNE; the ankle from knee, TIB, ANK."""
    names = dict(marker_names or {})
    widths = dict(widths_m or {})
    md = 0.014 if marker_diameter_m is None else float(marker_diameter_m)

    def exp(mk: str) -> Array | None:
        v = means.get(names.get(mk, mk))
        return None if v is None or not np.isfinite(v).all() else np.asarray(v, dtype=float)

    hips = static_hip_centres(model, means, pelvis_factor=pelvis_factor, marker_names=names)
    out: dict[str, dict[str, Array]] = {}
    for side, hjc in hips.items():
        p = side.upper()
        pts: dict[str, Array] = {"hip": hjc}
        prox = hjc
        for jc, (a, b) in JOINT_CENTRE_PAIRS.items():
            xa, xb = exp(f"{p}.{a}"), exp(f"{p}.{b}")
            if xa is not None and xb is not None:
                pts[jc] = 0.5 * (xa + xb)
            else:
                wand = _wand(means, p, "thigh_cluster" if jc == "knee" else "shank_cluster")
                wd = widths.get(f"{p}.{jc}")
                if xa is not None and wand is not None and wd is not None:
                    pts[jc] = chord_joint_centre(prox, wand, xa, 0.5 * (wd + md))
            if jc not in pts:
                break
            prox = pts[jc]
        if {"knee", "ankle"} <= set(pts):
            out[side] = pts
    return out


def joint_centre_scale_factors(
    model: Model,
    static_markers: Any,
    *,
    pelvis_factor: float = 1.0,
    marker_names: Mapping[str, str] | None = None,
    widths_m: Mapping[str, float] | None = None,
    marker_diameter_m: float | None = None,
) -> tuple[dict[str, float], dict[str, dict[str, Any]]]:
    """Thigh and shank scale factors from joint-centre distances in a static trial (Kainz et
    al. 2017, J Appl Biomech 33:354-360: scaling the thigh by hip–knee and the shank by
    knee–ankle joint-centre distances is more accurate than by skin-marker pairs).

    The joint centres are :func:`static_joint_centres`' (epicondyle and malleolus midpoints,
    or Plug-in Gait's chord function from the lab's joint widths); the factors are their
    distances over the model's joint-origin distances in the default pose (hip → knee → ankle
    joint): the skin markers' positions in the generic marker set do not enter (gait2392 puts
    its malleolus markers 3 cm above the ankle joint, which inflated the shank by ~10 % when
    scaled by marker pairs).

    Returns ``({body: factor}, {measurement: details})``; a side without its knee and ankle
    centres, or a pelvis without 3 markers, gives nothing for that leg (thigh and shank are
    scaled together this way or not at all: a shank by joint centres under a thigh by marker
    pairs would put the knee where neither definition does).
    """
    means = _static_means(static_markers)
    data = model.create_data()
    forward_kinematics(model, data, model.default_coordinates())

    def origin(body: str) -> Array:
        return np.asarray(data.oMf[model.body_frame[body]].translation, dtype=float)

    centres = static_joint_centres(
        model, means, pelvis_factor=pelvis_factor, marker_names=marker_names,
        widths_m=widths_m, marker_diameter_m=marker_diameter_m,
    )  # fmt: skip
    factors: dict[str, float] = {}
    details: dict[str, dict[str, Any]] = {}
    for side, pts in centres.items():
        femur, tibia, talus = f"femur_{side}", f"tibia_{side}", f"talus_{side}"
        if not all(b in model.body_frame for b in (femur, tibia, talus)):
            continue
        for body, a, b, x_a, x_b in (
            (femur, femur, tibia, pts["hip"], pts["knee"]),
            (tibia, tibia, talus, pts["knee"], pts["ankle"]),
        ):
            d_m = float(np.linalg.norm(origin(a) - origin(b)))
            d_e = float(np.linalg.norm(x_a - x_b))
            factors[body] = d_e / d_m
            details[f"{body} (joint centres)"] = {"experimental_m": d_e, "model_m": d_m}
    return factors, details
