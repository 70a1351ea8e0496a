"""InertialIdentifier: recovery of known mass distributions from simulated mocap + force plates.

Ground truth: a whole-body model built in code (Dumas 2007 generic segments, 75 kg, 1.75 m; arms
welded to the thorax), moved along sums of sines on every coordinate (pelvis free). The plates
measure the base-link wrench computed by Pinocchio's RNEA (independent of msk's regressor),
with 1 % of body weight white noise on the forces (and the matching moment noise); the
kinematics carry white noise equivalent to 2 mm markers, low-pass filtered (4 Hz zero-lag
Butterworth, as the plates) and differentiated numerically.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from msk.datasets.models import generic_bodies, subject_bodies, whole_body_model
from msk.datasets.trials import identification_trial
from msk.dynamics.identification import (
    MIRROR_SIGNS,
    BoundingEllipsoid,
    IdentificationTrial,
    InertialIdentifier,
    base_residuals,
    excitation_report,
    lump_subtrees,
    root_generalized_forces,
)
from msk.dynamics.regressors import (
    base_link_regressor,
    external_generalized_forces,
    joint_torque_regressor,
    regressor_layout,
)
from msk.exceptions import IdentificationError
from msk.model.anthropometry import is_physically_consistent
from msk.model.core import Body, Joint, Model

G = 9.80665


@pytest.fixture(scope="module")
def lumped():
    return lump_subtrees(whole_body_model(), ["torso"])


# ------------------------------------------------------------------------------------------
# building blocks
# ------------------------------------------------------------------------------------------
def test_vectorized_regressor_matches_pinocchio_on_whole_body():
    model = whole_body_model()
    rng = np.random.default_rng(1)
    th = rng.uniform(-1, 1, (7, model.n_coords))
    thd, thdd = rng.normal(size=th.shape), rng.normal(size=th.shape)
    layout = regressor_layout(model)
    a = joint_torque_regressor(model, th, thd, thdd, layout=layout)
    b = joint_torque_regressor(model, th, thd, thdd, layout=layout, method="pinocchio")
    np.testing.assert_allclose(a, b, atol=1e-9 * np.abs(b).max())


def test_root_generalized_forces_match_pinocchio_fext():
    model = whole_body_model()
    rng = np.random.default_rng(2)
    th = rng.uniform(-1, 1, (5, model.n_coords))
    fext = np.zeros((5, model.pin_model.njoints, 6))
    data = model.create_data()
    f_w = np.zeros((5, 3))
    m_w = np.zeros((5, 3))
    q = model.coupling.q(th)
    for n in range(5):
        pin.forwardKinematics(model.pin_model, data, q[n])
        for body in ("foot_r", "foot_l", "hand_r"):
            w = pin.Force(rng.normal(scale=200, size=3), rng.normal(scale=20, size=3))
            j = model.body_joint[body]
            fext[n, j] += data.oMi[j].actInv(w).vector
            f_w[n] += w.linear
            m_w[n] += w.angular
    ref = external_generalized_forces(model, th, fext)[:, :6]
    np.testing.assert_allclose(root_generalized_forces(model, th, f_w, m_w), ref, atol=1e-9)


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_lumped_model_has_the_same_base_link_dynamics(seed):
    full = whole_body_model()
    lm = lump_subtrees(full, ["torso"])
    assert {b.name for b in lm.model.bodies} == {
        "pelvis", "torso", "femur_r", "femur_l", "tibia_r", "tibia_l", "foot_r", "foot_l"
    }  # fmt: skip
    assert "arm_flex_r" not in lm.model.coordinate_names
    rng = np.random.default_rng(seed)
    th = rng.uniform(-1, 1, (4, lm.model.n_coords))
    thd, thdd = rng.normal(size=th.shape), rng.normal(size=th.shape)
    y_id = base_link_regressor(lm.model, th, thd, thdd)
    y_full = base_link_regressor(full, lm.expand(th), _expand0(lm, thd), _expand0(lm, thdd))
    phi_id = regressor_layout(lm.model).parameters(lm.model)
    phi_full = regressor_layout(full).parameters(full)
    np.testing.assert_allclose(y_id @ phi_id, y_full @ phi_full, rtol=1e-9, atol=1e-8)
    np.testing.assert_allclose(lm.model.total_mass, full.total_mass)


def _expand0(lm, x):
    out = np.zeros((x.shape[0], lm.source.n_coords))
    out[:, lm.coordinate_index] = x
    return out


def test_redistribution_of_generic_lump_is_identity_and_preserves_scaled_lump(lumped):
    phi_l = lumped.lumped_parameters()["torso"]
    back = lumped.redistribute({"torso": phi_l})
    for b in lumped.members["torso"]:
        np.testing.assert_allclose(
            back.body(b).parameters(), lumped.source.body(b).parameters(), rtol=1e-4, atol=1e-5
        )
    # a heavier lump whose COM moved 1 cm forward: mass exact, COM and inertia matched
    target = phi_l * 1.1
    target[1] += target[0] * 0.01
    new = lumped.redistribute({"torso": target})
    got = lumped.lumped_parameters(new)["torso"]
    assert got[0] == pytest.approx(target[0], rel=1e-8)
    np.testing.assert_allclose(got[1:4] / got[0], target[1:4] / target[0], atol=5e-4)
    np.testing.assert_allclose(got[4:], target[4:], rtol=0.02, atol=0.01)
    for b in lumped.members["torso"]:
        assert is_physically_consistent(new.body(b).parameters())
        ratio = new.body(b).mass / lumped.source.body(b).mass
        assert ratio == pytest.approx(1.1, rel=1e-6)


def test_bounding_ellipsoid_contains_its_own_uniform_solid():
    phi = generic_bodies()["femur_r"].parameters()
    from msk.model.anthropometry import pseudo_inertia

    q = BoundingEllipsoid.from_parameters(phi, scale=1.0).q_matrix()
    # uniform solid ellipsoid: tr(QJ) = m (1 − 3/5)
    assert np.trace(q @ pseudo_inertia(phi)) == pytest.approx(0.4 * phi[0], rel=1e-6)


# ------------------------------------------------------------------------------------------
# recovery of known subjects
# ------------------------------------------------------------------------------------------
def _fit(lm, trials, total_mass, **kw):
    # prior: the generic tables scaled to the measured mass (as in practice)
    scale = total_mass / lm.model.total_mass
    prior = {b.name: b.parameters() * scale for b in lm.model.bodies}
    return InertialIdentifier(lm.model, total_mass=total_mass, prior=prior, **kw).fit(
        [lm.restrict_trial(t) for t in trials]
    )


@pytest.mark.parametrize("kind", ["athlete", "elderly"])
def test_recovers_well_identified_segments_and_halves_held_out_residuals(lumped, kind):
    truth = whole_body_model(subject_bodies(kind))
    lm_truth = lump_subtrees(truth, ["torso"])
    true_phi = {b.name: b.parameters() for b in lm_truth.model.bodies}
    train = [identification_trial(truth, 15.0, seed, name=f"{kind}{seed}") for seed in (11, 12)]
    ident = _fit(lumped, train, truth.total_mass)
    # every segment consistent, symmetric, total mass exact
    for name, phi in ident.parameters_.items():
        assert is_physically_consistent(phi), name
    np.testing.assert_allclose(
        ident.parameters_["femur_l"], MIRROR_SIGNS * ident.parameters_["femur_r"], atol=1e-9
    )
    assert sum(p[0] for p in ident.parameters_.values()) == pytest.approx(truth.total_mass, 1e-6)
    # the upper-body lump is well identified; every well-identified segment is recovered within
    # 5 % (mass) and 1 cm (COM), and better than the scaled tables
    well = [s for s in ident.segments_ if s.flag == "well identified"]
    assert "torso" in {s.name for s in well}, ident.summary()
    for s in well:
        m_true = true_phi[s.name][0]
        c_true = true_phi[s.name][1:4] / m_true
        assert abs(s.mass - m_true) / m_true < 0.05, (s.name, s.mass, m_true)
        assert np.linalg.norm(s.com - c_true) < 0.01, (s.name, s.com, c_true)
    t = _idx(ident, "torso")
    assert abs(ident.phi_[10 * t] - true_phi["torso"][0]) < 0.5 * abs(
        ident.prior_[10 * t] - true_phi["torso"][0]
    )
    # the other segments: the truth lies within 4 posterior standard deviations (calibrated)
    for s in ident.segments_:
        m_true = true_phi[s.name][0]
        assert abs(s.mass - m_true) < 4 * s.mass_std + 0.05 * m_true, (s.name, s.mass, m_true)
    # held-out trial (other motion): pelvis residuals with the identified model vs the scaled
    # anthropometric one, without measurement noise (the part due to the parameters) and with
    # it (then the noise floor, ~8 N and ~5 N·m here, limits the reduction)
    scaled = lumped.source.with_inertias(
        {b.name: b.parameters() * truth.total_mass / lumped.source.total_mass
         for b in lumped.source.bodies}
    )  # fmt: skip
    identified = ident.to_model(lumped)
    clean = [identification_trial(truth, 8.0, 99, marker_noise_m=0.0, plate_noise=0.0)]
    before, after = base_residuals(scaled, clean), base_residuals(identified, clean)
    assert after.force_rms_n < 0.5 * before.force_rms_n, (before, after)
    assert after.moment_rms_nm < 0.5 * before.moment_rms_nm, (before, after)
    noisy = [identification_trial(truth, 8.0, 99)]
    before, after = base_residuals(scaled, noisy), base_residuals(identified, noisy)
    assert after.force_rms_n < before.force_rms_n, (before, after)
    assert after.moment_rms_nm < before.moment_rms_nm, (before, after)
    # the redistributed full model carries the identified lump
    lump = lumped.lumped_parameters(ident.to_model(lumped))["torso"]
    assert lump[0] == pytest.approx(ident.parameters_["torso"][0], rel=1e-6)


def _idx(ident, name):
    return [s.name for s in ident.segments_].index(name)


def test_clarabel_and_ipopt_agree_and_kkt_without_active_constraints(lumped):
    truth = whole_body_model(subject_bodies("athlete"))
    trial = lumped.restrict_trial(identification_trial(truth, 6.0, 5))
    kw = {"noise_std": np.array([7.0, 7.0, 7.0, 3.0, 3.0, 3.0]), "bounding_ellipsoids": None}
    a = InertialIdentifier(lumped.model, total_mass=truth.total_mass, **kw).fit(trial)
    b = InertialIdentifier(lumped.model, total_mass=truth.total_mass, solver="ipopt", **kw).fit(
        trial
    )
    # same optimum (ipopt has no ε margin on J, so it may be marginally lower)
    hx, gx = a._x_system(a.noise_std_)
    obj = lambda x: x @ (hx + np.eye(x.size)) @ x - 2 * (gx + a._x_prior) @ x  # noqa: E731
    assert abs(obj(a.x_) - obj(b.x_)) < 1e-5 * abs(obj(a.x_))
    masses = slice(0, None, 10)
    np.testing.assert_allclose(a.phi_[masses], b.phi_[masses], rtol=0.02)
    # without constraints the solution is the Gaussian posterior mean (H + I) x = g + x_prior
    # (noise-free data and a tight prior keep every segment strictly inside the consistent set)
    from msk.dynamics.identification import default_prior_std

    tight = {b.name: 0.05 * default_prior_std(b.parameters()) for b in lumped.model.bodies}
    clean = lumped.restrict_trial(
        identification_trial(truth, 6.0, 5, marker_noise_m=0.0, plate_noise=0.0)
    )
    c = InertialIdentifier(lumped.model, prior_std=tight, **kw).fit(clean)
    hx, gx = c._x_system(c.noise_std_)
    x_ref = np.linalg.solve(hx + np.eye(hx.shape[0]), gx + c._x_prior)
    np.testing.assert_allclose(c.x_, x_ref, rtol=1e-5, atol=1e-6)


def test_fixed_segments_stay_at_prior_and_bad_input_is_named(lumped):
    truth = whole_body_model(subject_bodies("elderly"))
    trial = lumped.restrict_trial(identification_trial(truth, 4.0, 3))
    ident = InertialIdentifier(lumped.model, fixed=("foot_r", "foot_l")).fit(trial)
    np.testing.assert_array_equal(
        ident.parameters_["foot_r"], lumped.model.body("foot_r").parameters()
    )
    assert ident.flags_["foot_r"] == "prior"
    with pytest.raises(IdentificationError, match="foot_r"):
        InertialIdentifier(lumped.model, fixed=("foot_r",)).fit(trial)
    with pytest.raises(IdentificationError, match="columns"):
        InertialIdentifier(lumped.model).fit(
            IdentificationTrial(
                trial.theta[:, :5], trial.theta_dot[:, :5], trial.theta_ddot[:, :5], trial.tau_ext
            )
        )
    with pytest.raises(IdentificationError, match="not fitted"):
        InertialIdentifier(lumped.model).predict(trial.theta, trial.theta_dot, trial.theta_ddot)


def test_standing_still_is_flagged_and_stays_at_prior(lumped):
    truth = whole_body_model(subject_bodies("athlete"))
    still = tuple(c.name for c in truth.coordinates)
    trial = lumped.restrict_trial(identification_trial(truth, 3.0, 8, still=still))
    ident = InertialIdentifier(lumped.model, total_mass=truth.total_mass).fit(trial)
    assert ident.flags_["femur_r"] in ("prior", "weakly identified")
    assert ident.weak_directions_ and ident.advice()
    assert ident.condition_number_ > 1e3 or not np.isfinite(ident.condition_number_)
    # unexcited inertias stay at the prior
    i = _idx(ident, "tibia_r")
    np.testing.assert_allclose(ident.phi_[10 * i + 4], ident.prior_[10 * i + 4], rtol=0.05)
    for phi in ident.parameters_.values():
        assert is_physically_consistent(phi)


@settings(
    max_examples=8, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    seed=st.integers(0, 2**31 - 1),
    factors=st.lists(st.floats(0.6, 1.5), min_size=4, max_size=4),
    duration=st.floats(0.8, 3.0),
    noise=st.floats(0.0, 0.05),
)
def test_identified_segments_are_always_physically_consistent(
    lumped, seed, factors, duration, noise
):
    gen = generic_bodies()
    bodies = dict(gen)
    for name, f in zip(("femur_r", "tibia_r", "torso", "pelvis"), factors):
        b = gen[name]
        bodies[name] = Body(name, b.mass * f, b.com * f, b.inertia * f)
    truth = whole_body_model(bodies)
    trial = lumped.restrict_trial(
        identification_trial(truth, duration, seed, plate_noise=noise, cutoff_hz=8.0)
    )
    ident = InertialIdentifier(lumped.model, total_mass=truth.total_mass).fit(trial)
    for name, phi in ident.parameters_.items():
        assert is_physically_consistent(phi), (name, phi)
    assert np.all(np.isfinite(ident.std_))


@pytest.mark.slow
@pytest.mark.realdata
def test_real_subject01_walk_split_halves(real_dir, ref_dir):
    """OpenSim subject01 walk (gait10dof18musc, OpenSim's IK angles, two plates): identify on the
    first half, compare pelvis residuals on the held-out second half; total mass vs the plates."""
    from msk.dynamics.loads import external_loads, plates_from_table
    from msk.io.opensim_files import read_sto
    from msk.kinematics.ik import kinematics_from_coordinates
    from msk.model.osim import load_osim

    folder = real_dir / "opensim-subject01-walk"
    osim = ref_dir / "opensim-core" / "gait10dof18musc_subject01.osim"
    if not folder.is_dir() or not osim.is_file():
        pytest.skip("subject01 walk or gait10dof18musc model absent")
    model = load_osim(osim)
    ik = read_sto(folder / "subject01_walk_IK.mot")
    grf = read_sto(folder / "subject01_walk_grf.mot")
    kin = kinematics_from_coordinates(ik.time, ik.data, ik.columns, cutoff_hz=6.0, model=model)
    loads = external_loads(model, kin, plates_from_table(grf.time, grf.data, grf.columns))
    whole = IdentificationTrial.from_loads(model, kin, loads, name="subject01_walk")
    n = whole.n_frames
    inner = np.arange(n)[(kin.time > kin.time[0] + 0.1) & (kin.time < kin.time[-1] - 0.1)]
    half = inner[inner.size // 2]
    pick = lambda idx, name: IdentificationTrial(  # noqa: E731
        whole.theta[idx], whole.theta_dot[idx], whole.theta_ddot[idx], whole.tau_ext[idx], name
    )
    train = pick(inner[inner < half], "first half")
    test = pick(inner[inner >= half], "second half")
    ident = InertialIdentifier(model).fit(train)
    for name, phi in ident.parameters_.items():
        assert is_physically_consistent(phi), name
    before = base_residuals(model, test)
    after = ident.score(test)
    force, _ = loads.total()
    plate_mass = float(np.mean(force[inner, 1]) / G)
    m_id = sum(p[0] for p in ident.parameters_.values())
    print(
        f"\nsubject01: model mass {model.total_mass:.2f} kg, plates {plate_mass:.2f} kg, "
        f"identified {m_id:.2f} kg; held-out pelvis residual force RMS "
        f"{before.force_rms_n:.1f} → {after.force_rms_n:.1f} N, moment "
        f"{before.moment_rms_nm:.1f} → {after.moment_rms_nm:.1f} N·m\n{ident.summary()}"
    )
    assert abs(m_id - plate_mass) < 0.1 * plate_mass


@pytest.mark.slow
@pytest.mark.realdata
def test_real_subject01_gait2392_msk_ik_lumped_feet():
    """gait2392 subject01 walk1 through msk's own pipeline (markers → msk IK → plates → loads),
    feet (calcn + toes) lumped; identify on the first half, held-out second half."""
    from msk.datasets.opensim_subject01 import load_subject01
    from msk.dynamics.loads import external_loads
    from msk.kinematics.ik import kinematics_from_coordinates, solve_kinematics

    try:
        s = load_subject01()
    except FileNotFoundError as exc:  # pragma: no cover - depends on the shared folder
        pytest.skip(f"OpenSim subject01 pipeline data absent: {exc}")
    sel = (s.trc_time >= 0.5 - 1e-6) & (s.trc_time <= 2.5 + 1e-6)
    kin = solve_kinematics(
        s.model, s.markers[sel], s.marker_labels, s.trc_time[sel],
        weights=s.weights, coordinate_tasks=s.coordinate_tasks,
    )  # fmt: skip
    kin = kinematics_from_coordinates(kin.time, kin.q_raw, s.model.coordinate_names, cutoff_hz=6.0)
    loads = external_loads(s.model, kin, s.plates)
    lm = lump_subtrees(s.model, ["calcn_r", "calcn_l"])
    whole = lm.restrict_trial(IdentificationTrial.from_loads(s.model, kin, loads))
    n = whole.n_frames
    idx = np.arange(5, n - 5)
    half = idx[idx.size // 2]

    def pick(ix):
        return IdentificationTrial(
            whole.theta[ix], whole.theta_dot[ix], whole.theta_ddot[ix], whole.tau_ext[ix]
        )

    train, test = pick(idx[idx < half]), pick(idx[idx >= half])
    ident = InertialIdentifier(lm.model).fit(train)
    for name, phi in ident.parameters_.items():
        assert is_physically_consistent(phi), name
    full = ident.to_model(lm)
    force, _ = loads.total()
    plate_mass = float(np.mean(force[idx, 1]) / G)
    m_id = full.total_mass
    before = base_residuals(s.model, [_full_trial(lm, test)])
    after = base_residuals(full, [_full_trial(lm, test)])
    print(
        f"\ngait2392 subject01 (msk IK): model {s.model.total_mass:.2f} kg, plates "
        f"{plate_mass:.2f} kg, identified {m_id:.2f} kg; held-out pelvis residual force RMS "
        f"{before.force_rms_n:.1f} → {after.force_rms_n:.1f} N, moment "
        f"{before.moment_rms_nm:.1f} → {after.moment_rms_nm:.1f} N·m\n{ident.summary()}"
    )
    assert abs(m_id - plate_mass) < 0.1 * plate_mass
    assert after.force_rms_n < before.force_rms_n


def _full_trial(lm, trial):
    """An identification-model trial as a source-model trial (removed coordinates at θ_ref)."""
    return IdentificationTrial(
        lm.expand(trial.theta), _expand0(lm, trial.theta_dot), _expand0(lm, trial.theta_ddot),
        trial.tau_ext,
    )  # fmt: skip


def test_massless_bodies_stay_massless():
    base = whole_body_model()
    model = Model(
        name="with_virtual",
        bodies=[*base.bodies, Body("virtual", 0.0)],
        joints=[*base.joints, Joint("virtual_weld", "torso", "virtual")],
        coordinates=base.coordinates,
    )
    lm = lump_subtrees(model, ["torso"])
    trial = lm.restrict_trial(identification_trial(model, 2.0, 4))
    ident = InertialIdentifier(lm.model, total_mass=model.total_mass).fit(trial)
    full = ident.to_model(lm)
    np.testing.assert_array_equal(full.body("virtual").parameters(), np.zeros(10))
    assert full.total_mass == pytest.approx(model.total_mass, rel=1e-6)
    # unlumped: the massless body is held at zero and flagged "prior"
    ident = InertialIdentifier(model).fit(identification_trial(model, 2.0, 4))
    assert ident.flags_["virtual"] == "prior"
    np.testing.assert_array_equal(ident.parameters_["virtual"], np.zeros(10))
    assert ident.to_model().body("virtual").mass == 0.0


# ------------------------------------------------------------------------------------------
# prior weight by cross-validation (issue 19) and the excitation report
# ------------------------------------------------------------------------------------------
def _mass_errors(ident, truth_lm):
    true_phi = {b.name: b.parameters() for b in truth_lm.model.bodies}
    return {
        s.name: (abs(s.mass - true_phi[s.name][0]), abs(s.prior_mass - true_phi[s.name][0]))
        for s in ident.segments_
    }


@pytest.mark.parametrize(("kind", "seconds"), [("athlete", 15.0), ("elderly", 4.0)])
def test_cv_prior_weight_is_never_worse_than_prior_only_held_out(lumped, kind, seconds):
    truth = whole_body_model(subject_bodies(kind))
    train = [identification_trial(truth, seconds, seed, name=f"{kind}{seed}") for seed in (31, 32)]
    ident = _fit(lumped, train, truth.total_mass, prior_weight="cv")
    cv = ident.cv_scores_
    assert cv is not None and cv.folds == (f"{kind}31", f"{kind}32")  # leave one trial out
    assert ident.prior_weight_ == cv.weights[cv.selected]
    po = cv.prior_only
    assert np.isinf(cv.weights[po]) and cv.score[po] == 1.0
    # the selection is admissible: neither pooled held-out residual above prior only's
    assert cv.force_rms_n[cv.selected] <= cv.force_rms_n[po] + 1e-9
    assert cv.moment_rms_nm[cv.selected] <= cv.moment_rms_nm[po] + 1e-9
    assert cv.fold_force_rms_n.shape == (cv.weights.size, 2)
    assert sum(p[0] for p in ident.parameters_.values()) == pytest.approx(truth.total_mass, 1e-6)
    for phi in ident.parameters_.values():
        assert is_physically_consistent(phi)
    # an unseen trial of another motion: not worse than the prior at the total mass (the
    # generic model at the measured mass) beyond the noise (2 %)
    test = [lumped.restrict_trial(identification_trial(truth, 8.0, 99))]
    scale = truth.total_mass / lumped.model.total_mass
    prior_only = base_residuals(
        lumped.model, test, {b.name: scale * b.parameters() for b in lumped.model.bodies}
    )
    got = ident.score(test)
    assert got.force_rms_n <= 1.02 * prior_only.force_rms_n, (got, prior_only)
    assert got.moment_rms_nm <= 1.02 * prior_only.moment_rms_nm, (got, prior_only)


def test_cv_by_blocks_and_prior_only_when_the_data_say_nothing(lumped):
    truth = whole_body_model(subject_bodies("athlete"))
    # standing still: only the total mass and the horizontal COM are seen
    still = tuple(c.name for c in truth.coordinates)
    trial = identification_trial(truth, 4.0, 8, still=still, plate_noise=0.03)
    ident = _fit(lumped, [trial], truth.total_mass, prior_weight="cv", cv_folds=4)
    cv = ident.cv_scores_
    assert cv.folds == tuple(f"block {i}/4" for i in range(1, 5))
    assert sum(cv.fold_frames) == ident.n_frames_
    assert cv.force_rms_n[cv.selected] <= cv.force_rms_n[cv.prior_only] + 1e-9
    # fixed weights: ∞ is the prior scaled to the total mass exactly
    po = _fit(lumped, [trial], truth.total_mass, prior_weight=math.inf)
    scale = truth.total_mass / lumped.model.total_mass
    for b in lumped.model.bodies:
        np.testing.assert_allclose(po.parameters_[b.name], scale * b.parameters(), rtol=1e-9,
                                   atol=1e-12)  # fmt: skip
    assert set(po.flags_.values()) == {"prior"} and po.cv_scores_ is None
    with pytest.raises(IdentificationError, match="prior_weight"):
        InertialIdentifier(lumped.model, prior_weight=-1.0).fit(lumped.restrict_trial(trial))
    with pytest.raises(IdentificationError, match="2 trials"):
        InertialIdentifier(lumped.model, prior_weight="cv", cv_by="trials").fit(
            lumped.restrict_trial(trial)
        )


def test_rich_excitation_with_cv_recovers_segments_better_than_the_prior(lumped):
    """Measured per segment (synthetic athlete: thighs and shanks +20 % mass, COM shifted 2 cm;
    2 × 15 s of sums of sines on every coordinate, 1 % plate noise)."""
    truth = whole_body_model(subject_bodies("athlete"))
    train = [identification_trial(truth, 15.0, seed, name=str(seed)) for seed in (11, 12)]
    ident = _fit(lumped, train, truth.total_mass, prior_weight="cv")
    err = _mass_errors(ident, lump_subtrees(truth, ["torso"]))
    # the segments the motion excites (torso lump, thighs, shanks) move toward the truth (the
    # torso lump: mass error at most half the prior's)
    for name in ("torso", "femur_r", "tibia_r"):
        got, prior = err[name]
        assert got < prior, (name, got, prior, ident.summary())
    assert err["torso"][0] < 0.5 * err["torso"][1]
    # the summed absolute mass error is below the prior's
    assert sum(e[0] for e in err.values()) < 0.6 * sum(e[1] for e in err.values())


def test_excitation_report_names_segments_and_motions_from_the_regressor(lumped):
    truth = whole_body_model(subject_bodies("athlete"))
    still = tuple(c.name for c in truth.coordinates)
    trial = lumped.restrict_trial(identification_trial(truth, 3.0, 8, still=still))
    rep = excitation_report(lumped.model, trial, total_mass=truth.total_mass)
    assert {s.name for s in rep.segments} == {
        "pelvis", "torso", "femur_r/femur_l", "tibia_r/tibia_l", "foot_r/foot_l"
    }  # fmt: skip
    foot = rep.segment("foot_l")
    assert foot.poorly_excited and foot.mass_std_ratio > 0.9
    # the foot is excited by moving the ankle with the leg free, the trunk lump by the trunk
    assert "ankle" in foot.suggestions[0][0] and "leg free" in foot.suggestions[0][0]
    assert "trunk" in rep.segment("torso").suggestions[0][0]
    assert (
        rep.segment("tibia_r").suggestions[0][0].split(":")[1].strip().startswith(("knee", "hip"))
    )
    text = str(rep)
    assert "poorly excited" in text and "foot_r/foot_l" in text
    # rich motion: the torso lump and thighs are excited (mass and COM std < 0.7 × prior)
    rich = _fit(lumped, [identification_trial(truth, 15.0, 11)], truth.total_mass).excitation(
        suggest=False
    )
    for body in ("torso", "femur_r"):
        s = rich.segment(body)
        assert not s.poorly_excited and s.n_excited >= 4, str(rich)
        assert np.all(np.diff(s.information) >= 0)


def test_identified_model_applies_segments_by_status():
    """``by_status``: only a segment whose status is identified takes its identified inertia;
    ``all`` (the default) applies every one; the summary's list says which."""
    from msk.dynamics.identification import (
        MassIdentification,
        applied_segments,
        identified_model,
    )

    model = whole_body_model(generic_bodies())
    names = [b.name for b in model.bodies]
    heavier = {b.name: b.parameters() * 1.1 for b in model.bodies}
    status = {names[0]: "identified", names[1]: "not determined"}
    ident = MassIdentification(
        parameters=heavier,
        segments=[{"name": n, "status": status.get(n, "prior")} for n in names],
        condition_number=1.0, n_frames=10, advice=(), t0=0.0,
    )  # fmt: skip
    some = identified_model(model, ident, by_status=True)
    assert some.body(names[0]).mass == pytest.approx(1.1 * model.body(names[0]).mass)
    assert some.body(names[1]).mass == model.body(names[1]).mass  # not determined: the prior
    every = identified_model(model, ident)
    assert all(every.body(n).mass == pytest.approx(1.1 * model.body(n).mass) for n in names)
    assert applied_segments(ident, by_status=True) == [names[0]]
    assert applied_segments(ident) == sorted(names)
    assert identified_model(model, None) is model
