"""Inverse kinematics and inverse dynamics of a gait trial with the scaled gait2392 model.

python examples/02_ik_id.py
"""

from pathlib import Path

import numpy as np

from msk.dynamics.inverse import inverse_dynamics
from msk.dynamics.loads import external_loads, plates_from_trial
from msk.io import read_c3d, read_trc_trial, to_model_frame
from msk.kinematics.ik import solve_kinematics
from msk.model.files import load_model
from msk.model.markersets import recognise
from msk.personalise.scaling import place_markers, scale_from_static

REPO = Path(__file__).resolve().parents[1]
model = load_model("gait2392")
up = -np.asarray(model.gravity) / np.linalg.norm(model.gravity)

# static trial (OpenSim frame already): recognise the lab's labels, scale, place the others
static = read_trc_trial(REPO / "data/gc5-PS/PS_static_for_scaling.trc")
match = recognise(static.marker_labels, model.marker_names, markers=static.markers)
xs, labels = match.apply(static.markers, static.marker_labels)
model, report = scale_from_static(model, {k: xs[:, i] for i, k in enumerate(labels)},
                                  body_mass=82.8)  # fmt: skip
model, _ = place_markers(model, xs, labels, static.time)
print("scaling:", {b: m for b, m in report.methods.items() if b in ("pelvis", "femur_l")})

# the walk in the model frame (lab up → model up, heading from the walk)
walk = to_model_frame(read_c3d(REPO / "data/gc5-PS/PS_ngait_og_ss1.c3d"), up=up)
wm = recognise(walk.marker_labels, model.marker_names, markers=walk.markers)
kin = solve_kinematics(model, walk.markers, wm.model_labels(walk.marker_labels), walk.time,
                       cutoff_hz=6.0)  # fmt: skip
loads = external_loads(model, kin, plates_from_trial(walk), cutoff_hz=15.0)
tau = inverse_dynamics(model, kin, loads)
k = tau.coordinate_names.index("knee_angle_l")
print(
    f"IK marker RMS {1000 * np.nanmean(kin.marker_rms):.1f} mm; "
    f"left knee moment range {np.nanmin(tau.tau[:, k]):.0f}…{np.nanmax(tau.tau[:, k]):.0f} N·m"
)
