"""msk._runtime.isolated and msk.pipeline.batch: a batch survives any worker (killed, stopped,
hung)."""

from __future__ import annotations

import csv
import multiprocessing as mp
import os
import sys
import time
from pathlib import Path

import pytest

from msk._runtime.isolated import JobFailure, clean_sys_path, run_isolated
from tests.support import batch_jobs as jobs

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def ctx():
    if "forkserver" not in mp.get_all_start_methods():
        pytest.skip("no forkserver here")
    return mp.get_context("forkserver")


def test_six_jobs_one_killed_by_sigsegv_one_stopped(ctx, tmp_path):
    fns = [jobs.double, jobs.segfault, jobs.double, jobs.stop, jobs.double, jobs.double]
    done: list[int] = []
    t0 = time.monotonic()
    out = run_isolated(
        _dispatch,
        [(f.__name__, k) for k, f in enumerate(fns)],
        context=ctx,
        workers=2,
        time_limit_s=3.0,
        on_done=lambda k, v: done.append(k),
    )
    assert time.monotonic() - t0 < 30
    assert [out[k] for k in (0, 2, 4, 5)] == [0, 4, 8, 10]  # the good ones, all of them
    seg, stopped = out[1], out[3]
    assert isinstance(seg, JobFailure) and "killed by SIGSEGV (2 attempts)" in seg.reason
    assert isinstance(stopped, JobFailure) and "time limit of 3 s" in stopped.reason
    assert sorted(done) == list(range(6))


def _dispatch(name: str, arg: object) -> object:
    return getattr(jobs, name)(arg)


def test_a_job_killed_once_is_retried(ctx, tmp_path):
    (v,) = run_isolated(
        jobs.killed_once, [(str(tmp_path / "flag"),)], context=ctx, workers=1, time_limit_s=30
    )
    assert v == "second run"


def test_an_exception_is_the_jobs_failure_not_a_retry(ctx):
    (v,) = run_isolated(jobs.raises, [(0,)], context=ctx, workers=1, time_limit_s=30)
    assert isinstance(v, JobFailure) and v.attempts == 1 and "ValueError: bad input" in v.reason


def test_children_do_not_import_from_the_current_folder(ctx, tmp_path, monkeypatch):
    (tmp_path / "concurrent.py").write_text("raise ImportError('planted')\n")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "path", ["", str(tmp_path), *sys.path])
    (v,) = run_isolated(jobs.where_concurrent, [(0,)], context=ctx, workers=1, time_limit_s=30)
    origin, path = v
    assert not origin.startswith(str(tmp_path)) and "" not in path and str(tmp_path) not in path
    assert clean_sys_path(["", ".", str(tmp_path), "/x"]) == ["/x"]
    assert clean_sys_path([str(tmp_path), "/x"], keep=[str(tmp_path)]) == [str(tmp_path), "/x"]


def test_a_batch_session_over_its_time_limit_is_failed_and_cohort_written(tmp_path):
    from msk.pipeline.batch import run_batch

    cfg = REPO / "pipelines" / "gc5_PS.toml"
    res = run_batch([cfg], tmp_path / "b", workers=1, time_limit_s=0.2)
    (o,) = res.outcomes
    assert not o.ok and "time limit of 0.2 s" in o.error
    rows = list(csv.DictReader((tmp_path / "b" / "cohort.csv").open()))
    assert rows[0]["status"] == "failed" and "time limit" in rows[0]["error"]
    # no process of the killed session is left
    assert not [p for p in mp.active_children() if p.is_alive()]
    assert os.path.isdir(tmp_path / "b")
