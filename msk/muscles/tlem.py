"""TLEM 2.0 muscle-tendon parameters and geometry (Carbone et al. 2015) as data.

Source: Carbone V, Fluit R, Pellikaan P, et al. (2015) TLEM 2.0 – A comprehensive musculoskeletal
geometry dataset for subject-specific modeling of lower extremity. J Biomech 48(5):734–741;
supplementary tables copied into ``msk/data/tlem2/`` (see its ``ORIGIN.md``):

- Table 1: the 55 muscles (parts), their number of elements, path type (``S`` straight,
  ``VP`` via points, ``WS`` wrapping surface), origin/insertion type, mass (g), volume (ml);
- Table A3: per muscle-tendon *element* (166), its origin, via and insertion points, each on one
  bone, in that bone's local frame (m). The Psoas Major origins lie on the lumbar spine, which
  TLEM 2.0 does not describe: their location is ``nan``;
- Table A5: the 4 wrapping cylinders (bone, centre m, unit axis, radius m);
- Table A7: per element, nominal (optimal) fibre length (cm), tendon slack length (cm), nominal
  pennation angle (rad) and PCSA (cm²).

Everything is converted to SI once, here. The maximal isometric force is

    F_iso = σ · PCSA,

with the specific tension σ configurable (default 37 N/cm² = 3.7·10⁵ Pa, the value chosen for
msk's TLEM models; reported human values span ~20–100 N/cm², and a recent systematic
review recommends 26.8 N/cm²: Persad et al. 2024, J Appl Physiol 137:945–962).

The A5 cylinders are not linked to muscles in the tables; msk links them by name: "Gluteus
Maximus" → Gluteus Maximus Inferior/Superior, "Iliopsoas" → Iliacus */Psoas Major,
"Quadriceps Femoris" → Rectus Femoris/Vastus *, "Gastrocnemius" → Gastrocnemius */Plantaris
(Plantaris is the only other ``WS`` muscle crossing the knee posteriorly). Every muscle that
Table 1 marks ``WS`` gets exactly one cylinder; the loader checks it.

Element names are those of Table A7 (``AdductorBrevisDistal1``); Table A3 names them with spaces
(``Adductor Brevis Distal 1``) except the rectus femoris, whose two A3 elements "Rectus Femoris
1/2" are A7's ``RectusFemorisLateralis1`` / ``RectusFemorisMedialis1`` (element 1 inserts
laterally on the patella, z > 0, element 2 medially, z < 0).

Published defect repaired on load: Table A3 has no insertion row for "Tibialis Posterior
Medialis 3" (nor has the original .xlsx); msk gives it the insertion shared by the five other
tibialis posterior elements (foot, (0.04489, −0.01477, −0.02404) m).
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cache
from importlib.resources import files
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray

from msk.exceptions import FileFormatError, MissingDataError

__all__ = [
    "DEFAULT_SPECIFIC_TENSION",
    "TLEM_BONES",
    "TLEM_CYLINDER_MUSCLES",
    "TlemCylinder",
    "TlemDataset",
    "TlemElement",
    "TlemMuscle",
    "TlemPathPoint",
    "load_tlem2",
]

#: Default specific tension σ (Pa): 37 N/cm².
DEFAULT_SPECIFIC_TENSION: float = 37.0e4

#: Bones of the TLEM 2.0 tables (``spine`` only carries the Psoas Major origins, without
#: coordinates).
TLEM_BONES: tuple[str, ...] = ("pelvis", "femur", "patella", "tibia", "foot", "spine")

#: Wrapping cylinder (Table A5 name) → muscles (Table 1 names) that wrap over it (msk's link).
TLEM_CYLINDER_MUSCLES: dict[str, tuple[str, ...]] = {
    "Gluteus Maximus": ("Gluteus Maximus Inferior", "Gluteus Maximus Superior"),
    "Iliopsoas": ("Iliacus Lateralis", "Iliacus Medialis", "Iliacus Mid", "Psoas Major"),
    "Quadriceps Femoris": (
        "Rectus Femoris",
        "Vastus Intermedius",
        "Vastus Lateralis Inferior",
        "Vastus Lateralis Superior",
        "Vastus Medialis Inferior",
        "Vastus Medialis Mid",
        "Vastus Medialis Superior",
    ),
    "Gastrocnemius": ("Gastrocnemius Lateralis", "Gastrocnemius Medialis", "Plantaris"),
}

_A3_ALIASES = {
    "RectusFemoris1": "RectusFemorisLateralis1",
    "RectusFemoris2": "RectusFemorisMedialis1",
}

# Published defect: Table A3 (the .xlsx as well) gives no insertion row for "Tibialis Posterior
# Medialis 3"; its via points equal those of the other tibialis posterior elements, all five of
# which insert on the same foot point, so msk takes the insertion of element 2.
_A3_MISSING_INSERTION = {"Tibialis Posterior Medialis 3": "Tibialis Posterior Medialis 2"}

_FILES = {
    "t1": "Table_1_Muscle_list.csv",
    "a3": "Table_A3_Muscle-tendon_lines-of-action.csv",
    "a5": "Table_A5_Wrapping_Surfaces.csv",
    "a7": "Table_A7_Muscle-tendon_architecture.csv",
}

PointKind = Literal["origin", "via", "insertion"]


def _ro(a: NDArray[np.float64]) -> NDArray[np.float64]:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class TlemPathPoint:
    """One origin, via or insertion point of an element, in ``bone``'s local frame (m)."""

    kind: PointKind
    bone: str
    location: NDArray[np.float64]

    def __post_init__(self) -> None:
        object.__setattr__(self, "location", _ro(self.location))

    @property
    def is_located(self) -> bool:
        """False for the Psoas Major origins on the (undescribed) lumbar spine."""
        return bool(np.all(np.isfinite(self.location)))


@dataclass(frozen=True)
class TlemElement:
    """One muscle-tendon element (a line of action) with its Hill-model parameters in SI."""

    name: str
    label: str
    muscle: str
    points: tuple[TlemPathPoint, ...]
    optimal_fiber_length: float
    tendon_slack_length: float
    pennation_angle: float
    pcsa: float
    max_isometric_force: float
    cylinder: str | None

    @property
    def origin(self) -> TlemPathPoint:
        return self.points[0]

    @property
    def insertion(self) -> TlemPathPoint:
        return self.points[-1]

    @property
    def via_points(self) -> tuple[TlemPathPoint, ...]:
        return self.points[1:-1]


@dataclass(frozen=True)
class TlemMuscle:
    """A Table 1 muscle (part): its elements and descriptors (mass kg, volume m³; nan if none)."""

    name: str
    elements: tuple[str, ...]
    path_type: str
    origin_type: str
    insertion_type: str
    mass: float
    volume: float
    cylinder: str | None


@dataclass(frozen=True)
class TlemCylinder:
    """A wrapping cylinder (Table A5) fixed to ``bone``: centre (m), unit axis, radius (m)."""

    name: str
    bone: str
    center: NDArray[np.float64]
    axis: NDArray[np.float64]
    radius: float
    muscles: tuple[str, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _ro(self.center))
        object.__setattr__(self, "axis", _ro(self.axis))


@dataclass(frozen=True)
class TlemDataset:
    """The TLEM 2.0 muscle dataset; per-element arrays follow ``element_names``.

    Arrays (SI): ``optimal_fiber_length`` (m), ``tendon_slack_length`` (m), ``pennation_angle``
    (rad), ``pcsa`` (m²), ``max_isometric_force`` (N) = ``specific_tension`` (Pa) × ``pcsa``.
    """

    elements: tuple[TlemElement, ...]
    muscles: tuple[TlemMuscle, ...]
    cylinders: tuple[TlemCylinder, ...]
    specific_tension: float
    element_names: tuple[str, ...] = field(init=False)
    optimal_fiber_length: NDArray[np.float64] = field(init=False)
    tendon_slack_length: NDArray[np.float64] = field(init=False)
    pennation_angle: NDArray[np.float64] = field(init=False)
    pcsa: NDArray[np.float64] = field(init=False)
    max_isometric_force: NDArray[np.float64] = field(init=False)

    def __post_init__(self) -> None:
        els = self.elements
        object.__setattr__(self, "element_names", tuple(e.name for e in els))
        for attr in (
            "optimal_fiber_length",
            "tendon_slack_length",
            "pennation_angle",
            "pcsa",
            "max_isometric_force",
        ):
            object.__setattr__(self, attr, _ro(np.array([getattr(e, attr) for e in els])))

    def element(self, name: str) -> TlemElement:
        """The element called ``name`` (Table A7 spelling, e.g. ``"GluteusMediusAnterior3"``)."""
        for e in self.elements:
            if e.name == name:
                return e
        raise MissingDataError(f"TLEM 2.0: no muscle element {name!r}")

    def muscle(self, name: str) -> TlemMuscle:
        """The Table 1 muscle called ``name`` (e.g. ``"Gluteus Medius Anterior"``)."""
        for m in self.muscles:
            if m.name == name:
                return m
        raise MissingDataError(f"TLEM 2.0: no muscle {name!r}")

    def cylinder(self, name: str) -> TlemCylinder:
        """The wrapping cylinder called ``name`` (Table A5 spelling)."""
        for c in self.cylinders:
            if c.name == name:
                return c
        raise MissingDataError(f"TLEM 2.0: no wrapping cylinder {name!r}")

    def elements_of(self, muscle: str) -> tuple[TlemElement, ...]:
        """The elements of the Table 1 muscle ``muscle``, in table order."""
        names = set(self.muscle(muscle).elements)
        return tuple(e for e in self.elements if e.name in names)


# ---------------------------------------------------------------------------------------------
# reading


def _read_rows(source: Traversable | Path, file: str) -> list[list[str]]:
    path = source / file
    try:
        # Binary open + TextIOWrapper is what a text-mode open does; a Traversable's typed
        # ``open`` takes no ``newline`` (csv needs newline="").
        with path.open("rb") as raw, io.TextIOWrapper(raw, encoding="utf-8", newline="") as fh:
            return list(csv.reader(fh))
    except FileNotFoundError:
        raise MissingDataError(f"TLEM 2.0 table not found: {path}") from None


def _num(text: str, file: str, line: int, what: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise FileFormatError(f"{file}: line {line}: {what} is not a number: {text!r}") from None
    if not math.isfinite(v):
        raise FileFormatError(f"{file}: line {line}: {what} is not finite: {text!r}")
    return v


def _opt_num(text: str, file: str, line: int, what: str) -> float:
    return math.nan if text.strip() in ("", "-") else _num(text, file, line, what)


def _check_header(rows: list[list[str]], file: str, expected: Sequence[str]) -> None:
    head = [c.strip() for c in rows[0][: len(expected)]] if rows else []
    if head != list(expected):
        raise FileFormatError(f"{file}: line 1: header {head!r}, expected {list(expected)!r}")


class _T1Row(NamedTuple):
    name: str
    n: int
    path_type: str
    origin_type: str
    insertion_type: str
    mass: float
    volume: float


def _read_table1(rows: list[list[str]]) -> list[_T1Row]:
    file = _FILES["t1"]
    _check_header(rows, file, ["Muscle", "# elements", "Type line", "Origin", "Insertion"])
    out: list[_T1Row] = []
    prev_origin, prev_insertion = "", ""
    for line, row in enumerate(rows[1:], start=2):
        if len(row) < 7:
            raise FileFormatError(f"{file}: line {line}: expected 7 columns, got {row!r}")
        name = row[0].strip()
        n = _num(row[1], file, line, f"number of elements of {name!r}")
        if not name or n != int(n) or n < 1:
            raise FileFormatError(f"{file}: line {line}: bad muscle {name!r} / count {row[1]!r}")
        if row[2].strip() not in ("S", "VP", "WS"):
            raise FileFormatError(f"{file}: line {line}: {name!r}: unknown path type {row[2]!r}")
        # blank origin/insertion cells are merged cells of the .xlsx: same as the row above
        prev_origin = row[3].strip() or prev_origin
        prev_insertion = row[4].strip() or prev_insertion
        out.append(
            _T1Row(
                name=name,
                n=int(n),
                path_type=row[2].strip(),
                origin_type=prev_origin,
                insertion_type=prev_insertion,
                mass=_opt_num(row[5], file, line, f"mass of {name!r}") * 1e-3,
                volume=_opt_num(row[6], file, line, f"volume of {name!r}") * 1e-6,
            )
        )
    return out


_KINDS: dict[str, PointKind] = {"Origin": "origin", "Via": "via", "Insertion": "insertion"}


def _read_a3(rows: list[list[str]]) -> list[tuple[str, str, list[TlemPathPoint]]]:
    """(muscle, element label, points) in table order, each path validated."""
    file = _FILES["a3"]
    _check_header(
        rows, file, ["Muscle part", "Muscle-tendon element", "Type of Point", "Segment", "X"]
    )
    elements: list[tuple[str, str, list[TlemPathPoint]]] = []
    muscle = ""

    def close(line: int) -> None:
        if (
            elements
            and elements[-1][1] in _A3_MISSING_INSERTION
            and elements[-1][2][-1].kind == "via"
        ):
            donor = _A3_MISSING_INSERTION[elements[-1][1]]
            paths = {lab: pts for _, lab, pts in elements}
            if donor in paths:
                elements[-1][2].append(paths[donor][-1])
        if elements and elements[-1][2][-1].kind != "insertion":
            raise FileFormatError(
                f"{file}: element {elements[-1][1]!r} (ending before line {line}) has no insertion"
            )

    for line, row in enumerate(rows[1:], start=2):
        if len(row) < 7:
            raise FileFormatError(f"{file}: line {line}: expected 7 columns, got {row!r}")
        if row[0].strip():
            muscle = row[0].strip()
        label = row[1].strip()
        kind = _KINDS.get(row[2].strip())
        if kind is None:
            raise FileFormatError(f"{file}: line {line}: unknown point type {row[2]!r}")
        bone = row[3].strip().rstrip("*").lower()
        if bone not in TLEM_BONES:
            raise FileFormatError(f"{file}: line {line}: unknown bone {row[3]!r}")
        xyz = [c.strip() for c in row[4:7]]
        if all(c == "-" for c in xyz):
            loc = np.full(3, np.nan)
        else:
            loc = np.array(
                [_num(c, file, line, f"{label or muscle} {kind} {a}") for c, a in zip(xyz, "XYZ")]
            )
        if bone == "spine" and np.all(np.isfinite(loc)):
            raise FileFormatError(f"{file}: line {line}: a located point on the spine: {xyz!r}")
        if bone != "spine" and not np.all(np.isfinite(loc)):
            raise FileFormatError(f"{file}: line {line}: point on {bone} without coordinates")
        point = TlemPathPoint(kind=kind, bone=bone, location=loc)
        if label:
            close(line)
            if kind != "origin":
                raise FileFormatError(
                    f"{file}: line {line}: element {label!r} starts with {row[2]!r}, not Origin"
                )
            if not muscle:
                raise FileFormatError(f"{file}: line {line}: element {label!r} has no muscle")
            elements.append((muscle, label, [point]))
        else:
            if not elements:
                raise FileFormatError(f"{file}: line {line}: point before the first element")
            path = elements[-1][2]
            if kind == "origin" or path[-1].kind == "insertion":
                raise FileFormatError(
                    f"{file}: line {line}: element {elements[-1][1]!r}: unexpected {row[2]!r}"
                )
            path.append(point)
    close(len(rows))
    return elements


def _read_a5(rows: list[list[str]]) -> list[tuple[str, str, np.ndarray, np.ndarray, float]]:
    file = _FILES["a5"]
    _check_header(rows, file, ["Cylinder", "Segment", "Center (m)"])
    out = []
    for line, row in enumerate(rows[2:], start=3):  # second line: X, Y, Z sub-headers
        if len(row) < 9:
            raise FileFormatError(f"{file}: line {line}: expected 9 columns, got {row!r}")
        name, bone = row[0].strip(), row[1].strip().lower()
        if bone not in TLEM_BONES:
            raise FileFormatError(
                f"{file}: line {line}: cylinder {name!r}: unknown bone {row[1]!r}"
            )
        c = np.array([_num(v, file, line, f"{name!r} centre") for v in row[2:5]])
        a = np.array([_num(v, file, line, f"{name!r} axis") for v in row[5:8]])
        r = _num(row[8], file, line, f"{name!r} radius")
        na = float(np.linalg.norm(a))
        if not abs(na - 1.0) < 1e-6:
            raise FileFormatError(f"{file}: line {line}: cylinder {name!r}: axis norm {na}, not 1")
        if not r > 0:
            raise FileFormatError(f"{file}: line {line}: cylinder {name!r}: radius {r} <= 0")
        out.append((name, bone, c, a / na, r))
    return out


def _read_a7(rows: list[list[str]]) -> dict[str, tuple[float, float, float, float]]:
    file = _FILES["a7"]
    _check_header(
        rows,
        file,
        [
            "Muscle part",
            "Nominal fiber length (cm)",
            "Tendon slack length (cm)",
            "Nominal pennation angle (rad)",
            "PCSA (cm2)",
        ],
    )
    out: dict[str, tuple[float, float, float, float]] = {}
    for line, row in enumerate(rows[1:], start=2):
        if len(row) < 5:
            raise FileFormatError(f"{file}: line {line}: expected 5 columns, got {row!r}")
        name = row[0].strip()
        if not name or name in out:
            raise FileFormatError(f"{file}: line {line}: empty or duplicate element {name!r}")
        lf, ls, pen, pcsa = (
            _num(row[i], file, line, f"{name} {w}")
            for i, w in enumerate(("fibre length", "tendon slack length", "pennation", "PCSA"), 1)
        )
        if not lf > 0:
            raise FileFormatError(f"{file}: line {line}: {name}: fibre length {lf} cm <= 0")
        if not ls >= 0:
            raise FileFormatError(f"{file}: line {line}: {name}: tendon slack length {ls} cm < 0")
        if not 0 <= pen < math.pi / 2:
            raise FileFormatError(
                f"{file}: line {line}: {name}: pennation {pen} rad out of [0, π/2)"
            )
        if not pcsa > 0:
            raise FileFormatError(f"{file}: line {line}: {name}: PCSA {pcsa} cm² <= 0")
        out[name] = (lf * 1e-2, ls * 1e-2, pen, pcsa * 1e-4)
    return out


def load_tlem2(
    *,
    specific_tension: float = DEFAULT_SPECIFIC_TENSION,
    directory: str | Path | None = None,
) -> TlemDataset:
    """Load the TLEM 2.0 muscle dataset (166 elements of 55 muscles, 4 cylinders) in SI.

    Args:
        specific_tension: σ in Pa (default 37 N/cm² = 3.7·10⁵ Pa); ``F_iso = σ · PCSA``.
        directory: folder holding the four CSV tables (default: the copy shipped in
            ``msk/data/tlem2``).

    Raises:
        FileFormatError: a malformed row (file, line and offending value named) or tables that
            disagree (element counts, names, wrapping muscles).
        MissingDataError: a table is absent.
    """
    sigma = float(specific_tension)
    if not (math.isfinite(sigma) and sigma > 0):
        raise FileFormatError(
            f"TLEM 2.0: specific_tension must be > 0 Pa, got {specific_tension!r}"
        )
    if directory is None:
        return _load_default(sigma)
    return _load(Path(directory), sigma)


@cache
def _load_default(sigma: float) -> TlemDataset:
    return _load(files("msk") / "data" / "tlem2", sigma)


def _load(source: Traversable | Path, sigma: float) -> TlemDataset:
    t1 = _read_table1(_read_rows(source, _FILES["t1"]))
    a3 = _read_a3(_read_rows(source, _FILES["a3"]))
    a5 = _read_a5(_read_rows(source, _FILES["a5"]))
    a7 = _read_a7(_read_rows(source, _FILES["a7"]))
    f_a3, f_a7, f_t1, f_a5 = _FILES["a3"], _FILES["a7"], _FILES["t1"], _FILES["a5"]

    cyl_of_muscle: dict[str, str] = {}
    for cname, _bone, *_ in a5:
        if cname not in TLEM_CYLINDER_MUSCLES:
            raise FileFormatError(f"{f_a5}: cylinder {cname!r} is not linked to any muscle")
        for muscle_name in TLEM_CYLINDER_MUSCLES[cname]:
            cyl_of_muscle[muscle_name] = cname

    t1_names = [m.name for m in t1]
    elements: list[TlemElement] = []
    per_muscle: dict[str, list[str]] = {n: [] for n in t1_names}
    for muscle, label, points in a3:
        if muscle not in per_muscle:
            raise FileFormatError(f"{f_a3}: muscle {muscle!r} is not in {f_t1}")
        key = label.replace(" ", "")
        key = _A3_ALIASES.get(key, key)
        if key not in a7:
            raise FileFormatError(f"{f_a3}: element {label!r} has no row {key!r} in {f_a7}")
        if key in (e.name for e in elements):
            raise FileFormatError(f"{f_a3}: duplicate element {label!r}")
        lf, ls, pen, pcsa = a7[key]
        per_muscle[muscle].append(key)
        elements.append(
            TlemElement(
                name=key,
                label=label,
                muscle=muscle,
                points=tuple(points),
                optimal_fiber_length=lf,
                tendon_slack_length=ls,
                pennation_angle=pen,
                pcsa=pcsa,
                max_isometric_force=sigma * pcsa,
                cylinder=cyl_of_muscle.get(muscle),
            )
        )
    missing = sorted(set(a7) - {e.name for e in elements})
    if missing:
        raise FileFormatError(f"{f_a7}: elements without a line of action in {f_a3}: {missing}")

    muscles: list[TlemMuscle] = []
    for m in t1:
        name = m.name
        els = per_muscle[name]
        if len(els) != m.n:
            raise FileFormatError(
                f"{f_t1}: muscle {name!r} has {m.n} elements, {f_a3} has {len(els)}"
            )
        cyl = cyl_of_muscle.get(name)
        if (m.path_type == "WS") != (cyl is not None):
            raise FileFormatError(
                f"{f_t1}: muscle {name!r} path type {m.path_type!r} but cylinder {cyl!r}"
            )
        muscles.append(
            TlemMuscle(
                name=name,
                elements=tuple(els),
                path_type=m.path_type,
                origin_type=m.origin_type,
                insertion_type=m.insertion_type,
                mass=m.mass,
                volume=m.volume,
                cylinder=cyl,
            )
        )
    unknown = sorted({m for ms in TLEM_CYLINDER_MUSCLES.values() for m in ms} - set(t1_names))
    if unknown:
        raise FileFormatError(f"{f_t1}: wrapping muscles not in the table: {unknown}")

    cylinders = tuple(
        TlemCylinder(
            name=cname, bone=bone, center=c, axis=a, radius=r, muscles=TLEM_CYLINDER_MUSCLES[cname]
        )
        for cname, bone, c, a, r in a5
    )
    return TlemDataset(
        elements=tuple(elements),
        muscles=tuple(muscles),
        cylinders=cylinders,
        specific_tension=sigma,
    )
