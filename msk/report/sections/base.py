"""The report section: its key, title and place (``order``), and how it renders from a
:class:`ReportContext` — the results folder, the figures, the numbering of sections and
citations shared by every section of one report."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

from msk.gait.norms import NormativeBands
from msk.report.cycles import CycleCurves, pooled_curves
from msk.report.format import render
from msk.report.references import Citations
from msk.results.folder import SessionResults

__all__ = ["ReportContext", "Section"]


@dataclass
class ReportContext:
    """What the sections of one report share.

    Attributes:
        res: the session's results (tables and the typed summary).
        figures: the report's figures by name (inline SVG; a missing name is not drawn).
        gait: whether the session has gait results (False: an FES-only session).
        norms: the normative bands the grids draw (None: none attached).
        trials: the results of every task trial of the session (``res`` among them) whose
            cycles and strides the gait sections pool; empty: ``res`` alone.
        citations: the numbering of the works cited, in the order of first citation.
        sections: the numbers given so far (section key → number).
    """

    res: SessionResults
    figures: Mapping[str, str]
    gait: bool = True
    norms: NormativeBands | None = None
    trials: tuple[SessionResults, ...] = ()
    citations: Citations = field(default_factory=Citations)
    sections: dict[str, int] = field(default_factory=dict)
    _curves: list[CycleCurves | None] = field(default_factory=list, repr=False)

    def curves(self) -> CycleCurves | None:
        """Every gait cycle of both legs (:func:`msk.report.cycles.curves_from_tables`), once."""
        if not self._curves:
            self._curves.append(pooled_curves(self.trials or (self.res,)))
        return self._curves[0]

    def cite(self, *keys: str) -> str:
        return self.citations.cite(*keys)

    def number(self, key: str) -> int:
        """The section number of ``key``: the next one at its first call."""
        if key not in self.sections:
            self.sections[key] = len(self.sections) + 1
        return self.sections[key]

    def figure(self, name: str) -> str | None:
        return self.figures.get(name)


class Section(ABC):
    """One section of the report: ``context`` gathers what its template prints (None: the
    section is left out of this report), ``render`` numbers it and fills its template
    (``templates/sections/<key>.html.j2``)."""

    key: ClassVar[str]
    title: ClassVar[str]
    order: ClassVar[int]

    @abstractmethod
    def context(self, ctx: ReportContext) -> dict[str, Any] | None:
        """The template's variables, or None when the section has nothing for this session."""

    def render(self, ctx: ReportContext) -> str | None:
        data = self.context(ctx)
        if data is None:
            return None
        return render(
            f"sections/{self.key}.html.j2",
            n=ctx.number(self.key),
            key=self.key,
            title=data.pop("title", self.title),
            cite=ctx.cite,
            figure=ctx.figure,
            **data,
        )
