"""Steps ``opensim_export`` and ``opensim_model`` (not recorded stages): the files an OpenSim
user goes on from, in
the session folder's ``opensim/`` (:mod:`msk.results.folder`):

* ``opensim/markers.trc``: the task trial's markers in the model frame (OpenSim's ground, the
  frame of ``tables/q.mot``), mm, under the model's marker names;
* ``opensim/grf.mot``: the ground reactions msk applied, per body (after the plate
  assignment), force/point/torque in ground (:mod:`msk.io.opensim_export`);
* ``opensim/external_loads.xml``: the ExternalLoads applying ``grf.mot``'s columns to those
  bodies;
* ``opensim/model.osim`` (step ``opensim_model``, :func:`run_model`, after the mass
  identification): the scaled model msk used — bodies with the segment inertias of the
  ``joint_torques`` table, joints, coordinates, placed markers, the muscles with their scaled
  paths and parameters (:mod:`msk.io.osim_writer`). With
  ``tables/q.mot`` these are the inputs of OpenSim's inverse kinematics and dynamics.
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from msk.exceptions import ModelError, MskError
from msk.io.opensim_export import (
    grf_table,
    write_external_loads_xml,
    write_grf_mot,
    write_markers_trc,
)
from msk.io.osim_writer import write_osim
from msk.io.storage_twin import index_ranges
from msk.pipeline.inputs import SessionInputs

__all__ = ["FOLDER", "OpenSimExport", "run", "run_model"]

#: the session folder's sub-folder of OpenSim input files
FOLDER = "opensim"


@dataclass(frozen=True)
class OpenSimExport:
    """The files, written once into a private temporary folder (``staging``, removed with this
    object: a long trial's text is not held in memory to the end of the run), and the record
    for ``summary.json`` ``opensim``. :meth:`write` copies them into a session folder."""

    staging: tempfile.TemporaryDirectory[str]
    files: tuple[str, ...]
    record: Mapping[str, Any] = field(default_factory=dict)

    def write(self, folder: str | Path) -> list[Path]:
        """Copy the files into ``folder/opensim/``; returns their paths."""
        out = Path(folder) / FOLDER
        out.mkdir(parents=True, exist_ok=True)
        return [Path(shutil.copyfile(Path(self.staging.name) / f, out / f)) for f in self.files]


def run(inputs: SessionInputs, model: Any, kinematics: Any, loads: Any) -> OpenSimExport | None:
    """The OpenSim files of the task trial (module docstring); None without a model or loads."""
    if model is None or loads is None:
        return None
    trial = model.trial
    ext = loads.external
    marker_names = tuple(model.labels)
    markers = np.asarray(trial.markers, dtype=float)
    # only bodies that carry a load at some frame (an ExternalForce on a body never loaded
    # would apply zeros)
    loaded = [
        b
        for b, body in enumerate(ext.bodies)
        if np.nan_to_num(np.asarray(ext.force, dtype=float)[:, b]).any()
    ]
    bodies = tuple(ext.bodies[b] for b in loaded)
    table = grf_table(
        ext.time,
        bodies,
        np.asarray(ext.force, dtype=float)[:, loaded],
        np.asarray(ext.moment, dtype=float)[:, loaded],
        np.asarray(ext.point, dtype=float)[:, loaded],
    )
    staging = tempfile.TemporaryDirectory(prefix="msk-opensim-")
    d = Path(staging.name)
    files: list[str] = []
    markers_note = "no markers (the model stage kept none)"
    if markers.ndim == 3 and markers.shape[1] == len(marker_names) and markers.shape[1]:
        try:  # a label a TRC cannot hold (empty, a tab) leaves the markers out, not the run
            write_markers_trc(
                d / "markers.trc", trial.time, markers, marker_names, rate_hz=trial.point_rate_hz
            )
            files.append("markers.trc")
            markers_note = f"{len(marker_names)} markers, mm, model marker names"
        except MskError as exc:
            markers_note = f"not written: {exc}"
    _, written = write_grf_mot(d / "grf.mot", table)
    write_external_loads_xml(d / "external_loads.xml", "grf.mot", bodies)
    files += ["grf.mot", "external_loads.xml"]
    kept = np.isin(table.time, written.time)
    record = {
        "folder": FOLDER,
        "files": [f"{FOLDER}/{f}" for f in files],
        "markers": markers_note,
        "frame": "model (OpenSim ground): the frame of tables/q.mot",
        "external_loads": [
            {
                "name": f"{b}_ground_reaction",
                "applied_to_body": b,
                "force_identifier": f"{b}_force_v",
            }
            for b in bodies
        ],
        "grf_rows": int(written.time.size),
        "grf_rows_left_out": index_ranges(np.flatnonzero(~kept)) or None,
        "coordinates": "tables/q.mot",
    }
    return OpenSimExport(staging, tuple(files), record)


def run_model(
    inputs: SessionInputs, model: Any, mass_identification: Any = None
) -> OpenSimExport | None:
    """``opensim/model.osim``: the scaled model with the segment inertias the ``joint_torques``
    table was computed with — the mass-identified ones when the mass identification ran
    (:func:`msk.dynamics.identification.identified_model`), else the scaled generic
    ones — and the model's muscles (F_iso as the muscle-force stage used them, not the strength
    identification's factors). A model OpenSim cannot hold as written is left out and the
    record says why (:mod:`msk.io.osim_writer`)."""
    from msk.dynamics.identification import identified_model

    if model is None:
        return None
    staging = tempfile.TemporaryDirectory(prefix="msk-opensim-")
    inertias = "mass-identified" if mass_identification is not None else "scaled generic"
    try:
        mdl = identified_model(
            model.model, mass_identification, by_status=inputs.inertias_by_status
        )
        write_osim(Path(staging.name) / "model.osim", mdl, name=inputs.cfg.subject.name)
    except ModelError as exc:
        return OpenSimExport(staging, (), {"model": f"not written: {exc}"})
    note = (
        f"the scaled model msk used: bodies with the {inertias} segment inertias of the "
        "joint_torques table, joints, coordinates, placed markers, muscles with their scaled "
        "paths (the model's F_iso, not the strength identification's factors)"
    )
    return OpenSimExport(staging, ("model.osim",), {"model": note, "model_inertias": inertias})
