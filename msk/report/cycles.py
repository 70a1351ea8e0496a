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

import itertools
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from msk.exceptions import MskError
from msk.gait.cycles import GaitCycles
from msk.results.folder import SessionResults, pooled_gait
from msk.units import Array

__all__ = [
    "KINEMATICS",
    "KINETICS",
    "CycleCurves",
    "SideCurves",
    "Variable",
    "curves_from_gait",
    "curves_from_tables",
    "pooled_curves",
]

PERCENT = np.linspace(0.0, 100.0, 101)
#: two strikes of one foot farther apart than this are not one cycle (a gap in the events)
MAX_CYCLE_S = 2.5


@dataclass(frozen=True)
class Variable:
    """A curve of the grids: ``key`` the variable's name in :mod:`msk.gait.variables` (units in
    the name; the normative bands use the same names), its title and unit; ``stems`` the model
    coordinates it is computed from without :mod:`msk.gait`'s tables (``{s}`` the side suffix;
    (stem, sign on the right, sign on the left)) and ``kind`` ``angle`` (rad → deg), ``moment``
    (N·m → N·m/kg) or ``power`` (Σ τ θ̇ over the stems, W/kg)."""

    key: str
    title: str
    unit: str
    kind: str = "angle"
    stems: tuple[tuple[str, float, float], ...] = ()


def _v(key: str, title: str, unit: str, kind: str, *stems: tuple[str, float, float]) -> Variable:
    return Variable(key, title, unit, kind, tuple(stems))


#: the kinematics grid (columns: sagittal, frontal, transverse; rows: pelvis, hip, knee, ankle
#: and foot), Plug-in Gait conventions (:mod:`msk.gait.variables`); None: an empty cell
KINEMATICS: tuple[Variable | None, ...] = (
    _v("pelvis_tilt_deg", "Pelvis tilt (anterior +)", "deg", "angle", ("pelvis_tilt", -1, -1)),
    _v("pelvis_obliquity_deg", "Pelvis obliquity (up +)", "deg", "angle", ("pelvis_list", -1, 1)),
    _v(
        "pelvis_rotation_deg",
        "Pelvis rotation (forward +)",
        "deg",
        "angle",
        ("pelvis_rotation", 1, -1),
    ),
    _v("hip_flexion_deg", "Hip flexion", "deg", "angle", ("hip_flexion{s}", 1, 1)),
    _v("hip_adduction_deg", "Hip adduction", "deg", "angle", ("hip_adduction{s}", 1, 1)),
    _v("hip_rotation_deg", "Hip internal rotation", "deg", "angle", ("hip_rotation{s}", 1, 1)),
    _v("knee_flexion_deg", "Knee flexion", "deg", "angle", ("knee_angle{s}", -1, -1)),
    _v("knee_adduction_deg", "Knee varus (adduction)", "deg", "angle", ("knee_adduction{s}", 1, 1)),
    _v("knee_rotation_deg", "Knee internal rotation", "deg", "angle", ("knee_rotation{s}", 1, 1)),
    _v("ankle_dorsiflexion_deg", "Ankle dorsiflexion", "deg", "angle", ("ankle_angle{s}", 1, 1)),
    None,
    _v("foot_progression_deg", "Foot progression (internal +)", "deg", "angle"),
)
#: the kinetics grid (columns: hip, knee, ankle; rows: sagittal moment, frontal moment, power):
#: internal moments but the external knee adduction moment, as Plug-in Gait reports them
KINETICS: tuple[Variable | None, ...] = (
    _v(
        "hip_extension_moment_nm_kg",
        "Hip extension moment",
        "N·m/kg",
        "moment",
        ("hip_flexion{s}", -1, -1),
    ),
    _v(
        "knee_extension_moment_nm_kg",
        "Knee extension moment",
        "N·m/kg",
        "moment",
        ("knee_angle{s}", 1, 1),
    ),
    _v(
        "ankle_plantarflexion_moment_nm_kg",
        "Ankle plantarflexion moment",
        "N·m/kg",
        "moment",
        ("ankle_angle{s}", -1, -1),
    ),
    _v(
        "hip_abduction_moment_nm_kg",
        "Hip abduction moment",
        "N·m/kg",
        "moment",
        ("hip_adduction{s}", -1, -1),
    ),
    _v("knee_adduction_moment_nm_kg", "Knee adduction moment (external)", "N·m/kg", "moment"),
    None,
    _v(
        "hip_power_w_kg",
        "Hip power",
        "W/kg",
        "power",
        ("hip_flexion{s}", 1, 1),
        ("hip_adduction{s}", 1, 1),
        ("hip_rotation{s}", 1, 1),
    ),
    _v("knee_power_w_kg", "Knee power", "W/kg", "power", ("knee_angle{s}", 1, 1)),
    _v(
        "ankle_power_w_kg",
        "Ankle power",
        "W/kg",
        "power",
        ("ankle_angle{s}", 1, 1),
        ("subtalar_angle{s}", 1, 1),
    ),
)


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


def cycle_bounds(
    strikes: Sequence[float], offs: Sequence[float]
) -> list[tuple[float, float, float]]:
    """(strike, next strike, foot off or NaN) of every complete cycle."""
    out = []
    for a, b in itertools.pairwise(strikes):
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


def _series(res: SessionResults, v: Variable, sfx: str, right: bool) -> tuple[Array, Array] | None:
    """(time, values) of ``v`` on one side from the ``q`` and ``joint_torques`` tables."""
    q = res.table("q")
    tau = res.table("joint_torques") if res.has("joint_torques") else None
    mass = res.summary.subject.mass_kg or 1.0
    cols = [(stem.format(s=sfx), sr if right else sl) for stem, sr, sl in v.stems]
    if not cols or any(c not in q.columns for c, _ in cols):
        return None
    if v.kind == "angle":
        (c, sign), *_ = cols
        return q.time, sign * np.rad2deg(q.column(c))
    if tau is None or any(c not in tau.columns for c, _ in cols):
        return None
    t = tau.time
    if v.kind == "moment":
        (c, sign), *_ = cols
        return t, sign * tau.column(c) / mass
    if t.size < 2:
        return None
    power = np.zeros(t.size)
    for c, _ in cols:
        qa = np.interp(t, q.time, q.column(c))
        power = power + tau.column(c) * np.gradient(qa, t)
    return t, power / mass


def curves_from_tables(res: SessionResults) -> CycleCurves | None:
    """The cycles of both legs: :mod:`msk.gait`'s (``tables/gait_cycles_<side>``) when the
    folder has them, else from ``summary.events`` and the ``q`` and ``joint_torques`` tables
    (the coordinate-based variables only); None without a complete cycle."""
    try:
        cycles = res.gait_cycles()
    except (MskError, ValueError):
        cycles = None  # a malformed gait table: the cycles from the events
    if cycles is not None:
        return curves_from_gait(cycles)
    return _curves_from_events(res)


def _curves_from_events(res: SessionResults) -> CycleCurves | None:
    if not res.has("q"):
        return None
    sides = {}
    for side, sfx in (("left", "_l"), ("right", "_r")):
        bounds = cycle_bounds(_events(res, "Foot Strike", side), _events(res, "Foot Off", side))
        values: dict[str, Array] = {}
        for v in (*KINEMATICS, *KINETICS):
            if v is None or not bounds:
                continue
            series = _series(res, v, sfx, side == "right")
            if series is not None:
                values[v.key] = _normalise(*series, bounds)
        starts = np.array([b[0] for b in bounds])
        ends = np.array([b[1] for b in bounds])
        offs = np.array([100.0 * (b[2] - b[0]) / (b[1] - b[0]) for b in bounds])
        sides[side] = SideCurves(side, values, starts, ends, offs)
    if not sides["left"].n_cycles and not sides["right"].n_cycles:
        return None
    return CycleCurves(sides["left"], sides["right"], "the gait events of the task trial")


def curves_from_gait(cycles: GaitCycles) -> CycleCurves | None:
    """:class:`msk.gait.cycles.GaitCycles` as the report's curves."""
    sides = {}
    for side in ("left", "right"):
        sc = cycles.side(side)
        values = {name: np.asarray(sc.values)[:, :, j] for j, name in enumerate(cycles.variables)}
        sides[side] = SideCurves(
            side,
            values,
            np.asarray(sc.start_s, float),
            np.asarray(sc.end_s, float),
            np.asarray(sc.foot_off_pct, float),
        )
    if not sides["left"].n_cycles and not sides["right"].n_cycles:
        return None
    return CycleCurves(
        sides["left"], sides["right"], "msk.gait (every task trial's cycles)", tuple(cycles.notes)
    )


def pooled_curves(trials: Sequence[SessionResults]) -> CycleCurves | None:
    """Every cycle of every task trial in ``trials``, pooled per side: :mod:`msk.gait`'s cycles
    (:func:`msk.results.folder.pooled_gait`) where the folders have them, else those of
    :func:`curves_from_tables` of the first trial. A malformed gait table (a received folder)
    falls back the same way."""
    try:
        cycles, _ = pooled_gait(trials)
    except (MskError, ValueError):
        cycles = None
    if cycles is not None:
        pooled = curves_from_gait(cycles)
        if pooled is not None:
            return pooled
    parts = []
    for res in trials:
        try:
            part = _curves_from_events(res)
        except (MskError, ValueError):
            part = None
        if part is not None:
            parts.append(part)
    return _merge(parts) if parts else None


def _merge(parts: Sequence[CycleCurves]) -> CycleCurves:
    """The cycles of ``parts`` (several trials) side by side."""
    if len(parts) == 1:
        return parts[0]
    sides = {}
    for side in ("left", "right"):
        ps = [p.side(side) for p in parts]
        keys = {k for p in ps for k in p.values}
        values = {}
        for k in keys:
            blocks = [p.values.get(k, np.full((p.n_cycles, PERCENT.size), np.nan)) for p in ps]
            values[k] = np.concatenate(blocks, axis=0)
        sides[side] = SideCurves(
            side,
            values,
            np.concatenate([p.start_s for p in ps]),
            np.concatenate([p.end_s for p in ps]),
            np.concatenate([p.foot_off_pct for p in ps]),
        )
    return CycleCurves(sides["left"], sides["right"], f"the gait events of {len(parts)} trials")
