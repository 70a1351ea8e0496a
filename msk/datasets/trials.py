"""Synthetic trials with a known truth, for tests, benchmarks and tutorials.

:func:`make_trial` moves :func:`~msk.datasets.models.two_leg_model` along a known smooth motion
and returns the exact coordinates (θ, θ̇, θ̈ in closed form), the marker trajectories
(optionally with Gaussian noise), the ground reaction wrench that the motion needs — the
root-chain (base-link) rows of RNEA: the spatial force the ground would have to transmit to the
pelvis — split over two force plates (one under each foot, each with its own centre of pressure
and a free moment about the vertical), and the true joint torques. ``SyntheticTrial.write_c3d``
writes markers and plates as a C3D file with ezc3d (plates of type 2, channels in the plate
frame, mm), which :func:`msk.io.read_c3d` reads back; :func:`write_synthetic_session` writes a
whole session folder (model, C3D, config) for ``msk run``.

:func:`identification_trial` simulates a noisy inertial-identification trial of a
:func:`~msk.datasets.models.whole_body_model`.

Usage::

    from msk.datasets.models import two_leg_model
    from msk.datasets.trials import make_trial

    trial = make_trial(two_leg_model(), duration_s=2.0, rate_hz=100.0, noise_m=0.002)
    trial.write_c3d(tmp_path / "synthetic.c3d")
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from msk.datasets.models import two_leg_model
from msk.dynamics.identification import IdentificationTrial, root_generalized_forces
from msk.dynamics.loads import PlateWrench
from msk.io.c3d import plate_axes
from msk.model.core import Model, marker_positions
from msk.signal import derivative, filtfilt_butter
from msk.units import G0, Array

__all__ = [
    "IDENTIFICATION_RATE_HZ",
    "UP",
    "SyntheticTrial",
    "foot_points",
    "ground_wrench",
    "identification_trial",
    "make_trial",
    "motion",
    "plate_corners",
    "root_wrench",
    "split_wrench",
    "whole_body_motion",
    "write_synthetic_session",
]

UP = np.array([0.0, 1.0, 0.0])
#: sampling rate of :func:`identification_trial` (Hz)
IDENTIFICATION_RATE_HZ = 100.0


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
            if corners is None:
                raise ValueError(f"plate {pl.name} has no corners")
            centre = corners.mean(axis=0)
            rot = plate_axes(corners)
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


def write_synthetic_session(
    folder: Path,
    name: str = "synth",
    *,
    noise_m: float = 0.001,
    seed: int = 0,
    broken: bool = False,
    grf_cutoff_hz: float = 15.0,
) -> tuple[Path, SyntheticTrial]:
    """A session folder for ``msk run``: the :func:`~msk.datasets.models.two_leg_model` file, a
    simulated C3D ``<name>.c3d`` of :func:`make_trial` (1 s at 100 Hz, markers + 2 plates) and
    its config ``<name>.toml``.

    Returns ``(config_path, synthetic_trial)``; ``broken=True`` writes a truncated C3D."""
    from msk.model.files import save_model

    folder.mkdir(parents=True, exist_ok=True)
    model = two_leg_model()
    save_model(model, folder / "two_legs.toml", header="synthetic two-leg model (tests)")
    trial = make_trial(model, duration_s=1.0, rate_hz=100.0, noise_m=noise_m, seed=seed)
    c3d = trial.write_c3d(folder / f"{name}.c3d")
    if broken:
        c3d.write_bytes(c3d.read_bytes()[:700])
    cfg = folder / f"{name}.toml"
    cfg.write_text(
        f"""
[subject]
name = "{name}"
mass_kg = {model.total_mass}
height_m = 1.75
side = "left"

[model]
source = "two_legs.toml"
scale = false

[[trials]]
name = "walk"
file = "{name}.c3d"
role = "task"

[filters]
kinematics_cutoff_hz = 8.0
grf_cutoff_hz = {grf_cutoff_hz}
""",
        encoding="utf-8",
    )
    return cfg, trial


def whole_body_motion(
    model: Model, t: Array, rng: np.random.Generator, *, still: Sequence[str] = ()
) -> tuple[Array, Array, Array]:
    """Sums of sines on every coordinate (closed-form θ, θ̇, θ̈); ``still`` coordinates fixed."""
    n_c = model.n_coords
    th = np.tile(model.default_coordinates(), (t.size, 1))
    thd = np.zeros_like(th)
    thdd = np.zeros_like(th)
    for i, c in enumerate(model.coordinates):
        if c.name in still:
            continue
        base = {"knee": -0.6, "hip_flexion": 0.3}.get(
            c.name.rsplit("_", 1)[0].split("_angle")[0], 0.0
        )
        amp = 0.08 if c.kind == "translational" else (0.45 if "pelvis" not in c.name else 0.3)
        th[:, i] += base
        for _ in range(3):
            a = amp * rng.uniform(0.3, 0.6)
            w = 2 * np.pi * rng.uniform(0.15, 1.2)
            p = rng.uniform(0, 2 * np.pi)
            th[:, i] += a * np.sin(w * t + p)
            thd[:, i] += a * w * np.cos(w * t + p)
            thdd[:, i] -= a * w * w * np.sin(w * t + p)
    assert th.shape[1] == n_c
    return th, thd, thdd


def ground_wrench(model: Model, th: Array, thd: Array, thdd: Array) -> tuple[Array, Array]:
    """World force and moment about the origin the plates must supply (Pinocchio RNEA)."""
    q, v, a = model.coupling.embed(th, thd, thdd)
    data = model.create_data()
    f = np.empty((th.shape[0], 3))
    m = np.empty((th.shape[0], 3))
    for n in range(th.shape[0]):
        pin.rnea(model.pin_model, data, q[n], v[n], a[n])
        w = data.liMi[1].act(data.f[1])  # force through the first root joint (world: parent 0)
        f[n], m[n] = w.linear, w.angular
    return f, m


def identification_trial(
    truth: Model,
    duration_s: float,
    seed: int,
    *,
    marker_noise_m: float = 0.002,
    plate_noise: float = 0.01,
    cutoff_hz: float = 4.0,
    still: Sequence[str] = ("arm_flex_r", "arm_flex_l"),
    name: str = "",
) -> IdentificationTrial:
    """A noisy identification trial of ``truth`` (e.g.
    :func:`~msk.datasets.models.whole_body_model`) moved along sums of sines on every
    coordinate but ``still`` (pelvis free), at 100 Hz.

    The plates measure the base-link wrench computed by Pinocchio's RNEA (independent of msk's
    regressor), with ``plate_noise`` × body weight white noise on the forces (and the matching
    moment noise); the kinematics carry white noise equivalent to ``marker_noise_m`` markers,
    low-pass filtered (``cutoff_hz`` zero-lag Butterworth, as the plates) and differentiated
    numerically; 20 frames are dropped at each end (filter edges)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s, 1.0 / IDENTIFICATION_RATE_HZ)
    th, thd, thdd = whole_body_motion(truth, t, rng, still=still)
    f, m = ground_wrench(truth, th, thd, thdd)
    # 2 mm markers ≈ 1.2 mm on translations and 2 mm / 0.15 m / √3 rad on rotations (IK over
    # three markers per segment), white, then filtered like the plates
    rot_noise = marker_noise_m / 0.15 / np.sqrt(3)
    noise = np.array(
        [marker_noise_m / np.sqrt(3) if c.kind == "translational" else rot_noise
         for c in truth.coordinates]
    )  # fmt: skip
    for i, c in enumerate(truth.coordinates):
        if c.name in still:
            noise[i] = 0.0
    th_m = filtfilt_butter(
        th + rng.normal(size=th.shape) * noise, rate_hz=IDENTIFICATION_RATE_HZ, cutoff_hz=cutoff_hz
    )
    dt = 1.0 / IDENTIFICATION_RATE_HZ
    thd_m, thdd_m = derivative(th_m, dt=dt), derivative(th_m, dt=dt, order=2)
    weight = truth.total_mass * G0
    df = rng.normal(scale=plate_noise * weight, size=f.shape)
    plate_centre = np.array([0.4, 0.0, 0.2])
    dm = np.cross(plate_centre, df) + rng.normal(scale=plate_noise * weight * 0.05, size=m.shape)
    f_m = filtfilt_butter(f + df, rate_hz=IDENTIFICATION_RATE_HZ, cutoff_hz=cutoff_hz)
    m_m = filtfilt_butter(m + dm, rate_hz=IDENTIFICATION_RATE_HZ, cutoff_hz=cutoff_hz)
    tau = root_generalized_forces(truth, th_m, f_m, m_m)
    keep = slice(20, -20)  # drop filter edges
    return IdentificationTrial(th_m[keep], thd_m[keep], thdd_m[keep], tau[keep], name=name)
