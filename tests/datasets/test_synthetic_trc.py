"""Synthetic tasks in OpenSim's formats (:mod:`msk.datasets.trc`): the files written read back
through msk.io with the truth's marker positions and ground reactions (fast, gait2392 and
templates in DM's naming made here), and the DM sessions run on a known subject (slow)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from msk.datasets.tasks import Foothold, FootReactions, TaskMotion
from msk.datasets.trc import subject_model, write_trc_task
from msk.io import read_trc
from msk.model.core import marker_positions
from msk.model.files import load_model
from msk.pipeline import run_stages

REPO = Path(__file__).resolve().parents[2]

#: DM's column order: each plate's force, point and vertical torque, then the other torques
DM_COLUMNS = (
    "time",
    *[c for k in (1, 2, 3) for c in (
        f"ground_force_{k}_vx", f"ground_force_{k}_vy", f"ground_force_{k}_vz",
        f"ground_force_{k}_px", f"ground_force_{k}_py", f"ground_force_{k}_pz",
        f"ground_torque_{k}_z")],
    *[c for k in (1, 2, 3) for c in (f"ground_torque_{k}_x", f"ground_torque_{k}_y")],
)  # fmt: skip
#: model marker → DM label (as the DM session's model stage renames them)
RENAME = {"R.ASIS": "R_Asis", "L.ASIS": "L_Asis", "V.Sacral": "Sacral", "R.Heel": "R_Heel",
          "L.Heel": "L_Heel", "R.Toe.Tip": "R_Toe", "L.Toe.Tip": "L_Toe"}  # fmt: skip


@pytest.fixture(scope="module")
def gait2392():
    return load_model(REPO / "msk" / "data" / "models" / "gait2392.toml")


def _templates(folder, model):
    """A DM-like template: the .trc (the model's renamed markers, a moving arm marker the model
    does not carry, a fixed lab marker; mm, 120 Hz) and the .sto (DM's columns, 1200 Hz)."""
    from msk.io import write_sto, write_trc

    labels = [RENAME.get(m.name, m.name) for m in model.markers] + ["R_Elbow", "Oglobal"]
    n = 12
    t = 0.75 + np.arange(n) / 120.0
    pts = np.random.default_rng(1).normal(0.0, 0.3, (n, len(labels), 3))
    pts[:, -1] = [-0.2, 0.0, 0.0]  # a still lab marker
    trc = write_trc(folder / "tmpl.trc", time=t, markers=pts, labels=labels, rate_hz=120.0)
    tg = 0.75 + np.arange(10 * n) / 1200.0
    sto = write_sto(folder / "tmpl_grf.sto", time=tg, data=np.zeros((tg.size, 27)),
                    columns=DM_COLUMNS[1:])  # fmt: skip
    return trc, sto


def _motion_and_reactions(model, n=12, rate=120.0, g_rate=1200.0):
    rng = np.random.default_rng(0)
    names = list(model.coordinate_names)
    q = np.tile(model.default_coordinates(), (n, 1))
    q[:, names.index("pelvis_ty")] = 0.95
    q[:, names.index("pelvis_tx")] = np.linspace(0.0, 0.1, n)
    q[:, names.index("knee_angle_r")] = -0.3 * np.sin(np.arange(n) / 3.0)
    t = np.arange(n) / rate
    holds = (Foothold("calcn_r", 0.0, t[-1], 0.0, 0.1, 0.0, "step1"),
             Foothold("calcn_l", 0.0, t[-1], 0.0, -0.1, 0.0, "step2"))  # fmt: skip
    motion = TaskMotion(model, t, q, holds, "walk", 0.0)
    tg = np.arange(round(t[-1] * g_rate) + 1) / g_rate
    k = tg.size
    force = rng.normal(0.0, 50.0, (k, 2, 3))
    force[..., 1] = rng.uniform(200.0, 500.0, (k, 2))
    force[: k // 3, 1] = 0.0  # the left foot unloaded at first (its surface: none)
    cop = rng.normal(0.0, 0.2, (k, 2, 3))
    cop[..., 1] = 0.0
    cop[: k // 3, 1] = np.nan
    free = np.zeros((k, 2, 3))
    free[..., 1] = rng.normal(0.0, 3.0, (k, 2))
    free[: k // 3, 1] = 0.0
    surf = np.array([["step1", "step2"]] * k, dtype=object)
    surf[: k // 3, 1] = ""
    tot = force.sum(axis=1)
    re = FootReactions(tg, force, cop, free, surf.astype(str), tot, np.zeros_like(tot))
    return motion, re


def test_written_trc_sto_xml_read_back_with_the_truths_markers_and_ground_reactions(
    tmp_path, gait2392
):
    """No noise: every marker the model carries reads back at its forward-kinematics position in
    the lab (R p + o, 1e-6 m; the .trc in mm), an arm label it does not carry is a gap (0 0 0,
    read as missing), the fixed lab marker at the template's place; each plate's force, centre
    of pressure and free moment (msk.dynamics.loads' reading, the ExternalLoads file's plates) equal
    the
    truth's foot on that surface to 1e-6, zero where unloaded, and the ExternalLoads file
    applies each plate to that foot (the empty plate 3: no force)."""
    from msk.dynamics.loads import external_loads_assignment, plates_from_grf_file

    model = gait2392
    tmpl_trc, tmpl_sto = _templates(tmp_path, model)
    motion, re = _motion_and_reactions(model)
    yaw = np.deg2rad(170.0)
    rot = np.array([[np.cos(yaw), 0.0, np.sin(yaw)], [0.0, 1.0, 0.0],
                    [-np.sin(yaw), 0.0, np.cos(yaw)]])  # fmt: skip
    org = np.array([-1.5, 0.0, 0.2])
    trc, grf, xml, feet = write_trc_task(
        tmp_path / "out", "synthetic", motion, re, template_trc=tmpl_trc, template_grf=tmpl_sto,
        rename=RENAME, lab_from_model=rot, lab_origin_m=org, plates=("step1", "step2", ""),
        time_offset_s=0.75, noise_m=0.0, force_noise_n=0.0, cop_noise_m=0.0, torque_noise_nm=0.0,
    )  # fmt: skip
    assert feet == {"plate1": "calcn_r", "plate2": "calcn_l", "plate3": ""}
    # markers
    tab = read_trc(trc)
    assert tab.rate_hz == 120.0 and np.allclose(tab.time, 0.75 + motion.time, atol=1e-9)
    truth = marker_positions(model, motion.q) @ rot.T + org
    got = np.asarray(tab.markers, dtype=float)
    for i, m in enumerate(model.markers):
        j = list(tab.labels).index(RENAME.get(m.name, m.name))
        np.testing.assert_allclose(got[:, j], truth[:, i], atol=1e-6)
    elbow = got[:, list(tab.labels).index("R_Elbow")]
    assert np.all((elbow == 0) | np.isnan(elbow))
    np.testing.assert_allclose(got[:, list(tab.labels).index("Oglobal")],
                               np.tile([-0.2, 0.0, 0.0], (12, 1)), atol=1e-9)  # fmt: skip
    # ground reactions through msk.dynamics.loads, as the session's read stage does
    assign = external_loads_assignment(xml, grf)
    assert assign == {"plate1": "calcn_r", "plate2": "calcn_l", "plate3": "calcn_r"}
    plates = {p.name: p for p in plates_from_grf_file(grf, xml)}
    for j, name in enumerate(("plate1", "plate2")):
        p = plates[name]
        np.testing.assert_allclose(np.asarray(p.time) - 0.75, re.time, atol=1e-9)
        on = re.surface[:, j] != ""
        np.testing.assert_allclose(p.force[on], re.force[on, j] @ rot.T, atol=1e-6)
        np.testing.assert_allclose(p.cop[on], re.cop[on, j] @ rot.T + org, atol=1e-6)
        np.testing.assert_allclose(p.free_moment[on], re.free_moment[on, j] @ rot.T, atol=1e-6)
        assert np.all(p.force[~on] == 0.0)
    assert np.all(plates["plate3"].force == 0.0)


def test_subject_model_scales_segments_markers_and_mass(gait2392):
    """The subject: a body's joint offsets and markers scale by its factor, the mass is the
    given one."""
    sub = subject_model(gait2392, {"femur_r": 1.1, "tibia_r": 0.9}, mass_kg=81.0)
    assert sub.total_mass == pytest.approx(81.0)
    for mk0, mk1 in zip(gait2392.markers, sub.markers, strict=True):
        f = {"femur_r": 1.1, "tibia_r": 0.9}.get(mk0.body, 1.0)
        np.testing.assert_allclose(mk1.offset, f * np.asarray(mk0.offset), atol=1e-12)
    knee0 = next(j for j in gait2392.joints if j.child == "tibia_r")
    knee1 = next(j for j in sub.joints if j.child == "tibia_r")
    np.testing.assert_allclose(knee1.parent_offset.translation,
                               1.1 * knee0.parent_offset.translation, atol=1e-12)  # fmt: skip


_DM = REPO.parent / "shared" / "data" / "real" / "knee-grand-challenge-gc6-DM"


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.skipif(not _DM.is_dir(), reason="Grand Challenge DM data not present")
def test_dm_og1_recovers_a_known_subjects_walk_and_flags_what_it_does_not(tmp_path):
    """The DM overground config (no static) on a synthetic walk of a subject scaled by
    :data:`msk.datasets.trc.SUBJECT_FACTORS` from DM's own model, in DM's files, only the task
    swapped (``studies/task_swap.py --synthetic``; figures in docs/validation.md, issue 15
    thirteenth pass). Recovered: every thigh and shank marker on the segment its label names
    (before the placement fix three of the right leg's were exchanged across the knee, its knee
    43.7° RMS from the truth, unflagged), the pelvis, femur, foot and trunk scale factors
    within 1.5 %, the plates' weighing within 3 % of the true mass, no torque written in a
    frame whose foot stands on unmeasured floor. Not recovered, and bounded here as measured:
    the tibias 5–15 % short (the ASIS-to-heel leg factor is biased by the flexed knee; the
    left leg's two length measures disagree by > 5 %: flagged, the right's by 4.6 %: not), so
    the knee angles are off by up to 25° RMS; no segment mass is called identified."""
    import importlib.util
    import sys

    from msk.datasets.trc import trc_task
    from msk.pipeline import run_task_trials

    spec = importlib.util.spec_from_file_location("task_swap", REPO / "studies" / "task_swap.py")
    assert spec is not None and spec.loader is not None
    ts = importlib.util.module_from_spec(spec)
    sys.modules["task_swap"] = ts
    spec.loader.exec_module(ts)
    config = REPO / "pipelines" / "gc6_DM_og1.toml"
    task = trc_task(config, "walk", tmp_path, placed=run_stages(config, until="model")["model"])
    files = {"file": task.trc, "grf": task.grf, "external_loads": task.external_loads}
    cfg = ts.swapped_config("gc6_DM_og1", "synthetic_walk", files, tmp_path)
    (res,) = run_task_trials(cfg, tmp_path / "out")
    s = res.summary.to_dict()
    assert not [x for x in s["stages"] if x["status"] == "failed"]
    assert {x["name"]: x["status"] for x in s["stages"]}["inverse_dynamics"] == "computed"
    flags = {f["quantity"] for f in s["quality"]["flags"]}
    placed = s["model"]["marker_placement"]["placed"]
    for lab, body in placed.items():
        if "Thigh" in lab or "Shank" in lab:
            side = lab[0].lower()
            assert body == ("femur_" if "Thigh" in lab else "tibia_") + side, (lab, body)
    assert "markers_placed_against_label" not in flags
    cmp = ts.compare_to_truth(task, cfg)
    for body, (run, true) in cmp["scale"].items():
        err = run / true - 1.0
        if body.startswith("tibia"):
            assert -0.15 < err < -0.05, (body, run, true)
        else:
            assert abs(err) < 0.015, (body, run, true)
    assert "leg_length_disagreement_pct_l" in flags
    q = s["quality"]
    assert abs(q["plate_mass_kg"] / task.mass_kg - 1.0) < 0.03, q["plate_mass_kg"]
    assert not [g for g in s["identification"]["segments"] if g["status"] == "identified"]
    assert cmp["unblanked_true_unmeasured"] == 0
    assert 1000 * q["ik_marker_rms_mean_m"] < 8.0
    assert max(cmp["ik_deg"][f"hip_adduction_{c}"] for c in "rl") < 4.0, cmp["ik_deg"]
    assert max(cmp["ik_deg"][f"knee_angle_{c}"] for c in "rl") < 25.0, cmp["ik_deg"]
