"""The order in which pytest-xdist workers run the tests (``tests/conftest.py``): longest
files first in each worker's queue, from the durations recorded in ``tests/durations.json``."""

from __future__ import annotations

from collections import defaultdict

__all__ = ["worker_order"]


def worker_order(nodeids: list[str], seconds: list[float], n_workers: int) -> list[int]:
    """The order (indices into ``nodeids``) in which to hand the tests to ``n_workers``
    pytest-xdist workers under ``--dist worksteal``, given each test's expected ``seconds``.

    Worksteal hands the first ``⌊n/k⌋`` tests of the list to the first worker, the next share to
    the next, and lets an idle worker take the second half of a busy worker's queue. The tests
    of one file stay together (a module fixture or a shared session result is computed once per
    worker) and files are dealt to ``k`` bins, longest first, each to the bin with the least
    time so far (longest-processing-time rule); each bin runs its longest file first, so no long
    test is left at the end of a queue for one worker while the others idle, and what is stolen
    is the short tail. A bin with more tests than its share comes first: its spilled tail (short
    tests) starts the next worker, never the other way round."""
    files: dict[str, list[int]] = defaultdict(list)
    for i, nid in enumerate(nodeids):
        files[nid.split("::", 1)[0]].append(i)
    weight = {f: sum(seconds[i] for i in ix) for f, ix in files.items()}
    k = max(1, n_workers)
    bins: list[list[str]] = [[] for _ in range(k)]
    load = [0.0] * k
    for f in sorted(files, key=lambda f: (-weight[f], f)):
        b = min(range(k), key=lambda j: (load[j], j))
        bins[b].append(f)
        load[b] += weight[f]
    bins.sort(key=lambda b: -sum(len(files[f]) for f in b))
    return [i for b in bins for f in b for i in files[f]]
