"""Live mode's per-frame latency: the bundled trial (gc5 PS, C3D) and a DM trial (gc6 DM, TRC +
GRF) replayed as fast as possible through :class:`msk.live.LiveSession` (IK + causal filter +
inverse dynamics + muscle geometry + static optimisation + knee contact, gait2392's 92
muscles), p50/p99 of each stage and of the whole chain, and the chain's cost as a ratio to a
floor measured in the same run, frame by frame alternated with it: one Pinocchio forward
kinematics of the frame's pose and one cold DAQP solve of the frame's static-optimisation QP
(the same size: 92 activations + the reserves, one equality row per actuated coordinate).

Absolute µs belong to the host they ran on (printed with its load); the ratio to the floor is
the figure to compare across machines. Wall time (what a control loop waits) and the thread's
CPU time (``time.thread_time``: what a busy host's preemptions do not inflate) are both
printed; the ratio is of CPU times. Target (docs/user-guide.md, "Live mode"): p99 ≤ 1 ms on
an idle 2-core machine, chain ≤ 1.5× the floor.

    .venv/bin/python bench/bench_live.py [--passes 3] [--sessions gc5_PS gc6_DM_og1] [--json]

``bench/run_all.py`` runs it (part ``live``) alternately on the working tree and the previous
commit, each in a fresh interpreter.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

from msk.config import load_config
from msk.live import STAGES, LiveSession
from msk.live.sources import ReplaySource
from msk.muscles.geometry import jacobian_frames
from msk.muscles.hill import rigid_tendon_state
from msk.optimization import StaticOptimizationProblem
from msk.optimization._qp import _solve_daqp
from msk.pipeline.inputs import session_inputs
from msk.pipeline.live import live_setup

REPO = Path(__file__).resolve().parents[1]


def _floor(lm, q: np.ndarray, v: np.ndarray, tau: np.ndarray, data) -> float:
    """One forward kinematics + one cold DAQP solve of this frame's SO QP, s (QP built
    untimed)."""
    geo = lm.plan.evaluate(q[None], v[None], compact=True)
    st = rigid_tendon_state(lm.params, geo.lengths, geo.velocities)
    fa = np.maximum(st.max_active_force_along_tendon[0], 0.0)
    jac = jacobian_frames(geo.jacobian, np.zeros(1, dtype=np.intp), lm.actuated)[0]
    prob = StaticOptimizationProblem(
        jac, tau[lm.actuated], f_active=fa, f_passive=st.passive_force_along_tendon[0],
        reserve_optimal_force=np.ones(lm.actuated.size), activation_weights=lm.activation_weights,
        muscle_names=lm.muscle_names, coordinate_names=lm.actuated_names,
    )  # fmt: skip
    qp, _ = prob.standard_form()
    qpin = lm.model.coupling.q(q)
    t0 = time.thread_time()
    pin.forwardKinematics(lm.model.pin_model, data, qpin)
    _solve_daqp(qp, None)
    return time.thread_time() - t0


def run(name: str, passes: int, skip: int) -> dict[str, float]:
    cfg = load_config(REPO / "pipelines" / f"{name}.toml")
    task = session_inputs(cfg).task
    assert task is not None
    src = ReplaySource(task.file, grf=task.grf, external_loads=task.external_loads)
    setup = live_setup(
        cfg, src.layout.labels, src.rate_hz, plate_names=src.plate_names, assignment=src.assignment
    )
    lm = setup.model
    frames = list(src)
    data = lm.model.pin_model.createData()
    chain, cpu, stages, floor = [], [], [], []
    for _ in range(passes):
        session = LiveSession(lm)
        for k, f in enumerate(frames):
            c0 = time.thread_time()
            out = session.step(f)
            c1 = time.thread_time()
            if k >= skip:
                stages.append(out.stage_s)
                chain.append(out.latency_s)
                cpu.append(c1 - c0)
                floor.append(_floor(lm, out.q, out.v, out.torques, data))
    s = np.array(stages)
    c, cc, fl = np.array(chain), np.array(cpu), np.array(floor)
    n_m = len(lm.muscle_names)
    print(f"\n{name}: {len(frames)} frames at {src.rate_hz:g} Hz × {passes} passes "
          f"({c.size} timed), {n_m} muscles, lag {1e3 * session.lag_s:.1f} ms")  # fmt: skip
    print(f"  {'stage (wall)':<18s} {'p50 µs':>9s} {'p99 µs':>9s}")
    for k, st in enumerate(STAGES):
        print(f"  {st:<18s} {1e6 * np.percentile(s[:, k], 50):9.0f} "
              f"{1e6 * np.percentile(s[:, k], 99):9.0f}")  # fmt: skip
    w50, w99 = np.percentile(c, 50), np.percentile(c, 99)
    p50, p99 = np.percentile(cc, 50), np.percentile(cc, 99)
    f50, f99 = np.percentile(fl, 50), np.percentile(fl, 99)
    print(f"  {'chain (wall)':<18s} {1e6 * w50:9.0f} {1e6 * w99:9.0f}")
    print(f"  {'chain (CPU)':<18s} {1e6 * p50:9.0f} {1e6 * p99:9.0f}")
    print(f"  {'floor (CPU)':<18s} {1e6 * f50:9.0f} {1e6 * f99:9.0f}   (FK + one DAQP solve)")
    print(f"  chain / floor (CPU): p50 {p50 / f50:.1f}×, p99 {p99 / f99:.1f}×  "
          f"(targets: p99 ≤ 1000 µs on an idle host; ≤ 1.5× the floor)")  # fmt: skip
    out = {"chain_p50": p50, "chain_p99": p99, "floor_p50": f50, "floor_p99": f99,
           "wall_p50": w50, "wall_p99": w99, "lag_s": session.lag_s}  # fmt: skip
    for k, st in enumerate(STAGES):
        out[f"{st}_p50"] = float(np.percentile(s[:, k], 50))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--passes", type=int, default=3)
    ap.add_argument("--skip", type=int, default=10, help="first frames of a pass not timed")
    ap.add_argument("--sessions", nargs="+", default=["gc5_PS", "gc6_DM_og1"])
    ap.add_argument("--json", action="store_true", help="also one JSON line per session")
    args = ap.parse_args()
    load = os.getloadavg()
    print(f"host {platform.node()} ({platform.machine()}, {os.cpu_count()} CPUs), "
          f"load {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}, python {platform.python_version()}, "
          f"pinocchio {pin.__version__}")  # fmt: skip
    for name in args.sessions:
        figures = run(name, args.passes, args.skip)
        if args.json:
            print("JSON " + json.dumps({"session": name, **figures}), flush=True)


if __name__ == "__main__":
    main()
