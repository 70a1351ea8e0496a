"""The tension stage's KKT figures on gc5_PS (``pipelines/gc5_PS.toml``: emg_assisted with the
knee compartment rows, DAQP, its sub-problems): µs per solved frame of the whole stage
(:func:`msk.pipeline.tension.optimise`) with the figures computed over frames at once
(:func:`msk.optimization.kkt_batch`, what the pipeline runs), with them computed frame by frame
(:func:`msk.optimization.kkt` on each frame's whole QP, main's code before the eleventh pass)
and without them (``compute_kkt=False``). The three variants alternate round by round (the
machine is shared: each figure is the best of ``--repeat`` rounds, the median beside it), and
the batched figures are checked against the per-frame ones.

    .venv/bin/python bench/bench_kkt.py [--repeat 7] [--write-docs]

``--write-docs`` replaces the section "## Tension stage KKT figures" of docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np
from _timing import replace_doc_section
from threadpoolctl import threadpool_limits

import msk.optimization.problems as problems
from msk.config import load_config
from msk.optimization import KKTBatch, StandardQP, kkt, kkt_scale
from msk.pipeline.inputs import session_inputs
from msk.pipeline.mass_identification import identified_model
from msk.pipeline.session import run_stages
from msk.pipeline.tension import optimise

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "pipelines" / "gc5_PS.toml"
SECTION = "## Tension stage KKT figures (`bench/bench_kkt.py`)"


def per_frame(qps: list[StandardQP], xs: np.ndarray) -> KKTBatch:
    """Main's figures: :func:`kkt` frame by frame (and the scales, as cheap)."""
    figs = np.array([kkt(q, x).as_array() for q, x in zip(qps, xs)]).reshape(-1, 4)
    scale = np.array([kkt_scale(q, x) for q, x in zip(qps, xs)]).reshape(-1, 4)
    return KKTBatch(figs, scale, np.zeros(len(qps), dtype=bool))


def measure(repeat: int) -> dict[str, Any]:
    r = run_stages(CONFIG, until="muscle_geometry")
    inputs = session_inputs(load_config(CONFIG))
    model = identified_model(r["model"].model, r["mass_identification"])
    kin, loads = r["kinematics"], r["loads"]
    batched = problems.kkt_batch
    run_batch = problems._run_batch
    kept: dict[str, Any] = {}

    def stage() -> Any:
        return optimise(
            inputs, model, r["inverse_dynamics"].torques, r["muscle_geometry"], kin.time,
            loads.usable, r["emg"], kinematics=kin, external=loads.external,
        )  # fmt: skip

    def no_kkt(*a: Any, **k: Any) -> Any:
        return run_batch(*a, **{**k, "compute_kkt": False})

    def spy(*a: Any, **k: Any) -> Any:
        out = run_batch(*a, **k)
        kept.setdefault(variant, []).append(out.kkt)
        return out

    variants = {"batched": (batched, spy), "per frame": (per_frame, spy),
                "none": (batched, no_kkt)}  # fmt: skip
    times: dict[str, list[float]] = {v: [] for v in variants}
    n = 0
    with threadpool_limits(limits=1, user_api="blas"):
        for rnd in range(repeat + 1):  # round 0: warm-up
            for variant, (fn, rb) in variants.items():
                problems.kkt_batch, problems._run_batch = fn, rb
                try:
                    t0 = time.perf_counter()
                    sol = stage()
                    dt = time.perf_counter() - t0
                finally:
                    problems.kkt_batch, problems._run_batch = batched, run_batch
                n = int(np.isfinite(sol.forces).all(axis=1).sum())
                if rnd:
                    times[variant].append(dt / n * 1e6)
    a = np.concatenate(kept["batched"][: len(kept["batched"]) // (repeat + 1)])
    b = np.concatenate(kept["per frame"][: len(kept["per frame"]) // (repeat + 1)])
    ok = np.isfinite(b).all(axis=1)
    return {
        "frames": n,
        "best": {v: min(t) for v, t in times.items()},
        "median": {v: statistics.median(t) for v, t in times.items()},
        "max_diff": float(np.max(np.abs(a[ok] - b[ok]), initial=0.0)),
        "load": os.getloadavg()[0],
        "repeat": repeat,
    }


def _section(m: dict[str, Any]) -> str:
    b, med = m["best"], m["median"]
    rows = "\n".join(f"| {v} | {b[v]:.0f} | {med[v]:.0f} | {b[v] - b['none']:+.0f} |" for v in b)
    return (
        f"{SECTION}\n\n"
        f"gc5_PS ngait_og_ss1 ({m['frames']} solved frames; emg_assisted with the knee "
        "compartment rows, DAQP on its sub-problems): the whole tension stage "
        "(`msk.pipeline.tension.optimise`) in µs per solved frame, best and median of "
        f"{m['repeat']} alternating rounds, load {m['load']:.1f} "
        f"({datetime.date.today().isoformat()}, {platform.processor() or platform.machine()}, "
        "one BLAS thread). *batched*: the KKT figures of the solved frames by "
        "`msk.optimization.kkt_batch` (this pass); *per frame*: `msk.optimization.kkt` on "
        "each frame's whole QP (main before it); *none*: `compute_kkt=False`. The batched "
        f"figures equal the per-frame ones to {m['max_diff']:.1e} (absolute, largest over "
        "frames and figures).\n\n"
        "| KKT figures | best µs/frame | median µs/frame | cost over none |\n"
        "|---|---|---|---|\n" + rows + "\n"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--write-docs", action="store_true")
    args = ap.parse_args()
    m = measure(args.repeat)
    text = _section(m)
    print(text)
    if args.write_docs:
        replace_doc_section(ROOT / "docs" / "benchmarks.md", SECTION, text)


if __name__ == "__main__":
    main()
