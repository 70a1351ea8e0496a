"""Where a plate's load is applied and what it reads unloaded: steps and platforms standing on
force plates, plate offsets, plates to leave out.

A lab stores a plate's corners at the plate's own top, usually the floor; a stair step or a
platform built on the plate raises the surface the foot stands on by its height ``H`` (0.2–0.7 m)
without changing the file. The plate still measures the whole wrench of the foot standing on the
step (the step is rigid and rests on the plate only), so the wrench f_O = (F, M_O) is right; what
the corners' height gets wrong is the surface: the test "a foot stands on the plate" (its
lowest point within ``floor_m`` of the surface, :mod:`msk.dynamics.loads`) fails for every frame
and the contact is left unassigned, and the centre of pressure is put on the wrong plane
(c = h·u + u × M_h / F_u: the point where the line of action meets the plane at height h).

**Surface from the feet** (:func:`surface_from_feet`). Over the plate's loaded frames (vertical
force above twice the contact threshold), the foot whose floor projection lies inside the plate
outline grown by ``margin_m`` and is nearest the centre of pressure bears the load; its sole
height s_t is its lowest point's height along u (the origins of the foot bodies and their
markers, :func:`msk.dynamics.loads._foot_points`). When the median of s_t over those frames is
more than ``floor_m`` above the corners' height h_c and the foot stands within ``floor_m`` of
h_c in fewer than :data:`AT_CORNERS_MAX` of those frames (it never stood on the plate's own top:
a stance foot posed higher and higher by a leg scaled too long did), the surface is

    h_s = median_t(s_t) − c_s

with ``c_s`` the clearance of the lowest foot point above the surface it stands on, measured in
the same trial on the plates whose corners are their surface (median of s_t − h_c there): of the
foot that bears the raised plate's load if it stood on such a plate, else of every foot, 0 when
no such plate was loaded. The median is robust to the frames of heel strike and toe-off, when
the foot nearest the COP is rolling on a point. A foot never above the outline, or a plate
never loaded, keeps the corners' height.

**Offset** (:func:`plate_baseline`). A plate that reads a steady force with nothing on it (e.g.
30 N: an amplifier not zeroed before the trial) is in contact for the whole trial with a 20 N
threshold. Its quiet level is found in 0.1-s windows of the analog signal: windows whose vertical
force has a standard deviation under ``quiet_sd_n`` and whose mean is under ``max_offset_n`` in
magnitude; the quiet level F_0 (per axis) is the median of the windows within ``quiet_sd_n``
of the one nearest zero (the lowest steady level: the unloaded plate), kept when those windows
last ``min_quiet_s`` and |F_0·u| ≥ the contact threshold (a smaller offset makes no contact of
its own and is left alone: the Grand Challenge DM crouch treadmill's right belt reads 13 N in
swing). F_0 is removed from every sample with its moment about the plate centre
p_c: F' = F − F_0, M_O' = M_O − p_c × F_0, and the COP and free moment are those of the
corrected wrench on the corners' plane.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from msk.units import Array

__all__ = [
    "AT_CORNERS_MAX",
    "PlateBaseline",
    "PlateSurface",
    "plate_baseline",
    "prepared_plates",
    "surface_from_feet",
    "without_baseline",
]


#: largest share of a plate's loaded frames in which the foot bearing it stands at the corners'
#: height for the plate to be taken as raised (a foot landing on a step never stands at the
#: plate's own top; a stance foot whose pose drifts up off a floor plate, a leg scaled too
#: long, did before it drifted)
AT_CORNERS_MAX = 0.1


@dataclass(frozen=True)
class PlateSurface:
    """The surface a plate's load is applied on: ``height_m`` along the model's up,
    ``corners_height_m`` the height of its corners, and ``source``: ``"corners"`` (the file's),
    ``"feet"`` (inferred from the feet standing on it, :func:`surface_from_feet`; ``frames`` the
    loaded frames it used, ``clearance_m`` the lowest foot point's clearance subtracted) or
    ``"config"`` (``[loads] surface_height_m``)."""

    plate: str
    height_m: float
    corners_height_m: float
    source: str
    frames: int = 0
    clearance_m: float = 0.0

    def as_dict(self) -> dict[str, Any]:
        """The surface as summary.json states it."""
        return {
            "plate": self.plate,
            "height_m": self.height_m,
            "corners_height_m": self.corners_height_m,
            "above_corners_m": self.height_m - self.corners_height_m,
            "source": self.source,
            "frames": self.frames,
            "clearance_m": self.clearance_m,
        }


def _sole_heights(
    cop: Array,
    contact: NDArray[np.bool_],
    corners: Array | None,
    fpts: Sequence[Array],
    up: Array,
    hz: Array,
    margin_m: float,
) -> tuple[Array, Array]:
    """(K,) the lowest point's height of the foot over the outline nearest the COP, at the
    ``contact`` frames (NaN where no foot is over the outline), and (K,) that foot's index
    (-1)."""
    from msk.dynamics.loads import _inside_grown

    k = np.flatnonzero(contact)
    out = np.full(k.size, np.nan)
    which = np.full(k.size, -1)
    if k.size == 0 or corners is None:
        return out, which
    poly = np.asarray(corners, dtype=float) @ hz.T
    c2 = cop[k] @ hz.T
    best = np.full(k.size, np.inf)
    for f, pts in enumerate(fpts):
        x = pts[k]
        with np.errstate(invalid="ignore"):
            p2 = x @ hz.T
            inside = _inside_grown(p2, poly, margin_m).any(axis=1)
            d = np.linalg.norm(p2 - c2[:, None, :], axis=2)
            d = np.where(np.isfinite(d), d, np.inf).min(axis=1)
            low = np.where(np.isfinite(x).all(axis=2), x @ up, np.inf).min(axis=1)
        take = inside & (d < best) & np.isfinite(low)
        out[take] = low[take]
        which[take] = f
        best[take] = d[take]
    return out, which


def surface_from_feet(
    plates: Sequence[Any],
    fpts: Sequence[Array],
    up: Array,
    *,
    threshold_n: float,
    margin_m: float = 0.05,
    floor_m: float = 0.10,
    given: Mapping[str, float] | None = None,
) -> list[PlateSurface]:
    """The surface of each plate (module docstring): ``plates`` as
    :func:`msk.dynamics.loads.external_loads` prepares them (``name``, ``corners``, ``cop`` on
    the corners' plane, ``fv_recorded``, ``height``: the corners' height), ``fpts`` the feet's
    points [(N, P_f, 3)], ``given`` plate name → surface height above its corners (config)."""
    from msk.dynamics.loads import _horizontal_axes

    given = dict(given or {})
    hz = _horizontal_axes(up)
    soles: dict[str, tuple[Array, Array]] = {}
    for p in plates:
        loaded = np.asarray(p.fv_recorded) > 2.0 * threshold_n
        soles[p.name] = _sole_heights(p.cop, loaded, p.corners, fpts, up, hz, margin_m)
    # the clearance of each foot's lowest point over a surface, from the plates at their
    # corners (that foot's, else every foot's)
    gaps: dict[int, list[Array]] = {}
    for p in plates:
        s, which = soles[p.name]
        ok = np.isfinite(s)
        if p.name in given or not ok.any() or abs(float(np.median(s[ok])) - p.height) > floor_m:
            continue
        for f in np.unique(which[ok]).tolist():
            gaps.setdefault(int(f), []).append(s[ok & (which == f)] - p.height)
    every = [g for v in gaps.values() for g in v]
    clear_all = float(np.median(np.concatenate(every))) if every else 0.0
    clear = {f: float(np.median(np.concatenate(v))) for f, v in gaps.items()}
    out = []
    for p in plates:
        h_c = float(p.height)
        if p.name in given:
            out.append(PlateSurface(p.name, h_c + float(given[p.name]), h_c, "config"))
            continue
        s, which = soles[p.name]
        ok = np.isfinite(s)
        at_corners = float(np.mean(np.abs(s[ok] - h_c) <= floor_m)) if ok.any() else 1.0
        if ok.any() and float(np.median(s[ok])) - h_c > floor_m and at_corners < AT_CORNERS_MAX:
            # the foot that bears most of the loaded frames, and its clearance
            f = int(np.bincount(which[ok]).argmax())
            c = clear.get(f, clear_all)
            out.append(PlateSurface(p.name, float(np.median(s[ok])) - c, h_c, "feet",
                                    int(ok.sum()), c))  # fmt: skip
        else:
            out.append(PlateSurface(p.name, h_c, h_c, "corners"))
    return out


@dataclass(frozen=True)
class PlateBaseline:
    """A plate's steady unloaded reading ``force_n`` (3,) N removed (:func:`plate_baseline`),
    over ``quiet_s`` seconds of quiet windows."""

    plate: str
    force_n: Array
    quiet_s: float

    def as_dict(self) -> dict[str, Any]:
        """The offset as summary.json states it."""
        return {
            "plate": self.plate,
            "force_n": [float(x) for x in self.force_n],
            "quiet_s": self.quiet_s,
        }


def plate_baseline(
    plate: Any,
    up: Array,
    *,
    threshold_n: float = 20.0,
    window_s: float = 0.1,
    quiet_sd_n: float = 5.0,
    max_offset_n: float = 100.0,
    min_quiet_s: float = 0.2,
) -> PlateBaseline | None:
    """The plate's steady offset (module docstring), or ``None`` (none to remove)."""
    t = np.asarray(plate.time, dtype=float)
    f = np.asarray(plate.force, dtype=float)
    if t.size < 4:
        return None
    rate = (t.size - 1) / (t[-1] - t[0])
    w = max(round(float(window_s * rate)), 2)
    nw = t.size // w
    if nw == 0:
        return None
    fw = f[: nw * w].reshape(nw, w, 3)
    ok = np.isfinite(fw).all(axis=(1, 2))
    fw = fw[ok]
    if fw.shape[0] == 0:
        return None
    fv = fw @ np.asarray(up, dtype=float)
    sd = fv.std(axis=1)
    mean_v = fv.mean(axis=1)
    quiet = (sd < quiet_sd_n) & (np.abs(mean_v) <= max_offset_n)
    if not quiet.any():
        return None
    lowest = mean_v[quiet][np.argmin(np.abs(mean_v[quiet]))]
    level = quiet & (np.abs(mean_v - lowest) <= quiet_sd_n)
    quiet_s = float(level.sum() * w / rate)
    if quiet_s < min_quiet_s:
        return None
    f0 = np.median(fw[level].mean(axis=1), axis=0)
    if abs(float(f0 @ up)) < threshold_n:
        return None
    return PlateBaseline(plate.name, f0, quiet_s)


def without_baseline(plate: Any, baseline: PlateBaseline, up: Array) -> Any:
    """The plate with ``baseline`` removed: F' = F − F_0, M_O' = M_O − p_c × F_0 (p_c the plate
    centre), the COP and free moment of that wrench on the corners' plane (module
    docstring). A plate without corners takes p_c at its median COP."""
    up = np.asarray(up, dtype=float)
    f0 = np.asarray(baseline.force_n, dtype=float)
    if plate.corners is not None:
        centre = np.asarray(plate.corners, dtype=float).mean(axis=0)
    else:
        cop = np.asarray(plate.cop, dtype=float)
        good = np.isfinite(cop).all(axis=1)
        centre = np.median(cop[good], axis=0) if good.any() else np.zeros(3)
    h = float(centre @ up)
    f = np.asarray(plate.force, dtype=float) - f0
    m = plate.moment_about_origin() - np.cross(centre, f0)
    fv = f @ up
    with np.errstate(divide="ignore", invalid="ignore"):
        m_h = m - np.cross(h * up, f)
        cop = h * up + np.cross(up, m_h) / fv[:, None]
        free = m - np.cross(cop, f)
    bad = ~np.isfinite(cop).all(axis=1)
    cop[bad] = np.nan
    free[bad] = 0.0
    return dataclasses.replace(plate, force=f, cop=cop, free_moment=free)


def prepared_plates(
    plates: Iterable[Any],
    up: Array,
    *,
    ignore: Sequence[str] = (),
    remove_baseline: bool = True,
    threshold_n: float = 20.0,
    found: list[PlateBaseline] | None = None,
) -> Iterator[Any]:
    """``plates`` without the ignored ones and with their offsets removed (one at a time: a
    generator; each offset removed is appended to ``found``)."""
    skip = set(ignore)
    for p in plates:
        if p.name in skip:
            continue
        if remove_baseline:
            b = plate_baseline(p, up, threshold_n=threshold_n)
            if b is not None:
                if found is not None:
                    found.append(b)
                p = without_baseline(p, b, up)
        yield p
