import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msk.datasets.models import leg_model
from msk.dynamics.regressors import (
    base_link_regressor,
    base_parameters,
    external_generalized_forces,
    joint_torque_regressor,
    parameter_transform,
    regressor_layout,
    root_coordinate_indices,
)
from msk.exceptions import IdentificationError
from msk.model.core import INERTIAL_PARAMETER_NAMES

MODEL = leg_model()
LAYOUT = regressor_layout(MODEL)


def random_states(rng, n):
    th = rng.uniform(-1, 1, (n, MODEL.n_coords))
    th[:, 9] = rng.uniform(-2.0, 0.0, n)
    return th, rng.normal(size=th.shape), rng.normal(size=th.shape)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_regressor_times_parameters_equals_rnea(seed):
    rng = np.random.default_rng(seed)
    th, thd, thdd = random_states(rng, 3)
    y = joint_torque_regressor(MODEL, th, thd, thdd, layout=LAYOUT)
    phi = LAYOUT.parameters(MODEL)
    data = MODEL.create_data()
    q, v, a = MODEL.coupling.embed(th, thd, thdd)
    for n in range(3):
        tau = MODEL.coupling.project(th[n], pin.rnea(MODEL.pin_model, data, q[n], v[n], a[n]))
        np.testing.assert_allclose(y[n] @ phi, tau, rtol=1e-9, atol=1e-9)


def test_parameter_transform_matches_pinocchio_se3_action():
    rng = np.random.default_rng(3)
    for _ in range(5):
        inertia = pin.Inertia.Random()
        place = pin.SE3.Random()
        phi = inertia.toDynamicParameters()
        np.testing.assert_allclose(
            parameter_transform(place) @ phi,
            place.act(inertia).toDynamicParameters(),
            rtol=1e-10,
            atol=1e-12,
        )
    assert rng is not None


def test_base_link_equations_hold_with_external_forces():
    rng = np.random.default_rng(5)
    th, thd, thdd = random_states(rng, 4)
    nj = MODEL.pin_model.njoints
    fext = np.zeros((4, nj, 6))
    foot_joint = MODEL.body_joint["foot"]
    fext[:, foot_joint] = rng.normal(scale=300.0, size=(4, 6))
    tau_ext = external_generalized_forces(MODEL, th, fext)
    # RNEA with the external wrenches gives τ = Yφ − τ_ext
    data = MODEL.create_data()
    q, v, a = MODEL.coupling.embed(th, thd, thdd)
    y_root = base_link_regressor(MODEL, th, thd, thdd, layout=LAYOUT)
    root = root_coordinate_indices(MODEL)
    np.testing.assert_array_equal(root, np.arange(6))
    for n in range(4):
        forces = [pin.Force(f) for f in fext[n]]
        tau = pin.rnea(MODEL.pin_model, data, q[n], v[n], a[n], forces)
        tau_theta = MODEL.coupling.project(th[n], tau)
        np.testing.assert_allclose(
            y_root[n] @ LAYOUT.parameters(MODEL) - tau_ext[n, root], tau_theta[root], atol=1e-8
        )


def test_base_parameters_reproduce_regressor_and_names_are_ordered():
    rng = np.random.default_rng(7)
    th, thd, thdd = random_states(rng, 40)
    y = base_link_regressor(MODEL, th, thd, thdd, layout=LAYOUT)
    base = base_parameters(y, LAYOUT.parameter_names)
    assert 0 < base.rank < y.shape[-1]
    th2, thd2, thdd2 = random_states(rng, 5)
    y2 = base_link_regressor(MODEL, th2, thd2, thdd2, layout=LAYOUT).reshape(-1, y.shape[-1])
    phi = LAYOUT.parameters(MODEL) * rng.uniform(0.5, 1.5, y.shape[-1])
    np.testing.assert_allclose(y2[:, base.independent] @ base.beta(phi), y2 @ phi, atol=1e-8)
    assert LAYOUT.parameter_names[:10] == tuple(f"pelvis.{p}" for p in INERTIAL_PARAMETER_NAMES)
    # the base-link equations see every body's mass
    masses = [LAYOUT.parameter_names.index(f"{b}.m") for b in LAYOUT.body_names]
    assert set(masses) <= set(base.independent) | set(base.dependent)
    with pytest.raises(IdentificationError):
        base_parameters(np.zeros((6, 4)), ["a", "b", "c", "d"])
