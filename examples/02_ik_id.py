"""Inverse kinematics and inverse dynamics of a gait trial, as ``msk run`` computes them: one
call runs the session (``msk.run_session``: the scaled gait2392 model with the lab's foot
markers moved to the static's positions, IK, the plates' loads, inverse dynamics…), one reads
its results folder back typed (``msk.read_session``).

    python examples/02_ik_id.py [OUT_DIR]

The same figures as ``msk run pipelines/gc5_PS.toml --out OUT_DIR`` (its summary.json and
tables/joint_torques.csv); the library calls each stage makes are listed in
docs/architecture.md ("The stage graph of msk run").
"""

import sys
import tempfile
from pathlib import Path

import numpy as np

import msk

REPO = Path(__file__).resolve().parents[1]
out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp()) / "gc5_PS"
msk.run_session(REPO / "pipelines/gc5_PS.toml", out)  # a cached stage is not computed again
res = msk.read_session(out)
q = res.summary.quality
knee = res.tables["joint_torques"].column("knee_angle_l")  # N·m
print(
    f"IK marker RMS {1000 * q.ik_marker_rms_mean_m:.1f} mm; "
    f"left knee moment range {np.nanmin(knee):.0f}…{np.nanmax(knee):.0f} N·m"
)
