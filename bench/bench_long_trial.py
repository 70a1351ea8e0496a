"""Benchmark: peak memory and time of ``msk run`` on long trials (target: a 100 000-frame
trial within 1 GB peak RSS and linear time).

The long trials are the bundled Grand Challenge PS gait trial (``data/gc5-PS``, 145 frames at
120 Hz, 36 analog channels at 1200 Hz: 3 plates and 16 EMG) played forwards, backwards,
forwards… (a palindrome: markers, plates and EMG stay continuous) to 10 000, 30 000 and
100 000 frames (83 s, 4 min, 14 min), written as a real C3D file (once per length, in a
temporary folder, by a child process: :func:`msk.io.write_c3d`; beyond 65 535 frames, which a
C3D header cannot count, the frames are in ``TRIAL:ACTUAL_START_FIELD`` / ``ACTUAL_END_FIELD``).
The plates are written as type-2 plates in their own axes (force and the moment about the
surface centre, no transducer offset: the same forces, COP and free moments to float32
rounding), the EMG channels as read. The real ``pipelines/gc5_PS.toml`` session then runs on
that file with only its task file swapped (stage cache off): read (msk's C3D reader), model,
IK, loads, mass identification, inverse dynamics, EMG, muscle geometry, tensions, strength,
knee contact, tables, summary, report.

Each length runs in its own child process; printed per length: the child's peak RSS
(``getrusage(RUSAGE_CHILDREN).ru_maxrss``), wall time and time per frame, and after each stage
the high-water mark so far (VmHWM) and the resident memory then (VmRSS: what the stages
after it start from; results no later stage reads are released,
:func:`msk.pipeline.graph.run_graph`). Ratios between lengths show
linearity; absolute times depend on the machine's load.

``--trace``: instead, each node's run under :mod:`tracemalloc` (numpy's allocations; slower,
use ~4 000 and 12 000 frames): per node the bytes live before it, its transient (peak during
it minus live before) and the size of its result, and between two lengths their slopes in
bytes per frame — what each stage adds to the peak of a longer trial.

``--stage-peaks``: the child's VmHWM is reset after each stage (``/proc/self/clear_refs``, Linux
≥ 4.0), so each row's high-water is that stage's own peak — a stage under an earlier stage's
high-water shows its figure too; the peak RSS printed is then the largest of them.

Usage: ``.venv/bin/python bench/bench_long_trial.py [--frames 10000 30000 100000] [--trace]
[--stage-peaks]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "pipelines" / "gc5_PS.toml"


def _status_kib(field: str) -> int:
    """A ``/proc/self/status`` memory field (kB); 0 where /proc is not available."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith(field + ":"):
                return int(line.split()[1])
    except OSError:
        pass
    return 0


def _reset_hwm() -> bool:
    """Reset this process's VmHWM to its current resident set (``/proc/self/clear_refs``
    value 5, Linux ≥ 4.0); False where that is not possible."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
    except OSError:
        return False
    return True


class _StageMemory:
    """A progress stream that records VmHWM and VmRSS after every stage line; with
    ``per_stage``, VmHWM is reset after each record, so each row's high-water is the peak
    during that stage alone (since the previous stage's record)."""

    def __init__(self, per_stage: bool = False) -> None:
        self.rows: list[tuple[str, float, int, int]] = []
        self.per_stage = per_stage

    def write(self, text: str) -> int:
        if text.startswith("["):
            parts = text.split("]", 1)[1].split()
            hwm, rss = _status_kib("VmHWM"), _status_kib("VmRSS")
            self.rows.append((parts[0], float(parts[1]), hwm, rss))
            if self.per_stage and not _reset_hwm():
                raise OSError("--stage-peaks: cannot reset VmHWM (/proc/self/clear_refs)")
        return len(text)

    def flush(self) -> None:
        pass


def tile_trial(trial: Any, n_frames: int) -> Any:
    """``trial`` played forwards, backwards, forwards… to ``n_frames`` point frames (analog
    samples and plates follow; events dropped: detected from the plates)."""
    import numpy as np

    nf = trial.time.size
    ratio = round(trial.analog_ratio)
    block = np.arange(n_frames) // nf
    pos = np.arange(n_frames) % nf
    backwards = block % 2 == 1
    idx = np.where(backwards, nf - 1 - pos, pos)
    sub = np.arange(ratio)
    aidx = np.where(
        backwards[:, None], idx[:, None] * ratio + (ratio - 1 - sub), idx[:, None] * ratio + sub
    ).ravel()

    def take(obj: Any) -> Any:
        changes = {}
        for f in dataclasses.fields(obj):
            v = getattr(obj, f.name)
            if isinstance(v, np.ndarray) and v.ndim >= 1 and v.shape[0] == nf:
                changes[f.name] = v[idx]
            elif isinstance(v, np.ndarray) and v.ndim >= 1 and v.shape[0] == nf * ratio:
                changes[f.name] = v[aidx]
        return dataclasses.replace(obj, **changes)

    t0, dt = float(trial.time[0]), 1.0 / trial.point_rate_hz
    out = take(trial)
    return dataclasses.replace(
        out,
        time=t0 + dt * np.arange(n_frames),
        analog_time=t0 + dt / ratio * np.arange(n_frames * ratio),
        model_outputs=take(trial.model_outputs),
        plates=tuple(take(p) for p in trial.plates),
        events=(),
    )


def write_tiled(n_frames: int, path: Path) -> None:
    """The bundled PS trial tiled to ``n_frames`` (:func:`tile_trial`) written as a C3D at
    ``path`` (millimetres; plates as type 2 in their own axes, channels Fx Fy Fz Mx My Mz of
    the force and of the moment about the surface centre; the other analog channels as read)."""
    import numpy as np

    from msk.config import load_config
    from msk.io import read_c3d
    from msk.io.c3d import PlateSpec, write_c3d

    cfg = load_config(CONFIG)
    task = next(t for t in cfg.trials if t.role == "task")
    trial = tile_trial(read_c3d(task.file), n_frames)
    plate_ch = {c for p in trial.plates for c in p.channels}
    keep = [i for i, lab in enumerate(trial.analog_labels) if lab not in plate_ch]
    columns = [np.asarray(trial.analogs)[:, keep]]
    labels = [trial.analog_labels[i] for i in keep]
    units = [trial.analog_units[i] for i in keep]
    specs = []
    for k, p in enumerate(trial.plates):
        rot = np.asarray(p.rotation)
        names = tuple(f"P{k + 1}{c}" for c in ("Fx", "Fy", "Fz", "Mx", "My", "Mz"))
        columns.append(np.asarray(p.force) @ rot)  # plate axes, N
        columns.append(np.asarray(p.moment) @ rot * 1e3)  # plate axes, N·mm
        labels += names
        units += ["N"] * 3 + ["Nmm"] * 3
        specs.append(PlateSpec(names, np.asarray(p.corners), np.zeros(3), type=2))
    write_c3d(
        path,
        markers=trial.markers,
        marker_labels=trial.marker_labels,
        rate_hz=trial.point_rate_hz,
        point_units="mm",
        analogs=np.concatenate(columns, axis=1),
        analog_labels=labels,
        analog_units=units,
        analog_ratio=round(trial.analog_ratio),
        plates=specs,
        subject=trial.subject,
        first_frame=round(float(trial.time[0]) * trial.point_rate_hz),
    )


def _nbytes(obj: Any, seen: set[int]) -> int:
    """Bytes of the numpy arrays reachable from ``obj`` (dataclasses, mappings, sequences,
    attributes), each buffer once."""
    import numpy as np

    if id(obj) in seen:
        return 0
    seen.add(id(obj))
    if isinstance(obj, np.ndarray):
        return obj.nbytes if obj.base is None else _nbytes(obj.base, seen)
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return sum(_nbytes(getattr(obj, f.name), seen) for f in dataclasses.fields(obj))
    if isinstance(obj, dict):
        return sum(_nbytes(v, seen) for v in obj.values())
    if isinstance(obj, (list, tuple)):
        return sum(_nbytes(v, seen) for v in obj)
    if hasattr(obj, "__dict__"):
        return sum(_nbytes(v, seen) for v in vars(obj).values())
    return 0


def _traced(node: Any, rows: list[tuple[str, int, int, int]]) -> Any:
    """``node`` whose run records (name, live before, transient, result bytes)."""
    import tracemalloc

    run = node.run

    @functools.wraps(run)
    def wrapped(*args: Any, **kwargs: Any) -> Any:
        before = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        res = run(*args, **kwargs)
        peak = tracemalloc.get_traced_memory()[1]
        rows.append((node.name, before, peak - before, _nbytes(res, set())))
        return res

    return dataclasses.replace(node, run=wrapped)


def child(
    n_frames: int, c3d: Path, out: Path, trace: bool = False, stage_peaks: bool = False
) -> dict[str, Any]:
    """Run the session on the tiled C3D ``c3d`` in this process; figures as a dict."""
    import tracemalloc

    import msk.pipeline.graph as graph
    import msk.pipeline.session as session
    from msk.config import load_config

    cfg = load_config(CONFIG)
    trials = tuple(dataclasses.replace(t, file=c3d) if t.role == "task" else t for t in cfg.trials)
    cfg = dataclasses.replace(cfg, trials=trials)
    nodes = graph.GRAPH
    traced: list[tuple[str, int, int, int]] = []
    if trace:
        tracemalloc.start()
        nodes = tuple(_traced(n, traced) for n in nodes)
    session.run_graph = functools.partial(graph.run_graph, graph=nodes)  # type: ignore[assignment]
    mem = _StageMemory(per_stage=stage_peaks)
    hwm0 = _status_kib("VmHWM")
    t0 = time.perf_counter()
    res = session.run_session(cfg, out, progress=mem, use_cache=False)  # type: ignore[arg-type]
    seconds = time.perf_counter() - t0
    failed = [s.name for s in res.stages if s.status in ("failed", "not available")]
    return {
        "frames": n_frames,
        "seconds": seconds,
        "hwm_before_kib": hwm0,
        "stages": mem.rows,
        "failed": failed,
        "traced": traced,
        "stage_peaks": stage_peaks,
    }


def _print_traced(rows: list[dict[str, Any]]) -> None:
    """Per node: bytes live before, transient, result (MiB at the first length) and, between
    the first and last lengths, their slopes (bytes per frame)."""
    a, b = rows[0], rows[-1]
    dn = b["frames"] - a["frames"]
    print(f"per node, {a['frames']} frames (MiB) and slope to {b['frames']} (B/frame):")
    print(f"    {'node':<26}{'live':>8}{'trans':>8}{'result':>8} | {'live':>7}{'trans':>7}"
          f"{'result':>7}{'peak':>7}")  # fmt: skip
    for ra, rb in zip(a["traced"], b["traced"], strict=True):
        sl = [(rb[i] - ra[i]) / dn if dn else 0.0 for i in (1, 2, 3)]
        mib = [ra[i] / 2**20 for i in (1, 2, 3)]
        print(
            f"    {ra[0]:<26}{mib[0]:8.1f}{mib[1]:8.1f}{mib[2]:8.1f} | {sl[0]:7.0f}{sl[1]:7.0f}"
            f"{sl[2]:7.0f}{sl[0] + sl[1]:7.0f}"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, nargs="+", default=[10_000, 30_000, 100_000])
    ap.add_argument("--trace", action="store_true", help="per-node bytes under tracemalloc")
    ap.add_argument(
        "--stage-peaks", action="store_true",
        help="reset the child's VmHWM after each stage: each stage's own high-water",
    )  # fmt: skip
    ap.add_argument("--child", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--write", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--c3d", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--out", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.write:
        write_tiled(args.write, args.c3d)
        return
    if args.child:
        print(json.dumps(child(args.child, args.c3d, args.out, args.trace, args.stage_peaks)))
        return
    rows = []
    for n in args.frames:
        with tempfile.TemporaryDirectory() as tmp:
            c3d = Path(tmp) / f"PS_tiled_{n}.c3d"
            t0 = time.perf_counter()
            w = subprocess.run(
                [sys.executable, __file__, "--write", str(n), "--c3d", str(c3d)],
                capture_output=True, text=True, check=False,
            )  # fmt: skip
            if w.returncode != 0:
                sys.exit(f"{n} frames: writing the C3D failed:\n{w.stderr[-3000:]}")
            print(
                f"{n:7d} frames  C3D written: {c3d.stat().st_size / 2**20:.0f} MiB "
                f"({time.perf_counter() - t0:.1f} s)",
                flush=True,
            )
            before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
            p = subprocess.run(
                [sys.executable, __file__, "--child", str(n), "--c3d", str(c3d),
                 "--out", str(Path(tmp) / "out")] + (["--trace"] if args.trace else [])
                + (["--stage-peaks"] if args.stage_peaks else []),
                capture_output=True, text=True, check=False,
            )  # fmt: skip
            peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
        if p.returncode != 0:
            sys.exit(f"{n} frames: child failed ({p.returncode}):\n{p.stderr[-3000:]}")
        r = json.loads(p.stdout.strip().splitlines()[-1])
        # ru_maxrss of the children is the largest of any child so far: valid for this one
        # when it grew (lengths are run in increasing order)
        r["peak_kib"] = peak if peak > before else r["stages"][-1][2]
        if r["stage_peaks"]:  # the resets lowered the child's own record: the stages' largest
            r["peak_kib"] = max([r["hwm_before_kib"]] + [row[2] for row in r["stages"]])
        rows.append(r)
        print(
            f"{n:7d} frames  peak RSS {r['peak_kib'] / 1024:7.0f} MiB  {r['seconds']:7.1f} s  "
            f"{1e6 * r['seconds'] / n:6.0f} µs/frame"
            + (f"  (not run: {', '.join(r['failed'])})" if r["failed"] else ""),
            flush=True,
        )
        print(f"    after imports {r['hwm_before_kib'] / 1024:6.0f} MiB")
        hw_label = "stage peak" if r["stage_peaks"] else "high-water"
        for name, sec, hwm, rss in r["stages"]:
            print(
                f"    {name:<26}{sec:8.2f} s  {hw_label} {hwm / 1024:6.0f} MiB  "
                f"resident after {rss / 1024:6.0f} MiB"
            )
    if args.trace:
        _print_traced(rows)
        return
    if len(rows) > 1:
        a = rows[0]
        for b in rows[1:]:
            f = b["frames"] / a["frames"]
            dt, dm = b["seconds"] / a["seconds"], b["peak_kib"] / a["peak_kib"]
            print(f"{b['frames']} / {a['frames']} frames (x{f:g}): time x{dt:.2f}, RSS x{dm:.2f}")


if __name__ == "__main__":
    main()
