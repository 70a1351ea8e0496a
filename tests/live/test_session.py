"""The live chain frame by frame recovers a synthetic truth (two legs, ten muscles a leg, two
plates) after its stated lag (each per-frame stage equal to its batch computation: the tests of
FrameIK, FrameInverseDynamics, FrameStaticOptimization and FrameKneeContact)."""

from __future__ import annotations

import numpy as np
import pytest

from msk.datasets.trials import make_trial
from msk.dynamics.loads import sample_plate
from msk.exceptions import ConfigError, ModelError
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


def test_live_session_recovers_the_truth_after_its_lag(synthetic):
    model, tr = synthetic
    lm = live_model(
        model, tr.marker_labels, tr.rate_hz, options=LiveOptions(knee_joint="knee_r", cutoff_hz=6.0)
    )
    session = LiveSession(lm)
    out = [session.step(f) for f in _frames(tr)]
    # the group delay and two samples (the offline run's differences, centred two samples back)
    assert session.lag_s == pytest.approx(np.sqrt(2) / (2 * np.pi * 6.0) + 0.02, rel=0.03)
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


def test_a_plate_assigned_by_the_lab_loads_that_foot(synthetic):
    model, tr = synthetic
    frames = _frames(tr)
    auto = LiveSession(live_model(model, tr.marker_labels, tr.rate_hz))
    # both plates given to the left foot: the right foot never carries a load
    fixed = LiveSession(
        live_model(model, tr.marker_labels, tr.rate_hz, plate_bodies=["foot_l", "foot_l"])
    )
    right = fixed.model.feet.index("foot_r")
    loaded_auto = loaded_fixed = 0
    for f in frames:
        auto.step(f)
        fixed.step(f)
        loaded_auto += int(np.abs(auto.data.force[right]).sum() > 0)
        loaded_fixed += int(np.abs(fixed.data.force[right]).sum() > 0)
    assert loaded_auto > 10 and loaded_fixed == 0
    with pytest.raises(ModelError, match="not a foot"):
        live_model(model, tr.marker_labels, tr.rate_hz, plate_bodies=["pelvis"])


def test_the_linear_phase_smoother_recovers_the_truth_after_its_own_lag(synthetic):
    model, tr = synthetic
    opts = LiveOptions(smoother="linear_phase", fir_half_width_s=0.12)
    session = LiveSession(live_model(model, tr.marker_labels, tr.rate_hz, options=opts))
    assert session.lag_s == pytest.approx((12 + 2) / tr.rate_hz)  # 12 taps each side, 2 back
    out = [session.step(f) for f in _frames(tr)]
    t = np.array([f.time for f in out]) - session.lag_s
    late = t > 0.25
    truth = np.column_stack([np.interp(t, tr.time, tr.q[:, j]) for j in range(tr.q.shape[1])])
    q = np.array([f.q for f in out])
    assert np.degrees(np.abs(q - truth)[late]).max() < 1.0
    with pytest.raises(ConfigError, match="smoother"):
        live_model(model, tr.marker_labels, tr.rate_hz, options=LiveOptions(smoother="spline"))


def test_the_one_frame_geometry_equals_the_plans_evaluation_in_the_chain(synthetic):
    """Paths with wrapping surfaces take GeometryPlan.evaluate frame by frame: on wrap-free
    paths both give the same frames to round-off."""
    model, tr = synthetic
    lm = live_model(model, tr.marker_labels, tr.rate_hz, options=LiveOptions(knee_joint="knee_r"))
    fast, plan = LiveSession(lm), LiveSession(lm)
    assert fast.data.geometry is not None
    plan.data.geometry = None
    for f in _frames(tr)[:40]:
        a, b = fast.step(f), plan.step(f)
        np.testing.assert_allclose(a.muscle_forces, b.muscle_forces, rtol=1e-9, atol=1e-9)
        assert a.knee_axial == pytest.approx(b.knee_axial, rel=1e-9, abs=1e-9)
