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
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from msk.exceptions import ModelError
from msk.model import Joint, Model

__all__ = ["knee_side", "with_knee_alignment"]


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
    # B = J · child_offset⁻¹ (msk.model): B' = J · R_x(sign·α) · child_offset⁻¹
    co_new = (pin.SE3(_rx(sign * a), np.zeros(3)) * co.inverse()).inverse()
    aligned = Joint(
        spec.name, spec.parent, spec.child,
        parent_offset=po_new, child_offset=co_new, axes=spec.axes,
    )  # fmt: skip
    meta = dict(model.metadata.get("knee_alignment") or {})
    meta[joint] = {"varus_rad": a, "medial_shift_m": s, "side": "right" if sign > 0 else "left"}
    return model.with_joints({joint: aligned}).with_metadata(knee_alignment=meta)
