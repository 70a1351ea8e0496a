"""Muscle paths and parameters as data (what importers produce and geometry consumes).

Locations are in the frame of the body they are fixed to (m). Coordinate names refer to the
model's independent coordinates. These are plain frozen records: the geometry (lengths,
Jacobians, wrapping) lives in :mod:`msk.muscles.geometry`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from msk.model.joints import CoordinateFunction
from msk.units import Array

__all__ = [
    "ConditionalPathPoint",
    "MovingPathPoint",
    "Muscle",
    "PathPoint",
    "PathWrap",
    "WrapObject",
]


@dataclass(frozen=True, eq=False)
class PathPoint:
    """A point fixed in ``body`` (origin, via point or insertion)."""

    name: str
    body: str
    location: Array


@dataclass(frozen=True, eq=False)
class ConditionalPathPoint(PathPoint):
    """A via point active only while ``coordinate`` lies in ``[range[0], range[1]]``
    (OpenSim ``ConditionalPathPoint``)."""

    coordinate: str = ""
    range: tuple[float, float] = (-np.inf, np.inf)


@dataclass(frozen=True, eq=False)
class MovingPathPoint(PathPoint):
    """A point whose location in ``body`` is a function of coordinates, one function per axis
    (OpenSim ``MovingPathPoint``: ``x_location``, ``y_location``, ``z_location``).

    ``coordinates[k]`` is the coordinate driving axis k, or ``None`` when the axis is fixed at
    ``location[k]``.
    """

    coordinates: tuple[str | None, str | None, str | None] = (None, None, None)
    functions: tuple[CoordinateFunction | None, ...] = (None, None, None)


@dataclass(frozen=True, eq=False)
class WrapObject:
    """A wrapping surface fixed in ``body``: placement (translation m, body-fixed XYZ rotation
    rad as OpenSim's ``xyz_body_rotation``) and its shape parameters."""

    name: str
    body: str
    kind: str  # "cylinder", "ellipsoid", "sphere", "torus"
    translation: Array
    xyz_body_rotation: Array
    radius: float = 0.0
    length: float = 0.0
    dimensions: Array = field(default_factory=lambda: np.zeros(3))  # ellipsoid radii
    quadrant: str = "all"  # "all", "+x", "-x", "+y", "-y", "+z", "-z"
    active: bool = True


@dataclass(frozen=True, eq=False)
class PathWrap:
    """A muscle's use of a wrap object, between path points ``range`` (1-based, OpenSim;
    (-1, -1) = whole path)."""

    wrap_object: str
    method: str = "hybrid"
    range: tuple[int, int] = (-1, -1)


@dataclass(frozen=True, eq=False)
class Muscle:
    """A muscle–tendon unit: path, wraps and Hill parameters (SI).

    ``max_isometric_force`` F_iso (N), ``optimal_fiber_length`` l_opt (m),
    ``tendon_slack_length`` l_ts (m), ``pennation_angle`` α_opt (rad) at optimal fibre length,
    ``max_contraction_velocity`` in l_opt/s, ``kind`` the source class (e.g. Thelen2003Muscle).
    """

    name: str
    points: tuple[PathPoint, ...]
    max_isometric_force: float
    optimal_fiber_length: float
    tendon_slack_length: float
    pennation_angle: float = 0.0
    max_contraction_velocity: float = 10.0
    wraps: tuple[PathWrap, ...] = ()
    kind: str = "Muscle"
    extra: dict = field(default_factory=dict)  # other source-specific parameters, as given
