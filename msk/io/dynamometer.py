"""Dynamometer exports: a load-cell force (or a dynamometer's torque) and EMG channels in one
delimited text table → :class:`DynamometerRecording`, SI inside.

Formats: comma-separated (``.csv``), tab-separated (``.tsv``, ``.txt``; any suffix whose first
line has tabs and no commas) and either of them gzip-compressed (``.gz`` after the suffix). The
first line is the header; every other line one sample. Which column is what comes from the
caller (a session configuration's ``[[tests]]`` tables): the time column (s), the force column
with its unit (N, kN, kgf, lbf) or the torque column with its unit (N·m, N·mm, kgf·m, ft·lbf),
and the EMG columns with their unit (V, mV, µV). Inside, force is N, torque N·m, EMG V.

A file msk cannot use raises a typed :class:`~msk.exceptions.MskError`: missing file or column
(:class:`~msk.exceptions.MissingDataError`, naming the file, the column and the columns it has),
a cell that is not a number or not finite (:class:`~msk.exceptions.FileFormatError` naming the
file, the row — the line number in the text — the column and the value), a time column that
does not increase at a constant rate.
"""

from __future__ import annotations

import gzip
import io
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from msk.exceptions import FileFormatError, MissingDataError, UnitsError
from msk.units import G0, Array

__all__ = [
    "EMG_UNITS",
    "FORCE_UNITS",
    "TORQUE_UNITS",
    "DynamometerRecording",
    "read_dynamometer",
]

#: force unit → N
FORCE_UNITS: Mapping[str, float] = {
    "N": 1.0,
    "kN": 1000.0,
    "kgf": G0,
    "lbf": 4.4482216152605,
}
#: torque unit → N·m
TORQUE_UNITS: Mapping[str, float] = {
    "N.m": 1.0,
    "N.mm": 1e-3,
    "kgf.m": G0,
    "ft.lbf": 1.3558179483314004,
}
#: EMG unit → V
EMG_UNITS: Mapping[str, float] = {"V": 1.0, "mV": 1e-3, "uV": 1e-6}

#: the sampling interval may vary by this fraction of its median (text rounding of the times)
_RATE_REL_TOL = 0.01


@dataclass(frozen=True)
class DynamometerRecording:
    """One dynamometer test as read: ``time`` (N,) s from the file's time column;
    ``force`` (N,) N along the load cell's axis **or** ``torque`` (N,) N·m (the other None),
    with the file's own sign; ``emg`` (N, C) V in the order of ``emg_labels``; ``rate_hz`` the
    sampling rate; ``source`` the file; ``column`` the force/torque column's name."""

    source: Path
    time: Array
    force: Array | None
    torque: Array | None
    emg: Array
    emg_labels: tuple[str, ...]
    rate_hz: float
    column: str

    @property
    def n_samples(self) -> int:
        return int(self.time.shape[0])

    @property
    def duration_s(self) -> float:
        return float(self.time[-1] - self.time[0]) if self.n_samples > 1 else 0.0


def _text(path: Path) -> str:
    if not path.exists():
        raise MissingDataError(f"dynamometer file not found: {path}")
    if not path.is_file():
        raise FileFormatError(f"{path}: not a file")
    try:
        raw = path.read_bytes()
        if raw[:2] == b"\x1f\x8b":
            raw = gzip.decompress(raw)
    except (OSError, EOFError, gzip.BadGzipFile) as exc:
        raise FileFormatError(f"{path}: cannot read (corrupt gzip?): {exc}") from None
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise FileFormatError(
            f"{path}: not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset {exc.start})"
        ) from None


def _delimiter(path: Path, header: str) -> str:
    stem = path.name.lower().removesuffix(".gz")
    if stem.endswith((".tsv", ".tab")) or ("\t" in header and "," not in header):
        return "\t"
    if "," in header:
        return ","
    if ";" in header:
        return ";"
    raise FileFormatError(
        f"{path}: the header line {header[:80]!r} has no comma, tab or semicolon: not a "
        "delimited table"
    )


def _column(path: Path, names: list[str], name: str, what: str) -> int:
    if name in names:
        return names.index(name)
    low = [n.lower() for n in names]
    if name.lower() in low:
        return low.index(name.lower())
    raise MissingDataError(
        f"{path}: no {what} column {name!r}; the file has {', '.join(repr(n) for n in names)}"
    )


def _unit(table: Mapping[str, float], unit: str, what: str) -> float:
    key = unit.replace("·", ".").replace("µ", "u").replace("μ", "u")
    if key not in table:
        raise UnitsError(f"unknown {what} unit {unit!r}; known: {', '.join(table)}")
    return table[key]


def read_dynamometer(
    path: str | Path,
    *,
    time_column: str = "time_s",
    force_column: str | None = None,
    force_unit: str = "N",
    torque_column: str | None = None,
    torque_unit: str = "N.m",
    emg_columns: Mapping[str, str] | None = None,
    emg_unit: str = "V",
    rate_hz: float | None = None,
) -> DynamometerRecording:
    """Read one dynamometer test (module docstring: formats, units, errors).

    Exactly one of ``force_column`` / ``torque_column``. ``emg_columns``: channel label →
    column name (the label names the channel in results; e.g. ``{"VL": "emg_VL_uV"}``).
    ``rate_hz``: the sampling rate when the file has no time column (``time_column=""``);
    with a time column it is 1 / the median sampling interval.
    """
    path = Path(path)
    if (force_column is None) == (torque_column is None):
        raise MissingDataError(
            f"{path}: give exactly one of a force column and a torque column "
            f"(got force={force_column!r}, torque={torque_column!r})"
        )
    scale_main = (
        _unit(FORCE_UNITS, force_unit, "force")
        if force_column is not None
        else _unit(TORQUE_UNITS, torque_unit, "torque")
    )
    scale_emg = _unit(EMG_UNITS, emg_unit, "EMG")
    text = _text(path)
    first, _, _ = text.partition("\n")
    header = first.strip("\r")
    if not header.strip():
        raise FileFormatError(f"{path}: empty file or empty header line")
    sep = _delimiter(path, header)
    names = [h.strip().strip('"') for h in header.split(sep)]
    main_name = force_column if force_column is not None else torque_column
    assert main_name is not None
    emg_map = dict(emg_columns or {})
    wanted: list[tuple[str, int]] = []
    if time_column:
        wanted.append((time_column, _column(path, names, time_column, "time")))
    what = "force" if force_column is not None else "torque"
    wanted.append((main_name, _column(path, names, main_name, what)))
    for label, col in emg_map.items():
        wanted.append((col, _column(path, names, col, f"EMG ({label})")))
    idx = [i for _, i in wanted]
    try:
        data = np.loadtxt(
            io.StringIO(text), delimiter=sep, skiprows=1, usecols=idx, ndmin=2, dtype=float
        )
    except ValueError:
        data = _parse_slowly(path, text, sep, wanted)
    if data.shape[0] < 2:
        raise MissingDataError(f"{path}: {data.shape[0]} data row(s); a test needs samples")
    bad = np.argwhere(~np.isfinite(data))
    if bad.size:
        r, c = bad[0]
        raise FileFormatError(
            f"{path}: row {r + 2}, column {wanted[c][0]!r}: value {data[r, c]!r} is not finite"
        )
    k = 0
    if time_column:
        time = data[:, 0].copy()
        k = 1
        dt = np.diff(time)
        if (dt <= 0).any():
            r = int(np.flatnonzero(dt <= 0)[0])
            raise FileFormatError(
                f"{path}: row {r + 3}, column {time_column!r}: time {time[r + 1]!r} does not "
                f"increase (previous {time[r]!r})"
            )
        med = float(np.median(dt))
        off = np.abs(dt - med) > _RATE_REL_TOL * med
        if off.any():
            r = int(np.flatnonzero(off)[0])
            raise FileFormatError(
                f"{path}: row {r + 3}, column {time_column!r}: sampling interval {dt[r]:g} s "
                f"differs from the median {med:g} s: not a constant-rate recording"
            )
        rate = 1.0 / med
    else:
        if rate_hz is None or not math.isfinite(rate_hz) or rate_hz <= 0:
            raise MissingDataError(f"{path}: no time column: give the sampling rate (rate_hz)")
        rate = float(rate_hz)
        time = np.arange(data.shape[0]) / rate
    main = data[:, k] * scale_main
    emg = data[:, k + 1 :] * scale_emg
    return DynamometerRecording(
        source=path,
        time=time,
        force=main if force_column is not None else None,
        torque=main if torque_column is not None else None,
        emg=np.ascontiguousarray(emg),
        emg_labels=tuple(emg_map),
        rate_hz=float(rate),
        column=main_name,
    )


def _parse_slowly(path: Path, text: str, sep: str, wanted: list[tuple[str, int]]) -> Array:
    """Line-by-line parse naming the first bad cell (row = line number, column, value)."""
    rows = []
    for line_no, line in enumerate(text.splitlines()[1:], start=2):
        if not line.strip():
            continue
        cells = line.split(sep)
        row = []
        for name, i in wanted:
            if i >= len(cells):
                raise FileFormatError(
                    f"{path}: row {line_no}: {len(cells)} cells, no column {name!r} (cell {i + 1})"
                )
            cell = cells[i].strip().strip('"')
            try:
                row.append(float(cell))
            except ValueError:
                raise FileFormatError(
                    f"{path}: row {line_no}, column {name!r}: value {cell!r} is not a number"
                ) from None
        rows.append(row)
    return np.asarray(rows, dtype=float).reshape(len(rows), len(wanted))
