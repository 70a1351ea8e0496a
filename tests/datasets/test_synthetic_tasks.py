"""The hidden task kinds (issue 15, ninth pass): a two-leg squat and a stair ascent of Grand
Challenge subject JW made with a known truth in JW's lab format (:mod:`msk.datasets.tasks`)
and run through ``pipelines/gc4_JW.toml`` with only the task swapped (``studies/task_swap.py
--synthetic`` prints the same figures for JW and PS). Slow: each builds JW's model and runs the
session."""

from __future__ import annotations

import importlib.util
import sys
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from msk.pipeline import run_stages

REPO = Path(__file__).resolve().parents[2]
JW = REPO / "pipelines" / "gc4_JW.toml"
_GC4 = REPO.parent / "shared" / "data" / "real" / "knee-grand-challenge-gc4"


def _jw(fn):
    """A test on JW's session: slow (builds JW's model and runs the session), needs the Grand
    Challenge 4 data."""
    skip = pytest.mark.skipif(not _GC4.is_dir(), reason="Grand Challenge 4 data not present")
    return pytest.mark.slow(pytest.mark.realdata(skip(fn)))


# no flag is raised that is not true of the tasks: the stair's only flag is its feet on the
# uninstrumented steps (the static check's false "static markers contradicted" of the ninth
# pass went with the balanced stair of the twelfth; the squat's with the opposite-side rule)


def _script():
    spec = importlib.util.spec_from_file_location("task_swap", REPO / "studies" / "task_swap.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["task_swap"] = mod
    spec.loader.exec_module(mod)
    return mod


@cache
def _run(kind: str, folder: Path):
    from msk.datasets.tasks import lab_task
    from msk.pipeline import run_task_trials

    ht = _script()
    folder.mkdir(parents=True, exist_ok=True)
    placed = run_stages(JW, until="model")["model"]
    task = lab_task(JW, kind, folder / f"{kind}.c3d", placed=placed, seed=1)
    cfg = ht.swapped_config("gc4_JW", kind, {"file": task.path}, folder)
    (res,) = run_task_trials(cfg, folder / "out")
    return task, res, ht.compare_to_truth(task, cfg)


@pytest.fixture(scope="module")
def tmp_module(tmp_path_factory):
    return tmp_path_factory.mktemp("hidden")


@_jw
def test_jw_squat_no_false_flag_no_cycle_ik_and_torques_near_the_truth(tmp_module):
    """4 repetitions to 95° of knee flexion, each foot on its own plate: every stage computes,
    no gait cycle (a squat has no step), no flag (the knee's 95° is inside the physiological
    range), IK within 0.5° RMS of every leg coordinate, the knee's deepest
    flexion within 1°, the leg torques within 3 N·m RMS (the plates' 6 Hz low-pass), no frame
    of unmeasured contact."""
    _, res, cmp = _run("squat", tmp_module)
    s = res.summary.to_dict()
    assert not [x for x in s["stages"] if x["status"] not in ("computed", "not requested")]
    assert s["gait_cycle_s"] is None and s["events"] == []
    flags = {f["quantity"] for f in s["quality"]["flags"]}
    assert not flags, flags
    assert max(cmp["ik_deg"].values()) < 0.5, cmp["ik_deg"]
    assert abs(cmp["knee_r_range_deg"][1] - cmp["knee_r_true_deg"][1]) < 1.0
    assert cmp["knee_r_true_deg"][1] > 90.0
    assert max(cmp["tau_rmse_nm"].values()) < 3.0, cmp["tau_rmse_nm"]
    assert s["quality"]["unmeasured_contact_frames"] == 0 and cmp["written_unmeasured"] == 0
    assert "over the trial" in (res.out_dir / "report.html").read_text(encoding="utf-8")


@_jw
def test_jw_stair_unmeasured_steps_are_found_blanked_counted_and_flagged(tmp_module):
    """4 steps of 0.17 m, plates under the floor start (left foot) and steps 1–2, steps 3–4
    uninstrumented: every frame in which a foot stands on the right foot's floor spot or an
    upper step (the truth) has that leg's torques unwritten (NaN) — never a number computed
    without its reaction; the frames are counted in summary.json and flagged (a raised surface);
    on the written
    frames the knee torques are within 8 N·m RMS of the truth and IK within 0.5°; the pelvis
    residual over the measured frames stays under the 5 % BW gate."""
    _, res, cmp = _run("stair", tmp_module / "stair")
    q = res.summary.to_dict()["quality"]
    flags = {f["quantity"] for f in q["flags"]}
    assert flags == {"unmeasured_contact_raised_frames"}, flags
    assert "residual_force_rms_pct_bw" not in flags and q["residual_force_rms_pct_bw"] < 5.0
    assert cmp["true_unmeasured"] > 100
    assert cmp["unblanked_true_unmeasured"] == 0, cmp["unblanked_true_unmeasured"]
    assert q["unmeasured_contact_frames"] >= cmp["true_unmeasured"]
    assert max(cmp["ik_deg"].values()) < 0.5, cmp["ik_deg"]
    assert cmp["tau_rmse_nm"]["knee_angle_r"] < 8.0 and cmp["tau_rmse_nm"]["knee_angle_l"] < 8.0
    torques = np.genfromtxt(res.out_dir / "tables" / "joint_torques.csv", delimiter=",", names=True)
    assert np.isnan(torques["knee_angle_r"]).sum() > 0


@_jw
def test_jw_stair_with_steps_on_plates_prefixed_labels_and_plate_offsets(tmp_module):
    """The stair as a lab records it with the steps built on the plates: the file's plate
    corners at floor level (steps 1–2 are 0.17 and 0.34 m above them), every marker label
    ``JW:``-prefixed (the static's are not) and every plate reading 30 N unloaded, run with
    the shipped config and only the task swapped. Each step's surface is found from the feet
    within 1 cm, each offset within 1 N, every plate contact is assigned (none unassigned),
    the thigh and shank clusters placed from the static are tracked (no segment unobserved),
    and the joint torques are as near the truth as with the corners at the steps' height."""
    from msk.datasets.tasks import lab_task
    from msk.pipeline import run_task_trials

    ht = _script()
    folder = tmp_module / "stair_on_plates"
    folder.mkdir(parents=True, exist_ok=True)
    placed = run_stages(JW, until="model")["model"]
    task = lab_task(JW, "stair", folder / "stair.c3d", placed=placed, seed=1,
                    corners_at_floor=True, label_prefix="JW:", plate_offset_n=30.0)  # fmt: skip
    cfg = ht.swapped_config("gc4_JW", "stair", {"file": task.path}, folder)
    (res,) = run_task_trials(cfg, folder / "out")
    s = res.summary.to_dict()
    surf = {x["plate"]: x for x in s["plates"]["surfaces"]}
    assert surf["plate1"]["source"] == "corners"
    for name, h in (("plate2", 0.17), ("plate3", 0.34)):
        assert surf[name]["source"] == "feet"
        assert surf[name]["above_corners_m"] == pytest.approx(h, abs=0.01)
    offsets = s["plates"]["offsets_removed"]
    assert sorted(o["plate"] for o in offsets) == ["plate1", "plate2", "plate3"]
    assert all(abs(o["force_n"][1] - 30.0) < 1.0 for o in offsets)
    flags = {f["quantity"] for f in s["quality"]["flags"]}
    assert not any("unassigned" in f or "unobserved" in f for f in flags), flags
    cmp = ht.compare_to_truth(task, cfg)
    assert max(cmp["ik_deg"].values()) < 0.5, cmp["ik_deg"]
    assert cmp["unblanked_true_unmeasured"] == 0
    assert cmp["tau_rmse_nm"]["knee_angle_r"] < 8.0 and cmp["tau_rmse_nm"]["knee_angle_l"] < 8.0


def test_com_from_zmp_solves_the_cart_table_equation():
    """The centre of mass path of a zero-moment point stepping between two feet satisfies
    x − (h/g) ẍ = p at every interior sample (central differences, to round-off) and starts
    and ends at p (still); it is smoother than p (its largest step 10× smaller)."""
    from msk.datasets.tasks import com_from_zmp
    from msk.units import G0

    dt, h = 0.01, 0.9
    t = np.arange(0.0, 4.0 + dt / 2, dt)
    p = np.where((t > 1.0) & (t < 3.0), 0.1 * np.sign(np.sin(2 * np.pi * (t - 1.0))), 0.0)
    p += 0.002 * np.random.default_rng(0).standard_normal(t.size)
    x = com_from_zmp(p, dt, h)
    acc = (x[2:] - 2 * x[1:-1] + x[:-2]) / dt**2
    np.testing.assert_allclose(x[1:-1] - h / G0 * acc, p[1:-1], atol=1e-10)
    assert x[0] == pytest.approx(p[0]) and x[-1] == pytest.approx(p[-1])
    assert np.abs(np.diff(x)).max() < 0.1 * np.abs(np.diff(p)).max()


@_jw
def test_jw_stair_is_balanced_and_its_torques_near_published_stair_ascent(tmp_module):
    """The stair's true loads (JW's model, 0.17 m risers): every foot's centre of pressure on
    its sole (between its heel and toe markers, within its markers' width, at every loaded
    sample) and peak torques near published stair ascent — Riener et al. 2002 (Gait Posture
    15:32) and Protopapadaki et al. 2007 (Clin Biomech 22:203) report peak knee extension about
    1, hip extension about 1, ankle plantarflexion about 1.3–1.5 N·m/kg. Asserted: ankle
    plantarflexion 1.0–1.6; knee and hip extension 0.8–1.8 (measured 1.60–1.65 and 1.49–1.50:
    within the bounds, ~50–60 % above the published means; they were 3.0–3.3 and 2.0, the
    ankle 3.2–3.9, before the balance of issue 15's twelfth pass)."""
    import pinocchio as pin

    from msk.datasets.tasks import FEET
    from msk.model.core import marker_positions

    task, _, _ = _run("stair", tmp_module / "stair")
    model, names = task.motion.model, list(task.motion.model.coordinate_names)
    mass = sum(i.mass for i in model.pin_model.inertias)
    peaks = {}
    for side in "rl":
        tau = {c: task.tau[:, names.index(f"{c}_{side}")] / mass
               for c in ("knee_angle", "hip_flexion", "ankle_angle")}  # fmt: skip
        peaks[side] = (tau["knee_angle"].max(), -tau["hip_flexion"].min(),
                       -tau["ankle_angle"].min())  # fmt: skip
    for knee, hip, ankle in peaks.values():
        assert 0.8 < knee < 1.8 and 0.8 < hip < 1.8 and 1.0 < ankle < 1.6, peaks
    # the centre of pressure of each foot on its sole, in the foot's frame
    re = task.reactions
    th, _, _ = task.motion.at(re.time)
    data = model.create_data()
    th0 = model.default_coordinates()
    for j, foot in enumerate(FEET):
        sub = set(model.subtree(foot))
        idx = [i for i, m in enumerate(model.markers) if m.body in sub]
        pin.framesForwardKinematics(model.pin_model, data, model.coupling.q(th0))
        m0 = data.oMf[model.body_frame[foot]]
        local = np.array([m0.actInv(p) for p in marker_positions(model, th0)[0][idx]])
        loaded = np.flatnonzero(re.force[:, j, 1] > 50.0)[::5]
        assert loaded.size > 100
        for k in loaded:
            pin.framesForwardKinematics(model.pin_model, data, model.coupling.q(th[k]))
            c = data.oMf[model.body_frame[foot]].actInv(re.cop[k, j])
            assert local[:, 0].min() <= c[0] <= local[:, 0].max(), (foot, re.time[k], c)
            assert local[:, 2].min() <= c[2] <= local[:, 2].max(), (foot, re.time[k], c)
