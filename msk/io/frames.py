"""Lab frame → model frame: rotating a whole :class:`~msk.io.Trial`.

A C3D lab is usually Z-up with the walkway along ±x or ±y; an OpenSim model is Y-up with the
subject walking along +x. :func:`lab_to_model_rotation` builds the rotation ``R``
(``x_model = R x_lab``): the smallest rotation taking the lab vertical to the model's up
(Rodrigues), then a rotation about the vertical so that the horizontal progression of the
marker centroid (when longer than 0.3 m) points along the model's ``forward`` axis.
:func:`rotate_trial` (``Trial.rotated(R)``) applies ``R`` to everything that lives in the lab
frame, and :func:`to_model_frame` does both.

A rotation about the lab origin maps a point ``p`` to ``R p`` and a free vector (force,
moment) ``v`` to ``R v``; so a plate moment about its origin ``o`` stays the moment about the
rotated origin ``R o``: ``R (M_o) = R ((c − o) × F + T) = (R c − R o) × R F + R T``.

Heading from the pelvis (:func:`pelvis_heading_rotation`): the progression of the centroid says
nothing on a treadmill, in a short trial or one that goes back and forth (the subject's pelvis
then ends up facing anywhere and inverse kinematics settles tens of millimetres off). The pelvis
markers do: after levelling (lab up → model up), the yaw ψ about the vertical u that best maps
the observed horizontal pelvis-marker pattern b_i(t) (centred) onto the model's default-pose
pattern a_i (centred) is the 2-D Procrustes / Kabsch solution about one axis (Kabsch 1976, Acta
Cryst A32:922; Umeyama 1991, IEEE TPAMI 13:376, restricted to rotations about u):

    ψ_t = atan2(u · Σ_i b_i × a_i, Σ_i b_i · a_i),

and ψ is the circular median of ψ_t over the frames where those markers are all tracked, so the
subject's pelvis faces the model's forward. The fit is checked (horizontal residual after a
uniform scale) and the chain falls back to the progression (> 0.3 m), then to levelling only.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from msk.exceptions import ShapeMismatchError
from msk.trial import ForcePlate, Trial
from msk.units import Array

if TYPE_CHECKING:
    from msk.model.core import Model


__all__ = [
    "HEADING_SOURCES",
    "Heading",
    "lab_to_model_rotation",
    "pelvis_heading_rotation",
    "rotate_plate",
    "rotate_trial",
    "rotation_between",
    "to_model_frame",
    "up_from_ground_reactions",
]

#: horizontal progression (m) of the marker centroid below which no heading is applied
MIN_PROGRESSION_M = 0.3


def rotation_between(a: ArrayLike, b: ArrayLike) -> Array:
    """Smallest rotation taking the direction ``a`` to the direction ``b`` (Rodrigues):
    ``R = I + [v]× + [v]×² / (1 + c)`` with ``v = â × b̂``, ``c = â · b̂``; a half turn about
    an axis normal to ``a`` when they are opposite."""
    va = np.asarray(a, dtype=float)
    vb = np.asarray(b, dtype=float)
    if (
        va.shape != (3,)
        or vb.shape != (3,)
        or not (np.linalg.norm(va) > 0 and np.linalg.norm(vb) > 0)
    ):
        raise ShapeMismatchError(f"directions must be non-zero 3-vectors, got {va} and {vb}")
    va = va / np.linalg.norm(va)
    vb = vb / np.linalg.norm(vb)
    v = np.cross(va, vb)
    c = float(va @ vb)
    if c < -1 + 1e-12:  # opposite: half turn about any axis normal to a
        n = np.cross(va, [1.0, 0.0, 0.0])
        if np.linalg.norm(n) < 1e-6:
            n = np.cross(va, [0.0, 1.0, 0.0])
        n /= np.linalg.norm(n)
        return 2 * np.outer(n, n) - np.eye(3)
    s = float(np.linalg.norm(v))
    if s < 1e-15:  # the same direction
        return np.eye(3)
    # axis–angle form of the same rotation: stable near a half turn, where 1/(1 + c) is not
    k = v / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * kx + (1.0 - c) * kx @ kx


def lab_to_model_rotation(
    up_lab: ArrayLike,
    up_model: ArrayLike,
    markers: Array | None = None,
    *,
    forward: ArrayLike = (1.0, 0.0, 0.0),
) -> Array:
    """Rotation R (x_model = R x_lab): lab up → model up, then about the vertical so that the
    horizontal progression of the marker centroid (when > 0.3 m) points along ``forward``
    (projected on the model's floor plane). ``markers`` (N, M, 3) lab frame, NaN gaps."""
    u = np.asarray(up_model, dtype=float)
    r = rotation_between(up_lab, u)
    if markers is None or markers.size == 0:
        return r
    phi = _progression_yaw(np.asarray(markers, dtype=float), r, u / np.linalg.norm(u), forward)
    return r if phi is None else _about(u / np.linalg.norm(u), phi) @ r


#: where a heading came from, best first
HEADING_SOURCES: tuple[str, ...] = ("pelvis markers", "progression", "none")


@dataclasses.dataclass(frozen=True)
class Heading:
    """A lab → model rotation and how its heading (rotation about the vertical) was found.

    Attributes:
        rotation: (3, 3) R, ``x_model = R x_lab``.
        source: one of :data:`HEADING_SOURCES`.
        yaw_deg: the rotation about the model's up applied after levelling (deg).
        markers: the model's pelvis markers used (empty unless ``source == "pelvis markers"``).
        n_frames: frames the pelvis fit used.
        pelvis_rms_m: median horizontal RMS residual of the pelvis fit (m), NaN when not fitted.
        progression_yaw_deg: the yaw the progression would give (NaN when < 0.3 m).
        message: why a better source was not used.
    """

    rotation: Array
    source: str
    yaw_deg: float
    markers: tuple[str, ...] = ()
    n_frames: int = 0
    pelvis_rms_m: float = math.nan
    progression_yaw_deg: float = math.nan
    message: str = ""


def _about(u: Array, phi: float) -> Array:
    """Rotation by ``phi`` about the unit axis ``u`` (Rodrigues)."""
    k = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    return np.eye(3) + math.sin(phi) * k + (1 - math.cos(phi)) * k @ k


#: frames per block of the heading's rotated markers (a long trial's markers are not copied
#: whole)
HEADING_BLOCK = 4096


def _rotated_blocks(
    markers: Array, r: Array, *, zeros_as_gaps: bool = False
) -> Iterator[tuple[slice, Array]]:
    """``(frames, markers[frames] @ r.T)`` over consecutive blocks of :data:`HEADING_BLOCK`
    frames (each frame's values those of the whole product; exact-zero samples NaN first with
    ``zeros_as_gaps``)."""
    n = markers.shape[0]
    for c0 in range(0, n, HEADING_BLOCK):
        sl = slice(c0, min(c0 + HEADING_BLOCK, n))
        x = np.array(markers[sl], dtype=float)
        if zeros_as_gaps:
            x[(x == 0.0).all(axis=2)] = np.nan
        yield sl, x @ r.T


def _progression_yaw(
    markers: Array, r: Array, u: Array, forward: ArrayLike, *, zeros_as_gaps: bool = False
) -> float | None:
    """Yaw (rad, about ``u``) taking the horizontal progression of the marker centroid of
    ``markers`` (N, M, 3) levelled by ``r`` to ``forward``; None below
    :data:`MIN_PROGRESSION_M`. The centroids block by block (:func:`_rotated_blocks`)."""
    n = markers.shape[0]
    count = np.empty(n, dtype=np.intp)
    total = np.empty((n, 3))
    for sl, rotated in _rotated_blocks(markers, r, zeros_as_gaps=zeros_as_gaps):
        seen = np.asarray(np.isfinite(rotated).all(axis=2))  # (n, M): markers visible
        count[sl] = seen.sum(axis=1)
        total[sl] = np.where(seen[..., None], rotated, 0.0).sum(axis=1)
    ok = count > 0  # frames with no marker at all carry no centroid
    c = total[ok] / count[ok, None]
    if c.shape[0] < 2:
        return None
    d = c[-1] - c[0]
    d = d - (d @ u) * u
    if np.linalg.norm(d) < MIN_PROGRESSION_M:
        return None
    x = np.asarray(forward, dtype=float)
    x = x - (x @ u) * u
    d, x = d / np.linalg.norm(d), x / np.linalg.norm(x)
    return math.atan2(float(u @ np.cross(d, x)), float(d @ x))


def _circular_median(angles: Array, *, window: float = math.pi / 4) -> float:
    """Median of angles (rad) about their dominant direction, wrapped to (−π, π]: the circular
    mean, then the median of the angles within ``window`` of it (twice, so that a minority
    facing the other way — a subject who turned round — does not pull it)."""
    centre = math.atan2(float(np.sin(angles).mean()), float(np.cos(angles).mean()))
    for _ in range(2):
        dev = np.angle(np.exp(1j * (angles - centre)))
        near = np.abs(dev) <= window
        if not near.any():
            break
        centre = float(np.angle(np.exp(1j * (centre + float(np.median(dev[near]))))))
    return centre


def _root_markers(model: Model) -> list[str]:
    """Markers on the body the floating base carries (the pelvis of a gait model)."""
    from msk.model.core import GROUND

    roots = {j.child for j in model.joints if j.parent == GROUND}
    return [mk.name for mk in model.markers if mk.body in roots]


def pelvis_heading_rotation(
    up_lab: ArrayLike,
    up_model: ArrayLike,
    markers: Array,
    labels: Sequence[str],
    model: Model,
    *,
    rename: Mapping[str, str] | None = None,
    forward: ArrayLike = (1.0, 0.0, 0.0),
    min_frames: int = 5,
    min_spread_m: float = 0.05,
    max_rms_m: float = 0.03,
) -> Heading:
    """Lab → model rotation whose heading comes from the pelvis markers (module docstring).

    Fallback chain: the model's pelvis markers (markers on the floating-base body, e.g.
    gait2392's R.ASIS, L.ASIS, V.Sacral; at least 2 whose default-pose horizontal positions
    spread over ``min_spread_m``: a rotation about a known vertical needs only one horizontal
    direction; 3 are used when tracked) tracked together in ``min_frames`` frames with a fit
    residual ≤ ``max_rms_m`` → the progression of the marker centroid (≥ 0.3 m, as
    :func:`lab_to_model_rotation`) → levelling only.

    Args:
        up_lab: the lab's up (−gravity) in lab coordinates.
        up_model: the model's up (OpenSim: +y).
        markers: (N, M, 3) lab frame, m, NaN gaps.
        labels: the M labels, in the model's marker names where they match (else use
            ``rename``).
        model: the model (its default pose gives the pelvis pattern).
        rename: model marker → lab label, when ``labels`` are the lab's own labels.
        forward: the model's forward, for the progression fallback.
        min_frames, min_spread_m, max_rms_m: acceptance of the pelvis fit.

    Returns:
        :class:`Heading`.
    """
    from msk.model.core import forward_kinematics

    u = np.asarray(up_model, dtype=float)
    u = u / np.linalg.norm(u)
    r0 = rotation_between(up_lab, u)
    x = np.asarray(markers, dtype=float)  # not copied: levelled block by block
    labels = tuple(labels)
    if x.ndim != 3 or x.shape[2] != 3 or x.shape[1] != len(labels):
        raise ShapeMismatchError(f"markers {x.shape} must be (N, {len(labels)}, 3)")
    # exact zeros: gaps (TRC writers)
    prog = _progression_yaw(x, r0, u, forward, zeros_as_gaps=True) if x.size else None
    prog_deg = math.nan if prog is None else math.degrees(prog)
    inv = {v: k for k, v in (rename or {}).items()}
    col: dict[str, int] = {}
    for i, lab in enumerate(labels):
        col.setdefault(inv.get(lab, lab), i)
    names = [n for n in _root_markers(model) if n in col]
    why = ""
    if len(names) < 2:
        why = f"fewer than 2 pelvis markers in the trial ({names})"
    else:
        data = model.create_data()
        forward_kinematics(model, data, model.default_coordinates())
        model_pos = {n: np.asarray(data.oMf[model.marker_frame[n]].translation) for n in names}
        cols = [col[n] for n in names]
        parts = [rb[:, cols] for _, rb in _rotated_blocks(x, r0, zeros_as_gaps=True)]
        pelvis = np.concatenate(parts) if parts else np.empty((0, len(cols), 3))
        at = {n: k for k, n in enumerate(names)}  # the pelvis markers' columns of ``pelvis``
        seen = np.asarray(np.isfinite(pelvis).all(axis=2))
        # drop the least-tracked markers until enough frames track all the rest
        order = sorted(range(len(names)), key=lambda k: -int(seen[:, k].sum()))
        keep = list(order)
        while len(keep) > 2 and int(seen[:, keep].all(axis=1).sum()) < min_frames:
            keep.pop()
        names = [names[k] for k in sorted(keep)]
        frames = seen[:, sorted(keep)].all(axis=1)
        a = np.array([model_pos[n] for n in names])
        a = a - (a @ u)[:, None] * u
        a = a - a.mean(axis=0)
        spread = float(np.linalg.svd(a, compute_uv=False)[0]) if len(names) > 1 else 0.0
        if int(frames.sum()) < min_frames:
            why = f"pelvis markers {names} tracked together in {int(frames.sum())} frames"
        elif spread < min_spread_m:
            why = f"pelvis markers {names} span {spread:.3f} m horizontally"
        else:
            b = pelvis[frames][:, [at[n] for n in names]]
            b = b - (b @ u)[..., None] * u
            b = b - b.mean(axis=1, keepdims=True)
            cross = np.einsum("tij,j->t", np.cross(b, a[None]), u)
            dot = np.einsum("tij,ij->t", b, a)
            psi_t = np.arctan2(cross, dot)
            psi = _circular_median(psi_t)
            rot = _about(u, psi)
            bb = b @ rot.T
            s = np.einsum("tij,ij->t", bb, a) / np.maximum(np.einsum("tij,tij->t", bb, bb), 1e-12)
            res = np.sqrt(((s[:, None, None] * bb - a[None]) ** 2).sum(axis=2).mean(axis=1))
            rms = float(np.median(res))
            if rms <= max_rms_m:
                return Heading(
                    rot @ r0,
                    "pelvis markers",
                    math.degrees(psi),
                    tuple(names),
                    int(frames.sum()),
                    rms,
                    prog_deg,
                )
            why = f"pelvis markers {names} fit the model's pelvis to {rms:.3f} m only"
    if prog is not None:
        return Heading(
            _about(u, prog) @ r0, "progression", prog_deg, (), 0, math.nan, prog_deg, why
        )
    why += "; progression < 0.3 m"
    return Heading(r0, "none", 0.0, (), 0, math.nan, prog_deg, why)


def up_from_ground_reactions(
    markers: ArrayLike, forces: Sequence[ArrayLike], cops: Sequence[ArrayLike]
) -> Array | None:
    """The lab's up axis of a marker file that does not state it (a TRC: OpenSim's ground is
    +y, but OpenSim's ``C3DFileAdapter`` writes a C3D lab's markers unrotated, often +z up),
    from the ground reactions recorded with it in the same frame: the axis of the largest RMS
    force (:func:`msk.io.grf.grf_vertical_axis`: a ground reaction is mostly vertical),
    pointing to the side of the loaded COPs' surface where the markers are (the median marker
    coordinate along it minus the median loaded COP coordinate: a subject stands on the
    plates). ``markers`` (N, M, 3), ``forces``/``cops`` (Na, 3) per plate, one frame and unit
    (m). ``None`` without a loaded COP (vertical force above 20 N) or a marker."""
    from msk.io.grf import grf_vertical_axis

    k = grf_vertical_axis([np.asarray(f, dtype=float) for f in forces])
    heights = []
    for f, c in zip(forces, cops):
        f, c = np.asarray(f, dtype=float), np.asarray(c, dtype=float)
        loaded = (np.abs(f[:, k]) > 20.0) & np.isfinite(c).all(axis=1)
        heights.append(c[loaded, k])
    surface = np.concatenate(heights) if heights else np.zeros(0)
    m = np.asarray(markers, dtype=float)[..., k]
    m = m[np.isfinite(m)]
    if surface.size == 0 or m.size == 0:
        return None
    up = np.zeros(3)
    up[k] = 1.0 if float(np.median(m) - np.median(surface)) >= 0.0 else -1.0
    return up


def rotate_plate(plate: ForcePlate, rotation: ArrayLike) -> ForcePlate:
    """A :class:`~msk.io.ForcePlate` in the rotated frame (:meth:`msk.trial.ForcePlate.rotated`):
    force, moment (about the rotated origin), COP, free moment, corners and origin rotated; the
    plate axes become ``R @ axes``."""
    return plate.rotated(rotation)


def rotate_trial(trial: Trial, rotation: ArrayLike) -> Trial:
    """``trial`` with everything that lives in the lab frame rotated by R (about the lab
    origin): markers, force plates (:func:`rotate_plate`) and ``up``; ``vertical_axis`` becomes
    the axis nearest the new up; model outputs are kept; ``metadata["lab_to_model_rotation"]``
    accumulates R (:meth:`msk.trial.Trial.rotated`)."""
    return trial.rotated(rotation)


def to_model_frame(
    trial: Trial,
    *,
    up: ArrayLike = (0.0, 1.0, 0.0),
    forward: ArrayLike | None = (1.0, 0.0, 0.0),
) -> Trial:
    """``trial`` rotated into a model frame whose vertical is ``up`` (−gravity; OpenSim: +y)
    and, when ``forward`` is given and the subject progresses more than 0.3 m, whose walking
    direction is ``forward`` (OpenSim: +x). The rotation is in
    ``metadata["lab_to_model_rotation"]``."""
    if forward is None:
        r = lab_to_model_rotation(trial.up, up)
    else:
        r = lab_to_model_rotation(trial.up, up, trial.markers, forward=forward)
    return rotate_trial(trial, r)
