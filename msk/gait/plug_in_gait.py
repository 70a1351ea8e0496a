"""Knee flexion as Plug-in Gait measures it, from Plug-in Gait's own knee and ankle centres, for
the report's angles only (``[gait] angle_convention = "plug_in_gait"``; the model's dynamics
keep the model's joints).

Plug-in Gait's knee centre K is its "chord function" of the hip centre H, the thigh wand THI
and the lateral knee marker KNE (Davis et al. 1991, Hum Mov Sci 10:575-587; Vicon Plug-in Gait
reference guide): K in the plane (H, THI, KNE), ‖K − KNE‖ = r_K = (knee width + marker
diameter)/2, the angle H–K–KNE a right angle; its ankle centre A the same function of K, TIB
and ANK with r_A = (ankle width + marker diameter)/2 (:func:`chord_centres`). Its knee flexion
is the first angle of the YXZ Cardan sequence of the tibia relative to the femur (Vicon, Nexus
2.10 "Angle outputs"): the angle between the thigh axis H − K and the shank axis K − A, both
projected onto the femur's sagittal plane, whose normal is the femur's lateral axis ŷ (K → KNE,
orthogonal to the thigh axis):

    flexion = s atan2(((v × u) · ŷ), u · v),  u = P(H − K), v = P(K − A), P = I − ŷŷᵀ,

s = +1 right, −1 left (ŷ points to the subject's left on the left leg). Reproduces Vicon's
stored ``<S>KneeAngles`` X from its stored centres (``<S>FEP``, ``<S>FEO``, ``<S>TIO``) to 0.00°
(PiG_Motion3_FF) and 0.05° (PlugInC3D) (:func:`knee_flexion`).

Here H is the model's hip centre (the femur origin) as inverse kinematics poses it, and the
markers are the trial's. The widths are the lab's where the file has them (Vicon
``PROCESSING:RKneeWidth``…, :attr:`msk.trial.Subject.widths_m`; marker diameter
``PROCESSING:MarkerDiameter``, else Vicon's default 14 mm). Without a measured knee width, r_K
is the median distance of KNE from the model's knee centre over the trial (the model's own knee
half-width: the chord then moves the centre into the wand's plane, the antero-posterior part of
Plug-in Gait's centre); without a measured ankle width, A is the model's ankle centre (the talus
origin). gait2392's knee centre sits 14-22 mm anterior of Plug-in Gait's in the femur
(docs/validation.md), which makes its ``knee_angle`` 5-6° more flexed than Plug-in Gait's.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pinocchio as pin

from msk.units import Array

__all__ = [
    "PIG_MARKER_DIAMETER_M",
    "chord_centres",
    "knee_flexion",
    "plug_in_gait_knee_flexion",
]

#: Vicon's default marker diameter, m (Plug-in Gait's ``MarkerDiameter``)
PIG_MARKER_DIAMETER_M = 0.014
_SFX = {"right": "_r", "left": "_l"}
_SIGN = {"right": 1.0, "left": -1.0}


def chord_centres(proximal: Array, wand: Array, lateral: Array, r: float) -> Array:
    """(N, 3) Plug-in Gait's chord function per frame (module docstring): the point J at
    ``r`` from ``lateral`` with the angle proximal–J–lateral a right angle, in the plane of the
    three points, on the side of the line proximal–lateral away from ``wand``
    (:func:`msk.personalise.scaling.chord_joint_centre`, one frame). NaN where an input is."""
    p, w_, lat = (np.asarray(v, dtype=float) for v in (proximal, wand, lateral))
    d = p - lat
    length = np.linalg.norm(d, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = d / length
        w = (w_ - lat) - np.sum((w_ - lat) * u, axis=1, keepdims=True) * u
        w = w / np.linalg.norm(w, axis=1, keepdims=True)
        cb = np.minimum(r / length, 1.0)
    return lat + r * (cb * u - np.sqrt(1.0 - cb * cb) * w)


def knee_flexion(hip: Array, knee: Array, ankle: Array, lateral: Array, side: str) -> Array:
    """(N,) knee flexion (deg, flexion +) of the hip, knee and ankle centres with the femur's
    lateral axis toward the ``lateral`` knee marker (module docstring)."""
    h, k, a, lat = (np.asarray(v, dtype=float) for v in (hip, knee, ankle, lateral))
    with np.errstate(invalid="ignore", divide="ignore"):
        z = (h - k) / np.linalg.norm(h - k, axis=1, keepdims=True)
        y = (lat - k) - np.sum((lat - k) * z, axis=1, keepdims=True) * z
        y = y / np.linalg.norm(y, axis=1, keepdims=True)
        u = (h - k) - np.sum((h - k) * y, axis=1, keepdims=True) * y
        v = (k - a) - np.sum((k - a) * y, axis=1, keepdims=True) * y
        ang = np.arctan2(np.sum(np.cross(v, u) * y, axis=1), np.sum(u * v, axis=1))
    return _SIGN[side] * np.rad2deg(ang)


def _child_of(model: Any, coord: str) -> str | None:
    for j in model.joints:
        if any(ax.coordinate == coord and ax.kind == "revolute" for ax in j.axes):
            return str(j.child) if j.child in model.body_frame else None
    return None


def _marker(trial: Any, side: str, landmark: str, time: Array) -> Array | None:
    """(len(time), 3) the trial's marker of ``side`` ("R"/"L") and ``landmark`` at ``time``
    (linear interpolation; NaN outside the trial and in its gaps)."""
    from msk.model.markersets import parse_label

    for lab in trial.marker_labels:
        p = parse_label(lab)
        if p.side == side and p.landmark == landmark and p.kind == "landmark":
            x = np.asarray(trial.marker(lab), dtype=float)
            t = np.asarray(trial.time, dtype=float)
            return np.column_stack(
                [np.interp(time, t, x[:, c], left=np.nan, right=np.nan) for c in range(3)]
            )
    return None


def plug_in_gait_knee_flexion(
    model: Any, kinematics: Any, trial: Any, side: str
) -> tuple[Array | None, str]:
    """(N,) knee flexion of ``side`` as Plug-in Gait measures it on the model's hip centre and
    Plug-in Gait's knee and ankle centres (module docstring), and how they were placed; None
    and why when the trial lacks the thigh wand and lateral knee marker or the model the joints
    (``hip_flexion_<s>``, ``knee_angle_<s>``, ``ankle_angle_<s>``)."""
    sfx, p = _SFX[side], side[0].upper()
    joints = (("hip", "hip_flexion"), ("knee", "knee_angle"), ("ankle", "ankle_angle"))
    bodies = {k: _child_of(model, c + sfx) for k, c in joints}
    if any(b is None for b in bodies.values()):
        return None, "the model has no hip, knee and ankle joints named as gait2392's"
    t = np.asarray(kinematics.time, dtype=float)
    mk = {lm: _marker(trial, p, lm, t) for lm in
          ("thigh_cluster", "knee_lat", "shank_cluster", "ankle_lat")}  # fmt: skip
    if mk["thigh_cluster"] is None or mk["knee_lat"] is None:
        return None, f"no {p} thigh wand and lateral knee marker in the trial"
    q = np.asarray(kinematics.q, dtype=float)
    n = q.shape[0]
    centre = {k: np.full((n, 3), np.nan) for k in bodies}
    good = np.flatnonzero(np.isfinite(q).all(axis=1))
    data = model.create_data()
    frames = {k: model.body_frame[b] for k, b in bodies.items()}
    if good.size:
        qp = model.coupling.q(q[good])
        for k, i in enumerate(good):
            pin.framesForwardKinematics(model.pin_model, data, qp[k])
            for name, f in frames.items():
                centre[name][i] = data.oMf[f].translation
    subject = getattr(trial, "subject", None)
    widths: Mapping[str, float] = getattr(subject, "widths_m", None) or {}
    md = getattr(subject, "marker_diameter_m", None) or PIG_MARKER_DIAMETER_M
    kne = mk["knee_lat"]
    if f"{p}.knee" in widths:
        r_k = 0.5 * (widths[f"{p}.knee"] + md)
        how = f"knee width {1000 * widths[f'{p}.knee']:.0f} mm (the file's)"
    else:
        dist = np.linalg.norm(kne - centre["knee"], axis=1)
        if not np.isfinite(dist).any():
            return None, f"{p} lateral knee marker never seen with the model posed"
        r_k = float(np.nanmedian(dist))
        how = f"r {1000 * r_k:.0f} mm, the lateral knee marker's median distance from the model's"
    knee = chord_centres(centre["hip"], mk["thigh_cluster"], kne, r_k)
    if f"{p}.ankle" in widths and mk["shank_cluster"] is not None and mk["ankle_lat"] is not None:
        r_a = 0.5 * (widths[f"{p}.ankle"] + md)
        ankle = chord_centres(knee, mk["shank_cluster"], mk["ankle_lat"], r_a)
        how_a = f"ankle by the chord, width {1000 * widths[f'{p}.ankle']:.0f} mm"
    else:
        ankle = centre["ankle"]
        how_a = "the model's ankle centre"
    return knee_flexion(centre["hip"], knee, ankle, kne, side), (
        f"Plug-in Gait's knee centre (chord of the model's hip centre and the thigh wand, {how}"
        f"), {how_a}; the model's dynamics keep its own knee"
    )
