"""Section ``knee_loads``: the tibiofemoral contact force — total, medial and lateral (two-point
model) — predicted from the muscle forces, and the patellofemoral contact force (the patella's
third load with the quadriceps and the patellar tendon), against the instrumented implant's
measurement where there is one, and against the in-vivo range of walking peaks (2–3 body
weights: Kutzner et al. 2010; Fregly et al. 2012)."""

from __future__ import annotations

from typing import Any

from msk.report.figures import KNEE_WALKING_PEAK_BW
from msk.report.format import num
from msk.report.sections.base import ReportContext, Section

__all__ = ["KneeLoads"]


class KneeLoads(Section):
    key = "knee_loads"
    title = "Knee contact force"
    order = 50

    def context(self, ctx: ReportContext) -> dict[str, Any] | None:
        if not ctx.gait:
            return None
        res = ctx.res
        na = [i for i in res.summary.not_available or () if i.stage in
              ("knee_contact", "tension_optimization")][:1]  # fmt: skip
        if ctx.figure("contact") is None:
            return {"na": na, "rows": None}
        comp = res.summary.comparison
        rows = []
        strength = res.summary.strength
        # no group's strength applied: the subject-specific prediction is the generic one
        same = strength is not None and strength.applied_groups == ()
        variants = (("generic", "generic parameters"),) + (
            () if same else (("subject_specific", "subject-specific"),)
        )
        for v, vl in variants:
            for part in ("total", "medial", "lateral"):
                c = comp.knee_contact(v, part) if comp else None
                if c:
                    rows.append(
                        [
                            f"{vl}, {c.component}" if c.component else f"{vl}, {part}",
                            num(c.peak_predicted_bw, ".2f", "BW"),
                            num(c.peak_measured_bw, ".2f", "BW"),
                            num(c.rms_bw, ".2f", "BW"),
                            num(c.rms_n, ".0f", "N"),
                            num(c.nrmsd_pct, ".1f", "%"),
                            num(c.pearson_r, ".2f"),
                            num(c.icc, ".2f"),
                        ]
                    )
        lo, hi = KNEE_WALKING_PEAK_BW
        return {
            "na": na,
            "rows": rows,
            "band": f"{lo:g}–{hi:g} BW",
            "patellofemoral": _patellofemoral(res.summary.knee_loads, same),
            "applied": _applied(res.summary.strength),
        }


def _applied(strength: Any) -> str | None:
    """What the subject-specific prediction's model takes from the strength identification
    (``strength.applied_groups``), or None without one."""
    groups = None if strength is None else strength.applied_groups
    if groups is None:
        return None
    if not groups:
        return ("no muscle group's strength is identified, so the subject-specific "
                "prediction is the generic one (its rows are not repeated)")  # fmt: skip
    return (
        f"the subject-specific prediction takes the identified strength of "
        f"{', '.join(groups)}; every other group keeps the generic strength"
    )


def _patellofemoral(loads: Any, generic_only: bool = False) -> str | None:
    """The peak patellofemoral contact force per variant (``knee_loads``; the generic one only
    when ``generic_only``), or None."""
    peaks = None if loads is None else loads.peak_patellofemoral_bw
    if not peaks:
        return None
    if generic_only:
        peaks = {v: p for v, p in peaks.items() if v == "generic"}
    names = {"generic": "generic parameters", "subject_specific": "subject-specific"}
    return "; ".join(f"{names.get(v, v)} {num(p, '.2f', 'BW')}" for v, p in peaks.items())
