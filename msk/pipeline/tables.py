"""Step ``tables`` (not a recorded stage): the result tables of :mod:`msk.results.folder` from the
stage results (time axis 0, named columns, SI)."""

from __future__ import annotations

from typing import Any

import numpy as np

from msk.dynamics.identification import MassIdentification
from msk.dynamics.inverse import InverseDynamics
from msk.gait.analysis import GaitAnalysis
from msk.io.tables import Table
from msk.optimization.muscle_forces import MuscleForces
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.records import FesResult, GaitCycle, KneeContact, StrengthIdentification

__all__ = ["inertial_table", "run", "strength_table"]


def inertial_table(ident: MassIdentification) -> Table:
    """One row (``time`` = start of the data): ``<segment>.<parameter>`` in Pinocchio order."""
    from msk.model.core import INERTIAL_PARAMETER_NAMES

    cols, vals = [], []
    for b, phi in ident.parameters.items():
        cols += [f"{b}.{p}" for p in INERTIAL_PARAMETER_NAMES]
        vals += list(np.asarray(phi, dtype=float))
    return Table(np.array([ident.t0]), np.array([vals]), tuple(cols), "inertial_parameters")


def strength_table(strength: StrengthIdentification) -> Table:
    """One row: per group factor, CI, F_iso and ``status_code`` (:data:`msk.status.STATUS_CODES`,
    listed in ``summary.json`` ``strength.status_codes``: the tables are numeric)."""
    from msk.status import STATUS_CODES

    p = strength.profile
    status = p.statuses()
    cols, vals = [], []
    for g, name in enumerate(p.group_names):
        for fig, arr in (
            ("factor", p.factors),
            ("ci_low", p.ci_low),
            ("ci_high", p.ci_high),
            ("f_iso_generic", p.f_iso_generic),
            ("f_iso", p.f_iso),
        ):
            cols.append(f"{name}.{fig}")
            vals.append(float(arr[g]))
        cols.append(f"{name}.status_code")
        vals.append(float(STATUS_CODES[status[g]]))
    return Table(np.array([strength.t0]), np.array([vals]), tuple(cols), "strength")


def _contact_table(
    t: np.ndarray, contact: KneeContact, cycle: GaitCycle | None, bw: float
) -> Table:
    cols: list[str] = []
    data: list[np.ndarray] = []
    for name, c in contact.variants.items():
        cols += [f"{name}_{a}" for a in ("x", "y", "z")]
        cols += [f"{name}_total", f"{name}_total_bw"]
        data += [c.force, c.total[:, None], (c.total / bw)[:, None]]
        for comp in ("medial", "lateral", "axial", "shear_anterior", "shear_lateral"):
            v = getattr(c, comp)
            cols += [f"{name}_{comp}", f"{name}_{comp}_bw"]
            data += [v[:, None], (v / bw)[:, None]]
        if c.patellofemoral is not None:  # the patellar tendon's third load, on the patella
            cols += [f"{name}_patellofemoral", f"{name}_patellofemoral_bw"]
            data += [c.patellofemoral[:, None], (c.patellofemoral / bw)[:, None]]
    measured = None if cycle is None else cycle.measured_contact
    for comp, on_t in (measured or {}).items():
        cols += [f"measured_{comp}", f"measured_{comp}_bw"]
        data += [on_t[:, None], (on_t / bw)[:, None]]
    return Table(t, np.column_stack(data), tuple(cols), "knee_contact")


def run(
    inputs: SessionInputs,
    kinematics: Any,
    inverse_dynamics: InverseDynamics | None,
    mass_identification: MassIdentification | None,
    tension_optimization: MuscleForces | None,
    strength_identification: StrengthIdentification | None,
    knee_contact: KneeContact | None,
    gait_cycle: GaitCycle | None,
    fes: FesResult | None,
    gait_analysis: GaitAnalysis | None = None,
) -> dict[str, Table]:
    tables: dict[str, Table] = {}
    if kinematics is not None and inverse_dynamics is not None:
        kin, jt, t = kinematics, inverse_dynamics.torques, kinematics.time
        tables["q"] = Table(t, kin.q, tuple(kin.coordinate_names), "q")
        tables["joint_torques"] = Table(t, jt.tau, tuple(jt.coordinate_names), "joint_torques")
        tables["residuals"] = Table(
            t,
            np.column_stack([jt.residual_force, jt.residual_moment]),
            ("force_x", "force_y", "force_z", "moment_x", "moment_y", "moment_z"),
            "residuals",
        )
        sol = tension_optimization
        if sol is not None:
            tables["muscle_forces"] = Table(t, sol.forces, sol.muscles, "muscle_forces")
            tables["activations"] = Table(t, sol.activations, sol.muscles, "activations")
        if knee_contact is not None:
            tables["knee_contact"] = _contact_table(t, knee_contact, gait_cycle, inputs.body_weight)
        if mass_identification is not None:
            tables["inertial_parameters"] = inertial_table(mass_identification)
        if strength_identification is not None:
            tables["strength"] = strength_table(strength_identification)
        if gait_analysis is not None:
            tables.update(gait_analysis.cycles.to_tables())
    if fes is not None:
        from msk.fes.io import fes_tables  # on use: a gait session does not import msk.fes

        tables.update(fes_tables(fes.result))
    return tables
