"""Stage ``model``: load the model file, read the static trial, and make the model the subject's
(:func:`msk.personalise.personalise`: scaling, marker placement and its choice, leg split, sole
level, placement determinacy, the task trial in the model frame and the foot joints its markers
cannot observe)."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np

from msk.model.core import Model
from msk.personalise import (
    KneeAlignmentOptions,
    MarkerOptions,
    Personalisation,
    PersonaliseOptions,
    personalise,
    read_static_trial,
)
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.records import ReadResult

__all__ = ["BuiltModel", "load_model_file", "options", "run", "settings", "without_markers"]

#: the model stage's result: :class:`msk.personalise.Personalisation`
BuiltModel = Personalisation


def load_model_file(path: Path, markers: Path | None = None) -> Model:
    """An msk model file or an OpenSim ``.osim`` (with its marker-set ``.xml`` when given)."""
    if path.suffix.lower() == ".osim":
        from msk.model.osim import load_osim

        return load_osim(path, marker_set=markers)
    from msk.model.files import load_model

    model = load_model(path)
    if markers is not None:
        from msk.model.osim import read_marker_set

        model = read_marker_set(markers, model)
    return model


def settings(inputs: SessionInputs) -> dict[str, object]:
    cfg, mc = inputs.cfg, inputs.model_cfg
    assert mc is not None  # a gait stage
    return {
        "model": inputs.hashes["model"],
        "model_markers": inputs.hashes.get("model_markers"),
        "static": inputs.hashes.get("static"),
        "functional": sorted(v for k, v in inputs.hashes.items() if k.startswith("functional:")),
        "scale": mc.scale,
        "knee": mc.knee,
        "knee_alignment": (mc.knee_alignment, mc.knee_varus_deg, mc.knee_medial_shift_m),
        "mass": cfg.subject.mass_kg,
        "height": cfg.subject.height_m,
        "rename": dict(cfg.marker_rename),
        "move": list(cfg.marker_move),
        "virtual": dict(cfg.marker_virtual),
        # also read by the stage (the key is complete: its result is kept in the cache): the
        # weights (placement without a static; their names checked), the side (knee alignment
        # from markers), the model file's path (summary.json model.source)
        "weights": dict(cfg.marker_weights),
        "side": cfg.subject.side,
        "source": str(inputs.model_source),
    }


def options(inputs: SessionInputs) -> PersonaliseOptions:
    """The session's :class:`msk.personalise.PersonaliseOptions` (what :func:`settings` keys)."""
    cfg, mc = inputs.cfg, inputs.model_cfg
    assert mc is not None  # a gait stage
    source: Literal["given", "from_markers"] = (
        "from_markers" if mc.knee_alignment == "from_markers" else "given"
    )
    return PersonaliseOptions(
        mass_kg=inputs.mass_kg, height_m=cfg.subject.height_m, side=cfg.subject.side,
        scale=mc.scale, hip_centre=mc.hip_centre,
        knee_alignment=KneeAlignmentOptions(
            source=source, varus_deg=mc.knee_varus_deg, medial_shift_m=mc.knee_medial_shift_m
        ),
        markers=MarkerOptions(
            rename=cfg.marker_rename, weights=cfg.marker_weights, move=cfg.marker_move,
            virtual=cfg.marker_virtual,
        ),
        source=str(inputs.model_source), origin=str(cfg.path),
    )  # fmt: skip


def run(inputs: SessionInputs, read: ReadResult) -> Personalisation:
    """The generic model of ``[model]`` made the subject's from the static trial (when the
    session has one) and the task trial (:func:`msk.personalise.personalise`)."""
    mc = inputs.model_cfg
    assert mc is not None and inputs.model_source is not None  # a gait stage
    model = load_model_file(inputs.model_source, mc.markers)
    up = -np.asarray(model.gravity, dtype=float)
    static = (
        None
        if inputs.static is None
        else read_static_trial(inputs.static.file, up, model=model, rename=inputs.cfg.marker_rename)
    )
    functional = None
    trials = inputs.cfg.trials_with_role("functional")
    if static is not None and trials:  # the hip centres' functional trial (its first)
        from msk.io import read_trial, to_model_frame

        functional = to_model_frame(read_trial(trials[0].file), up=up, forward=None)
    return personalise(model, static, read.trial, options(inputs), hip_trial=functional)


def without_markers(model: Personalisation) -> Personalisation:
    """``model`` without the task's model-frame markers
    (:meth:`msk.personalise.Personalisation.without_markers`): the step ``gait_analysis`` is
    the last to read them, and :func:`msk.pipeline.graph.run_graph` drops them after it
    (:data:`msk.pipeline.graph.TRIMS`)."""
    return model.without_markers()
