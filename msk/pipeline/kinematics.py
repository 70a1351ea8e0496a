"""Stage ``kinematics``: inverse kinematics of the task trial
(:func:`msk.kinematics.trial.solve_trial`)."""

from __future__ import annotations

from typing import Any

from msk.kinematics.ik import Kinematics
from msk.kinematics.trial import solve_trial
from msk.personalise import Personalisation
from msk.pipeline.inputs import SessionInputs

__all__ = ["run", "settings"]


def settings(inputs: SessionInputs, model: Personalisation) -> Any:
    return {
        "weights": dict(inputs.cfg.marker_weights),
        "cut": inputs.cfg.filters.kinematics_cutoff_hz,
        "domain": inputs.cfg.filters.acceleration_domain,
        "held": dict(model.held),
    }


def run(inputs: SessionInputs, model: Personalisation) -> Kinematics:
    """:class:`msk.kinematics.ik.Kinematics` of the task trial."""
    return solve_trial(
        model.model, model.trial, model.labels, weights=inputs.cfg.marker_weights,
        held=model.held, cutoff_hz=inputs.cfg.filters.kinematics_cutoff_hz,
        acceleration_domain=inputs.cfg.filters.acceleration_domain,
    )  # fmt: skip
