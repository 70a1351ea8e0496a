"""Four-bar knee fits: to gait2392's spline knee and from synthetic marker clusters."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from msk.exceptions import IdentificationError, ShapeMismatchError
from msk.model.core import forward_kinematics
from msk.model.fourbar_fit import (
    cluster_pose,
    fit_four_bar,
    fit_four_bar_from_markers,
    fit_four_bar_to_joint,
    four_bar_joint,
    knee_path_of_joint,
)
from msk.model.joints import FourBarKnee
from msk.model.osim import load_osim

TRUTH = FourBarKnee(
    femur_a=(-0.010, -0.395),
    femur_b=(0.008, -0.400),
    tibia_c=(0.012, -0.010),
    tibia_d=(-0.018, -0.022),
    theta_ref=0.0,
    p_ref=(0.0, -0.405),
)
FLEXION = np.linspace(0.0, -2.094, 121)  # 0-120° (gait2392 knee_angle is negative in flexion)


@pytest.fixture(scope="module")
def gait2392(ref_dir):
    return load_osim(ref_dir / "opensim-models/gait2392_thelen2003muscle.osim")


def test_four_bar_reproduces_gait2392_tibia_path_within_1mm(gait2392):
    knee = next(j for j in gait2392.joints if j.name == "knee_r")
    fit = fit_four_bar_to_joint(knee, n_starts=0)
    assert fit.rms_m < 1e-3 and fit.crossed
    # independent check on a finer grid than the one fitted
    th = np.linspace(0.0, -2.094, 997)
    err = np.linalg.norm(fit.knee.solve(th)[0] - knee_path_of_joint(knee, th), axis=1)
    assert np.sqrt(np.mean(err**2)) < 1e-3
    l_ac, l_bd = fit.knee.link_lengths
    assert 0.015 <= l_ac <= 0.06 and 0.015 <= l_bd <= 0.06
    # plugged into the model: tibia origin in the femur frame follows the four-bar
    model = gait2392.with_joints({"knee_r": four_bar_joint(knee, fit.knee)})
    data = model.create_data()
    theta = model.default_coordinates()
    theta[model.coordinate_index("knee_angle_r")] = -1.2
    forward_kinematics(model, data, theta)
    femur, tibia = data.oMf[model.body_frame["femur_r"]], data.oMf[model.body_frame["tibia_r"]]
    rel = femur.actInv(tibia)
    np.testing.assert_allclose(rel.translation[:2], fit.knee.solve(-1.2)[0], atol=1e-12)
    assert rel.translation[2] == pytest.approx(0.0, abs=1e-12)


def _synthetic_trial(knee: FourBarKnee, rng, noise_m: float):
    n = 200
    t = np.linspace(0.0, 1.0, n)
    theta = -1.05 * (1 - np.cos(2 * np.pi * t)) * 0.95  # 0 → −2.0 → 0 rad
    thigh_local = np.array([[0.05, -0.15, 0.06], [0.03, -0.25, 0.07], [0.06, -0.2, 0.02],
                            [0.02, -0.3, 0.05]])  # fmt: skip
    shank_local = np.array([[0.04, -0.10, 0.05], [0.02, -0.22, 0.06], [0.05, -0.16, 0.0],
                            [0.01, -0.28, 0.04]])  # fmt: skip
    p, _, _ = knee.solve(theta)
    thigh = np.empty((n, 4, 3))
    shank = np.empty((n, 4, 3))
    for i in range(n):
        rf = pin.rpy.rpyToMatrix(0.2 * np.sin(3 * t[i]), 0.1, 0.3 + 0.5 * t[i])
        tf = np.array([0.5 * t[i], 0.9, 0.1])
        rk = pin.AngleAxis(theta[i], np.array([0.0, 0.0, 1.0])).toRotationMatrix()
        rs = rf @ rk
        ts = tf + rf @ np.array([p[i, 0], p[i, 1], 0.0])
        thigh[i] = tf + thigh_local @ rf.T
        shank[i] = ts + shank_local @ rs.T
    thigh += rng.normal(scale=noise_m, size=thigh.shape)
    shank += rng.normal(scale=noise_m, size=shank.shape)
    return thigh, shank, thigh_local, shank_local


def test_marker_based_fit_recovers_known_four_bar_with_1mm_noise():
    rng = np.random.default_rng(3)
    thigh, shank, tl, sl = _synthetic_trial(TRUTH, rng, noise_m=1e-3)
    fit = fit_four_bar_from_markers(thigh, shank, thigh_local=tl, shank_local=sl, n_starts=0)
    truth_path = TRUTH.solve(FLEXION[FLEXION > -2.0])[0]
    fit_path = fit.knee.solve(FLEXION[FLEXION > -2.0])[0]
    err = np.linalg.norm(fit_path - truth_path, axis=1)
    assert np.sqrt(np.mean(err**2)) < 1e-3
    assert fit.rms_m < 5e-3  # residual to the noisy observations (relative pose noise)
    assert fit.crossed
    # the instantaneous centre of rotation (intersection of the cruciates) is recovered
    for th in (0.0, -0.8, -1.6):
        np.testing.assert_allclose(_icr(fit.knee, th), _icr(TRUTH, th), atol=3e-3)


def _icr(knee: FourBarKnee, theta: float) -> np.ndarray:
    p = knee.solve(theta)[0]
    c, s = np.cos(theta), np.sin(theta)
    r = np.array([[c, -s], [s, c]])
    cf, df = p + r @ np.asarray(knee.tibia_c), p + r @ np.asarray(knee.tibia_d)
    a, b = np.asarray(knee.femur_a), np.asarray(knee.femur_b)
    st = np.linalg.solve(np.column_stack([cf - a, -(df - b)]), b - a)
    return a + st[0] * (cf - a)


def test_marker_based_fit_without_local_coordinates_finds_the_plane():
    rng = np.random.default_rng(4)
    thigh, shank, _, _ = _synthetic_trial(TRUTH, rng, noise_m=0.0)
    fit = fit_four_bar_from_markers(thigh, shank, n_starts=0)
    # frames are the clusters' (unknown to the fit): the path is still reproduced exactly
    assert fit.rms_m < 1e-4


def test_cluster_pose_and_bad_shapes():
    rng = np.random.default_rng(5)
    local = rng.normal(size=(4, 3))
    r = pin.rpy.rpyToMatrix(0.3, -0.2, 1.0)
    world = (local @ r.T + [1.0, 2.0, 3.0])[None]
    rot, tr = cluster_pose(local, world)
    np.testing.assert_allclose(rot[0], r, atol=1e-12)
    np.testing.assert_allclose(tr[0], [1.0, 2.0, 3.0], atol=1e-12)
    with pytest.raises(ShapeMismatchError):
        fit_four_bar(np.zeros(20), np.zeros((19, 2)))
    with pytest.raises(ShapeMismatchError):
        cluster_pose(local, world[:, :3])
    gap = np.concatenate([world, world]).copy()
    gap[1, 1:3] = np.nan  # the second frame keeps two markers
    with pytest.raises(IdentificationError, match="frame 1 has 2 markers"):
        cluster_pose(local, gap)
    line = np.outer(np.arange(4.0), [1.0, 0.5, 0.2])  # collinear cluster
    with pytest.raises(IdentificationError, match="frame 0 has collinear markers"):
        cluster_pose(line, line[None])
