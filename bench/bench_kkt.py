"""The tension stage's KKT check on gc5_PS (``pipelines/gc5_PS.toml``: emg_assisted with the
knee compartment rows, DAQP on its sub-problems): µs per solved frame of the whole stage
(:func:`msk.optimization.muscle_forces.solve_muscle_forces`) with the KKT figures (what the pipeline
runs) and
without them (``compute_kkt=False``), the two alternating round by round in one process; the
difference is the check's cost. One child process per source tree — this one (the figures
over frames at once, :func:`msk.optimization.kkt_stacked`) and ``--against`` (default
``/work/main``: :func:`msk.optimization.kkt` frame by frame on each frame's whole QP) —
alternating tree by tree (``--passes``), on the same machine under the same load.

    .venv/bin/python bench/bench_kkt.py [--repeat 7] [--passes 2] [--against /work/main]

prints its figures (only ``bench/run_all.py`` writes figures into the docs).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "pipelines" / "gc5_PS.toml"
SECTION = "## Tension stage KKT check (`bench/bench_kkt.py`)"


def child(repeat: int) -> dict[str, Any]:
    """In the tree on ``sys.path``: best and median µs/frame of the stage with and without the
    KKT figures (alternating), the worst KKT figure relative to its scale when available."""
    import numpy as np
    from threadpoolctl import threadpool_limits

    import msk
    import msk.optimization.problems as problems
    from msk.config import load_config
    from msk.dynamics.identification import identified_model
    from msk.optimization.muscle_forces import solve_muscle_forces
    from msk.pipeline.inputs import session_inputs
    from msk.pipeline.session import run_stages

    r = run_stages(CONFIG, until="muscle_geometry")
    inputs = session_inputs(load_config(CONFIG))
    model = identified_model(r["model"].model, r["mass_identification"])
    kin, loads = r["kinematics"], r["loads"]
    run_batch = problems._run_batch

    def no_kkt(*a: Any, **k: Any) -> Any:
        return run_batch(*a, **{**k, "compute_kkt": False})

    times: dict[str, list[float]] = {"kkt": [], "none": []}
    n, sol = 0, None
    with threadpool_limits(limits=1, user_api="blas"):
        for rnd in range(repeat + 1):  # round 0: warm-up
            for variant, rb in (("kkt", run_batch), ("none", no_kkt)):
                problems._run_batch = rb
                try:
                    t0 = time.perf_counter()
                    out = solve_muscle_forces(
                        model, r["inverse_dynamics"].torques, r["muscle_geometry"],
                        kin.time, loads.usable, r["emg"], kinematics=kin,
                        external=loads.external, **inputs.muscle_force_options(model),
                    )  # fmt: skip
                    dt = time.perf_counter() - t0
                finally:
                    problems._run_batch = run_batch
                n = int(np.isfinite(out.forces).all(axis=1).sum())
                if variant == "kkt":
                    sol = out
                if rnd:
                    times[variant].append(dt / n * 1e6)
    worst = getattr(sol, "kkt", None)
    return {
        "tree": str(Path(msk.__file__).resolve().parents[1]),
        "frames": n,
        "best": {v: min(t) for v, t in times.items()},
        "median": {v: statistics.median(t) for v, t in times.items()},
        "kkt_relative_max": None if worst is None else float(max(worst.relative)),
        "load": os.getloadavg()[0],
    }


def run_tree(tree: Path, repeat: int) -> dict[str, Any]:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", "--repeat", str(repeat)]
    out = subprocess.run(cmd, env=env, cwd=str(tree), capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def _section(runs: list[dict[str, Any]], repeat: int) -> str:
    rows = []
    for r in runs:
        b, med = r["best"], r["median"]
        who = "this branch (kkt_stacked)" if Path(r["tree"]) == ROOT else f"{r['tree']} (kkt)"
        rows.append(
            f"| {who} | {b['kkt']:.0f} | {b['none']:.0f} | {b['kkt'] - b['none']:+.0f} | "
            f"{med['kkt'] - med['none']:+.0f} | {r['load']:.1f} |"
        )
    worst = [r["kkt_relative_max"] for r in runs if r["kkt_relative_max"] is not None]
    return (
        f"{SECTION}\n\n"
        f"gc5_PS ngait_og_ss1 ({runs[0]['frames']} solved frames; emg_assisted with the knee "
        "compartment rows, DAQP on its sub-problems): the whole tension stage "
        "(`msk.optimization.muscle_forces.solve_muscle_forces`) in µs per solved frame with the "
        "KKT figures and "
        f"without them (`compute_kkt=False`), alternating, best of {repeat} rounds each; one "
        "process per source tree, the trees alternating "
        f"({datetime.date.today().isoformat()}, {platform.machine()}, one BLAS thread, shared "
        "2-core machine: load in the last column). The check's cost is the difference. "
        + (f"Worst KKT figure relative to its scale: {max(worst):.1e}. " if worst else "")
        + "\n\n| tree | with KKT | without | cost (best) | cost (median) | load |\n"
        "|---|---|---|---|---|---|\n" + "\n".join(rows) + "\n"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--passes", type=int, default=2)
    ap.add_argument("--against", type=Path, default=Path("/work/main"))
    ap.add_argument("--child", action="store_true")
    args = ap.parse_args()
    if args.child:
        print(json.dumps(child(args.repeat)))
        return
    runs = []
    for _ in range(args.passes):
        for tree in (args.against, ROOT):
            runs.append(run_tree(tree.resolve(), args.repeat))
            print(json.dumps(runs[-1]), flush=True)
    text = _section(runs, args.repeat)
    print(text)


if __name__ == "__main__":
    main()
