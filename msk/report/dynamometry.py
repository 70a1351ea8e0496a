"""The clinician's page of a dynamometry session: per test the measured strength (N·m, N·m/kg,
95 % interval) beside the published band for the subject's age, the factor against the scaled
generic model, the lever-arm assumption, which tests passed the trial and EMG checks and why
the others did not — from the template ``templates/dynamometry.html.j2`` (autoescaped)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from markupsafe import Markup

from msk.report.format import render
from msk.strength.isometric import CHECKS_FAILING, TestStrength

__all__ = ["report_html"]


def _band(r: Any) -> str:
    lo, hi = r.band_nm_per_kg
    if math.isnan(lo):
        return "none for this age"
    return f"{lo:.2f}–{hi:.2f}" + (" (below)" if r.below_band else "")


def _checks(r: Any) -> str:
    failed = sorted({f.quantity for f in r.flags if f.quantity in CHECKS_FAILING})
    if failed:
        return "failed: " + ", ".join(q.replace("_", " ") for q in failed)
    if r.status != "identified":
        return "passed; interval too wide"
    return "passed; below the published band" if r.below_band else "passed"


def _rows(results: list[Any], identified: bool) -> list[list[str]]:
    rows = []
    for r in results:
        cells = [
            str(r.test),
            f"{r.torque_nm:.1f}",
            f"[{r.torque_ci_nm[0]:.1f}, {r.torque_ci_nm[1]:.1f}]",
            f"{r.torque_nm_per_kg:.2f} [{r.torque_nm_per_kg_ci[0]:.2f}, "
            f"{r.torque_nm_per_kg_ci[1]:.2f}]",
            _band(r),
            f"{r.factor:.2f} [{r.factor_ci[0]:.2f}, {r.factor_ci[1]:.2f}]",
            f"{r.lever_arm_m * 100:.1f} ± {r.lever_arm_sd_m * 100:.1f} cm "
            f"({str(r.lever_arm_source).split(':')[0]})",
            _checks(r),
        ]
        if not identified:
            cells.append(str(r.reason))
        rows.append(cells)
    return rows


def _check_notes(r: Any) -> str:
    """One test's checks in words: the failed ones with their messages, else "every check
    passed", and the plausibility flag when raised."""
    failed = [f.message for f in r.flags if f.quantity in CHECKS_FAILING]
    band = [
        f"{f.value:.2f} N·m/kg is below the published band "
        f"{r.band_nm_per_kg[0]:.2f}–{r.band_nm_per_kg[1]:.2f} N·m/kg (source under "
        "Assumptions): submaximal effort, strap slip or the lever-arm assumption — or a true "
        "weakness"
        for f in r.flags
        if f.quantity == "below_published_band"
    ]
    if failed:
        text = "failed — " + "; ".join(failed)
    elif r.status != "identified":
        text = "every trial and EMG check passed, but " + str(r.reason)
    else:
        text = "every trial and EMG check passed (the target the most active channel, rest "
        text += "baseline or tared zero, plateau held, no saturation)"
    return text + ("; " + band[0] if band else "")


def report_html(summary: Mapping[str, Any], results: tuple[TestStrength, ...] | list[Any]) -> str:
    """The clinician's page: what was identified (torque, per kg, interval, published band,
    factor vs the scaled generic model, lever arm, checks), then what was not, each with its
    reason; the checks of every test and the assumptions (lever arm, co-contraction, band)."""
    from msk.report.html import CONTENT_SECURITY_POLICY

    s = summary["subject"]
    ident = [r for r in results if r.status == "identified"]
    nd = [r for r in results if r.status != "identified"]
    head = [
        "Test",
        "Torque (N·m)",
        "95 % interval",
        "N·m/kg [95 %]",
        "Published band (N·m/kg)",
        "× scaled generic",
        "Lever arm",
        "Checks",
    ]
    age = s.get("age_years")
    return (
        render(
            "dynamometry.html.j2",
            csp=Markup(CONTENT_SECURITY_POLICY),
            name=str(s["name"]),
            mass=f"{s['mass_kg']:g}",
            height=f"{s['height_m']:.2f}",
            age="not given" if age is None else f"{age:g} y",
            sex=s.get("sex") or "not given (published bands sex-pooled)",
            side=s["side"],
            window=f"{summary['settings']['plateau_window_s']:g}",
            head=head,
            identified=_rows(ident, True),
            not_determined=_rows(nd, False),
            n_below=sum(r.below_band for r in ident),
            checks=[(r.test, _check_notes(r)) for r in results],
            notes=[(r.test, r.lever_arm_source, r.cocontraction_note) for r in results],
            bands=sorted({(r.action, r.band_source) for r in results if r.band_source}),
        )
        + "\n"
    )
