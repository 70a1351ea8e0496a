"""Stage ``inverse_dynamics``: joint torques and pelvis residuals of the generic model and,
when the mass distribution was identified, of the identified one
(:func:`msk.dynamics.inverse.inverse_dynamics`, Pinocchio RNEA with the measured ground
reactions)."""

from __future__ import annotations

from typing import Any

from msk.dynamics.identification import MassIdentification, identified_model
from msk.dynamics.inverse import InverseDynamics
from msk.personalise import Personalisation
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.records import Loads

__all__ = ["contact_gated_torques", "run"]


def run(
    inputs: SessionInputs,
    model: Personalisation,
    kinematics: Any,
    loads: Loads,
    mass_identification: MassIdentification | None,
) -> InverseDynamics:
    from msk.dynamics.inverse import inverse_dynamics

    generic = contact_gated_torques(
        model.model, inverse_dynamics(model.model, kinematics, loads.external), loads
    )
    if mass_identification is None:
        return InverseDynamics(generic)
    m_id = identified_model(model.model, mass_identification, by_status=inputs.inertias_by_status)
    return InverseDynamics(
        generic,
        contact_gated_torques(m_id, inverse_dynamics(m_id, kinematics, loads.external), loads),
    )


def contact_gated_torques(model: Any, torques: Any, loads: Loads) -> Any:
    """``torques`` without the frames and legs whose ground reaction the plates miss
    (:func:`msk.dynamics.inverse.without_unmeasured_contact`): a foot standing on an unmeasured
    surface
    (``loads.contact``, runs of at least :data:`msk.dynamics.loads.STANDING_S`), and every foot in a
    frame whose plate load went to no foot or to two
    (:meth:`msk.dynamics.loads.ExternalLoads.flagged`)."""
    from msk.dynamics.inverse import without_unmeasured_contact

    contact = loads.contact
    if contact is None:
        return torques
    miss = contact.standing() | loads.external.flagged()[:, None]
    return without_unmeasured_contact(model, torques, miss, contact.feet)
