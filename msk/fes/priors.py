"""Population priors for the FES protocol, from Benoussaad et al. 2013, Table 3 (13 legs, 9
subjects).

The protocol cannot identify two quantities from its data and takes them as priors: the
stiffness ratio ``K_cm/F_cm`` (1/m; Benoussaad et al. 2013: "proportional to F_cm according to the
physiological model") and the fibre fraction ``L_c0/(L_c0 + L_s)`` (the muscle/tendon split of
the force–length optimum, Benoussaad et al. 2013, ref. [10]).  :func:`population_priors` gives their
mean and standard deviation over Table 3 — optionally leaving legs out, so that a leg is never
identified with a prior that contains its own published values — together with those of every Table
3 parameter.

Caveat: Table 3 has no ``L_s``; :data:`msk.fes.model.TABLE3` derives it from an assumed optimal
knee angle of 60° for every leg, so the Table 3 spread of the fibre fraction (0.191–0.201) is
an artefact of that assumption, not a measured population spread.  The recovery study
(``bench/fes_recovery.py``, ``docs/fes.md``) therefore also sweeps this prior by ±10–50 %.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from msk.exceptions import IdentificationError
from msk.fes.model import TABLE3, FesSubject, RecruitmentPW

__all__ = [
    "KS_STRETCH_MARGIN",
    "KS_STRETCH_MAX_TABLE3",
    "PRIOR_NAMES",
    "PopulationPriors",
    "k_s_lower_bound",
    "leg_values",
    "population_priors",
]

#: Parameters summarised per leg (SI units: m, N·m/rad, kg·m², N·m·s/rad, N, N/m).
PRIOR_NAMES: tuple[str, ...] = (
    "L_ext",
    "r_q",
    "K",
    "J",
    "B",
    "L_c0",
    "b",
    "L_s",
    "c1",
    "c2",
    "c3",
    "F_cm",
    "K_cm",
    "k_s",
    "stiffness_ratio",
    "fibre_fraction",
    "se_stretch",
)


def leg_values(subject: FesSubject) -> dict[str, float]:
    """Every :data:`PRIOR_NAMES` value of one leg (``se_stretch = F_cm/(k_s L_c0)``: the
    series-element elongation at ``F_cm`` in units of ``L_c0``)."""
    g, k, m = subject.geometry, subject.knee, subject.muscle
    rec = subject.recruitment
    c = rec.vector()[:3] if isinstance(rec, RecruitmentPW) else (np.nan, np.nan, np.nan)
    return {
        "L_ext": g.L_ext,
        "r_q": g.r_q,
        "K": k.K,
        "J": k.J,
        "B": k.B,
        "L_c0": m.L_c0,
        "b": m.b,
        "L_s": m.L_s,
        "c1": float(c[0]),
        "c2": float(c[1]),
        "c3": float(c[2]),
        "F_cm": m.F_cm,
        "K_cm": m.K_cm,
        "k_s": m.k_s,
        "stiffness_ratio": m.K_cm / m.F_cm,
        "fibre_fraction": m.L_c0 / (m.L_c0 + m.L_s),
        "se_stretch": m.F_cm / (m.k_s * m.L_c0),
    }


@dataclass(frozen=True)
class PopulationPriors:
    """Mean and sample SD (``ddof = 1``) of every :data:`PRIOR_NAMES` value over ``legs``."""

    legs: tuple[str, ...]
    mean: dict[str, float]
    sd: dict[str, float]

    @property
    def fibre_fraction(self) -> float:
        return self.mean["fibre_fraction"]

    @property
    def stiffness_ratio(self) -> float:
        return self.mean["stiffness_ratio"]

    def cv(self, name: str) -> float:
        """Coefficient of variation SD/mean of ``name``."""
        return self.sd[name] / abs(self.mean[name])


def population_priors(exclude: Iterable[str] = ()) -> PopulationPriors:
    """Table 3 means/SDs over the 13 legs, leaving out the legs (or whole subjects) ``exclude``.

    ``exclude`` may name legs (``"S3L"``) or subjects (``"S3"``, both legs).  Leaving a leg's
    subject out is what the recovery study does: its prior never contains its own values.
    """
    ex = set(exclude)
    legs = tuple(k for k in TABLE3 if k not in ex and k[:-1] not in ex)
    if len(legs) < 2:
        raise IdentificationError(f"population priors: fewer than 2 legs left after {sorted(ex)}")
    rows = [leg_values(TABLE3[k]) for k in legs]
    mean = {n: float(np.mean([r[n] for r in rows])) for n in PRIOR_NAMES}
    sd = {n: float(np.std([r[n] for r in rows], ddof=1)) for n in PRIOR_NAMES}
    return PopulationPriors(legs, mean, sd)


#: Largest series-element elongation at ``F_cm`` in Table 3, ``max F_cm/(k_s L_c0)`` = 2.76
#: (S3R: 523 N, 2.1 N/mm, 9.01 cm).
KS_STRETCH_MAX_TABLE3: float = max(leg_values(s)["se_stretch"] for s in TABLE3.values())

#: Margin on :data:`KS_STRETCH_MAX_TABLE3` for the default lower bound of the ``k_s`` NLP.
KS_STRETCH_MARGIN: float = 2.0


def k_s_lower_bound(F_cm: float, L_c0: float) -> float:
    """Default lower bound of ``k_s`` (N/m) in the NLP of Benoussaad et al. 2013, Eq. 8.

    Eq. 8 only asks ``k_s > 0``; the bound keeps ipopt away from the singular ``k_s → 0``.  It
    lets the series element stretch at ``F_cm`` by up to twice the largest elongation of any
    Table 3 leg, ``k_s ≥ F_cm / (2 · 2.76 · L_c0)``: every Table 3 ``k_s`` is at least twice
    its leg's bound (S3R, the most compliant series element relative to its force: 2.1 N/mm
    against a bound of 1.05 N/mm).
    """
    return F_cm / (KS_STRETCH_MARGIN * KS_STRETCH_MAX_TABLE3 * L_c0)
