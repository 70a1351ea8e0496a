"""Benchmark: ``msk run pipelines/gc5_PS.toml --no-cache`` cold, as a user types it.

Each run is a fresh interpreter (imports, model building, every stage, the report), timed from
outside (wall clock around the process), with the per-stage seconds the run prints. With
``--baseline REF`` the package as it is at git ``REF`` (``git archive``, imported from a
temporary folder ahead of the installed one) runs interleaved with the working tree, in the
same conditions, and the ratio working tree / baseline is printed. The load average is printed
before and after: on a shared machine only the ratio of the same run means something.

Usage: ``.venv/bin/python bench/bench_run_cold.py [--repeat 5] [--baseline main]`` (prints its
figures; ``bench/run_all.py`` prints the same comparison, and only it writes figures into the
docs).
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from datetime import date
from io import BytesIO
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "pipelines" / "gc5_PS.toml"
STAGE = re.compile(r"^\[\s*\d+/\d+\]\s+(\S+)\s+([\d.]+) s\s+(\S+)", re.M)
TARGET_S = 2.0
TARGET_CACHED_S = 0.5


def _load() -> str:
    return " / ".join(f"{x:.1f}" for x in os.getloadavg())


def _checkout(ref: str, into: Path) -> Path:
    """The ``msk`` package at git ``ref`` unpacked under ``into``."""
    blob = subprocess.run(
        ["git", "-C", str(REPO), "archive", "--format=tar", ref, "msk"],
        check=True,
        capture_output=True,
    ).stdout
    with tarfile.open(fileobj=BytesIO(blob)) as tar:
        tar.extractall(into, filter="data")
    return into


def _run_once(src: Path, out: Path, *, cached: bool = False) -> tuple[float, dict[str, float]]:
    """Wall time of one ``msk run`` (``--no-cache`` unless ``cached``: then the stage cache of
    ``out`` from an earlier run is used) with the package found in ``src``; stage seconds.

    The child may write bytecode (``PYTHONDONTWRITEBYTECODE`` is dropped from its environment):
    a user's second run finds msk's ``.pyc`` files, and a shell that forbids them would time
    the compilation of ~90 modules (~0.15 s) at every run."""
    # what the console script runs (msk.cli.console; main where there is no console yet)
    code = (
        f"import sys; sys.path.insert(0, {str(src)!r}); import msk.cli as c; "
        "getattr(c, 'console', lambda: sys.exit(c.main()))()"
    )
    cmd = [sys.executable, "-c", code, "run", str(CONFIG), "--out", str(out)]
    cmd += [] if cached else ["--no-cache"]
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO, env=env)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"msk run failed ({src}):\n{proc.stderr[-2000:]}")
    stages = {m.group(1): float(m.group(2)) for m in STAGE.finditer(proc.stderr)}
    return wall, stages


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="cold runs of each variant")
    ap.add_argument("--baseline", default=None, help="git ref to compare with (same run)")
    args = ap.parse_args()

    load0 = _load()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        variants = {"working tree": REPO}
        if args.baseline:
            variants = {f"baseline {args.baseline}": _checkout(args.baseline, root / "base"),
                        **variants}  # fmt: skip
        walls: dict[str, list[float]] = {v: [] for v in variants}
        stages: dict[str, dict[str, list[float]]] = {v: {} for v in variants}
        for k in range(args.repeat + 1):  # the first round warms the disk cache, not timed
            for name, src in variants.items():
                wall, st = _run_once(src, root / f"out_{k}_{len(walls[name])}")
                if k == 0:
                    continue
                walls[name].append(wall)
                for s, sec in st.items():
                    stages[name].setdefault(s, []).append(sec)
    load1 = _load()

    lines = []
    head = (
        f"Latest run ({date.today().isoformat()}, {platform.machine()}, {os.cpu_count()} cores "
        f"shared with other jobs, load average {load0} before, {load1} after (1/5/15 min); "
        f"Python {platform.python_version()}): `msk run pipelines/gc5_PS.toml --no-cache` in a "
        f"fresh interpreter each time, {args.repeat} runs per variant, interleaved, after one "
        "untimed round."
    )
    lines += [head, ""]
    names = list(variants)
    lines.append("| | " + " | ".join(names) + " |")
    lines.append("| --- |" + " --- |" * len(names))
    lines.append(
        "| wall, min / median (s) | "
        + " | ".join(f"{min(walls[n]):.2f} / {statistics.median(walls[n]):.2f}" for n in names)
        + " |"
    )
    all_stages = list(dict.fromkeys(s for n in names for s in stages[n]))
    for s in all_stages:
        cells = []
        for n in names:
            v = stages[n].get(s)
            cells.append(f"{statistics.median(v):.2f}" if v else "")
        if any(c not in ("", "0.00") for c in cells):
            lines.append(f"| {s} (median s) | " + " | ".join(cells) + " |")
    lines.append("")
    cur = walls["working tree"]
    if len(names) == 2:
        base = walls[names[0]]
        lines.append(
            f"- working tree / baseline: **{min(cur) / min(base):.2f}** (min), "
            f"{statistics.median(cur) / statistics.median(base):.2f} (median)."
        )
    lo, mid = min(cur), statistics.median(cur)
    verdict = "met" if mid <= TARGET_S else ("met by the fastest run only" if lo <= TARGET_S
                                             else "not met")  # fmt: skip
    lines.append(
        f"- Target ≤ {TARGET_S:g} s cold: {verdict} at this load (min {lo:.2f} s, median "
        f"{mid:.2f} s)."
    )
    text = "\n".join(lines)
    print(text)


if __name__ == "__main__":
    main()
