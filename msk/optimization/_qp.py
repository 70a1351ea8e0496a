"""Standard-form QP, solver-independent KKT figures and the solver registry.

Every tension-optimisation method of :mod:`msk.optimization` is mapped (in scaled variables, so
that all unknowns are O(1)) onto one standard form::

    minimise   ½ xᵀ H x + gᵀ x
    subject to A x = b          (m_eq rows, possibly none)
               cl ≤ C x ≤ cu    (m_in general inequality rows, possibly none; ±inf allowed)
               lb ≤ x ≤ ub      (±inf allowed)

and solved by a registered solver. The KKT figures are recomputed from the returned ``x`` alone
(independently of the solver's own multipliers), so that two solvers are judged the same way.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import OptimizationError
from msk.units import Array

__all__ = [
    "ACTIVE_TOL",
    "CLARABEL_OPTIONS",
    "DAQP_OPTIONS",
    "DEFAULT_SOLVER",
    "KKT",
    "KKT_BATCH_CONDITION",
    "KKT_CHUNK",
    "KKT_COLUMNS",
    "OSQP_OPTIONS",
    "STATUS_INFEASIBLE",
    "STATUS_NAMES",
    "STATUS_OPTIMAL",
    "STATUS_SOLVER_FAILED",
    "KKTBatch",
    "RawResult",
    "SolveOutput",
    "SolverSpec",
    "StandardQP",
    "active_bounds",
    "active_masks",
    "available_solvers",
    "get_solver",
    "kkt",
    "kkt_batch",
    "kkt_scale",
    "kkt_stacked",
    "least_squares_fallback",
    "new_warm",
    "register_solver",
    "solve_standard",
]

#: Frame status codes of batch solutions (``status`` arrays) and their names.
STATUS_OPTIMAL = 0
STATUS_INFEASIBLE = 1
STATUS_SOLVER_FAILED = 2
STATUS_NAMES: tuple[str, ...] = ("optimal", "infeasible", "solver_failed")

#: Relative distance to a bound under which the bound counts as active.
ACTIVE_TOL = 1e-9


@dataclass(frozen=True)
class StandardQP:
    """``min ½xᵀHx + gᵀx  s.t.  A x = b, cl ≤ C x ≤ cu, lb ≤ x ≤ ub`` (scaled variables;
    ``C`` None: no inequality rows)."""

    H: Array
    g: Array
    A: Array
    b: Array
    lb: Array
    ub: Array
    C: Array | None = None
    cl: Array | None = None
    cu: Array | None = None

    @property
    def n(self) -> int:
        return self.g.shape[0]

    @property
    def m_eq(self) -> int:
        return self.b.shape[0]

    @property
    def m_in(self) -> int:
        return 0 if self.C is None else self.C.shape[0]

    def inequality_rows(self) -> tuple[Array, Array, Array]:
        """``(C, cl, cu)``, empty ``(0, n)`` / ``(0,)`` when there are none."""
        if self.C is None:
            return np.zeros((0, self.n)), np.zeros(0), np.zeros(0)
        n_in = self.C.shape[0]
        cl = np.full(n_in, -np.inf) if self.cl is None else self.cl
        cu = np.full(n_in, np.inf) if self.cu is None else self.cu
        return self.C, cl, cu


@dataclass(frozen=True)
class KKT:
    """KKT figures of a QP solution, in the scaled variables of its standard form.

    Stationarity ``‖Hx + g + Aᵀν − μ_l + μ_u‖∞`` over the free variables (ν fitted by least
    squares, μ read off the active bounds), primal feasibility ``max(‖Ax − b‖∞, bound
    violation)``, dual feasibility ``max(0, −min μ)`` and complementarity ``max |μ_i · slack_i|``.
    """

    stationarity: float
    primal_feasibility: float
    dual_feasibility: float
    complementarity: float

    def max(self) -> float:
        """Largest of the four figures."""
        return max(
            self.stationarity, self.primal_feasibility, self.dual_feasibility, self.complementarity
        )

    def as_array(self) -> Array:
        return np.array(
            [
                self.stationarity,
                self.primal_feasibility,
                self.dual_feasibility,
                self.complementarity,
            ]
        )


KKT_COLUMNS: tuple[str, ...] = (
    "stationarity",
    "primal_feasibility",
    "dual_feasibility",
    "complementarity",
)


def active_masks(x: Array, lb: Array, ub: Array) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Masks of the lower and upper bounds active at ``x`` (relative tolerance ACTIVE_TOL);
    any shape (one frame, or frames stacked on axis 0)."""
    # x is finite, so x − (±inf) is ±inf (no NaN); infinite bounds are masked out
    lo = np.isfinite(lb) & (x - lb <= ACTIVE_TOL * (1.0 + np.abs(lb)))
    up = np.isfinite(ub) & (ub - x <= ACTIVE_TOL * (1.0 + np.abs(ub))) & ~lo
    return lo, up


def active_bounds(qp: StandardQP, x: Array) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Masks of the lower and upper bounds of ``qp`` active at ``x``."""
    return active_masks(x, qp.lb, qp.ub)


def kkt(qp: StandardQP, x: Array) -> KKT:
    """Solver-independent KKT figures of ``x`` for ``qp`` (see :class:`KKT`).

    The equality multipliers ν are fitted by least squares on the free variables; when those do
    not determine ν (fewer independent free columns than equality rows, a degenerate vertex),
    ν and the bound multipliers μ ≥ 0 are fitted together by bounded least squares over all
    variables, so that the figures measure whether *some* valid multipliers exist. Inequality
    rows ``cl ≤ C x ≤ cu`` active at ``x`` (relative tolerance :data:`ACTIVE_TOL`) join the
    equality rows in that fit; their multipliers must have the sign of the active side
    (dual feasibility) and vanish off it (complementarity), as the bounds' do.
    """
    grad = qp.H @ x + qp.g
    lo, up = active_bounds(qp, x)
    free = ~(lo | up)
    eq = float(np.max(np.abs(qp.A @ x - qp.b))) if qp.m_eq else 0.0
    c_mat, cl, cu = qp.inequality_rows()
    cx = c_mat @ x
    ilo, iup = active_masks(cx, cl, cu)
    iact = np.flatnonzero(ilo | iup)
    rows = np.vstack([qp.A, c_mat[iact]]) if iact.size else qp.A
    n_rows = rows.shape[0]
    full = grad
    nu = np.zeros(n_rows)
    if n_rows:
        af = rows[:, free]
        nu, _, rank, _ = np.linalg.lstsq(af.T, -grad[free], rcond=None)
        if rank < n_rows and ((lo | up).any() or iact.size):
            from scipy.optimize import lsq_linear

            act = np.flatnonzero(lo | up)
            e = np.zeros((qp.n, act.size))
            e[act, np.arange(act.size)] = np.where(lo[act], -1.0, 1.0)
            mat = np.hstack([rows.T, e])
            # an active lower inequality row enters as −λ Cᵀ (ν ≤ 0), an upper one as +λ Cᵀ
            in_lo = np.where(ilo[iact], -np.inf, 0.0)
            in_hi = np.where(ilo[iact], 0.0, np.inf)
            lower = np.concatenate([np.full(qp.m_eq, -np.inf), in_lo, np.zeros(act.size)])
            upper = np.concatenate([np.full(qp.m_eq, np.inf), in_hi, np.full(act.size, np.inf)])
            sol = lsq_linear(mat, -grad, bounds=(lower, upper), tol=1e-14, method="bvls")
            nu = sol.x[:n_rows]
        full = grad + rows.T @ nu
    stat = float(np.max(np.abs(full[free]))) if free.any() else 0.0
    mu = np.zeros_like(x)
    mu[lo] = full[lo]
    mu[up] = -full[up]
    lam = np.where(ilo[iact], -nu[qp.m_eq :], nu[qp.m_eq :]) if iact.size else np.zeros(0)
    with np.errstate(invalid="ignore"):
        viol = np.concatenate(
            [
                np.maximum(qp.lb - x, 0.0),
                np.maximum(x - qp.ub, 0.0),
                np.maximum(cl - cx, 0.0),
                np.maximum(cx - cu, 0.0),
            ]
        )
    viol = viol[np.isfinite(viol)]
    primal = max(eq, float(viol.max()) if viol.size else 0.0)
    dual = max(0.0, float(-mu.min()) if mu.size else 0.0, float(-lam.min()) if lam.size else 0.0)
    slack = np.zeros_like(x)
    slack[lo] = x[lo] - qp.lb[lo]
    slack[up] = qp.ub[up] - x[up]
    comp = float(np.max(np.abs(mu * slack))) if mu.size else 0.0
    if iact.size:
        rs = np.where(ilo[iact], cx[iact] - cl[iact], cu[iact] - cx[iact])
        comp = max(comp, float(np.max(np.abs(lam * rs))))
    return KKT(stat, primal, dual, comp)


def kkt_scale(qp: StandardQP, x: Array) -> Array:
    """The magnitudes the four KKT figures of ``x`` are judged against (:data:`KKT_COLUMNS`
    order): stationarity and dual feasibility against ``1 + ‖Hx + g‖∞`` (the multipliers are
    components of the gradient), primal feasibility against ``1 + max(‖b‖∞, ‖Ax‖∞, ‖Cx‖∞)``
    (the right-hand sides, e.g. scaled joint torques), complementarity (a multiplier times a
    slack) against ``(1 + ‖Hx + g‖∞)(1 + ‖x‖∞)``."""
    c_mat, _, _ = qp.inequality_rows()
    x2 = x[None, :]
    return _scales(
        (qp.H @ x + qp.g)[None, :], qp.b[None, :], (qp.A @ x)[None, :], (c_mat @ x)[None, :], x2
    )[0]


def _scales(grad: Array, b: Array, ax: Array, cx: Array, x: Array) -> Array:
    """:func:`kkt_scale` of frames stacked on axis 0."""
    g_mag = 1.0 + np.max(np.abs(grad), axis=1, initial=0.0)
    rhs_mag = 1.0 + np.max(
        np.abs(np.concatenate([b, ax, np.where(np.isfinite(cx), cx, 0.0)], axis=1)),
        axis=1, initial=0.0,
    )  # fmt: skip
    x_mag = 1.0 + np.max(np.abs(x), axis=1, initial=0.0)
    return np.stack([g_mag, rhs_mag, g_mag, g_mag * x_mag], axis=1)


@dataclass(frozen=True)
class KKTBatch:
    """KKT figures of frames stacked on axis 0: ``figures`` ``(K, 4)`` as
    :meth:`KKT.as_array` (columns :data:`KKT_COLUMNS`), ``scale`` ``(K, 4)`` the magnitudes
    they are judged against (:func:`kkt_scale`), ``fallback`` ``(K,)`` the frames whose
    multipliers the free columns did not determine (figures by :func:`kkt`'s bounded least
    squares)."""

    figures: Array
    scale: Array
    fallback: NDArray[np.bool_]

    @property
    def relative(self) -> Array:
        """``figures / scale`` ``(K, 4)``."""
        return np.asarray(self.figures / self.scale)


#: frames per stacked factorisation of :func:`kkt_batch` (bounds its working memory)
KKT_CHUNK = 256

#: largest 1-norm condition number of a frame's Gram matrix ``af afᵀ`` (rows × free columns)
#: whose multipliers :func:`kkt_batch` fits by the stacked semi-normal equations: there the
#: figures equal :func:`kkt`'s to 1e-11 of their scale (random QPs: ≤ 3e-12 up to 1e6, up to
#: 2e-9 between 1e6 and 1e8, where both are round-off of a badly conditioned fit), and the
#: fit is far from the rank cutoff of :func:`numpy.linalg.lstsq` (κ ~ 1e13): every such
#: frame is one whose rows its free columns determine, as :func:`kkt` finds. A frame above it
#: is computed by :func:`kkt` itself. The tension QPs of gc5_PS and UWA running: 3e4–7e4.
KKT_BATCH_CONDITION = 1e6


def kkt_batch(qps: Sequence[StandardQP], xs: ArrayLike) -> KKTBatch:
    """:func:`kkt` of every ``(qps[k], xs[k])`` (QPs of equal dimensions), computed over the
    frames at once (:func:`kkt_stacked` on their stacked arrays), and the figures' scales
    (:func:`kkt_scale`)."""
    h0 = qps[0].H
    ineq = [q.inequality_rows() for q in qps]
    return kkt_stacked(
        h0 if all(q.H is h0 for q in qps) else _stack(qps, "H"), _stack(qps, "g"),
        _stack(qps, "A"), _stack(qps, "b"), _stack(qps, "lb"), _stack(qps, "ub"),
        np.asarray(xs, dtype=float), np.stack([c for c, _, _ in ineq]),
        np.stack([v for _, v, _ in ineq]), np.stack([v for _, _, v in ineq]),
    )  # fmt: skip


def kkt_stacked(
    h: Array,
    g: Array,
    a: Array,
    b: Array,
    lb: Array,
    ub: Array,
    x: Array,
    c: Array | None = None,
    cl: Array | None = None,
    cu: Array | None = None,
) -> KKTBatch:
    """:func:`kkt` and :func:`kkt_scale` of ``K`` frames given as stacked arrays: ``h``
    ``(n, n)`` shared or ``(K, n, n)``; ``g``, ``lb``, ``ub`` ``(n,)`` shared or ``(K, n)``;
    ``a`` ``(K, m_eq, n)``, ``b`` ``(K, m_eq)``; ``x`` ``(K, n)``; inequality rows ``c``
    ``(K, m_in, n)`` with ``cl``, ``cu`` ``(K, m_in)`` (None: ±inf), or None.

    Each frame's least-squares fit of the multipliers ν of its equality rows and active
    inequality rows over its free variables (:func:`kkt`) is done for all frames at once, on
    the ``(K, rows, n)`` stack of their matrices with the columns of active variables and the
    rows of inactive inequalities zeroed (:func:`_fit_multipliers`: corrected semi-normal
    equations). A frame whose fit is ill-conditioned (1-norm condition number of its Gram
    matrix above :data:`KKT_BATCH_CONDITION`) or singular — among them every frame whose
    free columns do not determine ν, which :func:`kkt` fits by bounded least squares — is
    computed by :func:`kkt` itself (``fallback``). Equal to :func:`kkt` frame by frame to
    round-off, 1e-11 of :func:`kkt_scale` (``tests/optimization/test_optimization.py``: random QPs
    with
    random active sets, rank-deficient and ill-conditioned frames among them)."""
    n_fr, n = x.shape
    if c is None:
        c, cl, cu = np.zeros((n_fr, 0, n)), np.zeros((n_fr, 0)), np.zeros((n_fr, 0))
    m_in = c.shape[1]
    cl = np.full((n_fr, m_in), -np.inf) if cl is None else cl
    cu = np.full((n_fr, m_in), np.inf) if cu is None else cu
    figs = np.zeros((n_fr, 4))
    scale = np.ones((n_fr, 4))
    fb = np.zeros(n_fr, dtype=bool)

    def part(v: Array, sl: slice, ndim: int) -> Array:
        return v if v.ndim < ndim else v[sl]

    for i in range(0, n_fr, KKT_CHUNK):
        sl = slice(i, min(i + KKT_CHUNK, n_fr))
        figs[sl], scale[sl], fb[sl] = _kkt_chunk(
            part(h, sl, 3), part(g, sl, 2), a[sl], b[sl], part(lb, sl, 2), part(ub, sl, 2),
            x[sl], c[sl], cl[sl], cu[sl],
        )  # fmt: skip
    return KKTBatch(figs, scale, fb)


def _kkt_chunk(
    h: Array,
    g: Array,
    a_mat: Array,
    b_vec: Array,
    lb: Array,
    ub: Array,
    x: Array,
    c_mat: Array,
    cl: Array,
    cu: Array,
) -> tuple[Array, Array, NDArray[np.bool_]]:
    k_fr = x.shape[0]
    grad = (x @ h.T if h.ndim == 2 else (h @ x[:, :, None])[:, :, 0]) + g
    lb, ub = np.broadcast_to(lb, x.shape), np.broadcast_to(ub, x.shape)
    m_eq = a_mat.shape[1]
    lo, up = active_masks(x, lb, ub)
    free = ~(lo | up)
    ax = (a_mat @ x[:, :, None])[:, :, 0]
    cx = (c_mat @ x[:, :, None])[:, :, 0]
    ilo, iup = active_masks(cx, cl, cu)
    iact = ilo | iup
    rows = np.concatenate([a_mat, c_mat], axis=1)
    row_on = np.concatenate([np.ones((k_fr, m_eq), dtype=bool), iact], axis=1)
    r_tot = rows.shape[1]
    nu = np.zeros((k_fr, r_tot))
    need = np.zeros(k_fr, dtype=bool)
    if r_tot:
        # each frame's af (rows × free columns) as one (K, r, n) stack, the other entries zeroed
        rm = np.where(row_on[:, :, None], rows, 0.0)
        af = np.where(free[:, None, :], rm, 0.0)
        nu, need = _fit_multipliers(af, np.where(free, -grad, 0.0), row_on)
        full = grad + (nu[:, None, :] @ rm)[:, 0]
    else:
        full = grad
    stat = np.max(np.where(free, np.abs(full), 0.0), axis=1, initial=0.0)
    mu = np.where(lo, full, np.where(up, -full, 0.0))
    nu_in = nu[:, m_eq:]
    lam = np.where(iact, np.where(ilo, -nu_in, nu_in), 0.0)
    with np.errstate(invalid="ignore"):
        viol = np.concatenate(
            [np.maximum(lb - x, 0.0), np.maximum(x - ub, 0.0), np.maximum(cl - cx, 0.0),
             np.maximum(cx - cu, 0.0)],
            axis=1,
        )  # fmt: skip
    viol = np.where(np.isfinite(viol), viol, 0.0)
    eq = np.max(np.abs(ax - b_vec), axis=1, initial=0.0)
    primal = np.maximum(eq, np.max(viol, axis=1, initial=0.0))
    dual = 0.0 + np.maximum(  # + 0.0: no −0.0
        0.0, np.maximum(np.max(-mu, axis=1, initial=0.0), np.max(-lam, axis=1, initial=0.0))
    )
    slack = np.where(lo, x - lb, np.where(up, ub - x, 0.0))
    rs = np.where(iact, np.where(ilo, cx - cl, cu - cx), 0.0)
    comp = np.maximum(
        np.max(np.abs(mu * slack), axis=1, initial=0.0),
        np.max(np.abs(lam * rs), axis=1, initial=0.0),
    )
    figs = np.stack([stat, primal, dual, comp], axis=1)
    for k in np.flatnonzero(need).tolist():
        qp = StandardQP(
            h if h.ndim == 2 else h[k], g if g.ndim == 1 else g[k], a_mat[k], b_vec[k], lb[k],
            ub[k], c_mat[k] if c_mat.shape[1] else None, cl[k], cu[k],
        )  # fmt: skip
        figs[k] = kkt(qp, x[k]).as_array()
    return figs, _scales(grad, b_vec, ax, cx, x), need


def _fit_multipliers(
    af: Array, rhs: Array, row_on: NDArray[np.bool_]
) -> tuple[Array, NDArray[np.bool_]]:
    """``ν = argmin ‖afᵀ ν − rhs‖`` of every frame (``af`` ``(K, r, n)``, rows that are off
    all zero and given ν = 0) by the corrected semi-normal equations (Björck 1987, "Stability
    analysis of the method of seminormal equations for linear least squares problems", Linear
    Algebra Appl. 88–89:31–48, §4: one step of refinement makes them as accurate as a QR
    solution while κ(af)² ε < 1), and the frames left to :func:`kkt`: those whose Gram matrix
    ``af afᵀ`` is singular or has a 1-norm condition number above
    :data:`KKT_BATCH_CONDITION`."""
    k_fr, r_tot, _ = af.shape
    gram = af @ np.swapaxes(af, 1, 2)
    gram += np.eye(r_tot) * ~row_on[:, None, :]  # a row that is off: ν = 0 alone
    # a row with no free column
    dead = np.asarray(~(np.diagonal(gram, axis1=1, axis2=2) > 0).all(axis=1), dtype=bool)
    gram[dead] = np.eye(r_tot)
    try:
        ginv = np.linalg.inv(gram)
    except np.linalg.LinAlgError:  # an exactly singular frame: frame by frame
        ginv = np.empty_like(gram)
        for k in range(k_fr):
            try:
                ginv[k] = np.linalg.inv(gram[k])
            except np.linalg.LinAlgError:
                ginv[k], dead[k] = np.eye(r_tot), True
    nu = ginv @ (af @ rhs[:, :, None])  # (K, r, 1)
    resid = rhs[:, :, None] - np.swapaxes(af, 1, 2) @ nu
    nu += ginv @ (af @ resid)
    cond = np.abs(gram).sum(axis=1).max(axis=1) * np.abs(ginv).sum(axis=1).max(axis=1)
    return nu[:, :, 0], dead | ~(cond <= KKT_BATCH_CONDITION)


def _stack(qps: Sequence[StandardQP], name: str) -> Array:
    return np.stack([getattr(q, name) for q in qps])


# ---------------------------------------------------------------------------------------------
# solver registry
# ---------------------------------------------------------------------------------------------


@dataclass
class SolveOutput:
    """What a registered solver returns for one QP."""

    x: Array | None
    ok: bool
    infeasible: bool
    iterations: int = -1
    warm: Any = None


@dataclass
class SolverSpec:
    """A registered QP solver: ``solve(qp, warm) -> SolveOutput``.

    ``warm`` is whatever the solver returned as ``SolveOutput.warm`` for the previous frame
    (``None`` on the first frame or with ``warm_start=False``); it must not be required.
    """

    name: str
    solve: Callable[[StandardQP, Any], SolveOutput]
    description: str = ""
    options: dict[str, Any] = field(default_factory=dict)


_REGISTRY: dict[str, SolverSpec] = {}

#: Default solver: DAQP (dual active set, exact to round-off, warm start by working set).
DEFAULT_SOLVER = "daqp"


def register_solver(spec: SolverSpec) -> None:
    """Add (or replace) a solver in the registry under ``spec.name``."""
    _REGISTRY[spec.name] = spec


def available_solvers() -> tuple[str, ...]:
    """Names of the registered solvers (backends are imported only when first used)."""
    return tuple(sorted(_REGISTRY))


def get_solver(name: str) -> SolverSpec:
    try:
        return _REGISTRY[name]
    except KeyError:
        raise OptimizationError(
            f"unknown QP solver {name!r}; registered: {', '.join(available_solvers())}"
        ) from None


# --- DAQP, lower-level API (no qpsolvers overhead) -------------------------------------------


class _DaqpWarm:
    """A DAQP workspace kept across frames; ``update`` reuses the previous working set."""

    def __init__(self) -> None:
        self.model: Any = None
        self.shape: tuple[int, int, int] | None = None
        self.h: Any = None  # the H and g objects last sent: unchanged objects are not re-sent
        self.g: Any = None


def _daqp_sense(qp: StandardQP) -> NDArray[np.int32]:
    sense = np.zeros(qp.n + qp.m_eq + qp.m_in, dtype=np.int32)
    sense[qp.n : qp.n + qp.m_eq] = 5  # ACTIVE + IMMUTABLE: equality; inequality rows 0
    return sense


#: DAQP settings: primal tolerance tightened from its default 1e-6 (bounds could be violated by
#: 1e-6 in scaled units, i.e. mN) so that every solution satisfies KKT to 1e-10.
DAQP_OPTIONS: dict[str, Any] = {"primal_tol": 1e-10}


def _solve_daqp(qp: StandardQP, warm: Any) -> SolveOutput:
    import daqp

    bu = np.concatenate((qp.ub, qp.b))
    bl = np.concatenate((qp.lb, qp.b))
    a = qp.A if qp.m_eq else np.zeros((0, qp.n))
    if qp.m_in:  # general inequality rows after the equalities (DAQP sense 0)
        c_mat, cl, cu = qp.inequality_rows()
        a = np.ascontiguousarray(np.vstack([a, c_mat]))
        bu = np.concatenate((bu, np.where(np.isfinite(cu), cu, 1e30)))
        bl = np.concatenate((bl, np.where(np.isfinite(cl), cl, -1e30)))
    rows = qp.m_eq + qp.m_in
    if isinstance(warm, _DaqpWarm):
        if warm.model is not None and warm.shape == (qp.n, qp.m_eq, qp.m_in):
            h = None if qp.H is warm.h else qp.H
            g = None if qp.g is warm.g else qp.g
            if warm.model.update(H=h, f=g, A=a if rows else None, bupper=bu, blower=bl) < 0:
                warm.model = None  # the update found the frame infeasible: solve it cold
        else:
            warm.model = daqp.Model()
            warm.model.settings = DAQP_OPTIONS
            if warm.model.setup(qp.H, qp.g, a, bu, bl, _daqp_sense(qp))[0] < 0:
                warm.model = None  # e.g. infeasible bounds found by the setup: solve cold
            warm.shape = (qp.n, qp.m_eq, qp.m_in)
        warm.h, warm.g = qp.H, qp.g
    if isinstance(warm, _DaqpWarm) and warm.model is not None:
        x, _, flag, info = warm.model.solve()
        if flag < 0:  # do not carry a failed working set into the next frame
            warm.model = None
    else:
        x, _, flag, info = daqp.solve(qp.H, qp.g, a, bu, bl, _daqp_sense(qp), **DAQP_OPTIONS)
    ok = flag > 0
    return SolveOutput(
        x=np.asarray(x, dtype=float) if ok else None,
        ok=ok,
        infeasible=flag == -1,
        iterations=int(info.get("iterations", -1)),
        warm=warm,
    )


def _new_daqp_warm() -> _DaqpWarm:
    return _DaqpWarm()


# --- qpsolvers back-ends with tight tolerances -----------------------------------------------

#: Tolerances that make the first-order / interior-point solvers agree with DAQP to ~1e-9.
OSQP_OPTIONS: dict[str, Any] = {
    "eps_abs": 1e-9,
    "eps_rel": 1e-9,
    "polishing": True,  # OSQP ≥ 1.0 name of ``polish``
    "max_iter": 200_000,
    "raise_error": False,
}
CLARABEL_OPTIONS: dict[str, Any] = {
    # at 1e-11 alone Clarabel stops ~1e-5 (relative) away on problems with many active bounds;
    # less static regularisation and tighter iterative refinement bring it to ~1e-7
    "tol_gap_abs": 1e-13,
    "tol_gap_rel": 1e-13,
    "tol_feas": 1e-13,
    "tol_ktratio": 1e-12,
    "max_iter": 500,
    "static_regularization_constant": 1e-12,
    "iterative_refinement_reltol": 1e-16,
    "iterative_refinement_abstol": 1e-16,
}


def _qpsolvers_solver(
    name: str, options: dict[str, Any]
) -> Callable[[StandardQP, Any], SolveOutput]:
    def solve(qp: StandardQP, warm: Any) -> SolveOutput:
        import qpsolvers

        lb = np.where(np.isfinite(qp.lb), qp.lb, -1e20)
        ub = np.where(np.isfinite(qp.ub), qp.ub, 1e20)
        gmat = hvec = None
        if qp.m_in:  # cl ≤ C x ≤ cu as G x ≤ h (finite sides only)
            c_mat, cl, cu = qp.inequality_rows()
            up_, lo_ = np.isfinite(cu), np.isfinite(cl)
            gmat = np.vstack([c_mat[up_], -c_mat[lo_]])
            hvec = np.concatenate([cu[up_], -cl[lo_]])
        problem = qpsolvers.Problem(
            qp.H,
            qp.g,
            G=gmat,
            h=hvec,
            A=qp.A if qp.m_eq else None,
            b=qp.b if qp.m_eq else None,
            lb=lb,
            ub=ub,
        )
        initvals = warm if isinstance(warm, np.ndarray) and warm.shape == (qp.n,) else None
        opts = dict(options)
        sol = qpsolvers.solve_problem(problem, solver=name, initvals=initvals, **opts)
        x = None if sol.x is None else np.asarray(sol.x, dtype=float)
        # a point is accepted when it is feasible to 1e-6 (relative), whatever the solver's
        # flag: interior-point methods report "almost solved" on degenerate problems without a
        # strictly feasible point, which are feasible nonetheless; the KKT figures judge it
        ok = x is not None and bool(np.all(np.isfinite(x)))
        if ok and x is not None:
            scale = 1.0 + (float(np.max(np.abs(qp.b))) if qp.m_eq else 0.0)
            eq = float(np.max(np.abs(qp.A @ x - qp.b))) if qp.m_eq else 0.0
            with np.errstate(invalid="ignore"):
                bnd = max(float(np.max(qp.lb - x)), float(np.max(x - qp.ub)), 0.0)
                if qp.m_in:
                    c_mat, cl, cu = qp.inequality_rows()
                    cx = c_mat @ x
                    bnd = max(bnd, float(np.max(cl - cx)), float(np.max(cx - cu)))
            almost = qp.m_eq > 0 and eq <= 1e-8 * scale
            ok = eq <= 1e-6 * scale and bnd <= 1e-6 and (bool(sol.found) or almost)
        return SolveOutput(x=x if ok else None, ok=ok, infeasible=not ok, warm=x)

    return solve


register_solver(
    SolverSpec(
        "daqp",
        _solve_daqp,
        description="DAQP dual active-set, direct API; warm start keeps the working set",
    )
)
register_solver(
    SolverSpec(
        "osqp",
        _qpsolvers_solver("osqp", OSQP_OPTIONS),
        description="OSQP via qpsolvers, eps_abs = eps_rel = 1e-9, polish",
        options=OSQP_OPTIONS,
    )
)
register_solver(
    SolverSpec(
        "clarabel",
        _qpsolvers_solver("clarabel", CLARABEL_OPTIONS),
        description="Clarabel interior point via qpsolvers, tolerances 1e-13",
        options=CLARABEL_OPTIONS,
    )
)
register_solver(
    SolverSpec(
        "daqp-qpsolvers",
        _qpsolvers_solver("daqp", {}),
        description="DAQP through the qpsolvers front end (for measuring its overhead)",
    )
)


def new_warm(solver: str) -> Any:
    """A fresh warm-start object for ``solver`` (DAQP workspace, or the previous x)."""
    return _new_daqp_warm() if solver == "daqp" else None


# ---------------------------------------------------------------------------------------------
# one frame
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class RawResult:
    """A solved standard-form QP (scaled variables)."""

    x: Array
    status: int
    iterations: int
    solve_time_s: float
    kkt: KKT | None
    #: :func:`kkt_scale` of ``x`` (with ``kkt``)
    kkt_scale: Array | None = None


def least_squares_fallback(qp: StandardQP, solver: str) -> StandardQP:
    """The bounded least-squares problem solved for an infeasible frame.

    ``min ½‖A x − b‖² + ½ε (xᵀHx + 2gᵀx)  s.t. lb ≤ x ≤ ub`` with a small ε (1e-10 relative to
    ‖AᵀA‖): the bounds hold, the torque residual ``b − A x`` is as small as the bounds allow, and
    the original cost breaks the ties. Inequality rows are kept as constraints.
    """
    ata = qp.A.T @ qp.A
    eps = 1e-10 * max(1.0, float(np.max(np.abs(np.diag(ata)))))
    return StandardQP(
        H=ata + eps * qp.H,
        g=-qp.A.T @ qp.b + eps * qp.g,
        A=np.zeros((0, qp.n)),
        b=np.zeros(0),
        lb=qp.lb,
        ub=qp.ub,
        C=qp.C,
        cl=qp.cl,
        cu=qp.cu,
    )


def solve_standard(
    qp: StandardQP,
    *,
    solver: str,
    warm: Any = None,
    compute_kkt: bool = True,
    frame: int | None = None,
    strict: bool = False,
) -> tuple[RawResult, Any]:
    """Solve one frame; infeasible frames get the bounded least-squares point and a status."""
    spec = get_solver(solver)
    t0 = time.perf_counter()
    out = spec.solve(qp, warm)
    status = STATUS_OPTIMAL
    x = out.x
    if not out.ok:
        status = STATUS_INFEASIBLE if out.infeasible else STATUS_SOLVER_FAILED
        fb = spec.solve(least_squares_fallback(qp, solver), None)
        if fb.x is None:
            fb = get_solver("daqp").solve(least_squares_fallback(qp, solver), None)
        x = fb.x if fb.x is not None else np.clip(np.zeros(qp.n), qp.lb, qp.ub)
    assert x is not None
    # bounds hold to the solver's primal tolerance (1e-10 scaled); make them hold exactly so
    # that a tension is never reported as, e.g., −1e-8 N
    x = np.minimum(np.maximum(x, qp.lb), qp.ub)
    elapsed = time.perf_counter() - t0
    res = RawResult(
        x=x,
        status=status,
        iterations=out.iterations,
        solve_time_s=elapsed,
        kkt=kkt(qp, x) if compute_kkt else None,
        kkt_scale=kkt_scale(qp, x) if compute_kkt else None,
    )
    if strict and status != STATUS_OPTIMAL:
        where = f"frame {frame}" if frame is not None else "the frame"
        resid = float(np.linalg.norm(qp.A @ x - qp.b)) if qp.m_eq else 0.0
        raise OptimizationError(
            f"{where}: QP {STATUS_NAMES[status]} with solver {solver!r}; best bounded "
            f"least-squares torque residual ‖τ − R f‖ = {resid:.6g} (N·m / N)"
        )
    return res, out.warm
