"""The 20-subject dynamometry cohort end to end, against reading its files alone.

Sessions: ``pipelines/dynamometry_elderly/S01…S20.toml`` (four 10-s tests per subject at 2 kHz,
gzip CSV). Timed, best of ``--repeats``, in one process (no pool, no interpreter start-up):

* reading every test file (:func:`msk.io.dynamometer.read_dynamometer`): the baseline;
* :func:`msk.pipeline.dynamometry.run_dynamometry` of every subject (read, analyse, scale the
  model, model torques, write the folder).

Run: ``.venv/bin/python bench/bench_dynamometry.py [--repeats N]``: prints the section (only
``bench/run_all.py`` writes figures into the docs).
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
from pathlib import Path

from _timing import best_of

from msk.io.dynamometer import read_dynamometer
from msk.pipeline.dynamometry import load_dynamometry_config, run_dynamometry

ROOT = Path(__file__).resolve().parent.parent
SECTION = "## Dynamometry cohort"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    cfgs = [
        load_dynamometry_config(p)
        for p in sorted(ROOT.glob("pipelines/dynamometry_elderly/S*.toml"))
    ]
    if not cfgs:
        raise SystemExit("no dynamometry configs")

    def read_all() -> None:
        for c in cfgs:
            for tc in c.tests:
                read_dynamometer(tc.file, **c.reader)

    def run_all() -> None:
        with tempfile.TemporaryDirectory() as tmp:
            for c in cfgs:
                run_dynamometry(c, Path(tmp) / c.subject["name"])

    t_read, _ = best_of(read_all, args.repeats)
    t_run, _ = best_of(run_all, args.repeats, warmup=True)
    n = len(cfgs)
    load = os.getloadavg()[0]
    lines = [
        SECTION,
        "",
        f"`bench/bench_dynamometry.py` ({platform.processor() or platform.machine()}, "
        f"load {load:.1f}; best of {args.repeats}; one process). {n} subjects × 4 tests:",
        "",
        "| step | total (s) | per subject (s) |",
        "| --- | --- | --- |",
        f"| reading the files (baseline) | {t_read:.2f} | {t_read / n:.3f} |",
        f"| `run_dynamometry`, every subject | {t_run:.2f} | {t_run / n:.3f} |",
        "",
        f"Ratio: the cohort end to end costs {t_run / t_read:.2f}× reading its files.",
        "",
    ]
    text = "\n".join(lines)
    print(text)


if __name__ == "__main__":
    main()
