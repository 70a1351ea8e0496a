"""Signal processing on time series (time is axis 0): zero-lag filters, resampling, derivatives.

NaN handling is explicit: the filters refuse NaN (fill gaps first) so that a gap never smears
silently into its neighbours.
"""

from __future__ import annotations

import functools
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import MissingDataError, MskError

__all__ = [
    "CausalLowpass",
    "FilterType",
    "GapMethod",
    "LinearPhaseLowpass",
    "block_average",
    "derivative",
    "fill_gaps",
    "filtfilt_butter",
    "find_peaks",
    "lowpass_filtfilt_numpy",
    "resample_to",
    "true_runs",
]

FilterType = Literal["lowpass", "highpass", "bandpass", "bandstop"]
GapMethod = Literal["linear", "pchip", "cubic"]


def _rate_hint(rate_hz: float, wn: NDArray[np.float64]) -> str:
    """A hint when the rate looks 1000× too low (a time column in ms read as s)."""
    if np.any(wn >= 1) and 0 < rate_hz < 10.0:
        return (
            f" (a rate of {rate_hz:g} Hz: is the time column in milliseconds instead of seconds?)"
        )
    return ""


def _check_finite(x: NDArray[np.float64]) -> None:
    """NaN samples (gaps) and infinite ones (a corrupt value) are refused, each said so."""
    bad = ~np.isfinite(x)
    if not bad.any():
        return
    first = tuple(int(i[0]) for i in np.nonzero(bad))
    if np.isnan(x[first]):
        raise MissingDataError(
            f"cannot filter a signal with NaN samples (first at index {first}): fill the gaps first"
        )
    raise MissingDataError(
        f"cannot filter a signal with infinite samples (first {x[first]} at index {first}): "
        "a corrupt value in the input"
    )


#: the most samples (× columns) that :func:`filtfilt_butter` filters with
#: :func:`lowpass_filtfilt_numpy` (its sample loop runs in Python, ~1 µs a sample: ~50 ms
#: there, where importing ``scipy.signal`` costs ~1 s once per process)
NUMPY_FILTER_MAX_SAMPLES = 50_000


def _numpy_is_quicker(
    x: NDArray[np.float64], axis: int, order: int, btype: str, wn: NDArray[np.float64]
) -> bool:
    """Whether :func:`filtfilt_butter` takes the numpy filter: a low- or high-pass of even
    order along the first axis of a short signal, while ``scipy.signal`` is not imported
    yet."""
    import sys

    if "scipy.signal" in sys.modules or btype not in ("lowpass", "highpass") or order % 2:
        return False
    if wn.size != 1:
        return False
    if x.ndim == 0 or axis not in (0, -x.ndim) or x.shape[0] < 2:
        return False
    return x.size <= NUMPY_FILTER_MAX_SAMPLES


def filtfilt_butter(
    x: ArrayLike,
    *,
    rate_hz: float,
    cutoff_hz: float | tuple[float, float],
    order: int = 4,
    btype: FilterType = "lowpass",
    axis: int = 0,
) -> NDArray[np.float64]:
    """Zero-lag Butterworth filter (forward–backward, second-order sections).

    The forward–backward pass squares the magnitude response, so the effective order is
    ``2 * order`` and the −3 dB point moves below ``cutoff_hz``; this matches common
    biomechanics practice (Winter 2009) and OpenSim's coordinate filtering.
    """
    x = np.asarray(x, dtype=float)
    nyq = 0.5 * rate_hz
    wn = np.atleast_1d(np.asarray(cutoff_hz, dtype=float)) / nyq
    if np.any(wn <= 0) or np.any(wn >= 1):
        raise MskError(
            f"cutoff {cutoff_hz} Hz must lie in (0, {nyq}) Hz for rate {rate_hz} Hz"
            + _rate_hint(rate_hz, wn)
        )
    _check_finite(x)
    if _numpy_is_quicker(x, axis, order, btype, wn):
        # the same numbers (lowpass_filtfilt_numpy equals scipy's design and filter bit for bit)
        # without importing scipy.signal (~1 s with the scipy.stats it imports)
        cutoff = float(np.atleast_1d(np.asarray(cutoff_hz, dtype=float))[0])
        return lowpass_filtfilt_numpy(
            x, rate_hz=rate_hz, cutoff_hz=cutoff, order=order, btype=btype
        )
    from scipy import signal as _sig  # imported on use: 0.4 s that `msk --help` need not pay

    # a writable copy of the cached design (scipy's filter wants a writable buffer)
    sos = np.array(_butter_design(order, tuple(float(w) for w in wn), btype))
    padlen = min(3 * (2 * len(sos) + 1), x.shape[axis] - 1)
    return _sig.sosfiltfilt(sos, x, axis=axis, padlen=max(padlen, 0))


@functools.lru_cache(maxsize=256)
def _butter_design(order: int, wn: tuple[float, ...], btype: str) -> NDArray[np.float64]:
    """``scipy.signal.butter(order, wn, btype, output="sos")``, designed once per
    (order, normalised cut-off, type) — a session filters many channels with the same few
    designs (≈ 5 ms each) — and read-only."""
    from scipy import signal as _sig

    sos = np.asarray(
        _sig.butter(order, wn if len(wn) > 1 else wn[0], btype=btype, output="sos"), dtype=float
    )
    sos.setflags(write=False)
    return sos


def _butter_sos(order: int, wn: float, btype: str = "lowpass") -> NDArray[np.float64]:
    """``scipy.signal.butter(order, wn, btype, output="sos")`` (low- or high-pass, even
    ``order``) in numpy, by
    the same operations in the same order, hence equal to it bit for bit (tested): the analog
    prototype's poles −exp(iπm/(2N)), m = −N+1, −N+3, …, N−1 (Butterworth), prewarping
    ω = 4 tan(πW_n/2) (sampling rate 2); low-pass p ↦ ωp (gain ω^N), high-pass p ↦ ω/p
    (gain Re(1/Π(−p)), N zeros at 0); the bilinear transform z = (4 + p)/(4 − p) (zeros at
    −1 low-pass, at +1 high-pass) with the gain times Re(Π(4 − z)/Π(4 − p)); then
    second-order sections of conjugate pole pairs, the pair nearest the unit circle last, each
    denominator the product (z − p)(z − p̄) as ``numpy.convolve`` forms it, the gain in the
    first section."""
    n = order
    m = np.arange(-n + 1, n, 2, dtype=np.float64)
    analog = -np.exp(1j * np.pi * m / (2 * n))
    fs = 2.0
    warped = float(2 * fs * np.tan(np.pi * np.float64(wn) / fs))
    zeros = np.zeros(0)
    if btype == "lowpass":
        analog, gain = warped * analog, 1.0 * warped**n
        numerator = (1.0, 2.0, 1.0)
    else:  # high-pass: the prototype inverted, its zeros at infinity moved to the origin
        gain = 1 * np.real(np.prod(-zeros) / np.prod(-analog))
        analog, zeros = warped / analog, np.zeros(n)
        numerator = (1.0, -2.0, 1.0)
    fs2 = 2.0 * fs
    poles = (fs2 + analog) / (fs2 - analog)
    gain = gain * np.real(np.prod(fs2 - zeros) / np.prod(fs2 - analog))
    # scipy's _cplxreal: the members of positive imaginary part, by real part, each averaged
    # with its conjugate partner
    poles = poles[np.lexsort((abs(poles.imag), poles.real))]
    upper, lower = poles[poles.imag > 0], poles[poles.imag < 0]
    left = list((upper + lower.conj()) / 2)
    sos = np.zeros((n // 2, 6))
    for si in range(n // 2 - 1, -1, -1):
        worst = int(np.argmin(np.abs(1 - np.abs(np.array(left)))))
        p1 = left.pop(worst)
        a = np.ones((1,), dtype=complex)
        for root in (p1, p1.conj()):
            a = np.convolve(a, np.stack((np.ones_like(root), -root)), mode="full")
        sos[si, :3] = numerator
        sos[si, 3:] = np.real(a)
    sos[0][:3] *= gain
    return sos


def _even_order_wn(cutoff_hz: float, rate_hz: float, order: int, who: str) -> float:
    """The cut-off as a fraction of Nyquist, checked, for an even-order Butterworth."""
    wn = cutoff_hz / (0.5 * rate_hz)
    if not 0.0 < wn < 1.0:
        raise MskError(
            f"cutoff {cutoff_hz} Hz must lie in (0, {0.5 * rate_hz}) Hz for rate {rate_hz} Hz"
            + _rate_hint(rate_hz, np.atleast_1d(wn))
        )
    if order < 2 or order % 2:
        raise MskError(f"{who}: an even order >= 2 is needed, got {order}")
    return wn


def lowpass_filtfilt_numpy(
    x: ArrayLike, *, rate_hz: float, cutoff_hz: float, order: int = 4, btype: str = "lowpass"
) -> NDArray[np.float64]:
    """:func:`filtfilt_butter` (low-pass, even ``order``, time on axis 0) in numpy alone: the
    same second-order sections (Butterworth analog prototype, frequency prewarping and the
    bilinear transform, the gain in the first section, as ``scipy.signal.butter(...,
    output="sos")``), the same odd extension of ``3 (2 n_sections + 1)`` samples and the same
    steady-state initial conditions as ``scipy.signal.sosfiltfilt`` — equal to it bit for bit
    (tested). For short signals on a path that must not import ``scipy.signal`` (~0.5 s: the
    static trial's still window, which a cached run computes again); the sample loop runs in
    Python, one column at a time. ``btype="highpass"``: the high-pass of
    :func:`filtfilt_butter` the same way."""
    x = np.asarray(x, dtype=float)
    wn = _even_order_wn(cutoff_hz, rate_hz, order, "lowpass_filtfilt_numpy")
    _check_finite(x)
    sos = _butter_sos(order, wn, btype)
    # steady state of each section's step response, scaled by the sections before it
    zi = np.zeros((len(sos), 2))
    scale = 1.0
    for i, (b0, b1, b2, _, a1, a2) in enumerate(sos):
        zi[i] = scale * np.linalg.solve(
            np.array([[1.0 + a1, -1.0], [a2, 1.0]]), np.array([b1 - a1 * b0, b2 - a2 * b0])
        )
        scale *= (b0 + b1 + b2) / (1.0 + a1 + a2)
    n = x.shape[0]
    pad = min(3 * (2 * len(sos) + 1), n - 1)
    if pad > 0:
        ext = np.concatenate([2 * x[0] - x[pad:0:-1], x, 2 * x[-1] - x[-2 : -pad - 2 : -1]])
    else:
        ext = x.copy()

    coefs = sos.tolist()

    def sosfilt_one(vals: list[float]) -> list[float]:
        # Python floats: the same IEEE operations as scipy's loop, ~4× faster than numpy scalars
        first = vals[0]  # every section starts in the steady state of the input's first sample
        for i, (b0, b1, b2, _, a1, a2) in enumerate(coefs):
            z0, z1 = float(zi[i, 0]) * first, float(zi[i, 1]) * first
            out = []
            for xt in vals:
                yt = b0 * xt + z0
                z0 = b1 * xt - a1 * yt + z1
                z1 = b2 * xt - a2 * yt
                out.append(yt)
            vals = out
        return vals

    def sosfilt(sig: NDArray[np.float64]) -> NDArray[np.float64]:
        cols = sig.reshape(sig.shape[0], -1)
        y = np.empty_like(cols)
        for c in range(cols.shape[1]):  # each column on its own, as scipy filters them
            y[:, c] = sosfilt_one(cols[:, c].tolist())
        return y.reshape(sig.shape)

    y = sosfilt(sosfilt(ext)[::-1])[::-1]
    return np.ascontiguousarray(y[pad : pad + n])


class CausalLowpass:
    """A causal Butterworth low-pass run one sample at a time over ``channels`` (a stream:
    :mod:`msk.live`), with the first and second derivatives by central differences on the
    filtered samples — y, ẏ, ÿ of the sample *before* the newest one.

    The filter is the forward half of :func:`lowpass_filtfilt_numpy`'s (the same second-order
    sections, direct form II transposed), each section started in the steady state of the
    first sample. Its magnitude is |H| (order ``order``, −3 dB at ``cutoff_hz``), not |H|² as
    the zero-lag pass's; its phase is not zero: near DC the output lags the input by the group
    delay τ = −dφ/dω at ω = 0, for each section
    τ_s = Σ k b_k / Σ b_k − Σ k a_k / Σ a_k samples (exact for the designed coefficients;
    √2/(2π f_c) s for order 2, 2.613/(2π f_c) s for order 4 in the analog limit). The
    derivatives ẏ_{n−1} = (y_n − y_{n−2}) / 2Δt and ÿ_{n−1} = (y_n − 2 y_{n−1} + y_{n−2}) / Δt²
    are centred on the previous sample, so y, ẏ and ÿ all describe the same instant:
    :attr:`lag_s` = τ + Δt behind the newest input. ``scheme="gradient"``: the offline run's
    differences instead (:func:`derivative`, ``np.gradient`` applied twice),
    ẏ_{n−2} = (y_{n−1} − y_{n−3}) / 2Δt and ÿ_{n−2} = (y_n − 2 y_{n−2} + y_{n−4}) / 4Δt², centred
    two samples back (:attr:`lag_s` = τ + 2Δt); its ÿ's gain at frequency f is
    sin²(ωΔt)/(ωΔt)², against (2 − 2 cos ωΔt)/(ωΔt)² for the three-point one: it passes less
    of what the causal filter lets through above the cut-off.

    Nothing is allocated per sample: :meth:`step` writes into :attr:`y`, :attr:`dy`, :attr:`ddy`.
    """

    def __init__(
        self,
        channels: int,
        *,
        rate_hz: float,
        cutoff_hz: float,
        order: int = 2,
        scheme: str = "central",
    ) -> None:
        wn = _even_order_wn(cutoff_hz, rate_hz, order, "CausalLowpass")
        if scheme not in ("central", "gradient"):
            raise MskError(f"CausalLowpass: scheme {scheme!r} is not 'central' or 'gradient'")
        self.scheme = scheme
        back = 1 if scheme == "central" else 2  # samples between y's instant and the newest
        self.sos = _butter_sos(order, wn)
        self.dt = 1.0 / rate_hz
        k = np.arange(3)
        b, a = self.sos[:, :3], self.sos[:, 3:]
        delay = (b @ k) / b.sum(axis=1) - (a @ k) / a.sum(axis=1)
        #: group delay at DC of the filter, s
        self.group_delay_s = float(delay.sum()) * self.dt
        #: lag of y, ẏ, ÿ behind the newest input: the group delay and one sample (two with
        #: ``scheme="gradient"``), s
        self.lag_s = self.group_delay_s + back * self.dt
        n = int(channels)
        self._z = np.zeros((len(self.sos), 2, n))
        self._hist = np.zeros((1 + 2 * back, n))  # filtered y_n, y_{n−1}, …
        self._tmp = np.empty(n)
        self._out = np.empty(n)
        self.y = np.zeros(n)
        self.dy = np.zeros(n)
        self.ddy = np.zeros(n)
        self.count = 0

    def reset(self) -> None:
        """Forget the past: the next sample starts the filter in its steady state again."""
        self.count = 0

    def _start(self, x: NDArray[np.float64]) -> None:
        scale = 1.0
        for i, (b0, b1, b2, _, a1, a2) in enumerate(self.sos):
            zi = np.linalg.solve(
                np.array([[1.0 + a1, -1.0], [a2, 1.0]]), np.array([b1 - a1 * b0, b2 - a2 * b0])
            )
            self._z[i, 0] = scale * zi[0] * x
            self._z[i, 1] = scale * zi[1] * x
            scale *= (b0 + b1 + b2) / (1.0 + a1 + a2)
        self._hist[:] = x

    def step(self, x: NDArray[np.float64]) -> None:
        """Take the next sample ``x`` (channels,): :attr:`y`, :attr:`dy`, :attr:`ddy` become
        those of the previous sample (the first two samples: at rest at the first)."""
        if self.count == 0:
            self._start(x)
        y = self._smooth(x)
        h = self._hist
        for i in range(h.shape[0] - 1, 0, -1):
            h[i] = h[i - 1]
        h[0] = y
        self.count += 1
        if self.scheme == "gradient":
            # np.gradient twice, as the offline run differentiates (msk.signal.derivative):
            # ẏ_{n−2} = (y_{n−1} − y_{n−3}) / 2Δt, ÿ_{n−2} = (y_n − 2 y_{n−2} + y_{n−4}) / 4Δt²
            np.copyto(self.y, h[2])
            np.subtract(h[1], h[3], out=self.dy)
            self.dy *= 0.5 / self.dt
            np.subtract(h[0], h[2], out=self.ddy)
            self.ddy -= h[2]
            self.ddy += h[4]
            self.ddy *= 0.25 / (self.dt * self.dt)
            return
        np.copyto(self.y, h[1])
        np.subtract(h[0], h[2], out=self.dy)
        self.dy *= 0.5 / self.dt
        np.subtract(h[0], h[1], out=self.ddy)
        self.ddy -= h[1]
        self.ddy += h[2]
        self.ddy *= 1.0 / (self.dt * self.dt)

    def _smooth(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """The filter's output for the newest sample (a buffer)."""
        y, tmp = self._out, self._tmp
        y[:] = x
        for i, (b0, b1, b2, _, a1, a2) in enumerate(self.sos):
            z0, z1 = self._z[i, 0], self._z[i, 1]
            np.copyto(tmp, y)  # the section's input
            np.multiply(tmp, b0, out=y)
            y += z0
            # z0 ← b1 x − a1 y + z1 ;  z1 ← b2 x − a2 y
            np.multiply(tmp, b1, out=z0)
            z0 -= a1 * y
            z0 += z1
            np.multiply(tmp, b2, out=z1)
            z1 -= a2 * y
        return y


class LinearPhaseLowpass(CausalLowpass):
    """A causal low-pass of constant delay: the offline run's zero-lag Butterworth
    (:func:`lowpass_filtfilt_numpy`, ``order``, ``cutoff_hz``) as a finite impulse response
    delayed by ``half_width`` samples — y_n = Σ_{k=−K}^{K} h_k x_{n−K−k}, h the filtfilt
    operator's impulse response (symmetric: h_k = h_{−k}) truncated to |k| ≤ K and scaled to a
    gain of 1 at DC. A symmetric FIR has linear phase: every frequency is delayed by exactly
    KΔt (Oppenheim & Schafer 2010, §5.7.3), so y_n is the offline filter's output at
    t_n − KΔt up to the truncation (the L²-closest length-(2K+1) FIR to its response,
    Parseval), and the differences of :class:`CausalLowpass` (``scheme``) on it describe the
    instant :attr:`lag_s` = KΔt + Δt (+ 2Δt with ``"gradient"``) before the newest input, with
    the offline run's shape: θ̈ is not reshaped by a non-linear phase, only delayed.

    The longer the window, the closer to the offline filter and the longer the lag: the
    truncated tail of h is the error. ``half_width`` defaults to the samples within
    ``half_width_s`` (0.1 s: 12 samples at 120 Hz, the tail beyond carries < 1 % of Σ|h| at
    6 Hz). The first sample fills the window (the output starts at rest)."""

    def __init__(
        self,
        channels: int,
        *,
        rate_hz: float,
        cutoff_hz: float,
        order: int = 4,
        scheme: str = "gradient",
        half_width: int | None = None,
        half_width_s: float = 0.1,
    ) -> None:
        super().__init__(channels, rate_hz=rate_hz, cutoff_hz=cutoff_hz, order=2, scheme=scheme)
        _even_order_wn(cutoff_hz, rate_hz, order, "LinearPhaseLowpass")
        k = round(half_width_s * rate_hz) if half_width is None else int(half_width)
        if k < 1:
            raise MskError(f"LinearPhaseLowpass: half width {k} samples, need >= 1")
        pad = 40 * k + 400  # the impulse far from the ends of filtfilt's padding
        impulse = np.zeros(2 * pad + 1)
        impulse[pad] = 1.0
        resp = lowpass_filtfilt_numpy(impulse, rate_hz=rate_hz, cutoff_hz=cutoff_hz, order=order)
        taps = resp[pad - k : pad + k + 1]
        #: the FIR's coefficients h_{−K} … h_K (symmetric, sum 1)
        self.taps = taps / taps.sum()
        self.half_width = k
        back = 1 if scheme == "central" else 2
        self.group_delay_s = k * self.dt
        self.lag_s = self.group_delay_s + back * self.dt
        self._window = np.zeros((2 * k + 1, int(channels)))  # a ring of x_n, x_{n−1}, …
        # the taps in ring order for each position of the newest sample (row a: x_n in slot a)
        self._rolls = np.stack([np.roll(self.taps, a) for a in range(2 * k + 1)])
        self._at = 0

    def _start(self, x: NDArray[np.float64]) -> None:
        self._window[:] = x
        self._at = 0
        self._hist[:] = x

    def _smooth(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        w = self._window
        n = w.shape[0]
        self._at = (self._at - 1) % n  # a ring: the newest sample overwrites the oldest
        w[self._at] = x
        np.matmul(self._rolls[self._at], w, out=self._out)
        return self._out


def true_runs(mask: ArrayLike) -> list[tuple[int, int]]:
    """``[start, stop)`` index pairs of the runs of True of a boolean vector, in order."""
    d = np.diff(np.concatenate([[0], np.asarray(mask, dtype=bool).astype(int), [0]]))
    return [(int(a), int(b)) for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1))]


def find_peaks(x: ArrayLike, *, distance: int = 1, prominence: float = 0.0) -> NDArray[np.int64]:
    """Indices of the local maxima of ``x`` at least ``distance`` samples apart with a
    topographic prominence of at least ``prominence``.

    The same selection as ``scipy.signal.find_peaks(x, distance=..., prominence=...)`` (the
    tests compare them): a maximum is a sample higher than its left neighbour and not lower
    than its right one, a flat top counts once at its middle (the left one of two middles),
    the ends never count; peaks closer than ``distance`` are removed lowest first; the
    prominence of a peak is its height above the higher of the two lowest points between it
    and the nearest higher sample (or the end) on each side. In numpy, so that gait-event
    detection does not import ``scipy.signal`` (~0.45 s a cached run need not pay).
    """
    v = np.asarray(x, dtype=float)
    if v.ndim != 1:
        raise MskError(f"find_peaks: a 1-D signal is needed, got shape {v.shape}")
    if distance < 1:
        raise MskError(f"find_peaks: distance must be >= 1 sample, got {distance}")
    n = v.size
    if n < 3:
        return np.zeros(0, dtype=np.int64)
    # runs of equal values: a run is a peak when both neighbouring runs are lower
    starts = np.flatnonzero(np.r_[True, v[1:] != v[:-1]])
    ends = np.r_[starts[1:], n] - 1
    vals = v[starts]
    inner = np.arange(1, starts.size - 1)
    top = inner[(vals[inner] > vals[inner - 1]) & (vals[inner] > vals[inner + 1])]
    peaks = (starts[top] + ends[top]) // 2
    if peaks.size > 1 and distance > 1:
        keep = np.ones(peaks.size, dtype=bool)
        order = np.argsort(v[peaks])  # as scipy: the highest first, ties as argsort leaves them
        for j in order[::-1]:
            if not keep[j]:
                continue
            k = j - 1
            while k >= 0 and peaks[j] - peaks[k] < distance:
                keep[k] = False
                k -= 1
            k = j + 1
            while k < peaks.size and peaks[k] - peaks[j] < distance:
                keep[k] = False
                k += 1
        peaks = peaks[keep]
    if prominence > 0 and peaks.size:
        prom = np.empty(peaks.size)
        for i, pk in enumerate(peaks):
            h = v[pk]
            left = np.flatnonzero(v[:pk] > h)
            lo = left[-1] + 1 if left.size else 0
            right = np.flatnonzero(v[pk + 1 :] > h)
            hi = pk + 1 + right[0] if right.size else n
            prom[i] = h - max(v[lo : pk + 1].min(), v[pk:hi].min())
        peaks = peaks[prom >= prominence]
    return peaks.astype(np.int64)


def resample_to(
    t_src: ArrayLike, x: ArrayLike, t_dst: ArrayLike, *, axis: int = 0
) -> NDArray[np.float64]:
    """Linear interpolation of ``x`` sampled at ``t_src`` onto ``t_dst`` (NaN propagates)."""
    t_src = np.asarray(t_src, dtype=float)
    x = np.moveaxis(np.asarray(x, dtype=float), axis, 0)
    t_dst = np.asarray(t_dst, dtype=float)
    flat = x.reshape(x.shape[0], -1)
    out = np.empty((t_dst.size, flat.shape[1]))
    for j in range(flat.shape[1]):
        out[:, j] = np.interp(t_dst, t_src, flat[:, j], left=np.nan, right=np.nan)
    return np.moveaxis(out.reshape((t_dst.size, *x.shape[1:])), 0, axis)


def block_average(x: ArrayLike, factor: int, *, axis: int = 0) -> NDArray[np.float64]:
    """Average consecutive blocks of ``factor`` samples (analog rate → point rate, C3D style)."""
    x = np.moveaxis(np.asarray(x, dtype=float), axis, 0)
    n = x.shape[0] // factor
    out = x[: n * factor].reshape(n, factor, *x.shape[1:]).mean(axis=1)
    return np.moveaxis(out, 0, axis)


def derivative(x: ArrayLike, *, dt: float, order: int = 1, axis: int = 0) -> NDArray[np.float64]:
    """Central finite differences (second order inside, one-sided at the ends)."""
    y = np.asarray(x, dtype=float)
    for _ in range(order):
        y = np.gradient(y, dt, axis=axis, edge_order=2)
    return y


def _nan_runs(missing: NDArray[np.bool_]) -> NDArray[np.int64]:
    """Length of the NaN run each sample belongs to (0 for finite samples), 1-D."""
    n = missing.size
    if not missing.any():
        return np.zeros(n, dtype=np.int64)
    d = np.diff(np.concatenate([[0], missing.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    out = np.zeros(n, dtype=np.int64)
    lengths = ends - starts
    idx = np.repeat(np.arange(starts.size), lengths)
    out[missing] = lengths[idx]
    return out


def fill_gaps(
    x: ArrayLike,
    *,
    max_gap: int | None = None,
    method: GapMethod = "pchip",
    axis: int = 0,
) -> NDArray[np.float64]:
    """Interpolate interior NaN gaps along ``axis`` (e.g. marker gaps before filtering).

    Each column is interpolated from its finite samples (``linear``, shape-preserving ``pchip``
    or natural ``cubic`` spline, over the sample index). Gaps longer than ``max_gap`` samples,
    and NaN before the first / after the last finite sample, are left NaN: extrapolating a
    marker is never safe. Columns with fewer than two finite samples are returned unchanged.
    """
    from scipy.interpolate import CubicSpline, PchipInterpolator

    if method not in ("linear", "pchip", "cubic"):
        raise MskError(f"unknown gap-filling method {method!r} (linear, pchip, cubic)")
    if max_gap is not None and max_gap < 0:
        raise MskError(f"max_gap must be >= 0 samples, got {max_gap}")
    arr = np.moveaxis(np.array(x, dtype=float), axis, 0)
    flat = arr.reshape(arr.shape[0], -1)
    n = flat.shape[0]
    t = np.arange(n, dtype=float)
    for j in range(flat.shape[1]):
        col = flat[:, j]
        ok = np.isfinite(col)
        if ok.all() or ok.sum() < 2:
            continue
        first, last = np.flatnonzero(ok)[[0, -1]]
        fill = ~ok
        fill[:first] = False
        fill[last + 1 :] = False
        if max_gap is not None:
            fill &= _nan_runs(~ok) <= max_gap
        if not fill.any():
            continue
        if method == "linear":
            col[fill] = np.interp(t[fill], t[ok], col[ok])
        elif method == "pchip":
            col[fill] = PchipInterpolator(t[ok], col[ok])(t[fill])
        else:
            col[fill] = CubicSpline(t[ok], col[ok], bc_type="natural")(t[fill])
    return np.moveaxis(flat.reshape(arr.shape), 0, axis)
