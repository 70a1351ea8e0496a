"""``msk batch`` (many sessions in parallel: local pool or Dask) and ``msk compare`` (generic
against identified parameters across session folders): :mod:`msk.pipeline.batch`,
:mod:`msk.results.cohort`."""

from __future__ import annotations

import argparse
import csv
import io
import sys
from pathlib import Path
from typing import Any

from msk.cli import Command, positive_int

__all__ = ["COMMANDS"]


def _fmt(v: Any) -> str:
    import numpy as np

    if isinstance(v, float):
        return "nan" if not np.isfinite(v) else f"{v:.4g}"
    return str(v)


def batch_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "sessions",
        nargs="+",
        metavar="SESSION",
        type=Path,
        help="session configurations (.toml)",
    )
    p.add_argument("--out", required=True, type=Path, metavar="DIR")
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="Dask distributed scheduler (tcp://host:8786); default: local pool",
    )
    p.add_argument("--workers", type=positive_int, help="local pool size (default: #CPUs)")
    p.add_argument("--no-cache", action="store_true", help="recompute every stage")
    p.add_argument(
        "--time-limit",
        type=float,
        metavar="SECONDS",
        help="local pool: a session running longer is killed and failed (default: 3600)",
    )


def _batch(args: argparse.Namespace) -> int:
    from msk.pipeline.batch import run_batch

    res = run_batch(
        args.sessions,
        args.out,
        scheduler=args.scheduler,
        workers=args.workers,
        use_cache=not args.no_cache,
        progress=sys.stderr,
        time_limit_s=args.time_limit,
    )
    n_ok = len(res.outcomes) - len(res.failed)
    sys.stderr.write(
        f"{n_ok}/{len(res.outcomes)} sessions ok in {res.seconds:.1f} s; "
        f"cohort table {res.cohort_csv}\n"
    )
    return 1 if res.failed else 0


def cmp_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("folders", nargs="+", metavar="DIR", type=Path, help="session folders")
    p.add_argument("--out", type=Path, metavar="FILE", help="also write the table as CSV")


def _compare(args: argparse.Namespace) -> int:
    from msk.results.cohort import COMPARE_COLUMNS, compare_sessions

    rows = compare_sessions(args.folders)
    widths = {
        c: max(len(c), *(len(_fmt(r[c])) for r in rows)) if rows else len(c)
        for c in COMPARE_COLUMNS
    }
    sys.stdout.write("  ".join(c.ljust(widths[c]) for c in COMPARE_COLUMNS).rstrip() + "\n")
    for r in rows:
        sys.stdout.write(
            "  ".join(_fmt(r[c]).ljust(widths[c]) for c in COMPARE_COLUMNS).rstrip() + "\n"
        )
    if args.out is not None:
        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=list(COMPARE_COLUMNS), lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(buf.getvalue(), encoding="utf-8")
    return 0


COMMANDS = (
    Command("batch", "run many sessions in parallel (local pool or Dask)", batch_args, _batch),
    Command("compare", "generic vs identified parameters across session folders", cmp_args,
            _compare),
)  # fmt: skip
