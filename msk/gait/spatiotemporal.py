"""Spatiotemporal parameters of a walk, per side and per stride, from the gait events and the
heel positions.

A stride of side s runs from its foot strike t_i to its next one t_{i+1} (the cycle of
:mod:`msk.gait.cycles`); c is the contralateral foot strike inside it and o_s, o_c the foot
offs of side s and of the other side. With h_s(t) the heel position of side s (the origin of
the calcaneus / foot body, or a heel marker), ĥ the unit vector up, and the direction of
progression d̂ the horizontal unit vector of h_s(t_{i+1}) − h_s(t_i) (the definitions of
Vicon's Plug-in Gait and of Perry & Burnfield 2010, ch. 1):

* stride time T = t_{i+1} − t_i; stride length L = |h_s(t_{i+1}) − h_s(t_i)| horizontally;
* walking speed v = L / T; cadence = 120 / T steps/min (two steps per stride);
* step time = t_{i+1} − c (contralateral strike to this side's strike); step length = (h_s −
  h_c) · d̂ at t_{i+1}; step width = the horizontal distance of h_s(t_{i+1}) from the line
  through h_c(c) along d̂ (both feet on the ground);
* stance % = 100 (o_s − t_i)/T, swing % = 100 − stance %; double support % = 100 [(o_c − t_i) +
  (o_s − c)]/T, the initial and the terminal double support (o_c the other foot's off after t_i,
  before o_s).

On a treadmill the heels are first expressed relative to the belt: h_s(t) − u t, u the belt's
horizontal velocity (:func:`surface_velocity`: zero overground), so that the same definitions
give the stride on the belt (stride length = belt speed × stride time at a steady pace).

A parameter whose events are missing in a stride is NaN for that stride;
:meth:`SideSpatiotemporal.mean` and :meth:`~SideSpatiotemporal.sd` are over the strides that have
it.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from msk.exceptions import MissingDataError, ShapeMismatchError
from msk.gait.cycles import SIDES
from msk.units import Array

__all__ = [
    "PARAMETERS",
    "TREADMILL_PELVIS_SPEED_M_S",
    "SideSpatiotemporal",
    "Spatiotemporal",
    "spatiotemporal",
    "surface_velocity",
]

#: a walk whose pelvis advances slower than this (m/s, horizontally, first to last known frame)
#: is on a treadmill: overground gait is faster than 0.4 m/s even in slow pathological walkers
#: (Perry & Burnfield 2010, ch. 21)
TREADMILL_PELVIS_SPEED_M_S = 0.25

#: the parameters, units in the names (SI but for cadence and the percentages)
PARAMETERS: tuple[str, ...] = (
    "walking_speed_m_s",
    "cadence_steps_per_min",
    "stride_length_m",
    "stride_time_s",
    "step_length_m",
    "step_time_s",
    "stance_pct",
    "swing_pct",
    "double_support_pct",
    "step_width_m",
)


@dataclass(frozen=True)
class SideSpatiotemporal:
    """The spatiotemporal parameters of one side, stride by stride.

    Attributes:
        side: ``"left"`` or ``"right"``.
        stride_start_s: (n_strides,) the foot strike that starts each stride, s.
        values: (n_strides, len(parameters)) each stride's parameters (NaN: not computable).
        parameters: the column names of ``values`` (:data:`PARAMETERS`).
    """

    side: str
    stride_start_s: Array
    values: Array
    parameters: tuple[str, ...] = PARAMETERS

    def __post_init__(self) -> None:
        shape = (np.size(self.stride_start_s), len(self.parameters))
        if np.shape(self.values) != shape:
            raise ShapeMismatchError(
                f"{self.side} spatiotemporal: values {np.shape(self.values)}, expected {shape}"
            )

    @property
    def n_strides(self) -> int:
        """Number of strides."""
        return int(np.size(self.stride_start_s))

    def parameter(self, name: str) -> Array:
        """(n_strides,) one parameter per stride."""
        try:
            return np.asarray(self.values, dtype=float)[:, self.parameters.index(name)]
        except ValueError:
            raise MissingDataError(
                f"spatiotemporal: no parameter {name!r} (have {', '.join(self.parameters)})"
            ) from None

    def mean(self, name: str) -> float:
        """Mean over the strides that have ``name`` (NaN if none)."""
        x = self.parameter(name)
        x = x[np.isfinite(x)]
        return float(x.mean()) if x.size else float("nan")

    def sd(self, name: str) -> float:
        """Sample SD (n − 1) over the strides that have ``name`` (NaN with fewer than two)."""
        x = self.parameter(name)
        x = x[np.isfinite(x)]
        return float(x.std(ddof=1)) if x.size > 1 else float("nan")


@dataclass(frozen=True)
class Spatiotemporal:
    """Spatiotemporal parameters of both sides (module docstring).

    Attributes:
        left, right: :class:`SideSpatiotemporal`.
        source: where the heel positions come from (``"model"``: the feet's body origins,
            or the markers named).
        notes: what was decided (a stride without its contralateral events…).
    """

    left: SideSpatiotemporal
    right: SideSpatiotemporal
    source: str = "model"
    notes: tuple[str, ...] = ()

    def side(self, side: str) -> SideSpatiotemporal:
        """The parameters of ``side``."""
        if side not in SIDES:
            raise MissingDataError(f"spatiotemporal: no side {side!r} (left, right)")
        return self.left if side == "left" else self.right

    @staticmethod
    def concatenate(parts: Sequence[Spatiotemporal]) -> Spatiotemporal:
        """The strides of several trials (or sessions) pooled, per side (the parameters of the
        first part; a parameter another part lacks is NaN in its strides)."""
        if not parts:
            raise MissingDataError("spatiotemporal: nothing to pool")
        names = parts[0].left.parameters
        sides = {}
        for s in SIDES:
            starts, rows = [], []
            for p in parts:
                sp = p.side(s)
                starts.append(np.asarray(sp.stride_start_s, dtype=float))
                cols = [
                    sp.parameter(n) if n in sp.parameters else np.full(sp.n_strides, np.nan)
                    for n in names
                ]
                rows.append(np.column_stack(cols) if cols else np.zeros((sp.n_strides, 0)))
            sides[s] = SideSpatiotemporal(
                s, np.concatenate(starts), np.concatenate(rows).reshape(-1, len(names)), names
            )
        notes = tuple(dict.fromkeys(n for p in parts for n in p.notes))
        sources = ", ".join(dict.fromkeys(p.source for p in parts))
        return Spatiotemporal(sides["left"], sides["right"], sources, notes)

    def to_summary(self) -> dict[str, object]:
        """The ``summary.json`` ``gait.spatiotemporal`` object: side → ``{"n_strides",
        "stride_start_s", "parameters": {name: {"mean", "sd", "values"}}}``
        (:class:`msk.results.summary.SpatiotemporalSide`)."""
        out: dict[str, object] = {}
        for s in SIDES:
            sp = self.side(s)
            out[s] = {
                "n_strides": sp.n_strides,
                "stride_start_s": [float(x) for x in sp.stride_start_s],
                "parameters": {
                    p: {
                        "mean": _opt(sp.mean(p)),
                        "sd": _opt(sp.sd(p)),
                        "values": [_opt(x) for x in sp.parameter(p)],
                    }
                    for p in sp.parameters
                },
            }
        return out

    @staticmethod
    def from_summary(sides: Mapping[str, object], *, source: str = "model") -> Spatiotemporal:
        """The parameters of a ``gait.spatiotemporal`` object of the summary (a mapping
        side → :class:`msk.results.summary.SpatiotemporalSide` or its plain JSON)."""
        parts = {}
        for s in SIDES:
            rec = sides.get(s)
            if rec is None:
                parts[s] = SideSpatiotemporal(s, np.zeros(0), np.zeros((0, len(PARAMETERS))))
                continue
            d = rec.to_dict() if hasattr(rec, "to_dict") else rec
            assert isinstance(d, Mapping)
            names = tuple(d["parameters"])
            start = np.array([np.nan if x is None else x for x in d["stride_start_s"]], float)
            vals = np.array(
                [[np.nan if x is None else x for x in d["parameters"][p]["values"]] for p in names],
                dtype=float,
            ).reshape(len(names), start.size)
            parts[s] = SideSpatiotemporal(s, start, vals.T.copy(), names)
        return Spatiotemporal(parts["left"], parts["right"], source)


def _opt(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def _first(xs: Sequence[float], lo: float, hi: float) -> float:
    inside = [x for x in xs if lo < x < hi]
    return inside[0] if inside else float("nan")


def _last(xs: Sequence[float], lo: float, hi: float) -> float:
    inside = [x for x in xs if lo < x < hi]
    return inside[-1] if inside else float("nan")


def _at(time: Array, pos: Array, t: float) -> Array:
    """Position at time ``t`` (linear interpolation per axis; NaN outside)."""
    if not np.isfinite(t) or t < time[0] or t > time[-1]:
        return np.full(3, np.nan)
    return np.array([np.interp(t, time, pos[:, k]) for k in range(3)])


def surface_velocity(
    time: Array,
    heel: Mapping[str, Array],
    foot_strike: Mapping[str, Sequence[float]],
    foot_off: Mapping[str, Sequence[float]],
    *,
    pelvis: Array,
    up: Array,
) -> Array:
    """(3,) the horizontal velocity of the surface walked on (m/s): zero overground; on a
    treadmill (the pelvis advancing slower than :data:`TREADMILL_PELVIS_SPEED_M_S`) the belt's,
    the median horizontal velocity of the heels over the middle half of their stances (a foot
    standing on the belt moves with it)."""
    t = np.asarray(time, dtype=float)
    u = np.asarray(up, dtype=float) / np.linalg.norm(up)
    p = np.asarray(pelvis, dtype=float)
    ok = np.flatnonzero(np.isfinite(p).all(axis=1))
    if ok.size < 2:
        return np.zeros(3)
    d = p[ok[-1]] - p[ok[0]]
    d = d - (d @ u) * u
    if np.linalg.norm(d) / max(t[ok[-1]] - t[ok[0]], 1e-9) >= TREADMILL_PELVIS_SPEED_M_S:
        return np.zeros(3)
    vel: list[Array] = []
    for s in SIDES:
        if s not in heel:
            continue
        h = np.asarray(heel[s], dtype=float)
        v = np.gradient(h, t, axis=0)
        offs = sorted(float(x) for x in foot_off.get(s, ()))
        for a in sorted(float(x) for x in foot_strike.get(s, ())):
            off = _first(offs, a, np.inf)
            if not np.isfinite(off):
                continue
            mid = (t >= a + 0.25 * (off - a)) & (t <= a + 0.75 * (off - a))
            vel.append(v[mid])
    if not vel:
        return np.zeros(3)
    allv = np.concatenate(vel)
    allv = allv[np.isfinite(allv).all(axis=1)]
    if not allv.size:
        return np.zeros(3)
    m = np.median(allv, axis=0)
    return m - (m @ u) * u


def spatiotemporal(
    time: Array,
    heel: Mapping[str, Array],
    foot_strike: Mapping[str, Sequence[float]],
    foot_off: Mapping[str, Sequence[float]],
    *,
    up: Array,
    source: str = "model",
    surface: Array | None = None,
) -> Spatiotemporal:
    """Per side and stride the parameters of the module docstring.

    Args:
        time: (N,) s.
        heel: side → (N, 3) heel position in the world (m; NaN where unknown).
        foot_strike, foot_off: side → event times (s).
        up: (3,) the world's up direction.
        source: where ``heel`` comes from (kept in the result).
        surface: (3,) the walking surface's velocity (m/s; a treadmill's belt,
            :func:`surface_velocity`); None: at rest.
    """
    t = np.asarray(time, dtype=float)
    u = np.asarray(up, dtype=float)
    u = u / np.linalg.norm(u)
    notes: list[str] = []

    def horiz(x: Array) -> Array:
        return x - (x @ u) * u

    parts = {}
    for s in SIDES:
        o = "right" if s == "left" else "left"
        hs = sorted(float(x) for x in foot_strike.get(s, ()))
        ho = sorted(float(x) for x in foot_strike.get(o, ()))
        fs = sorted(float(x) for x in foot_off.get(s, ()))
        fo = sorted(float(x) for x in foot_off.get(o, ()))
        ps = np.asarray(heel[s], dtype=float) if s in heel else np.full((t.size, 3), np.nan)
        po = np.asarray(heel[o], dtype=float) if o in heel else np.full((t.size, 3), np.nan)
        if surface is not None:  # on the belt
            ps = ps - t[:, None] * np.asarray(surface, dtype=float)
            po = po - t[:, None] * np.asarray(surface, dtype=float)
        rows, starts = [], []
        for a, b in itertools.pairwise(hs):
            T = b - a
            r = dict.fromkeys(PARAMETERS, np.nan)
            r["stride_time_s"] = T
            r["cadence_steps_per_min"] = 120.0 / T
            d = horiz(_at(t, ps, b) - _at(t, ps, a))
            length = float(np.linalg.norm(d))
            r["stride_length_m"] = length
            r["walking_speed_m_s"] = length / T
            dh = d / length if np.isfinite(length) and length > 0 else np.full(3, np.nan)
            c = _last(ho, a, b)
            off = _first(fs, a, b)
            off_c = _first(fo, a, off if np.isfinite(off) else b)
            r["stance_pct"] = 100.0 * (off - a) / T
            r["swing_pct"] = 100.0 - r["stance_pct"]
            r["double_support_pct"] = 100.0 * ((off_c - a) + (off - c)) / T
            if np.isfinite(c):
                r["step_time_s"] = b - c
                hb, hc_b, hc_c = _at(t, ps, b), _at(t, po, b), _at(t, po, c)
                r["step_length_m"] = float(horiz(hb - hc_b) @ dh)
                w = horiz(hb - hc_c)
                r["step_width_m"] = float(np.linalg.norm(w - (w @ dh) * dh))
            else:
                notes.append(f"{s} stride at {a:.3f} s: no {o} foot strike inside it")
            rows.append([r[p] for p in PARAMETERS])
            starts.append(a)
        vals = np.asarray(rows, dtype=float).reshape(len(rows), len(PARAMETERS))
        parts[s] = SideSpatiotemporal(s, np.asarray(starts, dtype=float), vals)
    return Spatiotemporal(parts["left"], parts["right"], source, tuple(notes))
