"""Load a C3D trial: markers, force plates, EMG channels and events, in SI units.

python examples/01_load_c3d.py [path/to/trial.c3d]
"""

import sys
from pathlib import Path

import numpy as np

from msk.io import read_c3d

REPO = Path(__file__).resolve().parents[1]
path = Path(sys.argv[1]) if len(sys.argv) > 1 else REPO / "data/gc5-PS/PS_ngait_og_ss1.c3d"
trial = read_c3d(path)
print(
    f"{path.name}: {trial.markers.shape[0]} frames at {trial.point_rate_hz:g} Hz, "
    f"{len(trial.marker_labels)} markers (m), lab up = {trial.up}"
)
for p in trial.plates:
    peak = float(np.nanmax(np.linalg.norm(p.force, axis=1)))
    print(f"  plate {p.index + 1}: peak |F| {peak:.0f} N")
print("  events:", [(e.label, e.context, round(e.time, 3)) for e in trial.events])
