"""Stage ``inverse_dynamics``: joint torques and pelvis residuals of the generic model and,
when the mass distribution was identified, of the identified one
(:func:`msk.dynamics.inverse_dynamics`, Pinocchio RNEA with the measured ground reactions)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from msk.pipeline.inputs import SessionInputs
from msk.pipeline.loads import Loads
from msk.pipeline.mass_identification import MassIdentification, identified_model
from msk.pipeline.model import BuiltModel

__all__ = ["InverseDynamics", "run"]


@dataclass(frozen=True)
class InverseDynamics:
    """:class:`msk.dynamics.JointTorques` of the generic model and of the identified one
    (``None`` without mass identification)."""

    generic: Any
    identified: Any = None

    @property
    def torques(self) -> Any:
        """The torques the muscles must produce: identified where available, else generic."""
        return self.generic if self.identified is None else self.identified


def run(
    inputs: SessionInputs,
    model: BuiltModel,
    kinematics: Any,
    loads: Loads,
    mass_identification: MassIdentification | None,
) -> InverseDynamics:
    from msk.dynamics import inverse_dynamics

    generic = inverse_dynamics(model.model, kinematics, loads.external)
    if mass_identification is None:
        return InverseDynamics(generic)
    m_id = identified_model(model.model, mass_identification)
    return InverseDynamics(generic, inverse_dynamics(m_id, kinematics, loads.external))
