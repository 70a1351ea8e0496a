"""The still, double-stance part of a static trial.

A static trial is meant to hold one pose, but labs record more than that: the subject walks
onto the plates, shifts weight, lifts a leg (the Grand Challenge's ``jw_1legstand1``: quiet
double stance, then the left leg lifted with the hip at ~40° and the knee at ~85°). Scaling
and marker placement average the static over its frames (the mean marker positions, the
median pose; :func:`msk.personalise.scaling.scale_from_static`,
:func:`msk.personalise.scaling.place_markers`), so a
static that moves mixes poses. :func:`still_window` finds the longest run of frames in which

* the markers are still: the 90th percentile over the markers of the marker speed (after the
  kinematics' zero-lag 6 Hz low-pass, in numpy: :func:`msk.signal.lowpass_filtfilt_numpy`) is below
  :data:`STILL_SPEED_M_S`; the percentile leaves out a few markers (a hand scratching, a
  flickering marker) but not a limb, and
* both feet are down where the plates say so: as many plates carry at least
  :data:`PLATE_LOADED_FRACTION` of the frame's total vertical load as in any frame of the
  trial (a subject standing with both feet on one plate, or without plates, is not judged on
  this).

Thresholds (physiology and measurement, not any truth compared against): quiet standing sways
the centre of mass at ~5–10 mm/s on average and the centre of pressure at ~10–15 mm/s
(Prieto TE et al. 1996, IEEE Trans Biomed Eng 43(9):956-966, Table II "mean velocity"); a
marker at shoulder height moves ~1.5× the centre of mass (inverted pendulum), with peaks
about twice the mean: 30 mm/s. The 6 Hz filter leaves < 1 mm/s of a 0.5 mm marker noise.
Lifting a leg or shifting weight moves the limb's markers at 50–600 mm/s (``jw_1legstand1``).
The four shipped statics (``subject01_static``, ``PS_static_for_scaling``,
``PiG_Calibration3_FF``, ``Static1``) stand still at a 90th percentile of 3–17 mm/s.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import StaticTrialError
from msk.signal import lowpass_filtfilt_numpy, true_runs

__all__ = [
    "MIN_STILL_S",
    "PLATE_LOADED_FRACTION",
    "SPEED_PERCENTILE",
    "STILL_CUTOFF_HZ",
    "STILL_SPEED_M_S",
    "StillWindow",
    "still_window",
]

#: speed (m/s) below which the markers are still: quiet standing's sway, ~1.5× the centre of
#: mass's 5–10 mm/s at shoulder height, peaks twice the mean (Prieto et al. 1996)
STILL_SPEED_M_S = 0.03
#: percentile over the markers of the per-frame marker speed compared with STILL_SPEED_M_S
SPEED_PERCENTILE = 90.0
#: low-pass cut-off (Hz) of the markers before differentiation (the kinematics' default)
STILL_CUTOFF_HZ = 6.0
#: shortest still window (s): a few sway periods' worth of frames to average the pose over
MIN_STILL_S = 0.5
#: fraction of the frame's total vertical load above which a plate counts as loaded
PLATE_LOADED_FRACTION = 0.05


@dataclass(frozen=True)
class StillWindow:
    """The frames ``first`` … ``stop - 1`` (``start_s`` … ``end_s``) of a static trial of
    ``n_frames`` frames, in which the markers' speed percentile stays ≤ ``max_speed_m_s``
    (its largest value in the window: ``speed_m_s``) and ``plates`` plates are loaded
    (None: not judged by plates)."""

    first: int
    stop: int
    start_s: float
    end_s: float
    n_frames: int
    speed_m_s: float
    max_speed_m_s: float
    plates: int | None

    @property
    def whole(self) -> bool:
        """The window is the whole trial."""
        return self.first == 0 and self.stop == self.n_frames

    @property
    def frames(self) -> slice:
        """The window as a slice of the trial's frames."""
        return slice(self.first, self.stop)

    def summary(self) -> dict[str, Any]:
        """The record for ``summary.json`` ``model.static_window``."""
        return {
            "start_s": self.start_s,
            "end_s": self.end_s,
            "frames": self.stop - self.first,
            "of_frames": self.n_frames,
            "whole_trial": self.whole,
            "speed_p90_max_m_s": self.speed_m_s if np.isfinite(self.speed_m_s) else None,
            "judged": bool(np.isfinite(self.speed_m_s)),
            "still_below_m_s": self.max_speed_m_s,
            "plates_loaded": self.plates,
        }


def _speeds(markers: NDArray[np.float64], rate: float, cutoff_hz: float) -> NDArray[np.float64]:
    """(N, M) marker speeds (m/s), NaN where a marker is missing: each marker's runs of
    tracked frames filtered and differentiated on their own (no interpolation over gaps).
    The forward–backward filter keeps the raw noise in the first and last samples of a run
    (its padding ends on them: 0.5 mm of noise reads as 60 mm/s at 120 Hz), so the speed over
    half a cut-off period at each end of a run is the nearest interior sample's."""
    n, m = markers.shape[:2]
    out = np.full((n, m), np.nan)
    ok: NDArray[np.bool_] = np.asarray(np.isfinite(markers).all(axis=2))
    k = max(1, int(np.ceil(0.5 * rate / cutoff_hz)))
    runs: dict[tuple[int, int], list[int]] = {}  # (first, stop) → the markers tracked over it
    for j in range(m):
        for a, b in true_runs(ok[:, j]):
            if b - a >= max(16, 2 * k + 1):  # shorter: too short to filter and to be a window
                runs.setdefault((a, b), []).append(j)
    for (a, b), cols in runs.items():  # the markers of one run filtered together
        seg = markers[a:b, cols]
        if cutoff_hz < 0.5 * rate:  # numpy's filter: a cached run does not import scipy.signal
            seg = lowpass_filtfilt_numpy(seg, rate_hz=rate, cutoff_hz=cutoff_hz)
        v = np.linalg.norm(np.gradient(seg, 1.0 / rate, axis=0), axis=2)
        v[:k], v[-k:] = v[k], v[-k - 1]
        out[a:b, cols] = v
    return out


def still_window(
    markers: ArrayLike,
    time: ArrayLike,
    *,
    plate_loads: ArrayLike | None = None,
    max_speed_m_s: float = STILL_SPEED_M_S,
    min_duration_s: float = MIN_STILL_S,
    cutoff_hz: float = STILL_CUTOFF_HZ,
) -> StillWindow:
    """The longest still, double-stance window of a static trial (module docstring).

    Args:
        markers: (N, M, 3) m, NaN gaps.
        time: (N,) s.
        plate_loads: (N, P) vertical load (N) of each plate at the marker frames, or None.
        max_speed_m_s: still below this 90th percentile of the marker speeds.
        min_duration_s: shortest window accepted.
        cutoff_hz: low-pass cut-off of the markers before differentiation.

    A static shorter than ``min_duration_s`` or 16 frames (a single-frame TRC) cannot show
    motion: it is used whole (``speed_m_s`` NaN).

    Raises:
        StaticTrialError: no frame, or no still window of ``min_duration_s`` (the message gives
            the longest one and the speeds).
    """
    x = np.asarray(markers, dtype=float)
    t = np.asarray(time, dtype=float)
    n = x.shape[0]
    if n == 0:
        raise StaticTrialError("static trial: no frame")
    if n < 16 or t[-1] - t[0] < min_duration_s:
        # too short to show motion (a single-frame or sub-second static): used whole, not judged
        return StillWindow(
            first=0, stop=n, start_s=float(t[0]), end_s=float(t[-1]), n_frames=n,
            speed_m_s=float("nan"), max_speed_m_s=float(max_speed_m_s), plates=None,
        )  # fmt: skip
    rate = (n - 1) / (t[-1] - t[0])
    speed = _speeds(x, rate, cutoff_hz)
    seen = np.isfinite(speed).sum(axis=1) >= 3
    p = np.full(n, np.inf)
    if seen.any():
        p[seen] = np.nanpercentile(speed[seen], SPEED_PERCENTILE, axis=1)
    still = p <= max_speed_m_s
    plates = None
    if plate_loads is not None and np.size(plate_loads):
        fz = np.clip(np.nan_to_num(np.asarray(plate_loads, dtype=float)), 0.0, None)
        total = fz.sum(axis=1, keepdims=True)
        loaded = ((fz >= PLATE_LOADED_FRACTION * total) & (total > 0)).sum(axis=1)
        plates = int(loaded.max())
        still &= loaded == plates
    runs = true_runs(still)
    if runs:
        a, b = max(runs, key=lambda r: r[1] - r[0])
        duration = (b - a) / rate
    else:
        a = b = 0
        duration = 0.0
    if duration < min_duration_s:
        finite = p[np.isfinite(p)]
        low = float(np.min(finite)) if finite.size else float("nan")
        raise StaticTrialError(
            f"static trial: no still window of {min_duration_s:g} s (longest {duration:.2f} s "
            f"with the markers' {SPEED_PERCENTILE:g}th-percentile speed ≤ "
            f"{1000 * max_speed_m_s:g} mm/s" + ("" if plates is None else
            f" and {plates} plates loaded") + f"; lowest speed {1000 * low:.1f} mm/s)"
        )  # fmt: skip
    return StillWindow(
        first=int(a), stop=int(b), start_s=float(t[a]), end_s=float(t[b - 1]), n_frames=n,
        speed_m_s=float(np.max(p[a:b])), max_speed_m_s=float(max_speed_m_s), plates=plates,
    )  # fmt: skip
