"""Which joint is a model's knee, and which way its coordinates turn, in msk's reference
convention.

msk states its physiological ranges of motion (:data:`msk.quality.PHYSIOLOGICAL_RANGES_DEG`),
its gait variables (:mod:`msk.gait.variables`) and its normative bands in the convention of
OpenSim's gait models (gait2392: Delp SL et al. 1990 IEEE TBME 37:757; Anderson FC, Pandy MG
1999): every body with x anterior, y proximal (up), z to the right, and ``knee_angle_<s>``
the tibia's rotation about the femur's +z axis — negative in flexion. Other models keep the
names but not always the sign: the Rajagopal et al. (2016) walker knee turns the tibia about an
axis along the femur's −z (its ``knee_angle_r`` runs 0 → 120° in flexion).

:func:`reference_sign` maps a model's coordinate onto the reference convention, the one place
that knows it: s = +1 or −1 with q_ref = s · q and τ_ref = s · τ (a generalised force turns with
its coordinate). For a knee coordinate s is the sign of the z component, in the femur's axes, of
the revolute axis the coordinate drives linearly (the flexion–extension axis):

    s = sign(ẑ_femur · R_parent a),

R_parent the joint frame's rotation in the femur, a the axis in the joint frame (gait2392:
a = +z, s = +1; Rajagopal: R_parent a ≈ (0, −0.07, −0.998) on both sides, s = −1). Every other
coordinate keeps its sign (s = +1): the models msk ships agree on them.

:func:`knee_joint` finds the knee by what it joins rather than by its name: the joint whose
child body is the tibia of that side (``tibia_r``/``tibia_l``; gait2392's ``knee_r``,
Rajagopal's ``walker_knee_r``), else the joint that drives ``knee_angle_<s>`` by a revolute axis.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from msk.model.core import Model
from msk.model.joints import Linear

__all__ = ["KNEE_STEM", "knee_joint", "reference_sign", "reference_signs"]

#: the stem of the knee flexion coordinate's name (``knee_angle_r``, ``knee_angle_l``)
KNEE_STEM = "knee_angle"


def knee_joint(model: Model, side: str) -> str | None:
    """The name of the knee joint of ``side`` (``"r"``/``"l"``, or ``"_r"``/``"_l"``), None
    when the model has none (module docstring)."""
    s = side.strip("_")
    for j in model.joints:
        if j.child == f"tibia_{s}" and j.axes:
            return j.name
    coord = f"{KNEE_STEM}_{s}"
    for j in model.joints:
        if any(ax.coordinate == coord and ax.kind == "revolute" for ax in j.axes):
            return j.name
    return None


def reference_sign(model: Model, coordinate: str) -> float:
    """s (±1) with q_ref = s · q for ``coordinate`` of ``model`` (module docstring)."""
    return reference_signs(model).get(coordinate, 1.0)


def reference_signs(model: Model) -> Mapping[str, float]:
    """Coordinate → s for the coordinates whose sign differs from the reference convention
    (s = −1); the others are not listed (s = +1)."""
    out: dict[str, float] = {}
    for side in ("r", "l"):
        coord = f"{KNEE_STEM}_{side}"
        name = knee_joint(model, side)
        joint = next((j for j in model.joints if j.name == name), None)
        if joint is None:
            continue
        axis = next(
            (ax for ax in joint.axes
             if ax.kind == "revolute" and ax.coordinate == coord
             and isinstance(ax.function, Linear)),
            None,
        )  # fmt: skip
        if axis is None:
            continue
        slope = float(getattr(axis.function, "slope", 1.0))
        z = float((np.asarray(joint.parent_offset.rotation) @ axis.axis)[2]) * slope
        if z < 0.0:
            out[coord] = -1.0
    return out
