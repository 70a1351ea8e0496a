"""Stage ``knee_contact``: tibiofemoral contact force of the generic and the subject-specific
model (:func:`msk.contact.knee_contact_force`: the joint reaction with the muscle forces, from
the geometry pass's unit wrenches) and its two-point medial/lateral split
(:func:`msk.contact.split_medial_lateral`; Winby et al. 2009; Lerner et al. 2015)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from msk.pipeline.blocks import frame_blocks
from msk.pipeline.dynamics import InverseDynamics
from msk.pipeline.emg import EmgActivations
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.loads import Loads
from msk.pipeline.mass_identification import MassIdentification, identified_model
from msk.pipeline.model import BuiltModel
from msk.pipeline.runner import StageUnavailable
from msk.pipeline.strength import StrengthIdentification
from msk.pipeline.tension import MuscleTensions, optimise

__all__ = ["ContactVariant", "KneeContact", "run", "settings"]


@dataclass(frozen=True)
class ContactVariant:
    """One model's knee contact force (N, 3) in the knee joint frame fixed in the tibia, its
    magnitude and medial/lateral compartment forces (N); NaN where there is no muscle force."""

    force: np.ndarray
    total: np.ndarray
    medial: np.ndarray
    lateral: np.ndarray


@dataclass(frozen=True)
class KneeContact:
    """Contact of the ``generic`` model and, with identified strength, of the
    ``subject_specific`` one; the plateau geometry of the split; the measured force (as read)."""

    joint: str
    variants: Mapping[str, ContactVariant]
    plateau: Mapping[str, Any]
    measured: Any = None


def settings(inputs: SessionInputs) -> Any:
    return {
        "contact": inputs.hashes.get("contact_force"),
        "icd": inputs.cfg.contact.intercondylar_distance_m,
        "depth": inputs.cfg.contact.plateau_depth_m,
    }


def run(
    inputs: SessionInputs,
    model: BuiltModel,
    kinematics: Any,
    loads: Loads,
    mass_identification: MassIdentification | None,
    inverse_dynamics: InverseDynamics,
    emg: EmgActivations | None,
    muscle_geometry: Any,
    tension_optimization: MuscleTensions,
    strength_identification: StrengthIdentification | None,
    measured_contact: Any,
) -> KneeContact:
    from msk.contact import knee_contact_force, plateau_geometry, split_medial_lateral

    mdl, kin = model.model, kinematics
    joint = f"knee{inputs.sfx}"
    if joint not in {j.name for j in mdl.joints}:
        raise StageUnavailable(f"model has no joint {joint!r}")
    variants: dict[str, tuple[Any, MuscleTensions]] = {"generic": (mdl, tension_optimization)}
    if strength_identification is not None:
        from msk.strength import with_strength

        m_spec = with_strength(
            identified_model(mdl, mass_identification), strength_identification.profile
        )
        variants["subject_specific"] = (
            m_spec,
            optimise(
                inputs, m_spec, inverse_dynamics.torques, muscle_geometry, kin.time,
                loads.usable, emg, forces_only=True,
            ),
        )  # fmt: skip
    n = kin.time.size
    out: dict[str, ContactVariant] = {}
    plateau: dict[str, Any] = {}
    # ∂l/∂ξ of the geometry stage (same paths and muscle order in both variants: with_strength
    # only scales F_iso)
    dw = getattr(muscle_geometry, "distal_wrenches", {}).get(joint)
    for name, (m, s) in variants.items():
        # frames without muscle forces get no contact force (never zero muscle force)
        ok = np.flatnonzero(loads.usable & np.isfinite(s.forces).all(axis=1))
        cc = inputs.cfg.contact
        geo = plateau_geometry(
            m, joint=joint, intercondylar_distance_m=cc.intercondylar_distance_m,
            centre_m=None if cc.plateau_depth_m is None else (0.0, -cc.plateau_depth_m, 0.0),
        )  # fmt: skip
        force = np.full((n, 3), np.nan)
        medial = np.full(n, np.nan)
        lateral = np.full(n, np.nan)
        for fr in frame_blocks(ok):  # block by block: memory bounded on long trials
            contact = knee_contact_force(
                m, kin.take(fr), loads.external.take(fr),
                muscle_forces=s.forces[fr], muscle_names=tuple(s.muscles), joint=joint,
                distal_wrenches=None if dw is None else dw[fr],
            )  # fmt: skip
            force[fr] = contact.force
            ml = split_medial_lateral(contact, geo)
            medial[fr], lateral[fr] = ml.medial, ml.lateral
            del contact, ml
        out[name] = ContactVariant(force, np.linalg.norm(force, axis=1), medial, lateral)
        plateau = {
            "intercondylar_distance_m": geo.intercondylar_distance_m,
            "centre_m": list(geo.centre_m),
            "source": geo.source,
        }
    return KneeContact(joint, out, plateau, measured_contact)
