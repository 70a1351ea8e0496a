"""Why each strength group is, or is not, identified: its status and a reason in plain words.

Identifiability is judged per group, on the regression of Hayashibe et al. (2011, §V, Eq. 16)
that :class:`msk.strength.StrengthIdentifier` fits:

* its **excitation** — the group's activation must rise (the identifier's ``min_excitation``)
  and its muscles must have a moment arm about a regressed coordinate;
* the **correlation gate** (Hayashibe et al. 2011, §VI.C) — its EMG-driven moment must follow
  the joint moment in enough windows, else it keeps the generic strength (``prior``);
* its **own rows' fit** — r²_g, the mean over the coordinates its muscles cross of the fit r² of
  those coordinates' selected rows (a session-wide mean would let rows of muscles nobody asked
  about hide a group that fits, or the reverse);
* its **interval** — inside the bounds and no wider than the factor
  (:data:`msk.status.STRENGTH_CI_REL_WIDTH_MAX`);
* **confounding** — the correlation ρ_gh = Σ_gh / √(Σ_gg Σ_hh) of two groups' factor estimates
  from the regression covariance Σ (the delete-one-window jackknife of the identifier): with
  |ρ| ≥ :data:`CONFOUNDED_R` their columns of the design are nearly proportional, and the data
  cannot share the moment between them (Belsley, Kuh & Welsch 1980, *Regression Diagnostics*,
  §3.2: variance inflation through collinear columns).

The status words are those of :mod:`msk.status` (:func:`msk.status.strength_status` with r²_g);
a factor on a bound is ``at bound`` and never ``identified``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from msk.status import STRENGTH_CI_REL_WIDTH_MAX, STRENGTH_R2_MIN, Status, strength_status

__all__ = [
    "CONFOUNDED_R",
    "GroupDiagnosis",
    "diagnose",
    "group_r2",
    "joint_strength_or_error",
    "strength_summary",
]

#: |correlation| of two groups' factor estimates at or above which they are called confounded:
#: at 0.9 the variance inflation 1/(1 − ρ²) is above 5, the usual collinearity alarm (Belsley,
#: Kuh & Welsch 1980, §3.2; a VIF above 5–10).
CONFOUNDED_R = 0.9


@dataclass(frozen=True)
class GroupDiagnosis:
    """One group: ``status`` (a :class:`msk.status.Status` value), ``reason`` in plain words,
    ``r2`` the fit r² of its own rows (NaN when none was fitted), ``coordinates`` those rows'
    coordinates, ``confounded_with`` the groups whose estimates correlate with its own at
    |ρ| ≥ :data:`CONFOUNDED_R` and ``correlation`` those ρ."""

    group: str
    status: str
    reason: str
    r2: float
    coordinates: tuple[str, ...]
    confounded_with: tuple[str, ...]
    correlation: tuple[float, ...]


def _own_coordinates(profile: Any, g: int) -> list[int]:
    acts = getattr(profile, "acts", None)
    r2c = np.asarray(profile.r2_per_coordinate, dtype=float)
    if acts is None:  # not recorded: the coordinates where its gating correlation exists
        acting = np.isfinite(np.asarray(profile.gating_r)[:, g, :]).any(axis=0)
    else:
        acting = np.asarray(acts, dtype=bool)[g]
    return [j for j in range(r2c.size) if acting[j] and math.isfinite(r2c[j])]


def group_r2(profile: Any, g: int) -> float:
    """Fit r² of group ``g``'s own rows: the mean of ``profile.r2_per_coordinate`` over the
    regressed coordinates its muscles cross (NaN when it crosses none)."""
    own = _own_coordinates(profile, g)
    if not own:
        return float("nan")
    return float(np.mean(np.asarray(profile.r2_per_coordinate, dtype=float)[own]))


def _fmt(x: float) -> str:
    return f"{x:.2f}" if math.isfinite(x) else "n/a"


def diagnose(
    profile: Any,
    *,
    r2_min: float | None = None,
    confounded_r: float = CONFOUNDED_R,
    ci_rel_width_max: float = STRENGTH_CI_REL_WIDTH_MAX,
) -> tuple[GroupDiagnosis, ...]:
    """Status and reason of every group of a :class:`msk.strength.StrengthProfile` (module
    docstring for the criteria), in :attr:`group_names` order."""
    r2_min = STRENGTH_R2_MIN if r2_min is None else float(r2_min)
    lo, hi = (float(b) for b in profile.bounds)
    names: Sequence[str] = profile.group_names
    cnames: Sequence[str] = profile.coordinate_names
    corr = getattr(profile, "factor_correlation", None)
    excited = getattr(profile, "excited", None)
    out = []
    for g, name in enumerate(names):
        own = _own_coordinates(profile, g)
        r2g = group_r2(profile, g)
        f = float(profile.factors[g])
        cl, ch = float(profile.ci_low[g]), float(profile.ci_high[g])
        gated = bool(profile.identified[g])
        conf: list[tuple[str, float]] = []
        if corr is not None and gated:
            row = np.asarray(corr, dtype=float)[g]
            conf = [
                (names[h], float(row[h]))
                for h in range(len(names))
                if h != g and math.isfinite(row[h]) and abs(row[h]) >= confounded_r
            ]
        if excited is not None and not bool(excited[g]):
            status = Status.NOT_DETERMINED
        else:
            status = strength_status(
                f, cl, ch, lo, hi, r2g, gated=gated, r2_min=r2_min,
                ci_rel_width_max=ci_rel_width_max,
            )  # fmt: skip
        clauses: list[str] = []
        acting = getattr(profile, "acts", None)
        crosses = acting is None or bool(np.asarray(acting, dtype=bool)[g].any())
        if excited is not None and not bool(excited[g]):
            clauses.append(
                "never excited: its EMG never rises to a contraction in these trials, so the "
                "data hold no information on its strength (kept at the generic strength)"
            )
        elif not crosses:
            clauses.append(
                "never excited: its muscles have a negligible moment arm about every "
                "regressed joint (kept at the generic strength)"
            )
        elif not gated:
            clauses.append(
                "its EMG-driven moment never follows the joint moment in enough windows (the "
                f"correlation gate R ≥ {profile.gate_threshold:.2f}): kept at the generic "
                "strength, the data did not change it"
            )
        elif status == Status.AT_BOUND:
            side = "below" if f <= lo + 1e-9 else "above"
            clauses.append(
                f"at bound: the data ask for a factor {side} the plausible range "
                f"{lo:g}–{hi:g}× generic, so the bound ({f:.2f}), not the data, fixed it"
            )
        if conf and status != Status.IDENTIFIED and gated:
            clauses.append(
                "confounded with "
                + ", ".join(f"{h} (estimates correlated ρ = {r:+.2f})" for h, r in conf)
                + ": their moment columns are nearly proportional and the data cannot share "
                "the moment between them"
            )
        if status == Status.NOT_DETERMINED and gated and (excited is None or excited[g]):
            if not (math.isfinite(cl) and math.isfinite(ch)):
                clauses.append("no interval could be computed for its factor")
            elif cl <= lo * (1 + 1e-6) or ch >= hi * (1 - 1e-6):
                clauses.append(
                    f"its interval [{cl:.2f}, {ch:.2f}] touches a bound of the plausible range "
                    f"{lo:g}–{hi:g}× generic: the data allow factors outside it"
                )
            elif ch - cl > ci_rel_width_max * abs(f):
                clauses.append(
                    f"its interval [{cl:.2f}, {ch:.2f}] is wider than the factor {f:.2f} itself"
                )
            if not (math.isfinite(r2g) and r2g >= r2_min):
                clauses.append(
                    f"fit too poor on its own rows: r² {_fmt(r2g)} < {r2_min:g} on "
                    + (", ".join(cnames[j] for j in own) or "no fitted coordinate")
                )
        if status == Status.IDENTIFIED:
            clauses.append(
                f"identified: factor {f:.2f} [{cl:.2f}, {ch:.2f}] inside the plausible range, "
                f"fit r² {r2g:.2f} on its own rows (" + ", ".join(cnames[j] for j in own) + ")"
            )
        if not clauses:  # every status has a clause above; kept as a guard for new rules
            clauses.append(str(status))
        out.append(
            GroupDiagnosis(
                group=str(name),
                status=status.value,
                reason="; ".join(clauses),
                r2=r2g,
                coordinates=tuple(cnames[j] for j in own),
                confounded_with=tuple(h for h, _ in conf),
                correlation=tuple(r for _, r in conf),
            )
        )
    return tuple(out)


def joint_strength_or_error(
    strength: Any, model: Any, side: str, mass_kg: float | None
) -> dict[str, Any] | None:
    """``summary.strength.joint_strength``: the maximal isometric moment curves of the generic
    and the identified model (:func:`msk.strength.joint_strength_summary` of ``strength``'s
    profile), None without muscles, ``{"error": ...}`` when they cannot be computed (the
    curves must not cost a run its strength summary)."""
    if model is None or not model.muscles:
        return None
    from msk.strength.joint_strength import joint_strength_summary

    try:
        return joint_strength_summary(model, strength.profile, side=side, mass_kg=mass_kg)
    except Exception as exc:  # the curves must not cost the run its strength summary
        return {"error": f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}"}


_COMPUTE = object()  # strength_summary's default: compute the joint curves


def strength_summary(
    strength: Any,
    *,
    model: Any = None,
    side: str = "_r",
    mass_kg: float | None = None,
    joint: Any = _COMPUTE,
) -> dict[str, Any]:
    """``summary.strength`` of a strength identification (its ``profile``, ``groups``,
    ``protocols`` and ``failed`` channels): per group the factor, its intervals, F_iso and the
    :mod:`msk.status` word with its reason (:func:`diagnose`); ``identified`` = status
    "identified"; ``gated`` = the group passed the correlation gate. With the (generic,
    scaled) ``model``: ``joint_strength``, the maximal isometric moment curves of the generic
    and the identified model (:func:`joint_strength_or_error`), N·m and N·m/kg; ``joint``:
    those already computed."""
    from msk.status import STATUS_CODES, STATUS_MEANING

    p = strength.profile
    diag = diagnose(p)
    status = tuple(d.status for d in diag)
    protocols = getattr(strength, "protocols", None) or {}
    if joint is _COMPUTE:
        joint = joint_strength_or_error(strength, model, side, mass_kg)
    return {
        "groups": [
            {
                "group": n,
                "muscles": list(strength.groups.get(n, [])),
                "factor": float(p.factors[g]),
                "ci_low": float(p.ci_low[g]),
                "ci_high": float(p.ci_high[g]),
                "ci_cov_low": float(p.ci_cov_low[g]),
                "ci_cov_high": float(p.ci_cov_high[g]),
                "f_iso_generic_n": float(p.f_iso_generic[g]),
                "f_iso_n": float(p.f_iso[g]),
                "status": status[g],
                "identified": status[g] == "identified",
                "gated": bool(p.identified[g]),
                "reason": diag[g].reason,
                "r2": diag[g].r2 if math.isfinite(diag[g].r2) else None,
                "r2_coordinates": list(diag[g].coordinates),
                "confounded_with": list(diag[g].confounded_with),
                "protocol": protocols.get(n),
            }
            for g, n in enumerate(p.group_names)
        ],
        "r2": float(p.r2),
        "r2_min": STRENGTH_R2_MIN,
        "status_codes": dict(STATUS_CODES),
        "status_meaning": dict(STATUS_MEANING),
        "confidence": float(p.confidence),
        "bounds": list(p.bounds),
        "method": p.method,
        "applied_groups": [n for g, n in enumerate(p.group_names) if status[g] == "identified"],
        "joint_strength": joint,
        "failed_channels": [
            {
                "group": n,
                "muscles": list(rec.get("muscles", [])),
                "status": "not determined",
                "identified": False,
                "gated": False,
                "reason": rec.get("reason"),
                "protocol": rec.get("protocol"),
            }
            for n, rec in (getattr(strength, "failed", None) or {}).items()
        ],
    }
