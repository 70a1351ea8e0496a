"""Lab frame → model frame: rotating a whole :class:`~msk.io.Trial`.

A C3D lab is usually Z-up with the walkway along ±x or ±y; an OpenSim model is Y-up with the
subject walking along +x. :func:`lab_to_model_rotation` builds the rotation ``R``
(``x_model = R x_lab``): the smallest rotation taking the lab vertical to the model's up
(Rodrigues), then a rotation about the vertical so that the horizontal progression of the
marker centroid (when longer than 0.3 m) points along the model's ``forward`` axis.
:func:`rotate_trial` (``Trial.rotated(R)``) applies ``R`` to everything that lives in the lab
frame, and :func:`to_model_frame` does both.

A rotation about the lab origin maps a point ``p`` to ``R p`` and a free vector (force,
moment) ``v`` to ``R v``; so a plate moment about its origin ``o`` stays the moment about the
rotated origin ``R o``: ``R (M_o) = R ((c − o) × F + T) = (R c − R o) × R F + R T``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import ShapeMismatchError

if TYPE_CHECKING:
    from msk.io.c3d import ForcePlate, Trial

Array = NDArray[np.float64]

__all__ = [
    "lab_to_model_rotation",
    "rotate_plate",
    "rotate_trial",
    "rotation_between",
    "to_model_frame",
]

#: horizontal progression (m) of the marker centroid below which no heading is applied
MIN_PROGRESSION_M = 0.3


def rotation_between(a: ArrayLike, b: ArrayLike) -> Array:
    """Smallest rotation taking the direction ``a`` to the direction ``b`` (Rodrigues):
    ``R = I + [v]× + [v]×² / (1 + c)`` with ``v = â × b̂``, ``c = â · b̂``; a half turn about
    an axis normal to ``a`` when they are opposite."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if a.shape != (3,) or b.shape != (3,) or not (np.linalg.norm(a) > 0 and np.linalg.norm(b) > 0):
        raise ShapeMismatchError(f"directions must be non-zero 3-vectors, got {a} and {b}")
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    v = np.cross(a, b)
    c = float(a @ b)
    if c < -1 + 1e-12:  # opposite: half turn about any axis normal to a
        n = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(n) < 1e-6:
            n = np.cross(a, [0.0, 1.0, 0.0])
        n /= np.linalg.norm(n)
        return 2 * np.outer(n, n) - np.eye(3)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1 + c)


def lab_to_model_rotation(
    up_lab: ArrayLike,
    up_model: ArrayLike,
    markers: Array | None = None,
    *,
    forward: ArrayLike = (1.0, 0.0, 0.0),
) -> Array:
    """Rotation R (x_model = R x_lab): lab up → model up, then about the vertical so that the
    horizontal progression of the marker centroid (when > 0.3 m) points along ``forward``
    (projected on the model's floor plane). ``markers`` (N, M, 3) lab frame, NaN gaps."""
    u = np.asarray(up_model, dtype=float)
    r = rotation_between(up_lab, u)
    if markers is None or markers.size == 0:
        return r
    rotated = markers @ r.T
    seen = np.isfinite(rotated).all(axis=2)  # (N, M): markers visible in each frame
    count = seen.sum(axis=1)
    total = np.where(seen[..., None], rotated, 0.0).sum(axis=1)
    ok = count > 0  # frames with no marker at all carry no centroid
    c = total[ok] / count[ok, None]
    if c.shape[0] < 2:
        return r
    d = c[-1] - c[0]
    u = u / np.linalg.norm(u)
    d = d - (d @ u) * u
    if np.linalg.norm(d) < MIN_PROGRESSION_M:
        return r
    x = np.asarray(forward, dtype=float)
    x = x - (x @ u) * u
    d, x = d / np.linalg.norm(d), x / np.linalg.norm(x)
    phi = math.atan2(float(u @ np.cross(d, x)), float(d @ x))  # about the vertical u
    k = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    heading = np.eye(3) + math.sin(phi) * k + (1 - math.cos(phi)) * k @ k
    return heading @ r


def _check_rotation(r: ArrayLike, what: str) -> Array:
    r = np.asarray(r, dtype=float)
    if r.shape != (3, 3):
        raise ShapeMismatchError(f"{what}: rotation has shape {r.shape}, expected (3, 3)")
    if not np.allclose(r @ r.T, np.eye(3), atol=1e-9) or np.linalg.det(r) < 0:
        raise ShapeMismatchError(
            f"{what}: not a proper rotation matrix (det {np.linalg.det(r):.6g})"
        )
    return r


def rotate_plate(plate: ForcePlate, rotation: ArrayLike) -> ForcePlate:
    """A :class:`~msk.io.ForcePlate` in the rotated frame: force, moment (about the rotated
    origin), COP, free moment, corners and origin rotated; the plate axes become ``R @ axes``."""
    r = _check_rotation(rotation, f"force plate {plate.index + 1}")
    return dataclasses.replace(
        plate,
        force=plate.force @ r.T,
        moment=plate.moment @ r.T,
        cop=plate.cop @ r.T,
        free_moment=plate.free_moment @ r.T,
        corners=plate.corners @ r.T,
        origin=np.asarray(plate.origin, dtype=float) @ r.T,
        rotation=r @ plate.rotation,
    )


def rotate_trial(trial: Trial, rotation: ArrayLike) -> Trial:
    """``trial`` with everything that lives in the lab frame rotated by R (about the lab
    origin): markers, force plates (:func:`rotate_plate`) and ``up``; ``vertical_axis`` becomes
    the axis nearest the new up. Model outputs (Plug-in Gait angles, forces, moments, powers)
    are expressed in segment / joint frames, which a rotation of the lab does not change, so
    they are kept. ``metadata["lab_to_model_rotation"]`` accumulates R."""
    r = _check_rotation(rotation, str(trial.path))
    up = r @ np.asarray(trial.up, dtype=float)
    meta = dict(trial.metadata)
    prev = np.asarray(meta.get("lab_to_model_rotation", np.eye(3)), dtype=float)
    meta["lab_to_model_rotation"] = r @ prev
    return dataclasses.replace(
        trial,
        markers=trial.markers @ r.T,
        plates=tuple(rotate_plate(p, r) for p in trial.plates),
        up=up,
        vertical_axis=int(np.argmax(np.abs(up))),
        metadata=meta,
    )


def to_model_frame(
    trial: Trial,
    *,
    up: ArrayLike = (0.0, 1.0, 0.0),
    forward: ArrayLike | None = (1.0, 0.0, 0.0),
) -> Trial:
    """``trial`` rotated into a model frame whose vertical is ``up`` (−gravity; OpenSim: +y)
    and, when ``forward`` is given and the subject progresses more than 0.3 m, whose walking
    direction is ``forward`` (OpenSim: +x). The rotation is in
    ``metadata["lab_to_model_rotation"]``."""
    if forward is None:
        r = lab_to_model_rotation(trial.up, up)
    else:
        r = lab_to_model_rotation(trial.up, up, trial.markers, forward=forward)
    return rotate_trial(trial, r)
