"""msk._fork: a forked child computes exactly what the caller would, and the caller computes it
itself when the child cannot answer."""

from __future__ import annotations

import os

import numpy as np
import pytest

from msk import _fork
from msk._fork import Forked, Server, spare_cpu, start_server, stop_servers, take_server


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
