"""The API reference builds from the docstrings (pdoc) and has a page for every public module."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("pdoc") is None, reason="pdoc is not installed")
def test_api_reference_builds_with_a_page_per_public_module(tmp_path: Path) -> None:
    sys.path.insert(0, str(REPO / "docs"))
    try:
        import build_reference
    finally:
        sys.path.pop(0)
    pages = build_reference.build(tmp_path)
    written = {p.relative_to(tmp_path).with_suffix("").as_posix().replace("/", ".") for p in pages}
    missing = set(build_reference.public_modules()) - written
    assert not missing, f"modules without a reference page: {sorted(missing)}"
