"""A femur welded to the ground and a tibia on a one-axis revolute knee: the smallest model
on which the knee's side conventions (alignment, medial/lateral contact) can be checked; and
any model with its knees turned (a knee coordinate positive in flexion)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin

from msk.model.core import Axis, Body, Coordinate, Joint, Model
from msk.model.joints import Linear

#: knee centre in the world (the femur is welded there)
HIP = np.array([0.0, 1.0, 0.0])


def femur_tibia(
    knee_joint: str,
    shank_mass_kg: float = 4.0,
    shank_com: tuple[float, float, float] = (0.0, -0.2, 0.0),
) -> Model:
    """Femur welded at :data:`HIP`, tibia on a revolute knee about z named ``knee_joint``
    (coordinate ``knee_angle``, ±2.5 rad)."""
    bodies = [
        Body("femur", 7.0, [0.0, 0.2, 0.0], np.diag([0.1, 0.02, 0.1])),
        Body("tibia", shank_mass_kg, list(shank_com), np.diag([0.05, 0.005, 0.05])),
    ]
    joints = [
        Joint("ground_femur", "ground", "femur", parent_offset=pin.SE3(np.eye(3), HIP)),
        Joint(
            knee_joint, "femur", "tibia",
            axes=(Axis("revolute", [0, 0, 1], "knee_angle", Linear()),),
        ),
    ]  # fmt: skip
    return Model(
        name=knee_joint, bodies=bodies, joints=joints,
        coordinates=[Coordinate("knee_angle", range=(-2.5, 2.5))],
    )  # fmt: skip


def four_muscle_knee(knee_joint: str, shank_mass_kg: float = 4.0) -> Model:
    """:func:`femur_tibia` with four vertical muscles from the femur to the tibia, 30 mm anterior
    (extensors) or posterior (flexors) of the knee axis and 25 mm medial or lateral of the knee
    centre: ``lat_ext``, ``lat_flex``, ``med_ext``, ``med_flex`` (F_iso 3000 N). The lateral
    side is world +z on a right knee (``*_r``), −z on a left one (gait2392's frames are not
    mirrored)."""
    from msk.muscles.path import Muscle, PathPoint

    lat = 1.0 if knee_joint.endswith("_r") else -1.0
    muscles = []
    for side, z in (("lat", lat * 0.025), ("med", -lat * 0.025)):
        for kind, x in (("ext", 0.03), ("flex", -0.03)):
            pts = (
                PathPoint("o", "femur", np.array([x, 0.15, z])),
                PathPoint("i", "tibia", np.array([x, -0.06, z])),
            )
            muscles.append(Muscle(f"{side}_{kind}", pts, 3000.0, 0.1, 0.2, 0.0, 10.0))
    return femur_tibia(knee_joint, shank_mass_kg=shank_mass_kg).with_muscles(muscles)


def turned_knees(model: Model) -> Model:
    """``model`` with each knee's flexion axis reversed (a coordinate positive in flexion, as
    Rajagopal's walker knee)."""
    joints = {}
    for j in model.joints:
        if j.child.startswith("tibia_"):
            axes = tuple(
                dataclasses.replace(a, axis=-a.axis) if a.kind == "revolute" else a for a in j.axes
            )
            joints[j.name] = dataclasses.replace(j, axes=axes)
    return model.with_joints(joints)
