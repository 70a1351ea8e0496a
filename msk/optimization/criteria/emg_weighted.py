"""``emg_weighted``: the EMG-weighted tension optimisation of Hayashibe et al. (2011, Eq. 17–18):
min ‖R F − τ‖² + w_emg Σ_measured (F_i − F_ref,i)² with the EMG-based reference force
F_ref,i = a_i^EMG F_active,i (their Eq. 9), 0 ≤ F ≤ F_max."""

from __future__ import annotations

from typing import Any

import numpy as np

from msk.optimization.criteria.base import BlockProblem, Criterion, register

__all__ = ["EmgWeighted"]


@register
class EmgWeighted(Criterion):
    name = "emg_weighted"
    reads_emg = True

    def solve(
        self, problem: BlockProblem, options: Any
    ) -> tuple[np.ndarray, np.ndarray | None, Any]:
        import msk.optimization as o

        p = problem
        assert p.emg_activation is not None and p.measured is not None
        sol = o.solve_emg_weighted_batch(
            p.jacobian, p.torques, f_ref=p.kept(p.emg_activation) * p.f_active,
            measured=p.kept(p.measured), w_emg=options.w_emg, f_max=p.f_active + p.f_passive,
            solver=options.solver, warm=p.warm, **p.common,
        )  # fmt: skip
        return sol.forces, np.clip(sol.forces / np.maximum(p.f_active, 1e-9), 0, None), sol
