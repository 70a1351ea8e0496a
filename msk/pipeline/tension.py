"""Stage ``tension_optimization``: muscle forces that produce the joint torques
(:func:`msk.optimization.muscle_forces.solve_muscle_forces`, the criterion ``[optimization]
method`` names) on the frames each leg can be solved in, with the identified inertias when the
mass distribution was identified."""

from __future__ import annotations

import dataclasses
from typing import Any

from msk.dynamics.identification import MassIdentification, identified_model
from msk.dynamics.inverse import InverseDynamics
from msk.muscles.emg import EmgActivations
from msk.optimization.criteria import criterion
from msk.optimization.muscle_forces import MuscleForces, solve_muscle_forces
from msk.personalise import Personalisation
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.records import Loads

__all__ = ["needs", "run", "settings"]


def needs(inputs: SessionInputs) -> tuple[str, ...]:
    emg = criterion(inputs.cfg.optimization.method).reads_emg
    return ("model", "kinematics", "loads", "muscle_geometry", "inverse_dynamics") + (
        ("emg",) if emg else ()
    )


def settings(inputs: SessionInputs) -> Any:
    out = dataclasses.asdict(inputs.cfg.optimization)
    if inputs.cfg.optimization.compartment_nonnegative:  # the rows' contact points and patella
        out["contact"] = dataclasses.asdict(inputs.cfg.contact)
    return out


def run(
    inputs: SessionInputs,
    model: Personalisation,
    kinematics: Any,
    loads: Loads,
    mass_identification: MassIdentification | None,
    inverse_dynamics: InverseDynamics,
    muscle_geometry: Any,
    emg: EmgActivations | None,
) -> MuscleForces:
    torques = inverse_dynamics.torques
    m_id = identified_model(model.model, mass_identification, by_status=inputs.inertias_by_status)
    return solve_muscle_forces(
        m_id, torques, muscle_geometry, kinematics.time, loads.solvable, emg,
        kinematics=kinematics, external=loads.external,
        unbalanced=loads.unbalanced_for(torques.coordinate_names),
        **inputs.muscle_force_options(m_id),
    )  # fmt: skip
