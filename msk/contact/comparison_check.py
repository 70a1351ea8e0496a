"""Whether the configured measured knee contact force was compared, and why not.

The implant comparison is the headline validation figure of a session with an instrumented
knee: when a ``contact_force`` file is configured for the task trial and no
``knee_contact_*`` figure came out of the ``comparison`` stage, the run says why, as a quality
flag (``contact_comparison_not_available``): no gait cycle to place a cycle-normalised force
on, no measured force from the contact stage, or a measured force whose time base does not
overlap the trial's frames.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

__all__ = ["MIN_COMPARED_FRAMES", "comparison_flags"]

#: the comparison needs at least this many frames with both forces finite
MIN_COMPARED_FRAMES = 5


def comparison_flags(
    inputs: Any,
    gait_cycle: Any,
    comparison: Mapping[str, Any] | None,
    time: np.ndarray,
) -> list[dict[str, Any]]:
    """The flag (a list of zero or one) saying why a configured measured contact force was
    not compared; ``time`` is the kinematics' time base (s)."""
    task = inputs.task
    if task is None or getattr(task, "contact_force", None) is None:
        return []
    if any(str(k).startswith("knee_contact") for k in (comparison or {})):
        return []
    name = getattr(task.contact_force, "name", str(task.contact_force))
    measured = None if gait_cycle is None else gait_cycle.measured_contact
    t = np.asarray(time, dtype=float)
    n_frames = 0
    if gait_cycle is None:
        why = "the gait cycle step did not run (a core stage is missing)"
    elif measured is None and gait_cycle.cycle is None:
        strikes = gait_cycle.events.foot_strike.get(inputs.side, ()) if gait_cycle.events else ()
        why = (
            f"no gait cycle of the {inputs.side} side to place it on (two foot strikes are "
            f"needed; found {len(tuple(strikes))} in the file's events or from the plates)"
        )
    elif measured is None:
        why = "the knee_contact stage gave no measured force (see the stages' notes)"
    else:
        both = [np.isfinite(np.asarray(v, dtype=float)) for v in measured.values()]
        n_frames = int(max((b.sum() for b in both), default=0))
        span = f"{t[0]:.3f}–{t[-1]:.3f} s" if t.size else "no frames"
        c = gait_cycle.cycle
        placed = f", placed on the gait cycle {c[0]:.3f}–{c[1]:.3f} s," if c else ""
        why = (
            f"it overlaps{placed} {n_frames} of the trial's frames ({span}) where the "
            f"prediction is finite (at least {MIN_COMPARED_FRAMES} needed): its time base or "
            "the trial's first frame do not match, or the predicted contact force is not "
            "available"
        )
    return [
        {
            "trial": task.name,
            "quantity": "contact_comparison_not_available",
            "value": float(n_frames),
            "threshold": float(MIN_COMPARED_FRAMES),
            "message": f"measured knee contact force {name} not compared: {why}",
        }
    ]
