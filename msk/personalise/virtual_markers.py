"""Virtual markers: points a lab did not mark, made from the markers it did.

The pelvis of a marker set with two ASIS and two PSIS markers and no sacral marker (a common
set: Rajagopal et al. 2016's, CAST, IOR) has, in a model whose pelvis carries ASIS and sacral
markers (gait2392), only the two ASIS to pose it when there is no static trial: the PSIS
markers are not the model's and are placed from the motion like any lab marker, so the
pelvis' rotation about the inter-ASIS axis (its tilt) is left to the legs' markers (tilt
11° against 1° in the reference IK of Rajagopal et al.'s walk). The midpoint of the two PSIS
is where a sacral marker sits (on the sacrum between the PSIS: Davis et al. 1991; Plug-in Gait
takes it so, "SACR = (LPSI + RPSI)/2", Vicon Plug-in Gait reference guide), and it pins the
tilt to the model's own ASIS–sacrum geometry: :func:`with_virtual_sacrum` adds it to a trial.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

__all__ = ["with_virtual_sacrum"]


def with_virtual_sacrum(trial: Any, model: Any) -> tuple[Any, dict[str, Any] | None]:
    """``trial`` (:class:`msk.trial.Trial`) with the model's sacral marker added as the
    midpoint of the trial's two PSIS markers (NaN where either is missing or an exact zero),
    when the model has one sacral marker on its pelvis and the trial has no sacral marker but
    both PSIS; and a note for ``summary.json`` (None when nothing was added)."""
    from msk.model.markersets import parse_label

    sacral = [
        mk.name for mk in model.markers
        if mk.body == "pelvis" and parse_label(mk.name).landmark == "sacrum"
    ]  # fmt: skip
    labels = list(trial.marker_labels)
    parsed = {lab: parse_label(lab) for lab in labels}
    if len(sacral) != 1 or sacral[0] in labels:
        return trial, None
    if any(p.landmark == "sacrum" for p in parsed.values()):
        return trial, None
    psis = {p.side: lab for lab, p in parsed.items() if p.landmark == "psis" and p.side}
    if set(psis) != {"R", "L"}:
        return trial, None
    x = np.asarray(trial.markers, dtype=float)
    r, left = (x[:, labels.index(psis[s])] for s in ("R", "L"))
    gap = (r == 0.0).all(axis=-1) | (left == 0.0).all(axis=-1)
    mid = 0.5 * (r + left)
    mid[gap] = np.nan
    markers = np.concatenate([x, mid[:, None]], axis=1)
    out = dataclasses.replace(trial, markers=markers, marker_labels=(*labels, sacral[0]))
    return out, {
        "marker": sacral[0],
        "from": [psis["R"], psis["L"]],
        "why": "no sacral marker: the PSIS midpoint stands for it (pelvis tilt)",
    }
