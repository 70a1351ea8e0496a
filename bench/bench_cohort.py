"""The 20-subject dynamometry cohort end to end through its shipped configs, as ``msk batch``
runs it, against reading its 20 × 4 files alone.

Sessions: ``pipelines/dynamometry_elderly/S01…S20.toml`` (four maximal isometric tests per
subject, 2 kHz gzip CSV). Timed in this run, best of ``--repeats``:

* reading every test file (:func:`msk.io.dynamometer.read_dynamometer`, one process): the
  baseline;
* :func:`msk.pipeline.batch.run_batch` of the 20 configs on ``--workers`` local workers (what
  ``msk batch`` calls: each session in a child process, then ``cohort.csv`` and
  ``strength_cohort.csv``), wall time;
* :func:`msk.pipeline.dynamometry.run_dynamometry` of every subject in this process, one after
  the other (the work without the pool and interpreter start-ups).

Printed per subject and as ratios to the reading. Target: ≤ 1 s per subject on 2 cores.

    .venv/bin/python bench/bench_cohort.py [--repeats N] [--workers 2]

``bench/run_all.py`` runs it as its ``cohort`` part.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = "pipelines/dynamometry_elderly/S*.toml"


def _best(fn: Callable[[], Any], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def measure(repeats: int = 3, workers: int = 2) -> dict[str, float]:
    """Seconds of the three timings (module docstring) and the number of subjects."""
    from msk.io.dynamometer import read_dynamometer
    from msk.pipeline.batch import run_batch
    from msk.pipeline.dynamometry import load_dynamometry_config, run_dynamometry

    paths = sorted(ROOT.glob(CONFIGS))
    if not paths:
        raise SystemExit(f"no configs {CONFIGS}")
    cfgs = [load_dynamometry_config(p) for p in paths]
    files = sum(len(c.tests) for c in cfgs)

    def read_all() -> None:
        for c in cfgs:
            for tc in c.tests:
                read_dynamometer(tc.file, **c.reader)

    def batch() -> None:
        with tempfile.TemporaryDirectory() as tmp:
            res = run_batch([str(p) for p in paths], tmp, workers=workers)
            bad = [o.config for o in res.outcomes if not o.ok]
            if bad:
                raise SystemExit(f"sessions failed: {bad}")

    def serial() -> None:
        with tempfile.TemporaryDirectory() as tmp:
            for c in cfgs:
                run_dynamometry(c, Path(tmp) / c.subject["name"])

    read_all()  # warm the page cache and the imports
    return {
        "subjects": float(len(cfgs)),
        "files": float(files),
        "read_s": _best(read_all, repeats),
        "batch_s": _best(batch, repeats),
        "serial_s": _best(serial, repeats),
    }


def lines(m: dict[str, float], workers: int) -> list[tuple[str, str, str]]:
    """(figure, ratio, detail) rows, as ``bench/run_all.py`` prints them."""
    n = m["subjects"]
    return [
        (
            f"dynamometry cohort, `msk batch` of {n:.0f} subjects on {workers} workers / reading "
            f"their {m['files']:.0f} files",
            f"{m['batch_s'] / m['read_s']:.1f}×",
            f"{m['batch_s'] / n:.3f} s per subject (target ≤ 1 s on 2 cores), "
            f"reading {m['read_s'] / n:.3f} s per subject",
        ),
        (
            "dynamometry cohort, `run_dynamometry` one after the other in one process / reading",
            f"{m['serial_s'] / m['read_s']:.1f}×",
            f"{m['serial_s'] / n:.3f} s per subject",
        ),
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    print(f"load average {' / '.join(f'{x:.1f}' for x in os.getloadavg())}")
    m = measure(args.repeats, args.workers)
    for fig, ratio, detail in lines(m, args.workers):
        print(f"  {fig}: {ratio}  ({detail})")


if __name__ == "__main__":
    main()
