"""Stage ``knee_contact``: tibiofemoral contact force of the generic and the subject-specific
model (:func:`msk.contact.knee.knee_contact_force`: the joint reaction with the muscle forces, from
the knee's unit wrenches of a geometry pass) and its two-point medial/lateral split
(:func:`msk.contact.knee.split_medial_lateral`; Winby et al. 2009; Lerner et al. 2015).

Block by block of frames (:class:`msk.contact.blocks.ContactAssembly`): the knee's unit
wrenches are recomputed for each block from the model's paths (the geometry stage does not hold
them for the whole trial), and the subject-specific re-solve hands each solved block's forces to
both variants' contact (:func:`msk.optimization.muscle_forces.solve_muscle_forces`
``on_block``) — its forces are never held whole."""

from __future__ import annotations

from typing import Any

import numpy as np

from msk._runtime.blocks import frame_blocks
from msk.contact.blocks import ContactAssembly
from msk.dynamics.identification import MassIdentification, identified_model
from msk.dynamics.inverse import InverseDynamics
from msk.kinematics.ik import Kinematics
from msk.model.core import Model
from msk.muscles.emg import EmgActivations
from msk.optimization.muscle_forces import MuscleForces, solve_muscle_forces
from msk.personalise import Personalisation
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.records import KneeContact, Loads, StrengthIdentification
from msk.pipeline.runner import StageUnavailable

__all__ = ["run", "settings"]


def settings(inputs: SessionInputs) -> Any:
    return {
        "contact": inputs.hashes.get("contact_force"),
        "icd": inputs.cfg.contact.intercondylar_distance_m,
        "depth": inputs.cfg.contact.plateau_depth_m,
        "patella": inputs.cfg.contact.patella,
    }


def run(
    inputs: SessionInputs,
    model: Personalisation,
    kinematics: Kinematics,
    loads: Loads,
    mass_identification: MassIdentification | None,
    inverse_dynamics: InverseDynamics,
    emg: EmgActivations | None,
    muscle_geometry: Any,
    tension_optimization: MuscleForces,
    strength_identification: StrengthIdentification | None,
    measured_contact: Any,
) -> KneeContact:
    mdl, kin = model.model, kinematics
    from msk.model.conventions import knee_joint

    found = knee_joint(mdl, inputs.sfx)
    if found is None:
        raise StageUnavailable(f"model has no knee joint (child body 'tibia{inputs.sfx}')")
    joint = found
    from msk.muscles.geometry import geometry_plan

    # ∂l/∂ξ of the knee recomputed block by block from the model's paths (the geometry stage
    # does not keep them for the whole trial); the same paths and muscle order in
    # both variants (with_strength only scales F_iso)
    plan = geometry_plan(mdl)

    ci = mdl.coordinate_index(next(a.coordinate for s in mdl.joints if s.name == joint
                                   for a in s.axes if a.coordinate is not None))  # fmt: skip

    def wrenches(fr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The knee's unit wrenches (N, muscles, 6) and the muscles' length Jacobian on the
        knee coordinate (N, muscles) of frames ``fr`` (one geometry pass)."""
        if not fr.size:
            return np.zeros((0, plan.n_muscles, 6)), np.zeros((0, plan.n_muscles))
        g = plan.evaluate(kin.q[fr], distal_wrench_joints=(joint,), compact=True)
        return np.asarray(g.distal_wrenches[joint]), np.asarray(g.jacobian[:])[:, :, ci]

    from msk.contact.patella import patella_mode

    # a model whose quadriceps end on its own patella (Rajagopal) reaches the tibia through
    # the tendon whatever [contact] patella says (msk.contact.patella.patella_mode)
    mode = patella_mode(mdl, joint, inputs.cfg.contact.patella)
    tendon = mode == "tendon"

    def variant(m: Model) -> ContactAssembly:
        from msk.contact.patella import patellar_tendon

        pt = patellar_tendon(m, joint=joint) if tendon else None
        return ContactAssembly(m, inputs.knee_plateau(m, joint), kin, loads.external, joint, pt)

    gen_forces, names = tension_optimization.forces, tension_optimization.muscles
    # frames without the knee's muscle forces get no contact force (never zero muscle force;
    # a frame whose other leg is left out of the tension QP is solved for this knee:
    # ContactAssembly.fill)
    gen_ok = loads.solvable & np.isfinite(gen_forces).any(axis=1)
    # both variants on the inertias the muscle forces balance (the tension stage's torques are
    # the identified model's): the joint reaction of the generic model's inertias with those
    # forces mixed two models (PS ss1: up to 82/111 N on the medial/lateral split)
    m_id = identified_model(mdl, mass_identification, by_status=inputs.inertias_by_status)
    generic = variant(m_id)
    variants = {"generic": generic}
    if strength_identification is not None:
        from msk.strength import with_strength

        # only the identified groups' factors (the others keep the generic F_iso)
        m_spec = with_strength(m_id, strength_identification.profile.applied_factors())
        spec = variants["subject_specific"] = variant(m_spec)
        done = np.zeros(kin.time.size, dtype=bool)

        def on_block(fr: np.ndarray, forces: np.ndarray) -> None:
            """One block of the subject-specific re-solve: both variants' contact on its frames
            (the wrenches computed once), its forces then dropped — a long trial never holds
            the re-solve's forces whole."""
            w, jk = wrenches(fr)
            ks = np.isfinite(forces).any(axis=1)
            spec.fill(fr[ks], forces[ks], w[ks], names, jk[ks])
            kg = gen_ok[fr]
            generic.fill(fr[kg], gen_forces[fr[kg]], w[kg], names, jk[kg])
            done[fr] = True

        torques = inverse_dynamics.torques
        solve_muscle_forces(
            m_spec, torques, muscle_geometry, kin.time, loads.solvable, emg,
            on_block=on_block, kinematics=kin, external=loads.external,
            unbalanced=loads.unbalanced_for(torques.coordinate_names),
            **inputs.muscle_force_options(m_spec),
        )  # fmt: skip
        gen_ok &= ~done  # generic frames no re-solve block had (normally none)
    for fr in frame_blocks(np.flatnonzero(gen_ok)):  # block by block: memory bounded
        w, jk = wrenches(fr)
        generic.fill(fr, gen_forces[fr], w, names, jk)
    out = {name: v.result() for name, v in variants.items()}
    geo = variants["subject_specific" if "subject_specific" in variants else "generic"].geometry
    plateau = {
        "intercondylar_distance_m": geo.intercondylar_distance_m,
        "centre_m": list(geo.centre_m),
        "source": geo.source,
        "patella": mode,
    }
    return KneeContact(joint, out, plateau, measured_contact)
