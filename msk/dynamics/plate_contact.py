"""A plate that reads nothing while a foot stands on it: dead, disconnected or mis-assigned.

:func:`msk.dynamics.loads.foot_contact` finds the frames in which a foot stands still on a surface
(the floor, a plate's surface) without carrying a plate load. Beside a walkway's plates that
is the floor; but when the foot's floor projection lies inside a plate's outline, the plate
should be loaded — a plate that reads (almost) nothing there is dead (unplugged amplifier,
disconnected cable, a channel map pointing elsewhere), and that foot's ground reaction is
missing from the loads. :func:`dead_plates` reports each such plate with the time the foot
stood on it and the largest force it read meanwhile.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["dead_plates"]


def _plane_axes(up: NDArray[np.float64]) -> NDArray[np.float64]:
    """Two unit vectors spanning the plane normal to ``up`` (3, 2)."""
    a = np.eye(3)[int(np.argmin(np.abs(up)))]
    e1 = np.cross(up, a)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(up, e1)
    return np.column_stack([e1, e2])


def _inside(points: NDArray[np.float64], poly: NDArray[np.float64], margin: float) -> NDArray[Any]:
    """Each 2-D point (n, 2) inside the convex polygon (4, 2) shrunk by ``margin``."""
    centre = poly.mean(axis=0)
    ok = np.ones(points.shape[0], dtype=bool)
    for k in range(poly.shape[0]):
        a, b = poly[k], poly[(k + 1) % poly.shape[0]]
        edge = b - a
        normal = np.array([edge[1], -edge[0]]) / np.linalg.norm(edge)
        if (centre - a) @ normal > 0:
            normal = -normal  # outward
        ok &= (points - a) @ normal <= -margin
    return ok


def dead_plates(
    model: Any,
    kinematics: Any,
    contact: Any,
    plates: Iterable[Any],
    *,
    max_force_n: float = 20.0,
    margin_m: float = 0.02,
    min_s: float = 0.1,
) -> list[dict[str, Any]]:
    """Plates (model frame, :class:`msk.dynamics.loads.PlateWrench`: ``name``, ``time``, ``force``,
    ``corners``) under a foot that stands on an
    unmeasured surface (``contact``: :class:`msk.dynamics.loads.FootContact`) for ``min_s`` or
    longer —
    its floor projection (the median of the foot's points) at least ``margin_m`` inside the
    plate's outline — while the plate's force stays below ``max_force_n``. One record per
    plate: ``plate`` (its name), ``foot``, ``seconds``, ``start_s``, ``end_s``,
    ``max_force_n``."""
    from msk.dynamics.loads import _foot_points

    standing = np.asarray(contact.standing(), dtype=bool)
    if not standing.any():
        return []
    t = np.asarray(kinematics.time, dtype=float)
    q = np.asarray(kinematics.q, dtype=float)
    g = np.asarray(model.gravity, dtype=float)
    up = -g / np.linalg.norm(g) if np.linalg.norm(g) > 0 else np.array([0.0, 1.0, 0.0])
    axes = _plane_axes(up)
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    feet = list(contact.feet)
    where: dict[str, NDArray[np.float64]] = {}
    for k, foot in enumerate(feet):
        frames = np.flatnonzero(standing[:, k])
        if frames.size == 0:
            continue
        (pts,) = _foot_points(model, q, [foot], frames)
        with warnings.catch_warnings():  # a frame of unknown pose: all NaN, skipped below
            warnings.simplefilter("ignore", RuntimeWarning)
            xy = np.full((t.size, 2), np.nan)
            xy[frames] = np.nanmedian(pts[frames], axis=1) @ axes
        where[foot] = xy
    out = []
    for p in plates:
        if p.corners is None:
            continue
        corners = np.asarray(p.corners, dtype=float)
        if corners.shape != (4, 3) or not np.isfinite(corners).all():
            continue
        poly = corners @ axes
        load_t = np.asarray(p.time, dtype=float)
        force = np.linalg.norm(np.nan_to_num(np.asarray(p.force, dtype=float)), axis=1)
        for foot, xy in where.items():
            ok = np.isfinite(xy).all(axis=1)
            on = np.zeros(t.size, dtype=bool)
            on[ok] = _inside(xy[ok], poly, margin_m)
            if on.sum() * dt < min_s:
                continue
            span = (float(t[on][0]), float(t[on][-1]))
            sel = (load_t >= span[0] - dt) & (load_t <= span[1] + dt)
            peak = float(force[sel].max()) if sel.any() else 0.0
            if peak < max_force_n:
                out.append(
                    {"plate": str(p.name), "foot": foot, "seconds": float(on.sum() * dt),
                     "start_s": span[0], "end_s": span[1], "max_force_n": peak}
                )  # fmt: skip
    return out
