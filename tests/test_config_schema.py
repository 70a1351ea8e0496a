"""The session-config schema (issue 14): the options dataclasses of :mod:`msk.config` are the
schema; validation, ``msk print-config`` and ``docs/config.md`` are generated from them.

Every shipped ``pipelines/*.toml`` loads into the same dataclasses as before the schema was
declared (``tests/golden/config/<config>.json``, written by the previous hand-written reader;
``MSK_UPDATE_GOLDEN=1`` refreshes them after an intended change).
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pytest

from msk.config import load_config
from msk.exceptions import ConfigError

REPO = Path(__file__).resolve().parents[1]
CONFIGS = sorted((REPO / "pipelines").glob("*.toml"))
GOLDEN = REPO / "tests" / "golden" / "config"


def plain(x: Any) -> Any:
    """A loaded configuration as JSON values, with its types (paths relative to the repo)."""
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        fields = {f.name: plain(getattr(x, f.name)) for f in dataclasses.fields(x)}
        return {"__type__": type(x).__name__, **fields}
    if isinstance(x, Mapping):
        return {str(k): plain(v) for k, v in x.items()}
    if isinstance(x, tuple | list):
        return [plain(v) for v in x]
    if isinstance(x, Path):
        return {"path": os.path.relpath(x, REPO)}
    if isinstance(x, float):
        return {"float": repr(x)}
    return x


@pytest.mark.parametrize("config", CONFIGS, ids=[c.stem for c in CONFIGS])
def test_shipped_configs_load_unchanged(config: Path) -> None:
    try:
        got = plain(load_config(config))
    except ConfigError as exc:
        if "file not found" in str(exc):
            pytest.skip(f"{config.name}: its recordings are not here")
        raise
    golden = GOLDEN / f"{config.stem}.json"
    if os.environ.get("MSK_UPDATE_GOLDEN") == "1":
        golden.write_text(json.dumps(got, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    assert got == json.loads(golden.read_text(encoding="utf-8"))
