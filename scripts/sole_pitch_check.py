"""The sole's pitch at foot flat (msk.sole_level) in a config's shipped pipeline: model and
kinematics stages (msk.pipeline.session.run_stages), the foot-flat frames from the task's
markers, the calcaneus pitch at the kinematics' (filtered) poses there; and the ankle angle's
1st–99th percentiles and the IK marker RMS. Usage: sole_pitch_check.py CONFIG..."""

from __future__ import annotations

import sys

import numpy as np

from msk.pipeline.session import run_stages
from msk.sole_level import foot_flat_frames, sole_pitch


def main(paths: list[str]) -> None:
    for path in paths:
        res = run_stages(path, until="kinematics")
        built, kin = res["model"], res["kinematics"]
        model = built.model
        up = -np.asarray(model.gravity, dtype=float)
        up /= np.linalg.norm(up)
        x, labels, t = built.trial.markers, built.labels, np.asarray(kin.time, dtype=float)
        line = [
            path.split("/")[-1].removesuffix(".toml"),
            f"IK rms {1000 * np.nanmedian(kin.marker_rms):.2f} mm",
        ]
        for s in ("r", "l"):
            foot = [m.name for m in model.markers if m.body == f"calcn_{s}" and m.name in labels]
            h = x[:, [labels.index(m) for m in foot]] @ up
            flat = foot_flat_frames(h, t)
            q = np.asarray(kin.q, dtype=float)
            ok = flat & np.isfinite(q).all(axis=1)
            ci = model.coordinate_index(f"ankle_angle_{s}")
            a = np.degrees(np.nanpercentile(q[:, ci], [1, 50, 99]))
            if ok.sum():
                p = np.degrees(sole_pitch(model, q[ok], f"calcn_{s}"))
                lo, hi = np.percentile(p, [25, 75])
                pt = f"pitch med {np.median(p):+.1f} (IQR {lo:+.1f}…{hi:+.1f})"
            else:
                pt = "pitch: no flat frame"
            pct = "/".join(f"{v:+.1f}" for v in a)
            line.append(f"{s}: flat {ok.sum()}/{len(t)} {pt}; ankle p1/50/99 {pct}")
        print(" | ".join(line), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
