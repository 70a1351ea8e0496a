"""Plausibility gates on a walk: its knee contact force against in-vivo measurements, and its
pelvis tilt.

Instrumented knee prostheses measure the tibiofemoral contact force directly. In level walking
its peak is 2-3 body weights (BW): 2.61 BW on average over 5 subjects, Kutzner et al. 2010,
J Biomech 43:2164-2173; 2.0-2.5 BW in the Grand Challenge subjects,
Fregly et al. 2012, J Orthop Res 30:503-513. A model's estimate above
:data:`KNEE_CONTACT_WALKING_MAX_BW` (4.5 BW, one and a half times the highest in-vivo walking
peak) is not a subject's knee but a modelling error (muscle co-contraction the optimisation
invents, a hip centre or a segment misplaced, a moment arm off): :func:`knee_contact_flags`
raises a flag naming the bound and its source.

The bound is for walking. Whether a trial is a walk (:func:`gait_mode`): from the gait events,
walking has double support — at a foot strike the other foot is still on the ground (its last
event a strike) — and running a flight phase (its last event a foot off); without events of
both sides, the pelvis' mean horizontal speed against the walk-run transition speed,
:data:`WALK_RUN_SPEED_M_S` (≈ 2.0 m/s, Hreljac 1993, Med Sci Sports Exerc 25:1158-1162). A
running trial is not gated (in-vivo running loads are not measured at these speeds), nor a
stationary task (squat: its knee loads reach 3-4 BW in vivo) or a stair (a pelvis that rises or
falls: 3-3.5 BW in vivo, Kutzner et al. 2010).

Pelvis tilt (:func:`pelvis_tilt_flags`): in walking the pelvis tilts 10-15° anteriorly on
average, its ASIS–PSIS line against the horizontal, with a range of about 4° over the cycle
(Kadaba et al. 1990, J Orthop Res 8:383-392, Plug-in Gait's own definition); a model's pelvis
frame (gait2392's: ASIS and a sacral point) differs from that line by under 10°. A walk whose
mean pelvis tilt exceeds :data:`PELVIS_TILT_WALKING_MAX_DEG` (25°) in magnitude is a pelvis
the markers did not determine (two ASIS and the legs alone: a missing sacral or PSIS marker, a
PSIS placed from the motion) — the hips then take up the error (−50…−62° of hip extension at
6-12 mm marker RMS): flagged, with the tilt and the markers on the pelvis. The tilt judged is
the one the report gives (Plug-in Gait's ASIS–PSIS plane, :mod:`msk.gait.variables`) when the
caller passes it, else the model's ``pelvis_tilt`` coordinate.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from msk.quality import Flag

__all__ = [
    "KNEE_CONTACT_WALKING_MAX_BW",
    "LEVEL_MAX_RISE_M",
    "PELVIS_TILT_WALKING_MAX_DEG",
    "WALK_MIN_SPEED_M_S",
    "WALK_RUN_SPEED_M_S",
    "gait_mode",
    "knee_contact_flags",
    "pelvis_tilt_flags",
]

#: Largest plausible peak knee contact force in level walking, BW (1.5 × the highest in-vivo
#: walking peak, 3.0 BW: Kutzner et al. 2010; Fregly et al. 2012).
KNEE_CONTACT_WALKING_MAX_BW = 4.5
#: Largest plausible mean pelvis tilt magnitude in walking, deg (module docstring).
PELVIS_TILT_WALKING_MAX_DEG = 25.0
#: Walk-run transition speed, m/s (Hreljac 1993).
WALK_RUN_SPEED_M_S = 2.0
#: Slowest walk, m/s: below it the trial is a stationary task (pathological gait is rarely slower
#: than 0.2 m/s; a squat's pelvis does not travel)
WALK_MIN_SPEED_M_S = 0.2
#: Largest net rise or fall of the pelvis over a level walk, m (a stair's step is 0.15–0.2 m)
LEVEL_MAX_RISE_M = 0.12


def _mode_from_events(events: Any) -> str | None:
    strikes = {s: list(events.foot_strike.get(s, ())) for s in ("right", "left")}
    offs = {s: list(events.foot_off.get(s, ())) for s in ("right", "left")}
    votes = {"walking": 0, "running": 0}
    for side, other in (("right", "left"), ("left", "right")):
        prior = sorted([(t, "strike") for t in strikes[other]] + [(t, "off") for t in offs[other]])
        for t in strikes[side]:
            before = [k for u, k in prior if u < t and t - u < 1.5]
            if before:
                votes["walking" if before[-1] == "strike" else "running"] += 1
    if votes["walking"] == votes["running"]:
        return None
    return max(votes, key=lambda k: votes[k])


def _pelvis_path(kinematics: Any, up: Any) -> tuple[float, float, float] | None:
    """(net horizontal distance m, net rise m, duration s) of the pelvis over the tracked frames
    (its root translations ``*_tx/_ty/_tz``), None when they are not known."""
    names = list(kinematics.coordinate_names)
    cols = [next((i for i, n in enumerate(names) if n.endswith(ax)), None)
            for ax in ("_tx", "_ty", "_tz")]  # fmt: skip
    t = np.asarray(kinematics.time, dtype=float)
    if any(c is None for c in cols) or t.size < 2:
        return None
    x = np.asarray(kinematics.q, dtype=float)[:, [c for c in cols if c is not None]]
    ok = np.isfinite(x).all(axis=1)
    if ok.sum() < 2:
        return None
    u = np.asarray(up, dtype=float)
    u = u / np.linalg.norm(u)
    d = x[ok][-1] - x[ok][0]
    rise = float(np.dot(d, u))
    return float(np.linalg.norm(d - rise * u)), rise, float(t[ok][-1] - t[ok][0])


def gait_mode(events: Any, kinematics: Any, up: ArrayLike) -> tuple[str, str]:
    """(``"walking"``, ``"running"``, ``"stairs"``, ``"stationary"`` or ``"unknown"``, how it
    was judged) of a trial. A pelvis that rises or falls by more than :data:`LEVEL_MAX_RISE_M`
    over the trial is on stairs or a slope (not level walking); otherwise the gait events
    (:class:`msk.kinematics.events.GaitEvents`: double support or a flight phase); without
    events of both sides, the pelvis' net horizontal speed (the root translations
    ``*_tx/_ty/_tz`` of ``kinematics``; ``up`` the model's up direction): below
    :data:`WALK_MIN_SPEED_M_S` a stationary task (a squat, a sit-to-stand), above
    :data:`WALK_RUN_SPEED_M_S` running."""
    path = _pelvis_path(kinematics, up)
    if path is not None and abs(path[1]) > LEVEL_MAX_RISE_M:
        return "stairs", f"the pelvis rises {path[1]:+.2f} m over the trial (not level)"
    mode = _mode_from_events(events) if events is not None else None
    if mode is not None:
        why = "double support" if mode == "walking" else "a flight phase"
        return mode, f"the gait events show {why}"
    if path is None:
        return "unknown", "no gait events of both sides and no tracked pelvis"
    speed = path[0] / path[2] if path[2] > 0 else 0.0
    if speed < WALK_MIN_SPEED_M_S:
        return "stationary", f"the pelvis' mean horizontal speed {speed:.2f} m/s"
    mode = "walking" if speed <= WALK_RUN_SPEED_M_S else "running"
    return mode, f"the pelvis' mean horizontal speed {speed:.2f} m/s"


def knee_contact_flags(
    trial_name: str,
    totals_bw: Mapping[str, ArrayLike],
    mode: str,
    why: str,
    *,
    bound_bw: float = KNEE_CONTACT_WALKING_MAX_BW,
) -> list[Flag]:
    """A flag per model variant (``"generic"``, ``"subject_specific"``: its total knee contact
    force in BW over the trial) whose walking peak exceeds ``bound_bw``; nothing for a trial
    that is not a walk (``mode``, judged as ``why`` says: :func:`gait_mode`)."""
    if mode != "walking":
        return []
    out = []
    for variant, y in totals_bw.items():
        v = np.asarray(y, dtype=float)
        if not np.isfinite(v).any():
            continue
        peak = float(np.nanmax(v))
        if peak > bound_bw:
            out.append(
                Flag(
                    trial_name, f"knee_contact_peak_bw_{variant}", peak, bound_bw,
                    f"{variant} model: knee contact force peaks at {peak:.1f} BW in a walk "
                    f"({why}); in-vivo walking peaks are 2-3 BW (Kutzner et al. 2010, J "
                    f"Biomech 43:2164; Fregly et al. 2012, J Orthop Res 30:503): above "
                    f"{bound_bw:g} BW the estimate reflects the model (co-contraction, joint "
                    "centres, moment arms), not the knee",
                )
            )  # fmt: skip
    return out


def pelvis_tilt_flags(
    trial_name: str,
    kinematics: Any,
    mode: str,
    pelvis_markers: tuple[str, ...] = (),
    *,
    bound_deg: float = PELVIS_TILT_WALKING_MAX_DEG,
    tilt_deg: ArrayLike | None = None,
    frame: str = "",
) -> list[Flag]:
    """A flag when the mean pelvis tilt of a walk exceeds ``bound_deg`` in magnitude: the
    reported tilt ``tilt_deg`` (deg, any shape, NaN ignored; anterior +; e.g. the gait cycles'
    ``pelvis_tilt_deg`` in Plug-in Gait's pelvis frame, described by ``frame``), else the
    coordinate ``pelvis_tilt`` of ``kinematics`` (rad); ``pelvis_markers`` (the model's and
    the lab's markers on the pelvis used) are named in the message."""
    if mode != "walking":
        return []
    if tilt_deg is not None:
        tilt = np.asarray(tilt_deg, dtype=float).ravel()
        what = f"reported pelvis tilt ({frame})" if frame else "reported pelvis tilt"
    else:
        names = list(kinematics.coordinate_names)
        if "pelvis_tilt" not in names:
            return []
        tilt = np.degrees(np.asarray(kinematics.q, dtype=float)[:, names.index("pelvis_tilt")])
        what = "pelvis tilt (the model's pelvis_tilt coordinate)"
    if not np.isfinite(tilt).any():
        return []
    mean = float(np.nanmean(tilt))
    if abs(mean) <= bound_deg:
        return []
    lo, hi = float(np.nanmin(tilt)), float(np.nanmax(tilt))
    on = ", ".join(pelvis_markers) or "none"
    return [
        Flag(
            trial_name, "pelvis_tilt_mean_deg", mean, bound_deg if mean > 0 else -bound_deg,
            f"mean {what} {mean:.0f}° ({lo:.0f}…{hi:.0f}°) in a walk, beyond ±{bound_deg:g}° "
            "(walking: 10-15° anterior, Kadaba et al. 1990): a pelvis its markers do not "
            f"determine (pelvis markers: {on}; two ASIS need a sacral or both PSIS markers, "
            "with a static trial to place them) — hip angles and moments take up the error",
        )
    ]  # fmt: skip
