"""Shared fixtures (paths to the third-party recordings and reference tables), the lane
summary (the last line of a run names the lane that ran and its wall time) and the order in
which pytest-xdist workers run the tests (longest first, from ``tests/durations.json``)."""

from __future__ import annotations

import json
import os
import time
from collections import defaultdict
from pathlib import Path

import pytest
from hypothesis import settings

from msk._runtime.opensim_peer import opensim_available
from msk.datasets.shared import real_data_dir, reference_dir
from tests.support.schedule import worker_order

TESTS_DATA = Path(__file__).parent / "data"
DURATIONS = Path(__file__).parent / "durations.json"
# CI runs property tests on a fixed example sequence (reproducible, never flaky); locally they
# explore fresh examples on every run.
settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


@pytest.fixture(scope="session")
def real_dir() -> Path:
    d = real_data_dir()
    if not d.is_dir():
        pytest.skip(f"real recordings folder absent: {d}")
    return d


@pytest.fixture(scope="session")
def ref_dir() -> Path:
    d = reference_dir()
    if not d.is_dir():
        pytest.skip(f"reference folder absent: {d}")
    return d


@pytest.fixture(scope="session")
def needs_opensim() -> None:
    if not opensim_available():
        pytest.skip("opensim extra not installed")


@pytest.fixture(scope="session")
def tests_data() -> Path:
    return TESTS_DATA


# ---------------------------------------------------------------------------------------------
# lanes (docs/contributing.md): which one ran and how long it took, in the log of every run
# ---------------------------------------------------------------------------------------------
_START = time.perf_counter()


def lane_name(markexpr: str) -> str:
    """The lane a ``-m`` expression selects: ``fast`` (``not slow``, the default), ``slow``,
    ``whole suite`` (``slow or not slow``, or no expression), else the expression itself."""
    expr = " ".join(markexpr.split())
    return {
        "not slow": "fast",
        "slow": "slow",
        "slow or not slow": "whole suite",
        "not slow or slow": "whole suite",
        "": "whole suite",
    }.get(expr, f"-m {expr!r}")


def pytest_terminal_summary(
    terminalreporter: pytest.TerminalReporter, config: pytest.Config
) -> None:
    workers = config.getoption("numprocesses", None)
    terminalreporter.write_sep(
        "-",
        f"lane: {lane_name(config.getoption('markexpr') or '')}; wall time "
        f"{time.perf_counter() - _START:.1f} s (from conftest import, {os.cpu_count()} CPUs, "
        f"xdist workers: {workers or 0}, CI={os.environ.get('CI', '')!r})",
    )


# ---------------------------------------------------------------------------------------------
# pytest-xdist: longest tests first (docs/contributing.md)
# ---------------------------------------------------------------------------------------------
#: seconds assumed for a test absent from the table: a fast-lane test, a ``slow`` one
DEFAULT_SECONDS = 0.05
DEFAULT_SLOW_SECONDS = 5.0


def _recorded() -> dict[str, float]:
    try:
        table = json.loads(DURATIONS.read_text())
    except (OSError, ValueError):
        return {}
    return {str(k): float(v) for k, v in table.get("seconds", {}).items()}


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """In a pytest-xdist worker (every worker collects the same list and orders it alike), the
    selected tests in :func:`worker_order`; a plain run keeps pytest's order."""
    n = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "0") or 0)
    if os.environ.get("PYTEST_XDIST_WORKER") is None or n < 2:
        return
    table = _recorded()
    seconds = [
        table.get(
            it.nodeid,
            DEFAULT_SLOW_SECONDS if it.get_closest_marker("slow") else DEFAULT_SECONDS,
        )
        for it in items
    ]
    order = worker_order([it.nodeid for it in items], seconds, n)
    items[:] = [items[i] for i in order]


# MSK_UPDATE_DURATIONS=1: the run rewrites tests/durations.json with the durations it measured
# (tests it did not run keep their recorded value)
_MEASURED: dict[str, float] = defaultdict(float)


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    if os.environ.get("MSK_UPDATE_DURATIONS"):
        _MEASURED[report.nodeid] += report.duration


def pytest_sessionfinish(session: pytest.Session) -> None:
    if not os.environ.get("MSK_UPDATE_DURATIONS") or os.environ.get("PYTEST_XDIST_WORKER"):
        return
    table = _recorded() | {k: v for k, v in _MEASURED.items()}
    kept = {k: round(v, 2) for k, v in sorted(table.items()) if v >= DEFAULT_SECONDS}
    DURATIONS.write_text(
        json.dumps(
            {
                "what": "seconds (setup + call + teardown) of each test slower than "
                f"{DEFAULT_SECONDS} s, measured with MSK_UPDATE_DURATIONS=1; tests/conftest.py "
                "orders the pytest-xdist queues by them",
                "seconds": kept,
            },
            indent=1,
        )
        + "\n"
    )
