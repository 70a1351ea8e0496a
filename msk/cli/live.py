"""``msk live CONFIG --replay TRIAL --out DIR``: a recorded trial streamed through the live chain
(:mod:`msk.live`, set up by :func:`msk.pipeline.live.live_setup`), the latency distribution of
each stage and of the whole chain printed, the streamed results written as tables; or
``--lsl-in NAME``: the frames of an LSL stream; ``--lsl-out NAME``: the results published on an
LSL outlet too."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from msk.cli import Command, positive_int

__all__ = ["COMMANDS", "latency_report"]


def _args(p: argparse.ArgumentParser) -> None:
    p.add_argument("config", metavar="CONFIG", type=Path, help="session configuration (.toml)")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--replay", type=Path, metavar="TRIAL", help="a .c3d/.trc trial to replay")
    src.add_argument("--lsl-in", metavar="NAME", help="an LSL stream (msk.live.sources layout)")
    p.add_argument("--grf", type=Path, metavar="FILE", help="the replayed trial's GRF .mot/.sto")
    p.add_argument("--external-loads", type=Path, metavar="XML", help="the GRF's ExternalLoads")
    p.add_argument("--out", type=Path, metavar="DIR", help="write the streamed tables here")
    p.add_argument("--realtime", action="store_true", help="replay at the recorded rate")
    p.add_argument("--lsl-out", metavar="NAME", help="also publish the results on an LSL outlet")
    p.add_argument(
        "--scaled-inertias", action="store_true",
        help="the scaled segment inertias, not those identified on the configuration's task "
        "trial (which msk run's torques use)",
    )  # fmt: skip
    p.add_argument(
        "--smoother", choices=("butterworth", "linear_phase"), default="butterworth",
        help="causal Butterworth (shortest lag) or the offline filter as a linear-phase FIR",
    )  # fmt: skip
    p.add_argument("--ik-iterations", type=positive_int, default=10, metavar="N")
    p.add_argument(
        "--skip",
        type=int,
        default=10,
        metavar="N",
        help="frames left out of the latency figures (the first calls' warm-up)",
    )


def latency_report(percentiles: dict[str, tuple[float, float]], n_frames: int) -> str:
    """The latency table: each stage's and the whole chain's p50 and p99, µs."""
    lines = [f"latency over {n_frames} frames (µs):  stage  p50  p99"]
    for name, (p50, p99) in percentiles.items():
        lines.append(f"  {name:<18s} {1e6 * p50:9.0f} {1e6 * p99:9.0f}")
    return "\n".join(lines)


def _live(args: argparse.Namespace) -> int:
    from msk.live import LiveSession
    from msk.live.sinks import FrameRecorder, LslSink
    from msk.live.sources import LslSource, ReplaySource
    from msk.pipeline.live import live_setup

    source: ReplaySource | LslSource
    if args.replay is not None:
        source = ReplaySource(
            args.replay, grf=args.grf, external_loads=args.external_loads, realtime=args.realtime
        )
        rate = source.rate_hz
    else:
        source = LslSource(args.lsl_in)
        rate = source.rate_hz
    labels = source.layout.labels
    plates = source.plate_names if isinstance(source, ReplaySource) else ()
    assignment = source.assignment if isinstance(source, ReplaySource) else None
    setup = live_setup(
        args.config, labels, rate, identified=not args.scaled_inertias,
        ik_iterations=args.ik_iterations, smoother=args.smoother,
        plate_names=plates, assignment=assignment,
    )  # fmt: skip
    session = LiveSession(setup.model)
    record = FrameRecorder(setup.model)
    sinks = [record]
    if args.lsl_out:
        sinks.append(LslSink(args.lsl_out, setup.model))  # type: ignore[arg-type]
    for frame in source:
        out = session.step(frame)
        for sink in sinks:
            sink(out)
    n = len(record.frames)
    skip = min(args.skip, max(n - 1, 0))
    print(f"msk live: {n} frames at {rate:g} Hz; outputs lag the newest input by "
          f"{1e3 * session.lag_s:.1f} ms (the filter's delay and its differences)")  # fmt: skip
    if n:
        print(latency_report(record.latency_percentiles(skip), n - skip))
        chain = record.stage_seconds()[skip:].sum(axis=1)
        late = int((chain > 1.0 / rate).sum())
        print(f"frames whose chain took longer than the frame period ({1e3 / rate:.1f} ms): "
              f"{late} of {chain.size}")  # fmt: skip
    if args.out is not None and n:
        for path in record.write(args.out, setup.body_weight_n):
            sys.stderr.write(f"wrote {path}\n")
    return 0


COMMANDS = (
    Command(
        "live",
        "stream a trial (replayed, or an LSL inlet) through the chain frame by frame; print "
        "the latency distribution and write the streamed results",
        _args,
        _live,
    ),
)
