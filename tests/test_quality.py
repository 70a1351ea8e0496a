"""msk.quality: the body-mass balance and the gates (values against thresholds)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from msk.datasets.models import two_leg_model
from msk.quality import (
    SWAP_MIN_SEPARATION_M,
    THRESHOLDS,
    body_mass_from_loads,
    gait_flags,
    swapped_label_pairs,
    swapped_sides,
)


def _still(model, n, ty=0.93):
    q = np.zeros((n, len(model.coordinate_names)))
    q[:, model.coordinate_names.index("pelvis_ty")] = ty
    return SimpleNamespace(time=np.arange(n) / 100.0, q=q, v=np.zeros_like(q), a=np.zeros_like(q))


@pytest.mark.parametrize("mass", [55.0, 82.8])
def test_body_mass_balances_the_vertical_reaction(mass):
    model = two_leg_model()
    kin = _still(model, 50)
    g = float(np.linalg.norm(model.gravity))
    force = np.zeros((50, 2, 3))
    force[:, 0, 1] = 0.4 * mass * g
    force[:, 1, 1] = 0.6 * mass * g
    loads = SimpleNamespace(bodies=("foot_r", "foot_l"), force=force)
    assert body_mass_from_loads(model, kin, loads, np.ones(50, bool)) == pytest.approx(mass)
    assert body_mass_from_loads(model, kin, loads, np.zeros(50, bool)) is None


def _flags(model, kin, **quality):
    jt = SimpleNamespace(coordinate_names=kin_names(model), tau=np.zeros_like(kin.q))
    plate = quality.pop("plate", None)
    return gait_flags("walk1", quality=quality, model=model, kinematics=kin, joint_torques=jt,
                      mass_kg=70.0, height_m=1.7, plate_mass_kg=plate)  # fmt: skip


def kin_names(model):
    return tuple(model.coordinate_names)


def test_flags_name_trial_quantity_value_threshold():
    model = two_leg_model()
    kin = _still(model, 50)
    kin.coordinate_names = kin_names(model)
    kin.q[:, model.coordinate_names.index("knee_angle_r")] = np.linspace(-0.1, -0.5, 50)
    flags = _flags(model, kin, ik_marker_rms_mean_m=0.031, residual_force_rms_pct_bw=2.0,
                   plate=80.0)  # fmt: skip
    by = {f.quantity: f for f in flags}
    assert by["ik_marker_rms_mean_m"].value == pytest.approx(0.031)
    assert by["ik_marker_rms_mean_m"].threshold == THRESHOLDS["ik_marker_rms_mean_m"]
    assert "residual_force_rms_pct_bw" not in by
    assert by["plate_mass_difference_pct"].value == pytest.approx(100 * 10 / 70)
    # every still leg coordinate is frozen; the moving knee is not
    assert "ankle_angle_r_std_deg" in by and "knee_angle_r_std_deg" not in by
    assert all(f.trial == "walk1" for f in flags)


def test_no_flag_within_thresholds():
    model = two_leg_model()
    kin = _still(model, 50)
    kin.coordinate_names = kin_names(model)
    rng = np.random.default_rng(0)
    kin.q[:, 6:] += 0.05 * rng.standard_normal((50, kin.q.shape[1] - 6))
    flags = _flags(model, kin, ik_marker_rms_mean_m=0.012, residual_force_rms_pct_bw=3.0,
                   residual_moment_rms_nm=2.0, plate=71.0)  # fmt: skip
    assert flags == []


def _rigid_motion(local: np.ndarray, n: int, shift: float) -> np.ndarray:
    """(n, M, 3) markers of one rigid segment moving (rotation about z, translation)."""
    ang = np.linspace(0.0, 1.2, n)
    c, s = np.cos(ang), np.sin(ang)
    rot = np.stack([[c, -s, 0 * c], [s, c, 0 * c], [0 * c, 0 * c, 1 + 0 * c]]).transpose(2, 0, 1)
    tr = np.stack([np.linspace(0, 1.5, n) + shift, np.zeros(n), np.full(n, 0.5)], axis=1)
    return np.einsum("fij,mj->fmi", rot, local) + tr[:, None, :]


def test_inconsistent_static_markers_names_a_swapped_or_ghost_static_label():
    """Two rigid segments of 4 markers each (truth: 2 mm skin noise): the clean static agrees
    with the motion (nothing named); the static with labels A2 and B2 swapped names both, and
    nothing else; a ghost A3 seen in one static frame 7 mm from A1 is named; a skipped label
    is neither checked nor a partner."""
    from msk.quality import inconsistent_static_markers

    rng = np.random.default_rng(3)
    a = np.array([[0, 0, 0], [0.2, 0, 0], [0, 0.15, 0], [0.1, 0.1, 0.08]])
    b = np.array([[0, 0, 0], [0.18, 0, 0], [0, 0.12, 0], [0.09, 0.05, 0.1]])
    labels = ("A0", "A1", "A2", "A3", "B0", "B1", "B2", "B3")
    n = 200
    motion = np.concatenate(
        [_rigid_motion(a, n, 0.0), _rigid_motion(b, n, 0.6)[:, :, [1, 0, 2]]], axis=1
    )
    motion += rng.normal(0.0, 0.002, motion.shape)
    static = motion[:30] + rng.normal(0.0, 0.002, motion[:30].shape)
    assert inconsistent_static_markers(static, labels, motion, labels) == {}
    swapped = static[:, [0, 1, 6, 3, 4, 5, 2, 7]]
    bad = inconsistent_static_markers(swapped, labels, motion, labels)
    assert set(bad) == {"A2", "B2"}
    assert all(d > THRESHOLDS["static_marker_discrepancy_m"] for d in bad.values())
    ghost = static.copy()
    ghost[:, 3] = np.nan
    ghost[0, 3] = ghost[0, 1] + np.array([0.007, 0.0, 0.0])
    assert set(inconsistent_static_markers(ghost, labels, motion, labels)) == {"A3"}
    assert inconsistent_static_markers(ghost, labels, motion, labels, skip=["A3"]) == {}


def _walker(n: int = 120, seed: int = 0) -> tuple[np.ndarray, list[str]]:
    """Markers of a subject walking along +x in a +z-up lab (right = −y), 2 mm noise: pelvis
    (ASIS, PSIS), acromia, knees and heels, with the feet stepping across a narrow base."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 2.0, n)
    x0 = 1.2 * t
    sway = 0.02 * np.sin(np.pi * t)
    pts = {
        "RASI": (0.05, -0.12, 1.0), "LASI": (0.05, 0.12, 1.0),
        "RPSI": (-0.10, -0.05, 1.05), "LPSI": (-0.10, 0.05, 1.05),
        "R.Acromion": (0.0, -0.18, 1.45), "L.Acromion": (0.0, 0.18, 1.45),
        "RKNE": (0.1, -0.10, 0.5), "LKNE": (0.1, 0.10, 0.5),
        "RHEE": (0.0, -0.06, 0.05), "LHEE": (0.0, 0.06, 0.05),
    }  # fmt: skip
    cols = [np.column_stack([x0 + a, b + sway, np.full(n, c)]) for a, b, c in pts.values()]
    x = np.stack(cols, axis=1)
    return x + rng.normal(0.0, 0.002, x.shape), list(pts)


def test_swapped_label_pairs_finds_a_swap_from_the_pelvis_markers_alone():
    x, labels = _walker()
    up = np.array([0.0, 0.0, 1.0])
    assert swapped_label_pairs(x, labels, up) == []
    for r, lft in (("R.Acromion", "L.Acromion"), ("RASI", "LASI"), ("RHEE", "LHEE")):
        y = x.copy()
        i, j = labels.index(r), labels.index(lft)
        y[:, [i, j]] = y[:, [j, i]]
        (found,) = swapped_label_pairs(y, labels, up)
        assert found[:2] == (r, lft) and found[2] < -SWAP_MIN_SEPARATION_M
    # a pair 2 cm apart the wrong way (within the margin) is not called swapped
    y = x.copy()
    y[:, labels.index("RHEE"), 1] = 0.01 + y[:, labels.index("RHEE"), 1] * 0
    y[:, labels.index("LHEE"), 1] = -0.01
    assert swapped_label_pairs(y, labels, up) == []
    # without a posterior pelvis marker the side is not judged
    keep = [k for k, lab in enumerate(labels) if "PSI" not in lab]
    assert swapped_label_pairs(x[:, keep], [labels[k] for k in keep], up) == []


def test_a_knee_held_at_its_model_bound_is_flagged():
    """IK holding the knee at the model's hyperextension bound (gait2392-like +10°, inside the
    physiological range gate's +15°) in 30 % of the frames raises
    ``knee_angle_r_at_bound_frames_pct``; 3 % (under 5 %) does not (DM og4, four-bar knee,
    before the placement fix: the knee at +10° through stance)."""

    model = two_leg_model()
    i = model.coordinate_names.index("knee_angle_r")
    c = model.coordinates[i]
    model = model.with_coordinate_ranges({c.name: (c.range[0], np.radians(10.0))})
    rng = np.random.default_rng(1)
    for share, raised in ((0.30, True), (0.03, False)):
        kin = _still(model, 100)
        kin.coordinate_names = kin_names(model)
        kin.q[:, 6:] += 0.05 * rng.standard_normal((100, kin.q.shape[1] - 6))
        kin.q[:, i] = -0.3 + 0.05 * rng.standard_normal(100)
        kin.q[: int(share * 100), i] = np.radians(10.0)
        kin.q_raw = kin.q.copy()
        by = {f.quantity: f for f in _flags(model, kin)}
        assert ("knee_angle_r_at_bound_frames_pct" in by) is raised
        assert "knee_angle_r_deg" not in by  # +10° is inside the physiological range
        if raised:
            assert by["knee_angle_r_at_bound_frames_pct"].value == pytest.approx(30.0)


def test_com_height_and_the_residual_moment_bound_on_it():
    """The COM height is the model's (median over the frames, above the floor), and the
    residual-moment gate is 1 % of COM height × peak measured force (Hicks et al. 2015)."""
    from msk.quality import com_height

    model = two_leg_model()
    hi, lo = _still(model, 20, ty=0.93), _still(model, 20, ty=0.83)
    every = np.ones(20, dtype=bool)
    h = com_height(model, hi, every)
    assert h == pytest.approx(com_height(model, lo, every) + 0.10)
    assert com_height(model, hi, every, floor_m=0.05) == pytest.approx(h - 0.05)
    assert com_height(model, hi, np.zeros(20, dtype=bool)) is None
    kin = _still(model, 50)
    kin.coordinate_names = kin_names(model)
    jt = SimpleNamespace(coordinate_names=kin_names(model), tau=np.zeros_like(kin.q))
    quality = {"residual_moment_rms_nm": 10.0}

    def moment_flags(**kw):
        return [
            f for f in gait_flags("walk1", quality=quality, model=model, kinematics=kin,
                                  joint_torques=jt, mass_kg=70.0, height_m=1.7, **kw)
            if f.quantity == "residual_moment_rms_pct_com_height_peak_force"
        ]  # fmt: skip

    (f,) = moment_flags(peak_external_force_n=1000.0, com_height_m=0.9)
    assert f.value == pytest.approx(100 * 10.0 / (0.9 * 1000.0))
    assert "0.90 m" in f.message and "1000 N" in f.message
    assert moment_flags(peak_external_force_n=1000.0, com_height_m=1.2) == []
    (f,) = moment_flags(peak_external_force_n=1000.0)  # no COM height: 55 % of stature
    assert f.value == pytest.approx(100 * 10.0 / (0.55 * 1.7 * 1000.0))


def test_too_few_observed_measured_frames_are_flagged_a_few_excluded_are_not():
    model = two_leg_model()
    kin = _still(model, 50)
    kin.coordinate_names = kin_names(model)
    kin.q[:, 6:] += 0.05 * np.random.default_rng(0).standard_normal((50, kin.q.shape[1] - 6))
    few = _flags(model, kin, contact_measured_frames=121, observed_measured_frames=40)
    (f,) = [f for f in few if f.quantity == "observed_measured_frames_min_pct"]
    assert f.value == pytest.approx(100 * 40 / 121)
    assert f.threshold == THRESHOLDS["observed_measured_frames_min_pct"]
    most = _flags(model, kin, contact_measured_frames=121, observed_measured_frames=80)
    assert most == []


def test_no_measured_contact_frame_is_flagged():
    """A trial in which no frame's ground contact is measured (no plate loaded) raises
    ``contact_measured_frames``; one with measured frames, or with no frame at all, does not."""
    model = two_leg_model()
    kin = _still(model, 50)
    kin.coordinate_names = kin_names(model)
    by = {f.quantity: f for f in _flags(model, kin, contact_measured_frames=0, frames=50)}
    assert (
        by["contact_measured_frames"].value == 0.0
        and "of the 50" in by["contact_measured_frames"].message
    )
    for q in ({"contact_measured_frames": 12, "frames": 50}, {"contact_measured_frames": 0}):
        assert "contact_measured_frames" not in {f.quantity for f in _flags(model, kin, **q)}


def test_swapped_sides_needs_the_separation_margin():
    """``swapped_sides`` reports a pair whose right marker is left of the left one by more than
    :data:`SWAP_MIN_SEPARATION_M` (heels exchanged: 12 cm), not one within it (heels 4 mm the
    wrong way, as medial toe markers over a crossing step: UWA fast walking's first 1.55 s)."""
    x, labels = _walker()
    model = SimpleNamespace(body_frame={"pelvis": 0}, marker_names=tuple(labels),
                            gravity=np.array([0.0, 0.0, -9.81]))  # fmt: skip
    kin = SimpleNamespace(q=np.zeros((x.shape[0], 3)))
    assert swapped_sides(model, kin, x, labels) == []
    i, j = labels.index("RHEE"), labels.index("LHEE")
    y = x.copy()
    y[:, [i, j]] = y[:, [j, i]]
    ((r, lft, dz),) = swapped_sides(model, kin, y, labels)
    assert (r, lft) == ("RHEE", "LHEE") and dz == pytest.approx(-0.12, abs=0.01)
    y = x.copy()
    y[:, i, 1] = y[:, [i, j], 1].mean(axis=1) + 0.002
    y[:, j, 1] = y[:, i, 1] - 0.004
    assert swapped_sides(model, kin, y, labels) == []


def test_a_still_trial_raises_no_frozen_coordinate_flag():
    """Quiet standing (every leg coordinate within 0.5° SD of sway, one at 0.03°: UNIPD's
    Static1 run as a task, hip_flexion_r 0.04°) cannot tell an unobserved coordinate from a
    still one: no ``*_std_deg`` flag; the same coordinate frozen in a moving trial is flagged."""
    model = two_leg_model()
    rng = np.random.default_rng(3)
    kin = _still(model, 100)
    kin.coordinate_names = kin_names(model)
    kin.q[:, 6:] += np.radians(0.5) * rng.standard_normal((100, kin.q.shape[1] - 6))
    i = model.coordinate_names.index("hip_flexion_r")
    kin.q[:, i] = np.radians(0.03) * rng.standard_normal(100)
    assert not [f for f in _flags(model, kin) if f.quantity.endswith("_std_deg")]
    kin.q[:, model.coordinate_names.index("knee_angle_l")] = np.linspace(-0.1, -1.0, 100)
    by = {f.quantity for f in _flags(model, kin)}
    assert "hip_flexion_r_std_deg" in by


def test_two_still_markers_are_no_rigid_pair_of_the_static_check():
    """Markers on two segments that both stay still through the task (the two feet of a squat)
    keep their distance without being on one segment: the static, with the feet placed
    otherwise (4 cm wider), names none of them; moving, the same pairs are not rigid."""
    from msk.quality import inconsistent_static_markers

    rng = np.random.default_rng(5)
    feet = np.array([[0, 0, 0.1], [0.2, 0, 0.1], [0.1, 0.05, 0.12],
                     [0, 0, -0.1], [0.2, 0, -0.1], [0.1, 0.05, -0.12]])  # fmt: skip
    labels = ("R0", "R1", "R2", "L0", "L1", "L2")
    motion = np.repeat(feet[None], 200, axis=0) + rng.normal(0.0, 0.0015, (200, 6, 3))
    wide = feet.copy()
    wide[:3, 2] += 0.04
    static = np.repeat(wide[None], 30, axis=0) + rng.normal(0.0, 0.0015, (30, 6, 3))
    assert inconsistent_static_markers(static, labels, motion, labels) == {}
    # without the still exemption the cross-foot pairs would read as rigid and name them
    assert inconsistent_static_markers(static, labels, motion, labels, still_m=0.0) != {}


def test_unmeasured_contact_inside_the_measured_span_is_flagged_outside_it_is_not():
    """The gate ``unmeasured_contact_inside_pct``: a foot standing (≥ 0.15 s) on an unmeasured
    surface in more than 5 % of the frames between the first and last measured frame (a
    stair's upper steps); before and after the plates (a walkway's steps) and a run of a few
    frames (before a heel strike) do not count."""
    from types import SimpleNamespace as NS

    from msk.dynamics.loads import FootContact
    from msk.quality import unmeasured_contact_figures

    t = np.arange(100) / 100.0
    miss = np.zeros((100, 2), dtype=bool)
    measured = np.zeros(100, dtype=bool)
    measured[20:80] = True
    miss[:20, 0] = True  # before the plates: a walkway's first step
    miss[80:, 1] = True
    miss[30:33, 1] = True  # 20 ms before a heel strike
    known = np.ones(100, dtype=bool)
    contact = FootContact(("calcn_r", "calcn_l"), miss, miss, known, t)
    q = unmeasured_contact_figures(NS(contact=contact, measured=measured), t)
    assert q["unmeasured_contact_frames"] == 40 and q["unmeasured_contact_inside_pct"] == 0.0
    model = two_leg_model()
    kin = _still(model, 100)
    kin.coordinate_names = kin_names(model)
    assert not [f for f in _flags(model, kin, frames=100, **q)
                if f.quantity == "unmeasured_contact_inside_pct"]  # fmt: skip
    miss[40:60, 0] = True  # a step without a plate, inside
    contact = FootContact(("calcn_r", "calcn_l"), miss, miss, known, t)
    q = unmeasured_contact_figures(NS(contact=contact, measured=measured & ~miss[:, 0]), t)
    assert q["unmeasured_contact_inside_pct"] == pytest.approx(100 * 20 / 60)
    assert q["unmeasured_contact_inside_s"] == [0.4, 0.59]
    (flag,) = [f for f in _flags(model, kin, frames=100, **q)
               if f.quantity == "unmeasured_contact_inside_pct"]  # fmt: skip
    assert "0.40–0.59 s" in flag.message and "calcn_r 40" in flag.message


def test_unmeasured_contact_on_a_raised_surface_is_flagged():
    """A foot standing on a raised surface no plate measures (a stair's upper steps, found by
    the momentum balance) raises ``unmeasured_contact_raised_frames`` wherever it lies in the
    trial; none raises nothing."""
    model = two_leg_model()
    kin = _still(model, 100)
    kin.coordinate_names = kin_names(model)
    q = {"frames": 100, "unmeasured_contact_raised_frames": 30}
    (flag,) = [f for f in _flags(model, kin, **q)
               if f.quantity == "unmeasured_contact_raised_frames"]  # fmt: skip
    assert flag.value == 30.0 and "30 of the 100 frames" in flag.message
    q["unmeasured_contact_raised_frames"] = 0
    assert not [f for f in _flags(model, kin, **q) if f.quantity.startswith("unmeasured")]


def test_right_and_left_limb_markers_moving_alike_are_no_rigid_pair():
    """The legs of a squat move alike: a right and a left shank marker keep their distance
    (the task's stance width) without being on one segment. With the static's stance 6 cm
    wider, no shank marker is named; the pelvis' ASIS pair (one segment, opposite sides) is
    still checked: a static with its left ASIS 40 mm off is named."""
    from msk.quality import inconsistent_static_markers

    rng = np.random.default_rng(8)
    t = np.linspace(0.0, 8.0, 400)
    sink = 0.15 * (1 - np.cos(2 * np.pi * t / 2.0))  # 4 squats
    base = {
        "R.Shank.Up": [0.02, 0.45, 0.12], "R.Shank.Down": [0.03, 0.25, 0.12],
        "R.Shank.Front": [0.08, 0.35, 0.10], "L.Shank.Up": [0.02, 0.45, -0.12],
        "L.Shank.Down": [0.03, 0.25, -0.12], "L.Shank.Front": [0.08, 0.35, -0.10],
        "RASI": [0.10, 0.95, 0.12], "LASI": [0.10, 0.95, -0.12], "SACR": [-0.08, 0.97, 0.0],
        "RPSI": [-0.07, 0.98, 0.05], "LPSI": [-0.07, 0.98, -0.05],
    }  # fmt: skip
    labels = tuple(base)
    x0 = np.array([base[k] for k in labels])
    motion = np.repeat(x0[None], t.size, axis=0)
    shank = np.array(["Shank" in k for k in labels])
    motion[:, shank, 1] -= 0.5 * sink[:, None]  # the shanks tilt and sink alike
    motion[:, shank, 0] += 0.3 * sink[:, None]
    motion[:, ~shank, 1] -= sink[:, None]  # the pelvis sinks
    motion += rng.normal(0.0, 0.001, motion.shape)
    wide = x0.copy()
    wide[[labels.index(k) for k in labels if k.startswith("R.")], 2] += 0.06
    static = np.repeat(wide[None], 30, axis=0) + rng.normal(0.0, 0.001, (30, len(labels), 3))
    assert inconsistent_static_markers(static, labels, motion, labels) == {}
    ghost = static.copy()
    ghost[:, labels.index("LASI"), 2] -= 0.04
    assert set(inconsistent_static_markers(ghost, labels, motion, labels)) == {"LASI"}


def test_kkt_flags_name_trial_figure_frame_value_and_threshold() -> None:
    """A KKT figure above ``kkt_relative`` of its scale on a frame solved as optimal is
    flagged with the trial, the figure, the frame and time, the value and the threshold; at
    round-off (DAQP's 1e-15) nothing is, nor without a KKT check (closed_form)."""
    from msk.optimization.muscle_forces import KktWorst
    from msk.quality import kkt_flags

    cols = ("stationarity", "primal_feasibility", "dual_feasibility", "complementarity")
    worst = KktWorst(
        cols, np.array([3e-4, 1e-13, 0.0, 1e-16]), np.array([2e-5, 1e-15, 0.0, 1e-17]),
        np.array([41, 7, 0, 3]), np.array([1.25, 0.5, 0.0, 0.1]), 120,
    )  # fmt: skip
    (f,) = kkt_flags("walk", SimpleNamespace(kkt=worst))
    assert (f.trial, f.quantity, f.value, f.threshold) == (
        "walk",
        "optimization_kkt_stationarity",
        2e-5,
        THRESHOLDS["kkt_relative"],
    )
    assert "frame 41" in f.message and "t = 1.250 s" in f.message
    assert not kkt_flags("walk", SimpleNamespace(kkt=worst), {"kkt_relative": 1e-4})
    assert not kkt_flags("walk", SimpleNamespace(kkt=None))


def test_markers_placed_across_the_knee_against_their_label_are_flagged():
    """A thigh-cluster marker on the tibia and a shank-cluster marker on the femur (issue 15,
    thirteenth pass: a synthetic DM walk) are reported with the body their label names; the
    same markers on their own segments, markers without a leg landmark and a foot marker on the
    talus are not; a side the model lacks is not judged."""
    from msk.quality import model_flags, placement_label_conflicts

    bodies = ["pelvis", "femur_r", "tibia_r", "talus_r", "calcn_r", "femur_l", "tibia_l"]
    placed = {"R_Thigh_Inferior": "tibia_r", "R_Shank_Superior": "femur_r",
              "R_Thigh_Superior": "femur_r", "L_Shank_Lateral": "tibia_l",
              "Lumbar": "pelvis", "R_Heel": "talus_r", "R_Shoulder": "torso"}  # fmt: skip
    got = placement_label_conflicts(placed, bodies)
    assert got == {"R_Thigh_Inferior": ("tibia_r", "femur_r"),
                   "R_Shank_Superior": ("femur_r", "tibia_r")}  # fmt: skip
    assert placement_label_conflicts({"R_Thigh_Inferior": "tibia_r"}, ["femur", "tibia"]) == {}
    flags = model_flags("t", {"marker_placement": {"placed": placed}}, bodies)
    assert [(f.quantity, f.value) for f in flags] == [("markers_placed_against_label", 2.0)]
    assert "R_Thigh_Inferior on tibia_r" in flags[0].message
    ok = {k: v for k, v in placed.items() if k not in got}
    assert model_flags("t", {"marker_placement": {"placed": ok}}, bodies) == []
    # a sided label on the other side's body, whatever the segment
    assert placement_label_conflicts(
        {"R_Midfoot_Medial": "toes_l", "L_Heel": "calcn_l"}, bodies
    ) == {"R_Midfoot_Medial": ("toes_l", "a R body")}


@pytest.mark.parametrize(("functional", "flagged"), [(0.80, False), (0.83, True), (0.74, True)])
def test_a_leg_whose_two_length_measures_disagree_is_flagged(functional, flagged):
    """Hip to functional ankle against the ASIS-to-heel leg (0.78 m): 2.6 % passes, +6.4 % and
    −5.1 % are over the 5 % gate, with the side in the quantity; a side without both lengths
    (the leg factor kept) is not judged."""
    from msk.quality import model_flags

    info = {"leg_split": {
        "r": {"femur_length_m": 0.40, "tibia_length_m": functional - 0.40,
              "model_femur_m": 0.39, "model_tibia_m": 0.39},
        "l": {"femur_length_m": None, "tibia_length_m": None,
              "model_femur_m": None, "model_tibia_m": None},
    }}  # fmt: skip
    flags = model_flags("t", info, [])
    assert [f.quantity for f in flags] == (["leg_length_disagreement_pct_r"] if flagged else [])
    if flagged:
        assert flags[0].value == pytest.approx(100 * abs(functional / 0.78 - 1))
        assert flags[0].threshold == THRESHOLDS["leg_length_disagreement_pct"]


def test_a_leg_coordinate_the_placement_does_not_determine_is_flagged():
    """``model.placement_determinacy`` (msk.personalise.determinacy): a flag per coordinate it lists
    as not
    determined, its value the smaller cost change (a better fit: negative), its threshold the
    profile's tolerance, its message the coordinate, the shift and "not determined by the
    markers"; a coordinate with no flat direction found raises nothing."""
    from msk.personalise.determinacy import CoordinateProfile, PlacementProfile
    from msk.quality import model_flags

    coords = (
        CoordinateProfile("knee_angle_r", -0.5, (0.084, -0.085), (1.2e-4, -3e-5), 10, 0),
        CoordinateProfile("hip_flexion_r", 0.4, (0.08, -0.08), (6e-4, 9e-4), 13, 0),
    )
    info = {"placement_determinacy": PlacementProfile(0.087, 2e-4, 120, 0.007, coords).summary()}
    (flag,) = model_flags("t", info, [])
    assert flag.trial == "t" and flag.quantity == "placement_not_determined_knee_angle_r"
    assert flag.value == pytest.approx(-3e-5) and flag.threshold == pytest.approx(2e-4)
    assert "not determined by the markers (no static trial)" in flag.message
    assert "-4.9°" in flag.message and "better" in flag.message
    (flag,) = model_flags("t", {"placement_determinacy": {"not_run": "no frame fitted"}}, [])
    assert flag.quantity == "placement_determinacy_not_run" and "no frame fitted" in flag.message


def test_a_static_marker_moved_far_on_its_body_is_flagged_with_its_distance():
    """A static's anatomical marker relocated 60 mm (over 50 mm) and a moved foot marker
    127 mm (over 100 mm; a ghost in the static) are flagged with their names and distances;
    39 mm and 94 mm (the largest on the shipped statics) are not; without a static nothing is
    judged."""
    from msk.quality import model_flags

    placement = {"relocated": {"R.Knee.Lat": 0.039, "L.Ankle.Lat": 0.060},
                 "moved": {"R.Midfoot.Lat": 0.094, "L.Toe.Tip": 0.127}}  # fmt: skip
    info = {"static_window": {"whole_trial": True}, "marker_placement": placement}
    flags = {f.quantity: f for f in model_flags("t", info, [])}
    assert set(flags) == {"static_marker_relocated_m", "static_marker_moved_m"}
    assert flags["static_marker_relocated_m"].value == pytest.approx(0.060)
    assert "L.Ankle.Lat 60 mm" in flags["static_marker_relocated_m"].message
    assert "R.Knee.Lat" not in flags["static_marker_relocated_m"].message
    assert "L.Toe.Tip 127 mm" in flags["static_marker_moved_m"].message
    assert flags["static_marker_moved_m"].threshold == THRESHOLDS["static_marker_moved_m"]
    assert model_flags("t", {"marker_placement": placement}, []) == []


@pytest.mark.parametrize(
    ("pose", "flagged"),
    [({"pelvis_tilt": 12.0, "hip_flexion_r": 4.0, "hip_flexion_l": -3.0}, set()),
     ({"pelvis_tilt": -41.0, "hip_flexion_r": 4.0}, {"static_pelvis_tilt_deg"}),
     ({"pelvis_tilt": 8.0, "hip_flexion_l": -55.0}, {"static_hip_flexion_l_deg"})],
)  # fmt: skip
def test_a_static_standing_pose_beyond_the_gates_is_flagged(pose, flagged):
    """Standing pelvis tilt beyond ±25° and hip flexion beyond ±30° in the static's pose
    (``marker_placement.static_pose_deg``) are flagged with the value and the signed bound."""
    from msk.quality import model_flags

    info = {"static_window": {}, "marker_placement": {"static_pose_deg": pose}}
    flags = {f.quantity: f for f in model_flags("t", info, [])}
    assert set(flags) == flagged
    for f in flags.values():
        assert abs(f.value) > abs(f.threshold) and np.sign(f.value) == np.sign(f.threshold)


def test_file_and_plate_flags_name_what_they_found() -> None:
    """A ``[markers] rename`` naming labels in no trial (its count the value), a plate reading
    nothing under a foot (its largest force the value) and a foot past a plate's edge (how far)
    are each one flag of the trial; nothing raised without them."""
    from msk.quality import dead_plate_flags, marker_rename_flags, plate_edge_flags

    info = {"marker_set": {"notes": ["markers.rename: labels in no trial: RKNE, LKNEE", "ok"]}}
    (f,) = marker_rename_flags("walk", info)
    assert (f.trial, f.quantity, f.value) == ("walk", "marker_rename_unmatched", 2.0)
    assert "RKNE" in f.message
    dead = {"plate": "FP2", "foot": "calcn_l", "max_force_n": 3.0, "seconds": 0.6,
            "start_s": 1.0, "end_s": 1.6}  # fmt: skip
    (d,) = dead_plate_flags("walk", [dead])
    assert (d.quantity, d.value, d.threshold) == ("plate_dead", 3.0, 20.0) and "FP2" in d.message
    edge = {"foot": "calcn_r", "plate": "FP1", "max_outside_m": 0.04, "start_s": 0.1,
            "end_s": 0.3, "frames": 20}  # fmt: skip
    (e,) = plate_edge_flags("walk", {"plate_edge": [edge]})
    assert (e.quantity, e.value) == ("foot_past_plate_edge_m", 0.04) and "4 cm" in e.message
    assert not marker_rename_flags("walk", {}) and not dead_plate_flags("walk", [])
    assert not plate_edge_flags("walk", {})


def test_the_physiological_range_is_read_in_the_reference_convention():
    """A knee coordinate positive in flexion (Rajagopal's walker knee; here two_leg_model with
    its knee axes turned): 70° of flexion is inside the physiological range, 30° of
    hyperextension (−30° of that coordinate) is not, and the flag says the sign it used."""
    from tests.support.knees import turned_knees

    model = turned_knees(two_leg_model())
    i = model.coordinate_names.index("knee_angle_r")
    for deg, raised in ((70.0, False), (-30.0, True)):
        kin = _still(model, 50)
        kin.coordinate_names = kin_names(model)
        kin.q[:, i] = np.radians(deg) + 0.01 * np.sin(np.arange(50))
        kin.q_raw = kin.q.copy()
        by = {f.quantity: f for f in _flags(model, kin)}
        assert ("knee_angle_r_deg" in by) is raised
        if raised:
            assert by["knee_angle_r_deg"].value == pytest.approx(30.0, abs=0.6)
            assert "gait2392's sign" in by["knee_angle_r_deg"].message


def test_leg_coordinates_are_the_hips_and_below_and_an_arm_reserve_is_not_judged() -> None:
    """The reserve gate judges the coordinates of either leg's tree only: gait2392's and
    Rajagopal's hips, knees, ankles …, never the pelvis' or Rajagopal's torque-driven arms
    (whose names end in ``_r`` too); an arm's reserve carrying all its torque raises nothing
    while a knee's does."""
    from types import SimpleNamespace

    from msk.model.files import load_model
    from msk.optimization.muscle_forces import MuscleForces
    from msk.quality import leg_coordinates, optimization_flags

    g = leg_coordinates(load_model("gait2392"))
    assert {"hip_flexion_r", "knee_angle_l", "ankle_angle_r", "subtalar_angle_l"} <= g
    assert not {c for c in g if c.startswith(("pelvis", "lumbar"))}
    raj = load_model("rajagopal")
    legs = leg_coordinates(raj)
    arms = [c for c in raj.coordinate_names if c.startswith(("arm_", "elbow_", "pro_sup"))]
    assert arms and not set(arms) & legs and "knee_angle_r" in legs
    rt = np.full((10, 2), 30.0)
    sol = MuscleForces(
        np.full((10, 1), 100.0), np.full((10, 1), 0.1), ("vasint_r",), "static_optimization", 0,
        reserve_torques=rt, reserve_coordinates=(arms[0], "knee_angle_r"),
    )  # fmt: skip
    jt = SimpleNamespace(coordinate_names=(arms[0], "knee_angle_r"), tau=np.full((10, 2), 30.0))
    flags = {f.quantity for f in optimization_flags("t", sol, jt, legs=legs)}
    assert flags == {"knee_angle_r_reserve_rms_pct"}
    everything = {f.quantity for f in optimization_flags("t", sol, jt)}  # by suffix
    assert f"{arms[0]}_reserve_rms_pct" in everything
