"""The patellar tendon (``[contact] patella = "tendon"``) against the models' own quadriceps
paths (``"none"``) on every Grand Challenge gait trial with a measured contact force (PS ss1,
ss3, ss8; DM og1, og3, og4; JW og3), the shipped configs with only the task files swapped
(:mod:`studies.contact_validation`), spline knee. Prints per trial and setting the like
component's RMSE (BW) and Pearson r: PS's eTibia total (a magnitude), DM's medial + lateral and
JW's load cells (axial), and the medial / lateral forces where measured.

    python studies/patella_gait.py [--only gc5_PS] [--out FILE]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from contact_validation import TRIALS, _config


def _patella(mode: str):
    return lambda text: text + f'\n[contact]\npatella = "{mode}"\n'


def main(argv: list[str] | None = None) -> int:
    from msk.pipeline import run_task_trials

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", default="", help="comma-separated config names")
    p.add_argument("--out", type=Path)
    args = p.parse_args(argv)
    only = [s for s in args.only.split(",") if s]
    rows = [
        "| subject | trial | patella | total RMSE (BW) | total r | peak pred / meas (BW) "
        "| medial RMSE | medial r | lateral RMSE | lateral r |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name, trials in TRIALS.items():
            if only and name not in only:
                continue
            for trial, swap in trials:
                for mode in ("none", "tendon"):
                    cfg = _config(name, swap, "spline", folder, _patella(mode), mode)
                    (res,) = run_task_trials(cfg, folder / f"{name}_{trial}_{mode}")
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
                    rows.append(f"| {name.split('_')[1]} | {trial} | {mode} | " + " | ".join(cells)
                                + " |")  # fmt: skip
                    print(rows[-1], flush=True)
    text = "\n".join(rows) + "\n"
    if args.out:
        args.out.write_text(text, encoding="utf-8")
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
