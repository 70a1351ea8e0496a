"""``static_optimization``: min Σ w_i a_i^p with activation bounds and reserve actuators
(Crowninshield & Brand 1981; OpenSim's StaticOptimization; ``activation_weights = "volume"``:
w_i = V_i, the muscle volume, Happee 1994)."""

from __future__ import annotations

from typing import Any

import numpy as np

from msk.optimization.criteria.base import BlockProblem, Criterion, register

__all__ = ["StaticOptimization"]


@register
class StaticOptimization(Criterion):
    name = "static_optimization"

    def solve(
        self, problem: BlockProblem, options: Any
    ) -> tuple[np.ndarray, np.ndarray | None, Any]:
        import msk.optimization as o

        p = problem
        sol = o.solve_static_optimization_batch(
            p.jacobian, p.torques, f_active=p.f_active, f_passive=p.f_passive,
            reserve_optimal_force=p.reserve_optimal_force,
            activation_weights=p.activation_weights,
            activation_exponent=options.activation_exponent, solver=options.solver, warm=p.warm,
            **p.common,
        )  # fmt: skip
        return sol.forces, sol.activations, sol

    def describe(self, options: Any, *, gains_fitted: bool) -> str | None:
        w = "V_i " if options.activation_weights == "volume" else ""
        return f"min Σ {w}a_i^{options.activation_exponent:g}"
