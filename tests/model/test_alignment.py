"""Frontal-plane knee alignment (msk.model.alignment; Lerner et al. 2015 J Biomech 48:644)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from msk.exceptions import ModelError
from msk.model.alignment import knee_side, with_knee_alignment
from msk.model.core import Model, forward_kinematics
from tests.support.knees import HIP, femur_tibia

ANKLE = np.array([0.0, -0.4, 0.0])  # in the tibia frame
MODELS = Path(__file__).resolve().parents[2] / "msk" / "data" / "models"


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
    leg = femur_tibia(f"knee_{side}")
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
    from msk.model.files import load_model

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
    leg = femur_tibia("knee_r")
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


def _leg_poses(model, side: str, n: int, rng: np.random.Generator) -> np.ndarray:
    """Standing-to-stance poses: knee 0–20° flexed, hip flexion −10…20°, hip rotation ±10°,
    pelvis tilt ±5° (gait2392 coordinates)."""
    names = model.coordinate_names
    q = np.repeat(model.default_coordinates()[None], n, axis=0)
    ranges = (
        (f"knee_angle_{side}", -20.0, 0.0), (f"hip_flexion_{side}", -10.0, 20.0),
        (f"hip_rotation_{side}", -10.0, 10.0), ("pelvis_tilt", -5.0, 5.0),
    )  # fmt: skip
    for c, lo, hi in ranges:
        q[:, names.index(c)] = np.radians(rng.uniform(lo, hi, n))
    return q


@pytest.mark.parametrize("side", ["r", "l"])
@pytest.mark.parametrize(("varus_deg", "shift_m"), [(3.0, 0.0), (-4.097, 0.0), (-4.097, 0.0096)])
def test_knee_varus_from_markers_recovers_an_imposed_alignment(
    side: str, varus_deg: float, shift_m: float
) -> None:
    """Skin markers of gait2392 with a known alignment imposed (1 mm noise, 40 poses, knee
    0–20° flexed): the estimate against the neutral model is the imposed varus within 0.3°;
    a medial shift s is seen as the angle s / tibia length more varus (the epicondyles are on
    the femur, the malleoli move with the tibia: DM.osim's −4.1° and 9.6 mm read −2.8°)."""
    from msk.model.alignment import knee_varus_from_markers
    from msk.model.core import marker_positions
    from msk.model.files import load_model

    neutral = load_model(MODELS / "gait2392.toml")
    truth = with_knee_alignment(
        neutral, f"knee_{side}", varus_rad=np.radians(varus_deg), medial_shift_m=shift_m
    )
    rng = np.random.default_rng(3)
    x = marker_positions(truth, _leg_poses(truth, side, 40, rng))
    x = x + rng.normal(0.0, 0.001, x.shape)
    est = knee_varus_from_markers(neutral, x, list(truth.marker_names), side)
    data = neutral.create_data()
    forward_kinematics(neutral, data, neutral.default_coordinates())
    p = side.upper()
    ankle = {mk.name: mk for mk in neutral.markers}[f"{p}.Ankle.Lat"]
    tibia_len = float(np.linalg.norm(ankle.offset))
    expect = np.radians(varus_deg) + shift_m / tibia_len
    assert est.varus_rad == pytest.approx(expect, abs=np.radians(0.3))
    assert est.frames == 40 and est.iqr_rad < np.radians(1.0)
    assert est.varus_rad == pytest.approx(est.subject_rad - est.model_rad)


def test_knee_varus_from_markers_needs_the_epicondyles_and_malleoli() -> None:
    """A trial without the medial epicondyle marker (Grand Challenge DM's walks have no
    epicondyle or malleolus marker), or with the knee flexed beyond 25° in every frame, gives
    no estimate: a typed error, never a default."""
    from msk.exceptions import MissingDataError
    from msk.model.alignment import knee_varus_from_markers
    from msk.model.core import marker_positions
    from msk.model.files import load_model

    model = load_model(MODELS / "gait2392.toml")
    q = _leg_poses(model, "r", 10, np.random.default_rng(0))
    x = marker_positions(model, q)
    labels = list(model.marker_names)
    x[:, labels.index("R.Knee.Med")] = np.nan
    with pytest.raises(MissingDataError, match="0 frames"):
        knee_varus_from_markers(model, x, labels, "right")
    q[:, model.coordinate_names.index("knee_angle_r")] = np.radians(-40.0)
    with pytest.raises(MissingDataError, match="within 25°"):
        knee_varus_from_markers(model, marker_positions(model, q), labels, "right")
    with pytest.raises(MissingDataError, match=r"no 'L\.Knee\.Lat'"):
        knee_varus_from_markers(model, x, [lab.replace("L.", "X.") for lab in labels], "left")
