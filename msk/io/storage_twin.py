"""The OpenSim ``.sto``/``.mot`` twin of a result table that OpenSim's legacy ``Storage`` reads to
its last row.

OpenSim 4.6 has two readers of the same files. ``TimeSeriesTable`` (the STO file adapter) reads
``NaN``; the legacy ``Storage`` (the GUI's Load Motion and Plotter, AnalyzeTool, CMC) reads each
value with C++ stream extraction, which parses no spelling of a missing value (``nan``, ``NaN``,
``NAN``, ``-nan``, ``1.#QNAN`` were tried on OpenSim 4.6): it stops at the first one and the file
loads as the rows before it (a known OpenSim limitation, opensim-core issue 2505). An empty
cell shifts every later value. So no cell of a twin may be missing, and no number can stand
for "missing" without being read as a measurement.

The twin therefore holds the largest complete block of the table: columns that are missing on
many rows (an estimate msk did not compute for this trial, or the implant's measured force
outside its measured cycle) are left out when that keeps more values than leaving out rows,
then every row that still holds a missing value is left out, and a row whose time does not
advance past the previous kept row's (``Storage`` keeps one row per time: a gait-cycle table's
100 % row is the next cycle's 0 % instant). Among the column subsets "every
column finite on at least ``c`` rows" (one per distinct count ``c``) the one keeping the most
values ``rows × columns`` wins (ties: more rows). What is left out is listed in the twin's
header (``key=value`` lines both readers keep as metadata) and returned; the CSV table keeps
every row and column, ``nan`` where missing.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from msk.io.tables import Table

__all__ = ["StorageTwin", "index_ranges", "storage_twin"]


@dataclass(frozen=True)
class StorageTwin:
    """The complete block of a table: ``table`` (its rows and columns subset), ``rows_left_out``
    (row indices of the source table) and ``columns_left_out`` (names), and the ``header`` lines
    (``key=value``) that list them."""

    table: Table
    rows_left_out: NDArray[np.int64]
    columns_left_out: tuple[str, ...]

    @property
    def header(self) -> dict[str, str]:
        if not self.rows_left_out.size and not self.columns_left_out:
            return {}
        return {
            "msk_missing": "rows and columns holding a missing value (NaN), and rows repeating "
            "the previous row's time, are left out: OpenSim's Storage cannot read NaN and keeps "
            "one row per time; the CSV table has them",
            "msk_rows_left_out": index_ranges(self.rows_left_out) or "none",
            "msk_columns_left_out": ",".join(self.columns_left_out) or "none",
        }


def index_ranges(idx: Sequence[int] | NDArray[np.int64]) -> str:
    """Sorted indices as ranges: ``[0, 1, 2, 7, 9, 10]`` → ``"0-2,7,9-10"``."""
    out: list[str] = []
    ids = sorted(int(i) for i in idx)
    k = 0
    while k < len(ids):
        j = k
        while j + 1 < len(ids) and ids[j + 1] == ids[j] + 1:
            j += 1
        out.append(f"{ids[k]}" if j == k else f"{ids[k]}-{ids[j]}")
        k = j + 1
    return ",".join(out)


def storage_twin(table: Table) -> StorageTwin:
    """The largest complete block of ``table`` (module docstring): every value it holds is
    finite and unchanged."""
    x = np.asarray(table.data, dtype=float).reshape(table.time.size, -1)
    finite = np.isfinite(x)
    t = np.asarray(table.time, dtype=float)
    if finite.all() and (t.size < 2 or bool((np.diff(t) > 0).all())):
        return StorageTwin(table, np.zeros(0, dtype=np.int64), ())
    counts = finite.sum(axis=0)
    best: tuple[int, int, NDArray[np.bool_], NDArray[np.bool_]] | None = None
    for c in sorted({int(v) for v in counts if v > 0}, reverse=True):
        cols = counts >= c
        rows = finite[:, cols].all(axis=1)
        score = (int(rows.sum()) * int(cols.sum()), int(rows.sum()))
        if best is None or score > best[:2]:
            best = (*score, rows, cols)
    if best is None:  # no finite value at all: no row, no column
        rows = np.zeros(x.shape[0], dtype=bool)
        cols = np.zeros(x.shape[1], dtype=bool)
    else:
        rows, cols = best[2], best[3]
    rows = rows & _time_advances(t, rows)
    kept = Table(
        time=t[rows],
        data=x[np.ix_(rows, cols)],
        columns=tuple(c for c, k in zip(table.columns, cols) if k),
        name=table.name,
        angle_columns=tuple(
            c for c, k in zip(table.columns, cols) if k and c in table.angle_columns
        ),
    )
    return StorageTwin(
        kept,
        np.flatnonzero(~rows).astype(np.int64),
        tuple(c for c, k in zip(table.columns, cols) if not k),
    )


def _time_advances(t: NDArray[np.float64], rows: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Of the rows ``rows`` keeps, those whose time is later than the previous kept row's:
    ``Storage`` keeps one row per time (a gait-cycle table's 100 % row is the next cycle's 0 %
    instant: the later of the two is left out)."""
    out = np.zeros(t.size, dtype=bool)
    last = -np.inf
    for k in np.flatnonzero(rows):
        if t[k] > last:
            out[k] = True
            last = t[k]
    return out
