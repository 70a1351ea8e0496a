"""msk.io.osim_writer: an msk model as an OpenSim 4 .osim — read back by msk's importer and by
OpenSim 4.6 (child process) with the same bodies and the same marker positions at any pose."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from msk.exceptions import ModelError
from msk.io.osim_writer import body_fixed_xyz_angles, write_osim
from msk.joints import Composite, Linear, Multiplier, PiecewiseLinear, Polynomial, SimmSpline
from msk.model import Axis, Body, Coordinate, Joint, Marker, Model, marker_positions
from msk.osim import body_fixed_xyz, load_osim

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
    from msk.pipeline.model import load_model_file

    m = load_model_file(REPO / "models" / "gait2392.toml")
    _same_model(m, load_osim(write_osim(tmp_path / "g.osim", m)))


def test_what_opensim_cannot_hold_is_refused(tmp_path):
    with pytest.raises(ModelError, match="Composite"):
        write_osim(tmp_path / "a.osim", _chain(Composite(Linear(2.0), Linear(0.5))))
    with pytest.raises(ModelError, match="coordinate of joint free"):
        write_osim(tmp_path / "b.osim", _chain(foreign=True))
    assert not list(tmp_path.iterdir())


@pytest.mark.opensim
def test_opensim_places_the_markers_where_msk_does(tmp_path, needs_opensim):
    from msk.opensim_peer import run_opensim_script

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
