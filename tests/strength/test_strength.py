"""msk.strength: net-contribution strength identification (seeds/002 §V), W_emg study, tables."""

from __future__ import annotations

from dataclasses import FrozenInstanceError

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msk.datasets.strength import (
    LEG_TRUE_FACTORS,
    SyntheticLegTrial,
    concatenate_trials,
    gait_trial,
    mvc_trials,
    synthetic_leg,
)
from msk.exceptions import IdentificationError, ShapeMismatchError
from msk.muscles.activation import emg_to_activation
from msk.muscles.hill import MuscleParameters, rigid_tendon_state
from msk.strength import (
    StrengthIdentifier,
    area_ratio_table,
    expand_groups,
    group_contributions,
    moment_fit_table,
    net_contribution,
    net_force_table,
    net_joint_force,
    w_emg_stability,
    with_strength,
)

# activation dynamics assumed known (generic) by the identifier: those of the simulation
ACT = {
    "gamma1": -0.5,
    "gamma2": -0.5,
    "shape_factor": -1.0,
    "delay_samples": 4,
    "form": "exponential",
}


@pytest.fixture(scope="module")
def leg():
    return synthetic_leg(0)


def _inputs(leg, tr: SyntheticLegTrial):
    a = emg_to_activation(tr.emg, **ACT)
    state = rigid_tendon_state(leg.params, tr.muscle_tendon_length, tr.lengthening_velocity)
    return a, state


def _truth(names):
    return np.array([LEG_TRUE_FACTORS[g] for g in names])


# ---------------------------------------------------------------------------------------------
# net contribution matrix (seeds/002 Eq. 12-16)
# ---------------------------------------------------------------------------------------------
@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), scale=st.floats(0.5, 2.0))
def test_contributions_times_f_iso_give_the_joint_torques(seed, scale):
    """Σ_k C_k F_iso,k = −Jᵀ f for the forces of the same state (Eq. 12-14), any F_iso."""
    leg = synthetic_leg(seed % 7)
    tr = gait_trial(leg, n_cycles=1, seed=seed, emg_mult_noise=0.0, emg_add_noise=0.0)
    p = leg.params
    params = MuscleParameters(
        p.names,
        p.max_isometric_force * scale,
        p.optimal_fiber_length,
        p.tendon_slack_length,
        p.pennation_angle_at_optimal,
    )
    a = tr.activation_true
    s = rigid_tendon_state(params, tr.muscle_tendon_length, tr.lengthening_velocity)
    forces = a * s.max_active_force_along_tendon + s.passive_force_along_tendon
    c = net_contribution(tr.jacobian, a, s)
    tau = np.einsum("tmj,m->tj", c, params.max_isometric_force)
    np.testing.assert_allclose(tau, -np.einsum("tmj,tm->tj", tr.jacobian, forces), atol=1e-9)
    cg, other = group_contributions(c, leg.groups, params)
    np.testing.assert_allclose(cg.sum(axis=1) + other, tau, atol=1e-9)
    # active-only form of Eq. 13
    c_act = net_contribution(tr.jacobian, a, s, passive=False)
    f_act = a * s.max_active_force_along_tendon
    np.testing.assert_allclose(
        np.einsum("tmj,m->tj", c_act, params.max_isometric_force),
        -np.einsum("tmj,tm->tj", tr.jacobian, f_act),
        atol=1e-9,
    )


def test_expand_groups_copies_each_electrode_to_its_muscles(leg):
    v = np.arange(12.0).reshape(2, 6)
    out = expand_groups(v, leg.groups, leg.muscle_names)
    assert out.shape == (2, 15)
    for g, (name, members) in enumerate(leg.groups.items()):
        for m in members:
            np.testing.assert_array_equal(out[:, leg.muscle_names.index(m)], v[:, g], err_msg=name)


def test_bad_groups_and_shapes_raise_typed_errors_naming_the_culprit(leg):
    with pytest.raises(IdentificationError, match="NOPE"):
        StrengthIdentifier({"g": ("NOPE",)}, leg.params)
    with pytest.raises(IdentificationError, match="'RF' is in two"):
        StrengthIdentifier({"a": ("RF",), "b": ("RF", "VL")}, leg.params)
    with pytest.raises(IdentificationError, match="gate_threshold"):
        StrengthIdentifier(leg.groups, leg.params, gate_threshold=1.5)
    tr = gait_trial(leg, n_cycles=3, seed=1)
    a, s = _inputs(leg, tr)
    idf = StrengthIdentifier(leg.groups, leg.params)
    with pytest.raises(IdentificationError, match="not fitted"):
        idf.predict(tr.jacobian, a, s)
    with pytest.raises(ShapeMismatchError, match="tau"):
        idf.fit(tr.jacobian, a, tr.tau[:, :2], s, windows=tr.cycle)
    bad = a.copy()
    bad[5, 2] = np.nan
    with pytest.raises(IdentificationError, match="frame 5, column 'RF'"):
        idf.fit(tr.jacobian, bad, tr.tau, s, windows=tr.cycle)


# ---------------------------------------------------------------------------------------------
# recovery of known strengths
# ---------------------------------------------------------------------------------------------
def test_recovers_known_group_strengths_within_10_percent(leg):
    """Knee extensors ×1.7, plantar flexors ×0.6 of generic; noisy EMG and torques."""
    tr = gait_trial(leg, n_cycles=24, seed=0)
    a, s = _inputs(leg, tr)
    idf = StrengthIdentifier(leg.groups, leg.params, n_bootstrap=200, random_state=0)
    assert idf.fit(tr.jacobian, a, tr.tau, s, windows=tr.cycle) is idf
    p = idf.profile_
    truth = _truth(p.group_names)
    assert p.identified.all(), p.table()
    np.testing.assert_allclose(p.factors, truth, rtol=0.10, err_msg=p.table())
    np.testing.assert_allclose(p.f_iso, truth * p.f_iso_generic, rtol=0.10)
    ke, pf = p.group_names.index("knee_extensors"), p.group_names.index("plantar_flexors")
    assert abs(p.factors[ke] / 1.7 - 1) < 0.05 and abs(p.factors[pf] / 0.6 - 1) < 0.05
    # per-muscle outputs and the model-ready mapping
    vl = p.muscle_names.index("VL")
    assert p.muscle_factors[vl] == pytest.approx(p.factors[ke])
    assert p.max_isometric_forces()["VL"] == pytest.approx(1871.0 * p.factors[ke])
    assert p.strength_factors()["SOL"] == pytest.approx(p.factors[pf])
    # the residual term d (Eq. 16) finds the constant offset of the simulation
    np.testing.assert_allclose(p.residual, tr.offset, atol=4.0)
    assert p.r2 > 0.9 and np.all(p.r2_per_coordinate > 0.9)
    assert p.selected.all() and np.isfinite(p.gating_r[:, ke, 1]).all()
    # held-out trial: prediction and score
    ho = gait_trial(leg, n_cycles=4, seed=99)
    a2, s2 = _inputs(leg, ho)
    assert idf.score(ho.jacobian, a2, ho.tau, s2) > 0.9
    with pytest.raises(FrozenInstanceError):
        p.r2 = 0.0  # type: ignore[misc]
    assert "knee_extensors" in p.table()


#: subjects (motion, excitation and noise seeds) of the coverage test
N_COVERAGE_SEEDS = 120


@pytest.mark.slow
@pytest.mark.parametrize("n_cycles", [12, 24])
def test_confidence_intervals_are_honest_at_12_and_24_cycles(leg, n_cycles):
    """Issue 8: the true factor lies inside the 95 % intervals in ≥ 90 % of random subjects,
    for every group, with 12 *and* 24 cycles, and the known strengths are recovered.

    Estimator: phase-averaged IV (no errors-in-variables attenuation, which least squares
    keeps at any number of cycles while its interval shrinks), delete-one-cycle jackknife-t
    interval and BCa bootstrap, both rebuilding the instruments from the cycles they keep.
    Least squares (the default) is checked too at 12 cycles, where its interval is still wider
    than its bias; at 24 cycles it is not (0.87–0.97 per group, down to 0.80 on 30-seed
    subsets).
    Measured over these 120 seeds (docs/validation.md): jackknife-t ≥ 0.98 / 0.92 and BCa
    ≥ 0.97 / 0.90 per group at 12 / 24 cycles. 120 seeds, not 30: a 95 % interval covers a
    30-seed set ≥ 90 % only with ≈ 80 % probability per group (binomial; 30-seed subsets of
    these seeds at 24 cycles range 0.83–1.0), 120 seeds halve that Monte Carlo error.
    """
    inside = {k: np.zeros((N_COVERAGE_SEEDS, 6), dtype=bool) for k in ("jk", "boot", "ls")}
    err = np.zeros((N_COVERAGE_SEEDS, 6))
    for seed in range(N_COVERAGE_SEEDS):
        tr = gait_trial(leg, n_cycles=n_cycles, seed=seed)
        a, s = _inputs(leg, tr)
        p = (
            StrengthIdentifier(
                leg.groups,
                leg.params,
                instrument="phase_average",
                n_bootstrap=150,
                random_state=seed,
            )
            .fit(tr.jacobian, a, tr.tau, s, windows=tr.cycle)
            .profile_
        )
        truth = _truth(p.group_names)
        # a group gated out keeps its generic value (1): count it as covered only if true is 1
        ok = ~p.identified & (truth == 1.0)
        inside["boot"][seed] = ok | ((p.ci_low <= truth) & (truth <= p.ci_high))
        inside["jk"][seed] = ok | ((p.ci_cov_low <= truth) & (truth <= p.ci_cov_high))
        err[seed] = p.factors / truth - 1
        idn = p.identified
        assert np.all(p.ci_low[idn] <= p.factors[idn] + 1e-12)
        assert np.all(p.factors[idn] <= p.ci_high[idn] + 1e-12)
        if n_cycles == 12:
            q = (
                StrengthIdentifier(leg.groups, leg.params, n_bootstrap=0)
                .fit(tr.jacobian, a, tr.tau, s, windows=tr.cycle)
                .profile_
            )
            inside["ls"][seed] = (~q.identified & (truth == 1.0)) | (
                (q.ci_cov_low <= truth) & (truth <= q.ci_cov_high)
            )
    cover = {k: v.mean(axis=0) for k, v in inside.items()}
    assert cover["jk"].min() >= 0.9, cover
    # BCa at 24 cycles measured 0.900 exactly: the jackknife-t interval is the one asserted at
    # 0.9, the bootstrap with a margin for platform round-off in the resampled fits
    assert cover["boot"].min() >= 0.875, cover
    if n_cycles == 12:
        assert cover["ls"].min() >= 0.9, cover
    # recovery: knee extensors ×1.7 and plantar flexors ×0.6 within 10 % for every subject,
    # every group within 10 % on average (hip and ankle-dorsiflexor groups are less determined)
    ke, pf = p.group_names.index("knee_extensors"), p.group_names.index("plantar_flexors")
    assert np.abs(err[:, [ke, pf]]).max() < 0.10, err[:, [ke, pf]]
    assert np.all(np.abs(err.mean(axis=0)) < 0.03), err.mean(axis=0)
    assert np.all(np.median(np.abs(err), axis=0) < 0.10), err


def test_correlation_gate_rejects_a_group_whose_emg_does_not_follow_the_torque(leg):
    """Replace the hip-flexor electrode by unrelated noise: the gate flags it and its factor
    stays generic, the other groups are still recovered."""
    tr = gait_trial(leg, n_cycles=12, seed=4)
    rng = np.random.default_rng(0)
    emg = tr.emg.copy()
    junk = np.clip(0.3 + 0.1 * rng.standard_normal(emg.shape[0]), 0, 1)
    emg[:, leg.muscle_names.index("ILPSO")] = junk
    a = emg_to_activation(emg, **ACT)
    s = rigid_tendon_state(leg.params, tr.muscle_tendon_length, tr.lengthening_velocity)
    p = (
        StrengthIdentifier(leg.groups, leg.params, n_bootstrap=50)
        .fit(tr.jacobian, a, tr.tau, s, windows=tr.cycle)
        .profile_
    )
    hf = p.group_names.index("hip_flexors")
    assert not p.identified[hf]
    assert p.factors[hf] == 1.0 and np.isnan(p.ci_low[hf])
    assert np.nanmax(p.gating_r[:, hf, 0]) < p.gate_threshold
    ke = p.group_names.index("knee_extensors")
    assert abs(p.factors[ke] / 1.7 - 1) < 0.1


def test_no_window_passing_the_gate_raises(leg):
    tr = gait_trial(leg, n_cycles=4, seed=2)
    a, s = _inputs(leg, tr)
    rng = np.random.default_rng(1)
    with pytest.raises(IdentificationError, match="correlation gate"):
        StrengthIdentifier(leg.groups, leg.params, gate_threshold=0.99).fit(
            tr.jacobian, a, rng.standard_normal(tr.tau.shape), s, windows=tr.cycle
        )


# ---------------------------------------------------------------------------------------------
# identified parameters flow back: W_emg study (seeds/002 Table I)
# ---------------------------------------------------------------------------------------------
def test_identified_strengths_make_the_emg_weighted_qp_stable_across_w_emg(leg):
    tr = gait_trial(leg, n_cycles=6, seed=3)
    a, s = _inputs(leg, tr)
    p = (
        StrengthIdentifier(leg.groups, leg.params, n_bootstrap=0)
        .fit(tr.jacobian, a, tr.tau, s, windows=tr.cycle)
        .profile_
    )
    unit = a * s.f_active_length * s.f_velocity * s.cos_pennation
    n = 300
    res = w_emg_stability(
        tr.jacobian[:n],
        tr.tau[:n] - p.residual,
        unit[:n],
        np.ones(15, dtype=bool),
        leg.params.max_isometric_force,
        p.muscle_f_iso,
        muscle_names=leg.muscle_names,
    )
    assert res.max_force_generic.shape == (7, 15)
    for m in ("RF", "VL", "SOL", "MG"):
        i = leg.muscle_names.index(m)
        assert res.spread_identified[i] < 0.5 * res.spread_generic[i], res.table(m)
    # identified: the τ error falls as W_emg decreases (the τ term dominates), as in Table I
    assert np.all(np.diff(res.torque_error_identified) < 0)
    assert "spread" in res.table("RF")


# ---------------------------------------------------------------------------------------------
# comparison tables (seeds/003 Tables 4.1, 4.5-4.7)
# ---------------------------------------------------------------------------------------------
def test_comparison_tables_against_hand_computed_values():
    t = np.linspace(0.0, 1.0, 101)
    gen = np.column_stack([np.sin(np.pi * t), 2 * np.sin(np.pi * t)])
    opt = np.column_stack([0.5 * np.sin(np.pi * t), np.sin(np.pi * t)])
    tab = area_ratio_table({"scaled": gen, "optimized": opt}, [("scaled", "optimized")], ["A", "B"])
    np.testing.assert_allclose(tab.values[:, 0], [2.0, 2.0])
    assert tab.get("B", "scaled/optimized") == pytest.approx(2.0)
    net = net_joint_force(gen, ["A", "B"], positive=["B"], negative=["A"])
    np.testing.assert_allclose(net, np.sin(np.pi * t))
    nt = net_force_table({"x": net, "y": net + 1.0}, [("x", "y")])
    assert nt.get("x/y", "rms_N") == pytest.approx(1.0)
    assert nt.get("x/y", "peak_diff_N") == pytest.approx(-1.0)
    assert nt.get("x/y", "nrms") == pytest.approx(1.0 / np.ptp(net))
    mt = moment_fit_table(gen, gen, ["knee", "ankle"])
    np.testing.assert_allclose(mt.values[:, 0], 1.0)
    assert "Table 4.1" in mt.to_text()
    with pytest.raises(ShapeMismatchError):
        net_joint_force(gen, ["A", "B"], positive=["C"], negative=[])


def test_with_strength_scales_the_model_muscles():
    from msk.datasets.models import leg_model
    from msk.exceptions import ModelError
    from msk.muscles.path import Muscle, PathPoint

    muscles = [
        Muscle(
            n,
            (PathPoint("o", "pelvis", np.zeros(3)), PathPoint("i", "tibia", np.zeros(3))),
            f,
            0.1,
            0.3,
        )
        for n, f in (("RF", 1000.0), ("VL", 2000.0))
    ]
    model = leg_model().with_muscles(muscles)
    new = with_strength(model, {"RF": 1.5})
    assert [m.max_isometric_force for m in new.muscles] == [1500.0, 2000.0]
    assert model.muscles[0].max_isometric_force == 1000.0
    with pytest.raises(ModelError, match="XX"):
        with_strength(model, {"XX": 1.0})
    with pytest.raises(ModelError, match="> 0"):
        model.with_strength({"RF": 0.0})


def test_default_windows_and_coordinate_selection(leg):
    tr = gait_trial(leg, n_cycles=10, seed=6)
    a, s = _inputs(leg, tr)
    idf = StrengthIdentifier(
        leg.groups, leg.params, coordinates=("knee_flexion", "ankle_dorsiflexion"), n_windows=10
    )
    p = idf.fit(tr.jacobian, a, tr.tau, s, coordinate_names=tr.coordinate_names).profile_
    assert idf.coordinates_ == ("knee_flexion", "ankle_dorsiflexion")
    assert p.selected.shape == (10, 3) and not p.selected[:, 0].any()
    assert p.residual[0] == 0.0 and np.isnan(p.r2_per_coordinate[0])
    # hip groups act only on the hip: not identified, kept generic
    for g in ("hip_flexors", "hip_extensors"):
        assert not p.identified[p.group_names.index(g)]
    ke = p.group_names.index("knee_extensors")
    assert abs(p.factors[ke] / 1.7 - 1) < 0.1
    pred = idf.predict(tr.jacobian, a, s)
    assert pred.shape == tr.tau.shape
    with pytest.raises(IdentificationError, match="unknown coordinate"):
        StrengthIdentifier(leg.groups, leg.params, coordinates=("elbow",)).fit(
            tr.jacobian, a, tr.tau, s, coordinate_names=tr.coordinate_names
        )


def test_phase_averaged_instrument_removes_the_emg_noise_attenuation(leg):
    """Least squares on noisy-EMG regressors is attenuated (errors in variables); the IV with
    the leave-one-cycle-out phase-averaged activation is not. What the IV keeps is the bias of
    the activation itself (the concave Eq. 7 nonlinearity makes zero-mean envelope noise a
    negative activation bias, so the factors come out slightly high). Mean over 10 subjects,
    20 % envelope noise: measured LS −3.8 % / −2.6 %, IV +1.9 % / +1.6 % (KE / PF)."""
    err_ls, err_iv = [], []
    for seed in range(10):
        tr = gait_trial(leg, n_cycles=16, seed=seed, emg_mult_noise=0.2, tau_noise=0.01)
        a, s = _inputs(leg, tr)
        out = []
        for inst in ("none", "phase_average"):
            p = (
                StrengthIdentifier(leg.groups, leg.params, n_bootstrap=0, instrument=inst)
                .fit(tr.jacobian, a, tr.tau, s, windows=tr.cycle)
                .profile_
            )
            truth = _truth(p.group_names)
            sel = [p.group_names.index(g) for g in ("knee_extensors", "plantar_flexors")]
            out.append(p.factors[sel] / truth[sel] - 1)
        err_ls.append(out[0])
        err_iv.append(out[1])
        assert "IV" in p.method
    bias_ls = np.mean(err_ls, axis=0)
    bias_iv = np.mean(err_iv, axis=0)
    assert np.all(bias_ls < -0.02), bias_ls  # attenuated
    assert np.all(np.abs(bias_iv) < 0.8 * np.abs(bias_ls)), (bias_iv, bias_ls)
    assert np.all(bias_iv > 0), bias_iv
    assert np.max(np.abs(err_iv)) < 0.1


def test_without_intervals_the_factors_are_those_of_the_whole_fit(leg):
    """``intervals=False`` (a repeated identification for a derivative) skips the jackknife and
    the bootstrap: the same factors, statuses and fit, bit for bit; no standard error or
    interval (NaN)."""
    tr = gait_trial(leg, n_cycles=8, seed=4, emg_mult_noise=0.1, tau_noise=0.01)
    a, s = _inputs(leg, tr)
    for inst in ("none", "phase_average"):
        idf = StrengthIdentifier(leg.groups, leg.params, n_bootstrap=20, instrument=inst)
        full = idf.fit(tr.jacobian, a, tr.tau, s, windows=tr.cycle).profile_
        idf = StrengthIdentifier(leg.groups, leg.params, n_bootstrap=20, instrument=inst)
        bare = idf.fit(tr.jacobian, a, tr.tau, s, windows=tr.cycle, intervals=False).profile_
        assert np.isfinite(full.std_error[full.identified]).all()
        np.testing.assert_array_equal(bare.factors, full.factors)
        np.testing.assert_array_equal(bare.identified, full.identified)
        np.testing.assert_array_equal(bare.r2_per_coordinate, full.r2_per_coordinate)
        for name in ("std_error", "ci_low", "ci_high", "ci_cov_low", "ci_cov_high"):
            assert np.isnan(getattr(bare, name)).all(), name


# ---------------------------------------------------------------------------------------------
# with MVC trials (issue 17): every excited group recovered, honest intervals, the others not
# ---------------------------------------------------------------------------------------------
#: subjects of the MVC recovery tests (≥ 100: the Monte Carlo error of a coverage is ≈ 2.5 pp)
N_MVC_SEEDS = 120


def _gait_and_mvc(leg, seed, *, silent=(), mvc_groups=None):
    tr = concatenate_trials(
        gait_trial(leg, n_cycles=12, seed=seed, silent_groups=silent),
        mvc_trials(leg, seed=seed, groups=mvc_groups, repetitions=5),
    )
    a, s = _inputs(leg, tr)
    return tr, a, s


@pytest.mark.slow
def test_mvc_trials_recover_every_group_within_10_percent_with_honest_intervals(leg):
    """Issue 17: 12 gait cycles + 5 isometric MVC repetitions per action (flexion and extension
    of hip, knee, ankle: Hayashibe et al., IROS 2011, §VI.A), EMG on the MVC scale. With the
    phase-averaged IV, each action's repetitions instrumenting each other (``movements``), and
    the stratified jackknife-t interval with Satterthwaite degrees of freedom, every group —
    dorsiflexors and hip groups included (gait alone: up to 21 % off) — is within 10 % for
    every subject, and the 95 % interval covers the truth in ≥ 90 % of them.
    Measured (120 seeds): max error 2.1–4.5 %, coverage 0.91–0.97 per group.
    """
    inside = np.zeros((N_MVC_SEEDS, 6), dtype=bool)
    err = np.zeros((N_MVC_SEEDS, 6))
    for seed in range(N_MVC_SEEDS):
        tr, a, s = _gait_and_mvc(leg, seed)
        p = (
            StrengthIdentifier(leg.groups, leg.params, instrument="phase_average", n_bootstrap=0)
            .fit(tr.jacobian, a, tr.tau, s, windows=tr.cycle, movements=tr.movement)
            .profile_
        )
        truth = _truth(p.group_names)
        assert p.identified.all(), (seed, p.table())
        inside[seed] = (p.ci_cov_low <= truth) & (truth <= p.ci_cov_high)
        err[seed] = p.factors / truth - 1
    assert np.abs(err).max(axis=0).max() < 0.10, np.abs(err).max(axis=0)
    assert inside.mean(axis=0).min() >= 0.90, inside.mean(axis=0)


@pytest.mark.slow
def test_groups_the_data_do_not_excite_are_never_identified(leg):
    """Hip flexors and extensors silent in the gait trial (baseline excitation only) and no hip
    MVC: over 100 subjects they never come out ``identified`` (msk.status): the correlation gate
    keeps them generic (``prior``), or their interval says ``not determined`` / ``at bound``;
    the knee and ankle groups, excited by gait and MVC, are ``identified`` within 10 %."""
    hip = ("hip_flexors", "hip_extensors")
    knee_ankle = [g for g in leg.groups if g not in hip]
    counts: dict[str, dict[str, int]] = {g: {} for g in leg.groups}
    for seed in range(100):
        tr, a, s = _gait_and_mvc(leg, seed, silent=hip, mvc_groups=knee_ankle)
        p = (
            StrengthIdentifier(
                leg.groups,
                leg.params,
                instrument="phase_average",
                n_bootstrap=40,
                random_state=seed,
            )
            .fit(tr.jacobian, a, tr.tau, s, windows=tr.cycle, movements=tr.movement)
            .profile_
        )
        for g, status in zip(p.group_names, p.statuses()):
            counts[g][status] = counts[g].get(status, 0) + 1
        ka = [p.group_names.index(g) for g in knee_ankle]
        np.testing.assert_allclose(p.factors[ka], _truth(knee_ankle), rtol=0.10)
    for g in hip:
        assert "identified" not in counts[g], counts
    for g in knee_ankle:
        assert counts[g].get("identified", 0) >= 95, counts


def test_movements_must_each_have_three_windows_for_the_instrument(leg):
    tr, a, s = _gait_and_mvc(leg, 0, mvc_groups=["dorsiflexors"])
    mov = tr.movement.copy()
    mov[tr.cycle == tr.cycle.max()] = 7  # the last MVC repetition alone in its movement
    idf = StrengthIdentifier(leg.groups, leg.params, instrument="phase_average", n_bootstrap=0)
    with pytest.raises(IdentificationError, match="≥ 3 windows per movement"):
        idf.fit(tr.jacobian, a, tr.tau, s, windows=tr.cycle, movements=mov)
    split = tr.movement.copy()
    split[np.flatnonzero(tr.cycle == 0)[:10]] = 5  # window 0 spans two movements
    with pytest.raises(IdentificationError, match="window 0 spans 2 movements"):
        idf.fit(tr.jacobian, a, tr.tau, s, windows=tr.cycle, movements=split)
    with pytest.raises(ShapeMismatchError, match="movements"):
        idf.fit(tr.jacobian, a, tr.tau, s, windows=tr.cycle, movements=mov[:5])


def test_gating_windows_follow_the_solvable_runs_when_equal_chunks_are_too_short():
    """UNIPD Walking1's pattern (60 Hz, envelope low-passed at 6 Hz: windows ≥ 3/(π·6) s =
    10 frames): 51 solvable frames in runs of 5 (swing), 35 (the stance on the plate), 4 and
    7 (swing). Ten equal chunks would be 5 frames, straddling the gaps; the runs give the
    stance three windows of ≥ 10 frames inside it and leave the swing bits out. A trial
    whose equal chunks are long enough keeps the identifier's default."""
    from msk.strength.identification import envelope_window_s, gating_windows

    assert envelope_window_s(6.0) == pytest.approx(0.159, abs=1e-3)
    frames = np.concatenate(
        [np.arange(131, 136), np.arange(147, 182), np.arange(193, 197), np.arange(206, 213)]
    )
    keep, labels = gating_windows(frames, 60.0, envelope_window_s(6.0))
    assert labels is not None
    np.testing.assert_array_equal(frames[keep], np.arange(147, 182))
    assert labels.max() + 1 == 3
    counts = np.bincount(labels)
    assert counts.min() >= 10 and counts.sum() == 35
    # each window one contiguous piece of the stance
    for w in range(3):
        assert np.all(np.diff(frames[keep][labels == w]) == 1)
    keep2, labels2 = gating_windows(np.arange(600), 60.0, envelope_window_s(6.0))
    assert labels2 is None and keep2.all()
