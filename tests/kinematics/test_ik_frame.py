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


def _batch_step(ik, start, markers):
    """The batch solve's own LM (:func:`_levenberg_marquardt`) on FrameIK's problem."""
    from msk.kinematics.ik import _levenberg_marquardt

    x = markers[ik.columns]
    present = np.isfinite(x).all(axis=1)
    start = np.minimum(np.maximum(start, ik.lo), ik.hi)
    return _levenberg_marquardt(
        ik.problem, start, x, ik.sw, present, ik.free, ik.lo, ik.hi, ik.max_iterations,
        ik.tolerance, ik.ctask, ik.rel_tolerance,
    )  # fmt: skip


@pytest.mark.parametrize("locked", [False, True])
def test_frame_ik_is_the_batch_lm_to_the_last_bit(locked):
    """Preallocated buffers, not other arithmetic: with missing markers, a coordinate task and
    a coordinate held at a bound (and a locked coordinate: every step on a sub-block), θ and
    the iterations equal the batch solve's LM's (to the last bit on the hosts measured) and
    the data holds the returned θ's placements."""
    import dataclasses

    model = two_leg_model()
    if locked:
        model.coordinates = tuple(
            dataclasses.replace(c, locked=i == 5) for i, c in enumerate(model.coordinates)
        )
    tr = make_trial(model, duration_s=0.3, rate_hz=100.0, noise_m=0.002, seed=3)
    name = model.coordinate_names[-1]
    ik = FrameIK(model, tr.marker_labels, coordinate_tasks={name: (0.1, 0.5)})
    assert ik._lm is not None and ik._lm.all_free != locked
    k_b = model.coordinate_index(model.coordinate_names[3])
    ik.hi[k_b] = float(np.percentile(tr.q[:, k_b], 30))  # the bound is reached on most frames
    rng = np.random.default_rng(0)
    markers = tr.markers.copy()
    gone = rng.random(markers.shape[:2]) < 0.15
    markers[gone] = np.nan
    th_prev = tr.q[0]
    bound_hit = 0
    for n in range(1, tr.time.size):
        th_b, k_b2, ok_b, p_b = _batch_step(ik, th_prev, markers[n])
        th, k, ok, rms = ik.solve(th_prev, markers[n])
        # equal to the last bit on the hosts measured; 1e-12 rad allows another BLAS kernel
        np.testing.assert_allclose(th, th_b, rtol=0, atol=1e-12)
        assert k == k_b2 and ok == ok_b
        present = np.isfinite(markers[n][ik.columns]).all(axis=1)
        d = ((p_b - markers[n][ik.columns]) ** 2).sum(axis=1)[present]
        assert rms == pytest.approx(np.sqrt(d.mean()), rel=1e-12)
        assert ik.problem._at is th  # the data holds the returned θ's placements
        bound_hit += th[k_b] == ik.hi[k_b]
        th_prev = th
    assert bound_hit > 5


@pytest.mark.slow
def test_frame_ik_is_the_batch_lm_on_a_recorded_trial():
    """The same on the bundled trial's frames (gc5 PS: gait2392, splined knee coordinates,
    missing markers), each frame from the previous frame's solution."""
    from pathlib import Path

    from msk.config import load_config
    from msk.live import LiveSession
    from msk.live.sources import ReplaySource
    from msk.pipeline.inputs import session_inputs
    from msk.pipeline.live import live_setup

    root = Path(__file__).resolve().parents[2]
    cfg = load_config(root / "pipelines" / "gc5_PS.toml")
    task = session_inputs(cfg).task
    assert task is not None
    src = ReplaySource(task.file, grf=task.grf, external_loads=task.external_loads)
    lm = live_setup(
        cfg, src.layout.labels, src.rate_hz, plate_names=src.plate_names, assignment=src.assignment
    ).model
    ik = LiveSession(lm).data.ik  # the live session's IK (its options and coordinate tasks)
    assert ik._lm is not None
    th_prev = lm.model.default_coordinates()
    missing = 0
    for f in src:
        x = f.markers @ lm.rotation.T
        th_b, k_b, ok_b, _ = _batch_step(ik, th_prev, x)
        th, k, ok, _ = ik.solve(th_prev, x)
        np.testing.assert_allclose(th, th_b, rtol=0, atol=1e-12)
        assert k == k_b and ok == ok_b
        missing += not np.isfinite(x[ik.columns]).all()
        th_prev = th
    assert missing > 10


def test_value_and_slope_is_the_scalar_functions_arithmetic():
    """FrameIK's one-call (f, f') of each coordinate function equals the batch IK's separate
    closures bit for bit, inside, at and beyond a spline's knots."""
    from msk.kinematics.ik import _scalar_function, _value_and_slope
    from msk.model.joints import Linear, Multiplier, Polynomial, SimmSpline

    spline = SimmSpline(x=(-2.0, -1.0, -0.3, 0.2, 1.1, 2.0), y=(0.1, -0.2, 0.05, 0.3, 0.0, -0.4))
    functions = [
        spline, Multiplier(spline, -0.7), Polynomial((0.3, -1.2, 0.5, 2.0)),
        Multiplier(Polynomial((1.0, 0.2)), 3.0), Linear(0.5, 0.1), Multiplier(Linear(2.0), 0.25),
    ]  # fmt: skip
    xs = [-2.7, -2.0, -1.5, -1.0, -0.3, 0.0, 0.2, 0.9, 2.0, 3.1]
    for f in functions:
        fv, fd, _ = _scalar_function(f)  # type: ignore[misc]
        both = _value_and_slope(f)
        for x in xs:
            assert both(x) == (fv(x), fd(x))  # type: ignore[operator]
