"""The patellar mechanism for the tibiofemoral contact: the quadriceps reach the tibia only
through the patellar tendon.

Models such as gait2392 end their quadriceps on tibia-fixed (moving) points: the muscle's
tension F_Q then pulls the tibia along the quadriceps' own line, which in deep flexion runs
along the femur and so lands on the plateau as anterior shear. Anatomically the quadriceps pull
on the patella, which the femoral groove holds; the tibia receives the **patellar tendon** force
F_PT along the tendon, from the tibial tuberosity T towards the patella's apex.

**Tendon direction.** In the tibia frame (x anterior, y proximal along the long axis) ::

    e(φ) = (sin α(φ), cos α(φ), 0)

with α the sagittal angle between the tendon and the tibial long axis, positive when the
tendon runs anteriorly going proximally (it then pulls the tibia forward), as a function of the
knee flexion φ: van Eijden TMGJ, de Boer W, Weijs WA (1985) "The orientation of the distal
part of the quadriceps femoris muscle as a function of the knee flexion-extension angle",
J Biomech 18(10):803–809, Fig. 3 (α = +20.6° in extension, 0 near 75°, −17.3° at 120°;
:data:`VAN_EIJDEN_FLEXION_DEG`, :data:`VAN_EIJDEN_ANGLE_DEG`, linearly interpolated, held
constant outside 0–120°). φ is measured from the model, not from a coordinate convention: the
sagittal angle of the tibia's long axis in the femur frame, ``φ = atan2(y_t·x_f, y_t·y_f)``.

**Tendon insertion.** T is the patellar-ligament insertion of TLEM 2.0 (Carbone V et al. (2015)
J Biomech 48:734–741, Table A4) relative to its knee centre (Table A6), (42.3, −73.8, 13.0) mm
(right knee, +z lateral), times the tibia's scale factors (s_x, s_y, s_z) of
:func:`msk.personalise.scaling.scale_model`; z is mirrored for a left knee (+z medial in
gait2392's unmirrored frames).

**Tendon force (ratio ρ).** The patella is massless and its contact with the femur does no work
on the tibia, so the tendon applies to the tibia the same knee moment as the quadriceps it
replaces (virtual work over the knee coordinate θ; van Eijden TMGJ, Kouwenhoven E, Verburg J,
Weijs WA (1986) "A mathematical model of the patellofemoral joint", J Biomech 19(3):219–229,
whose ratio F_PT/F_Q is the quadriceps' effective moment arm over the tendon's)::

    F_PT,i = ρ_i F_i,     ρ_i = −(∂l_i/∂θ) / (e · v_T)

where ∂l_i/∂θ is muscle i's length Jacobian on the knee coordinate — the moment arm the muscle
forces were solved with, including gait2392's moving path points (whose own motion a rigid
unit wrench ∂l_i/∂ξ does not see: on gait2392 (∂l/∂ξ)·S is 67 mm at 0° and 46 mm at 90°
where ∂l/∂θ is 50 and 27 mm) — and e · v_T, with v_T = v_O + ω × T the velocity of T for the
knee's twist S (tibia relative to femur per unit θ̇), is the tendon's moment arm on θ. ρ
therefore carries the model's own quadriceps moment arm (the muscle forces still balance the
inverse-dynamics knee moment) and the published tendon geometry; it is clipped at 0 where the
two disagree in sign. On gait2392 it is 0.64–0.70 at 90° and 0.64–0.74 at 0°.

**Contact.** In the knee's free-body diagram (:mod:`msk.contact.knee`) each quadriceps' distal
unit wrench ∂l_i/∂ξ is replaced by the tendon's, ``−ρ_i (e, T × e)`` (world axes, moment about
the world origin: a tension F_i then pulls the tibia with F_i ρ_i e at T). Everything else
(inverse-dynamics wrench, other muscles, the two-point medial/lateral split, the compartment
rows of the tension QP) is unchanged, so ::

    W_contact = W_ID + Σ_{i ∉ Q} F_i ∂l_i/∂ξ − Σ_{i ∈ Q} F_i ρ_i (e, T × e).

**Patellofemoral contact.** The massless patella is held by three loads: the quadriceps'
tension along each muscle's line at the patella (unit u_i, pointing proximally: the model's own
path segment that ends on the tibia-fixed moving point riding with the patella), the tendon's
ρ_i F_i pulling distally along −e, and the femur's contact force F_PF. Their sum vanishes
(van Eijden et al. 1986, Eq. 1; Mason JJ et al. (2008) "Patellofemoral joint forces",
J Biomech 41(11):2337–2348)::

    F_PF = −Σ_{i ∈ Q} F_i (u_i − ρ_i e),

reported as its magnitude |F_PF| (:meth:`PatellarTendon.patellofemoral`). Its ratio to the
quadriceps force, |u − ρ e|, is small near extension, where the two pulls are nearly opposite,
and about 1 in deep flexion, where they are about perpendicular.
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from msk.exceptions import ModelError, ShapeMismatchError
from msk.model.core import Model, frame_placements
from msk.units import Array

__all__ = [
    "PATELLA_MODES",
    "QUADRICEPS_PREFIXES",
    "TUBEROSITY_M",
    "VAN_EIJDEN_ANGLE_DEG",
    "VAN_EIJDEN_FLEXION_DEG",
    "PatellarTendon",
    "patella_mode",
    "patellar_tendon",
    "tendon_angle_deg",
]

#: ``[contact] patella``: ``"none"`` (the model's quadriceps paths act on the tibia) or
#: ``"tendon"`` (the quadriceps reach the tibia through the patellar tendon)
PATELLA_MODES: tuple[str, ...] = ("none", "tendon")
PatellaMode = Literal["none", "tendon"]

#: knee flexion (deg) of van Eijden et al. (1985) Fig. 3
VAN_EIJDEN_FLEXION_DEG = np.arange(0.0, 121.0, 10.0)
#: patellar-tendon angle to the tibial long axis (deg, + anterior) at those flexions
VAN_EIJDEN_ANGLE_DEG = np.array(
    [20.62, 19.19, 15.88, 13.74, 11.61, 8.29, 4.98, 1.90, -1.90, -6.64, -9.72, -13.74, -17.30]
)
#: patellar-ligament insertion (tibial tuberosity) relative to the knee centre, right knee,
#: tibia axes x anterior, y proximal, z lateral (m): TLEM 2.0 Tables A4 and A6
TUBEROSITY_M = (0.0423, -0.0738, 0.0130)
#: name prefixes of the quadriceps (gait2392, Rajagopal 2016 and their variants)
QUADRICEPS_PREFIXES: tuple[str, ...] = (
    "rect_fem",
    "vas_med",
    "vas_int",
    "vas_lat",
    "recfem",
    "vasmed",
    "vasint",
    "vaslat",
)


def patella_mode(model: Model, joint: str, configured: str) -> str:
    """The mode the knee ``joint``'s contact uses: ``configured``, but ``"tendon"`` when a
    quadriceps of that side passes over a body that is neither on the tibia side nor on the
    chain from the root to the femur (Rajagopal et al. 2016's patella: a child of the femur
    whose motion a coupled coordinate ties to the knee's). Such a body moves with the knee but
    not with a rigid displacement of the tibia side, so the tibia's free-body diagram misses
    the part of the quadriceps' knee moment the coupling carries (by virtual work, the length
    Jacobian ∂l/∂θ is then not S · ∂l/∂ξ); the tendon restores it (ρ from ∂l/∂θ, module
    docstring)."""
    if configured == "tendon":
        return configured
    spec = next((j for j in model.joints if j.name == joint), None)
    if spec is None:
        return configured
    parent_of = {j.child: j.parent for j in model.joints}
    chain = set(model.subtree(spec.child))
    body: str | None = spec.parent
    while body is not None:
        chain.add(body)
        body = parent_of.get(body)
    side = joint[-2:]
    for m in model.muscles:
        nm = m.name.lower()
        if nm.startswith(QUADRICEPS_PREFIXES) and nm.endswith(side):
            if any(pt.body not in chain for pt in m.points):
                return "tendon"
    return configured


def tendon_angle_deg(flexion_deg: ArrayLike) -> Array:
    """α(φ): the patellar tendon's sagittal angle to the tibial axis (deg, + anterior) at knee
    flexion φ (deg), van Eijden et al. (1985) Fig. 3, linear between its 10° samples, held
    constant outside 0–120°."""
    return np.interp(np.asarray(flexion_deg, dtype=float), VAN_EIJDEN_FLEXION_DEG,
                     VAN_EIJDEN_ANGLE_DEG)  # fmt: skip


@dataclass(frozen=True, eq=False)
class PatellarTendon:
    """The patellar tendon of one knee of one model (module docstring).

    Attributes:
        joint: the knee joint; ``coordinate`` its independent coordinate θ.
        muscles: model indices of the quadriceps that act through the tendon.
        muscle_names: their names.
        insertion_m: T, the tendon's tibial insertion in the tibia frame (m).
        grid: (G,) knee-coordinate values the knee's motion is tabulated on.
        flexion_deg: (G,) knee flexion φ at those values (deg).
        twist: (G, 6) the tibia's motion relative to the femur per unit θ̇, tibia axes:
            velocity of the tibia-frame origin (m), then angular velocity (rad).
    """

    joint: str
    coordinate: str
    muscles: tuple[int, ...]
    muscle_names: tuple[str, ...]
    insertion_m: Array
    grid: Array
    flexion_deg: Array
    twist: Array

    def at(self, theta: ArrayLike) -> tuple[Array, Array, Array]:
        """Flexion φ (N,) deg, tendon direction e (N, 3) and knee twist S (N, 6), both in
        tibia axes, at knee-coordinate values ``theta`` (N,)."""
        th = np.asarray(theta, dtype=float)
        phi, e = self._direction(th)
        s = np.stack([np.interp(th, self.grid, self.twist[:, c]) for c in range(6)], axis=-1)
        return phi, e, s

    def _direction(self, th: Array) -> tuple[Array, Array]:
        """φ (N,) deg and e (N, 3) tibia axes at knee-coordinate values ``th``."""
        phi = np.interp(th, self.grid, self.flexion_deg)
        a = np.radians(tendon_angle_deg(phi))
        return phi, np.stack([np.sin(a), np.cos(a), np.zeros_like(a)], axis=-1)

    @cached_property
    def _insertion_velocity(self) -> Array:
        """(G, 3) v_T = v_O + ω × T on the grid, tibia axes (linear in S: its interpolation is
        that of S, to round-off)."""
        return self.twist[:, :3] + np.cross(self.twist[:, 3:], self.insertion_m)

    def line(self, theta: ArrayLike) -> tuple[Array, Array]:
        """The tendon direction e (N, 3; tibia axes) and its moment arm e · v_T (N,) (m per
        rad) at knee-coordinate values ``theta`` (N,): one evaluation for :meth:`ratio`,
        :meth:`substitute` and :meth:`patellofemoral` (their ``tendon`` argument)."""
        th = np.asarray(theta, dtype=float)
        _, e = self._direction(th)
        vt = self._insertion_velocity
        v_t = np.stack([np.interp(th, self.grid, vt[:, c]) for c in range(3)], axis=-1)
        return e, np.einsum("nc,nc->n", e, v_t)

    def moment_arm(self, theta: ArrayLike) -> Array:
        """(N,) the tendon's moment arm on the knee coordinate, e · v_T (m per rad)."""
        return self.line(theta)[1]

    def ratio(self, theta: ArrayLike, length_jacobian: ArrayLike,
              tendon: tuple[Array, Array] | None = None) -> Array:  # fmt: skip
        """ρ (N, K) = −(∂l/∂θ)/(e · v_T) for the quadriceps' length Jacobian on the knee
        coordinate ``length_jacobian`` (N, K), clipped at 0 (``tendon``: :meth:`line` at
        ``theta``, when already evaluated)."""
        _, arm = self.line(theta) if tendon is None else tendon
        dl = np.asarray(length_jacobian, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            rho = -dl / arm[:, None]
        return np.where(np.isfinite(rho), np.maximum(rho, 0.0), 0.0)

    def unit_wrench(self, e: Array, rot: ArrayLike, origin: ArrayLike) -> Array:
        """(N, 6) the tendon's unit wrench ``(e, T × e)`` (world axes, moment about the world
        origin) for tibia-axes directions ``e`` (N, 3) and tibia placements ``rot`` (N, 3, 3),
        ``origin`` (N, 3)."""
        r = np.asarray(rot, dtype=float)
        e_w = np.einsum("nij,nj->ni", r, e)
        t_w = np.asarray(origin, dtype=float) + np.einsum("nij,j->ni", r, self.insertion_m)
        return np.concatenate([e_w, np.cross(t_w, e_w)], axis=-1)

    def substitute(self, theta: ArrayLike, distal_wrenches: ArrayLike, rot: ArrayLike,
                   origin: ArrayLike, length_jacobian: ArrayLike) -> Array:  # fmt: skip
        """The distal unit wrenches (N, K, 6; world axes, moment about the world origin) with
        each quadriceps' row replaced by its tendon's ``−ρ_i (e, T × e)``, for tibia
        placements ``rot`` (N, 3, 3) and ``origin`` (N, 3), knee coordinate ``theta`` (N,)
        and the quadriceps' length Jacobian on it ``length_jacobian`` (N, len(muscles)).
        Rows of other muscles are returned unchanged."""
        w = np.array(distal_wrenches, dtype=float, copy=True)
        r = np.asarray(rot, dtype=float)
        p = np.asarray(origin, dtype=float)
        n = w.shape[0]
        if w.ndim != 3 or w.shape[2] != 6 or r.shape != (n, 3, 3) or p.shape != (n, 3):
            raise ShapeMismatchError(
                f"distal wrenches {w.shape}, rotations {r.shape}, origins {p.shape} do not "
                "match (N, K, 6), (N, 3, 3), (N, 3)"
            )
        if not self.muscles or not n:
            return w
        q = list(self.muscles)
        tendon = self.line(theta)
        rho = self.ratio(theta, length_jacobian, tendon)
        unit = self.unit_wrench(tendon[0], r, p)  # (N, 6)
        w[:, q, :] = -rho[..., None] * unit[:, None, :]
        return w

    def patellofemoral(self, theta: ArrayLike, quadriceps_lines: ArrayLike, rot: ArrayLike,
                       length_jacobian: ArrayLike, forces: ArrayLike,
                       tendon: tuple[Array, Array] | None = None,
                       rho: Array | None = None) -> Array:  # fmt: skip
        """F_PF (N, 3): the femur's force on the patella, world axes (module docstring),
        ``−Σ F_i (u_i − ρ_i e)``, for knee coordinate ``theta`` (N,), the quadriceps' lines
        at the patella ``quadriceps_lines`` (N, K, 3; the pull of a unit tension on the
        patella, normalised here), tibia rotations ``rot`` (N, 3, 3), their length Jacobian on
        the knee coordinate (N, K) and tensions ``forces`` (N, K) in N. A line of zero length
        (a muscle that does not reach the tibia) counts as no pull. ``tendon`` (:meth:`line`)
        and ``rho`` (:meth:`ratio`) at ``theta``, when already evaluated."""
        u = np.asarray(quadriceps_lines, dtype=float)
        f = np.asarray(forces, dtype=float)
        r = np.asarray(rot, dtype=float)
        n = u.shape[0]
        if u.ndim != 3 or u.shape[2] != 3 or f.shape != u.shape[:2] or r.shape != (n, 3, 3):
            raise ShapeMismatchError(
                f"quadriceps lines {u.shape}, forces {f.shape}, rotations {r.shape} do not "
                "match (N, K, 3), (N, K), (N, 3, 3)"
            )
        norm = np.linalg.norm(u, axis=2, keepdims=True)
        u = np.divide(u, norm, out=np.zeros_like(u), where=norm > 0)
        if tendon is None:
            tendon = self.line(theta)
        if rho is None:
            rho = self.ratio(theta, length_jacobian, tendon)
        e_w = np.einsum("nij,nj->ni", r, tendon[0])
        pull = u - rho[..., None] * e_w[:, None, :]
        return -np.einsum("nk,nkc->nc", f, pull)


_CACHE: weakref.WeakKeyDictionary[Model, dict[tuple[str, tuple[str, ...] | None], PatellarTendon]]
_CACHE = weakref.WeakKeyDictionary()


def patellar_tendon(
    model: Model,
    *,
    joint: str = "knee_r",
    muscles: Sequence[str] | None = None,
    step_rad: float = np.radians(0.5),
) -> PatellarTendon:
    """The :class:`PatellarTendon` of ``joint`` (cached per model).

    ``muscles``: the quadriceps by name (default: the model's muscles named with a
    :data:`QUADRICEPS_PREFIXES` prefix). The knee's motion relative to the femur is tabulated
    over the knee coordinate's range (default coordinates elsewhere) every ``step_rad`` and
    differentiated by central differences; T is :data:`TUBEROSITY_M` scaled by the tibia's
    scale factors, z mirrored on a left knee (joint name ending ``_l``).
    """
    key = (joint, None if muscles is None else tuple(muscles))
    hit = _CACHE.setdefault(model, {}).get(key)
    if hit is not None:
        return hit
    spec = next((j for j in model.joints if j.name == joint), None)
    if spec is None:
        raise ModelError(f"model {model.name}: no joint {joint!r}")
    coords = [ax.coordinate for ax in spec.axes if ax.coordinate is not None]
    if not coords or len(set(coords)) != 1:
        raise ModelError(
            f"model {model.name}: joint {joint!r} must be driven by one coordinate for the "
            f"patellar tendon, has {sorted(set(coords))}"
        )
    coord = coords[0]
    names = tuple(m.name for m in model.muscles)
    if muscles is None:
        picked = [i for i, nm in enumerate(names) if nm.lower().startswith(QUADRICEPS_PREFIXES)]
        picked = [i for i in picked if names[i].lower().endswith(joint[-2:])] or picked
    else:
        missing = [m for m in muscles if m not in names]
        if missing:
            raise ModelError(f"model {model.name}: no muscle(s) {missing} for the patellar tendon")
        picked = [names.index(m) for m in muscles]
    ci = model.coordinate_index(coord)
    lo, hi = model.coordinate_bounds()
    a, b = float(lo[ci]), float(hi[ci])
    if not (np.isfinite(a) and np.isfinite(b) and b > a):
        a, b = -np.pi * 0.9, np.pi * 0.9
    grid = np.arange(a, b + step_rad, step_rad)
    th = np.tile(model.default_coordinates(), (grid.size, 1))
    th[:, ci] = grid
    frames = [model.body_frame[spec.parent], model.body_frame[spec.child]]
    rot, pos = frame_placements(model, th, frames)
    r_rel = np.einsum("nji,njk->nik", rot[:, 0], rot[:, 1])  # femur → tibia
    p_rel = np.einsum("nji,nj->ni", rot[:, 0], pos[:, 1] - pos[:, 0])
    dp = np.gradient(p_rel, grid, axis=0)
    v_o = np.einsum("nji,nj->ni", r_rel, dp)  # tibia axes
    # ω from the rotation between neighbours (exact for a fixed axis): log(R_a^T R_b)/Δθ
    lo_i = np.maximum(np.arange(grid.size) - 1, 0)
    hi_i = np.minimum(np.arange(grid.size) + 1, grid.size - 1)
    omega = np.array(
        [pin.log3(r_rel[a].T @ r_rel[b]) / (grid[b] - grid[a]) for a, b in zip(lo_i, hi_i)]
    )
    # in the tibia axes at the middle sample: R_a^T R_b is in R_a's axes; rotate by half a step
    omega = np.einsum("nji,nj->ni", np.einsum("nji,njk->nik", r_rel, r_rel[lo_i]), omega)
    y_t = r_rel[:, :, 1]  # tibia long axis in femur axes
    flex = np.degrees(np.arctan2(y_t[:, 0], y_t[:, 1]))
    factors = (model.metadata.get("scale_factors") or {}).get(spec.child)
    sf = np.ones(3) if factors is None else np.broadcast_to(np.asarray(factors, float), 3)
    ins = np.asarray(TUBEROSITY_M, dtype=float) * sf
    if joint.lower().endswith(("_l", "_left")):
        ins[2] = -ins[2]
    out = PatellarTendon(
        joint=joint, coordinate=coord, muscles=tuple(picked),
        muscle_names=tuple(names[i] for i in picked), insertion_m=ins, grid=grid,
        flexion_deg=flex, twist=np.concatenate([v_o, omega], axis=1),
    )  # fmt: skip
    _CACHE[model][key] = out
    return out
