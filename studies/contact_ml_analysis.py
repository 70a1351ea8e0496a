"""Medial/lateral knee contact on PS and DM taken apart (docs/validation.md, "Medial and lateral
knee contact", items 7–9): how the measured split is defined, where the predicted lateral force
comes from, and what makes the late-stance peak.

    python studies/contact_ml_analysis.py

Runs the shipped configs (``pipelines/gc5_PS.toml`` on ss1/ss3/ss8, ``pipelines/gc6_DM_og1.toml``
on og1/og3/og4, only the task files swapped as ``studies/contact_validation.py`` does) up to the
``knee_contact`` stage, and the whole session once for the measured force on the trial's time
axis. Nothing is fitted; the measured force is printed beside the model's parts, never used to
choose anything. Printed per trial:

* the external knee adduction moment (inverse dynamics, no muscles: +M_x of the knee reaction on
  the left knee, −M_x on the right; N·m/kg), its peak in the first and second half of stance;
* over stance (predicted normal force > 0.3 BW): the lateral force the inverse-dynamics load
  alone gives (N/2 ± M_C,x/d), the muscles' part and the prediction, each mean and Pearson r
  with the measured lateral force; r of the adduction moment with measured medial − lateral;
* at the 10 % of stance frames where |predicted − measured| lateral is largest: each knee-
  crossing muscle's mean contribution to the medial and lateral forces and to M_C,x;
* at the predicted normal force's peak in the second half of stance (± 21 ms): the normal
  force of inverse dynamics and each muscle's part, the knee and ankle torques, soleus and
  gastrocnemii forces, activations, moment arms and plantarflexion shares, and (PS) the EMG
  envelopes (normalised to the session's peak) of soleus, gastrocnemii and rectus femoris;
* DM: the source's raw implant channels (``Force.raw``: F_SI, F_ML, M_VV) against the model's
  contact normal force, medio-lateral shear and frontal moment (sign and frame check).

Last, the gastrocnemii's and rectus femoris' knee moment arms in gait2392 and in Rajagopal et
al. (2016; lower-limb paths of Arnold et al. 2010) at 0–60° of flexion, both unscaled
(``shared/data/reference/opensim-models``).
"""

from __future__ import annotations

import csv
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "studies"))

from contact_validation import REAL, TRIALS, _config  # noqa: E402

Row = tuple[str, float, float, float, float]  # muscle, force N, Δmedial, Δlateral, ΔM_C,x


def _measured_on_time(cfg: Path, out: Path) -> tuple[np.ndarray, ...]:
    """(time, measured medial, measured lateral) in N on the trial's time axis, as the
    session's own tables write them (PS: cycle-normalised file placed on the gait cycle)."""
    from msk.pipeline import run_task_trials

    run_task_trials(cfg, out)
    with open(out / "tables" / "knee_contact.csv", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    return tuple(
        np.array([float(r[c]) for r in rows])
        for c in ("time", "measured_medial", "measured_lateral")
    )


class _Trial:
    """The pipeline's own stages of one trial and its contact split, on the frames with
    muscle forces."""

    def __init__(self, cfg: Path) -> None:
        from msk.config import load_config
        from msk.contact.knee import PlateauGeometry
        from msk.pipeline.session import run_stages

        st = run_stages(cfg, until="knee_contact")
        self.st = st
        self.model = st["model"].model
        self.tens = st["tension_optimization"]
        self.names = tuple(self.tens.muscles)
        kc = st["knee_contact"]
        self.joint = kc.joint
        self.side = "left" if self.joint.endswith("_l") else "right"
        self.sfx = self.joint[-2:]
        forces = np.asarray(self.tens.forces, dtype=float)
        self.ok = np.flatnonzero(st["loads"].usable & np.isfinite(forces).all(axis=1))
        self.forces = forces[self.ok]
        self.kin = st["kinematics"].take(self.ok)
        self.ext = st["loads"].external.take(self.ok)
        self.time = np.asarray(st["kinematics"].time)[self.ok]
        self.mass = float(load_config(cfg).subject.mass_kg)
        self.bw = self.mass * 9.80665
        p = kc.plateau
        self.geo = PlateauGeometry(
            float(p["intercondylar_distance_m"]), tuple(p["centre_m"]), str(p["source"])
        )
        self.c_id, self.ml_id = self.split(np.arange(self.ok.size), None)
        self.c_all, self.ml_all = self.split(np.arange(self.ok.size), self.forces)

    def split(self, frames: np.ndarray, forces: np.ndarray | None) -> tuple[Any, Any]:
        from msk.contact.knee import knee_contact_force, split_medial_lateral

        c = knee_contact_force(
            self.model,
            self.kin.take(frames),
            self.ext.take(frames),
            muscle_forces=forces if forces is None else forces[frames],
            muscle_names=self.names,
            joint=self.joint,
        )
        return c, split_medial_lateral(c, self.geo)

    def parts(self, frames: np.ndarray) -> list[Row]:
        """Each muscle's mean contribution on ``frames`` (contact with it alone minus none)."""
        _, m0 = self.split(frames, None)
        rows = []
        for j, name in enumerate(self.names):
            if not name.endswith(self.sfx) or not np.any(self.forces[frames, j] > 0):
                continue
            f = np.zeros_like(self.forces)
            f[:, j] = self.forces[:, j]
            _, mj = self.split(frames, f)
            dm = float(np.mean(mj.medial - m0.medial))
            dl = float(np.mean(mj.lateral - m0.lateral))
            dmx = float(np.mean(mj.frontal_moment - m0.frontal_moment))
            if abs(dm) + abs(dl) > 1.0:
                rows.append((name, float(self.forces[frames, j].mean()), dm, dl, dmx))
        return rows


def _frontal(tr: _Trial, t_meas: np.ndarray, m_med: np.ndarray, m_lat: np.ndarray) -> None:
    bw = tr.bw
    meas_lat = np.interp(tr.time, t_meas, m_lat, left=np.nan, right=np.nan)
    meas_med = np.interp(tr.time, t_meas, m_med, left=np.nan, right=np.nan)
    sgn = 1.0 if tr.side == "left" else -1.0
    kam = sgn * tr.c_id.moment[:, 0] / tr.mass
    stance = tr.ml_all.normal > 0.3 * bw
    idx = np.flatnonzero(stance)
    first, second = idx[: idx.size // 2], idx[idx.size // 2 :]
    print(
        f"external adduction moment (ID, no muscles): peaks {kam[first].max():.2f} / "
        f"{kam[second].max():.2f} N·m/kg (first / second half of stance)"
    )
    fin = stance & np.isfinite(meas_lat)

    def r(a: np.ndarray, b: np.ndarray) -> str:
        return f"{np.corrcoef(a[fin], b[fin])[0, 1]:+.2f}"

    def mean(a: np.ndarray, sel: Any = fin) -> str:
        return f"{np.mean(a[sel]) / bw:.2f}"

    lat_id, lat_all = tr.ml_id.lateral, tr.ml_all.lateral
    lat_mus = lat_all - lat_id
    print(
        f"stance lateral (BW, mean / r with measured): ID only {mean(lat_id)} / "
        f"{r(lat_id, meas_lat)}, muscles' part {mean(lat_mus)} / {r(lat_mus, meas_lat)}, "
        f"predicted {mean(lat_all)} / {r(lat_all, meas_lat)}, measured {mean(meas_lat)}"
    )
    print(
        f"stance medial r with measured: ID only {r(tr.ml_id.medial, meas_med)}, predicted "
        f"{r(tr.ml_all.medial, meas_med)}; adduction moment vs measured medial − lateral "
        f"{r(kam, meas_med - meas_lat)}"
    )
    err = np.where(fin, np.abs(lat_all - meas_lat), -np.inf)
    worst = np.sort(np.argsort(err)[::-1][: max(1, int(0.1 * fin.sum()))])
    tw = tr.time[worst]
    print(
        f"worst lateral frames ({worst.size}, t {tw.min():.3f}–{tw.max():.3f} s): predicted "
        f"{mean(lat_all, worst)} BW (ID only {mean(lat_id, worst)}), measured "
        f"{mean(meas_lat, worst)}; M_C,x ID only {np.mean(tr.ml_id.frontal_moment[worst]):.1f}"
        f" N·m, with the muscles {np.mean(tr.ml_all.frontal_moment[worst]):.1f} N·m"
    )
    rows = sorted(tr.parts(worst), key=lambda x: -abs(x[3] - x[2]))
    print("  muscle        force N  medial N  lateral N  M_C,x N·m")
    for name, f, dm, dl, dmx in rows[:8]:
        print(f"  {name:12s} {f:8.0f} {dm:+9.0f} {dl:+10.0f} {dmx:+10.2f}")


def _late_stance(tr: _Trial) -> None:
    bw, sfx = tr.bw, tr.sfx
    tot = tr.ml_all.normal
    idx = np.flatnonzero(tot > 0.3 * bw)
    second = idx[idx.size // 2 :]
    i2 = second[np.argmax(tot[second])]
    win = np.flatnonzero(np.abs(tr.time - tr.time[i2]) <= 0.021)
    coords = list(tr.model.coordinate_names)
    kq, aq = coords.index(f"knee_angle{sfx}"), coords.index(f"ankle_angle{sfx}")
    knee_deg = -np.rad2deg(np.asarray(tr.kin.q)[win, kq]).mean()
    print(
        f"late-stance peak t {tr.time[i2]:.3f} s: total {tot[i2] / bw:.2f} BW, knee flexed "
        f"{knee_deg:.1f}°"
    )
    late = sorted(tr.parts(win), key=lambda x: -(x[2] + x[3]))
    idn = float(np.mean(tr.ml_id.normal[win]))
    print(
        f"  normal force: ID only {idn / bw:.2f} BW + muscles "
        f"{sum(x[2] + x[3] for x in late) / bw:.2f} BW; largest: "
        + ", ".join(f"{x[0]} {(x[2] + x[3]) / bw:+.2f}" for x in late[:6])
    )
    tau = np.asarray(tr.st["inverse_dynamics"].torques.tau)[tr.ok][win]
    print(
        f"  ID torques: knee {tau[:, kq].mean():+.1f} N·m (+ extension), ankle "
        f"{tau[:, aq].mean():+.1f} N·m (+ dorsiflexion)"
    )
    geom = tr.st["muscle_geometry"]
    arms = np.asarray(geom.moment_arms)[tr.ok][win]
    gk, ga = geom.coordinate_index(f"knee_angle{sfx}"), geom.coordinate_index(f"ankle_angle{sfx}")
    acts = np.asarray(tr.tens.activations)[tr.ok]
    share = {}
    for m in (f"soleus{sfx}", f"med_gas{sfx}", f"lat_gas{sfx}", f"rect_fem{sfx}"):
        j, g = tr.names.index(m), geom.muscle_index(m)
        f = tr.forces[win, j]
        if "rect" not in m:
            share[m] = float(np.mean(f * -arms[:, g, ga]))
        print(
            f"  {m:11s} F {f.mean():5.0f} N, activation {acts[win, j].mean():.2f}; arms: "
            f"plantarflexion {-arms[:, g, ga].mean() * 1e3:4.1f} mm, knee "
            f"{arms[:, g, gk].mean() * 1e3:+5.1f} mm (+ extension)"
        )
    total = sum(share.values())
    print(
        "  plantarflexion moment shares: "
        + ", ".join(f"{m} {v / total:.0%}" for m, v in share.items())
        + f" (of {total:.0f} N·m)"
    )
    emg = tr.st.get("emg")
    if emg is None:
        return
    stance = np.flatnonzero(tr.ml_all.normal > 0.3 * bw)
    for m in (f"soleus{sfx}", f"med_gas{sfx}", f"lat_gas{sfx}", f"rect_fem{sfx}"):
        if m not in emg.muscles:
            continue
        env = np.asarray(emg.envelopes)[tr.ok][:, emg.column(m)]
        a = acts[:, tr.names.index(m)]
        print(
            f"  EMG {emg.sources[emg.column(m)]:7s} envelope at the peak {env[win].mean():.2f} "
            f"of the session's peak (stance max {env[stance].max():.2f}); model activation at "
            f"the peak {a[win].mean():.2f} (stance max {a[stance].max():.2f})"
        )


def _dm_raw(tr: _Trial, trial: str) -> None:
    from scipy.io import loadmat

    mc = tr.st["measured_contact"]
    d = loadmat(
        REAL / "knee-grand-challenge-gc6-DM" / "moissenet" / f"DM_ngait_{trial}.mat",
        squeeze_me=True,
        struct_as_record=False,
    )["Force"].raw
    tm = np.asarray(mc.time)
    sel = (tm >= tr.time[0]) & (tm <= tr.time[-1])
    pred = {
        "normal": tr.ml_all.normal,
        "shear F_z (+lateral)": tr.c_all.force[:, 2],
        "M_C,x": tr.ml_all.frontal_moment,
    }
    print(f"raw implant channels vs the prediction ({sel.sum()} frames): Pearson r, slope")
    for ch in ("F_SI", "F_ML", "M_VV"):
        y = np.asarray(getattr(d, ch), dtype=float)[sel]
        cells = []
        for key, p in pred.items():
            x = np.interp(tm[sel], tr.time, p)
            cells.append(f"{key} {np.corrcoef(x, y)[0, 1]:+.2f}, {np.polyfit(x, y, 1)[0]:+.3g}")
        print(f"  {ch:5s}: " + "; ".join(cells))


def _moment_arms() -> None:
    from msk.model.osim import load_osim
    from msk.muscles.geometry import muscle_geometry

    ref = REPO.parent / "shared" / "data" / "reference" / "opensim-models"
    flex = np.array([0.0, 5.0, 10.0, 15.0, 20.0, 30.0, 40.0, 60.0])
    print(f"\n## knee moment arms (mm, + flexor), knee flexed {flex.astype(int).tolist()}°")
    models = (
        ("gait2392", "gait2392_thelen2003muscle.osim", -1.0, ("med_gas", "lat_gas", "rect_fem")),
        ("Rajagopal2016", "Rajagopal2016.osim", 1.0, ("gasmed", "gaslat", "recfem")),
    )
    for label, file, sign, muscles in models:
        m = load_osim(ref / file)
        k = m.coordinate_index("knee_angle_r")
        th = np.tile(m.default_coordinates(), (flex.size, 1))
        th[:, k] = sign * np.deg2rad(flex)
        g = muscle_geometry(m, th)
        names = [mu.name for mu in m.muscles]
        for mu in muscles:
            arm = g.moment_arms[:, names.index(f"{mu}_r"), k] * sign * 1e3  # + flexor
            print(f"  {label:13s} {mu:9s} " + " ".join(f"{a:5.1f}" for a in arm))


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name in ("gc5_PS", "gc6_DM_og1"):
            for trial, swap in TRIALS[name]:
                cfg = _config(name, swap, "spline", folder, None, trial)
                t_meas, m_med, m_lat = _measured_on_time(cfg, folder / f"{name}_{trial}")
                tr = _Trial(cfg)
                print(
                    f"\n## {name} {trial} ({tr.side} knee, {tr.mass:.1f} kg, "
                    f"d = {tr.geo.intercondylar_distance_m * 1e3:.1f} mm)"
                )
                _frontal(tr, t_meas, m_med, m_lat)
                _late_stance(tr)
                if name == "gc6_DM_og1":
                    _dm_raw(tr, trial)
    _moment_arms()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
