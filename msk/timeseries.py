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

__all__ = ["FrameAxis", "frame_indices"]


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
