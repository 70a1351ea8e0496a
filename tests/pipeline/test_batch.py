"""msk.pipeline.batch: many sessions on a local process pool and on a real Dask LocalCluster, a
broken
session reported without stopping the others, the cohort table, msk compare."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from msk.cli import main
from msk.datasets.trials import write_synthetic_session
from msk.pipeline.batch import run_batch
from msk.results.cohort import COHORT_COLUMNS, compare_sessions

REPO = Path(__file__).resolve().parents[2]
GC5 = REPO / "pipelines" / "gc5_PS.toml"


def _cohort(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert rows and list(rows[0]) == list(COHORT_COLUMNS)
    return rows


@pytest.mark.slow
def test_dask_local_cluster(tmp_path):
    distributed = pytest.importorskip("distributed")
    a, _ = write_synthetic_session(tmp_path / "a", "synth_a", seed=1)
    b, _ = write_synthetic_session(tmp_path / "b", "synth_b", seed=2, noise_m=0.002)
    bad, _ = write_synthetic_session(tmp_path / "c", "broken", broken=True)
    configs = [a, GC5, bad, b]
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    ) as cluster:
        assert len(cluster.workers) == 2
        # the scheduler address, as `msk batch --scheduler tcp://...` passes it
        res = run_batch(configs, tmp_path / "out", scheduler=cluster.scheduler_address)
    assert [o.ok for o in res.outcomes] == [True, True, False, True]
    (failed,) = res.failed
    assert "\n" not in failed.error and "C3DError" in failed.error and "broken.c3d" in failed.error
    for name in ("synth_a", "gc5_PS", "synth_b"):
        assert (tmp_path / "out" / name / "report.html").is_file()
        assert (tmp_path / "out" / name / "tables" / "q.csv").is_file()
    assert not (tmp_path / "out" / "broken" / "summary.json").exists()
    rows = _cohort(res.cohort_csv)
    assert [r["status"] for r in rows] == ["ok", "ok", "failed", "ok"]
    ps = rows[1]
    assert ps["session"] == "PS" and float(ps["knee_contact_icc"]) > 0.3
    assert float(ps["ik_marker_rms_mean_mm"]) < 30 and ps["emg_flat_channels"] == "gmed gracilis"
    # the subject's mass and where it comes from; the left cycle's spatiotemporal parameters
    assert float(ps["mass_kg"]) == 82.8 and ps["mass_source"] == "config"
    assert ps["cycles_left"] == "1" and 0.9 < float(ps["walking_speed_m_s_left"]) < 1.3
    assert 55 < float(ps["stance_pct_left"]) < 70 and ps["stance_pct_right"] == ""
    assert "muscle_geometry" in rows[0]["stages_not_available"]


def test_local_pool_cli_and_compare(tmp_path, capsys):
    a, _ = write_synthetic_session(tmp_path / "a", "synth_a", seed=1)
    bad, _ = write_synthetic_session(tmp_path / "c", "broken", broken=True)
    out = tmp_path / "out"
    status = main(["batch", str(a), str(bad), "--out", str(out), "--workers", "2"])
    assert status == 1  # one session failed, the other completed
    err = capsys.readouterr().err
    failed = [ln for ln in err.splitlines() if ln.startswith("FAILED")]
    assert len(failed) == 1 and "broken.toml" in failed[0]
    assert "1/2 sessions ok" in err
    assert (out / "synth_a" / "summary.json").is_file()
    rows = _cohort(out / "cohort.csv")
    assert [r["status"] for r in rows] == ["ok", "failed"]
    # compare across session folders: generic vs identified masses and residuals
    table = compare_sessions([out / "synth_a"])
    masses = [r for r in table if r["quantity"] == "segment mass"]
    assert masses and all(r["unit"] == "kg" for r in masses)
    assert any(r["quantity"] == "pelvis residual RMS" for r in table)
    assert main(["compare", str(out / "synth_a"), "--out", str(tmp_path / "cmp.csv")]) == 0
    text = capsys.readouterr().out
    assert "segment mass" in text and "pelvis" in text
    assert (tmp_path / "cmp.csv").read_text().startswith("session,quantity,item,generic")
    # a folder that is not a session → one line, status 2
    assert main(["compare", str(tmp_path)]) == 2
