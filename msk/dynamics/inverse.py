"""Inverse dynamics on the embedded model, pelvis residuals and joint reaction forces.

Joint torques (Hayashibe et al. 2011, Eq. 1, RNEA on the Pinocchio tree, mapped to the independent
coordinates by virtual work)::

    τ_pin = RNEA(q, v, a, f_ext),   (q, v, a) = (g(θ), G θ̇, G θ̈ + Ġ θ̇)
    τ_θ   = Gᵀ τ_pin

so a coupled (spline or four-bar) knee gets one torque about its flexion coordinate. Variants:

``full``          the above;
``quasi_static``  v = a = 0, gravity and external loads only (the rehabilitation-robot lower-limb
model paper, §2.3, the SGM); ``geometric``     v = a = 0 and no gravity: the external loads alone.

**Pelvis residuals.** The root coordinates (the six pelvis DOFs) are unactuated, so their
generalised forces are the residuals (OpenSim's FX…MZ), and the residual wrench is the spatial
force the ground would have to transmit to the pelvis through the virtual root joint: RNEA's
``data.f`` of the first root joint, mapped to the world and reported about the pelvis origin.
With consistent kinematics, inertia and plates both vanish.

**Joint reaction.** RNEA's ``data.f[i]`` is the spatial force transmitted through joint i **from
the parent to the child** (the force the parent side exerts on the whole distal subtree),
including what the joint's actuator carries. :func:`joint_reaction` reports it in a chosen frame
(child joint frame, parent joint frame, world, or a body frame with an offset such as a tibial
plateau frame) as a force and a moment about that frame's origin. When muscle forces are given,
each muscle's tension is applied at its path points (on the bodies they are fixed to) as
external forces, so the transmitted wrench that remains is the bone-on-bone (contact + ligament)
load: the muscles spanning the joint no longer pass through it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import MissingDataError, ModelError, ShapeMismatchError
from msk.model.core import GROUND, Model
from msk.timeseries import FrameAxis
from msk.units import Array

__all__ = [
    "ID_BLOCK",
    "FrameInverseDynamics",
    "InverseDynamics",
    "JointReaction",
    "JointTorques",
    "Variant",
    "coordinates_carrying",
    "inverse_dynamics",
    "joint_reaction",
    "muscle_body_wrenches",
    "without_unmeasured_contact",
]

Variant = Literal["full", "quasi_static", "geometric"]


@dataclass(frozen=True)
class JointTorques(FrameAxis):
    """Generalised forces per independent coordinate (N·m or N), time on axis 0.

    Attributes:
        time: (N,) s.
        tau: (N, n_coords) τ_θ; columns ``coordinate_names`` (root coordinates = residuals).
        residual_force: (N, 3) N, world frame: force the ground must add to the pelvis.
        residual_moment: (N, 3) N·m, world frame, about ``residual_point``.
        residual_point: (N, 3) m, the pelvis (root body) origin in the world.
        root_coordinates: names of the residual columns of ``tau``.
        variant: ``full``, ``quasi_static`` or ``geometric``.
        tau_pin: (N, nv) τ on the Pinocchio DOFs before projection.
    """

    FRAME_FIELDS: ClassVar[tuple[str, ...]] = (
        "time",
        "tau",
        "residual_force",
        "residual_moment",
        "residual_point",
        "tau_pin",
    )

    time: Array
    tau: Array
    coordinate_names: tuple[str, ...]
    residual_force: Array
    residual_moment: Array
    residual_point: Array
    root_coordinates: tuple[str, ...]
    variant: str
    tau_pin: Array
    metadata: Mapping[str, Any] = field(default_factory=dict)

    def coordinate(self, name: str) -> Array:
        try:
            return self.tau[:, self.coordinate_names.index(name)]
        except ValueError:
            raise MissingDataError(f"joint torques have no coordinate {name!r}") from None

    @property
    def residuals(self) -> Array:
        """(N, k) generalised forces of the root coordinates."""
        return self.tau[:, [self.coordinate_names.index(c) for c in self.root_coordinates]]


@dataclass(frozen=True)
class JointReaction(FrameAxis):
    """Wrench transmitted through ``joint`` from its parent to its child (N, N·m), expressed in
    ``frame``: ``force`` (N, 3) and ``moment`` (N, 3) about the frame origin, frame axes."""

    FRAME_FIELDS: ClassVar[tuple[str, ...]] = (
        "time",
        "force",
        "moment",
    )

    time: Array
    joint: str
    frame: str
    force: Array
    moment: Array
    with_muscles: bool = False


def _root_info(model: Model) -> tuple[int, tuple[str, ...], str]:
    """First Pinocchio joint id of the root chain, root coordinate names and the root body."""
    if model.root_joint is None:
        raise ModelError(f"model {model.name}: no unique root joint (needed for residuals)")
    joint = next(j for j in model.joints if j.name == model.root_joint)
    name = f"{joint.name}_0" if len(joint.axes) > 1 else joint.name
    jid = model.pin_model.getJointId(name) if joint.axes else 0
    coords = tuple(dict.fromkeys(ax.coordinate for ax in joint.axes if ax.coordinate))
    return jid, coords, joint.child


def _chain_ids(model: Model, joint_name: str) -> tuple[int, int]:
    """First and last Pinocchio joint ids of an msk joint (its chain of 1-DOF axes)."""
    joint = next((j for j in model.joints if j.name == joint_name), None)
    if joint is None:
        raise ModelError(f"model {model.name}: no joint {joint_name!r}")
    if not joint.axes:
        raise ModelError(
            f"joint {joint_name} is a weld: its load is carried by the parent's joint; "
            "ask for a joint with at least one axis"
        )
    pm = model.pin_model
    if len(joint.axes) == 1:
        jid = pm.getJointId(joint.name)
        return jid, jid
    return pm.getJointId(f"{joint.name}_0"), pm.getJointId(f"{joint.name}_{len(joint.axes) - 1}")


def _states(
    model: Model, kinematics: Any, variant: str
) -> tuple[Array, Array, Array, Array, Array]:
    th = np.asarray(kinematics.q, dtype=float)
    names = tuple(kinematics.coordinate_names)
    if names != model.coordinate_names:
        raise ShapeMismatchError(
            f"kinematics columns {names[:4]}… do not match the model coordinates "
            f"{model.coordinate_names[:4]}…"
        )
    ok = np.isfinite(th).all(axis=1)
    if variant == "full":
        thd = np.asarray(kinematics.v, dtype=float)
        thdd = np.asarray(kinematics.a, dtype=float)
        ok &= np.isfinite(thd).all(axis=1) & np.isfinite(thdd).all(axis=1)
    else:
        thd = np.zeros_like(th)
        thdd = np.zeros_like(th)
    nq = model.pin_model.nq
    q = np.full((th.shape[0], nq), np.nan)
    v = np.zeros((th.shape[0], nq))
    a = np.zeros((th.shape[0], nq))
    if ok.any():
        q[ok], v[ok], a[ok] = model.coupling.embed(th[ok], thd[ok], thdd[ok])
    return th, q, v, a, ok


def _pin_model(model: Model, variant: str) -> pin.Model:
    if variant not in ("full", "quasi_static", "geometric"):
        raise ModelError(f"unknown inverse-dynamics variant {variant!r}")
    if variant != "geometric":
        return model.pin_model
    pm = pin.Model(model.pin_model)
    pm.gravity = pin.Motion.Zero()
    return pm


def _check_loads(loads: Any, time: Array) -> None:
    if loads is None:
        return
    n = time.size
    if np.asarray(loads.force).shape[0] != n:
        raise ShapeMismatchError(
            f"external loads have {np.asarray(loads.force).shape[0]} frames, kinematics {n}"
        )
    lt = np.asarray(loads.time, dtype=float)
    if lt.shape != time.shape or not np.allclose(lt, time, atol=1e-9):
        raise ShapeMismatchError("external loads are not on the kinematics time")


def _body_wrenches(
    model: Model,
    loads: Any,
    muscle_w: tuple[list[str], Array, Array] | None,
) -> tuple[list[int], Array, Array]:
    """Per loaded Pinocchio joint: world force and moment about the origin, (N, J, 3) each."""
    joints: list[int] = []
    fs: list[Array] = []
    ms: list[Array] = []

    def add(body: str, f: Array, m: Array) -> None:
        j = model.body_joint[body]
        if j == 0:
            return
        if j in joints:
            k = joints.index(j)
            fs[k] = fs[k] + f
            ms[k] = ms[k] + m
        else:
            joints.append(j)
            fs.append(np.asarray(f, dtype=float))
            ms.append(np.asarray(m, dtype=float))

    if loads is not None:
        for b, body in enumerate(loads.bodies):
            add(body, loads.force[:, b], loads.moment[:, b])
    if muscle_w is not None:
        for b, body in enumerate(muscle_w[0]):
            add(body, muscle_w[1][:, b], muscle_w[2][:, b])
    if not joints:
        return [], np.zeros((0, 0, 3)), np.zeros((0, 0, 3))
    return joints, np.stack(fs, axis=1), np.stack(ms, axis=1)


def _run_rnea(
    model: Model,
    pm: pin.Model,
    q: Array,
    v: Array,
    a: Array,
    ok: Array,
    loads: Any,
    *,
    muscle_w: tuple[list[str], Array, Array] | None = None,
    keep: Sequence[int] = (),
    need_jacobian: bool = False,
    origin: tuple[int, Array] | None = None,
) -> tuple[Array, dict[int, Array], dict[int, Array], Array | None, Array | None]:
    """RNEA per frame; returns τ_pin (N, nv), for joints in ``keep`` the transmitted force
    mapped to the world ((N, 6): force, moment about the world origin) and the joint placement
    ((N, 4, 4)), the world joint Jacobians (N, 6, nv) when computed, and the world position of
    the point ``origin = (joint, point in the joint frame)`` (N, 3) when asked.

    External wrenches are not passed to RNEA frame by frame: with the world-frame joint
    Jacobian J (``computeJointJacobians``, same pass as the forward kinematics) their
    generalised force is Σ_b (J masked to the DOFs supporting b)ᵀ f_b, and a transmitted
    force of joint j loses the external wrenches of the bodies in j's subtree — both applied
    to all frames at once after the loop (identical to ``rnea(..., fext)``).
    """
    n = q.shape[0]
    data = pm.createData()
    nv = pm.nv
    tau = np.full((n, nv), np.nan)
    f_keep = {j: np.full((n, 6), np.nan) for j in keep}
    m_keep = {j: np.full((n, 4, 4), np.nan) for j in keep}
    lj, lf, lm = _body_wrenches(model, loads, muscle_w)
    has_ext = bool(lj)
    with_jac = has_ext or need_jacobian
    jac = np.full((n, 6, nv), np.nan) if with_jac else None
    org = np.full((n, 3), np.nan) if origin is not None else None
    idx = np.flatnonzero(ok)
    omi = data.oMi  # live view of the joint placements
    for k in idx:
        qk = q[k]
        if with_jac:
            pin.computeJointJacobians(pm, data, qk)
            jac[k] = data.J  # type: ignore[index]
        elif keep or origin is not None:
            pin.forwardKinematics(pm, data, qk)
        if origin is not None:
            org[k] = omi[origin[0]].act(origin[1])  # type: ignore[index]
        tau[k] = pin.rnea(pm, data, qk, v[k], a[k])
        for j in keep:
            fw = data.oMi[j].act(data.f[j])
            f_keep[j][k, :3] = fw.linear
            f_keep[j][k, 3:] = fw.angular
            m_keep[j][k] = data.oMi[j].homogeneous
    if has_ext and idx.size:
        wrench = np.concatenate([lf, lm], axis=2)[idx]  # (K, J, 6) world, about the origin
        for i, j in enumerate(lj):
            support = [pm.joints[s].idx_v for s in pm.supports[j] if s > 0]
            gen = np.einsum("kdv,kd->kv", jac[idx][:, :, support], wrench[:, i])  # type: ignore[index]
            tau[idx[:, None], support] -= gen
            for jk in keep:
                if jk in pm.supports[j]:
                    f_keep[jk][idx] -= wrench[:, i]
    return tau, f_keep, m_keep, jac, org


class FrameInverseDynamics:
    """Joint torques τ_θ of one frame at a time (a stream: :mod:`msk.live`), the computation of
    :func:`inverse_dynamics` (variant ``"full"``; module docstring) with what does not change
    from frame to frame set up once: the Pinocchio data, the loaded bodies' joints and the DOFs
    supporting each. Per frame: (q, v, a) = (g(θ), Gθ̇, Gθ̈ + Ġθ̇), one
    ``computeJointJacobians`` and one ``rnea``, the external wrenches' generalised force
    Σ_b (J masked to the DOFs supporting b)ᵀ f_b subtracted, τ_θ = Gᵀ τ_pin — the numbers of
    :func:`inverse_dynamics` for that frame (the same operations in the same order).

    Args:
        model: the model (its inertias as they are).
        bodies: the bodies external wrenches are applied to, in the order of the ``force`` and
            ``moment`` rows given to :meth:`torques` (world frame, moment about the origin).
    """

    def __init__(self, model: Model, bodies: Sequence[str] = ()) -> None:
        from msk.kinematics.ik import _CouplingEvaluator

        self.model = model
        self.coupling = _CouplingEvaluator(model)
        self.pm = model.pin_model
        self.data = self.pm.createData()
        self.bodies = tuple(bodies)
        self._loaded: list[tuple[int, list[int], list[int]]] = []
        by_joint: dict[int, list[int]] = {}
        for b, body in enumerate(self.bodies):
            j = model.body_joint[body]
            if j != 0:
                by_joint.setdefault(j, []).append(b)
        for j, rows in by_joint.items():
            support = [self.pm.joints[s].idx_v for s in self.pm.supports[j] if s > 0]
            self._loaded.append((j, rows, support))
        self._w = np.empty(6)
        self.tau = np.empty(model.n_coords)

    def torques(
        self, theta: Array, theta_dot: Array, theta_ddot: Array, force: Array, moment: Array
    ) -> Array:
        """τ_θ (n_coords,) of the frame (θ, θ̇, θ̈), with the wrenches ``force``, ``moment``
        (B, 3) on :attr:`bodies`. The returned array is this object's buffer, overwritten by the
        next call."""
        cp = self.coupling
        q = cp.q(theta)
        g = cp.jacobian(theta)
        v = g @ theta_dot
        a = g @ theta_ddot + cp.bias(theta, theta_dot)
        pm, data = self.pm, self.data
        if self._loaded:
            pin.computeJointJacobians(pm, data, q)
        tau = pin.rnea(pm, data, q, v, a)
        w = self._w
        for _, rows, support in self._loaded:
            w[:3] = force[rows[0]]
            w[3:] = moment[rows[0]]
            for r in rows[1:]:
                w[:3] += force[r]
                w[3:] += moment[r]
            tau[support] -= data.J[:, support].T @ w
        np.dot(g.T, tau, out=self.tau)
        return self.tau


#: frames per block of a longer trial's inverse dynamics: its per-frame states,
#: world Jacobians and coupling Jacobians (~8 kB/frame on gait2392) are never held whole
ID_BLOCK = 4096


def inverse_dynamics(
    model: Model,
    kinematics: Any,
    loads: Any = None,
    *,
    variant: Variant = "full",
) -> JointTorques:
    """Joint torques τ_θ and pelvis residuals (see the module docstring).

    Args:
        model: the model (its inertias are used as they are).
        kinematics: :class:`msk.kinematics.ik.Kinematics` (``time``, ``q``, ``v``, ``a``, names).
        loads: :class:`msk.dynamics.loads.ExternalLoads` on the same time, or ``None``.
        variant: ``"full"``, ``"quasi_static"`` or ``"geometric"``.

    Returns:
        :class:`JointTorques`; frames whose kinematics are NaN are NaN. A trial longer than
        :data:`ID_BLOCK` frames is computed block by block (every frame's torques are computed
        alone, so the blocks give the one-pass result).
    """
    n = int(np.size(kinematics.time))
    if n <= ID_BLOCK:
        return _inverse_dynamics(model, kinematics, loads, variant=variant)
    parts = []
    for c0 in range(0, n, ID_BLOCK):
        fr = np.arange(c0, min(c0 + ID_BLOCK, n))
        part = None if loads is None else loads.take(fr)
        parts.append(_inverse_dynamics(model, kinematics.take(fr), part, variant=variant))
    joined: dict[str, Any] = {
        f: np.concatenate([getattr(p, f) for p in parts])
        for f in JointTorques.FRAME_FIELDS
        if getattr(parts[0], f) is not None
    }
    return dataclasses.replace(parts[0], **joined)


def _inverse_dynamics(
    model: Model, kinematics: Any, loads: Any, *, variant: Variant
) -> JointTorques:
    """:func:`inverse_dynamics` of one block of frames."""
    pm = _pin_model(model, variant)
    th, q, v, a, ok = _states(model, kinematics, variant)
    _check_loads(loads, np.asarray(kinematics.time, dtype=float))
    root_jid, root_coords, root_body = _root_info(model)
    last = model.body_joint[root_body]
    bp = model.body_placement[root_body].translation
    rd = model.root_dofs()
    if rd.size == 6:
        # τ_root = J_rootᵀ W: the six root DOFs' world Jacobian columns give the residual wrench
        # W (world, about the origin) from the root generalised forces, with no per-frame work
        tau_pin, _, _, jac, p = _run_rnea(
            model, pm, q, v, a, ok, loads, need_jacobian=True, origin=(last, bp)
        )
        fw = np.full((th.shape[0], 6), np.nan)
        if ok.any():
            j_root = jac[ok][:, :, rd]  # type: ignore[index]
            fw[ok] = np.linalg.solve(np.swapaxes(j_root, 1, 2), tau_pin[ok][:, rd, None])[..., 0]
    else:
        tau_pin, f_keep, _, _, p = _run_rnea(
            model, pm, q, v, a, ok, loads, keep=(root_jid,), origin=(last, bp)
        )
        fw = f_keep[root_jid]
    tau = np.full((th.shape[0], model.n_coords), np.nan)
    if ok.any():
        tau[ok] = model.coupling.project(th[ok], tau_pin[ok])
    assert p is not None  # _run_rnea returns the point when ``origin`` is given
    # moment about the pelvis origin (the root body's frame origin)
    moment = fw[:, 3:] - np.cross(p, fw[:, :3])
    return JointTorques(
        time=np.asarray(kinematics.time, dtype=float),
        tau=tau,
        coordinate_names=model.coordinate_names,
        residual_force=fw[:, :3],
        residual_moment=moment,
        residual_point=p,
        root_coordinates=root_coords,
        variant=variant,
        tau_pin=tau_pin,
    )


def muscle_body_wrenches(
    model: Model,
    q: ArrayLike,
    muscle_forces: ArrayLike,
    muscle_paths: Sequence[Sequence[tuple[str, ArrayLike]]],
) -> tuple[list[str], Array, Array]:
    """World wrenches that muscle tensions apply to the bodies.

    ``muscle_paths[i]`` is muscle i's path, origin to insertion, as ``(body, point in body)``
    pairs; ``q`` (N, n_coords); ``muscle_forces`` (N, K) tensions ≥ 0 (N). At each path point the
    muscle pulls towards its neighbours along the path: point k receives
    F_i (u_{k→k+1} + u_{k→k−1}) (one term at the ends). Returns the bodies and, per body, the
    force (N, B, 3) and moment about the world origin (N, B, 3).
    """
    th = np.asarray(q, dtype=float)
    f = np.asarray(muscle_forces, dtype=float)
    if f.shape != (th.shape[0], len(muscle_paths)):
        raise ShapeMismatchError(
            f"muscle forces {f.shape} must be (frames {th.shape[0]}, muscles {len(muscle_paths)})"
        )
    bodies: list[str] = []
    # per muscle: body index per point, local points
    pts: list[tuple[NDArray[np.intp], Array]] = []
    for path in muscle_paths:
        if len(path) < 2:
            raise ModelError("a muscle path needs at least two points")
        body_idx: list[int] = []
        for body, _ in path:
            if body not in model.body_frame:
                raise ModelError(f"model {model.name}: muscle path on unknown body {body!r}")
            if body not in bodies:
                bodies.append(body)
            body_idx.append(bodies.index(body))
        loc = np.array([np.asarray(p, dtype=float) for _, p in path])
        pts.append((np.asarray(body_idx, dtype=np.intp), loc))
    n = th.shape[0]
    fb = np.zeros((n, len(bodies), 3))
    mb = np.zeros((n, len(bodies), 3))
    data = model.create_data()
    fids = [model.body_frame[b] for b in bodies]
    good = np.isfinite(th).all(axis=1)
    fb[~good] = np.nan
    mb[~good] = np.nan
    qpin = model.coupling.q(np.where(good[:, None], th, 0.0))
    for k in np.flatnonzero(good):
        pin.framesForwardKinematics(model.pin_model, data, qpin[k])
        rot = np.array([data.oMf[i].rotation for i in fids])
        trans = np.array([data.oMf[i].translation for i in fids])
        for m, (idx, loc) in enumerate(pts):
            w = np.einsum("pij,pj->pi", rot[idx], loc) + trans[idx]  # (P, 3)
            seg = np.diff(w, axis=0)
            u = seg / np.linalg.norm(seg, axis=1)[:, None]
            pf = np.zeros_like(w)
            pf[:-1] += u
            pf[1:] -= u
            pf *= f[k, m]
            np.add.at(fb[k], idx, pf)
            np.add.at(mb[k], idx, np.cross(w, pf))
    return bodies, fb, mb


def joint_reaction(
    model: Model,
    kinematics: Any,
    loads: Any = None,
    *,
    joint: str,
    frame: str = "child",
    offset: pin.SE3 | None = None,
    muscle_forces: ArrayLike | None = None,
    muscle_paths: Sequence[Sequence[tuple[str, ArrayLike]]] | None = None,
    variant: Variant = "full",
) -> JointReaction:
    """Wrench transmitted through ``joint`` from parent to child, per frame.

    Args:
        joint: an msk joint name (e.g. ``"knee_r"``); its whole chain of axes counts as one
            joint (the wrench enters at the first axis).
        frame: ``"child"`` (the joint frame fixed in the child body), ``"parent"`` (the joint
            frame fixed in the parent body), ``"world"``, or a body name (its body frame).
        offset: an extra placement of the reporting frame relative to ``frame`` (e.g. a tibial
            plateau frame in the tibia body).
        muscle_forces, muscle_paths: tensions (N, K) and paths (see
            :func:`muscle_body_wrenches`); then the result is the bone-on-bone load.
        variant: as :func:`inverse_dynamics`.

    Sign convention: the force and moment are those the **parent side exerts on the child
    side** (OpenSim JointReaction "on child"), moment about the reporting frame's origin,
    components in the reporting frame's axes.
    """
    pm = _pin_model(model, variant)
    th, q, v, a, ok = _states(model, kinematics, variant)
    _check_loads(loads, np.asarray(kinematics.time, dtype=float))
    j0, j1 = _chain_ids(model, joint)
    mw = None
    if muscle_forces is not None:
        if muscle_paths is None:
            raise ModelError("muscle_forces given without muscle_paths")
        mw = muscle_body_wrenches(model, th, muscle_forces, muscle_paths)
    keep = (j0, j1)
    _, f_keep, m_keep, _, _ = _run_rnea(model, pm, q, v, a, ok, loads, muscle_w=mw, keep=keep)
    fw = f_keep[j0]  # world force, moment about the world origin
    spec = next(j for j in model.joints if j.name == joint)
    if frame == "child":
        place = m_keep[j1]
    elif frame == "world":
        place = np.broadcast_to(np.eye(4), (th.shape[0], 4, 4)).copy()
    else:
        body = spec.parent if frame == "parent" else frame
        if body not in model.body_frame:
            raise ModelError(f"model {model.name}: no body or frame {frame!r}")
        extra = spec.parent_offset if frame == "parent" else pin.SE3.Identity()
        place = np.full((th.shape[0], 4, 4), np.nan)
        data = model.create_data()
        fid = model.body_frame[body]
        for k in np.flatnonzero(ok):
            if body == GROUND:
                place[k] = extra.homogeneous
                continue
            pin.framesForwardKinematics(model.pin_model, data, q[k])
            place[k] = (data.oMf[fid] * extra).homogeneous
    if offset is not None:
        place = place @ offset.homogeneous
    rot = place[:, :3, :3]
    origin = place[:, :3, 3]
    m_o = fw[:, 3:] - np.cross(origin, fw[:, :3])
    force = np.einsum("nji,nj->ni", rot, fw[:, :3])
    moment = np.einsum("nji,nj->ni", rot, m_o)
    return JointReaction(
        time=np.asarray(kinematics.time, dtype=float),
        joint=joint,
        frame=frame if offset is None else f"{frame}+offset",
        force=force,
        moment=moment,
        with_muscles=mw is not None,
    )


def coordinates_carrying(model: Model, body: str) -> tuple[str, ...]:
    """The coordinates whose generalised force carries a load applied to ``body``: those of the
    joints between ``body`` and the root (a coordinate moves ``body`` when perturbed; measured at
    the model's default pose, a small rotation or translation of each coordinate in turn)."""
    data = model.create_data()
    th0 = model.default_coordinates().astype(float)
    fid = model.body_frame[body]
    pin.framesForwardKinematics(model.pin_model, data, model.coupling.q(th0))
    ref = pin.SE3(data.oMf[fid])
    out = []
    for i, c in enumerate(model.coordinate_names):
        th = th0.copy()
        th[i] += 1e-4
        pin.framesForwardKinematics(model.pin_model, data, model.coupling.q(th))
        if np.linalg.norm(pin.log6(ref.actInv(data.oMf[fid])).vector) > 1e-9:
            out.append(c)
    return tuple(out)


def without_unmeasured_contact(
    model: Model,
    torques: JointTorques,
    unmeasured: NDArray[np.bool_],
    feet: Sequence[str],
) -> JointTorques:
    """``torques`` with NaN where a foot's ground reaction is missing: at frame i, every
    non-root coordinate between a foot with ``unmeasured[i, k]`` and the pelvis
    (:func:`coordinates_carrying`). RNEA's torque at a joint balances the loads on its distal
    subtree (Featherstone 2008, §5.3), so a missing reaction on a foot falsifies the torques of
    that leg's joints only; the other leg's, the trunk's and the pelvis residuals (the measure of
    the missing load) are kept."""
    tau = np.array(torques.tau, dtype=float, copy=True)
    miss = np.asarray(unmeasured, dtype=bool)
    if miss.shape != (tau.shape[0], len(feet)):
        raise ShapeMismatchError(
            f"unmeasured {miss.shape} for {tau.shape[0]} frames × {len(feet)} feet"
        )
    names = list(torques.coordinate_names)
    for k, foot in enumerate(feet):
        if not miss[:, k].any():
            continue
        carry = coordinates_carrying(model, foot)
        cols = np.array(
            [names.index(c) for c in carry if c in names and c not in torques.root_coordinates],
            dtype=int,
        )
        tau[np.ix_(miss[:, k], cols)] = np.nan
    return dataclasses.replace(torques, tau=tau)


@dataclass(frozen=True)
class InverseDynamics:
    """:class:`msk.dynamics.inverse.JointTorques` of the generic model and of the identified one
    (``None`` without mass identification)."""

    generic: Any
    identified: Any = None

    @property
    def torques(self) -> Any:
        """The torques the muscles must produce: identified where available, else generic."""
        return self.generic if self.identified is None else self.identified
