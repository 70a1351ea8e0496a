"""Whole per-frame chain on gait2392 (92 muscles): inverse dynamics + muscle geometry (lengths,
Jacobians, Thelen2003 f_active) + OpenSim-equivalent static optimisation (+ knee contact force),
in µs per frame, and its ratio to OpenSim 4.6's StaticOptimization measured in the same run.

Data: subject01 walking of the OpenSim peer (``shared/tools/opensim-peer/data``), 0.5–2.5 s; both
sides work on the same states (OpenSim's IK as AnalyzeTool filters it, read back from the child
process, see ``msk.optimization.opensim_reference.opensim_full_static_optimization``). OpenSim's
time is the wall time of
``AnalyzeTool.run()`` (SO, 92 muscles + 6 pelvis residuals, IPOPT) timed inside the child,
divided by its frames; msk's are best-of-``--repeat`` batch calls after one warm-up.

    .venv/bin/python bench/bench_chain.py

prints its figures (only ``bench/run_all.py`` writes figures into the docs). Targets: ≤ 100 µs
per frame for the chain with the contact, ≤ 10 µs for the contact; ≥ 500× OpenSim's SO per
frame (the rehabilitation-robot lower-limb model paper reports < 2.5 ms per frame for its whole
model as the real-time bound).
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import os
import platform
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from msk.contact.knee import (
    compartment_force_map,
    knee_contact_force,
    plateau_geometry,
    split_medial_lateral,
)
from msk.contact.patella import patellar_tendon
from msk.datasets.opensim_subject01 import load_subject01
from msk.dynamics.inverse import inverse_dynamics
from msk.dynamics.loads import external_loads
from msk.kinematics.ik import kinematics_from_coordinates
from msk.muscles.geometry import geometry_plan, muscle_parameters
from msk.muscles.hill import Thelen2003Curves, rigid_tendon_state
from msk.optimization import TensionInequalities, solve_static_optimization_batch
from msk.optimization.opensim_reference import (
    compare_static_optimization,
    opensim_full_static_optimization,
)

TARGET_US = 100.0
TARGET_CONTACT_US = 10.0
CONTACT = "knee contact force + medial/lateral split"
#: ``[optimization] compartment_nonnegative``'s stages (not in the plain chain's sum): the
#: right knee's rows F_M, F_L ≥ 0 and the SO with them, which replaces the SO in the chain
ROWS = "compartment rows F_M, F_L (affine in f)"
SO_ROWS = "static optimisation with F_M, F_L ≥ 0"
#: ``[contact] patella = "tendon"`` (the default): the contact stage with the quadriceps
#: through the patellar tendon, which replaces the contact in the chain
PATELLA = "knee contact + split through the patellar tendon"
#: stages not in the plain chain's sum
EXTRA = (ROWS, SO_ROWS, PATELLA)
TARGET_RATIO = 500.0


def measure(repeat: int = 5) -> dict[str, Any]:
    """Every stage of the chain and OpenSim's SO on the same states, in one run: per stage the
    min and median wall µs/frame and the min CPU µs/frame of ``repeat`` batch calls after a
    warm-up; OpenSim's wall and CPU µs/frame; the force comparison with OpenSim."""
    s = load_subject01()
    model = s.model
    with tempfile.TemporaryDirectory() as tmp:
        os_ = opensim_full_static_optimization(Path(tmp), model.coordinate_names)
    k0 = kinematics_from_coordinates(os_["time"], os_["q"], model.coordinate_names, cutoff_hz=None)
    kin = dataclasses.replace(k0, q=os_["q"], v=os_["u"], a=os_["udot"])
    loads = external_loads(model, kin, s.plates, threshold_n=0.0)  # as OpenSim: every load
    params = muscle_parameters(model)
    curves = Thelen2003Curves.gait2392()
    plan = geometry_plan(model)
    n = kin.n_frames

    def stage_id():
        return inverse_dynamics(model, kin, loads)

    def stage_geometry():
        # with the knee's unit wrenches ∂l/∂ξ for the contact stage (same pass)
        g = plan.evaluate(kin.q, kin.v, distal_wrench_joints=("knee_r",))
        return g, rigid_tendon_state(params, g.lengths, g.velocities, curves=curves)

    jt = stage_id()
    geom, state = stage_geometry()
    root = jt.root_coordinates
    reserves = np.array([1.0 if c in root else 0.0 for c in jt.coordinate_names])

    def stage_so():
        return solve_static_optimization_batch(
            geom.jacobian, jt.tau, f_active=state.max_active_force_along_tendon,
            activation_min=0.01, activation_max=1.0, reserve_optimal_force=reserves,
            muscle_names=params.names, coordinate_names=jt.coordinate_names, compute_kkt=False,
        )  # fmt: skip

    sol = stage_so()

    def stage_contact():
        c = knee_contact_force(
            model, kin, loads, muscle_forces=sol, joint="knee_r",
            distal_wrenches=geom.distal_wrenches["knee_r"],
        )  # fmt: skip
        return split_medial_lateral(c)

    geo = plateau_geometry(model, joint="knee_r")
    tendon = patellar_tendon(model, joint="knee_r")
    knee_jac = np.asarray(geom.jacobian)[:, :, model.coordinate_index(tendon.coordinate)]

    def stage_patella():
        c = knee_contact_force(
            model, kin, loads, muscle_forces=sol, joint="knee_r",
            distal_wrenches=geom.distal_wrenches["knee_r"], patella=tendon,
            knee_jacobian=knee_jac,
        )  # fmt: skip
        return split_medial_lateral(c)

    def stage_rows():
        cm = compartment_force_map(
            model, kin, loads, joint="knee_r", geometry=geo,
            distal_wrenches=geom.distal_wrenches["knee_r"],
        )  # fmt: skip
        d = geo.intercondylar_distance_m
        return TensionInequalities(d * cm.offset, d * cm.gain, ("medial", "lateral"), 1.0)

    rows = stage_rows()

    def stage_so_rows():
        return solve_static_optimization_batch(
            geom.jacobian, jt.tau, f_active=state.max_active_force_along_tendon,
            activation_min=0.01, activation_max=1.0, reserve_optimal_force=reserves,
            muscle_names=params.names, coordinate_names=jt.coordinate_names, compute_kkt=False,
            inequalities=rows,
        )  # fmt: skip

    stages = {"inverse dynamics": stage_id, "geometry + f_active": stage_geometry,
              "static optimisation": stage_so,
              "knee contact force + medial/lateral split": stage_contact,
              ROWS: stage_rows, SO_ROWS: stage_so_rows, PATELLA: stage_patella}  # fmt: skip
    best: dict[str, float] = {}
    median: dict[str, float] = {}
    cpu: dict[str, float] = {}
    for name, fn in stages.items():
        fn()
        walls, c = [], np.inf
        for _ in range(repeat):
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            walls.append(time.perf_counter() - t0)
            c = min(c, time.process_time() - c0)
        best[name] = min(walls) / n * 1e6
        median[name] = float(np.median(walls)) / n * 1e6
        cpu[name] = c / n * 1e6
    floor = measure_floor(model, kin.q, geom.jacobian, jt.tau, state.max_active_force_along_tendon,
                          reserves, repeat)  # fmt: skip
    ms = {"forces": sol.forces, "activations": sol.activations, "muscle_names": params.names,
          "f_active": state.max_active_force_along_tendon}  # fmt: skip
    return {"n": n, "stages": list(stages), "best": best, "median": median, "cpu": cpu,
            "opensim_us": os_["per_frame_s"] * 1e6, "opensim_cpu_us": os_["per_frame_cpu_s"] * 1e6,
            "compare": compare_static_optimization(ms, os_), "repeat": repeat,
            "floor": floor}  # fmt: skip


def measure_floor(
    model: Any,
    q: np.ndarray,
    jac: np.ndarray,
    tau: np.ndarray,
    f_active: np.ndarray,
    reserves: np.ndarray,
    repeat: int,
) -> dict[str, float]:
    """The physical floor of the chain per frame (µs: wall min, median, CPU min over
    ``repeat`` passes after a warm-up): Pinocchio's kinematics of the frame
    (``computeJointJacobians``: every joint's placement and Jacobian) and one cold DAQP solve of
    a QP of the static optimisation's size (the muscles' activations and one reserve per
    coordinate, ``min Σa² s.t. Σ_j R_ij F_j a_j + r_i = τ_i, 0.01 ≤ a ≤ 1``; one workspace
    warm-started from frame to frame), frame by frame in a Python loop: what any per-frame
    chain on these libraries pays at least."""
    import daqp
    import pinocchio as pin

    pm, data = model.pin_model, model.create_data()
    n_frames, n_m = f_active.shape
    n_c = tau.shape[1]
    qp = [model.coupling.q(q[k]) for k in range(n_frames)]
    arms = -np.asarray(jac)  # moment arms r = −∂l/∂θ, (N, muscles, coordinates)
    opt = np.where(reserves > 0, 1.0, 100.0)  # reserve optimal forces (N·m per unit)
    h = np.eye(n_m + n_c)
    f = np.zeros(n_m + n_c)
    lo = np.concatenate([np.full(n_m, 0.01), np.full(n_c, -1e6), tau[0]])
    hi = lo.copy()
    hi[:n_m] = 1.0
    hi[n_m : n_m + n_c] = 1e6
    sense = np.concatenate([np.zeros(n_m + n_c), np.full(n_c, 5)]).astype(np.int32)
    a_rows = [np.hstack([(arms[k] * f_active[k][:, None]).T, np.diag(opt)])
              for k in range(n_frames)]  # fmt: skip

    def one_pass() -> int:
        # one DAQP workspace carried from frame to frame (its working set warm), as msk's SO
        qpm = daqp.Model()
        qpm.settings = {"primal_tol": 1e-10}
        ok = 0
        for k in range(n_frames):
            pin.computeJointJacobians(pm, data, qp[k])
            lo[n_m + n_c :] = hi[n_m + n_c :] = tau[k]
            if k == 0:
                qpm.setup(h, f, a_rows[k], hi, lo, sense)
            else:
                qpm.update(A=a_rows[k], bupper=hi, blower=lo)
            _, _, flag, _ = qpm.solve()
            ok += flag > 0
        return ok

    solved = one_pass()
    walls, c = [], np.inf
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        one_pass()
        walls.append(time.perf_counter() - t0)
        c = min(c, time.process_time() - c0)
    return {"best": min(walls) / n_frames * 1e6, "median": float(np.median(walls)) / n_frames * 1e6,
            "cpu": c / n_frames * 1e6, "solved": solved, "frames": n_frames,
            "size": (n_m + n_c, n_c)}  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    r = measure(args.repeat)
    n, stages, best, cpu = r["n"], r["stages"], r["best"], r["cpu"]
    med = r["median"]
    plain = [k for k in stages if k not in EXTRA]
    chain, chain_med, chain_cpu = (sum(d[k] for k in plain) for d in (best, med, cpu))
    chain_p = [c_ + d[PATELLA] - d[CONTACT] for c_, d in zip((chain, chain_med, chain_cpu),
                                                          (best, med, cpu))]  # fmt: skip
    so = "static optimisation"
    with_rows = [d[ROWS] + d[SO_ROWS] - d[so] for d in (best, med, cpu)]
    chain_r = chain + with_rows[0]
    os_us, os_cpu, c = r["opensim_us"], r["opensim_cpu_us"], r["compare"]
    so_ratio = os_cpu / cpu["static optimisation"]
    keep = c["keep"]
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    lines = [
        f"Latest run ({datetime.date.today().isoformat()}, {platform.machine()}, "
        f"{os.cpu_count()} cores shared with other jobs, load average {load[0]:.1f} / "
        f"{load[1]:.1f} / {load[2]:.1f} (1/5/15 min); Python {platform.python_version()}, numpy "
        f"{np.__version__}): gait2392 subject01 walk, {n} frames, 92 muscles × 23 coordinates "
        f"(+ 6 pelvis residuals), {r['repeat']} repeats after a warm-up.",
        "",
        "| stage | msk µs/frame: wall min | wall median | CPU min |",
        "| --- | --- | --- | --- |",
    ]
    for k in stages:
        lines.append(f"| {k} | {best[k]:,.1f} | {med[k]:,.1f} | {cpu[k]:,.1f} |")
    lines += [
        f"| **chain: ID + geometry + SO + contact** | **{chain:,.0f}** | {chain_med:,.0f} | "
        f"{chain_cpu:,.0f} |",
        f"| **chain with `compartment_nonnegative`: ID + geometry + rows + SO with them + "
        f"contact** | **{chain_r:,.0f}** | {chain_med + with_rows[1]:,.0f} | "
        f"{chain_cpu + with_rows[2]:,.0f} |",
        f'| **chain with the patellar tendon (`[contact] patella = "tendon"`)** | '
        f"**{chain_p[0]:,.0f}** | {chain_p[1]:,.0f} | {chain_p[2]:,.0f} |",
        f"| OpenSim 4.6 StaticOptimization (AnalyzeTool.run, same states) | {os_us:,.0f} | | "
        f"{os_cpu:,.0f} |",
        "",
        f"- OpenSim SO / msk SO per frame: **{so_ratio:,.0f}×** CPU, "
        f"{os_us / best['static optimisation']:,.0f}× wall; OpenSim SO / msk whole chain: "
        f"{os_cpu / chain_cpu:,.0f}× CPU, {os_us / chain:,.0f}× wall (the machine is "
        "shared: wall times vary by 2–3× between runs, CPU times much less).",
        f"- Same run, forces: median relative RMS {np.median(c['relative_rms'][keep]):.4f} of "
        f"each muscle's peak over the {keep.sum()} muscles OpenSim does not saturate "
        f"({c['not_converged_times'].size} frames where OpenSim's Σa² is > 1 % above msk's "
        f"left out; OpenSim at its default tolerance).",
        f"- `compartment_nonnegative` (the knee's rows in its leg's sub-problem): "
        f"SO with the rows / SO without, same run: "
        f"{best[SO_ROWS] / best[so]:.2f} (wall min), {med[SO_ROWS] / med[so]:.2f} (median); "
        f"with the rows' construction {with_rows[0]:+.1f} µs/frame on the chain (wall min).",
        f"- Patellar tendon: chain with it / without it {chain_p[0] / chain:.3f} (wall min; "
        f"median {chain_p[1] / chain_med:.3f}, CPU {chain_p[2] / chain_cpu:.3f}); contact "
        f"stage {best[PATELLA]:.1f} against {best[CONTACT]:.1f} µs/frame; target ≤ "
        f"{TARGET_US:.0f} µs/frame for the chain with it: "
        + ("met." if chain_p[0] <= TARGET_US else f"**not met** ({chain_p[0]:,.0f} µs)."),
        f"- Chain target ≤ {TARGET_US:.0f} µs/frame (wall min): "
        + ("met" if chain <= TARGET_US else f"**not met** ({chain:,.0f} µs)")
        + ", with the compartment rows "
        + ("met." if chain_r <= TARGET_US else f"**not met** ({chain_r:,.0f} µs).")
        + f" Ratio target ≥ {TARGET_RATIO:.0f}× (SO vs SO, CPU): "
        + ("met." if so_ratio >= TARGET_RATIO else f"**not met** ({so_ratio:,.0f}×).")
        + f" Contact ≤ {TARGET_CONTACT_US:.0f} µs/frame: "
        + ("met." if best[CONTACT] <= TARGET_CONTACT_US else "**not met**."),
        "- The real-time bound of the rehabilitation-robot lower-limb model paper (2.5 ms per "
        "frame for its whole model): " + ("met." if chain < 2500 else "not met."),
    ]
    text = "\n".join(lines)
    print(text)


if __name__ == "__main__":
    main()
