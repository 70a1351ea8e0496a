"""Many sessions at once: a local process pool by default, a Dask distributed cluster on demand.

``run_batch(configs, out)`` runs :func:`msk.pipeline.run_session` for every configuration into
``out/<session>/`` (``<session>`` = the config file's stem, made unique), in parallel:

* ``scheduler=None``: local child processes, one per session, ``workers`` at a time
  (:func:`msk._runtime.isolated.run_isolated`; ``forkserver`` start method: every child is forked
  from
  a server that imported msk once, no forked solver state; ``spawn`` where there is no
  forkserver): a child killed by a signal costs only its session (run once more, then failed
  with the signal's name), one over the time limit is killed and failed, and the children's
  ``sys.path`` does not start with the current folder;
* ``scheduler="tcp://host:8786"`` (or a ``distributed.Client``): the sessions are mapped on a
  Dask distributed cluster; the workers need msk installed and the paths visible.

A failing session never stops the others: its error is kept as one line (type and message), the
others complete and are written, and :attr:`BatchResult.failed` lists it. The cohort table
``out/cohort.csv`` has one row per session (:func:`msk.results.cohort.cohort_row`,
:data:`msk.results.cohort.COHORT_COLUMNS`). Dynamometry sessions
(:mod:`msk.pipeline.dynamometry`) also give ``out/strength_cohort.csv``: one row per subject
and test (torque, N·m/kg, interval, factor, published band, status, reason), and
``out/strength_cohort_summary.csv``: one row per test over the cohort (counts, the identified
tests' median and quartiles, the band, the reasons; :mod:`msk.results.strength_table`).
"""

from __future__ import annotations

import os
import re
import time as _time
import traceback
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from msk.exceptions import BatchError, MskError
from msk.results.cohort import check_cohort_replaceable, cohort_row, write_cohort_csv

__all__ = [
    "SESSION_TIME_LIMIT_S",
    "BatchResult",
    "SessionOutcome",
    "run_batch",
    "run_one",
]


@dataclass(frozen=True)
class SessionOutcome:
    """One session of a batch: ``ok`` or the one-line ``error``; ``row`` its cohort row."""

    config: str
    out_dir: str
    ok: bool
    seconds: float
    error: str = ""
    row: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class BatchResult:
    out_dir: Path
    outcomes: tuple[SessionOutcome, ...]
    cohort_csv: Path
    seconds: float

    @property
    def failed(self) -> tuple[SessionOutcome, ...]:
        return tuple(o for o in self.outcomes if not o.ok)


def _one_line(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {' '.join(str(exc).split())}"


def _run_dynamometry(config: str, out_dir: str) -> SessionOutcome:
    """A ``kind = "dynamometry"`` session (:mod:`msk.pipeline.dynamometry`): its cohort row
    counts the tests per status word; ``row["strength_rows"]`` holds its strength table rows
    (``strength_cohort.csv``)."""
    from msk.pipeline.dynamometry import run_dynamometry, strength_rows

    t0 = _time.perf_counter()
    try:
        res = run_dynamometry(config, out_dir)
    except MskError as exc:
        dt = _time.perf_counter() - t0
        msg = _one_line(exc)
        return SessionOutcome(
            config, out_dir, False, dt, msg, cohort_row(config, None, "failed", msg, dt)
        )
    dt = _time.perf_counter() - t0
    row = cohort_row(config, None, "ok", "", dt)
    words = [(r.test, r.status) for r in res.strengths]
    row.update(
        session=res.summary["session"],
        strength_groups_identified=sum(w == "identified" for _, w in words),
        strength_groups_at_bound=0,
        strength_groups_not_determined=sum(w == "not determined" for _, w in words),
        strength_group_status="; ".join(f"{t}: {w}" for t, w in words),
        strength_rows=strength_rows(
            res.summary["session"],
            res.strengths,
            age_years=res.summary["subject"].get("age_years"),
            mass_kg=res.summary["subject"].get("mass_kg"),
        ),
    )
    return SessionOutcome(config, out_dir, True, dt, "", row)


def run_one(config: str, out_dir: str, use_cache: bool = True) -> SessionOutcome:
    """Run one session, never raising: the outcome carries the error as one line."""
    from msk.io.c3d import ISOLATE_ENV
    from msk.pipeline import run_session
    from msk.pipeline.dynamometry import is_dynamometry_config

    if is_dynamometry_config(config):
        return _run_dynamometry(config, out_dir)
    t0 = _time.perf_counter()
    # C3D files are read in a child process: a native crash of the reader costs this session
    # (one line), never the worker and with it the pool (BrokenProcessPool)
    isolate_set = ISOLATE_ENV not in os.environ
    if isolate_set:
        os.environ[ISOLATE_ENV] = "1"
    try:
        res = run_session(config, out_dir, progress=None, use_cache=use_cache)
    except MskError as exc:
        dt = _time.perf_counter() - t0
        msg = _one_line(exc)
        return SessionOutcome(
            config, out_dir, False, dt, msg, cohort_row(config, None, "failed", msg, dt)
        )
    except Exception as exc:  # a bug in one session must not take the cohort down
        dt = _time.perf_counter() - t0
        tb = traceback.extract_tb(exc.__traceback__)
        where = f" ({tb[-1].filename}:{tb[-1].lineno})" if tb else ""
        msg = _one_line(exc) + where
        return SessionOutcome(
            config, out_dir, False, dt, msg, cohort_row(config, None, "failed", msg, dt)
        )
    finally:
        if isolate_set:
            os.environ.pop(ISOLATE_ENV, None)
    dt = _time.perf_counter() - t0
    return SessionOutcome(
        config, out_dir, True, dt, "", cohort_row(config, res.summary, "ok", "", dt)
    )


def _session_dirs(configs: Sequence[str | Path], out: Path) -> list[Path]:
    seen: dict[str, int] = {}
    dirs = []
    for c in configs:
        stem = Path(c).stem
        k = seen.get(stem, 0)
        seen[stem] = k + 1
        dirs.append(out / (stem if k == 0 else f"{stem}-{k + 1}"))
    return dirs


#: a local batch's default time limit per session (s): far above any session's run (a long
#: trial takes minutes), it ends one that hangs or was stopped
SESSION_TIME_LIMIT_S = 3600.0

#: what a session imports, imported once by the forkserver the pool's workers are forked from
WORKER_PRELOAD = (
    "msk.pipeline",
    "msk.pipeline.dynamometry",
    "scipy.signal",
    "msk.personalise.scaling",
    "msk.dynamics.identification",
    "msk.strength",
    "msk.contact.knee",
    "msk.report.html",
)


def _pool_context() -> Any:
    """Start method of the local pool's workers: forked from a server process that imported
    :data:`WORKER_PRELOAD` once (``forkserver``), so that a worker starts in ~10 ms instead of
    importing numpy, scipy and Pinocchio afresh (~1 s a worker, on the CPUs the
    others are working with); like ``spawn`` (the fallback where there is no forkserver), a
    worker inherits no state from the caller, only those imports."""
    import multiprocessing as mp

    if "forkserver" not in mp.get_all_start_methods():  # pragma: no cover - Windows
        return mp.get_context("spawn")
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(list(WORKER_PRELOAD))
    return ctx


def run_batch(
    configs: Sequence[str | Path],
    out_dir: str | Path,
    *,
    scheduler: Any = None,
    workers: int | None = None,
    use_cache: bool = True,
    progress: Any = None,
    time_limit_s: float | None = None,
) -> BatchResult:
    """Run every session configuration into ``out_dir/<session>/`` (see the module docstring).

    Locally each session runs in a child process of its own
    (:func:`msk._runtime.isolated.run_isolated`):
    a worker killed by a signal (a native crash, the OOM killer) costs only its session, which
    is run once more and then reported failed with the signal; a session running longer than
    ``time_limit_s`` (default :data:`SESSION_TIME_LIMIT_S`; hung, or stopped) is killed and
    reported failed at the time limit. ``cohort.csv`` is always written, one row per session."""
    t0 = _time.perf_counter()
    if not configs:
        raise BatchError("no session configurations given")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)):
        raise BatchError(f"workers = {workers!r} should be an integer ≥ 1")
    if workers is not None and workers < 1:
        raise BatchError(f"workers = {workers} should be ≥ 1 (local pool size)")
    limit = SESSION_TIME_LIMIT_S if time_limit_s is None else time_limit_s
    if isinstance(limit, bool) or not isinstance(limit, (int, float)) or not limit > 0:
        raise BatchError(f"time limit = {time_limit_s!r} should be a number of seconds > 0")
    if isinstance(scheduler, str) and not re.fullmatch(
        r"(tcp|tls|inproc|ucx|ws|wss)://[^\s/]+(:\d{1,5})?/?", scheduler
    ):
        raise BatchError(
            f"--scheduler {scheduler!r} is not a Dask scheduler address (tcp://host:8786)"
        )
    out = Path(out_dir).resolve()
    out.mkdir(parents=True, exist_ok=True)
    check_cohort_replaceable(out / "cohort.csv")  # before hours of work, not after
    cfgs = [str(Path(c).resolve()) for c in configs]
    dirs = [str(d) for d in _session_dirs(cfgs, out)]
    done: dict[int, SessionOutcome] = {}

    def collect(k: int, fut: Any) -> None:
        """Session ``k``'s outcome from its finished future (a dead or lost worker: failed)."""
        try:
            o = fut.result()
        except Exception as exc:  # worker died or was lost
            msg = _one_line(exc)
            o = SessionOutcome(
                cfgs[k], dirs[k], False, 0.0, msg, cohort_row(cfgs[k], None, "failed", msg, 0.0)
            )
        done[k] = o
        if progress is None:
            return
        if o.ok:
            progress.write(f"ok      {Path(o.config).name} → {o.out_dir} ({o.seconds:.1f} s)\n")
        else:
            progress.write(f"FAILED  {Path(o.config).name}: {o.error}\n")
        progress.flush()

    if scheduler is None:
        from msk._runtime.isolated import JobFailure, run_isolated

        n = workers or min(len(cfgs), os.cpu_count() or 1) or 1
        # worker BLAS threads sleep between calls instead of spinning on the CPUs the other
        # workers need (same thread count, same results; see msk.cli), set before they start
        os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "4")

        class _Done:  # collect()'s view of a finished job
            def __init__(self, value: Any) -> None:
                self.value = value

            def result(self) -> Any:
                if isinstance(self.value, JobFailure):
                    raise BatchError(self.value.reason)
                return self.value

        run_isolated(
            run_one,
            [(c, d, use_cache) for c, d in zip(cfgs, dirs)],
            context=_pool_context(),
            workers=n,
            time_limit_s=float(limit),
            on_done=lambda k, v: collect(k, _Done(v)),
        )
    else:
        try:
            from distributed import Client
            from distributed import as_completed as dask_as_completed
        except ImportError:
            raise BatchError(
                "--scheduler needs Dask distributed: pip install 'msk[dask]'"
            ) from None
        try:
            client = scheduler if isinstance(scheduler, Client) else Client(scheduler, timeout=20)
        except (OSError, ValueError, TypeError) as exc:
            raise BatchError(f"Dask scheduler {scheduler!r} unreachable: {exc}") from None
        try:
            dask_futs = client.map(run_one, cfgs, dirs, [use_cache] * len(cfgs), pure=False)
            index = {f.key: k for k, f in enumerate(dask_futs)}
            for df in dask_as_completed(dask_futs):
                collect(index[df.key], df)
        finally:
            if client is not scheduler:
                client.close()
    outcomes = [done[k] for k in range(len(cfgs))]
    cohort = write_cohort_csv(out / "cohort.csv", [o.row for o in outcomes])
    per_test = [r for o in outcomes for r in o.row.get("strength_rows", ())]
    if per_test:
        from msk.pipeline.dynamometry import write_strength_csv
        from msk.results.strength_table import cohort_summary_rows, write_summary_csv

        write_strength_csv(out / "strength_cohort.csv", per_test)
        write_summary_csv(out / "strength_cohort_summary.csv", cohort_summary_rows(per_test))
    return BatchResult(out, tuple(outcomes), cohort, _time.perf_counter() - t0)
