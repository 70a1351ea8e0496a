"""Live mode against ``msk run`` on the same trial (docs/validation.md, "Live mode against the
offline run"): each session's task trial replayed through :class:`msk.live.LiveSession`, every
output read at ``time − lag_s`` against the offline run interpolated there, after the causal
filter's 0.3 s start-up; and the offline IK's own angles through the live filter (what the
causal filter alone costs).

The offline reference is the session with the live mode's criterion (static optimisation, no
compartment rows; ``--shipped``: the session as shipped) on the inertias it identifies; the live
chain is set up on the same model (the identified inertias, the plates assigned as the session
assigns them).

    .venv/bin/python studies/live_agreement.py [--sessions gc5_PS gc6_DM_og1] [--order 2]
        [--shipped] [--smoother linear_phase]
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from msk.config import load_config
from msk.dynamics.identification import identified_model
from msk.live import LiveOptions, LiveSession, live_model
from msk.live.sources import ReplaySource
from msk.pipeline.inputs import session_inputs
from msk.pipeline.session import run_stages
from msk.signal import CausalLowpass

ROOT = Path(__file__).resolve().parents[1]
START_UP_S = 0.3


def _at(t: np.ndarray, time: np.ndarray, x: np.ndarray) -> np.ndarray:
    cols = range(x.shape[1])
    return np.column_stack([np.interp(t, time, x[:, j], left=np.nan, right=np.nan) for j in cols])


def study(
    name: str,
    order: int,
    shipped: bool,
    ik_iterations: int = 10,
    scheme: str = "gradient",
    smoother: str = "butterworth",
) -> None:
    cfg = load_config(ROOT / "pipelines" / f"{name}.toml")
    if not shipped:
        opt = dataclasses.replace(
            cfg.optimization, method="static_optimization", compartment_nonnegative=False
        )
        # the live knee contact takes the quadriceps' own lines of action (no patellar tendon)
        cfg = dataclasses.replace(
            cfg, optimization=opt, contact=dataclasses.replace(cfg.contact, patella="none")
        )
    res = run_stages(cfg, until="knee_contact")
    pers, inputs = res["model"], session_inputs(cfg)
    task = inputs.task
    assert task is not None
    src = ReplaySource(task.file, grf=task.grf, external_loads=task.external_loads)
    model = identified_model(
        pers.model, res.get("mass_identification"), by_status=inputs.inertias_by_status
    )
    to_model = {lab: m for m, lab in pers.rename.items()}
    knee = f"knee{inputs.sfx}"
    assign = {**src.assignment, **cfg.loads.assign}
    cut = cfg.filters.kinematics_cutoff_hz or 6.0
    lm = live_model(
        model, [to_model.get(lab, lab) for lab in src.labels], src.rate_hz,
        rotation=pers.rotation, weights=cfg.marker_weights, held=pers.held,
        options=LiveOptions(knee_joint=knee, cutoff_hz=cut, filter_order=order,
                            activation_weights=cfg.optimization.activation_weights,
                            ik_iterations=ik_iterations, derivative_scheme=scheme,
                            smoother=smoother),
        plateau=inputs.knee_plateau(model, knee), body_weight_n=inputs.body_weight,
        plate_bodies=[assign.get(p) for p in src.plate_names],
    )  # fmt: skip
    session = LiveSession(lm)
    out = [session.step(f) for f in src]
    kin, tq = res["kinematics"], res["inverse_dynamics"].torques
    t = np.array([f.time for f in out]) - session.lag_s
    late = t > kin.time[0] + START_UP_S
    act = lm.actuated
    dq = np.degrees(np.abs(np.array([f.q for f in out]) - _at(t, kin.time, kin.q)))[late][:, act]
    # the causal filter alone: the offline IK's raw angles through it
    raw = kin.q_raw
    filt = CausalLowpass(
        raw.shape[1], rate_hz=src.rate_hz, cutoff_hz=cut, order=order, scheme=scheme
    )
    ys = np.full_like(raw, np.nan)
    for k in np.flatnonzero(np.isfinite(raw).all(axis=1)):
        filt.step(raw[k])
        ys[k] = filt.y
    tt = kin.time - filt.lag_s
    alone = np.degrees(np.abs(ys - _at(tt, kin.time, kin.q)))[tt > kin.time[0] + START_UP_S]
    alone = alone[:, act]
    rms = np.array([f.marker_rms for f in out])
    its = np.array([f.ik_iterations for f in out])
    what = "shipped" if shipped else "static optimisation"
    print(f"\n{name} ({what}, {smoother}, order {order}, {scheme} differences): "
          f"{len(out)} frames, lag {1e3 * session.lag_s:.1f} ms; IK {its.mean():.1f} steps a "
          f"frame, RMS marker error median {1e3 * np.nanmedian(rms):.1f} mm")  # fmt: skip
    print(f"  angles: max {np.nanmax(dq):.2f}°, p95 {np.nanpercentile(dq, 95):.2f}° "
          f"(the filter alone: max {np.nanmax(alone):.2f}°, "
          f"p95 {np.nanpercentile(alone, 95):.2f}°)")  # fmt: skip
    names = lm.coordinate_names
    cols = [i for i, c in enumerate(names)
            if c.endswith(inputs.sfx) and c.startswith(("hip", "knee", "ankle"))]  # fmt: skip
    err = np.abs(np.array([f.torques for f in out]) - _at(t, kin.time, tq.tau))[late][:, cols]
    peak = np.nanmax(np.abs(tq.tau[:, cols]), axis=0)
    rel = 100 * err / peak
    for j, c in enumerate(cols):
        print(
            f"  {names[c]:<18s} torque (peak {peak[j]:5.1f} N·m): max "
            f"{np.nanmax(rel[:, j]):5.1f} %, p95 {np.nanpercentile(rel[:, j], 95):5.1f} %"
        )
    v = res["knee_contact"].variants["generic"]
    bw = inputs.body_weight
    for comp in ("axial", "medial", "lateral"):
        off = np.interp(t, kin.time, getattr(v, comp), left=np.nan, right=np.nan)
        live = np.array([getattr(f, f"knee_{comp}") for f in out])
        d = (np.abs(live - off) / bw)[late & np.isfinite(off)]
        print(f"  knee {comp:<8s}: max {d.max():.3f} BW, p95 {np.percentile(d, 95):.3f} BW "
              f"({d.size} frames)")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sessions", nargs="+", default=["gc5_PS", "gc6_DM_og1"])
    ap.add_argument("--order", type=int, default=2, help="the causal filter's order")
    ap.add_argument("--shipped", action="store_true", help="against the session as shipped")
    ap.add_argument("--ik-iterations", type=int, default=10, help="LM steps per frame at most")
    ap.add_argument("--scheme", default="gradient", choices=("central", "gradient"),
                    help="the causal filter's differences")  # fmt: skip
    ap.add_argument("--smoother", default="butterworth", choices=("butterworth", "linear_phase"),
                    help="the live filter (LiveOptions.smoother)")  # fmt: skip
    args = ap.parse_args()
    for name in args.sessions:
        study(name, args.order, args.shipped, args.ik_iterations, args.scheme, args.smoother)


if __name__ == "__main__":
    main()
