"""How a leg measured only from the pelvis to the heel is split between the femur and the tibia:
by the functional knee (and, on request, ankle) of its marker clusters.

Without knee or ankle markers (cluster-only protocols: UWA, the Grand Challenge DM and JW
walks) the femur and the tibia are scaled by one factor, the pose-matched ASIS-to-heel distance
over the model's (:data:`msk.personalise.scaling.SEGMENT_MEASUREMENTS`, ``leg_<side>``), which keeps
the
generic model's femur : tibia proportion. A walk moves the thigh, shank and foot clusters
through the knee's and the ankle's range, and their functional centres measure the split
(:func:`functional_leg_split`):

* the hip centre per frame: the model's, carried by its pelvis posed on its pelvis markers
  (Söderkvist & Wedin 1993, :func:`msk.personalise.functional_joints.segment_poses`);
* the knee: SCoRE between the thigh's and the shank's markers (Ehrig et al. 2006, Eq. 3) with
  its flexion axis left free (SARA, Ehrig et al. 2007;
  :func:`msk.personalise.functional_joints.score`,
  ``hinge=True``); the femur's length is the distance from the hip centre to that axis
  (median over the frames), its factor the present one times that length over the model's own
  femur measured the same way (SCoRE of the model's femur and tibia moved over the same range);
* the tibia: the rest of the leg — the model's hip-to-ankle length (the ASIS-to-heel
  measurement) minus the functional femur. With ``use_ankle`` it is measured instead, where the
  ankle is determined: SCoRE between the shank's and the calcaneus' markers, its main axis left
  free too, the tibia the distance from the knee axis to that point. The pipeline does not use
  it (its figures are reported): between trials of one subject the functional femur agrees to
  ~10 mm and this tibia does not (Grand Challenge DM, left: 411 / 430 / 431 mm in three trials),
  and a shank cluster sliding on the bone moves the knee's estimate along the tibia (synthetic:
  8 mm of slide, −5 mm of tibia; docs/validation.md).

Each centre is used only when the data determine it (:data:`CHECKS`): enough frames, enough
rotation about the joint's axis (SCoRE's error grows as the range of motion shrinks, Ehrig et
al. 2006: we ask the knee for 30°, half of a walking knee's flexion, and the ankle for 15°,
half of a walking ankle's range), a mismatch of its two estimates within soft tissue's (thigh
clusters move 10–30 mm on the femur in gait, Leardini et al. 2005, Gait Posture 21:212–225;
shank clusters less), a femur and tibia within 15 % of the leg factor's (a cluster on the wrong
segment, not a subject) and, for the ankle, hip-to-ankle within 5 % of the ASIS-to-heel
measurement. Otherwise the side keeps the leg factor, and the reason is said.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from msk.model.core import Model, forward_kinematics
from msk.personalise.functional_joints import (
    ScoreFit,
    SegmentPoses,
    cluster_shape,
    score,
    segment_poses,
)
from msk.units import Array

__all__ = ["CHECKS", "LEG_SPLIT_METHODS", "LegSplit", "functional_leg_split"]


#: the quality checks of a functional centre (see the module docstring)
CHECKS: Mapping[str, float] = {
    "min_frames": 50,
    "knee_min_range_deg": 30.0,
    "knee_max_mismatch_m": 0.025,
    "ankle_min_range_deg": 15.0,
    "ankle_max_mismatch_m": 0.010,
    "max_change": 0.15,
    "ankle_max_leg_difference": 0.05,
}

#: how a side's femur and tibia were split (``LegSplit.method``)
LEG_SPLIT_METHODS: tuple[str, ...] = (
    "functional knee and ankle",
    "functional knee, tibia the rest of the leg",
    "leg factor",
)


@dataclass(frozen=True)
class LegSplit:
    """One side's split.

    Attributes:
        side: "r" or "l".
        method: one of :data:`LEG_SPLIT_METHODS`.
        reason: why (what was not determined, or "" when both centres were used).
        leg_factor: the femur's and tibia's factor before (the ASIS-to-heel one).
        femur_factor: the femur's factor after (= ``leg_factor`` with "leg factor").
        tibia_factor: the tibia's factor after.
        femur_length_m: hip centre to the functional knee axis (NaN without a knee).
        tibia_length_m: functional knee axis to ankle centre (NaN without an ankle).
        model_femur_m: the model's hip-to-knee distance before (default pose).
        model_tibia_m: the model's knee-to-ankle distance before.
        knee: the knee fit's figures (frames, mismatch_mm, range_deg, condition) or empty.
        ankle: the ankle fit's figures or empty.
    """

    side: str
    method: str
    reason: str
    leg_factor: float
    femur_factor: float
    tibia_factor: float
    femur_length_m: float = float("nan")
    tibia_length_m: float = float("nan")
    model_femur_m: float = float("nan")
    model_tibia_m: float = float("nan")
    knee: Mapping[str, float] = field(default_factory=dict)
    ankle: Mapping[str, float] = field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        """JSON-ready (lengths in m, NaN as None)."""

        def num(v: float) -> float | None:
            return None if not np.isfinite(v) else float(v)

        return {
            "method": self.method,
            "reason": self.reason,
            "leg_factor": self.leg_factor,
            "femur_factor": self.femur_factor,
            "tibia_factor": self.tibia_factor,
            "femur_length_m": num(self.femur_length_m),
            "tibia_length_m": num(self.tibia_length_m),
            "model_femur_m": num(self.model_femur_m),
            "model_tibia_m": num(self.model_tibia_m),
            "knee": dict(self.knee),
            "ankle": dict(self.ankle),
        }


def _figures(fit: ScoreFit) -> dict[str, float]:
    sv = fit.singular_values
    return {
        "frames": float(fit.frames),
        "mismatch_mm": 1000.0 * fit.mismatch_rms_m,
        "range_deg": float(np.degrees(fit.rotation_range_rad)),
        "condition": float(sv[-1] / sv[0]),
    }


def _pelvis_poses(
    model: Model, x: Array, labels: Sequence[str], min_frames: int
) -> SegmentPoses | None:
    """The pelvis' poses in the model's pelvis frame, from its model markers' offsets (the
    frame that carries the model's hip centres), None with fewer than 3 tracked markers."""
    col = {lab: i for i, lab in reversed(list(enumerate(labels)))}
    mks = [
        mk for mk in model.markers
        if mk.body == "pelvis" and mk.name in col
        and int(np.isfinite(x[:, col[mk.name]]).all(axis=1).sum()) >= min_frames
    ]  # fmt: skip
    if len(mks) < 3:
        return None
    local = np.array([np.asarray(mk.offset, dtype=float) for mk in mks])
    return segment_poses(local, x[:, [col[mk.name] for mk in mks]])


def _cluster_poses(
    names: Sequence[str], x: Array, labels: Sequence[str], min_frames: int
) -> SegmentPoses | None:
    """A cluster's poses in a frame of its own
    (:func:`msk.personalise.functional_joints.cluster_shape`):
    its markers tracked in ``min_frames`` frames, the least tracked left out until
    ``min_frames`` frames track all of them; None when fewer than 3 remain."""
    col = {lab: i for i, lab in reversed(list(enumerate(labels)))}
    cols = [col[n] for n in dict.fromkeys(names) if n in col]
    seen = {c: np.isfinite(x[:, c]).all(axis=1) for c in cols}
    cols = sorted((c for c in cols if seen[c].sum() >= min_frames), key=lambda c: -seen[c].sum())
    while len(cols) >= 3 and np.logical_and.reduce([seen[c] for c in cols]).sum() < min_frames:
        cols = cols[:-1]
    if len(cols) < 3:
        return None
    return segment_poses(cluster_shape(x[:, cols]), x[:, cols])


def _revolute_coordinate(model: Model, child: str) -> str | None:
    """The free coordinate of the first revolute axis of the joint whose child is ``child``."""
    coords = {c.name: c for c in model.coordinates}
    for j in model.joints:
        if j.child != child:
            continue
        for ax in j.axes:
            c = coords.get(ax.coordinate or "")
            if ax.kind == "revolute" and c is not None and not c.locked:
                return c.name
    return None


def _model_fit(model: Model, a: str, b: str, coordinate: str, angles: Array) -> ScoreFit:
    """SCoRE (hinge) of the model's own bodies ``a`` and ``b`` with ``coordinate`` at
    ``angles`` (rad; the others at their defaults): the model's functional axis and centre by
    the same definition as the data's."""
    data = model.create_data()
    th = model.default_coordinates()
    k = model.coordinate_index(coordinate)
    rot: dict[str, list[Array]] = {a: [], b: []}
    org: dict[str, list[Array]] = {a: [], b: []}
    for ang in angles:
        q = th.copy()
        q[k] = ang
        forward_kinematics(model, data, q)
        for body in (a, b):
            o = data.oMf[model.body_frame[body]]
            rot[body].append(np.array(o.rotation, dtype=float, copy=True))
            org[body].append(np.array(o.translation, dtype=float, copy=True))
    n = len(angles)

    def poses(body: str) -> SegmentPoses:
        return SegmentPoses(np.array(rot[body]), np.array(org[body]), np.ones(n, bool), np.zeros(n))

    return score(poses(a), poses(b), hinge=True)


def _flexion_angles(model: Model, coordinate: str, range_rad: float, n: int = 25) -> Array:
    """``n`` angles over ``range_rad`` from 0 towards the side of 0 holding most of the
    coordinate's range (a knee's flexion side), clipped to the range."""
    lo, hi = next(c.range for c in model.coordinates if c.name == coordinate)
    if -lo >= hi:
        return np.linspace(0.0, max(lo, -range_rad), n)
    return np.linspace(0.0, min(hi, range_rad), n)


def _centred_angles(model: Model, coordinate: str, range_rad: float, n: int = 25) -> Array:
    """``n`` angles over ``range_rad`` centred on 0, clipped to the coordinate's range."""
    lo, hi = next(c.range for c in model.coordinates if c.name == coordinate)
    return np.linspace(max(lo, -range_rad / 2), min(hi, range_rad / 2), n)


def _perp_length(d: Array, n: Array) -> Array:
    """‖d − (d·n) n‖ per row (d (N, 3), n (N, 3) unit)."""
    return np.linalg.norm(d - np.sum(d * n, axis=1)[:, None] * n, axis=1)


def functional_leg_split(
    model: Model,
    markers: ArrayLike,
    labels: Sequence[str],
    leg_factors: Mapping[str, float],
    *,
    segments: Mapping[str, Sequence[str]] | None = None,
    checks: Mapping[str, float] | None = None,
    use_ankle: bool = False,
) -> dict[str, LegSplit]:
    """Femur and tibia factors of each side of ``leg_factors`` from its functional knee and
    ankle (the module docstring), or that side's leg factor and why.

    Lengths are compared like with like: the model's femur is the distance from its hip centre
    to the functional axis of its own knee (SCoRE of its femur and tibia bodies with the knee
    moved over the range the data show), its tibia the distance from that axis to its own
    ankle's functional centre (the ankle moved likewise, the subtalar at neutral); the data's by
    the same definitions from the clusters. A factor is the current one times the data's
    length over the model's.

    Args:
        model: the scaled model with its markers placed (the thigh, shank and calcaneus
            clusters on their bodies: :func:`msk.personalise.scaling.place_markers_from_motion` or
            :func:`msk.personalise.scaling.place_markers`), femur and tibia scaled by
            ``leg_factors``.
        markers: (N, M, 3) m, a motion trial in the model's frame (NaN gaps).
        labels: the M labels (model marker names).
        leg_factors: side ("r"/"l") → the factor femur and tibia share.
        segments: body → the labels of the markers on it (default: ``model``'s markers on
            it); the femur's, tibia's and calcaneus' are posed as rigid clusters of their own
            shape, the pelvis on the model's pelvis markers.
        checks: overrides of :data:`CHECKS`.
        use_ankle: the tibia from the functional ankle where it is determined (else, and by
            default, the rest of the leg; the ankle's figures are reported either way: see
            the module docstring for why the pipeline does not use it).

    Returns:
        side → :class:`LegSplit`.
    """
    ck = {**CHECKS, **(checks or {})}
    x = np.asarray(markers, dtype=float)
    labels = tuple(labels)
    min_frames = int(ck["min_frames"])
    data = model.create_data()
    forward_kinematics(model, data, model.default_coordinates())
    on: dict[str, list[str]] = {}
    for mk in model.markers:
        on.setdefault(mk.body, []).append(mk.name)
    on.update({b: list(v) for b, v in (segments or {}).items()})
    pelvis = _pelvis_poses(model, x, labels, min_frames) if "pelvis" in model.body_frame else None
    sf = model.metadata.get("scale_factors", {})
    out: dict[str, LegSplit] = {}
    for side, s_leg in leg_factors.items():
        femur, tibia, talus, calcn = (f"{b}_{side}" for b in ("femur", "tibia", "talus", "calcn"))
        knee_c = _revolute_coordinate(model, tibia)
        ankle_c = _revolute_coordinate(model, talus)

        def keep(reason: str, **kw: Any) -> LegSplit:
            return LegSplit(side, "leg factor", reason, s_leg, s_leg, s_leg, **kw)  # noqa: B023

        if (
            not all(b in model.body_frame for b in (femur, tibia, talus, calcn))
            or knee_c is None
            or ankle_c is None
        ):
            out[side] = keep("the model has no femur, tibia, talus and calcaneus with a knee "
                             "and an ankle on this side")  # fmt: skip
            continue
        c_f = float(np.asarray(sf.get(femur, [s_leg]), dtype=float).reshape(-1)[0])
        c_t = float(np.asarray(sf.get(tibia, [s_leg]), dtype=float).reshape(-1)[0])
        thigh, shank, foot = (
            _cluster_poses(on.get(b, []), x, labels, min_frames) for b in (femur, tibia, calcn)
        )
        missing = [n for n, p in (("pelvis", pelvis), ("thigh", thigh), ("shank", shank))
                   if p is None]  # fmt: skip
        if missing:
            out[side] = keep(f"fewer than 3 tracked markers on the {' and '.join(missing)}")
            continue
        assert pelvis is not None and thigh is not None and shank is not None
        try:
            knee = score(thigh, shank, hinge=True)
        except ValueError:
            out[side] = keep("the thigh and shank are posed together in < 2 frames")
            continue
        kf = _figures(knee)
        # the hip centre per frame: the pelvis' pose carrying the model's hip
        o_pelvis = data.oMf[model.body_frame["pelvis"]]
        o_femur = np.asarray(data.oMf[model.body_frame[femur]].translation, dtype=float)
        hip_local = np.asarray(o_pelvis.actInv(o_femur), dtype=float)
        hip = np.einsum("nij,j->ni", pelvis.rotation, hip_local) + pelvis.origin
        use = knee.used & pelvis.valid
        why = []
        if use.sum() < min_frames:
            why.append(f"{int(use.sum())} frames pose the pelvis, thigh and shank (< {min_frames})")
        if kf["range_deg"] < ck["knee_min_range_deg"]:
            why.append(f"the knee moves {kf['range_deg']:.0f}° (< {ck['knee_min_range_deg']:.0f}°)")
        if knee.mismatch_rms_m > ck["knee_max_mismatch_m"]:
            why.append(
                f"the thigh's and shank's knee centres differ by {kf['mismatch_mm']:.0f} mm RMS "
                f"(> {1000 * ck['knee_max_mismatch_m']:.0f})"
            )
        if why:
            out[side] = keep("knee not determined: " + "; ".join(why), knee=kf)
            continue
        # the model's own functional knee over the same range: femur = hip to its axis
        km = _model_fit(
            model, femur, tibia, knee_c, _flexion_angles(model, knee_c, knee.rotation_range_rad)
        )
        lf_m = float(np.linalg.norm(km.centre_a - np.dot(km.centre_a, km.axis_a) * km.axis_a))
        n_thigh = np.einsum("nij,j->ni", thigh.rotation, knee.axis_a)
        l_f = float(np.median(_perp_length(knee.centres[use] - hip[use], n_thigh[use])))
        s_f = c_f * l_f / lf_m
        ankle_fig: dict[str, float] = {}
        ankle_why = []
        l_t = float("nan")
        lt_m = float("nan")
        ankle = None
        if foot is None:
            ankle_why.append("fewer than 3 tracked markers on the calcaneus")
        else:
            try:
                ankle = score(shank, foot, hinge=True)
            except ValueError:
                ankle_why.append("the shank and foot are posed together in < 2 frames")
        if ankle is not None:
            ankle_fig = _figures(ankle)
            am = _model_fit(
                model, tibia, calcn, ankle_c,
                _centred_angles(model, ankle_c, ankle.rotation_range_rad),
            )  # fmt: skip
            d_m = am.centre_a - km.centre_b  # knee to ankle in the tibia frame
            lt_m = float(np.linalg.norm(d_m - np.dot(d_m, km.axis_b) * km.axis_b))
            both = ankle.used & knee.used
            if both.sum() < min_frames:
                ankle_why.append(f"{int(both.sum())} frames pose the thigh, shank and foot")
            if ankle_fig["range_deg"] < ck["ankle_min_range_deg"]:
                ankle_why.append(
                    f"the ankle moves {ankle_fig['range_deg']:.0f}° "
                    f"(< {ck['ankle_min_range_deg']:.0f}°)"
                )
            if ankle.mismatch_rms_m > ck["ankle_max_mismatch_m"]:
                ankle_why.append(
                    f"the shank's and foot's ankle centres differ by "
                    f"{ankle_fig['mismatch_mm']:.0f} mm RMS "
                    f"(> {1000 * ck['ankle_max_mismatch_m']:.0f})"
                )
            if both.any():
                n_shank = np.einsum("nij,j->ni", shank.rotation, knee.axis_b)
                d = ankle.centres[both] - knee.centres[both]
                l_t = float(np.median(_perp_length(d, n_shank[both])))
                diff = (l_f + l_t) / (lf_m + lt_m) - 1.0
                if abs(diff) > ck["ankle_max_leg_difference"]:
                    ankle_why.append(
                        f"hip to functional ankle {1000 * (l_f + l_t):.0f} mm is "
                        f"{100 * diff:+.1f} % of the ASIS-to-heel leg's "
                        f"{1000 * (lf_m + lt_m):.0f} mm"
                    )
        if not np.isfinite(lt_m):
            # the model's own ankle over a walking ankle's range (30°)
            am = _model_fit(model, tibia, calcn, ankle_c, _centred_angles(model, ankle_c, 0.52))
            d_m = am.centre_a - km.centre_b
            lt_m = float(np.linalg.norm(d_m - np.dot(d_m, km.axis_b) * km.axis_b))
        lengths = {"model_femur_m": lf_m, "model_tibia_m": lt_m}
        if ankle_why or not use_ankle:
            method = "functional knee, tibia the rest of the leg"
            reason = (
                "ankle not determined: " + "; ".join(ankle_why)
                if ankle_why
                else "the functional ankle is reported, not used (its knee-to-ankle length "
                "moves with the shank cluster's slide on the bone)"
            )
            s_t = c_t * (lf_m + lt_m - l_f) / lt_m
        else:
            method, reason = "functional knee and ankle", ""
            s_t = c_t * l_t / lt_m
        change = max(abs(s_f / c_f - 1.0), abs(s_t / c_t - 1.0))
        if change > ck["max_change"]:
            out[side] = keep(
                f"{method} gives femur × {s_f / c_f:.3f}, tibia × {s_t / c_t:.3f} of the leg "
                f"factor (more than {100 * ck['max_change']:.0f} %: a cluster on another "
                "segment?)",
                femur_length_m=l_f, tibia_length_m=l_t, knee=kf, ankle=ankle_fig, **lengths,
            )  # fmt: skip
            continue
        out[side] = LegSplit(
            side, method, reason, s_leg, s_f, s_t, l_f, l_t, lf_m, lt_m, kf, ankle_fig
        )
    return out
