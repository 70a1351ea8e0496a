"""A foot measured by a plate only when its whole footprint is on the plate.

A force plate measures the load of what stands on it. A foot whose heel is on the plate and
whose toes are past its edge (on the floor, or on the next plate) puts part of its ground
reaction where the plate does not measure it: the plate's wrench is not the foot's, and the
centre of pressure — the plate's, inside the plate — does not show it. :func:`plate_edge_frames`
judges it from the foot's position against the plate's outline (corners): in a frame of a
plate contact assigned to a foot, the foot's points near the plate surface (within
``surface_m`` of it: origins of the foot's bodies and their markers, the points
:func:`msk.dynamics.loads.external_loads` uses) are projected on the floor; a point farther than
``outside_m`` outside the outline means the foot straddles the edge there. Those frames are
to be counted as an unmeasured contact of that foot, like a foot on the floor beside the plates.

Plates without corners (a GRF file's) are not judged, nor raised ones
(:func:`floor_level_plates`): a step or platform standing on a plate passes all of its load to
the plate wherever the foot stands on it, and beyond a raised surface's edge there is nothing to
stand on.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "RAISED_PLATE_M",
    "exclude_plate_edges",
    "floor_level_plates",
    "plate_edge_frames",
]

Array = NDArray[np.float64]


def plate_edge_frames(
    model: Any,
    kinematics: Any,
    assignments: Sequence[Any],
    corners: Mapping[str, ArrayLike],
    up: ArrayLike,
    feet: Sequence[str],
    *,
    surface_m: float = 0.04,
    outside_m: float = 0.01,
) -> tuple[NDArray[np.bool_], list[dict[str, Any]]]:
    """(N, F) frames in which foot ``feet[f]`` straddles the edge of the plate its contact is
    assigned to (``assignments``: :class:`msk.dynamics.loads.Assignment`; ``corners``: plate name →
    (4, 3) m in the kinematics' frame; ``up`` the model's up), and one record per plate contact
    that straddles (plate, foot, first and last straddling time, frames, the farthest point
    outside in m)."""
    from msk.dynamics.loads import _foot_points, _horizontal_axes, outside_distance

    t = np.asarray(kinematics.time, dtype=float)
    q = np.asarray(kinematics.q, dtype=float)
    u = np.asarray(up, dtype=float)
    u = u / np.linalg.norm(u)
    ax = _horizontal_axes(u)
    out = np.zeros((t.size, len(feet)), dtype=bool)
    records: list[dict[str, Any]] = []
    for a in assignments:
        if a.body not in feet or a.plate not in corners:
            continue
        c = np.asarray(corners[a.plate], dtype=float)
        if c.shape != (4, 3) or not np.isfinite(c).all():
            continue
        sel = np.flatnonzero((t >= a.start_time - 1e-9) & (t <= a.end_time + 1e-9))
        if sel.size == 0:
            continue
        pts = _foot_points(model, q, [a.body], sel)[0][sel]  # (K, P, 3)
        height = float(np.mean(c @ u))
        low = np.abs(pts @ u - height) <= surface_m
        d = outside_distance(pts @ ax.T, c @ ax.T)
        d = np.where(low & np.isfinite(d), d, -np.inf).max(axis=1)
        bad = d > outside_m
        if not bad.any():
            continue
        f = list(feet).index(a.body)
        out[sel[bad], f] = True
        records.append({
            "plate": a.plate, "foot": a.body, "start_s": float(t[sel[bad][0]]),
            "end_s": float(t[sel[bad][-1]]), "frames": int(bad.sum()),
            "max_outside_m": float(d[bad].max()),
        })  # fmt: skip
    return out, records


def exclude_plate_edges(
    model: Any, kinematics: Any, external: Any, contact: Any, corners: Mapping[str, Any]
) -> tuple[Any, Any]:
    """``contact`` (:class:`msk.dynamics.loads.FootContact`) with the frames in which a foot
    straddles the edge of the floor-level plate it is assigned to (:func:`plate_edge_frames`,
    :func:`floor_level_plates`; ``corners`` plate name → (4, 3) corners at the plate's standing
    surface in the model frame) counted as unmeasured for that foot, and ``external`` with
    those runs recorded in its metadata (``plate_edge``); both unchanged when no foot straddles
    an edge."""
    up = -np.asarray(model.gravity, dtype=float)
    floor = floor_level_plates(corners, up)
    corners = {name: c for name, c in corners.items() if name in floor}
    if not corners or not contact.feet:
        return contact, external
    edge, records = plate_edge_frames(
        model, kinematics, external.assignments, corners, up, contact.feet
    )
    if not records:
        return contact, external
    return (
        dataclasses.replace(contact, unmeasured=contact.unmeasured | edge),
        dataclasses.replace(external, metadata={**external.metadata, "plate_edge": records}),
    )


#: a plate whose standing surface is higher than the lowest plate's by more than this carries a
#: step or platform (m)
RAISED_PLATE_M = 0.05


def floor_level_plates(
    corners: Mapping[str, ArrayLike], up: ArrayLike, *, raised_m: float = RAISED_PLATE_M
) -> set[str]:
    """The plates of ``corners`` (plate name → (4, 3) corners at the plate's standing surface,
    m) whose surface lies within ``raised_m`` of the lowest plate's along ``up``: the plates
    a foot can straddle onto the floor."""
    u = np.asarray(up, dtype=float)
    u = u / np.linalg.norm(u)
    heights = {name: float(np.mean(np.asarray(c, dtype=float) @ u)) for name, c in corners.items()}
    if not heights:
        return set()
    floor = min(heights.values())
    return {name for name, h in heights.items() if h <= floor + raised_m}
