"""msk.muscles.contraction: elastic-tendon contraction dynamics over time (seeds/003 Eq. 8–18)."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from msk.exceptions import MuscleModelError
from msk.muscles.contraction import (
    CONTRACTION_PARAMETER_ORDER,
    contraction_dynamics,
    contraction_functions,
    tendon_force_trajectory,
    trajectory_function,
)
from msk.muscles.hill import LloydBesierCurves, MuscleParameters, equilibrium, rigid_tendon_state

RATE_HZ = 100.0


def _params() -> MuscleParameters:
    # a short-tendon vastus, a long-tendon pennate soleus, a rectus femoris
    return MuscleParameters(
        ("vas_lat", "soleus", "rect_fem"),
        np.array([1870.0, 3550.0, 780.0]),
        np.array([0.084, 0.05, 0.114]),
        np.array([0.157, 0.25, 0.31]),
        np.array([0.0873, 0.4363, 0.0873]),
        np.array([10.0, 8.0, 10.0]),
    )


def _walk_like(duration_s: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """1 Hz activations in [0.05, 0.95] and muscle–tendon lengths (±2–4 cm) at 100 Hz."""
    t = np.arange(0.0, duration_s + 1e-9, 1.0 / RATE_HZ)
    w = 2.0 * np.pi
    act = np.column_stack([0.5 + 0.45 * np.sin(w * t + ph) for ph in (0.0, 1.0, 2.0)])
    lmt = np.column_stack(
        [
            l0 + amp * np.sin(w * t + ph)
            for l0, amp, ph in ((0.25, 0.03, 0.5), (0.30, 0.02, 1.5), (0.43, 0.04, 2.5))
        ]
    )
    return t, act, lmt


def _pmat(p: MuscleParameters, curves: LloydBesierCurves, stiffness: float = 1.0) -> np.ndarray:
    m = p.n_muscles
    return np.vstack(
        [
            p.optimal_fiber_length,
            p.tendon_slack_length,
            np.sin(p.pennation_angle_at_optimal),
            p.max_contraction_velocity,
            np.full(m, curves.skew),
            np.full(m, stiffness),
        ]
    )


# ---------------------------------------------------------------------------------------------
# the velocity inversion (Eq. 13) and the force balance (Eq. 8)
# ---------------------------------------------------------------------------------------------
@settings(max_examples=60, deadline=None)
@given(
    lm_rel=st.floats(0.5, 1.6),
    a=st.floats(0.0, 1.0),
    strain=st.floats(-0.01, 0.06),
    k=st.integers(0, 2),
)
def test_velocity_inversion_satisfies_the_force_balance(lm_rel, a, strain, k):
    """At any state, F_iso F̃_t(ε) = F_iso [F̃_A F̃_V a + F̃_P + b_m ṽ] cos φ (Eq. 8) with the
    velocity of the ODE and the numpy curves of msk.muscles.hill (Eq. 10–18)."""
    p = _params()
    curves = LloydBesierCurves()
    lopt = p.optimal_fiber_length[k]
    lm = lm_rel * lopt
    hgt = lopt * np.sin(p.pennation_angle_at_optimal[k])
    cos_p = np.sqrt(max(1.0 - (hgt / lm) ** 2, 0.01))
    lmt = lm * cos_p + p.tendon_slack_length[k] * (1.0 + strain)
    out = np.asarray(
        contraction_functions(curves, 1)["state"](lm, a, lmt, _pmat(p, curves)[:, k])
    ).ravel()
    dl, l_norm, cos_c, _, eps, ft, fa, fp, v_short = out
    assert cos_c == pytest.approx(cos_p, rel=1e-12)
    assert eps == pytest.approx(strain, abs=1e-12)
    # (the casadi ε, not ``strain``: Eq. 17–18 jump by 8e-6 at ε = 0.0127)
    assert ft == pytest.approx(float(curves.tendon_force_strain(eps)[0]), abs=1e-12)
    assert l_norm == pytest.approx(lm / (lopt * float(curves.optimal_length_scale(a))))
    assert fa == pytest.approx(float(curves.active_force_length(l_norm)[0]))
    assert fp == pytest.approx(float(curves.passive_force_length(l_norm)[0]))
    assert dl == pytest.approx(-v_short * p.max_contraction_velocity[k] * lopt)
    fibre = float(curves.tendon_force(a, l_norm, v_short, cos_p, 1.0))
    assert fibre == pytest.approx(ft, abs=1e-10)


def test_force_balance_holds_at_every_step_and_outputs_are_consistent():
    p = _params()
    t, act, lmt = _walk_like()
    s = contraction_dynamics(p, act, lmt, t)
    assert s.fiber_length.shape == (t.size, 3) and s.substeps == 2
    np.testing.assert_allclose(
        s.fiber_force_along_tendon, s.tendon_force, atol=1e-9 * s.tendon_force.max()
    )
    np.testing.assert_allclose(s.tendon_length, lmt - s.fiber_length * s.cos_pennation, atol=1e-15)
    np.testing.assert_allclose(
        s.tendon_strain, s.tendon_length / p.tendon_slack_length - 1.0, atol=1e-12
    )
    # constant-height pennation (Eq. 14)
    hgt = p.optimal_fiber_length * np.sin(p.pennation_angle_at_optimal)
    np.testing.assert_allclose(
        s.fiber_length * np.sin(s.pennation_angle),
        np.broadcast_to(hgt, s.fiber_length.shape),
        rtol=1e-9,
    )
    # the velocity of the ODE is the derivative of the integrated fibre length (2nd order)
    fd = np.gradient(s.fiber_length, t, axis=0)
    np.testing.assert_allclose(fd[5:-5], s.fiber_velocity[5:-5], atol=0.02 * np.ptp(fd))
    assert np.all(s.tendon_force > 0) and np.all(s.tendon_strain < 0.06)


# ---------------------------------------------------------------------------------------------
# limits: static equilibrium, rigid tendon
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("a", [0.0, 0.2, 0.6, 1.0])
def test_constant_inputs_converge_to_the_static_equilibrium(a):
    """At constant a and l_MT the ODE settles on msk.muscles.hill.equilibrium (v = 0), from a
    fibre 5 % of l_opt away from it and from the default initial state."""
    p = _params()
    curves = LloydBesierCurves(skew=0.0)  # hill.equilibrium has no activation-dependent l_opt
    lmt = p.tendon_slack_length + np.array([0.09, 0.05, 0.12])
    eq = equilibrium(p, lmt[None], a, curves=curves)
    t = np.arange(0.0, 1.5, 0.01)
    frames = np.tile(lmt, (t.size, 1))
    start = eq.fiber_length[0] + 0.05 * p.optimal_fiber_length
    s = contraction_dynamics(p, a, frames, t, curves=curves, initial_fiber_length=start)
    assert np.abs(s.fiber_length[0] - eq.fiber_length[0]).max() > 0.004
    np.testing.assert_allclose(s.fiber_length[-1], eq.fiber_length[0], rtol=1e-7)
    np.testing.assert_allclose(s.tendon_force[-1], eq.tendon_force[0], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(s.fiber_velocity[-1], 0.0, atol=1e-6)
    d = contraction_dynamics(p, a, frames[:3], t[:3], curves=curves)
    np.testing.assert_allclose(d.fiber_length, np.tile(eq.fiber_length, (3, 1)), rtol=1e-8)


def test_a_very_stiff_tendon_gives_the_rigid_tendon_state():
    """Tendon 10² and 10⁴ times stiffer: fibre length, velocity, pennation and force approach
    those of the rigid tendon at l_ts (msk.muscles.hill.rigid_tendon_state; Eq. 8 with its
    velocity). One step per sample: the BDF2 velocity then approximates the central difference
    of the sampled l_MT that the rigid state uses."""
    p = _params()
    curves = LloydBesierCurves()
    t, act, lmt = _walk_like()
    r = rigid_tendon_state(p, lmt, np.gradient(lmt, t, axis=0))
    v_short = -r.fiber_velocity / (p.max_contraction_velocity * p.optimal_fiber_length)
    l_norm = r.fiber_length / (p.optimal_fiber_length * curves.optimal_length_scale(act))
    f_rigid = curves.tendon_force(act, l_norm, v_short, r.cos_pennation, p.max_isometric_force)
    sl = slice(5, -5)  # away from the start and the one-sided differences of np.gradient
    errs = []
    for stiffness in (1e2, 1e4):
        s = contraction_dynamics(
            p, act, lmt, t, curves=curves, tendon_stiffness=stiffness, substeps=1, newton=4
        )
        rel = np.abs(s.fiber_length / r.fiber_length - 1.0).max()
        # tendon strain ≤ 4 %/stiffness, l_ts/l_m ≤ 5
        assert rel < 0.2 / stiffness, (stiffness, rel)
        np.testing.assert_allclose(s.cos_pennation, r.cos_pennation, rtol=1e-3)
        vmax = np.abs(r.fiber_velocity).max(axis=0)
        assert np.all(np.abs(s.fiber_velocity - r.fiber_velocity)[sl].max(axis=0) < 0.01 * vmax)
        errs.append(np.abs(s.tendon_force - f_rigid)[sl].max(axis=0) / f_rigid.max(axis=0))
    assert np.all(errs[1] < 0.005), errs
    # the compliant tendon is far from it: that is the point of the elastic model
    e = contraction_dynamics(p, act, lmt, t, curves=curves)
    assert np.abs(e.tendon_force - f_rigid).max(axis=0)[1] > 0.2 * f_rigid[:, 1].max()


# ---------------------------------------------------------------------------------------------
# the integrator
# ---------------------------------------------------------------------------------------------
def test_halving_the_step_converges_at_second_order():
    """BDF2: the change from h to h/2 shrinks about 4× per halving (after the start-up)."""
    p = _params()
    t, act, lmt = _walk_like()
    runs = {ss: contraction_dynamics(p, act, lmt, t, substeps=ss) for ss in (2, 4, 8, 16)}
    sl = slice(20, None)
    d = [
        np.abs(runs[2 * ss].fiber_length[sl] - runs[ss].fiber_length[sl]).max() for ss in (2, 4, 8)
    ]
    order = np.log2(np.array(d[:-1]) / np.array(d[1:]))
    assert np.all(order > 1.6) and np.all(order < 3.0), (d, order)
    df = np.abs(runs[16].tendon_force - runs[8].tendon_force).max(axis=0)
    assert np.all(df < 0.002 * p.max_isometric_force), df


def test_matches_scipy_solve_ivp_on_the_same_ode():
    """Same ODE (the casadi right-hand side, inputs linear between samples) integrated by
    scipy's Radau at rtol 1e-10: 4 substeps agree within 10 µm of fibre (0.2 % F_iso)."""
    p = _params()
    curves = LloydBesierCurves()
    t, act, lmt = _walk_like()
    s = contraction_dynamics(p, act, lmt, t, curves=curves, substeps=4)
    rhs = contraction_functions(curves, 1)["rhs"].map(3)
    pm = _pmat(p, curves)

    def inputs(tt: float) -> tuple[np.ndarray, np.ndarray]:
        return (
            np.array([np.interp(tt, t, act[:, k]) for k in range(3)]),
            np.array([np.interp(tt, t, lmt[:, k]) for k in range(3)]),
        )

    def f(tt: float, y: np.ndarray) -> np.ndarray:
        return np.asarray(rhs(y, *inputs(tt), pm)[0]).ravel()

    def jac(tt: float, y: np.ndarray) -> np.ndarray:
        return np.diag(np.asarray(rhs(y, *inputs(tt), pm)[1]).ravel())

    sol = solve_ivp(
        f,
        (t[0], t[-1]),
        s.fiber_length[0],
        method="Radau",
        t_eval=t,
        jac=jac,
        rtol=1e-10,
        atol=1e-13,
        max_step=0.005,
    )
    assert sol.success
    err = np.abs(sol.y.T - s.fiber_length)
    assert err.max() < 1e-5, err.max(axis=0)
    stiff = 37.5 * p.max_isometric_force / p.tendon_slack_length  # N/m on the linear region
    assert np.all(err.max(axis=0) * stiff < 0.002 * p.max_isometric_force)


def test_casadi_trajectory_equals_numpy_and_is_differentiable():
    """tendon_force_trajectory (symbolic) = contraction_dynamics; its derivative w.r.t. l_ts
    matches a central finite difference of the numpy model."""
    p = _params()
    curves = LloydBesierCurves()
    t, act, lmt = _walk_like(0.4)
    k = 1
    fn = trajectory_function(curves, 2, t.size, 1.0 / RATE_HZ)
    pk = _pmat(p, curves)[:, k]
    ft = np.asarray(fn(act[:, k], lmt[:, k], pk)).ravel()
    s = contraction_dynamics(p, act, lmt, t, curves=curves)
    np.testing.assert_allclose(ft * p.max_isometric_force[k], s.tendon_force[:, k], rtol=1e-10)
    ps = ca.SX.sym("p", len(CONTRACTION_PARAMETER_ORDER))
    expr = tendon_force_trajectory(list(act[:, k]), lmt[:, k], ps, 1.0 / RATE_HZ, curves=curves)
    dft = np.asarray(ca.Function("d", [ps], [ca.jacobian(expr, ps)])(pk))[:, 1]
    step = 1e-6
    hi = MuscleParameters.from_array(p.names, p.to_array() + _bump(k, step))
    lo = MuscleParameters.from_array(p.names, p.to_array() - _bump(k, step))
    fd = (
        contraction_dynamics(hi, act, lmt, t).tendon_force[:, k]
        - contraction_dynamics(lo, act, lmt, t).tendon_force[:, k]
    ) / (2 * step * p.max_isometric_force[k])
    np.testing.assert_allclose(dft, fd, rtol=1e-4, atol=1e-4 * np.abs(fd).max())


def _bump(k: int, step: float) -> np.ndarray:
    """Perturbation of the tendon slack length of muscle ``k`` in the MuscleParameters array."""
    out = np.zeros((3, 5))
    out[k, 2] = step
    return out


def test_bad_input_raises():
    p = _params()
    t, act, lmt = _walk_like(0.1)
    with pytest.raises(MuscleModelError, match="increase"):
        contraction_dynamics(p, act, lmt, t[::-1])
    with pytest.raises(MuscleModelError, match="muscle_tendon_length"):
        contraction_dynamics(p, act, lmt[:, :2], t)
    lmt_bad = lmt.copy()
    lmt_bad[3, 1] = np.nan
    with pytest.raises(MuscleModelError, match="soleus"):
        contraction_dynamics(p, act, lmt_bad, t)
    with pytest.raises(MuscleModelError, match="substeps"):
        contraction_dynamics(p, act, lmt, t, substeps=0)
    with pytest.raises(MuscleModelError, match="tendon_stiffness"):
        contraction_dynamics(p, act, lmt, t, tendon_stiffness=0.0)
