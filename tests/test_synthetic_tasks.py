"""The hidden task kinds (issue 15, ninth pass): a two-leg squat and a stair ascent of Grand
Challenge subject JW made with a known truth in JW's lab format (:mod:`msk.synthetic_tasks`)
and run through ``pipelines/gc4_JW.toml`` with only the task swapped (``scripts/task_swap.py
--synthetic`` prints the same figures for JW and PS). Slow: each builds JW's model and runs the
session."""

from __future__ import annotations

import importlib.util
import sys
from functools import cache
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
JW = REPO / "pipelines" / "gc4_JW.toml"
pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(
        not (REPO.parent / "shared" / "data" / "real" / "knee-grand-challenge-gc4").is_dir(),
        reason="Grand Challenge 4 data not present",
    ),
]
# the flag the synthetic stair raises that is not true of the task: the markers of two segments
# that move alike (pelvis and thigh of the synthetic stair's rigid trunk) pass the static
# check's rigid-pair test and their distances differ from the static's stance
# (docs/validation.md, issue 15 ninth pass); the squat's right and left shank and hindfoot
# markers no longer do (opposite-side limb markers are never a rigid pair)
KNOWN = {"static_markers_contradicted_m"}


def _script():
    spec = importlib.util.spec_from_file_location("task_swap", REPO / "scripts" / "task_swap.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["task_swap"] = mod
    spec.loader.exec_module(mod)
    return mod


@cache
def _run(kind: str, folder: Path):
    from msk.pipeline import run_task_trials
    from msk.synthetic_tasks import lab_task

    ht = _script()
    folder.mkdir(parents=True, exist_ok=True)
    task = lab_task(JW, kind, folder / f"{kind}.c3d", seed=1)
    cfg = ht.swapped_config("gc4_JW", kind, {"file": task.path}, folder)
    (res,) = run_task_trials(cfg, folder / "out")
    return task, res, ht.compare_to_truth(task, cfg)


@pytest.fixture(scope="module")
def tmp_module(tmp_path_factory):
    return tmp_path_factory.mktemp("hidden")


def test_jw_squat_no_false_flag_no_cycle_ik_and_torques_near_the_truth(tmp_module):
    """4 repetitions to 95° of knee flexion, each foot on its own plate: every stage computes,
    no gait cycle (a squat has no step), no flag (the knee's 95° is inside the physiological
    range), IK within 0.5° RMS of every leg coordinate, the knee's deepest
    flexion within 1°, the leg torques within 3 N·m RMS (the plates' 6 Hz low-pass), no frame
    of unmeasured contact."""
    _, res, cmp = _run("squat", tmp_module)
    s = res.summary
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


def test_jw_stair_unmeasured_steps_are_found_blanked_counted_and_flagged(tmp_module):
    """4 steps of 0.17 m, plates under the floor start (left foot) and steps 1–2, steps 3–4
    uninstrumented: every frame in which a foot stands on the right foot's floor spot or an
    upper step (the truth) has that leg's torques unwritten (NaN) — never a number computed
    without its reaction; the frames are counted in summary.json and flagged (a raised surface);
    on the written
    frames the knee torques are within 8 N·m RMS of the truth and IK within 0.5°; the pelvis
    residual over the measured frames stays under the 5 % BW gate."""
    _, res, cmp = _run("stair", tmp_module / "stair")
    q = res.summary["quality"]
    flags = {f["quantity"] for f in q["flags"]}
    assert "unmeasured_contact_raised_frames" in flags
    assert "residual_force_rms_pct_bw" not in flags and q["residual_force_rms_pct_bw"] < 5.0
    assert cmp["true_unmeasured"] > 100
    assert cmp["unblanked_true_unmeasured"] == 0, cmp["unblanked_true_unmeasured"]
    assert q["unmeasured_contact_frames"] >= cmp["true_unmeasured"]
    assert max(cmp["ik_deg"].values()) < 0.5, cmp["ik_deg"]
    assert cmp["tau_rmse_nm"]["knee_angle_r"] < 8.0 and cmp["tau_rmse_nm"]["knee_angle_l"] < 8.0
    torques = np.genfromtxt(res.out_dir / "tables" / "joint_torques.csv", delimiter=",", names=True)
    assert np.isnan(torques["knee_angle_r"]).sum() > 0
