"""Whether the configured measured knee contact force was compared, and why not.

The implant comparison is the headline validation figure of a session with an instrumented
knee: when a ``contact_force`` file is configured for the task trial and no
``knee_contact_*`` figure came out of the ``comparison`` stage, the run says why, as a quality
flag (``contact_comparison_not_available``): no gait cycle to place a cycle-normalised force
on, no measured force from the contact stage, or a measured force whose time base does not
overlap the trial's frames.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from msk.quality import Flag

__all__ = ["MIN_COMPARED_FRAMES", "comparison_flags"]

#: the comparison needs at least this many frames with both forces finite
MIN_COMPARED_FRAMES = 5


def comparison_flags(
    trial: str,
    contact_force: str | os.PathLike[str] | None,
    comparison: Mapping[str, object] | None,
    time: ArrayLike,
    *,
    side: str,
    cycle_ran: bool = True,
    cycle: tuple[float, float] | None = None,
    measured: Mapping[str, ArrayLike] | None = None,
    foot_strikes: Sequence[float] = (),
) -> list[Flag]:
    """The flag (a list of zero or one) saying why a configured measured contact force was
    not compared.

    Args:
        trial: the task trial's name.
        contact_force: the measured contact force file configured for it (None: none, no flag).
        comparison: the ``comparison`` figures by name (a ``knee_contact*`` one: compared).
        time: the kinematics' time base (s).
        side: the analysed side (``"left"``/``"right"``).
        cycle_ran: whether the gait cycle step ran.
        cycle: the analysed side's gait cycle ``(start, end)`` in s, None without one.
        measured: component → measured force on ``time`` (NaN outside the measured cycle),
            None when the contact stage gave none.
        foot_strikes: the analysed side's foot-strike times (s) found.
    """
    if contact_force is None:
        return []
    if any(str(k).startswith("knee_contact") for k in (comparison or {})):
        return []
    name = os.path.basename(os.fspath(contact_force))
    t = np.asarray(time, dtype=float)
    n_frames = 0
    if not cycle_ran:
        why = "the gait cycle step did not run (a core stage is missing)"
    elif measured is None and cycle is None:
        why = (
            f"no gait cycle of the {side} side to place it on (two foot strikes are "
            f"needed; found {len(tuple(foot_strikes))} in the file's events or from the plates)"
        )
    elif measured is None:
        why = "the knee_contact stage gave no measured force (see the stages' notes)"
    else:
        both = [np.isfinite(np.asarray(v, dtype=float)) for v in measured.values()]
        n_frames = int(max((b.sum() for b in both), default=0))
        span = f"{t[0]:.3f}–{t[-1]:.3f} s" if t.size else "no frames"
        placed = f", placed on the gait cycle {cycle[0]:.3f}–{cycle[1]:.3f} s," if cycle else ""
        why = (
            f"it overlaps{placed} {n_frames} of the trial's frames ({span}) where the "
            f"prediction is finite (at least {MIN_COMPARED_FRAMES} needed): its time base or "
            "the trial's first frame do not match, or the predicted contact force is not "
            "available"
        )
    return [
        Flag(
            trial=trial,
            quantity="contact_comparison_not_available",
            value=float(n_frames),
            threshold=float(MIN_COMPARED_FRAMES),
            message=f"measured knee contact force {name} not compared: {why}",
        )
    ]
