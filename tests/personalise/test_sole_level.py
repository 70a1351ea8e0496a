"""msk.personalise.sole_level: the ankle's gauge of a motion placement set by "sole level at foot
flat"."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from msk.datasets.models import free_pelvis, inertia
from msk.kinematics.ik import solve_kinematics
from msk.model.core import Axis, Body, Coordinate, Joint, Marker, Model, marker_positions
from msk.model.joints import Linear
from msk.personalise.determinacy import gauge_shifted_markers
from msk.personalise.sole_level import foot_flat_frames, level_sole_gauge, sole_pitch

FOOT = ["HEEL", "MID", "MET"]


def _shank_foot() -> Model:
    """Pelvis (6 DOF) → shank (knee hinge) → calcn_r (ankle hinge about z, the sole along x at
    zero), three shank and three foot markers; y up."""
    coords, pelvis = free_pelvis(0.9)
    coords += [Coordinate("knee_angle_r", range=(-2.0, 0.3)),
               Coordinate("ankle_angle_r", range=(-1.0, 1.0))]  # fmt: skip
    lin = Linear()
    z = np.array([0.0, 0.0, 1.0])
    bodies = [
        Body("pelvis", 11.0, np.array([-0.07, 0.0, 0.0]), inertia(11.0, 0.25)),
        Body("tibia_r", 3.5, np.array([0.0, -0.2, 0.0]), inertia(3.5, 0.4)),
        Body("calcn_r", 1.2, np.array([0.08, 0.0, 0.0]), inertia(1.2, 0.2)),
    ]
    joints = [
        pelvis,
        Joint("knee_r", "pelvis", "tibia_r", parent_offset=pin.SE3(np.eye(3), np.array(
            [0.0, -0.45, 0.08])), axes=(Axis("revolute", z, "knee_angle_r", lin),)),
        Joint("ankle_r", "tibia_r", "calcn_r", parent_offset=pin.SE3(np.eye(3), np.array(
            [0.0, -0.43, 0.0])), axes=(Axis("revolute", z, "ankle_angle_r", lin),)),
    ]  # fmt: skip
    markers = [
        Marker("ASIS", "pelvis", np.array([0.02, 0.0, 0.12])),
        Marker("PSIS", "pelvis", np.array([-0.15, 0.03, 0.05])),
        Marker("ILC", "pelvis", np.array([-0.05, 0.08, 0.14])),
        Marker("TIB1", "tibia_r", np.array([0.04, -0.15, 0.04])),
        Marker("TIB2", "tibia_r", np.array([0.04, -0.25, -0.03])),
        Marker("TIB3", "tibia_r", np.array([-0.02, -0.3, 0.05])),
        Marker("HEEL", "calcn_r", np.array([-0.06, -0.01, 0.0])),
        Marker("MID", "calcn_r", np.array([0.06, 0.03, 0.01])),
        Marker("MET", "calcn_r", np.array([0.15, -0.02, 0.03])),
    ]
    return Model(name="shank_foot", bodies=bodies, joints=joints, coordinates=coords,
                 markers=markers)  # fmt: skip


def _walk(model: Model, *, stance: bool = True, noise_m: float = 0.001, seed: int = 5):
    """Markers of a known motion at 100 Hz: two stances (the pose held, the pelvis carried
    forward as on a belt, the sole level: ankle = −(pelvis tilt + knee)) between swings (the
    pelvis raised up to 8 cm, knee and ankle moving); ``stance`` False: the pelvis never rests
    vertically. Returns markers, time, true poses."""
    n = 200
    t = np.arange(n) / 100.0
    q = np.tile(model.default_coordinates(), (n, 1))
    ix = {c: model.coordinate_index(c) for c in model.coordinate_names}
    q[:, ix["pelvis_tx"]] = 1.0 * t
    q[:, ix["pelvis_tilt"]] = 0.05
    ph = (t % 1.0) / 1.0  # one cycle per second; stance at 0.1–0.5
    swing = (ph < 0.1) | (ph >= 0.5)
    bump = np.where(swing, np.sin(np.pi * np.clip((ph - 0.5) % 1.0 / 0.6, 0, 1)), 0.0)
    q[:, ix["pelvis_ty"]] = 0.9 + 0.08 * bump
    q[:, ix["knee_angle_r"]] = -0.25 - 0.6 * bump
    q[:, ix["ankle_angle_r"]] = -(0.05 - 0.25) - 0.2 * bump  # stance: tilt + knee + ankle = 0
    if not stance:
        q[:, ix["pelvis_ty"]] = 0.95 + 0.05 * np.sin(2 * np.pi * 1.3 * t)
    x = marker_positions(model, q)
    x = x + np.random.default_rng(seed).normal(0.0, noise_m, x.shape)
    return x, t, q


def _fit(x, labels, t):
    def fit(model, frames):
        kin = solve_kinematics(model, x[frames], labels, t[frames], cutoff_hz=None)
        return np.asarray(kin.q_raw, dtype=float), 0.0

    return fit


def _ankle_mean(model, x, labels, t):
    q = np.asarray(solve_kinematics(model, x, labels, t, cutoff_hz=None).q_raw)
    return float(np.nanmean(q[:, model.coordinate_index("ankle_angle_r")]))


def test_foot_flat_frames_are_the_stance_frames():
    model = _shank_foot()
    x, t, q = _walk(model)
    labels = list(model.marker_names)
    h = x[:, [labels.index(m) for m in FOOT], 1]
    flat = foot_flat_frames(h, t)
    ph = t % 1.0
    stance = (ph >= 0.1) & (ph < 0.5)
    assert flat.sum() >= 0.6 * stance.sum()
    assert not (flat & ~stance).any()  # never in swing
    # the true sole is level there
    assert np.abs(np.degrees(sole_pitch(model, q[flat], "calcn_r"))).max() < 1e-9


def test_ankle_mean_recovered_from_a_placement_started_off():
    truth = _shank_foot()
    x, t, q = _walk(truth)
    labels = list(truth.marker_names)
    true_mean = float(np.mean(q[:, truth.coordinate_index("ankle_angle_r")]))
    for off_deg in (8.0, -6.0):
        # a placement from the motion that stopped with the foot markers rotated by the gauge:
        # every marker fits as well, the ankle's mean is off by off_deg
        placed = gauge_shifted_markers(truth, "ankle_angle_r", np.radians(off_deg),
                                       np.median(q, axis=0), FOOT)  # fmt: skip
        before = _ankle_mean(placed, x, labels, t)
        assert abs(np.degrees(before - true_mean) - off_deg) < 1.0
        leveled, sides = level_sole_gauge(placed, x, labels, t, _fit(x, labels, t), FOOT)
        (side,) = sides
        assert side.applied and side.summary()["status"] == "prior"
        assert abs(np.degrees(side.pitch_before_rad) - off_deg) < 1.5
        after = _ankle_mean(leveled, x, labels, t)
        assert abs(np.degrees(after - true_mean)) < 1.0


def test_no_foot_flat_keeps_the_placement_and_says_so():
    truth = _shank_foot()
    x, t, _ = _walk(truth, stance=False)
    labels = list(truth.marker_names)
    out, (side,) = level_sole_gauge(truth, x, labels, t, _fit(x, labels, t), FOOT)
    assert out is truth
    assert not side.applied and side.shift_rad == 0.0
    assert "foot-flat frames" in side.reason and side.summary()["status"] == "not applied"


def test_a_foot_marker_not_from_the_motion_keeps_the_placement():
    truth = _shank_foot()
    x, t, _ = _walk(truth)
    labels = list(truth.marker_names)
    out, (side,) = level_sole_gauge(truth, x, labels, t, _fit(x, labels, t), FOOT[:2])
    assert out is truth and not side.applied and "observed" in side.reason
