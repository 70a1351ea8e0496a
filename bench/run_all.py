"""Every speed figure of README.md and docs/benchmarks.md, in one run, each as a ratio to a
baseline measured in the same run, with the host (CPU model, cores) and the load average.

Baselines, each timed in this run beside what it calibrates:

* **OpenSim 4.6** (the ``opensim`` extra, in a child process,
  :func:`msk._runtime.opensim_peer.run_opensim_script`): inverse kinematics and inverse
  dynamics on the subject01 walk played to ~1,000 frames (``bench_id``), static optimisation on
  the same states (``bench_chain``); skipped, and said so, when OpenSim is not installed;
* **the physical floor**: Pinocchio's kinematics of each frame plus one warm-started DAQP solve
  of the static optimisation's size (``bench_chain.measure_floor``): the whole per-frame chain
  (inverse dynamics + muscle geometry + static optimisation + knee contact, 92 muscles) as a
  multiple of it;
* **the previous commit** (``--baseline REV``, default ``HEAD~1``; its ``msk`` package from
  ``git archive``, imported ahead of the working tree's), timed alternately with the working
  tree: the model stage of a session without a static trial (``pipelines/gc6_DM_og1.toml``,
  ``pipelines/uwa_fast_walking.toml``), ``msk run pipelines/gc5_PS.toml`` cold
  (``--no-cache``) and cached, and ``msk live``'s per-frame chain on gc5 PS and gc6 DM
  (``bench_live``: p50/p99 and the ratio to its frame-by-frame floor), each in a fresh
  interpreter;
* **reading the files alone**: the 20-subject dynamometry cohort through ``msk batch`` (2
  workers) and in one process, as a multiple of reading its 20 × 4 files (``bench_cohort``).

Absolute times are printed only beside the host line they were measured on; on a shared
machine only the ratios of one run compare.

    .venv/bin/python bench/run_all.py [--baseline REV] [--rounds 3] [--skip opensim,chain,...]
        [--write-docs]

``--write-docs`` writes the printed figures into docs/benchmarks.md (between its
``run_all:figures`` markers).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from datetime import date
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs" / "benchmarks.md"
MARK = "<!-- run_all:figures -->"
NO_STATIC = ("gc6_DM_og1", "uwa_fast_walking")
PARTS = ("opensim", "chain", "live", "model", "run", "cohort")

#: the model stage's seconds, in a fresh interpreter with the package of ``sys.argv[1]``
_MODEL_CHILD = """
import io, re, sys
sys.path.insert(0, sys.argv[1])
from msk.pipeline.session import run_stages
buf = io.StringIO()
run_stages(sys.argv[2], until="model", progress=buf)
print(re.search(r"\\]\\s+model\\s+([\\d.]+) s", buf.getvalue()).group(1))
"""


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def host() -> str:
    """The machine: CPU model, cores (and those this process may use), Python, numpy."""
    import numpy as np

    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - no sched_getaffinity
        usable = os.cpu_count() or 1
    return (
        f"{cpu_model()}, {os.cpu_count()} cores ({usable} usable), {platform.machine()}, "
        f"Python {platform.python_version()}, numpy {np.__version__}"
    )


def load() -> str:
    return " / ".join(f"{x:.1f}" for x in os.getloadavg())


class Figures:
    """The printed figures: one line each, and the notes (host, load) they stand beside."""

    def __init__(self) -> None:
        self.rows: list[tuple[str, str, str]] = []  # figure, ratio, detail (absolute times)

    def add(self, figure: str, ratio: str, detail: str) -> None:
        self.rows.append((figure, ratio, detail))
        print(f"  {figure}: {ratio}  ({detail})", flush=True)


def part(name: str, fn: Callable[[], None]) -> None:
    print(f"\n[{name}] load {load()}", flush=True)
    t0 = time.perf_counter()
    fn()
    print(f"[{name}] {time.perf_counter() - t0:.0f} s, load {load()}", flush=True)


def opensim_ik_id(fig: Figures, repeats: int) -> None:
    """msk's IK and ID against OpenSim 4.6's tools on the same files (``bench_id``)."""
    import bench_id
    from _timing import best_of

    from msk._runtime.opensim_peer import opensim_available, run_opensim_script
    from msk.datasets.opensim_subject01 import OPENSIM_IK_ID_SCRIPT, load_subject01
    from msk.dynamics.inverse import inverse_dynamics
    from msk.dynamics.loads import external_loads, plates_from_table
    from msk.kinematics.ik import kinematics_from_coordinates, solve_kinematics

    if not opensim_available():
        print("  OpenSim 4.6 not installed (pip install -e '.[opensim]'): IK/ID ratios skipped")
        return
    s = load_subject01()
    model = s.model
    with tempfile.TemporaryDirectory() as tmp:
        tr = bench_id.build_trial(s, 1000, Path(tmp))
        n = tr["time"].size
        plates = plates_from_table(tr["grf_time"], tr["grf"], tr["grf_columns"])

        def ik() -> Any:
            return solve_kinematics(
                model, tr["markers"], s.marker_labels, tr["time"], weights=s.weights,
                coordinate_tasks=s.coordinate_tasks, cutoff_hz=6.0,
            )  # fmt: skip

        t_ik, kin = best_of(ik, repeats)

        def idyn() -> Any:
            k = kinematics_from_coordinates(
                kin.time, kin.q_raw, kin.coordinate_names, cutoff_hz=6.0
            )
            return inverse_dynamics(model, k, external_loads(model, k, plates))

        t_id, _ = best_of(idyn, max(5, repeats))
        out = run_opensim_script(
            OPENSIM_IK_ID_SCRIPT, pipe=str(s.pipeline), trc=str(tr["trc"]), out=tmp,
            grf=str(tr["mot"]), t0=0.5, t1=tr["t1"], cutoff_hz=6.0, timeout_s=1800,
            ik_repeats=max(1, repeats - 1), id_repeats=5,
        )  # fmt: skip
        # msk again after OpenSim: the best of both sides of the child's run
        t_ik = min(t_ik, best_of(ik, repeats)[0])
        t_id = min(t_id, best_of(idyn, max(5, repeats))[0])
    for name, t_msk, frames, wall in (
        ("IK", t_ik, out["ik_frames"], out["ik_wall_s"]),
        ("ID", t_id, out["id_frames"], out["id_wall_s"]),
    ):
        fps, ofps = n / t_msk, frames / wall
        fig.add(
            f"{name}: msk / OpenSim 4.6, frames per second (subject01 walk, {n} frames)",
            f"{fps / ofps:.0f}×",
            f"msk {1e6 / fps:,.0f} µs/frame, OpenSim {1e6 / ofps:,.0f} µs/frame; best of "
            f"{repeats} (msk) and {max(1, repeats - 1)} (OpenSim IK)",
        )


def chain(fig: Figures, repeats: int) -> None:
    """The per-frame chain, its stages, the floor and OpenSim's static optimisation."""
    import bench_chain

    r = bench_chain.measure(repeats)
    best, cpu, fl = r["best"], r["cpu"], r["floor"]
    plain = [k for k in r["stages"] if k not in bench_chain.EXTRA]
    total = sum(best[k] for k in plain)
    total_cpu = sum(cpu[k] for k in plain)
    so = "static optimisation"
    n = r["n"]
    fig.add(
        f"chain ID + geometry + SO + knee contact (92 muscles, {n} frames) / floor",
        f"{total / fl['best']:.2f}× (CPU {total_cpu / fl['cpu']:.2f}×)",
        f"chain {total:.0f} µs/frame wall min (CPU {total_cpu:.0f}); floor "
        f"{fl['best']:.0f} µs/frame (CPU {fl['cpu']:.0f}): Pinocchio kinematics + one warm "
        f"DAQP solve of {fl['size'][0]} variables × {fl['size'][1]} equalities per frame; "
        + ", ".join(f"{k} {best[k]:.1f}" for k in plain),
    )
    with_pt = total + best[bench_chain.PATELLA] - best[bench_chain.CONTACT]
    fig.add(
        "chain with the patellar tendon / chain without it",
        f"{with_pt / total:.3f}×",
        f"{with_pt:.0f} against {total:.0f} µs/frame wall min (target ≤ 100 with it); contact "
        f"{best[bench_chain.PATELLA]:.1f} against {best[bench_chain.CONTACT]:.1f}",
    )
    fig.add(
        "knee contact + medial/lateral split / floor",
        f"{best[bench_chain.CONTACT] / fl['best']:.3f}×",
        f"{best[bench_chain.CONTACT]:.1f} µs/frame wall min",
    )
    if r.get("opensim_cpu_us"):
        fig.add(
            "static optimisation: OpenSim 4.6 / msk per frame, CPU",
            f"{r['opensim_cpu_us'] / cpu[so]:,.0f}×",
            f"OpenSim {r['opensim_cpu_us']:,.0f} µs CPU ({r['opensim_us']:,.0f} wall), msk "
            f"{cpu[so]:.1f} µs CPU ({best[so]:.1f} wall min)",
        )
        fig.add(
            "whole chain: OpenSim 4.6 SO alone / msk chain per frame, CPU",
            f"{r['opensim_cpu_us'] / total_cpu:,.0f}×",
            "OpenSim's static optimisation against msk's ID + geometry + SO + contact",
        )


def _alternate(variants: dict[str, Callable[[], float]], rounds: int) -> dict[str, list[float]]:
    """``rounds`` rounds of every variant in turn, after one untimed round."""
    got: dict[str, list[float]] = {v: [] for v in variants}
    for k in range(rounds + 1):
        for name, fn in variants.items():
            t = fn()
            if k:
                got[name].append(t)
    return got


def model_stage(fig: Figures, base: Path | None, ref: str, rounds: int) -> None:
    """The model stage of the sessions without a static trial, tree vs the previous commit."""
    for stem in NO_STATIC:
        cfg = REPO / "pipelines" / f"{stem}.toml"

        def run(src: Path, cfg: Path = cfg) -> float:
            out = subprocess.run(
                [sys.executable, "-c", _MODEL_CHILD, str(src), str(cfg)], check=True,
                capture_output=True, text=True, cwd=REPO,
            )  # fmt: skip
            return float(out.stdout.strip().splitlines()[-1])

        variants: dict[str, Callable[[], float]] = {"tree": lambda: run(REPO)}
        if base is not None:
            variants = {ref: lambda: run(base), **variants}
        got = _alternate(variants, rounds)
        mid = {k: statistics.median(v) for k, v in got.items()}
        detail = ", ".join(f"{k} {mid[k]:.2f} s (min {min(got[k]):.2f})" for k in got)
        ratio = f"{mid[ref] / mid['tree']:.2f}× faster" if base is not None else "—"
        fig.add(f"model stage, {stem} (no static trial): {ref} / tree, median of {rounds}",
                ratio, detail)  # fmt: skip


def msk_run(fig: Figures, base: Path | None, ref: str, rounds: int) -> None:
    """``msk run pipelines/gc5_PS.toml`` cold and cached, tree vs the previous commit."""
    import bench_run_cold

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        srcs = {"tree": REPO} if base is None else {ref: base, "tree": REPO}
        for what, cached in (("cold", False), ("cached", True)):
            count = iter(range(10**6))

            shares: list[float] = []

            def run(
                src: Path, name: str, cached: bool = cached, count: Any = count,
                shares: list[float] = shares,
            ) -> float:  # fmt: skip
                out = root / f"{name}_cached" if cached else root / f"{name}_{next(count)}"
                wall, stages = bench_run_cold._run_once(src, out, cached=cached)
                if name == "tree" and not cached and "report" in stages:
                    shares.append(stages["report"] / wall)
                return wall

            variants = {n: (lambda s=s, n=n: run(s, n)) for n, s in srcs.items()}
            got = _alternate(variants, rounds)
            mid = {k: statistics.median(v) for k, v in got.items()}
            detail = ", ".join(f"{k} {mid[k]:.2f} s (min {min(got[k]):.2f})" for k in got)
            ratio = f"{mid[ref] / mid['tree']:.2f}× faster" if base is not None else "—"
            fig.add(f"`msk run` gc5_PS {what}, fresh interpreter: {ref} / tree, median of "
                    f"{rounds}", ratio, detail)  # fmt: skip
            if shares:
                fig.add("report stage / whole cold `msk run` gc5_PS (target: not dominant)",
                        f"{statistics.median(shares):.1%}", f"{len(shares)} runs")  # fmt: skip


def cohort(fig: Figures, repeats: int) -> None:
    """The 20 dynamometry subjects through ``msk batch`` (2 workers) and in one process, as
    ratios to reading their files (``bench_cohort``)."""
    import bench_cohort

    for figure, ratio, detail in bench_cohort.lines(bench_cohort.measure(repeats, 2), 2):
        fig.add(figure, ratio, detail)


def live(fig: Figures, base: Path | None, ref: str, rounds: int) -> None:
    """``msk live``'s per-frame chain (``bench_live``: IK + filter + ID + geometry + SO + knee
    contact, 92 muscles) on gc5 PS and gc6 DM: p50/p99 of the thread's CPU time and its ratio to
    the floor timed frame by frame beside it, tree vs the previous commit alternated, each in a
    fresh interpreter."""
    import json

    def run(src: Path) -> dict[str, dict[str, float]]:
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(src), str(REPO)])}
        out = subprocess.run(
            [sys.executable, str(REPO / "bench" / "bench_live.py"), "--passes", "2", "--json"],
            check=True, capture_output=True, text=True, cwd=REPO, env=env,
        )  # fmt: skip
        rows = [json.loads(x[5:]) for x in out.stdout.splitlines() if x.startswith("JSON ")]
        return {r["session"]: r for r in rows}

    srcs = {"tree": REPO} if base is None else {ref: base, "tree": REPO}
    got: dict[str, list[dict[str, dict[str, float]]]] = {k: [] for k in srcs}
    for _ in range(rounds):
        for name, src in srcs.items():
            got[name].append(run(src))
    for session in got["tree"][0]:
        for name in srcs:
            runs = [r[session] for r in got[name]]
            p50 = statistics.median(r["chain_p50"] for r in runs)
            p99 = statistics.median(r["chain_p99"] for r in runs)
            f50 = statistics.median(r["floor_p50"] for r in runs)
            f99 = statistics.median(r["floor_p99"] for r in runs)
            stages = [k[:-4] for k in runs[0] if k.endswith("_p50") and k[:-4] not in
                      ("chain", "floor", "wall")]  # fmt: skip
            each = ", ".join(
                f"{k} {1e6 * statistics.median(r[k + '_p50'] for r in runs):.0f}" for k in stages
            )
            fig.add(f"`msk live` chain {session} ({name}), CPU / floor, median of {rounds}",
                    f"p50 {p50 / f50:.1f}×, p99 {p99 / f99:.1f}×",
                    f"chain p50 {1e6 * p50:.0f} µs, p99 {1e6 * p99:.0f} µs; floor (FK + one "
                    f"cold DAQP solve) p50 {1e6 * f50:.0f}, p99 {1e6 * f99:.0f}; stages p50 "
                    f"(wall, µs): {each}")  # fmt: skip
        if base is not None:
            old = statistics.median(r[session]["chain_p50"] for r in got[ref])
            new = statistics.median(r[session]["chain_p50"] for r in got["tree"])
            fig.add(f"`msk live` chain {session}: {ref} / tree, p50 CPU", f"{old / new:.2f}×",
                    f"{ref} {1e6 * old:.0f} µs, tree {1e6 * new:.0f} µs")  # fmt: skip


def write_docs(fig: Figures, head: str) -> None:
    lines = [head, "", "| figure | ratio | detail (absolute times on this host) |",
             "| --- | --- | --- |"]  # fmt: skip
    lines += [f"| {a} | {b} | {c} |" for a, b, c in fig.rows]
    text = DOCS.read_text(encoding="utf-8")
    before, _, rest = text.partition(MARK)
    _, _, after = rest.partition(MARK)
    DOCS.write_text(before + MARK + "\n" + "\n".join(lines) + "\n" + MARK + after, "utf-8")
    print(f"wrote {DOCS}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default="HEAD~1", help="git rev of the previous commit")
    ap.add_argument("--rounds", type=int, default=3, help="alternated rounds per comparison")
    ap.add_argument("--repeat", type=int, default=10, help="timed batch calls per chain stage")
    ap.add_argument("--skip", default="", help=f"comma-separated parts: {', '.join(PARTS)}")
    ap.add_argument("--write-docs", action="store_true", help=f"update {DOCS.name}")
    args = ap.parse_args()
    skip = set(filter(None, args.skip.split(",")))
    import bench_run_cold

    rev = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", args.baseline],
                         check=True, capture_output=True, text=True).stdout.strip()  # fmt: skip
    tree = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"],
                          check=True, capture_output=True, text=True).stdout.strip()  # fmt: skip
    head = (f"{date.today().isoformat()}, host: {host()}; load average (1/5/15 min) at the "
            f"start {load()}; tree at {tree} (+ uncommitted changes, if any), previous commit "
            f"{rev} ({args.baseline})")  # fmt: skip
    print(head, flush=True)
    fig = Figures()
    with tempfile.TemporaryDirectory() as tmp:
        base = bench_run_cold._checkout(rev, Path(tmp) / "base")
        if "opensim" not in skip:
            part("opensim", lambda: opensim_ik_id(fig, 3))
        if "chain" not in skip:
            part("chain", lambda: chain(fig, args.repeat))
        if "live" not in skip:
            part("live", lambda: live(fig, base, rev, args.rounds))
        if "model" not in skip:
            part("model", lambda: model_stage(fig, base, rev, args.rounds))
        if "run" not in skip:
            part("run", lambda: msk_run(fig, base, rev, args.rounds))
        if "cohort" not in skip:
            part("cohort", lambda: cohort(fig, args.rounds))
    end = f"load average at the end {load()}"
    print(f"\n{end}")
    if args.write_docs:
        write_docs(fig, head + "; " + end + ".")


if __name__ == "__main__":
    main()
