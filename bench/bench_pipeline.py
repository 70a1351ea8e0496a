"""Benchmark: ``msk run`` on the bundled Grand Challenge session (pipelines/gc5_PS.toml).

Times, in one process and into a fresh temporary folder:

1. the first run (empty stage cache; imports already warm: a throw-away run in another folder
   comes first unless ``--cold``),
2. a re-run with nothing changed (every stage from the content-hash cache) → the ratio
   re-run / first run (target < 10 %),
3. a re-run after changing one setting (``optimization.w_emg`` → only tension optimisation and
   what follows it are recomputed),
4. optionally ``--pdf``: the time Chromium takes to print report.pdf.

Usage: ``.venv/bin/python bench/bench_pipeline.py [--repeat 3] [--pdf] [--cold]``.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "pipelines" / "gc5_PS.toml"


def _copy_session(folder: Path) -> Path:
    """The sample config with absolute paths, in ``folder`` (so a setting can be edited)."""
    text = CONFIG.read_text(encoding="utf-8")
    for rel in ("../models/", "../data/"):
        text = text.replace(f'"{rel}', f'"{(CONFIG.parent / rel).resolve()}/')
    cfg = folder / "gc5_PS.toml"
    cfg.write_text(text, encoding="utf-8")
    return cfg


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="re-runs timed (median reported)")
    ap.add_argument("--pdf", action="store_true", help="also time report.pdf (Chromium)")
    ap.add_argument("--cold", action="store_true", help="no warm-up run (imports in the first)")
    args = ap.parse_args()

    from msk.pipeline import run_session

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        cfg = _copy_session(tmp)
        if not args.cold:
            run_session(cfg, tmp / "warmup")
            shutil.rmtree(tmp / "warmup")
        out = tmp / "out"
        t0 = time.perf_counter()
        first = run_session(cfg, out)
        t_first = time.perf_counter() - t0
        reruns = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            again = run_session(cfg, out)
            reruns.append(time.perf_counter() - t0)
        assert all(r.status in ("cached", "not requested") for r in again.stages), [
            (r.name, r.status) for r in again.stages
        ]
        t_rerun = statistics.median(reruns)
        cfg.write_text(cfg.read_text().replace("w_emg = 0.1", "w_emg = 0.2"), encoding="utf-8")
        t0 = time.perf_counter()
        changed = run_session(cfg, out)
        t_changed = time.perf_counter() - t0
        recomputed = [r.name for r in changed.stages if r.status == "computed"]

        print("msk run pipelines/gc5_PS.toml (subject PS, gait2392, 145 frames, 92 muscles)")
        print(f"  first run (empty cache)          {t_first:7.3f} s")
        for r in first.stages:
            print(f"    {r.name:<26}{r.seconds:7.3f} s  {r.status}")
        print(f"  re-run, nothing changed (median of {args.repeat}) {t_rerun:7.3f} s")
        print(
            f"  ratio re-run / first run         {100 * t_rerun / t_first:6.1f} %  (target < 10 %)"
        )
        print(
            f"  re-run after w_emg 0.1 → 0.2     {t_changed:7.3f} s  recomputed: "
            f"{', '.join(recomputed)}"
        )
        if args.pdf:
            from msk.report import write_pdf

            t0 = time.perf_counter()
            ok = write_pdf(out / "report.html", out / "report.pdf")
            print(
                f"  report.pdf (Chromium)            {time.perf_counter() - t0:7.3f} s"
                + ("" if ok else "  (Chromium not available)")
            )


if __name__ == "__main__":
    main()
