"""Input validation shared by the readers: special files, plausibility of what was read.

Every check raises a typed :class:`~msk.exceptions.MskError` whose message names the file (and
the channel, marker or parameter) and the offending value, on one line.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from msk.exceptions import MskError

__all__ = [
    "MAX_ABS_COORDINATE_M",
    "MAX_ABS_FORCE_N",
    "check_regular_file",
    "check_time_axis",
    "duplicates",
    "path_kind",
]

#: plausibility bounds of what a reader may return: a ground reaction (N) and a lab coordinate (m)
MAX_ABS_FORCE_N = 20_000.0
MAX_ABS_COORDINATE_M = 100.0


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def path_kind(path: str | Path) -> str:
    """What a path that is not a regular file is, for an error message: ``"a directory"``,
    ``"a FIFO (named pipe)"``, a device, ``"a socket"``, ``"not a regular file"`` or, when it
    cannot be examined, ``"not accessible"``."""
    try:
        return _kind(Path(path).stat().st_mode)
    except OSError:
        return "not accessible"


def check_regular_file(
    path: str | Path, error: type[MskError] = MskError, what: str = "file"
) -> Path:
    """``path`` if it names an existing regular file (symlinks followed), else ``error``.

    Uses ``os.stat`` only, never ``open``: opening a FIFO blocks and ``/dev/zero`` never ends.
    """
    p = Path(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise error(f"{p}: no such file") from None
    except OSError as exc:
        raise error(f"{p}: cannot access the {what}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(st.st_mode):
        raise error(f"{p}: is {_kind(st.st_mode)}, not a regular {what}")
    return p


def check_time_axis(
    path: str | Path, time: ArrayLike, error: type[MskError] = MskError, what: str = "time"
) -> None:
    """A time column must be finite and strictly increasing (names the first bad row)."""
    t = np.asarray(time, dtype=float).ravel()
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise error(f"{path}: {what} at row {bad[0] + 1} is {t[bad[0]]} (not finite)")
    if t.size > 1:
        d = np.diff(t)
        k = np.flatnonzero(d <= 0)
        if k.size:
            i = int(k[0])
            kind = "repeated" if d[i] == 0 else "decreasing (unsorted)"
            raise error(f"{path}: {what} is {kind} at row {i + 2}: {t[i + 1]:.9g} after {t[i]:.9g}")


def duplicates(labels: Sequence[str]) -> list[str]:
    """Labels present more than once (in first-seen order)."""
    seen: set[str] = set()
    dup: dict[str, None] = {}
    for lab in labels:
        if lab in seen:
            dup[lab] = None
        seen.add(lab)
    return list(dup)
