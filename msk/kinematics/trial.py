"""Inverse kinematics of a whole trial in the model frame: the frames IK can trust
(:data:`MIN_MARKER_FRACTION` of the best-seen model markers, every marked leg segment in view),
then :func:`msk.kinematics.ik.solve_kinematics`."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Protocol, cast

import numpy as np
from numpy.typing import NDArray

from msk.kinematics.ik import Kinematics
from msk.model.core import Model

__all__ = ["MIN_MARKER_FRACTION", "MarkerTrial", "solve_trial"]

#: a frame is solved by IK when it sees this fraction of the most model markers any frame sees
MIN_MARKER_FRACTION = 0.5


class MarkerTrial(Protocol):
    """What :func:`solve_trial` reads of a trial: markers ``(N, M, 3)`` m in the model frame
    (NaN gaps) and their time ``(N,)`` s (a :class:`msk.trial.Trial` is one)."""

    @property
    def markers(self) -> NDArray[np.float64]: ...

    @property
    def time(self) -> NDArray[np.float64]: ...


def solve_trial(
    model: Model,
    trial: MarkerTrial,
    labels: Sequence[str],
    *,
    weights: Mapping[str, float] | None,
    held: Mapping[str, tuple[float, float]] | None,
    cutoff_hz: float | None,
    initial_q: NDArray[np.float64] | None = None,
    acceleration_domain: str = "coordinates",
) -> Kinematics:
    """IK of a trial in the model frame; a frame that sees fewer than half of the model markers
    the trial tracks at best is not solved (a subject walking out of the capture volume leaves
    the acromia alone in view: IK there would give the legs any pose), nor a frame where a leg
    segment carrying markers in this trial has none in view (its pose would come from the
    neighbours only, and joint torques there from a guessed pose). ``initial_q``: as
    :func:`msk.kinematics.ik.solve_kinematics`'s (a warm start). ``acceleration_domain``
    ``"segment_com"``: θ̈ made consistent with the low-passed segment COMs
    (:func:`msk.kinematics.com_consistency.com_consistent_kinematics`)."""
    from msk.kinematics.ik import solve_kinematics

    names = set(model.marker_names)
    cols = [i for i, lab in enumerate(labels) if lab in names]
    # (N, used markers); the flags first, then the columns (not a copy of the used markers'
    # positions)
    finite = cast("NDArray[np.bool_]", np.isfinite(trial.markers).all(axis=2))
    seen = finite[:, cols]
    body_of = {m.name: m.body for m in model.markers}
    blind = np.zeros(trial.time.size, dtype=bool)
    for body in {body_of[labels[i]] for i in cols}:
        if body.startswith(("pelvis", "femur", "tibia", "calcn")):
            on = [k for k, i in enumerate(cols) if body_of[labels[i]] == body]
            blind |= ~seen[:, on].any(axis=1)
    markers = np.asarray(trial.markers, dtype=float)
    if blind.any():  # a copy only when frames are blanked (no copy of a long trial)
        markers = markers.copy()
        markers[blind] = np.nan
    kin = solve_kinematics(
        model,
        markers,
        labels,
        trial.time,
        weights=dict(weights or {}) or None,
        coordinate_tasks=dict(held or {}) or None,
        cutoff_hz=cutoff_hz,
        min_markers=max(3, int(np.ceil(MIN_MARKER_FRACTION * seen.sum(axis=1).max()))),
        initial_q=initial_q,
    )
    if acceleration_domain == "segment_com":
        from msk.kinematics.com_consistency import com_consistent_kinematics

        kin = com_consistent_kinematics(model, kin)
    return kin
