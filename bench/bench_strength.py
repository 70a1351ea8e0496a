"""Strength identification + EMG-driven calibration for one synthetic subject (3 trials).

    .venv/bin/python bench/bench_strength.py

Subject: the synthetic leg of :mod:`msk.datasets.strength` (15 muscles, 3 coordinates, knee
extensors ×1.7 and plantar flexors ×0.6 of generic), 3 gait trials of 4 cycles at 100 Hz with
EMG envelope noise (10 % multiplicative, 0.01 additive) and torque noise (3 % of range).

* identification (seeds/002 §V): all 3 trials, windows = cycles, 400 bootstrap replicates;
* calibration (seeds/003): 13 knee/ankle muscles, 4 functional groups, 2 trials of 2 cycles
  (moments from the seeds/003 Hill model with known parameters, EMG noise), 3 starts, Gauss–
  Newton with the casadi Jacobian; validated on the third trial. Optionally (``--ipopt``) the
  same calibration with ipopt (exact Hessian, lifted formulation), and (``--elastic``) with the
  elastic tendon (``tendon="elastic"``: contraction dynamics integrated inside the casadi graph,
  BDF2 with 2 substeps; the data are rigid-tendon data, so this line is a timing).

Target: identification + calibration < 60 s. Speed targets live here, never in tests.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import platform
import sys
import time

import numpy as np

from msk.datasets.strength import (
    CALIBRATION_GROUPS,
    LEG_TRUE_FACTORS,
    calibration_trial,
    calibration_truth,
    gait_trial,
    synthetic_leg,
)
from msk.muscles.activation import emg_to_activation
from msk.muscles.hill import rigid_tendon_state
from msk.strength import EMGDrivenCalibration, StrengthIdentifier


def main() -> None:
    use_ipopt = "--ipopt" in sys.argv
    use_elastic = "--elastic" in sys.argv
    leg = synthetic_leg(0)
    trials = [gait_trial(leg, n_cycles=4, seed=s) for s in (11, 12, 13)]

    # ---------------------------------------------------------------- identification
    t0 = time.perf_counter()
    jac = np.concatenate([t.jacobian for t in trials])
    emg = np.concatenate([t.emg for t in trials])
    tau = np.concatenate([t.tau for t in trials])
    lmt = np.concatenate([t.muscle_tendon_length for t in trials])
    vmt = np.concatenate([t.lengthening_velocity for t in trials])
    windows = np.concatenate([t.cycle + 100 * i for i, t in enumerate(trials)])
    act = emg_to_activation(
        emg, gamma1=-0.5, gamma2=-0.5, shape_factor=-1.0, delay_samples=4, form="exponential"
    )
    state = rigid_tendon_state(leg.params, lmt, vmt)
    idf = StrengthIdentifier(leg.groups, leg.params, n_bootstrap=400).fit(
        jac, act, tau, state, windows=windows
    )
    t_ident = time.perf_counter() - t0
    prof = idf.profile_

    # ---------------------------------------------------------------- calibration
    truth = calibration_truth()
    base = leg.params.subset(truth.muscle_names)
    m = len(truth.muscle_names)
    ctrials = [calibration_trial(leg, truth, seed=s, name=f"trial {s}") for s in (21, 22, 23)]
    t0 = time.perf_counter()
    cal = EMGDrivenCalibration(base, CALIBRATION_GROUPS, n_starts=3, max_iter=100).fit(ctrials[:2])
    t_cal = time.perf_counter() - t0
    val = cal.validate(ctrials[2:])
    t_ipopt = None
    if use_ipopt:
        t0 = time.perf_counter()
        cal_i = EMGDrivenCalibration(
            base, CALIBRATION_GROUPS, n_starts=3, max_iter=100, solver="ipopt"
        ).fit(ctrials[:2])
        t_ipopt = time.perf_counter() - t0

    t_elastic = None
    if use_elastic:
        t0 = time.perf_counter()
        cal_e = EMGDrivenCalibration(
            base, CALIBRATION_GROUPS, n_starts=3, max_iter=100, tendon="elastic"
        ).fit(ctrials[:2])
        t_elastic = time.perf_counter() - t0
        val_e = cal_e.validate(ctrials[2:])

    # ---------------------------------------------------------------- report
    load = os.getloadavg()[0]
    print(f"python {platform.python_version()}, {platform.machine()}, load average {load:.1f}")
    n_frames = jac.shape[0]
    print(
        f"identification: {n_frames} frames, {len(np.unique(windows))} windows, "
        f"15 muscles, 6 groups, 400 bootstrap: {t_ident:.2f} s"
    )
    for g, name in enumerate(prof.group_names):
        print(
            f"  {name:<16} true {LEG_TRUE_FACTORS[name]:.2f}  est {prof.factors[g]:.3f}  "
            f"boot [{prof.ci_low[g]:.3f}, {prof.ci_high[g]:.3f}]  "
            f"cov [{prof.ci_cov_low[g]:.3f}, {prof.ci_cov_high[g]:.3f}]"
        )
    res = cal.result_
    print(
        f"calibration: {sum(t.n_frames for t in ctrials[:2])} frames, {m} muscles, "
        f"{res.n_parameters} parameters, 3 starts (trf + casadi Jacobian): {t_cal:.2f} s"
    )
    print(
        f"  strength factors {np.round(cal.parameters_.strength_factors, 3)} (true 1.7 1 0.6 1.2)"
    )
    print(f"  r² calibration {np.round(res.calibration.r2, 4)}, held-out {np.round(val.r2, 4)}")
    if t_ipopt is not None:
        print(
            f"  ipopt (exact Hessian, lifted): {t_ipopt:.2f} s, factors "
            f"{np.round(cal_i.parameters_.strength_factors, 3)}"
        )
    if t_elastic is not None:
        print(
            f"  elastic tendon (BDF2, 2 substeps): {t_elastic:.2f} s, factors "
            f"{np.round(cal_e.parameters_.strength_factors, 3)}, r² calibration "
            f"{np.round(cal_e.result_.calibration.r2, 4)}, held-out {np.round(val_e.r2, 4)}; "
            f"identification + elastic calibration {t_ident + t_elastic:.2f} s"
        )
    total = t_ident + t_cal
    print(
        f"total {total:.2f} s (target < 60 s); identification / calibration = {t_ident / t_cal:.3f}"
    )


if __name__ == "__main__":
    main()
