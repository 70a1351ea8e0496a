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

**The MVC reference is a measurement.** In each MVC trial the plateau is the window of
``plateau_s`` seconds (default 1 s) where the joint torque's magnitude is highest, and the
channel's level is its mean envelope over that window — the usual definition of the MVC
amplitude (Konrad 2005, *The ABC of EMG*, Noraxon, on MVC normalisation: the mean amplitude
of the highest 500–1000 ms of the plateau; Burden 2010, J Electromyogr Kinesiol 20:1023) —
with the window chosen on the torque: choosing it on the EMG (or taking the single highest
sample) selects the envelope's noise and biases every reference high (≈ +3 % with a 10 %
envelope noise). E_c is the highest level over the MVC trials. Its standard error comes
from the plateau's own variability: with x_t the envelope's n samples in the window,
γ_k their autocovariances and Γ_m = γ_2m + γ_2m+1 summed while positive (Geyer 1992, Stat
Sci 7:473, the initial positive sequence estimator)::

    SE(E_c)² = (−γ_0 + 2 Σ_m Γ_m) / n

One reference is shared by every row of the session, so the window jackknife never resamples
it: its error is added to each group's variance by the delta method with a one-standard-error
secant — the identification is repeated with E_c × (1 + SE_c/E_c), giving Δs_g,c, and::

    Var(ŝ_g) = Var_jackknife(ŝ_g) + Σ_c Δs_g,c²

(both intervals are widened by the same t-quantile). A reference given in the configuration
or taken as the session's peak has no such term (``reference_uncertainty`` in ``extra``).

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
    "mvc_plateau",
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
    configuration; ``"session_peak"`` — the peak over every pooled trial, no MVC recorded);
    ``standard_error`` (channel units) of an MVC plateau's mean (:func:`mvc_plateau`), NaN
    where none is known (None: none at all)."""

    channels: tuple[str, ...]
    value: Array
    source: tuple[str, ...]
    standard_error: Array | None = None

    def relative_error(self, channel: str) -> float:
        """SE/E of ``channel``'s reference (NaN when unknown)."""
        if self.standard_error is None:
            return float("nan")
        k = self.channels.index(channel)
        return float(self.standard_error[k] / self.value[k])

    def as_dict(self) -> dict[str, Any]:
        return {
            c: {"value": float(v), "source": s, "relative_error": _finite(self.relative_error(c))}
            for c, v, s in zip(self.channels, self.value, self.source)
        }


def _finite(x: float) -> float | None:
    return x if np.isfinite(x) else None


def mvc_plateau(
    envelopes: Array, effort: Array, rate_hz: float, window_s: float = 1.0
) -> tuple[Array, Array]:
    """The MVC levels of an MVC trial's envelopes ``(N, K)`` and their standard errors
    (module docstring): the mean of each channel over the ``window_s`` seconds where the
    ``effort`` ``(N,)`` (the joint torque's magnitude) is highest, and SE² = (−γ_0 + 2 Σ Γ_m)/n
    of its n samples (Geyer 1992, initial positive sequence). The window is chosen on the
    torque, not on the EMG: choosing it on the EMG would pick its noise's highest second and
    bias every reference high. A trial shorter than the window gives each channel's highest
    sample and NaN."""
    x = np.asarray(envelopes, dtype=float)
    tq = np.nan_to_num(np.asarray(effort, dtype=float), nan=-np.inf)
    n = round(window_s * rate_hz)
    k_ch = x.shape[1]
    if n < 4 or x.shape[0] < n:
        with np.errstate(invalid="ignore"):
            return np.nanmax(x, axis=0), np.full(k_ch, np.nan)
    c = np.concatenate([[0.0], np.cumsum(np.where(np.isfinite(tq), tq, -1e12))])
    i = int(np.argmax(c[n:] - c[:-n]))
    w = x[i : i + n]
    levels, errors = np.full(k_ch, np.nan), np.full(k_ch, np.nan)
    for j in range(k_ch):
        col = w[:, j][np.isfinite(w[:, j])]
        if col.size < 4:
            continue
        d = col - col.mean()
        gamma = np.correlate(d, d, mode="full")[col.size - 1 :] / col.size
        var = -gamma[0]
        for m in range(col.size // 2):
            pair = gamma[2 * m] + (gamma[2 * m + 1] if 2 * m + 1 < col.size else 0.0)
            if pair <= 0:
                break
            var += 2.0 * pair
        levels[j] = col.mean()
        errors[j] = np.sqrt(max(var, gamma[0]) / col.size)
    return levels, errors


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


def _channel_plateaus(
    trials: Sequence[PooledTrial], edge_s: float, plateau_s: float
) -> dict[str, tuple[float, float]]:
    best: dict[str, tuple[float, float]] = {}
    for tr in trials:
        env = np.asarray(tr.envelopes, dtype=float)
        k = min(round(edge_s * tr.rate_hz), max((env.shape[0] - 1) // 2, 0))
        sl = slice(k, env.shape[0] - k)
        effort = np.linalg.norm(np.nan_to_num(np.asarray(tr.tau, dtype=float)), axis=1)
        levels, errors = mvc_plateau(env[sl], effort[sl], tr.rate_hz, plateau_s)
        for j, c in enumerate(tr.channels):
            if np.isfinite(levels[j]) and levels[j] > best.get(c, (0.0, 0.0))[0]:
                best[c] = (float(levels[j]), float(errors[j]))
    return best


def session_emg_reference(
    trials: Sequence[PooledTrial],
    *,
    given: Mapping[str, float] | None = None,
    edge_s: float = 0.0,
    plateau_s: float | None = 1.0,
) -> EmgReference:
    """One reference per channel for the whole session (module docstring): per channel the
    highest of the MVC trials' plateau means (each over the ``plateau_s`` seconds of its
    highest torque), with its standard error (:func:`mvc_plateau`; None: their highest
    sample, no error) where any exist, else the peak over every trial
    (``session_peak``); ``given`` values (channel units) win. ``edge_s`` seconds at each end
    of every trial are ignored (filter edge transients)."""
    channels = list(dict.fromkeys(c for tr in trials for c in tr.channels))
    mvc = [tr for tr in trials if tr.kind == "mvc"]
    if plateau_s is None:
        from_mvc = {c: (v, float("nan")) for c, v in _channel_peaks(mvc, edge_s).items()}
    else:
        from_mvc = _channel_plateaus(mvc, edge_s, plateau_s)
    from_all = _channel_peaks(trials, edge_s)
    values, sources, errors = [], [], []
    for c in channels:
        se = float("nan")
        if given and c in given:
            v, s = float(given[c]), "given"
        elif c in from_mvc and from_mvc[c][0] > 0:
            (v, se), s = from_mvc[c], "mvc"
        else:
            v, s = from_all.get(c, float("nan")), "session_peak"
        if not (np.isfinite(v) and v > 0):
            raise IdentificationError(
                f"EMG channel {c!r}: no positive reference for the normalisation ({s}: {v})"
            )
        values.append(v)
        sources.append(s)
        errors.append(se)
    return EmgReference(tuple(channels), np.asarray(values), tuple(sources), np.asarray(errors))


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
    plateau_s: float | None = 1.0,
    reference_uncertainty: bool = True,
    **identifier: Any,
) -> StrengthProfile:
    """Strength factors of the EMG groups from every trial of a session together (module
    docstring).

    ``channels`` model muscle → EMG channel label (one group per channel, named by it);
    ``activation(e, rate_hz)`` turns a trial's normalised envelopes ``(N, K)`` into activations
    (default: :func:`msk.muscles.activation.first_order_activation`, Hayashibe et al. 2011,
    Eq. 8); ``mvc`` given references (channel units); ``reference`` the session's normalisation
    computed by the caller (e.g. from the raw recordings, :func:`msk.muscles.emg.mvc_peaks`),
    else :func:`session_emg_reference` of ``trials`` (MVC level over ``plateau_s``);
    ``reference_uncertainty`` adds the references' standard errors to the intervals (module
    docstring); ``identifier`` keyword arguments of :class:`msk.strength.StrengthIdentifier`
    (``n_bootstrap``, ``instrument``, …).

    The returned profile's ``extra`` holds ``normalisation`` (per channel: reference, source
    and relative error), ``reference_uncertainty`` (per group: the standard deviation the
    references add to its factor),
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
        session_emg_reference(trials, given=mvc, edge_s=edge_s, plateau_s=plateau_s)
        if reference is None
        else reference
    )
    absent = sorted(set(groups) - set(ref.channels))
    if absent:
        raise IdentificationError(f"the EMG reference has no value for channel(s) {absent}")
    n_mus = len(params.names)
    n_coords = len(coordinate_names)
    jacs, lens, vels, taus, wins, movs = [], [], [], [], [], []
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
        tau = np.asarray(tr.tau, dtype=float)
        if tau.shape != (tr.n_frames, n_coords):
            raise ShapeMismatchError(
                f"trial {tr.name!r}: tau must be (N, {n_coords}), got {tau.shape}"
            )
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
    ref_of = np.array([ref.value[ref.channels.index(c)] for c in groups])

    def activations(reference: Array) -> Array:
        """Every trial's muscle activations ``(rows, M)`` with the channels normalised by
        ``reference`` (in ``groups`` order). Only the negative undershoot is clipped: a
        hold's envelope fluctuates about its plateau mean, above 1 half of the time."""
        out = []
        for tr in trials:
            env = np.asarray(tr.envelopes, dtype=float)
            cols = [tr.channels.index(c) for c in groups]
            e = np.clip(np.nan_to_num(env[:, cols] / reference[None], nan=0.0), 0.0, None)
            a_ch = np.asarray(activation(e, float(tr.rate_hz)), dtype=float)[tr.used()]
            a = np.zeros((a_ch.shape[0], n_mus))
            for k, members in enumerate(groups.values()):
                for m in members:
                    a[:, params.names.index(m)] = a_ch[:, k]
            out.append(a)
        return np.concatenate(out)

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
    jac_all, tau_all = _concatenate_jacobians(jacs), np.concatenate(taus)

    def fit(est: StrengthIdentifier, reference: Array, intervals: bool = True) -> StrengthProfile:
        est.fit(
            jac_all, activations(reference), tau_all, state, windows=labels,
            coordinate_names=coordinate_names, movements=mov if stratified else None,
            intervals=intervals,
        )  # fmt: skip
        return est.profile_

    profile = fit(est, ref_of)
    rel = np.array([ref.relative_error(c) for c in groups])
    if reference_uncertainty and np.isfinite(rel).any():
        # the secant needs the factors alone: the repeated identification skips the jackknife
        # and the bootstrap (the same factors)
        profile = _with_reference_error(
            profile, rel, lambda r: fit(
                StrengthIdentifier({g: tuple(v) for g, v in groups.items()}, params,
                                   **identifier), r, intervals=False),
            ref_of, tuple(groups),
        )  # fmt: skip
    sources_used = [s for c, s in zip(ref.channels, ref.source) if c in groups]
    kind = "session_peak" if "session_peak" in sources_used else "mvc"
    extra = dict(profile.extra)
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
    return dataclasses.replace(profile, extra=extra)


def _with_reference_error(
    profile: StrengthProfile,
    rel: Array,
    refit: Callable[[Array], StrengthProfile],
    reference: Array,
    channels: tuple[str, ...],
) -> StrengthProfile:
    """``profile`` with each group's variance grown by Σ_c Δs_g,c², Δs_g,c the change of its
    factor when channel c's reference grows by one standard error (module docstring)."""
    f = profile.factors
    var_ref = np.zeros(f.size)
    for k in np.flatnonzero(np.isfinite(rel) & (rel > 0)):
        r = reference.copy()
        r[k] *= 1.0 + rel[k]
        var_ref += (refit(r).factors - f) ** 2
    sd_ref = np.sqrt(var_ref)
    se = profile.std_error
    with np.errstate(invalid="ignore", divide="ignore"):
        tq = np.where(se > 0, (profile.ci_cov_high - f) / se, np.nan)
    lo, hi = profile.bounds
    grow = tq * sd_ref
    ci_low = np.maximum(f - np.hypot(f - profile.ci_low, grow), lo)
    ci_high = np.minimum(f + np.hypot(profile.ci_high - f, grow), hi)
    se_tot = np.hypot(se, sd_ref)
    extra = dict(profile.extra)
    extra["reference_uncertainty"] = {
        "relative_error": {c: _finite(float(x)) for c, x in zip(channels, rel)},
        "factor_sd": {g: float(s) for g, s in zip(profile.group_names, sd_ref)},
        "method": "delta method, one-standard-error secant of each MVC reference",
    }
    return dataclasses.replace(
        profile, std_error=se_tot, ci_cov_low=f - tq * se_tot, ci_cov_high=f + tq * se_tot,
        ci_low=ci_low, ci_high=ci_high, extra=extra,
    )  # fmt: skip
