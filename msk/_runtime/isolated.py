"""Run jobs each in its own child process: a worker that dies or hangs costs only its job.

A :class:`concurrent.futures.ProcessPoolExecutor` breaks as a whole when one worker dies (a
native crash, the OOM killer: ``BrokenProcessPool`` fails every pending job) and waits for ever
on a hung one. :func:`run_isolated` instead starts one child per job (``workers`` at a time),
from the given multiprocessing context (a ``forkserver`` whose server imported the heavy
modules once: a child starts in milliseconds), and for each job:

* its value, sent back through a pipe, when it returns;
* when the child dies without one (killed by a signal, ``os._exit``): it is run again up to
  ``retries`` times, then reported as failed with the signal's name;
* when it runs longer than ``time_limit_s`` (hung, or stopped by SIGSTOP): its whole process
  group (the child leads one: its own children go with it) is killed with SIGKILL — before the
  child is waited for, so the group id is still the child's own — and it is reported as failed
  at the time limit.

The children's ``sys.path`` does not start with the current folder (:func:`clean_sys_path`):
a ``concurrent.py`` or ``numpy.py`` in the folder ``msk batch`` is run from is never imported
in place of the library.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

__all__ = ["JobFailure", "clean_sys_path", "run_isolated", "sys_path_for_children"]


@dataclass(frozen=True)
class JobFailure:
    """Job ``index`` gave no value: ``reason`` (one line), after ``attempts`` runs."""

    index: int
    reason: str
    attempts: int


def clean_sys_path(path: Sequence[str], *, keep: Sequence[str] = ()) -> list[str]:
    """``path`` without the current folder (``""``, ``"."`` or the working directory itself)
    unless it is one of ``keep`` (where the library itself is imported from)."""
    cwd = os.path.realpath(os.getcwd())
    kept = {os.path.realpath(k) for k in keep}
    out = []
    for p in path:
        real = os.path.realpath(p or ".")
        if real == cwd and real not in kept:
            continue
        out.append(p)
    return out


@contextlib.contextmanager
def sys_path_for_children() -> Iterator[None]:
    """``sys.path`` as children started inside the block inherit it (:func:`clean_sys_path`,
    keeping the folder the ``msk`` package is imported from)."""
    import msk

    root = str(Path(msk.__file__).resolve().parent.parent)
    saved = list(sys.path)
    sys.path[:] = clean_sys_path(saved, keep=[root])
    try:
        yield
    finally:
        sys.path[:] = saved


def _child(conn: Connection, fn: Callable[..., Any], args: tuple[Any, ...]) -> None:
    """The child's body: lead a process group of its own, run ``fn(*args)``, send the value."""
    with contextlib.suppress(OSError):
        os.setpgid(0, 0)
    try:
        value = fn(*args)
    except BaseException as exc:  # reported by the parent as this job's failure
        conn.send(("error", f"{type(exc).__name__}: {' '.join(str(exc).split())}"))
    else:
        conn.send(("ok", value))
    conn.close()


def _signal_name(code: int | None) -> str:
    if code is None:
        return "no exit code"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exited with status {code} without a result"


def _kill_group(pid: int | None) -> None:
    if pid is None:
        return
    for kill in (lambda: os.killpg(pid, signal.SIGKILL), lambda: os.kill(pid, signal.SIGKILL)):
        with contextlib.suppress(ProcessLookupError, PermissionError, OSError):
            kill()


@dataclass
class _Running:
    index: int
    attempt: int
    proc: Any
    conn: Connection
    start: float


def run_isolated(
    fn: Callable[..., Any],
    jobs: Sequence[tuple[Any, ...]],
    *,
    context: Any,
    workers: int,
    time_limit_s: float,
    retries: int = 1,
    on_done: Callable[[int, Any], None] | None = None,
    poll_s: float = 0.5,
) -> list[Any]:
    """``fn(*jobs[k])`` for every ``k``, each in its own child of ``context``; returns, in job
    order, each value or a :class:`JobFailure` (see the module docstring). ``on_done(k,
    value_or_failure)`` is called as each job ends."""
    if workers < 1:
        raise ValueError(f"workers must be ≥ 1, got {workers}")
    results: dict[int, Any] = {}
    pending = [(k, 1) for k in range(len(jobs))]
    running: list[_Running] = []

    def finish(k: int, value: Any) -> None:
        results[k] = value
        if on_done is not None:
            on_done(k, value)

    def start(k: int, attempt: int) -> None:
        recv, send = context.Pipe(duplex=False)
        proc = context.Process(target=_child, args=(send, fn, tuple(jobs[k])), daemon=True)
        with sys_path_for_children():
            proc.start()
        send.close()
        running.append(_Running(k, attempt, proc, recv, time.monotonic()))

    def reap(r: _Running, *, kill: bool = False) -> None:
        if kill:  # before any wait: the child is not reaped, its pid is still its own
            _kill_group(r.proc.pid)
        r.proc.join(timeout=5)
        if r.proc.is_alive():
            r.proc.kill()
            r.proc.join(timeout=5)
        r.conn.close()
        running.remove(r)

    try:
        while pending or running:
            while pending and len(running) < workers:
                start(*pending.pop(0))
            now = time.monotonic()
            deadline = min(r.start + time_limit_s for r in running)
            ready = wait(
                [r.conn for r in running] + [r.proc.sentinel for r in running],
                timeout=max(0.0, min(poll_s, deadline - now)),
            )
            for r in list(running):
                if r.conn in ready or r.proc.sentinel in ready:
                    try:
                        status, value = r.conn.recv() if r.conn.poll() else (None, None)
                    except (EOFError, OSError):
                        status, value = None, None
                    if status is None and r.proc.is_alive():
                        continue  # the pipe woke but nothing came yet
                    reap(r)
                    if status == "ok":
                        finish(r.index, value)
                    elif status == "error":
                        finish(r.index, JobFailure(r.index, str(value), r.attempt))
                    elif r.attempt <= retries:
                        pending.insert(0, (r.index, r.attempt + 1))
                    else:
                        why = _signal_name(r.proc.exitcode)
                        times = f" ({r.attempt} attempts)" if r.attempt > 1 else ""
                        finish(r.index, JobFailure(r.index, f"worker {why}{times}", r.attempt))
                elif time.monotonic() - r.start > time_limit_s:
                    reap(r, kill=True)  # its process group: the job's own children too
                    finish(
                        r.index,
                        JobFailure(
                            r.index,
                            f"time limit of {time_limit_s:g} s exceeded (hung or stopped): killed",
                            r.attempt,
                        ),
                    )
    finally:
        for r in list(running):  # interrupted (Ctrl-C): no orphan is left running
            with contextlib.suppress(Exception):
                reap(r, kill=True)
    return [results[k] for k in range(len(jobs))]
