"""Validation on the Grand Challenge (5th) subject PS: predicted vs measured (eTibia) tibial
contact force, quadriceps forces vs EMG, and the W_emg trade-off of seeds/002 Table I.

Full chain per trial: gait2392 (shipped as ``gait2392``) scaled to ``PS_static_for_scaling.trc``
(75 kg, the mass the data's source assumes) → IK → plate loads → ID → muscle geometry →
OpenSim-equivalent static optimisation (Σ a², Thelen2003 curves of gait2392, rigid tendon,
``a ∈ [0.01, 1]``, pelvis residual actuators of optimal force 1) → knee contact force of the
instrumented LEFT knee (:mod:`msk.contact.knee`) → 101 samples over Left Foot Strike → next Left
Foot
Strike (the interval the eTibia curves support, see ``test_etibia_interval_is_the_gait_cycle``).

The marker names of the data differ from gait2392's marker set: the model marker → lab label
mapping is the ``[markers] rename`` of ``pipelines/gc5_PS.toml`` (the lab pipeline's session
file) when present, else :data:`RENAME` (the same mapping). Mapping gait2392's acromion
markers to the lab's ``RShoulder``/``LShoulder`` makes IK worse (30 vs 22 mm RMS): they are
left to be placed. The
static trial's other markers (thigh/shank clusters, PSIS…) are added to the scaled model where
they sit (:func:`msk.personalise.scaling.place_markers`), as the pipeline does.

Issue 7 variants (:class:`Variant`, table in ``docs/validation.md``): body mass from the plates
instead of 75 kg, the lab's foot markers moved to their static positions (``FOOT_MARKERS``),
and the criterion (Σ a², stress², volume-weighted Σ V a², Σ a³). Nothing is fitted to the eTibia
force. ``MEASURED`` (plate mass + lab foot markers, Σ a²) and ``RECOMMENDED`` (the same with
Σ V a²) are asserted besides the baseline, and ``EMG_ASSISTED`` (RECOMMENDED + w Σ (a − g ê)²,
EMG gains fitted leave-one-trial-out on the other trials' ID torques, :func:`loto_gains`).

Run as a script (``python -m tests.test_validation_gc5`` from the repository root) to print the
figures of ``docs/validation.md``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from msk.contact.knee import G0
from msk.optimization import STATUS_SOLVER_FAILED
from tests.support.gc5 import (
    BASELINE,
    BW,
    EMG_ASSISTED,
    MEASURED,
    QUADRICEPS,
    RECOMMENDED,
    TRIALS,
    VARIANTS,
    Gc5Run,
    Variant,
    contact_metrics,
    emg_weighted_contact,
    loto_gains,
    need_data,
    plate_mass_kg,
    quadriceps_spearman,
    run_trial,
    sweep,
)

# ---------------------------------------------------------------------------------------------
# tests
# ---------------------------------------------------------------------------------------------
#: floors reached (see docs/validation.md), with a small margin: r ≥, RMSE (BW of the variant) ≤
FLOORS: dict[Variant, dict[str, dict[str, float]]] = {
    BASELINE: {
        "PS_ngait_og_ss1": {"r": 0.86, "rmse_bw": 0.68},
        "PS_ngait_og_ss3": {"r": 0.80, "rmse_bw": 0.75},
        "PS_ngait_og_ss8": {"r": 0.80, "rmse_bw": 0.73},
    },
    MEASURED: {
        "PS_ngait_og_ss1": {"r": 0.88, "rmse_bw": 0.43},
        "PS_ngait_og_ss3": {"r": 0.81, "rmse_bw": 0.52},
        "PS_ngait_og_ss8": {"r": 0.82, "rmse_bw": 0.49},
    },
    RECOMMENDED: {
        "PS_ngait_og_ss1": {"r": 0.90, "rmse_bw": 0.40},
        "PS_ngait_og_ss3": {"r": 0.83, "rmse_bw": 0.49},
        "PS_ngait_og_ss8": {"r": 0.82, "rmse_bw": 0.47},
    },
    EMG_ASSISTED: {  # reached: r 0.923 / 0.852 / 0.877, RMSE 0.321 / 0.443 / 0.389
        "PS_ngait_og_ss1": {"r": 0.91, "rmse_bw": 0.34},
        "PS_ngait_og_ss3": {"r": 0.84, "rmse_bw": 0.46},
        "PS_ngait_og_ss8": {"r": 0.86, "rmse_bw": 0.41},
    },
}
#: largest peak over-prediction (BW) of each variant
PEAK_ERROR_MAX = {BASELINE: 2.0, MEASURED: 1.0, RECOMMENDED: 1.0, EMG_ASSISTED: 0.8}


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.parametrize(
    "variant", list(FLOORS), ids=["baseline", "measured", "recommended", "emg_assisted"]
)
@pytest.mark.parametrize("name", TRIALS)
def test_knee_contact_force_follows_the_etibia(real_dir: Path, name: str, variant: Variant) -> None:
    need_data(real_dir)
    run = run_trial(name, variant)
    assert run.kin.failed_frames.size == 0
    a, b = run.cycle
    inside = (run.kin.time >= a) & (run.kin.time <= b)
    assert np.isfinite(run.contact.total[inside]).all()
    m = contact_metrics(run)
    floor = FLOORS[variant][name]
    assert m["r"] >= floor["r"], m
    assert m["rmse_bw"] <= floor["rmse_bw"], m
    # the prediction overestimates the late-stance peak (no ligaments, generic model)
    assert 0.0 < m["peak_error_bw"] < PEAK_ERROR_MAX[variant], m
    # swing (last 35 % of the cycle) is light in both: below 1.3 BW
    assert run.on_cycle(run.contact.total)[65:].max() < 1.3 * variant.bw


@pytest.mark.slow
@pytest.mark.realdata
def test_emg_assisted_so_lowers_the_contact_error(real_dir: Path) -> None:
    """EMG-assisted SO (variant N: RECOMMENDED + w Σ (a − g ê)², w = 1, gains fitted on the two
    other trials' ID torques) lowers the RMSE of RECOMMENDED on every trial by > 0.02 BW and
    the late-stance (45–55 % of the cycle) over-prediction by > 0.15 BW; the gains are
    EMG-to-activation scales well below 1 (session-peak EMG asks for too much force)."""
    need_data(real_dir)
    for name in TRIALS:
        n, j = run_trial(name, EMG_ASSISTED), run_trial(name, RECOMMENDED)
        assert contact_metrics(n)["rmse_bw"] < contact_metrics(j)["rmse_bw"] - 0.02, name

        def late(run: Gc5Run) -> float:
            return float(np.mean((run.on_cycle(run.contact.total) - run.etibia_total)[45:56]))

        assert late(n) < late(j) - 0.15 * EMG_ASSISTED.bw, (name, late(n), late(j))
        groups, gains, _ = loto_gains(name, EMG_ASSISTED)
        assert len(groups) == 14 and np.all(gains < 0.6), dict(zip(groups, gains))
        assert n.so.status.size and not np.any(n.so.status == STATUS_SOLVER_FAILED)


@pytest.mark.slow
@pytest.mark.realdata
def test_plate_mass_and_lab_foot_markers(real_dir: Path) -> None:
    """The plates weigh PS at 82.8 kg (the mass identification finds 83.1 kg, the source assumes
    75 kg); placing the lab's foot markers halves the IK marker RMS (21–22 → < 11 mm)."""
    need_data(real_dir)
    assert 82.3 < plate_mass_kg() < 83.3
    for name in TRIALS:
        base = np.nanmean(run_trial(name).kin.marker_rms)
        fixed = np.nanmean(run_trial(name, MEASURED).kin.marker_rms)
        assert base > 0.02 and fixed < 0.011, (name, base, fixed)


@pytest.mark.slow
@pytest.mark.realdata
def test_etibia_interval_is_the_gait_cycle(real_dir: Path) -> None:
    """The 101 eTibia samples span Left Foot Strike → next Left Foot Strike (the whole cycle):
    the predicted force correlates with them over that interval and not over Foot Strike →
    Foot Off (stance only); the measured curve is also near zero over its last third (swing)."""
    need_data(real_dir)
    for name in TRIALS:
        run = run_trial(name)
        cycle = contact_metrics(run)["r"]
        stance = contact_metrics(run, end=run.foot_off)["r"]
        assert cycle > stance + 0.5, (name, cycle, stance)
        assert run.etibia_total[70:95].max() < 0.5 * BW


@pytest.mark.slow
@pytest.mark.realdata
def test_quadriceps_forces_rank_with_their_emg(real_dir: Path) -> None:
    """Spearman ρ of SO forces vs EMG envelopes (seed 004 Table 4 reports ρ > 0.93 for squats;
    gait with SO gives much less, see docs/validation.md): the vasti agree positively, more so
    with the volume-weighted criterion (recommended variant)."""
    need_data(real_dir)
    for variant, lo, mean in ((BASELINE, 0.15, 0.3), (RECOMMENDED, 0.35, 0.42)):
        rho = {name: quadriceps_spearman(run_trial(name, variant)) for name in TRIALS}
        vasti = [rho[n][m] for n in TRIALS for m in ("vas_med_l", "vas_lat_l")]
        assert min(vasti) > lo, (variant, rho)
        assert np.mean(vasti) > mean, (variant, rho)


@pytest.mark.slow
@pytest.mark.realdata
def test_emg_weight_sweep_reproduces_the_table_i_trade_off(real_dir: Path) -> None:
    """seeds/002 Table I: as W_emg decreases the torque error falls and the forces move away
    from the EMG references (their scale changes)."""
    need_data(real_dir)
    sw = sweep(run_trial("PS_ngait_og_ss1"))
    assert (sw.status == 0).all()
    err = sw.torque_error_rms
    dev = sw.emg_deviation_rms
    assert np.all(np.diff(err) < 0), err  # W_emg decreasing along the sweep
    assert np.all(np.diff(dev) > 0), dev
    assert err[-1] < 0.05 * err[0]
    i = sw.muscle_names.index("vas_lat_l")
    assert sw.max_force[-1, i] != pytest.approx(sw.max_force[0, i], rel=0.05)


@pytest.mark.slow
@pytest.mark.realdata
def test_emg_weighted_contact_is_computed_and_overestimates(real_dir: Path) -> None:
    """The EMG-weighted QP keeps the (session-peak normalised, hence too large) EMG references
    in the torque null space: its contact force follows the cycle loosely and overestimates it
    by several BW (docs/validation.md explains why)."""
    need_data(real_dir)
    e = emg_weighted_contact(run_trial("PS_ngait_og_ss1"), 1e-4)
    assert e["r"] > 0.3, e
    assert e["rmse_bw"] > 1.0 and e["peak_error_bw"] > 2.0, e


# ---------------------------------------------------------------------------------------------
# figures for docs/validation.md
# ---------------------------------------------------------------------------------------------
def main() -> None:  # pragma: no cover - a report, not a test
    import time

    print(f"plate mass {plate_mass_kg():.2f} kg (BW {plate_mass_kg() * G0:.1f} N)")
    print(
        "variant | trial | IK RMS mm | r | RMSE BW_var | RMSE BW75 | peak pred/meas BW_var | "
        "peak err BW_var (BW75) | stance RMSE | non-opt frames | rho vas_med vas_lat rect_fem"
    )
    for label, variant in VARIANTS.items():
        for name in TRIALS:
            run = run_trial(name, variant)
            m = contact_metrics(run)
            m75 = contact_metrics(run, bw=BW)
            rho = quadriceps_spearman(run)
            print(
                f"{label} | {name[-3:]} | {np.nanmean(run.kin.marker_rms) * 1e3:.1f} | "
                f"{m['r']:.3f} | {m['rmse_bw']:.3f} | {m75['rmse_bw']:.3f} | "
                f"{m['peak_pred_bw']:.2f} / {m['peak_meas_bw']:.2f} | {m['peak_error_bw']:+.2f} "
                f"({m75['peak_error_bw']:+.2f}) | {m['stance_rmse_bw']:.3f} | "
                f"{run.so.infeasible_frames.size}/{run.kin.n_frames} | "
                + " ".join(f"{rho[k]:.2f}" for k in QUADRICEPS)
            )
    for name in TRIALS:
        tic = time.perf_counter()
        run = run_trial(name)
        wall = time.perf_counter() - tic
        ms = contact_metrics(run, end=run.foot_off)
        print(f"{name}: baseline FS->FO r {ms['r']:.3f} RMSE {ms['rmse_bw']:.3f} ({wall:.1f} s)")
        for w in (1e-2, 1e-4):
            e = emg_weighted_contact(run, w)
            print(
                f"  EMG-weighted W={w:g}: r {e['r']:.3f} RMSE {e['rmse_bw']:.3f} "
                f"peak err {e['peak_error_bw']:+.2f}"
            )
    sw = sweep(run_trial("PS_ngait_og_ss1"))
    print(sw.table(muscle="vas_lat_l"))
    i = sw.muscle_names.index("med_gas_l")
    print(
        "mean force vas_lat_l, med_gas_l:",
        sw.mean_force[:, sw.muscle_names.index("vas_lat_l")],
        sw.mean_force[:, i],
    )


if __name__ == "__main__":  # pragma: no cover
    main()
