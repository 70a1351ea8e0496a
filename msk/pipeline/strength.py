"""Stage ``strength_identification``: one strength factor per EMG channel's muscle group from
the EMG activations, the moment-arm Jacobians and the joint torques, with bootstrap intervals
(:class:`msk.strength.StrengthIdentifier`; Hayashibe et al. 2011, §V, Eq. 12–14)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from msk.exceptions import IdentificationError
from msk.pipeline.dynamics import InverseDynamics
from msk.pipeline.emg import EmgActivations
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.loads import Loads
from msk.pipeline.model import BuiltModel
from msk.pipeline.runner import StageUnavailable

__all__ = ["StrengthIdentification", "run"]


@dataclass(frozen=True)
class StrengthIdentification:
    """The :class:`msk.strength.StrengthProfile` (factors × generic, intervals, statuses), the
    muscles of each group, and ``t0`` the start (s) of the data identified from."""

    profile: Any
    groups: Mapping[str, Sequence[str]]
    t0: float


def run(
    inputs: SessionInputs,
    model: BuiltModel,
    kinematics: Any,
    loads: Loads,
    inverse_dynamics: InverseDynamics,
    emg: EmgActivations,
    muscle_geometry: Any,
) -> StrengthIdentification:
    from msk.muscles.geometry import muscle_parameters
    from msk.muscles.hill import RigidTendonStateBlocks
    from msk.strength import StrengthIdentifier
    from msk.timeseries import FrameSparse

    jt = inverse_dynamics.torques
    good = loads.usable & np.isfinite(jt.tau).all(axis=1)
    frames = np.flatnonzero(good)
    if frames.size == 0:  # e.g. a trial no foot stands on a plate in: a reason, not a traceback
        raise StageUnavailable(
            "no frame with every foot's contact measured, every leg segment observed and "
            "finite joint torques"
        )
    # the Hill state of the frames used, computed block by block as the identifier needs it
    # (its ten (N, M) arrays are never held whole); the compact Jacobian of those frames only
    params = muscle_parameters(model.model)
    state = RigidTendonStateBlocks(
        params, muscle_geometry.lengths, muscle_geometry.velocities, frames
    )
    groups: dict[str, list[str]] = {}
    for k, m in enumerate(emg.muscles):
        if emg.usable[k]:
            groups.setdefault(emg.sources[k], []).append(m)
    if not groups:
        raise StageUnavailable("no usable EMG channel")
    # the measured muscles' columns only (compact over the muscles: the others are 0, and a
    # long trial's (N, M) activation was the stage's largest array, issue 18)
    cols = sorted({params.names.index(m) for k, m in enumerate(emg.muscles) if emg.usable[k]})
    act = FrameSparse(
        np.zeros((frames.size, len(cols))), np.asarray(cols, dtype=np.intp), (len(params.names),)
    )
    for k, m in enumerate(emg.muscles):
        if emg.usable[k]:
            act.values[:, cols.index(params.names.index(m))] = emg.activation[good, k]
    est = StrengthIdentifier(groups, params, n_bootstrap=200, random_state=0)
    # the whole trial's compact Jacobian, its rows of the used frames read block by block
    jac = muscle_geometry.jacobian
    jac = jac if isinstance(jac, FrameSparse) else np.asarray(jac)
    try:
        est.fit(
            jac,
            act,
            jt.tau[good],
            state,
            coordinate_names=jt.coordinate_names,
            frames=frames,
        )
    except IdentificationError as exc:
        # the measured frames do not determine any group (e.g. no window passes the
        # correlation gate on a trial with one stance on the plates): not available, said why
        raise StageUnavailable(
            f"the {int(good.sum())} measured frames determine no strength: {exc}"
        ) from None
    return StrengthIdentification(
        est.profile_, {g: list(v) for g, v in groups.items()}, float(kinematics.time[good][0])
    )
