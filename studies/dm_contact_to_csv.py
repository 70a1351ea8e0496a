"""Convert the Grand Challenge DM measured knee contact forces (.mat) to time-stamped CSV.

The MATLAB files of fmoissenet/MSK_Delp_U_Ankle (``DM_ngait_og*.mat``: ``Force.KneeMedial``,
``Force.KneeLateral`` in N at 120 Hz, one gait cycle, no time vector) are placed in the time
base of the trial's OpenSim marker file (``<trial>_new.trc`` of opensim-jam-org/jam-resources)
by matching the .mat's marker trajectories against the ``.trc`` markers
(:func:`msk.io.contact_force.align_dm_trial`; the ground reaction in ``<trial>_grf.sto``, when
present, is matched too as a check). The output is the CSV format that
:func:`msk.io.contact_force.read_measured_contact` reads::

    time,medial_N,lateral_N,total_N

``time`` in s (the ``.trc`` times of the aligned frames), forces in N, ``total`` = medial +
lateral (the axial force; the eTibia's 3-D magnitude is not in these files).

Usage::

    python studies/dm_contact_to_csv.py MAT [MAT ...] [--motion-dir DIR] [--out DIR]

``--motion-dir`` holds ``<trial>_new.trc`` and ``<trial>_grf.sto`` (default: the .mat's
parent's parent, the layout of ``data/real/knee-grand-challenge-gc6-DM/``); the output is
``<out>/<trial>_contact.csv`` (default ``--out .``). One line per trial is printed: offset,
marker residual, GRF check and the peak forces in body weights (the .mat's ``mass``).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from msk.io.contact_force import read_measured_contact
from msk.io.tables import write_csv_table

G0 = 9.80665
COLUMNS = ("medial_N", "lateral_N", "total_N")


def convert(mat: Path, motion_dir: Path, out_dir: Path) -> tuple[Path, str]:
    """Convert one .mat file; return the CSV written and a one-line summary."""
    trial = mat.stem
    trc = motion_dir / f"{trial}_new.trc"
    sto = motion_dir / f"{trial}_grf.sto"
    if not trc.is_file():
        raise FileNotFoundError(f"{trc}: the trial's marker file is needed for the time")
    meas = read_measured_contact(mat, trial=trc, grf=sto if sto.is_file() else None)
    assert meas.time is not None
    al = meas.metadata["alignment"]
    data = np.stack([meas.medial, meas.lateral, meas.total], axis=1)
    out = write_csv_table(
        out_dir / f"{trial}_contact.csv", time=meas.time, data=data, columns=COLUMNS
    )
    bw = float(meas.metadata["mass_kg"]) * G0
    peaks = np.nanmax(data, axis=0) / bw
    grf = (
        f"GRF {al['grf_plate']} {al['grf_start_time_s']:.6g} s RMS {al['grf_rms_n']:.1f} N"
        if al["grf_plate"]
        else "GRF not checked"
    )
    line = (
        f"{trial}: {meas.n_frames} frames, frame 0 = trc row {al['offset_frames']} "
        f"({al['start_time_s']:.6g} s), markers RMS {al['marker_rms_m'] * 1e3:.2f} mm "
        f"(±1 frame {al['neighbour_rms_m'] * 1e3:.1f} mm, {len(al['matches'])} markers), "
        f"{grf}; peak medial {peaks[0]:.2f} lateral {peaks[1]:.2f} total {peaks[2]:.2f} BW"
    )
    return out, line


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mat", nargs="+", type=Path, help="DM_*.mat files")
    ap.add_argument("--motion-dir", type=Path, default=None, help="folder of the .trc/.sto")
    ap.add_argument("--out", type=Path, default=Path("."), help="output folder")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for mat in args.mat:
        motion = args.motion_dir if args.motion_dir is not None else mat.resolve().parent.parent
        path, line = convert(mat, motion, args.out)
        print(f"{line} -> {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
