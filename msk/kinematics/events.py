"""Gait events (foot strike, foot off) from the force plates and from the kinematics.

Two detectors, combined per foot:

* **Plates** — a foot strikes when the vertical ground reaction on the foot (and the bodies
  distal to it) rises through ``threshold_n`` after at least ``min_swing_s`` unloaded, and comes
  off when it falls through it after at least ``min_stance_s`` loaded (the usual force-plate
  definition, e.g. Zeni et al. 2008 used it as their reference). Only edges inside the frames
  the plates observe count (a foot stepping on the floor beside a plate gives no edge).
* **Kinematics** — the coordinate-based algorithm of Zeni JA, Richards JG, Higginson JS (2008)
  Two simple methods for determining gait events during treadmill and overground walking using
  kinematic data, Gait Posture 27:710–714: along the pelvis's forward direction, heel strike is
  a local maximum of the heel position relative to the pelvis (x_heel − x_pelvis) and toe off a
  local minimum of the toe position relative to it (x_toe − x_pelvis). It works on treadmills
  and overground, wherever the feet are not on plates. The heel is the origin of the foot's
  calcaneus body, the toe the origin of its toes body (or the foot body's markers named
  ``*Toe*``/``*Heel*`` when the model has them).

A kinematic event within ``match_s`` of a plate event of the same kind is replaced by the plate
event (the plates are the more accurate where they see the foot). :func:`reconcile` compares the
events stored in a file with the detected ones: events that contradict the plates are replaced,
and the notes say so.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from msk.signal import find_peaks
from msk.units import Array

__all__ = ["DISTINCT_EVENT_S", "GaitEvents", "detect_gait_events", "reconcile"]

_SIDES = {"right": "_r", "left": "_l"}


@dataclass(frozen=True)
class GaitEvents:
    """Foot strikes and foot offs per side (``"right"``, ``"left"``), times in s, sorted.

    ``source`` says per side and kind where the times come from (``"plates"``,
    ``"kinematics"``, ``"plates+kinematics"``, ``"file"``); ``notes`` what was decided."""

    foot_strike: Mapping[str, tuple[float, ...]]
    foot_off: Mapping[str, tuple[float, ...]]
    source: Mapping[str, str] = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    def as_list(self) -> list[dict[str, Any]]:
        """Events as ``{"label", "context", "time"}`` records sorted by time."""
        out = [
            {"label": lab, "context": side.capitalize(), "time": float(t)}
            for lab, d in (("Foot Strike", self.foot_strike), ("Foot Off", self.foot_off))
            for side, ts in d.items()
            for t in ts
        ]
        return sorted(out, key=lambda e: e["time"])


def _body(model: Any, stems: Sequence[str], sfx: str) -> str | None:
    names = set(model.body_joint)
    for s in stems:
        if s + sfx in names:
            return s + sfx
    return None


def _edges(loaded: NDArray[np.bool_], observed: NDArray[np.bool_], t: Array,
           min_before_s: float, rising: bool) -> list[float]:  # fmt: skip
    out: list[float] = []
    x = loaded if rising else ~loaded
    idx = np.flatnonzero(x[1:] & ~x[:-1]) + 1
    for i in idx:
        # the state before the edge lasted min_before_s, and the plates saw the edge
        before = (t >= t[i] - min_before_s) & (t < t[i])
        if before.sum() < 1 or x[before].any():
            continue
        if not (observed[i - 1] or observed[i]):
            continue
        out.append(float(t[i]))
    return out


def _travel(x: Array, a: int, b: int, up: Array) -> float:
    """Horizontal distance (m) between the positions ``x`` at indices a and b (clipped)."""
    a, b = max(a, 0), min(b, x.shape[0] - 1)
    d = x[b] - x[a]
    return float(np.linalg.norm(d - (d @ up) * up))


def detect_gait_events(
    model: Any,
    kinematics: Any,
    loads: Any | None = None,
    *,
    observed: NDArray[np.bool_] | None = None,
    threshold_n: float = 20.0,
    min_swing_s: float = 0.1,
    min_stance_s: float = 0.1,
    min_step_s: float = 0.3,
    prominence_m: float = 0.05,
    match_s: float = 0.15,
    min_travel_m: float = 0.1,
) -> GaitEvents:
    """Foot strikes and foot offs of both feet (module docstring).

    Args:
        model: the model (feet: ``calcn_r/l`` or ``foot_r/l``; toes: ``toes_r/l``).
        kinematics: :class:`msk.kinematics.ik.Kinematics` (``time``, ``q``; NaN frames skipped).
        loads: :class:`msk.dynamics.loads.ExternalLoads` or None (kinematics only).
        observed: (N,) frames whose ground contact the plates observe (default: all).
        threshold_n: vertical force of contact (N).
        min_swing_s, min_stance_s: the unloaded / loaded time an edge needs before it.
        min_step_s: shortest time between two events of one kind on one foot (kinematics).
        prominence_m: smallest prominence of the heel/toe excursion peaks (m).
        match_s: a kinematic event this close to a plate event is replaced by it.
        min_travel_m: a kinematic strike (foot off) needs the heel (toe) to have moved this far
            horizontally in the ``min_step_s`` before (after) it: a step, not a squat.
    """
    t = np.asarray(kinematics.time, dtype=float)
    q = np.asarray(kinematics.q, dtype=float)
    n = t.size
    good = np.isfinite(q).all(axis=1)
    obs = np.ones(n, bool) if observed is None else np.asarray(observed, dtype=bool)
    g = np.asarray(model.gravity, dtype=float)
    up = -g / np.linalg.norm(g)
    rate = (n - 1) / (t[-1] - t[0]) if n > 1 else 1.0
    strikes: dict[str, tuple[float, ...]] = {}
    offs: dict[str, tuple[float, ...]] = {}
    source: dict[str, str] = {}
    gidx = np.flatnonzero(good)
    root = model.pin_model.frames[1].name if len(model.pin_model.frames) > 1 else ""
    pelvis = _body(model, ("pelvis",), "") or root
    feet = {
        side: (_body(model, ("calcn", "foot"), sfx), _body(model, ("toes",), sfx))
        for side, sfx in _SIDES.items()
    }
    # one forward-kinematics pass: pelvis forward axis, heel and toe positions (Zeni 2008)
    rel: dict[str, tuple[Array, Array]] = {}
    world: dict[str, tuple[Array, Array]] = {}
    if gidx.size > 10 and pelvis in model.body_frame:
        fp = model.body_frame[pelvis]
        data = model.create_data()
        qp = model.coupling.q(q[gidx])
        ids = {side: (model.body_frame[h], model.body_frame[tb or h])
               for side, (h, tb) in feet.items() if h is not None}  # fmt: skip
        fwd = np.zeros((gidx.size, 3))
        xp = np.zeros((gidx.size, 3))
        ph = {side: np.zeros((gidx.size, 3)) for side in ids}
        pt = {side: np.zeros((gidx.size, 3)) for side in ids}
        for i in range(gidx.size):
            pin.framesForwardKinematics(model.pin_model, data, qp[i])
            fwd[i] = data.oMf[fp].rotation[:, 0]
            xp[i] = data.oMf[fp].translation
            for side, (fh, ft) in ids.items():
                ph[side][i] = data.oMf[fh].translation
                pt[side][i] = data.oMf[ft].translation
        fwd -= (fwd @ up)[:, None] * up
        fwd /= np.maximum(np.linalg.norm(fwd, axis=1, keepdims=True), 1e-12)
        for side in ids:
            world[side] = (ph[side], pt[side])
            rel[side] = (
                np.einsum("ij,ij->i", ph[side] - xp, fwd),
                np.einsum("ij,ij->i", pt[side] - xp, fwd),
            )
    for side in _SIDES:
        heel_b = feet[side][0]
        if heel_b is None:
            continue
        # plates
        p_hs: list[float] = []
        p_to: list[float] = []
        if loads is not None:
            fv = np.zeros(n)
            for b in model.subtree(heel_b):
                if b in loads.bodies:
                    fv += np.nan_to_num(np.asarray(loads.force)[:, loads.bodies.index(b)]) @ up
            loaded = fv > threshold_n
            p_hs = _edges(loaded, obs, t, min_swing_s, True)
            p_to = _edges(loaded, obs, t, min_stance_s, False)
        # kinematics: heel-strike maxima of x_heel − x_pelvis, toe-off minima of x_toe − x_pelvis
        k_hs: list[float] = []
        k_to: list[float] = []
        if side in rel:
            xh, xt = rel[side]
            dist = max(1, int(min_step_s * rate))
            hs = find_peaks(xh, distance=dist, prominence=prominence_m)
            to = find_peaks(-xt, distance=dist, prominence=prominence_m)
            # a strike ends a swing and a foot off starts one: the foot travels ≥ min_travel_m
            # in the world over the min_step_s before (strike) / after (off) — the heel and
            # pelvis of a squat or a sway move against each other with the feet still
            wh, wt = world[side]
            k_hs = [float(t[gidx[i]]) for i in hs
                    if _travel(wh, i - dist, i, up) >= min_travel_m]  # fmt: skip
            k_to = [float(t[gidx[i]]) for i in to
                    if _travel(wt, i, i + dist, up) >= min_travel_m]  # fmt: skip

        def merge(plate: list[float], kin: list[float]) -> tuple[tuple[float, ...], str]:
            kept = [x for x in kin if not any(abs(x - p) <= match_s for p in plate)]
            out = tuple(sorted(plate + kept))
            src = "+".join(s for s, v in (("plates", plate), ("kinematics", kept)) if v)
            return out, src or "none"

        strikes[side], source[f"{side} foot strike"] = merge(p_hs, k_hs)
        offs[side], source[f"{side} foot off"] = merge(p_to, k_to)
    return GaitEvents(strikes, offs, source)


#: Two events of one side and kind closer than this are one event (a stride lasts ≥ 0.7 s at a
#: run's cadence; half of it)
DISTINCT_EVENT_S = 0.35


def reconcile(
    file_events: Sequence[Any],
    detected: GaitEvents,
    *,
    plate_events: GaitEvents | None = None,
    tolerance_s: float = 0.075,
) -> GaitEvents:
    """The events to use: the file's (``label`` ``"Foot Strike"``/``"Foot Off"``, ``context``
    ``"Left"``/``"Right"``, ``time``) where they agree with the plates, the detected ones
    where the file has none of a side/kind or where a file event lies farther than
    ``tolerance_s`` from the plate event it should be (the notes name each case). A file that
    marks only some events of a side and kind (often the strides over the plates) is completed
    by the detected ones farther than :data:`DISTINCT_EVENT_S` from every file event.

    ``plate_events`` are the plate-only events (default: those of ``detected`` whose source
    includes the plates). The default tolerance, 75 ms, is two frames at 60 Hz plus the ≈ 30 ms
    by which a 15 Hz zero-lag low-pass of the plate force moves a 20 N threshold crossing."""
    notes: list[str] = list(detected.notes)
    strikes = dict(detected.foot_strike)
    offs = dict(detected.foot_off)
    source = dict(detected.source)
    for label, table in (("Foot Strike", strikes), ("Foot Off", offs)):
        kind = label.lower()
        for side in _SIDES:
            f = sorted(
                float(e.time)
                for e in file_events
                if e.label == label and str(e.context).lower() == side and np.isfinite(e.time)
            )
            if not f:
                continue
            det = table.get(side, ())
            src = source.get(f"{side} {kind}", "")
            plates = (
                (plate_events.foot_strike if label == "Foot Strike" else plate_events.foot_off)
                .get(side, ())
                if plate_events is not None
                else (det if "plates" in src else ())
            )  # fmt: skip
            lo, hi = f[0] - 0.5, f[-1] + 0.5
            bad = [
                p for p in plates
                if lo <= p <= hi and min(abs(p - x) for x in f) > tolerance_s
            ]  # fmt: skip
            if bad:
                notes.append(
                    f"the file's {side} {kind} events contradict the plates (plate event at "
                    f"{bad[0]:.3f} s, nearest file event "
                    f"{min(f, key=lambda x: abs(x - bad[0])):.3f} s): detected events used"
                )
                continue
            # a file that marks only some of the trial's events (the strides over the plates):
            # the detected events of this side and kind farther than half a stride's shortest
            # duration from every file event complete it, so that every complete cycle is there
            extra = [d for d in det if min(abs(d - x) for x in f) > DISTINCT_EVENT_S]
            table[side] = tuple(sorted([*f, *extra]))
            source[f"{side} {kind}"] = "file" if not extra else f"file + {src or 'detected'}"
            if extra:
                notes.append(
                    f"the file marks {len(f)} {side} {kind} event(s); {len(extra)} detected "
                    f"({src or 'detected'}) added where it marks none"
                )
    return GaitEvents(strikes, offs, source, tuple(notes))
