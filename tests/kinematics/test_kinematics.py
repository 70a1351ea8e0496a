"""Inverse kinematics: exact recovery, gaps, limits, locked coordinates, weights, noise."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msk.datasets.models import two_leg_model
from msk.datasets.trials import make_trial
from msk.exceptions import KinematicsError, ShapeMismatchError
from msk.kinematics.ik import (
    STATUS_OK,
    STATUS_TOO_FEW_MARKERS,
    Kinematics,
    _MarkerProblem,
    kinematics_from_coordinates,
    solve_kinematics,
)
from msk.model.core import Coordinate, marker_positions

MODEL = two_leg_model()
TRIAL = make_trial(MODEL, duration_s=1.0, rate_hz=100.0)


def test_marker_jacobian_matches_finite_differences():
    prob = _MarkerProblem(MODEL, MODEL.marker_names)
    th = TRIAL.q[17]
    p, jac = prob.evaluate(th)
    np.testing.assert_allclose(p, marker_positions(MODEL, th)[0], atol=1e-14)
    h = 1e-6
    fd = np.empty_like(jac)
    for i in range(th.size):
        e = np.zeros_like(th)
        e[i] = h
        fd[:, i] = (prob.positions(th + e) - prob.positions(th - e)).ravel() / (2 * h)
    np.testing.assert_allclose(jac, fd, atol=1e-8)
    assert prob.coord_mask is not None
    prob.coord_mask = None  # the general (per-DOF mask) path gives the same Jacobian
    np.testing.assert_allclose(prob.evaluate(th)[1], jac, atol=1e-12)


@settings(max_examples=15, deadline=None)
@given(
    frame=st.integers(0, TRIAL.time.size - 1),
    seed=st.integers(0, 2**16),
    size=st.floats(0.05, 0.3),
)
def test_ik_on_exact_markers_returns_true_coordinates_from_a_perturbed_start(frame, seed, size):
    truth = TRIAL.q[frame]
    start = truth + np.random.default_rng(seed).uniform(-size, size, truth.size)
    kin = solve_kinematics(
        MODEL,
        TRIAL.markers[frame : frame + 1],
        TRIAL.marker_labels,
        TRIAL.time[frame : frame + 1],
        initial_q=start,
        cutoff_hz=None,
    )
    assert kin.status[0] == STATUS_OK
    np.testing.assert_allclose(kin.q_raw[0], truth, atol=1e-6)
    assert kin.marker_rms[0] < 1e-8


def test_whole_trial_from_default_start_and_derivatives():
    kin = solve_kinematics(MODEL, TRIAL.markers, TRIAL.marker_labels, TRIAL.time, cutoff_hz=8.0)
    assert isinstance(kin, Kinematics)
    assert kin.coordinate_names == MODEL.coordinate_names
    np.testing.assert_allclose(kin.q_raw, TRIAL.q, atol=1e-8)
    inner = slice(10, -10)  # away from the filter and difference edges
    np.testing.assert_allclose(kin.q[inner], TRIAL.q[inner], atol=2e-4)
    np.testing.assert_allclose(kin.v[inner], TRIAL.v[inner], atol=1e-2)
    np.testing.assert_allclose(kin.a[inner], TRIAL.a[inner], atol=0.3)
    assert kin.iterations.max() <= 10
    assert np.all(kin.marker_max < 1e-8)
    assert set(kin.marker_max_name) <= set(MODEL.marker_names)


def test_gaps_drop_markers_and_empty_frames_are_reported_not_guessed():
    x = TRIAL.markers.copy()
    gone = [0, 5, 10, 15, 20, 25]
    x[5, gone] = np.nan  # six markers missing: still solvable
    x[20, :] = np.nan  # nothing: reported
    x[21, 3:] = np.nan  # three markers for 16 coordinates: reported
    kin = solve_kinematics(MODEL, x, TRIAL.marker_labels, TRIAL.time, cutoff_hz=6.0)
    np.testing.assert_allclose(kin.q_raw[5], TRIAL.q[5], atol=1e-8)
    assert kin.n_markers_used[5] == len(MODEL.markers) - 6
    assert np.isnan(kin.marker_errors[5, gone]).all()
    assert list(kin.failed_frames) == [20, 21]
    assert kin.status[20] == STATUS_TOO_FEW_MARKERS
    assert np.isnan(kin.q[20]).all() and np.isnan(kin.v[21]).all()
    np.testing.assert_allclose(kin.q_raw[22], TRIAL.q[22], atol=1e-8)  # recovers after the gap
    with pytest.raises(KinematicsError, match=r"frame 20 \(t = 0.2000 s\)"):
        solve_kinematics(MODEL, x, TRIAL.marker_labels, TRIAL.time, strict=True)


def test_limits_are_respected_and_locked_coordinates_held():
    i_knee = MODEL.coordinate_index("knee_angle_r")
    i_ank = MODEL.coordinate_index("ankle_angle_l")
    coords = list(MODEL.coordinates)
    lo_knee = float(np.min(TRIAL.q[:, i_knee]))
    bound = lo_knee + 0.1
    coords[i_knee] = Coordinate("knee_angle_r", range=(bound, 0.17))
    coords[i_ank] = Coordinate("ankle_angle_l", range=(-0.7, 0.5), default=0.05, locked=True)
    model = MODEL._rebuilt(coordinates=coords)
    kin = solve_kinematics(model, TRIAL.markers, TRIAL.marker_labels, TRIAL.time, cutoff_hz=None)
    assert np.all(kin.q_raw[:, i_knee] >= bound - 1e-12)
    clipped = TRIAL.q[:, i_knee] < bound
    assert clipped.any()
    np.testing.assert_allclose(kin.q_raw[clipped, i_knee], bound, atol=1e-9)
    np.testing.assert_array_equal(kin.q_raw[:, i_ank], 0.05)
    # the misfit the locked ankle causes shows up on the left foot markers
    worst = {kin.marker_max_name[n] for n in range(kin.n_frames)}
    assert worst & {"LHEE", "LTOE", "LMT5", "RHEE", "RTOE", "RMT5"}


def test_weights_and_coordinate_tasks():
    x = TRIAL.markers.copy()
    x[:, MODEL.marker_names.index("RTOE")] += [0.0, 0.03, 0.0]  # a bad marker
    w = {"RTOE": 0.0}
    kin = solve_kinematics(MODEL, x, TRIAL.marker_labels, TRIAL.time, weights=w, cutoff_hz=None)
    assert "RTOE" not in kin.marker_names
    np.testing.assert_allclose(kin.q_raw, TRIAL.q, atol=1e-7)
    tasks = {"ankle_angle_r": (0.0, 1e6)}
    kin = solve_kinematics(
        MODEL, TRIAL.markers, TRIAL.marker_labels, TRIAL.time, coordinate_tasks=tasks
    )
    assert np.abs(kin.q_raw[:, MODEL.coordinate_index("ankle_angle_r")]).max() < 1e-3
    with pytest.raises(KinematicsError, match="RTOE: weight"):
        solve_kinematics(MODEL, x, TRIAL.marker_labels, TRIAL.time, weights={"RTOE": -1.0})
    with pytest.raises(ShapeMismatchError):
        solve_kinematics(MODEL, x[:, :3], TRIAL.marker_labels, TRIAL.time)


def test_noise_2mm_errors_are_small():
    noisy = make_trial(MODEL, duration_s=1.0, rate_hz=100.0, noise_m=0.002, seed=3)
    kin = solve_kinematics(MODEL, noisy.markers, noisy.marker_labels, noisy.time, cutoff_hz=6.0)
    err = kin.q - TRIAL.q
    rot = [c.kind == "rotational" for c in MODEL.coordinates]
    rms_deg = np.rad2deg(np.sqrt(np.mean(err[10:-10][:, rot] ** 2, axis=0)))
    print("IK 2 mm noise: RMS angle error (deg) per rotational coordinate", rms_deg.round(2))
    assert 0.0015 < np.mean(kin.marker_rms) < 0.0035
    assert rms_deg.max() < 1.5


def test_kinematics_from_coordinates_reorders_to_the_model():
    names = MODEL.coordinate_names[::-1]
    kin = kinematics_from_coordinates(
        TRIAL.time, TRIAL.q[:, ::-1], names, cutoff_hz=None, model=MODEL
    )
    np.testing.assert_allclose(kin.q, TRIAL.q)
    assert kin.coordinate_names == MODEL.coordinate_names


def test_markers_left_out_by_a_zero_weight_are_in_the_all_markers_rms():
    """A marker given weight 0 does not move the solution, and its distance is reported in
    ``marker_rms_all`` (over all the model markers of the trial), not in ``marker_rms``."""
    x = TRIAL.markers.copy()
    k = MODEL.marker_names.index("RTOE")
    x[:, k] += [0.0, 0.03, 0.0]  # 3 cm off
    kin = solve_kinematics(
        MODEL, x, TRIAL.marker_labels, TRIAL.time, weights={"RTOE": 0.0}, cutoff_hz=None
    )
    n = len(kin.marker_names) + 1
    assert np.nanmax(kin.marker_rms) < 1e-6
    assert kin.marker_rms_all is not None
    np.testing.assert_allclose(kin.marker_rms_all, np.sqrt(0.03**2 / n), rtol=1e-4)
    full = solve_kinematics(MODEL, TRIAL.markers, TRIAL.marker_labels, TRIAL.time, cutoff_hz=None)
    assert full.marker_rms_all is None


def test_a_trial_with_too_few_model_markers_in_every_frame_says_which_it_has():
    """Every frame with 4 of the model's markers (a pelvis and a heel, as a lab marker set the
    model does not recognise beyond those: BTS.c3d's Davis set with the gait2392 configs): one
    clear error naming the markers found and how many the free coordinates need."""
    x = TRIAL.markers.copy()
    x[:, 4:] = np.nan
    with pytest.raises(KinematicsError, match=r"at most 4 of the model's markers.* needed") as e:
        solve_kinematics(MODEL, x, TRIAL.marker_labels, TRIAL.time, cutoff_hz=6.0)
    assert f"seen in the trial: {', '.join(MODEL.marker_names[:4])} (" in str(e.value)


def test_per_frame_start_warm_starts_each_frame():
    """``initial_q`` of shape (N, n): each frame starts from its own row (a warm start from an
    earlier solution, issue 15 eleventh pass): from the exact poses the same solution in one
    or two iterations; from the poses 0.02 rad off (a previous pass of a placement) the same
    solution; a NaN row falls back to the prediction; a wrong shape is refused."""
    x, labels, t = TRIAL.markers, TRIAL.marker_labels, TRIAL.time
    cold = solve_kinematics(MODEL, x, labels, t, cutoff_hz=None)
    exact = solve_kinematics(MODEL, x, labels, t, cutoff_hz=None, initial_q=TRIAL.q)
    np.testing.assert_allclose(exact.q_raw, TRIAL.q, atol=1e-8)
    assert exact.iterations.max() <= 2 < cold.iterations.mean()
    rng = np.random.default_rng(3)
    off = TRIAL.q + rng.normal(0.0, 0.02, TRIAL.q.shape)
    off[7] = np.nan
    warm = solve_kinematics(MODEL, x, labels, t, cutoff_hz=None, initial_q=off)
    np.testing.assert_allclose(warm.q_raw, TRIAL.q, atol=1e-8)
    with pytest.raises(ShapeMismatchError, match="per frame"):
        solve_kinematics(MODEL, x, labels, t, initial_q=TRIAL.q[:-1])


def test_a_subject_tracked_for_part_of_the_trial_keeps_its_accelerations_at_the_window_ends():
    """A runner crossing the capture volume: θ known (with 0.5 mm noise) only in 0.8 s of a
    4 s trial, at 4 m/s with a 2.8 Hz bounce. The window is filtered on its own (its ends
    reflected), so the accelerations there are the truth's, within the noise a 6 Hz low-pass
    leaves — not the ±60 m/s² of a velocity stepping to zero outside the window."""
    rate, fc = 250.0, 6.0
    t = np.arange(0.0, 4.0, 1.0 / rate)
    w = 2 * np.pi * 2.8
    truth_q = 4.0 * t + 0.04 * np.sin(w * t)
    truth_a = -0.04 * w**2 * np.sin(w * t)
    q = truth_q + np.random.default_rng(3).normal(0.0, 5e-4, t.size)
    window = (t >= 1.6) & (t < 2.4)
    q[~window] = np.nan
    kin = kinematics_from_coordinates(t, q[:, None], ["pelvis_tx"], cutoff_hz=fc)
    a = kin.a[:, 0]
    assert np.isnan(a[~window]).all() and np.isfinite(a[window]).all()
    inner = window & (t >= 1.6 + 0.05) & (t < 2.4 - 0.05)  # 50 ms in from each end
    err = np.abs(a - truth_a)
    assert err[inner].max() < 3.0  # m/s², against a 12 m/s² bounce (held θ outside: 23)
    assert np.sqrt(np.mean(err[window] ** 2)) < 4.0  # (held θ outside: 14)
    v_truth = 4.0 + 0.04 * w * np.cos(w * t)
    assert np.abs(kin.v[window, 0] - v_truth[window]).max() < 0.5  # (held θ outside: 2.0)
