"""The known-truth squat to 100° with the patellar tendon (:mod:`msk.datasets.task_contact`),
run through ``pipelines/gc4_JW.toml`` with only the task swapped: the knee contact by
component against the truth. Slow: builds JW's model and runs the session once (module
fixture) for every assert."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
JW = REPO / "pipelines" / "gc4_JW.toml"
_GC4 = REPO.parent / "shared" / "data" / "real" / "knee-grand-challenge-gc4"

pytestmark = [
    pytest.mark.slow,
    pytest.mark.realdata,
    pytest.mark.skipif(not _GC4.is_dir(), reason="Grand Challenge 4 data not present"),
]

COMPONENTS = ("axial", "shear_anterior", "shear_lateral", "patellofemoral")
#: the right leg's muscle groups whose summed force is compared with the truth's
GROUPS = {
    "quadriceps": ("rect_fem_r", "vas_med_r", "vas_int_r", "vas_lat_r"),
    "hamstrings": ("bifemlh_r", "bifemsh_r", "semimem_r", "semiten_r"),
    "gastrocnemii": ("med_gas_r", "lat_gas_r"),
    "soleus": ("soleus_r",),
}


def _task_swap():
    spec = importlib.util.spec_from_file_location("task_swap", REPO / "studies" / "task_swap.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["task_swap"] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def squat100(tmp_path_factory):
    """One run: JW's squat to 100° (4 repetitions, markers, plates, EMG), its true contact with
    the tendon and the session's ``knee_contact.csv`` on the truth's samples; per variant and
    component the RMSE (BW), r and the peaks."""
    from msk.config import load_config
    from msk.datasets.task_contact import true_knee_contact
    from msk.datasets.tasks import lab_task
    from msk.pipeline import run_stages, run_task_trials

    folder = tmp_path_factory.mktemp("squat100")
    ht = _task_swap()
    placed = run_stages(JW, until="model")["model"]
    task = lab_task(JW, "squat", folder / "squat.c3d", placed=placed, seed=1,
                    knee_flexion_deg=100.0)  # fmt: skip
    truth = true_knee_contact(task, load_config(JW).optimization)
    cfg = ht.swapped_config("gc4_JW", "squat", {"file": task.path}, folder)
    (res,) = run_task_trials(cfg, folder / "out")
    tab = np.genfromtxt(res.out_dir / "tables" / "knee_contact.csv", delimiter=",", names=True)
    t, tt = tab["time"], truth.time
    idx = np.clip(np.round((t - t[0]) * (tt.size - 1) / (tt[-1] - tt[0])), 0,
                  tt.size - 1).astype(int)  # fmt: skip
    bw = truth.body_weight_n
    figs: dict[str, dict[str, dict[str, float]]] = {}
    for var in ("generic", "subject_specific"):
        if f"{var}_axial" not in (tab.dtype.names or ()):
            continue
        figs[var] = {}
        for comp in COMPONENTS:
            p, q = tab[f"{var}_{comp}"], getattr(truth, comp)[idx]
            ok = np.isfinite(p) & np.isfinite(q)
            e = (p[ok] - q[ok]) / bw
            figs[var][comp] = {
                "rmse_bw": float(np.sqrt(np.mean(e**2))),
                "r": float(np.corrcoef(p[ok], q[ok])[0, 1]),
                "frames": int(ok.sum()),
                "peak_bw": float(np.max(np.abs(p[ok])) / bw),
                "true_peak_bw": float(np.max(np.abs(q[ok])) / bw),
            }
    mf = np.genfromtxt(res.out_dir / "tables" / "muscle_forces.csv", delimiter=",", names=True)
    groups = {}
    for group, muscles in GROUPS.items():
        p = sum(mf[m] for m in muscles)
        q = sum(truth.forces[idx, truth.muscles.index(m)] for m in muscles)
        ok = np.isfinite(p)
        groups[group] = {
            "rmse_bw": float(np.sqrt(np.mean((p[ok] - q[ok]) ** 2)) / bw),
            "peak_bw": float(p[ok].max() / bw),
            "true_peak_bw": float(q.max() / bw),
        }
    knee = list(task.motion.model.coordinate_names).index("knee_angle_r")
    return {"truth": truth, "figs": figs, "frames": t.size, "groups": groups,
            "true_flexion_deg": float(np.degrees(-task.motion.q[:, knee]).max())}  # fmt: skip


def test_the_truth_is_the_tasks_own_loads(squat100):
    """The truth's inverse dynamics (its kinematics, its plates' reactions) reproduce the
    task's true torques to round-off; the squat reaches 100°; the truth loads the knee as a
    deep squat does with a patella: axial peak 3–5 BW, anterior (tendon-pulled) shear peak
    below the axial, patellofemoral peak 2–4 BW."""
    tr = squat100["truth"]
    bw = tr.body_weight_n
    assert tr.tau_rmse_nm < 1e-6
    assert squat100["true_flexion_deg"] == pytest.approx(100.0, abs=1.0)
    assert np.isfinite(tr.axial).all()
    assert 3.0 < tr.axial.max() / bw < 5.0
    assert tr.shear_anterior.max() < tr.axial.max()
    assert 2.0 < tr.patellofemoral.max() / bw < 4.0


@pytest.mark.parametrize("comp", COMPONENTS)
def test_msk_run_recovers_the_contact_by_component(squat100, comp):
    """The session's generic model (its muscles' generic strength, as the truth's) gives each
    component within 0.1 BW RMSE of the truth on every frame (measured: axial 0.041,
    anterior shear 0.039, lateral shear 0.003, patellofemoral 0.053 BW; r ≥ 0.997), and the
    components' peaks within 0.15 BW."""
    f = squat100["figs"]["generic"][comp]
    assert f["frames"] == squat100["frames"]
    assert f["rmse_bw"] < 0.1, f
    assert f["r"] > 0.99 or (comp == "shear_lateral" and f["r"] > 0.95), f
    assert f["peak_bw"] == pytest.approx(f["true_peak_bw"], abs=0.15), f


@pytest.mark.parametrize("group", list(GROUPS))
def test_msk_run_recovers_the_true_muscle_forces(squat100, group):
    """The session's generic muscle forces (``muscle_forces.csv``) against the truth's, summed
    by group: within 0.1 BW RMSE (measured: quadriceps 0.064, hamstrings 0.039, gastrocnemii
    0.008, soleus 0.009 BW; quadriceps peak 2.89 BW both) — the contact's error is the muscle
    forces', which is the kinematics' and the plates'."""
    g = squat100["groups"][group]
    assert g["rmse_bw"] < 0.1, g
    assert g["peak_bw"] == pytest.approx(g["true_peak_bw"], abs=0.2), g
