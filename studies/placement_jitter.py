"""How stable the marker placement from a motion trial is under perturbations that cannot matter.

    python studies/placement_jitter.py [--runs N] [--only uwa_fast_walking,gc6_DM_og1:ngait_og3]

Issue 15, ninth pass (docs/validation.md). Every session placed from its own motion (no static
trial: DM og1 / treadmill / crouch, UWA fast walking / running, and DM og1's task swaps og3, og4,
bouncy5, smooth1 of ``studies/task_swap.py``) is run through the model and kinematics stages
(``msk.pipeline.run_stages``) 1 + ``N`` times: unperturbed, then with a perturbation no physical
argument can care about injected in the model stage only (the trial's own IK tracks the
unperturbed markers), cycling through:

* ``factors``: the scaled femur and tibia × (1 ± 1e-4)
(``msk.personalise.scaling.scale_from_motion``
  wrapped);
* ``noise``: markers + N(0, 0.1 mm) per coordinate (exact-zero gaps kept);
* ``shift``: the trial without its first 1, 2, … frames (the placement's frame subsets move).

Printed per session: the whole trial's IK (mean marker RMS) unperturbed and its range, the
final placement's RMS range, the median and largest spread of a placed or moved marker's
body-frame offset, the femur/tibia factors' spread, the leg split's two placement RMSs per run,
and every discrete decision that flips (leg split, regularized or not, too loose / kept loose,
a marker's body, the knee branch). Nothing is asserted: this is the measurement; the test is
``tests/personalise/test_scaling.py`` (synthetic walk). ``--json`` writes the records.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "studies"))

SESSIONS = ["gc6_DM_og1", "gc6_DM_ngait_tm_ss", "gc6_DM_crouch_tm", "uwa_fast_walking",
            "uwa_running", "gc6_DM_og1:ngait_og3", "gc6_DM_og1:ngait_og4",
            "gc6_DM_og1:bouncy5", "gc6_DM_og1:smooth1"]  # fmt: skip


def _config(name: str) -> Any:
    from msk.config import load_config

    stem, _, alt = name.partition(":")
    cfg = load_config(REPO / "pipelines" / f"{stem}.toml")
    if not alt:
        return cfg
    from task_swap import ALTERNATIVES, swap_task  # type: ignore[import-not-found]

    files = dict(ALTERNATIVES[stem])[alt]
    return swap_task(cfg, alt, files)


def run_once(name: str, kind: str, k: int, seed: int) -> dict[str, Any]:
    """The model and kinematics stages of ``name`` with one perturbation ``kind`` (``none``,
    ``factors``, ``noise``, ``shift``) injected in the model stage only (the trial's own IK
    tracks the unperturbed markers)."""
    import msk.personalise.personalise as pmodel
    import msk.personalise.scaling as scaling
    from msk.pipeline import run_stages

    rng = np.random.default_rng(seed + 7919 * k)
    sign = 1.0 if k % 2 == 0 else -1.0
    orig_scale, orig_sp = scaling.scale_from_motion, pmodel.scale_and_place
    calls: list[dict[str, Any]] = []
    orig_place = scaling.place_markers_from_motion
    orig_rms = pmodel._placement_rms
    rms_pairs: list[float] = []

    def placement_rms(info):  # type: ignore[no-untyped-def]
        v = orig_rms(info)
        rms_pairs.append(1000 * v)
        return v

    def scale(model, *args, **kw):  # type: ignore[no-untyped-def]
        scaled, rep = orig_scale(model, *args, **kw)
        if kind != "factors":
            return scaled, rep
        f = {b: np.asarray(v, dtype=float) for b, v in rep.factors.items()}
        for b in ("femur_r", "femur_l", "tibia_r", "tibia_l"):
            if b in f:
                f[b] = f[b] * (1.0 + sign * 1e-4)
        meta = {m: scaled.metadata[m] for m in ("scale_ratios", "scale_methods")}
        new = scaling.apply_scale_factors(model, f, body_mass=kw.get("body_mass"))
        return new.with_metadata(**meta), rep

    def place(model, markers, labels, time, **kw):  # type: ignore[no-untyped-def]
        out = orig_place(model, markers, labels, time, **kw)
        if "median_neutral" in kw and kw.get("start") is None:  # the starts, not the descent
            calls.append(out[1])
        return out

    def scale_and_place(generic, static, task, opts, **kw):  # type: ignore[no-untyped-def]
        tr = task
        if kind == "noise":
            m = np.asarray(tr.markers, dtype=float)
            seen = (m != 0.0).any(axis=-1, keepdims=True)  # exact zeros are gaps (TRC)
            tr = dataclasses.replace(tr, markers=m + seen * rng.normal(0.0, 1e-4, m.shape))
        elif kind == "shift":
            n = 1 + k // 3
            tr = dataclasses.replace(tr, markers=tr.markers[n:], time=tr.time[n:])
        return orig_sp(generic, static, tr, opts, **kw)

    scaling.scale_from_motion = scale  # type: ignore[assignment]
    scaling.place_markers_from_motion = place  # type: ignore[assignment]
    pmodel.scale_and_place = scale_and_place  # type: ignore[assignment]
    pmodel._placement_rms = placement_rms  # type: ignore[assignment]
    try:
        r = run_stages(_config(name), until="kinematics")
    finally:
        scaling.scale_from_motion = orig_scale  # type: ignore[assignment]
        scaling.place_markers_from_motion = orig_place  # type: ignore[assignment]
        pmodel.scale_and_place = orig_sp  # type: ignore[assignment]
        pmodel._placement_rms = orig_rms  # type: ignore[assignment]
    bm, kin = r["model"], r["kinematics"]
    info = bm.info
    mp = dict(info["marker_placement"])
    offsets = {mk.name: np.asarray(mk.offset, dtype=float) for mk in bm.model.markers}
    return {
        "kind": kind,
        "ik_mm": 1000 * float(np.nanmean(kin.marker_rms)),
        "placement_mm": 1000 * float(mp["ik_marker_rms_m"]),
        "placement": mp,
        "calls": calls,
        "split_rms_mm": rms_pairs,
        "offsets": offsets,
        "leg_split": {s: v["method"] for s, v in dict(info.get("leg_split", {})).items()},
        "choice": info.get("placement_choice"),
        "factors": {
            b: float(v["factors"][0])
            for b, v in dict(info.get("scaling", {}).get("bodies", {})).items()
        },
    }


def summarise(name: str, runs: int, seed: int = 0) -> dict[str, Any]:
    kinds = ["none", *(("factors", "noise", "shift")[k % 3] for k in range(runs))]
    outs = [run_once(name, kind, k, seed) for k, kind in enumerate(kinds)]
    ik = np.array([o["ik_mm"] for o in outs])
    pl = np.array([o["placement_mm"] for o in outs])
    infos = [o["placement"] for o in outs]
    common = set.intersection(*(set(o["offsets"]) for o in outs))
    moving = set().union(*(set(i["placed"]) | set(i["moved"]) for i in infos)) & common
    off_spread = {
        lab: 1000 * float(np.max(np.linalg.norm(v - np.median(v, 0), axis=1)))
        for lab in moving
        for v in [np.array([o["offsets"][lab] for o in outs])]
    }
    flips: list[str] = []

    def flip(what: str, vals: list[Any]) -> None:
        s = sorted({repr(v) for v in vals})
        if len(s) > 1:
            flips.append(f"{what}: {' | '.join(s)}")

    flip("regularized", [i["regularized"] for i in infos])
    flip("leg split", [o["leg_split"] for o in outs])
    flip("kept_loose", [sorted(i["kept_loose"]) for i in infos])
    flip("too_loose", [sorted(i["too_loose"]) for i in infos])
    for lab in sorted(set().union(*(i["placed"] for i in infos))):
        flip(f"body of {lab}", [i["placed"].get(lab) for i in infos])
    flip("knee branch", [i["knee_flexion_branch"] for i in infos])
    flip("placement calls regularized",
         [[c["regularized"] for c in o["calls"]] for o in outs])  # fmt: skip
    fac = {b: float(np.ptp([o["factors"].get(b, np.nan) for o in outs]))
           for b in ("femur_r", "tibia_r", "femur_l", "tibia_l")}  # fmt: skip
    worst = max(off_spread, key=off_spread.__getitem__) if off_spread else "-"
    return {
        "session": name,
        "runs": len(outs),
        "kinds": kinds,
        "ik_mm": ik.tolist(),
        "placement_mm": pl.tolist(),
        "offset_spread_max_mm": [worst, off_spread.get(worst, 0.0)],
        "offset_spread_median_mm": float(np.median(list(off_spread.values()))) if off_spread else 0,
        "factor_spread": fac,
        "flips": flips,
        "split_rms_mm": [o["split_rms_mm"] for o in outs],
        "choice_mm": [
            [1000 * c["cost_m"] for c in o["choice"]["candidates"]] if o["choice"] else []
            for o in outs
        ],
        "chosen": [o["choice"]["chosen"] if o["choice"] else None for o in outs],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=6)
    ap.add_argument("--only", default="")
    ap.add_argument("--json", default="", help="write every session's record here")
    a = ap.parse_args()
    names = [s for s in a.only.split(",") if s] or SESSIONS
    records = []
    for name in names:
        r = summarise(name, a.runs)
        records.append(r)
        ik, pl = np.array(r["ik_mm"]), np.array(r["placement_mm"])
        print(
            f"{r['session']:<24} runs {r['runs']}  IK {ik[0]:.2f} mm, spread {ik.min():.2f}–"
            f"{ik.max():.2f}  placement {pl.min():.1f}–{pl.max():.1f} mm  offsets: median "
            f"spread {r['offset_spread_median_mm']:.2f} mm, worst {r['offset_spread_max_mm'][0]} "
            f"{r['offset_spread_max_mm'][1]:.1f} mm  factor spread "
            + " ".join(f"{b} {v:.1e}" for b, v in r["factor_spread"].items() if np.isfinite(v)),
            flush=True,
        )
        print("    IK per run: " + " ".join(f"{k}:{v:.2f}" for k, v in zip(r["kinds"], ik)))
        print("    leg split placement RMS (leg factor, split) mm: " + " ".join(
            "/".join(f"{v:.2f}" for v in p) for p in r["split_rms_mm"]))  # fmt: skip
        print("    candidates' task IK cost (mm, * chosen): " + " | ".join(
            " ".join(f"{v:.2f}" + ("*" if i == ch else "") for i, v in enumerate(c))
            for c, ch in zip(r["choice_mm"], r["chosen"])))  # fmt: skip
        print("    flips: " + ("; ".join(r["flips"]) or "none"), flush=True)
    if a.json:
        Path(a.json).write_text(json.dumps(records, indent=1, default=str))


if __name__ == "__main__":
    main()
