"""Muscle geometry per frame: lengths + Jacobians ∂l/∂θ of the lower-limb muscles, msk vs OpenSim.

Models: the scaled gait2392 of the OpenSim subject01 example (86 lower-limb muscles, via,
conditional and moving points) and Rajagopal 2016 (80 muscles, 46 cylinder wraps); frames:
the subject01 walk IK (211 frames, OpenSim's ``OutputReference``; Rajagopal takes the
coordinates it shares by name). msk computes, for the whole trial in one call, every length and
the full Jacobian (every muscle × every coordinate). OpenSim 4.6 (child process, timed inside it)
computes ``getLength`` + ``computeMomentArm`` of each muscle about the 7 coordinates of its own
leg (hip ×3, knee, ankle, subtalar, mtp) on a subset of frames — fewer outputs than msk.

    .venv/bin/python bench/bench_geometry.py               # print
    .venv/bin/python bench/bench_geometry.py --baseline 98101f1  # also time that revision's
                                                                 # geometry.py, same run

Only ``bench/run_all.py`` writes figures into the docs. **Target: < 60 µs per frame for the 86
gait2392 lower-limb muscles.**
"""

from __future__ import annotations

import argparse
import datetime
import importlib.util
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from msk._runtime.opensim_peer import POSE_PRELUDE, opensim_available, run_opensim_script
from msk.datasets.shared import reference_dir, shared_dir
from msk.model.core import Model
from msk.muscles.geometry import GeometryPlan

SECTION = "## Muscle geometry"
PEER = shared_dir() / "tools" / "opensim-peer" / "data"
GAIT2392 = PEER / "Pipelines/Gait2392_Simbody/OutputReference/subject01_simbody.osim"
IK = PEER / "Pipelines/Gait2392_Simbody/OutputReference/subject01_walk1_ik.mot"
RAJAGOPAL = reference_dir() / "opensim-models" / "Rajagopal2016.osim"
TRUNK = ("ercspn", "intobl", "extobl")
LEG = ("hip_flexion", "hip_adduction", "hip_rotation", "knee_angle", "ankle_angle",
       "subtalar_angle", "mtp_angle")  # fmt: skip

OPENSIM_TIMING = (
    POSE_PRELUDE
    + """
muscles = [m.getMuscles().get(n) for n in ARGS["muscles"]]
own = [[cs.get(n) for n in names] for names in ARGS["own_coords"]]
L, R = [], []
t0, c0 = time.perf_counter(), time.process_time()
for q in ARGS["q"]:
    set_pose(q)
    L.append([mu.getLength(s) for mu in muscles])
    R.append([[mu.computeMomentArm(s, c) for c in cl] for mu, cl in zip(muscles, own)])
RESULT["seconds"] = time.perf_counter() - t0
RESULT["cpu_seconds"] = time.process_time() - c0
RESULT["L"] = L
RESULT["R"] = R
RESULT["calls"] = len(ARGS["q"]) * sum(1 + len(c) for c in ARGS["own_coords"])
"""
)


def lower_limb(model: Model) -> Model:
    return model.with_muscles([m for m in model.muscles if not m.name.startswith(TRUNK)])


def walk(model: Model, source: Model) -> np.ndarray:
    """The subject01 IK (degrees → rad) in ``model``'s coordinate order (shared names)."""
    lines = IK.read_text().splitlines()
    end = next(i for i, ln in enumerate(lines) if ln.strip().lower() == "endheader")
    head = lines[end + 1].split("\t")
    data = np.array([[float(v) for v in ln.split()] for ln in lines[end + 2 :] if ln.strip()])
    th = np.tile(model.default_coordinates(), (data.shape[0], 1))
    for i, c in enumerate(model.coordinates):
        if c.name in head:
            col = data[:, head.index(c.name)]
            th[:, i] = np.deg2rad(col) if c.kind == "rotational" else col
    del source
    return th


def best_time(fn, repeat: int, clock=time.perf_counter) -> float:
    """Best of ``repeat`` runs after a warm-up (wall clock, or ``time.process_time``: CPU time,
    less sensitive to the other jobs on a shared machine)."""
    fn()
    best = np.inf
    for _ in range(repeat):
        t0 = clock()
        fn()
        best = min(best, clock() - t0)
    return best


def baseline_plan_class(rev: str) -> type:
    """``GeometryPlan`` of msk/muscles/geometry.py at git revision ``rev`` (``git show``,
    read-only), imported as a separate module so that both can be timed in the same run."""
    root = Path(__file__).resolve().parent.parent
    src = subprocess.run(
        ["git", "show", f"{rev}:msk/muscles/geometry.py"],
        cwd=root,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    path = Path(tempfile.mkdtemp()) / "geometry_baseline.py"
    path.write_text(src)
    spec = importlib.util.spec_from_file_location("msk_geometry_baseline", path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod.GeometryPlan


def bench_model(
    path: Path, label: str, *, repeat: int, osim_frames: int, baseline: type | None = None
) -> dict:
    from msk.model.osim import load_osim

    model = lower_limb(load_osim(path))
    th = walk(model, model)
    t0 = time.perf_counter()
    plan = GeometryPlan(model)
    t_plan = time.perf_counter() - t0
    t_batch = best_time(lambda: plan.evaluate(th), repeat)
    t_cpu = best_time(lambda: plan.evaluate(th), repeat, time.process_time)
    t_one = best_time(lambda: plan.evaluate(th[100:101]), repeat * 5)
    t_one_cpu = best_time(lambda: plan.evaluate(th[100:101]), repeat * 5, time.process_time)
    extra = {}
    if baseline is not None:
        old = baseline(model)
        rep = max(3, repeat // 2)
        ref, new = old.evaluate(th), plan.evaluate(th)
        extra = {
            "base_us_per_frame": 1e6 * best_time(lambda: old.evaluate(th), rep) / th.shape[0],
            "base_cpu_us_per_frame": 1e6
            * best_time(lambda: old.evaluate(th), rep, time.process_time)
            / th.shape[0],
            "base_us_single_frame": 1e6 * best_time(lambda: old.evaluate(th[100:101]), rep * 5),
            "base_dl": float(np.abs(new.lengths - ref.lengths).max()),
            "base_dj": float(np.abs(new.jacobian - ref.jacobian).max()),
        }
    row = {
        "label": label,
        "muscles": len(model.muscles),
        "coords": model.n_coords,
        "wraps": len(plan.wraps),
        "frames": th.shape[0],
        "plan_ms": 1e3 * t_plan,
        "us_per_frame": 1e6 * t_batch / th.shape[0],
        "cpu_us_per_frame": 1e6 * t_cpu / th.shape[0],
        "us_single_frame": 1e6 * t_one,
        "cpu_us_single_frame": 1e6 * t_one_cpu,
        **extra,
    }
    if opensim_available():
        sel = np.linspace(0, th.shape[0] - 1, osim_frames).astype(int)
        own = [[f"{c}_{m.name[-1]}" for c in LEG] for m in model.muscles]
        out = run_opensim_script(
            OPENSIM_TIMING,
            model=str(path),
            coords=list(model.coordinate_names),
            q=th[sel].tolist(),
            muscles=[m.name for m in model.muscles],
            own_coords=own,
        )
        geo = plan.evaluate(th[sel])
        own_idx = [[model.coordinate_index(c) for c in cl] for cl in own]
        arms = np.stack([geo.moment_arms[:, i, own_idx[i]] for i in range(len(own))], axis=1)
        dl = np.abs(geo.lengths - np.asarray(out["L"])).max(axis=0)
        dr = np.abs(arms - np.asarray(out["R"])).max(axis=(0, 2))
        n_wraps = np.array([len(m.wraps) for m in model.muscles])
        for key, sel_ in (("via", n_wraps == 0), ("wrap1", n_wraps == 1), ("wrap2", n_wraps > 1)):
            if sel_.any():
                k = int(np.argmax(np.where(sel_, np.maximum(dl, dr), -1.0)))
                row[f"worst_{key}"] = (model.muscles[k].name, dl[k], dr[k])
        row["osim_us_per_frame"] = 1e6 * out["seconds"] / sel.size
        row["osim_cpu_us_per_frame"] = 1e6 * out["cpu_seconds"] / sel.size
        row["osim_calls_per_frame"] = out["calls"] // sel.size
        row["ratio"] = row["osim_us_per_frame"] / row["us_per_frame"]
    return row


def markdown(rows: list[dict], baseline: str | None = None) -> str:
    load = os.getloadavg()[0]
    when = datetime.date.today().isoformat()
    lines = [
        SECTION,
        "",
        "`.venv/bin/python bench/bench_geometry.py`: lengths + full Jacobians "
        "∂l/∂θ (`msk.muscles.geometry.GeometryPlan.evaluate`) over the subject01 walk IK "
        "(211 frames, one batch call), best of repeated runs after a warm-up; OpenSim 4.6 "
        "`getLength` + `computeMomentArm` about the 7 coordinates of each muscle's own leg, "
        "timed inside the child process on evenly spaced frames of the same trial.",
        "",
        "**Target: < 60 µs per frame for the 86 gait2392 lower-limb muscles.**",
        "",
        f"<!-- bench_geometry:figures -->\nLatest run ({when}, {platform.machine()}, "
        f"{os.cpu_count()} cores shared with other jobs, load average {load:.1f}; "
        f"Python {platform.python_version()}, numpy {np.__version__}):",
        "",
        "| model | muscles × coords (wraps) | plan build | msk µs/frame, batch: wall (CPU) | msk "
        "µs, 1-frame call: wall (CPU) | OpenSim µs/frame: wall (CPU) [calls/frame] | "
        "OpenSim / msk, wall |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        osim = (
            f"{r['osim_us_per_frame']:,.0f} ({r['osim_cpu_us_per_frame']:,.0f}) "
            f"[{r['osim_calls_per_frame']}]"
            if "ratio" in r
            else "n/a"
        )
        ratio = f"{r['ratio']:,.0f}×" if "ratio" in r else "n/a"
        lines.append(
            f"| {r['label']} | {r['muscles']} × {r['coords']} ({r['wraps']}) | "
            f"{r['plan_ms']:.0f} ms | {r['us_per_frame']:,.0f} ({r['cpu_us_per_frame']:,.0f}) | "
            f"{r['us_single_frame']:,.0f} ({r['cpu_us_single_frame']:,.0f}) | "
            f"{osim} | {ratio} |"
        )
    if baseline and "base_us_per_frame" in rows[0]:
        lines += [
            "",
            f"Same run, the previous implementation (`geometry.py` of `{baseline}`, "
            "`--baseline`), and the largest difference of this one's results from it:",
            "",
        ]
        for r in rows:
            lines.append(
                f"- {r['label']}: batch {r['base_us_per_frame']:,.0f} "
                f"({r['base_cpu_us_per_frame']:,.0f}) µs/frame → {r['us_per_frame']:,.0f} "
                f"({r['cpu_us_per_frame']:,.0f}), "
                f"{r['base_us_per_frame'] / r['us_per_frame']:.1f}× faster; 1-frame call "
                f"{r['base_us_single_frame']:,.0f} µs → {r['us_single_frame']:,.0f} µs; "
                f"|Δl| ≤ {r['base_dl']:.1e} m, |ΔJ| ≤ {r['base_dj']:.1e} m/rad"
            )
    lines += [
        "",
        "Agreement with OpenSim 4.6 on the same frames (max over frames; moment arms about "
        "each muscle's own-leg coordinates), worst muscle:",
        "",
    ]
    for r in rows:
        for key, what in (
            ("worst_via", "via-point muscles"),
            ("worst_wrap1", "one wrap cylinder"),
            ("worst_wrap2", "two wrap cylinders"),
        ):
            if key in r:
                n, dl, dr = r[key]
                lines.append(f"- {r['label']}, {what}: `{n}` length {dl * 1e3:.2g} mm, "
                             f"moment arm {dr * 1e3:.2g} mm")  # fmt: skip
    g = rows[0]["us_per_frame"]
    lines += [
        "",
        (
            "Target met."
            if g < 60
            else f"Target **not** met on this run ({g:.0f} µs/frame wall, "
            f"{rows[0]['cpu_us_per_frame']:.0f} µs CPU)."
        ),
        "<!-- bench_geometry:figures -->",
        "",
        "Reading the wrap figures. With one cylinder msk's path is the exact geodesic "
        "(tangent points from the developed cylinder; tests/muscles/test_wrapping.py checks "
        "it against a constrained numerical minimisation); OpenSim 4.6 places the tangent-"
        "point heights by a plane-intersection approximation and skips its tangency iteration"
        " for a single wrap, so its lengths are never shorter than msk's and exceed them by "
        "up to ~1 mm in deep knee flexion (gracilis, semitendinosus), with moment arms up to "
        "~8 mm apart there. With two cylinders on one path (the gastrocnemii: condyles + "
        "shank) OpenSim re-wraps at most 8 times and stops at 0.5 mm of length change; its "
        "path can then enter the shank cylinder (the incoming segment is not tangent), and at"
        " one frame of the left leg it jumps to a 0.68 m path (neighbouring frames ~0.46 m). "
        "msk iterates the wraps to convergence (tangent points still to 1e-12 m), which the "
        "analytic Jacobian needs (envelope theorem): 17–30 plain passes over the two "
        "gastrocnemius wraps for most frames, 10–18 with Aitken's Δ² extrapolation after "
        "every other pass (convergence is still judged on a plain pass, so the fixed point is"
        " the same). The 0.2 m gastrocnemius figure above is OpenSim's jump at frame 165 "
        "(0.676 m; msk 0.453 m). At 7 of the 211 frames (31, 92, 105, 165, 178 left, 129, 142"
        " right) the condyle and shank cylinders of a gastrocnemius overlap: a tangent point "
        "of one wrap lies inside the other cylinder, which refuses that wrap, and the shank "
        "wrap then jumps to the segment before the condyles and goes round the long way "
        "(quadrant −y), so the wrap rules admit no consistent path and the iteration "
        "alternates between a ~0.47 m and a ~0.72 m path (a 2-cycle; msk used to return the "
        "state its pass limit landed on, 0.72 m at six of these frames). msk now resolves "
        "such a cycle among candidate topologies, each iterated to its own fixed point so "
        "that the Jacobian stays exact: one wrap off, the others free; the shortest "
        "admissible one (the wrap left off wraps nothing at the fixed point), else the "
        "converged one that loses least length. At these frames that is the shank wrap alone,"
        " 0.451–0.459 m, between the neighbouring frames' lengths (largest change between "
        "neighbouring frames along the walk, all 80 muscles: 1.9 cm; it was 27 cm); OpenSim "
        "gives 0.430–0.438 m at six of them and its 0.676 m jump at frame 165.",
        "",
        "Where the time goes (gait2392, 211 frames, in chunks of ~50 frames so that the "
        "temporaries stay in cache and need no fresh pages): forward kinematics of the 27 "
        "Pinocchio joints and their Jacobians, batched over frames (a few frames: Pinocchio's "
        "own pass, frame by frame); the coupling functions and moving points as one spline "
        "table; the path points through one sparse product; then the segment unit lines "
        "(u, x × u) of the segments that cross a joint, summed into the (muscle, crossed "
        "coordinate) rows by a sparse map fixed at plan time, and one dot product with the "
        "twists per row (no dense muscle × DOF products, no G product). With wraps "
        "(Rajagopal) the wraps of all paths are applied in rounds (the r-th wrap of every "
        "path at once); the two-wrap fixed-point iteration is still about half of the time.",
        "",
    ]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--osim-frames", type=int, default=20)
    ap.add_argument("--baseline", metavar="REV", help="also time geometry.py of this git revision")
    args = ap.parse_args()
    base = baseline_plan_class(args.baseline) if args.baseline else None
    rows = [
        bench_model(GAIT2392, "gait2392 subject01", repeat=args.repeat,
                    osim_frames=args.osim_frames, baseline=base),
        bench_model(RAJAGOPAL, "Rajagopal 2016", repeat=args.repeat,
                    osim_frames=args.osim_frames, baseline=base),
    ]  # fmt: skip
    text = markdown(rows, args.baseline)
    print(text)


if __name__ == "__main__":
    main()
