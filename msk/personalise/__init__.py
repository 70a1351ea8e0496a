"""A generic model made the subject's: scaling from a static trial, marker placement (static or from
the motion, chosen among candidates), the static trial's still window, functional joint centres,
the femur:tibia split, and what the markers leave undetermined (determinacy, the sole-level
prior); :func:`personalise` does it all and returns one :class:`Personalisation`."""

from msk.personalise.options import KneeAlignmentOptions, MarkerOptions, PersonaliseOptions
from msk.personalise.personalise import Personalisation, personalise
from msk.personalise.static_trial import StaticTrial, read_static_trial

__all__ = [
    "KneeAlignmentOptions",
    "MarkerOptions",
    "Personalisation",
    "PersonaliseOptions",
    "StaticTrial",
    "personalise",
    "read_static_trial",
]
