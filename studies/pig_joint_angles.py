"""The report's hip and knee angles against Vicon's stored Plug-in Gait angles on the BTKData
Plug-in Gait walks, the shipped session ``pipelines/pig_motion3.toml`` with its trial files
swapped (:mod:`studies.pig_sessions`).

Per walk and side, over every frame both have: msk's reported angles (the gait analysis'
variables: hip angles of the thigh relative to the reported pelvis frame, knee flexion by the
config's ``[gait] angle_convention``) and, before, the model's coordinates (``hip_flexion``,
``hip_adduction``, ``hip_rotation``, −``knee_angle``), minus Vicon's ``<S>HipAngles`` X / Y / Z
and ``<S>KneeAngles`` X: RMS, mean and r. And the knee centre: Vicon's ``<S>FEO`` minus msk's
(the tibia origin) in msk's femur frame, per frame (median, SD, 5th-95th percentile of x).
Run: ``python studies/pig_joint_angles.py [data folder]``.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

from msk.config import load_config
from msk.io import read_c3d
from msk.model.core import forward_kinematics
from msk.pipeline.session import run_stages
from studies.pig_sessions import WALKS, _config, _output

PLANES = (("flexion", 0), ("adduction", 1), ("rotation", 2))


def _stats(ours: np.ndarray, theirs: np.ndarray) -> str:
    ok = np.isfinite(ours) & np.isfinite(theirs)
    d = ours[ok] - theirs[ok]
    r = np.corrcoef(ours[ok], theirs[ok])[0, 1]
    return f"RMS {np.sqrt(np.mean(d**2)):4.1f}, mean {d.mean():+5.1f}, r {r:.3f} (n {ok.sum()})"


def study(real: Path, task: str, static: str | None, mass: float) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        r = run_stages(load_config(_config(real, task, static, mass, Path(tmp))),
                       until="gait_analysis")  # fmt: skip
    built, kin, ga = r["model"], r["kinematics"], r["gait_analysis"]
    model = built.model
    raw = read_c3d(real / "btkdata" / f"{task}.c3d")
    t_raw = np.asarray(raw.time, dtype=float)
    t = np.asarray(kin.time, dtype=float)
    print(f"\n{task} (static: {static or 'none'})")
    for note in ga.variables.notes:
        print(f"  note: {note}")

    def vicon(stem: str, k: int) -> np.ndarray:
        y = _output(raw, stem)[:, k].astype(float)
        y = np.degrees(y) if np.nanmax(np.abs(y)) < 4.0 else y  # some files store radians
        return np.interp(t, t_raw, y, left=np.nan, right=np.nan)

    data = model.create_data()
    for side in "RL":
        s = {"R": "right", "L": "left"}[side]
        series = ga.variables.series[s]
        for plane, k in PLANES:
            before = np.degrees(kin.coordinate(f"hip_{plane}_{s[0]}"))
            pig = vicon(f"{side}HipAngles", k)
            print(f"  {side} hip {plane:9s} before {_stats(before, pig)}; "
                  f"after {_stats(series[f'hip_{plane}_deg'], pig)}")  # fmt: skip
        before = -np.degrees(kin.coordinate(f"knee_angle_{s[0]}"))
        pig = vicon(f"{side}KneeAngles", 0)
        after = series["knee_flexion_deg"]
        common = np.where(np.isfinite(after), before, np.nan)  # on the frames of both
        print(f"  {side} knee flexion    before {_stats(before, pig)}; "
              f"on after's frames {_stats(common, pig)}; after {_stats(after, pig)}")  # fmt: skip
        ff, ft = model.body_frame[f"femur_{s[0]}"], model.body_frame[f"tibia_{s[0]}"]
        feo = np.asarray(built.trial.marker(f"{side}FEO"), dtype=float)
        t_tr = np.asarray(built.trial.time, dtype=float)
        d = []
        for i, ti in enumerate(t):
            j = int(np.argmin(np.abs(t_tr - ti)))
            if not (np.isfinite(kin.q[i]).all() and np.isfinite(feo[j]).all()):
                continue
            forward_kinematics(model, data, kin.q[i])
            rf = np.asarray(data.oMf[ff].rotation)
            d.append(1000.0 * rf.T @ (feo[j] - np.asarray(data.oMf[ft].translation)))
        dd = np.asarray(d)
        med, sd = np.median(dd, axis=0), dd.std(axis=0)
        p5, p95 = np.percentile(dd[:, 0], [5, 95])
        print(f"  {side} knee centre Vicon − msk (femur frame, mm): median x/y/z "
              f"{med[0]:+.0f} / {med[1]:+.0f} / {med[2]:+.0f}, SD {sd[0]:.0f} / {sd[1]:.0f} / "
              f"{sd[2]:.0f}, x 5-95 % {p5:+.0f}…{p95:+.0f}")  # fmt: skip


def main() -> None:
    real = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[2]
    if len(sys.argv) <= 1:
        real = real / "shared" / "data" / "real"
    for task, static, mass in WALKS:
        study(real, task, static, mass)


if __name__ == "__main__":
    main()
