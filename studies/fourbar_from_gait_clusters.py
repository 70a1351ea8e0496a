"""Can a subject's four-bar knee be fitted from the thigh and shank clusters of a walk?
(issue 16, "four-bar knee on real data"; docs/validation.md, medial/lateral section item 12).

    python studies/fourbar_from_gait_clusters.py [--only gc5_PS,gc6_DM_og1,gc4_JW]

For each shipped config whose instrumented leg carries a thigh and a shank cluster (PS, DM, JW),
the config is run up to its kinematics (``msk.pipeline.run_stages``: the model scaled, the lab's
markers placed — PS and JW from their statics, DM from the walk — with the spline knee). The
clusters' placed offsets in the femur and tibia frames give, at each frame of the walk, the
tibia's pose relative to the femur by the clusters alone (Söderkvist & Wedin 1993 fits,
:func:`msk.model.fourbar_fit.fit_four_bar_from_markers`): the flexion angle θ(t) and the sagittal
path
p(t) of the tibia origin in the femur frame, which is what a functional calibration of the
four-bar (seed 004 §2.1) fits. Printed per subject: the frames and the flexion range, the path
the clusters give minus the model's knee path at the same θ (mean per 10° of flexion, RMS, 5th /
95th percentiles; + anterior, + proximal), and the four-bar fitted to it
(:func:`msk.model.fourbar_fit.fit_four_bar`, bounded as for a knee): its residual and its path minus
the model's. No contact force is read.

A knee's tibia origin moves a few millimetres antero-posteriorly with flexion and cannot move
proximally into the femur; a cluster path that rises by centimetres with flexion is the thigh
cluster sliding on the thigh (soft-tissue artefact, Cappozzo et al. 1996; Leardini et al. 2005,
10–30 mm on the thigh in gait), not a knee path.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from msk.model.fourbar_fit import fit_four_bar_from_markers, knee_path_of_joint
from msk.pipeline import run_stages

ROOT = Path(__file__).resolve().parents[1]
SESSIONS = {"gc5_PS": "l", "gc6_DM_og1": "r", "gc4_JW": "r"}


def cluster(model, markers: np.ndarray, labels: list[str], body: str):
    mk = [m for m in model.markers if m.body == body and m.name in labels]
    idx = [labels.index(m.name) for m in mk]
    return np.array([m.offset for m in mk]), markers[:, idx, :], [m.name for m in mk]


def one(config: str, side: str) -> None:
    built = run_stages(ROOT / "pipelines" / f"{config}.toml", until="model")["model"]
    model, labels = built.model, list(built.labels)
    x = built.trial.markers
    tl, tw, tn = cluster(model, x, labels, f"femur_{side}")
    sl, sw, sn = cluster(model, x, labels, f"tibia_{side}")
    ok = (np.isfinite(tw).all(-1).sum(1) >= 3) & (np.isfinite(sw).all(-1).sum(1) >= 3)
    print(f"\n### {config} (knee_{side}): thigh {', '.join(tn)}; shank {', '.join(sn)}")
    if ok.sum() < 12:
        print(f"{int(ok.sum())} frames with both clusters: not enough")
        return
    fit = fit_four_bar_from_markers(tw[ok], sw[ok], thigh_local=tl, shank_local=sl)
    joint = next(j for j in model.joints if j.name == f"knee_{side}")
    th = fit.theta
    model_path = knee_path_of_joint(joint, th)
    d_markers = 1000 * (fit.target - model_path)
    d_fit = 1000 * (fit.target + fit.residual - model_path)
    flex = -np.degrees(th)
    print(f"{int(ok.sum())} of {ok.size} frames; flexion {flex.min():.1f}–{flex.max():.1f}°")
    print(
        "\n| flexion (°) | frames | clusters − model, x / y (mm) | fitted four-bar − model (mm) |"
    )
    print("| --- | --- | --- | --- |")
    for lo in range(int(np.floor(flex.min() / 10) * 10), int(flex.max()) + 1, 10):
        sel = (flex >= lo) & (flex < lo + 10)
        if sel.any():
            a, b = d_markers[sel].mean(0), d_fit[sel].mean(0)
            print(f"| {lo}–{lo + 10} | {int(sel.sum())} | {a[0]:+.1f} / {a[1]:+.1f} | "
                  f"{b[0]:+.1f} / {b[1]:+.1f} |")  # fmt: skip
    rms = float(np.sqrt((d_markers**2).sum(1).mean()))
    p = np.percentile(d_markers, [5, 95], axis=0)
    print(f"\nclusters − model: RMS {rms:.1f} mm; x 5–95 % {p[0, 0]:+.1f}…{p[1, 0]:+.1f}, "
          f"y {p[0, 1]:+.1f}…{p[1, 1]:+.1f} mm")  # fmt: skip
    rf = float(np.sqrt((d_fit**2).sum(1).mean()))
    res, worst = 1000 * fit.rms_m, 1000 * fit.max_error_m
    print(f"four-bar fit: residual RMS {res:.1f} mm (max {worst:.1f}),"
          f" crossed {fit.crossed}; its path − model RMS {rf:.1f} mm, max "
          f"{np.abs(d_fit).max():.1f} mm")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default=",".join(SESSIONS))
    args = ap.parse_args()
    for name in args.only.split(","):
        one(name, SESSIONS[name])


if __name__ == "__main__":
    main()
