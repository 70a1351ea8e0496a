"""OpenSim ground-reaction files: the force sets of a ``.mot/.sto`` and ExternalLoads ``.xml``.

An OpenSim GRF file holds one or more *force sets*, each three columns of force
(``<identifier>x/y/z`` with a force identifier ending in ``v``), three of the point of
application (the COP; the point identifier is the force identifier with ``v`` → ``p``) and,
optionally, three of a torque (the free moment). Every naming in common use is recognised:

=================================  ===============================  =======================
force                              point                            torque
=================================  ===============================  =======================
``ground_force_vx``                ``ground_force_px``              ``ground_torque_x``
``ground_force_r_vx``              ``ground_force_r_px``            ``ground_torque_r_x``
``r_ground_force_vx``              ``r_ground_force_px``            ``r_ground_torque_x``
``ground_force_1_vx``              ``ground_force_1_px``            ``ground_torque_1_x``
``1_ground_force_vx``              ``1_ground_force_px``            ``1_ground_torque_x``
=================================  ===============================  =======================

(``moment`` may stand for ``torque``; matching ignores case.) The torque identifier is the force
identifier with its last ``force`` replaced by ``torque`` (or ``moment``) and the trailing ``v``
dropped. Columns may come in any order (the Grand Challenge DM files list ``ground_torque_1_z``
next to the forces and ``_x``, ``_y`` at the end); a missing torque component is taken as 0
(files that store no torque at all: the wrench is then a pure force at the COP).

**Plate names.** The sets are named ``plate1``, ``plate2``, … in the order in which their
force-x column appears in the file, whether they were found by their names or by the
identifiers of an ExternalLoads file — so a plate name read here and one from
:func:`external_force_sets` agree.

The ExternalLoads ``.xml`` (``<ExternalForce>`` elements with ``applied_to_body``,
``force_identifier``, ``point_identifier``, ``torque_identifier``,
``force_expressed_in_body``, ``point_expressed_in_body``; ``<datafile>``) says which body each
set is applied to. msk reads forces and points expressed in ``ground`` (the lab), the only
choice of the plate-derived files in use; other frames raise :class:`ForcePlateError`.

**Per-plate vector columns** (OpenSim's ``C3DFileAdapter`` forces table flattened by
``TimeSeriesTableVec3.flatten()``, e.g. ``std_walking2_grfs.sto`` of opensim-core, pyCGM2's
``*_GRF.mot``): ``f<k>_1 f<k>_2 f<k>_3`` (force of plate k), ``p<k>_…`` (its point),
``m<k>_…`` (the moment about that point); ``flatten(['_x', '_y', '_z'])`` gives
``f<k>_x …``, read alike. The point is, by the adapter's ``ForceLocation``, the plate origin
(``OriginOfForcePlate``: fixed, the moment has all three components), the COP
(``CenterOfPressure``: the free moment only) or the point of wrench application. Names such as
``F1X`` or ``Fx1`` were not found in OpenSim GRF files (only in lab CSV exports) and are not
read.

**A fixed point** (:func:`is_fixed_point`: the same point at every loaded frame, to 1e-9 of its
size — a COP always moves) is not where the foot presses: the COP and the free moment are
computed from the force F and the moment M_P about P (:func:`wrench_at_cop`), on the plane
through P normal to the file's vertical (the axis of its largest force).

**Units** (:func:`grf_length_unit`): forces in N; points in a length unit L and moments in
N·L. L is read from the header when it has a ``Units=`` line (``m``, ``cm``, ``mm``) or
OpenSim's ``Units are S.I. units`` line; otherwise from the data: over the loaded frames (the
vertical force above max(20 N, 10 % of its peak)) the largest COP coordinate is ≤ 20 (a lab
point within 20 m of its origin: metres) or ≥ 100 (beyond 100 m no lab reaches: millimetres);
in between (20–100) the file is ambiguous and :class:`~msk.exceptions.UnitsError` names the
file and the column.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from msk.exceptions import FileFormatError, ForcePlateError, MissingDataError, UnitsError
from msk.units import Array

__all__ = [
    "ExternalForceSpec",
    "ExternalLoadsSpec",
    "GrfForceSet",
    "GrfLengthUnit",
    "external_force_sets",
    "grf_force_sets",
    "grf_length_unit",
    "grf_vertical_axis",
    "header_length_unit",
    "is_fixed_point",
    "read_external_loads_xml",
    "wrench_at_cop",
]


_FORCE_X = re.compile(r"^(?P<stem>.*force.*)v(?P<ax>x)$", re.IGNORECASE)
#: ``f1_1``/``p1_1``/``m1_1`` (flatten's default suffixes) or ``f1_x``/…
_VEC = re.compile(r"^(?P<kind>[fpm])(?P<plate>\d+)_(?P<ax>[123xyz])$", re.IGNORECASE)
_VEC_AXES = ("123", "xyz")

#: length unit names → metres (a GRF file's points; its moments are N·unit)
LENGTH_UNITS_M: dict[str, float] = {
    "m": 1.0, "meter": 1.0, "meters": 1.0, "metre": 1.0, "metres": 1.0,
    "cm": 1e-2, "centimeter": 1e-2, "centimeters": 1e-2, "centimetre": 1e-2,
    "centimetres": 1e-2,
    "mm": 1e-3, "millimeter": 1e-3, "millimeters": 1e-3, "millimetre": 1e-3,
    "millimetres": 1e-3,
}  # fmt: skip
#: the data rule: the largest loaded COP coordinate ≤ this → metres …
METRES_MAX = 20.0
#: … ≥ this → millimetres; in between: ambiguous
MILLIMETRES_MIN = 100.0


@dataclass(frozen=True)
class GrfForceSet:
    """One force set of a GRF table: column names of force, point (COP) and torque.

    ``torque`` holds ``None`` for a component absent from the file (taken as 0). ``body`` is the
    body an ExternalLoads file applies the set to (``None`` when found by column names).
    """

    name: str
    force_identifier: str
    force: tuple[str, str, str]
    point: tuple[str, str, str]
    torque: tuple[str | None, str | None, str | None]
    body: str | None = None


@dataclass(frozen=True)
class ExternalForceSpec:
    """One ``<ExternalForce>`` of an ExternalLoads file (the text of its elements)."""

    name: str
    applied_to_body: str
    force_identifier: str
    point_identifier: str
    torque_identifier: str | None
    force_expressed_in_body: str = "ground"
    point_expressed_in_body: str = "ground"


@dataclass(frozen=True)
class ExternalLoadsSpec:
    """An ExternalLoads ``.xml``: its enabled forces and its data file (resolved against the
    folder of the xml; ``None`` when the file names none)."""

    path: Path
    forces: tuple[ExternalForceSpec, ...]
    datafile: Path | None


def _lookup(columns: Sequence[str]) -> dict[str, str]:
    return {c.lower(): c for c in columns}


def _torque_identifiers(force_identifier: str) -> list[str]:
    """``ground_force_1_v`` → [``ground_torque_1_``, ``ground_moment_1_``]."""
    stem = force_identifier[:-1]
    k = stem.lower().rfind("force")
    return [stem[:k] + word + stem[k + len("force") :] for word in ("torque", "moment")]


def _name_sets(sets: list[GrfForceSet], columns: Sequence[str]) -> tuple[GrfForceSet, ...]:
    """Name the sets plate1… in file order of their force-x column."""
    pos = {c: i for i, c in enumerate(columns)}
    order = sorted(sets, key=lambda s: pos[s.force[0]])
    return tuple(
        GrfForceSet(f"plate{k + 1}", s.force_identifier, s.force, s.point, s.torque, s.body)
        for k, s in enumerate(order)
    )


def grf_force_sets(columns: Sequence[str], *, source: str = "GRF table") -> tuple[GrfForceSet, ...]:
    """The force sets of a GRF table found from its column names (module docstring).

    Raises:
        MissingDataError: no ``…force…vx`` column, or a set lacks a force or point component
            (names ``source`` and the columns).
    """
    cols = [c for c in columns if c.lower() != "time"]
    low = _lookup(cols)
    found: list[GrfForceSet] = []
    for c in cols:
        m = _FORCE_X.match(c)
        if m is None:
            continue
        found.append(_set_from_identifiers(c[:-1], None, None, low, source))
    found += _vector_sets(cols, low, source)
    if not found:
        raise MissingDataError(
            f"{source}: no ground-reaction columns (…force…vx, e.g. ground_force_vx, "
            f"ground_force_1_vx, 1_ground_force_vx; or f1_1 p1_1 m1_1); columns: "
            f"{list(cols)[:12]}"
        )
    return _name_sets(found, list(columns))


def _vector_sets(cols: Sequence[str], low: dict[str, str], source: str) -> list[GrfForceSet]:
    """The ``f<k>_1 … p<k>_1 … m<k>_1 …`` sets (module docstring), one per plate k whose
    force-x column is present."""
    out = []
    for c in cols:
        m = _VEC.match(c)
        if m is None or m["kind"].lower() != "f" or m["ax"].lower() not in "1x":
            continue
        axes = _VEC_AXES[0] if m["ax"] == "1" else _VEC_AXES[1]
        k = m["plate"]

        def names(kind: str, k: str = k, axes: str = axes, f: str = m["kind"]) -> list[str]:
            # the plate's kind letter in the force column's case
            letter = kind.upper() if f.isupper() else kind
            return [f"{letter}{k}_{a}" for a in axes]

        got = {kind: [low.get(n.lower()) for n in names(kind)] for kind in "fpm"}
        for kind, what in (("f", "force"), ("p", "point")):
            if None in got[kind]:
                raise MissingDataError(
                    f"{source}: plate {k}'s {what} needs columns {names(kind)}; missing "
                    f"{[n for n, g in zip(names(kind), got[kind]) if g is None]}"
                )
        f, p, tq = got["f"], got["p"], got["m"]
        out.append(
            GrfForceSet(
                "",
                f"f{k}_",
                (f[0], f[1], f[2]),  # type: ignore[arg-type]
                (p[0], p[1], p[2]),  # type: ignore[arg-type]
                (tq[0], tq[1], tq[2]),
            )
        )
    return out


def grf_vertical_axis(forces: Sequence[Array]) -> int:
    """The file's vertical axis (0, 1, 2): the axis of the largest RMS force summed over the
    force sets ``forces`` (each (N, 3) N) — a ground reaction is mostly vertical."""
    rms = np.zeros(3)
    for f in forces:
        f = np.asarray(f, dtype=float)
        rms += np.sqrt(np.nanmean(f**2, axis=0)) if f.size else 0.0
    return int(np.argmax(rms))


def is_fixed_point(force: Array, point: Array, vertical: int) -> bool:
    """Is ``point`` (N, 3) one fixed point (a plate origin) rather than a COP? True when it
    is the same at every loaded frame (vertical force above max(20 N, 10 % of its peak)) to
    1e-9 of its size: a foot's COP always moves (it rolls from heel to toe in gait, sways by
    millimetres in standing). False without loaded frames."""
    fv = np.abs(np.asarray(force, dtype=float)[:, vertical])
    peak = float(np.nanmax(fv)) if fv.size else 0.0
    loaded = fv > max(20.0, 0.1 * peak)
    p = np.asarray(point, dtype=float)[loaded]
    if p.shape[0] < 2 or not np.isfinite(p).all():
        return False
    spread = float(np.max(np.ptp(p, axis=0)))
    return spread <= 1e-9 * (1.0 + float(np.max(np.abs(p))))


def wrench_at_cop(force: Array, point: Array, moment: Array, vertical: int) -> tuple[Array, Array]:
    """The COP and free moment of a ground reaction given as a force F and the moment M_P
    about a point P of the plate's surface (a plate origin): the COP c = P + r, r normal to
    the vertical n, is where the moment has no horizontal part, M_P = r × F + T n. With
    (i, j, k) the cyclic axes ending in the vertical k (the COP of btk's
    ``GroundReactionWrenchFilter``, Barre & Armand 2014, which OpenSim's ``C3DFileAdapter``
    writes in ``CenterOfPressure`` mode)::

        r_i = −M_j / F_k,   r_j = M_i / F_k,   T = M_k − (r_i F_j − r_j F_i)

    Returns ``(cop, free_moment)``, (N, 3) each, in the units of ``point`` and ``moment``;
    the COP is NaN where F_k = 0 (the moment is then 0). The wrench is unchanged:
    c × F + T n = P × F + M_P wherever F_k ≠ 0."""
    f = np.asarray(force, dtype=float)
    p = np.asarray(point, dtype=float)
    m = np.asarray(moment, dtype=float)
    k = int(vertical)
    i, j = (k + 1) % 3, (k + 2) % 3
    fk = f[:, k]
    ok = fk != 0.0
    safe = np.where(ok, fk, 1.0)
    r = np.zeros_like(f)
    r[:, i] = -m[:, j] / safe
    r[:, j] = m[:, i] / safe
    cop = p + r
    cop[~ok] = np.nan
    tq = np.zeros_like(f)
    tq[:, k] = np.where(ok, m[:, k] - (r[:, i] * f[:, j] - r[:, j] * f[:, i]), 0.0)
    return cop, tq


@dataclass(frozen=True)
class GrfLengthUnit:
    """The length unit of a GRF file's points (its moments are N·unit): ``metres`` per unit,
    ``source`` ``"header"`` or ``"data"``, ``detail`` what decided it (module docstring)."""

    metres: float
    source: str
    detail: str


def header_length_unit(path: str | Path) -> float | None:
    """Metres per length unit of an OpenSim ``.sto/.mot`` header: a ``Units=<unit>`` line
    (``m``, ``cm``, ``mm``, spelled out or not, any case) or OpenSim's ``Units are S.I.
    units`` line; ``None`` when the header says nothing of units.

    Raises:
        UnitsError: a ``Units=`` value that is not a length unit (names the file and value).
    """
    path = Path(path)
    with open(path, encoding="utf-8", errors="replace") as fh:
        for line in fh:
            s = line.strip()
            if s.lower() == "endheader":
                break
            if s.lower().startswith("units are s.i."):
                return 1.0
            if "=" in s:
                key, val = (x.strip() for x in s.split("=", 1))
                if key.lower() == "units":
                    unit = val.split()[0].lower() if val.split() else ""
                    if unit not in LENGTH_UNITS_M:
                        raise UnitsError(
                            f"{path}: header Units={val!r} is not a length unit "
                            f"({', '.join(sorted(LENGTH_UNITS_M))})"
                        )
                    return LENGTH_UNITS_M[unit]
    return None


def grf_length_unit(
    path: str | Path,
    cops: Sequence[Array],
    forces: Sequence[Array],
    point_columns: Sequence[str],
    vertical: int,
) -> GrfLengthUnit:
    """The length unit of a GRF file (module docstring): the header's, else the data's —
    the largest |coordinate| of the COPs ``cops`` (file units, (N, 3) each, for a fixed-point
    set the COP :func:`wrench_at_cop` gives) over the frames whose vertical force
    (``forces``, N) exceeds max(20 N, 10 % of its peak): ≤ :data:`METRES_MAX` metres,
    ≥ :data:`MILLIMETRES_MIN` millimetres. Metres when no frame is loaded (nothing to apply).

    Raises:
        UnitsError: the largest coordinate between the two (names the file, the point column
            and the value).
    """
    u = header_length_unit(path)
    if u is not None:
        return GrfLengthUnit(u, "header", f"{path}: header")
    best, col = 0.0, ""
    for c, f, names in zip(cops, forces, point_columns):
        fv = np.abs(np.asarray(f, dtype=float)[:, vertical])
        if not fv.size:
            continue
        loaded = (fv > max(20.0, 0.1 * float(np.nanmax(fv)))) & np.isfinite(c).all(axis=1)
        if not loaded.any():
            continue
        a = np.abs(np.asarray(c, dtype=float)[loaded])
        if float(a.max()) > best:
            best, col = float(a.max()), str(names)
    if best <= METRES_MAX:
        return GrfLengthUnit(1.0, "data", f"largest loaded COP coordinate {best:.4g} ≤ "
                                          f"{METRES_MAX:g}: metres")  # fmt: skip
    if best >= MILLIMETRES_MIN:
        return GrfLengthUnit(1e-3, "data", f"largest loaded COP coordinate {best:.4g} ({col}) "
                                           f"≥ {MILLIMETRES_MIN:g}: millimetres")  # fmt: skip
    raise UnitsError(
        f"{path}: units of the points not determined: the largest loaded COP coordinate is "
        f"{best:.4g} ({col}), between {METRES_MAX:g} (metres) and {MILLIMETRES_MIN:g} "
        "(millimetres); add a header line Units=m or Units=mm"
    )


def _set_from_identifiers(
    force_id: str,
    point_id: str | None,
    torque_id: str | None,
    low: dict[str, str],
    source: str,
    body: str | None = None,
    element: str = "",
) -> GrfForceSet:
    where = f"{source}{element}"
    f = [low.get((force_id + a).lower()) for a in "xyz"]
    if None in f:
        raise MissingDataError(
            f"{where}: force identifier {force_id!r} needs columns "
            f"{[force_id + a for a in 'xyz']}; missing "
            f"{[force_id + a for a, c in zip('xyz', f) if c is None]}"
        )
    if point_id is None:
        if not force_id.lower().endswith("v"):
            raise MissingDataError(f"{where}: force identifier {force_id!r} does not end in 'v'")
        point_id = force_id[:-1] + "p"
    p = [low.get((point_id + a).lower()) for a in "xyz"]
    if None in p:
        raise MissingDataError(
            f"{where}: point identifier {point_id!r} needs columns "
            f"{[point_id + a for a in 'xyz']}; missing "
            f"{[point_id + a for a, c in zip('xyz', p) if c is None]}"
        )
    cands = [torque_id] if torque_id is not None else _torque_identifiers(force_id)
    tq: list[str | None] = [None, None, None]
    for cand in cands:
        got = [low.get((cand + a).lower()) for a in "xyz"]
        if any(g is not None for g in got):
            tq = got
            break
    return GrfForceSet(
        "",
        force_id,
        (f[0], f[1], f[2]),  # type: ignore[arg-type]
        (p[0], p[1], p[2]),  # type: ignore[arg-type]
        (tq[0], tq[1], tq[2]),
        body,
    )


def _text(el: ET.Element, tag: str) -> str | None:
    sub = el.find(tag)
    if sub is None or sub.text is None or not sub.text.strip():
        return None
    return sub.text.strip()


def read_external_loads_xml(path: str | Path) -> ExternalLoadsSpec:
    """Parse an OpenSim ExternalLoads ``.xml`` (OpenSim 3 and 4 layouts).

    Disabled forces (``<isDisabled>true`` or ``<appliesForce>false``) are left out.

    Raises:
        FileFormatError: not XML, no ``<ExternalLoads>``, no enabled ``<ExternalForce>``, or an
            ExternalForce without ``applied_to_body`` / ``force_identifier`` (names the file
            and the element).
        ForcePlateError: a force or point expressed in a body other than ``ground``.
    """
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except FileNotFoundError:
        raise MissingDataError(f"{path}: ExternalLoads file not found") from None
    except ET.ParseError as exc:
        raise FileFormatError(f"{path}: not a valid XML file ({exc})") from None
    el = root if root.tag == "ExternalLoads" else root.find(".//ExternalLoads")
    if el is None:
        raise FileFormatError(f"{path}: no <ExternalLoads> element (root <{root.tag}>)")
    forces: list[ExternalForceSpec] = []
    for k, ef in enumerate(el.iter("ExternalForce")):
        name = ef.get("name") or f"ExternalForce[{k + 1}]"
        tag = f"<ExternalForce name={name!r}>"
        disabled = (_text(ef, "isDisabled") or "false").lower() == "true"
        applies = (_text(ef, "appliesForce") or "true").lower() == "true"
        if disabled or not applies:
            continue
        body = _text(ef, "applied_to_body")
        fid = _text(ef, "force_identifier")
        for what, val in (("applied_to_body", body), ("force_identifier", fid)):
            if val is None:
                raise FileFormatError(f"{path}: {tag} has no <{what}>")
        fexp = _text(ef, "force_expressed_in_body") or "ground"
        pexp = _text(ef, "point_expressed_in_body") or "ground"
        for what, val in (("force_expressed_in_body", fexp), ("point_expressed_in_body", pexp)):
            if val != "ground":
                raise ForcePlateError(
                    f"{path}: {tag} <{what}>{val}</{what}>: msk reads ground-reaction data "
                    "expressed in 'ground' (the lab) only"
                )
        pid = _text(ef, "point_identifier")
        if pid is None:
            raise FileFormatError(
                f"{path}: {tag} has no <point_identifier> (a force without a point of "
                "application is not a ground reaction msk can apply)"
            )
        forces.append(
            ExternalForceSpec(
                name=name,
                applied_to_body=str(body),
                force_identifier=str(fid),
                point_identifier=pid,
                torque_identifier=_text(ef, "torque_identifier"),
                force_expressed_in_body=fexp,
                point_expressed_in_body=pexp,
            )
        )
    if not forces:
        raise FileFormatError(f"{path}: <ExternalLoads> holds no enabled <ExternalForce>")
    df = _text(el, "datafile")
    datafile = None
    if df is not None and df.lower() != "unassigned":
        datafile = Path(df) if Path(df).is_absolute() else path.parent / df
    return ExternalLoadsSpec(path=path, forces=tuple(forces), datafile=datafile)


def external_force_sets(
    spec: ExternalLoadsSpec, columns: Sequence[str], *, source: str = "GRF table"
) -> tuple[GrfForceSet, ...]:
    """The force sets an ExternalLoads file names in a GRF table (``columns``), each with its
    body, named ``plate<k>`` like :func:`grf_force_sets` (file order of the force-x column,
    ranked together with the sets found by column names so that both agree).

    Raises:
        MissingDataError: an identifier of the xml matches no column of the table (names the
            xml, the ExternalForce and the identifier).
    """
    low = _lookup([c for c in columns if c.lower() != "time"])
    mine = [
        _set_from_identifiers(
            ef.force_identifier,
            ef.point_identifier,
            ef.torque_identifier,
            low,
            f"{spec.path}",
            body=ef.applied_to_body,
            element=f" <ExternalForce name={ef.name!r}> (data {source})",
        )
        for ef in spec.forces
    ]
    try:
        auto = list(grf_force_sets(columns, source=source))
    except MissingDataError:
        auto = []
    pos = {c: i for i, c in enumerate(columns)}
    ranked = sorted({s.force[0] for s in auto} | {s.force[0] for s in mine}, key=pos.__getitem__)
    out = []
    for s in mine:
        out.append(
            GrfForceSet(
                f"plate{ranked.index(s.force[0]) + 1}",
                s.force_identifier,
                s.force,
                s.point,
                s.torque,
                s.body,
            )
        )
    return tuple(out)
