"""Hip centre and sagittal hip moment of msk's pipeline against Vicon Plug-in Gait's, per
``model.hip_centre`` method, on the Plug-in Gait walks of BTKData.

Plug-in Gait's hip centre is its femur's proximal point ``<S>FEP`` (a virtual point in the
files: Davis et al. 1991 from the file's leg length and inter-ASIS distance reproduces it to
0.4 mm). msk's hip centre is the femur origin of the pipeline's own model posed at the
pipeline's own IK, every frame; the difference (median over frames) is given in the pelvis
frame of the markers (ISB: x anterior, y up, z right; mid-PSIS, else the sacral marker).
Moments: the sagittal hip moment (−τ_hip_flexion / mass) against PiG's
``<S>HipMoment`` X (N·m/kg) low-passed like msk (6 Hz), over each stance (Foot Strike →
Foot Off of the file's events) whose foot is on a plate: RMS and mean difference.

Run: ``python studies/hip_centre_pig.py [data folder]`` (prints a markdown table).
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

from msk.config import load_config
from msk.io import read_c3d
from msk.model.core import forward_kinematics
from msk.personalise.hip_centre import PelvisLandmarks, pelvis_frame
from msk.pipeline.session import run_stages
from msk.signal import filtfilt_butter

ROOT = Path(__file__).resolve().parents[1]
METHODS = ("model", "harrington", "davis")


def _config(real: Path, name: str, method: str, folder: Path) -> Path:
    gait = ROOT / "msk" / "data" / "models" / "gait2392.toml"
    trials, mass = "", 66.4  # PlugInC3D: PiG's normalisation mass (docs/validation.md)
    if name == "PiG_Motion3_FF":
        trials = (
            f'[[trials]]\nname = "static"\nfile = "{real}/btkdata/PiG_Calibration3_FF.c3d"\n'
            'role = "static"\n'
        )
        mass = 74.0
    p = folder / f"{name}_{method}.toml"
    p.write_text(
        f'[subject]\nname = "s"\nmass_kg = {mass}\nheight_m = 1.76\nside = "right"\n'
        f'[model]\nsource = "{gait}"\nhip_centre = "{method}"\n{trials}'
        f'[[trials]]\nname = "walk"\nfile = "{real}/btkdata/{name}.c3d"\nrole = "task"\n',
        encoding="utf-8",
    )
    return p


def _stances(trial, side: str) -> list[tuple[float, float]]:
    ctx = {"R": "Right", "L": "Left"}[side]
    strikes = sorted(trial.events_named("Foot Strike", ctx))
    offs = sorted(trial.events_named("Foot Off", ctx))
    return [(t, min(o for o in offs if o > t)) for t in strikes if any(o > t for o in offs)]


def _landmarks(trial, j: int) -> PelvisLandmarks | None:
    labels = set(trial.marker_labels)
    post = ["RPSI", "LPSI"] if {"RPSI", "LPSI"} <= labels else ["SACR"]
    x = [trial.marker(lab)[j] for lab in ("RASI", "LASI", *post)]
    if not np.isfinite(np.asarray(x)).all():
        return None
    return PelvisLandmarks(x[0], x[1], np.mean(x[2:], axis=0))


def _lowpass(x: np.ndarray, rate_hz: float) -> np.ndarray:
    out = np.full_like(x, np.nan)
    ok = np.isfinite(x)
    d = np.diff(np.concatenate([[0], ok.astype(int), [0]]))
    for i0, i1 in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=True):
        if i1 - i0 > 12:
            out[i0:i1] = filtfilt_butter(x[i0:i1], rate_hz=rate_hz, cutoff_hz=6.0)
    return out


def study(real: Path, name: str, method: str, folder: Path, mass: float) -> dict:
    """Hip-centre offsets (PiG − msk, mm, msk pelvis frame: median over frames) and, per
    stance, the sagittal hip moment's RMS difference and mean difference (N·m/kg)."""
    cfg = load_config(_config(real, name, method, folder))
    r = run_stages(cfg, until="inverse_dynamics")
    built, kin = r["model"], r["kinematics"]
    model, trial = built.model, built.trial
    raw = read_c3d(real / "btkdata" / f"{name}.c3d")
    tau = r["inverse_dynamics"].torques
    data = model.create_data()
    out: dict = {"method": method, "info": built.info.get("hip_centre", {}), "stances": []}
    t_tr = np.asarray(trial.time, dtype=float)
    for side in "RL":
        s = side.lower()
        pig = np.asarray(trial.marker(f"{side}FEP"), dtype=float)
        d = []
        for i, t in enumerate(kin.time):
            j = int(np.argmin(np.abs(t_tr - t)))
            if not (np.isfinite(kin.q[i]).all() and np.isfinite(pig[j]).all()):
                continue
            forward_kinematics(model, data, kin.q[i])
            lm = _landmarks(trial, j)
            if lm is None:
                continue
            rot, _ = pelvis_frame(lm)
            hip = np.asarray(data.oMf[model.body_frame[f"femur_{s}"]].translation)
            d.append(rot.T @ (pig[j] - hip))
        out[f"{side}_offset_mm"] = 1000.0 * np.median(np.asarray(d), axis=0)
        ours = -tau.coordinate(f"hip_flexion_{s}") / mass
        t_tau = np.asarray(tau.time, dtype=float)
        px = raw.model_outputs.get(f"{side}HipMoment")[:, 0]
        lp = _lowpass(px, raw.point_rate_hz)
        t_raw = np.asarray(raw.time, dtype=float)
        for st in _stances(raw, side):
            sel = (t_raw >= st[0]) & (t_raw <= st[1])
            m = np.interp(t_raw[sel], t_tau, ours, left=np.nan, right=np.nan)
            ok = np.isfinite(m) & np.isfinite(lp[sel])
            if ok.sum() < 10 or ok.mean() < 0.9:
                continue  # PiG has kinetics only with the foot on a plate
            diff = m[ok] - lp[sel][ok]
            out["stances"].append((side, st, float(np.sqrt(np.mean(diff**2))), float(diff.mean())))
    return out


def main() -> None:
    real = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT.parent / "shared" / "data" / "real"
    print(
        "| file | hip centre | side | PiG − msk hip centre, pelvis x / y / z (mm) | distance (mm) "
        "| hip moment RMS, mean msk − PiG per stance (N·m/kg) |"
    )
    print("| --- | --- | --- | --- | --- | --- |")
    with tempfile.TemporaryDirectory() as tmp:
        for name, mass in (("PiG_Motion3_FF", 74.0), ("PlugInC3D", 66.4)):
            for m in METHODS:
                res = study(real, name, m, Path(tmp), mass)
                for side in "RL":
                    o = res[f"{side}_offset_mm"]
                    st = "; ".join(f"{a:.2f}, {b:+.2f}" for sd, _, a, b in res["stances"]
                                   if sd == side)  # fmt: skip
                    used = res["info"].get("method", m)
                    print(f"| {name} | {m}{'' if used == m else ' → ' + used} | {side} "
                          f"| {o[0]:+.0f} / {o[1]:+.0f} / {o[2]:+.0f} "
                          f"| {np.linalg.norm(o):.0f} | {st} |")  # fmt: skip


if __name__ == "__main__":
    main()
