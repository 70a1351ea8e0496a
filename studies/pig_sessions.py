"""The shipped Plug-in Gait session (``pipelines/pig_motion3.toml``) on every Plug-in Gait walk
of BTKData, its trial files swapped, against Vicon's stored outputs.

Per walk and side: the hip centre against Plug-in Gait's ``<S>FEP`` (median over frames, in the
markers' ISB pelvis frame, mm), the knee centre against ``<S>FEO`` and the ankle centre against
``<S>TIO`` (in msk's femur and tibia frames); the knee flexion against ``<S>KneeAngles`` X
(−``knee_angle``; mean, SD, r) and the flexion of the same three joint centres measured as
Plug-in Gait measures it (the angle between the hip→knee and knee→ankle lines in the femur's
sagittal plane), which separates the definition from the centres; and, per stance on a plate
(Foot Strike → Foot Off of the file's events), the RMS difference, r and mean difference of
the hip, knee and ankle sagittal moments (N·m/kg; ``PiG X = −τ_hip_flexion = +τ_knee_angle =
−τ_ankle_angle``, PiG low-passed like msk at 6 Hz) against the project's ceilings
(``tests/test_validation_plugin_gait.py``: 0.25 / 0.35 / 0.25 N·m/kg).

PiG_Motion3_FF runs with its static PiG_Calibration3_FF; PlugInC3D has none (mass 66.4 kg,
docs/validation.md). Run: ``python studies/pig_sessions.py [data folder]``.
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
#: joint → (gait2392 coordinate stem, sign onto PiG's X, PiG output stem)
SIGN = {
    "hip": ("hip_flexion", -1.0, "HipMoment"),
    "knee": ("knee_angle", 1.0, "KneeMoment"),
    "ankle": ("ankle_angle", -1.0, "AnkleMoment"),
}
#: RMS ceilings (N·m/kg) of tests/test_validation_plugin_gait.py
CEILING = {"hip": 0.25, "knee": 0.35, "ankle": 0.25}
WALKS = (("PiG_Motion3_FF", "PiG_Calibration3_FF", 74.0), ("PlugInC3D", None, 66.4))


def _config(real: Path, task: str, static: str | None, mass: float, folder: Path) -> Path:
    """pig_motion3.toml with its trials swapped for ``task`` (and ``static``)."""
    head = (ROOT / "pipelines" / "pig_motion3.toml").read_text().split("[[trials]]")[0]
    head = head.replace("mass_kg = 74.0", f"mass_kg = {mass}")
    trials = ""
    if static is not None:
        trials += (
            f'[[trials]]\nname = "static"\nfile = "{real}/btkdata/{static}.c3d"\nrole = "static"\n'
        )
    trials += f'[[trials]]\nname = "walk"\nfile = "{real}/btkdata/{task}.c3d"\nrole = "task"\n'
    p = folder / "session.toml"
    p.write_text(head + trials, encoding="utf-8")
    return p


def _stances(trial, side: str) -> list[tuple[float, float]]:
    ctx = {"R": "Right", "L": "Left"}[side]
    strikes = sorted(trial.events_named("Foot Strike", ctx))
    offs = sorted(trial.events_named("Foot Off", ctx))
    return [(t, min(o for o in offs if o > t)) for t in strikes if any(o > t for o in offs)]


def _lowpass(x: np.ndarray, rate_hz: float) -> np.ndarray:
    out = np.full_like(x, np.nan)
    ok = np.isfinite(x)
    d = np.diff(np.concatenate([[0], ok.astype(int), [0]]))
    for i0, i1 in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=True):
        if i1 - i0 > 12:
            out[i0:i1] = filtfilt_butter(x[i0:i1], rate_hz=rate_hz, cutoff_hz=6.0)
    return out


def _output(raw, stem: str) -> np.ndarray:
    labels = raw.model_outputs.labels
    return np.asarray(raw.model_outputs.get(stem + ("V" if stem + "V" in labels else "")))


def study(real: Path, task: str, static: str | None, mass: float) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        r = run_stages(load_config(_config(real, task, static, mass, Path(tmp))),
                       until="inverse_dynamics")  # fmt: skip
    built, kin = r["model"], r["kinematics"]
    model, trial = built.model, built.trial
    raw = read_c3d(real / "btkdata" / f"{task}.c3d")
    tau = r["inverse_dynamics"].torques
    data = model.create_data()
    t_tr = np.asarray(trial.time, dtype=float)
    t_raw = np.asarray(raw.time, dtype=float)
    t_tau = np.asarray(tau.time, dtype=float)
    used = built.info.get("hip_centre", {}).get("method")
    print(f"\n{task} (static: {static or 'none'}; hip centre {used})")
    for side in "RL":
        s = side.lower()
        frame = {b: model.body_frame[f"{b}_{s}"] for b in ("femur", "tibia", "talus")}
        hip, knee, ankle, geo = [], [], [], []
        for i, t in enumerate(kin.time):
            j = int(np.argmin(np.abs(t_tr - t)))
            if not np.isfinite(kin.q[i]).all():
                geo.append(np.nan)
                continue
            forward_kinematics(model, data, kin.q[i])
            pos = {b: np.asarray(data.oMf[f].translation) for b, f in frame.items()}
            rf = np.asarray(data.oMf[frame["femur"]].rotation)
            rt = np.asarray(data.oMf[frame["tibia"]].rotation)
            u, v = pos["femur"] - pos["tibia"], pos["tibia"] - pos["talus"]
            z = rf[:, 2]
            u, v = u - z * (u @ z), v - z * (v @ z)
            geo.append(float(np.degrees(np.arctan2(np.cross(v, u) @ z, u @ v))))
            x = {k: np.asarray(trial.marker(lab), dtype=float)[j]
                 for k, lab in (("fep", f"{side}FEP"), ("feo", f"{side}FEO"),
                                ("tio", f"{side}TIO"))}  # fmt: skip
            post = ["RPSI", "LPSI"] if "RPSI" in trial.marker_labels else ["SACR"]
            lm = [np.asarray(trial.marker(lab), dtype=float)[j] for lab in ("RASI", "LASI", *post)]
            if np.isfinite(np.asarray(lm)).all() and np.isfinite(x["fep"]).all():
                rot, _ = pelvis_frame(PelvisLandmarks(lm[0], lm[1], np.mean(lm[2:], axis=0)))
                hip.append(rot.T @ (x["fep"] - pos["femur"]))
            if np.isfinite(x["feo"]).all():
                knee.append(rf.T @ (x["feo"] - pos["tibia"]))
            if np.isfinite(x["tio"]).all():
                ankle.append(rt.T @ (x["tio"] - pos["talus"]))
        for name, d in (("hip (pelvis frame)", hip), ("knee (femur frame)", knee),
                        ("ankle (tibia frame)", ankle)):  # fmt: skip
            o = 1000.0 * np.median(np.asarray(d), axis=0)
            print(f"  {side} PiG − msk {name}: x/y/z {o[0]:+.0f} / {o[1]:+.0f} / {o[2]:+.0f} mm, "
                  f"distance {np.linalg.norm(o):.1f} mm")  # fmt: skip
        ka = -np.degrees(kin.coordinate(f"knee_angle_{s}"))
        pk = np.degrees(np.interp(kin.time, t_raw, _output(raw, f"{side}KneeAngles")[:, 0]))
        g = np.asarray(geo)
        ok = np.isfinite(ka) & np.isfinite(pk) & np.isfinite(g)
        d = ka[ok] - pk[ok]
        print(f"  {side} knee flexion msk − PiG: mean {d.mean():+.1f}°, SD {d.std():.1f}°, "
              f"r {np.corrcoef(ka[ok], pk[ok])[0, 1]:.3f}; msk's centres measured as PiG "
              f"measures − msk's knee_angle: {np.mean(g[ok] - ka[ok]):+.2f}° "
              f"(SD {np.std(g[ok] - ka[ok]):.2f}°)")  # fmt: skip
        for st in _stances(raw, side):
            sel = (t_raw >= st[0]) & (t_raw <= st[1])
            row = []
            for joint, (coord, sign, stem) in SIGN.items():
                ours = sign * tau.coordinate(f"{coord}_{s}") / mass
                lp = _lowpass(_output(raw, f"{side}{stem}")[:, 0], raw.point_rate_hz)
                m = np.interp(t_raw[sel], t_tau, ours, left=np.nan, right=np.nan)
                good = np.isfinite(m) & np.isfinite(lp[sel])
                if good.sum() < 10 or good.mean() < 0.9:
                    row.append(f"{joint} — (no PiG kinetics: foot off the plates)")
                    continue
                diff = m[good] - lp[sel][good]
                rms = float(np.sqrt(np.mean(diff**2)))
                rr = float(np.corrcoef(m[good], lp[sel][good])[0, 1])
                over = " OVER" if rms > CEILING[joint] else ""
                row.append(f"{joint} RMS {rms:.2f}{over}, r {rr:.2f}, mean {diff.mean():+.2f}")
            print(f"  {side} stance {st[0]:.2f}–{st[1]:.2f} s: " + "; ".join(row))


def main() -> None:
    real = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT.parent / "shared" / "data" / "real"
    for task, static, mass in WALKS:
        study(real, task, static, mass)


if __name__ == "__main__":
    main()
