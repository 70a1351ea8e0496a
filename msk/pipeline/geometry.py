"""Stage ``muscle_geometry``: muscle-tendon lengths, velocities and moment-arm Jacobians on the
usable frames (:func:`msk.muscles.geometry.muscle_geometry`), with the knee's unit wrenches
∂l/∂ξ for the contact stage from the same pass.

The Jacobian and the wrenches are kept compact (:class:`msk.timeseries.FrameSparse`: only the
coordinates each muscle crosses, only the muscles crossing the knee), evaluated block by block
(:mod:`msk.pipeline.blocks`): a long trial never holds them dense."""

from __future__ import annotations

from typing import Any

import numpy as np

from msk.pipeline.blocks import frame_blocks
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.loads import Loads
from msk.pipeline.model import BuiltModel
from msk.pipeline.runner import StageUnavailable

__all__ = ["run"]


def run(inputs: SessionInputs, model: BuiltModel, kinematics: Any, loads: Loads) -> Any:
    """:class:`msk.muscles.geometry.MuscleGeometry` with compact ``jacobian`` and
    ``distal_wrenches``; frames that are not usable are evaluated at the default pose, at rest
    (their values are never used)."""
    mdl, kin, ok = model.model, kinematics, loads.usable
    if not mdl.muscles:
        raise StageUnavailable(f"model {mdl.name} has no muscles")
    from msk.muscles.geometry import MuscleGeometry, geometry_plan, muscle_geometry
    from msk.timeseries import FrameSparse

    q = np.where(ok[:, None], kin.q, mdl.default_coordinates()[None, :])
    v = np.where(ok[:, None], kin.v, 0.0)
    knee = tuple(j.name for j in mdl.joints if j.name == f"knee{inputs.sfx}")
    plan = geometry_plan(mdl)
    jpos = plan.jacobian_positions()
    dpos = {j: plan.distal_positions(j) for j in knee}
    # filled block by block into arrays allocated once (a list of blocks concatenated at the
    # end held the whole geometry twice at that moment: the stage's high-water, issue 18)
    n, n_mus = q.shape[0], len(plan.muscle_names)
    lengths = np.empty((n, n_mus))
    vel = np.empty((n, n_mus))
    jac = FrameSparse(np.empty((n, jpos.size)), jpos, (n_mus, len(plan.coordinate_names)))
    dws = {j: FrameSparse(np.empty((n, dpos[j].size)), dpos[j], (n_mus, 6)) for j in knee}
    for b in frame_blocks(n):
        sl = slice(int(b[0]), int(b[-1]) + 1) if b.size else slice(0, 0)
        g = muscle_geometry(mdl, q[sl], v[sl], plan=plan, distal_wrench_joints=knee)
        lengths[sl] = g.lengths
        vel[sl] = g.velocities
        jac.values[sl] = np.asarray(g.jacobian).reshape(b.size, -1)[:, jpos]
        for j in knee:
            dws[j].values[sl] = np.asarray(g.distal_wrenches[j]).reshape(b.size, -1)[:, dpos[j]]
        del g
    return MuscleGeometry(
        tuple(plan.muscle_names), tuple(plan.coordinate_names), lengths, jac, vel, dws
    )
