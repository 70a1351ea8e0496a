"""OpenSim 4.6 StaticOptimization as a side-by-side reference (run in a child process).

:func:`opensim_static_optimization_reference` runs OpenSim's AnalyzeTool + StaticOptimization
(``use_muscle_physiology``, activation exponent 2, the model's residual actuators file, 6 Hz
coordinates; IPOPT's ``convergence_criterion`` and ``max_iterations``, OpenSim's defaults 1e-4
and 100 unless given) on the gait2392 subject01 walking pipeline
(``shared/tools/opensim-peer/data`` layout) and, at each SO frame and on the very states SO
used (the tool's states storage), returns the moment arms about the requested coordinates,
OpenSim's ``calcInextensibleTendonActiveFiberForce(s, 1.0)`` and OpenSim's activations, so
that msk's :class:`~msk.optimization.StaticOptimizationProblem` can be solved on identical
inputs.
:func:`opensim_full_static_optimization` runs SO on the whole model (every muscle, the pelvis
residuals) and returns the states SO used, so that msk's whole chain (inverse dynamics,
geometry, SO) can run on them; :func:`compare_static_optimization` compares the two solutions.
``opensim`` is never imported in this process (see :mod:`msk._runtime.opensim_peer`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from msk._runtime.opensim_peer import run_opensim_script
from msk.units import Array

__all__ = [
    "COMPARE_WINDOW",
    "FULL_SO_WINDOW",
    "GAIT2392_RIGHT_LEG",
    "IPOPT_DEFAULT",
    "IPOPT_TIGHT",
    "OpenSimSOReference",
    "compare_static_optimization",
    "opensim_full_static_optimization",
    "opensim_static_optimization_reference",
]

#: The right-leg coordinates of gait2392.
GAIT2392_RIGHT_LEG: tuple[str, ...] = (
    "hip_flexion_r",
    "hip_adduction_r",
    "hip_rotation_r",
    "knee_angle_r",
    "ankle_angle_r",
    "subtalar_angle_r",
    "mtp_angle_r",
)

_SCRIPT = r"""
import opensim as osim, os, time, numpy as np
data = ARGS["data"]; out = ARGS["out"]
PIPE = os.path.join(data, "Pipelines", "Gait2392_Simbody")
model_path = os.path.join(PIPE, "OutputReference", "subject01_simbody.osim")
el = osim.ExternalLoads(os.path.join(PIPE, "subject01_walk1_grf.xml"), True)
el.setDataFileName(os.path.join(PIPE, "subject01_walk1_grf.mot"))
el_xml = os.path.join(out, "external_loads.xml"); el.printToXML(el_xml)
at = osim.AnalyzeTool(os.path.join(PIPE, "setup_static_optimization.xml"), False)
at.setName("so"); at.setModelFilename(model_path); at.setReplaceForceSet(False)
files = osim.ArrayStr(); files.append(os.path.join(PIPE, "gait2392_SO_Residual_Actuators.xml"))
at.setForceSetFiles(files); at.setResultsDir(out)
at.setInitialTime(ARGS["t0"]); at.setFinalTime(ARGS["t1"])
at.setExternalLoadsFileName(el_xml); at.setStatesFileName(""); at.setSpeedsFileName("")
at.setCoordinatesFileName(os.path.join(PIPE, "subject01_walk1_ik.mot"))
at.setLowpassCutoffFrequency(6.0)
so = osim.StaticOptimization.safeDownCast(at.getAnalysisSet().get("StaticOptimization"))
so.setStartTime(ARGS["t0"]); so.setEndTime(ARGS["t1"]); so.setStepInterval(1)
so.setUseModelForceSet(True); so.setActivationExponent(2.0); so.setUseMusclePhysiology(True)
setup = os.path.join(out, "setup_so.xml"); at.printToXML(setup)
tool = osim.AnalyzeTool(setup)
# IPOPT's tolerance and iteration cap: printToXML leaves these two properties out and
# AnalyzeTool(setup) has already copied its analyses into the model, so set them on that copy
so_run = osim.StaticOptimization.safeDownCast(
    tool.getModel().updAnalysisSet().get("StaticOptimization"))
so_run.setConvergenceCriterion(ARGS.get("convergence_criterion", 1e-4))
so_run.setMaxIterations(ARGS.get("max_iterations", 100))
RESULT.update(convergence_criterion=so_run.getConvergenceCriterion(),
              max_iterations=so_run.getMaxIterations())
tic = time.perf_counter()
if not tool.run():
    raise RuntimeError("OpenSim static optimization failed")
RESULT["so_wall_s"] = time.perf_counter() - tic
act = osim.Storage(os.path.join(out, "so_StaticOptimization_activation.sto"))
alab = act.getColumnLabels(); alab = [alab.get(i) for i in range(alab.getSize())]
states = tool.getStatesStorage()
slab = states.getColumnLabels(); slab = [slab.get(i) for i in range(slab.getSize())]
stimes = np.array([states.getStateVector(i).getTime() for i in range(states.getSize())])
model = osim.Model(model_path); s = model.initSystem()
cs = model.getCoordinateSet()
coords = [cs.get(n) for n in ARGS["coords"]]
muscles = [model.getMuscles().get(i) for i in range(model.getMuscles().getSize())]
muscles = [m for m in muscles if m.getName().endswith(ARGS["suffix"])]
names = [m.getName() for m in muscles]
T, R, FA, A = [], [], [], []
for k in range(act.getSize()):
    sv = act.getStateVector(k); t = sv.getTime()
    row = int(np.argmin(np.abs(stimes - t)))
    if abs(stimes[row] - t) > 1e-6:
        continue
    y = states.getStateVector(row).getData()
    for j, lab in enumerate(slab[1:]):
        parts = lab.split("/")
        if parts[-1] not in ("value", "speed") or not cs.contains(parts[-2]):
            continue
        c = cs.get(parts[-2])
        if parts[-1] == "value":
            c.setValue(s, y.get(j), False)
        else:
            c.setSpeedValue(s, y.get(j))
    model.realizeVelocity(s)
    a = sv.getData()
    T.append(t)
    A.append([a.get(alab.index(n) - 1) for n in names])
    R.append([[m.computeMomentArm(s, c) for c in coords] for m in muscles])
    FA.append([m.calcInextensibleTendonActiveFiberForce(s, 1.0) for m in muscles])
RESULT.update(time=T, muscles=names, moment_arms=R, f_active=FA, activations=A,
              min_control=[m.getMinControl() for m in muscles],
              max_control=[m.getMaxControl() for m in muscles])
"""


@dataclass(frozen=True)
class OpenSimSOReference:
    """OpenSim SO inputs and outputs per frame (time on axis 0).

    ``moment_arms`` ``(N, n_muscles, n_coords)`` (OpenSim's ``computeMomentArm`` = −∂L/∂q, so
    the msk Jacobian is ``−moment_arms``), ``f_active`` ``(N, n_muscles)``, ``activations``
    ``(N, n_muscles)`` from OpenSim, the muscles' ``min_control``/``max_control``, and the wall
    time of OpenSim's AnalyzeTool run (``so_wall_s``, all its muscles and residuals).
    """

    time: Array
    muscle_names: tuple[str, ...]
    coordinate_names: tuple[str, ...]
    moment_arms: Array
    f_active: Array
    activations: Array
    min_control: Array
    max_control: Array
    so_wall_s: float


def opensim_static_optimization_reference(
    data_dir: Path | str,
    out_dir: Path | str,
    *,
    t0: float,
    t1: float,
    coordinates: Sequence[str] = GAIT2392_RIGHT_LEG,
    muscle_suffix: str = "_r",
    drop_uncoupled: bool = True,
    convergence_criterion: float = 1e-4,
    max_iterations: int = 100,
) -> OpenSimSOReference:
    """Run OpenSim SO on gait2392 subject01 walking over ``[t0, t1]`` s and read it back.

    ``convergence_criterion`` / ``max_iterations`` are StaticOptimization's IPOPT settings
    (OpenSim's defaults; at 1e-4 IPOPT stops up to ~0.3 % above the optimal Σ a², which moves
    small muscles by up to ~5 % of their peak: use 1e-8 to compare solutions).

    Muscles whose name ends with ``muscle_suffix`` are kept; with ``drop_uncoupled`` those with
    no moment arm about ``coordinates`` at any frame (e.g. the ``_r`` trunk muscles) are
    dropped, so that the result is the decoupled subproblem of these coordinates.
    """
    out = run_opensim_script(
        _SCRIPT,
        data=str(data_dir),
        out=str(out_dir),
        t0=float(t0),
        t1=float(t1),
        coords=list(coordinates),
        suffix=muscle_suffix,
        convergence_criterion=float(convergence_criterion),
        max_iterations=int(max_iterations),
    )
    r = np.asarray(out["moment_arms"], dtype=float)
    keep = np.abs(r).max(axis=(0, 2)) > 0 if drop_uncoupled else np.ones(r.shape[1], dtype=bool)
    return OpenSimSOReference(
        time=np.asarray(out["time"], dtype=float),
        muscle_names=tuple(n for n, k in zip(out["muscles"], keep) if k),
        coordinate_names=tuple(coordinates),
        moment_arms=r[:, keep],
        f_active=np.asarray(out["f_active"], dtype=float)[:, keep],
        activations=np.asarray(out["activations"], dtype=float)[:, keep],
        min_control=np.asarray(out["min_control"], dtype=float)[keep],
        max_control=np.asarray(out["max_control"], dtype=float)[keep],
        so_wall_s=float(out["so_wall_s"]),
    )


# ---------------------------------------------------------------------------------------------
# the whole model (every muscle, pelvis residuals) with the states SO used
# ---------------------------------------------------------------------------------------------
#: time window of :func:`opensim_full_static_optimization` (s)
FULL_SO_WINDOW = (0.5, 2.5)
#: default window of :func:`compare_static_optimization`: the edges of the filtered window
#: are left out (OpenSim at its default tolerance; a converged comparison uses every frame)
COMPARE_WINDOW = (0.6, 2.4)
#: OpenSim's StaticOptimization IPOPT defaults, and the settings at which it reaches the optimum
IPOPT_DEFAULT = {"convergence_criterion": 1e-4, "max_iterations": 100}
IPOPT_TIGHT = {"convergence_criterion": 1e-8, "max_iterations": 1000}


def _peer_data_dir() -> Path:
    from msk.datasets.shared import shared_dir

    return shared_dir() / "tools" / "opensim-peer" / "data"


#: prepended to the reference script: CPU time of AnalyzeTool.run (the wall time is its own)
_CPU = r"""
import opensim as _osim, time as _time
_run = _osim.AnalyzeTool.run
def _timed_run(self, *a):
    c = _time.process_time()
    ok = _run(self, *a)
    RESULT["so_cpu_s"] = _time.process_time() - c
    return ok
_osim.AnalyzeTool.run = _timed_run
"""

#: appended to the reference script: the states SO used, q, q̇ and q̈ = d(q̇)/dt of the GCV
#: splines (StaticOptimization's target accelerations), at the SO frames ``T``
_STATES = r"""
ss = osim.GCVSplineSet(5, states)
Qs, Us, As = [], [], []
d1 = osim.StdVectorInt(); d1.append(0)
for c in ARGS["all_coords"]:
    vl = next(l for l in slab if l.endswith("/" + c + "/value"))
    sl = next(l for l in slab if l.endswith("/" + c + "/speed"))
    Qs.append([ss.get(vl).calcValue(osim.Vector(1, t)) for t in T])
    Us.append([ss.get(sl).calcValue(osim.Vector(1, t)) for t in T])
    As.append([ss.get(sl).calcDerivative(d1, osim.Vector(1, t)) for t in T])
RESULT.update(q=Qs, u=Us, udot=As)
"""


def opensim_full_static_optimization(
    out_dir: Path | str,
    coordinate_names: Sequence[str],
    *,
    data_dir: Path | str | None = None,
    convergence_criterion: float = 1e-4,
    max_iterations: int = 100,
) -> dict[str, Any]:
    """OpenSim 4.6 SO on all 92 muscles (+ pelvis residuals) of gait2392 subject01 walking over
    :data:`FULL_SO_WINDOW`, timed in the child (wall time of AnalyzeTool.run, and its CPU
    time), with the states it used: ``q``, ``u`` (q̇) and ``udot`` (q̈ = d(q̇)/dt of the GCV
    splines, StaticOptimization's target accelerations) at the SO frames; IPOPT settings as
    given (OpenSim's defaults: :data:`IPOPT_DEFAULT`). ``data_dir`` is the OpenSim peer's data
    folder (default ``shared/tools/opensim-peer/data``)."""
    t0, t1 = FULL_SO_WINDOW
    data = Path(data_dir) if data_dir is not None else _peer_data_dir()
    out = run_opensim_script(
        _CPU + _SCRIPT + _STATES, data=str(data), out=str(out_dir), t0=t0, t1=t1,
        coords=["knee_angle_r"], suffix="", all_coords=list(coordinate_names),
        convergence_criterion=float(convergence_criterion), max_iterations=int(max_iterations),
    )  # fmt: skip
    act = np.asarray(out["activations"], dtype=float)
    fa = np.asarray(out["f_active"], dtype=float)
    t = np.asarray(out["time"], dtype=float)
    return {
        "time": t,
        "q": np.asarray(out["q"], dtype=float).T,
        "u": np.asarray(out["u"], dtype=float).T,
        "udot": np.asarray(out["udot"], dtype=float).T,
        "forces": act * fa,  # OpenSim's SO has no passive fibre force
        "activations": act,
        "f_active": fa,
        "muscle_names": tuple(out["muscles"]),
        "convergence_criterion": float(out["convergence_criterion"]),
        "max_iterations": int(out["max_iterations"]),
        "so_wall_s": float(out["so_wall_s"]),
        "per_frame_s": float(out["so_wall_s"]) / max(t.size, 1),
        "per_frame_cpu_s": float(out.get("so_cpu_s", np.nan)) / max(t.size, 1),
    }


def compare_static_optimization(
    ms: dict[str, Any], os_: dict[str, Any], *, window: tuple[float, float] = COMPARE_WINDOW
) -> dict[str, Any]:
    """msk (``ms``: ``muscle_names``, ``activations``, ``forces``, ``f_active`` on the frames
    of ``os_``) against :func:`opensim_full_static_optimization` (``os_``).

    Per muscle: RMS of (msk − OpenSim) force relative to the muscle's OpenSim peak, over the
    frames of ``window`` where OpenSim's Σ a² is not > 1 % above msk's (none with the settings
    above; with a plate threshold or OpenSim's default tolerance some are), for the muscles
    OpenSim does not saturate (max activation < 0.99)."""
    names = list(os_["muscle_names"])
    idx = [ms["muscle_names"].index(n) for n in names]
    t = os_["time"]
    inner = (t >= window[0]) & (t <= window[1])
    a_ms = ms["activations"][:, idx]
    cost_ms = np.sum(a_ms**2, axis=1)
    cost_os = np.sum(os_["activations"] ** 2, axis=1)
    converged = (cost_os - cost_ms) <= 0.01 * cost_os
    use = inner & converged
    f_ms = ms["forces"][:, idx][use]
    f_os = os_["forces"][use]
    saturated = os_["activations"][inner].max(axis=0) >= 0.99
    peak = np.maximum(np.abs(f_os).max(axis=0), 1e-9)
    rel = np.sqrt(np.mean((f_ms - f_os) ** 2, axis=0)) / peak
    keep = ~saturated
    fa_rel = np.abs(ms["f_active"][:, idx] - os_["f_active"])[inner].max(axis=0) / np.maximum(
        os_["f_active"][inner].max(axis=0), 1e-9
    )
    return {
        "names": names,
        "relative_rms": rel,
        "peak": peak,
        "saturated": [n for n, s in zip(names, saturated) if s],
        "keep": keep,
        "worst": names[int(np.argmax(np.where(keep, rel, -1)))],
        "n_frames": int(use.sum()),
        "not_converged_times": t[inner & ~converged],
        "f_active_rel_max": float(fa_rel.max()),
        "activation_rms": float(np.sqrt(np.mean((a_ms - os_["activations"])[use] ** 2))),
        "cost_msk": cost_ms,
        "cost_opensim": cost_os,
    }
