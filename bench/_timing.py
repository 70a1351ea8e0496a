"""Timing helper shared by the benchmarks (run as scripts: ``bench/`` is on ``sys.path``)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any


def best_of(fn: Callable[[], Any], repeats: int = 3, *, warmup: bool = False) -> tuple[float, Any]:
    """Best wall time (s) of ``repeats`` calls of ``fn`` and the last call's result; with
    ``warmup`` one untimed call first (imports, caches)."""
    if warmup:
        fn()
    best, out = float("inf"), None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out
