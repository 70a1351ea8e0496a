"""Synchronisation of the analog data (plates, goniometer) with the markers, from the data.

    python studies/analog_marker_sync.py

Two independent estimates per Grand Challenge trial (the shipped ``pipelines/gc5_PS.toml`` and
``pipelines/gc6_DM_og1.toml``, only the task files swapped):

* **vertical momentum**: on the frames whose every foot contact is on a plate and whose leg
  segments the markers observe (``Loads.usable``), the plates'
  total vertical force Σ F_z(t + d) against m (g + z̈_G(t)) from the model's centre of mass on
  the inverse-kinematics coordinates (Newton's second law for the whole body); the shift ``d``
  (3-sample steps at 1200 Hz, ±50 ms) with the smallest RMS difference;
* **goniometer** (PS only: its C3D records a knee electrogoniometer on an analog channel): the
  shift ``d`` maximising |r| between goniometer(t + d) and the IK knee angle of the same leg.

The shipped UWA configs (``pipelines/uwa_fast_walking.toml``, ``uwa_running.toml``: Vicon,
250 Hz markers) get the vertical-momentum estimate too.

For subject JW (``pipelines/gc4_JW.toml``), whose load-cell file carries the knee goniometer in
degrees (``GON``), the IK knee flexion is also compared with it in degrees: the linear fit
IK = a·GON + b and the mean difference over the frames whose ground reaction is measured.

A positive ``d`` means the analog signal shows an event ``d`` later than the markers. Used in
docs/validation.md (medial/lateral contact, "the 21–41 ms lead") as evidence that is not the
measured contact force.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import contact_validation as cv

SHIFTS_S = np.arange(-0.05, 0.0501, 3 / 1200)


def _best(score: list[tuple[float, float]]) -> tuple[float, float, float]:
    """(best score, its shift, score at zero shift) of (score, shift) pairs, lower is better."""
    best = min(score)
    zero = min(score, key=lambda s: abs(s[1]))
    return best[0], best[1], zero[0]


def _momentum(kin: object, loads: object, model: object) -> tuple[float, float, float]:
    import pinocchio as pin

    t = np.asarray(kin.time)  # type: ignore[attr-defined]
    q, v = np.asarray(kin.q), np.asarray(kin.v)  # type: ignore[attr-defined]
    pm = model.pin_model  # type: ignore[attr-defined]
    data = model.create_data()  # type: ignore[attr-defined]
    g = np.asarray(pm.gravity.linear)
    up = -g / np.linalg.norm(g)
    height = np.full(t.size, np.nan)
    for k in np.flatnonzero(np.isfinite(q).all(axis=1)):
        qp, _, _ = model.coupling.embed(q[k : k + 1], v[k : k + 1], v[k : k + 1])  # type: ignore[attr-defined]
        pin.centerOfMass(pm, data, qp[0])
        height[k] = np.asarray(data.com[0]) @ up
    dt = float(np.median(np.diff(t)))
    newton = sum(i.mass for i in pm.inertias) * (
        np.linalg.norm(g) + np.gradient(np.gradient(height, dt), dt)
    )
    fz = np.nansum(np.asarray(loads.external.force) @ up, axis=1)  # type: ignore[attr-defined]
    score = []
    for d in SHIFTS_S:
        f = np.interp(t + d, t, fz, left=np.nan, right=np.nan)
        ok = np.asarray(loads.usable) & np.isfinite(f) & np.isfinite(newton)  # type: ignore[attr-defined]
        ok[:5] = ok[-5:] = False  # the finite-difference ends
        score.append((float(np.sqrt(np.mean((f[ok] - newton[ok]) ** 2))), float(d)))
    return _best(score)


def _goniometer(kin: object, task_file: Path, side: str) -> tuple[float, float, float] | None:
    from msk.io import read_c3d

    tr = read_c3d(task_file)
    labels = [str(s).strip() for s in tr.analog_labels]
    if "goniometer" not in labels:
        return None
    g = np.asarray(tr.analogs)[:, labels.index("goniometer")]
    t = np.asarray(kin.time)  # type: ignore[attr-defined]
    knee = np.asarray(kin.q)[:, list(kin.coordinate_names).index(f"knee_angle_{side[0]}")]  # type: ignore[attr-defined]
    score = []
    for d in SHIFTS_S:
        gi = np.interp(t + d, np.asarray(tr.analog_time), g, left=np.nan, right=np.nan)
        ok = np.isfinite(gi) & np.isfinite(knee)
        score.append((-abs(float(np.corrcoef(gi[ok], knee[ok])[0, 1])), float(d)))
    return _best(score)


def _jw_goniometer() -> None:
    from msk.config import load_config
    from msk.pipeline import run_stages

    cfg = load_config(cv.REPO / "pipelines" / "gc4_JW.toml")
    (task,) = [tc for tc in cfg.trials if tc.role == "task"]
    assert task.contact_force is not None
    cells = np.loadtxt(task.contact_force, delimiter=",", skiprows=1, usecols=range(7))
    r = run_stages(cfg, until="loads")
    kin, usable = r["kinematics"], r["loads"].usable
    gon = np.interp(kin.time, cells[:, 0], cells[:, 5])
    knee = -np.degrees(kin.q[:, list(kin.coordinate_names).index("knee_angle_r")])
    a, b = np.polyfit(gon, knee, 1)
    print(
        f"JW og3 goniometer (deg) vs IK knee flexion: r {np.corrcoef(gon, knee)[0, 1]:.3f}, "
        f"IK = {a:.2f} GON {b:+.1f}°; on the measured frames IK − GON "
        f"{np.mean((knee - gon)[usable]):+.1f}° "
        f"(IK {knee[usable].min():.1f}…{np.percentile(knee[usable], 50):.1f}° min…median, "
        f"GON {gon[usable].min():.1f}…{np.percentile(gon[usable], 50):.1f}°)"
    )


def main() -> int:
    from msk.config import load_config
    from msk.pipeline import run_stages

    folder = Path(tempfile.mkdtemp())
    print(
        "| trial | momentum: best d (ms) | RMS at d / at 0 (N) | goniometer: best d (ms) "
        "| |r| at d / at 0 |"
    )
    print("| --- | --- | --- | --- | --- |")
    for name, trials in cv.TRIALS.items():
        for trial, swap in trials:
            cfg = load_config(cv._config(name, swap, "spline", folder, None, trial))
            r = run_stages(cfg, until="loads")
            m = _momentum(r["kinematics"], r["loads"], r["model"].model)
            (task,) = [tc for tc in cfg.trials if tc.role == "task"]
            gon = (
                _goniometer(r["kinematics"], task.file, cfg.subject.side)
                if task.file.suffix.lower() == ".c3d"
                else None
            )
            gtxt = (
                "— | —" if gon is None else f"{gon[1] * 1000:+.1f} | {-gon[0]:.3f} / {-gon[2]:.3f}"
            )
            print(
                f"| {name.split('_')[1]} {trial} | {m[1] * 1000:+.1f} | {m[0]:.1f} / {m[2]:.1f} "
                f"| {gtxt} |",
                flush=True,
            )
    for stem in ("uwa_fast_walking", "uwa_running"):  # the shipped UWA configs as they are
        cfg = load_config(cv.REPO / "pipelines" / f"{stem}.toml")
        r = run_stages(cfg, until="loads")
        m = _momentum(r["kinematics"], r["loads"], r["model"].model)
        print(f"| {stem} | {m[1] * 1000:+.1f} | {m[0]:.1f} / {m[2]:.1f} | — | — |", flush=True)
    _jw_goniometer()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
