"""Time-series tables (:class:`Table`) and CSV result tables: first column ``time`` (s), then
named columns in SI units.

This is the contract other tools read (``tables/*.csv`` of a run). Writes are atomic: the
table is written to a temporary file in the same folder and renamed, so a failed run never
leaves a half-written table behind.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import FileFormatError, MissingDataError
from msk.io.validate import check_regular_file

__all__ = ["Table", "read_csv_table", "write_csv_table", "write_text_atomic"]


@dataclass(frozen=True)
class Table:
    """A time series table: ``time (N,)`` s, ``data (N, K)`` SI, ``columns`` (K names).

    ``in_degrees_in_file`` records the header flag of the file read; ``angle_columns`` are the
    columns that were converted deg → rad (and are converted back when written with
    ``in_degrees=True``).
    """

    time: NDArray[np.float64]
    data: NDArray[np.float64]
    columns: tuple[str, ...]
    name: str = ""
    in_degrees_in_file: bool = False
    angle_columns: tuple[str, ...] = ()
    metadata: Mapping[str, str] = field(default_factory=dict)

    def column(self, name: str) -> NDArray[np.float64]:
        try:
            return self.data[:, self.columns.index(name)]
        except ValueError:
            raise MissingDataError(f"table {self.name!r}: no column {name!r}") from None

    @property
    def rate_hz(self) -> float:
        """Mean sampling rate (NaN for fewer than two rows)."""
        if self.time.size < 2:
            return float("nan")
        return float((self.time.size - 1) / (self.time[-1] - self.time[0]))


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` (parent folders created): a temporary file in the same folder,
    then renamed, so a failed write never leaves a half-written file behind."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", newline="\n") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


#: rows per block of :func:`format_rows` (a block's values as Python floats, ~24 bytes each)
FORMAT_BLOCK = 4096


def format_rows(time: NDArray[np.float64], data: NDArray[np.float64], sep: str) -> list[str]:
    """The rows ``time, data…`` with full float precision (``%.17g``) joined by ``sep``,
    formatted block by block: a long table never holds its whole list of values. One
    ``%``-format per row (the text of ``np.char.mod("%.17g", ·)`` joined by ``sep``, ~2.5×
    faster)."""
    if time.size == 0:
        return []
    rows: list[str] = []
    for c0 in range(0, time.size, FORMAT_BLOCK):
        body = np.column_stack([time[c0 : c0 + FORMAT_BLOCK], data[c0 : c0 + FORMAT_BLOCK]])
        fmt = sep.join(["%.17g"] * body.shape[1])
        rows.extend(fmt % tuple(r) for r in body.tolist())
    return rows


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
    rows = format_rows(t, x, ",")
    return write_text_atomic(path, "\n".join([",".join(("time", *cols)), *rows]) + "\n")


def read_csv_table(path: str | Path, *, time_column: str | None = "time") -> Table:
    """Read a CSV table written by :func:`write_csv_table` (first column must be ``time``).

    ``time_column`` names the first column expected (``None``: any name, e.g. a cycle
    percentage such as ``sample_0_to_100``); its values become ``Table.time``. One empty field
    after the last column (a trailing comma, as some lab exports write on every data row) is
    not a value."""
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
        if len(parts) == len(cols) + 1 and not parts[-1].strip():
            parts.pop()
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
