import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.signal import find_peaks as scipy_find_peaks

from msk.exceptions import MissingDataError, MskError
from msk.signal import (
    block_average,
    derivative,
    filtfilt_butter,
    find_peaks,
    lowpass_filtfilt_numpy,
    resample_to,
    true_runs,
)


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


def test_fill_gaps_recovers_smooth_signal_and_leaves_long_gaps_and_edges():
    from msk.signal import fill_gaps

    t = np.linspace(0, 1, 201)
    truth = np.stack([np.sin(2 * np.pi * t), np.cos(2 * np.pi * t) + t], axis=1)
    x = truth.copy()
    x[:3, 0] = np.nan  # leading: stays NaN
    x[50:56, 0] = np.nan  # 6-sample gap: filled
    x[100:140, 1] = np.nan  # 40-sample gap: too long with max_gap=10
    x[170:175, 1] = np.nan  # 5-sample gap: filled
    for method in ("linear", "pchip", "cubic"):
        y = fill_gaps(x, max_gap=10, method=method)
        assert np.isnan(y[:3, 0]).all() and np.isnan(y[100:140, 1]).all()
        # 6 samples over a peak of a 1 Hz sine at 200 Hz: chord error ~6e-3, pchip flattens the
        # extremum (~3e-3), the natural spline follows it (~1e-5)
        tol = {"linear": 8e-3, "pchip": 4e-3, "cubic": 5e-5}[method]
        np.testing.assert_allclose(y[50:56, 0], truth[50:56, 0], atol=tol)
        np.testing.assert_allclose(y[170:175, 1], truth[170:175, 1], atol=tol)
        ok = np.isfinite(x)
        np.testing.assert_array_equal(y[ok], x[ok])
    # no limit: the long gap is bridged too; markers (N, M, 3) along axis 0
    y = fill_gaps(x, method="pchip")
    assert np.isfinite(y[100:140, 1]).all()
    m = np.stack([truth, truth], axis=1)[:, :, :1].repeat(3, axis=2)
    m[10:12, 1] = np.nan
    np.testing.assert_allclose(fill_gaps(m)[10:12, 1], m[10:12, 0], atol=1e-4)


def test_fill_gaps_bad_options():
    from msk.signal import fill_gaps

    with pytest.raises(MskError, match="method"):
        fill_gaps(np.ones(5), method="spline")  # type: ignore[arg-type]
    with pytest.raises(MskError, match="max_gap"):
        fill_gaps(np.ones(5), max_gap=-1)
    np.testing.assert_array_equal(fill_gaps(np.array([np.nan, 1.0, np.nan])), [np.nan, 1.0, np.nan])


# ---- find_peaks: the same selection as scipy.signal.find_peaks ---------------------------------
@settings(max_examples=300, deadline=None)
@given(
    # few distinct levels: plateaus, equal heights and ties in the distance filter are common
    x=arrays(np.float64, st.integers(0, 80), elements=st.integers(-4, 4).map(float)),
    distance=st.integers(1, 12),
    prominence=st.sampled_from([0.0, 0.5, 1.0, 2.5, 6.0]),
)
def test_find_peaks_matches_scipy(x, distance, prominence):
    kwargs = {"distance": distance} | ({"prominence": prominence} if prominence > 0 else {})
    expected, _ = scipy_find_peaks(x, **kwargs)
    np.testing.assert_array_equal(find_peaks(x, distance=distance, prominence=prominence), expected)


def test_find_peaks_on_a_smooth_signal_and_bad_arguments():
    t = np.linspace(0, 4, 401)
    x = np.sin(2 * np.pi * t) + 0.3 * np.sin(2 * np.pi * 7 * t)
    for d, p in [(1, 0.0), (30, 0.2), (60, 1.0)]:
        expected, _ = scipy_find_peaks(x, distance=d, prominence=p or None)
        np.testing.assert_array_equal(find_peaks(x, distance=d, prominence=p), expected)
    assert find_peaks(x, distance=60, prominence=1.0).size == 4  # one per period
    with pytest.raises(MskError, match="distance"):
        find_peaks(x, distance=0)
    with pytest.raises(MskError, match="1-D"):
        find_peaks(np.ones((3, 3)))


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(2, 300),
    columns=st.integers(1, 4),
    order=st.sampled_from([2, 4, 6]),
    cutoff_hz=st.floats(0.5, 59.0),
    seed=st.integers(0, 2**31 - 1),
)
def test_numpy_lowpass_equals_scipy_sosfiltfilt(n, columns, order, cutoff_hz, seed):
    """The numpy-only zero-lag low-pass is filtfilt_butter (scipy's butter + sosfiltfilt with
    the same padding) to rounding: designs, padding and initial conditions alike."""
    x = np.cumsum(np.random.default_rng(seed).normal(size=(n, columns)), axis=0)
    ref = filtfilt_butter(x, rate_hz=120.0, cutoff_hz=cutoff_hz, order=order)
    got = lowpass_filtfilt_numpy(x, rate_hz=120.0, cutoff_hz=cutoff_hz, order=order)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9 * max(1.0, np.abs(ref).max()))
    one = lowpass_filtfilt_numpy(x[:, 0], rate_hz=120.0, cutoff_hz=cutoff_hz, order=order)
    np.testing.assert_allclose(one, ref[:, 0], rtol=0, atol=1e-9 * max(1.0, np.abs(ref).max()))


def test_numpy_lowpass_refuses_what_it_cannot_do():
    x = np.zeros((10, 2))
    with pytest.raises(MskError, match="even order"):
        lowpass_filtfilt_numpy(x, rate_hz=100.0, cutoff_hz=5.0, order=3)
    with pytest.raises(MskError, match="must lie in"):
        lowpass_filtfilt_numpy(x, rate_hz=100.0, cutoff_hz=50.0)
    x[3, 1] = np.nan
    with pytest.raises(MissingDataError):
        lowpass_filtfilt_numpy(x, rate_hz=100.0, cutoff_hz=5.0)


@given(arrays(np.bool_, st.integers(0, 40)))
def test_true_runs_rebuild_the_mask(mask):
    """The runs cover exactly the True samples, are ordered and separated by False."""
    runs = true_runs(mask)
    rebuilt = np.zeros(mask.size, dtype=bool)
    for a, b in runs:
        assert 0 <= a < b <= mask.size
        rebuilt[a:b] = True
    np.testing.assert_array_equal(rebuilt, mask)
    assert all(b1 < a2 for (_, b1), (a2, _) in itertools.pairwise(runs))


def test_causal_lowpass_is_the_forward_butterworth_one_sample_late():
    from scipy import signal as sig

    from msk.signal import CausalLowpass

    rng = np.random.default_rng(0)
    x = np.cumsum(rng.normal(size=(300, 2)), axis=0)
    f = CausalLowpass(2, rate_hz=100.0, cutoff_hz=6.0, order=2)
    ys, dys = [], []
    for row in x:
        f.step(row)
        ys.append(f.y.copy())
        dys.append(f.dy.copy())
    sos = sig.butter(2, 6.0 / 50.0, output="sos")
    ref, _ = sig.sosfilt(sos, x, axis=0, zi=sig.sosfilt_zi(sos)[:, :, None] * x[0])
    np.testing.assert_allclose(np.array(ys)[1:], ref[:-1], atol=1e-10)
    np.testing.assert_allclose(np.array(dys)[2:], (ref[2:] - ref[:-2]) / 0.02, atol=1e-8)


def test_causal_lowpass_lag_is_its_group_delay():
    from msk.signal import CausalLowpass

    for order, analog in ((2, np.sqrt(2.0)), (4, 2.6131)):
        f = CausalLowpass(1, rate_hz=1000.0, cutoff_hz=6.0, order=order)
        # the analog prototype's delay at DC, 1/ω_c Σ 1/sin(...) (bilinear: close at f_c ≪ f_s)
        assert f.group_delay_s == pytest.approx(analog / (2 * np.pi * 6.0), rel=0.01)
        assert f.lag_s == pytest.approx(f.group_delay_s + 1e-3)
        # a slow sine comes out shifted by the lag
        t = np.arange(3000) / 1000.0
        x = np.sin(2 * np.pi * 0.5 * t)
        out = np.empty_like(x)
        for k, v in enumerate(x):
            f.step(np.array([v]))
            out[k] = f.y[0]
        late = t > 1.0
        shifted = np.sin(2 * np.pi * 0.5 * (t[late] - f.lag_s))
        np.testing.assert_allclose(out[late], shifted, atol=2e-3)


def test_causal_lowpass_gradient_scheme_is_the_offline_differences_two_samples_back():
    from scipy import signal as sig

    from msk.signal import CausalLowpass, derivative

    rng = np.random.default_rng(1)
    x = np.cumsum(rng.normal(size=(200, 3)), axis=0)
    f = CausalLowpass(3, rate_hz=100.0, cutoff_hz=6.0, scheme="gradient")
    assert f.lag_s == pytest.approx(f.group_delay_s + 0.02)
    ys, dys, ddys = [], [], []
    for row in x:
        f.step(row)
        ys.append(f.y.copy())
        dys.append(f.dy.copy())
        ddys.append(f.ddy.copy())
    sos = sig.butter(2, 6.0 / 50.0, output="sos")
    ref, _ = sig.sosfilt(sos, x, axis=0, zi=sig.sosfilt_zi(sos)[:, :, None] * x[0])
    # np.gradient twice on the filtered samples (interior), read two samples later
    v, a = derivative(ref, dt=0.01), derivative(ref, dt=0.01, order=2)
    np.testing.assert_allclose(np.array(ys)[4:], ref[2:-2], atol=1e-10)
    np.testing.assert_allclose(np.array(dys)[4:], v[2:-2], atol=1e-8)
    np.testing.assert_allclose(np.array(ddys)[4:], a[2:-2], rtol=1e-9, atol=1e-6)
    with pytest.raises(MskError):
        CausalLowpass(1, rate_hz=100.0, cutoff_hz=6.0, scheme="spline")


def test_linear_phase_lowpass_delays_every_frequency_by_its_half_width():
    """A symmetric FIR: a sine of any frequency comes out with the FIR's gain at that frequency
    and delayed by exactly K samples (no phase distortion); its taps are the zero-lag filter's
    response (:func:`lowpass_filtfilt_numpy` of an impulse), truncated and of sum 1."""
    from msk.signal import LinearPhaseLowpass, lowpass_filtfilt_numpy

    rate, k = 100.0, 10
    f0 = LinearPhaseLowpass(1, rate_hz=rate, cutoff_hz=6.0, half_width=k, scheme="central")
    assert f0.lag_s == pytest.approx((k + 1) / rate)
    taps = f0.taps
    np.testing.assert_allclose(taps, taps[::-1], rtol=0, atol=1e-15)
    assert taps.sum() == pytest.approx(1.0, abs=1e-14)
    imp = np.zeros(401)
    imp[200] = 1.0
    ref = lowpass_filtfilt_numpy(imp, rate_hz=rate, cutoff_hz=6.0)[200 - k : 201 + k]
    np.testing.assert_allclose(taps, ref / ref.sum(), rtol=1e-12)
    t = np.arange(600) / rate
    for hz in (0.7, 2.5, 5.0, 9.0):
        f = LinearPhaseLowpass(1, rate_hz=rate, cutoff_hz=6.0, half_width=k, scheme="central")
        out = np.empty_like(t)
        for n, v in enumerate(np.sin(2 * np.pi * hz * t)):
            f.step(np.array([v]))
            out[n] = f.y[0]
        gain = taps[k] + 2 * sum(
            taps[k + j] * np.cos(2 * np.pi * hz * j / rate) for j in range(1, k + 1)
        )
        late = t > 0.5
        want = gain * np.sin(2 * np.pi * hz * (t[late] - f.lag_s))
        np.testing.assert_allclose(out[late], want, rtol=0, atol=1e-12)
    with pytest.raises(MskError):
        LinearPhaseLowpass(1, rate_hz=rate, cutoff_hz=6.0, half_width=0)


def test_causal_lowpass_refuses_a_cutoff_above_nyquist():
    from msk.signal import CausalLowpass

    with pytest.raises(MskError):
        CausalLowpass(1, rate_hz=10.0, cutoff_hz=6.0)
    with pytest.raises(MskError):
        CausalLowpass(1, rate_hz=100.0, cutoff_hz=6.0, order=3)


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(2, 400),
    columns=st.integers(0, 3),
    order=st.sampled_from([2, 4, 6, 8]),
    rate_hz=st.sampled_from([60.0, 100.0, 120.0, 250.0, 1000.0, 2000.0]),
    fraction=st.floats(0.002, 0.45),
    seed=st.integers(0, 2**31 - 1),
)
def test_numpy_lowpass_is_scipy_bit_for_bit(n, columns, order, rate_hz, fraction, seed):
    """The numpy low- and high-pass design scipy's sections and filter as sosfiltfilt does, to
    the last bit: filtfilt_butter may take them (no scipy.signal import) without changing a
    number."""
    from scipy import signal as sig

    from msk.signal import _butter_sos

    cutoff_hz = fraction * rate_hz
    wn = cutoff_hz / (0.5 * rate_hz)
    shape = (n, columns) if columns else (n,)
    x = np.cumsum(np.random.default_rng(seed).normal(size=shape), axis=0)
    for btype in ("lowpass", "highpass"):
        sos = sig.butter(order, wn, btype=btype, output="sos")
        np.testing.assert_array_equal(_butter_sos(order, wn, btype), sos)
        ref = sig.sosfiltfilt(sos, x, axis=0, padlen=min(3 * (2 * len(sos) + 1), n - 1))
        got = lowpass_filtfilt_numpy(
            x, rate_hz=rate_hz, cutoff_hz=cutoff_hz, order=order, btype=btype
        )
        np.testing.assert_array_equal(got, ref)
