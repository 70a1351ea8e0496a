"""Generic segment inertial parameters from body mass, height and sex.

Two published tables are available:

``"dumas2007"``
    Dumas R, Chèze L, Verriest J-P (2007) Adjustments to McConville et al. and Young et al. body
    segment inertial parameters. J Biomech 40:543–553 (Table 2 of the paper). Segment frames are
    the ISB frames (Wu et al. 2002, 2005): origin at the proximal joint centre (``origin`` of
    each segment), **x anterior, y superior (proximal, along the segment), z to the right**, in
    the standing anatomical pose. Values are for the right side; the left side is the mirror
    image (z → −z, which flips the sign of ``com[2]``, ``I_xz`` and ``I_yz``). The relative COM
    position ``(c_x, c_y, c_z)`` and the relative radii of gyration ``r_ij`` are fractions of the
    segment length ``L``::

        c = L (c_x, c_y, c_z),   I_ij = ± m (r_ij L)²,

    where the minus sign applies to the products marked ``i`` in the paper (``j`` in the CSV:
    an "imaginary" radius, i.e. a negative tensor entry). The tensor entries are those of the
    inertia matrix itself (``I_xy`` is the (0, 1) entry), as in Dumas et al. 2007, Eq. 1.
    Caution: the published female thorax tensor (and the female ``thorax_alt`` and
    ``hand_alt``) violates the triangle inequality on principal moments, so it is *not*
    physically consistent (:func:`is_physically_consistent` is False); use it as a prior only.

``"deleva1996"``
    de Leva P (1996) Adjustments to Zatsiorsky–Seluyanov's segment inertia parameters.
    J Biomech 29:1223–1230, Table 4 (transcribed from the paper into
    ``msk/data/anthropometry/deleva1996_table4.csv``). The table gives the COM on the
    longitudinal axis as a fraction of the length measured from the *origin* landmark (HJC for
    the thigh, KJC for the shank, HEEL for the foot, VERT for the head, CERV for the trunk...)
    and principal radii of gyration about the sagittal, transverse and longitudinal axes.
    msk expresses them in ISB-oriented frames so both tables can be used alike: origin at the
    origin landmark, **y along the longitudinal axis pointing from the other landmark to the
    origin landmark (superior/proximal), x anterior, z right**, so ``com = (0, −c L, 0)`` and
    ``I = m L² diag(r_sag², r_lon², r_trv²)``. The foot is the exception (its longitudinal axis
    is heel → toe tip): origin at HEEL, **x along HEEL → TTIP (anterior), y superior, z right**,
    ``com = (c L, 0, 0)`` and ``I = m L² diag(r_lon², r_sag², r_trv²)``. "Sagittal" is the axis
    lying in the sagittal plane perpendicular to the longitudinal axis (antero-posterior for the
    upright segments, vertical for the foot); "transverse" is the medio-lateral axis. (The
    paper does not define the two columns for the foot; another public implementation maps
    them the other way round, a ≤ 10 % difference between two moments.) The rows used are
    head VERT–CERV, trunk CERV–MIDH, upper/middle/lower trunk CERV–XYPH / XYPH–OMPH /
    OMPH–MIDH, upper arm SJC–EJC, forearm EJC–WJC, hand WJC–MET3, thigh HJC–KJC, shank
    KJC–LMAL (``shank_ajc``: KJC–AJC, ankle joint centre, same mass), foot HEEL–TTIP.

OpenSim bodies (gait2392, Rajagopal 2016) use the same orientation in the default pose — x
anterior, y superior (distal → proximal along the limb), z to the right — *for both legs*
(left-leg geometry is mirrored in z, the axes are not; checked on the gait2392 bodies and path
points). A right-side segment therefore goes onto ``femur_r`` with an identity rotation and a
translation (:func:`transform_segment`); a left-side one is first mirrored
(:func:`mirror_segment`, done by :func:`generic_segments` for ``*_l`` keys).

Pinocchio's standard inertial-parameter vector (``pinocchio.Inertia.toDynamicParameters``) is
``φ = (m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz)`` with the inertia taken about
the body-frame origin (:data:`INERTIAL_PARAMETER_NAMES`). Physical consistency of ``φ`` is the
positive definiteness of the 4×4 pseudo-inertia matrix (Wensing, Kim & Slotine 2017, IEEE RA-L
3(1):60–67, Eq. 5 and Theorem 1)::

    J(φ) = [[Σ, h], [hᵀ, m]],   Σ = ½ tr(Ī) 1₃ − Ī,   h = m c,

where ``Ī`` is the rotational inertia about the origin.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from functools import cache
from importlib.resources import files
from importlib.resources.abc import Traversable
from typing import Literal, cast

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import AnthropometryError, FileFormatError, InertiaError, MskError
from msk.model.core import INERTIAL_PARAMETER_NAMES
from msk.results.summary import Anthropometry, AnthropometrySegment

__all__ = [
    "DELEVA1996_SEGMENTS",
    "DUMAS2007_SEGMENTS",
    "INERTIAL_PARAMETER_NAMES",
    "REFERENCE_STATURE",
    "SEXES",
    "TABLES",
    "SegmentInertia",
    "SegmentRatios",
    "generic_segments",
    "inertia_about",
    "inertial_parameters",
    "is_physically_consistent",
    "mirror_segment",
    "model_anthropometry",
    "pseudo_inertia",
    "segment_from_parameters",
    "segment_table",
    "to_pinocchio_inertia",
    "total_mass",
    "transform_segment",
]

Sex = Literal["male", "female"]
Table = Literal["dumas2007", "deleva1996"]

SEXES: tuple[str, ...] = ("male", "female")
TABLES: tuple[str, ...] = ("dumas2007", "deleva1996")


#: Reference statures (m) that turn the tables' mean segment lengths into length/height ratios:
#: de Leva 1996 (Zatsiorsky–Seluyanov samples: 1741 mm men, 1735 mm women) and Dumas 2007
#: (McConville et al. 1980 men, Young et al. 1983 women: 1.77 m and 1.61 m).
REFERENCE_STATURE: dict[tuple[str, str], float] = {
    ("deleva1996", "male"): 1.741,
    ("deleva1996", "female"): 1.735,
    ("dumas2007", "male"): 1.77,
    ("dumas2007", "female"): 1.61,
}

#: Segments of a full body that sum to ~100 % of body mass (bilateral ones are duplicated with
#: ``_r`` / ``_l`` suffixes by :func:`generic_segments`).
DUMAS2007_SEGMENTS: tuple[str, ...] = (
    "head_neck",
    "thorax",
    "pelvis",
    "upper_arm",
    "forearm",
    "hand",
    "thigh",
    "shank",
    "foot",
)
DELEVA1996_SEGMENTS: tuple[str, ...] = (
    "head",
    "upper_trunk",
    "middle_trunk",
    "lower_trunk",
    "upper_arm",
    "forearm",
    "hand",
    "thigh",
    "shank",
    "foot",
)

_BILATERAL = frozenset(
    {"upper_arm", "forearm", "hand", "thigh", "shank", "shank_ajc", "foot", "hand_alt", "foot_alt"}
)

_DUMAS_NAMES = {
    "HeadNeck": "head_neck",
    "Thorax": "thorax",
    "Arm": "upper_arm",
    "Forearm": "forearm",
    "Hand": "hand",
    "Pelvis": "pelvis",
    "Thigh": "thigh",
    "Leg": "shank",
    "Foot": "foot",
    "AltThorax": "thorax_alt",
    "AltHand": "hand_alt",
    "AltPelvis": "pelvis_alt",
    "AltFoot": "foot_alt",
}

_DUMAS_FILE = "dumas2007_segment_inertial_parameters.csv"
_DELEVA_FILE = "deleva1996_table4.csv"


def _readonly(a: ArrayLike, shape: tuple[int, ...], what: str) -> NDArray[np.float64]:
    arr = np.array(a, dtype=float)
    if arr.shape != shape:
        raise InertiaError(f"{what}: expected shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InertiaError(f"{what}: non-finite value in {arr.tolist()}")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class SegmentInertia:
    """Inertial parameters of one segment (SI).

    Attributes:
        name: segment name (``thigh_r``...).
        mass: mass m (kg).
        com: centre of mass c (3,) in the segment frame (m).
        inertia: inertia tensor (3, 3) about the COM, segment-frame axes (kg m²).
        length: segment length L used to scale the table (m); ``nan`` if unknown.
        origin: what the frame origin is (landmark or joint centre), for humans.
    """

    name: str
    mass: float
    com: NDArray[np.float64]
    inertia: NDArray[np.float64]
    length: float
    origin: str = ""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mass) and self.mass >= 0.0):
            raise InertiaError(
                f"segment {self.name!r}: mass must be finite and >= 0, got {self.mass}"
            )
        object.__setattr__(self, "mass", float(self.mass))
        object.__setattr__(self, "length", float(self.length))
        object.__setattr__(self, "com", _readonly(self.com, (3,), f"segment {self.name!r} com"))
        inertia = _readonly(self.inertia, (3, 3), f"segment {self.name!r} inertia")
        if not np.allclose(inertia, inertia.T, rtol=1e-9, atol=1e-12):
            raise InertiaError(
                f"segment {self.name!r}: inertia is not symmetric: {inertia.tolist()}"
            )
        object.__setattr__(self, "inertia", inertia)


@dataclass(frozen=True)
class SegmentRatios:
    """The relative (dimensionless) parameters of one table row, in the msk segment frame.

    ``mass = mass_fraction · body_mass``, ``length = length_ratio · height``,
    ``com = com_ratio · length``, ``inertia = mass · length² · gyration_sq``.
    """

    name: str
    table: str
    sex: str
    origin: str
    other_end: str
    length_ratio: float
    mass_fraction: float
    com_ratio: NDArray[np.float64]
    gyration_sq: NDArray[np.float64]

    def __post_init__(self) -> None:
        object.__setattr__(self, "com_ratio", _readonly(self.com_ratio, (3,), self.name))
        object.__setattr__(self, "gyration_sq", _readonly(self.gyration_sq, (3, 3), self.name))


def _data_path(name: str) -> Traversable:
    return files("msk") / "data" / "anthropometry" / name


def _signed_sq(text: str, where: str) -> float:
    """``"0.09j"`` → −0.09², ``"0.02"`` → +0.02² (Dumas 2007 "i" notation)."""
    s = text.strip()
    neg = s.endswith("j")
    try:
        r = float(s[:-1] if neg else s)
    except ValueError:
        raise FileFormatError(f"{_DUMAS_FILE}: {where}: bad radius of gyration {text!r}") from None
    return -(r**2) if neg else r**2


def _float(text: str, file: str, where: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise FileFormatError(f"{file}: {where}: not a number: {text!r}") from None


@cache
def _load_dumas() -> dict[tuple[str, str], SegmentRatios]:
    out: dict[tuple[str, str], SegmentRatios] = {}
    with _data_path(_DUMAS_FILE).open(encoding="utf-8") as fh:
        for i, row in enumerate(csv.DictReader(fh), start=2):
            where = f"line {i} ({row.get('Segment')!r}, {row.get('Gender')!r})"
            seg = _DUMAS_NAMES.get(row["Segment"])
            sex = {"M": "male", "F": "female"}.get(row["Gender"])
            if seg is None or sex is None:
                raise FileFormatError(f"{_DUMAS_FILE}: {where}: unknown segment or sex")
            f = [_float(row[k], _DUMAS_FILE, where) for k in ("Length", "RelMass")]
            c = [_float(row[k], _DUMAS_FILE, where) for k in ("RelComX", "RelComY", "RelComZ")]
            xx, yy, zz = (_signed_sq(row[k], where) for k in ("RelIXX", "RelIYY", "RelIZZ"))
            xy, xz, yz = (_signed_sq(row[k], where) for k in ("RelIXY", "RelIXZ", "RelIYZ"))
            g = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
            out[(seg, sex)] = SegmentRatios(
                name=seg,
                table="dumas2007",
                sex=sex,
                origin=row["Origin"],
                other_end=row["LengthPoint2"]
                if row["LengthPoint1"] == row["Origin"]
                else row["LengthPoint1"],
                length_ratio=f[0] / REFERENCE_STATURE[("dumas2007", sex)],
                mass_fraction=f[1],
                com_ratio=np.array(c),
                gyration_sq=g,
            )
    return out


@cache
def _load_deleva() -> dict[tuple[str, str], SegmentRatios]:
    out: dict[tuple[str, str], SegmentRatios] = {}
    with _data_path(_DELEVA_FILE).open(encoding="utf-8") as fh:
        for i, row in enumerate(csv.DictReader(fh), start=2):
            where = f"line {i} ({row.get('segment')!r}, {row.get('sex')!r})"
            seg, sex = row["segment"], row["sex"]
            keys = ("length_mm", "mass_pct", "com_pct_from_origin", "r_sag_pct", "r_trv_pct")
            length_mm, mass, com, r_sag, r_trv = (_float(row[k], _DELEVA_FILE, where) for k in keys)
            r_lon = _float(row["r_lon_pct"], _DELEVA_FILE, where)
            c, rs, rt, rl = com / 100, r_sag / 100, r_trv / 100, r_lon / 100
            if seg == "foot":
                com_ratio = np.array([c, 0.0, 0.0])
                g = np.diag([rl**2, rs**2, rt**2])
            else:
                com_ratio = np.array([0.0, -c, 0.0])
                g = np.diag([rs**2, rl**2, rt**2])
            out[(seg, sex)] = SegmentRatios(
                name=seg,
                table="deleva1996",
                sex=sex,
                origin=row["origin_landmark"],
                other_end=row["other_landmark"],
                length_ratio=length_mm / 1000.0 / REFERENCE_STATURE[("deleva1996", sex)],
                mass_fraction=mass / 100,
                com_ratio=com_ratio,
                gyration_sq=g,
            )
    return out


def _check_table_sex(table: str, sex: str) -> None:
    if table not in TABLES:
        raise AnthropometryError(f"unknown anthropometric table {table!r}; use one of {TABLES}")
    if sex not in SEXES:
        raise AnthropometryError(f"unknown sex {sex!r}; use one of {SEXES}")


def segment_table(table: Table = "dumas2007", *, sex: Sex) -> dict[str, SegmentRatios]:
    """The relative parameters of every segment of ``table`` for ``sex``, keyed by segment name.

    Dumas 2007 also provides its alternative definitions (``thorax_alt``, ``hand_alt``,
    ``pelvis_alt``, ``foot_alt``); de Leva 1996 provides ``trunk`` besides its three parts and
    ``shank_ajc`` (knee to ankle joint centre) besides ``shank`` (knee to lateral malleolus).
    """
    _check_table_sex(table, sex)
    rows = _load_dumas() if table == "dumas2007" else _load_deleva()
    return {seg: r for (seg, s), r in rows.items() if s == sex}


def _positive(value: float, what: str) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0.0):
        raise AnthropometryError(f"{what} must be a positive finite number, got {value!r}")
    return v


def mirror_segment(seg: SegmentInertia, *, name: str | None = None) -> SegmentInertia:
    """Mirror image through the sagittal plane (z → −z): the left-side segment of a right one.

    ``c_z``, ``I_xz`` and ``I_yz`` change sign (Dumas et al. 2007, Sect. 2).
    """
    s = np.diag([1.0, 1.0, -1.0])
    return SegmentInertia(
        name=seg.name if name is None else name,
        mass=seg.mass,
        com=s @ seg.com,
        inertia=s @ seg.inertia @ s,
        length=seg.length,
        origin=seg.origin,
    )


def generic_segments(
    body_mass: float,
    height: float | None = None,
    *,
    sex: Sex,
    table: Table = "dumas2007",
    segment_lengths: Mapping[str, float] | None = None,
    segments: Sequence[str] | None = None,
) -> dict[str, SegmentInertia]:
    """Generic segment inertial parameters scaled to a subject.

    Args:
        body_mass: body mass M (kg).
        height: stature H (m); segment lengths default to ``L = (L̄ / H̄) H`` with the table's
            mean length L̄ and reference stature H̄ (:data:`REFERENCE_STATURE`).
        sex: ``"male"`` or ``"female"``.
        table: ``"dumas2007"`` (default) or ``"deleva1996"``.
        segment_lengths: measured lengths (m), e.g. from markers, keyed by base name
            (``"thigh"``, both sides) or by sided name (``"thigh_l"``, takes precedence). They
            override the height-based lengths; with ``height=None`` every segment needs one.
        segments: base names to compute (default: the full body, :data:`DUMAS2007_SEGMENTS` or
            :data:`DELEVA1996_SEGMENTS`, whose masses sum to ~100 % of M).

    Returns:
        ``{name: SegmentInertia}``; bilateral segments appear twice as ``<name>_r`` and
        ``<name>_l`` (the left one mirrored), axial ones once. ``m = f M``, ``c = L ĉ`` and
        ``I = m L² R²`` in the frames documented in the module docstring.
    """
    _check_table_sex(table, sex)
    m_body = _positive(body_mass, "body_mass (kg)")
    h = None if height is None else _positive(height, "height (m)")
    rows = segment_table(table, sex=sex)
    names = (
        list(segments)
        if segments is not None
        else list(DUMAS2007_SEGMENTS if table == "dumas2007" else DELEVA1996_SEGMENTS)
    )
    lengths = dict(segment_lengths or {})
    known = set(rows) | {f"{n}_{s}" for n in rows if n in _BILATERAL for s in "rl"}
    for key, value in lengths.items():
        if key not in known:
            raise AnthropometryError(
                f"segment_lengths: unknown segment {key!r} for table {table!r}"
            )
        _positive(value, f"segment_lengths[{key!r}] (m)")
    out: dict[str, SegmentInertia] = {}
    for base in names:
        if base not in rows:
            raise AnthropometryError(
                f"unknown segment {base!r} for table {table!r}; known: {sorted(rows)}"
            )
        r = rows[base]
        sides = ("_r", "_l") if base in _BILATERAL else ("",)
        for suffix in sides:
            name = base + suffix
            if name in lengths:
                length = float(lengths[name])
            elif base in lengths:
                length = float(lengths[base])
            elif h is not None:
                length = r.length_ratio * h
            else:
                raise AnthropometryError(f"segment {name!r}: no length given and height is None")
            mass = r.mass_fraction * m_body
            seg = SegmentInertia(
                name=name,
                mass=mass,
                com=r.com_ratio * length,
                inertia=mass * length**2 * r.gyration_sq,
                length=length,
                origin=r.origin,
            )
            out[name] = mirror_segment(seg) if suffix == "_l" else seg
    return out


def inertia_about(seg: SegmentInertia, point: ArrayLike) -> NDArray[np.float64]:
    """Inertia tensor about ``point`` (segment frame), by the parallel-axis theorem.

    ``I_P = I_C + m (‖d‖² 1₃ − d dᵀ)``, ``d = c − p``.
    """
    p = _readonly(point, (3,), f"segment {seg.name!r} point")
    d = seg.com - p
    return seg.inertia + seg.mass * (float(d @ d) * np.eye(3) - np.outer(d, d))


def transform_segment(
    seg: SegmentInertia,
    *,
    rotation: ArrayLike | None = None,
    translation: ArrayLike | None = None,
    name: str | None = None,
    origin: str | None = None,
) -> SegmentInertia:
    """Express a segment's inertia in another frame F (e.g. an OpenSim body frame).

    F's origin is ``translation`` t and its axes are the columns of ``rotation`` R, both given
    in the current segment frame S (so ``p_S = t + R p_F``). Then ``c_F = Rᵀ (c_S − t)`` and, the
    tensor being about the COM, ``I_F = Rᵀ I_S R``; the inertia about F's origin follows with
    :func:`inertia_about` or :func:`inertial_parameters`.
    """
    r = np.eye(3) if rotation is None else _readonly(rotation, (3, 3), "rotation")
    if not np.allclose(r.T @ r, np.eye(3), atol=1e-9) or np.linalg.det(r) < 0:
        raise InertiaError(f"segment {seg.name!r}: rotation is not a proper rotation: {r.tolist()}")
    t = np.zeros(3) if translation is None else _readonly(translation, (3,), "translation")
    return SegmentInertia(
        name=seg.name if name is None else name,
        mass=seg.mass,
        com=r.T @ (seg.com - t),
        inertia=r.T @ seg.inertia @ r,
        length=seg.length,
        origin=seg.origin if origin is None else origin,
    )


def to_pinocchio_inertia(seg: SegmentInertia) -> pin.Inertia:
    """The segment as a ``pinocchio.Inertia`` (mass, lever = COM, inertia about the COM)."""
    return pin.Inertia(seg.mass, seg.com.copy(), seg.inertia.copy())


def inertial_parameters(seg: SegmentInertia) -> NDArray[np.float64]:
    """Standard parameter vector φ in :data:`INERTIAL_PARAMETER_NAMES` order.

    ``φ = (m, m c, Ī_xx, Ī_xy, Ī_yy, Ī_xz, Ī_yz, Ī_zz)`` with ``Ī = I_C + m [c]×ᵀ[c]×`` the
    inertia about the frame origin (same as ``pinocchio.Inertia.toDynamicParameters``).
    """
    i0 = inertia_about(seg, np.zeros(3))
    h = seg.mass * seg.com
    return np.array(
        [seg.mass, *h, i0[0, 0], i0[0, 1], i0[1, 1], i0[0, 2], i0[1, 2], i0[2, 2]],
        dtype=float,
    )


def _phi(phi: ArrayLike) -> NDArray[np.float64]:
    return _readonly(phi, (10,), "inertial parameter vector φ (m, mx, my, mz, Ixx, ..., Izz)")


def segment_from_parameters(
    phi: ArrayLike, *, name: str, length: float = math.nan, origin: str = ""
) -> SegmentInertia:
    """Inverse of :func:`inertial_parameters` (needs ``m > 0``)."""
    p = _phi(phi)
    m = p[0]
    if not m > 0.0:
        raise InertiaError(f"segment {name!r}: mass must be > 0 to recover the COM, got {m}")
    c = p[1:4] / m
    i0 = np.array([[p[4], p[5], p[7]], [p[5], p[6], p[8]], [p[7], p[8], p[9]]])
    ic = i0 - m * (float(c @ c) * np.eye(3) - np.outer(c, c))
    return SegmentInertia(name=name, mass=m, com=c, inertia=ic, length=length, origin=origin)


def pseudo_inertia(phi: ArrayLike) -> NDArray[np.float64]:
    """4×4 pseudo-inertia ``J = [[½ tr(Ī) 1₃ − Ī, h], [hᵀ, m]]`` (Wensing et al. 2017, Eq. 5).

    ``J = ∫ [x; 1][x; 1]ᵀ dm`` is the second-moment matrix of the mass distribution, linear in φ.
    """
    p = _phi(phi)
    i0 = np.array([[p[4], p[5], p[7]], [p[5], p[6], p[8]], [p[7], p[8], p[9]]])
    j = np.empty((4, 4))
    j[:3, :3] = 0.5 * np.trace(i0) * np.eye(3) - i0
    j[:3, 3] = p[1:4]
    j[3, :3] = p[1:4]
    j[3, 3] = p[0]
    return j


def is_physically_consistent(phi: ArrayLike, *, tol: float = 0.0) -> bool:
    """Whether φ is physically consistent: ``λ_min(J(φ)) > tol`` (Wensing et al. 2017, Thm 1).

    Strict positive definiteness is equivalent to m > 0 and the principal moments about the COM
    being positive and satisfying the triangle inequalities strictly. ``tol`` (kg m², ≥ 0) asks
    for a margin.
    """
    return bool(np.linalg.eigvalsh(pseudo_inertia(phi))[0] > tol)


def total_mass(segments: Iterable[SegmentInertia]) -> float:
    """Sum of the masses (kg)."""
    return float(sum(s.mass for s in segments))


#: the model's segments (gait2392 / Rajagopal stems) → the table's segments they hold (the
#: foot = talus + calcaneus + toes; the torso = trunk, head and arms)
_MODEL_SEGMENTS = {
    "pelvis": ("pelvis",),
    "femur": ("thigh",),
    "tibia": ("shank",),
    "foot": ("foot",),
    "torso": ("head_neck", "thorax", "upper_arm", "forearm", "hand"),
}


def model_anthropometry(
    body_names: Iterable[str], mass_kg: float | None, height_m: float | None, sex: str
) -> Anthropometry | None:
    """``summary.anthropometry``: the generic segment masses of the anthropometric table
    (Dumas R, Chèze L, Verriest J-P 2007, J Biomech 40:543-553) mapped on the model's bodies
    ``body_names`` (the foot = talus + calcaneus + toes; the torso = trunk, head and arms).
    Segment masses are fractions of body mass: the stature (1.75 m when None) only sets
    lengths and inertias, which are not reported. None when the table has no such subject."""
    try:
        sx = cast(Literal["male", "female"], sex)
        segs = generic_segments(float(mass_kg or np.nan), height_m or 1.75, sex=sx)
    except MskError:
        return None
    out = {}
    for body in body_names:
        base, _, sd = body.rpartition("_") if body.endswith(("_l", "_r")) else (body, "", "")
        key = "foot" if base in ("talus", "calcn", "toes") else base
        if key not in _MODEL_SEGMENTS:
            continue
        total = 0.0
        for s in _MODEL_SEGMENTS[key]:
            for name, seg in segs.items():
                stem = name[:-2] if name.endswith(("_l", "_r")) else name
                side_ok = not sd or not name.endswith(("_l", "_r")) or name.endswith("_" + sd)
                if stem == s and side_ok:
                    total += seg.mass
        label = f"{key}_{sd}" if sd else key
        out[label] = AnthropometrySegment(mass_kg=total, table="Dumas et al. 2007")
    return Anthropometry(segments=out, table="Dumas et al. 2007", sex=sex)
