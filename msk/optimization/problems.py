"""Bounded tension QP, OpenSim-equivalent static optimisation and EMG-weighted QP.

Sign convention as in :mod:`msk.optimization.closed_form`: ``J = ∂l/∂θ`` ``(n_muscles,
n_coords)``, tensions ``f ≥ 0``, generalised force ``τ = −Jᵀ f = R f`` with ``R = −Jᵀ``.

Every problem is a frozen dataclass of one frame; :func:`solve` maps it onto the scaled
standard form of :mod:`msk.optimization._qp` (unknowns O(1): ``f/F_iso``, activations, reserve
controls), calls a registered solver (DAQP by default) and returns a :class:`QPSolution` with the
residual, the solver-independent KKT figures, the active bounds and a status. The ``*_batch``
functions take stacked arrays ``(N, n_muscles, n_coords)`` / ``(N, n_coords)`` and reuse one
DAQP workspace across frames (warm start from the previous working set).

Infeasible frames (no reserves, torque beyond the muscles' capacity) are never dropped: the
bounded least-squares point ``argmin ‖τ − R f‖ s.t. bounds`` is returned with status
``"infeasible"`` and its residual, or, with ``strict=True``, an
:class:`~msk.exceptions.OptimizationError` names the frame and the residual.
"""

from __future__ import annotations

import dataclasses
import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import OptimizationError
from msk.optimization._common import (
    as_float,
    check_finite,
    check_frame,
    check_positive,
    set_fields,
)
from msk.optimization._qp import (
    DAQP_OPTIONS,
    DEFAULT_SOLVER,
    KKT,
    KKT_CHUNK,
    KKT_COLUMNS,
    STATUS_INFEASIBLE,
    STATUS_NAMES,
    STATUS_OPTIMAL,
    STATUS_SOLVER_FAILED,
    RawResult,
    StandardQP,
    active_bounds,
    active_masks,
    get_solver,
    kkt,
    kkt_batch,
    kkt_scale,
    kkt_stacked,
    new_warm,
    solve_standard,
)
from msk.units import Array

__all__ = [
    "POWER_CURVATURE_FLOOR",
    "POWER_MAX_ITERATIONS",
    "POWER_STEP_TOL",
    "BatchSolution",
    "BoolArray",
    "EMGWeightSweep",
    "EMGWeightedProblem",
    "FrameStaticOptimization",
    "Problem",
    "QPSolution",
    "StaticOptimizationProblem",
    "TensionInequalities",
    "TensionProblem",
    "WarmStart",
    "emg_weight_sweep",
    "solve",
    "solve_emg_assisted_batch",
    "solve_emg_weighted_batch",
    "solve_static_optimization_batch",
    "solve_tension_batch",
    "volume_weights",
]

BoolArray = NDArray[np.bool_]


# ---------------------------------------------------------------------------------------------
# frame layout: standard-form unknowns  ->  forces, activations, reserves
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Layout:
    """How ``x`` maps back: ``f = scale ⊙ x[:m] + offset``, reserves ``r = x[m:]`` on ``idx``."""

    n_coords: int
    scale: Array
    offset: Array
    reserve_idx: NDArray[np.intp]
    reserve_opt: Array
    activations: bool
    objective_scale: float = 1.0
    objective_constant: float = 0.0
    #: optimal values of the reserves of :class:`TensionInequalities` rows, after the coordinate
    #: reserves in ``x`` (empty: no inequality rows)
    inequality_opt: Array = field(default_factory=lambda: np.zeros(0))

    def unpack(self, x: Array) -> tuple[Array, Array | None, Array]:
        m = self.scale.shape[0]
        f = self.scale * x[:m] + self.offset
        r = np.zeros(self.n_coords)
        r[self.reserve_idx] = x[m : m + self.reserve_idx.shape[0]]
        return f, (x[:m].copy() if self.activations else None), r

    def inequality_reserves(self, x: Array) -> Array:
        """The reserves of the inequality rows (row units), ``(k,)``."""
        k = self.inequality_opt.shape[0]
        return self.inequality_opt * x[x.shape[0] - k :] if k else np.zeros(0)


@dataclass(frozen=True)
class TensionInequalities:
    """Affine functions of the muscle tensions that must stay non-negative, per frame, each with
    a non-negative reserve that the cost penalises::

        c_k + Σ_i G_ki f_i + s_k ≥ 0,   s_k ≥ 0,   cost + Σ_k (s_k / s_opt,k)²

    e.g. the medial and lateral compartment forces of a knee, F_M(f) ≥ 0 and F_L(f) ≥ 0, in
    moment units (:func:`msk.contact.knee.compartment_force_map`: a compartment cannot pull). The
    reserve ``s_k`` carries what no admissible tension can (a frontal moment of the ligaments
    the model lacks); like a coordinate reserve of optimal force ``s_opt`` it costs
    ``(s/s_opt)²``, i.e. a reserve of ``s_opt`` costs as much as a fully active muscle.
    ``offset`` c ``(N, k)`` and ``gain`` G ``(N, k, m)`` (row units per N of tension, muscle
    columns in the problem's order) per frame; ``reserve_optimal`` ``(k,)`` or a scalar (> 0,
    row units); ``names`` one per row. A static optimisation, EMG-assisted or EMG-weighted
    batch given them adds the rows and the reserves (:class:`BatchSolution`
    ``inequality_reserves``)."""

    offset: Array
    gain: Array
    names: tuple[str, ...]
    reserve_optimal: Array | float = 1.0

    def __post_init__(self) -> None:
        c = np.asarray(self.offset, dtype=float)
        g = np.asarray(self.gain, dtype=float)
        if c.ndim != 2 or g.ndim != 3 or g.shape[:2] != c.shape:
            raise OptimizationError(
                f"inequalities: offset {c.shape} must be (N, k) and gain {g.shape} (N, k, m)"
            )
        names = tuple(str(n) for n in self.names)
        if len(names) != c.shape[1]:
            raise OptimizationError(f"{len(names)} inequality names for {c.shape[1]} rows")
        check_finite(c, "inequality offset", names)
        if not np.all(np.isfinite(g)):
            idx = tuple(int(i) for i in np.argwhere(~np.isfinite(g))[0])
            raise OptimizationError(f"inequality gain is not finite at index {idx}")
        opt = as_float(self.reserve_optimal, (c.shape[1],), "inequality reserve_optimal")
        if not np.all(np.isfinite(opt) & (opt > 0)):
            raise OptimizationError(f"inequality reserve_optimal must be > 0 and finite: {opt}")
        set_fields(self, offset=c, gain=g, names=names, reserve_optimal=opt)

    @property
    def n_rows(self) -> int:
        return int(np.asarray(self.offset).shape[1])

    def take(self, frames: slice | NDArray[np.intp]) -> TensionInequalities:
        """The rows of ``frames`` only (a slice gives views, no copy): for a batch solved in
        several calls on consecutive frames."""
        return TensionInequalities(
            np.asarray(self.offset)[frames], np.asarray(self.gain)[frames], self.names,
            self.reserve_optimal,
        )  # fmt: skip

    def check(self, n_frames: int, m: int) -> None:
        """Typed error unless the rows cover ``n_frames`` frames of ``m`` muscles."""
        g = np.asarray(self.gain)
        if g.shape[0] != n_frames or g.shape[2] != m:
            raise OptimizationError(
                f"inequality gain {g.shape} does not match {n_frames} frames × {m} muscles"
            )

    def rows(self, k: int, scale: Array, offset: Array, n_before: int) -> tuple[Array, Array]:
        """Frame ``k``'s rows on the standard-form unknowns ``x = [x_m; (n_before others);
        x_s]`` with tensions ``f = scale ⊙ x_m + offset`` and reserves ``s = s_opt ⊙ x_s``:
        ``(C, cl)`` with ``C x ≥ cl``."""
        g = np.asarray(self.gain)[k]
        opt = np.asarray(self.reserve_optimal)
        n_in, m = g.shape
        c_mat = np.zeros((n_in, m + n_before + n_in))
        c_mat[:, :m] = g * scale
        c_mat[:, m + n_before :] = np.diag(opt)
        return c_mat, -np.asarray(self.offset)[k] - g @ offset


def _reserve_forces(
    reserve_optimal_force: ArrayLike | None, n: int, names: Sequence[str] | None
) -> Array | None:
    """``reserve_optimal_force`` as a checked ``(n,)`` array (≥ 0, finite), or ``None``."""
    if reserve_optimal_force is None:
        return None
    opt = as_float(reserve_optimal_force, (n,), "reserve_optimal_force")
    if np.any(opt < 0) or not np.all(np.isfinite(opt)):
        i = int(np.argmax((opt < 0) | ~np.isfinite(opt)))
        which = repr(names[i]) if names is not None else str(i)
        raise OptimizationError(
            f"reserve optimal force of coordinate {which} must be ≥ 0 and finite: {float(opt[i])!r}"
        )
    return opt


def _reserves(
    reserve_optimal_force: ArrayLike | None, n: int, names: Sequence[str] | None
) -> tuple[NDArray[np.intp], Array]:
    """Coordinates with a reserve actuator (optimal force > 0) and their optimal forces."""
    opt = _reserve_forces(reserve_optimal_force, n, names)
    if opt is None:
        return np.zeros(0, dtype=np.intp), np.zeros(0)
    idx = np.flatnonzero(opt > 0)
    return idx, opt[idx]


def _assemble(
    r_scaled: Array,
    b: Array,
    lb_m: Array,
    ub_m: Array,
    res_idx: NDArray[np.intp],
    res_opt: Array,
    res_lb: Array,
    res_ub: Array,
    cost: tuple[Array, Array] | None = None,
) -> StandardQP:
    """``min Σx² + Σr²  s.t. [R S, E diag(opt)] [x; r] = b`` with bounds (H = 2I), or the cost
    ``(H, g)`` given (e.g. :func:`_weighted_cost`)."""
    n, m = r_scaled.shape
    k = res_idx.shape[0]
    if k:
        e = np.zeros((n, k))
        e[res_idx, np.arange(k)] = res_opt
        a = np.hstack([r_scaled, e])
        lb = np.concatenate([lb_m, res_lb])
        ub = np.concatenate([ub_m, res_ub])
    else:
        a, lb, ub = r_scaled, lb_m, ub_m
    nv = m + k
    h, g = _constant_cost(nv) if cost is None else cost
    return StandardQP(H=h, g=g, A=a, b=b, lb=lb, ub=ub)


_COST_CACHE: dict[int, tuple[Array, Array]] = {}


def _constant_cost(nv: int) -> tuple[Array, Array]:
    """``H = 2I``, ``g = 0`` as shared arrays (the same objects every frame, so the DAQP
    workspace is not re-factorised for an unchanged cost). Never modified in place (DAQP needs
    writable buffers, so they cannot be flagged read-only)."""
    if nv not in _COST_CACHE:
        _COST_CACHE[nv] = (2.0 * np.eye(nv), np.zeros(nv))
    return _COST_CACHE[nv]


def _weighted_cost(weights: Array, n_reserves: int) -> tuple[Array, Array]:
    """``H = 2 diag(w, 1…1)``, ``g = 0``: the cost ``Σ w_i x_i² + Σ r_j²``."""
    return np.diag(2.0 * np.concatenate([weights, np.ones(n_reserves)])), np.zeros(
        weights.shape[0] + n_reserves
    )


#: SQP of the power criterion: step tolerance (scaled unknowns) and iteration limit
POWER_STEP_TOL = 1e-10
POWER_MAX_ITERATIONS = 100
#: smallest activation at which the curvature of w a^p is evaluated (keeps H > 0 at a = 0)
POWER_CURVATURE_FLOOR = 1e-3


def _power_cost(x: Array, m: int, w: Array, p: float) -> float:
    """``Σ w_i a_i^p + Σ r_j²`` of the standard-form unknowns ``x = [a; r]`` (a ≥ 0)."""
    return float(np.sum(w * np.maximum(x[:m], 0.0) ** p) + np.sum(x[m:] ** 2))


def _power_model(qp: StandardQP, x: Array, m: int, w: Array, p: float) -> StandardQP:
    """Second-order model at ``x`` of ``Σ w_i a_i^p + Σ r_j²`` on the constraints of ``qp``:
    ``H_ii = w_i p (p−1) max(a_i, ε)^(p−2)``, ``g = ∇F(x) − H x`` (its gradient at ``x`` is the
    true gradient, so a fixed point of the model is a KKT point of the power criterion)."""
    a = np.maximum(x[:m], 0.0)
    curv = w * p * (p - 1.0) * np.maximum(a, POWER_CURVATURE_FLOOR) ** (p - 2.0)
    hd = np.concatenate([curv, np.full(x.shape[0] - m, 2.0)])
    grad = np.concatenate([w * p * a ** (p - 1.0), 2.0 * x[m:]])
    return dataclasses.replace(qp, H=np.diag(hd), g=grad - hd * x)


def _solve_power(
    qp: StandardQP,
    m: int,
    w: Array,
    p: float,
    *,
    solver: str,
    warm: Any,
    compute_kkt: bool,
    frame: int | None,
    strict: bool,
) -> tuple[RawResult, Any]:
    """``min Σ w_i a_i^p + Σ r_j²`` on the constraints of ``qp`` (its Σ w a² form) by sequential
    QP: start at the p = 2 optimum, solve the second-order model (:func:`_power_model`) with
    ``solver``, backtrack along the step (Armijo; the feasible set is convex, so every point of
    the step is feasible) until the step is below :data:`POWER_STEP_TOL`. The KKT figures are
    those of the model at the returned point, i.e. of the power criterion itself. A frame whose
    p = 2 problem is infeasible keeps its bounded least-squares point and status."""
    raw, warm = solve_standard(
        qp, solver=solver, warm=warm, compute_kkt=compute_kkt, frame=frame, strict=strict
    )
    if raw.status != STATUS_OPTIMAL:
        return raw, warm
    x, iters, status = raw.x, raw.iterations, raw.status
    t0 = raw.solve_time_s
    for _ in range(POWER_MAX_ITERATIONS):
        model = _power_model(qp, x, m, w, p)
        sub, warm = solve_standard(model, solver=solver, warm=warm, compute_kkt=False)
        iters += max(sub.iterations, 0)
        t0 += sub.solve_time_s
        if sub.status != STATUS_OPTIMAL:
            status = sub.status
            break
        d = sub.x - x
        f0 = _power_cost(x, m, w, p)
        slope = float((model.g + model.H @ x) @ d)  # ∇F(x)·d < 0 unless converged
        # Armijo, with a round-off allowance so that the (quadratically convergent) full
        # Newton steps are taken near the optimum, where the decrease is below machine precision
        tol_f = 1e-14 * (1.0 + abs(f0))
        alpha = 1.0
        while (
            alpha > 1e-12
            and _power_cost(x + alpha * d, m, w, p) > f0 + 1e-4 * alpha * slope + tol_f
        ):
            alpha *= 0.5
        x = np.minimum(np.maximum(x + alpha * d, qp.lb), qp.ub)
        if float(np.max(np.abs(d), initial=0.0)) <= POWER_STEP_TOL:
            break
    else:
        status = STATUS_SOLVER_FAILED
    if strict and status != STATUS_OPTIMAL:
        where = f"frame {frame}" if frame is not None else "the frame"
        raise OptimizationError(
            f"{where}: power criterion (p = {p:g}) did not converge with solver {solver!r}"
        )
    pm = _power_model(qp, x, m, w, p) if compute_kkt else None
    res = RawResult(
        x=x,
        status=status,
        iterations=iters,
        solve_time_s=t0,
        kkt=None if pm is None else kkt(pm, x),
        kkt_scale=None if pm is None else kkt_scale(pm, x),
    )
    return res, warm


# ---------------------------------------------------------------------------------------------
# problems
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TensionProblem:
    """Bounded tension QP of one frame (the criterion of the rehabilitation-robot lower-limb model
    paper, with bounds)::

        minimise   Σ_i (f_i / F_iso,i)²  +  Σ_j r_j²
        subject to R f + diag(F_res) r = τ,     f_min ≤ f ≤ f_max

    ``f_max`` defaults to ``F_iso`` (pass ``F_iso·f_l·f_v`` for a length/velocity-dependent
    capacity), ``f_min`` to 0. ``reserve_optimal_force`` ``(n_coords,)`` adds a coordinate
    actuator of torque ``F_res,j · r_j`` wherever it is > 0: OpenSim-style reserves whose cost
    ``r_j²`` is small only when ``F_res,j`` is large, so a reserve of 1 N·m costs a torque of
    1 N·m as much as a fully active muscle; with unbounded reserves every frame is feasible.
    """

    jacobian: Array
    tau: Array
    f_iso: Array
    f_max: Array | None = None
    f_min: Array | None = None
    reserve_optimal_force: Array | None = None
    muscle_names: tuple[str, ...] | None = None
    coordinate_names: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        j, tau, mn, cn = check_frame(
            self.jacobian, self.tau, self.muscle_names, self.coordinate_names
        )
        m, n = j.shape
        f_iso = as_float(self.f_iso, (m,), "f_iso")
        check_positive(f_iso, "f_iso", mn)
        f_max = f_iso.copy() if self.f_max is None else as_float(self.f_max, (m,), "f_max")
        f_min = np.zeros(m) if self.f_min is None else as_float(self.f_min, (m,), "f_min")
        _check_bounds(f_min, f_max, "force", mn)
        set_fields(
            self,
            jacobian=j,
            tau=tau,
            f_iso=f_iso,
            f_max=f_max,
            f_min=f_min,
            reserve_optimal_force=_reserve_forces(self.reserve_optimal_force, n, cn),
            muscle_names=mn,
            coordinate_names=cn,
        )

    def standard_form(self) -> tuple[StandardQP, _Layout]:
        assert self.f_max is not None and self.f_min is not None
        idx, opt = _reserves(self.reserve_optimal_force, self.tau.shape[0], self.coordinate_names)
        return _tension_qp(-self.jacobian.T, self.tau, self.f_iso, self.f_min, self.f_max, idx, opt)


def _tension_qp(
    r: Array,
    tau: Array,
    f_iso: Array,
    f_min: Array,
    f_max: Array,
    idx: NDArray[np.intp],
    opt: Array,
) -> tuple[StandardQP, _Layout]:
    k = idx.shape[0]
    inf = np.full(k, np.inf)
    qp = _assemble(r * f_iso, tau, f_min / f_iso, f_max / f_iso, idx, opt, -inf, inf)
    lay = _Layout(tau.shape[0], f_iso, np.zeros_like(f_iso), idx, opt, activations=False)
    return qp, lay


@dataclass(frozen=True)
class StaticOptimizationProblem:
    """OpenSim's StaticOptimization (``use_muscle_physiology = true``, exponent 2), one frame::

        minimise   Σ_i a_i²  +  Σ_j r_j²
        subject to Σ_i R_ji (a_i F_act,i + F_pass,i) + F_res,j r_j = τ_j
                   a_min ≤ a ≤ a_max,   r_min ≤ r ≤ r_max

    ``f_active`` is OpenSim's ``calcInextensibleTendonActiveFiberForce(s, 1.0)``: the active
    fibre force along the tendon at full activation with a rigid tendon,
    ``F_iso · f_l(l̃_M) · f_v(ṽ_M) · cos α`` (from the Hill model:
    ``msk.muscles.hill.rigid_tendon_state(...).max_active_force_along_tendon``; its
    ``passive_force_along_tendon`` is the ``f_passive`` of the variant below).
    Subtleties of OpenSim's implementation (``StaticOptimizationTarget``) this reproduces:

    * the objective sums ``|x|²`` over **all** actuators, muscles and residual/reserve
      ``CoordinateActuator`` alike; a reserve's price is set only by its ``optimal_force``;
    * each actuator's force is *overridden* by ``x · F_opt``, so OpenSim's SO has **no passive
      fibre force**: to reproduce it leave ``f_passive`` at 0. A non-zero ``f_passive``
      (``F_iso f_PE cos α`` from the Hill model) is the common "SO with passive forces" variant;
    * the bounds are the actuators' ``min_control``/``max_control``: gait2392's muscles use
      ``[0.01, 1]``, not ``[0, 1]``; residuals are often unbounded;
    * OpenSim imposes the equality in acceleration space, ``q̈_target − q̈(x) = 0``, i.e.
      ``M⁻¹(τ_act(x) − τ)`` = 0 for the unconstrained coordinates; with ``M`` invertible this is
      the same feasible set, hence the same optimum, as the torque equality used here, whose
      ``τ`` is the inverse-dynamics result on the same (filtered) kinematics;
    * OpenSim uses IPOPT with a convergence tolerance (default 1e-4), so its activations agree
      with this exact QP to about that tolerance, and it keeps the last iterate when IPOPT fails.
    * coordinates crossed by no actuator but the muscles decouple: in gait2392 the pelvis
      residuals act on the pelvis coordinates only, so the right-leg rows form their own QP.

    Checked against OpenSim 4.6 on gait2392 subject01 walking
    (``tests/optimization/test_optimization.py``,
    13 frames, 43 right-leg muscles × 7 coordinates, same states, ``f_passive = 0``):
    activations agree to 0.005 max / 0.0008 RMS and msk's cost is never above OpenSim's
    (≈ 3e-4 lower: IPOPT's tolerance).

    **Other criteria** (muscles only; reserves keep ``r_j²``): ``minimise Σ_i w_i a_i^p + Σ_j
    r_j²`` with ``activation_weights`` ``w`` (default 1) and ``activation_exponent`` ``p ≥ 2``
    (default 2, the criterion above):

    * ``w_i = V_i`` (muscle volume, ∝ ``F_iso,i · l_opt,i``), p = 2: the volume-weighted
      activation criterion of Happee (1994, J Biomech 27:953) and Happee & Van der Helm (1995,
      J Biomech 28:1179) — a proxy of metabolic energy, which penalises large muscles;
    * p = 3: the "maximum endurance" criterion of Crowninshield & Brand (1981, J Biomech
      14:793), Σ (f_i / PCSA_i)³, written in activations as OpenSim's
      ``activation_exponent = 3``. It shares the load more evenly between synergists.

    p = 2 stays one QP (``H = 2 diag(w)``). p > 2 is convex but not quadratic: it is solved by
    sequential QP with the same solver (:func:`_solve_power`: second-order model
    ``H = diag(w p (p−1) a^(p−2))``, Armijo backtracking, from the p = 2 optimum), and the KKT
    figures are those of the power criterion at the returned point.
    """

    jacobian: Array
    tau: Array
    f_active: Array
    f_passive: Array | None = None
    activation_min: Array | float = 0.0
    activation_max: Array | float = 1.0
    reserve_optimal_force: Array | None = None
    reserve_min_control: Array | float = -np.inf
    reserve_max_control: Array | float = np.inf
    muscle_names: tuple[str, ...] | None = None
    coordinate_names: tuple[str, ...] | None = None
    activation_weights: Array | None = None
    activation_exponent: float = 2.0

    def __post_init__(self) -> None:
        j, tau, mn, cn = check_frame(
            self.jacobian, self.tau, self.muscle_names, self.coordinate_names
        )
        m, n = j.shape
        w = _activation_weights(self.activation_weights, m, mn)
        _check_exponent(self.activation_exponent)
        fa = as_float(self.f_active, (m,), "f_active")
        check_finite(fa, "f_active", mn)
        if np.any(fa < 0):
            i = int(np.argmax(fa < 0))
            raise OptimizationError(f"f_active of muscle {mn[i]!r} is negative: {float(fa[i])!r}")
        fp = np.zeros(m) if self.f_passive is None else as_float(self.f_passive, (m,), "f_passive")
        check_finite(fp, "f_passive", mn)
        amin = as_float(self.activation_min, (m,), "activation_min")
        amax = as_float(self.activation_max, (m,), "activation_max")
        _check_bounds(amin, amax, "activation", mn)
        ropt = _reserve_forces(self.reserve_optimal_force, n, cn)
        rmin = as_float(self.reserve_min_control, (n,), "reserve_min_control")
        rmax = as_float(self.reserve_max_control, (n,), "reserve_max_control")
        set_fields(
            self,
            jacobian=j,
            tau=tau,
            f_active=fa,
            f_passive=fp,
            activation_min=amin,
            activation_max=amax,
            reserve_optimal_force=ropt,
            reserve_min_control=rmin,
            reserve_max_control=rmax,
            muscle_names=mn,
            coordinate_names=cn,
            activation_weights=w,
            activation_exponent=float(self.activation_exponent),
        )

    def standard_form(self) -> tuple[StandardQP, _Layout]:
        """The QP of ``Σ w_i a_i² + Σ r_j²`` (the problem itself when p = 2; the start and the
        constraints of the sequential QP when p > 2)."""
        assert self.f_passive is not None and self.coordinate_names is not None
        idx, opt = _reserves(self.reserve_optimal_force, self.tau.shape[0], self.coordinate_names)
        cost = None
        if self.activation_weights is not None:
            cost = _weighted_cost(self.activation_weights, idx.shape[0])
        return _static_qp(
            -self.jacobian.T,
            self.tau,
            self.f_active,
            self.f_passive,
            np.asarray(self.activation_min),
            np.asarray(self.activation_max),
            idx,
            opt,
            np.asarray(self.reserve_min_control)[idx],
            np.asarray(self.reserve_max_control)[idx],
            cost,
        )


class FrameStaticOptimization:
    """:class:`StaticOptimizationProblem` (exponent 2) of one frame at a time, warm-started from
    the previous frame's working set (a stream: :mod:`msk.live`)::

        minimise   Σ_i w_i a_i² + Σ_j r_j²
        subject to Σ_i R_ji (a_i F_act,i + F_pass,i) + F_res,j r_j = τ_j,   a_min ≤ a ≤ a_max

    The QP of :meth:`StaticOptimizationProblem.standard_form` (the same cost, bounds and
    reserve columns, built once here; per frame only the muscle columns R F_act and the
    right-hand side τ − R F_pass change, written into buffers) solved whole by ``solver``
    with the solver's warm start carried (:func:`new_warm`). The batch
    (:func:`solve_static_optimization_batch`) splits the same QP into its independent blocks:
    the same optimum to round-off (tested).

    Args:
        muscle_names, coordinate_names: the columns of the Jacobians and torques given to
            :meth:`solve`.
        activation_weights, reserve_optimal_force, activation_min, activation_max,
        reserve_min_control, reserve_max_control, solver: as
            :class:`StaticOptimizationProblem`'s (reserves default to 1 on every coordinate).
    """

    def __init__(
        self,
        muscle_names: Sequence[str],
        coordinate_names: Sequence[str],
        *,
        activation_weights: ArrayLike | None = None,
        reserve_optimal_force: ArrayLike | None = None,
        activation_min: ArrayLike = 0.0,
        activation_max: ArrayLike = 1.0,
        reserve_min_control: ArrayLike = -np.inf,
        reserve_max_control: ArrayLike = np.inf,
        solver: str = DEFAULT_SOLVER,
    ) -> None:
        self.muscle_names, self.coordinate_names = tuple(muscle_names), tuple(coordinate_names)
        m, n = len(self.muscle_names), len(self.coordinate_names)
        ropt = np.ones(n) if reserve_optimal_force is None else reserve_optimal_force
        idx, opt = _reserves(ropt, n, self.coordinate_names)
        k = idx.shape[0]
        w = _activation_weights(activation_weights, m, self.muscle_names)
        self.h, self.g = _constant_cost(m + k) if w is None else _weighted_cost(w, k)
        amin = np.broadcast_to(np.asarray(activation_min, dtype=float), (m,))
        amax = np.broadcast_to(np.asarray(activation_max, dtype=float), (m,))
        rmin = np.broadcast_to(np.asarray(reserve_min_control, dtype=float), (n,))[idx]
        rmax = np.broadcast_to(np.asarray(reserve_max_control, dtype=float), (n,))[idx]
        self.lb = np.concatenate([amin, rmin])
        self.ub = np.concatenate([amax, rmax])
        self.a = np.zeros((n, m + k))
        self.a[idx, m + np.arange(k)] = opt
        # DAQP's bounds, the variables' then the equality rows' (b written into both)
        self._bu = np.concatenate([self.ub, np.empty(n)])
        self._bl = np.concatenate([self.lb, np.empty(n)])
        self.b = self._bu[m + k :]
        self._bl_b = self._bl[m + k :]
        self._sense = np.zeros(m + k + n, dtype=np.int32)
        self._sense[m + k :] = 5  # ACTIVE + IMMUTABLE: equality (as msk.optimization._qp)
        self.m = m
        self.spec = get_solver(solver)
        self.warm = new_warm(solver)
        self._daqp: Any = None
        if solver == "daqp":
            import daqp

            self._daqp = daqp
        self.forces = np.empty(m)
        self.activations = np.empty(m)

    def solve(
        self, jacobian: Array, tau: Array, f_active: Array, f_passive: Array
    ) -> tuple[Array, Array, int]:
        """Forces (m,), activations (m,) and the status (:data:`STATUS_OPTIMAL`, …) of one
        frame: ``jacobian`` (m, n) = ∂l/∂θ, ``tau`` (n,), the force curves (m,). The returned
        arrays are this object's buffers (NaN when not solved), overwritten by the next call."""
        m = self.m
        r = jacobian.T  # R = −∂l/∂θᵀ: the signs folded into the products below
        np.multiply(r, f_active, out=self.a[:, :m])
        np.negative(self.a[:, :m], out=self.a[:, :m])
        np.add(tau, r @ f_passive, out=self.b)
        if self._daqp is not None:
            x, ok, infeasible = self._solve_daqp()
        else:
            qp = StandardQP(H=self.h, g=self.g, A=self.a, b=self.b, lb=self.lb, ub=self.ub)
            out = self.spec.solve(qp, self.warm)
            self.warm = out.warm
            x, ok, infeasible = out.x, out.ok, out.infeasible
        if not ok or x is None:
            self.forces[:] = np.nan
            self.activations[:] = np.nan
            return (
                self.forces,
                self.activations,
                (STATUS_INFEASIBLE if infeasible else STATUS_SOLVER_FAILED),
            )
        np.copyto(self.activations, x[:m])
        np.multiply(f_active, self.activations, out=self.forces)
        self.forces += f_passive
        return self.forces, self.activations, STATUS_OPTIMAL

    def _solve_daqp(self) -> tuple[Array | None, bool, bool]:
        """The registered DAQP solve (:func:`msk.optimization._qp._solve_daqp`: the same data,
        settings, warm start and fallbacks) on this object's buffers: the workspace kept in
        ``warm.model`` is updated with the frame's A and bounds (H and g are constant), a
        failed update or solve drops it (a cold solve; the next frame sets it up afresh).
        Returns x, whether it solved, whether DAQP found the frame infeasible."""
        daqp, warm = self._daqp, self.warm
        bu, bl = self._bu, self._bl
        np.copyto(self._bl_b, self.b)
        if warm.model is not None:
            if warm.model.update(None, None, self.a, bu, bl) < 0:
                warm.model = None  # the update found the frame infeasible: solve it cold
        else:
            warm.model = daqp.Model()
            warm.model.settings = DAQP_OPTIONS
            if warm.model.setup(self.h, self.g, self.a, bu, bl, self._sense.copy())[0] < 0:
                warm.model = None
            warm.shape = (self.lb.size, self.b.size, 0)
        warm.h, warm.g = self.h, self.g
        if warm.model is not None:
            x, _, flag, _ = warm.model.solve()
            if flag < 0:  # do not carry a failed working set into the next frame
                warm.model = None
        else:
            x, _, flag, _ = daqp.solve(
                self.h, self.g, self.a, bu, bl, self._sense.copy(), **DAQP_OPTIONS
            )
        return (x if flag > 0 else None), flag > 0, flag == -1


def volume_weights(max_isometric_force: ArrayLike, optimal_fiber_length: ArrayLike) -> Array:
    """Activation weights ``w_i = V_i / mean(V)`` of the volume-weighted criterion ``Σ V_i a_i²``
    (Happee 1994; :class:`StaticOptimizationProblem`, "Other criteria").

    Muscle volume ``V_i = PCSA_i · l_opt,i = F_iso,i · l_opt,i / σ`` with one specific tension
    σ for all muscles, so ``V_i ∝ F_iso,i · l_opt,i``; the weights are normalised to mean 1
    (only their ratios change the optimum)."""
    f_iso = np.asarray(max_isometric_force, dtype=float)
    l_opt = np.asarray(optimal_fiber_length, dtype=float)
    if f_iso.shape != l_opt.shape or f_iso.ndim != 1:
        raise OptimizationError(
            f"volume_weights: max_isometric_force {f_iso.shape} and optimal_fiber_length "
            f"{l_opt.shape} should be (n_muscles,) arrays"
        )
    vol = f_iso * l_opt
    if not (np.all(np.isfinite(vol)) and np.all(vol > 0)):
        k = int(np.flatnonzero(~(np.isfinite(vol) & (vol > 0)))[0])
        raise OptimizationError(f"volume_weights: muscle {k} has F_iso·l_opt = {float(vol[k])!r}")
    return vol / vol.mean()


def _activation_weights(weights: ArrayLike | None, m: int, names: Sequence[str]) -> Any:
    """``activation_weights`` as a checked ``(m,)`` array (> 0, finite), or ``None``."""
    if weights is None:
        return None
    w = as_float(weights, (m,), "activation_weights")
    check_finite(w, "activation_weights", names)
    check_positive(w, "activation_weights", names)
    return w


def _check_exponent(p: float) -> None:
    if not (np.isfinite(p) and p >= 2.0):
        raise OptimizationError(f"activation_exponent must be finite and ≥ 2: {p!r}")


def _static_qp(
    r: Array,
    tau: Array,
    fa: Array,
    fp: Array,
    amin: Array,
    amax: Array,
    idx: NDArray[np.intp],
    opt: Array,
    rmin: Array,
    rmax: Array,
    cost: tuple[Array, Array] | None = None,
) -> tuple[StandardQP, _Layout]:
    qp = _assemble(r * fa, tau - r @ fp, amin, amax, idx, opt, rmin, rmax, cost)
    return qp, _Layout(tau.shape[0], fa, fp, idx, opt, activations=True)


@dataclass(frozen=True)
class EMGWeightedProblem:
    """EMG-weighted tension optimisation of one frame (Hayashibe et al. 2011, Eq. 17–18)::

        minimise   ½‖τ − R f‖²  +  (W_emg/2) Σ_{i measured} (f_i − f*_i)²  +  (ε/2) Σ_{i ∉ M} f_i²
        subject to f ≥ f_min (= 0),  f ≤ f_max (optional)

    Hayashibe et al. 2011 writes ``Z = ½‖τ − Jᵀf‖² + (W_emg/2)‖f − f*‖²`` subject to ``E_t f ≤ 0``
    (Eq. 18), with ``f`` along muscle lengthening: tensions are non-positive there. With the
    msk convention (``f`` = tension, ``τ = −Jᵀ f``) the same problem reads as above with
    ``f ≥ 0``. ``f*`` (``f_ref``) is the EMG-based reference force of Eq. 9
    (``a f_l f_v F_iso``), known only for the ``measured`` muscles. ``W_emg`` has the units of
    ``R``² (m² for rotations) when ``f`` is in N and ``τ`` in N·m.

    The Hessian ``RᵀR + W_emg E_M`` is singular when there are more unmeasured muscles than
    coordinates, so the optimum of Eq. 17 is not unique; the Tikhonov term ``ε/2 Σ f_i²`` on
    the unmeasured muscles (on all muscles when ``W_emg = 0``) makes it strictly convex and
    picks the smallest such forces. ``ε = regularization · mean_i ‖R_:,i‖²`` (default
    ``regularization = 1e-6``) biases the forces by about that relative amount.
    """

    jacobian: Array
    tau: Array
    f_ref: Array
    measured: NDArray[np.bool_]
    w_emg: float
    f_max: Array | None = None
    f_min: Array | None = None
    regularization: float = 1e-6
    muscle_names: tuple[str, ...] | None = None
    coordinate_names: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        j, tau, mn, cn = check_frame(
            self.jacobian, self.tau, self.muscle_names, self.coordinate_names
        )
        m = j.shape[0]
        meas = _measured_mask(self.measured, m)
        fr = as_float(self.f_ref, (m,), "f_ref")
        fr = np.where(meas, fr, 0.0)
        check_finite(fr, "f_ref", mn)
        fmax = np.full(m, np.inf) if self.f_max is None else as_float(self.f_max, (m,), "f_max")
        fmin = np.zeros(m) if self.f_min is None else as_float(self.f_min, (m,), "f_min")
        _check_bounds(fmin, fmax, "force", mn)
        _check_weights(self.w_emg, self.regularization)
        set_fields(
            self,
            jacobian=j,
            tau=tau,
            f_ref=fr,
            measured=meas,
            f_max=fmax,
            f_min=fmin,
            w_emg=float(self.w_emg),
            regularization=float(self.regularization),
            muscle_names=mn,
            coordinate_names=cn,
        )

    def standard_form(self) -> tuple[StandardQP, _Layout]:
        assert self.f_min is not None and self.f_max is not None
        return _emg_qp(
            -self.jacobian.T,
            self.tau,
            self.f_ref,
            self.measured,
            self.w_emg,
            self.regularization,
            self.f_min,
            self.f_max,
            _emg_scale(self.f_ref, self.f_max, self.measured),
        )


def _measured_mask(measured: ArrayLike, m: int) -> BoolArray:
    meas = np.asarray(measured)
    if meas.dtype != bool:
        idx = meas.astype(int).ravel()
        if np.any((idx < 0) | (idx >= m)):
            raise OptimizationError(f"measured muscle index out of range 0..{m - 1}: {idx}")
        mask = np.zeros(m, dtype=bool)
        mask[idx] = True
        return mask
    if meas.shape != (m,):
        raise OptimizationError(f"measured mask has shape {meas.shape}, expected ({m},)")
    return meas.copy()


def _check_weights(w_emg: float, regularization: float) -> None:
    if not (np.isfinite(w_emg) and w_emg >= 0):
        raise OptimizationError(f"w_emg must be finite and ≥ 0: {w_emg!r}")
    if not (np.isfinite(regularization) and regularization > 0):
        raise OptimizationError(f"regularization must be finite and > 0: {regularization!r}")


def _check_bounds(lo: Array, hi: Array, what: str, names: Sequence[str]) -> None:
    bad = ~(lo <= hi) | np.isnan(lo) | np.isnan(hi)
    if bad.any():
        i = int(np.argmax(bad))
        raise OptimizationError(
            f"{what} bounds of muscle {names[i]!r} are inconsistent: "
            f"min {float(lo[i])!r} > max {float(hi[i])!r}"
        )


def _emg_scale(f_ref: Array, f_max: Array, measured: BoolArray) -> Array:
    """Per-muscle force scale (N) so that the scaled unknowns are O(1)."""
    fin = np.isfinite(f_max) & (f_max > 0)
    base = max(1.0, float(np.max(np.abs(f_ref[measured]))) if measured.any() else 1.0)
    return np.where(fin, f_max, base)


def _emg_qp(
    r: Array,
    tau: Array,
    f_ref: Array,
    measured: BoolArray,
    w_emg: float,
    regularization: float,
    f_min: Array,
    f_max: Array,
    scale: Array,
) -> tuple[StandardQP, _Layout]:
    m = f_ref.shape[0]
    rs = r * scale
    eps = regularization * float(np.mean(np.sum(r * r, axis=0)))
    if eps <= 0:
        eps = regularization
    wdiag = np.where(measured, w_emg, eps) if w_emg > 0 else np.full(m, eps)
    h = rs.T @ rs + np.diag(wdiag * scale * scale)
    g = -(rs.T @ tau) - np.where(measured, w_emg, 0.0) * scale * f_ref
    c = float(np.max(np.diag(h)))
    c = c if c > 0 else 1.0
    qp = StandardQP(
        H=h / c,
        g=g / c,
        A=np.zeros((0, m)),
        b=np.zeros(0),
        lb=f_min / scale,
        ub=f_max / scale,
    )
    lay = _Layout(
        tau.shape[0],
        scale,
        np.zeros(m),
        np.zeros(0, dtype=np.intp),
        np.zeros(0),
        activations=False,
        objective_scale=c,
        objective_constant=0.5 * float(tau @ tau)
        + 0.5 * w_emg * float(np.sum(f_ref[measured] ** 2)),
    )
    return qp, lay


Problem = TensionProblem | StaticOptimizationProblem | EMGWeightedProblem


# ---------------------------------------------------------------------------------------------
# solutions
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class QPSolution:
    """Solution of one frame.

    ``forces`` (N) ``(n_muscles,)``; ``activations`` for static optimisation, else ``None``;
    ``reserve_controls`` ``(n_coords,)`` (0 where no reserve) and ``reserve_torques`` =
    ``F_res ⊙ r``; ``torque_error`` = ``τ − R f`` (muscles only, N·m or N) and ``residual`` =
    ``τ − R f − F_res ⊙ r`` (the equality constraint; for the EMG-weighted QP, where the torque
    is a penalty, both are ``τ − R f``); ``residual_norm`` = ``‖residual‖``; ``objective`` the
    problem's cost at the solution, in its own units (Eq. 17 value, incl. the ε term, for the
    EMG-weighted QP); ``kkt`` the
    solver-independent KKT figures in the scaled standard form; ``active_lower`` /
    ``active_upper`` the muscle bounds active at the solution; ``status`` ``"optimal"``,
    ``"infeasible"`` (bounded least-squares point returned) or ``"solver_failed"``.
    """

    forces: Array
    activations: Array | None
    reserve_controls: Array
    reserve_torques: Array
    torque_error: Array
    residual: Array
    residual_norm: float
    objective: float
    kkt: KKT
    active_lower: BoolArray
    active_upper: BoolArray
    solver: str
    status: str
    iterations: int
    solve_time_s: float
    muscle_names: tuple[str, ...]
    coordinate_names: tuple[str, ...]


def solve(
    problem: Problem,
    *,
    solver: str = DEFAULT_SOLVER,
    strict: bool = False,
    frame: int | None = None,
) -> QPSolution:
    """Solve one frame of any problem of this module with a registered solver (a power
    criterion, ``activation_exponent > 2``, by sequential QP with that solver)."""
    qp, lay = problem.standard_form()
    power = _power_of(problem)
    if power is None:
        raw, _ = solve_standard(qp, solver=solver, compute_kkt=True, frame=frame, strict=strict)
    else:
        raw, _ = _solve_power(
            qp, *power, solver=solver, warm=None, compute_kkt=True, frame=frame, strict=strict
        )
    assert raw.kkt is not None
    f, act, rc = lay.unpack(raw.x)
    r = -problem.jacobian.T
    terr = problem.tau - r @ f
    rt = np.zeros_like(rc)
    rt[lay.reserve_idx] = lay.reserve_opt * rc[lay.reserve_idx]
    resid = terr - rt
    lo, up = active_bounds(qp, raw.x)
    m = f.shape[0]
    if power is None:
        obj = (
            lay.objective_scale * float(0.5 * raw.x @ qp.H @ raw.x + qp.g @ raw.x)
            + lay.objective_constant
        )
    else:
        obj = _power_cost(raw.x, *power)
    assert problem.muscle_names is not None and problem.coordinate_names is not None
    return QPSolution(
        forces=f,
        activations=act,
        reserve_controls=rc,
        reserve_torques=rt,
        torque_error=terr,
        residual=resid,
        residual_norm=float(np.linalg.norm(resid)),
        objective=obj,
        kkt=raw.kkt,
        active_lower=lo[:m],
        active_upper=up[:m],
        solver=solver,
        status=STATUS_NAMES[raw.status],
        iterations=raw.iterations,
        solve_time_s=raw.solve_time_s,
        muscle_names=problem.muscle_names,
        coordinate_names=problem.coordinate_names,
    )


def _power_of(problem: Problem) -> tuple[int, Array, float] | None:
    """``(m, w, p)`` of a static optimisation with ``activation_exponent > 2``, else None."""
    if not isinstance(problem, StaticOptimizationProblem) or problem.activation_exponent == 2.0:
        return None
    m = problem.f_active.shape[0]
    w = np.ones(m) if problem.activation_weights is None else problem.activation_weights
    return m, w, problem.activation_exponent


@dataclass(frozen=True)
class BatchSolution:
    """Per-frame solutions stacked over time (axis 0); fields as in :class:`QPSolution`.

    ``status`` ``(N,)`` int8 codes (0 optimal, 1 infeasible, 2 solver failed; names in
    ``STATUS_NAMES``); ``kkt`` ``(N, 4)`` with columns ``kkt_columns`` (NaN without
    ``compute_kkt``) and ``kkt_scale`` the magnitudes they are judged against; ``solve_time_s`` per
    frame (solver call, incl. fallback); ``time`` optional frame times in s;
    ``inequality_reserves`` ``(N, k)`` the reserves ``s_k`` of :class:`TensionInequalities`
    rows (row units, ``inequality_names``), None when the batch had none.
    """

    forces: Array
    activations: Array | None
    reserve_controls: Array
    reserve_torques: Array
    torque_error: Array
    residual: Array
    residual_norm: Array
    kkt: Array
    active_lower: BoolArray
    active_upper: BoolArray
    status: NDArray[np.int8]
    iterations: NDArray[np.int64]
    solve_time_s: Array
    solver: str
    muscle_names: tuple[str, ...]
    coordinate_names: tuple[str, ...]
    time: Array | None = None
    kkt_columns: tuple[str, ...] = KKT_COLUMNS
    status_names: tuple[str, ...] = STATUS_NAMES
    #: ``(N, k)`` reserves of the :class:`TensionInequalities` rows (row units; None without)
    inequality_reserves: Array | None = None
    inequality_names: tuple[str, ...] = ()
    #: ``(N, 4)`` the magnitudes the ``kkt`` figures are judged against
    #: (:func:`~msk.optimization.kkt_scale`; NaN where ``kkt`` is)
    kkt_scale: Array | None = None

    @property
    def infeasible_frames(self) -> NDArray[np.intp]:
        """Indices of the frames that are not optimal (reported, never dropped)."""
        return np.flatnonzero(self.status != STATUS_OPTIMAL)


# ---------------------------------------------------------------------------------------------
# batches: per-batch buffers, decoupled reserves
# ---------------------------------------------------------------------------------------------


#: The solver with which decoupled reserves leave the batch QPs: DAQP's active-set solution is
#: exact to round-off, so the reduced QP gives the same solution; an iterative solver (OSQP,
#: Clarabel) would stop elsewhere inside its tolerance, so it keeps solving the whole QP.
_EXACT_SOLVER = "daqp"


def _decoupled_reserves(
    jac: Array,
    tau: Array,
    idx: NDArray[np.intp],
    opt: Array,
    lo: Array,
    hi: Array,
) -> BoolArray:
    """Mask over the reserves ``idx`` that can leave the QP of every frame of a batch.

    A reserve decouples when no muscle crosses its coordinate (that column of every frame's
    Jacobian is exactly 0, e.g. gait2392's pelvis residuals): its equality row then reads
    ``opt_j r_j = τ_j`` alone, so ``r_j = τ_j / opt_j`` at the optimum whatever the muscles do,
    and the muscles' QP is the same without that row and column. This holds only while
    ``τ_j / opt_j`` lies inside the reserve's control bounds ``lo``/``hi`` (``(k,)`` or
    ``(N, k)``) in every frame (always, when they are infinite); otherwise the reserve stays."""
    if idx.size == 0:
        return np.zeros(0, dtype=bool)
    free = np.array([not jac[:, :, c].any() for c in idx])  # one strided pass per column
    vals = tau[:, idx] / opt
    inside = np.all((vals >= lo) & (vals <= hi), axis=0)
    return free & inside


@dataclass(frozen=True)
class _Reduction:
    """How a batch's reduced QPs (decoupled reserves left out, :class:`_BatchQP`) map back.

    ``expand`` puts the dropped reserves' controls (``values`` ``(N, d)``) into the reduced
    solution, giving the ``x`` of the whole QP (muscles, then every reserve in coordinate
    order, then the reserves of inequality rows, which ``kept`` lists last); ``full(k)`` is
    the whole QP of frame ``k``, for its KKT figures and for a frame that is not optimal
    (solved whole, so that its bounded least-squares point is unchanged)."""

    kept: NDArray[np.intp]
    dropped: NDArray[np.intp]
    values: Array
    full: Callable[[int], StandardQP]

    def expand(self, x: Array, k: int) -> Array:
        m = x.shape[0] - self.kept.shape[0]
        xf = np.empty(m + self.kept.shape[0] + self.dropped.shape[0])
        xf[:m] = x[:m]
        xf[self.kept] = x[m:]
        xf[self.dropped] = self.values[k]
        return xf


#: Sub-problems with fewer unknowns than this are merged with another one (one DAQP call per
#: sub-problem and frame costs a few µs of Python, more than a small QP saves)
_MIN_BLOCK_UNKNOWNS = 16
#: Frames whose sub-problems are assembled at once (bounds the memory of long trials)
_BLOCK_CHUNK = 512


def _nonzero_pattern(jac: Array) -> BoolArray:
    """``(m, n)``: whether muscle ``i`` has a nonzero moment arm about coordinate ``j`` in any
    frame of ``jac`` ``(N, m, n)`` (in chunks of frames: no ``(N, m, n)`` temporary)."""
    out = np.zeros(jac.shape[1:], dtype=bool)
    for s0 in range(0, jac.shape[0], _BLOCK_CHUNK):
        out |= (jac[s0 : s0 + _BLOCK_CHUNK] != 0).any(axis=0)
    return out


def _independent_blocks(
    pattern: BoolArray, h: Array
) -> list[tuple[NDArray[np.intp], NDArray[np.intp]]]:
    """The independent sub-problems of QPs whose equality rows × unknowns have the nonzero
    ``pattern`` (rows, nv) in every frame and the cost matrix ``h`` (nv, nv): the connected
    components of the graph joining a row to its unknowns and two unknowns coupled by ``h``,
    as (rows, unknowns) index arrays, sorted; components with fewer than
    :data:`_MIN_BLOCK_UNKNOWNS` unknowns merged into another one. One component (nothing to
    split) when some unknown or row belongs to no equality (it would be a QP without rows)."""
    n_rows, nv = pattern.shape
    if not (pattern.any(axis=0).all() and pattern.any(axis=1).all()):
        return [(np.arange(n_rows), np.arange(nv))]
    c = pattern.astype(float)
    off = (h != 0).astype(float)
    np.fill_diagonal(off, 1.0)
    reach = (c @ off @ c.T) > 0  # rows sharing an unknown, or joined through h
    while True:  # transitive closure by squaring
        nxt = (reach.astype(float) @ reach.astype(float)) > 0
        if (nxt == reach).all():
            break
        reach = nxt
    row_label = reach.argmax(axis=1)  # the first row of each row's component
    col_label = row_label[pattern.argmax(axis=0)]  # through any row of the unknown
    comps = [[np.flatnonzero(row_label == lab), np.flatnonzero(col_label == lab)]
             for lab in np.unique(row_label)]  # fmt: skip
    comps.sort(key=lambda rc: rc[1].size)
    while len(comps) > 1 and comps[0][1].size < _MIN_BLOCK_UNKNOWNS:
        small = comps.pop(0)
        comps[0] = [np.union1d(comps[0][0], small[0]), np.union1d(comps[0][1], small[1])]
        comps.sort(key=lambda rc: rc[1].size)
    comps.sort(key=lambda rc: int(rc[1][0]))
    return [(r, c) for r, c in comps]


class _BatchQP:
    """The standard-form QPs ``min ½xᵀHx + gᵀx  s.t. [R S, E diag(opt)] [x; r] = b``, bounds,
    of a batch's frames (muscle column scales ``S`` = ``scale`` ``(m,)`` or ``(N, m)``),
    built in arrays allocated once per batch instead of per frame: the constraint matrix is one
    buffer whose muscle block is overwritten every frame (DAQP reads it during ``update``;
    nothing keeps a frame's QP once the next is built), the reserve block written once; bounds
    ``lb``/``ub`` and ``g`` are ``(nv,)`` for all frames or ``(N, nv)`` rows, ``h`` one matrix.
    ``R = −Jᵀ`` is read from ``jac`` frame by frame (no transposed copy of the batch). The
    reserves that decouple from the muscles (:func:`_decoupled_reserves`) and their rows are
    left out when ``decouple`` is true; ``reduction`` then says how the solutions map back.
    With ``decouple`` and the output map ``f = out_scale ⊙ x + out_offset`` given, the QPs
    that split into independent sub-problems (:func:`_independent_blocks`) have ``blocks``
    and are solved by :meth:`solve_blocks` (:func:`_run_blocks`). ``inequalities``
    (:class:`TensionInequalities`) add the rows ``C x ≥ cl`` and their reserves (the last
    unknowns); each row takes part in the split like an equality row over the muscles of its
    nonzero gains and its own reserve (:meth:`whole` is a frame's QP with every unknown)."""

    def __init__(
        self,
        jac: Array,
        tau: Array,
        scale: Array,
        idx: NDArray[np.intp],
        opt: Array,
        lb: Array,
        ub: Array,
        h: Array,
        g: Array,
        *,
        passive: Array | None = None,
        layout: Callable[[int], _Layout],
        full: Callable[[int], StandardQP],
        decouple: bool = True,
        out_scale: Array | None = None,
        out_offset: Array | None = None,
        inequalities: TensionInequalities | None = None,
    ) -> None:
        n_fr, m, n = jac.shape
        nres = idx.shape[0]
        drop = np.zeros(nres, dtype=bool)
        if decouple:  # on the coordinate reserves' own bounds (before the rows' reserves)
            drop = _decoupled_reserves(jac, tau, idx, opt, lb[..., m:], ub[..., m:])
        self.ineq = inequalities
        n_in = 0
        if inequalities is not None:  # their reserves s ≥ 0 after the coordinate reserves
            n_in = inequalities.n_rows
            inequalities.check(n_fr, m)
            lb = np.concatenate([lb, np.zeros((*lb.shape[:-1], n_in))], axis=-1)
            ub = np.concatenate([ub, np.full((*ub.shape[:-1], n_in), np.inf)], axis=-1)
            g = np.concatenate([g, np.zeros((*g.shape[:-1], n_in))], axis=-1)
            hh = np.zeros((h.shape[0] + n_in, h.shape[0] + n_in))
            hh[: h.shape[0], : h.shape[0]] = h
            hh[h.shape[0] :, h.shape[0] :] = 2.0 * np.eye(n_in)  # (s/s_opt)², as a reserve
            h = hh
        keep = ~drop
        rows = np.setdiff1d(np.arange(n), idx[drop])
        ineq_cols = m + nres + np.arange(n_in)  # the rows' reserves in the whole QP's x
        cols = np.concatenate([np.arange(m), m + np.flatnonzero(keep), ineq_cols])
        k = int(keep.sum())
        self.jac, self.tau, self.m = jac, tau, m
        self.neg_scale = -scale  # R S = −Jᵀ S = Jᵀ (−S), the same numbers
        self.passive = passive if passive is not None and passive.any() else None
        contiguous = rows.size > 0 and rows[-1] - rows[0] + 1 == rows.size
        self.rows: slice | NDArray[np.intp] = (
            slice(int(rows[0]), int(rows[-1]) + 1) if contiguous else rows
        )
        self.coords = rows  # the coordinates of the QP's rows
        self.a = np.zeros((rows.size, m + k + n_in))
        self.a[np.searchsorted(rows, idx[keep]), m + np.arange(k)] = opt[keep]
        self.n_reserves = k
        self.lb, self.ub = lb[..., cols], ub[..., cols]
        self.h = h[np.ix_(cols, cols)] if drop.any() else h
        self.g = g[..., cols]
        self.layout = layout
        self.whole_h = h  # the whole QP's H (every reserve, the rows' reserves last)
        self.whole_g, self.whole_lb, self.whole_ub = g, lb, ub  # and its g and bounds
        self.res_idx, self.res_opt = idx, opt
        self.full_qp = full
        self.reduction: _Reduction | None = None
        if drop.any():
            self.reduction = _Reduction(
                kept=np.concatenate([m + np.flatnonzero(keep), ineq_cols]),
                dropped=m + np.flatnonzero(drop),
                values=tau[:, idx[drop]] / opt[drop],
                full=self.whole if inequalities is not None else full,
            )
        # independent sub-problems (e.g. each leg, the back): solved apart, same solution. The
        # inequality rows join the muscles they involve (a knee's compartment rows: the
        # muscles crossing that knee, all in its leg's sub-problem) and their own reserves.
        self.blocks: list[tuple[NDArray[np.intp], NDArray[np.intp]]] | None = None
        self.out_scale, self.out_offset = out_scale, out_offset
        if decouple and out_scale is not None and out_offset is not None and rows.size:
            pattern = np.zeros((rows.size + n_in, m + k + n_in), dtype=bool)
            pattern[: rows.size, :m] = _nonzero_pattern(jac)[:, rows].T
            pattern[: rows.size, m:] = self.a[:, m:] != 0
            if inequalities is not None:
                gain = np.asarray(inequalities.gain)
                pattern[rows.size :, :m] = (gain != 0).any(axis=0)
                pattern[rows.size :, m + k :] = np.eye(n_in, dtype=bool)
            blocks = _independent_blocks(pattern, self.h)
            if len(blocks) > 1:
                self.blocks = blocks

    def whole(self, k: int) -> StandardQP:
        """Frame ``k``'s whole QP (every reserve; with inequality rows, their reserves after
        the coordinate reserves and the rows ``C x ≥ cl``): for its KKT figures and for a
        frame that is not optimal."""
        qp = self.full_qp(k)
        if self.ineq is None:
            return qp
        n_in = self.ineq.n_rows
        lay = self.layout(k)
        c_mat, cl = self.ineq.rows(k, lay.scale, lay.offset, qp.n - self.m)
        return StandardQP(
            H=self.whole_h, g=np.concatenate([qp.g, np.zeros(n_in)]),
            A=np.hstack([qp.A, np.zeros((qp.m_eq, n_in))]), b=qp.b,
            lb=np.concatenate([qp.lb, np.zeros(n_in)]),
            ub=np.concatenate([qp.ub, np.full(n_in, np.inf)]), C=c_mat, cl=cl,
        )  # fmt: skip

    def whole_stack(self, fr: NDArray[np.intp]) -> tuple[Any, ...]:
        """The whole QPs of frames ``fr`` (:meth:`whole`) as stacked arrays ``(H, g, A, b,
        lb, ub, C, cl)`` (``H`` and, when the same for every frame, ``g``, ``lb``, ``ub``
        shared; ``C``, ``cl`` None without inequality rows), for
        :func:`~msk.optimization.kkt_stacked`; needs the output map (``out_scale``,
        ``out_offset``)."""
        assert self.out_scale is not None and self.out_offset is not None
        m, n_fr = self.m, fr.size
        jac = self.jac[fr]
        idx, opt = self.res_idx, self.res_opt
        nres = idx.shape[0]
        n_in = 0 if self.ineq is None else self.ineq.n_rows
        n = jac.shape[2]
        a = np.zeros((n_fr, n, m + nres + n_in))
        s = self.neg_scale if self.neg_scale.ndim == 1 else self.neg_scale[fr][:, None, :]
        a[:, :, :m] = np.swapaxes(jac, 1, 2) * s  # R S = −Jᵀ S
        a[:, idx, m + np.arange(nres)] = opt
        b = self.tau[fr]
        if self.passive is not None:
            b = b + np.einsum("kmn,km->kn", jac, self.passive[fr])  # τ − R f_p

        def rows(v: Array) -> Array:
            return v if v.ndim == 1 else v[fr]

        g, lb, ub = rows(self.whole_g), rows(self.whole_lb), rows(self.whole_ub)
        if self.ineq is None:
            return self.whole_h, g, a, b, lb, ub, None, None
        gain = np.asarray(self.ineq.gain)[fr]
        scale = np.broadcast_to(self.out_scale, (self.tau.shape[0], m))[fr]
        offset = np.broadcast_to(self.out_offset, (self.tau.shape[0], m))[fr]
        c = np.zeros((n_fr, n_in, m + nres + n_in))
        c[:, :, :m] = gain * scale[:, None, :]
        c[:, :, m + nres :] = np.diag(np.asarray(self.ineq.reserve_optimal))
        cl = -np.asarray(self.ineq.offset)[fr] - (gain @ offset[:, :, None])[:, :, 0]
        return self.whole_h, g, a, b, lb, ub, c, cl

    def __call__(self, k: int) -> tuple[StandardQP, _Layout]:
        m, a = self.m, self.a
        jr = self.jac[k][:, self.rows]
        s = self.neg_scale if self.neg_scale.ndim == 1 else self.neg_scale[k]
        np.multiply(jr.T, s, out=a[:, :m])
        b = self.tau[k, self.rows]
        if self.passive is not None:
            b = b + jr.T @ self.passive[k]  # τ − R f_p
        lb = self.lb if self.lb.ndim == 1 else self.lb[k]
        ub = self.ub if self.ub.ndim == 1 else self.ub[k]
        g = self.g if self.g.ndim == 1 else self.g[k]
        lay = self.layout(k)
        if self.ineq is None:
            return StandardQP(H=self.h, g=g, A=a, b=b, lb=lb, ub=ub), lay
        c_mat, cl = self.ineq.rows(k, -s, lay.offset, self.n_reserves)
        lay = dataclasses.replace(lay, inequality_opt=np.asarray(self.ineq.reserve_optimal))
        return StandardQP(H=self.h, g=g, A=a, b=b, lb=lb, ub=ub, C=c_mat, cl=cl), lay

    def solve_blocks(
        self, models: list[Any] | None = None
    ) -> tuple[Array, BoolArray, NDArray[np.int64], Array, list[Any]]:
        """Every frame's QP solved as its independent sub-problems (:attr:`blocks`), each with
        its own warm-started DAQP workspace: ``x`` ``(N, nv)`` (bounds made exact, as
        :func:`solve_standard` does), whether all sub-problems of a frame were solved, the
        active-set iterations and the solve time of each frame, and the DAQP workspaces (to
        pass as ``models`` to the next call on the following frames: it starts from their
        working sets). The sub-problems' data are assembled for :data:`_BLOCK_CHUNK` frames at
        once; per frame only DAQP is called."""
        import daqp

        assert self.blocks is not None
        n_frames, m = self.tau.shape[0], self.m
        nv = self.a.shape[1]
        n_eq = self.coords.size
        x_all = np.empty((n_frames, nv))
        ok = np.ones(n_frames, dtype=bool)
        iters = np.zeros(n_frames, dtype=np.int64)
        times = np.zeros(n_frames)
        models = list(models) if models is not None else [None] * len(self.blocks)
        cost = [(np.ascontiguousarray(self.h[np.ix_(c, c)]), c) for _, c in self.blocks]
        senses = []
        for r, c in self.blocks:
            sense = np.zeros(c.size + r.size, dtype=np.int32)
            sense[c.size : c.size + int(np.count_nonzero(r < n_eq))] = 5  # equalities
            senses.append(sense)  # (ACTIVE + IMMUTABLE); inequality rows 0, after them
        ineq = self.ineq
        if ineq is not None:  # the rows' reserves s = s_opt x_s: C's constant columns
            c_fix = np.zeros((ineq.n_rows, nv))
            c_fix[:, nv - ineq.n_rows :] = np.diag(np.asarray(ineq.reserve_optimal))
        for s0 in range(0, n_frames, _BLOCK_CHUNK):
            s1 = min(s0 + _BLOCK_CHUNK, n_frames)
            jc = self.jac[s0:s1]
            s = self.neg_scale if self.neg_scale.ndim == 1 else self.neg_scale[s0:s1]
            bb = self.tau[s0:s1][:, self.rows]
            if self.passive is not None:
                jr = jc[:, :, self.rows]
                bb = bb + np.einsum("kmr,km->kr", jr, self.passive[s0:s1])
            # bounds and g: one row for every frame, or this chunk's rows of per-frame ones
            lb, ub, g = (
                np.broadcast_to(v if v.ndim == 1 else v[s0:s1], (s1 - s0, nv))
                for v in (self.lb, self.ub, self.g)
            )
            if ineq is not None:  # C x ≥ cl with f = scale ⊙ x + offset (TensionInequalities)
                gc = np.asarray(ineq.gain)[s0:s1]
                cl = -np.asarray(ineq.offset)[s0:s1]
                if self.passive is not None:
                    cl = cl - np.einsum("kim,km->ki", gc, self.passive[s0:s1])
            data = []
            for (r, c), (hb, _), sense in zip(self.blocks, cost, senses, strict=True):
                cm, cr = c[c < m], c[c >= m]
                re, ri = r[r < n_eq], r[r >= n_eq] - n_eq
                ab = np.empty((s1 - s0, r.size, c.size))
                # R S = Jᵀ (−S) of the block's coordinates and muscles
                jb = jc[:, cm[:, None], self.coords[re][None, :]]  # (c, muscles, rows)
                sb = s[cm] if s.ndim == 1 else s[:, None, cm]
                np.multiply(np.swapaxes(jb, 1, 2), sb, out=ab[:, : re.size, : cm.size])
                ab[:, : re.size, cm.size :] = self.a[np.ix_(re, cr)]
                bu_rows, bl_rows = bb[:, re], bb[:, re]
                if ri.size:  # G S of the block's rows and muscles, then the rows' reserves
                    gr = gc[:, ri[:, None], cm[None, :]]
                    np.multiply(gr, -sb, out=ab[:, re.size :, : cm.size])
                    ab[:, re.size :, cm.size :] = c_fix[np.ix_(ri, cr)]
                    up = np.full((s1 - s0, ri.size), np.inf)  # one-sided: c + G f + s ≥ 0
                    bu_rows = np.concatenate([bu_rows, up], axis=1)
                    bl_rows = np.concatenate([bl_rows, cl[:, ri]], axis=1)
                bu = np.ascontiguousarray(np.concatenate([ub[:, c], bu_rows], axis=1))
                bl = np.ascontiguousarray(np.concatenate([lb[:, c], bl_rows], axis=1))
                gb = np.ascontiguousarray(g[:, c]) if self.g.ndim == 2 else None
                data.append((ab, bu, bl, gb, hb, sense, np.empty((s1 - s0, c.size))))
            for j in range(s1 - s0):
                t0 = _time.perf_counter()
                it = 0
                for b, (ab, bu, bl, gb, hb, sense, xs) in enumerate(data):
                    model = models[b]
                    if model is None:
                        model = daqp.Model()
                        model.settings = DAQP_OPTIONS
                        f0 = self.g[cost[b][1]] if gb is None else gb[j]
                        flag = model.setup(hb, f0, ab[j], bu[j], bl[j], sense)[0]
                    elif gb is None:
                        flag = model.update(A=ab[j], bupper=bu[j], blower=bl[j])
                    else:
                        flag = model.update(f=gb[j], A=ab[j], bupper=bu[j], blower=bl[j])
                    if flag >= 0:
                        xs[j], _, flag, info = model.solve()
                        it += info["iterations"]
                    if flag <= 0:  # not solved (the frame is solved whole): start afresh
                        models[b] = None
                        ok[s0 + j] = False
                    else:
                        models[b] = model
                iters[s0 + j] = it
                times[s0 + j] = _time.perf_counter() - t0
            for (_, c), d in zip(self.blocks, data, strict=True):
                x_all[s0:s1, c] = d[-1]
            np.minimum(np.maximum(x_all[s0:s1], lb), ub, out=x_all[s0:s1])
        return x_all, ok, iters, times, models


@dataclass
class _BlockWarm:
    """The warm start a call solved by sub-problems leaves (:attr:`WarmStart.state`): the
    sub-problems and their DAQP workspaces; the next call continues from them when its QPs
    split the same way, else starts cold (same solutions either way, to round-off)."""

    blocks: list[tuple[NDArray[np.intp], NDArray[np.intp]]]
    models: list[Any]

    def fits(self, build: _BatchQP) -> bool:
        theirs = build.blocks or []
        return len(theirs) == len(self.blocks) and all(
            np.array_equal(r0, r1) and np.array_equal(c0, c1)
            for (r0, c0), (r1, c1) in zip(self.blocks, theirs, strict=True)
        )


class WarmStart:
    """A batch solver's warm start carried from one call to the next (``warm=`` of the
    ``*_batch`` functions): the calls on consecutive frame blocks of one trial, given the same
    object, each start from the previous block's last working set, as one call on all the
    frames would (a long trial solved block by block, :mod:`msk._runtime.blocks`). A fresh
    object starts cold, like a call without it."""

    def __init__(self) -> None:
        self.state: Any = None
        self.started = False


def _run_batch(
    n_frames: int,
    build: Callable[[int], tuple[StandardQP, _Layout]],
    jac: Array,
    tau: Array,
    *,
    solver: str,
    warm_start: bool,
    strict: bool,
    compute_kkt: bool,
    activations: bool,
    carry: WarmStart | None = None,
    muscle_names: tuple[str, ...],
    coordinate_names: tuple[str, ...],
    time: ArrayLike | None,
    power: tuple[int, Array, float] | None = None,
    reduction: _Reduction | None = None,
    inequality_names: tuple[str, ...] = (),
) -> BatchSolution:
    """Solve ``build(k)`` for every frame (warm-started). With a ``reduction`` (decoupled
    reserves left out of ``build``'s QPs, :class:`_BatchQP`) each solution is expanded back to
    the whole QP, whose KKT figures are reported, and a frame that is not optimal is solved
    whole (cold), exactly as without the reduction."""
    get_solver(solver)
    _, m, n = jac.shape
    assert reduction is None or power is None
    whole = reduction is None
    if (
        isinstance(build, _BatchQP)
        and build.blocks is not None
        and power is None
        and warm_start
        and solver == _EXACT_SOLVER
    ):
        return _run_blocks(
            n_frames, build, jac, tau, strict=strict, compute_kkt=compute_kkt,
            activations=activations, muscle_names=muscle_names,
            coordinate_names=coordinate_names, time=time, reduction=reduction, carry=carry,
            inequality_names=inequality_names,
        )  # fmt: skip
    # the frame-by-frame outputs (not allocated for the sub-problem path above)
    forces = np.empty((n_frames, m))
    acts = np.empty((n_frames, m)) if activations else None
    rc = np.zeros((n_frames, n))
    rt = np.zeros((n_frames, n))
    kk = np.full((n_frames, 4), np.nan)
    ks = np.full((n_frames, 4), np.nan)
    xs = np.empty((n_frames, m))  # muscle unknowns and their bounds, for the active sets
    lbs = np.empty((n_frames, m))
    ubs = np.empty((n_frames, m))
    status = np.zeros(n_frames, dtype=np.int8)
    iters = np.zeros(n_frames, dtype=np.int64)
    times = np.zeros(n_frames)
    ineq: Array | None = None
    warm = None
    if warm_start:
        warm = carry.state if carry is not None and carry.started else new_warm(solver)
        if isinstance(warm, _BlockWarm):  # the previous call solved sub-problems: start cold
            warm = new_warm(solver)
    for k in range(n_frames):
        qp, lay = build(k)
        if power is None:
            raw, w = solve_standard(
                qp,
                solver=solver,
                warm=warm,
                compute_kkt=compute_kkt and whole,
                frame=k,
                strict=strict and whole,
            )
        else:
            raw, w = _solve_power(
                qp,
                *power,
                solver=solver,
                warm=warm,
                compute_kkt=compute_kkt,
                frame=k,
                strict=strict,
            )
        if warm_start:
            warm = w
        x = raw.x
        if reduction is not None:
            if raw.status == STATUS_OPTIMAL:
                x = reduction.expand(x, k)
                if compute_kkt:
                    kb = kkt_batch([reduction.full(k)], x[None, :])
                    kk[k], ks[k] = kb.figures[0], kb.scale[0]
            else:
                qp = reduction.full(k)
                raw, _ = solve_standard(
                    qp, solver=solver, compute_kkt=compute_kkt, frame=k, strict=strict
                )
                x = raw.x
        f, a, r = lay.unpack(x)
        forces[k] = f
        if acts is not None and a is not None:
            acts[k] = a
        if lay.inequality_opt.size:
            if ineq is None:
                ineq = np.full((n_frames, lay.inequality_opt.size), np.nan)
            ineq[k] = lay.inequality_reserves(x)
        rc[k] = r
        rt[k, lay.reserve_idx] = lay.reserve_opt * r[lay.reserve_idx]
        if raw.kkt is not None:
            kk[k] = raw.kkt.as_array()
        if raw.kkt_scale is not None:
            ks[k] = raw.kkt_scale
        xs[k], lbs[k], ubs[k] = x[:m], qp.lb[:m], qp.ub[:m]
        status[k] = raw.status
        iters[k] = raw.iterations
        times[k] = raw.solve_time_s
    if carry is not None and warm_start:
        carry.state, carry.started = warm, True
    out = _batch_solution(
        xs, lbs, ubs, forces, acts, rc, rt, tau, jac, kk, status, iters, times, solver,
        muscle_names, coordinate_names, time, ks,
    )  # fmt: skip
    if inequality_names:
        if ineq is None:
            ineq = np.zeros((n_frames, len(inequality_names)))
        out = dataclasses.replace(
            out, inequality_reserves=ineq, inequality_names=tuple(inequality_names)
        )
    return out


def _run_blocks(
    n_frames: int,
    build: _BatchQP,
    jac: Array,
    tau: Array,
    *,
    strict: bool,
    compute_kkt: bool,
    activations: bool,
    muscle_names: tuple[str, ...],
    coordinate_names: tuple[str, ...],
    time: ArrayLike | None,
    reduction: _Reduction | None,
    carry: WarmStart | None = None,
    inequality_names: tuple[str, ...] = (),
) -> BatchSolution:
    """:func:`_run_batch` for a batch whose QPs split into independent sub-problems
    (:attr:`_BatchQP.blocks`, DAQP, warm-started): every frame solved by
    :meth:`_BatchQP.solve_blocks`, the outputs assembled for all frames at once. A frame that
    some sub-problem could not solve is solved whole, cold, by :func:`solve_standard` (status,
    bounded least-squares point and ``strict`` exactly as in :func:`_run_batch`); KKT figures
    are those of the whole QP of each frame. With inequality rows (:class:`TensionInequalities`)
    their reserves are the last unknowns of every frame's ``x``, whole or reduced."""
    _, m, n = jac.shape
    state = carry.state if carry is not None and carry.started else None
    models = state.models if isinstance(state, _BlockWarm) and state.fits(build) else None
    x, ok, iters, times, models = build.solve_blocks(models)
    if carry is not None:
        carry.state, carry.started = _BlockWarm(build.blocks or [], models), True
    if reduction is not None:
        xf = np.empty((n_frames, m + reduction.kept.size + reduction.dropped.size))
        xf[:, :m] = x[:, :m]
        xf[:, reduction.kept] = x[:, m:]
        xf[:, reduction.dropped] = reduction.values
        x = xf
    status = np.full(n_frames, STATUS_OPTIMAL, dtype=np.int8)
    kk = np.full((n_frames, 4), np.nan)
    ks = np.full((n_frames, 4), np.nan)

    def whole(k: int) -> StandardQP:
        return reduction.full(k) if reduction is not None else build(k)[0]

    for k in np.flatnonzero(~ok):
        raw, _ = solve_standard(
            whole(int(k)), solver=_EXACT_SOLVER, compute_kkt=compute_kkt, frame=int(k),
            strict=strict,
        )  # fmt: skip
        x[k], status[k], iters[k] = raw.x, raw.status, raw.iterations
        times[k] += raw.solve_time_s
        if raw.kkt is not None:
            kk[k] = raw.kkt.as_array()
        if raw.kkt_scale is not None:
            ks[k] = raw.kkt_scale
    if compute_kkt:  # the solved frames' whole QPs, stacked, their figures over frames at once
        solved = np.flatnonzero(ok)
        for a in range(0, solved.size, KKT_CHUNK):
            fr = solved[a : a + KKT_CHUNK]
            h, g, am, b, lb, ub, c, cl = build.whole_stack(fr)
            kb = kkt_stacked(h, g, am, b, lb, ub, x[fr], c, cl)
            kk[fr], ks[fr] = kb.figures, kb.scale
    assert build.out_scale is not None and build.out_offset is not None
    forces = build.out_scale * x[:, :m] + build.out_offset
    acts = x[:, :m].copy() if activations else None
    lay = build.layout(0)
    nres = lay.reserve_idx.shape[0]
    rc = np.zeros((n_frames, n))
    rc[:, lay.reserve_idx] = x[:, m : m + nres]
    rt = np.zeros((n_frames, n))
    rt[:, lay.reserve_idx] = lay.reserve_opt * x[:, m : m + nres]
    lbs = np.broadcast_to(build.lb[..., :m], (n_frames, m))
    ubs = np.broadcast_to(build.ub[..., :m], (n_frames, m))
    out = _batch_solution(
        x[:, :m], lbs, ubs, forces, acts, rc, rt, tau, jac, kk, status, iters, times,
        _EXACT_SOLVER, muscle_names, coordinate_names, time, ks,
    )  # fmt: skip
    if build.ineq is None:
        return out
    return dataclasses.replace(
        out, inequality_reserves=np.asarray(build.ineq.reserve_optimal) * x[:, m + nres :],
        inequality_names=tuple(inequality_names),
    )  # fmt: skip


def _batch_solution(
    x_muscles: Array,
    lbs: Array,
    ubs: Array,
    forces: Array,
    acts: Array | None,
    rc: Array,
    rt: Array,
    tau: Array,
    jac: Array,
    kk: Array,
    status: Any,
    iters: Any,
    times: Any,
    solver: str,
    muscle_names: Any,
    coordinate_names: Any,
    time: ArrayLike | None,
    kkt_scale: Array | None = None,
) -> BatchSolution:
    """The :class:`BatchSolution` of solved frames: active bounds from the muscle variables
    ``x_muscles`` and their bounds, torque error τ + Jᵀf and residual (error − reserves)."""
    n_frames = forces.shape[0]
    alo, aup = active_masks(x_muscles, lbs, ubs)
    terr = tau + np.einsum("kmn,km->kn", jac, forces)
    resid = terr - rt
    t = None if time is None else as_float(time, (n_frames,), "time")
    return BatchSolution(
        forces=forces,
        activations=acts,
        reserve_controls=rc,
        reserve_torques=rt,
        torque_error=terr,
        residual=resid,
        residual_norm=np.linalg.norm(resid, axis=1),
        kkt=kk,
        active_lower=alo,
        active_upper=aup,
        status=status,
        iterations=iters,
        solve_time_s=times,
        solver=solver,
        muscle_names=muscle_names,
        coordinate_names=coordinate_names,
        time=t,
        kkt_scale=kkt_scale,
    )


def _per_frame(value: ArrayLike | None, n_frames: int, m: int, what: str, default: float) -> Any:
    if value is None:
        return np.full((n_frames, m), default)
    return as_float(value, (n_frames, m), what)


def _batch_inputs(
    jacobians: ArrayLike,
    taus: ArrayLike,
    muscle_names: Sequence[str] | None,
    coordinate_names: Sequence[str] | None,
) -> tuple[Array, Array, tuple[str, ...], tuple[str, ...]]:
    return check_frame(jacobians, taus, muscle_names, coordinate_names, ndim=3, tau_name="taus")


def solve_tension_batch(
    jacobians: ArrayLike,
    taus: ArrayLike,
    *,
    f_iso: ArrayLike,
    f_max: ArrayLike | None = None,
    f_min: ArrayLike | None = None,
    reserve_optimal_force: ArrayLike | None = None,
    solver: str = DEFAULT_SOLVER,
    warm_start: bool = True,
    warm: WarmStart | None = None,
    strict: bool = False,
    compute_kkt: bool = True,
    muscle_names: Sequence[str] | None = None,
    coordinate_names: Sequence[str] | None = None,
    time: ArrayLike | None = None,
    inequalities: TensionInequalities | None = None,
) -> BatchSolution:
    """:class:`TensionProblem` over frames. ``f_max``/``f_min`` ``(m,)`` or ``(N, m)``."""
    jac, tau, mn, cn = _batch_inputs(jacobians, taus, muscle_names, coordinate_names)
    n_frames, m, n = jac.shape
    fi = as_float(f_iso, (m,), "f_iso")
    check_positive(fi, "f_iso", mn)
    fmax = (
        np.broadcast_to(fi, (n_frames, m))
        if f_max is None
        else as_float(f_max, (n_frames, m), "f_max")
    )
    fmin = _per_frame(f_min, n_frames, m, "f_min", 0.0)
    bad = ~(fmin <= fmax)
    if bad.any():
        k, i = (int(v) for v in np.argwhere(bad)[0])
        raise OptimizationError(
            f"force bounds of muscle {mn[i]!r} at frame {k} are inconsistent: "
            f"min {float(fmin[k, i])!r} > max {float(fmax[k, i])!r}"
        )
    idx, opt = _reserves(reserve_optimal_force, n, cn)
    inf = np.full((n_frames, idx.shape[0]), np.inf)
    lay = _Layout(n, fi, np.zeros(m), idx, opt, activations=False)

    def full(k: int) -> StandardQP:
        r = np.ascontiguousarray(-jac[k].T)
        return _tension_qp(r, tau[k], fi, fmin[k], fmax[k], idx, opt)[0]

    build = _BatchQP(
        jac,
        tau,
        fi,
        idx,
        opt,
        np.hstack([fmin / fi, -inf]),
        np.hstack([fmax / fi, inf]),
        *_constant_cost(m + idx.shape[0]),
        layout=lambda k: lay,
        full=full,
        decouple=solver == _EXACT_SOLVER,
        out_scale=fi,
        out_offset=np.zeros(m),
        inequalities=inequalities,
    )
    return _run_batch(
        n_frames,
        build,
        jac,
        tau,
        solver=solver,
        warm_start=warm_start,
        carry=warm,
        strict=strict,
        compute_kkt=compute_kkt,
        activations=False,
        muscle_names=mn,
        coordinate_names=cn,
        time=time,
        reduction=build.reduction,
        inequality_names=() if inequalities is None else inequalities.names,
    )


def solve_static_optimization_batch(
    jacobians: ArrayLike,
    taus: ArrayLike,
    *,
    f_active: ArrayLike,
    f_passive: ArrayLike | None = None,
    activation_min: ArrayLike = 0.0,
    activation_max: ArrayLike = 1.0,
    reserve_optimal_force: ArrayLike | None = None,
    reserve_min_control: ArrayLike = -np.inf,
    reserve_max_control: ArrayLike = np.inf,
    activation_weights: ArrayLike | None = None,
    activation_exponent: float = 2.0,
    solver: str = DEFAULT_SOLVER,
    warm_start: bool = True,
    warm: WarmStart | None = None,
    strict: bool = False,
    compute_kkt: bool = True,
    muscle_names: Sequence[str] | None = None,
    coordinate_names: Sequence[str] | None = None,
    time: ArrayLike | None = None,
    inequalities: TensionInequalities | None = None,
) -> BatchSolution:
    """:class:`StaticOptimizationProblem` over frames; ``f_active``/``f_passive`` ``(N, m)``;
    ``activation_weights`` ``(m,)`` and ``activation_exponent`` as in the problem (criterion
    ``Σ w_i a_i^p + Σ r_j²``).

    With DAQP and p = 2, a reserve whose coordinate no muscle crosses in any frame (gait2392's
    pelvis residuals) leaves the QP with its row: ``r_j = τ_j / F_res,j`` exactly, unless its
    control bounds could be active (:func:`_decoupled_reserves`); every output, KKT figures
    included, is that of the whole QP (to round-off), and a frame that is not optimal is
    solved whole. Likewise the QP splits into its independent sub-problems when no muscle
    joins them (gait2392: each leg, the back joined to one of them), each solved with its own
    warm-started DAQP workspace (:meth:`_BatchQP.solve_blocks`): the same solution to
    round-off (~1e-16 on activations), a DAQP refactorisation of about a third of the size.

    ``inequalities`` (:class:`TensionInequalities`, e.g. knee compartment forces ≥ 0): rows
    ``c + G f + s ≥ 0`` added to every frame's QP with reserves ``s ≥ 0`` costing
    ``(s/s_opt)²`` like the coordinate reserves. A row joins the sub-problem of the muscles
    whose gain is nonzero in some frame, with its reserve (a knee's compartment rows: the
    muscles crossing that knee, all in its leg's sub-problem), so the split and the decoupled
    reserves are kept; the solution is that of the whole QP to round-off."""
    jac, tau, mn, cn = _batch_inputs(jacobians, taus, muscle_names, coordinate_names)
    n_frames, m, n = jac.shape
    fa = as_float(f_active, (n_frames, m), "f_active")
    check_finite(fa, "f_active", mn)
    if np.any(fa < 0):
        k, i = (int(v) for v in np.argwhere(fa < 0)[0])
        raise OptimizationError(f"f_active of muscle {mn[i]!r} at frame {k} is negative")
    fp = _per_frame(f_passive, n_frames, m, "f_passive", 0.0)
    check_finite(fp, "f_passive", mn)
    amin = as_float(activation_min, (m,), "activation_min")
    amax = as_float(activation_max, (m,), "activation_max")
    _check_bounds(amin, amax, "activation", mn)
    idx, opt = _reserves(reserve_optimal_force, n, cn)
    rmin = as_float(reserve_min_control, (n,), "reserve_min_control")[idx]
    rmax = as_float(reserve_max_control, (n,), "reserve_max_control")[idx]
    w = _activation_weights(activation_weights, m, mn)
    _check_exponent(activation_exponent)
    cost = None if w is None else _weighted_cost(w, idx.shape[0])  # one H for every frame
    power = None
    if activation_exponent != 2.0:
        power = (m, np.ones(m) if w is None else w, float(activation_exponent))

    def full(k: int) -> StandardQP:
        r = np.ascontiguousarray(-jac[k].T)
        return _static_qp(r, tau[k], fa[k], fp[k], amin, amax, idx, opt, rmin, rmax, cost)[0]

    build = _BatchQP(
        jac,
        tau,
        fa,
        idx,
        opt,
        np.concatenate([amin, rmin]),
        np.concatenate([amax, rmax]),
        *(_constant_cost(m + idx.shape[0]) if cost is None else cost),
        passive=fp,
        layout=lambda k: _Layout(n, fa[k], fp[k], idx, opt, activations=True),
        full=full,
        decouple=power is None and solver == _EXACT_SOLVER,  # p > 2: SQP keeps every unknown
        out_scale=fa,
        out_offset=fp,
        inequalities=inequalities,
    )
    return _run_batch(
        n_frames,
        build,
        jac,
        tau,
        solver=solver,
        warm_start=warm_start,
        carry=warm,
        strict=strict,
        compute_kkt=compute_kkt,
        activations=True,
        muscle_names=mn,
        coordinate_names=cn,
        time=time,
        power=power,
        reduction=build.reduction,
        inequality_names=() if inequalities is None else inequalities.names,
    )


def solve_emg_weighted_batch(
    jacobians: ArrayLike,
    taus: ArrayLike,
    *,
    f_ref: ArrayLike,
    measured: ArrayLike,
    w_emg: float,
    f_max: ArrayLike | None = None,
    f_min: ArrayLike | None = None,
    regularization: float = 1e-6,
    solver: str = DEFAULT_SOLVER,
    warm_start: bool = True,
    warm: WarmStart | None = None,
    strict: bool = False,
    compute_kkt: bool = True,
    muscle_names: Sequence[str] | None = None,
    coordinate_names: Sequence[str] | None = None,
    time: ArrayLike | None = None,
    inequalities: TensionInequalities | None = None,
) -> BatchSolution:
    """:class:`EMGWeightedProblem` over frames; ``f_ref`` ``(N, m)`` (EMG-based f*).
    ``inequalities`` (:class:`TensionInequalities`): rows ``c + G f + s ≥ 0`` whose reserves
    cost ``½ (s/s_opt)²``, the price of a torque error of ``s_opt``."""
    jac, tau, mn, cn = _batch_inputs(jacobians, taus, muscle_names, coordinate_names)
    n_frames, m, _ = jac.shape
    meas = _measured_mask(measured, m)
    fr = np.where(meas, as_float(f_ref, (n_frames, m), "f_ref"), 0.0)
    check_finite(fr, "f_ref", mn)
    fmax = _per_frame(f_max, n_frames, m, "f_max", np.inf)
    fmin = _per_frame(f_min, n_frames, m, "f_min", 0.0)
    _check_weights(w_emg, regularization)

    if inequalities is not None:
        inequalities.check(n_frames, m)

    def build(k: int) -> tuple[StandardQP, _Layout]:
        scale = _emg_scale(fr[k], fmax[k], meas)
        r = np.ascontiguousarray(-jac[k].T)  # R of this frame (no transposed batch copy)
        qp, lay = _emg_qp(r, tau[k], fr[k], meas, w_emg, regularization, fmin[k], fmax[k], scale)
        if inequalities is None:
            return qp, lay
        # reserves s = s_opt x_s appended, costing ½ s² like the torque error's ½ ‖τ − R f‖²
        n_in = inequalities.n_rows
        h = np.zeros((m + n_in, m + n_in))
        h[:m, :m] = qp.H
        h[m:, m:] = np.eye(n_in) / lay.objective_scale
        c_mat, cl = inequalities.rows(k, scale, np.zeros(m), 0)
        ext = StandardQP(
            H=h, g=np.concatenate([qp.g, np.zeros(n_in)]), A=np.zeros((0, m + n_in)),
            b=np.zeros(0), lb=np.concatenate([qp.lb, np.zeros(n_in)]),
            ub=np.concatenate([qp.ub, np.full(n_in, np.inf)]), C=c_mat, cl=cl,
        )  # fmt: skip
        return ext, dataclasses.replace(
            lay, inequality_opt=np.asarray(inequalities.reserve_optimal)
        )

    return _run_batch(
        n_frames,
        build,
        jac,
        tau,
        solver=solver,
        warm_start=warm_start,
        carry=warm,
        strict=strict,
        compute_kkt=compute_kkt,
        activations=False,
        muscle_names=mn,
        coordinate_names=cn,
        time=time,
        inequality_names=() if inequalities is None else inequalities.names,
    )


# ---------------------------------------------------------------------------------------------
# W_emg study (Hayashibe et al. 2011, Table I)
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class EMGWeightSweep:
    """The W_emg study of Hayashibe et al. 2011, Table I, one row per ``w_emg``.

    ``torque_error_rms`` ``(W,)``: RMS over frames and coordinates of ``τ − R f`` (N·m);
    ``torque_error_rms_per_coordinate`` ``(W, n_coords)``; ``max_force`` / ``mean_force``
    ``(W, n_muscles)`` over frames; ``emg_deviation_rms`` ``(W,)``: RMS of ``f − f*`` over the
    measured muscles and frames (N); ``forces`` ``(W, N, n_muscles)``; ``status`` ``(W, N)``.
    """

    w_emg: Array
    torque_error_rms: Array
    torque_error_rms_per_coordinate: Array
    max_force: Array
    mean_force: Array
    emg_deviation_rms: Array
    forces: Array
    status: NDArray[np.int8]
    muscle_names: tuple[str, ...]
    coordinate_names: tuple[str, ...]

    def table(self, muscle: str | None = None, coordinate: str | None = None) -> str:
        """Plain-text table like Hayashibe et al. 2011, Table I (W_emg, τ error, max force of
        ``muscle``)."""
        mi = self.muscle_names.index(muscle) if muscle is not None else None
        ci = self.coordinate_names.index(coordinate) if coordinate is not None else None
        head = f"{'W_emg':>10} {'tau err RMS':>12} {'|f-f*| RMS':>11}"
        head += f" {'max ' + muscle if muscle else 'max force':>14}"
        lines = [head]
        for w in range(self.w_emg.shape[0]):
            err = (
                self.torque_error_rms_per_coordinate[w, ci]
                if ci is not None
                else self.torque_error_rms[w]
            )
            fmax = self.max_force[w, mi] if mi is not None else self.max_force[w].max()
            lines.append(
                f"{self.w_emg[w]:>10.3g} {err:>12.4g} {self.emg_deviation_rms[w]:>11.4g}"
                f" {fmax:>14.4g}"
            )
        return "\n".join(lines)


def emg_weight_sweep(
    jacobians: ArrayLike,
    taus: ArrayLike,
    *,
    f_ref: ArrayLike,
    measured: ArrayLike,
    w_emgs: Sequence[float] = (1.0, 0.5, 0.1, 0.05, 0.01, 0.005, 0.001),
    f_max: ArrayLike | None = None,
    regularization: float = 1e-6,
    solver: str = DEFAULT_SOLVER,
    muscle_names: Sequence[str] | None = None,
    coordinate_names: Sequence[str] | None = None,
) -> EMGWeightSweep:
    """Solve the EMG-weighted QP for each ``W_emg`` (defaults: the values of Hayashibe et al. 2011,
    Table I)."""
    ws = np.asarray(w_emgs, dtype=float)
    sols = [
        solve_emg_weighted_batch(
            jacobians,
            taus,
            f_ref=f_ref,
            measured=measured,
            w_emg=float(w),
            f_max=f_max,
            regularization=regularization,
            solver=solver,
            compute_kkt=False,
            muscle_names=muscle_names,
            coordinate_names=coordinate_names,
        )
        for w in ws
    ]
    meas = _measured_mask(measured, sols[0].forces.shape[1])
    fr = np.asarray(f_ref, dtype=float)
    dev = [
        float(np.sqrt(np.mean((s.forces[:, meas] - fr[:, meas]) ** 2))) if meas.any() else 0.0
        for s in sols
    ]
    return EMGWeightSweep(
        w_emg=ws,
        torque_error_rms=np.array([np.sqrt(np.mean(s.torque_error**2)) for s in sols]),
        torque_error_rms_per_coordinate=np.array(
            [np.sqrt(np.mean(s.torque_error**2, axis=0)) for s in sols]
        ),
        max_force=np.array([s.forces.max(axis=0) for s in sols]),
        mean_force=np.array([s.forces.mean(axis=0) for s in sols]),
        emg_deviation_rms=np.array(dev),
        forces=np.array([s.forces for s in sols]),
        status=np.array([s.status for s in sols]),
        muscle_names=sols[0].muscle_names,
        coordinate_names=sols[0].coordinate_names,
    )


def solve_emg_assisted_batch(
    jacobians: ArrayLike,
    taus: ArrayLike,
    *,
    f_active: ArrayLike,
    f_passive: ArrayLike | None = None,
    a_ref: ArrayLike,
    measured: ArrayLike,
    w_track: float = 1.0,
    activation_weights: ArrayLike | None = None,
    activation_min: ArrayLike = 0.0,
    activation_max: ArrayLike = 1.0,
    reserve_optimal_force: ArrayLike | None = None,
    reserve_min_control: ArrayLike = -np.inf,
    reserve_max_control: ArrayLike = np.inf,
    solver: str = DEFAULT_SOLVER,
    warm_start: bool = True,
    warm: WarmStart | None = None,
    strict: bool = False,
    compute_kkt: bool = True,
    muscle_names: Sequence[str] | None = None,
    coordinate_names: Sequence[str] | None = None,
    time: ArrayLike | None = None,
    inequalities: TensionInequalities | None = None,
) -> BatchSolution:
    """EMG-assisted static optimisation over frames: static optimisation whose activations of
    the measured muscles are pulled towards EMG-based references, torques kept exact::

        minimise   Σ_i w_i a_i²  +  w_track Σ_{i ∈ M} (a_i − a*_i)²  +  Σ_j r_j²
        subject to Σ_i R_ji (a_i F_act,i + F_pas,i) + F_res,j r_j = τ_j,   a_min ≤ a ≤ a_max

    ``a_ref`` ``(N, m)`` is a*, e.g. ``g_c ê_c`` (an EMG activation times an EMG-to-activation
    gain, :func:`msk.strength.fit_emg_gains`), used only for the ``measured`` muscles;
    ``activation_weights`` w (default 1; the volume weights of Happee 1994 are the usual
    choice); ``w_track`` ≥ 0 is dimensionless (activations², relative to w). ``w_track = 0``
    is :func:`solve_static_optimization_batch` with exponent 2. Unlike the EMG-weighted QP of
    Hayashibe et al. 2011, Eq. 17 (torque error penalised, W_emg in m²), the torques are constraints
    here, so the EMG can only redistribute force inside the null space of ``R`` (the sharing between
    synergists, antagonists and biarticular muscles), never change the net joint moments.
    The cost is ``Σ (w_i + w_track [i ∈ M]) a_i² − 2 w_track Σ_{i ∈ M} a*_i a_i`` + constant:
    one QP per frame, ``H`` shared by all frames. ``f_passive`` ``(N, m)`` (default 0) as in
    :func:`solve_static_optimization_batch`. The :class:`BatchSolution` has the activations and
    the forces ``a F_act + F_pas``.
    """
    jac, tau, mn, cn = _batch_inputs(jacobians, taus, muscle_names, coordinate_names)
    n_frames, m, n = jac.shape
    fa = as_float(f_active, (n_frames, m), "f_active")
    check_finite(fa, "f_active", mn)
    if np.any(fa < 0):
        k, i = (int(v) for v in np.argwhere(fa < 0)[0])
        raise OptimizationError(f"f_active of muscle {mn[i]!r} at frame {k} is negative")
    fp = _per_frame(f_passive, n_frames, m, "f_passive", 0.0)
    check_finite(fp, "f_passive", mn)
    meas = _measured_mask(measured, m)
    aref = np.where(meas, as_float(a_ref, (n_frames, m), "a_ref"), 0.0)
    check_finite(aref, "a_ref", mn)
    if not (np.isfinite(w_track) and w_track >= 0):
        raise OptimizationError(f"w_track must be finite and ≥ 0: {w_track!r}")
    amin = as_float(activation_min, (m,), "activation_min")
    amax = as_float(activation_max, (m,), "activation_max")
    _check_bounds(amin, amax, "activation", mn)
    idx, opt = _reserves(reserve_optimal_force, n, cn)
    rmin = as_float(reserve_min_control, (n,), "reserve_min_control")[idx]
    rmax = as_float(reserve_max_control, (n,), "reserve_max_control")[idx]
    w = _activation_weights(activation_weights, m, mn)
    w = np.ones(m) if w is None else w
    wm = np.where(meas, float(w_track), 0.0)
    h, _ = _weighted_cost(w + wm, idx.shape[0])  # one H for every frame
    gs = np.hstack([-2.0 * wm * aref, np.zeros((n_frames, idx.shape[0]))])  # g of every frame

    def full(k: int) -> StandardQP:
        r = np.ascontiguousarray(-jac[k].T)
        return _static_qp(r, tau[k], fa[k], fp[k], amin, amax, idx, opt, rmin, rmax, (h, gs[k]))[0]

    build = _BatchQP(
        jac,
        tau,
        fa,
        idx,
        opt,
        np.concatenate([amin, rmin]),
        np.concatenate([amax, rmax]),
        h,
        gs,
        passive=fp,
        layout=lambda k: _Layout(n, fa[k], fp[k], idx, opt, activations=True),
        full=full,
        decouple=solver == _EXACT_SOLVER,
        out_scale=fa,
        out_offset=fp,
        inequalities=inequalities,
    )
    return _run_batch(
        n_frames,
        build,
        jac,
        tau,
        solver=solver,
        warm_start=warm_start,
        carry=warm,
        strict=strict,
        compute_kkt=compute_kkt,
        activations=True,
        muscle_names=mn,
        coordinate_names=cn,
        time=time,
        reduction=build.reduction,
        inequality_names=() if inequalities is None else inequalities.names,
    )
