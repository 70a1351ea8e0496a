"""What a marker placement from the motion (no static trial) leaves undetermined: a profile of
the fit along each joint's gauge.

Without a static trial the offsets of the markers on a leg (clusters placed, foot markers
moved: :func:`msk.personalise.scaling.place_markers_from_motion`) are fitted together with the
poses. When
every marker distal to a joint has a free offset, rotating those offsets about the joint by δ
while the joint's coordinate moves by −δ at every frame leaves every marker where it was — for
a revolute joint exactly (R(θ + δ) R(δ)⁻¹ = R(θ)), for a joint with coupled translations (the
gait2392 knee) nearly: the mean of that coordinate over the trial is then fixed by where the
placement's passes started and stopped, not by the markers (DM's crouch: 1 nm of marker noise
moved its mean knee flexion 28.5–33.4°, docs/validation.md).

The check is the profile likelihood of the coordinate's offset (Raue A, Kreutz C, Maiwald T,
Bachmann J, Schilling M, Klingmüller U, Timmer J (2009) Structural and practical
identifiability analysis of partially observed dynamical models by exploiting the profile
likelihood. Bioinformatics 25:1923–1929: PL(θ_i) = min over the other parameters of the fit's
cost, θ_i held; a parameter whose profile stays within the cost's resolution over a range is
not determined over that range), bounded from above without re-optimising the offsets: for a
coordinate c of a joint whose child subtree S carries the free markers m ∈ S,

    p_m(δ) = T_B(θ̄ + δ e_c)⁻¹ T_B(θ̄) p_m     (T_B: the body's placement, θ̄ the median pose),

i.e. each free marker kept where it is at the median pose while c moves by δ there, and the
poses refitted to the markers with these offsets (J(δ), the placement's own cost). J(δ) is
≥ the profile's minimum at that shift (the other offsets are not re-optimised), so
J(δ) − J(0) ≤ ε shows a placement with the mean of c shifted (by the refitted poses' mean
change Δc̄) that fits the markers as well: c̄ is *not determined* by the markers to within Δc̄.
A rise above ε does not prove the converse (the offsets could compensate further); such a
coordinate is reported as "no flat direction found", never as identified. A coordinate whose
mean a stated prior sets instead of the markers (:mod:`msk.personalise.sole_level`: the ankles,
"sole level
at foot flat") keeps its profile but is reported with status "prior", not "not determined".
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from msk._runtime.fork import Forked, spare_cpu
from msk.exceptions import ModelError
from msk.model.core import Marker, Model, frame_placements
from msk.units import Array

__all__ = [
    "PELVIS_MIN_SPREAD_M",
    "PROFILE_COORDINATE_STEMS",
    "PROFILE_SHIFT_DEG",
    "CoordinateProfile",
    "PelvisDeterminacy",
    "PlacementProfile",
    "gauge_shifted_markers",
    "joint_child",
    "pelvis_determinacy",
    "placement_profile",
]

#: the least distance (m) of a fixed pelvis marker from the line through two others for the
#: three to pose the pelvis: a marker cluster's own size (a sacral marker sits ~0.1 m behind the
#: inter-ASIS line; two markers within 2 cm of one line leave a rotation about it to noise)
PELVIS_MIN_SPREAD_M = 0.02

#: shift (deg) of each profiled coordinate's mean: 5°, the error above which a kinematic gait
#: measurement "should raise concern" (McGinley JL, Baker R, Wolfe R, Morris ME (2009) The
#: reliability of three-dimensional kinematic gait measurements: a systematic review. Gait
#: Posture 29:360–369; 2–5° "reasonable", ≤ 2° "acceptable") — a mean the markers cannot tell
#: from one 5° away is not a measurement
PROFILE_SHIFT_DEG = 5.0

#: the leg coordinates profiled (gait2392 / Rajagopal stems, each side): the angles whose means
#: a report reads; the hip's three (a thigh cluster's rotation about the femur is the same kind
#: of gauge as a shank cluster's about the knee)
PROFILE_COORDINATE_STEMS = (
    "hip_flexion", "hip_adduction", "hip_rotation", "knee_angle", "ankle_angle",
)  # fmt: skip

#: a fit of the placement's frames: (model, initial poses (N, n) or None) → (poses (N, n) with
#: NaN rows where a frame is not solved, cost in m)
Fit = Callable[[Model, Array | None], tuple[Array, float]]


@dataclass(frozen=True)
class CoordinateProfile:
    """One coordinate's profile: its mean over the fitted frames (rad), and for the shifts +δ
    and −δ the refitted poses' change of that mean (rad) and the cost's change (m)."""

    coordinate: str
    mean_rad: float
    mean_change_rad: tuple[float, float]
    cost_change_m: tuple[float, float]
    free_markers: int
    fixed_markers: int

    def determined(self, tolerance_m: float) -> bool:
        """False when a shifted placement fits within ``tolerance_m`` of the fit (or better)."""
        return min(self.cost_change_m) > tolerance_m

    def summary(self, tolerance_m: float, prior: str | None = None) -> dict[str, Any]:
        """``prior``: the stated prior that sets this coordinate's mean (status "prior": the
        profile is still reported, the markers do not determine it, the prior does)."""
        if prior is not None:
            status = "prior"
        elif self.determined(tolerance_m):
            status = "no flat direction found"
        else:
            status = "not determined"
        return {
            "mean_deg": float(np.degrees(self.mean_rad)),
            "mean_change_deg": [float(np.degrees(v)) for v in self.mean_change_rad],
            "cost_change_m": [float(v) for v in self.cost_change_m],
            "free_markers": self.free_markers,
            "fixed_markers": self.fixed_markers,
            "status": status,
            **({"prior": f"set by prior: {prior}"} if prior is not None else {}),
        }


@dataclass(frozen=True)
class PelvisDeterminacy:
    """Whether the root segment's (pelvis') fixed markers pose it (:func:`pelvis_determinacy`).

    Attributes:
        body: the root segment.
        fixed: its observed markers at fixed offsets (the model's own).
        free: its observed markers placed or moved from the motion.
        spread_m: the largest distance of a fixed marker from the line through two others
            (0 with fewer than three).
        not_determined: the root joint's rotation coordinates the fixed markers leave free
            (the one about the line through two fixed markers, every one with fewer).
    """

    body: str
    fixed: tuple[str, ...]
    free: tuple[str, ...]
    spread_m: float
    not_determined: tuple[str, ...]

    def summary(self) -> dict[str, Any]:
        """``summary.json`` ``model.placement_determinacy.pelvis``."""
        return {
            "body": self.body,
            "fixed_markers": list(self.fixed),
            "free_markers": list(self.free),
            "spread_m": self.spread_m,
            "status": "not determined" if self.not_determined else "determined",
            "not_determined": list(self.not_determined),
            "method": "rank of the observed fixed-offset markers on the root segment: three, "
            f"not within {1000 * PELVIS_MIN_SPREAD_M:g} mm of one line, pose it "
            "(msk.personalise.determinacy.pelvis_determinacy)",
        }


@dataclass(frozen=True)
class PlacementProfile:
    """The profiles of a motion placement's leg coordinates (:func:`placement_profile`): the
    shift tried (rad), the cost's resolution ``tolerance_m`` (a cost change within it is one
    the placement cannot tell), the frames fitted and the unshifted cost (m)."""

    shift_rad: float
    tolerance_m: float
    frames: int
    cost_m: float
    coordinates: tuple[CoordinateProfile, ...]
    #: the root segment's check (:func:`pelvis_determinacy`), the first of the chain
    pelvis: PelvisDeterminacy | None = None

    def not_determined(
        self, priors: Mapping[str, str] | None = None
    ) -> tuple[CoordinateProfile, ...]:
        """The coordinates the markers leave free, less those a stated prior sets (``priors``:
        coordinate → the prior)."""
        return tuple(
            c for c in self.coordinates
            if not c.determined(self.tolerance_m) and c.coordinate not in (priors or {})
        )  # fmt: skip

    def summary(self, priors: Mapping[str, str] | None = None) -> dict[str, Any]:
        """``summary.json`` ``model.placement_determinacy``; ``priors``: coordinate → the stated
        prior that sets its mean (status "prior", not "not determined")."""
        priors = dict(priors or {})
        return {
            "method": "profile of the placement's task IK cost along each joint's gauge "
            "(msk.personalise.determinacy): the free marker offsets distal to the joint kept "
            "in place at "
            "the median pose with the coordinate shifted by ±shift_deg, the frames refitted; "
            "a cost change ≤ tolerance_m: the coordinate's mean is not determined by the "
            "markers (no static trial)",
            "shift_deg": float(np.degrees(self.shift_rad)),
            "tolerance_m": self.tolerance_m,
            "frames": self.frames,
            "cost_m": self.cost_m,
            "coordinates": {
                c.coordinate: c.summary(self.tolerance_m, priors.get(c.coordinate))
                for c in self.coordinates
            },
            "not_determined": [c.coordinate for c in self.not_determined(priors)],
            "set_by_prior": {k: f"set by prior: {v}" for k, v in priors.items()},
            **({"pelvis": self.pelvis.summary()} if self.pelvis is not None else {}),
        }


def pelvis_determinacy(
    model: Model,
    free: Sequence[str],
    observed: Sequence[str],
    *,
    min_spread_m: float = PELVIS_MIN_SPREAD_M,
) -> PelvisDeterminacy:
    """What the root segment's markers leave free (module docstring): its observed markers not
    in ``free`` are fixed; with three not collinear (a distance ≥ ``min_spread_m`` from the
    line through two others) nothing; with two, the root joint's rotation coordinate whose axis
    is closest to the line through them; with fewer, every rotation coordinate of the root
    joint.

    Raises:
        ModelError: the model has no joint from the ground.
    """
    root = next((j for j in model.joints if j.parent in ("ground", "world", "universe")), None)
    if root is None:
        raise ModelError(f"model {model.name!r}: no joint from the ground to a root segment")
    seen, loose = set(observed), set(free)
    on = [mk for mk in model.markers if mk.body == root.child and mk.name in seen]
    fixed = [mk for mk in on if mk.name not in loose]
    rots = [(a.coordinate, np.asarray(a.axis, dtype=float)) for a in root.axes
            if a.kind == "revolute" and a.coordinate is not None]  # fmt: skip
    spread = 0.0
    line: Array | None = None
    pts = [np.asarray(mk.offset, dtype=float) for mk in fixed]
    for i in range(len(pts)):
        for k in range(i + 1, len(pts)):
            d = pts[k] - pts[i]
            n = float(np.linalg.norm(d))
            if n < 1e-9:
                continue
            if line is None:
                line = d / n
            for m, p in enumerate(pts):
                if m not in (i, k):
                    v = p - pts[i]
                    spread = max(spread, float(np.linalg.norm(v - np.dot(v, d / n) * d / n)))
    if spread >= min_spread_m:
        undetermined: tuple[str, ...] = ()
    elif line is not None and rots:
        # the joint axes are in the parent's frame; the root's rotations are about the
        # segment's own axes at its neutral (gait2392: tilt z, list x, rotation y)
        best = max(rots, key=lambda r: abs(float(np.dot(r[1], line))) / np.linalg.norm(r[1]))
        undetermined = (str(best[0]),)
    else:
        undetermined = tuple(str(c) for c, _ in rots)
    return PelvisDeterminacy(
        root.child, tuple(mk.name for mk in fixed),
        tuple(mk.name for mk in on if mk.name in loose), spread, undetermined,
    )  # fmt: skip


def joint_child(model: Model, coordinate: str) -> str:
    """The child body of the joint a revolute axis of which ``coordinate`` drives."""
    for j in model.joints:
        if any(ax.coordinate == coordinate and ax.kind == "revolute" for ax in j.axes):
            return j.child
    raise ModelError(f"model {model.name!r}: no revolute joint axis drives {coordinate!r}")


def gauge_shifted_markers(
    model: Model, coordinate: str, shift_rad: float, pose: Array, free: Sequence[str]
) -> Model:
    """``model`` whose ``free`` markers on the bodies distal to ``coordinate``'s joint are
    re-expressed so that at ``pose`` with ``coordinate`` + ``shift_rad`` they sit where they
    sat at ``pose``: p' = T_B(θ̄ + δ e_c)⁻¹ T_B(θ̄) p (the module docstring's gauge move)."""
    sub = set(model.subtree(joint_child(model, coordinate)))
    free_set = set(free)
    moving = [mk for mk in model.markers if mk.body in sub and mk.name in free_set]
    if not moving:
        return model
    bodies = sorted({mk.body for mk in moving})
    ids = [model.body_frame[b] for b in bodies]
    shifted = np.array(pose, dtype=float)
    shifted[model.coordinate_index(coordinate)] += shift_rad
    r0, p0 = frame_placements(model, np.asarray(pose, dtype=float)[None], ids)
    r1, p1 = frame_placements(model, shifted[None], ids)
    out = []
    for mk in model.markers:
        if mk.body in sub and mk.name in free_set:
            k = bodies.index(mk.body)
            world = r0[0, k] @ mk.offset + p0[0, k]
            out.append(Marker(mk.name, mk.body, r1[0, k].T @ (world - p1[0, k])))
        else:
            out.append(mk)
    return model.with_markers(out)


def placement_profile(
    model: Model,
    fit: Fit,
    free: Sequence[str],
    observed: Sequence[str],
    *,
    tolerance_m: float,
    shift_deg: float = PROFILE_SHIFT_DEG,
    stems: Sequence[str] = PROFILE_COORDINATE_STEMS,
) -> PlacementProfile:
    """The profile (module docstring) of each coordinate of ``model`` named ``<stem>``,
    ``<stem>_r`` or ``<stem>_l`` (``stems``) at ±``shift_deg``: ``fit`` the placement's frames
    with ``model`` (the reference poses; θ̄ their median), then with the ``free`` markers
    (placed or moved from the motion) distal to the coordinate's joint gauge-shifted,
    warm-started at the reference poses with the coordinate shifted. ``observed``: the
    markers the trial has (a model marker it lacks observes nothing; counted neither free nor
    fixed). A coordinate without a marker distal to its joint is left out."""
    q_ref, cost0 = fit(model, None)
    q_ref = np.asarray(q_ref, dtype=float)
    ok = np.isfinite(q_ref).all(axis=1)
    if not ok.any() or not np.isfinite(cost0):
        raise ModelError(f"model {model.name!r}: the placement's frames could not be fitted")
    pose = np.median(q_ref[ok], axis=0)
    delta = float(np.radians(shift_deg))
    seen = set(observed)
    body_of: Mapping[str, str] = {mk.name: mk.body for mk in model.markers if mk.name in seen}
    wanted = set(stems)
    profiled: list[tuple[str, int, list[str]]] = []  # (coordinate, index, distal markers)
    for coord in model.coordinate_names:
        if (coord[:-2] if coord.endswith(("_r", "_l")) else coord) not in wanted:
            continue
        ci = model.coordinate_index(coord)
        sub = set(model.subtree(joint_child(model, coord)))
        distal = [m for m, b in body_of.items() if b in sub]
        if distal:
            profiled.append((coord, ci, distal))

    def shifted_fit(job: tuple[str, int, float]) -> tuple[float, float]:
        # (the refitted poses' change of the coordinate's mean, the cost's change)
        coord, ci, sign = job
        mean0 = float(np.mean(q_ref[ok, ci]))
        shifted = gauge_shifted_markers(model, coord, sign * delta, pose, free)
        start = q_ref.copy()
        start[:, ci] += sign * delta
        q, cost = fit(shifted, np.where(np.isfinite(start), start, 0.0))
        q = np.asarray(q, dtype=float)
        good = np.isfinite(q).all(axis=1)
        change = float(np.mean(q[good, ci])) - mean0 if good.any() else float("nan")
        return change, float(cost) - float(cost0)

    def fits(jobs: Sequence[tuple[str, int, float]]) -> list[tuple[float, float]]:
        return [shifted_fit(j) for j in jobs]

    # the fits are independent: the second half in a forked child on a second CPU when there
    # is one (msk._runtime.fork: the same code on the same data, the same numbers)
    jobs = [(coord, ci, sign) for coord, ci, _ in profiled for sign in (1.0, -1.0)]
    half = len(jobs) // 2
    if half and spare_cpu():
        child = Forked(fits, jobs[half:])
        got = fits(jobs[:half]) + child.result()
    else:
        got = fits(jobs)
    out = []
    free_set = set(free)
    for k, (coord, ci, distal) in enumerate(profiled):
        (c_plus, j_plus), (c_minus, j_minus) = got[2 * k], got[2 * k + 1]
        n_free = sum(m in free_set for m in distal)
        out.append(
            CoordinateProfile(
                coord, float(np.mean(q_ref[ok, ci])), (c_plus, c_minus), (j_plus, j_minus),
                n_free, len(distal) - n_free,
            )
        )  # fmt: skip
    return PlacementProfile(delta, float(tolerance_m), int(ok.sum()), float(cost0), tuple(out))
