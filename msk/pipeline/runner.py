"""The stage runner: content-hash cache, status records, progress lines.

:class:`Runner` runs the nodes of :data:`msk.pipeline.graph.GRAPH` in their declared order. A
node's cache key is the sha256 of its name, :func:`msk._runtime.cache.code_fingerprint` (the source
of
msk and the versions of its numerical dependencies), its settings and the keys of the nodes it
reads, so a changed setting recomputes exactly the stages downstream of it. Values are stored
by :class:`msk._runtime.cache.StageCache` (``.npz`` + JSON, checksummed, never pickled).

Status of a recorded stage: ``computed`` / ``cached`` / ``not requested`` (the configuration
has no trial for it) / ``not available`` (a prerequisite or library piece is missing, recorded
with the reason) / ``failed`` (an analysis stage raised: recorded with its message and, for an
internal error, the code location; the run goes on). Errors of the core stages, and every
:class:`~msk.exceptions.ConfigError`, end the run.
"""

from __future__ import annotations

import hashlib
import json
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from msk import __version__
from msk._runtime.cache import StageCache, code_fingerprint, dependency_versions
from msk._runtime.fork import start_deferred
from msk.exceptions import ConfigError, MskError, NotAvailableError
from msk.results.folder import json_default
from msk.results.summary import Summary

__all__ = [
    "RunResult",
    "Runner",
    "StageRecord",
    "StageUnavailable",
    "file_sha256",
    "stage_key",
    "versions",
]


@dataclass(frozen=True)
class StageRecord:
    """What happened to one stage: ``status`` computed | cached | not requested |
    not available | failed."""

    name: str
    status: str
    seconds: float
    message: str = ""
    key: str = ""


@dataclass(frozen=True)
class RunResult:
    """A finished run: the session folder, its summary (:class:`msk.results.summary.Summary`, read
    back from the ``summary.json`` the run wrote: the typed value of exactly that file) and the
    stage records."""

    out_dir: Path
    summary: Summary
    stages: tuple[StageRecord, ...]
    seconds: float

    @property
    def not_available(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.stages if s.status in ("not available", "failed"))


class StageUnavailable(Exception):
    """A stage cannot run (missing library piece or prerequisite): recorded, not an error."""


def file_sha256(path: str | Path) -> str:
    """sha256 of a file's bytes (read in 1 MiB blocks)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def stage_key(*parts: Any) -> str:
    """sha256 of the JSON text of ``parts`` (numpy values through :func:`json_default`)."""
    text = json.dumps(parts, sort_keys=True, default=json_default)
    return hashlib.sha256(text.encode()).hexdigest()


def versions() -> dict[str, str]:
    """msk, Python and the numerical dependencies
    (:func:`msk._runtime.cache.dependency_versions`)."""
    return {"msk": __version__, **dependency_versions()}


class Runner:
    """Runs stages with the cache, records their status and writes progress lines.

    ``stages`` are the recorded stage names in order (progress ``[k/n]``); ``core`` those whose
    errors end the run; ``fail_stage`` makes the named stage raise (a test hook)."""

    def __init__(
        self,
        cache_dir: Path | None,
        progress: TextIO | None,
        *,
        stages: tuple[str, ...],
        core: frozenset[str],
        fail_stage: str | None = None,
    ) -> None:
        self.cache = StageCache(cache_dir) if cache_dir is not None else None
        self.progress = progress
        self.stages = stages
        self.core = core
        self.fail_stage = fail_stage
        self.records: list[StageRecord] = []
        self.keys: dict[str, str] = {}

    def _record(self, rec: StageRecord) -> None:
        self.records.append(rec)
        if self.progress is None:
            return
        k = self.stages.index(rec.name) + 1 if rec.name in self.stages else 0
        msg = f" — {rec.message}" if rec.message and rec.status != "computed" else ""
        self.progress.write(
            f"[{k:2d}/{len(self.stages)}] {rec.name:<24} {rec.seconds:7.2f} s  {rec.status}{msg}\n"
        )
        self.progress.flush()

    def skip(self, name: str, reason: str) -> None:
        """Record a stage the configuration does not ask for (not an error)."""
        self._record(StageRecord(name, "not requested", 0.0, reason))

    def derive(
        self,
        name: str,
        fn: Any,
        inputs: tuple[str, ...],
        *,
        settings: Any = None,
        cache: bool = False,
    ) -> Any:
        """An unrecorded step (formatting of upstream results): its key is the hash of the
        keys it reads, so that nodes downstream of it have one. With ``cache`` its value is
        kept in the stage cache like a stage's (key: also the code fingerprint and
        ``settings``), without a status record."""
        upstream = [self.keys.get(n) for n in inputs]
        if not cache:
            self.keys[name] = stage_key(name, upstream)
            return fn()
        key = self.keys[name] = stage_key(name, code_fingerprint(), settings, upstream)
        if self.cache is not None:
            hit, value = self.cache.load(name, key)
            if hit:
                return value
        value = fn()
        if self.cache is not None:
            self.cache.save(name, key, value)
        return value

    def run(
        self,
        name: str,
        fn: Any,
        *,
        needs: tuple[str, ...] = (),
        reads: tuple[str, ...] = (),
        settings: Any = None,
        cache: bool = True,
        to_cache: Callable[[Any], Any] | None = None,
        from_cache: Callable[[Any], Any] | None = None,
    ) -> Any:
        """Run ``fn()`` as stage ``name``: not available when a stage of ``needs`` is missing;
        the key holds the keys of ``needs`` and of the optional ``reads`` that ran. ``to_cache``
        and ``from_cache`` (optional, together): the value's form in the cache and back — the
        cache keeps ``to_cache(value)``, a hit gives ``from_cache`` of what it kept."""
        t0 = time.perf_counter()
        missing = [n for n in needs if n not in self.keys]
        if missing:
            self._record(StageRecord(name, "not available", 0.0, f"needs {', '.join(missing)}"))
            return None
        upstream = [self.keys[n] for n in needs] + [self.keys.get(n) for n in reads]
        key = stage_key(name, code_fingerprint(), settings, upstream)
        store = self.cache if cache else None
        if store is not None:
            hit, value = store.load(name, key)
            if hit and from_cache is not None:
                try:
                    value = from_cache(value)
                except Exception:  # an entry that does not make a value: computed again
                    hit, value = False, None
            if hit:
                self.keys[name] = key
                self._record(StageRecord(name, "cached", time.perf_counter() - t0, "", key))
                return value
        start_deferred()  # a stage is computed: the servers msk run registered (msk._runtime.fork)
        try:
            if self.fail_stage == name:
                raise RuntimeError(f"stage {name} failed on purpose (test hook)")
            value = fn()
        except (StageUnavailable, NotAvailableError) as exc:
            self._record(
                StageRecord(name, "not available", time.perf_counter() - t0, str(exc), key)
            )
            return None
        except MskError as exc:
            # a configuration error is the user's to fix: the run ends with one line and a
            # non-zero exit, whatever the stage (an EMG channel typo is not a "failed stage")
            if name in self.core or isinstance(exc, ConfigError):
                raise
            msg = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
            self._record(StageRecord(name, "failed", time.perf_counter() - t0, msg, key))
            return None
        except Exception as exc:
            # a bug in an analysis module must not cost the session its other results: the
            # stage is recorded as failed, with the error and where it happened
            if name in self.core:
                raise
            tb = traceback.extract_tb(exc.__traceback__)
            where = f" ({Path(tb[-1].filename).name}:{tb[-1].lineno})" if tb else ""
            msg = f"internal error: {type(exc).__name__}: {' '.join(str(exc).split())}{where}"
            self._record(StageRecord(name, "failed", time.perf_counter() - t0, msg, key))
            return None
        note = ""
        if store is not None and not store.save(
            name, key, value if to_cache is None else to_cache(value)
        ):
            note = store.last_reason  # e.g. a long trial's model stage (graph.model_to_cache)
        self.keys[name] = key
        self._record(StageRecord(name, "computed", time.perf_counter() - t0, note, key))
        return value
