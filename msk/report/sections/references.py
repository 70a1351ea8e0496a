"""Section ``references``: every work the report cites, numbered in the order of first
citation (:class:`msk.report.references.Citations`), with authors and year. Rendered last, so
every other section's citations are in."""

from __future__ import annotations

from typing import Any

from msk.report.sections.base import ReportContext, Section

__all__ = ["References"]


class References(Section):
    key = "references"
    title = "References"
    order = 100

    def context(self, ctx: ReportContext) -> dict[str, Any] | None:
        cited = ctx.citations.cited
        return {"cited": cited} if cited else None
