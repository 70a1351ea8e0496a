"""Activation dynamics: EMG envelope (neural excitation) → muscle activation, per muscle column.

Two families, both taking ``e`` of shape ``(N, M)`` (time on axis 0, one column per muscle):

* **first order** (:func:`first_order_activation`), Hayashibe et al. 2011, Eq. 8::

      ȧ = (u − a)/T,   T = T_a if u > a, T_d otherwise                       (form="seed002")

  and the two standard state-dependent variants: Thelen 2003 / OpenSim
  ``MuscleFirstOrderActivationDynamicModel`` (``T = T_a (0.5 + 1.5 a)`` when activating,
  ``T = T_d/(0.5 + 1.5 a)`` when deactivating, form="thelen") and Zajac/Winters
  (``ȧ = (u − a)(u/T_a + (1 − u)/T_d)``, form="zajac"). Integrated with the exponential
  update ``a ← u + (a − u) exp(−h/T)``: exact for form="seed002" (u is held over each sample,
  so T is constant on it), and on ``substeps`` sub-intervals per sample for the state-dependent
  forms (first-order accurate in h). Each update is a convex combination of a and u, so
  a ∈ [0, 1] whenever u ∈ [0, 1].

* **second-order recursive filter** (:func:`recursive_filter`), the EMG-driven vs OpenSim thesis,
  Eq. 1–6
  (Lloyd & Besier 2003; Buchanan 2004)::

      u(t) = α e(t − d) − β1 u(t − 1) − β2 u(t − 2)                          (Eq. 1)
      β1 = γ1 + γ2,  β2 = γ1 γ2,  |γ1| < 1,  |γ2| < 1                          (Eq. 2–5)

  The poles are z = −γ1, −γ2 (stable for |γ| < 1). For Eq. 1 as printed the steady-state gain
  is α/(1 + β1 + β2), so Eq. 6 (α − β1 − β2 = 1, i.e. **α = 1 + β1 + β2**) is exactly the
  unit-gain condition; we impose it (checked by a test). For γ1, γ2 ∈ (−1, 0] both poles are in
  [0, 1), the impulse response is non-negative and sums to 1, so u ∈ [0, 1] for e ∈ [0, 1]; a
  positive γ gives a negative pole (an alternating, overshooting response).

  followed by the neural → muscle activation nonlinearity (:func:`nonlinear_activation`), in one
  of two forms:

  - ``form="piecewise"`` (default): the EMG-driven vs OpenSim thesis, Eq. 7 as printed, the
    one-parameter model of
    Manal & Buchanan (2003, J Biomech 36:1197)::

        a = d ln(c u + 1)      0 ≤ u < 0.3085
        a = m u + b            0.3085 ≤ u ≤ 1,        shape factor A ∈ [0, 0.6915)

    The thesis says b, c, d and m follow from A alone but does not print the relation; we take
    the construction its Fig. 2.3 describes: the linear piece runs from Q = (u₀, u₀ + A),
    u₀ = 0.3085 (A is the distance from P = (u₀, u₀) on the identity line to Q), to (1, 1), and
    the logarithmic piece passes through (0, 0) and meets the line at Q with the same slope
    (value and slope continuous). A = 0 is the identity a = u; the EMG-driven vs OpenSim thesis,
    Table 3.1 bounds A to [0.01, 0.12]. It is the default because it is the only form the EMG-driven
    vs OpenSim thesis uses (Eq. 7, Table 3.1).
  - ``form="exponential"``: Lloyd & Besier (2003, J Biomech 36:765, Eq. 8)::

        a = (e^{A u} − 1)/(e^{A} − 1),   −3 < A ≤ 0   (A → 0 gives a = u)

    used by :mod:`msk.strength.calibration` (smooth in A and u, which its exact casadi
    derivatives need).
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from msk.exceptions import MuscleModelError
from msk.units import Array

__all__ = [
    "PIECEWISE_BREAKPOINT",
    "ActivationForm",
    "NonlinearityForm",
    "emg_to_activation",
    "first_order_activation",
    "nonlinear_activation",
    "piecewise_coefficients",
    "recursive_filter",
    "recursive_filter_coefficients",
]

ActivationForm = Literal["seed002", "thelen", "zajac"]
NonlinearityForm = Literal["piecewise", "exponential"]

#: Neural activation at which the EMG-driven vs OpenSim thesis, Eq. 7 switches from the logarithmic
#: to the linear piece (Manal & Buchanan 2003).
PIECEWISE_BREAKPOINT = 0.3085


def _as_2d(e: ArrayLike) -> tuple[Array, bool]:
    x = np.asarray(e, dtype=float)
    was_1d = x.ndim == 1
    if was_1d:
        x = x[:, None]
    if x.ndim != 2:
        raise MuscleModelError(f"excitation must be (N,) or (N, M), got shape {x.shape}")
    if not np.isfinite(x).all():
        r, c = np.argwhere(~np.isfinite(x))[0]
        raise MuscleModelError(f"excitation has a non-finite value at frame {r}, column {c}")
    return x, was_1d


def _per_muscle(v: ArrayLike, m: int, what: str) -> Array:
    a = np.asarray(v, dtype=float)
    if a.ndim == 0:
        return np.full(m, float(a))
    if a.shape != (m,):
        raise MuscleModelError(f"{what} must be a scalar or have {m} entries, got shape {a.shape}")
    return a


def _names(m: int, names: tuple[str, ...] | list[str] | None) -> list[str]:
    return list(names) if names is not None else [f"column {j}" for j in range(m)]


def first_order_activation(
    excitation: ArrayLike,
    *,
    rate_hz: float,
    tau_act_s: ArrayLike = 0.015,
    tau_deact_s: ArrayLike = 0.050,
    form: ActivationForm = "seed002",
    initial: ArrayLike | None = None,
    substeps: int = 4,
    names: tuple[str, ...] | list[str] | None = None,
) -> Array:
    """First-order activation dynamics (Hayashibe et al. 2011, Eq. 8; Thelen 2003; Zajac 1989).

    ``excitation`` u is ``(N,)`` or ``(N, M)`` in [0, 1], held constant over each sample
    interval; ``initial`` defaults to u at the first sample (no start-up transient). Time
    constants may be per muscle. Returns a of the same shape.
    """
    u, was_1d = _as_2d(excitation)
    n, m = u.shape
    nm = _names(m, names)
    ta = _per_muscle(tau_act_s, m, "tau_act_s")
    td = _per_muscle(tau_deact_s, m, "tau_deact_s")
    for tau, what in ((ta, "tau_act_s"), (td, "tau_deact_s")):
        bad = ~(np.isfinite(tau) & (tau > 0))
        if bad.any():
            j = int(np.flatnonzero(bad)[0])
            raise MuscleModelError(f"muscle {nm[j]!r}: {what} must be > 0 s, got {tau[j]}")
    if rate_hz <= 0 or substeps < 1:
        raise MuscleModelError(f"rate_hz must be > 0 and substeps >= 1, got {rate_hz}, {substeps}")
    if form not in ("seed002", "thelen", "zajac"):
        raise MuscleModelError(f"unknown activation form {form!r}")
    a = u[0].copy() if initial is None else _per_muscle(initial, m, "initial").copy()
    out = np.empty_like(u)
    out[0] = a
    if form == "seed002":
        # u is held over each interval, so a moves monotonically towards u without crossing it
        # and T stays T_a or T_d throughout: one exponential step per sample is exact.
        ka, kd = np.exp(-1.0 / (rate_hz * ta)), np.exp(-1.0 / (rate_hz * td))
        for k in range(1, n):
            uk = u[k - 1]
            a = uk + (a - uk) * np.where(uk > a, ka, kd)
            out[k] = a
        return out[:, 0] if was_1d else out
    h = 1.0 / (rate_hz * substeps)
    for k in range(1, n):
        uk = u[k - 1]
        for _ in range(substeps):
            if form == "thelen":
                tau = np.where(uk > a, ta * (0.5 + 1.5 * a), td / (0.5 + 1.5 * a))
            else:
                tau = 1.0 / (uk / ta + (1.0 - uk) / td)
            a = uk + (a - uk) * np.exp(-h / tau)
        out[k] = a
    return out[:, 0] if was_1d else out


def recursive_filter_coefficients(gamma1: float, gamma2: float) -> tuple[float, float, float]:
    """(α, β1, β2) of the EMG-driven vs OpenSim thesis, Eq. 2–6 with α = 1 + β1 + β2 (unit
    steady-state gain)."""
    b1 = gamma1 + gamma2
    b2 = gamma1 * gamma2
    return 1.0 + b1 + b2, b1, b2


def recursive_filter(
    excitation: ArrayLike,
    *,
    gamma1: ArrayLike,
    gamma2: ArrayLike,
    delay_samples: ArrayLike = 0,
    initial: Literal["steady", "zero"] = "steady",
    names: tuple[str, ...] | list[str] | None = None,
) -> Array:
    """Neural activation u(t) from e(t) (the EMG-driven vs OpenSim thesis, Eq. 1–6), one filter per
    column.

    ``gamma1``, ``gamma2`` and ``delay_samples`` (the electromechanical delay d, in samples)
    may be per muscle. |γ| ≥ 1 raises :class:`MuscleModelError` naming the muscle and value.
    The first ``d`` samples of the delayed input repeat e(0); ``initial="steady"`` starts the
    filter at rest on e(0) (no transient), ``"zero"`` from u = 0.
    """
    e, was_1d = _as_2d(excitation)
    n, m = e.shape
    nm = _names(m, names)
    g1 = _per_muscle(gamma1, m, "gamma1")
    g2 = _per_muscle(gamma2, m, "gamma2")
    d = _per_muscle(delay_samples, m, "delay_samples")
    for g, what in ((g1, "gamma1"), (g2, "gamma2")):
        bad = ~(np.abs(g) < 1.0)
        if bad.any():
            j = int(np.flatnonzero(bad)[0])
            raise MuscleModelError(
                f"muscle {nm[j]!r}: |{what}| must be < 1 for a stable filter (the EMG-driven vs "
                "OpenSim thesis, Eq. 4-5), "
                f"got {g[j]}"
            )
    if np.any(d < 0) or np.any(d != np.round(d)):
        j = int(np.flatnonzero((d < 0) | (d != np.round(d)))[0])
        raise MuscleModelError(
            f"muscle {nm[j]!r}: delay_samples must be a whole number >= 0, got {d[j]}"
        )
    from scipy.signal import lfilter, lfilter_zi  # on use: ~0.45 s a cached run need not pay

    out = np.empty_like(e)
    for j in range(m):
        alpha, b1, b2 = recursive_filter_coefficients(g1[j], g2[j])
        dj = int(d[j])
        x = np.concatenate([np.full(dj, e[0, j]), e[: n - dj, j]]) if dj else e[:, j]
        b, a = [alpha], [1.0, b1, b2]
        if initial == "steady":
            zi = lfilter_zi(b, a) * x[0]
            out[:, j] = lfilter(b, a, x, zi=zi)[0]
        else:
            out[:, j] = lfilter(b, a, x)
    return out[:, 0] if was_1d else out


def piecewise_coefficients(shape_factor: float) -> tuple[float, float, float, float]:
    """``(d, c, m, b)`` of the EMG-driven vs OpenSim thesis, Eq. 7 (Manal & Buchanan 2003) for shape
    factor A.

    The line ``a = m u + b`` joins Q = (u₀, u₀ + A) to (1, 1) (u₀ = :data:`PIECEWISE_BREAKPOINT`);
    ``a = d ln(c u + 1)`` passes through the origin and matches the line's value and slope at
    u₀. With x = c u₀ the two conditions reduce to ``(1 + x) ln(1 + x)/x = (u₀ + A)/(m u₀)``,
    whose left side increases from 1 (x → 0), so x is unique. A = 0 returns the identity
    (``d = inf``, ``c = 0``, ``m = 1``, ``b = 0``). A outside [0, 1 − u₀) raises
    :class:`MuscleModelError`.
    """
    from scipy.optimize import brentq

    u0 = PIECEWISE_BREAKPOINT
    A = float(shape_factor)
    if not (0.0 <= A < 1.0 - u0):
        raise MuscleModelError(
            f"piecewise shape factor A must be in [0, {1.0 - u0:.4f}), got {A} "
            "(the EMG-driven vs OpenSim thesis, Table 3.1, uses [0.01, 0.12]; form='exponential' "
            "takes A in (-3, 0])"
        )
    y0 = u0 + A
    m = (1.0 - y0) / (1.0 - u0)
    b = 1.0 - m
    if A < 1e-12:
        return math.inf, 0.0, 1.0, 0.0
    r = y0 / (m * u0)

    def g(x: float) -> float:
        return (1.0 + x) * math.log1p(x) / x - r

    hi = 1.0
    while g(hi) < 0.0:
        hi *= 2.0
    x = brentq(g, 1e-12, hi, xtol=1e-14, rtol=1e-14)
    c = x / u0
    d = y0 / math.log1p(x)
    return d, c, m, b


def nonlinear_activation(
    neural_activation: ArrayLike,
    *,
    shape_factor: ArrayLike,
    form: NonlinearityForm = "piecewise",
    names: tuple[str, ...] | list[str] | None = None,
) -> Array:
    """Muscle activation a from neural activation u (the EMG-driven vs OpenSim thesis, Eq. 7), per
    column.

    ``form="piecewise"`` (default; Manal & Buchanan 2003, the form the EMG-driven vs OpenSim thesis
    prints): ``a = d ln(c u + 1)`` below u = 0.3085, ``a = m u + b`` above, coefficients from
    :func:`piecewise_coefficients`, A ∈ [0, 0.6915). ``form="exponential"`` (Lloyd & Besier
    2003, Eq. 8): ``a = (e^{A u} − 1)/(e^{A} − 1)``, A ∈ (−3, 0]. A = 0 is a = u in both.
    A outside its form's range raises :class:`MuscleModelError` naming the muscle.
    """
    u, was_1d = _as_2d(neural_activation)
    m = u.shape[1]
    nm = _names(m, names)
    A = _per_muscle(shape_factor, m, "shape_factor")
    if form == "piecewise":
        a = np.empty_like(u)
        for j in range(m):
            try:
                d, c, slope, b = piecewise_coefficients(A[j])
            except MuscleModelError as exc:
                raise MuscleModelError(f"muscle {nm[j]!r}: {exc}") from None
            if c == 0.0:
                a[:, j] = u[:, j]
                continue
            low = u[:, j] < PIECEWISE_BREAKPOINT
            # log1p of c u for u < 0 (filter undershoot) is kept finite by the clip
            a[:, j] = np.where(
                low, d * np.log1p(c * np.maximum(u[:, j], -0.99 / c)), slope * u[:, j] + b
            )
        return a[:, 0] if was_1d else a
    if form != "exponential":
        raise MuscleModelError(f"unknown nonlinearity form {form!r}: 'piecewise' or 'exponential'")
    bad = ~((A > -3.0) & (A <= 0.0))
    if bad.any():
        j = int(np.flatnonzero(bad)[0])
        raise MuscleModelError(
            f"muscle {nm[j]!r}: exponential shape factor A must be in (-3, 0], got {A[j]}"
        )
    lin = np.abs(A) < 1e-8
    As = np.where(lin, -1.0, A)
    a = np.where(lin, u, np.expm1(As * u) / np.expm1(As))
    return a[:, 0] if was_1d else a


def emg_to_activation(
    excitation: ArrayLike,
    *,
    gamma1: ArrayLike,
    gamma2: ArrayLike,
    shape_factor: ArrayLike,
    delay_samples: ArrayLike = 0,
    form: NonlinearityForm = "piecewise",
    names: tuple[str, ...] | list[str] | None = None,
) -> Array:
    """Recursive filter then nonlinearity (the EMG-driven vs OpenSim thesis, Eq. 1–7): e(t) → u(t) →
    a(t); ``form`` and the range of ``shape_factor`` as in :func:`nonlinear_activation`."""
    u = recursive_filter(
        excitation, gamma1=gamma1, gamma2=gamma2, delay_samples=delay_samples, names=names
    )
    return nonlinear_activation(u, shape_factor=shape_factor, form=form, names=names)
