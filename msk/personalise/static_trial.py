"""A static trial as marker placement reads it: its markers in the model frame, its subject's
measured widths and its still, double-stance window."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from msk.personalise.static_window import StillWindow
from msk.trial import Subject

__all__ = ["StaticTrial", "read_static_trial"]


@dataclass(frozen=True)
class StaticTrial:
    """A static trial's markers ``(N, M, 3)`` m in the model frame (vertical rotated to the
    model's up; no heading: the subject stands still) with their ``labels`` and ``time`` (the
    whole trial's), the file's :class:`msk.trial.Subject` (None when it has none), the part
    that is still in double stance (``window``) and the file's ``name`` (messages)."""

    markers: NDArray[np.float64]
    labels: tuple[str, ...]
    time: NDArray[np.float64]
    subject: Subject | None
    window: StillWindow
    name: str


def read_static_trial(path: Path, up: NDArray[np.float64]) -> StaticTrial:
    """Markers of a static trial in the model frame (any format :func:`msk.io.read_trial`
    reads, rotated so that its vertical is the model's ``up``), the file's subject and its
    still double-stance window (:func:`msk.personalise.static_window.still_window` on its
    measured markers and, where the file has plates, their vertical loads at the marker frames).

    Raises:
        StaticTrialError: the static has no still window (the message names the file).
    """
    from msk.exceptions import StaticTrialError
    from msk.io import read_trial, to_model_frame
    from msk.io.c3d import is_measured_marker
    from msk.model.markersets import zeros_as_gaps
    from msk.personalise.static_window import still_window

    tr = to_model_frame(read_trial(path), up=up, forward=None)
    keep = [i for i, lab in enumerate(tr.marker_labels) if is_measured_marker(lab)]
    loads = None
    if tr.plates and np.size(tr.analog_time):
        u = np.asarray(up, dtype=float)
        loads = np.stack(
            [np.interp(tr.time, tr.analog_time, np.asarray(p.force, float) @ u) for p in tr.plates],
            axis=1,
        )
    try:
        window = still_window(zeros_as_gaps(tr.markers)[:, keep], tr.time, plate_loads=loads)
    except StaticTrialError as exc:
        raise StaticTrialError(f"{path.name}: {exc}") from None
    return StaticTrial(tr.markers, tr.marker_labels, tr.time, tr.subject, window, path.name)
