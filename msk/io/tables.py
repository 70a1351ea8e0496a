"""CSV result tables: first column ``time`` (s), then named columns in SI units.

This is the contract other tools read (``tables/*.csv`` of a run). Writes are atomic: the
table is written to a temporary file in the same folder and renamed, so a failed run never
leaves a half-written table behind.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from msk.exceptions import FileFormatError
from msk.io.opensim_files import Table, _atomic_write
from msk.io.validate import check_regular_file

__all__ = ["read_csv_table", "write_csv_table"]


def write_csv_table(
    path: str | Path,
    table: Table | None = None,
    *,
    time: ArrayLike | None = None,
    data: ArrayLike | None = None,
    columns: Sequence[str] | None = None,
) -> Path:
    """Write ``time`` + named columns as CSV (full float precision, ``nan`` for missing)."""
    path = Path(path)
    if table is not None:
        time, data, columns = table.time, table.data, table.columns
    if time is None or data is None or columns is None:
        raise FileFormatError(f"{path}: pass a Table or time, data and columns")
    t = np.asarray(time, dtype=float).reshape(-1)
    x = np.asarray(data, dtype=float).reshape(t.size, -1)
    cols = tuple(columns)
    if x.shape[1] != len(cols):
        raise FileFormatError(f"{path}: {x.shape[1]} data columns but {len(cols)} names")
    bad = [c for c in cols if not c or any(ch in c for ch in ',"\n\r') or c == "time"]
    if bad:
        raise FileFormatError(f"{path}: invalid CSV column names {bad}")
    body = np.column_stack([t, x])
    rows = [",".join(r) for r in np.char.mod("%.17g", body)] if body.size else []
    return _atomic_write(path, "\n".join([",".join(("time", *cols)), *rows]) + "\n")


def read_csv_table(path: str | Path, *, time_column: str | None = "time") -> Table:
    """Read a CSV table written by :func:`write_csv_table` (first column must be ``time``).

    ``time_column`` names the first column expected (``None``: any name, e.g. a cycle
    percentage such as ``sample_0_to_100``); its values become ``Table.time``."""
    path = check_regular_file(path, FileFormatError)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise FileFormatError(f"{path}: not UTF-8 text (byte {exc.start}): not a CSV") from None
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines:
        raise FileFormatError(f"{path}: empty file")
    cols = [c.strip() for c in lines[0].split(",")]
    if time_column is not None and cols[0] != time_column:
        raise FileFormatError(f"{path}: first column is {cols[0]!r}, expected {time_column!r}")
    rows = []
    for k, ln in enumerate(lines[1:], start=2):
        parts = ln.split(",")
        if len(parts) != len(cols):
            raise FileFormatError(f"{path}: line {k} has {len(parts)} values, expected {len(cols)}")
        try:
            rows.append([float(p) for p in parts])
        except ValueError as exc:
            raise FileFormatError(f"{path}: line {k}: {exc}") from None
    arr = np.array(rows, dtype=float).reshape(-1, len(cols))
    return Table(
        time=arr[:, 0].copy(), data=arr[:, 1:].copy(), columns=tuple(cols[1:]), name=path.stem
    )
