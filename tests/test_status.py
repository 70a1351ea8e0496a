"""msk.status: one vocabulary (identified | at bound | not determined | prior) for every
identified quantity; property tests of the rules that issue 17 found broken."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msk.status import (
    STATUS_CODES,
    STRENGTH_CI_REL_WIDTH_MAX,
    STRENGTH_R2_MIN,
    Status,
    fes_status,
    gain_status,
    group_status,
    inertia_status,
    segment_status,
    status_from_code,
    strength_status,
)

LO, HI = 0.5, 2.0
inside = st.floats(0.51, 1.99)
good_r2 = st.floats(STRENGTH_R2_MIN, 1.0)


def test_words_and_codes():
    assert [s.value for s in Status] == ["identified", "at bound", "not determined", "prior"]
    assert sorted(STATUS_CODES.values()) == [0, 1, 2, 3]
    for word, code in STATUS_CODES.items():
        assert status_from_code(float(code)) == word
    assert Status.AT_BOUND == "at bound"  # a str: JSON writes the word


def test_the_bundled_session_numbers():
    # issue 17: factor 0.5 on the bound, interval "0.50–0.50", r² −0.11
    assert strength_status(0.5, 0.5, 0.5, LO, HI, -0.11) == "at bound"
    assert strength_status(0.4999999999999999, 0.5, 0.5, LO, HI, 0.9) == "at bound"
    assert strength_status(2.0000000000000004, 1.5, 2.0, LO, HI, 0.9) == "at bound"
    assert strength_status(0.73, 0.5, 2.0, LO, HI, -0.11) == "not determined"
    assert strength_status(1.13, 0.9, 1.3, LO, HI, 0.8) == "identified"
    assert strength_status(1.0, math.nan, math.nan, LO, HI, 0.8, gated=False) == "prior"
    assert strength_status(1.1, math.nan, math.nan, LO, HI, 0.8) == "not determined"
    assert strength_status(1.1, 0.9, 1.3, LO, HI, None) == "not determined"


@given(
    bound=st.sampled_from([LO, HI]),
    ulps=st.integers(-4, 4),
    ci=st.tuples(inside, inside),
    r2=st.floats(-1.0, 1.0),
)
def test_a_factor_within_rounding_of_a_bound_is_at_bound(bound, ulps, ci, r2):
    f = bound
    for _ in range(abs(ulps)):
        f = np.nextafter(f, math.inf if ulps > 0 else -math.inf)
    s = strength_status(float(f), min(ci), max(ci), LO, HI, r2)
    assert s == Status.AT_BOUND


@given(factor=inside, other=inside, side=st.sampled_from(["low", "high"]), r2=good_r2)
def test_an_interval_touching_a_bound_is_never_identified(factor, other, side, r2):
    lo, hi = (LO, max(factor, other)) if side == "low" else (min(factor, other), HI)
    s = strength_status(factor, lo, hi, LO, HI, r2)
    assert s != Status.IDENTIFIED and s == Status.NOT_DETERMINED


def test_a_wide_interval_is_not_identified():
    # the audit's case: bounds [0, 3], factor 0.45, interval 0.013–0.880 (wider than the factor)
    assert strength_status(0.45, 0.013, 0.880, 0.0, 3.0, 0.8) == "not determined"
    assert strength_status(0.45, 0.30, 0.70, 0.0, 3.0, 0.8) == "identified"


@given(factor=inside, ci=st.tuples(inside, inside), r2=good_r2)
def test_identified_means_an_interval_narrower_than_the_factor(factor, ci, r2):
    lo, hi = min(ci), max(ci)
    s = strength_status(factor, lo, hi, LO, HI, r2)
    assert (s == Status.IDENTIFIED) == (hi - lo <= STRENGTH_CI_REL_WIDTH_MAX * factor)


@given(factor=inside, ci=st.tuples(inside, inside), r2=st.floats(-10.0, STRENGTH_R2_MIN))
def test_a_poor_fit_is_never_identified(factor, ci, r2):
    if r2 >= STRENGTH_R2_MIN:
        return
    assert strength_status(factor, min(ci), max(ci), LO, HI, r2) != Status.IDENTIFIED


@settings(max_examples=200)
@given(
    factor=st.floats(0.0, 3.0),
    a=st.floats(0.0, 3.0) | st.just(math.nan),
    b=st.floats(0.0, 3.0) | st.just(math.nan),
    r2=st.floats(-5.0, 1.0) | st.none(),
    gated=st.booleans(),
)
def test_identified_only_strictly_inside_with_an_adequate_fit(factor, a, b, r2, gated):
    s = strength_status(factor, a, b, LO, HI, r2, gated=gated)
    assert isinstance(s, Status)
    if s == Status.IDENTIFIED:
        assert gated and r2 is not None and r2 >= STRENGTH_R2_MIN
        assert LO < min(a, b) and max(a, b) < HI and LO < factor < HI
        assert not any(math.isclose(x, bd) for x in (factor, a, b) for bd in (LO, HI))


def test_segment_that_moved_far_is_not_prior():
    # issue 17: a rank-deficient trial moved segments 49–89 % from the prior
    for moved in (0.49, 0.89):
        s = inertia_status(10.0 * (1 + moved), 10.0, 4.0, com_std=[0.03] * 3)
        assert s == Status.NOT_DETERMINED
    assert inertia_status(10.2, 10.0, 2.9, com_std=[0.03] * 3) == Status.PRIOR
    # moved COM only
    s = inertia_status(10.0, 10.0, 2.9, com=[0.05, 0, 0], prior_com=[0, 0, 0])
    assert s == Status.NOT_DETERMINED
    # precise: identified wherever it is
    assert inertia_status(14.0, 10.0, 0.1, com_std=[0.002] * 3) == Status.IDENTIFIED
    assert inertia_status(math.nan, 10.0, 0.1) == Status.NOT_DETERMINED


@given(prior=st.floats(0.05, 60.0), rel=st.floats(0.07, 5.0), rel_std=st.floats(0.021, 1.0))
def test_a_segment_moved_beyond_the_prior_tolerance_is_never_prior(prior, rel, rel_std):
    m = prior * (1 + rel)
    assert inertia_status(m, prior, rel_std * m) == Status.NOT_DETERMINED


def test_summary_records_including_old_ones():
    st_rec = {"bounds": [0.5, 2.0], "r2": -0.11}
    # written before the status existed: identified meant "passed the correlation gate"
    old = {"group": "rf", "factor": 0.5, "ci_low": 0.5, "ci_high": 0.5, "identified": True}
    assert group_status(old, st_rec) == "at bound"
    assert group_status({**old, "status": "prior"}, st_rec) == "prior"
    seg = {"mass_kg": 18.2, "prior_mass_kg": 12.97, "mass_std_kg": 3.07, "flag": "prior"}
    assert segment_status(seg) == "not determined"


def test_gain_and_fes_status():
    assert gain_status(0.0) == "at bound"
    assert gain_status(1e-9) == "at bound"
    # no interval (the EMG-assisted fit computes none): its precision is unknown
    assert gain_status(1.7) == "not determined"
    assert gain_status(1.7, ci=(1.5, 1.9)) == "identified"
    assert gain_status(1.7, ci=(0.2, 3.0)) == "not determined"
    assert gain_status(1.7, ci=(0.0, 1.9)) == "not determined"
    assert gain_status(1.7, converged=False) == "not determined"
    assert gain_status(math.inf) == "not determined"
    assert gain_status(1.0, prior=1.0) == "prior"
    assert fes_status(0.04, from_prior=True) == "prior"
    assert fes_status(3.0, prior=3.0, nrmsd_pct=2.0) == "prior"
    assert fes_status(3.5, prior=3.0, nrmsd_pct=2.0) == "identified"
    # k_s after a good fit: the protocol does not determine it (docs/fes.md recovery)
    assert fes_status(3.5, prior=3.0, nrmsd_pct=2.0, determined=False) == "not determined"
    assert fes_status(3.0, prior=3.0, nrmsd_pct=2.0, determined=False) == "prior"
    assert fes_status(3.5, prior=3.0, nrmsd_pct=40.0) == "not determined"
    assert fes_status(1e6, prior=3.0, nrmsd_pct=2.0, upper=1e6) == "at bound"


@pytest.mark.parametrize("name", ["WELL_IDENTIFIED_MASS_REL_STD", "WELL_IDENTIFIED_COM_STD_M"])
def test_thresholds_agree_with_the_identification_flags(name):
    import msk.dynamics.identification as ident
    import msk.status as status

    assert getattr(status, name) == getattr(ident, name)
