"""msk's static optimisation on the full gait2392 model against OpenSim 4.6's StaticOptimization,
side by side on subject01 walking (the OpenSim peer's model and IK).

Both sides use the same imported model (``subject01_simbody.osim``: 92 Thelen2003 muscles) and
the same kinematics: OpenSim's reference IK ``.mot`` as AnalyzeTool prepares it (padded,
low-pass filtered at 6 Hz, quintic GCV splines); the child process returns the states SO used
(q, q̇ from the tool's states storage, q̈ the spline derivative of q̇, as StaticOptimization
computes its target accelerations). Everything else is computed independently: msk does its
own inverse dynamics (plates → feet), muscle geometry, Thelen2003 rigid-tendon active force
(``f_active``, gait2392 curves) and QP (Σ a², ``a ∈ [min_control, max_control] = [0.01, 1]``,
six pelvis residual actuators); OpenSim runs AnalyzeTool + StaticOptimization in a child
process (the script of :mod:`msk.optimization.opensim_reference`, every muscle kept, plus the
states read-back above) with the peer's residual actuators file (FX…MZ on the pelvis).

What "OpenSim-equivalent" takes, found here:

- **Plate loads without a contact threshold.** OpenSim's ExternalLoads apply the plate wrench
  whatever its size; msk's ``external_loads`` zeroes a plate below ``threshold_n`` (20 N by
  default). At heel strikes and toe-offs (a few to 20 N on one plate: 9 of the 121 frames)
  the joint torques then differ by 0.6–5.7 N·m and so do the optima (Σ a² up to 6.5 % apart,
  once read as IPOPT failures): ``threshold_n=0``.
- **IPOPT converged.** StaticOptimization's defaults (``optimizer_convergence_criterion`` 1e-4,
  ``optimizer_max_iterations`` 100) stop IPOPT 0.007–0.3 % above the optimal Σ a², which moves
  the small muscles (toe flexors/extensors, obliquus externus: peaks 8–42 N) by 2–5 %
  of their peak. At 1e-8 OpenSim reaches the optimum; msk's QP (DAQP) is exact either way.

(Filtering the IK with msk's own zero-lag Butterworth instead of OpenSim's IIR + GCV spline
changes q̇ enough to move ``f_active`` by ~3 % of its peak and the forces by ~4 % RMS: the
comparison is only meaningful on identical states.)

The pelvis residuals are the only actuators of the six root coordinates and no muscle moves
them (a rigid motion of the whole body leaves every muscle length unchanged), so the residual
actuators' kind (OpenSim point/torque actuators vs msk coordinate reserves) does not change the
muscle forces.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from msk.datasets.shared import shared_dir
from msk.dynamics.inverse import inverse_dynamics
from msk.dynamics.loads import external_loads
from msk.kinematics.ik import kinematics_from_coordinates
from msk.muscles.geometry import muscle_geometry, muscle_parameters
from msk.muscles.hill import Thelen2003Curves, rigid_tendon_state
from msk.optimization import solve_static_optimization_batch
from msk.optimization.opensim_reference import (
    FULL_SO_WINDOW,
    IPOPT_DEFAULT,
    IPOPT_TIGHT,
    compare_static_optimization,
    opensim_full_static_optimization,
)

PEER_DATA = shared_dir() / "tools" / "opensim-peer" / "data"
T0, T1 = FULL_SO_WINDOW
#: every SO frame (OpenSim's first one is at 0.4999993 s)
ALL = (T0 - 1e-3, T1 + 1e-3)
#: OpenSim's ExternalLoads apply the plate wrench whatever its size: no contact threshold
PLATE_THRESHOLD_N = 0.0


def msk_static_optimization(
    os_: dict[str, Any],
    model: Any,
    plates: Any,
    *,
    repeats: int = 1,
    threshold_n: float = PLATE_THRESHOLD_N,
) -> dict[str, Any]:
    """msk's chain on OpenSim's states: ID (plate loads applied from ``threshold_n`` up),
    geometry, f_active and SO on every SO frame; per-frame times of each stage (best of
    ``repeats``)."""
    k0 = kinematics_from_coordinates(os_["time"], os_["q"], model.coordinate_names, cutoff_hz=None)
    kin = dataclasses.replace(k0, q=os_["q"], v=os_["u"], a=os_["udot"])
    loads = external_loads(model, kin, plates, threshold_n=threshold_n)
    params = muscle_parameters(model)
    curves = Thelen2003Curves.gait2392()
    best: dict[str, float] = {}
    out: dict[str, Any] = {}
    n = kin.n_frames
    for _ in range(max(1, repeats)):
        t_a = time.perf_counter()
        jt = inverse_dynamics(model, kin, loads)
        t_b = time.perf_counter()
        geom = muscle_geometry(model, kin.q, kin.v)
        state = rigid_tendon_state(params, geom.lengths, geom.velocities, curves=curves)
        t_c = time.perf_counter()
        root = jt.root_coordinates
        reserves = np.array([1.0 if c in root else 0.0 for c in jt.coordinate_names])
        sol = solve_static_optimization_batch(
            geom.jacobian,
            jt.tau,
            f_active=state.max_active_force_along_tendon,
            activation_min=0.01,
            activation_max=1.0,
            reserve_optimal_force=reserves,
            muscle_names=params.names,
            coordinate_names=jt.coordinate_names,
            time=kin.time,
            compute_kkt=False,
        )
        t_d = time.perf_counter()
        for key, val in (
            ("id_s", (t_b - t_a) / n),
            ("geometry_s", (t_c - t_b) / n),
            ("so_s", (t_d - t_c) / n),
            ("chain_s", (t_d - t_a) / n),
        ):
            best[key] = min(best.get(key, np.inf), val)
        out = {
            "forces": sol.forces,
            "activations": sol.activations,
            "f_active": state.max_active_force_along_tendon,
            "status": sol.status,
            "jacobian": geom.jacobian,
            "tau": jt.tau,
            "reserves": reserves,
            "loads": loads,
        }
    out.update(per_frame_s=best, muscle_names=params.names, n_frames=n)
    return out


def msk_cost_on_opensim_torques(ms: dict[str, Any], os_: dict[str, Any]) -> np.ndarray:
    """Σ a² of msk's optimum per frame when the muscles must produce the joint torques OpenSim's
    forces produce through msk's moment arms, τ'_j = −Σ_i ∂l_i/∂q_j F_i^OpenSim (non-root
    coordinates; the pelvis rows are the residuals' in both). OpenSim's activations are feasible
    for this problem, so the optimum is ≤ OpenSim's Σ a²; the gap is how far IPOPT stopped
    above the optimum."""
    idx = [ms["muscle_names"].index(n) for n in os_["muscle_names"]]
    jac = ms["jacobian"][:, idx]
    tau = ms["tau"].copy()
    muscles = ms["reserves"] == 0.0
    tau[:, muscles] = -np.einsum("kmn,km->kn", jac, os_["forces"])[:, muscles]
    sol = solve_static_optimization_batch(
        jac,
        tau,
        f_active=ms["f_active"][:, idx],
        activation_min=0.01,
        activation_max=1.0,
        reserve_optimal_force=ms["reserves"],
        compute_kkt=False,
    )
    assert (sol.status == 0).all()
    return np.sum(sol.activations**2, axis=1)


def opensim_forces_residual(ms: dict[str, Any], os_: dict[str, Any]) -> np.ndarray:
    """(N, n) joint-torque residual −Jᵀ F^OpenSim − τ_msk on the non-root coordinates (N·m)."""
    idx = [ms["muscle_names"].index(n) for n in os_["muscle_names"]]
    res = -np.einsum("kmn,km->kn", ms["jacobian"][:, idx], os_["forces"]) - ms["tau"]
    return res[:, ms["reserves"] == 0.0]


def run_side_by_side(
    tmp: Path, *, repeats: int = 3, **opensim: Any
) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
    from msk.datasets.opensim_subject01 import load_subject01

    s = load_subject01()
    os_ = opensim_full_static_optimization(tmp, s.model.coordinate_names, **opensim)
    ms = msk_static_optimization(os_, s.model, s.plates, repeats=repeats)
    return ms, os_, compare_static_optimization(ms, os_, window=ALL)


def _skip_without_peer_data() -> None:
    if not PEER_DATA.is_dir():
        pytest.skip(f"OpenSim peer data absent: {PEER_DATA}")


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.opensim
def test_full_model_static_optimization_matches_converged_opensim(
    needs_opensim: None, tmp_path: Path
) -> None:
    """GitHub issue 7: every muscle OpenSim does not saturate within 2 % RMS of its peak, on
    OpenSim converged to 1e-8, every frame of 0.5–2.5 s; and the objectives agree."""
    _skip_without_peer_data()
    ms, os_, c = run_side_by_side(tmp_path, **IPOPT_TIGHT)
    assert os_["convergence_criterion"] == IPOPT_TIGHT["convergence_criterion"]
    assert len(os_["muscle_names"]) == 92 and set(os_["muscle_names"]) == set(ms["muscle_names"])
    rel, keep = c["relative_rms"], c["keep"]
    cost_ms, cost_os = c["cost_msk"], c["cost_opensim"]
    cost_on_os = msk_cost_on_opensim_torques(ms, os_)
    gap = (cost_os - cost_on_os) / cost_os
    own = (cost_ms - cost_os) / cost_os
    residual = opensim_forces_residual(ms, os_)
    print(
        f"full gait2392 SO vs OpenSim 4.6 (IPOPT tol {os_['convergence_criterion']:g}): "
        f"{c['n_frames']} frames, {keep.sum()} unsaturated muscles, relative RMS median "
        f"{np.median(rel[keep]):.2e}, max {rel[keep].max():.2e} ({c['worst']}), all 92 max "
        f"{rel.max():.2e}; saturated {c['saturated']}; activation RMS "
        f"{c['activation_rms']:.1e}; Σa² msk − OpenSim {own.min():+.1e}…{own.max():+.1e} "
        f"(relative); OpenSim above msk's optimum on its own torques by {gap.min():.1e}…"
        f"{gap.max():.1e}; OpenSim forces in msk's ID equations: max "
        f"{np.abs(residual).max():.1e} N·m"
    )
    ratio = os_["per_frame_s"] / ms["per_frame_s"]["so_s"]
    print(
        f"per frame (OpenSim at tol 1e-8, slower than its default): OpenSim SO "
        f"{os_['per_frame_s'] * 1e3:.1f} ms wall ({os_['per_frame_cpu_s'] * 1e3:.1f} ms CPU), "
        f"msk SO {ms['per_frame_s']['so_s'] * 1e6:.0f} µs (x {ratio:.0f}), msk ID + geometry "
        f"+ SO {ms['per_frame_s']['chain_s'] * 1e6:.0f} µs"
    )
    assert c["f_active_rel_max"] < 1e-8  # identical muscle physiology on identical states
    assert (ms["status"] == 0).all()
    assert c["not_converged_times"].size == 0 and c["n_frames"] == os_["time"].size == 121
    assert keep.sum() >= 85
    assert (rel[keep] < 0.02).all(), c["worst"]  # the criterion
    assert rel[keep].max() < 2e-3 and np.median(rel[keep]) < 1e-4  # floors reached: 1e-4, 1e-5
    assert rel.max() < 2e-3  # the saturated muscles agree as well
    # objectives: same Σ a² at every frame, up to msk's and OpenSim's ID (≤ 5 mN·m apart)
    assert np.abs(own).max() < 5e-4
    assert np.abs(residual).max() < 0.02
    # on the torques OpenSim met, msk's optimum is never above OpenSim's, and OpenSim is at it
    assert (cost_on_os <= cost_os + 1e-9).all()
    assert gap.max() < 1e-6
    # the speed ratio is printed only: bench/bench_chain.py reports it against its 500x target

    # the 20 N contact threshold of msk's default plate assignment is what differs at heel
    # strikes and toe-offs: OpenSim's forces then miss msk's torques by 0.6–5.7 N·m there only
    from msk.datasets.opensim_subject01 import load_subject01

    s = load_subject01()
    ms20 = msk_static_optimization(os_, s.model, s.plates, threshold_n=20.0)
    small = np.any(np.abs(ms20["loads"].force - ms["loads"].force).max(axis=2) > 0.0, axis=1)
    off = np.abs(opensim_forces_residual(ms20, os_)).max(axis=1) > 0.1
    print(
        f"threshold 20 N: plates below 20 N at t = {np.round(os_['time'][small], 3)}; OpenSim's "
        f"forces > 0.1 N·m off msk's torques at t = {np.round(os_['time'][off], 3)}"
    )
    assert off.any() and not (off & ~small).any()


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.opensim
def test_opensim_default_tolerance_stops_above_the_optimum(
    needs_opensim: None, tmp_path: Path
) -> None:
    """At StaticOptimization's default IPOPT settings (1e-4, 100 iterations) OpenSim's Σ a² is
    above msk's optimum (on the torques OpenSim met) at every frame: the small muscles' 2–5 %
    differences seen there are OpenSim's tolerance, not a modelling difference."""
    _skip_without_peer_data()
    ms, os_, c = run_side_by_side(tmp_path, repeats=1, **IPOPT_DEFAULT)
    assert os_["convergence_criterion"] == IPOPT_DEFAULT["convergence_criterion"]
    rel, keep = c["relative_rms"], c["keep"]
    cost_os = c["cost_opensim"]
    gap = (cost_os - msk_cost_on_opensim_torques(ms, os_)) / cost_os
    above = [n for n, r, k in zip(c["names"], rel, keep) if k and r >= 0.02]
    print(
        f"OpenSim at its default tolerance: Σa² above the optimum by {gap.min():.1e}…"
        f"{gap.max():.1e} (relative); relative RMS median {np.median(rel[keep]):.2e}, max "
        f"{rel[keep].max():.3f} ({c['worst']}); ≥ 2 %: {above}"
    )
    assert gap.min() > 1e-5  # never at the optimum (reached: 7e-5 … 3e-3)
    assert 0 < len(above) <= 12 and rel[keep].max() < 0.1
    peaks = c["peak"][[c["names"].index(n) for n in above]]
    assert peaks.max() < 50.0  # only small muscles (reached: 8–42 N)
