"""msk.quality: the body-mass balance and the gates (values against thresholds)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from msk.quality import THRESHOLDS, body_mass_from_loads, gait_flags
from msk.synthetic_models import two_leg_model


def _still(model, n, ty=0.93):
    q = np.zeros((n, len(model.coordinate_names)))
    q[:, model.coordinate_names.index("pelvis_ty")] = ty
    return SimpleNamespace(time=np.arange(n) / 100.0, q=q, v=np.zeros_like(q), a=np.zeros_like(q))


@pytest.mark.parametrize("mass", [55.0, 82.8])
def test_body_mass_balances_the_vertical_reaction(mass):
    model = two_leg_model()
    kin = _still(model, 50)
    g = float(np.linalg.norm(model.gravity))
    force = np.zeros((50, 2, 3))
    force[:, 0, 1] = 0.4 * mass * g
    force[:, 1, 1] = 0.6 * mass * g
    loads = SimpleNamespace(bodies=("foot_r", "foot_l"), force=force)
    assert body_mass_from_loads(model, kin, loads, np.ones(50, bool)) == pytest.approx(mass)
    assert body_mass_from_loads(model, kin, loads, np.zeros(50, bool)) is None


def _flags(model, kin, **quality):
    jt = SimpleNamespace(coordinate_names=kin_names(model), tau=np.zeros_like(kin.q))
    plate = quality.pop("plate", None)
    return gait_flags("walk1", quality=quality, model=model, kinematics=kin, joint_torques=jt,
                      mass_kg=70.0, height_m=1.7, plate_mass_kg=plate)  # fmt: skip


def kin_names(model):
    return tuple(model.coordinate_names)


def test_flags_name_trial_quantity_value_threshold():
    model = two_leg_model()
    kin = _still(model, 50)
    kin.coordinate_names = kin_names(model)
    kin.q[:, model.coordinate_names.index("knee_angle_r")] = np.linspace(-0.1, -0.5, 50)
    flags = _flags(model, kin, ik_marker_rms_mean_m=0.031, residual_force_rms_pct_bw=2.0,
                   plate=80.0)  # fmt: skip
    by = {f.quantity: f for f in flags}
    assert by["ik_marker_rms_mean_m"].value == pytest.approx(0.031)
    assert by["ik_marker_rms_mean_m"].threshold == THRESHOLDS["ik_marker_rms_mean_m"]
    assert "residual_force_rms_pct_bw" not in by
    assert by["plate_mass_difference_pct"].value == pytest.approx(100 * 10 / 70)
    # every still leg coordinate is frozen; the moving knee is not
    assert "ankle_angle_r_std_deg" in by and "knee_angle_r_std_deg" not in by
    assert all(f.trial == "walk1" for f in flags)


def test_no_flag_within_thresholds():
    model = two_leg_model()
    kin = _still(model, 50)
    kin.coordinate_names = kin_names(model)
    rng = np.random.default_rng(0)
    kin.q[:, 6:] += 0.05 * rng.standard_normal((50, kin.q.shape[1] - 6))
    flags = _flags(model, kin, ik_marker_rms_mean_m=0.012, residual_force_rms_pct_bw=3.0,
                   residual_moment_rms_nm=2.0, plate=71.0)  # fmt: skip
    assert flags == []
