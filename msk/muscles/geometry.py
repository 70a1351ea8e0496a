"""Muscle–tendon path geometry: lengths, Jacobians ∂l/∂θ, moment arms, lengthening velocities.

A muscle path is a chain of points fixed in model bodies (origin, via points, insertion),
**conditional** via points (active while one coordinate lies in a range), **moving** points
(location in the body a function of coordinates, as gait2392's quadriceps insertions) and
**wrapping cylinders** (the rehabilitation-robot lower-limb model paper, §2.1 "via cylinders";
OpenSim ``WrapCylinder`` with quadrant).

Length (Hayashibe et al. 2011, Eq. 6–7)::

    l(θ) = Σ_s |x_{B,s} − x_{A,s}| + Σ_wraps (geodesic arc on the cylinder)

over the straight segments s from A to B. Its Jacobian with respect to the Pinocchio
configuration, for unit vectors u_s = (x_B − x_A)/|x_B − x_A| and the translational Jacobians
J_x of the attached points, is ::

    ∂l/∂q_pin = Σ_s u_sᵀ (J_{x_B} − J_{x_A})

and with respect to the independent coordinates (q_pin = g(θ), G = ∂g/∂θ)::

    J_l = ∂l/∂θ = (∂l/∂q_pin) G + Σ_moving points f_pᵀ R_b ∂p_b/∂θ

where f_p is the net unit "pull" on point p (u of the segment arriving minus u of the segment
leaving) and ∂p_b/∂θ the derivative of a moving point's location in its body b. Moment arms are
r = −J_l (OpenSim's ``computeMomentArm`` convention) and the muscle–tendon force f maps to joint
torques τ = −J_lᵀ f = rᵀ f (Hayashibe et al. 2011, Eq. 7); the lengthening velocity is l̇ = J_l θ̇.

Translational Jacobians are never formed: with the world-frame joint Jacobian J (6×nv, columns
are joint twists at the world origin, Pinocchio's ``computeJointJacobians``), a point x on body b
has J_x = (J_lin − [x]× J_ang) S_b (S_b keeps the joints that support b), so
uᵀ J_x = (u, x × u)ᵀ J S_b: each segment contributes its unit line L_s = (u, x × u) (Plücker
coordinates, the same for every x on the segment) with + at its end and − at its start. With
G diagonal per Pinocchio DOF (q_j = g_j(θ_{c_j})), ::

    ∂l_m/∂θ_c = Σ_e (Σ_s σ_{s,e} L_s)ᵀ Σ_{j ∈ e} J_j g_j'(θ_c)

where the effective column e groups the DOFs of coordinate c that support the same bodies and
σ_{s,e} = [e supports the end body of s] − [e supports its start body]. A joint that carries
the whole path (or none of it) contributes exactly nothing (the unit wrenches of a path sum to
zero), so only the (muscle, e) rows of the joints a muscle crosses are computed, by sparse
products fixed at plan time (``σ`` is static without wraps; a segment followed by conditional
points has a few candidate ends). This is the Pinocchio frame Jacobian in LOCAL_WORLD_ALIGNED
shifted to the points, without a Python loop over points, muscles or frames. Joint placements
and J are computed for all frames at once from the Pinocchio tree (1-DOF joints: each column is
(o_j × a_j, a_j) for a revolute, (a_j, 0) for a prismatic joint), or, for a few frames, by
Pinocchio itself frame by frame; tests check both against each other and against Pinocchio.

Wrapping (cylinder, the rehabilitation-robot lower-limb model paper, §2.1): in the cylinder frame
(axis z, radius R) the shortest path from P to S over the cylinder is a straight line in the
developed surface: tangent points T1, T2 on the circle (plane xy), heights interpolated linearly
along the developed length, arc length sqrt((R Δφ)² + Δz²). By the envelope theorem (the geodesic
length is stationary w.r.t. the tangent points) the derivative of P–T1–arc–T2–S is that of two
straight segments P→T1 and T2→S whose inner ends T1, T2 are fixed in the cylinder's body; the arc
adds nothing. The wrap decision follows OpenSim 4.6 (``WrapCylinder::wrapLine``,
``GeometryPath::applyWrapObjects``): unconstrained cylinders wrap when the segment crosses the
cylinder; a quadrant (``+x``, ``-y``…) forces the path around the active side; no wrap when both
tangent points lie beyond ±length/2; among the segments of the wrap range, a crossing segment wins,
else the smallest length increase. Several wraps on one path are re-applied in turn on the current
path (as OpenSim) until the tangent points stop moving (1e-12 m; OpenSim stops after 8 passes or 0.5
mm), so that the envelope theorem holds. The tangent points contract linearly (~0.3 a pass), so
after every other pass Aitken's Δ² extrapolates them (x* = x₂ − (Δx₂)²/(Δx₂ − Δx₁), only where the
steps shrink); convergence is still judged on a plain pass, hence the same fixed point in about 40 %
fewer passes. A path that alternates between two states (the wraps choose different segments
in turn: a 2-cycle) has no path consistent with the wrap rules; some gastrocnemius poses of
Rajagopal 2016 reach it where the condyle and shank cylinders overlap (a tangent point of one
wrap inside the other cylinder refuses that wrap, and the shank wrap jumps to the segment
before the condyles, the long way round: ~0.72 m instead of ~0.47 m). Such a path is resolved
among candidate topologies, each iterated to its own fixed point so that the Jacobian stays
exact: one wrap position off, the others free; the shortest admissible candidate (the wrap
left off wraps no segment at the fixed point), else the converged one that loses least length
(:meth:`GeometryPlan._resolve_cycles`). Ellipsoids, spheres and tori raise :class:`ModelError`
(naming the muscle and the wrap object); OpenSim's own single-cylinder path is an
approximation of the geodesic (tangent-point heights by plane intersection), up to ~1 mm
longer in deep flexion.

Per-model static structure (point → body, support masks, moving/conditional points, wrap
candidates, the sparse row maps above, the coordinate functions as one spline table) is
precomputed once in a :class:`GeometryPlan` (Pinocchio ``Data`` style); a trial is processed in
one call, frames, muscles and wraps vectorised with numpy (the wraps of all paths are applied in
rounds: the r-th wrap of every path at once).
"""

from __future__ import annotations

import itertools
import threading
import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import ModelError, ShapeMismatchError
from msk.model.core import Model
from msk.model.joints import Linear, Multiplier, SimmSpline
from msk.muscles.hill import MuscleParameters
from msk.muscles.path import ConditionalPathPoint, MovingPathPoint, Muscle, PathPoint, WrapObject
from msk.timeseries import FrameAxis, FrameSparse
from msk.units import Array

__all__ = [
    "FrameGeometry",
    "GeometryPlan",
    "MuscleGeometry",
    "finite_frames",
    "geometry_plan",
    "jacobian_frames",
    "moment_arm_pattern",
    "muscle_geometry",
    "muscle_parameters",
    "wrap_cylinder",
]


# --------------------------------------------------------------------------------------------
# results
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class MuscleGeometry(FrameAxis):
    """Muscle–tendon geometry over a trial (time on axis 0, SI).

    Attributes:
        muscle_names: muscles in model order (``model.muscles``).
        coordinate_names: the model's independent coordinates θ.
        lengths: l (N, n_muscles), m.
        jacobian: J_l = ∂l/∂θ (N, n_muscles, n_coords), m/rad (m/m for translations); dense,
            or (the pipeline's ``muscle_geometry`` stage) a :class:`msk.timeseries.FrameSparse`
            holding only the coordinates each muscle crosses (``jacobian[frames]`` is dense).
        velocities: l̇ = J_l θ̇ (N, n_muscles), m/s, or ``None`` when no θ̇ was given.
        distal_wrenches: per joint asked for (``distal_wrench_joints``), ∂l/∂ξ (N, n_muscles, 6)
            for a rigid world twist ξ of everything distal to that joint: columns (force x, y,
            z, moment x, y, z about the world origin), world axes; zero for the muscles that do
            not cross it (see :meth:`GeometryPlan.evaluate`).
    """

    FRAME_FIELDS: ClassVar[tuple[str, ...]] = (
        "lengths",
        "jacobian",
        "velocities",
        "distal_wrenches",
    )

    muscle_names: tuple[str, ...]
    coordinate_names: tuple[str, ...]
    lengths: Array
    jacobian: Array | FrameSparse
    velocities: Array | None = None
    distal_wrenches: Mapping[str, Array | FrameSparse] = field(default_factory=dict)

    @property
    def moment_arms(self) -> Array:
        """r = −∂l/∂θ (N, n_muscles, n_coords), OpenSim's ``computeMomentArm`` sign."""
        return -np.asarray(self.jacobian)

    def muscle_index(self, name: str) -> int:
        try:
            return self.muscle_names.index(name)
        except ValueError:
            raise ModelError(f"no muscle {name!r} in this geometry") from None

    def coordinate_index(self, name: str) -> int:
        try:
            return self.coordinate_names.index(name)
        except ValueError:
            raise ModelError(f"no coordinate {name!r} in this geometry") from None


def muscle_parameters(model: Model) -> MuscleParameters:
    """F_iso, l_opt, l_ts, α_opt, v_max of ``model.muscles`` as arrays in model muscle order
    (the :class:`msk.muscles.hill.MuscleParameters` the Hill module consumes)."""
    ms = [_as_muscle(m) for m in model.muscles]
    return MuscleParameters(
        tuple(m.name for m in ms),
        np.array([m.max_isometric_force for m in ms], dtype=float),
        np.array([m.optimal_fiber_length for m in ms], dtype=float),
        np.array([m.tendon_slack_length for m in ms], dtype=float),
        np.array([m.pennation_angle for m in ms], dtype=float),
        np.array([m.max_contraction_velocity for m in ms], dtype=float),
    )


def _as_muscle(m: Any) -> Muscle:
    if not isinstance(m, Muscle):
        raise ModelError(f"model muscle {m!r} is not an msk.muscles.path.Muscle record")
    return m


# --------------------------------------------------------------------------------------------
# cylinder wrapping (vectorised over any leading shape)
# --------------------------------------------------------------------------------------------
_QUADRANTS = {
    "all": (0, 0),
    "x": (0, 1),
    "+x": (0, 1),
    "-x": (0, -1),
    "y": (1, 1),
    "+y": (1, 1),
    "-y": (1, -1),
}
_TWO_PI = 2.0 * np.pi


def _dsign(x: Array) -> Array:
    # SimmMacros DSIGN: (x >= 0) ? 1 : -1
    return np.where(x >= 0.0, 1.0, -1.0)


def _not_active(angle: Array, x_axis: Any, sign: Any) -> NDArray[np.bool_]:
    out = np.where(x_axis, (angle >= 0.5 * np.pi) & (angle <= 1.5 * np.pi), angle > np.pi)
    return np.where(sign < 0, ~out, out)


def wrap_cylinder(
    a: ArrayLike,
    b: ArrayLike,
    radius: float,
    *,
    quadrant: str = "all",
    length: float = np.inf,
) -> tuple[NDArray[np.bool_], Array, Array, Array, NDArray[np.bool_]]:
    """Shortest path from a to b over a cylinder (axis z through the origin, frame of the
    cylinder), shapes (..., 3). As OpenSim, the surface is infinite except that there is no wrap
    when both tangent points lie beyond ±``length``/2.

    Returns ``(wraps, t1, t2, arc, mandatory)``: a boolean mask, the tangent points (..., 3),
    the geodesic arc length between them (0 where it does not wrap) and whether the straight
    segment crossed the cylinder (OpenSim's *mandatory* wrap). Where it does not wrap, t1 = t2 = b.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    q = quadrant.strip().lower()
    if q not in _QUADRANTS:
        raise ModelError(f"cylinder quadrant {quadrant!r} is not one of {sorted(_QUADRANTS)}")
    axis, sign = _QUADRANTS[q]
    return _wrap_cylinder(a, b, float(radius), axis, sign, 0.5 * float(length))


def _wrap_cylinder(
    a: Array, b: Array, r: Any, axis: Any, sign: Any, half: Any
) -> tuple[NDArray[np.bool_], Array, Array, Array, NDArray[np.bool_]]:
    """:func:`wrap_cylinder` with radius, quadrant (axis 0/1, sign 0/±1) and half-length as
    scalars or arrays broadcasting against ``a[..., 0]`` (several cylinders at once)."""
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    ra2 = ax * ax + ay * ay
    rb2 = bx * bx + by * by
    r2 = r * r
    inside = (ra2 < r2) | (rb2 < r2)
    # closest approach of the projected segment to the axis (t in (0, 1) on the segment)
    dx, dy = bx - ax, by - ay
    dd = np.maximum(dx * dx + dy * dy, 1e-300)
    t = -(ax * dx + ay * dy) / dd
    cx, cy = ax + t * dx, ay + t * dy
    crosses = (cx * cx + cy * cy < r2) & (t > 0.0) & (t < 1.0)
    scalar = np.ndim(axis) == 0 and np.ndim(sign) == 0
    x_axis = axis == 0
    unconstrained = sign == 0
    if scalar and unconstrained:
        wraps = crosses.copy()
    else:
        pa = np.where(x_axis, ax, ay)
        pb = np.where(x_axis, bx, by)
        near = np.where(x_axis, cx, cy)
        on_a = _dsign(pa) == sign
        on_b = _dsign(pb) == sign
        # a point on the active side: wrap if crossing, or if the two points straddle the
        # quadrant plane and the line passes on the inactive side; no point on the active
        # side: the path is forced around the active side
        straddle = (_dsign(pa) != _dsign(pb)) & (_dsign(near) != sign)
        wraps = np.where(on_a | on_b, crosses | straddle, True)
        if not scalar:
            wraps = np.where(unconstrained, crosses, wraps)
    wraps = wraps & ~inside
    # tangent angles (OpenSim Creator's ScrewWrap formulation of the same geodesic)
    ra = np.sqrt(np.maximum(ra2, r2))
    rb = np.sqrt(np.maximum(rb2, r2))
    la = np.sqrt(np.maximum(ra2 - r2, 0.0))
    lb = np.sqrt(np.maximum(rb2 - r2, 0.0))
    da = np.arccos(np.clip(r / ra, -1.0, 1.0))
    db = np.arccos(np.clip(r / rb, -1.0, 1.0))
    phia = np.arctan2(ay, ax)
    phib = np.arctan2(by, bx)
    a_pos = np.mod(phia + da, _TWO_PI)
    a_neg = np.mod(phia - da, _TWO_PI)
    b_pos = np.mod(phib + db, _TWO_PI)
    b_neg = np.mod(phib - db, _TWO_PI)
    d_pos = np.mod(b_neg - a_pos, _TWO_PI)  # counter-clockwise a → b
    d_neg = np.mod(a_neg - b_pos, _TWO_PI)  # clockwise a → b
    if scalar and unconstrained:
        pos_ok = np.ones_like(wraps)
        neg_ok = np.ones_like(wraps)
    else:
        n1, n2 = _not_active(a_pos, x_axis, sign), _not_active(b_neg, x_axis, sign)
        pos_ok = ~((n1 & n2) | (~n1 & ~n2 & (d_pos > np.pi)))
        n1, n2 = _not_active(b_pos, x_axis, sign), _not_active(a_neg, x_axis, sign)
        neg_ok = ~((n1 & n2) | (~n1 & ~n2 & (d_neg > np.pi)))
        if not scalar:
            pos_ok = pos_ok | unconstrained
            neg_ok = neg_ok | unconstrained
    wraps = wraps & (pos_ok | neg_ok)
    positive = np.where(pos_ok & neg_ok, d_pos < d_neg, pos_ok)
    phi1 = np.where(positive, a_pos, a_neg)
    dphi = np.where(positive, d_pos, -d_neg)
    arc2d = r * np.abs(dphi)
    total = np.maximum(la + lb + arc2d, 1e-300)
    dz = bz - az
    z1 = az + dz * la / total
    z2 = az + dz * (la + arc2d) / total
    phi2 = phi1 + dphi
    wraps = wraps & ~((np.abs(z1) > half) & (np.abs(z2) > half))
    t1 = np.stack([r * np.cos(phi1), r * np.sin(phi1), z1], -1)
    t2 = np.stack([r * np.cos(phi2), r * np.sin(phi2), z2], -1)
    arc = np.where(wraps, np.sqrt(arc2d**2 + (z2 - z1) ** 2), 0.0)
    t1 = np.where(wraps[..., None], t1, b)
    t2 = np.where(wraps[..., None], t2, b)
    return wraps, t1, t2, arc, crosses & wraps


def _rot_xyz_body(angles: Array) -> Array:
    out = np.eye(3)
    for k, ang in enumerate(angles):
        c, s = np.cos(ang), np.sin(ang)
        i, j = [(1, 2), (0, 2), (0, 1)][k]
        rk = np.eye(3)
        rk[i, i] = rk[j, j] = c
        if k == 1:
            rk[i, j], rk[j, i] = s, -s
        else:
            rk[i, j], rk[j, i] = -s, s
        out = out @ rk
    return out


# --------------------------------------------------------------------------------------------
# the plan
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _WrapEntry:
    muscle: int
    name: str
    body: int  # index into plan bodies
    rotation: Array  # cylinder frame in body frame
    translation: Array
    radius: float
    length: float
    quadrant: str
    candidates: Array  # slot ids (original segments in range)
    extra_slot: int


class _WrapRound:
    """Per-wrap constants of a set of wraps on distinct paths, as arrays (K, ...)."""

    def __init__(self, plan: GeometryPlan, ks: list[int]) -> None:
        ws = [plan.wraps[k] for k in ks]
        self.k = np.asarray(ks, dtype=np.intp)
        self.body = np.array([w.body for w in ws], dtype=np.intp)
        self.muscle = np.array([w.muscle for w in ws], dtype=np.intp)
        self.extra = np.array([w.extra_slot for w in ws], dtype=np.intp)
        self.rotation = np.array([w.rotation for w in ws]).reshape(-1, 3, 3)
        self.translation = np.array([w.translation for w in ws]).reshape(-1, 3)
        shape = (len(ws), 1, 1)
        self.radius = np.array([w.radius for w in ws]).reshape(shape)
        self.half = np.array([0.5 * w.length for w in ws]).reshape(shape)
        quad = [_QUADRANTS[w.quadrant] for w in ws]
        self.axis = np.array([q[0] for q in quad], dtype=np.intp).reshape(shape)
        self.sign = np.array([q[1] for q in quad], dtype=np.intp).reshape(shape)
        cands = [plan._candidates[k] for k in ks]
        c_max = max((c.size for c in cands), default=0)
        self.cand = np.array(
            [np.concatenate([c, np.full(c_max - c.size, c[0])]) for c in cands], dtype=np.intp
        ).reshape(len(ws), c_max)
        self.cand_ok = np.array([np.arange(c_max) < c.size for c in cands], dtype=bool).reshape(
            len(ws), c_max
        )
        spans = [plan._muscle_slots[w.muscle] for w in ws]
        s_max = max((s1 - s0 for s0, s1 in spans), default=0)
        self.muscle_slots = np.array(
            [np.r_[np.arange(s0, s1), np.full(s_max - (s1 - s0), s0)] for s0, s1 in spans],
            dtype=np.intp,
        ).reshape(len(ws), s_max)


@dataclass
class _PathState:
    """Per-trial segment table: ends A/B (world), their point ids (−1: none; ≤ −2: wrap tangent
    points), validity, and the arc length of each muscle's wraps."""

    sa: Array
    sb: Array
    ia: NDArray[np.intp]
    ib: NDArray[np.intp]
    valid: NDArray[np.bool_]
    arcs: Array


_MAX_WRAP_PASSES = 100
_AITKEN = True  # extrapolate the multi-wrap iteration (tests compare with the plain one)
_AITKEN_RATIO = 0.7
_CHUNK_BYTES = 480 * 1024  # largest per-chunk temporary (wrap-free plans)
_PIN_FRAMES = 8  # up to this many frames, forward kinematics by Pinocchio frame by frame
_WRAP_TOL = 1e-12


class GeometryPlan:
    """Static structure of a model's muscle paths, computed once (à la Pinocchio ``Data``).

    Holds the gathered body list (Pinocchio joint + placement of each body frame), every path
    point's body and location, conditional ranges, moving-point functions, per-body support masks
    over the Pinocchio DOFs, the segment slots of each muscle and the wrap candidates. Read-only
    after construction.
    """

    def __init__(self, model: Model) -> None:
        from scipy import sparse  # on use: a cached run's geometry needs no scipy.sparse

        # a weak reference: the per-model cache (weak keys) must not keep its model alive
        self._model = weakref.ref(model)
        self.model_name = model.name
        self.muscles: tuple[Muscle, ...] = tuple(_as_muscle(m) for m in model.muscles)
        self.muscle_names = tuple(m.name for m in self.muscles)
        if len(set(self.muscle_names)) != len(self.muscle_names):
            dup = sorted({n for n in self.muscle_names if self.muscle_names.count(n) > 1})
            raise ModelError(f"model {model.name}: duplicate muscle names {dup}")
        self.coordinate_names = model.coordinate_names
        pm = model.pin_model
        nv = pm.nv
        self.nv = nv
        wrap_objects = _wrap_objects(model)

        bodies: list[str] = []
        body_index: dict[str, int] = {}

        def body_id(name: str, what: str) -> int:
            if name not in model.body_frame:
                raise ModelError(f"{what}: unknown body {name!r}")
            if name not in body_index:
                body_index[name] = len(bodies)
                bodies.append(name)
            return body_index[name]

        p_body: list[int] = []
        p_loc: list[Array] = []
        p_muscle: list[int] = []
        cond: list[tuple[int, int, float, float]] = []  # point, coord, lo, hi
        moving: list[tuple[int, int, int, Any]] = []  # point, axis, coord, function
        starts: list[int] = []
        for mi, mus in enumerate(self.muscles):
            if len(mus.points) < 2:
                raise ModelError(f"muscle {mus.name}: needs at least 2 path points")
            starts.append(len(p_body))
            for k, pt in enumerate(mus.points):
                if not isinstance(pt, PathPoint):
                    raise ModelError(f"muscle {mus.name}: path point {pt!r} is not a PathPoint")
                what = f"muscle {mus.name} point {pt.name}"
                idx = len(p_body)
                p_body.append(body_id(pt.body, what))
                loc = np.asarray(pt.location, dtype=float).reshape(-1)
                if loc.shape != (3,) or not np.all(np.isfinite(loc)):
                    raise ModelError(f"{what}: location must be 3 finite numbers, got {loc}")
                p_loc.append(loc)
                p_muscle.append(mi)
                if isinstance(pt, ConditionalPathPoint):
                    if k in (0, len(mus.points) - 1):
                        raise ModelError(f"{what}: origin/insertion cannot be conditional")
                    ci = _coord(model, pt.coordinate, what)
                    cond.append((idx, ci, float(pt.range[0]), float(pt.range[1])))
                elif isinstance(pt, MovingPathPoint):
                    for ax in range(3):
                        cname = pt.coordinates[ax] if ax < len(pt.coordinates) else None
                        fun = pt.functions[ax] if ax < len(pt.functions) else None
                        if cname is None or fun is None:
                            continue
                        moving.append((idx, ax, _coord(model, cname, what), fun))
        n_pts = len(p_body)
        self.n_points = n_pts
        self.starts = np.asarray(starts, dtype=np.intp)
        self.point_body = np.asarray(p_body, dtype=np.intp)
        self.point_muscle = np.asarray(p_muscle, dtype=np.intp)
        self.point_location = np.asarray(p_loc, dtype=float).reshape(n_pts, 3)
        self.conditional = cond
        self.moving = moving
        self.moving_points = np.unique(np.array([mv[0] for mv in moving], dtype=np.intp))
        is_last = np.zeros(n_pts, dtype=bool)
        ends = np.append(self.starts[1:], n_pts) - 1 if n_pts else np.zeros(0, np.intp)
        is_last[ends] = True
        self.is_last = is_last

        # segment slots: one per non-last point, then one extra per wrap use; grouped by muscle
        slot_start: list[int] = []  # original start point (or -1 for extra slots)
        slot_muscle: list[int] = []
        slot_of_point = np.full(n_pts, -1, dtype=np.intp)
        wraps: list[_WrapEntry] = []
        muscle_slot_start: list[int] = []
        for mi, mus in enumerate(self.muscles):
            muscle_slot_start.append(len(slot_start))
            s0 = int(self.starts[mi])
            npm = len(mus.points)
            for k in range(npm - 1):
                slot_of_point[s0 + k] = len(slot_start)
                slot_start.append(s0 + k)
                slot_muscle.append(mi)
            for pw in mus.wraps:
                wo = _find_wrap(wrap_objects, pw.wrap_object, mus.name)
                if not wo.active:
                    continue
                if wo.kind != "cylinder":
                    raise ModelError(
                        f"muscle {mus.name}: wrap object {wo.name!r} of kind {wo.kind!r} is not "
                        "supported (only cylinders)"
                    )
                if not (wo.radius > 0 and np.isfinite(wo.radius)):
                    raise ModelError(
                        f"muscle {mus.name}: wrap cylinder {wo.name!r} radius must be > 0, "
                        f"got {wo.radius}"
                    )
                q = str(wo.quadrant).strip().lower()
                if q not in _QUADRANTS:
                    raise ModelError(
                        f"muscle {mus.name}: wrap cylinder {wo.name!r} quadrant {wo.quadrant!r} "
                        "is not supported (all, ±x, ±y)"
                    )
                lo, hi = pw.range
                first = lo - 1 if lo >= 1 else 0
                last = hi - 1 if hi >= 1 else npm - 1
                if not (0 <= first < last <= npm - 1):
                    raise ModelError(
                        f"muscle {mus.name}: wrap {wo.name!r} range {pw.range} outside the "
                        f"{npm} path points"
                    )
                # a later wrap may also wrap the T2→S part of an earlier one (OpenSim applies
                # the wraps of a path in order, on the current path)
                cands = [muscle_slot_start[-1] + k for k in range(first, last)]
                extra = len(slot_start)
                slot_start.append(-1)
                slot_muscle.append(mi)
                wraps.append(
                    _WrapEntry(
                        muscle=mi,
                        name=wo.name,
                        body=body_id(wo.body, f"wrap object {wo.name}"),
                        rotation=_rot_xyz_body(np.asarray(wo.xyz_body_rotation, dtype=float)),
                        translation=np.asarray(wo.translation, dtype=float).reshape(3),
                        radius=float(wo.radius),
                        length=float(wo.length) if wo.length > 0 else np.inf,
                        quadrant=q,
                        candidates=np.asarray(cands, dtype=np.intp),
                        extra_slot=extra,
                    )
                )
        self.slot_start = np.asarray(slot_start, dtype=np.intp)
        self.slot_muscle = np.asarray(slot_muscle, dtype=np.intp)
        self.muscle_slot_start = np.asarray(muscle_slot_start, dtype=np.intp)
        self.slot_of_point = slot_of_point
        self.wraps = tuple(wraps)
        # candidate segments of each wrap: the original segments of its range and the T2 → end
        # segments of the other wraps of the same path
        self._n_wraps = np.bincount([w.muscle for w in wraps], minlength=len(self.muscles))
        self._candidates = [
            np.concatenate(
                [w.candidates, [v.extra_slot for v in wraps if v.muscle == w.muscle and v is not w]]
            ).astype(np.intp)
            for w in wraps
        ]
        bounds = [*muscle_slot_start, len(slot_start)]
        self._muscle_slots = [(bounds[i], bounds[i + 1]) for i in range(len(self.muscles))]
        orig = self.slot_start >= 0
        self.orig_slots = np.flatnonzero(orig)
        self.orig_start_point = self.slot_start[orig]

        # bodies: Pinocchio joint, placement of the body frame in the joint frame, support mask
        self.body_names = tuple(bodies)
        self.body_joint = np.array([model.body_joint[b] for b in bodies], dtype=np.intp)
        self.body_rot = np.array(
            [model.body_placement[b].rotation for b in bodies], dtype=float
        ).reshape(-1, 3, 3)
        self.body_trans = np.array(
            [model.body_placement[b].translation for b in bodies], dtype=float
        ).reshape(-1, 3)
        mask = np.zeros((len(bodies) + 1, nv))  # last row: "no body" (unused endpoints)
        for i, jid in enumerate(self.body_joint):
            for j in pm.supports[int(jid)]:
                if j > 0:
                    mask[i, pm.joints[j].idx_v : pm.joints[j].idx_v + pm.joints[j].nv] = 1.0
        self.support = mask
        self.cond_points = np.array([c[0] for c in cond], dtype=np.intp)
        self.cond_coord = np.array([c[1] for c in cond], dtype=np.intp)
        self.cond_lo = np.array([c[2] for c in cond], dtype=float)
        self.cond_hi = np.array([c[3] for c in cond], dtype=float)
        # extended points: path points, then T1, T2 of every wrap; (muscle, body) pairs
        wb_ = np.repeat(np.array([w.body for w in wraps], dtype=np.intp), 2)
        wm_ = np.repeat(np.array([w.muscle for w in wraps], dtype=np.intp), 2)
        ext_body = np.concatenate([self.point_body, wb_])
        ext_muscle = np.concatenate([self.point_muscle, wm_])
        self._n_ext = int(ext_body.size)
        keys = ext_muscle.astype(np.int64) * (len(bodies) + 1) + ext_body
        uniq, pair_of = np.unique(keys, return_inverse=True)
        pair_muscle = uniq // (len(bodies) + 1)
        pair_body = uniq % (len(bodies) + 1)
        n_pairs = uniq.size
        self._agg = sparse.csr_matrix(
            (np.ones(self._n_ext), (pair_of, np.arange(self._n_ext))),
            shape=(n_pairs, self._n_ext + 1),
        )
        self._pair_start = np.searchsorted(pair_muscle, np.arange(len(self.muscles)))
        self._pair_mask = self.support[pair_body]
        # static point locations as a sparse (P, 3B) matrix: x_p = R_b loc_p + t_b
        nb = len(bodies)
        rows_ = np.repeat(np.arange(n_pts), 3)
        cols_ = (self.point_body[:, None] * 3 + np.arange(3)).reshape(-1)
        self._loc_matrix = sparse.csr_matrix(
            (self.point_location.reshape(-1), (rows_, cols_)), shape=(n_pts, 3 * nb)
        )
        slot_of = {int(p): j for j, p in enumerate(self.moving_points)}
        self._mv_point = np.array([mv[0] for mv in moving], dtype=np.intp)
        self._mv_axis = np.array([mv[1] for mv in moving], dtype=np.intp)
        self._mv_coord = np.array([mv[2] for mv in moving], dtype=np.intp)
        self._mv_slot = np.array([slot_of[mv[0]] for mv in moving], dtype=np.intp)
        self._moving_bank = _FunctionBank(self._mv_coord, [mv[3] for mv in moving])
        # static start point of every slot (T2 of its wrap for the extra slots)
        ia_static = self.slot_start.copy()
        for k, w in enumerate(wraps):
            ia_static[w.extra_slot] = n_pts + 2 * k + 1
        self._ia_static = ia_static
        # wraps in rounds: round r holds the r-th wrap of every path (at most one per muscle,
        # so the wraps of a round touch disjoint slots and are applied at once)
        order: dict[int, list[int]] = {}
        for k, w in enumerate(wraps):
            order.setdefault(w.muscle, []).append(k)
        n_rounds = max((len(v) for v in order.values()), default=0)
        self._wrap_rounds = [
            _WrapRound(self, [v[r] for v in order.values() if len(v) > r]) for r in range(n_rounds)
        ]
        self._multi_rounds = [
            _WrapRound(self, [v[r] for v in order.values() if len(v) > 1 and len(v) > r])
            for r in range(n_rounds)
        ]
        self._multi_rounds = [r for r in self._multi_rounds if r.k.size]
        multi_muscles = sorted({w.muscle for w in wraps if self._n_wraps[w.muscle] > 1})
        self._multi_muscles = np.asarray(multi_muscles, dtype=np.intp)
        self._multi_wraps = np.array(
            [k for k, w in enumerate(wraps) if self._n_wraps[w.muscle] > 1], dtype=np.intp
        )
        self._multi_watch = np.array(
            [s for m in multi_muscles for s in range(*self._muscle_slots[m])], dtype=np.intp
        )
        # position in _multi_muscles of each watched slot and of each multi-wrap
        self._multi_watch_of = np.array(
            [i for i, m in enumerate(multi_muscles) for _ in range(*self._muscle_slots[m])],
            dtype=np.intp,
        )
        self._multi_watch_start = np.searchsorted(
            self._multi_watch_of, np.arange(len(multi_muscles))
        ).astype(np.intp)
        self._multi_wrap_of = np.searchsorted(
            self._multi_muscles, [wraps[k].muscle for k in self._multi_wraps]
        ).astype(np.intp)
        # the embedding θ → q_pin, grouped
        cp = model.coupling
        self._q_const = np.array(
            [float(f(0.0)) if c < 0 else 0.0 for c, f in zip(cp.coordinate, cp.functions)]
        )
        self._var_dof = np.array([k for k, c in enumerate(cp.coordinate) if c >= 0], dtype=np.intp)
        self._coupling_bank = _FunctionBank(
            np.asarray(cp.coordinate, dtype=np.intp)[self._var_dof],
            [cp.functions[k] for k in self._var_dof],
        )
        self._dof_coord = np.asarray(cp.coordinate, dtype=np.intp)
        # batched forward kinematics of the Pinocchio tree (1-DOF joints)
        self._fk = _tree_structure(pm)
        self._pm = pm
        self._local = threading.local()  # a Pinocchio Data per thread (few-frame calls)
        self._body_joint_list = [int(j) for j in self.body_joint]
        self._build_rows(model, ext_body, ext_muscle)

    def _build_rows(self, model: Model, ext_body: Array, ext_muscle: Array) -> None:
        """Static structure of the fast Jacobian aggregation.

        ∂l_m/∂θ_c = Σ_{j: q_j = g_j(θ_c)} g_j'(θ_c) Σ_{p ∈ m, j supports body(p)} W_pᵀ J_j with
        W_p = (f_p, x_p × f_p) the unit wrench at path point p. DOFs of one coordinate that
        support the same plan bodies are merged into one effective column e (their twists scaled
        by g_j' and summed); a row (m, e) exists only when e supports some but not all of
        muscle m's bodies (the unit wrenches of a muscle sum to zero: a joint that carries the
        whole path, or none of it, contributes nothing).
        """
        from scipy import sparse  # on use: a cached run's geometry needs no scipy.sparse

        nb = len(self.body_names)
        nv = self.nv
        sup = self.support[:nb].astype(bool)  # (B, nv)
        cols: dict[tuple[int, bytes], int] = {}
        col_coord: list[int] = []
        dof_col = np.full(nv, -1, dtype=np.intp)
        for j in range(nv):
            c = int(self._dof_coord[j])
            if c < 0 or not sup[:, j].any():
                continue
            key = (c, sup[:, j].tobytes())
            if key not in cols:
                cols[key] = len(col_coord)
                col_coord.append(c)
            dof_col[j] = cols[key]
        n_cols = len(col_coord)
        used = np.flatnonzero(dof_col >= 0)
        # DOFs sorted by effective column, for one reduceat (no BLAS call: on a shared
        # machine a threaded gemm costs more than it saves on these small products)
        order = used[np.argsort(dof_col[used], kind="stable")]
        self._col_dofs = order
        self._col_start = np.searchsorted(dof_col[order], np.arange(n_cols))
        col_sup = np.zeros((nb, n_cols), dtype=bool)
        for j in used.tolist():
            col_sup[:, dof_col[j]] = sup[:, j]
        r_idx: list[int] = []
        p_idx: list[int] = []
        row_col: list[int] = []
        row_target: list[int] = []
        nc = len(self.coordinate_names)
        for mi in range(self.n_muscles):
            pts = np.flatnonzero(ext_muscle == mi)
            bmask = col_sup[ext_body[pts]]  # (points, cols)
            for e in range(n_cols):
                on = bmask[:, e]
                if on.any() and not on.all():
                    r = len(row_col)
                    row_col.append(e)
                    row_target.append(mi * nc + col_coord[e])
                    for p in pts[on]:
                        r_idx.append(r)
                        p_idx.append(int(p))
        n_rows = len(row_col)
        self._row_muscle = np.asarray(row_target, dtype=np.intp) // max(nc, 1)
        self._col_sup = col_sup
        # the rows, then one row per moving point (its net wrench, for the ∂p_b/∂θ term)
        n_mvp = self.moving_points.size
        r_idx += list(range(n_rows, n_rows + n_mvp))
        p_idx += [int(p) for p in self.moving_points]
        self._row_agg = sparse.csr_matrix(
            (np.ones(len(r_idx)), (r_idx, p_idx)), shape=(n_rows + n_mvp, self._n_ext + 1)
        )
        self._mv_row = n_rows + np.searchsorted(self.moving_points, self._mv_point)
        self._build_static_segments()
        per_frame = 48 * max(self._row_agg.shape[0], self.n_points, self.slot_start.size, 1)
        self._chunk = max(8, _CHUNK_BYTES // per_frame)
        self._row_col = np.asarray(row_col, dtype=np.intp)
        mv_target = self.point_muscle[self._mv_point] * nc + self._mv_coord
        targets = np.concatenate([np.asarray(row_target, dtype=np.intp), mv_target])
        uniq, inv = np.unique(targets, return_inverse=True)
        n_src = targets.size
        self._target_sum = sparse.csr_matrix(
            (np.ones(n_src), (inv, np.arange(n_src))), shape=(uniq.size, n_src)
        )
        self._target_cols = uniq.astype(np.intp)
        self._target_muscle = (uniq // max(nc, 1)).astype(np.intp)
        self._target_coord = (uniq % max(nc, 1)).astype(np.intp)
        self._muscle_of_target = sparse.csr_matrix(
            (np.ones(uniq.size), (self._target_muscle, np.arange(uniq.size))),
            shape=(self.n_muscles, uniq.size),
        )

    def _build_static_segments(self) -> None:
        """Without wraps every segment starts at a fixed point and ends at the next active one:
        the rows are then Σ_s σ_s L_s with L_s = (u_s, x_A × u_s) the segment's unit line
        (Plücker coordinates: the same at both ends) and σ_s = A[:, end] − A[:, start]
        static, except for a segment followed by conditional points, whose end is one of a few
        candidates (the next points up to the first unconditional one)."""
        from scipy import sparse  # on use: a cached run's geometry needs no scipy.sparse

        self._static = not self.wraps
        if not self._static:
            return
        sp = self.orig_start_point
        n_seg = sp.size
        is_cond = np.zeros(self.n_points, dtype=bool)
        is_cond[self.cond_points] = True
        agg = self._row_agg.tocsc()
        dyn = np.flatnonzero(is_cond[sp + 1])
        static = np.flatnonzero(~is_cond[sp + 1])
        ends = agg[:, sp[static] + 1] @ sparse.csc_matrix(
            (np.ones(static.size), (np.arange(static.size), static)), shape=(static.size, n_seg)
        )
        sigma = (ends - agg[:, sp]).tocsc()
        sigma.eliminate_zeros()
        need = np.union1d(np.flatnonzero(np.diff(sigma.indptr) > 0), dyn).astype(np.intp)
        self._seg_need = need
        self._seg_sigma = sigma[:, need].tocsr()
        cands = []
        for s in dyn:
            c = [int(sp[s]) + 1]
            while is_cond[c[-1]]:
                c.append(c[-1] + 1)
            cands.append(c)
        depth = max((len(c) for c in cands), default=0)
        self._dyn_seg = dyn
        self._dyn_need = np.searchsorted(need, dyn)
        self._dyn_cand = np.array(
            [c + [c[-1]] * (depth - len(c)) for c in cands], dtype=np.intp
        ).reshape(dyn.size, depth)
        ent_seg = [i for i, c in enumerate(cands) for _ in c]
        ent_lvl = [k for c in cands for k in range(len(c))]
        ent_pt = [p for c in cands for p in c]
        self._ent_seg = np.asarray(ent_seg, dtype=np.intp)
        self._ent_lvl = np.asarray(ent_lvl, dtype=np.intp)
        self._ent_agg = agg[:, np.asarray(ent_pt, dtype=np.intp)].tocsr()

    @property
    def model(self) -> Model | None:
        """The model this plan was built for (``None`` once that model is gone)."""
        return self._model()

    @property
    def n_muscles(self) -> int:
        return len(self.muscles)

    # -------------------------------------------------------------- evaluation
    def kinematics(self, theta: Array) -> tuple[Array, Array, Array, Array]:
        """Per frame: world-frame joint Jacobians J (N, 6, nv) (Pinocchio's
        ``computeJointJacobians``), body rotations (N, B, 3, 3) and translations (N, B, 3) in
        world, and G (N, nq, n_coords); all frames at once (batched forward kinematics)."""
        q, g = self._embed(theta)
        jac, rot, trans = self._body_kinematics(q)
        return jac, rot, trans, g

    def _embed(self, theta: Array) -> tuple[Array, Array]:
        """q = g(θ) (N, nq) and G = ∂g/∂θ (N, nq, n_coords), as ``model.coupling`` computes them,
        with the coordinate functions evaluated in groups (splines sharing knots at once)."""
        q, d = self._embed_diag(theta)
        g = np.zeros((theta.shape[0], q.shape[1], len(self.coordinate_names)))
        k = np.flatnonzero(self._dof_coord >= 0)
        g[:, k, self._dof_coord[k]] = d[:, k]
        return q, g

    def _embed_diag(self, theta: Array) -> tuple[Array, Array]:
        """q = g(θ) (N, nq) and the non-zero entries of G: g_j'(θ_{c_j}) (N, nq), 0 for a
        constant DOF (each Pinocchio DOF is a function of one coordinate)."""
        n = theta.shape[0]
        q = np.empty((n, self._q_const.size))
        q[:] = self._q_const
        d = np.zeros((n, self._q_const.size))
        val, d1 = self._coupling_bank.evaluate(theta)
        q[:, self._var_dof] = val
        d[:, self._var_dof] = d1
        return q, d

    def evaluate(
        self,
        theta: ArrayLike,
        theta_dot: ArrayLike | None = None,
        *,
        distal_wrench_joints: Sequence[str] = (),
        compact: bool = False,
    ) -> MuscleGeometry:
        """Lengths, Jacobians ∂l/∂θ (and l̇ when θ̇ is given) for θ of shape (N, n_coords).

        ``compact``: the Jacobian as a :class:`msk.timeseries.FrameSparse` of the entries at
        :meth:`jacobian_positions` (the values the dense one has there, copied from the same
        pass: bit for bit), never allocated dense — ``(N, n_muscles, n_coords)`` float64 is
        17 kB a frame for gait2392, 69 MB for a block of 4 096 frames.

        ``distal_wrench_joints``: model joints (e.g. ``("knee_r",)``) for which the same pass
        also returns :attr:`MuscleGeometry.distal_wrenches`, the unit wrench ∂l_i/∂ξ of each
        muscle on everything distal to the joint (ξ a rigid world twist of that side, a virtual
        six-DOF joint in its place). It is Σ (u, x × u) over the path-segment ends on the
        bodies the joint supports, which is exactly the Jacobian row (muscle, joint) the length
        Jacobian already aggregates (module docstring: a row exists for every muscle that
        crosses the joint): no extra path resolution. Only for a joint none of whose DOFs moves
        with a coordinate (no such row) is the path evaluated once more.
        """
        th = _frames(theta, len(self.coordinate_names), "q")
        thd = None
        if theta_dot is not None:
            thd = _frames(theta_dot, len(self.coordinate_names), "qdot")
            if thd.shape != th.shape:
                raise ShapeMismatchError(f"qdot shape {thd.shape} differs from q shape {th.shape}")
        n = th.shape[0]
        m, nc = self.n_muscles, len(self.coordinate_names)
        lengths = np.empty((n, m))
        jl = np.empty((n, self._target_cols.size)) if compact else np.zeros((n, m, nc))
        vel = None if thd is None else np.empty((n, m))
        joints = tuple(dict.fromkeys(distal_wrench_joints))
        dw = {j: np.zeros((n, m, 6)) for j in joints}
        by_row = {j: self._distal_rows(j) for j in joints}
        rowed = {j: r for j, r in by_row.items() if r is not None}
        # frames in chunks: the temporaries stay small (cache, and no fresh pages to fault in
        # on every call); wrap iterations keep the whole batch (their cost is per pass)
        # chunks of equal size (no short last chunk paying the per-chunk overhead alone)
        n_chunks = -(-n // self._chunk) if self._static else 1
        bounds = [c * n // n_chunks for c in range(n_chunks + 1)] if n else [0, 0]
        for c0, c1 in itertools.pairwise(bounds):
            sl = slice(c0, c1)
            self._evaluate_into(
                th[sl], None if thd is None else thd[sl], lengths[sl], jl[sl],
                None if vel is None else vel[sl],
                {j: (rows, mus, dw[j][sl]) for j, (rows, mus) in rowed.items()},
            )  # fmt: skip
        for j, r in by_row.items():
            if r is None and n:
                dw[j][:] = self._distal_by_twists(th, self._joint_dofs(j))
        jac: Array | FrameSparse = (
            FrameSparse(jl, self._target_cols.copy(), (m, nc)) if compact else jl
        )
        return MuscleGeometry(self.muscle_names, self.coordinate_names, lengths, jac, vel, dw)

    def jacobian_positions(self) -> NDArray[np.intp]:
        """Flat (muscle, coordinate) positions, increasing, of the Jacobian entries
        :meth:`evaluate` writes: every other entry of ∂l/∂θ is exactly 0 (the compact form
        :class:`msk.timeseries.FrameSparse` keeps these only)."""
        return self._target_cols.copy()

    def distal_positions(self, joint: str) -> NDArray[np.intp]:
        """Flat (muscle, component) positions, increasing, of the entries of
        :attr:`MuscleGeometry.distal_wrenches` ``[joint]`` that can be nonzero (the six
        components of the muscles crossing ``joint``; all of them when the wrenches come from
        :meth:`_distal_by_twists`)."""
        rows = self._distal_rows(joint)
        if rows is None:
            return np.arange(self.n_muscles * 6, dtype=np.intp)
        mus = np.unique(rows[1])
        return (mus[:, None] * 6 + np.arange(6)).ravel().astype(np.intp)

    def _joint_dofs(self, joint: str) -> list[int]:
        """Pinocchio velocity indices of the axes of the model joint ``joint`` (first first)."""
        model = self.model
        if model is None:
            raise ModelError(f"geometry plan of {self.model_name!r}: its model is gone")
        spec = next((j for j in model.joints if j.name == joint), None)
        if spec is None:
            raise ModelError(f"model {model.name}: no joint {joint!r}")
        if not spec.axes:
            raise ModelError(f"model {model.name}: joint {joint!r} is a weld (no axis to cut at)")
        names = [joint] if len(spec.axes) == 1 else [f"{joint}_{k}" for k in range(len(spec.axes))]
        out = []
        for name in names:
            jid = self._pm.getJointId(name)
            if jid >= self._pm.njoints:
                raise ModelError(f"model {model.name}: no Pinocchio joint {name!r} for {joint!r}")
            out.append(int(self._pm.joints[jid].idx_v))
        return out

    def _distal_rows(self, joint: str) -> tuple[NDArray[np.intp], NDArray[np.intp]] | None:
        """The Jacobian rows (muscle, e) whose effective column e supports exactly the plan bodies
        distal to ``joint``, and their muscles; ``None`` when no column does (then
        :meth:`_distal_by_twists`). Computed once per joint (the plan's model is immutable): a
        stream evaluates one frame per call (:mod:`msk.live`)."""
        cache = self.__dict__.setdefault("_distal_rows_cache", {})
        if joint not in cache:
            cache[joint] = self._find_distal_rows(joint)
        return cache[joint]

    def _find_distal_rows(self, joint: str) -> tuple[NDArray[np.intp], NDArray[np.intp]] | None:
        """:meth:`_distal_rows` computed."""
        dofs = self._joint_dofs(joint)
        nb = len(self.body_names)
        pattern = self.support[:nb, dofs[0]].astype(bool)
        if not pattern.any():  # no muscle point distal to the joint
            return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp)
        match = np.flatnonzero((self._col_sup == pattern[:, None]).all(axis=0))
        if match.size == 0:
            return None
        rows = np.flatnonzero(self._row_col == match[0])
        return rows, self._row_muscle[rows]

    def _distal_by_twists(self, th: Array, dofs: list[int]) -> Array:
        """∂l/∂ξ (N, M, 6) by the path evaluation with, in place of the joint Jacobian, unit
        twists on ``dofs`` (those with the first one's support pattern: the axes of a coupled
        joint all carry the same distal bodies, so a 3-axis joint needs two stacked
        evaluations, a 1-axis one six). Used when no Jacobian row gives it directly."""
        sup = self.support
        cols = [iv for iv in dofs if np.array_equal(sup[:, iv], sup[:, dofs[0]])]
        k = th.shape[0]
        jac, rot, trans, _ = self.kinematics(th)
        groups = [list(range(c, min(c + len(cols), 6))) for c in range(0, 6, len(cols))]
        reps = len(groups)
        fake = np.zeros((reps * k, *jac.shape[1:]))
        for r, comps in enumerate(groups):
            for col, comp in zip(cols, comps):
                fake[r * k : (r + 1) * k, comp, col] = 1.0
        tile = (reps,) + (1,) * (rot.ndim - 1)
        _, dl_dq, _ = self._paths(
            np.tile(th, (reps, 1)), fake, np.tile(rot, tile), np.tile(trans, (reps, 1, 1))
        )
        w = np.empty((k, self.n_muscles, 6))
        for r, comps in enumerate(groups):
            for col, comp in zip(cols, comps):
                w[:, :, comp] = dl_dq[r * k : (r + 1) * k, :, col]
        return w

    def _evaluate_into(
        self,
        th: Array,
        thd: Array | None,
        lengths: Array,
        jl: Array,
        vel: Array | None,
        distal: Mapping[str, tuple[NDArray[np.intp], NDArray[np.intp], Array]] | None = None,
    ) -> None:
        """One chunk of :meth:`evaluate`, written into the given output views (``jl`` dense
        ``(n, M, n_coords)`` or compact ``(n, U)``, the entries at :attr:`_target_cols`);
        ``distal``: per joint (its rows, their muscles, the (n, M, 6) view their wrenches go
        to)."""
        n = th.shape[0]
        q, dg = self._embed_diag(th)
        jac, rot, trans = self._body_kinematics(q)
        if self._static:
            lengths[:], rows, dloc = self._static_rows(th, rot, trans)
        else:
            lengths[:], wp, dloc = self._wrenches(th, rot, trans)
            rows = _spmm(self._row_agg, wp.reshape(-1, n * 6)).reshape(-1, n, 6)
        for r_idx, mus, out in (distal or {}).values():
            out[:, mus] = rows[r_idx].transpose(1, 0, 2)
        # effective columns: twists of the DOFs of one coordinate scaled by g_j' and summed
        n_rows = self._row_col.size
        if n_rows:
            jg = jac[:, :, self._col_dofs] * dg[:, None, self._col_dofs]
            jt = np.add.reduceat(jg, self._col_start, axis=2).transpose(2, 0, 1)  # (E, N, 6)
            vals = np.einsum("rnc,rnc->rn", rows[:n_rows], jt[self._row_col])
        else:  # no muscle crosses a joint
            vals = np.zeros((0, n))
        if self.moving:
            mv_p, mv_ax = self._mv_point, self._mv_axis
            col = rot[:, self.point_body[mv_p], :, mv_ax]  # (E, N, 3)
            term = np.einsum("eni,eni->en", rows[self._mv_row, :, :3], col) * dloc.T
            vals = np.concatenate([vals, term])
        v = _spmm(self._target_sum, vals)  # (U, N)
        if jl.ndim == 2:  # compact: the entries at _target_cols, in their order
            jl[:] = v.T
        else:
            jl.reshape(n, -1)[:, self._target_cols] = v.T
        if vel is not None and thd is not None:
            vel[:] = _spmm(self._muscle_of_target, v * thd.T[self._target_coord]).T

    def _body_kinematics(self, q: Array) -> tuple[Array, Array, Array]:
        """World-frame joint Jacobians (N, 6, nv), plan-body rotations (N, B, 3, 3) and
        translations (N, B, 3) from q_pin."""
        n = q.shape[0]
        if n <= _PIN_FRAMES:
            # a few frames: Pinocchio's own (C++) pass per frame beats ~10 numpy calls per joint
            data = getattr(self._local, "data", None)
            if data is None:
                data = self._local.data = self._pm.createData()
            jac = np.empty((n, 6, self.nv))
            rjb = np.empty((n, self.body_joint.size, 3, 3))
            tjb = np.empty((n, self.body_joint.size, 3))
            joints = self._body_joint_list
            for i in range(n):
                jac[i] = np.reshape(pin.computeJointJacobians(self._pm, data, q[i]), (6, -1))
                omi = data.oMi
                for b, jid in enumerate(joints):
                    m_ = omi[jid]
                    rjb[i, b] = m_.rotation
                    tjb[i, b] = m_.translation
        else:
            rj, tj, jac = _batched_fk(self._fk, q, self.nv)
            rjb = rj[:, self.body_joint]
            tjb = tj[:, self.body_joint]
        rot = rjb @ self.body_rot
        trans = tjb + np.einsum("nbij,bj->nbi", rjb, self.body_trans)
        return jac, rot, trans

    def _apply_round(
        self,
        rd: _WrapRound,
        st: _PathState,
        rot: Array,
        trans: Array,
        fa: NDArray[np.intp],
        only: NDArray[np.intp] | None = None,
        *,
        dry: bool = False,
    ) -> tuple[Array, Array]:
        """Wrap, for each of the K wraps of a round (distinct paths) and each frame of ``fa``,
        the best candidate segment over the cylinder (a crossing segment wins, else the smallest
        length increase): the segment A→B becomes A→T1 and T2→B (the wrap's extra slot).
        ``only`` (K, F): −2 keeps a wrap off (−1: free). Returns the hit masks and arc lengths
        (K, F); ``dry``: only the decision, the path is left unchanged."""
        nk, nf = rd.k.size, fa.size
        rb = rot[fa[None, :], rd.body[:, None]]  # (K, F, 3, 3)
        rc = rb @ rd.rotation[:, None]
        oc = trans[fa[None, :], rd.body[:, None]] + (rb @ rd.translation[:, None, :, None])[..., 0]
        ix = (rd.cand[:, :, None], fa[None, None, :])  # (K, C, F)
        a = np.einsum("kfji,kcfj->kfci", rc, st.sa[ix] - oc[:, None])
        b = np.einsum("kfji,kcfj->kfci", rc, st.sb[ix] - oc[:, None])
        wraps, t1, t2, arc, mand = _wrap_cylinder(a, b, rd.radius, rd.axis, rd.sign, rd.half)
        wraps &= st.valid[ix].transpose(0, 2, 1) & rd.cand_ok[:, None, :]
        mand &= wraps
        change = np.linalg.norm(t1 - a, axis=-1) + arc + np.linalg.norm(b - t2, axis=-1)
        change -= np.linalg.norm(b - a, axis=-1)
        order = np.arange(rd.cand.shape[1])
        score = np.where(mand, -1e9 + order, np.where(wraps, change, np.inf))
        if only is not None:  # a wrap kept off
            score = np.where(only[..., None] == -2, np.inf, score)
        best = np.argmin(score, axis=2)  # (K, F)
        kk, ff = np.nonzero(np.isfinite(np.take_along_axis(score, best[..., None], 2)[..., 0]))
        hit = np.zeros((nk, nf), dtype=bool)
        arc_hit = np.zeros((nk, nf))
        hit[kk, ff] = True
        if kk.size == 0 or dry:
            return hit, arc_hit
        kb = best[kk, ff]
        fr = fa[ff]
        slot = rd.cand[kk, kb]
        rch, och = rc[kk, ff], oc[kk, ff]
        t1w = np.einsum("nij,nj->ni", rch, t1[kk, ff, kb]) + och
        t2w = np.einsum("nij,nj->ni", rch, t2[kk, ff, kb]) + och
        e = rd.extra[kk]
        st.sa[e, fr] = t2w
        st.sb[e, fr] = st.sb[slot, fr]
        st.ib[e, fr] = st.ib[slot, fr]
        st.ia[e, fr] = -3 - 2 * rd.k[kk]
        st.valid[e, fr] = True
        st.sb[slot, fr] = t1w
        st.ib[slot, fr] = -2 - 2 * rd.k[kk]
        arc_hit[kk, ff] = arc[kk, ff, kb]
        st.arcs[rd.muscle[kk], fr] += arc_hit[kk, ff]
        return hit, arc_hit

    def _remove_round(self, rd: _WrapRound, st: _PathState, hit: Array, arc: Array) -> None:
        """Undo :meth:`_apply_round` where ``hit`` (K, n): the segment ending at the wrap's T1
        takes back the end of the segment starting at its T2; ``arc`` (K, n) the arcs added."""
        kk, fr = np.nonzero(hit)
        if kk.size == 0:
            return
        slots = rd.muscle_slots[kk]  # (H, S_max), padded with the first slot
        mine = st.ib[slots, fr[:, None]] == (-2 - 2 * rd.k[kk])[:, None]
        into = slots[np.arange(kk.size), np.argmax(mine, axis=1)]
        e = rd.extra[kk]
        st.sb[into, fr] = st.sb[e, fr]
        st.ib[into, fr] = st.ib[e, fr]
        st.valid[e, fr] = False
        st.ia[e, fr] = -1
        st.arcs[rd.muscle[kk], fr] -= arc[kk, fr]

    def _iterate_wraps(
        self,
        st: _PathState,
        rot: Array,
        trans: Array,
        wr: tuple[Array, Array],
        todo: NDArray[np.intp],
        frozen: NDArray[np.intp] | None = None,
    ) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
        """Several wraps on one path: re-wrap each on the current path until the tangent points
        stop moving (OpenSim iterates up to 8 times to 0.5 mm; we go to convergence so that the
        envelope theorem, hence the analytic Jacobian, holds). ``wr`` = (hits, arcs) of every
        wrap (n_wraps, N), updated in place; ``frozen`` (n_wraps, N): −2 keeps a wrap off,
        −1 leaves it free.

        Returns, per (multi-wrap muscle, frame) (M', N): whether it converged and whether it
        ended in a 2-cycle (its wraps choose different segments in turn and the path alternates
        between two states; it is left on the shorter one, see :meth:`_resolve_cycles`)."""
        n = st.valid.shape[1]
        watch, mm = self._multi_watch, self._multi_muscles
        hits, arc_of = wr
        if frozen is None:
            frozen = np.full(hits.shape, -1, dtype=np.intp)
        converged = np.zeros((mm.size, n), dtype=bool)
        cycled = np.zeros((mm.size, n), dtype=bool)
        back2 = None  # watched segment ends two passes back
        last_x = 0  # last pass followed by an extrapolation
        for p in range(1, _MAX_WRAP_PASSES + 1):
            wx = (watch[:, None], todo[None, :])
            snap = self._take_state(st, wr, todo)
            before = np.concatenate(snap[:2], 0)
            for rd in self._multi_rounds:
                undo = np.zeros((rd.k.size, n), dtype=bool)
                undo[:, todo] = hits[rd.k][:, todo]
                self._remove_round(rd, st, undo, arc_of[rd.k])
                h, arc = self._apply_round(
                    rd, st, rot, trans, todo, frozen[rd.k[:, None], todo[None, :]]
                )
                hits[rd.k[:, None], todo] = h
                arc_of[rd.k[:, None], todo] = arc
            after = np.concatenate([st.sa[wx], st.sb[wx]], 0)
            moved = np.abs(after - before).max(axis=2)  # (2W, F)
            keep = moved.max(axis=0) >= _WRAP_TOL
            conv = self._per_muscle(moved) < _WRAP_TOL  # (M', F)
            converged[:, todo] = conv
            cyc = np.zeros_like(keep)
            if back2 is not None:
                # a muscle back to its state of two passes ago, which moved: a 2-cycle
                cyc_m: NDArray[np.bool_] = ~conv & (
                    self._per_muscle(np.abs(after - back2).max(axis=2)) < _WRAP_TOL
                )
                cyc = cyc_m.any(axis=0)
            if cyc.any():
                # a 2-cycle never converges: leave each cycling muscle on the shorter of the two
                # states (the previous pass's or this one's) and stop iterating the frame (the
                # other muscles of the frame are finished by :meth:`_resolve_cycles`)
                c = np.flatnonzero(cyc)
                fr = todo[c]
                now = self._take_state(st, wr, fr)
                prev = tuple(x[:, c] for x in snap)
                back = cyc_m[:, c] & (self._state_lengths(prev) < self._state_lengths(now))
                self._put_state(st, wr, fr, prev, back)
                cycled[:, fr] = cyc_m[:, c]
                keep[c] = False
            if _AITKEN and back2 is not None and p - last_x >= 2:
                # Aitken's Δ² on three successive iterates x0, x1 = F(x0), x2 = F(x1) of the
                # frames converging linearly (the tangent points contract by ~0.3 a pass): a
                # better start for the next pass; convergence is still judged on a plain pass,
                # so the fixed point is the same
                d1, d2 = before - back2, after - before
                dd = d2 - d1
                n1 = np.abs(d1).max(axis=(0, 2))
                n2 = np.abs(d2).max(axis=(0, 2))
                good = keep & (n2 < _AITKEN_RATIO * n1)
                if good.any():
                    g = np.flatnonzero(good)
                    d2g, ddg = d2[:, g], dd[:, g]
                    use = (np.abs(ddg) > 1e-300) & (np.abs(d2g) < _AITKEN_RATIO * np.abs(d1[:, g]))
                    step = np.where(use, d2g * d2g / np.where(use, ddg, 1.0), 0.0)
                    x = after[:, g] - step
                    wg = (watch[:, None], todo[g][None, :])
                    st.sa[wg], st.sb[wg] = x[: watch.size], x[watch.size :]
                    last_x = p
            back2 = before[:, keep]
            todo = todo[keep]  # keep iterating the frames still moving
            if todo.size == 0:
                break
        return converged, cycled

    def _resolve_cycles(
        self,
        st: _PathState,
        rot: Array,
        trans: Array,
        wr: tuple[Array, Array],
        cycled: NDArray[np.bool_],
    ) -> None:
        """The path of a (muscle, frame) whose wrap iteration ends in a 2-cycle.

        Such a cycle means that OpenSim's wrap rules admit no consistent path: Rajagopal's
        gastrocnemii reach it where the condyle and shank cylinders overlap. The condyle
        tangent point falls inside the shank cylinder (an end inside the radius: no wrap), so
        the shank wrap is refused on the segment after the condyles and its quadrant forces it
        onto the segment before them, the long way round (~0.72 m instead of ~0.47 m); on the
        next pass the condyle wrap takes the segment before the shank again, and so on.

        The candidates are the paths with one wrap position r of the path off (the r-th wrap
        of every multi-wrap path) and the others free, each iterated to its own fixed point, so
        that the envelope theorem, hence the analytic Jacobian, holds. A candidate is
        admissible when the iteration converges and the wrap left off, re-applied at the fixed
        point, wraps no segment; the shortest admissible one is kept. Where none is (the
        frames above: dropping the shank wrap lets the path cut through the shank cylinder,
        dropping the condyle wrap lets the segment before the shank graze the condyle
        cylinder), the converged candidate that loses least length, hence stays closest to
        the path that cannot be completed, is kept: for the gastrocnemii the shank wrap alone,
        the path OpenSim's rules give once the shank tangent point is inside the condyle
        cylinder (the neighbouring frames). Without a converged candidate the shorter of the
        two cycle states stays.
        """
        mm = self._multi_muscles
        hits, arc_of = wr
        n = hits.shape[1]
        frames = np.flatnonzero(cycled.any(axis=0))
        here = cycled[:, frames]
        base = self._take_state(st, wr, frames)
        # the other muscles of these frames: iterated on to their own fixed points (the wraps
        # of the cycling ones off meanwhile)
        frozen = np.full(hits.shape, -1, dtype=np.intp)
        frozen[self._multi_wraps[:, None], frames] = np.where(here[self._multi_wrap_of], -2, -1)
        self._iterate_wraps(st, rot, trans, wr, frames, frozen)
        free = self._take_state(st, wr, frames)
        strict = self._take_state(st, wr, frames)  # shortest admissible candidate
        strict_len = np.full((mm.size, frames.size), np.inf)
        loose = self._take_state(st, wr, frames)  # longest converged candidate
        loose_len = np.full((mm.size, frames.size), -np.inf)
        for rd in self._multi_rounds:
            self._put_state(st, wr, frames, base)
            off = np.zeros((rd.k.size, n), dtype=bool)
            off[:, frames] = hits[rd.k][:, frames]
            self._remove_round(rd, st, off, arc_of[rd.k])
            idx = (rd.k[:, None], frames[None, :])
            hits[idx], arc_of[idx] = False, 0.0
            frozen = np.full(hits.shape, -1, dtype=np.intp)
            frozen[idx] = -2
            conv, cyc = self._iterate_wraps(st, rot, trans, wr, frames, frozen)
            state = self._take_state(st, wr, frames)
            length = self._state_lengths(state)
            ok = conv[:, frames] & ~cyc[:, frames]
            would = np.zeros_like(ok)
            would[np.searchsorted(mm, rd.muscle)] = self._apply_round(
                rd, st, rot, trans, frames, dry=True
            )[0]
            better = ok & ~would & (length < strict_len)
            strict_len = np.where(better, length, strict_len)
            self._put_state_into(strict, state, better)
            longer = ok & (length > loose_len)
            loose_len = np.where(longer, length, loose_len)
            self._put_state_into(loose, state, longer)
        self._put_state(st, wr, frames, free)
        self._put_state(st, wr, frames, base, here)
        self._put_state(st, wr, frames, loose, here & np.isfinite(loose_len))
        self._put_state(st, wr, frames, strict, here & np.isfinite(strict_len))

    def _take_state(
        self, st: _PathState, wr: tuple[Array, Array], fr: NDArray[np.intp]
    ) -> tuple[NDArray[Any], ...]:
        """Copy of the multi-wrap paths' state at frames ``fr``: watched slot ends, point ids
        and validity (W, F, ...), arcs (M', F) and the wraps' hits and arcs (K', F)."""
        wx = (self._multi_watch[:, None], fr[None, :])
        kx = (self._multi_wraps[:, None], fr[None, :])
        return (
            st.sa[wx], st.sb[wx], st.ia[wx], st.ib[wx], st.valid[wx],
            st.arcs[self._multi_muscles[:, None], fr], wr[0][kx], wr[1][kx],
        )  # fmt: skip

    def _put_state(
        self,
        st: _PathState,
        wr: tuple[Array, Array],
        fr: NDArray[np.intp],
        state: tuple[Array, ...],
        which: NDArray[np.bool_] | None = None,
    ) -> None:
        """Write back a :meth:`_take_state` copy, for the (muscle, frame) pairs ``which``
        (M', F) only when given."""
        cur = self._take_state(st, wr, fr)
        if which is not None:
            state = self._merge_state(cur, state, which)
        wx = (self._multi_watch[:, None], fr[None, :])
        kx = (self._multi_wraps[:, None], fr[None, :])
        st.sa[wx], st.sb[wx], st.ia[wx], st.ib[wx], st.valid[wx] = state[:5]
        st.arcs[self._multi_muscles[:, None], fr] = state[5]
        wr[0][kx], wr[1][kx] = state[6:]

    def _merge_state(
        self, cur: tuple[Array, ...], new: tuple[Array, ...], which: NDArray[np.bool_]
    ) -> tuple[Array, ...]:
        """``new`` where ``which`` (M', F), else ``cur``."""
        bw, bk = which[self._multi_watch_of], which[self._multi_wrap_of]
        masks = (bw[..., None], bw[..., None], bw, bw, bw, which, bk, bk)
        return tuple(np.where(m, x, y) for m, x, y in zip(masks, new, cur))

    def _put_state_into(
        self, dst: tuple[Array, ...], src: tuple[Array, ...], which: NDArray[np.bool_]
    ) -> None:
        merged = self._merge_state(dst, src, which)
        for d, m in zip(dst, merged):
            d[...] = m

    def _state_lengths(self, state: tuple[Array, ...]) -> Array:
        """Path lengths (M', F) of the multi-wrap muscles in a :meth:`_take_state` copy."""
        sa, sb, valid, arcs = state[0], state[1], state[4], state[5]
        seg = np.where(valid, np.linalg.norm(sb - sa, axis=-1), 0.0)
        out = arcs.copy()
        np.add.at(out, self._multi_watch_of, seg)
        return out

    def _per_muscle(self, moved: Array) -> Array:
        """Largest movement (M', F) of each multi-wrap muscle's watched ends, from (2W, F)."""
        w = self._multi_watch.size
        m = np.maximum(moved[:w], moved[w:])
        return np.maximum.reduceat(m, self._multi_watch_start, axis=0)

    def _paths(self, th: Array, jac: Array, rot: Array, trans: Array) -> tuple[Array, Array, Array]:
        """Lengths (N, M), ∂l/∂q_pin (N, M, nv) and the moving-point part of ∂l/∂θ (N, M, nc)
        for any joint Jacobians ``jac`` (N, 6, nv) (used by :mod:`msk.contact.knee`; ``evaluate``
        aggregates in θ directly)."""
        n = th.shape[0]
        m = self.n_muscles
        lengths, wp, dloc = self._wrenches(th, rot, trans)
        pb = self.point_body
        p_ext = self._n_ext
        # per (muscle, body) pair, then masked by the joints supporting that body
        n_pairs = self._pair_mask.shape[0]
        w_pairs = (self._agg @ wp.reshape(p_ext + 1, n * 6)).reshape(n_pairs, n, 6)
        nv = jac.shape[-1]
        contrib = np.empty((n_pairs, n, nv))
        np.matmul(w_pairs.transpose(1, 0, 2), jac, out=contrib.transpose(1, 0, 2))
        contrib *= self._pair_mask[:, None, :]
        # pairs are sorted by muscle (and every muscle has one): contiguous block sums
        dl_dq = np.add.reduceat(contrib, self._pair_start, axis=0).transpose(1, 0, 2)
        # moving points: f_pᵀ R_b ∂p_b/∂θ, f_p the net unit pull on p
        dl_dth = np.zeros((n, m, len(self.coordinate_names)))
        if self.moving:
            mv_p, mv_ax, mv_c = self._mv_point, self._mv_axis, self._mv_coord
            # (E, n, 3) — advanced indices separated by a slice go first
            col = rot[:, pb[mv_p], :, mv_ax]  # body-frame axis k of each moving entry, in world
            term = np.einsum("eni,eni->ne", wp[mv_p, :, :3], col) * dloc
            # numpy's stub for ufunc.at takes no slice in the index tuple (numpy accepts it)
            np.add.at(dl_dth, (slice(None), self.point_muscle[mv_p], mv_c), term)  # type: ignore[arg-type]
        return lengths, dl_dq, dl_dth

    def _wrenches(self, th: Array, rot: Array, trans: Array) -> tuple[Array, Array, Array]:
        """Lengths (N, M), the net unit wrench (f_p, x_p × f_p) at every extended path point
        (P_ext + 1, N, 6) (last row: a dummy) and the moving-point derivatives ∂p_b/∂θ (N, E).
        Internally point- and slot-major ((P, N, 3), (S, N, 3)) so that gathers by point or
        slot are contiguous."""
        n = th.shape[0]
        n_pts = self.n_points
        m = self.n_muscles
        xw, dloc, active = self._points(th, rot, trans)
        frames = np.arange(n)
        os_, sp = self.orig_slots, self.orig_start_point
        if active is not None:
            idx = np.where(active, np.arange(n_pts)[:, None], n_pts)
            nxt_all = np.minimum.accumulate(idx[::-1], axis=0)[::-1]
            end = np.minimum(nxt_all[sp + 1], n_pts - 1)  # sp is never a last point
            sb_orig = xw[end, frames]
            valid_orig = active[sp]
        else:
            end = np.broadcast_to((sp + 1)[:, None], (sp.size, n))
            sb_orig = xw[sp + 1]
            valid_orig = np.ones((sp.size, n), dtype=bool)
        # slot table
        n_slots = self.slot_start.size
        if n_slots == sp.size:  # no wraps: the original segments only
            st = _PathState(
                xw[sp], sb_orig, np.broadcast_to(sp[:, None], (sp.size, n)), end, valid_orig,
                np.zeros((m, n)),
            )  # fmt: skip
        else:
            sa = np.zeros((n_slots, n, 3))
            sb = np.zeros((n_slots, n, 3))
            ia = np.full((n_slots, n), -1, dtype=np.intp)
            ib = np.full((n_slots, n), -1, dtype=np.intp)
            valid = np.zeros((n_slots, n), dtype=bool)
            sa[os_] = xw[sp]
            sb[os_] = sb_orig
            ia[os_] = sp[:, None]
            ib[os_] = end
            valid[os_] = valid_orig
            st = _PathState(sa, sb, ia, ib, valid, np.zeros((m, n)))
        # the wraps of all paths, one round (at most one wrap per path) at a time, as OpenSim
        # applies the wraps of a path in order on the current path
        hits = np.zeros((len(self.wraps), n), dtype=bool)
        arc_of = np.zeros((len(self.wraps), n))
        every = np.arange(n)
        for rd in self._wrap_rounds:
            hits[rd.k], arc_of[rd.k] = self._apply_round(rd, st, rot, trans, every)
        # several wraps on one path: re-wrap each on the current path until the tangent points
        # stop moving (OpenSim iterates up to 8 times to 0.5 mm; we go to convergence so that
        # the envelope theorem, hence the analytic Jacobian, holds)
        if self._multi_rounds:
            wr = (hits, arc_of)
            _, cycled = self._iterate_wraps(st, rot, trans, wr, every)
            if cycled.any():
                self._resolve_cycles(st, rot, trans, wr, cycled)
        sa, sb, ia, ib, valid, arcs = st.sa, st.sb, st.ia, st.ib, st.valid, st.arcs
        # straight segments (slot-major)
        d = sb - sa
        seg = np.sqrt(np.einsum("sni,sni->sn", d, d))
        ok = valid & (seg > 0.0)
        u = d / np.where(ok, seg, np.inf)[..., None]  # 0 where invalid
        seg = np.where(ok, seg, 0.0)
        lengths = (np.add.reduceat(seg, self.muscle_slot_start, axis=0) + arcs).T
        # unit wrenches (u, x × u) at both segment ends, summed per path point (each point
        # starts and ends at most one segment per frame, so the scatter is injective); the
        # callers aggregate them per (muscle, body) or per Jacobian row
        p_ext = self._n_ext
        ibx = np.where(ib >= 0, ib, self.n_points + (-ib - 2))
        ibx = np.where(ok, ibx, p_ext)  # invalid ends go to the dummy row (their u is 0)
        wp = np.zeros((p_ext + 1, n, 6))
        wa = np.empty((u.shape[0], n, 6))
        wa[..., :3] = u
        _cross_into(sa, u, wa[..., 3:])
        wp[self._ia_static] = -wa  # each point starts at most one segment
        _cross_into(sb, u, wa[..., 3:])
        wp[ibx, frames] += wa  # ... and ends at most one
        return lengths, wp, dloc

    def _static_rows(self, th: Array, rot: Array, trans: Array) -> tuple[Array, Array, Array]:
        """Without wraps: lengths (N, M), the aggregated wrenches of the rows and moving points
        (R + P_mv, N, 6) (see :meth:`_build_static_segments`) and ∂p_b/∂θ (N, E)."""
        n = th.shape[0]
        xw, dloc, active = self._points(th, rot, trans)
        sp = self.orig_start_point
        sa = xw[sp]
        sb = xw[sp + 1]
        ent_on = None
        if active is not None and self._dyn_seg.size:
            # end of a segment followed by conditional points: its first active candidate
            # (the last candidate is unconditional)
            lvl = np.argmax(active[self._dyn_cand], axis=1)  # (D, N)
            end = np.take_along_axis(self._dyn_cand[:, :, None], lvl[:, None, :], 1)[:, 0]
            sb[self._dyn_seg] = xw[end, np.arange(n)]
            ent_on = lvl[self._ent_seg] == self._ent_lvl[:, None]  # (entries, N)
        d = sb - sa
        seg = np.sqrt(np.einsum("sni,sni->sn", d, d))
        ok = seg > 0.0
        if active is not None:
            ok &= active[sp]  # a segment starting at an inactive point is not on the path
        u = d / np.where(ok, seg, np.inf)[..., None]  # 0 where invalid
        seg = np.where(ok, seg, 0.0)
        lengths = np.add.reduceat(seg, self.muscle_slot_start, axis=0).T
        need = self._seg_need
        lines = np.empty((need.size, n, 6))
        un = u[need]
        lines[..., :3] = un
        _cross_into(sa[need], un, lines[..., 3:])
        rows = _spmm(self._seg_sigma, lines.reshape(need.size, n * 6))
        if ent_on is not None:
            ent = lines[self._dyn_need[self._ent_seg]] * ent_on[..., None]
            rows += _spmm(self._ent_agg, ent.reshape(-1, n * 6))
        return lengths, rows.reshape(-1, n, 6), dloc

    def _points(
        self, th: Array, rot: Array, trans: Array
    ) -> tuple[Array, Array, NDArray[np.bool_] | None]:
        """World positions of the path points (P, N, 3), the moving-point derivatives ∂p_b/∂θ
        (N, E) and which points are active (P, N) (``None`` without conditional points)."""
        n = th.shape[0]
        n_pts = self.n_points
        # point locations in world: static points through one sparse product with the body
        # rotations (no per-point gather), moving points recomputed from their functions
        pb = self.point_body
        nb = len(self.body_names)
        rt = rot.transpose(1, 3, 2, 0).reshape(nb * 3, 3 * n)  # [(b, j), (i, n)]
        trans_b = trans.transpose(1, 0, 2)  # (B, N, 3)
        xw = _spmm(self._loc_matrix, rt).reshape(n_pts, 3, n).transpose(0, 2, 1) + trans_b[pb]
        dloc = np.zeros((n, 0))
        if self.moving:
            mp = self.moving_points
            loc = np.broadcast_to(self.point_location[mp], (n, mp.size, 3)).copy()
            val, dloc = self._moving_bank.evaluate(th)
            loc[:, self._mv_slot, self._mv_axis] = val
            xm = np.matmul(rot[:, pb[mp]], loc[..., None])[..., 0] + trans[:, pb[mp]]
            xw[mp] = xm.transpose(1, 0, 2)
        # active points (point-major)
        active: NDArray[np.bool_] | None = None
        if self.cond_points.size:
            active = np.ones((n_pts, n), dtype=bool)
            v = th[:, self.cond_coord].T
            active[self.cond_points] = (v >= self.cond_lo[:, None]) & (v <= self.cond_hi[:, None])
        return xw, dloc, active


class FrameGeometry:
    """:meth:`GeometryPlan.evaluate` of one frame at a time (a stream: :mod:`msk.live`) for a
    plan without wrapping surfaces: the same maths — x_p = R_b loc_p + t_b, segment lines
    L_s = (u_s, x_A × u_s) aggregated into Jacobian rows, ∂l/∂θ = Σ rows · (J_joint G) and the
    moving points' ∂p/∂θ terms, l̇ = (∂l/∂θ) θ̇, the distal unit wrenches from the same rows —
    on arrays without the frame axis, into buffers of this object, the coordinate functions of
    the embedding and of the moving points in one bank.

    Equal to :meth:`GeometryPlan.evaluate` (``compact=True``) to round-off (1e-12 relative:
    a few products summed in another order; tested). :meth:`evaluate` returns the buffers
    :attr:`lengths` (M,), :attr:`velocities` (M,), :attr:`jacobian` (U,) (the entries at
    :meth:`GeometryPlan.jacobian_positions`) and :attr:`distal_wrenches` (per joint, (M, 6)),
    overwritten by the next call.

    Raises:
        ModelError: the plan has wrapping surfaces (use :meth:`GeometryPlan.evaluate`).
    """

    def __init__(self, plan: GeometryPlan, distal_wrench_joints: Sequence[str] = ()) -> None:
        if not plan._static:
            raise ModelError(
                f"geometry plan of {plan.model_name!r}: wrapping surfaces need "
                "GeometryPlan.evaluate (FrameGeometry evaluates wrap-free paths)"
            )
        self.plan = plan
        m = plan.n_muscles
        cb = plan._coupling_bank
        self._n_embed = cb.size
        mb = plan._moving_bank
        self._bank = _FunctionBank(
            np.concatenate([cb.coords, mb.coords]), [*cb.functions, *mb.functions]
        )
        self._q = plan._q_const.copy()
        self._dg = np.zeros(plan._q_const.size)
        self._data = plan._pm.createData()
        self._nb = len(plan.body_names)
        self._body_rot = plan.body_rot
        self._body_trans = plan.body_trans
        self._mp_body = plan.point_body[plan.moving_points]
        self._mp_loc = plan.point_location[plan.moving_points].copy()
        self._trans_pb = plan.point_body
        self._active = np.ones(plan.n_points, dtype=bool)
        self._has_cond = bool(plan.cond_points.size)
        self._dyn_rows = np.arange(plan._dyn_seg.size)
        self._mv_col = plan.point_body[plan._mv_point]
        self._need = plan._seg_need
        self._lines = np.empty((plan._seg_need.size, 6))
        self._n_rows = plan._row_col.size
        self.lengths = np.empty(m)
        self.velocities = np.empty(m)
        self.jacobian = np.empty(plan._target_cols.size)
        joints = tuple(dict.fromkeys(distal_wrench_joints))
        self._distal: list[tuple[Array, NDArray[np.intp], NDArray[np.intp]]] = []
        self.distal_wrenches: dict[str, Array] = {}
        for j in joints:
            self.distal_wrenches[j] = out = np.zeros((m, 6))
            rows = plan._distal_rows(j)
            if rows is not None:
                self._distal.append((out, rows[0], rows[1]))
        # a joint none of whose DOFs moves with a coordinate: the plan's twist evaluation
        self._by_twists = [j for j in joints if plan._distal_rows(j) is None]

    def evaluate(self, theta: Array, theta_dot: Array) -> FrameGeometry:
        """Lengths, l̇, the compact ∂l/∂θ and the distal wrenches at θ, θ̇ (n_coords,)."""
        pl = self.plan
        th = theta[None]
        val, d1 = self._bank.evaluate(th)
        ne = self._n_embed
        q, dg = self._q, self._dg
        q[pl._var_dof] = val[0, :ne]
        dg[pl._var_dof] = d1[0, :ne]
        # body placements and the world joint Jacobians (Pinocchio)
        data = self._data
        jac = np.reshape(pin.computeJointJacobians(pl._pm, data, q), (6, -1))
        omi = data.oMi.tolist()  # one conversion (indexing Pinocchio's vector costs as much)
        hom = np.array([omi[j].homogeneous for j in pl._body_joint_list])
        rjb = hom[:, :3, :3]
        rot = rjb @ self._body_rot
        trans = hom[:, :3, 3] + np.einsum("bij,bj->bi", rjb, self._body_trans)
        # path points in world (P, 3)
        rt = rot.transpose(0, 2, 1).reshape(self._nb * 3, 3)
        xw = _spmm(pl._loc_matrix, rt)
        xw += trans[self._trans_pb]
        if pl.moving:
            loc = self._mp_loc.copy()
            loc[pl._mv_slot, pl._mv_axis] = val[0, ne:]
            xw[pl.moving_points] = (rot[self._mp_body] @ loc[..., None])[..., 0] + trans[
                self._mp_body
            ]
        active = None
        if self._has_cond:
            active = self._active
            v = theta[pl.cond_coord]
            active[pl.cond_points] = (v >= pl.cond_lo) & (v <= pl.cond_hi)
        # segments: start fixed, end at the next active point
        sp = pl.orig_start_point
        sa = xw[sp]
        sb = xw[sp + 1]
        ent_on = None
        if active is not None and pl._dyn_seg.size:
            lvl = np.argmax(active[pl._dyn_cand], axis=1)
            sb[pl._dyn_seg] = xw[pl._dyn_cand[self._dyn_rows, lvl]]
            ent_on = lvl[pl._ent_seg] == pl._ent_lvl
        d = sb - sa
        seg = np.sqrt(np.einsum("si,si->s", d, d))
        ok = seg > 0.0
        if active is not None:
            ok &= active[sp]
        u = d / np.where(ok, seg, np.inf)[:, None]
        seg[~ok] = 0.0
        self.lengths[:] = np.add.reduceat(seg, pl.muscle_slot_start)
        need, lines = self._need, self._lines
        un = u[need]
        lines[:, :3] = un
        _cross_into(sa[need], un, lines[:, 3:])
        rows = _spmm(pl._seg_sigma, lines)
        if ent_on is not None:
            rows += _spmm(pl._ent_agg, lines[pl._dyn_need[pl._ent_seg]] * ent_on[:, None])
        for out, r_idx, mus in self._distal:
            out[mus] = rows[r_idx]
        for j in self._by_twists:
            self.distal_wrenches[j][:] = pl._distal_by_twists(th, pl._joint_dofs(j))[0]
        # ∂l/∂θ: each row against its coordinate's effective column
        if self._n_rows:
            jg = jac[:, pl._col_dofs] * dg[pl._col_dofs]
            jt = np.add.reduceat(jg, pl._col_start, axis=1).T  # (E, 6)
            vals = np.einsum("rc,rc->r", rows[: self._n_rows], jt[pl._row_col])
        else:
            vals = np.zeros(0)
        if pl.moving:
            col = rot[self._mv_col, :, pl._mv_axis]  # (E, 3)
            term = np.einsum("ei,ei->e", rows[pl._mv_row, :3], col) * d1[0, ne:]
            vals = np.concatenate([vals, term])
        jl = _spmm(pl._target_sum, vals[:, None])[:, 0]
        self.jacobian[:] = jl
        self.velocities[:] = _spmm(
            pl._muscle_of_target, (jl * theta_dot[pl._target_coord])[:, None]
        )[:, 0]
        return self


# --------------------------------------------------------------------------------------------
# moving-point functions, evaluated in groups
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _FunctionGroup:
    """Functions of one coordinate evaluated together: SimmSplines sharing their knots (possibly
    scaled by a Multiplier) as one table, anything else one by one."""

    coordinate: int
    entries: NDArray[np.intp]  # index into plan.moving
    slots: NDArray[np.intp]  # moving-point slot
    axes: NDArray[np.intp]
    knots: Array | None = None  # (n,)
    coef: Array | None = None  # (4, K, n): y, b, c, d
    functions: tuple[Any, ...] = ()

    def evaluate(self, x: Array) -> tuple[Array, Array]:
        """Values and first derivatives, (N, K) each."""
        if self.knots is None or self.coef is None:
            val = np.stack([np.asarray(f(x), dtype=float) for f in self.functions], -1)
            d1 = np.stack([np.asarray(f.d1(x), dtype=float) for f in self.functions], -1)
            return val, d1
        kn = self.knots
        y, b, c, d = self.coef
        i = np.clip(np.searchsorted(kn, x, side="right") - 1, 0, kn.size - 2)
        dx = (x - kn[i])[:, None]
        bi, ci, di = b[:, i].T, c[:, i].T, d[:, i].T
        val = y[:, i].T + dx * (bi + dx * (ci + dx * di))
        d1 = bi + dx * (2.0 * ci + 3.0 * dx * di)
        lo, hi = (x < kn[0])[:, None], (x > kn[-1])[:, None]
        if lo.any() or hi.any():  # linear extrapolation with the end slopes, as SimmSpline
            val = np.where(lo, y[:, 0] + (x[:, None] - kn[0]) * b[:, 0], val)
            val = np.where(hi, y[:, -1] + (x[:, None] - kn[-1]) * b[:, -1], val)
            d1 = np.where(lo, b[:, 0], np.where(hi, b[:, -1], d1))
        return val, d1


class _FunctionBank:
    """Functions f_e(θ_{c_e}) evaluated together in entry order: exactly-Linear ones in one
    pass, all SimmSplines (possibly scaled by a Multiplier) in one padded table whatever their
    knots, anything else one by one. Same arithmetic as the functions themselves."""

    def __init__(self, coords: NDArray[np.intp], functions: list[Any]) -> None:
        coords = np.asarray(coords, dtype=np.intp)
        self.coords, self.functions = coords, list(functions)
        self.size = len(functions)
        lin = [e for e, f in enumerate(functions) if _linear_of(f) is not None]
        spl = [e for e, f in enumerate(functions) if e not in set(lin) and _spline_of(f)]
        self.other = [e for e in range(self.size) if e not in set(lin) | set(spl)]
        self.other_coord = [int(coords[e]) for e in self.other]
        self.other_fun = [functions[e] for e in self.other]
        self.lin = np.asarray(lin, dtype=np.intp)
        self.lin_coord = coords[self.lin]
        lins = [t for t in (_linear_of(functions[e]) for e in lin) if t is not None]
        self.scale = np.array([t[0] for t in lins])
        self.slope = np.array([t[1].slope for t in lins], dtype=float)
        self.intercept = np.array([t[1].intercept for t in lins], dtype=float)
        self.d_lin = self.scale * self.slope
        self.spl = np.asarray(spl, dtype=np.intp)
        self.spl_coord = coords[self.spl]
        tabs = [t for t in (_spline_of(functions[e]) for e in spl) if t is not None]
        nk = np.array([len(t[1].x) for t in tabs], dtype=np.intp)
        k_max = int(nk.max()) if nk.size else 2
        self.knots = np.full((len(spl), k_max), np.inf)
        self.coef = np.zeros((4, len(spl), k_max))
        for i, (scale, sp) in enumerate(tabs):
            self.knots[i, : nk[i]] = sp.x
            self.coef[:, i, : nk[i]] = scale * np.stack([np.asarray(sp.y), *sp.coefficients])
        self.nk = nk
        rows = np.arange(len(spl))
        self.k0 = self.knots[:, 0].copy()
        self.k1 = self.knots[rows, nk - 1] if nk.size else np.zeros(0)
        self.y0, self.b0 = self.coef[0, :, 0].copy(), self.coef[1, :, 0].copy()
        self.y1 = self.coef[0, rows, nk - 1] if nk.size else np.zeros(0)
        self.b1 = self.coef[1, rows, nk - 1] if nk.size else np.zeros(0)
        self.rows = rows

    def evaluate(self, theta: Array) -> tuple[Array, Array]:
        """Values and first derivatives (N, E) for θ (N, n_coords)."""
        n = theta.shape[0]
        val = np.empty((n, self.size))
        d1 = np.empty((n, self.size))
        if self.lin.size:
            # scale·(slope·x + intercept): Multiplier(Linear) as it computes, 1·y = y exactly
            val[:, self.lin] = self.scale * (self.slope * theta[:, self.lin_coord] + self.intercept)
            d1[:, self.lin] = self.d_lin
        if self.spl.size:
            x = theta[:, self.spl_coord]
            # index of the last knot ≤ x (searchsorted "right" − 1) on the +inf-padded table
            i = np.minimum(np.maximum((self.knots <= x[..., None]).sum(-1) - 1, 0), self.nk - 2)
            dx = x - self.knots[self.rows, i]
            y, b, c, d = self.coef[:, self.rows, i]
            v = y + dx * (b + dx * (c + dx * d))
            g = b + dx * (2.0 * c + 3.0 * dx * d)
            lo, hi = x < self.k0, x > self.k1
            if lo.any() or hi.any():  # linear extrapolation with the end slopes, as SimmSpline
                v = np.where(lo, self.y0 + (x - self.k0) * self.b0, v)
                v = np.where(hi, self.y1 + (x - self.k1) * self.b1, v)
                g = np.where(lo, self.b0, np.where(hi, self.b1, g))
            val[:, self.spl] = v
            d1[:, self.spl] = g
        for e, c, f in zip(self.other, self.other_coord, self.other_fun):
            x = theta[:, c]
            val[:, e] = np.asarray(f(x), dtype=float)
            d1[:, e] = np.asarray(f.d1(x), dtype=float)
        return val, d1


def _linear_of(fun: Any) -> tuple[float, Linear] | None:
    if type(fun) is Linear:
        return 1.0, fun
    if type(fun) is Multiplier and type(fun.function) is Linear:
        return float(fun.scale), fun.function
    return None


def _spline_of(fun: Any) -> tuple[float, SimmSpline] | None:
    if type(fun) is SimmSpline:
        return 1.0, fun
    if type(fun) is Multiplier and type(fun.function) is SimmSpline:
        return float(fun.scale), fun.function
    return None


def _group_functions(items: list[tuple[int, int, int, int, Any]]) -> list[_FunctionGroup]:
    """Group (entry, slot, axis, coordinate, function) by coordinate and spline knots."""
    groups: dict[tuple, list[tuple[int, int, int, int, Any]]] = {}
    for it in items:
        sp = _spline_of(it[4])
        key = (it[3], tuple(sp[1].x)) if sp is not None else (it[3], None)
        groups.setdefault(key, []).append(it)
    out = []
    for (coord, knots), its in groups.items():
        idx = [np.array([it[k] for it in its], dtype=np.intp) for k in range(3)]
        if knots is None:
            out.append(
                _FunctionGroup(coord, idx[0], idx[1], idx[2], functions=tuple(it[4] for it in its))
            )
            continue
        coef = np.zeros((4, len(its), len(knots)))
        for k, it in enumerate(its):
            sp = _spline_of(it[4])
            assert sp is not None  # grouped under spline knots
            scale, spl = sp
            coef[:, k] = scale * np.stack([np.asarray(spl.y), *spl.coefficients])
        out.append(
            _FunctionGroup(coord, idx[0], idx[1], idx[2], knots=np.asarray(knots), coef=coef)
        )
    return out


# --------------------------------------------------------------------------------------------
# batched forward kinematics (all frames at once)
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Tree:
    parents: tuple[int, ...]
    rotations: Array  # joint placements in the parent joint frame
    translations: Array
    revolute: tuple[bool, ...]
    axes: Array  # unit axis of each joint (its own frame)
    idx_q: tuple[int, ...]
    idx_v: tuple[int, ...]
    frame_axis: tuple[int, ...]  # 0, 1, 2 for an axis of the joint frame, -1 otherwise
    identity_rotation: tuple[bool, ...]
    zero_translation: tuple[bool, ...]
    skew: Array  # [a_j]×


def _spmm(a: Any, x: Array) -> Array:
    """``a @ x`` of a CSR matrix and a dense (n, k) float64 block: scipy's own kernel
    (``csr_matvecs``, what ``__matmul__`` ends in: the same sums, bit for bit) called directly,
    without the operator's dispatch (≈ 20 µs a call, most of a one-frame product)."""
    if (
        x.ndim != 2
        or x.dtype != np.float64
        or a.format != "csr"
        or a.dtype != np.float64
        or a.shape[1] != x.shape[0]
    ):
        return np.asarray(a @ x)
    try:  # a private kernel: a scipy that moves or changes it gets the operator
        from scipy.sparse import _sparsetools

        out = np.zeros((a.shape[0], x.shape[1]))
        _sparsetools.csr_matvecs(
            a.shape[0], a.shape[1], x.shape[1], a.indptr, a.indices, a.data,
            np.ascontiguousarray(x).ravel(), out.ravel(),
        )  # fmt: skip
    except (ImportError, AttributeError, TypeError, ValueError):
        return np.asarray(a @ x)
    return out


def _cross_into(x: Array, u: Array, out: Array) -> None:
    """out = x × u over the last axis (faster than ``np.cross`` on small trailing axes)."""
    x0, x1, x2 = x[..., 0], x[..., 1], x[..., 2]
    u0, u1, u2 = u[..., 0], u[..., 1], u[..., 2]
    out[..., 0] = x1 * u2 - x2 * u1
    out[..., 1] = x2 * u0 - x0 * u2
    out[..., 2] = x0 * u1 - x1 * u0


def _tree_structure(pm: pin.Model) -> _Tree:
    n = pm.njoints
    axes = np.zeros((n, 3))
    rev = [False] * n
    for j in range(1, n):
        jm = pm.joints[j]
        name = jm.shortname()
        if jm.nq != 1 or jm.nv != 1:
            raise ModelError(f"joint {pm.names[j]}: muscle geometry needs 1-DOF joints ({name})")
        if name.endswith("Unaligned"):
            axes[j] = np.asarray(jm.extract().axis, dtype=float)
            rev[j] = "Revolute" in name
        elif name[-2] in "RP" and name[-1] in "XYZ":
            axes[j, "XYZ".index(name[-1])] = 1.0
            rev[j] = name[-2] == "R"
        else:
            raise ModelError(f"joint {pm.names[j]}: unsupported Pinocchio joint {name}")
    return _Tree(
        parents=tuple(int(p) for p in pm.parents),
        rotations=np.array([pm.jointPlacements[j].rotation for j in range(n)]),
        translations=np.array([pm.jointPlacements[j].translation for j in range(n)]),
        revolute=tuple(rev),
        axes=axes,
        idx_q=tuple(int(pm.joints[j].idx_q) for j in range(n)),
        idx_v=tuple(int(pm.joints[j].idx_v) for j in range(n)),
        frame_axis=tuple(
            int(np.flatnonzero(axes[j])[0])
            if np.count_nonzero(axes[j]) == 1 and axes[j].max() == 1.0
            else -1
            for j in range(n)
        ),
        identity_rotation=tuple(
            bool(np.array_equal(pm.jointPlacements[j].rotation, np.eye(3))) for j in range(n)
        ),
        zero_translation=tuple(not np.any(pm.jointPlacements[j].translation) for j in range(n)),
        skew=np.array([pin.skew(axes[j]) for j in range(n)]),
    )


def _batched_fk(tree: _Tree, q: Array, nv: int) -> tuple[Array, Array, Array]:
    """oMi of every joint (N, njoints, 3, 3), (N, njoints, 3) and the world-frame joint Jacobian
    (N, 6, nv): column of joint j = (o_j × a_j, a_j) if revolute, (a_j, 0) if prismatic, with
    a_j its world axis and o_j its origin (the joint twist at the world origin).

    Identity placements are skipped and a rotation about a frame axis k only mixes the two
    other columns of the parent rotation (R_j = R_p R_k(q): column i1 → c·r_i1 + s·r_i2,
    column i2 → c·r_i2 − s·r_i1), so no per-joint 3 × 3 products remain but for unaligned axes.
    """
    n = q.shape[0]
    nj = len(tree.parents)
    rot = np.empty((n, nj, 3, 3))
    trans = np.empty((n, nj, 3))
    rot[:, 0] = np.eye(3)
    trans[:, 0] = 0.0
    jac = np.zeros((n, 6, nv))
    for j in range(1, nj):
        par = tree.parents[j]
        rp = rot[:, par]
        tp = trans[:, par]
        if not tree.identity_rotation[j]:
            rp = rp @ tree.rotations[j]
        if not tree.zero_translation[j]:
            tp = tp + rot[:, par] @ tree.translations[j]
        qj = q[:, tree.idx_q[j]]
        iv = tree.idx_v[j]
        k = tree.frame_axis[j]
        a = rp[:, :, k] if k >= 0 else rp @ tree.axes[j]
        if tree.revolute[j]:
            c, s_ = np.cos(qj)[:, None], np.sin(qj)[:, None]
            if k >= 0:
                i1, i2 = (k + 1) % 3, (k + 2) % 3
                out = rot[:, j]
                out[:, :, k] = a
                out[:, :, i1] = c * rp[:, :, i1] + s_ * rp[:, :, i2]
                out[:, :, i2] = c * rp[:, :, i2] - s_ * rp[:, :, i1]
            else:
                kk = tree.skew[j]
                rot[:, j] = rp @ (np.eye(3) + s_[..., None] * kk + (1.0 - c[..., None]) * (kk @ kk))
            trans[:, j] = tp
            _cross_into(tp, a, jac[:, :3, iv])
            jac[:, 3:, iv] = a
        else:
            rot[:, j] = rp
            trans[:, j] = tp + a * qj[:, None]
            jac[:, :3, iv] = a
    return rot, trans, jac


# --------------------------------------------------------------------------------------------
# helpers and the batch API
# --------------------------------------------------------------------------------------------
def _coord(model: Model, name: str, what: str) -> int:
    try:
        return model.coordinate_index(name)
    except ModelError:
        raise ModelError(f"{what}: unknown coordinate {name!r}") from None


def _wrap_objects(model: Model) -> dict[str, WrapObject]:
    raw = getattr(model, "wrap_objects", None)
    if raw is None:
        raw = model.metadata.get("wrap_objects", ())
    items = raw.values() if isinstance(raw, Mapping) else raw
    return {w.name: w for w in items}


def _find_wrap(objects: dict[str, WrapObject], ref: Any, muscle: str) -> WrapObject:
    if isinstance(ref, WrapObject):
        return ref
    if ref not in objects:
        raise ModelError(f"muscle {muscle}: wrap object {ref!r} not found in the model")
    return objects[ref]


def _frames(x: ArrayLike, n_coords: int, what: str) -> Array:
    a = np.asarray(x, dtype=float)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != n_coords:
        raise ShapeMismatchError(
            f"{what} must be (N, {n_coords}) (one column per model coordinate), got {a.shape}"
        )
    if not np.all(np.isfinite(a)):
        bad = int(np.argwhere(~np.isfinite(a))[0, 0])
        raise ShapeMismatchError(f"{what}: non-finite value at frame {bad}")
    return a


_PLANS: weakref.WeakKeyDictionary[Model, GeometryPlan] = weakref.WeakKeyDictionary()


#: frames per block of :func:`finite_frames` / :func:`jacobian_frames` (a few MB per block for
#: gait2392's 92 muscles × 23 coordinates: long trials need no full-size temporary)
FRAME_BLOCK = 2048


def _compact_columns(
    jacobian: FrameSparse, cols: NDArray[np.intp]
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """Of a compact Jacobian's positions: those in coordinate ``cols`` (indices into its
    values), their muscles and their places in ``cols``."""
    mus, coord = np.divmod(jacobian.positions, jacobian.trailing[1])
    place = np.full(jacobian.trailing[1], -1, dtype=np.intp)
    place[cols] = np.arange(cols.size)
    keep = np.flatnonzero(place[coord] >= 0)
    return keep, mus[keep], place[coord[keep]]


def finite_frames(
    jacobian: Array | FrameSparse, columns: Sequence[int] | NDArray[np.intp]
) -> NDArray[np.bool_]:
    """(N,) frames whose Jacobian ``(N, M, n)`` is finite in the coordinate ``columns``,
    block by block (no (N, M, len(columns)) temporary; a compact one's stored entries in
    those columns only: the others are 0)."""
    cols = np.asarray(columns, dtype=np.intp)
    n = jacobian.shape[0]
    out = np.empty(n, dtype=bool)
    keep = _compact_columns(jacobian, cols)[0] if isinstance(jacobian, FrameSparse) else None
    for c0 in range(0, n, FRAME_BLOCK):
        sl = slice(c0, c0 + FRAME_BLOCK)
        if isinstance(jacobian, FrameSparse) and keep is not None:
            out[sl] = np.isfinite(np.asarray(jacobian.values[sl])[:, keep]).all(axis=1)
        else:
            out[sl] = np.isfinite(jacobian[sl][:, :, cols]).all(axis=(1, 2))
    return out


def _frame_indices(
    frames: NDArray[np.bool_] | NDArray[np.intp] | None, n_frames: int
) -> NDArray[np.intp]:
    """Frame indices of ``frames``: a mask, indices, or None (all ``n_frames``)."""
    if frames is None:
        return np.arange(n_frames)
    return np.flatnonzero(frames) if np.asarray(frames).dtype == bool else np.asarray(frames)


def jacobian_frames(
    jacobian: Array | FrameSparse,
    frames: NDArray[np.bool_] | NDArray[np.intp],
    columns: Sequence[int] | NDArray[np.intp] | None = None,
) -> Array:
    """``jacobian[frames][:, :, columns]`` (the same values) gathered block by block, without
    the intermediate full-width copy of ``jacobian[frames]`` (of a compact Jacobian, its
    stored entries in ``columns`` put in place: no dense block of every coordinate). The
    result has numpy's memory layout of that expression (coordinate-major: the arithmetic
    downstream, whose summation order follows the strides, gives the same bits)."""
    idx = _frame_indices(frames, jacobian.shape[0])
    cols = np.arange(jacobian.shape[2]) if columns is None else np.asarray(columns, np.intp)
    out = np.empty((cols.size, idx.size, jacobian.shape[1])).transpose(1, 2, 0)
    if isinstance(jacobian, FrameSparse):
        keep, mus, place = _compact_columns(jacobian, cols)
        for c0 in range(0, idx.size, FRAME_BLOCK):
            sl = slice(c0, c0 + FRAME_BLOCK)
            out[sl] = 0.0
            out[sl, mus, place] = np.asarray(jacobian.values[idx[sl]])[:, keep]
        return out
    for c0 in range(0, idx.size, FRAME_BLOCK):
        out[c0 : c0 + FRAME_BLOCK] = jacobian[idx[c0 : c0 + FRAME_BLOCK]][:, :, cols]
    return out


def moment_arm_pattern(
    jacobian: Array | FrameSparse,
    frames: NDArray[np.bool_] | NDArray[np.intp] | None = None,
    columns: Sequence[int] | NDArray[np.intp] | None = None,
) -> NDArray[np.bool_]:
    """(M, len(columns)) whether muscle m has a moment arm about coordinate ``columns[c]`` (all
    coordinates: None) in some of ``frames`` (indices or a mask; all: None) of ``jacobian``
    ``(N, M, n)``: the entry ∂l_m/∂θ_c is nonzero and finite there (r = −J_l, module
    docstring: the moment arm is zero exactly where the Jacobian entry is). Block by block,
    without a dense copy; of a compact Jacobian its stored entries only (the others are 0)."""
    n_frames, n_mus, n = jacobian.shape
    idx = _frame_indices(frames, n_frames)
    cols = np.arange(n) if columns is None else np.asarray(columns, np.intp)
    out = np.zeros((n_mus, cols.size), dtype=bool)
    if isinstance(jacobian, FrameSparse):
        keep, mus, place = _compact_columns(jacobian, cols)
        hit = np.zeros(keep.size, dtype=bool)
        for c0 in range(0, idx.size, FRAME_BLOCK):
            v = np.asarray(jacobian.values[idx[c0 : c0 + FRAME_BLOCK]])[:, keep]
            hit |= ((v != 0) & np.isfinite(v)).any(axis=0)
        out[mus[hit], place[hit]] = True
        return out
    for c0 in range(0, idx.size, FRAME_BLOCK):
        blk = np.asarray(jacobian[idx[c0 : c0 + FRAME_BLOCK]])[:, :, cols]
        out |= ((blk != 0) & np.isfinite(blk)).any(axis=0)
    return out


def geometry_plan(model: Model) -> GeometryPlan:
    """The (cached) :class:`GeometryPlan` of ``model`` (models are immutable)."""
    plan = _PLANS.get(model)
    if plan is None:
        plan = GeometryPlan(model)
        _PLANS[model] = plan
    return plan


def muscle_geometry(
    model: Model,
    q: ArrayLike,
    qdot: ArrayLike | None = None,
    *,
    plan: GeometryPlan | None = None,
    distal_wrench_joints: Sequence[str] = (),
    compact: bool = False,
) -> MuscleGeometry:
    """Lengths l(θ), Jacobians ∂l/∂θ and lengthening velocities of every muscle of ``model``
    over a trial: ``q`` (N, n_coords) independent coordinates θ, ``qdot`` θ̇ (optional).
    ``distal_wrench_joints`` (e.g. ``("knee_r",)``): also the unit wrenches ∂l/∂ξ of the muscles
    on the side distal to these joints, from the same pass
    (:attr:`MuscleGeometry.distal_wrenches`, used by :func:`msk.contact.knee.knee_contact_force`).
    ``compact``: the Jacobian as a :class:`msk.timeseries.FrameSparse`, never dense
    (:meth:`GeometryPlan.evaluate`).

    See the module docstring for the maths (Hayashibe et al. 2011, Eq. 6–7; the rehabilitation-robot
    lower-limb model paper, §2.1).
    """
    plan = plan if plan is not None else geometry_plan(model)
    if plan.model is not model:
        raise ModelError(f"geometry plan was built for model {plan.model_name!r}, not this one")
    return plan.evaluate(q, qdot, distal_wrench_joints=distal_wrench_joints, compact=compact)
