"""``msk --help`` start-up time (issue target ≤ 0.3 s) against a bare ``python -c pass`` in the
same run, and what importing the verbs costs.

    python bench/bench_cli.py [--repeats 7]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

BIN = Path(sys.executable).parent


def _times(cmd: list[str], n: int) -> list[float]:
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True)
        out.append(time.perf_counter() - t0)
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=7)
    args = p.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f}, {args.repeats} repeats")
    base = _times([sys.executable, "-c", "pass"], args.repeats)
    msk = _times([str(BIN / "msk"), "--help"], args.repeats)
    for name, t in (("python -c pass", base), ("msk --help", msk)):
        print(
            f"{name:16s} min {1000 * min(t):6.0f} ms  median {1000 * statistics.median(t):6.0f} ms"
        )
    print(f"msk --help − bare interpreter: {1000 * (min(msk) - min(base)):.0f} ms (min)")


if __name__ == "__main__":
    main()
