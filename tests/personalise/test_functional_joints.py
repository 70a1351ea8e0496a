"""Functional joint centres: segment poses (Söderkvist & Wedin 1993) and SCoRE / SARA (Ehrig
et al. 2006, 2007) on synthetic clusters with a known centre and axis, with marker noise."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from msk.personalise.functional_joints import cluster_shape, score, segment_poses

RNG = np.random.default_rng(7)
CLUSTER = np.array([[0.05, 0.02, 0.06], [-0.04, -0.05, 0.07], [0.01, -0.12, 0.05], [0.0, 0.0, 0.1]])


def _rot(rpy):
    return np.array([pin.rpy.rpyToMatrix(*r) for r in rpy])


def _markers(rot, org, local, noise_m):
    x = np.einsum("nij,kj->nki", rot, local) + org[:, None]
    return x + RNG.normal(0.0, noise_m, x.shape)


def test_segment_poses_recover_a_known_pose_with_gaps():
    n = 200
    rot = _rot(RNG.uniform(-1.0, 1.0, (n, 3)))
    org = RNG.uniform(-1.0, 1.0, (n, 3))
    x = _markers(rot, org, CLUSTER, 0.001)
    x[::7, 1] = np.nan  # one marker lost: three still pose the frame
    x[::11, :2] = np.nan  # two lost: not posed
    p = segment_poses(CLUSTER, x)
    assert not p.valid[::11].any()
    ok = p.valid
    assert ok.sum() > 0.85 * n
    err = np.einsum("nji,njk->nik", rot[ok], p.rotation[ok])  # Rᵀ R̂
    ang = np.degrees(np.arccos(np.clip((np.trace(err, axis1=1, axis2=2) - 1) / 2, -1, 1)))
    # 1 mm of noise on a cluster ~0.15 m across: about 1° per frame
    assert np.median(ang) < 1.0 and ang.max() < 4.0
    assert np.abs(p.origin[ok] - org[ok]).max() < 0.005
    assert np.nanmedian(p.fit_rms_m) == pytest.approx(0.001, rel=0.5)


def test_cluster_shape_is_the_cluster_up_to_a_rigid_motion():
    n = 100
    rot = _rot(RNG.uniform(-1.0, 1.0, (n, 3)))
    x = _markers(rot, RNG.uniform(-1, 1, (n, 3)), CLUSTER, 0.001)
    shape = cluster_shape(x)
    d_true = np.linalg.norm(CLUSTER[:, None] - CLUSTER[None], axis=2)
    d = np.linalg.norm(shape[:, None] - shape[None], axis=2)
    assert np.abs(d - d_true).max() < 0.001


def _two_segments(n, centre_a, centre_b, rel_rpy, noise_m):
    """Segment a moving freely, b rotating about a point fixed in both (c_a in a, c_b in b)
    by ``rel_rpy`` (N, 3) relative to a."""
    ra = _rot(np.column_stack([0.2 * np.sin(np.linspace(0, 6, n)), np.zeros(n), np.zeros(n)]))
    oa = np.column_stack([np.linspace(0, 2, n), np.full(n, 0.9), np.zeros(n)])
    rb = np.einsum("nij,njk->nik", ra, _rot(rel_rpy))
    c = np.einsum("nij,j->ni", ra, centre_a) + oa
    ob = c - np.einsum("nij,j->ni", rb, centre_b)
    xa = _markers(ra, oa, CLUSTER, noise_m)
    xb = _markers(rb, ob, CLUSTER * [1, 1, -1], noise_m)
    return segment_poses(CLUSTER, xa), segment_poses(CLUSTER * [1, 1, -1], xb), c


def test_score_finds_a_ball_joints_centre():
    n = 400
    t = np.linspace(0, 4 * np.pi, n)
    rel = np.column_stack([0.4 * np.sin(t), 0.3 * np.sin(0.7 * t), 0.5 * np.sin(1.3 * t)])
    ca, cb = np.array([0.0, -0.4, 0.0]), np.array([0.0, 0.05, 0.0])
    a, b, c = _two_segments(n, ca, cb, rel, 0.0015)
    fit = score(a, b)
    assert np.linalg.norm(fit.centre_a - ca) < 0.003
    assert np.linalg.norm(fit.centre_b - cb) < 0.003
    # per frame: the rotations' noise (~1°) carried 0.4 m
    assert np.sqrt(np.nanmean(np.sum((fit.centres - c) ** 2, axis=1))) < 0.006
    assert fit.mismatch_rms_m < 0.010  # the same noise, through both segments
    assert fit.frames == n


def test_score_hinge_finds_the_axis_and_a_point_on_it():
    n = 400
    flex = -0.6 + 0.6 * np.cos(np.linspace(0, 4 * np.pi, n))  # 0 to −69°
    rel = np.column_stack([np.zeros(n), np.zeros(n), flex])
    ca, cb = np.array([0.0, -0.4, 0.0]), np.array([0.0, 0.0, 0.0])
    a, b, _ = _two_segments(n, ca, cb, rel, 0.0015)
    fit = score(a, b, hinge=True)
    assert fit.hinge
    assert abs(abs(fit.axis_a[2]) - 1.0) < 1e-3  # the flexion axis, z in a's frame
    assert abs(abs(fit.axis_b[2]) - 1.0) < 1e-3
    # on the axis: x, y of the true centre (its z along the axis is not determined)
    assert np.linalg.norm(fit.centre_a[:2] - ca[:2]) < 0.003
    assert np.degrees(fit.rotation_range_rad) == pytest.approx(np.degrees(1.2), abs=3.0)
    # the axis direction is the least determined: its singular value (the rotations' noise,
    # ~1° = 0.02 rad) far below the others
    assert fit.singular_values[-1] < 0.15 * fit.singular_values[-2]


def test_score_needs_two_common_frames():
    a = segment_poses(CLUSTER, np.full((5, 4, 3), np.nan))
    with pytest.raises(ValueError, match="frames"):
        score(a, a)
