"""A static trial as marker placement reads it: its markers in the model frame, its subject's
measured widths and its still, double-stance window.

The window is judged on the markers the model uses (:func:`judged_markers`): a subject who
moves the arms, scratches the head or turns it while the legs and the pelvis stand still gives
a static the model can use, and its arm markers (which no model segment carries) must not
refuse it."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from msk.personalise.static_window import StillWindow
from msk.trial import Subject

__all__ = ["StaticTrial", "judged_markers", "read_static_trial"]


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
    #: measured markers the still window did not judge (on no segment of the model)
    not_judged: tuple[str, ...] = ()


def judged_markers(
    labels: Sequence[str],
    model: Any | None = None,
    rename: Mapping[str, str] | None = None,
) -> tuple[str, ...]:
    """The labels whose stillness the static's window is judged on: the measured markers
    (:func:`msk.io.c3d.is_measured_marker`), less — when ``model`` is given — those the
    model does not use: the markers :func:`msk.model.markersets.recognise` excludes for
    ``model`` (arm and head markers of a model without those segments, a patella marker
    without a patella) and the shoulder girdle's on a model without it
    (:func:`msk.model.markersets.shoulder_girdle_markers`)."""
    from msk.io.c3d import is_measured_marker

    measured = [lab for lab in labels if is_measured_marker(lab)]
    if model is None:
        return tuple(measured)
    from msk.model.markersets import recognise, shoulder_girdle_markers

    bodies = [b.name for b in model.bodies]
    match = recognise(labels, model.marker_names, rename=rename, model_bodies=bodies)
    off = {*match.excluded, *shoulder_girdle_markers(list(labels), bodies)}
    off -= set(match.rename.values())  # a marker the model pairs is used, whatever its name
    return tuple(lab for lab in measured if lab not in off)


def read_static_trial(
    path: Path,
    up: NDArray[np.float64],
    *,
    model: Any | None = None,
    rename: Mapping[str, str] | None = None,
) -> StaticTrial:
    """Markers of a static trial in the model frame (any format :func:`msk.io.read_trial`
    reads, rotated so that its vertical is the model's ``up``), the file's subject and its
    still double-stance window (:func:`msk.personalise.static_window.still_window` on the
    markers :func:`judged_markers` keeps for ``model`` (with the configuration's ``rename``;
    no model: every measured marker) and, where the file has plates, their vertical loads at
    the marker frames).

    Raises:
        StaticTrialError: the static has no still window (the message names the file).
    """
    from msk.exceptions import StaticTrialError
    from msk.io import read_trial, to_model_frame
    from msk.io.c3d import is_measured_marker
    from msk.model.markersets import zeros_as_gaps
    from msk.personalise.static_window import still_window

    tr = to_model_frame(read_trial(path), up=up, forward=None)
    judged = set(judged_markers(tr.marker_labels, model, rename))
    keep = [i for i, lab in enumerate(tr.marker_labels) if lab in judged]
    not_judged = tuple(
        lab for lab in tr.marker_labels if is_measured_marker(lab) and lab not in judged
    )
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
    return StaticTrial(
        tr.markers, tr.marker_labels, tr.time, tr.subject, window, path.name, not_judged
    )
