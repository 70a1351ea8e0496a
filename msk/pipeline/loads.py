"""Stage ``loads``: the ground reactions assigned to the feet
(:func:`msk.dynamics.loads.external_loads`)
and the frames whose ground contact the plates measure
(:func:`msk.dynamics.loads.contact_measured`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from typing import Any

import numpy as np

from msk.dynamics.loads import ASSIGNMENT_METHOD, rotated_plate
from msk.dynamics.plate_footprint import exclude_plate_edges
from msk.dynamics.plate_surface import prepared_plates
from msk.kinematics.observation import OBSERVATION_METHOD
from msk.personalise import Personalisation
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.records import Loads, ReadResult

__all__ = [
    "run",
    "settings",
    "unbalanced_coordinates",
]


def settings(inputs: SessionInputs) -> Any:
    return {
        "cut": inputs.cfg.filters.grf_cutoff_used_hz,
        "assignment": ASSIGNMENT_METHOD,
        "assign": dict(inputs.cfg.loads.assign),
        "surface_height_m": dict(inputs.cfg.loads.surface_height_m),
        "ignore": list(inputs.cfg.loads.ignore),
        "remove_baseline": inputs.cfg.loads.remove_baseline,
        "observed": OBSERVATION_METHOD,
    }


def run(inputs: SessionInputs, read: ReadResult, model: Personalisation, kinematics: Any) -> Loads:
    """The read trial's plates (a C3D's, or its GRF file's) in the model frame (rotated here,
    not kept by the model stage), assigned to the feet."""
    from msk.dynamics.loads import foot_contact
    from msk.kinematics.observation import observed_frames

    rot = model.rotation
    lc = inputs.cfg.loads
    plate_names = [p.name for p in read.plates or ()]
    for key, given in (("surface_height_m", list(lc.surface_height_m)), ("ignore", lc.ignore)):
        unknown = [g for g in given if g not in plate_names]
        if unknown:
            from msk.exceptions import ConfigError

            task = inputs.task.file if inputs.task else "the task"
            raise ConfigError(
                f"[loads] {key}: no plate {unknown[0]!r} in {task} "
                f"(its plates: {', '.join(plate_names) or 'none'})"
            )
    # rotated one at a time, as external_loads resamples them: one analog-rate plate in the
    # model frame is held at a time
    up = -np.asarray(model.model.gravity, dtype=float)
    up = up / np.linalg.norm(up)
    offsets: list[Any] = []
    # a plate left out, a plate's unloaded offset removed (msk.dynamics.plate_surface)
    plates: Iterator[Any] = prepared_plates(
        (rotated_plate(p, rot) for p in read.plates or ()), up, ignore=lc.ignore,
        remove_baseline=lc.remove_baseline, found=offsets,
    )  # fmt: skip
    ext = inputs.external_loads(model.model, read.trial, kinematics, plates, read.assignment)
    ext = dataclasses.replace(ext, metadata={
        **ext.metadata, "plate_offsets": [b.as_dict() for b in offsets],
        "ignored_plates": [p.name for p in read.plates or () if p.name in set(lc.ignore)],
    })  # fmt: skip
    contact = foot_contact(model.model, kinematics, ext)
    # a foot straddling its plate's edge: not measured there (msk.dynamics.plate_footprint)
    # (at the plate's standing surface: a step built on it, msk.dynamics.plate_surface)
    lift = {s["plate"]: s["height_m"] - s["corners_height_m"]
            for s in ext.metadata.get("surfaces", ())}  # fmt: skip
    corners = {p.name: np.asarray(p.corners) @ np.asarray(rot, dtype=float).T
               + lift.get(p.name, 0.0) * up
               for p in read.plates or () if p.corners is not None
               and p.name not in set(lc.ignore)}  # fmt: skip
    contact, ext = exclude_plate_edges(model.model, kinematics, ext, contact, corners)
    # contact_measured's frames (msk.dynamics.loads), from the same per-foot test
    measured = contact.known & ~contact.unmeasured.any(axis=1) & ~ext.flagged()
    obs = observed_frames(model.model, kinematics)
    # every test but the feet's: per leg, only that foot's contact counts (the other foot may
    # stand off the plates: its reaction does not enter this leg's torques)
    body = (
        np.isfinite(kinematics.q).all(axis=1)
        & np.isfinite(kinematics.a).all(axis=1)
        & contact.known
        & ~ext.flagged()
        & obs.observed
    )
    usable = body & ~contact.unmeasured.any(axis=1)
    legs = body[:, None] & ~contact.unmeasured
    out = Loads(ext, measured, usable, obs, contact, legs)
    names = tuple(model.model.coordinate_names)
    from msk.dynamics.plate_contact import dead_plates

    # a plate under a standing foot that reads nothing (one rotated plate at a time again)
    dead = dead_plates(
        model.model, kinematics, contact,
        (rotated_plate(p, rot) for p in read.plates or () if p.name not in set(lc.ignore)),
    )  # fmt: skip
    return dataclasses.replace(
        out,
        unbalanced=unbalanced_coordinates(model.model, out, names),
        coordinate_names=names,
        dead_plates=tuple(dead),
    )


def unbalanced_coordinates(model: Any, loads: Loads, coordinate_names: Any) -> np.ndarray:
    """(N, len(coordinate_names)) the coordinates whose torque would balance a missing ground
    reaction on the :attr:`Loads.solvable` frames: those between a foot whose leg is not
    solvable there (``loads.legs``) and the root
    (:func:`msk.dynamics.inverse.coordinates_carrying`).
    All False without ``legs``."""
    from msk.dynamics.inverse import coordinates_carrying

    names = list(coordinate_names)
    out = np.zeros((loads.usable.shape[0], len(names)), dtype=bool)
    if loads.legs is None or loads.contact is None:
        return out
    solvable = loads.solvable
    for k, foot in enumerate(loads.contact.feet):
        off = solvable & ~loads.legs[:, k]
        if not off.any():
            continue
        cols = [names.index(c) for c in coordinates_carrying(model, foot) if c in names]
        out[np.ix_(off, np.asarray(cols, dtype=int))] = True
    return out
