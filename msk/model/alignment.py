"""Frontal-plane (varus/valgus) alignment of a knee: the tibia tilted and shifted on the femur.

A generic model such as gait2392 has a knee with one degree of freedom and a neutral frontal
alignment: with every coordinate at zero the tibia's long axis continues the femur's and the
tibia-frame origin lies on the femur's sagittal plane. A subject's knee — a total knee
replacement in particular — may sit in varus or valgus and be offset medio-laterally. Lerner ZF,
DeMers MS, Delp SL, Browning RC (2015) J Biomech 48:644–650 showed that the two-point split of
the tibiofemoral contact force into medial and lateral compartments depends on the
subject's tibiofemoral alignment and contact locations: the alignment decides where the knee
lies relative to the ground reaction force in the frontal plane.

:func:`with_knee_alignment` imposes a *given* alignment (from imaging, the implant's surgical
record or the subject's own model; never fitted to a measured contact force) on the knee
joint: the tibia body frame ``B`` of the aligned model is ::

    B = T(s) · J(θ) · R_x(±α)

with ``J(θ)`` the knee's own motion (spline, four-bar: unchanged), ``α`` the varus angle
(adduction of the tibia; valgus < 0) applied after flexion about the tibia's anterior axis,
as the ``knee_add`` coordinate of a six-DOF knee (e.g. OpenSim-JAM's ``knee_add_r``: rotation
about x after the flexion about z), and ``T(s)`` a translation by ``s`` medially in the femur
frame (as its ``knee_tz_r``, which is along the femur-frame z axis). Sides (OpenSim
conventions, body frames not mirrored: x anterior, y up, z to the right): on a **right** knee
varus is a rotation about +x and medial is −z; on a **left** knee varus is about −x and medial
is +z, so the two knees of a symmetric subject are mirror images.

Everything distal to the knee (tibia, foot, the muscle points and markers on them) moves with
the tibia; marker placement done afterwards places the lab markers on the aligned bodies.

:func:`knee_varus_from_markers` *estimates* the frontal alignment from the subject's own skin
markers: the frontal angle between the femoral mechanical axis (hip centre → knee centre, the
epicondyles' midpoint) and the tibial axis (knee centre → ankle centre, the malleoli's
midpoint), measured on the trial and on the scaled generic model with the same markers; their
difference is the subject's varus relative to the model (the hip–knee–ankle angle of Moreland
JR, Bassett LW, Hanker GJ (1987) J Bone Joint Surg Am 69:745–749, from markers instead of a
long-leg radiograph). Skin markers sit on soft tissue that slides over the epicondyles and
malleoli; frontal knee angles from skin markers are uncertain by several degrees (Benoit DL
et al. (2006) Gait Posture 24:152–164: 2–3° and more in gait; Leardini A et al. (2005) Gait
Posture 21:212–225), so the estimate is ±2–3° at best. A medio-lateral shift of the tibia
moves the malleoli, not the epicondyles: the markers see it as an angle (s / tibia length:
9.6 mm ≈ 1.3°) and cannot tell the two apart.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from msk.exceptions import MissingDataError, ModelError
from msk.model.core import Joint, Model, forward_kinematics

__all__ = [
    "MAX_FLEXION_FOR_ALIGNMENT_DEG",
    "MarkerAlignment",
    "frontal_knee_angle",
    "knee_side",
    "knee_varus_from_markers",
    "with_knee_alignment",
]

#: frames used by :func:`knee_varus_from_markers`: knee flexion (angle between the femoral and
#: tibial axes) at most this. The angle is defined on the extended leg, and the skin markers
#: slide more over the epicondyles as the knee flexes; 25° keeps a knee patient's standing
#: static (Grand Challenge PS stands at 17–18° by these axes) and gait's stance (loading
#: response peaks at 15–20° of flexion, Perry & Burnfield 2010 ch. 6), not its swing (60°)
MAX_FLEXION_FOR_ALIGNMENT_DEG = 25.0


def knee_side(joint: str) -> str:
    """``"right"`` / ``"left"`` from a knee joint's name suffix (``_r`` / ``_l``)."""
    low = joint.lower()
    if low.endswith(("_r", "_right")):
        return "right"
    if low.endswith(("_l", "_left")):
        return "left"
    raise ModelError(f"knee joint {joint!r}: cannot tell the side from its name")


def _rx(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def with_knee_alignment(
    model: Model,
    joint: str,
    *,
    varus_rad: float = 0.0,
    medial_shift_m: float = 0.0,
    side: str | None = None,
) -> Model:
    """A new model whose ``joint`` (a knee) carries the given frontal alignment (module
    docstring): the tibia in ``varus_rad`` of varus (negative: valgus) about its anterior axis
    after flexion, shifted ``medial_shift_m`` medially in the femur frame.

    ``side`` defaults to the joint name's suffix. A zero alignment returns ``model`` itself.
    Raises :class:`~msk.exceptions.ModelError` for an unknown joint, a side that cannot be
    told, or an alignment out of the physiological range (|α| ≤ 20°, |s| ≤ 30 mm).
    """
    spec = next((j for j in model.joints if j.name == joint), None)
    if spec is None:
        raise ModelError(f"model {model.name}: no joint {joint!r}")
    a, s = float(varus_rad), float(medial_shift_m)
    if not (np.isfinite(a) and abs(a) <= np.radians(20.0)):
        raise ModelError(f"knee {joint}: varus angle {np.degrees(a)!r}° outside ±20°")
    if not (np.isfinite(s) and abs(s) <= 0.03):
        raise ModelError(f"knee {joint}: medial shift {s!r} m outside ±0.03 m")
    if a == 0.0 and s == 0.0:
        return model
    sd = knee_side(joint) if side is None else side.lower()
    if sd in ("r", "right"):
        sign = 1.0  # right knee: varus about +x, medial is −z
    elif sd in ("l", "left"):
        sign = -1.0  # left knee: varus about −x, medial is +z
    else:
        raise ModelError(f"side must be 'right' or 'left', got {side!r}")
    po = pin.SE3(spec.parent_offset)
    co = pin.SE3(spec.child_offset)
    # T(s) in the femur frame: the parent offset's translation moves by −sign·s along its z
    po_new = pin.SE3(po.rotation, po.translation + po.rotation @ np.array([0.0, 0.0, -sign * s]))
    # B = J · child_offset⁻¹ (msk.model.core): B' = J · R_x(sign·α) · child_offset⁻¹
    co_new = (pin.SE3(_rx(sign * a), np.zeros(3)) * co.inverse()).inverse()
    aligned = Joint(
        spec.name, spec.parent, spec.child,
        parent_offset=po_new, child_offset=co_new, axes=spec.axes,
    )  # fmt: skip
    meta = dict(model.metadata.get("knee_alignment") or {})
    meta[joint] = {"varus_rad": a, "medial_shift_m": s, "side": "right" if sign > 0 else "left"}
    return model.with_joints({joint: aligned}).with_metadata(knee_alignment=meta)


def frontal_knee_angle(
    hip: np.ndarray,
    knee_lat: np.ndarray,
    knee_med: np.ndarray,
    ankle_lat: np.ndarray,
    ankle_med: np.ndarray,
) -> np.ndarray:
    """Varus angle (rad; valgus < 0) of a knee from its hip centre, epicondyles and malleoli
    (arrays (..., 3), any side): α = asin(u_f·l) − asin(u_t·l), with u_f the unit femoral
    mechanical axis (hip → epicondyle midpoint), u_t the unit tibial axis (epicondyle →
    malleolus midpoint) and l the unit lateral direction (medial → lateral epicondyle). Each
    term is the axis' inclination out of the plane normal to l; flexion about l changes
    neither, so the angle holds in flexed frames too (to the extent the flexion axis is l).
    A tibia pointing more medially than the femur (the knee lateral of the hip–ankle line):
    varus, α > 0."""
    h, kl, km, al, am = (
        np.asarray(v, dtype=float) for v in (hip, knee_lat, knee_med, ankle_lat, ankle_med)
    )
    k, a = 0.5 * (kl + km), 0.5 * (al + am)
    lat = kl - km
    lat = lat / np.linalg.norm(lat, axis=-1, keepdims=True)
    uf = (k - h) / np.linalg.norm(k - h, axis=-1, keepdims=True)
    ut = (a - k) / np.linalg.norm(a - k, axis=-1, keepdims=True)
    sf = np.clip(np.sum(uf * lat, axis=-1), -1.0, 1.0)
    st = np.clip(np.sum(ut * lat, axis=-1), -1.0, 1.0)
    return np.asarray(np.arcsin(sf) - np.arcsin(st))


@dataclass(frozen=True)
class MarkerAlignment:
    """A knee's frontal alignment estimated from skin markers (:func:`knee_varus_from_markers`).

    ``varus_rad``: the subject's varus relative to the model (``subject_rad − model_rad``;
    valgus < 0); ``subject_rad``: median over the frames used of the trial's angle;
    ``model_rad``: the scaled model's angle with its own markers in its default pose;
    ``iqr_rad``: interquartile range of the trial's angle over those frames; ``frames``:
    their number (knee flexion ≤ :data:`MAX_FLEXION_FOR_ALIGNMENT_DEG`, every marker and the
    hip centre measured)."""

    varus_rad: float
    subject_rad: float
    model_rad: float
    iqr_rad: float
    frames: int


_KNEE_ANKLE = ("Knee.Lat", "Knee.Med", "Ankle.Lat", "Ankle.Med")


def knee_varus_from_markers(
    model: Model,
    markers: np.ndarray,
    labels: Sequence[str],
    side: str,
    *,
    max_flexion_deg: float = MAX_FLEXION_FOR_ALIGNMENT_DEG,
    min_frames: int = 5,
) -> MarkerAlignment:
    """The ``side`` knee's varus relative to ``model`` from a trial's skin markers (module
    docstring): :func:`frontal_knee_angle` on the trial (the hip centre where the pelvis
    markers put the model's, :func:`msk.personalise.scaling.static_hip_centres`, frame by frame)
    minus the
    same angle of ``model`` with its own markers (``<S>.Knee.Lat/Med``, ``<S>.Ankle.Lat/Med``,
    gait2392's names; ``labels`` in model names) in its default pose. Use the model as scaled,
    before its markers are placed on the trial (placement would carry the subject's
    alignment into the model's markers).

    Frames: those with the four markers and the pelvis measured and the knee flexed at most
    ``max_flexion_deg`` (the angle between the two axes); the median over them.

    Raises:
        MissingDataError: fewer than ``min_frames`` such frames (e.g. a marker set without
            epicondyle or malleolus markers, as Grand Challenge DM's walks).
        ModelError: the model lacks one of those markers or the side's thigh and shank.
    """
    from msk.personalise.scaling import static_hip_centres

    sd = side.lower()[:1]
    if sd not in ("r", "l"):
        raise ModelError(f"side must be 'right' or 'left', got {side!r}")
    p = sd.upper()
    names = [f"{p}.{m}" for m in _KNEE_ANKLE]
    have = {mk.name: mk for mk in model.markers}
    missing = [n for n in names if n not in have]
    if missing or f"femur_{sd}" not in model.body_frame:
        raise ModelError(f"model {model.name}: no marker {missing[0] if missing else ''!r} "
                         f"or no femur_{sd} for the frontal knee angle")  # fmt: skip
    # the model's own angle: its markers and hip centre (femur origin), default pose
    data = model.create_data()
    forward_kinematics(model, data, model.default_coordinates())
    world = {
        n: np.asarray(data.oMf[model.body_frame[have[n].body]].act(np.asarray(have[n].offset)))
        for n in names
    }
    hip_m = np.asarray(data.oMf[model.body_frame[f"femur_{sd}"]].translation, dtype=float)
    model_rad = float(frontal_knee_angle(hip_m, *(world[n] for n in names)))
    # the trial's, frame by frame
    x = np.asarray(markers, dtype=float)
    labels = list(labels)
    idx = [labels.index(n) if n in labels else -1 for n in names]
    if min(idx) < 0:
        raise MissingDataError(
            f"knee alignment from markers: the trial has no {names[idx.index(-1)]!r}"
        )
    pts = x[:, idx]  # (F, 4, 3)
    ok = np.isfinite(pts).all(axis=(1, 2))
    angles: list[float] = []
    max_flex = np.radians(max_flexion_deg)
    for f in np.flatnonzero(ok):
        frame = {lab: x[f, i] for i, lab in enumerate(labels) if np.isfinite(x[f, i]).all()}
        hips = static_hip_centres(model, frame)
        if sd not in hips:
            continue
        kl, km, al, am = pts[f]
        k, a = 0.5 * (kl + km), 0.5 * (al + am)
        uf, ut = k - hips[sd], a - k
        cos = float(np.dot(uf, ut) / (np.linalg.norm(uf) * np.linalg.norm(ut)))
        if np.arccos(np.clip(cos, -1.0, 1.0)) > max_flex:
            continue
        angles.append(float(frontal_knee_angle(hips[sd], kl, km, al, am)))
    if len(angles) < min_frames:
        raise MissingDataError(
            f"knee alignment from markers: {len(angles)} frames with {', '.join(names)}, the "
            f"pelvis and the knee within {max_flexion_deg:g}° of extension (need {min_frames})"
        )
    arr = np.asarray(angles)
    q1, med, q3 = np.percentile(arr, [25.0, 50.0, 75.0])
    return MarkerAlignment(
        varus_rad=float(med - model_rad), subject_rad=float(med), model_rad=model_rad,
        iqr_rad=float(q3 - q1), frames=int(arr.size),
    )  # fmt: skip
