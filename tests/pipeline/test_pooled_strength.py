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


def _record() -> dict:
    """A pooled record as :func:`run_pooled_strength` returns it: knee extensors identified,
    plantar flexors on the lower bound but written "identified" (a hand-edited or foreign
    file), dorsiflexors not determined, one channel that failed a check."""

    def grp(name, factor, ci, status, moment=None, protocol=None):
        return {
            "group": name, "muscles": [f"{name}_r"], "factor": factor, "ci_bootstrap": ci,
            "ci_jackknife_t": ci, "f_iso_generic_n": 1000.0, "status": status,
            "reason": f"{name}: reason in plain words", "r2_own_rows": 0.8,
            "own_coordinates": ["knee_angle_r"], "protocol": protocol, "moment_nm": moment,
            "moment_ci_nm": [None, None] if moment is None else [0.9 * moment, 1.1 * moment],
            "moment_test": None if moment is None else "knee extension at knee flexion 60°",
        }  # fmt: skip

    proto = {"test": "isometric MVC", "action": "ankle dorsiflexion", "text": "isometric MVC "
             "of ankle dorsiflexion at ankle angle 0°"}  # fmt: skip
    return {
        "config": "s.toml", "trials": {"walk": {}, "mvc_knee": {}}, "normalisation": {},
        "normalisation_kind": "mvc", "normalisation_bias": None, "fit_r2_all_rows": 0.7,
        "confidence": 0.95, "bounds": [0.5, 2.0], "mass_kg": 70.0,
        "groups": [
            grp("knee_extensors", 1.2, [1.05, 1.35], "identified", moment=210.0),
            grp("plantar_flexors", 0.5, [0.5, 0.62], "identified", moment=99.0),
            grp("dorsiflexors", 1.4, [0.6, 2.0], "not determined", protocol=proto),
        ],
        "failed_channels": {"hamstrings": {"muscles": ["bflh_r"], "failed_in": {
            "walk": ["EMG channel 'hamstrings': flat"]}, "protocol": None}},
    }  # fmt: skip


def test_no_group_at_a_bound_is_identified_in_summary_compare_cohort_or_report(tmp_path):
    """The pooled strength goes into an ``msk run`` folder's summary.json (typed) and its
    report; a group on a bound written "identified" reads "at bound" in the summary, the
    cohort row, ``msk compare`` and the report, and shows no moment there."""
    from msk.pipeline.pooled_strength import attach_to_session
    from msk.results.cohort import cohort_row, compare_sessions
    from msk.results.folder import read_session
    from tests.support.summaries import BASE

    folder = tmp_path / "run"
    folder.mkdir()
    (folder / "summary.json").write_text(
        json.dumps({"format": "msk-session-summary/1", **BASE}), encoding="utf-8"
    )
    assert attach_to_session(folder, _record()) == [folder / "summary.json"]
    s = read_session(folder).summary
    ps = s.pooled_strength
    assert ps is not None and ps.normalisation_kind == "mvc"
    words = {g.group: ps.group_status(g) for g in (*ps.groups, *ps.failed_channels)}
    assert words == {"knee_extensors": "identified", "plantar_flexors": "at bound",
                     "dorsiflexors": "not determined", "hamstrings": "not determined"}  # fmt: skip
    row = cohort_row("s.toml", s, "ok", "", 1.0)
    cohort = dict(x.split(": ") for x in row["pooled_strength_group_status"].split("; "))
    assert cohort == words
    notes = {r["item"]: r["note"] for r in compare_sessions([folder])
             if r["quantity"] == "pooled strength factor"}  # fmt: skip
    assert notes == {k: v for k, v in words.items() if k != "hamstrings"}
    assert (folder / "report.html").is_file()
    # a session run with another configuration is not given this one's strength
    other = tmp_path / "other.toml"
    other.write_text("# another session\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="another configuration"):
        attach_to_session(folder, {**_record(), "config": str(other)})


def test_the_mvc_reference_is_the_torque_plateau_when_every_mvc_trial_is_pooled(tmp_path):
    """Every MVC trial of the session pooled (its torque known): the channel's reference is
    its mean over the highest-torque second, with a standard error, not the raw peak; an MVC
    trial left out of the pool keeps the peak (no torque to choose the plateau by)."""
    import numpy as np

    from msk.pipeline.pooled_strength import _plateau_reference
    from msk.strength.pooled import EmgReference, PooledTrial

    cfg = _cfg(tmp_path)
    rng = np.random.default_rng(0)
    n = 300  # 3 s at 100 Hz: rest, a 1.5-s hold, rest
    hold = np.zeros(n)
    hold[75:225] = 1.0
    env = (0.02 + 0.5 * hold * (1 + 0.1 * rng.standard_normal(n)))[:, None]
    tau = (80.0 * hold)[:, None]

    def trial(name, kind):
        return PooledTrial(name, kind, 100.0, ("c",), env, np.zeros((n, 1, 1)),
                           np.zeros((n, 1)), np.zeros((n, 1)), tau)  # fmt: skip

    peak = EmgReference(("c",), np.array([env.max()]), ("mvc",))
    ref = _plateau_reference(cfg, peak, [trial("walk", "task"), trial("mvc_knee", "mvc")])
    assert ref.value[0] < env.max() and abs(ref.value[0] / 0.52 - 1) < 0.05
    assert 0 < ref.relative_error("c") < 0.05
    assert _plateau_reference(cfg, peak, [trial("walk", "task")]) is peak
