"""Hill-type muscle models: normalised curves, rigid-tendon states and elastic-tendon equilibrium.

Three families of curves are provided, all vectorised over arrays of any shape (typically
``(N frames, M muscles)``):

* **Hayashibe et al. 2011** (reference force, Eq. 9–11)::

      f* = a · f_l(l) · f_v(l̇) · F_iso                                   (Eq. 9)
      f_l(l̃) = exp(−((l̃ − 1)/K)²)                                        (Eq. 10)
      f_v(ṽ) = 0                                        ṽ < −v_max
             = V_sh (v_max + ṽ) / (V_sh v_max − ṽ)       −v_max ≤ ṽ < 0   (Eq. 11)
             = (V_sh V_shl v_max + V_ml ṽ) / (V_sh V_shl v_max + ṽ)   0 ≤ ṽ

  with l̃ = l/l_opt, ṽ = l̇/l_opt the lengthening velocity in optimal lengths per second and
  Stroeve's constants V_sh = 0.3, V_shl = 0.23, V_ml = 1.3. The OCR of Eq. 10 lost the value of
  K: the default ``K = sqrt(0.45)`` makes Eq. 10 coincide with Thelen's Gaussian (width 0.45).

* **the EMG-driven vs OpenSim thesis** (§2.2.2, Lloyd & Besier 2003 / Buchanan 2004), see
  :class:`LloydBesierCurves`: passive ``F̃_P = e^{10(l̃−1)}/e^5`` (Eq. 10), tendon
  ``F̃_t = 0 (ε ≤ 0); 1480.3 ε² (0 < ε < 0.0127); 37.5 ε − 0.2375 (ε ≥ 0.0127)`` (Eq. 15–18),
  Epstein–Herzog force–velocity (Eq. 11–12), damping ``b_m ṽ`` (Eq. 8, 13), activation-dependent
  optimal fibre length ``l_opt(t) = l_opt (λ(1 − a) + 1)`` (Eq. 9) and pennation
  ``φ = asin(l_opt sin φ_0 / l_m)`` (Eq. 14, a parallelogram of constant height). The tendon force
  of Eq. 8 is ``F_t = F_iso [F̃_A(l̃) F̃_V(ṽ) a + F̃_P(l̃) + b_m ṽ] cos φ``.

* **Thelen 2003** exactly as OpenSim 4.x ``Thelen2003Muscle`` evaluates it (``calcfal``,
  ``calcfpe``, ``calcfse``, ``calcdlceN`` and its inverse), see :class:`Thelen2003Curves`.

Rigid tendon (what OpenSim's static optimisation uses with ``use_muscle_physiology``, via
``Muscle::calcInextensibleTendonActiveFiberForce``): the tendon stays at its slack length, the
fibre of constant-height pennation has length ``l_f = sqrt(h² + (l_MT − l_TS)²)``,
``h = l_opt sin α_0``, so ``cos α = (l_MT − l_TS)/l_f`` and ``l̇_f = l̇_MT cos α``; the maximal
active force along the tendon is ``F_iso f_l(l̃_f) f_v(ṽ_f) cos α`` (with activation 1 inside
f_v, as OpenSim does).

Elastic tendon: :func:`equilibrium` solves the static force balance
``F_iso (a f_l + f_PE) cos α = F_iso f_T(ε_T)`` per frame and muscle with a vectorised, bracketed
Newton iteration (OpenSim ``Thelen2003Muscle::initMuscleState`` with zero velocity).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import FileFormatError, MuscleModelError
from msk.timeseries import FrameAxis
from msk.units import Array

__all__ = [
    "MAX_PENNATION_ANGLE",
    "MUSCLE_PARAMETER_ORDER",
    "CurveSet",
    "EquilibriumState",
    "LloydBesierCurves",
    "MuscleParameters",
    "RigidTendonFrame",
    "RigidTendonState",
    "RigidTendonStateBlocks",
    "Thelen2003Curves",
    "equilibrium",
    "fl_gaussian",
    "fv_stroeve",
    "pennation_constant_height",
    "reference_force",
    "rigid_tendon_state",
]

#: Column order of :meth:`MuscleParameters.to_array` (checked by a round-trip test).
MUSCLE_PARAMETER_ORDER: tuple[str, ...] = (
    "max_isometric_force",
    "optimal_fiber_length",
    "tendon_slack_length",
    "pennation_angle_at_optimal",
    "max_contraction_velocity",
)

#: OpenSim's default maximum pennation angle (``acos(0.1)``) used to clamp the fibre length.
MAX_PENNATION_ANGLE = float(np.arccos(0.1))


# ---------------------------------------------------------------------------------------------
# Parameters
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class MuscleParameters:
    """Muscle–tendon parameters, one entry per muscle (SI: N, m, rad; v_max in l_opt/s)."""

    names: tuple[str, ...]
    max_isometric_force: Array
    optimal_fiber_length: Array
    tendon_slack_length: Array
    pennation_angle_at_optimal: Array
    max_contraction_velocity: Array = field(default_factory=lambda: np.empty(0))

    def __post_init__(self) -> None:
        m = len(self.names)
        object.__setattr__(self, "names", tuple(str(n) for n in self.names))
        if len(set(self.names)) != m:
            dup = sorted({n for n in self.names if self.names.count(n) > 1})
            raise MuscleModelError(f"duplicate muscle names: {dup}")
        vmax = self.max_contraction_velocity
        if np.size(vmax) == 0:
            object.__setattr__(self, "max_contraction_velocity", np.full(m, 10.0))
        for key in MUSCLE_PARAMETER_ORDER:
            v = np.broadcast_to(np.asarray(getattr(self, key), dtype=float), (m,)).copy()
            v.setflags(write=False)
            object.__setattr__(self, key, v)
        for key in (
            "max_isometric_force",
            "optimal_fiber_length",
            "tendon_slack_length",
            "max_contraction_velocity",
        ):
            v = getattr(self, key)
            bad = ~(np.isfinite(v) & (v > 0))
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise MuscleModelError(f"muscle {self.names[i]!r}: {key} must be > 0, got {v[i]}")
        pen = self.pennation_angle_at_optimal
        bad = ~((pen >= 0) & (pen < np.pi / 2))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise MuscleModelError(
                f"muscle {self.names[i]!r}: pennation_angle_at_optimal must be in [0, pi/2) rad, "
                f"got {pen[i]}"
            )

    @property
    def n_muscles(self) -> int:
        return len(self.names)

    def to_array(self) -> Array:
        """``(M, 5)`` array with columns in :data:`MUSCLE_PARAMETER_ORDER`."""
        return np.column_stack([getattr(self, k) for k in MUSCLE_PARAMETER_ORDER])

    @classmethod
    def from_array(cls, names: tuple[str, ...] | list[str], values: ArrayLike) -> MuscleParameters:
        v = np.asarray(values, dtype=float)
        if v.ndim != 2 or v.shape != (len(names), len(MUSCLE_PARAMETER_ORDER)):
            raise MuscleModelError(
                f"parameter array must be ({len(names)}, {len(MUSCLE_PARAMETER_ORDER)}), "
                f"got {v.shape}"
            )
        return cls(tuple(names), *(v[:, j] for j in range(v.shape[1])))

    def subset(self, names: list[str] | tuple[str, ...]) -> MuscleParameters:
        """The parameters of ``names``, in that order."""
        idx = []
        for n in names:
            if n not in self.names:
                raise MuscleModelError(f"unknown muscle {n!r}")
            idx.append(self.names.index(n))
        return MuscleParameters.from_array(tuple(names), self.to_array()[idx])

    @classmethod
    def from_csv(
        cls, path: str | Path, *, max_contraction_velocity: float = 10.0
    ) -> MuscleParameters:
        """Read a muscle table (columns ``muscle, max_isometric_force_N, optimal_fiber_length_m,
        tendon_slack_length_m, pennation_angle_at_optimal_rad``), as extracted from ``.osim``."""
        path = Path(path)
        cols = (
            "max_isometric_force_N",
            "optimal_fiber_length_m",
            "tendon_slack_length_m",
            "pennation_angle_at_optimal_rad",
        )
        try:
            with path.open(newline="") as fh:
                rows = list(csv.DictReader(fh))
            names = tuple(r["muscle"] for r in rows)
            vals = np.array([[float(r[c]) for c in cols] for r in rows])
        except (OSError, KeyError, ValueError) as exc:
            raise FileFormatError(f"{path}: cannot read muscle table ({exc})") from exc
        vmax = np.full(len(names), max_contraction_velocity)
        return cls(names, vals[:, 0], vals[:, 1], vals[:, 2], vals[:, 3], vmax)


# ---------------------------------------------------------------------------------------------
# Curves
# ---------------------------------------------------------------------------------------------
class CurveSet(Protocol):
    """Normalised curves used by :func:`equilibrium` (value and derivative)."""

    def active_force_length(self, l_norm: ArrayLike) -> tuple[Array, Array]: ...

    def passive_force_length(self, l_norm: ArrayLike) -> tuple[Array, Array]: ...

    def tendon_force_strain(self, strain: ArrayLike) -> tuple[Array, Array]: ...


@dataclass(frozen=True)
class Thelen2003Curves:
    """Thelen (2003) curves as OpenSim 4.x ``Thelen2003Muscle`` computes them.

    * active force–length ``f_L = exp(−(l̃ − 1)²/γ)``, γ = ``kshape_active``;
    * passive ``f_PE = (exp(k_PE (l̃ − 1)/ε_0^M) − 1)/(exp(k_PE) − 1)`` for l̃ > 1, else 0;
    * tendon ``f_T = F_toe/(e^{k_toe} − 1) (e^{k_toe ε/ε_toe} − 1)`` for 0 < ε ≤ ε_toe,
      ``k_lin (ε − ε_toe) + F_toe`` beyond, with k_toe = 3, F_toe = 0.33 and OpenSim's exact
      ``ε_toe = 99 ε_0 e³/(166 e³ − 67)`` (the paper's 0.609 ε_0) and ``k_lin = 0.67/(ε_0 − ε_toe)``
      so that f_T(ε_0) = 1;
    * force–velocity from Thelen's Eq. 6–7 (velocity as a function of force), inverted in closed
      form, with the linear extrapolation OpenSim applies below f = 0 and above
      ``fv_linear_extrap_threshold · F_len``.

    Defaults are the values of the Thelen 2003 paper; :meth:`gait2392` gives those
    stored in ``gait2392_thelen2003muscle.osim`` and :meth:`opensim_defaults` OpenSim's own.
    """

    kshape_active: float = 0.45
    kshape_passive: float = 4.0
    fmax_muscle_strain: float = 0.6
    fmax_tendon_strain: float = 0.033
    af: float = 0.25
    flen: float = 1.4
    fv_linear_extrap_threshold: float = 0.95

    @classmethod
    def gait2392(cls) -> Thelen2003Curves:
        """Values in gait2392_thelen2003muscle.osim: KshapeActive 0.5, KshapePassive 4, Af 0.3,
        Flen 1.8, FmaxMuscleStrain 0.6, FmaxTendonStrain 0.033."""
        return cls(kshape_active=0.5, kshape_passive=4.0, af=0.3, flen=1.8)

    @classmethod
    def opensim_defaults(cls) -> Thelen2003Curves:
        """OpenSim 4.x ``Thelen2003Muscle`` property defaults."""
        return cls(kshape_active=0.45, kshape_passive=5.0, af=0.25, flen=1.8)

    # tendon constants ------------------------------------------------------------------------
    @property
    def strain_toe(self) -> float:
        e3 = np.exp(3.0)
        return float(99.0 * self.fmax_tendon_strain * e3 / (166.0 * e3 - 67.0))

    @property
    def k_lin(self) -> float:
        return 0.67 / (self.fmax_tendon_strain - self.strain_toe)

    def active_force_length(self, l_norm: ArrayLike) -> tuple[Array, Array]:
        x = np.asarray(l_norm, dtype=float) - 1.0
        f = np.exp(-(x**2) / self.kshape_active)
        return f, -2.0 * x / self.kshape_active * f

    def passive_force_length(self, l_norm: ArrayLike) -> tuple[Array, Array]:
        x = np.asarray(l_norm, dtype=float) - 1.0
        k, e0 = self.kshape_passive, self.fmax_muscle_strain
        pos = x > 0
        ex = np.exp(k * np.where(pos, x, 0.0) / e0)
        den = np.expm1(k)
        return np.where(pos, (ex - 1.0) / den, 0.0), np.where(pos, k / e0 * ex / den, 0.0)

    def tendon_force_strain(self, strain: ArrayLike) -> tuple[Array, Array]:
        e = np.asarray(strain, dtype=float)
        et, kl, ftoe, ktoe = self.strain_toe, self.k_lin, 0.33, 3.0
        c = ftoe / np.expm1(ktoe)
        ex = np.exp(ktoe * np.clip(e, 0.0, et) / et)
        f = np.where(e > et, kl * (e - et) + ftoe, np.where(e > 0, c * (ex - 1.0), 0.0))
        df = np.where(e > et, kl, np.where(e > 0, c * ktoe / et * ex, 0.0))
        return f, df

    def force_velocity(self, v_norm: ArrayLike, activation: ArrayLike = 1.0) -> Array:
        """f_v at normalised lengthening velocity ``v_norm = l̇_f/(v_max l_opt)``.

        Closed-form inverse of OpenSim's ``calcdlceN`` (Thelen 2003 Eq. 6–7) with
        κ = 0.25 + 0.75 a: concentric (v ≤ 0) ``f_v = (κ + v)/(κ − v/A_f)``, eccentric
        ``f_v = (κ + v c F_len)/(κ + v c)`` with ``c = (2 + 2/A_f)/(F_len − 1)``, linearly
        extrapolated (in v as a function of f) below f_v = 0 and above
        ``fv_linear_extrap_threshold · F_len`` as OpenSim does.
        """
        v = np.asarray(v_norm, dtype=float)
        k = 0.25 + 0.75 * np.asarray(activation, dtype=float)
        af, fl = self.af, self.flen
        c = (2.0 + 2.0 / af) / (fl - 1.0)
        # concentric, valid for v >= -k (f >= 0)
        conc = (k + v) / (k - v / af)
        conc_lin = (v + k) / (k * (1.0 + 1.0 / af))  # slope dv/df = k (1 + 1/Af) at f = 0
        f0 = self.fv_linear_extrap_threshold * fl
        v0 = k * (f0 - 1.0) / (c * (fl - f0))
        ecc = (k + v * c * fl) / (k + v * c)
        slope = k * (fl - 1.0) / (c * (fl - f0) ** 2)  # dv/df at f0
        ecc_lin = f0 + (v - v0) / slope
        return np.where(v <= 0, np.where(v >= -k, conc, conc_lin), np.where(v <= v0, ecc, ecc_lin))


@dataclass(frozen=True)
class LloydBesierCurves:
    """Curves of the EMG-driven model of the EMG-driven vs OpenSim thesis, §2.2.2 (Lloyd & Besier
    2003).

    * active force–length: Gaussian ``exp(−((l̃ − 1)/K)²)`` (the thesis shows Gordon's curve
      only as a figure; we use the form of Hayashibe et al. 2011, Eq. 10 with ``width`` = K);
    * passive ``F̃_P = e^{10(l̃ − 1)}/e^5`` (Eq. 10, as printed: non-zero below l̃ = 1);
    * tendon (Eq. 15–18): ``1480.3 ε²`` up to ε = 0.0127, then ``37.5 ε − 0.2375``;
    * force–velocity (Eq. 11–12, ṽ = shortening velocity / v_max > 0 concentric):
      ``(b − a ṽ)/(b + ṽ)`` with a = b = ``hill_curvature`` (so f_v(1) = 0), and eccentric
      ``F_ecc − (F_ecc − 1) b'/(b' − ṽ)`` (a' = 0 so the asymptote is F_ecc; b' is chosen so the
      eccentric slope at 0 is ``ecc_slope_ratio`` times the concentric one — the thesis does not
      give a', b').
    """

    width: float = float(np.sqrt(0.45))
    hill_curvature: float = 0.25
    f_ecc: float = 1.8
    ecc_slope_ratio: float = 2.0
    damping: float = 0.1
    skew: float = 0.15

    def active_force_length(self, l_norm: ArrayLike) -> tuple[Array, Array]:
        x = np.asarray(l_norm, dtype=float) - 1.0
        f = np.exp(-((x / self.width) ** 2))
        return f, -2.0 * x / self.width**2 * f

    def passive_force_length(self, l_norm: ArrayLike) -> tuple[Array, Array]:
        f = np.exp(10.0 * (np.asarray(l_norm, dtype=float) - 1.0)) / np.exp(5.0)
        return f, 10.0 * f

    def tendon_force_strain(self, strain: ArrayLike) -> tuple[Array, Array]:
        e = np.asarray(strain, dtype=float)
        f = np.where(e >= 0.0127, 37.5 * e - 0.2375, np.where(e > 0, 1480.3 * e**2, 0.0))
        df = np.where(e >= 0.0127, 37.5, np.where(e > 0, 2 * 1480.3 * e, 0.0))
        return f, df

    def force_velocity(self, v_shortening_norm: ArrayLike) -> Array:
        """Eq. 11–12; ``v_shortening_norm``: shortening speed / (v_max l_opt), > 0 concentric."""
        v = np.asarray(v_shortening_norm, dtype=float)
        a = b = self.hill_curvature
        conc = np.maximum((b - a * v) / (b + v), 0.0)
        slope_c = (1.0 + a) / b
        bp = (self.f_ecc - 1.0) / (self.ecc_slope_ratio * slope_c)
        # the eccentric branch (v < 0) at the lengthening speeds only: at a shortening speed
        # v = b' its formula divides by zero (a speed the concentric branch answers)
        v_ecc = np.minimum(v, 0.0)
        ecc = self.f_ecc - (self.f_ecc - 1.0) * bp / (bp - v_ecc)
        return np.where(v >= 0, conc, ecc)

    def optimal_length_scale(self, activation: ArrayLike) -> Array:
        """Eq. 9: ``l_opt(t)/l_opt = λ (1 − a(t)) + 1``."""
        return self.skew * (1.0 - np.asarray(activation, dtype=float)) + 1.0

    def tendon_force(
        self,
        activation: ArrayLike,
        l_norm: ArrayLike,
        v_shortening_norm: ArrayLike,
        cos_pennation: ArrayLike,
        max_isometric_force: ArrayLike,
    ) -> Array:
        """Eq. 8: ``F_t = F_iso [F̃_A F̃_V a + F̃_P + b_m ṽ] cos φ`` (ṽ lengthening =
        −shortening)."""
        fa, _ = self.active_force_length(l_norm)
        fp, _ = self.passive_force_length(l_norm)
        fv = self.force_velocity(v_shortening_norm)
        damp = -self.damping * np.asarray(v_shortening_norm, dtype=float)
        return (
            np.asarray(max_isometric_force)
            * (fa * fv * np.asarray(activation) + fp + damp)
            * np.asarray(cos_pennation)
        )


def fl_gaussian(l_norm: ArrayLike, *, width: float = float(np.sqrt(0.45))) -> Array:
    """Hayashibe et al. 2011, Eq. 10: ``f_l(l̃) = exp(−((l̃ − 1)/K)²)`` with K = ``width``."""
    return np.exp(-(((np.asarray(l_norm, dtype=float) - 1.0) / width) ** 2))


def fv_stroeve(
    v_norm: ArrayLike,
    *,
    v_max: ArrayLike = 10.0,
    v_sh: float = 0.3,
    v_shl: float = 0.23,
    v_ml: float = 1.3,
) -> Array:
    """Hayashibe et al. 2011, Eq. 11 (Stroeve 1999); ``v_norm`` = lengthening velocity in
    l_opt/s."""
    v = np.asarray(v_norm, dtype=float)
    vm = np.asarray(v_max, dtype=float)
    conc = v_sh * (vm + v) / (v_sh * vm - v)
    ecc = (v_sh * v_shl * vm + v_ml * v) / (v_sh * v_shl * vm + v)
    return np.where(v < -vm, 0.0, np.where(v < 0, conc, ecc))


def reference_force(
    activation: ArrayLike,
    fiber_length: ArrayLike,
    fiber_velocity: ArrayLike,
    params: MuscleParameters,
    *,
    width: float = float(np.sqrt(0.45)),
) -> Array:
    """Hayashibe et al. 2011, Eq. 9: ``f* = a f_l(l) f_v(l̇) F_iso`` for arrays ``(N, M)`` (SI)."""
    lopt = params.optimal_fiber_length
    fl = fl_gaussian(np.asarray(fiber_length) / lopt, width=width)
    fv = fv_stroeve(np.asarray(fiber_velocity) / lopt, v_max=params.max_contraction_velocity)
    return np.asarray(activation) * fl * fv * params.max_isometric_force


def pennation_constant_height(
    fiber_length: ArrayLike, params: MuscleParameters
) -> tuple[Array, Array]:
    """the EMG-driven vs OpenSim thesis, Eq. 14: ``sin φ = l_opt sin φ_0 / l_m``; returns (φ, cos
    φ)."""
    h = params.optimal_fiber_length * np.sin(params.pennation_angle_at_optimal)
    s = np.clip(h / np.asarray(fiber_length, dtype=float), 0.0, 1.0)
    return np.arcsin(s), np.sqrt(1.0 - s**2)


# ---------------------------------------------------------------------------------------------
# Rigid tendon
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RigidTendonState(FrameAxis):
    """Muscle state per frame for an inextensible tendon; arrays ``(N, M)``."""

    FRAME_FIELDS: ClassVar[tuple[str, ...]] = (
        "fiber_length",
        "norm_fiber_length",
        "fiber_velocity",
        "norm_fiber_velocity",
        "cos_pennation",
        "f_active_length",
        "f_velocity",
        "f_passive",
        "max_active_force_along_tendon",
        "passive_force_along_tendon",
    )

    names: tuple[str, ...]
    fiber_length: Array
    norm_fiber_length: Array
    fiber_velocity: Array
    norm_fiber_velocity: Array
    cos_pennation: Array
    f_active_length: Array
    f_velocity: Array
    f_passive: Array
    max_active_force_along_tendon: Array
    passive_force_along_tendon: Array


def _check_lengths(params: MuscleParameters, x: ArrayLike, what: str) -> Array:
    a = np.asarray(x, dtype=float)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != params.n_muscles:
        raise MuscleModelError(f"{what} must be (N, {params.n_muscles}), got {a.shape}")
    if not np.isfinite(a).all():
        r, c = np.argwhere(~np.isfinite(a))[0]
        raise MuscleModelError(f"{what}: non-finite value at frame {r}, muscle {params.names[c]!r}")
    return a


def rigid_tendon_state(
    params: MuscleParameters,
    muscle_tendon_length: ArrayLike,
    lengthening_velocity: ArrayLike | None = None,
    *,
    curves: Thelen2003Curves | None = None,
    activation_in_fv: float = 1.0,
) -> RigidTendonState:
    """Fibre state and maximal active force for a rigid tendon (OpenSim SO convention).

    ``l_f = sqrt(h² + (l_MT − l_TS)²)`` with ``h = l_opt sin α_0`` (constant height), clamped at
    ``h / sin(α_max)`` (α_max = acos 0.1, OpenSim's default); ``cos α = (l_MT − l_TS)/l_f``
    (0 when the path is shorter than the tendon); ``l̇_f = l̇_MT cos α``;
    ``F_max,along = F_iso f_l(l̃_f) f_v(ṽ_f) cos α`` (Hayashibe et al. 2011, Eq. 9 with a = 1) — the
    same quantity as OpenSim's ``calcInextensibleTendonActiveFiberForce(s, 1.0)``.
    """
    curves = curves or Thelen2003Curves()
    lmt = _check_lengths(params, muscle_tendon_length, "muscle_tendon_length")
    vmt = (
        np.zeros_like(lmt)
        if lengthening_velocity is None
        else _check_lengths(params, lengthening_velocity, "lengthening_velocity")
    )
    if vmt.shape != lmt.shape:
        raise MuscleModelError(f"lengthening_velocity {vmt.shape} != lengths {lmt.shape}")
    lopt = params.optimal_fiber_length
    h = lopt * np.sin(params.pennation_angle_at_optimal)
    along = lmt - params.tendon_slack_length
    lmin = np.maximum(h / np.sin(MAX_PENNATION_ANGLE), 1e-6 * lopt)
    lf = np.maximum(np.sqrt(h**2 + along**2), lmin)
    cos_a = np.clip(along / lf, 0.0, 1.0)
    vf = vmt * cos_a
    vn = vf / (lopt * params.max_contraction_velocity)
    fl, _ = curves.active_force_length(lf / lopt)
    fpe, _ = curves.passive_force_length(lf / lopt)
    fv = curves.force_velocity(vn, activation_in_fv)
    fiso = params.max_isometric_force
    return RigidTendonState(
        names=params.names,
        fiber_length=lf,
        norm_fiber_length=lf / lopt,
        fiber_velocity=vf,
        norm_fiber_velocity=vn,
        cos_pennation=cos_a,
        f_active_length=fl,
        f_velocity=fv,
        f_passive=fpe,
        max_active_force_along_tendon=fiso * fl * fv * cos_a,
        passive_force_along_tendon=fiso * fpe * cos_a,
    )


class RigidTendonFrame:
    """The two force curves of :func:`rigid_tendon_state` for one frame at a time (a stream:
    :mod:`msk.live`): ``F_max,along = F_iso f_l(l̃_f) f_v(ṽ_f) cos α`` and
    ``F_P,along = F_iso f_PE(l̃_f) cos α`` (Thelen 2003 curves, activation 1 inside f_v), with
    the constants of ``params`` folded once and every array a buffer of this object. The same
    operations in the same order as :func:`rigid_tendon_state`: equal to it bit for bit
    (tested). :meth:`__call__` returns the buffers :attr:`active` and :attr:`passive`,
    overwritten by the next call."""

    def __init__(self, params: MuscleParameters, curves: Thelen2003Curves | None = None) -> None:
        cv = curves or Thelen2003Curves()
        self.params = params
        lopt = np.asarray(params.optimal_fiber_length, dtype=float)
        h = lopt * np.sin(params.pennation_angle_at_optimal)
        self._lopt = lopt
        self._h2 = h**2
        self._lmin = np.maximum(h / np.sin(MAX_PENNATION_ANGLE), 1e-6 * lopt)
        self._slack = np.asarray(params.tendon_slack_length, dtype=float)
        self._vscale = lopt * params.max_contraction_velocity
        self._fiso = np.asarray(params.max_isometric_force, dtype=float)
        self._ka, self._kp, self._e0 = cv.kshape_active, cv.kshape_passive, cv.fmax_muscle_strain
        self._den = np.expm1(self._kp)
        # force–velocity constants of Thelen2003Curves.force_velocity at activation 1
        k = 0.25 + 0.75 * 1.0
        af, fl = cv.af, cv.flen
        c = (2.0 + 2.0 / af) / (fl - 1.0)
        f0 = cv.fv_linear_extrap_threshold * fl
        self._fv = (k, af, fl, c, k * (1.0 + 1.0 / af), f0, k * (f0 - 1.0) / (c * (fl - f0)))
        self._slope = k * (fl - 1.0) / (c * (fl - f0) ** 2)
        m = lopt.size
        self._lf, self._cos, self._vn = np.empty(m), np.empty(m), np.empty(m)
        self._x, self._fl, self._fv_out = np.empty(m), np.empty(m), np.empty(m)
        self._t = np.empty(m)
        self.active, self.passive = np.empty(m), np.empty(m)

    def __call__(self, lengths: Array, velocities: Array) -> tuple[Array, Array]:
        """``(F_max,along, F_P,along)`` (M,) of one frame's muscle–tendon lengths and lengthening
        velocities (M,)."""
        # one sum each: finite unless an entry is not (or the sum overflows: then look)
        s = float(np.add.reduce(lengths)) + float(np.add.reduce(velocities))
        if not math.isfinite(s) and not (
            np.isfinite(lengths).all() and np.isfinite(velocities).all()
        ):
            bad = np.flatnonzero(~(np.isfinite(lengths) & np.isfinite(velocities)))[0]
            raise MuscleModelError(
                f"muscle {self.params.names[bad]!r}: non-finite length or velocity "
                f"({float(lengths[bad])!r}, {float(velocities[bad])!r})"
            )
        lf, cos_a, vn, x, t = self._lf, self._cos, self._vn, self._x, self._t
        along = np.subtract(lengths, self._slack, out=t)
        np.multiply(along, along, out=lf)
        lf += self._h2
        np.sqrt(lf, out=lf)
        np.maximum(lf, self._lmin, out=lf)
        np.divide(along, lf, out=cos_a)
        np.maximum(cos_a, 0.0, out=cos_a)  # clip to [0, 1] (no NaN here)
        np.minimum(cos_a, 1.0, out=cos_a)
        np.multiply(velocities, cos_a, out=vn)
        vn /= self._vscale
        # x = l̃_f − 1; f_l = exp(−x²/K_a)
        np.divide(lf, self._lopt, out=x)
        x -= 1.0
        fl = self._fl
        np.multiply(x, x, out=fl)
        np.negative(fl, out=fl)
        fl /= self._ka
        np.exp(fl, out=fl)
        # f_PE = (exp(K_p x/ε_0) − 1)/(e^{K_p} − 1) where x > 0, else 0
        pas = self.passive
        np.maximum(x, 0.0, out=pas)
        pas *= self._kp
        pas /= self._e0
        np.exp(pas, out=pas)
        pas -= 1.0
        pas /= self._den
        pas[x <= 0] = 0.0
        # f_v: concentric branch everywhere, the other three where they apply
        k, af, flen, c, kc, f0, v0 = self._fv
        fv = self._fv_out
        np.divide(vn, af, out=t)
        np.subtract(k, t, out=t)
        np.add(vn, k, out=fv)
        fv /= t
        if np.minimum.reduce(vn) < -k:
            lo = vn < -k
            fv[lo] = (vn[lo] + k) / kc
        if np.maximum.reduce(vn) > 0:
            ecc = vn > 0
            v = vn[ecc]
            fv[ecc] = np.where(
                v <= v0, (k + v * c * flen) / (k + v * c), f0 + (v - v0) / self._slope
            )
        act = self.active
        np.multiply(self._fiso, fl, out=act)
        act *= fv
        act *= cos_a
        np.multiply(self._fiso, pas, out=pas)
        pas *= cos_a
        return act, pas


@dataclass(frozen=True)
class RigidTendonStateBlocks:
    """The rigid-tendon state (:func:`rigid_tendon_state`) of ``params`` on muscle–tendon
    lengths and lengthening velocities ``(N_all, M)``, computed on demand for a block of frames:
    the ten ``(N, M)`` state arrays of a long trial are never held whole.
    :func:`rigid_tendon_state` works frame by frame, so a block's state equals the rows of the
    whole trial's. ``frames``: the rows of ``lengths``/``velocities`` that make up the trial
    (indices; None: all of them), so the caller need not copy a subset."""

    params: MuscleParameters
    lengths: Array
    velocities: Array
    frames: NDArray[np.int64] | None = None

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.params.names)

    @property
    def n_frames(self) -> int:
        return int(self.lengths.shape[0] if self.frames is None else self.frames.size)

    def rows(self, sl: slice) -> RigidTendonState:
        """The state of the frames ``sl`` (of the ``n_frames``)."""
        idx = sl if self.frames is None else self.frames[sl]
        return rigid_tendon_state(self.params, self.lengths[idx], self.velocities[idx])

    def full(self) -> RigidTendonState:
        """The state of every frame (held whole)."""
        return self.rows(slice(None))


# ---------------------------------------------------------------------------------------------
# Elastic tendon: static equilibrium
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class EquilibriumState(FrameAxis):
    """Static fibre–tendon equilibrium; arrays ``(N, M)`` (SI)."""

    FRAME_FIELDS: ClassVar[tuple[str, ...]] = (
        "fiber_length",
        "norm_fiber_length",
        "tendon_length",
        "tendon_strain",
        "cos_pennation",
        "tendon_force",
        "active_fiber_force",
        "passive_fiber_force",
    )

    names: tuple[str, ...]
    fiber_length: Array
    norm_fiber_length: Array
    tendon_length: Array
    tendon_strain: Array
    cos_pennation: Array
    tendon_force: Array
    active_fiber_force: Array
    passive_fiber_force: Array
    iterations: int


def _balance(
    x: Array,
    lmt: Array,
    a: Array,
    fv: Array,
    h: Array,
    lopt: Array,
    lts: Array,
    fiso: Array,
    curves: CurveSet,
) -> tuple[Array, Array, dict[str, Array]]:
    """Residual r(x) = F_fibre cos α − F_tendon and dr/dx, x = fibre length along the tendon."""
    lf = np.sqrt(x**2 + h**2)
    cos_a = x / lf
    ln = lf / lopt
    fl, dfl = curves.active_force_length(ln)
    fp, dfp = curves.passive_force_length(ln)
    eps = (lmt - x) / lts - 1.0
    ft, dft = curves.tendon_force_strain(eps)
    fm = fiso * (a * fl * fv + fp)
    dfm_dlf = fiso * (a * fv * dfl + dfp) / lopt
    r = fm * cos_a - fiso * ft
    # d lf/dx = cos α; d cos α/dx = h²/lf³; d eps/dx = −1/l_TS
    dr = dfm_dlf * cos_a * cos_a + fm * h**2 / lf**3 + fiso * dft / lts
    info = {"lf": lf, "cos": cos_a, "eps": eps, "ft": ft, "fl": fl, "fp": fp}
    return r, dr, info


def equilibrium(
    params: MuscleParameters,
    muscle_tendon_length: ArrayLike,
    activation: ArrayLike,
    *,
    curves: CurveSet | None = None,
    f_velocity: ArrayLike = 1.0,
    tol_n: float = 1e-8,
    max_iter: int = 100,
) -> EquilibriumState:
    """Elastic-tendon static equilibrium ``F_iso (a f_L f_V + f_PE) cos α = F_iso f_T(ε)``.

    Unknown: the fibre length along the tendon ``x = l_f cos α`` (constant-height pennation,
    ``l_f = sqrt(x² + h²)``), bracketed in ``(0, l_MT − l_TS]`` where the residual changes sign;
    the Newton step starts, like OpenSim's ``initMuscleState``, from a tendon at 1.01 l_TS and
    falls back to bisection whenever it would leave the bracket. Arrays are ``(N, M)``
    (``activation`` broadcasts). A path shorter than the tendon slack length gives zero force and
    the fibre at its shortest (clamped) length. Raises :class:`MuscleModelError` naming the muscle
    and frame if it does not converge to ``tol_n`` newtons.
    """
    curves = curves or Thelen2003Curves()
    lmt = _check_lengths(params, muscle_tendon_length, "muscle_tendon_length")
    a = np.broadcast_to(np.asarray(activation, dtype=float), lmt.shape)
    fv = np.broadcast_to(np.asarray(f_velocity, dtype=float), lmt.shape)
    lopt = np.broadcast_to(params.optimal_fiber_length, lmt.shape)
    lts = np.broadcast_to(params.tendon_slack_length, lmt.shape)
    fiso = np.broadcast_to(params.max_isometric_force, lmt.shape)
    h = lopt * np.sin(params.pennation_angle_at_optimal)
    xmin = np.sqrt(np.maximum((h / np.sin(MAX_PENNATION_ANGLE)) ** 2 - h**2, 0.0))
    xmin = np.maximum(xmin, 1e-6 * lopt)
    slack = lmt - lts <= xmin
    hi = np.where(slack, 2.0 * xmin, lmt - lts)
    lo = xmin.copy()
    r_lo, _, _ = _balance(lo, lmt, a, fv, h, lopt, lts, fiso, curves)
    # fibre already stronger than the tendon at its shortest length: clamp (OpenSim's
    # "FiberAtLowerBound"), or the path is shorter than the tendon: no force.
    at_min = slack | (r_lo >= 0)
    x = np.where(at_min, xmin, np.clip(lmt - 1.01 * lts, lo, hi))
    it = 0
    r, dr, info = _balance(x, lmt, a, fv, h, lopt, lts, fiso, curves)
    while it < max_iter:
        done = (np.abs(r) <= tol_n) | at_min
        if done.all():
            break
        it += 1
        # keep the bracket: r(lo) < 0 (the tendon pulls harder), r(hi) >= 0
        lo = np.where(r < 0, x, lo)
        hi = np.where(r > 0, x, hi)
        with np.errstate(divide="ignore", invalid="ignore"):
            xn = x - r / dr
        bad = ~np.isfinite(xn) | (xn <= lo) | (xn >= hi)
        xn = np.where(bad, 0.5 * (lo + hi), xn)
        x = np.where(done, x, xn)
        r, dr, info = _balance(x, lmt, a, fv, h, lopt, lts, fiso, curves)
    fail = ~((np.abs(r) <= tol_n) | at_min)
    if fail.any():
        f, m = np.argwhere(fail)[0]
        raise MuscleModelError(
            f"muscle {params.names[m]!r}, frame {f}: equilibrium did not converge in {max_iter} "
            f"iterations (residual {r[f, m]:.3g} N, l_MT = {lmt[f, m]:.5g} m, a = {a[f, m]:.3g})"
        )
    ft = np.where(slack, 0.0, info["ft"])
    act = np.where(slack, 0.0, fiso * a * info["fl"] * fv)
    pas = np.where(slack, 0.0, fiso * info["fp"])
    return EquilibriumState(
        names=params.names,
        fiber_length=info["lf"],
        norm_fiber_length=info["lf"] / lopt,
        tendon_length=lmt - x,
        tendon_strain=np.where(slack, 0.0, info["eps"]),
        cos_pennation=info["cos"],
        tendon_force=fiso * ft,
        active_fiber_force=act,
        passive_fiber_force=pas,
        iterations=it,
    )
