"""Synthetic ground-truth trials: a two-legged model moved along a known smooth motion.

``make_trial`` returns the exact coordinates (θ, θ̇, θ̈ in closed form), the marker trajectories
(optionally with Gaussian noise), the ground reaction wrench that the motion needs — the
root-chain (base-link) rows of RNEA: the spatial force the ground would have to transmit to the
pelvis — split over two force plates (one under each foot, each with its own centre of pressure
and a free moment about the vertical), and the true joint torques. ``SyntheticTrial.write_c3d``
writes markers and plates as a C3D file with ezc3d (plates of type 2, channels in the plate
frame, mm), which :func:`msk.io.read_c3d` reads back.

Usage::

    from synthetic import make_trial, two_leg_model
    trial = make_trial(two_leg_model(), duration_s=2.0, rate_hz=100.0, noise_m=0.002)
    trial.write_c3d(tmp_path / "synthetic.c3d")
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
from model_factory import free_pelvis, inertia
from numpy.typing import NDArray

from msk.joints import Linear, Polynomial
from msk.loads import PlateWrench
from msk.model import Axis, Body, Coordinate, Joint, Marker, Model, marker_positions

Array = NDArray[np.float64]
UP = np.array([0.0, 1.0, 0.0])


def two_leg_model() -> Model:
    """Pelvis (6 DOF) with two legs (3-DOF hip, knee with coupled translations, 1-DOF ankle),
    y up, 16 coordinates, 30 markers; segment values close to ``model_factory.leg_model``."""
    lin = Linear()
    coords, pelvis_joint = free_pelvis(0.93)
    bodies = [Body("pelvis", 11.0, [-0.07, 0.0, 0.0], inertia(11.0, 0.25))]
    joints = [pelvis_joint]
    markers = [
        Marker("RASI", "pelvis", [0.02, 0.0, 0.12]),
        Marker("LASI", "pelvis", [0.02, 0.0, -0.12]),
        Marker("RPSI", "pelvis", [-0.15, 0.03, 0.05]),
        Marker("LPSI", "pelvis", [-0.15, 0.03, -0.05]),
    ]
    for side, s in (("r", 1.0), ("l", -1.0)):
        up = side.upper()
        coords += [
            Coordinate(f"hip_flexion_{side}", range=(-1.2, 2.0)),
            Coordinate(f"hip_adduction_{side}", range=(-0.9, 0.5)),
            Coordinate(f"hip_rotation_{side}", range=(-0.7, 0.7)),
            Coordinate(f"knee_angle_{side}", range=(-2.1, 0.17)),
            Coordinate(f"ankle_angle_{side}", range=(-0.7, 0.5)),
        ]
        bodies += [
            Body(f"femur_{side}", 8.8, [0.0, -0.17, 0.0], inertia(8.8, 0.40)),
            Body(f"tibia_{side}", 3.5, [0.0, -0.18, 0.0], inertia(3.5, 0.40)),
            Body(f"foot_{side}", 1.2, [0.06, -0.03, 0.0], inertia(1.2, 0.2)),
        ]
        joints += [
            Joint(
                f"hip_{side}",
                "pelvis",
                f"femur_{side}",
                parent_offset=pin.SE3(np.eye(3), np.array([-0.07, -0.066, s * 0.083])),
                axes=(
                    Axis("revolute", [0, 0, 1], f"hip_flexion_{side}", lin),
                    Axis("revolute", [s * 0.9, s * 0.1, 0.0], f"hip_adduction_{side}", lin),
                    Axis("revolute", [0, s, 0], f"hip_rotation_{side}", lin),
                ),
            ),
            Joint(
                f"knee_{side}",
                f"femur_{side}",
                f"tibia_{side}",
                axes=(
                    Axis(
                        "prismatic",
                        [1, 0, 0],
                        f"knee_angle_{side}",
                        Polynomial((0.002, -0.004, 0.0)),
                    ),
                    Axis(
                        "prismatic",
                        [0, 1, 0],
                        f"knee_angle_{side}",
                        Polynomial((-0.001, 0.003, -0.40)),
                    ),
                    Axis("revolute", [0, 0, 1], f"knee_angle_{side}", lin),
                ),
            ),
            Joint(
                f"ankle_{side}",
                f"tibia_{side}",
                f"foot_{side}",
                parent_offset=pin.SE3(np.eye(3), np.array([0.0, -0.43, 0.0])),
                axes=(Axis("revolute", [0, 0, 1], f"ankle_angle_{side}", lin),),
            ),
        ]
        markers += [
            Marker(f"{up}THI", f"femur_{side}", [0.03, -0.2, s * 0.06]),
            Marker(f"{up}THA", f"femur_{side}", [0.05, -0.12, s * 0.02]),
            Marker(f"{up}KNE", f"femur_{side}", [0.0, -0.4, s * 0.05]),
            Marker(f"{up}KNM", f"femur_{side}", [0.0, -0.4, -s * 0.05]),
            Marker(f"{up}TIB", f"tibia_{side}", [0.03, -0.2, s * 0.05]),
            Marker(f"{up}TIA", f"tibia_{side}", [0.05, -0.1, -s * 0.01]),
            Marker(f"{up}ANK", f"tibia_{side}", [0.0, -0.42, s * 0.04]),
            Marker(f"{up}ANM", f"tibia_{side}", [0.0, -0.42, -s * 0.04]),
            Marker(f"{up}HEE", f"foot_{side}", [-0.05, -0.05, 0.0]),
            Marker(f"{up}TOE", f"foot_{side}", [0.16, -0.06, 0.0]),
            Marker(f"{up}MT5", f"foot_{side}", [0.12, -0.05, s * 0.04]),
        ]
    return Model(name="two_legs", bodies=bodies, joints=joints, coordinates=coords, markers=markers)


# mean, amplitude, frequency (Hz), phase of every coordinate of two_leg_model (smooth motion)
_MOTION = {
    "pelvis_tx": (0.0, 0.05, 0.5, 0.0),
    "pelvis_ty": (0.93, 0.02, 1.0, 0.3),
    "pelvis_tz": (0.0, 0.03, 0.5, 1.0),
    "pelvis_tilt": (0.02, 0.06, 0.7, 0.2),
    "pelvis_list": (0.0, 0.04, 0.5, 0.7),
    "pelvis_rotation": (0.0, 0.08, 0.4, 1.1),
    "hip_flexion_r": (0.15, 0.25, 0.7, 0.0),
    "hip_adduction_r": (-0.15, 0.06, 0.5, 0.4),
    "hip_rotation_r": (0.05, 0.10, 0.6, 0.9),
    "knee_angle_r": (-0.45, 0.30, 0.7, 0.5),
    "ankle_angle_r": (0.05, 0.20, 0.8, 0.1),
    "hip_flexion_l": (0.10, 0.20, 0.6, 2.0),
    "hip_adduction_l": (-0.15, 0.06, 0.5, 2.4),
    "hip_rotation_l": (-0.05, 0.10, 0.6, 2.9),
    "knee_angle_l": (-0.40, 0.25, 0.6, 2.5),
    "ankle_angle_l": (0.0, 0.15, 0.8, 2.1),
}


def motion(model: Model, t: Array) -> tuple[Array, Array, Array]:
    """θ, θ̇, θ̈ (closed form) of the smooth test motion at times ``t``."""
    t = np.asarray(t, dtype=float)[:, None]
    p = np.array([_MOTION[c] for c in model.coordinate_names])
    w = 2 * np.pi * p[:, 2]
    arg = w * t + p[:, 3]
    th = p[:, 0] + p[:, 1] * np.sin(arg)
    thd = p[:, 1] * w * np.cos(arg)
    thdd = -p[:, 1] * w**2 * np.sin(arg)
    return th, thd, thdd


def root_wrench(model: Model, th: Array, thd: Array, thdd: Array) -> tuple[Array, Array]:
    """External wrench the motion needs (base-link rows of RNEA): force (K, 3) and moment about
    the world origin (K, 3), world frame. It equals the spatial force RNEA transmits through the
    first root joint, mapped to the world."""
    pm = model.pin_model
    data = pm.createData()
    q, v, a = model.coupling.embed(th, thd, thdd)
    out_f = np.empty((th.shape[0], 3))
    out_m = np.empty((th.shape[0], 3))
    for k in range(th.shape[0]):
        pin.forwardKinematics(pm, data, q[k])
        pin.rnea(pm, data, q[k], v[k], a[k])
        fw = data.oMi[1].act(data.f[1])
        out_f[k], out_m[k] = fw.linear, fw.angular
    return out_f, out_m


def foot_points(model: Model, th: Array, feet: tuple[str, str]) -> Array:
    """Floor projections (y = 0) of a mid-foot point of each foot, (K, 2, 3)."""
    data = model.create_data()
    local = np.array([0.05, -0.05, 0.0])
    out = np.empty((th.shape[0], len(feet), 3))
    fids = [model.body_frame[f] for f in feet]
    for k in range(th.shape[0]):
        pin.framesForwardKinematics(model.pin_model, data, model.coupling.q(th[k]))
        for j, fid in enumerate(fids):
            out[k, j] = data.oMf[fid].act(local)
    out[..., 1] = 0.0
    return out


def split_wrench(force: Array, moment: Array, c_r: Array, c_l: Array) -> tuple[Array, ...]:
    """Split a ground wrench (force, moment about the origin) over two plates on the floor y = 0.

    The total centre of pressure c and free moment T follow from the wrench; the share
    α = projection of c on the segment [c_l, c_r] (clipped to [0.15, 0.85]) goes to the right
    plate with its COP at c_r + e, the rest to the left with COP c_l + e, where
    e = c − (α c_r + (1 − α) c_l); the two wrenches add up exactly to the total.

    Returns force_r, cop_r, free_r, force_l, cop_l, free_l (each (K, 3), world).
    """
    fy = force[:, 1]
    c = np.column_stack([moment[:, 2] / fy, np.zeros_like(fy), -moment[:, 0] / fy])
    tfree = moment[:, 1] - (c[:, 2] * force[:, 0] - c[:, 0] * force[:, 2])
    d = c_r - c_l
    alpha = np.clip(np.einsum("ki,ki->k", c - c_l, d) / np.einsum("ki,ki->k", d, d), 0.15, 0.85)
    e = c - (alpha[:, None] * c_r + (1 - alpha[:, None]) * c_l)
    f_r = alpha[:, None] * force
    cop_r = c_r + e
    free_r = np.outer(alpha * tfree, UP)
    m_r = np.cross(cop_r, f_r) + free_r
    f_l = force - f_r
    m_l = moment - m_r
    cop_l = np.column_stack([m_l[:, 2] / f_l[:, 1], np.zeros_like(fy), -m_l[:, 0] / f_l[:, 1]])
    free_l = m_l - np.cross(cop_l, f_l)
    return f_r, cop_r, free_r, f_l, cop_l, free_l


@dataclass(frozen=True)
class SyntheticTrial:
    """A simulated trial with its truth (see the module docstring)."""

    model: Model
    time: Array
    q: Array
    v: Array
    a: Array
    markers: Array
    marker_labels: tuple[str, ...]
    analog_time: Array
    plates: tuple[PlateWrench, ...]
    grf_force: Array
    grf_moment: Array
    feet: tuple[str, str]
    tau_true: Array
    rate_hz: float
    analog_ratio: int

    def write_c3d(self, path: str | Path) -> Path:
        """Markers (mm) and the two plates (type 2, plate-frame channels, N and N·mm)."""
        from msk.io import PlateSpec, write_c3d

        labels: list[str] = []
        chans = []
        specs = []
        for k, pl in enumerate(self.plates):
            corners = pl.corners
            centre = corners.mean(axis=0)
            rot = _plate_rotation(corners)
            m_centre = np.cross(pl.cop - centre, pl.force) + pl.free_moment
            f_loc = pl.force @ rot
            m_loc = m_centre @ rot * 1000.0
            names = [f"{a}{k + 1}" for a in ("Fx", "Fy", "Fz", "Mx", "My", "Mz")]
            labels += names
            chans.append(np.column_stack([f_loc, m_loc]))
            specs.append(PlateSpec(channels=tuple(names), corners_m=corners, origin_m=np.zeros(3)))
        return write_c3d(
            path,
            markers=self.markers,
            marker_labels=self.marker_labels,
            rate_hz=self.rate_hz,
            point_units="mm",
            analogs=np.hstack(chans),
            analog_labels=labels,
            analog_units=["N", "N", "N", "Nmm", "Nmm", "Nmm"] * len(self.plates),
            analog_ratio=self.analog_ratio,
            plates=specs,
        )


def _plate_rotation(corners: Array) -> Array:
    """Plate axes as msk.io reads them from the corners (x = c0 − c1, z = x × (c0 − c3))."""
    ax = corners[0] - corners[1]
    ay = corners[0] - corners[3]
    az = np.cross(ax, ay)
    ay = np.cross(az, ax)
    return np.column_stack(
        [ax / np.linalg.norm(ax), ay / np.linalg.norm(ay), az / np.linalg.norm(az)]
    )


def plate_corners(centre: Array, half_x: float = 0.50, half_z: float = 0.14) -> Array:
    """Corners of a floor plate (y = 0) whose z axis points down, as C3D plates usually do."""
    c = np.array([centre[0], 0.0, centre[2]])
    return np.array(
        [
            c + np.array([half_x, 0, half_z]),
            c + np.array([-half_x, 0, half_z]),
            c + np.array([-half_x, 0, -half_z]),
            c + np.array([half_x, 0, -half_z]),
        ]
    )


def make_trial(
    model: Model | None = None,
    *,
    duration_s: float = 2.0,
    rate_hz: float = 100.0,
    analog_ratio: int = 10,
    noise_m: float = 0.0,
    seed: int = 0,
) -> SyntheticTrial:
    """Simulate the smooth motion on ``model`` (default :func:`two_leg_model`) and return the
    markers, the two plates (at the analog rate) and the truth."""
    model = model or two_leg_model()
    feet = ("foot_r", "foot_l")
    n = round(duration_s * rate_hz)
    t = np.arange(n) / rate_hz
    ta = np.arange(n * analog_ratio) / (rate_hz * analog_ratio)
    th, thd, thdd = motion(model, t)
    ath, athd, athdd = motion(model, ta)
    force, moment = root_wrench(model, ath, athd, athdd)
    pts = foot_points(model, ath, feet)
    f_r, cop_r, free_r, f_l, cop_l, free_l = split_wrench(force, moment, pts[:, 0], pts[:, 1])
    plates = (
        PlateWrench("plate1", ta, f_r, cop_r, free_r, plate_corners(pts[:, 0].mean(axis=0))),
        PlateWrench("plate2", ta, f_l, cop_l, free_l, plate_corners(pts[:, 1].mean(axis=0))),
    )
    markers = marker_positions(model, th)
    if noise_m > 0:
        markers = markers + np.random.default_rng(seed).normal(0.0, noise_m, markers.shape)
    # true torques: RNEA with the plate wrenches applied to the feet (root rows vanish)
    pm = model.pin_model
    data = pm.createData()
    q, v, a = model.coupling.embed(th, thd, thdd)
    tau = np.empty((n, pm.nv))
    idx = np.arange(n) * analog_ratio
    for k in range(n):
        pin.forwardKinematics(pm, data, q[k])
        fext = pin.StdVec_Force()
        fext.extend([pin.Force.Zero() for _ in range(pm.njoints)])
        for pl, foot in zip(plates, feet):
            j = model.body_joint[foot]
            i = idx[k]
            f_w = pin.Force(pl.force[i], np.cross(pl.cop[i], pl.force[i]) + pl.free_moment[i])
            fext[j] = fext[j] + data.oMi[j].actInv(f_w)
        tau[k] = pin.rnea(pm, data, q[k], v[k], a[k], fext)
    return SyntheticTrial(
        model=model,
        time=t,
        q=th,
        v=thd,
        a=thdd,
        markers=markers,
        marker_labels=model.marker_names,
        analog_time=ta,
        plates=plates,
        grf_force=force,
        grf_moment=moment,
        feet=feet,
        tau_true=model.coupling.project(th, tau),
        rate_hz=rate_hz,
        analog_ratio=analog_ratio,
    )


# ---------------------------------------------------------------------------------------------
# the real OpenSim subject01 walk on the scaled gait2392 (used by tests and bench/bench_id.py)
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Subject01:
    """Inputs of OpenSim's gait2392 subject01 walk (``shared/tools/opensim-peer/data``)."""

    pipeline: Path
    model: Model
    trc_time: Array
    markers: Array
    marker_labels: tuple[str, ...]
    weights: dict[str, float]
    coordinate_tasks: dict[str, tuple[float, float]]
    plates: tuple[PlateWrench, ...]
    ik_time: Array
    ik_q: Array  # OpenSim's reference IK, rad / m, model coordinate order

    @property
    def model_path(self) -> Path:
        return self.pipeline / "OutputReference" / "subject01_simbody.osim"

    @property
    def reference_id_path(self) -> Path:
        return (
            self.pipeline
            / "OutputReference"
            / "ResultsInverseDynamics"
            / "InverseDynamicsOutput.sto"
        )


def subject01_pipeline() -> Path:
    from msk._data import shared_dir

    return shared_dir() / "tools" / "opensim-peer" / "data" / "Pipelines" / "Gait2392_Simbody"


def load_subject01() -> Subject01:
    """Model (via :func:`msk.osim.load_osim`), markers, IK tasks, plates and reference IK.

    The reference IK ``.mot`` has an old SIMM header without ``inDegrees``: its rotational
    coordinates are in degrees and converted here.
    """
    from msk.io.opensim_files import read_sto, read_trc
    from msk.kinematics import ik_tasks_from_setup
    from msk.loads import plates_from_table
    from msk.osim import load_osim

    pipe = subject01_pipeline()
    model = load_osim(pipe / "OutputReference" / "subject01_simbody.osim")
    trc = read_trc(pipe / "subject01_walk1.trc")
    weights, tasks = ik_tasks_from_setup(pipe / "subject01_Setup_IK.xml")
    grf = read_sto(pipe / "subject01_walk1_grf.mot")
    plates = plates_from_table(grf.time, grf.data, grf.columns)
    ik = read_sto(pipe / "OutputReference" / "subject01_walk1_ik.mot")
    cols = [ik.columns.index(c) for c in model.coordinate_names]
    q = ik.data[:, cols].copy()
    rot = [c.kind == "rotational" for c in model.coordinates]
    q[:, rot] = np.deg2rad(q[:, rot])
    return Subject01(
        pipeline=pipe,
        model=model,
        trc_time=trc.time,
        markers=trc.markers,
        marker_labels=trc.labels,
        weights=weights,
        coordinate_tasks=tasks,
        plates=plates,
        ik_time=ik.time,
        ik_q=q,
    )


#: OpenSim child-process script: IK (when ``trc`` is given) and ID with the subject01 setups,
#: each repeated ``ik_repeats`` / ``id_repeats`` times and timed inside the child (best kept).
OPENSIM_IK_ID_SCRIPT = """
import opensim as osim, os, time
P = ARGS["pipe"]
out = ARGS["out"]
model = P + "/OutputReference/subject01_simbody.osim"
ik_mot = ARGS.get("ik_mot")
if ARGS.get("trc"):
    ik_mot = out + "/ik.mot"
    walls = []
    for _ in range(int(ARGS.get("ik_repeats", 1))):
        ik = osim.InverseKinematicsTool(P + "/subject01_Setup_IK.xml")
        ik.set_model_file(model)
        ik.setMarkerDataFileName(ARGS["trc"])
        ik.setStartTime(ARGS["t0"]); ik.setEndTime(ARGS["t1"])
        ik.setResultsDir(out)
        ik.setOutputMotionFileName(ik_mot)
        tic = time.perf_counter(); ok = ik.run(); walls.append(time.perf_counter() - tic)
    RESULT["ik_wall_s"] = min(walls)
    RESULT["ik_walls_s"] = walls
    t = osim.TimeSeriesTable(ik_mot)
    RESULT["ik_frames"] = t.getNumRows()
    RESULT["ik_time"] = list(t.getIndependentColumn())
    RESULT["ik_labels"] = list(t.getColumnLabels())
    RESULT["ik_data"] = t.getMatrix().to_numpy().tolist()
el = osim.ExternalLoads(P + "/subject01_walk1_grf.xml", True)
el.setDataFileName(os.path.abspath(ARGS["grf"]))
el.printToXML(out + "/el.xml")
walls = []
for _ in range(int(ARGS.get("id_repeats", 1))):
    idt = osim.InverseDynamicsTool(P + "/subject01_Setup_InverseDynamics.xml")
    idt.setModelFileName(model)
    idt.setCoordinatesFileName(ik_mot)
    idt.setExternalLoadsFileName(out + "/el.xml")
    idt.setLowpassCutoffFrequency(ARGS["cutoff_hz"])
    idt.setStartTime(ARGS["t0"]); idt.setEndTime(ARGS["t1"])
    idt.setResultsDir(out); idt.setOutputGenForceFileName("id.sto")
    tic = time.perf_counter(); ok = idt.run(); walls.append(time.perf_counter() - tic)
RESULT["id_wall_s"] = min(walls)
RESULT["id_walls_s"] = walls
t = osim.TimeSeriesTable(out + "/id.sto")
RESULT["id_frames"] = t.getNumRows()
RESULT["id_time"] = list(t.getIndependentColumn())
RESULT["id_labels"] = list(t.getColumnLabels())
RESULT["id_data"] = t.getMatrix().to_numpy().tolist()
"""
