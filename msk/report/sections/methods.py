"""Section ``methods``: the chain of methods of this session (with the static trial only when
the session has one), filtering, scaling and marker placement, the stages with their status and
time, the tension optimisation's KKT check and EMG gains, software versions and input files."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import PurePath
from typing import Any

from markupsafe import Markup

from msk.report.format import check, num, or_, status_html
from msk.report.sections.base import ReportContext, Section
from msk.results.summary import Kkt
from msk.status import gain_status

__all__ = ["Methods"]


def _scaling_note(model: Any) -> str:
    """How each leg segment was scaled (``summary.model.scaling`` and ``.leg_split``)."""
    bodies = dict(((model.scaling or {}).get("bodies") or {}) if model is not None else {})
    if not bodies:
        return ""
    legs = [b for b in bodies if b.split("_")[0] in ("pelvis", "femur", "tibia", "calcn")]
    parts = [f"{b} × {float(bodies[b]['factors'][0]):.3f} ({bodies[b]['method']})" for b in legs]
    text = "Scaling of the leg segments: " + "; ".join(parts) + "."
    split = dict(model.leg_split or {})
    for side, sp in sorted(split.items()):
        how = str(sp.get("method"))
        why = str(sp.get("reason") or "")
        text += (
            f" Femur : tibia split, {'right' if side == 'r' else 'left'} leg (no knee or ankle "
            f"marker; one pelvis-to-heel factor {float(sp.get('leg_factor', 1.0)):.3f}): {how}"
            + (f" — {why}" if why else "")
            + "."
        )
    return text


def _placement_note(model: Any) -> str:
    """Which leg coordinates' means a placement from the motion leaves undetermined
    (``summary.model.placement_determinacy``)."""
    det = dict((model.placement_determinacy or {}) if model is not None else {})
    coords = dict(det.get("coordinates") or {})
    if not coords:
        return ""
    tol_mm = 1000 * float(det.get("tolerance_m", 0.0))

    def part(name: str, c: Mapping[str, Any]) -> str:
        dm = [float(v) for v in c.get("mean_change_deg", ())]
        dc = [1000 * float(v) for v in c.get("cost_change_m", ())]
        shifts = ", ".join(f"{m:+.1f}° → {d:+.3f} mm" for m, d in zip(dm, dc))
        verdict = c.get("prior") or c.get("status")  # "set by prior: …" when a prior sets it
        return f"{name} {float(c.get('mean_deg', 0.0)):.1f}° ({shifts}): {verdict}"

    return (
        "Marker placement from the task (no static trial): each leg coordinate's mean shifted "
        f"by ±{float(det.get('shift_deg', 0.0)):g}° with the markers distal to its joint kept "
        "in place, the task's frames refitted (change of the mean → change of the task IK "
        f"cost; within {tol_mm:.1f} mm or below: not determined by the markers): "
        + "; ".join(part(n, c) for n, c in coords.items())
        + "."
    )


def _static_window(win: Any) -> str:
    if not win:
        return ""
    rule = (
        f"markers' 90th-percentile speed ≤ {1000 * float(win.get('still_below_m_s') or 0.0):.0f}"
        " mm/s"
        + (
            ""
            if win.get("plates_loaded") is None
            else f", {win.get('plates_loaded')} plates loaded"
        )
    )
    if win.get("judged") is False:
        return "the whole trial (too short to judge whether it moves)"
    if win.get("whole_trial"):
        return f"the whole trial, still throughout ({rule})"
    return (
        f"{win.get('start_s', 0.0):.2f}–{win.get('end_s', 0.0):.2f} s "
        f"({win.get('frames')} of {win.get('of_frames')} frames), its longest "
        f"still, double-stance part ({rule})"
    )


def _kkt(kkt: Kkt) -> dict[str, Any]:
    tol = kkt.relative_tolerance
    rows = []
    figures = {
        "stationarity": kkt.stationarity,
        "primal_feasibility": kkt.primal_feasibility,
        "dual_feasibility": kkt.dual_feasibility,
        "complementarity": kkt.complementarity,
    }
    for name, f in figures.items():
        if f is None:
            continue
        rows.append(
            [
                name.replace("_", " "),
                num(f.max, ".1e"),
                num(f.relative_max, ".1e"),
                or_(f.frame, "—"),
                num(f.time_s, ".3f", "s"),
                check(f.relative_max, tol) if tol is not None else "—",
            ]
        )
    return {"frames": or_(kkt.frames, "—"), "tol": num(tol, ".0e"), "rows": rows}


class Methods(Section):
    key = "methods"
    title = "Methods, stages and software"
    order = 90

    def context(self, ctx: ReportContext) -> dict[str, Any] | None:
        s = ctx.res.summary
        static = any(i.role == "static" for i in s.inputs)
        win = s.model.static_window if s.model is not None else None
        stages = [
            [
                r.name,
                Markup('<span class="na">{}</span>').format(r.status)
                if r.status in ("not available", "failed")
                else r.status,
                num(r.seconds, ".2f", "s"),
                or_(r.message, ""),
            ]
            for r in s.stages or ()
        ]
        opt = s.optimization
        gains = []
        if opt and opt.emg_gains:
            gst = opt.emg_gain_status or {}
            gains = [
                [c, num(g, ".3f"), status_html(gst.get(c) or gain_status(g).value)]
                for c, g in opt.emg_gains.items()
            ]
        return {
            "gait": ctx.gait,
            "fes": bool(s.fes),
            "static": static,
            "plate_assignment": or_(s.methods.plate_assignment if s.methods else None, "?"),
            "filtering": s.methods.filtering if s.methods else None,
            "scaling": _scaling_note(s.model),
            "placement": _placement_note(s.model),
            "static_window": _static_window(win) if static else "",
            "stages": stages,
            "opt": opt,
            "frames_solved": ", ".join(
                f"{k} {int(v)}" for k, v in (opt.frames_solved or {}).items()
            )
            if opt
            else "",
            "kkt": _kkt(opt.kkt) if opt and opt.kkt is not None else None,
            "gains": gains,
            "versions": [[k, v] for k, v in s.versions.items()],
            "inputs": [[i.role, PurePath(i.path).name, i.sha256[:16] + "…"] for i in s.inputs],
        }
