"""The clinician's page of a dynamometry session: per test the measured strength (N·m, N·m/kg,
interval), the factor against the scaled generic model, the lever-arm assumption, the status
and its reason — from the template ``templates/dynamometry.html.j2`` (autoescaped)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from markupsafe import Markup

from msk.report.format import render
from msk.strength.isometric import TestStrength

__all__ = ["report_html"]


def _rows(results: list[Any], identified: bool) -> list[list[str]]:
    rows = []
    for r in results:
        cells = [
            str(r.test),
            f"{r.torque_nm:.1f}",
            f"[{r.torque_ci_nm[0]:.1f}, {r.torque_ci_nm[1]:.1f}]",
            f"{r.torque_per_kg:.2f} [{r.torque_per_kg_ci[0]:.2f}, {r.torque_per_kg_ci[1]:.2f}]",
            f"{r.factor:.2f} [{r.factor_ci[0]:.2f}, {r.factor_ci[1]:.2f}]",
            f"{r.lever_arm_m * 100:.1f} ± {r.lever_arm_sd_m * 100:.1f} cm "
            f"({str(r.lever_arm_source).split(':')[0]})",
        ]
        if not identified:
            cells.append(str(r.reason))
        rows.append(cells)
    return rows


def report_html(summary: Mapping[str, Any], results: tuple[TestStrength, ...] | list[Any]) -> str:
    """The clinician's page: what was identified (torque, per kg, interval, factor vs the
    scaled generic model, lever arm), then what was not, each with its reason."""
    from msk.report.html import CONTENT_SECURITY_POLICY

    s = summary["subject"]
    ident = [r for r in results if r.status == "identified"]
    nd = [r for r in results if r.status != "identified"]
    head = ["Test", "Torque (N·m)", "95 % interval", "N·m/kg", "× scaled generic", "Lever arm"]
    return (
        render(
            "dynamometry.html.j2",
            csp=Markup(CONTENT_SECURITY_POLICY),
            name=str(s["name"]),
            mass=f"{s['mass_kg']:g}",
            height=f"{s['height_m']:.2f}",
            sex=s.get("sex") or "not given",
            side=s["side"],
            window=f"{summary['settings']['plateau_window_s']:g}",
            head=head,
            identified=_rows(ident, True),
            not_determined=_rows(nd, False),
            notes=[(r.test, r.lever_arm_source, r.cocontraction_note) for r in results],
        )
        + "\n"
    )
