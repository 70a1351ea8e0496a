"""Comparison metrics between a measured (reference) and a simulated (estimated) series.

All functions take numpy-compatible arrays with time (samples) on axis 0.  A 1-D input gives a
``float``; a 2-D input ``(n_samples, n_columns)`` is compared column by column and gives a 1-D
array with one value per column.  Percentages are returned in percent (``x 100``) and say so in
their docstring.

Definitions follow the seed documents:

* ``nrmsd`` — Benoussaad et al. 2013, Eq. 9: RMS deviation normalised by the *range* of the measured
  signal,
  ``sqrt(mean((X_m - X_s)^2)) / |max(X_m) - min(X_m)| x 100``.
* ``nrmse`` — the implanted-FES identification paper, §V: RMS error normalised by the *RMS value* of
  the measured signal,
  ``sqrt(mean((X_m - X_s)^2)) / sqrt(mean(X_m^2)) x 100``.
* ``icc`` / ``sem`` — the rehabilitation-robot lower-limb model paper, §2 (agreement of two methods,
  ICC and standard error of
  measurement, SEM expressed as a percentage of the range, Tables 3, 5, 6); ICC forms are those of
  Shrout & Fleiss (1979) computed from the two-way ANOVA mean squares.
* ``spearman`` — the rehabilitation-robot lower-limb model paper, Table 4 (rank correlation).
* ``area_ratio`` — the EMG-driven vs OpenSim thesis, Tables 4.5–4.6: ratio of trapezoidal areas
  under two curves.
* ``r2``, ``rms`` — the EMG-driven vs OpenSim thesis, §3 (coefficient of determination and RMS
  difference).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import MissingDataError, ShapeMismatchError

__all__ = [
    "IccForm",
    "PeakMode",
    "area_ratio",
    "icc",
    "nrmsd",
    "nrmse",
    "peak_difference",
    "pearson_r",
    "r2",
    "rms",
    "root_mean_square",
    "sem",
    "spearman",
]

IccForm = Literal["1,1", "2,1", "3,1", "1,k", "2,k", "3,k"]
PeakMode = Literal["max", "min", "absmax"]

Metric = float | NDArray[np.float64]


def _pair(a: ArrayLike, b: ArrayLike, what: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    x = np.asarray(a, dtype=float)
    y = np.asarray(b, dtype=float)
    if x.shape != y.shape:
        raise ShapeMismatchError(f"{what}: shapes differ, {x.shape} vs {y.shape}")
    if x.ndim not in (1, 2):
        raise ShapeMismatchError(f"{what}: expected 1-D or 2-D arrays, got shape {x.shape}")
    if x.shape[0] == 0:
        raise MissingDataError(f"{what}: empty input (0 samples)")
    if np.isnan(x).any() or np.isnan(y).any():
        raise MissingDataError(f"{what}: input contains NaN samples; drop or fill them first")
    return x, y


def _out(v: NDArray[np.float64] | np.floating) -> Metric:
    v = np.asarray(v, dtype=float)
    return float(v) if v.ndim == 0 else v


def root_mean_square(x: ArrayLike) -> float:
    """Root mean square ``sqrt(mean(x²))`` over every element (same units as input)."""
    v = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean(v**2)))


def rms(a: ArrayLike, b: ArrayLike) -> Metric:
    """Root-mean-square difference ``sqrt(mean((a - b)^2))`` over axis 0 (same units as input)."""
    x, y = _pair(a, b, "rms")
    return _out(np.sqrt(np.mean((x - y) ** 2, axis=0)))


def nrmsd(measured: ArrayLike, simulated: ArrayLike) -> Metric:
    """Normalised RMS deviation in percent, Benoussaad et al. 2013, Eq. 9.

    ``NRMSD = sqrt(1/N sum (X_m - X_s)^2) / |max(X_m) - min(X_m)| x 100``: the normalisation is
    the range of the *measured* data.  A constant measured signal has no range: the result is
    ``inf`` (or ``nan`` if both are equal), never an exception.
    """
    x, y = _pair(measured, simulated, "nrmsd")
    num = np.sqrt(np.mean((x - y) ** 2, axis=0))
    den = np.abs(np.max(x, axis=0) - np.min(x, axis=0))
    with np.errstate(divide="ignore", invalid="ignore"):
        return _out(100.0 * num / den)


def nrmse(measured: ArrayLike, simulated: ArrayLike) -> Metric:
    """Normalised RMS error in percent, the implanted-FES identification paper, §V.

    "The RMS error was normalized to the RMS value of the measured data":
    ``NRMSE = sqrt(mean((X_m - X_s)^2)) / sqrt(mean(X_m^2)) x 100``.  Note that it depends on the
    origin of ``X_m`` (angles from the vertical vs. from full extension give different values).
    """
    x, y = _pair(measured, simulated, "nrmse")
    num = np.sqrt(np.mean((x - y) ** 2, axis=0))
    den = np.sqrt(np.mean(x**2, axis=0))
    with np.errstate(divide="ignore", invalid="ignore"):
        return _out(100.0 * num / den)


def r2(measured: ArrayLike, predicted: ArrayLike) -> Metric:
    """Coefficient of determination ``1 - SS_res / SS_tot`` (can be negative for bad fits)."""
    x, y = _pair(measured, predicted, "r2")
    ss_res = np.sum((x - y) ** 2, axis=0)
    ss_tot = np.sum((x - np.mean(x, axis=0)) ** 2, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return _out(1.0 - ss_res / ss_tot)


def pearson_r(a: ArrayLike, b: ArrayLike) -> Metric:
    """Pearson product-moment correlation coefficient (its square is r² of a linear fit)."""
    x, y = _pair(a, b, "pearson_r")
    xc = x - np.mean(x, axis=0)
    yc = y - np.mean(y, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.sum(xc * yc, axis=0) / np.sqrt(np.sum(xc**2, axis=0) * np.sum(yc**2, axis=0))
    return _out(np.clip(r, -1.0, 1.0))


def _rank(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Average ranks (ties share the mean rank), column-wise: a value's rank is the mean of the
    1-based positions its ties take in the sorted column (``scipy.stats.rankdata``'s
    ``"average"``, without importing scipy.stats)."""
    cols = np.asarray(x, dtype=float).reshape(x.shape[0], -1)
    out = np.empty_like(cols)
    for c in range(cols.shape[1]):
        order = np.argsort(cols[:, c], kind="stable")
        s = cols[order, c]
        new = np.concatenate([[True], s[1:] != s[:-1]])
        bounds = np.concatenate([np.flatnonzero(new), [s.size]])  # each tie group's start, end
        out[order, c] = (0.5 * (bounds[:-1] + 1 + bounds[1:]))[np.cumsum(new) - 1]
    return out.reshape(x.shape)


def spearman(a: ArrayLike, b: ArrayLike) -> Metric:
    """Spearman rank correlation ρ: Pearson correlation of the (average-tie) ranks, the
    rehabilitation-robot lower-limb model paper."""
    x, y = _pair(a, b, "spearman")
    return pearson_r(_rank(x), _rank(y))


def _anova2(y: NDArray[np.float64]) -> tuple[float, float, float, float, int, int]:
    n, k = y.shape
    grand = y.mean()
    ss_rows = k * np.sum((y.mean(axis=1) - grand) ** 2)
    ss_cols = n * np.sum((y.mean(axis=0) - grand) ** 2)
    ss_tot = np.sum((y - grand) ** 2)
    ss_err = ss_tot - ss_rows - ss_cols
    bms = ss_rows / (n - 1)
    jms = ss_cols / (k - 1)
    ems = ss_err / ((n - 1) * (k - 1))
    wms = (ss_cols + ss_err) / (n * (k - 1))
    return bms, jms, ems, wms, n, k


def icc(ratings: ArrayLike, other: ArrayLike | None = None, *, form: IccForm = "2,1") -> float:
    """Intraclass correlation coefficient (Shrout & Fleiss 1979), as used in the
    rehabilitation-robot lower-limb model paper.

    ``ratings`` is ``(n_targets, k_raters)``; with ``other`` given, the two 1-D series are the
    two raters (e.g. model estimate and measurement, the rehabilitation-robot lower-limb model
    paper, Table 6) and ``k = 2``.  With the between-targets (BMS), between-raters (JMS), residual
    (EMS) and within-target (WMS) mean squares of the two-way ANOVA:

    * ICC(1,1) = (BMS − WMS) / (BMS + (k−1) WMS)
    * ICC(2,1) = (BMS − EMS) / (BMS + (k−1) EMS + k (JMS − EMS)/n)   (absolute agreement)
    * ICC(3,1) = (BMS − EMS) / (BMS + (k−1) EMS)                     (consistency)
    * ICC(1,k) = (BMS − WMS)/BMS, ICC(2,k) = (BMS − EMS)/(BMS + (JMS − EMS)/n),
      ICC(3,k) = (BMS − EMS)/BMS (reliability of the mean of the k raters).
    """
    if other is not None:
        x, y = _pair(ratings, other, "icc")
        if x.ndim != 1:
            raise ShapeMismatchError(f"icc: two-rater form needs 1-D series, got shape {x.shape}")
        data = np.column_stack([x, y])
    else:
        data = np.asarray(ratings, dtype=float)
        if data.ndim != 2:
            raise ShapeMismatchError(
                f"icc: ratings must be (n_targets, k_raters), got {data.shape}"
            )
        if np.isnan(data).any():
            raise MissingDataError("icc: ratings contain NaN")
    if data.shape[0] < 2 or data.shape[1] < 2:
        raise MissingDataError(f"icc: need at least 2 targets and 2 raters, got {data.shape}")
    bms, jms, ems, wms, n, k = _anova2(data)
    with np.errstate(divide="ignore", invalid="ignore"):
        if form == "1,1":
            v = (bms - wms) / (bms + (k - 1) * wms)
        elif form == "2,1":
            v = (bms - ems) / (bms + (k - 1) * ems + k * (jms - ems) / n)
        elif form == "3,1":
            v = (bms - ems) / (bms + (k - 1) * ems)
        elif form == "1,k":
            v = (bms - wms) / bms
        elif form == "2,k":
            v = (bms - ems) / (bms + (jms - ems) / n)
        elif form == "3,k":
            v = (bms - ems) / bms
        else:
            raise ShapeMismatchError(f"icc: unknown form {form!r}")
    return float(v)


def sem(
    ratings: ArrayLike,
    other: ArrayLike | None = None,
    *,
    form: IccForm = "2,1",
    percent_of_range: bool = False,
) -> float:
    """Standard error of measurement ``SEM = SD sqrt(1 − ICC)`` (the rehabilitation-robot lower-limb
    model paper, Tables 3, 5, 6).

    ``SD`` is the sample standard deviation (ddof=1) of all observations pooled; ICC is
    :func:`icc` of the given ``form``.  With ``percent_of_range`` the SEM is expressed, as in
    the rehabilitation-robot lower-limb model paper, as a percentage of the range (max − min) of all
    observations.
    """
    if other is not None:
        x, y = _pair(ratings, other, "sem")
        data = np.column_stack([x, y])
    else:
        data = np.asarray(ratings, dtype=float)
    value = icc(data, form=form)
    sd = float(np.std(data, ddof=1))
    s = sd * np.sqrt(max(0.0, 1.0 - value))
    if percent_of_range:
        rng = float(np.max(data) - np.min(data))
        return float("inf") if rng == 0 else 100.0 * s / rng
    return float(s)


def area_ratio(a: ArrayLike, b: ArrayLike, *, t: ArrayLike | None = None) -> Metric:
    """Ratio of trapezoidal areas under ``a`` and ``b``: ``∫a dt / ∫b dt`` (the EMG-driven vs
    OpenSim thesis Tab. 4.5).

    ``t`` (s) is the common time base; without it unit spacing is used (the ratio does not depend
    on a uniform spacing).
    """
    x, y = _pair(a, b, "area_ratio")
    tt = None if t is None else np.asarray(t, dtype=float)
    if tt is not None and tt.shape != (x.shape[0],):
        raise ShapeMismatchError(f"area_ratio: time has shape {tt.shape}, data {x.shape}")
    ax = np.trapezoid(x, x=tt, axis=0)
    ay = np.trapezoid(y, x=tt, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return _out(ax / ay)


def peak_difference(a: ArrayLike, b: ArrayLike, *, mode: PeakMode = "max") -> Metric:
    """Difference of peaks ``peak(a) − peak(b)``; ``mode`` is ``max``, ``min`` or ``absmax``.

    ``absmax`` compares the largest magnitudes (``max|a| − max|b|``).
    """
    x, y = _pair(a, b, "peak_difference")
    if mode == "max":
        return _out(np.max(x, axis=0) - np.max(y, axis=0))
    if mode == "min":
        return _out(np.min(x, axis=0) - np.min(y, axis=0))
    if mode == "absmax":
        return _out(np.max(np.abs(x), axis=0) - np.max(np.abs(y), axis=0))
    raise ShapeMismatchError(f"peak_difference: unknown mode {mode!r}")
