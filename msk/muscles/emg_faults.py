"""Single-sample faults of a raw EMG channel: found, repaired or the channel excluded, and said.

One sample of 1e20 V, ``inf`` or a 50 V transient in a channel of millivolts (a converter
glitch, a dropped packet of a wireless system, a static discharge) passes the high-pass, the
rectification and the low-pass of the linear envelope as one large impulse: it moves the
envelope for ~0.1 s and, with the session's peak as the normalisation, every activation of the
channel. The faults are found on the raw channel, before any filter, with a robust local scale:

* the channel is cut into blocks of ``block_s`` (≥ 16 samples); each block's centre is its
  median ``c_b`` and its spread the median absolute deviation ``MAD_b = median|x − c_b|``
  (Hampel 1974; Leys et al. 2013 for the MAD as the robust scale), neither moved by a few
  samples of the block, however large;
* a sample's scale is the largest MAD of its block and of the ``context_blocks`` blocks on each
  side (a burst's first samples are judged against the burst, not against the rest before
  it), and at least the channel's quantisation step;
* a sample is a fault when it is not finite or ``|x − c_b| > threshold × scale``: with the
  default 50, a Gaussian sample exceeds it with probability < 10⁻²⁵⁰ and a Laplacian one
  (EMG's amplitude distribution within a contraction; Clancy and Hogan 1999) < 10⁻¹⁵.

Runs of faults no longer than ``max_run_s`` are replaced by the straight line between the good
samples on either side (the isolated glitch is repaired); a channel with a longer run or more
than ``max_fraction`` of its samples at fault is not repaired but excluded (its envelope is
then NaN, as a flat channel's). Either way :class:`SampleFaults` says which channel, how many
samples, the first one's time and value, so that the run raises a quality flag.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from msk.quality import Flag

__all__ = ["SampleFaults", "fault_flags", "find_sample_faults", "repair_sample_faults"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class SampleFaults:
    """The faults of one channel: ``count`` samples (``nonfinite`` of them NaN/inf), the first
    at sample ``first_index`` (time ``first_time_s``) with value ``first_value``; the largest
    deviation in units of the local scale (``worst_ratio``, inf for a non-finite one);
    ``repaired`` (interpolated) or excluded, with the ``reason``."""

    channel: str
    count: int
    nonfinite: int
    first_index: int
    first_time_s: float
    first_value: float
    worst_ratio: float
    longest_run: int
    repaired: bool
    reason: str

    def message(self) -> str:
        """One line naming the channel, the count, the first sample's time and value."""
        t = self.first_time_s
        what = f"{self.count} faulty sample{'s' if self.count != 1 else ''}"
        if self.nonfinite:
            what += f" ({self.nonfinite} not finite)"
        done = "repaired by linear interpolation" if self.repaired else "channel excluded"
        return (
            f"EMG channel {self.channel!r}: {what}, first at {t:.4f} s (sample "
            f"{self.first_index}, value {self.first_value:.4g}); {done} ({self.reason})"
        )


def _quantum(x: Array) -> float:
    """The smallest step between distinct finite values (the converter's LSB), 0 if none."""
    u = np.unique(x[np.isfinite(x)])
    d = np.diff(u)
    d = d[d > 0]
    return float(d.min()) if d.size else 0.0


def find_sample_faults(
    x: ArrayLike,
    *,
    rate_hz: float,
    threshold: float = 50.0,
    block_s: float = 0.01,
    context_blocks: int = 2,
    global_factor: float = 20.0,
) -> tuple[NDArray[np.bool_], Array]:
    """Faulty samples of one raw channel ``x`` (N,) (see the module docstring) and each
    sample's deviation in units of its local scale (inf where not finite)."""
    x = np.asarray(x, dtype=float).ravel()
    n = x.size
    if n == 0:
        return np.zeros(0, dtype=bool), np.zeros(0)
    finite = np.isfinite(x)
    clean = bool(finite.all())
    b = max(16, round(block_s * rate_hz))
    nb = -(-n // b)
    pad = np.full(nb * b, np.nan)
    pad[:n] = x if clean else np.where(finite, x, np.nan)
    blocks = pad.reshape(nb, b)
    median = np.median if clean and nb * b == n else np.nanmedian  # NaN-free: the fast one
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN blocks
        centre = median(blocks, axis=1)
        if not np.isfinite(centre).any():
            return ~finite, np.where(finite, 0.0, np.inf)
        centre = np.where(np.isfinite(centre), centre, np.nanmedian(centre))
        dev = np.abs(blocks - centre[:, None])  # (nb, b), NaN where not finite or padding
        mad = median(dev, axis=1)
    mad = np.where(np.isfinite(mad), mad, 0.0)
    k = max(int(context_blocks), 0)
    wide = np.concatenate([np.zeros(k), mad, np.zeros(k)])
    scale = np.lib.stride_tricks.sliding_window_view(wide, 2 * k + 1).max(axis=1)
    floor = _quantum(x)
    if floor == 0.0:
        fin = np.abs(x[finite])
        floor = 1e-12 * float(fin.max()) if fin.size and fin.max() > 0 else np.finfo(float).tiny
    scale = np.maximum(scale, floor)
    flat = dev.ravel()[:n]
    # and beyond anything the channel does: ``global_factor`` × its 99th-percentile deviation
    reach = float(np.percentile(flat if clean else flat[finite], 99)) if finite.any() else 0.0
    with np.errstate(invalid="ignore", over="ignore"):
        beyond = flat > global_factor * max(reach, floor)
        dev /= scale[:, None]  # the deviation in units of the local scale, in place
        bad = (flat > threshold) & beyond
    ratio = flat
    ratio[~finite] = np.inf
    return bad | ~finite, ratio


def _runs(mask: NDArray[np.bool_]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Start and end (exclusive) indices of the runs of True in ``mask``."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)


def repair_sample_faults(
    x: ArrayLike,
    *,
    rate_hz: float,
    channel: str = "",
    t0: float = 0.0,
    threshold: float = 50.0,
    max_run_s: float = 0.005,
    max_fraction: float = 0.001,
) -> tuple[Array | None, SampleFaults | None]:
    """``(x repaired, faults)`` of channel ``channel`` whose first sample is at ``t0`` (s):
    ``x`` itself and ``None`` when it has no fault; the repaired
    copy when every run of faults is at most ``max_run_s`` long (≥ 1 sample) and they are at
    most ``max_fraction`` of the samples; ``(None, faults)`` when the channel is to be
    excluded."""
    x = np.asarray(x, dtype=float).ravel()
    bad, ratio = find_sample_faults(x, rate_hz=rate_hz, threshold=threshold)
    count = int(bad.sum())
    if count == 0:
        return x, None
    starts, ends = _runs(bad)
    longest = int((ends - starts).max())
    max_run = max(1, round(max_run_s * rate_hz))
    first = int(starts[0])
    worst = float(ratio[bad].max())
    nonfinite = int((~np.isfinite(x)).sum())
    fixable = longest <= max_run and count <= max(1, max_fraction * x.size) and count < x.size
    if fixable:
        reason = (
            f"{count} sample{'s' if count != 1 else ''} beyond {threshold:g} × the local "
            f"robust scale or not finite, runs of ≤ {longest}"
        )
    elif longest > max_run:
        reason = f"a run of {longest} faulty samples, longer than {max_run} ({max_run_s:g} s)"
    else:
        reason = f"{count} faulty samples, more than {100 * max_fraction:g} % of {x.size}"
    faults = SampleFaults(
        channel=channel,
        count=count,
        nonfinite=nonfinite,
        first_index=first,
        first_time_s=t0 + first / rate_hz,
        first_value=float(x[first]),
        worst_ratio=worst,
        longest_run=longest,
        repaired=fixable,
        reason=reason,
    )
    if not fixable:
        return None, faults
    good = np.flatnonzero(~bad)
    y = x.copy()
    y[bad] = np.interp(np.flatnonzero(bad), good, x[good])
    return y, faults


def fault_flags(trial: str, faults: Sequence[SampleFaults]) -> list[Flag]:
    """The quality flags (``summary.json`` ``quality.flags``) of the faults: one per channel,
    quantity ``emg_sample_faults`` (repaired) or ``emg_channel_excluded``, value the count."""
    from msk.quality import Flag  # on use: reading EMG does not import the quality gates

    return [
        Flag(
            trial=trial,
            quantity="emg_sample_faults" if f.repaired else "emg_channel_excluded",
            value=float(f.count),
            threshold=0.0,
            message=f.message(),
        )
        for f in faults
    ]
