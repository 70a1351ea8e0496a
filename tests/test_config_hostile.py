"""msk.config: a hostile configuration is one ConfigError line, never a traceback."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from msk.config import load_config
from msk.exceptions import ConfigError

REPO = Path(__file__).resolve().parents[1]


def _gc5(tmp_path: Path, old: str, new: str) -> Path:
    text = (REPO / "pipelines" / "gc5_PS.toml").read_text(encoding="utf-8")
    text = text.replace('"../', f'"{REPO}/')
    assert old in text
    cfg = tmp_path / "s.toml"
    cfg.write_text(text.replace(old, new), encoding="utf-8")
    return cfg


def test_deep_nesting(tmp_path):
    (tmp_path / "d.toml").write_text("a = " + "[" * 100_000 + "]" * 100_000 + "\n")
    with pytest.raises(ConfigError, match="nested too deeply"):
        load_config(tmp_path / "d.toml")


def test_a_400_digit_mass(tmp_path):
    with pytest.raises(ConfigError, match="401 digits"):
        load_config(_gc5(tmp_path, "mass_kg = 82.8", "mass_kg = 1" + "0" * 400))


def test_a_nul_byte_in_a_path(tmp_path):
    cfg = _gc5(tmp_path, "PS_ngait_og_ss1.c3d", "PS_ngait\\u0000og.c3d")
    with pytest.raises(ConfigError, match="NUL"):
        load_config(cfg)


def test_a_symlink_loop(tmp_path):
    os.symlink(tmp_path / "b", tmp_path / "a")
    os.symlink(tmp_path / "a", tmp_path / "b")
    cfg = _gc5(tmp_path, f"{REPO}/data/gc5-PS/PS_ngait_og_ss1.c3d", str(tmp_path / "a"))
    with pytest.raises(ConfigError, match=r"cannot be resolved"):
        load_config(cfg)
