"""``closed_form``: the unbounded Lagrange-multiplier solution F = W Cᵀ (C W Cᵀ)⁻¹ τ of the
quasi-static lower-limb model of "A computationally efficient musculoskeletal model of the lower
limb for the control of rehabilitation robots" (its Eq. 6; :mod:`msk.optimization.closed_form`),
W the squared F_iso of the muscles."""

from __future__ import annotations

from typing import Any

import numpy as np

from msk.optimization.criteria.base import BlockProblem, Criterion, register

__all__ = ["ClosedForm"]


@register
class ClosedForm(Criterion):
    name = "closed_form"
    quadratic = False

    def solve(
        self, problem: BlockProblem, options: Any
    ) -> tuple[np.ndarray, np.ndarray | None, Any]:
        import msk.optimization as o

        p = problem
        lag = o.solve_lagrange_batch(
            p.jacobian, p.torques, area=p.kept(p.f_iso), muscle_names=p.common["muscle_names"]
        )
        return lag.forces, lag.forces / np.maximum(p.f_active, 1e-9), None
