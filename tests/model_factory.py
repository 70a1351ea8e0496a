"""Tiny models built in code for tests (pelvis free chain, hip, coupled knee, welded foot)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from msk.joints import CoordinateFunction, Linear, Polynomial
from msk.model import Axis, Body, Coordinate, Joint, Marker, Model


def inertia(m: float, l: float) -> np.ndarray:
    """Inertia about the COM of a slender segment of mass ``m`` and length ``l`` (long axis y)."""
    return np.diag([m * l**2 / 12, m * l**2 / 80, m * l**2 / 12])


def free_pelvis(pelvis_height: float) -> tuple[list[Coordinate], Joint]:
    """The pelvis's 6 coordinates (``pelvis_tx/ty/tz``, ``pelvis_tilt/list/rotation``,
    ``pelvis_ty`` defaulting to ``pelvis_height``) and the free ``ground_pelvis`` joint, y up."""
    lin = Linear()
    coords = [
        Coordinate("pelvis_tx", "translational", (-5, 5)),
        Coordinate("pelvis_ty", "translational", (-1, 2), pelvis_height),
        Coordinate("pelvis_tz", "translational", (-5, 5)),
        Coordinate("pelvis_tilt"),
        Coordinate("pelvis_list"),
        Coordinate("pelvis_rotation"),
    ]
    joint = Joint(
        "ground_pelvis",
        "ground",
        "pelvis",
        axes=(
            Axis("prismatic", [1, 0, 0], "pelvis_tx", lin),
            Axis("prismatic", [0, 1, 0], "pelvis_ty", lin),
            Axis("prismatic", [0, 0, 1], "pelvis_tz", lin),
            Axis("revolute", [0, 0, 1], "pelvis_tilt", lin),
            Axis("revolute", [1, 0, 0], "pelvis_list", lin),
            Axis("revolute", [0, 1, 0], "pelvis_rotation", lin),
        ),
    )
    return coords, joint


def leg_model(knee_x: CoordinateFunction | None = None, knee_y: CoordinateFunction | None = None):
    """Pelvis (6 DOF: 3 translations, 3 rotations) → thigh (3-DOF hip with an oblique axis)
    → shank (knee: coupled translations + flexion) → foot (welded), y up as OpenSim."""
    knee_x = knee_x or Polynomial((0.002, -0.004, 0.0))
    knee_y = knee_y or Polynomial((-0.001, 0.003, -0.40))
    coords, pelvis_joint = free_pelvis(0.9)
    coords += [
        Coordinate("hip_flexion"),
        Coordinate("hip_adduction"),
        Coordinate("hip_rotation"),
        Coordinate("knee_angle", range=(-2.1, 0.2)),
    ]
    lin = Linear()
    bodies = [
        Body("pelvis", 11.0, [-0.07, 0.0, 0.0], inertia(11.0, 0.25)),
        Body("femur", 8.8, [0.0, -0.17, 0.0], inertia(8.8, 0.40)),
        Body("tibia", 3.5, [0.0, -0.18, 0.0], inertia(3.5, 0.40)),
        Body("foot", 1.2, [0.08, -0.02, 0.0], inertia(1.2, 0.2)),
    ]
    joints = [
        pelvis_joint,
        Joint(
            "hip",
            "pelvis",
            "femur",
            parent_offset=pin.SE3(np.eye(3), np.array([-0.07, -0.066, 0.083])),
            axes=(
                Axis("revolute", [0, 0, 1], "hip_flexion", lin),
                Axis("revolute", [0.9, 0.1, 0.0], "hip_adduction", lin),
                Axis("revolute", [0, 1, 0], "hip_rotation", lin),
            ),
        ),
        Joint(
            "knee",
            "femur",
            "tibia",
            axes=(
                Axis("prismatic", [1, 0, 0], "knee_angle", knee_x),
                Axis("prismatic", [0, 1, 0], "knee_angle", knee_y),
                Axis("revolute", [0, 0, 1], "knee_angle", lin),
            ),
        ),
        Joint(
            "ankle_weld",
            "tibia",
            "foot",
            parent_offset=pin.SE3(pin.rpy.rpyToMatrix(0.1, 0.0, 0.2), np.array([0, -0.43, 0])),
            child_offset=pin.SE3(np.eye(3), np.array([0.01, 0.02, 0.0])),
        ),
    ]
    markers = [
        Marker("ASIS", "pelvis", [0.02, 0.0, 0.12]),
        Marker("PSIS", "pelvis", [-0.15, 0.03, 0.05]),
        Marker("THI", "femur", [0.03, -0.2, 0.06]),
        Marker("KNE", "femur", [0.0, -0.4, 0.05]),
        Marker("TIB", "tibia", [0.03, -0.2, 0.05]),
        Marker("ANK", "tibia", [0.0, -0.42, 0.04]),
        Marker("HEE", "foot", [-0.03, -0.02, 0.0]),
        Marker("TOE", "foot", [0.16, -0.03, 0.0]),
    ]
    return Model(name="leg", bodies=bodies, joints=joints, coordinates=coords, markers=markers)
