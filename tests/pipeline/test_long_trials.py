"""Long trials in bounded memory (issue 18): the compact per-frame Jacobian
(:class:`msk.timeseries.FrameSparse`), batch solvers warm-started across calls
(:class:`msk.optimization.WarmStart`) and the pipeline's frame blocks
(:mod:`msk._runtime.blocks`): blocked results equal unblocked ones to round-off."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import msk.optimization as o
from msk._runtime import blocks
from msk._runtime.cache import decode, encode
from msk.datasets.optimization import leg_like_frames
from msk.timeseries import FrameSparse
from tests.support.sessions import stages

REPO = Path(__file__).resolve().parents[2]


def _sparse_dense(n: int = 7) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(1)
    dense = np.zeros((n, 4, 3))
    pos = np.array([0, 4, 5, 9, 11])
    dense.reshape(n, -1)[:, pos] = rng.normal(size=(n, pos.size))
    return dense, pos


def _assert_fields_equal(a: Any, b: Any) -> None:
    """Two dataclass results equal field by field (arrays exactly)."""
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y, err_msg=f.name)
        else:
            assert x == y, f.name


def test_frame_sparse_is_the_dense_array() -> None:
    dense, pos = _sparse_dense()
    fs = FrameSparse.from_dense(dense, pos)
    assert fs.shape == dense.shape and fs.ndim == 3 and len(fs) == 7
    np.testing.assert_array_equal(fs[:], dense)
    np.testing.assert_array_equal(np.asarray(fs), dense)
    np.testing.assert_array_equal(fs[2], dense[2])
    np.testing.assert_array_equal(fs[1:4], dense[1:4])
    idx = np.array([5, 0, 5])
    np.testing.assert_array_equal(fs[idx], dense[idx])
    mask = np.arange(7) % 2 == 0
    np.testing.assert_array_equal(fs[mask], dense[mask])
    np.testing.assert_array_equal(fs.take(mask)[:], dense[mask])
    both = FrameSparse.concatenate([fs.take(np.arange(3)), fs.take(np.arange(3, 7))])
    np.testing.assert_array_equal(both[:], dense)
    with pytest.raises(TypeError):
        fs[:, 0]


def test_frame_sparse_is_storable_in_the_stage_cache() -> None:
    dense, pos = _sparse_dense()
    fs = FrameSparse.from_dense(dense, pos)
    tree, arrays, _ = encode(fs)
    back = decode(tree, arrays)
    assert isinstance(back, FrameSparse)
    np.testing.assert_array_equal(back[:], dense)


def test_frame_blocks_cover_the_frames_in_order(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(blocks, "FRAME_BLOCK", 4)
    parts = blocks.frame_blocks(10)
    assert [p.size for p in parts] == [3, 3, 4]
    np.testing.assert_array_equal(np.concatenate(parts), np.arange(10))
    idx = np.array([1, 4, 8])
    assert [list(p) for p in blocks.frame_blocks(idx)] == [[1, 4, 8]]
    assert [p.size for p in blocks.frame_blocks(0)] == [0]


@pytest.mark.parametrize("exponent", [2.0, 3.0])
def test_warm_start_carried_across_blocks_equals_one_call(exponent: float) -> None:
    d = leg_like_frames(12, 4, 60, seed=3)
    fa = np.tile(d.f_iso, (60, 1))
    kw = {"f_active": fa, "activation_exponent": exponent, "reserve_optimal_force": np.ones(4)}
    whole = o.solve_static_optimization_batch(d.jacobians, d.taus, **kw)  # type: ignore[arg-type]
    fresh = o.solve_static_optimization_batch(
        d.jacobians,
        d.taus,
        warm=o.WarmStart(),
        **kw,  # type: ignore[arg-type]
    )
    np.testing.assert_array_equal(fresh.forces, whole.forces)
    carry = o.WarmStart()
    parts = []
    for sl in (slice(0, 17), slice(17, 40), slice(40, 60)):
        kb = dict(kw, f_active=fa[sl])
        parts.append(
            o.solve_static_optimization_batch(
                d.jacobians[sl],
                d.taus[sl],
                warm=carry,
                **kb,  # type: ignore[arg-type]
            )
        )
    forces = np.concatenate([p.forces for p in parts])
    np.testing.assert_allclose(forces, whole.forces, rtol=0, atol=1e-9 * np.abs(whole.forces).max())
    np.testing.assert_array_equal(np.concatenate([p.iterations for p in parts]), whole.iterations)


@pytest.mark.parametrize("criterion", ["static", "static_p3", "assisted", "weighted", "tension"])
def test_batch_with_inequality_rows_in_parts_equals_one_call(criterion: str) -> None:
    """With inequality rows (the knee compartment rows) every frame's QP is whole, solved in
    turn: the frames solved in three calls, the warm start carried (``WarmStart``) and the
    rows taken per part (``TensionInequalities.take``), give one call's forces, activations,
    reserves, inequality reserves, statuses and active-set iterations bit for bit (the tension
    stage's solve parts, :data:`msk._runtime.blocks.SOLVE_BLOCK`); rows that bind on some
    frames (offsets around −20, gains ~0.02 per N)."""
    d = leg_like_frames(12, 4, 60, seed=7)
    rng = np.random.default_rng(4)
    fa = np.tile(d.f_iso, (60, 1))
    fp = rng.uniform(0.0, 30.0, (60, 12))
    rows = o.TensionInequalities(
        rng.normal(-20.0, 10.0, (60, 2)), rng.normal(0.0, 0.02, (60, 2, 12)), ("a", "b")
    )
    meas = np.arange(12) % 3 == 0

    def run(sl: slice, warm: Any) -> Any:
        kw: dict[str, Any] = {"solver": "daqp", "warm": warm, "inequalities": rows.take(sl)}
        jac, tau = d.jacobians[sl], d.taus[sl]
        res = np.ones(4)
        if criterion in ("static", "static_p3"):
            p = 3.0 if criterion == "static_p3" else 2.0
            return o.solve_static_optimization_batch(
                jac, tau, f_active=fa[sl], f_passive=fp[sl], reserve_optimal_force=res,
                activation_exponent=p, **kw,
            )  # fmt: skip
        if criterion == "assisted":
            return o.solve_emg_assisted_batch(
                jac, tau, f_active=fa[sl], f_passive=fp[sl], a_ref=np.full((60, 12), 0.1)[sl],
                measured=meas, reserve_optimal_force=res, **kw,
            )  # fmt: skip
        if criterion == "weighted":
            return o.solve_emg_weighted_batch(
                jac, tau, f_ref=np.full((60, 12), 100.0)[sl], measured=meas, w_emg=0.1,
                f_max=fa[sl], **kw,
            )  # fmt: skip
        return o.solve_tension_batch(
            jac, tau, f_iso=d.f_iso, f_max=fa[sl], reserve_optimal_force=res, **kw
        )

    whole = run(slice(0, 60), o.WarmStart())
    assert whole.inequality_reserves is not None and (whole.inequality_reserves > 1e-6).any()
    carry = o.WarmStart()
    parts = [run(sl, carry) for sl in (slice(0, 17), slice(17, 40), slice(40, 60))]
    for name in ("forces", "activations", "reserve_torques", "inequality_reserves", "status",
                 "iterations"):  # fmt: skip
        a = getattr(whole, name)
        if a is None:
            assert all(getattr(p, name) is None for p in parts), name
            continue
        np.testing.assert_array_equal(
            np.concatenate([getattr(p, name) for p in parts]), a, err_msg=name
        )


@pytest.mark.slow
@pytest.mark.parametrize("frame_block", [40, 4096])
def test_tension_and_contact_in_solve_parts_equal_whole_blocks(
    monkeypatch: pytest.MonkeyPatch, frame_block: int
) -> None:
    """gc5_PS (``emg_assisted`` with the knee compartment rows): the tension stage and the
    knee contact stage (its subject-specific re-solve handed to the contact per block) with
    each block solved in parts of 16 frames (:data:`msk._runtime.blocks.SOLVE_BLOCK`; blocks of
    40 frames with the Jacobian recomputed per block, or the trial in one block) give the
    stages' results of whole-block solves bit for bit: forces, activations, reserve torques,
    frontal reserves, the EMG gains, the contact forces and their medial/lateral split."""
    from threadpoolctl import threadpool_limits

    from msk.config import load_config
    from msk.pipeline import contact, tension
    from msk.pipeline.inputs import session_inputs

    cfg = load_config(REPO / "pipelines" / "gc5_PS.toml")
    assert cfg.optimization.compartment_nonnegative
    # the stages with blocks of ``frame_block`` frames, each solved whole (the trial's 145
    # frames are fewer than the default solve part)
    r = stages("gc5_PS.toml", "knee_contact", frame_block=frame_block)
    assert r["kinematics"].time.size <= blocks.SOLVE_BLOCK
    monkeypatch.setattr(blocks, "FRAME_BLOCK", frame_block)
    monkeypatch.setattr(blocks, "SOLVE_BLOCK", 16)
    inputs = session_inputs(cfg)
    args = (inputs, r["model"], r["kinematics"], r["loads"], r["mass_identification"],
            r["inverse_dynamics"])  # fmt: skip
    with threadpool_limits(limits=1, user_api="blas"):
        ten = tension.run(*args, r["muscle_geometry"], r["emg"])
        con = contact.run(
            *args, r["emg"], r["muscle_geometry"], r["tension_optimization"],
            r["strength_identification"], r["measured_contact"],
        )  # fmt: skip
    ref = r["tension_optimization"]
    for f in dataclasses.fields(ref):
        a, b = getattr(ref, f.name), getattr(ten, f.name)
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(b, a, err_msg=f.name)
        elif f.name == "kkt":  # the worst KKT figures: round-off, their frames the same
            assert b.frames == a.frames and b.columns == a.columns
            np.testing.assert_array_equal(b.frame, a.frame)
            np.testing.assert_allclose(b.value, a.value, rtol=0, atol=1e-13)
        else:
            assert b == a, f.name
    assert np.isfinite(ref.forces).sum() > 100 * len(ref.muscles)
    assert ref.frontal_reserve_moments is not None
    assert set(con.variants) == set(r["knee_contact"].variants) == {"generic", "subject_specific"}
    for name, v in r["knee_contact"].variants.items():
        for f in dataclasses.fields(v):
            np.testing.assert_array_equal(
                getattr(con.variants[name], f.name), getattr(v, f.name), err_msg=f.name
            )


def test_solve_parts_cover_a_block(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(blocks, "SOLVE_BLOCK", 4)
    parts = blocks.solve_parts(10)
    assert [(p.start, p.stop) for p in parts] == [(0, 4), (4, 8), (8, 10)]
    assert blocks.solve_parts(4) == [slice(0, 4)]
    assert blocks.solve_parts(0) == [slice(0, 0)]


@pytest.fixture(scope="module")
def gait2392() -> object:
    from msk.model.files import load_model

    return load_model(REPO / "msk" / "data" / "models" / "gait2392.toml")


def test_plan_positions_hold_every_nonzero_entry(gait2392: object) -> None:
    from msk.muscles.geometry import geometry_plan, muscle_geometry

    model = gait2392
    plan = geometry_plan(model)  # type: ignore[arg-type]
    rng = np.random.default_rng(0)
    q0 = model.default_coordinates()  # type: ignore[attr-defined]
    q = q0[None, :] + 0.2 * rng.normal(size=(20, q0.size))
    knee = "knee_l"
    g = muscle_geometry(model, q, plan=plan, distal_wrench_joints=(knee,))  # type: ignore[arg-type]
    jac = np.asarray(g.jacobian)
    pos = plan.jacobian_positions()
    assert pos.size < jac[0].size / 3  # compact: most entries are structural zeros
    np.testing.assert_array_equal(FrameSparse.from_dense(jac, pos)[:], jac)
    dw = np.asarray(g.distal_wrenches[knee])
    np.testing.assert_array_equal(FrameSparse.from_dense(dw, plan.distal_positions(knee))[:], dw)


def test_session_in_small_blocks_equals_one_block(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """gc5_PS (145 frames, gait2392: geometry, static optimisation, strength, knee contact)
    in blocks of 40 frames gives the tables of one block to round-off."""
    from msk.config import load_config
    from msk.pipeline import run_session
    from msk.results.folder import read_session
    from tests.support.sessions import session

    cfg = load_config(REPO / "pipelines" / "gc5_PS.toml")
    one = session("gc5_PS.toml")  # the shipped session in one block, shared
    monkeypatch.setattr(blocks, "FRAME_BLOCK", 40)
    many = run_session(cfg, tmp_path / "many", use_cache=False)
    assert [s.status for s in many.stages] == [s.status for s in one.stages]
    assert "failed" not in {s.status for s in one.stages}
    a, b = read_session(one.out_dir), read_session(many.out_dir)
    for name in ("muscle_forces", "activations", "residuals", "knee_contact", "strength"):
        ta, tb = a.tables[name], b.tables[name]
        assert ta.columns == tb.columns
        da, db = np.asarray(ta.data), np.asarray(tb.data)
        scale = np.nanmax(np.abs(da))
        np.testing.assert_allclose(db, da, rtol=0, atol=1e-9 * scale, err_msg=name)


@given(st.integers(0, 60), st.integers(1, 20))
def test_gain_fit_frames_are_all_or_evenly_spaced(n: int, cap: int) -> None:
    """The ``emg_assisted`` gain fit sees every frame up to the cap, else ``cap`` distinct,
    sorted frames spanning the first to the last."""
    from msk.optimization import muscle_forces

    frames = np.arange(n) * 3 + 5
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(muscle_forces, "GAIN_FIT_FRAMES", cap)
        fit = muscle_forces.fit_frames(frames)
    if n <= cap:
        np.testing.assert_array_equal(fit, frames)
    else:
        assert fit.size == cap and np.all(np.diff(fit) > 0) and set(fit) <= set(frames)
        assert fit[0] == frames[0] and (cap == 1 or fit[-1] == frames[-1])


def test_emg_assisted_gains_from_a_frame_sample(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """gc5_PS (``emg_assisted``): the EMG gains fitted on half the frames, evenly spaced, are
    those of all frames within 15 %, and the trial solved in blocks of 40 frames meets its
    torques on every frame."""
    from msk.config import load_config
    from msk.optimization import muscle_forces
    from msk.pipeline import run_stages

    cfg = load_config(REPO / "pipelines" / "gc5_PS.toml")
    assert cfg.optimization.method == "emg_assisted"
    full = stages("gc5_PS.toml", "knee_contact")["tension_optimization"]
    monkeypatch.setattr(muscle_forces, "GAIN_FIT_FRAMES", 70)
    monkeypatch.setattr(blocks, "FRAME_BLOCK", 40)
    part = run_stages(cfg, until="tension_optimization")["tension_optimization"]
    assert full.emg_gains is not None and part.emg_gains is not None
    assert set(part.emg_gains) == set(full.emg_gains)
    for ch, g in full.emg_gains.items():
        assert part.emg_gains[ch] == pytest.approx(g, rel=0.15), ch
    assert part.infeasible_frames == 0
    assert np.isfinite(part.forces).sum() == np.isfinite(full.forces).sum()


def test_tension_forces_only_are_the_stage_forces() -> None:
    """The knee contact stage's re-solve keeps the forces only: the same forces as the tension
    stage's (gc5_PS, ``emg_assisted``), no activations or reserve torques held."""
    from threadpoolctl import threadpool_limits

    from msk.config import load_config
    from msk.dynamics.identification import identified_model
    from msk.optimization.muscle_forces import solve_muscle_forces
    from msk.pipeline.inputs import session_inputs

    cfg = load_config(REPO / "pipelines" / "gc5_PS.toml")
    r = stages("gc5_PS.toml", "knee_contact")
    full = r["tension_optimization"]
    torques = r["inverse_dynamics"].torques
    with threadpool_limits(limits=1, user_api="blas"):
        m_id = identified_model(r["model"].model, r["mass_identification"])
        only = solve_muscle_forces(
            m_id, torques, r["muscle_geometry"], r["kinematics"].time,
            r["loads"].solvable, r["emg"], forces_only=True, kinematics=r["kinematics"],
            external=r["loads"].external,
            unbalanced=r["loads"].unbalanced_for(torques.coordinate_names),
            **session_inputs(cfg).muscle_force_options(m_id),
        )  # fmt: skip
    np.testing.assert_array_equal(only.forces, full.forces)
    assert np.isfinite(full.forces).any()
    assert only.activations.shape == (full.forces.shape[0], 0) and only.reserve_torques is None
    assert (only.infeasible_frames, only.excluded_frames) == (
        full.infeasible_frames,
        full.excluded_frames,
    )


def test_foot_points_in_blocks_equal_one_pass(monkeypatch: pytest.MonkeyPatch) -> None:
    """The feet's points computed block by block of frames (``msk.dynamics.loads._POINT_BLOCK``) are
    those of one pass, bit for bit, unknown poses (NaN) and frames not asked for left NaN."""
    import msk.dynamics.loads as loads
    from msk.datasets.models import two_leg_model

    model = two_leg_model()
    rng = np.random.default_rng(3)
    q0 = model.default_coordinates()
    q = q0[None, :] + 0.2 * rng.normal(size=(53, q0.size))
    q[[4, 30]] = np.nan
    feet = loads._default_feet(model)
    frames = np.flatnonzero(np.arange(53) != 11)
    one = loads._foot_points(model, q, feet, frames)
    monkeypatch.setattr(loads, "_POINT_BLOCK", 8)
    many = loads._foot_points(model, q, feet, frames)
    assert len(feet) == 2 and len(one) == 2
    for a, b in zip(one, many, strict=True):
        np.testing.assert_array_equal(a, b)
        assert np.isnan(a[[4, 11, 30]]).all() and np.isfinite(np.delete(a, [4, 11, 30], 0)).all()


def test_shipped_emg_assisted_session_over_several_assembly_chunks(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """gc5_PS as shipped (``emg_assisted``, per-frame EMG reference) with the split QP's data
    assembled 40 frames at a time instead of 512 — the path every trial over 512 usable frames
    takes, which failed before (per-frame g stretched onto one chunk) — gives the one-chunk
    tensions to round-off."""
    import msk.optimization.problems as problems
    from msk.config import load_config
    from msk.pipeline import run_stages

    cfg = load_config(REPO / "pipelines" / "gc5_PS.toml")
    assert cfg.optimization.method == "emg_assisted"
    one = stages("gc5_PS.toml", "knee_contact")["tension_optimization"]
    monkeypatch.setattr(problems, "_BLOCK_CHUNK", 40)
    many = run_stages(cfg, until="tension_optimization")["tension_optimization"]
    assert np.isfinite(one.forces).sum() > 100 and many.infeasible_frames == 0
    np.testing.assert_allclose(many.forces, one.forces, rtol=0, atol=1e-6 * np.nanmax(one.forces))


def test_identification_regressor_in_blocks_equals_one_pass(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A trial longer than ``REGRESSOR_BLOCK`` is stacked block by block: the same statistics to
    round-off, hence the same fit."""
    from threadpoolctl import threadpool_limits

    import msk.dynamics.identification as ident
    from msk.datasets.models import subject_bodies, whole_body_model
    from msk.datasets.trials import identification_trial

    truth = whole_body_model(subject_bodies("athlete"))
    trial = identification_trial(truth, 4.0, 5)
    kw = {"total_mass": truth.total_mass, "noise_std": np.array([7.0] * 3 + [3.0] * 3)}
    # one BLAS thread, as msk runs a session: a threaded BLAS sums in an order that varies
    # from call to call, and the conic solver's stopping point moves with it (3.8e-5 kg)
    with threadpool_limits(limits=1, user_api="blas"):
        one = ident.InertialIdentifier(truth, **kw).fit(trial)  # type: ignore[arg-type]
        monkeypatch.setattr(ident, "REGRESSOR_BLOCK", 37)
        many = ident.InertialIdentifier(truth, **kw).fit(trial)  # type: ignore[arg-type]
    assert many.n_frames_ == one.n_frames_ > 37
    # the Gram statistics to round-off; the identified parameters to the conic solver's tolerance
    for x in ("_h", "_g", "_c"):
        a, b = getattr(one, x), getattr(many, x)
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-12 * np.abs(a).max(), err_msg=x)
    # (on the scale of the whole parameter vector, which the solver's stopping test is on:
    # on a SkylakeX-kernel BLAS the humerus' mass moved 7e-6 kg, 4e-6 of itself)
    scale = max(float(np.abs(phi).max()) for phi in one.parameters_.values())
    for name, phi in one.parameters_.items():
        np.testing.assert_allclose(
            many.parameters_[name], phi, rtol=1e-6, atol=1e-6 * scale, err_msg=name
        )


def test_table_rows_formatted_in_blocks_are_the_same_text(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import msk.io.tables as tables
    from msk.io.opensim_files import write_sto

    rng = np.random.default_rng(2)
    tab = tables.Table(
        time=np.arange(11) / 100.0, data=rng.normal(size=(11, 3)), columns=("a", "b", "c")
    )
    one_csv = tables.write_csv_table(tmp_path / "one.csv", tab).read_bytes()
    one_sto = write_sto(tmp_path / "one.sto", tab, name="t").read_bytes()
    monkeypatch.setattr(tables, "FORMAT_BLOCK", 4)
    assert tables.write_csv_table(tmp_path / "b.csv", tab).read_bytes() == one_csv
    assert write_sto(tmp_path / "b.sto", tab, name="t").read_bytes() == one_sto


def test_strength_state_block_by_block_equals_the_whole_state(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The Hill state computed per block of frames (:class:`RigidTendonStateBlocks`, with a
    frame subset as the pipeline passes it) gives the identification of the whole state."""
    import msk.strength.identification as si
    from msk.datasets.strength import gait_trial, synthetic_leg
    from msk.muscles.activation import emg_to_activation
    from msk.muscles.hill import RigidTendonStateBlocks, rigid_tendon_state
    from msk.strength import StrengthIdentifier

    leg = synthetic_leg(0)
    tr = gait_trial(leg, n_cycles=12, seed=1)
    act = emg_to_activation(
        tr.emg, gamma1=-0.5, gamma2=-0.5, shape_factor=-1.0, delay_samples=4, form="exponential"
    )
    frames = np.flatnonzero(np.arange(tr.tau.shape[0]) % 7 != 3)  # a subset, as `good`
    lmt, vmt = tr.muscle_tendon_length, tr.lengthening_velocity
    whole = rigid_tendon_state(leg.params, lmt[frames], vmt[frames])
    lazy = RigidTendonStateBlocks(leg.params, lmt, vmt, frames)
    assert lazy.n_frames == frames.size and lazy.names == whole.names
    np.testing.assert_array_equal(lazy.rows(slice(5, 9)).f_passive, whole.f_passive[5:9])
    monkeypatch.setattr(si, "_FRAME_BLOCK", 50)  # several blocks, the last one short
    fits = []
    for state in (whole, lazy):
        est = StrengthIdentifier(leg.groups, leg.params, n_bootstrap=20, random_state=0)
        est.fit(tr.jacobian[frames], act[frames], tr.tau[frames], state, windows=tr.cycle[frames])
        fits.append(est)
    # the whole trial's Jacobian (dense and compact) with the rows named by ``frames``
    from msk.timeseries import FrameSparse

    dense = np.asarray(tr.jacobian)
    compact = FrameSparse.from_dense(dense, np.flatnonzero(np.any(dense != 0, axis=0).ravel()))
    for jac in (dense, compact):
        est = StrengthIdentifier(leg.groups, leg.params, n_bootstrap=20, random_state=0)
        est.fit(jac, act[frames], tr.tau[frames], lazy, windows=tr.cycle[frames], frames=frames)
        fits.append(est)
    for est in fits[1:]:
        np.testing.assert_array_equal(est.factors_, fits[0].factors_)
        np.testing.assert_array_equal(est.bootstrap_, fits[0].bootstrap_)
    with pytest.raises(si.ShapeMismatchError):
        fits[0].predict(tr.jacobian, act, lazy)  # frames of the state ≠ frames of the data


@pytest.mark.parametrize("instrument", ["none", "phase_average"])
def test_strength_compact_group_contributions_equal_the_dense_ones(
    monkeypatch: pytest.MonkeyPatch, instrument: str
) -> None:
    """With a compact Jacobian the identifier keeps only the (group, coordinate) pairs the
    groups' muscles cross; the profile (factors, intervals, gating, fit r²) is the dense one's,
    the structural pairs hold every nonzero contribution and are fewer than G × n."""

    import msk.strength.identification as si
    from msk.datasets.strength import gait_trial, synthetic_leg
    from msk.muscles.activation import emg_to_activation
    from msk.muscles.hill import RigidTendonStateBlocks
    from msk.strength import StrengthIdentifier
    from msk.timeseries import FrameSparse

    leg = synthetic_leg(0)
    tr = gait_trial(leg, n_cycles=12, seed=2)
    act = emg_to_activation(
        tr.emg, gamma1=-0.5, gamma2=-0.5, shape_factor=-1.0, delay_samples=4, form="exponential"
    )
    n, n_mus, n_coords = tr.jacobian.shape
    # a leg whose coordinates the groups do not all cross: two extra coordinates, one crossed
    # by the first group's first muscle only, one by no muscle
    dense = np.zeros((n, n_mus, n_coords + 2))
    dense[:, :, :n_coords] = tr.jacobian
    first = leg.params.names.index(next(iter(leg.groups.values()))[0])
    dense[:, first, n_coords] = 0.01 * np.sin(np.linspace(0.0, 40.0, n))
    tau = np.concatenate([tr.tau, np.zeros((n, 2))], axis=1)
    tau[:, n_coords] = -dense[:, first, n_coords] * 500.0
    compact = FrameSparse.from_dense(dense, np.flatnonzero(np.any(dense != 0, axis=0).ravel()))
    frames = np.flatnonzero(np.arange(n) % 5 != 2)
    state = RigidTendonStateBlocks(
        leg.params, tr.muscle_tendon_length, tr.lengthening_velocity, frames
    )
    pos = si._group_pattern(compact, leg.groups, leg.params)
    assert 0 < pos.size < len(leg.groups) * (n_coords + 2)
    monkeypatch.setattr(si, "_FRAME_BLOCK", 64)  # several blocks, the last one short
    est = StrengthIdentifier(leg.groups, leg.params, n_bootstrap=20, instrument=instrument)
    cg, other = est._contributions(compact, act[frames], state, frames, compact=True)
    cg_dense, other_dense = est._contributions(dense, act[frames], state, frames)
    assert isinstance(cg, FrameSparse) and cg.values.shape == (frames.size, pos.size)
    np.testing.assert_array_equal(np.asarray(cg), cg_dense)  # zeros outside the pairs
    np.testing.assert_array_equal(other, other_dense)
    profiles = []
    for jac in (dense, compact):
        est = StrengthIdentifier(leg.groups, leg.params, n_bootstrap=20, instrument=instrument)
        est.fit(jac, act[frames], tau[frames], state, windows=tr.cycle[frames], frames=frames)
        profiles.append(est.profile_)
    _assert_fields_equal(*profiles)


def test_bounded_least_squares_from_normal_equations_equals_bvls_on_the_rows() -> None:
    """The strength regression solved from XᵀX, Xᵀy accumulated by windows (no stacked rows)
    has the minimiser of BVLS on the rows, bounds active or not, to 1e-9."""
    from scipy.optimize import lsq_linear

    from msk.strength.identification import _bounded_from_normal

    rng = np.random.default_rng(4)
    for trial in range(6):
        x = rng.normal(size=(300, 7)) * rng.uniform(0.1, 10.0, size=7)
        beta = rng.uniform(-1.0, 3.0, size=7)
        y = x @ beta + 0.3 * rng.normal(size=300)
        lo = np.r_[np.full(5, 0.5), -np.inf, -np.inf]
        hi = np.r_[np.full(5, 2.0), np.inf, np.inf]
        rows = lsq_linear(x, y, bounds=(lo, hi), method="bvls", tol=1e-12).x
        xtx, xty = np.zeros((7, 7)), np.zeros(7)
        for part in np.array_split(np.arange(300), 9):  # window by window
            xtx += x[part].T @ x[part]
            xty += x[part].T @ y[part]
        normal = _bounded_from_normal(xtx, xty, lo, hi)
        np.testing.assert_allclose(normal, rows, rtol=0, atol=1e-9, err_msg=str(trial))
        assert np.any((rows[:5] == 0.5) | (rows[:5] == 2.0)) or trial > 0  # bounds bite


def test_root_generalised_forces_in_blocks_equal_one_pass(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import msk.dynamics.identification as ident
    from msk.datasets.models import subject_bodies, whole_body_model

    model = whole_body_model(subject_bodies("athlete"))
    rng = np.random.default_rng(5)
    n = 50
    th = model.default_coordinates()[None, :] + 0.3 * rng.normal(size=(n, model.n_coords))
    f, m = rng.normal(size=(n, 3)) * 300, rng.normal(size=(n, 3)) * 50
    one = ident.root_generalized_forces(model, th, f, m)
    monkeypatch.setattr(ident, "REGRESSOR_BLOCK", 7)
    np.testing.assert_array_equal(ident.root_generalized_forces(model, th, f, m), one)


def test_run_graph_releases_each_result_after_its_last_reader() -> None:
    """With ``keep``, a node's result is dropped once no later node reads it (the read trial
    of a long session is not held to the end); without, every result is returned."""
    import weakref
    from types import SimpleNamespace

    from msk.pipeline.graph import Node, last_readers, run_graph
    from msk.pipeline.runner import Runner

    class Big:
        pass

    alive: dict[str, bool] = {}
    refs: dict[str, weakref.ref[Big]] = {}

    def source(inputs: object) -> Big:
        b = Big()
        refs["source"] = weakref.ref(b)
        return b

    def first(inputs: object, source: Big) -> str:
        return "first"

    def middle(inputs: object, first: str) -> str:
        alive["at middle"] = refs["source"]() is not None
        return "middle"

    def last(inputs: object, middle: str, first: str) -> str:
        return "last"

    graph = (
        Node("source", source),
        Node("first", first, ("source",)),
        Node("middle", middle, ("first",)),
        Node("last", last, ("middle", "first")),
    )
    assert last_readers(graph) == {"source": 1, "first": 3, "middle": 3}
    inputs = SimpleNamespace(gait=True)
    names = tuple(n.name for n in graph)

    def runner() -> Runner:
        return Runner(None, None, stages=names, core=frozenset())

    out = run_graph(inputs, runner(), graph, keep=("last",))  # type: ignore[arg-type]
    assert out == {"last": "last"} and alive["at middle"] is False
    out = run_graph(inputs, runner(), graph)  # type: ignore[arg-type]
    assert set(out) == set(names) and alive["at middle"] is True


def test_model_stage_keeps_no_analog_rate_data() -> None:
    """The model stage's trial holds the markers (model frame) only: the analogs and plates
    stay with the read stage, which is released after the EMG stage; the read stage keeps the
    plates' force, COP and free moment (shared with the file's plates, not copied) and the
    analog channels of no plate, nothing else at the analog rate."""
    from msk.config import load_config
    from msk.pipeline import read as read_stage
    from msk.pipeline.inputs import session_inputs

    cfg = load_config(REPO / "pipelines" / "gc5_PS.toml")
    r = stages("gc5_PS.toml", "knee_contact")
    built, read = r["model"], r["read"]
    assert built.trial.plates == () and built.trial.analogs.size == 0
    np.testing.assert_array_equal(built.lab_up, read.trial.up)
    assert built.trial.markers.shape == read.trial.markers.shape
    full = read_stage.read_task(session_inputs(cfg))
    light = read_stage.for_session(session_inputs(cfg), full)
    assert read.trial.plates == () and len(read.plates) == len(full.trial.plates) == 3
    plate_channels = {c for p in full.trial.plates for c in p.channels}
    assert set(light.trial.analog_labels) == set(full.trial.analog_labels) - plate_channels
    assert len(light.trial.analog_labels) == 18 and set(cfg.emg.channels.values()) <= set(
        light.trial.analog_labels
    )
    for lab in light.trial.analog_labels:  # the same samples
        np.testing.assert_array_equal(light.trial.analog(lab), full.trial.analog(lab))
    for pw, fp in zip(light.plates, full.trial.plates):
        assert np.shares_memory(pw.force, fp.force) and np.shares_memory(pw.cop, fp.cop)
    assert light.trial.markers is full.trial.markers
    assert light.trial.model_outputs.data.size == 0


def test_emg_channel_by_channel_on_the_frames_equals_resampling_the_whole() -> None:
    """process_emg with ``time`` (each channel resampled as soon as processed) equals the
    analog-rate envelopes resampled afterwards: MVC-clipped, session-peak, flat and delayed
    channels, a channel shared by two muscles, a synergist."""
    from msk.muscles.emg import process_emg

    rng = np.random.default_rng(3)
    rate, n = 1000.0, 4000
    t = np.arange(n) / rate
    burst = np.clip(np.sin(2 * np.pi * 1.1 * t), 0, None)
    x = np.column_stack(
        [
            np.round(rng.normal(size=n) * (0.05 + a * burst) / 1e-4) * 1e-4
            for a in (1.0, 2.0, 0.5, 1.5)
        ]
        + [np.round(rng.normal(size=n) * 1e-3 / 1e-4) * 1e-4]  # flat: noise, no modulation
    )
    labels = ("A", "B", "C", "D", "F")
    opts: dict[str, object] = dict(
        rate_hz=rate, labels=labels,
        muscles={"a": "A", "a2": "A", "b": "B", "c": "C", "d": "D", "f": "F"},
        synergists={"s": ("a", "b")}, mvc={"B": 0.2}, t0=0.25,
        delay_s={"a": 0.0, "a2": 0.02, "c": 0.05, "s": 0.01},
    )  # fmt: skip
    whole = process_emg(x, **opts)  # type: ignore[arg-type]
    frames = 0.25 + np.arange(0.0, 3.9, 1 / 120)
    per_channel = process_emg(x, time=frames, **opts)  # type: ignore[arg-type]
    ref = whole.resampled(frames)
    assert whole.quality.flat.tolist() == [False, False, False, False, True]
    assert any("clipped to 100 %" in w for w in whole.warnings)
    direct = [i for i, m in enumerate(ref.muscle_names) if m != "s"]
    np.testing.assert_array_equal(per_channel.envelopes[:, direct], ref.envelopes[:, direct])
    np.testing.assert_allclose(per_channel.envelopes, ref.envelopes, rtol=0, atol=1e-15)
    assert per_channel.warnings == whole.warnings
    np.testing.assert_array_equal(per_channel.normalisation_value, whole.normalisation_value)
    np.testing.assert_array_equal(per_channel.time, frames)


def test_plates_sampled_first_give_the_same_loads() -> None:
    """external_loads of plates already on the kinematics time
    (:func:`msk.dynamics.loads.sample_plate`,
    column by column) equals external_loads of the analog-rate plates, bit for bit."""
    from msk.dynamics.loads import external_loads, sample_plate

    r = stages("gc5_PS.toml", "knee_contact")
    mdl, kin, read = r["model"], r["kinematics"], r["read"]
    rot = mdl.rotation
    from msk.pipeline.loads import rotated_plate

    plates = [rotated_plate(p, rot) for p in read.plates]
    up = -np.asarray(mdl.model.gravity) / np.linalg.norm(mdl.model.gravity)
    a = external_loads(mdl.model, kin, plates, cutoff_hz=15.0)
    sampled = [sample_plate(p, kin.time, up, cutoff_hz=15.0) for p in plates]
    b = external_loads(mdl.model, kin, sampled, cutoff_hz=15.0)
    for f in ("force", "moment", "point"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)
    assert a.assignments == b.assignments and a.metadata == b.metadata
    rotated = sampled[0].rotated(rot.T)
    np.testing.assert_allclose(rotated.force @ rot.T, sampled[0].force, atol=1e-9)


def test_inverse_dynamics_in_blocks_equals_one_pass(monkeypatch: pytest.MonkeyPatch) -> None:
    """gc5_PS's inverse dynamics in blocks of 40 frames: the one-pass torques and residuals."""
    import msk.dynamics.inverse as dyn

    r = stages("gc5_PS.toml", "knee_contact")
    mdl, kin, ext = r["model"].model, r["kinematics"], r["loads"].external
    one = dyn.inverse_dynamics(mdl, kin, ext)
    monkeypatch.setattr(dyn, "ID_BLOCK", 40)
    many = dyn.inverse_dynamics(mdl, kin, ext)
    assert kin.time.size > 3 * 40
    for f in dyn.JointTorques.FRAME_FIELDS:
        np.testing.assert_array_equal(getattr(many, f), getattr(one, f), err_msg=f)
    assert many.coordinate_names == one.coordinate_names


def test_knee_contact_in_blocks_equals_one_pass() -> None:
    """The knee contact stage (gc5_PS: generic and subject-specific) with the knee wrenches
    recomputed per block and the subject-specific re-solve consumed per block of 40 frames
    (never held whole) gives the contact of one pass: the whole re-solve's forces and the
    whole trial's wrenches from one geometry evaluation, to round-off."""
    from threadpoolctl import threadpool_limits

    from msk.config import load_config
    from msk.contact.knee import knee_contact_force, plateau_geometry, split_medial_lateral
    from msk.contact.patella import patellar_tendon
    from msk.dynamics.identification import identified_model
    from msk.muscles.geometry import muscle_geometry
    from msk.optimization.muscle_forces import solve_muscle_forces
    from msk.pipeline.inputs import session_inputs
    from msk.strength import with_strength

    cfg = load_config(REPO / "pipelines" / "gc5_PS.toml")
    r = stages("gc5_PS.toml", "knee_contact", frame_block=40)
    got = r["knee_contact"]
    assert set(got.variants) == {"generic", "subject_specific"}
    assert not r["muscle_geometry"].distal_wrenches  # not held from geometry to contact
    inputs, mdl, kin = session_inputs(cfg), r["model"].model, r["kinematics"]
    joint = got.joint
    knee_coord = mdl.coordinate_index(
        next(a.coordinate for j in mdl.joints if j.name == joint for a in j.axes if a.coordinate)
    )
    m_id = identified_model(mdl, r["mass_identification"])  # both variants' inertias
    spec = with_strength(m_id, r["strength_identification"].profile.applied_factors())
    torques = r["inverse_dynamics"].torques
    with threadpool_limits(limits=1, user_api="blas"):
        resolve = solve_muscle_forces(
            spec, torques, r["muscle_geometry"], kin.time,
            r["loads"].solvable, r["emg"], forces_only=True, kinematics=kin,
            external=r["loads"].external,
            unbalanced=r["loads"].unbalanced_for(torques.coordinate_names),
            **inputs.muscle_force_options(spec),
        )  # fmt: skip
    forces = {"generic": r["tension_optimization"].forces, "subject_specific": resolve.forces}
    models = {"generic": m_id, "subject_specific": spec}
    # the knee's leg: its muscles (the side's suffix) solved; the other leg's forces (NaN where
    # its foot stands off the plates) load no part of this knee's distal side: 0
    side = [k for k, m in enumerate(r["tension_optimization"].muscles) if m.endswith(joint[-2:])]
    for name, f in forces.items():
        ok = np.flatnonzero(r["loads"].solvable & np.isfinite(f[:, side]).all(axis=1))
        assert ok.size > 100
        assert (~np.isfinite(f[ok])).any()  # frames whose other leg is left out
        g = muscle_geometry(mdl, kin.q[ok], distal_wrench_joints=(joint,))
        tendon = cfg.contact.patella == "tendon"  # the quadriceps through the patellar tendon
        c = knee_contact_force(
            models[name], kin.take(ok), r["loads"].external.take(ok),
            muscle_forces=np.nan_to_num(f[ok], nan=0.0),
            muscle_names=r["tension_optimization"].muscles, joint=joint,
            distal_wrenches=g.distal_wrenches[joint],
            patella=patellar_tendon(models[name], joint=joint) if tendon else None,
            knee_jacobian=np.asarray(g.jacobian)[:, :, knee_coord] if tendon else None,
        )  # fmt: skip
        cc = cfg.contact
        geo = plateau_geometry(
            models[name], joint=joint, intercondylar_distance_m=cc.intercondylar_distance_m,
            centre_m=None if cc.plateau_depth_m is None else (0.0, -cc.plateau_depth_m, 0.0),
        )  # fmt: skip
        ml = split_medial_lateral(c, geo)
        v = got.variants[name]
        scale = np.abs(c.force).max()
        assert np.isnan(np.delete(v.total, ok)).all()
        np.testing.assert_allclose(v.force[ok], c.force, rtol=0, atol=1e-9 * scale)
        np.testing.assert_allclose(v.medial[ok], ml.medial, rtol=0, atol=1e-9 * scale)
        np.testing.assert_allclose(v.lateral[ok], ml.lateral, rtol=0, atol=1e-9 * scale)


def test_foot_point_velocities_in_blocks_equal_one_pass(monkeypatch: pytest.MonkeyPatch) -> None:
    """The feet's point velocities block by block (``msk.dynamics.loads._POINT_BLOCK``, each block
    with
    its neighbouring frames) are those of one pass bit for bit: central differences inside,
    one-sided next to a gap (NaN frames) and at the ends, NaN between two gaps."""
    import msk.dynamics.loads as loads

    rng = np.random.default_rng(5)
    p = rng.normal(size=(61, 4, 3))
    p[[0, 9, 10, 12, 33, 60]] = np.nan  # an end, a 2-frame gap, a frame between two gaps
    t = np.cumsum(rng.uniform(0.008, 0.009, 61))
    one = loads._velocity_one_pass(p, t)
    monkeypatch.setattr(loads, "_POINT_BLOCK", 8)  # blocks cut at 8, 16, …: through the gaps
    many = loads._velocity(p, t)
    np.testing.assert_array_equal(many, one)
    assert np.isnan(one[11]).all() and np.isfinite(one[[1, 8, 13, 32, 34, 59]]).all()


@pytest.mark.parametrize("instrument", ["none", "phase_average"])
def test_strength_compact_activation_equals_the_dense_one(
    monkeypatch: pytest.MonkeyPatch, instrument: str
) -> None:
    """The activation given compact over the muscles (the measured muscles' columns only, as
    the pipeline's strength stage gives it) identifies the profile of the dense activation
    with zeros in the other columns, bit for bit, in several contribution blocks."""

    import msk.strength.identification as si
    from msk.datasets.strength import gait_trial, synthetic_leg
    from msk.muscles.activation import emg_to_activation
    from msk.muscles.hill import RigidTendonStateBlocks
    from msk.strength import StrengthIdentifier
    from msk.timeseries import FrameSparse

    leg = synthetic_leg(0)
    tr = gait_trial(leg, n_cycles=12, seed=2)
    act = emg_to_activation(
        tr.emg, gamma1=-0.5, gamma2=-0.5, shape_factor=-1.0, delay_samples=4, form="exponential"
    )
    frames = np.flatnonzero(np.arange(act.shape[0]) % 5 != 2)
    # one group's muscles unmeasured (0): the others' columns kept
    groups = dict(list(leg.groups.items())[1:])
    cols = sorted(leg.params.names.index(m) for ms in groups.values() for m in ms)
    assert 0 < len(cols) < len(leg.params.names)
    dense = np.zeros((frames.size, len(leg.params.names)))
    dense[:, cols] = act[frames][:, cols]
    compact = FrameSparse.from_dense(dense, cols)
    jac = FrameSparse.from_dense(tr.jacobian, np.flatnonzero(np.any(tr.jacobian != 0, axis=0)))
    state = RigidTendonStateBlocks(
        leg.params, tr.muscle_tendon_length, tr.lengthening_velocity, frames
    )
    monkeypatch.setattr(si, "_FRAME_BLOCK", 64)  # several blocks, the last one short
    profiles = []
    for a in (dense, compact):
        est = StrengthIdentifier(groups, leg.params, n_bootstrap=20, instrument=instrument)
        est.fit(jac, a, tr.tau[frames], state, windows=tr.cycle[frames], frames=frames)
        profiles.append(est.profile_)
    _assert_fields_equal(*profiles)
    assert np.isfinite(profiles[0].factors).all()


def test_recomputed_jacobian_rows_are_the_geometry_stages_values(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """gc5_PS in blocks of 40 frames: the geometry stage holds no Jacobian
    (:class:`msk.pipeline.geometry.JacobianRows`); every way the later stages read it (a slice,
    indices across blocks, a mask, one frame, rows and columns, the dense ``jac[frames]``)
    gives bit for bit the values of the stage's blocks evaluated and held, and the tension
    stage on it equals the tension stage on the held array."""
    import pickle

    from threadpoolctl import threadpool_limits

    from msk.config import load_config
    from msk.muscles.geometry import geometry_plan
    from msk.pipeline import geometry, tension
    from msk.pipeline.geometry import JacobianRows, posed_geometry
    from msk.pipeline.inputs import session_inputs

    r = stages("gc5_PS.toml", "knee_contact", frame_block=40)
    monkeypatch.setattr(blocks, "FRAME_BLOCK", 40)
    cfg = load_config(REPO / "pipelines" / "gc5_PS.toml")
    mdl, kin, ok = r["model"].model, r["kinematics"], r["loads"].solvable
    geo = geometry.run(session_inputs(cfg), r["model"], kin, r["loads"])
    rows = geo.jacobian.values
    assert isinstance(rows, JacobianRows)
    plan = geometry_plan(mdl)
    pos = plan.jacobian_positions()
    parts = []
    for b in blocks.frame_blocks(kin.q.shape[0]):
        g = posed_geometry(mdl, kin.q, kin.v, ok, slice(int(b[0]), int(b[-1]) + 1), plan)
        parts.append(np.asarray(g.jacobian).reshape(b.size, -1)[:, pos])
    held = np.concatenate(parts)
    n = held.shape[0]
    assert n > 3 * 40 and rows.shape == held.shape
    rng = np.random.default_rng(3)
    idx = np.sort(rng.choice(n, 50, replace=False))
    mask = rng.random(n) < 0.3
    for key in (slice(None), slice(17, 93), idx, idx[::-1], mask, 77, (idx, slice(2, 9))):
        np.testing.assert_array_equal(rows[key], held[key])
    np.testing.assert_array_equal(np.asarray(rows), held)
    np.testing.assert_array_equal(pickle.loads(pickle.dumps(rows)), held)
    dense = FrameSparse(held, pos, geo.jacobian.trailing)
    np.testing.assert_array_equal(geo.jacobian[idx], dense[idx])
    inputs = session_inputs(cfg)
    whole = geo.__class__(
        geo.muscle_names, geo.coordinate_names, geo.lengths, dense, geo.velocities
    )
    with threadpool_limits(limits=1, user_api="blas"):
        a = tension.run(inputs, r["model"], kin, r["loads"], r["mass_identification"],
                        r["inverse_dynamics"], geo, r["emg"])  # fmt: skip
        b = tension.run(inputs, r["model"], kin, r["loads"], r["mass_identification"],
                        r["inverse_dynamics"], whole, r["emg"])  # fmt: skip
    np.testing.assert_array_equal(a.forces, b.forces)
    assert np.isfinite(a.forces).any()


def test_zeros_as_gaps_view_copies_only_what_it_blanks() -> None:
    """No exact-zero sample: a read-only view of the same buffer, the same values; one: the
    blanked copy of :func:`msk.model.markersets.zeros_as_gaps`."""
    from msk.model.markersets import zeros_as_gaps, zeros_as_gaps_view

    rng = np.random.default_rng(5)
    x = rng.normal(size=(30, 4, 3))
    x[3, 1] = np.nan
    v = zeros_as_gaps_view(x)
    assert np.shares_memory(v, x) and not v.flags.writeable
    np.testing.assert_array_equal(v, zeros_as_gaps(x))
    x[7, 2] = 0.0
    c = zeros_as_gaps_view(x)
    assert not np.shares_memory(c, x) and np.isnan(c[7, 2]).all()
    np.testing.assert_array_equal(c, zeros_as_gaps(x))


def test_model_stage_markers_in_blocks_equal_the_whole_trial(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The model stage's levelled and model-frame markers of a trial longer than a block: the
    heading (pelvis fit and progression) computed block by block equals the one-pass heading,
    and :func:`msk.personalise.task_markers.model_frame_columns` equals ``match.apply`` of the whole
    rotated trial, bit for bit (gc5_PS's task, blocks of 7 and 40 frames, a gap of exact
    zeros)."""
    from msk.config import load_config
    from msk.io import frames
    from msk.model.markersets import recognise
    from msk.personalise.task_markers import model_frame_columns
    from msk.pipeline.inputs import session_inputs
    from msk.pipeline.model import load_model_file

    cfg = load_config(REPO / "pipelines" / "gc5_PS.toml")
    read = stages("gc5_PS.toml", "knee_contact")["read"]
    inputs = session_inputs(cfg)
    assert inputs.model_source is not None and inputs.model_cfg is not None
    model = load_model_file(inputs.model_source, inputs.model_cfg.markers)
    trial = read.trial
    x = np.array(trial.markers, dtype=float)
    x[20:25, 3] = 0.0  # exact zeros: gaps
    trial = dataclasses.replace(trial, markers=x)
    match = recognise(trial.marker_labels, model.marker_names, rename=cfg.marker_rename)
    up = -np.asarray(model.gravity, dtype=float)

    def heading() -> tuple[Any, np.ndarray]:
        h = frames.pelvis_heading_rotation(
            trial.up, up, x, trial.marker_labels, model, rename=match.rename
        )
        return h, frames.lab_to_model_rotation(trial.up, up, x)

    whole, rot_whole = heading()
    whole_cols = match.apply(trial.rotated(whole.rotation).markers, trial.marker_labels)
    for size in (7, 40):
        monkeypatch.setattr(frames, "HEADING_BLOCK", size)
        monkeypatch.setattr(blocks, "FRAME_BLOCK", size)
        part, rot_part = heading()
        np.testing.assert_array_equal(part.rotation, whole.rotation)
        rest = [f.name for f in dataclasses.fields(whole) if f.name != "rotation"]
        assert [getattr(part, f) for f in rest] == [getattr(whole, f) for f in rest]
        np.testing.assert_array_equal(rot_part, rot_whole)
        cols, names = model_frame_columns(trial, whole.rotation, match)
        assert names == whole_cols[1]
        np.testing.assert_array_equal(cols, whole_cols[0])
    assert whole.source in ("pelvis markers", "progression")


def test_loads_stage_in_point_blocks_equals_one_pass(monkeypatch: pytest.MonkeyPatch) -> None:
    """gc5_PS's loads stage (plates rotated and sampled one at a time, the feet's speeds for
    the measured-contact test block by block of ``msk.dynamics.loads._POINT_BLOCK`` frames): blocks
    of
    8 frames give the one-pass result bit for bit (external loads, measured and usable
    frames)."""
    import msk.dynamics.loads as ml
    from msk.config import load_config
    from msk.pipeline import loads as stage
    from msk.pipeline.inputs import session_inputs

    cfg = load_config(REPO / "pipelines" / "gc5_PS.toml")
    r = stages("gc5_PS.toml", "knee_contact")
    inputs = session_inputs(cfg)
    one = stage.run(inputs, r["read"], r["model"], r["kinematics"])
    monkeypatch.setattr(ml, "_POINT_BLOCK", 8)
    many = stage.run(inputs, r["read"], r["model"], r["kinematics"])
    np.testing.assert_array_equal(many.measured, one.measured)
    np.testing.assert_array_equal(many.usable, one.usable)
    for f in ("force", "moment", "point"):
        np.testing.assert_array_equal(getattr(many.external, f), getattr(one.external, f))
    assert one.measured.any() and not one.measured.all()


def test_run_graph_trims_a_result_after_the_node_named() -> None:
    """With ``keep``, a trim replaces a result once its ``after`` node has run: the nodes
    before see it whole, those after the trimmed one; without ``keep``, nothing is trimmed."""
    from types import SimpleNamespace

    from msk.pipeline.graph import Node, run_graph
    from msk.pipeline.runner import Runner

    seen: dict[str, tuple[str, ...]] = {}

    def source(inputs: object) -> tuple[str, ...]:
        return ("a", "b")

    def first(inputs: object, source: tuple[str, ...]) -> str:
        seen["first"] = source
        return "first"

    def second(inputs: object, source: tuple[str, ...], first: str) -> str:
        seen["second"] = source
        return "second"

    graph = (
        Node("source", source),
        Node("first", first, ("source",)),
        Node("second", second, ("source", "first")),
    )
    trims = (("first", "source", lambda s: s[:1]),)
    names = tuple(n.name for n in graph)
    inputs = SimpleNamespace(gait=True)

    def runner() -> Runner:
        return Runner(None, None, stages=names, core=frozenset())

    out = run_graph(inputs, runner(), graph, keep=("second",), trims=trims)  # type: ignore[arg-type]
    assert out == {"second": "second"}
    assert seen == {"first": ("a", "b"), "second": ("a",)}
    run_graph(inputs, runner(), graph, trims=trims)  # type: ignore[arg-type]
    assert seen == {"first": ("a", "b"), "second": ("a", "b")}


def test_read_trims_drop_markers_and_plates_only() -> None:
    """``without_markers`` / ``without_plates`` (the graph's TRIMS) drop the task's markers and
    the plates and share everything else; the model stage holds its own markers (model frame,
    not the read result's array), so that dropping them from ``read`` frees them."""
    from msk.pipeline import model as model_stage
    from msk.pipeline import read as read_stage
    from msk.pipeline.graph import GRAPH, TRIMS

    names = [n.name for n in GRAPH]
    assert [(a, r) for a, r, _ in TRIMS] == [
        ("model", "read"),
        ("loads", "read"),
        ("gait_analysis", "model"),
    ]
    # the model's markers: read by the kinematics stage and the step swapped_markers only
    # (the summary takes that step's pairs); the step runs right after the kinematics
    assert names.index("swapped_markers") == names.index("kinematics") + 1
    # no node after the model stage but the loads, mass identification and EMG stages reads
    # ``read``, and none of them the markers (their code: loads.assign_loads takes the plates,
    # mass_identification the assignment, emg the analog channels)
    readers = [n.name for n in GRAPH if "read" in n.reads_results]
    assert readers == ["measured_contact", "model", "loads", "mass_identification", "emg"]
    assert names.index("model") < names.index("loads") < names.index("emg")
    r = stages("gc5_PS.toml", "knee_contact")
    built, read = r["model"], r["read"]
    assert not np.shares_memory(built.trial.markers, read.trial.markers)
    assert not np.shares_memory(r["kinematics"].q, built.trial.markers)
    assert r["swapped_markers"] == ()  # gc5_PS: no swapped pair
    slim = model_stage.without_markers(built)
    assert slim.trial.markers.shape == (built.trial.time.size, 0, 3)
    assert slim.trial.marker_labels == built.trial.marker_labels
    assert slim.trial.gaps is built.trial.gaps and slim.trial.events is built.trial.events
    assert slim.model is built.model and slim.labels == built.labels
    light = read_stage.without_plates(read_stage.without_markers(read))
    assert light.plates == () and light.trial.markers.shape == (read.trial.time.size, 0, 3)
    assert light.trial.marker_labels == () and light.trial.analogs is read.trial.analogs
    assert light.trial.analog_time is read.trial.analog_time and light.contact is read.contact
    assert light.assignment == read.assignment and read.plates and read.trial.marker_labels
