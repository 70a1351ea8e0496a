"""Stage ``report``: the report's figures (:func:`msk.report.build_figures`), cached on the
content of the tables and the summary sections they draw; the report itself is written with the
results folder (:func:`msk.pipeline.session.run_session`)."""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from typing import Any

import numpy as np

from msk.io.tables import Table
from msk.pipeline.inputs import SessionInputs
from msk.results.folder import SessionResults

__all__ = ["run", "settings"]

#: summary.json sections the figures draw
FIGURE_SECTIONS = (
    "gait_cycle_s",
    "events",
    "gait",
    "subject",
    "identification",
    "strength",
    "anthropometry",
    "comparison",
    "fes",
)


def settings(inputs: SessionInputs, tables: Mapping[str, Table], summary: Mapping[str, Any]) -> Any:
    return [
        [
            (n, tb.columns, hashlib.sha256(np.ascontiguousarray(tb.data).tobytes()).hexdigest())
            for n, tb in tables.items()
        ],
        [summary.get(k) for k in FIGURE_SECTIONS],
    ]


def run(
    inputs: SessionInputs, tables: Mapping[str, Table], summary: Mapping[str, Any]
) -> dict[str, str]:
    """Figure name → SVG/PNG text of the report."""
    from msk.report import build_figures

    res = SessionResults(dict(tables), summary, None, tuple(summary["angle_columns"]))
    return build_figures(res)
