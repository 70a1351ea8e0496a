"""Stage ``model``: load the model, recognise the marker set, choose the heading, scale (static
trial, else the motion, else the stature) and place the lab markers; then the task trial in the
model frame and the foot joints its markers cannot observe.

Frames (:func:`msk.io.lab_to_model_rotation`, :func:`msk.io.frames.pelvis_heading_rotation`):
lab vertical → the model's up (−gravity) and the walking direction → the model's +x (OpenSim's
convention), or the pelvis markers' heading where the progression disagrees with it by more
than 30° (treadmill, turning, short trials). Marker placement: :func:`msk.scaling.place_markers`
(static trial) or :func:`msk.scaling.place_markers_from_motion`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from msk.exceptions import ConfigError, ModelError
from msk.io.frames import lab_to_model_rotation
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.read import ReadResult, read_static_markers

__all__ = ["HELD_COORDINATE_WEIGHT", "BuiltModel", "load_model_file", "run", "settings"]

#: IK weight of the coordinate task holding an unobserved foot joint at 0 rad (weight per rad²,
#: markers per m²: 1° off costs as much as 17 mm of marker error)
HELD_COORDINATE_WEIGHT = 1.0


@dataclass(frozen=True)
class BuiltModel:
    """The scaled model with its placed markers, what was done (``info``: source, marker set,
    heading, scaling, placement — reported in ``summary.json`` ``model``), the lab → model
    rotation, and the task trial in the model frame (``trial``, exact-zero samples as gaps)
    with its labels in model names (``labels``), the foot coordinates held near neutral by an
    IK coordinate task (``held``: name → (value rad, weight)) and the GRF-file plates rotated
    alike (``grf_plates``)."""

    model: Any
    info: Mapping[str, Any]
    rotation: np.ndarray
    rename: Mapping[str, str]
    trial: Any
    labels: tuple[str, ...]
    held: Mapping[str, tuple[float, float]]
    grf_plates: tuple[Any, ...] | None


def load_model_file(path: Path, markers: Path | None = None) -> Any:
    """An msk model file or an OpenSim ``.osim`` (with its marker-set ``.xml`` when given)."""
    if path.suffix.lower() == ".osim":
        from msk.osim import load_osim

        return load_osim(path, marker_set=markers)
    from msk.model_files import load_model

    model = load_model(path)
    if markers is not None:
        from msk.osim import read_marker_set

        model = read_marker_set(markers, model)
    return model


def settings(inputs: SessionInputs) -> Any:
    cfg, mc = inputs.cfg, inputs.model_cfg
    assert mc is not None  # a gait stage
    return {
        "model": inputs.hashes["model"],
        "model_markers": inputs.hashes.get("model_markers"),
        "static": inputs.hashes.get("static"),
        "scale": mc.scale,
        "knee": mc.knee,
        "mass": cfg.subject.mass_kg,
        "height": cfg.subject.height_m,
        "rename": dict(cfg.marker_rename),
        "move": list(cfg.marker_move),
    }


def _rotated_plate(plate: Any, rot: np.ndarray) -> Any:
    """A :class:`msk.loads.PlateWrench` rotated by ``rot`` about the origin (force, COP,
    free moment, corners)."""
    r = np.asarray(rot, dtype=float)
    return dataclasses.replace(
        plate,
        force=np.asarray(plate.force) @ r.T,
        cop=np.asarray(plate.cop) @ r.T,
        free_moment=np.asarray(plate.free_moment) @ r.T,
        corners=None if plate.corners is None else np.asarray(plate.corners) @ r.T,
    )


def _scale_and_place(inputs: SessionInputs, read: ReadResult) -> dict[str, Any]:
    from msk.io.frames import pelvis_heading_rotation
    from msk.markersets import recognise, zeros_as_gaps
    from msk.scaling import (
        place_markers,
        place_markers_from_motion,
        scale_from_motion,
        scale_from_static,
    )

    cfg, trial, mc = inputs.cfg, read.trial, inputs.model_cfg
    assert mc is not None and inputs.model_source is not None  # a gait stage
    model = load_model_file(inputs.model_source, mc.markers)
    bodies = [b.name for b in model.bodies]
    info: dict[str, Any] = {"source": str(inputs.model_source), "generic_mass_kg": model.total_mass}
    x_lab = zeros_as_gaps(trial.markers)
    match = recognise(
        trial.marker_labels, model.marker_names, rename=cfg.marker_rename,
        model_bodies=bodies, markers=x_lab,
    )  # fmt: skip
    up = -np.asarray(model.gravity, dtype=float)
    # the static trial, read once: its labels for the checks, its markers for scaling
    static_read = None if inputs.static is None else read_static_markers(inputs.static.file, up)
    labels_all = set(trial.marker_labels)
    if static_read is not None:
        labels_all |= set(static_read[1])
    # names in the configuration that match nothing are errors, not silently ignored (a lab
    # label absent from these trials is a note: rename tables of a protocol list variants a
    # given session may not use)
    absent = sorted(set(cfg.marker_rename.values()) - labels_all)
    unknown = sorted(set(cfg.marker_rename) - set(model.marker_names))
    if unknown:
        raise ConfigError(f"{cfg.path}: markers.rename: the model has no marker {unknown[0]!r}")
    info["marker_set"] = {
        "protocol": match.protocol,
        "matched": dict(match.rename),
        "excluded": dict(match.excluded),
        "notes": list(match.notes)
        + ([f"markers.rename: labels in no trial: {', '.join(absent)}"] if absent else []),
    }
    # heading: the progression where it agrees with the pelvis markers (within 30°), else the
    # pelvis markers (treadmill, turning, short trials), else none
    head = pelvis_heading_rotation(
        trial.up, up, x_lab, trial.marker_labels, model, rename=match.rename
    )
    rot, source = head.rotation, head.source
    prog = head.progression_yaw_deg
    if prog is not None and (
        head.source != "pelvis markers"
        or abs((head.yaw_deg - prog + 180.0) % 360.0 - 180.0) <= 30.0
    ):
        rot, source = lab_to_model_rotation(trial.up, up, trial.markers), "progression"
    info["heading"] = {
        "source": source,
        "pelvis_yaw_deg": head.yaw_deg if head.source == "pelvis markers" else None,
        "progression_yaw_deg": prog,
        "message": head.message,
    }
    report = None
    if static_read is not None:
        sm, slabels_raw, stime = static_read
        smatch = recognise(
            slabels_raw, model.marker_names, rename=cfg.marker_rename,
            model_bodies=bodies, markers=zeros_as_gaps(sm),
        )  # fmt: skip
        sm, slabels = smatch.apply(sm, slabels_raw)
        if mc.scale:
            static = {lab: sm[:, i] for i, lab in enumerate(slabels)}
            model, report = scale_from_static(
                model, static, height_m=cfg.subject.height_m, body_mass=cfg.subject.mass_kg
            )
        try:
            model, placed = place_markers(
                model, sm, slabels, stime, move=cfg.marker_move,
                hints=smatch.body_hints([b.name for b in model.bodies]),
            )  # fmt: skip
        except ModelError as exc:
            raise ConfigError(f"{cfg.path}: markers.move: {exc}") from None
    else:
        # no static trial: the task trial's own markers scale and place (the segment lengths
        # are constant over a motion; msk.scaling.scale_from_motion)
        xm, mlabels = match.apply(trial.rotated(rot).markers, trial.marker_labels)
        if mc.scale:
            model, report = scale_from_motion(
                model, xm, mlabels, trial.time, height_m=cfg.subject.height_m,
                body_mass=cfg.subject.mass_kg,
            )  # fmt: skip
        model, placed = place_markers_from_motion(
            model, xm, mlabels, trial.time, move=cfg.marker_move
        )
    info["marker_placement"] = placed
    if report is not None:
        info["scaling"] = report.summary()
        info["scale_ratios"] = dict(model.metadata.get("scale_ratios", {}))
    info["mass_kg"] = model.total_mass
    return {"model": model, "info": info, "rotation": rot, "rename": dict(match.rename)}


def held_foot_coordinates(
    model: Any, markers: np.ndarray, labels: tuple[str, ...]
) -> dict[str, tuple[float, float]]:
    """Foot joints the markers cannot observe (fewer than 3 markers on the bodies distal to the
    joint: e.g. Plug-in Gait's heel + toe), held near neutral by an IK coordinate task
    (OpenSim's IKCoordinateTask) instead of wandering to −75°. A marker counts when the trial
    tracks it in at least half of the frames it tracks anything (metatarsal-head markers lost
    in most frames do not observe the subtalar)."""
    vis = np.isfinite(markers).all(axis=2)
    anyvis = vis.any(axis=1)
    frac = vis[anyvis].mean(axis=0) if anyvis.any() else np.zeros(len(labels))
    seen = {
        lab for k, lab in enumerate(labels) if lab in model.marker_names and frac[k] >= 0.5
    }  # fmt: skip
    body_of = {m.name: m.body for m in model.markers}
    held: dict[str, tuple[float, float]] = {}
    for sfx in ("_r", "_l"):
        for coord, child in (("subtalar_angle", "calcn"), ("mtp_angle", "toes")):
            name, body = coord + sfx, child + sfx
            if name not in model.coordinate_names or body not in model.body_joint:
                continue
            sub = set(model.subtree(body))
            if sum(body_of.get(m) in sub for m in seen) < 3:
                held[name] = (0.0, HELD_COORDINATE_WEIGHT)
    return held


def run(inputs: SessionInputs, read: ReadResult) -> BuiltModel:
    from msk.markersets import zeros_as_gaps

    cfg, trial = inputs.cfg, read.trial
    built = _scale_and_place(inputs, read)
    model = built["model"]
    unknown = sorted(set(cfg.marker_weights) - set(model.marker_names) - set(trial.marker_labels))
    if unknown:
        raise ConfigError(f"{cfg.path}: markers.weights: no marker {unknown[0]!r}")
    # the task trial in the model frame (lab up → model up, heading as decided above);
    # exact-zero samples are gaps (TRC writers store missing markers as 0, 0, 0)
    rot = built["rotation"]
    mtrial = trial.rotated(rot)
    mtrial = dataclasses.replace(mtrial, markers=zeros_as_gaps(mtrial.markers))
    inv = {v: k for k, v in built["rename"].items()}
    labels = tuple(inv.get(lab, lab) for lab in trial.marker_labels)
    grf = None if read.grf is None else tuple(_rotated_plate(p, rot) for p in read.grf)
    return BuiltModel(
        model, built["info"], rot, built["rename"], mtrial, labels,
        held_foot_coordinates(model, mtrial.markers, labels), grf,
    )  # fmt: skip
