"""Whether a shipped session configuration's recordings are here (the real-data tests skip
without ``../shared``; with it, a file the configuration names and that is missing is an error,
never a silent skip)."""

from __future__ import annotations

import re
from pathlib import Path

from msk.datasets.shared import real_data_dir
from msk.model.files import model_file

__all__ = ["recordings_present"]

_KEYS = r'^\s*(?:file|grf|external_loads|contact_force|source)\s*=\s*"([^"]+)"'


def recordings_present(cfg: Path) -> bool:
    """True when every file ``cfg`` names exists (``[model] source`` may name a shipped model);
    False when one is missing and the shared recordings are absent; an AssertionError naming
    the file when one is missing although the shared recordings are here."""
    text = cfg.read_text(encoding="utf-8")
    missing = []
    for value in re.findall(_KEYS, text, flags=re.M):
        try:
            path = model_file(value, base=cfg.parent)
        except Exception:
            path = (cfg.parent / value).resolve()
        if not Path(path).exists():
            missing.append(value)
    if not missing:
        return True
    assert not real_data_dir().is_dir(), f"{cfg.name}: names files that do not exist: {missing}"
    return False
