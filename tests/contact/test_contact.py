"""Knee contact force from the tibia free-body diagram (msk.contact.knee, seed 004 §2.1)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msk.contact.knee import (
    CONTACT_COLUMNS,
    G0,
    INTERCONDYLAR_DISTANCE_M,
    PLATEAU_DEPTH_M,
    KneeContact,
    MedialLateral,
    PlateauGeometry,
    knee_contact_force,
    muscle_distal_wrenches,
    plateau_geometry,
    split_medial_lateral,
)
from msk.datasets.models import leg_model
from msk.dynamics.inverse import joint_reaction
from msk.exceptions import ModelError, ShapeMismatchError
from msk.kinematics.ik import kinematics_from_coordinates
from msk.model.core import Model
from msk.muscles.geometry import muscle_geometry
from msk.muscles.path import ConditionalPathPoint, Muscle, PathPoint, PathWrap, WrapObject
from tests.support.knees import HIP, femur_tibia
from tests.support.legacy_contact import legacy_knee_contact_force

M_SHANK = 4.0
COM = np.array([0.01, -0.22, 0.0])  # shank COM in the tibia frame
ORIGIN = np.array([0.03, 0.20, 0.01])  # quadriceps origin on the femur (femur frame)
INSERT = np.array([0.045, -0.07, 0.0])  # patellar-tendon insertion on the tibia


def _pt(name: str, body: str, xyz) -> PathPoint:
    return PathPoint(name, body, np.asarray(xyz, dtype=float))


def _muscle(name: str, points, wraps=()) -> Muscle:
    return Muscle(name, tuple(points), 3000.0, 0.1, 0.2, 0.0, 10.0, wraps=tuple(wraps))


def seated_shank() -> Model:
    """A femur welded to the ground (knee centre at ``HIP``), a shank on a revolute knee about
    z and one quadriceps from the femur to the tibial tuberosity: the leg-extension bench."""
    model = femur_tibia("knee", shank_mass_kg=M_SHANK, shank_com=tuple(COM))
    return model.with_muscles(
        [_muscle("quad", [_pt("o", "femur", ORIGIN), _pt("i", "tibia", INSERT)])]
    )


def _rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _static(model: Model, q: np.ndarray):
    q = np.atleast_2d(np.asarray(q, dtype=float))
    t = np.arange(q.shape[0]) * 0.01
    return kinematics_from_coordinates(t, q, model.coordinate_names, cutoff_hz=None)


@settings(max_examples=25, deadline=None)
@given(theta=st.floats(-1.4, 1.4), f_extra=st.floats(0.0, 2000.0))
def test_single_quadriceps_holding_the_shank_is_solved_by_hand(
    theta: float, f_extra: float
) -> None:
    """Static shank held by one muscle: contact = −(weight) − (muscle pull), by hand."""
    model = seated_shank()
    r = _rz(theta)
    g = np.array([0.0, -G0, 0.0])
    p_ins = HIP + r @ INSERT
    u = (HIP + ORIGIN - p_ins) / np.linalg.norm(HIP + ORIGIN - p_ins)  # pull on the tibia
    arm = np.cross(r @ INSERT, u)[2]
    weight_moment = np.cross(r @ COM, M_SHANK * g)[2]
    f_hold = max(-weight_moment / arm, 0.0) + f_extra  # the equilibrium tension, plus extra
    kin = _static(model, [[theta]] * 3)
    out = knee_contact_force(
        model, kin, muscle_forces=np.full((3, 1), f_hold), joint="knee", variant="quasi_static"
    )
    force_w = -M_SHANK * g - f_hold * u
    moment_w = -np.cross(r @ COM, M_SHANK * g) - np.cross(r @ INSERT, f_hold * u)
    np.testing.assert_allclose(out.force, np.tile(r.T @ force_w, (3, 1)), atol=1e-9)
    np.testing.assert_allclose(out.moment, np.tile(r.T @ moment_w, (3, 1)), atol=1e-9)
    f_t = r.T @ force_w
    np.testing.assert_allclose(out.normal, -f_t[1], atol=1e-9)
    np.testing.assert_allclose(out.tangential, np.hypot(f_t[0], f_t[2]), atol=1e-9)
    np.testing.assert_allclose(out.total, np.linalg.norm(force_w), atol=1e-9)
    bw = (7.0 + M_SHANK) * G0
    np.testing.assert_allclose(out.total_bw, np.linalg.norm(force_w) / bw, atol=1e-12)
    if f_extra == 0.0 and -weight_moment / arm > 0:
        # holding exactly: the joint carries no moment about its axis
        assert abs(out.moment[0, 2]) < 1e-8


def test_quadriceps_in_extension_compresses_the_plateau() -> None:
    model = seated_shank()
    kin = _static(model, [[0.0], [-0.3], [-1.2]])
    out = knee_contact_force(
        model, kin, muscle_forces=np.full((3, 1), 1500.0), joint="knee", variant="quasi_static"
    )
    assert isinstance(out, KneeContact) and out.columns == CONTACT_COLUMNS
    assert out.values.shape == (3, len(CONTACT_COLUMNS))
    assert np.all(out.column("normal_n") > 800.0)  # the tendon pulls the tibia onto the femur
    np.testing.assert_allclose(out.in_body_weights(), out.values / out.body_weight_n)
    with pytest.raises(ModelError, match="no column"):
        out.column("medial_n")


def _moving_leg():
    """The pelvis–femur–tibia–foot test leg with static-path muscles (no moving points, no
    wraps), and a smooth motion."""
    model = leg_model()
    muscles = [
        _muscle(
            "glut",
            [_pt("o", "pelvis", [-0.04, 0.03, 0.12]), _pt("i", "femur", [-0.02, -0.01, 0.055])],
        ),
        _muscle(
            "quad",
            [
                _pt("o", "femur", [0.029, -0.192, 0.031]),
                _pt("v", "femur", [0.035, -0.36, 0.002]),
                _pt("i", "tibia", [0.045, -0.06, 0.0]),
            ],
        ),
        _muscle(
            "ham",
            [
                _pt("o", "pelvis", [-0.12, -0.10, 0.07]),
                _pt("v", "tibia", [-0.03, -0.04, -0.02]),
                _pt("i", "tibia", [-0.024, -0.06, -0.019]),
            ],
        ),
        _muscle(
            "gas",
            [
                _pt("o", "femur", [-0.019, -0.393, -0.024]),
                _pt("v", "tibia", [-0.03, -0.15, -0.02]),
                _pt("i", "foot", [-0.05, 0.03, -0.005]),
            ],
        ),
    ]
    model = model.with_muscles(muscles)
    t = np.linspace(0.0, 1.0, 41)
    q = np.tile(model.default_coordinates(), (t.size, 1))
    q[:, 0] += 0.3 * t
    q[:, 3] += 0.1 * np.sin(2 * np.pi * t)
    q[:, 6] += 0.5 * np.sin(2 * np.pi * t)
    q[:, 7] += 0.1 * np.cos(2 * np.pi * t)
    q[:, 9] = -0.6 - 0.5 * np.sin(2 * np.pi * t)
    return model, kinematics_from_coordinates(t, q, model.coordinate_names, cutoff_hz=None)


def test_without_muscle_forces_it_is_the_inverse_dynamics_joint_reaction() -> None:
    model, kin = _moving_leg()
    ref = joint_reaction(model, kin, joint="knee", frame="tibia")
    for forces in (None, np.zeros((kin.n_frames, 4))):
        out = knee_contact_force(model, kin, muscle_forces=forces, joint="knee")
        ok = np.isfinite(ref.force).all(axis=1)
        assert ok.sum() > 30
        np.testing.assert_allclose(out.force[ok], ref.force[ok], atol=1e-9)
        np.testing.assert_allclose(out.moment[ok], ref.moment[ok], atol=1e-9)
        assert out.muscles_included is (forces is not None)


def test_muscle_pull_agrees_with_the_path_point_wrenches_of_dynamics() -> None:
    """Independent route: ``joint_reaction`` with the muscles applied at their path points
    (msk.dynamics.inverse.muscle_body_wrenches) gives the same bone-on-bone load."""
    model, kin = _moving_leg()
    rng = np.random.default_rng(3)
    f = rng.uniform(0.0, 1500.0, (kin.n_frames, 4))
    paths = [[(p.body, p.location) for p in m.points] for m in model.muscles]
    ref = joint_reaction(
        model, kin, joint="knee", frame="tibia", muscle_forces=f, muscle_paths=paths
    )
    out = knee_contact_force(model, kin, muscle_forces=f, joint="knee")
    ok = np.isfinite(ref.force).all(axis=1)
    np.testing.assert_allclose(out.force[ok], ref.force[ok], atol=1e-7)
    np.testing.assert_allclose(out.moment[ok], ref.moment[ok], atol=1e-7)
    # named columns in any order, absent muscles are zero
    out2 = knee_contact_force(
        model,
        kin,
        muscle_forces=f[:, ::-1],
        muscle_names=["gas", "ham", "quad", "glut"],
        joint="knee",
    )
    np.testing.assert_allclose(out2.force, out.force, atol=1e-9)


def _wrapped_leg() -> Model:
    """The test leg with a gastrocnemius over two wrapping cylinders, a semimembranosus with a
    conditional point and a hip muscle that does not cross the knee."""
    model = leg_model()
    wraps = [
        WrapObject(
            "cond",
            "femur",
            "cylinder",
            np.array([-0.005, -0.41, 0.0]),
            np.array([0.05, 0.02, 0.0]),
            radius=0.025,
            length=0.1,
            quadrant="-x",
        ),
        WrapObject(
            "shank",
            "tibia",
            "cylinder",
            np.array([-0.03, -0.1, 0.0]),
            np.zeros(3),
            radius=0.02,
            length=0.1,
            quadrant="-x",
        ),
    ]
    muscles = [
        _muscle(
            "gas",
            [
                _pt("o", "femur", [-0.019, -0.393, -0.024]),
                _pt("v", "femur", [-0.03, -0.402, -0.026]),
                _pt("i", "foot", [-0.05, 0.03, -0.005]),
            ],
            wraps=[PathWrap("cond"), PathWrap("shank")],
        ),
        _muscle(
            "semimem",
            [
                _pt("o", "pelvis", [-0.12, -0.10, 0.07]),
                ConditionalPathPoint(
                    "c",
                    "tibia",
                    np.array([-0.035, -0.035, -0.019]),
                    coordinate="knee_angle",
                    range=(-0.5585, 0.1745),
                ),
                _pt("i", "tibia", [-0.024, -0.054, -0.019]),
            ],
        ),
        _muscle(
            "glut",
            [_pt("o", "pelvis", [-0.04, 0.03, 0.12]), _pt("i", "femur", [-0.02, -0.01, 0.055])],
        ),
    ]
    return model.with_muscles(muscles).with_metadata(wrap_objects=wraps)


def test_distal_wrench_projects_on_the_knee_twist_as_the_length_jacobian() -> None:
    """With wrapping cylinders and conditional points: ∂l/∂ξ · (knee twist) = ∂l/∂θ_knee."""
    model = _wrapped_leg()
    rng = np.random.default_rng(0)
    q = np.tile(model.default_coordinates(), (12, 1))
    q[:, 6:9] += rng.uniform(-0.4, 0.4, (12, 3))
    q[:, 9] = rng.uniform(-1.8, 0.1, 12)
    w = muscle_distal_wrenches(model, q, joint="knee")
    jl = muscle_geometry(model, q).jacobian
    pm = model.pin_model
    data = pm.createData()
    jid = pm.getJointId("knee_2")  # last axis of the knee chain: its twist moves the tibia
    for k in range(q.shape[0]):
        qp = model.coupling.q(q[k : k + 1])[0]
        gk = model.coupling.jacobian(q[k : k + 1])[0]
        pin.computeJointJacobians(pm, data, qp)
        knee_cols = [
            pm.joints[j].idx_v for j in range(1, pm.njoints) if pm.names[j].startswith("knee")
        ]
        twist = data.J[:, knee_cols] @ gk[knee_cols, 9]
        np.testing.assert_allclose(w[k] @ twist, jl[k, :, 9], atol=1e-10)
        assert jid > 0
    assert np.abs(w[:, 2]).max() == 0.0  # the hip muscle does not cross the knee
    assert np.abs(w[:, 0]).max() > 0.1


def test_bad_input_raises_typed_errors() -> None:
    model, kin = _moving_leg()
    with pytest.raises(ModelError, match="no joint 'knee_x'"):
        knee_contact_force(model, kin, joint="knee_x")
    with pytest.raises(ShapeMismatchError, match="muscles"):
        knee_contact_force(model, kin, muscle_forces=np.zeros((kin.n_frames, 3)), joint="knee")
    with pytest.raises(ModelError, match="no muscle 'soleus'"):
        knee_contact_force(
            model, kin, muscle_forces=np.zeros((kin.n_frames, 1)), muscle_names=["soleus"],
            joint="knee",
        )  # fmt: skip
    with pytest.raises(ModelError, match="weld"):
        muscle_distal_wrenches(model, kin.q, joint="ankle_weld")
    with pytest.raises(ModelError, match="body mass"):
        knee_contact_force(model, kin, joint="knee", body_mass_kg=0.0)


# ---------------------------------------------------------------------------------------------
# medial / lateral split (two-point model, Winby et al. 2009; Lerner et al. 2015)
# ---------------------------------------------------------------------------------------------
MODELS = Path(__file__).resolve().parents[2] / "msk" / "data" / "models"


def _contact(force, moment, joint: str = "knee_r") -> KneeContact:
    f = np.atleast_2d(np.asarray(force, dtype=float))
    m = np.atleast_2d(np.asarray(moment, dtype=float))
    tang = np.hypot(f[:, 0], f[:, 2])
    values = np.stack([-f[:, 1], f[:, 0], f[:, 2], tang, np.linalg.norm(f, axis=1)], axis=1)
    return KneeContact(
        time=np.arange(f.shape[0]) * 0.01, joint=joint, body="tibia", force=f, moment=m,
        values=values, body_weight_n=700.0, muscles_included=True,
    )  # fmt: skip


def test_static_split_by_hand() -> None:
    """N = 1000 N, frontal moment 20 N·m about the knee-frame origin, 50 N lateral shear
    20 mm above the plateau, contact midpoint 5 mm lateral: M_C,x = 20 + 0.02·50 − 0.005·1000
    = 16 N·m, so F_L = 500 + 16/0.04 = 900 N and F_M = 100 N (right knee)."""
    geo = PlateauGeometry(0.04, (0.0, -0.02, 0.005), "test")
    right = split_medial_lateral(_contact([0.0, -1000.0, 50.0], [20.0, 3.0, -7.0]), geo)
    assert isinstance(right, MedialLateral) and right.side == "right"
    np.testing.assert_allclose(right.frontal_moment, [16.0])
    np.testing.assert_allclose(right.lateral, [900.0])
    np.testing.assert_allclose(right.medial, [100.0])
    np.testing.assert_allclose(right.values, [[100.0, 900.0]])
    np.testing.assert_allclose(right.in_body_weights(), [[100.0 / 700.0, 900.0 / 700.0]])
    # the same load on a left knee: +z is medial there
    left = split_medial_lateral(_contact([0.0, -1000.0, 50.0], [20.0, 3.0, -7.0], "knee_l"), geo)
    assert left.side == "left"
    np.testing.assert_allclose([left.medial[0], left.lateral[0]], [900.0, 100.0])
    # without moment and at the origin level: an even split
    even = split_medial_lateral(_contact([0.0, -800.0, 0.0], [0.0, 0.0, 0.0]), PlateauGeometry())
    np.testing.assert_allclose([even.medial[0], even.lateral[0]], [400.0, 400.0])


_f = st.floats(-3000.0, 3000.0)
_m = st.floats(-100.0, 100.0)


@settings(max_examples=60, deadline=None)
@given(
    force=st.tuples(_f, _f, _f),
    moment=st.tuples(_m, _m, _m),
    d=st.floats(0.02, 0.08),
    centre=st.tuples(st.floats(-0.02, 0.02), st.floats(-0.05, 0.0), st.floats(-0.02, 0.02)),
    side=st.sampled_from(["right", "left"]),
)
def test_split_balances_force_and_frontal_moment(force, moment, d, centre, side) -> None:
    """F_M + F_L = N, and the two normal point forces plus the shear at the plateau level
    reproduce the frontal moment of the load about the knee-frame origin."""
    geo = PlateauGeometry(d, centre, "test")
    out = split_medial_lateral(_contact(force, moment), geo, side=side)
    f = np.asarray(force)
    np.testing.assert_allclose(out.medial + out.lateral, [-f[1]], atol=1e-9)
    np.testing.assert_allclose(out.normal, [-f[1]], atol=1e-9)
    c = np.asarray(centre)
    ez = np.array([0.0, 0.0, 1.0])
    sgn = 1.0 if side == "right" else -1.0  # +z lateral on the right, medial on the left
    p_lat, p_med = c + sgn * 0.5 * d * ez, c - sgn * 0.5 * d * ez
    ey = np.array([0.0, 1.0, 0.0])
    m = (
        np.cross(p_lat, -out.lateral[0] * ey)
        + np.cross(p_med, -out.medial[0] * ey)
        + np.cross(c, [f[0], 0.0, f[2]])
    )
    np.testing.assert_allclose(m[0], moment[0], atol=1e-8 * (1 + np.abs(f).max()))
    # Winby's form: each compartment from the moment about the other contact point
    m_o = np.asarray(moment)
    m_at = lambda p: m_o - np.cross(p, f)  # noqa: E731
    np.testing.assert_allclose(out.lateral[0] * d, sgn * m_at(p_med)[0], atol=1e-7)
    np.testing.assert_allclose(out.medial[0] * d, -sgn * m_at(p_lat)[0], atol=1e-7)


@settings(max_examples=30, deadline=None)
@given(force=st.tuples(_f, _f, _f), moment=st.tuples(_m, _m, _m), cz=st.floats(-0.01, 0.01))
def test_left_is_the_mirror_image_of_right(force, moment, cz) -> None:
    """Reflecting a right-knee load through the sagittal plane (z → −z: F_z, M_x, M_y change
    sign) gives the left knee the same medial and lateral forces."""
    fx, fy, fz = force
    mx, my, mz = moment
    right = split_medial_lateral(
        _contact(force, moment, "knee_r"), PlateauGeometry(0.04, (0.0, -0.022, cz))
    )
    left = split_medial_lateral(
        _contact([fx, fy, -fz], [-mx, -my, mz], "knee_l"),
        PlateauGeometry(0.04, (0.0, -0.022, -cz)),
    )
    np.testing.assert_allclose(left.medial, right.medial, atol=1e-9)
    np.testing.assert_allclose(left.lateral, right.lateral, atol=1e-9)


def test_split_is_vectorised_and_nan_safe() -> None:
    rng = np.random.default_rng(3)
    n = 20000
    f = rng.normal(0.0, 800.0, (n, 3))
    m = rng.normal(0.0, 30.0, (n, 3))
    f[5] = np.nan
    c = _contact(f, m)
    out = split_medial_lateral(c)  # its speed is measured in bench/bench_contact.py
    assert np.isnan(out.medial[5]) and np.isfinite(np.delete(out.medial, 5)).all()
    assert out.medial.shape == (n,)


def test_side_and_geometry_validation() -> None:
    c = _contact([0.0, -100.0, 0.0], [0.0, 0.0, 0.0], joint="knee")
    with pytest.raises(ModelError, match="side"):
        split_medial_lateral(c)
    assert split_medial_lateral(c, side="L").side == "left"
    with pytest.raises(ModelError, match="side must be"):
        split_medial_lateral(c, side="up")
    with pytest.raises(ModelError, match="intercondylar"):
        PlateauGeometry(0.0)
    with pytest.raises(ModelError, match="centre"):
        PlateauGeometry(0.04, (0.0, float("nan"), 0.0))


@pytest.fixture(scope="module")
def gait_models() -> dict[str, Model]:
    from msk.model.files import load_model

    return {
        "spline": load_model(MODELS / "gait2392.toml"),
        "four-bar": load_model(MODELS / "gait2392_fourbar.toml"),
    }


def _stance_load(model: Model, q: np.ndarray, medial_offset: float):
    """A 700 N vertical load on each calcaneus, applied below the knee and ``medial_offset``
    medial of it (world z is to the right; gait2392 stands at the origin, facing +x)."""
    from msk.dynamics.loads import ExternalLoads

    data = model.create_data()
    pin.framesForwardKinematics(model.pin_model, data, model.coupling.q(q[0]))
    n = q.shape[0]
    bodies = ("calcn_r", "calcn_l")
    force = np.zeros((n, 2, 3))
    force[:, :, 1] = 700.0
    point = np.zeros((n, 2, 3))
    for b, (tibia, sgn) in enumerate((("tibia_r", 1.0), ("tibia_l", -1.0))):
        knee = data.oMf[model.body_frame[tibia]].translation
        point[:, b] = knee + np.array([0.0, -0.45, -sgn * medial_offset])
    return ExternalLoads(
        time=np.arange(n) * 0.01, bodies=bodies, force=force,
        moment=np.cross(point, force), point=point,
    )  # fmt: skip


@pytest.mark.parametrize("kind", ["spline", "four-bar"])
def test_gait2392_knees_split_medial_under_a_medial_load(gait_models, kind: str) -> None:
    """gait2392 (spline knee) and its four-bar version, symmetric pose: a vertical load passing
    30 mm medial of the knee loads the medial compartment of both knees, the left knee is the
    mirror image of the right one, and the two knee models agree."""
    model = gait_models[kind]
    q0 = model.default_coordinates()
    names = model.coordinate_names
    for side in ("r", "l"):
        q0[names.index(f"knee_angle_{side}")] = -0.35
        q0[names.index(f"hip_flexion_{side}")] = 0.2
        q0[names.index(f"hip_adduction_{side}")] = 0.05
    q = np.tile(q0, (3, 1))
    kin = _static(model, q)
    loads = _stance_load(model, q, 0.03)
    out = {}
    for side in ("r", "l"):
        c = knee_contact_force(model, kin, loads, joint=f"knee_{side}", variant="quasi_static")
        out[side] = split_medial_lateral(c, plateau_geometry(model, joint=f"knee_{side}"))
        np.testing.assert_allclose(out[side].medial + out[side].lateral, c.normal, atol=1e-9)
        assert np.all(c.normal > 600.0)
        assert np.all(out[side].medial > out[side].lateral + 500.0)  # 700 N × 30 mm / 40 mm
    np.testing.assert_allclose(out["l"].medial, out["r"].medial, rtol=1e-6)
    np.testing.assert_allclose(out["l"].lateral, out["r"].lateral, rtol=1e-6)
    if kind == "four-bar":
        spline = gait_models["spline"]
        c = knee_contact_force(
            spline, _static(spline, q), _stance_load(spline, q, 0.03), joint="knee_r",
            variant="quasi_static",
        )  # fmt: skip
        ref = split_medial_lateral(c)
        np.testing.assert_allclose(out["r"].medial, ref.medial, atol=2.0)


def test_plateau_geometry_follows_the_tibia_scale_factors(gait_models) -> None:
    from msk.personalise.scaling import apply_scale_factors

    model = gait_models["four-bar"]
    generic = plateau_geometry(model, joint="knee_l")
    assert generic.intercondylar_distance_m == pytest.approx(INTERCONDYLAR_DISTANCE_M)
    assert generic.centre_m == pytest.approx((0.0, -PLATEAU_DEPTH_M, 0.0))
    scaled = apply_scale_factors(model, {"tibia_l": [1.1, 1.2, 0.9]})
    geo = plateau_geometry(scaled, joint="knee_l")
    assert geo.intercondylar_distance_m == pytest.approx(0.9 * INTERCONDYLAR_DISTANCE_M)
    assert geo.centre_m == pytest.approx((0.0, -1.2 * PLATEAU_DEPTH_M, 0.0))
    assert "0.9" in geo.source
    given_ = plateau_geometry(scaled, joint="knee_l", intercondylar_distance_m=0.045,
                              centre_m=(0.001, -0.03, 0.002))  # fmt: skip
    assert given_.intercondylar_distance_m == 0.045 and given_.centre_m[2] == 0.002
    with pytest.raises(ModelError, match="no joint"):
        plateau_geometry(model, joint="knee_x")


# ---------------------------------------------------------------------------------------------
# the vectorised route equals the RNEA + per-twist path route (the implementation until 2026-11)
# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def walk() -> dict[str, object]:
    """Kinematics (filtered at 6 Hz) and plate loads of the subject01 walk, 0.5–2.5 s."""
    from msk.datasets.opensim_subject01 import load_subject01

    s = load_subject01()
    sel = (s.ik_time >= 0.5) & (s.ik_time <= 2.5)
    return {"subject": s, "time": s.ik_time[sel], "q": s.ik_q[sel]}


@pytest.mark.parametrize("kind", ["spline", "four-bar"])
def test_vectorised_contact_equals_the_rnea_route_on_the_walk(gait_models, walk, kind) -> None:
    """gait2392 (spline knee) and its four-bar version on the real subject01 walk, both knees,
    full and quasi-static: force and moment equal today's route to 1e-9 (relative to the
    largest component), whether ∂l/∂ξ comes from the geometry stage or from its own pass; the
    medial/lateral split follows."""
    from msk.dynamics.loads import external_loads

    model = gait_models[kind]
    s: Any = walk["subject"]
    kin = kinematics_from_coordinates(
        walk["time"], walk["q"], model.coordinate_names, cutoff_hz=6.0
    )
    loads = external_loads(model, kin, s.plates, threshold_n=0.0)
    rng = np.random.default_rng(7)
    f = rng.uniform(0.0, 1200.0, (kin.n_frames, len(model.muscles)))
    geom = muscle_geometry(model, kin.q, kin.v, distal_wrench_joints=("knee_r", "knee_l"))
    for joint in ("knee_r", "knee_l"):
        for variant in ("full", "quasi_static"):
            ref_f, ref_m = legacy_knee_contact_force(
                model, kin, loads, muscle_forces=f, joint=joint, variant=variant
            )
            for dw in (None, geom.distal_wrenches[joint]):
                out = knee_contact_force(
                    model, kin, loads, muscle_forces=f, joint=joint, variant=variant,
                    distal_wrenches=dw,
                )  # fmt: skip
                assert np.abs(out.force - ref_f).max() <= 1e-9 * np.abs(ref_f).max()
                assert np.abs(out.moment - ref_m).max() <= 1e-9 * np.abs(ref_m).max()
            ref = KneeContact(
                out.time, joint, out.body, ref_f, ref_m, out.values, out.body_weight_n, True
            )
            a, b = split_medial_lateral(out), split_medial_lateral(ref)
            scale = np.abs(b.normal).max()
            assert np.abs(a.medial - b.medial).max() <= 1e-9 * scale
            assert np.abs(a.lateral - b.lateral).max() <= 1e-9 * scale
    # the geometry pass gives the same Jacobians with and without the wrenches
    plain = muscle_geometry(model, kin.q, kin.v)
    np.testing.assert_array_equal(plain.jacobian, geom.jacobian)
    np.testing.assert_array_equal(plain.lengths, geom.lengths)


def test_distal_wrenches_of_the_geometry_pass_equal_the_twist_evaluation() -> None:
    """Wrapping cylinders (the per-point wrench route) and conditional points: the wrench rows
    of the geometry pass equal the path evaluation with unit twists on the knee; muscles that
    do not cross the knee get exact zeros; NaN frames stay NaN in muscle_distal_wrenches."""
    from msk.muscles.geometry import geometry_plan

    model = _wrapped_leg()
    rng = np.random.default_rng(1)
    q = np.tile(model.default_coordinates(), (15, 1))
    q[:, 6:9] += rng.uniform(-0.4, 0.4, (15, 3))
    q[:, 9] = rng.uniform(-1.8, 0.1, 15)
    plan = geometry_plan(model)
    assert not plan._static
    geom = muscle_geometry(model, q, distal_wrench_joints=("knee", "hip"))
    ref = plan._distal_by_twists(q, plan._joint_dofs("knee"))
    np.testing.assert_allclose(geom.distal_wrenches["knee"], ref, rtol=0, atol=1e-12)
    assert np.all(geom.distal_wrenches["knee"][:, 2] == 0.0)  # the hip muscle
    ref_hip = plan._distal_by_twists(q, plan._joint_dofs("hip"))
    np.testing.assert_allclose(geom.distal_wrenches["hip"], ref_hip, rtol=0, atol=1e-12)
    q[3] = np.nan
    w = muscle_distal_wrenches(model, q, joint="knee")
    assert np.isnan(w[3]).all() and np.isfinite(np.delete(w, 3, axis=0)).all()
    with pytest.raises(ModelError, match="no joint"):
        muscle_geometry(model, q[:2], distal_wrench_joints=("knee_x",))


def test_contact_checks_the_given_distal_wrenches() -> None:
    model, kin = _moving_leg()
    f = np.ones((kin.n_frames, 4))
    with pytest.raises(ShapeMismatchError, match="distal wrenches"):
        knee_contact_force(
            model, kin, muscle_forces=f, joint="knee", distal_wrenches=np.zeros((3, 4, 6))
        )
    geom = muscle_geometry(model, kin.q, distal_wrench_joints=("knee",))
    a = knee_contact_force(model, kin, muscle_forces=f, joint="knee")
    b = knee_contact_force(
        model, kin, muscle_forces=f, joint="knee", distal_wrenches=geom.distal_wrenches["knee"]
    )
    np.testing.assert_array_equal(a.force, b.force)


# ---------------------------------------------------------------------------------------------
# conventions of the split on a tiny LEFT and RIGHT knee built in code (issue 16): OpenSim body
# frames are not mirrored (z to the right on both legs), so +z is lateral on the right knee and
# medial on the left one
# ---------------------------------------------------------------------------------------------
Z_MUSCLE = 0.025  # the biceps-like muscle runs vertically this far lateral of the knee centre


def _one_knee(side: str) -> Model:
    """A femur welded to the ground (knee centre at ``HIP``), a shank on a revolute knee about
    z (``knee_r`` or ``knee_l``) and one vertical muscle ``Z_MUSCLE`` lateral of the knee."""

    lat = 1.0 if side == "r" else -1.0  # world z of the lateral side
    model = femur_tibia(f"knee_{side}", shank_mass_kg=M_SHANK)
    z = lat * Z_MUSCLE
    return model.with_muscles(
        [
            _muscle(
                "lateral",
                [_pt("o", "femur", [-0.02, 0.15, z]), _pt("i", "tibia", [-0.02, -0.06, z])],
            )
        ]
    )


def _foot_load(n: int, z_point: float):
    """700 N straight up on the shank, 0.4 m below the knee centre, at world z ``z_point``."""
    from msk.dynamics.loads import ExternalLoads

    force = np.zeros((n, 1, 3))
    force[:, :, 1] = 700.0
    point = np.tile(HIP + np.array([0.0, -0.4, z_point]), (n, 1, 1))
    return ExternalLoads(
        time=np.arange(n) * 0.01, bodies=("tibia",), force=force,
        moment=np.cross(point, force), point=point,
    )  # fmt: skip


@pytest.mark.parametrize("side", ["r", "l"])
def test_external_varus_moment_loads_the_medial_compartment_of_either_knee(side: str) -> None:
    """An upward ground reaction passing 30 mm medial of the knee (an external knee adduction
    moment, 700 N × 0.03 m = 21 N·m) makes F_M − F_L = 2·21/d = 1050 N for d = 40 mm on a
    right and on a left knee; the contact's frontal moment M_C,x has the sign of the side's
    abduction (−x on the right, +x on the left: it balances the external adduction moment)."""
    model = _one_knee(side)
    medial_z = -0.03 if side == "r" else 0.03
    kin = _static(model, [[0.0]] * 3)
    c = knee_contact_force(
        model, kin, _foot_load(3, medial_z), joint=f"knee_{side}", variant="quasi_static"
    )
    ml = split_medial_lateral(c, PlateauGeometry(0.04, (0.0, -0.02, 0.0)))
    assert ml.side == ("right" if side == "r" else "left")
    np.testing.assert_allclose(ml.normal, 700.0 - M_SHANK * G0, atol=1e-9)
    np.testing.assert_allclose(ml.medial - ml.lateral, 1050.0, atol=1e-8)
    np.testing.assert_allclose(ml.frontal_moment, -21.0 if side == "r" else 21.0, atol=1e-10)
    # the same reaction passing 30 mm lateral loads the lateral compartment
    c = knee_contact_force(
        model, kin, _foot_load(3, -medial_z), joint=f"knee_{side}", variant="quasi_static"
    )
    ml = split_medial_lateral(c, PlateauGeometry(0.04, (0.0, -0.02, 0.0)))
    np.testing.assert_allclose(ml.lateral - ml.medial, 1050.0, atol=1e-8)


@pytest.mark.parametrize("side", ["r", "l"])
def test_a_lateral_muscle_loads_the_lateral_compartment_of_either_knee(side: str) -> None:
    """A 500 N muscle pulling the tibia up 25 mm lateral of the knee centre presses the lateral
    condyle: F_L − F_M = 2·500·0.025/0.04 = 625 N, N = 500 N − the shank's weight, on the
    right and on the left knee (the sign of every muscle's frontal contribution)."""
    model = _one_knee(side)
    kin = _static(model, [[0.0]] * 3)
    c = knee_contact_force(
        model, kin, muscle_forces=np.full((3, 1), 500.0), joint=f"knee_{side}",
        variant="quasi_static",
    )  # fmt: skip
    ml = split_medial_lateral(c, PlateauGeometry(0.04, (0.0, -0.02, 0.0)))
    np.testing.assert_allclose(ml.normal, 500.0 - M_SHANK * G0, atol=1e-8)
    np.testing.assert_allclose(ml.lateral - ml.medial, 625.0, atol=1e-8)


@pytest.mark.parametrize("side", ["r", "l"])
@pytest.mark.parametrize("psi_deg", [-5.0, 3.0])
def test_turning_the_plateau_about_the_tibia_mixes_the_sagittal_moment_into_the_split(
    side: str, psi_deg: float
) -> None:
    """Docs, medial/lateral contact item 11: the split's frame turned by ψ about the tibia's long
    axis (``plateau_offset``) sees the frontal moment cos ψ M_C,x − sin ψ M_C,z about the same
    contact midpoint C (on that axis) and the same normal force, so a frame error moves the
    lateral force by ((cos ψ − 1) M_C,x − sin ψ M_C,z)/d — first order in the sagittal moment
    at C, which the muscles balance. A flexed knee, a reaction 30 mm medial and 50 mm anterior
    of the knee (both moments non-zero), and muscle tensions: the exact identity."""
    model = _one_knee_four(side)
    n = 3
    kin = _static(model, [[-0.4]] * n)
    z = -0.03 if side == "r" else 0.03
    force = np.zeros((n, 1, 3))
    force[:, :, 1] = 700.0
    point = np.tile(HIP + np.array([0.05, -0.4, z]), (n, 1, 1))
    from msk.dynamics.loads import ExternalLoads

    loads = ExternalLoads(
        time=np.arange(n) * 0.01, bodies=("tibia",), force=force,
        moment=np.cross(point, force), point=point,
    )  # fmt: skip
    f = np.tile([300.0, 50.0, 120.0, 10.0], (n, 1))
    geo = PlateauGeometry(0.04, (0.0, -0.022, 0.0))
    psi = np.radians(psi_deg)
    turned = pin.SE3(pin.exp3(np.array([0.0, psi, 0.0])), np.zeros(3))
    c0 = knee_contact_force(model, kin, loads, muscle_forces=f, joint=f"knee_{side}")
    c1 = knee_contact_force(
        model, kin, loads, muscle_forces=f, joint=f"knee_{side}", plateau_offset=turned
    )
    ml0, ml1 = split_medial_lateral(c0, geo), split_medial_lateral(c1, geo)
    m_c = c0.moment - np.cross(np.array(geo.centre_m), c0.force)  # about C, unturned frame
    assert np.all(np.abs(m_c[:, 0]) > 5.0) and np.all(np.abs(m_c[:, 2]) > 5.0)
    np.testing.assert_allclose(
        ml1.frontal_moment, np.cos(psi) * m_c[:, 0] - np.sin(psi) * m_c[:, 2], atol=1e-9
    )
    np.testing.assert_allclose(ml1.normal, ml0.normal, atol=1e-9)
    sign = 1.0 if side == "r" else -1.0  # + M_C,x loads the lateral compartment on the right
    np.testing.assert_allclose(
        ml1.lateral - ml0.lateral,
        sign * ((np.cos(psi) - 1.0) * m_c[:, 0] - np.sin(psi) * m_c[:, 2]) / 0.04,
        atol=1e-7,
    )


# ---------------------------------------------------------------------------------------------
# compartment forces affine in the tensions; F_M, F_L ≥ 0 in static optimisation (issue 16,
# seventh pass)
# ---------------------------------------------------------------------------------------------
def _varus_frames(model: Model, side: str, medial_m: float, n: int = 3):
    """Static knee at 0°, 700 N straight up 0.4 m below the knee, ``medial_m`` medial of it."""
    z = -medial_m if side == "r" else medial_m
    return _static(model, [[0.0]] * n), _foot_load(n, z)


@pytest.mark.parametrize("side", ["r", "l"])
def test_compartment_map_is_the_split_of_the_contact_with_any_tensions(side: str) -> None:
    """offset + gain · f equals split_medial_lateral(knee_contact_force(f)) to round-off, for
    random tensions, a bent moving knee and an external load, on either side."""
    from msk.contact.knee import compartment_force_map
    from tests.support.knees import four_muscle_knee

    model = four_muscle_knee(f"knee_{side}")
    t = np.arange(6) * 0.01
    q = np.linspace(-0.2, -0.9, 6)[:, None]
    kin = kinematics_from_coordinates(t, q, model.coordinate_names, cutoff_hz=None)
    loads = _foot_load(6, 0.02)
    geo = PlateauGeometry(0.041, (0.002, -0.023, 0.001))
    f = np.random.default_rng(3).uniform(0.0, 900.0, (6, 4))
    cm = compartment_force_map(model, kin, loads, joint=f"knee_{side}", geometry=geo)
    c = knee_contact_force(model, kin, loads, muscle_forces=f, joint=f"knee_{side}")
    ref = split_medial_lateral(c, geo)
    got = cm.forces(f)
    scale = np.abs(ref.normal).max()
    assert np.abs(got[:, 0] - ref.medial).max() <= 1e-10 * scale
    assert np.abs(got[:, 1] - ref.lateral).max() <= 1e-10 * scale
    assert cm.side == ("right" if side == "r" else "left")
    # the lateral extensor presses the lateral compartment more than the medial one
    i = cm.muscle_names.index("lat_ext")
    assert np.all(cm.gain[:, 1, i] > cm.gain[:, 0, i])


def _constrained_so(model: Model, side: str, medial_m: float, f_active: float):
    """Static optimisation (activations², reserves 1 N·m) of the knee's torques with and without
    the rows d·F_M ≥ 0, d·F_L ≥ 0 (frontal reserves 1 N·m), as the tension stage poses them."""
    from msk.contact.knee import compartment_force_map
    from msk.muscles.geometry import jacobian_frames
    from msk.optimization import TensionInequalities, solve_static_optimization_batch

    kin, loads = _varus_frames(model, side, medial_m)
    joint = f"knee_{side}"
    geo = PlateauGeometry(0.04, (0.0, -0.02, 0.0))
    # the load passes through the knee axis' sagittal line and the shank hangs straight: no
    # knee torque (checked below against the contact's own moment about the axis)
    tau = np.zeros((kin.n_frames, 1))
    c = knee_contact_force(model, kin, loads, joint=joint)
    np.testing.assert_allclose(c.moment[:, 2], 0.0, atol=1e-9)
    geom = muscle_geometry(model, kin.q, kin.v, distal_wrench_joints=(joint,))
    jac = jacobian_frames(geom.jacobian, np.arange(kin.n_frames), [0])
    cm = compartment_force_map(
        model, kin, loads, joint=joint, geometry=geo, distal_wrenches=geom.distal_wrenches[joint]
    )
    rows = TensionInequalities(0.04 * cm.offset, 0.04 * cm.gain, ("medial", "lateral"), 1.0)
    fa = np.full((kin.n_frames, 4), f_active)
    kw: dict[str, Any] = {"f_active": fa, "reserve_optimal_force": np.ones(1)}
    free = solve_static_optimization_batch(jac, tau, **kw)
    held = solve_static_optimization_batch(jac, tau, inequalities=rows, **kw)
    return cm, free, held, jac, tau, kw, rows


@pytest.mark.parametrize("side", ["r", "l"])
def test_nonnegative_compartments_recruit_the_lateral_muscles_under_a_varus_load(side) -> None:
    """700 N passing 30 mm medial of the knee (21 N·m of external adduction moment, no sagittal
    torque): without muscles F_L = (661 − 1050)/2 = −194 N (the lateral compartment pulls) and
    static optimisation recruits nothing. With F_M, F_L ≥ 0 the two lateral muscles co-contract
    (1.125 N of F_L per N: ≈ 172 N together), the medial ones stay off, both compartments are
    ≥ 0 to 0.1 N (the reserve is priced quadratically, like a coordinate reserve, so it keeps a
    few mN·m where the muscles' last newtons cost more: d·F_L = −s), the knee torque is still
    produced exactly; DAQP's answer has KKT figures ≤ 1e-8 and Clarabel's agrees."""
    from msk.optimization import solve_static_optimization_batch

    model = _one_knee_four(side)
    cm, free, held, jac, tau, kw, rows = _constrained_so(model, side, 0.03, 1000.0)
    np.testing.assert_allclose(cm.offset[:, 1], (661.0 - 1050.0) / 2, atol=0.5)
    assert np.all(free.forces < 1e-6) and np.all(cm.forces(free.forces)[:, 1] < -190.0)
    comp = cm.forces(held.forces)
    assert np.all(comp >= -0.1)
    names = cm.muscle_names
    lat = [names.index("lat_ext"), names.index("lat_flex")]
    med = [names.index("med_ext"), names.index("med_flex")]
    assert np.all(held.forces[:, lat].sum(axis=1) >= 171.0)
    assert np.all(held.forces[:, med] < 1e-6)
    np.testing.assert_allclose(held.residual, 0.0, atol=1e-9)
    np.testing.assert_allclose(held.reserve_torques, 0.0, atol=1e-9)
    np.testing.assert_allclose(held.torque_error, free.torque_error, atol=1e-9)
    s = held.inequality_reserves
    assert s is not None and np.all(s < 0.005)
    np.testing.assert_allclose(0.04 * comp[:, 1] + s[:, 1], 0.0, atol=1e-8)
    assert np.nanmax(held.kkt) <= 1e-8
    other = solve_static_optimization_batch(jac, tau, inequalities=rows, solver="clarabel", **kw)
    np.testing.assert_allclose(other.forces, held.forces, atol=1e-3)


def test_a_varus_load_no_muscle_can_balance_takes_a_frontal_reserve_and_is_flagged() -> None:
    """The same knee with muscles of 50 N capacity: the lateral muscles saturate, the frontal
    reserve of the lateral row carries the rest (d·F_L + s = 0, s > 0), the compartments stay ≥ 0
    once the reserve is counted, and the quality gate names it."""
    from msk.optimization.muscle_forces import MuscleForces
    from msk.quality import frontal_reserve_flags

    model = _one_knee_four("r")
    cm, _, held, *_ = _constrained_so(model, "r", 0.03, 50.0)
    s = held.inequality_reserves
    assert s is not None
    assert np.all(s[:, 1] > 1.0) and np.all(s[:, 0] < 1e-9)
    names = cm.muscle_names
    assert np.all(held.activations[:, names.index("lat_ext")] > 0.999)
    np.testing.assert_allclose(0.04 * cm.forces(held.forces)[:, 1] + s[:, 1], 0.0, atol=1e-8)
    n = held.forces.shape[0]
    ten = MuscleForces(
        held.forces, held.activations, names, "static_optimization", 0,
        frontal_reserve_moments=s, compartment_rows=("knee_r_medial", "knee_r_lateral"),
        id_frontal_moment_peak_nm=float(np.max(np.abs(0.02 * (cm.offset[:, 1] - cm.offset[:, 0])))),
    )  # fmt: skip
    flags = frontal_reserve_flags("trial", ten)
    assert [f.quantity for f in flags] == ["knee_r_lateral_frontal_reserve_pct"]
    assert flags[0].value > 10.0 and "knee_r_lateral" in flags[0].message
    quiet = MuscleForces(
        held.forces, held.activations, names, "static_optimization", 0,
        frontal_reserve_moments=np.zeros((n, 2)),
        compartment_rows=("knee_r_medial", "knee_r_lateral"), id_frontal_moment_peak_nm=21.0,
    )  # fmt: skip
    assert frontal_reserve_flags("trial", quiet) == []


def _one_knee_four(side: str) -> Model:
    from tests.support.knees import four_muscle_knee

    return four_muscle_knee(f"knee_{side}", shank_mass_kg=M_SHANK)


# ---------------------------------------------------------------------------------------------
# any knee whose child body is the tibia: Rajagopal's walker knee (coupled translations, three
# rotations driven by one coordinate, positive in flexion)
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["rajagopal", "gait2392"])
def test_walker_and_spline_knees_hold_a_static_stance_by_hand(name: str) -> None:
    """Static pose, a 700 N vertical load under each calcaneus, no muscle force: the femur's
    force and moment on the tibia side are minus the loads and the weights of the tibia side,
    computed here from the bodies' placements alone (no RNEA), on both knees."""
    from msk.model.conventions import knee_joint, reference_sign
    from msk.model.files import load_model

    model = load_model(name)
    names = model.coordinate_names
    q0 = model.default_coordinates()
    for side in ("r", "l"):
        c = f"knee_angle_{side}"
        q0[names.index(c)] = reference_sign(model, c) * np.radians(-25.0)  # 25° of flexion
        q0[names.index(f"hip_flexion_{side}")] = 0.2
    q = np.tile(q0, (3, 1))
    kin = _static(model, q)
    loads = _stance_load(model, q, 0.02)
    data = model.create_data()
    pin.framesForwardKinematics(model.pin_model, data, model.coupling.q(q0))
    g = np.array([0.0, -G0, 0.0])
    for side, b in (("r", 0), ("l", 1)):
        joint = knee_joint(model, side)
        assert joint == ("walker_knee_" if name == "rajagopal" else "knee_") + side
        tib = data.oMf[model.body_frame[f"tibia_{side}"]]
        force_w = -loads.force[0, b].copy()
        moment_w = -np.cross(loads.point[0, b] - tib.translation, loads.force[0, b])
        for body in model.subtree(f"tibia_{side}"):
            bd = model.body(body)
            c_w = data.oMf[model.body_frame[body]].act(bd.com)
            force_w -= bd.mass * g
            moment_w -= np.cross(c_w - tib.translation, bd.mass * g)
        out = knee_contact_force(model, kin, loads, joint=joint, variant="quasi_static")
        np.testing.assert_allclose(out.force, np.tile(tib.rotation.T @ force_w, (3, 1)), atol=1e-7)
        np.testing.assert_allclose(out.moment, np.tile(tib.rotation.T @ moment_w, (3, 1)),
                                   atol=1e-7)  # fmt: skip
        assert np.all(out.normal > 600.0)  # the stance compresses the plateau


def test_walker_knee_muscle_pulls_do_the_virtual_work_of_their_moment_arms() -> None:
    """Rajagopal, flexed 30°, random tensions: the muscles' part of the contact wrench
    (with tensions minus without) does, over the knee's own motion (the tibia side's world
    twist S per unit knee coordinate, its coupled translations and rotations included, by
    central differences of the tibia's placement), the virtual work Σ F_i ∂l_i/∂θ of the
    length Jacobian (virtual work: S · Σ F_i ∂l_i/∂ξ = Σ F_i ∂l_i/∂θ)."""
    from msk.contact.patella import patellar_tendon
    from msk.model.core import frame_placements
    from msk.model.files import load_model

    model = load_model("rajagopal")
    ci = model.coordinate_index("knee_angle_r")
    q0 = model.default_coordinates()
    q0[ci] = np.radians(30.0)
    q = np.tile(q0, (2, 1))
    kin = _static(model, q)
    rng = np.random.default_rng(5)
    f = rng.uniform(0.0, 800.0, (2, len(model.muscles)))
    jac = muscle_geometry(model, q, np.zeros_like(q)).jacobian[:, :, ci]
    # the quadriceps insert on Rajagopal's patella (a body on the femur, coupled to the knee
    # coordinate): they load the tibia through the patellar tendon (msk.contact.patella)
    tendon = patellar_tendon(model, joint="walker_knee_r")
    kw = {"joint": "walker_knee_r", "variant": "quasi_static", "patella": tendon,
          "knee_jacobian": jac}  # fmt: skip
    bare = knee_contact_force(model, kin, muscle_forces=np.zeros_like(f), **kw)
    full = knee_contact_force(model, kin, muscle_forces=f, **kw)
    frame = [model.body_frame["tibia_r"]]
    h = 1e-6
    qs = np.tile(q0, (3, 1))
    qs[:, ci] += [-h, 0.0, h]
    rot, pos = frame_placements(model, qs, frame)
    r, p = rot[1, 0], pos[1, 0]
    omega = pin.log3(rot[0, 0].T @ rot[2, 0]) / (2 * h)
    omega = rot[0, 0] @ omega  # world axes
    v_o = (pos[2, 0] - pos[0, 0]) / (2 * h) - np.cross(omega, p)  # at the world origin
    d_force = r @ (full.force[0] - bare.force[0])
    d_moment = r @ (full.moment[0] - bare.moment[0]) + np.cross(p, d_force)
    work = omega @ d_moment + v_o @ d_force
    want = float(f[0] @ jac[0])
    assert abs(want) > 10.0
    assert work == pytest.approx(want, rel=1e-5, abs=1e-6)
    assert np.all(full.normal > bare.normal)  # tensions across the knee compress it
