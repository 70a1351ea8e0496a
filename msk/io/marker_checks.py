"""Marker samples that cannot be the marker: a trajectory that teleports away and back.

A labelled trajectory that jumps to another point for a few frames and then returns (a label
swapped with a neighbouring marker, a ghost reflection picked up by the labeller) is not the
marker there. A skin marker's acceleration stays far below ``a_max`` = 500 m/s² (about 50 g;
heel and foot markers at heel strike in running reach 10–20 g), so between two frames its
displacement departs from the constant-velocity extrapolation

    e_k = ‖(x_k − x_{k−1}) − (x_{k−1} − x_{k−2})‖

by at most a_max Δt² (5 cm at 100 Hz). :func:`find_teleports` reports a run of frames
k … k′−1 entered by such a jump (e_k above the threshold ``max(min_jump_m, a_max Δt²)``) and
left by one back (e_k′, with the velocity after the run, above it too) whose two jumps cancel
— ‖J_in + J_out‖ < ½ min(‖J_in‖, ‖J_out‖), J the jumps net of the local velocity — within
``max_run_s``: the trajectory comes back to where it was going, so the run is a foreign point,
not a motion. Those samples are gaps for inverse kinematics (it ignores a missing marker).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["MAX_MARKER_ACCELERATION", "Teleport", "find_teleports"]

#: a skin marker's largest plausible acceleration (m/s²): ~50 g
MAX_MARKER_ACCELERATION = 500.0


@dataclass(frozen=True)
class Teleport:
    """A run of frames ``first``…``last`` (0-based, inclusive) in which ``label``'s
    trajectory sits ``distance_m`` away from its path (the jump into the run, net of the
    marker's velocity)."""

    label: str
    first: int
    last: int
    distance_m: float


def find_teleports(
    markers: NDArray[np.float64],
    labels: Sequence[str],
    rate_hz: float,
    *,
    min_jump_m: float = 0.05,
    max_run_s: float = 0.25,
    max_acceleration: float = MAX_MARKER_ACCELERATION,
) -> list[Teleport]:
    """The teleports (module docstring) of ``markers`` (N, M, 3) in metres, NaN gaps, sampled
    at ``rate_hz``; none when the rate is not positive."""
    x = np.asarray(markers, dtype=float)
    if x.ndim != 3 or x.shape[0] < 4 or not rate_hz > 0 or not np.isfinite(rate_hz):
        return []
    dt = 1.0 / rate_hz
    thr = max(min_jump_m, max_acceleration * dt * dt)
    max_run = max(1, round(max_run_s * rate_hz))
    with np.errstate(invalid="ignore"):
        d = np.diff(x, axis=0)  # d[k-1] = x[k] - x[k-1]
        v_before = np.full_like(d, np.nan)
        v_before[1:] = d[:-1]
        net = d - v_before  # jump into frame k net of the velocity before it
        e = np.linalg.norm(net, axis=2)
        cand = np.isfinite(e) & (e > thr)
    out: list[Teleport] = []
    for m in np.flatnonzero(cand.any(axis=0)).tolist():
        ks = np.flatnonzero(cand[:, m])  # index into d: the jump into frame ks + 1
        i = 0
        while i < ks.size:
            k_in = int(ks[i])
            j_in = net[k_in, m]
            found = None
            for j in range(i + 1, ks.size):
                k_out = int(ks[j])
                if k_out - k_in > max_run:
                    break
                # the jump back, net of the velocity after it (before it, at the run's end)
                v_after = d[k_out + 1, m] if k_out + 1 < d.shape[0] else d[k_in - 1, m]
                if not np.isfinite(v_after).all():
                    v_after = d[k_in - 1, m]
                j_out = d[k_out, m] - v_after
                n_in, n_out = float(np.linalg.norm(j_in)), float(np.linalg.norm(j_out))
                if n_out > thr and float(np.linalg.norm(j_in + j_out)) < 0.5 * min(n_in, n_out):
                    found = j
                    break
            if found is None:
                i += 1
                continue
            k_out = int(ks[found])
            out.append(Teleport(str(labels[m]), k_in + 1, k_out, float(np.linalg.norm(j_in))))
            i = found + 1
            while i < ks.size and ks[i] <= k_out + 1:  # the jump's echo in the next difference
                i += 1
    return out
