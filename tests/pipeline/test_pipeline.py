"""msk.pipeline: a synthetic session with known truth through the whole chain, atomic writes,
the content-hash cache, the CLI verbs, and the bundled Grand Challenge session end to end."""

from __future__ import annotations

import dataclasses
import json
import re
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from msk._runtime.blocks import FRAME_BLOCK
from msk.cli import main
from msk.config import TEMPLATE, config_reference, load_config, render_config
from msk.datasets.trials import write_synthetic_session
from msk.exceptions import ConfigError
from msk.io.opensim_files import read_sto
from msk.pipeline import STAGES, file_sha256, lab_to_model_rotation, run_session, run_stages
from msk.pipeline.inputs import session_inputs
from msk.pipeline.runner import Runner
from msk.results.folder import TABLES, read_session
from msk.results.summary import Summary
from tests.support import sessions

REPO = Path(__file__).resolve().parents[2]
GC5 = REPO / "pipelines" / "gc5_PS.toml"


@pytest.fixture(scope="module")
def synth(tmp_path_factory):
    folder = tmp_path_factory.mktemp("synth")
    cfg, trial = write_synthetic_session(folder)
    res = run_session(cfg, folder / "out")
    return cfg, trial, res


def test_rotation_lab_to_model():
    # Z-up lab walking along -x → model y up, walking along +x
    t = np.linspace(0, 1, 20)
    markers = np.zeros((20, 2, 3))
    markers[:, :, 0] = -1.5 * t[:, None]
    markers[:, :, 2] = 1.0
    r = lab_to_model_rotation(np.array([0, 0, 1.0]), np.array([0, 1.0, 0]), markers)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0)
    np.testing.assert_allclose(r @ [0, 0, 1.0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(r @ [-1.0, 0, 0], [1, 0, 0], atol=1e-12)
    # standing still: only the vertical is aligned
    r2 = lab_to_model_rotation(np.array([0, 1.0, 0]), np.array([0, 1.0, 0]), markers * 0)
    np.testing.assert_allclose(r2, np.eye(3), atol=1e-12)


def test_synthetic_session_recovers_truth(synth):
    _, trial, res = synth
    out = read_session(res.out_dir)
    text = (res.out_dir / "summary.json").read_text()
    assert Summary.from_json(text).to_json() == text  # the typed summary round-trips exactly
    q = out.table("q")
    names = list(q.columns)
    # joint angles: IK on 1 mm marker noise recovers the simulated motion
    legs = [names.index(c) for c in names if c.startswith(("hip", "knee", "ankle"))]
    err = np.abs(q.data[:, legs] - trial.q[:, legs])
    assert np.sqrt(np.mean(err[5:-5] ** 2)) < np.deg2rad(1.0)
    # joint torques against the true RNEA torques (inverse dynamics with the plates)
    tau = out.table("joint_torques")
    for c in ("hip_flexion_l", "knee_angle_l", "hip_flexion_r"):
        k = names.index(c)
        a, b = tau.column(c)[10:-10], trial.tau_true[10:-10, k]
        assert np.sqrt(np.mean((a - b) ** 2)) < 0.1 * np.ptp(b) + 1.0, c
    # residuals: plates and motion are consistent → small pelvis residual force
    assert out.summary.quality.residual_force_rms_pct_bw < 5.0
    # identified masses sum to the subject's mass (constraint of the identification)
    segs = out.summary.identification.segments
    assert sum(s.mass_kg for s in segs) == pytest.approx(trial.model.total_mass, rel=1e-3)
    assert out.has("inertial_parameters")
    # the muscle stages are honestly reported as not available (model without muscles)
    na = {i.stage: i.reason for i in out.summary.not_available}
    assert "muscle_geometry" in na and "no muscles" in na["muscle_geometry"]
    assert {"tension_optimization", "strength_identification", "knee_contact"} <= set(na)
    assert "emg" in na
    for t in ("muscle_forces", "strength", "knee_contact"):
        assert not (res.out_dir / "tables" / f"{t}.csv").exists()
    html = (res.out_dir / "report.html").read_text()
    assert "Not available" in html and "muscle_geometry" in html


def test_summary_contract(synth):
    _, _, res = synth
    s = json.loads((res.out_dir / "summary.json").read_text())
    assert s["versions"]["msk"] and s["versions"]["numpy"] != "not installed"
    task = next(i for i in s["inputs"] if i["role"] == "task")
    assert task["sha256"] == file_sha256(task["path"])
    assert s["settings"]["filters"]["grf_cutoff_hz"] == 15.0
    assert [st["name"] for st in s["stages"]] == list(STAGES)
    assert all(st["seconds"] >= 0 for st in s["stages"])
    assert set(s["tables"]) <= set(TABLES)
    # every CSV starts with time and has an OpenSim twin with the same numbers
    for name in s["tables"]:
        head = (res.out_dir / "tables" / f"{name}.csv").read_text().splitlines()[0]
        assert head.split(",")[0] == "time"
    q_csv = read_session(res.out_dir).table("q")
    q_mot = read_sto(res.out_dir / "tables" / "q.mot")
    assert q_mot.in_degrees_in_file
    np.testing.assert_allclose(q_mot.data, q_csv.data, rtol=1e-12, atol=1e-12)


def test_run_result_summary_is_the_typed_summary_json(synth):
    """``RunResult.summary`` is a :class:`msk.results.summary.Summary`, the typed value of exactly
    the
    summary.json the run wrote: its JSON text round-trips to the file's byte for byte."""
    _, _, res = synth
    text = (res.out_dir / "summary.json").read_text(encoding="utf-8")
    assert isinstance(res.summary, Summary)
    assert res.summary.to_json() == text
    assert res.summary == Summary.from_json(text)
    assert res.summary.quality.ik_failed_frames == json.loads(text)["quality"]["ik_failed_frames"]


def test_failed_run_writes_nothing(tmp_path):
    cfg, _ = write_synthetic_session(tmp_path / "s")
    out = tmp_path / "fresh"
    with pytest.raises(RuntimeError, match="on purpose"):
        run_session(cfg, out, _fail_stage="report")
    assert not (out / "summary.json").exists()
    assert not (out / "report.html").exists()
    assert not (out / "tables").exists()
    # a previous good result stays intact when a later run fails half-way
    run_session(cfg, out)
    before = (out / "summary.json").read_bytes()
    tables_before = sorted(p.name for p in (out / "tables").iterdir())
    with pytest.raises(RuntimeError):
        run_session(cfg, out, use_cache=False, _fail_stage="inverse_dynamics")
    assert (out / "summary.json").read_bytes() == before
    assert sorted(p.name for p in (out / "tables").iterdir()) == tables_before
    leftovers = [p.name for p in tmp_path.iterdir() if p.name.startswith(".fresh")]
    assert leftovers == []


def test_analysis_stage_error_is_recorded_not_fatal(tmp_path):
    cfg, _ = write_synthetic_session(tmp_path / "s")
    res = run_session(cfg, tmp_path / "out", _fail_stage="comparison")
    rec = {r.name: r for r in res.stages}["comparison"]
    assert rec.status == "failed"
    assert rec.message.startswith("internal error: RuntimeError") and "runner.py:" in rec.message
    out = read_session(res.out_dir)
    assert out.has("joint_torques") and out.summary.comparison is None
    assert any(i.stage == "comparison" for i in out.summary.not_available)


def test_cache_reuses_and_invalidates(tmp_path):
    cfg, _ = write_synthetic_session(tmp_path / "s")
    out = tmp_path / "out"
    first = run_session(cfg, out)
    a0 = read_session(out).table("joint_torques").data
    second = run_session(cfg, out)
    st1 = {r.name: r.status for r in first.stages}
    st2 = {r.name: r.status for r in second.stages}
    assert {s for s in st1.values()} <= {"computed", "not available", "not requested"}
    assert st1["fes"] == "not requested"  # no FES trial in the configuration
    # every computed stage comes from the cache, the model too (its plain-data state:
    # msk.pipeline.graph.model_to_cache; a msk.model.core.Model is not storable without pickle)
    assert all(st2[n] == "cached" for n, s in st1.items() if s == "computed")
    assert not list((out / ".cache").glob("*.pkl"))
    # identical numbers from the cache
    a = read_session(out).table("joint_torques").data
    assert np.array_equal(a, a0, equal_nan=True)
    # a changed setting recomputes exactly the stages downstream of it
    cfg.write_text(cfg.read_text().replace("grf_cutoff_hz = 15.0", "grf_cutoff_hz = 12.0"))
    third = run_session(cfg, out)
    st3 = {r.name: r.status for r in third.stages}
    assert st3["read"] == st3["kinematics"] == "cached"
    assert st3["loads"] == st3["mass_identification"] == st3["inverse_dynamics"] == "computed"
    b = read_session(out).table("joint_torques").data
    assert not np.allclose(a, b, equal_nan=True)
    # a poisoned or corrupted entry is never used: flip a byte of every cached array file
    for f in (out / ".cache").glob("*.npz"):
        blob = bytearray(f.read_bytes())
        blob[len(blob) // 2] ^= 0xFF
        f.write_bytes(bytes(blob))
    fourth = run_session(cfg, out)
    st4 = {r.name: r.status for r in fourth.stages}
    assert "cached" not in st4.values()
    assert np.array_equal(read_session(out).table("joint_torques").data, b, equal_nan=True)


def test_model_stage_from_the_cache_gives_the_later_stages_the_same_numbers(tmp_path):
    """The later stages computed on the model rebuilt from the cache (every entry but the read
    and model stages' removed) write the tables of the run that computed it, bit for bit; an
    entry that does not make a model is computed again, never fatal."""
    from msk.pipeline import graph

    cfg, _ = write_synthetic_session(tmp_path / "s")
    out = tmp_path / "out"
    run_session(cfg, out)
    before = read_session(out)
    for f in (out / ".cache").iterdir():
        if not f.name.startswith(("read-", "model-")):
            f.unlink()
    again = run_session(cfg, out)
    status = {r.name: r.status for r in again.stages}
    assert status["model"] == "cached" and status["kinematics"] == "computed"
    after = read_session(out)
    assert set(after.tables) == set(before.tables)
    for name, tb in before.tables.items():
        assert np.array_equal(after.table(name).data, tb.data, equal_nan=True), name
    # a stored model state that cannot be built (an unknown body): the stage is computed again
    for f in (out / ".cache").glob("model-*.json"):
        f.unlink()

    def broken(stored):
        bad = dataclasses.replace(stored.model, bodies=stored.model.bodies[1:])
        return graph.model_from_cache(dataclasses.replace(stored, model=bad))

    runs = []
    nodes = tuple(
        dataclasses.replace(n, from_cache=broken) if n.name == "model" else n for n in graph.GRAPH
    )
    for _ in range(2):
        runner = Runner(out / ".cache", None, stages=graph.STAGES, core=graph.CORE_STAGES)
        graph.run_graph(session_inputs(load_config(cfg)), runner, nodes[:4])
        runs.append({r.name: r.status for r in runner.records})
    assert runs[0]["model"] == "computed" and runs[1]["model"] == "computed"
    assert runs[1]["kinematics"] == "cached"
    # a long trial's model stage is not written (its model-frame markers: issue 18's bound)
    built = run_stages(cfg, until="model")["model"]
    assert graph.model_to_cache(built).model is not built.model
    long = dataclasses.replace(built, trial=SimpleNamespace(time=np.zeros(FRAME_BLOCK + 1)))
    assert graph.model_to_cache(long) is long


def test_cli_run_print_config_and_errors(tmp_path, capsys):
    cfg, _ = write_synthetic_session(tmp_path / "s")
    assert main(["run", str(cfg), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    assert (tmp_path / "o" / "report.html").is_file()
    capsys.readouterr()
    assert main(["print-config"]) == 0
    assert capsys.readouterr().out == config_reference()
    assert main(["print-config", "--example", "--out", str(tmp_path / "t.toml")]) == 0
    assert (tmp_path / "t.toml").read_text() == TEMPLATE
    assert main(["print-config", str(cfg)]) == 0
    assert capsys.readouterr().out == render_config(load_config(cfg))
    # a bad config (unknown key) → one line, status 2
    bad = tmp_path / "bad.toml"
    bad.write_text(cfg.read_text().replace("[filters]", "[filters]\ncolour = 3"))
    bad.with_name("two_legs.toml").write_bytes((cfg.parent / "two_legs.toml").read_bytes())
    (tmp_path / "synth.c3d").write_bytes((cfg.parent / "synth.c3d").read_bytes())
    assert main(["run", str(bad), "--out", str(tmp_path / "o2")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("msk: error:") and "filters.colour" in err[0]
    # a broken C3D (core stage) → one line, status 2, nothing written
    broken, _ = write_synthetic_session(tmp_path / "b", broken=True)
    assert main(["run", str(broken), "--out", str(tmp_path / "o3"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "synth.c3d" in err[0]
    assert not (tmp_path / "o3" / "summary.json").exists()


def test_several_task_trials_each_get_a_results_folder(tmp_path, capsys):
    """``msk run`` analyses every task trial (one folder each); ``run_session`` refuses a
    configuration with several rather than silently analysing the first."""
    cfg, _ = write_synthetic_session(tmp_path / "s")
    second = cfg.read_text() + '\n[[trials]]\nname = "walk2"\nfile = "synth.c3d"\nrole = "task"\n'
    cfg.write_text(second.replace("[filters]", "[filters]", 1))
    with pytest.raises(ConfigError, match=r"2 task trials \(walk, walk2\)"):
        run_session(cfg, tmp_path / "refused")
    assert not (tmp_path / "refused").exists()
    assert main(["run", str(cfg), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    for name in ("walk", "walk2"):
        folder = tmp_path / "o" / name
        assert (folder / "report.html").is_file()
        summary = json.loads((folder / "summary.json").read_text())
        assert summary["trial"] == name, summary.get("trial")
    # and one report of the session, every task trial's cycles in it
    html = (tmp_path / "o" / "report.html").read_text(encoding="utf-8")
    assert "trials walk, walk2" in html and 'id="kinematics"' in html


@pytest.mark.slow
def test_bundled_grand_challenge_session():
    """The README's main job: subject PS, gait2392, every stage available, the knee contact
    force within the range of the measured eTibia force."""
    res = sessions.session(GC5)  # the folder shared with the other tests reading it
    s = res.summary.to_dict()
    status = {r.name: r.status for r in res.stages}
    assert status.pop("fes") == "not requested"  # a gait session without FES trials
    assert all(v == "computed" for v in status.values()), status
    out = read_session(res.out_dir)
    # the trial holds one right foot strike: no complete right cycle, no right cycle table
    assert out.summary.gait is not None and (out.summary.gait.cycles or {}).get("right") == 0
    assert set(out.tables) == {
        t for t in TABLES if not t.startswith("fes_") and t != "gait_cycles_right"
    }
    q = s["quality"]
    assert q["ik_failed_frames"] == 0 and q["ik_marker_rms_mean_m"] < 0.03
    assert set(q["emg_flat_channels"]) == {"gracilis", "gmed"}
    kc = s["comparison"]["knee_contact_subject_specific"]
    # eTibia peak 1611 N = 2.19 × (75 kg g), the source's mass; the session uses the plates' 82.8 kg
    assert kc["peak_measured_bw"] == pytest.approx(2.19 * 75.0 / 82.8, abs=0.02)
    # measured: the peak 0.59 BW over with the plates at 15 Hz, 0.61 at the kinematics' 6 Hz
    # (RMSE 0.30 → 0.27 BW, r 0.92 → 0.94): the peak is over-predicted, within 0.65 BW
    assert abs(kc["peak_predicted_bw"] - kc["peak_measured_bw"]) < 0.65
    assert kc["pearson_r"] > 0.5
    # left stance on plate 1, right foot on plates 2 and 3
    bodies = {a["plate"]: a["body"] for a in q["plate_assignments"]}
    assert bodies == {"plate1": "calcn_l", "plate2": "calcn_r", "plate3": "calcn_r"}
    assert s["gait_cycle_s"] == pytest.approx([5.1417, 6.2333], abs=1e-3)
    assert (res.out_dir / "tables" / "muscle_forces.sto").is_file()


@pytest.mark.slow
@pytest.mark.parametrize("method", ["emg_weighted", "emg_assisted"])
def test_bundled_session_with_emg_informed_tension_optimization(tmp_path, method):
    """The EMG-informed methods of ``[optimization]`` on the bundled session: torques met,
    EMG-assisted gains fitted per channel (only usable channels), the contact force computed."""
    text, n = re.subn(
        r'(?m)^method = ".*"$', f'method = "{method}"\nw_track = 1.0', GC5.read_text(), count=1
    )
    assert n == 1
    cfg = tmp_path / "session.toml"  # the session's relative paths made absolute
    cfg.write_text(text.replace('"../', f'"{REPO.as_posix()}/'))
    res = run_session(cfg, tmp_path / method)
    status = {r.name: r.status for r in res.stages}
    assert status["tension_optimization"] == status["knee_contact"] == "computed", status
    opt = res.summary.to_dict()["optimization"]
    assert opt["method"] == method and opt["infeasible_frames"] == 0
    forces = read_session(res.out_dir).table("muscle_forces").data
    # the KKT check of every solved frame, reported: DAQP at round-off of the scales (a frame
    # whose other leg is left out — its foot off the plates — is solved and checked too)
    kkt = opt["kkt"]
    solved = np.isfinite(forces[:, 1:]).any(axis=1)  # column 0: time
    assert kkt["frames"] == int(solved.sum()) > int(np.isfinite(forces).all(axis=1).sum()) > 0
    for c in ("stationarity", "primal_feasibility", "dual_feasibility", "complementarity"):
        assert 0.0 <= kkt[c]["relative_max"] < 1e-12 and kkt[c]["max"] >= 0.0, (c, kkt[c])
    assert "KKT check of the" in (res.out_dir / "report.html").read_text(encoding="utf-8")
    assert np.all(np.nan_to_num(forces) >= -1e-6)
    if method == "emg_assisted":
        gains = opt["emg_gains"]
        # one gain per usable channel (gracilis and gmed are flat), EMG at session peak → g < 1
        assert set(gains) == {
            "semimem",
            "bifeml",
            "vasmed",
            "vaslat",
            "rf",
            "medgas",
            "latgas",
            "tfl",
            "tibant",
            "peronl",
            "soleus",
            "addmag",
            "gmax",
            "sartorius",
        }
        assert all(0.0 <= g < 1.0 for g in gains.values()), gains
        assert "g_c" in opt["criterion"]
        assert "gain g_c" in (res.out_dir / "report.html").read_text(encoding="utf-8")


@pytest.mark.slow
def test_emg_assisted_without_a_usable_channel_is_static_optimisation():
    """``emg_assisted`` with no EMG channel usable (flat, unplugged) solves every frame, without
    gains, as static optimisation with exponent 2 (the same activations to the solver's
    tolerance) and says so in its criterion; it never fails the stage."""
    import dataclasses

    from msk.pipeline import tension
    from msk.pipeline.inputs import session_inputs

    cfg = load_config(GC5)
    assert cfg.optimization.method == "emg_assisted"
    r = run_stages(cfg, until="muscle_geometry")
    flat = dataclasses.replace(r["emg"], usable=np.zeros_like(r["emg"].usable))
    args = (r["model"], r["kinematics"], r["loads"], r["mass_identification"])
    rest = (r["inverse_dynamics"], r["muscle_geometry"])
    ea = tension.run(session_inputs(cfg), *args, *rest, flat)
    assert ea.emg_gains is None and "no EMG channel" in (ea.criterion or "")
    so_cfg = dataclasses.replace(
        cfg,
        optimization=dataclasses.replace(
            cfg.optimization, method="static_optimization", activation_exponent=2
        ),
    )
    so = tension.run(session_inputs(so_cfg), *args, *rest, None)
    assert ea.infeasible_frames == so.infeasible_frames == 0
    np.testing.assert_allclose(ea.activations, so.activations, atol=1e-6)


def test_broken_library_piece_is_reported_not_faked(tmp_path, monkeypatch):
    """A stage whose library piece is broken is 'failed' (with the reason and where) in
    summary.json and the report; the stages after it run on what exists."""
    import msk.dynamics.identification

    cfg, _ = write_synthetic_session(tmp_path / "s")
    monkeypatch.delattr(msk.dynamics.identification, "InertialIdentifier")
    res = run_session(cfg, tmp_path / "out")
    status = {r.name: r.status for r in res.stages}
    assert status["mass_identification"] == "failed"
    assert status["inverse_dynamics"] == "computed"  # on the generic (scaled) inertias
    out = read_session(res.out_dir)
    assert not out.has("inertial_parameters") and out.has("joint_torques")
    (item,) = [i for i in out.summary.not_available if i.stage == "mass_identification"]
    assert "ImportError" in item.reason and "InertialIdentifier" in item.reason
    assert out.summary.identification is None
    html = (res.out_dir / "report.html").read_text()
    assert "InertialIdentifier" in html


def test_mass_identification_trials_are_used(tmp_path):
    cfg, trial = write_synthetic_session(tmp_path / "s")
    write_synthetic_session(tmp_path / "s", "extra", seed=3)
    text = cfg.read_text() + (
        '\n[[trials]]\nname = "exciting"\nfile = "extra.c3d"\nrole = "mass_identification"\n'
    )
    # [[trials]] must come before the [filters] table in TOML: rebuild the file in order
    head, filters = text.split("[filters]")
    filters, more = filters.split("\n[[trials]]", 1)
    cfg.write_text(head + "[[trials]]" + more + "\n[filters]" + filters)
    res = run_session(cfg, tmp_path / "out")
    s = res.summary.to_dict()
    assert s["identification"]["n_frames"] > trial.time.size  # task + exciting trial
    assert any(i["role"] == "mass_identification:exciting" for i in s["inputs"])


def test_config_typos_end_the_run_with_one_line(tmp_path, capsys):
    """An EMG channel or marker-weight name that matches nothing is a configuration error
    (exit 2, one line, nothing written), not a 'failed stage' with exit 0."""
    base = GC5.read_text(encoding="utf-8")
    base = base.replace('"../', f'"{REPO}/')
    for edit, message in (
        (lambda t: t.replace('vas_med_l = "vasmed"', 'vas_med_l = "vasmedX"'),
         "has no analog channel 'vasmedX'"),
        (lambda t: t.replace("weights = {}", 'weights = { "R.ASISS" = 2.0 }'),
         "markers.weights: no marker 'R.ASISS'"),
        (lambda t: t + '\n[loads]\nsurface_height_m = { plate9 = 0.2 }\n',
         "[loads] surface_height_m: no plate 'plate9'"),
    ):  # fmt: skip
        cfg = tmp_path / "typo.toml"
        cfg.write_text(edit(base), encoding="utf-8")
        out = tmp_path / "out"
        assert main(["run", str(cfg), "--out", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], err
        assert not (out / "summary.json").exists()


@pytest.mark.slow
@pytest.mark.realdata
def test_an_emg_channel_absent_from_the_trial_is_flagged_not_fatal(tmp_path):
    """A configured EMG channel the task file does not record, with no analog label like it
    (another trial of the session without that electrode), leaves its muscle untracked and
    raises the ``emg_channels_missing`` flag; the run completes (exit 0)."""
    text = GC5.read_text(encoding="utf-8").replace('"../', f'"{REPO}/')
    assert 'vas_med_l = "vasmed"' in text
    cfg = tmp_path / "absent.toml"
    cfg.write_text(text.replace('vas_med_l = "vasmed"', 'vas_med_l = "EMG16"'), encoding="utf-8")
    res = run_session(cfg, tmp_path / "out")
    status = {r.name: r.status for r in res.stages}
    assert status["emg"] == "computed" and status["tension_optimization"] == "computed"
    flags = res.summary.to_dict()["quality"]["flags"]
    (flag,) = [f for f in flags if f["quantity"] == "emg_channels_missing"]
    assert flag["value"] == 1 and "'EMG16'" in flag["message"] and "vas_med_l" in flag["message"]
    out = read_session(res.out_dir)
    assert "EMG16" not in (out.summary.quality.emg_flat_channels or ())


@pytest.mark.slow
@pytest.mark.realdata
def test_given_knee_alignment_and_contact_depth_reach_the_model_and_the_split(tmp_path):
    """``[model] knee_varus_deg`` / ``knee_medial_shift_m`` align the side of interest's knee
    (PS: the left one) and nothing else; ``[contact] plateau_depth_m`` places the contact
    points (msk.model.alignment, msk.contact.knee)."""
    from msk.pipeline import run_stages

    text = GC5.read_text(encoding="utf-8").replace('"../', f'"{REPO}/')
    text = text.replace("scale = true\n", "scale = true\nknee_varus_deg = 3.0\n")
    text = text.replace(
        "knee_varus_deg = 3.0\n", "knee_varus_deg = 3.0\nknee_medial_shift_m = -0.005\n"
    )
    text += "\n[contact]\nplateau_depth_m = 0.03\n"
    cfg = tmp_path / "s.toml"
    cfg.write_text(text, encoding="utf-8")
    st = run_stages(cfg, until="knee_contact")
    model = st["model"].model
    assert model.metadata["knee_alignment"] == {
        "knee_l": {"varus_rad": pytest.approx(np.radians(3.0)), "medial_shift_m": -0.005,
                   "side": "left"}
    }  # fmt: skip
    assert st["model"].info["knee_alignment"]["knee_l"]["side"] == "left"
    knee_l = next(j for j in model.joints if j.name == "knee_l")
    knee_r = next(j for j in model.joints if j.name == "knee_r")
    assert np.allclose(knee_r.child_offset.rotation, np.eye(3))
    # left varus: the tibia turns about −x after flexion (child offset = R_x(+α))
    c, s_ = np.cos(np.radians(3.0)), np.sin(np.radians(3.0))
    np.testing.assert_allclose(
        knee_l.child_offset.rotation, [[1, 0, 0], [0, c, -s_], [0, s_, c]], atol=1e-12
    )
    assert st["knee_contact"].plateau["centre_m"] == [0.0, -0.03, 0.0]
    assert np.isfinite(st["knee_contact"].variants["generic"].medial).any()


def test_static_knee_held_only_where_no_epicondyle_and_malleolus():
    from msk.datasets.models import two_leg_model
    from msk.personalise.coordinates import HELD_COORDINATE_WEIGHT, held_static_knees

    model = two_leg_model()
    # right: lateral epicondyle and malleolus (Plug-in Gait); left: clusters and a patella
    labels = ("RASI", "LASI", "RKNE", "RANK", "LThighSuperior", "LShankInferior", "LPatella")
    assert held_static_knees(model, labels) == {"knee_angle_l": (0.0, HELD_COORDINATE_WEIGHT)}
    assert held_static_knees(model, ("RKNE", "RANK", "LKNE", "LMedMal")) == {}
    assert set(held_static_knees(model, ("RKNE", "LANK"))) == {"knee_angle_r", "knee_angle_l"}


def test_knee_flexion_bound_widened_to_the_physiological_limit_only_where_narrower():
    """A knee flexed past gait2392's 120° (a running swing) is solved where it is, not held at
    the bound; a knee with positive flexion (Rajagopal's convention) is left alone."""
    from msk.datasets.models import two_leg_model
    from msk.datasets.trials import make_trial
    from msk.kinematics.ik import solve_kinematics
    from msk.model.core import marker_positions
    from msk.personalise.coordinates import knee_flexion_to_physiological

    model = two_leg_model()  # knees [-120.3°, 9.7°]
    wide, widened = knee_flexion_to_physiological(model)
    assert widened == {k: [-155.0, pytest.approx(np.degrees(0.17))] for k in widened}
    assert set(widened) == {"knee_angle_r", "knee_angle_l"}
    positive = model.with_coordinate_ranges(
        {"knee_angle_r": (0.0, 2.1), "knee_angle_l": (0.0, 2.1)}
    )
    assert knee_flexion_to_physiological(positive) == (positive, {})
    # a knee that turns the other way (Rajagopal's walker knee: + in flexion, 0…120°) has
    # its flexion bound widened on its positive side
    from tests.support.knees import turned_knees

    turned = turned_knees(model).with_coordinate_ranges(
        {"knee_angle_r": (-0.17, 2.1), "knee_angle_l": (-0.17, 2.1)}
    )
    _, widened = knee_flexion_to_physiological(turned)
    assert widened["knee_angle_r"] == [pytest.approx(np.degrees(-0.17)), pytest.approx(155.0)]
    tr = make_trial(model, duration_s=0.5)
    q = tr.q.copy()
    k = model.coordinate_names.index("knee_angle_l")
    q[:, k] = np.radians(np.linspace(-100.0, -140.0, q.shape[0]))  # a swing past 120°
    x = marker_positions(model, q) + np.random.default_rng(0).normal(
        0, 0.001, (q.shape[0], len(model.markers), 3)
    )
    labels = [m.name for m in model.markers]
    held = solve_kinematics(model, x, labels, tr.time, cutoff_hz=None)
    free = solve_kinematics(wide, x, labels, tr.time, cutoff_hz=None)
    assert np.degrees(held.q[:, k]).min() > -120.4  # clamped: the pose there is not measured
    assert np.abs(np.degrees(free.q[:, k] - q[:, k])).max() < 1.0
    assert np.nanmean(free.marker_rms) < 0.5 * np.nanmean(held.marker_rms)


@pytest.mark.slow
@pytest.mark.realdata
def test_a_trial_no_plate_measures_runs_kinematics_and_says_why_no_dynamics(tmp_path):
    """The bundled session with its task's plates unloaded (a walk past the plates, or a trial
    cut with no foot on one; swept in issue 15, eighth pass): the run completes with the
    kinematics, the identification stages are not available with a reason — not an internal
    error (was ``ValueError: cannot reshape array of size 0`` in tension_optimization and
    strength_identification) —, the ``contact_measured_frames`` flag says why, and muscle
    forces are solved only for the leg that swings (issue 16/15: per-leg frames); the strength
    stage tries the EMG leg's swing frames and says they determine nothing."""
    import ezc3d

    c = ezc3d.c3d(str(REPO / "data" / "gc5-PS" / "PS_ngait_og_ss1.c3d"))
    ch = np.asarray(c["parameters"]["FORCE_PLATFORM"]["CHANNEL"]["value"]).ravel() - 1
    analogs = c["data"]["analogs"]
    analogs[0, ch, :] = 0.0
    c["data"]["analogs"] = analogs
    c.write(str(tmp_path / "noplate.c3d"))
    text = GC5.read_text(encoding="utf-8").replace('"../', f'"{REPO}/')
    text = text.replace(f'"{REPO}/data/gc5-PS/PS_ngait_og_ss1.c3d"', f'"{tmp_path}/noplate.c3d"')
    text = re.sub(r'(?m)^contact_force = ".*"$', "", text)
    cfg = tmp_path / "noplate.toml"
    cfg.write_text(text, encoding="utf-8")
    res = run_session(cfg, tmp_path / "out")
    q = res.summary.to_dict()["quality"]
    assert q["contact_measured_frames"] == 0 and q["ik_marker_rms_mean_m"] < 0.012
    (flag,) = [f for f in q["flags"] if f["quantity"] == "contact_measured_frames"]
    assert "no frame of the 145" in flag["message"]
    why = {r["stage"]: r["reason"] for r in res.summary.to_dict()["not_available"]}
    # a swinging leg bears no ground reaction: its muscle forces are solved while the other
    # foot stands on the (now unmeasured) floor — never both legs in one frame
    solved = res.summary.to_dict()["optimization"]["frames_solved"]
    assert 0 < solved["r"] < 145 and 0 < solved["l"] < 145, solved
    forces = read_session(res.out_dir).table("muscle_forces")
    cols = list(forces.columns)
    both = [
        np.isfinite(forces.data[:, [k for k, n in enumerate(cols) if n.endswith(sfx)]]).all(axis=1)
        for sfx in ("_r", "_l")
    ]
    assert not (both[0] & both[1]).any()
    # strength per leg: the EMG leg's swing frames (the other foot on the unmeasured floor)
    # are its own frames, too few to pass the correlation gate — said so
    assert "solvable frames determine no strength" in why["strength_identification"], why
    assert why["mass_identification"].startswith("fewer than 2 frames"), why
    assert not any("internal error" in r for r in why.values()), why
    assert not [r for r in res.summary.to_dict()["not_available"] if r["status"] == "failed"]


def test_placement_frames_are_interleaved_over_the_well_tracked_frames():
    """:func:`msk.personalise.placement.placement_frames` (issue 15, eleventh pass): at most
    ``max_frames`` frames, evenly interleaved from the first to the last well-tracked frame,
    none of a stretch where three markers drop out (NaN or exact zeros), the same on every
    call; a trial shorter than ``max_frames`` gives all its well-tracked frames, and one where
    most frames miss markers still gives ``max_frames`` (from the best-tracked)."""
    from msk.personalise.placement import placement_frames

    rng = np.random.default_rng(0)
    x = rng.normal(size=(1000, 10, 3))
    x[300:400, :3] = np.nan  # three markers lost
    x[600:650, 4:7] = 0.0  # three more, written as zeros (TRC)
    x[800:820, 9] = np.nan  # one: still well tracked
    idx = placement_frames(x, 100)
    assert idx.size == 100 and np.all(np.diff(idx) > 0)
    assert idx[0] == 0 and idx[-1] == 999
    assert not np.isin(idx, np.r_[300:400, 600:650]).any()
    assert np.isin(idx, np.r_[800:820]).any()
    well = np.setdiff1d(np.arange(1000), np.r_[300:400, 600:650])
    assert np.ptp(np.diff(np.searchsorted(well, idx))) <= 1  # evenly over the 850 of them
    np.testing.assert_array_equal(idx, placement_frames(x, 100))
    assert placement_frames(x[:50], 100).tolist() == list(range(50))
    y = x.copy()
    y[100:, :3] = np.nan  # only the first 100 frames see every marker, most miss three
    worse = placement_frames(y, 150)
    assert worse.size == 150 and worse[-1] == 999
    assert not np.isin(worse, np.r_[600:650]).any()  # these miss six


def test_foot_joint_held_by_the_frames_the_ik_solves_not_by_any_trajectory():
    """Issue 15, twelfth pass: a subtalar is observed when three markers on the foot are
    tracked in half of the frames the IK solves (at least half of the most model markers any
    frame sees), not of every frame that tracks something — a running trial's unlabelled
    trajectories and acromia outlast its foot markers (UWA ``Running_1``: the right subtalar
    was held with its metatarsal heads tracked in 93 % of the solved frames)."""
    from msk.model.files import load_model
    from msk.personalise.coordinates import held_foot_coordinates

    model = load_model(REPO / "msk" / "data" / "models" / "gait2392.toml")
    pelvis = ["R.ASIS", "L.ASIS", "V.Sacral"]
    foot = ["R.Heel", "R.Toe.Lat", "R.Toe.Med"]
    labels = (*pelvis, *foot, "R.Acromium", "*33")
    assert set(labels[:-1]) <= set(model.marker_names)
    x = np.full((100, len(labels), 3), np.nan)
    x[20:60, : len(pelvis) + len(foot)] = 0.1  # the subject in the capture volume
    x[:, -2:] = 0.2  # an acromion and an unlabelled trajectory, tracked throughout
    held = held_foot_coordinates(model, x, labels)
    assert "subtalar_angle_r" not in held and "subtalar_angle_l" in held
    lost = x.copy()
    lost[30:60, labels.index("R.Toe.Med")] = np.nan  # tracked in 10 of the 40 solved frames
    assert "subtalar_angle_r" in held_foot_coordinates(model, lost, labels)


def test_the_pipeline_imports_neither_the_fes_package_nor_scipy_signal():
    """A gait session's run (and a cached one wholly) does not pay for the FES package's
    casadi, ``scipy.optimize`` and ``scipy.signal``/``scipy.stats``: importing the stage graph,
    the summary and the tables imports none of them (the FES stage imports them on use)."""
    code = (
        "import sys\n"
        "import msk.pipeline, msk.pipeline.summary, msk.pipeline.tables, msk.pipeline.graph\n"
        "heavy = ('msk.fes.protocol', 'msk.fes.identify', 'scipy.signal', 'scipy.stats')\n"
        "print(' '.join(m for m in heavy if m in sys.modules))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=True
    )
    assert proc.stdout.strip() == ""
