"""Analog channels held as the file stores them, scaled per channel when read.

A C3D file stores analog samples as 16-bit integers or 32-bit floats with a per-channel scale
and offset (C3D User Guide, Motion Lab Systems 2008, ch. "The ANALOG group": value =
``(sample - OFFSET) * SCALE * GEN_SCALE``). A long trial's float64 copy of them is 4 (int16) or
2 (float32) times the stored size (18 channels at 1200 Hz for 100 000 point frames,
144 MB in float64). :class:`StoredAnalogs` keeps the stored samples and applies
``(float64(sample) - offset) * factor`` to the rows and channels a consumer indexes: element for
element the same float64 operations as scaling the whole array, so the values are bit-identical.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["StoredAnalogs"]


@dataclass(frozen=True, eq=False)
class StoredAnalogs:
    """``(N, C)`` analog samples in their stored dtype (``raw``) with per-channel ``offset`` and
    ``factor`` (``(C,)`` float64); indexing and ``np.asarray`` give the scaled float64 values."""

    raw: NDArray[Any]
    offset: NDArray[np.float64]
    factor: NDArray[np.float64]

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(self.raw.shape)

    @property
    def ndim(self) -> int:
        return 2

    @property
    def size(self) -> int:
        return int(self.raw.size)

    @property
    def dtype(self) -> np.dtype[np.float64]:
        return np.dtype(np.float64)

    @property
    def nbytes(self) -> int:
        """Bytes held (the stored samples), not the float64 size."""
        return int(self.raw.nbytes + self.offset.nbytes + self.factor.nbytes)

    def __len__(self) -> int:
        return int(self.raw.shape[0])

    def __array__(self, dtype: Any = None, copy: bool | None = None) -> NDArray[Any]:
        out = (self.raw.astype(np.float64) - self.offset) * self.factor
        return out if dtype is None else out.astype(dtype, copy=False)

    def __getitem__(self, key: Any) -> NDArray[np.float64]:
        rows, cols = key if isinstance(key, tuple) else (key, slice(None))
        if isinstance(cols, list):
            cols = np.asarray(cols, dtype=np.int64)
        out: NDArray[np.float64] = (self.raw[rows, cols].astype(np.float64) - self.offset[cols]) * (
            self.factor[cols]
        )
        return out
