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
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from msk.exceptions import FileFormatError, ForcePlateError, MissingDataError

__all__ = [
    "ExternalForceSpec",
    "ExternalLoadsSpec",
    "GrfForceSet",
    "external_force_sets",
    "grf_force_sets",
    "read_external_loads_xml",
]

_FORCE_X = re.compile(r"^(?P<stem>.*force.*)v(?P<ax>x)$", re.IGNORECASE)


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
    if not found:
        raise MissingDataError(
            f"{source}: no ground-reaction columns (…force…vx, e.g. ground_force_vx, "
            f"ground_force_1_vx, 1_ground_force_vx); columns: {list(cols)[:12]}"
        )
    return _name_sets(found, list(columns))


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
