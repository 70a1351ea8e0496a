"""Population priors from seeds/000 Table 3 (msk.fes.priors)."""

from __future__ import annotations

import numpy as np
import pytest

from msk.exceptions import IdentificationError
from msk.fes.model import TABLE3
from msk.fes.priors import leg_values, population_priors


def test_population_priors_are_table3_means_and_sds() -> None:
    pop = population_priors()
    assert len(pop.legs) == 13
    ratios = [s.muscle.K_cm / s.muscle.F_cm for s in TABLE3.values()]
    assert pop.stiffness_ratio == pytest.approx(np.mean(ratios))
    assert pop.sd["stiffness_ratio"] == pytest.approx(np.std(ratios, ddof=1))
    assert pop.mean["F_cm"] == pytest.approx(np.mean([s.muscle.F_cm for s in TABLE3.values()]))
    assert 0.19 < pop.fibre_fraction < 0.2  # L_s from the assumed 60° optimum: tiny spread
    assert pop.cv("fibre_fraction") < 0.02 < 0.2 < pop.cv("stiffness_ratio")


def test_leave_subject_out_never_contains_the_leg() -> None:
    pop = population_priors(exclude=["S9"])
    assert "S9L" not in pop.legs and "S9R" not in pop.legs and len(pop.legs) == 11
    rest = [leg_values(TABLE3[k])["stiffness_ratio"] for k in pop.legs]
    assert pop.stiffness_ratio == pytest.approx(np.mean(rest))
    assert population_priors(exclude=["S3L"]).legs == tuple(k for k in TABLE3 if k != "S3L")
    with pytest.raises(IdentificationError):
        population_priors(exclude=[k for k in TABLE3][:12])


def test_leave_subject_out_prior_errors_of_the_recovery_study() -> None:
    """docs/fes.md: with its subject left out, the fibre-fraction prior is within 3.2 % of every
    leg's own value (Table 3's L_s comes from one assumed 60° optimum), the K_cm/F_cm prior is
    −30 … +178 % off (S6R … S9L)."""
    ff_err, ratio_err = {}, {}
    for leg, s in TABLE3.items():
        pop = population_priors(exclude=[leg[:-1]])
        own = leg_values(s)
        ff_err[leg] = pop.fibre_fraction / own["fibre_fraction"] - 1.0
        ratio_err[leg] = pop.stiffness_ratio / own["stiffness_ratio"] - 1.0
    assert max(abs(e) for e in ff_err.values()) < 0.032
    assert min(ratio_err, key=ratio_err.__getitem__) == "S6R"
    assert max(ratio_err, key=ratio_err.__getitem__) == "S9L"
    assert -0.31 < ratio_err["S6R"] < -0.29 and 1.77 < ratio_err["S9L"] < 1.79
