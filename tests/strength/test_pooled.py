"""msk.strength.pooled: a session's task and MVC trials in one identification, one EMG
normalisation (the MVC trials' peaks), per-group statuses."""

from __future__ import annotations

import numpy as np
import pytest

from msk.datasets.strength import LEG_TRUE_FACTORS, gait_trial, mvc_trials, synthetic_leg
from msk.exceptions import IdentificationError
from msk.muscles.activation import emg_to_activation
from msk.strength.pooled import (
    PooledTrial,
    identify_pooled,
    mvc_plateau,
    session_emg_reference,
)

ACT = {
    "gamma1": -0.5,
    "gamma2": -0.5,
    "shape_factor": -1.0,
    "delay_samples": 4,
    "form": "exponential",
}


def _act(e, rate_hz):
    return emg_to_activation(e, **ACT)


@pytest.fixture(scope="module")
def leg():
    return synthetic_leg(0)


def _pooled(tr, name, kind, movement, gains, leg):
    """A synthetic trial as a PooledTrial: one channel per group (its first muscle's
    envelope), in 'channel units' (× an electrode gain unknown to the identifier)."""
    chans = tuple(leg.groups)
    first = [leg.params.names.index(m[0]) for m in leg.groups.values()]
    env = tr.emg[:, first] * gains[None]
    return PooledTrial(
        name, kind, 100.0, chans, env, tr.jacobian, tr.muscle_tendon_length,
        tr.lengthening_velocity, tr.tau, windows=tr.cycle, movement=movement,
    )  # fmt: skip


def _session(leg, seed, *, with_mvc=True, silent=()):
    rng = np.random.default_rng(seed + 7)
    gains = rng.uniform(0.05, 2.0, len(leg.groups))  # mV: each electrode its own gain
    trials = [
        _pooled(gait_trial(leg, n_cycles=6, seed=seed, silent_groups=silent), "walk1", "task",
                "gait", gains, leg),
        _pooled(gait_trial(leg, n_cycles=6, seed=seed + 1000, silent_groups=silent), "walk2",
                "task", "gait", gains, leg),
    ]  # fmt: skip
    if with_mvc:
        targets = [g for g in leg.groups if g not in silent]
        for k, g in enumerate(targets):
            # a maximal effort held steady, with the gait trials' envelope noise (10 %
            # multiplicative, 1 % additive, 5 Hz) not clipped at the MVC: its plateau mean IS
            # the MVC scale (1) of the gait trials
            tr = mvc_trials(leg, seed=seed + 100 * k, groups=[g], repetitions=5,
                            effort=(1.0, 1.0), emg_ceiling=None)  # fmt: skip
            trials.append(_pooled(tr, f"mvc_{g}", "mvc", g, gains, leg))
    channels = {m: g for g, ms in leg.groups.items() for m in ms}
    return trials, channels


def _fit(leg, trials, channels, **kw):
    opts = {"instrument": "phase_average", "n_bootstrap": 0} | kw
    return identify_pooled(
        trials, channels, leg.params, coordinate_names=("hip", "knee", "ankle"),
        activation=_act, **opts,
    )  # fmt: skip


def _truth(names):
    return np.array([LEG_TRUE_FACTORS[g] for g in names])


def test_reference_is_the_mvc_plateau_when_mvc_trials_exist_else_the_session_peak(leg):
    trials, _ = _session(leg, 0)
    ref = session_emg_reference(trials)
    assert set(ref.source) == {"mvc"}
    mvc = [t for t in trials if t.kind == "mvc"]
    # each channel's own MVC trial sets it: the plateau mean is the true
    # MVC (1 × the electrode's gain, drawn as in _session) within 4 of its own standard
    # errors, below the trial's highest sample
    gains = np.random.default_rng(0 + 7).uniform(0.05, 2.0, len(leg.groups))
    for k, c in enumerate(ref.channels):
        own = next(t for t in mvc if t.name == f"mvc_{c}")
        assert ref.value[k] < own.envelopes[:, k].max()
        assert 0.005 < ref.relative_error(c) < 0.1
        assert abs(ref.value[k] / gains[k] - 1) < 4 * ref.relative_error(c)
    peaks = np.max([t.envelopes.max(axis=0) for t in mvc], axis=0)
    np.testing.assert_allclose(session_emg_reference(trials, plateau_s=None).value, peaks)
    ref2 = session_emg_reference(trials[:2])
    assert set(ref2.source) == {"session_peak"}
    np.testing.assert_allclose(
        ref2.value, np.maximum(trials[0].envelopes.max(0), trials[1].envelopes.max(0))
    )
    assert np.isnan(ref2.standard_error).all()
    ref3 = session_emg_reference(trials, given={"dorsiflexors": 3.0})
    assert ref3.source[ref3.channels.index("dorsiflexors")] == "given"


def test_mvc_plateau_standard_error_is_that_of_the_window_mean():
    """Known truth: an AR(1) envelope (φ = 0.8, σ = 0.1 about a level of 1) held 3 s at
    100 Hz beside a torque whose highest second is known; over 400 draws the plateau mean
    is unbiased and its standard error (Geyer's initial positive sequence) matches the
    spread of the means within 25 %."""
    rng = np.random.default_rng(1)
    n, phi = 300, 0.8
    torque = np.concatenate([np.full(100, 50.0), np.full(100, 60.0), np.full(100, 50.0)])
    means, ses = [], []
    for _ in range(400):
        z = np.zeros(n)
        w = rng.standard_normal(n) * 0.1 * np.sqrt(1 - phi**2)
        for t in range(1, n):
            z[t] = phi * z[t - 1] + w[t]
        level, se = mvc_plateau((1.0 + z)[:, None], torque, 100.0, 1.0)
        means.append(level[0])
        ses.append(se[0])
    assert abs(np.mean(means) - 1.0) < 3 * np.std(means) / np.sqrt(400)
    assert np.mean(ses) == pytest.approx(np.std(means), rel=0.25)


def test_pooled_gait_and_mvc_recover_every_group_within_10_percent(leg):
    """Two gait trials + 5 MVC repetitions per action, electrodes of unknown gain (0.05–2 mV):
    normalised by the MVC trials' peaks, every group recovered within 10 %, identified, each
    judged on its own rows; the MVC trials' torques are rows of the regression."""
    trials, channels = _session(leg, 3)
    p = _fit(leg, trials, channels, n_bootstrap=40)
    np.testing.assert_allclose(p.factors, _truth(p.group_names), rtol=0.10)
    assert all(s == "identified" for s in p.statuses()), p.table()
    assert p.extra["normalisation_kind"] == "mvc"
    assert p.extra["trials"]["mvc_knee_extensors"]["rows"] == trials[2 + 2].n_frames
    assert sum(r["rows"] for r in p.extra["trials"].values()) == sum(t.n_frames for t in trials)
    assert "normalisation_bias" not in p.extra


def test_without_mvc_the_session_peak_is_used_and_said_with_its_bias(leg):
    """No MVC trial: the session-wide peak (of the gait trials) normalises every trial — one
    reference, not each trial's own — and the profile states the bias: the gait peak is below
    the MVC, activations too high, factors low."""
    trials, channels = _session(leg, 3, with_mvc=False)
    p = _fit(leg, trials, channels, instrument="none", n_bootstrap=0)
    assert p.extra["normalisation_kind"] == "session_peak"
    assert "too LOW" in p.extra["normalisation_bias"]
    ke = p.group_names.index("knee_extensors")
    assert p.factors[ke] < LEG_TRUE_FACTORS["knee_extensors"]


def test_a_group_nobody_excites_does_not_drag_the_others_down(leg):
    """Hip groups silent in gait and without MVC: never identified, while the knee and ankle
    groups stay identified (judged on their own rows, not the session's mean r²)."""
    hip = ("hip_flexors", "hip_extensors")
    trials, channels = _session(leg, 5, silent=hip)
    p = _fit(leg, trials, channels, n_bootstrap=40)
    st = dict(zip(p.group_names, p.statuses()))
    assert all(st[g] != "identified" for g in hip), st
    assert all(st[g] == "identified" for g in leg.groups if g not in hip), (st, p.table())


def test_bad_input_names_the_trial(leg):
    trials, channels = _session(leg, 0, with_mvc=False)
    with pytest.raises(IdentificationError, match="repeat"):
        _fit(leg, [trials[0], trials[0]], channels)
    bad = PooledTrial(
        "short", "task", 100.0, ("x",), np.ones((5, 1)), trials[0].jacobian[:5],
        trials[0].lengths[:5], trials[0].velocities[:5], trials[0].tau[:5],
    )  # fmt: skip
    with pytest.raises(IdentificationError, match="short"):
        _fit(leg, [trials[0], bad], channels)


def test_the_mvc_references_error_widens_the_intervals(leg):
    """One reference per channel is shared by every row, so the window jackknife cannot see
    its error: the delta-method term (one-SE secant) widens every group's interval and is
    recorded per group; without it the standard errors are the jackknife's alone."""
    trials, channels = _session(leg, 2)
    p = _fit(leg, trials, channels)
    q = _fit(leg, trials, channels, reference_uncertainty=False)
    np.testing.assert_allclose(p.factors, q.factors)
    sd = np.array([p.extra["reference_uncertainty"]["factor_sd"][g] for g in p.group_names])
    assert (sd > 0).all()
    np.testing.assert_allclose(p.std_error, np.hypot(q.std_error, sd))
    assert ((p.ci_cov_high - p.ci_cov_low) > (q.ci_cov_high - q.ci_cov_low)).all()
    assert "reference_uncertainty" not in q.extra


@pytest.mark.slow
def test_pooled_intervals_cover_the_truth_over_100_subjects(leg):
    """100 synthetic subjects (gait ×2 + 5 MVC holds per action with the same envelope noise
    as the gait, unknown electrode gains, torque noise): every group within 10 % of its
    truth for every subject, and the 95 % jackknife-t interval — with the MVC references'
    error — covers the truth at the nominal rate minus the binomial slack
    (0.95 − 2·√(0.95·0.05/100) ≈ 0.91; ≥ 0.90 asserted). Without the references' error the
    coverage of these sessions is 0.53–0.83 (30 subjects)."""
    n = 100
    inside = np.zeros((n, 6), dtype=bool)
    err = np.zeros((n, 6))
    for seed in range(n):
        trials, channels = _session(leg, seed)
        p = _fit(leg, trials, channels)
        truth = _truth(p.group_names)
        inside[seed] = (p.ci_cov_low <= truth) & (truth <= p.ci_cov_high)
        err[seed] = p.factors / truth - 1
    print("max |err| per group", np.abs(err).max(axis=0), "coverage", inside.mean(axis=0))
    assert np.abs(err).max() < 0.10, np.abs(err).max(axis=0)
    assert inside.mean(axis=0).min() >= 0.90, inside.mean(axis=0)


def test_default_windows_cut_task_trials_into_equal_chunks_and_keep_an_mvc_one(leg):
    """Without labels, a task trial is cut into round(T / window_s) equal windows (no
    remainder window of a few frames) and an MVC trial is one window; windows never straddle
    two trials."""
    from dataclasses import replace

    trials, channels = _session(leg, 0)
    walk = replace(trials[0], windows=None)  # 6 cycles of ≈ 1 s at 100 Hz
    mvcs = [replace(t, windows=None) for t in trials[2:]]
    p = _fit(leg, [walk, *mvcs], channels, instrument="none", window_s=1.5)
    rec = p.extra["trials"]
    assert rec["walk1"]["windows"] == round(walk.n_frames / 150)
    assert all(rec[t.name]["windows"] == 1 for t in mvcs)
    assert p.window_labels.max() + 1 == sum(r["windows"] for r in rec.values())
