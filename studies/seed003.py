"""seeds/003 Tables 4.1 and 4.5–4.7 reproduced on the recording we have: the EMG-driven model
against OpenSim 4.6 with generically scaled and with EMG-calibrated ("optimized") muscle
parameters, our figures beside the thesis' published ones.

The thesis (seeds/003, Ch. 3–4) calibrates an EMG-driven knee/ankle model (Eq. 1–20; Lloyd &
Besier 2003, Buchanan et al. 2004) on treadmill walking of three subjects with MVC-normalised EMG
of nine muscles, copies the calibrated maximum isometric force, optimal fibre length and tendon
slack length of twelve muscles into an OpenSim model and compares, over stance, activations and
forces of three models — OpenSim "scaled", OpenSim "optimized", EMG-driven — by ratios of
trapezoidal areas (Table 4.5 activations, Table 4.6 forces) and net knee/ankle forces by r², RMS,
peak-to-peak-normalised RMS and difference in peak (Table 4.7, ``seeds/003 §3.4``). Table 4.1 is
the calibration fit of the joint moments.

Here (:func:`seed003_comparison`):

* **data**: the only stored walk with EMG of those muscles and an OpenSim model: the Rajagopal
  walk (``opensim-rajagopal-walk``: IK coordinates, ID moments, GRF, processed EMG normalised to
  its own peak — **no MVC**) on ``subject_walk_scaled.osim``; one subject, not three;
* **EMG-driven model**: :class:`msk.strength.EMGDrivenCalibration` on the twelve muscles of
  ``seeds/003 §3.2.1`` (VI = mean of VM and VL EMG, BFSH from BFLH, SM and ST from the medial
  hamstrings electrode), four strength groups, bounds of Table 3.1, knee and ankle moments,
  calibrated on 0.45–1.30 s (the first 0.1 s padding), elastic tendon by default;
* **OpenSim 4.6** (child process, :mod:`msk._runtime.opensim_peer`): AnalyzeTool +
StaticOptimization
  (Σ a², muscle physiology, 6 Hz coordinates, 100 Hz) on the model as published ("scaled") and
  with the twelve muscles' F_iso, l_opt, l_ts replaced by the calibrated ones ("optimized"),
  pelvis residuals and reserve actuators added. The thesis runs RRA + CMC; CMC's muscle
  distribution is the same instantaneous Σ a² static optimisation (``seeds/003 §2.3``, Eq. 30)
  inside a tracking loop, which needs an RRA-adjusted model we do not have — so static
  optimisation is the peer, and that difference is stated wherever the tables are printed;
* **windows**: the right-leg stance the recording contains: 0.55–1.02 s (inside the calibration
  window; mid to late stance, the coordinates start at 0.45 s) and 1.42–1.80 s (held out; early
  to mid stance, the recording ends at 1.80 s). The thesis compares whole stance phases.

The gastrocnemii get one electrode; the thesis averages its knee- and ankle-model MG/LG outputs
(Table 4.4); here one model spans both joints, so there is nothing to average.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from msk.exceptions import MskError
from msk.strength.calibration import CalibrationTrial, EMGDrivenCalibration
from msk.strength.studies import MetricTable, area_ratio_table, moment_fit_table, net_force_table

Array = NDArray[np.float64]

__all__ = [
    "EMG_MAP",
    "GROUPS",
    "PAPER",
    "THESIS_NAMES",
    "Seed003Comparison",
    "rajagopal_calibration_data",
    "rajagopal_walk",
    "seed003_comparison",
]

RATE_HZ = 100.0
COORDS = ("knee_angle_r", "ankle_angle_r")
#: Rajagopal muscle → EMG column(s) of ``electromyography.sto`` (``seeds/003 §3.2.1``)
EMG_MAP: dict[str, tuple[str, ...]] = {
    "recfem_r": ("rectus_femoris",),
    "vasmed_r": ("vastus_medius",),
    "vasint_r": ("vastus_lateralis", "vastus_medius"),
    "vaslat_r": ("vastus_lateralis",),
    "bflh_r": ("biceps_femoris",),
    "bfsh_r": ("biceps_femoris",),
    "semimem_r": ("medial_hamstrings",),
    "semiten_r": ("medial_hamstrings",),
    "gasmed_r": ("gastrocnemius",),
    "gaslat_r": ("gastrocnemius",),
    "soleus_r": ("soleus",),
    "tibant_r": ("tibialis_anterior",),
}
#: the thesis' abbreviations, in the order of its tables
THESIS_NAMES = ("RF", "VM", "VI", "VL", "BFLH", "BFSH", "SM", "ST", "MG", "LG", "Sol", "TA")
#: strength groups (``seeds/003 Table 4.3``: G_e, G_f, G_pf, G_df)
GROUPS: dict[str, tuple[str, ...]] = {
    "knee_extensors": ("recfem_r", "vaslat_r", "vasmed_r", "vasint_r"),
    "knee_flexors": ("bflh_r", "bfsh_r", "semimem_r", "semiten_r"),
    "plantar_flexors": ("gasmed_r", "gaslat_r", "soleus_r"),
    "dorsiflexors": ("tibant_r",),
}
#: net forces (``seeds/003 §3.4``): knee = extensors − flexors, ankle = plantar − dorsiflexors
NET = {
    "knee": (
        ("recfem_r", "vasmed_r", "vasint_r", "vaslat_r"),
        ("bflh_r", "bfsh_r", "semimem_r", "semiten_r", "gasmed_r", "gaslat_r"),
    ),
    "ankle": (("gasmed_r", "gaslat_r", "soleus_r"), ("tibant_r",)),
}
CALIBRATION_WINDOW = (0.45, 1.30)
HELD_OUT_WINDOW = (1.30, 1.80)
#: right-leg stance inside each window (grf_walk.mot: right foot on the ground 0.267–1.024 s
#: and 1.4115–2.168 s; the coordinates span 0.45–1.80 s)
STANCES = {"calibration stance": (0.55, 1.02), "held-out stance": (1.42, 1.80)}
PAIRS = (("scaled", "optimized"), ("emg", "scaled"), ("emg", "optimized"))

#: The thesis' published values (seeds/003): Table 4.1 averages (r², RMS N·m, nRMS); Tables
#: 4.5/4.6 per muscle (scaled/optimized, EMG/scaled, EMG/optimized); Table 4.7 per joint,
#: comparison and subject (r², RMS N, nRMS, difference in peak N).
PAPER: dict[str, Any] = {
    "4.1": {"knee_angle_r": (0.924, 7.76, 0.069), "ankle_angle_r": (0.954, 11.01, 0.068)},
    "4.5": {
        "RF": (1.045, 0.521, 0.533), "VM": (1.735, 0.539, 0.917), "VI": (1.838, 0.625, 1.150),
        "VL": (1.850, 0.628, 1.217), "BFLH": (3.244, 0.308, 0.907), "BFSH": (0.969, 0.174, 0.157),
        "SM": (2.899, 0.201, 0.491), "ST": (3.293, 0.334, 0.750), "MG": (1.361, 0.513, 0.700),
        "LG": (2.070, 0.478, 1.014), "Sol": (1.690, 0.956, 1.526), "TA": (1.399, 0.679, 0.946),
    },
    "4.6": {
        "RF": (0.892, 0.914, 0.733), "VM": (0.644, 1.148, 0.731), "VI": (0.655, 1.264, 0.831),
        "VL": (0.711, 1.272, 0.920), "BFLH": (0.959, 0.694, 0.628), "BFSH": (0.637, 0.274, 0.160),
        "SM": (0.665, 1.487, 0.696), "ST": (0.910, 0.540, 0.410), "MG": (0.765, 1.013, 0.775),
        "LG": (0.849, 1.009, 0.859), "Sol": (1.145, 1.191, 1.362), "TA": (0.678, 1.099, 0.747),
    },
    "4.7": {
        "ankle": {
            "scaled/optimized": [(0.999, 38, 0.009, 24), (0.999, 48, 0.012, 24),
                                 (0.998, 57, 0.014, 12)],
            "emg/scaled": [(0.925, 477, 0.104, 214), (0.956, 305, 0.071, 592),
                           (0.917, 529, 0.119, 414)],
            "emg/optimized": [(0.929, 469, 0.101, 190), (0.959, 299, 0.070, 568),
                              (0.914, 536, 0.120, 426)],
        },
        "knee": {
            "scaled/optimized": [(0.936, 402, 0.101, 527), (0.989, 167, 0.054, 129),
                                 (0.848, 481, 0.152, 495)],
            "emg/scaled": [(0.913, 491, 0.135, 1072), (0.751, 487, 0.151, 534),
                           (0.740, 437, 0.146, 156)],
            "emg/optimized": [(0.919, 778, 0.187, 1600), (0.737, 589, 0.173, 663),
                              (0.907, 391, 0.116, 651)],
        },
    },
}  # fmt: skip


def rajagopal_walk(real_dir: Path | str, ref_dir: Path | str) -> tuple[Any, Any, Any, Array, Any]:
    """The Rajagopal walk on ``subject_walk_scaled.osim`` at :data:`RATE_HZ` over 0.45–1.80 s:
    the model, the ID and EMG tables, the time grid and msk's muscle geometry along the
    recorded coordinates (coordinates the file does not hold at 0)."""
    from msk.io.opensim_files import read_sto
    from msk.model.osim import load_osim
    from msk.muscles.geometry import muscle_geometry

    d = Path(real_dir) / "opensim-rajagopal-walk"
    model = load_osim(Path(ref_dir) / "opensim-core" / "subject_walk_scaled.osim")
    coords = read_sto(d / "coordinates.sto")
    ids = read_sto(d / "id_walk.sto")
    emg = read_sto(d / "electromyography.sto")
    t = np.arange(0.45, 1.80 + 1e-9, 1.0 / RATE_HZ)
    by_name = {c.split("/")[-2]: i for i, c in enumerate(coords.columns) if c.endswith("/value")}
    q = np.column_stack(
        [
            np.interp(t, coords.time, coords.data[:, by_name[n]]) if n in by_name else 0 * t
            for n in model.coordinate_names
        ]
    )
    return model, ids, emg, t, muscle_geometry(model, q, np.gradient(q, 1.0 / RATE_HZ, axis=0))


def rajagopal_calibration_data(real_dir: Path | str, ref_dir: Path | str) -> tuple[Any, dict]:
    """The twelve muscles' parameters (``subject_walk_scaled.osim``) and the Rajagopal walk at
    100 Hz over 0.45–1.80 s (:func:`rajagopal_walk`): time ``t``, EMG envelopes ``e`` (mean of
    each 2 kHz column on the time grid, clipped to [0, 1]), musculotendon lengths ``lmt``,
    velocities ``vmt``, moment arms ``r`` (knee, ankle) from msk's geometry along the recorded
    coordinates and the ID moments ``m``."""
    from msk.muscles.geometry import muscle_parameters

    model, ids, emg, t, geo = rajagopal_walk(real_dir, ref_dir)
    names = tuple(EMG_MAP)
    idx = [geo.muscle_index(m) for m in names]
    cidx = [geo.coordinate_index(c) for c in COORDS]
    env = np.column_stack(
        [
            np.mean([np.interp(t, emg.time, emg.data[:, emg.columns.index(c)]) for c in cols], 0)
            for cols in EMG_MAP.values()
        ]
    )
    moments = np.column_stack(
        [np.interp(t, ids.time, ids.data[:, ids.columns.index(f"{c}_moment")]) for c in COORDS]
    )
    full = {
        "t": t,
        "e": np.clip(env, 0.0, 1.0),
        "lmt": geo.lengths[:, idx],
        "vmt": np.asarray(geo.velocities)[:, idx],
        "r": geo.moment_arms[:, idx][:, :, cidx],
        "m": moments,
    }
    return muscle_parameters(model).subset(names), full


def _trial(full: Mapping[str, Array], t0: float, t1: float, name: str) -> CalibrationTrial:
    sel = (full["t"] >= t0 - 1e-9) & (full["t"] <= t1 + 1e-9)
    return CalibrationTrial(
        full["e"][sel], full["lmt"][sel], full["vmt"][sel], full["r"][sel], full["m"][sel],
        RATE_HZ, COORDS, name,
    )  # fmt: skip


_OPENSIM_SO = r"""
import opensim as osim, os
out = ARGS["out"]
m = osim.Model(ARGS["model"])
ms = m.getMuscles()
for name, (f, lo, ls) in ARGS["params"].items():
    mu = ms.get(name)
    mu.setMaxIsometricForce(f); mu.setOptimalFiberLength(lo); mu.setTendonSlackLength(ls)
cs = m.getCoordinateSet()
have = set()
for i in range(m.getForceSet().getSize()):
    ca = osim.CoordinateActuator.safeDownCast(m.getForceSet().get(i))
    if ca is not None:
        have.add(ca.get_coordinate())
for i in range(cs.getSize()):
    c = cs.get(i)
    if c.getName() in have or c.get_locked(0):
        continue
    pelvis = c.getName().startswith("pelvis_")
    ca = osim.CoordinateActuator(c.getName())
    ca.setName(("residual_" if pelvis else "reserve_") + c.getName())
    ca.setOptimalForce(ARGS["residual_force"] if pelvis else ARGS["reserve_force"])
    ca.setMinControl(-1e4); ca.setMaxControl(1e4)
    m.addForce(ca)
m.finalizeConnections()
model_path = os.path.join(out, "model.osim"); m.printToXML(model_path)
el = osim.ExternalLoads(ARGS["grf_xml"], True)
el.setDataFileName(ARGS["grf_mot"])
el_xml = os.path.join(out, "external_loads.xml"); el.printToXML(el_xml)
at = osim.AnalyzeTool()
at.setName("so"); at.setModelFilename(model_path); at.setReplaceForceSet(False)
at.setResultsDir(out); at.setInitialTime(ARGS["t0"]); at.setFinalTime(ARGS["t1"])
at.setExternalLoadsFileName(el_xml); at.setCoordinatesFileName(ARGS["coordinates"])
at.setLowpassCutoffFrequency(6.0)
so = osim.StaticOptimization()
so.setName("StaticOptimization"); so.setStartTime(ARGS["t0"]); so.setEndTime(ARGS["t1"])
so.setStepInterval(ARGS["step"]); so.setUseModelForceSet(True)
so.setActivationExponent(2.0); so.setUseMusclePhysiology(True)
at.getAnalysisSet().cloneAndAppend(so)
setup = os.path.join(out, "setup_so.xml"); at.printToXML(setup)
tool = osim.AnalyzeTool(setup)
if not tool.run():
    raise RuntimeError("OpenSim static optimization failed")
for kind in ("activation", "force"):
    st = osim.Storage(os.path.join(out, "so_StaticOptimization_%s.sto" % kind))
    lab = st.getColumnLabels(); lab = [lab.get(i) for i in range(lab.getSize())]
    T, V = [], []
    for k in range(st.getSize()):
        sv = st.getStateVector(k); d = sv.getData()
        T.append(sv.getTime())
        V.append([d.get(lab.index(n) - 1) for n in ARGS["muscles"]])
    RESULT[kind] = V
    RESULT["time"] = T
"""


def _write_coordinates_mot(coordinates_sto: Path, path: Path) -> None:
    """OpenSim's AnalyzeTool reads coordinates by name: the ``/jointset/.../value`` columns of
    the Moco example's states file as a plain ``.mot`` (radians, ``inDegrees=no``)."""
    from msk.io.opensim_files import read_sto

    c = read_sto(coordinates_sto, angle_columns=())
    keep = [i for i, n in enumerate(c.columns) if n.endswith("/value")]
    names = [c.columns[i].split("/")[-2] for i in keep]
    rows = np.column_stack([c.time, c.data[:, keep]])
    head = (
        f"coordinates\nversion=1\nnRows={rows.shape[0]}\nnColumns={rows.shape[1]}\n"
        "inDegrees=no\nendheader\n" + "\t".join(["time", *names]) + "\n"
    )
    body = "\n".join("\t".join(f"{v:.10g}" for v in r) for r in rows)
    path.write_text(head + body + "\n")


def opensim_static_optimization(
    real_dir: Path | str,
    ref_dir: Path | str,
    parameters: Mapping[str, tuple[float, float, float]] | None,
    *,
    t0: float,
    t1: float,
    muscles: Sequence[str] = tuple(EMG_MAP),
) -> tuple[Array, Array, Array]:
    """OpenSim 4.6 static optimisation of the Rajagopal walk over [t0, t1] at 100 Hz (module
    docstring), with ``parameters`` = {muscle: (F_iso N, l_opt m, l_ts m)} replacing the
    model's (None: the model as published). Returns time, activations and forces ``(N, M)``."""
    import tempfile

    from msk._runtime.opensim_peer import run_opensim_script

    d = Path(real_dir) / "opensim-rajagopal-walk"
    with tempfile.TemporaryDirectory(prefix="msk-seed003-") as tmp:
        mot = Path(tmp) / "coordinates.mot"
        _write_coordinates_mot(d / "coordinates.sto", mot)
        res = run_opensim_script(
            _OPENSIM_SO,
            out=tmp,
            model=str(Path(ref_dir) / "opensim-core" / "subject_walk_scaled.osim"),
            params={k: list(map(float, v)) for k, v in (parameters or {}).items()},
            coordinates=str(mot),
            grf_xml=str(d / "grf_walk.xml"),
            grf_mot=str(d / "grf_walk.mot"),
            t0=t0,
            t1=t1,
            step=10,  # coordinates at 1 kHz → 100 Hz
            residual_force=10.0,
            reserve_force=1.0,
            muscles=list(muscles),
        )
    return (np.asarray(res["time"]), np.asarray(res["activation"]), np.asarray(res["force"]))


@dataclass(frozen=True)
class Seed003Comparison:
    """Our tables (``msk.strength.studies.MetricTable``, one per stance for 4.5–4.7) and what
    produced them: ``calibration`` (Table 4.1 on the calibration window), ``held_out_fit``
    (Table 4.1's columns on the held-out window), ``activations`` / ``forces`` (Tables 4.5,
    4.6) and ``net`` (Table 4.7, per stance and joint), the strength factors, and the
    settings (tendon, peer)."""

    calibration: MetricTable
    held_out_fit: MetricTable
    activations: dict[str, MetricTable]
    forces: dict[str, MetricTable]
    net: dict[str, dict[str, MetricTable]]
    strength_factors: dict[str, float]
    tendon: str

    def to_markdown(self) -> str:
        """The tables with the thesis' numbers beside ours (``docs/seed003.md``)."""
        return _markdown(self)


def seed003_comparison(
    real_dir: Path | str,
    ref_dir: Path | str,
    *,
    tendon: str = "elastic",
    n_starts: int = 3,
    random_state: int = 0,
) -> Seed003Comparison:
    """Calibrate the EMG-driven model, run OpenSim 4.6 scaled and optimized, and build
    ``seeds/003`` Tables 4.1 and 4.5–4.7 for each stance (module docstring). Raises
    :class:`MskError` when OpenSim is not installed."""
    from msk._runtime.opensim_peer import opensim_available

    if not opensim_available():
        raise MskError("seeds/003 tables need OpenSim 4.6 as the peer: pip install 'msk[opensim]'")
    params, full = rajagopal_calibration_data(real_dir, ref_dir)
    calib = _trial(full, *CALIBRATION_WINDOW, "calibration")
    held = _trial(full, *HELD_OUT_WINDOW, "held out")
    cal = EMGDrivenCalibration(
        params, GROUPS, tendon=tendon, n_starts=n_starts, max_iter=150, regularization=1e-2,
        random_state=random_state,
    ).fit([calib])  # fmt: skip
    skip = round(cal.skip_s * RATE_HZ)
    fit1 = moment_fit_table(
        calib.moments[skip:], cal.predict(calib)[skip:], COORDS,
        title="joint-moment fit, calibration window (seeds/003 Table 4.1)",
    )  # fmt: skip
    fit2 = moment_fit_table(
        held.moments[skip:], cal.predict(held)[skip:], COORDS,
        title="joint-moment fit, held-out window",
    )  # fmt: skip
    opt = cal.parameters_.muscle_parameters(params, GROUPS)
    opt_map = {
        n: (opt.max_isometric_force[i], opt.optimal_fiber_length[i], opt.tendon_slack_length[i])
        for i, n in enumerate(opt.names)
    }
    names = list(EMG_MAP)
    acts: dict[str, MetricTable] = {}
    forces: dict[str, MetricTable] = {}
    net: dict[str, dict[str, MetricTable]] = {}
    for (label, (s0, s1)), trial, (w0, _) in zip(
        STANCES.items(), (calib, held), (CALIBRATION_WINDOW, HELD_OUT_WINDOW)
    ):
        a_emg, f_emg = cal.predict_forces(trial)
        t_emg = w0 + np.arange(trial.n_frames) / RATE_HZ
        sel = (t_emg >= s0 - 1e-9) & (t_emg <= s1 + 1e-9)
        t = t_emg[sel]
        series_a: dict[str, Array] = {"emg": a_emg[sel]}
        series_f: dict[str, Array] = {"emg": f_emg[sel]}
        for key, p in (("scaled", None), ("optimized", opt_map)):
            ts, a, f = opensim_static_optimization(real_dir, ref_dir, p, t0=s0, t1=s1)
            series_a[key] = np.column_stack([np.interp(t, ts, a[:, j]) for j in range(len(names))])
            series_f[key] = np.column_stack([np.interp(t, ts, f[:, j]) for j in range(len(names))])
        acts[label] = area_ratio_table(
            series_a, PAIRS, THESIS_NAMES, time=t, title=f"activation area ratios, {label}"
        )
        forces[label] = area_ratio_table(
            series_f, PAIRS, THESIS_NAMES, time=t, title=f"force area ratios, {label}"
        )
        net[label] = {}
        for joint, (pos, neg) in NET.items():
            nets = {k: _net(v, names, pos, neg) for k, v in series_f.items()}
            net[label][joint] = net_force_table(nets, PAIRS, title=f"net {joint} force, {label}")
    factors = dict(zip(cal.group_names, map(float, cal.parameters_.strength_factors)))
    return Seed003Comparison(fit1, fit2, acts, forces, net, factors, tendon)


def _net(forces: Array, names: Sequence[str], pos: Sequence[str], neg: Sequence[str]) -> Array:
    from msk.strength.studies import net_joint_force

    return net_joint_force(forces, names, pos, neg)


def _ratio(v: float) -> str:
    """A ratio cell; above 100 the denominator's area is ≈ 0 (the muscle is silent there)."""
    return "> 100" if v > 100.0 else f"{v:.3f}"


def _markdown(c: Seed003Comparison) -> str:
    p = PAPER
    out = [
        f"EMG-driven model: {c.tendon} tendon, strength factors "
        + ", ".join(f"{k} {v:.2f}" for k, v in c.strength_factors.items())
        + ". OpenSim 4.6 peer: static optimisation (the thesis: RRA + CMC).",
        "",
        "**Table 4.1** (joint-moment fit; thesis: average of 3 subjects, calibration trials)",
        "",
        "| coordinate | r² ours (calib. / held out) | r² thesis | RMS N·m ours | RMS thesis "
        "| nRMS ours | nRMS thesis |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for co in COORDS:
        r2a, r2b = c.calibration.get(co, "r2"), c.held_out_fit.get(co, "r2")
        pr = p["4.1"][co]
        out.append(
            f"| {co} | {r2a:.3f} / {r2b:.3f} | {pr[0]:.3f} | "
            f"{c.calibration.get(co, 'rms_Nm'):.2f} / {c.held_out_fit.get(co, 'rms_Nm'):.2f} | "
            f"{pr[1]:.2f} | {c.calibration.get(co, 'nrms'):.3f} / "
            f"{c.held_out_fit.get(co, 'nrms'):.3f} | {pr[2]:.3f} |"
        )
    stances = list(c.activations)
    for num, tabs in (("4.5", c.activations), ("4.6", c.forces)):
        what = "activation" if num == "4.5" else "force"
        cols = " | ".join(
            f"{a}/{b} {s.split()[0]}"
            for a, b in (("S", "O"), ("E", "S"), ("E", "O"))
            for s in stances
        )
        out += [
            "",
            f"**Table {num}** ({what} area ratios over stance, trapezoidal rule; S = OpenSim "
            "scaled, O = OpenSim optimized, E = EMG-driven; ours per stance, thesis: mean of 3 "
            "subjects)",
            "",
            f"| muscle | {cols} | thesis S/O | thesis E/S | thesis E/O |",
            "| --- |" + " --- |" * (3 * len(stances) + 3),
        ]
        for m in THESIS_NAMES:
            ours = [tabs[s].get(m, f"{a}/{b}") for a, b in PAIRS for s in stances]
            out.append(
                f"| {m} | "
                + " | ".join(_ratio(v) for v in ours)
                + " | "
                + " | ".join(f"{v:.3f}" for v in p[num][m])
                + " |"
            )
    out += [
        "",
        "**Table 4.7** (net joint force: knee = extensors − flexors, ankle = plantar − "
        "dorsiflexors; r², RMS N, nRMS, difference in peak N; thesis: subjects 1–3)",
        "",
        "| joint | comparison | stance | r² | RMS N | nRMS | Δ peak N | thesis r² (S1, S2, S3) "
        "| thesis RMS N | thesis Δ peak N |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for joint in NET:
        for a, b in PAIRS:
            row = f"{a}/{b}"
            th = p["4.7"][joint][row]
            for s in stances:
                t = c.net[s][joint]
                out.append(
                    f"| {joint} | {row} | {s} | {t.get(row, 'r2'):.3f} | "
                    f"{t.get(row, 'rms_N'):.0f} | {t.get(row, 'nrms'):.3f} | "
                    f"{t.get(row, 'peak_diff_N'):.0f} | "
                    + ", ".join(f"{x[0]:.3f}" for x in th)
                    + " | "
                    + ", ".join(f"{x[1]:.0f}" for x in th)
                    + " | "
                    + ", ".join(f"{x[3]:.0f}" for x in th)
                    + " |"
                )
    return "\n".join(out) + "\n"
