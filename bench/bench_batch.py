"""Benchmark: ``msk batch`` of 20 sessions on a Dask ``LocalCluster`` (2 worker processes).

The cohort is the bundled Grand Challenge session (real), 18 simulated sessions
(``msk.datasets.trials.write_synthetic_session``: the synthetic two-leg model with 1–3 mm marker
noise) and one deliberately broken session (truncated C3D). Times, in the same run: the first
batch (empty stage caches), then a re-run with nothing changed (every stage from the
content-hash cache); prints the ratio (target < 10 %) and checks that exactly the broken
session is reported and 19 are written.

Usage: ``.venv/bin/python bench/bench_batch.py [--workers 2]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from msk.datasets.trials import write_synthetic_session
from msk.pipeline.batch import run_batch

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    from distributed import LocalCluster

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        configs = [REPO / "pipelines" / "gc5_PS.toml"]
        for i in range(18):
            cfg, _ = write_synthetic_session(root / f"s{i:02d}", f"synth_{i:02d}", seed=i,
                                  noise_m=0.001 * (1 + i % 3))  # fmt: skip
            configs.append(cfg)
        bad, _ = write_synthetic_session(root / "broken", "broken", broken=True)
        configs.append(bad)
        out = root / "out"
        with LocalCluster(
            n_workers=args.workers, threads_per_worker=1, processes=True, dashboard_address=":0"
        ) as cluster:
            t0 = time.perf_counter()
            first = run_batch(configs, out, scheduler=cluster.scheduler_address)
            t1 = time.perf_counter()
            again = run_batch(configs, out, scheduler=cluster.scheduler_address)
            t2 = time.perf_counter()
        written = sum((Path(o.out_dir) / "report.html").is_file() for o in first.outcomes if o.ok)
        print(f"sessions: {len(configs)} ({len(first.failed)} failed, {written} written)")
        for o in first.failed:
            print(f"  failed: {o.error}")
        print(f"first batch:  {t1 - t0:6.2f} s")
        print(f"re-run:       {t2 - t1:6.2f} s  ({100 * (t2 - t1) / (t1 - t0):.1f} % of the first)")
        assert len(first.failed) == 1 and written == 19, "expected 19 sessions written, 1 failed"
        assert [o.ok for o in again.outcomes] == [o.ok for o in first.outcomes]


if __name__ == "__main__":
    main()
