"""The lab pipeline: one session configuration → the results contract (:mod:`msk.results.folder`).

Composition only: every number comes from an msk library call. One module per stage, each a
function of the :class:`~msk.pipeline.inputs.SessionInputs` and of its upstream results,
returning a frozen result; the graph (:mod:`msk.pipeline.graph`) declares the order and the
dependencies in one place; :mod:`msk.pipeline.runner` runs it with the content-hash cache,
status records and progress; :mod:`msk.pipeline.session` writes the folder.

    read → model (load, scale, place markers) → kinematics → loads → mass_identification
      → inverse_dynamics → emg → muscle_geometry → tension_optimization
      → strength_identification → knee_contact → comparison → fes → report

**Stage status.** ``computed`` / ``cached`` / ``not requested`` (the configuration has no
trial for it) / ``not available`` (a prerequisite or library piece is missing: recorded with
the reason, never replaced by made-up numbers) / ``failed`` (an analysis stage raised: recorded
with its message and the run goes on). The core stages (read, model, kinematics, loads, inverse
dynamics, report) have no fallback: their errors end the run, and nothing is written.

**Cache.** A stage's key is the sha256 of its name, the code fingerprint (the source of msk and
the versions of its numerical dependencies), its settings and the keys of the stages it reads
(input files enter through their content hash). Values are stored in ``<out>/.cache`` by
:mod:`msk._runtime.cache` (``.npz`` + JSON, checksummed, never pickled).

**FES.** The ``fes`` stage runs the identification protocol on the ``role = "fes"`` trials; a
session may hold only FES trials: the gait stages are then ``not requested``.
"""

from __future__ import annotations

from msk.io.frames import lab_to_model_rotation
from msk.personalise.scaling import DEFAULT_MEASUREMENTS
from msk.pipeline.graph import CORE_STAGES, GRAPH, STAGES, Node
from msk.pipeline.runner import RunResult, StageRecord, file_sha256
from msk.pipeline.session import run_session, run_stages, run_task_trials, split_task_trials

__all__ = [
    "CORE_STAGES",
    "DEFAULT_MEASUREMENTS",
    "GRAPH",
    "STAGES",
    "Node",
    "RunResult",
    "StageRecord",
    "file_sha256",
    "lab_to_model_rotation",
    "run_session",
    "run_stages",
    "run_task_trials",
    "split_task_trials",
]
