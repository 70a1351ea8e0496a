"""A live session set up from a session configuration (``msk live``): the pipeline's model stage
makes the subject's model from the static trial (:func:`msk.personalise.personalise`, as
``msk run`` does) with the segment inertias its mass identification finds on the
configuration's task trial (an earlier recording of the subject: the inertias ``msk run``'s
joint torques use; ``identified=False``: the scaled ones), and :func:`msk.live.live_model`
sets the streaming chain up on it.

The lab → model rotation is the one the model stage found for the configuration's task trial
(:attr:`msk.personalise.Personalisation.rotation`): a stream recorded in the same lab. The
static optimisation of live mode uses the configuration's activation weights, exponent and
solver; an EMG-driven criterion (``emg_assisted``, ``emg_weighted``) fits its gains on a whole
trial and the knee compartment rows need the trial's contact geometry block by block: live mode
solves static optimisation without them (docs/user-guide.md, "Live mode").
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from msk.config import SessionConfig, load_config
from msk.live import LiveModel, LiveOptions, live_model
from msk.pipeline.inputs import session_inputs
from msk.pipeline.session import run_stages

__all__ = ["LiveSetup", "live_setup"]


@dataclass(frozen=True)
class LiveSetup:
    """``model``: the live chain's :class:`msk.live.LiveModel`; ``personalisation``: the model
    stage's result; ``identified``: whether the segment inertias are the identified ones;
    ``body_weight_n``: the session's body weight (the BW columns)."""

    model: LiveModel
    personalisation: Any
    identified: bool
    body_weight_n: float


def live_setup(
    config: str | Path | SessionConfig,
    labels: Sequence[str],
    rate_hz: float,
    *,
    identified: bool = True,
    ik_iterations: int = 10,
    filter_order: int = 2,
    smoother: str = "butterworth",
    plate_names: Sequence[str] = (),
    assignment: Mapping[str, str] | None = None,
) -> LiveSetup:
    """The live chain of ``config``'s subject for a stream of the lab's marker ``labels`` at
    ``rate_hz``. ``identified``: run the pipeline up to its mass identification on the
    configured task trial and use those inertias, as ``msk run``'s torques do (none
    identified, or False: the scaled ones). ``smoother``: :class:`msk.live.LiveOptions`'.
    ``plate_names``: the stream's plates, in order; ``assignment``: plate name → body (an
    ExternalLoads ``.xml``'s), with ``[loads] assign`` over it, as ``msk run`` assigns."""
    from msk.dynamics.identification import identified_model

    cfg = config if isinstance(config, SessionConfig) else load_config(config)
    res = run_stages(cfg, until="mass_identification" if identified else "model")
    pers = res["model"]
    inputs = session_inputs(cfg)
    mass = res.get("mass_identification") if identified else None
    model = identified_model(pers.model, mass, by_status=inputs.inertias_by_status)
    to_model = {lab: name for name, lab in pers.rename.items()}
    from msk.model.conventions import knee_joint

    found = knee_joint(model, inputs.sfx)
    knee = found if found is not None else f"knee{inputs.sfx}"
    has_knee = found is not None
    opt = cfg.optimization
    options = LiveOptions(
        cutoff_hz=cfg.filters.kinematics_cutoff_hz or 6.0, filter_order=filter_order,
        smoother=smoother,
        ik_iterations=ik_iterations, knee_joint=knee if has_knee else None,
        activation_weights=opt.activation_weights, activation_exponent=opt.activation_exponent,
        solver=opt.solver,
    )  # fmt: skip
    assign = {**(assignment or {}), **cfg.loads.assign}
    lm = live_model(
        model, [to_model.get(lab, lab) for lab in labels], rate_hz, rotation=pers.rotation,
        weights=cfg.marker_weights, held=pers.held, options=options,
        plateau=inputs.knee_plateau(model, knee) if has_knee else None,
        body_weight_n=inputs.body_weight,
        plate_bodies=[assign.get(p) for p in plate_names],
    )  # fmt: skip
    return LiveSetup(lm, pers, mass is not None, float(inputs.body_weight))
