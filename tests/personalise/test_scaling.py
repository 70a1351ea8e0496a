"""Model scaling: recovery of known segment lengths, OpenSim 4.6 ScaleTool side by side, a real
static trial."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msk._runtime.opensim_peer import run_opensim_script
from msk.datasets.models import leg_model
from msk.exceptions import KinematicsError, MissingDataError, ModelError
from msk.model.core import Marker, forward_kinematics, marker_positions
from msk.model.osim import load_osim
from msk.personalise.scaling import (
    Measurement,
    apply_scale_factors,
    measure_scale_factors,
    muscle_path_lengths,
    read_scale_setup,
    scale_inertia,
    scale_model,
)

LEG_MEASUREMENTS = (
    Measurement("pelvis", (("ASIS", "PSIS"),), ("pelvis",)),
    Measurement("thigh", (("THI", "KNE"),), ("femur",)),
    Measurement("shank", (("TIB", "ANK"),), ("tibia",)),
    Measurement("foot", (("HEE", "TOE"),), ("foot",)),
)


def _femur_length(model):
    """Hip centre to knee (tibia origin) distance in the default pose."""
    data = model.create_data()
    forward_kinematics(model, data, model.default_coordinates())
    hip = data.oMf[model.body_frame["femur"]].translation
    knee = data.oMf[model.body_frame["tibia"]].translation
    return float(np.linalg.norm(knee - hip))


def _shank_length(model):
    data = model.create_data()
    forward_kinematics(model, data, model.default_coordinates())
    knee = data.oMf[model.body_frame["tibia"]].translation
    ankle = data.oMf[model.body_frame["foot"]].translation
    return float(np.linalg.norm(ankle - knee))


def test_scaling_recovers_known_segment_lengths_from_a_noisy_static_trial():
    generic = leg_model()
    truth = {"pelvis": 1.08, "femur": 1.12, "tibia": 0.93, "foot": 1.04}
    subject = apply_scale_factors(generic, truth, body_mass=71.0)
    rng = np.random.default_rng(0)
    pos = marker_positions(subject, subject.default_coordinates())[0]
    frames = 240  # 2 s at 120 Hz, 1 mm noise
    static = {
        name: pos[i] + rng.normal(scale=1e-3, size=(frames, 3))
        for i, name in enumerate(subject.marker_names)
    }
    static["TOE"][:10] = np.nan  # gaps are ignored
    scaled = scale_model(generic, static, measurements=LEG_MEASUREMENTS, body_mass=71.0)
    assert abs(_femur_length(scaled) - _femur_length(subject)) < 1e-3
    assert abs(_shank_length(scaled) - _shank_length(subject)) < 1e-3
    for body, s in truth.items():
        np.testing.assert_allclose(scaled.metadata["scale_factors"][body], s, atol=5e-3)
    np.testing.assert_allclose(
        marker_positions(scaled, scaled.default_coordinates()),
        marker_positions(subject, subject.default_coordinates()),
        atol=2e-3,
    )
    assert scaled.total_mass == pytest.approx(71.0)
    # the generic model is untouched (immutable)
    assert generic.total_mass == pytest.approx(24.5)
    assert generic.metadata.get("scale_factors") is None


def test_mass_distribution_and_inertia_scale_with_m_s2():
    generic = leg_model()
    scaled = apply_scale_factors(generic, {"femur": 1.1}, body_mass=2 * generic.total_mass)
    for b, g in zip(scaled.bodies, generic.bodies):
        assert b.mass == pytest.approx(2 * g.mass)
        s = 1.1 if b.name == "femur" else 1.0
        np.testing.assert_allclose(b.inertia, 2 * s**2 * g.inertia, rtol=1e-12)
        np.testing.assert_allclose(b.com, s * g.com)


@settings(max_examples=30, deadline=None)
@given(
    st.lists(st.floats(0.7, 1.4), min_size=3, max_size=3),
    st.lists(st.floats(-1.0, 1.0), min_size=12, max_size=12),
)
def test_inertia_scaling_equals_stretched_point_masses(s, raw):
    """I' from J' = S J S equals the inertia of point masses whose positions are stretched."""
    m = np.array([1.0, 2.0, 0.5, 1.5])
    pts = np.asarray(raw).reshape(4, 3)
    pts = pts - (m[:, None] * pts).sum(0) / m.sum()  # about the centre of mass

    def inertia(p):
        return sum(mi * (pi @ pi * np.eye(3) - np.outer(pi, pi)) for mi, pi in zip(m, p))

    np.testing.assert_allclose(
        scale_inertia(inertia(pts), s), inertia(pts * np.asarray(s)), atol=1e-12
    )


def test_bad_scaling_input():
    generic = leg_model()
    with pytest.raises(ModelError, match="no bodies"):
        apply_scale_factors(generic, {"humerus": 1.1})
    with pytest.raises(ModelError, match="positive"):
        apply_scale_factors(generic, {"femur": -1.0})
    with pytest.raises(MissingDataError, match="no \\(valid\\) marker 'TOE'"):
        measure_scale_factors(generic, {"HEE": np.zeros(3)}, LEG_MEASUREMENTS[3:])
    with pytest.raises(MissingDataError, match="no marker 'XYZ'"):
        measure_scale_factors(
            generic, {"HEE": np.zeros(3)}, [Measurement("m", (("HEE", "XYZ"),), ("foot",))]
        )


def _subject01(shared: Path):
    d = shared / "tools/opensim-peer/data/Pipelines/Gait2392_Simbody"
    return d, read_scale_setup(d / "subject01_Setup_Scale.xml")


def _read_static(path: Path, t0: float, t1: float):
    from msk.io.opensim_files import read_trc

    trc = read_trc(path)
    sel = (trc.time >= t0 - 1e-9) & (trc.time <= t1 + 1e-9)
    return {lab: trc.markers[sel, i] for i, lab in enumerate(trc.labels)}


_SCALE_PEER = """
import opensim as osim
tool = osim.ScaleTool(ARGS["setup"])
gm = tool.getGenericModelMaker()
gm.setModelFileName(ARGS["model"])
gm.setMarkerSetFileName(ARGS["markers"])
ms = tool.getModelScaler()
ms.setMarkerFileName(ARGS["trc"])
ms.setOutputModelFileName(ARGS["out"])
tool.getMarkerPlacer().setApply(False)
tool.setPathToSubject("")
tool.run()
"""


@pytest.mark.opensim
@pytest.mark.slow
def test_scaled_gait2392_matches_opensim_scale_tool(ref_dir, needs_opensim, tmp_path):
    """gait2392 scaled to subject01's static trial with subject01's Scale setup (measurements
    torso, pelvis, thigh, shank, foot; manual femur/tibia factors; 72.6 kg; no marker
    placement): msk vs OpenSim 4.6 ScaleTool."""
    d, setup = _subject01(ref_dir.parent.parent)
    generic_path = ref_dir / "opensim-models/gait2392_thelen2003muscle.osim"
    markers = d / "gait2392_Scale_MarkerSet.xml"
    out = tmp_path / "osim_scaled.osim"
    run_opensim_script(
        _SCALE_PEER,
        setup=str(d / "subject01_Setup_Scale.xml"),
        model=str(generic_path),
        markers=str(markers),
        trc=str(d / "subject01_static.trc"),
        out=str(out),
    )
    ref = load_osim(out)
    generic = load_osim(generic_path, marker_set=markers)
    assert setup.time_range is not None and setup.mass == pytest.approx(72.6)
    static = _read_static(d / "subject01_static.trc", *setup.time_range)
    ours = scale_model(
        generic,
        static,
        measurements=setup.measurements,
        scale_factors=setup.manual,
        body_mass=setup.mass,
    )
    assert ours.total_mass == pytest.approx(ref.total_mass, rel=1e-12)
    for b in ref.bodies:
        a = ours.body(b.name)
        assert a.mass == pytest.approx(b.mass, rel=1e-9)
        np.testing.assert_allclose(a.com, b.com, atol=1e-6)
        np.testing.assert_allclose(a.inertia, b.inertia, rtol=1e-5, atol=1e-9)
    for j, k in zip(ours.joints, ref.joints):
        np.testing.assert_allclose(
            j.parent_offset.translation, k.parent_offset.translation, atol=1e-6
        )
    th = np.random.default_rng(2).uniform(-0.5, 0.5, (4, ours.n_coords))
    np.testing.assert_allclose(marker_positions(ours, th), marker_positions(ref, th), atol=2e-6)
    mr = {m.name: m for m in ref.muscles}
    for m in ours.muscles:
        r = mr[m.name]
        assert m.optimal_fiber_length == pytest.approx(r.optimal_fiber_length, abs=1e-6)
        assert m.tendon_slack_length == pytest.approx(r.tendon_slack_length, abs=1e-6)
        for p, q in zip(m.points, r.points):
            np.testing.assert_allclose(p.location, q.location, atol=1e-6)
    # path lengths scale: l_opt changed where the path changed
    assert any(
        m.optimal_fiber_length != g.optimal_fiber_length
        for m, g in zip(ours.muscles, generic.muscles)
    )
    lengths = muscle_path_lengths(ours)
    assert all(v > 0 for v in lengths.values())


# Grand Challenge subject PS static trial → gait2392 (markers named as in its TRC)
GC5_PAIRS = {
    "pelvis": [("RAsis", "LAsis")],
    "thigh": [("RAsis", "RKneeLateral"), ("LAsis", "LKneeLateral")],
    "shank": [("RKneeLateral", "RAnkleLateral"), ("LKneeLateral", "LAnkleLateral")],
    "foot": [("RHeel", "RToe"), ("LHeel", "LToe")],
}
GC5_TO_GAIT2392 = {
    "RAsis": "R.ASIS",
    "LAsis": "L.ASIS",
    "RKneeLateral": "R.Knee.Lat",
    "LKneeLateral": "L.Knee.Lat",
    "RAnkleLateral": "R.Ankle.Lat",
    "LAnkleLateral": "L.Ankle.Lat",
    "RHeel": "R.Heel",
    "LHeel": "L.Heel",
    "RToe": "R.Toe.Tip",
    "LToe": "L.Toe.Tip",
}


@pytest.mark.slow
@pytest.mark.realdata
def test_scale_gait2392_to_grand_challenge_static_trial(real_dir, ref_dir):
    d = ref_dir.parent.parent / "tools/opensim-peer/data/Pipelines/Gait2392_Simbody"
    generic = load_osim(
        ref_dir / "opensim-models/gait2392_thelen2003muscle.osim",
        marker_set=d / "gait2392_Scale_MarkerSet.xml",
    )
    static = _read_static(real_dir / "knee-grand-challenge-gc5/PS_static_for_scaling.trc", 0, 99)
    model_of = {v: k for k, v in GC5_TO_GAIT2392.items()}
    bodies = {
        "pelvis": ("pelvis",),
        "thigh": ("femur_r", "femur_l"),
        "shank": ("tibia_r", "tibia_l", "talus_r", "talus_l"),
        "foot": ("calcn_r", "calcn_l", "toes_r", "toes_l"),
    }
    meas = [
        Measurement(k, tuple((GC5_TO_GAIT2392[a], GC5_TO_GAIT2392[b]) for a, b in v), bodies[k])
        for k, v in GC5_PAIRS.items()
    ]
    names = {GC5_TO_GAIT2392[k]: k for k in model_of.values()}
    scaled = scale_model(generic, static, measurements=meas, marker_names=names, body_mass=68.0)
    ratios = scaled.metadata["scale_ratios"]
    # subject PS: 1.67 m, 68 kg (Fregly et al. 2012); gait2392 is 1.8 m, 75.16 kg
    assert all(0.75 < r < 1.15 for r in ratios.values()), ratios
    assert scaled.total_mass == pytest.approx(68.0)
    # after scaling, the measured distances match the trial's on average (by construction)
    pos = dict(zip(scaled.marker_names, marker_positions(scaled, scaled.default_coordinates())[0]))
    means = {k: np.nanmean(v, axis=0) for k, v in static.items()}
    for a, b in GC5_PAIRS["thigh"]:
        dm = np.linalg.norm(pos[GC5_TO_GAIT2392[a]] - pos[GC5_TO_GAIT2392[b]])
        de = np.linalg.norm(means[a] - means[b])
        assert abs(dm - de) < 0.02


_MANUAL_SCALE_PEER = """
import opensim as osim
m = osim.Model(ARGS["model"])
s = m.initSystem()
ss = osim.ScaleSet()
for body, f in ARGS["factors"].items():
    sc = osim.Scale()
    sc.setSegmentName(body)
    sc.setScaleFactors(osim.Vec3(*f))
    sc.setApply(True)
    ss.cloneAndAppend(sc)
RESULT["ok"] = m.scale(s, ss, True, ARGS["mass"])
m.printToXML(ARGS["out"])
"""


@pytest.mark.opensim
@pytest.mark.slow
def test_rajagopal_manual_nonuniform_scaling_matches_opensim_model_scale(
    ref_dir, needs_opensim, tmp_path
):
    """Rajagopal 2016 (wrap cylinders, coupled patella) scaled with non-uniform manual factors:
    msk vs OpenSim 4.6 ``Model::scale`` (preserve mass distribution, 70 kg)."""
    path = ref_dir / "opensim-models/Rajagopal2016.osim"
    factors = {
        "pelvis": [1.05, 1.0, 1.1],
        "femur_r": [1.1, 0.95, 1.05],
        "tibia_r": [0.9, 1.08, 1.0],
        "femur_l": [1.2, 1.2, 1.2],
    }
    out = tmp_path / "scaled.osim"
    res = run_opensim_script(
        _MANUAL_SCALE_PEER, model=str(path), factors=factors, mass=70.0, out=str(out)
    )
    assert res["ok"]
    ref = load_osim(out)
    ours = apply_scale_factors(load_osim(path), factors, body_mass=70.0)
    for b in ref.bodies:
        a = ours.body(b.name)
        assert a.mass == pytest.approx(b.mass, rel=1e-12)
        np.testing.assert_allclose(a.com, b.com, atol=1e-12)
        if len(set(factors.get(b.name, [1.0]))) == 1:
            # uniform factors: I' = (m'/m) s² I in both; OpenSim's non-uniform inertia scaling
            # is an approximation (it equalises principal moments), ours is exact (J' = S J S)
            np.testing.assert_allclose(a.inertia, b.inertia, rtol=1e-12, atol=1e-15)
    for j, k in zip(ours.joints, ref.joints):
        np.testing.assert_allclose(
            j.parent_offset.translation, k.parent_offset.translation, atol=1e-12
        )
        np.testing.assert_allclose(
            j.child_offset.translation, k.child_offset.translation, atol=1e-12
        )
    wraps = {w.name: w for w in ref.metadata["wrap_objects"]}
    for w in ours.metadata["wrap_objects"]:
        r = wraps[w.name]
        np.testing.assert_allclose(w.translation, r.translation, atol=1e-12)
        assert (w.radius, w.length) == pytest.approx((r.radius, r.length), rel=1e-12)
    th = np.random.default_rng(0).uniform(0.0, 0.5, (3, ours.n_coords))
    np.testing.assert_allclose(marker_positions(ours, th), marker_positions(ref, th), atol=1e-12)
    mr = {m.name: m for m in ref.muscles}
    for m in ours.muscles:
        r = mr[m.name]
        for p, q in zip(m.points, r.points):
            np.testing.assert_allclose(p.location, q.location, atol=1e-12)
        # path-length ratio: exact for via-point paths; wrapped paths differ by OpenSim's
        # approximate cylinder tangent points (≤ 0.02 % one cylinder, ≤ 0.3 % for the
        # gastrocnemii wrapping over two)
        rel = {0: 1e-9, 1: 5e-4}.get(len(m.wraps), 5e-3)
        assert m.optimal_fiber_length == pytest.approx(r.optimal_fiber_length, rel=rel)
        assert m.tendon_slack_length == pytest.approx(r.tendon_slack_length, rel=rel)


# ---------------------------------------------------------------------------------------------
# marker placement (OpenSim Scale's MarkerPlacer step)
# ---------------------------------------------------------------------------------------------
#: cluster markers with a known place on the synthetic two-leg model (body, local position)
CLUSTERS = {
    "RTHC": ("femur_r", [0.05, -0.22, 0.04]),
    "LTHC": ("femur_l", [0.05, -0.28, -0.04]),
    "RSHC": ("tibia_r", [0.05, -0.25, 0.03]),
    "LSHC": ("tibia_l", [0.04, -0.15, -0.03]),
    "RMID": ("foot_r", [0.08, -0.05, 0.02]),
}


def _static_with_clusters(noise_m: float, n: int = 15, seed: int = 0):
    """Static frames of the two-leg model carrying the clusters (known truth)."""
    from msk.datasets.models import two_leg_model
    from msk.model.core import Marker

    model = two_leg_model()
    truth = model.with_markers(
        [*model.markers, *(Marker(k, b, np.array(p)) for k, (b, p) in CLUSTERS.items())]
    )
    theta = model.default_coordinates()
    names = model.coordinate_names
    for c, v in (("pelvis_tx", 0.4), ("pelvis_rotation", 0.3), ("knee_angle_r", -0.15),
                 ("hip_flexion_l", 0.1), ("ankle_angle_l", 0.05)):  # fmt: skip
        theta[names.index(c)] = v
    x = marker_positions(truth, np.repeat(theta[None], n, axis=0))
    x += np.random.default_rng(seed).normal(0.0, noise_m, x.shape)
    return model, truth, x, np.arange(n) / 100.0


@pytest.mark.parametrize("noise_m", [0.0, 0.002])
def test_place_markers_puts_clusters_on_their_bones_at_their_place(noise_m):
    from msk.personalise.scaling import place_markers

    model, truth, x, t = _static_with_clusters(noise_m)
    x[3, 0] = np.nan  # a gap in a model marker
    placed, info = place_markers(model, x, truth.marker_names, t)
    assert info["placed"] == {k: b for k, (b, _) in CLUSTERS.items()}
    assert info["static_marker_rms_m"] <= 1e-6 + 2 * noise_m
    got = {m.name: m for m in placed.markers}
    assert set(got) == set(truth.marker_names)
    for name, (body, local) in CLUSTERS.items():
        assert got[name].body == body
        np.testing.assert_allclose(got[name].offset, local, atol=1e-6 + 2 * noise_m)
    # the model markers themselves are untouched
    for m in model.markers:
        np.testing.assert_array_equal(got[m.name].offset, m.offset)


def test_place_markers_skips_unseen_markers_and_names_an_unsolvable_static():
    from msk.personalise.scaling import place_markers

    model, truth, x, t = _static_with_clusters(0.0)
    x[:, truth.marker_names.index("RMID")] = np.nan
    placed, info = place_markers(model, x, truth.marker_names, t)
    assert "RMID" not in info["placed"] and "RMID" not in placed.marker_names
    with pytest.raises((MissingDataError, KinematicsError), match="no frame could be solved"):
        place_markers(model, np.full_like(x, np.nan), truth.marker_names, t)


def test_place_markers_moves_named_model_markers_and_leaves_out_far_and_virtual_points():
    """``move``: a model marker 4 cm off where this subject carries it goes back to its true
    place (on its own body); a point 0.6 m from every bone (an arm marker on a model without
    arms) and the points that are not markers (Vicon's unlabelled ``*1``, Plug-in Gait's
    ``PELO``) are not placed."""
    from msk.model.core import Marker
    from msk.personalise.scaling import place_markers

    _, truth, x, t = _static_with_clusters(0.0)
    shift = np.array([0.04, 0.0, 0.0])
    true_offset = next(m.offset for m in truth.markers if m.name == "RTHC")
    generic = truth.with_markers(
        [Marker(m.name, m.body, m.offset + shift) if m.name == "RTHC" else m
         for m in truth.markers]
    )  # fmt: skip
    far = x[:, truth.marker_names.index("RTHC")] + np.array([0.0, 0.0, 0.8])
    near = x[:, truth.marker_names.index("RSHC")] + 0.01
    xs = np.concatenate([x, far[:, None], near[:, None], near[:, None]], axis=1)
    labels = [*truth.marker_names, "R.Wrist", "*1", "PELO"]
    kept, _ = place_markers(generic, xs, labels, t)
    np.testing.assert_allclose(
        next(m.offset for m in kept.markers if m.name == "RTHC"), true_offset + shift
    )
    moved, info = place_markers(generic, xs, labels, t, move=["RTHC"])
    got = next(m for m in moved.markers if m.name == "RTHC")
    assert got.body == "femur_r"
    np.testing.assert_allclose(got.offset, true_offset, atol=1e-6)
    assert info["moved"] == {"RTHC": pytest.approx(0.04, abs=1e-6)}
    assert info["static_marker_rms_m"] < 1e-6  # the pose came without the moved marker
    assert info["too_far"]["R.Wrist"][1] > 0.25 and "R.Wrist" not in moved.marker_names
    assert info["not_markers"] == ["*1", "PELO"]
    assert not {"*1", "PELO"} & set(moved.marker_names)
    with pytest.raises(ModelError, match="no marker 'RTHX' to move"):
        place_markers(generic, xs, labels, t, move=["RTHX"])


def test_is_measured_marker():
    from msk.io import is_measured_marker

    for lab in ("*1", "*23", "PELO", "LFEA", "RTIL", "LFOP", "RTOO", "HEDA", "TRXO", "LHUO"):
        assert not is_measured_marker(lab), lab
    for lab in ("LASI", "RTOE", "LTIB", "RTHI", "LHEE", "RPSI", "R.Knee.Lat", "RKNEin", "*x"):
        assert is_measured_marker(lab), lab


def test_point_segment_distance_and_bone_segments():
    from msk.datasets.models import two_leg_model
    from msk.personalise.scaling import bone_segments, point_segment_distance

    a, b = np.zeros(3), np.array([1.0, 0.0, 0.0])
    assert point_segment_distance([0.5, 0.2, 0.0], a, b) == pytest.approx(0.2)
    assert point_segment_distance([-0.3, 0.4, 0.0], a, b) == pytest.approx(0.5)  # beyond a
    assert point_segment_distance([1.0, 0.0, 0.0], a, a) == pytest.approx(1.0)  # degenerate
    model = two_leg_model()
    data = model.create_data()
    forward_kinematics(model, data, model.default_coordinates())
    segs = bone_segments(model, data)
    femur = [s for s in segs if s[0] == "femur_r"]
    knee = data.oMf[model.body_frame["tibia_r"]].translation
    assert len(femur) == 1 and np.allclose(femur[0][2], knee)
    foot = next(s for s in segs if s[0] == "foot_r")  # a leaf: origin → 2 × COM
    com = next(bd.com for bd in model.bodies if bd.name == "foot_r")
    np.testing.assert_allclose(
        foot[2], data.oMf[model.body_frame["foot_r"]].act(2.0 * np.asarray(com)), atol=1e-12
    )


def test_usable_measurements_keep_those_whose_markers_all_exist():
    from msk.personalise.scaling import usable_measurements

    specs = [
        ("pelvis", (("RASI", "LASI"),), ("pelvis",)),
        Measurement("thigh", (("RASI", "RKNE"), ("LASI", "LKNE")), ("femur_r", "femur_l")),
    ]
    got = usable_measurements(specs, {"RASI", "LASI", "RKNE"})
    assert got == [Measurement("pelvis", (("RASI", "LASI"),), ("pelvis",))]
    assert len(usable_measurements(specs, {"RASI", "LASI", "RKNE", "LKNE"})) == 2
    assert usable_measurements(specs, ()) == []


# ---------------------------------------------------------------------------------------------
# scaling and marker placement without a static trial
# ---------------------------------------------------------------------------------------------
GAIT2392 = Path(__file__).resolve().parents[2] / "msk" / "data" / "models" / "gait2392.toml"
TRUE_FACTORS = {
    "pelvis": 1.06,
    "femur_r": 1.10,
    "femur_l": 1.09,
    "tibia_r": 0.94,
    "tibia_l": 0.95,
    "talus_r": 1.04,
    "calcn_r": 1.04,
    "toes_r": 1.04,
    "talus_l": 1.03,
    "calcn_l": 1.03,
    "toes_l": 1.03,
    "torso": 0.97,
}


@pytest.fixture(scope="module")
def gait2392():
    from msk.model.files import load_model

    return load_model(GAIT2392)


def _gait_poses(model, n=80):
    """A walking-like motion: hips ±30°, knees 0–60°, ankles ±15°, pelvis moving forward."""
    th = np.repeat(model.default_coordinates()[None], n, axis=0)
    ph = np.linspace(0.0, 2 * np.pi, n)
    c = model.coordinate_names
    for name, v in {
        "pelvis_tx": np.linspace(0.0, 1.4, n),
        "hip_flexion_r": 0.5 * np.sin(ph),
        "hip_flexion_l": -0.5 * np.sin(ph),
        "knee_angle_r": -0.5 * (1 - np.cos(ph)),
        "knee_angle_l": -0.5 * (1 + np.cos(ph)),
        "ankle_angle_r": 0.25 * np.sin(ph),
        "ankle_angle_l": -0.25 * np.sin(ph),
        "lumbar_extension": 0.05 * np.sin(2 * ph),
    }.items():
        th[:, c.index(name)] = v
    return th


def _motion(model, truth, noise_m=0.001, seed=0):
    th = _gait_poses(truth)
    x = marker_positions(truth, th)
    x = x + np.random.default_rng(seed).normal(0.0, noise_m, x.shape)
    return x, list(truth.marker_names), np.arange(len(th)) / 100.0


def test_scale_from_motion_measures_what_a_static_trial_would(gait2392):
    """A walk of a scaled gait2392 (known factors): the motion-derived factors equal those a
    static trial of the same subject gives (the measurement method's own values: ASIS–knee
    also carries the pelvis, so 1.091 for a femur stretched by 1.10), within 0.5 %."""
    from msk.personalise.scaling import SEGMENT_MEASUREMENTS, choose_measurements, scale_from_motion

    truth = apply_scale_factors(gait2392, TRUE_FACTORS)
    x, labels, t = _motion(gait2392, truth)
    pos = marker_positions(truth, truth.default_coordinates())[0]
    static = {n: np.repeat(pos[None, i], 3, axis=0) for i, n in enumerate(truth.marker_names)}
    meas = choose_measurements(SEGMENT_MEASUREMENTS, truth.marker_names)
    want, _ = measure_scale_factors(gait2392, static, meas)
    scaled, rep = scale_from_motion(gait2392, x, labels, t, body_mass=70.0)
    assert set(rep.methods) == {b.name for b in gait2392.bodies}
    assert set(rep.methods.values()) == {"motion markers"}
    for body, f in want.items():
        assert rep.factors[body][0] == pytest.approx(f[0], rel=0.005), body
        assert rep.factors[body][0] == pytest.approx(TRUE_FACTORS[body], rel=0.02), body
    assert scaled.total_mass == pytest.approx(70.0)
    assert scaled.metadata["scale_methods"]["femur_r"] == "motion markers"
    # knee–ankle spans the knee (flexed 0–60°): the plain median over frames (default-pose
    # model distance) is off by ~1 %; a pair on one segment (heel–toe) is the same either way
    _, plain = scale_from_motion(gait2392, x, labels, t, pose_matched=False)
    assert abs(plain.factors["tibia_r"][0] / want["tibia_r"][0] - 1) > 0.005
    assert plain.factors["calcn_r"][0] == pytest.approx(want["calcn_r"][0], rel=0.005)


def test_scale_from_motion_falls_back_on_height_and_says_so(gait2392):
    from msk.personalise.scaling import scale_from_motion

    truth = apply_scale_factors(gait2392, TRUE_FACTORS)
    x, labels, t = _motion(gait2392, truth)
    for name in ("R.Knee.Lat", "R.Knee.Med", "L.Knee.Lat", "L.Knee.Med"):
        x[:, labels.index(name)] = 0.0  # static-only markers carried as zeros (GC6 DM)
    _, rep = scale_from_motion(gait2392, x, labels, t, height_m=1.71)
    assert rep.height_factor == pytest.approx(1.71 / 1.80)
    for body in ("femur_r", "femur_l", "tibia_r", "tibia_l"):
        assert rep.methods[body] == "height"
        np.testing.assert_allclose(rep.factors[body], 1.71 / 1.80)
    assert rep.methods["pelvis"] == "motion markers"
    assert rep.factors["pelvis"][0] == pytest.approx(TRUE_FACTORS["pelvis"], rel=0.01)
    # no stature: the subject's size from the measured segments (median factor), never left
    # at the generic size while other segments say the subject is not generic
    _, rep = scale_from_motion(gait2392, x, labels, t)
    measured = [rep.factors[b][0] for b, m in rep.methods.items() if m == "motion markers"]
    assert rep.methods["tibia_r"] == "height"
    assert rep.height_factor == pytest.approx(np.median(measured))
    np.testing.assert_allclose(rep.factors["tibia_r"], rep.height_factor)
    assert not any("unscaled" in m for m in rep.messages)


def test_place_markers_from_motion_finds_each_clusters_bone_and_leaves_out_loose_markers(gait2392):
    from msk.personalise.scaling import place_markers_from_motion

    clusters = {
        "RTH1": ("femur_r", (0.03, -0.20, 0.07)),
        "RTH2": ("femur_r", (0.06, -0.28, 0.05)),
        "RSH1": ("tibia_r", (0.04, -0.15, 0.05)),
        "LSH1": ("tibia_l", (0.04, -0.20, -0.05)),
        "RPSI": ("pelvis", (-0.15, 0.06, 0.05)),
        "RMT2": ("calcn_r", (0.17, 0.03, 0.0)),
        "SKIN": ("femur_l", (0.05, -0.25, -0.06)),
    }
    truth = gait2392.with_markers(
        [*gait2392.markers, *(Marker(k, b, np.array(p)) for k, (b, p) in clusters.items())]
    )
    x, labels, t = _motion(gait2392, truth, noise_m=0.001)
    rng = np.random.default_rng(1)
    x[:, labels.index("SKIN")] += rng.normal(0.0, 0.05, (len(t), 3))  # not on any bone
    x[::4, labels.index("RTH1")] = np.nan  # gaps
    model, info = place_markers_from_motion(gait2392, x, labels, t, move=["R.Heel"], max_frames=40)
    expect = {k: b for k, (b, _) in clusters.items() if k != "SKIN"}
    assert info["placed"] == expect
    assert info["too_loose"]["SKIN"][1] > 0.02 and "SKIN" not in model.marker_names
    got = {m.name: m for m in model.markers}
    for k in expect:
        np.testing.assert_allclose(got[k].offset, clusters[k][1], atol=0.003)
        assert info["spread_m"][k] < 0.005
    assert info["ik_marker_rms_m"] < 0.003
    assert info["moved"]["R.Heel"] < 0.003
    with pytest.raises(ModelError, match=r"no marker 'R\.Nose' to move"):
        place_markers_from_motion(gait2392, x, labels, t, move=["R.Nose"])


def test_motion_scaling_of_grand_challenge_ps_agrees_with_its_static(real_dir, gait2392):
    """PS: the static trial (TRC) against the overground walk (c3d) — pelvis, feet, torso, and
    the whole leg (the walk has no knee or ankle marker)."""
    from msk.io import read_c3d
    from msk.io.frames import pelvis_heading_rotation
    from msk.io.opensim_files import read_trc
    from msk.model.markersets import recognise
    from msk.personalise.scaling import scale_from_motion, scale_from_static

    st = read_trc(real_dir / "knee-grand-challenge-gc5/PS_static_for_scaling.trc")
    m = recognise(st.labels, gait2392.marker_names)
    xs, ls = m.apply(st.markers, st.labels)
    _, rs = scale_from_static(gait2392, {lab: xs[:, i] for i, lab in enumerate(ls)})
    assert set(rs.methods.values()) == {"static markers"}
    tr = read_c3d(real_dir / "knee-grand-challenge-gc5/PS_ngait_og_ss1.c3d")
    m = recognise(tr.marker_labels, gait2392.marker_names, markers=tr.markers)
    h = pelvis_heading_rotation(
        tr.up, (0, 1, 0), tr.markers, tr.marker_labels, gait2392, rename=m.rename
    )
    x, labels = m.apply(tr.markers @ h.rotation.T, tr.marker_labels)
    _, rm = scale_from_motion(gait2392, x, labels, tr.time, height_m=1.67)
    for body in ("pelvis", "calcn_r", "calcn_l", "torso"):
        assert rm.methods[body] == "motion markers"
        assert rm.factors[body][0] == pytest.approx(rs.factors[body][0], rel=0.04), body
    # no knee or ankle marker in the walk: the whole leg from ASIS to heel (pose-matched)
    # scales femur and tibia alike; it agrees with the static's femur and tibia marker-pair
    # ratios weighted by the generic bone lengths (gait2392: 0.41 and 0.43 m) within 1 %, and
    # with the static's joint-centre factors (what the static scales by) within 4 %, where the
    # stature (1.67 / 1.80 = 0.93) would be 10 % short
    for side in "rl":
        assert rm.methods[f"femur_{side}"] == "motion markers"
        pair = (0.41 * rs.ratios[f"femur_{side}"] + 0.43 * rs.ratios[f"tibia_{side}"]) / 0.84
        assert rm.factors[f"femur_{side}"][0] == pytest.approx(pair, rel=0.01)
        leg = (0.41 * rs.factors[f"femur_{side}"][0] + 0.43 * rs.factors[f"tibia_{side}"][0]) / 0.84
        assert rm.factors[f"femur_{side}"][0] == pytest.approx(leg, rel=0.04)


def _jc_subject(gait2392, factors, *, sacrum=True, medial=True, noise_m=0.002, seed=1):
    """A static trial of gait2392 scaled by ``factors`` whose epicondyle and malleolus markers
    straddle the knee and ankle joint centres (ISB), in a random pose of the whole body."""
    from msk.model.core import Marker

    truth = apply_scale_factors(gait2392, factors)
    data = truth.create_data()
    forward_kinematics(truth, data, truth.default_coordinates())

    def local(body, child):
        o = data.oMf[truth.body_frame[body]]
        return np.asarray(o.actInv(data.oMf[truth.body_frame[child]].translation))

    mk = []
    for m in truth.markers:
        side = m.name[0].lower()
        if m.name[1:] in (".Knee.Lat", ".Knee.Med"):
            c = local(f"femur_{side}", f"tibia_{side}")
        elif m.name[1:] in (".Ankle.Lat", ".Ankle.Med"):
            c = local(f"tibia_{side}", f"talus_{side}")
        else:
            mk.append(m)
            continue
        lat = (1 if side == "r" else -1) * (1 if m.name.endswith("Lat") else -1)
        mk.append(Marker(m.name, m.body, c + np.array([0.0, 0.0, 0.05 * lat])))
    if not sacrum:  # IOR/CAST: two PSIS, no sacral marker
        sac = next(m for m in mk if m.name == "V.Sacral")
        mk = [m for m in mk if m.name != "V.Sacral"]
        for s, z in (("R", 0.05), ("L", -0.05)):
            mk.append(Marker(f"{s}PSIS", "pelvis", sac.offset + np.array([0.0, 0.0, z])))
    if not medial:
        mk = [m for m in mk if not m.name.endswith("Med")]
    truth = truth.with_markers(mk)
    q = truth.default_coordinates()
    c = truth.coordinate_names
    for name, v in {"pelvis_tilt": 0.2, "pelvis_rotation": 1.1, "pelvis_tx": 0.4,
                    "hip_flexion_r": 0.1, "knee_angle_l": -0.05}.items():  # fmt: skip
        q[c.index(name)] = v
    pos = marker_positions(truth, q[None])[0]
    rng = np.random.default_rng(seed)
    return {n: pos[i] + rng.normal(0.0, noise_m, (30, 3)) for i, n in enumerate(truth.marker_names)}


def test_joint_centre_scaling_recovers_thigh_and_shank_lengths(gait2392):
    """Thigh and shank from hip–knee and knee–ankle joint-centre distances (Kainz 2017):
    a subject with a long femur and a short tibia, 2 mm marker noise, any pose — the factors
    come back within 1.5 %, where the marker pairs (ASIS–knee, knee–ankle with gait2392's
    malleolus markers 3 cm above the joint) are off by more; scale_from_static uses them."""
    from msk.personalise.scaling import joint_centre_scale_factors, scale_from_static

    f = {"pelvis": 1.04, "femur_r": 1.12, "femur_l": 1.10, "tibia_r": 0.96, "tibia_l": 0.98}
    static = _jc_subject(gait2392, f)
    got, details = joint_centre_scale_factors(gait2392, static, pelvis_factor=1.04)
    assert set(got) == {"femur_r", "femur_l", "tibia_r", "tibia_l"}
    for body, v in got.items():
        assert v == pytest.approx(f[body], rel=0.015), body
    assert details["tibia_r (joint centres)"]["model_m"] == pytest.approx(0.43)
    _, rep = scale_from_static(gait2392, static)
    assert rep.factors["tibia_r"][0] == pytest.approx(f["tibia_r"], rel=0.015)
    assert rep.factors["femur_l"][0] == pytest.approx(f["femur_l"], rel=0.015)
    assert rep.ratios["tibia_r"] > 1.05 * f["tibia_r"]  # the marker pair, for the record
    assert "femur_r (joint centres)" in rep.ratios


def test_joint_centre_scaling_uses_the_psis_and_needs_the_medial_markers(gait2392):
    """An IOR/CAST pelvis (two PSIS, no sacral marker) still carries the hip centres; a
    static without medial markers gives no joint-centre factor (the marker pairs stay)."""
    from msk.personalise.scaling import joint_centre_scale_factors, scale_from_static

    f = {"pelvis": 0.97, "femur_r": 1.05, "femur_l": 1.05, "tibia_r": 1.08, "tibia_l": 1.08}
    got, _ = joint_centre_scale_factors(
        gait2392, _jc_subject(gait2392, f, sacrum=False), pelvis_factor=0.97
    )
    assert got["femur_r"] == pytest.approx(1.05, rel=0.015)
    assert got["tibia_l"] == pytest.approx(1.08, rel=0.015)
    lateral = _jc_subject(gait2392, f, medial=False)
    assert joint_centre_scale_factors(gait2392, lateral, pelvis_factor=0.97)[0] == {}
    _, rep = scale_from_static(gait2392, lateral)
    assert not any("joint centres" in k for k in rep.ratios)


def test_place_markers_moves_the_acromia_of_a_model_without_shoulder_girdle(gait2392):
    """gait2392's acromion markers sit on its rigid torso where the generic trunk puts them:
    a subject whose acromia are 4 cm higher gets them moved there by the static placement,
    without naming them in ``move``; the static pose is solved without them."""
    from msk.model.core import Marker
    from msk.personalise.scaling import place_markers

    up = np.array([0.0, 0.04, 0.0])
    truth = gait2392.with_markers(
        [Marker(m.name, m.body, m.offset + up) if "Acromium" in m.name else m
         for m in gait2392.markers]
    )  # fmt: skip
    q = truth.default_coordinates()
    x = np.repeat(marker_positions(truth, q[None]), 5, axis=0)
    placed, info = place_markers(gait2392, x, truth.marker_names, np.arange(5) / 100.0)
    assert set(info["moved"]) == {"R.Acromium", "L.Acromium"}
    assert info["moved"]["R.Acromium"] == pytest.approx(0.04, abs=1e-6)
    assert info["static_marker_rms_m"] < 1e-6
    got = {m.name: m.offset for m in placed.markers}
    want = {m.name: m.offset for m in truth.markers}
    np.testing.assert_allclose(got["L.Acromium"], want["L.Acromium"], atol=1e-6)


def test_unobserved_knees_take_the_flexion_branch_in_placement(gait2392):
    """Without a tracked model marker on the femur or the tibia (Grand Challenge DM's walks: no
    epicondyle or malleolus marker), the placement passes bound the knee to the flexion side
    of 0 (gait2392: [−120°, 10°] → [−120°, 0°]); with the knee markers tracked, nothing."""
    from msk.personalise.scaling import unobserved_knees_flexed

    x, labels, _ = _motion(gait2392, gait2392)
    assert unobserved_knees_flexed(gait2392, x, labels, 10) == {}
    body_of = {mk.name: mk.body for mk in gait2392.markers}
    legs = [i for i, lab in enumerate(labels) if body_of[lab].startswith(("femur", "tibia"))]
    x2 = x.copy()
    x2[:, legs] = np.nan
    lo, _ = dict(zip(gait2392.coordinate_names, zip(*gait2392.coordinate_bounds())))["knee_angle_r"]
    got = unobserved_knees_flexed(gait2392, x2, labels, 10)
    assert got == {"knee_angle_r": (lo, 0.0), "knee_angle_l": (lo, 0.0)}
    flexed = gait2392.with_coordinate_ranges(got)
    assert flexed.coordinate_bounds()[1][flexed.coordinate_names.index("knee_angle_r")] == 0.0


def test_place_markers_from_motion_keeps_the_only_markers_of_a_body_when_loose(gait2392):
    """Thigh cluster markers with 25 mm of skin motion (spread above the 20 mm limit): left out
    while the femur's own markers are tracked, kept (``kept_loose``) when nothing else observes
    the femur — a thigh with no marker lets IK swing the knee (DM og4)."""
    from msk.personalise.scaling import place_markers_from_motion

    clusters = {
        "RTH1": ("femur_r", (0.03, -0.20, 0.07)),
        "RTH2": ("femur_r", (0.06, -0.28, 0.05)),
        "RTH3": ("femur_r", (0.00, -0.24, 0.08)),
    }
    truth = gait2392.with_markers(
        [*gait2392.markers, *(Marker(k, b, np.array(p)) for k, (b, p) in clusters.items())]
    )
    x, labels, t = _motion(gait2392, truth, noise_m=0.001)
    rng = np.random.default_rng(2)
    for k in clusters:
        x[:, labels.index(k)] += rng.normal(0.0, 0.025 / np.sqrt(3.0), (len(t), 3))
    _, info = place_markers_from_motion(gait2392, x, labels, t, max_frames=40)
    assert set(info["too_loose"]) == set(clusters) and not info["kept_loose"]
    femur = [mk.name for mk in gait2392.markers if mk.body == "femur_r"]
    x[:, [labels.index(lab) for lab in femur]] = np.nan
    model, info = place_markers_from_motion(gait2392, x, labels, t, max_frames=40)
    assert set(info["kept_loose"]) == set(clusters) and not info["too_loose"]
    assert {k: info["placed"][k] for k in clusters} == {k: b for k, (b, _) in clusters.items()}
    assert set(clusters) <= set(model.marker_names)


def test_motion_placement_takes_the_walks_median_subtalar_as_neutral(gait2392):
    """No static trial, every foot marker moved: the subtalar offset is a gauge (the markers
    rotated on the calcaneus about its axis by δ and the joint by −δ fit equally). A lab's foot
    markers sitting where gait2392's would be with the subtalar 25° inverted (truth: subtalar
    ±6° about 0 through the walk) put the walk's subtalar at a median of ~25° unless
    ``median_neutral`` takes the walk's median as the joint's neutral: then within 2°."""
    from msk.kinematics.ik import solve_kinematics
    from msk.personalise.coordinates import free_foot_coordinates
    from msk.personalise.scaling import place_markers_from_motion

    th = _gait_poses(gait2392)
    c = gait2392.coordinate_names
    th[:, c.index("subtalar_angle_r")] = 0.1 * np.sin(np.linspace(0.0, 4 * np.pi, len(th)))
    x = marker_positions(gait2392, th)
    shifted = th.copy()
    shifted[:, c.index("subtalar_angle_r")] += np.radians(25.0)
    xs = marker_positions(gait2392, shifted)
    labels = list(gait2392.marker_names)
    feet = [m.name for m in gait2392.markers if m.body == "calcn_r"]
    for name in feet:
        x[:, labels.index(name)] = xs[:, labels.index(name)]
    x = x + np.random.default_rng(3).normal(0.0, 0.001, x.shape)
    t = np.arange(len(th)) / 100.0
    assert free_foot_coordinates(gait2392, feet) == ("subtalar_angle_r",)
    assert free_foot_coordinates(gait2392, feet[:-1]) == ()  # one marker kept: it observes
    # a generic marker the trial lacks observes nothing
    assert free_foot_coordinates(gait2392, feet[:-1], present=feet[:-1]) == ("subtalar_angle_r",)
    medians = {}
    for neutral in ((), ("subtalar_angle_r",)):
        model, info = place_markers_from_motion(
            gait2392, x, labels, t, move=feet, median_neutral=neutral, max_frames=40
        )
        kin = solve_kinematics(model, x, labels, t, cutoff_hz=None)
        medians[neutral] = np.degrees(np.median(kin.q_raw[:, c.index("subtalar_angle_r")]))
        assert kin.marker_rms.mean() < 0.003  # the same fit either way
        if neutral:
            assert np.degrees(info["median_neutral"]["subtalar_angle_r"]) == pytest.approx(
                25.0, abs=2.0
            )
    assert medians[()] == pytest.approx(25.0, abs=2.0)
    assert abs(medians[("subtalar_angle_r",)]) < 2.0


def test_a_short_tracked_window_is_placed_over_all_of_it_not_its_middle(gait2392):
    """Issue 15, twelfth pass: a running trial tracks its markers over ~1 s at 250 Hz, fewer
    frames than the placement takes (120) at its 60 Hz; the placement then uses all of the
    window at the highest rate that fits, not its middle 120 frames (0.48 s, one phase of a
    stride). Truth: the subtalar at 0 except a 20° bump over the middle 40 % of the window
    (250 frames), every foot marker moved: the walk's median (0) becomes the joint's neutral
    and the trial's IK sees the subtalar at a median within 2° of 0 (from the middle frames
    alone the median would be ~20°, and the trial's IK at ~−20°)."""
    from msk.kinematics.ik import solve_kinematics
    from msk.personalise.scaling import place_markers_from_motion

    n = 250
    th = _gait_poses(gait2392, n=n)
    c = gait2392.coordinate_names
    i = np.arange(n)
    th[:, c.index("subtalar_angle_r")] = np.radians(20.0) * np.exp(-(((i - 125) / 50.0) ** 16))
    x = marker_positions(gait2392, th) + np.random.default_rng(3).normal(0.0, 0.001, (n, 1, 3))
    labels = list(gait2392.marker_names)
    feet = [m.name for m in gait2392.markers if m.body == "calcn_r"]
    t = i / 250.0
    assert np.degrees(np.median(th[65:185, c.index("subtalar_angle_r")])) > 15.0
    model, info = place_markers_from_motion(
        gait2392, x, labels, t, move=feet, median_neutral=("subtalar_angle_r",)
    )
    assert info["frames"] == 84  # every third frame of the 250
    assert abs(np.degrees(info["median_neutral"]["subtalar_angle_r"])) < 2.0
    kin = solve_kinematics(model, x, labels, t, cutoff_hz=None)
    assert abs(np.degrees(np.median(kin.q_raw[:, c.index("subtalar_angle_r")]))) < 2.0


def test_a_trunk_with_one_tracked_marker_is_pulled_to_neutral_in_placement(gait2392):
    """A terminal body its tracked markers do not pin (a trunk with its sternum only, the lab's
    neck and shoulder markers still to place; toes with none) has its joint's rotations pulled
    towards neutral in the placement passes; a trunk with 2 markers does not, nor does a leg.
    Placement then puts the lab's trunk markers on the torso where they are."""
    from msk.personalise.scaling import (
        NEUTRAL_TASK_WEIGHT,
        place_markers_from_motion,
        unobserved_end_rotations,
    )

    trunk = {
        "NECK": ("torso", (-0.06, 0.40, 0.0)),
        "RSHO": ("torso", (-0.02, 0.38, 0.17)),
        "LSHO": ("torso", (-0.02, 0.38, -0.17)),
        "THOR": ("torso", (-0.12, 0.25, 0.0)),
    }
    truth = gait2392.with_markers(
        [*gait2392.markers, *(Marker(k, b, np.array(p)) for k, (b, p) in trunk.items())]
    )
    x, labels, t = _motion(gait2392, truth, noise_m=0.001)
    lumbar = {"lumbar_extension", "lumbar_bending", "lumbar_rotation"}
    every = unobserved_end_rotations(gait2392, x, labels, 10)
    assert set(every) == {"mtp_angle_r", "mtp_angle_l"}  # no marker on the toes
    for name in ("R.Acromium", "Top.Head"):
        x[:, labels.index(name)] = np.nan  # two markers and the lumbar joint pin the trunk
    assert set(unobserved_end_rotations(gait2392, x, labels, 10)) == set(every)
    x[:, labels.index("L.Acromium")] = np.nan  # the torso keeps its sternum only
    pulled = unobserved_end_rotations(gait2392, x, labels, 10)
    assert set(pulled) == lumbar | {"mtp_angle_r", "mtp_angle_l"}
    assert all(v == (0.0, NEUTRAL_TASK_WEIGHT) for v in pulled.values())
    model, info = place_markers_from_motion(gait2392, x, labels, t, max_frames=40)
    assert set(info["unobserved_rotations"]) == {"mtp_angle_r", "mtp_angle_l"}  # last pass
    got = {m.name: m for m in model.markers}
    for k, (body, p) in trunk.items():
        assert info["placed"][k] == body
        np.testing.assert_allclose(got[k].offset, p, atol=0.005)


def test_motion_placement_gives_near_ties_to_the_landmarks_body(gait2392):
    """A PSIS over a lumbar joint the walk hardly moves is as rigid on the torso as on the
    pelvis: the spread cannot tell them apart and the nearest bone may be the torso's. With the
    marker set's landmark hint (PSIS → pelvis) the tie goes to the pelvis; a hint outside the
    tie (a body the marker moves on) changes nothing."""
    from msk.personalise.scaling import place_markers_from_motion

    lab = {"LPSI": ("pelvis", (-0.17, 0.10, -0.04)), "RPSI": ("pelvis", (-0.17, 0.10, 0.04))}
    truth = gait2392.with_markers(
        [*gait2392.markers, *(Marker(k, b, np.array(p)) for k, (b, p) in lab.items())]
    )
    x, labels, t = _motion(gait2392, truth, noise_m=0.001)
    _, plain = place_markers_from_motion(gait2392, x, labels, t, max_frames=40)
    # the walk's lumbar joint hardly moves (±3°): without the hint the tie goes to the nearest
    # bone, the torso's (DM's and JW's L_Psis before the hint)
    assert {plain["placed"][k] for k in lab} == {"torso"}
    hinted, info = place_markers_from_motion(
        gait2392, x, labels, t, max_frames=40,
        hints={"LPSI": "pelvis", "RPSI": "pelvis"},
    )  # fmt: skip
    got = {m.name: m for m in hinted.markers}
    for k, (body, p) in lab.items():
        assert info["placed"][k] == body
        np.testing.assert_allclose(got[k].offset, p, atol=0.005)
    _, wrong = place_markers_from_motion(
        gait2392, x, labels, t, max_frames=40, hints={"LPSI": "femur_l"}
    )
    assert wrong["placed"]["LPSI"] == plain["placed"]["LPSI"]


def _pelvis_and_feet_walk(gait2392, noise_m=0.001, seed=4):
    """A walk with gait2392's pelvis and foot markers only (UWA, DM: no knee, thigh or shank
    model marker) and a lab's thigh and shank clusters, each marker with 4 mm of skin motion;
    the hips rotate ±8° about their long axes (the direction pelvis and feet leave free)."""
    clusters = {
        "RTH1": ("femur_r", (0.03, -0.20, 0.07)),
        "RTH2": ("femur_r", (0.06, -0.28, 0.05)),
        "RTH3": ("femur_r", (0.00, -0.24, 0.08)),
        "RTB1": ("tibia_r", (0.04, -0.15, 0.05)),
        "RTB2": ("tibia_r", (0.03, -0.22, 0.06)),
        "LTH1": ("femur_l", (0.03, -0.20, -0.07)),
        "LTH2": ("femur_l", (0.06, -0.28, -0.05)),
        "LTB1": ("tibia_l", (0.04, -0.15, -0.05)),
        "LTB2": ("tibia_l", (0.03, -0.22, -0.06)),
    }
    truth = gait2392.with_markers(
        [*gait2392.markers, *(Marker(k, b, np.array(p)) for k, (b, p) in clusters.items())]
    )
    th = _gait_poses(truth, n=160)
    c = truth.coordinate_names
    ph = np.linspace(0.0, 2 * np.pi, len(th))
    th[:, c.index("hip_rotation_r")] = np.radians(8.0) * np.sin(ph + 1.0)
    th[:, c.index("hip_rotation_l")] = np.radians(8.0) * np.sin(ph - 1.0)
    rng = np.random.default_rng(seed)
    x = marker_positions(truth, th) + rng.normal(0.0, noise_m, (len(th), len(truth.markers), 3))
    labels = list(truth.marker_names)
    for k in clusters:
        x[:, labels.index(k)] += rng.normal(0.0, 0.004 / np.sqrt(3.0), (len(th), 3))
    keep = {m.name for m in gait2392.markers if m.body.startswith(("pelvis", "calcn", "toes"))}
    for i, lab in enumerate(labels):
        if lab not in keep and lab not in clusters:
            x[:, i] = np.nan
    return x, labels, np.arange(len(th)) / 100.0, clusters


def _ik_cost(x, labels, t):
    """The walk's own IK cost of a placed model: mean over frames of the marker RMS (the
    unobserved knees on their flexion branch, as in the placement passes)."""
    from msk.kinematics.ik import solve_kinematics
    from msk.personalise.scaling import unobserved_knees_flexed

    def cost(model, info):
        flexed = unobserved_knees_flexed(model, x, labels, 10)
        on = model.with_coordinate_ranges(flexed) if flexed else model
        kin = solve_kinematics(on, x, labels, t, cutoff_hz=None, min_markers=3)
        return float(np.nanmean(kin.marker_rms))

    return cost


def _placed_and_refined(model, x, labels, t, **kw):
    from msk.personalise.scaling import place_markers_from_motion, refine_placement_from_motion

    start = place_markers_from_motion(model, x, labels, t, max_frames=40, regularize=True)
    got_model, got = refine_placement_from_motion(
        model, x, labels, t, start, _ik_cost(x, labels, t), max_frames=40, **kw
    )
    return start, got_model, got


@pytest.mark.slow
def test_refined_motion_placement_descends_to_the_truth_and_is_stable(gait2392):
    """Issue 15, tenth pass: the placement pulled towards neutral (unique, but the pull holds
    the ±8° hip rotation pelvis and feet do not observe: clusters up to 67 mm off their true
    offsets), then alternated with IK while the walk's own IK cost decreases
    (:func:`msk.personalise.scaling.refine_placement_from_motion`): the cost falls at every kept
    round,
    12 → < 3 mm, and every cluster ends within 8 mm of its truth. Repeated with the markers +
    0.1 mm noise and with the first frame dropped (``studies/placement_jitter.py``'s
    perturbations): the same bodies, the cost within 0.05 mm, the offsets within 6 mm of the
    unperturbed run's. Eleventh pass: the rounds are squared extrapolations (SQUAREM) and stop
    by the relative-decrease rule, not the round cap (3 rounds of 3 passes here: the plain
    alternation took 12 rounds of 2 passes to 2.7 mm). Run with the pipeline's stopping rule
    (:data:`msk.personalise.placement.DESCENT_REL_TOLERANCE`, 2 %; the function's default is
    0.1 %)."""
    from msk.personalise.placement import DESCENT_REL_TOLERANCE

    x, labels, t, clusters = _pelvis_and_feet_walk(gait2392)
    tol = {"rel_tolerance": DESCENT_REL_TOLERANCE}
    start, ref_model, ref = _placed_and_refined(gait2392, x, labels, t, **tol)
    path = ref["descent_cost_m"]
    assert all(b < a for a, b in itertools.pairwise(path)) and len(path) >= 3
    assert ref["descent_stop"] != "max_rounds"
    assert path[0] > 0.010 and path[-1] < 0.003
    assert ref["regularized"] is True
    truth = {k: b for k, (b, _) in clusters.items()}
    assert {k: ref["placed"][k] for k in clusters} == truth
    off0 = {m.name: np.asarray(m.offset) for m in start[0].markers}
    off = {m.name: np.asarray(m.offset) for m in ref_model.markers}
    assert max(np.linalg.norm(off0[k] - np.array(p)) for k, (_, p) in clusters.items()) > 0.05
    for k, (_, p) in clusters.items():
        assert np.linalg.norm(off[k] - np.array(p)) < 0.008, k
    rng = np.random.default_rng(5)
    for xr, tr in [(x + rng.normal(0.0, 1e-4, x.shape), t), (x[1:], t[1:])]:
        _, got_model, got = _placed_and_refined(gait2392, xr, labels, tr, **tol)
        assert {k: got["placed"][k] for k in clusters} == truth
        assert abs(got["descent_cost_m"][-1] - path[-1]) < 5e-5
        got_off = {m.name: np.asarray(m.offset) for m in got_model.markers}
        for k in clusters:
            assert np.linalg.norm(got_off[k] - off[k]) < 0.006, k


@pytest.mark.slow
def test_the_descents_weak_pull_does_not_bias_the_placement(gait2392, monkeypatch):
    """Issue 15, twelfth pass: the descent's passes pull every rotation towards neutral by
    :data:`msk.personalise.scaling.DESCENT_NEUTRAL_WEIGHT` (1e-5 /rad²: one marker 3 mm off per
    rad), which
    makes each pass's minimum unique on UWA's cluster-only legs (its unpulled passes jumped
    between basins). On the synthetic walk (±8° of hip rotation pelvis and feet do not see,
    known offsets) the pull changes nothing the markers can see: the same final cost to
    0.05 mm, every cluster within 0.5 mm of the unpulled descent's offsets (0.07 mm measured)
    and within 8 mm of its truth; the placement's own pull (:data:`msk.personalise.scaling.
    NEUTRAL_TASK_WEIGHT`, 100× more) kept in the passes would move them by more than 2 mm
    (4.4 mm measured)."""
    import msk.personalise.scaling as scaling

    x, labels, t, clusters = _pelvis_and_feet_walk(gait2392)
    _, pulled_model, pulled = _placed_and_refined(gait2392, x, labels, t)
    ref = {m.name: np.asarray(m.offset) for m in pulled_model.markers}
    moved = {}
    for w in (0.0, scaling.NEUTRAL_TASK_WEIGHT):
        monkeypatch.setattr(scaling, "DESCENT_NEUTRAL_WEIGHT", w)
        _, got_model, got = _placed_and_refined(gait2392, x, labels, t)
        off = {m.name: np.asarray(m.offset) for m in got_model.markers}
        moved[w] = max(np.linalg.norm(off[k] - ref[k]) for k in clusters)
        if w == 0.0:
            assert abs(got["descent_cost_m"][-1] - pulled["descent_cost_m"][-1]) < 5e-5
    assert moved[0.0] < 0.0005
    assert moved[scaling.NEUTRAL_TASK_WEIGHT] > 0.002
    assert max(
        np.linalg.norm(np.asarray(m.offset) - np.array(clusters[m.name][1]))
        for m in pulled_model.markers if m.name in clusters
    ) < 0.008  # fmt: skip


@pytest.mark.slow
def test_motion_scaling_and_placement_do_not_depend_on_the_lab_frame(gait2392):
    """Issue 15, tenth pass: the same walk recorded in a lab frame rotated 37° about the
    vertical and translated by metres (4.5 m sideways: beyond gait2392's ±3 m bound on
    ``pelvis_tz``), brought to the model frame as the model stage does (the progression's
    heading, :func:`msk.io.lab_to_model_rotation`, then
    :func:`msk.personalise.task_markers.lab_origin_offset`): the same scale factors and marker
    offsets to 1e-9. Without the translation (the markers as the lab gives them) the placement
    loses the clusters."""
    from msk.io.frames import lab_to_model_rotation
    from msk.personalise.scaling import scale_from_motion
    from msk.personalise.task_markers import lab_origin_offset

    x, labels, t, clusters = _pelvis_and_feet_walk(gait2392)
    up = (0.0, 1.0, 0.0)

    def in_lab(yaw_deg, shift):
        a = np.radians(yaw_deg)
        r = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
        return x @ r.T + np.asarray(shift)

    def built(xl, centre=True):
        xm = xl @ lab_to_model_rotation(up, up, xl).T
        if centre:
            xm = xm - lab_origin_offset(gait2392, xm)
        scaled, rep = scale_from_motion(gait2392, xm, labels, t, height_m=1.8)
        _, got_model, _ = _placed_and_refined(scaled, xm, labels, t)
        return rep.factors, {m.name: np.asarray(m.offset) for m in got_model.markers}

    ref_f, ref_o = built(in_lab(0.0, (0.0, 0.0, 0.0)))
    got_f, got_o = built(in_lab(37.0, (4.0, 1.5, 4.5)))
    for b in ref_f:
        np.testing.assert_allclose(got_f[b], ref_f[b], atol=1e-9)
    assert set(got_o) == set(ref_o)
    for k in ref_o:
        np.testing.assert_allclose(got_o[k], ref_o[k], atol=1e-9)
    _, raw_o = built(in_lab(37.0, (4.0, 1.5, 4.5)), centre=False)
    assert not set(clusters) <= set(raw_o) or any(
        np.linalg.norm(raw_o[k] - ref_o[k]) > 0.01 for k in clusters
    )


@pytest.mark.slow
def test_squared_extrapolation_descends_as_far_in_fewer_passes(gait2392, monkeypatch):
    """Issue 15, eleventh pass: on the synthetic pelvis-and-feet walk, the descent with squared
    extrapolation (SQUAREM, :func:`msk.personalise.scaling.refine_placement_from_motion`'s default)
    ends
    no higher than the plain alternation of placement passes and IK after 12 rounds of 2
    passes (the tenth pass's descent, run here with ``accelerate=False``), in at most half
    the passes, and stopped by its own rule (not the round cap)."""
    import msk.personalise.scaling as scaling

    x, labels, t, _ = _pelvis_and_feet_walk(gait2392)
    cost = _ik_cost(x, labels, t)
    start = scaling.place_markers_from_motion(
        gait2392, x, labels, t, max_frames=40, regularize=True
    )
    calls = [0]
    place = scaling.place_markers_from_motion

    def counted(*a, **k):
        calls[0] += 1
        return place(*a, **k)

    monkeypatch.setattr(scaling, "place_markers_from_motion", counted)

    def run(**kw):
        calls[0] = 0
        _, got = scaling.refine_placement_from_motion(
            gait2392, x, labels, t, start, cost, max_frames=40, **kw
        )
        return got, calls[0]

    plain, n_plain = run(accelerate=False, rel_tolerance=0.0, max_rounds=12)
    fast, n_fast = run()
    assert n_plain == 24 and plain["descent_stop"] == "max_rounds"
    assert fast["descent_stop"] in ("relative decrease", "no decrease")
    assert n_fast <= n_plain // 2  # measured: 12 passes, 2.70 mm; plain 24 passes, 2.72 mm
    assert fast["descent_cost_m"][-1] <= plain["descent_cost_m"][-1] + 1e-5


def test_place_markers_from_motion_never_puts_a_sided_label_on_the_other_side(gait2392):
    """A marker labelled right (R_Midfoot_Medial) that rides on the left foot — as rigid there as
    a still right foot marker is on either still foot in a squat (issue 15, thirteenth pass:
    R_Midfoot_Medial went to toes_l) — is not placed on any left body; an unsided marker on the
    left foot is."""
    from msk.personalise.scaling import place_markers_from_motion

    extra = {"R_Midfoot_Medial": ("calcn_l", (0.12, 0.03, 0.03)),
             "Midfoot_X": ("calcn_l", (0.12, 0.03, 0.03))}  # fmt: skip
    truth = gait2392.with_markers(
        [*gait2392.markers, *(Marker(k, b, np.array(p)) for k, (b, p) in extra.items())]
    )
    x, labels, t = _motion(gait2392, truth, noise_m=0.001)
    _, info = place_markers_from_motion(gait2392, x, labels, t, max_frames=40)
    assert info["placed"]["Midfoot_X"] == "calcn_l"
    body = info["placed"].get("R_Midfoot_Medial") or info["too_far"].get("R_Midfoot_Medial",
                                                                          [""])[0]  # fmt: skip
    assert not str(body).endswith("_l"), info


def test_unobserved_leg_starts_take_the_larger_of_default_pose_and_stature():
    from msk.personalise.scaling import (
        SEGMENT_MEASUREMENTS,
        choose_measurements,
        unobserved_leg_starts,
    )

    have = ["R.ASIS", "L.ASIS", "V.Sacral", "R.Heel", "L.Heel", "R.Toe.Tip", "L.Toe.Tip"]
    meas = choose_measurements(SEGMENT_MEASUREMENTS, have)
    assert {m.name for m in meas} >= {"leg_r", "leg_l", "pelvis"}
    ratios = {"pelvis": 1.0, "leg_r": 0.83, "leg_l": 0.95, "foot_r": 0.9, "foot_l": 0.9}
    got = unobserved_leg_starts(ratios, meas, 1.0)
    assert set(got) == {"leg_r", "leg_l"}  # pairs across an unobserved knee only
    # 17 % short of the stature's leg: a knee flexed through the trial (a run), both legs
    assert got["leg_r"]["start"] == 1.0 and got["leg_r"]["source"] == "stature"
    assert got["leg_l"]["start"] == 1.0 and got["leg_l"]["source"] == "stature"
    # 5 % short: a walk's median knee flexion, the default pose kept (the rule before)
    walk = unobserved_leg_starts({**ratios, "leg_r": 0.96}, meas, 1.0)
    assert {k: (v["start"], v["source"]) for k, v in walk.items()} == {
        "leg_r": (0.96, "default pose"),
        "leg_l": (0.95, "default pose"),
    }
    # a run whose other leg measures above the stature's keeps that one's own
    above = unobserved_leg_starts({**ratios, "leg_l": 1.02}, meas, 1.0)
    assert above["leg_l"]["start"] == 1.02 and above["leg_r"]["source"] == "stature"
    none = unobserved_leg_starts(ratios, meas, None)  # no stature: the default pose, as before
    assert {k: v["start"] for k, v in none.items()} == {"leg_r": 0.83, "leg_l": 0.95}
    # a knee marker measures the femur itself: no leg measurement, no start
    knees = choose_measurements(SEGMENT_MEASUREMENTS, [*have, "R.Knee.Lat", "L.Knee.Lat"])
    assert unobserved_leg_starts({"femur_r": 0.8, "femur_l": 0.8}, knees, 1.0) == {}


def _pelvis_and_feet_window(gait2392, legs, knee_deg, seed, n=250):
    """One stride over ``n`` frames at 250 Hz (1 s: a running trial's tracked window) of a
    gait2392 whose femur and tibia are scaled by ``legs`` (r, l), with its pelvis and foot
    markers only (no knee, thigh or shank marker: the leg is measured ASIS to heel), 1 mm of
    marker noise; the knees flex between ``knee_deg`` (never straight in a run)."""
    f = {f"{b}_{s}": v for s, v in zip("rl", legs) for b in ("femur", "tibia")}
    truth = apply_scale_factors(gait2392, f)
    th = np.repeat(truth.default_coordinates()[None], n, axis=0)
    ph = np.linspace(0.0, 2 * np.pi, n)
    c = truth.coordinate_names
    lo, hi = np.radians(knee_deg)
    for name, v in {
        "pelvis_tx": np.linspace(0.0, 2.0, n),
        "hip_flexion_r": 0.4 * np.sin(ph),
        "hip_flexion_l": -0.4 * np.sin(ph),
        "knee_angle_r": -(lo + (hi - lo) * 0.5 * (1 - np.cos(ph))),
        "knee_angle_l": -(lo + (hi - lo) * 0.5 * (1 + np.cos(ph))),
        "ankle_angle_r": 0.3 * np.sin(ph),
        "ankle_angle_l": -0.3 * np.sin(ph),
    }.items():
        th[:, c.index(name)] = v
    x = marker_positions(truth, th)
    x = x + np.random.default_rng(seed).normal(0.0, 0.001, x.shape)
    keep = [
        i for i, mk in enumerate(truth.markers) if mk.body.startswith(("pelvis", "calcn", "toes"))
    ]
    labels = [truth.marker_names[i] for i in keep]
    return x[:, keep], labels, np.arange(n) / 250.0


def test_a_running_windows_legs_start_from_the_stature_and_come_out_equal(gait2392):
    """Issue 15, thirteenth pass: a 1 s running window (knees flexed 20–92° throughout) with
    pelvis and foot markers only. Truth: both legs the stature's (× 1.00 of gait2392, 1.80 m).
    The default-pose ratio of ASIS to heel measures the flexed knee (~0.83 of the leg); from
    there (no stature given, the rule before) the pose-matched measurement ends 7–10 % short.
    From the stature's leg, both legs end within 0.5 % of the truth and of each other in every
    noise draw, and the report says the motion did not determine them (a flexed knee reaches
    the feet with any leg at least that long)."""
    from msk.personalise.scaling import scale_from_motion

    for seed in range(3):
        x, labels, t = _pelvis_and_feet_window(gait2392, (1.0, 1.0), (20.0, 92.0), seed)
        _, rep = scale_from_motion(gait2392, x, labels, t, height_m=1.80)
        r, lft = rep.ratios["leg_r"], rep.ratios["leg_l"]
        assert r == pytest.approx(1.0, abs=0.005) and lft == pytest.approx(1.0, abs=0.005), seed
        assert abs(lft / r - 1.0) < 0.005
        for side in ("leg_r", "leg_l"):
            assert rep.details[side]["start"]["source"] == "stature"
            assert rep.details[side]["start"]["default_pose"] < 0.9
            assert rep.details[side]["determined"] is False
        assert sum("do not determine its length" in m for m in rep.messages) == 2
        assert rep.summary()["leg_starts"]["leg_l"]["start"] == pytest.approx(1.0)
        _, before = scale_from_motion(gait2392, x, labels, t)  # no stature: the default pose
        assert before.ratios["leg_r"] < 0.95 and before.ratios["leg_l"] < 0.95


def test_legs_the_motion_does_not_determine_are_said_so_not_identified(gait2392):
    """The limit of the rule, measured: in the running window a left leg 4 % longer than the
    right, or both legs 4 % shorter than the stature's, come out as the stature's leg (within
    0.5 %) — pelvis and foot markers of a run whose knees never straighten do not tell a
    longer or shorter leg from a more or less flexed knee — and the report names both legs as
    not determined. In a walk whose knees straighten (0–57°) and whose default-pose ratio is
    above the stature's (legs × 1.05) the start is the default pose, the rule before: the
    result is the one without the stature, to the digit."""
    from msk.personalise.scaling import scale_from_motion

    for legs in ((1.0, 1.04), (0.96, 0.96)):
        x, labels, t = _pelvis_and_feet_window(gait2392, legs, (20.0, 92.0), 0)
        _, rep = scale_from_motion(gait2392, x, labels, t, height_m=1.80)
        for side in ("leg_r", "leg_l"):
            assert rep.ratios[side] == pytest.approx(1.0, abs=0.005), (legs, side)
            assert rep.details[side]["determined"] is False
    x, labels, t = _pelvis_and_feet_window(gait2392, (1.05, 1.05), (0.0, 57.0), 0)
    _, rep = scale_from_motion(gait2392, x, labels, t, height_m=1.80)
    _, plain = scale_from_motion(gait2392, x, labels, t)
    for side in ("leg_r", "leg_l"):
        assert rep.details[side]["start"]["source"] == "default pose"
        assert rep.ratios[side] == plain.ratios[side]
        assert "determined" not in rep.details[side]
