"""Long trials in bounded memory (issue 18): the compact per-frame Jacobian
(:class:`msk.timeseries.FrameSparse`), batch solvers warm-started across calls
(:class:`msk.optimization.WarmStart`) and the pipeline's frame blocks
(:mod:`msk.pipeline.blocks`): blocked results equal unblocked ones to round-off."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import msk.optimization as o
from msk.cache import decode, encode
from msk.optimization.synthetic import leg_like_frames
from msk.pipeline import blocks
from msk.timeseries import FrameSparse

REPO = Path(__file__).resolve().parents[1]


def _sparse_dense(n: int = 7) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(1)
    dense = np.zeros((n, 4, 3))
    pos = np.array([0, 4, 5, 9, 11])
    dense.reshape(n, -1)[:, pos] = rng.normal(size=(n, pos.size))
    return dense, pos


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


@pytest.fixture(scope="module")
def gait2392() -> object:
    from msk.model_files import load_model

    return load_model(REPO / "models" / "gait2392.toml")


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
    from msk.results import read_session

    cfg = load_config(REPO / "pipelines" / "gc5_PS.toml")
    one = run_session(cfg, tmp_path / "one", use_cache=False)
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


def test_identification_regressor_in_blocks_equals_one_pass(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A trial longer than ``REGRESSOR_BLOCK`` is stacked block by block: the same statistics to
    round-off, hence the same fit."""
    import msk.identification as ident
    from msk.synthetic_models import subject_bodies, whole_body_model
    from msk.synthetic_trials import identification_trial

    truth = whole_body_model(subject_bodies("athlete"))
    trial = identification_trial(truth, 4.0, 5)
    kw = {"total_mass": truth.total_mass, "noise_std": np.array([7.0] * 3 + [3.0] * 3)}
    one = ident.InertialIdentifier(truth, **kw).fit(trial)  # type: ignore[arg-type]
    monkeypatch.setattr(ident, "REGRESSOR_BLOCK", 37)
    many = ident.InertialIdentifier(truth, **kw).fit(trial)  # type: ignore[arg-type]
    assert many.n_frames_ == one.n_frames_ > 37
    # the Gram statistics to round-off; the identified parameters to the conic solver's tolerance
    for x in ("_h", "_g", "_c"):
        a, b = getattr(one, x), getattr(many, x)
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-12 * np.abs(a).max(), err_msg=x)
    for name, phi in one.parameters_.items():
        np.testing.assert_allclose(many.parameters_[name], phi, rtol=1e-6, atol=1e-9, err_msg=name)


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
