import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msk.exceptions import ModelError
from msk.model.joints import (
    Constant,
    Coupling,
    FourBarKnee,
    FourBarTranslation,
    Linear,
    Multiplier,
    Polynomial,
    SimmSpline,
)

# A crossed four-bar resembling the human knee (metres, femur frame x anterior, y proximal):
# ACL from posterior femur to anterior tibia, PCL from anterior femur to posterior tibia.
KNEE = FourBarKnee(
    femur_a=(-0.010, -0.395),
    femur_b=(0.008, -0.400),
    tibia_c=(0.012, -0.010),
    tibia_d=(-0.018, -0.022),
    theta_ref=0.0,
    p_ref=(0.0, -0.405),
)
FLEXION = np.linspace(0.0, -np.deg2rad(120), 241)  # gait2392 knee_angle is negative in flexion


def central(f, x, h=1e-6):
    return (f(x + h) - f(x - h)) / (2 * h)


def test_simmspline_reproduces_cubics_exactly():
    x = np.linspace(-1.0, 2.0, 9)
    y = x**3 - 2 * x + 0.5
    s = SimmSpline(tuple(x), tuple(y))
    xs = np.linspace(-1.0, 2.0, 101)
    np.testing.assert_allclose(s(xs), xs**3 - 2 * xs + 0.5, atol=1e-12)
    np.testing.assert_allclose(s.d1(xs), 3 * xs**2 - 2, atol=1e-10)
    np.testing.assert_allclose(s.d2(xs), 6 * xs, atol=1e-9)


def test_simmspline_extrapolates_linearly_and_validates_knots():
    s = SimmSpline((0.0, 1.0, 2.0, 3.0), (0.0, 1.0, 0.0, 1.0))
    slope = s.d1(3.0)
    assert s(4.0) == pytest.approx(1.0 + slope)
    assert s.d2(4.0) == 0.0
    with pytest.raises(ModelError, match="increase"):
        SimmSpline((0.0, 0.0, 1.0), (1.0, 2.0, 3.0))
    two = SimmSpline((0.0, 2.0), (1.0, 5.0))
    assert two(1.0) == pytest.approx(3.0)


@settings(max_examples=30, deadline=None)
@given(st.floats(-2.5, 2.5))
def test_function_derivatives_match_finite_differences(x):
    funs = [
        Linear(2.0, -1.0),
        Polynomial((0.3, -1.0, 2.0, 0.5)),
        SimmSpline(tuple(np.linspace(-3, 3, 7)), tuple(np.sin(np.linspace(-3, 3, 7)))),
        Multiplier(Polynomial((1.0, 0.0, 0.0)), -0.5),
        Constant(1.5),
    ]
    for f in funs:
        assert float(f.d1(x)) == pytest.approx(central(f, x), rel=1e-6, abs=1e-7)
        assert float(f.d2(x)) == pytest.approx(central(f.d1, x), rel=1e-5, abs=1e-6)


def test_four_bar_closes_over_full_flexion_range():
    res = KNEE.closure_residual(FLEXION)
    assert np.max(np.abs(res)) < 1e-10
    p, _, _ = KNEE.solve(0.0)
    np.testing.assert_allclose(p, KNEE.p_ref, atol=1e-12)  # reference branch is kept


def test_four_bar_derivatives_match_central_differences():
    p, p1, p2 = KNEE.solve(FLEXION[1:-1])
    h = 1e-6
    fd1 = (KNEE.solve(FLEXION[1:-1] + h)[0] - KNEE.solve(FLEXION[1:-1] - h)[0]) / (2 * h)
    fd2 = (KNEE.solve(FLEXION[1:-1] + h)[1] - KNEE.solve(FLEXION[1:-1] - h)[1]) / (2 * h)
    assert np.max(np.abs(p1 - fd1)) / np.max(np.abs(p1)) < 1e-6
    assert np.max(np.abs(p2 - fd2)) / np.max(np.abs(p2)) < 1e-6
    # rolling-gliding: the tibia moves posteriorly relative to the femur in flexion (roll-back)
    assert not np.allclose(p[0], p[-1])


def test_four_bar_reports_configurations_it_cannot_close():
    bad = FourBarKnee((0.0, 0.0), (0.02, 0.0), (0.0, 0.0), (0.03, 0.0), p_ref=(0.0, -0.01))
    with pytest.raises(ModelError, match="cannot close"):
        bad.solve(np.linspace(0, -3.0, 50))
    assert np.all(np.abs(bad.closure_residual(0.0)) < 1e-12)


def test_coupling_jacobian_and_bias_match_finite_differences():
    coupling = Coupling(
        coordinate=(0, 1, 1, -1, 1),
        functions=(
            Linear(1.0, 0.0),
            FourBarTranslation(KNEE, 0),
            FourBarTranslation(KNEE, 1),
            Constant(0.2),
            Linear(1.0, 0.0),
        ),
        n_coords=2,
    )
    rng = np.random.default_rng(0)
    theta = np.column_stack([rng.uniform(-1, 1, 5), rng.uniform(-1.8, -0.1, 5)])
    thd = rng.normal(size=(5, 2))
    thdd = rng.normal(size=(5, 2))
    g = coupling.jacobian(theta)
    h = 1e-6
    for i in range(2):
        e = np.zeros(2)
        e[i] = h
        fd = (coupling.q(theta + e) - coupling.q(theta - e)) / (2 * h)
        np.testing.assert_allclose(g[..., i], fd, rtol=1e-6, atol=1e-9)
    # Ġθ̇ = d/dt(G) θ̇ along θ(t) = θ + t θ̇
    fd_gdot = (coupling.jacobian(theta + h * thd) - coupling.jacobian(theta - h * thd)) / (2 * h)
    np.testing.assert_allclose(
        coupling.bias(theta, thd), np.einsum("nki,ni->nk", fd_gdot, thd), rtol=1e-6, atol=1e-8
    )
    q, v, a = coupling.embed(theta, thd, thdd)
    np.testing.assert_allclose(q, coupling.q(theta))
    np.testing.assert_allclose(v, np.einsum("nki,ni->nk", g, thd))
    np.testing.assert_allclose(a, np.einsum("nki,ni->nk", g, thdd) + coupling.bias(theta, thd))
    tau = rng.normal(size=(5, 5))
    # virtual work: τ_θ·θ̇ = τ_pin·v
    np.testing.assert_allclose(
        np.einsum("ni,ni->n", coupling.project(theta, tau), thd), np.einsum("nk,nk->n", tau, v)
    )
