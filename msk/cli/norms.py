"""``msk norms BATCH_DIR --out bands.csv``: a lab's own normative bands from the cycles of its
control sessions (the session folders of an ``msk batch`` output, read typed by
:func:`msk.results.folder.read_session`; :func:`msk.gait.norms.bands_from_sessions`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from msk.cli import Command

__all__ = ["COMMANDS"]


def norms_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "batch",
        type=Path,
        metavar="BATCH_DIR",
        help="an `msk batch` output folder (one session folder per subfolder)",
    )
    p.add_argument(
        "--out",
        type=Path,
        required=True,
        metavar="FILE",
        help="the bands file to write (CSV, msk.gait.norms format)",
    )
    p.add_argument(
        "--session",
        action="append",
        default=None,
        metavar="NAME",
        help="a control session's folder name (repeat; default: every session)",
    )
    p.add_argument(
        "--population",
        default=None,
        help="who the controls are (default: the sessions' count and names)",
    )
    p.add_argument("--source", default=None, help="who measured them (default: the folder)")
    p.add_argument(
        "--licence",
        default="the lab's own data (no licence stated)",
        help="the licence the bands may be shared under",
    )


def _norms(args: argparse.Namespace) -> int:
    from msk.exceptions import MissingDataError
    from msk.gait.norms import bands_from_sessions, write_norms

    batch: Path = args.batch
    if not batch.is_dir():
        raise MissingDataError(f"{batch}: not a folder (an `msk batch` output)")
    folders = sorted(p for p in batch.iterdir() if (p / "summary.json").is_file())
    if args.session:
        names = {f.name for f in folders}
        unknown = [s for s in args.session if s not in names]
        if unknown:
            raise MissingDataError(
                f"{batch}: no session folder {unknown[0]!r} (have {', '.join(sorted(names))})"
            )
        folders = [f for f in folders if f.name in set(args.session)]
    bands, used, skipped = bands_from_sessions(
        folders,
        population=args.population,
        source=args.source or f"msk norms {batch}",
        licence=args.licence,
    )
    for name, why in skipped:
        sys.stderr.write(f"{name}: left out ({why})\n")
    out = write_norms(args.out, bands)
    sys.stderr.write(
        f"{len(bands.variables)} variables from {bands.notes.get('n_cycles')} cycles of "
        f"{len(used)} sessions ({', '.join(used)}) → {out}\n"
    )
    return 0


COMMANDS = (
    Command("norms", "a lab's normative bands from its control sessions (msk batch output)",
            norms_args, _norms),
)  # fmt: skip
