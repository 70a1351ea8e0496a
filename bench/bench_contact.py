"""Knee contact force on gait2392 (92 muscles), subject01 walk: the former route (RNEA per frame,
a path evaluation per pair of unit twists, a forward-kinematics pass per frame) against the
vectorised one (``msk.contact.knee.knee_contact_force`` with the unit wrenches ∂l/∂ξ of the geometry
stage), both with the medial/lateral split, and the whole chain ID + geometry + SO + contact,
in µs per frame, all measured in the same run (their ratios are what to compare: on the shared
machine absolute times move ×2–3 with the load).

Data: subject01 walking of the OpenSim peer (``shared/tools/opensim-peer/data``), its IK
filtered at 6 Hz, 0.5–2.5 s, plate loads; static-optimisation forces by msk (no OpenSim here).
Each stage is a batch call over the trial, one warm-up then ``--repeat`` timed calls; min and
median are reported.

    .venv/bin/python bench/bench_contact.py

prints its figures (only ``bench/run_all.py`` writes figures into the docs). Target: ≤ 10 µs per
frame for the contact stage, medial/lateral split included.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from msk.contact.knee import (
    KneeContact,
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
from tests.support.legacy_contact import legacy_knee_contact_force

TARGET_US = 10.0
JOINT = "knee_r"


def timings(fn: Callable[[], Any], repeat: int, n: int) -> tuple[float, float]:
    """(min, median) wall µs per frame of ``repeat`` calls after one warm-up."""
    fn()
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return min(ts) / n * 1e6, float(np.median(ts)) / n * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=15)
    args = ap.parse_args()

    s = load_subject01()
    model = s.model
    sel = (s.ik_time >= 0.5) & (s.ik_time <= 2.5)
    kin = kinematics_from_coordinates(
        s.ik_time[sel], s.ik_q[sel], model.coordinate_names, cutoff_hz=6.0
    )
    loads = external_loads(model, kin, s.plates, threshold_n=0.0)
    params = muscle_parameters(model)
    curves = Thelen2003Curves.gait2392()
    plan = geometry_plan(model)
    geo = plateau_geometry(model, joint=JOINT)
    n = kin.n_frames

    def stage_id() -> Any:
        return inverse_dynamics(model, kin, loads)

    def stage_geometry(joints: tuple[str, ...] = (JOINT,)) -> Any:
        g = plan.evaluate(kin.q, kin.v, distal_wrench_joints=joints)
        return g, rigid_tendon_state(params, g.lengths, g.velocities, curves=curves)

    jt = stage_id()
    geom, state = stage_geometry()
    reserves = np.array([1.0 if c in jt.root_coordinates else 0.0 for c in jt.coordinate_names])

    def stage_so() -> Any:
        return solve_static_optimization_batch(
            geom.jacobian, jt.tau, f_active=state.max_active_force_along_tendon,
            activation_min=0.01, activation_max=1.0, reserve_optimal_force=reserves,
            muscle_names=params.names, coordinate_names=jt.coordinate_names, compute_kkt=False,
        )  # fmt: skip

    sol = stage_so()
    forces = np.nan_to_num(sol.forces)
    wrenches = geom.distal_wrenches[JOINT]

    def contact_old() -> Any:
        f, m = legacy_knee_contact_force(model, kin, loads, muscle_forces=forces, joint=JOINT)
        c = KneeContact(kin.time, JOINT, "tibia_r", f, m, np.zeros((n, 5)), 1.0, True)
        return split_medial_lateral(c, geo)

    def contact_new() -> Any:
        c = knee_contact_force(
            model, kin, loads, muscle_forces=forces, joint=JOINT, distal_wrenches=wrenches
        )
        return split_medial_lateral(c, geo)

    tendon = patellar_tendon(model, joint=JOINT)
    knee_jac = np.asarray(geom.jacobian)[:, :, model.coordinate_index(tendon.coordinate)]

    def contact_patella() -> Any:
        c = knee_contact_force(
            model, kin, loads, muscle_forces=forces, joint=JOINT, distal_wrenches=wrenches,
            patella=tendon, knee_jacobian=knee_jac,
        )  # fmt: skip
        return split_medial_lateral(c, geo)

    def contact_alone() -> Any:
        c = knee_contact_force(model, kin, loads, muscle_forces=forces, joint=JOINT, plan=plan)
        return split_medial_lateral(c, geo)

    def rows() -> TensionInequalities:
        cm = compartment_force_map(
            model, kin, loads, joint=JOINT, geometry=geo, distal_wrenches=wrenches
        )
        d = geo.intercondylar_distance_m
        return TensionInequalities(
            d * cm.offset, d * cm.gain, ("medial", "lateral"), 1.0
        )  # fmt: skip

    ineq = rows()

    def stage_so_rows() -> Any:
        return solve_static_optimization_batch(
            geom.jacobian, jt.tau, f_active=state.max_active_force_along_tendon,
            activation_min=0.01, activation_max=1.0, reserve_optimal_force=reserves,
            muscle_names=params.names, coordinate_names=jt.coordinate_names, compute_kkt=False,
            inequalities=ineq,
        )  # fmt: skip

    a, b = contact_old(), contact_new()
    err = max(
        float(np.abs(a.medial - b.medial).max()), float(np.abs(a.lateral - b.lateral).max())
    ) / float(np.abs(a.normal).max())

    stages: dict[str, Callable[[], Any]] = {
        "knee contact + split, former route (RNEA, twist paths)": contact_old,
        "knee contact + split, from the geometry stage's ∂l/∂ξ": contact_new,
        "knee contact + split, own geometry pass (no ∂l/∂ξ given)": contact_alone,
        "inverse dynamics": stage_id,
        "geometry + f_active": lambda: stage_geometry(()),
        "geometry + f_active + knee ∂l/∂ξ": stage_geometry,
        "static optimisation": stage_so,
        "compartment rows F_M, F_L (affine in f, from ∂l/∂ξ)": rows,
        "static optimisation with F_M, F_L ≥ 0 (rows given)": stage_so_rows,
        "knee contact + split through the patellar tendon (msk.contact.patella)": contact_patella,
    }
    res = {k: timings(fn, args.repeat, n) for k, fn in stages.items()}
    names = list(stages)
    old, new = res[names[0]], res[names[1]]
    chain_keys = ("inverse dynamics", "geometry + f_active + knee ∂l/∂ξ", "static optimisation")
    chain = [sum(res[k][i] for k in chain_keys) for i in (0, 1)]
    chain_c = [chain[i] + new[i] for i in (0, 1)]
    chain_o = [chain[i] + old[i] for i in (0, 1)]
    so, rows_t, so_rows = res[names[6]], res[names[7]], res[names[8]]
    chain_r = [chain_c[i] + rows_t[i] + so_rows[i] - so[i] for i in (0, 1)]
    pat = res[names[9]]
    chain_p = [chain[i] + pat[i] for i in (0, 1)]
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    lines = [
        f"Latest run ({datetime.date.today().isoformat()}, {platform.machine()}, "
        f"{os.cpu_count()} cores shared with other jobs, load average {load[0]:.1f} / "
        f"{load[1]:.1f} / {load[2]:.1f} (1/5/15 min); Python {platform.python_version()}, numpy "
        f"{np.__version__}): gait2392 subject01 walk, {n} frames, 92 muscles, `{JOINT}`, "
        f"{args.repeat} repeats after a warm-up.",
        "",
        "| stage | µs/frame: min | median |",
        "| --- | --- | --- |",
    ]
    for k in names:
        lines.append(f"| {k} | {res[k][0]:,.1f} | {res[k][1]:,.1f} |")
    lines += [
        f"| **chain: ID + geometry (with ∂l/∂ξ) + SO + contact** | **{chain_c[0]:,.0f}** | "
        f"{chain_c[1]:,.0f} |",
        f"| chain with the former contact | {chain_o[0]:,.0f} | {chain_o[1]:,.0f} |",
        f"| chain with the contact through the patellar tendon | {chain_p[0]:,.0f} | "
        f"{chain_p[1]:,.0f} |",
        f"| chain with the compartment rows (rows + SO with them) | {chain_r[0]:,.0f} | "
        f"{chain_r[1]:,.0f} |",
        "",
        f"- Contact stage, former / new: **{old[0] / new[0]:,.0f}×** (min), "
        f"{old[1] / new[1]:,.0f}× (median); the contact is now "
        f"{100 * new[0] / chain_c[0]:.0f} % of the chain "
        f"(the former route: {100 * old[0] / chain_o[0]:.0f} %).",
        f"- ∂l/∂ξ in the geometry pass: {res[names[5]][0] - res[names[4]][0]:+.1f} µs/frame "
        "(min; they are the knee rows of the length Jacobian, gathered).",
        f"- Same run, medial/lateral forces: largest difference {err:.1e} of the peak normal "
        "force between the two routes.",
        f"- `compartment_nonnegative` (each knee's rows "
        "solved in its leg's sub-problem, `_BatchQP.solve_blocks`): the rows cost "
        f"{rows_t[0]:.1f} µs/frame and the QP with them {so_rows[0]:.1f} against "
        f"{so[0]:.1f} µs/frame without (min; ratio {so_rows[0] / so[0]:.2f}, median "
        f"{so_rows[1] / so[1]:.2f}): {rows_t[0] + so_rows[0] - so[0]:+.1f} µs/frame on the "
        f"chain, which is then {chain_r[0]:,.0f} µs/frame (min; median {chain_r[1]:,.0f}).",
        f"- Patellar tendon: the contact stage {pat[0]:.1f} against {new[0]:.1f} µs/frame "
        f"(min; ratio {pat[0] / new[0]:.2f}); the chain with it {chain_p[0]:,.0f} µs/frame, "
        f"ratio to the chain without it {chain_p[0] / chain_c[0]:.3f} (target ≤ 100 µs/frame: "
        + ("met" if chain_p[0] <= 100.0 else "**not met**")
        + ").",
        f"- Target ≤ {TARGET_US:.0f} µs/frame for the contact stage (split included): "
        + ("met" if new[0] <= TARGET_US else "**not met**")
        + f" ({new[0]:.1f} min, {new[1]:.1f} median).",
    ]
    text = "\n".join(lines)
    print(text)


if __name__ == "__main__":
    main()
