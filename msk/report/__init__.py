"""The clinician report: a self-contained HTML page (and a PDF when Chromium is available).

Built from result objects only (:class:`msk.results.folder.SessionResults`: the tables and
``summary.json`` of a run as a typed :class:`msk.results.summary.Summary`, read by attribute), never
from the pipeline's internals, so ``msk report DIR`` can rebuild it from a session folder. A
``SessionResults`` built with a plain summary mapping converts it on construction
(:func:`msk.results.summary.as_summary`).

The page is a family of sections (:mod:`msk.report.sections`: a base, a registry, one module per
section) whose HTML comes from Jinja2 templates (``msk/report/templates``, autoescaped: every
string of a summary is data, never markup); figures are inline SVG written directly
(:mod:`msk.report.svg`); CSS is inline, with print rules that keep headings with their content.
Every number carries its unit; every plot has labelled axes with units and a legend.
"""

from __future__ import annotations

from msk.report.html import build_figures, render_html, write_pdf, write_report

__all__ = ["build_figures", "render_html", "write_pdf", "write_report"]
