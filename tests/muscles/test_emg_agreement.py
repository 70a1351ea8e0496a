"""msk.muscles.emg_agreement: timing agreement of predicted activations with EMG, on signals
whose agreement is known by construction."""

from __future__ import annotations

import numpy as np
import pytest

from msk.muscles.emg_agreement import (
    channel_agreement,
    cocontraction_index,
    on_off_agreement,
    pearson_r,
    spearman_rho,
)


def _burst(n: int, start: int, stop: int) -> np.ndarray:
    x = np.zeros(n)
    x[start:stop] = np.sin(np.linspace(0, np.pi, stop - start))
    return x


def test_pearson_recovers_the_correlation_of_a_noisy_copy() -> None:
    rng = np.random.default_rng(0)
    n = 20000
    emg = rng.standard_normal(n)
    sigma = 0.75  # truth: r = 1 / sqrt(1 + sigma²) = 0.8
    pred = 0.3 * emg + 0.3 * sigma * rng.standard_normal(n) + 0.1  # scale and offset: no effect
    assert pearson_r(pred, emg) == pytest.approx(0.8, abs=0.01)
    assert pearson_r(-pred, emg) == pytest.approx(-0.8, abs=0.01)


def test_spearman_is_blind_to_a_monotone_transform_and_pearson_is_not() -> None:
    rng = np.random.default_rng(1)
    x = rng.uniform(0, 3, 500)
    y = np.exp(3 * x) + rng.normal(0, 1e-6, 500)
    assert spearman_rho(y, x) == pytest.approx(1.0, abs=1e-9)
    assert pearson_r(y, x) < 0.9
    # ties get their mean rank: a two-level signal against itself
    z = np.repeat([0.0, 1.0], 50)
    assert spearman_rho(z, z) == pytest.approx(1.0)


def test_frames_with_a_nan_are_left_out_and_degenerate_inputs_give_nan() -> None:
    x = np.array([0.0, 1.0, 2.0, np.nan, 4.0, 5.0])
    y = np.array([0.0, 1.0, 2.0, 100.0, np.nan, 5.0])
    assert pearson_r(x, y) == pytest.approx(1.0)
    assert np.isnan(pearson_r(np.ones(5), np.arange(5.0)))  # constant signal
    assert np.isnan(spearman_rho([1.0, 2.0], [1.0, 2.0]))  # fewer than 3 frames
    with pytest.raises(ValueError, match="different lengths"):
        pearson_r(np.ones(3), np.ones(4))


def test_on_off_agreement_of_a_shifted_burst_is_the_shift_over_the_length() -> None:
    n = 200
    emg = np.zeros(n)
    emg[50:100] = 1.0
    for k in (0, 5, 20):
        pred = np.roll(emg, k) * 0.2  # scale does not matter: each to its own peak
        assert on_off_agreement(pred, emg) == pytest.approx(1 - 2 * k / n)
    # a criterion that never recruits the muscle is off everywhere: agrees on the off frames
    assert on_off_agreement(np.full(n, 1e-5), emg) == pytest.approx(0.75)
    with pytest.raises(ValueError, match="threshold"):
        on_off_agreement(emg, emg, threshold=1.5)


def test_cocontraction_index_is_one_for_equal_shapes_zero_for_disjoint_and_the_overlap() -> None:
    n = 300
    a = _burst(n, 0, 100)
    assert cocontraction_index(a, 3 * a, peak_a=1.0, peak_b=3.0) == pytest.approx(1.0)
    b = _burst(n, 150, 250)
    assert cocontraction_index(a, b, peak_a=1.0, peak_b=1.0) == pytest.approx(0.0)
    # two boxes of height 1 overlapping on 25 of their 50 frames: 2·25 / (50 + 50)
    u, v = np.zeros(n), np.zeros(n)
    u[0:50], v[25:75] = 1.0, 1.0
    assert cocontraction_index(u, v, peak_a=1.0, peak_b=1.0) == pytest.approx(0.5)
    # a window normalised by the whole cycle's peaks: half of b's amplitude in the window
    assert cocontraction_index(u, 0.5 * v, peak_a=1.0, peak_b=1.0) == pytest.approx(25 / 75)
    assert np.isnan(cocontraction_index(u, v, peak_a=0.0, peak_b=1.0))


def test_channel_agreement_per_channel_with_noise() -> None:
    rng = np.random.default_rng(2)
    n = 400
    t = np.linspace(0, 1, n)
    emg = np.column_stack([_burst(n, 40, 160), _burst(n, 200, 360)])
    pred = np.column_stack(
        [emg[:, 0] + rng.normal(0, 0.02, n), _burst(n, 40, 160)]  # right, wrong timing
    )
    pred[:10] = np.nan  # frames not solved
    ag = channel_agreement(pred, emg, ("a", "b"))
    assert ag.channels == ("a", "b")
    assert ag.r[0] > 0.99 and ag.r[1] < 0.0
    assert ag.on_off[0] > 0.95 and ag.on_off[1] < 0.5
    assert ag.frames.tolist() == [n - 10, n - 10]
    assert ag.median_r() == pytest.approx(np.median(ag.r))
    assert t.size == n
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        channel_agreement(pred, emg, ("a", "b", "c"))


@pytest.mark.slow
def test_ps_single_joint_muscles_follow_their_emg_and_the_rectus_does_not() -> None:
    """Real data, Grand Challenge PS ss1 (bundled), the shipped config with static optimisation
    (p = 2, volume): the single-joint muscles whose role in walking is unambiguous (vasti in the
    loading response, soleus in push-off) follow their own EMG (r > 0.6; measured 0.77–0.84),
    while the biarticular rectus femoris runs against it (r < 0; measured −0.28: the late-stance
    recruitment of docs/validation.md, medial/lateral contact, item 9). A broken time base
    between the EMG stage and the tensions would fail the first part."""
    import dataclasses
    from pathlib import Path

    from msk.config import load_config
    from msk.pipeline import run_stages

    cfg = load_config(Path(__file__).resolve().parents[2] / "pipelines" / "gc5_PS.toml")
    cfg = dataclasses.replace(
        cfg, optimization=dataclasses.replace(cfg.optimization, method="static_optimization")
    )
    r = run_stages(cfg, until="tension_optimization")
    emg, t = r["emg"], r["tension_optimization"]
    act = np.asarray(t.activations)
    solvable = np.asarray(r["loads"].solvable)
    muscles = ("vas_med_l", "vas_lat_l", "soleus_l", "rect_fem_l")
    pred = np.column_stack(
        [np.where(solvable, act[:, t.muscles.index(m)], np.nan) for m in muscles]
    )
    rec = np.column_stack([np.asarray(emg.activation)[:, emg.column(m)] for m in muscles])
    ag = channel_agreement(pred, rec, muscles)
    assert (ag.frames > 100).all()
    assert (ag.r[:3] > 0.6).all(), ag.r
    assert ag.r[3] < 0.0, ag.r
