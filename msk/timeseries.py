"""Frame selection on time-axis results: ``result.take(frames)``.

Every result msk computes over a trial is a frozen dataclass whose per-frame arrays have the
frames on axis 0. A class that derives from :class:`FrameAxis` lists those fields in
``FRAME_FIELDS``; ``take(frames)`` returns the same type with each of them indexed by
``frames`` and every other field (column names, per-muscle or per-channel arrays, scalars,
metadata) unchanged:

* arrays: ``x[frames]`` (an ``(N, …)`` array becomes ``(len(frames), …)``);
* per-frame tuples (e.g. the worst marker of each frame): the entries of those frames;
* mappings of per-frame arrays (e.g. one ``(N, m, 6)`` array per joint): each value indexed;
* ``None`` (an optional per-frame field that was not computed) stays ``None``.

``frames`` is a boolean mask of the N frames or integer indices (any order, repeats allowed,
negative ones count from the end). ``take`` copies (numpy fancy indexing) and never changes a
value, so ``r.take(i).q == r.q[i]`` exactly.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, ClassVar, Self

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import ShapeMismatchError

__all__ = ["FrameAxis", "FrameSparse", "frame_indices"]


def frame_indices(frames: ArrayLike, n: int, what: str = "result") -> NDArray[np.intp]:
    """``frames`` (boolean mask of ``n`` frames, or integer indices) as integer indices;
    :class:`~msk.exceptions.ShapeMismatchError` naming ``what`` for a mask of another length,
    a non-integer index or one outside ``-n .. n-1``."""
    f = np.asarray(frames)
    if f.ndim != 1:
        raise ShapeMismatchError(f"{what}: frames must be 1-D (mask or indices), got {f.shape}")
    if f.dtype == np.bool_:
        if f.size != n:
            raise ShapeMismatchError(f"{what}: frame mask has {f.size} entries, expected {n}")
        return np.flatnonzero(f)
    if f.size == 0:
        return np.zeros(0, dtype=np.intp)
    if not np.issubdtype(f.dtype, np.integer):
        raise ShapeMismatchError(f"{what}: frame indices must be integers, got {f.dtype}")
    bad = f[(f < -n) | (f >= n)]
    if bad.size:
        raise ShapeMismatchError(f"{what}: frame index {int(bad[0])} outside 0..{n - 1}")
    return f.astype(np.intp, copy=False)


def _take(value: Any, idx: NDArray[np.intp]) -> Any:
    if value is None:
        return None
    if isinstance(value, np.ndarray):
        return value[idx]
    if isinstance(value, FrameSparse):
        return value.take(idx)
    if isinstance(value, tuple):
        return tuple(value[i] for i in idx)
    if isinstance(value, Mapping):
        return {k: _take(v, idx) for k, v in value.items()}
    raise TypeError(f"cannot take frames of a {type(value).__name__}")


def _length(value: Any) -> int | None:
    if value is None:
        return None
    if isinstance(value, Mapping):
        return next((n for n in map(_length, value.values()) if n is not None), None)
    return len(value)


@dataclasses.dataclass(frozen=True, eq=False)
class FrameSparse:
    """A per-frame array ``(N, *trailing)`` that is zero outside fixed positions (the same in
    every frame): ``values`` ``(N, k)`` the entries at the flat ``positions`` ``(k,)`` of the
    trailing shape. A muscle Jacobian ∂l/∂θ ``(N, muscles, coordinates)`` holds only the
    coordinates each muscle crosses (a few of gait2392's 23), so a long trial keeps it at a
    fraction of its dense size.

    ``x[frames]`` (a slice, integer indices or a boolean mask of the frames) is the dense
    ``(len(frames), *trailing)`` array of those frames — the same values, zeros included, as
    the dense array indexed so; ``take(frames)`` keeps the compact form; ``np.asarray(x)`` is
    the whole dense array."""

    values: NDArray[np.float64]
    positions: NDArray[np.intp]
    trailing: tuple[int, ...]

    @classmethod
    def from_dense(cls, dense: NDArray[np.float64], positions: ArrayLike) -> FrameSparse:
        """The entries of ``dense`` ``(N, *trailing)`` at the flat trailing ``positions`` (the
        caller vouches that the other entries are zero)."""
        pos = np.asarray(positions, dtype=np.intp)
        n = dense.shape[0]
        return cls(dense.reshape(n, -1)[:, pos], pos, tuple(int(d) for d in dense.shape[1:]))

    @property
    def shape(self) -> tuple[int, ...]:
        return (int(self.values.shape[0]), *self.trailing)

    @property
    def ndim(self) -> int:
        return 1 + len(self.trailing)

    @property
    def dtype(self) -> np.dtype[Any]:
        return self.values.dtype

    def __len__(self) -> int:
        return int(self.values.shape[0])

    def __getitem__(self, frames: Any) -> NDArray[np.float64]:
        if isinstance(frames, tuple):
            raise TypeError("FrameSparse: index the frames only (x[frames][:, ...] for more)")
        v = self.values[frames]
        if v.ndim == 1:  # one frame
            out = np.zeros(int(np.prod(self.trailing)), dtype=v.dtype)
            out[self.positions] = v
            return out.reshape(self.trailing)
        out = np.zeros((v.shape[0], int(np.prod(self.trailing))), dtype=v.dtype)
        out[:, self.positions] = v
        return out.reshape(v.shape[0], *self.trailing)

    def __array__(self, dtype: Any = None, copy: Any = None) -> NDArray[Any]:
        out = self[:]
        return out if dtype is None else out.astype(dtype, copy=False)

    def take(self, frames: ArrayLike) -> FrameSparse:
        """The same compact array on ``frames`` (mask or indices)."""
        idx = frame_indices(frames, len(self), "FrameSparse")
        return dataclasses.replace(self, values=self.values[idx])

    @staticmethod
    def concatenate(parts: list[FrameSparse]) -> FrameSparse:
        """Frame blocks of one array (same positions and trailing shape) end to end."""
        first = parts[0]
        return dataclasses.replace(first, values=np.concatenate([p.values for p in parts]))


class FrameAxis:
    """Base of the frozen time-axis results: ``take(frames)`` (see the module docstring).

    A subclass (a frozen dataclass) names its per-frame fields in ``FRAME_FIELDS``; the number
    of frames N is the length of the first of them that is present."""

    FRAME_FIELDS: ClassVar[tuple[str, ...]] = ()

    @property
    def frame_count(self) -> int:
        """N, the number of frames (0 when no per-frame field is present)."""
        for name in self.FRAME_FIELDS:
            n = _length(getattr(self, name))
            if n is not None:
                return n
        return 0

    def take(self, frames: ArrayLike) -> Self:
        """The same result restricted to ``frames`` (boolean mask of the N frames or integer
        indices): every field of ``FRAME_FIELDS`` indexed on axis 0, the others unchanged."""
        idx = frame_indices(frames, self.frame_count, type(self).__name__)
        changes = {name: _take(getattr(self, name), idx) for name in self.FRAME_FIELDS}
        return dataclasses.replace(self, **changes)  # type: ignore[type-var]
