"""msk.io.osim_writer: an msk model as an OpenSim 4 .osim — read back by msk's importer and by
OpenSim 4.6 (child process) with the same bodies and the same marker positions at any pose."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from msk.exceptions import ModelError
from msk.io.osim_writer import body_fixed_xyz_angles, write_osim
from msk.model.core import Axis, Body, Coordinate, Joint, Marker, Model, marker_positions
from msk.model.joints import Composite, Linear, Multiplier, PiecewiseLinear, Polynomial, SimmSpline
from msk.model.osim import body_fixed_xyz, load_osim

REPO = Path(__file__).resolve().parents[2]


def test_orientation_angles_invert_the_body_fixed_rotation():
    rng = np.random.default_rng(0)
    for ang in [*rng.uniform(-3, 3, size=(50, 3)), (0.3, np.pi / 2, 0.0), (0.2, -np.pi / 2, 0.0)]:
        r = body_fixed_xyz(ang)
        np.testing.assert_allclose(body_fixed_xyz(body_fixed_xyz_angles(r)), r, atol=1e-12)


def _chain(knee_x: object = None, foreign: bool = False) -> Model:
    """Ground → thigh (free: 3 translations, 3 rotations) → shank (an oblique hinge, its
    translations functions of the flexion) → foot (a weld)."""
    rng = np.random.default_rng(1)
    bodies = [
        Body(n, m, rng.uniform(-0.1, 0.1, 3), np.diag(rng.uniform(0.01, 0.2, 3)))
        for n, m in (("thigh", 8.0), ("shank", 3.5), ("foot", 1.1))
    ]
    lin = Linear()
    free = Joint("free", "ground", "thigh", axes=(
        *(Axis("prismatic", e, c, lin) for e, c in zip(np.eye(3), ("tx", "ty", "tz"))),
        *(Axis("revolute", e, c, lin) for e, c in zip(np.eye(3), ("rx", "ry", "rz"))),
    ))  # fmt: skip
    fx = knee_x or Multiplier(SimmSpline((-2.0, -1.0, 0.0, 0.5), (0.01, -0.004, 0.0, 0.002)), 1.1)
    knee = Joint(
        "knee", "thigh", "shank",
        pin.SE3(body_fixed_xyz((0.1, -0.2, 0.3)), np.array([0.0, -0.4, 0.01])),
        pin.SE3(body_fixed_xyz((0.0, 0.05, -0.1)), np.array([0.0, 0.02, 0.0])),
        (
            Axis("prismatic", (1, 0, 0), "rx" if foreign else "flex", fx),
            Axis("prismatic", (0, 1, 0), "flex", PiecewiseLinear((-2.0, 0.0, 1.0), (0, 0.01, 0))),
            Axis("revolute", (0.1, 0.2, 0.97), "flex", Polynomial((0.05, 1.0, 0.0))),
        ),
    )  # fmt: skip
    weld = Joint("ankle", "shank", "foot", pin.SE3(np.eye(3), np.array([0.0, -0.43, 0.0])))
    coords = [Coordinate(c, "translational") for c in ("tx", "ty", "tz")]
    coords += [Coordinate(c) for c in ("rx", "ry", "rz")]
    coords += [Coordinate("flex", range=(-2.0, 0.5), default=-0.1)]
    markers = [Marker(f"M{k}", b, rng.uniform(-0.1, 0.1, 3)) for k, b in
               enumerate(("thigh", "shank", "foot", "ground"))]  # fmt: skip
    return Model(name="chain", bodies=bodies, joints=[free, knee, weld], coordinates=coords,
                 markers=markers)  # fmt: skip


def _same_model(a: Model, b: Model, n: int = 8) -> None:
    assert [mk.name for mk in a.markers] == [mk.name for mk in b.markers]
    assert b.total_mass == pytest.approx(a.total_mass, rel=1e-15)
    for ba in a.bodies:
        bb = next(x for x in b.bodies if x.name == ba.name)
        np.testing.assert_allclose(bb.parameters(), ba.parameters(), rtol=1e-14, atol=1e-15)
    names = [c.name for c in a.coordinates]
    th = np.random.default_rng(2).uniform(-0.6, 0.4, size=(n, len(names)))
    order = [names.index(c.name) for c in b.coordinates]
    np.testing.assert_allclose(
        marker_positions(b, th[:, order]), marker_positions(a, th), rtol=0, atol=1e-13
    )


def test_a_chain_of_every_function_reads_back_the_same(tmp_path):
    m = _chain()
    _same_model(m, load_osim(write_osim(tmp_path / "c.osim", m)))


def test_gait2392_reads_back_the_same(tmp_path):
    """Bodies, joints, markers and the 92 muscles (via, conditional and moving points): the
    same muscle–tendon lengths at any pose."""
    from msk.muscles.geometry import muscle_geometry
    from msk.pipeline.model import load_model_file

    m = load_model_file(REPO / "msk" / "data" / "models" / "gait2392.toml")
    back = load_osim(write_osim(tmp_path / "g.osim", m))
    _same_model(m, back)
    assert [mu.name for mu in back.muscles] == [mu.name for mu in m.muscles]
    for a, b in zip(m.muscles, back.muscles):
        assert (a.kind, a.max_isometric_force, a.tendon_slack_length) == (
            b.kind, b.max_isometric_force, b.tendon_slack_length,
        )  # fmt: skip
        assert a.extra == b.extra
    names = [c.name for c in m.coordinates]
    lo, hi = m.coordinate_bounds()
    rng = np.random.default_rng(4)
    th = np.clip(m.default_coordinates() + rng.uniform(-0.4, 0.4, (5, len(names))), lo, hi)
    order = [names.index(c.name) for c in back.coordinates]
    np.testing.assert_allclose(
        muscle_geometry(back, th[:, order]).lengths, muscle_geometry(m, th).lengths, atol=1e-14
    )


def test_wrap_objects_read_back_the_same(tmp_path):
    from msk.muscles.path import Muscle, PathPoint, PathWrap, WrapObject

    m = _chain()
    wraps = [
        WrapObject("cyl", "thigh", "cylinder", np.array([0.0, -0.3, 0.0]),
                   np.array([0.1, 0.2, 0.0]), radius=0.04, length=0.1, quadrant="-x"),
        WrapObject("ell", "shank", "ellipsoid", np.zeros(3), np.zeros(3),
                   dimensions=np.array([0.03, 0.05, 0.04])),
    ]  # fmt: skip
    mu = Muscle(
        "m1",
        (PathPoint("p1", "thigh", np.array([0.02, 0.0, 0.0])),
         PathPoint("p2", "shank", np.array([0.02, -0.1, 0.0]))),
        1000.0, 0.1, 0.3, 0.1, 10.0, (PathWrap("cyl", "hybrid", (1, 2)),), "Thelen2003Muscle",
    )  # fmt: skip
    m = Model(name="w", bodies=m.bodies, joints=m.joints, coordinates=m.coordinates,
              markers=m.markers, muscles=[mu], metadata={"wrap_objects": wraps})  # fmt: skip
    back = load_osim(write_osim(tmp_path / "w.osim", m))
    got = {w.name: w for w in back.metadata["wrap_objects"]}
    for w in wraps:
        b = got[w.name]
        assert (b.body, b.kind, b.quadrant, b.radius, b.length) == (
            w.body, w.kind, w.quadrant, w.radius, w.length,
        )  # fmt: skip
        np.testing.assert_array_equal(b.dimensions, w.dimensions)
        np.testing.assert_array_equal(b.xyz_body_rotation, w.xyz_body_rotation)
    (w0,) = back.muscles[0].wraps
    assert (w0.wrap_object, w0.method, w0.range) == ("cyl", "hybrid", (1, 2))


def test_what_opensim_cannot_hold_is_refused(tmp_path):
    with pytest.raises(ModelError, match="Composite"):
        write_osim(tmp_path / "a.osim", _chain(Composite(Linear(2.0), Linear(0.5))))
    with pytest.raises(ModelError, match="coordinate of joint free"):
        write_osim(tmp_path / "b.osim", _chain(foreign=True))
    assert not list(tmp_path.iterdir())


@pytest.mark.opensim
def test_opensim_places_the_markers_where_msk_does(tmp_path, needs_opensim):
    from msk._runtime.opensim_peer import run_opensim_script

    m = _chain()
    p = write_osim(tmp_path / "c.osim", m)
    names = [c.name for c in m.coordinates]
    th = np.random.default_rng(3).uniform(-0.6, 0.4, size=(6, len(names)))
    got = run_opensim_script(
        """
        import opensim as osim
        m = osim.Model(ARGS["model"])
        s = m.initSystem()
        RESULT["mass"] = m.getTotalMass(s)
        cs, ms = m.getCoordinateSet(), m.getMarkerSet()
        RESULT["pos"] = []
        for th in ARGS["th"]:
            for n, v in zip(ARGS["names"], th):
                cs.get(n).setValue(s, v, False)
            m.realizePosition(s)
            RESULT["pos"].append([[ms.get(i).getLocationInGround(s).get(k) for k in range(3)]
                                  for i in range(ms.getSize())])
        """,
        model=str(p),
        th=th.tolist(),
        names=names,
    )
    assert got["mass"] == pytest.approx(m.total_mass, rel=1e-14)
    np.testing.assert_allclose(np.array(got["pos"]), marker_positions(m, th), atol=1e-12)


@pytest.mark.opensim
def test_opensim_gives_msks_muscle_lengths_and_moment_arms(tmp_path, needs_opensim):
    """gait2392 written by msk: OpenSim 4.6's getLength / computeMomentArm of the 92 muscles
    equal msk's at random poses."""
    from msk.muscles.geometry import muscle_geometry
    from msk.pipeline.model import load_model_file
    from tests.support.opensim_geometry import opensim_geometry

    m = load_model_file(REPO / "msk" / "data" / "models" / "gait2392.toml")
    p = write_osim(tmp_path / "g.osim", m)
    lo, hi = m.coordinate_bounds()
    rng = np.random.default_rng(5)
    th = np.clip(m.default_coordinates() + rng.uniform(-0.4, 0.4, (4, m.n_coords)), lo, hi)
    names = list(m.coordinate_names)
    coords = [names.index(c) for c in ("hip_flexion_r", "knee_angle_r", "ankle_angle_l")]
    lengths, arms = opensim_geometry(p, m, th, list(range(len(m.muscles))), coords)
    geo = muscle_geometry(m, th)
    np.testing.assert_allclose(lengths, geo.lengths, atol=1e-12)
    np.testing.assert_allclose(arms, geo.moment_arms[:, :, coords], atol=1e-12)
