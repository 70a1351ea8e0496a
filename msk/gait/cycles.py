"""Every complete gait cycle of both legs, time-normalised to 0–100 % of the cycle.

A cycle of one foot runs from a foot strike to the next foot strike of the same foot
(Perry & Burnfield 2010, ch. 1; Kadaba et al. 1990 normalise it to 0–100 %); its foot off
lies between them, at

    foot_off_pct = 100 · (t_off − t_strike,i) / (t_strike,i+1 − t_strike,i).

A variable y(t) of the trial is sampled at the 101 instants t_k = t_strike,i + (k/100) ·
(t_strike,i+1 − t_strike,i), k = 0…100, by linear interpolation (:func:`normalise_cycles`).
Across cycles (and across trials, :meth:`GaitCycles.concatenate`), :meth:`SideCycles.mean` and
:meth:`SideCycles.sd` are the pointwise mean and sample standard deviation (n − 1) of the cycles,
NaN-aware: a cycle whose variable is unknown at a sample (a kinetic variable where the plates
did not measure that stance) does not enter that sample's mean.

The results folder holds one table per side, ``tables/gait_cycles_<side>.csv``
(:meth:`GaitCycles.to_tables`, :meth:`GaitCycles.from_tables`): one row per normalised
sample, first column ``time`` the trial time of the sample (s), then ``cycle`` (index of the
cycle), ``percent_cycle`` (0…100), ``foot_off_pct`` and ``measured`` (1 when the plates measured
the cycle's stance, else 0), then the variables.
"""

from __future__ import annotations

import itertools
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from msk.exceptions import MissingDataError, ShapeMismatchError
from msk.io.tables import Table
from msk.units import Array

__all__ = [
    "CYCLE_COLUMNS",
    "PERCENT",
    "SIDES",
    "GaitCycles",
    "SideCycles",
    "cycle_bounds",
    "normalise_cycles",
]

#: the 101 samples of a normalised cycle, % of the cycle
PERCENT: Array = np.linspace(0.0, 100.0, 101)
#: the sides, in the order of the report (left red, right green)
SIDES: tuple[str, str] = ("left", "right")
#: the columns of a ``gait_cycles_<side>`` table before the variables
CYCLE_COLUMNS: tuple[str, ...] = ("cycle", "percent_cycle", "foot_off_pct", "measured")


@dataclass(frozen=True)
class SideCycles:
    """The normalised cycles of one side.

    Attributes:
        side: ``"left"`` or ``"right"``.
        values: (n_cycles, 101, n_vars) the variables at 0, 1, …, 100 % of each cycle (the
            units of :attr:`GaitCycles.variables`' names; NaN where unknown).
        start_s, end_s: (n_cycles,) the cycle's foot strike and the next one of the same
            foot, s (trial time).
        foot_off_pct: (n_cycles,) the foot off of the cycle, % of the cycle (NaN without one).
        measured: (n_cycles,) whether the plates measured the cycle's stance (strike to foot
            off): its kinetic variables are NaN otherwise.
        trial: (n_cycles,) the task trial each cycle comes from.
    """

    side: str
    values: Array
    start_s: Array
    end_s: Array
    foot_off_pct: Array
    measured: np.ndarray
    trial: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        n = np.shape(self.values)[0]
        for name in ("start_s", "end_s", "foot_off_pct", "measured"):
            if np.shape(getattr(self, name)) != (n,):
                raise ShapeMismatchError(
                    f"{self.side} cycles: {name} has shape {np.shape(getattr(self, name))}, "
                    f"expected ({n},)"
                )
        if np.ndim(self.values) != 3 or np.shape(self.values)[1] != PERCENT.size:
            raise ShapeMismatchError(
                f"{self.side} cycles: values have shape {np.shape(self.values)}, expected "
                f"(n_cycles, {PERCENT.size}, n_vars)"
            )
        if self.trial and len(self.trial) != n:
            raise ShapeMismatchError(
                f"{self.side} cycles: {len(self.trial)} trial names, {n} cycles"
            )

    @property
    def n_cycles(self) -> int:
        """Number of cycles."""
        return int(np.shape(self.values)[0])

    def mean(self) -> Array:
        """(101, n_vars) pointwise mean over the cycles (NaN where no cycle is known)."""
        return _nan_stat(np.asarray(self.values, dtype=float), np.nanmean)

    def sd(self) -> Array:
        """(101, n_vars) pointwise sample standard deviation over the cycles (n − 1; NaN with
        fewer than two known cycles)."""
        v = np.asarray(self.values, dtype=float)
        n = np.isfinite(v).sum(axis=0)
        out = np.full(v.shape[1:], np.nan)
        ok = n >= 2
        if ok.any():
            out[ok] = _nan_stat(v, lambda a, axis: np.nanstd(a, axis=axis, ddof=1))[ok]
        return out

    def mean_foot_off_pct(self) -> float:
        """Mean foot off over the cycles, % (NaN without one)."""
        f = np.asarray(self.foot_off_pct, dtype=float)
        return float(np.nanmean(f)) if np.isfinite(f).any() else float("nan")


def _nan_stat(v: Array, fn: Any) -> Array:
    if v.shape[0] == 0:
        return np.full(v.shape[1:], np.nan)
    # an unknown sample stays NaN: numpy's all-NaN-slice warnings are silenced
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.asarray(fn(v, axis=0), dtype=np.float64)


@dataclass(frozen=True)
class GaitCycles:
    """Every complete cycle of both legs, normalised to 101 samples (module docstring).

    Attributes:
        variables: the variable names, units in the name where not SI/rad (``_deg``,
            ``_nm_kg``: N·m per kg body mass, ``_w_kg``: W per kg); :mod:`msk.gait.variables`.
        left, right: :class:`SideCycles` of each side (no cycle: ``n_cycles`` 0).
        notes: what was decided (a variable the model does not have, a cycle left out).
    """

    variables: tuple[str, ...]
    left: SideCycles
    right: SideCycles
    notes: tuple[str, ...] = ()
    percent: Array = field(default_factory=lambda: PERCENT.copy())

    def __post_init__(self) -> None:
        for s in (self.left, self.right):
            if s.n_cycles and np.shape(s.values)[2] != len(self.variables):
                raise ShapeMismatchError(
                    f"{s.side} cycles have {np.shape(s.values)[2]} variables, names "
                    f"{len(self.variables)}"
                )

    def side(self, side: str) -> SideCycles:
        """The cycles of ``side`` (``"left"``/``"right"``)."""
        if side not in SIDES:
            raise MissingDataError(f"gait cycles: no side {side!r} (left, right)")
        return self.left if side == "left" else self.right

    def index(self, variable: str) -> int:
        """Column of ``variable`` in the values' last axis."""
        try:
            return self.variables.index(variable)
        except ValueError:
            raise MissingDataError(
                f"gait cycles: no variable {variable!r} (have {', '.join(self.variables)})"
            ) from None

    def variable(self, side: str, variable: str) -> Array:
        """(n_cycles, 101) one variable's cycles of one side."""
        return np.asarray(self.side(side).values)[:, :, self.index(variable)]

    def mean(self, side: str) -> Array:
        """(101, n_vars) mean over the side's cycles."""
        return self.side(side).mean()

    def sd(self, side: str) -> Array:
        """(101, n_vars) sample SD over the side's cycles."""
        return self.side(side).sd()

    @staticmethod
    def concatenate(parts: Sequence[GaitCycles]) -> GaitCycles:
        """The cycles of several trials (or sessions) pooled, per side; variables that not
        every part has are left out (said in ``notes``)."""
        if not parts:
            raise MissingDataError("gait cycles: nothing to pool")
        common = [v for v in parts[0].variables if all(v in p.variables for p in parts[1:])]
        dropped = sorted({v for p in parts for v in p.variables} - set(common))
        sides = {}
        for s in SIDES:
            vals, st, en, fo, me = [], [], [], [], []
            tr: list[str] = []
            for p in parts:
                sc = p.side(s)
                cols = [p.variables.index(v) for v in common]
                v = np.asarray(sc.values, dtype=float)
                vals.append(v[..., cols] if sc.n_cycles else np.zeros((0, 101, len(cols))))
                st.append(sc.start_s)
                en.append(sc.end_s)
                fo.append(sc.foot_off_pct)
                me.append(sc.measured)
                tr.extend(sc.trial or ("",) * sc.n_cycles)
            sides[s] = SideCycles(
                s,
                np.concatenate(vals).reshape(-1, 101, len(common)),
                np.concatenate(st).astype(float),
                np.concatenate(en).astype(float),
                np.concatenate(fo).astype(float),
                np.concatenate(me).astype(bool),
                tuple(tr),
            )
        notes = tuple(n for p in parts for n in p.notes)
        if dropped:
            notes += (f"variables not in every part, left out of the pool: {', '.join(dropped)}",)
        return GaitCycles(tuple(common), sides["left"], sides["right"], tuple(dict.fromkeys(notes)))

    # -- the results folder's tables ------------------------------------------------------------
    def to_tables(self) -> dict[str, Table]:
        """``{"gait_cycles_<side>": Table}`` of the sides with at least one cycle (module
        docstring; a side without a complete cycle has no table)."""
        out = {}
        k = PERCENT.size
        for s in SIDES:
            sc = self.side(s)
            n = sc.n_cycles
            if n == 0:
                continue
            frac = PERCENT / 100.0
            time = sc.start_s[:, None] + frac[None, :] * (sc.end_s - sc.start_s)[:, None]
            head = np.column_stack(
                [
                    np.repeat(np.arange(n, dtype=float), k),
                    np.tile(PERCENT, n),
                    np.repeat(np.asarray(sc.foot_off_pct, dtype=float), k),
                    np.repeat(np.asarray(sc.measured, dtype=float), k),
                ]
            )
            body = np.asarray(sc.values, dtype=float).reshape(n * k, len(self.variables))
            out[f"gait_cycles_{s}"] = Table(
                time=np.asarray(time, dtype=float).ravel(),
                data=np.hstack([head, body]),
                columns=CYCLE_COLUMNS + self.variables,
                name=f"gait_cycles_{s}",
            )
        return out

    @staticmethod
    def from_tables(tables: Mapping[str, Table], *, trial: str = "") -> GaitCycles:
        """The cycles of the tables :meth:`to_tables` wrote (``trial``: the task trial's name,
        for every cycle); a side without its table has no cycle."""
        present = [s for s in SIDES if f"gait_cycles_{s}" in tables]
        if not present:
            raise MissingDataError("results: no table 'gait_cycles_left' or 'gait_cycles_right'")
        first = tables[f"gait_cycles_{present[0]}"]
        variables = tuple(first.columns[len(CYCLE_COLUMNS) :])
        k = PERCENT.size
        sides = {}
        for s in SIDES:
            name = f"gait_cycles_{s}"
            if name not in tables:
                e = np.zeros(0)
                sides[s] = SideCycles(s, np.zeros((0, k, len(variables))), e, e, e, e > 0)
                continue
            tab = tables[name]
            if tuple(tab.columns[: len(CYCLE_COLUMNS)]) != CYCLE_COLUMNS:
                raise ShapeMismatchError(
                    f"table {name}: first columns {tab.columns[:4]}, expected {CYCLE_COLUMNS}"
                )
            if tuple(tab.columns[len(CYCLE_COLUMNS) :]) != variables:
                raise ShapeMismatchError(f"table {name}: variables differ from the other side's")
            d = np.asarray(tab.data, dtype=float)
            if d.shape[0] % k:
                raise ShapeMismatchError(f"table {name}: {d.shape[0]} rows, not a multiple of {k}")
            n = d.shape[0] // k
            t = np.asarray(tab.time, dtype=float).reshape(n, k)
            sides[s] = SideCycles(
                s,
                d[:, len(CYCLE_COLUMNS) :].reshape(n, k, len(variables)),
                t[:, 0].copy(),
                t[:, -1].copy(),
                d[::k, 2].copy(),
                d[::k, 3] > 0.5,
                (trial,) * n,
            )
        return GaitCycles(variables, sides["left"], sides["right"])


def cycle_bounds(
    strikes: Sequence[float], offs: Sequence[float]
) -> list[tuple[float, float, float]]:
    """Every complete cycle of one foot: ``(start, end, foot_off_pct)`` for each pair of
    consecutive strikes (foot off: the first one strictly between them, NaN without one)."""
    s = sorted(float(x) for x in strikes if np.isfinite(x))
    o = sorted(float(x) for x in offs if np.isfinite(x))
    out = []
    for a, b in itertools.pairwise(s):
        if b <= a:
            continue
        inside = [x for x in o if a < x < b]
        fo = 100.0 * (inside[0] - a) / (b - a) if inside else float("nan")
        out.append((a, b, fo))
    return out


def normalise_cycles(
    time: Array,
    values: Array,
    bounds: Sequence[tuple[float, float, float]],
) -> Array:
    """(n_cycles, 101, n_vars) the columns of ``values`` (N, n_vars) on ``time`` (N,) sampled
    at 0…100 % of each cycle ``(start, end, _)`` by linear interpolation; a sample next to a
    NaN of the series, or outside ``time``, is NaN."""
    t = np.asarray(time, dtype=float)
    y = np.asarray(values, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    if y.shape[0] != t.size:
        raise ShapeMismatchError(f"values have {y.shape[0]} rows, time {t.size}")
    out = np.full((len(bounds), PERCENT.size, y.shape[1]), np.nan)
    for i, (a, b, _) in enumerate(bounds):
        tk = a + PERCENT / 100.0 * (b - a)
        inside = (tk >= t[0] - 1e-9) & (tk <= t[-1] + 1e-9)
        j = np.clip(np.searchsorted(t, tk, side="right") - 1, 0, t.size - 2)
        w = np.clip((tk - t[j]) / np.maximum(t[j + 1] - t[j], 1e-12), 0.0, 1.0)
        v = y[j] * (1.0 - w[:, None]) + y[j + 1] * w[:, None]
        v[~inside] = np.nan
        out[i] = v
    return out
