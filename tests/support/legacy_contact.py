"""The knee contact route msk used until 2026-11, kept as the reference of the vectorised
route in :func:`msk.contact.knee.knee_contact_force`: ``tests/contact/test_contact.py`` checks that
both
agree to 1e-9 and ``bench/bench_contact.py`` times both. Not API (it uses the geometry plan's
private per-twist path evaluation).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from msk.dynamics.inverse import Variant, joint_reaction
from msk.dynamics.loads import ExternalLoads
from msk.kinematics.ik import Kinematics
from msk.model.core import Model
from msk.muscles.geometry import geometry_plan

Array = NDArray[np.float64]


def legacy_knee_contact_force(
    model: Model,
    kin: Kinematics,
    loads: ExternalLoads,
    *,
    muscle_forces: Array,
    joint: str,
    variant: Variant = "full",
) -> tuple[Array, Array]:
    """Force and moment in the plateau (tibia) frame as msk computed them before the vectorised
    route (also timed by ``bench/bench_contact.py``): RNEA's transmitted wrench
    (``joint_reaction``, a Pinocchio pass per frame), ∂l/∂ξ from a path evaluation per pair of
    unit twists on the knee DOFs (``GeometryPlan._distal_by_twists``, the former
    ``muscle_distal_wrenches``), the tibia placement by ``framesForwardKinematics`` per frame."""
    jr = joint_reaction(model, kin, loads, joint=joint, frame="world", variant=variant)
    plan = geometry_plan(model)
    th = np.asarray(kin.q, dtype=float)
    w = plan._distal_by_twists(th, plan._joint_dofs(joint))
    add = np.einsum("nm,nmc->nc", muscle_forces, w)
    force_w = jr.force + add[:, :3]
    moment_w = jr.moment + add[:, 3:]
    spec = next(j for j in model.joints if j.name == joint)
    data = model.create_data()
    fid = model.body_frame[spec.child]
    place = np.empty((th.shape[0], 4, 4))
    qpin = model.coupling.q(th)
    for k in range(th.shape[0]):
        pin.framesForwardKinematics(model.pin_model, data, qpin[k])
        place[k] = data.oMf[fid].homogeneous
    rot, origin = place[:, :3, :3], place[:, :3, 3]
    m_o = moment_w - np.cross(origin, force_w)
    return np.einsum("nji,nj->ni", rot, force_w), np.einsum("nji,nj->ni", rot, m_o)
