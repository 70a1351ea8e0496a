"""Stage ``loads``: the ground reactions assigned to the feet (:func:`msk.loads.external_loads`)
and the frames whose ground contact the plates measure (:func:`msk.loads.contact_measured`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from msk.pipeline.inputs import SessionInputs
from msk.pipeline.model import BuiltModel
from msk.pipeline.read import ReadResult

__all__ = [
    "OBSERVATION",
    "PLATE_ASSIGNMENT",
    "Loads",
    "assign_loads",
    "grf_cutoff_hz",
    "rotated_plate",
    "run",
    "settings",
    "unbalanced_coordinates",
]

#: How msk.loads assigns plate contacts to feet (recorded in summary.json, part of the cache key).
PLATE_ASSIGNMENT = (
    "msk.loads: the foot standing on the plate (inside the outline, near the floor, not "
    "swinging over it; none while the still foot nearest the COP is posed off the surface)"
)


@dataclass(frozen=True)
class Loads:
    """``external``: :class:`msk.loads.ExternalLoads`; ``measured``: (N,) frames whose every
    foot on the floor stands on a plate (a walkway's steps before and after the plates miss a
    ground reaction: no residual or identification equation comes from them; a leg whose own
    foot is measured there is still solved, ``legs``);
    ``observation``: :class:`msk.observation.Observation`, the frames whose leg segments the
    markers observe (a segment out of the capture volume or a marker dropping out: its pose,
    hence q̈, is guessed there); ``usable``: measured and observed frames with finite q and q̈
    — the frames the whole-body figures and fits use; ``contact``:
    :class:`msk.loads.FootContact`, which foot stands on an unmeasured surface in which frame
    (its leg's joint torques are not written there: :func:`msk.pipeline.dynamics.run`);
    ``legs``: (N, F) the frames in which the leg of foot k of ``contact.feet`` can be solved on
    its own — observed and known with finite q and q̈, no plate load flagged, and THAT foot
    measured or off the floor, whatever the other feet stand on (RNEA's torque at a joint
    balances its distal subtree, Featherstone 2008 §5.3: a missing reaction under the other
    foot does not enter this leg's torques). The stages that work leg by leg (muscle tensions,
    knee contact, strength identification) use these frames (:attr:`solvable`,
    ``unbalanced``); the whole-body ones (residuals, mass identification, plate-mass check,
    gait events) ``usable``. ``unbalanced`` (N, len(``coordinate_names``)), computed here
    once (:func:`unbalanced_coordinates`) and read by the tension and knee contact stages
    (:meth:`unbalanced_for`): per :attr:`solvable` frame the coordinates between a foot whose
    leg is not solvable there and the root."""

    external: Any
    measured: np.ndarray
    usable: np.ndarray
    observation: Any = None
    contact: Any = None
    legs: np.ndarray | None = None
    unbalanced: np.ndarray | None = None
    coordinate_names: tuple[str, ...] = ()
    #: plates that read nothing while a foot stands on them (:func:`msk.plate_contact.dead_plates`)
    dead_plates: tuple[Any, ...] = ()

    def unbalanced_for(self, coordinate_names: Any) -> np.ndarray:
        """``unbalanced`` in the columns ``coordinate_names`` (e.g. the joint torques'): a
        coordinate this result does not name is never unbalanced (all False without
        ``unbalanced``)."""
        names = list(coordinate_names)
        out = np.zeros((self.usable.shape[0], len(names)), dtype=bool)
        if self.unbalanced is None:
            return out
        have = {c: k for k, c in enumerate(self.coordinate_names)}
        for j, c in enumerate(names):
            if c in have:
                out[:, j] = self.unbalanced[:, have[c]]
        return out

    @property
    def solvable(self) -> np.ndarray:
        """(N,) frames in which at least one leg can be solved (``usable`` without ``legs``
        or without feet)."""
        if self.legs is None or self.legs.shape[1] == 0:
            return self.usable
        return self.usable | self.legs.any(axis=1)

    @property
    def measured_observed(self) -> np.ndarray:
        """(N,) measured frames the markers observe (every measured frame without an
        ``observation``)."""
        if self.observation is None:
            return self.measured
        return self.measured & self.observation.observed


#: Which frames the dynamics-based figures use (recorded in the cache key).
OBSERVATION = (
    "msk.observation: every leg segment sees min(3, its tracked markers), 1/(4 f_c) from any "
    "frame where one does not or IK did not solve"
)


def assign_loads(
    inputs: SessionInputs,
    model: Any,
    trial: Any,
    kinematics: Any,
    plates: Any = None,
    assignment: Mapping[str, str] | None = None,
) -> Any:
    """:func:`msk.loads.external_loads` of a trial: its plates (a C3D's, or ``plates``), with the
    explicit assignment of the ExternalLoads ``.xml`` then of the config's ``[loads] assign``."""
    from msk.loads import external_loads, plates_from_trial

    plates = plates_from_trial(trial) if plates is None else plates
    assign = {**(assignment or {}), **inputs.cfg.loads.assign} or None
    return external_loads(
        model, kinematics, plates, assignment=assign, cutoff_hz=grf_cutoff_hz(inputs.cfg)
    )


def grf_cutoff_hz(cfg: Any) -> float:
    """The ground reactions' low-pass cut-off: ``[filters] grf_cutoff_hz``, absent: the
    kinematics' (Kristianslund et al. 2012: the same cut-off on both)."""
    f = cfg.filters
    return float(f.kinematics_cutoff_hz if f.grf_cutoff_hz is None else f.grf_cutoff_hz)


def settings(inputs: SessionInputs) -> Any:
    return {
        "cut": grf_cutoff_hz(inputs.cfg),
        "assignment": PLATE_ASSIGNMENT,
        "assign": dict(inputs.cfg.loads.assign),
        "observed": OBSERVATION,
    }


def rotated_plate(plate: Any, rot: np.ndarray) -> Any:
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


def run(inputs: SessionInputs, read: ReadResult, model: BuiltModel, kinematics: Any) -> Loads:
    """The read trial's plates (a C3D's, or its GRF file's) in the model frame (rotated here,
    not kept by the model stage), assigned to the feet."""
    from msk.loads import foot_contact
    from msk.observation import observed_frames

    rot = model.rotation
    # rotated one at a time, as external_loads resamples them: one analog-rate plate in the
    # model frame is held at a time (issue 18)
    plates: Iterator[Any] = (rotated_plate(p, rot) for p in read.plates or ())
    ext = assign_loads(inputs, model.model, read.trial, kinematics, plates, read.assignment)
    contact = foot_contact(model.model, kinematics, ext)
    # contact_measured's frames (msk.loads), from the same per-foot test
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
    from msk.plate_contact import dead_plates

    # a plate under a standing foot that reads nothing (one rotated plate at a time again)
    dead = dead_plates(
        model.model, kinematics, contact, (rotated_plate(p, rot) for p in read.plates or ())
    )
    return dataclasses.replace(
        out,
        unbalanced=unbalanced_coordinates(model.model, out, names),
        coordinate_names=names,
        dead_plates=tuple(dead),
    )


def unbalanced_coordinates(model: Any, loads: Loads, coordinate_names: Any) -> np.ndarray:
    """(N, len(coordinate_names)) the coordinates whose torque would balance a missing ground
    reaction on the :attr:`Loads.solvable` frames: those between a foot whose leg is not
    solvable there (``loads.legs``) and the root (:func:`msk.dynamics.coordinates_carrying`).
    All False without ``legs``."""
    from msk.dynamics import coordinates_carrying

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
