"""The knee's frontal plane on PS and DM: what sets the external adduction moment and the
two-point split, stance by stance, without the measured contact force (docs/validation.md,
"Medial and lateral knee contact", item 11).

    python studies/contact_frontal_plane.py [--only gc6_DM_og1:og3,...] [--varus 2]
                                            [--jitter 3 --sigma-mm 2] [--plates]

Runs the shipped configs (``pipelines/gc5_PS.toml`` on ss1/ss3/ss8, ``pipelines/gc6_DM_og1.toml``
on og1/og3/og4, only the task files swapped as ``studies/contact_validation.py`` does) up to the
``knee_contact`` stage. Per stance of the instrumented leg (its foot's vertical ground reaction
> 20 N) it prints:

* which frames the compared window holds: the stance's span, the share of it with muscle forces
  (usable frames), and (DM) the span of the measured force's time axis — only its times are
  read, never its values;
* the external knee adduction moment (inverse dynamics of the identified inertias, no muscles,
  about the tibia's anterior axis; N·m/kg): its peaks in the first and second half of the
  stance and where they fall (% of the stance);
* the ground reaction's medio-lateral shear over the vertical force (+ medial, i.e. toward the
  other foot), mean over the stance; the lab's medio-lateral balance ΣF_ml − m·a_ml of the
  model's centre of mass on the IK coordinates (a residual of the plates against the markers,
  % of body weight, mean over the stance);
* where the ground reaction's line crosses the plateau plane (mm from the contact points'
  midpoint, + lateral; contact points at ±d/2), the share of the stance it passes medial of the
  medial point, and the lateral force of inverse dynamics alone (N/2 + M_C,x/d) and predicted
  (the pipeline's own, muscles included), means in BW, and the share of stance frames where
  the predicted lateral force is held at the compartment rows' bound (< 0.02 BW);
* the tibia (plateau) frame in the lab: its anterior axis' angle to the progression in the
  floor plane (+ external rotation) and its long axis' frontal inclination (+ proximal end
  toward the midline);
* the split's sensitivity to its frame: the lateral force (muscle forces as solved) with the
  frame turned by ±5° about the tibia's long (axial), anterior (frontal tilt) and medio-lateral
  (flexion) axes (``plateau_offset``): RMS change over stance (BW) and r with the unturned curve
  — turning about the long axis mixes the sagittal moment into M_x (cos ψ M_x − sin ψ M_z),
  which the muscles have already balanced;
* ``--varus D`` (DM): the config re-run with the given knee alignment ± D° (placement, IK and
  muscle forces re-solved): d(KAM peaks)/d(varus), the GRF line's move, the lateral curve's RMS
  change and r with the shipped one;
* ``--jitter N``: N re-runs with the markers + N(0, σ) per coordinate in the model stage only
  (the marker placement from the walk; the trial's own IK tracks the unperturbed markers), the
  lateral curve's RMS change and r against the unperturbed run, and the KAM peaks' spread;
* ``--window`` (DM): the one place the measured force's *values* are read, for diagnosis only
  (nothing is chosen by it): Pearson r of the predicted and measured lateral force over the
  table's frames (usable and measured), and separately over the measured cycle's stance and
  its swing (up to the next stance), with the stance means of both;
* ``--plates`` (DM): every plate of the three trials, which foot it carries and that foot's
  mean medial shear ratio, read from the trials' ``*_grf.sto`` and ``*_external_loads.xml``.

Nothing is fitted; the measured force's values are read by ``--window`` only.
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "studies"))

from contact_validation import REAL, TRIALS, _config  # noqa: E402

RUNS = [(name, trial, swap) for name in ("gc5_PS", "gc6_DM_og1") for trial, swap in TRIALS[name]]
BOUND_BW = 0.02  # a predicted compartment force below this is at the rows' bound (lift-off)


def _run_stages(cfg: Path, sigma_m: float = 0.0, seed: int = 0) -> dict[str, Any]:
    """The pipeline's stages up to ``knee_contact``; ``sigma_m`` > 0: the markers + N(0, σ)
    in the model stage only (as ``studies/placement_jitter.py`` perturbs it)."""
    import msk.personalise.personalise as pmodel
    from msk.pipeline.session import run_stages

    if sigma_m <= 0:
        return run_stages(cfg, until="knee_contact")
    rng = np.random.default_rng(seed)
    orig = pmodel.scale_and_place

    def scale_and_place(generic, static, task, opts, **kw):  # type: ignore[no-untyped-def]
        tr = task
        m = np.asarray(tr.markers, dtype=float)
        seen = (m != 0.0).any(axis=-1, keepdims=True)  # exact zeros are gaps (TRC)
        tr = dataclasses.replace(tr, markers=m + seen * rng.normal(0.0, sigma_m, m.shape))
        return orig(generic, static, tr, opts, **kw)

    pmodel.scale_and_place = scale_and_place  # type: ignore[assignment]
    try:
        return run_stages(cfg, until="knee_contact")
    finally:
        pmodel.scale_and_place = orig  # type: ignore[assignment]


class Trial:
    """One trial's stages up to ``knee_contact`` and its frontal-plane quantities per frame."""

    def __init__(self, cfg: Path, sigma_m: float = 0.0, seed: int = 0) -> None:
        import pinocchio as pin

        from msk.config import load_config
        from msk.contact.knee import PlateauGeometry, knee_contact_force, split_medial_lateral
        from msk.dynamics.identification import identified_model
        from msk.model.core import forward_kinematics

        self.pin = pin
        st = _run_stages(cfg, sigma_m, seed)
        kc = st["knee_contact"]
        self.joint = kc.joint
        self.sfx = self.joint[-2:]
        self.side = "left" if self.sfx == "_l" else "right"
        self.model = identified_model(st["model"].model, st.get("mass_identification"))
        tens = st["tension_optimization"]
        self.names = tuple(tens.muscles)
        self.forces_all = np.asarray(tens.forces, dtype=float)
        kin, ext = st["kinematics"], st["loads"].external
        self.kin, self.ext = kin, ext
        self.time = np.asarray(kin.time, dtype=float)
        self.usable = np.asarray(st["loads"].usable) & np.isfinite(self.forces_all).all(axis=1)
        self.mass = float(load_config(cfg).subject.mass_kg)
        self.bw = self.mass * 9.80665
        p = kc.plateau
        self.geo = PlateauGeometry(
            float(p["intercondylar_distance_m"]), tuple(p["centre_m"]), str(p["source"])
        )
        self.half = 0.5 * self.geo.intercondylar_distance_m
        self.measured_span = None
        self.measured = kc.measured
        mt = getattr(kc.measured, "time", None)
        if mt is not None:
            self.measured_span = (float(np.min(mt)), float(np.max(mt)))
        gen = kc.variants["generic"]
        self.lateral = np.asarray(gen.lateral, dtype=float)  # the pipeline's own prediction
        c_id = knee_contact_force(self.model, kin, ext, joint=self.joint)
        self.c_id = c_id
        self.ml_id = split_medial_lateral(c_id, self.geo)
        # the foot's ground reaction and the plateau frame, centre of mass in the lab
        feet = [i for i, b in enumerate(ext.bodies) if b.endswith(self.sfx)]
        self.grf = np.asarray(ext.force, dtype=float)[:, feet].sum(axis=1)
        self.grf_m = np.asarray(ext.moment, dtype=float)[:, feet].sum(axis=1)
        self.grf_all = np.nan_to_num(np.asarray(ext.force, dtype=float)).sum(axis=1)
        m = self.model
        tib = next(j.child for j in m.joints if j.name == self.joint)
        data = m.create_data()
        q = np.asarray(kin.q, dtype=float)
        n = q.shape[0]
        self.rot = np.full((n, 3, 3), np.nan)
        self.org = np.full((n, 3), np.nan)
        com = np.full((n, 3), np.nan)
        fid = m.body_frame[tib]
        for i in range(n):
            if not np.isfinite(q[i]).all():
                continue
            qp = forward_kinematics(m, data, q[i])
            self.rot[i] = data.oMf[fid].rotation
            self.org[i] = data.oMf[fid].translation
            com[i] = pin.centerOfMass(m.pin_model, data, qp)
        self.com = com
        g = np.asarray(m.pin_model.gravity.linear, dtype=float)
        self.up = -g / np.linalg.norm(g)
        ok = np.flatnonzero(np.isfinite(com).all(axis=1))
        v = com[ok[-1]] - com[ok[0]]
        v -= (v @ self.up) * self.up
        self.prog = v / np.linalg.norm(v)
        right = np.cross(self.prog, self.up)
        self.lat_dir = right if self.side == "right" else -right  # the instrumented leg's lateral
        self.plateau_lateral = 1.0 if self.side == "right" else -1.0  # +z is lateral on the right

    # ---------------------------------------------------------------------------------
    def stances(self) -> list[np.ndarray]:
        """Contiguous frame runs with the instrumented foot's vertical reaction > 20 N."""
        on = np.nan_to_num(self.grf @ self.up) > 20.0
        edges = np.flatnonzero(np.diff(np.r_[0, on.astype(int), 0]))
        return [np.arange(a, b) for a, b in zip(edges[::2], edges[1::2]) if b - a >= 10]

    def kam(self) -> np.ndarray:
        """External adduction moment (ID, no muscles), N·m/kg (+ adduction)."""
        sgn = 1.0 if self.side == "left" else -1.0
        return sgn * self.c_id.moment[:, 0] / self.mass

    def tibia_angles(self) -> tuple[np.ndarray, np.ndarray]:
        """(axial, frontal inclination) in degrees: the tibia's anterior axis to the
        progression in the floor plane (+ external), its long axis in the plane normal to the
        progression (+ proximal end toward the midline)."""
        x, y = self.rot[:, :, 0], self.rot[:, :, 1]
        xh = x - np.outer(x @ self.up, self.up)
        axial = np.degrees(np.arctan2(xh @ self.lat_dir, xh @ self.prog))
        incl = np.degrees(np.arctan2(-(y @ self.lat_dir), y @ self.up))
        return axial, incl

    def medial_shear(self) -> np.ndarray:
        """The foot's ground reaction toward the other foot over its vertical component."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return -(self.grf @ self.lat_dir) / (self.grf @ self.up)

    def ml_balance_bw(self) -> np.ndarray:
        """(ΣF_ml − m a_ml) / (m g) in the lab's medio-lateral direction (all plates)."""
        dt = float(np.median(np.diff(self.time)))
        a = np.gradient(np.gradient(self.com @ self.lat_dir, dt), dt)
        return (self.grf_all @ self.lat_dir - self.mass * a) / self.bw

    def grf_crossing(self) -> np.ndarray:
        """Medio-lateral crossing (m, + lateral, from the contact midpoint) of the foot's
        ground reaction line with the plateau plane."""
        f, mo = self.grf, self.grf_m
        f2 = np.einsum("ni,ni->n", f, f)
        p = np.cross(f, mo) / np.where(f2 > 1.0, f2, np.nan)[:, None]  # point on the line
        pp = np.einsum("nji,nj->ni", self.rot, p - self.org)
        u = np.einsum("nji,nj->ni", self.rot, f)
        _, cy, cz = self.geo.centre_m
        t = (cy - pp[:, 1]) / u[:, 1]
        return self.plateau_lateral * (pp[:, 2] + t * u[:, 2] - cz)

    def turned_lateral(self, axis: int, deg: float, frames: np.ndarray) -> np.ndarray:
        """Predicted lateral force (N) on ``frames`` with the split's frame turned by ``deg``
        about plateau axis ``axis`` (0 anterior, 1 long, 2 medio-lateral)."""
        from msk.contact.knee import knee_contact_force, split_medial_lateral

        a = np.zeros(3)
        a[axis] = np.radians(deg)
        off = self.pin.SE3(self.pin.exp3(a), np.zeros(3))
        c = knee_contact_force(
            self.model, self.kin.take(frames), self.ext.take(frames),
            muscle_forces=self.forces_all[frames], muscle_names=self.names, joint=self.joint,
            plateau_offset=off,
        )  # fmt: skip
        return split_medial_lateral(c, self.geo).lateral


def _peaks(k: np.ndarray, fr: np.ndarray) -> tuple[float, float, float, float]:
    h = fr.size // 2
    i1, i2 = int(np.nanargmax(k[fr[:h]])), h + int(np.nanargmax(k[fr[h:]]))
    pct = lambda i: 100.0 * i / (fr.size - 1)  # noqa: E731
    return float(k[fr[i1]]), float(k[fr[i2]]), pct(i1), pct(i2)


def report(label: str, tr: Trial) -> list[dict[str, Any]]:
    bw = tr.bw
    kam, z = tr.kam(), 1000 * tr.grf_crossing()
    axial, incl = tr.tibia_angles()
    shear, bal = tr.medial_shear(), tr.ml_balance_bw()
    used = np.flatnonzero(tr.usable)
    span = f"{tr.time[used[0]]:.3f}–{tr.time[used[-1]]:.3f} s" if used.size else "none"
    meas = (
        f"; measured force {tr.measured_span[0]:.3f}–{tr.measured_span[1]:.3f} s"
        if tr.measured_span
        else ""
    )
    print(f"== {label}: usable frames {span}{meas}; d = {2000 * tr.half:.1f} mm")
    out = []
    for fr in tr.stances():
        cov = float(np.mean(tr.usable[fr]))
        t0, t1 = tr.time[fr[0]], tr.time[fr[-1]]
        mid = fr[int(0.1 * fr.size) : int(0.9 * fr.size)]  # the stance without its ends
        p1, p2, q1, q2 = _peaks(kam, mid)
        u = fr[tr.usable[fr]]
        rec: dict[str, Any] = {
            "label": label, "span": (t0, t1), "usable": cov, "kam": (p1, p2, q1, q2),
            "shear": float(np.nanmean(shear[mid])),
            "balance": float(np.nanmean(bal[mid][tr.usable[mid]])) if tr.usable[mid].any()
            else float("nan"),
            "grf_z": float(np.nanmean(z[mid])),
            "medial_of_P_M": float(np.mean(z[mid] < -1000 * tr.half)),
            "axial": float(np.nanmean(axial[mid])), "incl": float(np.nanmean(incl[mid])),
        }  # fmt: skip
        print(
            f"  stance {t0:.3f}–{t1:.3f} s, usable {100 * cov:.0f} %"
            + (f" (from {tr.time[u[0]]:.3f} s)" if u.size and cov < 1 else "")
        )
        print(
            f"    KAM peaks {p1:.2f} / {p2:.2f} N·m/kg at {q1:.0f} / {q2:.0f} % of the stance "
            f"(10–90 %); medial shear / vertical {rec['shear']:+.3f}; lab M-L balance "
            f"{100 * rec['balance']:+.1f} % BW (frames with every contact measured)"
        )
        print(
            f"    GRF line at the plateau {rec['grf_z']:+.1f} mm (+ lateral; contact points "
            f"±{1000 * tr.half:.1f}), medial of the medial point on "
            f"{100 * rec['medial_of_P_M']:.0f} % of the stance; tibia axial "
            f"{rec['axial']:+.1f}°, inclination {rec['incl']:+.1f}°"
        )
        if u.size >= 10:
            lat_id = tr.ml_id.lateral[u] / bw
            lat = tr.lateral[u] / bw
            rec["lat_id"], rec["lat"] = float(lat_id.mean()), float(lat.mean())
            rec["at_bound"] = float(np.mean(lat < BOUND_BW))
            print(
                f"    lateral (usable frames): ID alone {rec['lat_id']:+.2f} BW, predicted "
                f"{rec['lat']:+.2f} BW, at the rows' bound (< {BOUND_BW} BW) on "
                f"{100 * rec['at_bound']:.0f} % of them"
            )
            cells = []
            for axis, nm in ((1, "axial"), (0, "frontal tilt"), (2, "flexion")):
                worst = (0.0, 1.0)
                for deg in (-5.0, 5.0):
                    lt = tr.turned_lateral(axis, deg, u) / bw
                    rms = float(np.sqrt(np.mean((lt - lat) ** 2)))
                    r = float(np.corrcoef(lt, lat)[0, 1])
                    worst = (max(worst[0], rms), min(worst[1], r))
                rec[f"turn_{nm}"] = worst
                cells.append(f"{nm} RMS ≤ {worst[0]:.3f} BW, r ≥ {worst[1]:.3f}")
            print("    frame turned ±5°: " + "; ".join(cells))
        out.append(rec)
    sys.stdout.flush()
    return out


def window(tr: Trial) -> None:
    """Diagnosis only: r of predicted and measured lateral force on the table's frames, in
    stance and in swing (the measured force on the trial's time, DM)."""
    me = tr.measured
    if getattr(me, "time", None) is None:
        print("  window: the measured force has no time axis (cycle-normalised): skipped")
        return
    ml = np.interp(tr.time, me.time, me.lateral, left=np.nan, right=np.nan)
    both = tr.usable & np.isfinite(ml)
    # the measured cycle's stance (the first one reaching into the measured span) and its
    # swing (up to the next stance, which belongs to the next cycle)
    runs = [fr for fr in tr.stances() if tr.time[fr[-1]] >= me.time[0]]
    stance = np.zeros_like(both)
    swing = np.zeros_like(both)
    if runs:
        stance[runs[0]] = True
        end = runs[1][0] if len(runs) > 1 else tr.time.size
        swing[runs[0][-1] + 1 : end] = True

    def r(sel: np.ndarray) -> str:
        return f"{np.corrcoef(tr.lateral[sel], ml[sel])[0, 1]:+.2f} ({sel.sum()})"

    print(
        f"  window: lateral r over the table's frames {r(both)}, the cycle's stance "
        f"{r(both & stance)}, its swing {r(both & swing)}; stance mean measured "
        f"{np.mean(ml[both & stance]) / tr.bw:.2f} BW, predicted "
        f"{np.mean(tr.lateral[both & stance]) / tr.bw:.2f} BW"
    )


def _varus(delta: float) -> Callable[[str], str]:
    def edit(text: str) -> str:
        return re.sub(
            r"(?m)^knee_varus_deg = (\S+)",
            lambda m: f"knee_varus_deg = {float(m[1]) + delta:.4f}",
            text,
        )

    return edit


def _compare(a: Trial, b: Trial) -> tuple[float, float]:
    """RMS difference (BW) and r of the predicted lateral force on the frames both use."""
    ia = np.flatnonzero(a.usable)
    tb = {round(float(t), 6): i for i, t in enumerate(b.time)}
    pairs = [(i, tb[round(float(a.time[i]), 6)]) for i in ia if round(float(a.time[i]), 6) in tb]
    ii = np.array([p for p in pairs if b.usable[p[1]]])
    la, lb = a.lateral[ii[:, 0]], b.lateral[ii[:, 1]]
    return float(np.sqrt(np.mean((la - lb) ** 2)) / a.bw), float(np.corrcoef(la, lb)[0, 1])


def plates() -> None:
    """DM: each plate's foot and that foot's mean medial shear ratio per trial."""
    root = REAL / "knee-grand-challenge-gc6-DM"
    for trial in ("og1", "og3", "og4"):
        xml = (root / f"DM_ngait_{trial}_external_loads.xml").read_text(encoding="utf-8")
        bodies = re.findall(r"<applied_to_body>\s*([^<\s]+)\s*<", xml)
        ids = re.findall(r"<force_identifier>\s*ground_force_(\d)_v\s*<", xml)
        foot = dict(zip(ids, bodies))
        lines = (root / f"DM_ngait_{trial}_grf.sto").read_text(encoding="utf-8").splitlines()
        k = next(i for i, s in enumerate(lines) if s.strip() == "endheader")
        cols = lines[k + 1].split("\t")
        d = np.loadtxt(lines[k + 2 :])
        for p in sorted(foot):
            vy = d[:, cols.index(f"ground_force_{p}_vy")]
            on = np.flatnonzero(vy > 100.0)
            on = on[int(0.1 * on.size) : int(0.9 * on.size)]
            vz = d[on, cols.index(f"ground_force_{p}_vz")]
            vx = d[on, cols.index(f"ground_force_{p}_vx")]
            # lab z shear = a·vertical + b·anterior-posterior shear (least squares)
            (ca, cb), *_ = np.linalg.lstsq(np.stack([vy[on], vx], axis=1), vz, rcond=None)
            # OpenSim z is to the right: medial of a right foot is −z
            sgn = -1.0 if foot[p].endswith("_r") else 1.0
            print(
                f"  {trial} plate {p} ({foot[p]}, {d[on[0], 0]:.2f}–{d[on[-1], 0]:.2f} s): "
                f"medial shear / vertical {np.mean(sgn * vz / vy[on]):+.3f}, "
                f"lab z shear / vertical {np.mean(vz / vy[on]):+.3f} (fit: {ca:+.3f} vertical "
                f"{cb:+.3f} antero-posterior)"
            )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="name:trial,… (e.g. gc6_DM_og1:og3)")
    ap.add_argument("--varus", type=float, default=0.0, help="DM: alignment ± this (deg)")
    ap.add_argument("--jitter", type=int, default=0, help="re-runs with placement noise")
    ap.add_argument("--sigma-mm", type=float, default=2.0, help="placement noise (mm)")
    ap.add_argument("--plates", action="store_true", help="DM: each plate's shear ratio")
    ap.add_argument("--window", action="store_true", help="DM: r in stance / swing (diagnosis)")
    a = ap.parse_args()
    if a.plates:
        plates()
    sel = {s for s in a.only.split(",") if s}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name, trial, swap in RUNS:
            if sel and f"{name}:{trial}" not in sel:
                continue
            cfg = _config(name, swap, "spline", folder)
            tr = Trial(cfg)
            base = report(f"{name} {trial}", tr)
            if a.window:
                window(tr)
            if a.varus and name.startswith("gc6_DM"):
                for dv in (-a.varus, a.varus):
                    c2 = _config(name, swap, "spline", folder, _varus(dv), f"v{dv}")
                    t2 = Trial(c2)
                    other = report(f"{name} {trial} alignment {dv:+.1f}°", t2)
                    rms, r = _compare(tr, t2)
                    for b0, b1 in zip(base, other):
                        print(
                            f"  d(KAM peaks)/d(varus) {(b1['kam'][0] - b0['kam'][0]) / dv:+.3f} "
                            f"/ {(b1['kam'][1] - b0['kam'][1]) / dv:+.3f} N·m/kg per °, GRF "
                            f"line {(b1['grf_z'] - b0['grf_z']) / dv:+.2f} mm/°"
                        )
                    print(f"  lateral against the shipped run: RMS {rms:.3f} BW, r {r:.3f}")
            for k in range(a.jitter):
                t2 = Trial(cfg, sigma_m=a.sigma_mm / 1000, seed=k)
                rms, r = _compare(tr, t2)
                kp = [(b["kam"][0], b["kam"][1]) for b in report(f"{name} {trial} jitter {k}", t2)]
                print(
                    f"  jitter {k} (σ {a.sigma_mm:g} mm): lateral RMS {rms:.3f} BW, r {r:.3f}; "
                    "KAM peaks " + ", ".join(f"{x:.2f}/{y:.2f}" for x, y in kp)
                )


if __name__ == "__main__":
    main()
