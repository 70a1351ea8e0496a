"""Identify the segment inertial parameters from a walk's kinematics and plates (base-link
equations, physically consistent), and compare the pelvis residuals with the generic model.

    python examples/04_identify_mass.py
"""

from pathlib import Path

import numpy as np

from msk.dynamics.identification import IdentificationTrial, InertialIdentifier
from msk.dynamics.inverse import inverse_dynamics
from msk.dynamics.loads import contact_measured, external_loads, plates_from_trial
from msk.io import read_c3d, to_model_frame
from msk.kinematics.ik import solve_kinematics
from msk.model.files import load_model
from msk.model.markersets import recognise
from msk.personalise.scaling import place_markers_from_motion, scale_from_motion

REPO = Path(__file__).resolve().parents[1]
model = load_model("gait2392")
up = -np.asarray(model.gravity) / np.linalg.norm(model.gravity)
walk = to_model_frame(read_c3d(REPO / "data/gc5-PS/PS_ngait_og_ss1.c3d"), up=up)
match = recognise(walk.marker_labels, model.marker_names, markers=walk.markers)
x, labels = match.apply(walk.markers, walk.marker_labels)
model, _ = scale_from_motion(model, x, labels, walk.time, body_mass=82.8)
model, _ = place_markers_from_motion(model, x, labels, walk.time)
kin = solve_kinematics(model, x, labels, walk.time, cutoff_hz=6.0)
loads = external_loads(model, kin, plates_from_trial(walk), cutoff_hz=15.0)
good = contact_measured(model, kin, loads)
it = IdentificationTrial.from_loads(model, kin, loads, name="walk")
good &= np.isfinite(it.tau_ext).all(axis=1) & np.isfinite(it.theta_ddot).all(axis=1)
trial = IdentificationTrial(it.theta[good], it.theta_dot[good], it.theta_ddot[good],
                            it.tau_ext[good], "walk")  # fmt: skip
est = InertialIdentifier(model, total_mass=82.8, symmetric=True).fit([trial])
identified = model.with_inertias(est.parameters_)
for name, m in (("generic", model), ("identified", identified)):
    jt = inverse_dynamics(m, kin, loads)
    rf = jt.residual_force[good]
    print(
        f"{name}: pelvis residual force RMS {np.sqrt(np.nanmean(rf**2)):.1f} N "
        "(on the fitted frames)"
    )
for seg in est.segments_:
    print(f"  {seg.name:10s} {seg.mass:6.2f} ± {seg.mass_std:4.2f} kg "
          f"(prior {seg.prior_mass:5.2f}; {seg.flag})")  # fmt: skip
