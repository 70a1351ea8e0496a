"""Frames whose kinematics the markers observe: where every leg segment sees the markers that
pose it, away from the frames where one does not by the low-pass filter's spread.

A rigid segment's pose is determined by three non-collinear markers (Söderkvist & Wedin
1993, J Biomech 26:1473: their least-squares rotation, by singular value decomposition, is
unique only with at least three non-collinear points); with fewer, the inverse kinematics
poses it from its joints and the neighbouring segments — a pose guessed, not measured. A
segment is *under-observed* at a frame when it sees fewer than ``min(3, k)`` of its markers,
``k`` the number of its markers the trial tracks (seen in at least half of the solved frames;
a segment the lab marks with one or two markers is designed to be posed with its joints' help,
and is under-observed only when it loses one of them). Frames IK did not solve are unobserved.

Accelerations come from coordinates low-passed at ``f_c`` and differentiated twice
(:func:`msk.kinematics.ik.solve_kinematics`): a marker that drops out makes the pose jump, the
end of the solved window leaves the filter an extrapolated edge (the window is filtered on its
own, its ends reflected, but a reflection is a guess of the motion beyond), and the zero-lag filter
spreads either: the second derivative of a filtered step peaks about 1/(4 f_c) from it (40 ms
at 6 Hz, 4th order) and swings on to about 0.6/f_c. Every unobserved run is widened by
1/(4 f_c) on both sides (the spread :func:`msk.dynamics.loads.contact_measured` pads by), which
removes
the peak, not the whole swing. Measured on UWA's running trial (the subject enters the capture
volume with one pelvis marker of three in view and leaves it losing LCAL, then the right
thigh's cluster; pelvis residual 1,000–4,300 N there against 90–550 N in the observed
stance): widening by 0, 1/(4 f_c), 1/(2 f_c), 1/f_c leaves 97, 80, 58, 16 of the 121
measured frames with a residual (generic model) of 48.7, 44.1, 43.5, 48.7 % BW — beyond
1/(4 f_c) what remains is not the edges'. (Those figures predate the window's own filtering,
which took the 3,700–4,200 N at its ends down to ≤ 350 N.)

The dynamics-based figures (pelvis residuals, plate mass, mass identification, strength
identification, muscle forces) use only the observed frames (``msk.pipeline.loads``)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "LEG_BODIES",
    "MARKERS_TO_POSE",
    "OBSERVATION_METHOD",
    "Observation",
    "observed_frames",
]

#: body-name prefixes of the segments whose observation is checked (gait2392 / Rajagopal names)
LEG_BODIES = ("pelvis", "femur", "tibia", "calcn", "foot")

#: markers that pose a rigid segment without its joints (Söderkvist & Wedin 1993)
MARKERS_TO_POSE = 3


@dataclass(frozen=True)
class Observation:
    """``observed``: (N,) frames whose every leg segment sees its markers and that lie at least
    ``pad_frames`` from any frame that does not (and from any frame IK did not solve);
    ``short``: frames (solved) per segment where it sees fewer markers than ``needed``;
    ``needed``: markers needed per segment (``min(3, k)``)."""

    observed: NDArray[np.bool_]
    short: Mapping[str, int]
    needed: Mapping[str, int]
    pad_frames: int

    def excluded(self, frames: NDArray[np.bool_]) -> int:
        """How many of ``frames`` are not observed."""
        return int((np.asarray(frames, dtype=bool) & ~self.observed).sum())


def observed_frames(model: Any, kinematics: Any, *, pad_s: float | None = None) -> Observation:
    """The frames of ``kinematics`` (:class:`msk.kinematics.ik.Kinematics`) whose leg segments
    (:data:`LEG_BODIES`) the markers observe (module docstring). Marker visibility is read from
    ``kinematics.marker_errors`` (finite where a marker was present and used in a solved frame).
    ``pad_s``: the widening of each unobserved run; None (default): 1/(4 f_c) with the
    kinematics' cut-off, none when unfiltered."""
    errs = np.asarray(kinematics.marker_errors, dtype=float)
    names = tuple(kinematics.marker_names)
    t = np.asarray(kinematics.time, dtype=float)
    n = t.size
    solved = np.isfinite(errs).any(axis=1) if errs.ndim == 2 and errs.size else np.zeros(n, bool)
    solved &= np.isfinite(np.asarray(kinematics.q, dtype=float)).all(axis=1)
    body_of = {m.name: m.body for m in model.markers}
    present = np.isfinite(errs) if errs.ndim == 2 else np.zeros((n, 0), bool)
    bad = ~solved
    short: dict[str, int] = {}
    needed: dict[str, int] = {}
    n_solved = max(int(solved.sum()), 1)
    for body in sorted({body_of[m] for m in names if m in body_of}):
        if not body.startswith(LEG_BODIES):
            continue
        cols = [k for k, m in enumerate(names) if body_of.get(m) == body]
        seen = present[:, cols]
        tracked = int((seen[solved].sum(axis=0) >= 0.5 * n_solved).sum())
        need = min(MARKERS_TO_POSE, tracked)
        if need == 0:
            continue
        low = solved & (seen.sum(axis=1) < need)
        needed[body], short[body] = need, int(low.sum())
        bad |= low
    if pad_s is None:
        fc = getattr(kinematics, "cutoff_hz", None)
        pad_s = 1.0 / (4.0 * float(fc)) if fc else 0.0
    dt = float(np.median(np.diff(t))) if n > 1 else 1.0
    pad = round(pad_s / dt) if pad_s > 0 and dt > 0 else 0
    wide = bad.copy()
    if pad and bad.any():
        idx = np.flatnonzero(bad)
        # a frame is excluded when an unobserved frame lies within `pad` of it
        lo = np.searchsorted(idx, np.arange(n) - pad, side="left")
        hi = np.searchsorted(idx, np.arange(n) + pad, side="right")
        wide = hi > lo
    return Observation(solved & ~wide, short, needed, pad)


#: Which frames the dynamics-based figures use (recorded in the cache key).
OBSERVATION_METHOD = (
    "msk.kinematics.observation: every leg segment sees min(3, its tracked markers), 1/(4 f_c) "
    "from any "
    "frame where one does not or IK did not solve"
)
