"""Functional joint centres and axes from the markers of the two segments a joint links.

A segment's pose in every frame from its markers (:func:`segment_poses`): the rotation R and
translation t minimising Σ_i ‖R l_i + t − x_i‖² over its tracked markers (local positions
l_i, measured x_i; Söderkvist & Wedin 1993, J Biomech 26:1473–1477, the SVD solution).

The centre of a joint between segments a and b (:func:`score`, SCoRE: Ehrig et al. 2006,
J Biomech 39:2798–2809, Eq. 3) is the point fixed in both: c_a in a's frame and c_b in b's,

    min_{c_a, c_b} Σ_t ‖(R_a(t) c_a + t_a(t)) − (R_b(t) c_b + t_b(t))‖²,

linear least squares in (c_a, c_b) over the frames where both segments are posed; its world
position in frame t is the midpoint of the two estimates, and their RMS distance (the
"mismatch") measures how far the data are from a joint with a fixed centre (soft tissue moving
the markers on the bones, a joint that translates). For a joint that rotates about one axis
(the knee in walking) the centre is determined only up to a point on that axis: the stacked
system's smallest singular value is near zero and its right singular vector (a, b) is the axis
in both segments' frames (SARA: Ehrig et al. 2007, J Biomech 40:2150–2157); ``hinge=True``
drops that direction (the least-norm point on the axis) and reports the axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.units import Array

__all__ = ["ScoreFit", "SegmentPoses", "cluster_shape", "score", "segment_poses"]


@dataclass(frozen=True)
class SegmentPoses:
    """A segment's pose per frame from its markers.

    Attributes:
        rotation: (N, 3, 3) segment → world (NaN where not posed).
        origin: (N, 3) m, the segment frame's origin in the world (NaN where not posed).
        valid: (N,) posed (at least ``min_markers`` tracked, not collinear).
        fit_rms_m: (N,) RMS distance of the tracked markers from the fitted ones (NaN where
            not posed).
    """

    rotation: Array
    origin: Array
    valid: NDArray[np.bool_]
    fit_rms_m: Array


def segment_poses(local: ArrayLike, world: ArrayLike, *, min_markers: int = 3) -> SegmentPoses:
    """Söderkvist & Wedin (1993) least-squares pose of a segment in every frame.

    Args:
        local: (k, 3) m, the markers' positions in the segment frame.
        world: (N, k, 3) m, their measured positions (NaN gaps).
        min_markers: fewest tracked markers that pose a frame (3: a rigid body).
    """
    loc = np.asarray(local, dtype=float)
    x = np.asarray(world, dtype=float)
    n, k = x.shape[0], loc.shape[0]
    if x.shape[1:] != (k, 3) or loc.shape != (k, 3):
        raise ValueError(f"segment_poses: local {loc.shape} and world {x.shape} do not match")
    w = np.isfinite(x).all(axis=2).astype(float)  # (N, k)
    xz = np.where(w[:, :, None] > 0, x, 0.0)
    cnt = w.sum(axis=1)
    safe = np.maximum(cnt, 1.0)
    cl = (w @ loc) / safe[:, None]  # (N, 3)
    cw = np.einsum("nk,nkd->nd", w, xz) / safe[:, None]
    dl = loc[None] - cl[:, None]  # (N, k, 3)
    dw = xz - cw[:, None]
    h = np.einsum("nk,nki,nkj->nij", w, dl, dw)  # Σ w (l − l̄)(x − x̄)ᵀ
    u, s, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(np.einsum("nji,nkj->nik", vt, u)))
    d = np.where(d == 0, 1.0, d)
    fix = np.ones((n, 3))
    fix[:, 2] = d
    rot = np.einsum("nji,nj,nkj->nik", vt, fix, u)  # V diag(1, 1, d) Uᵀ
    org = cw - np.einsum("nij,nj->ni", rot, cl)
    # three markers pose a body when they are not collinear: the second singular value of the
    # centred local points (through H) is not negligible against the first
    valid = (cnt >= min_markers) & (s[:, 1] > 1e-6 * np.maximum(s[:, 0], 1e-12))
    fitted = np.einsum("nij,kj->nki", rot, loc) + org[:, None]
    err = np.where(w > 0, np.linalg.norm(fitted - xz, axis=2) ** 2, 0.0)
    rms = np.sqrt(err.sum(axis=1) / safe)
    rot[~valid] = np.nan
    org[~valid] = np.nan
    rms[~valid] = np.nan
    return SegmentPoses(rot, org, valid, rms)


def cluster_shape(world: ArrayLike, *, iterations: int = 3) -> Array:
    """The rigid shape (k, 3) of a marker cluster tracked in ``world`` (N, k, 3), in a frame of
    its own: the first frame that tracks every marker, then (``iterations`` times) the mean of
    the frames posed on it (generalised Procrustes, Gower 1975), centred on its centroid.

    Raises:
        ValueError: no frame tracks every marker.
    """
    x = np.asarray(world, dtype=float)
    full = np.isfinite(x).all(axis=(1, 2))
    if not full.any():
        raise ValueError("cluster_shape: no frame tracks every marker")
    ref = x[int(np.flatnonzero(full)[0])]
    for _ in range(iterations):
        p = segment_poses(ref, x[full])
        ok = p.valid
        local = np.einsum("nji,nkj->nki", p.rotation[ok], x[full][ok] - p.origin[ok][:, None])
        ref = local.mean(axis=0)
    return np.asarray(ref - ref.mean(axis=0), dtype=float)


@dataclass(frozen=True)
class ScoreFit:
    """A SCoRE joint centre (Ehrig et al. 2006) between segments a and b.

    Attributes:
        centre_a: (3,) m, the centre in a's frame.
        centre_b: (3,) m, the centre in b's frame.
        centres: (N, 3) m, its world position per frame (midpoint of the two estimates; NaN
            where a frame is not used).
        used: (N,) the frames used (both segments posed).
        mismatch_rms_m: RMS distance between the two estimates over the frames used.
        axis_a: (3,) unit, the least-determined direction in a's frame (the rotation axis of
            a hinge, SARA: Ehrig et al. 2007); sign arbitrary.
        axis_b: (3,) unit, the same in b's frame.
        singular_values: (6,) of the stacked system over √frames (m-free: rotations), largest
            first; the last over the first is how well the centre is determined along the
            axis.
        hinge: the axis direction was left out of the solution (the least-norm point on it).
        rotation_range_rad: the range (5th to 95th percentile) of b's rotation relative to a
            about the axis.
    """

    centre_a: Array
    centre_b: Array
    centres: Array
    used: NDArray[np.bool_]
    mismatch_rms_m: float
    axis_a: Array
    axis_b: Array
    singular_values: Array
    hinge: bool
    rotation_range_rad: float

    @property
    def frames(self) -> int:
        """Frames used."""
        return int(self.used.sum())


def score(a: SegmentPoses, b: SegmentPoses, *, hinge: bool = False) -> ScoreFit:
    """SCoRE (Ehrig et al. 2006, Eq. 3): the point fixed in both segments' frames, by linear
    least squares over the frames where both are posed; ``hinge`` leaves out the direction of
    the smallest singular value (the joint's axis, SARA, Ehrig et al. 2007), whose position
    along the axis the data do not determine.

    Raises:
        ValueError: fewer than 2 frames where both segments are posed.
    """
    used = a.valid & b.valid
    f = int(used.sum())
    if f < 2:
        raise ValueError(f"score: {f} frames with both segments posed")
    ra, rb = a.rotation[used], b.rotation[used]
    lhs = np.concatenate([ra, -rb], axis=2).reshape(-1, 6)
    rhs = (b.origin[used] - a.origin[used]).reshape(-1)
    u, s, vt = np.linalg.svd(lhs, full_matrices=False)
    keep = 5 if hinge else 6
    coef = (u[:, :keep].T @ rhs) / s[:keep]
    sol = vt[:keep].T @ coef
    ca, cb = sol[:3], sol[3:]
    pa = np.einsum("nij,j->ni", ra, ca) + a.origin[used]
    pb = np.einsum("nij,j->ni", rb, cb) + b.origin[used]
    mismatch = float(np.sqrt(np.mean(np.sum((pa - pb) ** 2, axis=1))))
    centres = np.full((used.size, 3), np.nan)
    centres[used] = 0.5 * (pa + pb)
    v = vt[5]
    ax_a = v[:3] / max(float(np.linalg.norm(v[:3])), 1e-12)
    ax_b = v[3:] / max(float(np.linalg.norm(v[3:])), 1e-12)
    # b's rotation relative to a about the axis: a unit vector normal to the axis, carried
    # from b's frame into a's, its angle in the plane normal to the axis
    rel = np.einsum("nji,njk->nik", ra, rb)  # R_aᵀ R_b
    p = np.cross(ax_b, np.eye(3)[int(np.argmin(np.abs(ax_b)))])
    p /= np.linalg.norm(p)
    q = np.einsum("nij,j->ni", rel, p)
    q -= np.outer(q @ ax_a, ax_a)
    ref = np.median(q, axis=0)
    ref -= np.dot(ref, ax_a) * ax_a
    ref /= max(float(np.linalg.norm(ref)), 1e-12)
    ang = np.arctan2(np.cross(ref, q) @ ax_a, q @ ref)
    lo, hi = np.percentile(ang, [5.0, 95.0])
    return ScoreFit(
        centre_a=ca, centre_b=cb, centres=centres, used=used, mismatch_rms_m=mismatch,
        axis_a=ax_a, axis_b=ax_b, singular_values=s / np.sqrt(f), hinge=hinge,
        rotation_range_rad=float(hi - lo),
    )  # fmt: skip
