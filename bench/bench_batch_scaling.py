"""Benchmark: how ``msk batch`` scales from one worker to two on the local process pool.

16 copies of the bundled Grand Challenge session (``pipelines/gc5_PS.toml``), every stage
computed (``use_cache=False``), run by :func:`msk.pipeline.batch.run_batch` with 1 and then 2
workers,
for each worker start method in the same run: ``forkserver`` (workers forked from a server
that imported msk once, :data:`msk.pipeline.batch.WORKER_PRELOAD`; the default) and ``spawn`` (each
worker imports everything afresh; the former default). Prints the wall times, the speed-up
2 workers / 1 worker, the per-session seconds and the load average before and after each
batch: the machine is shared, and other jobs on its 2 cores take from the 2-worker runs first.

Usage: ``.venv/bin/python bench/bench_batch_scaling.py [--sessions 16]
[--starts forkserver,spawn]``.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import statistics
import tempfile
import time
from pathlib import Path

import msk.pipeline.batch as batch

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "pipelines" / "gc5_PS.toml"


def _load() -> str:
    return "/".join(f"{x:.1f}" for x in os.getloadavg())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sessions", type=int, default=16)
    ap.add_argument("--starts", default="forkserver,spawn", help="worker start methods")
    args = ap.parse_args()
    os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "4")  # as `msk batch` (msk.cli) sets it
    default_context = batch._pool_context
    configs = [CONFIG] * args.sessions
    print(f"msk batch: {args.sessions} × gc5_PS, every stage computed, {os.cpu_count()} CPUs")
    results: dict[str, dict[int, float]] = {}
    for start in args.starts.split(","):
        batch._pool_context = (  # type: ignore[method-assign]
            default_context if start == "forkserver" else (lambda s=start: mp.get_context(s))
        )
        results[start] = {}
        for workers in (1, 2):
            with tempfile.TemporaryDirectory() as tmp:
                l0 = _load()
                t0 = time.perf_counter()
                res = batch.run_batch(configs, Path(tmp) / "out", workers=workers, use_cache=False)
                wall = time.perf_counter() - t0
                l1 = _load()
            assert not res.failed, [o.error for o in res.failed]
            per = [o.seconds for o in res.outcomes]
            results[start][workers] = wall
            print(
                f"  {start:<10} {workers} worker{'s' if workers > 1 else ' '}: {wall:6.1f} s  "
                f"(session median {statistics.median(per):.2f} s, first {min(per[:workers]):.2f}"
                f"–{max(per[:workers]):.2f} s; load {l0} → {l1})",
                flush=True,
            )
    for start, r in results.items():
        print(f"speed-up 2 workers / 1 worker, {start}: {r[1] / r[2]:.2f}× (target ≥ 1.8×)")
    batch._pool_context = default_context  # type: ignore[method-assign]


if __name__ == "__main__":
    main()
