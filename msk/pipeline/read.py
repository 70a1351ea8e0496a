"""Stage ``read``: the task trial (C3D, or OpenSim TRC + GRF), its explicit plate assignment
and the measured knee contact force, as read from the files (lab frame, SI)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from msk.exceptions import MissingDataError
from msk.pipeline.inputs import SessionInputs

__all__ = ["ReadResult", "read_static_markers", "run", "settings"]


@dataclass(frozen=True)
class ReadResult:
    """The task trial (:class:`msk.io.Trial`), the plates of its GRF file (``grf``, lab frame;
    None for a C3D's own plates), the ExternalLoads assignment plate → body, and the measured
    knee contact force (:class:`msk.io.contact_force.MeasuredContact`)."""

    trial: Any
    grf: tuple[Any, ...] | None = None
    assignment: Mapping[str, str] = field(default_factory=dict)
    contact: Any = None


def _read_contact(path: Path, trial: Path, grf: Path | None) -> Any:
    """Measured knee contact force (:func:`msk.io.contact_force.read_measured_contact`): a CSV
    with a time column or cycle-normalised (Grand Challenge eTibia), or a Grand Challenge DM
    ``.mat`` aligned to the task trial by its markers."""
    from msk.io.contact_force import read_measured_contact

    mat = path.suffix.lower() == ".mat"
    mc = read_measured_contact(path, trial=trial if mat else None, grf=grf if mat else None)
    if mc.n_frames < 2:
        raise MissingDataError(f"{path}: no contact-force samples")
    return mc


def settings(inputs: SessionInputs) -> Any:
    return {"files": dict(inputs.hashes)}


def run(inputs: SessionInputs) -> ReadResult:
    from msk.io import read_trial

    task = inputs.task
    assert task is not None  # a gait stage
    trial = read_trial(task.file)  # by suffix (a .trc: OpenSim ground, +y up)
    grf, assignment = None, {}
    if task.grf is not None:
        from msk.loads import external_loads_assignment, plates_from_grf_file

        # every common OpenSim column naming; with an ExternalLoads .xml, its force sets
        grf = tuple(plates_from_grf_file(task.grf, task.external_loads))
        if task.external_loads is not None:
            assignment = dict(external_loads_assignment(task.external_loads, task.grf))
    contact = None
    if task.contact_force is not None:
        contact = _read_contact(task.contact_force, task.file, task.grf)
    return ReadResult(trial, grf, assignment, contact)


def read_static_markers(
    path: Path, up: np.ndarray
) -> tuple[np.ndarray, tuple[str, ...], np.ndarray, Any]:
    """Markers of a static trial in the model frame (any format :func:`msk.io.read_trial`
    reads, rotated so that its vertical is the model's ``up``; no heading: the subject stands
    still) and the file's :class:`msk.trial.Subject`."""
    from msk.io import read_trial, to_model_frame

    tr = to_model_frame(read_trial(path), up=up, forward=None)
    return tr.markers, tr.marker_labels, tr.time, tr.subject
