"""tests/support/schedule.py: the order of the pytest-xdist queues (tests/conftest.py)."""

from __future__ import annotations

import json
import re
from pathlib import Path

from tests.support.schedule import worker_order


def _split(order: list[int], n_workers: int) -> list[list[int]]:
    """The queues worksteal deals out first: ⌊remaining / workers left⌋ tests each, in order."""
    queues, rest = [], list(order)
    for k in range(n_workers, 0, -1):
        take = len(rest) // k
        queues.append(rest[:take])
        rest = rest[take:]
    return queues


def test_each_worker_starts_with_a_long_file_and_files_stay_together() -> None:
    ids = (
        [f"a.py::t{i}" for i in range(4)]
        + [f"b.py::t{i}" for i in range(40)]
        + ["c.py::big"]
        + [f"d.py::t{i}" for i in range(3)]
    )
    seconds = [0.1] * len(ids)
    seconds[0] = seconds[1] = 100.0  # a.py: 200 s
    seconds[ids.index("c.py::big")] = 300.0
    seconds[ids.index("d.py::t0")] = 150.0
    order = worker_order(ids, seconds, 2)
    assert sorted(order) == list(range(len(ids)))  # every test once
    files = [ids[i].split("::")[0] for i in order]
    # each file in one run of the list (a module fixture is computed once per worker)
    assert len([f for k, f in enumerate(files) if k == 0 or files[k - 1] != f]) == 4
    # within a file pytest's order is kept
    assert [ids[i] for i in order if ids[i].startswith("b.py")] == ids[4:44]
    first, second = _split(order, 2)
    # the longest file starts one queue, the next longest files the other (after at most the
    # short tests spilled from the first bin); the long tests are never at a queue's end
    assert ids[first[0]] == "c.py::big"
    long_tests = {"a.py::t0", "a.py::t1", "d.py::t0"}
    assert long_tests <= {ids[i] for i in second}
    assert seconds[first[-1]] < 1.0 and seconds[second[-1]] < 1.0


def test_one_worker_keeps_every_file_whole() -> None:
    ids = ["x.py::a", "y.py::a", "x.py::b"]
    order = worker_order(ids, [1.0, 5.0, 1.0], 1)
    assert [ids[i] for i in order] == ["y.py::a", "x.py::a", "x.py::b"]


def test_every_recorded_duration_names_a_test_of_its_file() -> None:
    """A key of tests/durations.json whose test was renamed orders nothing: the renamed test
    counts as an unknown one (5 s when slow) and may be queued last. Every key names a test
    function defined in its file (a parametrised id by its function)."""
    root = Path(__file__).resolve().parents[1]
    table = json.loads((root / "tests" / "durations.json").read_text(encoding="utf-8"))
    stale = []
    for nodeid in table["seconds"]:
        path, _, name = nodeid.partition("::")
        func = name.split("[", 1)[0].split("::")[-1]
        source = root / path
        text = source.read_text(encoding="utf-8") if source.is_file() else ""
        if not re.search(rf"^\s*def {re.escape(func)}\(", text, flags=re.M):
            stale.append(nodeid)
    assert not stale, stale
