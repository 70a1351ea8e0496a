"""Stage ``read``: the task trial (C3D, or OpenSim TRC + GRF), its explicit plate assignment
and the measured knee contact force, read from the files (lab frame, SI) and kept as the later
stages read them: the markers, the analog channels that are not plate channels (the EMG), the
plates' force, COP and free moment (:class:`msk.dynamics.loads.PlateWrench`), no model outputs. A
long trial thus holds ~4.9 kB per frame after this stage instead of ~7.1 kB (gc5_PS: 16 EMG
and 3 plates)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from msk.exceptions import MissingDataError
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.records import ReadResult

__all__ = [
    "for_session",
    "measured_contact",
    "read_task",
    "run",
    "settings",
    "without_markers",
    "without_plates",
]


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
    """The task's files as the stages read them (:func:`for_session` of :func:`read_task`)."""
    return for_session(inputs, read_task(inputs))


def for_session(inputs: SessionInputs, read: ReadResult) -> ReadResult:
    """``read`` (as :func:`read_task` returns it) reduced to what the later stages read: the
    plates as :class:`msk.dynamics.loads.PlateWrench` (a C3D's: force, COP and free moment shared
    with
    its :class:`msk.trial.ForcePlate`, not copied; the moment about the plate origin, which no
    stage reads, left out), the analog channels of no plate (the EMG: ``[emg] channels`` may
    name any of them), the markers (shared); no model outputs (no stage reads them)."""
    from msk.dynamics.loads import plates_from_trial
    from msk.trial import ModelOutputs

    trial = read.trial
    plates = read.plates if read.plates is not None else plates_from_trial(trial)
    plate_channels = {c for p in trial.plates for c in p.channels}
    keep = [i for i, lab in enumerate(trial.analog_labels) if lab not in plate_channels]
    analogs = trial.analogs  # (a C3D read for the session: the stored samples, not scaled)
    if np.ndim(analogs) == 2 and keep != list(range(np.shape(analogs)[1])):
        analogs = np.ascontiguousarray(analogs[:, keep])  # (a C3D read for the session: none)
    light = dataclasses.replace(
        trial,
        plates=(),
        analogs=analogs,
        analog_labels=tuple(trial.analog_labels[i] for i in keep),
        analog_units=tuple(trial.analog_units[i] for i in keep),
        model_outputs=ModelOutputs((), (), (), np.zeros((trial.time.size, 0, 3))),
    )
    return ReadResult(light, tuple(plates), read.assignment, read.contact)


def without_markers(read: ReadResult) -> ReadResult:
    """``read`` without the task's markers (a ``(N, 0, 3)`` array, no labels): the model stage
    is the last to read them (its :class:`~msk.personalise.Personalisation` holds them in the
    model frame); :func:`msk.pipeline.graph.run_graph` drops them from ``read`` after it, so
    that a long trial's markers are not held twice through the loads and EMG stages.
    Time, rates, analogs and the plates are shared, not copied."""
    trial = read.trial
    n = int(np.shape(trial.markers)[0])
    empty = np.zeros((n, 0, 3))
    light = dataclasses.replace(trial, markers=empty, marker_labels=())
    return dataclasses.replace(read, trial=light)


def without_plates(read: ReadResult) -> ReadResult:
    """``read`` without its plates (``plates=()``): the loads stage is the last to read them;
    :func:`msk.pipeline.graph.run_graph` drops them after it (their analog-rate force, COP and
    free moment are the largest part of a long trial's read result). The assignment,
    the measured contact and the trial (its EMG channels) are kept."""
    return dataclasses.replace(read, plates=())


def _with_up_of(trial: Any, grf: tuple[Any, ...]) -> Any:
    """A marker file without a vertical (a TRC, read as OpenSim's +y up) given the up of its
    GRF file's lab (:func:`msk.io.frames.up_from_ground_reactions`) where the two differ: a
    C3D lab's markers written by OpenSim's ``C3DFileAdapter`` unrotated (+z up) with its
    plates."""
    from msk.io.frames import up_from_ground_reactions

    up = up_from_ground_reactions(trial.markers, [p.force for p in grf], [p.cop for p in grf])
    if up is None or np.allclose(up, trial.up):
        return trial
    return dataclasses.replace(trial, up=up, vertical_axis=int(np.argmax(np.abs(up))))


def read_task(inputs: SessionInputs) -> ReadResult:
    """The task trial, its GRF file's plates, assignment and measured contact as read."""
    from msk.io import read_c3d, read_trial

    task = inputs.task
    assert task is not None  # a gait stage
    if Path(task.file).suffix.lower() == ".c3d":
        # the plates' channels are not kept (no stage reads them; a long trial's largest array)
        trial = read_c3d(task.file, plate_channels=False, stored_analogs=True)
    else:
        trial = read_trial(task.file)  # by suffix (a .trc: OpenSim ground, +y up)
    grf, assignment = None, {}
    if task.grf is not None:
        from msk.dynamics.loads import external_loads_assignment, plates_from_grf_file

        # every common OpenSim column naming; with an ExternalLoads .xml, its force sets
        grf = tuple(plates_from_grf_file(task.grf, task.external_loads))
        if Path(task.file).suffix.lower() != ".c3d":
            trial = _with_up_of(trial, grf)
        if task.external_loads is not None:
            assignment = dict(external_loads_assignment(task.external_loads, task.grf))
    contact = None
    if task.contact_force is not None:
        contact = _read_contact(task.contact_force, task.file, task.grf)
    return ReadResult(trial, grf, assignment, contact)


def measured_contact(inputs: SessionInputs, read: ReadResult) -> Any:
    """Step ``measured_contact`` (not a recorded stage): the measured knee contact force of
    ``read`` alone, so that the stages after the loads and EMG do not read ``read`` and its
    analog-rate arrays are released early (:func:`msk.pipeline.graph.run_graph`)."""
    return read.contact
