"""What a static trial's marker placement needs besides
:func:`msk.personalise.scaling.place_markers`: the virtual joint-centre markers of a
lateral-marker protocol (Plug-in Gait's chord function), and the markers a static cannot place
for the task, placed from the task."""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from msk.model.core import Model
from msk.model.markersets import MarkerSetMatch
from msk.trial import Trial

__all__ = ["STATIC_CHECK_MIN_TASK_S", "chord_centres", "place_from_task"]

#: shortest task (s) whose frames seeing a marker pair can show it rigid for the static-label
#: check (:func:`msk.quality.inconsistent_static_markers`): about one step of walking, over
#: which the hip and knee flex and extend by 20–40° (distances across a joint change)
STATIC_CHECK_MIN_TASK_S = 0.5


def place_from_task(
    model: Model, trial: Trial, rot: NDArray[np.float64], match: MarkerSetMatch,
    bad: Mapping[str, float],
) -> tuple[Model, dict[str, float], dict[str, Any], list[str]]:  # fmt: skip
    """After the static placement, the markers the static cannot place for the task, placed
    from the task (:func:`msk.personalise.scaling.place_markers_from_motion` on the task with
    the model's markers and these only):

    * shoulder-girdle markers of a model without that segment (gait2392's acromia on its rigid
      torso, :func:`msk.model.markersets.shoulder_girdle_markers`): the scapula follows the
      arms, so where the static (arms out) puts them is not where they ride in the task
      (UNIPD's acromia 22–26 mm off through the walk when placed from its static, IK 17.5 →
      16.3 mm); moved on their body to their median position in the task;
    * the static markers the task contradicts (``bad``: lab label → discrepancy m,
      :func:`msk.quality.inconsistent_static_markers`): a model marker moved on its body,
      another marker fixed to its most rigid body;
    * model markers the lab rebuilds from a technical cluster (calibrated anatomical landmarks,
      :func:`msk.model.markersets.reconstructed_markers`: rigid with another marker to < 0.1 mm
      through the task): they ride the cluster's soft tissue, which sits differently on the
      bone in a standing static and in the task, so they are moved on their body to their
      median position in the task (UNIPD's ASIS/PSIS, GT, epicondyles, HF, TT, malleoli:
      thigh landmarks 9 mm distal and 8–11 mm lateral in the femur frame through Walking1 when
      placed from Static1, IK 16.3 → 14.4 mm).

    Returns the model, marker → displacement (m) of the markers moved, the record for
    ``summary.json`` ``model.static_check`` (empty without ``bad``; its quality flag) and the
    reconstructed markers moved."""
    from msk.model.markersets import reconstructed_markers, shoulder_girdle_markers
    from msk.personalise.scaling import place_markers_from_motion
    from msk.personalise.task_markers import model_frame_columns

    xm, mlabels = model_frame_columns(trial, rot, match)
    to_model = dict(match.lab_to_model)
    bad_names = {to_model.get(lab, lab) for lab in bad}
    known = set(model.marker_names)
    girdle = set(shoulder_girdle_markers(list(mlabels), [b.name for b in model.bodies]))
    # landmarks the lab rebuilds from a cluster (rigid with it through the task): placed where
    # the task's reconstruction puts them (msk.model.markersets.reconstructed_markers)
    recon = {m for m in reconstructed_markers(xm, mlabels) if m in known} - bad_names
    if not bad_names and not recon and not girdle & known:
        return model, {}, {}, []
    keep = [i for i, lab in enumerate(mlabels) if lab not in mlabels[:i] and (
        lab in bad_names or lab in known)]  # fmt: skip
    moved = sorted(n for n in bad_names | recon if n in known)
    new_markers = any(n not in known for n in bad_names)
    xm = xm[:, keep]  # the task's other columns dropped before the placement's passes
    model, placed = place_markers_from_motion(
        model, xm, [mlabels[i] for i in keep], trial.time, move=moved,
        iterations=3 if new_markers else 1,
    )  # fmt: skip
    record = {}
    if bad:
        record = {
            "contradicted_m": dict(bad),
            "moved_from_task_m": {k: v for k, v in placed["moved"].items() if k in bad_names},
            "placed_from_task": {k: v for k, v in placed["placed"].items() if k in bad_names},
        }
    return model, dict(placed["moved"]), record, sorted(recon)


def chord_centres(
    model: Model, sm: NDArray[np.float64], labels: tuple[str, ...],
    widths: Mapping[str, float], mdiam: float | None,
) -> tuple[dict[str, tuple[str, NDArray[np.float64], NDArray[np.float64]]], list[str]]:  # fmt: skip
    """The static pose of a lateral-marker protocol (no medial knee marker) as Plug-in Gait
    defines it (Davis et al. 1991): virtual markers for
    :func:`msk.personalise.scaling.place_markers` at the knee and ankle centres of the chord
    function (:func:`msk.personalise.scaling.static_joint_centres`; the tibia's and the talus'
    origins) and the lateral knee marker on the knee flexion axis at r = (knee width + marker
    diameter)/2 from the knee centre; the lateral knee and ankle markers are then placed
    (moved) where the static puts them, not held at the generic model's offsets (which differ
    from the subject's measured widths by 10–20 mm). Returns (virtual markers, markers to
    move)."""
    from msk.model.markersets import parse_label
    from msk.personalise.scaling import static_joint_centres

    if not widths:
        return {}, []
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        means = {lab: np.nanmean(sm[:, i], axis=0) for i, lab in enumerate(labels)}
    md = 0.014 if mdiam is None else float(mdiam)
    out: dict[str, tuple[str, NDArray[np.float64], NDArray[np.float64]]] = {}
    move: list[str] = []
    pts_of = static_joint_centres(model, means, widths_m=widths, marker_diameter_m=mdiam)
    for side, pts in pts_of.items():
        p = side.upper()
        knee_lat, ankle_lat = f"{p}.Knee.Lat", f"{p}.Ankle.Lat"
        if f"{p}.Knee.Med" in means or knee_lat not in means or f"{p}.knee" not in widths:
            continue  # epicondyles: the model's own knee markers place the knee
        tibia = f"tibia_{side}"
        axis = _revolute_axis(model, tibia)
        lat = next((mk.offset for mk in model.markers if mk.name == knee_lat), None)
        if axis is None or lat is None:
            continue
        # the flexion axis, pointing to the lateral side (the generic lateral knee marker's)
        knee_in_tibia = np.asarray(lat, dtype=float)  # femur frame ≈ tibia frame at θ = 0
        axis = axis if float(np.dot(axis, knee_in_tibia)) >= 0.0 else -axis
        r = 0.5 * (widths[f"{p}.knee"] + md)
        out[f"{p}.hip_centre"] = (f"femur_{side}", np.zeros(3), pts["hip"])
        out[f"{p}.knee_centre"] = (tibia, np.zeros(3), pts["knee"])
        out[f"{p}.ankle_centre"] = (f"talus_{side}", np.zeros(3), pts["ankle"])
        out[f"{p}.knee_axis"] = (tibia, r * axis, means[knee_lat])
        move += [m for m in (knee_lat, ankle_lat) if m in model.marker_names]
    # the pelvis pose the hip centres came from: the mid-PSIS as the sacral marker (IOR, PiG)
    psis = [lab for lab in means if parse_label(lab).landmark == "psis"]
    sacral = [mk for mk in model.markers if mk.body == "pelvis"
              and parse_label(mk.name).landmark == "sacrum"]  # fmt: skip
    if out and len(psis) == 2 and len(sacral) == 1 and sacral[0].name not in means:
        mid = 0.5 * (means[psis[0]] + means[psis[1]])
        out[f"{sacral[0].name}:mid_psis"] = ("pelvis", np.asarray(sacral[0].offset, float), mid)
    return out, move


def _revolute_axis(model: Model, body: str) -> NDArray[np.float64] | None:
    """Unit axis (in ``body``'s frame) of the revolute axis of the joint whose child is
    ``body`` (the knee's flexion axis for a tibia), None without one."""
    for j in model.joints:
        if j.child != body:
            continue
        for ax in j.axes:
            if ax.kind == "revolute":
                v = np.asarray(j.child_offset.rotation, dtype=float) @ np.asarray(ax.axis, float)
                return np.asarray(v / np.linalg.norm(v), dtype=float)
    return None
