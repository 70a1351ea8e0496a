"""Stage ``muscle_geometry``: muscle-tendon lengths, velocities and moment-arm Jacobians on the
usable frames (:func:`msk.muscles.geometry.muscle_geometry`).

The Jacobian is kept compact (:class:`msk.timeseries.FrameSparse`: only the coordinates each
muscle crosses), evaluated block by block (:mod:`msk._runtime.blocks`): a long trial never holds
it dense. The knee's unit wrenches ∂l/∂ξ are not kept: the knee contact stage recomputes them
block by block from the same paths, where it consumes them (held from this stage to the
contact stage, they would be 0.6 kB/frame of a long trial's resident set).

On a trial longer than one block (:data:`msk._runtime.blocks.FRAME_BLOCK`) the Jacobian is not
held either: its compact values are :class:`JacobianRows`, which recompute the rows asked for
block by block, each block exactly as this stage evaluated it (the same frames in one call:
bit for bit the values a held Jacobian would give). The tension, strength and knee contact
stages read it by blocks of frames; held, it would cost a 100 000-frame trial 2.1 kB/frame,
210 MB, from here to the contact stage. A trial of one block keeps it."""

from __future__ import annotations

from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from msk._runtime.blocks import frame_blocks
from msk.personalise import Personalisation
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.records import Loads
from msk.pipeline.runner import StageUnavailable

__all__ = ["JacobianRows", "compact_values", "posed_geometry", "run"]


class JacobianRows:
    """The compact values ``(N, k)`` of a trial's muscle Jacobian (the flat ``positions`` of
    each frame's ``(muscles, coordinates)`` matrix), recomputed where read: ``rows[frames]`` or
    ``rows[frames, columns]`` evaluates the geometry (:func:`msk.muscles.geometry.muscle_geometry`)
    on each block of ``blocks`` holding one of ``frames``, on the geometry stage's poses and
    velocities (unusable frames at the default pose, at rest) and in the stage's blocks, so each
    value is the one the stage computed. The last block evaluated is kept: reading a trial block
    by block evaluates each block once. Pickled as the array it stands for."""

    def __init__(
        self,
        model: Any,
        q: NDArray[np.float64],
        v: NDArray[np.float64],
        usable: NDArray[np.bool_],
        positions: NDArray[np.intp],
        blocks: list[NDArray[np.intp]],
    ) -> None:
        from msk.muscles.geometry import geometry_plan

        self._model, self._plan = model, geometry_plan(model)
        self._q, self._v, self._ok = q, v, usable
        self._positions = positions
        self._bounds = np.array([int(b[0]) for b in blocks] + [q.shape[0]], dtype=np.intp)
        self._cached: tuple[int, NDArray[np.float64]] | None = None
        self.shape = (int(q.shape[0]), int(positions.size))
        self.dtype = np.dtype(np.float64)
        self.ndim = 2

    def __len__(self) -> int:
        return self.shape[0]

    def block(self, k: int) -> NDArray[np.float64]:
        """The compact values of block ``k``'s frames, as the geometry stage computed them."""
        if self._cached is not None and self._cached[0] == k:
            return self._cached[1]
        sl = slice(int(self._bounds[k]), int(self._bounds[k + 1]))
        g = posed_geometry(self._model, self._q, self._v, self._ok, sl, self._plan)
        vals = compact_values(g.jacobian, self._positions)
        self._cached = (k, vals)
        return vals

    def __getitem__(self, key: Any) -> NDArray[np.float64]:
        rows, cols = key if isinstance(key, tuple) else (key, slice(None))
        idx = np.atleast_1d(np.arange(self.shape[0])[rows])
        width = np.empty(self.shape[1])[cols].size
        out = np.empty((idx.size, width))
        which = np.searchsorted(self._bounds, idx, side="right") - 1
        for k in np.unique(which):  # in block order: each block evaluated at most once
            here = which == k
            out[here] = self.block(int(k))[idx[here] - self._bounds[k]][:, cols]
        return out[0] if isinstance(rows, (int, np.integer)) else out

    def __array__(self, dtype: Any = None, copy: Any = None) -> NDArray[Any]:
        out = self[:]
        return out if dtype is None else out.astype(dtype, copy=False)

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        return (np.asarray, (self[:],))


def posed_geometry(
    model: Any,
    q: NDArray[np.float64],
    v: NDArray[np.float64],
    usable: NDArray[np.bool_],
    frames: slice,
    plan: Any,
) -> Any:
    """:func:`msk.muscles.geometry.muscle_geometry` of the ``frames`` of a trial, the frames
    that are not ``usable`` at the default pose, at rest; the Jacobian compact
    (:class:`msk.timeseries.FrameSparse` at the plan's positions: never dense)."""
    from msk.muscles.geometry import muscle_geometry

    ok = usable[frames, None]
    qb = np.where(ok, q[frames], model.default_coordinates()[None, :])
    vb = np.where(ok, v[frames], 0.0)
    return muscle_geometry(model, qb, vb, plan=plan, compact=True)


def compact_values(jacobian: Any, positions: NDArray[np.intp]) -> NDArray[np.float64]:
    """The values ``(N, k)`` of a compact Jacobian (:class:`msk.timeseries.FrameSparse`) at
    the flat ``positions`` (a subset of its own, increasing): its values array itself when the
    positions are its own."""
    if np.array_equal(jacobian.positions, positions):
        return cast(NDArray[np.float64], jacobian.values)
    return cast(
        NDArray[np.float64],
        jacobian.values[:, np.searchsorted(jacobian.positions, positions)],
    )


def run(inputs: SessionInputs, model: Personalisation, kinematics: Any, loads: Loads) -> Any:
    """:class:`msk.muscles.geometry.MuscleGeometry` with a compact ``jacobian`` (no
    ``distal_wrenches``); frames in which no leg is solvable
    (:attr:`msk.pipeline.loads.Loads.solvable`) are evaluated at the default pose, at rest
    (their values are never used). On a trial of more than one block the compact values are
    :class:`JacobianRows` (recomputed where read, not held)."""
    mdl, kin, ok = model.model, kinematics, loads.solvable
    if not mdl.muscles:
        raise StageUnavailable(f"model {mdl.name} has no muscles")
    from msk.muscles.geometry import MuscleGeometry, geometry_plan
    from msk.timeseries import FrameSparse

    plan = geometry_plan(mdl)
    jpos = plan.jacobian_positions()
    n, n_mus = kin.q.shape[0], len(plan.muscle_names)
    blocks = frame_blocks(n)
    held = len(blocks) == 1
    # filled block by block into arrays allocated once (a list of blocks concatenated at the
    # end would hold the whole geometry twice at that moment: the stage's high-water)
    lengths = np.empty((n, n_mus))
    vel = np.empty((n, n_mus))
    values: Any = (
        np.empty((n, jpos.size)) if held else JacobianRows(mdl, kin.q, kin.v, ok, jpos, blocks)
    )
    for b in blocks:
        sl = slice(int(b[0]), int(b[-1]) + 1) if b.size else slice(0, 0)
        g = posed_geometry(mdl, kin.q, kin.v, ok, sl, plan)
        lengths[sl] = g.lengths
        vel[sl] = g.velocities
        if held:
            values[sl] = compact_values(g.jacobian, jpos)
        del g
    jac = FrameSparse(cast(NDArray[np.float64], values), jpos, (n_mus, len(plan.coordinate_names)))
    return MuscleGeometry(tuple(plan.muscle_names), tuple(plan.coordinate_names), lengths, jac, vel)
