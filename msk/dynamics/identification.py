"""Subject-specific segment inertial parameters from motion capture and force plates.

Identification of the standard inertial parameters φ (10 per segment,
:data:`msk.model.core.INERTIAL_PARAMETER_NAMES`) from the **base-link equations** of the floating
base (Hayashibe et al. 2011, §II, Eq. 1–4), which need no joint torque::

    Y_root(θ, θ̇, θ̈) φ = τ_ext,root          (Hayashibe et al. 2011, Eq. 2, upper rows)

stacked over the frames of one or more exciting trials. τ_ext,root are the generalised forces of
the measured external wrenches on the pelvis coordinates (:func:`root_generalized_forces`).

Estimator (:class:`InertialIdentifier`)
    Maximum a posteriori estimate under a Gaussian prior φ ~ N(φ_prior, Σ_p) (generic
    anthropometric values, e.g. :func:`msk.model.anthropometry.generic_segments` placed on the
    model,
    or the model's own inertias) and Gaussian equation noise of standard deviation σ_k per
    base-link row k (force rows in N, moment rows in N·m; estimated from the residuals unless
    given)::

        min_φ  Σ_n Σ_k ((Y_k(n) φ − τ_k(n)) / σ_k)²  +  ‖Σ_p^{-1/2} (φ − φ_prior)‖²

    subject to physical consistency of every segment, J(φ_b) ⪰ ε (the 4×4 pseudo-inertia,
    :func:`msk.model.anthropometry.pseudo_inertia`; Wensing, Kim & Slotine 2017), the
    density-realisability condition tr(Q_b J(φ_b)) ≥ 0 for a bounding ellipsoid Q_b of the
    segment (Hayashibe et al. 2011, ref. [9]), optionally Σ m_b = M (known total mass), left/right
    symmetry (φ_l = S φ_r with the mirror z → −z) and segments held at the prior. The variables are
    scaled by the prior standard deviations (well-conditioned: the prior term is ‖x − x_prior‖²)
    and the rows by σ_k. Directions of φ that the motion does not excite carry no data
    information and stay at the prior instead of drifting. The problem is a convex QP with 4×4
    PSD cones, solved with Clarabel (default); ``solver="ipopt"`` solves the same problem over the
    log-Cholesky parametrisation J = U Uᵀ (Rucker & Wensing 2022) with casadi/ipopt.

Uncertainty and identifiability
    Base parameters (:func:`msk.dynamics.regressors.base_parameters`, structural, from random
    states),
    their data-only standard deviations σ (Y_bᵀ W² Y_b)^{-1}, the condition number of the stacked
    column-normalised base regressor, the posterior covariance (H + Σ_p^{-1})^{-1} of φ
    (constraints inactive; includes the prior) and a per-segment flag, the colour coding of
    Hayashibe et al. 2011, Fig. 3:

    - ``"well identified"``: posterior std of the mass ≤ :data:`WELL_IDENTIFIED_MASS_REL_STD`
      relative and of each COM coordinate ≤ :data:`WELL_IDENTIFIED_COM_STD_M`;
    - ``"prior"``: the data reduce neither the mass std nor any COM-coordinate std below
      :data:`PRIOR_STD_RATIO` × their prior std (the estimate is essentially the prior) — or the
      segment is held fixed;
    - ``"weakly identified"``: otherwise.

    ``weak_directions_`` lists the least excited parameter combinations (eigenvectors of the
    scaled data information matrix whose data std exceeds the prior std) in parameter names.

Identification model (:func:`lump_subtrees`)
    As in Hayashibe et al. 2011, §VI-B, the upper body (torso, head, arms) is identified as one
    link: its subtree is lumped rigidly at a reference pose into one body;
    :meth:`LumpedModel.redistribute` spreads the identified lump back over the musculoskeletal
    sub-links proportionally to their generic masses while matching the lump's mass, first moment
    and inertia (limbs are copied).
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from msk._runtime.fork import spare_cpu
from msk.dynamics.regressors import (
    BaseParameters,
    RegressorLayout,
    base_link_regressor,
    base_parameters,
    parameter_transform,
    regressor_layout,
    root_coordinate_indices,
    spatial_kinematics,
)
from msk.exceptions import IdentificationError, ModelError, OptimizationError
from msk.model.core import (
    INERTIAL_PARAMETER_NAMES,
    Body,
    Joint,
    Marker,
    Model,
    forward_kinematics,
)
from msk.units import Array

__all__ = [
    "DEFAULT_CV_GRID",
    "FLAGS",
    "MIRROR_SIGNS",
    "PRIOR_STD_RATIO",
    "WELL_IDENTIFIED_COM_STD_M",
    "WELL_IDENTIFIED_MASS_REL_STD",
    "BaseResiduals",
    "BoundingEllipsoid",
    "CrossValidation",
    "ExcitationReport",
    "IdentificationTrial",
    "InertialIdentifier",
    "LumpedModel",
    "MassIdentification",
    "SegmentEstimate",
    "SegmentExcitation",
    "WeakDirection",
    "applied_segments",
    "base_residuals",
    "default_prior_std",
    "excitation_report",
    "identified_model",
    "lump_subtrees",
    "root_generalized_forces",
    "segment_summary",
]

#: Sign pattern of the sagittal mirror z → −z on φ (flips m·c_z, I_xz and I_yz).
MIRROR_SIGNS: Array = np.array([1.0, 1.0, 1.0, -1.0, 1.0, 1.0, 1.0, -1.0, -1.0, 1.0])
#: Posterior relative std of the mass at or below which a segment is "well identified".
WELL_IDENTIFIED_MASS_REL_STD = 0.02
#: Posterior std (m) of every COM coordinate at or below which a segment is "well identified".
WELL_IDENTIFIED_COM_STD_M = 0.004
#: A segment whose posterior/prior std ratios (mass and every COM coordinate) all exceed this is
#: flagged "prior": the data barely inform it.
PRIOR_STD_RATIO = 0.7
FLAGS: tuple[str, ...] = ("well identified", "weakly identified", "prior")
#: Candidate prior weights λ of ``prior_weight="cv"`` (prior only, λ = ∞, is always added).
DEFAULT_CV_GRID: tuple[float, ...] = tuple(float(10.0**e) for e in range(-3, 5))

_PSD_N = 10  # entries of a 4×4 symmetric matrix in svec form


# ------------------------------------------------------------------------------------------
# external generalised forces on the root from world wrenches (vectorised)
# ------------------------------------------------------------------------------------------
def root_generalized_forces(
    model: Model, theta: ArrayLike, force_world: ArrayLike, moment_world: ArrayLike
) -> Array:
    """τ_ext,root (N, n_root) = Gᵀ S_rootᵀ [f; n] of the total external wrench.

    ``force_world`` (N, 3) is the sum of the external forces (N) and ``moment_world`` (N, 3) the
    sum of their moments about the **world origin** (N·m), e.g. ``ExternalLoads.total()``. Every
    body descends from the root chain, so the wrench acts on all root DOFs whatever body it is
    applied to. Columns follow :func:`msk.dynamics.regressors.root_coordinate_indices`.
    """
    th = np.atleast_2d(np.asarray(theta, dtype=float))
    f = np.asarray(force_world, dtype=float).reshape(-1, 3)
    n_w = np.asarray(moment_world, dtype=float).reshape(-1, 3)
    if f.shape[0] != th.shape[0] or n_w.shape[0] != th.shape[0]:
        raise IdentificationError(
            f"wrench has {f.shape[0]}/{n_w.shape[0]} frames but θ has {th.shape[0]}"
        )
    root = root_coordinate_indices(model)
    out = np.zeros((th.shape[0], root.size))
    # frame by frame maths, in blocks: the (N, n_dof, n_coords) coupling Jacobian and the
    # per-joint motion subspaces of a long trial are never held whole
    for c0 in range(0, th.shape[0], REGRESSOR_BLOCK):
        sl = slice(c0, c0 + REGRESSOR_BLOCK)
        out[sl] = _root_forces_block(model, root, th[sl], f[sl], n_w[sl])
    return out


def _root_forces_block(model: Model, root: NDArray[Any], th: Array, f: Array, n_w: Array) -> Array:
    """:func:`root_generalized_forces` of a block of frames."""
    q = model.coupling.q(th)
    zero = np.zeros_like(q)
    kin = spatial_kinematics(model, q, zero, zero)
    g = model.coupling.jacobian(th)
    pm = model.pin_model
    wrench = np.concatenate([f, n_w], axis=1)
    out = np.zeros((th.shape[0], root.size))
    coord_of_dof = np.asarray(model.coupling.coordinate)
    for j in range(1, pm.njoints):
        k = pm.joints[j].idx_v
        i = coord_of_dof[k]
        if i < 0 or i not in root:
            continue
        r = int(np.flatnonzero(root == i)[0])
        out[:, r] += g[:, k, i] * np.einsum("ni,ni->n", kin.subspace[j], wrench)
    return out


# ------------------------------------------------------------------------------------------
# trials
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class IdentificationTrial:
    """One trial for identification: θ, θ̇, θ̈ (N, n_coords) of the identification model and the
    external generalised forces on the root coordinates ``tau_ext`` (N, n_root) — or (N,
    n_coords), of which the root columns are used."""

    theta: Array
    theta_dot: Array
    theta_ddot: Array
    tau_ext: Array
    name: str = ""

    def __post_init__(self) -> None:
        arrays = {}
        for key in ("theta", "theta_dot", "theta_ddot", "tau_ext"):
            a = np.atleast_2d(np.asarray(getattr(self, key), dtype=float))
            arrays[key] = a
            object.__setattr__(self, key, a)
        shapes = {k: a.shape for k, a in arrays.items()}
        n = arrays["theta"].shape[0]
        if not (arrays["theta"].shape == arrays["theta_dot"].shape == arrays["theta_ddot"].shape):
            raise IdentificationError(f"trial {self.name!r}: θ, θ̇, θ̈ shapes differ: {shapes}")
        if arrays["tau_ext"].shape[0] != n:
            raise IdentificationError(
                f"trial {self.name!r}: τ_ext has {arrays['tau_ext'].shape[0]} frames, θ has {n}"
            )

    @property
    def n_frames(self) -> int:
        return int(self.theta.shape[0])

    @staticmethod
    def from_loads(
        model: Model, kinematics: Any, loads: Any, *, name: str = ""
    ) -> IdentificationTrial:
        """From :class:`msk.kinematics.ik.Kinematics` (``q, v, a``) and
        :class:`msk.dynamics.loads.ExternalLoads` (``total()``: world force and moment about the
        origin)
        on the same time base."""
        force, moment = loads.total()
        th = np.asarray(kinematics.q, dtype=float)
        good = np.isfinite(th).all(axis=1) & np.isfinite(force).all(axis=1)
        good &= np.isfinite(moment).all(axis=1)
        tau = np.full((th.shape[0], root_coordinate_indices(model).size), np.nan)
        if good.any():
            tau[good] = root_generalized_forces(model, th[good], force[good], moment[good])
        return IdentificationTrial(th, kinematics.v, kinematics.a, tau, name=name)


def _as_trials(
    trials: IdentificationTrial | Sequence[IdentificationTrial],
) -> list[IdentificationTrial]:
    if isinstance(trials, IdentificationTrial):
        return [trials]
    out = list(trials)
    if not out or not all(isinstance(t, IdentificationTrial) for t in out):
        raise IdentificationError("give one IdentificationTrial or a non-empty sequence of them")
    return out


def _trial_arrays(model: Model, trial: IdentificationTrial) -> tuple[Array, Array, Array, Array]:
    """θ, θ̇, θ̈, τ_root of the finite frames of a trial, checked against the model."""
    root = root_coordinate_indices(model)
    if trial.theta.shape[1] != model.n_coords:
        raise IdentificationError(
            f"trial {trial.name!r}: θ has {trial.theta.shape[1]} columns, model {model.name!r} "
            f"has {model.n_coords} coordinates"
        )
    tau = trial.tau_ext
    if tau.shape[1] == model.n_coords and tau.shape[1] != root.size:
        tau = tau[:, root]
    if tau.shape[1] != root.size:
        raise IdentificationError(
            f"trial {trial.name!r}: τ_ext has {tau.shape[1]} columns; expected {root.size} root "
            f"rows or {model.n_coords} coordinates"
        )
    good = np.isfinite(trial.theta).all(1) & np.isfinite(trial.theta_dot).all(1)
    good &= np.isfinite(trial.theta_ddot).all(1) & np.isfinite(tau).all(1)
    if good.all():  # no copy of a long trial's arrays
        return trial.theta, trial.theta_dot, trial.theta_ddot, tau
    return trial.theta[good], trial.theta_dot[good], trial.theta_ddot[good], tau[good]


# ------------------------------------------------------------------------------------------
# pseudo-inertia algebra (linear maps on φ)
# ------------------------------------------------------------------------------------------
def _pseudo_inertia_map() -> Array:
    """K (16, 10): vec(J(φ)) = K φ (row-major 4×4)."""
    from msk.model.anthropometry import pseudo_inertia

    return np.stack([pseudo_inertia(e).reshape(16) for e in np.eye(10)], axis=1)


_JMAP = _pseudo_inertia_map()
_SVEC_IDX = [(i, j) for j in range(4) for i in range(j + 1)]
_SVEC_SCALE = np.array([1.0 if i == j else math.sqrt(2.0) for i, j in _SVEC_IDX])


def _svec_rows(t: Array) -> Array:
    """L (10, 10): svec(T J(φ) T) = L φ for T = diag(t) (Clarabel's PSD triangle order)."""
    rows = np.array([4 * i + j for i, j in _SVEC_IDX])
    scale = np.array([t[i] * t[j] for i, j in _SVEC_IDX]) * _SVEC_SCALE
    return _JMAP[rows] * scale[:, None]


def _phi_from_pseudo(jm: Any) -> list[Any]:
    """φ from a pseudo-inertia J (works on numpy and casadi 4×4): Ī = tr(Σ) 1 − Σ."""
    s = [[jm[i, j] for j in range(3)] for i in range(3)]
    tr = s[0][0] + s[1][1] + s[2][2]
    return [
        jm[3, 3], jm[0, 3], jm[1, 3], jm[2, 3],
        tr - s[0][0], -s[0][1], tr - s[1][1], -s[0][2], -s[1][2], tr - s[2][2],
    ]  # fmt: skip


@dataclass(frozen=True)
class BoundingEllipsoid:
    """A segment-fixed ellipsoid {x : ‖diag(1/semi_axes) Rᵀ (x − center)‖ ≤ 1} (body frame, m)
    that must contain the segment's mass (density realisability, Hayashibe et al. 2011, ref.
    [9])."""

    center: Array
    semi_axes: Array
    rotation: Array = field(default_factory=lambda: np.eye(3))

    def q_matrix(self) -> Array:
        """Q (4×4) with [x;1]ᵀ Q [x;1] = 1 − ‖…‖² ≥ 0 inside; the condition is tr(Q J) ≥ 0."""
        c = np.asarray(self.center, dtype=float)
        r = np.asarray(self.rotation, dtype=float)
        a = np.asarray(self.semi_axes, dtype=float)
        if np.any(a <= 0):
            raise IdentificationError(f"bounding ellipsoid semi-axes must be > 0, got {a}")
        s_inv = r @ np.diag(1.0 / a**2) @ r.T
        q = np.empty((4, 4))
        q[:3, :3] = -s_inv
        q[:3, 3] = q[3, :3] = s_inv @ c
        q[3, 3] = 1.0 - c @ s_inv @ c
        return q

    @staticmethod
    def from_parameters(phi: ArrayLike, *, scale: float = 2.0) -> BoundingEllipsoid:
        """The uniform solid ellipsoid with the same COM and central second moments as φ
        (semi-axes √(5 λ_i(Σ_c)/m)), enlarged ``scale`` times."""
        from msk.model.anthropometry import pseudo_inertia

        p = np.asarray(phi, dtype=float)
        jm = pseudo_inertia(p)
        m = p[0]
        c = p[1:4] / m
        sig = jm[:3, :3] / m - np.outer(c, c)
        lam, vec = np.linalg.eigh(0.5 * (sig + sig.T))
        floor = 1e-3 * max(lam.max(), 1e-8)
        return BoundingEllipsoid(c, scale * np.sqrt(5.0 * np.maximum(lam, floor)), vec)


def default_prior_std(
    phi: ArrayLike,
    *,
    mass_rel_std: float = 0.3,
    com_std_m: float = 0.03,
    inertia_rel_std: float = 0.5,
) -> Array:
    """Diagonal prior standard deviations of φ (10,) around a generic value.

    σ_m = r_m m; σ_{mc_i} = √((m σ_c)² + (c_i σ_m)²); σ of the inertia entries (about the body
    origin) = r_I · max(Ī_ii) on the diagonal and half that off the diagonal.
    """
    p = np.asarray(phi, dtype=float)
    m = max(p[0], 1e-6)
    c = p[1:4] / m
    sm = mass_rel_std * m
    sh = np.sqrt((m * com_std_m) ** 2 + (c * sm) ** 2)
    i_scale = max(p[4], p[6], p[9], 1e-9 * m)
    si = inertia_rel_std * i_scale * np.array([1.0, 0.5, 1.0, 0.5, 0.5, 1.0])
    return np.concatenate([[sm], sh, si])


# ------------------------------------------------------------------------------------------
# results
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SegmentEstimate:
    """Identified mass (kg) and COM (m, body frame) of one segment with posterior std."""

    name: str
    mass: float
    mass_std: float
    com: Array
    com_std: Array
    prior_mass: float
    prior_com: Array
    flag: str


@dataclass(frozen=True)
class WeakDirection:
    """A poorly excited combination of parameters: ``std_ratio`` = data std / prior std along the
    direction (> 1: the prior dominates), ``components`` the largest (name, coefficient) pairs of
    the unit direction in prior-scaled parameters."""

    std_ratio: float
    components: tuple[tuple[str, float], ...]


@dataclass(frozen=True)
class BaseResiduals:
    """RMS of the base-link residuals Y_root φ − τ_ext,root over the frames of some trials.

    ``rms`` (n_root,) per root coordinate (``names``); ``force_rms_n`` and ``moment_rms_nm`` pool
    the translational and rotational coordinates (per component)."""

    rms: Array
    names: tuple[str, ...]
    force_rms_n: float
    moment_rms_nm: float
    n_frames: int


def _pool_rms(rms: Array, mask: NDArray[np.bool_]) -> float:
    """RMS pooled over the rows of ``mask`` (per component); nan when none."""
    return float(np.sqrt(np.mean(rms[mask] ** 2))) if mask.any() else math.nan


def _pool(model: Model, sq_sum: Array, n: int) -> BaseResiduals:
    root = root_coordinate_indices(model)
    kinds = np.array([model.coordinates[i].kind == "translational" for i in root])
    rms = np.sqrt(sq_sum / max(n, 1))
    f = float(np.sqrt(np.mean(rms[kinds] ** 2))) if kinds.any() else math.nan
    m = float(np.sqrt(np.mean(rms[~kinds] ** 2))) if (~kinds).any() else math.nan
    names = tuple(model.coordinates[i].name for i in root)
    return BaseResiduals(rms, names, f, m, n)


def base_residuals(
    model: Model,
    trials: IdentificationTrial | Sequence[IdentificationTrial],
    parameters: Mapping[str, ArrayLike] | None = None,
) -> BaseResiduals:
    """Pelvis (base-link) residual RMS of ``model`` — with its own inertias or with
    ``parameters`` (φ per body) — on trials: the misfit of Hayashibe et al. 2011, Eq. 2 Y_root φ −
    τ_ext,root."""
    layout = regressor_layout(model)
    phi = layout.parameters(model)
    for b, name in enumerate(layout.body_names):
        if parameters is not None and name in parameters:
            phi[10 * b : 10 * b + 10] = np.asarray(parameters[name], dtype=float)
    sq = np.zeros(root_coordinate_indices(model).size)
    n = 0
    for trial in _as_trials(trials):
        th, thd, thdd, tau = _trial_arrays(model, trial)
        y = base_link_regressor(model, th, thd, thdd, layout=layout)
        sq += np.sum((y @ phi - tau) ** 2, axis=0)
        n += th.shape[0]
    return _pool(model, sq, n)


# ------------------------------------------------------------------------------------------
# the identification model: lumping subtrees
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class LumpedModel:
    """An identification model made from a musculoskeletal model by lumping subtrees.

    Attributes:
        model: the identification model (each lumped subtree is one body, named after its root).
        source: the musculoskeletal model it was made from.
        members: lump body → the source bodies it contains (root first).
        placements: source body → its frame in the lump-root frame at the reference pose.
        coordinate_index: for each identification coordinate, its index in ``source``.
        theta_ref: the source reference pose (the removed coordinates are frozen there).
    """

    model: Model
    source: Model
    members: dict[str, tuple[str, ...]]
    placements: dict[str, pin.SE3]
    coordinate_index: NDArray[np.int64]
    theta_ref: Array

    def restrict(self, theta: ArrayLike) -> Array:
        """Source coordinates (…, n_source) → identification coordinates (…, n_id)."""
        th = np.asarray(theta, dtype=float)
        return th[..., self.coordinate_index]

    def expand(self, theta: ArrayLike) -> Array:
        """Identification coordinates → source coordinates (removed ones at ``theta_ref``)."""
        th = np.atleast_2d(np.asarray(theta, dtype=float))
        out = np.tile(self.theta_ref, (th.shape[0], 1))
        out[:, self.coordinate_index] = th
        return out

    def restrict_trial(self, trial: IdentificationTrial) -> IdentificationTrial:
        """A trial of the source model as a trial of the identification model."""
        tau = trial.tau_ext
        if tau.shape[1] == self.source.n_coords:
            tau = tau[:, root_coordinate_indices(self.source)]
        return IdentificationTrial(
            self.restrict(trial.theta),
            self.restrict(trial.theta_dot),
            self.restrict(trial.theta_ddot),
            tau,
            name=trial.name,
        )

    def lumped_parameters(self, model: Model | None = None) -> dict[str, Array]:
        """φ of every lump (in its root frame) from the bodies of ``model`` (default source)."""
        src = model or self.source
        out = {}
        for lump, members in self.members.items():
            out[lump] = sum(
                (
                    parameter_transform(self.placements[b]) @ src.body(b).parameters()
                    for b in members
                ),
                start=np.zeros(10),
            )
        return out

    def redistribute(
        self, parameters: Mapping[str, ArrayLike], *, generic: Model | None = None
    ) -> Model:
        """The source model with identified inertias (Hayashibe et al. 2011, §VI-B).

        Bodies that are not lumps are copied. A lump's identified φ_L is split over its members
        i: masses m_i = m_i^g · m_L / Σ m^g (proportional to the generic masses of ``generic``,
        default the source), and the first moments and inertias minimise
        Σ_i ‖(φ_i − s φ_i^g)/σ_i‖² + w ‖(Σ_i A_i φ_i − φ_L)/σ_L‖² with every J(φ_i) ⪰ 0
        (A_i: rigid placement of member i in the lump frame, s = m_L / Σ m^g, w = 10⁴), so the
        lump's total mass is exact and its COM and inertia are matched as closely as physical
        consistency of the members allows.
        """
        gen = generic or self.source
        out: dict[str, Array] = {}
        for name, phi in parameters.items():
            if name not in self.members and np.asarray(phi, dtype=float)[0] > 1e-12:
                out[name] = np.asarray(phi, dtype=float)  # massless bodies are left unchanged
        for lump, members in self.members.items():
            if lump not in parameters:
                continue
            phi_l = np.asarray(parameters[lump], dtype=float)
            if len(members) == 1:
                out[lump] = phi_l
                continue
            out.update(_split_lump(phi_l, [gen.body(b).parameters() for b in members],
                                   [parameter_transform(self.placements[b]) for b in members],
                                   members))  # fmt: skip
        return self.source.with_inertias(out)


def lump_subtrees(
    model: Model,
    roots: Sequence[str],
    *,
    theta_ref: ArrayLike | None = None,
    name: str | None = None,
) -> LumpedModel:
    """Identification model: each body in ``roots`` absorbs its whole subtree, rigidly at the
    reference pose ``theta_ref`` (default the coordinates' defaults).

    The lump's φ is Σ_i A(ʳX_i) φ_i (:func:`msk.dynamics.regressors.parameter_transform`); joints
    inside
    the lumps are removed, coordinates driving only removed joints are dropped and markers on
    absorbed bodies move to the lump body. Muscles are not kept.
    """
    th_ref = model.default_coordinates() if theta_ref is None else np.asarray(theta_ref, float)
    if th_ref.shape != (model.n_coords,):
        raise ModelError(f"theta_ref must have {model.n_coords} values, got {th_ref.shape}")
    data = model.create_data()
    forward_kinematics(model, data, th_ref)
    members: dict[str, tuple[str, ...]] = {}
    placements: dict[str, pin.SE3] = {}
    absorbed: set[str] = set()
    for root in roots:
        model.body(root)
        if root in absorbed or root in members:
            raise ModelError(f"lump root {root!r} is already inside another lump")
        sub = model.subtree(root)
        if absorbed & set(sub):
            raise ModelError(f"lumps overlap: {sorted(absorbed & set(sub))}")
        members[root] = tuple(sub)
        absorbed |= set(sub[1:])
        o_root = data.oMf[model.body_frame[root]]
        for bname in sub:
            placements[bname] = o_root.actInv(data.oMf[model.body_frame[bname]])
    bodies: list[Body] = []
    for b in model.bodies:
        if b.name in absorbed:
            continue
        if b.name in members:
            phi = sum(
                (
                    parameter_transform(placements[m]) @ model.body(m).parameters()
                    for m in members[b.name]
                ),
                start=np.zeros(10),
            )
            bodies.append(Body.from_parameters(b.name, phi))
        else:
            bodies.append(b)
    joints: list[Joint] = [j for j in model.joints if j.child not in absorbed]
    used = {ax.coordinate for j in joints for ax in j.axes if ax.coordinate is not None}
    coord_index = np.array([i for i, c in enumerate(model.coordinates) if c.name in used], int)
    owner = {m: lump for lump, ms in members.items() for m in ms}
    markers: list[Marker] = []
    for mk in model.markers:
        if mk.body in absorbed:
            offset = placements[mk.body].act(mk.offset)
            markers.append(Marker(mk.name, owner[mk.body], offset))
        else:
            markers.append(mk)
    ident = Model(
        name=name or f"{model.name}_identification",
        bodies=bodies,
        joints=joints,
        coordinates=[model.coordinates[i] for i in coord_index],
        markers=markers,
        gravity=model.gravity,
        metadata={**model.metadata, "lumped": {k: list(v) for k, v in members.items()}},
    )
    return LumpedModel(ident, model, members, placements, coord_index, th_ref)


def _split_lump(
    phi_l: Array, generic: list[Array], transforms: list[Array], names: Sequence[str]
) -> dict[str, Array]:
    import clarabel

    massive = [i for i, g in enumerate(generic) if g[0] > 1e-9]
    if len(massive) < len(generic):  # massless members (virtual bodies) are left unchanged
        out: dict[str, Array] = {}
        if massive:
            out.update(
                _split_lump(
                    phi_l,
                    [generic[i] for i in massive],
                    [transforms[i] for i in massive],
                    [names[i] for i in massive],
                )
            )
        return out
    m_gen = np.array([g[0] for g in generic])
    if phi_l[0] <= 0 or m_gen.sum() <= 0:
        raise IdentificationError(f"lump {names[0]!r}: mass must be > 0 to redistribute")
    s = phi_l[0] / m_gen.sum()
    n = len(generic)
    # variables: φ_i scaled by σ_i (prior-like scales of the generic members)
    sig = [default_prior_std(g) for g in generic]
    sig_l = default_prior_std(phi_l)
    x0 = np.concatenate([s * g / d for g, d in zip(generic, sig)])
    a_sum = np.hstack([(t * d[None, :]) / sig_l[:, None] for t, d in zip(transforms, sig)])
    w = 1e4
    hess = np.eye(10 * n) + w * a_sum.T @ a_sum
    lin = x0 + w * a_sum.T @ (phi_l / sig_l)
    a_rows, b_rows, cones = [], [], []
    eq = np.zeros((n, 10 * n))
    for i in range(n):
        eq[i, 10 * i] = sig[i][0]
    a_rows.append(eq)  # A x + s = b with s = 0: the member masses
    b_rows.append(s * m_gen)
    cones.append(clarabel.ZeroConeT(n))
    for i in range(n):
        t = _pseudo_scaling(generic[i])
        block = np.zeros((_PSD_N, 10 * n))
        block[:, 10 * i : 10 * i + 10] = -_svec_rows(t) * sig[i][None, :]
        a_rows.append(block)
        b_rows.append(-1e-7 * _svec_identity())
        cones.append(clarabel.PSDTriangleConeT(4))
    x = _clarabel_solve(
        hess, lin, np.vstack(a_rows), np.concatenate(b_rows), cones, "redistribution"
    )
    return {b: x[10 * i : 10 * i + 10] * sig[i] for i, b in enumerate(names)}


def _svec_identity() -> Array:
    return np.array([1.0 if i == j else 0.0 for i, j in _SVEC_IDX])


def _pseudo_scaling(phi: Array) -> Array:
    """T = diag(1/(√m ℓ) ×3, 1/√m): a congruence that brings J(φ) to O(1) (ℓ² = tr Σ / m)."""
    from msk.model.anthropometry import pseudo_inertia

    m = max(float(phi[0]), 1e-6)
    ell = math.sqrt(max(np.trace(pseudo_inertia(phi)[:3, :3]) / m, 1e-8))
    return np.array([1 / (math.sqrt(m) * ell)] * 3 + [1 / math.sqrt(m)])


def _clarabel_solve(
    hess: Array, lin: Array, a: Any, b: Array, cones: list[Any], what: str
) -> Array:
    """min ½ xᵀ(2H)x − 2 linᵀx  s.t.  A x + s = b, s ∈ cones (objective normalised)."""
    import clarabel
    import scipy.sparse as sp  # on use: a cached run does not import scipy.sparse

    k = max(float(np.max(np.abs(np.diag(hess)))), 1e-12)
    p = sp.triu(sp.csc_matrix(2.0 * hess / k)).tocsc()
    q = -2.0 * lin / k
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = 1e-10
    settings.tol_feas = 1e-10
    settings.max_iter = 200
    a_csc = a if sp.issparse(a) else sp.csc_matrix(a)
    sol = clarabel.DefaultSolver(p, q, a_csc, b, cones, settings).solve()
    status = str(sol.status)
    if status not in ("Solved", "AlmostSolved"):
        raise OptimizationError(f"{what}: Clarabel failed with status {status}")
    return np.asarray(sol.x, dtype=float)


# ------------------------------------------------------------------------------------------
# the estimator
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Group:
    primary: str
    members: tuple[tuple[int, Array], ...]  # (body index in layout, sign vector)


#: frames per block of the base-link regressor of a longer trial (~27 MB for 14 bodies): a
#: trial of at most this many frames is stacked in one pass
REGRESSOR_BLOCK = 4096


@dataclass
class _Stats:
    """Per-row Gram statistics of some frames: Σ Y_kᵀY_k, Σ Y_kᵀτ_k, Σ τ_k², frame count."""

    h: Array
    g: Array
    c: Array
    n: int

    @staticmethod
    def zeros(nr: int, n_phi: int) -> _Stats:
        return _Stats(np.zeros((nr, n_phi, n_phi)), np.zeros((nr, n_phi)), np.zeros(nr), 0)

    def add(self, other: _Stats) -> None:
        self.h += other.h
        self.g += other.g
        self.c += other.c
        self.n += other.n

    def accumulate(self, yk: list[Array], tau: Array) -> None:
        """Add the frames whose base-link rows are ``yk[k]`` (frames, params) and torques
        ``tau`` (frames, rows)."""
        for k, y in enumerate(yk):
            t = np.ascontiguousarray(tau[:, k])  # contiguous: the same BLAS path as always
            self.h[k] += y.T @ y
            self.g[k] += y.T @ t
            self.c[k] += t @ t
        self.n += tau.shape[0]

    def row_rss(self, phi: Array) -> Array:
        """Σ over frames of (Y_k φ − τ_k)² per row k."""
        return np.einsum("i,kij,j->k", phi, self.h, phi) - 2 * self.g @ phi + self.c


@dataclass(frozen=True)
class CrossValidation:
    """Held-out base-link residuals of :class:`InertialIdentifier` per prior weight.

    ``weights`` (W,) the candidate prior weights λ (``math.inf`` = prior only: the prior scaled
    to the total mass, no data); ``force_rms_n`` / ``moment_rms_nm`` (W,) the pelvis residual RMS
    pooled over all held-out frames; ``fold_force_rms_n`` / ``fold_moment_rms_nm`` (W, K) per
    fold (``folds`` names them); ``score`` (W,) the selection criterion (``metric``) relative to
    prior only (1 = prior only; ``inf`` = not admissible: worse than prior only on a pooled
    residual); ``selected`` the index of the chosen weight."""

    weights: Array
    force_rms_n: Array
    moment_rms_nm: Array
    fold_force_rms_n: Array
    fold_moment_rms_nm: Array
    folds: tuple[str, ...]
    fold_frames: tuple[int, ...]
    score: Array
    metric: str
    selected: int

    @property
    def prior_only(self) -> int:
        """Index of the prior-only candidate."""
        return int(np.flatnonzero(np.isinf(self.weights))[0])

    def table(self) -> list[str]:
        """One line per candidate weight: pooled and per-fold held-out RMS."""
        out = []
        for i, w in enumerate(self.weights):
            name = "prior only" if math.isinf(w) else f"λ = {w:.3g}"
            folds = " ".join(
                f"{f:.1f}/{m:.2f}"
                for f, m in zip(self.fold_force_rms_n[i], self.fold_moment_rms_nm[i])
            )
            mark = " ← selected" if i == self.selected else ""
            out.append(
                f"{name:<12} force {self.force_rms_n[i]:7.2f} N  moment "
                f"{self.moment_rms_nm[i]:6.2f} N·m  score {self.score[i]:.3f}  folds "
                f"(N/N·m) {folds}{mark}"
            )
        return out


class InertialIdentifier:
    """Physically consistent segment inertial parameters from base-link equations
    (Hayashibe et al. 2011, §II).

    Args:
        model: the identification model (e.g. ``lump_subtrees(full, ["torso"]).model``).
        prior: φ_prior per body (10 values, body frame); default the model's own inertias.
        prior_std: σ of φ per body (10 values) overriding :func:`default_prior_std`.
        mass_rel_std, com_std_m, inertia_rel_std: options of :func:`default_prior_std`.
        symmetric: constrain each ``*_l`` body to the mirror image (z → −z) of its ``*_r``.
        total_mass: known total mass M (kg): Σ m_b = M (e.g. the force-plate weight / g).
        fixed: bodies held at the prior (a symmetric pair must be fixed together).
        bounding_ellipsoids: ``"auto"`` (from the prior, :meth:`BoundingEllipsoid.from_parameters`
            with ``ellipsoid_scale``), a mapping body → :class:`BoundingEllipsoid` (others auto),
            or ``None`` (no ellipsoid constraint).
        noise_std: σ_k of the base-link rows (n_root,) in N / N·m; default estimated from the
            residuals (``noise_iterations`` refits).
        min_eigenvalue: ε of J(φ) ⪰ ε in the pseudo-inertia scaled to O(1) (strictness margin).
        solver: ``"clarabel"`` (SDP, default) or ``"ipopt"`` (log-Cholesky, casadi).
        prior_weight: λ, the weight of the prior term λ ‖x − x_prior‖² (1 = the Gaussian prior
            as stated; ``math.inf`` = prior only), or ``"cv"``: λ chosen by cross-validation
            over the held-out pelvis residuals (:class:`CrossValidation`) among ``cv_grid``
            (default :data:`DEFAULT_CV_GRID`) and "prior only" (the prior scaled to
            ``total_mass``), so that the choice is never worse than prior only on the held-out
            frames of the CV estimate.
        cv_folds: contiguous blocks of frames per trial when folding by blocks.
        cv_by: ``"auto"`` (leave one trial out with ≥ 2 trials, else blocks), ``"trials"`` or
            ``"blocks"`` (block i of every trial held out together).
        cv_metric: ``"both"`` (default: mean of the force and moment RMS², each relative to
            prior only; a weight whose pooled force *or* moment RMS exceeds prior only's is not
            admissible), ``"force"`` or ``"moment"``.

    Fitted attributes: ``parameters_`` (body → φ), ``phi_``, ``std_``, ``prior_``,
    ``prior_std_``, ``parameter_names_``, ``segments_`` (:class:`SegmentEstimate`), ``flags_``,
    ``base_`` (:class:`~msk.dynamics.regressors.BaseParameters`), ``base_std_``,
    ``condition_number_``,
    ``weak_directions_``, ``noise_std_``, ``n_frames_``, ``timing_`` (``stacking_s``,
    ``solve_s``, ``cv_s``), ``prior_weight_`` (λ used), ``cv_scores_``
    (:class:`CrossValidation` or ``None``).
    """

    def __init__(
        self,
        model: Model,
        *,
        prior: Mapping[str, ArrayLike] | None = None,
        prior_std: Mapping[str, ArrayLike] | None = None,
        mass_rel_std: float = 0.3,
        com_std_m: float = 0.03,
        inertia_rel_std: float = 0.5,
        symmetric: bool = True,
        total_mass: float | None = None,
        fixed: Sequence[str] = (),
        bounding_ellipsoids: Literal["auto"] | Mapping[str, BoundingEllipsoid] | None = "auto",
        ellipsoid_scale: float = 2.0,
        noise_std: ArrayLike | None = None,
        noise_iterations: int = 2,
        min_eigenvalue: float = 1e-5,
        solver: Literal["clarabel", "ipopt"] = "clarabel",
        prior_weight: float | Literal["cv"] = 1.0,
        cv_folds: int = 5,
        cv_by: Literal["auto", "trials", "blocks"] = "auto",
        cv_metric: Literal["both", "force", "moment"] = "both",
        cv_grid: Sequence[float] | None = None,
    ) -> None:
        self.model = model
        self.prior = prior
        self.prior_std = prior_std
        self.mass_rel_std = mass_rel_std
        self.com_std_m = com_std_m
        self.inertia_rel_std = inertia_rel_std
        self.symmetric = symmetric
        self.total_mass = total_mass
        self.fixed = tuple(fixed)
        self.bounding_ellipsoids = bounding_ellipsoids
        self.ellipsoid_scale = ellipsoid_scale
        self.noise_std = noise_std
        self.noise_iterations = noise_iterations
        self.min_eigenvalue = min_eigenvalue
        self.solver = solver
        if solver not in ("clarabel", "ipopt"):
            raise IdentificationError(f"unknown solver {solver!r}; use 'clarabel' or 'ipopt'")
        self.prior_weight = prior_weight
        self.cv_folds = cv_folds
        self.cv_by = cv_by
        self.cv_metric = cv_metric
        self.cv_grid = None if cv_grid is None else tuple(cv_grid)
        if cv_by not in ("auto", "trials", "blocks"):
            raise IdentificationError(f"unknown cv_by {cv_by!r}")
        if cv_metric not in ("both", "force", "moment"):
            raise IdentificationError(f"unknown cv_metric {cv_metric!r}")

    # ------------------------------------------------------------ set-up
    def _setup(self) -> None:
        model = self.model
        layout = regressor_layout(model)
        names = layout.body_names
        nb = len(names)
        prior = np.zeros(10 * nb)
        pstd = np.zeros(10 * nb)
        massless: list[str] = []
        for b, name in enumerate(names):
            phi = model.body(name).parameters()
            if self.prior is not None and name in self.prior:
                phi = np.asarray(self.prior[name], dtype=float).reshape(10)
            if not (phi[0] >= 0 and np.all(np.isfinite(phi))):
                raise IdentificationError(f"segment {name!r}: bad prior φ {phi.tolist()}")
            if phi[0] <= 1e-9:
                massless.append(name)  # virtual bodies stay massless (held at the prior)
            prior[10 * b : 10 * b + 10] = phi
            if name in massless:
                pstd[10 * b : 10 * b + 10] = 1.0
            elif self.prior_std is not None and name in self.prior_std:
                pstd[10 * b : 10 * b + 10] = np.asarray(self.prior_std[name], float).reshape(10)
            else:
                pstd[10 * b : 10 * b + 10] = default_prior_std(
                    phi,
                    mass_rel_std=self.mass_rel_std,
                    com_std_m=self.com_std_m,
                    inertia_rel_std=self.inertia_rel_std,
                )
            if np.any(pstd[10 * b : 10 * b + 10] <= 0):
                raise IdentificationError(f"segment {name!r}: prior std must be > 0")
        unknown = set(self.fixed) - set(names)
        if unknown:
            raise IdentificationError(
                f"fixed segments not in model {model.name!r}: {sorted(unknown)}"
            )
        index = {n: i for i, n in enumerate(names)}
        groups: list[_Group] = []
        fixed_mask = np.zeros(nb, bool)
        seen: set[str] = set()
        ones = np.ones(10)
        for name in names:
            if name in seen:
                continue
            partner = None
            if self.symmetric and name.endswith(("_r", "_l")):
                other = name[:-2] + ("_l" if name.endswith("_r") else "_r")
                partner = other if other in index else None
            group = (
                [name] if partner is None else sorted([name, partner], key=lambda s: s[-1] != "r")
            )
            seen |= set(group)
            is_fixed = [g in self.fixed or g in massless for g in group]
            if any(is_fixed) and not all(is_fixed):
                raise IdentificationError(
                    f"symmetric pair {group}: fix both or none (fixed={list(self.fixed)})"
                )
            if all(is_fixed):
                for g in group:
                    fixed_mask[index[g]] = True
                continue
            mem = [(index[group[0]], ones)]
            if len(group) == 2:
                mem.append((index[group[1]], MIRROR_SIGNS))
            groups.append(_Group(group[0], tuple(mem)))
        ng = len(groups)
        proj = np.zeros((10 * nb, 10 * ng))
        x_prior = np.zeros(10 * ng)
        for gi, grp in enumerate(groups):
            pb = grp.members[0][0]
            d = pstd[10 * pb : 10 * pb + 10]
            acc = np.zeros(10)
            for b, sgn in grp.members:
                proj[10 * b : 10 * b + 10, 10 * gi : 10 * gi + 10] = np.diag(sgn * d)
                acc += sgn * prior[10 * b : 10 * b + 10]
            x_prior[10 * gi : 10 * gi + 10] = acc / len(grp.members) / d
        phi_fixed = np.zeros(10 * nb)
        for b in np.flatnonzero(fixed_mask).tolist():
            phi_fixed[10 * b : 10 * b + 10] = prior[10 * b : 10 * b + 10]
        self._layout: RegressorLayout = layout
        self._groups = groups
        self._cone_cache: tuple[Any, ...] | None = None  # constraints of _solve, built once
        self._proj = proj
        self._x_prior = x_prior
        self._phi_fixed = phi_fixed
        self._fixed_mask = fixed_mask
        self.prior_ = prior
        self.prior_std_ = pstd
        self.parameter_names_ = layout.parameter_names
        self._x_names = tuple(
            f"{g.primary}{'(+_l)' if len(g.members) == 2 else ''}.{p}"
            for g in groups
            for p in INERTIAL_PARAMETER_NAMES
        )

    # ------------------------------------------------------------ stacking
    def _stack(self, trials: list[IdentificationTrial], n_blocks: int = 1) -> list[_Stats]:
        """Gram statistics of the base-link rows, summed into ``self._h, _g, _c``; returned per
        block — one per trial (``n_blocks == 0``) or ``n_blocks`` contiguous blocks of frames
        of every trial (block i holds the i-th chunk of each trial)."""
        model, layout = self.model, self._layout
        nr = root_coordinate_indices(model).size
        n_phi = 10 * len(layout.body_names)
        n_out = len(trials) if n_blocks == 0 else n_blocks
        blocks = [_Stats.zeros(nr, n_phi) for _ in range(n_out)]
        for ti, trial in enumerate(trials):
            th, thd, thdd, tau = _trial_arrays(model, trial)
            if th.shape[0] == 0:
                continue
            if n_blocks == 0:
                chunks = [(ti, np.arange(th.shape[0]))]
            else:
                chunks = list(enumerate(np.array_split(np.arange(th.shape[0]), n_blocks)))
            if th.shape[0] <= REGRESSOR_BLOCK:  # the regressor of the whole trial at once
                y = base_link_regressor(model, th, thd, thdd, layout=layout)
                yt = np.ascontiguousarray(y.transpose(1, 0, 2))  # (rows, N, params)
                for bi, idx in chunks:
                    blocks[bi].accumulate([yt[k][idx] for k in range(nr)], tau[idx])
                continue
            # a long trial: the regressor (N, rows, params) is never held whole
            for bi, idx in chunks:
                for c0 in range(0, idx.size, REGRESSOR_BLOCK):
                    sub = idx[c0 : c0 + REGRESSOR_BLOCK]
                    y = base_link_regressor(model, th[sub], thd[sub], thdd[sub], layout=layout)
                    yt = np.ascontiguousarray(y.transpose(1, 0, 2))
                    del y
                    blocks[bi].accumulate(list(yt), tau[sub])
                    del yt
        total = _Stats.zeros(nr, n_phi)
        for blk in blocks:
            total.add(blk)
        if total.n < 2:
            names = [t.name for t in trials]
            raise IdentificationError(f"trials {names}: fewer than 2 usable (finite) frames")
        self._h, self._g, self._c, self.n_frames_ = total.h, total.g, total.c, total.n
        return blocks

    # ------------------------------------------------------------ solving
    def _x_system(self, sigma: Array, st: _Stats | None = None) -> tuple[Array, Array]:
        """Scaled data information H_x and right-hand side g_x for noise σ_k."""
        h, g = (self._h, self._g) if st is None else (st.h, st.g)
        w = 1.0 / sigma**2
        h_phi = np.einsum("k,kij->ij", w, h)
        g_phi = np.einsum("k,ki->i", w, g) - h_phi @ self._phi_fixed
        return self._proj.T @ h_phi @ self._proj, self._proj.T @ g_phi

    def _row_rss(self, phi: Array, st: _Stats | None = None) -> Array:
        st = st or _Stats(self._h, self._g, self._c, self.n_frames_)
        return st.row_rss(phi)

    def _constraints(self) -> tuple[list[Array], list[Array], list[tuple[str, int]]]:
        """Rows (A, b, cone) of A x + s = b in the scaled variables x."""
        a_rows: list[Array] = []
        b_rows: list[Array] = []
        cones: list[tuple[str, int]] = []
        nx = self._proj.shape[1]
        names = self._layout.body_names
        if self.total_mass is not None:
            row = np.zeros(nx)
            for gi, grp in enumerate(self._groups):
                row[10 * gi] = len(grp.members) * self._proj[10 * grp.members[0][0], 10 * gi]
            fixed_m = sum(self._phi_fixed[10 * b] for b in range(len(names)))
            if not self.total_mass > fixed_m:
                raise IdentificationError(
                    f"total_mass {self.total_mass} kg ≤ mass of fixed segments {fixed_m:.3f} kg"
                )
            a_rows.append(row[None, :])
            b_rows.append(np.array([self.total_mass - fixed_m]))
            cones.append(("zero", 1))
        for gi, grp in enumerate(self._groups):
            pb = grp.members[0][0]
            d = self._proj[10 * pb : 10 * pb + 10, 10 * gi : 10 * gi + 10]
            phi0 = d @ self._x_prior[10 * gi : 10 * gi + 10]
            ell = self._ellipsoid(names[pb], phi0)
            if ell is not None:
                qv = ell.q_matrix().reshape(16) @ _JMAP  # tr(Q J(φ)) = qv · φ
                scale = float(qv @ phi0) or 1.0
                block = np.zeros((1, nx))
                block[0, 10 * gi : 10 * gi + 10] = -(qv @ d) / abs(scale)
                a_rows.append(block)
                b_rows.append(np.zeros(1))
                cones.append(("nonneg", 1))
            block = np.zeros((_PSD_N, nx))
            block[:, 10 * gi : 10 * gi + 10] = -_svec_rows(_pseudo_scaling(phi0)) @ d
            a_rows.append(block)
            b_rows.append(-self.min_eigenvalue * _svec_identity())
            cones.append(("psd", 4))
        return a_rows, b_rows, cones

    def _ellipsoid(self, name: str, phi0: Array) -> BoundingEllipsoid | None:
        if self.bounding_ellipsoids is None:
            return None
        if isinstance(self.bounding_ellipsoids, Mapping) and name in self.bounding_ellipsoids:
            return self.bounding_ellipsoids[name]
        return BoundingEllipsoid.from_parameters(phi0, scale=self.ellipsoid_scale)

    def _solve(self, hx: Array, gx: Array, weight: float = 1.0) -> Array:
        import clarabel
        import scipy.sparse as sp  # on use: a cached run does not import scipy.sparse

        if self._cone_cache is None:  # the same for every solve of a fit (cv grid: ~120)
            a_rows, b_rows, cones = self._constraints()
            kinds = {"zero": clarabel.ZeroConeT, "nonneg": clarabel.NonnegativeConeT}
            cl = [clarabel.PSDTriangleConeT(n) if k == "psd" else kinds[k](n) for k, n in cones]
            a_csc = sp.csc_matrix(np.vstack(a_rows))
            self._cone_cache = (a_rows, b_rows, cones, a_csc, np.concatenate(b_rows), cl)
        a_rows, b_rows, cones, a_csc, b, cl = self._cone_cache
        hess = hx + weight * np.eye(hx.shape[0])
        lin = gx + weight * self._x_prior
        if self.solver == "ipopt":
            return self._solve_ipopt(hess, lin, a_rows, b_rows, cones)
        return _clarabel_solve(hess, lin, a_csc, b, cl,
                               f"identification of {self.model.name!r}")  # fmt: skip

    def _solve_ipopt(
        self,
        hess: Array,
        lin: Array,
        a_rows: list[Array],
        b_rows: list[Array],
        cones: list[tuple[str, int]],
    ) -> Array:
        """Same problem over the log-Cholesky parametrisation Ĵ = U Uᵀ of each scaled J."""
        import casadi as ca

        nx = hess.shape[0]
        ng = nx // 10
        theta = ca.SX.sym("theta", 10 * ng)
        xs = []
        init = np.zeros(10 * ng)
        for gi, grp in enumerate(self._groups):
            pb = grp.members[0][0]
            d = np.diag(self._proj[10 * pb : 10 * pb + 10, 10 * gi : 10 * gi + 10])
            phi0 = d * self._x_prior[10 * gi : 10 * gi + 10]
            t = _pseudo_scaling(phi0)
            p = theta[10 * gi : 10 * gi + 10]
            ea = ca.exp(p[0])
            u = ca.SX.zeros(4, 4)
            u[0, 0], u[1, 1], u[2, 2], u[3, 3] = ca.exp(p[1]), ca.exp(p[2]), ca.exp(p[3]), 1
            u[0, 1], u[1, 2], u[0, 2] = p[4], p[5], p[6]
            u[0, 3], u[1, 3], u[2, 3] = p[7], p[8], p[9]
            u = ea * u
            jh = u @ u.T
            jm = ca.diag(1.0 / t) @ jh @ ca.diag(1.0 / t)
            phi = ca.vertcat(*_phi_from_pseudo(jm))
            xs.append(phi / d)
            init[10 * gi : 10 * gi + 10] = _log_cholesky(np.diag(t) @ _pseudo(phi0) @ np.diag(t))
        x = ca.vertcat(*xs)
        cost = x.T @ ca.DM(hess) @ x - 2 * ca.dot(ca.DM(lin), x)
        cons, lb, ub = [], [], []
        for a, b, (kind, _) in zip(a_rows, b_rows, cones):
            if kind == "psd":
                continue
            expr = ca.DM(b) - ca.DM(a) @ x  # s = b − A x
            cons.append(expr)
            lb += [0.0] * a.shape[0]
            ub += [0.0 if kind == "zero" else ca.inf] * a.shape[0]
        nlp = {"x": theta, "f": cost / max(float(np.max(np.diag(hess))), 1e-12)}
        if cons:
            nlp["g"] = ca.vertcat(*cons)
        opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.tol": 1e-10,
                "ipopt.max_iter": 500}  # fmt: skip
        solver = ca.nlpsol("inertial_id", "ipopt", nlp, opts)
        # keep the logarithmic coordinates within e^±6 of the prior (no overflow in exp)
        lbx = init.copy()
        ubx = init.copy()
        for gi in range(ng):
            sl = slice(10 * gi, 10 * gi + 4)
            lbx[sl] -= 6.0
            ubx[sl] += 6.0
            lbx[10 * gi + 4 : 10 * gi + 10] = -np.inf
            ubx[10 * gi + 4 : 10 * gi + 10] = np.inf
        kw = {"lbg": lb, "ubg": ub} if cons else {}
        res = solver(x0=init, lbx=lbx, ubx=ubx, **kw)
        status = solver.stats()["return_status"]
        if status not in ("Solve_Succeeded", "Solved_To_Acceptable_Level"):
            raise OptimizationError(f"identification of {self.model.name!r}: ipopt {status}")
        return np.asarray(ca.Function("x", [theta], [x])(res["x"]), dtype=float).reshape(-1)

    # ------------------------------------------------------------ public API
    def fit(
        self, trials: IdentificationTrial | Sequence[IdentificationTrial]
    ) -> InertialIdentifier:
        """Identify φ from the base-link equations of ``trials`` (Hayashibe et al. 2011, Eq. 2).

        With ``prior_weight="cv"`` the weight λ of the prior term is chosen first by
        cross-validation (:meth:`cross_validate`), then φ is fitted on all frames with it."""
        trial_list = _as_trials(trials)
        self._setup()
        t0 = _time.perf_counter()
        cv = isinstance(self.prior_weight, str)
        if cv and self.prior_weight != "cv":
            raise IdentificationError(f"prior_weight must be 'cv' or a float > 0, got "
                                      f"{self.prior_weight!r}")  # fmt: skip
        if not cv and not float(self.prior_weight) > 0:
            raise IdentificationError(f"prior_weight must be > 0, got {self.prior_weight!r}")
        by_trial = cv and self.cv_by != "blocks" and len(trial_list) >= 2
        if cv and self.cv_by == "trials" and len(trial_list) < 2:
            raise IdentificationError("cv_by='trials' needs at least 2 trials")
        n_blocks = 0 if by_trial else (max(int(self.cv_folds), 2) if cv else 1)
        blocks = self._stack(trial_list, n_blocks)
        t1 = _time.perf_counter()
        if cv:
            names = (
                tuple(t.name or f"trial {i}" for i, t in enumerate(trial_list))
                if by_trial
                else tuple(f"block {i + 1}/{n_blocks}" for i in range(n_blocks))
            )
            self.cv_scores_: CrossValidation | None = self._cross_validate(blocks, names)
            weight = float(self.cv_scores_.weights[self.cv_scores_.selected])
        else:
            self.cv_scores_ = None
            weight = float(self.prior_weight)
        t2 = _time.perf_counter()
        total = _Stats(self._h, self._g, self._c, self.n_frames_)
        x, sigma, hx, solves = self._fit_stats(total, weight)
        t3 = _time.perf_counter()
        self.prior_weight_ = weight
        self.noise_std_ = sigma
        self._hx = hx
        self.x_ = x
        self.phi_ = self._phi_of(x, weight)
        names_b = self._layout.body_names
        self.parameters_ = {
            n: self.phi_[10 * b : 10 * b + 10].copy() for b, n in enumerate(names_b)
        }
        self.timing_ = {"stacking_s": t1 - t0, "solve_s": t3 - t2, "solves": solves,
                        "cv_s": t2 - t1}  # fmt: skip
        self._uncertainty()
        return self

    def _initial_sigma(self, st: _Stats) -> Array:
        nr = st.c.size
        if self.noise_std is not None:
            sigma = np.broadcast_to(np.asarray(self.noise_std, dtype=float), (nr,)).copy()
            if np.any(sigma <= 0):
                raise IdentificationError(f"noise_std must be > 0, got {sigma}")
            return sigma
        # start from 5 % of the RMS pooled over the force rows and over the moment rows,
        # then re-estimate from the residuals. (Not per row: a row that is physically
        # near zero — the moment about the vertical when standing — would get a σ far
        # below the measurement noise, and the fit would trade every other row for it.)
        rms = np.sqrt(st.c / max(st.n, 1))
        trans = self._translational_rows()
        for kind in (trans, ~trans):
            if kind.any():
                rms[kind] = np.sqrt(np.mean(rms[kind] ** 2))
        return 0.05 * rms + 1e-6

    def _translational_rows(self) -> NDArray[np.bool_]:
        root = root_coordinate_indices(self.model)
        return np.array([self.model.coordinates[i].kind == "translational" for i in root])

    def _phi_of(self, x: Array, weight: float) -> Array:
        """φ of the solution ``x`` at prior weight ``weight``; prior only (``inf``) is the prior
        itself scaled to the total mass — every body as in the model, also a symmetric pair
        whose prior is not mirror-symmetric (legs scaled with different factors), which the
        symmetric parametrisation ``x`` can only average."""
        if not math.isinf(weight):
            return self._proj @ x + self._phi_fixed
        phi = np.asarray(self.prior_, dtype=float).copy()
        free = ~self._fixed_mask
        if self.total_mass is not None:
            masses = phi[0::10]
            fixed_m = float(masses[~free].sum())
            phi.reshape(-1, 10)[free] *= (self.total_mass - fixed_m) / float(masses[free].sum())
        return phi

    def _prior_only_x(self) -> Array:
        """The prior with every free segment scaled by one factor so that Σ m = total mass (the
        generic model at the measured mass; the prior itself without ``total_mass``)."""
        if self.total_mass is None:
            return self._x_prior.copy()
        names = self._layout.body_names
        free_m = sum(
            len(grp.members) * self._proj[10 * grp.members[0][0], 10 * gi]
            * self._x_prior[10 * gi]
            for gi, grp in enumerate(self._groups)
        )  # fmt: skip
        fixed_m = sum(self._phi_fixed[10 * b] for b in range(len(names)))
        if not free_m > 0 or not self.total_mass > fixed_m:
            raise IdentificationError(
                f"total_mass {self.total_mass} kg ≤ mass of fixed segments {fixed_m:.3f} kg"
            )
        return self._x_prior * ((self.total_mass - fixed_m) / free_m)

    def _fit_stats(
        self, st: _Stats, weight: float, first: tuple[Array, Array, Array] | None = None
    ) -> tuple[Array, Array, Array, int]:
        """x, σ, H_x and the number of solves of the MAP fit on the statistics ``st`` with prior
        weight λ (``inf``: prior only, σ from its residuals). ``first``: σ₀ and its
        :meth:`_x_system` on ``st`` when the caller has them (the same for every λ)."""
        sigma = self._initial_sigma(st) if first is None else first[0]
        if math.isinf(weight):
            x = self._prior_only_x()
            if self.noise_std is None:
                phi = self._phi_of(x, weight)
                rss = np.maximum(st.row_rss(phi), 0.0)
                sigma = np.sqrt(rss / st.n) + 1e-9 * (1 + np.sqrt(st.c / st.n))
            hx, _ = self._x_system(sigma, st)
            return x, sigma, hx, 0
        iterations = 1 if self.noise_std is not None else 1 + max(self.noise_iterations, 0)
        x = self._x_prior
        hx = np.zeros((x.size, x.size))
        for it in range(iterations):
            hx, gx = self._x_system(sigma, st) if it or first is None else first[1:]
            x = self._solve(hx, gx, weight)
            if it < iterations - 1:
                phi = self._proj @ x + self._phi_fixed
                rss = np.maximum(st.row_rss(phi), 0.0)
                sigma = np.sqrt(rss / st.n) + 1e-9 * (1 + np.sqrt(st.c / st.n))
        return x, sigma, hx, iterations

    def _cross_validate(self, blocks: list[_Stats], names: tuple[str, ...]) -> CrossValidation:
        """Held-out pelvis residuals per candidate λ (every block held out once)."""
        grid = np.array(
            sorted({float(w) for w in (self.cv_grid if self.cv_grid is not None
                                       else DEFAULT_CV_GRID)} | {math.inf})
        )  # fmt: skip
        if np.any(grid <= 0):
            raise IdentificationError(f"cv_grid weights must be > 0, got {grid.tolist()}")
        used = [i for i, b in enumerate(blocks) if b.n > 0]
        if len(used) < 2:
            raise IdentificationError(
                "cross-validation needs at least 2 blocks with frames (more frames or trials)"
            )
        nr = blocks[0].c.size
        trans = self._translational_rows()
        k = len(used)
        sq = np.zeros((grid.size, nr))
        fold_f = np.full((grid.size, k), np.nan)
        fold_m = np.full((grid.size, k), np.nan)
        trains = []
        for bi in used:
            train = _Stats.zeros(nr, blocks[bi].h.shape[1])
            for bj in used:
                if bj != bi:
                    train.add(blocks[bj])
            if train.n < 2:
                raise IdentificationError(
                    f"cross-validation fold {names[bi]!r}: no training frames"
                )
            trains.append(train)

        def held_out_rss(fold: int) -> list[Array]:
            """Held-out residual sums per row of every λ of the grid, trained without ``fold``."""
            train, held = trains[fold], blocks[used[fold]]
            sigma0 = self._initial_sigma(train)
            first = (sigma0, *self._x_system(sigma0, train))
            out = []
            for w in grid:
                x, _, _, _ = self._fit_stats(train, float(w), first)
                out.append(np.maximum(held.row_rss(self._phi_of(x, float(w))), 0.0))
            return out

        # the folds are independent and Clarabel releases the GIL: two at a time with a second
        # CPU free (msk._runtime.fork.spare_cpu; the sums below are taken in fold order, so the
        # result
        # does not depend on it). Not with ipopt, whose MUMPS is not thread-safe.
        threads = 2 if self.solver != "ipopt" and spare_cpu() else 1
        with ThreadPoolExecutor(max_workers=threads) as pool:
            per_fold = list(pool.map(held_out_rss, range(k)))
        n_held = 0
        for fi, bi in enumerate(used):
            held = blocks[bi]
            n_held += held.n
            for wi, rss in enumerate(per_fold[fi]):
                sq[wi] += rss
                rms = np.sqrt(rss / held.n)
                fold_f[wi, fi] = _pool_rms(rms, trans)
                fold_m[wi, fi] = _pool_rms(rms, ~trans)
        rms_all = np.sqrt(sq / n_held)
        force = np.array([_pool_rms(r, trans) for r in rms_all])
        moment = np.array([_pool_rms(r, ~trans) for r in rms_all])
        po = int(np.flatnonzero(np.isinf(grid))[0])
        f0 = max(force[po], 1e-12) if np.isfinite(force[po]) else 1.0
        m0 = max(moment[po], 1e-12) if np.isfinite(moment[po]) else 1.0
        rel_f = np.nan_to_num(force / f0, nan=1.0)
        rel_m = np.nan_to_num(moment / m0, nan=1.0)
        if self.cv_metric == "force":
            score = rel_f**2
        elif self.cv_metric == "moment":
            score = rel_m**2
        else:
            score = 0.5 * (rel_f**2 + rel_m**2)
            # admissible only if neither pooled residual is worse than prior only
            score = np.where((rel_f <= 1.0 + 1e-12) & (rel_m <= 1.0 + 1e-12), score, math.inf)
        score[po] = 1.0
        # smallest score; ties → the larger weight (closer to the prior)
        best = min(range(grid.size), key=lambda i: (score[i], -grid[i]))
        return CrossValidation(
            grid, force, moment, fold_f, fold_m, tuple(names[i] for i in used),
            tuple(blocks[i].n for i in used), score, self.cv_metric, int(best),
        )  # fmt: skip

    def _uncertainty(self) -> None:
        nx = self._hx.shape[0]
        # prior only (λ = ∞): the data were not used, report the prior covariance (λ = 1)
        lam = 1.0 if math.isinf(self.prior_weight_) else self.prior_weight_
        cov_x = (
            np.eye(nx) if math.isinf(self.prior_weight_)
            else np.linalg.inv(self._hx + lam * np.eye(nx))
        )  # fmt: skip
        self._cov_x = cov_x
        cov_phi = self._proj @ cov_x @ self._proj.T
        self.covariance_ = cov_phi
        self.std_ = np.sqrt(np.maximum(np.diag(cov_phi), 0.0))
        prior_cov = self._proj @ self._proj.T / lam  # x prior covariance is the identity / λ
        names = self._layout.body_names
        segments: list[SegmentEstimate] = []
        flags: dict[str, str] = {}
        for b, name in enumerate(names):
            sl = slice(10 * b, 10 * b + 10)
            phi = self.phi_[sl]
            prior = self.prior_[sl]
            if self._fixed_mask[b]:
                flag = "prior"
                m_std, c_std, ratio = 0.0, np.zeros(3), np.ones(4)
            else:
                m_std, c_std = _mass_com_std(phi, cov_phi[sl, sl])
                pm_std, pc_std = _mass_com_std(prior, prior_cov[sl, sl])
                ratio = np.concatenate([[m_std / pm_std], c_std / pc_std])
                if m_std <= WELL_IDENTIFIED_MASS_REL_STD * phi[0] and np.all(
                    c_std <= WELL_IDENTIFIED_COM_STD_M
                ):
                    flag = "well identified"
                elif np.all(ratio > PRIOR_STD_RATIO):
                    flag = "prior"
                else:
                    flag = "weakly identified"
            flags[name] = flag
            segments.append(
                SegmentEstimate(
                    name, float(phi[0]), float(m_std), _com(phi), c_std,
                    float(prior[0]), _com(prior), flag,
                )
            )  # fmt: skip
        self.segments_ = tuple(segments)
        self.flags_ = flags
        # weak directions: data information of the scaled variables below the prior's (= λ)
        ev, vec = np.linalg.eigh(0.5 * (self._hx + self._hx.T))
        weak = []
        for i in np.argsort(ev)[:8]:
            if ev[i] >= lam:
                break
            v = vec[:, i]
            top = np.argsort(-np.abs(v))[:4]
            comps = tuple((self._x_names[j], float(v[j])) for j in top if abs(v[j]) > 0.1)
            std_ratio = math.inf if ev[i] <= 1e-12 else math.sqrt(lam / ev[i])
            weak.append(WeakDirection(float(std_ratio), comps))
        self.weak_directions_ = tuple(weak)
        # structural base parameters (random states) and their data-only std on this data
        self.base_ = _structural_base(self.model, self._layout)
        w = 1.0 / self.noise_std_**2
        h_phi = np.einsum("k,kij->ij", w, self._h)
        ind = self.base_.independent
        # Y φ = Y_b β with β = projection φ ⇒ information on β is Y_bᵀ W Y_b
        hb = h_phi[np.ix_(ind, ind)]
        dscale = np.sqrt(np.maximum(np.diag(hb), 1e-300))
        hn = hb / np.outer(dscale, dscale)
        ev = np.linalg.eigvalsh(hn)
        self.condition_number_ = float(math.sqrt(ev[-1] / ev[0])) if ev[0] > 0 else math.inf
        try:
            cov_b = np.linalg.inv(hn) / np.outer(dscale, dscale)
            self.base_std_ = np.sqrt(np.maximum(np.diag(cov_b), 0.0))
        except np.linalg.LinAlgError:
            self.base_std_ = np.full(ind.size, math.inf)

    def _check_fitted(self) -> None:
        if not hasattr(self, "phi_"):
            raise IdentificationError("InertialIdentifier is not fitted: call fit() first")

    def predict(self, theta: ArrayLike, theta_dot: ArrayLike, theta_ddot: ArrayLike) -> Array:
        """Base-link generalised forces Y_root φ̂ (N, n_root) the identified model needs — the
        external wrench the force plates should measure, projected on the root coordinates."""
        self._check_fitted()
        y = base_link_regressor(self.model, theta, theta_dot, theta_ddot, layout=self._layout)
        return y @ self.phi_

    def score(self, trials: IdentificationTrial | Sequence[IdentificationTrial]) -> BaseResiduals:
        """Residual RMS of the base-link equations with the identified parameters."""
        self._check_fitted()
        return base_residuals(self.model, trials, self.parameters_)

    def to_model(self, lumped: LumpedModel | None = None) -> Model:
        """The identified model: ``lumped.redistribute`` onto the musculoskeletal model when the
        identification model came from :func:`lump_subtrees`, else ``model.with_inertias``."""
        self._check_fitted()
        if lumped is not None:
            return lumped.redistribute(self.parameters_)
        return self.model.with_inertias({n: p for n, p in self.parameters_.items() if p[0] > 1e-12})

    def summary(self) -> str:
        """A human-readable table (mass, COM, std, flag) with excitation guidance."""
        self._check_fitted()
        lines = [
            f"inertial identification of {self.model.name!r}: {self.n_frames_} frames, "
            f"condition number {self.condition_number_:.3g}, {self.base_.rank} base parameters",
            f"{'segment':<14}{'mass kg':>9}{'±':>7}{'prior':>8}  {'COM m (±)':<34}flag",
        ]
        for s in self.segments_:
            com = " ".join(f"{c:+.3f}({e:.3f})" for c, e in zip(s.com, s.com_std))
            lines.append(
                f"{s.name:<14}{s.mass:9.3f}{s.mass_std:7.3f}{s.prior_mass:8.3f}  {com:<34}{s.flag}"
            )
        lines.append(f"total mass {sum(s.mass for s in self.segments_):.3f} kg")
        lines.extend(self.advice())
        return "\n".join(lines)

    def excitation(self, *, suggest: bool = True) -> ExcitationReport:
        """How well the fitted trials excite each segment, and which motion would excite the
        poorly excited ones (:func:`excitation_report`)."""
        self._check_fitted()
        lam = 1.0 if math.isinf(self.prior_weight_) else self.prior_weight_
        nx = self._hx.shape[0]
        cov0 = np.linalg.inv(self._hx + lam * np.eye(nx))
        candidates = self._candidate_motions() if suggest else []
        infos = [(label, self._motion_information(th, thd, thdd)) for label, th, thd, thdd in
                 candidates]  # fmt: skip
        covs = [(label, np.linalg.inv(self._hx + hc + lam * np.eye(nx))) for label, hc in infos]
        out: list[SegmentExcitation] = []
        mc = slice(0, 4)
        for gi, grp in enumerate(self._groups):
            sl = slice(10 * gi, 10 * gi + 10)
            c_g = cov0[sl, sl] * lam  # posterior / prior covariance (scaled variables)
            ratio = np.sqrt(np.maximum(np.diag(c_g), 0.0))
            ev = np.linalg.eigvalsh(np.linalg.inv(c_g))
            info = np.sort(np.maximum(ev - 1.0, 0.0))  # data / prior information per direction
            poor = bool(np.any(ratio[mc] > PRIOR_STD_RATIO))
            sugg: list[tuple[str, float]] = []
            if poor and covs:
                gains = []
                for label, cov in covs:
                    r1 = np.sqrt(np.maximum(np.diag(cov[sl, sl] * lam)[mc], 1e-300))
                    gains.append((label, float(np.mean(np.log(ratio[mc] / r1)))))
                gains.sort(key=lambda t: -t[1])
                sugg = [(lb, g) for lb, g in gains[:3] if g > 0.05]
            names = tuple(self._layout.body_names[b] for b, _ in grp.members)
            out.append(SegmentExcitation(
                names, float(ratio[0]), ratio[1:4].copy(), float(np.max(ratio[4:])),
                info, int(np.sum(ratio < PRIOR_STD_RATIO)), poor, tuple(sugg),
            ))  # fmt: skip
        return ExcitationReport(tuple(out), self.n_frames_, float(lam))

    def _motion_information(self, th: Array, thd: Array, thdd: Array) -> Array:
        y = base_link_regressor(self.model, th, thd, thdd, layout=self._layout)
        w = 1.0 / self.noise_std_**2
        h_phi = np.einsum("k,nki,nkj->ij", w, y, y)
        return np.asarray(self._proj.T @ h_phi @ self._proj)

    def _candidate_motions(self) -> list[tuple[str, Array, Array, Array]]:
        """Per non-root rotational coordinate: a 1 Hz swing and 5 still poses (2 s at 100 Hz
        each) about the model's default pose."""
        model = self.model
        root = set(root_coordinate_indices(model).tolist())
        base = model.default_coordinates()
        lo, hi = model.coordinate_bounds()
        t = np.arange(200) / 100.0
        out = []
        for i, c in enumerate(model.coordinates):
            if i in root or c.kind == "translational":
                continue
            amp = 0.5
            if np.isfinite(lo[i]) and np.isfinite(hi[i]):
                amp = min(amp, 0.45 * (hi[i] - lo[i]))
            centre = base[i]
            if np.isfinite(lo[i]) and np.isfinite(hi[i]):
                centre = float(np.clip(centre, lo[i] + amp, hi[i] - amp))
            words = _motion_words(c.name)
            th = np.tile(base, (t.size, 1))
            thd = np.zeros_like(th)
            thdd = np.zeros_like(th)
            w = 2 * np.pi
            th[:, i] = centre + amp * np.sin(w * t)
            thd[:, i] = amp * w * np.cos(w * t)
            thdd[:, i] = -amp * w * w * np.sin(w * t)
            out.append((f"swing: {words}, ±{np.degrees(amp):.0f}° at 1 Hz", th, thd, thdd))
            poses = np.tile(base, (t.size, 1))
            poses[:, i] = centre + amp * np.repeat(np.linspace(-1, 1, 5), t.size // 5)
            zero = np.zeros_like(poses)
            out.append(
                (f"still poses on plates: {words} held at 5 angles over ±{np.degrees(amp):.0f}°",
                 poses, zero, zero)
            )  # fmt: skip
        return out

    def advice(self) -> list[str]:
        """Guidance when the motion is not exciting enough: the segments left at the prior and
        the least excited parameter combinations (in parameter names)."""
        self._check_fitted()
        out = []
        at_prior = [n for n, f in self.flags_.items() if f == "prior" and not self._fixed_mask[
            self._layout.body_names.index(n)]]  # fmt: skip
        if at_prior:
            out.append(
                "not excited (estimate stays at the prior): " + ", ".join(at_prior)
                + " — move these segments more (larger, faster, multi-planar motion)"
            )  # fmt: skip
        for wd in self.weak_directions_[:5]:
            comb = " ".join(f"{c:+.2f}·{n}" for n, c in wd.components)
            how = "no data" if math.isinf(wd.std_ratio) else f"data std {wd.std_ratio:.2g}× prior"
            out.append(f"weak direction ({how}): {comb}")
        return out


_WORDS = (
    ("hip_flexion", "hip flexion/extension"),
    ("hip_adduction", "hip abduction/adduction"),
    ("hip_rotation", "hip internal/external rotation"),
    ("knee", "knee flexion/extension"),
    ("ankle", "ankle plantar/dorsiflexion"),
    ("subtalar", "subtalar inversion/eversion"),
    ("mtp", "toe flexion/extension"),
    ("lumbar_extension", "trunk flexion/extension"),
    ("lumbar_bending", "trunk lateral bending"),
    ("lumbar_rotation", "trunk axial rotation"),
    ("arm_flex", "shoulder flexion/extension"),
    ("arm_add", "shoulder abduction (T-pose)"),
    ("arm_rot", "shoulder rotation"),
    ("elbow", "elbow flexion/extension"),
)


def _motion_words(coordinate: str) -> str:
    """Plain words for moving one coordinate (``hip_adduction_r`` → "hip abduction/adduction
    (right), with the leg free")."""
    base, side = coordinate, ""
    if coordinate.endswith(("_r", "_l")):
        base, side = coordinate[:-2], " (right)" if coordinate.endswith("_r") else " (left)"
    words = next((w for key, w in _WORDS if base.startswith(key)), coordinate)
    leg = base.startswith(("hip", "knee", "ankle", "subtalar", "mtp"))
    return words + side + (", with the leg free (stand on the other leg)" if leg else "")


@dataclass(frozen=True)
class SegmentExcitation:
    """Excitation of one identified segment (a left/right pair counts once).

    ``mass_std_ratio``, ``com_std_ratio`` (3,), ``inertia_std_ratio`` (largest over the 6
    inertia entries): posterior / prior std (1 = the data say nothing); ``information`` (10,)
    the eigenvalues of data / prior information of the segment's parameters (others
    marginalised), ascending; ``n_excited`` parameters with std ratio < :data:`PRIOR_STD_RATIO`;
    ``poorly_excited`` when the mass or a COM coordinate is not; ``suggestions`` (motion, mean
    log-reduction of the mass and COM std) of the candidate motions that help most."""

    bodies: tuple[str, ...]
    mass_std_ratio: float
    com_std_ratio: Array
    inertia_std_ratio: float
    information: Array
    n_excited: int
    poorly_excited: bool
    suggestions: tuple[tuple[str, float], ...]

    @property
    def name(self) -> str:
        return "/".join(self.bodies)


@dataclass(frozen=True)
class ExcitationReport:
    """Per-segment excitation of some trials (:func:`excitation_report`)."""

    segments: tuple[SegmentExcitation, ...]
    n_frames: int
    prior_weight: float

    def segment(self, body: str) -> SegmentExcitation:
        for s in self.segments:
            if body in s.bodies:
                return s
        raise IdentificationError(f"no identified segment {body!r} in the report")

    def lines(self) -> list[str]:
        out = [
            f"excitation over {self.n_frames} frames (posterior/prior std; 1 = not excited; "
            f"≤ {PRIOR_STD_RATIO} excited):",
            f"{'segment':<20}{'mass':>6}{'COM x':>7}{'COM y':>7}{'COM z':>7}{'inertia':>8}"
            f"{'excited':>9}",
        ]
        for s in self.segments:
            com = "".join(f"{r:7.2f}" for r in s.com_std_ratio)
            out.append(f"{s.name:<20}{s.mass_std_ratio:6.2f}{com}{s.inertia_std_ratio:8.2f}"
                       f"{s.n_excited:>6}/10")  # fmt: skip
        for s in self.segments:
            if s.poorly_excited:
                how = "; ".join(f"{m} (std ×{math.exp(-g):.2f})" for m, g in s.suggestions)
                out.append(
                    f"{s.name}: poorly excited — "
                    + (
                        how
                        or "no 2 s single-coordinate "
                        "motion cuts its mass/COM std by ≥ 5 % more: record longer trials"
                    )
                )
        return out

    def __str__(self) -> str:
        return "\n".join(self.lines())


def excitation_report(
    model: Model,
    trials: IdentificationTrial | Sequence[IdentificationTrial],
    *,
    suggest: bool = True,
    **identifier_options: Any,
) -> ExcitationReport:
    """Experiment-design aid: which segments ``trials`` excite and which motion would excite the
    rest (in the spirit of Hayashibe et al., IROS 2011: T-pose / functional movements).

    The trials are fitted (:class:`InertialIdentifier` with ``identifier_options``); per segment
    the posterior/prior std of mass, COM and inertia follow from the base-link regressor columns
    (information Y_bᵀ W Y_b, the others marginalised). For a poorly excited segment every
    candidate motion — per joint coordinate, a 1 Hz swing (θ̈ and θ̇: inertia and the mass
    through the segment's own acceleration) and still poses at 5 angles (gravity only: the
    first moments m·c through the change of orientation) — is added to the trials' information
    and ranked by how much it reduces that segment's mass and COM std."""
    ident = InertialIdentifier(model, **identifier_options).fit(trials)
    return ident.excitation(suggest=suggest)


def _pseudo(phi: Array) -> Array:
    from msk.model.anthropometry import pseudo_inertia

    return pseudo_inertia(phi)


def _log_cholesky(jh: Array) -> Array:
    """θ with U(θ) U(θ)ᵀ = Ĵ, U upper triangular (Rucker & Wensing 2022 parametrisation)."""
    flip = np.eye(4)[::-1]
    jh = 0.5 * (jh + jh.T)
    w, v = np.linalg.eigh(jh)
    jh = v @ np.diag(np.maximum(w, 1e-8 * max(w.max(), 1e-12))) @ v.T
    low = np.linalg.cholesky(flip @ jh @ flip)
    u = flip @ low @ flip  # upper triangular, J = U Uᵀ
    ea = u[3, 3]
    un = u / ea
    return np.array([
        math.log(ea), math.log(un[0, 0]), math.log(un[1, 1]), math.log(un[2, 2]),
        un[0, 1], un[1, 2], un[0, 2], un[0, 3], un[1, 3], un[2, 3],
    ])  # fmt: skip


def _com(phi: Array) -> Array:
    return phi[1:4] / phi[0] if phi[0] > 0 else np.zeros(3)


def _mass_com_std(phi: Array, cov: Array) -> tuple[float, Array]:
    """σ_m and σ_c (3,) by the delta method, c = h / m."""
    m = phi[0]
    h = phi[1:4]
    jac = np.zeros((4, 10))
    jac[0, 0] = 1.0
    jac[1:, 0] = -h / m**2
    jac[1:, 1:4] = np.eye(3) / m
    c = jac @ cov @ jac.T
    d = np.sqrt(np.maximum(np.diag(c), 0.0))
    return float(d[0]), d[1:]


def _structural_base(model: Model, layout: RegressorLayout, n_states: int = 120) -> BaseParameters:
    """Base parameters of the base-link regressor from random states (structural, seeded)."""
    rng = np.random.default_rng(20240611)
    lo, hi = model.coordinate_bounds()
    lo = np.maximum(lo, -np.pi)
    hi = np.minimum(hi, np.pi)
    th = rng.uniform(lo, hi, (n_states, model.n_coords))
    thd = rng.normal(size=th.shape)
    thdd = rng.normal(size=th.shape)
    y = base_link_regressor(model, th, thd, thdd, layout=layout)
    return base_parameters(y, layout.parameter_names)


@dataclass(frozen=True)
class MassIdentification:
    """Identified inertial parameters per body (Pinocchio order ``m, mx, my, mz, Ixx, Ixy, Iyy,
    Ixz, Iyz, Izz``), per-segment figures with their status (:func:`segment_summary`), the
    condition number of the identification, the frames used, advice on the motions that would
    excite the rest, and ``t0`` the start (s) of the data identified from."""

    parameters: Mapping[str, np.ndarray]
    segments: Sequence[Mapping[str, Any]]
    condition_number: float
    n_frames: int
    advice: Sequence[str]
    t0: float


def segment_summary(s: Any) -> dict[str, Any]:
    """One identified segment as JSON-ready figures with its :mod:`msk.status` word (a segment
    that moved from its prior without becoming precise is "not determined", never "prior")."""
    from msk.status import segment_status

    out = {
        "name": s.name,
        "mass_kg": s.mass,
        "mass_std_kg": s.mass_std,
        "prior_mass_kg": s.prior_mass,
        "com_m": s.com,
        "com_std_m": s.com_std,
        "prior_com_m": s.prior_com,
        "flag": s.flag,
    }
    out["status"] = segment_status(out).value
    return out


def identified_model(
    model: Any, ident: MassIdentification | None, *, by_status: bool = False
) -> Any:
    """``model`` with the identified inertias (``model`` itself when nothing was identified).

    ``by_status``: only the segments whose status (:func:`segment_summary`, :mod:`msk.status`)
    is ``identified`` take their identified inertia; a segment the data do not determine
    (``not determined``, ``at bound``) or left at its prior keeps ``model``'s — an estimate the
    data do not determine is not used downstream as if they did. ``False``: every identified
    segment, whatever its status."""
    if ident is None:
        return model
    chosen = {b: ident.parameters[b] for b in applied_segments(ident, by_status=by_status)}
    return model.with_inertias(chosen) if chosen else model


def applied_segments(ident: MassIdentification | None, *, by_status: bool = False) -> list[str]:
    """The segments whose identified inertia :func:`identified_model` applies."""
    if ident is None:
        return []
    if not by_status:
        return sorted(ident.parameters)
    identified = {str(s["name"]) for s in ident.segments if s.get("status") == "identified"}
    return sorted(b for b in ident.parameters if b in identified)
