"""``bounded_qp``: min Σ (F_i/F_iso,i)² with R F = τ and 0 ≤ F ≤ F_max (the bounded tension
QP; Crowninshield & Brand 1981 with force bounds), reserve actuators priced as muscles."""

from __future__ import annotations

from typing import Any

import numpy as np

from msk.optimization.criteria.base import BlockProblem, Criterion, register

__all__ = ["BoundedQP"]


@register
class BoundedQP(Criterion):
    name = "bounded_qp"

    def solve(
        self, problem: BlockProblem, options: Any
    ) -> tuple[np.ndarray, np.ndarray | None, Any]:
        import msk.optimization as o

        p = problem
        sol = o.solve_tension_batch(
            p.jacobian, p.torques, f_iso=p.kept(p.f_iso), f_max=p.f_active + p.f_passive,
            reserve_optimal_force=p.reserve_optimal_force, solver=options.solver, warm=p.warm,
            **p.common,
        )  # fmt: skip
        return sol.forces, np.clip(sol.forces / np.maximum(p.f_active, 1e-9), 0, None), sol
