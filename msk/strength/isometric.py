"""Maximal voluntary isometric contractions on a dynamometer: the measured joint torque of the
targeted muscle group, its EMG MVC amplitudes, the trial's checks, and the factor against the
generic model scaled to the subject.

**Force → torque.** The load cell reads ``F(t)`` (N) along its axis, strapped at a distance
``d`` (m, the lever arm) from the joint centre, perpendicular to the segment. The baseline
``F_0`` is the mean of the pre-effort window ``[t_0, t_0 + T_b]`` when that window is a rest
(the target's EMG envelope below ``rest_fraction`` of its plateau and no drift); a recording
started with the effort under way has no rest to read, and ``F_0`` is then the cell's tared
zero (0 in the file, ± ``zero_sd``), stated (:attr:`IsometricTrial.baseline_source`). The
effort is
``s (F(t) − F_0)`` with ``s = ±1`` the direction the test pulls the cell. The maximal effort is
the best sustained window of length ``T_w`` (the largest moving mean over ``T_w``, e.g. 1 s;
the customary MVC plateau, e.g. Meldrum et al. 2007, and the SENIAM-era practice of reporting
a sustained mean, not a single peak sample)::

    F̄ = max_t (1/T_w) ∫_t^{t+T_w} s (F − F_0) dt,      τ_meas = d · F̄        (N·m)

A dynamometer exporting torque gives ``τ(t)`` directly (``d`` is then not used).

**Lever arm.** Given by the configuration (``lever_arm_m`` with its standard deviation), or
from the subject's stature ``H`` and the segment-length ratios of de Leva (1996, Table 4): knee
tests strapped at the ankle, ``d = L_shank − δ`` with ``L_shank = r_shank H`` (KJC–LMAL) and
``δ`` the strap's centre above the malleolus; ankle tests strapped over the forefoot,
``d = k L_foot`` (``L_foot = r_foot H``, HEEL–TTIP) with ``k`` the fraction of the foot
length from the ankle joint centre to the strap. ``k = 0.5 ± 0.1`` puts the strap over the
metatarsal heads: the ankle centre lies about 0.2–0.25 ``L_foot`` in front of the heel and the
metatarsal heads about 0.7–0.75 ``L_foot`` (de Leva 1996 HEEL–TTIP), ``0.25 ≤ k ≤ 0.55``; a
strap at mid-foot is ``k ≈ 0.3``, inside two standard deviations. The force line is taken
perpendicular to the foot: in the supine tests the cable runs along the leg (dorsiflexion: to a
fixture beyond the sole; plantarflexion: to a fixture behind the head, about 1.5–2 m away), i.e.
perpendicular to a neutral foot, and the lever arm is the strap's distance from the ankle axis
across the leg, ``k L_foot cos θ`` at an ankle angle θ off neutral (cos 10° = 0.985: inside the
standard deviation). A cable anchored off the leg's axis (e.g. 0.1 m above the sole's level
over 1.5 m) tilts the line by < 4° (cos > 0.998). Without the subject's sex the mean of the
male and female ratios is used and half their difference joins the standard deviation. The
result always states which (:attr:`TestStrength.lever_arm_source`).

**Plausibility: the published band.** Each action has a band of maximal isometric torque per
kilogram of body mass for older adults (:data:`LITERATURE_BANDS`, sex-pooled: the female
lower edge to the male upper edge, since the data sets often do not give the sex), used when
the subject is at least ``BAND_MIN_AGE_YEARS`` old. A test whose interval lies wholly below the
band (its upper end below the band's lower edge) carries ``below_published_band``: a torque this
low is either a true weakness or a failed measurement (submaximal effort, the strap slipping or
the subject sliding on the bench, the lever-arm assumption), which the trial's own checks
cannot tell apart. The test stays ``identified`` (a weakness is the finding a clinician looks
for; hiding it as "not determined" would hide exactly the patients the test is for), and the
flag, the band and its source are written with it so that the number is not acted upon before
the test is repeated; ``msk run --strict`` exits non-zero on it.

**Interval.** Independent relative errors add in quadrature: the plateau's variability
(the standard deviation of ``s (F − F_0)`` inside the best window, relative to ``F̄``), the
lever arm's, the tared zero's (``σ_0``, only when the zero is the tare) and half the
co-contraction correction (below)::

    u_rel = sqrt((σ_F / F̄)² + (σ_0 / F̄)² + (σ_d / d)² + (½ τ_co / τ_ag)²)
    95 % interval: τ_ag (1 ± 1.96 u_rel)

**Co-contraction.** The antagonist's activation ``a_ant`` is its plateau envelope divided by
its own MVC amplitude (the largest plateau envelope of that channel over the session's tests);
the antagonists' torque at the posture is ``τ_co = a_ant · τ_ant,max`` and the agonists
produced ``τ_ag = τ_meas + τ_co``. ``τ_ant,max`` is the subject's own measured net torque in
the antagonist's test when the session has one (same posture in the usual protocols), else
the scaled model's antagonist torque (below); the result says which. (The net torque the
cell measures is agonists minus antagonists.) Without a usable antagonist channel
``τ_co = 0``, stated.

**Model torque.** For the generic model scaled to the subject (gait2392, every body by
``H / H_model``, masses by the body mass, F_iso unchanged as OpenSim's scale tool leaves it),
at the test posture ``q`` every agonist fully active with the rigid-tendon Hill state at zero
velocity (:func:`msk.muscles.hill.rigid_tendon_state`)::

    τ_model(q) = Σ_{i: s R_i(q) > 0} s R_i(q) F_iso,i f_L(l̃_i(q)) cos α_i(q),  R_i = −∂l_i/∂θ

and the antagonists' ``τ_ant,model`` the same sum over the muscles of the other sign. A posture
angle not given (e.g. the ankle of a supine test) is swept over its stated range, whose
extremes give the model's interval. The factor is ``τ_ag / τ_model`` with the two intervals
combined (lower over upper, upper over lower).

**Checks** (each a :class:`msk.quality.Flag` naming test, channel and value; ``fails`` ones make
the group ``not determined`` with the reason):

* ``target_not_most_active``: the target's plateau envelope, relative to that channel's session
  maximum, is below another channel's (cross-talk, a swapped electrode, a wrong effort);
* ``effort_before_baseline``: the target's envelope in the pre-effort window exceeds
  ``rest_fraction`` of its plateau (the effort was under way: the baseline is not a rest);
* ``baseline_drift``: the force changes within the pre-effort window by more than
  ``drift_fraction`` of the effort above it; with ``baseline = "auto"`` these two choose the
  tared zero instead of failing the test (recorded as ``*_info``);
* ``baseline_offset`` (informational): the cell reads ``|F_0| > offset_max`` at rest (an
  untared cell; removed with the baseline);
* ``saturated``: the force reaches the cell's capacity, or stays on its largest value for at
  least ``clip_run_s`` (a clipped load cell or amplifier);
* ``plateau_short``: the effort stays at ≥ ``plateau_fraction`` of F̄ (0.1-s means) for less
  than ``T_w``, or the trial is shorter than ``T_w`` after the baseline;
* ``wrong_direction``: the largest sustained excursion is opposite to ``s``;
* ``emg_flat`` (:func:`msk.muscles.emg.channel_quality`): a dead/unused channel — fails the
  test when it is the target's; an antagonist's only removes the co-contraction correction;
* ``emg_quiet_other`` (informational, :func:`relabel_quiet_channels`): a non-target channel
  flat in this test but carrying EMG in another test of the session — a muscle at rest;
* ``emg_envelope_channel`` (informational): a channel that is an amplifier's pre-processed
  envelope (non-negative, nothing above the high-pass but quantisation, a moving amplitude
  below it: :func:`msk.muscles.emg.envelope_channel`) is used as its own envelope, low-passed
  only — the high-pass would leave nothing of it;
* ``emg_one_sided`` (informational): a channel with no negative sample (an amplifier's
  offset or half-wave output) that is not such an envelope: its envelope is a relative
  amplitude only.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from msk.exceptions import MissingDataError, ModelError
from msk.io.dynamometer import DynamometerRecording
from msk.muscles.emg import channel_quality, envelope_channel, linear_envelope
from msk.quality import Flag
from msk.status import STRENGTH_CI_REL_WIDTH_MAX, Status
from msk.units import Array

__all__ = [
    "BAND_MIN_AGE_YEARS",
    "CHECKS_FAILING",
    "LITERATURE_BANDS",
    "IsometricSettings",
    "IsometricTest",
    "IsometricTrial",
    "LeverArm",
    "LiteratureBand",
    "ModelTorque",
    "TestStrength",
    "agonist_mvc",
    "analyse_isometric",
    "band_check",
    "group_strength",
    "lever_arm_from_height",
    "literature_band",
    "model_isometric_torque",
    "relabel_quiet_channels",
    "remove_envelope_rest",
    "session_mvc",
    "subject_model",
    "target_check",
]

#: the checks whose flag makes the test's group ``not determined``
CHECKS_FAILING = frozenset(
    {
        "target_not_most_active",
        "effort_before_baseline",
        "baseline_drift",
        "saturated",
        "plateau_short",
        "wrong_direction",
        "emg_flat_target",
        "no_effort",
    }
)
#: z of a two-sided 95 % interval
_Z95 = 1.959963984540054


@dataclass(frozen=True)
class LiteratureBand:
    """A published band of maximal isometric torque per body mass, ``low_nm_per_kg`` to
    ``high_nm_per_kg`` (N·m/kg), and where it comes from (authors, year, population, posture)."""

    low_nm_per_kg: float
    high_nm_per_kg: float
    source: str


#: the youngest age (years) the older-adult bands of :data:`LITERATURE_BANDS` apply to
BAND_MIN_AGE_YEARS = 60.0

_SARABON = (
    "Šarabon, Kozinc & Perman (2021) Front Physiol 12:767941, meta-analysis of isometric knee "
    "strength: older adults, mid-range knee angle, pooled 95 % CI of the mean, {what}; "
    "sex-pooled (female lower edge – male upper edge)"
)
_SIMONEAU = (
    "Simoneau, Martin & Van Hoecke (2005) J Gerontol A 60:439, men aged 77 y: {what} N·m "
    "isometric at the neutral ankle, knee extended; per kg and sex-pooled as {how}"
)
#: published maximal isometric torque per kg for older adults (≥ 60 y), by action
#: (:class:`LiteratureBand`); the ankle bands are derived from absolute torques (stated)
LITERATURE_BANDS: dict[str, LiteratureBand] = {
    "knee extension": LiteratureBand(
        1.40, 2.16, _SARABON.format(what="extension 1.40–1.64 (women), 1.74–2.16 N·m/kg (men)")
    ),
    "knee flexion": LiteratureBand(
        0.46, 0.89, _SARABON.format(what="flexion 0.46–0.81 (women), 0.69–0.89 N·m/kg (men)")
    ),
    "ankle plantarflexion": LiteratureBand(
        0.56,
        1.33,
        _SIMONEAU.format(
            what="80",
            how="80 N·m over 60–100 kg = 0.80–1.33 N·m/kg, the lower edge × 0.7 for women "
            "(approximate)",
        ),
    ),
    "ankle dorsiflexion": LiteratureBand(
        0.32,
        0.70,
        _SIMONEAU.format(
            what="42",
            how="42 N·m over 60–100 kg = 0.42–0.70 N·m/kg, the lower edge × 0.75 for women "
            "(approximate)",
        ),
    ),
}


def literature_band(action: str, age_years: float | None) -> LiteratureBand | None:
    """The published band of ``action`` for a subject of ``age_years`` (``None``: no band for
    this action, or the age not given or below :data:`BAND_MIN_AGE_YEARS`)."""
    if age_years is None or age_years < BAND_MIN_AGE_YEARS:
        return None
    return LITERATURE_BANDS.get(action)


@dataclass(frozen=True, kw_only=True)
class IsometricSettings:
    """How an isometric trial is analysed (SI; the module docstring's symbols)."""

    #: where the zero comes from: ``"pre_effort"`` (the first T_b), ``"tared"`` (the file's 0,
    #: the cell tared before the test, ± ``zero_sd``), ``"auto"`` (the pre-effort window when
    #: it is a rest — target EMG below ``rest_fraction`` of its plateau, no drift — else tared)
    baseline: str = "auto"
    zero_sd: float = 9.80665  #: N (or N·m): the tare's uncertainty (1 kgf)
    baseline_window_s: float = 0.25  #: T_b
    plateau_window_s: float = 1.0  #: T_w
    plateau_fraction: float = 0.9
    rest_fraction: float = 0.5
    drift_fraction: float = 0.1
    offset_max_n: float = 20.0
    capacity: float | None = None  #: the cell's capacity, N (or N·m); None: not known
    clip_run_s: float = 0.02
    #: a channel whose high-passed RMS is below this many ADC steps is dead
    flat_rms_lsb: float = 3.0
    highpass_hz: float = 20.0
    lowpass_hz: float = 6.0


@dataclass(frozen=True, kw_only=True)
class IsometricTest:
    """One test of a protocol: its ``name``, the model ``action`` (a key of
    :data:`msk.strength.joint_strength.ACTIONS`: ``"knee extension"``…), the swept
    coordinate's angle ``angle_deg`` in the action's clinical convention with the range
    ``angle_range_deg`` when it is not measured (0: given), the other coordinates' posture
    (stem → deg, coordinate convention), the ``target`` EMG channel (its agonist) and the
    ``antagonist`` channel (or ""), the direction ``sign`` the effort moves the reading, and
    the strap's ``segment`` for an anthropometric lever arm (``"shank"``, ``"foot"``)."""

    name: str
    action: str
    angle_deg: float
    posture_deg: Mapping[str, float] = field(default_factory=dict)
    angle_range_deg: float = 0.0
    target: str = ""
    antagonist: str = ""
    sign: float = 1.0
    segment: str = "shank"


@dataclass(frozen=True)
class LeverArm:
    """A lever arm ``value_m`` ± ``sd_m`` (one standard deviation) and where it comes from."""

    value_m: float
    sd_m: float
    source: str


@dataclass(frozen=True)
class IsometricTrial:
    """The analysed trial: baseline ``baseline_n`` (N, or N·m for a torque export), the best
    window ``[window_start_s, window_start_s + plateau_window_s)`` with the effort's mean
    ``plateau_mean`` and standard deviation ``plateau_sd`` above the baseline (N or N·m),
    ``plateau_s`` how long the effort held ≥ plateau_fraction of the mean, the EMG envelope
    means (V) in the window (``emg_plateau``) and in the baseline window (``emg_baseline``) by
    channel label, and the ``flags`` of the checks (``checks`` name → passed)."""

    test: str
    is_torque: bool
    baseline_n: float
    baseline_sd: float
    baseline_source: str
    plateau_mean: float
    plateau_sd: float
    window_start_s: float
    plateau_s: float
    emg_plateau: Mapping[str, float]
    emg_baseline: Mapping[str, float]
    emg_flat: Mapping[str, bool]
    flags: tuple[Flag, ...]
    #: per channel that is an amplifier's envelope (``emg_envelope_channel``): its level at
    #: rest in this trial (the 1st percentile of its envelope, V), which
    #: :func:`remove_envelope_rest` takes off the session's amplitudes
    emg_rest: Mapping[str, float] = field(default_factory=dict)

    @property
    def failed(self) -> tuple[Flag, ...]:
        return tuple(f for f in self.flags if f.quantity in CHECKS_FAILING)


@dataclass(frozen=True)
class ModelTorque:
    """The scaled generic model's maximal isometric torques at the test posture (N·m, positive
    in the named direction): agonists ``agonist_nm`` (low, nominal, high over the posture's
    range) and antagonists ``antagonist_nm`` (nominal); the posture used (coordinate → deg)."""

    agonist_nm: tuple[float, float, float]
    antagonist_nm: float
    posture_deg: Mapping[str, float]
    muscles: tuple[str, ...]


@dataclass(frozen=True)
class TestStrength:
    """The strength of one test's targeted group (module docstring for every figure)."""

    test: str
    action: str
    status: str
    reason: str
    torque_nm: float
    torque_ci_nm: tuple[float, float]
    torque_nm_per_kg: float
    torque_nm_per_kg_ci: tuple[float, float]
    measured_net_nm: float
    cocontraction_nm: float
    cocontraction_note: str
    lever_arm_m: float
    lever_arm_sd_m: float
    lever_arm_source: str
    model_nm: float
    model_range_nm: tuple[float, float]
    factor: float
    factor_ci: tuple[float, float]
    flags: tuple[Flag, ...]
    #: the published band of the test's action (N·m/kg, NaN: none) and its source ("" none)
    band_nm_per_kg: tuple[float, float] = (float("nan"), float("nan"))
    band_source: str = ""

    @property
    def below_band(self) -> bool:
        """Whether the ``below_published_band`` flag was raised."""
        return any(f.quantity == "below_published_band" for f in self.flags)

    def as_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {
            k: getattr(self, k)
            for k in self.__dataclass_fields__
            if k
            not in (
                "flags",
                "torque_ci_nm",
                "torque_nm_per_kg_ci",
                "model_range_nm",
                "factor_ci",
                "band_nm_per_kg",
            )
        }
        d["band_nm_per_kg"] = [None if math.isnan(x) else x for x in self.band_nm_per_kg]
        d["below_published_band"] = self.below_band
        d["torque_ci_nm"] = list(self.torque_ci_nm)
        d["torque_nm_per_kg_ci"] = list(self.torque_nm_per_kg_ci)
        d["model_range_nm"] = list(self.model_range_nm)
        d["factor_ci"] = list(self.factor_ci)
        d["flags"] = [f.as_dict() for f in self.flags]
        return d


def _flag(test: str, quantity: str, value: float, threshold: float, message: str) -> Flag:
    return Flag(test, quantity, float(value), float(threshold), message)


def _moving_mean(x: Array, n: int) -> Array:
    c = np.concatenate(([0.0], np.cumsum(x)))
    return (c[n:] - c[:-n]) / n


def _longest_run(mask: NDArray[np.bool_]) -> int:
    if not mask.any():
        return 0
    d = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    return int((ends - starts).max())


def analyse_isometric(
    rec: DynamometerRecording,
    test: IsometricTest,
    *,
    settings: IsometricSettings | None = None,
) -> IsometricTrial:
    """Baseline, best sustained window, EMG envelopes and the checks of one trial (module
    docstring). The trial must hold the baseline window and one plateau window."""
    st = settings or IsometricSettings()
    rate = rec.rate_hz
    is_torque = rec.force is None
    y = rec.torque if is_torque else rec.force
    assert y is not None
    n = y.shape[0]
    nb = max(round(st.baseline_window_s * rate), 2)
    nw = max(round(st.plateau_window_s * rate), 1)
    if n < nb + 2:
        raise MissingDataError(
            f"{rec.source}: test {test.name!r} has {n} samples: shorter than the baseline "
            f"window ({st.baseline_window_s:g} s at {rate:g} Hz)"
        )
    flags: list[Flag] = []
    unit = "N·m" if is_torque else "N"
    col = rec.column
    base = y[:nb]
    b_mean = float(base.mean())
    third = max(nb // 3, 1)
    drift = float(test.sign * (base[-third:].mean() - base[:third].mean()))
    # the best window does not depend on a constant baseline: locate it on s·y
    after_raw = test.sign * y[nb:]
    nw_eff = min(nw, after_raw.shape[0])
    k = int(np.argmax(_moving_mean(after_raw, nw_eff)))
    i0 = nb + k
    # EMG: envelopes, flat channels, plateau and baseline amplitudes
    labels = rec.emg_labels
    emg_plateau: dict[str, float] = {}
    emg_base: dict[str, float] = {}
    emg_flat: dict[str, bool] = {}
    if labels:
        env = linear_envelope(
            rec.emg, rate_hz=rate, highpass_hz=st.highpass_hz, lowpass_hz=st.lowpass_hz
        )
        # an MVC trial is contracted throughout: no envelope-modulation criterion (a sustained
        # contraction is not modulated); dead = RMS within a few quantisation steps or far
        # below the other channels'
        q = channel_quality(
            rec.emg,
            rate_hz=rate,
            labels=labels,
            highpass_hz=st.highpass_hz,
            lowpass_hz=st.lowpass_hz,
            flat_modulation=0.0,
            flat_rms_lsb=st.flat_rms_lsb,
            flat_rel_rms=0.0,
        )
        enveloped: dict[str, float] = {}
        for j, lab in enumerate(labels):
            pre = (
                envelope_channel(
                    rec.emg[:, j],
                    rate_hz=rate,
                    highpass_hz=st.highpass_hz,
                    lowpass_hz=st.lowpass_hz,
                    floor_lsb=st.flat_rms_lsb,
                )
                if q.flat[j]
                else None
            )
            if pre is not None:  # an amplifier's envelope output: used as the envelope
                env[:, j] = pre.envelope
                k_e = min(round(rate / st.lowpass_hz), max(n // 10, 0))
                enveloped[lab] = float(np.percentile(pre.envelope[k_e : n - k_e], 1.0))
                flags.append(
                    _flag(
                        test.name,
                        "emg_envelope_channel",
                        pre.hp_rms_lsb,
                        st.flat_rms_lsb,
                        f"{test.name}: EMG {lab}: a pre-processed envelope, not raw EMG (no "
                        f"negative sample; {pre.hp_rms_lsb:.1f} quantisation steps above the "
                        f"{st.highpass_hz:g}-Hz high-pass, {pre.lp_sd_lsb:.0f} below it): used "
                        f"as its envelope, low-passed at {st.lowpass_hz:g} Hz, not rectified "
                        "again; the session's lowest rest level of the channel is taken off "
                        "its amplitudes",
                    )
                )
            emg_plateau[lab] = float(env[i0 : i0 + nw_eff, j].mean())
            emg_base[lab] = float(env[:nb, j].mean())
            emg_flat[lab] = bool(q.flat[j]) and pre is None
            if emg_flat[lab]:
                role = "target" if lab == test.target else "other"
                raw_sd = float(rec.emg[:, j].std())
                low = (
                    f"; its raw SD {raw_sd * 1e6:.1f} µV lies below the {st.highpass_hz:g}-Hz "
                    "high-pass: a processed or movement signal, not raw EMG"
                    if raw_sd > 3.0 * q.rms[j]
                    else ""
                )
                flags.append(
                    _flag(
                        test.name,
                        f"emg_flat_{role}",
                        float(q.rms_lsb[j]),
                        st.flat_rms_lsb,
                        f"{test.name}: EMG {lab}: flat/dead channel (RMS "
                        f"{q.rms[j] * 1e6:.1f} µV = {q.rms_lsb[j]:.1f} quantisation "
                        f"steps above the high-pass{low})",
                    )
                )
            if float(rec.emg[:, j].min()) >= 0.0 and lab not in enveloped:
                flags.append(
                    _flag(
                        test.name,
                        "emg_one_sided",
                        float(rec.emg[:, j].min()),
                        0.0,
                        f"{test.name}: EMG {lab}: no negative sample (offset "
                        f"{float(np.median(rec.emg[:, j])) * 1e6:.0f} µV, one-sided "
                        "signal): its envelope is a relative amplitude",
                    )
                )
    elif test.target:
        raise MissingDataError(
            f"{rec.source}: test {test.name!r}: target EMG channel {test.target!r} not read"
        )
    # is the pre-effort window a rest?
    rest_flags: list[Flag] = []
    t = test.target
    if t and t in emg_plateau and not emg_flat[t]:
        # an envelope channel's amplifier rest level is no contraction
        r0 = enveloped.get(t, 0.0) if labels else 0.0
        p, b = emg_plateau[t] - r0, emg_base[t] - r0
        if p > 0 and b > st.rest_fraction * p:
            rest_flags.append(
                _flag(
                    test.name,
                    "effort_before_baseline",
                    b / p,
                    st.rest_fraction,
                    f"{test.name}: EMG {t}: {100 * b / p:.0f} % of its "
                    "plateau already in the pre-effort window: the effort was "
                    "under way",
                )
            )
    level = float(np.mean(after_raw[k : k + nw_eff])) - test.sign * b_mean
    if level > 0.0 and abs(drift) > st.drift_fraction * level:
        rest_flags.append(
            _flag(
                test.name,
                "baseline_drift",
                drift,
                st.drift_fraction * level,
                f"{test.name}: {col}: the force changes by {drift:.1f} {unit} "
                f"within the {st.baseline_window_s:g}-s pre-effort window "
                f"(> {100 * st.drift_fraction:.0f} % of the effort above it)",
            )
        )
    at_rest = not rest_flags
    if st.baseline == "tared" or (st.baseline == "auto" and not at_rest):
        f0, f0_sd = 0.0, st.zero_sd
        why = "the pre-effort window is not a rest" if not at_rest else "configured"
        source = f"the cell's tared zero (0 {unit} in the file, ± {st.zero_sd:g} {unit}): {why}"
        for f in rest_flags:  # they chose the zero; informational
            flags.append(dataclasses.replace(f, quantity=f.quantity + "_info"))
    else:
        f0, f0_sd = b_mean, 0.0
        source = f"mean of the first {st.baseline_window_s:g} s (pre-effort window)"
        flags.extend(rest_flags)
        if not is_torque and at_rest and abs(f0) > st.offset_max_n:
            flags.append(
                _flag(
                    test.name,
                    "baseline_offset",
                    f0,
                    st.offset_max_n,
                    f"{test.name}: {col}: the load cell reads {f0:.1f} N "
                    f"({f0 / 9.80665:.1f} kgf) at rest before the effort; removed as "
                    "the baseline",
                )
            )
    eff = test.sign * (y - f0)
    after = eff[nb:]
    win = after[k : k + nw_eff]
    mean, sd = float(win.mean()), float(win.std())
    start_s = float(rec.time[i0] - rec.time[0])
    if nw_eff < nw:
        flags.append(
            _flag(
                test.name,
                "plateau_short",
                after.shape[0] / rate,
                st.plateau_window_s,
                f"{test.name}: {col}: {after.shape[0] / rate:.2f} s after the baseline "
                f"window, shorter than the {st.plateau_window_s:g}-s plateau window",
            )
        )
    if mean <= 0.0:
        flags.append(
            _flag(
                test.name,
                "no_effort",
                mean,
                0.0,
                f"{test.name}: {col}: no effort above the baseline (best window {mean:.1f} {unit})",
            )
        )
    mm_opp = _moving_mean(-after, nw_eff)
    if mean > 0.0 and float(mm_opp.max()) > mean:
        flags.append(
            _flag(
                test.name,
                "wrong_direction",
                float(mm_opp.max()),
                mean,
                f"{test.name}: {col}: the largest sustained excursion "
                f"({float(mm_opp.max()):.1f} {unit}) is opposite to the test's "
                f"direction ({mean:.1f} {unit}): check the cell's sign",
            )
        )
    held = 0.0
    if mean > 0.0:
        ns = max(round(0.1 * rate), 1)
        sm = _moving_mean(after, min(ns, after.shape[0]))
        held = _longest_run(sm >= st.plateau_fraction * mean) / rate
        if held < st.plateau_window_s and nw_eff == nw:
            flags.append(
                _flag(
                    test.name,
                    "plateau_short",
                    held,
                    st.plateau_window_s,
                    f"{test.name}: {col}: the effort held ≥ "
                    f"{100 * st.plateau_fraction:.0f} % of its best "
                    f"{st.plateau_window_s:g}-s mean for {held:.2f} s only",
                )
            )
    top = float(y.max()) if test.sign > 0 else float(y.min())
    if st.capacity is not None and abs(top) >= 0.995 * st.capacity:
        flags.append(
            _flag(
                test.name,
                "saturated",
                abs(top),
                st.capacity,
                f"{test.name}: {col}: reaches {abs(top):.1f} {unit}, the cell's "
                f"capacity ({st.capacity:g} {unit})",
            )
        )
    else:
        run = _longest_run(y == top) / rate
        if run >= st.clip_run_s:
            flags.append(
                _flag(
                    test.name,
                    "saturated",
                    run,
                    st.clip_run_s,
                    f"{test.name}: {col}: stays on its extreme value {top:.2f} "
                    f"{unit} for {run * 1000:.0f} ms: clipped",
                )
            )
    return IsometricTrial(
        test=test.name,
        is_torque=is_torque,
        baseline_n=f0,
        baseline_sd=f0_sd,
        baseline_source=source,
        plateau_mean=mean,
        plateau_sd=sd,
        window_start_s=start_s,
        plateau_s=held,
        emg_plateau=emg_plateau,
        emg_baseline=emg_base,
        emg_flat=emg_flat,
        flags=tuple(flags),
        emg_rest=dict(enveloped) if labels else {},
    )


def remove_envelope_rest(trials: Sequence[IsometricTrial]) -> list[IsometricTrial]:
    """The trials with each envelope channel's amplifier rest level taken off its plateau and
    baseline amplitudes: ``R_c = min_i`` of the trials' rest levels (:attr:`IsometricTrial.\
    emg_rest`; the session's quietest reading of the channel), ``e ← max(e − R_c, 0)``. An
    RMS or envelope output reads its noise floor at rest, which raw EMG's high-pass removes:
    left in, it would count as activity (an antagonist's co-contraction, a target's share of
    its MVC)."""
    rest: dict[str, float] = {}
    for tr in trials:
        for lab, v in tr.emg_rest.items():
            rest[lab] = min(rest.get(lab, v), v)
    out = []
    for tr in trials:
        if not tr.emg_rest:
            out.append(tr)
            continue
        plateau = dict(tr.emg_plateau)
        base = dict(tr.emg_baseline)
        for lab in tr.emg_rest:
            plateau[lab] = max(plateau[lab] - rest[lab], 0.0)
            base[lab] = max(base[lab] - rest[lab], 0.0)
        out.append(dataclasses.replace(tr, emg_plateau=plateau, emg_baseline=base))
    return out


def relabel_quiet_channels(trials: Sequence[IsometricTrial]) -> list[IsometricTrial]:
    """The trials with each ``emg_flat_other`` flag of a channel that is *not* flat in another
    test of the session replaced by the informational ``emg_quiet_other``: a non-target muscle
    whose EMG stays at the noise floor during one test (the vastus lateralis during a knee
    flexion, the gastrocnemius during a dorsiflexion) is at rest, not a dead electrode, when the
    same channel carries EMG in another test. Only a channel flat in every test of the session
    is called dead. The analysis is unchanged (the channel still counts as no co-contraction in
    that test)."""
    alive = {lab for tr in trials for lab, flat in tr.emg_flat.items() if not flat}
    out = []
    for tr in trials:
        flags = []
        for f in tr.flags:
            lab = next(
                (
                    lab
                    for lab, flat in tr.emg_flat.items()
                    if flat and f.message.startswith(f"{tr.test}: EMG {lab}: flat/dead")
                ),
                None,
            )
            if f.quantity == "emg_flat_other" and lab in alive:
                active = [o.test for o in trials if lab in o.emg_flat and not o.emg_flat[lab]]
                rms = f.message.split("(RMS ", 1)[-1].split(" = ", 1)[0]
                f = dataclasses.replace(
                    f,
                    quantity="emg_quiet_other",
                    message=f"{tr.test}: EMG {lab}: quiet during this test (RMS {rms}, at the "
                    f"noise floor) and active in {', '.join(active)}: a muscle at rest, not a "
                    "dead channel; no co-contraction counted from it in this test",
                )
            flags.append(f)
        out.append(dataclasses.replace(tr, flags=tuple(flags)))
    return out


def session_mvc(trials: Sequence[IsometricTrial]) -> dict[str, float]:
    """Each channel's MVC amplitude (V): its largest plateau envelope over the session's tests
    (flat channels left out)."""
    out: dict[str, float] = {}
    for tr in trials:
        for lab, v in tr.emg_plateau.items():
            if not tr.emg_flat.get(lab, False):
                out[lab] = max(out.get(lab, 0.0), v)
    return out


def agonist_mvc(
    trials: Sequence[IsometricTrial], tests: Sequence[IsometricTest]
) -> dict[str, float]:
    """Each target channel's MVC amplitude (V): its plateau envelope in the test that targets
    it (flat channels left out; the largest when several tests target it)."""
    out: dict[str, float] = {}
    for tr, te in zip(trials, tests):
        t = te.target
        if t and t in tr.emg_plateau and not tr.emg_flat.get(t, False):
            out[t] = max(out.get(t, 0.0), tr.emg_plateau[t])
    return out


def target_check(
    trial: IsometricTrial, test: IsometricTest, mvc: Mapping[str, float]
) -> Flag | None:
    """``target_not_most_active``: the target's plateau envelope relative to its session MVC
    below another (non-flat) channel's; ``None`` when it is the most active."""
    t = test.target
    if not t or t not in trial.emg_plateau or trial.emg_flat.get(t, False):
        return None
    rel = {
        lab: v / mvc[lab]
        for lab, v in trial.emg_plateau.items()
        if mvc.get(lab, 0.0) > 0 and not trial.emg_flat.get(lab, False)
    }
    if t not in rel:
        return None
    top = max(rel, key=lambda lab: rel[lab])
    if top == t or rel[top] <= rel[t]:
        return None
    return _flag(
        test.name,
        "target_not_most_active",
        rel[t],
        rel[top],
        f"{test.name}: EMG {t} (the target) at {100 * rel[t]:.0f} % of its session "
        f"maximum, {top} at {100 * rel[top]:.0f} % of its own: the target is not the "
        "most active channel",
    )


# de Leva (1996) Table 4 lengths (mm) and reference statures (mm) by sex
_DELEVA_MM = {
    "male": {"shank": 434.0, "foot": 258.1, "stature": 1741.0},
    "female": {"shank": 432.3, "foot": 228.3, "stature": 1735.0},
}


def lever_arm_from_height(
    segment: str,
    height_m: float,
    *,
    sex: str | None = None,
    strap_offset_m: float = 0.05,
    strap_offset_sd_m: float = 0.02,
    foot_fraction: float = 0.5,
    foot_fraction_sd: float = 0.1,
    ratio_rel_sd: float = 0.04,
) -> LeverArm:
    """Lever arm from stature (module docstring): ``"shank"`` → ``r_shank H − δ``; ``"foot"``
    → ``k r_foot H``. ``ratio_rel_sd``: the spread of a segment's length for a given stature
    (about 4 %, relative). ``sex`` None: the mean of both tables, half the difference added
    to the standard deviation."""
    if not (0.5 < height_m < 2.5):
        raise ModelError(f"height {height_m!r} m: not a stature in metres")
    sexes = [sex] if sex else ["male", "female"]
    for s in sexes:
        if s not in _DELEVA_MM:
            raise ModelError(f"sex must be 'male' or 'female', got {s!r}")
    if segment not in ("shank", "foot"):
        raise ModelError(f"lever-arm segment must be 'shank' or 'foot', got {segment!r}")
    lengths = [_DELEVA_MM[s][segment] / _DELEVA_MM[s]["stature"] * height_m for s in sexes]
    length = float(np.mean(lengths))
    sex_sd = 0.5 * (max(lengths) - min(lengths))
    who = sex or "both sexes averaged"
    if segment == "shank":
        d = length - strap_offset_m
        sd = math.hypot(ratio_rel_sd * length, strap_offset_sd_m, sex_sd)
        src = (
            f"anthropometric: shank length (knee centre to lateral malleolus) {length:.3f} m = "
            f"de Leva (1996) Table 4 ratio × height {height_m:.2f} m ({who}), minus the strap's "
            f"centre {strap_offset_m:.3f} ± {strap_offset_sd_m:.3f} m above the malleolus"
        )
    else:
        d = foot_fraction * length
        sd = math.hypot(
            foot_fraction * ratio_rel_sd * length, foot_fraction_sd * length, foot_fraction * sex_sd
        )
        src = (
            f"anthropometric: {foot_fraction:.2f} ± {foot_fraction_sd:.2f} × foot length "
            f"{length:.3f} m (heel to toe tip, de Leva (1996) Table 4 ratio × height "
            f"{height_m:.2f} m, {who}) from the ankle centre to the strap (over the "
            "metatarsal heads), the force line perpendicular to the foot (a cable along the leg)"
        )
    return LeverArm(float(d), float(sd), src)


def subject_model(model: Any, *, height_m: float, mass_kg: float) -> Any:
    """The generic ``model`` scaled to a subject known by stature and mass: every body by
    ``height_m / H_model`` (:func:`msk.personalise.scaling.model_height`), segment masses to
    ``mass_kg``,
    fibre and tendon slack lengths with the paths, F_iso unchanged."""
    from msk.personalise.scaling import apply_scale_factors, model_height

    h_model, _ = model_height(model)
    s = float(height_m) / h_model
    factors = {b.name: np.full(3, s) for b in model.bodies}
    return apply_scale_factors(model, factors, body_mass=float(mass_kg))


def model_isometric_torque(model: Any, test: IsometricTest, *, side: str) -> ModelTorque:
    """The model's maximal isometric agonist and antagonist torques at the test's posture
    (module docstring), over ``angle_deg ± angle_range_deg``."""
    from msk.muscles.geometry import muscle_geometry, muscle_parameters
    from msk.muscles.hill import rigid_tendon_state
    from msk.strength.joint_strength import ACTIONS

    if test.action not in ACTIONS:
        raise ModelError(
            f"test {test.name!r}: unknown action {test.action!r}; have {sorted(ACTIONS)}"
        )
    spec = ACTIONS[test.action]
    sfx = "_r" if side.lower() in ("right", "r") else "_l"
    base = np.asarray(model.default_coordinates(), dtype=float).copy()
    for c in model.coordinates:
        if not c.name.endswith(("_tx", "_ty", "_tz")):
            base[model.coordinate_index(c.name)] = 0.0
    posture: dict[str, float] = {}
    for stem, deg in test.posture_deg.items():
        base[model.coordinate_index(stem + sfx)] = math.radians(deg)
        posture[stem + sfx] = float(deg)
    k = model.coordinate_index(spec.coordinate + sfx)
    angles = np.array(
        [
            test.angle_deg - test.angle_range_deg,
            test.angle_deg,
            test.angle_deg + test.angle_range_deg,
        ]
    )
    q = np.tile(base, (3, 1))
    q[:, k] = np.deg2rad(spec.coordinate_sign * angles)
    posture[spec.coordinate + sfx] = float(spec.coordinate_sign * test.angle_deg)
    params = muscle_parameters(model)
    geo = muscle_geometry(model, q)
    force = rigid_tendon_state(params, geo.lengths).max_active_force_along_tendon
    per = spec.direction * geo.moment_arms[:, :, k] * force
    ag = np.where(per > 0.0, per, 0.0).sum(axis=1)
    ant = np.where(per < 0.0, -per, 0.0).sum(axis=1)
    muscles = tuple(params.names[i] for i in np.flatnonzero(per[1] > 0.0))
    lo, hi = float(ag.min()), float(ag.max())
    return ModelTorque((lo, float(ag[1]), hi), float(ant[1]), posture, muscles)


def group_strength(
    trial: IsometricTrial,
    test: IsometricTest,
    *,
    lever: LeverArm | None,
    model: ModelTorque,
    mass_kg: float,
    mvc: Mapping[str, float],
    own_mvc: Mapping[str, float] | None = None,
    own_torque_nm: Mapping[str, tuple[str, float]] | None = None,
    band: LiteratureBand | None = None,
) -> TestStrength:
    """The targeted group's strength from an analysed trial (module docstring): torque,
    per kg, 95 % interval, factor vs the model, status and reason. ``lever`` None for a torque
    export; ``mvc`` each channel's session maximum (:func:`session_mvc`, the target check);
    ``own_mvc`` each channel's plateau in the test that targets it (:func:`agonist_mvc`, the
    antagonist's activation; absent: ``mvc``); ``own_torque_nm`` channel → (test, the
    subject's measured net torque in the test that targets it): the antagonists' maximal
    torque of the co-contraction correction (absent: the scaled model's); ``band`` the
    published band of the action (:func:`literature_band`; ``None``: no plausibility check)."""
    flags = list(trial.flags)
    tc = target_check(trial, test, mvc)
    if tc is not None:
        flags.append(tc)
    if trial.is_torque:
        d, sd_d, src = 1.0, 0.0, "not used: the dynamometer exports torque"
    else:
        if lever is None:
            raise ModelError(f"test {test.name!r}: a force export needs a lever arm")
        d, sd_d, src = lever.value_m, lever.sd_m, lever.source
    net = d * trial.plateau_mean
    # co-contraction
    a = test.antagonist
    co, note = 0.0, "no antagonist channel named: no co-contraction correction"
    if a:
        if a not in trial.emg_plateau:
            note = f"antagonist channel {a} not recorded: no co-contraction correction"
        elif trial.emg_flat.get(a, False):
            note = f"antagonist channel {a} flat: no co-contraction correction"
        elif (ref := (own_mvc if own_mvc is not None else mvc).get(a, 0.0)) <= 0.0:
            note = f"antagonist channel {a} has no MVC of its own: no co-contraction correction"
        elif (act := trial.emg_plateau[a] / ref) > 1.0:
            note = (
                f"antagonist {a} at {100 * act:.0f} % of its own MVC test's plateau (cross-talk "
                "or a submaximal MVC test): no co-contraction correction"
            )
            flags.append(
                _flag(
                    test.name,
                    "cocontraction_above_mvc",
                    act,
                    1.0,
                    f"{test.name}: EMG {a} (antagonist) at {100 * act:.0f} % of its "
                    "own MVC test: co-contraction not corrected",
                )
            )
        elif own_torque_nm is not None and own_torque_nm.get(a, ("", 0.0))[1] > 0.0:
            name, ant = own_torque_nm[a]
            co = act * ant
            note = (
                f"{a} at {100 * act:.0f} % of its own MVC test's plateau × the subject's "
                f"measured {name} torque {ant:.1f} N·m"
            )
        else:
            co = act * model.antagonist_nm
            note = (
                f"{a} at {100 * act:.0f} % of its own MVC test's plateau × the scaled model's "
                f"antagonist torque {model.antagonist_nm:.1f} N·m"
            )
    tau = net + co
    rel = []
    if trial.plateau_mean > 0:
        rel.append(trial.plateau_sd / trial.plateau_mean)
        rel.append(trial.baseline_sd / trial.plateau_mean)
    rel.append(sd_d / d if d > 0 else 0.0)
    if tau > 0:
        rel.append(0.5 * co / tau)
    u = math.sqrt(sum(r * r for r in rel))
    ci = (tau * (1 - _Z95 * u), tau * (1 + _Z95 * u))
    lo_m, mid_m, hi_m = model.agonist_nm
    factor = tau / mid_m if mid_m > 0 else float("nan")
    fci = (ci[0] / hi_m, ci[1] / lo_m) if lo_m > 0 else (float("nan"), float("nan"))
    if band is not None:
        bf = band_check(test.name, ci[1] / mass_kg, tau / mass_kg, band, src)
        if bf is not None:
            flags.append(bf)
    failed = [f for f in flags if f.quantity in CHECKS_FAILING]
    width = (fci[1] - fci[0]) / factor if factor > 0 else float("inf")
    if failed:
        status = Status.NOT_DETERMINED.value
        reason = "; ".join(f.message for f in failed)
    elif not (width <= STRENGTH_CI_REL_WIDTH_MAX):
        status = Status.NOT_DETERMINED.value
        reason = (
            f"{test.name}: the factor's interval [{fci[0]:.2f}, {fci[1]:.2f}] is wider than "
            f"{STRENGTH_CI_REL_WIDTH_MAX:g} × the factor: the lever arm or the plateau is too "
            "uncertain"
        )
    else:
        status = Status.IDENTIFIED.value
        reason = "every check passed"
    return TestStrength(
        test=test.name,
        action=test.action,
        status=status,
        reason=reason,
        torque_nm=float(tau),
        torque_ci_nm=(float(ci[0]), float(ci[1])),
        torque_nm_per_kg=float(tau / mass_kg),
        torque_nm_per_kg_ci=(float(ci[0] / mass_kg), float(ci[1] / mass_kg)),
        measured_net_nm=float(net),
        cocontraction_nm=float(co),
        cocontraction_note=note,
        lever_arm_m=float(d),
        lever_arm_sd_m=float(sd_d),
        lever_arm_source=src,
        model_nm=float(mid_m),
        model_range_nm=(float(lo_m), float(hi_m)),
        factor=float(factor),
        factor_ci=(float(fci[0]), float(fci[1])),
        flags=tuple(flags),
        band_nm_per_kg=(
            (band.low_nm_per_kg, band.high_nm_per_kg) if band else (float("nan"), float("nan"))
        ),
        band_source=band.source if band else "",
    )


def band_check(
    test: str, upper_nm_per_kg: float, nm_per_kg: float, band: LiteratureBand, lever: str
) -> Flag | None:
    """``below_published_band`` when the interval's upper end ``upper_nm_per_kg`` lies below
    the band's lower edge (module docstring); ``None`` otherwise. ``lever`` names the
    lever-arm assumption in the message."""
    if not (upper_nm_per_kg < band.low_nm_per_kg):
        return None
    return _flag(
        test,
        "below_published_band",
        nm_per_kg,
        band.low_nm_per_kg,
        f"{test}: {nm_per_kg:.2f} N·m/kg (interval up to {upper_nm_per_kg:.2f}) is below the "
        f"published band for age, {band.low_nm_per_kg:.2f}–{band.high_nm_per_kg:.2f} N·m/kg "
        f"({band.source}): submaximal effort, strap slip or the lever-arm assumption "
        f"({lever.split(':')[0]}) — or a true weakness; repeat the test before acting on it",
    )
