"""The live chain frame by frame: each per-frame stage equal to its batch computation, and the
whole chain recovering a synthetic truth (two legs, ten muscles a leg, two plates) after its
stated lag."""

from __future__ import annotations

import numpy as np
import pytest

from msk.datasets.models import two_leg_model
from msk.datasets.trials import make_trial
from msk.dynamics.inverse import FrameInverseDynamics, inverse_dynamics
from msk.dynamics.loads import external_loads, sample_plate
from msk.kinematics.ik import FrameIK, kinematics_from_coordinates, solve_kinematics
from msk.live import LiveInput, LiveOptions, LiveSession, live_model
from tests.support.two_legs import muscled_two_legs

UP = np.array([0.0, 1.0, 0.0])


@pytest.fixture(scope="module")
def synthetic():
    model = muscled_two_legs()
    return model, make_trial(model, duration_s=0.8, rate_hz=100.0, noise_m=0.0005, seed=3)


def _frames(tr):
    sampled = [sample_plate(p, tr.time, UP) for p in tr.plates]
    force = np.stack([s.force for s in sampled], axis=1)
    moment = np.stack([s.moment for s in sampled], axis=1)
    return [
        LiveInput(float(tr.time[k]), tr.markers[k], force[k], moment[k])
        for k in range(tr.time.size)
    ]


def test_frame_ik_equals_the_batch_solve():
    model = two_leg_model()
    tr = make_trial(model, duration_s=0.3, rate_hz=100.0, noise_m=0.001, seed=1)
    batch = solve_kinematics(model, tr.markers, tr.marker_labels, tr.time, cutoff_hz=None)
    ik = FrameIK(model, tr.marker_labels)
    for n in range(1, tr.time.size):
        th, _, ok, rms = ik.solve(batch.q_raw[n - 1], tr.markers[n])
        assert ok
        np.testing.assert_allclose(th, batch.q_raw[n], atol=2e-6)
        assert rms == pytest.approx(batch.marker_rms[n], rel=1e-4)
    # and the truth, within the markers' noise
    assert np.abs(th - tr.q[-1]).max() < np.radians(1.0)


def test_frame_ik_without_enough_markers_keeps_the_start():
    model = two_leg_model()
    tr = make_trial(model, duration_s=0.1, rate_hz=100.0)
    ik = FrameIK(model, tr.marker_labels)
    start = model.default_coordinates()
    th, k, ok, rms = ik.solve(start, np.full_like(tr.markers[0], np.nan))
    assert th is start and k == 0 and not ok and np.isnan(rms)


def test_frame_inverse_dynamics_equals_the_batch():
    model = two_leg_model()
    tr = make_trial(model, duration_s=0.5, rate_hz=100.0)
    kin = kinematics_from_coordinates(tr.time, tr.q, model.coordinate_names, cutoff_hz=None)
    kin = type(kin)(**{**kin.__dict__, "v": tr.v, "a": tr.a})
    ext = external_loads(model, kin, tr.plates)
    batch = inverse_dynamics(model, kin, ext)
    fid = FrameInverseDynamics(model, ext.bodies)
    for k in range(0, tr.time.size, 7):
        tau = fid.torques(tr.q[k], tr.v[k], tr.a[k], ext.force[k], ext.moment[k])
        np.testing.assert_allclose(tau, batch.tau[k], rtol=1e-10, atol=1e-9)
    # the batch recovers the simulated torques: so does the frame
    act = [i for i, c in enumerate(model.coordinate_names) if not c.startswith("pelvis")]
    np.testing.assert_allclose(tau[act], tr.tau_true[k][act], atol=2.0)


def test_live_session_recovers_the_truth_after_its_lag(synthetic):
    model, tr = synthetic
    lm = live_model(
        model, tr.marker_labels, tr.rate_hz, options=LiveOptions(knee_joint="knee_r", cutoff_hz=6.0)
    )
    session = LiveSession(lm)
    out = [session.step(f) for f in _frames(tr)]
    assert session.lag_s == pytest.approx(np.sqrt(2) / (2 * np.pi * 6.0) + 0.01, rel=0.03)
    t = np.array([f.time for f in out]) - session.lag_s
    late = t > 0.25  # the filter's start-up (≈ 3/f_c) over
    truth = np.column_stack([np.interp(t, tr.time, tr.q[:, j]) for j in range(tr.q.shape[1])])
    q = np.array([f.q for f in out])
    # the causal low-pass at the lag: the shape of a smooth movement within 1°
    assert np.degrees(np.abs(q - truth)[late]).max() < 1.0
    assert all(f.qp_status == 0 for f in out)
    assert all(f.ik_converged for f in out)
    forces = np.array([f.muscle_forces for f in out])
    assert np.isfinite(forces).all() and (forces >= -1e-6).all()
    axial = np.array([f.knee_axial for f in out])
    assert np.isfinite(axial).all()
    rms = np.array([f.marker_rms for f in out])
    assert np.median(rms) < 0.002  # 0.5 mm noise per coordinate
    assert out[-1].stage_s.shape == (6,) and out[-1].latency_s > 0


def test_live_session_torques_follow_the_truth(synthetic):
    model, tr = synthetic
    lm = live_model(model, tr.marker_labels, tr.rate_hz)
    session = LiveSession(lm)
    out = [session.step(f) for f in _frames(tr)]
    t = np.array([f.time for f in out]) - session.lag_s
    late = (t > 0.25) & (t < tr.time[-1] - 0.05)
    act = [i for i, c in enumerate(model.coordinate_names) if not c.startswith("pelvis")]
    tau = np.array([f.torques for f in out])[:, act]
    truth = np.column_stack([np.interp(t, tr.time, tr.tau_true[:, j]) for j in act])
    peak = np.abs(tr.tau_true[:, act]).max(axis=0)
    err = (np.abs(tau - truth)[late] / peak).max(axis=0)
    assert err.max() < 0.10, dict(zip([model.coordinate_names[i] for i in act], err.round(3)))
