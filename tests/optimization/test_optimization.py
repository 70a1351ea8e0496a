"""Tension optimisation (msk.optimization): closed form, bounded QP, static optimisation, EMG QP."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scipy.optimize import lsq_linear, minimize

from msk.datasets.optimization import leg_like_frames
from msk.datasets.shared import shared_dir
from msk.exceptions import OptimizationError
from msk.optimization import (
    EMGWeightedProblem,
    LagrangeProblem,
    SolveOutput,
    SolverSpec,
    StandardQP,
    StaticOptimizationProblem,
    TensionProblem,
    available_solvers,
    build_coefficient_table,
    emg_weight_sweep,
    lagrange_coefficients,
    register_solver,
    solve,
    solve_emg_assisted_batch,
    solve_emg_weighted_batch,
    solve_lagrange,
    solve_lagrange_batch,
    solve_static_optimization_batch,
    solve_tension_batch,
)
from msk.optimization.opensim_reference import opensim_static_optimization_reference

pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")  # qpsolvers sparse conversion

HSET = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _random_moment_arms(rng: np.random.Generator, m: int, n: int) -> np.ndarray:
    """Sparse leg-like moment arms R (n, m): each muscle crosses 1–2 coordinates, 1–6 cm."""
    r = np.zeros((n, m))
    for i in range(m):
        cs = rng.choice(n, size=int(rng.integers(1, min(2, n) + 1)), replace=False)
        r[cs, i] = rng.choice([-1.0, 1.0], size=cs.size) * rng.uniform(0.01, 0.06, cs.size)
    for c in range(n):  # every coordinate has an agonist and an antagonist
        r[c, 2 * c % m] = 0.03
        r[c, (2 * c + 1) % m] = -0.03
    return r


def _kkt_truth(seed: int, m: int, n: int, f_hi_frac: float):
    """A bounded tension QP whose optimum is known from its KKT conditions.

    For ``min Σ x²  s.t. A x = τ, lb ≤ x ≤ ub`` (x = f/F_iso, A = R F_iso), the point
    ``x* = clip(Aᵀλ/2, lb, ub)`` with ``τ = A x*`` satisfies stationarity with the multipliers
    λ and bound multipliers of the right sign, so it is *the* optimum (strictly convex).
    """
    rng = np.random.default_rng(seed)
    r = _random_moment_arms(rng, m, n)
    f_iso = rng.uniform(200.0, 3000.0, m)
    a = r * f_iso
    lam = rng.normal(0.0, 1.0, n) / np.abs(a).sum(axis=1).mean() * 2.0
    ub = np.full(m, f_hi_frac)
    x = np.clip(a.T @ lam / 2.0, 0.0, ub)
    tau = a @ x
    return r, f_iso, ub * f_iso, x * f_iso, tau


@pytest.fixture(autouse=True)
def _solver_registry_restored():
    """Solvers a test registers are removed after it (the registry is the config's choices:
    ``docs/config.md`` lists them)."""
    from msk.optimization import _qp

    saved = dict(_qp._REGISTRY)
    yield
    _qp._REGISTRY.clear()
    _qp._REGISTRY.update(saved)


# ---------------------------------------------------------------------------------------------
# closed form (seeds/004 Eq. 6)
# ---------------------------------------------------------------------------------------------


def test_lagrange_single_coordinate_is_seed_eq6() -> None:
    rng = np.random.default_rng(3)
    c = rng.normal(0.0, 0.04, 9)
    area = rng.uniform(1e-4, 4e-3, 9)
    tau = 37.5
    sol = solve_lagrange(LagrangeProblem(jacobian=-c[:, None], tau=[tau], area=area))
    eq6 = area**2 * c * tau / np.sum((area * c) ** 2)
    np.testing.assert_allclose(sol.forces, eq6, rtol=1e-13)
    assert sol.residual_norm < 1e-12
    assert np.array_equal(sol.negative, eq6 < 0)
    assert sol.status == ("negative_forces" if (eq6 < 0).any() else "optimal")


def test_lagrange_multi_coordinate_is_stationary_and_flags_negative_forces() -> None:
    rng = np.random.default_rng(4)
    r = _random_moment_arms(rng, 12, 4)
    area = rng.uniform(200, 2000, 12)
    tau = rng.normal(0, 40, 4)
    sol = solve_lagrange(LagrangeProblem(jacobian=-r.T, tau=tau, area=area))
    np.testing.assert_allclose(r @ sol.forces, tau, atol=1e-10)
    # stationarity of Σ(F/A)² − λᵀ(C F − τ): 2 F / A² = Cᵀ λ
    np.testing.assert_allclose(2 * sol.forces / area**2, r.T @ sol.multipliers, atol=1e-12)
    assert sol.negative.any() and sol.status == "negative_forces"
    assert sol.kkt.max() < 1e-8
    # any other feasible force vector costs more
    null = np.linalg.svd(r)[2][4:]
    other = sol.forces + null.T @ rng.normal(0, 50, null.shape[0])
    assert np.sum((other / area) ** 2) > np.sum((sol.forces / area) ** 2)


def test_lagrange_batch_equals_frames() -> None:
    d = leg_like_frames(20, 5, 30, seed=2)
    b = solve_lagrange_batch(d.jacobians, d.taus, area=d.f_iso)
    for k in (0, 11, 29):
        one = solve_lagrange(LagrangeProblem(jacobian=d.jacobians[k], tau=d.taus[k], area=d.f_iso))
        np.testing.assert_allclose(b.forces[k], one.forces, rtol=1e-10, atol=1e-9)
    assert b.residual_norm.max() < 1e-9


@given(seed=st.integers(0, 10_000), m=st.integers(4, 30), n=st.integers(1, 6))
@HSET
def test_closed_form_equals_bounded_qp_when_no_bound_is_active(seed: int, m: int, n: int) -> None:
    m = max(m, 2 * n)
    rng = np.random.default_rng(seed)
    r = _random_moment_arms(rng, m, n)
    f_iso = rng.uniform(200.0, 3000.0, m)
    # λ with Rᵀλ > 0 for every muscle (flip the muscles that oppose it): F = W Rᵀλ/2 > 0
    lam = rng.normal(0.0, 1.0, n)
    s = np.sign(r.T @ lam)
    s[s == 0] = 1.0
    r = r * s
    f_cf = f_iso**2 * (r.T @ lam)
    f_cf *= 0.5 / np.max(f_cf / f_iso)  # largest activation 0.5: no upper bound active
    tau = r @ f_cf
    cf = solve_lagrange(LagrangeProblem(jacobian=-r.T, tau=tau, area=f_iso))
    qp = solve(TensionProblem(jacobian=-r.T, tau=tau, f_iso=f_iso))
    assert not cf.negative.any()
    assert qp.status == "optimal"
    assert not qp.active_upper.any()
    np.testing.assert_allclose(qp.forces, cf.forces, rtol=1e-7, atol=1e-7 * f_iso.max())


# ---------------------------------------------------------------------------------------------
# precomputed coefficient table over a functional DOF (seeds/004 §2.2)
# ---------------------------------------------------------------------------------------------


def _fdof_jacobian(s: np.ndarray, m: int = 10, n: int = 3) -> np.ndarray:
    """Smooth J(s) along a functional path s (knee flexion, rad); (len(s), m, n)."""
    rng = np.random.default_rng(7)
    base = _random_moment_arms(rng, m, n).T
    amp = 0.3 * base * rng.uniform(0.2, 1.0, base.shape)
    w = rng.uniform(0.5, 2.0, base.shape)
    return -(base[None] + amp[None] * np.sin(w[None] * s[:, None, None]))


@pytest.mark.parametrize("kind, order", [("linear", 2), ("cubic", 4)])
def test_coefficient_table_matches_direct_solution(kind: str, order: int) -> None:
    area = np.linspace(300, 2500, 10)
    s_eval = np.linspace(0.05, 1.95, 101)
    rng = np.random.default_rng(8)
    tau = rng.normal(0, 30, (101, 3))
    direct = solve_lagrange_batch(_fdof_jacobian(s_eval), tau, area=area).forces
    errors = []
    for g in (21, 41, 81):
        grid = np.linspace(0.0, 2.0, g)
        table = build_coefficient_table(grid, _fdof_jacobian(grid), area=area, kind=kind)
        errors.append(np.abs(table.forces(s_eval, tau) - direct).max())
    # interpolation error converges at the interpolant's order, and is small at 41 points
    rate = np.log2(errors[0] / errors[1]), np.log2(errors[1] / errors[2])
    assert min(rate) > order - 0.6, (errors, rate)
    assert errors[1] < (2e-2 if kind == "linear" else 2e-4) * np.abs(direct).max()
    # a scalar lookup is the same as the vectorised one, and grid nodes are exact
    table = build_coefficient_table(grid, _fdof_jacobian(grid), area=area, kind=kind)
    np.testing.assert_allclose(table.forces(s_eval[5], tau[5]), table.forces(s_eval, tau)[5])
    np.testing.assert_allclose(
        table.coefficients_at(grid[3]), lagrange_coefficients(_fdof_jacobian(grid[3:4])[0], area)
    )


def test_coefficient_table_refuses_extrapolation() -> None:
    grid = np.linspace(0.0, 2.0, 11)
    table = build_coefficient_table(grid, _fdof_jacobian(grid), area=np.ones(10))
    with pytest.raises(OptimizationError, match=r"frame 1 = 2\.5"):
        table.forces(np.array([1.0, 2.5]), np.zeros((2, 3)))


# ---------------------------------------------------------------------------------------------
# bounded QP: known optimum, KKT, second solver
# ---------------------------------------------------------------------------------------------


@given(seed=st.integers(0, 10_000), m=st.integers(6, 45), n=st.integers(1, 7))
@HSET
def test_bounded_qp_recovers_kkt_truth_and_agrees_with_second_solver(
    seed: int, m: int, n: int
) -> None:
    r, f_iso, f_max, f_true, tau = _kkt_truth(seed, m, n, f_hi_frac=0.6)
    prob = TensionProblem(jacobian=-r.T, tau=tau, f_iso=f_iso, f_max=f_max)
    sol = solve(prob)
    assert sol.status == "optimal"
    assert sol.kkt.max() < 1e-8, sol.kkt
    np.testing.assert_allclose(sol.forces, f_true, rtol=1e-7, atol=1e-7 * f_iso.max())
    assert np.array_equal(sol.active_lower, f_true <= 1e-9 * f_iso)
    for other in ("clarabel", "osqp"):
        sol2 = solve(prob, solver=other)
        assert sol2.status == "optimal" and sol2.solver == other
        scale = np.abs(sol.forces).max() + 1.0
        assert np.abs(sol2.forces - sol.forces).max() < 1e-6 * scale


def test_registry_lists_solvers_accepts_new_and_rejects_unknown() -> None:
    assert {"daqp", "osqp", "clarabel"} <= set(available_solvers())
    d = leg_like_frames(8, 2, 2, seed=1)
    calls = []

    def via_scipy(qp: StandardQP, warm: object) -> SolveOutput:
        calls.append(warm)
        res = minimize(
            lambda x: 0.5 * x @ qp.H @ x + qp.g @ x,
            np.clip(np.zeros(qp.n), qp.lb, qp.ub),
            jac=lambda x: qp.H @ x + qp.g,
            bounds=list(zip(qp.lb, qp.ub)),
            constraints=[{"type": "eq", "fun": lambda x: qp.A @ x - qp.b, "jac": lambda x: qp.A}],
            method="SLSQP",
            options={"ftol": 1e-14, "maxiter": 1000},
        )
        return SolveOutput(x=res.x, ok=bool(res.success), infeasible=False, warm="prev")

    register_solver(SolverSpec("test-slsqp", via_scipy, description="scipy SLSQP (tests)"))
    assert "test-slsqp" in available_solvers()
    a = solve_tension_batch(d.jacobians, d.taus, f_iso=d.f_iso)
    b = solve_tension_batch(d.jacobians, d.taus, f_iso=d.f_iso, solver="test-slsqp")
    assert calls == [None, "prev"] and b.solver == "test-slsqp"
    np.testing.assert_allclose(b.forces, a.forces, atol=1e-5 * a.forces.max())
    with pytest.raises(OptimizationError, match="unknown QP solver 'quadprog'"):
        solve(
            TensionProblem(jacobian=d.jacobians[0], tau=d.taus[0], f_iso=d.f_iso), solver="quadprog"
        )


def test_batch_warm_start_equals_cold_and_single_frames() -> None:
    d = leg_like_frames(43, 7, 60, seed=5)
    warm = solve_tension_batch(d.jacobians, d.taus, f_iso=d.f_iso)
    cold = solve_tension_batch(d.jacobians, d.taus, f_iso=d.f_iso, warm_start=False)
    assert (warm.status == 0).all()
    np.testing.assert_allclose(warm.forces, cold.forces, atol=1e-8)
    assert np.nanmax(warm.kkt) < 1e-8
    # warm start needs fewer active-set iterations than starting from scratch
    assert warm.iterations[1:].sum() < cold.iterations[1:].sum()
    one = solve(TensionProblem(jacobian=d.jacobians[17], tau=d.taus[17], f_iso=d.f_iso))
    np.testing.assert_allclose(warm.forces[17], one.forces, atol=1e-8)
    assert warm.residual_norm.max() < 1e-8
    # the synthetic torques came from known forces: they are feasible, and the optimum costs
    # no more than the truth
    cost = np.sum((warm.forces / d.f_iso) ** 2, axis=1)
    assert np.all(cost <= np.sum(d.activations_true**2, axis=1) + 1e-9)


def test_batch_with_other_solver_agrees() -> None:
    d = leg_like_frames(20, 4, 8, seed=9)
    a = solve_tension_batch(d.jacobians, d.taus, f_iso=d.f_iso)
    b = solve_tension_batch(d.jacobians, d.taus, f_iso=d.f_iso, solver="clarabel")
    np.testing.assert_allclose(b.forces, a.forces, atol=1e-6 * a.forces.max())


# ---------------------------------------------------------------------------------------------
# infeasible frames and reserves
# ---------------------------------------------------------------------------------------------


def test_infeasible_frames_are_reported_with_their_residual() -> None:
    d = leg_like_frames(15, 3, 10, seed=11)
    taus = d.taus.copy()
    taus[[3, 7]] *= 50.0  # beyond the muscles' capacity
    res = solve_tension_batch(d.jacobians, taus, f_iso=d.f_iso)
    assert list(res.infeasible_frames) == [3, 7]
    assert res.forces.shape == (10, 15)  # nothing dropped
    assert np.all(res.residual_norm[[3, 7]] > 1.0)
    assert np.all(np.delete(res.residual_norm, [3, 7]) < 1e-8)
    # the reported point is the bounded least-squares one (independent reference: scipy)
    for k in (3, 7):
        r = -d.jacobians[k].T
        ls = lsq_linear(r, taus[k], bounds=(np.zeros(15), d.f_iso), tol=1e-12)
        assert res.residual_norm[k] == pytest.approx(np.linalg.norm(r @ ls.x - taus[k]), rel=1e-5)
        assert np.all(res.forces[k] >= -1e-9) and np.all(res.forces[k] <= d.f_iso * (1 + 1e-9))
    with pytest.raises(OptimizationError, match=r"frame 3: QP infeasible.*residual"):
        solve_tension_batch(d.jacobians, taus, f_iso=d.f_iso, strict=True)
    with pytest.raises(OptimizationError, match="infeasible"):
        solve(TensionProblem(jacobian=d.jacobians[3], tau=taus[3], f_iso=d.f_iso), strict=True)


def test_reserves_make_every_frame_feasible() -> None:
    d = leg_like_frames(15, 3, 10, seed=11)
    taus = d.taus * 50.0
    res = solve_tension_batch(d.jacobians, taus, f_iso=d.f_iso, reserve_optimal_force=[1.0] * 3)
    assert (res.status == 0).all()
    assert res.residual_norm.max() < 1e-8 * np.abs(taus).max()
    np.testing.assert_allclose(res.torque_error, res.reserve_torques, atol=1e-8)
    assert np.abs(res.reserve_torques).max() > 1.0
    assert np.nanmax(res.kkt) < 1e-8
    # reserves stay idle when the muscles suffice (cost of 1 N·m of reserve ≫ muscles)
    ok = solve_tension_batch(d.jacobians, d.taus, f_iso=d.f_iso, reserve_optimal_force=1.0)
    assert np.abs(ok.reserve_torques).max() < 0.05 * np.abs(d.taus).max()


# ---------------------------------------------------------------------------------------------
# OpenSim-equivalent static optimisation
# ---------------------------------------------------------------------------------------------


@given(seed=st.integers(0, 10_000), m=st.integers(6, 30), n=st.integers(1, 6))
@HSET
def test_static_optimization_recovers_kkt_truth_with_passive_forces(
    seed: int, m: int, n: int
) -> None:
    rng = np.random.default_rng(seed)
    r = _random_moment_arms(rng, m, n)
    f_act = rng.uniform(100.0, 2500.0, m) * rng.uniform(0.3, 1.0, m)  # F_iso f_l f_v cos α
    f_pas = rng.uniform(0.0, 80.0, m) * (rng.random(m) < 0.3)
    a_min = np.full(m, 0.01)  # OpenSim models often use min_control = 0.01
    lam = rng.normal(0.0, 1.0, n) * 4.0 / np.abs(r * f_act).sum(axis=1).mean()
    a_true = np.clip(f_act * (r.T @ lam) / 2.0, a_min, 1.0)
    tau = r @ (a_true * f_act + f_pas)
    prob = StaticOptimizationProblem(
        jacobian=-r.T, tau=tau, f_active=f_act, f_passive=f_pas, activation_min=a_min
    )
    sol = solve(prob)
    assert sol.status == "optimal" and sol.activations is not None
    np.testing.assert_allclose(sol.activations, a_true, atol=1e-8)
    np.testing.assert_allclose(sol.forces, a_true * f_act + f_pas, atol=1e-5)
    assert sol.kkt.max() < 1e-8
    assert sol.objective == pytest.approx(np.sum(a_true**2), rel=1e-8, abs=1e-12)
    sol2 = solve(prob, solver="clarabel")
    assert sol2.activations is not None
    # the interior-point peer reaches the same optimum value; its point may sit 1e-4 off the
    # exact one where several activations are at a bound and the problem is badly scaled
    # (seed 743: 6 muscles, 4 coordinates, activation error 5e-4)
    assert np.sum(sol2.activations**2) == pytest.approx(sol.objective, rel=1e-5, abs=1e-9)
    np.testing.assert_allclose(sol2.activations, sol.activations, atol=1e-3)


@given(
    seed=st.integers(0, 10_000),
    m=st.integers(6, 30),
    n=st.integers(1, 6),
    p=st.sampled_from([2.0, 3.0, 4.0]),
    weighted=st.booleans(),
)
@HSET
def test_static_optimization_weighted_power_criterion_recovers_kkt_truth(
    seed: int, m: int, n: int, p: float, weighted: bool
) -> None:
    """``min Σ w_i a_i^p`` (volume weights, Crowninshield–Brand p = 3): for multipliers λ the
    point ``a = clip((f_act Rᵀλ / (p w))^(1/(p−1)), a_min, 1)`` with ``τ = R (a f_act)`` meets
    the KKT conditions of the strictly convex problem, so it is the optimum; DAQP (QP, or
    sequential QP for p > 2) and Clarabel agree, and the batch equals the frame solve. As
    many torques as muscles (m = n) leaves no choice to optimise — the point is fixed by the
    equalities, and Clarabel's interior point stalls near it (seed 34, m = n = 6: "insufficient
    progress", 1e-4 off): such draws are not this property's."""
    assume(n < m)
    rng = np.random.default_rng(seed)
    r = _random_moment_arms(rng, m, n)
    f_act = rng.uniform(100.0, 2500.0, m) * rng.uniform(0.3, 1.0, m)
    w = rng.uniform(0.2, 5.0, m) if weighted else np.ones(m)
    a_min = np.full(m, 0.01)
    lam = rng.normal(0.0, 1.0, n) * 4.0 / np.abs(r * f_act).sum(axis=1).mean()
    s = f_act * (r.T @ lam) / (p * w)
    a_true = np.clip(np.maximum(s, 0.0) ** (1.0 / (p - 1.0)), a_min, 1.0)
    tau = r @ (a_true * f_act)
    prob = StaticOptimizationProblem(
        jacobian=-r.T,
        tau=tau,
        f_active=f_act,
        activation_min=a_min,
        activation_weights=w if weighted else None,
        activation_exponent=p,
    )
    sol = solve(prob)
    assert sol.status == "optimal" and sol.activations is not None
    np.testing.assert_allclose(sol.activations, a_true, atol=1e-7)
    assert sol.kkt.max() < 1e-8
    assert sol.objective == pytest.approx(np.sum(w * a_true**p), rel=1e-7, abs=1e-12)
    sol2 = solve(prob, solver="clarabel")
    assert sol2.activations is not None
    np.testing.assert_allclose(sol2.activations, sol.activations, atol=1e-6)
    batch = solve_static_optimization_batch(
        (-r.T)[None],
        tau[None],
        f_active=f_act[None],
        activation_min=a_min,
        activation_weights=w if weighted else None,
        activation_exponent=p,
    )
    assert batch.activations is not None and batch.status[0] == 0
    np.testing.assert_allclose(batch.activations[0], sol.activations, atol=1e-9)
    assert batch.kkt[0].max() < 1e-8


def test_static_optimization_power_criterion_shares_load_more_evenly() -> None:
    """Two synergists of capacities 1000 N and 250 N on one coordinate: Σ a² gives
    a₁/a₂ = F₁/F₂ = 4, Σ a³ gives √4 = 2 (a^(p−1) ∝ F), and volume weights w = F give 1."""
    f_act = np.array([1000.0, 250.0])
    jac = -np.array([[0.05], [0.05]])
    tau = np.array([20.0])
    ratio = {}
    for key, w, p in (("a2", None, 2.0), ("a3", None, 3.0), ("vol", f_act / f_act.mean(), 2.0)):
        prob = StaticOptimizationProblem(
            jacobian=jac, tau=tau, f_active=f_act, activation_weights=w, activation_exponent=p
        )
        a = solve(prob).activations
        assert a is not None
        ratio[key] = a[0] / a[1]
    assert ratio["a2"] == pytest.approx(4.0, rel=1e-9)
    assert ratio["a3"] == pytest.approx(2.0, rel=1e-7)
    assert ratio["vol"] == pytest.approx(1.0, rel=1e-9)


@pytest.mark.parametrize(
    ("weights", "exponent"), [([1.0, 0.0], 2.0), ([1.0, np.inf], 2.0), (None, 1.5), (None, np.nan)]
)
def test_static_optimization_rejects_bad_weights_and_exponents(
    weights: list[float] | None, exponent: float
) -> None:
    with pytest.raises(OptimizationError):
        StaticOptimizationProblem(
            jacobian=-np.array([[0.05], [0.04]]),
            tau=np.array([10.0]),
            f_active=np.array([1000.0, 500.0]),
            activation_weights=weights,
            activation_exponent=exponent,
        )


def test_static_optimization_without_passive_is_the_tension_qp_in_activations() -> None:
    d = leg_like_frames(30, 5, 20, seed=12)
    f_act = np.broadcast_to(d.f_iso, (20, 30))
    so = solve_static_optimization_batch(d.jacobians, d.taus, f_active=f_act)
    tq = solve_tension_batch(d.jacobians, d.taus, f_iso=d.f_iso)
    assert so.activations is not None
    np.testing.assert_allclose(so.forces, tq.forces, atol=1e-7)
    np.testing.assert_allclose(so.activations * d.f_iso, so.forces, atol=1e-9)


def test_static_optimization_residual_actuators_with_bounds() -> None:
    d = leg_like_frames(12, 3, 6, seed=13)
    taus = d.taus.copy()
    taus[:, 0] += 500.0  # a "pelvis" load no muscle can carry
    opt = np.array([10.0, 0.0, 0.0])
    res = solve_static_optimization_batch(
        d.jacobians,
        taus,
        f_active=np.broadcast_to(d.f_iso, (6, 12)),
        reserve_optimal_force=opt,
        reserve_min_control=-1e3,
        reserve_max_control=1e3,
    )
    assert (res.status == 0).all()
    assert res.residual_norm.max() < 1e-7
    assert np.all(np.abs(res.reserve_controls[:, 0]) > 1.0)
    assert np.all(res.reserve_controls[:, 1:] == 0.0)
    # a bound on the residual control that is too tight makes the frames infeasible, reported
    tight = solve_static_optimization_batch(
        d.jacobians,
        taus,
        f_active=np.broadcast_to(d.f_iso, (6, 12)),
        reserve_optimal_force=opt,
        reserve_min_control=-1.0,
        reserve_max_control=1.0,
    )
    assert (tight.status == 1).all() and np.all(tight.residual_norm > 1.0)


# ---------------------------------------------------------------------------------------------
# EMG-weighted QP (seeds/002 Eq. 17–18) and the W_emg sweep (Table I)
# ---------------------------------------------------------------------------------------------


def _emg_case(seed: int = 21, noise: float = 0.3):
    """Few muscles, most measured: a real trade-off between torque fit and EMG fit."""
    d = leg_like_frames(10, 3, 25, seed=seed)
    rng = np.random.default_rng(seed)
    f_true = d.activations_true * d.f_iso
    f_ref = f_true * (1.0 + noise * rng.normal(size=f_true.shape))  # noisy EMG-based f*
    f_ref = np.maximum(f_ref, 0.0)
    measured = np.ones(10, dtype=bool)
    measured[[2, 5]] = False
    return d, f_true, f_ref, measured


def test_emg_weighted_limits() -> None:
    d, _, f_ref, measured = _emg_case()
    tau_scale = np.abs(d.taus).max()
    small = solve_emg_weighted_batch(
        d.jacobians, d.taus, f_ref=f_ref, measured=measured, w_emg=1e-12, regularization=1e-12
    )
    assert np.abs(small.torque_error).max() < 1e-6 * tau_scale  # feasible: torque fitted
    assert np.nanmax(small.kkt) < 1e-8
    big = solve_emg_weighted_batch(d.jacobians, d.taus, f_ref=f_ref, measured=measured, w_emg=1e6)
    np.testing.assert_allclose(big.forces[:, measured], f_ref[:, measured], atol=1e-3)
    assert np.nanmax(big.kkt) < 1e-8
    assert np.all(big.forces >= 0.0)


def test_emg_weighted_single_frame_agrees_with_second_solver() -> None:
    d, _, f_ref, measured = _emg_case(seed=22)
    prob = EMGWeightedProblem(
        jacobian=d.jacobians[4], tau=d.taus[4], f_ref=f_ref[4], measured=measured, w_emg=1e-3
    )
    a = solve(prob)
    b = solve(prob, solver="clarabel")
    assert a.kkt.max() < 1e-8
    np.testing.assert_allclose(b.forces, a.forces, atol=1e-6 * a.forces.max())
    np.testing.assert_allclose(a.residual, a.torque_error)
    # objective = seeds/002 Eq. 17 (+ the tiny ε term on the unmeasured muscles)
    r = -d.jacobians[4].T
    eps = 1e-6 * np.mean(np.sum(r * r, axis=0))  # default regularization, relative
    z = 0.5 * np.sum(a.torque_error**2) + 0.5e-3 * np.sum((a.forces - f_ref[4])[measured] ** 2)
    z += 0.5 * eps * np.sum(a.forces[~measured] ** 2)
    assert a.objective == pytest.approx(z, rel=1e-6)


def test_emg_weighted_recovers_known_forces_better_than_plain_static_optimization() -> None:
    """Known truth: forces from random activations; noisy torques and noisy EMG-based f*."""
    d, f_true, f_ref, measured = _emg_case(seed=24, noise=0.1)
    rng = np.random.default_rng(24)
    taus = d.taus + rng.normal(0.0, 0.02 * np.abs(d.taus).std(), d.taus.shape)
    emg = solve_emg_weighted_batch(d.jacobians, taus, f_ref=f_ref, measured=measured, w_emg=1e-3)
    plain = solve_tension_batch(d.jacobians, taus, f_iso=d.f_iso, reserve_optimal_force=1.0)

    def rms(f: np.ndarray, cols: np.ndarray | slice = slice(None)) -> float:
        return float(np.sqrt(np.mean((f[:, cols] - f_true[:, cols]) ** 2)))

    assert rms(emg.forces) < 0.5 * rms(plain.forces)
    # the torque information improves on the noisy EMG reference of the measured muscles
    assert rms(emg.forces, measured) < rms(f_ref, measured)


def test_emg_weight_sweep_trade_off_is_monotone() -> None:
    d, _, f_ref, measured = _emg_case(seed=23)
    ws = [1.0, 0.5, 0.1, 0.05, 0.01, 0.005, 0.001, 1e-4]
    sweep = emg_weight_sweep(
        d.jacobians, d.taus, f_ref=f_ref, measured=measured, w_emgs=ws, regularization=1e-9
    )
    assert sweep.forces.shape == (8, 25, 10)
    err, dev = sweep.torque_error_rms, sweep.emg_deviation_rms
    # W_emg decreasing down the table: torque error decreases, EMG deviation increases
    assert np.all(np.diff(err) <= 1e-9 * err.max()), err
    assert np.all(np.diff(dev) >= -1e-9 * dev.max()), dev
    assert err[0] > 10 * err[-1] and dev[-1] > 2 * dev[0]
    text = sweep.table(muscle="muscle0", coordinate="coord1")
    assert text.count("\n") == 8 and "max muscle0" in text


# ---------------------------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------------------------


def test_bad_input_raises_typed_errors_naming_the_item() -> None:
    d = leg_like_frames(6, 2, 3, seed=1)
    names = [f"m{i}" for i in range(6)]
    f_iso = d.f_iso.copy()
    f_iso[4] = 0.0
    with pytest.raises(OptimizationError, match="'m4'"):
        TensionProblem(jacobian=d.jacobians[0], tau=d.taus[0], f_iso=f_iso, muscle_names=names)
    with pytest.raises(OptimizationError, match="tau has shape"):
        TensionProblem(jacobian=d.jacobians[0], tau=[1.0, 2.0, 3.0], f_iso=d.f_iso)
    with pytest.raises(OptimizationError, match="jacobian has shape"):
        solve_tension_batch(d.jacobians[0], d.taus, f_iso=d.f_iso)
    bad = d.taus.copy()
    bad[1, 1] = np.nan
    with pytest.raises(OptimizationError, match="coord1"):
        solve_tension_batch(d.jacobians, bad, f_iso=d.f_iso)
    with pytest.raises(OptimizationError, match="w_emg"):
        EMGWeightedProblem(
            jacobian=d.jacobians[0], tau=d.taus[0], f_ref=d.f_iso, measured=[0, 1], w_emg=-1.0
        )
    with pytest.raises(OptimizationError, match="activation bounds of muscle 'm2'"):
        StaticOptimizationProblem(
            jacobian=d.jacobians[0],
            tau=d.taus[0],
            f_active=d.f_iso,
            activation_min=[0, 0, 0.5, 0, 0, 0],
            activation_max=[1, 1, 0.2, 1, 1, 1],
            muscle_names=names,
        )


# ---------------------------------------------------------------------------------------------
# OpenSim 4.6 StaticOptimization on gait2392 subject01 walking (real recording), side by side
# ---------------------------------------------------------------------------------------------

PEER_DATA = shared_dir() / "tools" / "opensim-peer" / "data"


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.opensim
def test_static_optimization_matches_opensim_on_gait2392_walk(
    needs_opensim: None, tmp_path: Path
) -> None:
    if not PEER_DATA.is_dir():
        pytest.skip(f"OpenSim peer data absent: {PEER_DATA}")
    ref = opensim_static_optimization_reference(PEER_DATA, tmp_path, t0=0.8, t1=1.0)
    assert ref.time.shape[0] >= 10 and len(ref.muscle_names) == 43
    # OpenSim's right-leg equations have no actuator but these 43 muscles, and the pelvis
    # residuals carry no right-leg moment: τ_leg = R (a_os ⊙ F_act) is the torque OpenSim met
    a_os = ref.activations
    tau = np.einsum("kmn,km->kn", ref.moment_arms, a_os * ref.f_active)
    res = solve_static_optimization_batch(
        -ref.moment_arms,
        tau,
        f_active=ref.f_active,
        activation_min=ref.min_control,  # 0.01 in gait2392
        activation_max=ref.max_control,
        muscle_names=ref.muscle_names,
        coordinate_names=ref.coordinate_names,
    )
    assert res.activations is not None
    assert (res.status == 0).all() and np.nanmax(res.kkt) < 1e-8
    cost_msk = np.sum(res.activations**2, axis=1)
    cost_os = np.sum(a_os**2, axis=1)
    # the exact optimum never costs more than IPOPT's (tolerance 1e-4), and not much less
    assert np.all(cost_msk <= cost_os + 1e-9)
    assert np.all(cost_os - cost_msk < 1e-3 * cost_os)
    da = res.activations - a_os
    worst = ref.muscle_names[int(np.abs(da).max(axis=0).argmax())]
    assert np.abs(da).max() < 0.01, worst
    assert np.sqrt(np.mean(da**2)) < 0.002


def test_volume_weights_are_relative_muscle_volumes() -> None:
    from msk.optimization import volume_weights

    w = volume_weights([1000.0, 500.0, 2000.0], [0.1, 0.2, 0.05])
    np.testing.assert_allclose(w, [1.0, 1.0, 1.0])
    w = volume_weights([1000.0, 3000.0], [0.1, 0.1])
    np.testing.assert_allclose(w, [0.5, 1.5])
    with pytest.raises(OptimizationError, match=r"muscle 1 has F_iso·l_opt = 0\.0"):
        volume_weights([1000.0, 0.0], [0.1, 0.1])
    with pytest.raises(OptimizationError, match="should be"):
        volume_weights([1000.0, 1.0], [0.1])


# ---------------------------------------------------------------------------------------------
# independent sub-problems (each leg apart) solved apart: the same solutions
# ---------------------------------------------------------------------------------------------


def _two_legs(n_frames: int = 40):
    """Two leg-like muscle sets on their own coordinates plus two coordinates no muscle crosses
    (a "pelvis"): the QPs split into one sub-problem per leg."""
    a, b = leg_like_frames(18, 4, n_frames, seed=3), leg_like_frames(20, 3, n_frames, seed=4)
    m1, n1 = a.jacobians.shape[1:]
    m2, n2 = b.jacobians.shape[1:]
    jac = np.zeros((n_frames, m1 + m2, 2 + n1 + n2))
    jac[:, :m1, 2 : 2 + n1] = a.jacobians
    jac[:, m1:, 2 + n1 :] = b.jacobians
    tau = np.concatenate([np.full((n_frames, 2), 7.0), a.taus, b.taus], axis=1)
    return jac, tau, np.concatenate([a.f_iso, b.f_iso])


def _whole_and_split(monkeypatch, run):
    """``run()`` with the QPs split into their sub-problems and with each frame's QP whole."""
    import msk.optimization.problems as problems

    calls = []
    solve_blocks = problems._BatchQP.solve_blocks
    monkeypatch.setattr(
        problems._BatchQP,
        "solve_blocks",
        lambda self, *a, **k: calls.append(1) or solve_blocks(self, *a, **k),
    )
    split = run()
    assert calls, "the QPs were not split"
    monkeypatch.setattr(problems, "_MIN_BLOCK_UNKNOWNS", 10**9)  # one block: the whole QP
    whole = run()
    assert len(calls) == 1
    return split, whole


def _assert_same(split, whole, atol: float = 1e-9) -> None:
    np.testing.assert_array_equal(split.status, whole.status)
    for name in ("forces", "reserve_controls", "torque_error", "residual_norm"):
        np.testing.assert_allclose(getattr(split, name), getattr(whole, name), rtol=0, atol=atol)
    if whole.activations is not None:
        np.testing.assert_allclose(split.activations, whole.activations, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(split.active_lower, whole.active_lower)
    np.testing.assert_array_equal(split.active_upper, whole.active_upper)
    np.testing.assert_allclose(split.kkt, whole.kkt, rtol=0, atol=1e-9)


def test_batch_splits_into_independent_subproblems(monkeypatch) -> None:
    import msk.optimization.problems as problems

    jac, tau, f_iso = _two_legs()
    n_frames, m, n = jac.shape
    rng = np.random.default_rng(0)
    fa = f_iso * rng.uniform(0.6, 1.0, size=(n_frames, m))
    fp = f_iso * rng.uniform(0.0, 0.02, size=(n_frames, m))
    reserves = np.ones(n)
    pattern = problems._nonzero_pattern(jac)[:, 2:].T
    blocks = problems._independent_blocks(
        np.hstack([pattern, np.eye(n - 2, dtype=bool)]), np.eye(m + n - 2)
    )
    assert [(r.size, c.size) for r, c in blocks] == [(4, 22), (3, 23)]

    def so():
        return solve_static_optimization_batch(
            jac, tau, f_active=fa, f_passive=fp, activation_min=0.01,
            reserve_optimal_force=reserves, activation_weights=np.linspace(0.5, 2.0, m),
        )  # fmt: skip

    split, whole = _whole_and_split(monkeypatch, so)
    assert (split.status == 0).all() and np.nanmax(split.kkt) < 1e-8
    _assert_same(split, whole)
    # the pelvis residuals left the QPs: τ / F_res exactly
    np.testing.assert_array_equal(split.reserve_controls[:, :2], 7.0)


def test_batch_split_tension_and_emg_assisted_and_infeasible_frames(monkeypatch) -> None:
    jac, tau, f_iso = _two_legs(30)
    jac, tau = jac[:, :, 2:], tau[:, 2:]  # no pelvis: without reserves it could not balance
    taus = tau.copy()
    taus[[5, 17], 1] = 1e5  # beyond the first leg's capacity: bounded least squares
    split, whole = _whole_and_split(
        monkeypatch, lambda: solve_tension_batch(jac, taus, f_iso=f_iso)
    )
    assert list(split.infeasible_frames) == [5, 17]
    _assert_same(split, whole, atol=1e-9 * np.abs(taus).max())

    n_frames, m, _ = jac.shape
    rng = np.random.default_rng(1)
    fa = np.broadcast_to(f_iso, (n_frames, m))
    measured = rng.uniform(size=m) < 0.5
    a_ref = rng.uniform(0.0, 0.3, size=(n_frames, m))

    def emg():
        return solve_emg_assisted_batch(
            jac, tau, f_active=fa, a_ref=a_ref, measured=measured, w_track=1.0,
            reserve_optimal_force=np.ones(jac.shape[2]),
        )  # fmt: skip

    import msk.optimization.problems as problems

    monkeypatch.setattr(problems, "_MIN_BLOCK_UNKNOWNS", 16)
    split, whole = _whole_and_split(monkeypatch, emg)
    _assert_same(split, whole)
    with pytest.raises(OptimizationError, match=r"frame 5: QP infeasible"):
        monkeypatch.setattr(problems, "_MIN_BLOCK_UNKNOWNS", 16)
        solve_tension_batch(jac, taus, f_iso=f_iso, strict=True)


def test_batch_split_per_frame_cost_and_bounds_over_several_chunks(monkeypatch) -> None:
    """Frames beyond one assembly chunk (``_BLOCK_CHUNK``) with per-frame ``g`` (the EMG
    reference of ``emg_assisted``) and per-frame bounds (``bounded_qp``'s F_max): each chunk
    reads its own rows (regression: a trial of more than 512 usable frames failed with a
    broadcast error), the same solutions as each frame's QP solved whole."""
    import msk.optimization.problems as problems

    monkeypatch.setattr(problems, "_BLOCK_CHUNK", 7)
    jac, tau, f_iso = _two_legs(30)
    jac, tau = jac[:, :, 2:], tau[:, 2:]
    n_frames, m, _ = jac.shape
    rng = np.random.default_rng(2)
    fa = f_iso * rng.uniform(0.6, 1.0, size=(n_frames, m))
    fp = f_iso * rng.uniform(0.0, 0.02, size=(n_frames, m))
    measured = rng.uniform(size=m) < 0.5
    a_ref = rng.uniform(0.0, 0.3, size=(n_frames, m))

    def emg():
        return solve_emg_assisted_batch(
            jac, tau, f_active=fa, f_passive=fp, a_ref=a_ref, measured=measured, w_track=1.0,
            reserve_optimal_force=np.ones(jac.shape[2]),
        )  # fmt: skip

    monkeypatch.setattr(problems, "_MIN_BLOCK_UNKNOWNS", 16)
    split, whole = _whole_and_split(monkeypatch, emg)
    assert (split.status == 0).all()
    _assert_same(split, whole)

    def bounded():
        return solve_tension_batch(
            jac, tau, f_iso=f_iso, f_max=fa + fp, reserve_optimal_force=np.ones(jac.shape[2])
        )

    monkeypatch.setattr(problems, "_MIN_BLOCK_UNKNOWNS", 16)
    split, whole = _whole_and_split(monkeypatch, bounded)
    _assert_same(split, whole, atol=1e-9 * np.abs(tau).max())


# ---------------------------------------------------------------------------------------------
# inequality rows c + G f + s ≥ 0 with penalised reserves (knee compartments ≥ 0, issue 16)
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("criterion", ["static", "static_p3", "assisted", "weighted", "tension"])
def test_inequality_rows_hold_with_kkt_and_a_second_solver(criterion: str) -> None:
    """Random frames (8 muscles, 2 coordinates) with two rows that the unconstrained solution
    violates by up to ~50 units: with the rows, c + G f + s ≥ 0 to 1e-9 on every frame, s ≥ 0,
    the torque equality unchanged (residual ≤ 1e-9; the EMG-weighted QP keeps its penalty),
    DAQP's KKT figures (inequality multipliers included) ≤ 1e-8, Clarabel's forces and reserves
    equal DAQP's to 1e-4 (relative); rows that never bind leave the solution as it was."""
    import msk.optimization as o

    rng = np.random.default_rng(11)
    n_fr, m, n = 12, 8, 2
    jac = rng.normal(0.0, 0.03, (n_fr, m, n))
    tau = rng.normal(0.0, 20.0, (n_fr, n))
    fa = np.full((n_fr, m), 1500.0)
    gain = rng.normal(0.0, 0.02, (n_fr, 2, m))
    off = rng.normal(-20.0, 10.0, (n_fr, 2))
    rows = o.TensionInequalities(off, gain, ("a", "b"))
    idle = o.TensionInequalities(off + 1e6, gain, ("a", "b"))
    meas = np.ones(m, dtype=bool)

    def run(ineq: Any, solver: str) -> Any:
        if criterion in ("static", "static_p3"):
            p = 3.0 if criterion == "static_p3" else 2.0
            return o.solve_static_optimization_batch(
                jac, tau, f_active=fa, reserve_optimal_force=np.ones(n), activation_exponent=p,
                solver=solver, inequalities=ineq,
            )  # fmt: skip
        if criterion == "assisted":
            return o.solve_emg_assisted_batch(
                jac, tau, f_active=fa, a_ref=np.full((n_fr, m), 0.1), measured=meas,
                reserve_optimal_force=np.ones(n), solver=solver, inequalities=ineq,
            )  # fmt: skip
        if criterion == "weighted":
            return o.solve_emg_weighted_batch(
                jac, tau, f_ref=np.full((n_fr, m), 100.0), measured=meas, w_emg=0.1, f_max=fa,
                solver=solver, inequalities=ineq,
            )  # fmt: skip
        return o.solve_tension_batch(
            jac, tau, f_iso=np.full(m, 1500.0), reserve_optimal_force=np.ones(n), solver=solver,
            inequalities=ineq,
        )  # fmt: skip

    free, held, loose = run(None, "daqp"), run(rows, "daqp"), run(idle, "daqp")
    assert free.inequality_reserves is None
    before = off + np.einsum("kim,km->ki", gain, free.forces)
    assert before.min() < -30.0
    s = held.inequality_reserves
    assert s is not None and held.inequality_names == ("a", "b") and np.all(s >= 0.0)
    after = off + np.einsum("kim,km->ki", gain, held.forces) + s
    assert after.min() >= -1e-9
    assert np.all(held.status == 0) and np.nanmax(held.kkt) <= 1e-8
    if criterion != "weighted":
        assert np.abs(held.residual).max() <= 1e-9
    np.testing.assert_allclose(loose.forces, free.forces, atol=1e-7)
    other = run(rows, "clarabel")
    scale = np.abs(held.forces).max()
    assert np.abs(other.forces - held.forces).max() <= 1e-4 * scale
    assert other.inequality_reserves is not None
    np.testing.assert_allclose(other.inequality_reserves, s, atol=1e-4 * max(1.0, s.max()))


def test_inequality_rows_check_their_shapes() -> None:
    import msk.optimization as o

    with pytest.raises(OptimizationError, match="offset"):
        o.TensionInequalities(np.zeros(3), np.zeros((3, 2, 4)), ("a", "b"))
    with pytest.raises(OptimizationError, match="names"):
        o.TensionInequalities(np.zeros((3, 2)), np.zeros((3, 2, 4)), ("a",))
    with pytest.raises(OptimizationError, match="reserve_optimal"):
        o.TensionInequalities(np.zeros((3, 2)), np.zeros((3, 2, 4)), ("a", "b"), 0.0)
    rows = o.TensionInequalities(np.zeros((3, 2)), np.zeros((3, 2, 4)), ("a", "b"))
    with pytest.raises(OptimizationError, match="does not match"):
        o.solve_static_optimization_batch(
            np.zeros((3, 5, 1)) + 0.01, np.zeros((3, 1)), f_active=np.ones((3, 5)),
            inequalities=rows,
        )  # fmt: skip


# ---------------------------------------------------------------------------------------------
# inequality rows inside the sub-problems (issue 16, tenth pass: a knee's compartment rows in
# its leg's sub-problem)
# ---------------------------------------------------------------------------------------------


def _knee_rows(n_frames: int, m: int, leg: slice, seed: int = 5):
    """Two rows ``c + G f + s ≥ 0`` over the muscles of one leg only (a knee's medial and
    lateral compartments: only the muscles crossing it, here 12 of the leg's), offsets that
    the unconstrained optimum violates, and one frame with the trivial row 0 ≥ 0 (the
    pipeline's row where the compartment map is not finite)."""
    import msk.optimization as o

    rng = np.random.default_rng(seed)
    gain = np.zeros((n_frames, 2, m))
    cols = np.arange(m)[leg][:12]
    gain[:, :, cols] = rng.normal(0.0, 0.02, (n_frames, 2, cols.size))
    off = rng.normal(-20.0, 10.0, (n_frames, 2))
    gain[3], off[3] = 0.0, 0.0
    return o.TensionInequalities(off, gain, ("knee_medial", "knee_lateral"))


def _whole_qp_reference(monkeypatch, run):
    """``run()`` with every frame's QP whole: no sub-problems and no reserve left out."""
    import msk.optimization.problems as problems

    with monkeypatch.context() as mp:
        mp.setattr(problems, "_MIN_BLOCK_UNKNOWNS", 10**9)
        mp.setattr(
            problems, "_decoupled_reserves",
            lambda jac, tau, idx, *a: np.zeros(idx.shape[0], dtype=bool),
        )  # fmt: skip
        return run()


@pytest.mark.parametrize("criterion", ["static", "assisted", "tension"])
def test_inequality_rows_join_the_subproblem_of_their_muscles(monkeypatch, criterion) -> None:
    """Two legs and a pelvis no muscle crosses (``_two_legs``), rows on the second leg's
    muscles: the QPs still split — the rows and their reserves in the second leg's
    sub-problem — and the pelvis reserves still leave them (τ/F_res exactly). Forces within
    1e-8 N and row reserves within 1e-10 of every frame's whole QP (no split, no reserve left
    out), KKT figures of the whole QP ≤ 1e-8, the rows hold, Clarabel on the whole QP agrees
    to 1e-4 (relative). Frames over several assembly chunks (``_BLOCK_CHUNK`` 7), per-frame
    cost (EMG reference) and bounds (``bounded_qp``'s F_max)."""
    import msk.optimization.problems as problems

    monkeypatch.setattr(problems, "_BLOCK_CHUNK", 7)
    jac, tau, f_iso = _two_legs(30)
    n_frames, m, n = jac.shape
    m1 = 18  # the first leg's muscles (``_two_legs``)
    ineq = _knee_rows(n_frames, m, slice(m1, m))
    rng = np.random.default_rng(6)
    fa = f_iso * rng.uniform(0.6, 1.0, size=(n_frames, m))
    fp = f_iso * rng.uniform(0.0, 0.02, size=(n_frames, m))

    def run(rows: Any = ineq, solver: str = "daqp") -> Any:
        if criterion == "static":
            return solve_static_optimization_batch(
                jac, tau, f_active=fa, f_passive=fp, activation_min=0.01,
                reserve_optimal_force=np.ones(n), activation_weights=np.linspace(0.5, 2.0, m),
                inequalities=rows, solver=solver,
            )  # fmt: skip
        if criterion == "assisted":
            return solve_emg_assisted_batch(
                jac, tau, f_active=fa, f_passive=fp, a_ref=rng_ref, measured=measured,
                w_track=1.0, reserve_optimal_force=np.ones(n), inequalities=rows, solver=solver,
            )  # fmt: skip
        return solve_tension_batch(
            jac, tau, f_iso=f_iso, f_max=fa + fp, reserve_optimal_force=np.ones(n),
            inequalities=rows, solver=solver,
        )  # fmt: skip

    measured = rng.uniform(size=m) < 0.5
    rng_ref = rng.uniform(0.0, 0.3, size=(n_frames, m))
    seen: list[Any] = []
    solve_blocks = problems._BatchQP.solve_blocks
    monkeypatch.setattr(
        problems._BatchQP, "solve_blocks",
        lambda self, *a, **k: seen.append(self.blocks) or solve_blocks(self, *a, **k),
    )  # fmt: skip
    split = run()
    assert len(seen) == 1
    # 4 + 3 torque rows (pelvis left out), then the two inequality rows: with the second leg
    (r1, _), (r2, c2) = seen[0]
    assert list(r1) == [0, 1, 2, 3] and list(r2) == [4, 5, 6, 7, 8]
    nv = m + (n - 2) + 2
    assert set(c2) >= {nv - 2, nv - 1} and set(c2) >= set(range(m1, m))
    whole = _whole_qp_reference(monkeypatch, run)
    assert len(seen) == 1
    assert (split.status == 0).all() and (whole.status == 0).all()
    np.testing.assert_allclose(split.forces, whole.forces, rtol=0, atol=1e-8)
    np.testing.assert_allclose(split.reserve_controls, whole.reserve_controls, atol=1e-10)
    s, sw = split.inequality_reserves, whole.inequality_reserves
    assert s is not None and sw is not None and split.inequality_names == ineq.names
    np.testing.assert_allclose(s, sw, rtol=0, atol=1e-10)
    assert np.nanmax(split.kkt) <= 1e-8
    np.testing.assert_array_equal(split.reserve_controls[:, :2], 7.0)  # τ / F_res, exactly
    held = ineq.offset + np.einsum("kim,km->ki", ineq.gain, split.forces) + s
    free = run(None)
    before = ineq.offset + np.einsum("kim,km->ki", ineq.gain, free.forces)
    assert before.min() < -20.0 and held.min() >= -1e-9 and np.all(s >= 0.0)
    other = run(solver="clarabel")
    scale = np.abs(split.forces).max()
    assert np.abs(other.forces - split.forces).max() <= 1e-4 * scale
    assert other.inequality_reserves is not None
    np.testing.assert_allclose(other.inequality_reserves, s, atol=1e-4 * max(1.0, s.max()))


def test_inequality_rows_in_subproblems_keep_the_infeasible_frame_fallback(monkeypatch) -> None:
    """A frame no tension can balance (no reserves, a torque beyond the first leg's capacity)
    with the rows in the second leg's sub-problem: that frame is solved whole (status
    ``infeasible``, the bounded least-squares point with the rows kept as constraints, the
    same as without the split), the others split; ``strict`` names the frame."""
    import msk.optimization.problems as problems

    jac, tau, f_iso = _two_legs(30)
    jac, tau = jac[:, :, 2:], tau[:, 2:]
    taus = tau.copy()
    taus[[5, 17], 1] = 1e5
    ineq = _knee_rows(jac.shape[0], jac.shape[1], slice(18, None))

    def run() -> Any:
        return solve_tension_batch(jac, taus, f_iso=f_iso, inequalities=ineq)

    split, whole = _whole_and_split(monkeypatch, run)
    assert list(split.infeasible_frames) == [5, 17] == list(whole.infeasible_frames)
    _assert_same(split, whole, atol=1e-9 * np.abs(taus).max())
    assert split.inequality_reserves is not None and whole.inequality_reserves is not None
    np.testing.assert_allclose(split.inequality_reserves, whole.inequality_reserves, atol=1e-9)
    held = ineq.offset + np.einsum("kim,km->ki", ineq.gain, split.forces)
    assert (held + split.inequality_reserves).min() >= -1e-9
    monkeypatch.setattr(problems, "_MIN_BLOCK_UNKNOWNS", 16)
    with pytest.raises(OptimizationError, match=r"frame 5: QP infeasible"):
        solve_tension_batch(jac, taus, f_iso=f_iso, inequalities=ineq, strict=True)


GC5_PS = Path(__file__).resolve().parents[2] / "pipelines" / "gc5_PS.toml"


@pytest.mark.slow
@pytest.mark.realdata
def test_knee_compartment_rows_in_the_leg_subproblem_on_gc5_ps(monkeypatch, tmp_path) -> None:
    """The shipped PS session (``emg_assisted``, ``compartment_nonnegative``: the left knee's
    rows F_M, F_L ≥ 0): the tension stage's QPs split into the two legs (the back with one of
    them), the knee's two rows and their reserves in the left leg's sub-problem (every muscle
    of a nonzero gain is a left-leg muscle); forces within 1e-8 N and frontal reserves within
    1e-10 N·m of every frame's whole QP (measured 1.3e-12 N), KKT figures ≤ 1e-8, Clarabel on
    the whole QP within 1e-5 of the largest force (measured 1e-7 N of 2 kN)."""
    import msk.optimization as o
    import msk.optimization.problems as problems
    from msk.pipeline import run_task_trials

    if not (shared_dir() / "data" / "real").is_dir():
        pytest.skip("shared real recordings absent")
    calls: list[tuple[Any, tuple[Any, ...], dict[str, Any]]] = []
    solve = o.solve_emg_assisted_batch

    def capture(*a: Any, **k: Any) -> Any:
        if k.get("inequalities") is not None and not calls:
            calls.append((solve, a, {n: v for n, v in k.items() if n != "warm"}))
        return solve(*a, **k)

    monkeypatch.setattr(o, "solve_emg_assisted_batch", capture)
    run_task_trials(GC5_PS, tmp_path / "out")
    monkeypatch.undo()
    assert calls, "the tension stage posed no compartment rows"
    fn, args, kw = calls[0]
    rows = kw["inequalities"]
    assert rows.names == ("knee_l_medial", "knee_l_lateral")  # PS: the left knee
    seen: list[Any] = []
    solve_blocks = problems._BatchQP.solve_blocks
    monkeypatch.setattr(
        problems._BatchQP, "solve_blocks",
        lambda self, *a, **k: seen.append(self.blocks) or solve_blocks(self, *a, **k),
    )  # fmt: skip
    split = fn(*args, **kw)
    assert len(seen) == 1 and len(seen[0]) == 2
    names, coords = split.muscle_names, split.coordinate_names
    n_eq = len(coords)  # the actuated coordinates (the pelvis has none): then the two rows
    left = [c for r, c in seen[0] if (r >= n_eq).any()]
    assert len(left) == 1 and all((r >= n_eq).sum() in (0, 2) for r, _ in seen[0])
    crossing = np.flatnonzero((rows.gain != 0).any(axis=(0, 1)))
    assert crossing.size and all(names[i].endswith("_l") for i in crossing)
    assert set(crossing) <= set(left[0])
    whole = _whole_qp_reference(monkeypatch, lambda: fn(*args, **kw))
    assert len(seen) == 1
    assert (split.status == 0).all() and (whole.status == 0).all()
    np.testing.assert_allclose(split.forces, whole.forces, rtol=0, atol=1e-8)
    s, sw = split.inequality_reserves, whole.inequality_reserves
    assert s is not None and sw is not None
    np.testing.assert_allclose(s, sw, rtol=0, atol=1e-10)
    assert np.nanmax(split.kkt) <= 1e-8
    other = fn(*args, **dict(kw, solver="clarabel"))
    assert np.abs(other.forces - split.forces).max() <= 1e-5 * np.abs(split.forces).max()


# ---------------------------------------------------------------------------------------------
# KKT figures over frames at once (kkt_batch) and their scales
# ---------------------------------------------------------------------------------------------


def _random_frame(rng, n, m_eq, m_in, h, p_act):
    """A QP and a point with a random active set: bounds and inequality rows put exactly at
    ``x`` (active), others at a distance or infinite; an optional residual on ``A x = b``."""
    x = rng.normal(size=n)
    lo = rng.random(n) < p_act / 2
    up = ~lo & (rng.random(n) < p_act / 2)
    lb = np.where(rng.random(n) < 0.1, -np.inf, x - rng.uniform(0.1, 2.0, n))
    ub = np.where(rng.random(n) < 0.1, np.inf, x + rng.uniform(0.1, 2.0, n))
    lb, ub = np.where(lo, x, lb), np.where(up, x, ub)
    a = rng.normal(size=(m_eq, n))
    b = a @ x + rng.normal(scale=1e-3, size=m_eq) * rng.integers(0, 2)
    c = cl = cu = None
    if m_in:
        c = rng.normal(size=(m_in, n))
        cx = c @ x
        il = rng.random(m_in) < 0.4
        iu = ~il & (rng.random(m_in) < 0.4)
        cl, cu = np.where(il, cx, cx - 1.0), np.where(iu, cx, np.inf)
    g = rng.normal(size=n)
    return StandardQP(h, g, a, b, lb, ub, c, cl, cu), x


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**31 - 1), n=st.integers(1, 12), m_eq=st.integers(0, 6),
    m_in=st.integers(0, 3), shared_h=st.booleans(), frames=st.integers(1, 9),
)  # fmt: skip
def test_kkt_batch_equals_kkt_frame_by_frame(seed, n, m_eq, m_in, shared_h, frames) -> None:
    """Random QPs with random active sets (bounds and inequality rows, some infinite bounds,
    rank-deficient frames with more rows than free columns, points off the equality rows): the
    batched figures and scales equal :func:`kkt` and :func:`kkt_scale` of each frame to
    round-off (1e-11 of the scale)."""
    from msk.optimization import kkt, kkt_batch, kkt_scale

    rng = np.random.default_rng(seed)

    def spd():
        q = rng.normal(size=(n, n))
        return q @ q.T

    h = spd() if shared_h else None
    pairs = [
        _random_frame(rng, n, m_eq, m_in, h if shared_h else spd(), rng.uniform(0, 1))
        for _ in range(frames)
    ]
    qps, xs = [p[0] for p in pairs], np.array([p[1] for p in pairs])
    kb = kkt_batch(qps, xs)
    ref = np.array([kkt(q, x).as_array() for q, x in pairs])
    scale = np.array([kkt_scale(q, x) for q, x in pairs])
    np.testing.assert_allclose(kb.scale, scale, rtol=1e-14)
    np.testing.assert_array_less(np.abs(kb.figures - ref), 1e-11 * scale)
    assert np.all(kb.figures >= 0)


def test_kkt_batch_leaves_the_undetermined_frames_to_kkt() -> None:
    """A frame with more equality rows than free columns (two bounds active: multipliers not
    determined by the free columns: kkt's bounded least squares) is computed by kkt; a
    well-posed frame next to it by the stacked fit; both as kkt finds them."""
    from msk.optimization import kkt, kkt_batch

    rng = np.random.default_rng(3)
    n = 4
    x = rng.normal(size=n)
    a = rng.normal(size=(3, n))
    tight = StandardQP(np.eye(n), rng.normal(size=n), a, a @ x, x - [0, 0, 1, 1], x + 1.0)
    loose = StandardQP(np.eye(n), rng.normal(size=n), a, a @ x, x - 1.0, x + 1.0)
    kb = kkt_batch([tight, loose], np.array([x, x]))
    assert kb.fallback.tolist() == [True, False]
    for k, q in enumerate((tight, loose)):
        np.testing.assert_allclose(kb.figures[k], kkt(q, x).as_array(), atol=1e-13)
    assert kb.figures[0, 0] < 1e-12  # 3 rows span the 2 free columns


def test_batch_kkt_scale_and_a_solver_that_stops_short() -> None:
    """The batch solvers report each frame's KKT scales; DAQP's frames sit at round-off of
    them, while a solver that returns a point off the optimum (a registered one that returns
    the least-norm point of the rows) is called optimal by its status but fails the check —
    what the tension stage's gate ``kkt_relative`` catches."""
    from msk.optimization.muscle_forces import worst_kkt
    from msk.quality import THRESHOLDS

    d = leg_like_frames(12, 4, 15, seed=4)
    res = np.ones(4)
    a = solve_tension_batch(d.jacobians, d.taus, f_iso=d.f_iso, reserve_optimal_force=res)
    assert a.kkt_scale is not None and np.all(a.kkt_scale >= 1.0)
    assert np.all(a.kkt / a.kkt_scale < 1e-12)

    def sloppy(qp, warm):  # the least-norm point of the rows, in the bounds: no optimum
        x = np.linalg.lstsq(qp.A, qp.b, rcond=None)[0]
        return SolveOutput(x=np.clip(x, qp.lb, qp.ub), ok=True, infeasible=False)

    register_solver(SolverSpec("test-sloppy", sloppy, description="least-norm point (tests)"))
    b = solve_tension_batch(
        d.jacobians, d.taus, f_iso=d.f_iso, reserve_optimal_force=res, solver="test-sloppy"
    )
    assert np.all(b.status == 0)
    _, rel, frame, n = worst_kkt(b.kkt, b.kkt_scale, b.status == 0, np.arange(15) + 100)
    assert n == 15 and rel.max() > THRESHOLDS["kkt_relative"] and np.all(frame >= 100)
    # an infeasible frame (status ≠ 0) is not checked
    _, rel2, _, n2 = worst_kkt(b.kkt, b.kkt_scale, np.zeros(15, dtype=bool), np.arange(15))
    assert n2 == 0 and np.all(rel2 == 0)


@pytest.mark.parametrize("with_rows", [False, True])
def test_whole_qps_stacked_for_the_kkt_check_are_each_frames_whole_qp(monkeypatch, with_rows):
    """The stacked whole QPs the split batches check KKT on (``_BatchQP.whole_stack``) are,
    frame by frame, the whole QP (``_BatchQP.whole``) of static optimisation with passive
    forces, emg_assisted and bounded_qp, with and without inequality rows and decoupled
    reserves (pelvis columns no muscle crosses)."""
    import msk.optimization as o
    import msk.optimization.problems as problems

    jac, tau, f_iso = _two_legs(12)
    n_frames, m, _ = jac.shape
    rng = np.random.default_rng(5)
    fa = f_iso * rng.uniform(0.6, 1.0, size=(n_frames, m))
    fp = f_iso * rng.uniform(0.0, 0.02, size=(n_frames, m))
    rows = None
    if with_rows:
        gain = rng.normal(size=(n_frames, 2, m)) * (np.arange(m) < 18)  # the first leg's
        rows = o.TensionInequalities(rng.normal(size=(n_frames, 2)), gain, ("a", "b"))
    checked = []
    stack = problems._BatchQP.whole_stack

    def spy(self, fr):
        out = stack(self, fr)
        h, g, a, b, lb, ub, c, cl = out
        for i, k in enumerate(fr):
            qp = self.whole(int(k))
            np.testing.assert_array_equal(h, qp.H)
            for mine, ref in ((g, qp.g), (lb, qp.lb), (ub, qp.ub)):
                np.testing.assert_array_equal(mine if mine.ndim == 1 else mine[i], ref)
            np.testing.assert_array_equal(a[i], qp.A)
            np.testing.assert_allclose(b[i], qp.b, rtol=1e-14, atol=1e-12)
            if qp.C is None:
                assert c is None
            else:
                np.testing.assert_array_equal(c[i], qp.C)
                np.testing.assert_allclose(cl[i], qp.cl, rtol=1e-14, atol=1e-12)
            checked.append(int(k))
        return out

    monkeypatch.setattr(problems._BatchQP, "whole_stack", spy)
    monkeypatch.setattr(problems, "_MIN_BLOCK_UNKNOWNS", 16)  # split the small QPs too
    res = np.ones(jac.shape[2])
    kw = {"reserve_optimal_force": res, "inequalities": rows}
    solve_static_optimization_batch(jac, tau, f_active=fa, f_passive=fp, **kw)
    solve_emg_assisted_batch(
        jac, tau, f_active=fa, f_passive=fp, a_ref=rng.uniform(0, 0.3, size=(n_frames, m)),
        measured=rng.uniform(size=m) < 0.5, w_track=1.0, **kw,
    )  # fmt: skip
    solve_tension_batch(jac, tau, f_iso=f_iso, f_max=fa + fp, **kw)
    assert len(checked) >= 3 * n_frames - 6  # every solved frame of the three batches
