"""Half of a job in a forked child while the caller does the other half (a second free CPU).

Used where one session spends most of its wall time in independent pieces of pure Python or
GIL-holding native work: threads would not run them side by side, a forked child does, with
the parent's imports and data already in place (~10 ms to fork).
Nothing changes in the results: the child computes exactly what the caller would have (same
code, same data, same BLAS thread count), pickles it into a pipe, and the caller falls back to
computing it itself if the child fails in any way.

:func:`spare_cpu` decides (also for GIL-releasing work run on two threads, such as the folds
of the mass-identification cross-validation): only in the main thread of a top-level process
(never inside a batch worker, whose siblings use the other CPUs), with at least two CPUs in
its affinity mask, where ``os.fork`` exists, and unless ``MSK_FORK=0``.

A :class:`Server` is a child forked early that imports a module on the free CPU while the
caller works, then computes one function of that module for it: the caller pays neither the
import nor the computation beyond its wait. A command registers it with :func:`defer_server`
and the stage runner forks it (:func:`start_deferred`) when it first computes a stage: a run
whose stages all come from the cache forks no child, whose import would only take CPU from it.
"""

from __future__ import annotations

import importlib
import os
import pickle
from collections.abc import Callable
from typing import Any, Generic, TypeVar

__all__ = [
    "ENV",
    "Forked",
    "Server",
    "defer_server",
    "spare_cpu",
    "start_deferred",
    "start_server",
    "stop_servers",
    "take_server",
]

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


class Server:
    """A child forked now that imports ``module`` meanwhile (and calls ``module.warm()`` if
    given) and, when :meth:`call` sends it arguments, returns ``module.function(*args)``
    (once). Its standard streams are ``/dev/null``: it holds no pipe of the caller's open."""

    def __init__(self, module: str, function: str, warm: str | None = None) -> None:
        self._pid = -1
        req_r, req_w = os.pipe()
        ans_r, ans_w = os.pipe()
        try:
            pid = os.fork()
        except OSError:
            for fd in (req_r, req_w, ans_r, ans_w):
                os.close(fd)
            return
        if pid == 0:  # pragma: no cover - the child (coverage does not follow os.fork)
            try:
                os.close(req_w)
                os.close(ans_r)
                null = os.open(os.devnull, os.O_RDWR)
                for fd in (0, 1, 2):
                    os.dup2(null, fd)
                _SERVERS.clear()
                mod = importlib.import_module(module)
                fn = getattr(mod, function)
                if warm is not None:
                    getattr(mod, warm)()
                with os.fdopen(req_r, "rb") as fh:
                    request = fh.read()
                if request:
                    answer = pickle.dumps(fn(*pickle.loads(request)), pickle.HIGHEST_PROTOCOL)
                    with os.fdopen(ans_w, "wb") as fh:
                        fh.write(answer)
            finally:
                os._exit(0)
        os.close(req_r)
        os.close(ans_w)
        self._pid, self._req, self._ans = pid, req_w, ans_r

    def call(self, *args: Any) -> Any:
        """``module.function(*args)`` computed by the child; :class:`RuntimeError` if it cannot
        (the caller computes it itself)."""
        if self._pid < 0:
            raise RuntimeError("no server")
        pid, self._pid = self._pid, -1
        try:
            with os.fdopen(self._req, "wb") as fh:
                fh.write(pickle.dumps(args, pickle.HIGHEST_PROTOCOL))
            with os.fdopen(self._ans, "rb") as fh:
                data = fh.read()
        except OSError as exc:
            raise RuntimeError(f"server: {exc}") from None
        finally:
            os.waitpid(pid, 0)
        if not data:
            raise RuntimeError("server: no answer")
        return pickle.loads(data)

    def close(self) -> None:
        """Let the child go without a request (it exits when its import is done)."""
        if self._pid < 0:
            return
        self._pid = -1
        os.close(self._req)
        os.close(self._ans)


_SERVERS: dict[str, Server] = {}
_DEFERRED: dict[str, tuple[str, str, str | None]] = {}


def start_server(key: str, module: str, function: str, warm: str | None = None) -> None:
    """Fork a :class:`Server` for ``module.function`` under ``key`` when a CPU is spare."""
    if key not in _SERVERS and spare_cpu():
        _SERVERS[key] = Server(module, function, warm)


def defer_server(key: str, module: str, function: str, warm: str | None = None) -> None:
    """Register a :class:`Server` for ``module.function`` under ``key``, forked by the next
    :func:`start_deferred` (never, if nothing calls it before :func:`stop_servers`)."""
    _DEFERRED[key] = (module, function, warm)


def start_deferred() -> None:
    """Fork the servers registered by :func:`defer_server` (:func:`start_server`; once)."""
    while _DEFERRED:
        key, (module, function, warm) = _DEFERRED.popitem()
        start_server(key, module, function, warm)


def take_server(key: str) -> Server | None:
    """The server started under ``key`` (once; ``None`` if there is none)."""
    return _SERVERS.pop(key, None)


def stop_servers() -> None:
    """Release every server not used (and forget the ones not started)."""
    _DEFERRED.clear()
    while _SERVERS:
        _SERVERS.popitem()[1].close()
