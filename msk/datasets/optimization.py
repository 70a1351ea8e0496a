"""Synthetic leg-like tension-optimisation data with a known truth (tests and benchmarks).

Moment arms are sparse like a leg's: each muscle crosses 1–3 *adjacent* coordinates (mono- and
bi-articular muscles along a chain), with |r| of 1–6 cm, varying smoothly over the frames of a
cycle. The generalised forces come from known activations, so every frame is feasible unless
the caller scales them up.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from msk.units import Array

__all__ = ["SyntheticFrames", "leg_like_frames"]


@dataclass(frozen=True)
class SyntheticFrames:
    """``jacobians`` ``(N, m, n)`` (``J = −Rᵀ``), ``taus`` ``(N, n)`` = ``R (F_iso a_true)``."""

    jacobians: Array
    taus: Array
    f_iso: Array
    activations_true: Array
    phase: Array


def leg_like_frames(
    n_muscles: int, n_coords: int, n_frames: int, *, seed: int = 0, max_activation: float = 0.3
) -> SyntheticFrames:
    """Smooth, sparse, leg-like moment arms and feasible torques over one movement cycle."""
    rng = np.random.default_rng(seed)
    base = np.zeros((n_muscles, n_coords))
    amp = np.zeros((n_muscles, n_coords))
    for i in range(n_muscles):
        span = int(rng.integers(1, 4 if n_coords >= 3 else n_coords + 1))
        start = int(rng.integers(0, n_coords - span + 1))
        for c in range(start, start + span):
            base[i, c] = rng.choice([-1.0, 1.0]) * rng.uniform(0.01, 0.06)
            amp[i, c] = rng.uniform(0.0, 0.4) * abs(base[i, c])
    # every coordinate is crossed by at least one agonist and one antagonist
    for c in range(n_coords):
        for sign in (-1.0, 1.0):
            if not np.any(np.sign(base[:, c]) == sign):
                i = int(rng.integers(n_muscles))
                base[i, c] = sign * rng.uniform(0.01, 0.06)
    phase = np.linspace(0.0, 2 * np.pi, n_frames, endpoint=False)
    shift = rng.uniform(0, 2 * np.pi, size=(n_muscles, n_coords))
    r_moment = base[None] + amp[None] * np.sin(phase[:, None, None] + shift[None])
    r_moment[:, base == 0] = 0.0
    f_iso = rng.uniform(150.0, 3000.0, size=n_muscles)
    act = max_activation * (0.5 + 0.5 * np.sin(phase[:, None] + rng.uniform(0, 6.3, n_muscles)))
    act *= rng.uniform(0.2, 1.0, size=n_muscles)
    taus = np.einsum("kmn,km->kn", r_moment, act * f_iso)
    return SyntheticFrames(
        jacobians=-r_moment, taus=taus, f_iso=f_iso, activations_true=act, phase=phase
    )
