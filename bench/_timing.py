"""Timing helper shared by the benchmarks (run as scripts: ``bench/`` is on ``sys.path``)."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
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


def replace_doc_section(path: Path, heading: str, section: str) -> None:
    """Write ``section`` (starting with its ``heading`` line) into the Markdown file ``path``
    in place of the section with that heading (up to the next ``## ``), or at its end;
    atomically."""
    old = path.read_text(encoding="utf-8") if path.exists() else ""
    if heading in old:
        head, rest = old.split(heading, 1)
        nxt = rest.find("\n## ")
        new = head + section + (rest[nxt:] if nxt >= 0 else "")
    else:
        new = old.rstrip("\n") + "\n\n" + section
    tmp = path.with_suffix(".md.tmp")
    tmp.write_text(new, encoding="utf-8")
    tmp.replace(path)
