"""Models built in code with known segment values, for tests, benchmarks and tutorials.

- :func:`leg_model`: one leg (pelvis free, 3-DOF hip with an oblique axis, knee with coupled
  translations, welded foot), 8 markers;
- :func:`two_leg_model`: pelvis free and two legs (3-DOF hips, coupled knees, 1-DOF ankles),
  16 coordinates, 30 markers (:func:`msk.datasets.trials.make_trial` moves it);
- :func:`whole_body_model`: pelvis free, 3-DOF lumbar joint, head and arms, two legs, with
  Dumas 2007 generic segments (:func:`generic_bodies`) or a subject departing from them
  (:func:`subject_bodies`), for inertial identification
  (:func:`msk.datasets.trials.identification_trial`).

All are y up, as OpenSim models.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from msk.model.anthropometry import generic_segments
from msk.model.core import Axis, Body, Coordinate, Joint, Marker, Model
from msk.model.joints import CoordinateFunction, Linear, Polynomial
from msk.units import Array

__all__ = [
    "WHOLE_BODY_SEGMENTS",
    "free_pelvis",
    "generic_bodies",
    "inertia",
    "leg_model",
    "subject_bodies",
    "two_leg_model",
    "whole_body_model",
]


def _v(x: float, y: float, z: float) -> Array:
    return np.array([x, y, z], dtype=float)


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
            Axis("prismatic", _v(1, 0, 0), "pelvis_tx", lin),
            Axis("prismatic", _v(0, 1, 0), "pelvis_ty", lin),
            Axis("prismatic", _v(0, 0, 1), "pelvis_tz", lin),
            Axis("revolute", _v(0, 0, 1), "pelvis_tilt", lin),
            Axis("revolute", _v(1, 0, 0), "pelvis_list", lin),
            Axis("revolute", _v(0, 1, 0), "pelvis_rotation", lin),
        ),
    )
    return coords, joint


def leg_model(
    knee_x: CoordinateFunction | None = None, knee_y: CoordinateFunction | None = None
) -> Model:
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
        Body("pelvis", 11.0, _v(-0.07, 0.0, 0.0), inertia(11.0, 0.25)),
        Body("femur", 8.8, _v(0.0, -0.17, 0.0), inertia(8.8, 0.40)),
        Body("tibia", 3.5, _v(0.0, -0.18, 0.0), inertia(3.5, 0.40)),
        Body("foot", 1.2, _v(0.08, -0.02, 0.0), inertia(1.2, 0.2)),
    ]
    joints = [
        pelvis_joint,
        Joint(
            "hip",
            "pelvis",
            "femur",
            parent_offset=pin.SE3(np.eye(3), np.array([-0.07, -0.066, 0.083])),
            axes=(
                Axis("revolute", _v(0, 0, 1), "hip_flexion", lin),
                Axis("revolute", _v(0.9, 0.1, 0.0), "hip_adduction", lin),
                Axis("revolute", _v(0, 1, 0), "hip_rotation", lin),
            ),
        ),
        Joint(
            "knee",
            "femur",
            "tibia",
            axes=(
                Axis("prismatic", _v(1, 0, 0), "knee_angle", knee_x),
                Axis("prismatic", _v(0, 1, 0), "knee_angle", knee_y),
                Axis("revolute", _v(0, 0, 1), "knee_angle", lin),
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
        Marker("ASIS", "pelvis", _v(0.02, 0.0, 0.12)),
        Marker("PSIS", "pelvis", _v(-0.15, 0.03, 0.05)),
        Marker("THI", "femur", _v(0.03, -0.2, 0.06)),
        Marker("KNE", "femur", _v(0.0, -0.4, 0.05)),
        Marker("TIB", "tibia", _v(0.03, -0.2, 0.05)),
        Marker("ANK", "tibia", _v(0.0, -0.42, 0.04)),
        Marker("HEE", "foot", _v(-0.03, -0.02, 0.0)),
        Marker("TOE", "foot", _v(0.16, -0.03, 0.0)),
    ]
    return Model(name="leg", bodies=bodies, joints=joints, coordinates=coords, markers=markers)


def two_leg_model() -> Model:
    """Pelvis (6 DOF) with two legs (3-DOF hip, knee with coupled translations, 1-DOF ankle),
    y up, 16 coordinates, 30 markers; segment values close to :func:`leg_model`."""
    lin = Linear()
    coords, pelvis_joint = free_pelvis(0.93)
    bodies = [Body("pelvis", 11.0, _v(-0.07, 0.0, 0.0), inertia(11.0, 0.25))]
    joints = [pelvis_joint]
    markers = [
        Marker("RASI", "pelvis", _v(0.02, 0.0, 0.12)),
        Marker("LASI", "pelvis", _v(0.02, 0.0, -0.12)),
        Marker("RPSI", "pelvis", _v(-0.15, 0.03, 0.05)),
        Marker("LPSI", "pelvis", _v(-0.15, 0.03, -0.05)),
    ]
    for side, s in (("r", 1.0), ("l", -1.0)):
        up = side.upper()
        coords += [
            Coordinate(f"hip_flexion_{side}", range=(-1.2, 2.0)),
            Coordinate(f"hip_adduction_{side}", range=(-0.9, 0.5)),
            Coordinate(f"hip_rotation_{side}", range=(-0.7, 0.7)),
            Coordinate(f"knee_angle_{side}", range=(-2.1, 0.17)),
            Coordinate(f"ankle_angle_{side}", range=(-0.7, 0.5)),
        ]
        bodies += [
            Body(f"femur_{side}", 8.8, _v(0.0, -0.17, 0.0), inertia(8.8, 0.40)),
            Body(f"tibia_{side}", 3.5, _v(0.0, -0.18, 0.0), inertia(3.5, 0.40)),
            Body(f"foot_{side}", 1.2, _v(0.06, -0.03, 0.0), inertia(1.2, 0.2)),
        ]
        joints += [
            Joint(
                f"hip_{side}",
                "pelvis",
                f"femur_{side}",
                parent_offset=pin.SE3(np.eye(3), np.array([-0.07, -0.066, s * 0.083])),
                axes=(
                    Axis("revolute", _v(0, 0, 1), f"hip_flexion_{side}", lin),
                    Axis("revolute", _v(s * 0.9, s * 0.1, 0.0), f"hip_adduction_{side}", lin),
                    Axis("revolute", _v(0, s, 0), f"hip_rotation_{side}", lin),
                ),
            ),
            Joint(
                f"knee_{side}",
                f"femur_{side}",
                f"tibia_{side}",
                axes=(
                    Axis(
                        "prismatic",
                        _v(1, 0, 0),
                        f"knee_angle_{side}",
                        Polynomial((0.002, -0.004, 0.0)),
                    ),
                    Axis(
                        "prismatic",
                        _v(0, 1, 0),
                        f"knee_angle_{side}",
                        Polynomial((-0.001, 0.003, -0.40)),
                    ),
                    Axis("revolute", _v(0, 0, 1), f"knee_angle_{side}", lin),
                ),
            ),
            Joint(
                f"ankle_{side}",
                f"tibia_{side}",
                f"foot_{side}",
                parent_offset=pin.SE3(np.eye(3), np.array([0.0, -0.43, 0.0])),
                axes=(Axis("revolute", _v(0, 0, 1), f"ankle_angle_{side}", lin),),
            ),
        ]
        markers += [
            Marker(f"{up}THI", f"femur_{side}", _v(0.03, -0.2, s * 0.06)),
            Marker(f"{up}THA", f"femur_{side}", _v(0.05, -0.12, s * 0.02)),
            Marker(f"{up}KNE", f"femur_{side}", _v(0.0, -0.4, s * 0.05)),
            Marker(f"{up}KNM", f"femur_{side}", _v(0.0, -0.4, -s * 0.05)),
            Marker(f"{up}TIB", f"tibia_{side}", _v(0.03, -0.2, s * 0.05)),
            Marker(f"{up}TIA", f"tibia_{side}", _v(0.05, -0.1, -s * 0.01)),
            Marker(f"{up}ANK", f"tibia_{side}", _v(0.0, -0.42, s * 0.04)),
            Marker(f"{up}ANM", f"tibia_{side}", _v(0.0, -0.42, -s * 0.04)),
            Marker(f"{up}HEE", f"foot_{side}", _v(-0.05, -0.05, 0.0)),
            Marker(f"{up}TOE", f"foot_{side}", _v(0.16, -0.06, 0.0)),
            Marker(f"{up}MT5", f"foot_{side}", _v(0.12, -0.05, s * 0.04)),
        ]
    return Model(name="two_legs", bodies=bodies, joints=joints, coordinates=coords, markers=markers)


#: whole-body model body → Dumas 2007 segment (:func:`msk.model.anthropometry.generic_segments`)
WHOLE_BODY_SEGMENTS = {
    "pelvis": "pelvis",
    "torso": "thorax",
    "head": "head_neck",
    "humerus_r": "upper_arm_r",
    "humerus_l": "upper_arm_l",
    "forearm_r": "forearm_r",
    "forearm_l": "forearm_l",
    "hand_r": "hand_r",
    "hand_l": "hand_l",
    "femur_r": "thigh_r",
    "femur_l": "thigh_l",
    "tibia_r": "shank_r",
    "tibia_l": "shank_l",
    "foot_r": "foot_r",
    "foot_l": "foot_l",
}


def generic_bodies(mass_kg: float = 75.0, height_m: float = 1.75) -> dict[str, Body]:
    """The bodies of :func:`whole_body_model` from the Dumas 2007 tables (male)."""
    segs = generic_segments(mass_kg, height_m, sex="male")
    return {
        b: Body(b, s.mass, s.com, s.inertia)
        for b, s in ((b, segs[n]) for b, n in WHOLE_BODY_SEGMENTS.items())
    }


def whole_body_model(bodies: dict[str, Body] | None = None) -> Model:
    """Pelvis (6 DOF) + 3-DOF lumbar joint + head and arms welded to the torso (one 1-DOF
    shoulder each, held still) + two legs (3-DOF hip, coupled knee, ankle); y up."""
    bodies = bodies or generic_bodies()
    lin = Linear()
    se3 = lambda x, y, z: pin.SE3(np.eye(3), np.array([x, y, z]))  # noqa: E731
    coords, pelvis_joint = free_pelvis(0.95)
    coords += [
        Coordinate("lumbar_extension"),
        Coordinate("lumbar_bending"),
        Coordinate("lumbar_rotation"),
        Coordinate("arm_flex_r"),
        Coordinate("arm_flex_l"),
    ]
    joints = [
        pelvis_joint,
        Joint("back", "pelvis", "torso", parent_offset=se3(0, 0.47, 0), axes=(
            Axis("revolute", _v(0, 0, 1), "lumbar_extension", lin),
            Axis("revolute", _v(1, 0, 0), "lumbar_bending", lin),
            Axis("revolute", _v(0, 1, 0), "lumbar_rotation", lin),
        )),
        Joint("neck", "torso", "head"),
    ]  # fmt: skip
    for s, z in (("r", 1.0), ("l", -1.0)):
        coords += [
            Coordinate(f"hip_flexion_{s}"),
            Coordinate(f"hip_adduction_{s}"),
            Coordinate(f"hip_rotation_{s}"),
            Coordinate(f"knee_angle_{s}", range=(-2.1, 0.2)),
            Coordinate(f"ankle_angle_{s}"),
        ]
        joints += [
            Joint(f"shoulder_{s}", "torso", f"humerus_{s}", parent_offset=se3(0, -0.03, 0.18 * z),
                  axes=(Axis("revolute", _v(0, 0, 1), f"arm_flex_{s}", lin),)),
            Joint(f"elbow_{s}", f"humerus_{s}", f"forearm_{s}", parent_offset=se3(0, -0.27, 0)),
            Joint(f"wrist_{s}", f"forearm_{s}", f"hand_{s}", parent_offset=se3(0, -0.25, 0)),
            Joint(f"hip_{s}", "pelvis", f"femur_{s}", parent_offset=se3(-0.02, -0.07, 0.085 * z),
                  axes=(
                Axis("revolute", _v(0, 0, 1), f"hip_flexion_{s}", lin),
                Axis("revolute", _v(1, 0, 0), f"hip_adduction_{s}", lin),
                Axis("revolute", _v(0, 1, 0), f"hip_rotation_{s}", lin),
            )),
            Joint(f"knee_{s}", f"femur_{s}", f"tibia_{s}", parent_offset=se3(0, -0.43, 0), axes=(
                Axis("prismatic", _v(1, 0, 0), f"knee_angle_{s}", Polynomial((0.002, -0.004, 0.0))),
                Axis("prismatic", _v(0, 1, 0), f"knee_angle_{s}", Polynomial((-0.001, 0.003, 0.0))),
                Axis("revolute", _v(0, 0, 1), f"knee_angle_{s}", lin),
            )),
            Joint(f"ankle_{s}", f"tibia_{s}", f"foot_{s}", parent_offset=se3(0, -0.43, 0),
                  axes=(Axis("revolute", _v(0, 0, 1), f"ankle_angle_{s}", lin),)),
        ]  # fmt: skip
    return Model(name="whole_body", bodies=list(bodies.values()), joints=joints, coordinates=coords)


def subject_bodies(kind: str) -> dict[str, Body]:
    """True segments of a subject whose mass distribution departs from the tables: ``"generic"``
    (the tables), ``"athlete"`` (thighs and shanks ×1.20, COM shifted 2 cm) or ``"elderly"``
    (×0.85, −1.5 cm)."""
    gen = generic_bodies()
    if kind == "generic":
        return gen
    factor, shift = {"athlete": (1.20, 0.02), "elderly": (0.85, -0.015)}[kind]
    out = dict(gen)
    for name in ("femur_r", "femur_l", "tibia_r", "tibia_l"):
        b = gen[name]
        com = b.com + np.array([shift, -shift, 0.0])
        out[name] = Body(name, b.mass * factor, com, b.inertia * factor)
    return out
