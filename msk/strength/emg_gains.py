"""EMG-to-activation gains fitted jointly with EMG-assisted static optimisation.

Without an MVC trial an EMG envelope ``ê`` (e.g. divided by its session peak) has no absolute
scale. The EMG-driven vs OpenSim thesis (Fig. 2.1) calibrates such scales — flexor/extensor gain
factors ``G_f``, ``G_e`` — against the inverse-dynamics moments; Hayashibe et al. 2011, §V reads the
regression of the ID torques on the EMG-driven contributions as strength factors
(:class:`StrengthIdentifier`). Here the gains are instead the ones that make the EMG the best
description of torque-compatible activations: over all frames ``t`` of the training trials, jointly
in the activations and the gains,

.. math::

    \\min_{a, g}\\; \\sum_t \\Big[ \\sum_i w_i a_{ti}^2
        + w_{track} \\sum_{c} \\sum_{i \\in c} (a_{ti} - g_c\\, ê_{ti})^2 + \\sum_j r_{tj}^2 \\Big]
    \\quad \\text{s.t.}\\; R_t (a_t ⊙ F_{act,t} + F_{pas,t}) + F_{res} r_t = τ_t,\\;
    a_{min} ≤ a_t ≤ a_{max},\\; g ≥ 0

(``c`` a gain group: one EMG channel or a synergist group; ``i ∈ c`` its muscles). The torques
are hard constraints, so the gains are identified from the ID torques only. The problem is
jointly convex in ``(a, g)`` (a convex quadratic of a linear map of them, linear constraints)
and separable over frames once ``g`` is fixed; it is solved by two-block coordinate descent:
the ``a``-step is :func:`msk.optimization.solve_emg_assisted_batch` with ``a* = g ê`` (one QP
per frame), the ``g``-step is closed form, ``g_c = max(0, Σ_t Σ_{i∈c} a_ti ê_ti / Σ_t Σ_{i∈c}
ê_ti²)``. Each step minimises the joint objective exactly over its block, so the objective never
increases and (two blocks, convex, the ``a``-block a strictly convex QP) the iterates converge to
the joint minimum (Grippo & Sciandrone 2000, Oper. Res. Lett. 26:127). Convergence is linear;
it slows as ``w_track`` grows (``a`` then follows ``g ê`` closely and each ``g``-step is short).
The iterates of the fixed-point map g ↦ G(g) (a-step, then g-step) are therefore extrapolated
by Anderson mixing (Walker & Ni 2011), each extrapolation kept only if the joint objective does
not increase (else the plain step): the same fixed point, monotone objective, fewer a-steps
(Grand Challenge PS: 28 → 11).

With ``w_track → 0`` the gains become the least-squares scale of the static-optimisation
activations on the EMG; with ``w_track → ∞`` the activations follow ``g ê`` wherever the torques
allow. When the torques determine the activations (no redundancy) the gains are the
least-squares scale of those activations on the EMG at every ``w_track``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import IdentificationError
from msk.units import Array

__all__ = ["ANDERSON_MEMORY", "EMGGainFit", "fit_emg_gains"]


@dataclass(frozen=True)
class EMGGainFit:
    """Result of :func:`fit_emg_gains`. ``gains`` ``(G,)`` in ``group_names`` order;
    ``muscle_gains`` ``(M,)`` (0 for unmeasured muscles) and ``measured`` ``(M,)`` in
    ``muscle_names`` order; ``objective`` the joint objective after each iteration
    (non-increasing); ``solution`` the last ``a``-step (:class:`BatchSolution` over the stacked
    frames)."""

    group_names: tuple[str, ...]
    gains: Array
    muscle_names: tuple[str, ...]
    muscle_gains: Array
    measured: NDArray[np.bool_]
    w_track: float
    iterations: int
    converged: bool
    objective: Array
    solution: Any

    def reference(self, emg_activation: ArrayLike) -> Array:
        """``a* = g ê`` ``(N, M)`` for EMG activations ``ê`` ``(N, M)`` of new frames."""
        return np.asarray(emg_activation, dtype=float) * self.muscle_gains


def _group_index(
    groups: Mapping[str, Sequence[str]], muscle_names: Sequence[str]
) -> list[NDArray[np.intp]]:
    index = {n: i for i, n in enumerate(muscle_names)}
    out, seen = [], set()
    for g, members in groups.items():
        if not members:
            raise IdentificationError(f"gain group {g!r} has no muscle")
        for mname in members:
            if mname not in index:
                raise IdentificationError(f"muscle {mname!r} of gain group {g!r} is not a muscle")
            if mname in seen:
                raise IdentificationError(f"muscle {mname!r} is in more than one gain group")
            seen.add(mname)
        out.append(np.array([index[mname] for mname in members], dtype=np.intp))
    return out


#: iterates of the gain fit combined by its Anderson extrapolation
ANDERSON_MEMORY = 5


def fit_emg_gains(
    jacobians: ArrayLike,
    taus: ArrayLike,
    *,
    f_active: ArrayLike,
    f_passive: ArrayLike | None = None,
    emg_activation: ArrayLike,
    groups: Mapping[str, Sequence[str]],
    muscle_names: Sequence[str],
    w_track: float = 1.0,
    activation_weights: ArrayLike | None = None,
    activation_min: ArrayLike = 0.0,
    activation_max: ArrayLike = 1.0,
    reserve_optimal_force: ArrayLike | None = None,
    coordinate_names: Sequence[str] | None = None,
    initial_gain: float = 1.0,
    tol: float = 1e-5,
    max_iterations: int = 500,
) -> EMGGainFit:
    """Fit one EMG-to-activation gain per group jointly with EMG-assisted static optimisation
    (module docstring). Frames of several trials are simply stacked (axis 0): they share the
    gains and nothing else. ``jacobians`` ``(N, M, n)`` J = ∂l/∂θ, ``taus`` ``(N, n)`` ID
    torques, ``f_active`` ``(N, M)`` F_iso f_l f_v cos α, ``f_passive`` ``(N, M)`` the passive
    force along the tendon (default 0), ``emg_activation`` ``(N, M)`` EMG
    activation of each muscle's channel (any scale; values of muscles outside ``groups``
    ignored). Stops when no gain moves by more than ``tol`` (absolute) in an iteration;
    ``converged`` is False when ``max_iterations`` is reached first."""
    from msk.optimization import solve_emg_assisted_batch

    names = tuple(muscle_names)
    m = len(names)
    idx = _group_index(groups, names)
    e = np.asarray(emg_activation, dtype=float)
    if e.ndim != 2 or e.shape[1] != m:
        raise IdentificationError(f"emg_activation has shape {e.shape}, expected (N, {m})")
    if not (np.isfinite(w_track) and w_track > 0):
        raise IdentificationError(f"w_track must be finite and > 0: {w_track!r}")
    measured = np.zeros(m, dtype=bool)
    for ii in idx:
        measured[ii] = True
    den = np.array([float(np.sum(e[:, ii] ** 2)) for ii in idx])
    if np.any(den <= 0):
        g = int(np.argmax(den <= 0))
        raise IdentificationError(f"gain group {list(groups)[g]!r} has no EMG signal (all zero)")
    w = np.ones(m) if activation_weights is None else np.asarray(activation_weights, float)
    gains = np.full(len(idx), float(initial_gain))
    converged = False

    def muscle_gains(gv: Array) -> Array:
        out = np.zeros(m)
        for ii, gc in zip(idx, gv):
            out[ii] = gc
        return out

    def a_step(gv: Array) -> tuple[Any, Array, Array, float]:
        """The activations at the gains ``gv``, the g-step from them and the joint objective
        J(a, G(g)) there."""
        sol = solve_emg_assisted_batch(
            jacobians, taus, f_active=f_active, f_passive=f_passive,
            a_ref=e * muscle_gains(gv), measured=measured, w_track=w_track,
            activation_weights=activation_weights, activation_min=activation_min,
            activation_max=activation_max, reserve_optimal_force=reserve_optimal_force,
            compute_kkt=False, muscle_names=names, coordinate_names=coordinate_names,
        )  # fmt: skip
        a = sol.activations
        assert a is not None
        g_new = np.array(
            [max(0.0, float(np.sum(a[:, ii] * e[:, ii])) / d) for ii, d in zip(idx, den)]
        )
        dev = (a - e * muscle_gains(g_new))[:, measured]
        obj = float(
            np.sum(a * a * w) + w_track * np.sum(dev * dev) + np.sum(sol.reserve_controls**2)
        )
        return sol, a, g_new, obj

    # g ↦ G(g) (the a-step then the g-step) is the coordinate descent's fixed-point map; its
    # iterates are extrapolated by Anderson mixing over the last ANDERSON_MEMORY of them
    # (Walker & Ni 2011, SIAM J Numer Anal 49:1715), an extrapolation kept only when the joint
    # objective does not increase — else the plain step — so the objective stays monotone
    # and the fixed point (the joint minimum) is the same.
    gk = gains
    sol, _, g_img, obj = a_step(gk)
    iterations, history = 1, [obj]
    past: list[tuple[Array, Array]] = [(gk, g_img)]
    while True:
        if float(np.max(np.abs(g_img - gk))) <= tol:
            converged = True
            break
        if iterations >= max_iterations:
            break
        prop = g_img
        if len(past) >= 2:
            res = np.array([gi - g0 for g0, gi in past]).T  # (G, k) residuals G(g) − g
            img = np.array([gi for _, gi in past]).T
            d_res, d_img = np.diff(res, axis=1), np.diff(img, axis=1)
            gamma = np.linalg.lstsq(d_res, res[:, -1], rcond=1e-10)[0]
            prop = np.maximum(g_img - d_img @ gamma, 0.0)
        cand = a_step(prop)
        iterations += 1
        if cand[3] > obj and prop is not g_img:  # extrapolation rejected: the plain step
            past = []
            prop = g_img
            cand = a_step(prop)
            iterations += 1
        gk, (sol, _, g_img, obj) = prop, cand
        history.append(obj)
        past = [*past[-(ANDERSON_MEMORY - 1) :], (gk, g_img)]
    gains = g_img
    return EMGGainFit(
        group_names=tuple(groups),
        gains=gains,
        muscle_names=names,
        muscle_gains=muscle_gains(gains),
        measured=measured,
        w_track=float(w_track),
        iterations=iterations,
        converged=converged,
        objective=np.array(history),
        solution=sol,
    )
