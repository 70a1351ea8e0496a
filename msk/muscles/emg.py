"""EMG processing: raw analog channels → normalised linear envelopes per muscle.

Pipeline (the EMG-driven vs OpenSim thesis, §2.2.1 and §3.1.4; Hayashibe et al. 2011, §IV), per
channel::

    x → high-pass (zero-lag Butterworth, default 30 Hz; removes offset and movement artefact)
      → full-wave rectification |·|
      → low-pass (zero-lag Butterworth, default 6 Hz) = linear envelope
      → e(t) = envelope / MVC, clipped to [0, 1]
      → electromechanical delay: e_d(t) = e(t − d)

MVC is the peak of the envelope of the MVC trials, processed with the same filters (one peak per
channel over all MVC trials together, as in the EMG-driven vs OpenSim thesis, §3.1.4). Without an
MVC for a channel, the session's own envelope peak is used and a warning is *recorded in the result*
(``normalisation_source == "session_peak"``, ``warnings``), because the activation is then relative
(it always reaches 1). Muscles without an electrode take the mean envelope of named synergists
(e.g. vastus intermedius from vastus medialis and lateralis, the EMG-driven vs OpenSim thesis,
§3.2.1).

Quality checks (figures are reported for every channel in :class:`ChannelQuality`):

* **flat** (dead, unplugged or unused channel): the high-passed RMS is below ``flat_rms_lsb``
  quantisation steps, or below ``flat_rel_rms`` × the median RMS of the channels processed
  together (needs ≥ 3 channels), or the envelope is not modulated: its 99th/10th percentile ratio
  (inner part, filter edges excluded) is below ``flat_modulation`` (stationary noise gives
  ≈ 1.2–1.5, EMG of a muscle that works during the trial gives > 3). A channel whose envelope
  repeats with the gait cycle is not flat by the quantisation or the modulation test: a muscle
  that bursts once per stride over a high noise floor (surface EMG of a small or deep muscle,
  a low amplifier gain) can have a 99th/10th percentile ratio under ``flat_modulation`` and an
  RMS of a few quantisation steps, yet its envelope, shifted by one stride, matches itself —
  stationary noise's does not. The test is the envelope's autocorrelation (Pearson r between
  e(t) and e(t + τ) over their overlap) at its best lag τ in :data:`CYCLE_LAG_S` (a stride of
  running to slow walking), with at least two such lags in the record: r ≥
  ``flat_cycle_correlation`` (0.6: the stride-to-stride repeatability of healthy gait EMG
  envelopes, coefficients of multiple correlation 0.6–0.9, Kadaba MP et al. 1989, J Orthop Res
  7:849–860; white noise through the 6 Hz envelope filter decorrelates within 0.1 s) keeps
  the channel (:attr:`ChannelQuality.cycle_correlation`, :attr:`ChannelQuality.cycle_period_s`).
* **pre-processed envelope** (:func:`envelope_channel`): an amplifier's rectified and
  smoothed (RMS or linear-envelope) output stored in place of the raw EMG: no negative sample,
  the content above the high-pass at the quantisation floor (≤ ``floor_lsb`` steps), but a
  signal that moves below it (its low-passed standard deviation ≥ ``moving_lsb`` steps). The
  high-pass would remove it (it looks flat); it is used as its own envelope, low-passed only,
  and said so by the caller.
* **saturated** (clipped amplifier or ADC): at least ``clip_min_samples`` samples (and at least
  ``clip_fraction`` of the trial) sit within half a quantisation step of the channel's extreme
  value, or reach ``saturation_level`` when the range is known.
* **faulty samples** (a glitch: 1e20, inf, NaN, a transient far beyond the channel's range),
  found on the raw channel before any filter (:mod:`msk.muscles.emg_faults`): isolated ones
  are interpolated, a channel with a longer run is excluded (NaN, whatever ``bad_channel``
  says); both are listed in :attr:`EmgEnvelopes.sample_faults` and the warnings. MVC trials
  are repaired the same way (an excluded channel gives no MVC).

By default a flat channel's envelope is set to NaN (``bad_channel="nan"``) so that it cannot be
mistaken for activity; ``"keep"`` keeps it, ``"raise"`` raises :class:`EmgError`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Literal, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import EmgError, MissingDataError
from msk.muscles.emg_faults import SampleFaults, repair_sample_faults
from msk.signal import filtfilt_butter, resample_to
from msk.timeseries import FrameAxis
from msk.units import Array

if TYPE_CHECKING:
    from msk.analogs import StoredAnalogs

__all__ = [
    "CYCLE_LAG_S",
    "RAJAGOPAL_STEMS",
    "ChannelQuality",
    "EmgActivations",
    "EmgEnvelopes",
    "EnvelopeChannel",
    "NormalisationSource",
    "channel_quality",
    "cycle_correlation",
    "emg_activations",
    "envelope_channel",
    "envelopes_from_trial",
    "linear_envelope",
    "missing_channels",
    "mvc_peaks",
    "process_emg",
    "suggest_channels",
    "unknown_muscles",
]

NormalisationSource = Literal["mvc", "session_peak"]

#: lags (s) over which an envelope is looked for its gait-cycle repetition: a stride of running
#: (~0.6–0.8 s) to slow or pathological walking (~2 s; healthy walking 0.9–1.4 s)
CYCLE_LAG_S = (0.5, 2.0)
#: rate (Hz) the envelope is sampled at for the autocorrelation (it holds nothing above its
#: low-pass cut-off)
_CYCLE_RATE_HZ = 50.0


@dataclass(frozen=True)
class ChannelQuality:
    """Per-channel quality figures (arrays of length C, in the order of ``labels``)."""

    labels: tuple[str, ...]
    flat: NDArray[np.bool_]
    saturated: NDArray[np.bool_]
    rms: Array  #: RMS after the high-pass filter, input units
    lsb: Array  #: quantisation step (smallest difference between distinct values), input units
    rms_lsb: Array  #: rms / lsb
    relative_rms: Array  #: rms / median rms of the channels processed together (NaN if < 3)
    modulation: Array  #: 99th / 10th percentile of the envelope
    clipped_fraction: Array  #: fraction of samples at an extreme (saturation) value
    #: the envelope's autocorrelation at its best lag in :data:`CYCLE_LAG_S` (NaN: the record
    #: holds fewer than two such lags, or the envelope is constant)
    cycle_correlation: Array = dataclasses.field(default_factory=lambda: np.empty(0))
    #: that lag, s (NaN as above)
    cycle_period_s: Array = dataclasses.field(default_factory=lambda: np.empty(0))

    def summary(self) -> list[str]:
        """One line per flagged channel, with the figures that flagged it."""
        lines = []
        for i, lab in enumerate(self.labels):
            if self.flat[i]:
                lines.append(
                    f"channel {lab!r} is flat: rms {self.rms[i]:.3g} ({self.rms_lsb[i]:.1f} LSB, "
                    f"{self.relative_rms[i]:.3f} of the median channel), "
                    f"envelope modulation {self.modulation[i]:.2f}"
                    + (
                        f", autocorrelation {self.cycle_correlation[i]:.2f} at "
                        f"{self.cycle_period_s[i]:.2f} s"
                        if i < self.cycle_correlation.size
                        and np.isfinite(self.cycle_correlation[i])
                        else ""
                    )
                )
            if self.saturated[i]:
                lines.append(
                    f"channel {lab!r} is saturated: {100 * self.clipped_fraction[i]:.2f} % of "
                    "samples at the extreme value"
                )
        return lines


@dataclass(frozen=True)
class EmgEnvelopes(FrameAxis):
    """Normalised EMG envelopes e(t) ∈ [0, 1] (NaN for unusable channels), time on axis 0."""

    FRAME_FIELDS: ClassVar[tuple[str, ...]] = (
        "time",
        "envelopes",
    )

    time: Array  #: (N,) s
    envelopes: Array  #: (N, n_muscles)
    muscle_names: tuple[str, ...]
    muscle_sources: tuple[str, ...]  #: channel label(s) behind each muscle ("vasmed+vaslat")
    channel_labels: tuple[str, ...]  #: channels actually used, in the order below
    normalisation_source: tuple[str, ...]  #: per channel: "mvc" or "session_peak"
    normalisation_value: Array  #: per channel: the divisor, input units
    quality: ChannelQuality
    delay_s: Array  #: per muscle electromechanical delay applied
    warnings: tuple[str, ...]
    #: single-sample faults found in the raw channels (:mod:`msk.muscles.emg_faults`)
    sample_faults: tuple[SampleFaults, ...] = ()

    @property
    def rate_hz(self) -> float:
        return float(1.0 / np.median(np.diff(self.time))) if self.time.size > 1 else float("nan")

    @property
    def usable(self) -> NDArray[np.bool_]:
        """Muscles whose envelope is finite throughout."""
        return np.asarray(np.isfinite(self.envelopes).all(axis=0))

    def column(self, muscle: str) -> Array:
        if muscle not in self.muscle_names:
            raise MissingDataError(f"muscle {muscle!r} not in EMG envelopes {self.muscle_names}")
        return self.envelopes[:, self.muscle_names.index(muscle)]

    def resampled(self, time: ArrayLike) -> EmgEnvelopes:
        """Envelopes linearly interpolated at ``time`` (e.g. the marker frames)."""
        t = np.asarray(time, dtype=float)
        return EmgEnvelopes(
            time=t,
            envelopes=resample_to(self.time, self.envelopes, t),
            muscle_names=self.muscle_names,
            muscle_sources=self.muscle_sources,
            channel_labels=self.channel_labels,
            normalisation_source=self.normalisation_source,
            normalisation_value=self.normalisation_value,
            quality=self.quality,
            delay_s=self.delay_s,
            warnings=self.warnings,
            sample_faults=self.sample_faults,
        )


def _as_channels(x: ArrayLike, n_labels: int | None = None) -> Array:
    a = np.asarray(x, dtype=float)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2:
        raise EmgError(f"EMG must be (N samples, C channels), got shape {a.shape}")
    if n_labels is not None and a.shape[1] != n_labels:
        if a.shape[0] == n_labels:
            raise EmgError(
                f"EMG has shape {a.shape} but {n_labels} labels: pass (N samples, C channels) "
                "(transpose the analogs)"
            )
        raise EmgError(f"EMG has {a.shape[1]} channels but {n_labels} labels")
    return a


def linear_envelope(
    emg: ArrayLike,
    *,
    rate_hz: float,
    highpass_hz: float = 30.0,
    lowpass_hz: float = 6.0,
    order: int = 4,
) -> Array:
    """High-pass, full-wave rectify, low-pass (the EMG-driven vs OpenSim thesis, §2.2.1); ``(N, C)``
    → ``(N, C)``.

    Both filters are zero-lag Butterworth (:func:`msk.signal.filtfilt_butter`); the envelope is
    clipped at 0 (the low-pass can ring slightly below zero). Units are those of the input.
    """
    x = _as_channels(emg)
    if not np.isfinite(x).all():
        r, c = np.argwhere(~np.isfinite(x))[0]
        raise MissingDataError(f"EMG channel {c} has a non-finite sample at index {r}: fill it")
    hp = filtfilt_butter(x, rate_hz=rate_hz, cutoff_hz=highpass_hz, order=order, btype="highpass")
    env = filtfilt_butter(np.abs(hp), rate_hz=rate_hz, cutoff_hz=lowpass_hz, order=order)
    return np.maximum(env, 0.0)


@dataclass(frozen=True)
class EnvelopeChannel:
    """A channel recognised as a pre-processed envelope (:func:`envelope_channel`): its
    ``envelope`` (low-passed only, input units), the quantisation step ``lsb``, the RMS above
    the high-pass in steps (``hp_rms_lsb``) and the low-passed standard deviation in steps
    (``lp_sd_lsb``)."""

    envelope: Array
    lsb: float
    hp_rms_lsb: float
    lp_sd_lsb: float


def envelope_channel(
    x: ArrayLike,
    *,
    rate_hz: float,
    highpass_hz: float = 30.0,
    lowpass_hz: float = 6.0,
    floor_lsb: float = 3.0,
    moving_lsb: float = 1.0,
    order: int = 4,
) -> EnvelopeChannel | None:
    """The channel ``x`` ``(N,)`` as an envelope when it is a pre-processed (rectified and
    smoothed) EMG amplitude rather than raw EMG, else None.

    Raw surface EMG is zero-mean with its power at 20–500 Hz (De Luca 1997, *J Appl Biomech*
    13:135); an envelope — |x| low-passed, or a moving RMS — is non-negative with its power
    below a few hertz. Criteria: no negative sample; the high-passed (``highpass_hz``) RMS at
    most ``floor_lsb`` quantisation steps (the ADC's floor: nothing of raw EMG left); the
    ``lowpass_hz`` low-passed signal's standard deviation at least ``moving_lsb`` steps (it
    moves: not a dead channel with an offset — the quantisation noise itself, ≈ 0.29 steps
    white, keeps ≈ 0.29 √(2 f_lp / f_s) ≈ 0.02 steps below 6 Hz at 2 kHz). The envelope
    returned is the channel low-passed at ``lowpass_hz``, neither high-passed nor rectified
    again. A channel without distinct quantisation steps
    (LSB 0, e.g. a float export) is judged with the step taken as 1e-6 of its range."""
    v = np.asarray(x, dtype=float).ravel()
    if v.size < 8 or not np.isfinite(v).all() or float(v.min()) < 0.0:
        return None
    u = np.unique(v)
    d = np.diff(u)
    lsb = float(d.min()) if d.size else 0.0
    if lsb <= 0.0 or lsb < 1e-9 * max(float(np.ptp(v)), 1e-300):
        lsb = 1e-6 * float(np.ptp(v))
    if lsb <= 0.0:
        return None
    hp = filtfilt_butter(v, rate_hz=rate_hz, cutoff_hz=highpass_hz, order=order, btype="highpass")
    lp = filtfilt_butter(v, rate_hz=rate_hz, cutoff_hz=lowpass_hz, order=order)
    k = _edge(v.size, rate_hz, lowpass_hz)
    inner = slice(k, v.size - k) if k else slice(None)
    hp_lsb = float(np.sqrt(np.mean(hp[inner] ** 2))) / lsb
    lp_lsb = float(np.std(lp[inner])) / lsb
    if hp_lsb > floor_lsb or lp_lsb < moving_lsb:
        return None
    return EnvelopeChannel(np.maximum(lp, 0.0), lsb, hp_lsb, lp_lsb)


def _edge(n: int, rate_hz: float, lowpass_hz: float) -> int:
    """Samples to ignore at each end when taking peaks/percentiles (filter transients)."""
    return min(round(rate_hz / lowpass_hz), max(n // 10, 0))


def mvc_peaks(
    trials: Sequence[tuple[ArrayLike, float, Sequence[str]]],
    *,
    highpass_hz: float = 30.0,
    lowpass_hz: float = 6.0,
    order: int = 4,
) -> dict[str, float]:
    """Peak envelope per channel label over all MVC trials ``(emg (N, C), rate_hz, labels)``.

    One value per channel from all trials together (the EMG-driven vs OpenSim thesis, §3.1.4); the
    first and last ``rate/lowpass`` samples of each trial are ignored (filter edge transients).
    """
    peaks: dict[str, float] = {}
    for emg, rate, labels in trials:
        labels = [str(s).strip() for s in labels]
        x = _as_channels(emg, len(labels)).copy()
        keep = []
        for j, lab in enumerate(labels):  # a glitch must not set the MVC (emg_faults)
            fixed, _ = repair_sample_faults(x[:, j], rate_hz=rate, channel=lab)
            if fixed is not None:
                x[:, j] = fixed
                keep.append(j)
            else:
                x[:, j] = 0.0  # excluded: no MVC from this trial for the channel
        env = linear_envelope(
            x, rate_hz=rate, highpass_hz=highpass_hz, lowpass_hz=lowpass_hz, order=order
        )
        k = _edge(env.shape[0], rate, lowpass_hz)
        inner = env[k : env.shape[0] - k] if k else env
        for j in keep:
            lab = labels[j]
            peaks[lab] = max(peaks.get(lab, 0.0), float(inner[:, j].max()))
    return peaks


@dataclass(frozen=True)
class _ChannelStats:
    """One channel's quality figures before the cross-channel ones (relative RMS, flags)."""

    rms: float
    lsb: float
    modulation: float
    clipped: float
    envelope: Array  #: max(low-pass(|high-pass(x)|), 0) with order-4 filters, (N,)
    cycle_correlation: float = float("nan")
    cycle_period_s: float = float("nan")


def cycle_correlation(envelope: ArrayLike, rate_hz: float) -> tuple[float, float]:
    """The autocorrelation of ``envelope`` (N,) at its stride over the lags of
    :data:`CYCLE_LAG_S`, and that lag (s): Pearson r between e(t) and e(t + τ) over their
    overlap, at the peak of the shortest lag within 0.05 of the best (a multiple of the stride
    matches about as well), the envelope
    sampled at :data:`_CYCLE_RATE_HZ` (module docstring). (NaN, NaN) when the record is shorter
    than two of the shortest lags or the envelope is constant."""
    e = np.asarray(envelope, dtype=float)
    step = max(1, int(rate_hz // _CYCLE_RATE_HZ))
    e = e[::step]
    r_hz = rate_hz / step
    lo = max(1, int(np.ceil(CYCLE_LAG_S[0] * r_hz)))
    hi = min(int(CYCLE_LAG_S[1] * r_hz), e.size // 2)
    if hi < lo or not np.isfinite(e).all():
        return float("nan"), float("nan")
    lags = np.arange(lo, hi + 1)
    r = np.full(lags.size, np.nan)
    for i, k in enumerate(lags):
        a, b = e[:-k], e[k:]
        sa, sb = float(a.std()), float(b.std())
        if sa > 0.0 and sb > 0.0:
            r[i] = float(np.mean((a - a.mean()) * (b - b.mean())) / (sa * sb))
    if not np.isfinite(r).any():
        return float("nan"), float("nan")
    # the shortest lag as good as the best to within 0.05 (not a multiple of the stride)
    i = int(np.flatnonzero(np.nan_to_num(r, nan=-np.inf) >= np.nanmax(r) - 0.05)[0])
    while i + 1 < r.size and np.nan_to_num(r[i + 1], nan=-np.inf) > r[i]:
        i += 1  # up to that peak
    return float(r[i]), float(lags[i] / r_hz)


def _channel_stats(
    x: Array,
    *,
    rate_hz: float,
    highpass_hz: float,
    lowpass_hz: float,
    saturation_level: float | None,
) -> _ChannelStats:
    """:func:`channel_quality`'s figures of one channel ``x`` (N,)."""
    n = x.shape[0]
    hp = filtfilt_butter(x, rate_hz=rate_hz, cutoff_hz=highpass_hz, btype="highpass")
    rms = float(np.sqrt(np.mean(hp**2)))
    np.abs(hp, out=hp)
    env = np.maximum(filtfilt_butter(hp, rate_hz=rate_hz, cutoff_hz=lowpass_hz), 0.0)
    del hp
    k = _edge(n, rate_hz, lowpass_hz)
    inner = env[k : n - k] if k else env
    p10 = float(np.percentile(inner, 10))
    p99 = float(np.percentile(inner, 99))
    modulation = p99 / p10 if p10 > 0 else (np.inf if p99 > 0 else 1.0)
    u = np.unique(x)
    d = np.diff(u)
    d = d[d > 0]
    lsb = float(d.min()) if d.size else 0.0
    tol = 0.5 * lsb if lsb > 0 else 0.0
    at_max = x >= u[-1] - tol
    at_min = x <= u[0] + tol
    if saturation_level is not None:
        at_max |= x >= saturation_level
        at_min |= x <= -saturation_level
    clipped = max(at_max.sum(), at_min.sum()) / n if u.size > 1 else 1.0
    cyc, period = cycle_correlation(inner, rate_hz)
    return _ChannelStats(rms, lsb, float(modulation), float(clipped), env, cyc, period)


def _quality(
    labels: tuple[str, ...],
    stats: Sequence[_ChannelStats],
    n: int,
    *,
    flat_rms_lsb: float = 20.0,
    flat_rel_rms: float = 0.05,
    flat_modulation: float = 1.6,
    flat_cycle_correlation: float = 0.6,
    clip_min_samples: int = 5,
    clip_fraction: float = 0.002,
) -> ChannelQuality:
    """The flags of :func:`channel_quality` from every channel's :class:`_ChannelStats`."""
    c = len(stats)
    rms = np.array([st.rms for st in stats])
    lsb = np.array([st.lsb for st in stats])
    modulation = np.array([st.modulation for st in stats])
    clipped = np.array([st.clipped for st in stats])
    with np.errstate(divide="ignore", invalid="ignore"):
        rms_lsb = np.where(lsb > 0, rms / lsb, 0.0)
    rel = rms / np.median(rms) if c >= 3 and np.median(rms) > 0 else np.full(c, np.nan)
    cyc = np.array([st.cycle_correlation for st in stats])
    period = np.array([st.cycle_period_s for st in stats])
    flat = (rms_lsb < flat_rms_lsb) | (modulation < flat_modulation)
    flat &= ~(np.nan_to_num(cyc, nan=-1.0) >= flat_cycle_correlation)  # bursts with the cycle
    if c >= 3:
        flat |= rel < flat_rel_rms
    n_clip = clipped * n
    saturated = (~flat) & (n_clip >= clip_min_samples) & (clipped >= clip_fraction)
    return ChannelQuality(
        labels=labels,
        flat=flat,
        saturated=saturated,
        rms=rms,
        lsb=lsb,
        rms_lsb=rms_lsb,
        relative_rms=rel,
        modulation=modulation,
        clipped_fraction=clipped,
        cycle_correlation=cyc,
        cycle_period_s=period,
    )


def channel_quality(
    emg: ArrayLike,
    *,
    rate_hz: float,
    labels: Sequence[str],
    highpass_hz: float = 30.0,
    lowpass_hz: float = 6.0,
    flat_rms_lsb: float = 20.0,
    flat_rel_rms: float = 0.05,
    flat_modulation: float = 1.6,
    flat_cycle_correlation: float = 0.6,
    clip_min_samples: int = 5,
    clip_fraction: float = 0.002,
    saturation_level: float | None = None,
) -> ChannelQuality:
    """Flat and saturated channel detection with the figures behind each decision (channel by
    channel: one channel's filtered copies at a time)."""
    labels = tuple(str(s).strip() for s in labels)
    x = _as_channels(emg, len(labels))
    stats = []
    for j in range(x.shape[1]):
        st = _channel_stats(
            np.ascontiguousarray(x[:, j]), rate_hz=rate_hz, highpass_hz=highpass_hz,
            lowpass_hz=lowpass_hz, saturation_level=saturation_level,
        )  # fmt: skip
        stats.append(dataclasses.replace(st, envelope=np.empty(0)))
    return _quality(
        labels, stats, x.shape[0], flat_rms_lsb=flat_rms_lsb, flat_rel_rms=flat_rel_rms,
        flat_modulation=flat_modulation, flat_cycle_correlation=flat_cycle_correlation,
        clip_min_samples=clip_min_samples, clip_fraction=clip_fraction,
    )  # fmt: skip


def missing_channels(
    channels: Mapping[str, str], labels: Sequence[str], *, typo_cutoff: float = 0.8
) -> tuple[dict[str, str], tuple[str, ...]]:
    """The configured EMG ``channels`` (muscle → channel label) a trial's analog ``labels`` lack,
    split into likely typos and absent channels.

    A missing label whose closest unmapped analog label (:func:`difflib.get_close_matches`,
    similarity ≥ ``typo_cutoff``: one wrong or extra character in a 5-character label) exists is
    a typo → ``{label: suggestion}``; any other missing label is absent from this recording (a
    channel not recorded in this trial) → the tuple. Comparison after stripping blanks."""
    import difflib

    have = [str(s).strip() for s in labels]
    wanted = {str(c).strip() for c in channels.values()}
    free = [lab for lab in have if lab not in wanted]
    typos: dict[str, str] = {}
    absent: list[str] = []
    for ch in sorted(wanted - set(have)):
        close = difflib.get_close_matches(ch, free, n=1, cutoff=typo_cutoff)
        if close:
            typos[ch] = close[0]
        else:
            absent.append(ch)
    return typos, tuple(absent)


#: (pattern, gait2392 muscle stem): how EMG channel labels name a muscle, matched in this order at
#: the start of the label's letters (side words and "emg" removed, lower case): full names
#: ("Rectus femoris"), the short names of clinical labs ("vasmed", "tibant", "gmax") and the
#: three-letter codes of Motion Analysis files ("REC", "VAS", "BIC", "TIB", "SOL")
EMG_NAMES: tuple[tuple[str, str], ...] = (
    (r"rect|rf$|rec$", "rect_fem"),
    (r"vas\w*med|vm$|vmo$", "vas_med"),
    (r"vas\w*int|vi$", "vas_int"),
    (r"vas\w*lat|vl$|vas$|vastus$", "vas_lat"),
    (r"bi\w*(short|brev|sh$)|bfsh", "bifemsh"),
    (r"bic|bifem|bf", "bifemlh"),
    (r"semimem|sm$", "semimem"),
    (r"semiten|st$", "semiten"),
    (r"(gas|gastr)\w*lat|lat\w*gas|lg$", "lat_gas"),
    (r"(gas|gastr)\w*med|med\w*gas|mg$|gas", "med_gas"),
    (r"sol", "soleus"),
    (r"tib\w*post|tp$", "tib_post"),
    (r"tib|ta$", "tib_ant"),
    (r"per\w*brev|fib\w*brev|pb$", "per_brev"),
    (r"peron|fibul|perl|pl$", "per_long"),
    (r"gmax|glu\w*max", "glut_max2"),
    (r"gmed|glu\w*med", "glut_med2"),
    (r"gmin|glu\w*min", "glut_min2"),
    (r"tfl|tensor", "tfl"),
    (r"add\w*mag|am$", "add_mag2"),
    (r"add\w*brev", "add_brev"),
    (r"add", "add_long"),
    (r"grac", "grac"),
    (r"sar", "sar"),
    (r"psoas", "psoas"),
    (r"iliac", "iliacus"),
)

#: gait2392 muscle stem → the Rajagopal et al. (2016) model's name for the same muscle (the
#: suggestion is made in the model's own names)
RAJAGOPAL_STEMS: Mapping[str, str] = {
    "rect_fem": "recfem", "vas_med": "vasmed", "vas_int": "vasint", "vas_lat": "vaslat",
    "bifemsh": "bfsh", "bifemlh": "bflh", "lat_gas": "gaslat", "med_gas": "gasmed",
    "tib_post": "tibpost", "tib_ant": "tibant", "per_brev": "perbrev", "per_long": "perlong",
    "glut_max2": "glmax2", "glut_med2": "glmed2", "glut_min2": "glmin2",
    "add_mag2": "addmagMid", "add_brev": "addbrev", "add_long": "addlong", "sar": "sart",
}  # fmt: skip

_LEFT = frozenset({"l", "left", "lt", "sx", "sin"})
_RIGHT = frozenset({"r", "right", "rt", "dx"})
_NOISE = frozenset({"emg", "voltage", "sensor", "analog", "channel", "ch", "muscle"})


def _emg_stem(letters: str) -> str | None:
    import re

    for pattern, stem in EMG_NAMES:
        if re.match(pattern, letters):
            return stem
    return None


def suggest_channels(
    labels: Sequence[str], muscles: Sequence[str], *, side: str = "r"
) -> dict[str, tuple[str, bool]]:
    """EMG channel label → (model muscle, whether the label names the side), for the labels
    that name a muscle of :data:`EMG_NAMES` (``"Left Rectus femoris"`` → ``rect_fem_l``,
    ``"LREC"`` → ``rect_fem_l``, ``"vasmed"`` → ``vas_med_<side>``; in a model that names the
    muscle as Rajagopal et al. 2016 do, :data:`RAJAGOPAL_STEMS`: ``recfem_l``).

    The side is a word of the label (``L``, ``Left``, ``R``, ``right``…) or a one-letter prefix
    of a code (``RTIB``); a label naming no side gets ``side``. Only muscles in ``muscles``
    are suggested; a muscle two labels name goes to the first. A guess from the label only: the
    user confirms it (``[emg] channels``)."""
    import re

    have = set(muscles)
    out: dict[str, tuple[str, bool]] = {}
    taken: set[str] = set()
    for label in labels:
        words = [w for w in re.split(r"[^a-z]+", str(label).lower()) if w and w not in _NOISE]
        sides = [w for w in words if w in _LEFT | _RIGHT]
        letters = "".join(w for w in words if w not in _LEFT | _RIGHT)
        stem = _emg_stem(letters) if letters else None
        named = sides[0][0] if sides else None
        if stem is None and not sides and letters[:1] in ("l", "r") and len(letters) > 2:
            stem = _emg_stem(letters[1:])  # LREC, RTIB: a side letter before a code
            named = letters[0] if stem is not None else None
        if stem is None:
            continue
        muscle = f"{stem}_{named or side}"
        if muscle not in have:  # the model names it otherwise (Rajagopal)
            muscle = f"{RAJAGOPAL_STEMS.get(stem, stem)}_{named or side}"
        if muscle in have and muscle not in taken:
            out[str(label)] = (muscle, named is not None)
            taken.add(muscle)
    return out


def unknown_muscles(
    channels: Mapping[str, str], muscles: Sequence[str], *, cutoff: float = 0.6
) -> dict[str, str | None]:
    """The configured EMG ``channels``' muscle names (their keys) that are no muscle of the model,
    each with the closest model muscle name (:func:`difflib.get_close_matches`, similarity ≥
    ``cutoff``: ``rectfem_r`` → ``rect_fem_r``) or ``None`` when nothing is close."""
    import difflib

    names = list(muscles)
    return {
        key: next(iter(difflib.get_close_matches(key, names, n=1, cutoff=cutoff)), None)
        for key in sorted(set(channels) - set(names))
    }


def process_emg(
    emg: ArrayLike | StoredAnalogs,
    *,
    rate_hz: float,
    labels: Sequence[str],
    muscles: Mapping[str, str] | None = None,
    synergists: Mapping[str, Sequence[str]] | None = None,
    mvc: Mapping[str, float] | None = None,
    mvc_trials: Sequence[tuple[ArrayLike, float, Sequence[str]]] | None = None,
    highpass_hz: float = 30.0,
    lowpass_hz: float = 6.0,
    order: int = 4,
    delay_s: float | Mapping[str, float] = 0.0,
    t0: float = 0.0,
    time: ArrayLike | None = None,
    bad_channel: Literal["nan", "keep", "raise"] = "nan",
    quality_options: Mapping[str, Any] | None = None,
) -> EmgEnvelopes:
    """Raw EMG ``(N, C)`` with channel ``labels`` → :class:`EmgEnvelopes`.

    ``muscles`` maps muscle name → channel label (config); ``None`` uses every channel as its own
    muscle. A label absent from ``labels`` raises :class:`MissingDataError` naming the muscle,
    the channel and the available labels. ``synergists`` maps a muscle without electrode to the
    muscles (already in ``muscles``) whose normalised envelopes it averages. ``mvc`` maps channel
    label → MVC envelope peak (:func:`mvc_peaks`), in the units of ``emg``; alternatively
    ``mvc_trials`` (``(emg, rate_hz, labels)`` tuples) are processed here with the same filters
    (explicit ``mvc`` values win). ``delay_s`` (scalar or
    per muscle) is the electromechanical delay: ``e_d[k] = e[k − round(d·rate)]``, the first
    samples repeating e[0].

    ``time``: the envelopes linearly interpolated at these times (s; the samples are at
    ``t0 + k / rate_hz``), each muscle's as soon as its channel is processed — the same as
    :meth:`EmgEnvelopes.resampled` of the result without ``time`` (synergists' means to
    round-off), holding one channel at the analog rate at a time (a long trial).
    """
    from msk.analogs import StoredAnalogs

    labels = tuple(str(s).strip() for s in labels)
    x: Array | StoredAnalogs
    if isinstance(emg, StoredAnalogs) and emg.shape[1] == len(labels):
        x = emg  # held as stored (a long trial's C3D): each channel scaled as it is read
    else:
        x = _as_channels(emg, len(labels))
    n = x.shape[0]
    if muscles is None:
        muscles = {lab: lab for lab in labels}
    missing = [(m, ch) for m, ch in muscles.items() if str(ch).strip() not in labels]
    if missing:
        m, ch = missing[0]
        raise MissingDataError(
            f"EMG channel {ch!r} (for muscle {m!r}) not found; available channels: {list(labels)}"
        )
    used: list[str] = []
    for ch in muscles.values():
        if str(ch).strip() not in used:
            used.append(str(ch).strip())
    idx = [labels.index(ch) for ch in used]
    names = list(muscles)
    msrc = [str(muscles[m]).strip() for m in names]
    for m, group in (synergists or {}).items():
        if m in names:
            raise EmgError(f"muscle {m!r} has both an electrode and a synergist mapping")
        unknown = [g for g in group if g not in names]
        if unknown or not group:
            raise MissingDataError(
                f"synergists {unknown or list(group)} of muscle {m!r} are not mapped muscles "
                f"({names})"
            )
    n_direct = len(names)
    syn = [(m, [names.index(g) for g in group]) for m, group in (synergists or {}).items()]
    for m, gi in syn:
        msrc.append("+".join(msrc[g] for g in gi))
        names.append(m)
    if isinstance(delay_s, Mapping):
        unknown = [m for m in delay_s if m not in names]
        if unknown:
            raise EmgError(f"delay given for unknown muscles {unknown}")
        delays = np.array([float(delay_s.get(m, 0.0)) for m in names])
    else:
        delays = np.full(len(names), float(delay_s))
    if np.any(delays < 0):
        j = int(np.flatnonzero(delays < 0)[0])
        raise EmgError(
            f"muscle {names[j]!r}: electromechanical delay must be >= 0 s, got {delays[j]}"
        )
    shifts = np.round(delays * rate_hz).astype(int)
    mvc_all: dict[str, float] = {}
    if mvc_trials:
        mvc_all.update(
            mvc_peaks(mvc_trials, highpass_hz=highpass_hz, lowpass_hz=lowpass_hz, order=order)
        )
    mvc_all.update({str(k).strip(): float(v) for k, v in (mvc or {}).items()})
    t_src = t0 + np.arange(n) / rate_hz
    t_out = t_src if time is None else np.asarray(time, dtype=float)
    out = np.empty((t_out.size, len(names)))
    qopt = dict(quality_options or {})
    k = _edge(n, rate_hz, lowpass_hz)
    stats: list[_ChannelStats] = []
    # muscles whose envelope a synergist averages: kept at the analog rate until the end
    in_groups = sorted({g for _, gi in syn for g in gi})
    grouped: dict[int, Array] = {}
    sources: list[str] = []
    norm = np.empty(len(used))
    over = np.zeros(len(used))
    norm_warnings: list[str] = []
    faults: list[SampleFaults] = []
    excluded = np.zeros(len(used), dtype=bool)
    for j, (ch, i) in enumerate(zip(used, idx)):
        xj = np.ascontiguousarray(x[:, i])
        # one glitch (1e20, inf, a 50 V transient) repaired, or the channel excluded: said
        fixed, fault = repair_sample_faults(xj, rate_hz=rate_hz, channel=ch, t0=t0)
        if fault is not None:
            faults.append(fault)
        if fixed is None:
            excluded[j] = True
            fixed = np.where(np.isfinite(xj), xj, 0.0)  # processed, then set to NaN
        xj = fixed
        st = _channel_stats(
            xj, rate_hz=rate_hz, highpass_hz=highpass_hz, lowpass_hz=lowpass_hz,
            saturation_level=qopt.get("saturation_level"),
        )  # fmt: skip
        # the envelope (the EMG-driven vs OpenSim thesis, §2.2.1): the quality pass's one when the
        # orders agree
        env = (
            st.envelope
            if order == 4
            else linear_envelope(
                xj, rate_hz=rate_hz, highpass_hz=highpass_hz, lowpass_hz=lowpass_hz, order=order
            )[:, 0]
        )
        del xj
        stats.append(dataclasses.replace(st, envelope=np.empty(0)))
        inner = env[k : n - k] if k else env
        if ch in mvc_all:
            v = float(mvc_all[ch])
            if not (np.isfinite(v) and v > 0):
                raise EmgError(f"EMG channel {ch!r}: MVC value must be > 0, got {v}")
            norm[j] = v
            sources.append("mvc")
        else:
            norm[j] = float(inner.max())
            sources.append("session_peak")
            norm_warnings.append(
                f"channel {ch!r}: no MVC given, normalised to the session's peak envelope "
                f"({norm[j]:.4g}); activation is relative, not % MVC"
            )
        with np.errstate(divide="ignore", invalid="ignore"):
            e = env / (norm[j] if norm[j] > 0 else np.nan)
        del env, inner
        e_in = np.nan_to_num(e[k : n - k] if k else e, nan=0.0)
        over[j] = e_in.max() if e_in.size else 0.0
        del e_in
        np.clip(e, 0.0, 1.0, out=e)
        for g in in_groups:
            if msrc[g] == ch:
                grouped[g] = e  # synergists average the undelayed envelopes (below)
        for col in range(n_direct):
            if msrc[col] != ch:
                continue
            s = int(shifts[col])
            ed = e if s <= 0 else np.concatenate([np.full(min(s, n), e[0]), e[: max(n - s, 0)]])
            out[:, col] = (
                ed if time is None else np.interp(t_out, t_src, ed, left=np.nan, right=np.nan)
            )
        del e
    quality = _quality(
        tuple(used), stats, n,
        **{key: v for key, v in qopt.items() if key != "saturation_level"},
    )  # fmt: skip
    warnings: list[str] = list(quality.summary())
    warnings += [f.message() for f in faults]
    unusable = quality.flat | excluded if bad_channel == "nan" else excluded
    if bad_channel == "raise" and quality.flat.any():
        raise EmgError("; ".join(quality.summary()))
    warnings += norm_warnings
    for j, ch in enumerate(used):
        if sources[j] == "mvc" and over[j] > 1.0:
            warnings.append(
                f"channel {ch!r}: envelope reaches {100 * over[j]:.1f} % of MVC; clipped to 100 %"
            )
    for col in range(n_direct):
        if unusable[used.index(msrc[col])]:
            out[:, col] = np.nan
    for c, (_, gi) in enumerate(syn):
        # the mean of the group's normalised envelopes (NaN for a flat one), then its own delay
        cols = [
            np.full(n, np.nan) if unusable[used.index(msrc[g])] else grouped[g] for g in gi
        ]  # fmt: skip
        col = n_direct + c
        m_e = np.mean(cols, axis=0)
        s = int(shifts[col])
        if s > 0:
            m_e = np.concatenate([np.full(min(s, n), m_e[0]), m_e[: max(n - s, 0)]])
        out[:, col] = (
            m_e if time is None else np.interp(t_out, t_src, m_e, left=np.nan, right=np.nan)
        )
    return EmgEnvelopes(
        time=t_out,
        envelopes=out,
        muscle_names=tuple(names),
        muscle_sources=tuple(msrc),
        channel_labels=tuple(used),
        normalisation_source=tuple(sources),
        normalisation_value=norm,
        quality=quality,
        delay_s=shifts / rate_hz,
        warnings=tuple(warnings),
        sample_faults=tuple(faults),
    )


class _AnalogTrial(Protocol):
    analogs: NDArray[np.float64]
    analog_labels: tuple[str, ...]
    analog_rate_hz: float
    analog_time: NDArray[np.float64]


def envelopes_from_trial(
    trial: _AnalogTrial,
    *,
    muscles: Mapping[str, str] | None = None,
    channels: Sequence[str] | None = None,
    **options: Any,
) -> EmgEnvelopes:
    """:func:`process_emg` on the analog channels of a :class:`msk.io.Trial` (``read_c3d``).

    Give either ``muscles`` (muscle → channel label) or ``channels`` (labels used as muscle
    names); MVC values in ``options["mvc"]`` must be in the trial's analog units
    (``trial.analog_units``). Time starts at ``trial.analog_time[0]``.
    """
    if muscles is None and channels is None:
        raise EmgError("envelopes_from_trial needs `muscles` (muscle -> channel) or `channels`")
    labels = tuple(str(s).strip() for s in trial.analog_labels)
    if muscles is None:
        muscles = {str(c).strip(): str(c).strip() for c in channels or ()}
    t = np.asarray(trial.analog_time, dtype=float)
    return process_emg(
        trial.analogs,  # a StoredAnalogs is scaled channel by channel as process_emg reads it
        rate_hz=float(trial.analog_rate_hz),
        labels=labels,
        muscles=muscles,
        t0=float(t[0]) if t.size else 0.0,
        **options,
    )


@dataclass(frozen=True)
class EmgActivations:
    """Per model muscle with an EMG channel: ``envelopes`` and ``activation`` (N, m) on the
    kinematics' time base (activation NaN for unusable channels), the channel each muscle reads
    (``sources``), ``usable`` (m,), the normalisation used, the reader's warnings and the
    per-channel :class:`ChannelQuality` and the raw channels' single-sample faults."""

    normalisation: str
    muscles: tuple[str, ...]
    sources: tuple[str, ...]
    envelopes: np.ndarray
    activation: np.ndarray
    usable: np.ndarray
    warnings: Sequence[str]
    quality: Any
    #: single-sample faults of the raw channels (:class:`msk.muscles.emg_faults.SampleFaults`),
    #: each repaired or its channel excluded
    sample_faults: tuple[Any, ...] = ()

    def column(self, muscle: str) -> int:
        """Index of ``muscle`` in :attr:`muscles`."""
        return self.muscles.index(muscle)


def emg_activations(
    trial: Any,
    *,
    muscles: Mapping[str, str],
    highpass_hz: float,
    lowpass_hz: float,
    delay_s: float,
    time: np.ndarray,
    mvc_trials: Sequence[tuple[Any, float, Sequence[str]]] = (),
    mvc: Mapping[str, float] | None = None,
) -> EmgActivations:
    """Activations of the model muscles ``muscles`` (model muscle → analog channel of
    ``trial``) on the time base ``time``: each channel's linear envelope
    (:func:`envelopes_from_trial`: high-pass, rectify, low-pass, electromechanical delay
    ``delay_s``, normalised by the MVC recordings ``mvc_trials`` or the MVC values ``mvc``,
    else by the trial's own peak), clipped to [0, 1] and passed through first-order activation
    dynamics (:func:`msk.muscles.activation.first_order_activation`); an unusable channel's
    activation is NaN. ``normalisation`` says which reference the activations are relative
    to."""
    from msk.muscles.activation import first_order_activation

    options: dict[str, Any] = {}
    if mvc_trials:
        options["mvc_trials"] = list(mvc_trials)
    if mvc:
        options["mvc"] = {k: float(v) for k, v in mvc.items()}
    env = envelopes_from_trial(
        trial, muscles=dict(muscles), highpass_hz=highpass_hz, lowpass_hz=lowpass_hz,
        delay_s=delay_s, time=time, **options,
    )  # fmt: skip
    e = np.clip(np.nan_to_num(env.envelopes, nan=0.0), 0.0, 1.0)
    act = first_order_activation(e, rate_hz=trial.point_rate_hz)
    act[:, ~env.usable] = np.nan
    return EmgActivations(
        "MVC" if (mvc_trials or mvc) else "this session's peak (relative activations, not "
        "strength)",
        tuple(env.muscle_names), tuple(env.muscle_sources), env.envelopes, act,
        np.asarray(env.usable), list(env.warnings), env.quality, tuple(env.sample_faults),
    )  # fmt: skip
