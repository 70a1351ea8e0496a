"""Benchmark: read_c3d on a synthetic 10,000-frame, 60-marker, 3-plate C3D (analogs at 10x).

Writes the file with ezc3d (``msk.io.write_c3d``), then times, in the same run:
* raw ``ezc3d.c3d(path)`` (no plate extraction),
* ``ezc3d.c3d(path, extract_forceplat_data=True)`` (ezc3d's own, per-frame plate loop),
* ``msk.io.read_c3d(path)`` cold (first call in the process) and warm (median of 5).

Usage: ``.venv/bin/python bench/bench_c3d.py [--frames 10000] [--repeat 5]`` (prints its
figures; only ``bench/run_all.py`` writes figures into the docs). Target: read_c3d < 1 s.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np


def make_file(path: Path, *, frames: int, markers: int, plates: int, ratio: int) -> Path:
    from msk.io.c3d import PlateSpec, write_c3d

    rng = np.random.default_rng(0)
    x = rng.uniform(-1.0, 2.0, size=(frames, markers, 3))
    x[rng.random((frames, markers)) < 0.01] = np.nan
    na = frames * ratio
    chans, labels, specs = [], [], []
    for p in range(plates):
        ta = np.arange(na) / (100.0 * ratio)
        fz = -700.0 * np.clip(np.sin(2 * np.pi * (ta + p / 3)), 0, None)
        f = np.column_stack([rng.normal(0, 5, na), rng.normal(0, 5, na), fz])
        m = np.column_stack(
            [rng.normal(0, 1e4, na), rng.normal(0, 1e4, na), rng.normal(0, 1e3, na)]
        )
        chans.append(np.column_stack([f, m]))
        lab = [f"{q}{p + 1}" for q in ("Fx", "Fy", "Fz", "Mx", "My", "Mz")]
        labels += lab
        c = np.array([0.6 * p, 0.0, 0.0])
        corners = c + np.array([[0.6, 0.4, 0], [0.0, 0.4, 0], [0.0, 0.0, 0], [0.6, 0.0, 0]])
        specs.append(
            PlateSpec(channels=tuple(lab), corners_m=corners, origin_m=np.array([0, 0, -0.04]))
        )
    emg = rng.normal(0, 1e-4, size=(na, 8))
    labels += [f"EMG{k + 1}" for k in range(8)]
    return write_c3d(
        path,
        markers=x,
        marker_labels=[f"M{k:02d}" for k in range(markers)],
        rate_hz=100.0,
        point_units="mm",
        analogs=np.column_stack([*chans, emg]),
        analog_labels=labels,
        analog_ratio=ratio,
        plates=specs,
    )


def _time(fn, repeat: int) -> list[float]:
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=10_000)
    ap.add_argument("--markers", type=int, default=60)
    ap.add_argument("--plates", type=int, default=3)
    ap.add_argument("--ratio", type=int, default=10)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--skip-ezc3d-plates", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        path = make_file(
            Path(d) / "bench.c3d",
            frames=args.frames,
            markers=args.markers,
            plates=args.plates,
            ratio=args.ratio,
        )
        size_mb = path.stat().st_size / 1e6
        from msk.io import read_c3d

        t0 = time.perf_counter()
        tr = read_c3d(path)
        cold = time.perf_counter() - t0
        import ezc3d

        # interleaved so that both see the same machine load
        warm_t, raw_t = [], []
        for _ in range(args.repeat):
            raw_t += _time(lambda: ezc3d.c3d(str(path)), 1)
            warm_t += _time(lambda: read_c3d(path), 1)
        warm, raw = statistics.median(warm_t), statistics.median(raw_t)
        ezfp = (
            float("nan")
            if args.skip_ezc3d_plates
            else statistics.median(
                _time(
                    lambda: ezc3d.c3d(str(path), extract_forceplat_data=True),
                    max(1, args.repeat // 2),
                )
            )
        )
    print(
        f"file: {args.frames} frames x {args.markers} markers, {args.plates} plates, "
        f"{tr.analogs.shape[1]} analog channels x {tr.analogs.shape[0]} samples ({size_mb:.1f} MB)"
    )
    print(f"read_c3d cold            : {cold * 1e3:8.1f} ms")
    print(f"read_c3d warm (median {args.repeat}) : {warm * 1e3:8.1f} ms")
    print(f"ezc3d.c3d raw (median {args.repeat}) : {raw * 1e3:8.1f} ms")
    print(f"ezc3d.c3d + plates       : {ezfp * 1e3:8.1f} ms")
    print(f"ratio read_c3d / raw ezc3d: {warm / raw:.2f}")
    print(f"target < 1 s: {'met' if warm < 1.0 else 'NOT met'}")


if __name__ == "__main__":
    main()
