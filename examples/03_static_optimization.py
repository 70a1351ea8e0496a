"""Muscle forces and the knee contact force with its medial/lateral split, as ``msk run``
computes them, against the instrumented implant's measurement (Grand Challenge PS): one call
runs the session (``msk.run_session``), one reads its results back typed
(``msk.read_session``).

    python examples/03_static_optimization.py [OUT_DIR]

The same figures as ``msk run pipelines/gc5_PS.toml --out OUT_DIR`` (tables/knee_contact.csv):
``generic`` with the generic muscle strengths, ``subject_specific`` with the strength of the
groups the EMG identifies (every other group generic), ``measured`` the implant's.
"""

import sys
import tempfile
from pathlib import Path

import numpy as np

import msk

REPO = Path(__file__).resolve().parents[1]
out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp()) / "gc5_PS"
msk.run_session(REPO / "pipelines/gc5_PS.toml", out)
res = msk.read_session(out)
forces = res.tables["muscle_forces"]
print(f"{int(np.isfinite(forces.data).all(axis=1).sum())} frames with muscle forces")
contact = res.tables["knee_contact"]
for variant in ("generic", "subject_specific", "measured"):
    total, med, lat = (np.nanmax(contact.column(f"{variant}_{c}_bw"))
                       for c in ("total", "medial", "lateral"))  # fmt: skip
    print(f"{variant}: peak knee contact {total:.2f} BW (medial {med:.2f}, lateral {lat:.2f})")
