"""``msk run`` (a session configuration → its results folder), ``msk print-config`` (every
configuration key with its type, default, unit and meaning — generated from the options
dataclasses, :func:`msk.config.config_reference`; with a CONFIG, that configuration resolved with
every default; ``--example``, the commented example), ``msk report`` (rebuild a folder's
report) and ``msk strength`` (the session's trials pooled into one strength identification,
:mod:`msk.pipeline.pooled_strength`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from msk.cli import Command

__all__ = ["COMMANDS"]


def _run_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("config", metavar="CONFIG", type=Path, help="session configuration (.toml)")
    p.add_argument("--out", required=True, type=Path, metavar="DIR", help="session folder")
    p.add_argument("--no-cache", action="store_true", help="recompute every stage")
    p.add_argument("--pdf", action="store_true", help="also print report.pdf (Chromium)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--strict", action="store_true", help="exit 3 when any quality gate is raised")


def _run(args: argparse.Namespace) -> int:
    from msk._runtime import fork as _fork

    try:
        return _run_sessions(args)
    finally:
        _fork.stop_servers()


def _run_sessions(args: argparse.Namespace) -> int:
    from msk._runtime.terminal import terminal_safe
    from msk.config.dynamometry import is_dynamometry_config
    from msk.pipeline import run_task_trials

    if is_dynamometry_config(args.config):
        from msk.pipeline.dynamometry import run_dynamometry

        dyn = run_dynamometry(args.config, args.out, progress=None if args.quiet else sys.stderr)
        for f in dyn.summary["flags"]:
            if not args.quiet:
                sys.stderr.write(f"{dyn.out_dir}: flag: {f['message']}\n")
        failed = [r for r in dyn.strengths if r.status != "identified" or r.below_band]
        return 3 if args.strict and failed else 0
    raised = 0
    runs = run_task_trials(
        args.config,
        args.out,
        progress=None if args.quiet else sys.stderr,
        use_cache=not args.no_cache,
        pdf=args.pdf,
    )
    if len(runs) > 1:  # one report of the session: every task trial's cycles pooled
        from msk.report import write_report
        from msk.results.folder import read_session

        parts = [read_session(r.out_dir) for r in runs]
        path = write_report(parts[0], args.out, pdf=args.pdf, trials=parts)
        if not args.quiet:
            sys.stderr.write(f"{path}: the session's report ({len(parts)} task trials)\n")
            if args.pdf and (Path(args.out) / "report.pdf").is_file():
                sys.stderr.write(f"{(Path(args.out) / 'report.pdf').resolve()}\n")
    for res in runs:
        if args.pdf and not args.quiet:
            pdf = res.out_dir / "report.pdf"
            sys.stderr.write(
                f"{pdf}\n"
                if pdf.is_file()
                else f"{res.out_dir}: report.pdf not written (no headless Chromium, or it failed)\n"
            )
        missing = res.not_available
        if missing and not args.quiet:
            sys.stderr.write(f"{res.out_dir}: stages not available: {', '.join(missing)}\n")
        flags = res.summary.quality.flags or ()
        raised += len(flags)
        for f in flags:
            msg = terminal_safe(" ".join(str(f.message).split()))
            sys.stderr.write(f"{res.out_dir}: quality flag: {msg}\n")
    return 3 if args.strict and raised else 0


def _print_config_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "config", nargs="?", metavar="CONFIG", type=Path,
        help="a session configuration: print it resolved, every default filled in",
    )  # fmt: skip
    p.add_argument("--example", action="store_true", help="the commented example session")
    p.add_argument("--out", type=Path, metavar="FILE", help="write to FILE (default stdout)")


def _print_config(args: argparse.Namespace) -> int:
    from msk.config import TEMPLATE, config_reference, load_config, render_config

    if args.example:
        text = TEMPLATE
    elif args.config is not None:
        text = render_config(load_config(args.config))
    else:
        text = config_reference()
    if args.out is None:
        sys.stdout.write(text)
    else:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text, encoding="utf-8")
    return 0


def _report_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "folder", metavar="DIR", type=Path,
        help="a session folder of msk run, or the folder of its task-trial folders (one report "
        "of them all)",
    )  # fmt: skip
    p.add_argument("--pdf", action="store_true", help="also print report.pdf (Chromium)")
    p.add_argument(
        "--norms", type=Path, metavar="FILE",
        help="normative bands (CSV of msk.gait.norms, e.g. from msk norms) drawn under the "
        "gait-cycle grids (default: the set msk ships)",
    )  # fmt: skip


def _report(args: argparse.Namespace) -> int:
    from msk.exceptions import SummaryError
    from msk.report import write_report
    from msk.results.folder import read_task_trials

    parts = read_task_trials(args.folder)  # a session folder, or one per task trial
    res = parts[0]
    from msk.report.html import SHIPPED

    norms: Any = SHIPPED  # the shipped set unless a file is named
    if args.norms is not None:
        from msk.gait.norms import read_norms

        norms = read_norms(args.norms)
    try:
        path = write_report(res, args.folder, pdf=args.pdf, norms=norms, trials=parts)
    except (ValueError, TypeError, KeyError, IndexError, AttributeError, RecursionError) as exc:
        # a received folder's summary.json that passes the schema but not the report's reading
        # (an unknown status word, a string where a window is expected): one line, no traceback
        raise SummaryError(
            f"{args.folder / 'summary.json'}: cannot be reported "
            f"({type(exc).__name__}: {' '.join(str(exc).split())[:200]})"
        ) from None
    sys.stdout.write(f"{path}\n")
    if args.pdf and (args.folder / "report.pdf").is_file():
        sys.stdout.write(f"{(args.folder / 'report.pdf').resolve()}\n")  # the PDF's path
    if args.pdf and not (args.folder / "report.pdf").is_file():
        # asked for and not printed: said, and not a success (no stale PDF is left either)
        sys.stderr.write("msk: report.pdf not written (no headless Chromium, or it failed)\n")
        return 1
    return 0


def _strength_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("config", metavar="CONFIG", type=Path, help="session configuration (.toml)")
    p.add_argument(
        "--out", required=True, type=Path, metavar="DIR",
        help="output folder; when it holds the session of `msk run CONFIG --out DIR`, its "
        "summary.json gains `pooled_strength` and its report the pooled strength",
    )  # fmt: skip
    p.add_argument("--quiet", action="store_true", help="no progress lines")


def _strength(args: argparse.Namespace) -> int:
    from msk.pipeline.pooled_strength import attach_to_session, run_pooled_strength

    rec = run_pooled_strength(args.config, args.out, progress=None if args.quiet else sys.stderr)
    n = sum(g["status"] == "identified" for g in rec["groups"])
    sys.stdout.write(
        f"{args.out / 'strength.json'}: {n}/{len(rec['groups'])} groups identified "
        f"(EMG normalisation: {rec['normalisation_kind']})\n"
    )
    for path in attach_to_session(args.out, rec):
        sys.stdout.write(f"{path}: pooled_strength added (report rebuilt)\n")
    return 0


COMMANDS = (
    Command("run", "run a session pipeline (C3D → results folder)", _run_args, _run),
    Command("print-config", "print every session-config key (type, default, unit, meaning), a "
            "config resolved, or the example", _print_config_args, _print_config),
    Command("report", "rebuild report.html of a session folder", _report_args, _report),
    Command("strength", "identify strength from a session's task and MVC trials together "
            "([strength] pool; one EMG normalisation)", _strength_args, _strength),
)  # fmt: skip
