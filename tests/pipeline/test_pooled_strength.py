"""msk.pipeline.pooled_strength (``msk strength``): the [strength] pool of a session, its
validation, and the shipped JW strength session run end to end."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from msk.config import load_config
from msk.exceptions import ConfigError
from msk.pipeline.pooled_strength import pooled_trials
from tests.support.recordings import recordings_present

REPO = Path(__file__).resolve().parents[2]
STRENGTH = REPO / "pipelines" / "strength"
POOLED = {
    "gc4_JW": {"ngait_og3", "1legstand1_task"},
    "gc5_PS": {"ngait_og_ss1", "ngait_og_ss3", "ngait_og_ss8"},
}

_SESSION = """[subject]
mass_kg = 70.0
height_m = 1.75
[model]
source = "model.toml"
[[trials]]
name = "still"
file = "still.c3d"
role = "static"
[[trials]]
name = "walk"
file = "walk.c3d"
[[trials]]
name = "squat"
file = "squat.c3d"
[[trials]]
name = "mvc_knee"
file = "mvc.c3d"
role = "mvc"
"""


def _cfg(tmp_path: Path, strength: str = ""):
    for f in ("model.toml", "still.c3d", "walk.c3d", "squat.c3d", "mvc.c3d"):
        (tmp_path / f).write_text("")
    p = tmp_path / "s.toml"
    p.write_text(_SESSION + (f"[strength]\n{strength}\n" if strength else ""), encoding="utf-8")
    return load_config(p)


def test_pool_defaults_to_every_task_and_mvc_trial_and_keeps_its_order(tmp_path: Path) -> None:
    assert [t.name for t in pooled_trials(_cfg(tmp_path))] == ["walk", "squat", "mvc_knee"]
    cfg = _cfg(tmp_path, 'pool = ["squat", "walk"]\nwindow_s = 2.0')
    assert [t.name for t in pooled_trials(cfg)] == ["squat", "walk"]
    assert cfg.strength.window_s == 2.0


@pytest.mark.parametrize(
    ("pool", "said"), [('["still"]', "role 'static'"), ('["jump"]', "'jump', which is no trial")]
)
def test_pool_names_only_task_and_mvc_trials(tmp_path: Path, pool: str, said: str) -> None:
    with pytest.raises(ConfigError, match=r"strength\.pool") as e:
        _cfg(tmp_path, f"pool = {pool}")
    assert said in str(e.value)


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.parametrize("name", sorted(POOLED))
def test_shipped_strength_sessions_give_every_group_a_status_reason_and_protocol(
    tmp_path: Path, name: str
) -> None:
    """JW's gait and single-leg stance, PS's three gait trials, pooled (no MVC trial:
    session-peak normalisation, stated with its bias in every group's reason): exit 0; every
    group a status and a reason judged on its own rows; a group on a bound never identified;
    every group not identified a protocol entry."""
    cfg = STRENGTH / f"{name}.toml"
    if not recordings_present(cfg):
        pytest.skip(f"the {name} recordings are not here")
    from msk.cli import main

    assert main(["strength", str(cfg), "--out", str(tmp_path), "--quiet"]) == 0
    rec = json.loads((tmp_path / "strength.json").read_text())
    assert rec["normalisation_kind"] == "session_peak"
    assert "too LOW" in rec["normalisation_bias"]
    assert set(rec["trials"]) == POOLED[name]
    assert all(t["rows"] > 0 for t in rec["trials"].values())
    assert {v["source"] for v in rec["normalisation"].values()} == {"session_peak"}
    for g in rec["groups"]:
        assert g["status"] in ("identified", "at bound", "not determined", "prior")
        assert "lower bound on the strength" in g["reason"]
        lo, hi = 0.5, 2.0
        if g["factor"] is not None and not (lo + 1e-6 < g["factor"] < hi - 1e-6):
            assert g["status"] != "identified", g
        if g["status"] != "identified":
            assert "protocol" in g
    for g, v in rec["failed_channels"].items():  # left out: in which trial, which check
        assert v["failed_in"] and all(v["failed_in"].values()), (g, v)
    assert (tmp_path / "strength.txt").read_text().startswith("group")
