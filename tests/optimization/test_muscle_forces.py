"""Muscle forces on the frames each leg can be solved in
(:func:`msk.optimization.muscle_forces.solve_muscle_forces` ``unbalanced``): a leg whose foot
stands off the plates is left out of a frame's QP and the other leg solved, with the forces of
the fully measured frame (the tension QP is separable by leg)."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from msk.config.options import ContactConfig, EmgConfig, OptimizationConfig
from msk.dynamics.inverse import coordinates_carrying
from msk.optimization.muscle_forces import left_out, solve_muscle_forces
from msk.pipeline.inputs import SessionInputs
from tests.support.two_legs import muscled_two_legs, two_leg_trial


def _inputs(method: str, channels: dict[str, str] | None = None) -> Any:
    rows = method.endswith("+compartments")
    cfg = SimpleNamespace(
        optimization=OptimizationConfig(
            method=method.removesuffix("+compartments"), compartment_nonnegative=rows
        ),
        emg=EmgConfig(channels=channels or {}),
        contact=ContactConfig(),
    )
    return SimpleNamespace(cfg=cfg, sfx="_r")


def optimise(inputs: Any, model: Any, *args: Any, **kw: Any) -> Any:
    """:func:`solve_muscle_forces` with the options a session's configuration ``inputs`` sets
    (:meth:`msk.pipeline.inputs.SessionInputs.muscle_force_options`)."""
    inputs.knee_plateau = lambda m, joint: SessionInputs.knee_plateau(inputs, m, joint)
    options = SessionInputs.muscle_force_options(inputs, model)
    return solve_muscle_forces(model, *args, **kw, **options)


def _emg(model: Any, n: int) -> Any:
    """Smooth activations of three muscles a leg (channel per muscle)."""
    names = tuple(m for m in (mu.name for mu in model.muscles) if m.split("_")[0] in
                  ("vasti", "hams", "soleus"))  # fmt: skip
    t = np.arange(n) / 100.0
    act = np.stack([0.2 + 0.1 * np.sin(2 * np.pi * t + k) for k in range(len(names))], axis=1)
    return SimpleNamespace(
        muscles=names, activation=act, usable=np.ones(len(names), dtype=bool),
        column=names.index,
    )  # fmt: skip


@pytest.mark.parametrize(
    "method",
    [
        "static_optimization",
        "bounded_qp",
        "closed_form",
        "emg_weighted",
        "emg_assisted",
        "static_optimization+compartments",
    ],
)
def test_a_leg_off_the_plates_leaves_the_other_legs_forces(method: str) -> None:
    """Frames 10–24: the left foot stands off the plates (its leg's torques NaN, as
    :func:`msk.dynamics.inverse.without_unmeasured_contact` leaves them). The right leg's forces
    there
    equal those of the fully measured trial (every criterion: the QP is separable by leg), the
    left leg's are NaN, and every other frame is as before."""
    model = muscled_two_legs()
    kin, tq, geo = two_leg_trial(model)
    n = kin.time.size
    emg = _emg(model, n) if method.startswith("emg") else None
    channels = None if emg is None else {m: m for m in emg.muscles}
    inputs = _inputs(method, channels)
    usable = np.ones(n, dtype=bool)
    kw = {"kinematics": kin, "external": None}
    full = optimise(inputs, model, tq, geo, kin.time, usable, emg, **kw)

    off = np.zeros(n, dtype=bool)
    off[10:25] = True
    left = [c for c in coordinates_carrying(model, "foot_l") if c not in tq.root_coordinates]
    cols = [tq.coordinate_names.index(c) for c in left]
    tau = tq.tau.copy()
    tau[np.ix_(off, cols)] = np.nan
    gated = type(tq)(**{**tq.__dict__, "tau": tau})
    unbalanced = np.zeros_like(tau, dtype=bool)
    unbalanced[np.ix_(off, cols)] = True
    one = optimise(inputs, model, gated, geo, kin.time, usable, emg, unbalanced=unbalanced, **kw)

    names = one.muscles
    right = np.array([m.endswith("_r") for m in names])
    assert np.isfinite(full.forces).all()
    # emg_assisted: the right channels' gains are the same fixed point, to the fit's tolerance
    # (1e-5 on a gain); the left ones are fitted on the frames the left leg is solved in.
    # emg_weighted: its Tikhonov weight ε = 1e-6 · mean_i ‖r_i‖² averages over the muscles
    # posed, and a left-out leg's are not posed (2e-6 relative here)
    tol = {"emg_assisted": 1e-3, "emg_weighted": 1e-5}.get(method, 1e-6)
    np.testing.assert_allclose(one.forces[:, right], full.forces[:, right], rtol=tol, atol=tol)
    assert np.isnan(one.forces[np.ix_(off, ~right)]).all()
    if method != "emg_assisted":
        np.testing.assert_allclose(
            one.forces[np.ix_(~off, ~right)], full.forces[np.ix_(~off, ~right)], rtol=tol,
            atol=tol,
        )  # fmt: skip
    if one.reserve_torques is not None:
        rc = [one.reserve_coordinates.index(c) for c in left]
        assert np.isnan(one.reserve_torques[np.ix_(off, rc)]).all()
        assert np.isfinite(one.reserve_torques[~off]).all()
    if one.frontal_reserve_moments is not None:  # the right knee's rows: solved throughout
        np.testing.assert_allclose(
            one.frontal_reserve_moments, full.frontal_reserve_moments, rtol=tol, atol=tol
        )
        assert one.id_frontal_moment_peak_nm == pytest.approx(full.id_frontal_moment_peak_nm)
    if method == "emg_assisted":
        assert one.emg_gains is not None and full.emg_gains is not None
        for ch, g in full.emg_gains.items():
            if ch.endswith("_r"):
                assert one.emg_gains[ch] == pytest.approx(g, abs=1e-4), ch
    # without ``unbalanced`` a frame with NaN torques is excluded whole (never solved)
    whole = optimise(inputs, model, gated, geo, kin.time, usable, emg, **kw)
    assert np.isnan(whole.forces[off]).all() and whole.excluded_frames == off.sum()


def test_left_out_is_the_component_holding_the_coordinate() -> None:
    """Muscles 0–1 span coordinates 0–1, muscle 2 coordinates 1–2 (joined to them), muscle 3
    coordinate 3 alone: leaving out coordinate 0 leaves out muscles 0–2 and coordinates 0–2."""
    pattern = np.array([[1, 1, 0, 0], [1, 0, 0, 0], [0, 1, 1, 0], [0, 0, 0, 1]], dtype=bool)
    mus, coords = left_out(pattern, np.array([True, False, False, False]))
    np.testing.assert_array_equal(mus, [True, True, True, False])
    np.testing.assert_array_equal(coords, [True, True, True, False])
    mus, coords = left_out(pattern, np.array([False, False, False, True]))
    np.testing.assert_array_equal(mus, [False, False, False, True])
    np.testing.assert_array_equal(coords, [False, False, False, True])


def test_frames_solved_counts_each_leg() -> None:
    """summary.json's ``optimization.frames_solved``: per leg the frames with every one of its
    muscle forces (the right leg in all 5 frames, the left one in 2)."""
    from msk.optimization.muscle_forces import MuscleForces, frames_solved

    f = np.ones((5, 4))
    f[[1, 2], 2] = np.nan
    f[0] = np.nan
    f[0, :2] = 1.0
    sol = MuscleForces(f, f, ("a_r", "b_r", "a_l", "b_l"), "bounded_qp", 0)
    assert frames_solved(sol) == {"r": 5, "l": 2}


def _left_off(model: Any, tq: Any, frames: slice = slice(10, 25)) -> tuple[Any, np.ndarray, Any]:
    """The trial's torques with the left leg's NaN on ``frames`` (its foot off the plates), the
    ``unbalanced`` mask of those frames, and the left leg's coordinates."""
    n = tq.tau.shape[0]
    off = np.zeros(n, dtype=bool)
    off[frames] = True
    left = [c for c in coordinates_carrying(model, "foot_l") if c not in tq.root_coordinates]
    cols = [tq.coordinate_names.index(c) for c in left]
    tau = tq.tau.copy()
    tau[np.ix_(off, cols)] = np.nan
    unbalanced = np.zeros_like(tau, dtype=bool)
    unbalanced[np.ix_(off, cols)] = True
    return type(tq)(**{**tq.__dict__, "tau": tau}), unbalanced, off


@pytest.mark.parametrize("method", ["static_optimization", "static_optimization+compartments"])
def test_a_left_out_leg_is_not_posed(method: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The solver never sees a left-out leg: the QPs of the frames whose left foot is off the
    plates hold the right leg's muscles and coordinates only (and the right knee's compartment
    rows), so the KKT figures and the infeasible count are those of what was solved; every
    frame is checked once."""
    import msk.optimization as o

    model = muscled_two_legs()
    kin, tq, geo = two_leg_trial(model)
    gated, unbalanced, off = _left_off(model, tq)
    calls: list[tuple[np.ndarray, tuple[str, ...], tuple[str, ...], bool]] = []
    real = o.solve_static_optimization_batch

    def spy(jac: Any, tau: Any, **kw: Any) -> Any:
        times = np.asarray(kw["time"])
        calls.append(
            (times, tuple(kw["muscle_names"]), tuple(kw["coordinate_names"]),
             kw.get("inequalities") is not None)
        )  # fmt: skip
        return real(jac, tau, **kw)

    monkeypatch.setattr(o, "solve_static_optimization_batch", spy)
    n = kin.time.size
    one = optimise(
        _inputs(method), model, gated, geo, kin.time, np.ones(n, dtype=bool), None,
        kinematics=kin, external=None, unbalanced=unbalanced,
    )  # fmt: skip
    left_c = {tq.coordinate_names[k] for k in np.flatnonzero(unbalanced.any(axis=0))}
    seen = np.zeros(n, dtype=int)
    for times, mus, coords, rows in calls:
        fr = np.searchsorted(kin.time, times)
        seen[fr] += 1
        if off[fr].all():
            assert not [m for m in mus if m.endswith("_l")] and not (left_c & set(coords))
            assert rows == method.endswith("+compartments")  # the right knee's rows
        else:
            assert not off[fr].any() and len(mus) == len(one.muscles)
    assert (seen == 1).all()
    assert one.kkt is not None and one.kkt.frames == n and one.infeasible_frames == 0
    assert np.isfinite(one.activations[np.ix_(off, [m.endswith("_r") for m in one.muscles])]).all()


def test_a_left_out_legs_unposable_inputs_do_not_exclude_the_frame() -> None:
    """Where the left foot is off the plates, the left leg's moment arms are never read:
    non-finite there, the frame is still solved for the right leg (equal to the
    fully measured trial's forces) and not counted as excluded; without ``unbalanced`` the
    frame is excluded whole."""
    model = muscled_two_legs()
    kin, tq, geo = two_leg_trial(model)
    n = kin.time.size
    inputs, usable = _inputs("static_optimization"), np.ones(n, dtype=bool)
    full = optimise(inputs, model, tq, geo, kin.time, usable, None)
    gated, unbalanced, off = _left_off(model, tq)
    lm = np.array([m.endswith("_l") for m in geo.muscle_names])
    jac = geo.jacobian.copy()
    jac[np.ix_(off, lm)] = np.nan
    bad = type(geo)(**{**geo.__dict__, "jacobian": jac})
    one = optimise(inputs, model, gated, bad, kin.time, usable, None, unbalanced=unbalanced)
    right = np.array([m.endswith("_r") for m in one.muscles])
    assert one.excluded_frames == 0
    np.testing.assert_allclose(one.forces[:, right], full.forces[:, right], rtol=1e-6, atol=1e-6)
    assert np.isnan(one.forces[np.ix_(off, ~right)]).all()
    whole = optimise(inputs, model, gated, bad, kin.time, usable, None)
    assert whole.excluded_frames == off.sum() and np.isnan(whole.forces[off]).all()


def test_left_out_patterns_of_a_leg_off_the_plates() -> None:
    """``left_out_patterns``: with the left foot off the plates in frames 10–24, one pattern
    besides the empty one — the left leg's muscles and coordinates —, those frames' index 1;
    a left moment arm NaN there leaves the frame posable, a right one (frame 12) or a left
    one where the left foot is measured (frame 30) does not."""
    from msk.muscles.geometry import muscle_parameters
    from msk.optimization.muscle_forces import actuated, left_out_patterns

    model = muscled_two_legs()
    kin, tq, geo = two_leg_trial(model)
    n = kin.time.size
    gated, unbalanced, off = _left_off(model, tq)
    act = actuated(tq)
    lm = np.array([m.endswith("_l") for m in geo.muscle_names])
    jac = geo.jacobian.copy()
    jac[np.ix_(off, lm)] = np.nan
    jac[12, ~lm] = np.nan
    jac[30, lm] = np.nan
    bad = type(geo)(**{**geo.__dict__, "jacobian": jac})
    posable = np.isfinite(jac[:, :, act]).all(axis=(1, 2))
    drop_m, drop_c, drop_id, pos = left_out_patterns(
        bad, muscle_parameters(model), gated.tau, act, np.ones(n, dtype=bool), posable,
        unbalanced[:, act],
    )  # fmt: skip
    np.testing.assert_array_equal(drop_m, [np.zeros_like(lm), lm])
    left_c = [tq.coordinate_names[k] in coordinates_carrying(model, "foot_l") for k in act]
    np.testing.assert_array_equal(drop_c, [np.zeros(len(act), dtype=bool), left_c])
    np.testing.assert_array_equal(drop_id[off], 1)
    np.testing.assert_array_equal(drop_id[~off], 0)
    expect = np.ones(n, dtype=bool)
    expect[[12, 30]] = False
    np.testing.assert_array_equal(pos, expect)
    assert not posable[off].any()  # the input is not changed


@pytest.mark.parametrize("method", ["static_optimization", "emg_assisted", "closed_form"])
def test_nothing_left_out_is_the_call_without_unbalanced(method: str) -> None:
    """An all-False ``unbalanced`` (every foot measured) gives bit for bit the result of a
    call without it: forces, activations, reserves and KKT figures."""
    model = muscled_two_legs()
    kin, tq, geo = two_leg_trial(model)
    n = kin.time.size
    emg = _emg(model, n) if method.startswith("emg") else None
    inputs = _inputs(method, None if emg is None else {m: m for m in emg.muscles})
    usable = np.ones(n, dtype=bool)
    a = optimise(inputs, model, tq, geo, kin.time, usable, emg)
    b = optimise(inputs, model, tq, geo, kin.time, usable, emg,
                 unbalanced=np.zeros_like(tq.tau, dtype=bool))  # fmt: skip
    np.testing.assert_array_equal(a.forces, b.forces)
    np.testing.assert_array_equal(a.activations, b.activations)
    if a.reserve_torques is not None:
        np.testing.assert_array_equal(a.reserve_torques, b.reserve_torques)
    if a.kkt is not None:
        assert b.kkt is not None
        np.testing.assert_array_equal(a.kkt.value, b.kkt.value)
        np.testing.assert_array_equal(a.kkt.frame, b.kkt.frame)


def test_optimization_figures_count_the_solved_leg_only() -> None:
    """summary.json's ``optimization`` figures and the quality gates that read muscle forces,
    on a result whose left leg is left out of frames 0–5 of 10: the right leg's activations
    there count in its saturation (saturated in 3 of its 10 frames: 30 % > 25 %, flagged; a
    whole-row count saw 0 of 4), the left leg's over its 4 solved frames only; the reserve
    RMS of a left coordinate over its solved frames."""
    from msk.optimization.muscle_forces import MuscleForces, frames_solved
    from msk.quality import optimization_flags

    acts = np.full((10, 4), 0.2)
    acts[:6, 2:] = np.nan  # left leg left out
    acts[[0, 2, 4], 0] = 1.0  # a_r saturated where only the right leg was solved
    rt = np.zeros((10, 2))
    rt[:6, 1] = np.nan
    rt[6:, 1] = 3.0
    sol = MuscleForces(
        acts * 1000.0, acts, ("a_r", "b_r", "a_l", "b_l"), "static_optimization", 0,
        infeasible_frames=0, reserve_torques=rt, reserve_coordinates=("knee_r", "knee_l"),
    )  # fmt: skip
    assert frames_solved(sol) == {"r": 10, "l": 4}
    jt = SimpleNamespace(coordinate_names=("knee_r", "knee_l"), tau=np.full((10, 2), 20.0))
    flags = {f.quantity: f for f in optimization_flags("t", sol, jt)}
    assert flags["a_r_saturated_frames_pct"].value == pytest.approx(30.0)
    assert flags["knee_l_reserve_rms_pct"].value == pytest.approx(15.0)  # 3 of 20 N·m
    assert "knee_r_reserve_rms_pct" not in flags


def test_kkt_summary_is_the_typed_record_of_the_worst_figures() -> None:
    """``summary.optimization.kkt`` built as a typed :class:`msk.results.summary.Kkt`: per
    figure the worst value, relative value, frame and time; the gate's tolerance; it reads
    back equal from its JSON."""
    from msk.optimization import KKT_COLUMNS
    from msk.optimization.muscle_forces import KktWorst, kkt_summary
    from msk.quality import THRESHOLDS
    from msk.results.summary import Kkt

    n = len(KKT_COLUMNS)
    worst = KktWorst(
        columns=KKT_COLUMNS,
        value=np.arange(n) * 1e-9,
        relative=np.arange(n) * 1e-14,
        frame=np.arange(n) + 3,
        time_s=(np.arange(n) + 3) / 100.0,
        frames=42,
    )
    rec = kkt_summary(worst)
    assert rec.frames == 42 and rec.relative_tolerance == THRESHOLDS["kkt_relative"]
    comp = rec.complementarity
    assert comp is not None and comp.frame == n + 2 and comp.max == pytest.approx((n - 1) * 1e-9)
    assert Kkt.from_dict(rec.to_dict()) == rec
    assert list(rec.to_dict())[2:] == list(KKT_COLUMNS)
