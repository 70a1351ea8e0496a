"""Each identification step of msk.fes.identify on short synthetic data (fast)."""

from __future__ import annotations

import numpy as np
import pytest

from msk.exceptions import IdentificationError, MissingDataError
from msk.fes.identify import (
    calcium_gain,
    cross_validate,
    force_length_factor,
    identify_force_length,
    identify_isometric_transients,
    identify_pendulum_linear,
    identify_pendulum_nonlinear,
    identify_recruitment_pw,
    identify_series_stiffness,
    identify_static_torque,
    shank_anthropometry,
)
from msk.fes.model import SEED001_SUBJECT, TABLE3, KneeParams
from msk.fes.protocol import IsometricTrial, fibre_fraction
from msk.fes.simulate import simulate
from msk.fes.stimulation import Stimulation, pulse_train, stimulation_from_profile

RNG = np.random.default_rng(42)
EMPTY = Stimulation(np.zeros(0), np.zeros(0))


def test_static_torque_linear_least_squares() -> None:
    th = np.deg2rad(np.arange(0, 91, 5.0))
    tq = 11.1 * np.sin(th)
    r = identify_static_torque(th, tq)
    assert r.K == pytest.approx(11.1)
    assert r.nrmsd == pytest.approx(0.0, abs=1e-10)
    noisy = identify_static_torque(th, tq + RNG.normal(0, 0.111, th.size))
    assert noisy.K == pytest.approx(11.1, rel=0.02)
    assert 0.2 < noisy.nrmsd < 2.0
    with pytest.raises(IdentificationError):
        identify_static_torque(np.zeros(3), np.zeros(3))


def test_pendulum_seed001_keq_and_fv() -> None:
    """seeds/001 §V: K_eq = ω_n² J = 12.115 N·m/rad, F_v = 2 ζ ω_n J = 0.201 N·m·s/rad."""
    k = SEED001_SUBJECT.knee
    omega_n, zeta = k.omega_n, k.zeta  # 5.94 rad/s, 0.049: implied by Table I
    t = np.arange(0, 12, 0.04)  # the seed's 40 ms goniometer period
    wd = omega_n * np.sqrt(1 - zeta**2)
    y = np.deg2rad(20) * np.exp(-zeta * omega_n * t) * np.cos(wd * t)
    r = identify_pendulum_linear(t, y, J=0.343)
    assert r.K_eq == pytest.approx(12.1, abs=0.05)
    assert r.B == pytest.approx(0.201, abs=2e-3)
    assert r.K_eq - 4.026 * 9.8 * 0.194 == pytest.approx(4.441, abs=0.05)
    # seeds/000 variant: K known, J derived
    r0 = identify_pendulum_linear(t, y, K_eq=k.K_eq)
    assert r0.J == pytest.approx(0.343, rel=1e-3)


def test_pendulum_nonlinear_removes_large_drop_bias() -> None:
    s = TABLE3["S3L"]
    tr = simulate(s, EMPTY, duration=6.0, x0=np.array([np.deg2rad(50), 0, 0, 0]))
    t, y = tr.time[::5], tr.theta_r[::5] + RNG.normal(0, np.deg2rad(0.5), tr.time[::5].size)
    lin = identify_pendulum_linear(t, y, K_eq=s.knee.K)
    nl = identify_pendulum_nonlinear(t, y, K=s.knee.K, init=lin)
    assert abs(lin.J / 0.29 - 1) > 0.02  # sin θ ≈ θ biases the linear estimate at 50°
    assert nl.J == pytest.approx(0.29, rel=0.01)
    assert nl.B == pytest.approx(0.19, rel=0.03)
    assert nl.nrmsd < lin.nrmsd


def test_anthropometry_seed001_mass() -> None:
    a = shank_anthropometry(66.0, 1.75)
    assert a.mass == pytest.approx(4.026)  # seeds/001 Table I, exactly Winter's 0.061
    assert 0.15 < a.L_og < 0.3 and 0.2 < a.J < 0.5


def _iso_forces(s, angles, level, duration=8.0):  # type: ignore[no-untyped-def]
    out = []
    for a in angles:
        st = stimulation_from_profile(np.array([0.0, duration]), np.array([level, level]))
        tr = simulate(s, st, duration=duration, isometric_angle=a)
        out.append(tr.F_c[-250:].mean())
    return np.array(out)


def test_force_length_exact_with_series_elongation() -> None:
    s = TABLE3["S10R"]
    angles = np.deg2rad([90, 80, 70, 60, 50, 40, 30])
    f = _iso_forces(s, angles, 300e-6)
    rho = fibre_fraction(s)
    r = identify_force_length(angles, f, geometry=s.geometry, fibre_fraction=rho, k_s=s.muscle.k_s)
    assert r.b == pytest.approx(s.muscle.b, rel=5e-3)
    assert r.L_c0 == pytest.approx(s.muscle.L_c0, rel=2e-3)
    rigid = identify_force_length(angles, f, geometry=s.geometry, fibre_fraction=rho)
    assert abs(rigid.b / s.muscle.b - 1) > abs(r.b / s.muscle.b - 1)  # seed's rigid SE biases b
    with pytest.raises(IdentificationError, match="deg"):
        identify_force_length(angles, -f, geometry=s.geometry, fibre_fraction=rho)


def test_recruitment_pw_recovers_sigmoid() -> None:
    s = TABLE3["S10R"]
    angle = np.deg2rad(60)
    pws = np.linspace(0, 420e-6, 13)
    f = np.array([_iso_forces(s, [angle], p)[0] if p > 0 else 0.0 for p in pws])
    r = identify_recruitment_pw(pws, f, knee_angle=angle, subject=s, stiffness_ratio=600.0)
    a1 = s.recruitment(420e-6)
    assert r.c2 == pytest.approx(8.12, rel=0.02)
    assert r.c3 == pytest.approx(0.75, rel=0.01)
    assert r.c1 == pytest.approx(1.15 / a1, rel=0.01)  # normalised so that α(PW_max) ≈ 1
    assert r.c1 * r.F_cm == pytest.approx(1.15 * 300, rel=0.01)  # the identifiable product
    assert r.K_cm == pytest.approx(600.0 * r.F_cm)
    assert calcium_gain(s.calcium, 20.0) == pytest.approx(0.922, abs=2e-3)
    assert force_length_factor(s, angle, 0.0) <= 1.0


def _short_dynamic(s):  # type: ignore[no-untyped-def]
    t = np.array([0, 0.3, 1.3, 2.0, 2.6, 2.6001, 3.4, 3.4001, 4.0])
    lv = np.array([0, 0, 420, 420, 0, 0, 350, 0, 0]) * 1e-6
    st = stimulation_from_profile(t, lv)
    tr = simulate(s, st, duration=4.0)
    return st, tr.time[::5], tr.theta_r[::5]


def test_series_stiffness_nlp_recovers_ks() -> None:
    s = TABLE3["S3L"]
    st, t, y = _short_dynamic(s)
    y = y + RNG.normal(0, np.deg2rad(0.5), y.size)
    r = identify_series_stiffness(t, y, st, s, k_s0=3e3)
    assert r.solver_status == "Solve_Succeeded"
    assert r.k_s == pytest.approx(10e3, rel=0.03)
    assert r.nrmsd < r.nrmsd_initial
    assert r.nrmsd < 2.0
    cv = cross_validate(t, y, st, s.with_muscle(k_s=r.k_s))
    assert cv.nrmsd == pytest.approx(r.nrmsd, rel=0.05)
    with pytest.raises(MissingDataError):
        identify_series_stiffness(t[:5], y[:5], st, s)


def test_knee_params_linear_pendulum_identities() -> None:
    k = KneeParams(J=0.3, B=0.2, K=10.0, K_e=2.0)
    assert k.omega_n**2 * k.J == pytest.approx(k.K_eq)
    assert 2 * k.zeta * k.omega_n * k.J == pytest.approx(k.B)


def test_isometric_transients_refit_from_short_trains() -> None:
    """1.5 s trains (the seed's): the force is still rising, the transient fit recovers truth."""
    s = TABLE3["S10R"]
    trials = []
    for angle_deg, pw in ((30, 420e-6), (60, 420e-6), (90, 420e-6), (60, 250e-6), (60, 320e-6)):
        st = pulse_train(pw, duration=1.5, t_start=0.2)
        a = np.deg2rad(angle_deg)
        tr = simulate(s, st, duration=2.0, isometric_angle=a)
        trials.append(IsometricTrial(a, st, tr.time, tr.torque))
    start = s.with_muscle(F_cm=250.0, b=0.45, L_c0=0.095).with_recruitment(
        type(s.recruitment)(1.15, 6.0, 0.65)
    )
    r = identify_isometric_transients(
        trials, start, fibre_fraction=fibre_fraction(s), stiffness_ratio=600.0
    )
    a1 = s.recruitment(420e-6)
    assert r.F_cm == pytest.approx(300.0 * a1, rel=0.01)
    assert r.b == pytest.approx(0.54, rel=0.01)
    assert r.L_c0 == pytest.approx(0.0918, rel=0.01)
    assert (r.c2, r.c3) == pytest.approx((8.12, 0.75), rel=0.02)
    assert r.nrmsd < 0.1
    assert r.torque.shape == r.torque_fit.shape == (r.time.size, 5)


def test_series_stiffness_solver_failures_are_typed() -> None:
    """Empty k_s box, NaN data: IdentificationError naming the step, leg and values."""
    s = TABLE3["S3L"]
    st, t, y = _short_dynamic(s)
    with pytest.raises(IdentificationError, match=r"k_s NLP .*S3L.*empty k_s box"):
        identify_series_stiffness(t, y, st, s, k_s_bounds=(2e6, 1e6))
    bad = y.copy()
    bad[10] = np.nan
    with pytest.raises(IdentificationError, match=r"k_s NLP .*S3L.*F_cm = 438"):
        identify_series_stiffness(t, bad, st, s, k_s0=3e3)


def test_ks_lower_bound_admits_every_table3_leg() -> None:
    """The default k_s bound comes from Table 3 (max F_cm/(k_s L_c0) = 2.76, S3R) × 2."""
    from msk.fes.priors import KS_STRETCH_MAX_TABLE3, k_s_lower_bound

    assert KS_STRETCH_MAX_TABLE3 == pytest.approx(523 / (2100 * 0.0901), rel=1e-9)
    for leg in TABLE3.values():
        m = leg.muscle
        assert m.k_s >= 2 * k_s_lower_bound(m.F_cm, m.L_c0) * (1 - 1e-12)


def test_series_stiffness_nlp_with_free_kcm() -> None:
    """identify_stiffness_ratio's NLP: K_cm 50 % off, everything else right → both recovered."""
    s = TABLE3["S3L"]
    st, t, y = _short_dynamic(s)
    y = y + RNG.normal(0, np.deg2rad(0.5), y.size)
    start = s.with_muscle(K_cm=1.5 * s.muscle.K_cm)
    fixed = identify_series_stiffness(t, y, st, start, k_s0=5e3)
    free = identify_series_stiffness(t, y, st, start, k_s0=5e3, free_K_cm=True)
    assert abs(fixed.k_s / 10e3 - 1) > 0.1  # k_s compensates the wrong K_cm
    assert free.k_s == pytest.approx(10e3, rel=0.03)
    assert free.K_cm == pytest.approx(s.muscle.K_cm, rel=0.03)
    assert free.nrmsd < fixed.nrmsd
