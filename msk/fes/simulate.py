"""Simulation of the quadriceps–shank model with casadi.

The right-hand side (Benoussaad et al. 2013, Eq. 1–7, 10–12, see :mod:`msk.fes.model`) is one casadi
function of the state ``x = (θ_r, θ̇_r, K_c, F_c)``, the step input ``w = (level, Π_c(t_k),
Π_c(t_k + h/2), Π_c(t_k + h))`` and the parameter vector (:data:`~msk.fes.model.PARAM_NAMES`).

Two integrators are offered:

* ``"rk4"`` (default): a fixed-step classical Runge–Kutta scheme on the stimulation grid (``h`` =
  2 ms: 30 ms / 20 ms calcium phases and 50 ms or 32 ms pulse periods fall on the grid, so the
  piecewise-linear ``Π_c`` is sampled exactly by the stages).  The system is not stiff for the
  seed's parameter ranges (fastest rates: ``U_c + |ε̇_c|`` ≈ 30–60 s⁻¹ and the shank–tendon
  mode ``√(k_s r_q²/J)`` ≈ 10–30 rad/s, both ``≪ 2.8/h``); the whole trajectory is one
  ``mapaccum`` casadi function, differentiable for the identification NLPs.
* ``"cvodes"``: SUNDIALS' BDF integrator (stiff-capable, adaptive) over each grid step with the
  same linear interpolation of ``Π_c``: the reference the RK4 scheme is tested against.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Literal

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from msk.exceptions import ModelError
from msk.fes.model import PARAM_NAMES, FesSubject, RecruitmentCurrent, param_vector
from msk.fes.stimulation import Stimulation, sample_on_grid

__all__ = [
    "DT",
    "STATE_NAMES",
    "FesTrajectory",
    "rhs_function",
    "simulate",
    "simulator_function",
    "step_function",
]

DT = 2e-3  # s
STATE_NAMES = ("theta_r", "omega_r", "K_c", "F_c")
_SMOOTH = 1e-6  # smoothing of sign/abs, in the units of the Eq. 3 numerator (N/s)

Method = Literal["rk4", "cvodes"]
RecKind = Literal["pw", "current"]


def _alpha_sym(kind: RecKind, level: ca.SX, r: list[ca.SX]) -> ca.SX:
    if kind == "pw":
        c1, c2, c3, pw_max = r
        return c1 / (1 + ca.exp(c2 * (c3 - level / pw_max)))
    a_i, b_r, c_r, d_r = r
    i_max = 3e-3
    rr = b_r * (1 + a_i * level / i_max) * (level * 1e3)
    return d_r * (ca.tanh(rr - c_r) + ca.tanh(c_r))


@functools.lru_cache(maxsize=8)
def rhs_function(kind: RecKind = "pw", isometric: bool = False, ce: str = "000") -> ca.Function:
    """``f(x, level, Π_c, p) → (ẋ, α, ε_c, ε̇_c)`` (Benoussaad et al. 2013, Eq. 1–7, 10–12).

    ``ce = "001"`` uses the implanted-FES identification paper's contractile element (its Eq. 3,
    5–6) instead: ``F_0 = F_cm Fl(L)``, ``K_0 = K_cm Fl(L)`` with the force–length factor of the
    *whole* muscle length ``L(θ)`` (the implanted-FES identification paper, Eq. 5–6: ``Fl =
    exp(−((L/L_opt − 1)/b_l)²)``, here ``L_opt = L_c0 + L_s``, ``b_l L_opt = b L_c0``), and with ``p
    = 1/k_s``, ``q = 1/(L_c0 k_s)``, ``D = 1 + p K_c − s_v q F_c``::

        Ḟ_c = [u (α F_0 − F_c) + (K_c − s_v F_c/L_c0) L̇] / D
        K̇_c = u (α K_0 − K_c) / D − |ε̇_c| K_c,   ε̇_c = (L̇/L_c0 + q u (F_c − α F_0)) / D

    which is the implanted-FES identification paper, Eq. 3 with its fused-tetanus ``u = 1`` read as
    the calcium rate ``u`` (``U_c`` while stimulating, ``Π_c ≡ 1``; ``U_r`` after the train) and ``a
    ε̇ = L̇/L_c0``, ``b ε̇ = L̇``.  ``Ḟ_c`` is Benoussaad et al.'s (2013) (Eq. 1, 3 eliminated);
    ``K̇_c`` differs from it: its relaxation term is divided by ``D``.
    """
    x = ca.SX.sym("x", 4)
    level = ca.SX.sym("level")
    pi = ca.SX.sym("pi")
    p = ca.SX.sym("p", len(PARAM_NAMES))
    P = {n: p[i] for i, n in enumerate(PARAM_NAMES)}
    th_r, om, kc, fc = x[0], x[1], x[2], x[3]
    if isometric:
        om = 0 * om
    if ce not in ("000", "001"):
        raise ModelError(f"contractile element model {ce!r}: expected '000' or '001'")
    alpha = _alpha_sym(kind, level, [P["rec0"], P["rec1"], P["rec2"], P["rec3"]])
    theta = P["theta_rest"] - th_r
    length = P["L_ext"] + P["r_q"] * theta
    l_dot = -P["r_q"] * om
    u = pi * P["U_c"] + (1 - pi) * P["U_r"]
    k_s, l_c0 = P["k_s"], P["L_c0"]
    if ce == "000":
        l_c = length - P["L_s"] - fc / k_s
        eps_c = (l_c - l_c0) / l_c0
        fl = ca.exp(-((eps_c / P["b"]) ** 2))
    else:  # the implanted-FES identification paper, Eq. 5-6: force-length on the whole muscle
        fl = ca.exp(-(((length - P["L_s"] - l_c0) / (l_c0 * P["b"])) ** 2))
        eps_c = (length - P["L_s"] - fc / k_s - l_c0) / l_c0
    drive = alpha * fl * pi * P["U_c"]
    num = k_s * l_dot + fc * u - drive * P["F_cm"]
    s_v = num / ca.sqrt(num**2 + _SMOOTH**2)
    den = k_s * l_c0 + kc * l_c0 - s_v * fc
    eps_c_dot = num / den
    abs_eps = s_v * eps_c_dot
    if ce == "000":
        kc_dot = -(u + abs_eps) * kc + drive * P["K_cm"]
        fc_dot = -(u + abs_eps) * fc + drive * P["F_cm"] + kc * l_c0 * eps_c_dot
    else:  # the implanted-FES identification paper, Eq. 3 (D = den / (k_s L_c0))
        d = den / (k_s * l_c0)
        kc_dot = (drive * P["K_cm"] - u * kc) / d - abs_eps * kc
        fc_dot = (drive * P["F_cm"] - u * fc + (kc - s_v * fc / l_c0) * l_dot) / d
    torque = P["r_q"] * fc
    passive = P["B"] * om + P["K"] * ca.sin(th_r) + P["K_e"] * th_r
    om_dot = (torque - passive) / P["J"]
    if isometric:
        xdot = ca.vertcat(0, 0, kc_dot, fc_dot)
    else:
        xdot = ca.vertcat(om, om_dot, kc_dot, fc_dot)
    return ca.Function(
        "fes_rhs",
        [x, level, pi, p],
        [xdot, alpha, eps_c, eps_c_dot],
        ["x", "level", "pi", "p"],
        ["xdot", "alpha", "eps_c", "eps_c_dot"],
    )


@functools.lru_cache(maxsize=16)
def step_function(
    kind: RecKind, isometric: bool, dt: float, method: Method, ce: str = "000"
) -> ca.Function:
    """One time step ``(x, w, p) → x_next`` of :func:`rhs_function` over ``dt``: RK4 on the
    stimulation samples ``w = (level, Π_c(t), Π_c(t + dt/2), Π_c(t + dt))`` (``method="rk4"``),
    or CVODES with Π_c linear over the step."""
    f = rhs_function(kind, isometric, ce)
    x = ca.SX.sym("x", 4)
    w = ca.SX.sym("w", 4)
    p = ca.SX.sym("p", len(PARAM_NAMES))
    if method == "rk4":
        k1 = f(x, w[0], w[1], p)[0]
        k2 = f(x + 0.5 * dt * k1, w[0], w[2], p)[0]
        k3 = f(x + 0.5 * dt * k2, w[0], w[2], p)[0]
        k4 = f(x + dt * k3, w[0], w[3], p)[0]
        xn = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return ca.Function("fes_step", [x, w, p], [xn])
    tau = ca.SX.sym("t")
    pi_t = w[1] + (w[3] - w[1]) * tau / dt
    ode = f(x, w[0], pi_t, p)[0]
    integ = ca.integrator(
        "fes_cvodes",
        "cvodes",
        {"x": x, "p": ca.vertcat(w, p), "t": tau, "ode": ode},
        0.0,
        dt,
        {"abstol": 1e-10, "reltol": 1e-10},
    )
    xs = ca.MX.sym("x", 4)
    ws = ca.MX.sym("w", 4)
    ps = ca.MX.sym("p", len(PARAM_NAMES))
    return ca.Function("fes_step", [xs, ws, ps], [integ(x0=xs, p=ca.vertcat(ws, ps))["xf"]])


@functools.lru_cache(maxsize=64)
def simulator_function(
    kind: RecKind,
    isometric: bool,
    n_steps: int,
    dt: float = DT,
    method: Method = "rk4",
    ce: str = "000",
) -> ca.Function:
    """``F(x0, W[4×n], p) → X[4×n]`` (states at the end of each step), cached per shape."""
    return step_function(kind, isometric, dt, method, ce).mapaccum("fes_sim", n_steps)


@dataclass(frozen=True)
class FesTrajectory:
    """Simulated states on the grid ``time`` (s, axis 0) with their column names.

    ``theta_r`` rad from rest (positive towards extension), ``knee_angle`` = θ_rest − θ_r (rad,
    0 = full extension), ``F_c`` N, ``K_c`` N/m, ``torque`` = r_q F_c N·m, ``alpha`` recruitment.
    """

    time: NDArray[np.float64]
    states: NDArray[np.float64]
    knee_angle: NDArray[np.float64]
    torque: NDArray[np.float64]
    alpha: NDArray[np.float64]
    columns: tuple[str, ...] = STATE_NAMES

    @property
    def theta_r(self) -> NDArray[np.float64]:
        return self.states[:, 0]

    @property
    def F_c(self) -> NDArray[np.float64]:
        return self.states[:, 3]


def simulate(
    subject: FesSubject,
    stim: Stimulation,
    *,
    duration: float | None = None,
    x0: NDArray[np.float64] | None = None,
    isometric_angle: float | None = None,
    dt: float = DT,
    method: Method = "rk4",
) -> FesTrajectory:
    """Simulate ``subject`` driven by ``stim`` from ``x0`` (default: at rest, relaxed).

    ``isometric_angle`` (knee angle θ, rad) clamps the shank there (dynamometer trials); the
    grid is ``t_k = k dt`` for ``k = 0 … n`` with ``n = ceil(duration/dt)``.
    """
    kind: RecKind = "current" if isinstance(subject.recruitment, RecruitmentCurrent) else "pw"
    if stim.kind != kind:
        raise ModelError(
            f"FES subject {subject.name!r} has {kind} recruitment but the stimulation is "
            f"{stim.kind}-modulated"
        )
    subject.validate()
    if duration is None:
        duration = stim.end_time + 1.0
    n = int(np.ceil(duration / dt - 1e-9))
    w = sample_on_grid(stim, n, dt, subject.calcium.tau_c, subject.calcium.tau_r)
    p = param_vector(subject)
    if x0 is None:
        x0 = np.zeros(4)
    x0 = np.asarray(x0, dtype=float).copy()
    iso = isometric_angle is not None
    if iso:
        x0[0] = subject.knee.theta_rest - float(isometric_angle)  # type: ignore[arg-type]
        x0[1] = 0.0
    sim = simulator_function(kind, iso, n, dt, method, subject.contractile)
    try:
        xs = np.asarray(sim(x0, w, p)).T
    except RuntimeError as e:  # casadi: NaN/Inf or an assertion inside the simulator
        raise ModelError(
            f"FES simulation of {subject.name!r} failed ({n} steps of {dt} s, x0 = {x0}): "
            f"{str(e).strip().splitlines()[-1] if str(e).strip() else type(e).__name__}"
        ) from e
    states = np.vstack([x0, xs])
    time = np.arange(n + 1, dtype=np.float64) * dt
    level = np.append(w[0], w[0, -1])
    alpha = np.asarray(subject.recruitment(level), dtype=float)
    alpha = np.where(level > 0, alpha, 0.0)
    return FesTrajectory(
        time=time,
        states=states,
        knee_angle=subject.knee.theta_rest - states[:, 0],
        torque=subject.geometry.r_q * states[:, 3],
        alpha=alpha,
    )
