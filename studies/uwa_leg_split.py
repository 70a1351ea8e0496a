"""How the leg is split between femur and tibia in a session without knee or ankle markers.

    python studies/uwa_leg_split.py [config ...]   (default: pipelines/uwa_fast_walking.toml;
    docs/validation.md ran it on uwa_fast_walking, gc6_DM_og1 and uwa_running)

Issue 15, sixth pass (docs/validation.md). Without a knee or ankle marker the femur and the tibia
get one factor, the pose-matched ASIS-to-heel distance over the generic model's
(``msk.personalise.scaling.SEGMENT_MEASUREMENTS``, ``leg_<side>``): the generic femur : tibia
proportion is
kept. Two pieces of evidence from the motion itself on how this subject's leg is split:

1. **functional joint centres** (SCoRE, Ehrig et al. 2006 J Biomech 39:2798, Eq. 3): the point
   fixed in both the thigh cluster's and the shank cluster's frames (the knee), and in both the
   shank cluster's and the foot markers' (the ankle), by linear least squares over the frames
   that track all six markers; printed in the scaled model's femur / tibia frames against its
   own knee / ankle (x anterior, y proximal, z lateral-right; the knee's point is defined only
   up to its flexion axis, so z there means little);
2. **what-if factors**: the session re-run (``msk.cli.main``) with the femur and tibia factors
   multiplied by ``f`` and ``t`` (``msk.personalise.scaling.scale_from_motion`` wrapped in this
   process
   only): IK marker RMS (the markers' verdict), residual force and moment after mass
   identification (the plates' verdict, reported not chosen on).

Evidence of the sixth pass; the seventh ships the rule it led to (``msk.personalise.leg_split``: the
femur
to the functional knee, the tibia the rest of the leg), so the what-if factors here now multiply
whatever the scaling gives, that split included (the figures of docs/validation.md's sixth pass
were taken before it).
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parent.parent
GRID = [(1.0, 1.0), (1.0, 0.97), (1.0, 0.93), (1.03, 0.93), (1.03, 1.0), (0.97, 0.97), (0.97, 0.93)]
CLUSTERS = {
    "r": (("RTH1", "RTH2", "RTH3"), ("RTB1", "RTB2", "RTB3"), ("RCAL", "RMT1", "RMT5")),
    "l": (("LTH1", "LTH2", "LTH3"), ("LTB1", "LTB2", "LTB3"), ("LCAL", "LMT1", "LMT5")),
}


def _frames(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation (N, 3, 3) and origin (N, 3) of a 3-marker cluster x (3, N, 3)."""
    e1 = x[1] - x[0]
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e3 = np.cross(e1, x[2] - x[0])
    e3 /= np.linalg.norm(e3, axis=1)[:, None]
    return np.stack([e1, np.cross(e3, e1), e3], axis=2), x.mean(axis=0)


def score_centre(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, float]:
    """SCoRE (Ehrig et al. 2006, Eq. 3): world trajectory (N, 3) of the point fixed in both
    3-marker clusters ``a`` and ``b`` (each (3, N, 3), every frame tracked), and the RMS
    mismatch (m) of its two estimates."""
    ra, oa = _frames(a)
    rb, ob = _frames(b)
    lhs = np.concatenate([np.concatenate([ra[k], -rb[k]], axis=1) for k in range(ra.shape[0])])
    rhs = np.concatenate([ob[k] - oa[k] for k in range(ra.shape[0])])
    sol = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    ca = np.einsum("nij,j->ni", ra, sol[:3]) + oa
    cb = np.einsum("nij,j->ni", rb, sol[3:]) + ob
    return ca, float(np.sqrt(np.mean(np.sum((ca - cb) ** 2, axis=1))))


def joint_centres(cfg_path: Path) -> None:
    import pinocchio as pin

    from msk.config import load_config
    from msk.pipeline import run_stages

    r = run_stages(load_config(cfg_path), until="kinematics")
    kin, bm = r["kinematics"], r["model"]
    model, trial = bm.model, bm.trial
    pm, data = model.pin_model, model.create_data()
    labels = list(trial.marker_labels)
    x = np.asarray(trial.markers, dtype=float)
    t, q, v = np.asarray(kin.time), np.asarray(kin.q), np.asarray(kin.v)
    tt = np.asarray(trial.time)
    for side, (thigh, shank, foot) in CLUSTERS.items():
        if not all(m in labels for m in (*thigh, *shank, *foot)):
            print(f"{cfg_path.name} {side}: clusters incomplete, skipped")
            continue
        for name, (pa, pb), parent, child in (
            ("knee", (thigh, shank), f"hip_{side}_2", f"knee_{side}_2"),
            ("ankle", (shank, foot), f"knee_{side}_2", f"ankle_{side}"),
        ):
            xa = np.stack([x[:, labels.index(m)] for m in pa])
            xb = np.stack([x[:, labels.index(m)] for m in pb])
            seen = np.isfinite(xa).all(axis=(0, 2)) & np.isfinite(xb).all(axis=(0, 2))
            c, mis = score_centre(xa[:, seen], xb[:, seen])
            cs = np.column_stack(
                [np.interp(t, tt[seen], c[:, i], left=np.nan, right=np.nan) for i in range(3)]
            )
            jp, jc = pm.getJointId(parent), pm.getJointId(child)
            rel = []
            for k in np.flatnonzero(np.isfinite(cs).all(axis=1) & np.isfinite(q).all(axis=1)):
                qp, _, _ = model.coupling.embed(q[k : k + 1], v[k : k + 1], v[k : k + 1])
                pin.forwardKinematics(pm, data, qp[0])
                rel.append(
                    data.oMi[jp].actInv(cs[k]) - data.oMi[jp].actInv(data.oMi[jc].translation)
                )
            d = 1000 * np.median(np.asarray(rel), axis=0)
            print(
                f"{cfg_path.name} {side} {name}: SCoRE − model {name} in the "
                f"{'femur' if name == 'knee' else 'tibia'} frame x {d[0]:+.1f} y {d[1]:+.1f} "
                f"z {d[2]:+.1f} mm (median of {len(rel)} frames; mismatch {1000 * mis:.1f} mm "
                f"RMS over {int(seen.sum())})"
            )


def what_if(cfg_path: Path, femur: float, tibia: float, out: Path) -> dict[str, Any]:
    import msk.personalise.scaling as scaling
    from msk.cli import main

    orig = scaling.scale_from_motion

    def wrapped(model: Any, *args: Any, **kw: Any) -> Any:
        scaled, rep = orig(model, *args, **kw)
        f = {b: np.asarray(s, dtype=float) for b, s in rep.factors.items()}
        for s in "rl":
            f[f"femur_{s}"] = f[f"femur_{s}"] * femur
            f[f"tibia_{s}"] = f[f"tibia_{s}"] * tibia
        meta = {k: scaled.metadata[k] for k in ("scale_ratios", "scale_methods")}
        new = scaling.apply_scale_factors(model, f, body_mass=kw.get("body_mass"))
        return new.with_metadata(**meta), rep

    scaling.scale_from_motion = wrapped  # type: ignore[assignment]
    try:
        main(["run", str(cfg_path), "--out", str(out)])
    finally:
        scaling.scale_from_motion = orig  # type: ignore[assignment]
    return dict(json.loads((out / "summary.json").read_text())["quality"])


def main() -> int:
    cfgs = [Path(a) for a in sys.argv[1:]] or [REPO / "pipelines" / "uwa_fast_walking.toml"]
    folder = Path(tempfile.mkdtemp())
    for cfg in cfgs:
        joint_centres(cfg)
    print("| config | femur × | tibia × | IK (mm) | residual (% BW) | moment (N·m) | flags |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for cfg in cfgs:
        for f, tb in GRID:
            qd = what_if(cfg, f, tb, folder / f"{cfg.stem}_{f}_{tb}")
            print(
                f"| {cfg.stem} | {f:.2f} | {tb:.2f} | {1000 * qd['ik_marker_rms_mean_m']:.1f} "
                f"| {qd['residual_force_rms_pct_bw']:.2f} | {qd['residual_moment_rms_nm']:.1f} "
                f"| {len(qd['flags'])} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
