"""Gait cycles: bounds, time normalisation (a known truth), statistics, table round trip."""

from __future__ import annotations

import numpy as np
import pytest

from msk.exceptions import ShapeMismatchError
from msk.gait.cycles import PERCENT, GaitCycles, SideCycles, cycle_bounds, normalise_cycles


def test_cycle_bounds_pairs_strikes_and_places_the_foot_off():
    b = cycle_bounds([0.1, 1.2, 2.3, 2.3], [0.75, 1.85, 2.9])
    assert [(a, e) for a, e, _ in b] == [(0.1, 1.2), (1.2, 2.3)]
    assert b[0][2] == pytest.approx(100 * 0.65 / 1.1)
    assert b[1][2] == pytest.approx(100 * 0.65 / 1.1)
    assert np.isnan(cycle_bounds([0.0, 1.0], [])[0][2])


def test_normalisation_recovers_a_known_periodic_signal():
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 3.0, 301)
    period = [(0.2, 1.3, 60.0), (1.3, 2.35, 61.0)]
    # y is a sine over each cycle: y(p) = sin(2π p) at p = % / 100 of that cycle
    y = np.zeros_like(t)
    for a, b, _ in period:
        sel = (t >= a) & (t <= b)
        y[sel] = np.sin(2 * np.pi * (t[sel] - a) / (b - a))
    noisy = y + rng.normal(0.0, 1e-4, t.size)
    got = normalise_cycles(t, np.column_stack([noisy, 2 * noisy]), period)
    assert got.shape == (2, 101, 2)
    truth = np.sin(2 * np.pi * PERCENT / 100)
    assert np.abs(got[:, :, 0] - truth).max() < 5e-3  # linear interpolation of a 100 Hz sine
    assert np.allclose(got[:, :, 1], 2 * got[:, :, 0])
    # outside the series: NaN
    assert np.isnan(normalise_cycles(t, y, [(2.5, 3.5, np.nan)])[0, -1, 0])


def _cycles(n_left: int = 3, n_right: int = 2) -> GaitCycles:
    rng = np.random.default_rng(1)

    def side(s: str, n: int) -> SideCycles:
        start = np.arange(n) * 1.1 + (0.0 if s == "left" else 0.55)
        return SideCycles(
            s,
            rng.normal(size=(n, 101, 2)),
            start,
            start + 1.1,
            np.full(n, 61.0),
            np.arange(n) % 2 == 0,
            ("walk",) * n,
        )

    return GaitCycles(("knee_flexion_deg", "knee_adduction_moment_nm_kg"),
                      side("left", n_left), side("right", n_right))  # fmt: skip


def test_mean_and_sd_over_cycles_are_pointwise_and_nan_aware():
    c = _cycles()
    v = c.left.values.copy()
    v[0, :, 1] = np.nan  # a stance the plates did not measure
    left = SideCycles("left", v, c.left.start_s, c.left.end_s, c.left.foot_off_pct,
                      c.left.measured)  # fmt: skip
    assert np.allclose(left.mean()[:, 0], v[:, :, 0].mean(axis=0))
    assert np.allclose(left.mean()[:, 1], v[1:, :, 1].mean(axis=0))
    assert np.allclose(left.sd()[:, 1], v[1:, :, 1].std(axis=0, ddof=1))
    one = SideCycles("left", v[:1], c.left.start_s[:1], c.left.end_s[:1],
                     c.left.foot_off_pct[:1], c.left.measured[:1])  # fmt: skip
    assert np.isnan(one.sd()).all()


def test_tables_round_trip_and_pooling():
    c = _cycles()
    tabs = c.to_tables()
    assert tabs["gait_cycles_left"].data.shape == (3 * 101, 4 + 2)
    back = GaitCycles.from_tables(tabs, trial="walk")
    for s in ("left", "right"):
        a, b = c.side(s), back.side(s)
        assert np.allclose(a.values, b.values)
        assert np.allclose(a.start_s, b.start_s) and np.allclose(a.end_s, b.end_s)
        assert (a.measured == b.measured).all()
        assert np.allclose(a.foot_off_pct, b.foot_off_pct)
    pooled = GaitCycles.concatenate([c, back])
    assert pooled.left.n_cycles == 6 and pooled.right.n_cycles == 4
    assert np.allclose(pooled.mean("left"), c.mean("left"))


def test_shapes_are_checked():
    with pytest.raises(ShapeMismatchError, match="foot_off_pct"):
        SideCycles("left", np.zeros((2, 101, 1)), np.zeros(2), np.ones(2), np.zeros(3),
                   np.zeros(2, bool))  # fmt: skip


def test_a_side_without_cycles_has_no_table():
    c = _cycles(n_left=2, n_right=0)
    tabs = c.to_tables()
    assert set(tabs) == {"gait_cycles_left"}
    back = GaitCycles.from_tables(tabs)
    assert back.right.n_cycles == 0 and back.left.n_cycles == 2
    assert np.isnan(back.mean("right")).all()
    pooled = GaitCycles.concatenate([back, c])
    assert pooled.left.n_cycles == 4 and pooled.right.n_cycles == 0
