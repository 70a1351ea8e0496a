"""Muscle lengths and moment arms of an ``.osim`` model computed by OpenSim 4.6 in a child
process (:func:`msk._runtime.opensim_peer.run_opensim_script`), for cross-checks."""

from __future__ import annotations

from typing import Any

import numpy as np

from msk._runtime.opensim_peer import POSE_PRELUDE

__all__ = ["OPENSIM_GEOMETRY", "opensim_geometry"]

OPENSIM_GEOMETRY = (
    POSE_PRELUDE
    + """
muscles = [m.getMuscles().get(n) for n in ARGS["muscles"]]
macs = [cs.get(n) for n in ARGS["ma_coords"]]
L, R = [], []
t0 = time.perf_counter()
for q in ARGS["q"]:
    set_pose(q)
    L.append([mu.getLength(s) for mu in muscles])
    R.append([[mu.computeMomentArm(s, c) for c in macs] for mu in muscles])
RESULT["seconds"] = time.perf_counter() - t0
RESULT["L"] = L
RESULT["R"] = R
"""
)


def opensim_geometry(
    path: Any, model: Any, theta: Any, muscles: Any, coords: Any
) -> tuple[Any, Any]:
    """Lengths (N, m) and moment arms (N, m, c) of ``muscles`` about ``coords`` at ``theta``."""
    from msk._runtime.opensim_peer import run_opensim_script

    out = run_opensim_script(
        OPENSIM_GEOMETRY,
        model=str(path),
        coords=list(model.coordinate_names),
        q=np.asarray(theta).tolist(),
        muscles=[model.muscles[k].name for k in muscles],
        ma_coords=[model.coordinate_names[i] for i in coords],
    )
    return np.asarray(out["L"]), np.asarray(out["R"])
