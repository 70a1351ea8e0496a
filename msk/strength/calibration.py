"""EMG-driven calibration of muscle parameters to inverse-dynamics moments (the EMG-driven vs
OpenSim thesis, §2.2, §3.2).

Forward model (per muscle k, frame t; the EMG-driven vs OpenSim thesis, Eq. 1–20), EMG envelope e →
moment:

    e_d(t)  = e(t − d)                         electromechanical delay d ∈ [0, 100 ms]   (Eq. 1)
    u(t)    = α e_d(t) − β1 u(t−1) − β2 u(t−2),  β1 = γ1 + γ2, β2 = γ1 γ2, α = 1 + β1 + β2
                                                                                       (Eq. 1–6)
    a(t)    = (e^{A u} − 1)/(e^{A} − 1)     shape factor A  (Eq. 7's role; Lloyd & Besier 2003)
    l_o(t)  = l_opt (λ (1 − a) + 1)            force–length skew λ                        (Eq. 9)
    F_k     = G F_iso [F̃_A(l̃) F̃_V(ṽ) a + F̃_P(l̃) + b_m ṽ] cos φ                   (Eq. 8, 19–20)
    M_F(j)  = Σ_k R_k(j) F_k,   R = −∂l/∂θ                                        (moment arms)

with the curves of :class:`msk.muscles.hill.LloydBesierCurves` (Gaussian active force–length,
``e^{10(l̃−1)}/e^5`` passive, Epstein–Herzog force–velocity, damping b_m) and the activation of
:mod:`msk.muscles.activation` (recursive filter + exponential nonlinearity; the thesis prints
A ∈ [0.01, 0.12] for the piecewise log/linear form of Manal & Buchanan, our exponential form uses
Lloyd & Besier's A ∈ (−3, 0), bounds [−2.9, −0.01]). Contraction, ``tendon=``:

* ``"rigid"`` (default): the tendon stays at its slack length l_ts (fibre length
  ``sqrt(h² + (l_MT − l_ts)²)``, ``h = l_opt sin φ_0``, constant-height pennation, Eq. 14,
  velocity ``l̇_MT cos φ``): the forces are smooth explicit functions of the parameters;
* ``"elastic"``: the thesis' elastic tendon (Eq. 8–18): the fibre length is integrated over the
  trial by :mod:`msk.muscles.contraction` (BDF2 with ``substeps`` steps per sample, the force
  balance of Eq. 8 solved for the fibre velocity by Newton; the thesis uses
  Runge–Kutta–Fehlberg) from the static equilibrium at the first sample, and
  ``F_k = G F_iso F̃_t(ε)`` (Eq. 16–18). The integrator is a fixed chain of casadi operations
  (one SX function per trial length, mapped over the muscles in an MX graph), so its derivatives
  with respect to l_opt, l_ts, λ and the activation parameters are exact.

Both are differentiated exactly by casadi. The fractional delay d is a linear interpolation
between samples (``e_d(t) = Σ_i max(0, 1 − |d/h − i|) e(t − i h)``), continuous in d.

Calibrated parameters (bounds of the EMG-driven vs OpenSim thesis, Table 3.1): strength factors G
per functional group ∈ [0.5, 2] (Eq. 19–20), per muscle the optimal fibre length (× [0.95, 1.05]),
tendon slack length (× [0.85, 1.15]), γ1, γ2 ∈ [−0.9, 0.9], d ∈ [0, 0.1] s, A; and the global skew
λ ∈ [0, 0.25]. Objective: the mean squared difference between M_F and the inverse-dynamics
moment M_I over the calibration trials, each coordinate divided by the standard deviation of its
M_I, plus a small Tikhonov term on the parameters normalised to their ranges (default 1e-4).

Solver: casadi + ipopt with exact derivatives (casadi AD; Hessian of the Lagrangian by AD) from
``n_starts`` starting points (the initial guess, then uniform random points in the bounds) —
instead of the thesis' simulated annealing. Over-fitting is checked on held-out trials
(:meth:`EMGDrivenCalibration.validate`).
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from scipy import sparse

from msk import metrics as compare
from msk.exceptions import IdentificationError, ShapeMismatchError
from msk.muscles.activation import nonlinear_activation, recursive_filter
from msk.muscles.contraction import contraction_dynamics, trajectory_function
from msk.muscles.hill import LloydBesierCurves, MuscleParameters
from msk.strength.identification import STRENGTH_FACTOR_BOUNDS, StrengthProfile
from msk.units import Array

__all__ = [
    "CALIBRATION_BOUNDS",
    "MUSCLE_CALIBRATION_PARAMETERS",
    "CalibrationParameters",
    "CalibrationResult",
    "CalibrationTrial",
    "EMGDrivenCalibration",
    "FitMetrics",
    "casadi_curves",
    "emg_driven_forces",
    "fractional_delay",
]

#: Per-muscle calibrated parameters, in the order of the parameter vector blocks.
MUSCLE_CALIBRATION_PARAMETERS: tuple[str, ...] = (
    "optimal_fiber_length_scale",
    "tendon_slack_length_scale",
    "gamma1",
    "gamma2",
    "delay_s",
    "shape_factor",
)

#: Bounds (the EMG-driven vs OpenSim thesis, Table 3.1; A for the exponential form, see the module
#: docstring).
CALIBRATION_BOUNDS: dict[str, tuple[float, float]] = {
    "strength_factor": STRENGTH_FACTOR_BOUNDS,
    "optimal_fiber_length_scale": (0.95, 1.05),
    "tendon_slack_length_scale": (0.85, 1.15),
    "gamma1": (-0.9, 0.9),
    "gamma2": (-0.9, 0.9),
    "delay_s": (0.0, 0.1),
    "shape_factor": (-2.9, -0.01),
    "skew": (0.0, 0.25),
}

_DEFAULT_INITIAL: dict[str, float] = {
    "strength_factor": 1.0,
    "optimal_fiber_length_scale": 1.0,
    "tendon_slack_length_scale": 1.0,
    "gamma1": -0.5,
    "gamma2": -0.5,
    "delay_s": 0.04,
    "shape_factor": -1.0,
    "skew": 0.15,
}


# ---------------------------------------------------------------------------------------------
# data and parameters
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CalibrationTrial:
    """One trial for the EMG-driven model (time on axis 0, SI, muscles in parameter order).

    ``excitation`` e ``(N, M)`` normalised EMG envelopes in [0, 1] (muscles without electrode
    take a synergist's, the EMG-driven vs OpenSim thesis, §3.2.1); ``muscle_tendon_length`` and
    ``lengthening_velocity`` ``(N, M)``; ``moment_arms`` R = −∂l/∂θ ``(N, M, n)`` for the
    calibrated coordinates; ``moments`` the inverse-dynamics moments ``(N, n)``.
    """

    excitation: Array
    muscle_tendon_length: Array
    lengthening_velocity: Array
    moment_arms: Array
    moments: Array
    rate_hz: float
    coordinate_names: tuple[str, ...]
    name: str = "trial"

    def __post_init__(self) -> None:
        e = np.asarray(self.excitation, dtype=float)
        if e.ndim != 2:
            raise ShapeMismatchError(
                f"trial {self.name!r}: excitation must be (N, M), got {e.shape}"
            )
        n, m = e.shape
        for key, shape in (
            ("excitation", (n, m)),
            ("muscle_tendon_length", (n, m)),
            ("lengthening_velocity", (n, m)),
            ("moment_arms", (n, m, len(self.coordinate_names))),
            ("moments", (n, len(self.coordinate_names))),
        ):
            v = np.asarray(getattr(self, key), dtype=float)
            if v.shape != shape:
                raise ShapeMismatchError(
                    f"trial {self.name!r}: {key} must have shape {shape}, got {v.shape}"
                )
            if not np.isfinite(v).all():
                idx = tuple(int(i) for i in np.argwhere(~np.isfinite(v))[0])
                raise IdentificationError(f"trial {self.name!r}: {key} is not finite at {idx}")
            object.__setattr__(self, key, v)
        if not self.rate_hz > 0:
            raise IdentificationError(f"trial {self.name!r}: rate_hz must be > 0: {self.rate_hz}")
        object.__setattr__(self, "coordinate_names", tuple(self.coordinate_names))

    @property
    def n_frames(self) -> int:
        return int(self.excitation.shape[0])


@dataclass(frozen=True)
class CalibrationParameters:
    """EMG-driven model parameters: ``strength_factors`` per group ``(G,)``, the per-muscle
    arrays of :data:`MUSCLE_CALIBRATION_PARAMETERS` ``(M,)`` and the global ``skew`` λ."""

    group_names: tuple[str, ...]
    muscle_names: tuple[str, ...]
    strength_factors: Array
    optimal_fiber_length_scale: Array
    tendon_slack_length_scale: Array
    gamma1: Array
    gamma2: Array
    delay_s: Array
    shape_factor: Array
    skew: float

    def to_vector(self) -> Array:
        """``[G…, (l_opt scale, l_ts scale, γ1, γ2, d, A) per block of M…, λ]``."""
        blocks = [np.asarray(getattr(self, k), dtype=float) for k in MUSCLE_CALIBRATION_PARAMETERS]
        return np.concatenate([np.asarray(self.strength_factors, float), *blocks, [self.skew]])

    @classmethod
    def from_vector(
        cls, x: ArrayLike, group_names: Sequence[str], muscle_names: Sequence[str]
    ) -> CalibrationParameters:
        v = np.asarray(x, dtype=float)
        g, m = len(group_names), len(muscle_names)
        if v.shape != (g + 6 * m + 1,):
            raise ShapeMismatchError(f"parameter vector must be ({g + 6 * m + 1},), got {v.shape}")
        blocks = {
            k: v[g + i * m : g + (i + 1) * m] for i, k in enumerate(MUSCLE_CALIBRATION_PARAMETERS)
        }
        return cls(tuple(group_names), tuple(muscle_names), v[:g], skew=float(v[-1]), **blocks)

    def muscle_factors(self, groups: Mapping[str, Sequence[str]]) -> Array:
        """Strength factor of each muscle (1 outside every group)."""
        out = np.ones(len(self.muscle_names))
        for gi, gname in enumerate(self.group_names):
            for mname in groups[gname]:
                out[self.muscle_names.index(mname)] = self.strength_factors[gi]
        return out

    def muscle_parameters(
        self, base: MuscleParameters, groups: Mapping[str, Sequence[str]]
    ) -> MuscleParameters:
        """``base`` with calibrated F_iso, l_opt and l_ts."""
        return MuscleParameters(
            base.names,
            base.max_isometric_force * self.muscle_factors(groups),
            base.optimal_fiber_length * self.optimal_fiber_length_scale,
            base.tendon_slack_length * self.tendon_slack_length_scale,
            base.pennation_angle_at_optimal,
            base.max_contraction_velocity,
        )


@dataclass(frozen=True)
class FitMetrics:
    """Moment fit per coordinate (the EMG-driven vs OpenSim thesis, Table 4.1): r², RMS (N·m) and
    RMS normalised to the peak-to-peak range of the inverse-dynamics moment."""

    coordinate_names: tuple[str, ...]
    r2: Array
    rms: Array
    nrms: Array


@dataclass(frozen=True)
class CalibrationResult:
    """Outcome of :meth:`EMGDrivenCalibration.fit`."""

    parameters: CalibrationParameters
    initial: CalibrationParameters
    objective: float
    start_objectives: Array
    start_status: tuple[str, ...]
    best_start: int
    calibration: FitMetrics
    solve_time_s: float
    n_parameters: int
    n_residuals: int
    extra: dict[str, Any] = field(default_factory=dict)


def _check_tendon(tendon: str) -> str:
    if tendon not in ("rigid", "elastic"):
        raise IdentificationError(f"unknown tendon model {tendon!r}: use 'rigid' or 'elastic'")
    return tendon


# ---------------------------------------------------------------------------------------------
# numpy reference forward model
# ---------------------------------------------------------------------------------------------
def fractional_delay(excitation: ArrayLike, delay_samples: ArrayLike) -> Array:
    """``e(t − d)`` per column with linear interpolation between samples (``e(t<0) = e(0)``)."""
    e = np.asarray(excitation, dtype=float)
    d = np.broadcast_to(np.asarray(delay_samples, dtype=float), (e.shape[1],))
    out = np.empty_like(e)
    n = e.shape[0]
    for k in range(e.shape[1]):
        i0 = int(np.floor(d[k]))
        fr = d[k] - i0
        idx0 = np.clip(np.arange(n) - i0, 0, n - 1)
        idx1 = np.clip(np.arange(n) - i0 - 1, 0, n - 1)
        out[:, k] = (1.0 - fr) * e[idx0, k] + fr * e[idx1, k]
    return out


def emg_driven_forces(
    params: CalibrationParameters,
    base: MuscleParameters,
    groups: Mapping[str, Sequence[str]],
    trial: CalibrationTrial,
    *,
    curves: LloydBesierCurves | None = None,
    tendon: str = "rigid",
    substeps: int = 2,
) -> tuple[Array, Array]:
    """Activations and tendon forces ``(N, M)`` of the EMG-driven model (module docstring),
    numpy reference of the casadi expressions. ``tendon="elastic"`` integrates the contraction
    dynamics of :mod:`msk.muscles.contraction` (``substeps`` BDF2 steps per sample) instead of
    the rigid tendon."""
    curves = curves or LloydBesierCurves()
    _check_tendon(tendon)
    h = 1.0 / trial.rate_hz
    ed = fractional_delay(trial.excitation, params.delay_s / h)
    u = recursive_filter(ed, gamma1=params.gamma1, gamma2=params.gamma2)
    a = nonlinear_activation(
        np.clip(u, -1.0, 2.0), shape_factor=params.shape_factor, form="exponential"
    )
    mp = params.muscle_parameters(base, groups)
    if tendon == "elastic":
        state = contraction_dynamics(
            mp,
            a,
            trial.muscle_tendon_length,
            np.arange(trial.n_frames) * h,
            curves=replace(curves, skew=params.skew),
            substeps=substeps,
        )
        return a, state.tendon_force
    lopt, lts = mp.optimal_fiber_length, mp.tendon_slack_length
    hgt = lopt * np.sin(mp.pennation_angle_at_optimal)
    x = np.maximum(trial.muscle_tendon_length - lts, 0.1 * lopt)
    lf = np.sqrt(hgt**2 + x**2)
    cos_p = x / lf
    l_norm = lf / (lopt * replace(curves, skew=params.skew).optimal_length_scale(a))
    v_short = -trial.lengthening_velocity * cos_p / (mp.max_contraction_velocity * lopt)
    f = curves.tendon_force(a, l_norm, v_short, cos_p, mp.max_isometric_force)
    return a, f


# ---------------------------------------------------------------------------------------------
# casadi forward model
# ---------------------------------------------------------------------------------------------
def casadi_curves(curves: LloydBesierCurves) -> dict[str, Any]:
    """Casadi versions of the :class:`LloydBesierCurves` used here (same constants; tested
    against the numpy methods): ``fa(l̃)``, ``fp(l̃)``, ``fv(ṽ_shortening)``, ``scale(a)``."""
    w = curves.width
    a_c = b_c = curves.hill_curvature
    slope_c = (1.0 + a_c) / b_c
    bp = (curves.f_ecc - 1.0) / (curves.ecc_slope_ratio * slope_c)
    fecc = curves.f_ecc

    def fa(ln: Any) -> Any:
        return ca.exp(-(((ln - 1.0) / w) ** 2))

    def fp(ln: Any) -> Any:
        return ca.exp(10.0 * (ln - 1.0)) / np.exp(5.0)

    def fv(v: Any) -> Any:
        vp = ca.fmax(v, 0.0)
        vn = ca.fmin(v, 0.0)
        conc = ca.fmax((b_c - a_c * vp) / (b_c + vp), 0.0)
        ecc = fecc - (fecc - 1.0) * bp / (bp - vn)
        return ca.if_else(v >= 0, conc, ecc)

    def scale(act: Any, skew: Any) -> Any:
        return skew * (1.0 - act) + 1.0

    return {"fa": fa, "fp": fp, "fv": fv, "scale": scale, "damping": curves.damping}


class EMGDrivenCalibration:
    """EMG-driven calibration (the EMG-driven vs OpenSim thesis, §2.2.3, §3.2) with casadi/ipopt
    multi-start.

    Args:
        params: generic (scaled) muscle parameters, muscle order of the trial arrays.
        groups: functional group → muscles sharing a strength factor (the EMG-driven vs OpenSim
        thesis, Eq. 19–20:
            knee flexors / extensors, ankle plantar / dorsiflexors).
        bounds: overrides of :data:`CALIBRATION_BOUNDS`.
        initial: overrides of the initial guess (scalars per parameter name).
        fixed: parameter names held at their initial value (e.g. ``("skew",)``).
        shared: per-muscle parameters given one value per functional group (e.g.
            ``("gamma1", "gamma2", "delay_s", "shape_factor")``) — fewer parameters, less
            over-fitting of short trials; the EMG-driven vs OpenSim thesis calibrates them per
            muscle (the default).
        n_starts: multi-start count (first = initial guess).
        regularization: weight of the Tikhonov term on range-normalised deviations from the
            initial guess.
        skip_s: padding at the start of each trial excluded from the objective
            (the EMG-driven vs OpenSim thesis, §3.2.2; covers the delay and filter start-up).
        max_iter, tol: ipopt options.
        tendon: ``"rigid"`` (default) or ``"elastic"`` (contraction dynamics over time, module
            docstring; the EMG-driven vs OpenSim thesis' model, ~2–8× slower to calibrate).
        substeps: BDF2 steps per sample interval of the elastic tendon.
    """

    def __init__(
        self,
        params: MuscleParameters,
        groups: Mapping[str, Sequence[str]],
        *,
        bounds: Mapping[str, tuple[float, float]] | None = None,
        initial: Mapping[str, float] | None = None,
        fixed: Sequence[str] = (),
        shared: Sequence[str] = (),
        n_starts: int = 3,
        regularization: float = 1e-6,
        skip_s: float = 0.1,
        max_iter: int = 200,
        tol: float = 1e-9,
        curves: LloydBesierCurves | None = None,
        random_state: int | None = 0,
        solver: str = "trf",
        tendon: str = "rigid",
        substeps: int = 2,
    ) -> None:
        self.params = params
        self.groups = {g: tuple(m) for g, m in groups.items()}
        for g, members in self.groups.items():
            for mname in members:
                if mname not in params.names:
                    raise IdentificationError(f"functional group {g!r}: unknown muscle {mname!r}")
        self.bounds = dict(CALIBRATION_BOUNDS)
        self.bounds.update(bounds or {})
        self.initial = dict(_DEFAULT_INITIAL)
        self.initial.update(initial or {})
        for key in list(fixed):
            if key not in self.bounds:
                raise IdentificationError(f"unknown calibration parameter {key!r}")
        self.fixed = tuple(fixed)
        for key in shared:
            if key not in MUSCLE_CALIBRATION_PARAMETERS:
                raise IdentificationError(
                    f"only per-muscle parameters can be shared within groups, not {key!r} "
                    f"(choose from {MUSCLE_CALIBRATION_PARAMETERS})"
                )
        self.shared = tuple(shared)
        self.n_starts = int(n_starts)
        self.regularization = float(regularization)
        self.skip_s = float(skip_s)
        self.max_iter = int(max_iter)
        self.tol = float(tol)
        self.curves = curves or LloydBesierCurves()
        self.random_state = random_state
        if solver not in ("trf", "ipopt"):
            raise IdentificationError(f"unknown solver {solver!r}: use 'trf' or 'ipopt'")
        self.solver = solver
        self.tendon = _check_tendon(tendon)
        if substeps < 1:
            raise IdentificationError(f"substeps must be >= 1, got {substeps}")
        self.substeps = int(substeps)

    # ----------------------------------------------------------------- layout
    @property
    def group_names(self) -> tuple[str, ...]:
        return tuple(self.groups)

    def _kinds(self) -> list[str]:
        g, m = len(self.groups), self.params.n_muscles
        return (
            ["strength_factor"] * g
            + [k for k in MUSCLE_CALIBRATION_PARAMETERS for _ in range(m)]
            + ["skew"]
        )

    def _bounds_vectors(self) -> tuple[Array, Array, Array]:
        kinds = self._kinds()
        lo = np.array([self.bounds[k][0] for k in kinds])
        hi = np.array([self.bounds[k][1] for k in kinds])
        x0 = np.array([self.initial[k] for k in kinds])
        fixed = np.array([k in self.fixed for k in kinds])
        lo = np.where(fixed, x0, lo)
        hi = np.where(fixed, x0, hi)
        if np.any(x0 < lo - 1e-12) or np.any(x0 > hi + 1e-12):
            i = int(np.flatnonzero((x0 < lo) | (x0 > hi))[0])
            raise IdentificationError(
                f"initial {kinds[i]} = {x0[i]} outside its bounds [{lo[i]}, {hi[i]}]"
            )
        return lo, hi, x0

    def _tying(self) -> Array:
        """``T`` (n_x, n_y): full parameter vector x = T y from the optimised vector y (per-muscle
        parameters in :attr:`shared` take one value per functional group)."""
        g, m = len(self.groups), self.params.n_muscles
        nx = g + 6 * m + 1
        group_of = np.full(m, -1)
        for gi, gname in enumerate(self.groups):
            for mname in self.groups[gname]:
                group_of[self.params.names.index(mname)] = gi
        cols: list[Array] = []
        for i in range(g):
            c = np.zeros(nx)
            c[i] = 1.0
            cols.append(c)
        for b, key in enumerate(MUSCLE_CALIBRATION_PARAMETERS):
            base = g + b * m
            if key in self.shared:
                for gi in range(g):
                    c = np.zeros(nx)
                    c[base + np.flatnonzero(group_of == gi)] = 1.0
                    cols.append(c)
                loners = np.flatnonzero(group_of < 0)
            else:
                loners = np.arange(m)
            for k in loners:
                c = np.zeros(nx)
                c[base + k] = 1.0
                cols.append(c)
        c = np.zeros(nx)
        c[-1] = 1.0
        cols.append(c)
        return np.column_stack(cols)

    def _check_trials(self, trials: Sequence[CalibrationTrial]) -> tuple[str, ...]:
        if not trials:
            raise IdentificationError("no calibration trial given")
        cn = trials[0].coordinate_names
        for t in trials:
            if t.excitation.shape[1] != self.params.n_muscles:
                raise ShapeMismatchError(
                    f"trial {t.name!r} has {t.excitation.shape[1]} muscles, "
                    f"parameters {self.params.n_muscles}"
                )
            if t.coordinate_names != cn:
                raise ShapeMismatchError(
                    f"trial {t.name!r} coordinates {t.coordinate_names} differ from {cn}"
                )
        return cn

    # ----------------------------------------------------------------- casadi model
    def _symbolic_forces(self, x: Any, trial: CalibrationTrial) -> list[Any]:
        """Muscle forces, one ``(N, 1)`` casadi column per muscle, of the parameter vector ``x``
        (see the module docstring): SX for the rigid tendon. For the elastic tendon the
        activation part is an SX function of ``x`` and the contraction dynamics one
        :func:`~msk.muscles.contraction.trajectory_function` mapped over the muscles, so with an
        MX ``x`` the graph stays small and casadi builds its Jacobian in well under a second."""
        if self.tendon == "rigid":
            return self._sx_forces(x, trial)
        m, n = self.params.n_muscles, trial.n_frames
        xs = ca.SX.sym("x", x.shape[0])
        acts, pks, fisos = self._sx_forces(xs, trial, elastic_parts=True)
        pre = ca.Function("pre", [xs], [ca.horzcat(*acts), ca.horzcat(*pks), ca.horzcat(*fisos)])
        amat, pmat, fmat = pre(x)
        traj = trajectory_function(self.curves, self.substeps, n, 1.0 / trial.rate_hz)
        ft = traj.map(m)(amat, ca.DM(trial.muscle_tendon_length), pmat)
        return [fmat[k] * ft[:, k] for k in range(m)]

    def _sx_forces(self, x: Any, trial: CalibrationTrial, *, elastic_parts: bool = False) -> Any:
        """Rigid-tendon forces (SX columns) or, with ``elastic_parts``, the lists of
        activation columns, contraction parameter vectors and F_iso of the elastic model."""
        cc = casadi_curves(self.curves)
        g, m = len(self.groups), self.params.n_muscles
        n = trial.n_frames
        h = 1.0 / trial.rate_hz
        sf = x[:g]
        blk = {
            k: x[g + i * m : g + (i + 1) * m] for i, k in enumerate(MUSCLE_CALIBRATION_PARAMETERS)
        }
        skew = x[g + 6 * m]
        gidx = np.full(m, -1)
        for gi, gname in enumerate(self.groups):
            for mname in self.groups[gname]:
                gidx[self.params.names.index(mname)] = gi
        p = self.params
        dmax = int(np.ceil(self.bounds["delay_s"][1] / h)) + 1
        forces = []
        parts: tuple[list[Any], list[Any], list[Any]] = ([], [], [])
        for k in range(m):
            e = trial.excitation[:, k]
            ds = blk["delay_s"][k] / h
            ed = ca.SX.zeros(n, 1)
            for i in range(dmax + 1):
                wi = ca.fmax(0.0, 1.0 - ca.fabs(ds - i))
                shifted = e[np.clip(np.arange(n) - i, 0, n - 1)]
                ed = ed + wi * ca.DM(shifted)
            g1, g2 = blk["gamma1"][k], blk["gamma2"][k]
            b1, b2 = g1 + g2, g1 * g2
            alpha = 1.0 + b1 + b2
            u_prev2 = ed[0]
            u_prev1 = ed[0]
            us = []
            for t in range(n):
                ut = alpha * ed[t] - b1 * u_prev1 - b2 * u_prev2
                us.append(ut)
                u_prev2, u_prev1 = u_prev1, ut
            u = ca.fmin(ca.fmax(ca.vertcat(*us), -1.0), 2.0)
            big_a = blk["shape_factor"][k]
            act = (ca.exp(big_a * u) - 1.0) / (ca.exp(big_a) - 1.0)
            lopt = p.optimal_fiber_length[k] * blk["optimal_fiber_length_scale"][k]
            lts = p.tendon_slack_length[k] * blk["tendon_slack_length_scale"][k]
            fiso = p.max_isometric_force[k] * (sf[int(gidx[k])] if gidx[k] >= 0 else 1.0)
            if elastic_parts:
                sin0 = np.sin(p.pennation_angle_at_optimal[k])
                vmax = p.max_contraction_velocity[k]
                parts[0].append(act)
                parts[1].append(ca.vertcat(lopt, lts, sin0, vmax, skew, 1.0))
                parts[2].append(fiso)
                continue
            hgt = lopt * np.sin(p.pennation_angle_at_optimal[k])
            xf = ca.fmax(ca.DM(trial.muscle_tendon_length[:, k]) - lts, 0.1 * lopt)
            lf = ca.sqrt(hgt**2 + xf**2)
            cos_p = xf / lf
            l_norm = lf / (lopt * cc["scale"](act, skew))
            v_short = (
                -ca.DM(trial.lengthening_velocity[:, k])
                * cos_p
                / (p.max_contraction_velocity[k] * lopt)
            )
            force = (
                fiso
                * (
                    cc["fa"](l_norm) * cc["fv"](v_short) * act
                    + cc["fp"](l_norm)
                    - cc["damping"] * v_short
                )
                * cos_p
            )
            forces.append(force)
        return parts if elastic_parts else forces

    def _symbolic_moments(self, x: Any, trial: CalibrationTrial) -> Any:
        """M_F ``(N, n)`` as a casadi SX matrix of the parameter vector ``x``."""
        return self._moments_of(self._symbolic_forces(x, trial), trial)

    @staticmethod
    def _moments_of(forces: list[Any], trial: CalibrationTrial) -> Any:
        cols = []
        for j in range(len(trial.coordinate_names)):
            mj = ca.DM.zeros(trial.n_frames, 1)
            for k, fk in enumerate(forces):
                rj = trial.moment_arms[:, k, j]
                if np.any(rj != 0):
                    mj = mj + ca.DM(rj) * fk
            cols.append(mj)
        return ca.horzcat(*cols)

    # ----------------------------------------------------------------- fit
    def fit(self, trials: Sequence[CalibrationTrial]) -> EMGDrivenCalibration:
        """Calibrate on ``trials`` (concatenated objective). Returns ``self``; ``result_``,
        ``parameters_`` and ``coordinate_names_`` are set."""
        from scipy import sparse  # on use: a cached run decoding results need not pay for it

        cn = self._check_trials(trials)
        t0 = time.perf_counter()
        lo_x, hi_x, x0_x = self._bounds_vectors()
        tmat = self._tying()
        first = np.argmax(tmat > 0, axis=0)  # a representative entry of x per entry of y
        lo, hi = lo_x[first], hi_x[first]
        x0 = np.array([x0_x[tmat[:, i] > 0].mean() for i in range(tmat.shape[1])])
        # the elastic model calls casadi functions (MX graph), the rigid one is inlined (SX)
        y = (ca.MX if self.tendon == "elastic" else ca.SX).sym("y", tmat.shape[1])
        x = ca.mtimes(ca.DM(sparse.csc_matrix(tmat)), y)  # sparse: keeps the Jacobian coloured
        all_m = np.concatenate([t.moments for t in trials])
        sd = np.maximum(np.std(all_m, axis=0), 1e-9)
        fiso = self.params.max_isometric_force
        fnorm, rows, cols, vals, target = [], [], [], [], []
        offset_f, offset_r = 0, 0
        for tr in trials:
            fk = self._symbolic_forces(x, tr)
            n, m = tr.n_frames, len(fk)
            # normalised forces F/F_iso, column-major (muscle k, frame t) -> k * n + t
            fnorm.append(ca.vertcat(*[fk[k] / fiso[k] for k in range(m)]))
            skip = min(round(self.skip_s * tr.rate_hz), n - 1)
            tt = np.arange(skip, n)
            for j in range(len(cn)):
                for k in range(m):
                    rj = tr.moment_arms[tt, k, j]
                    nzr = rj != 0
                    if not nzr.any():
                        continue
                    rows.append(offset_r + j * tt.size + np.flatnonzero(nzr))
                    cols.append(offset_f + k * n + tt[nzr])
                    vals.append(rj[nzr] * fiso[k] / sd[j])
                target.append(tr.moments[tt, j] / sd[j])
            offset_f += n * m
            offset_r += tt.size * len(cn)
        n_res = offset_r
        rmat = sparse.csr_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
            shape=(n_res, offset_f),
        )
        mvec = np.concatenate(target)
        fvec = ca.vertcat(*fnorm)
        span = np.where(hi > lo, hi - lo, 1.0)
        free = hi > lo
        if self.solver == "ipopt":
            best, objs, stats = self._solve_ipopt(y, fvec, rmat, mvec, lo, hi, x0, span)
        else:
            best, objs, stats = self._solve_trf(y, fvec, rmat, mvec, lo, hi, x0, span, free)
        best = tmat @ best
        x0 = tmat @ x0
        best_i = int(np.argmin(objs))
        pars = CalibrationParameters.from_vector(best, self.group_names, self.params.names)
        self.parameters_ = pars
        self.coordinate_names_ = cn
        metrics = self.validate(trials)
        self.result_ = CalibrationResult(
            parameters=pars,
            initial=CalibrationParameters.from_vector(x0, self.group_names, self.params.names),
            objective=float(objs[best_i]),
            start_objectives=np.array(objs),
            start_status=tuple(stats),
            best_start=best_i,
            calibration=metrics,
            solve_time_s=time.perf_counter() - t0,
            n_parameters=int(free.sum()),
            n_residuals=n_res,
            extra={"solver": self.solver, "tendon": self.tendon, "substeps": self.substeps},
        )
        return self

    def _starts(self, lo: Array, hi: Array, x0: Array) -> list[Array]:
        rng = np.random.default_rng(self.random_state)
        starts = [x0]
        for _ in range(max(self.n_starts - 1, 0)):
            starts.append(np.where(hi > lo, rng.uniform(lo, hi), x0))
        return starts

    def _solve_trf(
        self,
        x: Any,
        fvec: Any,
        rmat: sparse.csr_matrix,
        mvec: Array,
        lo: Array,
        hi: Array,
        x0: Array,
        span: Array,
        free: NDArray[np.bool_],
    ) -> tuple[Array, list[float], list[str]]:
        """Bounded Gauss–Newton (scipy ``least_squares``, trust-region reflective) with the exact
        casadi Jacobian ∂F/∂x (sparse: each force depends on 8 parameters)."""
        from scipy.optimize import least_squares  # on use (see fit)

        f_fn = ca.Function("F", [x], [fvec])
        jf_fn = ca.Function("JF", [x], [ca.jacobian(fvec, x)])
        n_res = mvec.size
        w = 1.0 / np.sqrt(n_res)
        sreg = np.sqrt(self.regularization)
        idx = np.flatnonzero(free)

        def full(xf: Array, base: Array) -> Array:
            out = base.copy()
            out[idx] = xf
            return out

        best, best_f = x0, np.inf
        objs, stats = [], []
        for xs in self._starts(lo, hi, x0):

            def res(xf: Array, xs: Array = xs) -> Array:
                xx = full(xf, xs)
                fv = np.asarray(f_fn(xx)).ravel()
                return np.concatenate([w * (rmat @ fv - mvec), sreg * (xf - x0[idx]) / span[idx]])

            def jac(xf: Array, xs: Array = xs) -> Array:
                xx = full(xf, xs)
                jf = jf_fn(xx).sparse()
                top = np.asarray((rmat @ jf[:, idx]).todense()) * w
                return np.vstack([top, np.diag(sreg / span[idx])])

            sol = least_squares(
                res,
                np.clip(xs[idx], lo[idx], hi[idx]),
                jac=jac,
                bounds=(lo[idx], hi[idx]),
                method="trf",
                tr_solver="lsmr",
                x_scale=span[idx],
                xtol=self.tol,
                ftol=self.tol,
                gtol=self.tol,
                max_nfev=self.max_iter,
            )
            fval = 2.0 * float(sol.cost)
            objs.append(fval)
            stats.append(str(sol.message))
            if fval < best_f:
                best_f, best = fval, full(sol.x, xs)
        return best, objs, stats

    def _solve_ipopt(
        self,
        x: Any,
        fvec: Any,
        rmat: sparse.csr_matrix,
        mvec: Array,
        lo: Array,
        hi: Array,
        x0: Array,
        span: Array,
    ) -> tuple[Array, list[float], list[str]]:
        """ipopt with exact derivatives on the lifted problem: the normalised forces are
        variables tied to the model by equality constraints, so the Hessian of the Lagrangian is
        sparse (each force depends on its muscle's parameters, its group factor and λ)."""
        nf = int(fvec.shape[0])
        z = (ca.MX if isinstance(x, ca.MX) else ca.SX).sym("z", nf)
        rm = ca.DM(rmat)
        rv = ca.mtimes(rm, z) - ca.DM(mvec)
        n_res = mvec.size
        obj = ca.sumsqr(rv) / n_res + self.regularization * ca.sumsqr((x - ca.DM(x0)) / ca.DM(span))
        solver = ca.nlpsol(
            "calib",
            "ipopt",
            # casadi's nlpsol overloads take an all-SX or an all-MX dict, not the SX | MX union
            {"x": ca.vertcat(x, z), "f": obj, "g": fvec - z},  # type: ignore[dict-item]
            {
                "ipopt.print_level": 0,
                "print_time": False,
                "ipopt.max_iter": self.max_iter,
                "ipopt.tol": self.tol,
                "ipopt.sb": "yes",
            },
        )
        f_fn = ca.Function("F", [x], [fvec])
        big = np.full(nf, np.inf)
        best, best_f = x0, np.inf
        objs, stats = [], []
        for xs in self._starts(lo, hi, x0):
            z0 = np.asarray(f_fn(xs)).ravel()
            sol = solver(
                x0=np.concatenate([xs, z0]),
                lbx=np.concatenate([lo, -big]),
                ubx=np.concatenate([hi, big]),
                lbg=0.0,
                ubg=0.0,
            )
            fval = float(sol["f"])
            objs.append(fval)
            stats.append(str(solver.stats()["return_status"]))
            if fval < best_f:
                best_f, best = fval, np.asarray(sol["x"]).ravel()[: lo.size]
        return best, objs, stats

    # ----------------------------------------------------------------- predict / score
    def _check_fitted(self) -> None:
        if not hasattr(self, "parameters_"):
            raise IdentificationError("EMGDrivenCalibration is not fitted: call fit() first")

    def predict_forces(self, trial: CalibrationTrial) -> tuple[Array, Array]:
        """Activations and muscle forces ``(N, M)`` with the calibrated parameters."""
        self._check_fitted()
        return emg_driven_forces(
            self.parameters_,
            self.params,
            self.groups,
            trial,
            curves=self.curves,
            tendon=self.tendon,
            substeps=self.substeps,
        )

    def predict(self, trial: CalibrationTrial) -> Array:
        """Forward-dynamic moments ``M_F = Σ_k R_k F_k`` ``(N, n)``."""
        _, f = self.predict_forces(trial)
        return np.einsum("tmj,tm->tj", trial.moment_arms, f)

    def validate(self, trials: Sequence[CalibrationTrial]) -> FitMetrics:
        """r², RMS and peak-to-peak-normalised RMS per coordinate over ``trials``
        (the EMG-driven vs OpenSim thesis, Table 4.1), padding excluded."""
        self._check_fitted()
        cn = self._check_trials(trials)
        meas, pred = [], []
        for tr in trials:
            skip = min(round(self.skip_s * tr.rate_hz), tr.n_frames - 1)
            meas.append(tr.moments[skip:])
            pred.append(self.predict(tr)[skip:])
        mm, pp = np.concatenate(meas), np.concatenate(pred)
        return FitMetrics(
            coordinate_names=cn,
            r2=np.atleast_1d(compare.r2(mm, pp)),
            rms=np.atleast_1d(compare.rms(mm, pp)),
            nrms=np.atleast_1d(compare.nrmsd(mm, pp)) / 100.0,
        )

    def score(self, trials: Sequence[CalibrationTrial]) -> float:
        """Mean r² over coordinates on ``trials``."""
        return float(np.mean(self.validate(trials).r2))

    def to_profile(self) -> StrengthProfile:
        """The calibrated strength factors as a :class:`StrengthProfile` (no intervals)."""
        self._check_fitted()
        pars = self.parameters_
        g = len(self.groups)
        mf = pars.muscle_factors(self.groups)
        fgen = np.array(
            [
                sum(self.params.max_isometric_force[self.params.names.index(mn)] for mn in mem)
                for mem in self.groups.values()
            ]
        )
        groups_of = {mn: gname for gname, mem in self.groups.items() for mn in mem}
        nan = np.full(g, np.nan)
        met = self.result_.calibration if hasattr(self, "result_") else None
        r2c = met.r2 if met is not None else np.full(len(self.coordinate_names_), np.nan)
        return StrengthProfile(
            group_names=self.group_names,
            factors=np.asarray(pars.strength_factors, float),
            f_iso_generic=fgen,
            f_iso=fgen * pars.strength_factors,
            ci_low=nan,
            ci_high=nan,
            ci_cov_low=nan,
            ci_cov_high=nan,
            std_error=nan,
            identified=np.ones(g, dtype=bool),
            muscle_names=self.params.names,
            muscle_groups=tuple(groups_of.get(mn, "") for mn in self.params.names),
            muscle_factors=mf,
            muscle_f_iso=self.params.max_isometric_force * mf,
            coordinate_names=self.coordinate_names_,
            residual=np.zeros(len(self.coordinate_names_)),
            r2=float(np.mean(r2c)),
            r2_per_coordinate=r2c,
            gate_threshold=float("nan"),
            gating_r=np.zeros((0, g, len(self.coordinate_names_))),
            window_r=np.zeros((0, len(self.coordinate_names_))),
            selected=np.zeros((0, len(self.coordinate_names_)), dtype=bool),
            window_labels=np.zeros(0, dtype=np.int64),
            confidence=float("nan"),
            n_samples=int(self.result_.n_residuals) if hasattr(self, "result_") else 0,
            n_bootstrap=0,
            method=(
                "EMG-driven calibration (the EMG-driven vs OpenSim thesis §2.2.3), casadi/ipopt "
                "multi-start"
            ),
        )
