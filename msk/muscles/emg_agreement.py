"""Agreement of predicted muscle activations with recorded EMG activations: timing, not amplitude.

Evidence about a muscle-force criterion that is not a measured joint load (the criterion's
predicted activations against the subject's own EMG), in the three measures used to compare
static-optimisation criteria with EMG in the literature:

- **Pearson r** and **Spearman ρ** over the compared frames of one muscle (as Heintz &
  Gutierrez-Farewik 2007, Gait Posture 26:279, compare static-optimisation forces with EMG):
  the shape of the activation over the cycle, blind to its scale — EMG normalised to the
  session's peak is a relative activation (no MVC), so only the shape is comparable.
- **On/off agreement**: each signal divided by its own peak over the compared frames and called
  "on" above ``threshold`` (default 25 % of the peak: a choice of this module, not a
  published constant); the fraction of frames where both are on or both off. A prediction whose
  peak is below ``floor`` (an activation the criterion never recruits) is off everywhere.
- **Co-contraction index** of two muscles (Falconer & Winter 1985, Electromyogr Clin
  Neurophysiol 25:135, Eq. 1): CI = 2 Σ min(a, b) / Σ (a + b), the common area over the total
  area, each signal divided by its own peak over the cycle first (so an EMG and a prediction are
  compared on the same footing).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.units import Array

__all__ = [
    "ChannelAgreement",
    "channel_agreement",
    "cocontraction_index",
    "on_off_agreement",
    "pearson_r",
    "spearman_rho",
]


def _pairs(a: ArrayLike, b: ArrayLike) -> tuple[Array, Array]:
    x = np.asarray(a, dtype=float).ravel()
    y = np.asarray(b, dtype=float).ravel()
    if x.shape != y.shape:
        raise ValueError(f"signals of different lengths: {x.size} and {y.size}")
    ok = np.isfinite(x) & np.isfinite(y)
    return x[ok], y[ok]


def pearson_r(a: ArrayLike, b: ArrayLike) -> float:
    """Pearson r of ``a`` and ``b`` over the frames where both are finite (NaN with fewer than
    3 such frames or a constant signal)."""
    x, y = _pairs(a, b)
    if x.size < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return float("nan")
    return float(np.corrcoef(x, y)[0, 1])


def _ranks(x: Array) -> Array:
    """Average ranks (ties share their mean rank)."""
    order = np.argsort(x, kind="mergesort")
    ranks = np.empty(x.size)
    ranks[order] = np.arange(x.size, dtype=float)
    _, inverse, counts = np.unique(x, return_inverse=True, return_counts=True)
    sums = np.bincount(inverse, weights=ranks)
    return np.asarray(sums[inverse] / counts[inverse], dtype=float)


def spearman_rho(a: ArrayLike, b: ArrayLike) -> float:
    """Spearman ρ (Pearson r of the average ranks) over the frames where both are finite."""
    x, y = _pairs(a, b)
    if x.size < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return float("nan")
    return pearson_r(_ranks(x), _ranks(y))


def _on(x: Array, threshold: float, floor: float) -> NDArray[np.bool_]:
    peak = float(np.max(x)) if x.size else 0.0
    if peak <= floor:
        return np.zeros(x.shape, dtype=bool)
    return np.asarray(x > threshold * peak)


def on_off_agreement(
    predicted: ArrayLike, emg: ArrayLike, *, threshold: float = 0.25, floor: float = 1e-3
) -> float:
    """Fraction of the frames (both finite) where ``predicted`` and ``emg`` are both on or both
    off, each "on" above ``threshold`` × its own peak over those frames; a signal whose peak is
    ≤ ``floor`` is off everywhere. NaN without a common finite frame."""
    if not 0.0 < threshold < 1.0:
        raise ValueError(f"threshold must be in (0, 1): {threshold!r}")
    x, y = _pairs(predicted, emg)
    if x.size == 0:
        return float("nan")
    return float(np.mean(_on(x, threshold, floor) == _on(y, threshold, floor)))


def cocontraction_index(a: ArrayLike, b: ArrayLike, *, peak_a: float, peak_b: float) -> float:
    """Falconer & Winter (1985) co-contraction index 2 Σ min(â, b̂) / Σ (â + b̂) of two muscles
    over the given frames (both finite), â = a / ``peak_a`` and b̂ = b / ``peak_b`` (each
    muscle's own peak over the cycle, passed so that a window of the cycle is normalised like
    the whole). 1: identical normalised curves; 0: never active together. NaN when a peak is
    not positive or the window is empty or silent."""
    if not (peak_a > 0 and peak_b > 0):
        return float("nan")
    x, y = _pairs(a, b)
    x, y = np.clip(x / peak_a, 0.0, None), np.clip(y / peak_b, 0.0, None)
    total = float(np.sum(x + y))
    if x.size == 0 or total == 0.0:
        return float("nan")
    return float(2.0 * np.sum(np.minimum(x, y)) / total)


@dataclass(frozen=True)
class ChannelAgreement:
    """Per EMG channel (``channels``): Pearson ``r``, Spearman ``rho``, ``on_off`` agreement
    (fractions) and the number of compared ``frames``, each (k,)."""

    channels: tuple[str, ...]
    r: Array
    rho: Array
    on_off: Array
    frames: NDArray[np.int64]

    def median_r(self) -> float:
        """Median Pearson r over the channels that have one (NaN when none has)."""
        ok = np.isfinite(self.r)
        return float(np.median(self.r[ok])) if ok.any() else float("nan")


def channel_agreement(
    predicted: ArrayLike,
    emg: ArrayLike,
    channels: Sequence[str],
    *,
    threshold: float = 0.25,
) -> ChannelAgreement:
    """Agreement of ``predicted`` (N, k) activations — one column per EMG channel, e.g. the
    mean activation of the muscles that channel drives — with ``emg`` (N, k) activations over
    the frames where both are finite, channel by channel."""
    p = np.asarray(predicted, dtype=float)
    e = np.asarray(emg, dtype=float)
    if p.ndim != 2 or p.shape != e.shape or p.shape[1] != len(channels):
        raise ValueError(f"predicted {p.shape} and emg {e.shape} must both be (N, {len(channels)})")
    k = p.shape[1]
    r, rho, onoff = np.full(k, np.nan), np.full(k, np.nan), np.full(k, np.nan)
    n = np.zeros(k, dtype=np.int64)
    for j in range(k):
        r[j] = pearson_r(p[:, j], e[:, j])
        rho[j] = spearman_rho(p[:, j], e[:, j])
        onoff[j] = on_off_agreement(p[:, j], e[:, j], threshold=threshold)
        n[j] = int(np.sum(np.isfinite(p[:, j]) & np.isfinite(e[:, j])))
    return ChannelAgreement(tuple(channels), r, rho, onoff, n)
