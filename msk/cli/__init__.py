"""The ``msk`` command.

Every verb is a :class:`Command` (name, help line, argument builder, handler) listed in the
``COMMANDS`` tuple of one module of :data:`VERB_MODULES`; :func:`build_parser` reads them —
importing a verb module registers nothing and imports nothing heavy (handlers import the
library when they run), so ``msk --help`` never loads Pinocchio, casadi or matplotlib. Adding a
verb = a :class:`Command` in one of those modules (or a new module + one line in
:data:`VERB_MODULES`). Any :class:`msk.exceptions.MskError` ends the command with exactly one
line ``msk: error: <message>`` on stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NoReturn

from msk import __version__
from msk.exceptions import MskError

__all__ = ["VERB_MODULES", "Command", "build_parser", "console", "main", "positive_int"]

#: Modules whose ``COMMANDS`` tuple lists their verbs, in the order ``msk --help`` shows them.
VERB_MODULES: tuple[str, ...] = (
    "msk.cli.session",
    "msk.cli.init",
    "msk.cli.batch",
    "msk.cli.norms",
    "msk.cli.info",
    "msk.cli.live",
)


@dataclass(frozen=True)
class Command:
    """A verb: its help line, argument builder and handler (returns the exit status)."""

    name: str
    help: str
    arguments: Callable[[argparse.ArgumentParser], None]
    handler: Callable[[argparse.Namespace], int]


def commands() -> tuple[Command, ...]:
    """Every verb of :data:`VERB_MODULES` (a repeated name is an error of the package)."""
    out: dict[str, Command] = {}
    for mod in VERB_MODULES:
        for cmd in importlib.import_module(mod).COMMANDS:
            if cmd.name in out:
                raise RuntimeError(f"msk verb {cmd.name!r} defined twice ({mod})")
            out[cmd.name] = cmd
    return tuple(out.values())


class _Parser(argparse.ArgumentParser):
    """argparse with usage errors on one line (``msk: error: …``, exit 2), like every other."""

    def error(self, message: str) -> NoReturn:
        msg = " ".join(message.split())
        self.exit(2, f"msk: error: {self.prog}: {msg} (see {self.prog} --help)\n")


def positive_int(text: str) -> int:
    """argparse type: an integer ≥ 1 (``--workers``)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} should be ≥ 1")
    return value


def _safe_streams() -> None:
    """A strict-ASCII (or any non-UTF-8) terminal gets escapes, never a UnicodeEncodeError."""
    for stream in (sys.stdout, sys.stderr):
        if hasattr(stream, "reconfigure") and (stream.errors or "strict") == "strict":
            try:
                stream.reconfigure(errors="backslashreplace")
            except (ValueError, OSError):  # pragma: no cover - detached or closed
                pass


def build_parser() -> argparse.ArgumentParser:
    """The argparse parser with every registered verb."""
    parser = _Parser(
        prog="msk", description="Subject-specific musculoskeletal analysis of the lower limb."
    )
    parser.add_argument("--version", action="version", version=f"msk {__version__}")
    sub = parser.add_subparsers(dest="verb", metavar="COMMAND")
    sub.required = True
    for cmd in commands():
        p = sub.add_parser(cmd.name, help=cmd.help, description=cmd.help)
        cmd.arguments(p)
        p.set_defaults(_handler=cmd.handler)
    return parser


def _quiet_blas_threads() -> None:
    """OpenBLAS's worker threads sleep as soon as a call is done instead of spinning on a core
    for ~0.1 s after every threaded call (``OPENBLAS_THREAD_TIMEOUT``: 2⁴ cycles instead of
    2²⁸). Same thread count, hence the same results; on a shared machine and in a batch,
    where the spinning threads took the CPU the other workers need, the runs are faster and
    steadier. Read when OpenBLAS loads (numpy's import), so set before it; a value already in
    the environment is kept."""
    os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "4")


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``msk`` console script; returns the exit status."""
    _quiet_blas_threads()
    _safe_streams()
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args._handler(args) or 0)
    except MskError as exc:
        from msk._runtime.terminal import terminal_safe

        msg = terminal_safe(" ".join(str(exc).split())) or type(exc).__name__
        print(f"msk: error: {msg}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into head & co.
        return 0
    except OSError as exc:
        print(f"msk: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2


def console() -> NoReturn:
    """The ``msk`` console script (and ``python -m msk.cli``): :func:`main` in a short-lived
    process, so the cyclic garbage collector runs less often (first generation every 20,000
    allocations instead of 700: ~0.07 s of a cold ``msk run``, most of them over the ~10⁶
    objects that imports create) and the process ends without the interpreter's last collection
    over every object (``gc.freeze``: ~0.15 s; the objects are freed with the process all the
    same, finalisers and ``atexit`` handlers still run)."""
    import gc

    gc.set_threshold(20_000, 20, 20)
    code = main()
    gc.freeze()
    sys.exit(code)
