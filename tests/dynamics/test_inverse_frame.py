"""FrameInverseDynamics: one frame's joint torques equal inverse_dynamics' for that frame."""

from __future__ import annotations

import numpy as np

from msk.datasets.models import two_leg_model
from msk.datasets.trials import make_trial
from msk.dynamics.inverse import FrameInverseDynamics, inverse_dynamics
from msk.dynamics.loads import external_loads
from msk.kinematics.ik import kinematics_from_coordinates


def test_frame_inverse_dynamics_equals_the_batch():
    model = two_leg_model()
    tr = make_trial(model, duration_s=0.5, rate_hz=100.0)
    kin = kinematics_from_coordinates(tr.time, tr.q, model.coordinate_names, cutoff_hz=None)
    kin = type(kin)(**{**kin.__dict__, "v": tr.v, "a": tr.a})
    ext = external_loads(model, kin, tr.plates)
    batch = inverse_dynamics(model, kin, ext)
    fid = FrameInverseDynamics(model, ext.bodies)
    for k in range(0, tr.time.size, 7):
        tau = fid.torques(tr.q[k], tr.v[k], tr.a[k], ext.force[k], ext.moment[k])
        np.testing.assert_allclose(tau, batch.tau[k], rtol=1e-10, atol=1e-9)
    # the batch recovers the simulated torques: so does the frame
    act = [i for i, c in enumerate(model.coordinate_names) if not c.startswith("pelvis")]
    np.testing.assert_allclose(tau[act], tr.tau_true[k][act], atol=2.0)
