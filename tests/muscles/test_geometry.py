"""Muscle path geometry: lengths, analytic Jacobians ∂l/∂θ and moment arms (issue 6)."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pinocchio as pin
import pytest

from msk.datasets.models import leg_model
from msk.exceptions import ModelError, ShapeMismatchError
from msk.model.core import Axis, Joint, Model
from msk.model.joints import FourBarKnee, FourBarTranslation, Linear, SimmSpline
from msk.muscles.geometry import (
    FrameGeometry,
    GeometryPlan,
    MuscleGeometry,
    geometry_plan,
    muscle_geometry,
    muscle_parameters,
)
from msk.muscles.hill import MuscleParameters
from msk.muscles.path import (
    ConditionalPathPoint,
    MovingPathPoint,
    Muscle,
    PathPoint,
    PathWrap,
    WrapObject,
)
from tests.support.opensim_geometry import opensim_geometry

# the crossed four-bar of tests/model/test_joints.py (femur frame: x anterior, y proximal)
KNEE = FourBarKnee(
    femur_a=(-0.010, -0.395),
    femur_b=(0.008, -0.400),
    tibia_c=(0.012, -0.010),
    tibia_d=(-0.018, -0.022),
    theta_ref=0.0,
    p_ref=(0.0, -0.405),
)
KNEE_IDX = 9

# gait2392-like patellar-tendon insertion: tibia-frame location as splines of the knee angle
_KA = (-2.0944, -1.22173, -0.523599, -0.349066, -0.174533, 0.0, 0.00174533, 0.10472)
PATELLA_X = SimmSpline(_KA, (0.0155, 0.0226, 0.0394, 0.0411, 0.0421, 0.0421, 0.0421, 0.0421))
PATELLA_Y = SimmSpline(_KA, (0.0234, 0.0276, 0.0268, 0.0253, 0.0237, 0.0237, 0.0237, 0.0237))


def _pt(name, body, xyz):
    return PathPoint(name, body, np.asarray(xyz, dtype=float))


def _muscle(name, points, wraps=(), f_iso=1000.0, l_opt=0.1, l_ts=0.2, pen=0.1):
    return Muscle(name, tuple(points), f_iso, l_opt, l_ts, pen, 10.0, wraps=tuple(wraps))


WRAPS = [
    # unconstrained cylinder around the distal femur (quadriceps), axis along z (medio-lateral)
    WrapObject(
        "KnExt_at_fem", "femur", "cylinder", np.array([0.00358, -0.402, 0.0]),
        np.array([0.0, 0.0, 0.1]), radius=0.025, length=0.1,
    ),
    # gastrocnemius at the condyles: forced around the posterior side (quadrant -x)
    WrapObject(
        "Gastroc_at_condyles", "femur", "cylinder", np.array([-0.005, -0.41, 0.0]),
        np.array([0.05, 0.02, 0.0]), radius=0.025, length=0.1, quadrant="-x",
    ),
    # and at the shank (second wrap on the same path, on another body)
    WrapObject(
        "Gas_at_shank", "tibia", "cylinder", np.array([-0.03, -0.1, 0.0]),
        np.array([0.0, 0.0, 0.0]), radius=0.02, length=0.1, quadrant="-x",
    ),
]  # fmt: skip


def muscles_for_leg() -> list[Muscle]:
    """Via, conditional, moving points and cylinder wraps on the pelvis–femur–tibia–foot leg."""
    return [
        _muscle("glut_med", [_pt("o", "pelvis", [-0.04, 0.03, 0.12]),
                             _pt("i", "femur", [-0.02, -0.01, 0.055])]),
        _muscle("semimem", [
            _pt("o", "pelvis", [-0.12, -0.10, 0.07]),
            ConditionalPathPoint("c", "tibia", np.array([-0.035, -0.035, -0.019]),
                                 coordinate="knee_angle", range=(-0.5585, 0.1745)),
            _pt("i", "tibia", [-0.024, -0.054, -0.019]),
        ]),
        _muscle("rect_fem", [
            _pt("o", "pelvis", [-0.03, -0.03, 0.097]),
            ConditionalPathPoint("c", "femur", np.array([0.033, -0.403, 0.002]),
                                 coordinate="knee_angle", range=(-2.618, -1.46)),
            MovingPathPoint("p", "tibia", np.array([0.04, 0.02, 0.0015]),
                            coordinates=("knee_angle", "knee_angle", None),
                            functions=(PATELLA_X, PATELLA_Y, None)),
        ]),
        _muscle("vas_int", [
            _pt("o", "femur", [0.029, -0.192, 0.031]),
            _pt("v", "femur", [0.033, -0.30, 0.002]),
            MovingPathPoint("p", "tibia", np.array([0.04, 0.02, 0.0018]),
                            coordinates=("knee_angle", "knee_angle", None),
                            functions=(PATELLA_X, PATELLA_Y, None)),
        ], wraps=[PathWrap("KnExt_at_fem")]),
        _muscle("med_gas", [
            _pt("o", "femur", [-0.019, -0.393, -0.024]),
            _pt("v", "femur", [-0.030, -0.402, -0.026]),
            _pt("i", "foot", [-0.05, 0.03, -0.005]),
        ], wraps=[PathWrap("Gastroc_at_condyles"), PathWrap("Gas_at_shank")]),
        # a moving point driven by a coordinate of another joint (hip flexion)
        _muscle("odd", [
            _pt("o", "pelvis", [0.0, 0.0, 0.05]),
            MovingPathPoint("m", "femur", np.array([0.01, -0.2, 0.02]),
                            coordinates=("hip_flexion", None, "knee_angle"),
                            functions=(Linear(0.03, 0.01), None, Linear(-0.01, 0.02))),
            _pt("i", "tibia", [0.0, -0.3, 0.03]),
        ]),
    ]  # fmt: skip


def leg_with_muscles(*, four_bar: bool = False) -> Model:
    model = leg_model()
    if four_bar:
        model = model.with_joints({"knee": four_bar_knee_joint()})
    return model.with_muscles(muscles_for_leg()).with_metadata(wrap_objects=WRAPS)


def four_bar_knee_joint() -> Joint:
    return Joint(
        "knee",
        "femur",
        "tibia",
        axes=(
            Axis("prismatic", [1, 0, 0], "knee_angle", FourBarTranslation(KNEE, 0)),
            Axis("prismatic", [0, 1, 0], "knee_angle", FourBarTranslation(KNEE, 1)),
            Axis("revolute", [0, 0, 1], "knee_angle", Linear()),
        ),
    )


def random_poses(model: Model, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    th = rng.uniform(-0.6, 0.6, (n, model.n_coords))
    th[:, :3] = rng.uniform(-0.5, 0.5, (n, 3))
    th[:, KNEE_IDX] = rng.uniform(-2.0, 0.1, n)
    return th


def fd_jacobian(model: Model, th: np.ndarray, h: float = 1e-6) -> np.ndarray:
    out = np.empty((th.shape[0], len(model.muscles), model.n_coords))
    for i in range(model.n_coords):
        e = np.zeros(model.n_coords)
        e[i] = h
        lp = muscle_geometry(model, th + e).lengths
        lm = muscle_geometry(model, th - e).lengths
        out[..., i] = (lp - lm) / (2 * h)
    return out


def assert_jacobian_matches_fd(model: Model, th: np.ndarray, rtol: float = 1e-6) -> float:
    geo = muscle_geometry(model, th)
    fd = fd_jacobian(model, th)
    err = np.linalg.norm(geo.jacobian - fd, axis=-1)
    scale = np.linalg.norm(fd, axis=-1)
    # floor: central differences carry ~1e-10 m/rad of round-off; rows below 1 mm are judged
    # against 1 mm
    rel = err / np.maximum(scale, 1e-3)
    worst = np.unravel_index(np.argmax(rel), rel.shape)
    assert rel.max() < rtol, (
        f"muscle {geo.muscle_names[worst[1]]} frame {worst[0]}: rel err {rel.max():.2e}"
    )
    return float(rel.max())


# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("four_bar", [False, True], ids=["spline_knee", "four_bar_knee"])
def test_analytic_jacobian_equals_central_differences(four_bar):
    model = leg_with_muscles(four_bar=four_bar)
    th = random_poses(model, 40, seed=3 if four_bar else 4)
    assert_jacobian_matches_fd(model, th)


def test_every_path_feature_is_exercised_by_the_random_poses():
    model = leg_with_muscles(four_bar=True)
    th = random_poses(model, 40, seed=3)
    plan = geometry_plan(model)
    assert plan.moving and plan.conditional and len(plan.wraps) == 3
    knee = th[:, KNEE_IDX]
    # both states of each conditional point occur
    for lo, hi in zip(plan.cond_lo, plan.cond_hi):
        inside = (knee >= lo) & (knee <= hi)
        assert inside.any() and (~inside).any()
    # each wrap is on in some frames and off in others; compare with the straight path length
    geo = muscle_geometry(model, th)
    straight = model.with_metadata(wrap_objects=[]).with_muscles(
        [Muscle(m.name, m.points, 1.0, 1.0, 1.0) for m in model.muscles]
    )
    l0 = muscle_geometry(straight, th).lengths
    for name in ("vas_int", "med_gas"):
        i = geo.muscle_index(name)
        wrapped = geo.lengths[:, i] > l0[:, i] + 1e-9
        # the unconstrained cylinder wraps only in flexion; the "-x" quadrant forces the
        # gastrocnemius around the back of the condyles / shank in every pose
        assert wrapped.any() and ((~wrapped).any() if name == "vas_int" else wrapped.all())
        assert np.all(geo.lengths[:, i] >= l0[:, i] - 1e-12)


def test_lengths_equal_point_distances_from_pinocchio_frames():
    """Independent check of l(θ): points as Pinocchio frames, forward kinematics, distances."""
    model = leg_with_muscles()
    th = random_poses(model, 5, seed=7)
    geo = muscle_geometry(model, th)
    pm = model.pin_model.copy()
    fid = {}
    for mus in model.muscles[:2]:
        for k, p in enumerate(mus.points):
            place = model.body_placement[p.body] * pin.SE3(np.eye(3), np.asarray(p.location))
            fid[(mus.name, k)] = pm.addFrame(
                pin.Frame(f"{mus.name}{k}", model.body_joint[p.body], 0, place,
                          pin.FrameType.OP_FRAME)
            )  # fmt: skip
    data = pm.createData()
    for n in range(th.shape[0]):
        pin.framesForwardKinematics(pm, data, model.coupling.q(th[n]))
        x = {key: data.oMf[f].translation for key, f in fid.items()}
        glut = np.linalg.norm(x[("glut_med", 1)] - x[("glut_med", 0)])
        assert geo.lengths[n, 0] == pytest.approx(glut, abs=1e-14)
        knee = th[n, KNEE_IDX]
        pts = [0, 1, 2] if -0.5585 <= knee <= 0.1745 else [0, 2]
        semi = sum(
            np.linalg.norm(x[("semimem", b)] - x[("semimem", a)])
            for a, b in itertools.pairwise(pts)
        )
        assert geo.lengths[n, 1] == pytest.approx(semi, abs=1e-14)


def test_jacobian_equals_frame_jacobian_shifted_to_the_points():
    """∂l/∂q_pin = Σ u_sᵀ (J_{p_{s+1}} − J_{p_s}) with Pinocchio's LOCAL_WORLD_ALIGNED frame
    Jacobian shifted to each point (the formula of the issue), for a two-segment via path."""
    model = leg_with_muscles()
    th = random_poses(model, 3, seed=11)
    plan = GeometryPlan(model)
    geo = plan.evaluate(th)
    data = model.create_data()
    for n in range(th.shape[0]):
        q = model.coupling.q(th[n])
        pin.computeJointJacobians(model.pin_model, data, q)
        pin.updateFramePlacements(model.pin_model, data)
        pts, jacs = [], []
        for p in model.muscles[0].points:
            f = model.body_frame[p.body]
            oMf = data.oMf[f]
            x = oMf.act(np.asarray(p.location))
            jf = pin.getFrameJacobian(
                model.pin_model, data, f, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
            )
            r = x - oMf.translation
            jp = jf[:3] - pin.skew(r) @ jf[3:]
            pts.append(x)
            jacs.append(jp)
        u = (pts[1] - pts[0]) / np.linalg.norm(pts[1] - pts[0])
        dl_dq = u @ (jacs[1] - jacs[0])
        expect = dl_dq @ model.coupling.jacobian(th[n])
        np.testing.assert_allclose(geo.jacobian[n, 0], expect, atol=1e-14)


def test_batch_result_shapes_names_velocities_and_moment_arm_sign():
    model = leg_with_muscles(four_bar=True)
    th = random_poses(model, 7, seed=5)
    thd = np.random.default_rng(0).normal(size=th.shape)
    geo = muscle_geometry(model, th, thd)
    assert isinstance(geo, MuscleGeometry)
    m = len(model.muscles)
    assert geo.lengths.shape == (7, m)
    assert geo.jacobian.shape == (7, m, model.n_coords)
    assert geo.muscle_names == tuple(mu.name for mu in model.muscles)
    assert geo.coordinate_names == model.coordinate_names
    np.testing.assert_allclose(geo.moment_arms, -geo.jacobian)
    # l̇ = J θ̇ equals the derivative of l along θ(t) = θ + t θ̇
    h = 1e-6
    fd = muscle_geometry(model, th + h * thd).lengths - muscle_geometry(model, th - h * thd).lengths
    np.testing.assert_allclose(geo.velocities, fd / (2 * h), rtol=1e-6, atol=1e-9)
    # one frame as a 1-D vector, and frames are independent of the batch they are in
    one = muscle_geometry(model, th[3])
    np.testing.assert_allclose(one.lengths[0], geo.lengths[3], atol=1e-15)
    np.testing.assert_allclose(one.jacobian[0], geo.jacobian[3], atol=1e-15)
    assert muscle_geometry(model, th).velocities is None
    assert geometry_plan(model) is geometry_plan(model)
    with pytest.raises(ShapeMismatchError, match=r"\(N, 10\)"):
        muscle_geometry(model, np.zeros((3, 9)))
    with pytest.raises(ShapeMismatchError, match="qdot"):
        muscle_geometry(model, th, thd[:2])
    with pytest.raises(ModelError, match="no muscle 'nope'"):
        geo.muscle_index("nope")


@pytest.mark.parametrize("four_bar", [False, True])
def test_compact_jacobian_equals_the_dense_one_bit_for_bit(four_bar):
    """``compact=True`` (issue 18: no dense (N, muscles, coordinates) array) gives, at
    :meth:`GeometryPlan.jacobian_positions`, the dense Jacobian's entries bit for bit, zeros
    elsewhere, and the same lengths, velocities and distal wrenches; on wrapped paths (the
    frames iterate together) and on a plan without wraps (evaluated in frame chunks)."""
    from msk.timeseries import FrameSparse

    model = leg_with_muscles(four_bar=four_bar)
    static = model.with_muscles([m for m in muscles_for_leg() if not m.wraps])
    for mdl in (model, static):
        th = random_poses(mdl, 40, seed=11)
        thd = np.random.default_rng(2).normal(size=th.shape)
        dense = muscle_geometry(mdl, th, thd, distal_wrench_joints=("knee",))
        comp = muscle_geometry(mdl, th, thd, distal_wrench_joints=("knee",), compact=True)
        assert isinstance(comp.jacobian, FrameSparse) and not isinstance(
            dense.jacobian, FrameSparse
        )
        pos = geometry_plan(mdl).jacobian_positions()
        np.testing.assert_array_equal(comp.jacobian.positions, pos)
        assert comp.jacobian.values.shape == (40, pos.size)
        assert pos.size < dense.jacobian[0].size  # some entries are structurally zero
        np.testing.assert_array_equal(comp.jacobian[:], dense.jacobian)
        np.testing.assert_array_equal(comp.lengths, dense.lengths)
        np.testing.assert_array_equal(comp.velocities, dense.velocities)
        np.testing.assert_array_equal(comp.distal_wrenches["knee"], dense.distal_wrenches["knee"])


def test_frames_of_a_compact_jacobian_equal_those_of_the_dense_one():
    """``jacobian_frames`` and ``finite_frames`` of a compact Jacobian (FrameSparse) read its
    stored entries only: the same values, zeros, memory layout (coordinate-major) and finite
    flags as of the dense array, for frames in any order, a mask, columns in any order, and
    frames with a NaN entry inside or outside the columns asked for."""
    from msk.muscles.geometry import finite_frames, jacobian_frames
    from msk.timeseries import FrameSparse

    mdl = leg_with_muscles()
    g = muscle_geometry(mdl, random_poses(mdl, 30, seed=4), compact=True)
    sparse_j = g.jacobian
    assert isinstance(sparse_j, FrameSparse)
    vals = sparse_j.values.copy()
    nc = sparse_j.trailing[1]
    vals[3, 0] = np.nan  # a NaN at the first stored entry's coordinate
    sparse_j = FrameSparse(vals, sparse_j.positions, sparse_j.trailing)
    dense = sparse_j[:]
    nan_col = int(sparse_j.positions[0] % nc)
    rng = np.random.default_rng(0)
    for cols in (np.arange(nc), np.array([nan_col, 1, 0]), np.array([c for c in range(nc)
                                                                   if c != nan_col])):  # fmt: skip
        for frames in (np.arange(30), rng.permutation(30)[:11], rng.random(30) < 0.5):
            a = jacobian_frames(sparse_j, frames, cols)
            b = jacobian_frames(dense, frames, cols)
            np.testing.assert_array_equal(a, b)
            assert a.strides == b.strides
        np.testing.assert_array_equal(finite_frames(sparse_j, cols), finite_frames(dense, cols))
        assert finite_frames(sparse_j, cols)[3] == (nan_col not in cols)


def test_moment_arm_pattern_finds_the_coordinates_each_muscle_crosses():
    """``moment_arm_pattern``: (muscle, coordinate) with a nonzero finite moment arm in some of
    the frames asked for — against the finite-difference Jacobian's (an estimate independent
    of the analytic one), the same of a compact and a dense Jacobian, for a subset of frames
    (indices or mask) and columns in any order; an entry zero or NaN in those frames is not
    a moment arm."""
    from msk.muscles.geometry import moment_arm_pattern
    from msk.timeseries import FrameSparse

    mdl = leg_with_muscles()
    th = random_poses(mdl, 12, seed=5)
    truth = (np.abs(fd_jacobian(mdl, th)) > 1e-6).any(axis=0)
    assert truth.any() and not truth.all()  # the root coordinates carry every path
    g = muscle_geometry(mdl, th, compact=True)
    sparse_j = g.jacobian
    assert isinstance(sparse_j, FrameSparse)
    np.testing.assert_array_equal(moment_arm_pattern(sparse_j), truth)
    np.testing.assert_array_equal(moment_arm_pattern(sparse_j[:]), truth)
    # a stored entry nonzero in frame 5 only, another NaN in frame 5 and zero elsewhere
    vals = sparse_j.values.copy()
    nc = sparse_j.trailing[1]
    (m0, c0), (m1, c1) = (divmod(int(p), nc) for p in sparse_j.positions[:2])
    vals[:, 0], vals[5, 0] = 0.0, 0.03
    vals[:, 1], vals[5, 1] = 0.0, np.nan
    sparse_j = FrameSparse(vals, sparse_j.positions, sparse_j.trailing)
    with_5, without_5 = np.array([7, 5, 0]), np.arange(12) != 5
    cols = np.array([c1, c0, nc - 1])
    for jac in (sparse_j, sparse_j[:]):
        full = moment_arm_pattern(jac)
        assert full[m0, c0] and not full[m1, c1]
        assert moment_arm_pattern(jac, with_5)[m0, c0]
        assert not moment_arm_pattern(jac, without_5)[m0, c0]
        np.testing.assert_array_equal(moment_arm_pattern(jac, without_5, cols),
                                      moment_arm_pattern(jac, without_5)[:, cols])  # fmt: skip
        assert not moment_arm_pattern(jac, np.zeros(12, dtype=bool)).any()


def test_tau_equals_minus_jacobian_transpose_force_against_pinocchio_rnea():
    """τ = −J_lᵀ f (seed 002 Eq. 7): the tension f of a straight muscle applied as two opposite
    point forces on its bodies gives, through Pinocchio's RNEA (no gravity, at rest), the same
    generalised forces once projected on θ (τ_θ = Gᵀ τ_pin)."""
    model = leg_with_muscles()
    pm = model.pin_model.copy()
    pm.gravity = pin.Motion.Zero()
    data = pm.createData()
    th = random_poses(model, 3, seed=2)
    geo = muscle_geometry(model, th)
    f = 250.0
    mus = model.muscles[0]
    for n in range(3):
        q = model.coupling.q(th[n])
        pin.forwardKinematics(pm, data, q)
        pin.updateFramePlacements(pm, data)
        xs = [data.oMf[model.body_frame[p.body]].act(np.asarray(p.location)) for p in mus.points]
        u = (xs[1] - xs[0]) / np.linalg.norm(xs[1] - xs[0])
        fext = [pin.Force.Zero() for _ in range(pm.njoints)]
        for p, x, force in ((mus.points[0], xs[0], f * u), (mus.points[1], xs[1], -f * u)):
            jid = model.body_joint[p.body]
            omi = data.oMi[jid]
            local = omi.actInv(pin.Force(force, np.cross(x, force)))  # world wrench → joint
            fext[jid] = fext[jid] + local
        tau = pin.rnea(pm, data, q, np.zeros(pm.nv), np.zeros(pm.nv), fext)
        tau_theta = model.coupling.project(th[n], -tau)  # joint torques that the muscle produces
        np.testing.assert_allclose(tau_theta, -geo.jacobian[n, 0] * f, atol=1e-10)


def test_muscle_parameters_in_model_order():
    model = leg_with_muscles()
    params = muscle_parameters(model)
    assert isinstance(params, MuscleParameters)
    assert params.names == tuple(m.name for m in model.muscles)
    np.testing.assert_allclose(params.max_isometric_force, 1000.0)
    np.testing.assert_allclose(params.pennation_angle_at_optimal, 0.1)
    with pytest.raises(ModelError, match=r"not an msk\.muscles\.path\.Muscle"):
        muscle_parameters(model.with_muscles(["x"]))


def test_bad_paths_raise_model_error_naming_muscle_and_object():
    base = leg_model()
    o = _pt("o", "pelvis", [0, 0, 0])
    i = _pt("i", "femur", [0, -0.2, 0])
    ell = WrapObject("pat_ell", "femur", "ellipsoid", np.zeros(3), np.zeros(3),
                     dimensions=np.array([0.03, 0.02, 0.05]))  # fmt: skip
    cases = [
        (_muscle("m1", [o, _pt("i", "humerus", [0, 0, 0])]), [], "m1.*unknown body 'humerus'"),
        (_muscle("m2", [o, i], wraps=[PathWrap("pat_ell")]), [ell],
         "m2: wrap object 'pat_ell' of kind 'ellipsoid' is not supported"),
        (_muscle("m3", [o, i], wraps=[PathWrap("nowhere")]), [], "m3: wrap object 'nowhere'"),
        (_muscle("m4", [ConditionalPathPoint("c", "pelvis", np.zeros(3), coordinate="knee_angle"),
                        i]), [], "m4 point c: origin/insertion cannot be conditional"),
        (_muscle("m5", [o, ConditionalPathPoint("c", "femur", np.zeros(3), coordinate="elbow"),
                        i]), [], "m5 point c: unknown coordinate 'elbow'"),
        (_muscle("m6", [o]), [], "m6: needs at least 2"),
        (_muscle("m7", [o, i], wraps=[PathWrap("KnExt_at_fem", range=(2, 5))]), WRAPS,
         "m7: wrap 'KnExt_at_fem' range"),
    ]  # fmt: skip
    for mus, wraps, msg in cases:
        model = base.with_muscles([mus]).with_metadata(wrap_objects=wraps)
        with pytest.raises(ModelError, match=msg):
            GeometryPlan(model)
    # inactive wrap objects are ignored, as OpenSim does
    off = WrapObject("off", "femur", "torus", np.zeros(3), np.zeros(3), active=False)
    GeometryPlan(
        base.with_muscles([_muscle("m8", [o, i], wraps=[PathWrap("off")])]).with_metadata(
            wrap_objects=[off]
        )
    )


def test_batched_forward_kinematics_equals_pinocchio():
    from msk.muscles.geometry import _batched_fk, _tree_structure

    model = leg_with_muscles(four_bar=True)
    th = random_poses(model, 4, seed=9)
    q = model.coupling.q(th)
    pm = model.pin_model
    rot, trans, jac = _batched_fk(_tree_structure(pm), q, pm.nv)
    data = pm.createData()
    for n in range(4):
        ref = pin.computeJointJacobians(pm, data, q[n])
        np.testing.assert_allclose(jac[n], ref, atol=1e-13)
        for j in range(1, pm.njoints):
            np.testing.assert_allclose(rot[n, j], data.oMi[j].rotation, atol=1e-13)
            np.testing.assert_allclose(trans[n, j], data.oMi[j].translation, atol=1e-13)


# --------------------------------------------------------------------------------------------
# real models (need msk.model.osim) and OpenSim 4.6 (child process)
# --------------------------------------------------------------------------------------------
GAIT2392_SUBJECT01 = "Pipelines/Gait2392_Simbody/OutputReference/subject01_simbody.osim"
GAIT2392_IK = "Pipelines/Gait2392_Simbody/OutputReference/subject01_walk1_ik.mot"
LEG_COORDS = ("hip_flexion", "hip_adduction", "hip_rotation", "knee_angle", "ankle_angle",
              "subtalar_angle", "mtp_angle")  # fmt: skip


def _load_osim(path):
    import msk.model.osim as osim

    if not path.is_file():
        pytest.skip(f"model file absent: {path}")
    return osim.load_osim(path)


def _peer_data():
    from msk.datasets.shared import shared_dir

    d = shared_dir() / "tools" / "opensim-peer" / "data"
    if not d.is_dir():
        pytest.skip(f"OpenSim peer data absent: {d}")
    return d


def read_ik_mot(path, model: Model) -> np.ndarray:
    """θ (N, n_coords) from an OpenSim IK .mot (degrees for rotational coordinates), in model
    coordinate order; coordinates absent from the file keep their default."""
    lines = path.read_text().splitlines()
    end = next(i for i, ln in enumerate(lines) if ln.strip().lower() == "endheader")
    head = lines[end + 1].split("\t")
    data = np.array([[float(v) for v in ln.split()] for ln in lines[end + 2 :] if ln.strip()])
    th = np.tile(model.default_coordinates(), (data.shape[0], 1))
    for i, c in enumerate(model.coordinates):
        if c.name in head:
            col = data[:, head.index(c.name)]
            th[:, i] = np.deg2rad(col) if c.kind == "rotational" else col
    return th


TRUNK = ("ercspn", "intobl", "extobl")


def right_leg(model: Model) -> tuple[list[int], list[int]]:
    mus = [
        k
        for k, m in enumerate(model.muscles)
        if m.name.endswith("_r") and not m.name.startswith(TRUNK)
    ]
    coords = [model.coordinate_index(f"{c}_r") for c in LEG_COORDS]
    return mus, coords


@pytest.mark.parametrize(
    "where", ["opensim-models/gait2392_thelen2003muscle.osim", "opensim-models/Rajagopal2016.osim"]
)
def test_real_models_analytic_jacobian_equals_central_differences(ref_dir, where):
    model = _load_osim(ref_dir / where)
    rng = np.random.default_rng(0)
    lo, hi = model.coordinate_bounds()
    th = model.default_coordinates() + rng.uniform(-0.3, 0.3, (6, model.n_coords))
    # stay off the range ends: gait2392's conditional points switch exactly at knee_angle's bound
    th = np.clip(th, lo + 0.02, hi - 0.02)
    assert_jacobian_matches_fd(model, th)


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.opensim
def test_gait2392_right_leg_matches_opensim_over_the_subject01_walk(needs_opensim):
    """Lengths and moment arms (7 right-leg coordinates) of the 43 right-leg muscles of the
    scaled gait2392 vs OpenSim 4.6 getLength / computeMomentArm, 16 frames of the walk IK."""
    data = _peer_data()
    path = data / GAIT2392_SUBJECT01
    model = _load_osim(path)
    th = read_ik_mot(data / GAIT2392_IK, model)
    th = th[np.linspace(0, th.shape[0] - 1, 16).astype(int)]
    mus, coords = right_leg(model)
    lengths, arms = opensim_geometry(path, model, th, mus, coords)
    geo = muscle_geometry(model, th)
    dl = np.abs(geo.lengths[:, mus] - lengths).max(axis=0)
    dr = np.abs(geo.moment_arms[:, mus][:, :, coords] - arms).max(axis=(0, 2))
    worst = int(np.argmax(np.maximum(dl, dr)))
    name = model.muscles[mus[worst]].name
    print(f"gait2392 vs OpenSim: worst {name}: length {dl[worst]:.2e} m, arm {dr[worst]:.2e} m")
    assert len(mus) == 43
    assert dl.max() < 1e-4 and dr.max() < 1e-4, (name, dl[worst], dr[worst])


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.opensim
def test_rajagopal_right_leg_with_wrap_cylinders_matches_opensim(needs_opensim, ref_dir):
    """Rajagopal 2016 (46 cylinder wraps) driven by the subject01 walk (coordinates shared by
    name): via-point muscles agree to 0.1 mm; cylinder-wrapping ones within OpenSim's own
    approximation of the geodesic (see docs/muscle_geometry.md)."""
    data = _peer_data()
    path = ref_dir / "opensim-models" / "Rajagopal2016.osim"
    model = _load_osim(path)
    g2392 = _load_osim(data / GAIT2392_SUBJECT01)
    walk = read_ik_mot(data / GAIT2392_IK, g2392)[::14]
    th = np.tile(model.default_coordinates(), (walk.shape[0], 1))
    for i, c in enumerate(model.coordinates):
        if c.name in g2392.coordinate_names:
            th[:, i] = walk[:, g2392.coordinate_index(c.name)]
    mus, coords = right_leg(model)
    lengths, arms = opensim_geometry(path, model, th, mus, coords)
    geo = muscle_geometry(model, th)
    dl = np.abs(geo.lengths[:, mus] - lengths).max(axis=0)
    dr = np.abs(geo.moment_arms[:, mus][:, :, coords] - arms).max(axis=(0, 2))
    wrapping = np.array([bool(model.muscles[k].wraps) for k in mus])
    for k in np.flatnonzero(wrapping):
        print(f"  {model.muscles[mus[k]].name:14s} {len(model.muscles[mus[k]].wraps)} wraps: "
              f"length {dl[k] * 1e3:.3f} mm, arm {dr[k] * 1e3:.3f} mm")  # fmt: skip
    for label, sel in (("via", ~wrapping), ("wrapping", wrapping)):
        k = int(np.argmax(np.where(sel, np.maximum(dl, dr), -1.0)))
        print(f"Rajagopal {label}: worst {model.muscles[mus[k]].name}: length {dl[k]:.2e} m, "
              f"arm {dr[k]:.2e} m")  # fmt: skip
    assert dl[~wrapping].max() < 1e-4 and dr[~wrapping].max() < 1e-4
    # one cylinder: msk's path is the exact geodesic; OpenSim 4.6 places the tangent points by
    # a plane-intersection approximation (no tangency iteration for a single wrap), so its
    # path is never shorter than ours, and longer by up to ~1 mm in deep knee flexion
    single = wrapping & np.array([len(model.muscles[k].wraps) == 1 for k in mus])
    ours = geo.lengths[:, mus][:, single]
    assert np.all(ours <= lengths[:, single] + 1e-6)
    assert dl[single].max() < 1.5e-3 and dr[single].max() < 1e-2
    # two cylinders (gastrocnemii): OpenSim stops its wrap iterations at 0.5 mm of length
    # change and its path can cut into the shank cylinder; ours is the converged one
    assert dl[wrapping].max() < 5e-2


@pytest.mark.slow
@pytest.mark.realdata
def test_knee_moment_arms_spline_vs_four_bar_are_plausible():
    """Quadriceps and hamstrings knee moment arms, 0–120° flexion, gait2392 spline knee vs a
    four-bar fitted to it (msk.model.fourbar_fit): quadriceps extend with 2–6 cm and average 4–6 cm
    over 0–60° (in-vivo range cited by seed 000); hamstrings flex; both knees agree within 4 mm
    (the four-bar reproduces the spline path, its rolling–gliding enters through G)."""
    import msk.model.fourbar_fit as fourbar_fit

    model = _load_osim(_peer_data() / GAIT2392_SUBJECT01)
    knee = next(j for j in model.joints if j.name == "knee_r")
    fit = fourbar_fit.fit_four_bar_to_joint(knee, flexion=(0.0, -np.deg2rad(120.0)))
    four_bar = model.with_joints({"knee_r": fourbar_fit.four_bar_joint(knee, fit.knee)})
    flexion = np.linspace(0.0, 120.0, 61)
    quads = ("rect_fem_r", "vas_med_r", "vas_int_r", "vas_lat_r")
    hams = ("semimem_r", "semiten_r", "bifemlh_r", "bifemsh_r")
    arms = {}
    for label, mdl in (("spline", model), ("four-bar", four_bar)):
        th = np.tile(mdl.default_coordinates(), (flexion.size, 1))
        k = mdl.coordinate_index("knee_angle_r")
        th[:, k] = -np.deg2rad(flexion)
        geo = muscle_geometry(mdl, th)
        r = {m: geo.moment_arms[:, geo.muscle_index(m), k] for m in quads + hams}
        arms[label] = r
        for m in quads:
            assert np.all((r[m] > 0.02) & (r[m] < 0.06)), (label, m, r[m].min(), r[m].max())
            early = r[m][flexion <= 60.0].mean()
            assert 0.04 <= early <= 0.06, (label, m, early)
        for m in hams:
            assert np.all(r[m][flexion <= 90.0] < -0.01), (label, m)
    for m in quads + hams:
        assert np.abs(arms["spline"][m] - arms["four-bar"][m]).max() < 4e-3, m
    # and the four-bar's moment arms are the derivative of its lengths (G carries p'(θ))
    th = np.tile(four_bar.default_coordinates(), (8, 1))
    th[:, four_bar.coordinate_index("knee_angle_r")] = -np.linspace(0.05, 2.0, 8)
    assert_jacobian_matches_fd(four_bar, th)


def test_grouped_function_evaluation_equals_the_functions_and_the_coupling():
    from msk.model.joints import Multiplier, Polynomial
    from msk.muscles.geometry import _group_functions

    knots = (-2.0, -1.2, -0.5, 0.0, 0.1)
    funs = [
        Multiplier(SimmSpline(knots, (0.01, 0.02, 0.04, 0.05, 0.05)), 0.97),
        SimmSpline(knots, (0.3, 0.1, 0.0, -0.1, 0.2)),
        Linear(0.3, -0.1),
        Polynomial((0.1, 0.0, -0.2)),
        SimmSpline((0.0, 1.0), (0.0, 2.0)),
    ]
    groups = _group_functions([(k, k, 0, 0, f) for k, f in enumerate(funs)])
    assert len(groups) == 3  # the two splines on the same knots share one table
    x = np.linspace(-2.5, 0.6, 53)  # includes both extrapolation ranges
    for grp in groups:
        val, d1 = grp.evaluate(x)
        for j, e in enumerate(grp.entries):
            np.testing.assert_allclose(val[:, j], funs[e](x), atol=1e-15)
            np.testing.assert_allclose(d1[:, j], funs[e].d1(x), atol=1e-14)
    model = leg_with_muscles(four_bar=True)
    th = random_poses(model, 6, seed=1)
    q, g = GeometryPlan(model)._embed(th)
    np.testing.assert_allclose(q, model.coupling.q(th), atol=1e-15)
    np.testing.assert_allclose(g, model.coupling.jacobian(th), atol=1e-15)


def test_plan_cache_does_not_keep_models_alive_and_plans_are_not_mixed():
    import gc
    import weakref

    from msk.muscles import geometry

    model = leg_with_muscles()
    geometry_plan(model)
    ref = weakref.ref(model)
    other = leg_with_muscles()
    with pytest.raises(ModelError, match="plan was built for model 'leg'"):
        muscle_geometry(other, np.zeros(10), plan=geometry_plan(model))
    del model
    gc.collect()
    assert ref() is None
    assert all(k is not None for k in geometry._PLANS.keys())


# --------------------------------------------------------------------------------------------
# the fast evaluation paths (issue 6 speed work): same results as the direct definitions
# --------------------------------------------------------------------------------------------
def test_function_bank_equals_the_functions_whatever_their_knots():
    from msk.model.joints import Constant, Multiplier, Polynomial
    from msk.muscles.geometry import _FunctionBank

    funs = [
        Multiplier(SimmSpline((-2.0, -1.2, -0.5, 0.0, 0.1), (0.01, 0.02, 0.04, 0.05, 0.05)), 0.97),
        SimmSpline((0.0, 1.0), (0.0, 2.0)),
        Linear(0.3, -0.1),
        Polynomial((0.1, 0.0, -0.2)),
        SimmSpline(_KA, (0.0155, 0.0226, 0.0394, 0.0411, 0.0421, 0.0421, 0.0421, 0.0421)),
        Constant(0.25),
        Linear(-1.5, 0.0),
        Multiplier(Linear(0.7, 0.2), -1.3),
    ]
    coords = np.array([0, 1, 0, 2, 1, 2, 2, 1])
    bank = _FunctionBank(coords, funs)
    rng = np.random.default_rng(5)
    th = rng.uniform(-2.6, 1.4, (64, 3))  # beyond every spline's knots on both sides
    th[:5, :] = [
        [-2.0, 0.0, 0.1],
        [-1.2, 1.0, 0.0],
        [0.1, -2.0944, 0.2],
        [0.0, 0.10472, 0],
        [0] * 3,
    ]
    val, d1 = bank.evaluate(th)
    for e, (c, f) in enumerate(zip(coords, funs)):
        np.testing.assert_allclose(val[:, e], f(th[:, c]), rtol=0, atol=1e-15)
        np.testing.assert_allclose(d1[:, e], f.d1(th[:, c]), rtol=0, atol=1e-14)


def _chained_conditional_model() -> Model:
    """Two consecutive conditional via points on one path (the segment before them ends at the
    first active one of three candidates), next to a moving point."""
    chain = _muscle("chain", [
        _pt("o", "pelvis", [-0.11, -0.08, 0.07]),
        ConditionalPathPoint("c1", "femur", np.array([-0.03, -0.38, -0.01]),
                             coordinate="knee_angle", range=(-1.5, -0.5)),
        ConditionalPathPoint("c2", "tibia", np.array([-0.035, -0.03, -0.02]),
                             coordinate="knee_angle", range=(-0.8, -0.1)),
        MovingPathPoint("p", "tibia", np.array([0.04, -0.06, 0.0]),
                        coordinates=("knee_angle", "knee_angle", None),
                        functions=(PATELLA_X, PATELLA_Y, None)),
        _pt("i", "foot", [0.02, 0.01, 0.0]),
    ])  # fmt: skip
    return leg_model().with_muscles([*muscles_for_leg()[:3], chain])  # no wraps


def test_consecutive_conditional_points_lengths_and_jacobian():
    model = _chained_conditional_model()
    th = random_poses(model, 60, seed=11)
    plan = geometry_plan(model)
    assert plan._static and plan._dyn_cand.shape[1] == 3  # o → c1 | c2 | p
    knee = th[:, KNEE_IDX]
    c1, c2 = (knee >= -1.5) & (knee <= -0.5), (knee >= -0.8) & (knee <= -0.1)
    assert all(((c1 == x) & (c2 == y)).any() for x in (0, 1) for y in (0, 1))  # 4 states
    assert_jacobian_matches_fd(model, th)
    geo = muscle_geometry(model, th)
    pm = model.pin_model
    data = pm.createData()
    mus = model.muscles[-1]
    q = model.coupling.q(th)
    seen = set()
    for n in range(th.shape[0]):
        pin.framesForwardKinematics(pm, data, q[n])
        pts = []
        for pt in mus.points:
            if isinstance(pt, ConditionalPathPoint):
                lo, hi = pt.range
                if not lo <= th[n, KNEE_IDX] <= hi:
                    continue
                seen.add(pt.name)
            loc = np.asarray(pt.location, dtype=float).copy()
            if isinstance(pt, MovingPathPoint):
                loc[:2] = [pt.functions[0](th[n, KNEE_IDX]), pt.functions[1](th[n, KNEE_IDX])]
            frame = data.oMf[pm.getFrameId(pt.body)]
            pts.append(frame.rotation @ loc + frame.translation)
        ref = sum(np.linalg.norm(b - a) for a, b in itertools.pairwise(pts))
        assert abs(geo.lengths[n, -1] - ref) < 1e-12, n
    assert seen == {"c1", "c2"}
    # a coordinate the path does not cross (the pelvis DOFs carry the whole path) is exactly 0
    assert np.all(geo.jacobian[:, :, :6] == 0.0)


def test_frame_geometry_equals_the_plan_evaluation():
    """One frame at a time (a stream) through moving and consecutive conditional points (every
    activity state), with the knee's distal wrenches: the batch's lengths, velocities, compact
    Jacobian and wrenches to round-off."""
    model = _chained_conditional_model()
    th = random_poses(model, 60, seed=12)
    thd = np.random.default_rng(5).standard_normal(th.shape)
    plan = geometry_plan(model)
    assert plan.moving and plan.cond_points.size
    full = plan.evaluate(th, thd, distal_wrench_joints=("knee",), compact=True)
    frame = FrameGeometry(plan, ("knee",))
    for n in range(th.shape[0]):
        out = frame.evaluate(th[n], thd[n])
        np.testing.assert_allclose(out.lengths, full.lengths[n], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(out.velocities, full.velocities[n], rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(out.jacobian, full.jacobian.values[n], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(
            out.distal_wrenches["knee"], full.distal_wrenches["knee"][n], rtol=1e-12, atol=1e-15
        )
    with pytest.raises(ModelError, match="wrapping"):
        FrameGeometry(geometry_plan(leg_with_muscles()))


@pytest.mark.parametrize("four_bar", [False, True], ids=["spline_knee", "four_bar_knee"])
def test_few_frame_calls_equal_the_batch(four_bar):
    """Few frames take Pinocchio's forward kinematics frame by frame, batches the numpy one;
    single-frame calls, short and long batches agree."""
    model = leg_with_muscles(four_bar=four_bar)
    th = random_poses(model, 24, seed=21)
    thd = np.random.default_rng(2).standard_normal(th.shape)
    plan = GeometryPlan(model)
    full = plan.evaluate(th, thd)
    for sl in (slice(0, 1), slice(3, 7), slice(5, 20)):
        part = plan.evaluate(th[sl], thd[sl])
        np.testing.assert_allclose(part.lengths, full.lengths[sl], rtol=0, atol=1e-14)
        np.testing.assert_allclose(part.jacobian, full.jacobian[sl], rtol=0, atol=1e-13)
        np.testing.assert_allclose(part.velocities, full.velocities[sl], rtol=0, atol=1e-13)
    np.testing.assert_allclose(
        full.velocities, np.einsum("nmi,ni->nm", full.jacobian, thd), rtol=0, atol=1e-14
    )


def test_chunked_batches_equal_one_pass():
    model = _chained_conditional_model()
    th = random_poses(model, 37, seed=4)
    thd = np.random.default_rng(3).standard_normal(th.shape)
    plan = GeometryPlan(model)
    assert plan._chunk > th.shape[0]
    ref = plan.evaluate(th, thd)
    plan._chunk = 5  # 8 chunks, the last one of 2 frames (Pinocchio's kinematics)
    out = plan.evaluate(th, thd)
    np.testing.assert_allclose(out.lengths, ref.lengths, rtol=0, atol=1e-14)
    np.testing.assert_allclose(out.jacobian, ref.jacobian, rtol=0, atol=1e-13)
    np.testing.assert_allclose(out.velocities, ref.velocities, rtol=0, atol=1e-13)


def _rajagopal_walk(ref_dir, frames):
    data = _peer_data()
    model = _load_osim(ref_dir / "opensim-models" / "Rajagopal2016.osim")
    g2392 = _load_osim(data / GAIT2392_SUBJECT01)
    walk = read_ik_mot(data / GAIT2392_IK, g2392)[frames]
    th = np.tile(model.default_coordinates(), (walk.shape[0], 1))
    for i, c in enumerate(model.coordinates):
        if c.name in g2392.coordinate_names:
            th[:, i] = walk[:, g2392.coordinate_index(c.name)]
    return model, th


# frames of the subject01 walk where the two wraps of a Rajagopal gastrocnemius used to
# alternate between two paths (~0.47 m and ~0.72 m) without converging
CYCLE_FRAMES = {"gasmed_l": (31, 92, 105, 165, 178), "gasmed_r": (129, 142)}


@pytest.mark.slow
@pytest.mark.realdata
def test_wrap_iteration_shortcuts_keep_the_plain_iteration_result(ref_dir, monkeypatch):
    """Two wraps on one path (Rajagopal's gastrocnemii): the Aitken-extrapolated iteration
    gives what the plain iteration to convergence gives, 2-cycle frames included, and neither
    depends on the parity of the pass limit (it used to: a 2-cycle ended on the state the
    limit landed on)."""
    from msk.muscles import geometry

    model, th = _rajagopal_walk(ref_dir, [10, 31, 50, 92, 129, 150, 165])
    plan = GeometryPlan(model)
    fast = plan.evaluate(th)
    monkeypatch.setattr(geometry, "_AITKEN", False)
    plain = plan.evaluate(th)
    np.testing.assert_allclose(fast.lengths, plain.lengths, rtol=0, atol=1e-13)
    np.testing.assert_allclose(fast.jacobian, plain.jacobian, rtol=0, atol=1e-10)
    monkeypatch.setattr(geometry, "_MAX_WRAP_PASSES", geometry._MAX_WRAP_PASSES + 1)
    odd = plan.evaluate(th)
    np.testing.assert_allclose(odd.lengths, plain.lengths, rtol=0, atol=1e-13)
    np.testing.assert_allclose(odd.jacobian, plain.jacobian, rtol=0, atol=1e-10)


@pytest.mark.slow
@pytest.mark.realdata
def test_two_cylinder_cycles_resolve_to_a_fixed_point_with_an_exact_jacobian(ref_dir):
    """At the frames where the gastrocnemius wraps alternate between two paths, the path is
    a fixed point of one topology (the shank wrap alone): no 0.72 m path, the length of the
    plain iteration with the condyle wrap removed, and the analytic Jacobian equals central
    differences there (envelope theorem)."""
    frames = sorted({f for fs in CYCLE_FRAMES.values() for f in fs})
    model, th = _rajagopal_walk(ref_dir, frames)
    plan = GeometryPlan(model)
    geo = plan.evaluate(th)
    # the cycle is really met (the resolution is exercised) ...
    cycles = []
    orig = GeometryPlan._resolve_cycles

    def spy(self, st, rot, trans, wr, cycled):
        cycles.append({self.muscle_names[m] for m in self._multi_muscles[cycled.any(axis=1)]})
        return orig(self, st, rot, trans, wr, cycled)

    try:
        GeometryPlan._resolve_cycles = spy
        plan.evaluate(th)
    finally:
        GeometryPlan._resolve_cycles = orig
    assert cycles == [set(CYCLE_FRAMES)]
    # ... and every gastrocnemius stays a ~0.45–0.48 m path
    gas = [plan.muscle_names.index(n) for n in ("gaslat_l", "gaslat_r", "gasmed_l", "gasmed_r")]
    assert np.all((geo.lengths[:, gas] > 0.44) & (geo.lengths[:, gas] < 0.48))
    # the same muscles without their condyle wrap (a plain single-wrap path): same lengths
    # and Jacobians at those frames
    shank_only = model.with_muscles(
        [
            dataclasses.replace(
                m, wraps=tuple(w for w in m.wraps if "condyles" not in str(w.wrap_object))
            )
            if m.name in CYCLE_FRAMES
            else m
            for m in model.muscles
        ]
    )
    ref = muscle_geometry(shank_only, th)
    for name, fs in CYCLE_FRAMES.items():
        k = plan.muscle_names.index(name)
        rows = [frames.index(f) for f in fs]
        np.testing.assert_allclose(geo.lengths[rows, k], ref.lengths[rows, k], rtol=0, atol=1e-12)
        np.testing.assert_allclose(geo.jacobian[rows, k], ref.jacobian[rows, k], atol=1e-10)
    assert_jacobian_matches_fd(model, th)


@pytest.mark.slow
@pytest.mark.realdata
def test_rajagopal_lengths_are_continuous_along_the_walk(ref_dir):
    """Every Rajagopal muscle over the 211 frames of the subject01 walk: no jump > 2 cm
    between neighbouring frames (a 2-cycle of the gastrocnemius wraps used to return a
    0.72 m path between 0.46–0.47 m neighbours)."""
    model, th = _rajagopal_walk(ref_dir, slice(None))
    assert th.shape[0] == 211
    geo = muscle_geometry(model, th)
    jump = np.abs(np.diff(geo.lengths, axis=0))
    f, k = np.unravel_index(np.argmax(jump), jump.shape)
    assert jump.max() < 0.02, (geo.muscle_names[k], int(f), float(jump.max()))


def test_extrapolated_wrap_iteration_equals_the_plain_one(monkeypatch):
    from msk.muscles import geometry

    model = leg_with_muscles(four_bar=True)
    th = random_poses(model, 40, seed=6)
    plan = GeometryPlan(model)
    fast = plan.evaluate(th)
    monkeypatch.setattr(geometry, "_AITKEN", False)
    plain = plan.evaluate(th)
    np.testing.assert_allclose(fast.lengths, plain.lengths, rtol=0, atol=1e-13)
    np.testing.assert_allclose(fast.jacobian, plain.jacobian, rtol=0, atol=1e-10)
