import numpy as np
import pytest

from msk.exceptions import MissingDataError, MskError
from msk.signal import block_average, derivative, filtfilt_butter, resample_to


def test_lowpass_keeps_slow_removes_fast_without_lag():
    rate = 1000.0
    t = np.arange(0, 2, 1 / rate)
    slow = np.sin(2 * np.pi * 2 * t)
    x = slow + 0.5 * np.sin(2 * np.pi * 150 * t)
    y = filtfilt_butter(x, rate_hz=rate, cutoff_hz=20.0)
    inner = slice(200, -200)
    assert np.max(np.abs(y[inner] - slow[inner])) < 5e-3
    # zero lag: cross-correlation peak at zero shift
    lags = np.arange(-20, 21)
    cc = [np.dot(np.roll(y, k)[inner], slow[inner]) for k in lags]
    assert lags[int(np.argmax(cc))] == 0


def test_filter_rejects_nan_and_bad_cutoff():
    x = np.ones(100)
    x[10] = np.nan
    with pytest.raises(MissingDataError):
        filtfilt_butter(x, rate_hz=100, cutoff_hz=10)
    with pytest.raises(MskError, match="cutoff"):
        filtfilt_butter(np.ones(100), rate_hz=100, cutoff_hz=60)


def test_resample_block_average_and_derivative():
    t = np.linspace(0, 1, 101)
    x = np.stack([t**2, 3 * t], axis=1)
    y = resample_to(t, x, np.array([0.25, 0.5]))
    np.testing.assert_allclose(y, [[0.0625, 0.75], [0.25, 1.5]], atol=1e-4)
    np.testing.assert_allclose(block_average(np.arange(12.0), 4), [1.5, 5.5, 9.5])
    np.testing.assert_allclose(derivative(t**2, dt=0.01), 2 * t, atol=1e-9)
    np.testing.assert_allclose(derivative(t**3, dt=0.01, order=2)[5:-5], 6 * t[5:-5], atol=1e-6)
