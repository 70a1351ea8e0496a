"""Plug-in Gait's knee flexion: the chord function recovers a known knee centre, the flexion a
known angle of known centres (both sides, any orientation, marker noise), and on a posed model
the chord knee and ankle from exact markers give the flexion of the model's own centres."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pinocchio as pin
import pytest
from scipy.spatial.transform import Rotation

from msk.datasets.models import two_leg_model
from msk.gait.plug_in_gait import chord_centres, knee_flexion, plug_in_gait_knee_flexion
from msk.personalise.scaling import chord_joint_centre


def _leg(theta_deg: np.ndarray, side: str, r: float = 0.058):
    """Hip, knee, ankle, thigh wand and lateral knee marker of a leg whose thigh is vertical
    and whose shank is flexed by theta (ankle behind the knee), x anterior, y up, z right."""
    s = 1.0 if side == "right" else -1.0
    n = theta_deg.size
    th = np.deg2rad(theta_deg)
    knee = np.zeros((n, 3))
    hip = np.tile([0.0, 0.42, 0.0], (n, 1))
    ankle = np.column_stack([-0.40 * np.sin(th), -0.40 * np.cos(th), np.zeros(n)])
    kne = np.tile([0.0, 0.0, s * r], (n, 1))
    thi = np.tile([0.0, 0.2, s * 0.09], (n, 1))  # the wand in the frontal plane of the thigh
    return hip, knee, ankle, kne, thi


@pytest.mark.parametrize("side", ["right", "left"])
def test_chord_recovers_the_knee_centre_and_flexion_a_known_angle(side):
    theta = np.linspace(-5.0, 70.0, 16)
    hip, knee, ankle, kne, thi = _leg(theta, side)
    rot = Rotation.random(random_state=7).as_matrix()  # the whole leg turned anyhow
    hip, knee, ankle, kne, thi = (
        x @ rot.T + [0.3, 0.9, -0.2] for x in (hip, knee, ankle, kne, thi)
    )
    k = chord_centres(hip, thi, kne, 0.058)
    assert k == pytest.approx(knee, abs=1e-12)
    # the one-frame chord of the static placement agrees
    assert chord_joint_centre(hip[3], thi[3], kne[3], 0.058) == pytest.approx(k[3], abs=1e-12)
    assert knee_flexion(hip, k, ankle, kne, side) == pytest.approx(theta, abs=1e-9)
    # 0.5 mm marker noise: within 0.5°
    rng = np.random.default_rng(2)
    noisy = [x + rng.normal(0.0, 0.0005, x.shape) for x in (thi, kne, ankle)]
    k2 = chord_centres(hip, noisy[0], noisy[1], 0.058)
    assert np.abs(knee_flexion(hip, k2, noisy[2], noisy[1], side) - theta).max() < 0.5


def test_an_abducted_shank_does_not_change_the_flexion():
    """The flexion is the angle in the femur's sagittal plane: a shank swung 10° out of it
    keeps its projected angle."""
    theta = np.array([30.0])
    hip, knee, ankle, kne, _ = _leg(theta, "right")
    tilt = Rotation.from_rotvec(np.deg2rad(10.0) * np.array([1.0, 0.0, 0.0]))
    swung = tilt.apply(ankle)
    proj = np.degrees(np.arctan2(-swung[0, 0], -swung[0, 1]))
    assert knee_flexion(hip, knee, swung, kne, "right") == pytest.approx([proj], abs=1e-9)


def test_on_a_posed_model_the_chord_gives_the_flexion_of_its_centres():
    """Markers put where the chord puts the model's own knee and ankle centres (lateral knee
    and ankle markers at r along the femur's and tibia's lateral axes, wands on the lateral
    side): with the file's widths the flexion equals that of the model's centres; without
    them the chord with the knee marker's distance, and the model's ankle."""
    model = two_leg_model()
    names = model.coordinate_names
    n = 12
    q = np.zeros((n, len(names)))
    q[:, names.index("pelvis_ty")] = 0.93
    q[:, names.index("hip_flexion_r")] = np.linspace(-0.2, 0.5, n)
    q[:, names.index("knee_angle_r")] = -np.linspace(0.0, 1.1, n)
    data = model.create_data()
    qp = model.coupling.q(q)
    r_k, r_a = (0.10 + 0.014) / 2, (0.07 + 0.014) / 2
    pts = {k: np.zeros((n, 3)) for k in ("hip", "knee", "ankle", "KNE", "THI", "ANK", "TIB")}
    for i in range(n):
        pin.framesForwardKinematics(model.pin_model, data, qp[i])
        f = data.oMf[model.body_frame["femur_r"]]
        t = data.oMf[model.body_frame["tibia_r"]]
        a = data.oMf[model.body_frame["foot_r"]]  # the ankle joint's child
        pts["hip"][i], pts["knee"][i], pts["ankle"][i] = f.translation, t.translation, a.translation
        lat_f, lat_t = f.rotation[:, 2], t.rotation[:, 2]
        pts["KNE"][i] = t.translation + r_k * lat_f
        pts["THI"][i] = f.translation + 0.5 * (t.translation - f.translation) + 0.08 * lat_f
        pts["ANK"][i] = a.translation + r_a * lat_t
        pts["TIB"][i] = t.translation + 0.5 * (a.translation - t.translation) + 0.07 * lat_t
    labels = ("RKNE", "RTHI", "RANK", "RTIB")
    markers = np.stack([pts[lab[1:]] for lab in labels], axis=1)
    time = np.arange(n) * 0.01

    def trial(widths):
        sub = SimpleNamespace(widths_m=widths, marker_diameter_m=None)
        return SimpleNamespace(
            time=time, marker_labels=labels, subject=sub,
            marker=lambda lab: markers[:, labels.index(lab)],
        )  # fmt: skip

    kin = SimpleNamespace(time=time, q=q, coordinate_names=names)
    # the femur's sagittal plane is the chord's: the model's knee moves only in it (no varus)
    truth = knee_flexion(pts["hip"], pts["knee"], pts["ankle"], pts["KNE"], "right")
    got, how = plug_in_gait_knee_flexion(
        model, kin, trial({"R.knee": 0.10, "R.ankle": 0.07}), "right"
    )
    assert got is not None and "knee width 100 mm" in how and "ankle by the chord" in how
    assert got == pytest.approx(truth, abs=1e-6)
    got2, how2 = plug_in_gait_knee_flexion(model, kin, trial({}), "right")
    assert got2 is not None and "the model's ankle centre" in how2
    assert got2 == pytest.approx(truth, abs=1e-6)
    none, why = plug_in_gait_knee_flexion(model, kin, trial({}), "left")
    assert none is None and "no L thigh wand" in why
