"""Normative bands: the mean ± SD of a population's gait variables over the cycle.

File format (CSV, UTF-8; :func:`read_norms`, :func:`write_norms`)::

    # population: healthy adults walking at self-selected speed (n = 12 subjects)
    # source: <who measured them, with the citation>
    # licence: <the licence the data are shared under>
    # n_subjects: 12
    # n_cycles: 96
    variable,percent_cycle,mean,sd
    knee_flexion_deg,0,4.1,3.2
    knee_flexion_deg,1,5.0,3.3
    …

    …
    walking_speed_m_s,,1.32,0.14
    cadence_steps_per_min,,109.5,6.8

Header lines start with ``#`` and hold ``key: value``; ``population``, ``source`` and ``licence``
are required, any other key is kept (``notes``). Curve rows: ``variable`` (a name of
:mod:`msk.gait.variables`, units in the name), ``percent_cycle`` (0…100, the same 101 samples
for every variable), ``mean`` and ``sd`` in the variable's unit. Scalar rows (one per
variable, ``percent_cycle`` empty): a spatiotemporal parameter
(:data:`msk.gait.spatiotemporal.PARAMETERS`, units in the name), its mean and SD. A band is
mean ± 1 SD unless the reader draws otherwise.

:func:`bands_from_cycles` builds a lab's own bands from pooled cycles (the ``msk norms`` verb):
per variable and sample, the mean and sample SD (n − 1) over every cycle of the control
subjects, both sides pooled (healthy gait is taken as symmetric, Sadeghi et al. 2000 review the
evidence); ``n_cycles`` counts the cycles that entered. :func:`scalar_norms` gives the
spatiotemporal rows: per control session the mean over its strides (both sides pooled), then
the mean and sample SD of those session means (``n_sessions_spatiotemporal``) — the spread
between subjects, which a patient's value is compared with, not one subject's stride-to-stride
variability; one session gives no SD (NaN).
"""

from __future__ import annotations

import csv
import io
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from msk.exceptions import FileFormatError, MissingDataError
from msk.gait.cycles import PERCENT, SIDES, GaitCycles
from msk.gait.spatiotemporal import Spatiotemporal
from msk.io.tables import write_text_atomic
from msk.units import Array

__all__ = [
    "NORM_COLUMNS",
    "SHIPPED_DIR",
    "NormativeBands",
    "bands_from_cycles",
    "bands_from_sessions",
    "read_norms",
    "scalar_norms",
    "shipped_norms",
    "write_norms",
]

#: the normative bands shipped with msk (package data; provenance in its ``ORIGIN.md``)
SHIPPED_DIR = Path(__file__).resolve().parents[1] / "data" / "norms"

#: the columns of a normative-band file
NORM_COLUMNS: tuple[str, ...] = ("variable", "percent_cycle", "mean", "sd")
_REQUIRED = ("population", "source", "licence")


@dataclass(frozen=True)
class NormativeBands:
    """Normative mean and SD of gait variables at 0…100 % of the cycle.

    Attributes:
        variables: the variables (names of :mod:`msk.gait.variables`, units in the name).
        mean, sd: (101, n_vars) the population's mean and SD at each % of the cycle.
        population: who (healthy adults at self-selected speed, n subjects, age…).
        source: where the numbers come from (authors, year, data set).
        licence: the licence they are shared under.
        notes: the other header keys of the file (``n_subjects``, ``n_cycles``, …).
        percent: (101,) % of the cycle.
        scalars: spatiotemporal parameter → (mean, SD) (SD NaN: not known).
    """

    variables: tuple[str, ...]
    mean: Array
    sd: Array
    population: str
    source: str
    licence: str
    notes: Mapping[str, str] = field(default_factory=dict)
    percent: Array = field(default_factory=lambda: PERCENT.copy())
    scalars: Mapping[str, tuple[float, float]] = field(default_factory=dict)

    def scalar(self, name: str) -> tuple[float, float] | None:
        """``(mean, sd)`` of the spatiotemporal parameter ``name``; None when the set lacks it."""
        v = self.scalars.get(name)
        return None if v is None else (float(v[0]), float(v[1]))

    def band(self, variable: str) -> tuple[Array, Array]:
        """``(mean, sd)`` (101,) of ``variable``."""
        try:
            j = self.variables.index(variable)
        except ValueError:
            raise MissingDataError(
                f"normative bands ({self.source}): no variable {variable!r}"
            ) from None
        return np.asarray(self.mean)[:, j], np.asarray(self.sd)[:, j]

    def has(self, variable: str) -> bool:
        """Whether the bands hold ``variable``."""
        return variable in self.variables


def shipped_norms() -> dict[str, Path]:
    """The normative-band files shipped with msk (``msk/data/norms/*.csv``) by name (the file
    stem); read one with :func:`read_norms`."""
    return {p.stem: p for p in sorted(SHIPPED_DIR.glob("*.csv"))}


def write_norms(path: str | Path, bands: NormativeBands) -> Path:
    """Write ``bands`` in the format of the module docstring (atomically)."""
    buf = io.StringIO()
    head = {"population": bands.population, "source": bands.source, "licence": bands.licence}
    head.update({k: v for k, v in bands.notes.items() if k not in head})
    for k, v in head.items():
        buf.write(f"# {k}: {' '.join(str(v).split())}\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(NORM_COLUMNS)
    m = np.asarray(bands.mean, dtype=float)
    s = np.asarray(bands.sd, dtype=float)
    for j, var in enumerate(bands.variables):
        for i, pc in enumerate(np.asarray(bands.percent, dtype=float)):
            w.writerow([var, f"{pc:g}", _num(float(m[i, j])), _num(float(s[i, j]))])
    for var, (mu, sd) in bands.scalars.items():
        w.writerow([var, "", _num(float(mu)), _num(float(sd))])
    return write_text_atomic(path, buf.getvalue())


def _num(x: float) -> str:
    return f"{x:.6g}" if np.isfinite(x) else "nan"


def read_norms(path: str | Path) -> NormativeBands:
    """The bands of a file in the format of the module docstring; a missing header key, a
    wrong column or a variable without its 101 samples raises :class:`FileFormatError` naming
    the file, line and value."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise FileFormatError(f"{p}: cannot read normative bands: {exc}") from None
    head: dict[str, str] = {}
    rows: list[tuple[int, list[str]]] = []
    for line_no, line in enumerate(text.splitlines(), start=1):
        if line.startswith("#"):
            key, sep, val = line[1:].partition(":")
            if not sep:
                raise FileFormatError(f"{p}: line {line_no}: header {line!r} is not '# key: value'")
            head[key.strip()] = val.strip()
        elif line.strip():
            rows.append((line_no, next(csv.reader([line]))))
    for key in _REQUIRED:
        if key not in head:
            raise FileFormatError(f"{p}: header line '# {key}: …' is missing")
    if not rows or tuple(c.strip() for c in rows[0][1]) != NORM_COLUMNS:
        header_row = rows[0][1] if rows else None
        raise FileFormatError(f"{p}: columns {header_row}, expected {','.join(NORM_COLUMNS)}")
    data: dict[str, dict[float, tuple[float, float]]] = {}
    scalars: dict[str, tuple[float, float]] = {}
    for k, r in rows[1:]:
        if len(r) != len(NORM_COLUMNS):
            raise FileFormatError(
                f"{p}: line {k} has {len(r)} values, expected {len(NORM_COLUMNS)}"
            )
        var = r[0].strip()
        try:
            mu, sd = float(r[2]), float(r[3])
            pc = None if not r[1].strip() else float(r[1])
        except ValueError as exc:
            raise FileFormatError(f"{p}: line {k}: {exc}") from None
        if (pc is None and var in data) or (pc is not None and var in scalars):
            raise FileFormatError(
                f"{p}: line {k}: variable {var!r} is both a curve (percent_cycle given) and a "
                "scalar (percent_cycle empty)"
            )
        if pc is None:
            if var in scalars:
                raise FileFormatError(f"{p}: line {k}: scalar {var!r} given twice")
            scalars[var] = (mu, sd)
        else:
            data.setdefault(var, {})[pc] = (mu, sd)
    variables = tuple(data)
    mean = np.full((PERCENT.size, len(variables)), np.nan)
    sdev = np.full_like(mean, np.nan)
    for j, var in enumerate(variables):
        got = data[var]
        missing = [x for x in PERCENT if float(x) not in got]
        if missing:
            raise FileFormatError(
                f"{p}: variable {var!r} has no row at percent_cycle {missing[0]:g} (needs 0…100)"
            )
        for i, x in enumerate(PERCENT):
            mean[i, j], sdev[i, j] = got[float(x)]
    notes = {key: val for key, val in head.items() if key not in _REQUIRED}
    return NormativeBands(
        variables, mean, sdev, head["population"], head["source"], head["licence"], notes,
        scalars=scalars,
    )  # fmt: skip


def bands_from_cycles(
    cycles: Sequence[GaitCycles],
    *,
    population: str,
    source: str,
    licence: str,
    sides: Sequence[str] = SIDES,
    notes: Mapping[str, str] | None = None,
) -> NormativeBands:
    """Bands from the cycles of control sessions (module docstring): the variables every
    session has, mean and sample SD over the cycles of ``sides`` pooled."""
    if not cycles:
        raise MissingDataError("normative bands: no session's cycles to pool")
    pooled = GaitCycles.concatenate(cycles)
    vals = [np.asarray(pooled.side(s).values, dtype=float) for s in sides]
    allv = np.concatenate(vals) if vals else np.zeros((0, PERCENT.size, len(pooled.variables)))
    if allv.shape[0] == 0:
        raise MissingDataError("normative bands: the sessions hold no complete gait cycle")
    known = np.isfinite(allv)
    n = known.sum(axis=0)
    with np.errstate(all="ignore"):
        tot = np.where(known, allv, 0.0).sum(axis=0)
        mean = np.where(n > 0, tot / np.maximum(n, 1), np.nan)
        dev = np.where(known, allv - mean[None], 0.0)
        sd = np.where(n > 1, np.sqrt((dev**2).sum(axis=0) / np.maximum(n - 1, 1)), np.nan)
    info = {"n_sessions": str(len(cycles)), "n_cycles": str(allv.shape[0])}
    info.update(notes or {})
    return NormativeBands(pooled.variables, mean, sd, population, source, licence, info)


def scalar_norms(sessions: Sequence[Spatiotemporal]) -> dict[str, tuple[float, float]]:
    """The spatiotemporal rows of a normative set (module docstring): per parameter, the mean
    and sample SD (n − 1) over the sessions of each session's stride mean, both sides pooled;
    a parameter no session has is left out, one session gives an SD of NaN."""
    per: dict[str, list[float]] = {}
    for st in sessions:
        for name in st.left.parameters:
            v = np.concatenate([st.side(s).parameter(name) for s in SIDES
                                if name in st.side(s).parameters])  # fmt: skip
            v = v[np.isfinite(v)]
            if v.size:
                per.setdefault(name, []).append(float(v.mean()))
    out: dict[str, tuple[float, float]] = {}
    for name, vals in per.items():
        a = np.asarray(vals)
        out[name] = (float(a.mean()), float(a.std(ddof=1)) if a.size > 1 else float("nan"))
    return out


def bands_from_sessions(
    folders: Sequence[str | Path],
    *,
    population: str | None = None,
    source: str,
    licence: str,
) -> tuple[NormativeBands, list[str], list[tuple[str, str]]]:
    """Bands from the results folders of control sessions (``msk run`` / ``msk batch``),
    read typed (:meth:`msk.results.folder.SessionResults.gait_cycles`), with the scalar rows of
    their spatiotemporal parameters (:func:`scalar_norms`,
    :meth:`~msk.results.folder.SessionResults.spatiotemporal`); a folder without gait
    cycles is left out. Returns the bands, the sessions used and ``(session, why)`` of those
    left out. ``population`` defaults to "control sessions of this lab (n = …: names)"."""
    from msk.exceptions import MskError
    from msk.results.folder import read_session

    cycles: list[GaitCycles] = []
    strides: list[Spatiotemporal] = []
    used: list[str] = []
    skipped: list[tuple[str, str]] = []
    for f in folders:
        p = Path(f)
        try:
            res = read_session(p)
            c = res.gait_cycles()
            st = res.spatiotemporal()
        except MskError as exc:
            skipped.append((p.name, " ".join(str(exc).split())))
            continue
        if c is None or not (c.left.n_cycles or c.right.n_cycles):
            skipped.append((p.name, "no complete gait cycle"))
            continue
        cycles.append(c)
        if st is not None:
            strides.append(st)
        used.append(p.name)
    if not cycles:
        raise MissingDataError(
            "normative bands: no session with gait cycles among "
            f"{', '.join(Path(f).name for f in folders) or 'no folder'}"
        )
    pop = population or f"control sessions of this lab (n = {len(used)}: {', '.join(used)})"
    bands = bands_from_cycles(cycles, population=pop, source=source, licence=licence)
    if strides:
        bands = replace(
            bands,
            scalars=scalar_norms(strides),
            notes={**bands.notes, "n_sessions_spatiotemporal": str(len(strides))},
        )
    return bands, used, skipped
