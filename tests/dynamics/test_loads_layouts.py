"""Plate assignment for real lab layouts, on synthetic feet whose loads are known.

A model of two feet moved in code (each foot a body with three translations from a still
pelvis; markers at the heel, toe and 5th metatarsal head; sole 6 cm under the foot origin) walks
over plates whose wrench is built from the feet's own loads (700 N each in stance, slight shear,
COP under the foot, pure force at that point). Each scene checks the assignment against that
truth: adjacent walkway plates (double support across two plates, toes inside the next plate's
margin), a foot straddling two plates, both feet on one plate (flagged, never split), a raised
step plate, a split-belt treadmill whose belts carry the stance foot backwards at 1.17 m/s
(feet cross belts once: the belt's long contact run is split where the foot changes), with and
without plate outlines.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable

import numpy as np
import pinocchio as pin
import pytest

from msk.datasets.models import free_pelvis, inertia
from msk.dynamics.loads import PlateWrench, contact_measured, external_loads
from msk.kinematics.ik import kinematics_from_coordinates
from msk.model.core import Axis, Body, Coordinate, Joint, Marker, Model
from msk.model.joints import Linear

RATE = 100.0
SOLE = 0.06  # foot origin above the sole
LOAD = 700.0
FEET = ("foot_r", "foot_l")


def feet_model() -> Model:
    """Pelvis (free, kept still at 0.9 m) and two feet translated from it (x, y, z each)."""
    lin = Linear()
    coords, pelvis_joint = free_pelvis(0.9)
    bodies = [Body("pelvis", 10.0, [0.0, 0.0, 0.0], inertia(10.0, 0.25))]
    joints = [pelvis_joint]
    markers = []
    for side, s in (("r", 1.0), ("l", -1.0)):
        foot = f"foot_{side}"
        coords += [Coordinate(f"{foot}_{a}", "translational", (-5, 5)) for a in "xyz"]
        bodies.append(Body(foot, 1.0, [0.05, -0.03, 0.0], inertia(1.0, 0.2)))
        joints.append(
            Joint(
                f"ankle_{side}",
                "pelvis",
                foot,
                parent_offset=pin.SE3.Identity(),
                axes=tuple(
                    Axis("prismatic", np.eye(3)[i], f"{foot}_{a}", lin) for i, a in enumerate("xyz")
                ),
            )
        )
        up = side.upper()
        markers += [
            Marker(f"{up}HEE", foot, [-0.05, -SOLE, 0.0]),
            Marker(f"{up}TOE", foot, [0.17, -SOLE, 0.0]),
            Marker(f"{up}MT5", foot, [0.12, -SOLE + 0.01, s * 0.04]),
        ]
    return Model(name="feet", bodies=bodies, joints=joints, coordinates=coords, markers=markers)


MODEL = feet_model()

Knots = list[tuple[float, float, float, float]]  # time, x, z, sole height


def foot_path(t: np.ndarray, *pieces: Knots) -> np.ndarray:
    """Sole-centre path (N, 3) through the (time, x, z, height) knots of the pieces, piecewise
    linear."""
    k = np.array([kn for piece in pieces for kn in piece], dtype=float)
    return np.column_stack([np.interp(t, k[:, 0], k[:, i]) for i in (1, 3, 2)])


def swing(t0: float, t1: float, x0: float, x1: float, z0: float, z1: float) -> Knots:
    """A swing from (x0, z0) to (x1, z1) lifting the sole 8 cm at mid-swing."""
    tm = (t0 + t1) / 2
    return [(t0, x0, z0, 0.0), (tm, (x0 + x1) / 2, (z0 + z1) / 2, 0.08), (t1, x1, z1, 0.0)]


def kinematics(t: np.ndarray, soles: dict[str, np.ndarray]):
    """Kinematics of the feet model with the feet's soles (heel–toe middle) on the paths."""
    q = np.zeros((t.size, len(MODEL.coordinate_names)))
    q[:, MODEL.coordinate_index("pelvis_ty")] = 0.9
    for foot, path in soles.items():
        origin = path + np.array([-0.06, SOLE, 0.0]) - np.array([0.0, 0.9, 0.0])
        for i, a in enumerate("xyz"):
            q[:, MODEL.coordinate_index(f"{foot}_{a}")] = origin[:, i]
    return kinematics_from_coordinates(t, q, MODEL.coordinate_names, cutoff_hz=None)


def corners(x0: float, x1: float, z0: float, z1: float, h: float = 0.0) -> np.ndarray:
    """A plate outline (4, 3) at height h (C3D order: its z axis points down)."""
    return np.array([[x1, h, z1], [x0, h, z1], [x0, h, z0], [x1, h, z0]])


def plate(
    name: str,
    t: np.ndarray,
    loads: list[tuple[np.ndarray, np.ndarray]],
    outline: np.ndarray | None,
) -> PlateWrench:
    """A plate carrying the given (vertical load (N,), point (N, 3)) pairs: F = Σ F_i with a
    5 % forward shear, COP = load-weighted mean point, free moment = the rest of Σ c_i × F_i."""
    force = np.zeros((t.size, 3))
    m = np.zeros((t.size, 3))
    for fv, c in loads:
        f = np.column_stack([0.05 * fv, fv, np.zeros_like(fv)])
        force += f
        m += np.cross(c, f)
    with np.errstate(invalid="ignore", divide="ignore"):
        cop = sum(fv[:, None] * c for fv, c in loads) / force[:, 1:2]
    cop[force[:, 1] <= 0] = np.nan
    free = m - np.cross(np.nan_to_num(cop), force)
    return PlateWrench(name, t, force, cop, free, outline)


def stance(t: np.ndarray, *spans: tuple[float, float]) -> np.ndarray:
    """LOAD inside the [t0, t1] spans, 0 elsewhere."""
    out = np.zeros(t.size)
    for a, b in spans:
        out[(t >= a - 1e-9) & (t <= b + 1e-9)] = LOAD
    return out


def on_body(loads, body: str) -> np.ndarray:
    return loads.force[:, loads.body_index(body)] if body in loads.bodies else 0 * loads.time


def spans(loads) -> list[tuple[str, str, float, float]]:
    return [
        (a.plate, a.body, round(a.start_time, 2), round(a.end_time, 2)) for a in loads.assignments
    ]


def outline(on: bool, *args: float) -> np.ndarray | None:
    """:func:`corners` when ``on``, else None (a plate known by its COP only)."""
    return corners(*args) if on else None


def _both_ways(build: Callable[[bool], None]) -> None:
    """Run a scene with plate outlines and without (COP-only rule); same assignment."""
    for with_outline in (True, False):
        build(with_outline)


# ---------------------------------------------------------------------------------------------
def test_adjacent_walkway_plates_double_support_and_toes_over_the_next_plate():
    """Right foot on plate 1 (toes 2 cm inside plate 2) 0–0.6 s, left foot swings over plate 1
    and lands on plate 2 at 0.5 s: both plates loaded at once, each by its own foot."""
    t = np.arange(0, 1.2, 1 / RATE)
    r = foot_path(t, [(0.0, 0.51, 0.09, 0.0)], swing(0.6, 1.1, 0.51, 1.7, 0.09, 0.09))
    l_ = foot_path(t, swing(0.0, 0.5, -0.5, 0.85, -0.09, -0.09), [(1.2, 0.85, -0.09, 0.0)])
    kin = kinematics(t, {"foot_r": r, "foot_l": l_})
    w_r, w_l = stance(t, (0.0, 0.6)), stance(t, (0.5, 1.2))

    def run(on: bool) -> None:
        p1 = plate("plate1", t, [(w_r, r)], outline(on, 0.0, 0.6, -0.3, 0.3))
        p2 = plate("plate2", t, [(w_l, l_)], outline(on, 0.6, 1.2, -0.3, 0.3))
        loads = external_loads(MODEL, kin, [p1, p2])
        assert spans(loads) == [("plate1", "foot_r", 0.0, 0.6), ("plate2", "foot_l", 0.5, 1.19)]
        assert loads.flags == ()
        np.testing.assert_allclose(on_body(loads, "foot_r")[:, 1], w_r)
        np.testing.assert_allclose(on_body(loads, "foot_l")[:, 1], w_l)
        np.testing.assert_allclose(loads.point[w_r > 0, loads.body_index("foot_r")], r[w_r > 0])

    _both_ways(run)


def test_foot_standing_beside_a_plate_does_not_share_its_load():
    """A large plate (1.2 m): the left foot stands alone on the floor with its toes 2 cm over
    the plate's edge (the plate records nothing) while the right foot swings, then the right
    heel strikes the plate's middle (0.5 s) and the left foot leaves (0.6 s). The plate's load
    is the right foot's from the first frame, no shared contact is flagged (UWA's fast walk).
    When the left toes do load the plate, the double support is shared and flagged."""
    t = np.arange(0, 1.2, 1 / RATE)
    # left sole centre 0.13 m behind the edge: toes (+0.11 from the sole centre) 2 cm over it
    l_ = foot_path(t, [(0.0, -0.13, -0.09, 0.0), (0.6, -0.13, -0.09, 0.0)],
                   swing(0.6, 1.2, -0.13, 1.2, -0.09, -0.09))  # fmt: skip
    r = foot_path(t, swing(0.0, 0.5, -0.9, 0.5, 0.09, 0.09), [(1.2, 0.5, 0.09, 0.0)])
    kin = kinematics(t, {"foot_r": r, "foot_l": l_})
    w_r = stance(t, (0.5, 1.2))
    p1 = plate("plate1", t, [(w_r, r)], corners(0.0, 1.2, -0.6, 0.6))
    loads = external_loads(MODEL, kin, [p1])
    assert loads.flags == ()
    assert spans(loads) == [("plate1", "foot_r", 0.5, 1.19)]
    np.testing.assert_allclose(on_body(loads, "foot_r")[:, 1], w_r)
    # the same left foot when its toes do load the plate (a tenth of its load): the double
    # support 0.5–0.6 s is shared, flagged, never split
    toes = l_ + np.array([0.1, 0.0, 0.0])
    both = plate("plate1", t, [(0.1 * stance(t, (0.0, 0.6)), toes), (w_r, r)],
                 corners(0.0, 1.2, -0.6, 0.6))  # fmt: skip
    flagged = external_loads(MODEL, kin, [both])
    assert [(f.reason, round(f.start_time, 2)) for f in flagged.flags] == [("shared", 0.5)]


def test_one_foot_straddling_two_plates_loads_both():
    """The right foot stands across the joint of plates 1 and 2 (heel on 1, toes on 2; 60/40)
    while the left swings past: both plates go to the right foot, their sum on it."""
    t = np.arange(0, 0.8, 1 / RATE)
    r = foot_path(t, [(0.0, 0.6, 0.09, 0.0), (0.8, 0.6, 0.09, 0.0)])
    l_ = foot_path(t, [(0.0, -0.3, -0.09, 0.0)], swing(0.1, 0.7, -0.3, 1.5, -0.09, -0.09))
    kin = kinematics(t, {"foot_r": r, "foot_l": l_})
    w = stance(t, (0.0, 0.8))
    heel, toe = r + np.array([-0.08, 0, 0]), r + np.array([0.1, 0, 0])
    p1 = plate("plate1", t, [(0.6 * w, heel)], corners(0.0, 0.6, -0.3, 0.3))
    p2 = plate("plate2", t, [(0.4 * w, toe)], corners(0.6, 1.2, -0.3, 0.3))
    loads = external_loads(MODEL, kin, [p1, p2])
    assert [(a.plate, a.body) for a in loads.assignments] == [
        ("plate1", "foot_r"),
        ("plate2", "foot_r"),
    ]
    np.testing.assert_allclose(on_body(loads, "foot_r")[:, 1], w)
    np.testing.assert_allclose(loads.point[:, 0], 0.6 * heel + 0.4 * toe, atol=1e-12)


def test_both_feet_on_one_plate_are_flagged_not_split():
    """A long plate: the right foot stands on it throughout, the left swings over it, stands on
    it 0.4–0.8 s and swings off. Those frames are flagged shared (load on no foot, not
    measured); the rest goes to the right foot."""
    t = np.arange(0, 1.2, 1 / RATE)
    r = foot_path(t, [(0.0, 0.3, 0.09, 0.0), (1.2, 0.3, 0.09, 0.0)])
    l_ = foot_path(
        t, swing(0.0, 0.4, -0.4, 0.8, -0.09, -0.09), swing(0.8, 1.2, 0.8, 2.0, -0.09, -0.09)
    )
    kin = kinematics(t, {"foot_r": r, "foot_l": l_})
    w_r, w_l = stance(t, (0.0, 1.2)), stance(t, (0.4, 0.8))
    both = (t >= 0.4 - 1e-9) & (t <= 0.8 + 1e-9)

    def run(on: bool) -> None:
        pl = plate("plate1", t, [(w_r, r), (w_l, l_)], outline(on, -0.2, 1.4, -0.4, 0.4))
        loads = external_loads(MODEL, kin, [pl])
        assert spans(loads) == [("plate1", "foot_r", 0.0, 0.39), ("plate1", "foot_r", 0.81, 1.19)]
        assert [(f.plate, f.reason, f.start_time, f.end_time, f.feet) for f in loads.flags] == [
            ("plate1", "shared", 0.4, 0.8, ("foot_r", "foot_l"))
        ]
        np.testing.assert_array_equal(loads.shared_contact, both)
        assert np.all(on_body(loads, "foot_r")[both] == 0.0)  # not guessed, not split
        assert "foot_l" not in loads.bodies
        np.testing.assert_allclose(on_body(loads, "foot_r")[~both, 1], LOAD)
        measured = contact_measured(MODEL, kin, loads)
        assert not measured[both].any() and measured[~both].all()

    _both_ways(run)


def test_raised_step_plate_uses_its_own_surface_height():
    """Plate 1 on the floor, plate 2 on a 20 cm step: the left foot stands on the step plate.
    The step's surface comes from its corners (or its COPs); a still foot on the step while the
    step plate is unloaded (0.9–1.0 s) is an unmeasured contact."""
    t = np.arange(0, 1.2, 1 / RATE)
    h = 0.20
    r = foot_path(t, [(0.0, 0.3, 0.09, 0.0)], swing(0.6, 1.3, 0.3, 1.6, 0.09, 0.09))
    r[:, 1] += (h + 0.04) * np.clip((t - 0.6) / 0.3, 0, 1)  # swings up past the step
    l_ = foot_path(t, swing(0.0, 0.5, -0.3, 0.9, -0.09, -0.09), [(1.2, 0.9, -0.09, 0.0)])
    l_[:, 1] += h * np.clip((t - 0.2) / 0.3, 0, 1)  # climbs onto the step
    kin = kinematics(t, {"foot_r": r, "foot_l": l_})
    w_r, w_l = stance(t, (0.0, 0.6)), stance(t, (0.5, 0.9), (1.0, 1.2))

    def run(on: bool) -> None:
        p1 = plate("plate1", t, [(w_r, r)], outline(on, 0.0, 0.6, -0.3, 0.3))
        p2 = plate("plate2", t, [(w_l, l_)], outline(on, 0.6, 1.2, -0.3, 0.3, h))
        loads = external_loads(MODEL, kin, [p1, p2])
        assert [(a.plate, a.body) for a in loads.assignments] == [
            ("plate1", "foot_r"),
            ("plate2", "foot_l"),
            ("plate2", "foot_l"),
        ]
        assert loads.metadata["surface_heights_m"]["plate2"] == np.float64(h)
        np.testing.assert_allclose(on_body(loads, "foot_l")[:, 1], w_l)
        measured = contact_measured(MODEL, kin, loads)
        gap = (t > 0.9 + 1e-9) & (t < 1.0 - 1e-9)
        assert not measured[gap].any() and measured[(t > 0.52) & (t < 0.88)].all()

    _both_ways(run)
    # the plate's corners at the floor (a step built on the plate, stored as labs store it):
    # held at the corners' height, a foot 20 cm above the plate does not stand on it; the
    # surface inferred from that foot (msk.dynamics.plate_surface) is the step's and the foot
    # gets its load
    p_low = plate("plate2", t, [(w_l, l_)], corners(0.6, 1.2, -0.3, 0.3, 0.0))
    low = external_loads(MODEL, kin, [p_low], infer_surface=False)
    assert all(a.body != "foot_l" for a in low.assignments)
    assert low.unassigned_contact[(w_l > 0) & (t > 0.75)].all()
    found = external_loads(MODEL, kin, [p_low])
    (sf,) = found.metadata["surfaces"]
    assert sf["source"] == "feet" and sf["height_m"] == pytest.approx(h, abs=0.01)
    assert [a.body for a in found.assignments] == ["foot_l", "foot_l"]
    np.testing.assert_allclose(on_body(found, "foot_l")[:, 1], w_l)


def test_split_belt_treadmill_feet_on_own_belts_then_crossing():
    """Two 2-m belts side by side (right z > 0); belts carry the stance foot backwards at
    1.17 m/s, feet 4 cm from the belt joint (their points reach inside the other belt's
    margin). Steps: right 0–0.6, left 0.5–1.1, right 1.0–1.6, then the left foot lands on the
    RIGHT belt at 1.5 s (crossing) and stays to the end. The right belt's contact run from 1.0 s
    to the end is split: right foot, shared 1.5–1.6 s (flagged), left foot."""
    t = np.arange(0, 2.0, 1 / RATE)
    zr, zl, zx = 0.04, -0.04, 0.16

    def stance_knots(t0: float, t1: float, z: float) -> Knots:
        return [(t0, 0.35, z, 0.0), (t1, -0.35, z, 0.0)]

    r = foot_path(
        t,
        stance_knots(0.0, 0.6, zr),
        swing(0.6, 1.0, -0.35, 0.35, zr, zr),
        stance_knots(1.0, 1.6, zr),
        swing(1.6, 2.0, -0.35, 0.35, zr, zr),
    )
    l_ = foot_path(
        t,
        [(0.0, -0.1, zl, 0.03)],
        swing(0.1, 0.5, -0.1, 0.35, zl, zl)[1:],
        stance_knots(0.5, 1.1, zl),
        [(1.1, -0.35, zl, 0.0), (1.3, 0.0, zl, 0.08), (1.4, 0.2, zl, 0.05)],  # past the right
        stance_knots(1.5, 2.1, zx),  # then across, in front of it
    )
    kin = kinematics(t, {"foot_r": r, "foot_l": l_})
    w_r = stance(t, (0.0, 0.6), (1.0, 1.6))
    w_l_own, w_l_cross = stance(t, (0.5, 1.1)), stance(t, (1.5, 2.1))
    # the landing frame (1.50 s: the left foot still moves at 1.2 m/s) counts as swing
    shared = (t >= 1.51 - 1e-9) & (t <= 1.6 + 1e-9)

    def run(on: bool) -> None:
        right = plate("belt_r", t, [(w_r, r), (w_l_cross, l_)], outline(on, -1, 1, 0.0, 0.25))
        left = plate("belt_l", t, [(w_l_own, l_)], outline(on, -1, 1, -0.25, 0.0))
        loads = external_loads(MODEL, kin, [right, left])
        assert spans(loads) == [
            ("belt_r", "foot_r", 0.0, 0.6),
            ("belt_r", "foot_r", 1.0, 1.5),
            ("belt_r", "foot_l", 1.61, 1.99),
            ("belt_l", "foot_l", 0.5, 1.1),
        ]
        assert [(f.plate, f.reason, f.start_time, f.end_time) for f in loads.flags] == [
            ("belt_r", "shared", 1.51, 1.6)
        ]
        np.testing.assert_array_equal(loads.shared_contact, shared)
        f_r, f_l = on_body(loads, "foot_r")[:, 1], on_body(loads, "foot_l")[:, 1]
        ok = ~shared & (np.abs(t - 1.5) > 1e-9)
        np.testing.assert_allclose(f_r[ok], w_r[ok])
        np.testing.assert_allclose(f_l[ok], (w_l_own + w_l_cross)[ok])
        assert not contact_measured(MODEL, kin, loads)[shared].any()

    _both_ways(run)


@pytest.mark.parametrize(
    ("lift", "flagged"), [(0.3, []), (0.1, [("plate1", "unassigned", 0.27, 0.6)])]
)
def test_a_swinging_foot_does_not_take_the_load_of_a_stance_foot_posed_too_high(lift, flagged):
    """A long plate (a single-belt treadmill, or both feet within the COP radius): the right
    foot stands on it 0–0.6 s with the COP under it, but its pose (the kinematics of a leg
    scaled too long) rises 12 cm off the surface over 0.2 s from ``lift`` s on, past the 10 cm
    floor test; the left foot swings low (sole ≤ 8 cm) over the plate at 2.4 m/s beside it and
    lands beyond it. The load is never given to the swinging left foot (as on the Grand
    Challenge DM crouch treadmill's files, issue 15: 27 frames of a belt's load on the left
    foot): a short lift takes the right foot's label from the frames before it, a long one is
    flagged unassigned."""
    t = np.arange(0, 0.7, 1 / RATE)
    r_true = foot_path(t, [(0.0, 0.3, 0.09, 0.0), (0.7, 0.3, 0.09, 0.0)])
    r_posed = r_true + np.outer(np.clip((t - lift) / 0.2, 0.0, 1.0), [0.0, 0.12, 0.0])
    l_ = foot_path(t, [(0.0, -0.3, -0.09, 0.0)], swing(0.1, 0.6, -0.3, 0.9, -0.09, -0.09))
    kin = kinematics(t, {"foot_r": r_posed, "foot_l": l_})
    w_r = stance(t, (0.0, 0.6))

    def run(on: bool) -> None:
        pl = plate("plate1", t, [(w_r, r_true)], outline(on, 0.0, 0.7, -0.3, 0.3))
        loads = external_loads(MODEL, kin, [pl])
        assert "foot_l" not in loads.bodies
        got = [(f.plate, f.reason, round(f.start_time, 2), round(f.end_time, 2))
               for f in loads.flags]  # fmt: skip
        assert got == flagged
        off = loads.unassigned_contact
        np.testing.assert_allclose(on_body(loads, "foot_r")[~off, 1], w_r[~off])
        assert spans(loads)[0][:3] == ("plate1", "foot_r", 0.0)

    _both_ways(run)


def test_explicit_assignment_overrides_one_plate_and_explains_its_foot():
    """assignment= names one plate's body for all its frames (even a wrong-looking one); the
    other plate is still assigned automatically."""
    t = np.arange(0, 1.2, 1 / RATE)
    r = foot_path(t, [(0.0, 0.51, 0.09, 0.0)], swing(0.6, 1.1, 0.51, 1.7, 0.09, 0.09))
    l_ = foot_path(t, swing(0.0, 0.5, -0.5, 0.85, -0.09, -0.09), [(1.2, 0.85, -0.09, 0.0)])
    kin = kinematics(t, {"foot_r": r, "foot_l": l_})
    p1 = plate("plate1", t, [(stance(t, (0.0, 0.6)), r)], corners(0.0, 0.6, -0.3, 0.3))
    p2 = plate("plate2", t, [(stance(t, (0.5, 1.2)), l_)], corners(0.6, 1.2, -0.3, 0.3))
    loads = external_loads(MODEL, kin, [p1, p2], assignment={"plate1": "pelvis"})
    assert [(a.plate, a.body) for a in loads.assignments] == [
        ("plate1", "pelvis"),
        ("plate2", "foot_l"),
    ]


# ---------------------------------------------------------------------------------------------
# real: Grand Challenge DM on the instrumented split-belt treadmill (GRF file, no xml, no outline)
# ---------------------------------------------------------------------------------------------
DM_FOOT = ("Heel", "Toe", "Midfoot_Medial", "Midfoot_Lateral", "Hindfoot", "Midfoot_Superior",
           "ToeMedial", "ToeLateral")  # fmt: skip


def marker_feet_model() -> Model:
    """Each foot a chain of bodies placed exactly on its markers (heel = ``calcn_*``, the other
    foot markers its children, all by translations): the foot points are the markers."""
    lin = Linear()
    coords, pelvis_joint = free_pelvis(0.0)
    bodies = [Body("pelvis", 1.0, [0.0, 0.0, 0.0], inertia(1.0, 0.2))]
    joints = [pelvis_joint]
    for side in "rl":
        for k, m in enumerate(DM_FOOT):
            name = f"calcn_{side}" if k == 0 else f"{side}_{m}"
            coords += [Coordinate(f"{name}_{a}", "translational", (-50, 50)) for a in "xyz"]
            bodies.append(Body(name, 0.1, [0.0, 0.0, 0.0], inertia(0.1, 0.05)))
            axes = tuple(
                Axis("prismatic", np.eye(3)[i], f"{name}_{a}", lin) for i, a in enumerate("xyz")
            )
            parent = "pelvis" if k == 0 else f"calcn_{side}"
            joints.append(Joint(f"j_{name}", parent, name, pin.SE3.Identity(), axes=axes))
    return Model(name="marker_feet", bodies=bodies, joints=joints, coordinates=coords, markers=[])


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.parametrize(
    ("trial", "steps"), [("DM_ngait_tm_ss1", (15, 14)), ("DM_crouch_tm1", (13, 12))]
)
def test_dm_split_belt_treadmill_by_foot_proximity(real_dir, trial, steps):
    """DM treadmill walks (17 s normal, 14 s crouch): two belts known only by their GRF columns.
    Every step goes to one foot by proximity (left belt → left foot, right belt → right foot,
    alternating; the first and last steps cut by the trial's ends), the COP lies under the
    assigned foot's markers, at most a frame is shared, and (speeds relative to the belts)
    nearly every frame is measured."""
    from msk.dynamics.loads import plates_from_grf_file
    from msk.io import read_trc

    base = real_dir / "knee-grand-challenge-gc6-DM"
    model = marker_feet_model()
    tr = read_trc(base / f"{trial}_new.trc")
    col = {lab: i for i, lab in enumerate(tr.labels)}
    q = np.zeros((tr.time.size, len(model.coordinate_names)))
    for side, s in (("r", "R"), ("l", "L")):
        heel = tr.markers[:, col[f"{s}_Heel"]]
        for k, m in enumerate(DM_FOOT):
            name = f"calcn_{side}" if k == 0 else f"{side}_{m}"
            x = tr.markers[:, col[f"{s}_{m}"]] - (0.0 if k == 0 else heel)
            for i, a in enumerate("xyz"):
                q[:, model.coordinate_index(f"{name}_{a}")] = x[:, i]
    kin = kinematics_from_coordinates(tr.time, q, model.coordinate_names, cutoff_hz=None)
    plates = plates_from_grf_file(base / f"{trial}_grf_filt.sto")
    feet = ("calcn_r", "calcn_l")
    loads = external_loads(model, kin, plates, feet=feet)
    got = loads.assignments
    assert sum(a.plate == "plate1" and a.body == "calcn_l" for a in got) == steps[0]
    assert sum(a.plate == "plate2" and a.body == "calcn_r" for a in got) == steps[1]
    assert len(got) == sum(steps)
    inner = [a for a in got if a.start_time > kin.time[0] + 0.1 and a.end_time < kin.time[-1] - 0.1]
    short = [a for a in inner if a.end_time - a.start_time < 0.6]
    assert not short  # whole stances, not pieces
    order = [a.body for a in sorted(got, key=lambda a: a.start_time)]
    assert all(a != b for a, b in itertools.pairwise(order))  # feet alternate
    # flagged: a shared frame at most, and blips of 20–40 N (the filtered belts' noise, whose COP
    # is meaningless) left unassigned
    assert loads.shared_contact.sum() <= 1 and loads.unassigned_contact.sum() <= 6
    for b in loads.bodies:
        j = loads.body_index(b)
        ok = np.isfinite(loads.point[:, j, 0])
        pts = [tr.markers[:, col[f"{b[-1].upper()}_{m}"]] for m in DM_FOOT]
        d = np.min([np.linalg.norm((p - loads.point[:, j])[:, [0, 2]], axis=1) for p in pts], 0)
        assert np.percentile(d[ok], 95) < 0.09, (b, np.percentile(d[ok], 95))
    # the load on no foot: a few frames; measured: nearly all (a treadmill measures every step)
    fv_all = sum(np.interp(kin.time, p.time, p.force[:, 1]) for p in plates)
    assert loads.total()[0][:, 1].sum() > 0.99 * fv_all.sum()
    assert contact_measured(model, kin, loads, feet=feet).mean() > 0.98
