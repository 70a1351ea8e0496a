"""The options of :func:`msk.personalise.personalise`: what the session's configuration says about
the subject, the model's scaling and knee alignment, and the lab's markers."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal

__all__ = ["KneeAlignmentOptions", "MarkerOptions", "PersonaliseOptions"]


@dataclass(frozen=True, kw_only=True)
class KneeAlignmentOptions:
    """The frontal alignment of the side of interest's knee (:mod:`msk.model.alignment`):
    ``source`` ``"given"`` (``varus_deg``, ``medial_shift_m``; both 0: the generic model's) or
    ``"from_markers"`` (estimated from the static trial's, else the task's, epicondyle and
    malleolus markers; then both given values must be 0)."""

    source: Literal["given", "from_markers"] = "given"
    varus_deg: float = 0.0
    medial_shift_m: float = 0.0


@dataclass(frozen=True, kw_only=True)
class MarkerOptions:
    """The lab's markers: model marker name → lab label (``rename``), IK weight by model marker
    name (``weights``, absent: 1), model markers moved to where the trial puts them on their
    body (``move``, technical clusters), virtual markers made from the measured ones
    (``virtual``)."""

    rename: Mapping[str, str] = field(default_factory=dict)
    weights: Mapping[str, float] = field(default_factory=dict)
    move: tuple[str, ...] = ()
    #: virtual markers, name → definition (:mod:`msk.personalise.virtual_markers`)
    virtual: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True, kw_only=True)
class PersonaliseOptions:
    """What :func:`msk.personalise.personalise` does: the subject (``mass_kg``, ``height_m``
    — None: unknown —, the ``side`` of interest, ``"left"`` or ``"right"``), whether the model
    is scaled (``scale``), where the hip joint centres go (``hip_centre``: the model's own,
    or a regression from the static trial's pelvis markers, :mod:`msk.personalise.hip_centre`),
    the knee's alignment, the lab's markers, the model file's name
    reported as the source (``source``) and the prefix of configuration errors (``origin``:
    the configuration file)."""

    mass_kg: float
    height_m: float | None = None
    side: str = "right"
    scale: bool = True
    hip_centre: str = "model"
    knee_alignment: KneeAlignmentOptions = field(default_factory=KneeAlignmentOptions)
    markers: MarkerOptions = field(default_factory=MarkerOptions)
    source: str = ""
    origin: str = "personalise"

    @property
    def sfx(self) -> str:
        """Coordinate/body suffix of the side of interest (``_r`` or ``_l``)."""
        return "_l" if self.side == "left" else "_r"
