"""Marker-set recognition: lab labels → gait2392 markers by anatomical landmark."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from msk.model.files import load_model
from msk.model.markersets import parse_label, recognise

MODELS = Path(__file__).resolve().parents[2] / "msk" / "data" / "models"


@pytest.fixture(scope="module")
def gait2392():
    return load_model(MODELS / "gait2392.toml")


def _labels(path: Path) -> list[str]:
    if path.suffix == ".trc":
        from msk.io.opensim_files import read_trc

        return list(read_trc(path).labels)
    ezc3d = pytest.importorskip("ezc3d")
    c = ezc3d.c3d(str(path))
    pt = c["parameters"]["POINT"]
    return list(pt["LABELS"]["value"]) + list(pt.get("LABELS2", {}).get("value", []))


def _match(model, path: Path):
    if not path.exists():
        pytest.skip(f"{path} absent")
    return recognise(_labels(path), model.marker_names, model_bodies=[b.name for b in model.bodies])


@pytest.mark.parametrize(
    ("label", "side", "landmark"),
    [
        ("R_Knee_Lateral", "R", "knee_lat"),
        ("R.Knee.Lat", "R", "knee_lat"),
        ("RKneeLateral", "R", "knee_lat"),
        ("RKNE", "R", "knee_lat"),
        ("RLE", "R", "knee_lat"),
        ("LKNEin", "L", "knee_med"),
        ("RankleMedial", "R", "ankle_med"),
        ("LMM", "L", "ankle_med"),
        ("JW:RAsis", "R", "asis"),
        ("r asis", "R", "asis"),
        ("ASIS_L", "L", "asis"),
        ("RightKneeLateral", "R", "knee_lat"),
        ("RTOE", "R", "mt2"),  # Plug-in Gait: 2nd metatarsal head, not the toe tip
        ("RToe", "R", "toe_tip"),
        ("R.Toe", "R", "toe_tip"),
        ("LVMH", "L", "mt5"),
        ("RIMH", "R", "mt1"),
        ("LCAL", "L", "heel"),
        ("SACR", None, "sacrum"),
        ("S2", None, "sacrum"),
        ("L5", None, "spine"),
        ("STRN", None, "xiphoid"),
        ("RTH1", "R", "thigh_cluster"),
        ("L_Shank_Superior", "L", "shank_cluster"),
    ],
)
def test_parse_label_reads_side_and_landmark(label, side, landmark):
    p = parse_label(label)
    assert (p.side, p.landmark) == (side, landmark), p


@pytest.mark.parametrize(
    ("label", "kind"),
    [
        ("*12", "unlabelled"),
        ("Oglobal", "lab axis"),
        ("Zglobal", "lab axis"),
        ("PELO", "model output"),
        ("LKneeAngles", "model output"),
        ("RHipPower", "model output"),
        ("LeftHipCenter", "model output"),
        ("JW:RShoulderCenter", "model output"),
        ("#", "not a marker"),
    ],
)
def test_parse_label_sets_non_markers_apart(label, kind):
    assert parse_label(label).kind == kind


def test_prefixes_explicit_renames_and_apply(gait2392):
    labels = ["JW:RAsis", "JW:LAsis", "JW:Sacral", "JW:RKneeLateral", "JW:RThighSuperior", "*3"]
    m = recognise(labels, gait2392.marker_names, rename={"R.Knee.Med": "JW:RKneeLateral"})
    assert m.rename["R.ASIS"] == "JW:RAsis"
    assert m.rename["V.Sacral"] == "JW:Sacral"
    # the user's rename wins (even a wrong one) and the label is not used twice
    assert m.rename["R.Knee.Med"] == "JW:RKneeLateral"
    assert "R.Knee.Lat" not in m.rename
    assert m.unmatched_lab == ("JW:RThighSuperior",)
    assert m.excluded == {"*3": "unlabelled trajectory"}
    x = np.arange(2 * 6 * 3, dtype=float).reshape(2, 6, 3)
    kept, names = m.apply(x, labels)
    assert kept.shape == (2, 5, 3)
    assert names == ("R.ASIS", "L.ASIS", "V.Sacral", "R.Knee.Med", "JW:RThighSuperior")
    np.testing.assert_array_equal(kept[:, 4], x[:, 4])


def test_arm_markers_are_kept_for_a_model_with_arms(gait2392):
    m = recognise(["RELB", "RASI"], gait2392.marker_names, model_bodies=["pelvis", "humerus_r"])
    assert "RELB" in m.unmatched_lab and not m.excluded
    m = recognise(["RELB", "RASI"], gait2392.marker_names, model_bodies=["pelvis", "torso"])
    assert "arm" in m.excluded["RELB"]


GC = {
    "knee-grand-challenge-gc5/PS_ngait_og_ss1.c3d": "Grand Challenge",
    "knee-grand-challenge-gc4/jw_ngait_og3.c3d": "Grand Challenge",
    "knee-grand-challenge-gc6-DM/DM_ngait_og1_new.trc": "Grand Challenge",
}


@pytest.mark.parametrize("rel", sorted(GC))
def test_grand_challenge_motion_trials(real_dir, gait2392, rel):
    m = _match(gait2392, real_dir / rel)
    assert m.protocol == GC[rel]
    inv = m.lab_to_model
    for lab in m.rename.values():
        assert lab in _labels(real_dir / rel)
    for s in ("R", "L"):
        asis = next(lab for lab in inv if parse_label(lab).landmark == "asis" and lab[0] == s)
        assert inv[asis] == f"{s}.ASIS"
        assert "heel" in m.rename[f"{s}.Heel"].lower()
        assert m.rename[f"{s}.Toe.Tip"].endswith("Toe")
    assert m.rename["V.Sacral"] == "Sacral"
    for axis in ("Oglobal", "Xglobal", "Yglobal", "Zglobal"):
        assert m.excluded[axis].startswith("lab axis")
    assert any("arm" in why for why in m.excluded.values())
    for cluster in ("RThighSuperior", "R_Thigh_Superior"):
        assert cluster not in inv
    if "DM" in rel:
        assert m.rename["R.Knee.Lat"] == "R_Knee_Lateral"
        assert m.rename["R.Knee.Med"] == "R_Knee_Medial"
        assert m.rename["R.Ankle.Med"] == "RankleMedial"
        assert m.rename["R.Ankle.Lat"] == "R_Ankle_Lateral"
        assert m.rename["R.Toe.Med"] == "R_ToeMedial"
    else:  # no knee/ankle markers in the GC4/GC5 motion trials
        assert "R.Knee.Lat" in m.unmatched_model


def test_grand_challenge_static(real_dir, gait2392):
    m = _match(gait2392, real_dir / "knee-grand-challenge-gc5/PS_static_for_scaling.trc")
    assert m.rename["R.Knee.Lat"] == "RKneeLateral"
    assert m.rename["L.Knee.Med"] == "LKneeMedial"
    assert m.rename["R.Ankle.Med"] == "RankleMedial"
    assert m.rename["L.Ankle.Lat"] == "LAnkleLateral"
    assert m.rename["R.Toe.Tip"] == "RToe"
    assert {"RPsis", "Xiphoid", "RHindfoot", "RMidfootMedial"} <= set(m.unmatched_lab)


def test_plug_in_gait(real_dir, gait2392):
    m = _match(gait2392, real_dir / "btkdata/PiG_Motion3_FF.c3d")
    assert m.protocol == "Plug-in Gait"
    assert m.rename["R.ASIS"] == "RASI"
    assert m.rename["L.Knee.Lat"] == "LKNE"
    assert m.rename["R.Ankle.Lat"] == "RANK"
    assert m.rename["R.Heel"] == "RHEE"
    assert "R.Toe.Tip" not in m.rename  # RTOE is on the 2nd metatarsal head
    assert {"RTOE", "LTOE", "RTHI", "LTIB", "RPSI"} <= set(m.unmatched_lab)
    assert m.excluded["PELO"].startswith("model output")
    assert m.excluded["*1"] == "unlabelled trajectory"
    assert m.excluded["LKneeAnglesV"].startswith("model output")
    m = _match(gait2392, real_dir / "btkdata/FunctionalStatic.c3d")
    assert m.rename["R.Knee.Med"] == "RKNEin"
    assert m.rename["L.Ankle.Med"] == "LANKin"
    assert m.rename["V.Sacral"] == "SACR"
    assert "Sternum" not in m.rename  # STRN is on the xiphoid
    assert m.excluded["LeftHipCenter"].startswith("model output")


def test_uwa_has_no_knee_or_ankle_markers(real_dir, gait2392):
    m = _match(gait2392, real_dir / "motonms-testdata/UWA/Fast_Walking.c3d")
    assert m.protocol == "UWA clusters"
    assert m.rename["R.ASIS"] == "RASI"
    assert m.rename["V.Sacral"] == "SACR"
    assert m.rename["L.Heel"] == "LCAL"
    assert m.rename["L.Toe.Med"] == "LMT1"
    assert m.rename["R.Toe.Lat"] == "RMT5"
    assert not {"R.Knee.Lat", "R.Ankle.Lat", "L.Knee.Lat"} & set(m.rename)
    assert {"LTH1", "RTB3", "LPSI"} <= set(m.unmatched_lab)
    assert m.excluded["*51"] == "unlabelled trajectory"
    assert "arm" in m.excluded["RFA1"]


@pytest.mark.parametrize("trial", ["Static1.c3d", "Walking1.c3d"])
def test_unipd_ior_cast(real_dir, gait2392, trial):
    m = _match(gait2392, real_dir / "motonms-testdata/UNIPD" / trial)
    assert m.protocol == "IOR/CAST"
    expect = {
        "R.ASIS": "RASIS",
        "L.ASIS": "LASIS",
        "R.Knee.Lat": "RLE",
        "R.Knee.Med": "RME",
        "L.Ankle.Lat": "LLM",
        "L.Ankle.Med": "LMM",
        "R.Heel": "RCA",
        "R.Toe.Med": "RIMH",
        "R.Toe.Lat": "RVMH",
    }
    assert {k: m.rename[k] for k in expect} == expect
    assert "V.Sacral" not in m.rename  # L5 is a lumbar vertebra
    assert {"RGT", "RHF", "RTT", "L5", "RPSIS"} <= set(m.unmatched_lab)


def test_opensim_sets(real_dir, gait2392):
    m = _match(gait2392, real_dir / "opensim-subject01-walk/subject01_static.trc")
    assert m.protocol.startswith("OpenSim")
    assert all(m.rename[k] == k for k in m.rename)
    assert len(m.rename) == len(gait2392.marker_names)
    assert "arm" in m.excluded["R.Elbow"]
    m = _match(gait2392, real_dir / "opensim-rajagopal-walk/markers_walk.trc")
    expect = {
        "V.Sacral": "S2",
        "R.Knee.Lat": "R.Knee",
        "R.Ankle.Lat": "R.Ankle",
        "R.Toe.Tip": "R.Toe",
        "R.Toe.Lat": "R.MT5",
    }
    assert {k: m.rename[k] for k in expect} == expect
    assert {"R.TH1", "R.SH4", "R.PSIS"} <= set(m.unmatched_lab)


def test_shoulder_girdle_markers_only_for_a_model_without_that_segment():
    """Acromion / clavicle / "Shoulder" markers are the shoulder girdle's on a model whose
    torso is rigid (gait2392); never on a model with a scapula or humerus; arm markers, the
    sternum, C7 and the jugular notch (Plug-in Gait CLAV) are not."""
    from msk.model.markersets import shoulder_girdle_markers

    labels = ["R.Acromium", "LSHO", "RA", "RShoulder", "RCLAV", "CLAV", "C7", "Sternum",
              "R_ShoulderAnterior", "RELB", "RASIS"]  # fmt: skip
    assert shoulder_girdle_markers(labels, ["pelvis", "torso", "femur_r"]) == (
        "R.Acromium", "LSHO", "RA", "RShoulder", "RCLAV"
    )  # fmt: skip
    assert shoulder_girdle_markers(labels, ["pelvis", "torso", "humerus_r"]) == ()


def test_foot_markers_are_the_foot_landmarks():
    """Heel, metatarsal heads, toe tip and midfoot labels of any grammar; not the ankle, knee
    or pelvis."""
    from msk.model.markersets import foot_markers

    labels = ["R.Heel", "LCA", "RVMH", "L.Toe.Tip", "R.Toe.Med", "RMidfootSuperior", "RLM",
              "R.Knee.Lat", "LASIS", "R.Ankle.Lat"]  # fmt: skip
    assert foot_markers(labels) == ("R.Heel", "LCA", "RVMH", "L.Toe.Tip", "R.Toe.Med",
                                    "RMidfootSuperior")  # fmt: skip


def _cluster_walk(n: int = 300, noise_m: float = 3e-4, seed: int = 0):
    """A thigh-like segment swinging and translating through a walk: three physical cluster
    markers measured with camera noise, two anatomical landmarks rebuilt from the noisy cluster
    (CAST: stored in the cluster's frame, recomputed each frame), a skin marker sliding 5 mm on
    the segment, and a marker on another segment."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 2.0, n)
    ang = 0.5 * np.sin(2 * np.pi * t)
    rot = np.zeros((n, 3, 3))
    rot[:, 0, 0] = rot[:, 1, 1] = np.cos(ang)
    rot[:, 0, 1], rot[:, 1, 0] = -np.sin(ang), np.sin(ang)
    rot[:, 2, 2] = 1.0
    origin = np.stack([1.2 * t, 0.9 + 0.02 * np.sin(4 * np.pi * t), 0 * t], axis=1)
    local = np.array([[0.05, -0.1, 0.04], [-0.04, -0.12, 0.05], [0.0, -0.2, 0.06]])
    cluster = origin[:, None] + np.einsum("nij,kj->nki", rot, local)
    cluster += rng.normal(0.0, noise_m, cluster.shape)
    # the cluster's technical frame from its noisy markers, and two landmarks in it
    e1 = cluster[:, 1] - cluster[:, 0]
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e3 = np.cross(e1, cluster[:, 2] - cluster[:, 0])
    e3 /= np.linalg.norm(e3, axis=1, keepdims=True)
    frame = np.stack([e1, np.cross(e3, e1), e3], axis=2)
    calib = np.array([[0.03, -0.35, 0.05], [0.02, -0.36, -0.07]])
    landmarks = cluster.mean(axis=1, keepdims=True) + np.einsum("nij,kj->nki", frame, calib)
    skin = origin + np.einsum("nij,j->ni", rot, [0.0, -0.05, 0.07])
    skin += 0.005 * np.sin(2 * np.pi * t)[:, None] + rng.normal(0.0, noise_m, (n, 3))
    other = origin + np.array([0.0, -0.45, 0.0]) + rng.normal(0.0, noise_m, (n, 3))
    x = np.concatenate([cluster, landmarks, skin[:, None], other[:, None]], axis=1)
    return x, ["TH1", "TH2", "TH3", "LE", "ME", "SKIN", "TT"]


def test_reconstructed_markers_are_the_landmarks_rebuilt_from_a_cluster():
    """Known truth: the two landmarks computed from a noisy cluster keep their distance
    exactly; physical markers (cluster markers on one rigid plate, 0.3 mm camera noise; a skin
    marker; another segment's) never do, whatever the seed."""
    from msk.model.markersets import reconstructed_markers

    for seed in range(5):
        x, labels = _cluster_walk(seed=seed)
        assert reconstructed_markers(x, labels) == ("LE", "ME")
    # gaps (NaN or exact zeros) are skipped, a pair seen in too few frames is not judged
    x[5:, 4] = 0.0
    assert reconstructed_markers(x, labels) == ()
    assert reconstructed_markers(x, labels, min_frames=5) == ("LE", "ME")
    # a label duplicated (one point twice) is not a reconstruction
    y = np.concatenate([x[:, :1], x[:, :1]], axis=1)
    assert reconstructed_markers(y, ["TH1", "TH1b"]) == ()


@pytest.mark.slow
@pytest.mark.realdata
def test_unipd_cast_landmarks_are_reconstructed(real_dir):
    """BTS/IOR (UNIPD Walking1): ASIS–PSIS of each side, GT–LE–ME of each thigh and
    HF–TT–LM–MM of each shank are rebuilt from clusters; C7, L5 and the foot markers are
    measured."""
    from msk.io import read_trial
    from msk.model.markersets import reconstructed_markers

    tr = read_trial(real_dir / "motonms-testdata/UNIPD/Walking1.c3d")
    rec = set(reconstructed_markers(tr.markers, tr.marker_labels))
    kinds = ("ASIS", "PSIS", "GT", "LE", "ME", "HF", "TT", "LM", "MM")
    sides = {s + m for s in "RL" for m in kinds}
    assert rec == sides


def test_other_side_and_knee_segments_of_labels_and_bodies():
    """``other_side``: the bodies of the other side than a sided label's, whatever the label's
    spelling, none for a midline label and never a midline body; ``is_knee_segment``: the
    femur and tibia bodies (either side) and stems, which the thigh and shank landmarks name."""
    from msk.model.markersets import LANDMARK_BODIES, is_knee_segment, other_side

    bodies = ["pelvis", "femur_r", "tibia_r", "calcn_r", "femur_l", "tibia_l", "toes_l", "torso"]
    right = [False, False, False, False, True, True, True, False]
    for lab in ("R_Thigh_Inferior", "RKNE", "RightAnkleLateral", "R.Knee.Lat", "JW:RAsis"):
        assert other_side(lab, bodies).tolist() == right, lab
    left = [b.endswith("_r") for b in bodies]
    for lab in ("L_Shank_Superior", "LANK", "Left_Heel"):
        assert other_side(lab, bodies).tolist() == left, lab
    for lab in ("Sternum", "SACR", "C7", "Oglobal"):
        assert not other_side(lab, bodies).any(), lab
    assert other_side("RKNE", []).shape == (0,)
    assert [is_knee_segment(b) for b in bodies] == [
        False, True, True, False, True, True, False, False]  # fmt: skip
    knee = {lm for lm, stem in LANDMARK_BODIES.items() if is_knee_segment(stem)}
    assert {"knee_lat", "thigh_cluster", "ankle_med", "shank_cluster"} <= knee
    assert not knee & {"asis", "heel", "toe_tip", "sternum"}


def test_a_trial_wide_subject_prefix_is_dropped_once_unless_ambiguous():
    """``JW:LASI`` → ``LASI`` when one prefix is shared by the labels that carry one (a lab's
    unprefixed axes keep their names); kept when the labels carry two prefixes, when fewer than
    half carry it, or when dropping it would give two labels one name."""
    from msk.model.markersets import strip_subject_prefix

    assert strip_subject_prefix(["JW:LASI", "JW:RASI", "Oglobal"]) == (
        ("LASI", "RASI", "Oglobal"),
        "JW:",
    )
    assert strip_subject_prefix(["LASI", "RASI"]) == (("LASI", "RASI"), "")
    assert strip_subject_prefix(["A:LASI", "B:RASI"]) == (("A:LASI", "B:RASI"), "")
    assert strip_subject_prefix(["JW:LASI", "RASI", "LPSI"])[1] == ""
    assert strip_subject_prefix(["JW:LASI", "LASI"]) == (("JW:LASI", "LASI"), "")


def test_static_and_task_with_different_prefixes_read_alike(tmp_path):
    """A static written with ``S1:`` and a task with ``JW:`` (and one without): every trial's
    labels are read without its prefix (msk.io.read_c3d, msk.io.read_trc), so the markers placed
    from the static are the task's; the prefix is in the trial's metadata."""
    from msk.io import read_c3d, write_c3d
    from msk.io.opensim_files import read_trc

    x = np.random.default_rng(0).normal(size=(5, 3, 3))
    names = ["LASI", "RASI", "R.Thigh.Upper"]
    got = {}
    for pre in ("", "S1:", "JW:"):
        p = write_c3d(tmp_path / f"t{pre[:2]}.c3d", markers=x,
                      marker_labels=[pre + n for n in names], rate_hz=100.0)  # fmt: skip
        tr = read_c3d(p)
        got[pre] = tr.marker_labels
        assert tr.metadata["label_prefix"] == pre
        assert tuple(tr.gaps.labels) == tuple(names)
    assert got[""] == got["S1:"] == got["JW:"] == tuple(names)
    trc = tmp_path / "t.trc"
    head = "\t".join(f"JW:{n}\t\t" for n in names)
    rows = "\n".join(
        f"{i + 1}\t{i / 100:.2f}\t" + "\t".join(f"{v:.4f}" for v in x[i].ravel()) for i in range(5)
    )
    trc.write_text(
        "PathFileType\t4\t(X/Y/Z)\tt.trc\n"
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame"
        "\tOrigNumFrames\n100\t100\t5\t3\tm\t100\t1\t5\n"
        f"Frame#\tTime\t{head}\n\t\tX1\tY1\tZ1\tX2\tY2\tZ2\tX3\tY3\tZ3\n\n{rows}\n"
    )
    assert read_trc(trc).labels == tuple(names)


def test_a_configured_label_with_the_prefix_the_reader_dropped_still_matches():
    """``rename = {"R.Knee.Med" = "JW:RKneeLateral"}`` pairs with the label read as
    ``RKneeLateral`` (the trial's prefix dropped when read)."""
    from msk.model.markersets import as_read

    gait2392 = load_model(MODELS / "gait2392.toml")
    labels = ["RAsis", "LAsis", "Sacral", "RKneeLateral"]
    m = recognise(labels, gait2392.marker_names, rename={"R.Knee.Med": "JW:RKneeLateral"})
    assert m.rename["R.Knee.Med"] == "RKneeLateral"
    assert as_read("JW:Other", labels) == "JW:Other"
    assert as_read("LAsis", labels) == "LAsis"


@pytest.mark.parametrize(
    ("label", "side", "landmark"),
    [("R_IAS", "R", "asis"), ("L_IPS", "L", "psis"), ("R_FTC", "R", "gt"),
     ("L_FLE", "L", "knee_lat"), ("L_FME", "L", "knee_med"), ("R_FAX", "R", "fib_head"),
     ("R_TTC", "R", "tib_tub"), ("L_FAL", "L", "ankle_lat"), ("L_TAM", "L", "ankle_med"),
     ("L_FCC", "L", "heel"), ("L_FM1", "L", "mt1"), ("L_FM5", "L", "mt5"),
     ("R_SAE", "R", "acromion"), ("CV7", None, "c7"), ("LV5", None, "spine"),
     ("L_SK2", "L", "shank_cluster")],
)  # fmt: skip
def test_van_sint_jan_landmark_codes(label, side, landmark):
    p = parse_label(label)
    assert (p.side, p.landmark) == (side, landmark)


def test_helen_hayes_toe_is_the_second_metatarsal_head():
    """Motion Analysis' Helen Hayes set: ``R.Toe`` sits on the 2nd metatarsal head (Kadaba et
    al. 1990), not at gait2392's toe tip: left unpaired (placed); OpenSim's own labels keep
    theirs."""
    hh = ["R.ASIS", "L.ASIS", "V.Sacral", "R.Thigh", "R.Knee", "R.Tibia", "R.Ankle", "R.Heel",
          "R.Toe", "L.Knee", "L.Ankle", "L.Heel", "L.Toe"]  # fmt: skip
    model = load_model("gait2392")
    m = recognise(hh, model.marker_names)
    assert m.protocol == "Helen Hayes"
    assert "R.Toe.Tip" not in m.rename and "R.Toe" in m.unmatched_lab
    assert m.rename["R.Heel"] == "R.Heel" and m.rename["R.Knee.Lat"] == "R.Knee"
    other = recognise(["RASI", "LASI", "RHeel", "RToe", "RKNE"], model.marker_names)
    assert other.rename["R.Toe.Tip"] == "RToe"
