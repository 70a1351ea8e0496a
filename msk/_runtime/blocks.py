"""Frame blocks of the per-frame stages on long trials.

``muscle_geometry``, ``tension_optimization``, ``strength_identification`` and
``knee_contact`` work on at most :data:`FRAME_BLOCK` frames at a time, so that a long trial
never holds a dense (N, muscles, coordinates) Jacobian or the solvers' (N, …) temporaries
whole: memory is bounded by the block, not the trial. A trial of at most ``FRAME_BLOCK``
frames (every shipped session) is one block, computed exactly as without blocks; on longer
ones the warm-started solvers carry their warm start from one block to the next, so results do
not depend on the block size beyond round-off.

Inside a block, the tension QPs with the knee compartment rows (whole per frame, solved one
frame after the other) are solved in parts of :data:`SOLVE_BLOCK` frames, the warm start
carried: bit for bit the block's one call (``tests/pipeline/test_long_trials.py``), while the
block's
geometry passes (whose wrapped paths iterate the block's frames together) stay per block.
"""

from __future__ import annotations

import itertools

import numpy as np
from numpy.typing import NDArray

__all__ = ["FRAME_BLOCK", "SOLVE_BLOCK", "frame_blocks", "solve_parts"]

#: frames per block (a block of gait2392's 92 muscles × 23 coordinates: ~100 MB of temporaries)
FRAME_BLOCK = 4096

#: frames per QP solve call inside a block, where the frames' QPs are solved one after the
#: other and only the warm start joins them (:func:`solve_parts`): the block's dense Jacobian
#: and the solver's (frames, muscles) arrays are this many frames'
SOLVE_BLOCK = 1024


def frame_blocks(frames: int | NDArray[np.intp]) -> list[NDArray[np.intp]]:
    """``frames`` (a count N, or frame indices) in consecutive blocks of at most
    :data:`FRAME_BLOCK` frames, of equal size (one block, possibly empty, for ≤ FRAME_BLOCK)."""
    idx = np.arange(frames) if isinstance(frames, int) else np.asarray(frames, dtype=np.intp)
    n = idx.size
    k = max(1, -(-n // FRAME_BLOCK))
    bounds = [c * n // k for c in range(k + 1)]
    return [idx[a:b] for a, b in itertools.pairwise(bounds)]


def solve_parts(n: int) -> list[slice]:
    """Positions ``0 … n−1`` of a block's frames in consecutive slices of at most
    :data:`SOLVE_BLOCK` (one slice, possibly empty, for ≤ SOLVE_BLOCK)."""
    return [slice(a, min(a + SOLVE_BLOCK, n)) for a in range(0, n, SOLVE_BLOCK)] or [slice(0, 0)]
