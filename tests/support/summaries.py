"""A minimal valid ``summary.json`` body shared by the tests that build results folders."""

from __future__ import annotations

from typing import Any

__all__ = ["BASE"]

#: the required keys of a summary with neutral values
BASE: dict[str, Any] = {
    "session": "S1",
    "created_utc": "2026-01-01T00:00:00Z",
    "versions": {"msk": "0.1.0"},
    "config": {"path": "s.toml", "sha256": "0" * 64},
    "inputs": [{"role": "task", "path": "t.c3d", "sha256": "1" * 64, "bytes": 10}],
    "settings": {"subject": {"name": "S1"}},
    "subject": {"name": "S1", "mass_kg": 70.0, "height_m": None, "side": "left"},
    "quality": {},
    "stages": [],
    "not_available": [],
}
