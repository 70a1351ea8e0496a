"""The true knee contact of a synthetic lab task (:mod:`msk.datasets.tasks`), with the
quadriceps acting through the patellar tendon.

The task's truth is its motion θ(t) (exact θ̇, θ̈ from the quintic spline), the feet's ground
reactions and the joint torques τ they need. Its **true muscle forces** are the muscle forces of
that model carrying exactly those torques by the session's criterion (``[optimization]``: for
static optimisation, min Σ V_i a_i² with Σ_i F_i(a_i) r_ij = τ_j; Crowninshield & Brand 1981,
Anderson & Pandy 2001) on the **true** kinematics and reactions — a subject who recruits their
muscles that way — posed with the same knee (the compartment rows with the tendon when the
criterion has them). The **true contact** is then the knee's free-body balance with those forces
and the quadriceps reaching the tibia only through the patellar tendon
(:mod:`msk.contact.patella`, :func:`msk.contact.knee.knee_contact_force`)::

    W_contact = W_ID + Σ_{i ∉ Q} F_i ∂l_i/∂ξ − Σ_{i ∈ Q} F_i ρ_i (e, T × e),

resolved on the tibial plateau: axial (compressive, along the tibia's long axis), anterior and
lateral shear on the tibia (:class:`msk.contact.blocks.ContactVariant`), and the
patellofemoral force |F_PF|.

A pipeline run on the task's C3D therefore differs from this truth only by what it estimates:
the kinematics from noisy markers (and their 6 Hz low-pass), the plates' noise and filter, the
segment inertias it identifies — not by its criterion or its knee mechanism."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from msk.units import Array

__all__ = ["TrueKneeContact", "task_external_loads", "true_knee_contact"]


@dataclass(frozen=True)
class TrueKneeContact:
    """A task's true knee contact (module docstring) at the motion's samples ``time`` (s).

    Attributes:
        time: (N,) s.
        muscles: names of the columns of ``forces``.
        forces: (N, K) the true muscle tensions (N).
        force: (N, 3) the femur's force on the tibia in the plateau frame (x anterior,
            y proximal, z right), N.
        axial: (N,) compressive force along the tibia's long axis, N.
        shear_anterior: (N,) anterior shear on the tibia, N.
        shear_lateral: (N,) lateral shear on the tibia, N.
        patellofemoral: (N,) |F_PF|, N.
        body_weight_n: the model's weight m g (N).
        tau_rmse_nm: RMS difference between the inverse dynamics of the truth's kinematics and
            reactions and the task's true torques over the leg coordinates (a check of the
            reconstruction, ≈ 0).
    """

    time: Array
    muscles: tuple[str, ...]
    forces: Array
    force: Array
    axial: Array
    shear_anterior: Array
    shear_lateral: Array
    patellofemoral: Array
    body_weight_n: float
    tau_rmse_nm: float


def task_external_loads(task: Any) -> Any:
    """The task's true ground reactions at its motion's samples as
    :class:`msk.dynamics.loads.ExternalLoads` on the feet (world frame; moment about the
    world origin = c × f + free moment; point = the centre of pressure)."""
    from msk.datasets.tasks import FEET
    from msk.dynamics.loads import ExternalLoads

    re, t = task.reactions, np.asarray(task.motion.time, dtype=float)
    idx = np.clip(np.searchsorted(re.time, t - 1e-9), 0, re.time.size - 1)
    f = np.asarray(re.force[idx], dtype=float)
    cop = np.asarray(re.cop[idx], dtype=float)
    m = np.cross(np.nan_to_num(cop), f) + np.asarray(re.free_moment[idx], dtype=float)
    return ExternalLoads(time=t, bodies=tuple(FEET), force=f, moment=m, point=cop)


def true_knee_contact(
    task: Any,
    options: Any,
    *,
    joint: str = "knee_r",
    intercondylar_distance_m: float | None = None,
    centre_m: Any = None,
) -> TrueKneeContact:
    """The true knee contact of ``task`` (a :class:`msk.datasets.tasks.LabTask`) with the
    patellar tendon (module docstring): the muscle forces by the criterion ``options`` (an
    :class:`msk.config.options.OptimizationConfig`, the session's ``[optimization]``) on the
    true motion and reactions of the task's model, and the contact of ``joint`` with them.
    ``intercondylar_distance_m``, ``centre_m``: the two contact points of the compartment rows
    (:func:`msk.contact.knee.plateau_geometry`; default: the model's scaled defaults)."""
    from msk.contact.blocks import ContactAssembly
    from msk.contact.knee import plateau_geometry
    from msk.contact.patella import patellar_tendon
    from msk.dynamics.inverse import inverse_dynamics
    from msk.kinematics.ik import kinematics_from_coordinates
    from msk.muscles.geometry import geometry_plan, muscle_geometry
    from msk.optimization.muscle_forces import solve_muscle_forces

    motion = task.motion
    model = motion.model
    t = np.asarray(motion.time, dtype=float)
    th, thd, thdd = motion.at(t)
    names = tuple(model.coordinate_names)
    kin = kinematics_from_coordinates(t, th, names, cutoff_hz=None, model=model)
    kin = dataclasses.replace(kin, v=np.asarray(thd, float), a=np.asarray(thdd, float))
    ext = task_external_loads(task)
    tq = inverse_dynamics(model, kin, ext)
    legs = [i for i, c in enumerate(tq.coordinate_names) if c.startswith(("hip", "knee", "ankle"))]
    cols = [names.index(tq.coordinate_names[i]) for i in legs]
    tau_rmse = float(np.sqrt(np.mean((tq.tau[:, legs] - task.tau[:, cols]) ** 2)))
    plateau = plateau_geometry(
        model, joint=joint, intercondylar_distance_m=intercondylar_distance_m, centre_m=centre_m
    )
    geo = muscle_geometry(model, kin.q, kin.v)
    mf = solve_muscle_forces(
        model, tq, geo, t, np.ones(t.size, dtype=bool), None, options=options,
        knee_joint=joint, knee_plateau=plateau if options.compartment_nonnegative else None,
        knee_patella=True, forces_only=True, kinematics=kin, external=ext,
    )  # fmt: skip
    pt = patellar_tendon(model, joint=joint)
    asm = ContactAssembly(model, plateau, kin, ext, joint, pt)
    plan = geometry_plan(model)
    spec = next(j for j in model.joints if j.name == joint)
    ci = model.coordinate_index(next(a.coordinate for a in spec.axes if a.coordinate is not None))
    g = plan.evaluate(kin.q, distal_wrench_joints=(joint,), compact=True)
    asm.fill(np.arange(t.size), mf.forces, np.asarray(g.distal_wrenches[joint]), mf.muscles,
             np.asarray(g.jacobian[:])[:, :, ci])  # fmt: skip
    c = asm.result()
    mass = float(sum(i.mass for i in model.pin_model.inertias))
    from msk.units import G0

    pf = c.patellofemoral if c.patellofemoral is not None else np.full(t.size, np.nan)
    return TrueKneeContact(
        time=t, muscles=tuple(mf.muscles), forces=np.asarray(mf.forces), force=c.force,
        axial=c.axial, shear_anterior=c.shear_anterior, shear_lateral=c.shear_lateral,
        patellofemoral=pf, body_weight_n=mass * G0, tau_rmse_nm=tau_rmse,
    )  # fmt: skip
