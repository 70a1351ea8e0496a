"""msk.metrics: the average ranks Spearman's ρ takes, against scipy.stats.rankdata."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import rankdata, spearmanr

from msk.metrics import _rank, spearman


@pytest.mark.parametrize("seed", range(20))
def test_average_ranks_equal_scipy_rankdata_with_ties(seed):
    rng = np.random.default_rng(seed)
    x = rng.integers(0, 5, size=(int(rng.integers(1, 40)), 3)).astype(float)
    np.testing.assert_array_equal(_rank(x), rankdata(x, axis=0))
    np.testing.assert_array_equal(_rank(x[:, 0]), rankdata(x[:, 0]))


def test_spearman_recovers_scipy_spearmanr():
    rng = np.random.default_rng(7)
    a = rng.normal(size=50)
    b = a**3 + 0.1 * rng.normal(size=50)
    assert spearman(a, b) == pytest.approx(spearmanr(a, b).statistic, abs=1e-14)
