"""Stage ``muscle_geometry``: muscle-tendon lengths, velocities and moment-arm Jacobians on the
usable frames (:func:`msk.muscles.geometry.muscle_geometry`), with the knee's unit wrenches
∂l/∂ξ for the contact stage from the same pass."""

from __future__ import annotations

from typing import Any

import numpy as np

from msk.pipeline.inputs import SessionInputs
from msk.pipeline.loads import Loads
from msk.pipeline.model import BuiltModel
from msk.pipeline.runner import StageUnavailable

__all__ = ["run"]


def run(inputs: SessionInputs, model: BuiltModel, kinematics: Any, loads: Loads) -> Any:
    """:class:`msk.muscles.geometry.MuscleGeometry`; frames that are not usable are evaluated at
    the default pose, at rest (their values are never used)."""
    mdl, kin, ok = model.model, kinematics, loads.usable
    if not mdl.muscles:
        raise StageUnavailable(f"model {mdl.name} has no muscles")
    from msk.muscles.geometry import muscle_geometry

    q = np.where(ok[:, None], kin.q, mdl.default_coordinates()[None, :])
    v = np.where(ok[:, None], kin.v, 0.0)
    knee = tuple(j.name for j in mdl.joints if j.name == f"knee{inputs.sfx}")
    return muscle_geometry(mdl, q, v, distal_wrench_joints=knee)
