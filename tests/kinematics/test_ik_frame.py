"""FrameIK: one frame's inverse kinematics from the previous frame's solution equals the batch
solve's frame and recovers the truth within the markers' noise."""

from __future__ import annotations

import numpy as np
import pytest

from msk.datasets.models import two_leg_model
from msk.datasets.trials import make_trial
from msk.kinematics.ik import FrameIK, solve_kinematics


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
