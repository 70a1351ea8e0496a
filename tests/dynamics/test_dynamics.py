"""Inverse dynamics, pelvis residuals, joint reactions: synthetic truth, identities, real data."""

from __future__ import annotations

import dataclasses
import importlib.util
import itertools

import numpy as np
import pinocchio as pin
import pytest

from msk.datasets.models import two_leg_model
from msk.datasets.opensim_subject01 import OPENSIM_IK_ID_SCRIPT, load_subject01, subject01_pipeline
from msk.datasets.trials import make_trial
from msk.dynamics.inverse import inverse_dynamics, joint_reaction, muscle_body_wrenches
from msk.dynamics.loads import external_loads, plates_from_table, plates_from_trial
from msk.exceptions import ModelError
from msk.kinematics.ik import kinematics_from_coordinates, solve_kinematics
from msk.model.core import Axis, Body, Joint
from msk.model.joints import FourBarKnee, FourBarTranslation, Linear

MODEL = two_leg_model()
TRIAL = make_trial(MODEL, duration_s=1.0, rate_hz=100.0)
KIN = dataclasses.replace(
    kinematics_from_coordinates(TRIAL.time, TRIAL.q, MODEL.coordinate_names, cutoff_hz=None),
    v=TRIAL.v,
    a=TRIAL.a,
)
LOADS = external_loads(MODEL, KIN, TRIAL.plates)
HAVE_OSIM = importlib.util.find_spec("msk.model.osim") is not None
NEEDS_OSIM = pytest.mark.skipif(
    not HAVE_OSIM, reason="msk.model.osim (OpenSim model import) missing"
)


def _report(tag: str, jt, truth) -> tuple[float, float, float]:
    legs = [i for i, c in enumerate(MODEL.coordinate_names) if c not in jt.root_coordinates]
    inner = slice(20, -20)  # 0.2 s at each end: start-up of the zero-lag filter
    rng = np.ptp(truth.tau_true[:, legs], axis=0)
    err = np.abs(jt.tau[inner][:, legs] - truth.tau_true[inner][:, legs]).max(axis=0) / rng
    rms = np.sqrt(np.mean((jt.tau[inner][:, legs] - truth.tau_true[inner][:, legs]) ** 2, 0))
    res_f = float(np.abs(jt.residual_force[inner]).max())
    res_m = float(np.abs(jt.residual_moment[inner]).max())
    rms_f = float(np.sqrt(np.mean(jt.residual_force[inner] ** 2)))
    rms_m = float(np.sqrt(np.mean(jt.residual_moment[inner] ** 2)))
    print(
        f"{tag}: max torque error {100 * err.max():.2f} % of range "
        f"({MODEL.coordinate_names[legs[int(np.argmax(err))]]}), RMS error "
        f"{100 * np.max(rms / rng):.2f} % of range at most ({np.max(rms):.2f} N·m); "
        f"residuals max {res_f:.3f} N, {res_m:.3f} N·m, RMS {rms_f:.3f} N, {rms_m:.3f} N·m"
    )
    return float(err.max()), res_f, res_m


def test_synthetic_c3d_trial_recovers_torques_and_zero_residuals(tmp_path):
    """Simulated motion → markers + two plates → C3D → read_c3d → IK → loads → ID."""
    from msk.io import read_c3d

    truth = make_trial(MODEL, duration_s=2.0, rate_hz=100.0)
    trial = read_c3d(truth.write_c3d(tmp_path / "truth.c3d"))
    kin = solve_kinematics(MODEL, trial.markers, trial.marker_labels, trial.time, cutoff_hz=10.0)
    assert (kin.status == 0).all()
    np.testing.assert_allclose(kin.q_raw, truth.q, atol=1e-6)
    loads = external_loads(MODEL, kin, plates_from_trial(trial))
    jt = inverse_dynamics(MODEL, kin, loads)
    err, res_f, res_m = _report("synthetic, no noise", jt, truth)
    assert err < 0.01
    assert res_f < 1.0 and res_m < 1.0


def test_synthetic_with_2mm_marker_noise_reports_errors(tmp_path):
    from msk.io import read_c3d

    truth = make_trial(MODEL, duration_s=2.0, rate_hz=100.0, noise_m=0.002, seed=7)
    trial = read_c3d(truth.write_c3d(tmp_path / "noisy.c3d"))
    kin = solve_kinematics(MODEL, trial.markers, trial.marker_labels, trial.time, cutoff_hz=6.0)
    loads = external_loads(MODEL, kin, plates_from_trial(trial))
    jt = inverse_dynamics(MODEL, kin, loads)
    err, res_f, res_m = _report("synthetic, 2 mm noise, 6 Hz", jt, truth)
    assert err < 0.15
    assert res_f < 30.0 and res_m < 10.0


def test_variants_match_pinocchio_dynamic_terms():
    full = inverse_dynamics(MODEL, KIN, LOADS)
    qs = inverse_dynamics(MODEL, KIN, LOADS, variant="quasi_static")
    geo = inverse_dynamics(MODEL, KIN, LOADS, variant="geometric")
    assert full.variant == "full" and qs.variant == "quasi_static"
    pm = MODEL.pin_model
    data = pm.createData()
    for k in (3, 50, 96):
        q, v, a = MODEL.coupling.embed(TRIAL.q[k], TRIAL.v[k], TRIAL.a[k])
        mass = pin.crba(pm, data, q)
        mass = np.triu(mass) + np.triu(mass, 1).T
        nle = pin.nonLinearEffects(pm, data, q, v)
        grav = pin.computeGeneralizedGravity(pm, data, q)
        np.testing.assert_allclose(
            full.tau_pin[k] - qs.tau_pin[k], mass @ a + nle - grav, atol=1e-9
        )
        np.testing.assert_allclose(qs.tau_pin[k] - geo.tau_pin[k], grav, atol=1e-9)
    with pytest.raises(ModelError, match="variant"):
        inverse_dynamics(MODEL, KIN, LOADS, variant="dynamic")  # type: ignore[arg-type]


def test_loads_fext_through_pinocchio_rnea_gives_the_same_torques():
    jt = inverse_dynamics(MODEL, KIN, LOADS)
    pm = MODEL.pin_model
    data = pm.createData()
    for k in (0, 61):
        q, v, a = MODEL.coupling.embed(TRIAL.q[k], TRIAL.v[k], TRIAL.a[k])
        pin.forwardKinematics(pm, data, q)
        tau = pin.rnea(pm, data, q, v, a, LOADS.fext(MODEL, data, k))
        np.testing.assert_allclose(jt.tau_pin[k], tau, atol=1e-9)


def test_residual_wrench_equals_the_root_generalised_forces():
    # a 2 kg error on the pelvis makes residuals appear
    pelvis = MODEL.body("pelvis")
    wrong = MODEL.with_bodies({"pelvis": Body("pelvis", 13.0, pelvis.com, pelvis.inertia)})
    jt = inverse_dynamics(wrong, KIN, LOADS)
    names = jt.root_coordinates
    assert names == ("pelvis_tx", "pelvis_ty", "pelvis_tz", "pelvis_tilt", "pelvis_list",
                     "pelvis_rotation")  # fmt: skip
    # translations along the world axes: τ = F; the first rotation (tilt, about world z) sees M_z
    np.testing.assert_allclose(jt.residuals[:, :3], jt.residual_force, atol=1e-9)
    np.testing.assert_allclose(jt.coordinate("pelvis_tilt"), jt.residual_moment[:, 2], atol=1e-9)
    assert np.abs(jt.residual_force[:, 1]).max() > 2.0 * 9.0  # ≈ 2 kg (g + a_y)
    # consistent model and plates: zero residuals
    ok = inverse_dynamics(MODEL, KIN, LOADS)
    assert np.abs(ok.residuals).max() < 1e-9
    np.testing.assert_allclose(ok.tau, TRIAL.tau_true, atol=1e-9)


def test_four_bar_knee_torque_is_projected_by_virtual_power():
    knee = FourBarKnee(
        (-0.010, -0.395), (0.008, -0.400), (0.012, -0.010), (-0.018, -0.022), p_ref=(0.0, -0.405)
    )
    four_bar = Joint(
        "knee_r",
        "femur_r",
        "tibia_r",
        axes=(
            Axis("prismatic", [1, 0, 0], "knee_angle_r", FourBarTranslation(knee, 0)),
            Axis("prismatic", [0, 1, 0], "knee_angle_r", FourBarTranslation(knee, 1)),
            Axis("revolute", [0, 0, 1], "knee_angle_r", Linear()),
        ),
    )
    model = MODEL.with_joints({"knee_r": four_bar})
    jt = inverse_dynamics(model, KIN, LOADS)
    _, v, _ = model.coupling.embed(TRIAL.q, TRIAL.v, TRIAL.a)
    power_pin = np.einsum("nk,nk->n", jt.tau_pin, v)
    power_theta = np.einsum("ni,ni->n", jt.tau, TRIAL.v)
    np.testing.assert_allclose(power_theta, power_pin, rtol=1e-10, atol=1e-9)


def _subtree_check(k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quasi-static free body of tibia + foot: force and moment (about the world origin) the
    femur must apply, computed from the segment weights and the right plate."""
    data = MODEL.create_data()
    pin.framesForwardKinematics(MODEL.pin_model, data, MODEL.coupling.q(TRIAL.q[k]))
    f = np.zeros(3)
    m = np.zeros(3)
    for body in ("tibia_r", "foot_r"):
        b = MODEL.body(body)
        c = data.oMf[MODEL.body_frame[body]].act(b.com)
        w = b.mass * MODEL.gravity
        f -= w
        m -= np.cross(c, w)
    i = LOADS.body_index("foot_r")
    f -= LOADS.force[k, i]
    m -= LOADS.moment[k, i]
    return f, m, data.oMf[MODEL.body_frame["tibia_r"]].homogeneous


def test_joint_reaction_is_the_free_body_load_of_the_distal_segments():
    world = joint_reaction(MODEL, KIN, LOADS, joint="knee_r", frame="world", variant="quasi_static")
    child = joint_reaction(MODEL, KIN, LOADS, joint="knee_r", frame="child", variant="quasi_static")
    tibia = joint_reaction(
        MODEL, KIN, LOADS, joint="knee_r", frame="tibia_r", variant="quasi_static"
    )
    offset = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, 0.3), np.array([0.0, -0.02, 0.0]))
    plateau = joint_reaction(
        MODEL, KIN, LOADS, joint="knee_r", frame="tibia_r", offset=offset, variant="quasi_static"
    )
    for k in (0, 44, 99):
        f, m, h = _subtree_check(k)
        np.testing.assert_allclose(world.force[k], f, atol=1e-9)
        np.testing.assert_allclose(world.moment[k], m, atol=1e-9)
        rot, org = h[:3, :3], h[:3, 3]
        # the tibia body frame is the child joint frame here (no child offset)
        np.testing.assert_allclose(child.force[k], rot.T @ f, atol=1e-9)
        np.testing.assert_allclose(tibia.moment[k], rot.T @ (m - np.cross(org, f)), atol=1e-9)
        r2 = rot @ offset.rotation
        o2 = org + rot @ offset.translation
        np.testing.assert_allclose(plateau.force[k], r2.T @ f, atol=1e-9)
        np.testing.assert_allclose(plateau.moment[k], r2.T @ (m - np.cross(o2, f)), atol=1e-9)
    # the last knee axis is a revolute z in the child joint frame: its τ is the z moment there
    jt = inverse_dynamics(MODEL, KIN, LOADS, variant="quasi_static")
    dof = MODEL.pin_model.joints[MODEL.pin_model.getJointId("knee_r_2")].idx_v
    np.testing.assert_allclose(child.moment[:, 2], jt.tau_pin[:, dof], atol=1e-9)
    with pytest.raises(ModelError, match="no joint 'elbow'"):
        joint_reaction(MODEL, KIN, LOADS, joint="elbow")


def _path_length(path, th):
    data = MODEL.create_data()
    pin.framesForwardKinematics(MODEL.pin_model, data, MODEL.coupling.q(th))
    pts = [data.oMf[MODEL.body_frame[b]].act(np.asarray(p)) for b, p in path]
    return sum(np.linalg.norm(b - a) for a, b in itertools.pairwise(pts))


def test_muscle_forces_remove_their_share_from_the_joint_reaction():
    # a vastus-like muscle: femur → via point on the femur → tibia (crosses the knee only)
    path = [("femur_r", [0.03, -0.15, 0.02]), ("femur_r", [0.05, -0.38, 0.0]),
            ("tibia_r", [0.04, -0.06, 0.0])]  # fmt: skip
    tension = np.full((TRIAL.time.size, 1), 800.0)
    base = inverse_dynamics(MODEL, KIN, LOADS)
    r0 = joint_reaction(MODEL, KIN, LOADS, joint="knee_r", frame="world")
    r1 = joint_reaction(
        MODEL, KIN, LOADS, joint="knee_r", frame="world", muscle_forces=tension,
        muscle_paths=[path],
    )  # fmt: skip
    assert r1.with_muscles and not r0.with_muscles
    bodies, fb, mb = muscle_body_wrenches(MODEL, TRIAL.q, tension, [path])
    i = bodies.index("tibia_r")
    # the reaction no longer carries the muscle's pull on the tibia
    np.testing.assert_allclose(r1.force, r0.force - fb[:, i], atol=1e-9)
    np.testing.assert_allclose(r1.moment, r0.moment - mb[:, i], atol=1e-9)
    # internal forces: the total wrench on the body is unchanged
    np.testing.assert_allclose(fb.sum(axis=1), 0.0, atol=1e-9)
    # generalised force of the muscle: Q = −T ∂L/∂θ (finite differences of the path length)
    k = 31
    ik = MODEL.coordinate_index("knee_angle_r")
    e = np.zeros(MODEL.n_coords)
    e[ik] = 1e-6
    dl = (_path_length(path, TRIAL.q[k] + e) - _path_length(path, TRIAL.q[k] - e)) / 2e-6
    from msk.dynamics.inverse import _run_rnea, _states

    th, q, v, a, ok = _states(MODEL, KIN, "full")
    tau_pin, *_ = _run_rnea(
        MODEL, MODEL.pin_model, q, v, a, ok, LOADS,
        muscle_w=muscle_body_wrenches(MODEL, th, tension, [path]),
    )  # fmt: skip
    tau1 = MODEL.coupling.project(th[k], tau_pin[k])
    np.testing.assert_allclose(tau1[ik] - base.tau[k, ik], 800.0 * dl, rtol=1e-6)
    hip = MODEL.coordinate_index("hip_flexion_r")
    assert abs(tau1[hip] - base.tau[k, hip]) < 1e-8  # one-joint muscle: the hip is untouched


# ---------------------------------------------------------------------------------------------
# real data
# ---------------------------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.realdata
@NEEDS_OSIM
def test_subject01_10dof_id_matches_opensim_reference(real_dir, ref_dir):
    """OpenSim's subject01 walk (gait10dof18musc): OpenSim's IK angles → msk ID vs its ID."""
    from msk.io.opensim_files import read_sto
    from msk.model.osim import load_osim

    folder = real_dir / "opensim-subject01-walk"
    model = load_osim(ref_dir / "opensim-core" / "gait10dof18musc_subject01.osim")
    ik = read_sto(folder / "subject01_walk_IK.mot")
    grf = read_sto(folder / "subject01_walk_grf.mot")
    ref = read_sto(folder / "subject01_walk_ID.sto")
    kin = kinematics_from_coordinates(ik.time, ik.data, ik.columns, cutoff_hz=6.0, model=model)
    loads = external_loads(model, kin, plates_from_table(grf.time, grf.data, grf.columns))
    assert {(a.plate, a.body) for a in loads.assignments} == {
        ("plate1", "calcn_r"),
        ("plate2", "calcn_l"),
    }
    jt = inverse_dynamics(model, kin, loads)
    inner = (ref.time > 0.1) & (ref.time < 2.4)
    for c in ("hip_flexion_r", "knee_angle_r", "ankle_angle_r", "hip_flexion_l", "knee_angle_l",
              "ankle_angle_l"):  # fmt: skip
        d = np.interp(ref.time, kin.time, jt.coordinate(c)) - ref.column(c + "_moment")
        rms = float(np.sqrt(np.mean(d[inner] ** 2)))
        print(f"10-dof {c}: RMS difference to OpenSim {rms:.2f} N·m")
        assert rms < 2.0


def _subject01_or_skip():
    pipe = subject01_pipeline()
    if not (pipe / "subject01_walk1.trc").is_file():  # pragma: no cover - shared folder
        pytest.skip(f"OpenSim peer data absent: {pipe}")
    return load_subject01()


@pytest.mark.slow
@pytest.mark.realdata
@NEEDS_OSIM
def test_subject01_gait2392_ik_and_id_against_opensim_reference():
    from msk.io.opensim_files import read_sto
    from msk.model.core import marker_positions

    s = _subject01_or_skip()
    sel = (s.trc_time >= 0.5 - 1e-6) & (s.trc_time <= 2.5 + 1e-6)
    kin = solve_kinematics(
        s.model, s.markers[sel], s.marker_labels, s.trc_time[sel],
        weights=s.weights, coordinate_tasks=s.coordinate_tasks,
    )  # fmt: skip
    assert (kin.status == 0).all()
    # OpenSim's reference IK on the same frames: its marker RMS with the same markers
    osel = (s.ik_time >= 0.5 - 1e-6) & (s.ik_time <= 2.5 + 1e-6)
    q_os = s.ik_q[osel]
    pos = marker_positions(s.model, q_os)
    cols = [s.model.marker_names.index(n) for n in kin.marker_names]
    meas = s.markers[sel][:, [s.marker_labels.index(n) for n in kin.marker_names]]
    d = np.linalg.norm(pos[:, cols] - meas, axis=2)
    rms_os = np.sqrt(np.nanmean(d**2, axis=1))
    print(
        f"gait2392 IK marker RMS: msk {1000 * np.mean(kin.marker_rms):.2f} mm, "
        f"OpenSim {1000 * np.mean(rms_os):.2f} mm; worst marker {set(kin.marker_max_name)}"
    )
    assert np.mean(kin.marker_rms) <= np.mean(rms_os) + 1e-4
    dq = np.rad2deg(np.sqrt(np.mean((kin.q_raw - q_os) ** 2, axis=0)))
    rot = [c.kind == "rotational" for c in s.model.coordinates]
    print(f"gait2392 IK vs OpenSim: max RMS angle difference {dq[rot].max():.4f} deg")
    assert dq[rot].max() < 0.05

    ref = read_sto(s.reference_id_path)
    inner = (ref.time > 0.55) & (ref.time < 1.6)
    for tag, q in (("OpenSim IK", q_os), ("msk IK", kin.q_raw)):
        k = kinematics_from_coordinates(kin.time, q, s.model.coordinate_names, cutoff_hz=6.0)
        loads = external_loads(s.model, k, s.plates)
        jt = inverse_dynamics(s.model, k, loads)
        for c in ("hip_flexion_r", "knee_angle_r", "ankle_angle_r"):
            diff = np.interp(ref.time, k.time, jt.coordinate(c)) - ref.column(c + "_moment")
            rms = float(np.sqrt(np.mean(diff[inner] ** 2)))
            print(f"gait2392 ({tag}) {c}: RMS difference to OpenSim's reference ID {rms:.2f} N·m")
            assert rms < 2.0


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.opensim
@NEEDS_OSIM
def test_subject01_gait2392_ik_and_id_live_against_opensim_4_6(needs_opensim, tmp_path):
    """OpenSim 4.6 IK + ID (6 Hz) run now in a child process on the same files as msk."""
    from msk._runtime.opensim_peer import run_opensim_script

    s = _subject01_or_skip()
    out = run_opensim_script(
        OPENSIM_IK_ID_SCRIPT, pipe=str(s.pipeline), trc=str(s.pipeline / "subject01_walk1.trc"),
        out=str(tmp_path), grf=str(s.pipeline / "subject01_walk1_grf.mot"), t0=0.5, t1=2.5,
        cutoff_hz=6.0,
    )  # fmt: skip
    # IK: msk vs OpenSim on the same markers, weights and coordinate tasks
    sel = (s.trc_time >= 0.5 - 1e-6) & (s.trc_time <= 2.5 + 1e-6)
    kin = solve_kinematics(
        s.model, s.markers[sel], s.marker_labels, s.trc_time[sel],
        weights=s.weights, coordinate_tasks=s.coordinate_tasks,
    )  # fmt: skip
    labels = out["ik_labels"]
    q_os = np.asarray(out["ik_data"])[:, [labels.index(c) for c in s.model.coordinate_names]]
    rot = [c.kind == "rotational" for c in s.model.coordinates]
    q_os[:, rot] = np.deg2rad(q_os[:, rot])
    assert q_os.shape == kin.q_raw.shape
    dq = np.rad2deg(np.sqrt(np.mean((kin.q_raw - q_os) ** 2, axis=0)))[rot]
    worst = np.array(s.model.coordinate_names)[rot][int(np.argmax(dq))]
    print(
        f"gait2392 IK vs OpenSim 4.6 IK (live): max RMS angle difference {dq.max():.4f} deg "
        f"({worst})"
    )
    assert dq.max() < 0.05
    # ID: msk on OpenSim's own IK output vs OpenSim's ID of it
    t_os = np.asarray(out["id_time"])
    d_os = np.asarray(out["id_data"])
    k6 = kinematics_from_coordinates(kin.time, q_os, s.model.coordinate_names, cutoff_hz=6.0)
    jt = inverse_dynamics(s.model, k6, external_loads(s.model, k6, s.plates))
    inner = (t_os > 0.55) & (t_os < 2.45)
    for c in ("hip_flexion_r", "hip_adduction_r", "knee_angle_r", "ankle_angle_r"):
        o = d_os[:, out["id_labels"].index(c + "_moment")]
        diff = np.interp(t_os, k6.time, jt.coordinate(c)) - o
        rms = float(np.sqrt(np.mean(diff[inner] ** 2)))
        print(f"gait2392 {c}: RMS difference to OpenSim 4.6 ID (live) {rms:.2f} N·m")
        assert rms < 2.0


def test_without_unmeasured_contact_blanks_only_the_leg_whose_reaction_is_missing():
    """A missing ground reaction under the right foot (frames 10–19) falsifies the torques of
    the right leg's joints only (RNEA: a joint's torque balances its distal subtree): those are
    NaN there; the left leg's and the pelvis residuals (root rows) are kept, as every frame
    outside."""
    from msk.dynamics.inverse import coordinates_carrying, without_unmeasured_contact

    kin = kinematics_from_coordinates(TRIAL.time, TRIAL.q, MODEL.coordinate_names, cutoff_hz=None)
    kin = dataclasses.replace(kin, v=TRIAL.v, a=TRIAL.a)
    jt = inverse_dynamics(MODEL, kin, external_loads(MODEL, kin, TRIAL.plates))
    right = set(coordinates_carrying(MODEL, "foot_r")) - set(jt.root_coordinates)
    assert right == {c for c in MODEL.coordinate_names if c.endswith("_r")}
    miss = np.zeros((TRIAL.time.size, 2), dtype=bool)
    miss[10:20, 0] = True
    out = without_unmeasured_contact(MODEL, jt, miss, ("foot_r", "foot_l"))
    cols = [jt.coordinate_names.index(c) for c in right]
    assert np.isnan(out.tau[10:20][:, cols]).all()
    keep = np.ones(out.tau.shape, dtype=bool)
    keep[np.ix_(np.arange(10, 20), cols)] = False
    np.testing.assert_array_equal(out.tau[keep], jt.tau[keep])
