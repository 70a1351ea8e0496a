"""Force-plate signals that cannot be a foot's load: a clipped (saturated) channel, a centre
of pressure far outside the plate (:func:`cop_warnings`).

An amplifier or converter driven beyond its range holds its last code: the channel reads one
exact value, its extreme, for as long as the load exceeds the range. A foot's load never does:
near a peak of the vertical force (curvature ~10⁵ N/s² in walking) the force changes by more
than a 16-bit converter's step within a few milliseconds, so it stays on one exact value for
at most a few samples. :func:`saturation_warnings` reports a component of a plate's force or
moment, in the plate's own axes (where each is one channel of a type-2/4 plate), that sits on
exactly its largest (or smallest) value for ``min_run_s`` or longer, at a load above
``min_force_n`` — the clipped part of the trial is then not a measurement.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from msk.trial import ForcePlate

__all__ = ["cop_warnings", "longest_run_at_extreme", "saturation_warnings"]


def longest_run_at_extreme(x: NDArray[np.float64]) -> tuple[int, float]:
    """The longest run of samples exactly at ``x``'s largest or smallest finite value, and
    that value (the one of the longer run)."""
    fin = np.isfinite(x)
    if not fin.any():
        return 0, float("nan")
    best, where = 0, float("nan")
    for v in (float(np.max(x[fin])), float(np.min(x[fin]))):
        at = np.concatenate([[0], (x == v).astype(np.int8), [0]])
        d = np.diff(at)
        runs = np.flatnonzero(d == -1) - np.flatnonzero(d == 1)
        if runs.size and int(runs.max()) > best:
            best, where = int(runs.max()), v
    return best, where


def saturation_warnings(
    plate: ForcePlate, *, min_run_s: float = 0.01, min_force_n: float = 50.0
) -> list[str]:
    """One line per force or moment component of ``plate`` that looks clipped (see the module
    docstring); empty for a plate that does not."""
    out = []
    min_run = max(3, round(min_run_s * plate.rate_hz))
    axes = np.asarray(plate.rotation, dtype=float)
    load = np.linalg.norm(np.asarray(plate.force, dtype=float), axis=1)
    for what, signal, unit in (("force", plate.force, "N"), ("moment", plate.moment, "N·m")):
        local = np.asarray(signal, dtype=float) @ axes  # components along the plate's axes
        for k, axis in enumerate("xyz"):
            run, value = longest_run_at_extreme(local[:, k])
            if run < min_run or value == 0.0:
                continue
            at = np.isclose(local[:, k], value, rtol=0.0, atol=0.0)
            if not np.nanmax(np.where(at, load, 0.0)) > min_force_n:
                continue
            out.append(
                f"force platform {plate.index + 1}: {what} {axis} (plate axes) holds exactly "
                f"{value:.6g} {unit}, its extreme, for {run} samples "
                f"({1000 * run / plate.rate_hz:.0f} ms): clipped (saturated amplifier or "
                "converter); the load there is not measured"
            )
    return out


def cop_warnings(
    plate: ForcePlate, *, factor: float = 2.0, min_force_n: float = 100.0
) -> list[str]:
    """A centre of pressure far outside the plate under a real load: farther from the plate's
    centre than ``factor`` × its half-diagonal while ``|F| > min_force_n`` — a wrong origin,
    calibration or plate type, not a foot (on 25 real C3D files' plates the COP stays within
    1.06 half-diagonals under 100 N or more)."""
    corners = np.asarray(plate.corners, dtype=float)
    cop = np.asarray(plate.cop, dtype=float)
    if corners.shape != (4, 3) or not np.isfinite(corners).all() or cop.size == 0:
        return []
    centre = corners.mean(axis=0)
    half = float(np.linalg.norm(corners - centre, axis=1).max())
    load = np.linalg.norm(np.asarray(plate.force, dtype=float), axis=1)
    with np.errstate(invalid="ignore"):
        far = np.linalg.norm(cop - centre, axis=1)
        bad = (load > min_force_n) & (far > factor * half)
    if half <= 0 or not bad.any():
        return []
    k = int(np.argmax(np.where(bad, far, -np.inf)))
    return [
        f"force platform {plate.index + 1}: centre of pressure {far[k]:.3g} m from the plate's "
        f"centre (its half-diagonal {half:.3g} m) under {load[k]:.0f} N in {int(bad.sum())} "
        "samples: the plate's origin, calibration or type is wrong"
    ]
