"""Stimulation pulse trains (the model's input) and their sampling on a simulation grid.

A :class:`Stimulation` is a list of pulses, each with a time (s) and a level: the pulse width
(s, Benoussaad et al. 2013) or the current amplitude (A, the implanted-FES identification paper).
Zero-level pulses are no pulses.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import ConfigError

__all__ = [
    "StimKind",
    "Stimulation",
    "calcium_pi",
    "pulse_train",
    "sample_on_grid",
    "stimulation_from_profile",
]

StimKind = Literal["pw", "current"]


@dataclass(frozen=True)
class Stimulation:
    """Pulse times (s, increasing) and levels (PW in s or current in A)."""

    pulse_times: NDArray[np.float64]
    levels: NDArray[np.float64]
    kind: StimKind = "pw"
    columns: tuple[str, ...] = ("pulse_time", "level")

    def __post_init__(self) -> None:
        t = np.asarray(self.pulse_times, dtype=float)
        lv = np.asarray(self.levels, dtype=float)
        if t.shape != lv.shape or t.ndim != 1:
            raise ConfigError(f"stimulation: times {t.shape} and levels {lv.shape} differ")
        if np.any(np.diff(t) <= 0):
            raise ConfigError("stimulation: pulse times must be strictly increasing")
        if np.any(lv < 0) or not np.all(np.isfinite(lv)):
            raise ConfigError("stimulation: levels must be finite and >= 0")
        object.__setattr__(self, "pulse_times", t)
        object.__setattr__(self, "levels", lv)

    @property
    def end_time(self) -> float:
        return float(self.pulse_times[-1]) if self.pulse_times.size else 0.0

    def __add__(self, other: Stimulation) -> Stimulation:
        if other.kind != self.kind:
            raise ConfigError(f"stimulation: cannot merge {self.kind} with {other.kind} pulses")
        t = np.concatenate([self.pulse_times, other.pulse_times])
        lv = np.concatenate([self.levels, other.levels])
        order = np.argsort(t, kind="stable")
        return Stimulation(t[order], lv[order], self.kind)

    def shifted(self, dt: float) -> Stimulation:
        return Stimulation(self.pulse_times + dt, self.levels, self.kind)


def pulse_train(
    level: float,
    *,
    duration: float,
    frequency_hz: float = 20.0,
    t_start: float = 0.0,
    kind: StimKind = "pw",
) -> Stimulation:
    """Constant-level train of ``round(duration f)`` pulses starting at ``t_start``."""
    n = round(duration * frequency_hz)
    t = t_start + np.arange(n) / frequency_hz
    return Stimulation(t, np.full(n, float(level)), kind)


def stimulation_from_profile(
    t: ArrayLike,
    level: ArrayLike,
    *,
    frequency_hz: float = 20.0,
    kind: StimKind = "pw",
) -> Stimulation:
    """Pulses at ``frequency_hz`` over ``[t0, t_end)`` whose level samples a profile ``level(t)``.

    This is how a recorded PW or current channel (piecewise constant, sampled) becomes pulses.
    """
    t = np.asarray(t, dtype=float)
    lv = np.asarray(level, dtype=float)
    n = int(np.floor((t[-1] - t[0]) * frequency_hz + 1e-9))
    tp = t[0] + np.arange(n) / frequency_hz
    return Stimulation(tp, np.interp(tp, t, lv), kind)


def calcium_pi(
    t: ArrayLike, pulse_times: NDArray[np.float64], tau_c: float, tau_r: float, *, left: bool
) -> NDArray[np.float64]:
    """``Π_c(t)`` of Benoussaad et al. 2013, Eq. 12 from the most recent pulse (``left``: pulses <
    t)."""
    t = np.asarray(t, dtype=float)
    if pulse_times.size == 0:
        return np.zeros_like(t)
    idx = np.searchsorted(pulse_times, t, side="left" if left else "right") - 1
    s = t - pulse_times[np.maximum(idx, 0)]
    pi = np.where(s < tau_c, 1.0, np.clip((tau_r - (s - tau_c)) / tau_r, 0.0, 1.0))
    return np.where(idx >= 0, pi, 0.0)


def sample_on_grid(
    stim: Stimulation, n_steps: int, dt: float, tau_c: float, tau_r: float
) -> NDArray[np.float64]:
    """Step inputs ``(4, n_steps)``: held level, ``Π_c`` at the start, middle, end of each step.

    ``Π_c`` is piecewise linear between pulses, so with pulse times, ``τ_c`` and ``τ_r`` on the
    grid the RK4 stages see it exactly; at the end of a step the left limit is used.
    """
    on = stim.levels > 0
    tp = stim.pulse_times[on]
    lv = stim.levels[on]
    tk = np.arange(n_steps) * dt
    idx = np.searchsorted(tp, tk + 1e-9, side="right") - 1
    level = np.where(idx >= 0, lv[np.maximum(idx, 0)] if lv.size else 0.0, 0.0)
    eps = 1e-9
    p0 = calcium_pi(tk + eps, tp, tau_c, tau_r, left=False)
    pm = calcium_pi(tk + 0.5 * dt, tp, tau_c, tau_r, left=False)
    p1 = calcium_pi(tk + dt - eps, tp, tau_c, tau_r, left=True)
    return np.vstack([level, p0, pm, p1])
