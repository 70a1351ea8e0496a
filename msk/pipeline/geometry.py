"""Stage ``muscle_geometry``: muscle-tendon lengths, velocities and moment-arm Jacobians on the
usable frames (:func:`msk.muscles.geometry.muscle_geometry`).

The Jacobian is kept compact (:class:`msk.timeseries.FrameSparse`: only the coordinates each
muscle crosses), evaluated block by block (:mod:`msk.pipeline.blocks`): a long trial never holds
it dense. The knee's unit wrenches ∂l/∂ξ are not kept: the knee contact stage recomputes them
block by block from the same paths, where it consumes them (issue 18: held from this stage to
the contact stage, they were 0.6 kB/frame of a long trial's resident set)."""

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
    """:class:`msk.muscles.geometry.MuscleGeometry` with a compact ``jacobian`` (no
    ``distal_wrenches``); frames that are not usable are evaluated at the default pose, at rest
    (their values are never used)."""
    mdl, kin, ok = model.model, kinematics, loads.usable
    if not mdl.muscles:
        raise StageUnavailable(f"model {mdl.name} has no muscles")
    from msk.muscles.geometry import MuscleGeometry, geometry_plan, muscle_geometry
    from msk.timeseries import FrameSparse

    q = np.where(ok[:, None], kin.q, mdl.default_coordinates()[None, :])
    v = np.where(ok[:, None], kin.v, 0.0)
    plan = geometry_plan(mdl)
    jpos = plan.jacobian_positions()
    # filled block by block into arrays allocated once (a list of blocks concatenated at the
    # end held the whole geometry twice at that moment: the stage's high-water, issue 18)
    n, n_mus = q.shape[0], len(plan.muscle_names)
    lengths = np.empty((n, n_mus))
    vel = np.empty((n, n_mus))
    jac = FrameSparse(np.empty((n, jpos.size)), jpos, (n_mus, len(plan.coordinate_names)))
    for b in frame_blocks(n):
        sl = slice(int(b[0]), int(b[-1]) + 1) if b.size else slice(0, 0)
        g = muscle_geometry(mdl, q[sl], v[sl], plan=plan)
        lengths[sl] = g.lengths
        vel[sl] = g.velocities
        jac.values[sl] = np.asarray(g.jacobian).reshape(b.size, -1)[:, jpos]
        del g
    return MuscleGeometry(tuple(plan.muscle_names), tuple(plan.coordinate_names), lengths, jac, vel)
