"""Tests of msk.model.anthropometry: published table values, scaling, frames, Pinocchio
parameters."""

from __future__ import annotations

import csv
from importlib.resources import files

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from msk.exceptions import AnthropometryError, InertiaError, MskError
from msk.model.anthropometry import (
    DELEVA1996_SEGMENTS,
    DUMAS2007_SEGMENTS,
    INERTIAL_PARAMETER_NAMES,
    REFERENCE_STATURE,
    SEXES,
    TABLES,
    SegmentInertia,
    generic_segments,
    inertia_about,
    inertial_parameters,
    is_physically_consistent,
    mirror_segment,
    pseudo_inertia,
    segment_from_parameters,
    segment_table,
    to_pinocchio_inertia,
    total_mass,
    transform_segment,
)

# de Leva (1996) Table 4, values of the paper (percent): mass, COM from the origin landmark
# (HJC, KJC, HEEL, OMPH for the lower trunk), radii of gyration sagittal / transverse /
# longitudinal, length (mm).
DELEVA_PAPER = {
    ("male", "thigh"): (14.16, 40.95, 32.9, 32.9, 14.9, 422.2),
    ("male", "shank"): (4.33, 44.59, 25.5, 24.9, 10.3, 434.0),
    ("male", "shank_ajc"): (4.33, 43.95, 25.1, 24.6, 10.2, 440.3),
    ("male", "foot"): (1.37, 44.15, 25.7, 24.5, 12.4, 258.1),
    ("male", "lower_trunk"): (11.17, 61.15, 61.5, 55.1, 58.7, 145.7),
    ("male", "trunk"): (43.46, 51.38, 32.8, 30.6, 16.9, 603.3),
    ("female", "thigh"): (14.78, 36.12, 36.9, 36.4, 16.2, 368.5),
    ("female", "shank"): (4.81, 44.16, 27.1, 26.7, 9.3, 432.3),
    ("female", "shank_ajc"): (4.81, 43.52, 26.7, 26.3, 9.2, 438.6),
    ("female", "foot"): (1.29, 40.14, 29.9, 27.9, 13.9, 228.3),
    ("female", "lower_trunk"): (12.47, 49.20, 43.3, 40.2, 44.4, 181.5),
    ("female", "trunk"): (42.57, 49.64, 30.7, 29.2, 14.7, 614.8),
}


@pytest.mark.parametrize(("sex", "segment"), sorted(DELEVA_PAPER))
def test_deleva_paper_values(sex: str, segment: str) -> None:
    mass_pct, com_pct, r_sag, r_trv, r_lon, length_mm = DELEVA_PAPER[(sex, segment)]
    body_mass, height = 80.0, REFERENCE_STATURE[("deleva1996", sex)]
    segs = generic_segments(body_mass, height, sex=sex, table="deleva1996", segments=[segment])
    seg = segs[f"{segment}_r"] if f"{segment}_r" in segs else segs[segment]
    length = length_mm / 1000
    assert seg.length == pytest.approx(length, rel=1e-12)
    assert seg.mass == pytest.approx(mass_pct / 100 * body_mass, rel=1e-12)
    if segment == "foot":  # x along HEEL -> TTIP, origin at HEEL
        assert seg.com == pytest.approx([com_pct / 100 * length, 0, 0], abs=1e-12)
        radii = np.sqrt(np.diag(seg.inertia)[[1, 2, 0]] / seg.mass) / length
    else:  # y from the distal landmark to the proximal origin landmark
        assert seg.com == pytest.approx([0, -com_pct / 100 * length, 0], abs=1e-12)
        radii = np.sqrt(np.diag(seg.inertia)[[0, 2, 1]] / seg.mass) / length
    assert radii == pytest.approx(np.array([r_sag, r_trv, r_lon]) / 100, rel=1e-12)
    assert np.count_nonzero(seg.inertia - np.diag(np.diag(seg.inertia))) == 0


def test_deleva_landmarks_lower_limb() -> None:
    for sex in SEXES:
        rows = segment_table("deleva1996", sex=sex)
        assert (rows["thigh"].origin, rows["thigh"].other_end) == ("HJC", "KJC")
        assert (rows["shank"].origin, rows["shank"].other_end) == ("KJC", "LMAL")
        assert (rows["foot"].origin, rows["foot"].other_end) == ("HEEL", "TTIP")


def test_deleva_differs_from_biobuddy_transcription_only_where_documented() -> None:
    """The biobuddy CSV agrees with the paper table except for the documented entries."""
    path = files("msk") / "data" / "anthropometry" / "deleva1996_table4_as_coded_in_biobuddy.csv"
    with path.open(encoding="utf-8") as fh:
        bb = {(r["sex"], r["segment"]): r for r in csv.DictReader(fh)}
    names = {"lower_arm": "forearm", "mid_trunk": "middle_trunk"}
    differences = set()
    for (sex, seg_bb), row in bb.items():
        seg = names.get(seg_bb, seg_bb)
        ours = segment_table("deleva1996", sex=sex)[seg]
        g = np.diag(ours.gyration_sq)
        if seg == "foot":
            r_sag, r_trv, r_lon = np.sqrt(g[[1, 2, 0]])
        else:
            r_sag, r_trv, r_lon = np.sqrt(g[[0, 2, 1]])
        com = np.abs(ours.com_ratio).max()
        pairs = {
            "mass": (ours.mass_fraction, float(row["mass_fraction_of_body_mass"])),
            "com": (com, float(row["com_fraction_of_segment_length"])),
            "r_sag": (r_sag, float(row["r_gyr_sagittal_fraction"])),
            "r_trv": (r_trv, float(row["r_gyr_transverse_fraction"])),
            "r_lon": (r_lon, float(row["r_gyr_longitudinal_fraction"])),
        }
        for what, (a, b) in pairs.items():
            if abs(a - b) > 1e-9:
                differences.add((sex, seg, what))
    # biobuddy's hand is WJC-fingertip (same mass, other COM and radii); the paper's is WJC-MET3
    hand = {(s, "hand", w) for s in SEXES for w in ("com", "r_sag", "r_trv", "r_lon")}
    assert differences == hand | {("female", "head", "mass"), ("female", "foot", "r_lon")}


@pytest.mark.parametrize("table", TABLES)
@pytest.mark.parametrize("sex", SEXES)
def test_full_body_masses_sum_to_body_mass(table: str, sex: str) -> None:
    segs = generic_segments(72.5, 1.70, sex=sex, table=table)
    assert total_mass(segs.values()) / 72.5 == pytest.approx(1.0, abs=0.005)
    expected = DUMAS2007_SEGMENTS if table == "dumas2007" else DELEVA1996_SEGMENTS
    assert len(segs) == len(expected) + 6
    assert {"thigh_r", "thigh_l", "shank_r", "foot_l"} <= set(segs)


def test_deleva_whole_trunk_equals_sum_of_parts() -> None:
    for sex in SEXES:
        rows = segment_table("deleva1996", sex=sex)
        parts = sum(rows[k].mass_fraction for k in ("upper_trunk", "middle_trunk", "lower_trunk"))
        assert parts == pytest.approx(rows["trunk"].mass_fraction, abs=1e-9)


def test_dumas_values_and_imaginary_products() -> None:
    body_mass, sex = 75.0, "male"
    length = 0.432  # Dumas 2007 mean male thigh length -> ratio 1 at the reference stature
    segs = generic_segments(body_mass, REFERENCE_STATURE[("dumas2007", sex)], sex=sex)
    th = segs["thigh_r"]
    assert th.length == pytest.approx(length)
    assert th.mass == pytest.approx(0.123 * body_mass)
    assert th.com == pytest.approx(np.array([-0.041, -0.429, 0.033]) * length)
    m_l2 = th.mass * length**2
    assert th.inertia[0, 0] == pytest.approx(0.29**2 * m_l2)
    assert th.inertia[1, 1] == pytest.approx(0.15**2 * m_l2)
    assert th.inertia[2, 2] == pytest.approx(0.30**2 * m_l2)
    assert th.inertia[0, 1] == pytest.approx(+(0.07**2) * m_l2)  # "0.07"
    assert th.inertia[0, 2] == pytest.approx(-(0.02**2) * m_l2)  # "0.02j"
    assert th.inertia[1, 2] == pytest.approx(-(0.07**2) * m_l2)  # "0.07j"
    # left side: mirrored in z
    tl = segs["thigh_l"]
    assert tl.com == pytest.approx(th.com * [1, 1, -1])
    assert tl.inertia[0, 2] == pytest.approx(-th.inertia[0, 2])
    assert tl.inertia[1, 2] == pytest.approx(-th.inertia[1, 2])
    assert tl.inertia[0, 1] == pytest.approx(th.inertia[0, 1])
    assert segs["shank_r"].mass == pytest.approx(0.045 * body_mass)
    assert segs["pelvis"].origin == "L5S1JointCenter"


def test_dumas_alternative_segments_available() -> None:
    segs = generic_segments(60.0, 1.6, sex="female", segments=["pelvis_alt", "foot_alt"])
    assert set(segs) == {"pelvis_alt", "foot_alt_r", "foot_alt_l"}
    assert segs["foot_alt_r"].origin == "Calcaneum"


def test_height_scaling_and_measured_lengths() -> None:
    a = generic_segments(70.0, 1.60, sex="female", table="deleva1996")
    b = generic_segments(70.0, 1.80, sex="female", table="deleva1996")
    assert b["thigh_r"].length / a["thigh_r"].length == pytest.approx(1.8 / 1.6)
    assert b["thigh_r"].inertia == pytest.approx(a["thigh_r"].inertia * (1.8 / 1.6) ** 2)
    c = generic_segments(70.0, 1.60, sex="female", segment_lengths={"thigh": 0.40, "thigh_l": 0.41})
    assert c["thigh_r"].length == 0.40
    assert c["thigh_l"].length == 0.41
    d = generic_segments(
        70.0, sex="male", segment_lengths={"thigh": 0.4, "shank": 0.42}, segments=["thigh", "shank"]
    )
    assert d["shank_l"].length == 0.42


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"body_mass": -1.0, "height": 1.7, "sex": "male"}, "body_mass"),
        ({"body_mass": 70.0, "height": float("nan"), "sex": "male"}, "height"),
        ({"body_mass": 70.0, "height": 1.7, "sex": "x"}, "sex 'x'"),
        ({"body_mass": 70.0, "height": 1.7, "sex": "male", "table": "winter"}, "winter"),
        ({"body_mass": 70.0, "height": 1.7, "sex": "male", "segments": ["tail"]}, "tail"),
        ({"body_mass": 70.0, "height": None, "sex": "male"}, "no length"),
        (
            {"body_mass": 70.0, "height": 1.7, "sex": "male", "segment_lengths": {"femur": 0.4}},
            "femur",
        ),
        (
            {"body_mass": 70.0, "height": 1.7, "sex": "male", "segment_lengths": {"thigh": 0}},
            "thigh",
        ),
    ],
)
def test_bad_input_raises_typed_errors(kwargs: dict, match: str) -> None:
    with pytest.raises(AnthropometryError, match=match):
        generic_segments(**kwargs)


def test_segment_inertia_validation() -> None:
    with pytest.raises(InertiaError, match="thigh"):
        SegmentInertia("thigh", 1.0, np.zeros(2), np.eye(3), 0.4)
    with pytest.raises(InertiaError, match="symmetric"):
        SegmentInertia("thigh", 1.0, np.zeros(3), np.triu(np.ones((3, 3))), 0.4)
    seg = SegmentInertia("thigh", 1.0, np.zeros(3), np.eye(3), 0.4)
    with pytest.raises(ValueError):  # arrays are read-only
        seg.com[0] = 1.0
    assert issubclass(InertiaError, MskError)


# ---------------------------------------------------------------------------------------------
# frames, parallel axis, Pinocchio


def _cloud_strategy():  # type: ignore[no-untyped-def]
    n = st.integers(min_value=4, max_value=8)
    return n.flatmap(
        lambda k: st.tuples(
            arrays(np.float64, (k,), elements=st.floats(0.1, 5.0)),
            arrays(np.float64, (k, 3), elements=st.floats(-0.5, 0.5)),
        )
    )


def _cloud_segment(masses: np.ndarray, pts: np.ndarray) -> SegmentInertia:
    m = masses.sum()
    c = masses @ pts / m
    d = pts - c
    ic = sum(mi * (di @ di * np.eye(3) - np.outer(di, di)) for mi, di in zip(masses, d))
    return SegmentInertia("cloud", m, c, ic, 1.0)


def _cloud_inertia_about(masses: np.ndarray, pts: np.ndarray, p: np.ndarray) -> np.ndarray:
    d = pts - p
    return sum(mi * (di @ di * np.eye(3) - np.outer(di, di)) for mi, di in zip(masses, d))


_vec3 = arrays(np.float64, (3,), elements=st.floats(-1.0, 1.0))
_quat = arrays(np.float64, (4,), elements=st.floats(-1.0, 1.0)).filter(
    lambda q: np.linalg.norm(q) > 0.1
)


def _rot(q: np.ndarray) -> np.ndarray:
    q = q / np.linalg.norm(q)
    return pin.Quaternion(q[0], q[1], q[2], q[3]).toRotationMatrix()


@settings(max_examples=50, deadline=None)
@given(_cloud_strategy(), _vec3)
def test_parallel_axis_against_point_masses(cloud, p) -> None:  # type: ignore[no-untyped-def]
    masses, pts = cloud
    seg = _cloud_segment(masses, pts)
    assert inertia_about(seg, p) == pytest.approx(_cloud_inertia_about(masses, pts, p), abs=1e-9)


@settings(max_examples=50, deadline=None)
@given(_cloud_strategy(), _quat, _vec3)
def test_transform_segment_against_point_masses(cloud, q, t) -> None:  # type: ignore[no-untyped-def]
    masses, pts = cloud
    r = _rot(q)
    seg = transform_segment(_cloud_segment(masses, pts), rotation=r, translation=t)
    pts_f = (pts - t) @ r  # p_F = R^T (p_S - t)
    ref = _cloud_segment(masses, pts_f)
    assert seg.com == pytest.approx(ref.com, abs=1e-12)
    assert seg.inertia == pytest.approx(ref.inertia, abs=1e-9)
    # inertia about the new origin, via the standard parameter vector
    phi = inertial_parameters(seg)
    i0 = _cloud_inertia_about(masses, pts_f, np.zeros(3))
    assert phi[[4, 5, 6, 7, 8, 9]] == pytest.approx(i0[[0, 0, 1, 0, 1, 2], [0, 1, 1, 2, 2, 2]])


@settings(max_examples=50, deadline=None)
@given(_cloud_strategy(), _quat, _vec3)
def test_transform_matches_pinocchio_se3_action(cloud, q, t) -> None:  # type: ignore[no-untyped-def]
    masses, pts = cloud
    seg = _cloud_segment(masses, pts)
    # a cloud on a line or a point has a singular inertia, which pinocchio refuses to build
    assume(np.linalg.eigvalsh(np.asarray(seg.inertia)).min() > 1e-9)
    r = _rot(q)
    moved = transform_segment(seg, rotation=r, translation=t)
    ref = pin.SE3(r, np.asarray(t)).actInv(to_pinocchio_inertia(seg))
    assert to_pinocchio_inertia(moved).toDynamicParameters() == pytest.approx(
        ref.toDynamicParameters(), abs=1e-9
    )


def test_inertial_parameter_order_round_trip_with_pinocchio() -> None:
    assert INERTIAL_PARAMETER_NAMES == (
        "m",
        "mx",
        "my",
        "mz",
        "Ixx",
        "Ixy",
        "Iyy",
        "Ixz",
        "Iyz",
        "Izz",
    )
    for seg in generic_segments(70.0, 1.75, sex="male").values():
        phi = inertial_parameters(seg)
        pin_phi = to_pinocchio_inertia(seg).toDynamicParameters()
        assert phi == pytest.approx(pin_phi, rel=1e-12, abs=1e-15)
        back = segment_from_parameters(pin_phi, name=seg.name, length=seg.length)
        assert back.com == pytest.approx(seg.com, abs=1e-12)
        assert back.inertia == pytest.approx(seg.inertia, abs=1e-12)
        pin_back = pin.Inertia.FromDynamicParameters(phi)
        assert pin_back.mass == pytest.approx(seg.mass)
        assert pin_back.lever == pytest.approx(seg.com)
        assert pin_back.inertia == pytest.approx(seg.inertia, abs=1e-12)
    # each name picks the documented entry
    seg = SegmentInertia("x", 2.0, np.array([0.1, 0.2, 0.3]), np.diag([1.0, 2.0, 3.0]), 1.0)
    phi = dict(zip(INERTIAL_PARAMETER_NAMES, inertial_parameters(seg)))
    i0 = inertia_about(seg, np.zeros(3))
    assert phi["my"] == pytest.approx(0.4)
    assert phi["Ixz"] == pytest.approx(i0[0, 2])
    assert phi["Iyy"] == pytest.approx(i0[1, 1])


def test_mirror_is_an_involution_and_keeps_mass() -> None:
    seg = generic_segments(70.0, 1.75, sex="female")["foot_r"]
    assert mirror_segment(mirror_segment(seg)).inertia == pytest.approx(seg.inertia)
    assert np.linalg.eigvalsh(mirror_segment(seg).inertia) == pytest.approx(
        np.linalg.eigvalsh(seg.inertia)
    )


def test_transform_rejects_reflection() -> None:
    seg = generic_segments(70.0, 1.75, sex="male")["thigh_r"]
    with pytest.raises(InertiaError, match="thigh_r"):
        transform_segment(seg, rotation=np.diag([1.0, 1.0, -1.0]))


def test_opensim_placement_identity_rotation() -> None:
    """An ISB thigh placed on an OpenSim femur (origin at the hip centre) keeps its numbers."""
    seg = generic_segments(75.0, 1.77, sex="male")["thigh_r"]
    placed = transform_segment(seg, rotation=np.eye(3), translation=np.zeros(3), name="femur_r")
    assert placed.com == pytest.approx(seg.com)
    assert placed.com[1] < 0  # COM below the hip: y points proximally


# ---------------------------------------------------------------------------------------------
# physical consistency


# The published Dumas 2007 female thorax tensor (and the female alternative thorax and hand)
# violate the triangle inequality on principal moments (e.g. thorax: 0.0295 + 0.0843 < 0.1272
# in units of m L^2), whichever sign convention is used for the products: a property of the
# table, not of msk. Everything else is strictly consistent.
KNOWN_INCONSISTENT = {
    ("dumas2007", "female", "thorax"),
    ("dumas2007", "female", "thorax_alt"),
    ("dumas2007", "female", "hand_alt"),
}


@pytest.mark.parametrize("table", TABLES)
@pytest.mark.parametrize("sex", SEXES)
def test_real_segments_are_physically_consistent(table: str, sex: str) -> None:
    names = list(segment_table(table, sex=sex))
    segs = generic_segments(70.0, 1.75, sex=sex, table=table, segments=names)
    for seg in segs.values():
        phi = inertial_parameters(seg)
        j = pseudo_inertia(phi)
        assert j == pytest.approx(j.T)
        base = seg.name.removesuffix("_r").removesuffix("_l")
        expected = (table, sex, base) not in KNOWN_INCONSISTENT
        assert is_physically_consistent(phi) == expected, seg.name
        principal = np.sort(np.linalg.eigvalsh(seg.inertia))
        assert (principal[0] + principal[1] > principal[2]) == expected, seg.name


def test_pseudo_inertia_is_second_moment_of_mass() -> None:
    rng = np.random.default_rng(0)
    masses, pts = rng.uniform(0.1, 2.0, 6), rng.normal(size=(6, 3))
    seg = _cloud_segment(masses, pts)
    x1 = np.hstack([pts, np.ones((6, 1))])
    expected = (masses[:, None, None] * np.einsum("ni,nj->nij", x1, x1)).sum(axis=0)
    assert pseudo_inertia(inertial_parameters(seg)) == pytest.approx(expected, abs=1e-12)


def test_triangle_inequality_violation_is_inconsistent() -> None:
    # principal moments 1, 1, 3: I_zz > I_xx + I_yy is impossible for a real body
    bad = SegmentInertia("bad", 1.0, np.array([0.1, 0.0, 0.0]), np.diag([1.0, 1.0, 3.0]), 1.0)
    phi = inertial_parameters(bad)
    assert not is_physically_consistent(phi)
    assert np.linalg.eigvalsh(pseudo_inertia(phi))[0] < 0
    # a flat plate sits on the boundary: consistent only in the non-strict sense
    plate = SegmentInertia("plate", 1.0, np.zeros(3), np.diag([1.0, 2.0, 3.0]), 1.0)
    assert not is_physically_consistent(inertial_parameters(plate))
    assert np.linalg.eigvalsh(pseudo_inertia(inertial_parameters(plate)))[0] == pytest.approx(0)
    # negative mass
    phi2 = inertial_parameters(generic_segments(70.0, 1.75, sex="male")["shank_r"])
    phi2[0] = -phi2[0]
    assert not is_physically_consistent(phi2)


def test_consistency_margin_and_shape_errors() -> None:
    phi = inertial_parameters(generic_segments(70.0, 1.75, sex="male")["thigh_r"])
    lam = np.linalg.eigvalsh(pseudo_inertia(phi))[0]
    assert is_physically_consistent(phi, tol=0.5 * lam)
    assert not is_physically_consistent(phi, tol=2 * lam)
    with pytest.raises(InertiaError, match="φ"):
        pseudo_inertia(np.zeros(9))
    with pytest.raises(InertiaError, match="mass"):
        segment_from_parameters(np.zeros(10), name="foot_r")


def test_model_anthropometry_maps_the_table_on_the_model_bodies() -> None:
    """``summary.anthropometry``: each model body gets its table segment's mass (femur = thigh,
    tibia = shank, talus/calcaneus/toes = one foot, torso = trunk, head and both arms): on a
    whole gait2392-like body list the masses add up to the table's whole body (Dumas et al.
    2007, the fractions of 70 kg); a body the table has no segment for is left out and an
    unknown sex gives None."""
    from msk.model.anthropometry import generic_segments, model_anthropometry

    legs = [f"{b}_{s}" for s in "rl" for b in ("femur", "tibia", "talus", "calcn", "toes")]
    rec = model_anthropometry(["pelvis", *legs, "torso", "patella_r"], 70.0, None, "male")
    assert rec is not None and rec.table == "Dumas et al. 2007" and rec.sex == "male"
    segs = generic_segments(70.0, 1.75, sex="male")
    assert set(rec.segments) == {"pelvis", "femur_r", "femur_l", "tibia_r", "tibia_l", "foot_r",
                                 "foot_l", "torso"}  # fmt: skip
    got = {k: v.mass_kg for k, v in rec.segments.items()}
    assert got["femur_l"] == pytest.approx(segs["thigh_l"].mass)
    assert got["foot_r"] == pytest.approx(segs["foot_r"].mass)
    assert got["torso"] == pytest.approx(
        sum(
            v.mass
            for k, v in segs.items()
            if k.startswith(("head", "thorax", "upper", "fore", "hand"))
        )
    )
    assert sum(got.values()) == pytest.approx(sum(v.mass for v in segs.values()))
    assert model_anthropometry(["pelvis"], 70.0, None, "unknown") is None
