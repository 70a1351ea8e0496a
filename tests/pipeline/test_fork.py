"""msk._runtime.fork: a forked child computes exactly what the caller would, and the caller computes
it
itself when the child cannot answer."""

from __future__ import annotations

import os

import numpy as np
import pytest

from msk._runtime import fork as _fork
from msk._runtime.fork import (
    Forked,
    Server,
    defer_server,
    spare_cpu,
    start_deferred,
    start_server,
    stop_servers,
    take_server,
)


def _work(n: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(n)
    a = rng.standard_normal((50, 50))
    return {"x": np.linalg.solve(a @ a.T + np.eye(50), rng.standard_normal(50)), "pid": os.getpid()}


def _fail(_: int) -> None:
    raise ValueError("no answer")


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no os.fork")
def test_the_child_computes_what_the_caller_would():
    got = Forked(_work, 3).result()
    here = _work(3)
    np.testing.assert_array_equal(got["x"], here["x"])  # bit for bit
    assert got["pid"] != os.getpid()


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no os.fork")
def test_a_failing_child_is_computed_again_here():
    with pytest.raises(ValueError, match="no answer"):  # the caller's own error, not a pipe's
        Forked(_fail, 0).result()


def test_msk_fork_0_keeps_everything_in_the_process(monkeypatch):
    monkeypatch.setenv(_fork.ENV, "0")
    assert not spare_cpu()


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no os.fork")
def test_a_server_imports_first_and_answers_once():
    srv = Server("math", "fsum")
    assert srv.call([0.1] * 10) == 1.0
    with pytest.raises(RuntimeError):  # once
        srv.call([1.0])
    Server("math", "fsum").close()  # released unused: the child exits on its own


def test_servers_by_key(monkeypatch):
    monkeypatch.setenv(_fork.ENV, "0")  # no spare CPU: nothing is started
    start_server("k", "math", "fsum")
    assert take_server("k") is None
    stop_servers()


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no os.fork")
def test_a_deferred_server_is_forked_by_start_deferred_only(monkeypatch):
    """``msk run`` registers the figure server; the runner forks it when a stage is computed,
    so that a run whose every stage comes from the cache forks nothing."""
    monkeypatch.setattr(_fork, "spare_cpu", lambda: True)
    defer_server("k", "math", "fsum")
    assert take_server("k") is None  # registered, not forked
    start_deferred()
    srv = take_server("k")
    assert srv is not None and srv.call([0.1] * 10) == 1.0
    start_deferred()  # once
    assert take_server("k") is None
    defer_server("k", "math", "fsum")
    stop_servers()  # a registered server never started is forgotten
    start_deferred()
    assert take_server("k") is None


def test_a_cached_run_forks_no_figure_server(tmp_path, monkeypatch):
    """The runner starts the registered servers before it computes a stage, never on a hit."""
    from msk.pipeline.runner import Runner

    started: list[int] = []
    monkeypatch.setattr("msk.pipeline.runner.start_deferred", lambda: started.append(1))
    for expect in (1, 1):  # computed, then a hit: still the one start
        runner = Runner(tmp_path, None, stages=("s",), core=frozenset())
        assert runner.run("s", lambda: {"x": 1.0}, settings=1) == {"x": 1.0}
        assert len(started) == expect
