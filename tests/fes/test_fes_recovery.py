"""Per-parameter recovery of the FES protocol on all 13 seeds/000 Table 3 legs with population
priors (Table 3 means without the leg's subject), 1 % torque and 0.5° angle noise.

The figures asserted are the ones reached (docs/fes.md, ``bench/fes_recovery.py``), not a
blanket tolerance: the passive parameters are recovered; the muscle parameters are not, because
the K_cm/F_cm prior is off by −30 … +178 % on these legs and the k_s NLP compensates it.
"""

from __future__ import annotations

import numpy as np
import pytest

from msk.fes.model import TABLE3
from msk.fes.recovery import RecoveryRun, recovery_run
from msk.status import FES_DETERMINED_BY_PROTOCOL


@pytest.fixture(scope="module")
def runs() -> dict[str, RecoveryRun]:
    return {leg: recovery_run(leg) for leg in TABLE3}


def _within(runs: dict[str, RecoveryRun], name: str, tol: float) -> int:
    return sum(1 for r in runs.values() if r.ok and abs(r.error[name]) <= tol)


@pytest.mark.slow
def test_population_prior_recovery_per_parameter(runs: dict[str, RecoveryRun]) -> None:
    assert len(runs) == 13
    failed = {leg: r.failure for leg, r in runs.items() if not r.ok}
    # S6R (F_cm 45 N): the pass-0 k_s NLP fails (typed error); every other leg gives a result
    assert set(failed) <= {"S6R"}, failed
    assert all("pass 0" in f and "k_s NLP" in f for f in failed.values()), failed
    for r in runs.values():
        if r.ok:  # priors never contain the leg's own values: its subject is left out
            assert abs(r.prior_error["stiffness_ratio"]) > 0.01
    # passive knee: within 1 % on every leg that ran
    for name in ("K", "J", "B"):
        assert _within(runs, name, 0.01) >= 12, name
    # geometry: from stature through a polynomial calibrated on Table 3 (circular, see docs)
    assert _within(runs, "L_ext", 0.005) >= 12 and _within(runs, "r_q", 0.005) >= 12
    # muscle: the figures reached (legs within the tolerance, out of 13)
    reached = {
        ("L_c0", 0.05): 8,
        ("L_c0", 0.15): 12,
        ("L_s", 0.05): 10,
        ("L_s", 0.15): 12,
        ("b", 0.05): 3,
        ("b", 0.25): 7,
        ("F_cm", 0.05): 3,
        ("F_cm", 0.10): 6,
        ("F_cm", 0.25): 8,
        ("F_cm·α_max", 0.05): 4,
        ("F_cm·α_max", 0.10): 6,
        ("F_cm·α_max", 0.30): 9,
        ("K_cm", 0.05): 3,
        ("K_cm", 0.30): 8,
        ("k_s", 0.10): 3,
        ("k_s", 0.50): 7,
        ("c1", 0.05): 5,
        ("c1", 0.10): 7,
        ("c1", 0.25): 9,
        ("c2", 0.10): 5,
        ("c2", 0.25): 8,
        ("c3", 0.05): 6,
        ("c3", 0.25): 8,
    }
    got = {key: _within(runs, *key) for key in reached}
    low = {key: (got[key], n) for key, n in reached.items() if got[key] < n}
    assert not low, f"fewer legs than recorded in docs/fes.md (got, recorded): {low}"
    # what the report may call "identified" (msk.status.FES_DETERMINED_BY_PROTOCOL): within
    # 15 % on at least 12 of the 13 legs; every other reported muscle parameter is not
    for key in ("knee.K", "knee.J", "knee.B", "muscle.L_c0", "muscle.b", "muscle.F_cm",
                "muscle.k_s", "recruitment.c1", "recruitment.c2", "recruitment.c3"):  # fmt: skip
        name = key.split(".")[1]
        recovered = _within(runs, name, 0.15) >= 12
        assert recovered == (key in FES_DETERMINED_BY_PROTOCOL), (key, _within(runs, name, 0.15))


@pytest.mark.slow
def test_population_prior_cross_validation(runs: dict[str, RecoveryRun]) -> None:
    """The identified model still predicts the unseen stimulation: NRMSD < 13 % on every leg
    that ran (seeds/000 Table 2 cross-validation: 5.2–50.5 % on real legs)."""
    cv = [r.nrmsd_cross_validation for r in runs.values() if r.ok]
    assert len(cv) >= 12 and max(cv) < 13.0
    assert np.median(cv) < 8.0
