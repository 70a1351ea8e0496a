"""Step ``gait_cycle`` (not a recorded stage): the gait events — the file's where they agree
with the plates, else detected from the plates and the kinematics (Zeni et al. 2008) — the gait
cycle of the report, and the measured knee contact force on the kinematics' time base."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np

from msk.personalise import Personalisation
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.records import GaitCycle, KneeContact, Loads

__all__ = ["run"]


def run(
    inputs: SessionInputs,
    model: Personalisation,
    kinematics: Any,
    loads: Loads,
    knee_contact: KneeContact | None,
) -> GaitCycle:
    from msk.kinematics.events import detect_gait_events, reconcile

    events = reconcile(
        model.trial.events,
        detect_gait_events(model.model, kinematics, loads.external, observed=loads.measured),
    )
    strikes = sorted(events.foot_strike.get(inputs.side, ()))
    t = kinematics.time

    def on_plates(c: tuple[float, float]) -> float:
        sel = (t >= c[0]) & (t <= c[1])
        return float(loads.measured[sel].mean()) if sel.any() else 0.0

    # the gait cycle of the report: the one the plates measure best (the first on a tie; a
    # walkway's plates often see the second cycle of the trial, not the first)
    cycles = list(itertools.pairwise(strikes))
    cycle = max(cycles, key=on_plates) if cycles else None
    measured = None
    meas = None if knee_contact is None else knee_contact.measured
    if meas is not None and (meas.time is not None or cycle is not None):
        if meas.time is not None:
            tm = np.asarray(meas.time, dtype=float)
        else:
            assert cycle is not None  # the condition above
            tm = cycle[0] + np.asarray(meas.cycle_fraction, dtype=float) * (cycle[1] - cycle[0])
        measured = {}
        for comp in ("total", "medial", "lateral"):
            y = np.asarray(getattr(meas, comp), dtype=float)
            if np.isfinite(y).any():
                measured[comp] = np.interp(t, tm, y, left=np.nan, right=np.nan)
    return GaitCycle(events, cycle, measured)
