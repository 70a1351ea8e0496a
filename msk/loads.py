"""External loads: force-plate wrenches assigned to the feet, and other applied forces.

Each plate gives, at its own (analog) rate, the ground reaction force F, the centre of pressure
(COP) c on its surface and the free moment T (about the vertical through c). msk carries a plate
wrench as a spatial force at the world origin, world axes::

    f_O = (F, M_O),   M_O = c × F + T

which is linear in the recorded channels, so it is what gets resampled to the kinematics time
(linear interpolation) — the COP is not interpolated. A plate is *in contact* where its vertical
force (along −gravity) exceeds ``threshold_n``. Each contiguous contact interval is assigned to
the foot that stands on the plate. A foot *stands* on a plate at a frame when all of these hold
for its points (origins of the foot bodies and their descendants, and their markers):

* the floor projection of one of them lies inside the plate outline (corners) grown by
  ``margin_m``;
* the one nearest the floor is within ``floor_m`` of the plate surface (the height of the
  recorded COPs);
* it is not swinging over the plate: a foot whose slowest point moves faster than
  ``speed_mps`` does not stand on the plate while another foot on it is both slower and nearer
  the centre of pressure (a supporting foot is still, or rolls about the heel or the toes; a
  swinging foot passing over the plate moves at metres per second).

The outline test alone counts a foot swinging over the plate, or a foot standing on the next
plate with its toes within the margin, as standing on it (overground gait, e.g. the Grand
Challenge walks). The foot standing on the plate for most of the sampled frames of the interval
wins. A plate without corners uses the distance from the COP to the foot points only (nearest
foot within ``cop_radius_m``). An interval with no foot standing on the plate, or with two feet
standing on it for most of its frames, raises :class:`~msk.exceptions.ForcePlateError` naming
the plate and the time.

Signs: F is the force the ground exerts **on the subject** (vertical component positive up).
Plates that recorded the action instead (negative vertical force during contact) are flipped
automatically (``sign="auto"``).

For ``pin.rnea(model, data, q, v, a, fext)`` the wrench of body b is expressed in the local frame
of the Pinocchio joint carrying it: ``fext[j] = data.oMi[j].actInv(f_O)``
(:meth:`ExternalLoads.fext`).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import ForcePlateError, MissingDataError, ModelError, ShapeMismatchError
from msk.model import Model
from msk.signal import filtfilt_butter, resample_to

Array = NDArray[np.float64]


@dataclass(frozen=True)
class PlateWrench:
    """One force plate in the lab (= model world) frame, at its own rate.

    ``force`` (Na, 3) N, ``cop`` (Na, 3) m (NaN where unloaded), ``free_moment`` (Na, 3) N·m
    (along the plate normal), ``corners`` (4, 3) m or ``None`` (unknown outline).
    """

    name: str
    time: Array
    force: Array
    cop: Array
    free_moment: Array
    corners: Array | None = None

    def moment_about_origin(self) -> Array:
        """M_O = c × F + T, zero where the COP is undefined (Na, 3)."""
        cop = np.nan_to_num(self.cop)
        m = np.cross(cop, self.force) + np.nan_to_num(self.free_moment)
        m[~np.isfinite(self.cop).all(axis=1)] = 0.0
        return m


def plates_from_trial(trial: Any) -> tuple[PlateWrench, ...]:
    """The plates of a :class:`msk.io.Trial` (``trial.plates`` at ``trial.analog_time``)."""
    out = []
    for p in trial.plates:
        out.append(
            PlateWrench(
                name=f"plate{p.index + 1}",
                time=np.asarray(trial.analog_time, dtype=float),
                force=np.asarray(p.force, dtype=float),
                cop=np.asarray(p.cop, dtype=float),
                free_moment=np.asarray(p.free_moment, dtype=float),
                corners=np.asarray(p.corners, dtype=float),
            )
        )
    return tuple(out)


def plates_from_table(
    time: ArrayLike,
    data: ArrayLike,
    columns: Sequence[str],
    *,
    prefixes: Sequence[str] = ("ground_", "1_ground_"),
) -> tuple[PlateWrench, ...]:
    """Plates from an OpenSim GRF table (``<prefix>force_v[xyz]``, ``<prefix>force_p[xyz]``,
    ``<prefix>torque_[xyz]``), one plate per prefix (no corners)."""
    t = np.asarray(time, dtype=float)
    x = np.asarray(data, dtype=float)
    cols = list(columns)
    out = []
    for k, pre in enumerate(prefixes):

        def grab(names: list[str], pre: str = pre) -> Array:
            try:
                return x[:, [cols.index(pre + n) for n in names]]
            except ValueError:
                raise MissingDataError(
                    f"GRF table: no columns {[pre + n for n in names]}"
                ) from None

        f = grab(["force_vx", "force_vy", "force_vz"])
        c = grab(["force_px", "force_py", "force_pz"])
        tq = grab(["torque_x", "torque_y", "torque_z"])
        c = c.copy()
        c[np.linalg.norm(f, axis=1) == 0.0] = np.nan
        out.append(PlateWrench(f"plate{k + 1}", t, f, c, tq, None))
    return tuple(out)


@dataclass(frozen=True)
class AppliedForce:
    """An extra external force on a body (a carried load, an end-effector force).

    ``force`` (N, 3) world N, applied at ``point`` (N, 3) m — in the world frame, or in the body
    frame when ``point_in_body``; ``moment`` (N, 3) N·m an optional pure couple (world). Samples
    are on the kinematics time.
    """

    body: str
    force: Array
    point: Array
    moment: Array | None = None
    point_in_body: bool = False


@dataclass(frozen=True)
class Assignment:
    """One contact interval of a plate and the body it was assigned to."""

    plate: str
    body: str
    start_time: float
    end_time: float


@dataclass(frozen=True)
class ExternalLoads:
    """External wrenches per body on the kinematics time (world frame, SI).

    ``force[:, b]`` (N) and ``moment[:, b]`` (N·m, about the **world origin**) of body
    ``bodies[b]``; ``point[:, b]`` the point of application (the COP for plate loads; NaN when
    unloaded or undefined). ``moment_about_point`` gives the moment about that point (the free
    moment for a single plate).
    """

    time: Array
    bodies: tuple[str, ...]
    force: Array
    moment: Array
    point: Array
    assignments: tuple[Assignment, ...] = ()
    metadata: Mapping[str, Any] = field(default_factory=dict)

    def moment_about_point(self) -> Array:
        """M_O − p × F (N, B, 3); NaN where the point is undefined."""
        return self.moment - np.cross(self.point, self.force)

    def body_index(self, body: str) -> int:
        try:
            return self.bodies.index(body)
        except ValueError:
            raise MissingDataError(f"no external load on body {body!r}") from None

    def fext(self, model: Model, data: pin.Data, frame: int) -> pin.StdVec_Force:
        """Pinocchio ``fext`` of one frame (joint-local forces); needs ``data.oMi`` at that
        frame's configuration (``pin.forwardKinematics``)."""
        out = pin.StdVec_Force()
        out.extend([pin.Force.Zero() for _ in range(model.pin_model.njoints)])
        for b, body in enumerate(self.bodies):
            j = model.body_joint[body]
            if j == 0:
                continue
            f_w = pin.Force(self.force[frame, b], self.moment[frame, b])
            out[j] = out[j] + data.oMi[j].actInv(f_w)
        return out

    def total(self) -> tuple[Array, Array]:
        """Sum over bodies: force (N, 3) and moment about the world origin (N, 3)."""
        return self.force.sum(axis=1), self.moment.sum(axis=1)


_SAMPLES = 12  # frames per contact interval used to decide which foot stands on a plate


def _default_feet(model: Model) -> tuple[str, ...]:
    names = [b.name for b in model.bodies]
    for stem in ("calcn", "foot"):
        feet = [n for n in names if n.startswith(stem)]
        if len(feet) >= 1:
            return tuple(feet)
    raise ModelError(
        f"model {model.name}: cannot guess the feet (no body named calcn* or foot*); pass feet="
    )


def _horizontal_axes(up: Array) -> Array:
    a = np.eye(3)[int(np.argmin(np.abs(up)))]
    e1 = np.cross(up, a)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(up, e1)
    return np.stack([e1, e2])  # (2, 3)


def _inside_grown(points2: Array, poly2: Array, margin: float) -> Array:
    """Is each 2-D point (..., 2) inside the convex polygon grown by ``margin``?"""
    centre = poly2.mean(axis=0)
    ok = np.ones(points2.shape[:-1], dtype=bool)
    n = poly2.shape[0]
    for k in range(n):
        a, b = poly2[k], poly2[(k + 1) % n]
        edge = b - a
        normal = np.array([edge[1], -edge[0]]) / np.linalg.norm(edge)
        if (centre - a) @ normal > 0:
            normal = -normal  # outward
        ok &= (points2 - a) @ normal <= margin
    return ok


def _runs(mask: Array) -> list[tuple[int, int]]:
    """[start, end) index pairs of the True runs of a boolean vector."""
    d = np.diff(np.concatenate([[0], mask.astype(int), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _foot_points(model: Model, q: Array, feet: Sequence[str], frames: Array) -> list[Array]:
    """World points of each foot at the given frames: [(N, P_f, 3)] (NaN elsewhere).

    Points are the body origins of the foot and its descendants and their markers, computed
    from the placements of the few joints carrying them.
    """
    pm = model.pin_model
    data = pm.createData()
    specs = []
    for foot in feet:
        segs = model.subtree(foot)
        fids = [model.body_frame[s] for s in segs]
        fids += [model.marker_frame[mk.name] for mk in model.markers if mk.body in segs]
        parents = [pm.frames[f].parentJoint for f in fids]
        joints = sorted(set(parents))
        which = np.array([joints.index(j) for j in parents])
        local = np.array([pm.frames[f].placement.translation for f in fids])
        specs.append((joints, which, local))
    all_joints = sorted({j for sp in specs for j in sp[0]})
    out = [np.full((q.shape[0], sp[2].shape[0], 3), np.nan) for sp in specs]
    good = frames[np.isfinite(q[frames]).all(axis=1)]
    if good.size == 0:
        return out
    qpin = model.coupling.q(q[good])
    h = np.empty((good.size, len(all_joints), 4, 4))
    for i in range(good.size):
        pin.forwardKinematics(pm, data, qpin[i])
        h[i] = [data.oMi[j].homogeneous for j in all_joints]
    for f, (joints, which, local) in enumerate(specs):
        hj = h[:, [all_joints.index(j) for j in joints]][:, which]  # (K, P, 4, 4)
        out[f][good] = np.einsum("kpij,pj->kpi", hj[..., :3, :3], local) + hj[..., :3, 3]
    return out


def external_loads(
    model: Model,
    kinematics: Any,
    plates: Sequence[PlateWrench],
    *,
    feet: Sequence[str] | None = None,
    assignment: Mapping[str, str] | None = None,
    threshold_n: float = 20.0,
    margin_m: float = 0.05,
    cop_radius_m: float = 0.30,
    floor_m: float = 0.10,
    speed_mps: float = 1.0,
    sign: Literal["auto"] | float = "auto",
    cutoff_hz: float | None = None,
    extra: Sequence[AppliedForce] = (),
) -> ExternalLoads:
    """Assign plate wrenches to feet and bring them to the kinematics time.

    Args:
        model: the model (feet and markers are looked up in it).
        kinematics: a :class:`msk.kinematics.Kinematics` (``time``, ``q``).
        plates: the plates (:func:`plates_from_trial`, :func:`plates_from_table`).
        feet: bodies that can stand on a plate (default: bodies named ``calcn*`` or ``foot*``).
        assignment: plate name → body, to bypass the automatic assignment.
        threshold_n: vertical force above which a plate is in contact.
        margin_m: growth of the plate outline for the "foot on plate" test.
        cop_radius_m: largest COP–foot distance for plates without corners.
        floor_m: largest distance of a standing foot's point nearest the floor from the plate
            surface (along the vertical).
        speed_mps: speed of a foot's slowest point above which it is swinging (when another
            foot on the plate is slower and nearer the COP).
        sign: +1 / −1 multiplies the plate force and free moment; ``"auto"`` makes the vertical
            force positive up during contact.
        cutoff_hz: optional zero-lag low-pass of the plate wrench at its own rate.
        extra: other applied forces.

    Raises:
        ForcePlateError: a contact interval cannot be assigned (names plate and time).
    """
    t = np.asarray(kinematics.time, dtype=float)
    q = np.asarray(kinematics.q, dtype=float)
    n = t.size
    g = np.asarray(model.gravity, dtype=float)
    up = -g / np.linalg.norm(g) if np.linalg.norm(g) > 0 else np.array([0.0, 1.0, 0.0])
    feet = tuple(feet) if feet is not None else _default_feet(model)
    for f in feet:
        if f not in model.body_joint:
            raise ModelError(f"model {model.name}: no foot body {f!r}")
    bodies: list[str] = []
    force: list[Array] = []
    moment: list[Array] = []
    point_num: list[Array] = []  # Σ F_v c  (to average the COP by vertical force)
    point_den: list[Array] = []
    assigned: list[Assignment] = []

    def slot(body: str) -> int:
        if body not in bodies:
            if body not in model.body_joint:
                raise ModelError(f"model {model.name}: no body {body!r} for an external load")
            bodies.append(body)
            for lst in (force, moment, point_num):
                lst.append(np.zeros((n, 3)))
            point_den.append(np.zeros(n))
        return bodies.index(body)

    prepared = []
    for pl in plates:
        f_raw = np.asarray(pl.force, dtype=float)
        if f_raw.ndim != 2 or f_raw.shape[1] != 3 or f_raw.shape[0] != np.size(pl.time):
            raise ShapeMismatchError(
                f"{pl.name}: force {f_raw.shape} does not match time ({np.size(pl.time)},)"
            )
        fv_raw = np.nan_to_num(f_raw) @ up
        loaded_raw = np.abs(fv_raw) > threshold_n
        if sign == "auto":
            s = -1.0 if loaded_raw.any() and np.sum(fv_raw[loaded_raw]) < 0 else 1.0
        else:
            s = float(sign)
        f_pl = s * np.nan_to_num(f_raw)
        m_pl = (
            s * PlateWrench(pl.name, pl.time, f_raw, pl.cop, pl.free_moment).moment_about_origin()
        )
        f_pl[~loaded_raw] = 0.0
        m_pl[~loaded_raw] = 0.0
        ta = np.asarray(pl.time, dtype=float)
        if cutoff_hz is not None:
            rate = (ta.size - 1) / (ta[-1] - ta[0])
            f_pl = filtfilt_butter(f_pl, rate_hz=rate, cutoff_hz=cutoff_hz)
            m_pl = filtfilt_butter(m_pl, rate_hz=rate, cutoff_hz=cutoff_hz)
        f_k = np.nan_to_num(resample_to(ta, f_pl, t))
        m_k = np.nan_to_num(resample_to(ta, m_pl, t))
        fv = f_k @ up
        contact = fv > threshold_n
        # COP of the resampled wrench on the plate surface (height of the recorded COPs)
        cop_ok = np.isfinite(pl.cop).all(axis=1) & loaded_raw
        h = float(np.median(pl.cop[cop_ok] @ up)) if cop_ok.any() else 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            # c = h·up + (up × M_O_h)/F_v with M_O_h the moment about the point h·up
            m_h = m_k - np.cross(h * up, f_k)
            cop = h * up + np.cross(up, m_h) / fv[:, None]
        cop[~contact] = np.nan
        prepared.append((pl, f_k, m_k, fv, cop, h, _runs(contact)))

    # foot points, once, at the frames that decide the assignments
    sample: dict[tuple[int, int], Array] = {}
    for pl, *_, runs in prepared:
        if assignment is None or pl.name not in assignment:
            for i0, i1 in runs:
                n_s = min(_SAMPLES, i1 - i0)
                sample[(i0, i1)] = np.unique(np.linspace(i0, i1 - 1, n_s).round().astype(int))
    fpts: list[Array] = []
    if sample:
        at = np.concatenate(list(sample.values()))
        at = np.unique(np.clip(np.concatenate([at - 1, at, at + 1]), 0, n - 1))  # speeds too
        fpts = _foot_points(model, q, feet, at)
    crit = _Criteria(margin_m, cop_radius_m, floor_m, speed_mps)

    for pl, f_k, m_k, fv, cop, h, runs in prepared:
        for i0, i1 in runs:
            if assignment is not None and pl.name in assignment:
                body = assignment[pl.name]
            else:
                body = _assign(pl, feet, fpts, cop, h, sample[(i0, i1)], i0, i1, t, up, crit)
            b = slot(body)
            sl = slice(i0, i1)
            force[b][sl] += f_k[sl]
            moment[b][sl] += m_k[sl]
            point_num[b][sl] += fv[sl, None] * cop[sl]
            point_den[b][sl] += fv[sl]
            assigned.append(Assignment(pl.name, body, float(t[i0]), float(t[i1 - 1])))

    # extra applied forces
    data = model.create_data()
    for ex in extra:
        b = slot(ex.body)
        fe = np.asarray(ex.force, dtype=float)
        pe = np.asarray(ex.point, dtype=float)
        if fe.shape != (n, 3) or pe.shape != (n, 3):
            raise ShapeMismatchError(
                f"applied force on {ex.body}: force {fe.shape} and point {pe.shape} "
                f"must be ({n}, 3)"
            )
        if ex.point_in_body:
            fid = model.body_frame[ex.body]
            pw = np.full_like(pe, np.nan)
            good = np.flatnonzero(np.isfinite(q).all(axis=1))
            qpin = model.coupling.q(q[good]) if good.size else np.zeros((0, 0))
            for i, k in enumerate(good):
                pin.framesForwardKinematics(model.pin_model, data, qpin[i])
                pw[k] = data.oMf[fid].act(pe[k])
            pe = pw
        me = np.cross(pe, fe)
        if ex.moment is not None:
            me = me + np.asarray(ex.moment, dtype=float)
        force[b] += fe
        moment[b] += me
        mag = np.linalg.norm(fe, axis=1)
        point_num[b] += mag[:, None] * pe
        point_den[b] += mag

    nb = len(bodies)
    with np.errstate(divide="ignore", invalid="ignore"):
        point = (
            np.stack([pn / pd[:, None] for pn, pd in zip(point_num, point_den)], axis=1)
            if nb
            else np.zeros((n, 0, 3))
        )
    point[~np.isfinite(point)] = np.nan
    return ExternalLoads(
        time=t,
        bodies=tuple(bodies),
        force=np.stack(force, axis=1) if nb else np.zeros((n, 0, 3)),
        moment=np.stack(moment, axis=1) if nb else np.zeros((n, 0, 3)),
        point=point,
        assignments=tuple(assigned),
    )


def contact_measured(
    model: Model,
    kinematics: Any,
    loads: ExternalLoads,
    *,
    feet: Sequence[str] | None = None,
    threshold_n: float = 20.0,
    height_m: float = 0.08,
    speed_mps: float = 0.5,
) -> NDArray[np.bool_]:
    """(N,) bool: the frames whose ground contact is all measured — every foot on the ground
    carries a plate load.

    A foot is *on the ground* at frame i when its point nearest the floor is within
    ``height_m`` of the floor (the lowest point of any foot over the trial) and its slowest point
    moves slower than ``speed_mps`` (central differences); it *carries a plate load* when the
    vertical external force on it and its descendants (``loads``) exceeds ``threshold_n``.
    Foot points as for the plate assignment (module docstring). Frames with an unknown pose
    (NaN ``q``) are False.

    On the other frames a foot stands on the floor beside the plates (the steps before and after
    a walkway's plates): inverse dynamics misses its ground reaction, so the pelvis residuals,
    the identification equations and that leg's joint torques there measure nothing. The
    defaults were read on overground gait (Plug-in Gait BTKData, Grand Challenge PS): from heel
    strike to toe-off the lowest foot point is ≤ 6 cm above the floor and the slowest one moves
    at < 0.3 m/s; in swing it moves at > 1 m/s but in the last frame or two before heel strike
    (those, unloaded, count as unmeasured: conservative).
    """
    t = np.asarray(kinematics.time, dtype=float)
    q = np.asarray(kinematics.q, dtype=float)
    n = t.size
    known = np.isfinite(q).all(axis=1)
    if n < 3 or not known.any():
        return known
    g = np.asarray(model.gravity, dtype=float)
    up = -g / np.linalg.norm(g) if np.linalg.norm(g) > 0 else np.array([0.0, 1.0, 0.0])
    feet = tuple(feet) if feet is not None else _default_feet(model)
    pts = _foot_points(model, q, feet, np.arange(n))
    with warnings.catch_warnings():  # all-NaN frames (unknown pose): NaN, excluded below
        warnings.simplefilter("ignore", RuntimeWarning)
        low = np.stack([np.nanmin(p @ up, axis=1) for p in pts], axis=1)  # (N, F)
        speed = np.stack(
            [np.nanmin(np.linalg.norm(np.gradient(p, t, axis=0), axis=2), axis=1) for p in pts],
            axis=1,
        )
        floor = np.nanmin(low)
    grounded = (low - floor <= height_m) & (speed <= speed_mps)
    fv = np.zeros((n, len(feet)))
    for k, foot in enumerate(feet):
        for b in model.subtree(foot):
            if b in loads.bodies:
                fv[:, k] += np.asarray(loads.force[:, loads.bodies.index(b)]) @ up
    return known & ~(grounded & ~(fv > threshold_n)).any(axis=1)


@dataclass(frozen=True)
class _Criteria:
    """Thresholds of the "foot stands on the plate" test (module docstring)."""

    margin_m: float
    cop_radius_m: float
    floor_m: float
    speed_mps: float


def _foot_state(
    pts: Array, prev: Array, nxt: Array, dt: Array, poly2: Array, cop2: Array, h: float,
    up: Array, hz: Array, crit: _Criteria,
) -> tuple[Array, Array, Array]:  # fmt: skip
    """Per sampled frame, for one foot: on the plate (a point inside the grown outline and one
    within ``floor_m`` of the surface height), speed of its slowest point, floor-plane distance
    of its nearest point to the COP. ``pts``, ``prev``, ``nxt`` (K, P, 3) are the foot points at
    the frames and at their neighbours (``dt`` (K,) s apart)."""
    p2 = pts @ hz.T
    inside = _inside_grown(p2, poly2, crit.margin_m).any(axis=1)
    with np.errstate(invalid="ignore"):
        low = np.where(np.isfinite(pts).all(axis=2), np.abs(pts @ up - h), np.inf).min(axis=1)
        speed = np.linalg.norm(nxt - prev, axis=2) / dt[:, None]
        slow = np.where(np.isfinite(speed), speed, np.inf).min(axis=1)
        near = np.linalg.norm(p2 - cop2[:, None, :], axis=2)
        near = np.where(np.isfinite(near), near, np.inf).min(axis=1)
    return inside & (low <= crit.floor_m), slow, near


def _standing(on: Array, speed: Array, near: Array, speed_mps: float) -> Array:
    """(frames, feet): the feet ``on`` the plate, less the swinging ones — faster than
    ``speed_mps`` while another foot on the plate is both slower and nearer the COP."""
    out = on.copy()
    for a in range(on.shape[1]):
        for b in range(on.shape[1]):
            if a != b:
                beaten = on[:, b] & (speed[:, b] < speed[:, a]) & (near[:, b] < near[:, a])
                out[:, a] &= ~(beaten & (speed[:, a] > speed_mps))
    return out


def _assign(
    pl: PlateWrench,
    feet: Sequence[str],
    fpts: list[Array],
    cop: Array,
    h: float,
    frames: Array,
    i0: int,
    i1: int,
    t: Array,
    up: Array,
    crit: _Criteria,
) -> str:
    """The foot standing on plate ``pl`` during frames [i0, i1), judged on the foot points
    ``fpts`` ([(N, P, 3)], filled at ``frames`` and their neighbours) at ``frames`` (at most
    ``_SAMPLES`` of the interval); ``h`` is the height of the plate surface along ``up``."""
    span = f"{pl.name} contact {t[i0]:.3f}–{t[i1 - 1]:.3f} s"
    hz = _horizontal_axes(up)
    c2 = cop[frames] @ hz.T
    if pl.corners is not None:
        poly = np.asarray(pl.corners, dtype=float) @ hz.T
        k0 = np.clip(frames - 1, 0, t.size - 1)
        k1 = np.clip(frames + 1, 0, t.size - 1)
        dt = np.maximum(t[k1] - t[k0], 1e-12)
        state = [
            _foot_state(fp[frames], fp[k0], fp[k1], dt, poly, c2, h, up, hz, crit) for fp in fpts
        ]
        on = _standing(*(np.stack(x, axis=1) for x in zip(*state)), crit.speed_mps)
        frac = on.mean(axis=0)
        both = (on.sum(axis=1) >= 2).mean()
        if both > 0.5:
            names = [f for f, x in zip(feet, frac) if x > 0]
            raise ForcePlateError(
                f"{span}: both feet ({', '.join(names)}) stand on the plate at "
                f"t = {t[frames[int(np.argmax(on.sum(axis=1) >= 2))]]:.3f} s; cannot split its load"
            )
        best = int(np.argmax(frac))
        if frac[best] < 0.5:
            raise ForcePlateError(
                f"{span}: no foot over the plate at t = {t[i0]:.3f} s (best {feet[best]} on it "
                f"in {100 * frac[best]:.0f} % of the frames)"
            )
        return feet[best]
    # nearest point of each foot (feet may carry different numbers of points: reduce first)
    dist = np.stack(
        [
            np.where(np.isfinite(d), d, np.inf).min(axis=1)
            for d in (np.linalg.norm(fp[frames] @ hz.T - c2[:, None, :], axis=2) for fp in fpts)
        ],
        axis=1,
    )  # (frames, feet)
    usable = np.isfinite(dist).all(axis=1)
    med = np.median(dist[usable], axis=0) if usable.any() else np.full(len(feet), np.inf)
    best = int(np.argmin(med))
    radius = crit.cop_radius_m
    if not med[best] <= radius:
        raise ForcePlateError(
            f"{span}: no foot within {radius} m of the centre of pressure at t = {t[i0]:.3f} s "
            f"(nearest {feet[best]} at {med[best]:.3f} m)"
        )
    return feet[best]
