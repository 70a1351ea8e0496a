"""Muscle forces by static optimisation on a trial, and the knee contact force with its
medial/lateral split — the library calls ``msk run`` composes.

    python examples/03_static_optimization.py
"""

from pathlib import Path

import numpy as np

from msk.contact.knee import knee_contact_force, plateau_geometry, split_medial_lateral
from msk.dynamics.inverse import inverse_dynamics
from msk.dynamics.loads import contact_measured, external_loads, plates_from_trial
from msk.io import read_c3d, to_model_frame
from msk.kinematics.ik import solve_kinematics
from msk.model.files import load_model
from msk.model.markersets import recognise
from msk.muscles.geometry import muscle_geometry, muscle_parameters
from msk.muscles.hill import rigid_tendon_state
from msk.optimization import solve_static_optimization_batch
from msk.personalise.scaling import place_markers_from_motion, scale_from_motion

REPO = Path(__file__).resolve().parents[1]
model = load_model("gait2392")
up = -np.asarray(model.gravity) / np.linalg.norm(model.gravity)
walk = to_model_frame(read_c3d(REPO / "data/gc5-PS/PS_ngait_og_ss1.c3d"), up=up)
match = recognise(walk.marker_labels, model.marker_names, markers=walk.markers)
x, labels = match.apply(walk.markers, walk.marker_labels)
# no static trial: scale and place the lab's markers from the walk itself
model, _ = scale_from_motion(model, x, labels, walk.time, body_mass=82.8)
model, _ = place_markers_from_motion(model, x, labels, walk.time)
kin = solve_kinematics(model, x, labels, walk.time, cutoff_hz=6.0)
loads = external_loads(model, kin, plates_from_trial(walk), cutoff_hz=15.0)
ok = contact_measured(model, kin, loads) & np.isfinite(kin.a).all(axis=1)
tau = inverse_dynamics(model, kin, loads)
geom = muscle_geometry(model, kin.q[ok], kin.v[ok], distal_wrench_joints=("knee_l",))
params = muscle_parameters(model)
state = rigid_tendon_state(params, geom.lengths, geom.velocities)
act = [i for i, c in enumerate(tau.coordinate_names) if c not in tau.root_coordinates]
sol = solve_static_optimization_batch(
    geom.jacobian[:, :, act], tau.tau[ok][:, act],
    f_active=np.clip(state.max_active_force_along_tendon, 0, None),
    f_passive=state.passive_force_along_tendon, reserve_optimal_force=np.ones(len(act)),
    muscle_names=params.names,
)  # fmt: skip
print(f"{ok.sum()} frames, infeasible {sol.infeasible_frames.size}")
idx = np.flatnonzero(ok)


class _Take:  # the frames of ``ok`` of a time-axis result
    def __init__(self, obj):
        self.__dict__.update({k: (v[idx] if isinstance(v, np.ndarray) and v.shape[:1] ==
                                  (ok.size,) else v) for k, v in vars(obj).items()})  # fmt: skip


contact = knee_contact_force(model, _Take(kin), _Take(loads), muscle_forces=sol.forces,
                             muscle_names=params.names, joint="knee_l",
                             distal_wrenches=geom.distal_wrenches["knee_l"])  # fmt: skip
ml = split_medial_lateral(contact, plateau_geometry(model, joint="knee_l"))
bw = 82.8 * 9.80665
print(
    f"peak knee contact {np.nanmax(contact.total) / bw:.2f} BW "
    f"(medial {np.nanmax(ml.medial) / bw:.2f}, lateral {np.nanmax(ml.lateral) / bw:.2f})"
)
