"""Hill-type models: curves, derivatives, rigid-tendon state, elastic equilibrium, vs OpenSim."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq

from msk.exceptions import MuscleModelError
from msk.muscles.hill import (
    MUSCLE_PARAMETER_ORDER,
    LloydBesierCurves,
    MuscleParameters,
    RigidTendonFrame,
    Thelen2003Curves,
    equilibrium,
    fl_gaussian,
    fv_stroeve,
    pennation_constant_height,
    reference_force,
    rigid_tendon_state,
)


def _params() -> MuscleParameters:
    return MuscleParameters(
        ("vas_lat", "soleus", "rect_fem"),
        np.array([1870.0, 3550.0, 780.0]),
        np.array([0.084, 0.05, 0.114]),
        np.array([0.157, 0.25, 0.31]),
        np.array([0.0873, 0.4363, 0.0873]),
        np.array([10.0, 8.0, 10.0]),
    )


# --- parameters -------------------------------------------------------------------------------
def test_parameter_order_round_trip():
    p = _params()
    arr = p.to_array()
    assert arr.shape == (3, len(MUSCLE_PARAMETER_ORDER))
    q = MuscleParameters.from_array(p.names, arr)
    for k in MUSCLE_PARAMETER_ORDER:
        np.testing.assert_array_equal(getattr(q, k), getattr(p, k))
    np.testing.assert_array_equal(
        arr[:, MUSCLE_PARAMETER_ORDER.index("optimal_fiber_length")], p.optimal_fiber_length
    )
    s = p.subset(["rect_fem", "vas_lat"])
    assert s.names == ("rect_fem", "vas_lat")
    assert s.max_isometric_force.tolist() == [780.0, 1870.0]


def test_bad_parameters_name_the_muscle():
    with pytest.raises(MuscleModelError, match=r"soleus.*optimal_fiber_length.*-0.05"):
        MuscleParameters(("a", "soleus"), [1.0, 1.0], [0.1, -0.05], [0.2, 0.2], [0.0, 0.0])
    with pytest.raises(MuscleModelError, match=r"'b'.*pennation"):
        MuscleParameters(("a", "b"), [1.0, 1.0], [0.1, 0.1], [0.2, 0.2], [0.0, 2.0])
    with pytest.raises(MuscleModelError, match="duplicate"):
        MuscleParameters(("a", "a"), [1.0, 1.0], [0.1, 0.1], [0.2, 0.2], [0.0, 0.0])


def test_reads_gait2392_muscle_table(ref_dir):
    p = MuscleParameters.from_csv(
        ref_dir / "opensim-models" / "gait2392_thelen2003muscle_muscles.csv"
    )
    assert p.n_muscles == 92
    i = p.names.index("soleus_r")
    assert p.max_isometric_force[i] == pytest.approx(3549.0)
    assert np.all(p.max_contraction_velocity == 10.0)


# --- curves and derivatives ---------------------------------------------------------------------
@pytest.mark.parametrize(
    "curves", [Thelen2003Curves(), Thelen2003Curves.gait2392(), LloydBesierCurves()]
)
@pytest.mark.parametrize(
    "which,grid",
    [
        ("active_force_length", np.linspace(0.4, 1.7, 57)),
        ("passive_force_length", np.linspace(1.003, 1.7, 57)),
        (
            "tendon_force_strain",
            np.r_[np.linspace(1e-4, 0.0199, 30), np.linspace(0.0205, 0.06, 30)],
        ),
    ],
)
def test_analytic_derivatives_match_finite_differences(curves, which, grid):
    f = getattr(curves, which)
    h = 1e-7
    _, d = f(grid)
    fd = (f(grid + h)[0] - f(grid - h)[0]) / (2 * h)
    np.testing.assert_allclose(d, fd, rtol=1e-5, atol=1e-6)


def test_thelen_tendon_reaches_one_at_fmax_strain_and_is_c1():
    c = Thelen2003Curves()
    f, _ = c.tendon_force_strain(c.fmax_tendon_strain)
    assert f == pytest.approx(1.0, abs=1e-12)
    et = c.strain_toe
    assert et == pytest.approx(0.609 * c.fmax_tendon_strain, rel=1e-3)  # the paper's rounding
    f, df = c.tendon_force_strain(np.array([et - 1e-10, et + 1e-10]))
    assert f[0] == pytest.approx(f[1], abs=1e-7)  # continuous
    assert df[0] == pytest.approx(df[1], rel=1e-6)  # and so is its slope (C1)
    assert c.tendon_force_strain(-0.01)[0] == 0.0


def _thelen_velocity(c: Thelen2003Curves, fv: np.ndarray, a: float) -> np.ndarray:
    """Forward Thelen 2003 Eq. 6-7 as OpenSim's calcdlceN writes it (afl = 1): v(f)."""
    k = 0.25 + 0.75 * a
    af, flen = c.af, c.flen
    f0 = c.fv_linear_extrap_threshold * flen

    def v_of(f):
        b = np.where(f <= 1, 1 + f / af, (2 + 2 / af) * (flen - f) / (flen - 1))
        return k * (f - 1) / b

    def dv_of(f):
        b = np.where(f <= 1, 1 + f / af, (2 + 2 / af) * (flen - f) / (flen - 1))
        db = np.where(f <= 1, 1 / af, -(2 + 2 / af) / (flen - 1))
        return k / b - k * (f - 1) / b**2 * db

    inside = (fv > 0) & (fv < f0)
    fe = np.where(fv <= 0, 0.0, f0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(inside, v_of(fv), v_of(fe) + dv_of(fe) * (fv - fe))


@pytest.mark.parametrize("curves", [Thelen2003Curves(), Thelen2003Curves.gait2392()])
@pytest.mark.parametrize("a", [1.0, 0.3])
def test_thelen_force_velocity_inverts_opensim_velocity_law(curves, a):
    f_true = np.r_[np.linspace(-0.3, 0.999, 40), np.linspace(1.001, 2.2, 40)]
    v = _thelen_velocity(curves, f_true, a)
    np.testing.assert_allclose(curves.force_velocity(v, a), f_true, atol=1e-10)
    assert curves.force_velocity(0.0, a) == pytest.approx(1.0)


def test_seed002_curves():
    assert fl_gaussian(1.0) == 1.0
    assert fl_gaussian(1.0 + np.sqrt(0.45)) == pytest.approx(np.exp(-1))
    # Eq. 10 with K = sqrt(0.45) is Thelen's Gaussian of width 0.45
    l = np.linspace(0.5, 1.5, 11)
    np.testing.assert_allclose(fl_gaussian(l), Thelen2003Curves().active_force_length(l)[0])
    v = np.array([-12.0, -10.0, -5.0, 0.0, 2.0, 1e6])
    fv = fv_stroeve(v, v_max=10.0)
    assert fv[0] == 0.0 and fv[1] == pytest.approx(0.0) and fv[3] == 1.0
    assert fv[2] == pytest.approx(0.3 * 5 / (3 + 5))
    assert fv[-1] == pytest.approx(1.3, rel=1e-4)
    assert np.all(np.diff(fv[1:]) > 0)
    p = _params()
    f = reference_force(0.5, p.optimal_fiber_length[None], np.zeros((1, 3)), p)
    np.testing.assert_allclose(f[0], 0.5 * p.max_isometric_force)


def test_seed003_curves_and_eq8():
    c = LloydBesierCurves()
    lo, _ = c.tendon_force_strain(np.array([0.0127 - 1e-9, 0.0127]))
    assert lo[0] == pytest.approx(lo[1], abs=1e-5)  # Eq. 17 meets Eq. 18 (printed rounding)
    assert c.tendon_force_strain(0.033)[0] == pytest.approx(1.0, abs=2e-3)
    assert c.passive_force_length(1.5)[0] == pytest.approx(1.0)  # e^{10·0.5}/e^5
    fv = c.force_velocity(np.array([1.0, 0.0, -1e9]))
    assert fv[0] == pytest.approx(0.0) and fv[1] == 1.0 and fv[2] == pytest.approx(c.f_ecc)
    assert c.optimal_length_scale(0.0) == pytest.approx(1.15)  # Eq. 9, λ = 0.15
    ft = c.tendon_force(0.6, 1.0, 0.0, 0.9, 1000.0)
    assert ft == pytest.approx(1000 * (0.6 + np.exp(-5)) * 0.9)
    # damping adds b_m ṽ (ṽ lengthening = −shortening)
    d = c.tendon_force(0.6, 1.0, -0.1, 1.0, 1.0) - c.tendon_force(0.6, 1.0, 0.0, 1.0, 1.0)
    assert d == pytest.approx(0.6 * (c.force_velocity(-0.1) - 1) + 0.1 * c.damping)


# --- rigid tendon -------------------------------------------------------------------------------
def test_rigid_tendon_recovers_known_fiber_state():
    p = _params()
    rng = np.random.default_rng(0)
    lf = p.optimal_fiber_length * rng.uniform(0.6, 1.4, (50, 3))
    h = p.optimal_fiber_length * np.sin(p.pennation_angle_at_optimal)
    lmt = p.tendon_slack_length + np.sqrt(lf**2 - h**2)
    s = rigid_tendon_state(p, lmt)
    np.testing.assert_allclose(s.fiber_length, lf, rtol=1e-12)
    _, cos_true = pennation_constant_height(lf, p)
    np.testing.assert_allclose(s.cos_pennation, cos_true, rtol=1e-12)
    c = Thelen2003Curves()
    np.testing.assert_allclose(
        s.max_active_force_along_tendon,
        p.max_isometric_force * c.active_force_length(lf / p.optimal_fiber_length)[0] * cos_true,
    )
    # velocity: l̇_f = l̇_MT cos α, checked against the finite difference of l_f(t)
    t = np.linspace(0, 1, 2001)
    lmt_t = (p.tendon_slack_length + 1.0 * p.optimal_fiber_length) + 0.02 * np.sin(2 * np.pi * t)[
        :, None
    ]
    vmt = 0.02 * 2 * np.pi * np.cos(2 * np.pi * t)[:, None] * np.ones((1, 3))
    st_ = rigid_tendon_state(p, lmt_t, vmt)
    fd = np.gradient(st_.fiber_length, t, axis=0)
    np.testing.assert_allclose(st_.fiber_velocity[5:-5], fd[5:-5], atol=1e-5)
    assert np.all(st_.f_velocity[vmt[:, 0] > 0.01, 0] > 1)
    with pytest.raises(MuscleModelError, match="frame 1"):
        rigid_tendon_state(p, np.array([[0.3, 0.3, 0.4], [np.nan, 0.3, 0.4]]))


def test_rigid_tendon_frame_equals_the_batch_state_bit_for_bit():
    """Every branch: short paths (cos α clipped to 0), the fibre-length floor, concentric,
    the concentric extrapolation below f_v = 0, eccentric and its extrapolation."""
    p = _params()
    rng = np.random.default_rng(4)
    lmt = p.tendon_slack_length + p.optimal_fiber_length * rng.uniform(-0.3, 1.6, (400, 3))
    speed = p.optimal_fiber_length * p.max_contraction_velocity
    vmt = speed * rng.uniform(-1.6, 1.6, (400, 3))
    batch = rigid_tendon_state(p, lmt, vmt)
    vn = batch.norm_fiber_velocity
    assert (vn < -1).any() and ((vn > -1) & (vn < 0)).any() and (vn > 0.5).any()
    assert (batch.cos_pennation == 0).any()
    frame = RigidTendonFrame(p)
    for n in range(lmt.shape[0]):
        fa, fp = frame(lmt[n], vmt[n])
        np.testing.assert_array_equal(fa, batch.max_active_force_along_tendon[n])
        np.testing.assert_array_equal(fp, batch.passive_force_along_tendon[n])
    with pytest.raises(MuscleModelError, match="soleus"):
        frame(np.array([0.3, np.nan, 0.4]), np.zeros(3))


# --- elastic tendon equilibrium -----------------------------------------------------------------
@pytest.mark.parametrize("curves", [Thelen2003Curves.gait2392(), LloydBesierCurves()])
def test_equilibrium_matches_independent_root_finder(curves):
    p = _params()
    rng = np.random.default_rng(1)
    lmt = (p.tendon_slack_length + p.optimal_fiber_length) * rng.uniform(0.95, 1.08, (20, 3))
    a = rng.uniform(0.02, 1.0, (20, 3))
    eq = equilibrium(p, lmt, a, curves=curves)
    h = p.optimal_fiber_length * np.sin(p.pennation_angle_at_optimal)
    for i in range(0, 20, 4):
        for j in range(3):

            def r(x, i=i, j=j):
                lf = np.hypot(x, h[j])
                ln = lf / p.optimal_fiber_length[j]
                fm = (
                    a[i, j] * curves.active_force_length(ln)[0] + curves.passive_force_length(ln)[0]
                )
                eps = (lmt[i, j] - x) / p.tendon_slack_length[j] - 1
                return float(fm * x / lf - curves.tendon_force_strain(eps)[0])

            xs = np.linspace(1e-4, lmt[i, j] - p.tendon_slack_length[j], 400)
            rv = np.array([r(x) for x in xs])
            roots = [
                brentq(r, xs[k], xs[k + 1], xtol=1e-14)
                for k in np.flatnonzero(np.sign(rv[:-1]) != np.sign(rv[1:]))
            ]
            x_eq = eq.fiber_length[i, j] * eq.cos_pennation[i, j]
            assert min(abs(x_eq - x0) for x0 in roots) < 1e-9
    # the balance holds: tendon force = fibre force along the tendon
    fib = (eq.active_fiber_force + eq.passive_fiber_force) * eq.cos_pennation
    np.testing.assert_allclose(eq.tendon_force, fib, atol=1e-6)


@pytest.mark.parametrize("curves", [Thelen2003Curves(), LloydBesierCurves()])
def test_force_balance_jacobian_matches_finite_differences(curves):
    from msk.muscles.hill import _balance

    p = _params()
    shape = (7, 3)
    rng = np.random.default_rng(2)
    lopt = np.broadcast_to(p.optimal_fiber_length, shape)
    lts = np.broadcast_to(p.tendon_slack_length, shape)
    fiso = np.broadcast_to(p.max_isometric_force, shape)
    h = lopt * np.sin(p.pennation_angle_at_optimal)
    lmt = (lts + lopt) * rng.uniform(1.0, 1.06, shape)
    x = lopt * rng.uniform(0.8, 1.2, shape)
    a = rng.uniform(0.1, 1.0, shape)
    args = (lmt, a, np.ones(shape), h, lopt, lts, fiso, curves)
    _, dr, _ = _balance(x, *args)
    eps = 1e-8
    fd = (_balance(x + eps, *args)[0] - _balance(x - eps, *args)[0]) / (2 * eps)
    np.testing.assert_allclose(dr, fd, rtol=1e-5)


def test_equilibrium_slack_path_gives_zero_force():
    p = _params()
    lmt = np.array([p.tendon_slack_length * 0.9])
    eq = equilibrium(p, lmt, 1.0)
    np.testing.assert_array_equal(eq.tendon_force, 0.0)


@settings(max_examples=40, deadline=None)
@given(
    scale=st.floats(0.9, 1.15),
    a=st.floats(0.01, 1.0),
)
def test_equilibrium_force_is_bounded_and_increases_with_activation(scale, a):
    p = _params()
    lmt = ((p.tendon_slack_length + p.optimal_fiber_length) * scale)[None]
    lo = equilibrium(p, lmt, a * 0.5)
    hi = equilibrium(p, lmt, a)
    assert np.all(hi.tendon_force >= lo.tendon_force - 1e-6)
    assert np.all(hi.tendon_force >= 0)


# --- OpenSim 4.6 cross-check --------------------------------------------------------------------
_OSIM_BODY = """
import opensim as osim
m = osim.Model(ARGS["model"])
s = m.initSystem()
cs = m.getCoordinateSet()
ms = m.getMuscles()
rows = []
for pose in ARGS["poses"]:
    for name, val in pose["q"].items():
        cs.get(name).setValue(s, val, False)
    for name, val in pose["qdot"].items():
        cs.get(name).setSpeedValue(s, val)
    m.assemble(s)
    m.realizeVelocity(s)
    rig = {n: ms.get(n).calcInextensibleTendonActiveFiberForce(s, 1.0) for n in ARGS["muscles"]}
    vel = {n: ms.get(n).getLengtheningSpeed(s) for n in ARGS["muscles"]}
    for name, val in pose["qdot"].items():
        cs.get(name).setSpeedValue(s, 0.0)
    for act in ARGS["activations"]:
        for n in ARGS["muscles"]:
            ms.get(n).setActivation(s, act)
        m.equilibrateMuscles(s)
        m.realizeDynamics(s)
        for n in ARGS["muscles"]:
            mu = ms.get(n)
            rows.append(dict(muscle=n, act=act, lmt=mu.getLength(s), vmt=vel[n], rigid=rig[n],
                             tendon_force=mu.getTendonForce(s), fiber_length=mu.getFiberLength(s)))
RESULT["rows"] = rows
"""


@pytest.mark.opensim
def test_against_opensim_thelen2003(needs_opensim, ref_dir):
    from msk._runtime.opensim_peer import run_opensim_script

    model = ref_dir / "opensim-models" / "gait2392_thelen2003muscle.osim"
    muscles = [
        "rect_fem_r",
        "vas_lat_r",
        "vas_int_r",
        "med_gas_r",
        "soleus_r",
        "bifemlh_r",
        "tib_ant_r",
        "glut_max1_r",
        "semimem_r",
    ]
    poses = [
        {
            "q": {"hip_flexion_r": 0.5, "knee_angle_r": -0.8, "ankle_angle_r": 0.1},
            "qdot": {"hip_flexion_r": 2.0, "knee_angle_r": -4.0, "ankle_angle_r": 3.0},
        },
        {
            "q": {"hip_flexion_r": -0.2, "knee_angle_r": -0.1, "ankle_angle_r": -0.3},
            "qdot": {"hip_flexion_r": -1.5, "knee_angle_r": 5.0, "ankle_angle_r": -4.0},
        },
    ]
    acts = [0.05, 0.4, 1.0]
    out = run_opensim_script(
        _OSIM_BODY, model=str(model), poses=poses, activations=acts, muscles=muscles
    )["rows"]
    p = MuscleParameters.from_csv(
        ref_dir / "opensim-models" / "gait2392_thelen2003muscle_muscles.csv"
    )
    p = p.subset(muscles)
    curves = Thelen2003Curves.gait2392()
    n = len(out) // len(muscles)
    get = lambda key: np.array([r[key] for r in out]).reshape(n, len(muscles))  # noqa: E731
    eq = equilibrium(p, get("lmt"), get("act"), curves=curves)
    ft = get("tendon_force")
    assert np.all(ft > 1.0)
    np.testing.assert_allclose(eq.tendon_force, ft, rtol=1e-5)  # measured: 1.1e-7
    np.testing.assert_allclose(eq.fiber_length, get("fiber_length"), rtol=1e-6)  # 3e-9
    rs = rigid_tendon_state(p, get("lmt"), get("vmt"), curves=curves)
    assert np.abs(rs.f_velocity - 1).max() > 0.05  # the speeds do exercise the f_v curve
    np.testing.assert_allclose(  # measured: 4e-12
        rs.max_active_force_along_tendon, get("rigid"), rtol=1e-8, atol=1e-9
    )


def test_lloyd_besier_force_velocity_is_finite_at_the_eccentric_pole_speed():
    """The eccentric formula's pole b' = (f_ecc − 1)/(r (1 + a)/b) lies at a *shortening* speed
    (0.08 with the defaults), where the concentric branch answers: no division by zero there
    (found by hypothesis in tests/strength/test_strength_calibration.py)."""
    c = LloydBesierCurves()
    b = c.hill_curvature
    pole = (c.f_ecc - 1.0) / (c.ecc_slope_ratio * (1.0 + c.hill_curvature) / b)
    with np.errstate(all="raise"):
        f = c.force_velocity(np.array([-pole, 0.0, pole]))
    assert np.isfinite(f).all()
    assert f[2] == pytest.approx((b - b * pole) / (b + pole))  # the concentric branch
