"""Section ``spatiotemporal``: the spatiotemporal parameters of each side (stride and step time,
cadence, stance, swing and double-support %, stride and step length, walking speed) from the
gait events and the pelvis' travel, left beside right.

Per cycle i of one side, strike s_i, next strike s_{i+1}, foot off o_i, and the other foot's
foot off o' and strike s' inside it (Perry & Burnfield 2010 phases): stride time T = s_{i+1} −
s_i; cadence 120 / T steps/min; stance 100·(o_i − s_i)/T %; double support
100·((o' − s_i) + (o_i − s'))/T %; step time s_i − (the other foot's last strike before s_i);
stride length the pelvis' horizontal travel from s_i to s_{i+1} (model frame, walking along
+x); speed stride length / T.

The norm column holds the normative set's scalar rows (:mod:`msk.gait.norms`): its mean ± SD;
a side whose mean lies more than :data:`NORM_FLAG_SD` normative SDs from the normative mean is
marked (▲ above, ▼ below, and coloured).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from msk.exceptions import MskError
from msk.report.cycles import cycle_bounds
from msk.report.sections.base import ReportContext, Section
from msk.results.folder import SessionResults, pooled_gait

__all__ = ["NORM_FLAG_SD", "Spatiotemporal", "norm_position", "spatiotemporal_from_events"]

#: (key, label, unit, format)
PARAMETERS = (
    ("walking_speed_m_s", "walking speed", "m/s", ".2f"),
    ("cadence_steps_per_min", "cadence", "steps/min", ".1f"),
    ("stride_time_s", "stride time", "s", ".3f"),
    ("step_time_s", "step time", "s", ".3f"),
    ("stride_length_m", "stride length", "m", ".3f"),
    ("step_length_m", "step length", "m", ".3f"),
    ("step_width_m", "step width", "m", ".3f"),
    ("stance_pct", "stance", "% cycle", ".1f"),
    ("swing_pct", "swing", "% cycle", ".1f"),
    ("double_support_pct", "double support", "% cycle", ".1f"),
)


def _events(res: SessionResults, label: str, side: str) -> list[float]:
    return sorted(
        float(e.time)
        for e in res.summary.events or ()
        if e.label == label and str(e.context).lower() == side and e.time is not None
    )


def spatiotemporal_from_events(res: SessionResults) -> dict[str, dict[str, list[float]]]:
    """Per side, per parameter (:data:`PARAMETERS`), the value of every cycle."""
    pelvis = None
    if res.has("q"):
        q = res.table("q")
        if {"pelvis_tx", "pelvis_tz"} <= set(q.columns):
            pelvis = (q.time, q.column("pelvis_tx"), q.column("pelvis_tz"))

    def travel(a: float, b: float) -> float:
        if pelvis is None:
            return float("nan")
        t, x, z = pelvis
        if a < t[0] or b > t[-1]:
            return float("nan")
        return float(np.hypot(np.interp(b, t, x) - np.interp(a, t, x),
                              np.interp(b, t, z) - np.interp(a, t, z)))  # fmt: skip

    out: dict[str, dict[str, list[float]]] = {}
    for side, other in (("left", "right"), ("right", "left")):
        strikes, offs = _events(res, "Foot Strike", side), _events(res, "Foot Off", side)
        o_strikes, o_offs = _events(res, "Foot Strike", other), _events(res, "Foot Off", other)
        vals: dict[str, list[float]] = {k: [] for k, *_ in PARAMETERS}
        for a, b, off in cycle_bounds(strikes, offs):
            T = b - a
            vals["stride_time_s"].append(T)
            vals["cadence_steps_per_min"].append(120.0 / T)
            vals["stance_pct"].append(100.0 * (off - a) / T)
            vals["swing_pct"].append(100.0 * (b - off) / T)
            oo = [t for t in o_offs if a < t < b]
            os_ = [t for t in o_strikes if a < t < b]
            ds = (oo[0] - a) + (off - os_[0]) if oo and os_ and np.isfinite(off) else np.nan
            vals["double_support_pct"].append(100.0 * ds / T)
            prev = [t for t in o_strikes if a - T < t < a]
            vals["step_time_s"].append(a - prev[-1] if prev else np.nan)
            stride = travel(a, b)
            vals["stride_length_m"].append(stride)
            vals["step_length_m"].append(travel(prev[-1], a) if prev else np.nan)
            vals["walking_speed_m_s"].append(stride / T)
            vals["step_width_m"].append(np.nan)
        out[side] = vals
    return out


#: how many normative SDs from the normative mean a side's mean may sit before the table marks it
#: (±2 SD: ~95 % of a normal population inside)
NORM_FLAG_SD = 2.0


def _finite(values: list[float]) -> np.ndarray:
    v = np.asarray(values, dtype=float)
    return v[np.isfinite(v)]


def _cell(values: list[float], fmt: str) -> str:
    v = _finite(values)
    if not v.size:
        return "—"
    if v.size == 1:
        return f"{v[0]:{fmt}}"
    return f"{v.mean():{fmt}} ± {v.std(ddof=1):{fmt}} (n {v.size})"


def norm_position(values: list[float], norm: tuple[float, float] | None) -> str:
    """Where a side's mean sits against a normative (mean, SD): ``"high"`` / ``"low"`` beyond
    :data:`NORM_FLAG_SD` SDs, ``""`` inside them or when either is unknown."""
    v = _finite(values)
    if norm is None or not v.size or not (np.isfinite(norm[0]) and np.isfinite(norm[1])):
        return ""
    z = (float(v.mean()) - norm[0]) / norm[1] if norm[1] > 0 else 0.0
    return "high" if z > NORM_FLAG_SD else "low" if z < -NORM_FLAG_SD else ""


def _norm_cell(norm: tuple[float, float] | None, fmt: str) -> str:
    if norm is None or not np.isfinite(norm[0]):
        return "—"
    return f"{norm[0]:{fmt}}" + (f" ± {norm[1]:{fmt}}" if np.isfinite(norm[1]) else "")


def _from_gait(
    trials: Sequence[SessionResults],
) -> tuple[dict[str, dict[str, list[float]]], str] | None:
    try:
        _, st = pooled_gait(trials)
    except (MskError, ValueError):
        st = None
    if st is None:
        return None
    out: dict[str, dict[str, list[float]]] = {}
    for side in ("left", "right"):
        sd = st.side(side)
        out[side] = {
            k: [float(x) for x in sd.parameter(k)] if k in sd.parameters else []
            for k, *_ in PARAMETERS
        }
    how = (
        "times from the gait events; lengths, speed and step width from the heel positions "
        f"({st.source}) along the direction of progression (msk.gait)"
    )
    return out, how


class Spatiotemporal(Section):
    key = "spatiotemporal"
    title = "Spatiotemporal parameters"
    order = 20

    def context(self, ctx: ReportContext) -> dict[str, Any] | None:
        if not ctx.gait or not ctx.res.summary.events:
            return None
        typed = _from_gait(ctx.trials or (ctx.res,))
        if typed is not None:
            vals, how = typed
        else:
            vals = {"left": {}, "right": {}}
            for trial in ctx.trials or (ctx.res,):
                for side, params in spatiotemporal_from_events(trial).items():
                    for k, v in params.items():
                        vals[side].setdefault(k, []).extend(v)
            how = (
                "times from the gait events; lengths and speed from the pelvis' horizontal "
                "travel between foot strikes; step width needs the feet's positions (not "
                "computed here: “—”)"
            )
        if not any(vals[s]["stride_time_s"] for s in vals):
            return None
        norms = ctx.norms
        rows, flagged = [], 0
        for k, label, unit, fmt in PARAMETERS:
            norm = norms.scalar(k) if norms is not None else None
            cells = [
                (f"{label} ({unit})", ""),
            ]
            for side in ("left", "right"):
                pos = norm_position(vals[side][k], norm)
                flagged += bool(pos)
                mark = {"high": " ▲", "low": " ▼"}.get(pos, "")
                cells.append((_cell(vals[side][k], fmt) + mark, f"out {pos}" if pos else ""))
            cells.append((_norm_cell(norm, fmt), ""))
            rows.append(cells)
        cycles = {s: len(vals[s]["stride_time_s"]) for s in vals}
        named = norms.population.split(":")[0] if norms is not None else ""
        return {
            "rows": rows, "cycles": cycles, "how": how, "norms_named": named,
            "has_scalars": bool(norms is not None and norms.scalars), "flagged": flagged,
            "flag_sd": f"{NORM_FLAG_SD:g}",
            "norm_n": (norms.notes.get("n_sessions_spatiotemporal", "") if norms else ""),
        }  # fmt: skip
