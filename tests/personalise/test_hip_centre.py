"""Hip centres by regression (msk.personalise.hip_centre): known truths built in code, and Plug-in
Gait's
own hip centres reproduced from a Vicon static."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from msk.exceptions import ModelError
from msk.model.files import load_model
from msk.personalise.hip_centre import (
    PelvisLandmarks,
    no_static_hip_centre,
    pelvis_frame,
    pelvis_pose_for_hips,
    place_hip_centres,
    regression_hip_centres,
)
from msk.personalise.scaling import static_hip_centres

ROOT = Path(__file__).resolve().parents[2]


def _rotation(rng: np.random.Generator) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def _pelvis(pw: float, pd: float, psis_w: float, rot: np.ndarray, org: np.ndarray):
    """Landmarks of a pelvis whose ISB frame is (rot, org): ASIS at ±PW/2 on z, the PSIS
    PD behind the mid-ASIS, 20 mm up (the frame's x is normal to z in the ASIS–PSIS plane:
    the PSIS' height sets the frame's tilt, not PD's definition)."""
    up = 0.02
    back = np.sqrt(pd**2 - up**2)
    loc = {
        "RASI": [0.0, 0.0, pw / 2], "LASI": [0.0, 0.0, -pw / 2],
        "RPSI": [-back, up, psis_w / 2], "LPSI": [-back, up, -psis_w / 2],
    }  # fmt: skip
    return {k: rot @ np.asarray(v) + org for k, v in loc.items()}


def test_harrington_recovers_its_equations_in_any_pose() -> None:
    rng = np.random.default_rng(0)
    rot, org = _rotation(rng), rng.normal(size=3)
    pw, pd = 0.25, 0.16
    pts = _pelvis(pw, pd, 0.09, rot, org)
    lm = PelvisLandmarks(pts["RASI"], pts["LASI"], 0.5 * (pts["RPSI"] + pts["LPSI"]))
    assert lm.width_m == pytest.approx(pw)
    assert lm.depth_m == pytest.approx(pd)
    got = regression_hip_centres(lm, method="harrington")
    # Harrington et al. 2007, PW and PD in mm
    x, y, z = -0.24 * 160 - 9.9, -0.30 * 250 - 10.9, 0.33 * 250 + 7.3
    r_isb, o = pelvis_frame(lm)
    assert np.allclose(o, org)
    for side, s in (("r", 1.0), ("l", -1.0)):
        truth = r_isb @ (np.array([x, y, s * z]) / 1000.0) + o
        assert np.allclose(got[side], truth, atol=1e-9)
    # the ISB frame: z to the right ASIS, y up (towards the PSIS' 20 mm rise after tilt)
    assert np.allclose(r_isb[:, 2], rot[:, 2])


def test_regression_with_marker_noise_stays_within_a_few_mm() -> None:
    rng = np.random.default_rng(1)
    rot, org = _rotation(rng), rng.normal(size=3)
    pts = _pelvis(0.24, 0.17, 0.09, rot, org)
    lm = PelvisLandmarks(pts["RASI"], pts["LASI"], 0.5 * (pts["RPSI"] + pts["LPSI"]))
    truth = regression_hip_centres(lm)
    errs = []
    for _ in range(200):
        noisy = {k: v + rng.normal(scale=0.002, size=3) for k, v in pts.items()}
        lm_n = PelvisLandmarks(noisy["RASI"], noisy["LASI"], 0.5 * (noisy["RPSI"] + noisy["LPSI"]))
        est = regression_hip_centres(lm_n)
        errs += [np.linalg.norm(est[s] - truth[s]) for s in "rl"]
    # 2 mm marker noise: the centre (~100 mm from the mid-ASIS) moves by the frame's tilt
    assert np.percentile(errs, 95) < 0.006


def test_davis_and_bell_forms() -> None:
    lm = PelvisLandmarks(np.array([0.0, 0.0, 0.125]), np.array([0.0, 0.0, -0.125]),
                         np.array([-0.15, 0.0, 0.0]))  # fmt: skip
    ll = 0.9
    c = 0.115 * 900 - 15.3
    th, be = np.radians(28.4), np.radians(18.0)
    xd = 0.1288 * 900 - 48.56 + 7.0
    davis = regression_hip_centres(lm, method="davis", leg_length_m=ll)
    truth = np.array([
        c * np.cos(th) * np.sin(be) - xd * np.cos(be),
        -xd * np.sin(be) - c * np.cos(th) * np.cos(be),
        125.0 - c * np.sin(th),
    ]) / 1000.0  # fmt: skip
    assert np.allclose(davis["r"], truth)
    assert np.allclose(davis["l"], truth * [1, 1, -1])
    bell = regression_hip_centres(lm, method="bell")
    assert np.allclose(bell["r"], np.array([-0.19, -0.30, 0.36]) * 0.25)
    with pytest.raises(ModelError, match="leg length"):
        regression_hip_centres(lm, method="davis")
    with pytest.raises(ModelError, match="unknown"):
        regression_hip_centres(lm, method="functional")


def _static_of(model, rot: np.ndarray, org: np.ndarray, shift: np.ndarray) -> dict:
    """A static's pelvis markers: the model's ASIS and a PSIS pair around its sacral marker,
    all moved by ``shift`` (pelvis frame) — the subject's markers sit elsewhere on the bone
    than the generic model's."""
    off = {mk.name: np.asarray(mk.offset) for mk in model.markers}
    loc = {  # the ASIS under the model's names, as the pipeline renames them
        "R.ASIS": off["R.ASIS"] + shift, "L.ASIS": off["L.ASIS"] + shift,
        "RPSI": off["V.Sacral"] + [0.0, 0.0, 0.045] + shift,
        "LPSI": off["V.Sacral"] + [0.0, 0.0, -0.045] + shift,
    }  # fmt: skip
    return {k: rot @ v + org for k, v in loc.items()}


def test_place_hip_centres_puts_the_model_hips_on_the_regression() -> None:
    model = load_model(ROOT / "msk" / "data" / "models" / "gait2392.toml")
    rng = np.random.default_rng(2)
    rot, org = _rotation(rng), np.array([0.3, 0.9, -0.1])
    means = _static_of(model, rot, org, np.array([0.03, 0.0, 0.0]))
    placed, info = place_hip_centres(
        model, np.array([list(means.values())]), list(means), method="harrington"
    )
    assert info["method"] == "harrington"
    exp = PelvisLandmarks(means["R.ASIS"], means["L.ASIS"], 0.5 * (means["RPSI"] + means["LPSI"]))
    truth = regression_hip_centres(exp)
    # the placed model's own pelvis fit (what marker placement and the knee chord use)
    hips = static_hip_centres(placed, means)
    half = abs(info["width_residual_m"]) / 2
    for s in "rl":
        assert np.linalg.norm(hips[s] - truth[s]) <= half + 1e-6
    mid = 0.5 * (hips["r"] + hips["l"])
    assert np.allclose(mid, 0.5 * (truth["r"] + truth["l"]), atol=1e-9)
    # the generic hips were where the markers' shift put them: 30 mm from the truth, about
    before = static_hip_centres(model, means)
    assert min(np.linalg.norm(before[s] - truth[s]) for s in "rl") > 0.02
    # the pelvis markers moved on the body; nothing else did
    assert set(info["pelvis_markers_moved_m"]) == {"R.ASIS", "L.ASIS", "V.Sacral"}
    others = {m.name: m.offset for m in model.markers if m.body != "pelvis"}
    assert all(np.array_equal(m.offset, others[m.name]) for m in placed.markers
               if m.name in others)  # fmt: skip


def test_the_pose_keeps_the_markers_tilt_about_the_hip_axis() -> None:
    model = load_model(ROOT / "msk" / "data" / "models" / "gait2392.toml")
    means = _static_of(model, np.eye(3), np.zeros(3), np.zeros(3))
    r, t, info = pelvis_pose_for_hips(model, means)
    # the generic markers fit the generic pelvis exactly, and both hip axes are along z:
    # the pose is a pure translation, taking the model's mid-hip to the regression's
    assert info["pelvis_fit_rms_m"] < 1e-9
    assert np.allclose(r, np.eye(3), atol=1e-9)
    lm = PelvisLandmarks(means["R.ASIS"], means["L.ASIS"], 0.5 * (means["RPSI"] + means["LPSI"]))
    reg = regression_hip_centres(lm)
    hips = {j.child[-1]: j.parent_offset.translation for j in model.joints if j.parent == "pelvis"
            and j.child.startswith("femur")}  # fmt: skip
    assert np.allclose(t, 0.5 * (reg["r"] + reg["l"]) - 0.5 * (hips["r"] + hips["l"]))
    assert np.allclose(info["shift_m"]["r"], reg["r"] - hips["r"])


def test_without_pelvis_landmarks_the_model_hip_is_kept_and_said() -> None:
    model = load_model(ROOT / "msk" / "data" / "models" / "gait2392.toml")
    x = np.zeros((1, 2, 3))
    same, info = place_hip_centres(model, x, ["RASI", "LASI"], method="harrington")
    assert same is model
    assert info["method"] == "model" and info["requested"] == "harrington"
    assert "PSIS" in info["reason"]
    assert no_static_hip_centre("harrington")["method"] == "model"
    assert "no static" in no_static_hip_centre("harrington")["reason"]
    with pytest.raises(ModelError):
        place_hip_centres(model, x, ["RASI", "LASI"], method="sphere")


@pytest.mark.slow
@pytest.mark.realdata
def test_davis_reproduces_plug_in_gaits_hip_centre(real_dir: Path) -> None:
    """Plug-in Gait's hip centre (its femur's proximal point <S>FEP in the static) from the
    markers and the file's leg length and marker size: Davis et al. (1991) as Vicon applies
    it, to 1 mm; Harrington's (pelvic width and depth) sits 15-25 mm from it on this subject."""
    from msk.io import read_c3d

    path = real_dir / "btkdata" / "PiG_Calibration3_FF.c3d"
    if not path.is_file():
        pytest.skip("btkdata/PiG_Calibration3_FF.c3d absent")
    tr = read_c3d(path)

    def mean(lab: str) -> np.ndarray:
        return np.nanmean(np.asarray(tr.marker(lab), dtype=float), axis=0)

    lm = PelvisLandmarks(mean("RASI"), mean("LASI"), 0.5 * (mean("RPSI") + mean("LPSI")))
    davis = regression_hip_centres(lm, method="davis", leg_length_m=0.92)  # LLegLength
    harr = regression_hip_centres(lm)
    for side in "RL":
        pig = mean(f"{side}FEP")
        assert np.linalg.norm(davis[side.lower()] - pig) < 0.001
        assert 0.015 < np.linalg.norm(harr[side.lower()] - pig) < 0.025
