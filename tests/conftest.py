"""Shared fixtures: paths to the third-party recordings and reference tables."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import settings

from msk._data import real_data_dir, reference_dir
from msk.opensim_peer import opensim_available

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
