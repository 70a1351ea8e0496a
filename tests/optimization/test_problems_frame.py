"""FrameStaticOptimization: the batch static optimisation's QP, one frame at a time with the
warm start carried, gives the batch's forces."""

from __future__ import annotations

import numpy as np

import msk.optimization as o
from msk.muscles.geometry import muscle_parameters
from msk.muscles.hill import rigid_tendon_state
from msk.optimization.muscle_forces import actuated
from tests.support.two_legs import muscled_two_legs, two_leg_trial


def test_frame_static_optimization_equals_the_batch():
    model = muscled_two_legs()
    _, tq, geo = two_leg_trial(model, n=30)
    params = muscle_parameters(model)
    act = actuated(tq)
    st = rigid_tendon_state(params, geo.lengths, geo.velocities)
    fa = np.maximum(st.max_active_force_along_tendon, 0.0)
    fp = st.passive_force_along_tendon
    jac = np.asarray(geo.jacobian)[:, :, act]
    tau = tq.tau[:, act]
    names = tuple(tq.coordinate_names[i] for i in act)
    w = o.volume_weights(params.max_isometric_force, params.optimal_fiber_length)
    batch = o.solve_static_optimization_batch(
        jac, tau, f_active=fa, f_passive=fp, reserve_optimal_force=np.ones(len(act)),
        activation_weights=w, muscle_names=params.names, coordinate_names=names,
    )  # fmt: skip
    frame = o.FrameStaticOptimization(params.names, names, activation_weights=w)
    for k in range(tau.shape[0]):
        f, a, status = frame.solve(jac[k], tau[k], fa[k], fp[k])
        assert status == o.STATUS_OPTIMAL
        np.testing.assert_allclose(f, batch.forces[k], atol=1e-6)
        np.testing.assert_allclose(a, batch.activations[k], atol=1e-9)
    assert ((a >= -1e-12) & (a <= 1.0 + 1e-12)).all()
