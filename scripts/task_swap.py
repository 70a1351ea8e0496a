"""Run the shipped session configs with only their task files swapped for other recordings of
the same kinds (other trials and tasks of the same subject, other subjects and labs with a
marker set of the same family, standing-only tasks), as a user — or a scorer — would.

For each (config, alternative task) pair the config is read as shipped, its task trial's files
(``file``, and ``grf``/``external_loads``/``contact_force`` where the alternative has them)
replaced, and the session run into a temporary folder. Printed per run: exit status (ok, or the
one-line error; "CRASH" and the exception for a traceback), IK marker RMS, pelvis residual
force (% BW), the measured contact force's RMSE and r where there is one, and the quality
flags raised. Nothing here is asserted: it is the
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
GC4 = REAL / "knee-grand-challenge-gc4"


#: DM trials: name → {field: path} (the treadmill trials have no ExternalLoads file)
def _dm(t: str) -> dict[str, Path]:
    if t.endswith("tm1") or t.endswith("tm_ss1"):
        return {"file": DM / f"DM_{t}_new.trc", "grf": DM / f"DM_{t}_grf_filt.sto"}
    files = {
        "file": DM / f"DM_{t}_new.trc",
        "grf": DM / f"DM_{t}_grf.sto",
        "external_loads": DM / f"DM_{t}_external_loads.xml",
    }
    if t.startswith("ngait_og"):
        files["contact_force"] = REPO / "data" / "gc6-DM" / f"DM_{t}_contact.csv"
    return files  # fmt: skip


UWA, UNIPD = REAL / "motonms-testdata" / "UWA", REAL / "motonms-testdata" / "UNIPD"
OSIM = REAL / "opensim-core-c3d"
S01, RAJ = REAL / "opensim-subject01-walk", REAL / "opensim-rajagopal-walk"
PIG_WALKS = (
    "btkdata/PlugInC3D.c3d",
    "btkdata/Gait.c3d",
    "btkdata/type-2a.c3d",
    "opensim-core-c3d/walking2.c3d",
    "ezc3d-testfiles/BTS.c3d",
)

#: config stem → alternative task trials: (name, {field: path}). Other trials of the shipped
#: kinds: the same subject's other trials and tasks, other labs' walks with the same marker sets.
ALTERNATIVES: dict[str, list[tuple[str, dict[str, Path]]]] = {
    "gc5_PS": [
        *[(f"ngait_og_ss{k}", {"file": GC5 / f"PS_ngait_og_ss{k}.c3d",
                               "contact_force": GC5 / f"PS_ngait_og_ss{k}_eTibia.csv"})
          for k in (3, 8)],
        ("static_as_task", {"file": GC5 / "PS_static_for_scaling.trc"}),
        ("jw_ngait_og3", {"file": GC4 / "jw_ngait_og3.c3d"}),
    ],
    "gc4_JW": [("1legstand1_task", {"file": GC4 / "jw_1legstand1.c3d"})],
    "gc6_DM_og1": [(t, _dm(t)) for t in ("ngait_og3", "ngait_og4", "bouncy5", "smooth1",
                                         "crouch_tm1", "ngait_tm_ss1")],
    "gc6_DM_crouch_tm": [(t, _dm(t)) for t in ("ngait_tm_ss1", "ngait_og1", "bouncy5")],
    "gc6_DM_ngait_tm_ss": [(t, _dm(t)) for t in ("crouch_tm1", "ngait_og1", "smooth1")],
    "unipd_bts": [
        *[(f"walking{k}", {"file": UNIPD / f"Walking{k}.c3d"}) for k in (2, 3)],
        ("BTS", {"file": REAL / "ezc3d-testfiles" / "BTS.c3d"}),
        ("static1_task", {"file": UNIPD / "Static1.c3d"}),  # standing-only, no plate loaded
    ],
    "uwa_fast_walking": [("running_1", {"file": UWA / "Running_1.c3d"})],
    "uwa_running": [("fast_walking", {"file": UWA / "Fast_Walking.c3d"})],
    "pig_motion3": [
        *[(Path(f).stem, {"file": REAL / f}) for f in PIG_WALKS],
        # standing-only tasks: on three plates, and the session's own static (no plates)
        ("FunctionalStatic", {"file": REAL / "btkdata" / "FunctionalStatic.c3d"}),
        ("calibration3_task", {"file": REAL / "btkdata" / "PiG_Calibration3_FF.c3d"}),
    ],
    "opensim_subject01": [
        ("walking2", {"file": OSIM / "std_walking2_markers.trc",
                      "grf": OSIM / "std_walking2_grfs.sto"}),
        ("rajagopal_walk", {"file": RAJ / "markers_walk.trc", "grf": RAJ / "grf_walk.mot",
                            "external_loads": RAJ / "grf_walk.xml"}),
    ],
    "opensim_rajagopal": [
        ("subject01_walk", {"file": S01 / "subject01_walk.trc",
                            "grf": S01 / "subject01_walk_grf.mot",
                            "external_loads": S01 / "subject01_walk_grf.xml"}),
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
                except MskError as exc:  # the CLI's exit 2: a refusal with a message
                    msg = " ".join(str(exc).split())[:150]
                    print(f"| {stem} | {name} | error: {msg} | | | | |")
                    continue
                except Exception as exc:  # a crash (a traceback), reported per run
                    msg = " ".join(f"{type(exc).__name__}: {exc}".split())[:150]
                    print(f"| {stem} | {name} | CRASH {msg} | | | | |")
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
