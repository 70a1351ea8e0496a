"""Elastic-tendon contraction dynamics over time (the EMG-driven vs OpenSim thesis, §2.2.2, Eq.
8–18).

One ordinary differential equation per muscle, the fibre length ``l_m(t)``, driven by the
activation ``a(t)`` and the muscle–tendon length ``l_MT(t)`` (Lloyd & Besier 2003; Buchanan
2004; Bassett 2006). With the curves of :class:`msk.muscles.hill.LloydBesierCurves`:

    l_o(t) = l_opt (λ (1 − a) + 1),      l̃ = l_m / l_o(t)                                (Eq. 9)
    sin φ  = l_opt sin φ_0 / l_m         (constant-height pennation)                       (Eq. 14)
    l_t    = l_MT − l_m cos φ,   ε = (l_t − l_ts)/l_ts                                     (Eq. 15)
    F̃_t(ε) = 0 (ε ≤ 0);  1480.3 ε² (ε < 0.0127);  37.5 ε − 0.2375                      (Eq. 16–18)
    F̃_t    = [F̃_A(l̃) F̃_V(ṽ) a + F̃_P(l̃) + b_m ṽ] cos φ                                (Eq. 8)

with ṽ = l̇_m/(v_max l_opt) the normalised lengthening velocity (``v = −ṽ`` the shortening one,
the argument of Eq. 11–12). Series fibre and tendon carry the same force, so Eq. 8 is solved for
the velocity (Eq. 13): with ``A = a F̃_A(l̃)`` and ``c = F̃_t(ε)/cos φ − F̃_P(l̃)``,

    A F̃_V(v) − b_m v = c.

The damping b_m > 0 makes the left side strictly decreasing in v for every A ≥ 0 (also a = 0,
where the undamped force–velocity relation cannot be inverted — Schutte 1993), and each branch of
Eq. 11–12 gives a quadratic (Bassett 2006):

* concentric (c ≤ A, v ≥ 0), ``F̃_V = (b − a_h v)/(b + v)``:
  ``b_m v² + (a_h A + b_m b + c) v − b (A − c) = 0``; beyond v = b/a_h (F̃_V = 0)
  ``v = −c/b_m``;
* eccentric (c > A, u = −v > 0), ``F̃_V = F_ecc − (F_ecc − 1) b'/(b' + u)``:
  ``b_m u² + (A F_ecc + b_m b' − c) u − b' (c − A) = 0``;

each solved by the cancellation-free form of the positive root. Hence
``dl_m/dt = −v(l_m, a, l_MT) v_max l_opt``: an explicit ODE whose right-hand side is a casadi
expression (``casadi.if_else`` branches, continuous; differentiable except at v = 0 and on the
tendon toe, where one-sided derivatives exist).

**Integrator.** The tendon is stiff: relaxing a force error takes
``τ ≈ (A F̃_V′ + b_m) l_ts/(37.5 v_max l_opt)``, down to a fraction of a millisecond for a passive
vastus — far below a 10 ms sample — and F̃_V′ changes tenfold between isometric and fast
eccentric contraction. The fibre length is therefore advanced with the implicit, L-stable,
second-order backward differentiation formula (BDF2; variable-step form, ω = h_n/h_{n−1})::

    l_{n+1} − ((1+ω)² l_n − ω² l_{n−1})/(1+2ω) = h_n (1+ω)/(1+2ω) · l̇_m(t_{n+1}, l_{n+1})

solved for the velocity: with ``l = c0 + β l̇`` (c0, β the BDF2 history and weight) the force
balance of Eq. 8, ``R(l̇) = cos φ [a F̃_A F̃_V(v) + F̃_P + b_m ṽ] − F̃_t(ε) = 0``, is monotone in
l̇ — the damping keeps ∂R/∂l̇ ≥ b_m cos φ/(v_max l_opt) > 0 (Millard 2013's damped
equilibrium) — and nearly linear for a stiff tendon, so ``newton`` (default 3) Newton iterations
from the linear extrapolation ``l_n + ω (l_n − l_{n−1})`` converge (∂R/∂l̇ exact by casadi; each
update limited to 0.1 l_opt of fibre, which only acts far from the solution). Newton on the
fibre length itself, through the inverted force–velocity relation, does not: its kink at v = 0
and the hyperbolic eccentric branch make it cycle once the tendon is 100× stiffer.
``substeps`` steps per sample interval with a(t) and l_MT(t) linear in between; the first
interval, where the inputs start moving away from the static initial state, takes
4 × ``substeps`` steps, the very first one backward Euler. BDF2 has no
order reduction on this stiff problem, unlike the one-step Rosenbrock method ROS2 we tried first
(2 mm fibre-length error at 10 ms steps on a 1 Hz walk-like input, against 0.05 mm for BDF2).
The initial fibre length is the static equilibrium at the first sample (v = 0,
:func:`msk.muscles.hill.equilibrium`), reached by pseudo-transient continuation: ``n_init``
damped linearly implicit Euler steps ``Δl = H l̇_m/(1 + H |J|)`` (J = ∂l̇_m/∂l_m),
H = 0.5 s, each limited to 0.1 l_opt, at constant inputs from the fibre of a tendon at 2 %
strain. All of it is a fixed chain of casadi operations, so a calibration differentiates the
whole discrete trajectory exactly (:func:`tendon_force_trajectory`).

:func:`contraction_dynamics` is the numpy face: activations and lengths ``(N, M)`` →
:class:`ContractionState` (fibre length, velocity, pennation, tendon and fibre forces over time).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, ClassVar

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from msk.exceptions import MuscleModelError
from msk.muscles.hill import MAX_PENNATION_ANGLE, LloydBesierCurves, MuscleParameters
from msk.timeseries import FrameAxis
from msk.units import Array

__all__ = [
    "CONTRACTION_PARAMETER_ORDER",
    "ContractionState",
    "contraction_dynamics",
    "contraction_functions",
    "tendon_force_trajectory",
    "trajectory_function",
]

#: Order of the per-muscle parameter vector ``p`` of the casadi functions.
CONTRACTION_PARAMETER_ORDER: tuple[str, ...] = (
    "optimal_fiber_length",
    "tendon_slack_length",
    "sin_pennation_at_optimal",
    "max_contraction_velocity",
    "skew",
    "tendon_stiffness",
)

NEWTON_ITERATIONS = 3  # default Newton iterations per implicit step
_MAX_UPDATE = 0.1  # largest change of l_m per Newton / pseudo-time update, × l_opt
_START_REFINE = 4  # the first interval (backward Euler start, initial transient) is refined
_INIT_STEP_S = 0.5
_COS_MIN = float(np.cos(MAX_PENNATION_ANGLE))


@dataclass(frozen=True)
class ContractionState(FrameAxis):
    """Fibre and tendon state over time; arrays ``(N, M)`` (SI), ``time`` ``(N,)``.

    ``fiber_velocity`` is the lengthening velocity l̇_m of the ODE at each state and
    ``norm_fiber_velocity`` ṽ = l̇_m/(v_max l_opt); ``norm_fiber_length`` is relative to the
    activation-dependent l_o(t) (Eq. 9). Forces are in newtons: ``tendon_force`` F_iso F̃_t(ε);
    ``active_fiber_force`` F_iso a F̃_A F̃_V, ``passive_fiber_force`` F_iso F̃_P,
    ``damping_fiber_force`` F_iso b_m ṽ, all along the fibre, and ``fiber_force_along_tendon``
    their sum times cos φ (equal to the tendon force, Eq. 8).
    """

    FRAME_FIELDS: ClassVar[tuple[str, ...]] = (
        "time",
        "fiber_length",
        "norm_fiber_length",
        "fiber_velocity",
        "norm_fiber_velocity",
        "pennation_angle",
        "cos_pennation",
        "tendon_length",
        "tendon_strain",
        "tendon_force",
        "active_fiber_force",
        "passive_fiber_force",
        "damping_fiber_force",
        "fiber_force_along_tendon",
    )

    names: tuple[str, ...]
    time: Array
    fiber_length: Array
    norm_fiber_length: Array
    fiber_velocity: Array
    norm_fiber_velocity: Array
    pennation_angle: Array
    cos_pennation: Array
    tendon_length: Array
    tendon_strain: Array
    tendon_force: Array
    active_fiber_force: Array
    passive_fiber_force: Array
    damping_fiber_force: Array
    fiber_force_along_tendon: Array
    substeps: int


# ---------------------------------------------------------------------------------------------
# casadi maths
# ---------------------------------------------------------------------------------------------
def _tendon(eps: Any) -> Any:
    """Eq. 16–18 (casadi)."""
    ep = ca.fmax(eps, 0.0)
    return ca.if_else(eps >= 0.0127, 37.5 * eps - 0.2375, 1480.3 * ep**2)


def _shortening_velocity(act_fl: Any, c: Any, curves: LloydBesierCurves) -> Any:
    """Normalised shortening velocity v solving ``A F̃_V(v) − b_m v = c`` (Eq. 13, module
    docstring): closed-form roots of the concentric / eccentric quadratics."""
    bm = curves.damping
    a_h = b_h = curves.hill_curvature
    bp = (curves.f_ecc - 1.0) / (curves.ecc_slope_ratio * (1.0 + a_h) / b_h)
    fecc = curves.f_ecc

    def pos_root(bq: Any, cq: Any) -> Any:  # positive root of bm x² + bq x − cq, cq ≥ 0
        s = ca.sqrt(bq**2 + 4.0 * bm * cq)
        return ca.if_else(bq >= 0, 2.0 * cq / (bq + s + 1e-300), (s - bq) / (2.0 * bm))

    d_conc = ca.fmax(act_fl - c, 0.0)
    v_conc = pos_root(act_fl * a_h + bm * b_h + c, b_h * d_conc)
    v_conc = ca.if_else(c < -bm * b_h / a_h, -c / bm, v_conc)  # F̃_V = 0 beyond v = b/a
    d_ecc = ca.fmax(c - act_fl, 0.0)
    u_ecc = pos_root(act_fl * fecc + bm * bp - c, bp * d_ecc)
    return ca.if_else(c <= act_fl, v_conc, -u_ecc)


def _fiber_state(l_m: Any, a: Any, l_mt: Any, p: Any, curves: LloydBesierCurves) -> dict[str, Any]:
    """All quantities of the module docstring at fibre length ``l_m`` (casadi expressions)."""
    lopt, lts, sin0, vmax, skew, kt = (p[i] for i in range(6))
    hgt = lopt * sin0
    lmin = ca.fmax(hgt / np.sin(MAX_PENNATION_ANGLE), 0.05 * lopt)
    lf = ca.fmax(l_m, lmin)
    cos_p = ca.sqrt(ca.fmax(1.0 - (hgt / lf) ** 2, _COS_MIN**2))
    l_norm = lf / (lopt * (skew * (1.0 - a) + 1.0))
    fa = ca.exp(-(((l_norm - 1.0) / curves.width) ** 2))
    fp = ca.exp(10.0 * (l_norm - 1.0) - 5.0)
    l_t = l_mt - lf * cos_p
    eps = l_t / lts - 1.0
    ft = _tendon(kt * eps)
    act_fl = ca.fmax(a, 0.0) * fa
    c = ft / cos_p - fp
    v_short = _shortening_velocity(act_fl, c, curves)
    return {
        "dl": -v_short * vmax * lopt,
        "l_norm": l_norm,
        "cos": cos_p,
        "l_t": l_t,
        "eps": eps,
        "ft": ft,
        "fa": fa,
        "fp": fp,
        "act_fl": act_fl,
        "v_short": v_short,
    }


def _force_velocity(v_short: Any, curves: LloydBesierCurves) -> Any:
    """Eq. 11–12 (casadi), as :meth:`LloydBesierCurves.force_velocity`."""
    a_h = b_h = curves.hill_curvature
    bp = (curves.f_ecc - 1.0) / (curves.ecc_slope_ratio * (1.0 + a_h) / b_h)
    vp, vn = ca.fmax(v_short, 0.0), ca.fmin(v_short, 0.0)
    conc = ca.fmax((b_h - a_h * vp) / (b_h + vp), 0.0)
    ecc = curves.f_ecc - (curves.f_ecc - 1.0) * bp / (bp - vn)
    return ca.if_else(v_short >= 0, conc, ecc)


def _balance_function(curves: LloydBesierCurves) -> ca.Function:
    """``R(l̇, c0, β, a, l_MT, p) → (R, ∂R/∂l̇)``: Eq. 8 residual, fibre force along the tendon
    minus tendon force (/F_iso), at the implicit-step fibre length ``l = c0 + β l̇``."""
    ld, c0, beta, a, lmt = (ca.SX.sym(n) for n in ("ldot", "c0", "beta", "a", "l_mt"))
    p = ca.SX.sym("p", len(CONTRACTION_PARAMETER_ORDER))
    st = _fiber_state(c0 + beta * ld, a, lmt, p, curves)
    v_short = -ld / (p[3] * p[0])
    fibre = st["act_fl"] * _force_velocity(v_short, curves) + st["fp"] - curves.damping * v_short
    r = st["cos"] * fibre - st["ft"]
    return ca.Function("balance", [ld, c0, beta, a, lmt, p], [r, ca.jacobian(r, ld)])


def _bdf2_interval(
    balance: ca.Function,
    y: Any,
    y_prev: Any,
    inputs: tuple[Any, Any, Any, Any],
    p: Any,
    h: Any,
    hs_prev: Any,
    substeps: int,
    start: bool,
    damping: float,
    newton: int,
) -> tuple[Any, Any]:
    """``substeps`` BDF2 steps over one sample interval (the first a backward Euler step when
    ``start``); ``hs_prev`` is the length of the substep that ended at ``y``. Each step solves
    the force balance (Eq. 8) at ``l = c0 + β l̇`` for the velocity l̇ by
    ``newton`` Newton iterations from the linear extrapolation. Returns (y at the end, y one
    substep before)."""
    a0, a1, m0, m1 = inputs
    hs = h / substeps
    dr_min = 0.5 * _COS_MIN * damping / (p[3] * p[0])  # the damping keeps ∂R/∂l̇ > 0
    for i in range(substeps):
        s1 = (i + 1) / substeps
        aj, mj = a0 + s1 * (a1 - a0), m0 + s1 * (m1 - m0)
        if start and i == 0:
            c0, beta, z = y, hs, y
        else:
            w = hs / hs_prev  # variable-step BDF2, ω = h_n/h_{n-1}
            c0 = ((1.0 + w) ** 2 * y - w**2 * y_prev) / (1.0 + 2.0 * w)
            beta = hs * (1.0 + w) / (1.0 + 2.0 * w)
            z = y + w * (y - y_prev)
        ld = (z - c0) / beta
        max_d = _MAX_UPDATE * p[0] / beta
        for _ in range(newton):
            r, dr = balance(ld, c0, beta, aj, mj, p)
            d = r / ca.fmax(dr, dr_min)
            ld = ld - ca.fmin(ca.fmax(d, -max_d), max_d)
        y_prev, y, hs_prev = y, c0 + beta * ld, hs
    return y, y_prev


@lru_cache(maxsize=16)
def contraction_functions(
    curves: LloydBesierCurves, substeps: int, newton: int = NEWTON_ITERATIONS
) -> dict[str, ca.Function]:
    """Casadi functions of one muscle (SX; inlined when called on SX arguments), ``p`` in the
    order of :data:`CONTRACTION_PARAMETER_ORDER`:

    * ``rhs(l_m, a, l_MT, p) → (l̇_m, J)``: the ODE and its exact ∂l̇_m/∂l_m;
    * ``start(l_m, a0, a1, l_MT0, l_MT1, p, h) → (l_m(t + h), l_m one substep before)``: the
      first sample interval (4 × ``substeps`` steps: backward Euler, then BDF2);
    * ``step(l_m, l_m_prev, a0, a1, l_MT0, l_MT1, p, h, hs_prev) → (…)``: the next ones (BDF2,
      ``hs_prev`` the length of the substep from ``l_m_prev`` to ``l_m``);
    * ``init_<n>(a, l_MT, p) → l_m``: ``n`` ∈ {5, 10, 20, 40} pseudo-transient steps to the
      static equilibrium;
    * ``state(l_m, a, l_MT, p) → [l̇_m, l̃, cos φ, l_t, ε, F̃_t, F̃_A, F̃_P, v]``.
    """
    if substeps < 1 or newton < 1:
        raise MuscleModelError(f"substeps and newton must be >= 1, got {substeps}, {newton}")
    lm, lm_prev, a, lmt = (ca.SX.sym(n) for n in ("l_m", "l_m_prev", "a", "l_mt"))
    p = ca.SX.sym("p", len(CONTRACTION_PARAMETER_ORDER))
    st = _fiber_state(lm, a, lmt, p, curves)
    jac = ca.jacobian(st["dl"], lm)
    rhs = ca.Function("rhs", [lm, a, lmt, p], [st["dl"], jac])
    keys = ("dl", "l_norm", "cos", "l_t", "eps", "ft", "fa", "fp", "v_short")
    state = ca.Function("state", [lm, a, lmt, p], [ca.vertcat(*(st[k] for k in keys))])

    a0, a1, m0, m1, h, hs_prev = (
        ca.SX.sym(n) for n in ("a0", "a1", "lmt0", "lmt1", "h", "hs_prev")
    )
    inputs = (a0, a1, m0, m1)
    bal = _balance_function(curves)
    y_s = _bdf2_interval(
        bal,
        lm,
        lm,
        inputs,
        p,
        h,
        h,
        _START_REFINE * substeps,
        start=True,
        damping=curves.damping,
        newton=newton,
    )
    start = ca.Function("start", [lm, a0, a1, m0, m1, p, h], list(y_s))
    y_n = _bdf2_interval(
        bal,
        lm,
        lm_prev,
        inputs,
        p,
        h,
        hs_prev,
        substeps,
        start=False,
        damping=curves.damping,
        newton=newton,
    )
    step = ca.Function("step", [lm, lm_prev, a0, a1, m0, m1, p, h, hs_prev], list(y_n))

    # pseudo-transient continuation to the static equilibrium: linearly implicit Euler
    y = _initial_guess(a, lmt, p)
    inits = {}
    for n in range(1, 41):
        f0, j0 = rhs(y, a, lmt, p)
        dy = _INIT_STEP_S * f0 / (1.0 + _INIT_STEP_S * ca.fabs(j0))
        y = y + ca.fmin(ca.fmax(dy, -_MAX_UPDATE * p[0]), _MAX_UPDATE * p[0])
        if n in (5, 10, 20, 40):
            inits[f"init_{n}"] = ca.Function(f"init_{n}", [a, lmt, p], [y])
    return {"rhs": rhs, "start": start, "step": step, "state": state, **inits}


def _initial_guess(a: Any, l_mt: Any, p: Any) -> Any:
    """Fibre length of a tendon at 2 % strain (rigid-tendon geometry), kept ≥ 0.3 l_opt."""
    lopt, lts, sin0 = p[0], p[1], p[2]
    hgt = lopt * sin0
    x = ca.fmax(l_mt - 1.02 * lts, 0.3 * lopt)
    return ca.sqrt(x**2 + hgt**2)


def tendon_force_trajectory(
    activation: Sequence[Any] | Any,
    muscle_tendon_length: Sequence[Any] | Any,
    p: Any,
    dt: float | ArrayLike,
    *,
    curves: LloydBesierCurves,
    substeps: int = 2,
    n_init: int = 20,
    newton: int = NEWTON_ITERATIONS,
) -> Any:
    """Normalised tendon force F̃_t ``(N, 1)`` of one muscle along a trajectory, as a casadi
    expression of symbolic activations (``N`` scalars or an ``(N, 1)`` column) and parameters
    ``p`` (:data:`CONTRACTION_PARAMETER_ORDER`); ``muscle_tendon_length`` ``(N,)`` numbers or
    expressions, ``dt`` the sample interval(s). Exact derivatives of the discrete integrator
    follow by casadi AD (used by the elastic-tendon EMG-driven calibration)."""
    fns = contraction_functions(curves, int(substeps), int(newton))
    init = fns[f"init_{_check_n_init(n_init)}"]
    shape = getattr(muscle_tendon_length, "shape", None)
    n = int(shape[0]) if shape is not None else len(muscle_tendon_length)
    acts = [activation[t] for t in range(n)]
    lmt = [muscle_tendon_length[t] for t in range(n)]
    dts = np.broadcast_to(np.asarray(dt, dtype=float), (max(n - 1, 1),))
    lm = init(acts[0], lmt[0], p)
    lm_prev = lm
    out = []
    for t in range(n):
        out.append(fns["state"](lm, acts[t], lmt[t], p)[5])
        if t + 1 == n:
            break
        ins = (acts[t], acts[t + 1], lmt[t], lmt[t + 1])
        if t == 0:
            lm, lm_prev = fns["start"](lm, *ins, p, dts[t])
        else:
            lm, lm_prev = fns["step"](lm, lm_prev, *ins, p, dts[t], _last_substep(dts, t, substeps))
    return ca.vertcat(*out)


@lru_cache(maxsize=32)
def trajectory_function(
    curves: LloydBesierCurves,
    substeps: int,
    n: int,
    dt: float,
    n_init: int = 20,
    newton: int = NEWTON_ITERATIONS,
) -> ca.Function:
    """``ft(a, l_MT, p) → F̃_t``: :func:`tendon_force_trajectory` as one casadi function of
    ``n`` activations, ``n`` muscle–tendon lengths and the parameters ``p`` (all ``(·, 1)``) at
    the uniform interval ``dt``. An MX graph calling it (``.map`` over muscles) stays small, so
    casadi builds its Jacobian quickly; the elastic-tendon calibration uses it."""
    a = ca.SX.sym("a", n)
    lmt = ca.SX.sym("l_mt", n)
    p = ca.SX.sym("p", len(CONTRACTION_PARAMETER_ORDER))
    ft = tendon_force_trajectory(
        a, lmt, p, dt, curves=curves, substeps=substeps, n_init=n_init, newton=newton
    )
    return ca.Function("tendon_force_trajectory", [a, lmt, p], [ft])


def _last_substep(dt: Array, i: int, substeps: int) -> float:
    """Length of the substep that ended at sample ``i`` (the first interval is refined)."""
    return float(dt[i - 1]) / (substeps * (_START_REFINE if i == 1 else 1))


def _check_n_init(n_init: int) -> int:
    if n_init not in (5, 10, 20, 40):
        raise MuscleModelError(f"n_init must be one of 5, 10, 20, 40, got {n_init}")
    return int(n_init)


# ---------------------------------------------------------------------------------------------
# numpy face
# ---------------------------------------------------------------------------------------------
def _as_frames(params: MuscleParameters, x: ArrayLike, n: int | None, what: str) -> Array:
    v = np.asarray(x, dtype=float)
    if v.ndim == 1 and n is not None and v.shape[0] == n and params.n_muscles != n:
        v = v[:, None]
    shape = (n if n is not None else 1, params.n_muscles)
    if v.ndim > 2 or (v.ndim == 2 and v.shape[1] != params.n_muscles):
        raise MuscleModelError(f"{what} must be (N, {params.n_muscles}), got {v.shape}")
    try:
        v = np.broadcast_to(v, shape)
    except ValueError as exc:
        raise MuscleModelError(f"{what} must be {shape}, got {np.shape(x)}") from exc
    if not np.isfinite(v).all():
        r, c = np.argwhere(~np.isfinite(v))[0]
        raise MuscleModelError(f"{what}: non-finite value at frame {r}, muscle {params.names[c]!r}")
    return np.array(v, dtype=float)


def contraction_dynamics(
    params: MuscleParameters,
    activation: ArrayLike,
    muscle_tendon_length: ArrayLike,
    time: ArrayLike,
    *,
    curves: LloydBesierCurves | None = None,
    substeps: int = 2,
    tendon_stiffness: float = 1.0,
    initial_fiber_length: ArrayLike | None = None,
    n_init: int = 20,
    newton: int = NEWTON_ITERATIONS,
) -> ContractionState:
    """Integrate the elastic-tendon fibre dynamics (module docstring) over ``time``.

    Args:
        params: muscle parameters (F_iso, l_opt, l_ts, φ_0, v_max), ``M`` muscles.
        activation: a(t) ``(N, M)`` (broadcast), linear between samples.
        muscle_tendon_length: l_MT(t) ``(N, M)``, linear between samples.
        time: ``(N,)`` strictly increasing sample times (s).
        curves: the EMG-driven vs OpenSim thesis curves (skew λ and damping b_m included); default
            :class:`LloydBesierCurves`.
        substeps: BDF2 steps per sample interval.
        tendon_stiffness: multiplier of the strain in Eq. 16–18 (> 1: a stiffer tendon; large
            values approach the rigid tendon).
        initial_fiber_length: ``(M,)`` fibre lengths at ``time[0]``; default the static
            equilibrium there (``n_init`` pseudo-transient steps).
    """
    curves = curves or LloydBesierCurves()
    t = np.asarray(time, dtype=float)
    if t.ndim != 1 or t.size < 1 or not np.all(np.isfinite(t)):
        raise MuscleModelError(f"time must be a finite (N,) array, got shape {t.shape}")
    if t.size > 1 and not np.all(np.diff(t) > 0):
        i = int(np.flatnonzero(np.diff(t) <= 0)[0])
        raise MuscleModelError(f"time must increase strictly: t[{i}] = {t[i]}, next {t[i + 1]}")
    if not tendon_stiffness > 0:
        raise MuscleModelError(f"tendon_stiffness must be > 0, got {tendon_stiffness}")
    n, m = t.size, params.n_muscles
    lmt = _as_frames(params, muscle_tendon_length, n, "muscle_tendon_length")
    act = _as_frames(params, activation, n, "activation")
    fns = contraction_functions(curves, int(substeps), int(newton))
    pmat = np.vstack(
        [
            params.optimal_fiber_length,
            params.tendon_slack_length,
            np.sin(params.pennation_angle_at_optimal),
            params.max_contraction_velocity,
            np.full(m, curves.skew),
            np.full(m, float(tendon_stiffness)),
        ]
    )
    start, step = fns["start"].map(m), fns["step"].map(m)
    state = fns["state"].map(m)
    if initial_fiber_length is None:
        lm = np.asarray(fns[f"init_{_check_n_init(n_init)}"].map(m)(act[0], lmt[0], pmat))
        lm = lm.ravel()
    else:
        lm = np.broadcast_to(np.asarray(initial_fiber_length, dtype=float), (m,)).copy()
        if not np.all(np.isfinite(lm) & (lm > 0)):
            raise MuscleModelError(f"initial_fiber_length must be finite and > 0, got {lm}")
    traj = np.empty((n, m))
    traj[0] = lm
    lm_prev = lm
    dt = np.diff(t)
    for i in range(n - 1):
        ins = (act[i], act[i + 1], lmt[i], lmt[i + 1])
        if i == 0:
            out = start(lm, *ins, pmat, dt[i])
        else:
            out = step(lm, lm_prev, *ins, pmat, dt[i], _last_substep(dt, i, int(substeps)))
        lm, lm_prev = (np.asarray(o).ravel() for o in out)
        traj[i + 1] = lm
    if not np.isfinite(traj).all():
        r, c = np.argwhere(~np.isfinite(traj))[0]
        raise MuscleModelError(
            f"muscle {params.names[c]!r}: contraction dynamics diverged at frame {r}"
        )
    cols = np.empty((n, 9, m))
    for i in range(n):
        cols[i] = np.asarray(state(traj[i], act[i], lmt[i], pmat))
    dl, l_norm, cos_p, l_t, eps, ft, fa, fp, v_short = (cols[:, j, :] for j in range(9))
    fiso = params.max_isometric_force
    v_norm = -v_short
    lf = np.maximum(traj, 0.0)
    active = fiso * np.maximum(act, 0.0) * fa * curves.force_velocity(v_short)
    passive = fiso * fp
    damping = fiso * curves.damping * v_norm
    return ContractionState(
        names=params.names,
        time=t,
        fiber_length=lf,
        norm_fiber_length=l_norm,
        fiber_velocity=dl,
        norm_fiber_velocity=v_norm,
        pennation_angle=np.arccos(np.clip(cos_p, -1.0, 1.0)),
        cos_pennation=cos_p,
        tendon_length=l_t,
        tendon_strain=eps,
        tendon_force=fiso * ft,
        active_fiber_force=active,
        passive_fiber_force=passive,
        damping_fiber_force=damping,
        fiber_force_along_tendon=(active + passive + damping) * cos_p,
        substeps=int(substeps),
    )
