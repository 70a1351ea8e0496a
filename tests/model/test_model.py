import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from msk.datasets.models import leg_model
from msk.exceptions import ModelError
from msk.model.core import (
    INERTIAL_PARAMETER_NAMES,
    Axis,
    Body,
    Coordinate,
    Joint,
    Model,
    marker_positions,
)
from msk.model.joints import Constant, FourBarKnee, FourBarTranslation, Linear


def _rodrigues(axis, angle):
    k = ca.DM([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return ca.DM.eye(3) + ca.sin(angle) * k + (1 - ca.cos(angle)) * (k @ k)


def _casadi_lagrangian(model: Model, theta, theta_dot):
    """Independent forward kinematics + energies in casadi (no Pinocchio)."""
    coord = {c.name: i for i, c in enumerate(model.coordinates)}
    pose = {"ground": (ca.SX.eye(3), ca.SX.zeros(3))}
    kinetic, potential = 0, 0
    g = ca.DM(model.gravity)
    for joint in model.joints:
        r, p = pose[joint.parent]
        po = joint.parent_offset
        p = p + r @ ca.DM(po.translation)
        r = r @ ca.DM(po.rotation)
        for ax in joint.axes:
            qk = ax.function(theta[coord[ax.coordinate]]) if ax.coordinate else ax.function(0)
            if ax.kind == "prismatic":
                p = p + r @ (ca.DM(ax.axis) * qk)
            else:
                r = r @ _rodrigues(ax.axis, qk)
        co = joint.child_offset.inverse()
        p = p + r @ ca.DM(co.translation)
        r = r @ ca.DM(co.rotation)
        pose[joint.child] = (r, p)
        body = model.body(joint.child)
        c = p + r @ ca.DM(body.com)
        v = ca.jtimes(c, theta, theta_dot)
        r_dot = ca.reshape(ca.jtimes(ca.reshape(r, 9, 1), theta, theta_dot), 3, 3)
        w_skew = r.T @ r_dot
        w = ca.vertcat(w_skew[2, 1], w_skew[0, 2], w_skew[1, 0])
        kinetic += 0.5 * body.mass * ca.dot(v, v) + 0.5 * w.T @ ca.DM(body.inertia) @ w
        potential += -body.mass * ca.dot(g, c)
    return kinetic - potential


def test_embedded_rnea_equals_euler_lagrange():
    model = leg_model()
    n = model.n_coords
    th, thd, thdd = ca.SX.sym("th", n), ca.SX.sym("thd", n), ca.SX.sym("thdd", n)
    lag = _casadi_lagrangian(model, th, thd)
    dl_dthd = ca.gradient(lag, thd)
    tau_el = ca.jtimes(dl_dthd, ca.vertcat(th, thd), ca.vertcat(thd, thdd)) - ca.gradient(lag, th)
    f = ca.Function("el", [th, thd, thdd], [tau_el])
    rng = np.random.default_rng(1)
    data = model.create_data()
    for _ in range(10):
        x = rng.uniform(-1, 1, n)
        x[9] = rng.uniform(-2.0, 0.0)
        xd, xdd = rng.normal(size=n), rng.normal(size=n)
        q, v, a = model.coupling.embed(x, xd, xdd)
        tau = pin.rnea(model.pin_model, data, q, v, a)
        tau_theta = model.coupling.project(x, tau)
        ref = np.asarray(f(x, xd, xdd)).ravel()
        np.testing.assert_allclose(tau_theta, ref, rtol=1e-8, atol=1e-8 * np.abs(ref).max())


def test_total_mass_markers_and_frames():
    model = leg_model()
    assert model.total_mass == pytest.approx(11.0 + 8.8 + 3.5 + 1.2)
    data = model.create_data()
    pin.computeAllTerms(
        model.pin_model, data, *model.coupling.embed(np.zeros(10), np.zeros(10), np.zeros(10))[:2]
    )
    # Pinocchio's total mass includes the welded foot appended to the tibia joint
    assert data.mass[0] == pytest.approx(model.total_mass)
    x = model.default_coordinates()
    pos = marker_positions(model, x)[0]
    # pelvis at (0, 0.9, 0), no rotation: ASIS is offset + pelvis position
    np.testing.assert_allclose(pos[0], [0.02, 0.9, 0.12], atol=1e-12)
    # welded foot: HEE = tibia origin + R_weld (child_offset⁻¹ · offset)
    knee = model.coupling.q(x)[9:12]
    tib = np.array([-0.07, 0.9 - 0.066, 0.083]) + np.array([knee[0], knee[1], 0.0])
    r = pin.rpy.rpyToMatrix(0.1, 0.0, 0.2)
    expect = tib + np.array([0, -0.43, 0]) + r @ (np.array([-0.03, -0.02, 0]) - [0.01, 0.02, 0])
    np.testing.assert_allclose(pos[6], expect, atol=1e-12)


def test_inertial_parameter_order_round_trip():
    assert INERTIAL_PARAMETER_NAMES[0] == "m" and len(INERTIAL_PARAMETER_NAMES) == 10
    body = Body("b", 2.0, [0.1, -0.2, 0.3], np.diag([0.1, 0.2, 0.3]) + 0.01)
    phi = body.parameters()
    named = dict(zip(INERTIAL_PARAMETER_NAMES, phi))
    assert named["m"] == 2.0
    assert named["my"] == pytest.approx(2.0 * -0.2)
    # Ixy about the origin = Ixy_com − m·cx·cy (Pinocchio convention: I = Ic + m·(cᵀc·1 − c cᵀ))
    assert named["Ixy"] == pytest.approx(0.01 - 2.0 * 0.1 * -0.2)
    back = Body.from_parameters("b", phi)
    np.testing.assert_allclose(back.com, body.com)
    np.testing.assert_allclose(back.inertia, body.inertia, atol=1e-14)


def test_with_inertias_returns_new_model_and_keeps_original():
    model = leg_model()
    phi = model.body("femur").parameters() * 1.2
    new = model.with_inertias({"femur": phi})
    assert new.body("femur").mass == pytest.approx(1.2 * 8.8)
    assert model.body("femur").mass == 8.8
    assert new.pin_model is not model.pin_model
    np.testing.assert_allclose(new.pin_model.inertias[model.body_joint["femur"]].mass, 1.2 * 8.8)


def test_four_bar_knee_variant_runs_through_the_same_machinery():
    knee = FourBarKnee(
        (-0.010, -0.395), (0.008, -0.400), (0.012, -0.010), (-0.018, -0.022), p_ref=(0.0, -0.405)
    )
    base = leg_model()
    joint = next(j for j in base.joints if j.name == "knee")
    four_bar = Joint(
        "knee",
        "femur",
        "tibia",
        axes=(
            Axis("prismatic", [1, 0, 0], "knee_angle", FourBarTranslation(knee, 0)),
            Axis("prismatic", [0, 1, 0], "knee_angle", FourBarTranslation(knee, 1)),
            Axis("revolute", [0, 0, 1], "knee_angle", Linear()),
        ),
    )
    model = base.with_joints({"knee": four_bar})
    assert joint is not four_bar
    x = np.zeros(10)
    x[9] = -1.0
    q = model.coupling.q(x)
    p, _, _ = knee.solve(-1.0)
    np.testing.assert_allclose(q[9:11], p)


def test_invalid_models_raise_model_error_naming_the_culprit():
    lin = Linear()
    body = Body("a", 1.0)
    with pytest.raises(ModelError, match="unknown coordinate 'nope'"):
        Model(
            name="m",
            bodies=[body],
            coordinates=[],
            joints=[Joint("j", "ground", "a", axes=(Axis("revolute", [0, 0, 1], "nope", lin),))],
        )
    with pytest.raises(ModelError, match="not connected to ground"):
        Model(
            name="m",
            bodies=[body, Body("b", 1.0)],
            coordinates=[],
            joints=[Joint("j", "ground", "a"), Joint("k", "c", "b")],
        )
    with pytest.raises(ModelError, match="mass"):
        Body("x", -1.0)
    with pytest.raises(ModelError, match="no coordinate"):
        Model(
            name="m",
            bodies=[body],
            coordinates=[Coordinate("c")],
            joints=[Joint("j", "ground", "a", axes=(Axis("revolute", [0, 0, 1], "c", lin),))],
        ).coordinate_index("d")
    with pytest.raises(ModelError, match="has no coordinate"):
        Model(
            name="m",
            bodies=[body],
            coordinates=[],
            joints=[Joint("j", "ground", "a", axes=(Axis("revolute", [0, 0, 1], None, lin),))],
        )
    Model(
        name="m",
        bodies=[body],
        coordinates=[],
        joints=[
            Joint("j", "ground", "a", axes=(Axis("revolute", [0, 0, 1], None, Constant(0.1)),))
        ],
    )


def test_frame_placements_equal_forward_kinematics_frame_by_frame():
    """:func:`msk.model.core.frame_placements` (one vectorised coupling, one product for every
    frame) gives the placements :func:`msk.model.core.forward_kinematics` leaves in ``data.oMf``,
    for bodies and markers, over many poses."""
    from msk.model.core import forward_kinematics, frame_placements

    model = leg_model()
    rng = np.random.default_rng(1)
    lo, hi = model.coordinate_bounds()
    th = rng.uniform(np.maximum(lo, -1.0), np.minimum(hi, 1.0), (7, model.n_coords))
    frames = [model.body_frame[b.name] for b in model.bodies]
    frames += [model.marker_frame[m.name] for m in model.markers]
    rot, tra = frame_placements(model, th, frames)
    assert rot.shape == (7, len(frames), 3, 3) and tra.shape == (7, len(frames), 3)
    data = model.create_data()
    for n in range(7):
        forward_kinematics(model, data, th[n])
        for k, f in enumerate(frames):
            np.testing.assert_allclose(rot[n, k], data.oMf[f].rotation, atol=1e-14)
            np.testing.assert_allclose(tra[n, k], data.oMf[f].translation, atol=1e-14)
    np.testing.assert_allclose(
        frame_placements(model, th, [model.marker_frame[m.name] for m in model.markers])[1],
        marker_positions(model, th), atol=1e-14,
    )  # fmt: skip


def test_state_round_trip_through_the_stage_cache_builds_the_same_model(tmp_path):
    """The cache stores no Model (Pinocchio objects), but its plain-data state, from which the
    same Pinocchio model is built: every frame placement, inertia and marker position exact."""
    from msk._runtime.cache import StageCache
    from msk.datasets.models import two_leg_model

    rng = np.random.default_rng(3)
    base = two_leg_model()
    j = base.joints[1]
    tilt = pin.SE3(pin.exp3(rng.normal(size=3)), 0.05 * rng.normal(size=3))
    tilted = Joint(j.name, j.parent, j.child, tilt, None, j.axes)  # type: ignore[arg-type]
    model = base.with_joints({j.name: tilted}).with_metadata(knee={"varus_rad": 0.07})
    cache = StageCache(tmp_path)
    assert not cache.save("model", "k", {"model": model})  # a Model itself is not storable
    assert cache.save("model", "k", {"model": model.state()}), cache.last_reason
    hit, stored = cache.load("model", "k")
    assert hit
    again = Model.from_state(stored["model"])
    assert again.pin_model == model.pin_model
    for a, b in zip(model.pin_model.frames, again.pin_model.frames):
        assert np.array_equal(a.placement.homogeneous, b.placement.homogeneous)
    assert again.joints[1].child_offset is None
    assert np.array_equal(again.joints[1].parent_offset.homogeneous, tilt.homogeneous)
    assert again.coupling == model.coupling and again.metadata == model.metadata
    theta = 0.3 * rng.normal(size=(5, model.n_coords))
    assert np.array_equal(marker_positions(again, theta), marker_positions(model, theta))
    # a changed specification is seen: the state is the model's, not a generic one
    heavier = model.with_bodies({"pelvis": Body("pelvis", 12.0)})
    assert Model.from_state(heavier.state()).pin_model != model.pin_model
