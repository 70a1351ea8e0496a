"""A session's trials pooled into one strength identification (Hayashibe et al. 2011, §V–VI).

Hayashibe, Venture, Ayusawa & Nakamura (2011) identify strength in three steps: the EMG of
every channel is normalised by the **MVC trials** (§VI.A: "MVC for the extension and flexion
in each joint"); the tasks that excite each group are chosen by the correlation of its torque
and EMG (§VI.C, the correlation gate of :class:`msk.strength.StrengthIdentifier`); the
regression of Eq. 16 is solved on the rows of all those trials together. Here:

**One normalisation for the session.** Trial i's envelope of channel c, e_i,c(t) in the
channel's units, is divided by one reference per channel, never by that trial's own peak::

    ê_i,c(t) = e_i,c(t) / E_c,   E_c = max_{i ∈ MVC} max_t e_i,c(t)      (MVC trials exist)
                                 E_c = max_{i ∈ pool} max_t e_i,c(t)     (otherwise: stated)

An explicit value (the lab's MVC in channel units) wins over both. Without MVC trials the
session peak is a *sub*-maximal reference: ê is too high by E_c^MVC / E_c^session, so the
EMG-driven force is too high and the factors come out **low** by about that ratio (a muscle
that never contracts fully looks weak); the profile records ``normalisation`` per channel so
that the report can say it. A per-trial peak would give each trial its own scale and make the
rows of different trials inconsistent — it is never used.

**Rows.** Each trial contributes its usable frames (``frames``) as rows of Eq. 16 with its own
joint torques — inverse dynamics of a task, or the joint torque of an isometric MVC (inverse
dynamics of the static posture on the plates, or a dynamometer's torque): τ = Σ_g s_g C_g + …
at the trial's posture, the antagonists' EMG entering as co-contraction like any other column.
Windows (the gating and resampling units) never straddle two trials: a task trial is cut into
round(T / ``window_s``) equal chunks of its used rows (default 0.5 s: half a gait cycle,
≈ 3 correlation times of a 6-Hz envelope) unless it
gives its own labels (cycles); an MVC
trial is one window (one repetition) unless labelled. ``movement`` names what a trial's windows
repeat (for the instrument and the stratified jackknife of the identifier).

**Per group.** Statuses are judged on each group's own rows (:func:`msk.strength.diagnose`):
the fit r² of the coordinates its muscles cross, not the session-wide mean.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from msk.exceptions import IdentificationError, ShapeMismatchError
from msk.muscles.hill import MuscleParameters, RigidTendonStateBlocks
from msk.strength.identification import StrengthIdentifier, StrengthProfile
from msk.timeseries import FrameSparse
from msk.units import Array

__all__ = [
    "EmgReference",
    "PooledTrial",
    "identify_pooled",
    "session_emg_reference",
]

#: the kinds of trial a pooled identification takes
TrialKind = Literal["task", "mvc"]


@dataclass(frozen=True)
class PooledTrial:
    """One trial's rows for :func:`identify_pooled`, every per-frame array on the trial's
    ``N`` frames (time axis 0, ``rate_hz``).

    ``envelopes`` ``(N, K)`` the linear EMG envelopes of ``channels`` in the **channel's units**
    (not normalised); ``jacobian`` ``(N, M, n)`` ∂l/∂θ (dense or
    :class:`msk.timeseries.FrameSparse`), ``lengths`` / ``velocities`` ``(N, M)`` the
    musculotendon lengths and lengthening velocities (m, m/s) in the parameters' muscle order;
    ``tau`` ``(N, n)`` the joint torques (N·m; NaN allowed outside ``frames``);
    ``frames`` the rows that enter the regression (default: all); ``windows`` one label per
    frame (cycles, repetitions) or None (module docstring); ``kind`` ``"task"`` or ``"mvc"``
    (an MVC trial's envelopes set the normalisation, and its torques enter the regression);
    ``movement`` what the windows repeat (default: the kind)."""

    name: str
    kind: TrialKind
    rate_hz: float
    channels: tuple[str, ...]
    envelopes: Array
    jacobian: Array | FrameSparse
    lengths: Array
    velocities: Array
    tau: Array
    frames: NDArray[np.int64] | None = None
    windows: NDArray[np.int64] | None = None
    movement: str | None = None

    @property
    def n_frames(self) -> int:
        return int(np.asarray(self.envelopes).shape[0])

    def used(self) -> NDArray[np.int64]:
        """The rows that enter the regression."""
        return (
            np.arange(self.n_frames, dtype=np.int64)
            if self.frames is None
            else np.asarray(self.frames, dtype=np.int64)
        )


@dataclass(frozen=True)
class EmgReference:
    """The session's EMG normalisation: per channel the reference ``value`` (channel units) and
    its ``source`` (``"mvc"`` — the MVC trials' peak; ``"given"`` — a value of the
    configuration; ``"session_peak"`` — the peak over every pooled trial, no MVC recorded)."""

    channels: tuple[str, ...]
    value: Array
    source: tuple[str, ...]

    def as_dict(self) -> dict[str, Any]:
        return {
            c: {"value": float(v), "source": s}
            for c, v, s in zip(self.channels, self.value, self.source)
        }


def _channel_peaks(trials: Sequence[PooledTrial], edge_s: float) -> dict[str, float]:
    peaks: dict[str, float] = {}
    for tr in trials:
        env = np.asarray(tr.envelopes, dtype=float)
        k = min(round(edge_s * tr.rate_hz), max((env.shape[0] - 1) // 2, 0))
        inner = env[k : env.shape[0] - k] if k else env
        for j, c in enumerate(tr.channels):
            col = inner[:, j]
            col = col[np.isfinite(col)]
            if col.size:
                peaks[c] = max(peaks.get(c, 0.0), float(col.max()))
    return peaks


def session_emg_reference(
    trials: Sequence[PooledTrial],
    *,
    given: Mapping[str, float] | None = None,
    edge_s: float = 0.0,
) -> EmgReference:
    """One reference per channel for the whole session (module docstring): the peak envelope
    over the MVC trials where any exist, else over every trial (``session_peak``); ``given``
    values (channel units) win. ``edge_s`` seconds at each end of every trial are ignored
    (filter edge transients)."""
    channels = list(dict.fromkeys(c for tr in trials for c in tr.channels))
    mvc = [tr for tr in trials if tr.kind == "mvc"]
    from_mvc = _channel_peaks(mvc, edge_s)
    from_all = _channel_peaks(trials, edge_s)
    values, sources = [], []
    for c in channels:
        if given and c in given:
            v, s = float(given[c]), "given"
        elif c in from_mvc and from_mvc[c] > 0:
            v, s = from_mvc[c], "mvc"
        else:
            v, s = from_all.get(c, float("nan")), "session_peak"
        if not (np.isfinite(v) and v > 0):
            raise IdentificationError(
                f"EMG channel {c!r}: no positive reference for the normalisation ({s}: {v})"
            )
        values.append(v)
        sources.append(s)
    return EmgReference(tuple(channels), np.asarray(values), tuple(sources))


def _default_windows(
    tr: PooledTrial, used: NDArray[np.int64], window_s: float
) -> NDArray[np.int64]:
    if tr.windows is not None:
        w = np.asarray(tr.windows, dtype=np.int64)
        if w.shape != (tr.n_frames,):
            raise ShapeMismatchError(
                f"trial {tr.name!r}: windows must have one label per frame ({tr.n_frames}), "
                f"got {w.shape}"
            )
        return np.unique(w[used], return_inverse=True)[1]
    if tr.kind == "mvc":
        return np.zeros(used.size, dtype=np.int64)
    # round(T / window_s) (≥ 1) equal chunks of the used rows, in time order: no remainder
    # window of a few frames
    n_w = max(1, round(used.size / (window_s * tr.rate_hz)))
    return (np.arange(used.size) * n_w // used.size).astype(np.int64)


def _jacobian_rows(jac: Array | FrameSparse, used: NDArray[np.int64]) -> Array | FrameSparse:
    if isinstance(jac, FrameSparse):
        return jac.take(used)
    return np.asarray(jac, dtype=float)[used]


def _concatenate_jacobians(parts: list[Array | FrameSparse]) -> Array | FrameSparse:
    if all(isinstance(p, FrameSparse) for p in parts):
        sparse = [p for p in parts if isinstance(p, FrameSparse)]
        trailing = sparse[0].trailing
        if any(p.trailing != trailing for p in sparse):
            raise ShapeMismatchError("the trials' Jacobians have different shapes")
        pos = np.unique(np.concatenate([p.positions for p in sparse]))
        vals = []
        for p in sparse:
            v = np.zeros((p.values.shape[0], pos.size))
            v[:, np.searchsorted(pos, p.positions)] = p.values
            vals.append(v)
        return FrameSparse(np.concatenate(vals), pos.astype(np.intp), trailing)
    return np.concatenate([np.asarray(p) for p in parts])


def identify_pooled(
    trials: Sequence[PooledTrial],
    channels: Mapping[str, str],
    params: MuscleParameters,
    *,
    coordinate_names: Sequence[str],
    activation: Callable[[Array, float], Array] | None = None,
    mvc: Mapping[str, float] | None = None,
    reference: EmgReference | None = None,
    window_s: float = 0.5,
    edge_s: float = 0.0,
    **identifier: Any,
) -> StrengthProfile:
    """Strength factors of the EMG groups from every trial of a session together (module
    docstring).

    ``channels`` model muscle → EMG channel label (one group per channel, named by it);
    ``activation(e, rate_hz)`` turns a trial's normalised envelopes ``(N, K)`` into activations
    (default: :func:`msk.muscles.activation.first_order_activation`, Hayashibe et al. 2011,
    Eq. 8); ``mvc`` given references (channel units); ``reference`` the session's normalisation
    computed by the caller (e.g. from the raw recordings, :func:`msk.muscles.emg.mvc_peaks`),
    else :func:`session_emg_reference` of ``trials``; ``identifier`` keyword arguments of
    :class:`msk.strength.StrengthIdentifier` (``n_bootstrap``, ``instrument``, …).

    The returned profile's ``extra`` holds ``normalisation`` (per channel: reference and source),
    ``normalisation_kind`` (``"mvc"`` or ``"session_peak"``), ``trials`` (per trial: kind, rows
    and windows) and the bias statement of a session-peak normalisation.
    """
    if not trials:
        raise IdentificationError("identify_pooled: no trial")
    names = [tr.name for tr in trials]
    if len(set(names)) != len(names):
        raise IdentificationError(f"identify_pooled: trial names repeat: {names}")
    if activation is None:
        from msk.muscles.activation import first_order_activation

        def activation(e: Array, rate_hz: float) -> Array:
            return first_order_activation(e, rate_hz=rate_hz)

    groups: dict[str, list[str]] = {}
    for m, c in channels.items():
        if m not in params.names:
            raise IdentificationError(f"identify_pooled: unknown muscle {m!r}")
        groups.setdefault(str(c), []).append(m)
    ref = (
        session_emg_reference(trials, given=mvc, edge_s=edge_s) if reference is None else reference
    )
    absent = sorted(set(groups) - set(ref.channels))
    if absent:
        raise IdentificationError(f"the EMG reference has no value for channel(s) {absent}")
    n_mus = len(params.names)
    n_coords = len(coordinate_names)
    acts, jacs, lens, vels, taus, wins, movs = [], [], [], [], [], [], []
    record: dict[str, Any] = {}
    offset = 0
    movement_names: list[str] = []
    for tr in trials:
        if tr.kind not in ("task", "mvc"):
            raise IdentificationError(f"trial {tr.name!r}: kind must be 'task' or 'mvc'")
        env = np.asarray(tr.envelopes, dtype=float)
        if env.shape != (tr.n_frames, len(tr.channels)):
            raise ShapeMismatchError(
                f"trial {tr.name!r}: envelopes must be (N, {len(tr.channels)}), got {env.shape}"
            )
        missing = sorted(set(groups) - set(tr.channels))
        if missing:
            raise IdentificationError(f"trial {tr.name!r} has no envelope of channel(s) {missing}")
        used = tr.used()
        if used.size == 0:
            raise IdentificationError(f"trial {tr.name!r}: no usable frame")
        e = np.empty((env.shape[0], len(groups)))
        for k, c in enumerate(groups):
            e[:, k] = env[:, tr.channels.index(c)] / ref.value[ref.channels.index(c)]
        e = np.clip(np.nan_to_num(e, nan=0.0), 0.0, 1.0)
        a_ch = np.asarray(activation(e, float(tr.rate_hz)), dtype=float)[used]
        a = np.zeros((used.size, n_mus))
        for k, members in enumerate(groups.values()):
            for m in members:
                a[:, params.names.index(m)] = a_ch[:, k]
        tau = np.asarray(tr.tau, dtype=float)
        if tau.shape != (tr.n_frames, n_coords):
            raise ShapeMismatchError(
                f"trial {tr.name!r}: tau must be (N, {n_coords}), got {tau.shape}"
            )
        acts.append(a)
        jacs.append(_jacobian_rows(tr.jacobian, used))
        lens.append(np.asarray(tr.lengths, dtype=float)[used])
        vels.append(np.asarray(tr.velocities, dtype=float)[used])
        taus.append(tau[used])
        w = _default_windows(tr, used, window_s)
        wins.append(w + offset)
        offset += int(w.max()) + 1
        mv = tr.movement or tr.kind
        if mv not in movement_names:
            movement_names.append(mv)
        movs.append(np.full(used.size, movement_names.index(mv), dtype=np.int64))
        record[tr.name] = {
            "kind": tr.kind,
            "rows": int(used.size),
            "windows": int(w.max()) + 1,
            "movement": mv,
        }
    lengths = np.concatenate(lens)
    state = RigidTendonStateBlocks(params, lengths, np.concatenate(vels))
    est = StrengthIdentifier({g: tuple(v) for g, v in groups.items()}, params, **identifier)
    labels, mov = np.concatenate(wins), np.concatenate(movs)
    # a stratum of one window adds nothing to the stratified jackknife's variance: with any
    # movement of fewer than 2 windows the windows are taken as one stratum (CR3) — but the
    # instrument never mixes movements (the identifier then asks for ≥ 3 windows of each)
    per_mov = [np.unique(labels[mov == k]).size for k in range(len(movement_names))]
    iv = identifier.get("instrument", "none") == "phase_average"
    stratified = len(movement_names) > 1 and (iv or min(per_mov) >= 2)
    est.fit(
        _concatenate_jacobians(jacs),
        np.concatenate(acts),
        np.concatenate(taus),
        state,
        windows=labels,
        coordinate_names=coordinate_names,
        movements=mov if stratified else None,
    )
    sources_used = [s for c, s in zip(ref.channels, ref.source) if c in groups]
    kind = "session_peak" if "session_peak" in sources_used else "mvc"
    extra = dict(est.profile_.extra)
    extra.update(
        normalisation=ref.as_dict(),
        normalisation_kind=kind,
        trials=record,
        movements=movement_names,
        stratified_by_movement=stratified,
    )
    if any(s == "session_peak" and c in groups for c, s in zip(ref.channels, ref.source)):
        peak = [c for c, s in zip(ref.channels, ref.source) if s == "session_peak" and c in groups]
        extra["normalisation_bias"] = (
            f"channel(s) {', '.join(peak)} normalised to the session's peak envelope (no MVC "
            "trial): the peak of submaximal trials is below the MVC, so activations are too "
            "high and those groups' factors too LOW by about the ratio of the session peak to "
            "the true MVC"
        )
    return dataclasses.replace(est.profile_, extra=extra)
