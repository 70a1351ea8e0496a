"""Fitting the crossed four-bar knee (the rehabilitation-robot lower-limb model paper, §2.1) to a
knee path.

Two sources of the path p(θ) of the tibia-frame origin in the femur joint frame:

* a model's spline knee (gait2392: the ``knee_angle`` translation splines of Delp et al. 1990 /
  Yamaguchi & Zajac 1989) — :func:`fit_four_bar_to_joint`;
* a functional-calibration trial: thigh and shank marker clusters moved through flexion
  (:func:`fit_four_bar_from_markers`): the shank pose relative to the thigh, T_rel(t) =
  T_thigh(t)⁻¹ T_shank(t) (cluster poses by the SVD / Kabsch fit of the cluster's local
  coordinates), projected on the sagittal plane gives θ(t) (rotation about the plane normal)
  and p(t) (tibia-frame origin).

Both reduce to the same nonlinear least squares (scipy ``least_squares``, trust-region
reflective with bounds) over x = (A, B, C, D, p_ref) ∈ ℝ¹⁰ with θ_ref fixed::

    min_x Σ_t ‖ p_4bar(θ_t; x) − p_t ‖²

where the link lengths L_AC, L_BD follow from the reference configuration (see
:class:`msk.model.joints.FourBarKnee`). Anatomical plausibility is imposed by bounds: the femur
attachments lie within 4 cm (antero-posterior) and −2…+5 cm (proximo-distal) of the mean knee
position, the tibia attachments within 4 cm of the tibia origin and −5…+2 cm vertically, and the
cruciates are crossed — the ACL runs from the posterior femur (A) to the anterior tibia (C), the
PCL from the anterior femur (B) to the posterior tibia (D): A_x ≤ B_x + 1 cm, C_x ≥ −1 cm ≥ D_x
(bounds), with link lengths ≥ 1.5 cm (penalty). Several starts are tried; the best is kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares

from msk.exceptions import IdentificationError, ModelError, ShapeMismatchError
from msk.model.core import Axis, Joint
from msk.model.joints import FourBarKnee, FourBarTranslation, Linear
from msk.personalise.functional_joints import segment_poses
from msk.units import Array

__all__ = [
    "FourBarFit",
    "cluster_pose",
    "fit_four_bar",
    "fit_four_bar_from_markers",
    "fit_four_bar_to_joint",
    "four_bar_joint",
    "knee_path_of_joint",
]

_MIN_LINK_M = 0.015


@dataclass(frozen=True)
class FourBarFit:
    """Result of a four-bar fit.

    ``knee`` the fitted linkage; ``theta`` (N,) the flexion angles used (rad) and ``target``
    (N, 2) the path fitted (m, femur joint frame x anterior, y proximal); ``residual`` (N, 2)
    fitted − target; ``rms_m`` the RMS of ‖residual‖; ``max_error_m`` its maximum;
    ``crossed`` whether the cruciates AC and BD cross at the reference configuration.
    """

    knee: FourBarKnee
    theta: Array
    target: Array
    residual: Array
    rms_m: float
    max_error_m: float
    crossed: bool


def _knee_from(x: Array, theta_ref: float) -> FourBarKnee:
    return FourBarKnee(
        (float(x[0]), float(x[1])),
        (float(x[2]), float(x[3])),
        (float(x[4]), float(x[5])),
        (float(x[6]), float(x[7])),
        float(theta_ref),
        (float(x[8]), float(x[9])),
    )


def _segments_cross(p1: Array, p2: Array, p3: Array, p4: Array) -> bool:
    def orient(a: Array, b: Array, c: Array) -> float:
        return float((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))

    return (
        orient(p1, p2, p3) * orient(p1, p2, p4) < 0 and orient(p3, p4, p1) * orient(p3, p4, p2) < 0
    )


def _crossing(knee: FourBarKnee) -> tuple[float, float]:
    """(s, t) with A + s(C − A) = B + t(D − B) at the reference configuration; the cruciates
    cross when both lie in (0, 1)."""
    c, sn = np.cos(knee.theta_ref), np.sin(knee.theta_ref)
    r = np.array([[c, -sn], [sn, c]])
    p = np.asarray(knee.p_ref)
    a, b = np.asarray(knee.femur_a), np.asarray(knee.femur_b)
    cf = p + r @ np.asarray(knee.tibia_c)
    df = p + r @ np.asarray(knee.tibia_d)
    m = np.column_stack([cf - a, -(df - b)])
    if abs(np.linalg.det(m)) < 1e-14:
        return -1.0, -1.0
    s, t = np.linalg.solve(m, b - a)
    return float(s), float(t)


def _crossed(knee: FourBarKnee) -> bool:
    c = np.cos(knee.theta_ref)
    s = np.sin(knee.theta_ref)
    r = np.array([[c, -s], [s, c]])
    p = np.asarray(knee.p_ref)
    cf = p + r @ np.asarray(knee.tibia_c)
    df = p + r @ np.asarray(knee.tibia_d)
    return _segments_cross(np.asarray(knee.femur_a), cf, np.asarray(knee.femur_b), df)


def fit_four_bar(
    theta: ArrayLike,
    target: ArrayLike,
    *,
    theta_ref: float | None = None,
    initial: FourBarKnee | None = None,
    n_starts: int = 4,
    seed: int = 0,
) -> FourBarFit:
    """Fit a crossed four-bar to the path ``target`` (N, 2) sampled at angles ``theta`` (N,).

    ``theta_ref`` (default: the angle closest to 0) is the reference configuration; ``initial``
    adds a start to the random multi-start (``n_starts``, reproducible with ``seed``).
    """
    th = np.asarray(theta, dtype=float).reshape(-1)
    tg = np.asarray(target, dtype=float)
    if tg.shape != (th.size, 2):
        raise ShapeMismatchError(f"four-bar fit: target {tg.shape} vs theta {th.shape}")
    if th.size < 12:
        raise IdentificationError(f"four-bar fit needs ≥ 12 samples, got {th.size}")
    if theta_ref is None:
        theta_ref = float(th[np.argmin(np.abs(th))])
    pm = tg.mean(axis=0)
    lo = np.array(
        [pm[0] - 0.04, pm[1] - 0.01, pm[0] - 0.01, pm[1] - 0.01,
         -0.01, -0.05, -0.04, -0.05, pm[0] - 0.05, pm[1] - 0.05]
    )  # fmt: skip
    hi = np.array(
        [pm[0] + 0.01, pm[1] + 0.05, pm[0] + 0.04, pm[1] + 0.05,
         0.04, 0.01, 0.01, 0.01, pm[0] + 0.05, pm[1] + 0.05]
    )  # fmt: skip
    scale = np.sqrt(th.size)

    def residual(x: Array) -> Array:
        knee = _knee_from(x, theta_ref)
        l1, l2 = knee.link_lengths
        s_ac, t_bd = _crossing(knee)
        pen = (
            10.0
            * scale
            * np.array(
                [
                    max(0.0, _MIN_LINK_M - l1),
                    max(0.0, _MIN_LINK_M - l2),
                    0.01 * max(0.0, 0.1 - s_ac),
                    0.01 * max(0.0, s_ac - 0.9),
                    0.01 * max(0.0, 0.1 - t_bd),
                    0.01 * max(0.0, t_bd - 0.9),
                ]
            )
        )
        try:
            p, _, _ = knee.solve(th)
        except (ModelError, np.linalg.LinAlgError):
            return np.full(2 * th.size + 6, 1.0)
        if not np.all(np.isfinite(p)):
            return np.full(2 * th.size + 6, 1.0)
        return np.concatenate([(p - tg).ravel(), pen])

    rng = np.random.default_rng(seed)
    starts = []
    if initial is not None:
        starts.append(
            np.r_[initial.femur_a, initial.femur_b, initial.tibia_c, initial.tibia_d, initial.p_ref]
        )
    # a generic human-like start: attachments 1-2 cm around the joint, crossed
    p0 = tg[np.argmin(np.abs(th - theta_ref))]
    starts.append(
        np.concatenate(
            [
                p0 + np.array([-0.010, 0.012]),
                p0 + np.array([0.008, 0.006]),
                [0.012, -0.010],
                [-0.018, -0.022],
                p0,
            ]
        )
    )
    for _ in range(n_starts):
        starts.append(lo + rng.uniform(0.15, 0.85, lo.size) * (hi - lo))
    best = None
    for x0 in starts:
        x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
        sol = least_squares(residual, x0, bounds=(lo, hi), x_scale=0.01, xtol=1e-12, ftol=1e-12)
        if best is None or sol.cost < best.cost:
            best = sol
    assert best is not None
    knee = _knee_from(best.x, theta_ref)
    try:
        p, _, _ = knee.solve(th)
    except ModelError as exc:
        raise IdentificationError(f"four-bar fit failed: {exc}") from exc
    res = p - tg
    err = np.linalg.norm(res, axis=1)
    return FourBarFit(
        knee=knee,
        theta=th,
        target=tg,
        residual=res,
        rms_m=float(np.sqrt(np.mean(err**2))),
        max_error_m=float(err.max()),
        crossed=_crossed(knee),
    )


def knee_path_of_joint(joint: Joint, theta: ArrayLike) -> Array:
    """p(θ) (N, 2): x and y translations of a knee joint whose axes are translations along the
    parent x and y driven by one coordinate, then a rotation about z (gait2392's knee)."""
    th = np.asarray(theta, dtype=float)
    out = np.zeros((th.size, 2))
    for ax in joint.axes:
        if ax.kind != "prismatic":
            continue
        k = int(np.argmax(np.abs(ax.axis)))
        if k > 1 or abs(abs(ax.axis[k]) - 1) > 1e-12:
            raise ModelError(f"joint {joint.name}: translation axis {ax.axis} is not x or y")
        out[:, k] += np.sign(ax.axis[k]) * np.asarray(ax.function(th), dtype=float)
    return out


def fit_four_bar_to_joint(
    joint: Joint, *, flexion: tuple[float, float] = (0.0, -2.094), n: int = 121, **kwargs: object
) -> FourBarFit:
    """Fit a four-bar to a spline knee over ``flexion`` (rad; gait2392: 0 to −2.094)."""
    th = np.linspace(flexion[0], flexion[1], n)
    return fit_four_bar(th, knee_path_of_joint(joint, th), **kwargs)  # type: ignore[arg-type]


def four_bar_joint(joint: Joint, knee: FourBarKnee) -> Joint:
    """``joint`` with its x/y translations replaced by the four-bar's p(θ) (same coordinate,
    same offsets, rotation about z kept as θ)."""
    coords = {a.coordinate for a in joint.axes if a.coordinate}
    if len(coords) != 1:
        raise ModelError(f"joint {joint.name}: a four-bar knee needs one coordinate, has {coords}")
    (c,) = coords
    axes = (
        Axis("prismatic", np.array([1.0, 0.0, 0.0]), c, FourBarTranslation(knee, 0)),
        Axis("prismatic", np.array([0.0, 1.0, 0.0]), c, FourBarTranslation(knee, 1)),
        Axis("revolute", np.array([0.0, 0.0, 1.0]), c, Linear()),
    )
    return Joint(
        joint.name, joint.parent, joint.child, joint.parent_offset, joint.child_offset, axes
    )


# ------------------------------------------------------------------------------------------
# functional calibration from marker clusters
# ------------------------------------------------------------------------------------------
def cluster_pose(local: ArrayLike, world: ArrayLike) -> tuple[Array, Array]:
    """Least-squares rigid pose (R, t) with world ≈ R local + t per frame (Söderkvist & Wedin
    1993, :func:`msk.personalise.functional_joints.segment_poses`).

    ``local`` (k, 3), ``world`` (N, k, 3) → R (N, 3, 3), t (N, 3). Frames with a missing (NaN)
    marker use the remaining markers (≥ 3 needed).

    Raises:
        ShapeMismatchError: ``local`` and ``world`` do not match.
        IdentificationError: a frame with fewer than three tracked (non-collinear) markers.
    """
    loc = np.asarray(local, dtype=float)
    w = np.asarray(world, dtype=float)
    if w.ndim != 3 or w.shape[1:] != loc.shape or loc.shape[1] != 3:
        raise ShapeMismatchError(f"cluster pose: local {loc.shape} vs world {w.shape}")
    poses = segment_poses(loc, w)
    if (bad := np.flatnonzero(~poses.valid)).size:
        i = int(bad[0])
        tracked = int(np.isfinite(w[i]).all(axis=1).sum())
        why = f"{tracked} markers (< 3)" if tracked < 3 else "collinear markers"
        raise IdentificationError(f"cluster pose: frame {i} has {why}")
    return poses.rotation, poses.origin


def fit_four_bar_from_markers(
    thigh: ArrayLike,
    shank: ArrayLike,
    *,
    thigh_local: ArrayLike | None = None,
    shank_local: ArrayLike | None = None,
    **kwargs: object,
) -> FourBarFit:
    """Functional calibration of the four-bar knee from a knee flexion trial.

    ``thigh`` (N, k1, 3) and ``shank`` (N, k2, 3): cluster marker trajectories (m, lab frame).
    ``thigh_local`` / ``shank_local``: the cluster markers in the femur / tibia frames (x
    anterior, y proximal, z lateral, e.g. from the model after a static calibration); the fitted
    A, B are then in the femur frame and C, D in the tibia frame. Without them the first frame's
    cluster geometry defines the frames. The trial must then start near full extension: the
    sagittal plane is normal to the mean rotation axis of the shank relative to the thigh (z,
    oriented so that flexion is negative), the femur frame's y axis points from the mean centre
    of rotation c to the thigh cluster (proximal), x = y × z (anterior), and the tibia frame is
    parallel to the femur frame in the first frame, with its origin at c.

    θ(t) is the planar rotation angle of the tibia frame relative to the femur frame (about +z),
    p(t) the tibia-origin position in the femur x-y plane; see :func:`fit_four_bar`.
    """
    th_w = np.asarray(thigh, dtype=float)
    sh_w = np.asarray(shank, dtype=float)
    if th_w.ndim != 3 or sh_w.ndim != 3 or th_w.shape[0] != sh_w.shape[0]:
        raise ShapeMismatchError(f"four-bar markers: thigh {th_w.shape} vs shank {sh_w.shape}")
    given = thigh_local is not None and shank_local is not None
    tl = np.asarray(thigh_local if given else th_w[0] - np.nanmean(th_w[0], 0), dtype=float)
    sl = np.asarray(shank_local if given else sh_w[0] - np.nanmean(sh_w[0], 0), dtype=float)
    rf, tf = cluster_pose(tl, th_w)
    rs, ts = cluster_pose(sl, sh_w)
    r_rel = np.einsum("nji,njk->nik", rf, rs)
    p_rel = np.einsum("nji,nj->ni", rf, ts - tf)
    if not given:
        r_rel, p_rel = _functional_frames(r_rel, p_rel)
    theta = np.arctan2(r_rel[:, 1, 0], r_rel[:, 0, 0])
    theta = np.unwrap(theta)
    return fit_four_bar(theta, p_rel[:, :2], **kwargs)  # type: ignore[arg-type]


def _functional_frames(r_rel: Array, p_rel: Array) -> tuple[Array, Array]:
    """Sagittal femur / tibia frames from the relative motion of two clusters (see
    :func:`fit_four_bar_from_markers`); returns r_rel, p_rel expressed in them."""
    rel0 = np.einsum("ji,njk->nik", r_rel[0], r_rel)
    w = np.stack([rel0[:, 2, 1] - rel0[:, 1, 2], rel0[:, 0, 2] - rel0[:, 2, 0],
                  rel0[:, 1, 0] - rel0[:, 0, 1]], -1)  # fmt: skip
    ref = w[np.argmax(np.linalg.norm(w, axis=1))]
    if np.linalg.norm(ref) < 1e-6:
        raise IdentificationError("four-bar markers: the shank does not rotate about the thigh")
    z = (w * np.sign(w @ ref)[:, None]).sum(0)
    z = -z / np.linalg.norm(z)  # flexion (the motion away from the first frame) is negative
    tmp = np.cross(z, [1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.cross(z, [0.0, 1.0, 0.0])
    e1 = tmp / np.linalg.norm(tmp)
    basis = np.stack([e1, np.cross(z, e1), z])
    r2 = np.einsum("ij,njk,lk->nil", basis, r_rel, basis)
    p2 = p_rel @ basis.T
    th = np.arctan2(r2[:, 1, 0], r2[:, 0, 0])
    # mean centre of rotation: c = p_t + R(θ_t) c'  (c in the femur plane, c' in the tibia)
    n = th.size
    a = np.zeros((2 * n, 4))
    a[:, :2] = np.tile(np.eye(2), (n, 1))
    cth, sth = np.cos(th), np.sin(th)
    a[0::2, 2], a[0::2, 3] = -cth, sth
    a[1::2, 2], a[1::2, 3] = -sth, -cth
    sol = np.linalg.lstsq(a, p2[:, :2].reshape(-1), rcond=None)[0]
    c, c_t = sol[:2], sol[2:]
    y = -c / np.linalg.norm(c)  # from c towards the thigh-cluster origin (proximal)
    x = np.array([y[1], -y[0]])  # x = y × z in the plane
    b2 = np.stack([x, y])
    basis = np.vstack([np.c_[b2, np.zeros(2)] @ basis[:3], basis[2]])
    r_out = np.einsum("ij,njk,lk->nil", basis, r_rel, basis)
    p_out = p_rel @ basis.T
    # tibia origin at the centre of rotation: p ← p + R c'
    c_t3 = np.r_[b2 @ c_t, 0.0]
    p_out = p_out + np.einsum("nij,j->ni", r_out, c_t3)
    return r_out, p_out
