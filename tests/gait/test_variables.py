"""Gait variables: the external knee adduction moment against closed-form and independent
Newton–Euler computations, joint angles and powers from known coordinates, cycles."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pinocchio as pin
import pytest
from scipy.spatial.transform import Rotation

from msk.datasets.models import two_leg_model
from msk.dynamics.loads import ExternalLoads
from msk.gait.variables import (
    gait_cycles,
    gait_variables,
    hip_angles,
    knee_adduction_moment,
    pelvis_marker_frame,
)

MODEL = two_leg_model()
NAMES = MODEL.coordinate_names
MASS = 70.0


def _kin(q, v=None, a=None, dt=0.01):
    q = np.atleast_2d(q)
    n = q.shape[0]
    return SimpleNamespace(
        time=np.arange(n) * dt,
        q=q,
        v=np.zeros_like(q) if v is None else v,
        a=np.zeros_like(q) if a is None else a,
        coordinate_names=NAMES,
    )


def _q0(**coords):
    q = np.zeros(len(NAMES))
    q[NAMES.index("pelvis_ty")] = 0.93
    for k, x in coords.items():
        q[NAMES.index(k)] = x
    return q


def _loads(time, body, force, point):
    n = time.size
    f = np.broadcast_to(force, (n, 3)).copy()
    p = np.broadcast_to(point, (n, 3)).copy()
    return ExternalLoads(
        time=time, bodies=(body,), force=f[:, None], moment=np.cross(p, f)[:, None],
        point=p[:, None],
    )  # fmt: skip


def _pose(q, body):
    data = MODEL.create_data()
    pin.framesForwardKinematics(MODEL.pin_model, data, MODEL.coupling.q(q[None])[0])
    return data.oMf[MODEL.body_frame[body]]


@pytest.mark.parametrize("side", ["right", "left"])
def test_kam_closed_form_force_medial_to_the_knee(side):
    """Upright leg, vertical reaction F under the knee shifted medially by d: KAM = F d / m
    (the segments' weights act in the knee's sagittal plane: no frontal moment)."""
    s = 1.0 if side == "right" else -1.0
    sfx = "_r" if side == "right" else "_l"
    q = _q0()
    kin = _kin(q)
    knee = _pose(q, "tibia" + sfx).translation
    d, F = 0.04, 700.0
    point = knee + np.array([0.0, -0.45, -s * d])  # medial: toward the midline
    loads = _loads(kin.time, "foot" + sfx, np.array([0.0, F, 0.0]), point)
    kam = knee_adduction_moment(MODEL, kin, loads, side, mass_kg=MASS)
    assert kam is not None
    assert kam[0] == pytest.approx(F * d / MASS, rel=1e-9)


def test_kam_equals_statics_of_the_distal_segments_in_any_pose():
    """Static, any pose: −M_internal = (P − K) × F + Σ_b (c_b − K) × m_b g about the knee, on
    the tibia's anterior axis (an independent free-body computation, no RNEA)."""
    rng = np.random.default_rng(4)
    for _ in range(5):
        q = _q0(
            hip_flexion_r=rng.uniform(-0.3, 0.8),
            hip_adduction_r=rng.uniform(-0.3, 0.3),
            hip_rotation_r=rng.uniform(-0.3, 0.3),
            knee_angle_r=rng.uniform(-1.2, 0.0),
            ankle_angle_r=rng.uniform(-0.3, 0.3),
            pelvis_list=rng.uniform(-0.1, 0.1),
        )
        kin = _kin(q)
        F = rng.normal(0, 100, 3) + np.array([0.0, 700.0, 0.0])
        P = _pose(q, "foot_r").translation + rng.normal(0, 0.05, 3)
        loads = _loads(kin.time, "foot_r", F, P)
        tib = _pose(q, "tibia_r")
        K = tib.translation
        g = np.asarray(MODEL.gravity)
        m_ext = np.cross(P - K, F)
        for b in ("tibia_r", "foot_r"):
            body = next(x for x in MODEL.bodies if x.name == b)
            c = _pose(q, b).act(body.com)
            m_ext += np.cross(c - K, body.mass * g)
        kam = knee_adduction_moment(MODEL, kin, loads, "right", mass_kg=MASS)
        assert kam is not None
        assert kam[0] == pytest.approx(tib.rotation[:, 0] @ m_ext / MASS, rel=1e-8, abs=1e-10)


def test_kam_matches_newton_euler_with_finite_differences_in_motion():
    """Swinging leg, no ground reaction: M_pc + Σ (c_b − K) × m_b g = Σ_b [Ḣ_b + (c_b − K) ×
    m_b c̈_b] about the moving knee centre, Ḣ_b = d/dt(R I Rᵀ ω) and c̈_b by central differences."""
    dt = 1e-4
    t = np.arange(-3, 4) * dt + 0.3
    w = 2 * np.pi
    coords = {"hip_flexion_r": 0.4 * np.sin(w * t), "hip_adduction_r": 0.1 * np.sin(2 * w * t),
              "knee_angle_r": -0.6 + 0.5 * np.sin(w * t), "ankle_angle_r": 0.2 * np.cos(w * t),
              "pelvis_tx": 1.2 * t, "pelvis_list": 0.05 * np.sin(w * t)}  # fmt: skip
    dcoords = {"hip_flexion_r": 0.4 * w * np.cos(w * t),
               "hip_adduction_r": 0.2 * w * np.cos(2 * w * t),
               "knee_angle_r": 0.5 * w * np.cos(w * t), "ankle_angle_r": -0.2 * w * np.sin(w * t),
               "pelvis_tx": 1.2 + 0 * t, "pelvis_list": 0.05 * w * np.cos(w * t)}  # fmt: skip
    ddcoords = {"hip_flexion_r": -0.4 * w**2 * np.sin(w * t),
                "hip_adduction_r": -0.4 * w**2 * np.sin(2 * w * t),
                "knee_angle_r": -0.5 * w**2 * np.sin(w * t),
                "ankle_angle_r": -0.2 * w**2 * np.cos(w * t), "pelvis_tx": 0 * t,
                "pelvis_list": -0.05 * w**2 * np.sin(w * t)}  # fmt: skip
    q = np.array([_q0(**{k: x[i] for k, x in coords.items()}) for i in range(t.size)])
    v = np.zeros_like(q)
    a = np.zeros_like(q)
    for k in coords:
        v[:, NAMES.index(k)] = dcoords[k]
        a[:, NAMES.index(k)] = ddcoords[k]
    kin = SimpleNamespace(time=t, q=q, v=v, a=a, coordinate_names=NAMES)
    kam = knee_adduction_moment(MODEL, kin, None, "right", mass_kg=1.0)
    assert kam is not None
    i = 3  # the middle frame
    g = np.asarray(MODEL.gravity)
    tib = [_pose(q[j], "tibia_r") for j in range(t.size)]
    K = tib[i].translation
    rhs = np.zeros(3)
    for b in ("tibia_r", "foot_r"):
        body = next(x for x in MODEL.bodies if x.name == b)
        poses = [_pose(q[j], b) for j in range(t.size)]
        c = np.array([p.act(body.com) for p in poses])
        cdd = (c[i + 1] - 2 * c[i] + c[i - 1]) / dt**2
        R = np.array([p.rotation for p in poses])

        def h(j, R=R, body=body):
            rd = (R[j + 1] - R[j - 1]) / (2 * dt)
            om = rd @ R[j].T
            omega = np.array([om[2, 1], om[0, 2], om[1, 0]])
            return R[j] @ body.inertia @ R[j].T @ omega

        hdot = (h(i + 1) - h(i - 1)) / (2 * dt)
        rhs += hdot + np.cross(c[i] - K, body.mass * cdd) - np.cross(c[i] - K, body.mass * g)
    # external moment about K = −M_pc = −rhs; KAM (right) = x_tibia · M_ext
    expected = -(tib[i].rotation[:, 0] @ rhs)
    assert kam[i] == pytest.approx(expected, rel=1e-4, abs=1e-4)


def test_angles_moments_and_powers_from_known_coordinates():
    q = np.array([_q0(hip_flexion_r=0.3, knee_angle_r=-0.5, ankle_angle_l=0.1)] * 3)
    v = np.zeros_like(q)
    v[:, NAMES.index("knee_angle_r")] = 2.0
    tau = np.zeros_like(q)
    tau[:, NAMES.index("knee_angle_r")] = 35.0
    tau[:, NAMES.index("ankle_angle_l")] = -70.0
    torques = SimpleNamespace(coordinate_names=NAMES, tau=tau)
    gv = gait_variables(MODEL, _kin(q, v), torques=torques, mass_kg=MASS)
    r, left = gv.series["right"], gv.series["left"]
    assert r["hip_flexion_deg"][0] == pytest.approx(np.rad2deg(0.3))
    assert r["knee_flexion_deg"][0] == pytest.approx(np.rad2deg(0.5))
    assert left["ankle_dorsiflexion_deg"][0] == pytest.approx(np.rad2deg(0.1))
    assert r["knee_extension_moment_nm_kg"][0] == pytest.approx(0.5)
    assert left["ankle_plantarflexion_moment_nm_kg"][0] == pytest.approx(1.0)
    assert r["knee_power_w_kg"][0] == pytest.approx(1.0)
    assert "knee_adduction_deg" in gv.not_modelled


def test_cycles_of_a_synthetic_walk_pelvis_and_foot_progression():
    """Walking along a heading of 40° with a known pelvis obliquity and toe-out: the angles are
    relative to the progression direction, each side from its own side."""
    t = np.arange(0.0, 3.0, 0.01)
    heading = np.deg2rad(40.0)
    q = np.array([_q0() for _ in t])
    q[:, NAMES.index("pelvis_tx")] = 1.2 * t * np.cos(heading)
    q[:, NAMES.index("pelvis_tz")] = -1.2 * t * np.sin(heading)
    # the pelvis' Plug-in Gait frame (its markers' ASIS–PSIS plane, R_body R_m): R_y(heading)
    # R_x(5°) (right side down); the body's rotation R_body = R Rmᵀ in the model's
    # tilt-list-rotation
    r_m, _ = pelvis_marker_frame(MODEL)
    r_pig = Rotation.from_euler("YX", [heading, np.deg2rad(5.0)]).as_matrix()
    tilt, lst, rot = Rotation.from_matrix(r_pig @ r_m.T).as_euler("ZXY")
    q[:, NAMES.index("pelvis_tilt")] = tilt
    q[:, NAMES.index("pelvis_list")] = lst
    q[:, NAMES.index("pelvis_rotation")] = rot
    q[:, NAMES.index("hip_rotation_r")] = np.deg2rad(-10.0)  # external: toe out
    q[:, NAMES.index("knee_angle_r")] = -0.5 * (1 - np.cos(2 * np.pi * t / 1.1))
    kin = _kin(q)
    strikes = {"right": (0.2, 1.3, 2.4), "left": (0.75, 1.85)}
    offs = {"right": (0.87, 1.97), "left": (1.42, 2.52)}
    cyc, _ = gait_cycles(MODEL, kin, strikes, offs, mass_kg=MASS, trial="walk")
    assert cyc.right.n_cycles == 2 and cyc.left.n_cycles == 1
    assert cyc.right.foot_off_pct == pytest.approx([100 * 0.67 / 1.1] * 2)
    assert not cyc.right.measured.any()  # no kinetics
    m = cyc.mean("right")
    assert m[:, cyc.index("pelvis_obliquity_deg")] == pytest.approx(-5.0, abs=1e-6)
    assert cyc.mean("left")[:, cyc.index("pelvis_obliquity_deg")] == pytest.approx(5.0, abs=1e-6)
    assert m[:, cyc.index("pelvis_tilt_deg")] == pytest.approx(0.0, abs=1e-6)
    assert m[:, cyc.index("pelvis_rotation_deg")] == pytest.approx(0.0, abs=1e-6)
    # foot progression, pelvis level: toe-out (negative) by the hip's external rotation
    q[:, NAMES.index("pelvis_tilt")] = 0.0
    q[:, NAMES.index("pelvis_list")] = 0.0
    q[:, NAMES.index("pelvis_rotation")] = heading
    level, _ = gait_cycles(MODEL, _kin(q), strikes, offs, mass_kg=MASS)
    fpa = level.mean("right")[:, level.index("foot_progression_deg")]
    assert fpa == pytest.approx(-10.0, abs=1e-6)
    assert level.mean("left")[:, level.index("foot_progression_deg")] == pytest.approx(0, abs=1e-6)
    knee = m[:, cyc.index("knee_flexion_deg")]
    assert knee[0] == pytest.approx(np.rad2deg(0.5 * (1 - np.cos(2 * np.pi * 0.2 / 1.1))), abs=0.2)


def test_kam_of_a_long_trial_is_computed_block_by_block(monkeypatch):
    """The same values in blocks (the memory bound of long trials) as in one pass."""
    import msk.dynamics.inverse as inverse
    from msk.kinematics.ik import Kinematics

    rng = np.random.default_rng(5)
    n = 7
    q = np.array([_q0(knee_angle_r=-x, hip_adduction_r=0.1 * x) for x in rng.uniform(0, 1, n)])
    z = np.zeros(n)
    kin = Kinematics(
        time=np.arange(n) * 0.01, q=q, v=0 * q, a=0 * q, coordinate_names=NAMES, q_raw=q,
        status=np.zeros(n, np.int64), marker_rms=z, marker_max=z, marker_max_name=("",) * n,
        marker_errors=np.zeros((n, 0)), marker_names=(), n_markers_used=np.zeros(n, np.int64),
        iterations=np.zeros(n, np.int64),
    )  # fmt: skip
    loads = _loads(kin.time, "foot_r", np.array([10.0, 600.0, -20.0]), np.array([0.3, 0, 0.1]))
    whole = knee_adduction_moment(MODEL, kin, loads, "right", mass_kg=MASS)
    monkeypatch.setattr(inverse, "ID_BLOCK", 3)
    blocks = knee_adduction_moment(MODEL, kin, loads, "right", mass_kg=MASS)
    assert whole is not None and blocks is not None
    assert np.array_equal(whole, blocks)


def test_pelvis_tilt_is_plug_in_gaits_the_asis_psis_line():
    """The model's pelvis body level (pelvis_tilt = 0) with its PSIS markers 30 mm above its
    ASIS, 170 mm behind: Plug-in Gait's tilt (of the ASIS–PSIS line) is atan(30/170) = 10.0°
    anterior, whatever the model's body frame; a pelvis without PSIS or sacral marker gives
    the body frame's tilt (0°), and the notes say which frame."""
    from msk.model.core import Marker

    t = np.arange(0.0, 2.5, 0.01)
    q = np.array([_q0(pelvis_tx=1.2 * x) for x in t])
    strikes = {"right": (0.2, 1.3), "left": (0.75, 1.85)}
    offs = {"right": (0.87, 1.97), "left": (1.42, 2.52)}
    cyc, _ = gait_cycles(MODEL, _kin(q), strikes, offs, mass_kg=MASS)
    tilt = cyc.mean("right")[:, cyc.index("pelvis_tilt_deg")]
    assert tilt == pytest.approx(np.degrees(np.arctan2(0.03, 0.17)), abs=1e-6)
    assert any("Plug-in Gait's pelvis" in n and "+10.0°" in n for n in cyc.notes)
    bare = MODEL.with_markers([m for m in MODEL.markers if "PSI" not in m.name])
    cyc0, _ = gait_cycles(bare, _kin(q), strikes, offs, mass_kg=MASS)
    assert cyc0.mean("right")[:, cyc0.index("pelvis_tilt_deg")] == pytest.approx(0.0, abs=1e-6)
    assert any("body frame (no PSIS pair nor sacral" in n for n in cyc0.notes)
    sacral = MODEL.with_markers([*bare.markers, Marker("SACR", "pelvis", [-0.17, 0.03, 0.0])])
    r_m, how = pelvis_marker_frame(sacral)
    assert r_m is not None and "sacral marker SACR" in how


@pytest.mark.parametrize("side", ["right", "left"])
def test_hip_angles_recover_a_known_thigh_in_any_pelvis(side):
    """Thigh posed from known Plug-in Gait hip angles (YXZ Cardan, z-x'-y'' in the model's
    axes) in randomly turned pelvis frames: flexion, adduction and internal rotation
    recovered, each side from its own side (adduction and rotation mirrored on the left)."""
    s = 1.0 if side == "right" else -1.0
    rng = np.random.default_rng(3)
    n = 20
    truth = np.column_stack(
        [rng.uniform(-20, 60, n), rng.uniform(-15, 15, n), rng.uniform(-30, 30, n)]
    )
    pelvis = Rotation.random(n, random_state=4).as_matrix()
    rel = Rotation.from_euler(
        "ZXY", np.deg2rad(truth * [1.0, s, s])
    ).as_matrix()  # flexion about z, adduction about x' (+ on the right), rotation about y''
    thigh = np.einsum("nij,njk->nik", pelvis, rel)
    thigh[5] = np.nan  # a failed frame stays NaN
    h = hip_angles(pelvis, thigh, side)
    got = np.column_stack([h["hip_flexion_deg"], h["hip_adduction_deg"], h["hip_rotation_deg"]])
    assert np.isnan(got[5]).all()
    ok = np.arange(n) != 5
    assert got[ok] == pytest.approx(truth[ok], abs=1e-9)


def test_hip_flexion_is_relative_to_the_reported_pelvis_frame():
    """The model's pelvis body tilted 8° posterior with its PSIS markers 30 mm above its ASIS,
    170 mm behind (Plug-in Gait's pelvis 10.0° anterior of the body) and the right hip flexed
    0.3 rad: the reported pelvis tilt is 10.0 − 8 = 2.0° anterior, the hip flexion 0.3 rad +
    10.0°, and hip flexion − anterior tilt is the thigh's inclination (0.3 rad + 8°); the
    frontal and transverse hip angles zero. Without PSIS markers: the model's coordinates."""
    t = np.arange(0.0, 2.5, 0.01)
    q = np.array(
        [_q0(pelvis_tx=1.2 * x, pelvis_tilt=np.deg2rad(8.0), hip_flexion_r=0.3) for x in t]
    )
    strikes = {"right": (0.2, 1.3), "left": (0.75, 1.85)}
    offs = {"right": (0.87, 1.97), "left": (1.42, 2.52)}
    cyc, gv = gait_cycles(MODEL, _kin(q), strikes, offs, mass_kg=MASS)
    m = cyc.mean("right")
    tilt_m = np.degrees(np.arctan2(0.03, 0.17))
    assert m[:, cyc.index("pelvis_tilt_deg")] == pytest.approx(tilt_m - 8.0, abs=1e-6)
    hip = m[:, cyc.index("hip_flexion_deg")]
    assert hip == pytest.approx(np.degrees(0.3) + tilt_m, abs=1e-6)
    thigh = hip - m[:, cyc.index("pelvis_tilt_deg")]
    assert thigh == pytest.approx(np.degrees(0.3) + 8.0, abs=1e-6)
    assert m[:, cyc.index("hip_adduction_deg")] == pytest.approx(0.0, abs=1e-6)
    assert m[:, cyc.index("hip_rotation_deg")] == pytest.approx(0.0, abs=1e-6)
    assert gv.series["right"]["hip_flexion_deg"][0] == pytest.approx(hip[0], abs=1e-6)
    assert any("hip angles: the thigh relative to the pelvis frame" in n for n in cyc.notes)
    bare = MODEL.with_markers([mk for mk in MODEL.markers if "PSI" not in mk.name])
    cyc0, _ = gait_cycles(bare, _kin(q), strikes, offs, mass_kg=MASS)
    hip0 = cyc0.mean("right")[:, cyc0.index("hip_flexion_deg")]
    assert hip0 == pytest.approx(np.degrees(0.3), abs=1e-6)
