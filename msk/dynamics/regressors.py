"""Inertial-parameter regressors of the embedded model: joint torques and base-link equations.

The inverse dynamics of a rigid multibody system is linear in the standard inertial parameters
φ (10 per body, :data:`msk.model.core.INERTIAL_PARAMETER_NAMES`, each body's parameters in its own
body frame; Hayashibe et al. 2011, Eq. 1)::

    τ_θ = Gᵀ (M(q) a + b(q, v)) − Gᵀ Jᵀ f_ext = Y_θ(θ, θ̇, θ̈) φ − τ_ext

The first rows — the generalised forces of the floating-base (pelvis) coordinates, which no
actuator drives — give the **base-link equations** (Hayashibe et al. 2011, Eq. 2)::

    Y_root(θ, θ̇, θ̈) φ = τ_ext,root

which identify φ from motion capture and force plates without any joint torque.

Pinocchio's ``computeJointTorqueRegressor`` gives Y per *joint* (parameters in the joint frame
of each 1-DOF Pinocchio joint); msk bodies are attached to their last joint with a fixed
placement X_b, so the body columns are Y_joint · A(X_b), with A the linear map of inertial
parameters under a rigid displacement (:func:`parameter_transform`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import IdentificationError
from msk.model.core import INERTIAL_PARAMETER_NAMES, Model
from msk.units import Array

__all__ = [
    "BaseParameters",
    "RegressorLayout",
    "SpatialKinematics",
    "base_link_regressor",
    "base_parameters",
    "external_generalized_forces",
    "joint_torque_regressor",
    "parameter_transform",
    "regressor_layout",
    "root_coordinate_indices",
    "spatial_kinematics",
]


def _skew(x: Array) -> Array:
    return np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])


def _sym_to_vec(s: Array) -> Array:
    return np.array([s[0, 0], s[0, 1], s[1, 1], s[0, 2], s[1, 2], s[2, 2]])


def _vec_to_sym(v: Array) -> Array:
    return np.array([[v[0], v[1], v[3]], [v[1], v[2], v[4]], [v[3], v[4], v[5]]])


def parameter_transform(placement: pin.SE3) -> Array:
    """A (10×10) with φ_parent = A φ_child for a body frame placed at ``placement`` (R, p).

    m' = m, h' = R h + m p, and, with inertias about the frame origins and S(x)ᵀS(x) = xᵀx·1 − x xᵀ:
    I' = R I Rᵀ + m S(p)ᵀS(p) + S(R h)ᵀS(p) + S(p)ᵀS(R h).
    """
    r, p = placement.rotation, placement.translation
    sp = _skew(p)
    a = np.zeros((10, 10))
    for k in range(10):
        e = np.zeros(10)
        e[k] = 1.0
        m, h, inertia = e[0], e[1:4], _vec_to_sym(e[4:])
        rh = r @ h
        srh = _skew(rh)
        new_i = r @ inertia @ r.T + m * sp.T @ sp + srh.T @ sp + sp.T @ srh
        a[:, k] = np.concatenate([[m], rh + m * p, _sym_to_vec(new_i)])
    return a


@dataclass(frozen=True)
class RegressorLayout:
    """Which columns of the Pinocchio joint regressor each body uses (precomputed per model)."""

    body_names: tuple[str, ...]
    joint_ids: tuple[int, ...]
    transforms: Array  # (n_bodies, 10, 10)

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(f"{b}.{p}" for b in self.body_names for p in INERTIAL_PARAMETER_NAMES)

    def parameters(self, model: Model) -> Array:
        """φ of ``model`` in layout order (n_bodies·10,)."""
        return np.concatenate([model.body(b).parameters() for b in self.body_names])


def regressor_layout(model: Model, bodies: Sequence[str] | None = None) -> RegressorLayout:
    """Layout of the body-parameter regressor (all bodies of the model by default)."""
    names = tuple(bodies) if bodies is not None else tuple(b.name for b in model.bodies)
    for n in names:
        model.body(n)  # raises ModelError naming the body
    return RegressorLayout(
        body_names=names,
        joint_ids=tuple(model.body_joint[n] for n in names),
        transforms=np.stack([parameter_transform(model.body_placement[n]) for n in names]),
    )


def _coordinates(
    model: Model, theta: ArrayLike, theta_dot: ArrayLike, theta_ddot: ArrayLike
) -> tuple[Array, Array, Array]:
    """θ, θ̇, θ̈ as ``(N, n_coords)`` arrays (one frame: N = 1), else an error."""
    th = np.atleast_2d(np.asarray(theta, dtype=float))
    thd = np.atleast_2d(np.asarray(theta_dot, dtype=float))
    thdd = np.atleast_2d(np.asarray(theta_ddot, dtype=float))
    if not (th.shape == thd.shape == thdd.shape) or th.shape[1] != model.n_coords:
        raise IdentificationError(
            f"θ, θ̇, θ̈ must all be (N, {model.n_coords}); got {th.shape}, {thd.shape}, {thdd.shape}"
        )
    return th, thd, thdd


def _states(
    model: Model, theta: ArrayLike, theta_dot: ArrayLike, theta_ddot: ArrayLike
) -> tuple[Array, Array, Array, Array, Array]:
    th, thd, thdd = _coordinates(model, theta, theta_dot, theta_ddot)
    q, v, a = model.coupling.embed(th, thd, thdd)
    return th, q, v, a, model.coupling.jacobian(th)


def joint_torque_regressor(
    model: Model,
    theta: ArrayLike,
    theta_dot: ArrayLike,
    theta_ddot: ArrayLike,
    *,
    layout: RegressorLayout | None = None,
    rows: ArrayLike | None = None,
    method: Literal["vectorized", "pinocchio"] = "vectorized",
) -> Array:
    """Y_θ (N, n_rows, 10·n_bodies) with τ_θ = Y_θ φ (no external forces; gravity included).

    ``rows`` selects coordinates (indices into ``model.coordinates``); default all.

    ``method="vectorized"`` (default) evaluates all frames at once: forward kinematics vectorised
    over frames (:func:`spatial_kinematics`), each body's regressor Y_b(v_b, a_b) (Pinocchio's
    ``bodyRegressor``) and τ_i = Σ_k G_ki S_kᵀ Σ_{b in subtree(k)} ᵒX_b* Y_b φ_b, with one Python
    loop over bodies, none over frames. ``method="pinocchio"`` calls
    ``computeJointTorqueRegressor`` frame by frame (the independent reference).
    """
    layout = layout or regressor_layout(model)
    sel = np.arange(model.n_coords) if rows is None else np.asarray(rows, dtype=int)
    if method == "vectorized":
        q, v, a, d1 = _embed_diagonal(model, theta, theta_dot, theta_ddot)
        return _vectorised_regressor(model, q, v, a, d1, layout, sel)
    if method != "pinocchio":
        raise IdentificationError(f"unknown regressor method {method!r}")
    th, q, v, a, g = _states(model, theta, theta_dot, theta_ddot)
    data = model.create_data()
    nb = len(layout.body_names)
    out = np.empty((th.shape[0], sel.size, 10 * nb))
    cols = [slice(10 * (j - 1), 10 * j) for j in layout.joint_ids]
    for n in range(th.shape[0]):
        y_pin = pin.computeJointTorqueRegressor(model.pin_model, data, q[n], v[n], a[n])
        y_theta = g[n][:, sel].T @ y_pin
        for b in range(nb):
            out[n, :, 10 * b : 10 * b + 10] = y_theta[:, cols[b]] @ layout.transforms[b]
    return out


def root_coordinate_indices(model: Model) -> Array:
    """Indices of the coordinates driving the root (pelvis) joint: the base-link rows."""
    if model.root_joint is None:
        raise IdentificationError(f"model {model.name}: no unique root joint")
    joint = next(j for j in model.joints if j.name == model.root_joint)
    names = [ax.coordinate for ax in joint.axes if ax.coordinate is not None]
    return np.array([model.coordinate_index(n) for n in dict.fromkeys(names)], dtype=int)


def base_link_regressor(
    model: Model,
    theta: ArrayLike,
    theta_dot: ArrayLike,
    theta_ddot: ArrayLike,
    *,
    layout: RegressorLayout | None = None,
    method: Literal["vectorized", "pinocchio"] = "vectorized",
) -> Array:
    """Y_root (N, 6, 10·n_bodies): the floating-base rows of :func:`joint_torque_regressor`."""
    return joint_torque_regressor(
        model,
        theta,
        theta_dot,
        theta_ddot,
        layout=layout,
        rows=root_coordinate_indices(model),
        method=method,
    )


def external_generalized_forces(model: Model, theta: ArrayLike, fext_local: ArrayLike) -> Array:
    """τ_ext = Gᵀ Σ_k J_kᵀ f_k (N, n_coords) from spatial forces per Pinocchio joint.

    ``fext_local`` is (N, njoints, 6) = [f, n] of each joint's external wrench expressed in the
    joint's local frame (Pinocchio ``fext`` convention; entry 0 is the universe and is ignored).
    """
    th = np.atleast_2d(np.asarray(theta, dtype=float))
    f = np.asarray(fext_local, dtype=float).reshape(th.shape[0], model.pin_model.njoints, 6)
    q = model.coupling.q(th)
    g = model.coupling.jacobian(th)
    data = model.create_data()
    out = np.empty_like(th)
    for n in range(th.shape[0]):
        pin.computeJointJacobians(model.pin_model, data, q[n])
        tau = np.zeros(model.pin_model.nv)
        for j in range(1, model.pin_model.njoints):
            if np.any(f[n, j]):
                jac = pin.getJointJacobian(model.pin_model, data, j, pin.ReferenceFrame.LOCAL)
                tau += jac.T @ f[n, j]
        out[n] = g[n].T @ tau
    return out


@dataclass(frozen=True)
class BaseParameters:
    """Base (identifiable) parameters β = φ_b + K φ_d of a regressor (QR with pivoting).

    Y φ = Y[:, independent] β for every state, with β = ``projection`` @ φ.
    """

    independent: Array  # column indices of φ kept as base parameters
    dependent: Array
    k: Array  # (n_base, n_dependent)
    projection: Array  # (n_base, n_params)
    names: tuple[str, ...]
    rank: int

    def beta(self, phi: ArrayLike) -> Array:
        return self.projection @ np.asarray(phi, dtype=float)


def base_parameters(
    stacked_regressor: ArrayLike, names: Sequence[str], *, rtol: float = 1e-8
) -> BaseParameters:
    """Base parameters from a regressor stacked over (random) states, by column-pivoted QR.

    ``stacked_regressor`` is (rows, n_params) (flatten frames × equations first).
    """
    from scipy.linalg import qr

    y = np.asarray(stacked_regressor, dtype=float)
    if y.ndim == 3:
        y = y.reshape(-1, y.shape[-1])
    scale = np.linalg.norm(y, axis=0)
    scale[scale == 0] = 1.0
    _, r, piv = qr(y / scale, mode="economic", pivoting=True)
    diag = np.abs(np.diag(r))
    if diag.size == 0 or diag[0] == 0:
        raise IdentificationError("regressor is identically zero: nothing is identifiable")
    rank = int(np.sum(diag > rtol * diag[0]))
    ind, dep = np.sort(piv[:rank]), np.sort(piv[rank:])
    # Y_d = Y_b K  (least squares, exact up to round-off for dependent columns)
    k, *_ = np.linalg.lstsq(y[:, ind], y[:, dep], rcond=None)
    proj = np.zeros((rank, y.shape[1]))
    proj[np.arange(rank), ind] = 1.0
    proj[:, dep] = k
    return BaseParameters(
        independent=ind,
        dependent=dep,
        k=k,
        projection=proj,
        names=tuple(names[i] for i in ind),
        rank=rank,
    )


# ------------------------------------------------------------------------------------------
# vectorised regressor (all frames at once, one Python loop over joints and bodies)
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SpatialKinematics:
    """World-frame kinematics of every Pinocchio joint over N frames (index 0: universe).

    ``rotation[j]`` (N, 3, 3) and ``translation[j]`` (N, 3) are oM_j; ``velocity[j]`` and
    ``acceleration[j]`` (N, 6) are spatial motions [linear; angular] expressed in the world frame
    *at the world origin* (Featherstone's ground-frame convention), the acceleration including
    −g as the acceleration of the universe; ``subspace[j]`` (N, 6) is the joint's motion
    subspace S_j in the same convention.
    """

    rotation: list[Array]
    translation: list[Array]
    velocity: list[Array]
    acceleration: list[Array]
    subspace: list[Array]


def _joint_axes(pm: pin.Model) -> list[tuple[str, Array]]:
    out: list[tuple[str, Array]] = [("U", np.zeros(3))]
    for j in range(1, pm.njoints):
        jm = pm.joints[j]
        jd = jm.createData()
        jm.calc(jd, np.zeros(pm.nq))
        s = np.asarray(jd.S).reshape(6)
        if np.linalg.norm(s[3:]) > 0.5:
            out.append(("R", s[3:] / np.linalg.norm(s[3:])))
        else:
            out.append(("P", s[:3] / np.linalg.norm(s[:3])))
    return out


def _cross(a: Array, b: Array) -> Array:
    """a × b over the last axis (broadcasting), without ``np.cross``'s overhead."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def _motion_cross(m1: Array, m2: Array) -> Array:
    """m1 × m2 for spatial motions [v; ω] (…, 6)."""
    v1, w1 = m1[..., :3], m1[..., 3:]
    v2, w2 = m2[..., :3], m2[..., 3:]
    return np.concatenate([_cross(w1, v2) + _cross(v1, w2), _cross(w1, w2)], axis=-1)


def spatial_kinematics(model: Model, q: ArrayLike, v: ArrayLike, a: ArrayLike) -> SpatialKinematics:
    """Forward kinematics (position, velocity, acceleration) of all joints for N frames at once.

    ``q, v, a`` are Pinocchio configurations (N, nq) (use ``model.coupling.embed``). The loop
    runs over joints; every operation is vectorised over frames (no per-frame Python work).
    """
    pm = model.pin_model
    q = np.atleast_2d(np.asarray(q, dtype=float))
    v = np.atleast_2d(np.asarray(v, dtype=float))
    a = np.atleast_2d(np.asarray(a, dtype=float))
    n = q.shape[0]
    rot = [np.broadcast_to(np.eye(3), (n, 3, 3))]
    trans = [np.zeros((n, 3))]
    vel = [np.zeros((n, 6))]
    acc0 = np.zeros((n, 6))
    acc0[:, :3] = -np.asarray(pm.gravity.linear)
    acc0[:, 3:] = -np.asarray(pm.gravity.angular)
    acc = [acc0]
    sub = [np.zeros((n, 6))]
    for j, (kind, u) in enumerate(_joint_axes(pm)):
        if j == 0:
            continue
        par = pm.parents[j]
        place = pm.jointPlacements[j]
        idx = pm.joints[j].idx_q
        qj, vj, aj = q[:, idx], v[:, idx], a[:, idx]
        r_pl = rot[par] @ place.rotation  # (N, 3, 3)
        p_pl = trans[par] + rot[par] @ place.translation
        w = r_pl @ u  # world axis (N, 3)
        s = np.zeros((n, 6))
        if kind == "R":
            c, sn = np.cos(qj), np.sin(qj)
            k = _skew(u)
            r_q = (
                np.eye(3)[None]
                + sn[:, None, None] * k[None]
                + (1.0 - c)[:, None, None] * (k @ k)[None]
            )
            rot.append(r_pl @ r_q)
            trans.append(p_pl)
            s[:, :3] = _cross(p_pl, w)
            s[:, 3:] = w
        else:
            rot.append(r_pl)
            trans.append(p_pl + w * qj[:, None])
            s[:, :3] = w
        sv = s * vj[:, None]
        vel_j = vel[par] + sv
        vel.append(vel_j)
        acc.append(acc[par] + s * aj[:, None] + _motion_cross(vel_j, sv))
        sub.append(s)
    return SpatialKinematics(rot, trans, vel, acc, sub)


def _body_regressor(vb: Array, ab: Array) -> Array:
    """Pinocchio ``bodyRegressor`` vectorised: Y (N, 6, 10) with f = I a + v ×* I v = Y φ for
    body-frame spatial velocity ``vb`` and acceleration ``ab`` (N, 6)."""
    n = vb.shape[0]
    v, w = vb[:, :3], vb[:, 3:]
    a, dw = ab[:, :3], ab[:, 3:]
    y = np.zeros((n, 6, 10))
    acc_lin = a + _cross(w, v)
    y[:, :3, 0] = acc_lin
    # f_lin = ([ω̇]× + [ω]×[ω]×) h
    wx, wy, wz = w[:, 0], w[:, 1], w[:, 2]
    dx, dy, dz = dw[:, 0], dw[:, 1], dw[:, 2]
    y[:, 0, 1] = -(wy * wy + wz * wz)
    y[:, 0, 2] = wx * wy - dz
    y[:, 0, 3] = wx * wz + dy
    y[:, 1, 1] = wx * wy + dz
    y[:, 1, 2] = -(wx * wx + wz * wz)
    y[:, 1, 3] = wy * wz - dx
    y[:, 2, 1] = wx * wz - dy
    y[:, 2, 2] = wy * wz + dx
    y[:, 2, 3] = -(wx * wx + wy * wy)
    # f_ang = −[a + ω × v]× h
    ax, ay, az = acc_lin[:, 0], acc_lin[:, 1], acc_lin[:, 2]
    y[:, 3, 2] = az
    y[:, 3, 3] = -ay
    y[:, 4, 1] = -az
    y[:, 4, 3] = ax
    y[:, 5, 1] = ay
    y[:, 5, 2] = -ax

    # f_ang += Ī ω̇ + ω × Ī ω, Ī = (xx, xy, yy, xz, yz, zz)
    def lmat(x: Array) -> Array:
        out = np.zeros((n, 3, 6))
        out[:, 0, 0], out[:, 0, 1], out[:, 0, 3] = x[:, 0], x[:, 1], x[:, 2]
        out[:, 1, 1], out[:, 1, 2], out[:, 1, 4] = x[:, 0], x[:, 1], x[:, 2]
        out[:, 2, 3], out[:, 2, 4], out[:, 2, 5] = x[:, 0], x[:, 1], x[:, 2]
        return out

    lw = lmat(w)
    y[:, 3:, 4:] = lmat(dw) + _cross(w[:, None, :], lw.transpose(0, 2, 1)).transpose(0, 2, 1)
    return y


def _to_body(m: Array, r_b: Array, p_b: Array) -> Array:
    """World-origin spatial motions m (N, 6) or (N, k, 6) → body frame (R_b, p_b): Rᵀ(v + ω × p_b),
    Rᵀω (row vectors times R_b: batched matmul, no einsum)."""
    m3 = m[:, None, :] if m.ndim == 2 else m
    w = m3[..., 3:]
    p = p_b[:, None, :]
    lin = m3[..., :3] + np.stack(
        [
            w[..., 1] * p[..., 2] - w[..., 2] * p[..., 1],
            w[..., 2] * p[..., 0] - w[..., 0] * p[..., 2],
            w[..., 0] * p[..., 1] - w[..., 1] * p[..., 0],
        ],
        axis=-1,
    )
    out = np.concatenate([lin @ r_b, w @ r_b], axis=-1)
    return out[:, 0, :] if m.ndim == 2 else out


def _embed_diagonal(
    model: Model, theta: ArrayLike, theta_dot: ArrayLike, theta_ddot: ArrayLike
) -> tuple[Array, Array, Array, Array]:
    """(q, v, a) and f_k'(θ) per Pinocchio DOF (N, nq): the embedding without the dense G."""
    th, thd, thdd = _coordinates(model, theta, theta_dot, theta_ddot)
    cp = model.coupling
    n = th.shape[0]
    q = np.empty((n, cp.nq))
    v = np.zeros((n, cp.nq))
    a = np.zeros((n, cp.nq))
    d1 = np.zeros((n, cp.nq))
    for k, (i, f) in enumerate(zip(cp.coordinate, cp.functions)):
        x = th[:, i] if i >= 0 else np.zeros(n)
        q[:, k] = f(x)
        if i < 0:
            continue
        d1[:, k] = f.d1(x)
        v[:, k] = d1[:, k] * thd[:, i]
        a[:, k] = d1[:, k] * thdd[:, i] + f.d2(x) * thd[:, i] ** 2
    return q, v, a, d1


def _vectorised_regressor(
    model: Model,
    q: Array,
    v: Array,
    a: Array,
    d1: Array,
    layout: RegressorLayout,
    sel: NDArray[np.intp],
) -> Array:
    """Rows ``sel`` of Y_θ for all frames: τ_i = Σ_k G_ki S_kᵀ Σ_{b ⪰ k} Y_b(v_b, a_b) φ_b."""
    pm = model.pin_model
    kin = spatial_kinematics(model, q, v, a)
    n = q.shape[0]
    nb = len(layout.body_names)
    out = np.zeros((n, sel.size, 10 * nb))
    coord_of_dof = np.asarray(model.coupling.coordinate)
    joint_of_dof = {pm.joints[j].idx_v: j for j in range(1, pm.njoints)}
    for b, name in enumerate(layout.body_names):
        jb = layout.joint_ids[b]
        if jb == 0:
            continue
        support = set(pm.supports[jb])
        # effective world motion subspace of each selected coordinate acting on this body
        s_eff = np.zeros((n, sel.size, 6))
        for r, i in enumerate(sel):
            for k in np.flatnonzero(coord_of_dof == i):
                j = joint_of_dof[int(k)]
                if j in support:
                    s_eff[:, r] += d1[:, k][:, None] * kin.subspace[j]
        if not np.any(s_eff):
            continue
        place = model.body_placement[name]
        r_b = kin.rotation[jb] @ place.rotation
        p_b = kin.translation[jb] + kin.rotation[jb] @ place.translation
        y_b = _body_regressor(
            _to_body(kin.velocity[jb], r_b, p_b), _to_body(kin.acceleration[jb], r_b, p_b)
        )
        out[:, :, 10 * b : 10 * b + 10] = _to_body(s_eff, r_b, p_b) @ y_b
    return out
