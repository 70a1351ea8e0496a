"""The ankle's gauge of a placement from the motion fixed by a stated prior: the sole is level
when the foot is flat on the ground.

Without a static trial every foot marker is moved from the motion
(:func:`msk.personalise.scaling.place_markers_from_motion`), so the mean ankle angle is an exact
gauge
(:mod:`msk.personalise.determinacy`): rotating the foot's marker offsets about the ankle axis by −δ
while
the ankle coordinate moves by +δ leaves every marker in place, and the mean is wherever the
placement's start and stop put it. The prior that fixes it: in the foot-flat phase of stance
(loading response to heel rise: the heel and the forefoot both on the ground, Perry J, Burnfield
JM (2010) Gait Analysis: Normal and Pathological Function, 2nd ed., ch. 4 "Ankle–foot
complex") the plantar surface lies on the floor, and in gait2392 the calcaneus frame's x
axis is that surface's heel-to-metatarsal line — at zero ankle and subtalar angles
with the tibia vertical the MTP joint centre sits 2 mm below the calcaneus origin 179 mm in
front of it (gait2392's ``mtp_r`` offset [0.1788, −0.002, 0.00108] m: a pitch of −0.6°; Delp
SL et al. (1990) IEEE Trans Biomed Eng 37:757–767). So its pitch

    φ(q) = asin(e_up · R_calcn(q) e_x)      (e_up = −g/|g|, R_calcn the body's rotation)

is 0 at foot flat. The gauge's shift δ of a side's ankle solves

    median_{t ∈ F} φ(q_t + δ e_ankle) = 0      (F: that foot's foot-flat frames)

(a scalar root, found by the secant method; φ is monotone in δ near the root: gait2392's ankle
axis is 12° off the medio-lateral axis), and
:func:`msk.personalise.determinacy.gauge_shifted_markers` moves
the free foot markers so that the refitted poses carry that δ.

Foot-flat frames (:func:`foot_flat_frames`) come from the markers alone: the foot's markers
(on the calcaneus) all moving vertically slower than :data:`FLAT_VERTICAL_SPEED_M_S` with
their mean height above their own lowest within :data:`FLAT_HEIGHT_TOLERANCE_M` of that mean's
lowest — heights and vertical speeds only, so a treadmill's belt, which carries the foot
forward in stance, does not hide it. A trial with fewer than :data:`MIN_FLAT_FRAMES` such
frames on a side (no stance, running, toe walking whose heel never rests) keeps the
placement's ankle as it is, and says so (:class:`SoleLevel`, ``reason``).

The prior sets the foot's orientation, not the shank's: an ankle still moves with its knee's
own gauge when that is free (docs/validation.md).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from msk.model.core import Model, frame_placements
from msk.personalise.determinacy import gauge_shifted_markers, joint_child
from msk.units import Array

__all__ = [
    "FLAT_HEIGHT_TOLERANCE_M",
    "FLAT_VERTICAL_SPEED_M_S",
    "MIN_FLAT_FRAMES",
    "SOLE_PRIOR",
    "SoleLevel",
    "foot_flat_frames",
    "level_sole_gauge",
    "sole_pitch",
]

#: the foot is down when its markers' mean height above their own lowest heights (each one's 2nd
#: percentile) is within 20 mm of that mean's lowest: on gc5_PS's shipped walk (a static
#: session) a heel marker sits 10–15 mm above its lowest (at initial contact: heel pad
#: compressed, foot dorsiflexed) at foot flat, a toe-tip marker 30–35 mm (its lowest at toe-off),
#: midfoot and metatarsal markers 0–7 mm — a mean of 10–13 mm; at initial contact and toe-off
#: the mean is 40–60 mm, in swing 60–150 mm. Not each marker within a tolerance of its own
#: lowest: no frame has all of them there
FLAT_HEIGHT_TOLERANCE_M = 0.020

#: a foot marker is still when its vertical speed is under 0.1 m/s: a heel marker at heel
#: strike or heel rise moves vertically at 0.3–2 m/s; at foot flat mostly ≤ 0.05 m/s (the
#: same walk)
FLAT_VERTICAL_SPEED_M_S = 0.10

#: fewer foot-flat frames than this on a side: no prior applied there
MIN_FLAT_FRAMES = 5

#: the prior's name in ``summary.json`` and the report
SOLE_PRIOR = "sole level at foot flat"


@dataclass(frozen=True)
class SoleLevel:
    """One side's gauge: the ankle coordinate, its foot body, the foot-flat frames found (of the
    trial), the frames fitted, the median sole pitch there before (rad) and the ankle shift δ
    applied (rad; 0 and ``applied`` False when the prior could not be applied: ``reason``)."""

    coordinate: str
    body: str
    flat_frames: int
    fitted_frames: int
    pitch_before_rad: float
    shift_rad: float
    applied: bool
    reason: str = ""

    def summary(self) -> dict[str, Any]:
        return {
            "prior": SOLE_PRIOR,
            "status": "prior" if self.applied else "not applied",
            "body": self.body,
            "foot_flat_frames": self.flat_frames,
            "fitted_frames": self.fitted_frames,
            "sole_pitch_before_deg": float(np.degrees(self.pitch_before_rad))
            if self.applied
            else None,
            "ankle_shift_deg": float(np.degrees(self.shift_rad)),
            **({"reason": self.reason} if self.reason else {}),
        }


def foot_flat_frames(
    heights: Array,
    time: Array,
    *,
    height_tolerance_m: float = FLAT_HEIGHT_TOLERANCE_M,
    vertical_speed_m_s: float = FLAT_VERTICAL_SPEED_M_S,
) -> NDArray[np.bool_]:
    """Frames (N,) where the foot's tracked markers (columns of ``heights`` (N, M), m above any
    fixed level, NaN when not tracked; at least two) all move vertically slower than
    ``vertical_speed_m_s`` (central differences over ``time``) and their mean height above
    their own lowest heights (each one's 2nd percentile) is within ``height_tolerance_m`` of
    that mean's lowest (2nd percentile)."""
    h = np.asarray(heights, dtype=float)
    t = np.asarray(time, dtype=float)
    n = h.shape[0]
    if n < 3 or h.shape[1] == 0:
        return np.zeros(n, dtype=bool)
    use = np.isfinite(h).sum(axis=0) >= 3
    if use.sum() < 2:
        return np.zeros(n, dtype=bool)
    h = h[:, use]
    low = np.nanpercentile(h, 2.0, axis=0)
    v = np.gradient(h, t, axis=0)
    seen = np.isfinite(v)
    two = seen.sum(axis=1) >= 2
    if not two.any():
        return np.zeros(n, dtype=bool)
    excess = np.full(n, np.inf)
    excess[two] = np.nanmean(np.where(seen, h - low, np.nan)[two], axis=1)
    down = excess <= np.percentile(excess[two], 2.0) + height_tolerance_m
    with np.errstate(invalid="ignore"):
        still = (np.abs(v) <= vertical_speed_m_s) | ~seen
    return np.asarray(down & still.all(axis=1) & two, dtype=bool)


def sole_pitch(model: Model, q: Array, body: str) -> Array:
    """φ(q) (module docstring) of ``body`` at the poses ``q`` (F, n): rad, toes up positive."""
    up = -np.asarray(model.gravity, dtype=float)
    up = up / np.linalg.norm(up)
    rot, _ = frame_placements(model, np.asarray(q, dtype=float), [model.body_frame[body]])
    return np.asarray(np.arcsin(np.clip(rot[:, 0, :, 0] @ up, -1.0, 1.0)), dtype=float)


def _median_pitch(model: Model, q: Array, body: str, ci: int, delta: float) -> float:
    shifted = np.array(q, dtype=float)
    shifted[:, ci] += delta
    return float(np.median(sole_pitch(model, shifted, body)))


def _root(model: Model, q: Array, body: str, ci: int) -> tuple[float, float]:
    """(median pitch at δ = 0, δ with median pitch 0) by the secant method."""
    p0 = _median_pitch(model, q, body, ci, 0.0)
    a, fa = 0.0, p0
    b = -p0
    fb = _median_pitch(model, q, body, ci, b)
    for _ in range(30):
        if abs(fb) < 1e-10 or fb == fa:
            break
        a, fa, b = b, fb, b - fb * (b - a) / (fb - fa)
        fb = _median_pitch(model, q, body, ci, b)
    return p0, float(b)


def level_sole_gauge(
    model: Model,
    markers: Array,
    labels: Sequence[str],
    time: Array,
    fit: Callable[[Model, Array], tuple[Array, float]],
    free: Sequence[str],
    *,
    sides: Mapping[str, str] | None = None,
    max_frames: int = 60,
) -> tuple[Model, tuple[SoleLevel, ...]]:
    """``model`` with each side's ankle gauge fixed by the prior (module docstring).

    ``markers`` (N, M, 3) in the model's frame (its up: −gravity), ``labels`` their names
    (model names), ``time`` (N,) s; ``fit(model, frames)``: the poses (F, n) of the frames
    ``frames`` (indices into ``markers``) fitted with ``model`` and their cost; ``free``: the
    markers placed or moved from this motion. ``sides``: ankle coordinate → foot body (its
    markers tell foot flat: on gait2392 the heel, midfoot and metatarsal heads, not the toes
    whose marker is lowest at toe-off); default gait2392's ``ankle_angle_<s>`` →
    ``calcn_<s>``. A side is left as it is when the model lacks it, a foot
    marker distal to the ankle is not free (the gauge is not free then), or fewer than
    :data:`MIN_FLAT_FRAMES` foot-flat frames are found. Up to ``max_frames`` foot-flat frames
    (evenly spread) are fitted; the shift is applied at their median pose."""
    x = np.asarray(markers, dtype=float)
    t = np.asarray(time, dtype=float)
    up = -np.asarray(model.gravity, dtype=float)
    up = up / np.linalg.norm(up)
    labels = tuple(labels)
    if sides is None:
        sides = {f"ankle_angle_{s}": f"calcn_{s}" for s in ("r", "l")}
    free_set = set(free)
    out: list[SoleLevel] = []
    for coord, body in sides.items():
        if coord not in model.coordinate_names or body not in model.body_frame:
            continue
        ankle_sub = set(model.subtree(joint_child(model, coord)))
        distal = [mk.name for mk in model.markers if mk.body in ankle_sub and mk.name in labels]
        foot = [mk.name for mk in model.markers if mk.body == body and mk.name in labels]

        kept = SoleLevel(coord, body, 0, 0, float("nan"), 0.0, False)
        if not foot:
            out.append(replace(kept, reason="no foot marker in the trial"))
            continue
        if not set(distal) <= free_set:
            out.append(replace(kept, reason="a foot marker is not placed from the motion: the "
                               "ankle's mean is observed"))  # fmt: skip
            continue
        h = x[:, [labels.index(m) for m in foot]] @ up
        flat = np.flatnonzero(foot_flat_frames(h, t))
        if flat.size < MIN_FLAT_FRAMES:
            why = (
                f"{flat.size} foot-flat frames (fewer than {MIN_FLAT_FRAMES}: no stance with the "
                "foot flat and still: running, toe walking): the placement's ankle kept"
            )
            out.append(replace(kept, flat_frames=int(flat.size), reason=why))
            continue
        pick = flat[np.round(np.linspace(0, flat.size - 1, min(max_frames, flat.size)))
                    .astype(int)]  # fmt: skip
        q, _ = fit(model, pick)
        q = np.asarray(q, dtype=float)
        ok = np.isfinite(q).all(axis=1)
        if ok.sum() < MIN_FLAT_FRAMES:
            out.append(replace(kept, flat_frames=int(flat.size),
                               reason="the foot-flat frames could not be fitted"))  # fmt: skip
            continue
        ci = model.coordinate_index(coord)
        p0, delta = _root(model, q[ok], body, ci)
        model = gauge_shifted_markers(model, coord, delta, np.median(q[ok], axis=0), free)
        out.append(SoleLevel(coord, body, int(flat.size), int(ok.sum()), p0, delta, True))
    return model, tuple(out)
