"""The gait-cycle curves the report draws: every complete cycle of each leg, time-normalised
to 0–100 % of the cycle, per variable, with the foot off of each cycle.

A cycle of one foot runs from its foot strike to its next foot strike (Kadaba et al. 1990
normalise it to 0–100 %); a variable y(t) is sampled at t_k = t_strike,i + (k/100)·(t_strike,i+1
− t_strike,i), k = 0…100, by linear interpolation, and its foot off lies at
100·(t_off − t_strike,i)/(t_strike,i+1 − t_strike,i) %. The report's mean and SD are pointwise
over the cycles (NaN-aware: a kinetic curve is unknown where the plates did not measure the
stance). Built here from the tables of one results folder and its ``summary.events``
(:func:`curves_from_tables`).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from msk.results.folder import SessionResults
from msk.units import Array

__all__ = ["KINEMATICS", "KINETICS", "CycleCurves", "SideCurves", "Variable", "curves_from_tables"]

PERCENT = np.linspace(0.0, 100.0, 101)
#: two strikes of one foot farther apart than this are not one cycle (a gap in the events)
MAX_CYCLE_S = 2.5


@dataclass(frozen=True)
class Variable:
    """A curve of the grids: ``column`` of ``table`` (``{s}`` the side suffix ``_l``/``_r``)
    × ``sign``, in the unit of ``unit``; ``kind`` ``angle`` (rad → deg), ``moment`` (N·m →
    N·m/kg), ``power`` (the moment × the coordinate's angular velocity, W/kg)."""

    key: str
    title: str
    row: str
    plane: str
    column: str | None
    sign: float
    unit: str
    kind: str


_P = ("sagittal", "frontal", "transverse")
#: the kinematics grid: rows pelvis, hip, knee, ankle; columns the three planes
KINEMATICS: tuple[Variable, ...] = (
    Variable("pelvis_tilt", "Pelvis tilt (anterior +)", "pelvis", _P[0], "pelvis_tilt", -1.0, "deg", "angle"),
    Variable("pelvis_obliquity", "Pelvis obliquity (list)", "pelvis", _P[1], "pelvis_list", 1.0, "deg", "angle"),
    Variable("pelvis_rotation", "Pelvis rotation", "pelvis", _P[2], "pelvis_rotation", 1.0, "deg", "angle"),
    Variable("hip_flexion", "Hip flexion", "hip", _P[0], "hip_flexion{s}", 1.0, "deg", "angle"),
    Variable("hip_adduction", "Hip adduction", "hip", _P[1], "hip_adduction{s}", 1.0, "deg", "angle"),
    Variable("hip_rotation", "Hip internal rotation", "hip", _P[2], "hip_rotation{s}", 1.0, "deg", "angle"),
    Variable("knee_flexion", "Knee flexion", "knee", _P[0], "knee_angle{s}", -1.0, "deg", "angle"),
    Variable("knee_varus", "Knee varus", "knee", _P[1], None, 1.0, "deg", "angle"),
    Variable("knee_rotation", "Knee internal rotation", "knee", _P[2], None, 1.0, "deg", "angle"),
    Variable("ankle_dorsiflexion", "Ankle dorsiflexion", "ankle", _P[0], "ankle_angle{s}", 1.0, "deg", "angle"),
    Variable("subtalar_inversion", "Subtalar inversion", "ankle", _P[1], "subtalar_angle{s}", 1.0, "deg", "angle"),
    Variable("foot_progression", "Foot progression", "ankle", _P[2], None, 1.0, "deg", "angle"),
)  # fmt: skip
#: the kinetics grid: internal net joint moments (three planes) and sagittal powers
KINETICS: tuple[Variable, ...] = (
    Variable("hip_flexion_moment", "Hip flexion moment", "hip moment", _P[0], "hip_flexion{s}", 1.0, "N·m/kg", "moment"),
    Variable("hip_adduction_moment", "Hip adduction moment", "hip moment", _P[1], "hip_adduction{s}", 1.0, "N·m/kg", "moment"),
    Variable("hip_rotation_moment", "Hip internal rotation moment", "hip moment", _P[2], "hip_rotation{s}", 1.0, "N·m/kg", "moment"),
    Variable("knee_flexion_moment", "Knee flexion moment", "knee moment", _P[0], "knee_angle{s}", -1.0, "N·m/kg", "moment"),
    Variable("knee_adduction_moment", "Knee adduction moment", "knee moment", _P[1], None, 1.0, "N·m/kg", "moment"),
    Variable("knee_rotation_moment", "Knee rotation moment", "knee moment", _P[2], None, 1.0, "N·m/kg", "moment"),
    Variable("ankle_dorsiflexion_moment", "Ankle dorsiflexion moment", "ankle moment", _P[0], "ankle_angle{s}", 1.0, "N·m/kg", "moment"),
    Variable("subtalar_inversion_moment", "Subtalar inversion moment", "ankle moment", _P[1], "subtalar_angle{s}", 1.0, "N·m/kg", "moment"),
    Variable("ankle_rotation_moment", "Ankle rotation moment", "ankle moment", _P[2], None, 1.0, "N·m/kg", "moment"),
    Variable("hip_power", "Hip power", "power", _P[0], "hip_flexion{s}", 1.0, "W/kg", "power"),
    Variable("knee_power", "Knee power", "power", _P[0], "knee_angle{s}", 1.0, "W/kg", "power"),
    Variable("ankle_power", "Ankle power", "power", _P[0], "ankle_angle{s}", 1.0, "W/kg", "power"),
)  # fmt: skip


@dataclass(frozen=True)
class SideCurves:
    """The normalised cycles of one side: ``values[key]`` (n_cycles, 101), the cycles' foot
    strike times (s) and foot offs (% of the cycle, NaN without one)."""

    side: str
    values: dict[str, Array]
    start_s: Array
    end_s: Array
    foot_off_pct: Array

    @property
    def n_cycles(self) -> int:
        return int(np.size(self.start_s))

    def mean(self, key: str) -> Array | None:
        v = self.values.get(key)
        if v is None or not np.isfinite(v).any():
            return None
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return np.nanmean(v, axis=0)

    def sd(self, key: str) -> Array | None:
        v = self.values.get(key)
        if v is None or (np.isfinite(v).sum(axis=0) < 2).all():
            return None
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return np.nanstd(v, axis=0, ddof=1)

    def cycles_with(self, key: str) -> int:
        v = self.values.get(key)
        return 0 if v is None else int(np.isfinite(v).any(axis=1).sum())


@dataclass(frozen=True)
class CycleCurves:
    """Both sides' cycles and where they came from (``source``, in words)."""

    left: SideCurves
    right: SideCurves
    source: str
    notes: tuple[str, ...] = field(default_factory=tuple)

    def side(self, side: str) -> SideCurves:
        return self.left if side == "left" else self.right

    @property
    def n_cycles(self) -> int:
        return self.left.n_cycles + self.right.n_cycles


def _events(res: SessionResults, label: str, side: str) -> list[float]:
    return sorted(
        float(e.time)
        for e in res.summary.events or ()
        if e.label == label
        and str(e.context).lower() == side
        and e.time is not None
        and np.isfinite(e.time)
    )


def cycle_bounds(strikes: Sequence[float], offs: Sequence[float]) -> list[tuple[float, float, float]]:
    """(strike, next strike, foot off or NaN) of every complete cycle."""
    out = []
    for a, b in zip(strikes[:-1], strikes[1:]):
        if not 0.0 < b - a <= MAX_CYCLE_S:
            continue
        off = [t for t in offs if a < t < b]
        out.append((a, b, off[0] if off else float("nan")))
    return out


def _normalise(t: Array, y: Array, bounds: Sequence[tuple[float, float, float]]) -> Array:
    out = np.full((len(bounds), PERCENT.size), np.nan)
    for k, (a, b, _) in enumerate(bounds):
        if a < t[0] - 1e-9 or b > t[-1] + 1e-9:
            continue  # the cycle runs past the table (a trimmed trial)
        out[k] = np.interp(a + PERCENT / 100.0 * (b - a), t, y, left=np.nan, right=np.nan)
    return out


def curves_from_tables(res: SessionResults) -> CycleCurves | None:
    """The cycles of both legs from ``summary.events`` and the ``q`` and ``joint_torques``
    tables; None without a ``q`` table or a complete cycle."""
    if not res.has("q"):
        return None
    q = res.table("q")
    tau = res.table("joint_torques") if res.has("joint_torques") else None
    mass = res.summary.subject.mass_kg or 1.0
    sides = {}
    for side, sfx in (("left", "_l"), ("right", "_r")):
        bounds = cycle_bounds(_events(res, "Foot Strike", side), _events(res, "Foot Off", side))
        values: dict[str, Array] = {}
        for v in (*KINEMATICS, *KINETICS):
            if v.column is None or not bounds:
                continue
            col = v.column.format(s=sfx)
            if col not in q.columns:
                continue
            ang = q.column(col)
            if v.kind == "angle":
                y = v.sign * np.rad2deg(ang)
                t = q.time
            else:
                if tau is None or col not in tau.columns:
                    continue
                t = tau.time
                torque = tau.column(col)
                if v.kind == "moment":
                    y = v.sign * torque / mass
                else:
                    qa = np.interp(t, q.time, ang)
                    y = torque * np.gradient(qa, t) / mass if t.size > 1 else torque * np.nan
            values[v.key] = _normalise(t, y, bounds)
        starts = np.array([b[0] for b in bounds])
        ends = np.array([b[1] for b in bounds])
        offs = np.array([100.0 * (b[2] - b[0]) / (b[1] - b[0]) for b in bounds])
        sides[side] = SideCurves(side, values, starts, ends, offs)
    if not sides["left"].n_cycles and not sides["right"].n_cycles:
        return None
    return CycleCurves(sides["left"], sides["right"], "the gait events of the task trial")
