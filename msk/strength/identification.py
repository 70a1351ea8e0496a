"""Muscle-strength identification by regression on the net contribution matrix
(Hayashibe et al. 2011, §V).

Per muscle k and coordinate j (Hayashibe et al. 2011, Eq. 12–14)::

    τ_k = −J_kᵀ f_k = [−J_kᵀ a_k f_l(l_k) f_v(l̇_k)] F_iso,k = C_k F_iso,k            (Eq. 12–14)

with J = ∂l/∂θ (Hayashibe et al. 2011, Eq. 6, shape ``(N, M, n)``), a_k the EMG-driven activation
and f_l, f_v the normalised force–length and force–velocity factors of the muscle state
(:func:`msk.muscles.hill.rigid_tendon_state`; its ``cos α`` is included so that the force is
along the tendon, and with ``passive=True`` the passive fibre force ``F_iso f_P cos α`` — which
also scales with F_iso — is added to the activation term:
``C_k = −J_kᵀ (a_k f_l f_v + f_P) cos α``).

**Synergist groups.** One EMG electrode drives a group g of muscles with a common activity
level (Hayashibe et al. 2011, §V, "muscle grouping in stretch reflex"), and the unknown is the
group's strength factor s_g: ``F_iso,k = s_g F_iso,k^generic`` for k ∈ g. With
``C_g = Σ_{k∈g} C_k F_iso,k^generic`` the j-th torque reads (Hayashibe et al. 2011, Eq. 15–16)::

    τ(j) = Σ_{g ∈ G_emg} s_g C_g(j) + Σ_{k ∉ G_emg} C_k(j) F_iso,k^generic + d_j           (Eq. 16)

where d_j is the constant residual term (contributions of elements that are not modelled: deep
muscles without EMG, ligaments, residual inertial errors). Muscles outside every group keep their
generic strength and their generic contribution is subtracted from τ.

**Correlation gating** (Hayashibe et al. 2011, §VI.C: "correlation analysis in the level of the net
contribution matrix was performed to judge which EMG-measured synergist muscle group have enough
correlation and contribute to the torque production"). The trial is cut into windows (cycles,
trials or fixed-length chunks). In window w, for coordinate j:

* r_{w,g,j} = Pearson(C_g(j), τ(j)) for every group — the per-group gating figure;
* R_{w,j} = multiple correlation of τ(j) with its least-squares fit by ``[C_g(j)]_g`` and a
  constant (how well the EMG-measured groups explain the torque in this window; the square root
  of the adjusted R², so that short windows with many groups are not favoured).

Rows of window w, coordinate j enter the regression only if R_{w,j} ≥ ``gate_threshold``
(default **0.6**: the groups explain ≥ 36 % of the torque variance in the window; on 50–100
samples such an R is far beyond chance, so the threshold is about *relevance*, not significance).
A group is identified only if its own contribution correlates, r_{w,g,j} ≥ ``gate_threshold``,
on at least ``min_windows`` selected windows of some coordinate; otherwise its factor stays 1
(generic), its contribution moves to the known side, and it is flagged ``identified=False``.

**Regression.** Bounded linear least squares for the factors s_g ∈ [0.5, 2.0]
(the EMG-driven vs OpenSim thesis, Table 3.1) and a free d_j per coordinate; each coordinate's rows
are divided by the standard deviation of its torque so that joints weigh equally. It is solved from
the normal equations XᵀX β = Xᵀy accumulated window by window (bounded: BVLS on the Cholesky factor
of XᵀX, ``scipy.optimize.lsq_linear``), so the stacked rows are never held: a long trial's design
(one row per frame and coordinate) costs no memory beyond its windows' (p, p) sums. Same
minimiser as BVLS on the rows (tests/pipeline/test_long_trials.py: to 1e-9 on random designs with
active bounds); against the previous BVLS on the stacked rows, the strength factors of the
shipped sessions (gc4_JW, gc5_PS, gc6_DM_crouch_tm) moved by at most 2e-14 relative.

**Confidence intervals** (reported both):

* *bootstrap* over windows (cluster bootstrap: windows are resampled with replacement, which
  keeps the within-window correlation of EMG and torque errors), percentile interval of the
  bounded estimate; fast because each window's normal equations are precomputed;
* *regression covariance*: the cluster-robust (sandwich) covariance of the least-squares
  estimate in its delete-one-window jackknife form (CR3),
  ``(W − 1)/W Σ_w (β_(−w) − β̄)(β_(−w) − β̄)ᵀ``, with Student-t quantiles on W − p degrees of
  freedom (p regression parameters). The classical ``σ² (XᵀX)⁻¹`` is *not* used: errors within
  a window are strongly autocorrelated (low-passed EMG and torque noise), which makes it far too
  narrow; the CR1 sandwich and t_{W−1} were measured to under-cover with ~12 windows.
  The percentile bootstrap interval is widened by ``sqrt(W/(W−1)) t_{W−p}/z`` for the same
  reason.

**Errors in variables and honest intervals.** Noise in the EMG envelopes is noise in the
regressors, which attenuates the least-squares factors (synthetic leg, 10 % envelope noise:
knee extensors −1.4 … −1.7 %, plantar flexors −0.7 … −1.2 %, hip extensors −1.6 … −2.1 %, the
same at 12, 24 and 48 cycles) while their intervals shrink as 1/√cycles: the least-squares
intervals do not include that bias and stop being honest as the data grow. Measured coverage
of the least-squares 95 % intervals, synthetic leg, 10 % envelope and 3 % torque noise, seeds
0–119, worst group (jackknife-t / bootstrap): 12 cycles 0.97 / 0.97 (the t_{W−p} quantile with
W − p = 3 is wide enough to hide the bias), 24 cycles 0.88 / 0.87, 48 cycles 0.82.

With ``instrument="phase_average"`` (windows = cycles of one movement) the estimator is
instrumental variables instead (Fuller 1987, *Measurement Error Models*, §1.4; Wooldridge 2010,
*Econometric Analysis of Cross Section and Panel Data*, §5.1 and §15.7): the instrument of C_g in
window w is the same contribution built with the activation averaged, at the same phase of the
cycle, over the *other* windows — it follows the true activation pattern but is independent of
window w's EMG noise, so the attenuation disappears (at the price of ≈ 5–10 % wider intervals).
Bounded IV minimises ``(Zᵀ(y − Xβ))ᵀ (ZᵀZ)⁻¹ Zᵀ(y − Xβ)``. Its intervals resample whole cycles
*including the noise they put into the other cycles' instruments*: C_g is affine in the
activation and the phase average is linear, so the instrument of window w built from any
weighted set of the other windows is the same weighting of the per-pair instruments
``Z_{w←v}`` (w's contribution with v's activation alone), whose cross-products ``Z_{w←v}ᵀX_w``,
``Z_{w←v}ᵀy_w`` are precomputed once (O(W²)):

* the jackknife deletes cycle u from the regression *and* from every other cycle's instrument
  (then the average of W − 2 cycles) — the delete-one-cluster jackknife of the whole estimator
  (Efron & Tibshirani 1993, *An Introduction to the Bootstrap*, ch. 11; CR3 above);
* the bootstrap draws cycles with replacement and rebuilds each picked cycle's instrument from
  the other picked cycles (copies of itself excluded; the weight matrix ZᵀZ is the full-sample
  one, which leaves the exactly identified estimate unchanged), and its interval is the
  bias-corrected and accelerated percentile (BCa, Efron 1987, *J. Am. Stat. Assoc.* 82:171;
  acceleration from the jackknife values), widened by the same c.

Measured coverage of the IV 95 % intervals (same set-up, seeds 0–119; per group, worst group,
jackknife-t / BCa): 12 cycles 0.98 / 0.97, 24 cycles 0.92 / 0.90, 48 cycles 0.93 / 0.925
(mean over groups ≈ 0.99, 0.94, 0.95); 30-seed subsets at 24 cycles range 0.83–1.0 per group,
as the binomial Monte Carlo error of 30 draws allows. What remains is the bias of the
activation itself, which no instrument removes: the concave nonlinearity of the EMG-driven vs
OpenSim thesis, Eq. 7 turns zero-mean envelope noise into a slightly low mean activation, hence
slightly high factors (10 % noise: +0.3 … +0.9 %, 0.2–0.3 standard errors at 24–48 cycles; 20 %
envelope noise: least squares −3.8 % / −2.6 %, IV +1.9 % / +1.6 % on knee extensors / plantar
flexors). It grows relative to the interval as √cycles, so with 10 % noise the IV intervals stay
honest up to ≈ 100 cycles, with 20 % noise only to ≈ 15–20 cycles (not measured beyond). Least
squares stays the default because the instrument needs windows that are repetitions of one movement.

**MVC trials**. From gait alone some groups are weakly determined (synthetic leg,
24 cycles, 3 % torque noise: dorsiflexors ±6 %, up to 21 % off over 120 subjects — torque noise,
not a model mismatch: noise-free data give the factors exactly). The protocol of
Hayashibe et al. 2011 (Hayashibe, Venture, Ayusawa & Nakamura, IROS 2011, §VI.A) records MVCs of
flexion and extension at each joint; with their joint torques, they enter Eq. 16 as more windows.
``fit(movements=…)`` labels what each window repeats (gait cycles; each MVC action's repetitions): a
window is instrumented by the other windows of its own movement (≥ 3 each), the jackknife is the
stratified one (Wolter 2007, *Introduction to Variance Estimation*, §4.5) and the t quantile
takes Satterthwaite's degrees of freedom per parameter (a factor fixed mainly by 5 MVC
repetitions has ≈ 4, not W − p). Measured, 12 cycles + 5 repetitions per action, seeds 0–119:
every group within 4.5 % for every subject, jackknife-t coverage 0.91–0.97 per group. A group
whose activation never reaches ``min_excitation`` is not excited and stays generic, ``not
determined`` (without activity its factor would be fitted on its passive force and
co-contraction alone).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk import metrics as compare
from msk.exceptions import IdentificationError, ShapeMismatchError
from msk.muscles.hill import MuscleParameters, RigidTendonState, RigidTendonStateBlocks
from msk.timeseries import FrameSparse
from msk.units import Array

#: Bounds on strength factors, the EMG-driven vs OpenSim thesis, Table 3.1 (G_f, G_e ∈ [0.5, 2.0]).
STRENGTH_FACTOR_BOUNDS: tuple[float, float] = (0.5, 2.0)

__all__ = [
    "STRENGTH_FACTOR_BOUNDS",
    "StrengthIdentifier",
    "StrengthProfile",
    "envelope_window_s",
    "expand_groups",
    "gating_windows",
    "group_contributions",
    "net_contribution",
    "with_strength",
]


# ---------------------------------------------------------------------------------------------
# net contribution matrix
# ---------------------------------------------------------------------------------------------
#: frames per block of the contribution matrices (:meth:`StrengthIdentifier._contributions`):
#: a block's dense Jacobian and contributions of 92 muscles × 23 coordinates are ~9 MB each
#: (at 2048 frames they would be ~35 MB each, ~100 MB together: the strength stage's fixed part
#: of a long trial's peak). Each frame's values do not depend on the block.
_FRAME_BLOCK = 512


#: a muscle state given whole, or computed block by block on demand
StateLike = RigidTendonState | RigidTendonStateBlocks


def _state_rows(state: StateLike, sl: slice, n: int) -> RigidTendonState:
    """``state`` with its (n, M) arrays restricted to the frames ``sl`` (views; computed for
    these frames only when ``state`` is a :class:`RigidTendonStateBlocks`)."""
    if isinstance(state, RigidTendonStateBlocks):
        return state.rows(sl)
    changes: dict[str, Any] = {}
    for f in dataclasses.fields(state):
        v = getattr(state, f.name)
        if isinstance(v, np.ndarray) and v.ndim == 2 and v.shape[0] == n:
            changes[f.name] = v[sl]
    return dataclasses.replace(state, **changes)


def _as3(x: ArrayLike, what: str) -> Array:
    a = np.asarray(x, dtype=float)
    if a.ndim != 3:
        raise ShapeMismatchError(f"{what} must be (N, n_muscles, n_coords), got shape {a.shape}")
    if not np.isfinite(a).all():
        t, m, j = np.argwhere(~np.isfinite(a))[0]
        raise IdentificationError(f"{what}: non-finite value at frame {t}, muscle {m}, coord {j}")
    return a


def _as2(x: ArrayLike, shape: tuple[int, int], what: str, names: Sequence[str]) -> Array:
    a = np.asarray(x, dtype=float)
    if a.shape != shape:
        raise ShapeMismatchError(f"{what} must have shape {shape}, got {a.shape}")
    bad = ~np.isfinite(a)
    if bad.any():
        t, m = np.argwhere(bad)[0]
        raise IdentificationError(f"{what}: non-finite value at frame {t}, column {names[m]!r}")
    return a


def net_contribution(
    jacobian: ArrayLike,
    activation: ArrayLike,
    state: RigidTendonState,
    *,
    passive: bool = True,
) -> Array:
    """Net contribution matrix ``C_k = −J_kᵀ a_k f_l f_v cos α`` (Hayashibe et al. 2011, Eq. 13–14).

    ``jacobian`` J = ∂l/∂θ ``(N, M, n)``, ``activation`` ``(N, M)``, ``state`` the rigid-tendon
    muscle state of the **generic** parameters (only the normalised factors f_l, f_v, f_P and
    cos α are used, which do not depend on F_iso). With ``passive`` the passive fibre force is
    added: ``C_k = −J_kᵀ (a f_l f_v + f_P) cos α``. Returns ``(N, M, n)`` in N·m per N of F_iso
    (so ``τ = Σ_k C_k F_iso,k``).
    """
    jac = _as3(jacobian, "jacobian")
    n, m, _ = jac.shape
    a = _as2(activation, (n, m), "activation", state.names)
    if state.f_active_length.shape != (n, m):
        raise ShapeMismatchError(
            f"muscle state is {state.f_active_length.shape}, jacobian has (N, M) = {(n, m)}"
        )
    unit = a * state.f_active_length * state.f_velocity
    if passive:
        unit = unit + state.f_passive
    unit = unit * state.cos_pennation
    return -jac * unit[:, :, None]


def _group_index(
    groups: Mapping[str, Sequence[str]], muscle_names: Sequence[str]
) -> tuple[tuple[str, ...], list[list[int]]]:
    names = list(muscle_names)
    idx: list[list[int]] = []
    seen: dict[str, str] = {}
    for g, members in groups.items():
        if len(members) == 0:
            raise IdentificationError(f"synergist group {g!r} has no muscle")
        ii = []
        for mname in members:
            if mname not in names:
                raise IdentificationError(f"synergist group {g!r}: unknown muscle {mname!r}")
            if mname in seen:
                raise IdentificationError(
                    f"muscle {mname!r} is in two synergist groups: {seen[mname]!r} and {g!r}"
                )
            seen[mname] = g
            ii.append(names.index(mname))
        idx.append(ii)
    return tuple(groups), idx


def expand_groups(
    values: ArrayLike, groups: Mapping[str, Sequence[str]], muscle_names: Sequence[str]
) -> Array:
    """Copy per-group columns ``(N, G)`` (one EMG electrode per group) to muscles ``(N, M)``;
    muscles outside every group get 0."""
    v = np.asarray(values, dtype=float)
    gnames, idx = _group_index(groups, muscle_names)
    if v.ndim != 2 or v.shape[1] != len(gnames):
        raise ShapeMismatchError(f"values must be (N, {len(gnames)}) for groups, got {v.shape}")
    out = np.zeros((v.shape[0], len(muscle_names)))
    for g, ii in enumerate(idx):
        out[:, ii] = v[:, [g]]
    return out


def _rows(jacobian: ArrayLike | FrameSparse, frames: NDArray[np.int64]) -> Array:
    """The rows ``frames`` of a dense or compact Jacobian, dense (N_frames, M, n)."""
    if isinstance(jacobian, FrameSparse):
        return np.asarray(jacobian[frames])
    return np.asarray(jacobian, dtype=float)[frames]


def group_contributions(
    contribution: ArrayLike,
    groups: Mapping[str, Sequence[str]],
    params: MuscleParameters,
) -> tuple[Array, Array]:
    """``(C_g, τ_other)``: ``C_g = Σ_{k∈g} C_k F_iso,k^generic`` ``(N, G, n)`` and the generic
    contribution of the muscles outside every group ``(N, n)`` (Hayashibe et al. 2011, Eq.
    15–16)."""
    c = _as3(contribution, "contribution")
    if c.shape[1] != params.n_muscles:
        raise ShapeMismatchError(
            f"contribution has {c.shape[1]} muscles, parameters {params.n_muscles}"
        )
    _, idx = _group_index(groups, params.names)
    cf = c * params.max_isometric_force[None, :, None]
    cg = np.stack([cf[:, ii].sum(axis=1) for ii in idx], axis=1)
    inside = np.zeros(params.n_muscles, dtype=bool)
    for ii in idx:
        inside[ii] = True
    return cg, cf[:, ~inside].sum(axis=1)


#: group contributions ``(N, G, n)``: dense, or compact (only the (group, coordinate) pairs a
#: group's muscles cross: elsewhere exactly zero, :func:`_group_pattern`)
GroupContributions = Array | FrameSparse


def _group_pattern(
    jacobian: FrameSparse, groups: Mapping[str, Sequence[str]], params: MuscleParameters
) -> NDArray[np.intp]:
    """Flat positions ``g · n + j`` of the pairs (group g, coordinate j) where some muscle of g
    has a structural entry of the compact ``jacobian`` ``(N, M, n)``: elsewhere the group's
    contribution ``C_g = −Σ_k J_kᵀ (…) F_iso,k`` is zero in every frame."""
    n_mus, n_coords = jacobian.trailing
    flat = np.zeros(n_mus * n_coords, dtype=bool)
    flat[jacobian.positions] = True
    crosses = flat.reshape(n_mus, n_coords)
    _, idx = _group_index(groups, params.names)
    gp = np.array([crosses[ii].any(axis=0) for ii in idx]).reshape(len(idx), n_coords)
    return np.flatnonzero(gp.ravel())


def _column(cg: GroupContributions, g: int, j: int) -> Array:
    """Group g's contribution to coordinate j in every frame ``(N,)`` (zeros where compact
    ``cg`` holds no such pair)."""
    if not isinstance(cg, FrameSparse):
        return cg[:, g, j]
    k = np.flatnonzero(cg.positions == g * cg.trailing[1] + j)
    return cg.values[:, int(k[0])] if k.size else np.zeros(len(cg))


def _columns(x: Array | FrameSparse, cols: Sequence[int]) -> Array:
    """``x[:, cols]`` of an (N, M) array, dense or compact (:class:`FrameSparse` over M)."""
    if not isinstance(x, FrameSparse):
        return x[:, cols]
    out = np.zeros((len(x), len(cols)))
    where = {int(p): k for k, p in enumerate(x.positions)}
    for c, col in enumerate(cols):
        if col in where:
            out[:, c] = x.values[:, where[col]]
    return out


def _group_scale(cg: GroupContributions) -> Array:
    """max over frames of |C_g| ``(G, n)``, without an |C_g| copy."""
    if not isinstance(cg, FrameSparse):
        return np.maximum(cg.max(axis=0), -cg.min(axis=0))
    out = np.zeros(int(np.prod(cg.trailing)))
    if len(cg):
        out[cg.positions] = np.maximum(cg.values.max(axis=0), -cg.values.min(axis=0))
    return out.reshape(cg.trailing)


def _sum_groups(cg: GroupContributions, which: NDArray[np.bool_]) -> Array:
    """Σ over the groups ``which`` of C_g ``(N, n)``, in group order (the same sums as the
    dense ``cg[:, which, :].sum(axis=1)``: a compact form leaves out exact zeros only)."""
    if not isinstance(cg, FrameSparse):
        return np.asarray(cg[:, which, :].sum(axis=1))
    n_coords = cg.trailing[1]
    out = np.zeros((len(cg), n_coords))
    for k, pos in enumerate(cg.positions.tolist()):
        g, j = divmod(pos, n_coords)
        if which[g]:
            out[:, j] += cg.values[:, k]
    return out


def _weighted_groups(cg: GroupContributions, factors: Array) -> Array:
    """``Σ_g s_g C_g`` ``(N, n)`` (Eq. 16), block by block of frames for a compact ``cg``
    (each frame's sum as in one dense pass)."""
    if not isinstance(cg, FrameSparse):
        return np.einsum("tgj,g->tj", cg, factors)
    out = np.empty((len(cg), cg.trailing[1]))
    for c0 in range(0, len(cg), _FRAME_BLOCK):
        sl = slice(c0, c0 + _FRAME_BLOCK)
        out[sl] = np.einsum("tgj,g->tj", cg[sl], factors)
    return out


# ---------------------------------------------------------------------------------------------
# result
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class StrengthProfile:
    """Identified strength per synergist group and per muscle (frozen; SI).

    Group arrays ``(G,)`` in :attr:`group_names` order: ``factors`` s_g (× generic),
    ``f_iso_generic`` / ``f_iso`` the group's summed F_iso (N) before/after, ``ci_low`` /
    ``ci_high`` the bootstrap percentile interval of s_g, ``ci_cov_low`` / ``ci_cov_high`` the
    interval from the (cluster-robust) regression covariance, ``std_error`` its standard error,
    ``identified`` whether the group passed the correlation gate (else factor 1, CIs NaN) —
    not whether the data determined it: that is :meth:`statuses` (:mod:`msk.status`).
    Muscle arrays ``(M,)`` in :attr:`muscle_names` order: ``muscle_factors``, ``muscle_f_iso``.
    ``residual`` d_j per coordinate (N·m), ``r2_per_coordinate`` fit r² on the selected rows,
    ``r2`` their mean. Gating figures: ``gating_r`` ``(W, G, n)`` per-window correlation of C_g
    with τ (NaN where the group does not act), ``window_r`` ``(W, n)`` multiple correlation,
    ``selected`` ``(W, n)`` rows used, ``gate_threshold``.
    """

    group_names: tuple[str, ...]
    factors: Array
    f_iso_generic: Array
    f_iso: Array
    ci_low: Array
    ci_high: Array
    ci_cov_low: Array
    ci_cov_high: Array
    std_error: Array
    identified: NDArray[np.bool_]
    muscle_names: tuple[str, ...]
    muscle_groups: tuple[str, ...]
    muscle_factors: Array
    muscle_f_iso: Array
    coordinate_names: tuple[str, ...]
    residual: Array
    r2: float
    r2_per_coordinate: Array
    gate_threshold: float
    gating_r: Array
    window_r: Array
    selected: NDArray[np.bool_]
    window_labels: NDArray[np.int64]
    confidence: float
    n_samples: int
    n_bootstrap: int
    method: str
    bounds: tuple[float, float] = STRENGTH_FACTOR_BOUNDS
    extra: dict[str, Any] = field(default_factory=dict)
    #: per group, whether its activation rose above ``min_excitation`` of the identifier (a
    #: group the data do not excite is kept generic and ``not determined``); None: all were
    excited: NDArray[np.bool_] | None = None
    #: ``(G, n)`` whether group g's muscles have a moment arm about coordinate j (its own rows
    #: of the regression); None: not recorded
    acts: NDArray[np.bool_] | None = None
    #: ``(G, G)`` correlation of the groups' factor estimates from the regression covariance
    #: (NaN for groups kept generic); None: not recorded
    factor_correlation: Array | None = None

    def strength_factors(self) -> dict[str, float]:
        """Muscle → factor (× generic F_iso), ready for :func:`with_strength`."""
        return {n: float(f) for n, f in zip(self.muscle_names, self.muscle_factors)}

    def applied_factors(self) -> dict[str, float]:
        """Muscle → the factor a model of the subject takes: the group's factor where its
        status (:meth:`statuses`) is ``identified``, else 1 (the generic F_iso) — a factor on a
        bound or not determined by the data is not applied as if it were known."""
        keep = {n for n, st in zip(self.group_names, self.statuses()) if st == "identified"}
        return {
            n: float(f) if g in keep else 1.0
            for n, g, f in zip(self.muscle_names, self.muscle_groups, self.muscle_factors)
        }

    def max_isometric_forces(self) -> dict[str, float]:
        """Muscle → identified F_iso (N)."""
        return {n: float(f) for n, f in zip(self.muscle_names, self.muscle_f_iso)}

    def statuses(self, *, r2_min: float | None = None) -> tuple[str, ...]:
        """Per group, the :class:`msk.status.Status` value (``identified``, ``at bound``,
        ``not determined``, ``prior``) of :func:`msk.strength.diagnosis.diagnose`: from the
        factor, its bootstrap interval, the bounds, the fit r² of the group's own rows and the
        correlation gate (:func:`msk.status.strength_status`); a group the data do not excite
        (:attr:`excited`) is ``not determined``."""
        from msk.strength.diagnosis import diagnose

        return tuple(d.status for d in diagnose(self, r2_min=r2_min))

    def table(self) -> str:
        """Plain-text table: group, factor, 95 % CIs, F_iso generic → identified."""
        pct = round(100 * self.confidence)
        lines = [
            f"{'group':<18} {'factor':>7} {f'boot {pct}% CI':>16} {f'cov {pct}% CI':>16}"
            f" {'F_iso gen (N)':>13} {'F_iso (N)':>10}"
        ]
        status = self.statuses()
        for g, name in enumerate(self.group_names):
            flag = "" if self.identified[g] else "  (gated out: kept generic)"
            flag = f"  {status[g]}{flag}"
            lines.append(
                f"{name:<18} {self.factors[g]:>7.3f} "
                f"{f'[{self.ci_low[g]:.3f}, {self.ci_high[g]:.3f}]':>16} "
                f"{f'[{self.ci_cov_low[g]:.3f}, {self.ci_cov_high[g]:.3f}]':>16}"
                f" {self.f_iso_generic[g]:>13.0f} {self.f_iso[g]:>10.0f}{flag}"
            )
        lines.append(f"fit r² {self.r2:.3f}; method: {self.method}")
        return "\n".join(lines)


def with_strength(model: Any, strength: StrengthProfile | Mapping[str, float]) -> Any:
    """A new :class:`msk.model.core.Model` whose muscles take the identified F_iso
    (:meth:`msk.model.core.Model.with_strength` with the profile's per-muscle factors)."""
    factors = strength.strength_factors() if isinstance(strength, StrengthProfile) else strength
    return model.with_strength(factors)


# ---------------------------------------------------------------------------------------------
# estimator
# ---------------------------------------------------------------------------------------------
def _bounded_from_normal(a: Array, b: Array, lo: Array, hi: Array) -> Array:
    """argmin ½xᵀAx − bᵀx on lo ≤ x ≤ hi (A SPD), via lsq_linear on the Cholesky factor."""
    try:
        lfac = np.linalg.cholesky(a)
    except np.linalg.LinAlgError:
        lfac = np.linalg.cholesky(a + 1e-10 * np.trace(a) * np.eye(a.shape[0]))
    rhs = np.linalg.solve(lfac, b)
    from scipy.optimize import lsq_linear  # on use: decoding cached results need not pay

    return lsq_linear(lfac.T, rhs, bounds=(lo, hi), method="bvls", tol=1e-12).x


def _windows(windows: ArrayLike | None, n: int, n_default: int) -> NDArray[np.int64]:
    if windows is None:
        return np.minimum(np.arange(n) * n_default // n, n_default - 1).astype(np.int64)
    w = np.asarray(windows)
    if w.shape != (n,):
        raise ShapeMismatchError(f"windows must be one label per frame ({n},), got {w.shape}")
    _, inv = np.unique(w, return_inverse=True)
    return inv.astype(np.int64)


def envelope_window_s(lowpass_hz: float) -> float:
    """The shortest gating window (s): three correlation times τ = 1/(π f_c) of an EMG
    envelope zero-lag low-passed at ``lowpass_hz`` — 0.16 s at 6 Hz. τ is the integral of
    the envelope's autocorrelation, ∫₀^∞ ρ(t) dt (a first-order low-pass: 1/(2π f_c); the
    forward–backward Butterworth of orders 2 and 4 at 6 Hz on white noise, measured:
    0.049–0.053 s); the envelope decorrelates over about 2τ, so a window of 3τ holds only
    ≈ 1.5 independent envelope values and a shorter one less: its correlation of C_g with τ
    (the gate) then measures the filter, not the muscle."""
    return 3.0 / (np.pi * float(lowpass_hz))


def gating_windows(
    frames: ArrayLike, rate_hz: float, min_window_s: float, n_default: int = 10
) -> tuple[NDArray[np.bool_], NDArray[np.int64] | None]:
    """The gating windows of a trial's usable ``frames`` (sorted frame indices at
    ``rate_hz``) when :class:`StrengthIdentifier`'s ``n_default`` equal chunks would be
    shorter than ``min_window_s`` (:func:`envelope_window_s`): each contiguous run of frames
    (a stance on a plate, a swing) is cut into ⌊length / min⌋ equal windows of at least
    ``min_window_s``, a window never straddles a gap in time (its correlation would join
    unrelated instants), and a run shorter than one window (a few frames of swing between
    plates) gives none — its frames are left out (``keep`` False). Returns ``(keep,
    labels)``, labels for the kept frames; ``(all True, None)`` when the equal chunks are
    long enough (the identifier's default stands)."""
    f = np.asarray(frames, dtype=np.int64)
    keep = np.ones(f.size, dtype=bool)
    min_len = int(np.ceil(min_window_s * rate_hz - 1e-9))
    if f.size == 0 or f.size // max(n_default, 1) >= min_len:
        return keep, None
    labels = np.full(f.size, -1, dtype=np.int64)
    k = 0
    for run in np.split(np.arange(f.size), np.flatnonzero(np.diff(f) > 1) + 1):
        n_w = run.size // max(min_len, 1)
        if n_w:
            labels[run] = k + np.arange(run.size) * n_w // run.size
            k += n_w
    keep = labels >= 0
    return keep, labels[keep]


def _movement_of_windows(
    movements: ArrayLike | None, labels: NDArray[np.int64], n: int
) -> NDArray[np.int64]:
    """Movement label (0…K−1) of each window from per-frame ``movements`` (default: one)."""
    n_win = int(labels.max()) + 1
    if movements is None:
        return np.zeros(n_win, dtype=np.int64)
    m = np.asarray(movements)
    if m.shape != (n,):
        raise ShapeMismatchError(f"movements must be one label per frame ({n},), got {m.shape}")
    _, inv = np.unique(m, return_inverse=True)
    out = np.full(n_win, -1, dtype=np.int64)
    for w in range(n_win):
        mw = np.unique(inv[labels == w])
        if mw.size != 1:
            raise IdentificationError(
                f"window {w} spans {mw.size} movements: a window must repeat one movement"
            )
        out[w] = mw[0]
    return out


def _phase_average_loo(
    values: Array,
    labels: NDArray[np.int64],
    grid: int = 101,
    movement: NDArray[np.int64] | None = None,
) -> Array:
    """Leave-one-window-out average of ``values`` (N, M) at the same normalised phase of each
    window, over the other windows of the same ``movement`` (per window; default: all windows
    repeat one movement)."""
    n_win = int(labels.max()) + 1
    if movement is None:
        movement = np.zeros(n_win, dtype=np.int64)
    ph_grid = np.linspace(0.0, 1.0, grid)
    curves = np.zeros((n_win, grid, values.shape[1]))
    phases = []
    for w in range(n_win):
        idx = np.flatnonzero(labels == w)
        ph = np.linspace(0.0, 1.0, idx.size) if idx.size > 1 else np.zeros(idx.size)
        phases.append((idx, ph))
        for k in range(values.shape[1]):
            curves[w, :, k] = np.interp(ph_grid, ph, values[idx, k]) if idx.size else 0.0
    out = np.empty_like(values)
    for w, (idx, ph) in enumerate(phases):
        same = movement == movement[w]
        mean_other = (curves[same].sum(axis=0) - curves[w]) / max(int(same.sum()) - 1, 1)
        for k in range(values.shape[1]):
            out[idx, k] = np.interp(ph, ph_grid, mean_other[:, k])
    return out


def _interp_matrix(x_from: Array, x_to: Array) -> Array:
    """Weights ``(len(x_to), len(x_from))`` of ``np.interp(x_to, x_from, ·)`` (x_from increasing),
    so that interpolation of many columns is one matrix product."""
    out = np.zeros((x_to.size, x_from.size))
    if x_from.size == 1:
        out[:, 0] = 1.0
        return out
    pos = np.interp(x_to, x_from, np.arange(x_from.size, dtype=float))
    i0 = np.clip(np.floor(pos).astype(np.int64), 0, x_from.size - 2)
    frac = pos - i0
    rows = np.arange(x_to.size)
    out[rows, i0] = 1.0 - frac
    out[rows, i0 + 1] += frac
    return out


def _bca_limits(boot: Array, est: Array, jack: Array, alpha: float) -> tuple[Array, Array]:
    """BCa limits (Efron 1987): bias correction z0 from the bootstrap, acceleration from the
    jackknife values."""
    # the normal quantile and distribution function (scipy.stats.norm's ppf and cdf are these
    # special functions) without importing scipy.stats (~1 s on a cold run)
    from scipy.special import ndtr, ndtri

    n_b = boot.shape[0]
    frac = (np.sum(boot < est, axis=0) + 0.5 * np.sum(boot == est, axis=0)) / n_b
    z0 = ndtri(np.clip(frac, 0.5 / n_b, 1 - 0.5 / n_b))
    d = jack.mean(axis=0) - jack
    den = 6.0 * np.sum(d**2, axis=0) ** 1.5
    acc = np.where(den > 0, np.sum(d**3, axis=0) / np.where(den > 0, den, 1.0), 0.0)
    out = []
    for q in (alpha / 2, 1 - alpha / 2):
        zq = z0 + ndtri(q)
        lev = ndtr(z0 + zq / (1 - acc * zq))
        out.append(np.array([np.quantile(boot[:, i], lev[i]) for i in range(boot.shape[1])]))
    return out[0], out[1]


def _iv_normal(szz: Array, szx: Array, szy: Array) -> tuple[Array, Array]:
    """(A, b) of the bounded IV problem ½βᵀAβ − bᵀβ, A = Sxzᵀ Szz⁻¹ Szx, b = Szxᵀ Szz⁻¹ Szy."""
    w = np.linalg.lstsq(szz, np.column_stack([szx, szy]), rcond=None)[0]
    return szx.T @ w[:, :-1], szx.T @ w[:, -1]


class StrengthIdentifier:
    """Strength identification by regression on the net contribution matrix (Hayashibe et al. 2011,
    §V).

    Scikit-learn style: :meth:`fit` returns ``self``; fitted attributes end in ``_``
    (``profile_``, ``factors_``, ``residual_``, ``coordinates_``). See the module docstring for
    the maths, the correlation gate and the two confidence intervals.

    Args:
        groups: synergist group → muscle names (one EMG electrode per group).
        params: generic muscle parameters (F_iso^generic, in the muscle order of the arrays).
        coordinates: coordinate names to regress on (default: every coordinate on which some
            group acts).
        gate_threshold: correlation gate (see module docstring), default 0.6.
        min_windows: selected windows a group must correlate on to be identified.
        bounds: strength-factor bounds (the EMG-driven vs OpenSim thesis, Table 3.1).
        n_windows: number of equal contiguous windows when ``fit`` gets no ``windows`` labels.
        n_bootstrap: bootstrap replicates (0 disables the bootstrap interval).
        confidence: level of both intervals.
        passive: include the passive fibre force in C_k.
        instrument: ``"phase_average"`` replaces least squares by instrumental variables (see
            the module docstring); the windows must then be repetitions of one movement
            (cycles). Use it for honest intervals when there are more than ≈ 12 cycles: the
            least-squares intervals do not include the EMG-noise (errors-in-variables) bias.
        random_state: seed of the bootstrap.
        min_excitation: a group is *excited* only if the 99th percentile of its activation
            reaches this level (default 0.25: an excitation of ≈ 20 % MVC gives 0.2–0.29 through
            the EMG-driven vs OpenSim thesis, Eq. 7 nonlinearity, A = 0 … −1, with MVC-normalised
            EMG; a channel normalised to its session peak always reaches it). A group that is not
            excited is kept generic (its contribution — passive force and baseline activity — moves
            to the known side) and its status is ``not determined``: without activity the regression
            would fit its factor on the passive force and co-contraction alone.
    """

    def __init__(
        self,
        groups: Mapping[str, Sequence[str]],
        params: MuscleParameters,
        *,
        coordinates: Sequence[str] | None = None,
        gate_threshold: float = 0.6,
        min_windows: int = 2,
        bounds: tuple[float, float] = STRENGTH_FACTOR_BOUNDS,
        n_windows: int = 10,
        n_bootstrap: int = 400,
        confidence: float = 0.95,
        passive: bool = True,
        instrument: Literal["none", "phase_average"] = "none",
        random_state: int | None = 0,
        min_excitation: float = 0.25,
    ) -> None:
        _group_index(groups, params.names)
        if instrument not in ("none", "phase_average"):
            raise IdentificationError(
                f"instrument must be 'none' or 'phase_average', got {instrument!r}"
            )
        self.instrument = instrument
        if not (0.0 < gate_threshold < 1.0):
            raise IdentificationError(f"gate_threshold must be in (0, 1), got {gate_threshold}")
        if not (0.0 < bounds[0] < bounds[1]):
            raise IdentificationError(f"strength bounds must satisfy 0 < low < high: {bounds}")
        if not (0.0 < confidence < 1.0):
            raise IdentificationError(f"confidence must be in (0, 1), got {confidence}")
        self.groups = {g: tuple(m) for g, m in groups.items()}
        self.params = params
        self.coordinates = None if coordinates is None else tuple(coordinates)
        self.gate_threshold = float(gate_threshold)
        self.min_windows = int(min_windows)
        self.bounds = (float(bounds[0]), float(bounds[1]))
        self.n_windows = int(n_windows)
        self.n_bootstrap = int(n_bootstrap)
        self.confidence = float(confidence)
        self.passive = bool(passive)
        self.random_state = random_state
        if not (0.0 <= min_excitation < 1.0):
            raise IdentificationError(f"min_excitation must be in [0, 1), got {min_excitation}")
        self.min_excitation = float(min_excitation)

    # ----------------------------------------------------------------- helpers
    def _contributions(
        self,
        jacobian: ArrayLike | FrameSparse,
        activation: ArrayLike | FrameSparse,
        state: StateLike,
        frames: ArrayLike | None = None,
        *,
        compact: bool = False,
    ) -> tuple[GroupContributions, Array]:
        """Group contributions ``C_g`` ``(N, G, n)`` and the other muscles' ``(N, n)``.
        ``compact`` with a compact Jacobian: ``C_g`` as a :class:`FrameSparse` of the (group,
        coordinate) pairs the groups' muscles cross (:func:`_group_pattern`; a few of G × n on
        gait2392), else dense."""
        if tuple(state.names) != self.params.names:
            raise ShapeMismatchError(
                f"muscle state names {state.names[:3]}… differ from the parameters' "
                f"{self.params.names[:3]}…"
            )
        # block by block over the frames: the (N, M, n) contributions of a long trial are never
        # held whole (each frame's values are computed exactly as in one pass); ``frames``: the
        # rows of ``jacobian`` used, read block by block (never copied whole)
        rows = None if frames is None else np.asarray(frames, dtype=np.int64)
        jac: Array | FrameSparse
        if isinstance(jacobian, FrameSparse):  # compact (the pipeline's): dense block by block
            jac = jacobian
            sel = np.arange(len(jac)) if rows is None else rows
            for c0 in range(0, sel.size, _FRAME_BLOCK):
                r = sel[c0 : c0 + _FRAME_BLOCK]
                bad = r[~np.isfinite(jac.values[r]).all(axis=1)]
                if bad.size:
                    _as3(jac[bad[:1]], f"jacobian (from frame {int(bad[0])})")
            if jac.ndim != 3:
                raise ShapeMismatchError(f"jacobian must be (N, M, n), got {jac.shape}")
        else:
            jac = _as3(jacobian, "jacobian")
        n = jac.shape[0] if rows is None else int(rows.size)

        def block(sl: slice) -> Array:
            return np.asarray(jac[sl] if rows is None else jac[rows[sl]])

        act: Array | FrameSparse
        if isinstance(activation, FrameSparse):  # the measured muscles' columns only
            if activation.shape != (n, jac.shape[1]):
                raise ShapeMismatchError(
                    f"activation must have shape {(n, jac.shape[1])}, got {activation.shape}"
                )
            _as2(
                activation.values, activation.values.shape, "activation",
                [state.names[int(k)] for k in activation.positions],
            )  # fmt: skip
            act = activation  # dense block by block below
        else:
            act = _as2(activation, (n, jac.shape[1]), "activation", state.names)
        if isinstance(state, RigidTendonStateBlocks) and state.n_frames != n:
            raise ShapeMismatchError(f"muscle state has {state.n_frames} frames, jacobian {n}")
        pos = (
            _group_pattern(jac, self.groups, self.params)
            if compact and isinstance(jac, FrameSparse)
            else None
        )
        if n <= _FRAME_BLOCK and pos is None:
            c = net_contribution(
                block(slice(None)), act, _state_rows(state, slice(None), n), passive=self.passive
            )
            return group_contributions(c, self.groups, self.params)
        cg = other = None  # filled block by block (no list of parts concatenated at the end)
        for c0 in range(0, max(n, 1), _FRAME_BLOCK):
            sl = slice(c0, c0 + _FRAME_BLOCK)
            st = _state_rows(state, sl, n)
            c = net_contribution(block(sl), act[sl], st, passive=self.passive)
            g_part, o_part = group_contributions(c, self.groups, self.params)
            del c
            if cg is None or other is None:
                shape = (n, *g_part.shape[1:]) if pos is None else (n, pos.size)
                cg = np.empty(shape)
                other = np.empty((n, *o_part.shape[1:]))
            cg[sl] = g_part if pos is None else g_part.reshape(g_part.shape[0], -1)[:, pos]
            other[sl] = o_part
        assert cg is not None and other is not None  # one block at least
        if pos is not None:
            return FrameSparse(cg, pos, (len(self.groups), other.shape[1])), other
        return cg, other

    def _coords(self, coordinate_names: Sequence[str] | None, n: int) -> tuple[str, ...]:
        names = tuple(coordinate_names) if coordinate_names is not None else None
        if names is None:
            names = tuple(f"coord{j}" for j in range(n))
        if len(names) != n:
            raise ShapeMismatchError(f"{len(names)} coordinate names for {n} coordinates")
        return names

    def _instrument_pairs(
        self,
        jacobian: ArrayLike,
        activation: Array,
        state: StateLike,
        labels: NDArray[np.int64],
        gid: NDArray[np.int64],
        blocks: Sequence[tuple[int, int, Array, Array]],
        sd: Array,
        movement: NDArray[np.int64],
        grid: int = 101,
    ) -> tuple[Array, Array]:
        """Per pair of windows (w, v): ``P[w, v] = Z_{w←v}ᵀ X_w`` ``(W, W, p, p)`` and
        ``Q[w, v] = Z_{w←v}ᵀ y_w`` ``(W, W, p)``, where ``Z_{w←v}`` is window w's instrument
        built from window v's activation alone (resampled at w's phases); zero for v = w.

        The contribution is affine in the activation and the phase average is linear, so the
        instrument of w built from any weighted set of other windows (weights summing to 1) is
        the same weighting of the ``Z_{w←v}``: this lets the jackknife and the bootstrap rebuild
        every instrument from the windows they keep (:meth:`fit`). Windows of different
        ``movement`` (per window) do not instrument each other: ``P[w, v] = 0`` there.
        """
        jac = np.asarray(jacobian, dtype=float)
        n_frames, n_mus, _ = jac.shape
        if isinstance(state, RigidTendonStateBlocks):
            state = state.full()
        fiso = self.params.max_isometric_force[None, :, None]
        ka = net_contribution(jac, np.ones((n_frames, n_mus)), state, passive=False) * fiso
        kp = net_contribution(jac, np.zeros((n_frames, n_mus)), state, passive=self.passive)
        kp = kp * fiso
        _, idx = _group_index(self.groups, self.params.names)
        gm = np.zeros((gid.size, n_mus))
        for r, g in enumerate(gid):
            gm[r, idx[g]] = 1.0
        n_win = int(labels.max()) + 1
        ph_grid = np.linspace(0.0, 1.0, grid)
        frames = []
        curves = np.zeros((n_win, grid, n_mus))
        for w in range(n_win):
            iw = np.flatnonzero(labels == w)
            ph = np.linspace(0.0, 1.0, iw.size) if iw.size > 1 else np.zeros(iw.size)
            frames.append((iw, ph))
            curves[w] = _interp_matrix(ph, ph_grid) @ activation[iw]
        n_par = blocks[0][2].shape[1]
        pp = np.zeros((n_win, n_win, n_par, n_par))
        qq = np.zeros((n_win, n_win, n_par))
        by_window: dict[int, list[tuple[int, Array, Array]]] = {}
        for w, j, x, yv in blocks:
            by_window.setdefault(w, []).append((j, x, yv))
        ng = gid.size
        for w, items in by_window.items():
            iw, ph = frames[w]
            lw = _interp_matrix(ph_grid, ph)  # (n_w, grid): grid → window w's phases
            for j, x, yv in items:
                xy = np.column_stack([x, yv])  # (n_w, p + 1)
                # Σ_t lw[t, k] ka[t, m, j] xy[t, q] → (M, grid, p + 1)
                h = np.matmul(lw.T[None], ka[iw, :, j].T[:, :, None] * xy[None])
                # group part of Z_{w←v}ᵀ [X y] for every source window v → (W, G, p + 1)
                zxy = np.einsum("gm,mvq->vgq", gm, np.matmul(curves.transpose(2, 0, 1), h))
                zxy += ((kp[iw, :, j] @ gm.T).T @ xy)[None]
                zxy /= sd[j]
                pp[w, :, :ng] += zxy[:, :, :-1]
                qq[w, :, :ng] += zxy[:, :, -1]
                pp[w, :, ng:] += (x[:, ng:].T @ x)[None]
                qq[w, :, ng:] += (x[:, ng:].T @ yv)[None]
            pp[w, w] = 0.0
            qq[w, w] = 0.0
        other = movement[:, None] != movement[None, :]
        pp[other] = 0.0
        qq[other] = 0.0
        return pp, qq

    # ----------------------------------------------------------------- fit
    def fit(
        self,
        jacobian: ArrayLike | FrameSparse,
        activation: ArrayLike | FrameSparse,
        tau: ArrayLike,
        state: StateLike,
        *,
        windows: ArrayLike | None = None,
        coordinate_names: Sequence[str] | None = None,
        movements: ArrayLike | None = None,
        frames: ArrayLike | None = None,
        intervals: bool = True,
    ) -> StrengthIdentifier:
        """Identify the group strengths from one or more concatenated trials.

        ``jacobian`` ``(N, M, n)`` J = ∂l/∂θ (dense, or a :class:`msk.timeseries.FrameSparse`,
        used block by block); ``activation`` ``(N, M)`` EMG-driven activations
        (see :func:`expand_groups` and :func:`msk.muscles.activation.emg_to_activation`;
        dense, or a :class:`msk.timeseries.FrameSparse` over the muscles holding the measured
        muscles' columns only — the others are 0 — kept compact but for the instrument);
        ``tau`` ``(N, n)`` inverse-dynamics torques; ``state`` the rigid-tendon state of the
        generic parameters (whole, or a :class:`msk.muscles.hill.RigidTendonStateBlocks`
        computing it block by block: the same numbers without holding it); ``windows`` one
        label per frame (cycle / trial / motion) — the gating and bootstrap units (default:
        ``n_windows`` equal chunks); ``movements`` one label per frame naming the movement
        each window repeats (e.g. the gait cycles, and each MVC action's repetitions,
        Hayashibe et al. 2011, §VI.A) — with ``instrument="phase_average"`` a window is instrumented
        by the other windows of its movement only, which must then have ≥ 3 windows, and the
        intervals resample within movements (default: all windows repeat one movement).
        ``frames``: the rows of ``jacobian`` that the other arguments' rows are (default:
        all), read block by block — a long trial's Jacobian rows are not copied.
        ``intervals=False``: the factors alone (the same numbers), without the jackknife and
        the bootstrap — standard errors and intervals NaN (a caller that repeats the
        identification for a derivative, :func:`msk.strength.identify_pooled`).
        """
        # Student's t and the normal quantiles (scipy.stats' t.ppf and norm.ppf are these special
        # functions) without importing scipy.stats (~1 s on a cold run)
        from scipy.special import ndtri, stdtrit

        if frames is not None:
            frames = np.asarray(frames, dtype=np.int64)
        # compact (the pairs the groups' muscles cross) when the Jacobian is: a long trial's
        # (N, G, n) contributions are mostly structural zeros
        cg, other = self._contributions(jacobian, activation, state, frames, compact=True)
        n_frames, n_groups, n_coords = cg.shape
        cnames = self._coords(coordinate_names, n_coords)
        y_all = _as2(tau, (n_frames, n_coords), "tau", cnames) - other
        labels = _windows(windows, n_frames, self.n_windows)
        n_win = int(labels.max()) + 1
        if n_win < 3:
            raise IdentificationError(f"need at least 3 windows for gating/bootstrap, got {n_win}")
        use_iv = self.instrument == "phase_average"
        win_mov = _movement_of_windows(movements, labels, n_frames)
        n_per_mov = np.bincount(win_mov)
        if use_iv and n_per_mov.min() < 3:
            k = int(np.argmin(n_per_mov))
            raise IdentificationError(
                f"instrument='phase_average' needs ≥ 3 windows per movement; movement {k} "
                f"has {int(n_per_mov[k])}"
            )
        zg = cg
        # a compact activation (the measured muscles' columns) stays compact but for the
        # instrument, which averages every column
        act_arr = (
            activation
            if isinstance(activation, FrameSparse) and not use_iv
            else np.asarray(activation, dtype=float)
        )
        if use_iv:
            a_bar = _phase_average_loo(np.asarray(act_arr), labels, movement=win_mov)
            zg, _ = self._contributions(jacobian, a_bar, state, frames, compact=True)
        # coordinates used
        scale = _group_scale(cg)  # max |C_g| (G, n)
        acts = scale > 1e-9 * max(float(scale.max()), 1e-300)
        if self.coordinates is None:
            use = [j for j in range(n_coords) if acts[:, j].any()]
        else:
            use = []
            for c in self.coordinates:
                if c not in cnames:
                    raise IdentificationError(f"unknown coordinate {c!r}; have {list(cnames)}")
                use.append(cnames.index(c))
        if not use:
            raise IdentificationError("no synergist group acts on the selected coordinates")

        # gating figures
        gating_r = np.full((n_win, n_groups, n_coords), np.nan)
        window_r = np.full((n_win, n_coords), np.nan)
        for w in range(n_win):
            sel = labels == w
            for j in use:
                yw = y_all[sel, j]
                if yw.size < 3 or np.ptp(yw) == 0:
                    continue
                gs = [g for g in range(n_groups) if acts[g, j]]
                for g in gs:
                    xg = _column(cg, g, j)[sel]
                    if np.ptp(xg) > 0:
                        gating_r[w, g, j] = float(compare.pearson_r(xg, yw))
                xw = np.column_stack([_column(cg, g, j)[sel] for g in gs] + [np.ones(yw.size)])
                beta, *_ = np.linalg.lstsq(xw, yw, rcond=None)
                # adjusted R² (short windows with many groups would inflate the plain one)
                r2w = float(compare.r2(yw, xw @ beta))
                dof = yw.size - xw.shape[1]
                r2a = 1.0 - (1.0 - r2w) * (yw.size - 1) / dof if dof > 0 else 0.0
                window_r[w, j] = float(np.sqrt(max(0.0, r2a)))
        selected = np.zeros((n_win, n_coords), dtype=bool)
        selected[:, use] = np.nan_to_num(window_r[:, use], nan=0.0) >= self.gate_threshold
        passes = (np.nan_to_num(gating_r, nan=-1.0) >= self.gate_threshold) & selected[:, None, :]
        identified = passes.sum(axis=0).max(axis=1) >= self.min_windows
        identified &= acts[:, use].any(axis=1)
        _, gidx = _group_index(self.groups, self.params.names)
        excited = (
            np.array([float(np.quantile(_columns(act_arr, ii), 0.99, axis=0).max()) for ii in gidx])
            >= self.min_excitation
        )
        identified &= excited
        if not selected.any():
            raise IdentificationError(
                f"no window passes the correlation gate (R ≥ {self.gate_threshold}) on "
                f"{[cnames[j] for j in use]}; best R = {np.nanmax(window_r):.3f}"
            )
        gid = np.flatnonzero(identified)
        # known side: unidentified groups at generic strength
        y_known = y_all - _sum_groups(cg, ~identified)

        # regression design, block per (window, coordinate)
        used_coords = [j for j in use if selected[:, j].any()]
        sd = np.array([max(float(np.std(y_all[:, j])), 1e-12) for j in range(n_coords)])
        n_par = gid.size + len(used_coords)
        lo = np.concatenate([np.full(gid.size, self.bounds[0]), np.full(len(used_coords), -np.inf)])
        hi = np.concatenate([np.full(gid.size, self.bounds[1]), np.full(len(used_coords), np.inf)])
        szz = np.zeros((n_win, n_par, n_par))
        szx = np.zeros((n_win, n_par, n_par))
        szy = np.zeros((n_win, n_par))
        # the rows themselves are kept only for the instrument pairs (IV): the least-squares
        # estimate and its intervals need the per-window sums alone
        blocks: list[tuple[int, int, Array, Array]] = []
        n_rows = 0
        for w in range(n_win):
            sel = labels == w
            for jj, j in enumerate(used_coords):
                if not selected[w, j]:
                    continue
                x = np.zeros((int(sel.sum()), n_par))
                for gg, g in enumerate(gid.tolist()):
                    x[:, gg] = _column(cg, g, j)[sel] / sd[j]
                x[:, gid.size + jj] = 1.0 / sd[j]
                z = x.copy()
                if use_iv:
                    for gg, g in enumerate(gid.tolist()):
                        z[:, gg] = _column(zg, g, j)[sel] / sd[j]
                yv = y_known[sel, j] / sd[j]
                szz[w] += z.T @ z
                szx[w] += z.T @ x
                szy[w] += z.T @ yv
                n_rows += yv.size
                if use_iv:
                    blocks.append((w, j, x, yv))
        zz_tot, zx_tot, zy_tot = szz.sum(axis=0), szx.sum(axis=0), szy.sum(axis=0)
        if gid.size and np.linalg.matrix_rank(zx_tot) < n_par:
            raise IdentificationError(
                "the selected windows do not separate the synergist groups "
                f"{[list(self.groups)[g] for g in gid]} (singular regression)"
            )
        if use_iv:
            sol = _bounded_from_normal(*_iv_normal(zz_tot, zx_tot, zy_tot), lo, hi)
        else:  # least squares from its normal equations (Z = X: zx_tot = XᵀX, zy_tot = Xᵀy)
            sol = _bounded_from_normal(zx_tot, zy_tot, lo, hi)

        # cluster-robust covariance: delete-one-window jackknife (CR3), on the unconstrained
        # estimating equations Zᵀ(y − Xβ) = 0 (the CR1 sandwich is too narrow with few windows)
        alpha = 1.0 - self.confidence
        active_w = np.flatnonzero(np.any(selected, axis=1))
        n_eff = int(active_w.size)
        if not intervals:
            n_jack = 0
            jack = np.empty((0, n_par))
            jack_mov = np.zeros(0, dtype=np.int64)
        elif use_iv:
            # delete-one-cycle jackknife of the whole IV estimator: the deleted cycle leaves
            # the regression *and* every other cycle's instrument (which then averages W − 2
            # cycles), so the instrument's own EMG noise is part of the spread
            pp, qq = self._instrument_pairs(
                jacobian if frames is None else _rows(jacobian, frames),
                np.asarray(act_arr),
                state,
                labels,
                gid,
                blocks,
                sd,
                win_mov,
            )
            # window w's instrument averages the other windows of its movement: weight
            # 1 / (n_k − 1), or 1 / (n_k − 2) when the deleted window is of the same movement
            p_row, q_row = pp.sum(axis=1), qq.sum(axis=1)
            n_jack = n_win
            jack = np.empty((n_jack, n_par))
            for u in range(n_win):
                cw = 1.0 / (n_per_mov[win_mov] - 1.0 - (win_mov == win_mov[u]))
                cw[u] = 0.0
                s_u = np.einsum("w,wpq->pq", cw, p_row - pp[:, u])
                r_u = np.einsum("w,wp->p", cw, q_row - qq[:, u])
                jack[u] = np.linalg.lstsq(s_u, r_u, rcond=None)[0]
            jack_mov = win_mov
        else:
            n_jack = n_eff
            jack = np.empty((n_jack, n_par))
            for i, w in enumerate(active_w.tolist()):
                jack[i] = np.linalg.lstsq(zx_tot - szx[w], zy_tot - szy[w], rcond=None)[0]
            jack_mov = np.zeros(n_jack, dtype=np.int64)
        # stratified delete-one jackknife (Wolter 2007, *Introduction to Variance Estimation*,
        # §4.5): Σ_k (n_k − 1)/n_k Σ_{u∈k} (β_(−u) − β̄_k)(β_(−u) − β̄_k)ᵀ over movements k
        # (one movement: the CR3 form above)
        cov = np.zeros((n_par, n_par))
        strata = np.unique(jack_mov)
        v_h = np.zeros((strata.size, n_par))  # per-movement variance contributions
        n_h = np.zeros(strata.size)
        for i, k in enumerate(strata):
            jk = jack[jack_mov == k]
            dev = jk - jk.mean(axis=0)
            n_h[i] = jk.shape[0]
            cov += dev.T @ dev * (n_h[i] - 1) / n_h[i]
            v_h[i] = np.sum(dev**2, axis=0) * (n_h[i] - 1) / n_h[i]
        se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        # Student-t on W − p degrees of freedom (p regression parameters): the conservative
        # small-sample choice for cluster-robust inference with few windows — or fewer, per
        # parameter, when its variance comes from a movement with few windows (e.g. 3 MVC
        # repetitions): Satterthwaite's (1946, *Biometrics Bull.* 2:110) effective degrees of
        # freedom of the stratified variance, (Σ_k v_k)² / Σ_k v_k²/(n_k − 1)
        v_sum = v_h.sum(axis=0)
        satt = v_sum**2 / np.maximum(
            np.sum(v_h**2 / np.maximum(n_h - 1, 1)[:, None], axis=0), 1e-300
        )
        dof = np.clip(np.where(v_sum > 0, satt, np.inf), 1.0, max(n_eff - n_par, 1))
        tq = stdtrit(dof, 1.0 - alpha / 2)  # (p,)
        # the percentile bootstrap within a movement of n_k windows has variance (n_k − 1)/n_k
        # of the jackknife's: the interval is widened by the square root of the inverse ratio
        # (one movement: sqrt(W/(W − 1)))
        shrink = np.sum(v_h * ((n_h - 1) / n_h)[:, None], axis=0)
        ratio = np.where(shrink > 0, v_sum / np.where(shrink > 0, shrink, 1.0), 1.0)
        if strata.size == 1:
            ratio = np.full(n_par, n_eff / max(n_eff - 1, 1))
        if not intervals:
            cov = np.full((n_par, n_par), np.nan)
            se = np.full(n_par, np.nan)

        # bootstrap over windows
        rng = np.random.default_rng(self.random_state)
        n_boot = self.n_bootstrap if intervals else 0
        boot = np.full((n_boot, n_par), np.nan)
        for bi in range(n_boot):
            if use_iv:
                # whole cycles are resampled within each movement: cycle w's instrument
                # averages the *other* picked cycles of its movement (copies of w excluded);
                # the weight matrix keeps the full-sample Z
                mult = np.zeros(n_win)
                for k, nk in enumerate(n_per_mov.tolist()):
                    wk = np.flatnonzero(win_mov == k)
                    mk = np.full(nk, nk)
                    while mk.max() > nk - 1:  # each picked cycle needs another to average
                        mk = np.bincount(rng.integers(0, nk, nk), minlength=nk)
                    mult[wk] = mk
                cw = mult / (n_per_mov[win_mov] - mult)
                ab, bb = _iv_normal(
                    np.einsum("w,wpq->pq", mult, szz),
                    np.einsum("w,v,wvpq->pq", cw, mult, pp),
                    np.einsum("w,v,wvp->p", cw, mult, qq),
                )
            else:
                pick = rng.choice(active_w, size=active_w.size, replace=True)
                ab, bb = _iv_normal(
                    szz[pick].sum(axis=0), szx[pick].sum(axis=0), szy[pick].sum(axis=0)
                )
            # a coordinate absent from the resample keeps d from the full fit (tiny ridge)
            ridge = np.zeros(n_par)
            ridge[gid.size :] = 1e-9 * max(float(np.trace(ab)), 1.0)
            ab = ab + np.diag(ridge)
            bb = bb + ridge * sol
            boot[bi] = _bounded_from_normal(ab, bb, lo, hi)

        # assemble the profile
        gnames = tuple(self.groups)
        factors = np.ones(n_groups)
        factors[gid] = sol[: gid.size]
        ci_low = np.full(n_groups, np.nan)
        ci_high = np.full(n_groups, np.nan)
        cl = np.full(n_groups, np.nan)
        ch = np.full(n_groups, np.nan)
        sev = np.full(n_groups, np.nan)
        if n_boot > 0 and gid.size:
            # percentile interval, widened for the small number of windows by
            # c = sqrt(W/(W-1)) t_{W-p}/z (the percentile bootstrap of a few clusters is narrow)
            est = sol[: gid.size]
            if use_iv:
                # BCa (Efron 1987): the IV's bootstrap distribution is skewed and median-biased
                q_lo, q_hi = _bca_limits(boot[:, : gid.size], est, jack[:, : gid.size], alpha)
            else:
                q_lo = np.quantile(boot[:, : gid.size], alpha / 2, axis=0)
                q_hi = np.quantile(boot[:, : gid.size], 1 - alpha / 2, axis=0)
            widen = (np.sqrt(ratio) * tq / float(ndtri(1 - alpha / 2)))[: gid.size]
            ci_low[gid] = np.maximum(est - widen * np.maximum(est - q_lo, 0.0), self.bounds[0])
            ci_high[gid] = np.minimum(est + widen * np.maximum(q_hi - est, 0.0), self.bounds[1])
        sev[gid] = se[: gid.size]
        cl[gid] = factors[gid] - tq[: gid.size] * sev[gid]
        ch[gid] = factors[gid] + tq[: gid.size] * sev[gid]
        residual = np.zeros(n_coords)
        for jj, j in enumerate(used_coords):
            residual[j] = sol[gid.size + jj]
        _, idx = _group_index(self.groups, self.params.names)
        mf = np.ones(self.params.n_muscles)
        mg = ["" for _ in range(self.params.n_muscles)]
        fgen = np.zeros(n_groups)
        for g, ii in enumerate(idx):
            mf[ii] = factors[g]
            fgen[g] = float(self.params.max_isometric_force[ii].sum())
            for i in ii:
                mg[i] = gnames[g]
        # correlation of the factor estimates (confounded groups: near ±1)
        corr = np.full((n_groups, n_groups), np.nan)
        if gid.size:
            cg_cov = cov[: gid.size, : gid.size]
            sd_g = np.sqrt(np.clip(np.diag(cg_cov), 0.0, None))
            with np.errstate(invalid="ignore", divide="ignore"):
                corr[np.ix_(gid, gid)] = cg_cov / np.outer(sd_g, sd_g)
        # fit r² on the selected rows, in N·m
        pred = _weighted_groups(cg, factors) + residual[None] + other
        r2c = np.full(n_coords, np.nan)
        tau_arr = y_all + other
        for j in used_coords:
            rows = selected[labels, j]
            r2c[j] = float(compare.r2(tau_arr[rows, j], pred[rows, j]))
        self.coordinate_names_ = cnames
        self.coordinates_ = tuple(cnames[j] for j in used_coords)
        self.factors_ = factors
        self.residual_ = residual
        self.bootstrap_ = boot
        self.covariance_ = cov
        self.profile_ = StrengthProfile(
            group_names=gnames,
            factors=factors,
            f_iso_generic=fgen,
            f_iso=fgen * factors,
            ci_low=ci_low,
            ci_high=ci_high,
            ci_cov_low=cl,
            ci_cov_high=ch,
            std_error=sev,
            identified=identified,
            muscle_names=self.params.names,
            muscle_groups=tuple(mg),
            muscle_factors=mf,
            muscle_f_iso=self.params.max_isometric_force * mf,
            coordinate_names=cnames,
            residual=residual,
            r2=float(np.nanmean(r2c[used_coords])),
            r2_per_coordinate=r2c,
            gate_threshold=self.gate_threshold,
            gating_r=gating_r,
            window_r=window_r,
            selected=selected,
            window_labels=labels,
            confidence=self.confidence,
            n_samples=n_rows,
            n_bootstrap=self.n_bootstrap,
            method=(
                "net-contribution regression (Hayashibe et al. 2011 Eq. 12-16), "
                + ("bounded IV, phase-averaged instrument" if use_iv else "bounded least squares")
            ),
            bounds=self.bounds,
            excited=excited,
            acts=acts.copy(),
            factor_correlation=corr,
        )
        return self

    # ----------------------------------------------------------------- predict / score
    def _check_fitted(self) -> None:
        if not hasattr(self, "profile_"):
            raise IdentificationError("StrengthIdentifier is not fitted: call fit() first")

    def predict(self, jacobian: ArrayLike, activation: ArrayLike, state: StateLike) -> Array:
        """Joint torques ``Σ_g s_g C_g + Σ_{k∉G} C_k F_iso,k + d`` ``(N, n)`` (Eq. 16)."""
        self._check_fitted()
        cg, other = self._contributions(jacobian, activation, state)
        return np.einsum("tgj,g->tj", cg, self.factors_) + other + self.residual_[None]

    def score(
        self,
        jacobian: ArrayLike,
        activation: ArrayLike,
        tau: ArrayLike,
        state: StateLike,
    ) -> float:
        """Mean r² over the fitted coordinates of :meth:`predict` against ``tau``."""
        pred = self.predict(jacobian, activation, state)
        t = np.asarray(tau, dtype=float)
        if t.shape != pred.shape:
            raise ShapeMismatchError(f"tau is {t.shape}, prediction {pred.shape}")
        cols = [self.coordinate_names_.index(c) for c in self.coordinates_]
        return float(np.mean(np.atleast_1d(compare.r2(t[:, cols], pred[:, cols]))))
