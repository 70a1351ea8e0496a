"""Live mode against ``msk run`` on the bundled trial (gc5 PS, ``pipelines/gc5_PS.toml``): the
joint angles, torques and knee contact of the stream, read at ``time − lag_s``, against the
offline run's, after the causal filter's start-up.

The offline reference is the same session with the live mode's criterion (static optimisation
with the session's activation weights, no compartment rows: the EMG-assisted gains are fitted
on the whole trial) and both on the inertias the session identifies; what remains is owed to
the causal filter (the live IK equals the offline IK: FrameIK) and to the causal plate
assignment. Targets (issue: angles within 1°, torques within 5 % of peak, contact within
0.1 BW) and what is achieved are tabulated in docs/validation.md ("Live mode against the
offline run"); the bounds below are the achieved figures, rounded up, so that a regression
fails."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def streamed():
    from msk.config import load_config
    from msk.dynamics.identification import identified_model
    from msk.live import LiveOptions, LiveSession, live_model
    from msk.live.sources import ReplaySource
    from msk.pipeline.inputs import session_inputs
    from msk.pipeline.session import run_stages

    cfg = load_config(ROOT / "pipelines" / "gc5_PS.toml")
    cfg = dataclasses.replace(
        cfg,
        optimization=dataclasses.replace(
            cfg.optimization, method="static_optimization", compartment_nonnegative=False
        ),
        # the live knee contact takes the quadriceps' own lines of action (no patellar tendon)
        contact=dataclasses.replace(cfg.contact, patella="none"),
    )
    res = run_stages(cfg, until="knee_contact")
    pers, inputs = res["model"], session_inputs(cfg)
    model = identified_model(pers.model, res["mass_identification"])
    assert inputs.task is not None
    src = ReplaySource(inputs.task.file)
    to_model = {lab: m for m, lab in pers.rename.items()}
    knee = f"knee{inputs.sfx}"
    lm = live_model(
        model, [to_model.get(lab, lab) for lab in src.labels], src.rate_hz,
        rotation=pers.rotation, weights=cfg.marker_weights, held=pers.held,
        options=LiveOptions(knee_joint=knee, activation_weights="volume"),
        plateau=inputs.knee_plateau(model, knee), body_weight_n=inputs.body_weight,
    )  # fmt: skip
    session = LiveSession(lm)
    out = [session.step(f) for f in src]
    t = np.array([f.time for f in out]) - session.lag_s
    return res, inputs, lm, out, t


def _at(t, time, series):
    cols = range(series.shape[1])
    return np.column_stack(
        [np.interp(t, time, series[:, j], left=np.nan, right=np.nan) for j in cols]
    )


@pytest.mark.slow
def test_live_angles_follow_the_offline_run(streamed):
    res, _, lm, out, t = streamed
    kin = res["kinematics"]
    late = t > kin.time[0] + 0.3
    d = np.degrees(np.abs(np.array([f.q for f in out]) - _at(t, kin.time, kin.q)))[late]
    d = d[:, lm.actuated]
    assert np.nanmax(d) < 1.1  # target 1°: 1.08° achieved, the causal filter's alone
    assert np.nanpercentile(d, 95) < 0.45


@pytest.mark.slow
def test_live_torques_follow_the_offline_run(streamed):
    res, inputs, lm, out, t = streamed
    kin, tq = res["kinematics"], res["inverse_dynamics"].torques
    late = t > kin.time[0] + 0.3
    cols = [i for i, c in enumerate(lm.coordinate_names)
            if c.endswith(inputs.sfx) and c.startswith(("hip", "knee", "ankle"))]  # fmt: skip
    err = np.abs(np.array([f.torques for f in out]) - _at(t, kin.time, tq.tau))[late][:, cols]
    rel = err / np.nanmax(np.abs(tq.tau[:, cols]), axis=0)
    # target 5 % of each coordinate's peak: 95th percentile 4–22 %, at most 4.5–28 % achieved
    assert np.nanpercentile(rel, 95, axis=0).max() < 0.23
    assert np.nanmax(rel) < 0.30


@pytest.mark.slow
def test_live_knee_contact_follows_the_offline_run(streamed):
    res, inputs, _, out, t = streamed
    kin, v = res["kinematics"], res["knee_contact"].variants["generic"]
    late = t > kin.time[0] + 0.3
    bw = inputs.body_weight
    worst = {}
    for comp in ("axial", "medial", "lateral"):
        off = np.interp(t, kin.time, getattr(v, comp), left=np.nan, right=np.nan)
        live = np.array([getattr(f, f"knee_{comp}") for f in out])
        d = (np.abs(live - off) / bw)[late & np.isfinite(off)]
        assert d.size > 60
        worst[comp] = float(d.max())
    # target 0.1 BW: axial 0.176, medial 0.128, lateral 0.077 BW achieved
    assert worst["axial"] < 0.19 and worst["medial"] < 0.14 and worst["lateral"] < 0.09, worst


@pytest.mark.slow
def test_the_linear_phase_smoother_trades_lag_for_agreement(streamed):
    """The offline filter as a symmetric FIR (14 samples each side at 120 Hz): every frequency
    delayed alike, 133 ms instead of 54 ms; angles, the hip flexion and ankle torques and the
    medial and lateral contact agree better, the hip rotation and knee torques still miss the
    5 % target (docs/validation.md)."""
    from msk.live import LiveSession
    from msk.live.sources import ReplaySource

    res, inputs, lm, _, _ = streamed
    opts = dataclasses.replace(lm.options, smoother="linear_phase")
    session = LiveSession(dataclasses.replace(lm, options=opts))
    out = [session.step(f) for f in ReplaySource(inputs.task.file)]
    assert session.lag_s == pytest.approx(16 / 120.0)  # 14 samples and the differences' 2
    t = np.array([f.time for f in out]) - session.lag_s
    kin, tq = res["kinematics"], res["inverse_dynamics"].torques
    late = t > kin.time[0] + 0.3
    d = np.degrees(np.abs(np.array([f.q for f in out]) - _at(t, kin.time, kin.q)))[late]
    assert np.nanmax(d[:, lm.actuated]) < ANGLES_LINEAR_PHASE
    names = lm.coordinate_names
    cols = [i for i, c in enumerate(names)
            if c.endswith(inputs.sfx) and c.startswith(("hip", "knee", "ankle"))]  # fmt: skip
    err = np.abs(np.array([f.torques for f in out]) - _at(t, kin.time, tq.tau))[late][:, cols]
    worst = np.nanmax(err / np.nanmax(np.abs(tq.tau[:, cols]), axis=0), axis=0)
    got = {names[c].removesuffix(inputs.sfx): float(w) for c, w in zip(cols, worst)}
    for name, bound in TORQUES_LINEAR_PHASE.items():
        assert got[name] < bound, (name, got)


#: achieved on PS with the linear-phase smoother, rounded up (max, fraction of peak)
ANGLES_LINEAR_PHASE = 0.75
TORQUES_LINEAR_PHASE = {
    "hip_flexion": 0.05,
    "hip_adduction": 0.065,
    "hip_rotation": 0.25,
    "knee_angle": 0.165,
    "ankle_angle": 0.032,
}


@pytest.mark.slow
def test_msk_live_cli_writes_the_streamed_tables(tmp_path, capsys):

    from msk.cli import main
    from msk.io.tables import read_csv_table

    out = tmp_path / "live"
    code = main([
        "live", str(ROOT / "pipelines" / "gc5_PS.toml"),
        "--replay", str(ROOT / "data" / "gc5-PS" / "PS_ngait_og_ss1.c3d"), "--out", str(out),
    ])  # fmt: skip
    assert code == 0
    text = capsys.readouterr().out
    assert "chain" in text and "p99" in text and "lag" in text
    q = read_csv_table(out / "tables" / "q.csv")
    kc = read_csv_table(out / "tables" / "knee_contact.csv")
    assert q.data.shape[0] == kc.data.shape[0] == 145
    assert np.isfinite(kc.column("live_axial_bw")).all()
