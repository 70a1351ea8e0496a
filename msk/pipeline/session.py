"""Running a session: a configuration → the results folder of :mod:`msk.results.folder`.

:func:`run_session` resolves the inputs (:func:`~msk.pipeline.inputs.session_inputs`), runs the
stage graph (:func:`~msk.pipeline.graph.run_graph`) with the cache in ``<out>/.cache``, adds
the stage records to the summary and writes the folder atomically with its report.
:func:`run_task_trials` does it for every task trial of a session.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any, TextIO

from threadpoolctl import threadpool_limits

from msk._runtime.memory import map_large_blocks
from msk.config import SessionConfig, load_config
from msk.exceptions import ConfigError
from msk.pipeline.graph import CORE_STAGES, GRAPH, STAGES, run_graph
from msk.pipeline.inputs import session_inputs
from msk.pipeline.runner import Runner, RunResult
from msk.results.folder import SessionResults, check_replaceable, write_session
from msk.results.summary import Summary

__all__ = ["run_session", "run_stages", "run_task_trials", "split_task_trials"]


def split_task_trials(cfg: SessionConfig) -> list[SessionConfig]:
    """One configuration per task trial, each keeping the session's other trials (static,
    mass identification, MVC, FES); a configuration with at most one task trial is returned
    as is."""
    tasks = cfg.trials_with_role("task")
    if len(tasks) <= 1:
        return [cfg]
    return [
        dataclasses.replace(cfg, trials=tuple(t for t in cfg.trials if t.role != "task" or t is k))
        for k in tasks
    ]


def run_task_trials(
    config: str | Path | SessionConfig,
    out_dir: str | Path,
    **options: Any,
) -> list[RunResult]:
    """:func:`run_session` for every task trial of the session: one task trial → ``out_dir``
    itself; several → ``out_dir/<trial name>/`` each (a complete results folder, whose report
    and tables are that trial's; ``msk compare`` reads them together). ``options`` as for
    :func:`run_session`. Every target folder is checked before anything is computed; a core
    stage failing on one trial raises after the trials before it were written."""
    cfg = config if isinstance(config, SessionConfig) else load_config(config)
    parts = split_task_trials(cfg)
    out = Path(out_dir).resolve()
    if len(parts) == 1:
        return [run_session(cfg, out, **options)]
    dirs = [out / t.name for t in cfg.trials_with_role("task")]
    for d in dirs:
        check_replaceable(d)
    return [run_session(c, d, **options) for c, d in zip(parts, dirs)]


def run_stages(
    config: str | Path | SessionConfig, *, until: str, progress: TextIO | None = None
) -> dict[str, Any]:
    """The results of the graph's nodes up to and including ``until`` (node name → result),
    without cache and without writing anything: the pipeline's own model, kinematics, loads…
    for a study that goes on from there."""
    names = [n.name for n in GRAPH]
    if until not in names:
        raise ConfigError(f"no pipeline stage {until!r}; stages: {', '.join(names)}")
    cfg = config if isinstance(config, SessionConfig) else load_config(config)
    runner = Runner(None, progress, stages=STAGES, core=CORE_STAGES)
    with threadpool_limits(limits=1, user_api="blas"):
        return run_graph(session_inputs(cfg), runner, GRAPH[: names.index(until) + 1])


def run_session(
    config: str | Path | SessionConfig,
    out_dir: str | Path,
    *,
    progress: TextIO | None = None,
    use_cache: bool = True,
    pdf: bool = False,
    _fail_stage: str | None = None,
) -> RunResult:
    """Run the whole chain for one session and write the results contract into ``out_dir``.

    ``progress`` gets one line per stage (status and seconds); ``use_cache=False`` recomputes
    every stage; ``pdf=True`` also prints ``report.pdf`` with headless Chromium (when installed).
    Raises :class:`~msk.exceptions.MskError` when a core stage fails (nothing is written then).
    """
    t_start = time.perf_counter()
    cfg = config if isinstance(config, SessionConfig) else load_config(config)
    tasks = cfg.trials_with_role("task")
    if len(tasks) > 1:
        names = ", ".join(t.name for t in tasks)
        raise ConfigError(
            f"{cfg.path}: {len(tasks)} task trials ({names}): run_session analyses one; "
            "run_task_trials (what `msk run` does) analyses each into its own folder"
        )
    out = Path(out_dir).resolve()
    check_replaceable(out)  # fail before computing, not after
    runner = Runner(
        out / ".cache" if use_cache else None, progress, stages=STAGES, core=CORE_STAGES,
        fail_stage=_fail_stage,
    )  # fmt: skip
    # one BLAS thread: the numbers do not depend on the machine's core count (OpenBLAS sums in
    # another order with 2 threads: mass identification moved by ~5e-7), and batch workers do
    # not oversubscribe the cores
    with threadpool_limits(limits=1, user_api="blas"):
        # every other stage's result is released once no later stage reads it, and its
        # arrays leave the resident set (glibc: mapped, not kept in the heap)
        map_large_blocks()
        results = run_graph(
            session_inputs(cfg),
            runner,
            keep=("tables", "summary", "report", "opensim_export", "opensim_model"),
        )
    tables, figures = results["tables"], results["report"]
    summary = dict(results["summary"])
    exports = [e for e in (results.get(n) for n in ("opensim_export", "opensim_model")) if e]
    if exports:
        summary["opensim"] = {k: v for e in exports for k, v in e.record.items()}
        summary["opensim"]["files"] = [f"opensim/{f}" for e in exports for f in e.files]
    summary["stages"] = [dataclasses.asdict(r) for r in runner.records]
    summary["not_available"] = [
        {"stage": r.name, "status": r.status, "reason": r.message}
        for r in runner.records
        if r.status in ("not available", "failed")
    ]
    summary["run_seconds"] = time.perf_counter() - t_start
    failed = [r for r in runner.records if r.status == "failed"]
    if failed:  # a stage that bad input made fail is a quality gate: --strict exits 3
        quality = summary["quality"] = dict(summary.get("quality") or {})
        quality["flags"] = [*(quality.get("flags") or ()), *(
            {"trial": str(summary.get("trial") or ""), "quantity": "stage_failed",
             "value": 1.0, "threshold": 0.0,
             "message": f"stage {r.name} failed, its results are not available: {r.message}"}
            for r in failed
        )]  # fmt: skip

    def report(res: SessionResults, folder: Path) -> None:
        from msk.report import write_report

        for export in exports:
            export.write(folder)  # opensim/: markers, GRF, ExternalLoads, model

        write_report(res, folder, figures=figures, pdf=pdf)

    angles = tuple(summary["angle_columns"])
    write_session(out, SessionResults(tables, summary, None, angles), report=report)
    if progress is not None:
        progress.write(f"wrote {out} in {time.perf_counter() - t_start:.2f} s\n")
    # the public result is typed: the summary.json just written, read back (its text
    # round-trips: Summary.from_json(text).to_json() == text)
    typed = Summary.from_json((out / "summary.json").read_text(encoding="utf-8"))
    return RunResult(out, typed, tuple(runner.records), time.perf_counter() - t_start)
