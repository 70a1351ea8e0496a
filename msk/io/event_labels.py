"""Gait events in the namings labs store them, read as foot strikes and foot offs per side.

A C3D's ``EVENT`` group gives each event a label and a context. Vicon writes ``Foot Strike`` /
``Foot Off`` with the context ``Left`` / ``Right``; Qualisys (and many lab scripts) write the
side and the kind in the label — ``LHS``, ``RHS`` (heel strike), ``LTO``, ``RTO`` (toe off) —
with an empty or ``General`` context; others spell out ``Left Heel Strike``, ``R_FS``,
``Right Toe Off``, ``LIC`` (initial contact). :func:`standard_events` rewrites every event it
recognises as Vicon's ``Foot Strike`` / ``Foot Off`` with context ``Left`` / ``Right`` (what
:func:`msk.kinematics.events.reconcile` reads) and returns the others apart, so that a reader can
say
which labels it did not use instead of dropping them silently.

Recognised (case, spaces, ``_`` and ``-`` ignored): a side from the context (``left``, ``l``,
``right``, ``r``) or, failing that, a prefix of the label (``left``, ``right``, ``l``, ``r``);
and a kind — strike: ``footstrike``, ``heelstrike``, ``footcontact``, ``heelcontact``,
``initialcontact``, ``hs``, ``fs``, ``ic``; off: ``footoff``, ``toeoff``, ``fo``, ``to``.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

from msk.trial import Event

__all__ = ["OFF_NAMES", "STRIKE_NAMES", "gait_event", "standard_events"]

#: Label stems (lower case, no separators) read as a foot strike.
STRIKE_NAMES: tuple[str, ...] = (
    "footstrike", "heelstrike", "footcontact", "heelcontact", "initialcontact", "hs", "fs", "ic",
)  # fmt: skip
#: Label stems read as a foot off.
OFF_NAMES: tuple[str, ...] = ("footoff", "toeoff", "fo", "to")

_SIDE_WORDS = {"left": "Left", "l": "Left", "right": "Right", "r": "Right"}


def _squash(s: str) -> str:
    return re.sub(r"[\s_\-]+", "", s.strip().lower())


def _kind(stem: str) -> str | None:
    if stem in STRIKE_NAMES:
        return "Foot Strike"
    if stem in OFF_NAMES:
        return "Foot Off"
    return None


def gait_event(label: str, context: str) -> tuple[str, str] | None:
    """``(kind, side)`` — ``"Foot Strike"``/``"Foot Off"``, ``"Left"``/``"Right"`` — of an event
    label and context, None when they name no foot strike or off of a side."""
    lab, ctx = _squash(label), _squash(context)
    side = _SIDE_WORDS.get(ctx)
    if side is not None:
        kind = _kind(lab)
        if kind is not None:
            return kind, side
    # the side in the label (longest prefix first: "left…" before "l…")
    for word in ("left", "right", "l", "r"):
        if lab.startswith(word):
            kind = _kind(lab[len(word) :])
            if kind is not None:
                label_side = _SIDE_WORDS[word]
                if side is not None and side != label_side:
                    return None  # "LHS" in the Right context: contradictory, not guessed
                return kind, label_side
    return None


def standard_events(events: Iterable[Event]) -> tuple[tuple[Event, ...], tuple[Event, ...]]:
    """(every event recognised by :func:`gait_event`, as ``Foot Strike``/``Foot Off`` with
    context ``Left``/``Right``, time unchanged; the events not recognised, as they were)."""
    ok: list[Event] = []
    other: list[Event] = []
    for e in events:
        g = gait_event(e.label, e.context)
        if g is None:
            other.append(e)
        else:
            ok.append(Event(label=g[0], context=g[1], time=e.time))
    return tuple(ok), tuple(other)
