"""Step ``gait_analysis`` (not a recorded stage): every complete gait cycle of both legs
normalised with the gait-lab variables, and the spatiotemporal parameters, from the events of
``gait_cycle``, the kinematics, the joint torques of ``inverse_dynamics`` and the ground
reactions (:func:`msk.gait.analysis.analyse_gait`)."""

from __future__ import annotations

from typing import Any

from msk.dynamics.identification import MassIdentification
from msk.dynamics.inverse import InverseDynamics
from msk.gait.analysis import GaitAnalysis
from msk.personalise import Personalisation
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.records import GaitCycle, Loads

__all__ = ["run"]


def run(
    inputs: SessionInputs,
    model: Personalisation,
    kinematics: Any,
    loads: Loads,
    gait_cycle: GaitCycle,
    inverse_dynamics: InverseDynamics | None,
    mass_identification: MassIdentification | None,
) -> GaitAnalysis:
    from msk.dynamics.identification import identified_model
    from msk.gait.analysis import analyse_gait

    # the torques the report draws (identified inertias where identified) and their model
    torques = None if inverse_dynamics is None else inverse_dynamics.torques
    dyn = model.model
    if inverse_dynamics is not None and inverse_dynamics.identified is not None:
        assert mass_identification is not None  # the identified torques come from it
        dyn = identified_model(
            model.model, mass_identification, by_status=inputs.inertias_by_status
        )
    events = gait_cycle.events
    return analyse_gait(
        model.model, kinematics, events.foot_strike, events.foot_off,
        mass_kg=inputs.mass_kg, torques=torques, loads=loads.external, dynamics_model=dyn,
        trial=inputs.task.name if inputs.task is not None else "",
        angle_convention=inputs.cfg.gait.angle_convention, markers=model.trial,
    )  # fmt: skip
