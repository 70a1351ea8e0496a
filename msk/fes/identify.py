"""Identification steps of the quadriceps–shank model (Benoussaad et al. 2013, §2.3, the
implanted-FES identification paper, §IV).

Every step is a free function returning a frozen result with its identified values, the
measured/predicted series it was fitted on (with column names) and its quality figures
``nrmsd`` (Benoussaad et al. 2013, Eq. 9, %) and ``nrmse`` (the implanted-FES identification paper,
§V, %), both from :mod:`msk.metrics`.

Steps (in protocol order):

1. :func:`geometry_from_height` — ``L_ext``, ``r_q`` by linear least squares on normalised
   quadriceps lengths from a fifth-order polynomial × anthropometric shank length
   (000 §2.3.1.1, 001 §IV.B).
2. :func:`shank_anthropometry` — shank+foot mass, COM distance and inertia about the knee from
   body mass and height by regression tables (001 §IV.A).
3. :func:`identify_static_torque` — ``K`` of ``T_s = K sin θ_r`` by linear least squares
   (000 Eq. 7, §2.3.1.2).
4. :func:`identify_pendulum_linear` — ``ω_n``, ``ζ`` of the free response, then ``J`` (or
   ``K_eq``) and ``B`` (000 §2.3.1.2; 001 Eq. 4: ``K_eq = ω_n² J``, ``F_v = 2 ζ ω_n J``) and
   :func:`identify_pendulum_nonlinear` — direct fit of the nonlinear passive model.
5. :func:`identify_force_length` — ``b``, ``L_c0`` (and ``L_s``) by linear least squares on
   the logarithm of Eq. 2 (000 §2.3.1.3, 001 Eq. 5).
6. :func:`identify_recruitment_pw` — ``c1, c2, c3`` by nonlinear least squares on isometric
   steady-state torques, then ``F_cm`` and ``K_cm`` (000 §2.3.1.4, Eq. 10);
   :func:`identify_recruitment_current` — ``a_I, B_r, C_r, D_r`` from dynamic data with the
   model in the loop (001 Eq. 7, Fig. 5).
7. :func:`identify_series_stiffness` — ``k_s`` by the NLP of 000 Eq. 8, solved with casadi +
   ipopt by multiple shooting (model integrated in the loop, ``k_s > 0``).
8. :func:`cross_validate` — NRMSD/NRMSE of the identified model on an unseen stimulation.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from msk.exceptions import IdentificationError, MissingDataError
from msk.fes.model import (
    GEOMETRY_POLY_FROM_HEIGHT,
    PARAM_NAMES,
    SHANK_LENGTH_FRACTION,
    CalciumParams,
    FesSubject,
    G,
    GeometryParams,
    RecruitmentCurrent,
    RecruitmentPW,
    param_vector,
)
from msk.fes.priors import k_s_lower_bound
from msk.fes.simulate import DT, simulate, step_function
from msk.fes.stimulation import Stimulation, calcium_pi, sample_on_grid
from msk.metrics import nrmsd, nrmse

__all__ = [
    "WINTER_FOOT_AND_LEG",
    "CrossValidationResult",
    "ForceLengthResult",
    "GeometryResult",
    "IsometricFitResult",
    "PendulumResult",
    "RecruitmentCurrentResult",
    "RecruitmentPWResult",
    "SeriesStiffnessResult",
    "ShankAnthropometry",
    "StaticTorqueResult",
    "calcium_gain",
    "cross_validate",
    "geometry_from_height",
    "identify_force_length",
    "identify_isometric_transients",
    "identify_pendulum_linear",
    "identify_pendulum_nonlinear",
    "identify_recruitment_current",
    "identify_recruitment_pw",
    "identify_series_stiffness",
    "identify_static_torque",
    "shank_anthropometry",
]

F64 = NDArray[np.float64]


def _quality(measured: F64, predicted: F64) -> tuple[float, float]:
    return float(nrmsd(measured, predicted)), float(nrmse(measured, predicted))


def _fmt(v: Any) -> str:
    a = np.asarray(v, dtype=float)
    if a.ndim == 0:
        return f"{float(a):.4g}"
    return "[" + ", ".join(f"{x:.4g}" for x in a.ravel()[:8]) + (", …]" if a.size > 8 else "]")


@contextlib.contextmanager
def solver_step(step: str, who: str, **values: Any) -> Iterator[None]:
    """Turn a casadi/ipopt/scipy failure inside the block into :class:`IdentificationError`.

    The message names the identification ``step``, the leg or trial ``who`` and the offending
    ``values`` (start point, bounds, fixed parameters), plus the solver's first message line.
    ``RuntimeError`` is what casadi raises (assertions, NaN in a Function, ipopt exceptions);
    ``ValueError``/``LinAlgError`` are scipy's (non-finite residuals, infeasible start).
    """
    try:
        yield
    except (RuntimeError, ValueError, np.linalg.LinAlgError) as e:
        vals = ", ".join(f"{k} = {_fmt(v)}" for k, v in values.items())
        lines = [ln.strip() for ln in str(e).splitlines() if ln.strip()]
        why = lines[-1] if lines else type(e).__name__
        raise IdentificationError(f"{step} ({who}): solver failed with {vals}: {why}") from e


def _check_finite(step: str, who: str, **values: Any) -> None:
    bad = {k: v for k, v in values.items() if not np.all(np.isfinite(np.asarray(v, float)))}
    if bad:
        raise IdentificationError(
            f"{step} ({who}): non-finite result "
            + ", ".join(f"{k} = {_fmt(v)}" for k, v in bad.items())
        )


# --------------------------------------------------------------------------- geometry (1)
@dataclass(frozen=True)
class GeometryResult:
    """``L(θ) = L_ext + r_q θ`` fitted to polynomial lengths (columns ``knee_angle, L, L_fit``)."""

    L_ext: float
    r_q: float
    knee_angle: F64
    length: F64
    length_fit: F64
    nrmsd: float
    nrmse: float
    columns: tuple[str, ...] = ("knee_angle", "length", "length_fit")

    @property
    def geometry(self) -> GeometryParams:
        return GeometryParams(self.L_ext, self.r_q)


def geometry_from_height(
    height: float,
    *,
    poly: tuple[float, ...] = GEOMETRY_POLY_FROM_HEIGHT,
    shank_fraction: float = SHANK_LENGTH_FRACTION,
    n_angles: int = 10,
) -> GeometryResult:
    """Benoussaad et al. 2013, §2.3.1.1: ``L_ext``, ``r_q`` from stature only.

    Normalised lengths ``L/ℓ_s = Σ p_i θ^i`` at ``n_angles`` regularly spaced knee angles in
    [0°, 90°] times the shank length ``ℓ_s = shank_fraction · height``, then linear least
    squares on Eq. 5.  See :data:`~msk.fes.model.GEOMETRY_POLY_FROM_HEIGHT` for the polynomial.
    """
    if not 0.5 < height < 2.6:
        raise IdentificationError(f"geometry_from_height: height {height} m is not a stature")
    th = np.linspace(0.0, np.pi / 2, n_angles)
    length = np.asarray(shank_fraction * height * np.polyval(poly[::-1], th), dtype=np.float64)
    A = np.column_stack([np.ones_like(th), th])
    (l_ext, r_q), *_ = np.linalg.lstsq(A, length, rcond=None)
    fit = A @ np.array([l_ext, r_q])
    return GeometryResult(float(l_ext), float(r_q), th, length, fit, *_quality(length, fit))


# ---------------------------------------------------------------------- anthropometry (2)
#: Winter (2009) Table 4.1, "foot and leg": mass fraction of body mass, COM and radius of
#: gyration about the proximal (knee) joint as fractions of the leg length (knee–ankle), and
#: the leg length as a fraction of stature (Drillis & Contini 0.246 H).
WINTER_FOOT_AND_LEG = {"mass": 0.061, "com": 0.606, "rho_proximal": 0.735, "length": 0.246}


@dataclass(frozen=True)
class ShankAnthropometry:
    """Shank + foot from regression tables (the implanted-FES identification paper, §IV.A), SI
    units."""

    mass: float
    length: float
    L_og: float
    J: float

    @property
    def gravity_stiffness(self) -> float:
        """``M_s g L_og`` (N·m/rad): the gravity part of ``K_eq`` (the implanted-FES identification
        paper, Eq. 4)."""
        return self.mass * G * self.L_og


def shank_anthropometry(
    body_mass: float, height: float, *, table: dict[str, float] | None = None
) -> ShankAnthropometry:
    """Shank+foot mass, COM distance from the knee and inertia about the knee.

    The implanted-FES identification paper, §IV.A cites "regression equations [16]" without the
    table; its mass (4.026 kg for 66 kg) is exactly Winter's foot-and-leg fraction 0.061, which we
    use.  With Winter's COM (0.606) and proximal radius of gyration (0.735) and a 0.246 H leg length
    we get ``L_og`` = 0.261 m and ``J`` = 0.403 kg·m² for the implanted-FES identification paper's
    subject, against its reported
    0.194 m and 0.343 kg·m² (whose table we could not identify); pass ``table`` to use others.
    """
    t = WINTER_FOOT_AND_LEG if table is None else table
    if body_mass <= 0 or height <= 0:
        raise IdentificationError(f"shank_anthropometry: bad mass {body_mass} / height {height}")
    m = t["mass"] * body_mass
    ell = t["length"] * height
    return ShankAnthropometry(m, ell, t["com"] * ell, m * (t["rho_proximal"] * ell) ** 2)


# ------------------------------------------------------------------------ static torque (3)
@dataclass(frozen=True)
class StaticTorqueResult:
    """``T_s = K sin θ_r`` (Benoussaad et al. 2013, Eq. 7) fitted; columns ``theta_r, torque,
    torque_fit``."""

    K: float
    theta_r: F64
    torque: F64
    torque_fit: F64
    nrmsd: float
    nrmse: float
    columns: tuple[str, ...] = ("theta_r", "torque", "torque_fit")


def identify_static_torque(theta_r: ArrayLike, torque: ArrayLike) -> StaticTorqueResult:
    """Linear least squares ``K = Σ T sin θ_r / Σ sin² θ_r`` (Benoussaad et al. 2013, §2.3.1.2)."""
    th = np.asarray(theta_r, dtype=float)
    tq = np.asarray(torque, dtype=float)
    if th.shape != tq.shape or th.size < 2:
        raise MissingDataError(f"static torque: need >= 2 angle/torque pairs, got {th.shape}")
    s = np.sin(th)
    if np.sum(s**2) < 1e-8:
        raise IdentificationError("static torque: all angles at rest, K is not identifiable")
    k = float(s @ tq / (s @ s))
    fit = k * s
    return StaticTorqueResult(k, th, tq, fit, *_quality(tq, fit))


# ----------------------------------------------------------------------------- pendulum (4)
@dataclass(frozen=True)
class PendulumResult:
    """Passive pendulum: ``J``, ``B``, ``K_eq`` with ``ω_n``, ``ζ``; columns ``time, θ_r, fit``."""

    J: float
    B: float
    K_eq: float
    omega_n: float
    zeta: float
    time: F64
    theta_r: F64
    theta_r_fit: F64
    nrmsd: float
    nrmse: float
    method: str
    columns: tuple[str, ...] = ("time", "theta_r", "theta_r_fit")


def _damped(t: F64, a: float, sig: float, wd: float, phi: float, c: float) -> F64:
    return a * np.exp(-sig * t) * np.cos(wd * t + phi) + c


def identify_pendulum_linear(
    time: ArrayLike,
    theta_r: ArrayLike,
    *,
    K_eq: float | None = None,
    J: float | None = None,
) -> PendulumResult:
    """Free response of the linearised pendulum ``J γ̈ + B γ̇ + K_eq γ = 0`` (001 Eq. 4).

    ``θ_r(t) = A e^{−ζω_n t} cos(ω_d t + φ) + c`` is fitted by nonlinear least squares
    (started from the zero crossings and the logarithmic decrement), ``ω_n² = ω_d² + σ²``,
    ``ζ = σ/ω_n``.  Give exactly one of ``K_eq`` (Benoussaad et al. 2013: ``K`` from the static
    test, then ``J = K/ω_n²``) or ``J`` (the implanted-FES identification paper: anthropometric
    ``J``, then ``K_eq = ω_n² J``); ``B = 2 ζ ω_n J`` in both cases.  The sine is linearised: large
    drops bias ``ω_n`` (use :func:`identify_pendulum_nonlinear` to remove it).
    """
    t = np.asarray(time, dtype=float)
    y = np.asarray(theta_r, dtype=float)
    if (K_eq is None) == (J is None):
        raise IdentificationError("pendulum: give exactly one of K_eq or J")
    if t.shape != y.shape or t.size < 20:
        raise MissingDataError(f"pendulum: need >= 20 samples, got {t.shape} / {y.shape}")
    t = t - t[0]
    yc = y - np.median(y[-max(5, y.size // 10) :])
    zc = np.nonzero(np.diff(np.signbit(yc)))[0]
    if zc.size < 3:
        raise IdentificationError("pendulum: fewer than 3 zero crossings, no oscillation")
    period = 2 * np.mean(np.diff(t[zc]))
    wd0 = 2 * np.pi / period
    peaks = [np.max(np.abs(yc[zc[i] : zc[i + 1] + 1])) for i in range(min(zc.size - 1, 6))]
    dec = np.log(peaks[0] / peaks[-1]) / max(len(peaks) - 1, 1) if len(peaks) > 1 else 0.1
    sig0 = max(dec * 2 / period, 1e-3)
    p0 = [y[0] - np.median(y[-10:]), sig0, wd0, 0.0, np.median(y[-10:])]
    with solver_step("pendulum (linear)", "pendulum trial", start=p0):
        res = least_squares(lambda q: _damped(t, *q) - y, p0, method="lm")
    _check_finite("pendulum (linear)", "pendulum trial", fit=res.x)
    _a, sig, wd, _phi, _c = res.x
    wn = float(np.hypot(wd, sig))
    zeta = float(abs(sig) / wn)
    if J is None:
        assert K_eq is not None
        J = K_eq / wn**2
    else:
        K_eq = wn**2 * J
    B = 2 * zeta * wn * J
    fit = _damped(t, *res.x)
    return PendulumResult(
        float(J), float(B), float(K_eq), wn, zeta, t, y, fit, *_quality(y, fit), "linear"
    )


@functools.lru_cache(maxsize=16)
def _passive_sim(n: int, dt: float) -> ca.Function:
    """``θ_r`` trajectory of ``J θ̈ + B θ̇ + K sin θ + K_e θ = 0`` by RK4 and its Jacobian."""
    x = ca.SX.sym("x", 2)
    q = ca.SX.sym("q", 4)  # J, B, K, K_e

    def f(x: ca.SX) -> ca.SX:
        return ca.vertcat(x[1], -(q[1] * x[1] + q[2] * ca.sin(x[0]) + q[3] * x[0]) / q[0])

    k1 = f(x)
    k2 = f(x + dt / 2 * k1)
    k3 = f(x + dt / 2 * k2)
    k4 = f(x + dt * k3)
    step = ca.Function("pstep", [x, q], [x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)])
    sim = step.mapaccum("psim", n - 1)
    x0 = ca.MX.sym("x0", 2)
    qq = ca.MX.sym("q", 4)
    th = ca.horzcat(x0[0], sim(x0, qq)[0, :]).T
    z = ca.vertcat(x0, qq)
    return ca.Function("passive", [z], [th, ca.jacobian(th, z)])


def identify_pendulum_nonlinear(
    time: ArrayLike,
    theta_r: ArrayLike,
    *,
    K: float,
    K_e: float = 0.0,
    J: float | None = None,
    init: PendulumResult | None = None,
    dt: float = DT,
) -> PendulumResult:
    """Direct fit of ``J θ̈_r + B θ̇_r + K sin θ_r + K_e θ_r = 0`` (Benoussaad et al. 2013, Eq.
    6–7).

    Free parameters: ``B``, the release angle and velocity, and ``J`` (when ``J`` is None,
    Benoussaad et al. 2013) or ``K_e`` (when ``J`` is given, the implanted-FES identification paper:
    the elastic part of ``K_eq``). Gauss–Newton (scipy ``least_squares``) with the exact
    sensitivities of the casadi RK4 simulation; the measured series is resampled on the ``dt`` grid.
    """
    t = np.asarray(time, dtype=float)
    y = np.asarray(theta_r, dtype=float)
    if t.shape != y.shape or t.size < 20:
        raise MissingDataError(f"pendulum: need >= 20 samples, got {t.shape} / {y.shape}")
    t = t - t[0]
    n = int(np.floor(t[-1] / dt + 1e-9)) + 1
    tg = np.arange(n) * dt
    yg = np.interp(tg, t, y)
    if init is None:
        init = identify_pendulum_linear(t, y, K_eq=K + K_e) if J is None else None
        if init is None:
            init = identify_pendulum_linear(t, y, J=J)
    fun = _passive_sim(n, dt)
    om0 = (yg[2] - yg[0]) / (2 * dt)
    fit_j = J is None
    z0 = [yg[0], om0, init.J if fit_j else init.K_eq - K, init.B]

    def full(z: F64) -> F64:
        jj, ke = (z[2], K_e) if fit_j else (J, z[2])
        return np.array([z[0], z[1], jj, z[3], K, ke])

    def resid(z: F64) -> F64:
        return np.asarray(fun(full(z))[0]).ravel() - yg

    def jac(z: F64) -> F64:
        jf = np.asarray(fun(full(z))[1])
        return np.column_stack([jf[:, 0], jf[:, 1], jf[:, 2] if fit_j else jf[:, 5], jf[:, 3]])

    with solver_step("pendulum (nonlinear)", "pendulum trial", start=z0, K=K, K_e=K_e):
        res = least_squares(resid, z0, jac=jac, x_scale=np.abs(np.array(z0)) + 1e-3)
    _check_finite("pendulum (nonlinear)", "pendulum trial", fit=res.x)
    z = res.x
    j_hat = float(z[2]) if fit_j else float(J)  # type: ignore[arg-type]
    ke_hat = K_e if fit_j else float(z[2])
    k_eq = K + ke_hat
    b_hat = float(z[3])
    fitted = np.interp(t, tg, resid(z) + yg)
    wn = float(np.sqrt(k_eq / j_hat))
    return PendulumResult(
        j_hat,
        b_hat,
        k_eq,
        wn,
        b_hat / (2 * np.sqrt(k_eq * j_hat)),
        t,
        y,
        fitted,
        *_quality(y, fitted),
        "nonlinear",
    )


# ------------------------------------------------------------------------ force–length (5)
@dataclass(frozen=True)
class ForceLengthResult:
    """``Fl(ε_c) = exp(−(ε_c/b)²)`` (Benoussaad et al. 2013, Eq. 2) fitted, with normalised
    forces."""

    b: float
    L_c0: float
    L_s: float
    F_peak: float
    knee_angle: F64
    force_norm: F64
    force_norm_fit: F64
    nrmsd: float
    nrmse: float
    columns: tuple[str, ...] = ("knee_angle", "force_norm", "force_norm_fit")


def identify_force_length(
    knee_angle: ArrayLike,
    force: ArrayLike,
    *,
    geometry: GeometryParams,
    fibre_fraction: float,
    k_s: float = np.inf,
) -> ForceLengthResult:
    """``b``, ``L_c0`` by linear least squares on the logarithm of Eq. 2 (Benoussaad et al. 2013,
    §2.3.1.3).

    With ``x = L(θ) − F/k_s = L_c + L_s`` (the CE length plus the constant slack length; the
    seed takes ``k_s = ∞``, "SE highly stiff", which is the default), ``ln F = a0 + a1 x +
    a2 x²`` is linear in ``a``; the optimum ``L_c0 + L_s = −a1/(2 a2)`` and the width
    ``b L_c0 = 1/√(−a2)``.  The split between ``L_c0`` and ``L_s`` is the muscle/tendon
    proportion at the optimum (the seed's ref. [10]): ``L_c0 = fibre_fraction (L_c0 + L_s)``.
    Passing the current ``k_s`` estimate removes the series-element elongation bias (the
    protocol iterates this step after the NLP of Eq. 8).  ``F_peak`` is the model's optimum
    force ``exp(a0 − a1²/(4 a2))``; NRMSD/NRMSE are on forces normalised by the largest one.
    """
    th = np.asarray(knee_angle, dtype=float)
    f = np.asarray(force, dtype=float)
    if th.shape != f.shape or th.size < 3:
        raise MissingDataError(f"force–length: need >= 3 isometric angles, got {th.shape}")
    if np.any(f <= 0):
        bad = th[f <= 0]
        raise IdentificationError(
            f"force–length: non-positive force at knee angle(s) {np.rad2deg(bad)} deg"
        )
    x = geometry.L_ext + geometry.r_q * th - (0.0 if np.isinf(k_s) else f / k_s)
    xm = x.mean()
    A = np.column_stack([np.ones_like(x), x - xm, (x - xm) ** 2])
    a0, a1, a2 = np.linalg.lstsq(A, np.log(f), rcond=None)[0]
    if a2 >= 0:
        raise IdentificationError(
            f"force–length: log-force is not concave over the angles (a2 = {a2:.3g}); no optimum"
        )
    opt = xm - a1 / (2 * a2)
    width = 1.0 / np.sqrt(-a2)
    l_c0 = fibre_fraction * opt
    l_s = opt - l_c0
    b = width / l_c0
    peak = float(np.exp(a0 - a1**2 / (4 * a2)))
    fn = f / f.max()
    fit = np.exp(a0 + a1 * (x - xm) + a2 * (x - xm) ** 2) / f.max()
    return ForceLengthResult(
        float(b), float(l_c0), float(l_s), peak, th, fn, fit, *_quality(fn, fit)
    )


def force_length_factor(
    subject: FesSubject, knee_angle: ArrayLike, force: ArrayLike
) -> NDArray[np.float64]:
    """``Fl(ε_c)`` at steady isometric force ``F`` (``L_c = L(θ) − L_s − F/k_s``)."""
    m, g = subject.muscle, subject.geometry
    lc = g.L_ext + g.r_q * np.asarray(knee_angle, float) - m.L_s - np.asarray(force) / m.k_s
    return np.exp(-(((lc - m.L_c0) / m.L_c0 / m.b) ** 2))


def calcium_gain(calcium: CalciumParams, frequency_hz: float) -> float:
    """Steady isometric force per ``α F_cm Fl`` at ``frequency_hz``: ``κ = ⟨y⟩``.

    ``y`` is the periodic solution of ``ẏ = −u(t) y + Π_c(t) U_c`` (Benoussaad et al. 2013, Eq. 1
    with ``ε̇_c = 0``, Eq. 11–12); ``κ`` = 0.921 at 20 Hz with the seed's calcium constants and
    1 for a fused tetanus (``Π_c ≡ 1``).
    """
    period = 1.0 / frequency_hz
    n = 2000
    tt = np.arange(n) * period / n
    pi = calcium_pi(tt, np.array([0.0]), calcium.tau_c, calcium.tau_r, left=False)
    if calcium.tau_c >= period:
        pi = np.ones(n)
    u = pi * calcium.U_c + (1 - pi) * calcium.U_r
    h = period / n
    y = 1.0
    for _ in range(60):  # periods to converge
        ys = np.empty(n)
        for k in range(n):
            ys[k] = y
            y = (y + h * pi[k] * calcium.U_c) / (1 + h * u[k])
    return float(ys.mean())


# ------------------------------------------------------------------------- recruitment (6)
@dataclass(frozen=True)
class RecruitmentPWResult:
    """Eq. 10 fitted; ``F_cm``, ``K_cm`` deduced; columns ``pw, alpha, alpha_fit``."""

    c1: float
    c2: float
    c3: float
    F_cm: float
    K_cm: float
    pw: F64
    alpha: F64
    alpha_fit: F64
    nrmsd: float
    nrmse: float
    columns: tuple[str, ...] = ("pw", "alpha", "alpha_fit")

    @property
    def recruitment(self) -> RecruitmentPW:
        return RecruitmentPW(self.c1, self.c2, self.c3)


def identify_recruitment_pw(
    pw: ArrayLike,
    force: ArrayLike,
    *,
    knee_angle: float,
    subject: FesSubject,
    frequency_hz: float = 20.0,
    stiffness_ratio: float = 900.0,
    pw_max: float = 420e-6,
) -> RecruitmentPWResult:
    """``c1, c2, c3`` by nonlinear least squares (Benoussaad et al. 2013, §2.3.1.4), then ``F_cm``,
    ``K_cm``.

    ``α_i = (F_i / Fl_i) / (F_max / Fl_max)``: steady isometric forces at the test angle
    normalised by the one at ``PW_max`` as in the seed, each first divided by its force–length
    factor ``Fl(ε_c)`` (with ``L_c = L − L_s − F/k_s`` from ``subject``'s current ``b``,
    ``L_c0``, ``L_s``, ``k_s``; the seed neglects this, exact only for a rigid tendon).  Only
    the product ``c1 F_cm`` is identifiable: the normalisation fixes ``α(PW_max) ≈ 1``.  The
    The Table 3 sets of Benoussaad et al. 2013 do not all satisfy it (their ``α(PW_max)`` spans 0.87
    (S5L) to 1.03 (S9L)), so for such a leg ``c1`` and ``F_cm`` differ from the published ones by
    that factor while ``F_cm α(PW_max)`` is recovered.  ``F_cm = F_max / (κ Fl_max α̂(PW_max))``
    with ``κ`` = :func:`calcium_gain`; ``K_cm = stiffness_ratio · F_cm`` ("proportional to
    F_cm according to the physiological model", ratio in 1/m).
    """
    p = np.asarray(pw, dtype=float)
    f = np.asarray(force, dtype=float)
    if p.shape != f.shape or p.size < 4:
        raise MissingDataError(f"recruitment: need >= 4 trains, got {p.shape}")
    fl = force_length_factor(subject, np.full_like(f, knee_angle), np.maximum(f, 0.0))
    g = f / fl
    imax = int(np.argmax(p))
    if g[imax] <= 0:
        raise IdentificationError(f"recruitment: no force at PW_max = {p[imax] * 1e6:.0f} us")
    alpha = g / g[imax]
    # PW = 0 is no pulse (zero force) while Eq. 10 gives α(0) = c1/(1 + e^{c2 c3}) > 0: such
    # trains carry no information on the sigmoid and are left out of the fit.
    on = p > 0
    p, alpha, f, fl = p[on], alpha[on], f[on], fl[on]
    imax = int(np.argmax(p))
    x = p / pw_max
    if fl[imax] < 0.05:
        m = subject.muscle
        raise IdentificationError(
            f"recruitment (PW) ({subject.name}): force–length factor {fl[imax]:.3g} at the test "
            f"angle {np.rad2deg(knee_angle):.0f} deg and PW_max (b = {m.b:.4g}, L_c0 = "
            f"{m.L_c0:.4g} m, L_s = {m.L_s:.4g} m, k_s = {m.k_s:.4g} N/m): F_cm would be "
            f"{f[imax] / max(fl[imax], 1e-300):.4g} N"
        )

    def model(c: F64) -> F64:
        return c[0] / (1 + np.exp(c[1] * (c[2] - x)))

    with solver_step("recruitment (PW)", subject.name, pw=p, alpha=alpha):
        res = least_squares(
            lambda c: model(c) - alpha,
            [1.0, 6.0, 0.5],
            bounds=([0.1, 0.1, -1.0], [5.0, 100.0, 2.0]),
        )
    c1, c2, c3 = (float(v) for v in res.x)
    fit = model(res.x)
    a_max = c1 / (1 + np.exp(c2 * (c3 - p[imax] / pw_max)))
    kappa = calcium_gain(subject.calcium, frequency_hz)
    f_cm = float(f[imax] / (kappa * fl[imax] * a_max))
    return RecruitmentPWResult(
        c1, c2, c3, f_cm, stiffness_ratio * f_cm, p, alpha, fit, *_quality(alpha, fit)
    )


# ------------------------------------------- isometric transients (refinement of 5 and 6)
@dataclass(frozen=True)
class IsometricFitResult:
    """Force–length and recruitment refitted on the isometric torque *time courses*.

    ``torque`` and ``torque_fit`` are ``(n_samples, n_trials)`` on ``time`` (s, axis 0).
    """

    F_cm: float
    K_cm: float
    b: float
    L_c0: float
    L_s: float
    c1: float
    c2: float
    c3: float
    time: F64
    torque: F64
    torque_fit: F64
    nrmsd: float
    nrmse: float
    columns: tuple[str, ...] = ("time", "torque", "torque_fit")

    @property
    def recruitment(self) -> RecruitmentPW:
        return RecruitmentPW(self.c1, self.c2, self.c3)


_ISO_FREE = ("F_cm", "b", "L_c0", "rec1", "rec2")


@functools.lru_cache(maxsize=8)
def _iso_fit_function(n: int, dt: float, n_trials: int, ce: str = "000") -> ca.Function:
    step = step_function("pw", True, dt, "rk4", ce)
    sim = step.mapaccum("iso", n)
    x0 = ca.MX.sym("x0", 4)
    w = ca.MX.sym("w", 4, n)
    p = ca.MX.sym("p", len(PARAM_NAMES))
    q = ca.MX.sym("q", len(_ISO_FREE))
    c = ca.MX.sym("c", 2)  # stiffness ratio K_cm/F_cm (1/m), fibre fraction
    tied = {
        "K_cm": c[0] * q[0],
        "L_s": q[2] * (1 - c[1]) / c[1],
    }
    p_full = ca.vertcat(
        *[
            q[_ISO_FREE.index(nm)] if nm in _ISO_FREE else tied.get(nm, p[i])
            for i, nm in enumerate(PARAM_NAMES)
        ]
    )
    r_q = p[PARAM_NAMES.index("r_q")]
    torque = r_q * ca.horzcat(x0[3], sim(x0, w, p_full)[3, :]).T
    one = ca.Function("iso_one", [x0, w, p, q, c], [torque])
    many = one.map(n_trials, "serial")
    X0 = ca.MX.sym("X0", 4, n_trials)
    W = ca.MX.sym("W", 4, n * n_trials)
    out = ca.vec(many(X0, W, p, q, c))
    return ca.Function("iso_fit", [X0, W, p, q, c], [out, ca.jacobian(out, q)])


def identify_isometric_transients(
    trials: Sequence[Any],
    subject: FesSubject,
    *,
    fibre_fraction: float,
    stiffness_ratio: float,
    dt: float = DT,
) -> IsometricFitResult:
    """Refit ``F_cm, b, L_c0, c2, c3`` on the isometric torque *time courses* (model in the loop).

    Our addition to Benoussaad et al. 2013, §2.3.1.3–4: with Table 3's ``K_cm/k_s`` the model's
    isometric force rises at ≈ ``u k_s/(k_s + K_c)`` (time constants up to 1.3 s), so the seed's 1.5
    s trains never reach the steady state its steps assume.  Every trial (``knee_angle``,
    ``stim``, ``time``, ``torque`` from rest; e.g. :class:`msk.fes.protocol.IsometricTrial`) is
    simulated with the current ``k_s`` (``K_cm = stiffness_ratio F_cm``, ``L_s`` from the
    fibre fraction) and the torque errors are minimised by Gauss–Newton with exact casadi
    sensitivities, starting from ``subject``.  ``c1`` stays fixed (only ``c1 F_cm`` is
    identifiable) and is renormalised to ``α(PW_max) = 1`` at the end.
    """
    if len(trials) == 0:
        raise MissingDataError("isometric transients: no trials")
    durations = {round(float(tr.time[-1] - tr.time[0]), 6) for tr in trials}
    if len(durations) != 1:
        raise IdentificationError(f"isometric transients: trials differ in length {durations}")
    n = int(np.floor(durations.pop() / dt + 1e-9))
    cal = subject.calcium
    X0 = np.zeros((4, len(trials)))
    X0[0] = [subject.knee.theta_rest - tr.knee_angle for tr in trials]
    W = np.hstack([sample_on_grid(tr.stim, n, dt, cal.tau_c, cal.tau_r) for tr in trials])
    Y = np.column_stack([_grid_measure(tr.time, tr.torque, n, dt)[1] for tr in trials])
    fun = _iso_fit_function(n, dt, len(trials), subject.contractile)
    p = param_vector(subject)
    rec = subject.recruitment
    if not isinstance(rec, RecruitmentPW):
        raise IdentificationError(f"{subject.name}: isometric transients need PW recruitment")
    m = subject.muscle
    q0 = np.array([m.F_cm, m.b, m.L_c0, rec.c2, rec.c3])
    c = np.array([stiffness_ratio, fibre_fraction])
    y = Y.T.ravel()

    def resid(q: F64) -> F64:
        return np.asarray(fun(X0, W, p, q, c)[0]).ravel() - y

    def jac(q: F64) -> F64:
        return np.asarray(fun(X0, W, p, q, c)[1])

    lb = np.array([1.0, 0.05, 0.2 * m.L_c0, 0.1, -1.0])
    ub = np.array([1e5, 3.0, 5.0 * m.L_c0, 100.0, 2.0])
    who = f"{subject.name}, {len(trials)} isometric trials"
    if not np.all(np.isfinite(q0)) or np.any(q0[:3] <= 0):
        raise IdentificationError(
            f"isometric transients ({who}): bad start F_cm, b, L_c0, c2, c3 = {_fmt(q0)}"
        )
    with solver_step("isometric transients", who, start=q0, lower=lb, upper=ub):
        res = least_squares(resid, np.clip(q0, lb, ub), jac=jac, bounds=(lb, ub), x_scale=q0)
    _check_finite("isometric transients", who, fit=res.x)
    f_cm, b, l_c0, c2, c3 = (float(v) for v in res.x)
    a_max = float(rec.c1 / (1 + np.exp(c2 * (c3 - 1.0))))
    fit = (res.fun + y).reshape(len(trials), n + 1).T
    tg = np.arange(n + 1, dtype=np.float64) * dt
    q_nrmsd, q_nrmse = _quality(Y.ravel(), fit.ravel())
    return IsometricFitResult(
        F_cm=f_cm * a_max,
        K_cm=stiffness_ratio * f_cm * a_max,
        b=b,
        L_c0=l_c0,
        L_s=l_c0 * (1 - fibre_fraction) / fibre_fraction,
        c1=rec.c1 / a_max,
        c2=c2,
        c3=c3,
        time=tg,
        torque=Y,
        torque_fit=fit,
        nrmsd=q_nrmsd,
        nrmse=q_nrmse,
    )


# --------------------------------------------- model-in-the-loop fits (recruitment I, k_s)
def _grid_measure(time: F64, theta_r: F64, n: int, dt: float) -> tuple[F64, F64]:
    tg = np.arange(n + 1, dtype=np.float64) * dt
    return tg, np.interp(tg, time - time[0], theta_r)


@functools.lru_cache(maxsize=16)
def _traj_with_jac(
    kind: str, n: int, dt: float, free: tuple[str, ...], ce: str = "000"
) -> ca.Function:
    step = step_function(kind, False, dt, "rk4", ce)
    sim = step.mapaccum("sim", n)
    x0 = ca.MX.sym("x0", 4)
    w = ca.MX.sym("w", 4, n)
    p = ca.MX.sym("p", len(PARAM_NAMES))
    q = ca.MX.sym("q", len(free))
    p_full = ca.vertcat(
        *[q[free.index(n)] if n in free else p[i] for i, n in enumerate(PARAM_NAMES)]
    )
    th = ca.horzcat(x0[0], sim(x0, w, p_full)[0, :]).T
    return ca.Function("traj", [x0, w, p, q], [th, ca.jacobian(th, q)])


#: Box on (a_I, B_r [1/mA], C_r, D_r) for the fit of the implanted-FES identification paper: D_r and
#: C_r trade off (for C_r ≪ 0 the tanh pair is nearly exponential) and would otherwise drift without
#: changing α(I) much.
_REC_I_LB = np.array([-0.9, 0.01, -3.0, 0.1])
_REC_I_UB = np.array([2.0, 5.0, 3.0, 20.0])


@dataclass(frozen=True)
class RecruitmentCurrentResult:
    """The implanted-FES identification paper, Eq. 7 identified from dynamic data; columns ``time,
    theta_r, theta_r_fit``."""

    a_I: float
    B_r: float
    C_r: float
    D_r: float
    time: F64
    theta_r: F64
    theta_r_fit: F64
    nrmsd: float
    nrmse: float
    columns: tuple[str, ...] = ("time", "theta_r", "theta_r_fit")

    @property
    def recruitment(self) -> RecruitmentCurrent:
        return RecruitmentCurrent(self.a_I, self.B_r, self.C_r, self.D_r)


def identify_recruitment_current(
    time: ArrayLike,
    theta_r: ArrayLike,
    stim: Stimulation,
    subject: FesSubject,
    *,
    init: RecruitmentCurrent | None = None,
    dt: float = DT,
    max_nfev: int = 100,
) -> RecruitmentCurrentResult:
    """``a_I, B_r, C_r, D_r`` minimising the angle errors of the simulated model (001 Fig. 5).

    Nonlinear least squares (scipy trust-region reflective) with the exact sensitivities of the
    casadi RK4 trajectory; the shank starts at rest, relaxed.
    """
    t = np.asarray(time, dtype=float)
    y = np.asarray(theta_r, dtype=float)
    n = int(np.floor((t[-1] - t[0]) / dt + 1e-9))
    tg, yg = _grid_measure(t, y, n, dt)
    s0 = subject.with_recruitment(init or subject.recruitment)
    if not isinstance(s0.recruitment, RecruitmentCurrent):
        raise IdentificationError(f"{subject.name}: current recruitment needs a current model")
    w = sample_on_grid(stim, n, dt, s0.calcium.tau_c, s0.calcium.tau_r)
    free = ("rec0", "rec1", "rec2", "rec3")
    fun = _traj_with_jac("current", n, dt, free, s0.contractile)
    p = param_vector(s0)
    idx = [PARAM_NAMES.index(k) for k in free]
    x0 = np.zeros(4)

    def resid(q: F64) -> F64:
        return np.asarray(fun(x0, w, p, q)[0]).ravel() - yg

    def jac(q: F64) -> F64:
        return np.asarray(fun(x0, w, p, q)[1])

    q0 = np.clip(p[idx], _REC_I_LB + 1e-6, _REC_I_UB - 1e-6)
    with solver_step("recruitment (current)", subject.name, start=q0):
        res = least_squares(
            resid,
            q0,
            jac=jac,
            bounds=(_REC_I_LB, _REC_I_UB),
            x_scale=np.abs(q0) + 0.1,
            max_nfev=max_nfev,
        )
    _check_finite("recruitment (current)", subject.name, fit=res.x)
    q = res.x
    fit = np.interp(t - t[0], tg, resid(q) + yg)
    a_i, b_r, c_r, d_r = (float(v) for v in q)
    return RecruitmentCurrentResult(a_i, b_r, c_r, d_r, t, y, fit, *_quality(y, fit))


@dataclass(frozen=True)
class SeriesStiffnessResult:
    """``k_s`` (N/m) by the NLP of Benoussaad et al. 2013, Eq. 8; columns ``time, theta_r,
    theta_r_fit``."""

    k_s: float
    k_s_initial: float
    time: F64
    theta_r: F64
    theta_r_fit: F64
    theta_r_initial: F64
    nrmsd: float
    nrmse: float
    nrmsd_initial: float
    solver_status: str
    iterations: int
    columns: tuple[str, ...] = ("time", "theta_r", "theta_r_fit", "theta_r_initial")
    #: ``K_cm`` (N/m) of the fit: the subject's unless ``free_K_cm`` identified it jointly
    K_cm: float = float("nan")


#: ipopt return statuses whose point is kept (the others raise :class:`IdentificationError`);
#: ``solver_status`` of the result tells which one it was.
_IPOPT_USABLE = frozenset(
    {
        "Solve_Succeeded",
        "Solved_To_Acceptable_Level",
        "Maximum_Iterations_Exceeded",
        "Search_Direction_Becomes_Too_Small",
        "Feasible_Point_Found",
    }
)


@functools.lru_cache(maxsize=8)
def _ks_nlp(
    n_int: int, m: int, dt: float, kind: str, free_K_cm: bool = False, ce: str = "000"
) -> tuple[ca.Function, dict[str, int]]:
    """Multiple-shooting NLP of Eq. 8: nodes every ``m`` steps, ``k_s`` in N/mm (and, with
    ``free_K_cm``, a factor on ``K_cm`` as the second decision variable)."""
    step = step_function(kind, False, dt, "rk4", ce)
    interval = step.mapaccum("interval", m).expand()  # SX: fast exact Hessians
    many = interval.map(n_int, "serial")
    npar = len(PARAM_NAMES)
    ks = ca.MX.sym("ks_mm")
    kf = ca.MX.sym("kcm_factor", 1 if free_K_cm else 0)
    X = ca.MX.sym("X", 4, n_int + 1)  # scaled node states
    scale = ca.MX.sym("scale", 4)
    W = ca.MX.sym("W", 4, n_int * m)
    P = ca.MX.sym("P", npar)
    Y = ca.MX.sym("Y", 1, n_int * m)  # measured θ_r at the end of every step
    x0 = ca.MX.sym("x0", 4)
    k_idx = PARAM_NAMES.index("k_s")
    c_idx = PARAM_NAMES.index("K_cm")
    assert c_idx == k_idx - 1
    kcm = kf * P[c_idx] if free_K_cm else P[c_idx]
    p_full = ca.vertcat(P[:c_idx], kcm, 1e3 * ks, P[k_idx + 1 :])
    Xu = X * ca.repmat(scale, 1, n_int + 1)
    traj = many(Xu[:, :n_int], W, p_full)  # interval i reads columns i m … (i+1) m − 1
    ends = traj[:, m - 1 :: m]
    gaps = (ends - Xu[:, 1:]) / ca.repmat(scale, 1, n_int)
    err = traj[0, :] - Y
    obj = ca.sumsqr(err) * dt
    g = ca.vertcat(ca.vec(gaps), (Xu[:, 0] - x0) / scale)
    z = ca.vertcat(ks, kf, ca.vec(X))
    prm = ca.vertcat(ca.vec(W), P, ca.vec(Y), x0, scale)
    nlp = {"x": z, "f": obj, "g": g, "p": prm}
    opts = {
        "ipopt.print_level": 0,
        "print_time": False,
        "ipopt.tol": 1e-10,
        "ipopt.max_iter": 200,
    }
    solver = ca.nlpsol("ks_nlp", "ipopt", nlp, opts)
    return solver, {"n_g": int(g.numel()), "n_z": int(z.numel())}


def identify_series_stiffness(
    time: ArrayLike,
    theta_r: ArrayLike,
    stim: Stimulation,
    subject: FesSubject,
    *,
    k_s0: float | None = None,
    k_s_bounds: tuple[float, float] | None = None,
    interval_steps: int = 25,
    dt: float = DT,
    free_K_cm: bool = False,
    K_cm_factor_bounds: tuple[float, float] = (0.1, 10.0),
) -> SeriesStiffnessResult:
    """``min_{k_s} ∫ (θ_r − θ_s)² dt  s.t. k_s > 0`` (Benoussaad et al. 2013, Eq. 8) with casadi +
    ipopt.

    Direct multiple shooting: the state ``(θ_r, θ̇_r, K_c, F_c)`` is a decision variable every
    ``interval_steps`` RK4 steps (50 ms), continuity and the initial rest state are equality
    constraints, and the integral is the sum over every 2 ms sample; ``k_s`` is scaled in N/mm
    and boxed in ``k_s_bounds`` (N/m; Eq. 8's ``k_s > 0`` made strict: by default
    :func:`~msk.fes.priors.k_s_lower_bound` — the series element may stretch at ``F_cm`` by up
    to twice the largest elongation in Table 3, 2 × 2.76 ``L_c0`` — and 10⁶ N/m).
    The node states are initialised from a simulation at ``k_s0`` (the seed initialises from
    the literature).  All other parameters are those of ``subject`` (initial phase).
    """
    t = np.asarray(time, dtype=float)
    y = np.asarray(theta_r, dtype=float)
    k0 = float(subject.muscle.k_s if k_s0 is None else k_s0)
    s0 = subject.with_muscle(k_s=k0)
    kind = "current" if isinstance(subject.recruitment, RecruitmentCurrent) else "pw"
    n_total = int(np.floor((t[-1] - t[0]) / dt + 1e-9))
    m = interval_steps
    n_int = n_total // m
    n = n_int * m
    if n_int < 2:
        raise MissingDataError(f"k_s NLP: trial of {t[-1] - t[0]:.3f} s is too short")
    tg, yg = _grid_measure(t, y, n, dt)
    w = sample_on_grid(stim, n, dt, s0.calcium.tau_c, s0.calcium.tau_r)
    init = simulate(s0, stim, duration=n * dt, dt=dt)
    scale = np.array([1.0, 5.0, max(s0.muscle.K_cm, 1.0), max(s0.muscle.F_cm, 1.0)])
    xnodes = init.states[::m][: n_int + 1].T / scale[:, None]
    solver, dims = _ks_nlp(n_int, m, dt, kind, free_K_cm, s0.contractile)
    p = param_vector(s0)
    prm = np.concatenate([w.T.ravel(), p, yg[1:], np.zeros(4), scale])
    nf = 1 if free_K_cm else 0
    z0 = np.concatenate([[k0 / 1e3], np.ones(nf), xnodes.T.ravel()])
    lbx = np.full(dims["n_z"], -np.inf)
    ubx = np.full(dims["n_z"], np.inf)
    m0 = s0.muscle
    if k_s_bounds is None:
        k_s_bounds = (k_s_lower_bound(m0.F_cm, m0.L_c0), 1e6)
    step, who = "k_s NLP (Benoussaad et al. 2013 Eq. 8)", f"{subject.name}, dynamic trial"
    if not (0 < k_s_bounds[0] < k_s_bounds[1]) or not np.isfinite(k_s_bounds[0]):
        raise IdentificationError(
            f"{step} ({who}): empty k_s box [{k_s_bounds[0]:.4g}, {k_s_bounds[1]:.4g}] N/m "
            f"(F_cm = {m0.F_cm:.4g} N, L_c0 = {m0.L_c0:.4g} m from the previous steps)"
        )
    _check_finite(step, who, initial_states=xnodes)
    lbx[0], ubx[0] = k_s_bounds[0] / 1e3, k_s_bounds[1] / 1e3
    z0[0] = float(np.clip(z0[0], lbx[0], ubx[0]))
    if free_K_cm:
        lbx[1], ubx[1] = K_cm_factor_bounds
    values = {
        "k_s0": k0,
        "k_s_box": np.array(k_s_bounds),
        "F_cm": m0.F_cm,
        "K_cm": m0.K_cm,
        "L_c0": m0.L_c0,
        "b": m0.b,
    }
    with solver_step(step, who, **values):
        sol = solver(x0=z0, p=prm, lbx=lbx, ubx=ubx, lbg=0, ubg=0)
    stats = solver.stats()
    k_hat = float(sol["x"][0]) * 1e3
    kcm_hat = float(sol["x"][1]) * m0.K_cm if free_K_cm else m0.K_cm
    status = str(stats.get("return_status", ""))
    if status not in _IPOPT_USABLE or not np.isfinite(k_hat):
        vals = ", ".join(f"{k} = {_fmt(v)}" for k, v in values.items())
        raise IdentificationError(
            f"{step} ({who}): ipopt returned {status} (k_s = {k_hat:.4g} N/m) with {vals}"
        )
    final = simulate(s0.with_muscle(k_s=k_hat, K_cm=kcm_hat), stim, duration=n * dt, dt=dt)
    fit = np.interp(t - t[0], tg, final.theta_r)
    fit0 = np.interp(t - t[0], tg, init.theta_r)
    return SeriesStiffnessResult(
        k_s=k_hat,
        k_s_initial=k0,
        time=t,
        theta_r=y,
        theta_r_fit=fit,
        theta_r_initial=fit0,
        nrmsd=float(nrmsd(y, fit)),
        nrmse=float(nrmse(y, fit)),
        nrmsd_initial=float(nrmsd(y, fit0)),
        solver_status=status,
        iterations=int(stats.get("iter_count", -1)),
        K_cm=kcm_hat,
    )


# --------------------------------------------------------------------- cross-validation (8)
@dataclass(frozen=True)
class CrossValidationResult:
    """Prediction of an unseen stimulation; columns ``time, theta_r, theta_r_sim``."""

    time: F64
    theta_r: F64
    theta_r_sim: F64
    nrmsd: float
    nrmse: float
    columns: tuple[str, ...] = ("time", "theta_r", "theta_r_sim")


def cross_validate(
    time: ArrayLike, theta_r: ArrayLike, stim: Stimulation, subject: FesSubject, *, dt: float = DT
) -> CrossValidationResult:
    """Simulate ``subject`` under ``stim`` from rest and compare with the measured ``θ_r``."""
    t = np.asarray(time, dtype=float)
    y = np.asarray(theta_r, dtype=float)
    tr = simulate(subject, stim, duration=float(t[-1] - t[0]) + dt, dt=dt)
    sim = np.interp(t - t[0], tr.time, tr.theta_r)
    return CrossValidationResult(t, y, sim, *_quality(y, sim))
