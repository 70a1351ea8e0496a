"""The patellar tendon (``[contact] patella = "tendon"``) against the models' own quadriceps
paths (``"none"``), and the common EMG gain (``[optimization] emg_gains = "common"``) against
one gain per channel, on every Grand Challenge gait trial with a measured contact force (PS ss1,
ss3, ss8; DM og1, og3, og4; JW og3): the shipped configs with only the task files swapped
(:mod:`studies.contact_validation`), spline knee. Prints per trial and setting the compared
component's RMSE (BW) and Pearson r (PS: the eTibia total, a magnitude; DM: medial + lateral,
axial; JW: the load cells, axial), the medial and lateral ones where measured, and the lateral
share Σ F_L / Σ (F_M + F_L) over the frames whose measured medial + lateral force exceeds
0.5 BW (stance), predicted / measured.

    python studies/patella_gait.py [--only gc5_PS] [--variants none,tendon] [--out FILE]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from contact_validation import TRIALS, _config

#: variant → (patella, emg_gains, compartments held ≥ 0 as shipped)
VARIANTS = {
    "none": ("none", None, True),
    "tendon": ("tendon", None, True),
    "tendon+common": ("tendon", "common", True),
    "none+common": ("none", "common", True),
    "none-free": ("none", None, False),
    "tendon-free": ("tendon", None, False),
}


def _edit(patella: str, gains: str | None, held: bool):
    def edit(text: str) -> str:
        if not held:
            text = text.replace("compartment_nonnegative = true", "compartment_nonnegative = false")
        if gains is not None:
            text = text.replace("[optimization]\n", f'[optimization]\nemg_gains = "{gains}"\n', 1)
        return text + f'\n[contact]\npatella = "{patella}"\n'

    return edit


def _share(run) -> str:
    from msk.results.folder import read_session

    res = read_session(run.out_dir)
    if not res.has("knee_contact"):
        return "—"
    kc = res.table("knee_contact")
    cols = kc.columns
    if "measured_medial_bw" not in cols or "measured_lateral_bw" not in cols:
        return "—"

    def get(c: str) -> np.ndarray:
        return np.asarray(kc.column(c), dtype=float)

    mm, ml = get("measured_medial_bw"), get("measured_lateral_bw")
    pm, pl = get("generic_medial_bw"), get("generic_lateral_bw")
    ok = np.isfinite(mm + ml + pm + pl) & (mm + ml > 0.5)
    if not ok.any():
        return "—"
    pred = pl[ok].sum() / (pm[ok] + pl[ok]).sum()
    meas = ml[ok].sum() / (mm[ok] + ml[ok]).sum()
    return f"{pred:.2f} / {meas:.2f}"


def main(argv: list[str] | None = None) -> int:
    from msk.pipeline import run_task_trials

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", default="", help="comma-separated config names")
    p.add_argument("--variants", default="none,tendon", help="comma-separated VARIANTS keys")
    p.add_argument("--trials", default="", help="comma-separated trial names (e.g. og1)")
    p.add_argument("--out", type=Path)
    args = p.parse_args(argv)
    only = [s for s in args.only.split(",") if s]
    rows = [
        "| subject | trial | variant | total RMSE (BW) | total r | peak pred / meas (BW) "
        "| medial RMSE | medial r | lateral RMSE | lateral r | lateral share pred / meas |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name, trials in TRIALS.items():
            if only and name not in only:
                continue
            for trial, swap in trials:
                if args.trials and trial not in args.trials.split(","):
                    continue
                for tag in args.variants.split(","):
                    cfg = _config(name, swap, "spline", folder, _edit(*VARIANTS[tag]), tag)
                    (res,) = run_task_trials(cfg, folder / f"{name}_{trial}_{tag}")
                    comp = res.summary.to_dict()["comparison"] or {}
                    cells = []
                    for part in ("", "_medial", "_lateral"):
                        c = comp.get(f"knee_contact_generic{part}")
                        cells += [f"{c['rms_bw']:.3f}", f"{c['pearson_r']:.3f}"] if c else ["—"] * 2
                        if part == "":
                            cells.append(
                                f"{c['peak_predicted_bw']:.2f} / {c['peak_measured_bw']:.2f}"
                                if c
                                else "—"
                            )
                    cells.append(_share(res))
                    rows.append(f"| {name.split('_')[1]} | {trial} | {tag} | " + " | ".join(cells)
                                + " |")  # fmt: skip
                    print(rows[-1], flush=True)
    text = "\n".join(rows) + "\n"
    if args.out:
        args.out.write_text(text, encoding="utf-8")
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
