"""The OpenSim peer's gait2392 subject01 walk (``shared/tools/opensim-peer/data``), the sample
data of OpenSim's Gait2392_Simbody pipeline, as msk inputs, for cross-checks and benchmarks.

:func:`load_subject01` reads the scaled model, the markers, the IK tasks, the plates and
OpenSim's reference IK; :data:`OPENSIM_IK_ID_SCRIPT` is the OpenSim child-process script (run by
:func:`msk._runtime.opensim_peer.run_opensim_script`) of OpenSim's IK and ID with the subject01
setups.
The data are not bundled: :func:`subject01_pipeline` may not exist.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from msk.dynamics.loads import PlateWrench
from msk.model.core import Model
from msk.units import Array

__all__ = ["OPENSIM_IK_ID_SCRIPT", "Subject01", "load_subject01", "subject01_pipeline"]


@dataclass(frozen=True)
class Subject01:
    """Inputs of OpenSim's gait2392 subject01 walk (``shared/tools/opensim-peer/data``)."""

    pipeline: Path
    model: Model
    trc_time: Array
    markers: Array
    marker_labels: tuple[str, ...]
    weights: dict[str, float]
    coordinate_tasks: dict[str, tuple[float, float]]
    plates: tuple[PlateWrench, ...]
    ik_time: Array
    ik_q: Array  # OpenSim's reference IK, rad / m, model coordinate order

    @property
    def model_path(self) -> Path:
        return self.pipeline / "OutputReference" / "subject01_simbody.osim"

    @property
    def reference_id_path(self) -> Path:
        return (
            self.pipeline
            / "OutputReference"
            / "ResultsInverseDynamics"
            / "InverseDynamicsOutput.sto"
        )


def subject01_pipeline() -> Path:
    from msk.datasets.shared import shared_dir

    return shared_dir() / "tools" / "opensim-peer" / "data" / "Pipelines" / "Gait2392_Simbody"


def load_subject01() -> Subject01:
    """Model (via :func:`msk.model.osim.load_osim`), markers, IK tasks, plates and reference IK.

    The reference IK ``.mot`` has an old SIMM header without ``inDegrees``: its rotational
    coordinates are in degrees and converted here.
    """
    from msk.dynamics.loads import plates_from_table
    from msk.io.opensim_files import read_sto, read_trc
    from msk.kinematics.ik import ik_tasks_from_setup
    from msk.model.osim import load_osim

    pipe = subject01_pipeline()
    model = load_osim(pipe / "OutputReference" / "subject01_simbody.osim")
    trc = read_trc(pipe / "subject01_walk1.trc")
    weights, tasks = ik_tasks_from_setup(pipe / "subject01_Setup_IK.xml")
    grf = read_sto(pipe / "subject01_walk1_grf.mot")
    plates = plates_from_table(grf.time, grf.data, grf.columns)
    ik = read_sto(pipe / "OutputReference" / "subject01_walk1_ik.mot")
    cols = [ik.columns.index(c) for c in model.coordinate_names]
    q = ik.data[:, cols].copy()
    rot = [c.kind == "rotational" for c in model.coordinates]
    q[:, rot] = np.deg2rad(q[:, rot])
    return Subject01(
        pipeline=pipe,
        model=model,
        trc_time=trc.time,
        markers=trc.markers,
        marker_labels=trc.labels,
        weights=weights,
        coordinate_tasks=tasks,
        plates=plates,
        ik_time=ik.time,
        ik_q=q,
    )


#: OpenSim child-process script: IK (when ``trc`` is given) and ID with the subject01 setups,
#: each repeated ``ik_repeats`` / ``id_repeats`` times and timed inside the child (best kept).
OPENSIM_IK_ID_SCRIPT = """
import opensim as osim, os, time
P = ARGS["pipe"]
out = ARGS["out"]
model = P + "/OutputReference/subject01_simbody.osim"
ik_mot = ARGS.get("ik_mot")
if ARGS.get("trc"):
    ik_mot = out + "/ik.mot"
    walls = []
    for _ in range(int(ARGS.get("ik_repeats", 1))):
        ik = osim.InverseKinematicsTool(P + "/subject01_Setup_IK.xml")
        ik.set_model_file(model)
        ik.setMarkerDataFileName(ARGS["trc"])
        ik.setStartTime(ARGS["t0"]); ik.setEndTime(ARGS["t1"])
        ik.setResultsDir(out)
        ik.setOutputMotionFileName(ik_mot)
        tic = time.perf_counter(); ok = ik.run(); walls.append(time.perf_counter() - tic)
    RESULT["ik_wall_s"] = min(walls)
    RESULT["ik_walls_s"] = walls
    t = osim.TimeSeriesTable(ik_mot)
    RESULT["ik_frames"] = t.getNumRows()
    RESULT["ik_time"] = list(t.getIndependentColumn())
    RESULT["ik_labels"] = list(t.getColumnLabels())
    RESULT["ik_data"] = t.getMatrix().to_numpy().tolist()
el = osim.ExternalLoads(P + "/subject01_walk1_grf.xml", True)
el.setDataFileName(os.path.abspath(ARGS["grf"]))
el.printToXML(out + "/el.xml")
walls = []
for _ in range(int(ARGS.get("id_repeats", 1))):
    idt = osim.InverseDynamicsTool(P + "/subject01_Setup_InverseDynamics.xml")
    idt.setModelFileName(model)
    idt.setCoordinatesFileName(ik_mot)
    idt.setExternalLoadsFileName(out + "/el.xml")
    idt.setLowpassCutoffFrequency(ARGS["cutoff_hz"])
    idt.setStartTime(ARGS["t0"]); idt.setEndTime(ARGS["t1"])
    idt.setResultsDir(out); idt.setOutputGenForceFileName("id.sto")
    tic = time.perf_counter(); ok = idt.run(); walls.append(time.perf_counter() - tic)
RESULT["id_wall_s"] = min(walls)
RESULT["id_walls_s"] = walls
t = osim.TimeSeriesTable(out + "/id.sto")
RESULT["id_frames"] = t.getNumRows()
RESULT["id_time"] = list(t.getIndependentColumn())
RESULT["id_labels"] = list(t.getColumnLabels())
RESULT["id_data"] = t.getMatrix().to_numpy().tolist()
"""
