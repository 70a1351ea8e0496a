"""Closed-form Lagrange-multiplier solution and its precomputed-coefficient table (the
rehabilitation-robot lower-limb model paper).

Sign convention (all of :mod:`msk.optimization`): the muscle Jacobian is ``J = ∂l/∂θ``
(Hayashibe et al. 2011, Eq. 6), shape ``(n_muscles, n_coords)``; a tension ``f ≥ 0`` shortens the
muscle, so the generalised force it produces is ``τ = −Jᵀ f = R f`` with the moment-arm matrix
``R = −Jᵀ`` (OpenSim's ``computeMomentArm`` is ``−∂L/∂q``, i.e. a column of ``R``ᵀ).

The rehabilitation-robot lower-limb model paper, Eq. 5 writes the muscle generalised force as
``τ_Mus = Σ_i C_i F_i``, so ``C = R``, and minimises the squared sum of muscle stresses ``Σ
(F_i/A_i)²`` (``A_i`` the physiological cross-section area; any quantity proportional to it, e.g.
``F_iso``, gives the same forces). With one coordinate, Lagrange multipliers give Eq. 6::

    F_i = A_i² C_i τ_Mus / Σ_j (A_j C_j)²

With ``n`` coordinates and ``W = diag(A²)`` the same stationarity condition
``2 W⁻¹ F = Cᵀ λ`` and ``C F = τ`` give::

    F = K τ,    K = W Cᵀ (C W Cᵀ)⁻¹               (n_muscles × n_coords)

which reduces to Eq. 6 for ``n = 1``. The solution is **unbounded**: nothing keeps ``F ≥ 0``,
so a muscle whose moment arm opposes the torque gets a negative (compressive) force; such
forces are flagged in ``negative``, never clipped. Use :func:`msk.optimization.solve_tension`
when the bounds matter; both agree whenever no bound is active.

Because ``K`` depends only on the posture, the rehabilitation-robot lower-limb model paper, §2.2
(items 3–4) computes it offline over the workspace of a *functional* degree of freedom ``s`` (e.g.
knee flexion, the other coordinates following it), and online only looks it up:
:class:`CoefficientTable`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import OptimizationError
from msk.optimization._common import (
    as_float,
    check_frame,
    check_jacobian,
    check_positive,
    names_or_default,
    set_fields,
)
from msk.optimization._qp import KKT, StandardQP, kkt
from msk.units import Array

__all__ = [
    "SINGULAR_COND",
    "CoefficientTable",
    "LagrangeBatchSolution",
    "LagrangeProblem",
    "LagrangeSolution",
    "build_coefficient_table",
    "lagrange_coefficients",
    "solve_lagrange",
    "solve_lagrange_batch",
]

#: Condition number of ``C W Cᵀ`` beyond which a frame is declared singular (pseudo-inverse).
SINGULAR_COND = 1e12


def lagrange_coefficients(jacobian: ArrayLike, area: ArrayLike) -> Array:
    """``K = W Cᵀ (C W Cᵀ)⁻¹`` with ``C = −Jᵀ``, ``W = diag(A²)`` (the rehabilitation-robot
    lower-limb model paper, Eq. 6, n coords).

    ``jacobian`` is ``(n_muscles, n_coords)`` or a stack ``(N, n_muscles, n_coords)``; the result
    has the same leading shape. A singular ``C W Cᵀ`` (a coordinate no muscle crosses) uses the
    pseudo-inverse, which gives the least-squares torque fit.
    """
    j = np.asarray(jacobian, dtype=float)
    w = np.asarray(area, dtype=float) ** 2
    c = -np.swapaxes(j, -1, -2)  # (..., n, m)
    wct = w[:, None] * np.swapaxes(c, -1, -2)  # (..., m, n)
    m = c @ wct  # (..., n, n)
    try:
        cond = np.linalg.cond(m)
    except np.linalg.LinAlgError:
        cond = np.full(m.shape[:-2], np.inf)
    cond = np.nan_to_num(np.asarray(cond), nan=np.inf)
    if np.all(cond < SINGULAR_COND):
        return np.swapaxes(np.linalg.solve(m, np.swapaxes(wct, -1, -2)), -1, -2)
    return wct @ np.linalg.pinv(m, hermitian=True)


@dataclass(frozen=True)
class LagrangeProblem:
    """``min Σ (F_i/A_i)²  s.t.  C F = τ`` (the rehabilitation-robot lower-limb model paper, Eq.
    5–6), unbounded.

    ``jacobian`` ``J = ∂l/∂θ`` ``(n_muscles, n_coords)``, ``tau`` ``(n_coords,)`` the muscle
    generalised force ``τ_Mus`` (N·m, or N for a translation), ``area`` ``A_i`` ``(n_muscles,)``
    (PCSA in m², or ``F_iso`` in N: only ratios matter).
    """

    jacobian: Array
    tau: Array
    area: Array
    muscle_names: tuple[str, ...] | None = None
    coordinate_names: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        j, tau, mn, cn = check_frame(
            self.jacobian, self.tau, self.muscle_names, self.coordinate_names
        )
        area = as_float(self.area, (j.shape[0],), "area")
        check_positive(area, "area", mn)
        set_fields(self, jacobian=j, tau=tau, area=area, muscle_names=mn, coordinate_names=cn)


@dataclass(frozen=True)
class LagrangeSolution:
    """Closed-form forces ``F = K τ`` and what they imply.

    ``multipliers`` are the Lagrange multipliers ``λ = 2 (C W Cᵀ)⁻¹ τ`` of ``C F = τ`` for the
    cost ``Σ (F_i/A_i)²``; ``residual`` ``τ − C F`` is zero to round-off unless ``singular``;
    ``negative`` flags the compressive forces the unbounded solution may give; ``status`` is
    ``"optimal"``, ``"negative_forces"`` or ``"singular"``; ``kkt`` the KKT figures of the
    equality-constrained problem in the scaled unknowns ``F/A`` (no bounds: dual feasibility and
    complementarity are 0 by construction).
    """

    forces: Array
    coefficients: Array
    multipliers: Array
    residual: Array
    residual_norm: float
    negative: NDArray[np.bool_]
    singular: bool
    status: str
    kkt: KKT
    solver: str = "lagrange-closed-form"


def solve_lagrange(problem: LagrangeProblem) -> LagrangeSolution:
    """Solve Eq. 6 of the rehabilitation-robot lower-limb model paper, generalised to several
    coordinates (see the module docstring)."""
    k = lagrange_coefficients(problem.jacobian, problem.area)
    f = k @ problem.tau
    c = -problem.jacobian.T
    resid = problem.tau - c @ f
    m = c @ (problem.area[:, None] ** 2 * c.T)
    singular = bool(np.linalg.cond(m) >= SINGULAR_COND)
    lam = 2.0 * (np.linalg.pinv(m, hermitian=True) @ problem.tau)
    neg = f < 0
    status = "singular" if singular else ("negative_forces" if neg.any() else "optimal")
    nv = f.shape[0]
    qp = StandardQP(
        H=2.0 * np.eye(nv),
        g=np.zeros(nv),
        A=c * problem.area,
        b=problem.tau,
        lb=np.full(nv, -np.inf),
        ub=np.full(nv, np.inf),
    )
    return LagrangeSolution(
        forces=f,
        coefficients=k,
        multipliers=lam,
        residual=resid,
        residual_norm=float(np.linalg.norm(resid)),
        negative=neg,
        singular=singular,
        status=status,
        kkt=kkt(qp, f / problem.area),
    )


@dataclass(frozen=True)
class LagrangeBatchSolution:
    """Closed-form forces over frames (time on axis 0)."""

    forces: Array  # (N, n_muscles)
    residual_norm: Array  # (N,)
    negative: NDArray[np.bool_]  # (N, n_muscles)
    muscle_names: tuple[str, ...]
    solver: str = "lagrange-closed-form"


def solve_lagrange_batch(
    jacobians: ArrayLike,
    taus: ArrayLike,
    *,
    area: ArrayLike,
    muscle_names: Sequence[str] | None = None,
) -> LagrangeBatchSolution:
    """The rehabilitation-robot lower-limb model paper, Eq. 6, vectorised over frames: ``F[k] =
    K(J[k]) τ[k]`` (one stacked solve)."""
    j = check_jacobian(jacobians, 3)
    n_frames, m, n = j.shape
    tau = as_float(taus, (n_frames, n), "taus")
    mn = names_or_default(muscle_names, m, "muscle", "muscle")
    a = as_float(area, (m,), "area")
    check_positive(a, "area", mn)
    k = lagrange_coefficients(j, a)
    f = np.einsum("kmn,kn->km", k, tau)
    resid = tau + np.einsum("kmn,km->kn", j, f)
    return LagrangeBatchSolution(
        forces=f,
        residual_norm=np.linalg.norm(resid, axis=1),
        negative=f < 0,
        muscle_names=mn,
    )


@dataclass(frozen=True)
class CoefficientTable:
    """Lagrange coefficients ``K(s)`` tabulated over a functional DOF ``s`` (the
    rehabilitation-robot lower-limb model paper, §2.2).

    ``grid`` ``(G,)`` strictly increasing values of ``s`` (e.g. knee flexion in rad),
    ``coefficients`` ``(G, n_muscles, n_coords)``. At run time ``F = K(s) τ`` with ``K``
    interpolated (``kind`` ``"linear"``: error ≤ h²/8 · max|K''|; ``"cubic"``: O(h⁴)). Build
    with :func:`build_coefficient_table`. Values of ``s`` outside the grid raise
    :class:`~msk.exceptions.OptimizationError` (no extrapolation).
    """

    grid: Array
    coefficients: Array
    kind: Literal["linear", "cubic"] = "cubic"
    muscle_names: tuple[str, ...] | None = None
    coordinate_names: tuple[str, ...] | None = None
    _spline: Any = field(init=False, repr=False, compare=False, default=None)

    def __post_init__(self) -> None:
        from scipy.interpolate import make_interp_spline

        g = np.asarray(self.grid, dtype=float)
        k = np.asarray(self.coefficients, dtype=float)
        if g.ndim != 1 or k.ndim != 3 or k.shape[0] != g.shape[0]:
            raise OptimizationError(
                f"coefficient table: grid {g.shape} and coefficients {k.shape} do not match "
                "(expected (G,) and (G, n_muscles, n_coords))"
            )
        if np.any(np.diff(g) <= 0):
            i = int(np.argmax(np.diff(g) <= 0))
            raise OptimizationError(
                "coefficient table grid must increase strictly; "
                f"grid[{i + 1}] = {float(g[i + 1])!r}"
            )
        order = 1 if self.kind == "linear" else 3
        if self.kind not in ("linear", "cubic"):
            raise OptimizationError(f"unknown interpolation kind {self.kind!r}")
        if g.shape[0] <= order:
            raise OptimizationError(f"{g.shape[0]} grid points are too few for {self.kind}")
        m, n = k.shape[1:]
        object.__setattr__(self, "grid", g)
        object.__setattr__(self, "coefficients", k)
        object.__setattr__(
            self, "muscle_names", names_or_default(self.muscle_names, m, "muscle", "muscle")
        )
        object.__setattr__(
            self,
            "coordinate_names",
            names_or_default(self.coordinate_names, n, "coord", "coordinate"),
        )
        object.__setattr__(self, "_spline", make_interp_spline(g, k.reshape(len(g), -1), k=order))

    def coefficients_at(self, s: ArrayLike) -> Array:
        """``K(s)``: ``(n_muscles, n_coords)`` for a scalar, ``(N, n_muscles, n_coords)`` else."""
        sv = np.asarray(s, dtype=float)
        flat = np.atleast_1d(sv)
        out = (flat < self.grid[0]) | (flat > self.grid[-1]) | ~np.isfinite(flat)
        if out.any():
            i = int(np.argmax(out))
            raise OptimizationError(
                f"functional coordinate at frame {i} = {float(flat[i])!r} is outside the "
                f"coefficient table [{float(self.grid[0])!r}, {float(self.grid[-1])!r}]"
            )
        k = self._spline(flat).reshape(flat.shape[0], *self.coefficients.shape[1:])
        return k[0] if sv.ndim == 0 else k

    def forces(self, s: ArrayLike, tau: ArrayLike) -> Array:
        """Run-time forces ``F = K(s) τ`` (``s`` scalar, ``tau`` (n,); or (N,) and (N, n))."""
        k = self.coefficients_at(s)
        t = np.asarray(tau, dtype=float)
        if k.ndim == 2:
            return k @ t
        return np.einsum("kmn,kn->km", k, t)


def build_coefficient_table(
    grid: ArrayLike,
    jacobians: ArrayLike,
    *,
    area: ArrayLike,
    kind: Literal["linear", "cubic"] = "cubic",
    muscle_names: Sequence[str] | None = None,
    coordinate_names: Sequence[str] | None = None,
) -> CoefficientTable:
    """Offline stage of the rehabilitation-robot lower-limb model paper, §2.2: ``K`` at each grid
    value of the functional DOF.

    ``jacobians`` ``(G, n_muscles, n_coords)`` are the muscle Jacobians evaluated along the
    functional path (every coordinate set from ``s`` by the subject's fDOF relations).
    """
    j = check_jacobian(jacobians, 3)
    m = j.shape[1]
    mn = names_or_default(muscle_names, m, "muscle", "muscle")
    a = as_float(area, (m,), "area")
    check_positive(a, "area", mn)
    return CoefficientTable(
        grid=np.asarray(grid, dtype=float),
        coefficients=lagrange_coefficients(j, a),
        kind=kind,
        muscle_names=mn,
        coordinate_names=tuple(coordinate_names) if coordinate_names is not None else None,
    )
