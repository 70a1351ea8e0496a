"""Hip joint centres by regression on pelvis landmarks, and a model whose hips sit there.

Pelvis frame (ISB, Wu et al. 2002, J Biomech 35:543-548): origin O at the mid-ASIS; z from
the left to the right ASIS; x anterior, in the plane of the two ASIS and the mid-PSIS (or the
sacral marker), normal to z; y = z × x, superior. Pelvic width PW = ‖ASIS_R − ASIS_L‖, pelvic
depth PD = ‖O − mid-PSIS‖ (the sacral marker where there are no PSIS markers). In this frame
the right hip centre is (x, y, z) and the left one (x, y, −z), with (mm):

- ``harrington`` (Harrington et al. 2007, J Biomech 40:595-602, the equations from PW and PD;
  MRI of 8 adults and 24 children, leave-one-out errors 5.2 / 3.6 / 3.2 mm)::

      x = −0.24 PD − 9.9,  y = −0.30 PW − 10.9,  z = 0.33 PW + 7.3

  and, given the leg length LL (ASIS to medial malleolus; ``leg_length_m``)::

      y = −0.16 PW − 0.04 LL − 7.1,  z = 0.28 PD + 0.16 PW + 7.9

- ``davis`` (Davis et al. 1991, Hum Mov Sci 10:575-587; the form Vicon's Plug-in Gait uses,
  with its constants θ = 0.5 rad and β = 0.314 rad where the paper rounds to 28.4° and 18°):
  C = 0.115 LL − 15.3, the ASIS-to-trochanter distance X_dis = 0.1288 LL − 48.56 (the lab's
  measured one where given) plus the marker radius r_m, PW the lab's inter-ASIS distance where
  given::

      x = C cos θ sin β − (X_dis + r_m) cos β
      y = −(X_dis + r_m) sin β − C cos θ cos β
      z = PW/2 − C sin θ

- ``bell`` (Bell et al. 1990, J Biomech 23:617-621): x = −0.19 PW, y = −0.30 PW,
  z = 0.36 PW.

- ``functional`` (:func:`functional_hip_centres`, when the session has a trial of role
  ``functional``: the subject moving each hip through its range, a "star" or circumduction):
  each thigh marker m, expressed in the pelvis' frame in every frame t (the pelvis posed on its
  markers' static positions, Söderkvist & Wedin 1993), moves on a sphere about the hip centre c,
  ‖p_m(t) − c‖ = r_m; with k_m = r_m² − ‖c‖² the system 2 p_m(t)·c + k_m = ‖p_m(t)‖² is
  linear in (c, k_1…k_M): its least-squares solution over every marker and frame is the
  multi-marker centre of Gamage & Lasenby (2002, J Biomech 35:87-93), which needs no thigh
  cluster (one marker per thigh is enough: Plug-in Gait's wand and knee markers). The fit is
  refused (the regression or the model's hip is kept, said in the summary) when the thigh
  markers sweep less than :data:`FUNCTIONAL_MIN_RANGE_DEG` about the centre: the error of a
  functional centre grows quickly as the range of hip motion shrinks (Piazza SJ et al. 2004,
  J Biomech 37:349-356; Camomilla V et al. 2006, J Biomech 39:1096-1106).

Harrington et al. (2007) found their equations within 5 mm of the MRI centres where Bell's and
Davis' erred by 10-20 mm and more (Davis': mostly too far anterior and lateral), and Sangeux
et al. (2014, Gait Posture 40:20-25) found Harrington's as good as the best functional methods
in healthy adults: ``harrington`` is the default of :func:`regression_hip_centres`.

:func:`place_hip_centres` puts a model's hips there the way a marker placement does (OpenSim's
scaling with hip-centre virtual markers): the pelvis *body*, with its hip sockets and muscle
attachments, is posed in the static so that its hips sit on the regression centres
(:func:`pelvis_pose_for_hips`), and the model's pelvis markers are moved to where the static
puts them on that pose (:func:`with_pelvis_markers`). The hips then keep their place against
the pelvis markers through every later step (marker placement, inverse kinematics), and the
pelvis' muscles keep their geometry against the hip (moving the hip joints inside the pelvis
instead left the gluteal paths 34 mm off on a Plug-in Gait subject: 22 muscles saturated).
The hip *width* alone is then set to the regression's (:func:`with_hip_width`: the pelvis is
scaled as one body, so its hip width is the generic model's share of the pelvic width).

Without a static trial (:func:`place_hip_centres_from_motion`) the landmarks are the task's:
the pelvis markers' shape in the pelvis frame they define, median over the frames
(:func:`motion_pelvis_landmarks`: a rigid body's markers keep it whatever the pelvis does), and
the leg length the lab's, else the longest straight ASIS-to-malleolus distance the walk shows
(:data:`MOTION_LEG_LENGTH_PERCENTILE`); the hips are placed before the motion placement, which
keeps the pelvis markers where they are put here.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import MissingDataError, ModelError

__all__ = [
    "DAVIS_BETA_RAD",
    "DAVIS_THETA_RAD",
    "FUNCTIONAL_MIN_RANGE_DEG",
    "HIP_CENTRE_METHODS",
    "MOTION_LEG_LENGTH_PERCENTILE",
    "PelvisLandmarks",
    "functional_hip_centres",
    "motion_pelvis_landmarks",
    "no_static_hip_centre",
    "pelvis_frame",
    "pelvis_pose_for_hips",
    "place_hip_centres",
    "place_hip_centres_from_motion",
    "regression_hip_centres",
    "with_hip_width",
    "with_pelvis_markers",
]

Array = NDArray[np.float64]

#: The hip-centre methods (``model.hip_centre``): the generic model's own (scaled with its
#: pelvis) or a regression of this module.
HIP_CENTRE_METHODS: tuple[str, ...] = ("model", "harrington", "davis", "bell")

#: Davis et al.'s (1991) angles as Plug-in Gait applies them (rad): θ, of the hip centre about
#: the ASIS-to-trochanter line, and β, of that line below the pelvis plane (reproduce Vicon's
#: stored hip centre to 0.01 mm where the paper's 28.4° leave 0.4 mm)
DAVIS_THETA_RAD = 0.5
DAVIS_BETA_RAD = 0.314

#: least sweep (deg) a functional trial must give a hip: twice the 95th percentile of a thigh
#: marker's distance from its mean position in the pelvis over its distance from the centre,
#: the largest over a side's markers (±20°: with 1 mm of marker noise a synthetic circumduction
#: of ±8° put the centre 62 mm off, ±15° 17-19 mm, ±20° 8-10 mm, ±30° 2-4 mm; module docstring)
FUNCTIONAL_MIN_RANGE_DEG = 40.0


@dataclass(frozen=True)
class PelvisLandmarks:
    """Pelvis landmarks in one frame (m): the two ASIS and the posterior reference (mid-PSIS,
    or the sacral marker)."""

    asis_r: Array
    asis_l: Array
    posterior: Array

    @property
    def width_m(self) -> float:
        """Pelvic width PW, ‖ASIS_R − ASIS_L‖."""
        return float(np.linalg.norm(self.asis_r - self.asis_l))

    @property
    def depth_m(self) -> float:
        """Pelvic depth PD, ‖mid-ASIS − posterior‖."""
        return float(np.linalg.norm(0.5 * (self.asis_r + self.asis_l) - self.posterior))


def pelvis_frame(lm: PelvisLandmarks) -> tuple[Array, Array]:
    """The ISB pelvis frame (rotation (3, 3) with columns x anterior, y superior, z right; and
    its origin, the mid-ASIS).

    Raises:
        MissingDataError: a landmark is not finite or the three are collinear.
    """
    pts = np.array([lm.asis_r, lm.asis_l, lm.posterior], dtype=float)
    if not np.isfinite(pts).all():
        raise MissingDataError("pelvis frame: an ASIS or the PSIS/sacral landmark is missing")
    o = 0.5 * (pts[0] + pts[1])
    z = pts[0] - pts[1]
    nz = float(np.linalg.norm(z))
    if nz < 1e-6:
        raise MissingDataError("pelvis frame: the two ASIS coincide")
    z /= nz
    a = o - pts[2]
    x = a - np.dot(a, z) * z
    nx = float(np.linalg.norm(x))
    if nx < 1e-6:
        raise MissingDataError("pelvis frame: the PSIS/sacral landmark is on the ASIS line")
    x /= nx
    y = np.cross(z, x)
    return np.column_stack([x, y, z]), o


def _side_value(v: float | Mapping[str, float] | None, side: str) -> float | None:
    """``v`` for ``side`` ("r"/"l"): the number itself, or a mapping's entry ("r" or "R")."""
    if v is None:
        return None
    if isinstance(v, Mapping):
        x = v.get(side, v.get(side.upper()))
        return None if x is None else float(x)
    return float(v)


def regression_hip_centres(
    lm: PelvisLandmarks,
    *,
    method: str = "harrington",
    leg_length_m: float | Mapping[str, float] | None = None,
    marker_radius_m: float = 0.007,
    asis_trochanter_m: float | Mapping[str, float] | None = None,
    inter_asis_m: float | None = None,
) -> dict[str, Array]:
    """``{"r": centre, "l": centre}`` (m, in the landmarks' frame) by the regression
    ``method`` (module docstring; ``davis`` needs ``leg_length_m``, ``harrington`` uses it when
    given). ``leg_length_m`` and ``asis_trochanter_m`` are one number or one per side (``"r"``/
    ``"l"``, as Plug-in Gait's ``RLegLength``…). ``davis`` takes, as Plug-in Gait does, the
    lab's ASIS-to-trochanter distance for X_dis and its inter-ASIS distance for PW where given
    (``asis_trochanter_m``, ``inter_asis_m``), else the regression's and the markers'.

    Raises:
        ModelError: an unknown method, or ``davis`` without a leg length.
        MissingDataError: the landmarks do not define a pelvis frame.
    """
    rot, o = pelvis_frame(lm)
    pw, pd = 1000.0 * lm.width_m, 1000.0 * lm.depth_m
    local: dict[str, tuple[float, float, float]] = {}
    for side in ("r", "l"):
        ll_s = _side_value(leg_length_m, side)
        ll = None if ll_s is None else 1000.0 * ll_s
        if method == "harrington":
            x = -0.24 * pd - 9.9
            if ll is None:
                y, z = -0.30 * pw - 10.9, 0.33 * pw + 7.3
            else:
                y, z = -0.16 * pw - 0.04 * ll - 7.1, 0.28 * pd + 0.16 * pw + 7.9
        elif method == "davis":
            if ll is None:
                raise ModelError(f"hip centre 'davis' needs the leg length (side {side})")
            c = 0.115 * ll - 15.3
            th, be = DAVIS_THETA_RAD, DAVIS_BETA_RAD
            atd = _side_value(asis_trochanter_m, side)
            xd = (0.1288 * ll - 48.56 if atd is None else 1000.0 * atd) + 1000.0 * marker_radius_m
            w = pw if inter_asis_m is None else 1000.0 * float(inter_asis_m)
            x = c * np.cos(th) * np.sin(be) - xd * np.cos(be)
            y = -xd * np.sin(be) - c * np.cos(th) * np.cos(be)
            z = 0.5 * w - c * np.sin(th)
        elif method == "bell":
            x, y, z = -0.19 * pw, -0.30 * pw, 0.36 * pw
        else:
            raise ModelError(
                f"hip centre: unknown regression {method!r} (one of {HIP_CENTRE_METHODS})"
            )
        local[side] = (x, y, z)
    out = {}
    for side, s in (("r", 1.0), ("l", -1.0)):
        x, y, z = local[side]
        out[side] = np.asarray(rot @ (np.array([x, y, s * z]) / 1000.0) + o, dtype=float)
    return out


def _model_hips(model: Any) -> dict[str, Array]:
    """The hip centres in the pelvis body frame: the pelvis-side placement of the joints whose
    parent is the pelvis and child a femur."""
    out: dict[str, Array] = {}
    for j in model.joints:
        for side in ("r", "l"):
            if j.parent == "pelvis" and j.child == f"femur_{side}":
                out[side] = np.asarray(j.parent_offset.translation, dtype=float)
    return out


def _rotation_between(a: Array, b: Array) -> Array:
    """The smallest rotation taking unit ``a`` to unit ``b`` (Rodrigues)."""
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    s = float(np.linalg.norm(v))
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        perp = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
        perp /= np.linalg.norm(perp)
        return np.asarray(2.0 * np.outer(perp, perp) - np.eye(3), dtype=float)
    k = v / s
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.asarray(np.eye(3) + s * kx + (1.0 - c) * kx @ kx, dtype=float)


def _pelvis_model_markers(model: Any) -> dict[str, Array]:
    from msk.model.markersets import pelvis_landmarks

    return {k: np.asarray(mk.offset, dtype=float) for k, mk in pelvis_landmarks(model).items()}


def _landmarks_of(means: Mapping[str, ArrayLike]) -> dict[str, Array]:
    """The static's pelvis landmarks by label (``asis_r``… ``sacrum``, finite only)."""
    from msk.model.markersets import parse_label

    out: dict[str, Array] = {}
    for lab, v in means.items():
        x = np.asarray(v, dtype=float)
        if x.shape != (3,) or not np.isfinite(x).all():
            continue
        p = parse_label(lab)
        if p.kind != "landmark":
            continue
        if p.landmark in ("asis", "psis") and p.side in ("R", "L"):
            out.setdefault(f"{p.landmark}_{p.side.lower()}", x)
        elif p.landmark == "sacrum":
            out.setdefault("sacrum", x)
    return out


def _posterior(pts: Mapping[str, Array]) -> Array | None:
    if "psis_r" in pts and "psis_l" in pts:
        return 0.5 * (pts["psis_r"] + pts["psis_l"])
    return pts.get("sacrum")


def _body_of(label: str) -> tuple[str | None, str | None]:
    """(side "r"/"l" or None, the landmark's body stem) of a label."""
    from msk.model.markersets import LANDMARK_BODIES, parse_label

    p = parse_label(label)
    return ((p.side or "").lower() or None), LANDMARK_BODIES.get(p.landmark or "")


def functional_hip_centres(
    means: Mapping[str, ArrayLike],
    markers: ArrayLike,
    labels: tuple[str, ...] | list[str],
    *,
    min_range_deg: float = FUNCTIONAL_MIN_RANGE_DEG,
) -> tuple[dict[str, Array], dict[str, Any]]:
    """The hip centres (side → (3,) m, in the frame of the static ``means``: label → mean
    position) from a functional trial's ``markers`` (N, M, 3) m of ``labels`` (the static's
    names), by the sphere fit of the module docstring; and a summary per side (markers used,
    frames, residual RMS, sweep, or why a side was not fitted). A side is fitted with at least
    one thigh marker (femur landmark or cluster) and a sweep of ``min_range_deg``; the pelvis
    needs three of its markers in the static and the trial.

    Raises:
        MissingDataError: fewer than three pelvis markers common to the static and the trial.
    """
    import warnings

    from msk.personalise.functional_joints import segment_poses

    x = np.asarray(markers, dtype=float)
    labs = list(labels)
    common = [lab for lab in labs if lab in means and np.isfinite(np.asarray(means[lab])).all()]
    pel = [lab for lab in common if _body_of(lab)[1] == "pelvis"]
    if len(pel) < 3:
        raise MissingDataError(
            "functional hip centre: the static and the functional trial share "
            f"{len(pel)} pelvis markers ({', '.join(pel) or 'none'}); three are needed"
        )
    local = np.array([np.asarray(means[lab], dtype=float) for lab in pel])
    world = x[:, [labs.index(lab) for lab in pel]]
    world = np.where((world == 0.0).all(axis=-1, keepdims=True), np.nan, world)
    pose = segment_poses(local, world)
    centres: dict[str, Array] = {}
    info: dict[str, Any] = {"pelvis_markers": pel, "pelvis_frames": int(pose.valid.sum())}
    for side in ("r", "l"):
        thigh = [lab for lab in common if _body_of(lab) == (side, "femur")]
        rows, rhs, owner = [], [], []
        for k, lab in enumerate(thigh):
            w = x[:, labs.index(lab)]
            ok = pose.valid & np.isfinite(w).all(axis=1) & ~(w == 0.0).all(axis=1)
            p = np.einsum("nji,nj->ni", pose.rotation[ok], w[ok] - pose.origin[ok])
            rows.append(p)
            rhs.append((p**2).sum(axis=1))
            owner.append(np.full(p.shape[0], k))
        n = sum(r.shape[0] for r in rows)
        if not thigh or n < 10 * (3 + len(thigh)):
            info[side] = {"fitted": False, "thigh_markers": thigh,
                          "reason": f"{n} frames of {len(thigh)} thigh markers posed"}  # fmt: skip
            continue
        p_all, b, own = np.concatenate(rows), np.concatenate(rhs), np.concatenate(owner)
        a = np.zeros((n, 3 + len(thigh)))
        a[:, :3] = 2.0 * p_all
        a[np.arange(n), 3 + own] = 1.0
        sol, *_ = np.linalg.lstsq(a, b, rcond=None)
        c = sol[:3]
        radii, sweep = [], []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            for p in rows:
                r = np.linalg.norm(p - c, axis=1)
                radii.append(r)
                # the path's extent over its radius (the extent does not depend on the fitted
                # centre, which a short arc leaves uncertain)
                spread = np.linalg.norm(p - p.mean(axis=0), axis=1)
                sweep.append(float(np.degrees(2.0 * np.percentile(spread, 95) / np.median(r))))
        resid = np.concatenate([r - np.sqrt(max(sol[3 + k] + c @ c, 0.0))
                                for k, r in enumerate(radii)])  # fmt: skip
        # the centre's standard error: the algebraic residual's σ through (AᵀA)⁻¹
        alg = a @ sol - b
        dof = max(n - a.shape[1], 1)
        cov = np.linalg.pinv(a.T @ a)[:3, :3] * float(alg @ alg) / dof
        se = float(np.sqrt(max(np.linalg.eigvalsh(cov).max(), 0.0)))
        rng = float(max(sweep))
        entry = {"thigh_markers": thigh, "frames": int(n // len(thigh)),
                 "residual_rms_m": float(np.sqrt(np.mean(resid**2))), "centre_se_m": se,
                 "sweep_deg": rng}  # fmt: skip
        if rng < min_range_deg:
            why = f"the thigh swept {rng:.0f}°, under {min_range_deg:g}°"
            info[side] = {**entry, "fitted": False, "reason": why}
            continue
        centres[side] = np.asarray(c, dtype=float)
        info[side] = {**entry, "fitted": True}
    return centres, info


def pelvis_pose_for_hips(
    model: Any,
    means: Mapping[str, ArrayLike],
    *,
    method: str = "harrington",
    leg_length_m: float | Mapping[str, float] | None = None,
    marker_radius_m: float = 0.007,
    centres: Mapping[str, Array] | None = None,
    asis_trochanter_m: float | Mapping[str, float] | None = None,
    inter_asis_m: float | None = None,
) -> tuple[Array, Array, dict[str, Any]]:
    """The pose (rotation (3, 3), origin (3,)) of ``model``'s pelvis body in a static trial
    (``means``: lab label or model marker name → mean position, m) that puts the model's hips
    at ``method``'s regression centres (or at ``centres``, side → point in the static, e.g.
    :func:`functional_hip_centres`), and a summary.

    First the pelvis' pose P₀ = (R₀, t₀) fitted rigidly to the static's ASIS and PSIS/sacral
    landmarks through the model's own pelvis markers (Söderkvist & Wedin 1993; the mid-PSIS
    stands for a sacral marker the static lacks, and the reverse; 3 points); then P₀ moved so
    that the midpoint of the model's hips h_r, h_l lands on that of the regression centres
    H_r, H_l and the inter-hip axis on theirs (the smallest rotation Q taking
    R₀(h_r − h_l) to H_r − H_l): R = Q R₀, t = (H_r + H_l)/2 − R (h_r + h_l)/2. The pelvis'
    rotation about the inter-hip axis (its tilt) stays the markers'; where the model's hip
    width differs from the regression's, each hip is off by half the difference, medio-
    laterally (``width_residual_m``).

    Summary: method, PW, PD, the leg length used, the marker fit's RMS, ``shift_m`` (each
    regression centre minus the hip of P₀, in the pelvis frame of P₀, m: how far the
    regression moves the hip against the markers) and the width residual.

    Raises:
        MissingDataError: the static lacks an ASIS or the PSIS/sacral landmark, or the model
            lacks pelvis markers or hips to pose it.
    """
    from msk.personalise.functional_joints import segment_poses

    exp = _landmarks_of(means)
    mod = _pelvis_model_markers(model)
    post = _posterior(exp)
    if "asis_r" not in exp or "asis_l" not in exp or post is None:
        raise MissingDataError(
            "hip centre: the static needs both ASIS and both PSIS (or a sacral marker); has "
            + (", ".join(sorted(exp)) or "none")
        )
    hips = _model_hips(model)
    if set(hips) != {"r", "l"}:
        raise MissingDataError(f"hip centre: model {model.name} has no pelvis–femur hip joints")
    lm = PelvisLandmarks(exp["asis_r"], exp["asis_l"], post)
    reg = (
        {s: np.asarray(centres[s], dtype=float) for s in ("r", "l")}
        if centres is not None
        else regression_hip_centres(
            lm,
            method=method,
            leg_length_m=leg_length_m,
            marker_radius_m=marker_radius_m,
            asis_trochanter_m=asis_trochanter_m,
            inter_asis_m=inter_asis_m,
        )
    )
    pairs: list[tuple[Array, Array]] = []
    for key in ("asis_r", "asis_l"):
        if key in mod:
            pairs.append((mod[key], exp[key]))
    mpost = _posterior(mod)
    if mpost is not None:
        pairs.append((mpost, post))
    if len(pairs) < 3:
        raise MissingDataError(
            f"hip centre: model {model.name} lacks pelvis markers (ASIS, PSIS/sacrum) to pose "
            "its pelvis in the static"
        )
    local = np.array([a for a, _ in pairs])
    pts = np.array([b for _, b in pairs])
    pose = segment_poses(local, pts[None])
    if not bool(pose.valid[0]):
        raise MissingDataError("hip centre: the pelvis markers are collinear")
    r0, t0 = pose.rotation[0], pose.origin[0]
    w = {s: r0 @ hips[s] + t0 for s in hips}
    a = w["r"] - w["l"]
    b = reg["r"] - reg["l"]
    q = _rotation_between(a / np.linalg.norm(a), b / np.linalg.norm(b))
    rot = q @ r0
    org = 0.5 * (reg["r"] + reg["l"]) - rot @ (0.5 * (hips["r"] + hips["l"]))
    info = {
        "method": method,
        "pelvic_width_m": lm.width_m,
        "pelvic_depth_m": lm.depth_m,
        "leg_length_m": dict(leg_length_m) if isinstance(leg_length_m, Mapping) else leg_length_m,
        "pelvis_fit_rms_m": float(pose.fit_rms_m[0]),
        "shift_m": {s: [float(v) for v in r0.T @ (reg[s] - w[s])] for s in ("r", "l")},
        "width_residual_m": float(np.linalg.norm(b) - np.linalg.norm(a)),
    }
    return np.asarray(rot, dtype=float), np.asarray(org, dtype=float), info


def with_pelvis_markers(
    model: Any, rotation: ArrayLike, origin: ArrayLike, means: Mapping[str, ArrayLike]
) -> tuple[Any, dict[str, float]]:
    """``model`` with its pelvis landmark markers (ASIS, PSIS, sacrum) at their static
    positions (``means``, m) in the pelvis pose (``rotation``, ``origin``): p = Rᵀ (x̄ − t)
    (a model sacral marker the static lacks: at the mid-PSIS). Returns the model and each
    moved marker's displacement (m)."""
    from msk.model.core import Marker
    from msk.model.markersets import parse_label

    r = np.asarray(rotation, dtype=float)
    t = np.asarray(origin, dtype=float)
    exp = _landmarks_of(means)
    moved: dict[str, float] = {}
    markers = []
    for mk in model.markers:
        p = parse_label(mk.name)
        x: Array | None = None
        if mk.body == "pelvis" and p.kind == "landmark":
            if p.landmark in ("asis", "psis") and p.side in ("R", "L"):
                x = exp.get(f"{p.landmark}_{p.side.lower()}")
            elif p.landmark == "sacrum":
                x = exp["sacrum"] if "sacrum" in exp else _posterior(exp)
        if x is None:
            markers.append(mk)
            continue
        local = r.T @ (x - t)
        moved[mk.name] = float(np.linalg.norm(local - np.asarray(mk.offset, dtype=float)))
        markers.append(Marker(mk.name, mk.body, local))
    return model.with_markers(markers), moved


def with_hip_width(model: Any, width_m: float) -> tuple[Any, float]:
    """``model`` with its two hip joints moved in the pelvis, symmetrically along the line
    joining them, to ``width_m`` apart (their midpoint and that line kept); and how far each
    hip moved (m, positive outwards). The pelvis is scaled as one body (from its markers), so
    its hip width is the generic model's proportion of the pelvic width, not the subject's:
    a regression or a functional fit sets the width too (PlugInC3D: the scaled gait2392 hips
    157 mm apart, Davis' 142 mm, Plug-in Gait's 130 mm). Only the joints move: a few
    millimetres medio-laterally against the pelvis' muscle attachments. Applied to the
    regressions, not to a functional fit, whose medio-lateral coordinate a walk's few degrees
    of hip abduction leave uncertain (PiG_Motion3's walk as the functional trial: 64 mm too
    wide a hip once set to the fit's width)."""
    import pinocchio as pin

    hips = _model_hips(model)
    if set(hips) != {"r", "l"}:
        raise MissingDataError(f"hip centre: model {model.name} has no pelvis–femur hip joints")
    axis = hips["r"] - hips["l"]
    now = float(np.linalg.norm(axis))
    u = axis / now
    step = 0.5 * (float(width_m) - now)
    new = {}
    for j in model.joints:
        for side, sign in (("r", 1.0), ("l", -1.0)):
            if j.parent == "pelvis" and j.child == f"femur_{side}":
                off = j.parent_offset
                t = np.asarray(off.translation, dtype=float) + sign * step * u
                new[j.name] = dataclasses.replace(j, parent_offset=pin.SE3(off.rotation.copy(), t))
    return model.with_joints(new), step


def _leg_lengths(means: Mapping[str, Array]) -> dict[str, float]:
    """Per side (``"R"``/``"L"``) the ASIS to medial (else lateral) malleolus marker distance,
    m: the leg length of Davis et al. (1991) when the lab did not measure it."""
    from msk.model.markersets import parse_label

    asis: dict[str, Array] = {}
    ankle: dict[tuple[str, str], Array] = {}
    for lab, v in means.items():
        x = np.asarray(v, dtype=float)
        if x.shape != (3,) or not np.isfinite(x).all():
            continue
        p = parse_label(lab)
        if p.side not in ("R", "L"):
            continue
        if p.landmark == "asis":
            asis.setdefault(p.side, x)
        elif p.landmark in ("ankle_med", "ankle_lat"):
            ankle.setdefault((p.side, p.landmark[-3:]), x)
    out: dict[str, float] = {}
    for s in ("R", "L"):
        a = ankle.get((s, "med"), ankle.get((s, "lat")))
        if s in asis and a is not None:
            out[s] = float(np.linalg.norm(asis[s] - a))
    return out


#: percentile of a walk's ASIS-to-malleolus marker distance taken as the leg length without a
#: static trial: the distance is longest with the knee straight (near foot strike), and the
#: 95th percentile rather than the maximum keeps a noisy frame out (PiG_Motion3: 932 / 938 mm
#: against the lab's measured 920 mm, taped over the knee)
MOTION_LEG_LENGTH_PERCENTILE = 95.0


def _davis_inputs(
    measured: Mapping[str, float], lab: Any, source: str
) -> tuple[dict[str, float], dict[str, Any]]:
    """The leg length per side for ``davis``: the lab's (``lab``: a
    :class:`msk.trial.Subject`, its ``leg_lengths_m``; Plug-in Gait's ``LegLength``), else the
    markers' (``measured``); a side with neither takes the other side's. And the summary
    entries (lengths and their source)."""
    labs = dict(getattr(lab, "leg_lengths_m", None) or {})
    out: dict[str, float] = {}
    src: dict[str, str] = {}
    for s in ("R", "L"):
        if s in labs:
            out[s], src[s] = float(labs[s]), "the lab's (PROCESSING:LegLength)"
        elif s in measured:
            out[s], src[s] = float(measured[s]), source
    for s, o in (("R", "L"), ("L", "R")):
        if s not in out and o in out:
            out[s], src[s] = out[o], f"the {'left' if o == 'L' else 'right'} leg's"
    info: dict[str, Any] = {"leg_lengths_m": dict(out), "leg_length_source": src}
    troch = dict(getattr(lab, "asis_trochanter_m", None) or {})
    ia = getattr(lab, "inter_asis_m", None)
    if troch:
        info["asis_trochanter_m"] = troch
    if ia is not None:
        info["inter_asis_m"] = float(ia)
    return out, info


def _place_regression(
    model: Any,
    means: Mapping[str, Array],
    *,
    method: str,
    marker_radius_m: float,
    measured_legs: Mapping[str, float],
    leg_source: str,
    lab: Any,
) -> tuple[Any, dict[str, Any]]:
    """The model with its hips at ``method``'s regression centres from the pelvis landmarks of
    ``means`` (label → position, m), its pelvis markers moved there; or the model unchanged
    and a summary saying why (no leg length for ``davis``, pelvis markers missing)."""
    kw: dict[str, Any] = {}
    extra: dict[str, Any] = {}
    if method == "davis":
        legs, extra = _davis_inputs(measured_legs, lab, leg_source)
        if not legs:
            why = (
                "no leg length: none in the file (PROCESSING:LegLength), no ASIS and malleolus "
                "markers"
            )
            return model, {"method": "model", "requested": method, "reason": why}
        kw = {
            "leg_length_m": {s.lower(): v for s, v in legs.items()},
            "asis_trochanter_m": {
                s.lower(): v for s, v in extra.get("asis_trochanter_m", {}).items()
            }
            or None,
            "inter_asis_m": extra.get("inter_asis_m"),
        }
    try:
        model, rot, org, info = _posed_at(
            model, means, method=method, marker_radius_m=marker_radius_m, **kw
        )
    except MissingDataError as exc:
        return model, {"method": "model", "requested": method, "reason": str(exc)}
    model, moved = with_pelvis_markers(model, rot, org, means)
    return model, {**info, **extra, "marker_radius_m": marker_radius_m,
                   "pelvis_markers_moved_m": moved}  # fmt: skip


def _posed_at(
    model: Any, means: Mapping[str, Array], **kw: Any
) -> tuple[Any, Array, Array, dict[str, Any]]:
    """:func:`pelvis_pose_for_hips` after the model's hips are set to the centres' width
    (:func:`with_hip_width`): the model, the pose and its summary, ``hip_width_moved_m`` (each
    hip's move outwards) added and ``width_residual_m`` that before the move."""
    _, _, first = pelvis_pose_for_hips(model, means, **kw)
    res = float(first["width_residual_m"])
    hips = _model_hips(model)
    model, step = with_hip_width(model, float(np.linalg.norm(hips["r"] - hips["l"])) + res)
    rot, org, info = pelvis_pose_for_hips(model, means, **kw)
    return model, rot, org, {**info, "width_residual_m": res, "hip_width_moved_m": step}


def place_hip_centres(
    model: Any,
    markers: ArrayLike,
    labels: tuple[str, ...] | list[str],
    *,
    method: str,
    marker_radius_m: float = 0.007,
    functional: tuple[ArrayLike, tuple[str, ...] | list[str]] | None = None,
    lab: Any = None,
) -> tuple[Any, dict[str, Any]]:
    """The model with its hips at ``method``'s centres (:func:`pelvis_pose_for_hips` on the
    mean positions of a static trial's ``markers`` (N, M, 3), m, NaN gaps), and a summary for
    the run's ``summary.json``. ``"model"``, or a static whose pelvis markers do not determine
    the regression, leaves the model as it is and the summary says why. The pelvis markers
    are moved (:func:`with_pelvis_markers`).

    ``functional`` (a functional trial's markers (N, M, 3) and labels, in the static's names)
    is chosen over ``method`` when it fits both hips (:func:`functional_hip_centres`): method
    ``functional``, the ``requested`` one and why a refused fit fell back to it in the summary.

    The leg length of ``davis`` is the lab's (``lab``, a :class:`msk.trial.Subject`: Plug-in
    Gait's ``LegLength`` per side), else the ASIS-to-malleolus marker distance of the static
    (the medial malleolus where there is one); the lab's ASIS-to-trochanter and inter-ASIS
    distances are used where it gives them (:func:`regression_hip_centres`)."""
    import warnings

    if method not in HIP_CENTRE_METHODS:
        raise ModelError(f"hip centre: unknown method {method!r} (one of {HIP_CENTRE_METHODS})")
    x = np.asarray(markers, dtype=float)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        means = {lab_: np.nanmean(x[:, i], axis=0) for i, lab_ in enumerate(labels)}
    fallback: dict[str, Any] = {}
    if functional is not None:
        try:
            centres, finfo = functional_hip_centres(means, functional[0], functional[1])
        except MissingDataError as exc:
            centres, finfo = {}, {"reason": str(exc)}
        if set(centres) == {"r", "l"}:
            try:
                rot, org, info = pelvis_pose_for_hips(
                    model, means, method="functional", centres=centres
                )
            except MissingDataError as exc:
                finfo = {**finfo, "reason": str(exc)}
            else:
                model, moved = with_pelvis_markers(model, rot, org, means)
                return model, {**info, "requested": method, "functional": finfo,
                               "pelvis_markers_moved_m": moved}  # fmt: skip
        why = finfo.get("reason") or "; ".join(
            f"{s}: {v.get('reason')}" for s, v in finfo.items()
            if isinstance(v, dict) and not v.get("fitted", True)
        )  # fmt: skip
        fallback = {"functional_refused": why, "functional": finfo}
    if method == "model":
        return model, {**no_static_hip_centre(method), **fallback}
    model, info = _place_regression(
        model, means, method=method, marker_radius_m=marker_radius_m,
        measured_legs=_leg_lengths(means), leg_source="ASIS to malleolus markers (static)",
        lab=lab,
    )  # fmt: skip
    return model, {**info, **fallback}


def motion_pelvis_landmarks(
    markers: ArrayLike, labels: tuple[str, ...] | list[str]
) -> tuple[dict[str, Array], dict[str, float], int]:
    """A task trial's pelvis landmark markers (ASIS, PSIS, sacrum; ``labels`` in the model's
    names) in the pelvis frame they define (:func:`pelvis_frame`, every frame where it is
    defined), median over frames — the rigid shape a static trial's means would give, whatever
    the pelvis does —; the leg length per side (``"R"``/``"L"``), the
    :data:`MOTION_LEG_LENGTH_PERCENTILE` th percentile of the ASIS-to-malleolus (medial, else
    lateral) marker distance over the frames; and the number of frames the pelvis frame was
    defined in.

    Raises:
        MissingDataError: no frame with both ASIS and the PSIS or sacral markers.
    """
    import warnings

    from msk.model.markersets import parse_label

    x = np.asarray(markers, dtype=float)
    labs = list(labels)
    pel: dict[str, int] = {}
    ank: dict[tuple[str, str], int] = {}
    for i, lab in enumerate(labs):
        p = parse_label(lab)
        if p.kind != "landmark":
            continue
        if p.landmark in ("asis", "psis") and p.side in ("R", "L"):
            pel.setdefault(f"{p.landmark}_{p.side.lower()}", i)
        elif p.landmark == "sacrum":
            pel.setdefault("sacrum", i)
        elif p.landmark in ("ankle_med", "ankle_lat") and p.side in ("R", "L"):
            ank.setdefault((p.side, p.landmark[-3:]), i)
    if "asis_r" not in pel or "asis_l" not in pel:
        raise MissingDataError("hip centre: the task has no pair of ASIS markers")
    ar, al = x[:, pel["asis_r"]], x[:, pel["asis_l"]]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        if "psis_r" in pel and "psis_l" in pel:
            post = 0.5 * (x[:, pel["psis_r"]] + x[:, pel["psis_l"]])
            if "sacrum" in pel:
                sac = x[:, pel["sacrum"]]
                post = np.where(np.isfinite(post).all(axis=1, keepdims=True), post, sac)
        elif "sacrum" in pel:
            post = x[:, pel["sacrum"]]
        else:
            raise MissingDataError("hip centre: the task has neither PSIS pair nor sacral marker")
        o = 0.5 * (ar + al)
        z = ar - al
        z /= np.linalg.norm(z, axis=1, keepdims=True)
        a = o - post
        xa = a - np.sum(a * z, axis=1, keepdims=True) * z
        xa /= np.linalg.norm(xa, axis=1, keepdims=True)
        rot = np.stack([xa, np.cross(z, xa), z], axis=2)  # columns x, y, z
        ok = np.isfinite(rot).all(axis=(1, 2))
        if not ok.any():
            raise MissingDataError(
                "hip centre: no frame of the task has both ASIS and the PSIS or sacral marker"
            )
        means: dict[str, Array] = {}
        for i in pel.values():
            local = np.einsum("nji,nj->ni", rot[ok], x[ok, i] - o[ok])
            med = np.nanmedian(local, axis=0)
            if np.isfinite(med).all():
                means[labs[i]] = np.asarray(med, dtype=float)
        legs: dict[str, float] = {}
        for s in ("R", "L"):
            j = ank.get((s, "med"), ank.get((s, "lat")))
            if j is None or f"asis_{s.lower()}" not in pel:
                continue
            d = np.linalg.norm(x[:, pel[f"asis_{s.lower()}"]] - x[:, j], axis=1)
            d = d[np.isfinite(d)]
            if d.size:
                legs[s] = float(np.percentile(d, MOTION_LEG_LENGTH_PERCENTILE))
    return means, legs, int(ok.sum())


def place_hip_centres_from_motion(
    model: Any,
    markers: ArrayLike,
    labels: tuple[str, ...] | list[str],
    *,
    method: str,
    marker_radius_m: float = 0.007,
    lab: Any = None,
) -> tuple[Any, dict[str, Any]]:
    """:func:`place_hip_centres` for a session without a static trial: the pelvis landmarks
    are those of the task (``markers`` (N, M, 3), m, model names; their shape in the pelvis
    frame, :func:`motion_pelvis_landmarks`), the leg length of ``davis`` the lab's, else the
    task's. The pelvis markers are moved on the model here, and the motion placement that
    follows (:func:`msk.personalise.scaling.place_markers_from_motion`) keeps them where they
    are (it moves the model markers it is told to, the feet's): a Plug-in Gait walk without a
    static thus gets Plug-in Gait's hip as a walk with a static does."""
    if method not in HIP_CENTRE_METHODS:
        raise ModelError(f"hip centre: unknown method {method!r} (one of {HIP_CENTRE_METHODS})")
    if method == "model":
        return model, no_static_hip_centre(method)
    try:
        means, legs, frames = motion_pelvis_landmarks(markers, labels)
    except MissingDataError as exc:
        return model, {"method": "model", "requested": method, "reason": str(exc)}
    # one length for both legs, the longer reading: a knee that does not straighten in the
    # task (a crouch, a flexed strike, a malleolus marker riding high) reads short, and the
    # legs of a subject differ by millimetres (PlugInC3D: 1040 / 965 mm where Plug-in Gait's
    # hips match 1040 mm on both sides)
    longest = {s: max(legs.values()) for s in ("R", "L")} if legs else {}
    model, info = _place_regression(
        model, means, method=method, marker_radius_m=marker_radius_m, measured_legs=longest,
        leg_source=f"ASIS to malleolus markers, {MOTION_LEG_LENGTH_PERCENTILE:g}th percentile "
        "over the task, the longer leg",
        lab=lab,
    )  # fmt: skip
    info["task_leg_lengths_m"] = legs
    return model, {**info, "landmarks_from": f"the task ({frames} frames; no static trial)"}


def no_static_hip_centre(method: str) -> dict[str, Any]:
    """The summary of the model's own hip centre (``method`` ``"model"``; a regression
    without a static trial: :func:`place_hip_centres_from_motion`)."""
    if method not in HIP_CENTRE_METHODS:
        raise ModelError(f"hip centre: unknown method {method!r} (one of {HIP_CENTRE_METHODS})")
    if method == "model":
        return {"method": "model", "source": "the generic model's, scaled with its pelvis"}
    return {
        "method": "model",
        "requested": method,
        "reason": "no pelvis landmarks to place the regression's hips from",
    }
