"""A synthetic leg with known muscle strengths, for tests and benchmarks of :mod:`msk.strength`.

15 muscles over 3 sagittal coordinates (hip flexion, knee flexion, ankle dorsiflexion; positive
moment = positive coordinate direction), grouped into 6 synergist groups, one EMG electrode per
group (Hayashibe et al. 2011, §V: synergists share one activity level). Moment arms vary smoothly
with the angle they act on, ``r(θ) = r0 (1 + c sin(θ + φ))`` with random ``c ∈ [0.1, 0.3]`` and
``φ``; the musculotendon length is its integral ``l(θ) = l0 − r0 θ + r0 c cos(θ + φ)`` so that
``J = ∂l/∂θ = −r`` exactly (Hayashibe et al. 2011, Eq. 6). Generic parameters come from the
EMG-driven vs OpenSim thesis Tables 4.2–4.3 (F_iso, l_opt, l_ts of RF, VM, VI, VL, BFLH, BFSH, SM,
ST, MG, LG, Sol, TA) plus an iliopsoas (iliacus + psoas) and a gluteus maximus.

The motion is a gait-like cycle (≈1 s, 100 Hz) with cycle-to-cycle variability of duration,
amplitude and burst timing. Each group's excitation ``e(t)`` is a sum of phase-locked bursts; the
true activation is the EMG-driven vs OpenSim thesis, Eq. 1–6 filter of ``e`` and the exponential
nonlinearity (Lloyd & Besier 2003; ``form="exponential"``) with a known electromechanical delay;
the **recorded** EMG envelope is ``e (1 + σ_m η_m) + σ_a η_a`` (η: unit-variance Gaussian noise
low-passed at 5 Hz — multiplicative envelope noise and additive baseline noise), clipped to
[0, 1]. Joint torques are ``τ = −Jᵀ f + d + noise`` with the true strengths.

:func:`calibration_trial` turns a gait trial into the EMG-driven vs OpenSim thesis calibration trial
of the knee and ankle muscles whose moments come from known EMG-driven parameters
(:func:`calibration_truth`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy.signal import butter, sosfiltfilt

from msk.muscles.activation import emg_to_activation
from msk.muscles.hill import MuscleParameters, RigidTendonState, rigid_tendon_state
from msk.strength.calibration import CalibrationParameters, CalibrationTrial, emg_driven_forces
from msk.units import Array

__all__ = [
    "CALIBRATION_GROUPS",
    "CALIBRATION_TRUE_FACTORS",
    "LEG_COORDINATES",
    "LEG_GROUPS",
    "LEG_TRUE_FACTORS",
    "SyntheticLeg",
    "SyntheticLegTrial",
    "calibration_trial",
    "calibration_truth",
    "concatenate_trials",
    "gait_trial",
    "mvc_trials",
    "synthetic_leg",
]

#: Coordinates of the synthetic leg.
LEG_COORDINATES: tuple[str, ...] = ("hip_flexion", "knee_flexion", "ankle_dorsiflexion")

# name: (F_iso N, l_opt m, l_ts m, pennation rad, {coordinate index: r0 in m})
_MUSCLES: dict[str, tuple[float, float, float, float, dict[int, float]]] = {
    "ILPSO": (2400.0, 0.100, 0.160, 0.14, {0: 0.030}),
    "GMAX": (1800.0, 0.140, 0.125, 0.09, {0: -0.055}),
    "RF": (1169.0, 0.109, 0.296, 0.09, {0: 0.035, 1: -0.045}),
    "VL": (1871.0, 0.080, 0.149, 0.09, {1: -0.042}),
    "VM": (1294.0, 0.084, 0.119, 0.09, {1: -0.044}),
    "VI": (1365.0, 0.082, 0.128, 0.05, {1: -0.043}),
    "BFLH": (896.0, 0.077, 0.385, 0.0, {0: -0.060, 1: 0.030}),
    "SM": (1288.0, 0.061, 0.294, 0.26, {0: -0.058, 1: 0.035}),
    "ST": (410.0, 0.132, 0.238, 0.09, {0: -0.055, 1: 0.040}),
    "BFSH": (804.0, 0.101, 0.305, 0.40, {1: 0.028}),
    "MG": (1558.0, 0.072, 0.364, 0.30, {1: 0.020, 2: -0.050}),
    "LG": (683.0, 0.064, 0.296, 0.14, {1: 0.020, 2: -0.048}),
    "SOL": (3549.0, 0.088, 0.297, 0.44, {2: -0.048}),
    "TA": (905.0, 0.098, 0.223, 0.09, {2: 0.040}),
    "EDL": (512.0, 0.102, 0.345, 0.18, {2: 0.035}),
}

#: Synergist groups of the synthetic leg (one electrode each).
LEG_GROUPS: dict[str, tuple[str, ...]] = {
    "hip_flexors": ("ILPSO",),
    "hip_extensors": ("GMAX",),
    "knee_extensors": ("RF", "VL", "VM", "VI"),
    "knee_flexors": ("BFLH", "SM", "ST", "BFSH"),
    "plantar_flexors": ("MG", "LG", "SOL"),
    "dorsiflexors": ("TA", "EDL"),
}

#: True strength factors of the synthetic subject (``×`` generic F_iso).
LEG_TRUE_FACTORS: dict[str, float] = {
    "hip_flexors": 1.0,
    "hip_extensors": 1.0,
    "knee_extensors": 1.7,
    "knee_flexors": 1.0,
    "plantar_flexors": 0.6,
    "dorsiflexors": 1.0,
}

# group excitation bursts: (phase centre, width, amplitude)
_BURSTS: dict[str, tuple[tuple[float, float, float], ...]] = {
    "hip_flexors": ((0.62, 0.08, 0.75),),
    "hip_extensors": ((0.05, 0.07, 0.45), (0.95, 0.05, 0.25)),
    "knee_extensors": ((0.10, 0.07, 0.55), (0.92, 0.05, 0.25)),
    "knee_flexors": ((0.02, 0.06, 0.45), (0.85, 0.06, 0.55)),
    "plantar_flexors": ((0.42, 0.09, 0.80),),
    "dorsiflexors": ((0.04, 0.06, 0.7), (0.72, 0.08, 0.6)),
}


@dataclass(frozen=True)
class SyntheticLegTrial:
    """One synthetic trial (time on axis 0, SI; muscles in :attr:`params` order).

    ``emg`` is the recorded (noisy) envelope per muscle (the group's electrode copied to each
    member), ``excitation_true`` the noise-free one; ``activation_true`` = the EMG-driven vs OpenSim
    thesis filter of ``excitation_true``. ``tau`` ``(N, 3)`` are the "inverse-dynamics" torques
    (with noise and the constant residual ``offset``); ``tau_true`` without noise. ``cycle`` labels
    frames by cycle.
    """

    time: Array
    q: Array
    qdot: Array
    muscle_tendon_length: Array
    lengthening_velocity: Array
    jacobian: Array
    emg: Array
    excitation_true: Array
    activation_true: Array
    forces_true: Array
    tau: Array
    tau_true: Array
    offset: Array
    cycle: NDArray[np.int64]
    params: MuscleParameters
    coordinate_names: tuple[str, ...] = LEG_COORDINATES
    #: per frame, the movement the frame's window repeats (0: gait; MVC trials: one label per
    #: action, see :func:`mvc_trials`) — the ``movements`` of
    #: :meth:`msk.strength.StrengthIdentifier.fit`
    movement: NDArray[np.int64] | None = None

    @property
    def rate_hz(self) -> float:
        return float(1.0 / (self.time[1] - self.time[0]))


@dataclass(frozen=True)
class SyntheticLeg:
    """Geometry of the synthetic leg (fixed per seed): generic parameters and moment-arm laws."""

    params: MuscleParameters
    groups: dict[str, tuple[str, ...]]
    r0: Array  #: (M, 3) moment arms at the reference, m
    c: Array  #: (M, 3) relative modulation
    phi: Array  #: (M, 3) phase, rad
    l0: Array  #: (M,) musculotendon length at θ = 0

    @property
    def muscle_names(self) -> tuple[str, ...]:
        return self.params.names

    def lengths(self, q: Array) -> tuple[Array, Array]:
        """``l(θ)`` (N, M) and ``J = ∂l/∂θ`` (N, M, 3)."""
        th = q[:, None, :]
        ell = self.l0[None] + np.sum(
            -self.r0 * th + self.r0 * self.c * np.cos(th + self.phi), axis=2
        )
        jac = -self.r0 * (1.0 + self.c * np.sin(th + self.phi))
        return ell, jac

    def group_matrix(self) -> Array:
        """(G, M) 0/1 membership matrix in :attr:`groups` order."""
        names = self.muscle_names
        out = np.zeros((len(self.groups), len(names)))
        for g, members in enumerate(self.groups.values()):
            for m in members:
                out[g, names.index(m)] = 1.0
        return out


def synthetic_leg(seed: int = 0) -> SyntheticLeg:
    """The synthetic leg's geometry (random but realistic moment-arm variations)."""
    rng = np.random.default_rng(seed)
    names = tuple(_MUSCLES)
    m = len(names)
    r0 = np.zeros((m, 3))
    for i, n in enumerate(names):
        for j, r in _MUSCLES[n][4].items():
            r0[i, j] = r * rng.uniform(0.9, 1.1)
    c = np.where(r0 != 0, rng.uniform(0.1, 0.3, (m, 3)), 0.0)
    phi = rng.uniform(0, 2 * np.pi, (m, 3))
    fiso = np.array([_MUSCLES[n][0] for n in names])
    lopt = np.array([_MUSCLES[n][1] for n in names])
    lts = np.array([_MUSCLES[n][2] for n in names])
    pen = np.array([_MUSCLES[n][3] for n in names])
    params = MuscleParameters(names, fiso, lopt, lts, pen, np.full(m, 10.0))
    leg = SyntheticLeg(params, dict(LEG_GROUPS), r0, c, phi, np.zeros(m))
    # l0 such that the fibre is at l̃ ≈ U(0.85, 0.95) at the mean posture of the gait cycle
    # (a rigid tendon makes the fibre take the whole excursion: keep l̃ within ≈ [0.6, 1.35])
    qmean = np.array([[0.15, 0.35, 0.0]])
    ell, _ = leg.lengths(qmean)
    target = lts + lopt * rng.uniform(0.85, 0.95, m) * np.cos(pen)
    return SyntheticLeg(params, dict(LEG_GROUPS), r0, c, phi, target - ell[0])


def _smooth_noise(rng: np.random.Generator, shape: tuple[int, ...], rate_hz: float) -> Array:
    """Unit-variance Gaussian noise low-passed at 5 Hz (zero-lag)."""
    sos = butter(2, 5.0 / (rate_hz / 2), output="sos")
    x = sosfiltfilt(sos, rng.standard_normal(shape), axis=0)
    return x / np.std(x, axis=0, keepdims=True)


def _bump(ph: Array, centre: float, width: float) -> Array:
    d = (ph - centre + 0.5) % 1.0 - 0.5
    return np.exp(-0.5 * (d / width) ** 2)


def gait_trial(
    leg: SyntheticLeg,
    *,
    n_cycles: int = 12,
    rate_hz: float = 100.0,
    factors: dict[str, float] | None = None,
    seed: int = 0,
    emg_mult_noise: float = 0.10,
    emg_add_noise: float = 0.01,
    tau_noise: float = 0.03,
    gamma1: float = -0.5,
    gamma2: float = -0.5,
    shape_factor: float = -1.0,
    delay_s: float = 0.04,
    offset: tuple[float, float, float] = (2.0, -1.5, 1.0),
    force_fn: object | None = None,
    noise_seed: int | None = None,
    silent_groups: Sequence[str] = (),
) -> SyntheticLegTrial:
    """Simulate ``n_cycles`` gait-like cycles of the synthetic subject.

    ``factors`` (group → × generic F_iso) default to :data:`LEG_TRUE_FACTORS`. Noise levels:
    ``emg_mult_noise`` (relative, σ_m), ``emg_add_noise`` (absolute, σ_a, envelope units) and
    ``tau_noise`` (× the range of each torque). The true forces are those of the
    Hayashibe et al. 2011 reference force with the rigid-tendon Thelen state, ``f = F_iso (a f_l f_v
    + f_P) cos α`` — or, if ``force_fn(params, activation, lmt, vmt)`` is given, whatever it returns
    (the calibration tests use the EMG-driven vs OpenSim thesis Hill model there). ``seed`` draws
    the motion and the excitations, ``noise_seed`` (default ``seed + 10000``) the noise.
    ``silent_groups`` stay at the baseline excitation (0.03) throughout: the data do not excite
    them.
    """
    rng = np.random.default_rng(seed)
    factors = dict(LEG_TRUE_FACTORS if factors is None else factors)
    qs, phs, cyc = [], [], []
    for k in range(n_cycles):
        dur = rng.uniform(0.9, 1.1)
        n = round(dur * rate_hz)
        ph = np.arange(n) / n
        amp = rng.uniform(0.85, 1.15, 3)
        hip = 0.15 + amp[0] * 0.35 * np.cos(2 * np.pi * ph)
        knee = 0.1 + amp[1] * (0.25 * _bump(ph, 0.15, 0.07) + 1.0 * _bump(ph, 0.72, 0.1))
        ankle = amp[2] * (0.15 * np.sin(2 * np.pi * (ph - 0.1)) - 0.2 * _bump(ph, 0.62, 0.05))
        qs.append(np.column_stack([hip, knee, ankle]))
        phs.append(ph)
        cyc.append(np.full(n, k))
    q = np.concatenate(qs)
    # smooth the cycle joins (the cycles do not close exactly)
    sos = butter(2, 8.0 / (rate_hz / 2), output="sos")
    q = sosfiltfilt(sos, q, axis=0)
    ph = np.concatenate(phs)
    cycle = np.concatenate(cyc)
    g_names = list(leg.groups)
    for gname in silent_groups:
        if gname not in g_names:
            raise ValueError(f"silent_groups: unknown group {gname!r}; have {g_names}")
    # group excitations with cycle-to-cycle variability (a silent group keeps the baseline;
    # its bursts are still drawn so that the other groups' excitations do not change)
    e_group = np.full((q.shape[0], len(g_names)), 0.03)
    for g, gname in enumerate(g_names):
        on = 0.0 if gname in silent_groups else 1.0
        for centre, width, a in _BURSTS[gname]:
            for k in range(n_cycles):
                sel = cycle == k
                c = centre + rng.uniform(-0.03, 0.03)
                e_group[sel, g] += on * a * rng.uniform(0.5, 1.3) * _bump(ph[sel], c, width)
    return _simulate(
        leg,
        q,
        np.clip(e_group, 0.0, 1.0),
        cycle,
        rate_hz=rate_hz,
        factors=factors,
        rng_noise=np.random.default_rng(seed + 10_000 if noise_seed is None else noise_seed),
        emg_mult_noise=emg_mult_noise,
        emg_add_noise=emg_add_noise,
        tau_noise=tau_noise,
        gamma1=gamma1,
        gamma2=gamma2,
        shape_factor=shape_factor,
        delay_s=delay_s,
        offset=offset,
        force_fn=force_fn,
    )


def _simulate(
    leg: SyntheticLeg,
    q: Array,
    e_group: Array,
    cycle: NDArray[np.int64],
    *,
    rate_hz: float,
    factors: Mapping[str, float],
    rng_noise: np.random.Generator,
    emg_mult_noise: float,
    emg_add_noise: float,
    tau_noise: float | Array,
    gamma1: float,
    gamma2: float,
    shape_factor: float,
    delay_s: float,
    offset: tuple[float, float, float],
    force_fn: object | None = None,
    qdot: Array | None = None,
    movement: NDArray[np.int64] | None = None,
    emg_ceiling: float | None = 1.0,
) -> SyntheticLegTrial:
    """Forces, torques and recorded EMG of the motion ``q`` driven by the group excitations
    ``e_group`` (N, G) with the true strengths ``factors``. ``tau_noise`` is × the range of
    each torque (scalar), or the noise standard deviation per coordinate in N·m (array).
    The recorded envelope is clipped to ``[0, emg_ceiling]`` (None: no upper clip — the
    envelope of a maximal hold fluctuates around its mean, above it half of the time)."""
    n_frames = q.shape[0]
    time = np.arange(n_frames) / rate_hz
    if qdot is None:
        qdot = np.gradient(q, 1.0 / rate_hz, axis=0)
    lmt, jac = leg.lengths(q)
    vmt = np.einsum("tmj,tj->tm", jac, qdot)
    names = leg.muscle_names
    gm = leg.group_matrix()
    g_names = list(leg.groups)
    e_true = e_group @ gm
    delay = round(delay_s * rate_hz)
    a_true = emg_to_activation(
        e_true,
        gamma1=gamma1,
        gamma2=gamma2,
        shape_factor=shape_factor,
        delay_samples=delay,
        form="exponential",
    )
    scale = np.ones(len(names))
    for g, gname in enumerate(g_names):
        scale[gm[g] > 0] = factors.get(gname, 1.0)
    p = leg.params
    true_params = MuscleParameters(
        names,
        p.max_isometric_force * scale,
        p.optimal_fiber_length,
        p.tendon_slack_length,
        p.pennation_angle_at_optimal,
        p.max_contraction_velocity,
    )
    if force_fn is None:
        st: RigidTendonState = rigid_tendon_state(true_params, lmt, vmt)
        forces = a_true * st.max_active_force_along_tendon + st.passive_force_along_tendon
    else:
        forces = force_fn(true_params, a_true, lmt, vmt)  # type: ignore[operator]
    tau_true = -np.einsum("tmj,tm->tj", jac, forces) + np.asarray(offset)[None]
    if np.ndim(tau_noise) == 0:
        tau_sd = float(tau_noise) * np.ptp(tau_true, axis=0)
    else:
        tau_sd = np.asarray(tau_noise, dtype=float)
    tau = tau_true + tau_sd * _smooth_noise(rng_noise, tau_true.shape, rate_hz)
    e_obs_group = e_group * (
        1.0 + emg_mult_noise * _smooth_noise(rng_noise, e_group.shape, rate_hz)
    ) + emg_add_noise * _smooth_noise(rng_noise, e_group.shape, rate_hz)
    emg = np.clip(e_obs_group, 0.0, emg_ceiling) @ gm
    return SyntheticLegTrial(
        time=time,
        q=q,
        qdot=qdot,
        muscle_tendon_length=lmt,
        lengthening_velocity=vmt,
        jacobian=jac,
        emg=emg,
        excitation_true=e_true,
        activation_true=a_true,
        forces_true=forces,
        tau=tau,
        tau_true=tau_true,
        offset=np.asarray(offset, dtype=float),
        cycle=cycle.astype(np.int64),
        params=leg.params,
        movement=np.zeros(n_frames, dtype=np.int64) if movement is None else movement,
    )


def mvc_trials(
    leg: SyntheticLeg,
    *,
    seed: int = 0,
    groups: Sequence[str] | None = None,
    repetitions: int = 3,
    rate_hz: float = 100.0,
    factors: Mapping[str, float] | None = None,
    emg_mult_noise: float = 0.10,
    emg_add_noise: float = 0.01,
    tau_noise_nm: float = 3.0,
    effort: tuple[float, float] = (0.7, 0.9),
    delay_s: float = 0.04,
    offset: tuple[float, float, float] = (2.0, -1.5, 1.0),
    first_cycle: int = 0,
    first_movement: int = 1,
    emg_ceiling: float | None = 1.0,
) -> SyntheticLegTrial:
    """Isometric maximal voluntary contractions of the synthetic subject, concatenated.

    The protocol of Hayashibe et al. 2011 (Hayashibe, Venture, Ayusawa & Nakamura, IROS 2011, §VI.A:
    "MVC for the extension and flexion in each joint of lower limbs") with the joint torque
    recorded: for each group of ``groups`` (default: every group, i.e. flexion and extension of hip,
    knee and ankle), ``repetitions`` trials at a posture drawn within the gait range (hip 0–0.3,
    knee 0.3–0.8, ankle −0.1–0.1 rad), each 0.3 s rest, 0.5 s ramp up, 2 s hold at the
    excitation ``effort`` (drawn in that range, on the MVC scale of the gait trials), 0.5 s
    ramp down, 0.3 s rest; the other groups co-contract at 0–10 % of the effort over the
    baseline 0.03. Same EMG noise model as :func:`gait_trial`; torque noise ``tau_noise_nm``
    (N·m, standard deviation, 5 Hz low-passed: a dynamometer's or inverse dynamics' error).

    ``emg_ceiling`` the upper clip of the recorded envelope (None: none — the noise of a
    maximal hold is then symmetric about the MVC level, as in a real recording).

    One window (``cycle``) per trial, numbered from ``first_cycle``; ``movement`` labels the
    action (``first_movement + index in groups``) so that the repetitions of one action are
    averaged together for the instrument (:meth:`msk.strength.StrengthIdentifier.fit`).
    """
    rng = np.random.default_rng(seed + 20_000)
    g_names = list(leg.groups)
    targets = list(g_names if groups is None else groups)
    for gname in targets:
        if gname not in g_names:
            raise ValueError(f"mvc_trials: unknown group {gname!r}; have {g_names}")
    if repetitions < 1:
        raise ValueError(f"mvc_trials: repetitions must be ≥ 1, got {repetitions}")
    rest, ramp, hold = round(0.3 * rate_hz), round(0.5 * rate_hz), round(2.0 * rate_hz)
    shape = np.concatenate(
        [
            np.zeros(rest),
            0.5 - 0.5 * np.cos(np.pi * np.arange(ramp) / ramp),
            np.ones(hold),
            0.5 + 0.5 * np.cos(np.pi * np.arange(ramp) / ramp),
            np.zeros(rest),
        ]
    )
    n = shape.size
    qs, es, cyc, mov = [], [], [], []
    k = first_cycle
    for i, gname in enumerate(targets):
        g = g_names.index(gname)
        for _ in range(repetitions):
            posture = np.array(
                [rng.uniform(0.0, 0.3), rng.uniform(0.3, 0.8), rng.uniform(-0.1, 0.1)]
            )
            level = rng.uniform(*effort)
            e = 0.03 + np.outer(shape, rng.uniform(0.0, 0.1, len(g_names)) * level)
            e[:, g] = 0.03 + (level - 0.03) * shape
            qs.append(np.repeat(posture[None], n, axis=0))
            es.append(e)
            cyc.append(np.full(n, k))
            mov.append(np.full(n, first_movement + i))
            k += 1
    q = np.concatenate(qs)
    return _simulate(
        leg,
        q,
        np.clip(np.concatenate(es), 0.0, 1.0),
        np.concatenate(cyc).astype(np.int64),
        rate_hz=rate_hz,
        factors=dict(LEG_TRUE_FACTORS if factors is None else factors),
        rng_noise=np.random.default_rng(seed + 30_000),
        emg_mult_noise=emg_mult_noise,
        emg_add_noise=emg_add_noise,
        tau_noise=np.full(q.shape[1], tau_noise_nm),
        gamma1=-0.5,
        gamma2=-0.5,
        shape_factor=-1.0,
        delay_s=delay_s,
        offset=offset,
        qdot=np.zeros_like(q),
        movement=np.concatenate(mov).astype(np.int64),
        emg_ceiling=emg_ceiling,
    )


def concatenate_trials(*trials: SyntheticLegTrial) -> SyntheticLegTrial:
    """One trial of several (frames concatenated; windows and movements renumbered so that
    those of different trials stay distinct; time continues)."""
    if not trials:
        raise ValueError("concatenate_trials needs at least one trial")
    cyc, mov = [], []
    c0 = m0 = 0
    for tr in trials:
        c = np.unique(tr.cycle, return_inverse=True)[1]
        mv = tr.movement if tr.movement is not None else np.zeros(tr.cycle.size, np.int64)
        m = np.unique(mv, return_inverse=True)[1]
        cyc.append(c + c0)
        mov.append(m + m0)
        c0 += int(c.max()) + 1
        m0 += int(m.max()) + 1
    cat = {
        f: np.concatenate([getattr(tr, f) for tr in trials])
        for f in (
            "q",
            "qdot",
            "muscle_tendon_length",
            "lengthening_velocity",
            "jacobian",
            "emg",
            "excitation_true",
            "activation_true",
            "forces_true",
            "tau",
            "tau_true",
        )
    }
    dt = float(trials[0].time[1] - trials[0].time[0])
    return SyntheticLegTrial(
        time=np.arange(cat["q"].shape[0], dtype=np.float64) * dt,
        offset=trials[0].offset,
        cycle=np.concatenate(cyc).astype(np.int64),
        params=trials[0].params,
        coordinate_names=trials[0].coordinate_names,
        movement=np.concatenate(mov).astype(np.int64),
        **cat,
    )


#: The knee and ankle muscles of the synthetic leg (13) in the 4 functional groups of the
#: the EMG-driven vs OpenSim thesis calibration tests and benchmark.
CALIBRATION_GROUPS: dict[str, tuple[str, ...]] = {
    "knee_extensors": ("RF", "VL", "VM", "VI"),
    "knee_flexors": ("BFLH", "SM", "ST", "BFSH"),
    "plantar_flexors": ("MG", "LG", "SOL"),
    "dorsiflexors": ("TA", "EDL"),
}

#: True strength factors of :data:`CALIBRATION_GROUPS`, in that order (× generic F_iso).
CALIBRATION_TRUE_FACTORS: tuple[float, ...] = (1.7, 1.0, 0.6, 1.2)


def calibration_truth(seed: int = 1) -> CalibrationParameters:
    """Known parameters (the EMG-driven vs OpenSim thesis) of the :data:`CALIBRATION_GROUPS`
    muscles: strength factors :data:`CALIBRATION_TRUE_FACTORS`, per-muscle scales, activation and
    delay parameters drawn (``seed``) around the generic values, skew 0.12."""
    names = tuple(m for g in CALIBRATION_GROUPS.values() for m in g)
    rng = np.random.default_rng(seed)
    m = len(names)
    return CalibrationParameters(
        tuple(CALIBRATION_GROUPS),
        names,
        np.array(CALIBRATION_TRUE_FACTORS),
        rng.uniform(0.96, 1.04, m),
        rng.uniform(0.9, 1.1, m),
        rng.uniform(-0.8, -0.3, m),
        rng.uniform(-0.8, -0.3, m),
        rng.uniform(0.02, 0.08, m),
        rng.uniform(-2.0, -0.5, m),
        0.12,
    )


def calibration_trial(
    leg: SyntheticLeg,
    truth: CalibrationParameters,
    *,
    seed: int,
    n_cycles: int = 2,
    emg_mult_noise: float = 0.10,
    moment_noise: float = 0.0,
    excitation: Literal["recorded", "true"] = "recorded",
    name: str = "trial",
) -> CalibrationTrial:
    """A knee/ankle trial of ``leg`` (:func:`gait_trial` motion, 100 Hz) for the EMG-driven
    calibration: moments of the EMG-driven vs OpenSim thesis model
    (:func:`~msk.strength.calibration. emg_driven_forces`) with the known parameters ``truth``
    driven by the true excitations.

    ``excitation`` ``"recorded"`` gives the calibration the noisy EMG envelope of
    :func:`gait_trial` (``emg_mult_noise``), ``"true"`` the noise-free one; ``moment_noise`` adds
    white noise of that fraction of each moment's range (drawn from ``seed``).
    """
    names = truth.muscle_names
    base = leg.params.subset(names)
    idx = [leg.muscle_names.index(m) for m in names]
    tr = gait_trial(leg, seed=seed, n_cycles=n_cycles, emg_mult_noise=emg_mult_noise)
    r = -tr.jacobian[:, idx][:, :, 1:]
    clean = CalibrationTrial(
        tr.excitation_true[:, idx],
        tr.muscle_tendon_length[:, idx],
        tr.lengthening_velocity[:, idx],
        r,
        np.zeros((tr.q.shape[0], 2)),
        100.0,
        ("knee", "ankle"),
        name,
    )
    _, f = emg_driven_forces(truth, base, CALIBRATION_GROUPS, clean)
    moments = np.einsum("tmj,tm->tj", r, f)
    if moment_noise > 0:
        rng = np.random.default_rng(seed)
        moments = moments + moment_noise * np.ptp(moments, axis=0) * rng.standard_normal(
            moments.shape
        )
    return CalibrationTrial(
        tr.emg[:, idx] if excitation == "recorded" else clean.excitation,
        clean.muscle_tendon_length,
        clean.lengthening_velocity,
        r,
        moments,
        100.0,
        clean.coordinate_names,
        name,
    )
