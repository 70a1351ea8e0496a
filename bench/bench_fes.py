"""Benchmark: the full FES identification protocol (seeds/000) for one leg.

Run: ``.venv/bin/python bench/bench_fes.py [--leg S3L [S6R …]] [--repeat 2]``.  The first run in the
process is *cold* (casadi builds and caches the simulator, the sensitivity functions and the
multiple-shooting NLP); the following runs are *warm* (cached functions, new data).  Target:
the full protocol in < 30 s (the wall-clock target lives here, not in ``tests/``: the tests
run on shared, loaded machines).  Prints a markdown row per leg for ``docs/benchmarks.md``.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from msk.fes.model import TABLE3
from msk.fes.protocol import TABLE1, fibre_fraction, run_protocol, synthetic_session


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--leg", nargs="+", default=["S3L"], choices=sorted(TABLE3))
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    for leg in args.leg:
        bench_leg(leg, args.repeat)


def bench_leg(leg: str, repeat: int) -> None:
    s = TABLE3[leg]
    h, m = TABLE1[int(leg[1:-1])]
    ses = synthetic_session(
        s,
        height=h,
        body_mass=m,
        torque_noise=0.01,
        angle_noise_deg=0.5,
        rng=np.random.default_rng(1),
    )
    walls, cpus = [], []
    for i in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        res = run_protocol(
            ses, fibre_fraction=fibre_fraction(s), stiffness_ratio=s.muscle.K_cm / s.muscle.F_cm
        )
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
        passes = len(res.k_s_history) - 1
        table = {k: round(v, 2) for k, v in res.nrmsd_table().items()}
        print(
            f"run {i} ({'cold' if i == 0 else 'warm'}): wall {walls[-1]:.2f} s, CPU "
            f"{cpus[-1]:.2f} s, {passes} NLP passes, k_s = {res.subject.muscle.k_s / 1e3:.2f} "
            f"N/mm, NRMSD % {table}"
        )
    cold, warm = cpus[0], min(cpus[1:]) if len(cpus) > 1 else float("nan")
    warm_wall = min(walls[1:]) if len(walls) > 1 else float("nan")
    print(f"CPU: cold {cold:.2f} s, warm {warm:.2f} s, warm/cold = {warm / cold:.2f}")
    print(
        f"| {leg} full protocol (1 % torque, 0.5° noise) | {walls[0]:.1f} s / {cold:.1f} s "
        f"| {warm_wall:.1f} s / {warm:.1f} s | {warm / cold:.2f} | "
        f"{platform.machine()}, load {os.getloadavg()[0]:.1f} |"
    )


if __name__ == "__main__":
    main()
