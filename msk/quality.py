"""Quality gates: figures of a gait run checked against stated thresholds.

Every check returns :class:`Flag` records naming the trial, the quantity, the value and the
threshold, so that a wrong number never passes silently: ``summary.json`` carries them under
``quality.flags``, the report shows them in a banner at its top, and ``msk run --strict`` exits
with status 3 when any is raised.

Thresholds and their sources (:data:`THRESHOLDS`):

* IK marker error: mean per-frame RMS ≤ 20 mm and per-frame maximum ≤ 40 mm — OpenSim's
  recommendations for inverse kinematics ("RMS under 2 cm, maximum marker error under 2–4 cm",
  OpenSim User's Guide, *Getting started with inverse kinematics*; Hicks JL, Uchida TK, Seth A,
  Rajagopal A, Delp SL (2015) Is my model good enough? J Biomech Eng 137:020905, Table 2).
* Residual (pelvis) force RMS ≤ 5 % of body weight and residual moment RMS ≤ 1 % of
  (centre-of-mass height × peak external force): the residual bounds of Hicks et al. (2015,
  Table 2), stated there on the peak residuals; msk applies them to the RMS over the frames
  whose ground contact the plates measure (COM height 55 % of stature, 1.75 m when unknown).
* Analog scale: the plates' weighing a power of ten 10ᵏ (k ≠ 0, within 30 %) off the configured
  mass (:func:`plate_scale_factor`): ``ANALOG:SCALE``, ``GEN_SCALE`` or a unit mis-set.
* Body mass: the mass that balances the measured vertical ground reaction, Newton's second law
  on the whole body in integral form over the longest measured run,
  m̂ = ∫ F_z dt / (g T + Δv_com,z), more than 5 % from the configured mass.
* Joint angles outside physiological ranges of motion (:data:`PHYSIOLOGICAL_RANGES_DEG`: the
  active ranges of motion of healthy adults, Roaas A, Andersson GBJ (1982) Acta Orthop Scand
  53:205–208, widened by 10°), in gait2392's convention (knee flexion negative); a model whose
  coordinate turns the other way (Rajagopal's knee) is read through
  :func:`msk.model.conventions.reference_sign`.
* Coordinates at their model bound: a leg coordinate that IK holds at a bound of its model
  range (within :data:`AT_BOUND_TOLERANCE`) in more than 5 % of the solved frames: there the
  markers pull it beyond what the model allows and the pose is clamped, not measured (DM og4
  with a four-bar knee before the placement fix: the knee at its +10° hyperextension bound
  through stance — inside the physiological range gate's +15°, so that gate did not fire).
* Frozen coordinates: a leg coordinate whose standard deviation over the trial is below 0.05°
  (a segment that the markers do not observe stays at its initial value) — not judged on a
  still trial (every checked coordinate under 2° SD, the sway of quiet standing), where a
  still coordinate and an unobserved one look alike.
* No measured contact: a trial in which no frame has every foot's ground contact measured by
  the plates (no residual, plate mass, muscle forces or knee contact can be computed).
* Unobserved segments: solved frames in which no marker on a leg segment was used by IK.
* Tension optimisation: infeasible frames, frames excluded from it (non-finite or invalid
  inputs), a muscle saturated (activation ≥ 0.99) on more than 25 % of the frames it was
  solved in (the generic strength is short of the task for a quarter of it; a leg left out
  of a frame, its foot on unmeasured ground, is not counted there), reserve actuators
  carrying more than 10 % of a leg coordinate's peak joint torque (RMS over the frames its
  reserve was solved in); with knee compartments
  held ≥ 0 (``compartment_nonnegative``), a frontal reserve moment whose peak exceeds 10 % of
  the peak frontal moment of the knee's inverse-dynamics load (:func:`frontal_reserve_flags`:
  OpenSim's guideline for reserve actuators, peak below 10 % of the peak joint moment, applied
  to the frontal plane — the reserve stands for the ligaments the model lacks); a frame the
  QP solver called optimal whose KKT figure exceeds 1e-6 of its scale (:func:`kkt_flags`).
* Duplicate marker labels in the file; segments left at the generic size (no scaling).
* Static-trial markers whose distances to the markers of their own segment disagree with the
  motion trial's by more than 25 mm (median over at least 3 partners,
  :func:`inconsistent_static_markers`): a mislabelled, swapped or ghost marker in the static.
* No static trial: a leg coordinate whose mean over the task the marker placement does not
  determine — a placement with it ~5° away (:data:`msk.personalise.determinacy.PROFILE_SHIFT_DEG`,
  the
  error above which a gait measurement "should raise concern", McGinley et al. 2009) fits the
  markers within 0.2 mm of task IK cost or better
  (:func:`msk.personalise.determinacy.placement_profile`,
  the resolution the placement's own choice has: ``msk.personalise.placement.CHOICE_TOLERANCE_M``).
"""

from __future__ import annotations

import warnings
from collections.abc import Collection, Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from msk.metrics import root_mean_square as rms
from msk.model.markersets import LANDMARK_BODIES, is_knee_segment, other_side, parse_label
from msk.signal import true_runs
from msk.units import G0, Array

__all__ = [
    "AT_BOUND_TOLERANCE",
    "PHYSIOLOGICAL_RANGES_DEG",
    "SWAP_MIN_FRACTION",
    "SWAP_MIN_SEPARATION_M",
    "THRESHOLDS",
    "Flag",
    "body_mass_from_loads",
    "com_height",
    "contact_flags",
    "dead_plate_flags",
    "frontal_reserve_figures",
    "frontal_reserve_flags",
    "gait_flags",
    "gait_quality",
    "inconsistent_static_markers",
    "kkt_flags",
    "leg_coordinates",
    "marker_rename_flags",
    "model_flags",
    "optimization_flags",
    "placement_label_conflicts",
    "plate_edge_flags",
    "plate_scale_factor",
    "swapped_label_pairs",
    "swapped_sides",
    "trial_flags",
    "unmeasured_contact_figures",
]

#: the thresholds of the gates (SI unless the name says)
THRESHOLDS: Mapping[str, float] = {
    "ik_marker_rms_mean_m": 0.020,
    "ik_marker_max_mean_m": 0.040,
    "residual_force_rms_pct_bw": 5.0,
    "residual_moment_rms_pct_com_height_peak_force": 1.0,
    "body_mass_difference_pct": 5.0,
    "frozen_coordinate_std_deg": 0.05,
    # quiet standing sways the leg joints by well under 2° SD; any movement task (gait, squat,
    # stairs, a leg lifted) moves a hip or knee by more
    "still_trial_coordinate_std_deg": 2.0,
    "unobserved_segment_frames_pct": 5.0,
    "observed_measured_frames_min_pct": 50.0,
    # a foot on an unmeasured surface inside the measured span (stair steps without plates, a
    # foot off a plate mid-task): more than this share of the span's frames lose that leg's torques
    "unmeasured_contact_inside_pct": 5.0,
    "saturated_frames_pct": 25.0,
    "reserve_rms_pct_peak_torque": 10.0,
    "frontal_reserve_pct_peak_moment": 10.0,
    # a KKT figure of a frame the QP solver called optimal, relative to its scale
    # (msk.optimization.kkt_scale): DAQP's solutions sit at 1e-15–1e-12
    "kkt_relative": 1e-6,
    "saturation_activation": 0.99,
    "static_marker_discrepancy_m": 0.025,
    "coordinate_at_bound_frames_pct": 5.0,
    # the leg's two length measures without a static (msk.personalise.leg_split): hip to the
    # functional
    # knee and ankle against the ASIS-to-heel leg; the split's own limit for using the ankle
    "leg_length_disagreement_pct": 5.0,
    # a static's anatomical marker relocated from the scaled model's landmark by more than
    # twice the inter-examiner spread of palpated landmarks (up to ~2.5 cm; Della Croce U et al.
    # 2005, Gait Posture 21:226-237): on the shipped statics ≤ 39 mm (UNIPD's lateral
    # epicondyle, 26 mm above gait2392's), so 50 mm
    "static_marker_relocated_m": 0.05,
    # a marker the lab places where it likes (``move``: clusters, foot markers) moved by more
    # than a foot's marker region (~0.1 m: the midfoot-to-toe span): on the shipped statics
    # ≤ 94 mm (PS's lateral midfoot); a ghost in a static moved a foot marker 127 mm
    "static_marker_moved_m": 0.10,
    # a static's standing pose: the pelvis tilts 10-15° anteriorly (ASIS-PSIS line; Kadaba MP
    # et al. 1990, J Orthop Res 8:383-392) and a model's pelvis frame differs from that line by
    # under 10° (msk.kinematics.gait_plausibility): beyond 25° the static's pelvis is not
    # determined by its markers (or the subject did not stand); the hips of quiet standing are
    # within ~10° of neutral, a crouched stance 20-30°: beyond 30° the static is not standing or
    # its thighs are mis-solved
    "static_pelvis_tilt_deg": 25.0,
    "static_hip_flexion_deg": 30.0,
}

#: a solved coordinate within this of its model range bound is "at the bound" (rad or m)
AT_BOUND_TOLERANCE = 1e-3

#: physiological joint ranges (deg) by coordinate stem, gait2392/OpenSim sign conventions
#: (knee_angle is negative in flexion); active ROM of adults (Roaas & Andersson 1982) + 10°
PHYSIOLOGICAL_RANGES_DEG: Mapping[str, tuple[float, float]] = {
    "hip_flexion": (-40.0, 140.0),
    "hip_adduction": (-55.0, 40.0),
    "hip_rotation": (-55.0, 55.0),
    "knee_angle": (-155.0, 15.0),
    "ankle_angle": (-60.0, 45.0),
    "subtalar_angle": (-45.0, 45.0),
}

#: leg bodies whose observation by markers is checked (gait2392 / Rajagopal names)
_LEG_BODIES = ("femur", "tibia", "calcn")


@dataclass(frozen=True)
class Flag:
    """One raised quality gate: ``quantity`` measured ``value`` against ``threshold``."""

    trial: str
    quantity: str
    value: float
    threshold: float
    message: str

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def body_mass_from_loads(
    model: Any, kinematics: Any, loads: Any, frames: NDArray[np.bool_]
) -> float | None:
    """The mass whose whole-body Newton balance matches the measured vertical ground reaction,
    in integral form over the longest run of consecutive ``frames`` [t₀, t₁]:

        m̂ = ∫ F_z dt / (g (t₁ − t₀) + v_com,z(t₁) − v_com,z(t₀))

    (``loads.force`` summed over bodies, world frame, z along −gravity; v_com from the model and
    the kinematics at the two ends only, so the estimate does not rest on the model's mass
    distribution the way a frame-by-frame balance with COM accelerations does). None when the
    run is shorter than 10 frames."""
    g_vec = np.asarray(model.gravity, dtype=float)
    g = float(np.linalg.norm(g_vec))
    if g == 0.0:
        return None
    up = -g_vec / g
    t = np.asarray(kinematics.time, dtype=float)
    q, v = (np.asarray(x, dtype=float) for x in (kinematics.q, kinematics.v))
    ok = np.asarray(frames, dtype=bool) & np.isfinite(q).all(1) & np.isfinite(v).all(1)
    runs = true_runs(ok)
    if not runs:
        return None
    i0, i1 = max(runs, key=lambda r: r[1] - r[0])
    if i1 - i0 < 10:
        return None
    fz = np.nansum(np.asarray(loads.force, dtype=float)[i0:i1] @ up, axis=1)
    impulse = float(np.trapezoid(fz, t[i0:i1]))
    data = model.create_data()
    vz = []
    for k in (i0, i1 - 1):
        qp, vp, _ = model.coupling.embed(q[k : k + 1], v[k : k + 1], np.zeros_like(v[k : k + 1]))
        pin.centerOfMass(model.pin_model, data, qp[0], vp[0])
        vz.append(float(np.asarray(data.vcom[0]) @ up))
    den = g * float(t[i1 - 1] - t[i0]) + vz[1] - vz[0]
    return impulse / den if den > 0 else None


def com_height(
    model: Any, kinematics: Any, frames: NDArray[np.bool_], floor_m: float = 0.0
) -> float | None:
    """The whole-body centre of mass's height above the floor, median over ``frames``:
    median_t (c(q_t) · up − ``floor_m``), up = −gravity / g, c from the model's mass
    distribution (pinocchio ``centerOfMass``). The "COM height" of the residual-moment
    guideline (Hicks et al. 2015, J Biomech Eng 137:020905): measured on the model and the
    motion rather than assumed from the stature. None without a finite frame."""
    g_vec = np.asarray(model.gravity, dtype=float)
    g = float(np.linalg.norm(g_vec))
    q = np.asarray(kinematics.q, dtype=float)
    idx = np.flatnonzero(np.asarray(frames, dtype=bool) & np.isfinite(q).all(axis=1))
    if g == 0.0 or idx.size == 0:
        return None
    up = -g_vec / g
    data = model.create_data()
    z = np.empty(idx.size)
    for i, k in enumerate(idx.tolist()):
        qp = model.coupling.q(q[k : k + 1])  # g(θ) alone: the position needs no G, no Ġθ̇
        pin.centerOfMass(model.pin_model, data, qp[0])
        z[i] = float(np.asarray(data.com[0]) @ up)
    return float(np.median(z)) - floor_m


def inconsistent_static_markers(
    static: ArrayLike,
    static_labels: Sequence[str],
    motion: ArrayLike,
    motion_labels: Sequence[str],
    *,
    rigid_sd_m: float = 0.008,
    min_partners: int = 3,
    min_frames: int = 10,
    threshold_m: float = THRESHOLDS["static_marker_discrepancy_m"],
    skip: Sequence[str] = (),
    still_m: float = 0.01,
) -> dict[str, float]:
    """Static-trial markers whose labels the motion trial contradicts.

    Two markers on one segment keep their distance through a motion (skin motion aside):
    d_ab(t) = ‖x_a(t) − x_b(t)‖ with a standard deviation below ``rigid_sd_m`` over the
    motion's frames (``min_frames`` frames seeing both) makes (a, b) a *rigid pair* — unless
    both stay still (position SD < ``still_m`` on every axis): markers of two still segments
    keep their distance too (the two feet of a squat, the lab's axis markers), so a pair of
    still markers says nothing of one segment — or unless the two are on opposite sides
    (:func:`msk.model.markersets.parse_label`) and not both on the pelvis or trunk
    (:data:`msk.model.markersets.LANDMARK_BODIES`; a sided label of unknown landmark counts as a
    limb's): the legs of a squat move alike, so a right and a left shank marker keep their
    distance without being on one segment, at the task's stance width, not the static's. A
    static label names the same marker as the motion's when the static distance (median over
    its frames) matches the motion's median, e_ab = |d̄_ab^static − d̄_ab^motion|. A marker
    with at least ``min_partners`` rigid partners whose median discrepancy med_b e_ab exceeds
    ``threshold_m`` is not where its label says in the static (a mislabelled or swapped label,
    a ghost trajectory): one wrong marker raises a single e_ab of each partner, so the median
    names the wrong one (both, for a swap). The motion decides because it has many frames and
    the static's error would otherwise be carried into the scaling and the placement of every
    marker.

    ``skip``: labels neither checked nor used as partners — markers that are not fixed to a
    bone of the model between the two trials (acromia on a model without shoulder girdle:
    the scapula moves with the arms, 29–34 mm against C7 between UNIPD's arms-out static and
    its walks, :func:`msk.model.markersets.shoulder_girdle_markers`).

    Both trials (N, M, 3) in metres with NaN gaps, any frame (distances only). Returns
    label → median discrepancy (m) for the contradicted markers (UNIPD's ``Static1``: ``RIMH``
    seen in 1 frame of 107, 7 mm from ``RLM`` where the walks hold them 179 mm apart).
    """
    xs = np.asarray(static, dtype=float)
    xm = np.asarray(motion, dtype=float)
    js = {lab: i for i, lab in reversed(list(enumerate(static_labels)))}
    jm = {lab: i for i, lab in reversed(list(enumerate(motion_labels)))}
    common = [lab for lab in js if lab in jm and lab not in set(skip)]
    parsed = {lab: parse_label(lab) for lab in common}
    axial = {
        lab for lab, p in parsed.items()
        if LANDMARK_BODIES.get(p.landmark or "") in ("pelvis", "torso")
    }  # fmt: skip
    err: dict[str, list[float]] = {lab: [] for lab in common}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        spread = {lab: float(np.nan_to_num(np.nanstd(xm[:, jm[lab]], axis=0)).max())
                  for lab in common}  # fmt: skip
    for k, a in enumerate(common):
        for b in common[k + 1 :]:
            if spread[a] < still_m and spread[b] < still_m:
                continue  # two still markers keep any distance (both feet in a squat, lab axes)
            sa, sb = parsed[a].side, parsed[b].side
            if sa is not None and sb is not None and sa != sb and not {a, b} <= axial:
                continue  # a right and a left limb marker are never on one segment
            dm = np.linalg.norm(xm[:, jm[a]] - xm[:, jm[b]], axis=1)
            dm = dm[np.isfinite(dm)]
            if dm.size < min_frames or float(np.std(dm)) > rigid_sd_m:
                continue
            ds = np.linalg.norm(xs[:, js[a]] - xs[:, js[b]], axis=1)
            ds = ds[np.isfinite(ds)]
            if ds.size == 0:
                continue
            e = abs(float(np.median(ds)) - float(np.median(dm)))
            err[a].append(e)
            err[b].append(e)
    out: dict[str, float] = {}
    for lab, es in err.items():
        if len(es) >= min_partners and float(np.median(es)) > threshold_m:
            out[lab] = float(np.median(es))
    return out


def _pairs_and_pelvis(
    labels: Sequence[str],
) -> tuple[list[tuple[str, str]], dict[tuple[str, str], str], list[str]]:
    """Left/right pairs of one landmark among ``labels`` (:func:`msk.model.markersets.parse_label`),
    the labels by (landmark, side) and the posterior pelvis labels (sacrum, PSIS)."""

    by_side: dict[tuple[str, str], str] = {}
    posterior: list[str] = []
    for lab in dict.fromkeys(labels):
        pl = parse_label(lab)
        if pl.side in ("R", "L") and pl.landmark:
            by_side.setdefault((pl.landmark, pl.side), lab)
        if pl.landmark in ("sacrum", "psis"):
            posterior.append(lab)
    pairs = [(by_side[(lm, "R")], by_side[(lm, "L")]) for lm, sd in by_side if sd == "R"
             and (lm, "L") in by_side]  # fmt: skip
    return pairs, by_side, posterior


def _right_from_pelvis_markers(
    x: Array,
    col: Mapping[str, int],
    by_side: Mapping[tuple[str, str], str],
    posterior: Sequence[str],
    up: Array,
) -> Array | None:
    """(frames, 3) the subject's right r̂ = f̂ × û per frame from the pelvis markers: f̂ the
    horizontal direction from the posterior markers' mean to the ASIS midpoint (a midpoint a
    left/right swap does not move), û the vertical; None without both ASIS and a posterior
    marker."""
    ra, la = by_side.get(("asis", "R")), by_side.get(("asis", "L"))
    back = [col[b] for b in posterior if b in col]
    if ra is None or la is None or ra not in col or la not in col or not back:
        return None
    u = np.asarray(up, dtype=float)
    u = u / np.linalg.norm(u)
    front = 0.5 * (x[:, col[ra]] + x[:, col[la]])
    seen = np.isfinite(x[:, back]).all(axis=2)
    with np.errstate(invalid="ignore", divide="ignore"):
        rear = np.nansum(x[:, back], axis=1) / seen.sum(axis=1, keepdims=True)
        fwd = front - rear
        fwd -= np.outer(fwd @ u, u)
        right = np.cross(fwd, u)
        right /= np.linalg.norm(right, axis=1, keepdims=True)
    return right


#: a label pair is swapped in a trial when the right-side marker lies at least this far to the
#: subject's left of the left-side one (median over frames; the narrowest true separations —
#: medial foot markers in a narrow gait — are about 5 cm the right way round)
SWAP_MIN_SEPARATION_M = 0.03
#: … in at least this fraction of the frames where both are seen
SWAP_MIN_FRACTION = 0.8


def swapped_label_pairs(
    markers: Array, labels: Sequence[str], up: ArrayLike
) -> list[tuple[str, str, float]]:
    """Left/right label pairs swapped in a trial, from its markers alone (no model, no IK):
    (right label, left label, median (x_R − x_L) · r̂ in m, negative) for each pair whose
    right-side marker lies more than :data:`SWAP_MIN_SEPARATION_M` to the subject's left of the
    left-side one in at least :data:`SWAP_MIN_FRACTION` of the frames, r̂ the subject's right
    from the pelvis markers (both ASIS and a sacrum/PSIS marker; otherwise nothing is said).
    ``markers`` (frames, markers, 3) in a frame whose vertical is ``up``."""
    x = np.asarray(markers, dtype=float)
    pairs, by_side, posterior = _pairs_and_pelvis(labels)
    col = {lab: i for i, lab in reversed(list(enumerate(labels)))}
    right = _right_from_pelvis_markers(x, col, by_side, posterior, np.asarray(up, dtype=float))
    if right is None:
        return []
    out = []
    for r, lft in pairs:
        dz = np.einsum("fi,fi->f", x[:, col[r]] - x[:, col[lft]], right)
        dz = dz[np.isfinite(dz)]
        if dz.size < 3:
            continue
        med = float(np.median(dz))
        if med < -SWAP_MIN_SEPARATION_M and np.mean(dz < 0.0) >= SWAP_MIN_FRACTION:
            out.append((r, lft, med))
    return out


def swapped_sides(
    model: Any, kinematics: Any, markers: Array, labels: Sequence[str]
) -> list[tuple[str, str, float]]:
    """Left/right marker pairs whose labels look swapped: the median over the solved frames of
    (right marker − left marker) · r̂ is negative, r̂ the subject's right. Pairs are model
    markers of one landmark on both sides (:func:`msk.model.markersets.parse_label`).

    r̂ comes from the pelvis markers themselves where the trial has both ASIS and a posterior
    pelvis marker (sacrum or PSIS): r̂ = f̂ × û, f̂ the horizontal direction from the posterior
    markers' mean to the ASIS midpoint (a midpoint a swap does not move), û the model's
    vertical — so a swapped ASIS pair is found even when IK, fitting it, turned the pelvis
    round. Otherwise r̂ is the fitted pelvis's +z (gait2392/OpenSim), and when most pairs look
    swapped in it (the pelvis fitted the wrong way round) the pairs that do not are reported.
    A pair is reported only when the right marker lies more than
    :data:`SWAP_MIN_SEPARATION_M` to the left (a median within that margin is a pair that
    crosses or overlaps in the medio-lateral direction, e.g. medial toe markers over a piece of
    a trial with a narrow or crossing step, not a swap: UWA fast walking, its first 1.55 s,
    R.Toe.Med 3 mm left of L.Toe.Med).
    Returns (right, left, median in m, signed so that the subject's right is positive)."""
    if "pelvis" not in model.body_frame:
        return []
    q = np.asarray(kinematics.q, dtype=float)
    good = np.flatnonzero(np.isfinite(q).all(axis=1))
    if good.size == 0:
        return []
    known = set(model.marker_names)
    col = {lab: i for i, lab in reversed(list(enumerate(labels))) if lab in known}
    pairs, by_side, posterior = _pairs_and_pelvis(list(col))
    if not pairs:
        return []
    step = max(1, good.size // 60)
    frames = good[::step]
    x = np.asarray(markers, dtype=float)[frames]
    up = -np.asarray(model.gravity, dtype=float)
    right = _right_from_pelvis_markers(x, col, by_side, posterior, up)
    from_markers = right is not None
    if right is None:
        data = model.create_data()
        fp = model.body_frame["pelvis"]
        qp = model.coupling.q(q[frames])
        right = np.empty((frames.size, 3))
        for i in range(frames.size):
            pin.framesForwardKinematics(model.pin_model, data, qp[i])
            right[i] = data.oMf[fp].rotation[:, 2]
        from_markers = False
    med: dict[tuple[str, str], float] = {}
    for r, lft in pairs:
        dz = np.einsum("fi,fi->f", x[:, col[r]] - x[:, col[lft]], right)
        dz = dz[np.isfinite(dz)]
        if dz.size >= 3:
            med[(r, lft)] = float(np.median(dz))
    # without pelvis markers to say where right is, a swapped pelvis pair turns the fitted
    # pelvis round: then every other pair looks swapped in its frame and the swapped one does
    # not; the side the majority of pairs agree on is the subject's right
    reversed_pelvis = not from_markers and (
        sum(v < 0.0 for v in med.values()) > sum(v > 0.0 for v in med.values())
    )
    sign = -1.0 if reversed_pelvis else 1.0
    return [(r, lft, sign * v) for (r, lft), v in med.items() if sign * v < -SWAP_MIN_SEPARATION_M]


def plate_scale_factor(
    plate_mass_kg: float, mass_kg: float, *, tolerance: float = 0.3
) -> float | None:
    """The power of ten 10ᵏ (k ≠ 0) by which the plates' weighing m̂ of the subject
    (:func:`body_mass_from_loads`) misses the known mass m, when m̂ / m lies within
    ``tolerance`` (relative) of it: an analog scale, gain or unit mis-set by a decade (a
    wrong mass is rarely off by exactly a power of ten); None otherwise."""
    if not (plate_mass_kg > 0 and mass_kg > 0):
        return None
    r = plate_mass_kg / mass_kg
    k = round(float(np.log10(r)))
    if k == 0 or abs(r / 10.0**k - 1.0) > tolerance:
        return None
    return 10.0**k


def _flag(trial: str, quantity: str, value: float, threshold: float, message: str) -> Flag:
    return Flag(trial, quantity, float(value), float(threshold), message)


def _coordinate_flags(
    trial: str, kin: Any, th: Mapping[str, float], held: set[str], model: Any = None
) -> list[Flag]:
    out: list[Flag] = []
    q = np.asarray(kin.q, dtype=float)
    good = np.isfinite(q).all(axis=1)
    if not good.any():
        return out
    out += _at_bound_flags(trial, kin, th, held, model)
    stems = {
        j: name[:-2] if name.endswith(("_r", "_l")) else name
        for j, name in enumerate(kin.coordinate_names)
    }
    names = kin.coordinate_names
    # the ranges are stated in the reference convention (knee_angle negative in flexion): a
    # model whose coordinate turns the other way is read with its sign turned
    signs: Mapping[str, float] = {}
    if model is not None:
        from msk.model.conventions import reference_signs

        signs = reference_signs(model)
    checked = [
        j for j, st in stems.items() if st in PHYSIOLOGICAL_RANGES_DEG and names[j] not in held
    ]
    sds = np.array([np.degrees(np.std(q[good, j])) for j in checked])
    # a still trial (quiet standing: every checked coordinate's SD under the standing sway,
    # THRESHOLDS["still_trial_coordinate_std_deg"]) cannot tell a coordinate the markers do not
    # observe from one that does not move: no frozen-coordinate flag there
    still = bool(sds.size) and float(sds.max()) < th.get("still_trial_coordinate_std_deg", 0.0)
    for j, sd in zip(checked, sds.tolist()):
        name, stem = names[j], stems[j]
        deg = signs.get(name, 1.0) * np.degrees(q[good, j])
        lo, hi = PHYSIOLOGICAL_RANGES_DEG[stem]
        if deg.min() < lo or deg.max() > hi:
            worst = deg.min() if lo - deg.min() > deg.max() - hi else deg.max()
            bound = lo if worst < lo else hi
            out.append(
                _flag(trial, f"{name}_deg", worst, bound,
                      f"{name} reaches {worst:.1f}°"
                      + (" (gait2392's sign: flexion negative)" if name in signs else "")
                      + f", outside the physiological range [{lo:g}°, {hi:g}°]")
            )  # fmt: skip
        if sd < th["frozen_coordinate_std_deg"] and not still:
            out.append(
                _flag(trial, f"{name}_std_deg", sd, th["frozen_coordinate_std_deg"],
                      f"{name} is frozen (SD {sd:.3g}° over the trial): the markers do not "
                      "observe it; joint torques and muscle forces across it are not measured")
            )  # fmt: skip
    return out


def _at_bound_flags(
    trial: str, kin: Any, th: Mapping[str, float], held: set[str], model: Any
) -> list[Flag]:
    """Leg coordinates (:data:`PHYSIOLOGICAL_RANGES_DEG` stems) that IK holds at a bound of
    the model's range in more than the threshold's share of the solved frames."""
    out: list[Flag] = []
    raw = np.asarray(getattr(kin, "q_raw", np.zeros((0, 0))), dtype=float)
    if model is None or raw.ndim != 2 or raw.shape[0] == 0:
        return out
    coords = {c.name: c for c in getattr(model, "coordinates", ())}
    solved = np.isfinite(raw).all(axis=1)
    if not solved.any():
        return out
    for j, name in enumerate(kin.coordinate_names):
        stem = name[:-2] if name.endswith(("_r", "_l")) else name
        c = coords.get(name)
        if stem not in PHYSIOLOGICAL_RANGES_DEG or name in held or c is None or c.locked:
            continue
        lo, hi = c.range
        v = raw[solved, j]
        for bound, hit in ((lo, v <= lo + AT_BOUND_TOLERANCE), (hi, v >= hi - AT_BOUND_TOLERANCE)):
            pct = 100.0 * float(hit.mean())
            if pct > th["coordinate_at_bound_frames_pct"]:
                out.append(
                    _flag(trial, f"{name}_at_bound_frames_pct", pct,
                          th["coordinate_at_bound_frames_pct"],
                          f"{name} is held at its model bound {np.degrees(bound):.1f}° in "
                          f"{pct:.0f} % of the solved frames: the markers pull it beyond the "
                          "model's range; the pose there is clamped, not measured")
                )  # fmt: skip
    return out


def _unobserved_flags(trial: str, model: Any, kin: Any, th: Mapping[str, float]) -> list[Flag]:
    out: list[Flag] = []
    errs = np.asarray(getattr(kin, "marker_errors", np.zeros((0, 0))), dtype=float)
    names = tuple(getattr(kin, "marker_names", ()))
    if errs.ndim != 2 or errs.shape[1] != len(names) or errs.shape[0] == 0:
        return out
    body_of = {m.name: m.body for m in model.markers}
    bodies = sorted({b for b in body_of.values() if b.startswith(_LEG_BODIES)})
    solved = np.isfinite(errs).any(axis=1)  # frames IK solved (the others are reported apart)
    if not solved.any():
        return out
    n = int(solved.sum())
    for body in bodies:
        cols = [k for k, nm in enumerate(names) if body_of.get(nm) == body]
        seen = np.isfinite(errs[solved][:, cols]).any(axis=1) if cols else np.zeros(n, bool)
        pct = 100.0 * (1.0 - seen.mean())
        if pct > th["unobserved_segment_frames_pct"]:
            out.append(
                _flag(trial, f"{body}_unobserved_frames_pct", pct,
                      th["unobserved_segment_frames_pct"],
                      f"no marker observes {body} in {pct:.0f} % of the solved frames: its pose "
                      "there comes from the neighbouring segments only")
            )  # fmt: skip
    return out


def placement_label_conflicts(
    placed: Mapping[str, str], bodies: Sequence[str]
) -> dict[str, tuple[str, str]]:
    """Markers placed on a thigh or shank body other than the one their label names, or on a
    body of the other side than their label's: label → (body placed on, body named).
    ``placed``: lab label → body of a placement from the motion
    (:func:`msk.personalise.scaling.place_markers_from_motion`'s ``"placed"``); the named body is
    the
    label's landmark's (:data:`msk.model.markersets.LANDMARK_BODIES`: a thigh cluster or knee marker
    on the femur, a shank cluster or malleolus on the tibia) on its side, when the model has
    it. Without a static the body is the one the marker moves least on in the passes' inverse
    kinematics, and a knee no marker pins can make a thigh marker as still on the tibia as on
    the femur: a synthetic DM walk of a subject with a 7 % longer
    femur and 6 % shorter tibia had R_Thigh_Inferior placed on tibia_r and R_Shank_Superior,
    R_Shank_Lateral on femur_r, its right knee then solved 43.7° RMS from the truth at an IK
    marker RMS of 8.2 mm, unflagged; a synthetic squat's R_Midfoot_Medial on toes_l (still feet
    are as rigid to either foot). :func:`msk.personalise.scaling.place_markers_from_motion` now
    avoids
    both; the check stays for any placement that does not."""
    have = set(bodies)
    out: dict[str, tuple[str, str]] = {}
    for lab, body in placed.items():
        pl = parse_label(lab)
        body = str(body)
        if other_side(lab, (body,))[0]:  # a sided label on the other side's body
            out[lab] = (body, f"a {str(pl.side).upper()} body")
            continue
        stem = LANDMARK_BODIES.get(pl.landmark or "")
        if stem is None or not (is_knee_segment(stem) and is_knee_segment(body)):
            continue
        named = f"{stem}_{pl.side.lower()}" if pl.side else stem
        if named in have and body != named:
            out[lab] = (body, named)
    return out


def model_flags(
    trial: str,
    info: Mapping[str, Any],
    bodies: Sequence[str],
    thresholds: Mapping[str, float] = THRESHOLDS,
) -> list[Flag]:
    """The gates on how the model was made from the task without a static (``info``: the model
    stage's record, ``summary.json`` ``model``): thigh or shank markers placed on the other
    segment (:func:`placement_label_conflicts`), and a leg whose two length measures disagree —
    hip to the functional knee plus knee to the functional ankle (``msk.personalise.leg_split``,
    ``femur_length_m + tibia_length_m``) against the ASIS-to-heel leg the model was scaled to
    (``model_femur_m + model_tibia_m``) by more than ``leg_length_disagreement_pct``: the leg's
    scale, and the tibia's (the rest of the leg), are uncertain by that much. Both are true of
    the synthetic DM walks of docs/validation.md (synthetic hidden tasks), the second of DM's real
    crouch trial (left leg +7.7 %; its legs scaled 5–6 % shorter than by the same subject's
    overground walk); neither of DM's overground and treadmill walks (≤ 2.5 %). And a leg coordinate
    whose mean the placement does not determine (``placement_determinacy``,
    :func:`msk.personalise.determinacy.placement_profile`: a placement with it shifted by about
    :data:`msk.personalise.determinacy.PROFILE_SHIFT_DEG` fits the markers within the cost's
    resolution or
    better; value: the cost change, m; threshold: that resolution)."""
    th = {**THRESHOLDS, **thresholds}
    out: list[Flag] = []
    placed = (info.get("marker_placement") or {}).get("placed") or {}
    bad = placement_label_conflicts(placed, bodies)
    if bad:
        out.append(
            _flag(trial, "markers_placed_against_label", float(len(bad)), 0.0,
                  "placed from the motion on the other segment than their label names: "
                  + ", ".join(f"{lab} on {b} (label: {n})" for lab, (b, n) in sorted(bad.items()))
                  + " — the knee between them is solved from exchanged markers")
        )  # fmt: skip
    for side, v in sorted((info.get("leg_split") or {}).items()):
        lengths = [v.get(k) for k in ("femur_length_m", "tibia_length_m", "model_femur_m",
                                      "model_tibia_m")]  # fmt: skip
        if any(x is None or not np.isfinite(x) for x in lengths):
            continue
        lf, lt, mf, mt = (float(x) for x in lengths)
        diff = 100.0 * ((lf + lt) / (mf + mt) - 1.0)
        if abs(diff) > th["leg_length_disagreement_pct"]:
            out.append(
                _flag(trial, f"leg_length_disagreement_pct_{side}", abs(diff),
                      th["leg_length_disagreement_pct"],
                      f"leg {side}: hip to functional ankle {1000 * (lf + lt):.0f} mm is "
                      f"{diff:+.1f} % of the ASIS-to-heel leg's {1000 * (mf + mt):.0f} mm the "
                      "model was scaled to: the leg's and the tibia's scale factors are "
                      "uncertain by that much (no static trial; msk.personalise.leg_split)")
            )  # fmt: skip
    out += _relocation_flags(trial, info, th)
    det = dict(info.get("placement_determinacy") or {})
    if det.get("not_run"):
        out.append(
            _flag(trial, "placement_determinacy_not_run", 1.0, 0.0,
                  f"what the placement from the motion determines was not checked: "
                  f"{det['not_run']} (msk.personalise.determinacy)")
        )  # fmt: skip
    pel = dict(det.get("pelvis") or {})
    if pel.get("not_determined"):
        fixed = ", ".join(pel.get("fixed_markers", ())) or "none"
        out.append(
            _flag(trial, f"placement_not_determined_{pel.get('body', 'pelvis')}",
                  float(len(pel.get("fixed_markers", ()))), 3.0,
                  f"{pel.get('body', 'pelvis')} not posed by its markers (no static trial): "
                  f"{', '.join(pel['not_determined'])} left to the legs, whose markers the "
                  f"same motion placed — observed fixed markers {fixed} (three not on one "
                  "line are needed; with two ASIS a sacral marker or both PSIS, "
                  "msk.personalise.virtual_markers); the hip angles and moments take up the "
                  "error (msk.personalise.determinacy.pelvis_determinacy)")
        )  # fmt: skip
    tol = float(det.get("tolerance_m", 0.0))
    for name in det.get("not_determined", ()):
        c = dict(det["coordinates"][name])
        dc, dm = c["cost_change_m"], c["mean_change_deg"]
        k = int(np.argmin(dc))
        why = "every marker distal to its joint placed from the motion; " if not c.get(
            "fixed_markers") else ""  # fmt: skip
        out.append(
            _flag(trial, f"placement_not_determined_{name}", float(dc[k]), tol,
                  f"mean {name} {c['mean_deg']:.1f}° not determined by the markers (no static "
                  f"trial): a placement with it {dm[k]:+.1f}° away fits the task's markers "
                  f"{'as well' if dc[k] >= 0 else 'better'} (task IK cost {1000 * dc[k]:+.3f} "
                  f"mm; a change under {1000 * tol:.1f} mm is one the placement cannot resolve; "
                  f"{why}msk.personalise.determinacy)")
        )  # fmt: skip
    return out


def _relocation_flags(trial: str, info: Mapping[str, Any], th: Mapping[str, float]) -> list[Flag]:
    """A static's standing pose beyond the gates (``model.marker_placement.static_pose_deg``:
    pelvis tilt, hip flexion), and its markers moved far on their body (``relocated``:
    anatomical markers moved from the scaled model's landmark to where the static puts them;
    ``moved``: the ``move`` markers), each with its distance — a ghost or mislabelled marker
    in the static moves a model marker silently otherwise. Only with a static trial
    (``model.static_window``): without one the markers are placed from the motion."""
    if "static_window" not in info:
        return []
    mp = dict(info.get("marker_placement") or {})
    out: list[Flag] = []
    pose = dict(mp.get("static_pose_deg") or {})
    for name, th_key in (("pelvis_tilt", "static_pelvis_tilt_deg"),
                         ("hip_flexion_r", "static_hip_flexion_deg"),
                         ("hip_flexion_l", "static_hip_flexion_deg")):  # fmt: skip
        v = pose.get(name)
        if v is not None and np.isfinite(v) and abs(float(v)) > th[th_key]:
            out.append(
                _flag(trial, f"static_{name}_deg", float(v), np.copysign(th[th_key], float(v)),
                      f"the static trial's standing pose has {name} {float(v):.0f}°, beyond "
                      f"±{th[th_key]:g}° (quiet standing: pelvis tilt 10-15°, hips within ~10°"
                      "): a pelvis or thigh its markers do not determine, or a static not "
                      "standing — every marker placed from that pose carries the error")
            )  # fmt: skip
    for key, th_key, what in (
        ("relocated", "static_marker_relocated_m", "from the scaled model's landmark"),
        ("moved", "static_marker_moved_m", "from the model's generic place"),
    ):
        far = {k: float(v) for k, v in dict(mp.get(key) or {}).items() if float(v) > th[th_key]}
        if far:
            out.append(
                _flag(trial, th_key, max(far.values()), th[th_key],
                      f"the static trial {key} " + ", ".join(
                          f"{k} {1000 * v:.0f} mm" for k, v in sorted(far.items()))
                      + f" on its body {what}: a ghost or mislabelled marker in the static? "
                      "(msk.personalise.scaling.place_markers)")
            )  # fmt: skip
    return out


def leg_coordinates(model: Any) -> frozenset[str]:
    """The coordinates of the joints in either leg's tree: each joint whose child body is a
    femur (the hip) or below one (``Model.subtree``); empty for a model without femurs."""
    bodies: set[str] = set()
    for femur in ("femur_r", "femur_l"):
        if femur in getattr(model, "body_frame", {}):
            bodies.update(model.subtree(femur))
    return frozenset(
        ax.coordinate for j in getattr(model, "joints", ()) if j.child in bodies
        for ax in j.axes if ax.coordinate
    )  # fmt: skip


def optimization_flags(
    trial: str,
    sol: Any,
    jt: Any,
    thresholds: Mapping[str, float] = THRESHOLDS,
    legs: Collection[str] | None = None,
) -> list[Flag]:
    """The tension optimisation's gates (``sol``: a
    :class:`msk.optimization.muscle_forces.MuscleForces`; ``jt`` the joint torques its reserves are
    judged against): infeasible and excluded frames, a muscle saturated on more than
    ``saturated_frames_pct`` of the frames it was solved in, a leg coordinate's reserve RMS
    over its solved frames above ``reserve_rms_pct_peak_torque`` of its peak torque (``legs``:
    the leg coordinates, :func:`leg_coordinates`; None: those named ``*_r``/``*_l`` — an arm's
    torque-driven coordinate has no muscle to judge), the
    frontal reserves (:func:`frontal_reserve_flags`) and the KKT check (:func:`kkt_flags`).
    A leg left out of a frame (NaN there) counts in none of them."""
    th = {**THRESHOLDS, **thresholds}
    out: list[Flag] = []
    n_inf = int(getattr(sol, "infeasible_frames", 0) or 0)
    if n_inf:
        out.append(
            _flag(trial, "optimization_infeasible_frames", n_inf, 0,
                  f"{n_inf} frames of the tension optimisation are infeasible (bounded "
                  "least-squares point kept)")
        )  # fmt: skip
    n_exc = int(getattr(sol, "excluded_frames", 0) or 0)
    if n_exc:
        out.append(
            _flag(trial, "optimization_excluded_frames", n_exc, 0,
                  f"{n_exc} frames could not be posed to the tension optimisation "
                  f"({getattr(sol, 'excluded_reason', None) or 'invalid inputs'}): no muscle "
                  "force or contact force there")
        )  # fmt: skip
    acts = np.asarray(getattr(sol, "activations", np.zeros((0, 0))), dtype=float)
    names = tuple(getattr(sol, "muscles", ()))
    if acts.ndim == 2 and acts.size:
        # per muscle over the frames it was solved in (a leg left out of a frame's tension QP
        # has NaN activations there; the other leg's, solved, count)
        fin = np.isfinite(acts)
        n_fin = fin.sum(axis=0)
        if n_fin.any():
            hit = (np.where(fin, acts, 0.0) >= th["saturation_activation"]).sum(axis=0)
            sat = np.where(n_fin > 0, 100.0 * hit / np.maximum(n_fin, 1), 0.0)
            worst = int(np.argmax(sat))
            if sat[worst] > th["saturated_frames_pct"]:
                out.append(
                    _flag(trial, f"{names[worst]}_saturated_frames_pct", sat[worst],
                          th["saturated_frames_pct"],
                          f"{names[worst]} is saturated (activation ≥ "
                          f"{th['saturation_activation']:g}) in {sat[worst]:.0f} % of the frames"
                          f" ({int((sat > th['saturated_frames_pct']).sum())} muscles in all)")
                )  # fmt: skip
    rt = getattr(sol, "reserve_torques", None)
    rc = tuple(getattr(sol, "reserve_coordinates", None) or ())
    if rt is not None and rc:
        rt = np.asarray(rt, dtype=float)
        cn = tuple(jt.coordinate_names)
        for k, c in enumerate(rc):
            leg = c in legs if legs is not None else c.endswith(("_r", "_l"))
            if not leg or c not in cn:
                continue
            tau = np.asarray(jt.tau, dtype=float)[:, cn.index(c)]
            ok = np.isfinite(rt[:, k]) & np.isfinite(tau)
            if ok.sum() < 2:
                continue
            peak = float(np.max(np.abs(tau[ok])))
            if peak <= 1.0:
                continue
            pct = 100.0 * float(np.sqrt(np.mean(rt[ok, k] ** 2))) / peak
            if pct > th["reserve_rms_pct_peak_torque"]:
                out.append(
                    _flag(trial, f"{c}_reserve_rms_pct", pct, th["reserve_rms_pct_peak_torque"],
                          f"the reserve actuator of {c} carries {pct:.0f} % of its peak joint "
                          "torque (RMS): the muscles cannot produce that moment")
                )  # fmt: skip
    out += frontal_reserve_flags(trial, sol, th)
    out += kkt_flags(trial, sol, th)
    return out


def kkt_flags(trial: str, sol: Any, thresholds: Mapping[str, float] = THRESHOLDS) -> list[Flag]:
    """A KKT figure (stationarity, primal feasibility, dual feasibility, complementarity;
    :func:`msk.optimization.kkt`) of a frame the tension QP's solver called optimal above
    ``kkt_relative`` (1e-6) of its scale (:func:`msk.optimization.kkt_scale`: the gradient's
    magnitude, the right-hand sides' — the scaled joint torques — for primal feasibility):
    the solver's "optimal" is not one. DAQP's solutions sit at round-off (1e-15–1e-12 of
    the scale), an iterative solver's at its own tolerance; the infeasible frames (bounded
    least-squares point) are not checked here but flagged by
    ``optimization_infeasible_frames``. ``sol``: a
    :class:`msk.optimization.muscle_forces.MuscleForces` (its ``kkt``)."""
    th = {**THRESHOLDS, **thresholds}
    worst = getattr(sol, "kkt", None)
    if worst is None:
        return []
    out: list[Flag] = []
    tol = th["kkt_relative"]
    for k, c in enumerate(worst.columns):
        rel = float(worst.relative[k])
        if rel > tol:
            out.append(
                _flag(trial, f"optimization_kkt_{c}", rel, tol,
                      f"the tension QP of frame {int(worst.frame[k])} "
                      f"(t = {float(worst.time_s[k]):.3f} s), solved as optimal, fails its KKT "
                      f"check: {c.replace('_', ' ')} {rel:.1e} of its scale (tolerance "
                      f"{tol:.0e}; {float(worst.value[k]):.2e} in the QP's scaled variables)")
            )  # fmt: skip
    return out


def frontal_reserve_figures(sol: Any) -> dict[str, dict[str, Any]]:
    """Per knee compartment row of ``compartment_nonnegative`` (``sol``: a
    :class:`msk.optimization.muscle_forces.MuscleForces`), its frontal reserve moments' ``peak_nm``,
    ``rms_nm`` (None without a finite frame) and ``frames_above_1pct`` (frames above 1 % of the
    knee's peak inverse-dynamics frontal moment); empty without rows."""
    res = getattr(sol, "frontal_reserve_moments", None)
    rows = tuple(getattr(sol, "compartment_rows", ()) or ())
    if res is None or not rows:
        return {}
    res = np.asarray(res, dtype=float)
    peak_id = getattr(sol, "id_frontal_moment_peak_nm", None) or 0.0
    out: dict[str, dict[str, Any]] = {}
    for k, row in enumerate(rows):
        col = res[:, k][np.isfinite(res[:, k])]
        out[row] = {
            "peak_nm": float(col.max()) if col.size else None,
            "rms_nm": float(np.sqrt(np.mean(col**2))) if col.size else None,
            "frames_above_1pct": int((col > 0.01 * peak_id).sum()),
        }
    return out


def frontal_reserve_flags(
    trial: str, sol: Any, thresholds: Mapping[str, float] = THRESHOLDS
) -> list[Flag]:
    """Knee compartment rows (``[optimization] compartment_nonnegative``) whose frontal reserve
    moment peaks above ``frontal_reserve_pct_peak_moment`` (10 %) of the peak frontal moment of
    the knee's inverse-dynamics load about the contact midpoint (``sol``: a
    :class:`msk.optimization.muscle_forces.MuscleForces`; figures of
    :func:`frontal_reserve_figures`).
    The reserve is the moment about the opposite contact point that no admissible tension
    balances — in a knee, the collateral ligaments' share, absent from the model. The bound
    transposes OpenSim's guideline for reserve actuators (peak reserve below 10 % of the peak
    joint moment; OpenSim documentation, "Reserves and Residuals" and the simulation checklist)
    to the frontal plane."""
    th = {**THRESHOLDS, **thresholds}
    peak_id = getattr(sol, "id_frontal_moment_peak_nm", None)
    if peak_id is None or not peak_id > 0:
        return []
    out: list[Flag] = []
    for row, fig in frontal_reserve_figures(sol).items():
        if fig["peak_nm"] is None:
            continue
        pct = 100.0 * fig["peak_nm"] / float(peak_id)
        if pct > th["frontal_reserve_pct_peak_moment"]:
            out.append(
                _flag(trial, f"{row}_frontal_reserve_pct", pct,
                      th["frontal_reserve_pct_peak_moment"],
                      f"{row}: a frontal reserve moment of up to {fig['peak_nm']:.1f} N·m "
                      f"({pct:.0f} % of the knee's peak frontal moment {peak_id:.1f} N·m; above "
                      f"1 % of it on {fig['frames_above_1pct']} frames) keeps the compartment "
                      "from pulling where no muscle can: ligaments the model lacks would carry it")
            )  # fmt: skip
    return out


def contact_flags(trial: str, loads: Any, *, unassigned_pct: float = 1.0) -> list[Flag]:
    """Plate contacts whose load went to no body (:attr:`msk.dynamics.loads.ExternalLoads.flags`):
    both
    feet on one plate (its single wrench cannot be split between them: one resultant and one
    centre of pressure for two feet) or a load with no foot over the plate. Their frames are
    excluded from the residuals, the identification and the muscle forces
    (:func:`msk.dynamics.loads.contact_measured`): the flag says how many and where. A shared
    contact
    is always flagged; an unassigned one above ``unassigned_pct`` % of the frames (a
    treadmill's first frame with a belt's load and the foot not yet tracked is no finding)."""
    out: list[Flag] = []
    n = int(np.size(getattr(loads, "time", ())))
    for reason, mask, what in (
        ("shared", getattr(loads, "shared_contact", None), "both feet stand on one plate"),
        ("unassigned", getattr(loads, "unassigned_contact", None),
         "no foot stands on a loaded plate"),
    ):  # fmt: skip
        if mask is None or np.size(mask) != n or not np.any(mask):
            continue
        spans = [
            f"{c.plate} {c.start_time:.2f}–{c.end_time:.2f} s"
            + (f" ({', '.join(c.feet)})" if c.feet else "")
            for c in getattr(loads, "flags", ())
            if c.reason == reason
        ]
        k = int(np.count_nonzero(mask))
        if reason == "unassigned" and 100.0 * k / max(n, 1) <= unassigned_pct:
            continue
        out.append(
            _flag(trial, f"plate_{reason}_contact_frames", k, 0,
                  f"{what} in {k} frames ({'; '.join(spans[:3])}): its load is on no body, those "
                  "frames are left out of the residuals, the identification and the muscle forces")
        )  # fmt: skip
    return out


def gait_flags(
    trial_name: str,
    *,
    quality: Mapping[str, Any],
    model: Any,
    kinematics: Any,
    joint_torques: Any,
    mass_kg: float,
    height_m: float | None,
    marker_labels: Sequence[str] = (),
    optimization: Any = None,
    plate_mass_kg: float | None = None,
    peak_external_force_n: float | None = None,
    com_height_m: float | None = None,
    held: Sequence[str] = (),
    scaling_methods: Mapping[str, str] | None = None,
    thresholds: Mapping[str, float] = THRESHOLDS,
) -> list[Flag]:
    """Every gate of the module docstring on one gait trial.

    ``quality`` is the quality block of the run (``ik_marker_rms_mean_m``,
    ``residual_force_rms_pct_bw``, ``residual_moment_rms_nm`` …, None where not computed);
    ``optimization`` the tension result (:class:`msk.optimization.muscle_forces.MuscleForces`:
    forces,
    activations, excluded and infeasible frames, reserve torques); ``plate_mass_kg``
    :func:`body_mass_from_loads` of the trial; ``peak_external_force_n`` the
    largest ground-reaction magnitude as recorded (Hicks et al. 2015 state the moment bound on
    the measured external force; body weight when None); ``com_height_m`` the subject's
    centre-of-mass height above the floor (:func:`com_height`; 55 % of the stature when None);
    ``scaling_methods`` body → how it was scaled (a body left
    ``"unscaled"`` is flagged); ``held`` coordinates held near neutral by an IK coordinate task (the
    markers do not observe them; reported as such, not checked for range or freezing)."""
    th = {**THRESHOLDS, **thresholds}
    out: list[Flag] = []
    ik = quality.get("ik_marker_rms_mean_m")
    if ik is not None and np.isfinite(ik) and ik > th["ik_marker_rms_mean_m"]:
        out.append(
            _flag(trial_name, "ik_marker_rms_mean_m", ik, th["ik_marker_rms_mean_m"],
                  f"IK marker RMS {1000 * ik:.1f} mm over {1000 * th['ik_marker_rms_mean_m']:g} "
                  f"mm (worst marker {quality.get('ik_worst_marker', '?')})")
        )  # fmt: skip
    mx = np.asarray(getattr(kinematics, "marker_max", []), dtype=float)
    if mx.size and np.isfinite(mx).any():
        m = float(np.nanmean(mx))
        if m > th["ik_marker_max_mean_m"]:
            out.append(
                _flag(trial_name, "ik_marker_max_mean_m", m, th["ik_marker_max_mean_m"],
                      f"IK worst-marker error {1000 * m:.1f} mm on average over "
                      f"{1000 * th['ik_marker_max_mean_m']:g} mm (mostly "
                      f"{quality.get('ik_worst_marker', '?')})")
            )  # fmt: skip
    n_meas, n_obs = quality.get("contact_measured_frames"), quality.get("observed_measured_frames")
    if n_meas == 0 and quality.get("frames"):
        out.append(
            _flag(trial_name, "contact_measured_frames", 0.0, 1.0,
                  f"no frame of the {quality['frames']} in which the plates measure every foot's "
                  "ground contact (no plate loaded, a foot off the plates, or contact at the "
                  "trial's edges only): no residuals, plate mass, muscle forces or knee contact "
                  "for this trial, and no joint torque of a leg whose foot stands unmeasured")
        )  # fmt: skip
    pct = 100.0 * n_obs / n_meas if n_meas and n_obs is not None else 100.0
    if pct < th["observed_measured_frames_min_pct"]:
        out.append(
            _flag(trial_name, "observed_measured_frames_min_pct", pct,
                  th["observed_measured_frames_min_pct"],
                  f"only {n_obs} of the {n_meas} frames whose ground contact the plates measure "
                  f"({pct:.0f} %) have every leg segment observed by its markers "
                  "(msk.kinematics.observation): the residuals, the plate mass and the "
                  "identifications "
                  "rest on those few")
        )  # fmt: skip
    raised = quality.get("unmeasured_contact_raised_frames") or 0
    if raised and quality.get("frames"):
        out.append(
            _flag(trial_name, "unmeasured_contact_raised_frames", float(raised), 0.0,
                  f"a foot stands on a raised surface no plate measures (an uninstrumented step "
                  f"or box, found by the plates' vertical force falling short of the body's "
                  f"momentum balance) in {raised} of the {quality['frames']} frames: that "
                  "leg's joint torques are not written there, and no residual, muscle force or "
                  "knee contact comes from those frames")
        )  # fmt: skip
    ui = quality.get("unmeasured_contact_inside_pct")
    if ui is not None and ui > th["unmeasured_contact_inside_pct"]:
        span = quality.get("unmeasured_contact_inside_s") or [float("nan")] * 2
        feet = quality.get("unmeasured_contact_frames_by_foot") or {}
        out.append(
            _flag(trial_name, "unmeasured_contact_inside_pct", float(ui),
                  th["unmeasured_contact_inside_pct"],
                  f"a foot stands on a surface no plate measures in {ui:.0f} % of the frames "
                  f"between the first and last measured one ({span[0]:.2f}–{span[1]:.2f} s; "
                  + ", ".join(f"{f} {n}" for f, n in feet.items() if n) + " frames in the "
                  "trial): that leg's joint torques are not written there, and no residual, "
                  "muscle force or knee contact comes from those frames")
        )  # fmt: skip
    rf = quality.get("residual_force_rms_pct_bw")
    if rf is not None and np.isfinite(rf) and rf > th["residual_force_rms_pct_bw"]:
        out.append(
            _flag(trial_name, "residual_force_rms_pct_bw", rf, th["residual_force_rms_pct_bw"],
                  f"pelvis residual force RMS {rf:.1f} % BW over "
                  f"{th['residual_force_rms_pct_bw']:g} % BW (Hicks et al. 2015)")
        )  # fmt: skip
    rm = quality.get("residual_moment_rms_nm")
    if rm is not None and np.isfinite(rm):
        # COM height: the model's over the trial, else ≈ 55 % of stature (de Leva 1996)
        com_h = com_height_m if com_height_m else 0.55 * (height_m if height_m else 1.75)
        f_ext = peak_external_force_n if peak_external_force_n else mass_kg * G0
        pct = 100.0 * rm / (com_h * f_ext)
        if pct > th["residual_moment_rms_pct_com_height_peak_force"]:
            out.append(
                _flag(trial_name, "residual_moment_rms_pct_com_height_peak_force", pct,
                      th["residual_moment_rms_pct_com_height_peak_force"],
                      f"pelvis residual moment RMS {rm:.1f} N·m = {pct:.2f} % of COM height "
                      f"({com_h:.2f} m) × peak measured external force ({f_ext:.0f} N), over "
                      f"{th['residual_moment_rms_pct_com_height_peak_force']:g} % "
                      "(Hicks et al. 2015)")
            )  # fmt: skip
    if plate_mass_kg is not None and mass_kg > 0:
        d = 100.0 * (plate_mass_kg - mass_kg) / mass_kg
        if abs(d) > th["body_mass_difference_pct"]:
            out.append(
                _flag(trial_name, "plate_mass_difference_pct", d, th["body_mass_difference_pct"],
                      f"the plates weigh the subject at {plate_mass_kg:.1f} kg; the configuration"
                      f" says {mass_kg:g} kg ({d:+.1f} %)")
            )  # fmt: skip
        factor = plate_scale_factor(plate_mass_kg, mass_kg)
        if factor is not None:
            out.append(
                _flag(trial_name, "plate_force_scale", factor, 1.0,
                      f"the plates weigh the subject at {plate_mass_kg:.1f} kg, "
                      f"{plate_mass_kg / mass_kg:.3g} × the configured {mass_kg:g} kg: the "
                      f"forces look a factor {factor:g} off (ANALOG:SCALE, GEN_SCALE or the "
                      "channels' units mis-set); msk does not rescale them")
            )  # fmt: skip
    unscaled = sorted(b for b, m in (scaling_methods or {}).items() if m == "unscaled")
    if unscaled:
        out.append(
            _flag(trial_name, "unscaled_segments", len(unscaled), 0,
                  f"{', '.join(unscaled)} left at the generic model's size (no marker measured "
                  "the subject and no height is given: set subject.height_m)")
        )  # fmt: skip
    out += _coordinate_flags(trial_name, kinematics, th, set(held), model)
    out += _unobserved_flags(trial_name, model, kinematics, th)
    dup = sorted({lab for lab in marker_labels if list(marker_labels).count(lab) > 1})
    if dup:
        out.append(
            _flag(trial_name, "duplicate_marker_labels", len(dup), 0,
                  f"duplicate marker labels in the file: {', '.join(dup[:5])}")
        )  # fmt: skip
    if optimization is not None:
        legs = leg_coordinates(model) if model is not None else None
        out += optimization_flags(trial_name, optimization, joint_torques, th, legs or None)
    return out


def unmeasured_contact_figures(loads: Any, time: ArrayLike) -> dict[str, Any]:
    """``quality.unmeasured_contact_frames`` of ``loads`` (its ``contact``,
    :class:`msk.dynamics.loads.FootContact`, and ``measured`` frames): frames in which a foot
    stands on a surface no plate measures for at least :data:`msk.dynamics.loads.STANDING_S`
    (:meth:`msk.dynamics.loads.FootContact.standing`; its leg's joint torques are not written
    there), ``unmeasured_contact_frames_by_foot``, ``unmeasured_contact_raised_frames`` (those
    off the floor's level: a stair's upper steps, a box) and ``unmeasured_contact_inside_pct``:
    the share of the frames between the first and the last measured frame that have one (a
    walkway's steps before and after the plates lie outside; a foot off a plate in the middle
    of the task inside)."""
    contact = getattr(loads, "contact", None)
    if contact is None:
        return {}
    miss = np.asarray(contact.standing(), dtype=bool)
    anym: NDArray[np.bool_] = np.asarray(miss.any(axis=1), dtype=bool)
    meas = np.flatnonzero(np.asarray(loads.measured, dtype=bool))
    inside = None
    span = None
    if meas.size:
        a, b = int(meas[0]), int(meas[-1])
        inside = 100.0 * float(anym[a : b + 1].mean())
        t = np.asarray(time, dtype=float)
        hit = np.flatnonzero(anym[a : b + 1])
        if hit.size:
            span = [float(t[a + hit[0]]), float(t[a + hit[-1]])]
    floor = getattr(contact, "on_floor", None)
    raised = miss & ~np.asarray(floor, dtype=bool) if floor is not None else miss & False
    return {
        "unmeasured_contact_frames": int(anym.sum()),
        "unmeasured_contact_raised_frames": int(raised.any(axis=1).sum()),
        "unmeasured_contact_frames_by_foot": {
            f: int(miss[:, k].sum()) for k, f in enumerate(contact.feet)
        },
        "unmeasured_contact_inside_pct": inside,
        "unmeasured_contact_inside_s": span,
    }


def _mode(names: Sequence[str]) -> str:
    vals = [n for n in names if n]
    return max(set(vals), key=vals.count) if vals else ""


def gait_quality(
    trial: Any,
    kin: Any,
    jt: Any,
    loads: Any,
    emg: Any,
    sol: Any,
    strength: Any,
    ident: Any,
    body_weight: float,
    measured: NDArray[np.bool_],
    observed: NDArray[np.bool_],
    observation: Any = None,
) -> dict[str, Any]:
    """The data-quality figures of a gait trial (``summary.quality`` before its flags): marker
    gaps, IK marker RMS (mean, max, worst marker), frames measured and observed, and the pelvis
    residuals' RMS over the frames whose ground contact the plates measure (``measured``,
    :func:`msk.dynamics.loads.contact_measured`) and the markers observe (``observed`` ⊆
    ``measured``; ``observation``: :func:`msk.kinematics.observation.observed_frames`), None
    when there is none; with the EMG (``emg``), the tension result (``sol``), the strength
    identification (``strength``) and the mass identification (``ident``) their own figures.
    ``loads`` is the :class:`msk.dynamics.loads.ExternalLoads` (its plate assignments)."""
    ok = np.isfinite(jt.residual_force).all(axis=1) & observed
    res_f = rms(jt.residual_force[ok]) if ok.any() else None
    gaps = [
        {"marker": lab, "missing_frames": int(n), "longest_gap_frames": int(g)}
        for lab, n, g in zip(trial.gaps.labels, trial.gaps.n_missing, trial.gaps.longest_gap)
        if n > 0
    ]
    q: dict[str, Any] = {
        "frames": int(kin.time.size),
        "rate_hz": float(trial.point_rate_hz),
        "marker_gaps": gaps,
        "ik_failed_frames": int(kin.failed_frames.size),
        "ik_marker_rms_mean_m": float(np.nanmean(kin.marker_rms)),
        "ik_marker_rms_max_m": float(np.nanmax(kin.marker_rms)),
        "ik_worst_marker": _mode(kin.marker_max_name),
        "contact_measured_frames": int(measured.sum()),
        "observed_measured_frames": int(observed.sum()),
        "unobserved_segment_frames": (
            None if observation is None else {k: int(v) for k, v in observation.short.items()}
        ),
        "residual_force_rms_n": res_f,
        "residual_force_rms_pct_bw": None if res_f is None else 100 * res_f / body_weight,
        "residual_moment_rms_nm": rms(jt.residual_moment[ok]) if ok.any() else None,
        "plate_assignments": [
            {k: getattr(a, k) for k in ("plate", "body", "start_time", "end_time") if hasattr(a, k)}
            for a in getattr(loads, "assignments", ())
        ],
    }
    if emg is not None:
        flat = [emg.sources[k] for k in range(len(emg.muscles)) if not emg.usable[k]]
        q["emg_flat_channels"] = sorted(set(flat))
        q["emg_warnings"] = list(emg.warnings)
        q["emg_normalisation"] = emg.normalisation
    if sol is not None and sol.infeasible_frames is not None:
        q["optimization_infeasible_frames"] = sol.infeasible_frames
    if strength is not None:
        q["strength_fit_r2"] = float(strength.profile.r2)
    if ident is not None:
        q["identification_condition_number"] = ident.condition_number
    return q


def trial_flags(
    trial: str,
    *,
    file_name: str,
    quality: Mapping[str, Any],
    model: Any,
    kinematics: Any,
    joint_torques: Any,
    external: Any,
    measured: NDArray[np.bool_],
    mass_kg: float,
    height_m: float | None,
    marker_labels: Sequence[str],
    optimization: Any,
    plate_mass_kg: float | None,
    held: Sequence[str],
    model_info: Mapping[str, Any],
    swapped_pairs: Sequence[tuple[str, str, float]],
    static_name: str | None,
    emg_channels: Mapping[str, Any],
    analog_labels: Sequence[str],
    file_metadata: Mapping[str, Any],
) -> list[Flag]:
    """The gates raised on a gait trial (:func:`gait_flags`, :func:`contact_flags`,
    :func:`model_flags`), its left/right labels that look swapped (``swapped_pairs``,
    :func:`swapped_sides`) or were swapped back before scaling, a static trial refused or
    contradicted by the task (``model_info``: what personalisation reported), the
    configuration's EMG channels missing from the file (``emg_channels`` muscle → channel, the
    file's ``analog_labels``) and what the reader noticed in the file (``file_metadata``: its
    typed ``flags`` and ``warnings``: duplicate labels renamed, NaN plate samples…)."""
    from msk.dynamics.loads import peak_measured_force_n

    scaling = model_info.get("scaling", {}).get("bodies", {})
    out = list(
        gait_flags(
            trial, quality=quality, model=model, kinematics=kinematics,
            joint_torques=joint_torques, mass_kg=mass_kg, height_m=height_m,
            marker_labels=marker_labels, optimization=optimization, plate_mass_kg=plate_mass_kg,
            held=tuple(held), scaling_methods={b: v["method"] for b, v in scaling.items()},
            peak_external_force_n=peak_measured_force_n(external, measured),
            com_height_m=com_height(model, kinematics, measured, floor_m=float(np.median(
                list(external.metadata.get("surface_heights_m", {}).values()) or [0.0]))),
        )
    )  # fmt: skip
    out += contact_flags(trial, external)
    out += model_flags(trial, model_info, [b.name for b in model.bodies])
    for r, lft, dz in swapped_pairs:
        out.append(
            Flag(trial, f"{r}/{lft}_swapped", dz, -SWAP_MIN_SEPARATION_M,
                 f"{r} is {-1000 * dz:.0f} mm left of {lft} (the subject's right "
                 "from the pelvis): their labels look swapped (a labelling error in the file, or "
                 "the wrong side in the config)")
        )  # fmt: skip
    swapped = dict(model_info.get("marker_set", {}).get("swapped_back", {}))
    if swapped:
        out.append(
            Flag(trial, "marker_labels_swapped_back", max(-v for v in swapped.values()),
                 SWAP_MIN_SEPARATION_M,
                 "left/right labels swapped in the file: " + ", ".join(
                     f"{pair} ({-1000 * v:.0f} mm on the wrong side)"
                     for pair, v in sorted(swapped.items()))
                 + "; their markers were exchanged back before scaling and IK "
                 "(msk.quality.swapped_label_pairs, judged from the pelvis markers)")
        )  # fmt: skip
    if model_info.get("static_rejected"):
        out.append(
            Flag(trial, "static_not_used", 1.0, 0.0,
                 f"static trial {static_name!r}: {model_info['static_rejected']}")
        )  # fmt: skip
    bad = dict(model_info.get("static_check", {}).get("contradicted_m", {}))
    if bad:
        out.append(
            Flag(trial, "static_markers_contradicted_m", max(bad.values()),
                 THRESHOLDS["static_marker_discrepancy_m"],
                 "the static trial's " + ", ".join(
                     f"{lab} ({1000 * d:.0f} mm)" for lab, d in sorted(bad.items()))
                 + " disagree with their segment's other markers in the task (median distance "
                 "difference): mislabelled or ghost markers in the static, placed from the task "
                 "instead (msk.quality.inconsistent_static_markers)")
        )  # fmt: skip
    if emg_channels:
        from msk.muscles.emg import missing_channels

        _, absent = missing_channels(emg_channels, analog_labels)
        if absent:
            muscles = sorted(m for m, c in emg_channels.items() if str(c).strip() in absent)
            out.append(
                Flag(trial, "emg_channels_missing", len(absent), 0,
                     f"{file_name} has no analog channel "
                     f"{', '.join(repr(c) for c in absent)} of the configuration's [emg] "
                     f"channels: {', '.join(muscles)} tracked by no EMG in this trial")
            )  # fmt: skip
    typed = tuple(file_metadata.get("flags", ()))  # the reader's typed flags keep their quantity
    for f in typed:
        out.append(
            Flag(trial, str(f["quantity"]), float(f["value"]), float(f["threshold"]),
                 f"{file_name}: {f['message']}")
        )  # fmt: skip
    said = {f["message"] for f in typed}
    for w in file_metadata.get("warnings", ()):
        if w in said:
            continue
        out.append(Flag(trial, "input_file", 1.0, 0.0, f"{file_name}: {w}"))
    return out


def plate_edge_flags(trial: str, metadata: Mapping[str, Any]) -> list[Flag]:
    """A foot straddling a plate's edge (``metadata["plate_edge"]`` of the external loads,
    :mod:`msk.dynamics.plate_footprint`): those frames count as an unmeasured contact."""
    return [
        Flag(trial, "foot_past_plate_edge_m", e["max_outside_m"], 0.01,
             f"{e['foot']} straddles the edge of {e['plate']} from "
             f"{e['start_s']:.2f} to {e['end_s']:.2f} s ({e['frames']} frames, up to "
             f"{100 * e['max_outside_m']:.0f} cm past it): part of its ground reaction is "
             "off the plate, so those frames count as an unmeasured contact (no joint "
             "torques of that leg, residual, muscle force or knee contact from them; "
             "msk.dynamics.plate_footprint)")
        for e in metadata.get("plate_edge", ())
    ]  # fmt: skip


def marker_rename_flags(trial: str, model_info: Mapping[str, Any]) -> list[Flag]:
    """A ``[markers] rename`` entry naming a label in no trial (a typo: the model marker it
    meant is not tracked), from the marker set's notes (``model_info["marker_set"]``)."""
    unmatched = [
        n for n in (model_info.get("marker_set") or {}).get("notes", ())
        if str(n).startswith("markers.rename: labels in no trial")
    ]  # fmt: skip
    return [
        Flag(trial, "marker_rename_unmatched", float(len(str(note).split(":", 2)[-1].split(","))),
             0.0, f"{note} (a typo? the model markers they name are not tracked from them)")
        for note in unmatched
    ]  # fmt: skip


def dead_plate_flags(trial: str, dead_plates: Sequence[Mapping[str, Any]]) -> list[Flag]:
    """A plate reading nothing under a foot standing on it (a dead, disconnected or mis-mapped
    plate: that foot's ground reaction is missing)."""
    return [
        Flag(trial, "plate_dead", d["max_force_n"], 20.0,
             f"force plate {d['plate']} reads at most {d['max_force_n']:.0f} N while "
             f"{d['foot']} stands on it for {d['seconds']:.2f} s ({d['start_s']:.2f}–"
             f"{d['end_s']:.2f} s): a dead, disconnected or mis-mapped plate; that foot's "
             "ground reaction is missing")
        for d in dead_plates
    ]  # fmt: skip
