"""Marker-based inverse kinematics on the embedded model (global optimisation, frame by frame).

For each frame the independent coordinates θ minimise the weighted marker misfit::

    E(θ) = Σ_m w_m ‖p_m(g(θ)) − x_m‖²

where p_m is the world position of model marker m (a Pinocchio frame), x_m the measured position
and g the embedding θ → q_pin (:mod:`msk.model.joints`). The problem is solved by
Levenberg–Marquardt
on the residual r = √w (p − x) with the Jacobian

    J_θ = J_pin G,    J_pin,m = [J_lin − [p_m]× J_ang] restricted to the joints supporting m,

built from one ``pin.computeJointJacobians`` per iteration (world-frame joint Jacobian, no
per-marker Pinocchio call). Coordinate limits are enforced by projection (a step is clipped to
``range`` and a coordinate pushed against a bound is frozen for that step); locked coordinates
are held at their default. Each frame starts from the previous solution (warm start).

A marker missing in a frame (NaN) simply drops out of E; a frame with fewer usable markers than
``min_markers`` (or fewer scalar equations than free coordinates) is not guessed: its θ is NaN
and its status is :data:`STATUS_TOO_FEW_MARKERS`.

Velocities and accelerations come from θ low-pass filtered with a zero-lag Butterworth filter
(:func:`msk.signal.filtfilt_butter`, ``cutoff_hz``) and differentiated with central
differences; failed frames are bridged by linear interpolation for the filter only and stay NaN
in the output.
"""

from __future__ import annotations

import math
import time as _time
from bisect import bisect_right
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import (
    FileFormatError,
    KinematicsError,
    MissingDataError,
    ShapeMismatchError,
)
from msk.model.core import Model
from msk.model.joints import Constant, Linear, Multiplier, Polynomial, SimmSpline
from msk.signal import derivative, filtfilt_butter
from msk.timeseries import FrameAxis
from msk.units import Array

__all__ = [
    "STATUS_NAMES",
    "STATUS_NOT_CONVERGED",
    "STATUS_OK",
    "STATUS_TOO_FEW_MARKERS",
    "FrameIK",
    "Kinematics",
    "filtered_derivatives",
    "ik_tasks_from_setup",
    "kinematics_from_coordinates",
    "solve_kinematics",
]

#: per-frame status codes of :class:`Kinematics`
STATUS_OK = 0
STATUS_TOO_FEW_MARKERS = 1
STATUS_NOT_CONVERGED = 2
STATUS_NAMES = {STATUS_OK: "ok", STATUS_TOO_FEW_MARKERS: "too few markers", 2: "not converged"}


@dataclass(frozen=True)
class Kinematics(FrameAxis):
    """Joint kinematics over a trial (time on axis 0, SI: rad or m).

    Attributes:
        time: (N,) s.
        q: (N, n_coords) coordinates θ (filtered when ``cutoff_hz`` is set; NaN on failed frames).
        v, a: (N, n_coords) θ̇ and θ̈ from the filtered θ (NaN on failed frames).
        coordinate_names: column names of q, v, a.
        q_raw: (N, n_coords) θ as solved, before filtering.
        status: (N,) per-frame status (:data:`STATUS_OK`, :data:`STATUS_TOO_FEW_MARKERS`,
            :data:`STATUS_NOT_CONVERGED`).
        marker_rms: (N,) unweighted RMS marker distance (m) over the markers used.
        marker_max: (N,) largest marker distance (m); ``marker_max_name`` names that marker.
        marker_errors: (N, n_markers) distance model–measured per marker (NaN when not used).
        marker_names: column names of ``marker_errors``.
        n_markers_used, iterations: (N,) per frame.
        cutoff_hz: the low-pass cutoff used for v and a (None: no filtering).
        solve_time_s: wall-clock time of the frame-by-frame solve.
        marker_rms_all: (N,) RMS marker distance (m) over the markers used and the model
            markers of the trial given weight 0 (None when there are none).
    """

    FRAME_FIELDS: ClassVar[tuple[str, ...]] = (
        "time",
        "q",
        "v",
        "a",
        "q_raw",
        "status",
        "marker_rms",
        "marker_max",
        "marker_max_name",
        "marker_errors",
        "n_markers_used",
        "iterations",
    )

    time: Array
    q: Array
    v: Array
    a: Array
    coordinate_names: tuple[str, ...]
    q_raw: Array
    status: NDArray[np.int64]
    marker_rms: Array
    marker_max: Array
    marker_max_name: tuple[str, ...]
    marker_errors: Array
    marker_names: tuple[str, ...]
    n_markers_used: NDArray[np.int64]
    iterations: NDArray[np.int64]
    cutoff_hz: float | None = None
    solve_time_s: float = 0.0
    metadata: Mapping[str, object] = field(default_factory=dict)
    marker_rms_all: Array | None = None

    @property
    def n_frames(self) -> int:
        return int(self.time.size)

    @property
    def failed_frames(self) -> NDArray[np.int64]:
        """Indices of the frames whose status is not OK."""
        return np.flatnonzero(self.status != STATUS_OK)

    def coordinate(self, name: str) -> Array:
        """(N,) series of one coordinate."""
        try:
            return self.q[:, self.coordinate_names.index(name)]
        except ValueError:
            raise MissingDataError(f"kinematics has no coordinate {name!r}") from None


def _reflect(x: Array, pad: int) -> Array:
    """``pad`` samples before ``x[0]``: odd reflection of x − p plus p, p the quadratic fitted
    to ``x`` (value, slope and curvature stay continuous at the edge)."""
    k = np.arange(x.shape[0], dtype=float)
    basis = np.stack([np.ones_like(k), k, k**2], axis=1)
    coef = np.linalg.lstsq(basis, x, rcond=None)[0]
    dev = x - basis @ coef
    kk = np.arange(1, pad + 1, dtype=float)
    idx = np.minimum(kk.astype(int), x.shape[0] - 1)
    ext = np.stack([np.ones_like(kk), -kk, kk**2], axis=1) @ coef + 2 * dev[0] - dev[idx]
    return ext[::-1]


def filtered_derivatives(
    time: Array, q: Array, cutoff_hz: float | None, order: int
) -> tuple[Array, Array, Array]:
    """Filter θ and differentiate over the solved window (first to last finite frame; interior
    NaN frames bridged linearly); NaN frames, and every frame outside the window, stay NaN.

    The window's ends are the signal's ends: each is padded by the odd reflection of
    :func:`_reflect` before the zero-lag filter, as the trial's own ends are. A subject running
    through the capture volume is tracked for under a second of a longer trial; holding θ
    constant outside that window (its velocity stepping to zero) leaves the filter a kink at
    each end, which the zero-lag low-pass spreads into the accelerations over ≈ 1/f_c: 3,700–4,200
    N of pelvis residual at the ends of UWA's Running_1 window (4.9 m/s, 6 Hz)."""
    bad = np.asarray(~np.isfinite(q).all(axis=1), dtype=bool)
    if bad.all():
        nan = np.full_like(q, np.nan)
        return nan, nan.copy(), nan.copy()
    good = np.flatnonzero(~bad)
    lo, hi = int(good[0]), int(good[-1]) + 1
    tw = time[lo:hi]
    filled = q[lo:hi].copy()
    if bad[lo:hi].any():
        for j in range(q.shape[1]):
            filled[:, j] = np.interp(tw, time[good], q[good, j])
    m = tw.size
    if m < 3:
        v, a = np.zeros_like(filled), np.zeros_like(filled)
    else:
        dt = float(np.mean(np.diff(tw)))
        rate = 1.0 / dt
        if cutoff_hz is not None:
            # odd reflection about both ends (as OpenSim pads before filtering) over about
            # three periods of the cutoff, so that the edges are not dragged by the filter's
            # start-up
            pad = int(min(m - 1, np.ceil(3.0 * rate / cutoff_hz)))
            fit = int(min(m, max(4, np.ceil(rate / cutoff_hz))))
            head = _reflect(filled[:fit], pad)
            tail = _reflect(filled[::-1][:fit], pad)[::-1]
            ext = np.concatenate([head, filled, tail])
            ext = filtfilt_butter(ext, rate_hz=rate, cutoff_hz=cutoff_hz, order=order)
            filled = ext[pad : pad + m]
        v = derivative(filled, dt=dt)
        a = derivative(filled, dt=dt, order=2)
    out = [np.full_like(q, np.nan) for _ in range(3)]
    for o, x in zip(out, (filled, v, a)):
        o[lo:hi] = x
        o[bad] = np.nan
    return out[0], out[1], out[2]


def kinematics_from_coordinates(
    time: ArrayLike,
    q: ArrayLike,
    coordinate_names: Sequence[str],
    *,
    cutoff_hz: float | None = 6.0,
    filter_order: int = 4,
    model: Model | None = None,
) -> Kinematics:
    """Wrap coordinates from elsewhere (an OpenSim IK ``.mot``, a simulation) as
    :class:`Kinematics`, with v and a from the low-pass filtered θ.

    When ``model`` is given the columns are reordered to the model's coordinates (a missing
    coordinate raises :class:`MissingDataError`; extra columns are dropped).
    """
    t = np.asarray(time, dtype=float)
    x = np.asarray(q, dtype=float)
    names = tuple(coordinate_names)
    if x.ndim != 2 or x.shape != (t.size, len(names)):
        raise ShapeMismatchError(
            f"coordinates of shape {x.shape} do not match time {t.shape} and {len(names)} names"
        )
    if model is not None:
        missing = [c for c in model.coordinate_names if c not in names]
        if missing:
            raise MissingDataError(f"coordinates absent from the table: {missing}")
        x = x[:, [names.index(c) for c in model.coordinate_names]]
        names = model.coordinate_names
    qf, v, a = filtered_derivatives(t, x, cutoff_hz, filter_order)
    n = t.size
    nan = np.full(n, np.nan)
    return Kinematics(
        time=t,
        q=qf,
        v=v,
        a=a,
        coordinate_names=names,
        q_raw=x.copy(),
        status=np.where(np.isfinite(x).all(axis=1), STATUS_OK, STATUS_TOO_FEW_MARKERS),
        marker_rms=nan,
        marker_max=nan.copy(),
        marker_max_name=("",) * n,
        marker_errors=np.zeros((n, 0)),
        marker_names=(),
        n_markers_used=np.zeros(n, dtype=np.int64),
        iterations=np.zeros(n, dtype=np.int64),
        cutoff_hz=cutoff_hz,
    )


def _scalar_function(f: object) -> tuple[object, object, object] | None:
    """Fast scalar (value, first, second derivative) closures for the common coordinate
    functions."""
    if isinstance(f, Linear):
        slope, intercept = float(f.slope), float(f.intercept)
        return (lambda x: slope * x + intercept), (lambda x: slope), (lambda x: 0.0)
    if isinstance(f, Multiplier):
        inner = _scalar_function(f.function)
        if inner is None:
            return None
        s, fi, di, ddi = float(f.scale), inner[0], inner[1], inner[2]
        return (
            (lambda x: s * fi(x)),  # type: ignore[operator]
            (lambda x: s * di(x)),  # type: ignore[operator]
            (lambda x: s * ddi(x)),  # type: ignore[operator]
        )
    if isinstance(f, Polynomial):
        c = [float(x) for x in f.coefficients]
        n = len(c) - 1
        dc = [c[k] * (n - k) for k in range(n)]
        ddc = [dc[k] * (n - 1 - k) for k in range(n - 1)]

        def horner(coef: list[float], x: float) -> float:
            out = 0.0
            for a in coef:
                out = out * x + a
            return out

        return (lambda x: horner(c, x)), (lambda x: horner(dc, x)), (lambda x: horner(ddc, x))
    if isinstance(f, SimmSpline):
        knots = [float(x) for x in f.x]
        ys = [float(y) for y in f.y]
        b, c, d = (list(map(float, arr)) for arr in f.coefficients)
        last = len(knots) - 2

        def val(x: float) -> float:
            if x < knots[0]:
                return ys[0] + (x - knots[0]) * b[0]
            if x > knots[-1]:
                return ys[-1] + (x - knots[-1]) * b[-1]
            i = min(max(bisect_right(knots, x) - 1, 0), last)
            dx = x - knots[i]
            return ys[i] + dx * (b[i] + dx * (c[i] + dx * d[i]))

        def der(x: float) -> float:
            if x < knots[0]:
                return b[0]
            if x > knots[-1]:
                return b[-1]
            i = min(max(bisect_right(knots, x) - 1, 0), last)
            dx = x - knots[i]
            return b[i] + dx * (2 * c[i] + 3 * dx * d[i])

        def der2(x: float) -> float:
            if x < knots[0] or x > knots[-1]:
                return 0.0
            i = min(max(bisect_right(knots, x) - 1, 0), last)
            return 2 * c[i] + 6 * (x - knots[i]) * d[i]

        return val, der, der2
    return None


def _value_and_slope(f: object) -> object:
    """One closure x ↦ (f(x), f'(x)) with :func:`_scalar_function`'s arithmetic (one knot
    search for a spline)."""
    scale = None
    if isinstance(f, Multiplier) and isinstance(f.function, SimmSpline):
        scale, f = float(f.scale), f.function
    elif isinstance(f, Multiplier):
        inner = _value_and_slope(f.function)
        s = float(f.scale)

        def scaled(x: float) -> tuple[float, float]:
            v, d = inner(x)  # type: ignore[operator]
            return s * v, s * d

        return scaled
    if isinstance(f, SimmSpline):
        knots = [float(x) for x in f.x]
        ys = [float(y) for y in f.y]
        b, c, d = (list(map(float, arr)) for arr in f.coefficients)
        last = len(knots) - 2
        lo, hi = knots[0], knots[-1]

        def both(x: float) -> tuple[float, float]:
            if x < lo:
                return ys[0] + (x - lo) * b[0], b[0]
            if x > hi:
                return ys[-1] + (x - hi) * b[-1], b[-1]
            i = min(max(bisect_right(knots, x) - 1, 0), last)
            dx = x - knots[i]
            return (
                ys[i] + dx * (b[i] + dx * (c[i] + dx * d[i])),
                b[i] + dx * (2 * c[i] + 3 * dx * d[i]),
            )

        if scale is None:
            return both
        s = scale

        def scaled_spline(x: float) -> tuple[float, float]:
            if x < lo:
                return s * (ys[0] + (x - lo) * b[0]), s * b[0]
            if x > hi:
                return s * (ys[-1] + (x - hi) * b[-1]), s * b[-1]
            i = min(max(bisect_right(knots, x) - 1, 0), last)
            dx = x - knots[i]
            return (
                s * (ys[i] + dx * (b[i] + dx * (c[i] + dx * d[i]))),
                s * (b[i] + dx * (2 * c[i] + 3 * dx * d[i])),
            )

        return scaled_spline
    fast = _scalar_function(f)
    fv: Any
    fd: Any
    if fast is None:
        fv, fd = (lambda x: float(f(x))), (lambda x: float(f.d1(x)))  # type: ignore[operator,attr-defined]
    else:
        fv, fd = fast[0], fast[1]
    return lambda x: (fv(x), fd(x))


def _affine(f: object) -> tuple[float, float] | None:
    """(slope, intercept) when f is affine (Linear, possibly inside Multipliers)."""
    if isinstance(f, Linear):
        return float(f.slope), float(f.intercept)
    if isinstance(f, Multiplier):
        inner = _affine(f.function)
        if inner is not None:
            return f.scale * inner[0], f.scale * inner[1]
    return None


class _CouplingEvaluator:
    """Fast q = g(θ) and G = ∂g/∂θ for one θ: Linear and Constant axes vectorised, polynomials
    and splines by scalar closures, anything else through its own (vectorised) methods."""

    def __init__(self, model: Model) -> None:
        cp = model.coupling
        self.nq, self.n = cp.nq, cp.n_coords
        coord = np.asarray(cp.coordinate)
        affine = {k: _affine(f) for k, f in enumerate(cp.functions) if coord[k] >= 0}
        lin = [k for k, ab in affine.items() if ab is not None]
        self.lin_k = np.asarray(lin, dtype=int)
        self.lin_i = coord[self.lin_k] if lin else np.zeros(0, dtype=int)
        self.lin_s = np.array([affine[k][0] for k in lin])  # type: ignore[index]
        self.lin_b = np.array([affine[k][1] for k in lin])  # type: ignore[index]
        self.q0 = np.zeros(self.nq)
        self.other: list[tuple[int, int, object, object]] = []
        self.second: list[tuple[int, int, object]] = []  # f_k'' of the non-affine entries
        lin_set = set(lin)
        for k, f in enumerate(cp.functions):
            if coord[k] < 0:
                self.q0[k] = f.value if isinstance(f, Constant) else float(f(0.0))
            elif k not in lin_set:
                fast = _scalar_function(f)
                if fast is None:
                    fast = (
                        (lambda x, f=f: float(f(x))),
                        (lambda x, f=f: float(f.d1(x))),
                        (lambda x, f=f: float(f.d2(x))),
                    )
                self.other.append((k, int(coord[k]), fast[0], fast[1]))
                self.second.append((k, int(coord[k]), fast[2]))
        self.g_lin = np.zeros((self.nq, self.n))
        if lin:
            self.g_lin[self.lin_k, self.lin_i] = self.lin_s

        # affine part as one product: q = A θ + b (b holds the constants and intercepts)
        self.q_b = self.q0.copy()
        if lin:
            self.q_b[self.lin_k] = self.lin_b

    def q(self, theta: Array) -> Array:
        q = self.g_lin @ theta + self.q_b
        if self.other:
            th = theta.tolist()
            for k, i, f, _ in self.other:
                q[k] = f(th[i])  # type: ignore[operator]
        return q

    def jacobian(self, theta: Array) -> Array:
        g = self.g_lin.copy()
        if self.other:
            th = theta.tolist()
            for k, i, _, d in self.other:
                g[k, i] = d(th[i])  # type: ignore[operator]
        return g

    def bias(self, theta: Array, theta_dot: Array) -> Array:
        """Ġθ̇: f_k''(θ_i) θ̇_i² (zero on the affine entries), (nq,)."""
        out = np.zeros(self.nq)
        if self.second:
            th, thd = theta.tolist(), theta_dot.tolist()
            for k, i, dd in self.second:
                out[k] = dd(th[i]) * thd[i] * thd[i]  # type: ignore[operator]
        return out


class _MarkerProblem:
    """Vectorised marker positions and Jacobians for a fixed set of model markers.

    Positions come from the placements of the few joints that carry markers (one Pinocchio
    access per joint, not per marker); Jacobians from the world-frame joint Jacobian.
    """

    def __init__(self, model: Model, names: Sequence[str]) -> None:
        pm = model.pin_model
        self.model = model
        self.pm = pm
        self.data = pm.createData()
        frames = [model.marker_frame[n] for n in names]
        self.coupling = _CouplingEvaluator(model)
        parents = [pm.frames[f].parentJoint for f in frames]
        self.joints = sorted(set(parents))
        self.which = np.array([self.joints.index(j) for j in parents], dtype=int)
        local = np.array([pm.frames[f].placement.translation for f in frames])
        self.local_h = np.vstack([local.T, np.ones(len(frames))])  # (4, M)
        m = len(frames)
        # flat index of (row 3·joint(m) + c, column m) in the (3J × M) product
        self.take = ((3 * self.which[:, None] + np.arange(3)) * m + np.arange(m)[:, None]).ravel()
        self.omi = self.data.oMi  # live view of the joint placements
        self._at: Array | None = None  # θ of the placements held in data
        # marker m is moved by DOF k iff joint k supports the marker's parent joint
        mask = np.zeros((len(names), pm.nv), dtype=bool)
        for m, jid in enumerate(parents):
            for s in pm.supports[jid]:
                if s > 0:
                    mask[m, pm.joints[s].idx_v] = True
        self.mask = mask[:, None, :]
        # when every coordinate's DOFs either all move marker m or none does, the mask can be
        # applied after G (per coordinate), which allows a single matrix product
        coord = np.asarray(model.coupling.coordinate)
        cmask = np.zeros((len(names), model.n_coords))
        valid = True
        for i in range(model.n_coords):
            cols = mask[:, coord == i]
            if cols.shape[1]:
                valid &= bool(np.all(cols == cols[:, :1]))
                cmask[:, i] = cols[:, 0]
        self.coord_mask = np.repeat(cmask, 3, axis=0) if valid else None
        self.e_buf = np.zeros((len(names), 3, 6))
        self.e_buf[:, [0, 1, 2], [0, 1, 2]] = 1.0

    def _points(self) -> Array:
        # one (3J × 4) @ (4 × M) product, then each marker's rows of its own joint
        # one conversion of the placements (indexing Pinocchio's vector costs as much per item)
        omi = self.omi.tolist()
        h = np.array([omi[j].homogeneous for j in self.joints])[:, :3]
        return (h.reshape(-1, 4) @ self.local_h).ravel()[self.take].reshape(-1, 3)

    def positions(self, theta: Array) -> Array:
        pin.forwardKinematics(self.pm, self.data, self.coupling.q(theta))
        self._at = theta
        return self._points()

    def evaluate(self, theta: Array) -> tuple[Array, Array]:
        """Marker positions (M, 3) and the stacked Jacobian ∂p/∂θ (3M, n), rows (m, xyz)."""
        pin.computeJointJacobians(self.pm, self.data, self.coupling.q(theta))
        self._at = theta
        p = self._points()
        return p, self._jacobian(theta, p)

    def jacobian(self, theta: Array, p: Array) -> Array:
        """∂p/∂θ at θ whose marker positions ``p`` are already known."""
        if theta is self._at:  # the placements in data are those of θ: Jacobian only
            pin.computeJointJacobians(self.pm, self.data)
        else:
            pin.computeJointJacobians(self.pm, self.data, self.coupling.q(theta))
        return self._jacobian(theta, p)

    def _jacobian(self, theta: Array, p: Array) -> Array:
        jw = self.data.J  # (6, nv): spatial motion at the world origin, world axes
        g = self.coupling.jacobian(theta)
        if self.coord_mask is not None:
            # J_p = mask ⊙ ([I, −[p]×] (J G)): one (3M × 6) @ (6 × n) product
            e = self.e_buf
            px, py, pz = p[:, 0], p[:, 1], p[:, 2]
            e[:, 0, 4], e[:, 0, 5] = pz, -py
            e[:, 1, 3], e[:, 1, 5] = -pz, px
            e[:, 2, 3], e[:, 2, 4] = py, -px
            return (e.reshape(-1, 6) @ (jw @ g)) * self.coord_mask
        # general case (a coordinate drives DOFs on both sides of a marker's chain)
        jl, ja = jw[:3], jw[3:]
        pxc, pyc, pzc = p[:, 0:1], p[:, 1:2], p[:, 2:3]
        jp = np.empty((p.shape[0], 3, jw.shape[1]))
        jp[:, 0] = jl[0] + ja[1] * pzc - ja[2] * pyc
        jp[:, 1] = jl[1] + ja[2] * pxc - ja[0] * pzc
        jp[:, 2] = jl[2] + ja[0] * pyc - ja[1] * pxc
        jp *= self.mask
        return jp.reshape(-1, jw.shape[1]) @ g


def ik_tasks_from_setup(
    path: str | Path,
) -> tuple[dict[str, float], dict[str, tuple[float, float]]]:
    """Marker weights and coordinate tasks of an OpenSim ``InverseKinematicsTool`` setup file.

    Returns ``(weights, coordinate_tasks)`` for :func:`solve_kinematics`: ``IKMarkerTask`` →
    weight (0 when ``apply`` is false), ``IKCoordinateTask`` with ``apply`` true → (value,
    weight) (``value_type`` ``default_value`` or ``manual_value``: the ``value`` element).
    """
    import xml.etree.ElementTree as ET

    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        raise FileFormatError(f"{path}: cannot read the IK setup: {exc}") from None

    def num(el: ET.Element, tag: str, default: float) -> float:
        txt = el.findtext(tag)
        try:
            return float(txt) if txt is not None and txt.strip() else default
        except ValueError:
            raise FileFormatError(f"{path}: {el.get('name')}: bad <{tag}> {txt!r}") from None

    def applied(el: ET.Element) -> bool:
        return (el.findtext("apply") or "true").strip().lower() == "true"

    weights = {
        el.get("name", ""): num(el, "weight", 1.0) if applied(el) else 0.0
        for el in root.iter("IKMarkerTask")
    }
    tasks = {
        el.get("name", ""): (num(el, "value", 0.0), num(el, "weight", 1.0))
        for el in root.iter("IKCoordinateTask")
        if applied(el)
    }
    return weights, tasks


def solve_kinematics(
    model: Model,
    markers: ArrayLike,
    marker_labels: Sequence[str],
    time: ArrayLike,
    *,
    weights: Mapping[str, float] | None = None,
    coordinate_tasks: Mapping[str, tuple[float, float]] | None = None,
    cutoff_hz: float | None = 6.0,
    filter_order: int = 4,
    initial_q: ArrayLike | None = None,
    min_markers: int = 3,
    max_iterations: int = 50,
    tolerance: float = 1e-6,
    rel_tolerance: float = 1e-8,
    strict: bool = False,
) -> Kinematics:
    """Inverse kinematics of a marker trial (see the module docstring for the maths).

    Args:
        model: the model; its markers are matched to ``marker_labels`` by name (markers present
            in only one of them are ignored).
        markers: (N, M, 3) measured positions in m, NaN for gaps (e.g. ``Trial.markers``).
        marker_labels: the M labels.
        time: (N,) s.
        weights: marker name → weight w_m ≥ 0 (default 1; 0 drops the marker).
        coordinate_tasks: coordinate name → (value, weight): adds w (θ_i − value)² to E
            (OpenSim's ``IKCoordinateTask``).
        cutoff_hz: low-pass cutoff for θ before differentiation (None: no filter).
        initial_q: start of the first frame (default: the model defaults, then a root-only fit);
            or (N, n): each frame's own start (a frame whose row is not finite starts from the
            prediction of the frames before it) — a warm start from an earlier solution of
            the same frames, e.g. the previous pass of a placement
            (:func:`msk.personalise.scaling.place_markers_from_motion` ``warm``).
        min_markers: fewest markers for a frame to be solved.
        max_iterations, tolerance, rel_tolerance: LM stopping rules: the largest coordinate
            step (rad or m) below ``tolerance``, or a relative cost decrease below
            ``rel_tolerance`` (1e-8 moves θ by less than 0.001° on gait data).
        strict: raise :class:`KinematicsError` (naming the frame) instead of reporting a frame
            that cannot be solved.

    Returns:
        :class:`Kinematics`; frames that could not be solved are NaN with their status set.
    """
    x = np.asarray(markers, dtype=float)
    t = np.asarray(time, dtype=float)
    labels = tuple(marker_labels)
    if x.ndim != 3 or x.shape[2] != 3 or x.shape[1] != len(labels) or x.shape[0] != t.size:
        raise ShapeMismatchError(
            f"markers {x.shape} must be (N, M, 3) with N = len(time) = {t.size} and "
            f"M = len(marker_labels) = {len(labels)}"
        )
    weights = dict(weights or {})
    for name, wt in weights.items():
        if not np.isfinite(wt) or wt < 0:
            raise KinematicsError(f"marker {name}: weight must be finite and ≥ 0, got {wt}")
    used = [mk.name for mk in model.markers if mk.name in labels and weights.get(mk.name, 1.0) > 0]
    if len(used) < min_markers:
        raise KinematicsError(
            f"only {len(used)} model markers found in the data ({used}); need {min_markers}"
        )
    cols = [labels.index(n) for n in used]
    # each frame's used markers are taken as it is solved (x[n, cols]): a long trial's used
    # markers are not copied whole
    # model markers of the trial left out by a zero weight: their distances are reported
    ignored = [mk.name for mk in model.markers if mk.name in labels and mk.name not in used]
    ign_cols = [labels.index(n) for n in ignored]
    prob_ign = _MarkerProblem(model, ignored) if ignored else None
    errs_ign = np.full((t.size, len(ignored)), np.nan)
    w = np.array([weights.get(n, 1.0) for n in used])
    sw = np.sqrt(w)
    prob = _MarkerProblem(model, used)

    n_c = model.n_coords
    ctask = None
    if coordinate_tasks:
        idx = np.array([model.coordinate_index(c) for c in coordinate_tasks], dtype=int)
        val = np.array([float(v[0]) for v in coordinate_tasks.values()])
        cw = np.array([float(v[1]) for v in coordinate_tasks.values()])
        if np.any(~np.isfinite(cw)) or np.any(cw < 0):
            raise KinematicsError(f"coordinate task weights must be ≥ 0, got {cw.tolist()}")
        rows = np.zeros((idx.size, n_c))
        rows[np.arange(idx.size), idx] = np.sqrt(cw)
        ctask = (idx, val, np.sqrt(cw), rows)
    n_tasks = 0 if ctask is None else int(ctask[0].size)
    lo, hi = model.coordinate_bounds()
    locked = np.array([c.locked for c in model.coordinates])
    free = ~locked
    per_frame = None
    if initial_q is not None and np.ndim(initial_q) == 2:
        per_frame = np.asarray(initial_q, dtype=float)
        if per_frame.shape != (t.size, n_c):
            raise ShapeMismatchError(
                f"initial_q has shape {per_frame.shape}, need ({t.size}, {n_c}) per frame"
            )
        initial_q = None
    theta = model.default_coordinates() if initial_q is None else np.asarray(initial_q, float)
    if theta.shape != (n_c,):
        raise ShapeMismatchError(f"initial_q has shape {theta.shape}, the model has ({n_c},)")
    theta = np.clip(theta.astype(float).copy(), lo, hi)
    theta[locked] = model.default_coordinates()[locked]
    n_frames = t.size
    q_out = np.full((n_frames, n_c), np.nan)
    status = np.zeros(n_frames, dtype=np.int64)
    errs = np.full((n_frames, len(used)), np.nan)
    iters = np.zeros(n_frames, dtype=np.int64)
    n_used = np.zeros(n_frames, dtype=np.int64)
    root_free = np.zeros(n_c, dtype=bool)
    if model.root_joint is not None:
        root_coords = {
            ax.coordinate
            for j in model.joints
            if j.name == model.root_joint
            for ax in j.axes
            if ax.coordinate is not None
        }
        root_free = np.array([c.name in root_coords for c in model.coordinates]) & free
    first = True
    hist: list[Array] = []  # solutions of the last consecutive solved frames (prediction)
    tic = _time.perf_counter()
    for n in range(n_frames):
        xn = x[n, cols]
        present = np.isfinite(xn).all(axis=1)
        n_used[n] = int(present.sum())
        if n_used[n] < min_markers or 3 * n_used[n] + n_tasks < int(free.sum()):
            status[n] = STATUS_TOO_FEW_MARKERS
            hist.clear()
            if strict:
                raise KinematicsError(
                    f"frame {n} (t = {t[n]:.4f} s): {n_used[n]} markers present, "
                    f"need {max(min_markers, int(np.ceil((free.sum() - n_tasks) / 3)))}"
                )
            continue
        warm = per_frame is not None and bool(np.isfinite(per_frame[n]).all())
        if first and initial_q is None and root_free.any() and not warm:
            theta, _, _, _ = _levenberg_marquardt(
                prob, theta, xn, sw, present, root_free, lo, hi, max_iterations, tolerance
            )
        first = False
        # the frame's own start, else a polynomial prediction from the previous frames
        # (constant velocity / acceleration)
        if warm:
            assert per_frame is not None
            start = per_frame[n].copy()
        elif len(hist) >= 3:
            start = 3.0 * hist[-1] - 3.0 * hist[-2] + hist[-3]
        elif len(hist) == 2:
            start = 2.0 * hist[-1] - hist[-2]
        else:
            start = theta
        start = np.clip(start, lo, hi)
        start[locked] = theta[locked]
        theta, k, ok, p = _levenberg_marquardt(
            prob,
            start,
            xn,
            sw,
            present,
            free,
            lo,
            hi,
            max_iterations,
            tolerance,
            ctask,
            rel_tolerance,
        )
        iters[n] = k
        if not ok:
            status[n] = STATUS_NOT_CONVERGED
            if strict:
                raise KinematicsError(f"frame {n} (t = {t[n]:.4f} s): IK did not converge")
        hist.append(theta)
        del hist[:-3]
        q_out[n] = theta
        d = np.linalg.norm(p - xn, axis=1)
        d[~present] = np.nan
        errs[n] = d
        if prob_ign is not None:
            errs_ign[n] = np.linalg.norm(prob_ign.positions(theta) - x[n, ign_cols], axis=1)
    solve_time = _time.perf_counter() - tic
    if status.all():
        need = max(min_markers, int(np.ceil((free.sum() - n_tasks) / 3)))
        seen = [bool(np.isfinite(x[:, c]).all(axis=1).any()) for c in cols]
        found = [name for name, k in zip(used, seen, strict=True) if k]
        raise KinematicsError(
            "no frame could be solved (too few markers in every frame): at most "
            f"{int(n_used.max(initial=0))} of the model's markers in a frame, {need} needed for "
            f"its {int(free.sum())} free coordinates; the model's markers seen in the trial: "
            f"{', '.join(found) or 'none'} (the trial's other labels are not recognised as "
            "landmarks of the model: name them with [markers] rename)"
        )
    solved = np.isfinite(errs).any(axis=1)
    rms = np.full(n_frames, np.nan)
    sq = np.where(np.isfinite(errs), errs**2, 0.0)
    rms[solved] = np.sqrt(sq[solved].sum(axis=1) / np.isfinite(errs[solved]).sum(axis=1))
    mx = np.full(n_frames, np.nan)
    mx_name = [""] * n_frames
    for n in np.flatnonzero(solved).tolist():
        j = int(np.nanargmax(errs[n]))
        mx[n], mx_name[n] = errs[n, j], used[j]
    rms_all = None
    if ignored:
        both = np.concatenate([errs, errs_ign], axis=1)
        both[~solved] = np.nan
        cnt = np.isfinite(both).sum(axis=1)
        rms_all = np.full(n_frames, np.nan)
        rms_all[solved] = np.sqrt(
            np.where(np.isfinite(both), both**2, 0.0)[solved].sum(axis=1) / cnt[solved]
        )
    q_out[status == STATUS_TOO_FEW_MARKERS] = np.nan
    qf, v, a = filtered_derivatives(t, q_out, cutoff_hz, filter_order)
    return Kinematics(
        time=t,
        q=qf,
        v=v,
        a=a,
        coordinate_names=model.coordinate_names,
        q_raw=q_out,
        status=status,
        marker_rms=rms,
        marker_max=mx,
        marker_max_name=tuple(mx_name),
        marker_errors=errs,
        marker_names=tuple(used),
        n_markers_used=n_used,
        iterations=iters,
        cutoff_hz=cutoff_hz,
        solve_time_s=solve_time,
        marker_rms_all=rms_all,
    )


class FrameIK:
    """Inverse kinematics of one frame at a time, warm-started from the caller's θ (a stream:
    :mod:`msk.live`). The problem of :func:`solve_kinematics` — E(θ) = Σ_m w_m ‖p_m − x_m‖²
    (+ coordinate tasks) by projected Levenberg–Marquardt on r = √w (p − x) with the world
    joint Jacobians of Pinocchio (module docstring) — set up once for a fixed marker list:
    its marker problem, weights, bounds and task rows are built here, not per frame.

    ``solve(theta, x)`` starts from ``theta`` (the previous frame's solution) and runs at most
    ``max_iterations`` steps; from the same start it returns the θ :func:`solve_kinematics`
    returns for that frame (the same function, :func:`_levenberg_marquardt`).

    Args:
        model: the model; ``labels`` are the columns of the frames given to :meth:`solve`
            (model marker names; labels the model does not have are ignored).
        weights, coordinate_tasks, max_iterations, tolerance, rel_tolerance, min_markers: as
            :func:`solve_kinematics`'s.
    """

    def __init__(
        self,
        model: Model,
        labels: Sequence[str],
        *,
        weights: Mapping[str, float] | None = None,
        coordinate_tasks: Mapping[str, tuple[float, float]] | None = None,
        max_iterations: int = 50,
        tolerance: float = 1e-6,
        rel_tolerance: float = 1e-8,
        min_markers: int = 3,
    ) -> None:
        labels = tuple(labels)
        w_map = dict(weights or {})
        self.used = tuple(
            mk.name for mk in model.markers if mk.name in labels and w_map.get(mk.name, 1.0) > 0
        )
        if len(self.used) < min_markers:
            raise KinematicsError(
                f"only {len(self.used)} model markers among the stream's labels; need {min_markers}"
            )
        self.columns = np.array([labels.index(n) for n in self.used], dtype=np.intp)
        self.problem = _MarkerProblem(model, self.used)
        self.sw = np.sqrt(np.array([w_map.get(n, 1.0) for n in self.used]))
        self.lo, self.hi = model.coordinate_bounds()
        locked = np.array([c.locked for c in model.coordinates], dtype=bool)
        self.free = ~locked
        self.ctask = None
        if coordinate_tasks:
            idx = np.array([model.coordinate_index(c) for c in coordinate_tasks], dtype=int)
            val = np.array([float(v[0]) for v in coordinate_tasks.values()])
            cw = np.sqrt(np.array([float(v[1]) for v in coordinate_tasks.values()]))
            rows = np.zeros((idx.size, model.n_coords))
            rows[np.arange(idx.size), idx] = cw
            self.ctask = (idx, val, cw, rows)
        self.min_markers = int(min_markers)
        self.max_iterations = int(max_iterations)
        self.tolerance, self.rel_tolerance = float(tolerance), float(rel_tolerance)
        self._x = np.empty((len(self.used), 3))
        self._d = np.empty(len(self.used))
        self._diff = np.empty((len(self.used), 3))
        self._fin = np.empty((len(self.used), 3), dtype=bool)
        self._present = np.empty(len(self.used), dtype=bool)
        self._lm = (
            _FrameLM(self.problem, self.sw, self.free, self.lo, self.hi, self.ctask)
            if self.problem.coord_mask is not None
            else None
        )

    def solve(self, theta: Array, markers: Array) -> tuple[Array, int, bool, float]:
        """θ of one frame from the start ``theta`` and the frame's ``markers`` (M, 3) in the
        columns of ``labels``; returns θ, the iterations, whether it converged and the RMS
        marker distance (m) over the markers present. Fewer than ``min_markers`` present:
        ``theta`` unchanged, 0 iterations, not converged, NaN."""
        x, fin, present = self._x, self._fin, self._present
        np.take(markers, self.columns, axis=0, out=x)
        np.isfinite(x, out=fin)
        np.logical_and.reduce(fin, axis=1, out=present)
        n_present = int(np.count_nonzero(present))
        if n_present < self.min_markers:
            return theta, 0, False, float("nan")
        if self._lm is not None:
            return self._lm.solve(
                theta, x, present, n_present, self.max_iterations, self.tolerance,
                self.rel_tolerance,
            )  # fmt: skip
        start = np.minimum(np.maximum(theta, self.lo), self.hi)
        th, k, ok, p = _levenberg_marquardt(
            self.problem, start, x, self.sw, present, self.free, self.lo, self.hi,
            self.max_iterations, self.tolerance, self.ctask, self.rel_tolerance,
        )  # fmt: skip
        d, diff = self._d, self._diff
        np.subtract(p, x, out=diff)
        np.einsum("ij,ij->i", diff, diff, out=d)
        ss = float(np.add.reduce(d if n_present == d.size else d[present]))
        return th, k, ok, math.sqrt(ss / n_present)


def _levenberg_marquardt(
    prob: _MarkerProblem,
    theta: Array,
    target: Array,
    sw: Array,
    present: NDArray[np.bool_],
    free: NDArray[np.bool_],
    lo: Array,
    hi: Array,
    max_iterations: int,
    tolerance: float,
    ctask: tuple[NDArray[np.int64], Array, Array, Array] | None = None,
    rel_tolerance: float = 1e-8,
) -> tuple[Array, int, bool, Array]:
    """Projected LM on r = √w (p(θ) − x) over the free coordinates; returns θ, iterations, ok
    and the marker positions at θ."""
    # on use: a run whose kinematics come from the stage cache does not import scipy.linalg
    from scipy.linalg.lapack import dposv as _dposv

    th = np.minimum(np.maximum(theta, lo), hi)
    rows: Any = slice(None) if present.all() else np.repeat(present, 3)
    swr = np.repeat(sw, 3)[rows]
    tgt = target[present].ravel()
    m3 = tgt.size
    n_t = 0 if ctask is None else ctask[0].size
    # residual and Jacobian buffers: marker rows, then coordinate-task rows (constant Jacobian)
    r = np.empty(m3 + n_t)
    j = np.empty((m3 + n_t, th.size))
    if ctask is not None:
        j[m3:] = ctask[3]

    def residual(x: Array, pos: Array, out: Array) -> Array:
        np.multiply(swr, pos.ravel()[rows] - tgt, out=out[:m3])
        if ctask is not None:
            out[m3:] = ctask[2] * (x[ctask[0]] - ctask[1])
        return out

    p, jq = prob.evaluate(th)
    residual(th, p, r)
    np.multiply(swr[:, None], jq[rows], out=j[:m3])
    r_t = np.empty_like(r)
    cost = float(r @ r)
    lam = 1e-6
    all_free = bool(free.all())
    diag_idx = np.arange(th.size)
    for k in range(1, max_iterations + 1):
        grad = j.T @ r
        at_bound = (th <= lo) | (th >= hi)
        if all_free and not at_bound.any():
            whole, act = True, free
        else:
            # coordinates at a bound with the descent pushing outwards are frozen for this step
            act = free & ~(at_bound & (((th <= lo) & (grad > 0)) | ((th >= hi) & (grad < 0))))
            whole = all_free and bool(act.all())
        ja = j if whole else j[:, act]
        h = ja.T @ ja
        g = grad if whole else grad[act]
        diag = h[diag_idx[: h.shape[0]], diag_idx[: h.shape[0]]] + 1e-9
        while True:
            hl = h.copy()
            hl[diag_idx[: h.shape[0]], diag_idx[: h.shape[0]]] += lam * diag
            _, step, info = _dposv(hl, -g)
            if info != 0:
                lam *= 10.0
                continue
            if whole:
                trial = th + step
            else:
                trial = th.copy()
                trial[act] += step
            trial = np.minimum(np.maximum(trial, lo), hi)
            p_t = prob.positions(trial)
            residual(trial, p_t, r_t)
            cost_t = float(r_t @ r_t)
            if cost_t <= cost or lam > 1e12:
                break
            lam *= 4.0
        if cost_t > cost:
            return th, k, True, p  # no descent possible: at a (constrained) minimum
        moved = float(np.max(np.abs(trial - th)))
        decrease = cost - cost_t
        th, cost, p = trial, cost_t, p_t
        r, r_t = r_t, r
        if moved < tolerance or decrease <= rel_tolerance * max(cost, 1e-300):
            return th, k, True, p
        np.multiply(swr[:, None], prob.jacobian(th, p)[rows], out=j[:m3])
        lam = max(lam / 10.0, 1e-12)
    return th, max_iterations, False, p


class _FrameLM:
    """:func:`_levenberg_marquardt` with every buffer allocated once, for :class:`FrameIK`.

    The same iterations and the same floating-point operations on each entry (θ equal to the
    function's to the last bit on the frames of ``tests/kinematics/test_ik_frame.py``); what
    differs is the number of Python-level numpy calls per iteration: q = g(θ) and G = ∂g/∂θ
    into fixed arrays (one knot search per spline for both), the present markers' positions
    from one product of the carrying joints' homogeneous placements, their Jacobian rows
    J_m = (E(p_m) (J_pin G)) ⊙ (mask √w) with E(p) = [I, −[p]×] = e₀ + p A (A of 0 and ±1),
    the normal equations (JᵀJ + λ diag(JᵀJ)) δ = −Jᵀr formed with ``out=`` and solved by
    LAPACK's Cholesky (``dposv``) in place. A frame's rows (its present markers, then the
    coordinate tasks) are chosen once per frame (once per pattern of missing markers). A step
    that frees only part of the coordinates (a bound, a locked coordinate) takes the
    function's own path.
    """

    def __init__(
        self,
        prob: _MarkerProblem,
        sw: Array,
        free: NDArray[np.bool_],
        lo: Array,
        hi: Array,
        ctask: tuple[NDArray[np.int64], Array, Array, Array] | None,
    ) -> None:
        from scipy.linalg.lapack import dposv

        self.dposv = dposv
        self.prob, self.free, self.lo, self.hi, self.ctask = prob, free, lo, hi, ctask
        self.all_free = bool(free.all())
        cp = prob.coupling
        self.g_lin, self.q_b = cp.g_lin, cp.q_b
        # the non-affine entries: q_k = f_k(θ_i) and G_ki = f_k'(θ_i) from one call
        fns = prob.model.coupling.functions
        self.other = [(k, i, _value_and_slope(fns[k])) for k, i, _, _ in cp.other]
        m, n = sw.size, lo.size
        n_t = 0 if ctask is None else ctask[0].size
        self.m, self.n, self.n_t = m, n, n_t
        self.q = np.empty(cp.nq)
        self.g = cp.g_lin.copy()
        self.jg = np.empty((6, n))
        self.swr_all = np.repeat(sw, 3)
        # √w on the rows with the support mask folded in (0/1: the product is the function's)
        assert prob.coord_mask is not None
        self.maskw_all = prob.coord_mask * self.swr_all[:, None]
        # E(p) of each marker, [I, −[p]×] (3 × 6), is linear in p: E = e₀ + p A
        self.e = np.empty((m, 18))
        self.e0 = prob.e_buf.reshape(m, 18)[:1].copy()
        self.e_a = np.zeros((3, 18))
        for at, fr, sg in ((4, 2, 1), (5, 1, -1), (9, 2, -1), (11, 0, 1), (15, 1, 1), (16, 0, -1)):
            self.e_a[fr, at] = sg
        # the carrying joints' homogeneous placements (4J × 4) times the local points (4 × M):
        # marker m's (x, y, z) are the entries (4 joint(m) + c, m)
        n_j = len(prob.joints)
        self.pts = np.empty(4 * n_j * m)
        self.pts2 = self.pts.reshape(-1, m)
        self.take4 = ((4 * prob.which[:, None] + np.arange(3)) * m + np.arange(m)[:, None]).ravel()
        self.p_a, self.p_b = np.empty(3 * m), np.empty(3 * m)
        self.r_a, self.r_b = np.empty(3 * m + n_t), np.empty(3 * m + n_t)
        self.j = np.empty((3 * m + n_t, n))
        self.tgt = np.empty(3 * m)
        self.diff, self.d = np.empty(3 * m), np.empty(m)
        self.th_a, self.th_b = np.empty(n), np.empty(n)
        self.grad, self.tmp = np.empty(n), np.empty(n)
        self.task_rows = (
            []
            if ctask is None
            else list(zip(ctask[0].tolist(), ctask[1].tolist(), ctask[2].tolist(), strict=True))
        )
        self.th_list: list[float] = []
        self.h, self.hl = np.empty((n, n)), np.empty((n, n))
        self.h_diag = self.h.reshape(-1)[:: n + 1]
        self.hl_diag = self.hl.reshape(-1)[:: n + 1]
        self.hl_f = self.hl.T  # Fortran order of the symmetric matrix: dposv works in place
        self.dg = np.empty(n)
        self.nb = np.empty(n)
        self.b_lo, self.b_hi = np.empty(n, dtype=bool), np.empty(n, dtype=bool)
        self.b_any = np.empty(n, dtype=bool)
        self._present = b""

    def _rows(self, present: NDArray[np.bool_], n_present: int) -> None:
        """The frame's rows: present markers' (x, y, z), then the coordinate tasks."""
        key = present.tobytes()
        if key == self._present:
            return
        self._present = key
        self.all = n_present == self.m
        m3 = 3 * n_present
        rows = np.arange(m3) if self.all else np.flatnonzero(np.repeat(present, 3))
        self.rows, self.m3, self.m_p = rows, m3, n_present
        self.take_rows = self.take4[rows]
        self.swr = self.swr_all[rows]
        self.maskw = self.maskw_all[rows]
        k = m3 + self.n_t
        # (positions, residual, its marker rows) of the two points of a step
        self.slot_a = (self.p_a[:m3], self.r_a[:k], self.r_a[:m3])
        self.slot_b = (self.p_b[:m3], self.r_b[:k], self.r_b[:m3])
        self.jv, self.jm = self.j[:k], self.j[:m3]
        self.jv_t = self.jv.T
        self.tgt_v = self.tgt[:m3]
        self.e_v = self.e[:n_present]
        self.e2 = self.e_v.reshape(-1, 6)
        self.diff_v, self.diff3, self.d_v = (
            self.diff[:m3],
            self.diff[:m3].reshape(-1, 3),
            self.d[:n_present],
        )
        if self.ctask is not None:
            self.j[m3:k] = self.ctask[3]

    def _q(self, th: Array) -> Array:
        """q = g(θ) into the fixed buffer, and G's non-affine entries at θ (the Jacobian is
        always taken at the θ of the last q)."""
        q, g = self.q, self.g
        np.matmul(self.g_lin, th, out=q)
        q += self.q_b
        self.th_list = t = th.tolist()
        for k, i, fd in self.other:
            q[k], g[k, i] = fd(t[i])  # type: ignore[operator]
        return q

    def _evaluate(self, slot: tuple[Array, Array, Array]) -> float:
        """The present markers' positions from the placements now in the data, the residual
        r = √w (p − x) (then the task rows) and the cost rᵀr."""
        p, r, rm = slot
        prob = self.prob
        omi = prob.omi.tolist()
        hom = np.array([omi[j].homogeneous for j in prob.joints])
        np.matmul(hom.reshape(-1, 4), prob.local_h, out=self.pts2)
        np.take(self.pts, self.take_rows, out=p)
        np.subtract(p, self.tgt_v, out=rm)
        np.multiply(self.swr, rm, out=rm)
        # the task rows w_c (θ_c − value) in Python floats (θ's list from q(θ), just before)
        t = self.th_list
        for row, (i, v, w) in enumerate(self.task_rows, start=self.m3):
            r[row] = w * (t[i] - v)
        return float(r @ r)

    def _jacobian(self, p: Array) -> None:
        """J's marker rows at θ (placements, joint Jacobians and G already at θ)."""
        np.matmul(self.prob.data.J, self.g, out=self.jg)
        np.matmul(p.reshape(-1, 3), self.e_a, out=self.e_v)
        np.add(self.e_v, self.e0, out=self.e_v)
        jm = self.jm
        np.matmul(self.e2, self.jg, out=jm)
        np.multiply(jm, self.maskw, out=jm)

    def solve(
        self, theta: Array, target: Array, present: NDArray[np.bool_], n_present: int,
        max_iterations: int, tolerance: float, rel_tolerance: float,
    ) -> tuple[Array, int, bool, float]:  # fmt: skip
        """As :func:`_levenberg_marquardt`, and the RMS marker distance at the returned θ (a
        new array; ``prob._at`` kept as the function keeps it)."""
        prob, pm, data = self.prob, self.prob.pm, self.prob.data
        lo, hi = self.lo, self.hi
        self._rows(present, n_present)
        if self.all:
            np.copyto(self.tgt_v, target.reshape(-1))
        else:
            np.take(target.reshape(-1), self.rows, out=self.tgt_v)
        th, trial = self.th_a, self.th_b
        np.maximum(theta, lo, out=th)
        np.minimum(th, hi, out=th)
        cur, nxt = self.slot_a, self.slot_b
        j, jt = self.jv, self.jv_t
        grad, h, dg, hl, nb = self.grad, self.h, self.dg, self.hl, self.nb
        b_lo, b_hi, b_any, tmp = self.b_lo, self.b_hi, self.b_any, self.tmp
        pin.computeJointJacobians(pm, data, self._q(th))
        prob._at = None
        cost = self._evaluate(cur)
        self._jacobian(cur[0])
        lam = 1e-6
        ok = at_min = False
        k = 0
        for k in range(1, max_iterations + 1):  # noqa: B007 (k is returned)
            np.matmul(jt, cur[1], out=grad)
            np.less_equal(th, lo, out=b_lo)
            np.greater_equal(th, hi, out=b_hi)
            np.logical_or(b_lo, b_hi, out=b_any)
            if self.all_free and not np.count_nonzero(b_any):
                whole = True
            else:
                act = self.free & ~(b_any & ((b_lo & (grad > 0)) | (b_hi & (grad < 0))))
                whole = self.all_free and bool(act.all())
            if whole:
                np.matmul(jt, j, out=h)
                np.add(self.h_diag, 1e-9, out=dg)
                while True:
                    np.copyto(hl, h)
                    np.multiply(dg, lam, out=tmp)
                    self.hl_diag += tmp
                    np.negative(grad, out=nb)
                    _, step, info = self.dposv(self.hl_f, nb, 0, 1, 1)  # upper, in place
                    if info != 0:
                        lam *= 10.0
                        continue
                    np.add(th, step, out=trial)
                    np.maximum(trial, lo, out=trial)
                    np.minimum(trial, hi, out=trial)
                    pin.forwardKinematics(pm, data, self._q(trial))
                    cost_t = self._evaluate(nxt)
                    if cost_t <= cost or lam > 1e12:
                        break
                    lam *= 4.0
            else:  # the function's path: a sub-block of the free coordinates
                ja = j[:, act]
                hs = ja.T @ ja
                gs = grad[act]
                di = np.arange(hs.shape[0])
                diag = hs[di, di] + 1e-9
                while True:
                    hls = hs.copy()
                    hls[di, di] += lam * diag
                    _, step, info = self.dposv(hls, -gs)
                    if info != 0:
                        lam *= 10.0
                        continue
                    np.copyto(trial, th)
                    trial[act] += step
                    np.maximum(trial, lo, out=trial)
                    np.minimum(trial, hi, out=trial)
                    pin.forwardKinematics(pm, data, self._q(trial))
                    cost_t = self._evaluate(nxt)
                    if cost_t <= cost or lam > 1e12:
                        break
                    lam *= 4.0
            if cost_t > cost:  # no descent possible: at a (constrained) minimum
                ok = at_min = True
                break
            np.subtract(trial, th, out=tmp)
            np.abs(tmp, out=tmp)
            moved = max(tmp.tolist())
            decrease = cost - cost_t
            th, trial = trial, th
            cost = cost_t
            cur, nxt = nxt, cur
            if moved < tolerance or decrease <= rel_tolerance * max(cost, 1e-300):
                ok = True
                break
            pin.computeJointJacobians(pm, data)
            self._jacobian(cur[0])
            lam = max(lam / 10.0, 1e-12)
        out = th.copy()
        if not at_min:
            prob._at = out  # the data's placements are those of the returned θ
        # RMS marker distance at θ over the present markers (the function's p at θ)
        np.subtract(cur[0], self.tgt_v, out=self.diff_v)
        np.einsum("ij,ij->i", self.diff3, self.diff3, out=self.d_v)
        rms = math.sqrt(float(np.add.reduce(self.d_v)) / self.m_p)
        return out, (k if ok else max_iterations), ok, rms
