"""Benchmark: the report of the bundled session (pipelines/gc5_PS.toml) — its figures (the
``report`` stage, :func:`msk.report.build_figures`) and ``report.html`` written
(:func:`msk.report.write_report`, no PDF) — against the whole run.

The session is run once (``msk run``, no cache) into a temporary folder; then, in fresh
interpreters (imports of the report included, as in a run), the report is rebuilt from that
folder ``--repeat`` times. Printed: the median report time, the run's ``run_seconds`` and the
ratio. Target: ≤ 1 s.

Usage: ``.venv/bin/python bench/bench_report.py [--repeat 5]``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "pipelines" / "gc5_PS.toml"

_CHILD = """
import sys, time
from msk.results.folder import read_session
res = read_session(sys.argv[1])
t0 = time.perf_counter()
from msk.report import build_figures, write_report
figures = build_figures(res)
t1 = time.perf_counter()
write_report(res, sys.argv[1], figures=figures, pdf=False)
t2 = time.perf_counter()
print(t1 - t0, t2 - t1)
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="fresh interpreters timed (median)")
    args = ap.parse_args()
    env = {**os.environ, "PYTHONPATH": str(REPO), "MSK_NO_PDF": "1"}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "gc5"
        subprocess.run(
            [sys.executable, "-m", "msk.cli", "run", str(CONFIG), "--out", str(out),
             "--no-cache", "--quiet"],
            check=True, env=env,
        )  # fmt: skip
        summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
        stage = next(s["seconds"] for s in summary["stages"] if s["name"] == "report")
        figs, pages = [], []
        for _ in range(args.repeat):
            text = subprocess.run(
                [sys.executable, "-c", _CHILD, str(out)],
                check=True, env=env, capture_output=True, text=True,
            ).stdout.split()  # fmt: skip
            figs.append(float(text[0]))
            pages.append(float(text[1]))
    f, p = statistics.median(figs), statistics.median(pages)
    run = float(summary["run_seconds"])
    print(f"report stage in the run (figures)     {stage:7.3f} s")
    print(f"figures, fresh interpreter (median)   {f:7.3f} s")
    print(f"report.html written (median)          {p:7.3f} s")
    print(f"report total                          {f + p:7.3f} s  (target ≤ 1 s)")
    print(
        f"whole run (run_seconds)               {run:7.3f} s  → report {100 * (f + p) / run:.0f} %"
    )


if __name__ == "__main__":
    main()
