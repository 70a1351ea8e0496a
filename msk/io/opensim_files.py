"""OpenSim text formats: ``.trc`` marker files and ``.mot`` / ``.sto`` storage files.

Read both storage header styles: OpenSim 4 (``version=1`` / ``nRows=`` / ``nColumns=`` /
``inDegrees=`` … ``endheader``) and the older one (``name`` / ``datacolumns`` / ``datarows`` /
``range`` … ``endheader``). Inside msk everything is SI: angles are converted to rad on read when
the header says ``inDegrees=yes`` (``Table.angle_columns`` lists the converted columns) and TRC
marker coordinates to metres. Every writer produces files that OpenSim 4.6 opens
(``TimeSeriesTable``, ``TimeSeriesTableVec3``, ``Storage``; checked in ``tests/io``).
Writes are atomic (temporary file then rename).
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import FileFormatError, MissingDataError, UnitsError
from msk.io.tables import Table, format_rows, write_text_atomic
from msk.io.validate import MAX_ABS_COORDINATE_M, check_regular_file, check_time_axis
from msk.trial import GapReport, ModelOutputs, Subject, Trial

__all__ = [
    "MarkerTable",
    "Table",
    "is_angle_column",
    "read_mot",
    "read_sto",
    "read_trc",
    "read_trc_trial",
    "write_mot",
    "write_sto",
    "write_trc",
]

_TRC_UNITS_M = {"m": 1.0, "mm": 1e-3, "cm": 1e-2}
_NOT_ANGLE = re.compile(
    r"(_t[xyz](/|$)|force|torque|moment|_[pv][xyz]$|_[xyz]$|emg|activation|/speed|_u$)",
    re.IGNORECASE,
)


def is_angle_column(name: str) -> bool:
    """Heuristic used when ``inDegrees=yes``: is this column a rotation (deg → rad)?

    Translations (``pelvis_tx``), forces, torques, moments, points and GRF vectors
    (``ground_force_vx``, ``_px``), EMG and activations are not.
    """
    return name.lower() != "time" and _NOT_ANGLE.search(name) is None


@dataclass(frozen=True)
class MarkerTable:
    """Markers from a TRC file: ``markers (N, M, 3)`` in m (NaN = missing)."""

    time: NDArray[np.float64]
    markers: NDArray[np.float64]
    labels: tuple[str, ...]
    rate_hz: float
    units_in_file: str
    frame_numbers: NDArray[np.int64]
    #: what the reader noticed and decided (e.g. a header rate its time column contradicts)
    warnings: tuple[str, ...] = ()

    def marker(self, label: str) -> NDArray[np.float64]:
        try:
            return self.markers[:, self.labels.index(label)]
        except ValueError:
            raise MissingDataError(f"no marker {label!r} in TRC table") from None


# ---------------------------------------------------------------------------------------------
def _read_text(path: Path) -> list[str]:
    path = check_regular_file(path, FileFormatError)
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise FileFormatError(f"{path}: cannot read: {exc}") from exc
    if not text.strip():
        raise FileFormatError(f"{path}: empty file")
    return text.splitlines()


def _parse_rows(path: Path, lines: Sequence[str], start: int, ncol: int) -> NDArray[np.float64]:
    """Numeric rows (tab or space separated); short rows are padded with NaN."""
    rows = []
    for k, line in enumerate(lines[start:], start=start):
        if not line.strip():
            continue
        parts = line.split("\t") if "\t" in line else line.split()
        vals = [p.strip() for p in parts]
        if len(vals) > ncol:
            if any(v for v in vals[ncol:]):
                raise FileFormatError(
                    f"{path}: line {k + 1} has {len(vals)} values, header declares {ncol} columns"
                )
            vals = vals[:ncol]
        try:
            if any("_" in v for v in vals):  # float() reads "1_20" as 120: not a file's number
                raise ValueError(f"{next(v for v in vals if '_' in v)!r}")
            row = [float(v) if v else np.nan for v in vals]
        except ValueError as exc:
            raise FileFormatError(f"{path}: line {k + 1}: not a number ({exc})") from None
        row.extend([np.nan] * (ncol - len(row)))
        rows.append(row)
    return np.array(rows, dtype=float).reshape(-1, ncol)


# ---------------------------------------------------------------------------------------------
# .sto / .mot
# ---------------------------------------------------------------------------------------------
def read_sto(path: str | Path, *, angle_columns: Sequence[str] | None = None) -> Table:
    """Read an OpenSim ``.sto`` or ``.mot`` file (either header style) into a :class:`Table`.

    When the header says ``inDegrees=yes``, the columns in ``angle_columns`` (default: those for
    which :func:`is_angle_column` is true) are converted to rad.
    """
    path = Path(path)
    lines = _read_text(path)
    end = next((i for i, ln in enumerate(lines) if ln.strip().lower() == "endheader"), None)
    if end is None:
        raise FileFormatError(f"{path}: no 'endheader' line: not an OpenSim .sto/.mot file")
    meta: dict[str, str] = {}
    name = ""
    for i, ln in enumerate(lines[:end]):
        s = ln.strip()
        if "=" in s:
            k, v = s.split("=", 1)
            meta[k.strip()] = v.strip()
        elif i == 0:
            name = s.split("\t")[0].strip()
            if name.lower().startswith("name "):
                name = name[5:].strip()
        elif s:
            parts = s.split(None, 1)
            if parts[0].lower() in ("datacolumns", "datarows", "range", "name"):
                meta[parts[0]] = parts[1] if len(parts) > 1 else ""
    hdr_i = end + 1
    while hdr_i < len(lines) and not lines[hdr_i].strip():
        hdr_i += 1
    if hdr_i >= len(lines):
        raise FileFormatError(f"{path}: no column labels after 'endheader'")
    header = lines[hdr_i]
    cols = [c.strip() for c in (header.split("\t") if "\t" in header else header.split())]
    while cols and not cols[-1]:
        cols.pop()
    if not cols or cols[0].lower() != "time":
        raise FileFormatError(f"{path}: first column is {cols[:1]!r}, expected 'time'")
    data = _parse_rows(path, lines, hdr_i + 1, len(cols))
    check_time_axis(path, data[:, 0], FileFormatError, "time")
    n_rows = meta.get("nRows", meta.get("datarows"))
    if n_rows is not None and n_rows.strip().isdigit() and int(n_rows) != data.shape[0]:
        raise FileFormatError(
            f"{path}: header announces {n_rows} rows, file has {data.shape[0]} (truncated?)"
        )
    deg_flag = meta.get("inDegrees", "no").strip().lower() in ("yes", "true", "1")
    columns = tuple(cols[1:])
    values = data[:, 1:].copy()
    converted: tuple[str, ...] = ()
    if deg_flag:
        wanted = (
            [c for c in columns if is_angle_column(c)]
            if angle_columns is None
            else list(angle_columns)
        )
        missing = [c for c in wanted if c not in columns]
        if missing:
            raise MissingDataError(f"{path}: angle columns {missing} not in the file")
        idx = [columns.index(c) for c in wanted]
        values[:, idx] = np.deg2rad(values[:, idx])
        converted = tuple(wanted)
    return Table(
        time=data[:, 0].copy(),
        data=values,
        columns=columns,
        name=name,
        in_degrees_in_file=deg_flag,
        angle_columns=converted,
        metadata=meta,
    )


read_mot = read_sto


def write_sto(
    path: str | Path,
    table: Table | None = None,
    *,
    time: ArrayLike | None = None,
    data: ArrayLike | None = None,
    columns: Sequence[str] | None = None,
    name: str | None = None,
    in_degrees: bool = False,
    angle_columns: Sequence[str] | None = None,
    header: Mapping[str, str] | None = None,
) -> Path:
    """Write an OpenSim 4 ``.sto``/``.mot`` file (``version=1`` header, tab separated).

    Either pass a :class:`Table` or ``time``/``data``/``columns``. Values are SI; with
    ``in_degrees=True`` the angle columns (``angle_columns`` or the table's) are written in
    degrees and the header says ``inDegrees=yes``. Full float precision (``%.17g``); a missing
    value is written ``nan`` (``TimeSeriesTable`` reads it, the legacy ``Storage`` does not:
    :func:`msk.io.storage_twin.storage_twin` gives the complete block it reads). ``header``
    adds ``key=value`` lines (metadata of ``TimeSeriesTable``) before ``endheader``.
    """
    path = Path(path)
    if table is None:
        if time is None or data is None or columns is None:
            raise FileFormatError(f"{path}: pass a Table or time, data and columns")
        table = Table(
            time=np.asarray(time, dtype=float),
            data=np.asarray(data, dtype=float).reshape(len(np.asarray(time)), -1),
            columns=tuple(columns),
            name=name or path.stem,
            angle_columns=tuple(angle_columns or ()),
        )
    t = np.asarray(table.time, dtype=float).reshape(-1)
    x = np.asarray(table.data, dtype=float).reshape(t.size, -1)
    if x.shape[1] != len(table.columns):
        raise FileFormatError(
            f"{path}: {x.shape[1]} data columns but {len(table.columns)} column names"
        )
    bad = [c for c in table.columns if not c or any(ch in c for ch in "\t\n\r")]
    if bad or "time" in table.columns:
        raise FileFormatError(f"{path}: invalid column names {bad or ['time']}")
    angles = tuple(angle_columns) if angle_columns is not None else table.angle_columns
    if in_degrees and angles:
        x = x.copy()
        idx = [table.columns.index(c) for c in angles]
        x[:, idx] = np.rad2deg(x[:, idx])
    head = [
        (name or table.name or path.stem).replace("\n", " ") or "msk",
        "version=1",
        f"nRows={t.size}",
        f"nColumns={x.shape[1] + 1}",
        f"inDegrees={'yes' if in_degrees else 'no'}",
        *_header_lines(path, header),
        "endheader",
        "\t".join(("time", *table.columns)),
    ]
    rows = format_rows(t, x, "\t")
    return write_text_atomic(path, "\n".join(head + rows) + "\n")


_RESERVED = frozenset({"version", "nrows", "ncolumns", "indegrees", "endheader"})


def _header_lines(path: Path, header: Mapping[str, str] | None) -> list[str]:
    lines = []
    for k, v in (header or {}).items():
        bad = not k or any(ch in k for ch in "=\t\n\r ") or any(ch in v for ch in "\n\r")
        if bad or k.lower() in _RESERVED:
            raise FileFormatError(f"{path}: invalid header line {k!r}={v!r}")
        lines.append(f"{k}={v}")
    return lines


write_mot = write_sto


# ---------------------------------------------------------------------------------------------
# .trc
# ---------------------------------------------------------------------------------------------
def read_trc(path: str | Path) -> MarkerTable:
    """Read a TRC marker file; coordinates converted to metres from its ``Units``.

    The rows are placed in time by the ``Time`` column (as OpenSim does); when the header's
    ``DataRate`` contradicts that column's mean step by more than 1 % (a file subsampled
    without its header updated, e.g. opensim-core's ``std_walking2_markers.trc``: 250 Hz
    declared, 25 Hz rows), ``rate_hz`` is the column's and the contradiction is in
    ``warnings``."""
    path = Path(path)
    lines = _read_text(path)
    if len(lines) < 5 or not lines[0].startswith("PathFileType"):
        raise FileFormatError(f"{path}: not a TRC file (first line {lines[0][:40]!r})")
    keys = [k for k in lines[1].split("\t") if k.strip()]
    vals = [v for v in lines[2].split("\t") if v.strip()]
    info = {k.strip(): v.strip() for k, v in zip(keys, vals)}
    units = info.get("Units", "")
    if units not in _TRC_UNITS_M:
        raise UnitsError(f"{path}: TRC Units {units!r} not in {sorted(_TRC_UNITS_M)}")
    try:
        for key in ("DataRate", "NumMarkers"):
            if "_" in info.get(key, ""):  # float() reads "1_20" as 120
                raise ValueError(f"{key} = {info[key]!r} is not a number")
        rate = float(info.get("DataRate", "nan"))
        n_markers = int(float(info.get("NumMarkers", "0")))
    except ValueError as exc:
        raise FileFormatError(f"{path}: bad TRC header values: {exc}") from None
    if not (np.isfinite(rate) and 0 < rate <= 20_000):
        raise FileFormatError(
            f"{path}: TRC DataRate = {rate:g} Hz is not a sampling rate (0, 20000]"
        )
    names = [s.strip() for s in lines[3].split("\t")[2:]]
    labels = [s for s in names if s]
    if n_markers != len(labels):
        raise FileFormatError(
            f"{path}: header says NumMarkers={n_markers} but {len(labels)} names are listed"
        )
    start = 5
    data = _parse_rows(path, lines, start, 2 + 3 * n_markers)
    n_frames = info.get("NumFrames")
    if n_frames and n_frames.isdigit() and int(n_frames) != data.shape[0]:
        raise FileFormatError(
            f"{path}: header announces NumFrames={n_frames}, file has {data.shape[0]} rows"
        )
    check_time_axis(path, data[:, 1], FileFormatError, "time")
    warnings: tuple[str, ...] = ()
    if data.shape[0] >= 3:
        # the mean step: a column rounded to 1 ms (OpenSim's subject01: 0.017, 0.016, …)
        column_rate = (data.shape[0] - 1) / float(data[-1, 1] - data[0, 1])
        if abs(column_rate / rate - 1.0) > 0.01:
            warnings = (
                f"TRC header DataRate = {rate:g} Hz but its Time column steps at "
                f"{column_rate:.6g} Hz: the Time column's rate is used",
            )
            rate = column_rate
    markers = data[:, 2:].reshape(-1, n_markers, 3) * _TRC_UNITS_M[units]
    with np.errstate(invalid="ignore"):
        far = np.isinf(markers) | (np.abs(markers) > MAX_ABS_COORDINATE_M)
    if far.any():
        f, m, a = (int(i[0]) for i in np.nonzero(far))
        raise FileFormatError(
            f"{path}: marker {labels[m]!r} has {'XYZ'[a]} = {markers[f, m, a]:.6g} m at row "
            f"{f + 1}: beyond {MAX_ABS_COORDINATE_M:g} m from the lab origin"
        )
    from msk.model.markersets import strip_subject_prefix

    return MarkerTable(
        time=data[:, 1].copy(),
        markers=markers,
        labels=strip_subject_prefix(labels)[0],  # a subject prefix dropped, as read_c3d does
        rate_hz=rate,
        units_in_file=units,
        frame_numbers=np.nan_to_num(data[:, 0]).astype(np.int64),
        warnings=warnings,
    )


def read_trc_trial(path: str | Path, *, up: ArrayLike = (0.0, 1.0, 0.0)) -> Trial:
    """A TRC file as a markers-only :class:`msk.io.Trial` (no analogs, plates, events), so that
    a marker trial exported for OpenSim goes where a C3D trial goes. A TRC has no vertical
    axis: ``up`` is the frame's (OpenSim's ground: +y)."""
    path = Path(path)
    t = read_trc(path)
    u = np.asarray(up, dtype=float)
    if u.shape != (3,) or not np.linalg.norm(u) > 0:
        raise FileFormatError(f"{path}: up must be a non-zero 3-vector, got {up!r}")
    missing = ~np.asarray(np.isfinite(t.markers).all(axis=2))
    return Trial(
        path=path,
        point_rate_hz=float(t.rate_hz),
        time=t.time,
        markers=t.markers,
        marker_labels=t.labels,
        gaps=GapReport.from_missing(t.labels, missing),
        model_outputs=ModelOutputs((), (), (), np.zeros((t.time.size, 0, 3))),
        analog_rate_hz=0.0,
        analog_time=np.zeros(0),
        analogs=np.zeros((0, 0)),
        analog_labels=(),
        analog_units=(),
        plates=(),
        events=(),
        subject=Subject(),
        vertical_axis=int(np.argmax(np.abs(u))),
        up=u / np.linalg.norm(u),
        point_units_in_file=t.units_in_file,
        metadata={"warnings": t.warnings} if t.warnings else {},
    )


def write_trc(
    path: str | Path,
    *,
    time: ArrayLike,
    markers: ArrayLike,
    labels: Sequence[str],
    units: str = "mm",
    rate_hz: float | None = None,
) -> Path:
    """Write markers ``(N, M, 3)`` given in metres to a TRC file in ``units`` (NaN = missing)."""
    path = Path(path)
    if units not in _TRC_UNITS_M:
        raise UnitsError(f"{path}: TRC units {units!r} not in {sorted(_TRC_UNITS_M)}")
    t = np.asarray(time, dtype=float).reshape(-1)
    x = np.asarray(markers, dtype=float)
    if x.ndim != 3 or x.shape[0] != t.size or x.shape[2] != 3 or x.shape[1] != len(labels):
        raise FileFormatError(
            f"{path}: markers shape {x.shape} does not match {t.size} frames, "
            f"{len(labels)} labels, 3 coordinates"
        )
    bad = [lab for lab in labels if not lab or any(ch in lab for ch in "\t\n\r")]
    if bad:
        raise FileFormatError(f"{path}: invalid marker labels {bad}")
    if rate_hz is None:
        rate_hz = (t.size - 1) / (t[-1] - t[0]) if t.size > 1 else 1.0
    n, m = x.shape[0], x.shape[1]
    head = [
        f"PathFileType\t4\t(X/Y/Z)\t{path.name}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
        "OrigDataStartFrame\tOrigNumFrames",
        f"{rate_hz:.17g}\t{rate_hz:.17g}\t{n}\t{m}\t{units}\t{rate_hz:.17g}\t1\t{n}",
        "\t".join(["Frame#", "Time", *(f"{lab}\t\t" for lab in labels)]).rstrip("\t"),
        "\t\t" + "\t".join(f"X{k + 1}\tY{k + 1}\tZ{k + 1}" for k in range(m)),
        "",
    ]
    body = np.column_stack([np.arange(1, n + 1), t, x.reshape(n, 3 * m) / _TRC_UNITS_M[units]])
    rows = ["\t".join(r) for r in np.char.mod("%.17g", body)] if body.size else []
    rows = [r.replace("nan", "NaN") for r in rows]
    return write_text_atomic(path, "\n".join(head + rows) + "\n")
