"""Muscle–tendon path geometry: lengths, Jacobians ∂l/∂θ, moment arms, lengthening velocities.

A muscle path is a chain of points fixed in model bodies (origin, via points, insertion),
**conditional** via points (active while one coordinate lies in a range), **moving** points
(location in the body a function of coordinates, as gait2392's quadriceps insertions) and
**wrapping cylinders** (seed 004 §2.1 "via cylinders"; OpenSim ``WrapCylinder`` with quadrant).

Length (seed 002 Eq. 6–7)::

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
torques τ = −J_lᵀ f = rᵀ f (seed 002 Eq. 7); the lengthening velocity is l̇ = J_l θ̇.

Translational Jacobians are never formed: with the world-frame joint Jacobian J (6×nv, columns
are joint twists at the world origin, Pinocchio's ``computeJointJacobians``), a point x on body b
has J_x = (J_lin − [x]× J_ang) S_b (S_b keeps the joints that support b), so
uᵀ J_x = (u, x × u)ᵀ J S_b: each segment end contributes a unit wrench (u, x × u); the wrenches
are summed per (muscle, body) and multiplied by J once. This is the Pinocchio frame Jacobian in
LOCAL_WORLD_ALIGNED shifted to the point, without a Python loop over points. Joint placements
and J are computed for all frames at once from the Pinocchio tree (1-DOF joints: each column is
(o_j × a_j, a_j) for a revolute, (a_j, 0) for a prismatic joint); tests check them against
Pinocchio frame by frame.

Wrapping (cylinder, seed 004 §2.1): in the cylinder frame (axis z, radius R) the shortest path
from P to S over the cylinder is a straight line in the developed surface: tangent points T1, T2
on the circle (plane xy), heights interpolated linearly along the developed length, arc
length sqrt((R Δφ)² + Δz²). By the envelope theorem (the geodesic length is stationary w.r.t. the
tangent points) the derivative of P–T1–arc–T2–S is that of two straight segments P→T1 and
T2→S whose inner ends T1, T2 are fixed in the cylinder's body; the arc adds nothing. The wrap
decision follows OpenSim 4.6 (``WrapCylinder::wrapLine``, ``GeometryPath::applyWrapObjects``):
unconstrained cylinders wrap when the segment crosses the cylinder; a quadrant (``+x``, ``-y``…)
forces the path around the active side; no wrap when both tangent points lie beyond ±length/2;
among the segments of the wrap range, a crossing segment wins, else the smallest length increase.
Several wraps on one path are re-applied in turn on the current path (as OpenSim) until the
tangent points stop moving (1e-12 m; OpenSim stops after 8 passes or 0.5 mm), so that the
envelope theorem holds. Ellipsoids, spheres and tori raise :class:`ModelError` (naming the
muscle and the wrap object); OpenSim's own single-cylinder path is an approximation of the
geodesic (tangent-point heights by plane intersection), up to ~1 mm longer in deep flexion.

Per-model static structure (point → body, support masks, moving/conditional points, wrap
candidates) is precomputed once in a :class:`GeometryPlan` (Pinocchio ``Data`` style); a trial
is processed in one call, frames and muscles vectorised with numpy.
"""

from __future__ import annotations

import weakref
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray
from scipy import sparse

from msk.exceptions import ModelError, ShapeMismatchError
from msk.joints import Multiplier, SimmSpline
from msk.model import Model
from msk.muscles.hill import MuscleParameters
from msk.muscles.path import ConditionalPathPoint, MovingPathPoint, Muscle, PathPoint, WrapObject

Array = NDArray[np.float64]

__all__ = [
    "GeometryPlan",
    "MuscleGeometry",
    "geometry_plan",
    "muscle_geometry",
    "muscle_parameters",
    "wrap_cylinder",
]


# --------------------------------------------------------------------------------------------
# results
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class MuscleGeometry:
    """Muscle–tendon geometry over a trial (time on axis 0, SI).

    Attributes:
        muscle_names: muscles in model order (``model.muscles``).
        coordinate_names: the model's independent coordinates θ.
        lengths: l (N, n_muscles), m.
        jacobian: J_l = ∂l/∂θ (N, n_muscles, n_coords), m/rad (m/m for translations).
        velocities: l̇ = J_l θ̇ (N, n_muscles), m/s, or ``None`` when no θ̇ was given.
    """

    muscle_names: tuple[str, ...]
    coordinate_names: tuple[str, ...]
    lengths: Array
    jacobian: Array
    velocities: Array | None = None

    @property
    def moment_arms(self) -> Array:
        """r = −∂l/∂θ (N, n_muscles, n_coords), OpenSim's ``computeMomentArm`` sign."""
        return -self.jacobian

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


def _not_active(angle: Array, axis: int, sign: int) -> Array:
    out = (angle >= 0.5 * np.pi) & (angle <= 1.5 * np.pi) if axis == 0 else angle > np.pi
    return ~out if sign < 0 else out


def wrap_cylinder(
    a: ArrayLike,
    b: ArrayLike,
    radius: float,
    *,
    quadrant: str = "all",
    length: float = np.inf,
) -> tuple[Array, Array, Array, Array, Array]:
    """Shortest path from a to b over a cylinder (axis z through the origin, frame of the
    cylinder), shapes (..., 3). As OpenSim, the surface is infinite except that there is no wrap
    when both tangent points lie beyond ±``length``/2.

    Returns ``(wraps, t1, t2, arc, mandatory)``: a boolean mask, the tangent points (..., 3),
    the geodesic arc length between them (0 where it does not wrap) and whether the straight
    segment crossed the cylinder (OpenSim's *mandatory* wrap). Where it does not wrap, t1 = t2 = b.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    r = float(radius)
    q = quadrant.strip().lower()
    if q not in _QUADRANTS:
        raise ModelError(f"cylinder quadrant {quadrant!r} is not one of {sorted(_QUADRANTS)}")
    axis, sign = _QUADRANTS[q]
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    ra2 = ax * ax + ay * ay
    rb2 = bx * bx + by * by
    inside = (ra2 < r * r) | (rb2 < r * r)
    # closest approach of the projected segment to the axis (t in (0, 1) on the segment)
    dx, dy = bx - ax, by - ay
    dd = np.maximum(dx * dx + dy * dy, 1e-300)
    t = -(ax * dx + ay * dy) / dd
    cx, cy = ax + t * dx, ay + t * dy
    crosses = (cx * cx + cy * cy < r * r) & (t > 0.0) & (t < 1.0)
    if sign == 0:
        wraps = crosses.copy()
    else:
        pa, pb = a[..., axis], b[..., axis]
        near = cx if axis == 0 else cy
        on_a = _dsign(pa) == sign
        on_b = _dsign(pb) == sign
        # a point on the active side: wrap if crossing, or if the two points straddle the
        # quadrant plane and the line passes on the inactive side; no point on the active
        # side: the path is forced around the active side
        straddle = (_dsign(pa) != _dsign(pb)) & (_dsign(near) != sign)
        wraps = np.where(on_a | on_b, crosses | straddle, True)
    wraps = wraps & ~inside
    # tangent angles (OpenSim Creator's ScrewWrap formulation of the same geodesic)
    ra = np.sqrt(np.maximum(ra2, r * r))
    rb = np.sqrt(np.maximum(rb2, r * r))
    la = np.sqrt(np.maximum(ra2 - r * r, 0.0))
    lb = np.sqrt(np.maximum(rb2 - r * r, 0.0))
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
    if sign == 0:
        pos_ok = np.ones_like(wraps)
        neg_ok = np.ones_like(wraps)
    else:
        n1, n2 = _not_active(a_pos, axis, sign), _not_active(b_neg, axis, sign)
        pos_ok = ~((n1 & n2) | (~n1 & ~n2 & (d_pos > np.pi)))
        n1, n2 = _not_active(b_pos, axis, sign), _not_active(a_neg, axis, sign)
        neg_ok = ~((n1 & n2) | (~n1 & ~n2 & (d_neg > np.pi)))
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
    half = 0.5 * float(length)
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
_WRAP_TOL = 1e-12


class GeometryPlan:
    """Static structure of a model's muscle paths, computed once (à la Pinocchio ``Data``).

    Holds the gathered body list (Pinocchio joint + placement of each body frame), every path
    point's body and location, conditional ranges, moving-point functions, per-body support masks
    over the Pinocchio DOFs, the segment slots of each muscle and the wrap candidates. Read-only
    after construction.
    """

    def __init__(self, model: Model) -> None:
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
        self._moving_groups = _group_functions(
            [(e, slot_of[mv[0]], mv[1], mv[2], mv[3]) for e, mv in enumerate(moving)]
        )
        # static start point of every slot (T2 of its wrap for the extra slots)
        ia_static = self.slot_start.copy()
        for k, w in enumerate(wraps):
            ia_static[w.extra_slot] = n_pts + 2 * k + 1
        self._ia_static = ia_static
        # the embedding θ → q_pin, grouped
        cp = model.coupling
        self._q_const = np.array(
            [float(f(0.0)) if c < 0 else 0.0 for c, f in zip(cp.coordinate, cp.functions)]
        )
        self._coupling_groups = _group_functions(
            [(k, k, 0, c, f) for k, (c, f) in enumerate(zip(cp.coordinate, cp.functions)) if c >= 0]
        )
        # batched forward kinematics of the Pinocchio tree (1-DOF joints)
        self._fk = _tree_structure(pm)

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
        rj, tj, jac = _batched_fk(self._fk, q, self.nv)
        rjb = rj[:, self.body_joint]
        tjb = tj[:, self.body_joint]
        rot = rjb @ self.body_rot
        trans = tjb + np.einsum("nbij,bj->nbi", rjb, self.body_trans)
        return jac, rot, trans, g

    def _embed(self, theta: Array) -> tuple[Array, Array]:
        """q = g(θ) (N, nq) and G = ∂g/∂θ (N, nq, n_coords), as ``model.coupling`` computes them,
        with the coordinate functions evaluated in groups (splines sharing knots at once)."""
        n = theta.shape[0]
        q = np.broadcast_to(self._q_const, (n, self._q_const.size)).copy()
        g = np.zeros((n, self._q_const.size, len(self.coordinate_names)))
        for grp in self._coupling_groups:
            val, d1 = grp.evaluate(theta[:, grp.coordinate])
            q[:, grp.entries] = val
            g[:, grp.entries, grp.coordinate] = d1
        return q, g

    def evaluate(self, theta: ArrayLike, theta_dot: ArrayLike | None = None) -> MuscleGeometry:
        """Lengths, Jacobians ∂l/∂θ (and l̇ when θ̇ is given) for θ of shape (N, n_coords)."""
        th = _frames(theta, len(self.coordinate_names), "q")
        jac, rot, trans, g = self.kinematics(th)
        lengths, dl_dq, dl_dth = self._paths(th, jac, rot, trans)
        jl = np.matmul(dl_dq, g) + dl_dth
        vel = None
        if theta_dot is not None:
            thd = _frames(theta_dot, len(self.coordinate_names), "qdot")
            if thd.shape != th.shape:
                raise ShapeMismatchError(f"qdot shape {thd.shape} differs from q shape {th.shape}")
            vel = np.einsum("nmi,ni->nm", jl, thd)
        return MuscleGeometry(self.muscle_names, self.coordinate_names, lengths, jl, vel)

    def _apply_wrap(
        self,
        k: int,
        w: _WrapEntry,
        st: _PathState,
        rot: Array,
        trans: Array,
        frames: NDArray[np.intp] | None = None,
    ) -> tuple[Array, Array]:
        """Wrap the best candidate segment over cylinder ``w`` in ``frames`` (default all);
        returns the hit mask and arc length (full length; meaningful in ``frames``)."""
        n = st.sa.shape[1]
        fa = np.arange(n) if frames is None else frames
        rows = np.arange(fa.size)
        rc = rot[fa, w.body] @ w.rotation
        oc = trans[fa, w.body] + rot[fa, w.body] @ w.translation
        cand = self._candidates[k]
        ix = (cand[:, None], fa[None, :])  # (K, F) slot-major
        a = np.einsum("nji,knj->nki", rc, st.sa[ix] - oc)
        b = np.einsum("nji,knj->nki", rc, st.sb[ix] - oc)
        wraps, t1, t2, arc, mand = wrap_cylinder(
            a, b, w.radius, quadrant=w.quadrant, length=w.length
        )
        wraps &= st.valid[ix].T
        mand &= wraps
        change = np.linalg.norm(t1 - a, axis=-1) + arc + np.linalg.norm(b - t2, axis=-1)
        change -= np.linalg.norm(b - a, axis=-1)
        order = np.arange(cand.size, dtype=float)
        score = np.where(mand, -1e9 + order, np.where(wraps, change, np.inf))
        best = np.argmin(score, axis=1)
        hit_f = np.isfinite(score[rows, best])
        hit = np.zeros(n, dtype=bool)
        arc_hit = np.zeros(n)
        if not hit_f.any():
            return hit, arc_hit
        kb = best[hit_f]
        fr = fa[hit_f]
        slot = cand[kb]
        t1w = np.einsum("nij,nj->ni", rc[hit_f], t1[hit_f, kb]) + oc[hit_f]
        t2w = np.einsum("nij,nj->ni", rc[hit_f], t2[hit_f, kb]) + oc[hit_f]
        e = w.extra_slot
        st.sa[e, fr] = t2w
        st.sb[e, fr] = st.sb[slot, fr]
        st.ib[e, fr] = st.ib[slot, fr]
        st.ia[e, fr] = -3 - 2 * k
        st.valid[e, fr] = True
        st.sb[slot, fr] = t1w
        st.ib[slot, fr] = -2 - 2 * k
        hit[fr] = True
        arc_hit[fr] = arc[hit_f, kb]
        st.arcs[w.muscle, fr] += arc_hit[fr]
        return hit, arc_hit

    def _remove_wrap(self, k: int, w: _WrapEntry, st: _PathState, hit: Array, arc: Array) -> None:
        """Undo :meth:`_apply_wrap` of wrap ``k`` (the segment ending at its T1 takes back the end
        of the segment starting at its T2)."""
        if not hit.any():
            return
        fr = np.flatnonzero(hit)
        s0, s1 = self._muscle_slots[w.muscle]
        into = s0 + np.argmax(st.ib[s0:s1, fr] == -2 - 2 * k, axis=0)
        e = w.extra_slot
        st.sb[into, fr] = st.sb[e, fr]
        st.ib[into, fr] = st.ib[e, fr]
        st.valid[e, fr] = False
        st.ia[e, fr] = -1
        st.arcs[w.muscle, fr] -= arc[fr]

    def _paths(self, th: Array, jac: Array, rot: Array, trans: Array) -> tuple[Array, Array, Array]:
        """Lengths (N, M), ∂l/∂q_pin (N, M, nv) and the moving-point part of ∂l/∂θ (N, M, nc).
        Internally point- and slot-major ((P, N, 3), (S, N, 3)) so that gathers by point or
        slot are contiguous."""
        n = th.shape[0]
        n_pts = self.n_points
        m = self.n_muscles
        # point locations in world: static points through one sparse product with the body
        # rotations (no per-point gather), moving points recomputed from their functions
        pb = self.point_body
        nb = len(self.body_names)
        rt = rot.transpose(1, 3, 2, 0).reshape(nb * 3, 3 * n)  # [(b, j), (i, n)]
        trans_b = trans.transpose(1, 0, 2)  # (B, N, 3)
        xw = (self._loc_matrix @ rt).reshape(n_pts, 3, n).transpose(0, 2, 1) + trans_b[pb]
        dloc = np.zeros((n, len(self.moving)))
        if self.moving:
            mp = self.moving_points
            loc = np.broadcast_to(self.point_location[mp], (n, mp.size, 3)).copy()
            for grp in self._moving_groups:
                val, d1 = grp.evaluate(th[:, grp.coordinate])
                loc[:, grp.slots, grp.axes] = val
                dloc[:, grp.entries] = d1
            xm = np.matmul(rot[:, pb[mp]], loc[..., None])[..., 0] + trans[:, pb[mp]]
            xw[mp] = xm.transpose(1, 0, 2)
        # active points and the next active point of each point (point-major)
        frames = np.arange(n)
        os_, sp = self.orig_slots, self.orig_start_point
        if self.cond_points.size:
            active = np.ones((n_pts, n), dtype=bool)
            v = th[:, self.cond_coord].T
            active[self.cond_points] = (v >= self.cond_lo[:, None]) & (v <= self.cond_hi[:, None])
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
        hits: list[Array] = []
        arc_of: list[Array] = []
        for k, w in enumerate(self.wraps):
            h, arc = self._apply_wrap(k, w, st, rot, trans)
            hits.append(h)
            arc_of.append(arc)
        # several wraps on one path: re-wrap each on the current path until the tangent points
        # stop moving (OpenSim iterates up to 8 times to 0.5 mm; we go to convergence so that
        # the envelope theorem, hence the analytic Jacobian, holds)
        multi = [k for k, w in enumerate(self.wraps) if self._n_wraps[w.muscle] > 1]
        if multi:
            watch = np.concatenate(
                [np.arange(*self._muscle_slots[m]) for m in {self.wraps[k].muscle for k in multi}]
            )
            todo = np.arange(n)
            for _ in range(_MAX_WRAP_PASSES):
                wx = (watch[:, None], todo[None, :])
                before = np.concatenate([st.sa[wx], st.sb[wx]], 0)
                for k in multi:
                    w = self.wraps[k]
                    undo = np.zeros(n, dtype=bool)
                    undo[todo] = hits[k][todo]
                    self._remove_wrap(k, w, st, undo, arc_of[k])
                    h, arc = self._apply_wrap(k, w, st, rot, trans, todo)
                    hits[k][todo] = h[todo]
                    arc_of[k][todo] = arc[todo]
                moved = np.abs(np.concatenate([st.sa[wx], st.sb[wx]], 0) - before).max(axis=(0, 2))
                todo = todo[moved >= _WRAP_TOL]  # keep iterating the frames still moving
                if todo.size == 0:
                    break
        sa, sb, ia, ib, valid, arcs = st.sa, st.sb, st.ia, st.ib, st.valid, st.arcs
        # straight segments (slot-major)
        d = sb - sa
        seg = np.sqrt(np.einsum("sni,sni->sn", d, d))
        ok = valid & (seg > 0.0)
        u = d / np.where(ok, seg, np.inf)[..., None]  # 0 where invalid
        seg = np.where(ok, seg, 0.0)
        lengths = (np.add.reduceat(seg, self.muscle_slot_start, axis=0) + arcs).T
        # ∂l/∂q_pin: unit wrenches (u, x × u) at both segment ends, summed per path point (each
        # point starts and ends at most one segment per frame, so the scatter is injective),
        # then per (muscle, body) pair, then masked by the joints supporting that body
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
            np.add.at(dl_dth, (slice(None), self.point_muscle[mv_p], mv_c), term)
        return lengths, dl_dq, dl_dth


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
            out.append(_FunctionGroup(coord, *idx, functions=tuple(it[4] for it in its)))
            continue
        coef = np.zeros((4, len(its), len(knots)))
        for k, it in enumerate(its):
            scale, spl = _spline_of(it[4])  # type: ignore[misc]
            coef[:, k] = scale * np.stack([np.asarray(spl.y), spl._b, spl._c, spl._d])
        out.append(_FunctionGroup(coord, *idx, knots=np.asarray(knots), coef=coef))
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
    )


def _batched_fk(tree: _Tree, q: Array, nv: int) -> tuple[Array, Array, Array]:
    """oMi of every joint (N, njoints, 3, 3), (N, njoints, 3) and the world-frame joint Jacobian
    (N, 6, nv): column of joint j = (o_j × a_j, a_j) if revolute, (a_j, 0) if prismatic, with
    a_j its world axis and o_j its origin (the joint twist at the world origin)."""
    n = q.shape[0]
    nj = len(tree.parents)
    rot = np.empty((n, nj, 3, 3))
    trans = np.empty((n, nj, 3))
    rot[:, 0] = np.eye(3)
    trans[:, 0] = 0.0
    jac = np.zeros((n, 6, nv))
    for j in range(1, nj):
        par = tree.parents[j]
        rp = rot[:, par] @ tree.rotations[j]
        tp = trans[:, par] + rot[:, par] @ tree.translations[j]
        ax = tree.axes[j]
        qj = q[:, tree.idx_q[j]]
        a = rp @ ax
        iv = tree.idx_v[j]
        if tree.revolute[j]:
            k = pin.skew(ax)
            c, s_ = np.cos(qj)[:, None, None], np.sin(qj)[:, None, None]
            rot[:, j] = rp @ (np.eye(3) + s_ * k + (1.0 - c) * (k @ k))
            trans[:, j] = tp
            jac[:, :3, iv] = np.cross(tp, a)
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
) -> MuscleGeometry:
    """Lengths l(θ), Jacobians ∂l/∂θ and lengthening velocities of every muscle of ``model``
    over a trial: ``q`` (N, n_coords) independent coordinates θ, ``qdot`` θ̇ (optional).

    See the module docstring for the maths (seed 002 Eq. 6–7; seed 004 §2.1).
    """
    plan = plan if plan is not None else geometry_plan(model)
    if plan.model is not model:
        raise ModelError(f"geometry plan was built for model {plan.model_name!r}, not this one")
    return plan.evaluate(q, qdot)
