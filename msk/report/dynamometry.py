"""The clinician's page of a dynamometry session: per test the measured strength (N·m, N·m/kg,
interval), the factor against the scaled generic model, the lever-arm assumption, the status
and its reason."""

from __future__ import annotations

import html
from collections.abc import Mapping
from typing import Any

from msk.strength.isometric import TestStrength

__all__ = ["report_html"]


def report_html(summary: Mapping[str, Any], results: tuple[TestStrength, ...] | list[Any]) -> str:
    """The clinician's page: what was identified (torque, per kg, interval, factor vs the
    scaled generic model, lever arm), then what was not, each with its reason."""
    e = html.escape
    s = summary["subject"]
    sex = s.get("sex") or "not given"
    head = (
        f"<h1>Isometric strength — {e(str(s['name']))}</h1><p>Mass {s['mass_kg']:g} kg, "
        f"height {s['height_m']:.2f} m, sex {e(sex)}, side {e(s['side'])}. Maximal isometric "
        "torque of each test's targeted group: the best sustained "
        f"{summary['settings']['plateau_window_s']:g}-s mean of the dynamometer force above "
        "its baseline × the lever arm, plus the antagonists' co-contraction where their EMG "
        "allows; interval 95 % (plateau variability, lever arm, zero of the cell, "
        "co-contraction). Factor: against the generic model (gait2392) scaled to the "
        "subject's height and mass, every agonist fully active at the test posture.</p>"
    )

    def table(rows: list[Any], identified: bool) -> str:
        if not rows:
            return "<p>None.</p>"
        h = (
            "<tr><th>Test</th><th>Torque (N·m)</th><th>95 % interval</th><th>N·m/kg</th>"
            "<th>× scaled generic</th><th>Lever arm</th>"
            + ("" if identified else "<th>Why not determined</th>")
            + "</tr>"
        )
        body = []
        for r in rows:
            cells = [
                e(r.test),
                f"{r.torque_nm:.1f}",
                f"[{r.torque_ci_nm[0]:.1f}, {r.torque_ci_nm[1]:.1f}]",
                f"{r.torque_per_kg:.2f} [{r.torque_per_kg_ci[0]:.2f}, {r.torque_per_kg_ci[1]:.2f}]",
                f"{r.factor:.2f} [{r.factor_ci[0]:.2f}, {r.factor_ci[1]:.2f}]",
                f"{r.lever_arm_m * 100:.1f} ± {r.lever_arm_sd_m * 100:.1f} cm "
                f"({e(r.lever_arm_source.split(':')[0])})",
            ]
            if not identified:
                cells.append(e(r.reason))
            body.append("<tr>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>")
        return f"<table border='1' cellpadding='4'>{h}{''.join(body)}</table>"

    ident = [r for r in results if r.status == "identified"]
    nd = [r for r in results if r.status != "identified"]
    notes = "".join(
        f"<li>{e(r.test)}: lever arm {e(r.lever_arm_source)}; co-contraction: "
        f"{e(r.cocontraction_note)}</li>"
        for r in results
    )
    return (
        "<!doctype html><html><head><meta charset='utf-8'><title>Isometric strength</title>"
        f"</head><body>{head}<h2>Identified</h2>{table(ident, True)}"
        "<h2>Not determined</h2><p>The torque of a test that failed a check is shown for "
        "reference only: it is not the group's strength.</p>"
        f"{table(nd, False)}<h2>Assumptions</h2><ul>{notes}</ul></body></html>\n"
    )
