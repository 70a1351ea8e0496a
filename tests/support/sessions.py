"""Pipeline results computed once per configuration and shared, read-only, by every test that
reads them (``run_stages`` of a shipped config takes seconds to minutes; a dozen tests read the
same gc5_PS stages, four the same gc5_PS results folder).

:func:`session` returns ``run_task_trials(config, out)[0]`` of a shipped configuration, its
folder written once per process in a temporary folder removed at exit; tests read it and never
write into it.

:func:`stages` returns the nodes up to ``until`` of ``run_stages(config, until=...)``; the
results of a configuration are computed once per process (one pytest-xdist worker), to the
deepest node asked so far: a later call for an earlier node takes its part of them. Every array
in them is made read-only, so a test that would change a shared result fails loudly instead of
changing what the next test reads (a test that needs to write takes a copy). With
pytest-xdist each worker has its own cache: a result is computed at most once per worker (the
tests sharing one are kept in one file where they can be). (``xdist_group`` with
``--dist loadgroup`` would send them to one worker, but pytest-xdist 3.8 does not group under
pytest 9: it renames ``Item._nodeid``, which pytest 9 no longer reads.)

The results are those of the library's defaults: :func:`stages` refuses to run while a test has
one of the block sizes in :data:`KNOBS` monkeypatched (ask before patching), unless the block
size is asked for through ``frame_block``.
"""

from __future__ import annotations

import atexit
import dataclasses
import importlib
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from msk._runtime import blocks
from msk.config import load_config
from msk.pipeline import GRAPH, run_stages, run_task_trials
from msk.pipeline.runner import RunResult

__all__ = ["KNOBS", "REPO", "session", "stages"]

REPO = Path(__file__).resolve().parents[2]

#: the module attributes tests monkeypatch to run a stage in other block sizes (module → name)
KNOBS: tuple[tuple[str, str], ...] = (
    ("msk._runtime.blocks", "FRAME_BLOCK"),
    ("msk._runtime.blocks", "SOLVE_BLOCK"),
    ("msk.optimization.problems", "_BLOCK_CHUNK"),
    ("msk.optimization.muscle_forces", "GAIN_FIT_FRAMES"),
    ("msk.dynamics.loads", "_POINT_BLOCK"),
    ("msk.dynamics.inverse", "ID_BLOCK"),
    ("msk.io.frames", "HEADING_BLOCK"),
)


def _knob_values() -> dict[tuple[str, str], Any]:
    return {(m, a): getattr(importlib.import_module(m), a) for m, a in KNOBS}


_DEFAULTS = _knob_values()
_NAMES = [n.name for n in GRAPH]
#: (config path, frame block) → (index of the deepest node computed, its results)
_CACHE: dict[tuple[Path, int], tuple[int, dict[str, Any]]] = {}


def _freeze(x: Any, seen: set[int]) -> None:
    """Make every numpy array reachable through dataclasses, mappings and sequences
    read-only."""
    if id(x) in seen:
        return
    seen.add(id(x))
    if isinstance(x, np.ndarray):
        x.flags.writeable = False
    elif dataclasses.is_dataclass(x) and not isinstance(x, type):
        for f in dataclasses.fields(x):
            _freeze(getattr(x, f.name, None), seen)
    elif isinstance(x, Mapping):
        for v in x.values():
            _freeze(v, seen)
    elif isinstance(x, (list, tuple)):
        for v in x:
            _freeze(v, seen)


def _path(config: str | Path) -> Path:
    path = Path(config)
    if not path.is_absolute():
        path = REPO / "pipelines" / path
    return path.resolve()


def stages(config: str | Path, until: str, *, frame_block: int | None = None) -> Mapping[str, Any]:
    """``run_stages(config, until=until)`` of the shipped configuration ``config`` (a path, or
    a name in ``pipelines/``), computed once per process and shared read-only (module
    docstring); ``frame_block``: the stages run with ``msk._runtime.blocks.FRAME_BLOCK`` set to
    it (a separate result)."""
    path = _path(config)
    changed = {k: v for k, v in _knob_values().items() if v != _DEFAULTS[k]}
    if changed:
        raise RuntimeError(
            f"tests.support.sessions.stages called with {changed} monkeypatched: its results "
            "are the defaults' (ask for them before patching; frame_block= for FRAME_BLOCK)"
        )
    block = blocks.FRAME_BLOCK if frame_block is None else frame_block
    depth = _NAMES.index(until)
    key = (path, block)
    if key not in _CACHE or _CACHE[key][0] < depth:
        _CACHE[key] = (depth, _compute(path, until, block))
    results = _CACHE[key][1]
    return MappingProxyType({n: results[n] for n in _NAMES[: depth + 1]})


def _compute(path: Path, until: str, block: int) -> dict[str, Any]:
    default = blocks.FRAME_BLOCK
    blocks.FRAME_BLOCK = block
    try:
        results = run_stages(load_config(path), until=until)
    finally:
        blocks.FRAME_BLOCK = default
    _freeze(results, set())
    return results


_RUNS: dict[Path, RunResult] = {}


def session(config: str | Path) -> RunResult:
    """``run_task_trials(config, out)[0]`` of the shipped configuration ``config`` (a path, or a
    name in ``pipelines/``) with one task trial: its results folder written once per process
    and shared (module docstring); a test reads ``out_dir`` and never writes into it."""
    path = _path(config)
    if path not in _RUNS:
        changed = {k: v for k, v in _knob_values().items() if v != _DEFAULTS[k]}
        if changed:
            raise RuntimeError(f"tests.support.sessions.session called with {changed} patched")
        top = Path(tempfile.mkdtemp(prefix=f"msk-test-{path.stem}-"))
        atexit.register(shutil.rmtree, top, ignore_errors=True)
        (res,) = run_task_trials(path, top / path.stem)
        _RUNS[path] = res
    return _RUNS[path]
