"""Jobs for the isolated-worker tests (imported by the children: module-level functions)."""

from __future__ import annotations

import importlib.util
import os
import signal
import sys
import time
from pathlib import Path


def double(x: int) -> int:
    return 2 * x


def segfault(_: int) -> int:
    os.kill(os.getpid(), signal.SIGSEGV)
    time.sleep(10)
    return 0


def stop(_: int) -> int:
    os.kill(os.getpid(), signal.SIGSTOP)
    return 0


def killed_once(flag: str) -> str:
    """Killed by SIGKILL on its first run (as the OOM killer would), fine on the second."""
    p = Path(flag)
    if not p.exists():
        p.write_text("1")
        os.kill(os.getpid(), signal.SIGKILL)
    return "second run"


def raises(_: int) -> int:
    raise ValueError("bad input")


def where_concurrent(_: int) -> tuple[str, list[str]]:
    spec = importlib.util.find_spec("concurrent")
    return (str(spec.origin if spec else None), list(sys.path))
