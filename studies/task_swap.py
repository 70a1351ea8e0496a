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

``--synthetic`` adds the hidden task kinds (issue 15, ninth pass): a two-leg squat and a stair
ascent of the session's own placed model with a known truth, written in its lab's C3D format
(:func:`msk.datasets.tasks.lab_task`; the configs of :data:`SYNTHETIC`), run with only the task
swapped like the real alternatives. Besides the row of the table, each prints its figures
against the truth (:func:`compare_to_truth`): the leg coordinates' RMS difference (deg, over
the frames IK solved; the knee flexion's range solved vs true), the leg joint torques' RMSE
(N·m, over the frames the run writes a torque) and the true peaks, and the frames written as
unmeasured contact (NaN torques) against the truth's count
(``tests/datasets/test_synthetic_tasks.py``
asserts them on JW).

The DM configs (:data:`SYNTHETIC_TRC`: a ``.trc`` task with an OpenSim GRF ``.sto`` and, for
the overground one, its ExternalLoads ``.xml``; no static) get a level walk and a two-leg squat
of a *known* subject (:func:`msk.datasets.trc.trc_task`: the session's placed model scaled
again by known per-segment factors), written in DM's files' naming; their truth comparison adds
the scale factors the run chose against the subject's and the model's mass (issue 15,
thirteenth pass).

``stair_on_plates`` is the stair as a lab records it (:data:`AS_RECORDED`).

Usage: ``.venv/bin/python studies/task_swap.py [--only gc5_PS,gc6_DM_og1] [--synthetic
[--kinds squat,stair,stair_on_plates,walk] [--keep DIR]]``; ``--synthetic-only`` runs the
synthetic trials alone.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

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


#: configs whose lab format :func:`msk.datasets.tasks.lab_task` writes (a C3D task)
SYNTHETIC = ("gc4_JW", "gc5_PS")
#: configs whose lab format :func:`msk.datasets.trc.trc_task` writes (a .trc task with an
#: OpenSim GRF file): a known subject, not the session's own model (issue 15, thirteenth pass)
SYNTHETIC_TRC = ("gc6_DM_og1", "gc6_DM_ngait_tm_ss", "gc6_DM_crouch_tm")
#: the kinds each writer makes
KINDS_C3D, KINDS_TRC = ("squat", "stair", "stair_on_plates"), ("walk", "squat")
#: kinds as a lab records them (:func:`msk.datasets.tasks.lab_task`): the stair's steps standing
#: on their plates (the corners stored at floor level), every label with a subject prefix the
#: static lacks, every plate reading 30 N unloaded
AS_RECORDED = {
    "stair_on_plates": ("stair", {"corners_at_floor": True, "label_prefix": "S1:",
                                  "plate_offset_n": 30.0}),
}  # fmt: skip
#: the leg coordinates compared with a synthetic task's truth
LEG = ("hip_flexion", "hip_adduction", "hip_rotation", "knee_angle", "ankle_angle")


def swap_task(cfg: Any, name: str, files: dict[str, Path]) -> Any:
    """``cfg`` (a loaded config) with its task trial named ``name`` and its files replaced by
    ``files`` ({field: path}); the task's ``contact_force``, ``grf`` and ``external_loads``
    that ``files`` does not give are dropped (they belong to the shipped task)."""
    trials = []
    for t in cfg.trials:
        if t.role == "task":
            keep = {k: None for k in ("contact_force", "grf", "external_loads") if k not in files}
            t = dataclasses.replace(t, name=name, **files, **keep)
        trials.append(t)
    return dataclasses.replace(cfg, trials=tuple(trials))


def swapped_config(stem: str, name: str, files: dict[str, Path], folder: Path) -> Path:
    """The shipped config ``stem`` with its task swapped (:func:`swap_task`), written into
    ``folder`` as ``<stem>_<name>.toml``."""
    from msk.config import load_config, render_config

    cfg = load_config(REPO / "pipelines" / f"{stem}.toml")
    path = folder / f"{stem}_{name}.toml"
    path.write_text(render_config(swap_task(cfg, name, files)), encoding="utf-8")
    return path


def compare_to_truth(task: Any, cfg: Path) -> dict[str, Any]:
    """IK and joint torques of the run of ``cfg`` (up to inverse dynamics) against the truth
    of ``task`` (a :class:`msk.datasets.tasks.LabTask`): per leg coordinate the RMS
    difference (deg, frames IK solved) and the torque RMSE (N·m, frames with a written
    torque) and true peak; frames written as unmeasured contact; frames of the truth's
    unmeasured contact whose leg torque was written anyway (must be none)."""
    from msk.pipeline import run_stages

    res = run_stages(cfg, until="inverse_dynamics")
    kin, jt = res["kinematics"], res["inverse_dynamics"].generic
    names = list(task.motion.model.coordinate_names)
    true_t = task.motion.time
    out: dict[str, Any] = {"ik_deg": {}, "tau_rmse_nm": {}, "tau_peak_nm": {}}
    t = np.asarray(kin.time)
    # the trial starts at the truth's first sample (a .trc task: at its files' time offset)
    t0 = float(getattr(task, "time_offset_s", t[0]))
    idx = np.clip(np.round((t - t0) * (true_t.size - 1) / (true_t[-1] - true_t[0])), 0,
                  true_t.size - 1).astype(int)  # fmt: skip
    tau_w = np.asarray(jt.tau)
    for side in ("r", "l"):
        for c in LEG:
            n = f"{c}_{side}"
            q = np.rad2deg(kin.coordinate(n))
            qt = np.rad2deg(task.motion.q[idx, names.index(n)])
            ok = np.isfinite(q)
            out["ik_deg"][n] = float(np.sqrt(np.mean((q[ok] - qt[ok]) ** 2)))
            tau = tau_w[:, list(jt.coordinate_names).index(n)]
            tt = task.tau[idx, names.index(n)]
            ok = np.isfinite(tau)
            out["tau_rmse_nm"][n] = (
                float(np.sqrt(np.mean((tau[ok] - tt[ok]) ** 2))) if ok.any() else None
            )
            out["tau_peak_nm"][n] = float(np.abs(tt).max())
    out["frames"] = int(t.size)
    out["written_unmeasured"] = int(
        (~np.isfinite(tau_w[:, list(jt.coordinate_names).index("knee_angle_r")])).sum()
    )
    bad = 0
    for side in ("r", "l"):
        foot_on = np.zeros(true_t.size, dtype=bool)
        for fh in task.motion.footholds:
            if fh.foot.endswith(side) and fh.surface not in task.measured_surfaces:
                foot_on |= (true_t >= fh.t_on) & (true_t <= fh.t_off)
        col = list(jt.coordinate_names).index(f"knee_angle_{side}")
        bad += int((foot_on[idx] & np.isfinite(tau_w[:, col])).sum())
    out["unblanked_true_unmeasured"] = bad
    out["true_unmeasured"] = int(task.unmeasured[idx].sum())
    knee = names.index("knee_angle_r")
    out["knee_r_range_deg"] = (
        float(np.nanmin(np.rad2deg(-kin.coordinate("knee_angle_r")))),
        float(np.nanmax(np.rad2deg(-kin.coordinate("knee_angle_r")))),
    )
    out["knee_r_true_deg"] = (
        float(np.rad2deg(-task.motion.q[:, knee]).min()),
        float(np.rad2deg(-task.motion.q[:, knee]).max()),
    )
    truth_sf = getattr(task, "scale_factors", None)
    if truth_sf:  # a known subject (msk.datasets.trc): its segments and mass
        bodies = res["model"].info["scaling"]["bodies"]
        out["scale"] = {b: (float(bodies[b]["factors"][0]), float(f))
                        for b, f in truth_sf.items() if b in bodies}  # fmt: skip
        out["mass_kg"] = (float(res["model"].model.total_mass), float(task.mass_kg))
    return out


def _row(stem: str, name: str, path: Path, out: Path) -> Any:
    """Run one swapped config and print its row; the result, or None after an error."""
    from msk.exceptions import MskError
    from msk.pipeline import run_task_trials

    t0 = time.perf_counter()
    try:
        (res,) = run_task_trials(path, out)
    except MskError as exc:  # the CLI's exit 2: a refusal with a message
        msg = " ".join(str(exc).split())[:150]
        print(f"| {stem} | {name} | error: {msg} | | | | |")
        return None
    except Exception as exc:  # a crash (a traceback), reported per run
        msg = " ".join(f"{type(exc).__name__}: {exc}".split())[:150]
        print(f"| {stem} | {name} | CRASH {msg} | | | | |")
        return None
    q = res.summary.to_dict()["quality"]
    ik = 1000 * (q.get("ik_marker_rms_mean_m") or float("nan"))
    r = q.get("residual_force_rms_pct_bw")
    comp = res.summary.to_dict().get("comparison") or {}
    con = " · ".join(
        f"{k.removeprefix('knee_contact_')} {v['rms_bw']:.2f} / {v['pearson_r']:.2f}"
        for k, v in comp.items() if k.startswith("knee_contact_")
        and isinstance(v, dict) and "rms_bw" in v
    )  # fmt: skip
    flags = ", ".join(sorted({f["quantity"] for f in q.get("flags", [])}))
    print(f"| {stem} | {name} | ok ({time.perf_counter() - t0:.0f} s) | {ik:.1f} | "
          f"{'' if r is None else f'{r:.1f}'} | {con} | {flags or '—'} |")  # fmt: skip
    return res


def _print_truth(stem: str, kind: str, cmp: dict[str, Any]) -> None:
    ik = {k: round(v, 2) for k, v in cmp["ik_deg"].items()}
    tau = {k: None if v is None else round(v, 1) for k, v in cmp["tau_rmse_nm"].items()}
    peak = {k: round(v, 1) for k, v in cmp["tau_peak_nm"].items()}
    print(f"   {stem} {kind}: IK − truth (deg RMS): {ik}")
    print(f"   torque RMSE (N·m): {tau}")
    print(f"   true peak (N·m): {peak}")
    print(f"   knee_r flexion solved {cmp['knee_r_range_deg']}, true {cmp['knee_r_true_deg']}")
    print(f"   frames {cmp['frames']}, unmeasured written {cmp['written_unmeasured']}, "
          f"true {cmp['true_unmeasured']}, of those written: "
          f"{cmp['unblanked_true_unmeasured']}")  # fmt: skip
    if "scale" in cmp:
        sc = {b: f"{r:.3f}/{t:.3f}" for b, (r, t) in cmp["scale"].items()
              if not b.startswith(("talus", "toes"))}  # fmt: skip
        print(f"   scale factors run/truth: {sc}")
        print(f"   model mass run/truth (kg): {cmp['mass_kg'][0]:.1f}/{cmp['mass_kg'][1]:.1f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="comma-separated config stems")
    ap.add_argument("--synthetic", action="store_true", help="add the synthetic hidden tasks")
    ap.add_argument("--synthetic-only", action="store_true", help="the synthetic tasks alone")
    ap.add_argument(
        "--kinds",
        default="squat,stair,stair_on_plates,walk",
        help="synthetic task kinds (C3D labs: squat, stair, stair_on_plates; .trc labs: walk, "
        "squat)",
    )
    ap.add_argument("--keep", default="", help="folder to keep the synthetic trials and runs")
    args = ap.parse_args()

    only = set(filter(None, args.only.split(",")))
    print("| config | task | status | IK (mm) | residual (% BW) | contact RMSE (BW) / r | flags |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for stem, alts in ALTERNATIVES.items():
        if (only and stem not in only) or args.synthetic_only:
            continue
        for name, files in alts:
            if not all(p.exists() for p in files.values()):
                print(f"| {stem} | {name} | files missing | | | | |")
                continue
            with tempfile.TemporaryDirectory() as tmp:
                path = swapped_config(stem, name, files, Path(tmp))
                _row(stem, name, path, Path(tmp) / "out")
            sys.stdout.flush()
    if not (args.synthetic or args.synthetic_only):
        return
    from msk.datasets.tasks import lab_task
    from msk.datasets.trc import trc_task
    from msk.pipeline import run_stages

    for stem in SYNTHETIC:
        if only and stem not in only:
            continue
        for kind in filter(None, args.kinds.split(",")):
            if kind not in KINDS_C3D:
                continue
            with tempfile.TemporaryDirectory() as tmp:
                folder = Path(args.keep) / stem if args.keep else Path(tmp)
                folder.mkdir(parents=True, exist_ok=True)
                cfg = REPO / "pipelines" / f"{stem}.toml"
                placed = run_stages(cfg, until="model")["model"]
                base, extra = AS_RECORDED.get(kind, (kind, {}))
                task = lab_task(cfg, base, folder / f"{kind}.c3d", placed=placed, **extra)
                path = swapped_config(stem, f"synthetic_{kind}", {"file": task.path}, folder)
                if _row(stem, f"synthetic_{kind}", path, folder / f"out_{kind}") is not None:
                    _print_truth(stem, kind, compare_to_truth(task, path))
            sys.stdout.flush()
    for stem in SYNTHETIC_TRC:
        if only and stem not in only:
            continue
        for kind in filter(None, args.kinds.split(",")):
            if kind not in KINDS_TRC:
                continue
            with tempfile.TemporaryDirectory() as tmp:
                folder = Path(args.keep) / stem if args.keep else Path(tmp)
                cfg = REPO / "pipelines" / f"{stem}.toml"
                placed = run_stages(cfg, until="model")["model"]
                ttask = trc_task(cfg, kind, folder, placed=placed)
                files = {"file": ttask.trc, "grf": ttask.grf}
                if ttask.external_loads is not None:
                    files["external_loads"] = ttask.external_loads
                path = swapped_config(stem, f"synthetic_{kind}", files, folder)
                if _row(stem, f"synthetic_{kind}", path, folder / f"out_{kind}") is not None:
                    _print_truth(stem, kind, compare_to_truth(ttask, path))
            sys.stdout.flush()


if __name__ == "__main__":
    main()
