"""Synthetic non-gait lab tasks with a known truth: a two-leg squat and a stair ascent.

A lab session is scored on tasks the shipped files do not hold (Grand Challenge JW's session has
overground gait, single-leg stance, two-leg squat and stair ascent; only the first two are
shared). This module makes the other two from a subject's placed model (e.g. gait2392 scaled to
JW by ``msk run``'s model stage):

* :func:`squat_motion` — feet fixed, 3–5 repetitions down to a chosen knee flexion (the pelvis
  goes down and back and tilts forward; the legs solved by inverse kinematics to the feet's
  standing placements);
* :func:`stair_motion` — step-over-step ascent of a flight of 3–4 steps: each foot goes from its
  foothold to the one two steps up (minimum-jerk swing, Flash & Hogan 1985; the trailing heel
  rising before lift-off), the pelvis rising steadily from step to step, as high as the legs
  reach, and carried forward and sideways so that the motion's zero-moment point — the centre
  of pressure its ground reaction needs — stays on the sole of the supporting foot (mid-foot
  to ball) and goes from the trailing to the leading foot over each double support (the
  cart-table model, Kajita et al. 2003, corrected by the motion's own RNEA root wrench); the
  legs solved to the feet's placements.

Both return a :class:`TaskMotion` whose coordinates θ are a quintic spline through the IK
solutions at the marker rate, so θ̇ and θ̈ are exact at any rate. :func:`task_reactions` gives the
ground reactions the motion needs — the root (base-link) rows of Pinocchio's RNEA (the pelvis
residual of a perfect model is the ground reaction) — distributed to the feet in contact: all to
a single support, and in double support a share α: the total centre of pressure's projection
between the feet (for the stair between the points where its design has each foot press, so
that each foot's centre of pressure stays on its sole; for the squat between the feet's
centres, as :func:`msk.datasets.trials.split_wrench`), both feet's centres of pressure
displaced by one horizontal offset and the free moment shared, so that the feet's wrenches add
up exactly to the total (the same construction as :func:`~msk.datasets.trials.split_wrench`,
with each foot on its own surface height). :func:`true_torques` are RNEA's joint torques with
those foot wrenches.
:func:`write_lab_c3d` writes the trial in a lab's format — the template C3D's marker labels
(the model's markers by forward kinematics + Gaussian noise; labels the model lacks fixed
where the template has them still — lab axes — else gaps), its plates' channel labels and type,
its other analog channels (EMG: white noise modulated by the joint torques a channel's
muscles produce, plus the template's offsets; the rest noise) — with the plates where the task
puts them (a stair's plate corners at its step's height).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray
from scipy.interpolate import make_interp_spline

from msk.datasets.trials import root_wrench
from msk.io.c3d import plate_axes
from msk.model.core import Model, marker_positions
from msk.units import G0, Array

__all__ = [
    "FEET",
    "FootReactions",
    "Foothold",
    "LabPlate",
    "LabTask",
    "TaskMotion",
    "lab_task",
    "squat_motion",
    "stair_motion",
    "task_reactions",
    "true_torques",
    "write_lab_c3d",
]

#: the feet of a gait2392-like model (right, left)
FEET = ("calcn_r", "calcn_l")
_LEGS = {
    "calcn_r": ("hip_flexion_r", "hip_adduction_r", "hip_rotation_r", "knee_angle_r",
                "ankle_angle_r", "subtalar_angle_r"),
    "calcn_l": ("hip_flexion_l", "hip_adduction_l", "hip_rotation_l", "knee_angle_l",
                "ankle_angle_l", "subtalar_angle_l"),
}  # fmt: skip
#: the lowest foot marker's height above the sole when standing (marker radius + skin), m
_SOLE_M = 0.02
#: passes correcting a stair's pelvis path to its zero-moment point design (:func:`stair_motion`)
_ZMP_PASSES = 3
#: stair ascent posture and timing (:func:`stair_motion`): pelvis tilted forward and the trunk
#: flexed at the lumbar joint (deg), the trailing heel's rise at lift-off (deg) and how long
#: before the double support it begins (s), the pelvis below its straight-leg height (m), the
#: feet's start behind the first riser (m)
_TILT_DEG, _LEAN_DEG = 8.0, 15.0
_HEEL_DEG, _HEEL_PRE_S = 45.0, 0.25
_DROP_M, _X_START_M = 0.04, -0.12
#: where a stance foot presses, as a fraction of its sole from the heel to the toe marker: the
#: leading foot at the start of its stance, the trailing foot at its end
_PHI_LEAD, _PHI_TRAIL = 0.4, 0.75


def _mj(s: Array) -> Array:
    """Minimum-jerk profile 10 s³ − 15 s⁴ + 6 s⁵ of s clipped to [0, 1] (Flash & Hogan 1985)."""
    s = np.clip(s, 0.0, 1.0)
    return s**3 * (10.0 - 15.0 * s + 6.0 * s * s)


@dataclass(frozen=True)
class Foothold:
    """A foot standing still from ``t_on`` to ``t_off`` (s) on a surface of height ``height_m``
    at ``x_m`` (forward) / ``z_m`` (right) of its standing placement's origin."""

    foot: str
    t_on: float
    t_off: float
    x_m: float
    z_m: float
    height_m: float
    surface: str = "floor"


@dataclass(frozen=True)
class TaskMotion:
    """A task's motion: ``time`` (N,) at the marker rate, θ (N, n) there, the footholds (the
    contact truth), ``kind`` ("squat" / "stair"), the IK's worst foot position error (m) and the
    spline giving θ, θ̇, θ̈ at any time (:meth:`at`). The floor is y = 0."""

    model: Model
    time: Array
    q: Array
    footholds: tuple[Foothold, ...]
    kind: str
    foot_error_m: float
    spline: Any = field(repr=False, default=None)
    #: (N, F, 3) where each foot presses when on a foothold (world; a stair's design points,
    #: :func:`stair_motion`), ``None``: the foot's centre (:func:`task_reactions`)
    pressure: Array | None = field(repr=False, default=None)

    def at(self, t: Array) -> tuple[Array, Array, Array]:
        """θ, θ̇, θ̈ at times ``t`` (the quintic spline through the IK solutions)."""
        t = np.asarray(t, dtype=float)
        return self.spline(t), self.spline(t, 1), self.spline(t, 2)

    def contact(self, foot: str, t: Array) -> tuple[NDArray[np.bool_], Array]:
        """(K,) whether ``foot`` stands on a foothold at ``t`` and that surface's height."""
        t = np.asarray(t, dtype=float)
        on = np.zeros(t.shape, dtype=bool)
        h = np.full(t.shape, np.nan)
        for fh in self.footholds:
            if fh.foot == foot:
                k = (t >= fh.t_on) & (t <= fh.t_off)
                on |= k
                h[k] = fh.height_m
        return on, h


def _standing(model: Model) -> tuple[Array, float, dict[str, pin.SE3]]:
    """The default pose standing on the floor y = 0: θ, the pelvis height, and each foot's
    placement (its body frame) in the world."""
    th = model.default_coordinates().astype(float).copy()
    names = list(model.coordinate_names)
    iy = names.index("pelvis_ty")
    th[iy] = 0.0
    mk = marker_positions(model, th)[0]
    feet_mk = [i for i, m in enumerate(model.markers) if m.body in model.subtree(FEET[0])
               or m.body in model.subtree(FEET[1])]  # fmt: skip
    low = float(mk[feet_mk, 1].min()) if feet_mk else 0.0
    th[iy] = _SOLE_M - low
    data = model.create_data()
    pin.framesForwardKinematics(model.pin_model, data, model.coupling.q(th))
    place = {f: pin.SE3(data.oMf[model.body_frame[f]]) for f in FEET}
    return th, float(th[iy]), place


def _solve_legs(
    model: Model, th: Array, targets: Mapping[str, pin.SE3], *, iters: int = 40
) -> tuple[Array, float]:
    """θ with each leg's six coordinates moved so that its foot frame reaches its target
    placement (Gauss–Newton on log₆, finite-difference Jacobian); returns θ and the largest
    remaining position error (m)."""
    names = list(model.coordinate_names)
    data = model.create_data()
    th = th.copy()
    err_m = 0.0
    for foot, target in targets.items():
        idx = [names.index(c) for c in _LEGS[foot]]
        fid = model.body_frame[foot]

        def resid(
            x: Array, idx: list[int] = idx, fid: int = fid, target: pin.SE3 = target
        ) -> Array:
            th[idx] = x
            pin.framesForwardKinematics(model.pin_model, data, model.coupling.q(th))
            return np.asarray(pin.log6(target.actInv(data.oMf[fid])).vector)

        x = th[idx].copy()
        for _ in range(iters):
            r = resid(x)
            if np.linalg.norm(r) < 1e-10:
                break
            jac = np.empty((6, len(idx)))
            for j in range(len(idx)):
                d = np.zeros(len(idx))
                d[j] = 1e-7
                jac[:, j] = (resid(x + d) - r) / 1e-7
            # damped least squares, each step at most 0.2 rad
            step = np.linalg.solve(jac.T @ jac + 1e-6 * np.eye(len(idx)), jac.T @ r)
            x = x - step * min(1.0, 0.2 / max(float(np.abs(step).max()), 1e-12))
        r = resid(x)
        th[idx] = x
        err_m = max(err_m, float(np.linalg.norm(r[:3])))
    return th, err_m


def _sole_end(model: Model, foot: str, stand: pin.SE3, *, toe: bool) -> Array:
    """The foot's most anterior (``toe``) or posterior marker (its subtree's) at the sole, in
    the foot frame of the standing placement ``stand``."""
    th, _, _ = _standing(model)
    mk = marker_positions(model, th)[0]
    sub = set(model.subtree(foot))
    idx = [i for i, m in enumerate(model.markers) if m.body in sub]
    pick = np.argmax if toe else np.argmin
    end = mk[idx[int(pick(mk[idx, 0]))]].copy()
    end[1] = 0.0
    return np.asarray(stand.actInv(end), dtype=float)


def com_from_zmp(zmp: Array, dt: float, height_m: float, g: float = G0) -> Array:
    """The centre of mass path x whose zero-moment point is ``zmp`` (one horizontal axis,
    sampled every ``dt`` s) for a centre of mass at ``height_m`` above the support: the
    cart-table model x − (h/g) ẍ = p (Kajita et al. 2003, Eq. 2), solved as a boundary-value
    problem by central differences with x = p at both ends (still at the start and the end)."""
    from scipy.linalg import solve_banded

    p = np.asarray(zmp, dtype=float)
    n = p.size
    c = height_m / (g * dt * dt)
    ab = np.zeros((3, n))
    ab[0, 2:] = -c
    ab[1, :] = 1.0 + 2.0 * c
    ab[2, :-2] = -c
    ab[1, 0] = ab[1, -1] = 1.0
    return np.asarray(solve_banded((1, 1), ab, p), dtype=float)


def _com_x(model: Model, th: Array) -> Array:
    """(N,) the whole-body centre of mass's forward coordinate of each pose."""
    data = model.create_data()
    out = np.empty(th.shape[0])
    for k in range(th.shape[0]):
        out[k] = pin.centerOfMass(model.pin_model, data, model.coupling.q(th[k]))[0]
    return out


def _flexed(model: Model, th: Array) -> Array:
    """θ with the knees bent 30°, hips flexed 15° and ankles dorsiflexed 10°: the start of a
    leg solve on the flexion branch (gait2392 signs: knee flexion negative)."""
    th = th.copy()
    names = list(model.coordinate_names)
    for side in ("r", "l"):
        for c, v in (("knee_angle", -0.5), ("hip_flexion", 0.25), ("ankle_angle", 0.17)):
            if f"{c}_{side}" in names:
                th[names.index(f"{c}_{side}")] = v
    return th


def _foot_target(
    stand: pin.SE3,
    x_m: float,
    z_m: float,
    height_m: float,
    heel_rise_rad: float = 0.0,
    toe: Array | None = None,
) -> pin.SE3:
    """The standing placement moved by (x, height, z) and, with ``heel_rise_rad``, turned heel
    up about the foot's ``toe`` point (in the standing foot frame)."""
    p = np.array(stand.translation, dtype=float) + np.array([x_m, height_m, z_m])
    place = pin.SE3(stand.rotation, p)
    if heel_rise_rad == 0.0 or toe is None:
        return place
    pivot = place.act(np.asarray(toe, dtype=float))
    rz = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, -heel_rise_rad), np.zeros(3))
    turn = pin.SE3(np.eye(3), pivot) * rz * pin.SE3(np.eye(3), -pivot)
    return turn * place


def _motion(
    model: Model,
    t: Array,
    th: Array,
    footholds: Sequence[Foothold],
    kind: str,
    err_m: float,
    pressure: Array | None = None,
) -> TaskMotion:
    spline = make_interp_spline(t, th, k=5)
    return TaskMotion(model, t, th, tuple(footholds), kind, err_m, spline, pressure)


def squat_motion(
    model: Model,
    *,
    reps: int = 4,
    knee_flexion_deg: float = 95.0,
    rep_s: float = 2.4,
    still_s: float = 1.0,
    stance_half_width_m: float = 0.15,
    rate_hz: float = 120.0,
) -> TaskMotion:
    """A two-leg squat: ``reps`` repetitions (each down and up in ``rep_s``, a raised-cosine
    depth profile, 90–100 % deep, with a small asymmetric sway of pelvis and trunk) between
    ``still_s`` of quiet standing, the feet at ±``stance_half_width_m`` from the mid-line, still
    and flat; the pelvis goes down by d, back by 0.15 d and tilts forward by 45° × d / 0.4 m (the
    trunk 35° more by the lumbar joint), d found (bisection) so that the deepest knee flexion is
    ``knee_flexion_deg``; the legs solved to the feet."""
    th0, _, place = _standing(model)
    names = list(model.coordinate_names)
    duration = 2 * still_s + reps * rep_s
    t = np.arange(round(duration * rate_hz) + 1) / rate_hz
    tr = np.clip(t - still_s, 0.0, reps * rep_s)
    s = np.where((t > still_s) & (t < still_s + reps * rep_s),
                 0.5 * (1 - np.cos(2 * np.pi * tr / rep_s)), 0.0)  # fmt: skip
    holds = {f: (0.0, (1 if f.endswith("_r") else -1) * stance_half_width_m) for f in FEET}
    # the feet's standing placements, moved to the stance width
    targets = {
        f: _foot_target(place[f], 0.0, holds[f][1] - float(place[f].translation[2]), 0.0)
        for f in FEET
    }
    ik = names.index("knee_angle_r")

    # a person's squat is neither perfectly symmetric nor repeatable: the pelvis sways
    # (list ±2°, rotation ±3°, side ±1.5 cm, lumbar bending ±2°) at incommensurate rates and
    # each repetition reaches 90–100 % of the deepest one
    sway = {
        "pelvis_list": np.deg2rad(2.0) * np.sin(2 * np.pi * 0.23 * t + 0.4),
        "pelvis_rotation": np.deg2rad(3.0) * np.sin(2 * np.pi * 0.31 * t + 1.1),
        "pelvis_tz": 0.015 * np.sin(2 * np.pi * 0.17 * t + 2.0),
        "lumbar_bending": np.deg2rad(2.0) * np.sin(2 * np.pi * 0.41 * t + 0.7),
    }
    rep_scale = 1.0 - 0.1 * np.abs(np.sin(1.7 * np.arange(reps) + 0.3))
    rep_scale[0] = 1.0
    s = s * rep_scale[np.clip((tr // rep_s).astype(int), 0, reps - 1)]

    def pose(depth: float, sk: float, start: Array, k: int | None = None) -> tuple[Array, float]:
        th = start.copy()
        if k is not None:
            for c, x in sway.items():
                if c in names:
                    th[names.index(c)] = th0[names.index(c)] + x[k]
        # 2 cm lower when standing: knees slightly bent, off the singular straight leg
        th[names.index("pelvis_ty")] = th0[names.index("pelvis_ty")] - 0.005 - depth * sk
        th[names.index("pelvis_tx")] = th0[names.index("pelvis_tx")] - 0.15 * depth * sk
        th[names.index("pelvis_tilt")] = (
            th0[names.index("pelvis_tilt")] - np.deg2rad(45.0 * depth / 0.4) * sk
        )
        if "lumbar_extension" in names:
            th[names.index("lumbar_extension")] = -np.deg2rad(35.0) * sk
        return _solve_legs(model, th, targets)

    lo, hi = 0.05, 0.6
    for _ in range(25):
        mid = 0.5 * (lo + hi)
        th_d, _ = pose(mid, 1.0, _flexed(model, th0))
        if -np.rad2deg(th_d[ik]) < knee_flexion_deg:
            lo = mid
        else:
            hi = mid
    depth = 0.5 * (lo + hi)
    th = np.empty((t.size, th0.size))
    prev = _flexed(model, th0)
    err = 0.0
    for k in range(t.size):
        prev, e = pose(depth, float(s[k]), prev, k)
        th[k] = prev
        err = max(err, e)
    footholds = [
        Foothold(f, float(t[0]), float(t[-1]), 0.0, holds[f][1], 0.0, surface) for f, surface in
        zip(FEET, ("plate_r", "plate_l"), strict=True)
    ]  # fmt: skip
    return _motion(model, t, th, footholds, "squat", err)


def stair_motion(
    model: Model,
    *,
    steps: int = 4,
    step_height_m: float = 0.17,
    tread_m: float = 0.28,
    swing_s: float = 0.5,
    double_s: float = 0.3,
    still_s: float = 0.6,
    rate_hz: float = 120.0,
    tilt_deg: float = _TILT_DEG,
    lean_deg: float = _LEAN_DEG,
    heel_deg: float = _HEEL_DEG,
    drop_m: float = _DROP_M,
) -> TaskMotion:
    """A step-over-step ascent of ``steps`` steps (riser ``step_height_m``, tread ``tread_m``;
    step k's tread spans x ∈ [(k − 1) tread, k tread] at height k × riser): both feet start on the
    floor at x = −0.12 m; the right foot steps onto step 1, the left onto step 2, and so on, each
    swing ``swing_s``, each double support ``double_s`` (a 1.6 s stride, 69 % stance),
    ``still_s`` standing at both ends. The footholds are named ``floor_r``/``floor_l`` (each
    foot's place on the floor), ``step1`` … (the surfaces a lab instruments or not).

    Balance: the pelvis path is chosen so that the ground reaction the
    motion needs has its centre of pressure on the supporting sole — a zero-moment point
    designed on the feet (:data:`_PHI_LEAD` → :data:`_PHI_TRAIL` of the sole in single support,
    trailing → leading foot over each double support), the centre of mass from it by the
    cart-table model (:func:`com_from_zmp`), then :data:`_ZMP_PASSES` damped corrections by the
    motion's own zero-moment point (RNEA's root wrench), keeping the closest path whose feet are
    all reached. Without it the pelvis followed the feet and the centre of pressure left the
    foot by up to 0.5 m, the leg torques 2–3× published stair values. The body rises at a steady
    rate through each step (the trailing heel rising 45° from 0.25 s before the double
    support), the pelvis 4 cm below its straight-leg height or lower where the legs do not
    reach, the pelvis tilted 8° and the trunk 15° forward (``tilt_deg``, ``lean_deg``,
    ``heel_deg`` and ``drop_m`` change those four: level walking on zero risers,
    :func:`msk.datasets.trc.walk_motion`)."""
    th0, h_stand, place = _standing(model)
    names = list(model.coordinate_names)
    half_w = {f: float(place[f].translation[2]) for f in FEET}
    x_start = _X_START_M
    # footholds: (foot, x, height, surface) in order of landing, each foot alternating
    order: list[tuple[str, float, float, str]] = [
        ("calcn_r", x_start, 0.0, "floor_r"),
        ("calcn_l", x_start, 0.0, "floor_l"),
    ]
    for k in range(1, steps + 1):
        foot = FEET[(k - 1) % 2]
        order.append((foot, (k - 0.5) * tread_m, k * step_height_m, f"step{k}"))
    # timeline: foot k+2 of `order` lifts the foot of hold k at lift_k
    t_end = still_s + steps * (swing_s + double_s) + still_s
    holds: list[Foothold] = []
    last: dict[str, tuple[float, float, float, str]] = {}
    t_land = {"calcn_r": 0.0, "calcn_l": 0.0}
    for f, x, h, surf in order[:2]:
        last[f] = (0.0, x, h, surf)
    swings: list[tuple[str, float, float, tuple[float, float], tuple[float, float]]] = []
    t = still_s
    for f, x, h, surf in order[2:]:
        t_on0, x0, h0, surf0 = last[f]
        holds.append(Foothold(f, t_on0, t, x0 - x_start, 0.0, h0, surf0))
        swings.append((f, t, t + swing_s, (x0, h0), (x, h)))
        t += swing_s
        last[f] = (t, x, h, surf)
        t_land[f] = t
        t += double_s
    for f in FEET:
        t_on0, x0, h0, surf0 = last[f]
        holds.append(Foothold(f, t_on0, t_end, x0 - x_start, 0.0, h0, surf0))
    holds.sort(key=lambda fh: fh.t_on)

    ts = np.arange(round(t_end * rate_hz) + 1) / rate_hz

    def foot_xy(f: str, tt: float) -> tuple[float, float]:
        for fh in holds:
            if fh.foot == f and fh.t_on <= tt <= fh.t_off:
                return fh.x_m + x_start, fh.height_m
        for g, a, b, (xa, ha), (xb, hb) in swings:
            if g == f and a <= tt <= b:
                s = (tt - a) / (b - a)
                # lift over the nosing first, then forward; 5 cm clearance over the higher end
                # (sin²: the foot leaves and lands with no vertical speed)
                y = ha + (hb - ha) * float(_mj(np.array(s / 0.6))) + 0.05 * np.sin(np.pi * s) ** 2
                x = xa + (xb - xa) * float(_mj(np.array((s - 0.15) / 0.85)))
                return x, y
        raise AssertionError(f"{f} at {tt}")

    fx = np.array([[foot_xy(f, tt) for f in FEET] for tt in ts])  # (N, 2, 2): x, y
    # the trailing foot's heel rises over the double support before its lift-off (to 35° at
    # lift-off, pivoting on the toes) and the foot levels again over the first half of its swing
    rise = np.zeros((ts.size, 2))
    for g, a, _, _, _ in swings:
        j = FEET.index(g)
        pre_s = double_s + _HEEL_PRE_S
        pre = (ts >= a - pre_s) & (ts < a)
        rise[pre, j] = np.deg2rad(heel_deg) * _mj((ts[pre] - (a - pre_s)) / pre_s)
    toes = {f: _sole_end(model, f, place[f], toe=True) for f in FEET}
    origin = np.zeros(3)
    # the support: the lower of the standing feet's surfaces, rising at a steady rate from
    # the double support before each swing of the lower foot to the landing that raises it
    # (the body climbs through the whole step, not only in single support: a linear path
    # through those knots, its corners rounded by a 1.5 Hz low-pass)
    knots_t, knots_h = [0.0], [0.0]
    level = 0.0
    for g, a, b, _, (_, hb) in swings:
        other = [fh for fh in holds if fh.foot != g and fh.t_on <= a <= fh.t_off]
        new_level = min(hb, other[0].height_m) if other else hb
        if new_level != level:
            a0 = max(a - double_s, knots_t[-1])
            if a0 > knots_t[-1]:
                knots_t.append(a0)
                knots_h.append(level)
            knots_t.append(b)
            knots_h.append(new_level)
            level = new_level
    from msk.signal import filtfilt_butter

    pad = round(rate_hz)
    support = np.interp(ts, knots_t, knots_h)
    support = filtfilt_butter(np.pad(support, pad, mode="edge"), rate_hz=rate_hz,
                              cutoff_hz=1.5)[pad:-pad]  # fmt: skip
    ix, iz = names.index("pelvis_tx"), names.index("pelvis_tz")
    iy, itilt = names.index("pelvis_ty"), names.index("pelvis_tilt")
    ia = [names.index(c) for c in ("ankle_angle_r", "ankle_angle_l")]
    ilumb = names.index("lumbar_extension") if "lumbar_extension" in names else None

    # where each foot presses (its sole between the heel and the toe markers, on the foot's
    # centre line): in single support from 40 % to 75 % of the foot (mid-foot to the ball), the
    # trailing foot at 75 % in double support (its heel rising about the toes), the leading foot
    # at 40 %; the zero-moment point goes from foot to foot over each double support (minimum
    # jerk), to the left foot over the last 0.4 s of the start, and half-way between the feet
    # over the end's double support
    heels = {f: _sole_end(model, f, place[f], toe=False) for f in FEET}
    feet_mk = {f: [i for i, m in enumerate(model.markers) if m.body in set(model.subtree(f))]
               for f in FEET}  # fmt: skip
    mk0 = marker_positions(model, th0)[0]
    mid_z = {f: float(np.mean([place[f].actInv(mk0[i])[2] for i in feet_mk[f]])) for f in FEET}

    def press(j: int, k: int, phi: float) -> Array:
        f = FEET[j]
        q = heels[f] + phi * (toes[f] - heels[f])
        q[2] = mid_z[f]
        return np.asarray(place[f].act(q), dtype=float) + np.array([fx[k, j, 0], fx[k, j, 1], 0.0])

    on = np.array([[any(fh.foot == f and fh.t_on <= tt <= fh.t_off for fh in holds) for f in FEET]
                   for tt in ts])  # fmt: skip
    pressure = np.full((ts.size, 2, 3), np.nan)
    zmp = np.empty((ts.size, 3))
    k = 0
    while k < ts.size:
        e = k
        while e < ts.size and (on[e] == on[k]).all():
            e += 1
        u = (np.arange(k, e) - k + 0.5) / (e - k)
        if on[k].all():
            # the trailing foot lifts at the end of this double support (none at the end)
            lifts = [j for j in range(2) if e < ts.size and not on[e, j]]
            trail = lifts[0] if lifts else -1
            if k == 0:  # the start: from between the feet to the left (stance) foot
                ramp = 0.4 / (ts[e - 1] - ts[k] + 1e-9)
                w = 0.5 + 0.5 * _mj((u - 1.0 + ramp) / ramp)
            elif trail < 0:  # the end: to half-way between the feet
                w = 0.5 * _mj(u * (ts[e - 1] - ts[k]) / 0.4)
            else:
                w = _mj(u)
            # at the end, the foot that stood alone before is the one the load leaves
            tr = trail if trail >= 0 else (0 if k > 0 and on[k - 1, 0] else 1)
            lead = 1 - tr
            if trail >= 0:
                phi = (_PHI_TRAIL, _PHI_LEAD)
            else:  # standing on two steps (or still): the other foot nearer its mid-foot
                phi = (_PHI_TRAIL, _PHI_LEAD + 0.05) if k > 0 else (_PHI_LEAD, _PHI_LEAD)
            for i, kk in enumerate(range(k, e)):
                pts = [press(j, kk, phi[0] if j == tr else phi[1]) for j in range(2)]
                pressure[kk] = pts
                zmp[kk] = (1.0 - w[i]) * pts[tr] + w[i] * pts[lead]
        else:
            j = int(np.flatnonzero(on[k])[0])
            for i, kk in enumerate(range(k, e)):
                one = press(j, kk, _PHI_LEAD + (_PHI_TRAIL - _PHI_LEAD) * float(u[i]))
                pressure[kk, j] = one
                zmp[kk] = one
        k = e
    # laterally 85 % of the way from the mid-line to the foot's centre line (the zero-moment
    # point inside the stance foot's medial half: less sway)
    mid_line = float(np.mean([place[f].translation[2] for f in FEET]))
    zmp_z = mid_line + 0.85 * (zmp[:, 2] - mid_line)
    dt = 1.0 / rate_hz
    com0 = pin.centerOfMass(model.pin_model, model.create_data(), model.coupling.q(th0))
    h_com = float(com0[1])
    x_p = com_from_zmp(zmp[:, 0], dt, h_com) - float(com0[0])
    z_p = com_from_zmp(zmp_z, dt, h_com) - float(com0[2])

    def solve(pitch: Array) -> tuple[Array, float]:
        th = np.empty((ts.size, th0.size))
        prev = _flexed(model, th0)
        err = 0.0
        for k in range(ts.size):
            cur = prev.copy()
            cur[ix] = th0[ix] + x_p[k]
            cur[iy] = h_stand - drop + support[k]
            cur[iz] = th0[iz] + z_p[k]
            cur[itilt] = th0[itilt] - np.deg2rad(tilt_deg)
            if ilumb is not None:
                cur[ilumb] = th0[ilumb] - np.deg2rad(lean_deg)
            targets = {}
            for j, f in enumerate(FEET):
                pl = _foot_target(place[f], float(fx[k, j, 0]), 0.0, float(fx[k, j, 1]),
                                  float(rise[k, j] + rise_sw[k, j]), toes[f])  # fmt: skip
                if pitch[k, j] != 0.0:
                    pl = _foot_target(pl, 0.0, 0.0, 0.0, float(pitch[k, j]), origin)
                targets[f] = pl
            prev, e = _solve_legs(model, cur, targets)
            th[k] = prev
            err = max(err, e)
        return th, err

    # the swinging foot levels from the lift-off's heel rise to flat at landing (about its
    # toes: continuous with the stance's placement); first pass so; second: turned about its
    # origin by the difference between that pass's ankle and a minimum-jerk ankle from lift-off
    # to landing, windowed by sin²(π s) (zero at both ends) — a foot levelled early behind a
    # steep shank is 60° dorsiflexed
    rise_sw = np.zeros((ts.size, 2))
    for g, a, b, _, _ in swings:
        sw = (ts >= a) & (ts <= b)
        rise_sw[sw, FEET.index(g)] = np.deg2rad(heel_deg) * (1.0 - _mj((ts[sw] - a) / (b - a)))
    # the pelvis as high as the legs reach: its drop below the straight-leg height grown by
    # 1 cm until every foot placement is reached (< 0.1 mm) on the first path
    drop = drop_m
    th, err = solve(np.zeros((ts.size, 2)))
    while err > 1e-4 and drop < drop_m + 0.05:
        drop += 0.01
        th, err = solve(np.zeros((ts.size, 2)))
    pitch = np.zeros((ts.size, 2))
    for g, a, b, _, _ in swings:
        j = FEET.index(g)
        sw = (ts >= a) & (ts <= b)
        ka, kb = int(np.argmax(sw)), int(np.flatnonzero(sw)[-1])
        u = (ts[sw] - a) / (b - a)
        want = th[ka, ia[j]] + (th[kb, ia[j]] - th[ka, ia[j]]) * _mj(u)
        pitch[sw, j] = (th[sw, ia[j]] - want) * np.sin(np.pi * u) ** 2
    # the pelvis path corrected until the motion's own zero-moment point (RNEA's root wrench:
    # swing leg, trunk, vertical accelerations) follows the design: each pass moves the centre
    # of mass by the cart-table answer to the remaining error
    best = None
    for _ in range(_ZMP_PASSES + 1):
        th, err = solve(pitch)
        spline = make_interp_spline(ts, th, k=5)
        force, moment = root_wrench(model, th, spline(ts, 1), spline(ts, 2))
        hgt = zmp[:, 1]
        cx = (moment[:, 2] + hgt * force[:, 0]) / force[:, 1]
        cz = (hgt * force[:, 2] - moment[:, 0]) / force[:, 1]
        miss = float(np.sqrt(np.mean((zmp[:, 0] - cx) ** 2 + (zmp_z - cz) ** 2)))
        # kept: the path whose zero-moment point is nearest the design with every foot
        # placement reached (a pass that leaves the legs' reach is not taken)
        if err <= 1e-4 and (best is None or miss < best[0]):
            best = (miss, th, err)
        elif best is not None:
            break
        # damped, each pass's correction at most 5 cm
        x_p = x_p + np.clip(0.7 * com_from_zmp(zmp[:, 0] - cx, dt, h_com), -0.05, 0.05)
        z_p = z_p + np.clip(0.7 * com_from_zmp(zmp_z - cz, dt, h_com), -0.05, 0.05)
    if best is not None:
        _, th, err = best
    del half_w, t_land
    return _motion(model, ts, th, holds, "stair", err, pressure)


@dataclass(frozen=True)
class FootReactions:
    """Each foot's ground reaction at ``time`` (the analog rate): force (K, F, 3), centre of
    pressure on its surface (K, F, 3; NaN off contact), free moment about the vertical (K, F, 3),
    world frame; the surface each foot stands on per sample (``surface``: (K, F) str, "" in
    swing) and the total (force, moment about the origin) the motion needs."""

    time: Array
    force: Array
    cop: Array
    free_moment: Array
    surface: NDArray[np.str_]
    total_force: Array
    total_moment: Array


def _foot_points(model: Model, th: Array) -> Array:
    """(K, F, 3) the mid-point of each foot's markers (the foot's centre) in the world."""
    mk = marker_positions(model, th)
    out = np.empty((th.shape[0], len(FEET), 3))
    for j, f in enumerate(FEET):
        sub = set(model.subtree(f))
        idx = [i for i, m in enumerate(model.markers) if m.body in sub]
        out[:, j] = mk[:, idx].mean(axis=1)
    return out


def task_reactions(motion: TaskMotion, rate_hz: float) -> FootReactions:
    """The ground reactions of ``motion`` sampled at ``rate_hz`` (module docstring)."""
    model = motion.model
    t = np.arange(round(motion.time[-1] * rate_hz) + 1) / rate_hz
    th, thd, thdd = motion.at(t)
    force, moment = root_wrench(model, th, thd, thdd)
    pts = _foot_points(model, th)
    on = np.empty((t.size, 2), dtype=bool)
    hgt = np.empty((t.size, 2))
    surf = np.full((t.size, 2), "", dtype=object)
    for j, f in enumerate(FEET):
        on[:, j], hgt[:, j] = motion.contact(f, t)
        for fh in motion.footholds:
            if fh.foot == f:
                surf[(t >= fh.t_on) & (t <= fh.t_off), j] = fh.surface
    if motion.pressure is not None:  # the design's pressure points (a stair's)
        for j in range(len(FEET)):
            for a in range(3):
                col = motion.pressure[:, j, a]
                ok = np.isfinite(col)
                pts[:, j, a] = np.interp(t, motion.time[ok], col[ok]) if ok.any() else np.nan
    pts[..., 1] = np.where(on, hgt, np.nan)
    # the right foot's share α of the total: 1 or 0 in single support; in double support the
    # total COP's projection between the feet's pressure points clipped to [0, 1] (stair: the
    # motion's zero-moment point goes from the trailing to the leading foot), to [0.15, 0.85]
    # (squat), or a minimum-jerk transfer (a stair without pressure points)
    alpha = np.where(on[:, 0], 1.0, 0.0)
    both: NDArray[np.bool_] = np.asarray(on.all(axis=1), dtype=bool)
    if motion.kind == "stair" and motion.pressure is not None:
        h = np.nan_to_num(pts[:, :, 1]).mean(axis=1)
        fy = force[:, 1]
        c = np.column_stack([(moment[:, 2] + h * force[:, 0]) / fy, h,
                             (h * force[:, 2] - moment[:, 0]) / fy])  # fmt: skip
        d = np.nan_to_num(pts[:, 0] - pts[:, 1])
        d[:, 1] = 0.0
        rel = c - np.nan_to_num(pts[:, 1])
        rel[:, 1] = 0.0
        dd = np.einsum("ki,ki->k", d, d)
        proj = np.einsum("ki,ki->k", rel, d) / np.where(dd > 0.0, dd, 1.0)
        alpha = np.where(both, np.clip(proj, 0.0, 1.0), alpha)
    elif motion.kind == "squat":
        fy = force[:, 1]
        c = np.column_stack([moment[:, 2] / fy, np.zeros_like(fy), -moment[:, 0] / fy])
        d = pts[:, 0] - pts[:, 1]
        d[:, 1] = 0.0
        rel = c - pts[:, 1]
        rel[:, 1] = 0.0
        alpha = np.clip(np.einsum("ki,ki->k", rel, d) / np.einsum("ki,ki->k", d, d), 0.15, 0.85)
    else:
        k = 0
        while k < t.size:
            if not both[k]:
                k += 1
                continue
            e = k
            while e < t.size and both[e]:
                e += 1
            if k == 0 or e == t.size:  # standing at either end: shared evenly
                alpha[k:e] = 0.5
            else:
                # the foot that was standing alone before the double support is the trailing one
                r_before = on[k - 1, 0]
                s = _mj((np.arange(k, e) - k + 0.5) / (e - k))
                alpha[k:e] = 1.0 - s if r_before else s
            k = e
    # each foot: α F at p + e, T shared; e and T from the total wrench (exact sum)
    f_feet = np.stack([alpha[:, None] * force, (1.0 - alpha[:, None]) * force], axis=1)
    p = np.nan_to_num(pts)
    resid = moment - np.einsum("kfi->ki", np.cross(p, f_feet))
    fy = force[:, 1]
    ez = -resid[:, 0] / fy
    ex = resid[:, 2] / fy
    tfree = resid[:, 1] - (ez * force[:, 0] - ex * force[:, 2])
    off = np.column_stack([ex, np.zeros_like(ex), ez])
    cop = p + off[:, None, :]
    share = np.stack([alpha, 1.0 - alpha], axis=1)
    free = share[:, :, None] * np.outer(tfree, [0.0, 1.0, 0.0])[:, None, :]
    cop = np.where(on[..., None], cop, np.nan)
    f_feet = np.where(on[..., None], f_feet, 0.0)
    free = np.where(on[..., None], free, 0.0)
    return FootReactions(t, f_feet, cop, free, surf.astype(str), force, moment)


def true_torques(motion: TaskMotion, reactions: FootReactions, time: Array) -> Array:
    """(N, n) generalised forces of ``motion`` at ``time`` (samples of ``reactions.time``) by
    RNEA with the feet's reactions applied; the root rows are ≈ 0 (the reactions balance the
    motion)."""
    model = motion.model
    pm = model.pin_model
    data = pm.createData()
    th, thd, thdd = motion.at(time)
    q, v, a = model.coupling.embed(th, thd, thdd)
    idx = np.searchsorted(reactions.time, time - 1e-9)
    tau = np.empty((time.size, pm.nv))
    for k in range(time.size):
        pin.forwardKinematics(pm, data, q[k])
        fext = pin.StdVec_Force()
        fext.extend([pin.Force.Zero() for _ in range(pm.njoints)])
        for j, foot in enumerate(FEET):
            i = idx[k]
            fv = reactions.force[i, j]
            if not np.any(fv):
                continue
            m = np.cross(reactions.cop[i, j], fv) + reactions.free_moment[i, j]
            jid = model.body_joint[foot]
            fext[jid] = fext[jid] + data.oMi[jid].actInv(pin.Force(fv, m))
        tau[k] = pin.rnea(pm, data, q[k], v[k], a[k], fext)
    return np.asarray(model.coupling.project(th, tau))


@dataclass(frozen=True)
class LabPlate:
    """A plate of the written trial: its corners (4, 3) in the model frame (m), its channel
    labels (6, type 2) and the surface (foothold name) it measures."""

    surface: str
    corners: Array
    channels: tuple[str, ...]


#: EMG channel (substring of the label) → the coordinates whose torque of the given sign its
#: muscle produces (gait2392 signs: knee extensors give a positive knee_angle torque, hip
#: extensors a negative hip_flexion one, plantarflexors a negative ankle_angle one)
_EMG_DRIVE: dict[str, tuple[tuple[str, float], ...]] = {
    "vas": (("knee_angle", 1.0),),
    "rf": (("knee_angle", 1.0), ("hip_flexion", 1.0)),
    "semi": (("knee_angle", -1.0), ("hip_flexion", -1.0)),
    "bifem": (("knee_angle", -1.0), ("hip_flexion", -1.0)),
    "gas": (("ankle_angle", -1.0),),
    "soleus": (("ankle_angle", -1.0),),
    "tibant": (("ankle_angle", 1.0),),
    "peron": (("ankle_angle", -1.0),),
    "gmax": (("hip_flexion", -1.0),),
    "addmag": (("hip_flexion", -1.0), ("hip_adduction", 1.0)),
    "gmed": (("hip_adduction", -1.0),),
    "tfl": (("hip_adduction", -1.0), ("hip_flexion", 1.0)),
    "sart": (("hip_flexion", 1.0),),
    "gracilis": (("hip_adduction", 1.0),),
}


def _emg(
    label: str, tau: Array, names: Sequence[str], side: str, n: int, rng: np.random.Generator
) -> Array:
    """A raw EMG channel (V): white noise × (0.02 + the channel's muscles' torque / its peak)."""
    key = next((k for k in _EMG_DRIVE if k in label.lower()), None)
    env = np.zeros(tau.shape[0])
    if key is not None:
        for c, sgn in _EMG_DRIVE[key]:
            name = f"{c}_{side}"
            if name in names:
                env += np.clip(sgn * tau[:, list(names).index(name)], 0.0, None)
        if env.max() > 0:
            env = env / env.max()
    ratio = n // tau.shape[0]
    env_a = np.repeat(env, ratio)[:n]
    env_a = np.pad(env_a, (0, n - env_a.size), mode="edge")
    return (0.02 + env_a) * rng.normal(0.0, 0.3, n)


def write_lab_c3d(
    path: str | Path,
    motion: TaskMotion,
    reactions: FootReactions,
    *,
    template: str | Path,
    rename: Mapping[str, str],
    lab_from_model: Array,
    lab_origin_m: Array,
    plates: Sequence[LabPlate],
    side: str = "r",
    noise_m: float = 0.0015,
    seed: int = 0,
    tau: Array | None = None,
    label_prefix: str = "",
    plate_offset_n: float = 0.0,
) -> Path:
    """Write ``motion`` as a C3D in the lab format of ``template`` (module docstring).

    ``rename``: model marker name → the lab's label (:attr:`msk.personalise.Personalisation.rename`;
    others keep their model name); ``lab_from_model`` (3, 3) and ``lab_origin_m`` place the model
    frame in the lab (lab = R p + o); ``plates`` in the model frame, each measuring the feet on
    its surface (in the template's plate order and channel labels); ``tau`` (N, n) drives the EMG
    channels (``side``'s coordinates); ``label_prefix`` is put before every marker label (a
    Vicon subject prefix, ``JW:LASI``); ``plate_offset_n`` a steady force along the lab's up
    added to every plate's reading at its centre (an amplifier not zeroed)."""
    import ezc3d

    from msk.io import PlateSpec, write_c3d

    rng = np.random.default_rng(seed)
    tmpl = ezc3d.c3d(str(template))
    prm = tmpl["parameters"]
    rate = float(prm["POINT"]["RATE"]["value"][0])
    a_rate = float(prm["ANALOG"]["RATE"]["value"][0])
    ratio = round(a_rate / rate)
    labels = [str(s) for s in prm["POINT"]["LABELS"]["value"]]
    a_labels = [str(s) for s in prm["ANALOG"]["LABELS"]["value"]]
    a_units = [str(s) for s in prm["ANALOG"]["UNITS"]["value"]]
    scale = {"mm": 1000.0, "m": 1.0, "cm": 100.0}[str(prm["POINT"]["UNITS"]["value"][0])]
    rot = np.asarray(lab_from_model, dtype=float)
    org = np.asarray(lab_origin_m, dtype=float)
    model = motion.model
    n = motion.time.size
    mk = marker_positions(model, motion.q)  # (N, M, 3) model frame
    lab_of = {rename.get(m.name, m.name): i for i, m in enumerate(model.markers)}
    # the template's other labels: fixed ones (lab axes) at their template median; moving ones
    # the model does not carry (arms, head) left as gaps (a lab that does not track them)
    tpts = np.asarray(tmpl["data"]["points"][:3], dtype=float).transpose(2, 1, 0) / scale
    tpts[(tpts == 0).all(axis=2)] = np.nan
    out = np.full((n, len(labels), 3), np.nan)
    for j, lab in enumerate(labels):
        if lab in lab_of:
            out[:, j] = mk[:, lab_of[lab]] @ rot.T + org
    for j, lab in enumerate(labels):
        if lab in lab_of:
            continue
        tp = tpts[:, j]
        good = np.isfinite(tp).all(axis=1)
        if not good.any():
            continue
        if np.nanstd(tp[good], axis=0).max() < 0.005:
            out[:, j] = np.median(tp[good], axis=0)
            continue
        # a moving label the model does not carry (arms, head): not tracked (a gap)
    out = out + rng.normal(0.0, noise_m, out.shape)
    na = n * ratio
    analogs = np.zeros((na, len(a_labels)))
    specs = []
    rt = reactions.time
    ta = np.arange(na) / a_rate
    src = np.clip(np.searchsorted(rt, ta - 1e-9), 0, rt.size - 1)
    for pl in plates:
        corners_lab = pl.corners @ rot.T + org
        axes = plate_axes(corners_lab)
        centre = corners_lab.mean(axis=0)
        f_lab = np.zeros((na, 3))
        m_c = np.zeros((na, 3))
        for j in range(len(FEET)):
            on = reactions.surface[src, j] == pl.surface
            f = reactions.force[src, j] @ rot.T
            c = np.nan_to_num(reactions.cop[src, j]) @ rot.T + org
            tf = reactions.free_moment[src, j] @ rot.T
            f_lab += np.where(on[:, None], f, 0.0)
            m_c += np.where(on[:, None], np.cross(c - centre, f) + tf, 0.0)
        # plate noise: 2 N, 0.5 N·m
        f_lab += plate_offset_n * (rot @ np.array([0.0, 1.0, 0.0]))  # no moment about the centre
        f_loc = f_lab @ axes + rng.normal(0.0, 2.0, f_lab.shape)
        m_loc = (m_c @ axes + rng.normal(0.0, 0.5, m_c.shape)) * 1000.0
        for c, v in zip(pl.channels, np.column_stack([f_loc, m_loc]).T, strict=True):
            analogs[:, a_labels.index(c)] = v
        specs.append(PlateSpec(channels=tuple(pl.channels), corners_m=corners_lab,
                               origin_m=np.zeros(3)))  # fmt: skip
    plate_ch = {c for pl in plates for c in pl.channels}
    names = list(model.coordinate_names)
    for j, lab in enumerate(a_labels):
        if lab in plate_ch:
            continue
        offset = float(np.median(np.asarray(tmpl["data"]["analogs"][0, j], dtype=float)))
        if tau is not None and any(k in lab.lower() for k in _EMG_DRIVE):
            analogs[:, j] = offset + _emg(lab, tau, names, side, na, rng)
        else:
            analogs[:, j] = offset + rng.normal(0.0, 0.002, na)
    return write_c3d(
        path,
        markers=out,
        marker_labels=[label_prefix + lab for lab in labels],
        rate_hz=rate,
        point_units=str(prm["POINT"]["UNITS"]["value"][0]),
        analogs=analogs,
        analog_labels=a_labels,
        analog_units=a_units,
        analog_ratio=ratio,
        plates=specs,
    )


@dataclass(frozen=True)
class LabTask:
    """A task trial written in a session's lab format with its truth: the C3D ``path``, the
    ``motion`` (θ at the marker rate), the true generalised forces ``tau`` (N, n) there, and
    ``unmeasured`` (N,) the frames in which a foot stands on a surface no plate measures, and
    the surfaces the plates measure (``measured_surfaces``)."""

    path: Path
    motion: TaskMotion
    reactions: FootReactions
    tau: Array
    unmeasured: NDArray[np.bool_]
    measured_surfaces: frozenset[str] = frozenset()


def _tread(x0: float, x1: float, z0: float, z1: float, h: float) -> Array:
    """Corners of a horizontal plate (model frame) over x ∈ [x0, x1], z ∈ [z0, z1] at height h,
    ordered so that its z axis points down (as the Grand Challenge and most labs' plates)."""
    return np.array([[x1, h, z1], [x0, h, z1], [x0, h, z0], [x1, h, z0]], dtype=float)


def lab_task(
    config: str | Path,
    kind: str,
    path: str | Path,
    *,
    placed: Any,
    seed: int = 0,
    noise_m: float = 0.0015,
    step_height_m: float = 0.17,
    steps: int = 4,
    reps: int = 4,
    knee_flexion_deg: float = 95.0,
    corners_at_floor: bool = False,
    label_prefix: str = "",
    plate_offset_n: float = 0.0,
) -> LabTask:
    """A ``kind`` ("squat" or "stair") trial of the session ``config``'s subject in its lab's
    format: ``placed``, the session's personalised model (:class:`msk.personalise.Personalisation`
    that its ``msk run`` builds: scaled, markers placed from its static), its task
    C3D as the template (labels, rates, plate and analog channels), written to ``path``.

    Squat: each foot on its own plate — the feet straddle the boundary between the template's
    two nearest plates (±15 cm of their centres' midpoint along the line joining them; the
    subject faces across it). Stair: the template's first plate on the floor under the left
    foot's start, the next ones in steps 1 and 2 (corners at the step's height, tread-sized),
    the other steps uninstrumented; the flight along the lab's first horizontal axis. With
    ``corners_at_floor`` the steps stand on their plates and the file stores the plates'
    corners at floor level (as a lab does: the step's surface is ``k × step_height_m`` above
    them). ``label_prefix`` and ``plate_offset_n``: :func:`write_lab_c3d`."""
    import ezc3d

    built = placed
    model = built.model
    from msk.config import load_config

    cfg = load_config(config)
    template = cfg.trials_with_role("task")[0].file
    tmpl = ezc3d.c3d(str(template))
    prm = tmpl["parameters"]
    scale = {"mm": 1000.0, "m": 1.0, "cm": 100.0}[str(prm["POINT"]["UNITS"]["value"][0])]
    a_labels = [str(s) for s in prm["ANALOG"]["LABELS"]["value"]]
    chan = np.asarray(prm["FORCE_PLATFORM"]["CHANNEL"]["value"], dtype=int)
    corners_t = np.asarray(prm["FORCE_PLATFORM"]["CORNERS"]["value"], dtype=float) / scale
    n_pl = chan.shape[1]
    channels = [tuple(a_labels[c - 1] for c in chan[:6, k]) for k in range(n_pl)]
    up = np.asarray(built.lab_up, dtype=float)
    up = up / np.linalg.norm(up)
    rate = float(prm["POINT"]["RATE"]["value"][0])
    a_rate = float(prm["ANALOG"]["RATE"]["value"][0])
    if kind == "squat":
        motion = squat_motion(model, reps=reps, knee_flexion_deg=knee_flexion_deg, rate_hz=rate)
        cen = corners_t.mean(axis=1).T  # (P, 3) lab
        pairs = [(i, j) for i in range(n_pl) for j in range(i + 1, n_pl)]
        i, j = min(pairs, key=lambda p: float(np.linalg.norm(cen[p[0]] - cen[p[1]])))
        right_lab = cen[i] - cen[j]
        right_lab -= (right_lab @ up) * up
        right_lab /= np.linalg.norm(right_lab)
        fwd_lab = np.cross(up, right_lab)
        rot = np.column_stack([fwd_lab, up, right_lab])  # lab = rot @ model
        feet = _foot_points(model, motion.q[:1])[0]
        mid = 0.5 * (cen[i] + cen[j])
        mid -= (mid @ up) * up
        org = mid - rot @ np.array([feet[:, 0].mean(), 0.0, 0.0])
        org += float(np.mean(corners_t[:, :, i].T @ up)) * up
        floor = float(np.mean(corners_t[:, :, i].T @ up))
        plates_m = []
        for k, surf in ((i, "plate_r"), (j, "plate_l")):
            c_model = (corners_t[:, :, k].T - org) @ rot  # model = rotᵀ (lab − o)
            plates_m.append(LabPlate(surf, c_model, channels[k]))
        del floor
    elif kind == "stair":
        motion = stair_motion(model, steps=steps, step_height_m=step_height_m, rate_hz=rate)
        horiz = [np.eye(3)[a] for a in range(3) if abs(np.eye(3)[a] @ up) < 0.5]
        fwd_lab = horiz[0]
        right_lab = np.cross(fwd_lab, up)
        rot = np.column_stack([fwd_lab, up, right_lab])
        org = np.zeros(3)
        _, _, place = _standing(model)
        fl = _foot_points(model, motion.q[:1])[0, 1]
        fl_x = float(fl[0])
        fl_z = float(place["calcn_l"].translation[2])
        tread = 0.28
        plates_m = [
            LabPlate("floor_l", _tread(fl_x - 0.25, fl_x + 0.25, fl_z - 0.3, fl_z + 0.07, 0.0),
                     channels[0]),
        ]  # fmt: skip
        for k in range(1, min(n_pl, 3)):
            h = k * step_height_m
            hc = 0.0 if corners_at_floor else h
            plates_m.append(LabPlate(f"step{k}", _tread((k - 1) * tread, k * tread, -0.25, 0.25,
                                                        hc), channels[k]))  # fmt: skip
    else:
        raise ValueError(f"kind {kind!r}: 'squat' or 'stair'")
    reactions = task_reactions(motion, a_rate)
    tau = true_torques(motion, reactions, motion.time)
    out = write_lab_c3d(
        path, motion, reactions, template=template, rename=built.rename, lab_from_model=rot,
        lab_origin_m=org, plates=plates_m, noise_m=noise_m, seed=seed, tau=tau,
        side=cfg.subject.side[0] if cfg.subject.side else "r", label_prefix=label_prefix,
        plate_offset_n=plate_offset_n,
    )  # fmt: skip
    measured = {p.surface for p in plates_m}
    unmeasured = np.zeros(motion.time.size, dtype=bool)
    for fh in motion.footholds:
        if fh.surface not in measured:
            unmeasured |= (motion.time >= fh.t_on) & (motion.time <= fh.t_off)
    return LabTask(out, motion, reactions, tau, unmeasured, frozenset(measured))
