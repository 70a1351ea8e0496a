"""External loads: automatic plate assignment, C3D round trip, signs, errors, applied forces."""

from __future__ import annotations

import dataclasses
import functools
import tomllib
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from msk.datasets.models import two_leg_model
from msk.datasets.trials import make_trial
from msk.dynamics.inverse import inverse_dynamics
from msk.dynamics.loads import (
    AppliedForce,
    ExternalLoads,
    PlateWrench,
    external_loads,
    plates_from_table,
    plates_from_trial,
)
from msk.exceptions import ForcePlateError
from msk.kinematics.ik import kinematics_from_coordinates
from msk.model.core import Body

MODEL = two_leg_model()
TRIAL = make_trial(MODEL, duration_s=1.0, rate_hz=100.0, analog_ratio=10)
KIN = dataclasses.replace(
    kinematics_from_coordinates(TRIAL.time, TRIAL.q, MODEL.coordinate_names, cutoff_hz=None),
    v=TRIAL.v,
    a=TRIAL.a,
)


def _unloaded_between(pl: PlateWrench, t0: float, t1: float) -> PlateWrench:
    off = (pl.time > t0) & (pl.time < t1)
    f, c, m = pl.force.copy(), pl.cop.copy(), pl.free_moment.copy()
    f[off], c[off], m[off] = 0.0, np.nan, 0.0
    return dataclasses.replace(pl, force=f, cop=c, free_moment=m)


def test_plates_are_assigned_to_the_foot_standing_on_them():
    loads = external_loads(MODEL, KIN, TRIAL.plates)
    assert isinstance(loads, ExternalLoads)
    assert [(a.plate, a.body) for a in loads.assignments] == [
        ("plate1", "foot_r"),
        ("plate2", "foot_l"),
    ]
    idx = np.arange(TRIAL.time.size) * TRIAL.analog_ratio
    b = loads.body_index("foot_r")
    np.testing.assert_allclose(loads.force[:, b], TRIAL.plates[0].force[idx], atol=1e-9)
    np.testing.assert_allclose(loads.point[:, b], TRIAL.plates[0].cop[idx], atol=1e-9)
    np.testing.assert_allclose(
        loads.moment_about_point()[:, b], TRIAL.plates[0].free_moment[idx], atol=1e-8
    )
    f, m = loads.total()
    np.testing.assert_allclose(f, TRIAL.grf_force[idx], atol=1e-8)
    np.testing.assert_allclose(m, TRIAL.grf_moment[idx], atol=1e-8)


def test_contact_intervals_and_sign_of_an_action_plate():
    pl = _unloaded_between(TRIAL.plates[0], 0.3, 0.6)
    flipped = dataclasses.replace(
        TRIAL.plates[1], force=-TRIAL.plates[1].force, free_moment=-TRIAL.plates[1].free_moment
    )
    loads = external_loads(MODEL, KIN, [pl, flipped])
    spans = [(a.plate, a.body, a.start_time, a.end_time) for a in loads.assignments]
    assert spans[0][:3] == ("plate1", "foot_r", 0.0) and spans[0][3] == pytest.approx(0.3)
    assert spans[1][:3] == ("plate1", "foot_r", pytest.approx(0.6))
    assert spans[2][:2] == ("plate2", "foot_l")
    i = np.flatnonzero((TRIAL.time > 0.31) & (TRIAL.time < 0.59))
    assert np.all(loads.force[i, loads.body_index("foot_r")] == 0.0)
    assert np.isnan(loads.point[i, loads.body_index("foot_r")]).all()
    b = loads.body_index("foot_l")
    assert np.all(loads.force[:, b, 1] > 0)  # made a ground reaction again


def test_unassignable_contacts_are_flagged_or_raise_naming_plate_and_time():
    pl = TRIAL.plates[0]
    mid = (TRIAL.plates[0].corners + TRIAL.plates[1].corners) / 2
    both = dataclasses.replace(
        pl, corners=mid + np.array([[0, 0, 0.2], [0, 0, 0.2], [0, 0, -0.2], [0, 0, -0.2]])
    )
    flagged = external_loads(MODEL, KIN, [both])  # default: flag, never guess, never raise
    # both feet stand on it until 0.81 s; then the right foot swings (1–1.8 m/s) over it
    assert [(f.plate, f.reason, f.feet, f.start_time) for f in flagged.flags] == [
        ("plate1", "shared", ("foot_r", "foot_l"), 0.0)
    ]
    shared = flagged.shared_contact
    assert shared[KIN.time <= 0.8].all() and not flagged.unassigned_contact.any()
    assert np.all(flagged.total()[0][shared] == 0.0)  # the load is on no body there
    with pytest.raises(
        ForcePlateError, match=r"plate1 contact 0\.000.*both feet \(foot_r, foot_l\)"
    ):
        external_loads(MODEL, KIN, [both], on_unassigned="raise")
    far = dataclasses.replace(pl, corners=pl.corners + np.array([3.0, 0.0, 0.0]))
    assert [f.reason for f in external_loads(MODEL, KIN, [far]).flags] == ["unassigned"]
    with pytest.raises(ForcePlateError, match=r"plate1 .*no foot over the plate at t = 0\.000 s"):
        external_loads(MODEL, KIN, [far], on_unassigned="raise")
    no_corners = dataclasses.replace(pl, corners=None, cop=pl.cop + np.array([2.0, 0.0, 0.0]))
    with pytest.raises(ForcePlateError, match=r"no foot within 0\.3 m"):
        external_loads(MODEL, KIN, [no_corners], on_unassigned="raise")
    # a foot inside the outline but far from the plate surface does not stand on it
    for dy in (0.5, -0.5):
        shift = np.array([0.0, dy, 0.0])  # the model's up is +y
        lifted = dataclasses.replace(pl, cop=pl.cop + shift, corners=pl.corners + shift)
        # (a plate 0.5 m below the foot is a step built on it when its surface is inferred:
        # tests/dynamics/test_plate_surface.py)
        with pytest.raises(ForcePlateError, match=r"plate1 .*no foot over the plate"):
            external_loads(MODEL, KIN, [lifted], on_unassigned="raise", infer_surface=False)
        assert external_loads(MODEL, KIN, [lifted], infer_surface=False).unassigned_contact.all()
    assert external_loads(MODEL, KIN, [pl], floor_m=0.1).assignments[0].body == "foot_r"
    # without corners the COP decides
    ok = external_loads(MODEL, KIN, [dataclasses.replace(p, corners=None) for p in TRIAL.plates])
    assert [a.body for a in ok.assignments] == ["foot_r", "foot_l"]
    # an explicit assignment bypasses the test
    forced = external_loads(MODEL, KIN, [far], assignment={"plate1": "foot_r"})
    assert forced.assignments[0].body == "foot_r"


def test_c3d_round_trip_through_msk_io(tmp_path):
    from msk.io import read_c3d

    path = TRIAL.write_c3d(tmp_path / "synthetic.c3d")
    trial = read_c3d(path)
    assert trial.marker_labels == TRIAL.marker_labels
    np.testing.assert_allclose(trial.markers, TRIAL.markers, atol=1e-6)  # float32 in mm
    plates = plates_from_trial(trial)
    assert len(plates) == 2
    loads = external_loads(MODEL, KIN, plates)
    assert [a.body for a in loads.assignments] == ["foot_r", "foot_l"]
    idx = np.arange(TRIAL.time.size) * TRIAL.analog_ratio
    f, m = loads.total()
    scale = np.abs(TRIAL.grf_force).max()
    np.testing.assert_allclose(f, TRIAL.grf_force[idx], atol=1e-5 * scale)
    np.testing.assert_allclose(m, TRIAL.grf_moment[idx], atol=1e-5 * scale)


def test_fext_equals_minus_jacobian_transpose_of_the_world_wrench():
    loads = external_loads(MODEL, KIN, TRIAL.plates)
    geo = inverse_dynamics(MODEL, KIN, loads, variant="geometric")
    pm = MODEL.pin_model
    data = pm.createData()
    for k in (0, 37, 99):
        q = MODEL.coupling.q(TRIAL.q[k])
        tau = np.zeros(pm.nv)
        for b, body in enumerate(loads.bodies):
            jac = pin.computeFrameJacobian(pm, data, q, MODEL.body_frame[body], pin.WORLD)
            tau -= jac.T @ np.concatenate([loads.force[k, b], loads.moment[k, b]])
        np.testing.assert_allclose(geo.tau_pin[k], tau, atol=1e-9 * np.abs(tau).max())


def test_carried_load_equals_a_point_mass_added_to_the_body():
    mass, local = 5.0, np.array([0.05, 0.20, 0.10])
    n = TRIAL.time.size
    weight = np.tile(mass * MODEL.gravity, (n, 1))
    carried = AppliedForce("pelvis", weight, np.tile(local, (n, 1)), point_in_body=True)
    loads = external_loads(MODEL, KIN, [], extra=[carried])
    with_load = inverse_dynamics(MODEL, KIN, loads, variant="quasi_static")
    pelvis = MODEL.body("pelvis")
    inertia = pelvis.pin_inertia + pin.Inertia(mass, local, np.zeros((3, 3)))
    heavier = MODEL.with_bodies(
        {"pelvis": Body("pelvis", inertia.mass, inertia.lever, inertia.inertia)}
    )
    ref = inverse_dynamics(heavier, KIN, None, variant="quasi_static")
    np.testing.assert_allclose(with_load.tau, ref.tau, atol=1e-9)
    np.testing.assert_allclose(loads.point[:, 0, 1], KIN.q[:, 1] + 0.2, atol=0.05)


def test_plates_from_an_opensim_grf_table():
    t = np.linspace(0, 1, 11)
    cols = []
    data = []
    for pre in ("ground_", "1_ground_"):
        for name, val in (
            ("force_v", [10.0, 700.0, 5.0]),
            ("force_p", [0.3, 0.0, 0.1]),
            ("torque_", [0.0, 2.0, 0.0]),
        ):
            for ax, v in zip("xyz", val):
                cols.append(f"{pre}{name}{ax}")
                data.append(np.full(t.size, v))
    pls = plates_from_table(t, np.column_stack(data), cols)
    assert [p.name for p in pls] == ["plate1", "plate2"]
    np.testing.assert_allclose(pls[1].force[0], [10.0, 700.0, 5.0])
    np.testing.assert_allclose(
        pls[0].moment_about_origin()[0],
        np.cross([0.3, 0, 0.1], [10.0, 700.0, 5.0]) + np.array([0, 2.0, 0]),
    )


# ---------------------------------------------------------------------------------------------
# regression: Grand Challenge PS overground walk (data/gc5-PS, bundled with the repository)
# ---------------------------------------------------------------------------------------------
GC5 = Path(__file__).resolve().parents[2] / "data" / "gc5-PS"


@functools.lru_cache(maxsize=1)
def _gc5_walk() -> tuple[object, object, object]:
    """gait2392 scaled to PS, the overground walk in the model frame and its kinematics."""
    from msk.io import read_c3d, read_trc, to_model_frame
    from msk.kinematics.ik import solve_kinematics
    from msk.model.files import load_model
    from msk.personalise.scaling import (
        DEFAULT_MEASUREMENTS,
        place_markers,
        scale_model,
        usable_measurements,
    )

    with (Path(__file__).resolve().parents[2] / "pipelines" / "gc5_PS.toml").open("rb") as fh:
        inv = {v: k for k, v in tomllib.load(fh)["markers"]["rename"].items()}
    model = load_model("gait2392")
    static = read_trc(GC5 / "PS_static_for_scaling.trc")
    labels = tuple(inv.get(lab, lab) for lab in static.labels)
    meas = usable_measurements(DEFAULT_MEASUREMENTS, set(labels) & set(model.marker_names))
    markers = {lab: static.markers[:, i] for i, lab in enumerate(labels)}
    model = scale_model(model, markers, measurements=meas, body_mass=75.0)
    model, _ = place_markers(model, static.markers, labels, static.time)
    trial = to_model_frame(
        read_c3d(GC5 / "PS_ngait_og_ss1.c3d"), up=-np.asarray(model.gravity, dtype=float)
    )
    kin = solve_kinematics(
        model,
        trial.markers,
        tuple(inv.get(lab, lab) for lab in trial.marker_labels),
        trial.time,
        cutoff_hz=6.0,
    )
    return model, trial, kin


@pytest.mark.slow
def test_overground_walk_plates_go_to_the_standing_foot_not_the_swinging_one():
    """PS_ngait_og_ss1: the swinging right foot passes over plate 1 while the left foot stands
    on it (and the left over plate 3 under the right); the outline-based assignment alone
    counted both feet; plate 1 → left foot, plates 2 and 3 → right foot."""
    model, trial, kin = _gc5_walk()
    plates = plates_from_trial(trial)
    assert all(p.corners is not None for p in plates)
    loads = external_loads(model, kin, plates, cutoff_hz=15.0)
    assert [(a.plate, a.body) for a in loads.assignments] == [
        ("plate1", "calcn_l"),
        ("plate2", "calcn_r"),
        ("plate3", "calcn_r"),
    ]
    # the same answer as the COP-only rule (plates without outline)
    cop_only = external_loads(
        model, kin, [dataclasses.replace(p, corners=None) for p in plates], cutoff_hz=15.0
    )
    assert [a.body for a in cop_only.assignments] == [a.body for a in loads.assignments]
    np.testing.assert_array_equal(cop_only.force, loads.force)
    # without the swing test the outline counts both feet on plate 1 while the right foot swings
    # over it (flagged, before 2026-11-24: plate 1 from 5.31 s, plate 3 from 5.85 s); the right
    # foot stood still with its toes over plate 1's margin (on plate 2) while plate 1 recorded
    # nothing and the left foot swung, so it stands beside plate 1 through that run, and the
    # left beside plate 3 likewise: the same assignment, nothing shared
    bad = external_loads(model, kin, plates, cutoff_hz=15.0, speed_mps=np.inf)
    assert bad.flags == ()
    assert [(a.plate, a.body) for a in bad.assignments] == [
        (a.plate, a.body) for a in loads.assignments
    ]


def test_contact_measured_flags_a_foot_on_the_floor_beside_the_plates():
    """Standing still on both plates: every frame measured; plate 1 unloaded for 0.3 s (the
    right foot on the floor, its reaction not recorded): those frames are not; the same 0.3 s
    in the air (a hop: pelvis 0.2 m up, no foot on the floor): measured; unknown pose: not."""
    from msk.dynamics.loads import contact_measured

    t = KIN.time
    q = np.repeat(TRIAL.q[:1], t.size, axis=0)
    still = dataclasses.replace(KIN, q=q, v=np.zeros_like(q), a=np.zeros_like(q))
    full = external_loads(MODEL, still, TRIAL.plates)
    assert contact_measured(MODEL, still, full).all()
    window = (t > 0.3) & (t < 0.6)
    plates = (_unloaded_between(TRIAL.plates[0], 0.3, 0.6), TRIAL.plates[1])
    m = contact_measured(MODEL, still, external_loads(MODEL, still, plates))
    np.testing.assert_array_equal(m, ~window)
    # the left foot alone is always loaded
    part = external_loads(MODEL, still, plates)
    assert contact_measured(MODEL, still, part, feet=("foot_l",)).all()
    hop_q = q.copy()
    hop_q[window, MODEL.coordinate_index("pelvis_ty")] += 0.2
    hop = dataclasses.replace(still, q=hop_q)
    both_off = tuple(_unloaded_between(p, 0.3, 0.6) for p in TRIAL.plates)
    # the hop teleports the body (held 0.2 m up without support: no momentum balance), so the
    # dynamics' test of an unmarked support (shortfall_bw) is off here
    assert contact_measured(
        MODEL, hop, external_loads(MODEL, hop, both_off), shortfall_bw=np.inf
    ).all()
    gap_q = q.copy()
    gap_q[5] = np.nan
    gap = dataclasses.replace(still, q=gap_q)
    m = contact_measured(MODEL, gap, full)
    assert not m[5] and m[np.arange(t.size) != 5].all()


def test_contact_measured_widens_ground_contact_by_the_kinematic_filter_spread():
    """A hop (feet 0.2 m up for 0.3 s, plates unloaded): the feet leave and reach the floor
    within a frame, so unpadded every frame is measured; ``pad_s`` = 0.05 s (100 Hz: 5
    frames) widens each foot's ground contact into the flight, where it carries no load: the
    first and last frames of the flight are not measured, the rest are. The default pad is
    1/(4 f_c) of the kinematics' cutoff (none when unfiltered)."""
    from msk.dynamics.loads import contact_measured

    t = KIN.time
    q = np.repeat(TRIAL.q[:1], t.size, axis=0)
    still = dataclasses.replace(KIN, q=q, v=np.zeros_like(q), a=np.zeros_like(q))
    window = (t > 0.3) & (t < 0.6)
    hop_q = q.copy()
    hop_q[window, MODEL.coordinate_index("pelvis_ty")] += 0.2
    hop = dataclasses.replace(still, q=hop_q)
    loads = external_loads(MODEL, hop, tuple(_unloaded_between(p, 0.3, 0.6) for p in TRIAL.plates))
    # the body is held up without support (non-physical): the shortfall test is off
    off = {"shortfall_bw": np.inf}
    assert contact_measured(MODEL, hop, loads, **off).all()
    idx = np.flatnonzero(window)
    padded = contact_measured(MODEL, hop, loads, pad_s=0.05, **off)
    # the frame next to each jump moves fast (central differences): it is not on the ground,
    # so the pad reaches 4 frames into the flight
    assert not padded[idx[:4]].any() and not padded[idx[-4:]].any()
    assert padded[idx[5:-5]].all() and padded[~window].all()
    filtered = dataclasses.replace(hop, cutoff_hz=5.0)  # 1/(4·5 Hz) = 0.05 s
    np.testing.assert_array_equal(contact_measured(MODEL, filtered, loads, **off), padded)


def test_a_few_shared_frames_inside_one_foots_stance_take_that_foot():
    """A shared run shorter than 30 ms between two runs of one foot is that foot's (the other
    foot passing within the plate's margin after toe-off); a longer one, or one at the end of
    the contact, stays shared (flagged and left out)."""
    from msk.dynamics.loads import _SHARED, _segments

    t = np.arange(40) / 120.0
    lab = np.zeros(40, dtype=int)
    lab[10:13] = _SHARED  # 3 frames = 17 ms inside foot 0's stance
    assert _segments(lab, t, 0) == [(0, 40, 0)]
    lab[10:16] = _SHARED  # 6 frames = 42 ms: kept
    assert [s[2] for s in _segments(lab, t, 0)] == [0, _SHARED, 0]
    lab = np.zeros(40, dtype=int)
    lab[37:] = _SHARED  # at the end of the contact: kept
    assert [s[2] for s in _segments(lab, t, 0)] == [0, _SHARED]


def test_recorded_force_is_kept_beside_the_low_passed_one():
    """``force_recorded``: the plates' force as recorded (before the low-pass), summed over the
    assigned contacts; the residual-moment bound takes its peak (Hicks et al. 2015: the
    measured external force), which a low-pass lowers."""
    from msk.dynamics.loads import peak_measured_force_n

    idx = np.arange(TRIAL.time.size) * TRIAL.analog_ratio
    impact = [dataclasses.replace(p, force=p.force.copy()) for p in TRIAL.plates]
    k = int(np.argmax(impact[0].force[:, 1]))
    impact[0].force[k - 15 : k + 15, 1] += 600.0  # a 30 ms impact (3 frames)
    loads = external_loads(MODEL, KIN, impact, cutoff_hz=6.0)
    assert loads.force_recorded is not None
    want = np.sum([p.force[idx] for p in impact], axis=0)
    np.testing.assert_allclose(loads.force_recorded, want, atol=1e-8)
    every = np.ones(TRIAL.time.size, dtype=bool)
    peak = peak_measured_force_n(loads, every)
    assert peak == pytest.approx(np.linalg.norm(want, axis=1).max())
    filtered = np.linalg.norm(np.nansum(loads.force, axis=1), axis=1).max()
    assert filtered < peak
    # taken over the given frames; a result built without it falls back on the filtered force
    half = TRIAL.time < 0.5
    assert peak_measured_force_n(loads, half) == pytest.approx(
        np.linalg.norm(want[half], axis=1).max()
    )
    bare = dataclasses.replace(loads, force_recorded=None)
    assert peak_measured_force_n(bare, every) == pytest.approx(filtered)
    assert loads.take(half).force_recorded.shape == (int(half.sum()), 3)


def test_foot_contact_finds_feet_on_an_unmarked_support_by_the_momentum_balance():
    """Standing still 0.2 m up on a box no plate measures (0.3–0.6 s; plates unloaded there):
    the feet are at no plate's or the floor's height, but the plates' vertical force is
    m g short of m (g + z̈_G) while they stand still, so both feet are in unmeasured contact
    inside the box's run (the kinematic jumps onto and off it aside); off the box every foot's
    contact is measured. With the momentum test off (``shortfall_bw`` = ∞) nothing on the box
    counts as contact (the behaviour before: torques computed without the box's reaction)."""
    from msk.dynamics.loads import contact_measured, foot_contact

    t = KIN.time
    q = np.repeat(TRIAL.q[:1], t.size, axis=0)
    box = (t > 0.3) & (t < 0.6)
    q[box, MODEL.coordinate_index("pelvis_ty")] += 0.2
    still = dataclasses.replace(KIN, q=q, v=np.zeros_like(q), a=np.zeros_like(q))
    loads = external_loads(
        MODEL, still, tuple(_unloaded_between(p, 0.3, 0.6) for p in TRIAL.plates)
    )
    c = foot_contact(MODEL, still, loads)
    inner = box & (t > 0.33) & (t < 0.57)
    assert c.unmeasured[inner].all() and c.standing()[inner].all()
    away = (t < 0.28) | (t > 0.62)  # the frames next to the jumps move (central differences)
    assert c.on_floor is not None and not c.on_floor[inner].any() and c.on_floor[away].all()
    assert not c.unmeasured[~box].any()
    np.testing.assert_array_equal(
        contact_measured(MODEL, still, loads), c.known & ~c.unmeasured.any(axis=1)
    )
    off = foot_contact(MODEL, still, loads, shortfall_bw=np.inf)
    assert not off.unmeasured.any()
