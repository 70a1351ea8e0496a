"""When the predicted knee contact force leads the measured one, and how its medial/lateral split
moves with the knee's frontal alignment, on the Grand Challenge walks with compartment forces
(PS ss1/ss3/ss8, DM og1/og3/og4): the shipped configs with only the task files swapped
(:mod:`studies.contact_validation`), spline knee, patellar tendon.

**Lead.** For each component (``total``: the compared one — PS's eTibia magnitude, DM's axial
medial + lateral —, ``medial``, ``lateral``) the lead L maximises the Pearson correlation
r(L) = corr(F_pred(t), F_meas(t + L)) over |L| ≤ 100 ms (1 ms steps, both on the kinematics'
time base by linear interpolation, the frames where both exist); L > 0: the prediction is early.
Peak events: the time of the largest value in the first and the second half of stance (split
at the measured total's minimum between its two peaks), predicted − measured.

**Variants** (one edit of the shipped config each): ``shipped``; ``emd0`` / ``emd80`` (PS: the
EMG's electromechanical delay 0 / 80 ms instead of 40); ``so`` (PS: static optimisation, no
EMG); ``cut12`` (kinematics and ground reactions low-passed at 12 Hz instead of 6, both zero
lag); ``varus±3`` (the knee's frontal alignment 3° more varus / valgus than shipped:
``[model] knee_varus_deg``, :func:`msk.model.alignment.with_knee_alignment`).

The total's RMSE (BW) with the prediction delayed by 0, by its best lead and by 40 ms
(``rmse_delayed``: what a delay would buy, not a correction msk applies).

Lateral share Σ F_L / Σ (F_M + F_L) over the frames whose measured medial + lateral force
exceeds 0.5 BW (stance), predicted / measured.

    python studies/contact_timing.py [--variants shipped,emd0] [--trials ss3,og3] [--runs DIR]
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from contact_validation import TRIALS, _config


def _set(key: str, value: str, section: str):
    def edit(text: str) -> str:
        if re.search(rf"(?m)^{key} = ", text):
            return re.sub(rf"(?m)^{key} = .*$", f"{key} = {value}", text, count=1)
        if f"[{section}]\n" in text:
            return text.replace(f"[{section}]\n", f"[{section}]\n{key} = {value}\n", 1)
        return text + f"\n[{section}]\n{key} = {value}\n"

    return edit


def _varus(delta: float):
    def edit(text: str) -> str:
        m = re.search(r"(?m)^knee_varus_deg = (.*)$", text)
        base = float(m.group(1)) if m else 0.0
        return _set("knee_varus_deg", f"{base + delta:.3f}", "model")(text)

    return edit


def _both(*edits):
    def edit(text: str) -> str:
        for e in edits:
            text = e(text)
        return text

    return edit


#: variant → (edit, configs it applies to)
VARIANTS = {
    "shipped": (None, ("gc5_PS", "gc6_DM_og1")),
    "emd0": (_set("electromechanical_delay_s", "0.0", "emg"), ("gc5_PS",)),
    "emd80": (_set("electromechanical_delay_s", "0.08", "emg"), ("gc5_PS",)),
    "so": (_set("method", '"static_optimization"', "optimization"), ("gc5_PS",)),
    "cut12": (
        _both(
            _set("kinematics_cutoff_hz", "12.0", "filters"),
            _set("grf_cutoff_hz", "12.0", "filters"),
        ),
        ("gc5_PS", "gc6_DM_og1"),
    ),
    "varus+3": (_varus(3.0), ("gc5_PS", "gc6_DM_og1")),
    "varus-3": (_varus(-3.0), ("gc5_PS", "gc6_DM_og1")),
}

MAX_LEAD_S = 0.100


def lead(t: np.ndarray, pred: np.ndarray, meas: np.ndarray) -> tuple[float, float, float]:
    """(L s, r at L, r at 0): the lead maximising corr(pred(t), meas(t + L)) (module docstring)."""
    ok_m = np.isfinite(meas)
    tm, ym = t[ok_m], meas[ok_m]

    def r_at(lag: float) -> float:
        y = np.interp(t + lag, tm, ym, left=np.nan, right=np.nan)
        sel = np.isfinite(y) & np.isfinite(pred)
        if sel.sum() < 10:
            return np.nan
        return float(np.corrcoef(pred[sel], y[sel])[0, 1])

    lags = np.arange(-MAX_LEAD_S, MAX_LEAD_S + 1e-9, 0.001)
    rs = np.array([r_at(x) for x in lags])
    k = int(np.nanargmax(rs))
    return float(lags[k]), float(rs[k]), r_at(0.0)


def peaks(t: np.ndarray, pred: np.ndarray, meas: np.ndarray) -> tuple[float, ...]:
    """(first peak, second peak, loading onset, unloading) time differences predicted −
    measured (s): the peaks in the two halves of stance (split at the measured force's minimum
    between its two peaks); onset / unloading where each curve first rises / last falls
    through half of its own peak of that half."""
    sel = np.isfinite(meas) & np.isfinite(pred)
    ts, p, m = t[sel], pred[sel], meas[sel]
    st = np.flatnonzero(m > 0.5 * np.nanmax(m))
    if st.size < 4:
        return (np.nan,) * 4
    a, b = st[0], st[-1]
    mid = a + (b - a) // 4 + int(np.argmin(m[a + (b - a) // 4 : b - (b - a) // 4]))
    out = []
    for lo, hi in ((a, mid), (mid, b + 1)):
        out.append(float(ts[lo + np.argmax(p[lo:hi])] - ts[lo + np.argmax(m[lo:hi])]))
    # loading onset: the first rise through half of each curve's own first-half peak
    on = []
    for y in (p, m):
        half = 0.5 * np.max(y[a:mid])
        k = int(np.argmax(y[:mid] >= half))
        on.append(float(np.interp(half, [y[k - 1], y[k]], [ts[k - 1], ts[k]])) if k else ts[0])
    # unloading: the last fall through half of each curve's own second-half peak
    off = []
    for y in (p, m):
        half = 0.5 * np.max(y[mid : b + 1])
        k = len(y) - 1 - int(np.argmax(y[::-1] >= half))
        off.append(
            float(np.interp(half, [y[k + 1], y[k]], [ts[k + 1], ts[k]]))
            if k + 1 < len(y)
            else ts[-1]
        )
    return out[0], out[1], on[0] - on[1], off[0] - off[1]


def moment_peak(res, t: np.ndarray, pred: np.ndarray, meas: np.ndarray) -> tuple[float, ...]:
    """(predicted, measured) first-half-of-stance peak time minus that of the inverse-dynamics
    knee moment (its larger-magnitude extreme in the first half of stance), s."""
    side = "_l" if res.summary.subject.side == "left" else "_r"
    jt = res.table("joint_torques")
    mom = np.interp(t, np.asarray(jt.time), np.asarray(jt.column(f"knee_angle{side}")))
    sel = np.isfinite(meas) & np.isfinite(pred)
    ts, p, m, mo = t[sel], pred[sel], meas[sel], mom[sel]
    st = np.flatnonzero(m > 0.5 * np.nanmax(m))
    if st.size < 4:
        return (np.nan, np.nan)
    a, b = st[0], st[-1]
    q = (b - a) // 4
    mid = a + q + int(np.argmin(m[a + q : b - q]))
    seg = mo[a:mid]
    k = int(np.argmax(np.abs(seg)))
    tm = ts[a + k]
    return float(ts[a + np.argmax(p[a:mid])] - tm), float(ts[a + np.argmax(m[a:mid])] - tm)


def analyse(out_dir: Path) -> dict[str, object]:
    from msk.results.folder import read_session

    res = read_session(out_dir)
    kc = res.table("knee_contact")
    t = np.asarray(kc.time, dtype=float)
    comp = res.summary.comparison.knee_contact("generic") if res.summary.comparison else None
    axial = comp is not None and comp.component == "axial total"

    def col(c: str) -> np.ndarray:
        return np.asarray(kc.column(c), dtype=float) if c in kc.columns else np.full(t.size, np.nan)

    row: dict[str, object] = {}
    pairs = {
        "total": (
            col("generic_axial_bw" if axial else "generic_total_bw"),
            col("measured_total_bw"),
        ),
        "medial": (col("generic_medial_bw"), col("measured_medial_bw")),
        "lateral": (col("generic_lateral_bw"), col("measured_lateral_bw")),
    }
    for name, (p, m) in pairs.items():
        if np.isfinite(m).sum() < 10:
            continue
        row[name] = lead(t, p, m)
    row["peaks"] = peaks(t, *pairs["total"])
    # the total's RMSE (BW) with the prediction delayed by 0, by its best lead and by 40 ms
    p_tot, m_tot = pairs["total"]
    rms = []
    for lag in (0.0, row["total"][0], 0.040) if "total" in row else ():
        pd = np.interp(t - lag, t, p_tot, left=np.nan, right=np.nan)
        sel = np.isfinite(pd) & np.isfinite(m_tot)
        rms.append(float(np.sqrt(np.mean((pd[sel] - m_tot[sel]) ** 2))))
    row["rmse_delayed"] = tuple(rms)
    row["moment_peak"] = moment_peak(res, t, *pairs["total"])
    mm, ml = pairs["medial"][1], pairs["lateral"][1]
    pm, pl = pairs["medial"][0], pairs["lateral"][0]
    ok = np.isfinite(mm + ml + pm + pl) & (mm + ml > 0.5)
    if ok.any():
        row["share"] = (
            pl[ok].sum() / (pm[ok] + pl[ok]).sum(),
            ml[ok].sum() / (mm[ok] + ml[ok]).sum(),
        )
    if comp is not None:
        row["rmse"] = comp.rms_bw
    lat = res.summary.comparison.knee_contact("generic", "lateral")
    if lat is not None:
        row["lat_rmse_r"] = (lat.rms_bw, lat.pearson_r)
    return row


def main(argv: list[str] | None = None) -> int:
    from msk.pipeline import run_task_trials

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--variants", default="shipped")
    p.add_argument("--trials", default="")
    p.add_argument("--runs", type=Path, default=Path("/tmp/contact_timing"))
    args = p.parse_args(argv)
    args.runs.mkdir(parents=True, exist_ok=True)
    for tag in args.variants.split(","):
        edit, names = VARIANTS[tag]
        for name in names:
            for trial, swap in TRIALS[name]:
                if args.trials and trial not in args.trials.split(","):
                    continue
                out = args.runs / f"{name}_{trial}_{tag}"
                if not (out / "summary.json").exists():
                    cfg = _config(name, swap, "spline", args.runs, edit, f"{trial}{tag}")
                    (res,) = run_task_trials(cfg, out)
                    out = res.out_dir
                row = analyse(out)
                cells = [f"{k}: " + ", ".join(f"{v:+.3f}" if isinstance(v, float) else str(v)
                                              for v in (val if isinstance(val, tuple) else (val,)))
                         for k, val in row.items()]  # fmt: skip
                print(f"{name.split('_')[1]} {trial} {tag} | " + " | ".join(cells), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
