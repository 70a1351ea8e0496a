"""The FES-driven quadriceps–shank model of Benoussaad et al. 2013 (and the implanted-FES
identification paper variant).

Knee (Benoussaad et al. 2013, Eq. 5–7, the implanted-FES identification paper, Eq. 1–2), with ``θ``
the knee angle (0 = full extension) and ``θ_r = θ_rest − θ`` the angle from the rest (hanging)
position, positive towards extension::

    L(θ)  = L_ext + r_q θ                                      (000 Eq. 5; 001 Eq. 1)
    T_q   = J θ̈_r + B θ̇_r + K sin θ_r + K_e θ_r               (000 Eq. 6–7; 001 Eq. 2)
    T_q   = r_q F_c

``K sin θ_r`` is Benoussaad et al.'s (2013) lumped static torque (gravity + elasticity, Eq. 7); the
implanted-FES identification paper splits it into gravity ``M_s g L_og sin γ`` (→ ``K = M_s g
L_og``) and a linear elastic torque ``K_e γ`` (``γ = π/2 − θ = θ_r``).  Benoussaad et al. 2013 uses
``K_e = 0``.

Quadriceps under electrical stimulation (Benoussaad et al. 2013, Eq. 1–4 and Appendix Eq. 10–12)::

    α(PW) = c1 / (1 + exp(c2 (c3 − PW/PW_max)))                        (000 Eq. 10)
    α(I)  = D_r (tanh(R − C_r) + tanh(C_r)),  R = B_r (1 + a_I I/I_max) I   (001 Eq. 7)
    u(t)  = Π_c(t) U_c + (1 − Π_c(t)) U_r                              (000 Eq. 11)
    Π_c   = 1 for τ_c after a pulse, then (τ_r − t_r)/τ_r for τ_r, then 0  (000 Eq. 12)
    K̇_c  = −(u + |ε̇_c|) K_c + α K_cm Fl(ε_c) Π_c U_c                  (000 Eq. 1)
    Ḟ_c  = −(u + |ε̇_c|) F_c + α F_cm Fl(ε_c) Π_c U_c + K_c L_c0 ε̇_c
    Fl(ε_c) = exp(−(ε_c/b)²),   ε_c = (L_c − L_c0)/L_c0                 (000 Eq. 2)
    ε̇_c = (k_s L_0 ε̇ + F_c u − α F_cm Fl Π_c U_c)
           / (k_s L_c0 + K_c L_c0 − s_v F_c),  s_v = sign(numerator)     (000 Eq. 3–4)

Interpretations (the OCR'd seed leaves these open; they are ours):

* ``k_s L_0 ε̇`` is ``k_s L̇`` (``ε = (L − L_0)/L_0``), so the rest length ``L_0`` cancels.
* Eq. 3 is the time derivative of the series-element law ``F_c = k_s (L − L_c − L_s)`` with
  Eq. 1 substituted; we therefore compute the CE length algebraically,
  ``L_c = L(θ) − L_s − F_c/k_s``, with ``L_s`` the series-element (tendon) slack length.  This
  makes the state ``(θ_r, θ̇_r, K_c, F_c)``; ``L_s`` is not in Table 3: we derive it from the
  angle of optimal force (Benoussaad et al. 2013, §2.3.1.3: "rest position … position of the maximal
  isometric force") as ``L_s = L(θ_opt) − L_c0``.
* ``sign`` and ``|·|`` are smoothed as ``x/sqrt(x² + δ²)`` (``δ`` tiny) so that the model can
  sit inside an NLP; ε̇_c itself is continuous through the switch.
* In PW/I-modulated trains a pulse of zero width/amplitude is *no* pulse (``Π_c`` not reset):
  Eq. 10 gives ``α(0) = c1/(1+e^{c2 c3}) > 0`` which would otherwise produce force at PW = 0.
* The implanted-FES identification paper uses a fused-tetanus simplification (``u`` constant while
  stimulating).  We keep
  the same Eq. 1–4 model and obtain it with ``τ_c ≥ 1/f`` (``Π_c ≡ 1`` during a train).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import ModelError
from msk.units import G0

__all__ = [
    "GEOMETRY_POLY_FROM_HEIGHT",
    "PARAM_NAMES",
    "SEED001_SUBJECT",
    "SHANK_LENGTH_FRACTION",
    "TABLE2_NRMSD_PCT",
    "TABLE3",
    "CalciumParams",
    "FesSubject",
    "G",
    "GeometryParams",
    "KneeParams",
    "MuscleParams",
    "RecruitmentCurrent",
    "RecruitmentPW",
    "muscle_tendon_length",
    "param_vector",
    "subject_from_vector",
]

G = G0  # m/s²

#: Drillis & Contini segment fraction of stature for the leg (knee to ankle), ``ℓ_s = 0.246 H``.
SHANK_LENGTH_FRACTION = 0.246

#: Normalised quadriceps muscle–tendon length ``L/ℓ_s = Σ p_i θ^i`` (θ in rad, i = 0..5).
#: Benoussaad et al. 2013, §2.3.1.1 uses a fifth-order polynomial from its ref. [22] (Hawkins & Hull
#: 1990) whose coefficients are not in the seed: these coefficients are *ours*, shaped so that the
#: moment arm peaks mid-range, and calibrated so that the least-squares line over 10 angles
#: in [0°, 90°] gives ``L_ext = 0.2355 H`` and ``r_q = 0.02765 H``, i.e. reproduces every
#: ``L_ext``/``r_q`` pair of Benoussaad et al. 2013, Table 3 and of the implanted-FES identification
#: paper, Table I from the heights of Benoussaad et al. 2013, Table 1 (S3 1.75 m → 41.2 cm, 4.84 cm)
#: within rounding.
GEOMETRY_POLY_FROM_HEIGHT: tuple[float, ...] = (
    0.959841,
    0.0894062,
    0.0307723,
    0.00263559,
    -0.0149884,
    0.00381676,
)


@dataclass(frozen=True)
class KneeParams:
    """Passive knee (000 Eq. 6–7; 001 Eq. 2): J kg·m², B N·m·s/rad, K and K_e N·m/rad."""

    J: float
    B: float
    K: float
    K_e: float = 0.0
    theta_rest: float = np.pi / 2

    @property
    def K_eq(self) -> float:
        """Virtual stiffness of the linearised pendulum (001 Eq. 4): ``K_eq = K + K_e``."""
        return self.K + self.K_e

    @property
    def omega_n(self) -> float:
        return float(np.sqrt(self.K_eq / self.J))

    @property
    def zeta(self) -> float:
        return float(self.B / (2 * np.sqrt(self.K_eq * self.J)))


@dataclass(frozen=True)
class GeometryParams:
    """Muscle–tendon length ``L(θ) = L_ext + r_q θ`` (000 Eq. 5), metres."""

    L_ext: float
    r_q: float


@dataclass(frozen=True)
class MuscleParams:
    """Contractile and series elements (000 Eq. 1–4): N, N/m, m."""

    F_cm: float
    K_cm: float
    L_c0: float
    b: float
    k_s: float
    L_s: float


@dataclass(frozen=True)
class CalciumParams:
    """Calcium dynamics (000 Eq. 11–12); the seed's values are common to all subjects."""

    U_c: float = 30.0
    U_r: float = 10.0
    tau_c: float = 0.030
    tau_r: float = 0.020


@dataclass(frozen=True)
class RecruitmentPW:
    """Sigmoid recruitment in pulse width (000 Eq. 10); ``pw_max`` in seconds (420 µs)."""

    c1: float
    c2: float
    c3: float
    pw_max: float = 420e-6
    kind: Literal["pw"] = field(default="pw", init=False)

    def __call__(self, pw: ArrayLike) -> NDArray[np.float64]:
        x = np.asarray(pw, dtype=float) / self.pw_max
        return self.c1 / (1.0 + np.exp(self.c2 * (self.c3 - x)))

    def vector(self) -> tuple[float, float, float, float]:
        return (self.c1, self.c2, self.c3, self.pw_max)


@dataclass(frozen=True)
class RecruitmentCurrent:
    """tanh recruitment in current amplitude (001 Eq. 7).

    ``α(I) = D_r (tanh(R − C_r) + tanh(C_r))``, ``R = B_r (1 + a_I I/I_max) I``.  The implanted-FES
    identification paper gives ``B_r`` for ``I`` in mA (0–3 mA, ``I_max`` = 3 mA, α(3 mA) ≈ 0.92
    with its Table I); inputs here are SI (A) and are converted to mA inside.
    """

    a_I: float
    B_r: float
    C_r: float
    D_r: float
    i_max: float = 3e-3
    kind: Literal["current"] = field(default="current", init=False)

    def __call__(self, current: ArrayLike) -> NDArray[np.float64]:
        i = np.asarray(current, dtype=float)
        r = self.B_r * (1.0 + self.a_I * i / self.i_max) * (i * 1e3)
        return self.D_r * (np.tanh(r - self.C_r) + np.tanh(self.C_r))

    def vector(self) -> tuple[float, float, float, float]:
        return (self.a_I, self.B_r, self.C_r, self.D_r)


Recruitment = RecruitmentPW | RecruitmentCurrent


@dataclass(frozen=True)
class FesSubject:
    """One quadriceps–shank: geometry, knee, muscle, recruitment and calcium parameters."""

    name: str
    geometry: GeometryParams
    knee: KneeParams
    muscle: MuscleParams
    recruitment: Recruitment
    calcium: CalciumParams = CalciumParams()
    #: contractile-element equations: ``"000"`` (Benoussaad et al. 2013, Eq. 1–4) or ``"001"`` (the
    #: implanted-FES identification paper Eq. 3, 5–6; see :func:`msk.fes.simulate.rhs_function`)
    contractile: Literal["000", "001"] = "000"

    def with_knee(self, **kw: float) -> FesSubject:
        return dataclasses.replace(self, knee=dataclasses.replace(self.knee, **kw))

    def with_muscle(self, **kw: float) -> FesSubject:
        return dataclasses.replace(self, muscle=dataclasses.replace(self.muscle, **kw))

    def with_geometry(self, **kw: float) -> FesSubject:
        return dataclasses.replace(self, geometry=dataclasses.replace(self.geometry, **kw))

    def with_recruitment(self, recruitment: Recruitment) -> FesSubject:
        return dataclasses.replace(self, recruitment=recruitment)

    def with_calcium(self, **kw: float) -> FesSubject:
        return dataclasses.replace(self, calcium=dataclasses.replace(self.calcium, **kw))

    def validate(self) -> FesSubject:
        """Raise :class:`ModelError` naming the parameter if a value is not physical."""
        checks = {
            "J": self.knee.J,
            "L_ext": self.geometry.L_ext,
            "r_q": self.geometry.r_q,
            "L_c0": self.muscle.L_c0,
            "b": self.muscle.b,
            "k_s": self.muscle.k_s,
            "F_cm": self.muscle.F_cm,
        }
        for k, v in checks.items():
            if not np.isfinite(v) or v <= 0:
                raise ModelError(f"FES subject {self.name!r}: parameter {k} must be > 0, got {v}")
        if self.knee.B < 0 or self.muscle.K_cm < 0:
            raise ModelError(f"FES subject {self.name!r}: B and K_cm must be >= 0")
        rec = self.recruitment
        if isinstance(rec, RecruitmentCurrent) and abs(rec.i_max - 3e-3) > 1e-12:
            raise ModelError(
                f"FES subject {self.name!r}: the simulator uses the implanted-FES identification "
                "paper's I_max = 3 mA, "
                f"got i_max = {rec.i_max} A"
            )
        return self


def muscle_tendon_length(geometry: GeometryParams, theta: ArrayLike) -> NDArray[np.float64]:
    """``L(θ) = L_ext + r_q θ`` (000 Eq. 5), θ the knee angle from full extension (rad)."""
    return geometry.L_ext + geometry.r_q * np.asarray(theta, dtype=float)


#: Order of the model parameter vector used by the casadi functions (round-trip tested).
PARAM_NAMES: tuple[str, ...] = (
    "J",
    "B",
    "K",
    "K_e",
    "theta_rest",
    "L_ext",
    "r_q",
    "L_s",
    "L_c0",
    "b",
    "F_cm",
    "K_cm",
    "k_s",
    "U_c",
    "U_r",
    "rec0",
    "rec1",
    "rec2",
    "rec3",
)


def param_vector(s: FesSubject) -> NDArray[np.float64]:
    """Flatten ``s`` in :data:`PARAM_NAMES` order (recruitment: its ``vector()``)."""
    k, g, m, c = s.knee, s.geometry, s.muscle, s.calcium
    head = (k.J, k.B, k.K, k.K_e, k.theta_rest, g.L_ext, g.r_q, m.L_s, m.L_c0, m.b, m.F_cm)
    return np.array([*head, m.K_cm, m.k_s, c.U_c, c.U_r, *s.recruitment.vector()], dtype=float)


def subject_from_vector(template: FesSubject, p: ArrayLike) -> FesSubject:
    """Inverse of :func:`param_vector` (τ_c, τ_r, name and recruitment kind from ``template``)."""
    v = dict(zip(PARAM_NAMES, np.asarray(p, dtype=float).tolist()))
    rec: Recruitment
    if isinstance(template.recruitment, RecruitmentPW):
        rec = RecruitmentPW(v["rec0"], v["rec1"], v["rec2"], v["rec3"])
    else:
        rec = RecruitmentCurrent(
            v["rec0"], v["rec1"], v["rec2"], v["rec3"], i_max=template.recruitment.i_max
        )
    return FesSubject(
        name=template.name,
        geometry=GeometryParams(v["L_ext"], v["r_q"]),
        knee=KneeParams(v["J"], v["B"], v["K"], v["K_e"], v["theta_rest"]),
        muscle=MuscleParams(v["F_cm"], v["K_cm"], v["L_c0"], v["b"], v["k_s"], v["L_s"]),
        recruitment=rec,
        calcium=dataclasses.replace(template.calcium, U_c=v["U_c"], U_r=v["U_r"]),
        contractile=template.contractile,
    )


#: Angle of maximal isometric force assumed for the Table 3 subjects (not given in the seed).
THETA_OPT_TABLE3 = np.deg2rad(60.0)


def _table3(
    name: str,
    L_ext_cm: float,
    r_q_cm: float,
    K: float,
    J: float,
    B: float,
    L_c0_cm: float,
    b: float,
    c1: float,
    c2: float,
    c3: float,
    F_cm: float,
    K_cm_N_per_mm: float,
    k_s_N_per_mm: float,
) -> FesSubject:
    geom = GeometryParams(L_ext_cm / 100, r_q_cm / 100)
    L_c0 = L_c0_cm / 100
    L_s = float(muscle_tendon_length(geom, THETA_OPT_TABLE3)) - L_c0
    return FesSubject(
        name=name,
        geometry=geom,
        knee=KneeParams(J=J, B=B, K=K),
        muscle=MuscleParams(
            F_cm=float(F_cm),
            K_cm=K_cm_N_per_mm * 1e3,
            L_c0=L_c0,
            b=b,
            k_s=k_s_N_per_mm * 1e3,
            L_s=L_s,
        ),
        recruitment=RecruitmentPW(c1, c2, c3),
    )


#: Identified parameter sets of Benoussaad et al. 2013, Table 3 (left legs share their subject's
#: geometry, which the table gives once per subject).  S5R has no muscle parameters (Nsf) and is
#: absent. ``L_s`` is derived with an assumed optimal angle of 60° (see module docstring).
TABLE3: dict[str, FesSubject] = {
    s.name: s
    for s in (
        _table3("S3R", 41.2, 4.84, 10.8, 0.28, 0.28, 9.01, 0.38, 0.98, 7.23, 0.38, 523, 500, 2.1),
        _table3("S3L", 41.2, 4.84, 11.1, 0.29, 0.19, 9.07, 0.39, 1.21, 4.60, 0.66, 438, 400, 10),
        _table3("S4R", 44.3, 5.20, 15.7, 0.44, 0.32, 9.55, 0.41, 1.03, 8.75, 0.70, 707, 500, 8),
        _table3("S4L", 44.3, 5.20, 13.8, 0.34, 0.28, 9.72, 0.48, 0.99, 11.4, 0.64, 400, 375, 10),
        _table3("S5L", 42.4, 4.98, 10.6, 0.30, 0.21, 9.16, 0.46, 0.87, 34.8, 0.50, 239, 150, 2.4),
        _table3("S6R", 39.8, 4.67, 6.97, 0.20, 0.14, 8.67, 0.46, 1.04, 6.60, 0.55, 45, 45, 1),
        _table3("S6L", 39.8, 4.67, 6.36, 0.18, 0.12, 8.97, 0.43, 1.03, 6.83, 0.57, 270, 250, 3),
        _table3("S7R", 40.5, 4.76, 8.96, 0.26, 0.24, 8.75, 0.49, 1.12, 4.88, 0.61, 245, 100, 3),
        _table3("S7L", 40.5, 4.76, 8.55, 0.23, 0.23, 8.89, 0.45, 1.20, 5.07, 0.67, 269, 250, 12),
        _table3("S9R", 45.0, 5.28, 13.7, 0.38, 0.44, 9.66, 0.37, 0.99, 7.69, 0.41, 126, 100, 10),
        _table3("S9L", 45.0, 5.28, 11.6, 0.32, 0.34, 9.65, 0.32, 1.37, 5.24, 0.79, 500, 140, 5),
        _table3("S10R", 41.2, 4.84, 10.9, 0.32, 0.18, 9.18, 0.54, 1.15, 8.12, 0.75, 300, 180, 10),
        _table3("S10L", 41.2, 4.84, 10.6, 0.30, 0.19, 9.27, 0.46, 1.15, 18.4, 0.89, 452, 250, 12),
    )
}


#: Benoussaad et al. 2013, Table 2: NRMSD (%) per identification step and leg (S3R, S3L, S4R, S4L,
#: S5R, S5L, S6R, S6L, S7R, S7L, S9R, S9L, S10R, S10L); ``None`` where the seed reports
#: nonsignificant force (Nsf). Rows are the keys of
#: :meth:`msk.fes.protocol.ProtocolResult.nrmsd_table`.
TABLE2_NRMSD_PCT: dict[str, tuple[float | None, ...]] = {
    "static_torque": (
        2.36,
        3.87,
        3.13,
        2.35,
        3.20,
        3.17,
        3.88,
        3.49,
        2.50,
        2.81,
        2.49,
        4.96,
        2.86,
        3.55,
    ),
    "joint_mechanics": (
        2.60,
        3.26,
        3.80,
        2.86,
        3.10,
        3.87,
        3.97,
        3.45,
        3.65,
        5.07,
        4.01,
        3.51,
        2.87,
        3.70,
    ),
    "force_length": (17.3, 3.96, 10.4, 18.9, 35, 21, 5.01, 6.68, 35, 4, 38, 17, 10.8, 3.80),
    "recruitment": (5.93, 1.96, 2.44, 4.94, None, 6.16, 3.92, 2.47, 4.93, 1.2, 3.53, 10.7, 1, 0.18),
    "nlp_ks": (13.7, 4.77, 47.6, 13.6, None, 8.78, 9.34, 19.9, 8.63, 19, 10.5, 4.08, 11.1, 7.9),
    "cross_validation": (
        10.3,
        5.17,
        50.5,
        15.4,
        None,
        13.7,
        9.35,
        6.87,
        17.3,
        13.2,
        9.55,
        19.7,
        12.2,
        None,
    ),
}


def _seed001_subject() -> FesSubject:
    """The implanted-FES identification paper, Table I subject (1.75 m, 66 kg, neural implant,
    current-modulated at 31.25 Hz).

    ``K = M_s g L_og`` and ``K_e`` (Table I), ``F_v`` → ``B``.  The implanted-FES identification
    paper's force–length is in whole muscle–tendon length, ``F_0 = F_max exp(−((L_q/L_opt −
    1)/b_l)²)`` (Eq. 5); with ``L_c = L_q − L_s`` this is Eq. 2 with ``b L_c0 = b_l L_opt`` for any
    split: we take ``L_c0 = 0.09 m`` (Benoussaad et al.'s (2013) mean 9.2 cm), ``L_s = L_opt −
    L_c0`` and ``b = b_l L_opt / L_c0``.  ``K_max = 10⁴`` (Eq. 6, taken by the seed from the
    literature; read as N/m).  ``k_s`` is not identified in the implanted-FES identification paper:
    we use 10 N/mm (Table 3 order). The stimulation is fused (31.25 Hz, u = const), obtained with
    ``τ_c = 1/f``.  Its contractile element is the implanted-FES identification paper's own (Eq. 3,
    force–length on ``L_q``: ``contractile = "001"``).
    """
    M_s, L_og, J = 4.026, 0.194, 0.343
    L_opt, b_l, L_c0 = 0.455, 0.054, 0.09
    return FesSubject(
        name="seed001",
        geometry=GeometryParams(L_ext=0.412, r_q=0.048),
        knee=KneeParams(J=J, B=0.201, K=M_s * 9.8 * L_og, K_e=4.441),
        muscle=MuscleParams(
            F_cm=230.0, K_cm=1e4, L_c0=L_c0, b=b_l * L_opt / L_c0, k_s=1e4, L_s=L_opt - L_c0
        ),
        recruitment=RecruitmentCurrent(a_I=-0.295, B_r=0.593, C_r=-0.994, D_r=4.203),
        calcium=CalciumParams(tau_c=1 / 31.25, tau_r=0.020),
        contractile="001",
    )


SEED001_SUBJECT = _seed001_subject()
