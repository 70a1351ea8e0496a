"""A `[markers] rename` entry naming a label no trial has is a quality flag, not a note only
inside summary.json (a typo there changed gc5's muscle forces by +67 % silently)."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.slow
@pytest.mark.realdata
def test_a_rename_typo_is_flagged(tmp_path):
    from msk.pipeline import run_session

    text = (REPO / "pipelines" / "gc5_PS.toml").read_text(encoding="utf-8")
    text = text.replace('"../', f'"{REPO}/')
    assert '"R.ASIS" = "RAsis"' in text
    (tmp_path / "typo.toml").write_text(text.replace('"R.ASIS" = "RAsis"', '"R.ASIS" = "RAsiss"'))
    d = run_session(tmp_path / "typo.toml", tmp_path / "out").summary.to_dict()
    (flag,) = [f for f in d["quality"]["flags"] if f["quantity"] == "marker_rename_unmatched"]
    assert "RAsiss" in flag["message"] and flag["value"] == 1.0
