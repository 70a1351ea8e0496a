"""Shared fixtures (paths to the third-party recordings and reference tables) and the lane
summary: the last line of a run names the lane that ran and its wall time."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest
from hypothesis import settings

from msk._runtime.opensim_peer import opensim_available
from msk.datasets.shared import real_data_dir, reference_dir

TESTS_DATA = Path(__file__).parent / "data"
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
