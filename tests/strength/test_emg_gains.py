"""EMG-assisted static optimisation (:func:`msk.optimization.solve_emg_assisted_batch`) and the
jointly fitted EMG-to-activation gains (:func:`msk.strength.fit_emg_gains`) on synthetic data
with known answers."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

from msk.exceptions import IdentificationError, OptimizationError
from msk.optimization import solve_emg_assisted_batch, solve_static_optimization_batch
from msk.strength import fit_emg_gains


def _frames(rng: np.random.Generator, n_frames: int, m: int, n: int) -> tuple:
    """Jacobians J = ∂l/∂θ (moment arms ±2–6 cm) and F_act (500–2000 N) per frame."""
    base = rng.uniform(0.02, 0.06, (m, n)) * rng.choice([-1.0, 1.0], (m, n))
    jac = base[None] * (1.0 + 0.1 * rng.standard_normal((n_frames, m, n)))
    fa = rng.uniform(500.0, 2000.0, (n_frames, m))
    return jac, fa


def _torques(jac: np.ndarray, fa: np.ndarray, a: np.ndarray) -> np.ndarray:
    return -np.einsum("kmn,km->kn", jac, a * fa)  # τ = R f, R = −Jᵀ


def test_gains_are_recovered_when_the_torques_determine_the_activations() -> None:
    """As many muscles as coordinates: the activations are fixed by the torques, so the fitted
    gains are the generating ones at any w_track."""
    rng = np.random.default_rng(3)
    n_frames, m = 60, 4
    jac, fa = _frames(rng, n_frames, m, m)
    emg = rng.uniform(0.1, 1.0, (n_frames, m))
    names = ("m0", "m1", "m2", "m3")
    groups = {"a": ("m0", "m1"), "b": ("m2",), "c": ("m3",)}
    g_true = np.array([0.3, 0.3, 0.6, 0.15])
    tau = _torques(jac, fa, g_true * emg)
    for w_track in (0.1, 1.0, 10.0):
        fit = fit_emg_gains(
            jac, tau, f_active=fa, emg_activation=emg, groups=groups, muscle_names=names,
            w_track=w_track,
        )  # fmt: skip
        assert fit.converged
        np.testing.assert_allclose(fit.gains, [0.3, 0.6, 0.15], rtol=1e-6)
        np.testing.assert_allclose(fit.muscle_gains, g_true, rtol=1e-6)
        np.testing.assert_allclose(fit.reference(emg), g_true * emg, rtol=1e-6)


def test_gains_reach_the_joint_optimum_of_the_stacked_problem() -> None:
    """Redundant leg (6 muscles, 2 coordinates), 2 gain groups, one unmeasured muscle: the
    coordinate descent reaches the joint minimum over (a, g) of all frames (checked against
    SLSQP on the stacked problem) and its objective never increases."""
    rng = np.random.default_rng(7)
    n_frames, m, n = 8, 6, 2
    jac, fa = _frames(rng, n_frames, m, n)
    names = tuple(f"m{i}" for i in range(m))
    groups = {"flex": ("m0", "m1", "m2"), "ext": ("m3", "m4")}
    g_true = np.array([0.4, 0.4, 0.4, 0.2, 0.2, 0.0])
    emg = rng.uniform(0.1, 1.0, (n_frames, m))
    a_true = g_true * emg
    a_true[:, 5] = 0.05
    tau = _torques(jac, fa, a_true)
    w_v = rng.uniform(0.5, 2.0, m)
    w_track = 2.0
    fit = fit_emg_gains(
        jac, tau, f_active=fa, emg_activation=emg, groups=groups, muscle_names=names,
        w_track=w_track, activation_weights=w_v, tol=1e-8, max_iterations=5000,
    )  # fmt: skip
    assert fit.converged
    assert np.all(np.diff(fit.objective) <= 1e-9 * fit.objective[0])
    meas = fit.measured
    gi = np.array([0, 0, 0, 1, 1, -1])

    def unpack(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return x[: n_frames * m].reshape(n_frames, m), x[n_frames * m :]

    def cost(x: np.ndarray) -> tuple[float, np.ndarray]:
        a, g = unpack(x)
        dev = (a - np.where(meas, g[gi] * emg, 0.0)) * meas
        grad_g = [-2.0 * w_track * np.sum((dev * emg)[:, gi == c]) for c in range(2)]
        grad = np.concatenate([(2.0 * w_v * a + 2.0 * w_track * dev).ravel(), grad_g])
        return float(np.sum(w_v * a * a) + w_track * np.sum(dev**2)), grad

    # the torque equality is linear in x: rows (frame, coordinate), columns (frame, muscle) + g
    a_eq = np.zeros((n_frames * n, n_frames * m + 2))
    for k in range(n_frames):
        a_eq[k * n : (k + 1) * n, k * m : (k + 1) * m] = -(jac[k] * fa[k][:, None]).T

    b_eq = tau.ravel()
    x0 = np.concatenate([np.full(n_frames * m, 0.2), [0.3, 0.3]])
    ref = minimize(
        cost, x0, jac=True, method="SLSQP",
        constraints=[{"type": "eq", "fun": lambda x: a_eq @ x - b_eq, "jac": lambda x: a_eq}],
        bounds=[(0.0, 1.0)] * (n_frames * m) + [(0.0, None)] * 2,
        options={"ftol": 1e-14, "maxiter": 2000},
    )  # fmt: skip
    assert ref.success, ref.message
    _, g_ref = unpack(ref.x)
    np.testing.assert_allclose(fit.gains, g_ref, rtol=1e-3)
    assert fit.objective[-1] <= ref.fun * (1 + 1e-6)


def test_anderson_extrapolation_reaches_the_plain_descents_fixed_point(monkeypatch) -> None:
    """The gain fit's Anderson extrapolation (kept only where the joint objective does not
    increase) converges to the gains of plain coordinate descent (memory 1: no extrapolation),
    in fewer a-steps, with a non-increasing objective."""
    import msk.strength.emg_gains as eg

    rng = np.random.default_rng(3)
    n_frames, m, n = 12, 7, 2
    jac, fa = _frames(rng, n_frames, m, n)
    names = tuple(f"m{i}" for i in range(m))
    groups = {"a": ("m0", "m1"), "b": ("m2", "m3", "m4"), "c": ("m5",)}
    emg = rng.uniform(0.05, 1.0, (n_frames, m))
    tau = _torques(jac, fa, rng.uniform(0.05, 0.4, (n_frames, m)))
    kw = dict(f_active=fa, emg_activation=emg, groups=groups, muscle_names=names, w_track=3.0,
              tol=1e-10, max_iterations=20000)  # fmt: skip
    fast = fit_emg_gains(jac, tau, **kw)  # type: ignore[arg-type]
    monkeypatch.setattr(eg, "ANDERSON_MEMORY", 1)
    plain = fit_emg_gains(jac, tau, **kw)  # type: ignore[arg-type]
    assert fast.converged and plain.converged
    np.testing.assert_allclose(fast.gains, plain.gains, rtol=0, atol=1e-7)
    assert fast.iterations < plain.iterations
    for fit in (fast, plain):
        assert np.all(np.diff(fit.objective) <= 1e-12 * fit.objective[0])


def test_emg_assisted_so_limits() -> None:
    """w_track = 0 is static optimisation; a torque-compatible reference is reproduced when
    w_track is large; the torques are met exactly at every w_track."""
    rng = np.random.default_rng(11)
    n_frames, m, n = 10, 5, 2
    jac, fa = _frames(rng, n_frames, m, n)
    a_ref = rng.uniform(0.1, 0.5, (n_frames, m))
    tau = _torques(jac, fa, a_ref)
    meas = np.ones(m, dtype=bool)
    so = solve_static_optimization_batch(jac, tau, f_active=fa)
    zero = solve_emg_assisted_batch(jac, tau, f_active=fa, a_ref=a_ref, measured=meas, w_track=0)
    np.testing.assert_allclose(zero.activations, so.activations, atol=1e-8)
    big = solve_emg_assisted_batch(jac, tau, f_active=fa, a_ref=a_ref, measured=meas, w_track=1e6)
    np.testing.assert_allclose(big.activations, a_ref, atol=1e-5)
    mid = solve_emg_assisted_batch(jac, tau, f_active=fa, a_ref=a_ref, measured=meas, w_track=1.0)
    for sol in (zero, big, mid):
        assert (sol.status == 0).all()
        assert np.abs(sol.torque_error).max() < 1e-6
    # in between: closer to the reference than SO, cheaper in Σ a² than the reference
    assert np.linalg.norm(mid.activations - a_ref) < np.linalg.norm(so.activations - a_ref)
    assert np.sum(mid.activations**2) < np.sum(a_ref**2)
    with pytest.raises(OptimizationError, match="w_track"):
        solve_emg_assisted_batch(jac, tau, f_active=fa, a_ref=a_ref, measured=meas, w_track=-1)


def test_emg_assisted_so_with_passive_forces() -> None:
    """Passive forces enter the torque balance as in static optimisation: with w_track = 0 the
    same activations as SO with the same F_pas, forces a F_act + F_pas, torques met."""
    rng = np.random.default_rng(5)
    n_frames, m, n = 8, 5, 2
    jac, fa = _frames(rng, n_frames, m, n)
    fp = rng.uniform(0.0, 150.0, (n_frames, m))
    tau = _torques(jac, fa, rng.uniform(0.1, 0.4, (n_frames, m))) - np.einsum("kmn,km->kn", jac, fp)
    meas = np.ones(m, dtype=bool)
    a_ref = rng.uniform(0.1, 0.5, (n_frames, m))
    so = solve_static_optimization_batch(jac, tau, f_active=fa, f_passive=fp)
    ea = solve_emg_assisted_batch(
        jac, tau, f_active=fa, f_passive=fp, a_ref=a_ref, measured=meas, w_track=0
    )
    np.testing.assert_allclose(ea.activations, so.activations, atol=1e-8)
    np.testing.assert_allclose(ea.forces, ea.activations * fa + fp, rtol=1e-12)
    mid = solve_emg_assisted_batch(
        jac, tau, f_active=fa, f_passive=fp, a_ref=a_ref, measured=meas, w_track=1.0
    )
    assert (mid.status == 0).all() and np.abs(mid.torque_error).max() < 1e-6
    np.testing.assert_allclose(-np.einsum("kmn,km->kn", jac, mid.forces), tau, atol=1e-6)


def test_fit_emg_gains_rejects_bad_groups() -> None:
    rng = np.random.default_rng(0)
    jac, fa = _frames(rng, 5, 3, 2)
    tau = _torques(jac, fa, np.full((5, 3), 0.2))
    emg = rng.uniform(0.1, 1.0, (5, 3))
    kw = {"f_active": fa, "emg_activation": emg, "muscle_names": ("a", "b", "c")}
    with pytest.raises(IdentificationError, match="not a muscle"):
        fit_emg_gains(jac, tau, groups={"g": ("a", "z")}, **kw)
    with pytest.raises(IdentificationError, match="more than one"):
        fit_emg_gains(jac, tau, groups={"g": ("a",), "h": ("a", "b")}, **kw)
    emg0 = emg.copy()
    emg0[:, 2] = 0.0
    with pytest.raises(IdentificationError, match="no EMG"):
        fit_emg_gains(jac, tau, groups={"g": ("c",)}, **{**kw, "emg_activation": emg0})


def test_a_common_gain_keeps_the_measured_co_contraction() -> None:
    """One knee coordinate, two extensors and a flexor, all active as measured (the flexor
    against the extensors: co-contraction), every envelope on the same normalisation (true
    activation 0.5 ê). Per channel the flexor's gain collapses (no torque needs it; the joint
    minimum fits it to the static-optimisation activation); one common gain is set by the
    extensors and keeps the flexor's measured activity
    (:func:`msk.optimization.muscle_forces._emg_gains`, ``common``)."""
    from msk.optimization.muscle_forces import _emg_gains

    rng = np.random.default_rng(11)
    n_frames = 40
    arms = np.array([0.045, 0.04, -0.03])  # J = ∂l/∂θ: extensors shorten, flexor lengthens
    jac = np.tile(-arms[None, :, None], (n_frames, 1, 1))
    fa = np.tile([3000.0, 2500.0, 1500.0], (n_frames, 1))
    emg = np.column_stack(
        [rng.uniform(0.4, 1.0, n_frames), rng.uniform(0.4, 1.0, n_frames),
         rng.uniform(0.2, 0.5, n_frames)]
    )  # fmt: skip
    a_true = 0.5 * emg
    tau = _torques(jac, fa, a_true)
    assert np.all(tau > 0)  # net extension: the flexor is an antagonist
    names = ("vas_a", "vas_b", "bifem")
    channels = {"vas_a": "vasmed", "vas_b": "vaslat", "bifem": "bifeml"}
    args = (
        channels, 10.0, jac, tau, fa, np.zeros_like(fa), emg, np.ones(3, dtype=bool), names,
        None, None, ("knee",),
    )  # fmt: skip
    per = _emg_gains(*args)
    com = _emg_gains(*args, common=True)
    assert com.group_names == ("all",)
    g_flex_per = per.muscle_gains[2]
    assert g_flex_per < 0.25 * com.muscle_gains[2]  # the antagonist's EMG thrown away
    np.testing.assert_allclose(com.muscle_gains, com.muscle_gains[0])
    assert 0.35 < com.gains[0] < 0.55  # near the true 0.5 (the effort term pulls it down)
    # the common gain's flexor activation follows its EMG
    a_flex = com.solution.activations[:, 2]
    assert np.corrcoef(a_flex, emg[:, 2])[0, 1] > 0.9
    assert np.mean(a_flex) > 3 * np.mean(per.solution.activations[:, 2])
