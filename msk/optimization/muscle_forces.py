"""Muscle forces that produce the joint torques, frame by frame, by a registered criterion
(:mod:`msk.optimization.criteria`), on the frames each leg can be solved in.

:func:`solve_muscle_forces` poses, for every usable frame, the tension problem of the model's
muscles with the rigid-tendon force curves of their Hill state (:mod:`msk.muscles.hill`), the
joint torques of inverse dynamics and one reserve actuator per coordinate, and solves it by the
criterion ``[optimization] method`` names:

- ``static_optimization``: min Σ w_i a_i^p with activation bounds (Crowninshield & Brand 1981;
  w_i = V_i, the muscle volume, with ``activation_weights = "volume"``, Happee 1994);
- ``bounded_qp``: min Σ (F_i/F_iso,i)² with 0 ≤ F ≤ F_max;
- ``emg_weighted``: the EMG-weighted tension optimisation of Hayashibe et al. (2011, Eq. 17–18,
  with the EMG-based reference force of their Eq. 9);
- ``emg_assisted``: min Σ a_i² + w Σ (a_i − g_c ê_i)² with one gain per EMG channel, fitted on
  the trial's torques (at most :data:`GAIN_FIT_FRAMES` evenly spaced frames);
- ``closed_form``: the unbounded Lagrange-multiplier solution F = W Cᵀ (C W Cᵀ)⁻¹ τ
  (:mod:`msk.optimization.closed_form`).

A leg whose foot stands off the plates in a frame is left out of that frame's problem
(:func:`left_out`): every criterion's cost is a sum over muscles and reserves with one equality
row or torque penalty per coordinate, so the rest is solved exactly as the whole frame would be.
Long trials are solved block by block (:mod:`msk._runtime.blocks`), never holding a dense
(N, muscles, coordinates) Jacobian.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from msk._runtime.blocks import frame_blocks, solve_parts
from msk.exceptions import NotAvailableError
from msk.results.summary import Kkt, KktFigure, Optimization

if TYPE_CHECKING:
    from msk.config.options import OptimizationConfig
    from msk.muscles.emg import EmgActivations

__all__ = [
    "FRONTAL_RESERVE_OPTIMAL_NM",
    "GAIN_FIT_FRAMES",
    "KktWorst",
    "KneeCompartments",
    "MuscleForces",
    "actuated",
    "fit_frames",
    "frames_solved",
    "kkt_summary",
    "knee_compartments",
    "left_out",
    "left_out_patterns",
    "optimization_summary",
    "solve_muscle_forces",
    "worst_kkt",
]


@dataclass(frozen=True)
class MuscleForces:
    """Muscle forces (N) and activations (N, m) on the kinematics' time base (NaN on frames not
    optimised), the method and its criterion in words, the frames that could not be posed
    (``excluded_frames``, with the reason), the EMG gains of ``emg_assisted``, the infeasible
    frames and the reserve torques (N, coordinates) of the QP methods (None for
    ``closed_form``). With ``[optimization] compartment_nonnegative``: the frontal reserve
    moments (N, 2) N·m of the knee's medial and lateral rows (``compartment_rows``; the
    moment about the opposite contact point that no admissible tension balances, which
    ligaments would carry), the largest frontal moment of the inverse-dynamics load about the
    contact midpoint over the solved frames (``id_frontal_moment_peak_nm``, the reference of
    the quality gate). The QP methods' KKT check of the frames the solver called optimal
    (:class:`KktWorst`, None for ``closed_form`` or without such a frame)."""

    forces: np.ndarray
    activations: np.ndarray
    muscles: tuple[str, ...]
    method: str
    excluded_frames: int
    excluded_reason: str | None = None
    criterion: str | None = None
    emg_gains: Mapping[str, float] | None = None
    infeasible_frames: int | None = None
    reserve_torques: np.ndarray | None = None
    reserve_coordinates: tuple[str, ...] | None = None
    frontal_reserve_moments: np.ndarray | None = None
    compartment_rows: tuple[str, ...] = ()
    id_frontal_moment_peak_nm: float | None = None
    kkt: KktWorst | None = None


@dataclass(frozen=True)
class KktWorst:
    """The worst KKT figures of a trial's tension QPs over the frames the solver called
    optimal (the infeasible frames, whose bounded least-squares point is no optimum, are left
    out: flagged apart): per figure of ``columns`` (:data:`msk.optimization.KKT_COLUMNS`) the
    largest value ``value`` (scaled variables of the standard form), the largest value
    relative to its scale ``relative`` (:func:`msk.optimization.kkt_scale`: the gradient's
    magnitude, the right-hand sides' for primal feasibility) and the frame ``frame`` (index on
    the kinematics' time base) and ``time_s`` where that relative value is reached;
    ``frames`` the number of frames checked."""

    columns: tuple[str, ...]
    value: np.ndarray
    relative: np.ndarray
    frame: np.ndarray
    time_s: np.ndarray
    frames: int


def worst_kkt(
    kkt: np.ndarray, scale: np.ndarray, optimal: np.ndarray, frames: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Of one solve block: per KKT figure the largest value, the largest relative value and
    its frame (from ``frames``) over the rows ``optimal`` with finite figures (−1 and 0
    without any), and how many rows were checked."""
    use = optimal & np.isfinite(kkt).all(axis=1) & np.isfinite(scale).all(axis=1)
    if not use.any():
        return np.zeros(4), np.zeros(4), np.full(4, -1), 0
    rel = kkt[use] / scale[use]
    at = np.argmax(rel, axis=0)
    return kkt[use].max(axis=0), rel[at, np.arange(4)], frames[use][at], int(use.sum())


def left_out(pattern: np.ndarray, unbalanced: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The muscles (m,) and coordinates (n,) left out of a frame's tension QP when the
    coordinates ``unbalanced`` (n,) balance a missing ground reaction: the connected components
    of the graph joining a muscle to the coordinates it has a moment arm about (``pattern``
    (m, n), in any frame) that hold an unbalanced coordinate. Every criterion here sums its
    cost over muscles and reserves (Crowninshield & Brand 1981; Hayashibe et al. 2011, Eq. 17,
    whose ‖R f − τ‖² couples only muscles sharing a coordinate) with one equality row or torque
    penalty per coordinate, so the other components are independent sub-problems."""
    pattern = np.asarray(pattern, dtype=bool)
    coords = np.asarray(unbalanced, dtype=bool).copy()
    while True:
        muscles = np.asarray(pattern[:, coords].any(axis=1))
        grown = coords | pattern[muscles].any(axis=0)
        if (grown == coords).all():
            return muscles, coords
        coords = grown


def left_out_patterns(
    geometry: Any,
    params: Any,
    tau: np.ndarray,
    act_idx: list[int],
    usable: np.ndarray,
    posable: np.ndarray,
    miss: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The left-out legs of the ``usable`` frames (:func:`left_out`): the muscles (P, m) and
    coordinates (P, len(act_idx)) each distinct pattern leaves out (row 0: nothing, the fully
    measured frames'), each frame's pattern (N,) and the frames posable (N,): ``posable``
    (the whole frame's geometry, force curves and torques finite) or, for a frame with a leg
    left out, finite in the part kept (the left-out part's are never read). ``miss`` (N,
    len(act_idx)): per frame the coordinates whose torque balances a missing ground
    reaction; ``tau`` the joint torques (N, coordinates), ``act_idx`` the actuated columns.
    The muscles' moment-arm pattern is read on the frames posable whole."""
    from msk.muscles.geometry import jacobian_frames, moment_arm_pattern

    n_all = miss.shape[0]
    n_mus = len(params.names)
    # the distinct patterns ``drops`` (0: nothing left out) and each frame's index into them
    drops: list[tuple[np.ndarray, np.ndarray]] = [
        (np.zeros(n_mus, dtype=bool), np.zeros(len(act_idx), dtype=bool))
    ]
    drop_id = np.zeros(n_all, dtype=np.intp)
    retry = usable & ~posable & miss.any(axis=1)
    ok = usable & posable
    if miss[ok | retry].any():
        pattern = moment_arm_pattern(geometry.jacobian, ok, act_idx)
        both = ok | retry
        distinct, inv = np.unique(miss[both], axis=0, return_inverse=True)
        ids = np.zeros(distinct.shape[0], dtype=np.intp)
        for u, row in enumerate(distinct):
            if row.any():
                ids[u] = len(drops)
                drops.append(left_out(pattern, row))
        drop_id[both] = ids[np.asarray(inv).reshape(-1)]
    drop_m = np.array([d[0] for d in drops])  # (patterns, m)
    drop_c = np.array([d[1] for d in drops])  # (patterns, coordinates)
    # a frame with a leg left out that is not posable whole is when what is not posable lies
    # in the left-out part (its geometry, curves or torques are never read)
    posable = posable.copy()
    for fr in frame_blocks(np.flatnonzero(retry)) if retry.any() else ():
        gone_m, gone_c = drop_m[drop_id[fr]], drop_c[drop_id[fr]]
        jac = jacobian_frames(geometry.jacobian, fr, act_idx)
        fa, fp = _force_curves(params, geometry, fr)
        kept = (
            (np.isfinite(jac) | gone_m[:, :, None] | gone_c[:, None, :]).all(axis=(1, 2))
            & ((np.isfinite(fa) & np.isfinite(fp)) | gone_m).all(axis=1)
            & (np.isfinite(tau[fr][:, act_idx]) | gone_c).all(axis=1)
        )
        posable[fr[kept]] = True
        del jac, fa, fp
    return drop_m, drop_c, drop_id, posable


def actuated(torques: Any) -> list[int]:
    """Columns of the joint torques that muscles actuate (every coordinate but the root's)."""
    root = tuple(torques.root_coordinates)
    return [i for i, c in enumerate(torques.coordinate_names) if c not in root]


#: at most this many frames (evenly spaced over the trial) fit the EMG gains of ``emg_assisted``
GAIN_FIT_FRAMES = 4096


def fit_frames(frames: np.ndarray) -> np.ndarray:
    """The frames the EMG gains of ``emg_assisted`` are fitted on: all of ``frames`` up to
    :data:`GAIN_FIT_FRAMES`, else that many evenly spaced ones (one scalar per channel: every
    part of a long trial is represented, memory and time bounded; the solve then runs on every
    frame, block by block)."""
    if frames.size <= GAIN_FIT_FRAMES:
        return frames
    return frames[np.linspace(0, frames.size - 1, GAIN_FIT_FRAMES).round().astype(np.intp)]


def _emg_gains(
    channels: Mapping[str, str],
    w_track: float,
    jac: np.ndarray,
    tq: np.ndarray,
    fa: np.ndarray,
    fp: np.ndarray,
    emg_act: np.ndarray,
    measured: np.ndarray,
    names: tuple[str, ...],
    weights: np.ndarray | None,
    reserves: np.ndarray,
    coordinate_names: tuple[str, ...],
    common: bool = False,
) -> Any:
    """One EMG-to-activation gain per EMG channel of ``emg_assisted`` (``common``: one gain
    shared by every channel, ``[optimization] emg_gains = "common"``), fitted jointly with the
    activations on these frames' torques (:func:`msk.strength.fit_emg_gains`); only channels
    with signal on these frames take part (None when no channel has: the criterion is then
    static optimisation with exponent 2).

    Per channel, the joint minimum sets an antagonist's gain to the least-squares scale of the
    activation the torques need from it — near 0, since no torque needs co-contraction — so
    its measured activity is discarded. One common gain is fixed by the agonists and keeps
    each channel's normalised level (Lloyd & Besier 2003, J Biomech 36:765: per-channel
    normalisation, shared activation parameters)."""
    from msk.strength import fit_emg_gains

    groups: dict[str, list[str]] = {}
    for k, n in enumerate(names):
        if measured[k] and np.any(emg_act[:, k] > 0):
            groups.setdefault("all" if common else channels[n], []).append(n)
    if not groups:
        return None
    return fit_emg_gains(
        jac, tq, f_active=fa, f_passive=fp, emg_activation=emg_act, groups=groups,
        muscle_names=names, w_track=w_track,
        activation_weights=weights, reserve_optimal_force=reserves,
        coordinate_names=coordinate_names,
    )  # fmt: skip


def _force_curves(params: Any, geometry: Any, frames: Any) -> tuple[np.ndarray, np.ndarray]:
    """f_active (its negative extrapolation clipped to 0) and f_passive along the tendon of the
    rigid-tendon Hill state on the geometry's ``frames`` (a slice or indices), (n, m) each."""
    from msk.muscles.hill import rigid_tendon_state

    vel = None if geometry.velocities is None else geometry.velocities[frames]
    state = rigid_tendon_state(params, geometry.lengths[frames], vel)
    fmax = state.max_active_force_along_tendon
    return np.where(fmax < 0, 0.0, fmax), state.passive_force_along_tendon


#: optimal moment of the frontal reserves of ``compartment_nonnegative`` (N·m): a reserve of
#: 1 N·m costs as much as a fully active muscle, as the coordinate reserves (optimal torque 1)
FRONTAL_RESERVE_OPTIMAL_NM = 1.0


@dataclass(frozen=True)
class KneeCompartments:
    """What the knee compartment rows of one model need: the knee, its contact points, the
    geometry plan for its unit wrenches, and the kinematics and external loads they are
    evaluated on (:func:`msk.contact.knee.compartment_force_map`)."""

    joint: str
    geometry: Any
    plan: Any
    kinematics: Any
    external: Any
    patella: bool = False

    def rows(
        self, model: Any, fr: np.ndarray, names: tuple[str, ...], keep: np.ndarray | None = None
    ) -> tuple[Any, float]:
        """The rows ``d·F_M(f) + s_M ≥ 0``, ``d·F_L(f) + s_L ≥ 0`` (N·m: d·F_L is the frontal
        moment about the medial contact point, Winby et al. 2009) on frames ``fr`` and the
        largest |frontal moment| of the inverse-dynamics load there (N·m; over the frames
        ``keep`` (bool, like ``fr``) alone when given: those whose knee is solved). A frame
        whose map is not finite gets the trivial row 0 ≥ 0."""
        from msk.contact.knee import compartment_force_map
        from msk.optimization import TensionInequalities

        w = self.plan.evaluate(
            self.kinematics.q[fr], distal_wrench_joints=(self.joint,), compact=True
        )
        ext = None if self.external is None else self.external.take(fr)
        tendon = jk = None
        if self.patella:
            from msk.contact.patella import patellar_tendon

            tendon = patellar_tendon(model, joint=self.joint)
            jk = np.asarray(w.jacobian[:])[:, :, model.coordinate_index(tendon.coordinate)]
        cmap = compartment_force_map(
            model, self.kinematics.take(fr), ext, joint=self.joint, geometry=self.geometry,
            distal_wrenches=w.distal_wrenches[self.joint], patella=tendon, knee_jacobian=jk,
        )  # fmt: skip
        if cmap.muscle_names != tuple(names):
            raise NotAvailableError("compartment rows: muscle order differs from the QP's")
        d = self.geometry.intercondylar_distance_m
        off, gain = d * cmap.offset, d * cmap.gain
        bad = ~(np.isfinite(off).all(axis=1) & np.isfinite(gain).all(axis=(1, 2)))
        off[bad], gain[bad] = 0.0, 0.0
        # the frontal moment about the midpoint: d (F_L − F_M)/2 on a right knee (sign aside)
        mom = np.abs(off[:, 1] - off[:, 0]) if keep is None else np.abs(off[keep, 1] - off[keep, 0])
        peak = float(np.max(mom, initial=0.0)) / 2.0
        rows = TensionInequalities(
            off, gain, (f"{self.joint}_medial", f"{self.joint}_lateral"),
            FRONTAL_RESERVE_OPTIMAL_NM,
        )  # fmt: skip
        return rows, peak


def knee_compartments(
    model: Any, kinematics: Any, external: Any, *, joint: str, plateau: Any, patella: bool = False
) -> KneeCompartments:
    """The knee compartment rows F_M(f) ≥ 0, F_L(f) ≥ 0 of ``joint`` with its two contact points
    ``plateau`` (:func:`msk.contact.knee.plateau_geometry`, as the knee contact's split places
    them), evaluated on ``kinematics`` and ``external`` (:class:`NotAvailableError` when the model
    has no such joint). ``patella``: the quadriceps load the knee through the patellar tendon
    (:mod:`msk.contact.patella`), as the knee contact does."""
    from msk.muscles.geometry import geometry_plan

    if joint not in {j.name for j in model.joints}:
        raise NotAvailableError(f"compartment_nonnegative: model has no joint {joint!r}")
    return KneeCompartments(
        joint, plateau, geometry_plan(model), kinematics, external, patella=patella
    )


@dataclass(frozen=True)
class _Kept:
    """What one left-out pattern keeps of a frame's tension QP (:func:`left_out_patterns`):
    the muscles ``muscles`` (m,) and actuated coordinates ``coordinates`` kept (None: every
    one, the fully measured frames' pattern), their Jacobian ``columns``, names, activation
    weights and reserve optimal forces, whether the compartment rows' knee is left out
    (``knee_out``: no rows, no frontal reserve or peak), and the pattern's warm start (its
    QPs have their own unknowns; the fully measured frames continue from one another as in
    one call on them all)."""

    muscles: np.ndarray | None
    coordinates: np.ndarray | None
    columns: list[int] | np.ndarray
    muscle_names: tuple[str, ...]
    coordinate_names: tuple[str, ...]
    activation_weights: np.ndarray | None
    reserve_optimal_force: np.ndarray
    knee_out: bool
    warm: Any

    def kept(self, x: np.ndarray) -> np.ndarray:
        """``x``'s kept muscles (its last axis: (m,), (frames, m) or (frames, rows, m))."""
        return x if self.muscles is None else x[..., self.muscles]

    def widen_muscles(self, x: np.ndarray) -> np.ndarray:
        """``x`` (frames, kept muscles) in every muscle's column, NaN in the left-out ones."""
        return _widen(x, self.muscles)

    def widen_coordinates(self, x: np.ndarray) -> np.ndarray:
        """``x`` (frames, kept coordinates) in every actuated coordinate's column, NaN in the
        left-out ones."""
        return _widen(x, self.coordinates)


def _widen(x: np.ndarray, keep: np.ndarray | None) -> np.ndarray:
    """``x`` (frames, kept columns) in ``keep.size`` columns, NaN in the left-out ones (``x``
    itself when every column is kept: None)."""
    if keep is None:
        return x
    out = np.full((x.shape[0], keep.size), np.nan)
    out[:, keep] = x
    return out


def solve_muscle_forces(
    model: Any,
    torques: Any,
    geometry: Any,
    time: np.ndarray,
    usable: np.ndarray,
    emg: EmgActivations | None,
    *,
    options: OptimizationConfig,
    emg_channels: Mapping[str, str] | None = None,
    knee_joint: str | None = None,
    knee_plateau: Any = None,
    knee_patella: bool = False,
    forces_only: bool = False,
    on_block: Callable[[np.ndarray, np.ndarray], None] | None = None,
    kinematics: Any = None,
    external: Any = None,
    unbalanced: np.ndarray | None = None,
) -> MuscleForces:
    """Muscle forces of ``model`` for ``torques`` by the criterion ``options.method`` (a
    registered :class:`msk.optimization.criteria.Criterion`) on the ``usable`` frames. A frame
    whose inputs cannot be posed (non-finite geometry or torques, negative
    active force) is excluded and reported, never allowed to abort the whole stage; a muscle
    shortening faster than its maximal velocity produces no active force (the force–velocity
    curve's extrapolation below zero is clipped to 0 rather than costing the frame).

    ``forces_only`` (a re-solve that reads the forces alone): no KKT check, and the
    activations and reserve torques are not kept — ``activations`` is then ``(N, 0)`` and
    ``reserve_torques`` None — so that a long trial does not hold them .

    ``on_block(frames, forces)``: each solve block's frames (indices) and forces are handed to
    it as they are solved, and not kept — it implies ``forces_only``, and ``forces`` is then
    ``(N, 0)`` too (the knee contact stage computes its contact block by block: a long trial
    never holds the re-solve's forces whole).

    ``emg_channels`` (model muscle → EMG channel): the groups of the EMG gains of
    ``emg_assisted`` (one gain per channel).

    ``kinematics``, ``external`` (the trial's kinematics and external loads), ``knee_joint``
    and ``knee_plateau`` (its two contact points): needed with ``options.compartment_nonnegative``,
    which adds to every frame's QP the rows F_M(f) ≥ 0 and F_L(f) ≥ 0 of that knee
    (:func:`knee_compartments`), each with a frontal reserve moment ≥ 0 priced as a coordinate
    reserve. ``knee_patella``: those rows with the quadriceps acting through the patellar
    tendon (:mod:`msk.contact.patella`), as ``[contact] patella = "tendon"`` has the contact.

    ``unbalanced`` (N, coordinates of ``torques``; the loads stage's,
    :meth:`msk.pipeline.loads.Loads.unbalanced_for`): per frame the coordinates whose torque
    balances a missing ground reaction (a leg whose foot stands off the plates). The muscles
    and coordinates of the independent sub-problems holding them (:func:`left_out`: that leg)
    are left out of that frame — their forces, activations and reserve torques NaN — and the
    rest solved: each criterion's cost is a sum over muscles and reserves and each equality
    row a coordinate's, so the rest's solution is that of the whole frame's QP
    (``tests/optimization/test_muscle_forces.py`` checks each criterion). The left-out part is not
    posed: such a frame's QP holds the kept muscles and coordinates only (and the compartment
    rows only when their knee is kept), so the infeasible count, the KKT figures, the
    reserves and the activations describe what was solved; a frame is posable when the kept
    part's geometry, force curves and torques are finite. The EMG gains of ``emg_assisted``
    are fitted with the left-out rows at zero torque and zero EMG, which add nothing to the
    gains (g_c = Σ a ê / Σ ê²): each leg's channels on the frames it is solved in (the other
    leg's gains equal the fully measured trial's to the fit's tolerance); nothing of that
    fit's solution is reported."""
    import msk.optimization as o
    from msk.muscles.geometry import finite_frames, jacobian_frames, muscle_parameters
    from msk.optimization.criteria import BlockProblem, criterion

    act_idx = actuated(torques)
    params = muscle_parameters(model)
    # the Hill state block by block (its many (N, m) arrays are never held whole); here only
    # whether each frame's force curves are finite — the solves below recompute f_active and
    # f_passive for their own frames (elementwise: the same numbers), so that no (N, m) array
    # of them is held through the solves
    n_all = geometry.lengths.shape[0]
    curves_finite = np.zeros(n_all, dtype=bool)
    for fr in frame_blocks(n_all):
        sl = slice(int(fr[0]), int(fr[-1]) + 1) if fr.size else slice(0, 0)
        fa, fp = _force_curves(params, geometry, sl)
        curves_finite[sl] = np.isfinite(fa).all(axis=1) & np.isfinite(fp).all(axis=1)
        del fa, fp
    # the coordinates whose torque balances a missing ground reaction (the other legs' are
    # solved without them); their torques need not be finite
    miss = (
        np.zeros((n_all, len(act_idx)), dtype=bool)
        if unbalanced is None
        else np.asarray(unbalanced, dtype=bool)[:, act_idx]
    )
    posable = (
        finite_frames(geometry.jacobian, act_idx)
        & (np.isfinite(torques.tau[:, act_idx]) | miss).all(axis=1)
        & curves_finite
    )
    # per frame: the muscles and coordinates left out (the components holding an unbalanced
    # coordinate), as an index into the distinct patterns (0: nothing left out)
    drop_m, drop_c, drop_id, posable = left_out_patterns(
        geometry, params, torques.tau, act_idx, usable, posable, miss
    )
    ok = usable & posable
    # a frame whose every coordinate is left out has nothing to solve
    ok &= ~np.asarray(drop_c.all(axis=1))[drop_id]
    if not ok.any():  # e.g. a trial no foot stands on a plate in: a reason, not a traceback
        raise NotAvailableError(
            "no frame to optimise: none in which the plates measure a leg's foot contact (or "
            "it swings) and the markers observe every leg segment"
            + (f" ({int(usable.sum())} such frames, none posable)" if usable.any() else "")
        )
    excluded = int((usable & ~posable).sum())
    cn = tuple(torques.coordinate_names[i] for i in act_idx)
    reserves = np.ones(len(act_idx))
    opt = options
    meth = opt.method
    crit = criterion(meth)
    weights = (  # activation weights of static_optimization and emg_assisted
        o.volume_weights(params.max_isometric_force, params.optimal_fiber_length)
        if opt.activation_weights == "volume"
        else None
    )
    meas = None
    if crit.reads_emg:
        if emg is None:
            raise NotAvailableError(f"{meth} needs the EMG stage")
        meas = np.array(
            [n in emg.muscles and bool(emg.usable[emg.column(n)]) for n in params.names]
        )
    idx_ok = np.flatnonzero(ok)

    def emg_reference(fr: np.ndarray) -> np.ndarray:
        """EMG activation of each measured muscle's channel on frames ``fr`` (0 elsewhere)."""
        assert emg is not None and meas is not None
        a = np.zeros((fr.size, len(params.names)))
        for k, name in enumerate(params.names):
            if meas[k]:
                a[:, k] = emg.activation[fr, emg.column(name)]
        return a

    comp = None
    if opt.compartment_nonnegative and crit.quadratic:
        if kinematics is None or knee_joint is None:
            raise NotAvailableError("compartment_nonnegative needs the kinematics, loads and knee")
        comp = knee_compartments(
            model, kinematics, external, joint=knee_joint, plateau=knee_plateau,
            patella=knee_patella,
        )  # fmt: skip
    frontal = None if comp is None else np.full((time.size, 2), np.nan)
    # per pattern: whether the compartment rows' knee is left out (a coordinate between its
    # tibia and the root is): no frontal reserve or peak from such a frame
    knee_out = np.zeros(drop_c.shape[0], dtype=bool)
    if comp is not None:
        from msk.dynamics.inverse import coordinates_carrying

        child = next(j.child for j in model.joints if j.name == comp.joint)
        above = set(coordinates_carrying(model, child))
        knee_out = np.asarray(drop_c[:, [k for k, c in enumerate(cn) if c in above]].any(axis=1))
    id_peak = 0.0
    gain_fit = None
    if crit.fits_emg_gains:  # gains first (on a bounded frame sample), then every block
        assert meas is not None
        fit_fr = fit_frames(idx_ok)
        fa, fp = _force_curves(params, geometry, fit_fr)
        # a left-out leg's rows posed with zero torque and zero EMG: they add nothing to its
        # channels' gains (g_c = Σ a ê / Σ ê², msk.strength.fit_emg_gains), fitted on the
        # frames that leg is solved in
        gone = drop_id[fit_fr]
        gain_fit = _emg_gains(
            dict(emg_channels or {}), opt.w_track,
            jacobian_frames(geometry.jacobian, fit_fr, act_idx),
            np.where(drop_c[gone], 0.0, torques.tau[fit_fr][:, act_idx]), fa, fp,
            np.where(drop_m[gone], 0.0, emg_reference(fit_fr)), meas, params.names, weights,
            reserves, cn, common=opt.emg_gains == "common",
        )  # fmt: skip
        del fa, fp
        if gain_fit is not None:  # the fit's last a-step (its frames' solution) is not read
            gain_fit = dataclasses.replace(gain_fit, solution=None)
    gains = (
        None if gain_fit is None else dict(zip(gain_fit.group_names, map(float, gain_fit.gains)))
    )
    # each pattern's kept part (pattern 0, the fully measured frames', keeps every one)
    subs: list[_Kept] = []
    for pid in range(drop_m.shape[0]):
        km = None if pid == 0 else ~drop_m[pid]
        kc = None if pid == 0 else ~drop_c[pid]
        subs.append(_Kept(
            km, kc, act_idx if kc is None else np.asarray(act_idx)[kc],
            params.names if km is None else tuple(np.asarray(params.names, dtype=object)[km]),
            tuple(cn[k] for k in np.flatnonzero(~drop_c[pid])),
            weights if weights is None or km is None else weights[km],
            reserves if kc is None else reserves[kc], bool(knee_out[pid]), o.WarmStart(),
        ))  # fmt: skip
    n = time.size
    forces_only = forces_only or on_block is not None
    # filled block by block (no list of every block's forces concatenated at the end)
    f_all = np.full((n, 0 if on_block is not None else len(params.names)), np.nan)
    a_all = np.full((n, 0 if forces_only else len(params.names)), np.nan)
    rt = None if forces_only else np.full((n, len(act_idx)), np.nan)
    infeasible = 0
    kkt_val, kkt_rel = np.zeros(4), np.full(4, -1.0)
    kkt_at, kkt_n = np.full(4, -1), 0

    def solve(fr: np.ndarray, sub: _Kept, ineq: Any) -> tuple[np.ndarray, Any, Any]:
        """Forces, activations and the batch solution (None for ``closed_form``) of the frames
        ``fr``, all of one left-out pattern: the QP of the muscles and coordinates ``sub``
        keeps — the left-out leg is not posed at all — with the compartment rows ``ineq`` of
        those frames (None: without), warm-started from that pattern's last call."""
        jac = jacobian_frames(geometry.jacobian, fr, sub.columns)
        tq = torques.tau[fr][:, sub.columns]
        fa, fp = _force_curves(params, geometry, fr)
        if sub.muscles is not None:
            jac, fa, fp = jac[:, sub.muscles], fa[:, sub.muscles], fp[:, sub.muscles]
        names, w_act, res_opt = sub.muscle_names, sub.activation_weights, sub.reserve_optimal_force
        carry, kept = sub.warm, sub.kept
        common: dict[str, Any] = {
            "time": time[fr],
            # a re-solve that reads the forces alone does not check them
            "compute_kkt": not forces_only,
            "muscle_names": names,
            "coordinate_names": sub.coordinate_names,
        }
        if ineq is not None and sub.muscles is not None:  # the kept muscles' gains
            ineq = o.TensionInequalities(
                ineq.offset, kept(np.asarray(ineq.gain)), ineq.names, ineq.reserve_optimal
            )
        if ineq is not None:
            common["inequalities"] = ineq

        problem = BlockProblem(
            jac, tq, fa, fp, params.max_isometric_force, w_act, res_opt, carry, common, kept,
            emg_activation=emg_reference(fr) if crit.reads_emg else None,
            measured=meas, gains=gain_fit,
        )  # fmt: skip
        return crit.solve(problem, opt)

    # with the knee compartment rows a block is solved in parts of SOLVE_BLOCK frames (its
    # Jacobian and the solver's arrays are a part's, and the rows' per-frame arrays),
    # the warm start carried from part to part; each frame's QP is the same as in one call
    # (the sub-problem split follows the muscles' moment-arm pattern, the same in every part
    # of a trial in practice: tests/pipeline/test_long_trials.py checks gc5_PS in 16-frame parts
    # equal
    # to one call bit for bit). A block's frames are solved pattern by pattern of left-out
    # legs (the fully measured frames first, then each pattern's own smaller QP).
    split = comp is not None
    for fr in frame_blocks(idx_ok):
        rows = None
        if comp is not None:  # never with closed_form (comp is built for the QP methods)
            # the block's geometry pass (its wrapped paths iterate the block's frames together),
            # before the block's Jacobian is read
            rows, peak = comp.rows(model, fr, tuple(params.names), keep=~knee_out[drop_id[fr]])
            id_peak = max(id_peak, peak)
        block_forces = None if on_block is None else np.empty((fr.size, len(params.names)))
        pids = drop_id[fr]
        for pid in np.unique(pids).tolist():
            # positions in the block: a slice when the whole block has this pattern (the calls
            # of a trial without left-out legs are those of one pattern, as before)
            where: slice | np.ndarray = (
                slice(0, fr.size) if (pids == pid).all() else np.flatnonzero(pids == pid)
            )
            n_here = fr[where].size
            sub = subs[pid]
            for part in solve_parts(n_here) if split else [slice(0, n_here)]:
                at = part if isinstance(where, slice) else where[part]
                f_idx = fr[at]
                ineq = None if rows is None or sub.knee_out else rows.take(at)
                forces, acts, sol = solve(f_idx, sub, ineq)
                forces = sub.widen_muscles(forces)
                if block_forces is not None:
                    block_forces[at] = forces
                else:
                    f_all[f_idx] = forces
                if not forces_only:
                    a_all[f_idx] = sub.widen_muscles(acts)
                if sol is not None:
                    if rt is not None:
                        rt[f_idx] = sub.widen_coordinates(sol.reserve_torques)
                    if frontal is not None and sol.inequality_reserves is not None:
                        frontal[f_idx] = sol.inequality_reserves
                    infeasible += int(sol.infeasible_frames.size)
                    if sol.kkt_scale is not None:
                        v, r, at_k, n_ok = worst_kkt(
                            sol.kkt, sol.kkt_scale, sol.status == o.STATUS_OPTIMAL, f_idx
                        )
                        kkt_val, kkt_n = np.maximum(kkt_val, v), kkt_n + n_ok
                        better = r > kkt_rel
                        kkt_rel = np.where(better, r, kkt_rel)
                        kkt_at = np.where(better, at_k, kkt_at)
                del sol, forces, acts
        if on_block is not None:
            assert block_forces is not None
            on_block(fr, block_forces)
        del rows, block_forces
    described = crit.describe(opt, gains_fitted=gain_fit is not None)
    out = MuscleForces(
        f_all, a_all, tuple(params.names), meth, excluded,
        "non-finite geometry, torque or muscle force curves" if excluded else None,
        described, gains,
    )  # fmt: skip
    if not crit.quadratic:
        return out
    worst = None
    if kkt_n:
        worst = KktWorst(
            o.KKT_COLUMNS, kkt_val, kkt_rel, kkt_at, np.asarray(time, dtype=float)[kkt_at], kkt_n
        )
    out = dataclasses.replace(
        out, infeasible_frames=infeasible, reserve_torques=rt, reserve_coordinates=cn, kkt=worst
    )
    if comp is None:
        return out
    if described is not None:
        described += "; knee compartments F_M, F_L ≥ 0 (frontal reserve moments penalised)"
    return dataclasses.replace(
        out, criterion=described, frontal_reserve_moments=frontal,
        compartment_rows=(f"{comp.joint}_medial", f"{comp.joint}_lateral"),
        id_frontal_moment_peak_nm=id_peak,
    )  # fmt: skip


def frames_solved(sol: MuscleForces) -> dict[str, int]:
    """Per leg (the side suffix ``r``/``l`` of the muscles' names) the frames in which every
    muscle of that leg has a force (the tension stage leaves a leg out where its foot stands
    off the plates, :func:`solve_muscle_forces`)."""
    out = {}
    for side in ("r", "l"):
        cols = [k for k, n in enumerate(sol.muscles) if n.endswith(f"_{side}")]
        if cols and sol.forces.shape[1]:
            out[side] = int(np.isfinite(sol.forces[:, cols]).all(axis=1).sum())
    return out


def kkt_summary(worst: KktWorst) -> Kkt:
    """``summary.optimization.kkt`` of a :class:`KktWorst`: the frames checked, the relative
    tolerance of the quality gate (:data:`msk.quality.THRESHOLDS` ``kkt_relative``) and per
    figure its largest value, largest relative value and where."""
    from msk.quality import THRESHOLDS

    return Kkt(
        frames=int(worst.frames),
        relative_tolerance=THRESHOLDS["kkt_relative"],
        **{
            c: KktFigure(
                max=float(worst.value[k]),
                relative_max=float(worst.relative[k]),
                frame=int(worst.frame[k]),
                time_s=float(worst.time_s[k]),
            )
            for k, c in enumerate(worst.columns)
        },
    )


def optimization_summary(sol: MuscleForces, sfx: str) -> Optimization:
    """``summary.optimization`` of a tension result: method, criterion, the EMG gains and their
    :mod:`msk.status` words (:func:`msk.status.gain_status`), infeasible frames,
    :func:`frames_solved`, the RMS of the reserve torques of the analysed side's coordinates
    (suffix ``sfx``), :func:`kkt_summary` and the knee's frontal-plane reserve moments
    (:func:`msk.quality.frontal_reserve_figures`)."""
    from msk.quality import frontal_reserve_figures
    from msk.status import gain_status

    return Optimization(
        method=sol.method,
        criterion=sol.criterion,
        emg_gains=None if sol.emg_gains is None else dict(sol.emg_gains),
        emg_gain_status=None
        if not sol.emg_gains
        else {c: gain_status(float(g)).value for c, g in sol.emg_gains.items()},
        infeasible_frames=sol.infeasible_frames,
        frames_solved=frames_solved(sol),
        reserve_torque_rms_nm=None
        if sol.reserve_torques is None or sol.reserve_coordinates is None
        else {
            c: float(np.sqrt(np.nanmean(sol.reserve_torques[:, k] ** 2)))
            for k, c in enumerate(sol.reserve_coordinates)
            if c.endswith(sfx)
        },
        kkt=None if sol.kkt is None else kkt_summary(sol.kkt),
        frontal_reserve=None
        if sol.frontal_reserve_moments is None
        else {
            "id_frontal_moment_peak_nm": sol.id_frontal_moment_peak_nm or 0.0,
            **frontal_reserve_figures(sol),
        },
    )
