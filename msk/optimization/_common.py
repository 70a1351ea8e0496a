"""Input checking shared by the optimisation problems (typed errors naming the offending item)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from msk.exceptions import OptimizationError
from msk.units import Array

__all__ = [
    "as_float",
    "check_finite",
    "check_frame",
    "check_jacobian",
    "check_positive",
    "names_or_default",
    "set_fields",
]


def names_or_default(
    names: Sequence[str] | None, n: int, prefix: str, what: str
) -> tuple[str, ...]:
    if names is None:
        return tuple(f"{prefix}{i}" for i in range(n))
    out = tuple(str(s) for s in names)
    if len(out) != n:
        raise OptimizationError(f"{len(out)} {what} names given for {n} {what}s")
    return out


def as_float(value: ArrayLike, shape: tuple[int, ...], what: str) -> Array:
    """``value`` as a float array of ``shape`` (broadcast from a scalar), finite, else an error."""
    arr = np.asarray(value, dtype=float)
    try:
        arr = np.broadcast_to(arr, shape).copy()
    except ValueError:
        raise OptimizationError(
            f"{what} has shape {np.shape(value)}, expected {shape} (or a scalar)"
        ) from None
    return arr


def check_finite(arr: Array, what: str, names: Sequence[str] | None = None) -> None:
    bad = ~np.isfinite(arr)
    if bad.any():
        idx = np.argwhere(bad)[0]
        label = names[int(idx[-1])] if names is not None and arr.ndim >= 1 else str(tuple(idx))
        frame = f" at frame {int(idx[0])}" if arr.ndim >= 2 and names is not None else ""
        raise OptimizationError(
            f"{what} is not finite for {label}{frame}: {float(arr[tuple(idx)])!r}"
        )


def check_positive(arr: Array, what: str, names: Sequence[str]) -> None:
    bad = ~(arr > 0)
    if bad.any():
        i = int(np.argwhere(bad)[0][-1])
        value = float(arr.reshape(-1, arr.shape[-1])[0, i])
        raise OptimizationError(f"{what} must be > 0; muscle {names[i]!r} has {value!r}")


def check_jacobian(jacobian: ArrayLike, ndim: int) -> Array:
    j = np.asarray(jacobian, dtype=float)
    if j.ndim != ndim:
        shape = "(n_muscles, n_coords)" if ndim == 2 else "(n_frames, n_muscles, n_coords)"
        raise OptimizationError(f"jacobian has shape {j.shape}, expected {shape}")
    if not np.all(np.isfinite(j)):
        idx = tuple(int(i) for i in np.argwhere(~np.isfinite(j))[0])
        raise OptimizationError(f"jacobian is not finite at index {idx}: {float(j[idx])!r}")
    return j


def check_frame(
    jacobian: ArrayLike,
    tau: ArrayLike,
    muscle_names: Sequence[str] | None,
    coordinate_names: Sequence[str] | None,
    *,
    ndim: int = 2,
    tau_name: str = "tau",
) -> tuple[Array, Array, tuple[str, ...], tuple[str, ...]]:
    """The inputs every problem shares, checked: the jacobian ``(m, n)`` (or ``(N, m, n)`` with
    ``ndim=3``), the muscle and coordinate names (defaults ``muscle<i>``/``coord<j>``) and a
    finite ``tau`` ``(n,)`` (``(N, n)``). Returns ``(jacobian, tau, muscle_names,
    coordinate_names)``."""
    j = check_jacobian(jacobian, ndim)
    m, n = j.shape[-2:]
    mn = names_or_default(muscle_names, m, "muscle", "muscle")
    cn = names_or_default(coordinate_names, n, "coord", "coordinate")
    t = as_float(tau, (*j.shape[:-2], n), tau_name)
    check_finite(t, tau_name, cn)
    return j, t, mn, cn


def set_fields(obj: Any, **values: Any) -> None:
    """Store the checked, normalised values on a frozen dataclass (from its ``__post_init__``)."""
    for key, val in values.items():
        object.__setattr__(obj, key, val)
