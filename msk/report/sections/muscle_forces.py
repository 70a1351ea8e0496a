"""Section ``muscle_forces``: the largest leg-muscle forces of the side of interest over its
gait cycle (tension optimisation)."""

from __future__ import annotations

from typing import Any

from msk.report.sections.base import ReportContext, Section

__all__ = ["MuscleForces"]


class MuscleForces(Section):
    key = "muscle_forces"
    title = "Muscle forces"
    order = 60

    def context(self, ctx: ReportContext) -> dict[str, Any] | None:
        if not ctx.gait:
            return None
        s = ctx.res.summary
        na = [i for i in s.not_available or () if i.stage in
              ("tension_optimization", "muscle_geometry")][:1]  # fmt: skip
        side = s.subject.side or "right"
        opt = s.optimization
        return {
            "na": na,
            "side": side,
            "title": f"Muscle forces ({side} leg)",
            "method": opt.method if opt else None,
            "criterion": opt.criterion if opt else None,
        }
