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
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import FileFormatError, MissingDataError, ModelError, MskError
from msk.joints import Constant, CoordinateFunction, Multiplier
from msk.model import GROUND, Axis, Body, Joint, Marker, Model, forward_kinematics
from msk.muscles.path import ConditionalPathPoint, MovingPathPoint, Muscle, PathPoint, WrapObject

Array = NDArray[np.float64]

__all__ = [
    "Measurement",
    "ScaleSetup",
    "apply_scale_factors",
    "bone_segments",
    "measure_scale_factors",
    "muscle_path_lengths",
    "place_markers",
    "point_segment_distance",
    "read_scale_setup",
    "scale_inertia",
    "scale_model",
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
    out = []
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


def place_markers(
    model: Model,
    static_markers: np.ndarray,
    labels: Sequence[str],
    time: np.ndarray,
    *,
    max_distance_m: float = 0.25,
    move: Sequence[str] = (),
) -> tuple[Model, dict[str, Any]]:
    """Add the static trial's non-model markers to ``model`` (OpenSim's MarkerPlacer idea).

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

    Args:
        model: the (scaled) model, in the frame of ``static_markers``.
        static_markers: (N, M, 3) m, NaN gaps.
        labels: the M labels.
        time: (N,) s.
        max_distance_m: largest distance of a placed marker from its bone segment.
        move: model markers to move to their static positions (on their body).

    Returns:
        The model with the markers added, and ``{"static_marker_rms_m", "placed",
        "not_markers", "too_far", "moved"}`` (placed: marker → body; not_markers: the labels
        left out as not measured markers; too_far: marker → [nearest body, distance in m] of
        the markers left out by ``max_distance_m``; moved: marker → displacement in m).

    Raises:
        ModelError: a ``move`` name is not a model marker.
        KinematicsError: too few markers in every static frame.
        MissingDataError: no static frame could be solved.
    """
    from msk.io.c3d import is_measured_marker
    from msk.kinematics import solve_kinematics

    move = tuple(move)
    unknown = sorted(set(move) - set(model.marker_names))
    if unknown:
        raise ModelError(f"model {model.name}: no marker {unknown[0]!r} to move")
    n = static_markers.shape[0]
    frames = np.unique(np.linspace(0, n - 1, min(n, 9)).round().astype(int))
    base = model.with_markers([m for m in model.markers if m.name not in move]) if move else model
    kin = solve_kinematics(
        base, static_markers[frames], labels, time[frames], cutoff_hz=None, min_markers=3
    )
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
    markers, moved = list(model.markers), {}
    for k, mk in enumerate(markers):
        i = where.get(mk.name)
        if mk.name in move and i is not None and np.isfinite(mean[i]).all():
            local = np.asarray(data.oMf[model.body_frame[mk.body]].actInv(mean[i]), dtype=float)
            moved[mk.name] = float(np.linalg.norm(local - np.asarray(mk.offset, dtype=float)))
            markers[k] = Marker(mk.name, mk.body, local)
    added = []
    placed: dict[str, str] = {}
    too_far: dict[str, list[Any]] = {}
    not_markers = [lab for lab in labels if lab not in known and not is_measured_marker(lab)]
    for i, lab in enumerate(labels):
        if lab in known or lab in not_markers or not np.isfinite(mean[i]).all():
            continue
        dist, body = min((point_segment_distance(mean[i], a, b), nm) for nm, a, b in segs)
        if dist > max_distance_m:
            too_far[lab] = [body, dist]
            continue
        local = data.oMf[model.body_frame[body]].actInv(mean[i])
        added.append(Marker(lab, body, np.asarray(local, dtype=float)))
        placed[lab] = body
    info = {
        "static_marker_rms_m": float(np.nanmean(kin.marker_rms[ok])),
        "placed": placed,
        "not_markers": not_markers,
        "too_far": too_far,
        "moved": moved,
    }
    return model.with_markers([*markers, *added]), info
