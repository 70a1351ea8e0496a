"""One status vocabulary for every identified quantity.

A strength group, a segment's inertia, an EMG gain and an FES parameter each get exactly one of

* ``identified`` — the data determine the value: its interval lies inside the bounds and the
  fit behind it is adequate;
* ``at bound`` — the estimate sits on (or, by a rounding step, past) a bound of its
  optimisation: the bound, not the data, fixed it;
* ``not determined`` — a value was estimated but the data do not pin it down: the fit is below
  its stated threshold, the interval touches a bound or is missing, or the value moved away
  from its prior without becoming precise;
* ``prior`` — the value equals its prior (the generic model, or the protocol's assumption):
  the data did not change it.

The status is computed here, once, by pure functions of the numbers a run reports
(``summary.json``), and the summary, the tables, the report, its PDF, ``msk compare`` and the
cohort table all read it from there. Thresholds are the named constants below; each says where
it comes from.

Tables are numeric CSV, so ``strength.csv`` carries the status as ``<group>.status_code``:
:data:`STATUS_CODES` (listed in ``summary.json`` under ``strength.status_codes``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from enum import StrEnum
from typing import Any

__all__ = [
    "BOUND_REL_TOL",
    "FES_DETERMINED_BY_PROTOCOL",
    "FES_NRMSD_MAX_PCT",
    "PRIOR_REL_TOL",
    "PRIOR_SHIFT_PRIOR_STD",
    "SEGMENT_COM_PRIOR_STD_M",
    "SEGMENT_MASS_PRIOR_REL_STD",
    "STATUS_CODES",
    "STATUS_MEANING",
    "STRENGTH_CI_REL_WIDTH_MAX",
    "STRENGTH_R2_MIN",
    "WELL_IDENTIFIED_COM_STD_M",
    "WELL_IDENTIFIED_MASS_REL_STD",
    "Status",
    "at_bound",
    "fes_status",
    "gain_status",
    "group_status",
    "inertia_status",
    "segment_status",
    "status_from_code",
    "strength_status",
]


class Status(StrEnum):
    """The four words (their ``value`` is what ``summary.json`` and the tables hold)."""

    IDENTIFIED = "identified"
    AT_BOUND = "at bound"
    NOT_DETERMINED = "not determined"
    PRIOR = "prior"


#: Numeric codes of the statuses in the numeric tables (``strength.csv``).
STATUS_CODES: dict[str, int] = {
    Status.IDENTIFIED.value: 0,
    Status.AT_BOUND.value: 1,
    Status.NOT_DETERMINED.value: 2,
    Status.PRIOR.value: 3,
}
#: One sentence per status for readers of the report and of ``summary.json``.
STATUS_MEANING: dict[str, str] = {
    Status.IDENTIFIED.value: "the data determine the value: its interval lies inside the bounds "
    "and the fit is adequate",
    Status.AT_BOUND.value: "the estimate sits on a bound of the optimisation: the bound, not the "
    "data, fixed it",
    Status.NOT_DETERMINED.value: "estimated, but the data do not pin it down (poor fit, interval "
    "touching a bound, or moved from the prior without becoming precise)",
    Status.PRIOR.value: "the value equals its prior (generic model or protocol assumption)",
}

#: Minimum fit r² (dimensionless) of the strength regression (Hayashibe et al. 2011, Eq. 16: the ID
#: joint moments explained by the EMG-driven contributions) for a group to be ``identified``,
#: on the group's own rows (the coordinates its muscles cross: :func:`msk.strength.diagnose`).
#: Below 0.5 the EMG-driven model explains less than half of the joint-moment variance: most
#: of the moment is then left to the residual, and the factors absorb model error rather than
#: strength. The same threshold has been the report's "could not be estimated reliably" warning.
STRENGTH_R2_MIN = 0.5
#: Largest width of a strength factor's 95 % interval, relative to the factor, for the group to
#: be ``identified``: ``(ci_high − ci_low) ≤ STRENGTH_CI_REL_WIDTH_MAX · factor`` (a half-width
#: of ±50 %). Healthy adults' strength relative to a scaled generic model spreads over about
#: that much (Hayashibe et al. 2011 identify factors of 0.6–1.6); an interval wider than the
#: estimate itself cannot tell a half-strength group from a 1.5× one. An audit found a group called
#: identified with the interval [0.013, 0.880].
STRENGTH_CI_REL_WIDTH_MAX = 1.0
#: Relative tolerance for "on a bound": ``|x − b| ≤ BOUND_REL_TOL · max(1, |b|)``. The bounded
#: solvers (BVLS, IPOPT) return bound values up to a few rounding steps (e.g. 0.4999999999999999
#: for 0.5); 1e-6 is far above double rounding and far below any factor difference that matters
#: (the report prints two decimals).
BOUND_REL_TOL = 1e-6
#: Relative tolerance for "equals the prior" of parameters without a prior spread (EMG gains,
#: FES parameters): 0.1 %, well below the precision any of them is identified to.
PRIOR_REL_TOL = 1e-3
#: Posterior relative std of a segment mass at or below which it is ``identified`` (the
#: "well identified" criterion of :mod:`msk.dynamics.identification`, Hayashibe et al. 2011, Fig. 3
#: colour
# coding).
WELL_IDENTIFIED_MASS_REL_STD = 0.02
#: Posterior std (m) of every COM coordinate at or below which a segment is ``identified``.
WELL_IDENTIFIED_COM_STD_M = 0.004
#: Prior spread of a segment mass (relative) and COM (m): the defaults of
#: :func:`msk.dynamics.identification.default_prior_std`.
SEGMENT_MASS_PRIOR_REL_STD = 0.3
SEGMENT_COM_PRIOR_STD_M = 0.03
#: A segment is ``prior`` only while its mass and COM stay within this fraction of their prior
#: std of the prior value (0.2 σ: 6 % of the mass, 6 mm of COM with the defaults). A segment
#: that moved further is no longer "the prior", whatever its std (otherwise segments that
#: moved 49–89 % on a rank-deficient trial would be labelled "prior").
PRIOR_SHIFT_PRIOR_STD = 0.2
#: Largest NRMSD (% of the measured range, Benoussaad et al. 2013, Eq. 9) of an FES protocol step
#: for its parameters to be ``identified``: a quarter of the movement range. The medians of every
#: step in Benoussaad et al. 2013, Table 2 are 3–14 %; only 5 of its 70-odd step fits exceed 25 %.
FES_NRMSD_MAX_PCT = 25.0
#: FES model parameters the protocol's data determine (report keys): recovered within 15 % on
#: at least 12 of the 13 synthetic legs of Benoussaad et al. 2013, Table 3 with population priors
#: (docs/fes.md, asserted both ways by ``tests/fes/test_fes_recovery.py``). The others — ``b``,
#: ``F_cm``, ``k_s``, ``c1``–``c3`` — follow the K_cm/F_cm prior (7–9 legs of 13 within 25–50 %): a
#: good fit does not make them ``identified``.
FES_DETERMINED_BY_PROTOCOL: frozenset[str] = frozenset(
    {"knee.K", "knee.J", "knee.B", "muscle.L_c0"}
)


def _finite(x: float | None) -> bool:
    return x is not None and isinstance(x, (int, float)) and math.isfinite(x)


def at_bound(x: float, bound: float, *, rel_tol: float = BOUND_REL_TOL) -> bool:
    """``x`` equals ``bound`` up to ``rel_tol · max(1, |bound|)`` (never for an infinite one)."""
    if not math.isfinite(bound):
        return False
    return abs(x - bound) <= rel_tol * max(1.0, abs(bound))


def _on_or_past(x: float, lower: float, upper: float, rel_tol: float) -> bool:
    return (
        x <= lower
        or x >= upper
        or at_bound(x, lower, rel_tol=rel_tol)
        or at_bound(x, upper, rel_tol=rel_tol)
    )


def strength_status(
    factor: float | None,
    ci_low: float | None,
    ci_high: float | None,
    lower: float,
    upper: float,
    r2: float | None,
    *,
    gated: bool = True,
    r2_min: float = STRENGTH_R2_MIN,
    ci_rel_width_max: float = STRENGTH_CI_REL_WIDTH_MAX,
    rel_tol: float = BOUND_REL_TOL,
) -> Status:
    """Status of one strength group (factor × generic F_iso, bounded to [lower, upper]).

    ``gated`` = the group passed the correlation gate (Hayashibe et al. 2011, §VI.C); a group that
    did not keeps the generic factor: ``prior``. Otherwise, in this order: a factor on or past a
    bound is ``at bound``; a non-finite factor or interval, an interval touching a bound, an
    interval wider than ``ci_rel_width_max`` × the factor, or a fit r² below ``r2_min`` (or unknown)
    is ``not determined``; else ``identified``.
    """
    if not gated:
        return Status.PRIOR
    if not _finite(factor):
        return Status.NOT_DETERMINED
    assert factor is not None
    if _on_or_past(factor, lower, upper, rel_tol):
        return Status.AT_BOUND
    if not (_finite(ci_low) and _finite(ci_high)):
        return Status.NOT_DETERMINED
    assert ci_low is not None and ci_high is not None
    if _on_or_past(ci_low, lower, upper, rel_tol) or _on_or_past(ci_high, lower, upper, rel_tol):
        return Status.NOT_DETERMINED
    if ci_high - ci_low > ci_rel_width_max * abs(factor):
        return Status.NOT_DETERMINED
    if not _finite(r2) or r2 < r2_min:  # type: ignore[operator]
        return Status.NOT_DETERMINED
    return Status.IDENTIFIED


def inertia_status(
    mass: float | None,
    prior_mass: float,
    mass_std: float | None,
    *,
    com: Sequence[float] | None = None,
    prior_com: Sequence[float] | None = None,
    com_std: Sequence[float] | None = None,
    well_mass_rel_std: float = WELL_IDENTIFIED_MASS_REL_STD,
    well_com_std_m: float = WELL_IDENTIFIED_COM_STD_M,
    mass_prior_rel_std: float = SEGMENT_MASS_PRIOR_REL_STD,
    com_prior_std_m: float = SEGMENT_COM_PRIOR_STD_M,
    prior_shift: float = PRIOR_SHIFT_PRIOR_STD,
) -> Status:
    """Status of one segment's mass and COM (posterior std from the MAP identification).

    ``identified`` when the posterior std is small (mass ≤ 2 % relative, every COM coordinate
    ≤ 4 mm); ``prior`` when the mass and COM stayed within ``prior_shift`` prior std of the
    prior; otherwise — the estimate moved but is not precise — ``not determined``. Inertial
    parameters have no box bounds (only physical consistency), so never ``at bound``.
    """
    if not _finite(mass) or (mass_std is not None and not _finite(mass_std)):
        return Status.NOT_DETERMINED
    assert mass is not None
    std = 0.0 if mass_std is None else float(mass_std)
    cstd = [float(c) for c in com_std] if com_std is not None else []
    if any(not math.isfinite(c) for c in cstd):
        return Status.NOT_DETERMINED
    if std <= well_mass_rel_std * abs(mass) and all(c <= well_com_std_m for c in cstd) and mass > 0:
        return Status.IDENTIFIED
    moved = abs(mass - prior_mass) > prior_shift * mass_prior_rel_std * abs(prior_mass)
    if com is not None and prior_com is not None:
        d = math.dist([float(c) for c in com], [float(c) for c in prior_com])
        moved |= not math.isfinite(d) or d > prior_shift * com_prior_std_m
    return Status.NOT_DETERMINED if moved else Status.PRIOR


def gain_status(
    gain: float | None,
    *,
    lower: float = 0.0,
    upper: float = math.inf,
    prior: float | None = None,
    converged: bool = True,
    ci: tuple[float, float] | None = None,
    ci_rel_width_max: float = STRENGTH_CI_REL_WIDTH_MAX,
    rel_tol: float = BOUND_REL_TOL,
) -> Status:
    """Status of one EMG-to-activation gain (:func:`msk.strength.fit_emg_gains`, ``g ≥ 0``).

    A gain on its bound (0: the channel is switched off) is ``at bound``; a non-finite gain or
    an unconverged fit is ``not determined``; a gain equal to its ``prior`` (start value) within
    :data:`PRIOR_REL_TOL` is ``prior``; a gain without a 95 % interval ``ci`` (its precision is
    not known: the EMG-assisted fit computes none), or whose interval touches a bound or is
    wider than ``ci_rel_width_max`` × the gain, is ``not determined``; else ``identified`` —
    the rule of :func:`strength_status`.
    """
    if not _finite(gain) or not converged:
        return Status.NOT_DETERMINED
    assert gain is not None
    if _on_or_past(gain, lower, upper, rel_tol):
        return Status.AT_BOUND
    if prior is not None and abs(gain - prior) <= PRIOR_REL_TOL * max(abs(prior), 1e-12):
        return Status.PRIOR
    if ci is None or not (_finite(ci[0]) and _finite(ci[1])):
        return Status.NOT_DETERMINED
    lo, hi = float(ci[0]), float(ci[1])
    if _on_or_past(lo, lower, upper, rel_tol) or _on_or_past(hi, lower, upper, rel_tol):
        return Status.NOT_DETERMINED
    if hi - lo > ci_rel_width_max * abs(gain):
        return Status.NOT_DETERMINED
    return Status.IDENTIFIED


def fes_status(
    value: float | None,
    *,
    prior: float | None = None,
    from_prior: bool = False,
    nrmsd_pct: float | None = None,
    determined: bool = True,
    lower: float = -math.inf,
    upper: float = math.inf,
    nrmsd_max_pct: float = FES_NRMSD_MAX_PCT,
    rel_tol: float = BOUND_REL_TOL,
) -> Status:
    """Status of one FES model parameter (the protocol of Benoussaad et al. 2013).

    ``from_prior``: the protocol sets it from an assumption (geometry from the height, the
    K_cm/F_cm and L_c0/(L_c0 + L_s) ratios) → ``prior``; so is a value equal to its ``prior``
    (start value) within :data:`PRIOR_REL_TOL`. Otherwise a value on a bound is ``at bound``;
    a parameter the protocol does not determine (``determined=False``: not in
    :data:`FES_DETERMINED_BY_PROTOCOL`), or whose protocol step fits with an NRMSD above
    ``nrmsd_max_pct`` (or unknown), is ``not determined``; else ``identified``.
    """
    if not _finite(value):
        return Status.NOT_DETERMINED
    assert value is not None
    if from_prior:
        return Status.PRIOR
    if prior is not None and _finite(prior):
        if abs(value - prior) <= PRIOR_REL_TOL * max(abs(prior), 1e-12):
            return Status.PRIOR
    if _on_or_past(value, lower, upper, rel_tol):
        return Status.AT_BOUND
    if not determined or not _finite(nrmsd_pct) or nrmsd_pct > nrmsd_max_pct:  # type: ignore[operator]
        return Status.NOT_DETERMINED
    return Status.IDENTIFIED


# ---------------------------------------------------------------------------------------------
# from the records of summary.json (also for folders written before the status existed)
# ---------------------------------------------------------------------------------------------
def segment_status(seg: Mapping[str, Any]) -> Status:
    """Status of a ``summary.json`` ``identification.segments[*]`` record: its ``status`` when
    present, else :func:`inertia_status` of its mass, COM and their std."""
    if seg.get("status"):
        return Status(seg["status"])
    return inertia_status(
        seg.get("mass_kg"),
        float(seg.get("prior_mass_kg") or 0.0),
        seg.get("mass_std_kg"),
        com=seg.get("com_m"),
        prior_com=seg.get("prior_com_m"),
        com_std=seg.get("com_std_m"),
    )


def group_status(group: Mapping[str, Any], strength: Mapping[str, Any]) -> Status:
    """Status of a ``summary.json`` ``strength.groups[*]`` record (``strength`` the enclosing
    ``strength`` record: bounds and fit r²): its ``status`` when present, else
    :func:`strength_status` — in summaries written before the status existed, ``identified``
    meant only "passed the correlation gate"."""
    lo, hi = strength.get("bounds") or (0.5, 2.0)
    if group.get("status"):
        word = Status(group["status"])
        if word is not Status.IDENTIFIED:
            return word
        # a recorded "identified" is re-checked against the bounds: a factor or interval on a
        # bound is never identified, whoever wrote the file
        f, cl, ch = group.get("factor"), group.get("ci_low"), group.get("ci_high")
        if _finite(f) and _on_or_past(float(f), float(lo), float(hi), BOUND_REL_TOL):  # type: ignore[arg-type]
            return Status.AT_BOUND
        if not (_finite(cl) and _finite(ch)) or any(
            _on_or_past(float(x), float(lo), float(hi), BOUND_REL_TOL)  # type: ignore[arg-type]
            for x in (cl, ch)
        ):
            return Status.NOT_DETERMINED
        return word
    return strength_status(
        group.get("factor"),
        group.get("ci_low"),
        group.get("ci_high"),
        float(lo),
        float(hi),
        strength.get("r2"),
        gated=bool(group.get("gated", group.get("identified", True))),
    )


def status_from_code(code: float) -> Status:
    """The status of a numeric table code (:data:`STATUS_CODES`)."""
    for name, c in STATUS_CODES.items():
        if c == int(code):
            return Status(name)
    raise ValueError(f"unknown status code {code!r}")
