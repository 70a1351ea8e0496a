"""Cost of the segment-COM acceleration domain (:mod:`msk.kinematics.com_consistency`) against the
inverse
kinematics it follows, in the same run.

Trial: the UWA running session as shipped (``pipelines/uwa_running.toml``, Running_1: 1,436
frames at 250 Hz, the tracked window solved), its kinematics computed once by the pipeline's
own stages (:func:`msk.pipeline.run_stages`). Timed, best of ``--repeats``:

* :func:`msk.kinematics.com_consistency.com_consistent_kinematics` on that kinematics;
* :func:`msk.kinematics.ik.solve_kinematics` of the same trial (the pipeline's kinematics stage,
  ``msk.pipeline.kinematics.run``): the baseline.

Run: ``.venv/bin/python bench/bench_com_consistency.py [--repeats N]``: prints the section
(only ``bench/run_all.py`` writes figures into the docs).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
from pathlib import Path

import numpy as np
from _timing import best_of

from msk.config import load_config
from msk.kinematics.com_consistency import com_consistent_kinematics
from msk.pipeline import kinematics as kinematics_stage
from msk.pipeline import run_stages
from msk.pipeline.inputs import session_inputs

ROOT = Path(__file__).resolve().parent.parent
SECTION = "## Segment-COM acceleration domain"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    cfg_path = ROOT / "pipelines" / "uwa_running.toml"
    cfg = load_config(cfg_path)
    filters = dataclasses.replace(cfg.filters, acceleration_domain="coordinates")
    plain = dataclasses.replace(cfg, filters=filters)
    res = run_stages(plain, until="kinematics")
    built, kin = res["model"], res["kinematics"]
    inputs = session_inputs(plain)
    solved = int(np.isfinite(kin.a).all(axis=1).sum())
    t_ik, _ = best_of(lambda: kinematics_stage.run(inputs, built), args.repeats)
    t_com, _ = best_of(
        lambda: com_consistent_kinematics(built.model, kin), args.repeats, warmup=True
    )
    load = os.getloadavg()[0]
    lines = [
        SECTION,
        "",
        f"`bench/bench_com_consistency.py` ({platform.processor() or platform.machine()}, "
        f"load {load:.1f}; best of {args.repeats}). UWA running, {kin.n_frames} frames, "
        f"{solved} solved:",
        "",
        "| step | time (ms) | per solved frame (µs) |",
        "| --- | --- | --- |",
        f"| inverse kinematics (the kinematics stage, baseline) | {1e3 * t_ik:.1f} | "
        f"{1e6 * t_ik / solved:.0f} |",
        f"| `com_consistent_kinematics` | {1e3 * t_com:.1f} | {1e6 * t_com / solved:.0f} |",
        "",
        f"Ratio: the segment-COM domain costs {t_com / t_ik:.3f}× the trial's IK.",
        "",
    ]
    text = "\n".join(lines)
    print(text)


if __name__ == "__main__":
    main()
