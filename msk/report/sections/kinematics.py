"""Sections ``kinematics`` and ``kinetics``: the gait-cycle grids — pelvis, hip, knee and ankle
in the sagittal, frontal and transverse planes; internal net joint moments per kg and sagittal
joint powers — each side's mean ± SD over its cycles (left red, right green), a normative band
in grey where one is attached, the foot-off lines."""

from __future__ import annotations

from typing import Any

from msk.report.sections.base import ReportContext, Section
from msk.report.sections.session import event_source_words

__all__ = ["Kinematics", "Kinetics", "angle_notes", "pelvis_frame_words"]


def _cycles(ctx: ReportContext) -> dict[str, Any]:
    res = ctx.res
    curves = ctx.curves()
    src = res.summary.event_sources
    return {
        "n_left": curves.left.n_cycles if curves else 0,
        "n_right": curves.right.n_cycles if curves else 0,
        "sources": {
            side: event_source_words(src, side, "foot strike") for side in ("left", "right")
        },
        "cycle": res.summary.gait_cycle_s,
        "side": res.summary.subject.side or "right",
        "notes": list(curves.notes) if curves else [],
        "norms": ctx.norms,
        "pelvis_frame": pelvis_frame_words(ctx),
        "angle_notes": angle_notes(ctx),
    }


def angle_notes(ctx: ReportContext) -> list[str]:
    """How the hip and knee angles were defined (``summary.json`` ``gait.notes``, written by
    :func:`msk.gait.variables.gait_variables` and :func:`msk.gait.analysis.analyse_gait`)."""
    gait = ctx.res.summary.gait
    notes = (gait.notes or ()) if gait is not None else ()
    return [n for n in notes if n.startswith(("hip angles:", "left knee flexion",
                                              "right knee flexion"))]  # fmt: skip


def pelvis_frame_words(ctx: ReportContext) -> str:
    """The frame the pelvis angles are in (``summary.json`` ``gait.notes``, written by
    :func:`msk.gait.variables.gait_cycles`), "" when the summary does not say."""
    gait = ctx.res.summary.gait
    for note in (gait.notes or ()) if gait is not None else ():
        if note.startswith("pelvis angles in "):
            return note[len("pelvis angles in ") :]
    return ""


class Kinematics(Section):
    key = "kinematics"
    title = "Kinematics over the gait cycle"
    order = 30

    def context(self, ctx: ReportContext) -> dict[str, Any] | None:
        if not ctx.gait or not ctx.res.has("q"):
            return None
        data = _cycles(ctx)
        if not (data["n_left"] or data["n_right"]):
            data["title"] = "Kinematics over the trial"
        return data


class Kinetics(Section):
    key = "kinetics"
    title = "Kinetics over the gait cycle"
    order = 40

    def context(self, ctx: ReportContext) -> dict[str, Any] | None:
        if not ctx.gait or not ctx.res.has("joint_torques"):
            return None
        data = _cycles(ctx)
        if not (data["n_left"] or data["n_right"]):
            data["title"] = "Kinetics over the trial"
        return data
