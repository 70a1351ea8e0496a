"""``emg_assisted``: EMG-assisted static optimisation, min Σ w_i a_i² + w Σ (a_i − g_c ê_i)²
with the torques exact and one gain g_c per EMG channel, fitted on the trial's torques first
(:func:`msk.strength.fit_emg_gains`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from msk.optimization.criteria.base import BlockProblem, Criterion, register

__all__ = ["EmgAssisted"]


@register
class EmgAssisted(Criterion):
    name = "emg_assisted"
    reads_emg = True
    fits_emg_gains = True

    def solve(
        self, problem: BlockProblem, options: Any
    ) -> tuple[np.ndarray, np.ndarray | None, Any]:
        import msk.optimization as o

        p = problem
        if p.gains is None:
            a_ref, tracked = np.zeros_like(p.f_active), np.zeros(p.f_active.shape[1], dtype=bool)
        else:
            assert p.emg_activation is not None
            a_ref = p.kept(p.gains.reference(p.emg_activation))
            tracked = p.kept(np.asarray(p.gains.measured))
        sol = o.solve_emg_assisted_batch(
            p.jacobian, p.torques, f_active=p.f_active, f_passive=p.f_passive, a_ref=a_ref,
            measured=tracked, w_track=options.w_track, activation_weights=p.activation_weights,
            reserve_optimal_force=p.reserve_optimal_force, solver=options.solver, warm=p.warm,
            **p.common,
        )  # fmt: skip
        return sol.forces, sol.activations, sol

    def describe(self, options: Any, *, gains_fitted: bool) -> str | None:
        w = "V_i " if options.activation_weights == "volume" else ""
        if gains_fitted:
            return (
                f"min Σ {w}a_i^2 + {options.w_track:g} Σ (a_i − g_c ê_i)^2, gains g_c fitted on "
                "the trial's torques"
            )
        return f"min Σ {w}a_i^2 (no EMG channel with signal to track)"
