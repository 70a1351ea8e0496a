"""Input/output: C3D trials (via ezc3d), OpenSim ``.trc/.mot/.sto`` files, CSV result tables.

Everything returned is SI (m, s, rad, N, N·m, kg) with time on axis 0.
"""

from msk.io.c3d import (
    Event,
    ForcePlate,
    GapReport,
    ModelOutputs,
    PlateSpec,
    Subject,
    Trial,
    read_c3d,
    write_c3d,
)
from msk.io.opensim_files import (
    MarkerTable,
    Table,
    read_mot,
    read_sto,
    read_trc,
    write_mot,
    write_sto,
    write_trc,
)
from msk.io.tables import read_csv_table, write_csv_table

__all__ = [
    "Event",
    "ForcePlate",
    "GapReport",
    "MarkerTable",
    "ModelOutputs",
    "PlateSpec",
    "Subject",
    "Table",
    "Trial",
    "read_c3d",
    "read_csv_table",
    "read_mot",
    "read_sto",
    "read_trc",
    "write_c3d",
    "write_csv_table",
    "write_mot",
    "write_sto",
    "write_trc",
]
