"""The values the stage graph passes between stages that are compositions of library results
(a trial with its plates, the loads with the frames each leg can be solved in, the gait cycle,
the knee contact variants, the strength profile with its groups, the FES protocol's result).
Stages import these records, never one another."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from msk.contact.blocks import ContactVariant

__all__ = [
    "ContactVariant",
    "FesResult",
    "GaitCycle",
    "KneeContact",
    "Loads",
    "ReadResult",
    "StrengthIdentification",
]


@dataclass(frozen=True)
class ReadResult:
    """The task trial (:class:`msk.io.Trial`), its plates (``plates``), the ExternalLoads
    assignment plate → body, and the measured knee contact force
    (:class:`msk.io.contact_force.MeasuredContact`).

    As :func:`read_task` returns it, ``trial`` is the file's (a C3D's without its plates' analog
    channels) and ``plates`` the
    :class:`msk.dynamics.loads.PlateWrench` of a GRF file (None for a C3D's own plates); as the
    stage
    returns it (:func:`for_session`), ``trial`` has no plates, no plate channels and no model
    outputs, and ``plates`` are the :class:`msk.dynamics.loads.PlateWrench` of either (lab
    frame)."""

    trial: Any
    plates: tuple[Any, ...] | None = None
    assignment: Mapping[str, str] = field(default_factory=dict)
    contact: Any = None


@dataclass(frozen=True)
class Loads:
    """``external``: :class:`msk.dynamics.loads.ExternalLoads`; ``measured``: (N,) frames whose
    every
    foot on the floor stands on a plate (a walkway's steps before and after the plates miss a
    ground reaction: no residual or identification equation comes from them; a leg whose own
    foot is measured there is still solved, ``legs``);
    ``observation``: :class:`msk.kinematics.observation.Observation`, the frames whose leg segments
    the
    markers observe (a segment out of the capture volume or a marker dropping out: its pose,
    hence q̈, is guessed there); ``usable``: measured and observed frames with finite q and q̈
    — the frames the whole-body figures and fits use; ``contact``:
    :class:`msk.dynamics.loads.FootContact`, which foot stands on an unmeasured surface in which
    frame
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
    #: plates that read nothing while a foot stands on them
    #: (:func:`msk.dynamics.plate_contact.dead_plates`)
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


@dataclass(frozen=True)
class GaitCycle:
    """``events`` (:class:`msk.kinematics.events.GaitEvents`: times, sources, notes), the analysed
    side's
    cycle ``(start, end)`` in s (None without two foot strikes) and ``measured_contact``:
    component (total/medial/lateral) → measured force (N) on the kinematics' time base, NaN
    outside the measured cycle (None without a measured force or contact stage)."""

    events: Any
    cycle: tuple[float, float] | None
    measured_contact: Mapping[str, np.ndarray] | None

    def as_list(self) -> Sequence[Any]:
        """The events as ``summary.json`` lists them."""
        return self.events.as_list()


@dataclass(frozen=True)
class KneeContact:
    """Contact of the ``generic`` model (generic strength; the identified inertias, which the
    muscle forces balance) and, with identified strength, of the ``subject_specific`` one; the
    plateau geometry of the split; the measured force (as read)."""

    joint: str
    variants: Mapping[str, ContactVariant]
    plateau: Mapping[str, Any]
    measured: Any = None


@dataclass(frozen=True)
class StrengthIdentification:
    """The :class:`msk.strength.StrengthProfile` (factors × generic, intervals, statuses), the
    muscles of each group, and ``t0`` the start (s) of the data identified from."""

    profile: Any
    groups: Mapping[str, Sequence[str]]
    t0: float
    #: per group not identified, the isometric test that would identify it
    #: (:meth:`msk.strength.TestProtocol.as_dict`; None when no joint action loads the group)
    protocols: Mapping[str, Any] = field(default_factory=dict)
    #: per group whose EMG channel failed a check (left out of the regression): its muscles,
    #: the check's words (``reason``) and the test that would identify it (``protocol``)
    failed: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class FesResult:
    """The :class:`msk.fes.protocol.ProtocolResult` of the session."""

    result: Any
