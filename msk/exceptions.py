"""One exception hierarchy for msk.

Every error names what it is about (file, channel, segment, muscle, frame) and the offending
value, so that the CLI can print it on one line and exit with status 2.
"""

from __future__ import annotations

__all__ = [
    "AnthropometryError",
    "BatchError",
    "C3DError",
    "ConfigError",
    "EmgError",
    "FileFormatError",
    "ForcePlateError",
    "IdentificationError",
    "InertiaError",
    "KinematicsError",
    "MissingDataError",
    "ModelError",
    "MskError",
    "MuscleModelError",
    "NotAvailableError",
    "OptimizationError",
    "ShapeMismatchError",
    "StaticTrialError",
    "SummaryError",
    "SummaryKeyError",
    "SummaryVersionError",
    "UnitsError",
]


class MskError(Exception):
    """Base class of every error msk raises on purpose."""


class C3DError(MskError):
    """A C3D file cannot be read or is inconsistent (truncated, corrupt, no points, bad units)."""


class FileFormatError(MskError):
    """A text file (.trc, .mot, .sto, .csv, .toml, .osim) is malformed."""


class MissingDataError(MskError):
    """A channel, marker, coordinate or column that is needed is absent or empty."""


class StaticTrialError(MissingDataError):
    """A static trial has no still part to scale and place the markers from."""


class UnitsError(MskError):
    """A unit string is unknown or inconsistent with the quantity."""


class ForcePlateError(MskError):
    """A force platform is inconsistent or its load cannot be assigned to a foot."""


class ModelError(MskError):
    """A model is invalid or uses a feature msk does not support."""


class KinematicsError(MskError):
    """Inverse kinematics failed (too few markers in a frame, divergence)."""


class OptimizationError(MskError):
    """An optimisation problem is infeasible or a solver failed at a given frame."""


class IdentificationError(MskError):
    """An identification is ill-posed (not exciting enough, singular) or failed."""


class ConfigError(MskError):
    """A session configuration has an unknown key, a missing file or a bad value."""


class ShapeMismatchError(MskError):
    """Arrays that must be compared or combined have incompatible shapes (names both shapes)."""


class AnthropometryError(MskError):
    """Bad input to the anthropometric tables (unknown segment, sex or table; mass, length)."""


class InertiaError(MskError):
    """An inertial-parameter vector or inertia tensor has the wrong shape or is not finite."""


class MuscleModelError(ModelError):
    """A muscle parameter or state is invalid, or a muscle equilibrium failed (names the muscle)."""


class EmgError(MskError):
    """EMG cannot be processed (bad mapping, unusable MVC, bad filter band); names the channel."""


class BatchError(MskError):
    """A batch cannot start (no sessions, Dask scheduler unreachable or not installed)."""


class SummaryError(FileFormatError):
    """A ``summary.json`` does not follow the results contract
    (:class:`msk.results.folder.folder.summary.Summary`):
    a value of the wrong type, or not a session summary. ``key`` names the offending key
    (``strength.groups[2].factor``)."""

    def __init__(self, message: str, *, key: str | None = None) -> None:
        super().__init__(message)
        self.key = key


class SummaryKeyError(SummaryError):
    """A required key of ``summary.json`` is missing (``key`` names it)."""


class SummaryVersionError(SummaryError):
    """A ``summary.json`` has a newer schema version than this msk reads (``key`` = ``format``)."""


class NotAvailableError(MskError):
    """A result the data cannot give (a missing prerequisite: no EMG for an EMG criterion, no
    frame to solve): a pipeline records its stage as ``not available`` with this reason."""
