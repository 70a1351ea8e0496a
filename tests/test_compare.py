"""Tests of msk.metrics against scipy / hand computations and textbook data."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy import stats

from msk import metrics as compare
from msk.exceptions import MissingDataError, MskError, ShapeMismatchError

# Shrout & Fleiss (1979), Table 2: 6 targets rated by 4 judges, and their Table 4 results.
SHROUT_FLEISS = np.array(
    [
        [9, 2, 5, 8],
        [6, 1, 3, 2],
        [8, 4, 6, 8],
        [7, 1, 2, 6],
        [10, 5, 6, 9],
        [6, 2, 4, 7],
    ],
    dtype=float,
)


@pytest.mark.parametrize(
    ("form", "expected"),
    [("1,1", 0.17), ("2,1", 0.29), ("3,1", 0.71), ("1,k", 0.44), ("2,k", 0.62), ("3,k", 0.91)],
)
def test_icc_shrout_fleiss_table4(form: compare.IccForm, expected: float) -> None:
    assert compare.icc(SHROUT_FLEISS, form=form) == pytest.approx(expected, abs=0.005)


def test_icc_identical_raters_is_one_and_offset_breaks_agreement_only() -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(size=40)
    assert compare.icc(x, x.copy()) == pytest.approx(1.0)
    # a constant offset keeps consistency ICC(3,1) = 1 but lowers absolute agreement ICC(2,1)
    assert compare.icc(x, x + 1.0, form="3,1") == pytest.approx(1.0)
    assert compare.icc(x, x + 1.0, form="2,1") < 0.9


def test_sem_formula_and_percent_of_range() -> None:
    rng = np.random.default_rng(1)
    a = rng.normal(10, 3, size=200)
    b = a + rng.normal(0, 0.5, size=200)
    data = np.column_stack([a, b])
    v = compare.icc(a, b)
    expected = np.std(data, ddof=1) * np.sqrt(1 - v)
    assert compare.sem(a, b) == pytest.approx(expected)
    pct = compare.sem(a, b, percent_of_range=True)
    assert pct == pytest.approx(100 * expected / (data.max() - data.min()))
    # for two raters with independent error of SD 0.5, SEM ~ 0.5/sqrt(2)*... order 0.35-0.5
    assert 0.2 < compare.sem(a, b) < 0.6


def test_nrmsd_seed000_eq9_by_hand() -> None:
    xm = np.array([0.0, 1.0, 4.0, 2.0])
    xs = np.array([0.5, 1.0, 3.0, 2.0])
    rms = np.sqrt((0.25 + 0 + 1 + 0) / 4)
    assert compare.nrmsd(xm, xs) == pytest.approx(100 * rms / 4.0)
    assert compare.rms(xm, xs) == pytest.approx(rms)


def test_nrmse_seed001_normalised_by_rms_of_measured() -> None:
    xm = np.array([1.0, -1.0, 1.0, -1.0])
    xs = np.array([1.1, -0.9, 0.9, -1.1])
    assert compare.nrmse(xm, xs) == pytest.approx(10.0)
    # not range-normalised: the range is 2, NRMSD would be 5 %
    assert compare.nrmsd(xm, xs) == pytest.approx(5.0)


def test_columnwise_2d() -> None:
    rng = np.random.default_rng(2)
    a = rng.normal(size=(50, 3))
    b = a + rng.normal(scale=0.1, size=(50, 3))
    out = compare.nrmsd(a, b)
    assert isinstance(out, np.ndarray) and out.shape == (3,)
    for j in range(3):
        assert out[j] == pytest.approx(compare.nrmsd(a[:, j], b[:, j]))
    rho = compare.spearman(a, b)
    for j in range(3):
        assert rho[j] == pytest.approx(stats.spearmanr(a[:, j], b[:, j]).statistic)


def test_r2_and_pearson_against_scipy() -> None:
    rng = np.random.default_rng(3)
    x = rng.normal(size=100)
    y = 2 * x + rng.normal(scale=0.5, size=100)
    assert compare.pearson_r(x, y) == pytest.approx(stats.pearsonr(x, y).statistic)
    # r2 of the least-squares line equals pearson r squared
    slope, intercept = np.polyfit(x, y, 1)
    assert compare.r2(y, slope * x + intercept) == pytest.approx(compare.pearson_r(x, y) ** 2)
    assert compare.r2(y, y) == pytest.approx(1.0)


def test_spearman_ties_against_scipy() -> None:
    a = np.array([1, 2, 2, 3, 5, 5, 5, 8], dtype=float)
    b = np.array([2, 1, 4, 3, 7, 6, 6, 9], dtype=float)
    assert compare.spearman(a, b) == pytest.approx(stats.spearmanr(a, b).statistic)


def test_area_ratio_trapezoid() -> None:
    t = np.linspace(0, 1, 101)
    a = np.sin(np.pi * t)  # area 2/pi
    b = np.ones_like(t)  # area 1
    assert compare.area_ratio(a, b, t=t) == pytest.approx(2 / np.pi, rel=1e-3)
    # uniform spacing does not matter
    assert compare.area_ratio(a, b) == pytest.approx(compare.area_ratio(a, b, t=t))


def test_peak_difference_modes() -> None:
    a = np.array([0.0, 3.0, -5.0])
    b = np.array([1.0, 2.0, -1.0])
    assert compare.peak_difference(a, b) == pytest.approx(1.0)
    assert compare.peak_difference(a, b, mode="min") == pytest.approx(-4.0)
    assert compare.peak_difference(a, b, mode="absmax") == pytest.approx(3.0)


def test_bad_input_is_typed() -> None:
    with pytest.raises(ShapeMismatchError, match=r"\(3,\) vs \(4,\)"):
        compare.rms(np.zeros(3), np.zeros(4))
    with pytest.raises(MissingDataError):
        compare.nrmsd(np.array([1.0, np.nan]), np.array([1.0, 2.0]))
    with pytest.raises(MskError):
        compare.icc(np.zeros(5))


finite = st.floats(-1e3, 1e3, allow_nan=False, width=64)


@settings(max_examples=50, deadline=None)
@given(arrays(np.float64, 20, elements=finite), arrays(np.float64, 20, elements=finite))
def test_properties(a: np.ndarray, b: np.ndarray) -> None:
    assert compare.rms(a, a) == 0.0
    assert compare.rms(a, b) == pytest.approx(compare.rms(b, a))
    # scaling both series scales rms, leaves nrmsd unchanged
    if np.ptp(a) > 1e-6:
        assert compare.nrmsd(3 * a, 3 * b) == pytest.approx(compare.nrmsd(a, b), rel=1e-9)
    r = compare.spearman(a, b)
    assert np.isnan(r) or -1.0 <= r <= 1.0
