"""Half of a job in a forked child while the caller does the other half (a second free CPU).

Used where one session spends most of its wall time in independent pieces of pure Python or
GIL-holding native work (the report's figures, the folds of the mass-identification
cross-validation): threads would not run them side by side, a forked child does, with the
parent's imports and data already in place (~10 ms to fork). Nothing changes in the results:
the child computes exactly what the caller would have (same code, same data, same BLAS thread
count), pickles it into a pipe, and the caller falls back to computing it itself if the child
fails in any way.

:func:`spare_cpu` decides: only in the main thread of a top-level process (never inside a batch
worker, whose siblings use the other CPUs), with at least two CPUs in its affinity mask, where
``os.fork`` exists, and unless ``MSK_FORK=0``.
"""

from __future__ import annotations

import os
import pickle
from collections.abc import Callable
from typing import Any, Generic, TypeVar

__all__ = ["ENV", "Forked", "spare_cpu"]

#: environment switch: ``MSK_FORK=0`` computes everything in the calling process
ENV = "MSK_FORK"
T = TypeVar("T")


def spare_cpu() -> bool:
    """Whether a forked child may take a second CPU (see the module docstring)."""
    import multiprocessing as mp
    import threading

    if os.environ.get(ENV, "") == "0" or not hasattr(os, "fork"):
        return False
    if mp.parent_process() is not None or threading.current_thread() is not threading.main_thread():
        return False
    try:
        return len(os.sched_getaffinity(0)) >= 2
    except AttributeError:  # pragma: no cover - no sched_getaffinity
        return (os.cpu_count() or 1) >= 2


class Forked(Generic[T]):
    """``fn(*args)`` computed in a forked child; :meth:`result` collects it (or, if the child
    could not be forked or failed, computes it in the caller)."""

    def __init__(self, fn: Callable[..., T], *args: Any) -> None:
        self._fn, self._args = fn, args
        self._pid = -1
        self._fd = -1
        try:
            r, w = os.pipe()
        except OSError:
            return
        try:
            pid = os.fork()
        except OSError:
            os.close(r)
            os.close(w)
            return
        if pid == 0:  # pragma: no cover - the child (coverage does not follow os.fork)
            code = 1
            try:
                os.close(r)
                data = pickle.dumps(fn(*args), protocol=pickle.HIGHEST_PROTOCOL)
                with os.fdopen(w, "wb") as fh:
                    fh.write(data)
                code = 0
            finally:
                os._exit(code)
        os.close(w)
        self._pid, self._fd = pid, r

    def result(self) -> T:
        if self._pid < 0:
            return self._fn(*self._args)
        with os.fdopen(self._fd, "rb") as fh:
            data = fh.read()
        _, status = os.waitpid(self._pid, 0)
        self._pid = -1
        if status == 0 and data:
            try:
                return pickle.loads(data)
            except Exception:  # a truncated answer: computed here instead
                pass
        return self._fn(*self._args)
