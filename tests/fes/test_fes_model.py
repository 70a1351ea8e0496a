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
