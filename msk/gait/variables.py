"""The variables of a gait report, per side, on the trial's frames, and their normalised cycles.

**Kinematics** (degrees; the conventions of Vicon's Plug-in Gait, Kadaba et al. 1990, Davis et
al. 1991; each side seen from its own side):

* pelvis tilt (anterior +), obliquity (this side up +), rotation (this side forward +): the
  Cardan angles of the pelvis frame R_p relative to the progression frame P of the cycle —
  x̂ the horizontal direction of the pelvis's displacement over the cycle, ŷ up, ẑ = x̂ × ŷ
  (to the right) — in the order tilt (about ẑ), obliquity (about x̂'), rotation (about ŷ''):
  Pᵀ R_p = R_z(α) R_x(β) R_y(γ), tilt = −α, obliquity = −β on the right and +β on the left,
  rotation = +γ on the right and −γ on the left. R_p is Plug-in Gait's pelvis frame (Davis et
  al. 1991; Vicon's "Plug-in Gait kinematic variables"): the plane of the two ASIS and the
  mid-PSIS (else the sacral marker), z from the left to the right ASIS, x anterior in that
  plane, y = z × x — the frame of the model's pelvis markers as inverse kinematics poses them,
  R_p = R_body R_m with R_m that frame in the pelvis body (:func:`pelvis_marker_frame`), so the
  tilt is that of the ASIS–PSIS line. A model body frame is not that plane: gait2392's and
  Rajagopal's pelvis frames put x along the generic bones' ASIS–sacrum line tilted 3.2° and
  −6.6° (their markers' ASIS–PSIS plane about the body's z), and a subject's markers add their
  own offset. Without the ASIS pair and a PSIS/sacral marker on the model's pelvis the body
  frame is used, and :attr:`GaitVariables.notes` says so;
            out[var] = sign * np.rad2deg(q[:, c])
        if poses is not None and s in poses.thigh_rotation:
            out.update(hip_angles(poses.pelvis_rotation, poses.thigh_rotation[s], s))
        if angles is not None and s in angles:
            out.update({k: np.asarray(v, dtype=float) for k, v in angles[s].items()})
* foot progression (internal, toe-in, +): the angle in the floor plane between the foot's long
  axis (the x axis of the calcaneus / foot body) and x̂.

On a treadmill x̂ is the pelvis's displacement relative to the belt (the belt's velocity u:
:func:`msk.gait.spatiotemporal.surface_velocity`), i.e. −u's direction for a pelvis held in
place.

**Kinetics** (per kg of body mass m; internal moments, Plug-in Gait signs, but the knee
adduction moment, which is external as gait clinics report it):

* hip extension and abduction, knee extension and ankle plantarflexion moments: −τ_hip_flexion/m,
  −τ_hip_adduction/m, τ_knee_angle/m, −τ_ankle_angle/m, the generalised forces of inverse
  dynamics (:func:`msk.dynamics.inverse.inverse_dynamics`);
* the external knee adduction moment: the 3-D wrench the femur transmits to the tibia and the
  bodies distal to it, RNEA's spatial force f_knee after the backward pass (Featherstone 2008,
  §5.3; :func:`msk.dynamics.inverse.joint_reaction`), its moment about the knee centre (the
  tibia frame's origin) in the tibia frame (x anterior, y proximal, z right). The external
  moment is its opposite (Winter 2009, §5.1: the net internal moment balances the external
  loads and the segments' inertia), and adduction of the distal segment is a rotation about
  +x on the right and −x on the left, so KAM = −s M_x / m, s = +1 right, −1 left: positive
  when the ground reaction passes medial to the knee, as Plug-in Gait's (Schache & Baker
  2007);
* joint powers P = Σ_j τ_j θ̇_j over the joint's coordinates (W/kg; hip: its three, knee: its
  flexion, with the translations it drives, ankle: ankle and subtalar): generation +.

Kinetic variables are NaN where the leg's torques are (a foot's reaction not measured:
:func:`msk.dynamics.inverse.without_unmeasured_contact`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin
from scipy.spatial.transform import Rotation

from msk.gait.cycles import SIDES, GaitCycles, SideCycles, cycle_bounds, normalise_cycles
from msk.units import Array

__all__ = [
    "COORDINATE_ANGLES",
    "KINEMATICS",
    "KINETICS",
    "GaitVariables",
    "SegmentPoses",
    "gait_cycles",
    "gait_variables",
    "hip_angles",
    "pelvis_marker_frame",
    "segment_poses",
]

_SFX = {"right": "_r", "left": "_l"}
_SIGN = {"right": 1.0, "left": -1.0}

#: variable → (coordinate stem, sign): the joint angles taken from the model's coordinates
COORDINATE_ANGLES: Mapping[str, tuple[str, float]] = {
    "hip_flexion_deg": ("hip_flexion", 1.0),
    "hip_adduction_deg": ("hip_adduction", 1.0),
    "hip_rotation_deg": ("hip_rotation", 1.0),
    "knee_flexion_deg": ("knee_angle", -1.0),
    "knee_adduction_deg": ("knee_adduction", 1.0),
    "knee_rotation_deg": ("knee_rotation", 1.0),
    "ankle_dorsiflexion_deg": ("ankle_angle", 1.0),
}
#: every kinematic variable, in report order
KINEMATICS: tuple[str, ...] = (
    "pelvis_tilt_deg",
    "pelvis_obliquity_deg",
    "pelvis_rotation_deg",
    "hip_flexion_deg",
    "hip_adduction_deg",
    "hip_rotation_deg",
    "knee_flexion_deg",
    "knee_adduction_deg",
    "knee_rotation_deg",
    "ankle_dorsiflexion_deg",
    "foot_progression_deg",
)
#: every kinetic variable, in report order
KINETICS: tuple[str, ...] = (
    "hip_extension_moment_nm_kg",
    "hip_abduction_moment_nm_kg",
    "knee_extension_moment_nm_kg",
    "knee_adduction_moment_nm_kg",
    "ankle_plantarflexion_moment_nm_kg",
    "hip_power_w_kg",
    "knee_power_w_kg",
    "ankle_power_w_kg",
)
#: variable → (coordinate stem, sign) of the sagittal/frontal moments from the joint torques
_MOMENTS: Mapping[str, tuple[str, float]] = {
    "hip_extension_moment_nm_kg": ("hip_flexion", -1.0),
    "hip_abduction_moment_nm_kg": ("hip_adduction", -1.0),
    "knee_extension_moment_nm_kg": ("knee_angle", 1.0),
    "ankle_plantarflexion_moment_nm_kg": ("ankle_angle", -1.0),
}
#: power variable → the coordinate stems whose τ θ̇ it sums
_POWERS: Mapping[str, tuple[str, ...]] = {
    "hip_power_w_kg": ("hip_flexion", "hip_adduction", "hip_rotation"),
    "knee_power_w_kg": ("knee_angle", "knee_adduction", "knee_rotation"),
    "ankle_power_w_kg": ("ankle_angle", "subtalar_angle"),
}
_FOOT_BODIES = ("calcn", "foot")


@dataclass(frozen=True)
class SegmentPoses:
    """Poses the gait variables need, per frame (world = model frame; NaN on failed frames).

    Attributes:
        pelvis_rotation: (N, 3, 3) world ← pelvis.
        pelvis_origin: (N, 3) m.
        foot_rotation, heel: side → (N, 3, 3) world ← foot (calcaneus) body and (N, 3) its
            origin, m (the heel of :mod:`msk.gait.spatiotemporal`).
        foot_body: side → the foot body's name.
        up: (3,) the world's up direction (against gravity).
        pelvis_frame: which frame ``pelvis_rotation`` is (:func:`pelvis_marker_frame`).
        thigh_rotation: side → (N, 3, 3) world ← thigh: the femur body's rotation turned by
            its rest orientation in the pelvis body (zero hip coordinates), so that a thigh
            at rest is aligned with the pelvis body; given only when ``pelvis_rotation`` is
            Plug-in Gait's frame (the hip angles of :func:`hip_angles`).
    """

    pelvis_rotation: Array
    pelvis_origin: Array
    foot_rotation: Mapping[str, Array]
    heel: Mapping[str, Array]
    foot_body: Mapping[str, str]
    up: Array
    pelvis_frame: str = "the model's pelvis body frame"
    thigh_rotation: Mapping[str, Array] = field(default_factory=dict)


def _foot_body(model: Any, side: str) -> str | None:
    for stem in _FOOT_BODIES:
        if stem + _SFX[side] in model.body_frame:
            return str(stem + _SFX[side])
    return None


def pelvis_marker_frame(model: Any, body: str = "pelvis") -> tuple[Array | None, str]:
    """Plug-in Gait's pelvis frame in the model's pelvis ``body`` (rotation (3, 3), columns x
    anterior, y up, z right; module docstring) from the model's markers on it — the ASIS pair
    and the midpoint of the PSIS pair, else the sacral marker (:mod:`msk.model.markersets`
    labels: the lab's as placed, else the model's own) — and a description saying which; None
    and why when the markers do not define it."""
    from msk.model.markersets import pelvis_landmarks

    found = pelvis_landmarks(model, body)
    pts = {k: np.asarray(mk.offset, dtype=float) for k, mk in found.items()}
    names = {k: str(mk.name) for k, mk in found.items()}
    if "psis_r" in pts and "psis_l" in pts:
        post, post_name = (
            0.5 * (pts["psis_r"] + pts["psis_l"]),
            (f"the mid-PSIS ({names['psis_r']}, {names['psis_l']})"),
        )
    elif "sacrum" in pts:
        post, post_name = pts["sacrum"], f"the sacral marker {names['sacrum']}"
    else:
        return None, "the model's pelvis body frame (no PSIS pair nor sacral marker on it)"
    if "asis_r" not in pts or "asis_l" not in pts:
        return None, "the model's pelvis body frame (no ASIS pair on it)"
    z = pts["asis_r"] - pts["asis_l"]
    z = z / np.linalg.norm(z)
    a = 0.5 * (pts["asis_r"] + pts["asis_l"]) - post
    x = a - (a @ z) * z
    nx = float(np.linalg.norm(x))
    if nx < 1e-6:
        return None, "the model's pelvis body frame (its pelvis markers are collinear)"
    x = x / nx
    r = np.column_stack([x, np.cross(z, x), z])
    tilt = float(np.degrees(np.arctan2(-x[1], x[0])))
    return r, (
        f"the plane of the ASIS markers ({names['asis_r']}, {names['asis_l']}) and "
        f"{post_name} (Plug-in Gait's pelvis): its tilt is the model's pelvis body frame's "
        f"{tilt:+.1f}° (anterior +)"
    )


def segment_poses(model: Any, kinematics: Any) -> SegmentPoses:
    """The pelvis and feet poses over the trial (one forward-kinematics pass); the pelvis in
    Plug-in Gait's frame where the model's pelvis markers define it
    (:func:`pelvis_marker_frame`)."""
    q = np.asarray(kinematics.q, dtype=float)
    n = q.shape[0]
    good = np.isfinite(q).all(axis=1)
    g = np.asarray(model.gravity, dtype=float)
    up = -g / np.linalg.norm(g)
    pelvis = "pelvis" if "pelvis" in model.body_frame else model.pin_model.frames[1].name
    feet = {s: b for s in SIDES if (b := _foot_body(model, s)) is not None}
    pr = np.full((n, 3, 3), np.nan)
    po = np.full((n, 3), np.nan)
    fr = {s: np.full((n, 3, 3), np.nan) for s in feet}
    fo = {s: np.full((n, 3), np.nan) for s in feet}
    data = model.create_data()
    idx = np.flatnonzero(good)
    if idx.size:
        qp = model.coupling.q(q[idx])
        fp = model.body_frame[pelvis]
        ff = {s: model.body_frame[b] for s, b in feet.items()}
        for k, i in enumerate(idx):
            pin.framesForwardKinematics(model.pin_model, data, qp[k])
            pr[i] = data.oMf[fp].rotation
            po[i] = data.oMf[fp].translation
            for s, f in ff.items():
                fr[s][i] = data.oMf[f].rotation
                fo[s][i] = data.oMf[f].translation
    r_m, how = pelvis_marker_frame(model, pelvis)
    thighs: dict[str, Array] = {}
    if r_m is not None:
        pr = np.einsum("nij,jk->nik", pr, r_m)
        thighs = _thigh_rotations(model, q, good, pelvis)
    return SegmentPoses(pr, po, fr, fo, feet, up, how, thighs)


def _thigh_rotations(model: Any, q: Array, good: Array, pelvis: str) -> dict[str, Array]:
    """side → (N, 3, 3) world ← thigh (:class:`SegmentPoses`), the femur being the child of
    the joint driven by ``hip_flexion_<s>``; sides without one are left out."""
    femurs = {
        s: j.child for s in SIDES if (j := _joint_of(model, "hip_flexion" + _SFX[s])) is not None
    }
    femurs = {s: b for s, b in femurs.items() if b in model.body_frame}
    if not femurs:
        return {}
    data = model.create_data()
    fp = model.body_frame[pelvis]
    # the femurs' rest orientation in the pelvis body: every coordinate zero
    pin.framesForwardKinematics(
        model.pin_model, data, model.coupling.q(np.zeros((1, q.shape[1])))[0]
    )
    rest = {
        s: data.oMf[fp].rotation.T @ data.oMf[model.body_frame[b]].rotation
        for s, b in femurs.items()
    }
    out = {s: np.full((q.shape[0], 3, 3), np.nan) for s in femurs}
    idx = np.flatnonzero(good)
    if idx.size:
        qp = model.coupling.q(q[idx])
        for k, i in enumerate(idx):
            pin.framesForwardKinematics(model.pin_model, data, qp[k])
            for s, b in femurs.items():
                out[s][i] = data.oMf[model.body_frame[b]].rotation @ rest[s].T
    return out


def hip_angles(pelvis_rotation: Array, thigh_rotation: Array, side: str) -> dict[str, Array]:
    """Hip flexion, adduction and internal rotation (deg, (N,) each) of the thigh relative to
    the pelvis frame, Plug-in Gait's YXZ Cardan sequence (module docstring): R_pᵀ R_thigh =
    R_z(φ) R_x(θ) R_y(ψ) in the model's axes (x anterior, y up, z right), flexion φ,
    adduction s θ, internal rotation s ψ (s = +1 right, −1 left)."""
    r = np.asarray(pelvis_rotation, dtype=float)
    t = np.asarray(thigh_rotation, dtype=float)
    ok = np.isfinite(r).all(axis=(1, 2)) & np.isfinite(t).all(axis=(1, 2))
    ang = np.full((r.shape[0], 3), np.nan)
    if ok.any():
        rel = np.einsum("nji,njk->nik", r[ok], t[ok])
        ang[ok] = np.rad2deg(Rotation.from_matrix(rel).as_euler("ZXY"))
    s = _SIGN[side]
    return {
        "hip_flexion_deg": ang[:, 0],
        "hip_adduction_deg": s * ang[:, 1],
        "hip_rotation_deg": s * ang[:, 2],
    }


@dataclass(frozen=True)
class GaitVariables:
    """The coordinate-based variables of both sides on the trial's frames (the pelvis and foot
    progression angles depend on the cycle's progression direction: :func:`gait_cycles`
    computes them per cycle).

    Attributes:
        time: (N,) s.
        series: side → variable → (N,) values (units in the names).
        not_modelled: variables the model has no degree of freedom for (not given).
        knee_adduction_moment: how the knee adduction moment was computed (or why not).
        notes: what was decided (the model's knee has no frontal or transverse freedom…).
    """

    time: Array
    series: Mapping[str, Mapping[str, Array]]
    not_modelled: tuple[str, ...] = ()
    knee_adduction_moment: str = ""
    notes: tuple[str, ...] = field(default_factory=tuple)


def _col(names: Sequence[str], name: str) -> int | None:
    try:
        return list(names).index(name)
    except ValueError:
        return None


def _knee_joint(model: Any, side: str) -> Any | None:
    return _joint_of(model, "knee_angle" + _SFX[side])


def _joint_of(model: Any, coord: str) -> Any | None:
    """The joint with a revolute axis driven by ``coord``."""
    for j in model.joints:
        if any(ax.coordinate == coord and ax.kind == "revolute" for ax in j.axes):
            return j
    return None


def knee_adduction_moment(
    model: Any, kinematics: Any, loads: Any, side: str, *, mass_kg: float
) -> Array | None:
    """(N,) the external knee adduction moment of ``side`` (N·m/kg; module docstring), None
    when the model has no knee flexion coordinate on that side."""
    from msk.dynamics.inverse import ID_BLOCK, joint_reaction

    joint = _knee_joint(model, side)
    if joint is None:
        return None
    n = int(np.size(kinematics.time))
    parts = []
    # block by block on a long trial (every frame's wrench is computed alone: the same values)
    for c0 in range(0, n, ID_BLOCK) if n > ID_BLOCK else (0,):
        if n > ID_BLOCK:
            fr = np.arange(c0, min(c0 + ID_BLOCK, n))
            kin, ext = kinematics.take(fr), None if loads is None else loads.take(fr)
        else:
            kin, ext = kinematics, loads
        r = joint_reaction(model, kin, ext, joint=joint.name, frame=joint.child)
        parts.append(np.asarray(r.moment, dtype=float)[:, 0])
    return -_SIGN[side] * np.concatenate(parts) / mass_kg


def gait_variables(
    model: Any,
    kinematics: Any,
    *,
    torques: Any = None,
    loads: Any = None,
    mass_kg: float,
    dynamics_model: Any = None,
    poses: SegmentPoses | None = None,
    angles: Mapping[str, Mapping[str, Array]] | None = None,
    angle_notes: Sequence[str] = (),
) -> GaitVariables:
    """The coordinate-based kinematics and the kinetics of both sides (module docstring); the
    hip angles relative to Plug-in Gait's pelvis frame where ``poses`` has the thighs
    (:func:`hip_angles`), else the model's hip coordinates.

    Args:
        model: the model of ``kinematics``.
        kinematics: :class:`msk.kinematics.ik.Kinematics`.
        torques: :class:`msk.dynamics.inverse.JointTorques` (None: no kinetics).
        loads: :class:`msk.dynamics.loads.ExternalLoads` of the torques (the knee adduction
            moment's ground reactions; None: no knee adduction moment).
        mass_kg: body mass for the normalisation.
        dynamics_model: the model whose inertias gave ``torques`` (default ``model``).
        poses: :func:`segment_poses` of ``kinematics`` (None: the hip coordinates).
        angles: side → variable → (N,) angles replacing the model's (a reported angle
            convention: :mod:`msk.gait.plug_in_gait`), with ``angle_notes`` saying what.
    """
    from msk.model.conventions import reference_signs

    names = tuple(kinematics.coordinate_names)
    ref = reference_signs(model)  # q_ref = s q, τ_ref = s τ (msk.model.conventions)
    q = np.asarray(kinematics.q, dtype=float)
    v = np.asarray(kinematics.v, dtype=float)
    series: dict[str, dict[str, Array]] = {}
    missing: set[str] = set()
    kam_note = "no inverse dynamics" if torques is None else ""
    notes: list[str] = []
    for s in SIDES:
        out: dict[str, Array] = {}
        for var, (stem, sign) in COORDINATE_ANGLES.items():
            c = _col(names, stem + _SFX[s])
            if c is None:
                missing.add(var)
                continue
            out[var] = sign * ref.get(names[c], 1.0) * np.rad2deg(q[:, c])
        if poses is not None and s in poses.thigh_rotation:
            out.update(hip_angles(poses.pelvis_rotation, poses.thigh_rotation[s], s))
        if angles is not None and s in angles:
            out.update({k: np.asarray(v, dtype=float) for k, v in angles[s].items()})
        if torques is not None:
            tn = tuple(torques.coordinate_names)
            tau = np.asarray(torques.tau, dtype=float)
            for var, (stem, sign) in _MOMENTS.items():
                c = _col(tn, stem + _SFX[s])
                if c is not None:
                    out[var] = sign * ref.get(tn[c], 1.0) * tau[:, c] / mass_kg
            for var, stems in _POWERS.items():
                cols = [
                    (ct, cq)
                    for st in stems
                    if (ct := _col(tn, st + _SFX[s])) is not None
                    and (cq := _col(names, st + _SFX[s])) is not None
                ]
                if cols:
                    out[var] = sum(tau[:, ct] * v[:, cq] for ct, cq in cols) / mass_kg
            if loads is not None:
                kam = knee_adduction_moment(
                    dynamics_model if dynamics_model is not None else model,
                    kinematics,
                    loads,
                    s,
                    mass_kg=mass_kg,
                )
                ck = _col(tn, "knee_angle" + _SFX[s])
                if kam is not None and ck is not None:
                    # known where the leg's torques are (its foot's reaction measured)
                    kam[~np.isfinite(tau[:, ck])] = np.nan
                    out["knee_adduction_moment_nm_kg"] = kam
                    kam_note = (
                        "external knee adduction moment: minus the moment about the knee centre "
                        "of the wrench the femur transmits to the tibia (RNEA, ground reactions "
                        "and segment dynamics), about the tibia frame's anterior axis; + when "
                        "the ground reaction passes medial to the knee (Plug-in Gait's sign)"
                    )
                elif kam is None:
                    kam_note = "the model has no knee flexion coordinate"
            elif not kam_note:
                kam_note = "no ground reactions"
        series[s] = out
    have = {v for s in series.values() for v in s}
    not_modelled = tuple(v for v in COORDINATE_ANGLES if v in missing and v not in have)
    if poses is not None and poses.thigh_rotation:
        notes.append(
            "hip angles: the thigh relative to the pelvis frame of the pelvis angles (Plug-in "
            "Gait's YXZ Cardan sequence), not the model's hip coordinates"
        )
    notes.extend(angle_notes)
    if "knee_adduction_deg" in not_modelled:
        notes.append(
            "the model's knee has no adduction or rotation degree of freedom (one: flexion, "
            "the translations following it): knee varus/valgus and rotation angles not given"
        )
    return GaitVariables(
        np.asarray(kinematics.time, dtype=float), series, not_modelled, kam_note, tuple(notes)
    )


def _progression(
    poses: SegmentPoses, t: Array, a: float, b: float, surface: Array | None = None
) -> Array | None:
    """Horizontal unit direction of the pelvis's displacement from a to b relative to the
    surface walked on (``surface``: its velocity, a treadmill's belt)."""
    pa = np.array([np.interp(a, t, poses.pelvis_origin[:, k]) for k in range(3)])
    pb = np.array([np.interp(b, t, poses.pelvis_origin[:, k]) for k in range(3)])
    d = pb - pa
    if surface is not None:
        d = d - (b - a) * np.asarray(surface, dtype=float)
    d = d - (d @ poses.up) * poses.up
    nd = float(np.linalg.norm(d))
    return d / nd if np.isfinite(nd) and nd > 1e-3 else None


def _frame_angles(poses: SegmentPoses, side: str, x: Array) -> dict[str, Array]:
    """Pelvis and foot progression angles (deg) on every frame, progression direction x."""
    up = poses.up
    z = np.cross(x, up)
    p = np.column_stack([x, up, z])  # world ← progression
    out: dict[str, Array] = {}
    r = poses.pelvis_rotation
    ok = np.isfinite(r).all(axis=(1, 2))
    ang = np.full((r.shape[0], 3), np.nan)
    if ok.any():
        rel = np.einsum("ji,njk->nik", p, r[ok])
        ang[ok] = np.rad2deg(Rotation.from_matrix(rel).as_euler("ZXY"))
    s = _SIGN[side]
    out["pelvis_tilt_deg"] = -ang[:, 0]
    out["pelvis_obliquity_deg"] = -s * ang[:, 1]
    out["pelvis_rotation_deg"] = s * ang[:, 2]
    if side in poses.foot_rotation:
        f = poses.foot_rotation[side][:, :, 0]  # the foot's long axis in the world
        out["foot_progression_deg"] = np.rad2deg(np.arctan2(-s * (f @ z), f @ x))
    return out


def gait_cycles(
    model: Any,
    kinematics: Any,
    foot_strike: Mapping[str, Sequence[float]],
    foot_off: Mapping[str, Sequence[float]],
    *,
    torques: Any = None,
    loads: Any = None,
    mass_kg: float,
    dynamics_model: Any = None,
    poses: SegmentPoses | None = None,
    trial: str = "",
    threshold_n: float = 20.0,
    surface: Array | None = None,
    angles: Mapping[str, Mapping[str, Array]] | None = None,
    angle_notes: Sequence[str] = (),
) -> tuple[GaitCycles, GaitVariables]:
    """Every complete cycle of both legs with the variables of the module docstring.

    A cycle counts as measured when its stance (strike to foot off) has the leg's kinetics on
    every frame and the foot carries more than ``threshold_n`` of vertical ground reaction on
    at least half of them (a stance the plates saw). ``surface``: the velocity of the surface
    walked on (a treadmill's belt, :func:`msk.gait.spatiotemporal.surface_velocity`): the
    progression direction is the pelvis's relative to it. ``angles``, ``angle_notes``: angles
    replacing the model's (:func:`gait_variables`)."""
    poses = segment_poses(model, kinematics) if poses is None else poses
    gv = gait_variables(
        model, kinematics, torques=torques, loads=loads, mass_kg=mass_kg,
        dynamics_model=dynamics_model, poses=poses, angles=angles, angle_notes=angle_notes,
    )  # fmt: skip
    t = np.asarray(kinematics.time, dtype=float)
    have = {v for s in gv.series.values() for v in s}
    geo = {"pelvis_tilt_deg", "pelvis_obliquity_deg", "pelvis_rotation_deg"}
    if poses.foot_rotation:
        geo.add("foot_progression_deg")
    variables = tuple(v for v in KINEMATICS + KINETICS if v in have or v in geo)
    notes = [*gv.notes, f"pelvis angles in {poses.pelvis_frame}"]
    sides: dict[str, SideCycles] = {}
    for s in SIDES:
        bounds = cycle_bounds(foot_strike.get(s, ()), foot_off.get(s, ()))
        vals = np.full((len(bounds), 101, len(variables)), np.nan)
        measured = np.zeros(len(bounds), dtype=bool)
        fz = _vertical_load(model, loads, poses.foot_body.get(s), poses.up, t.size)
        for i, (a, b, fo_pct) in enumerate(bounds):
            x = _progression(poses, t, a, b, surface)
            series: dict[str, Array] = dict(gv.series.get(s, {}))
            if x is not None:
                series.update(_frame_angles(poses, s, x))
            else:
                notes.append(f"{s} cycle at {a:.3f} s: the pelvis did not progress")
            cols = [j for j, v in enumerate(variables) if v in series]
            if cols:
                y = np.column_stack([series[variables[j]] for j in cols])
                vals[i][:, cols] = normalise_cycles(t, y, [(a, b, fo_pct)])[0]
            off = a + fo_pct / 100.0 * (b - a) if np.isfinite(fo_pct) else b
            stance = (t >= a) & (t <= off)
            knee = series.get("knee_extension_moment_nm_kg")
            if knee is not None and stance.any() and fz is not None:
                measured[i] = bool(
                    np.isfinite(knee[stance]).all() and (fz[stance] > threshold_n).mean() >= 0.5
                )
        sides[s] = SideCycles(
            s,
            vals,
            np.array([c[0] for c in bounds], dtype=float),
            np.array([c[1] for c in bounds], dtype=float),
            np.array([c[2] for c in bounds], dtype=float),
            measured,
            (trial,) * len(bounds),
        )
    return GaitCycles(variables, sides["left"], sides["right"], tuple(notes)), gv


def _vertical_load(model: Any, loads: Any, foot: str | None, up: Array, n: int) -> Array | None:
    """(N,) vertical ground reaction on the foot and the bodies distal to it (N)."""
    if loads is None or foot is None:
        return None
    fz = np.zeros(n)
    for b in model.subtree(foot):
        if b in loads.bodies:
            fz += np.nan_to_num(np.asarray(loads.force)[:, loads.bodies.index(b)]) @ up
    return fz
