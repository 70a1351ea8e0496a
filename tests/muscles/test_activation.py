"""Activation dynamics: first order (seed 002 Eq. 8, Thelen, Zajac), recursive filter (seed 003)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from msk.exceptions import MuscleModelError
from msk.muscles.activation import (
    PIECEWISE_BREAKPOINT,
    emg_to_activation,
    first_order_activation,
    nonlinear_activation,
    piecewise_coefficients,
    recursive_filter,
    recursive_filter_coefficients,
)

RATE = 1000.0


def _step(n: int = 400, k0: int = 50, up: bool = True) -> np.ndarray:
    u = np.zeros(n) if up else np.ones(n)
    u[k0:] = 1.0 if up else 0.0
    return u


def test_seed002_step_response_has_the_theoretical_time_constants():
    ta, td = 0.015, 0.050
    t = np.arange(400) / RATE
    a = first_order_activation(_step(), rate_hz=RATE, tau_act_s=ta, tau_deact_s=td)
    # u switches at sample 50 and is held over each interval: a = 1 − exp(−(t − t_50)/τa)
    j = np.arange(51, 400)
    np.testing.assert_allclose(a[j], 1 - np.exp(-(t[j] - t[50]) / ta), atol=1e-12)
    d = first_order_activation(_step(up=False), rate_hz=RATE, tau_act_s=ta, tau_deact_s=td)
    np.testing.assert_allclose(d[j], np.exp(-(t[j] - t[50]) / td), atol=1e-12)
    # the 63.2 % crossing is one time constant after the step
    k = np.argmax(a >= 1 - np.exp(-1))
    assert abs(t[k] - t[50] - ta) <= 1 / RATE + 1e-9


def test_thelen_step_response_matches_closed_form():
    ta, td = 0.010, 0.040
    t = np.arange(400) / RATE
    a = first_order_activation(
        _step(), rate_hz=RATE, tau_act_s=ta, tau_deact_s=td, form="thelen", substeps=20
    )
    # ȧ = (1 − a)/(τa (0.5 + 1.5 a))  ⇒  t(a) = τa (−2 ln(1 − a) − 1.5 a)
    t_half = ta * (2 * np.log(2) - 0.75)
    t_num = np.interp(0.5, a[50:], t[50:] - t[50])
    assert t_num == pytest.approx(t_half, rel=0.02)
    d = first_order_activation(
        _step(up=False), rate_hz=RATE, tau_act_s=ta, tau_deact_s=td, form="thelen", substeps=20
    )
    # ȧ = −a (0.5 + 1.5 a)/τd  ⇒  t(a) = 2 τd ln((0.5 + 1.5 a)/(2 a))
    t_half_d = 2 * td * np.log(1.25)
    t_num_d = np.interp(-0.5, -d[50:], t[50:] - t[50])
    assert t_num_d == pytest.approx(t_half_d, rel=0.02)


def test_first_order_is_vectorised_and_validates():
    u = np.column_stack([_step(), _step(up=False)])
    a = first_order_activation(u, rate_hz=RATE, tau_act_s=[0.01, 0.02], tau_deact_s=0.05)
    a0 = first_order_activation(u[:, 0], rate_hz=RATE, tau_act_s=0.01, tau_deact_s=0.05)
    np.testing.assert_allclose(a[:, 0], a0)
    with pytest.raises(MuscleModelError, match=r"'soleus'.*tau_act_s.*-0.01"):
        first_order_activation(u, rate_hz=RATE, tau_act_s=[0.01, -0.01], names=["ta", "soleus"])


def test_recursive_filter_unit_gain_and_coefficients():
    alpha, b1, b2 = recursive_filter_coefficients(-0.6, -0.3)
    assert (b1, b2) == pytest.approx((-0.9, 0.18))
    assert alpha / (1 + b1 + b2) == pytest.approx(1.0)  # steady-state gain
    u = recursive_filter(_step(2000, 10), gamma1=-0.9, gamma2=-0.8, initial="zero")
    assert u[-1] == pytest.approx(1.0, abs=1e-9)
    # γ1 = γ2 = 0 is the identity
    e = np.random.default_rng(0).uniform(0, 1, 100)
    np.testing.assert_allclose(recursive_filter(e, gamma1=0.0, gamma2=0.0), e)
    # matches Eq. 1 evaluated literally
    g1, g2 = -0.7, 0.2
    alpha, b1, b2 = recursive_filter_coefficients(g1, g2)
    ref = np.zeros(100)
    for t in range(100):
        ref[t] = (
            alpha * e[t] - b1 * (ref[t - 1] if t > 0 else 0) - b2 * (ref[t - 2] if t > 1 else 0)
        )
    np.testing.assert_allclose(recursive_filter(e, gamma1=g1, gamma2=g2, initial="zero"), ref)


def test_recursive_filter_delay_and_stability_errors():
    e = _step(200, 20)
    u0 = recursive_filter(e, gamma1=-0.5, gamma2=-0.5)
    u = recursive_filter(e, gamma1=-0.5, gamma2=-0.5, delay_samples=15)
    np.testing.assert_allclose(u[15:], u0[:-15])
    with pytest.raises(MuscleModelError, match=r"'vas_lat'.*gamma2.*1.2"):
        recursive_filter(
            np.c_[e, e], gamma1=[-0.5, -0.5], gamma2=[-0.5, 1.2], names=["rf", "vas_lat"]
        )
    with pytest.raises(MuscleModelError, match=r"gamma1.*-1.0"):
        recursive_filter(e, gamma1=-1.0, gamma2=0.0)
    # a positive γ (negative pole) overshoots: documented reason for γ ∈ (−1, 0]
    assert recursive_filter(e, gamma1=0.8, gamma2=-0.5).max() > 1.0


def test_nonlinear_activation_shape():
    u = np.linspace(0, 1, 101)
    a = nonlinear_activation(u, shape_factor=-2.0, form="exponential")
    assert a[0] == 0.0 and a[-1] == pytest.approx(1.0)
    assert np.all(np.diff(a) > 0) and np.all(a >= u - 1e-15)  # concave, above the diagonal
    for A in (0.0, -1e-6):
        got = nonlinear_activation(u, shape_factor=A, form="exponential")
        np.testing.assert_allclose(got, u, atol=1e-6)
    with pytest.raises(MuscleModelError, match=r"shape factor A.*-3.5"):
        nonlinear_activation(u, shape_factor=-3.5, form="exponential")
    with pytest.raises(MuscleModelError, match=r"shape factor A.*0.5"):
        nonlinear_activation(u, shape_factor=0.5, form="exponential")
    with pytest.raises(MuscleModelError, match="unknown nonlinearity"):
        nonlinear_activation(u, shape_factor=0.0, form="cubic")  # type: ignore[arg-type]


@pytest.mark.parametrize("A", [0.01, 0.05, 0.12, 0.3, 0.6])
def test_piecewise_eq7_is_the_default_and_c1_at_the_breakpoint(A):
    """seeds/003 Eq. 7 (Manal & Buchanan 2003): log piece through (0, 0), line through
    Q = (0.3085, 0.3085 + A) and (1, 1), value and slope continuous at u = 0.3085."""
    d, c, m, b = piecewise_coefficients(A)
    u0 = PIECEWISE_BREAKPOINT
    assert m * u0 + b == pytest.approx(u0 + A, abs=1e-12) and m + b == pytest.approx(1.0)
    assert d * np.log1p(c * u0) == pytest.approx(u0 + A, abs=1e-10)  # value
    assert d * c / (c * u0 + 1.0) == pytest.approx(m, rel=1e-9)  # slope
    u = np.linspace(0.0, 1.0, 2001)
    a = nonlinear_activation(u, shape_factor=A)  # piecewise is the default form
    np.testing.assert_allclose(a, nonlinear_activation(u, shape_factor=A, form="piecewise"))
    assert a[0] == 0.0 and a[-1] == pytest.approx(1.0)
    assert np.all(np.diff(a) > 0) and np.all(a >= u - 1e-12)
    assert np.all(np.diff(a, 2) < 1e-9)  # concave: the slope never increases
    low = u < u0
    np.testing.assert_allclose(a[low], d * np.log1p(c * u[low]))
    np.testing.assert_allclose(a[~low], m * u[~low] + b)
    # larger A bends more (seeds/003 Fig. 2.3)
    assert np.all(nonlinear_activation(u, shape_factor=A + 0.01)[1:-1] > a[1:-1])


def test_piecewise_limits_and_range():
    u = np.linspace(0, 1, 11)
    np.testing.assert_allclose(nonlinear_activation(u, shape_factor=0.0), u)
    np.testing.assert_allclose(nonlinear_activation(u, shape_factor=1e-7), u, atol=1e-6)
    for bad in (-0.1, 0.7):
        with pytest.raises(MuscleModelError, match=r"muscle 'column 0'.*piecewise shape factor"):
            nonlinear_activation(u, shape_factor=bad)
    # the default form of emg_to_activation is the piecewise one
    e = np.full(50, 0.2)
    got = emg_to_activation(e, gamma1=-0.5, gamma2=-0.5, shape_factor=0.1)
    np.testing.assert_allclose(got, nonlinear_activation(np.full(50, 0.2), shape_factor=0.1))


unit = st.floats(0.0, 1.0, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(
    e=arrays(np.float64, (60, 2), elements=unit),
    g1=st.floats(-0.99, 0.0),
    g2=st.floats(-0.99, 0.0),
    A=st.floats(-2.99, 0.0),
    d=st.integers(0, 10),
    form=st.sampled_from(["seed002", "thelen", "zajac"]),
)
def test_activation_stays_in_unit_interval(e, g1, g2, A, d, form):
    a = emg_to_activation(
        e, gamma1=g1, gamma2=g2, shape_factor=A, delay_samples=d, form="exponential"
    )
    assert np.all(a >= -1e-12) and np.all(a <= 1 + 1e-12)
    b = first_order_activation(e, rate_hz=100.0, tau_act_s=0.01, tau_deact_s=0.04, form=form)
    assert np.all(b >= 0) and np.all(b <= 1)


@pytest.mark.slow
@pytest.mark.realdata
def test_on_rajagopal_processed_emg(real_dir):
    path = real_dir / "opensim-rajagopal-walk" / "electromyography.sto"
    with path.open() as fh:
        for line in fh:
            if line.strip() == "endheader":
                break
        header = fh.readline().split()
        data = np.loadtxt(fh)
    t, e = data[:, 0], data[:, 1:]
    assert header[0] == "time" and e.shape[1] == 10
    rate = 1 / np.median(np.diff(t))
    assert rate == pytest.approx(2000.0)
    e = np.clip(e, 0, 1)  # published max-normalised envelopes
    a = first_order_activation(e, rate_hz=rate, tau_act_s=0.015, tau_deact_s=0.05, form="thelen")
    assert np.all((a >= 0) & (a <= 1))
    # activation lags excitation: the cross-correlation peak is at a positive lag of a few ms
    lags = np.arange(0, 200)
    for j in range(e.shape[1]):
        x, y = e[:, j] - e[:, j].mean(), a[:, j] - a[:, j].mean()
        cc = [np.dot(x[: len(x) - k], y[k:]) for k in lags]
        lag_s = lags[int(np.argmax(cc))] / rate
        assert 0.002 < lag_s < 0.06, (header[j + 1], lag_s)
    u = emg_to_activation(
        e, gamma1=-0.95, gamma2=-0.95, shape_factor=-1.5, delay_samples=80, form="exponential"
    )
    assert np.all((u >= 0) & (u <= 1))


@pytest.mark.opensim
def test_thelen_form_matches_opensim_activation_model(needs_opensim):
    from msk._runtime.opensim_peer import run_opensim_script

    rng = np.random.default_rng(4)
    pts = np.column_stack([rng.uniform(0.01, 1, 30), rng.uniform(0, 1, 30)])
    out = run_opensim_script(
        """
import opensim as osim
m = osim.Thelen2003Muscle("m", 1000.0, 0.1, 0.2, 0.0)
m.setActivationTimeConstant(ARGS["ta"])
m.setDeactivationTimeConstant(ARGS["td"])
m.finalizeFromProperties()  # rebuilds the activation model from the properties
am = m.getActivationModel()
RESULT["dadt"] = [am.calcDerivative(a, u) for a, u in ARGS["pts"]]
""",
        ta=0.012,
        td=0.045,
        pts=pts.tolist(),
    )
    rate = 1e7  # one tiny exponential step ≈ a + ȧ h
    a0, u = pts[:, 0], pts[:, 1]
    e = np.vstack([u, u])
    a1 = first_order_activation(
        e, rate_hz=rate, tau_act_s=0.012, tau_deact_s=0.045, form="thelen", initial=a0, substeps=1
    )[1]
    np.testing.assert_allclose((a1 - a0) * rate, out["dadt"], rtol=1e-4, atol=1e-6)
