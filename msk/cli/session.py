"""``msk run`` (a session configuration → its results folder), ``msk print-config`` (every
configuration key with its type, default, unit and meaning — generated from the options
dataclasses, :func:`msk.config.config_reference`; with a CONFIG, that configuration resolved with
every default; ``--example``, the commented example) and ``msk report`` (rebuild a folder's
report)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

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

    # the report's figures: a child forked when the first stage is computed (none if every
    # stage comes from the cache) imports matplotlib on the free CPU while the stages run, and
    # draws them when the report stage asks (msk.report.build_figures)
    _fork.defer_server("figures", "msk.report.html", "_draw_all", warm="_warm")
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
        failed = [r for r in dyn.strengths if r.status != "identified"]
        return 3 if args.strict and failed else 0
    raised = 0
    for res in run_task_trials(
        args.config,
        args.out,
        progress=None if args.quiet else sys.stderr,
        use_cache=not args.no_cache,
        pdf=args.pdf,
    ):
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
    p.add_argument("folder", metavar="DIR", type=Path, help="a session folder of msk run")
    p.add_argument("--pdf", action="store_true", help="also print report.pdf (Chromium)")


def _report(args: argparse.Namespace) -> int:
    from msk.exceptions import SummaryError
    from msk.report import write_report
    from msk.results.folder import read_session

    res = read_session(args.folder)
    try:
        path = write_report(res, args.folder, pdf=args.pdf)
    except (ValueError, TypeError, KeyError, IndexError, AttributeError, RecursionError) as exc:
        # a received folder's summary.json that passes the schema but not the report's reading
        # (an unknown status word, a string where a window is expected): one line, no traceback
        raise SummaryError(
            f"{args.folder / 'summary.json'}: cannot be reported "
            f"({type(exc).__name__}: {' '.join(str(exc).split())[:200]})"
        ) from None
    sys.stdout.write(f"{path}\n")
    if args.pdf and not (args.folder / "report.pdf").is_file():
        # asked for and not printed: said, and not a success (no stale PDF is left either)
        sys.stderr.write("msk: report.pdf not written (no headless Chromium, or it failed)\n")
        return 1
    return 0


COMMANDS = (
    Command("run", "run a session pipeline (C3D → results folder)", _run_args, _run),
    Command("print-config", "print every session-config key (type, default, unit, meaning), a "
            "config resolved, or the example", _print_config_args, _print_config),
    Command("report", "rebuild report.html of a session folder", _report_args, _report),
)  # fmt: skip
