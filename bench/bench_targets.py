"""The speed targets' figures in one run, each next to its target, with the load average.

1. static optimisation: OpenSim 4.6 StaticOptimization / msk SO per frame, CPU (≥ 500×);
2. the chain ID + geometry + SO + knee contact (with the medial/lateral split), µs/frame (≤ 100);
3. the knee contact stage alone, µs/frame (≤ 10);
4. ``msk run pipelines/gc5_PS.toml --no-cache`` cold, in a fresh interpreter, s (≤ 2), and
   the same run again with its stage cache (≤ 0.5 s: the issue's "cached" target);
5. ``msk batch`` of 16 × gc5_PS, 1 worker / 2 workers on the local pool (≥ 1.8×), and the
   same on a Dask ``LocalCluster`` (1 / 2 worker processes, one thread each).

1–3 come from :func:`bench_chain.measure` (gait2392 subject01 walk, OpenSim on the same states,
``--repeat`` batch calls per stage after a warm-up: min and median; the verdict uses the min
wall time, the ratio the CPU times), 4 from ``bench_run_cold`` (``--cold`` runs after one
untimed run: min and median, verdict on the median), 5 from :func:`msk.pipeline.batch.run_batch`
(``forkserver`` workers, every stage computed). The machine is shared: the load average is
printed before and after each part; only figures of the same run compare.

    .venv/bin/python bench/bench_targets.py [--repeat 15] [--cold 5] [--sessions 16]
        [--skip batch] [--baseline main]

``--baseline REF`` measures the ``msk`` package as it is at git ``REF`` instead (``git
archive`` into a temporary folder, put ahead of the installed package for this process, the
cold runs and the batch workers): run it right before or after the working tree for a ratio
in the same conditions.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import platform
import statistics
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from datetime import date
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "pipelines" / "gc5_PS.toml"


def _load() -> str:
    return " / ".join(f"{x:.1f}" for x in os.getloadavg())


def _verdict(wall: float, cpu: float, target: float) -> str:
    """Met on the wall time (min); on a loaded machine, say when only the CPU time meets it."""
    if wall <= target:
        return "met"
    return "met in CPU time, not in wall time at this load" if cpu <= target else "not met"


def _msk_runs(src: Path, n: int, *, cached: bool) -> list[float]:
    """Wall times of ``n`` fresh-interpreter ``msk run``s of gc5_PS (cold: ``--no-cache``;
    cached: with the stage cache of one output folder) after one untimed run (it warms the disk
    cache, and fills the stage cache)."""
    import bench_run_cold

    walls = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(n + 1):
            out = Path(tmp) / ("out" if cached else f"out{k}")
            wall, _ = bench_run_cold._run_once(src, out, cached=cached)
            if k:
                walls.append(wall)
    return walls


@contextlib.contextmanager
def _local_pool(workers: int) -> Iterator[dict[str, Any]]:
    """``run_batch`` arguments for the local process pool of ``workers``."""
    yield {"workers": workers}


@contextlib.contextmanager
def _dask_cluster(workers: int) -> Iterator[dict[str, Any]]:
    """``run_batch`` arguments for a Dask LocalCluster of ``workers`` processes (one thread
    each), started before the timing: a cluster serves many batches, and the first session on
    each worker pays that worker's imports."""
    from distributed import Client, LocalCluster

    with (
        LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                     dashboard_address=None) as cluster,
        Client(cluster) as client,
    ):  # fmt: skip
        yield {"scheduler": client}


def _batch_speedup(
    label: str,
    detail: str,
    sessions: int,
    where: Callable[[int], contextlib.AbstractContextManager[dict[str, Any]]],
    notes: list[str],
) -> tuple[str, ...]:
    """The table row of ``msk batch`` of ``sessions`` × gc5_PS on 1 then 2 workers of
    ``where`` (every stage computed); a note per batch."""
    import msk.pipeline.batch as batch

    wall: dict[int, float] = {}
    for workers in (1, 2):
        l0 = _load()
        with where(workers) as kwargs, tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            res = batch.run_batch([CONFIG] * sessions, Path(tmp) / "out", use_cache=False, **kwargs)
            wall[workers] = time.perf_counter() - t0
        if res.failed:
            raise SystemExit(f"batch{label} failed: {[o.error for o in res.failed]}")
        notes.append(f"batch{label}, {workers} worker(s): {wall[workers]:.1f} s, load {l0} → "
                     f"{_load()}")  # fmt: skip
    speed = wall[1] / wall[2]
    return (f"`msk batch` {sessions} × gc5_PS{label}, 2 workers / 1", f"{speed:.2f}×",
            f"{wall[1]:.1f} s → {wall[2]:.1f} s ({detail})", "≥ 1.8×",
            "met" if speed >= 1.8 else "not met")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=15, help="timed batch calls per chain stage")
    ap.add_argument("--cold", type=int, default=5, help="timed cold `msk run`s")
    ap.add_argument("--sessions", type=int, default=16, help="sessions per batch")
    ap.add_argument("--skip", default="", help="comma-separated: chain, cold, batch, dask")
    ap.add_argument("--baseline", default=None, help="measure the msk package at this git ref")
    args = ap.parse_args()
    src = REPO
    if args.baseline:  # the package at a git ref, imported ahead of the installed one
        import bench_run_cold

        src = bench_run_cold._checkout(args.baseline, Path(tempfile.mkdtemp()))
        sys.path.insert(0, str(src))
        os.environ["PYTHONPATH"] = os.pathsep.join([str(src), os.environ.get("PYTHONPATH", "")])
    import bench_chain  # imports msk: after the baseline's path is set
    import bench_run_cold

    import msk

    print(f"msk from {Path(msk.__file__).parent}", flush=True)
    skip = set(filter(None, args.skip.split(",")))
    rows: list[tuple[str, str, str, str, str]] = []  # figure, value, detail, target, verdict
    notes: list[str] = [
        f"{date.today().isoformat()}, {platform.machine()}, {os.cpu_count()} cores shared with "
        f"other jobs, Python {platform.python_version()}; load average (1/5/15 min) at start "
        f"{_load()}"
    ]

    if "chain" not in skip:
        l0 = _load()
        r = bench_chain.measure(args.repeat)
        best, med, cpu = r["best"], r["median"], r["cpu"]
        so = "static optimisation"
        ratio = r["opensim_cpu_us"] / cpu[so]
        # the plain chain: the compartment rows' stages replace the SO, they do not add to it
        plain = [k for k in r["stages"] if k not in (bench_chain.ROWS, bench_chain.SO_ROWS)]
        chain = sum(best[k] for k in plain)
        chain_med = sum(med[k] for k in plain)
        chain_cpu = sum(cpu[k] for k in plain)
        contact = best[bench_chain.CONTACT]
        rows += [
            ("SO: OpenSim / msk per frame (CPU)", f"{ratio:,.0f}×",
             f"OpenSim {r['opensim_cpu_us']:,.0f} µs CPU ({r['opensim_us']:,.0f} wall), msk "
             f"{cpu[so]:.1f} µs CPU ({best[so]:.1f} wall min, {med[so]:.1f} median)",
             f"≥ {bench_chain.TARGET_RATIO:.0f}×", "met" if ratio >= bench_chain.TARGET_RATIO
             else "not met"),
            ("chain ID + geometry + SO + contact", f"{chain:.1f} µs/frame",
             f"wall min; median {chain_med:.1f}, CPU {chain_cpu:.1f}; "
             + ", ".join(f"{k} {best[k]:.1f}" for k in plain),
             f"≤ {bench_chain.TARGET_US:.0f} µs", _verdict(chain, chain_cpu,
                                                        bench_chain.TARGET_US)),
            ("knee contact + medial/lateral split", f"{contact:.1f} µs/frame",
             f"wall min; median {med[bench_chain.CONTACT]:.1f}, CPU {cpu[bench_chain.CONTACT]:.1f}",
             f"≤ {bench_chain.TARGET_CONTACT_US:.0f} µs",
             _verdict(contact, cpu[bench_chain.CONTACT], bench_chain.TARGET_CONTACT_US)),
        ]  # fmt: skip
        notes.append(
            f"chain: {r['n']} frames, 92 muscles, {args.repeat} repeats per stage; load {l0} → "
            f"{_load()}"
        )

    if "cold" not in skip:
        for what, cached, target in (("cold", False, bench_run_cold.TARGET_S),
                                     ("cached", True, bench_run_cold.TARGET_CACHED_S)):  # fmt: skip
            l0 = _load()
            walls = _msk_runs(src, args.cold, cached=cached)
            lo, mid = min(walls), statistics.median(walls)
            rows.append(
                (f"`msk run` gc5_PS {what} (fresh interpreter)", f"{mid:.2f} s",
                 f"median of {args.cold}; min {lo:.2f} s", f"≤ {target:g} s",
                 "met" if mid <= target else
                 ("met by the fastest run only" if lo <= target else "not met"))
            )  # fmt: skip
            notes.append(f"{what} run: load {l0} → {_load()}")

    if "batch" not in skip:
        os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "4")  # as `msk batch` sets it
        rows.append(_batch_speedup("", "forkserver workers", args.sessions, _local_pool, notes))
    if "dask" not in skip:
        rows.append(_batch_speedup(" on Dask", "LocalCluster, 1 thread per worker",
                                   args.sessions, _dask_cluster, notes))  # fmt: skip

    notes.append(f"load average at the end {_load()}")
    print("| figure | value | detail | target | verdict |")
    print("| --- | --- | --- | --- | --- |")
    for row in rows:
        print("| " + " | ".join(row) + " |")
    print()
    for note in notes:
        print(f"- {note}")


if __name__ == "__main__":
    main()
