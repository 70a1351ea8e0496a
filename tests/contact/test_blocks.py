"""The knee contact assembled block by block of frames equals the contact of one pass."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
import pytest

from msk.contact.blocks import ContactAssembly, ContactVariant
from msk.contact.knee import PlateauGeometry, knee_contact_force, split_medial_lateral
from msk.datasets.models import leg_model
from msk.dynamics.loads import ExternalLoads
from msk.kinematics.ik import Kinematics, kinematics_from_coordinates
from msk.model.core import Model
from msk.muscles.geometry import muscle_geometry
from msk.muscles.path import Muscle, PathPoint


def _pt(name: str, body: str, xyz: Sequence[float]) -> PathPoint:
    return PathPoint(name, body, np.asarray(xyz, dtype=float))


def _walking_leg() -> tuple[Model, Kinematics, ExternalLoads]:
    """The pelvis–femur–tibia–foot test leg with a hip muscle (no wrench on the knee's distal
    side), a quadriceps and a gastrocnemius, a smooth motion and a ground reaction on the
    foot."""
    spec = {
        "glut": [("o", "pelvis", [-0.04, 0.03, 0.12]), ("i", "femur", [-0.02, -0.01, 0.055])],
        "quad": [
            ("o", "femur", [0.029, -0.192, 0.031]),
            ("v", "femur", [0.035, -0.36, 0.002]),
            ("i", "tibia", [0.045, -0.06, 0.0]),
        ],
        "gas": [
            ("o", "femur", [-0.019, -0.393, -0.024]),
            ("v", "tibia", [-0.03, -0.15, -0.02]),
            ("i", "foot", [-0.05, 0.03, -0.005]),
        ],
    }
    muscles = [Muscle(n, tuple(_pt(*p) for p in pts), 3000.0, 0.1, 0.2) for n, pts in spec.items()]
    leg = leg_model()  # its knee renamed knee_r: the split tells the side from the name
    joints = [dataclasses.replace(j, name="knee_r") if j.name == "knee" else j for j in leg.joints]
    model = Model(
        name="leg_r", bodies=leg.bodies, joints=joints, coordinates=leg.coordinates
    ).with_muscles(muscles)
    t = np.linspace(0.0, 1.0, 23)
    q = np.tile(model.default_coordinates(), (t.size, 1))
    q[:, 0] += 0.3 * t
    q[:, 6] += 0.5 * np.sin(2 * np.pi * t)
    q[:, 9] = -0.6 - 0.5 * np.sin(2 * np.pi * t)
    kin = kinematics_from_coordinates(t, q, model.coordinate_names, cutoff_hz=None)
    force = np.zeros((t.size, 1, 3))
    force[:, 0, 1] = 500.0 + 200.0 * np.sin(np.pi * t)
    point = (
        np.tile([0.3, -0.9, 0.08], (t.size, 1, 1))
        + np.stack([0.2 * t, 0 * t, 0 * t], axis=1)[:, None, :]
    )
    loads = ExternalLoads(
        time=t, bodies=("foot",), force=force, moment=np.cross(point, force), point=point
    )
    return model, kin, loads


def test_blocks_fill_what_one_pass_gives() -> None:
    """Filled in three uneven blocks of frames, in any order, the contact force and the
    medial/lateral split are the one-pass values to round-off; a frame whose quadriceps force
    is unknown is left NaN, a frame missing only the hip muscle's force (no wrench on the
    knee's distal side) is filled with it counted as 0."""
    model, kin, loads = _walking_leg()
    n, names = kin.time.size, ("glut", "quad", "gas")
    rng = np.random.default_rng(3)
    forces = rng.uniform(50.0, 900.0, size=(n, 3))
    forces[[4, 5], 0] = np.nan  # hip muscle unknown: does not load the knee
    forces[[10, 17], 1] = np.nan  # quadriceps unknown: no contact on that frame
    g = muscle_geometry(model, kin.q, distal_wrench_joints=("knee_r",))
    wrenches = np.asarray(g.distal_wrenches["knee_r"])
    assert (wrenches[:, 0] == 0).all() and (wrenches[:, 1] != 0).any()
    geometry = PlateauGeometry(0.045, (0.0, -0.02, 0.0))

    blocked = ContactAssembly(model, geometry, kin, loads, "knee_r")
    for fr in (np.arange(15, n), np.arange(0, 4), np.arange(4, 15)):
        blocked.fill(fr, forces[fr], wrenches[fr], names)
    got = blocked.result()

    filled = np.setdiff1d(np.arange(n), [10, 17])
    one = knee_contact_force(
        model, kin.take(filled), loads.take(filled),
        muscle_forces=np.nan_to_num(forces[filled]), muscle_names=names, joint="knee_r",
        distal_wrenches=wrenches[filled],
    )  # fmt: skip
    ml = split_medial_lateral(one, geometry)
    assert isinstance(got, ContactVariant) and got.lateral_sign == 1.0
    assert np.isnan(got.force[[10, 17]]).all() and np.isnan(got.medial[[10, 17]]).all()
    scale = np.abs(one.force).max()
    assert scale > 100.0
    np.testing.assert_allclose(got.force[filled], one.force, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(got.medial[filled], ml.medial, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(got.lateral[filled], ml.lateral, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(got.total, np.linalg.norm(got.force, axis=1))
    np.testing.assert_allclose(got.axial, -got.force[:, 1])


@pytest.mark.parametrize("joint, sign", [("knee_r", 1.0), ("knee_l", -1.0)])
def test_unfilled_trial_is_nan_with_the_side_sign(joint: str, sign: float) -> None:
    model, kin, loads = _walking_leg()
    v = ContactAssembly(model, PlateauGeometry(), kin, loads, joint).result()
    assert v.force.shape == (kin.time.size, 3) and np.isnan(v.total).all()
    assert v.lateral_sign == sign
