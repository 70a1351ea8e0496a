"""The task trial's markers as scaling and placement read them: left/right label pairs swapped
back, the matched columns in the model frame, and the lab's origin taken out."""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from msk.model.core import Model
from msk.model.markersets import MarkerSetMatch
from msk.trial import Trial

__all__ = ["lab_origin_offset", "model_frame_columns", "swap_back"]


def swap_back(trial: Trial) -> tuple[Trial, dict[str, float]]:
    """``trial`` with the columns of left/right label pairs that its markers show swapped
    exchanged back (:func:`msk.quality.swapped_label_pairs`: the right-side marker ≥ 3 cm to
    the subject's left in ≥ 80 % of the frames, judged from the pelvis markers, before any
    model sees them), and "right/left" → median signed separation (m) of each pair exchanged
    (``summary.json`` ``model.marker_set.swapped_back``; a quality flag says so)."""
    from msk.model.markersets import zeros_as_gaps_view
    from msk.quality import swapped_label_pairs

    pairs = swapped_label_pairs(zeros_as_gaps_view(trial.markers), trial.marker_labels, trial.up)
    if not pairs:
        return trial, {}
    markers = np.array(trial.markers, dtype=float, copy=True)
    labels = list(trial.marker_labels)
    for r, lft, _ in pairs:
        i, j = labels.index(r), labels.index(lft)
        markers[:, [i, j]] = markers[:, [j, i]]
    fixed = dataclasses.replace(trial, markers=markers)
    return fixed, {f"{r}/{lft}": dz for r, lft, dz in pairs}


def lab_origin_offset(model: Model, markers: NDArray[np.float64]) -> NDArray[np.float64]:
    """(3,) m to subtract from a motion trial's markers (model frame) so that their median
    (over frames and markers, per axis) sits at the centroid of ``model``'s markers in its
    default pose: the trial then no longer depends on where the lab put its origin (the
    inverse kinematics of :func:`msk.personalise.scaling.scale_from_motion` and
    :func:`msk.personalise.scaling.place_markers_from_motion` start from the default pose and
    bound the pelvis translations). Zero when no marker is finite."""
    from msk.model.core import marker_positions

    x = np.asarray(markers, dtype=float)
    finite = np.isfinite(x).all(axis=-1)
    if not finite.any() or not model.markers:
        return np.zeros(3)
    med = np.median(x[finite], axis=0)
    pts = marker_positions(model, model.default_coordinates())[0]
    return np.asarray(med - pts.mean(axis=0), dtype=float)


def model_frame_columns(
    trial: Trial, rot: NDArray[np.float64], match: MarkerSetMatch
) -> tuple[NDArray[np.float64], tuple[str, ...]]:
    """``match.apply(trial.rotated(rot).markers, trial.marker_labels)`` (the matched columns in
    the model frame, model names, exact zeros as gaps) rotated block by block of
    :data:`msk.io.frames.HEADING_BLOCK` frames into the one array returned: a long trial's
    markers are not rotated whole first. Each frame's values are the whole product's."""
    from msk.io.frames import HEADING_BLOCK

    x = np.asarray(trial.markers, dtype=float)
    r = np.asarray(rot, dtype=float)
    labels = trial.marker_labels
    n = x.shape[0]
    first, names = match.apply(x[:HEADING_BLOCK] @ r.T, labels)
    if n <= HEADING_BLOCK:
        return first, names
    out = np.empty((n, *first.shape[1:]))
    out[:HEADING_BLOCK] = first
    for c0 in range(HEADING_BLOCK, n, HEADING_BLOCK):
        out[c0 : c0 + HEADING_BLOCK] = match.apply(x[c0 : c0 + HEADING_BLOCK] @ r.T, labels)[0]
    return out, names
