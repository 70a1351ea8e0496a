"""Run the shipped session configs with only their task files swapped for other recordings of
the same kind (other trials of the same subject and lab), as a user — or a scorer — would.

For each (config, alternative task) pair the config is read as shipped, its task trial's files
(``file``, and ``grf``/``external_loads``/``contact_force`` where the alternative has them)
replaced, and the session run into a temporary folder. Printed per run: exit status (ok, or the
one-line error), IK marker RMS, pelvis residual force (% BW), the measured contact force's RMSE
and r where there is one, and the quality flags raised. Nothing here is asserted: it is the
check that the configs are written for the kinds of data, not for their files.

Usage: ``.venv/bin/python scripts/task_swap.py [--only gc5_PS,gc6_DM_og1]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
REAL = REPO.parent / "shared" / "data" / "real"
GC5, DM = REAL / "knee-grand-challenge-gc5", REAL / "knee-grand-challenge-gc6-DM"

#: config stem → alternative task trials: (name, {field: path})
ALTERNATIVES: dict[str, list[tuple[str, dict[str, Path]]]] = {
    "gc5_PS": [
        (f"ngait_og_ss{k}", {"file": GC5 / f"PS_ngait_og_ss{k}.c3d",
                             "contact_force": GC5 / f"PS_ngait_og_ss{k}_eTibia.csv"})
        for k in (3, 8)
    ],
    "gc6_DM_og1": [
        (f"{t}", {"file": DM / f"DM_{t}_new.trc", "grf": DM / f"DM_{t}_grf.sto",
                  "external_loads": DM / f"DM_{t}_external_loads.xml",
                  **({"contact_force": REPO / "data" / "gc6-DM" / f"DM_{t}_contact.csv"}
                     if t in ("ngait_og3", "ngait_og4") else {})})
        for t in ("ngait_og3", "ngait_og4", "bouncy5", "smooth1")
    ],
    "unipd_bts": [
        (f"walking{k}", {"file": REAL / "motonms-testdata" / "UNIPD" / f"Walking{k}.c3d"})
        for k in (2, 3)
    ],
}  # fmt: skip


def _swap(cfg, name: str, files: dict[str, Path]):
    trials = []
    for t in cfg.trials:
        if t.role == "task":
            keep = {k: None for k in ("contact_force", "grf", "external_loads") if k not in files}
            t = dataclasses.replace(t, name=name, **files, **keep)
        trials.append(t)
    return dataclasses.replace(cfg, trials=tuple(trials))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="comma-separated config stems")
    args = ap.parse_args()
    from msk.config import load_config, render_config
    from msk.exceptions import MskError
    from msk.pipeline import run_task_trials

    only = set(filter(None, args.only.split(",")))
    print("| config | task | status | IK (mm) | residual (% BW) | contact RMSE (BW) / r | flags |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for stem, alts in ALTERNATIVES.items():
        if only and stem not in only:
            continue
        cfg = load_config(REPO / "pipelines" / f"{stem}.toml")
        for name, files in alts:
            if not all(p.exists() for p in files.values()):
                print(f"| {stem} | {name} | files missing | | | | |")
                continue
            with tempfile.TemporaryDirectory() as tmp:
                path = Path(tmp) / f"{stem}_{name}.toml"
                path.write_text(render_config(_swap(cfg, name, files)), encoding="utf-8")
                t0 = time.perf_counter()
                try:
                    (res,) = run_task_trials(path, Path(tmp) / "out")
                except MskError as exc:
                    msg = " ".join(str(exc).split())[:150]
                    print(f"| {stem} | {name} | error: {msg} | | | | |")
                    continue
                q = res.summary["quality"]
                ik = 1000 * (q.get("ik_marker_rms_mean_m") or float("nan"))
                r = q.get("residual_force_rms_pct_bw")
                comp = res.summary.get("comparison") or {}
                con = " · ".join(
                    f"{k.removeprefix('knee_contact_')} {v['rms_bw']:.2f} / {v['pearson_r']:.2f}"
                    for k, v in comp.items() if k.startswith("knee_contact_")
                    and isinstance(v, dict) and "rms_bw" in v
                )  # fmt: skip
                flags = ", ".join(sorted({f["quantity"] for f in q.get("flags", [])}))
                print(f"| {stem} | {name} | ok ({time.perf_counter() - t0:.0f} s) | {ik:.1f} | "
                      f"{'' if r is None else f'{r:.1f}'} | {con} | {flags or '—'} |")  # fmt: skip
            sys.stdout.flush()


if __name__ == "__main__":
    main()
