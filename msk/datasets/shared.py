"""Where msk finds the shared real recordings and reference tables (tests, benchmarks, docs).

``MSK_SHARED`` overrides the default, which is the ``shared/`` folder beside the repository.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["REPO_ROOT", "real_data_dir", "reference_dir", "shared_dir"]

REPO_ROOT = Path(__file__).resolve().parents[2]


def shared_dir() -> Path:
    """The shared folder (``$MSK_SHARED`` or ``<repo>/../shared``); it may not exist."""
    env = os.environ.get("MSK_SHARED")
    return Path(env) if env else REPO_ROOT.parent / "shared"


def real_data_dir() -> Path:
    """``shared/data/real``: third-party recordings."""
    return shared_dir() / "data" / "real"


def reference_dir() -> Path:
    """``shared/data/reference``: published models and tables."""
    return shared_dir() / "data" / "reference"
