"""Tension optimisation per frame: muscle forces from generalised forces.

Convention: the muscle Jacobian ``J = ∂l/∂θ`` (Hayashibe et al. 2011, Eq. 6) has shape
``(n_muscles, n_coords)``; tensions ``f ≥ 0`` produce ``τ = −Jᵀ f = R f`` (moment arms
``R = −Jᵀ``, OpenSim's ``computeMomentArm``). Batch functions take ``(N, n_muscles, n_coords)``
and ``(N, n_coords)``, time on axis 0.

Methods (each a frozen Problem → Solution pair):

- :class:`LagrangeProblem` → :class:`LagrangeSolution`: closed form, the rehabilitation-robot
  lower-limb model paper, Eq. 6,
  unbounded; :class:`CoefficientTable` tabulates it over a functional DOF (the rehabilitation-robot
  lower-limb model paper, §2.2);
- :class:`TensionProblem` → :class:`QPSolution`: ``min Σ(f/F_iso)²``, ``R f = τ``, bounds,
  optional reserves;
- :class:`StaticOptimizationProblem`: OpenSim's StaticOptimization (activations², muscle
  physiology, residual/reserve actuators);
- :class:`EMGWeightedProblem`: Hayashibe et al. 2011, Eq. 17–18, and :func:`emg_weight_sweep` (Table
  I).

Solvers: a registry (:func:`available_solvers`, :func:`register_solver`); DAQP through its own
API by default (exact, warm-started across frames), OSQP and Clarabel through ``qpsolvers``
with tight tolerances.
"""

from msk.optimization._qp import (
    DEFAULT_SOLVER,
    KKT,
    KKT_COLUMNS,
    STATUS_INFEASIBLE,
    STATUS_NAMES,
    STATUS_OPTIMAL,
    STATUS_SOLVER_FAILED,
    KKTBatch,
    SolveOutput,
    SolverSpec,
    StandardQP,
    available_solvers,
    kkt,
    kkt_batch,
    kkt_scale,
    kkt_stacked,
    register_solver,
)
from msk.optimization.closed_form import (
    CoefficientTable,
    LagrangeBatchSolution,
    LagrangeProblem,
    LagrangeSolution,
    build_coefficient_table,
    lagrange_coefficients,
    solve_lagrange,
    solve_lagrange_batch,
)
from msk.optimization.problems import (
    BatchSolution,
    EMGWeightedProblem,
    EMGWeightSweep,
    FrameStaticOptimization,
    Problem,
    QPSolution,
    StaticOptimizationProblem,
    TensionInequalities,
    TensionProblem,
    WarmStart,
    emg_weight_sweep,
    solve,
    solve_emg_assisted_batch,
    solve_emg_weighted_batch,
    solve_static_optimization_batch,
    solve_tension_batch,
    volume_weights,
)

__all__ = [
    "DEFAULT_SOLVER",
    "KKT",
    "KKT_COLUMNS",
    "STATUS_INFEASIBLE",
    "STATUS_NAMES",
    "STATUS_OPTIMAL",
    "STATUS_SOLVER_FAILED",
    "BatchSolution",
    "CoefficientTable",
    "EMGWeightSweep",
    "EMGWeightedProblem",
    "FrameStaticOptimization",
    "KKTBatch",
    "LagrangeBatchSolution",
    "LagrangeProblem",
    "LagrangeSolution",
    "Problem",
    "QPSolution",
    "SolveOutput",
    "SolverSpec",
    "StandardQP",
    "StaticOptimizationProblem",
    "TensionInequalities",
    "TensionProblem",
    "WarmStart",
    "available_solvers",
    "build_coefficient_table",
    "emg_weight_sweep",
    "kkt",
    "kkt_batch",
    "kkt_scale",
    "kkt_stacked",
    "lagrange_coefficients",
    "register_solver",
    "solve",
    "solve_emg_assisted_batch",
    "solve_emg_weighted_batch",
    "solve_lagrange",
    "solve_lagrange_batch",
    "solve_static_optimization_batch",
    "solve_tension_batch",
    "volume_weights",
]
