"""A femur welded to the ground and a tibia on a one-axis revolute knee: the smallest model
on which the knee's side conventions (alignment, medial/lateral contact) can be checked."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from msk.joints import Linear
from msk.model import Axis, Body, Coordinate, Joint, Model

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
