"""msk.fes.model: parameter sets, orderings, recruitment, geometry, Eq. 1–4 consistency."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msk.exceptions import ModelError
from msk.fes.identify import geometry_from_height
from msk.fes.model import (
    PARAM_NAMES,
    SEED001_SUBJECT,
    TABLE3,
    param_vector,
    subject_from_vector,
)
from msk.fes.protocol import TABLE1
from msk.fes.simulate import rhs_function


def test_param_vector_round_trip() -> None:
    for s in (*TABLE3.values(), SEED001_SUBJECT):
        p = param_vector(s)
        assert p.shape == (len(PARAM_NAMES),)
        assert subject_from_vector(s, p) == s


def test_table3_values_and_units() -> None:
    s = TABLE3["S3L"]
    assert s.geometry.L_ext == pytest.approx(0.412)
    assert s.geometry.r_q == pytest.approx(0.0484)
    assert (s.knee.K, s.knee.J, s.knee.B) == (11.1, 0.29, 0.19)
    assert s.muscle.k_s == pytest.approx(10e3)  # 10 N/mm
    assert s.muscle.K_cm == pytest.approx(400e3)  # 400 N/mm
    assert s.muscle.L_c0 == pytest.approx(0.0907)
    assert {"S3L", "S6R", "S9L", "S10R"} <= set(TABLE3)
    # Table 3 mean of b over the 14 legs minus S5R's missing muscle entries: close to 0.42
    assert np.mean([t.muscle.b for t in TABLE3.values()]) == pytest.approx(0.43, abs=0.02)


def test_recruitment_pw_eq10_and_normalisation() -> None:
    r = TABLE3["S3L"].recruitment
    # inflexion at c3 PW_max with value c1/2; Table 3 sets give alpha(PW_max) ~ 1
    assert r(r.c3 * 420e-6) == pytest.approx(r.c1 / 2)
    for name in ("S3L", "S6R", "S9L", "S10R"):
        assert TABLE3[name].recruitment(420e-6) == pytest.approx(1.0, abs=0.03)


def test_recruitment_current_seed001_eq7() -> None:
    r = SEED001_SUBJECT.recruitment
    assert r(0.0) == pytest.approx(0.0)
    a3 = float(r(3e-3))
    rr = 0.593 * (1 - 0.295) * 3.0
    assert a3 == pytest.approx(4.203 * (np.tanh(rr + 0.994) + np.tanh(-0.994)))
    assert 0.85 < a3 < 1.0
    grid = r(np.linspace(0, 3e-3, 50))
    assert np.all(np.diff(grid) > 0)


def test_geometry_from_height_reproduces_table3_and_seed001() -> None:
    for name, s in TABLE3.items():
        subject_no = int(name[1:-1])
        h = TABLE1[subject_no][0]
        g = geometry_from_height(h)
        assert g.L_ext == pytest.approx(s.geometry.L_ext, rel=0.004), name
        assert g.r_q == pytest.approx(s.geometry.r_q, rel=0.004), name
        assert g.nrmsd < 2.0  # the polynomial is nearly linear over 0–90°
    g = geometry_from_height(1.75)
    assert g.L_ext == pytest.approx(0.412, abs=5e-4)  # seeds/001 Table I
    assert g.r_q == pytest.approx(0.048, abs=5e-4)


def test_seed001_virtual_stiffness() -> None:
    k = SEED001_SUBJECT.knee
    assert k.K_eq == pytest.approx(12.1, abs=0.05)  # 4.026 * 9.8 * 0.194 + 4.441
    assert 2 * k.zeta * k.omega_n * k.J == pytest.approx(0.201)


def test_validate_names_parameter() -> None:
    bad = TABLE3["S3L"].with_muscle(k_s=-1.0)
    with pytest.raises(ModelError, match="k_s"):
        bad.validate()


@settings(max_examples=30, deadline=None)
@given(
    theta_r=st.floats(-0.3, 1.4),
    omega=st.floats(-3.0, 3.0),
    kc=st.floats(0.0, 3e5),
    fc=st.floats(0.0, 400.0),
    pi=st.floats(0.0, 1.0),
    pw=st.floats(0.0, 420e-6),
)
def test_eq3_is_the_derivative_of_the_series_element_law(
    theta_r: float, omega: float, kc: float, fc: float, pi: float, pw: float
) -> None:
    """ε̇_c of Eq. 3 equals d/dt of ε_c = (L − L_s − F_c/k_s − L_c0)/L_c0 with Ḟ_c of Eq. 1.

    An identity between two independent expressions: it checks our reading of Eq. 1–4.
    """
    s = TABLE3["S3L"]
    f = rhs_function("pw", False)
    p = param_vector(s)
    xdot, _alpha, _eps, eps_dot = (
        np.asarray(v).ravel() for v in f([theta_r, omega, kc, fc], pw, pi, p)
    )
    l_dot = -s.geometry.r_q * omega
    expected = (l_dot - xdot[3] / s.muscle.k_s) / s.muscle.L_c0
    assert eps_dot[0] == pytest.approx(
        expected[0] if np.ndim(expected) else expected, rel=1e-6, abs=1e-9
    )


def test_seed001_contractile_element_is_its_eq3() -> None:
    """rhs_function(..., ce="001") against seeds/001 Eq. 3 written out with its a, b, p, q
    (u = U_c, the fused-tetanus rate; F_0, K_0 from Eq. 5-6 on the whole muscle length)."""
    from msk.fes.model import SEED001_SUBJECT, param_vector
    from msk.fes.simulate import rhs_function

    s = SEED001_SUBJECT
    assert s.contractile == "001"
    m, g = s.muscle, s.geometry
    p = param_vector(s)
    level = 2e-3
    alpha = float(s.recruitment(level))
    u = s.calcium.U_c
    L_opt, b_l = m.L_c0 + m.L_s, m.b * m.L_c0 / (m.L_c0 + m.L_s)
    for x in ([0.3, 1.2, 4e3, 120.0], [0.5, -2.0, 8e3, 60.0], [0.1, 0.0, 1e3, 10.0]):
        theta = s.knee.theta_rest - x[0]
        L = g.L_ext + g.r_q * theta
        L0 = L  # ε = (L − L0)/L0: any reference length, it cancels (a ε̇ = L̇/L_c0)
        eps_dot = -g.r_q * x[1] / L0
        fl = np.exp(-(((L / L_opt - 1) / b_l) ** 2))
        F0, K0 = m.F_cm * fl, m.K_cm * fl
        a, b, pp, q = L0 / m.L_c0, L0, 1 / m.k_s, 1 / (m.L_c0 * m.k_s)
        kc, fc = x[2], x[3]
        sv = np.sign(a * eps_dot + q * u * (fc - F0 * alpha))
        D = 1 + pp * kc - sv * q * fc
        kc_dot = (
            (u * K0 + sv * q * u * F0 * kc) * alpha - (u + sv * q * u * fc + sv * a * eps_dot) * kc
        ) / D
        fc_dot = (u * F0 * alpha + (b * kc - sv * a * fc) * eps_dot - u * fc) / D
        out = np.asarray(rhs_function("current", False, "001")(x, level, 1.0, p)[0]).ravel()
        assert out[2] == pytest.approx(kc_dot, rel=1e-9)
        assert out[3] == pytest.approx(fc_dot, rel=1e-9)


def test_seed001_isometric_steady_force_on_whole_length() -> None:
    """Eq. 5: the steady isometric force is α F_max Fl(L_q), whatever k_s (no F/k_s shift)."""
    from msk.fes.model import SEED001_SUBJECT
    from msk.fes.simulate import simulate
    from msk.fes.stimulation import pulse_train

    s = SEED001_SUBJECT
    st = pulse_train(3e-3, duration=3.0, frequency_hz=31.25, kind="current")
    for deg in (24, 60, 77):
        a = np.deg2rad(deg)
        tr = simulate(s, st, duration=3.0, isometric_angle=a)
        L = s.geometry.L_ext + s.geometry.r_q * a
        fl = np.exp(-(((L - s.muscle.L_s - s.muscle.L_c0) / (s.muscle.b * s.muscle.L_c0)) ** 2))
        assert tr.F_c[-10] == pytest.approx(
            float(s.recruitment(3e-3)) * s.muscle.F_cm * fl, rel=1e-3
        )
