"""Stage ``mass_identification``: segment inertial parameters from the floating-base equations
of the task trial and the dedicated exciting trials
(:class:`msk.dynamics.identification.InertialIdentifier`,
physically consistent, symmetric, prior weight chosen by held-out residuals)."""

from __future__ import annotations

from typing import Any

import numpy as np

from msk.dynamics.identification import MassIdentification, segment_summary
from msk.kinematics.trial import solve_trial
from msk.personalise import Personalisation
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.records import Loads, ReadResult
from msk.pipeline.runner import StageUnavailable, file_sha256

__all__ = ["run", "settings"]


def settings(inputs: SessionInputs) -> Any:
    return {
        "trials": [file_sha256(t.file) for t in inputs.mass_trials],
        "mass": inputs.cfg.subject.mass_kg,
        # which segments the stages downstream apply (identified_model): in their keys through
        # this one
        "inertias": inputs.inertias_by_status,
    }


def run(
    inputs: SessionInputs, read: ReadResult, model: Personalisation, kinematics: Any, loads: Loads
) -> MassIdentification:
    from msk.dynamics.identification import IdentificationTrial, InertialIdentifier
    from msk.dynamics.loads import contact_measured
    from msk.io import read_trial, to_model_frame
    from msk.kinematics.observation import observed_frames

    cfg, mdl, kin = inputs.cfg, model.model, kinematics
    assert inputs.task is not None  # a gait stage
    up = -np.asarray(mdl.gravity, dtype=float)
    # measured and observed frames only (msk.kinematics.observation: a guessed pose's q̈ is no
    # equation)
    runs = [(inputs.task.name, kin, loads.external, loads.usable)]
    # the task and the dedicated exciting motions (Hayashibe et al. 2011, §VI)
    for tc in inputs.mass_trials:
        tr_i = to_model_frame(read_trial(tc.file), up=up)
        k_i = solve_trial(
            mdl, tr_i, inputs.labels_of(tr_i.marker_labels), weights=cfg.marker_weights,
            held=model.held, cutoff_hz=cfg.filters.kinematics_cutoff_hz,
            acceleration_domain=cfg.filters.acceleration_domain,
        )  # fmt: skip
        l_i = inputs.external_loads(mdl, tr_i, k_i, assignment=read.assignment)
        seen = observed_frames(mdl, k_i).observed
        runs.append((tc.name, k_i, l_i, contact_measured(mdl, k_i, l_i) & seen))
    its = []
    for nm, k_i, l_i, m_i in runs:
        it = IdentificationTrial.from_loads(mdl, k_i, l_i, name=nm)
        good = np.isfinite(it.tau_ext).all(axis=1) & np.isfinite(it.theta_ddot).all(axis=1) & m_i
        its.append(
            IdentificationTrial(
                it.theta[good], it.theta_dot[good], it.theta_ddot[good], it.tau_ext[good], nm
            )
        )
        del it  # its τ_ext of every frame
    if sum(len(it.theta) for it in its) < 2:  # e.g. no plate loaded: a reason, not a failure
        raise StageUnavailable(
            "fewer than 2 frames with every foot's contact measured and every leg segment "
            f"observed (trials {[it.name for it in its]})"
        )
    est = InertialIdentifier(
        mdl, total_mass=cfg.subject.mass_kg, symmetric=True, prior_weight="cv"
    ).fit(its)
    good = np.isfinite(kin.q).all(axis=1)
    return MassIdentification(
        {k: np.asarray(v) for k, v in est.parameters_.items()},
        [segment_summary(s) for s in est.segments_],
        float(est.condition_number_),
        int(est.n_frames_),
        list(est.advice()),
        float(kin.time[good][0]),
    )
