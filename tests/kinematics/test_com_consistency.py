"""msk.kinematics.com_consistency: the whole-body COM acceleration made consistent with the plates'
filter.

Known truth: a running-like motion of the two-leg model (strides at 1.4 Hz: hips ±57°, knees
to 86°; a pelvis bouncing at 2.8 Hz, turning, at 4 m/s) whose ground reaction is exactly
M (a_G − g); the plates' signal is low-passed like θ at 6 Hz. Low-passing θ (the coordinates
domain) leaves a residual force the truth does not have; the segment-COM domain removes it (to
the differentiation's round-off) without touching θ, θ̇ or any joint's θ̈.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msk.datasets.models import two_leg_model
from msk.kinematics.com_consistency import (
    com_accelerations,
    com_consistent_kinematics,
    low_passed_com_accelerations,
    root_translation_coordinates,
)
from msk.kinematics.ik import filtered_derivatives, kinematics_from_coordinates

RATE_HZ = 250.0
CUTOFF_HZ = 6.0


@pytest.fixture(scope="module")
def model():
    return two_leg_model()


def _motion(model, t: np.ndarray, speed: float = 1.0):
    """Analytic θ(t), θ̇(t), θ̈(t): each coordinate a_i + b_i sin(ω_i t + φ_i) (+ forward
    progression); ``speed`` scales every frequency."""
    names = model.coordinate_names
    k = len(names)
    amp = np.zeros(k)
    freq = np.zeros(k)
    phase = np.zeros(k)
    mean = model.default_coordinates().copy()
    spec = {
        "pelvis_ty": (0.03, 2.8, 0.0),
        "pelvis_tz": (0.02, 1.4, 0.3),
        "pelvis_tilt": (0.08, 2.8, 0.5),
        "pelvis_list": (0.06, 1.4, 1.0),
        "pelvis_rotation": (0.15, 1.4, 0.2),
        "hip_flexion_r": (1.0, 1.4, 0.0),
        "hip_flexion_l": (1.0, 1.4, np.pi),
        "hip_adduction_r": (0.1, 1.4, 0.4),
        "hip_adduction_l": (0.1, 1.4, np.pi + 0.4),
        "hip_rotation_r": (0.1, 1.4, 0.9),
        "knee_angle_r": (0.75, 1.4, 1.2),
        "knee_angle_l": (0.75, 1.4, np.pi + 1.2),
        "ankle_angle_r": (0.3, 1.4, 2.0),
        "ankle_angle_l": (0.3, 1.4, np.pi + 2.0),
    }
    for name, (a, f, p) in spec.items():
        i = names.index(name)
        amp[i], freq[i], phase[i] = a, 2 * np.pi * f * speed, p
    for side in ("r", "l"):
        mean[names.index(f"knee_angle_{side}")] = -0.75  # flexion negative: 0…−86°
    arg = freq[None, :] * t[:, None] + phase[None, :]
    th = mean[None, :] + amp[None, :] * np.sin(arg)
    thd = amp[None, :] * freq[None, :] * np.cos(arg)
    thdd = -amp[None, :] * freq[None, :] ** 2 * np.sin(arg)
    tx = names.index("pelvis_tx")
    th[:, tx] = 4.0 * speed * t
    thd[:, tx] = 4.0 * speed
    thdd[:, tx] = 0.0
    return th, thd, thdd


def _pin_com_acceleration(model, th, thd, thdd) -> np.ndarray:
    """Pinocchio's whole-body COM acceleration (``centerOfMass`` with v, a): the reference."""
    data = model.pin_model.createData()
    q, v, a = model.coupling.embed(th, thd, thdd)
    out = np.empty((th.shape[0], 3))
    for k in range(th.shape[0]):
        pin.centerOfMass(model.pin_model, data, q[k], v[k], a[k])
        out[k] = data.acom[0]
    return out


def _masses(model) -> np.ndarray:
    return np.array([b.mass for b in model.bodies if b.mass > 0 and model.body_joint[b.name] > 0])


def test_root_translation_coordinates_are_the_pelvis_translations(model):
    # the knee's coupled translations move only the shank and foot: not the root's
    assert root_translation_coordinates(model) == ("pelvis_tx", "pelvis_ty", "pelvis_tz")


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_com_accelerations_match_pinocchio_and_are_linear_in_theta_ddot(model, seed):
    rng = np.random.default_rng(seed)
    k = model.n_coords
    th = model.default_coordinates()[None, :] + 0.4 * rng.standard_normal((3, k))
    thd = 2.0 * rng.standard_normal((3, k))
    thdd = 20.0 * rng.standard_normal((3, k))
    acc, jac = com_accelerations(model, th, thd, thdd)
    m = _masses(model)
    whole = np.einsum("kbi,b->ki", acc, m) / m.sum()
    np.testing.assert_allclose(whole, _pin_com_acceleration(model, th, thd, thdd), atol=1e-9)
    # a_b is affine in θ̈ with slope J_b: a step along every coordinate at once
    step = rng.standard_normal((3, k))
    acc2, _ = com_accelerations(model, th, thd, thdd + step)
    np.testing.assert_allclose(acc2 - acc, np.einsum("kbij,kj->kbi", jac, step), atol=1e-9)
    # a subset of the columns, in the order asked: those of the whole Jacobian
    _, sub = com_accelerations(model, th, thd, thdd, columns=[7, 0, 2])
    np.testing.assert_array_equal(sub, jac[..., [7, 0, 2]])


def _known_truth(model, speed: float):
    t = np.arange(0.0, 1.6, 1.0 / RATE_HZ)
    th, thd, thdd = _motion(model, t, speed)
    mass = model.total_mass
    g = np.asarray(model.gravity)
    force = mass * (_pin_com_acceleration(model, th, thd, thdd) - g)  # the plates read this
    force_f = filtered_derivatives(t, force, CUTOFF_HZ, 4)[0]  # low-passed like θ
    kin = kinematics_from_coordinates(t, th, model.coordinate_names, cutoff_hz=CUTOFF_HZ)
    # the ends (two periods of the cut-off) are padded differently for the plates and the COMs
    edge = int(2 * RATE_HZ / CUTOFF_HZ)
    inner = slice(edge, t.size - edge)

    def residual(k) -> float:
        a_g = _pin_com_acceleration(model, k.q, k.v, k.a)
        r = mass * (a_g - g) - force_f
        return float(np.sqrt(np.mean(np.sum(r[inner] ** 2, axis=1))) / (mass * np.linalg.norm(g)))

    return kin, residual


def test_known_truth_residual_of_the_filter_domain_is_removed(model):
    kin, residual = _known_truth(model, speed=1.0)
    fixed = com_consistent_kinematics(model, kin)
    before, after = residual(kin), residual(fixed)
    assert before > 0.02, before  # the coordinates' domain: > 2 % BW where the truth has none
    assert after < 0.05 * before, (before, after)
    # θ and θ̇ untouched, and every joint's θ̈: only the root's translations change
    np.testing.assert_array_equal(fixed.q, kin.q)
    np.testing.assert_array_equal(fixed.v, kin.v)
    moved = np.flatnonzero(np.any(fixed.a != kin.a, axis=0))
    names = {model.coordinate_names[i] for i in moved}
    assert names <= {"pelvis_tx", "pelvis_ty", "pelvis_tz"}, names
    assert fixed.metadata["acceleration_domain"] == "segment_com"


def test_slow_motion_is_barely_changed(model):
    """A slow movement's COM of low-passed θ is the low-passed COM: little to correct."""
    kin, _ = _known_truth(model, speed=0.25)
    fast, _ = _known_truth(model, speed=1.0)
    change = np.nanmax(np.abs(com_consistent_kinematics(model, kin).a - kin.a))
    change_fast = np.nanmax(np.abs(com_consistent_kinematics(model, fast).a - fast.a))
    assert change < 0.05 * change_fast, (change, change_fast)


def test_whole_body_com_follows_the_low_passed_segment_coms(model):
    kin, _ = _known_truth(model, speed=1.0)
    fixed = com_consistent_kinematics(model, kin)
    target = low_passed_com_accelerations(model, kin)
    m = _masses(model)
    want = np.einsum("kbi,b->ki", target, m) / m.sum()
    got = _pin_com_acceleration(model, fixed.q, fixed.v, fixed.a)
    np.testing.assert_allclose(got, want, atol=1e-9)


def test_gaps_stay_nan_and_no_cutoff_is_a_no_op(model):
    kin, _ = _known_truth(model, speed=1.0)
    q_raw = kin.q_raw.copy()
    q_raw[100:110] = np.nan
    gappy = kinematics_from_coordinates(kin.time, q_raw, model.coordinate_names, cutoff_hz=6.0)
    fixed = com_consistent_kinematics(model, gappy)
    assert np.isnan(fixed.a[100:110]).all()
    assert np.isfinite(fixed.a[:100]).all() and np.isfinite(fixed.a[110:]).all()
    raw = dataclasses.replace(kin, cutoff_hz=None)
    assert com_consistent_kinematics(model, raw) is raw


def test_blocks_give_the_one_pass_result(model, monkeypatch):
    """A long trial is processed in blocks of frames (issue 18): the same numbers."""
    import msk.kinematics.com_consistency as cc

    kin, _ = _known_truth(model, speed=1.0)
    whole = com_consistent_kinematics(model, kin)
    monkeypatch.setattr(cc, "BLOCK", 37)
    np.testing.assert_array_equal(com_consistent_kinematics(model, kin).a, whole.a)
