"""Input/output: C3D trials (via ezc3d), OpenSim ``.trc/.mot/.sto`` files, CSV result tables;
:func:`read_trial` reads a trial file by its suffix; :func:`read_dynamometer` a dynamometer
export (CSV, tab-separated, gzip).

Everything returned is SI (m, s, rad, N, N·m, kg) with time on axis 0.
"""

from msk.io.c3d import PlateSpec, is_measured_marker, read_c3d, write_c3d
from msk.io.dynamometer import DynamometerRecording, read_dynamometer
from msk.io.frames import (
    lab_to_model_rotation,
    rotate_plate,
    rotate_trial,
    rotation_between,
    to_model_frame,
)
from msk.io.grf import (
    ExternalForceSpec,
    ExternalLoadsSpec,
    GrfForceSet,
    external_force_sets,
    grf_force_sets,
    read_external_loads_xml,
)
from msk.io.opensim_files import (
    MarkerTable,
    read_mot,
    read_sto,
    read_trc,
    read_trc_trial,
    write_mot,
    write_sto,
    write_trc,
)
from msk.io.readers import TrialReader, read_trial, register_trial_reader, trial_suffixes
from msk.io.tables import Table, read_csv_table, write_csv_table
from msk.trial import Event, ForcePlate, GapReport, ModelOutputs, Subject, Trial

__all__ = [
    "DynamometerRecording",
    "Event",
    "ExternalForceSpec",
    "ExternalLoadsSpec",
    "ForcePlate",
    "GapReport",
    "GrfForceSet",
    "MarkerTable",
    "ModelOutputs",
    "PlateSpec",
    "Subject",
    "Table",
    "Trial",
    "TrialReader",
    "external_force_sets",
    "grf_force_sets",
    "is_measured_marker",
    "lab_to_model_rotation",
    "read_c3d",
    "read_csv_table",
    "read_dynamometer",
    "read_external_loads_xml",
    "read_mot",
    "read_sto",
    "read_trc",
    "read_trc_trial",
    "read_trial",
    "register_trial_reader",
    "rotate_plate",
    "rotate_trial",
    "rotation_between",
    "to_model_frame",
    "trial_suffixes",
    "write_c3d",
    "write_csv_table",
    "write_mot",
    "write_sto",
    "write_trc",
]
