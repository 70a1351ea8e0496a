"""Spatiotemporal parameters recover a synthetic walk's known parameters (to 1 %)."""

from __future__ import annotations

import numpy as np
import pytest

from msk.gait.spatiotemporal import PARAMETERS, Spatiotemporal, spatiotemporal, surface_velocity
from msk.results.summary import Gait


def _walk(speed=1.3, stride_t=1.1, stance=0.61, width=0.12, heading_deg=30.0, noise=0.0005):
    """Heels of a walk in a y-up world heading at ``heading_deg`` from x in the floor plane:
    each heel still on the floor during its stance and moving forward during its swing."""
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 5.0, 0.005)
    step_t = stride_t / 2
    L = speed * stride_t
    h = np.deg2rad(heading_deg)
    fwd = np.array([np.cos(h), 0.0, -np.sin(h)])
    lat = np.array([np.sin(h), 0.0, np.cos(h)])  # to the right
    heel, fs, fo = {}, {}, {}
    for s, t0, side_sign in (("right", 0.1, 1.0), ("left", 0.1 + step_t, -1.0)):
        strikes = np.arange(t0, 5.0, stride_t)
        offs = strikes + stance * stride_t
        fs[s], fo[s] = tuple(strikes), tuple(offs)
        # heel progress: constant during stance, smooth advance of L during swing
        x = np.zeros_like(t)
        for k, a in enumerate(strikes):
            b = a + stride_t
            sel = (t >= a) & (t < b)
            ph = np.clip((t[sel] - offs[k]) / (b - offs[k]), 0, 1)
            x[sel] = k * L + L * (ph - np.sin(2 * np.pi * ph) / (2 * np.pi))
        x[t < strikes[0]] = 0.0
        x += (0.0 if s == "right" else L / 2) - 0.0
        p = x[:, None] * fwd + side_sign * width / 2 * lat + np.array([0, 0.03, 0])
        heel[s] = p + rng.normal(0.0, noise, p.shape)
    return t, heel, fs, fo


def test_synthetic_walk_parameters_within_one_percent():
    speed, stride_t, stance, width = 1.3, 1.1, 0.61, 0.12
    t, heel, fs, fo = _walk(speed, stride_t, stance, width)
    st = spatiotemporal(t, heel, fs, fo, up=np.array([0.0, 1.0, 0.0]))
    truth = {
        "walking_speed_m_s": speed,
        "cadence_steps_per_min": 120.0 / stride_t,
        "stride_length_m": speed * stride_t,
        "stride_time_s": stride_t,
        "step_length_m": speed * stride_t / 2,
        "step_time_s": stride_t / 2,
        "stance_pct": 100 * stance,
        "swing_pct": 100 * (1 - stance),
        "double_support_pct": 100 * 2 * (stance - 0.5),
        "step_width_m": width,
    }
    assert set(truth) == set(PARAMETERS)
    for s in ("left", "right"):
        sp = st.side(s)
        assert sp.n_strides >= 3
        for p, v in truth.items():
            assert sp.mean(p) == pytest.approx(v, rel=0.01), (s, p)


def test_summary_round_trip():
    t, heel, fs, fo = _walk()
    st = spatiotemporal(t, heel, fs, fo, up=np.array([0.0, 1.0, 0.0]))
    rec = Gait.from_dict({"spatiotemporal": st.to_summary(), "heel_source": "model"})
    assert Gait.from_dict(rec.to_dict()).to_dict() == rec.to_dict()
    back = Spatiotemporal.from_summary(rec.spatiotemporal or {})
    for s in ("left", "right"):
        assert np.allclose(back.side(s).values, st.side(s).values, equal_nan=True)
        assert back.side(s).mean("stride_time_s") == pytest.approx(st.side(s).mean("stride_time_s"))


def test_pooling_strides_of_two_trials():
    t, heel, fs, fo = _walk()
    a = spatiotemporal(t, heel, fs, fo, up=np.array([0.0, 1.0, 0.0]))
    t2, heel2, fs2, fo2 = _walk(speed=1.0)
    b = spatiotemporal(t2, heel2, fs2, fo2, up=np.array([0.0, 1.0, 0.0]))
    both = Spatiotemporal.concatenate([a, b])
    for s in ("left", "right"):
        n = a.side(s).n_strides + b.side(s).n_strides
        assert both.side(s).n_strides == n
        v = np.concatenate([a.side(s).parameter("walking_speed_m_s"),
                            b.side(s).parameter("walking_speed_m_s")])  # fmt: skip
        assert both.side(s).mean("walking_speed_m_s") == pytest.approx(np.nanmean(v))


def test_treadmill_walk_measured_on_the_belt():
    """The same walk on a treadmill (heels carried back at the walking speed, pelvis still):
    the belt's speed is found and the parameters are those of the walk, to 1 %."""
    speed = 1.25
    t, heel, fs, fo = _walk(speed=speed, heading_deg=0.0)
    fwd = np.array([1.0, 0.0, 0.0])
    belt = {s: h - speed * t[:, None] * fwd for s, h in heel.items()}
    pelvis = np.zeros((t.size, 3)) + np.array([0.0, 0.9, 0.0])
    up = np.array([0.0, 1.0, 0.0])
    u = surface_velocity(t, belt, fs, fo, pelvis=pelvis, up=up)
    assert u == pytest.approx([-speed, 0.0, 0.0], abs=0.01 * speed)
    st = spatiotemporal(t, belt, fs, fo, up=up, surface=u)
    for s in ("left", "right"):
        assert st.side(s).mean("walking_speed_m_s") == pytest.approx(speed, rel=0.01)
        assert st.side(s).mean("step_width_m") == pytest.approx(0.12, rel=0.01)
    # overground, the same call finds a surface at rest
    walking = np.column_stack([speed * t, 0.9 + 0 * t, 0 * t])
    assert not surface_velocity(t, heel, fs, fo, pelvis=walking, up=up).any()
