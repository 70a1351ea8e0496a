"""A motion trial in SI units: markers, model outputs, analogs, force platforms, events, subject.

The type every trial reader returns (:func:`msk.io.read_trial`: C3D via
:func:`msk.io.read_c3d`, OpenSim ``.trc`` via :func:`msk.io.read_trc_trial`) and every stage
consumes, with its companion records: :class:`ForcePlate`, :class:`Event`, :class:`Subject`,
:class:`GapReport`, :class:`ModelOutputs`. Time is axis 0 of every array; positions m, forces N,
moments N·m, time s, angles rad, mass kg, height m.

Rotating a trial about the lab origin (:meth:`Trial.rotated`, :meth:`ForcePlate.rotated`) maps a
point ``p`` to ``R p`` and a free vector (force, moment) ``v`` to ``R v``; so a plate moment about
its origin ``o`` stays the moment about the rotated origin ``R o``:
``R (M_o) = R ((c − o) × F + T) = (R c − R o) × R F + R T``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import MissingDataError, ShapeMismatchError
from msk.signal import block_average, resample_to

if TYPE_CHECKING:
    from msk.analogs import StoredAnalogs

__all__ = ["Event", "ForcePlate", "GapReport", "ModelOutputs", "Subject", "Trial"]


def _check_rotation(r: ArrayLike, what: str) -> NDArray[np.float64]:
    r = np.asarray(r, dtype=float)
    if r.shape != (3, 3):
        raise ShapeMismatchError(f"{what}: rotation has shape {r.shape}, expected (3, 3)")
    if not np.allclose(r @ r.T, np.eye(3), atol=1e-9) or np.linalg.det(r) < 0:
        raise ShapeMismatchError(
            f"{what}: not a proper rotation matrix (det {np.linalg.det(r):.6g})"
        )
    return r


def _longest_runs(missing: NDArray[np.bool_]) -> NDArray[np.int64]:
    """Longest run of True along axis 0 for each column, vectorised."""
    n, m = missing.shape
    if n == 0 or m == 0:
        return np.zeros(m, dtype=np.int64)
    pad = np.zeros((1, m), dtype=np.int8)
    d = np.diff(np.vstack([pad, missing.astype(np.int8), pad]), axis=0)
    starts_r, starts_c = np.nonzero(d == 1)
    ends_r, ends_c = np.nonzero(d == -1)
    # np.nonzero is row-major: reorder by column so starts and ends pair up
    o1 = np.lexsort((starts_r, starts_c))
    o2 = np.lexsort((ends_r, ends_c))
    lengths = ends_r[o2] - starts_r[o1]
    out = np.zeros(m, dtype=np.int64)
    np.maximum.at(out, starts_c[o1], lengths)
    return out


@dataclass(frozen=True)
class ForcePlate:
    """One force platform, at the analog rate, in the lab frame (SI).

    ``force`` is the ground reaction on the subject (upward when loaded), ``(Na, 3)`` N;
    ``moment`` is about ``origin``, the centre of the working surface (mean of the corners);
    ``cop`` is NaN where the plate-normal force is below the threshold; ``free_moment`` is the
    moment about the COP (along the plate normal), zero where the plate is unloaded.
    """

    index: int
    type: int
    force: NDArray[np.float64]
    moment: NDArray[np.float64]
    cop: NDArray[np.float64]
    free_moment: NDArray[np.float64]
    corners: NDArray[np.float64]
    origin: NDArray[np.float64]
    rotation: NDArray[np.float64]
    channels: tuple[str, ...]
    rate_hz: float

    @property
    def normal(self) -> NDArray[np.float64]:
        """Unit plate z axis in the lab (C3D plates usually point it down, into the plate)."""
        return self.rotation[:, 2]

    @property
    def peak_force_n(self) -> float:
        """Largest |F| over the trial (NaN samples ignored); 0 for an all-NaN plate."""
        norm = np.linalg.norm(self.force, axis=1)
        return float(np.nanmax(norm)) if np.isfinite(norm).any() else 0.0

    def rotated(self, rotation: ArrayLike) -> ForcePlate:
        """This plate in the rotated frame (``x_new = R x``): force, moment (about the rotated
        origin), COP, free moment, corners and origin rotated; the plate axes become
        ``R @ axes``."""
        r = _check_rotation(rotation, f"force plate {self.index + 1}")
        return dataclasses.replace(
            self,
            force=self.force @ r.T,
            moment=self.moment @ r.T,
            cop=self.cop @ r.T,
            free_moment=self.free_moment @ r.T,
            corners=self.corners @ r.T,
            origin=np.asarray(self.origin, dtype=float) @ r.T,
            rotation=r @ self.rotation,
        )


@dataclass(frozen=True)
class Event:
    """A labelled instant: ``context`` is usually Left/Right/General."""

    label: str
    context: str
    time: float


@dataclass(frozen=True)
class Subject:
    """Subject metadata found in the file (``None`` where absent).

    Mass from ``PROCESSING:Bodymass`` (Vicon), ``SUBJECTS``/``SUBJECT`` ``WEIGHT``/``MASS``;
    height from ``Height``/``HEIGHT``: a value above 3 is taken as mm (Vicon stores 1680),
    otherwise as m (older files store 1.63 even when the description says mm).
    ``widths_m``: the lab's anthropometric measurements of the joints, ``"R.knee"``,
    ``"L.ankle"``… (Vicon ``PROCESSING:RKneeWidth``, ``LAnkleWidth``; mm in the file), and
    ``marker_diameter_m`` (``PROCESSING:MarkerDiameter``; None when absent): what Plug-in Gait
    places its knee and ankle centres from (Davis et al. 1991). ``leg_lengths_m`` (``"R"``/``"L"``:
    ``PROCESSING:RLegLength``…, ASIS to medial malleolus measured on the subject),
    ``asis_trochanter_m`` (``RAsisTrocanterDistance``…) and ``inter_asis_m``
    (``InterAsisDistance``): what Plug-in Gait places its hip centres from (Davis et al. 1991);
    empty / None where absent or zero (Plug-in Gait's "not measured").
    """

    name: str | None = None
    mass_kg: float | None = None
    height_m: float | None = None
    widths_m: Mapping[str, float] = field(default_factory=dict)
    marker_diameter_m: float | None = None
    leg_lengths_m: Mapping[str, float] = field(default_factory=dict)
    asis_trochanter_m: Mapping[str, float] = field(default_factory=dict)
    inter_asis_m: float | None = None


@dataclass(frozen=True)
class GapReport:
    """Per marker: number of missing frames and the longest run of consecutive missing frames."""

    labels: tuple[str, ...]
    n_missing: NDArray[np.int64]
    longest_gap: NDArray[np.int64]

    @classmethod
    def from_missing(cls, labels: tuple[str, ...], missing: NDArray[np.bool_]) -> GapReport:
        """The report of a ``(N, M)`` missing-sample mask (column ``k`` = marker ``labels[k]``)."""
        return cls(
            labels=labels,
            n_missing=missing.sum(axis=0).astype(np.int64),
            longest_gap=_longest_runs(missing),
        )

    def with_gaps(self) -> tuple[str, ...]:
        """Labels of the markers that miss at least one frame."""
        return tuple(lab for lab, n in zip(self.labels, self.n_missing) if n > 0)


@dataclass(frozen=True)
class ModelOutputs:
    """Points that are model outputs (joint angles, forces, moments, powers), kept apart.

    ``data`` is ``(N, K, 3)``; angles are converted to rad and moments from N·mm to N·m (a
    Plug-in Gait moment normalised by body mass stays per kg); ``kinds[k]`` names the group
    (ANGLES, FORCES, MOMENTS, POWERS, REACTIONS) and ``units[k]`` the SI unit after conversion.
    """

    labels: tuple[str, ...]
    kinds: tuple[str, ...]
    units: tuple[str, ...]
    data: NDArray[np.float64]

    def get(self, label: str) -> NDArray[np.float64]:
        """``(N, 3)`` series of one output; :class:`MissingDataError` if absent."""
        try:
            return self.data[:, self.labels.index(label)]
        except ValueError:
            raise MissingDataError(f"no model output {label!r} (have {len(self.labels)})") from None


@dataclass(frozen=True)
class Trial:
    """A C3D trial in SI units. Markers ``(N, M, 3)`` m with NaN gaps; analogs ``(Na, C)``."""

    path: Path
    point_rate_hz: float
    time: NDArray[np.float64]
    markers: NDArray[np.float64]
    marker_labels: tuple[str, ...]
    gaps: GapReport
    model_outputs: ModelOutputs
    analog_rate_hz: float
    analog_time: NDArray[np.float64]
    analogs: NDArray[np.float64] | StoredAnalogs
    analog_labels: tuple[str, ...]
    analog_units: tuple[str, ...]
    plates: tuple[ForcePlate, ...]
    events: tuple[Event, ...]
    subject: Subject
    vertical_axis: int
    up: NDArray[np.float64]
    point_units_in_file: str = "m"
    metadata: Mapping[str, Any] = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return int(self.time.size)

    @property
    def duration_s(self) -> float:
        """Recording length ``N / rate`` (points, or analogs when there are no points)."""
        if self.n_frames:
            return self.n_frames / self.point_rate_hz
        return self.analog_time.size / self.analog_rate_hz if self.analog_rate_hz else 0.0

    def marker(self, label: str) -> NDArray[np.float64]:
        """``(N, 3)`` trajectory (m) of one marker; :class:`MissingDataError` if absent."""
        try:
            return self.markers[:, self.marker_labels.index(label)]
        except ValueError:
            raise MissingDataError(f"{self.path}: no marker {label!r}") from None

    def analog(self, label: str) -> NDArray[np.float64]:
        """``(Na,)`` samples of one analog channel (its own units, see ``analog_units``)."""
        try:
            return self.analogs[:, self.analog_labels.index(label)]
        except ValueError:
            raise MissingDataError(f"{self.path}: no analog channel {label!r}") from None

    @property
    def analog_ratio(self) -> float:
        """Analog samples per point frame."""
        return self.analog_rate_hz / self.point_rate_hz if self.point_rate_hz else 1.0

    def to_point_rate(self, x_analog: ArrayLike) -> NDArray[np.float64]:
        """Bring an analog-rate series (time on axis 0) to the point rate.

        Block average over each frame when the ratio is an integer (C3D subframes), otherwise
        linear interpolation onto ``time``.
        """
        x = np.asarray(x_analog, dtype=float)
        ratio = self.analog_ratio
        if abs(ratio - round(ratio)) < 1e-9 and round(ratio) >= 1:
            out = block_average(x, round(ratio))
            return out[: self.n_frames] if self.n_frames else out
        return resample_to(self.analog_time, x, self.time)

    def rotated(self, rotation: ArrayLike) -> Trial:
        """This trial with everything that lives in the lab frame rotated by R (``x_new = R x``,
        about the lab origin): markers, force plates (:meth:`ForcePlate.rotated`) and ``up``;
        ``vertical_axis`` becomes the axis nearest the new up. Model outputs (Plug-in Gait
        angles, forces, moments, powers) are expressed in segment / joint frames, which a
        rotation of the lab does not change, so they are kept.
        ``metadata["lab_to_model_rotation"]`` accumulates R (see
        :func:`msk.io.frames.to_model_frame`)."""
        r = _check_rotation(rotation, str(self.path))
        up = r @ np.asarray(self.up, dtype=float)
        meta = dict(self.metadata)
        prev = np.asarray(meta.get("lab_to_model_rotation", np.eye(3)), dtype=float)
        meta["lab_to_model_rotation"] = r @ prev
        return dataclasses.replace(
            self,
            markers=self.markers @ r.T,
            plates=tuple(p.rotated(r) for p in self.plates),
            up=up,
            vertical_axis=int(np.argmax(np.abs(up))),
            metadata=meta,
        )

    def events_named(self, label: str, context: str | None = None) -> tuple[float, ...]:
        """Times (s) of the events with this label (and context, if given)."""
        return tuple(
            e.time
            for e in self.events
            if e.label == label and (context is None or e.context == context)
        )
