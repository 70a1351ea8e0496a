"""Coupled joints by constraint embedding.

Every Pinocchio joint of an msk model has one degree of freedom, and its value is a scalar
function of one independent coordinate θ_i (OpenSim's CustomJoint ``TransformAxis``)::

    q_k = f_k(θ_{i_k})            (q_pin = g(θ))
    v_k = f_k'(θ_{i_k}) θ̇_{i_k}     (v = G θ̇,   G = ∂g/∂θ, one non-zero per row)
    a_k = f_k' θ̈_{i_k} + f_k'' θ̇_{i_k}²   (a = G θ̈ + Ġ θ̇)

and generalised forces map back as τ_θ = Gᵀ τ_pin (virtual work). A constant axis has
``coordinate = -1`` and a zero row in G.

Functions here are the ones OpenSim uses (Constant, LinearFunction, PolynomialFunction, SimmSpline,
MultiplierFunction, PiecewiseLinearFunction), the composition f(c(θ)) that eliminates a
CoordinateCouplerConstraint (:class:`Composite`), and the four-bar knee of the rehabilitation-robot
lower-limb model paper (§2.1), whose tibia translation is an exact closed-form function of the
flexion angle.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import ModelError
from msk.units import Array

__all__ = [
    "Composite",
    "Constant",
    "CoordinateFunction",
    "Coupling",
    "FourBarKnee",
    "FourBarTranslation",
    "Linear",
    "Multiplier",
    "PiecewiseLinear",
    "Polynomial",
    "SimmSpline",
]


class CoordinateFunction(Protocol):
    """A scalar function of one coordinate with its first and second derivatives (vectorised)."""

    def __call__(self, x: Any) -> Any: ...

    def d1(self, x: ArrayLike) -> Array: ...

    def d2(self, x: ArrayLike) -> Array: ...


@dataclass(frozen=True)
class Constant:
    """f(x) = c."""

    value: float

    def __call__(self, x: Any) -> Any:
        return 0.0 * x + self.value

    def d1(self, x: ArrayLike) -> Array:
        return np.zeros_like(np.asarray(x, dtype=float))

    def d2(self, x: ArrayLike) -> Array:
        return np.zeros_like(np.asarray(x, dtype=float))


@dataclass(frozen=True)
class Linear:
    """f(x) = slope·x + intercept (OpenSim ``LinearFunction`` coefficients ``slope intercept``)."""

    slope: float = 1.0
    intercept: float = 0.0

    def __call__(self, x: Any) -> Any:
        return self.slope * x + self.intercept

    def d1(self, x: ArrayLike) -> Array:
        return np.full_like(np.asarray(x, dtype=float), self.slope)

    def d2(self, x: ArrayLike) -> Array:
        return np.zeros_like(np.asarray(x, dtype=float))


@dataclass(frozen=True)
class Polynomial:
    """f(x) = Σ c_k x^(n-k), coefficients highest order first (OpenSim ``PolynomialFunction``)."""

    coefficients: tuple[float, ...]

    def __call__(self, x: Any) -> Any:
        out = 0.0 * x
        for c in self.coefficients:
            out = out * x + c
        return out

    def d1(self, x: ArrayLike) -> Array:
        return np.polyval(np.polyder(np.asarray(self.coefficients)), np.asarray(x, dtype=float))

    def d2(self, x: ArrayLike) -> Array:
        return np.polyval(np.polyder(np.asarray(self.coefficients), 2), np.asarray(x, dtype=float))


@dataclass(frozen=True)
class SimmSpline:
    """OpenSim's ``SimmSpline``: the Forsythe–Malcolm–Moler cubic spline.

    End conditions match the third derivative of the cubics through the first and last four
    knots (natural-like for three knots, linear for two). Outside the knots the function is
    extrapolated linearly with the end slope, as OpenSim does.
    """

    x: tuple[float, ...]
    y: tuple[float, ...]
    _b: Array = field(init=False, repr=False, compare=False)
    _c: Array = field(init=False, repr=False, compare=False)
    _d: Array = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        x = np.asarray(self.x, dtype=float)
        y = np.asarray(self.y, dtype=float)
        if x.ndim != 1 or x.shape != y.shape or x.size < 2:
            raise ModelError(f"SimmSpline needs ≥ 2 matching knots, got x{x.shape} y{y.shape}")
        if np.any(np.diff(x) <= 0):
            raise ModelError(f"SimmSpline knots must increase strictly: {x.tolist()}")
        b, c, d = _fmm_coefficients(x, y)
        object.__setattr__(self, "_b", b)
        object.__setattr__(self, "_c", c)
        object.__setattr__(self, "_d", d)

    @property
    def coefficients(self) -> tuple[Array, Array, Array]:
        """``(b, c, d)`` (one per knot) of the cubic after knot i,
        s_i(x) = y_i + b_i dx + c_i dx² + d_i dx³ with dx = x − x_i."""
        return self._b, self._c, self._d

    def _locate(self, x: Array) -> tuple[NDArray[np.intp], Array]:
        knots = np.asarray(self.x)
        i = np.clip(np.searchsorted(knots, x, side="right") - 1, 0, knots.size - 2)
        return i, x - knots[i]

    def __call__(self, x: Any) -> Any:
        xa = np.asarray(x, dtype=float)
        knots, ys = np.asarray(self.x), np.asarray(self.y)
        i, dx = self._locate(xa)
        val = ys[i] + dx * (self._b[i] + dx * (self._c[i] + dx * self._d[i]))
        lo, hi = xa < knots[0], xa > knots[-1]
        val = np.where(lo, ys[0] + (xa - knots[0]) * self._b[0], val)
        val = np.where(hi, ys[-1] + (xa - knots[-1]) * self._b[-1], val)
        return val if val.ndim else float(val)

    def d1(self, x: ArrayLike) -> Array:
        xa = np.asarray(x, dtype=float)
        knots = np.asarray(self.x)
        i, dx = self._locate(xa)
        val = self._b[i] + dx * (2 * self._c[i] + 3 * dx * self._d[i])
        val = np.where(xa < knots[0], self._b[0], val)
        return np.where(xa > knots[-1], self._b[-1], val)

    def d2(self, x: ArrayLike) -> Array:
        xa = np.asarray(x, dtype=float)
        knots = np.asarray(self.x)
        i, dx = self._locate(xa)
        val = 2 * self._c[i] + 6 * dx * self._d[i]
        return np.where((xa < knots[0]) | (xa > knots[-1]), 0.0, val)


def _fmm_coefficients(x: Array, y: Array) -> tuple[Array, Array, Array]:
    """Coefficients b, c, d of s_i(x) = y_i + b_i dx + c_i dx² + d_i dx³ (FMM ``spline``)."""
    n = x.size
    b, c, d = np.zeros(n), np.zeros(n), np.zeros(n)
    if n < 3:
        b[:] = (y[1] - y[0]) / (x[1] - x[0])
        return b, c, d
    nm1 = n - 1
    d[0] = x[1] - x[0]
    c[1] = (y[1] - y[0]) / d[0]
    for i in range(1, nm1):
        d[i] = x[i + 1] - x[i]
        b[i] = 2.0 * (d[i - 1] + d[i])
        c[i + 1] = (y[i + 1] - y[i]) / d[i]
        c[i] = c[i + 1] - c[i]
    b[0] = -d[0]
    b[nm1] = -d[n - 2]
    c[0] = c[nm1] = 0.0
    if n > 3:
        c[0] = c[2] / (x[3] - x[1]) - c[1] / (x[2] - x[0])
        c[nm1] = c[n - 2] / (x[nm1] - x[n - 3]) - c[n - 3] / (x[n - 2] - x[n - 4])
        c[0] = c[0] * d[0] * d[0] / (x[3] - x[0])
        c[nm1] = -c[nm1] * d[n - 2] * d[n - 2] / (x[nm1] - x[n - 4])
    for i in range(1, n):
        t = d[i - 1] / b[i - 1]
        b[i] -= t * d[i - 1]
        c[i] -= t * c[i - 1]
    c[nm1] /= b[nm1]
    for i in range(n - 2, -1, -1):
        c[i] = (c[i] - d[i] * c[i + 1]) / b[i]
    b[nm1] = (y[nm1] - y[n - 2]) / d[n - 2] + d[n - 2] * (c[n - 2] + 2.0 * c[nm1])
    for i in range(nm1):
        b[i] = (y[i + 1] - y[i]) / d[i] - d[i] * (c[i + 1] + 2.0 * c[i])
        d[i] = (c[i + 1] - c[i]) / d[i]
        c[i] = 3.0 * c[i]
    c[nm1] = 3.0 * c[nm1]
    d[nm1] = d[n - 2]
    return b, c, d


@dataclass(frozen=True)
class Multiplier:
    """f(x) = scale · g(x) (OpenSim ``MultiplierFunction``)."""

    function: CoordinateFunction
    scale: float

    def __call__(self, x: Any) -> Any:
        return self.scale * self.function(x)

    def d1(self, x: ArrayLike) -> Array:
        return self.scale * self.function.d1(x)

    def d2(self, x: ArrayLike) -> Array:
        return self.scale * self.function.d2(x)


@dataclass(frozen=True)
class PiecewiseLinear:
    """OpenSim ``PiecewiseLinearFunction``: linear interpolation through the knots, linear
    extrapolation with the end-segment slopes; f'' = 0 (almost everywhere)."""

    x: tuple[float, ...]
    y: tuple[float, ...]

    def __post_init__(self) -> None:
        x = np.asarray(self.x, dtype=float)
        if x.ndim != 1 or x.size < 2 or x.shape != np.shape(self.y) or np.any(np.diff(x) <= 0):
            raise ModelError(f"PiecewiseLinear needs ≥ 2 increasing knots, got x={self.x}")

    def _seg(self, xa: Array) -> tuple[NDArray[np.intp], Array]:
        knots = np.asarray(self.x)
        i = np.clip(np.searchsorted(knots, xa, side="right") - 1, 0, knots.size - 2)
        ys = np.asarray(self.y)
        slope = (ys[i + 1] - ys[i]) / (knots[i + 1] - knots[i])
        return i, slope

    def __call__(self, x: Any) -> Any:
        xa = np.asarray(x, dtype=float)
        i, slope = self._seg(xa)
        val = np.asarray(self.y)[i] + slope * (xa - np.asarray(self.x)[i])
        return val if val.ndim else float(val)

    def d1(self, x: ArrayLike) -> Array:
        return np.asarray(self._seg(np.asarray(x, dtype=float))[1], dtype=float)

    def d2(self, x: ArrayLike) -> Array:
        return np.zeros_like(np.asarray(x, dtype=float))


@dataclass(frozen=True)
class Composite:
    """f(x) = outer(inner(x)): a function of a coordinate eliminated by a
    CoordinateCouplerConstraint (dependent = inner(independent)). Chain rule:
    f' = outer'(inner) · inner', f'' = outer''(inner) · inner'² + outer'(inner) · inner''."""

    outer: CoordinateFunction
    inner: CoordinateFunction

    def __call__(self, x: Any) -> Any:
        return self.outer(self.inner(x))

    def d1(self, x: ArrayLike) -> Array:
        u = np.asarray(self.inner(x), dtype=float)
        return np.asarray(self.outer.d1(u) * self.inner.d1(x), dtype=float)

    def d2(self, x: ArrayLike) -> Array:
        u = np.asarray(self.inner(x), dtype=float)
        i1 = self.inner.d1(x)
        return np.asarray(
            self.outer.d2(u) * i1**2 + self.outer.d1(u) * self.inner.d2(x), dtype=float
        )


# --------------------------------------------------------------------------------------------
# four-bar knee (the rehabilitation-robot lower-limb model paper, §2.1)
# --------------------------------------------------------------------------------------------
_J2 = np.array([[0.0, -1.0], [1.0, 0.0]])


def _rot2(theta: Array) -> Array:
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


@dataclass(frozen=True)
class FourBarKnee:
    """Crossed four-bar linkage of the knee in the sagittal plane (the rehabilitation-robot
    lower-limb model paper, §2.1).

    Femur-fixed attachments A (anterior cruciate) and B (posterior cruciate), tibia-fixed
    attachments C and D, all in the plane (x anterior, y proximal) of the femur / tibia frames.
    The links AC and BD keep the lengths they have at θ = ``theta_ref``. The independent
    coordinate is the tibia rotation θ about the joint z axis (OpenSim ``knee_angle``, negative in
    flexion), and the tibia-frame origin position p(θ) in the femur (joint) frame follows from the
    loop closure in closed form (intersection of two circles)::

        u = C in the femur frame:  |u − A| = L_AC,   |u + R(θ)(d − c) − B| = L_BD
        p(θ) = u − R(θ) c

    Derivatives come from differentiating the two closure equations (exact, not numerical)::

        M u' = [0, −wᵀR'e],   M u'' = [−u'ᵀu', −w'ᵀw' − wᵀR''e],   M = [(u − A)ᵀ; wᵀ]

    with e = d − c, w = u + R e − B.
    """

    femur_a: tuple[float, float]
    femur_b: tuple[float, float]
    tibia_c: tuple[float, float]
    tibia_d: tuple[float, float]
    theta_ref: float = 0.0
    p_ref: tuple[float, float] = (0.0, 0.0)

    @property
    def link_lengths(self) -> tuple[float, float]:
        """L_AC and L_BD, defined by the reference configuration."""
        r = _rot2(np.asarray(self.theta_ref))
        p = np.asarray(self.p_ref)
        c_f = p + r @ np.asarray(self.tibia_c)
        d_f = p + r @ np.asarray(self.tibia_d)
        return (
            float(np.linalg.norm(c_f - self.femur_a)),
            float(np.linalg.norm(d_f - self.femur_b)),
        )

    def _branch(self) -> float:
        # sign of the intersection branch that contains the reference configuration
        r = _rot2(np.asarray(self.theta_ref))
        u_ref = np.asarray(self.p_ref) + r @ np.asarray(self.tibia_c)
        a = np.asarray(self.femur_a)
        e = np.asarray(self.tibia_d) - np.asarray(self.tibia_c)
        delta = np.asarray(self.femur_b) - r @ e - a
        cross = delta[0] * (u_ref - a)[1] - delta[1] * (u_ref - a)[0]
        return 1.0 if cross >= 0 else -1.0

    def solve(self, theta: ArrayLike) -> tuple[Array, Array, Array]:
        """Return p, p', p'' (each (..., 2)) of the tibia origin in the femur joint frame."""
        th = np.asarray(theta, dtype=float)
        l1, l2 = self.link_lengths
        a = np.asarray(self.femur_a)
        b = np.asarray(self.femur_b)
        c = np.asarray(self.tibia_c)
        e = np.asarray(self.tibia_d) - c
        r = _rot2(th)
        re = r @ e
        delta = b - re - a
        dist = np.linalg.norm(delta, axis=-1)
        if np.any(dist > l1 + l2) or np.any(dist < abs(l1 - l2)):
            bad = th.reshape(-1)[np.argmax((dist > l1 + l2) | (dist < abs(l1 - l2)))]
            raise ModelError(f"four-bar knee cannot close at knee angle {bad:.4f} rad")
        along = (l1**2 - l2**2 + dist**2) / (2 * dist)
        h = np.sqrt(np.maximum(l1**2 - along**2, 0.0))
        unit = delta / dist[..., None]
        perp = unit @ _J2.T
        u = a + along[..., None] * unit + self._branch() * h[..., None] * perp
        # derivatives by implicit differentiation of the closure equations
        r1 = r @ _J2  # R'
        r1e = r1 @ e
        r2e = -re  # R'' e
        w = u + re - b
        m = np.stack([u - a, w], axis=-2)
        rhs1 = np.stack([np.zeros_like(th), -np.einsum("...i,...i->...", w, r1e)], -1)
        u1 = np.linalg.solve(m, rhs1[..., None])[..., 0]
        w1 = u1 + r1e
        rhs2 = np.stack(
            [
                -np.einsum("...i,...i->...", u1, u1),
                -np.einsum("...i,...i->...", w1, w1) - np.einsum("...i,...i->...", w, r2e),
            ],
            -1,
        )
        u2 = np.linalg.solve(m, rhs2[..., None])[..., 0]
        p = u - r @ c
        p1 = u1 - r1 @ c
        p2 = u2 + r @ c
        return p, p1, p2

    def closure_residual(self, theta: ArrayLike) -> Array:
        """|AC| − L_AC and |BD| − L_BD at the solved configuration, shape (..., 2)."""
        th = np.asarray(theta, dtype=float)
        p, _, _ = self.solve(th)
        r = _rot2(th)
        cf = p + r @ np.asarray(self.tibia_c)
        df = p + r @ np.asarray(self.tibia_d)
        l1, l2 = self.link_lengths
        return np.stack(
            [
                np.linalg.norm(cf - self.femur_a, axis=-1) - l1,
                np.linalg.norm(df - self.femur_b, axis=-1) - l2,
            ],
            -1,
        )


@dataclass(frozen=True)
class FourBarTranslation:
    """One component (0: x anterior, 1: y proximal) of the four-bar tibia translation p(θ)."""

    linkage: FourBarKnee
    component: int

    def __call__(self, x: Any) -> Any:
        val = self.linkage.solve(x)[0][..., self.component]
        return val if np.ndim(val) else float(val)

    def d1(self, x: ArrayLike) -> Array:
        return self.linkage.solve(x)[1][..., self.component]

    def d2(self, x: ArrayLike) -> Array:
        return self.linkage.solve(x)[2][..., self.component]


# --------------------------------------------------------------------------------------------
# the embedding map θ -> q_pin
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Coupling:
    """q_pin = g(θ) with one scalar function per Pinocchio DOF (see the module docstring).

    ``coordinate[k]`` is the index of the independent coordinate driving Pinocchio DOF k, or -1
    for a constant DOF; ``functions[k]`` is f_k.
    """

    coordinate: tuple[int, ...]
    functions: tuple[CoordinateFunction, ...]
    n_coords: int

    @property
    def nq(self) -> int:
        return len(self.coordinate)

    def _cols(self, theta: Array, k: int) -> Array:
        i = self.coordinate[k]
        return theta[..., i] if i >= 0 else np.zeros(theta.shape[:-1])

    def q(self, theta: ArrayLike) -> Array:
        """g(θ): (..., n_coords) → (..., nq)."""
        th = np.asarray(theta, dtype=float)
        return np.stack(
            [np.asarray(f(self._cols(th, k)), dtype=float) for k, f in enumerate(self.functions)],
            -1,
        )

    def jacobian(self, theta: ArrayLike) -> Array:
        """G = ∂g/∂θ: (..., nq, n_coords)."""
        th = np.asarray(theta, dtype=float)
        out = np.zeros((*th.shape[:-1], self.nq, self.n_coords))
        for k, f in enumerate(self.functions):
            i = self.coordinate[k]
            if i >= 0:
                out[..., k, i] = f.d1(th[..., i])
        return out

    def bias(self, theta: ArrayLike, theta_dot: ArrayLike) -> Array:
        """Ġθ̇ = f_k''(θ_i) θ̇_i², shape (..., nq)."""
        th = np.asarray(theta, dtype=float)
        thd = np.asarray(theta_dot, dtype=float)
        out = np.zeros((*th.shape[:-1], self.nq))
        for k, f in enumerate(self.functions):
            i = self.coordinate[k]
            if i >= 0:
                out[..., k] = f.d2(th[..., i]) * thd[..., i] ** 2
        return out

    def embed(
        self, theta: ArrayLike, theta_dot: ArrayLike, theta_ddot: ArrayLike
    ) -> tuple[Array, Array, Array]:
        """(q, v, a) = (g(θ), Gθ̇, Gθ̈ + Ġθ̇)."""
        g = self.jacobian(theta)
        v = np.einsum("...ki,...i->...k", g, np.asarray(theta_dot, dtype=float))
        a = np.einsum("...ki,...i->...k", g, np.asarray(theta_ddot, dtype=float))
        return self.q(theta), v, a + self.bias(theta, theta_dot)

    def project(self, theta: ArrayLike, tau_pin: ArrayLike) -> Array:
        """τ_θ = Gᵀ τ_pin (virtual work): (..., nq) → (..., n_coords)."""
        return np.einsum("...ki,...k->...i", self.jacobian(theta), np.asarray(tau_pin, dtype=float))
