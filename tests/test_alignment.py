"""Frontal-plane knee alignment (msk.alignment; Lerner et al. 2015 J Biomech 48:644)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from msk.alignment import knee_side, with_knee_alignment
from msk.exceptions import ModelError
from msk.model import Axis, Body, Coordinate, Joint, Model, forward_kinematics

HIP = np.array([0.0, 1.0, 0.0])
ANKLE = np.array([0.0, -0.4, 0.0])  # in the tibia frame
MODELS = Path(__file__).resolve().parents[1] / "models"


def _leg(side: str) -> Model:
    """Femur welded at ``HIP``, tibia on a revolute knee about z named ``knee_<side>``."""
    from msk.joints import Linear

    bodies = [
        Body("femur", 7.0, [0.0, 0.2, 0.0], np.diag([0.1, 0.02, 0.1])),
        Body("tibia", 4.0, [0.0, -0.2, 0.0], np.diag([0.05, 0.005, 0.05])),
    ]
    joints = [
        Joint("ground_femur", "ground", "femur", parent_offset=pin.SE3(np.eye(3), HIP)),
        Joint(
            f"knee_{side}", "femur", "tibia",
            axes=(Axis("revolute", [0, 0, 1], "knee_angle", Linear()),),
        ),
    ]  # fmt: skip
    return Model(
        name="leg", bodies=bodies, joints=joints,
        coordinates=[Coordinate("knee_angle", range=(-2.5, 2.5))],
    )  # fmt: skip


def _tibia(model: Model, theta: float) -> pin.SE3:
    data = model.create_data()
    forward_kinematics(model, data, [theta])
    return pin.SE3(data.oMf[model.body_frame["tibia"]])


def _rx(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize("side", ["r", "l"])
@pytest.mark.parametrize("theta", [0.0, -0.6])
def test_valgus_moves_the_ankle_laterally_and_the_shift_moves_the_tibia_medially(
    side: str, theta: float
) -> None:
    """5° of valgus (varus −5°) after flexion θ: tibia = R_z(θ) R_x(∓5°), so in extension the
    ankle 0.4 m below the knee moves 0.4 sin 5° laterally; a 10 mm medial shift moves the whole
    tibia 10 mm medially (−z on the right, +z on the left)."""
    lat = 1.0 if side == "r" else -1.0
    leg = _leg(side)
    a = np.radians(-5.0)
    aligned = with_knee_alignment(leg, f"knee_{side}", varus_rad=a, medial_shift_m=0.01)
    b = _tibia(aligned, theta)
    np.testing.assert_allclose(b.rotation, _rz(theta) @ _rx(lat * a), atol=1e-12)
    np.testing.assert_allclose(b.translation, HIP + np.array([0.0, 0.0, -lat * 0.01]), atol=1e-12)
    if theta == 0.0:
        ankle = b.act(ANKLE) - _tibia(leg, 0.0).act(ANKLE)
        np.testing.assert_allclose(lat * ankle[2], 0.4 * np.sin(np.radians(5.0)) - 0.01, atol=1e-12)
        assert ankle[1] > 0  # the tilted shank reaches slightly less far down
    assert aligned.metadata["knee_alignment"][f"knee_{side}"]["medial_shift_m"] == 0.01


@pytest.mark.parametrize("name", ["gait2392.toml", "gait2392_fourbar.toml"])
def test_gait2392_knees_aligned_alike_are_mirror_images(name: str) -> None:
    """The same varus on both knees of gait2392 (spline and four-bar knee), symmetric pose:
    the left tibia is the right one reflected through the sagittal plane (z → −z)."""
    from msk.model_files import load_model

    model = load_model(MODELS / name)
    for s in ("r", "l"):
        model = with_knee_alignment(
            model, f"knee_{s}", varus_rad=np.radians(3.0), medial_shift_m=-0.004
        )
    q = model.default_coordinates()
    names = model.coordinate_names
    for s in ("r", "l"):
        q[names.index(f"knee_angle_{s}")] = -0.5
    data = model.create_data()
    forward_kinematics(model, data, q)
    right = data.oMf[model.body_frame["tibia_r"]]
    left = data.oMf[model.body_frame["tibia_l"]]
    mirror = np.diag([1.0, 1.0, -1.0])
    pelvis = data.oMf[model.body_frame["pelvis"]].translation
    np.testing.assert_allclose(
        mirror @ (right.translation - pelvis), left.translation - pelvis, atol=1e-12
    )
    np.testing.assert_allclose(mirror @ right.rotation @ mirror, left.rotation, atol=1e-12)
    # varus tilts the right tibia's long axis (y) so that its distal end goes medially (−z)
    assert right.rotation[2, 1] > 0.0 and left.rotation[2, 1] < 0.0


def test_zero_alignment_is_the_model_itself_and_bad_input_raises() -> None:
    leg = _leg("r")
    assert with_knee_alignment(leg, "knee_r") is leg
    with pytest.raises(ModelError, match="no joint"):
        with_knee_alignment(leg, "knee_x", varus_rad=0.1)
    with pytest.raises(ModelError, match="20"):
        with_knee_alignment(leg, "knee_r", varus_rad=0.5)
    with pytest.raises(ModelError, match=r"0\.03"):
        with_knee_alignment(leg, "knee_r", medial_shift_m=0.05)
    with pytest.raises(ModelError, match="side must be"):
        with_knee_alignment(leg, "knee_r", varus_rad=0.1, side="up")
    assert knee_side("knee_l") == "left" and knee_side("knee_right") == "right"
    with pytest.raises(ModelError, match="side"):
        knee_side("knee")
