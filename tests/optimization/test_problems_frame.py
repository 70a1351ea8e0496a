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


def test_frame_static_optimization_direct_daqp_is_the_registered_solver():
    """The DAQP workspace driven on the object's buffers gives what the registered solver
    (``msk.optimization._qp``'s DAQP entry) gives, bit for bit, through infeasible frames
    (bounded reserves, torques beyond the muscles) and the cold solve and fresh setup that
    follow them."""
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
    peak = np.abs(tau).max(axis=0)
    kw = dict(reserve_min_control=-2.0 * peak, reserve_max_control=2.0 * peak)
    direct = o.FrameStaticOptimization(params.names, names, **kw)
    generic = o.FrameStaticOptimization(params.names, names, **kw)
    assert direct._daqp is not None
    generic._daqp = None  # through StandardQP and the registered solver
    statuses = []
    for k in range(tau.shape[0]):
        t = tau[k] * (100.0 if k % 4 == 2 else 1.0)  # every fourth frame beyond the muscles
        f1, a1, s1 = direct.solve(jac[k], t, fa[k], fp[k])
        f2, a2, s2 = generic.solve(jac[k], t, fa[k], fp[k])
        assert s1 == s2
        assert np.array_equal(f1, f2, equal_nan=True) and np.array_equal(a1, a2, equal_nan=True)
        statuses.append(s1)
    assert statuses.count(o.STATUS_OPTIMAL) > 15 and statuses.count(o.STATUS_INFEASIBLE) > 3
