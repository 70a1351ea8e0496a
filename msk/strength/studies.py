"""Studies with identified strengths: W_emg stability (Hayashibe et al. 2011, Table I) and
comparison tables of generic vs identified parameters (the EMG-driven vs OpenSim thesis, Tables 4.1,
4.5–4.7).

All metric primitives come from :mod:`msk.metrics` (r², RMS, NRMSD, trapezoidal area ratio, peak
difference); this module only arranges them into frozen tables.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from msk import metrics as compare
from msk.exceptions import ShapeMismatchError
from msk.optimization import EMGWeightSweep, emg_weight_sweep
from msk.units import Array

__all__ = [
    "TABLE_I_W_EMG",
    "MetricTable",
    "WEmgStability",
    "area_ratio_table",
    "moment_fit_table",
    "net_force_table",
    "net_joint_force",
    "w_emg_stability",
]

#: The W_emg values of Hayashibe et al. 2011, Table I.
TABLE_I_W_EMG: tuple[float, ...] = (1.0, 0.5, 0.1, 0.05, 0.01, 0.005, 0.001)


# ---------------------------------------------------------------------------------------------
# W_emg stability
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class WEmgStability:
    """The W_emg sweep with generic and with identified F_iso (Hayashibe et al. 2011, Table I).

    ``max_force_generic`` / ``max_force_identified`` ``(W, M)``: maximal estimated force of each
    muscle over the frames, per W_emg; ``torque_error_*`` ``(W,)`` RMS of τ − R f (N·m);
    ``spread_*`` ``(M,)``: (max − min)/mean over W_emg of the maximal force (0 = stable);
    ``sweep_*`` the full :class:`msk.optimization.EMGWeightSweep` results.
    """

    w_emg: Array
    muscle_names: tuple[str, ...]
    max_force_generic: Array
    max_force_identified: Array
    torque_error_generic: Array
    torque_error_identified: Array
    spread_generic: Array
    spread_identified: Array
    sweep_generic: EMGWeightSweep
    sweep_identified: EMGWeightSweep

    def table(self, muscle: str) -> str:
        """Plain-text analogue of Hayashibe et al. 2011, Table I for one muscle."""
        i = self.muscle_names.index(muscle)
        lines = [
            f"{'W_emg':>8} | {'τ err (id)':>10} {'max f (id)':>11} | "
            f"{'τ err (gen)':>11} {'max f (gen)':>12}"
        ]
        for w in range(self.w_emg.size):
            lines.append(
                f"{self.w_emg[w]:>8.3g} | {self.torque_error_identified[w]:>10.3g} "
                f"{self.max_force_identified[w, i]:>11.0f} | {self.torque_error_generic[w]:>11.3g}"
                f" {self.max_force_generic[w, i]:>12.0f}"
            )
        lines.append(
            f"spread of max force over W_emg: identified {self.spread_identified[i]:.3f}, "
            f"generic {self.spread_generic[i]:.3f}"
        )
        return "\n".join(lines)


def _spread(max_force: Array) -> Array:
    mean = max_force.mean(axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(mean > 0, np.ptp(max_force, axis=0) / mean, np.nan)


def w_emg_stability(
    jacobian: ArrayLike,
    tau: ArrayLike,
    unit_reference: ArrayLike,
    measured: ArrayLike,
    f_iso_generic: ArrayLike,
    f_iso_identified: ArrayLike,
    *,
    w_emgs: Sequence[float] = TABLE_I_W_EMG,
    muscle_names: Sequence[str] | None = None,
    coordinate_names: Sequence[str] | None = None,
) -> WEmgStability:
    """Run the EMG-weighted QP sweep (Hayashibe et al. 2011, Eq. 17–18, :func:`msk.optimization.
    emg_weight_sweep`) with the EMG-based reference force ``f* = a f_l f_v F_iso`` (Eq. 9) built
    once from generic and once from identified F_iso.

    ``unit_reference`` ``(N, M)`` is ``a f_l f_v`` (reference force per newton of F_iso, e.g.
    ``activation * state.max_active_force_along_tendon / F_iso``); ``measured`` the muscles with
    EMG. The upper force bound is F_iso (generic or identified, respectively).
    Hayashibe et al. 2011, §VI.C reports that the maximal force varies much less with W_emg after
    identification.
    """
    ur = np.asarray(unit_reference, dtype=float)
    fg = np.asarray(f_iso_generic, dtype=float)
    fi = np.asarray(f_iso_identified, dtype=float)
    if ur.ndim != 2 or fg.shape != (ur.shape[1],) or fi.shape != fg.shape:
        raise ShapeMismatchError(
            f"unit_reference {ur.shape}, f_iso_generic {fg.shape}, f_iso_identified {fi.shape}: "
            "need (N, M), (M,), (M,)"
        )
    n = ur.shape[0]
    sweeps = []
    for f_iso in (fg, fi):
        sweeps.append(
            emg_weight_sweep(
                jacobian,
                tau,
                f_ref=ur * f_iso[None],
                measured=measured,
                w_emgs=w_emgs,
                f_max=np.broadcast_to(f_iso, (n, f_iso.size)),
                muscle_names=muscle_names,
                coordinate_names=coordinate_names,
            )
        )
    sg, si = sweeps
    return WEmgStability(
        w_emg=np.asarray(sg.w_emg, dtype=float),
        muscle_names=sg.muscle_names,
        max_force_generic=sg.max_force,
        max_force_identified=si.max_force,
        torque_error_generic=sg.torque_error_rms,
        torque_error_identified=si.torque_error_rms,
        spread_generic=_spread(sg.max_force),
        spread_identified=_spread(si.max_force),
        sweep_generic=sg,
        sweep_identified=si,
    )


# ---------------------------------------------------------------------------------------------
# comparison tables
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class MetricTable:
    """A small frozen table: ``values[i, j]`` for row ``row_names[i]``, column
    ``column_names[j]``; ``title`` says what it is (and cites the seed table)."""

    title: str
    row_names: tuple[str, ...]
    column_names: tuple[str, ...]
    values: Array

    def get(self, row: str, column: str) -> float:
        return float(self.values[self.row_names.index(row), self.column_names.index(column)])

    def to_text(self, fmt: str = "{:.3f}") -> str:
        w = max([len(r) for r in self.row_names] + [6])
        cw = [max(len(c), 9) for c in self.column_names]
        head = " " * w + " " + " ".join(f"{c:>{n}}" for c, n in zip(self.column_names, cw))
        lines = [self.title, head]
        for i, r in enumerate(self.row_names):
            cells = " ".join(f"{fmt.format(v):>{n}}" for v, n in zip(self.values[i], cw))
            lines.append(f"{r:<{w}} {cells}")
        return "\n".join(lines)


def _series(series: Mapping[str, ArrayLike], names: Sequence[str]) -> dict[str, Array]:
    out = {}
    shape = None
    for k, v in series.items():
        a = np.asarray(v, dtype=float)
        if a.ndim != 2 or a.shape[1] != len(names):
            raise ShapeMismatchError(f"series {k!r} must be (N, {len(names)}), got {a.shape}")
        if shape is not None and a.shape != shape:
            raise ShapeMismatchError(f"series {k!r} has shape {a.shape}, others {shape}")
        shape = a.shape
        out[k] = a
    return out


def area_ratio_table(
    series: Mapping[str, ArrayLike],
    pairs: Sequence[tuple[str, str]],
    muscle_names: Sequence[str],
    *,
    time: ArrayLike | None = None,
    title: str = (
        "area-under-curve ratios (trapezoidal rule, the EMG-driven vs OpenSim thesis Tables "
        "4.5-4.6)"
    ),
) -> MetricTable:
    """Per-muscle ratio of trapezoidal areas ``∫a/∫b`` for each pair ``(a, b)`` of named series
    ``(N, M)`` (activations → Table 4.5, forces → Table 4.6), via :func:`msk.metrics.area_ratio`.
    Columns are named ``"a/b"``."""
    s = _series(series, muscle_names)
    cols = []
    for a, b in pairs:
        if a not in s or b not in s:
            raise ShapeMismatchError(f"unknown series in pair {(a, b)}; have {sorted(s)}")
        cols.append(np.atleast_1d(compare.area_ratio(s[a], s[b], t=time)))
    return MetricTable(
        title, tuple(muscle_names), tuple(f"{a}/{b}" for a, b in pairs), np.column_stack(cols)
    )


def net_joint_force(
    forces: ArrayLike,
    muscle_names: Sequence[str],
    positive: Sequence[str],
    negative: Sequence[str],
) -> Array:
    """Net joint force ``Σ_{positive} F − Σ_{negative} F`` ``(N,)`` (the EMG-driven vs OpenSim
    thesis, §3.4: net knee force = extensors − flexors, net ankle force = plantar flexors −
    dorsiflexors)."""
    f = np.asarray(forces, dtype=float)
    names = list(muscle_names)
    if f.ndim != 2 or f.shape[1] != len(names):
        raise ShapeMismatchError(f"forces must be (N, {len(names)}), got {f.shape}")
    for m in (*positive, *negative):
        if m not in names:
            raise ShapeMismatchError(f"unknown muscle {m!r} in the net-force definition")
    pos = f[:, [names.index(m) for m in positive]].sum(axis=1)
    neg = f[:, [names.index(m) for m in negative]].sum(axis=1) if negative else 0.0
    return pos - neg


def net_force_table(
    net_forces: Mapping[str, ArrayLike],
    pairs: Sequence[tuple[str, str]],
    *,
    title: str = "net joint force comparison (the EMG-driven vs OpenSim thesis Table 4.7)",
) -> MetricTable:
    """For each pair ``(a, b)`` of net-force series ``(N,)``: r², RMS (N), RMS normalised to the
    peak-to-peak range of ``a`` and the difference in peak ``max a − max b`` (N) — the columns of
    the EMG-driven vs OpenSim thesis, Table 4.7."""
    s = {k: np.asarray(v, dtype=float) for k, v in net_forces.items()}
    rows = []
    for a, b in pairs:
        if a not in s or b not in s:
            raise ShapeMismatchError(f"unknown series in pair {(a, b)}; have {sorted(s)}")
        x, y = s[a], s[b]
        rows.append(
            [
                float(compare.r2(x, y)),
                float(compare.rms(x, y)),
                float(compare.nrmsd(x, y)) / 100.0,
                float(compare.peak_difference(x, y, mode="max")),
            ]
        )
    return MetricTable(
        title,
        tuple(f"{a}/{b}" for a, b in pairs),
        ("r2", "rms_N", "nrms", "peak_diff_N"),
        np.array(rows),
    )


def moment_fit_table(
    measured: ArrayLike,
    predicted: ArrayLike,
    coordinate_names: Sequence[str],
    *,
    title: str = "joint-moment fit (the EMG-driven vs OpenSim thesis Table 4.1)",
) -> MetricTable:
    """r², RMS (N·m) and peak-to-peak-normalised RMS of predicted vs inverse-dynamics moments
    ``(N, n)``, one row per coordinate (the EMG-driven vs OpenSim thesis, Table 4.1)."""
    m = np.asarray(measured, dtype=float)
    p = np.asarray(predicted, dtype=float)
    if m.ndim != 2 or m.shape != p.shape or m.shape[1] != len(coordinate_names):
        raise ShapeMismatchError(
            f"measured {m.shape} and predicted {p.shape} must be (N, {len(coordinate_names)})"
        )
    vals = np.column_stack(
        [
            np.atleast_1d(compare.r2(m, p)),
            np.atleast_1d(compare.rms(m, p)),
            np.atleast_1d(compare.nrmsd(m, p)) / 100.0,
        ]
    )
    return MetricTable(title, tuple(coordinate_names), ("r2", "rms_Nm", "nrms"), vals)
