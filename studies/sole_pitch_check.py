"""The sole's pitch at foot flat (msk.personalise.sole_level) in a config's shipped pipeline.

    python studies/sole_pitch_check.py pipelines/gc5_PS.toml ...

Issue 15, ankle pass (docs/validation.md). Per config: the model and kinematics stages
(msk.pipeline.session.run_stages), the foot-flat frames from the task's markers, the calcaneus
pitch at the kinematics' (filtered) poses there (median, IQR), the ankle angle's 1st / 50th /
99th percentiles and the IK marker RMS; with a static trial, also the same placed model's IK on
20 frames of the static's still window and the sole's pitch and the ankle there (the feet stand
flat in a static). Nothing is asserted (tests/personalise/test_sole_level.py is the test).
"""

from __future__ import annotations

import sys
from typing import Any

import numpy as np

from msk.kinematics.ik import solve_kinematics
from msk.model.markersets import zeros_as_gaps
from msk.personalise.sole_level import foot_flat_frames, sole_pitch
from msk.personalise.static_trial import read_static_trial
from msk.pipeline.inputs import session_inputs
from msk.pipeline.session import run_stages


def standing(path: str, built: Any) -> str:
    """The sole's pitch and the ankle (deg) in the static's still window, or ""."""
    from msk.config import load_config

    inputs = session_inputs(load_config(path))
    if inputs.static is None:
        return ""
    model = built.model
    up = -np.asarray(model.gravity, dtype=float)
    up /= np.linalg.norm(up)
    static = read_static_trial(inputs.static.file, up)
    sm, slabels, stime, window = static.markers, static.labels, static.time, static.window
    sm = zeros_as_gaps(np.asarray(sm))[window.frames]
    stime = np.asarray(stime)[window.frames]
    inv = {v: k for k, v in built.rename.items()}
    labels = tuple(inv.get(lab, lab) for lab in slabels)
    k = np.linspace(0, len(stime) - 1, min(20, len(stime))).astype(int)
    kin = solve_kinematics(model, sm[k], labels, stime[k], cutoff_hz=None)
    q = np.asarray(kin.q_raw)
    ok = np.isfinite(q).all(axis=1)
    parts = [f"static IK {1000 * np.nanmedian(kin.marker_rms):.1f} mm"]
    for s in ("r", "l"):
        p = np.degrees(np.median(sole_pitch(model, q[ok], f"calcn_{s}")))
        a = np.degrees(np.median(q[ok, model.coordinate_index(f"ankle_angle_{s}")]))
        parts.append(f"{s} standing pitch {p:+.1f}, ankle {a:+.1f}")
    return " | " + "; ".join(parts)


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
        print(" | ".join(line) + standing(path, built), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
