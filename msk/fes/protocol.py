"""The identification protocol: session data, standard stimulation profiles, synthetic
sessions from known parameters, and :func:`run_protocol` composing the steps of
:mod:`msk.fes.identify` (Benoussaad et al. 2013, §2.3; the implanted-FES identification paper, §IV
for :func:`run_protocol_seed001`).
"""

from __future__ import annotations

import contextlib
import time as _time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from scipy import signal as _sig

from msk.exceptions import IdentificationError, MissingDataError, ModelError
from msk.fes.identify import (
    CrossValidationResult,
    ForceLengthResult,
    GeometryResult,
    IsometricFitResult,
    PendulumResult,
    RecruitmentCurrentResult,
    RecruitmentPWResult,
    SeriesStiffnessResult,
    ShankAnthropometry,
    StaticTorqueResult,
    calcium_gain,
    cross_validate,
    geometry_from_height,
    identify_force_length,
    identify_isometric_transients,
    identify_pendulum_linear,
    identify_pendulum_nonlinear,
    identify_recruitment_current,
    identify_recruitment_pw,
    identify_series_stiffness,
    identify_static_torque,
)
from msk.fes.model import (
    CalciumParams,
    FesSubject,
    KneeParams,
    MuscleParams,
    RecruitmentCurrent,
    RecruitmentPW,
)
from msk.fes.priors import population_priors
from msk.fes.simulate import DT, simulate
from msk.fes.stimulation import StimKind, Stimulation, pulse_train, stimulation_from_profile

__all__ = [
    "TABLE1",
    "DynamicTrial",
    "FesSession",
    "IsometricTrial",
    "PendulumTrial",
    "ProtocolResult",
    "Seed001Result",
    "StaticTrial",
    "fibre_fraction",
    "identification_profile",
    "run_protocol",
    "run_protocol_seed001",
    "synthetic_session",
    "validation_profile",
]

F64 = NDArray[np.float64]

#: Benoussaad et al. 2013, Table 1: height (m) and weight (kg) per subject number.
TABLE1: dict[int, tuple[float, float]] = {
    1: (1.92, 64.0),
    2: (1.75, 85.6),
    3: (1.75, 72.0),
    4: (1.88, 94.0),
    5: (1.80, 65.0),
    6: (1.69, 50.0),
    7: (1.72, 54.0),
    9: (1.91, 62.7),
    10: (1.75, 75.0),
}


@dataclass(frozen=True)
class StaticTrial:
    """Passive static torques (N·m) at angles ``theta_r`` (rad from rest), Benoussaad et al. 2013,
    §2.3.1.2."""

    theta_r: F64
    torque: F64
    columns: tuple[str, ...] = ("theta_r", "torque")


@dataclass(frozen=True)
class PendulumTrial:
    """Free passive response after release: goniometer angle from rest (rad)."""

    time: F64
    theta_r: F64
    columns: tuple[str, ...] = ("time", "theta_r")


@dataclass(frozen=True)
class IsometricTrial:
    """One isometric train at ``knee_angle`` (rad): dynamometer active torque (N·m) vs time."""

    knee_angle: float
    stim: Stimulation
    time: F64
    torque: F64
    columns: tuple[str, ...] = ("time", "torque")

    @property
    def level(self) -> float:
        return float(self.stim.levels.max()) if self.stim.levels.size else 0.0

    def steady_torque(self, window: float = 0.5) -> float:
        """Mean torque over the last ``window`` s of the train (the "steady-state phase" of
        Benoussaad et al. 2013)."""
        t_end = self.stim.end_time + 1e-9
        sel = (self.time >= t_end - window) & (self.time <= t_end)
        if not np.any(sel):
            raise MissingDataError(
                f"isometric trial at {np.rad2deg(self.knee_angle):.0f} deg: no torque samples "
                f"in the steady window [{t_end - window:.2f}, {t_end:.2f}] s"
            )
        return float(np.mean(self.torque[sel]))


@dataclass(frozen=True)
class DynamicTrial:
    """Free shank under stimulation: goniometer angle from rest (rad) and the stimulation."""

    time: F64
    theta_r: F64
    stim: Stimulation
    columns: tuple[str, ...] = ("time", "theta_r")


@dataclass(frozen=True)
class FesSession:
    """Everything the protocol needs for one quadriceps–shank."""

    name: str
    height: float
    body_mass: float
    static: StaticTrial
    pendulum: PendulumTrial
    force_length: tuple[IsometricTrial, ...]
    recruitment: tuple[IsometricTrial, ...]
    identification: DynamicTrial
    validation: DynamicTrial
    frequency_hz: float = 20.0


def fibre_fraction(subject: FesSubject) -> float:
    """``L_c0 / (L_c0 + L_s)``: the muscle/tendon proportion at the optimum (protocol prior)."""
    m = subject.muscle
    return m.L_c0 / (m.L_c0 + m.L_s)


def identification_profile(
    *, kind: StimKind = "pw", level_max: float = 420e-6, frequency_hz: float = 20.0
) -> Stimulation:
    """Dynamic stimulation for the ``k_s`` NLP, shaped after Benoussaad et al. 2013, Fig. 3b (8.5
    s).

    Rest 1 s, ramp to the maximum in 1.5 s, hold 1 s, ramp down in 1 s, rest 1.5 s, a step at
    83 % for 1 s, rest.  (The seed's exact profile is not readable from the OCR text.)
    """
    t = [0, 1, 2.5, 3.5, 4.5, 6.0, 6.0001, 7.0, 7.0001, 8.5]
    r = [0, 0, 1, 1, 0, 0, 0.83, 0.83, 0, 0]
    return stimulation_from_profile(
        np.array(t), level_max * np.array(r), frequency_hz=frequency_hz, kind=kind
    )


def validation_profile(
    *, kind: StimKind = "pw", level_max: float = 420e-6, frequency_hz: float = 20.0
) -> Stimulation:
    """Cross-validation stimulation not used for identification (after Benoussaad et al. 2013, Fig.
    5a, 9.5 s).

    A 2 s plateau at 71 %, a 1.5 s triangle 60 → 100 → 60 %, and a 1 s step at 100 %.
    """
    t = [0, 0.5, 0.5001, 2.5, 2.5001, 4.0, 4.0001, 4.75, 5.5, 5.5001, 7.0, 7.0001, 8.0, 8.0001]
    r = [0, 0, 0.71, 0.71, 0, 0, 0.6, 1.0, 0.6, 0, 0, 1.0, 1.0, 0]
    t.append(9.5)
    r.append(0)
    return stimulation_from_profile(
        np.array(t), level_max * np.array(r), frequency_hz=frequency_hz, kind=kind
    )


def _goniometer(
    subject: FesSubject,
    stim: Stimulation,
    duration: float,
    rng: np.random.Generator,
    angle_noise: float,
    drift_noise: float,
    rate_hz: float,
    x0: F64 | None = None,
) -> tuple[F64, F64]:
    tr = simulate(subject, stim, duration=duration, x0=x0)
    step = round(1 / (rate_hz * DT))
    t = tr.time[::step]
    y = tr.theta_r[::step].copy()
    y += rng.normal(0.0, angle_noise, y.size)
    if drift_noise > 0:
        sos = _sig.butter(2, 0.5, fs=rate_hz, output="sos")
        d = _sig.sosfiltfilt(sos, rng.normal(size=y.size))
        y += drift_noise * d / np.std(d)
    return t, y


def synthetic_session(
    subject: FesSubject,
    *,
    height: float,
    body_mass: float,
    rng: np.random.Generator | None = None,
    torque_noise: float = 0.0,
    angle_noise_deg: float = 0.0,
    isometric_duration: float = 10.0,
    drop_angle_deg: float = 40.0,
    pendulum_duration: float = 8.0,
    frequency_hz: float = 20.0,
    level_max: float = 420e-6,
    force_length_level: float = 300e-6,
    force_length_angles_deg: tuple[float, ...] = (90, 80, 70, 60, 50, 40, 30),
    n_recruitment: int = 13,
    goniometer_rate_hz: float = 100.0,
    torque_rate_hz: float = 500.0,
    drift_noise_deg: float = 0.0,
) -> FesSession:
    """Simulate Benoussaad et al.'s (2013) protocol on ``subject`` (known truth) with optional
    noise.

    Static torques every 5° from rest to full extension, a pendulum drop from
    ``drop_angle_deg``, 7 isometric trains at ``force_length_level`` (300 µs), ``n_recruitment``
    trains from 0 to ``level_max`` (420 µs) at the angle of largest force, and the
    identification / cross-validation profiles.  Noise: Gaussian, ``torque_noise`` × the
    trial's peak torque and ``angle_noise_deg`` on the goniometer; ``drift_noise_deg`` adds a
    0.5 Hz band-limited goniometer error (unmodelled slow effects).

    ``isometric_duration`` defaults to 10 s, not the seed's 1.5 s: with Table 3's ``K_cm/k_s``
    the model's isometric force reaches only 63–100 % of its steady state after 1.5 s (force
    rise rate ≈ ``u k_s/(k_s + K_c)``), which a steady-state method cannot use.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    kind: StimKind = "current" if isinstance(subject.recruitment, RecruitmentCurrent) else "pw"
    k = subject.knee
    th_s = np.deg2rad(np.arange(0.0, 90.0 + 1e-9, 5.0))
    tq_s = k.K * np.sin(th_s) + k.K_e * th_s
    tq_s = tq_s + rng.normal(0.0, torque_noise * np.max(np.abs(tq_s)), tq_s.size)
    static = StaticTrial(th_s, tq_s)

    a_noise = np.deg2rad(angle_noise_deg)
    d_noise = np.deg2rad(drift_noise_deg)
    x0 = np.array([np.deg2rad(drop_angle_deg), 0.0, 0.0, 0.0])
    empty = Stimulation(np.zeros(0), np.zeros(0), kind)
    tp, yp = _goniometer(
        subject, empty, pendulum_duration, rng, a_noise, d_noise, goniometer_rate_hz, x0
    )
    pendulum = PendulumTrial(tp, yp)

    t_pad = 0.5

    def iso(angle: float, level: float) -> IsometricTrial:
        st = pulse_train(
            level, duration=isometric_duration, frequency_hz=frequency_hz, t_start=t_pad, kind=kind
        )
        tr = simulate(subject, st, duration=isometric_duration + 2 * t_pad, isometric_angle=angle)
        step = max(1, round(1 / (torque_rate_hz * DT)))
        tq = tr.torque[::step].copy()
        tq += rng.normal(0.0, torque_noise * max(np.max(np.abs(tq)), 1e-9), tq.size)
        return IsometricTrial(angle, st, tr.time[::step], tq)

    fl_trials = tuple(iso(np.deg2rad(a), force_length_level) for a in force_length_angles_deg)
    best = max(fl_trials, key=lambda tr: tr.steady_torque())
    levels = np.linspace(0.0, level_max, n_recruitment)
    rec_trials = tuple(iso(best.knee_angle, lv) for lv in levels)

    def dyn(st: Stimulation) -> DynamicTrial:
        t, y = _goniometer(
            subject, st, st.end_time + 1.0, rng, a_noise, d_noise, goniometer_rate_hz
        )
        return DynamicTrial(t, y, st)

    ident = dyn(identification_profile(kind=kind, level_max=level_max, frequency_hz=frequency_hz))
    valid = dyn(validation_profile(kind=kind, level_max=level_max, frequency_hz=frequency_hz))
    return FesSession(
        subject.name,
        height,
        body_mass,
        static,
        pendulum,
        fl_trials,
        rec_trials,
        ident,
        valid,
        frequency_hz,
    )


@dataclass(frozen=True)
class ProtocolResult:
    """All steps of Benoussaad et al.'s (2013) protocol, the identified subject, and timings (s)."""

    subject: FesSubject
    subject_initial: FesSubject
    geometry: GeometryResult
    static: StaticTorqueResult
    pendulum_linear: PendulumResult
    pendulum: PendulumResult
    force_length: ForceLengthResult
    recruitment: RecruitmentPWResult
    series_stiffness: SeriesStiffnessResult
    cross_validation_initial: CrossValidationResult
    cross_validation: CrossValidationResult
    k_s_history: tuple[float, ...]
    series_stiffness_first: SeriesStiffnessResult | None = None
    isometric_fit: IsometricFitResult | None = None
    seconds: dict[str, float] = field(default_factory=dict)
    #: priors used (``fibre_fraction``, ``stiffness_ratio``) and why the passes stopped early
    priors: dict[str, float] = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    def nrmsd_table(self) -> dict[str, float]:
        """Per-step NRMSD (%) in the rows of Benoussaad et al. 2013, Table 2."""
        return {
            "static_torque": self.static.nrmsd,
            "joint_mechanics": self.pendulum.nrmsd,
            "force_length": self.force_length.nrmsd,
            "recruitment": self.recruitment.nrmsd,
            "nlp_ks": self.series_stiffness.nrmsd,
            "cross_validation": self.cross_validation.nrmsd,
        }


@contextlib.contextmanager
def _stage(leg: str, stage: str) -> Iterator[None]:
    """Re-raise a step's typed error as :class:`IdentificationError` naming the leg and stage."""
    try:
        yield
    except (IdentificationError, ModelError) as e:
        raise IdentificationError(f"FES protocol, leg {leg}, {stage}: {e}") from e


def run_protocol(
    session: FesSession,
    *,
    fibre_fraction: float | None = None,
    stiffness_ratio: float | None = None,
    k_s0: float = 5e3,
    outer_iterations: int = 6,
    calcium: CalciumParams | None = None,
    steady_window: float = 0.5,
    isometric_transients: bool = False,
    identify_stiffness_ratio: bool = False,
) -> ProtocolResult:
    """Benoussaad et al.'s (2013) protocol on one quadriceps–shank (PW-modulated stimulation).

    1. geometry from height; 2. ``K`` (static torques); 3. ``J``, ``B`` (pendulum: linear
    estimate, then the direct nonlinear fit with ``K`` fixed); 4. ``b``, ``L_c0`` (force–length,
    ``k_s`` = ∞ in the first pass as in the seed); 5. ``c1–c3``, ``F_cm``, ``K_cm =
    stiffness_ratio F_cm``; 6. ``k_s`` by the NLP of Eq. 8 from ``k_s0`` (literature value);
    7. cross-validation before (``k_s0``, the seed's "before k_s identification") and after.

    The first outer iteration is the seed's protocol. Because the model's series element
    stretches by ``F/k_s`` (several cm at Table 3's forces and stiffnesses), the rigid-tendon
    force–length step is biased (e.g. ``b`` 0.60 instead of 0.39 for S3L); the next iterations
    therefore solve the fixed
    point ``k_s = NLP(steps 4–5 with L_c = L − L_s − F/k_s)`` by secant steps on ``log k_s``
    (``outer_iterations`` passes at most, stop when ``k_s`` moves by < 0.5 %).

    With ``isometric_transients`` each pass ≥ 1 also refits ``F_cm, b, L_c0, c2, c3`` on the
    isometric torque time courses (:func:`~msk.fes.identify.identify_isometric_transients`):
    needed when the trains are too short to reach the steady state (the seed's 1.5 s).

    ``fibre_fraction`` and ``stiffness_ratio`` are priors (the data do not identify them);
    ``None`` takes the means of Benoussaad et al. 2013, Table 3
    (:func:`msk.fes.priors.population_priors`). Every solver failure raises
    :class:`~msk.exceptions.IdentificationError` naming the leg, the stage and the offending values;
    a failure in a refinement pass (≥ 1) instead stops the passes and keeps the last complete one,
    with the reason in ``notes``.

    With ``identify_stiffness_ratio`` (our addition) the NLP of passes ≥ 1 also identifies
    ``K_cm`` (a factor in [0.1, 10] on ``stiffness_ratio · F_cm``) together with ``k_s``, and the
    next pass uses the identified ratio: the prior is then only the starting point.  The
    recovery study (``docs/fes.md``) shows what it changes with population priors.
    """
    secs: dict[str, float] = {}
    t0 = _time.perf_counter()
    if fibre_fraction is None or stiffness_ratio is None:
        pop = population_priors()
        fibre_fraction = pop.fibre_fraction if fibre_fraction is None else fibre_fraction
        stiffness_ratio = pop.stiffness_ratio if stiffness_ratio is None else stiffness_ratio
    ff, ratio = float(fibre_fraction), float(stiffness_ratio)
    ratio_prior = ratio
    if not (0 < ff < 1 and ratio > 0):
        raise IdentificationError(
            f"FES protocol, leg {session.name}: priors fibre_fraction = {ff} (in (0, 1)) and "
            f"stiffness_ratio = {ratio} 1/m (> 0) are not physical"
        )
    notes: list[str] = []
    calcium = calcium or CalciumParams()
    with _stage(session.name, "geometry, static torque and pendulum"):
        geo = geometry_from_height(session.height)
        static = identify_static_torque(session.static.theta_r, session.static.torque)
        pend_lin = identify_pendulum_linear(
            session.pendulum.time, session.pendulum.theta_r, K_eq=static.K
        )
        pend = identify_pendulum_nonlinear(
            session.pendulum.time, session.pendulum.theta_r, K=static.K, init=pend_lin
        )
    secs["passive"] = _time.perf_counter() - t0

    fl_angles = np.array([tr.knee_angle for tr in session.force_length])
    fl_force = np.array([tr.steady_torque(steady_window) for tr in session.force_length]) / geo.r_q
    rec_levels = np.array([tr.level for tr in session.recruitment])
    rec_force = np.array([tr.steady_torque(steady_window) for tr in session.recruitment]) / geo.r_q
    rec_angle = session.recruitment[0].knee_angle

    knee = KneeParams(J=pend.J, B=pend.B, K=static.K)

    def initial_phase(k_s: float, k_fl: float) -> tuple[FesSubject, ForceLengthResult, Any]:
        fl = identify_force_length(
            fl_angles, fl_force, geometry=geo.geometry, fibre_fraction=ff, k_s=k_fl
        )
        muscle = MuscleParams(F_cm=1.0, K_cm=ratio, L_c0=fl.L_c0, b=fl.b, k_s=k_s, L_s=fl.L_s)
        subj = FesSubject(
            session.name, geo.geometry, knee, muscle, RecruitmentPW(1.0, 5.0, 0.5), calcium
        )
        rec = identify_recruitment_pw(
            rec_levels,
            rec_force,
            knee_angle=rec_angle,
            subject=subj.with_muscle(k_s=k_fl),
            frequency_hz=session.frequency_hz,
            stiffness_ratio=ratio,
        )
        subj = subj.with_muscle(F_cm=rec.F_cm, K_cm=rec.K_cm).with_recruitment(rec.recruitment)
        return subj, fl, rec

    d = session.identification
    v = session.validation
    # the first outer iteration: the seed's protocol (rigid tendon in the force–length step, k_s0
    # from literature)
    t1 = _time.perf_counter()
    with _stage(session.name, "pass 0 (Benoussaad et al. 2013 protocol)"):
        subj_initial, fl, rec = initial_phase(k_s0, np.inf)
        cv0 = cross_validate(v.time, v.theta_r, v.stim, subj_initial)
        ks = identify_series_stiffness(d.time, d.theta_r, d.stim, subj_initial, k_s0=k_s0)
    ks_first = ks
    secs["pass_0"] = _time.perf_counter() - t1
    history = [float(k_s0), ks.k_s]
    # passes 1…: fixed point k_s = NLP(initial_phase(k_s)), secant steps on log k_s
    pts: list[tuple[float, float]] = []
    iso_fit = None
    k = ks.k_s
    subj = subj_initial.with_muscle(k_s=k)
    for it in range(1, outer_iterations):
        t1 = _time.perf_counter()
        try:
            with _stage(session.name, f"pass {it} (k_s = {k:.4g} N/m)"):
                if isometric_transients:
                    # warm start from the previous iteration (the first: the seed's steady-state
                    # values)
                    subj_k, fl_k, rec_k = subj.with_muscle(k_s=k), fl, rec
                    iso_k = identify_isometric_transients(
                        (*session.force_length, *session.recruitment),
                        subj_k,
                        fibre_fraction=ff,
                        stiffness_ratio=ratio,
                    )
                    subj_k = (
                        subj_k.with_muscle(F_cm=iso_k.F_cm, K_cm=iso_k.K_cm, b=iso_k.b)
                        .with_muscle(L_c0=iso_k.L_c0, L_s=iso_k.L_s)
                        .with_recruitment(iso_k.recruitment)
                    )
                else:
                    subj_k, fl_k, rec_k = initial_phase(k, k)
                ks_k = identify_series_stiffness(
                    d.time, d.theta_r, d.stim, subj_k, k_s0=k, free_K_cm=identify_stiffness_ratio
                )
        except IdentificationError as e:
            notes.append(f"passes stopped, pass {it - 1} kept: {e}")
            break
        secs[f"pass_{it}"] = _time.perf_counter() - t1
        if isometric_transients:
            iso_fit = iso_k
        subj, fl, rec, ks = subj_k.with_muscle(k_s=ks_k.k_s, K_cm=ks_k.K_cm), fl_k, rec_k, ks_k
        history.append(ks_k.k_s)
        h = np.log(ks_k.k_s / k)
        moved = 0.0
        if identify_stiffness_ratio:
            new_ratio = ks_k.K_cm / subj_k.muscle.F_cm
            moved, ratio = abs(np.log(new_ratio / ratio)), new_ratio
        if abs(h) < 5e-3 and moved < 5e-3:
            break
        pts.append((np.log(k), h))
        x1, h1 = pts[-1]
        xn = x1 + h1  # plain fixed-point step: log k ← log NLP(k)
        if len(pts) >= 2:
            x0, h0 = pts[-2]
            slope = (h1 - h0) / (x1 - x0) if x1 != x0 else 0.0
            if slope < -1e-3:  # secant on h(log k) = 0, at most 3 fixed-point steps long
                xn = x1 + float(np.clip(-h1 / slope, -3 * abs(h1), 3 * abs(h1)))
        k = float(np.exp(xn))
    with _stage(session.name, "cross-validation"):
        cv = cross_validate(v.time, v.theta_r, v.stim, subj)
    secs["total"] = _time.perf_counter() - t0
    return ProtocolResult(
        subj,
        subj_initial,
        geo,
        static,
        pend_lin,
        pend,
        fl,
        rec,
        ks,
        cv0,
        cv,
        tuple(history),
        ks_first,
        iso_fit,
        secs,
        {"fibre_fraction": ff, "stiffness_ratio": ratio_prior},
        tuple(notes),
    )


@dataclass(frozen=True)
class Seed001Result:
    """The implanted-FES identification paper's protocol (Table I rows): anthropometry, geometry,
    pendulum, force–length, recruitment from dynamic data, cross-validation; NRMSE as the seed
    reports it."""

    subject: FesSubject
    anthropometry: ShankAnthropometry
    geometry: GeometryResult
    pendulum_linear: PendulumResult
    pendulum: PendulumResult
    force_length: ForceLengthResult
    recruitment: RecruitmentCurrentResult
    cross_validation: CrossValidationResult


def run_protocol_seed001(
    session: FesSession,
    *,
    anthropometry: ShankAnthropometry,
    fibre_fraction: float,
    stiffness_ratio: float,
    k_s: float,
    recruitment_init: RecruitmentCurrent,
    calcium: CalciumParams,
    contractile: Literal["000", "001"] = "001",
) -> Seed001Result:
    """The implanted-FES identification paper, §IV: ``J`` and ``M_s g L_og`` from anthropometry,
    pendulum → ``K_eq``, ``F_v`` (``K_e = K_eq − M_s g L_og``), force–length at maximal stimulation
    (``F_max`` read as ``α = 1``: the implanted-FES identification paper's ``D_r`` absorbs the
    scale), recruitment ``α(I)`` from the first part of the dynamic data, cross-validation on the
    second part.  ``k_s`` and ``K_max`` are literature values in the seed (``K_cm = stiffness_ratio
    F_cm``).

    The model is the implanted-FES identification paper's own contractile element (its Eq. 3,
    force–length on the whole muscle length, Eq. 5–6; ``contractile = "001"``, the default) — the
    force–length step then fits Eq. 5 on ``L_q`` directly (rigid series element) — or Benoussaad et
    al.'s (2013) (``"000"``).
    """
    geo = geometry_from_height(session.height)
    k_g = anthropometry.gravity_stiffness
    p = session.pendulum
    pend_lin = identify_pendulum_linear(p.time, p.theta_r, J=anthropometry.J)
    pend = identify_pendulum_nonlinear(p.time, p.theta_r, K=k_g, J=anthropometry.J, init=pend_lin)
    knee = KneeParams(J=anthropometry.J, B=pend.B, K=k_g, K_e=pend.K_eq - k_g)
    fl_angles = np.array([tr.knee_angle for tr in session.force_length])
    fl_force = np.array([tr.steady_torque() for tr in session.force_length]) / geo.r_q
    fl = identify_force_length(
        fl_angles,
        fl_force,
        geometry=geo.geometry,
        fibre_fraction=fibre_fraction,
        k_s=np.inf if contractile == "001" else k_s,
    )
    f_max = fl.F_peak / calcium_gain(calcium, session.frequency_hz)
    muscle = MuscleParams(f_max, stiffness_ratio * f_max, fl.L_c0, fl.b, k_s, fl.L_s)
    subj = FesSubject(
        session.name, geo.geometry, knee, muscle, recruitment_init, calcium, contractile
    )
    d = session.identification
    rec = identify_recruitment_current(d.time, d.theta_r, d.stim, subj)
    subj = subj.with_recruitment(rec.recruitment)
    v = session.validation
    cv = cross_validate(v.time, v.theta_r, v.stim, subj)
    return Seed001Result(subj, anthropometry, geo, pend_lin, pend, fl, rec, cv)
