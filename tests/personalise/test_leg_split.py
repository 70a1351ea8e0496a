"""The femur : tibia split of a leg measured pelvis-to-heel, from the functional knee and ankle
(msk.personalise.leg_split): a subject leg of known femur and tibia lengths walks, its thigh, shank
and
foot clusters carry marker noise and soft-tissue-like motion; the model first scaled by one
factor is split back to the subject's lengths, and falls back, saying why, when the data do not
determine a centre."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from msk.datasets.models import free_pelvis, inertia
from msk.model.core import (
    Axis,
    Body,
    Coordinate,
    Joint,
    Marker,
    Model,
    forward_kinematics,
    marker_positions,
)
from msk.model.joints import Linear
from msk.personalise.leg_split import functional_leg_split

FEMUR_0, TIBIA_0 = 0.40, 0.43  # the generic model's hip-to-knee and knee-to-ankle (m)
HIP = np.array([-0.07, -0.07, 0.08])


def _leg(femur_m: float, tibia_m: float) -> Model:
    """Pelvis (free) → femur_r (3-DOF hip) → tibia_r (knee hinge, flexion negative) → talus_r
    (ankle hinge) → calcn_r (subtalar, an oblique axis through the ankle centre); y up."""
    lin = Linear()
    coords, pelvis_joint = free_pelvis(0.95)
    coords += [
        Coordinate("hip_flexion_r"),
        Coordinate("hip_adduction_r"),
        Coordinate("hip_rotation_r"),
        Coordinate("knee_angle_r", range=(-2.09, 0.17)),
        Coordinate("ankle_angle_r", range=(-0.7, 0.52)),
        Coordinate("subtalar_angle_r", range=(-0.35, 0.35)),
    ]
    v = np.array
    sub = v([0.78, 0.6, -0.2]) / np.linalg.norm([0.78, 0.6, -0.2])
    joints = [
        pelvis_joint,
        Joint("hip_r", "pelvis", "femur_r", parent_offset=pin.SE3(np.eye(3), HIP), axes=(
            Axis("revolute", v([0.0, 0.0, 1.0]), "hip_flexion_r", lin),
            Axis("revolute", v([1.0, 0.0, 0.0]), "hip_adduction_r", lin),
            Axis("revolute", v([0.0, 1.0, 0.0]), "hip_rotation_r", lin),
        )),
        Joint("knee_r", "femur_r", "tibia_r",
              parent_offset=pin.SE3(np.eye(3), v([0.0, -femur_m, 0.0])),
              axes=(Axis("revolute", v([0.0, 0.0, 1.0]), "knee_angle_r", lin),)),
        Joint("ankle_r", "tibia_r", "talus_r",
              parent_offset=pin.SE3(np.eye(3), v([0.0, -tibia_m, 0.0])),
              axes=(Axis("revolute", v([0.0, 0.0, 1.0]), "ankle_angle_r", lin),)),
        Joint("subtalar_r", "talus_r", "calcn_r",
              axes=(Axis("revolute", sub, "subtalar_angle_r", lin),)),
    ]  # fmt: skip
    bodies = [
        Body("pelvis", 11.0, v([-0.07, 0.0, 0.0]), inertia(11.0, 0.25)),
        Body("femur_r", 8.8, v([0.0, -0.17, 0.0]), inertia(8.8, 0.40)),
        Body("tibia_r", 3.5, v([0.0, -0.18, 0.0]), inertia(3.5, 0.40)),
        Body("talus_r", 0.1, v([0.0, 0.0, 0.0]), inertia(0.1, 0.05)),
        Body("calcn_r", 1.2, v([0.08, -0.02, 0.0]), inertia(1.2, 0.2)),
    ]
    k = femur_m / FEMUR_0
    markers = [
        Marker("RASI", "pelvis", v([0.02, 0.0, 0.12])),
        Marker("LASI", "pelvis", v([0.02, 0.0, -0.12])),
        Marker("SACR", "pelvis", v([-0.17, 0.03, 0.0])),
        # a thigh cluster (3) and a shank cluster (4), lateral, where a lab puts them
        Marker("RTH1", "femur_r", v([0.03, -0.20, 0.07]) * [1, k, 1]),
        Marker("RTH2", "femur_r", v([-0.02, -0.25, 0.08]) * [1, k, 1]),
        Marker("RTH3", "femur_r", v([0.02, -0.30, 0.075]) * [1, k, 1]),
        Marker("RTB1", "tibia_r", v([0.03, -0.12, 0.06])),
        Marker("RTB2", "tibia_r", v([-0.01, -0.17, 0.065])),
        Marker("RTB3", "tibia_r", v([0.03, -0.22, 0.06])),
        Marker("RTB4", "tibia_r", v([0.0, -0.27, 0.055])),
        Marker("RCAL", "calcn_r", v([-0.05, 0.0, 0.0])),
        Marker("RMT1", "calcn_r", v([0.13, -0.03, -0.04])),
        Marker("RMT5", "calcn_r", v([0.12, -0.03, 0.05])),
    ]
    return Model(name="leg_r", bodies=bodies, joints=joints, coordinates=coords,
                 markers=markers)  # fmt: skip


def _walk(model: Model, n: int = 400, knee_deg: float = 65.0) -> np.ndarray:
    """Coordinates (n, n_coords) of a few gait-like cycles: pelvis forward at 1.3 m/s, hip
    ±25°, knee 5° to ``knee_deg``, ankle ±15°, subtalar ±6°."""
    t = np.linspace(0.0, 3.0, n)
    w = 2 * np.pi / 1.1
    th = np.tile(model.default_coordinates(), (n, 1))
    idx = model.coordinate_index
    th[:, idx("pelvis_tx")] = 1.3 * t
    th[:, idx("pelvis_ty")] = 0.95 + 0.02 * np.sin(2 * w * t)
    th[:, idx("pelvis_list")] = 0.05 * np.sin(w * t)
    th[:, idx("pelvis_rotation")] = 0.08 * np.sin(w * t + 0.3)
    th[:, idx("hip_flexion_r")] = 0.1 + 0.44 * np.sin(w * t)
    th[:, idx("hip_adduction_r")] = 0.08 * np.sin(w * t + 1.0)
    th[:, idx("hip_rotation_r")] = 0.1 * np.sin(w * t + 2.0)
    k = np.radians(knee_deg - 5.0)
    th[:, idx("knee_angle_r")] = -np.radians(5.0) - k * (0.5 - 0.5 * np.cos(w * t + 0.8))
    th[:, idx("ankle_angle_r")] = 0.26 * np.sin(w * t - 0.5)
    th[:, idx("subtalar_angle_r")] = 0.1 * np.sin(w * t + 1.5)
    return th


def _trial(
    subject: Model, th: np.ndarray, seed: int = 3, sta: float = 1.0
) -> tuple[np.ndarray, list[str]]:
    """The subject's markers with 1.5 mm of noise and soft-tissue-like motion of the thigh and
    shank clusters: each cluster slides 8 mm and turns 3° on its bone with the knee's flexion
    (a smooth, cluster-specific rigid motion in the segment's frame, × ``sta``; thigh clusters
    move 10–30 mm on the femur in gait, Leardini et al. 2005), each marker 2 mm more of its
    own."""
    rng = np.random.default_rng(seed)
    x = marker_positions(subject, th)
    labels = [mk.name for mk in subject.markers]
    flex = -th[:, subject.coordinate_index("knee_angle_r")]
    flex = flex / flex.max()
    data = subject.create_data()
    rots = {}
    for body in ("femur_r", "tibia_r"):
        rots[body] = []
        for q in th:
            forward_kinematics(subject, data, q)
            rots[body].append(np.array(data.oMf[subject.body_frame[body]].rotation))
    for body in ("femur_r", "tibia_r"):
        cols = [j for j, mk in enumerate(subject.markers) if mk.body == body]
        local = np.array([subject.markers[j].offset for j in cols])
        centre = local.mean(axis=0)
        shift = rng.normal(0.0, 1.0, 3)
        shift *= sta * 0.008 / np.linalg.norm(shift)
        axis = rng.normal(0.0, 1.0, 3)
        axis /= np.linalg.norm(axis)
        own = rng.normal(0.0, 1.0, (len(cols), 3))
        own *= sta * 0.002 / np.linalg.norm(own, axis=1)[:, None]
        for i in range(len(th)):
            turn = pin.AngleAxis(sta * np.radians(3.0) * flex[i], axis).toRotationMatrix()
            moved = (local - centre) @ turn.T + centre + flex[i] * (shift + own)
            x[i, cols] += (moved - local) @ rots[body][i].T
    x += rng.normal(0.0, 0.0015, x.shape)
    return x, labels


def _scaled(leg_factor: float) -> Model:
    """The generic leg scaled by one factor, femur and tibia alike."""
    return _leg(FEMUR_0 * leg_factor, TIBIA_0 * leg_factor).with_metadata(
        scale_factors={"femur_r": [leg_factor] * 3, "tibia_r": [leg_factor] * 3}
    )


def test_the_functional_knee_and_ankle_recover_a_subjects_femur_and_tibia():
    femur, tibia = 0.435, 0.395  # the generic 0.40 / 0.43: femur longer, tibia shorter
    subject = _leg(femur, tibia)
    x, labels = _trial(subject, _walk(subject))
    leg = (femur + tibia) / (FEMUR_0 + TIBIA_0)  # what ASIS-to-heel gives both
    split = functional_leg_split(_scaled(leg), x, labels, {"r": leg}, use_ankle=True)["r"]
    assert split.method == "functional knee and ankle", split.reason
    # the femur within 5 mm (1.5 % of its factor), the tibia within 10 mm (2.5 %): the shank
    # cluster's 8 mm slide moves the knee's estimate along the tibia (the generic model's own
    # lengths are measured the same way: its knee and ankle functional centres)
    assert split.femur_length_m == pytest.approx(femur, abs=0.005)
    assert split.tibia_length_m == pytest.approx(tibia, abs=0.010)
    assert split.femur_factor == pytest.approx(femur / FEMUR_0, rel=0.015)
    assert split.tibia_factor == pytest.approx(tibia / TIBIA_0, rel=0.025)
    assert split.knee["range_deg"] > 50.0
    assert 2.0 < split.knee["mismatch_mm"] < 25.0  # the soft tissue shows


def test_without_foot_markers_the_tibia_takes_the_rest_of_the_leg():
    femur, tibia = 0.435, 0.395
    subject = _leg(femur, tibia)
    x, labels = _trial(subject, _walk(subject))
    x[:, [labels.index(m) for m in ("RMT1", "RMT5")]] = np.nan
    leg = (femur + tibia) / (FEMUR_0 + TIBIA_0)
    split = functional_leg_split(_scaled(leg), x, labels, {"r": leg}, use_ankle=True)["r"]
    assert split.method == "functional knee, tibia the rest of the leg"
    assert "calcaneus" in split.reason
    assert split.femur_factor == pytest.approx(femur / FEMUR_0, rel=0.015)
    # hip to ankle kept: the tibia is the leg's length less the functional femur
    assert split.tibia_factor == pytest.approx(tibia / TIBIA_0, rel=0.02)


def test_a_knee_that_barely_moves_keeps_the_leg_factor_and_says_why():
    subject = _leg(0.435, 0.395)
    x, labels = _trial(subject, _walk(subject, knee_deg=20.0))  # 15° of knee motion
    split = functional_leg_split(_scaled(1.0), x, labels, {"r": 1.0})["r"]
    assert split.method == "leg factor"
    assert split.femur_factor == split.tibia_factor == 1.0
    assert "knee not determined" in split.reason and "moves" in split.reason
    assert split.summary()["knee"]["range_deg"] < 30.0


def test_a_thigh_without_three_tracked_markers_keeps_the_leg_factor():
    subject = _leg(0.435, 0.395)
    x, labels = _trial(subject, _walk(subject))
    x[:, labels.index("RTH2")] = np.nan
    split = functional_leg_split(_scaled(1.0), x, labels, {"r": 1.0})["r"]
    assert split.method == "leg factor"
    assert "thigh" in split.reason


def test_by_default_the_tibia_is_the_rest_of_the_leg_and_the_ankle_is_reported():
    femur, tibia = 0.435, 0.395
    subject = _leg(femur, tibia)
    x, labels = _trial(subject, _walk(subject))
    leg = (femur + tibia) / (FEMUR_0 + TIBIA_0)
    split = functional_leg_split(_scaled(leg), x, labels, {"r": leg})["r"]
    assert split.method == "functional knee, tibia the rest of the leg"
    assert "reported, not used" in split.reason
    assert split.femur_factor == pytest.approx(femur / FEMUR_0, rel=0.015)
    assert split.tibia_factor == pytest.approx(tibia / TIBIA_0, rel=0.02)
    assert split.tibia_length_m == pytest.approx(tibia, abs=0.010)  # measured, not used
    assert split.summary()["ankle"]["range_deg"] > 15.0
