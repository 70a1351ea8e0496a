"""``msk run`` on real sessions of labs other than the Grand Challenge (GitHub issue 10).

Each session config is written in ``tmp_path`` with absolute paths into ``real_dir`` (the
data are not bundled) and run as a lab engineer would, with ``msk/data/models/gait2392.toml``:

* **Vicon Plug-in Gait** (BTKData ``PiG_Motion3_FF.c3d``, 3 plates, 16 unnamed EMG channels
  left out): static ``PiG_Calibration3_FF.c3d`` (a C3D static trial, no plates), 74 kg and
  1.76 m (the files' ``PROCESSING``), marker names from
  ``pipelines/markersets/plug_in_gait_to_gait2392.toml``. The trial walks ~1 s on the floor
  before and after the plates: those frames (a foot on the floor beside the plates) carry no
  residual, identification equation or muscle force (:func:`msk.dynamics.loads.contact_measured`).
* **OpenSim example subject01** (``subject01_walk.trc`` + ``subject01_walk_grf.mot``: markers
  from a TRC, forces from an OpenSim GRF file, ``grf`` key), static ``subject01_static.trc``,
  72.6 kg and 1.8034 m (OpenSim's ``subject01_Setup_Scale.xml``), the IK weights of its
  ``subject01_Setup_IK.xml`` except the acromion markers (weight 0: they sit on the scapula,
  which gait2392 lacks, and move ~8 cm between the arms-out static and the walk), the thigh /
  shank clusters moved to where the static trial puts them (``markers.move``).

Asserted: the run completes, every core stage is computed, IK marker RMS < 30 mm, pelvis
residual force RMS < 15 % BW (over the frames whose ground contact the plates measure), the
report exists, and without an EMG mapping the EMG and strength stages are "not available" with
a reason, never "failed".
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from msk.pipeline import CORE_STAGES, run_session

REPO = Path(__file__).resolve().parents[2]
GAIT2392 = REPO / "msk" / "data" / "models" / "gait2392.toml"
PIG_MAP = REPO / "pipelines" / "markersets" / "plug_in_gait_to_gait2392.toml"
#: IK weights of OpenSim's subject01_Setup_IK.xml, acromia at 0 (module docstring)
S01_WEIGHTS = {
    "Sternum": 1.0,
    "R.Acromium": 0.0,
    "L.Acromium": 0.0,
    "Top.Head": 0.1,
    **dict.fromkeys(("R.ASIS", "L.ASIS", "V.Sacral", "R.Heel", "L.Heel"), 10.0),
    **dict.fromkeys(("R.Toe.Tip", "L.Toe.Tip"), 10.0),
}
S01_CLUSTERS = [f"{s}.{seg}.{p}" for s in "RL" for seg in ("Thigh", "Shank") for p in
                ("Upper", "Front", "Rear")]  # fmt: skip


def _toml_table(d: dict) -> str:
    return "{ " + ", ".join(f'"{k}" = {v!r}' if not isinstance(v, str) else f'"{k}" = "{v}"'
                            for k, v in d.items()) + " }"  # fmt: skip


def _need(*paths: Path) -> None:
    for p in paths:
        if not p.is_file():
            pytest.skip(f"{p} absent")


def pig_config(real_dir: Path, folder: Path) -> Path:
    static = real_dir / "btkdata" / "PiG_Calibration3_FF.c3d"
    task = real_dir / "btkdata" / "PiG_Motion3_FF.c3d"
    _need(static, task)
    with PIG_MAP.open("rb") as fh:
        rename = tomllib.load(fh)["markers"]["rename"]
    cfg = folder / "pig_motion3.toml"
    cfg.write_text(
        f"""
[subject]
name = "flatFoot"
mass_kg = 74.0
height_m = 1.76
side = "right"

[model]
source = "{GAIT2392}"

[[trials]]
name = "calibration3"
file = "{static}"
role = "static"

[[trials]]
name = "motion3"
file = "{task}"
role = "task"

[markers]
rename = {_toml_table(rename)}
""",
        encoding="utf-8",
    )
    return cfg


def subject01_config(real_dir: Path, folder: Path) -> Path:
    d = real_dir / "opensim-subject01-walk"
    static, task, grf = (
        d / "subject01_static.trc",
        d / "subject01_walk.trc",
        d / "subject01_walk_grf.mot",
    )
    _need(static, task, grf)
    cfg = folder / "subject01_walk.toml"
    cfg.write_text(
        f"""
[subject]
name = "subject01"
mass_kg = 72.6
height_m = 1.8034
side = "right"

[model]
source = "{GAIT2392}"

[[trials]]
name = "static"
file = "{static}"
role = "static"

[[trials]]
name = "walk"
file = "{task}"
grf = "{grf}"
role = "task"

[markers]
weights = {_toml_table(S01_WEIGHTS)}
move = [{", ".join(f'"{c}"' for c in S01_CLUSTERS)}]
""",
        encoding="utf-8",
    )
    return cfg


def check_run(res) -> dict:
    s = res.summary.to_dict()
    status = {r.name: r for r in res.stages}
    for name in CORE_STAGES:
        assert status[name].status == "computed", (name, status[name])
    assert status["fes"].status == "not requested"
    # no EMG mapping: EMG and strength are not available, with a reason — never failed
    for name in ("emg", "strength_identification"):
        assert status[name].status == "not available" and status[name].message, status[name]
    assert not [r for r in res.stages if r.status == "failed"], s["not_available"]
    # the other analysis stages ran
    for name in ("mass_identification", "muscle_geometry", "tension_optimization",
                 "knee_contact", "comparison"):  # fmt: skip
        assert status[name].status == "computed", (name, status[name])
    q = s["quality"]
    assert q["ik_failed_frames"] == 0
    assert q["ik_marker_rms_mean_m"] < 0.030, q["ik_marker_rms_mean_m"]
    assert q["residual_force_rms_pct_bw"] < 15.0, q["residual_force_rms_pct_bw"]
    assert q["optimization_infeasible_frames"] == 0
    assert (res.out_dir / "report.html").is_file()
    assert (res.out_dir / "tables" / "joint_torques.sto").is_file()
    return q


@pytest.mark.slow
@pytest.mark.realdata
def test_msk_run_on_a_vicon_plug_in_gait_session(real_dir: Path, tmp_path: Path) -> None:
    cfg = pig_config(real_dir, tmp_path)
    res = run_session(cfg, tmp_path / "out")
    q = check_run(res)
    s = res.summary.to_dict()
    # the static trial is a C3D: scaled from it, its own markers placed — not PiG's virtual
    # segment points nor the unlabelled trajectories (*1, *2), which mean nothing on a bone
    placement = s["model"]["marker_placement"]
    assert {"LPSI", "RPSI", "LTHI", "RTHI", "LTIB", "RTIB"} <= set(placement["placed"])
    assert not set(placement["placed"]) & {"*1", "*2", "PELO", "LFEO", "RTIL"}
    assert {"*1", "PELO", "RFEA"} <= set(s["model"]["marker_set"]["excluded"])
    assert set(s["model"]["scale_ratios"]) >= {"pelvis", "femur_r", "tibia_l"}
    # left on plates 1 and 3, right on plate 2 (the file's Foot Strike events agree)
    bodies = {a["plate"]: a["body"] for a in q["plate_assignments"]}
    assert bodies == {"plate1": "calcn_l", "plate2": "calcn_r", "plate3": "calcn_l"}
    # ~1 s on the floor off the plates at each end: about half the frames are measured
    assert 120 <= q["contact_measured_frames"] <= 175 < q["frames"] == 293
    # the report's right gait cycle is the one on the plates (8.38–9.46 s), not the first
    assert s["gait_cycle_s"] == pytest.approx([8.38, 9.46], abs=0.01)
    # identification lowers the residuals of the generic (scaled) model on the measured frames
    comp = s["comparison"]["residual_force_rms_n"]
    assert comp["identified"] < comp["generic"]


@pytest.mark.slow
@pytest.mark.realdata
def test_msk_run_on_opensim_subject01_trc_and_grf_mot(real_dir: Path, tmp_path: Path) -> None:
    cfg = subject01_config(real_dir, tmp_path)
    res = run_session(cfg, tmp_path / "out")
    q = check_run(res)
    s = res.summary.to_dict()
    assert any(i["role"] == "grf" for i in s["inputs"])
    # TRC: already OpenSim's frame (+y up, walking along +x)
    assert s["frame"]["lab_up"] == pytest.approx([0.0, 1.0, 0.0])
    # (the heading from the pelvis markers turns it by 0.27° about the vertical)
    rot = np.asarray(s["frame"]["lab_to_model_rotation"])
    assert np.allclose(rot[:, 1], [0, 1, 0]) and np.allclose(rot, np.eye(3), atol=0.01)
    # the two GRF columns sets go to the feet OpenSim's subject01_walk_grf.xml names
    for a in q["plate_assignments"]:
        assert a["body"] == {"plate1": "calcn_r", "plate2": "calcn_l"}[a["plate"]], a
    placement = s["model"]["marker_placement"]
    # arm markers (no arms in gait2392) are left out, not fixed to the torso
    assert {"R.Wrist.Med", "L.Elbow"} <= set(s["model"]["marker_set"]["excluded"])
    assert not {"R.Wrist.Med", "L.Elbow"} & set(placement["placed"])
    # the clusters named in the config, and the acromia (no shoulder girdle in gait2392)
    assert set(placement["moved"]) == {*S01_CLUSTERS, "R.Acromium", "L.Acromium"}
    assert q["residual_force_rms_pct_bw"] < 5.0  # clean OpenSim example data


@pytest.mark.slow
@pytest.mark.realdata
def test_stock_osim_with_its_marker_set_in_a_separate_xml(real_dir: Path, tmp_path: Path) -> None:
    """A stock ``.osim`` without markers plus an OpenSim MarkerSet ``.xml`` (``[model]
    markers``): the subject01 walk runs on OpenSim's gait2392 as distributed."""
    from msk.model.files import load_model

    osim = real_dir.parent / "reference" / "opensim-models" / "gait2392_thelen2003muscle.osim"
    _need(osim)
    rows = "".join(
        f'<Marker name="{m.name}"><socket_parent_frame>/bodyset/{m.body}'
        f"</socket_parent_frame><location>{' '.join(f'{v:.6f}' for v in m.offset)}</location>"
        "<fixed>false</fixed></Marker>"
        for m in load_model(GAIT2392).markers
    )
    xml = tmp_path / "gait2392_markers.xml"
    head = '<?xml version="1.0"?><OpenSimDocument Version="40000"><MarkerSet name="markers">'
    xml.write_text(f"{head}<objects>{rows}</objects></MarkerSet></OpenSimDocument>")
    cfg = subject01_config(real_dir, tmp_path)
    text = cfg.read_text().replace(
        f'source = "{GAIT2392}"', f'source = "{osim}"\nmarkers = "{xml}"'
    )
    cfg.write_text(text)
    res = run_session(cfg, tmp_path / "out")
    q = res.summary.quality
    assert res.summary.model is not None and res.summary.model.source is not None
    assert Path(res.summary.model.source).resolve() == Path(osim).resolve()
    assert q.ik_marker_rms_mean_m is not None and q.ik_marker_rms_mean_m < 0.025
    assert q.residual_force_rms_pct_bw is not None and q.residual_force_rms_pct_bw < 5.0


@pytest.mark.slow
@pytest.mark.realdata
def test_a_static_of_another_subject_is_not_used_and_flagged(real_dir: Path, tmp_path: Path):
    """The PiG calibration of one subject with another lab's Plug-in Gait walk: the walk
    contradicts the static's leg markers, which are left out, and the static can no longer be
    posed. The model is then scaled and placed from the walk itself (as for a session without a
    static) and the flag ``static_not_used`` names both files and the markers; the run goes on."""
    other = real_dir / "btkdata" / "PlugInC3D.c3d"
    _need(other)
    cfg = pig_config(real_dir, tmp_path)
    cfg.write_text(cfg.read_text().replace("PiG_Motion3_FF.c3d", "PlugInC3D.c3d"))
    res = run_session(cfg, tmp_path / "out")
    s = res.summary.to_dict()  # the summary.json mapping (keys present or absent)
    (flag,) = [f for f in s["quality"]["flags"] if f["quantity"] == "static_not_used"]
    assert re.search(r"PiG_Calibration3_FF\.c3d.*PlugInC3D\.c3d.*RKNE", flag["message"])
    model = s["model"]
    assert "static_window" not in model and "static_rejected" in model
    assert s["quality"]["ik_marker_rms_mean_m"] < 0.02  # placed on the walk itself


@pytest.mark.slow
@pytest.mark.realdata
def test_a_trc_and_grf_of_a_z_up_lab_are_levelled_by_the_ground_reactions(
    real_dir: Path, tmp_path: Path
) -> None:
    """opensim-core's walking2 as OpenSim's C3DFileAdapter wrote it — markers ``.trc`` and
    plate-origin GRFs ``f1_1 … p1_1 … m1_1`` in mm and N·mm, both in the C3D's z-up lab, the
    GRFs subsampled to 20 Hz — as the task of the subject01 session: the lab's up is taken from
    the ground reactions (+z, not the TRC's default +y), and each plate's stance goes to one
    foot (right on plate 1, left on plate 2), none left unassigned."""
    d = real_dir / "opensim-core-c3d"
    trc, grf = d / "std_walking2_markers.trc", d / "std_walking2_grfs.sto"
    _need(trc, grf)
    cfg = subject01_config(real_dir, tmp_path)
    s01 = real_dir / "opensim-subject01-walk"
    text = cfg.read_text().replace(str(s01 / "subject01_walk.trc"), str(trc))
    cfg.write_text(text.replace(str(s01 / "subject01_walk_grf.mot"), str(grf)))
    res = run_session(cfg, tmp_path / "out")
    s = res.summary.to_dict()
    assert s["frame"]["lab_up"] == pytest.approx([0.0, 0.0, 1.0])
    rot = np.asarray(s["frame"]["lab_to_model_rotation"])
    assert rot[:, 2] == pytest.approx([0.0, 1.0, 0.0], abs=1e-9)  # lab z → model y
    q = s["quality"]
    bodies = {a["plate"]: a["body"] for a in q["plate_assignments"]}
    assert bodies == {"plate1": "calcn_r", "plate2": "calcn_l"}
    assert "plate_unassigned_contact_frames" not in {f["quantity"] for f in q["flags"]}
    # its header says 250 Hz, its rows step at 25 Hz: the rows' rate is used, and said so
    (rate,) = [f for f in q["flags"] if f["quantity"] == "input_file"]
    assert re.search(r"DataRate = 250 Hz .* steps at 25(\.\d+)? Hz", rate["message"])


@pytest.mark.slow
@pytest.mark.realdata
def test_the_rajagopal_model_on_its_own_walk_has_knee_contact(tmp_path: Path) -> None:
    """pipelines/opensim_rajagopal.toml with ``source = "rajagopal"`` (and ``[contact] patella =
    "none"``): the walker knee found as the tibia's joint, its knee contact computed through
    the patellar tendon (its quadriceps pass over its patella), its flexion (positive in the
    model) inside the physiological gate and reported as flexion, the peak knee contact within
    15 % of gait2392's on the same walk (3.74 BW, the shipped golden; measured 3.68 BW)."""
    src = REPO / "pipelines" / "opensim_rajagopal.toml"
    text = src.read_text(encoding="utf-8").replace('"../../shared', f'"{REPO.parent / "shared"}')
    text = text.replace('source = "gait2392"', 'source = "rajagopal"')
    text += '\n[contact]\npatella = "none"\n'
    if not (REPO.parent / "shared" / "data" / "real" / "opensim-rajagopal-walk").is_dir():
        pytest.skip("the Rajagopal walk is not here")
    cfg = tmp_path / "raj.toml"
    cfg.write_text(text, encoding="utf-8")
    res = run_session(cfg, tmp_path / "out")
    status = {r.name: r for r in res.stages}
    assert status["knee_contact"].status == "computed", status["knee_contact"]
    s = res.summary.to_dict()
    assert not [f for f in s["quality"]["flags"] if f["quantity"].startswith("knee_angle")]
    table = np.genfromtxt(res.out_dir / "tables" / "knee_contact.csv", delimiter=",", names=True)
    peak = float(np.nanmax(table["generic_total_bw"]))
    assert peak == pytest.approx(3.74, rel=0.15)
    assert np.isfinite(table["generic_total"]).sum() > 200
    cycles = np.genfromtxt(res.out_dir / "tables" / "gait_cycles_right.csv", delimiter=",",
                           names=True)  # fmt: skip
    assert 60.0 < np.nanmax(cycles["knee_flexion_deg"]) < 80.0  # swing flexion, gait2392: 73.7°
    assert np.nanmin(cycles["knee_flexion_deg"]) > -10.0
