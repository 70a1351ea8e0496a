"""Force-plate signals that cannot be a foot's load: a clipped (saturated) channel, a centre
of pressure far outside the plate (:func:`cop_warnings`), forces a decade off the subject's
weight (:func:`scale_flags`).

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

__all__ = [
    "PLAUSIBLE_STANCE_MASS_KG",
    "STANCE_BODY_WEIGHTS",
    "cop_warnings",
    "direction_warnings",
    "longest_run_at_extreme",
    "saturation_warnings",
    "scale_flags",
]


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


def direction_warnings(
    plates: list[ForcePlate] | tuple[ForcePlate, ...],
    up: NDArray[np.float64],
    markers: NDArray[np.float64],
    *,
    min_force_n: float = 100.0,
) -> list[str]:
    """The plates' loads against the lab's vertical: the reader takes ``up`` from the sign of
    the plates' summed vertical force, so a negative gain on every plate turns the lab upside
    down and one on a single plate makes it pull the subject into the floor. Said when the
    markers (N, M, 3) lie mostly below the plates' surfaces along ``up`` (the body stands on
    the plates: its markers are above them), and for a plate whose force under load
    (> ``min_force_n``) points down in most samples while ``up`` is the other plates' up."""
    out = []
    u = np.asarray(up, dtype=float)
    x = np.asarray(markers, dtype=float)
    surfaces = [float(np.mean(np.asarray(p.corners, dtype=float) @ u)) for p in plates]
    if plates and x.size and np.isfinite(x).any() and np.isfinite(surfaces).all():
        with np.errstate(invalid="ignore"):
            height = float(np.nanmedian(x @ u)) - float(np.mean(surfaces))
        if height < -0.05:
            out.append(
                f"the markers lie {-height:.2f} m below the force plates' surfaces along the "
                "vertical the plates' forces give: a negative gain or flipped plate axes has "
                "turned the vertical (and every ground reaction) upside down"
            )
    for p in plates:
        f = np.asarray(p.force, dtype=float)
        load = np.linalg.norm(f, axis=1)
        with np.errstate(invalid="ignore"):
            loaded = load > min_force_n
            down = (f @ u) < 0
        if loaded.sum() >= 10 and (down & loaded).sum() > 0.5 * loaded.sum() and len(plates) > 1:
            out.append(
                f"force platform {p.index + 1}: its force points down (into the floor) in "
                f"{int((down & loaded).sum())} of {int(loaded.sum())} loaded samples while the "
                "other plates push up: a negative gain or flipped axes"
            )
    return out


#: a plate's mean vertical force over its longest stance, in body weights, that a foot's load
#: gives: ~0.5 standing with a foot on each of two plates, 0.8–1 walking or standing on one
#: plate, ~1.6 running (a stance's impulse is half the body weight × the stride time) — with
#: margins for a foot partly on the plate and a jump landing
STANCE_BODY_WEIGHTS = (0.3, 3.0)
#: the body masses (kg) a plate's stance can weigh without a known mass: the stance range above
#: applied to 10–250 kg subjects
PLAUSIBLE_STANCE_MASS_KG = (STANCE_BODY_WEIGHTS[0] * 10.0, STANCE_BODY_WEIGHTS[1] * 250.0 / 2)


def _longest_stance(
    fz: NDArray[np.float64], rate_hz: float, min_s: float, min_load_n: float = 50.0
) -> float | None:
    """The mean of ``fz`` over its longest run above 10 % of its 99th percentile lasting at
    least ``min_s``; None without one, or when the 99th percentile is below ``min_load_n``
    (an unloaded plate: its offset and noise weigh nothing)."""
    f = np.where(np.isfinite(fz), fz, 0.0)
    top = float(np.percentile(f, 99)) if f.size else 0.0
    if not top > min_load_n:
        return None
    on = np.concatenate([[0], (f > 0.1 * top).astype(np.int8), [0]])
    d = np.diff(on)
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    if not starts.size:
        return None
    k = int(np.argmax(ends - starts))
    if (ends[k] - starts[k]) < min_s * rate_hz:
        return None
    return float(np.mean(f[starts[k] : ends[k]]))


def scale_flags(
    plates: list[ForcePlate] | tuple[ForcePlate, ...],
    up: NDArray[np.float64],
    mass_kg: float | None,
    *,
    g: float = 9.80665,
    min_stance_s: float = 0.15,
) -> list[dict[str, float | str]]:
    """Plates whose forces are off by a factor (``ANALOG:SCALE``, ``GEN_SCALE`` or a channel's
    units mis-set): each plate weighs the subject by its mean vertical force F̄ over its longest
    stance (≥ ``min_stance_s``), r = F̄ / (m g) body weights, which a foot's load keeps within
    :data:`STANCE_BODY_WEIGHTS`. Without a mass the plate's weighing m̂ = F̄ / g must lie within
    :data:`PLAUSIBLE_STANCE_MASS_KG`, and the plates must agree with one another within a
    factor 5 (the median plate as the reference). The factor said is the power of ten 10ᵏ
    bringing the ratio back into its range. Typed flags (``quantity`` ``plate_force_scale``,
    ``value`` the factor, ``threshold`` the ratio range's bound, ``message``)."""
    u = np.asarray(up, dtype=float)
    weigh: dict[int, float] = {}
    for p in plates:
        fz = np.asarray(p.force, dtype=float) @ u
        m = _longest_stance(fz, p.rate_hz, min_stance_s)
        if m is not None:
            weigh[p.index] = m / g  # kg
    out: list[dict[str, float | str]] = []

    def factor(ratio: float, lo: float, hi: float) -> float:
        k = round(float(np.log10(ratio / np.sqrt(lo * hi))))
        return 10.0**k

    ref = float(np.median(list(weigh.values()))) if len(weigh) >= 3 else None
    for index, m_hat in weigh.items():
        if mass_kg is not None and mass_kg > 0:
            r = m_hat / mass_kg
            lo, hi = STANCE_BODY_WEIGHTS
            what = f"{r:.2g} × the subject's {mass_kg:g} kg"
        else:
            lo, hi = PLAUSIBLE_STANCE_MASS_KG
            r = m_hat
            what = "no human's weight"
            if ref is not None and ref > 0 and not 0.2 <= m_hat / ref <= 5.0:
                r, lo, hi = m_hat / ref, 0.5, 2.0
                what = f"{r:.2g} × the other plates' median ({ref:.0f} kg)"
        if lo <= r <= hi or not r > 0:
            continue
        f = factor(r, lo, hi)
        said = f"a factor {f:g} off" if f != 1.0 else "off"
        out.append(
            {"quantity": "plate_force_scale", "value": f, "threshold": hi if r > hi else lo,
             "message": f"force platform {index + 1} weighs the subject at {m_hat:.3g} kg over "
             f"its longest stance: {what}; its forces look {said} (ANALOG:SCALE, GEN_SCALE or "
             "the channels' units mis-set); msk does not rescale them"}
        )  # fmt: skip
    return out
