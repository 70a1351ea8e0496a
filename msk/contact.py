"""Tibiofemoral (knee) contact force from the tibia free-body diagram (seed 004 §2.1).

The tibia side of the knee (the tibia and every body distal to it) is cut free at the knee. The
wrench the femur side transmits to it through the joint, from inverse dynamics, is
(:func:`msk.dynamics.joint_reaction`, RNEA's ``data.f`` of the knee)::

    W_ID = W_contact + Σ_i W_i

where W_i is the wrench muscle i applies to the distal side (non-zero only for muscles that
cross the knee) and W_contact the remaining bone-on-bone load (articular contact plus whatever
ligaments would carry: msk has no ligaments, so all of it is "contact"). A muscle–tendon tension
F_i ≥ 0 does virtual work δW = −F_i δl_i, so for a rigid virtual displacement ξ = (δp_O, δφ) of
the whole distal side (a world twist about the world origin) ::

    W_i = −F_i ∂l_i/∂ξ,    W_contact = W_ID + Σ_i F_i ∂l_i/∂ξ

``∂l_i/∂ξ`` (a unit wrench: the sum, over the segment ends on distal bodies, of (u, x × u)) is
taken from the path geometry of :mod:`msk.muscles.geometry` (via points, conditional and moving
points, wrapping cylinders, all as the muscle lengths and Jacobians use them): it is the length
Jacobian for a virtual six-DOF joint at the knee. Muscles entirely on one side contribute
nothing; a muscle crossing the knee pulls the distal side along its crossing segment(s).

**Tibial plateau frame.** The contact force is expressed in the frame of the knee's child body
(the tibia: ``tibia_r``/``tibia_l`` in gait2392; origin at the knee, OpenSim axes x anterior,
y proximal along the tibia long axis, z to the right), optionally moved by ``plateau_offset``.
Its **normal is the tibia long axis** (the frame's +y): the femur presses on the plateau along
−y, so the compressive normal force is ``normal = −F_y`` (positive in compression); the
tangential (shear) components are the anterior ``F_x`` and lateral/right ``F_z``; the moment is
about the frame origin. This is the force the **femur exerts on the tibia** (OpenSim
JointReaction "on child"). An instrumented prosthesis such as the eTibia measures a force along
the same line (its load cells sit under the plateau), which is what ``total`` compares with.

Without muscle forces the result is the inverse-dynamics joint reaction itself (no
double counting), and in a static pose with one muscle it is minus the weight of the distal
side minus the muscle pull, which the tests check by hand.

**Medial and lateral compartments (two-point model).** :func:`split_medial_lateral` divides
the normal force between a medial and a lateral contact point, after Winby CR, Lloyd DG,
Besier TF, Kirk TB (2009) J Biomech 42:2294–2300 and Lerner ZF, DeMers MS, Delp SL,
Browning RC (2015) J Biomech 48:644–650. The contact points P_M and P_L lie on the plateau
(plateau-frame z axis through their midpoint C), a distance d apart (the intercondylar
distance)::

    P_L, P_M = C ± (d/2) e_z        (right knee: +z lateral; LEFT knee: +z is MEDIAL)

Each carries a compressive force F_M, F_L along −y (the femur pushes the tibia down); the
tangential load is carried at the same level and so has no frontal-plane moment about C. With
the load (F, M_O) about the plateau-frame origin O, the moment about C is
``M_C = M_O − c × F`` (c = C − O); its frontal-plane (about the anterior x axis) component ::

    M_C,x = M_O,x − c_y F_z + c_z F_y = M_O,x + h F_z − c_z N,   h = −c_y (plateau depth)

is the shear × height transfer from the knee-centre level to the plateau. Force balance
along the normal and frontal moment balance about C give (right knee; N = −F_y)::

    F_M + F_L = N,       (d/2) (F_L − F_M) = M_C,x
    F_L = N/2 + M_C,x/d,   F_M = N/2 − M_C,x/d

which is Winby's form: each compartment force is the frontal moment about the *other*
contact point divided by d, ``F_M = −M^{P_L}_x / d``, ``F_L = M^{P_M}_x / d`` with
``M^{P}_x = M_C,x − ((P − C) × F)_x``. For the left knee the roles of ±z swap
(F_M = N/2 + M_C,x/d). A negative compartment force is condylar lift-off that the two-point
model (without ligaments) cannot carry; it is reported, not clipped.

Geometry (:func:`plateau_geometry`): d defaults to 40 mm (the generic intercondylar
distance of the two-point models of Winby et al. 2009 and Lerner et al. 2015) times the
tibia's medio-lateral scale factor (``model.metadata["scale_factors"][tibia][2]`` after
:func:`msk.scaling.scale_model`); C lies 22 mm below the tibia-frame origin (the top of the
gait2392/Rajagopal tibial-plateau mesh, 18–25 mm below the origin) times the tibia's
longitudinal scale factor. Both can be given explicitly (e.g. from imaging); they are never
fitted to measured forces. For instance the subject-specific contact points that
fmoissenet/MSK_Delp_U_Ankle ships for Grand Challenge subject DM (``p_DM.mat``: cubic
polynomials, constant terms) lie at z = ±18.6 mm (d ≈ 37.2 mm) and 33–34 mm below its knee
centre.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from msk.dynamics import Variant, joint_reaction
from msk.exceptions import ModelError, ShapeMismatchError
from msk.model import Model
from msk.muscles.geometry import GeometryPlan, geometry_plan

Array = NDArray[np.float64]

__all__ = [
    "CONTACT_COLUMNS",
    "G0",
    "INTERCONDYLAR_DISTANCE_M",
    "PLATEAU_DEPTH_M",
    "KneeContact",
    "MedialLateral",
    "PlateauGeometry",
    "knee_contact_force",
    "muscle_distal_wrenches",
    "plateau_geometry",
    "split_medial_lateral",
]

#: standard gravity used to express forces in body weights (BW = m g)
G0 = 9.80665

#: columns of :attr:`KneeContact.values` (N, plateau frame; ``normal`` positive compressive)
CONTACT_COLUMNS: tuple[str, ...] = (
    "normal_n",
    "shear_anterior_n",
    "shear_lateral_n",
    "tangential_n",
    "total_n",
)


@dataclass(frozen=True)
class KneeContact:
    """Tibiofemoral contact load over a trial (time on axis 0, SI, tibial plateau frame).

    Attributes:
        time: (N,) s.
        joint: the knee joint (e.g. ``"knee_l"``); ``body`` its child body (the tibia).
        force: (N, 3) force the femur exerts on the tibia, plateau-frame axes (x anterior,
            y proximal = plateau normal, z right in OpenSim's gait2392).
        moment: (N, 3) moment of that load about the plateau-frame origin, N·m.
        values: (N, 5) columns :data:`CONTACT_COLUMNS`: compressive normal ``−F_y``, shear
            ``F_x`` and ``F_z``, tangential ``√(F_x² + F_z²)`` and total ``|F|`` (N).
        body_weight_n: m g used by :meth:`in_body_weights` (N).
        muscles_included: the muscle forces were subtracted (False: the ID joint reaction).
    """

    time: Array
    joint: str
    body: str
    force: Array
    moment: Array
    values: Array
    body_weight_n: float
    muscles_included: bool
    columns: tuple[str, ...] = CONTACT_COLUMNS
    metadata: dict[str, Any] = field(default_factory=dict)

    def column(self, name: str) -> Array:
        """One column of :attr:`values` by name (e.g. ``"total_n"``)."""
        try:
            return self.values[:, self.columns.index(name)]
        except ValueError:
            raise ModelError(f"knee contact has no column {name!r}; has {self.columns}") from None

    @property
    def normal(self) -> Array:
        """(N,) compressive force along the plateau normal (N)."""
        return self.values[:, 0]

    @property
    def tangential(self) -> Array:
        """(N,) shear magnitude in the plateau plane (N)."""
        return self.values[:, 3]

    @property
    def total(self) -> Array:
        """(N,) contact force magnitude (N)."""
        return self.values[:, 4]

    def in_body_weights(self) -> Array:
        """:attr:`values` divided by the body weight (columns ``*_bw``)."""
        return self.values / self.body_weight_n

    @property
    def total_bw(self) -> Array:
        """(N,) total contact force in body weights."""
        return self.total / self.body_weight_n


def _chain_dofs(model: Model, joint: str) -> tuple[list[int], str]:
    """Pinocchio velocity indices of the axes of ``joint`` (first first) and its child body."""
    spec = next((j for j in model.joints if j.name == joint), None)
    if spec is None:
        raise ModelError(f"model {model.name}: no joint {joint!r}")
    if not spec.axes:
        raise ModelError(f"model {model.name}: joint {joint!r} is a weld (no axis to cut at)")
    names = [joint] if len(spec.axes) == 1 else [f"{joint}_{k}" for k in range(len(spec.axes))]
    pm = model.pin_model
    out = []
    for name in names:
        jid = pm.getJointId(name)
        if jid >= pm.njoints:
            raise ModelError(f"model {model.name}: no Pinocchio joint {name!r} for {joint!r}")
        out.append(int(pm.joints[jid].idx_v))
    return out, spec.child


def muscle_distal_wrenches(
    model: Model, q: ArrayLike, *, joint: str, plan: GeometryPlan | None = None
) -> Array:
    """∂l_i/∂ξ for a rigid world twist ξ of everything distal to ``joint``: (N, n_muscles, 6),
    columns (force x, y, z, moment x, y, z about the world origin), world axes.

    A tension F_i applies the wrench ``−F_i ∂l_i/∂ξ`` to the distal side (module docstring).
    Computed by the path geometry of :mod:`msk.muscles.geometry` with, in place of the
    Pinocchio joint Jacobian, unit twists on the DOFs of ``joint`` (the axes of a coupled
    knee all carry the same distal bodies, so a 3-axis knee needs two stacked evaluations, a
    1-axis one six): the length derivative of every path-segment end on a body these DOFs
    support, which is exactly what the length Jacobian sums.
    """
    th = np.asarray(q, dtype=float)
    if th.ndim != 2 or th.shape[1] != model.n_coords:
        raise ShapeMismatchError(f"q has shape {th.shape}, expected (N, {model.n_coords})")
    plan = plan if plan is not None else geometry_plan(model)
    if plan.model is not model:
        raise ModelError(f"geometry plan was built for model {plan.model.name!r}, not this one")
    dofs, _ = _chain_dofs(model, joint)
    # chain axes whose support pattern over the muscle-carrying bodies equals the first one's
    sup = np.asarray(plan.support)
    cols = [iv for iv in dofs if np.array_equal(sup[:, iv], sup[:, dofs[0]])]
    n = th.shape[0]
    out = np.full((n, plan.n_muscles, 6), np.nan)
    good = np.isfinite(th).all(axis=1)
    if not good.any():
        return out
    tg = th[good]
    k = tg.shape[0]
    jac, rot, trans, _ = plan.kinematics(tg)
    groups = [list(range(c, min(c + len(cols), 6))) for c in range(0, 6, len(cols))]
    reps = len(groups)
    fake = np.zeros((reps * k, *jac.shape[1:]))
    for r, comps in enumerate(groups):
        for col, comp in zip(cols, comps):
            fake[r * k : (r + 1) * k, comp, col] = 1.0
    tile = (reps,) + (1,) * (rot.ndim - 1)
    # the path evaluation of the geometry plan: (lengths, ∂l/∂q_pin, ∂l/∂θ of moving points)
    _, dl_dq, _ = plan._paths(
        np.tile(tg, (reps, 1)), fake, np.tile(rot, tile), np.tile(trans, (reps, 1, 1))
    )
    w = np.empty((k, plan.n_muscles, 6))
    for r, comps in enumerate(groups):
        for col, comp in zip(cols, comps):
            w[:, :, comp] = dl_dq[r * k : (r + 1) * k, :, col]
    out[good] = w
    return out


def _forces_in_model_order(
    model: Model, muscle_forces: Any, muscle_names: Sequence[str] | None, n: int
) -> Array:
    names = tuple(m.name for m in model.muscles)
    if hasattr(muscle_forces, "forces") and hasattr(muscle_forces, "muscle_names"):
        muscle_names = tuple(muscle_forces.muscle_names)
        muscle_forces = muscle_forces.forces
    f = np.asarray(muscle_forces, dtype=float)
    if f.ndim != 2 or f.shape[0] != n:
        raise ShapeMismatchError(f"muscle forces {f.shape} must be (frames {n}, muscles)")
    if muscle_names is None:
        if f.shape[1] != len(names):
            raise ShapeMismatchError(
                f"muscle forces have {f.shape[1]} columns, model {model.name} has "
                f"{len(names)} muscles (give muscle_names)"
            )
        return f
    muscle_names = tuple(muscle_names)
    if len(muscle_names) != f.shape[1]:
        raise ShapeMismatchError(
            f"{len(muscle_names)} muscle names for {f.shape[1]} muscle-force columns"
        )
    out = np.zeros((n, len(names)))
    for c, name in enumerate(muscle_names):
        if name not in names:
            raise ModelError(f"model {model.name}: no muscle {name!r} (muscle forces column {c})")
        out[:, names.index(name)] = f[:, c]
    return out


def knee_contact_force(
    model: Model,
    kinematics: Any,
    loads: Any = None,
    *,
    muscle_forces: Any = None,
    muscle_names: Sequence[str] | None = None,
    joint: str = "knee_r",
    plateau_offset: pin.SE3 | None = None,
    body_mass_kg: float | None = None,
    variant: Variant = "full",
    plan: GeometryPlan | None = None,
) -> KneeContact:
    """Tibiofemoral contact force per frame (see the module docstring, seed 004 §2.1).

    Args:
        model: the model (its muscles give the paths).
        kinematics: :class:`msk.kinematics.Kinematics` (``time``, ``q``, ``v``, ``a``, names).
        loads: :class:`msk.loads.ExternalLoads` on the same time, or ``None``.
        muscle_forces: tensions (N, K) ≥ 0 in N, or a solution with ``forces`` and
            ``muscle_names`` (e.g. :class:`msk.optimization.BatchSolution`); columns named by
            ``muscle_names`` (absent model muscles count as 0), default model order. ``None``:
            no muscles (the inverse-dynamics joint reaction).
        joint: the knee joint; its child body is the tibia (plateau frame).
        plateau_offset: placement of the plateau frame in the tibia frame (default identity).
        body_mass_kg: body mass for the BW columns (default: the model's total mass).
        variant: inverse-dynamics variant (``"full"``, ``"quasi_static"``, ``"geometric"``).
        plan: a geometry plan of ``model`` (default: the cached one).

    Returns:
        :class:`KneeContact`; frames whose kinematics are NaN are NaN.
    """
    spec = next((j for j in model.joints if j.name == joint), None)
    if spec is None:
        raise ModelError(f"model {model.name}: no joint {joint!r}")
    th = np.asarray(kinematics.q, dtype=float)
    n = th.shape[0]
    # ID wrench transmitted femur → distal side, world axes, moment about the world origin
    jr = joint_reaction(model, kinematics, loads, joint=joint, frame="world", variant=variant)
    force_w = np.array(jr.force, dtype=float)
    moment_w = np.array(jr.moment, dtype=float)
    with_muscles = muscle_forces is not None
    if with_muscles:
        f = _forces_in_model_order(model, muscle_forces, muscle_names, n)
        w = muscle_distal_wrenches(model, th, joint=joint, plan=plan)
        add = np.einsum("nm,nmc->nc", np.nan_to_num(f), w)
        add[~np.isfinite(f).all(axis=1)] = np.nan
        force_w += add[:, :3]
        moment_w += add[:, 3:]
    # plateau frame: the tibia body frame (child of the knee), optionally offset
    body = spec.child
    data = model.create_data()
    fid = model.body_frame[body]
    place = np.full((n, 4, 4), np.nan)
    qpin = model.coupling.q(np.where(np.isfinite(th), th, 0.0))
    for k in np.flatnonzero(np.isfinite(th).all(axis=1)):
        pin.framesForwardKinematics(model.pin_model, data, qpin[k])
        oMp = data.oMf[fid] if plateau_offset is None else data.oMf[fid] * plateau_offset
        place[k] = oMp.homogeneous
    rot = place[:, :3, :3]
    origin = place[:, :3, 3]
    m_o = moment_w - np.cross(origin, force_w)
    force = np.einsum("nji,nj->ni", rot, force_w)
    moment = np.einsum("nji,nj->ni", rot, m_o)
    tang = np.hypot(force[:, 0], force[:, 2])
    values = np.stack(
        [-force[:, 1], force[:, 0], force[:, 2], tang, np.linalg.norm(force, axis=1)], axis=1
    )
    mass = float(model.total_mass if body_mass_kg is None else body_mass_kg)
    if not (np.isfinite(mass) and mass > 0):
        raise ModelError(f"knee contact: body mass must be > 0 kg, got {mass!r}")
    return KneeContact(
        time=np.asarray(kinematics.time, dtype=float),
        joint=joint,
        body=body,
        force=force,
        moment=moment,
        values=values,
        body_weight_n=mass * G0,
        muscles_included=with_muscles,
        metadata={"variant": variant, "plateau_offset": plateau_offset is not None},
    )


# ---------------------------------------------------------------------------------------------
# medial / lateral split (two-point model, Winby et al. 2009; Lerner et al. 2015)
# ---------------------------------------------------------------------------------------------
#: generic intercondylar distance d between the medial and lateral contact points (m), as in
#: the two-point knee models of Winby et al. (2009) and Lerner et al. (2015)
INTERCONDYLAR_DISTANCE_M = 0.040
#: depth of the tibial plateau below the tibia-frame origin of gait2392 / Rajagopal (m): the
#: top of their tibia mesh lies 18–25 mm below the origin (the knee centre)
PLATEAU_DEPTH_M = 0.022

Side = Literal["right", "left"]


@dataclass(frozen=True)
class PlateauGeometry:
    """Medial/lateral contact points in the plateau frame of a :class:`KneeContact`.

    Attributes:
        intercondylar_distance_m: d, distance between the two contact points along the
            plateau's medio-lateral (z) axis (m, > 0).
        centre_m: C, midpoint of the two contact points in the plateau frame (m); its y is
            minus the plateau depth below the frame origin.
        source: how the values were obtained (generic, scaled, given).
    """

    intercondylar_distance_m: float = INTERCONDYLAR_DISTANCE_M
    centre_m: tuple[float, float, float] = (0.0, -PLATEAU_DEPTH_M, 0.0)
    source: str = "generic"

    def __post_init__(self) -> None:
        d = float(self.intercondylar_distance_m)
        if not (np.isfinite(d) and d > 0):
            raise ModelError(f"intercondylar distance must be > 0 m, got {d!r}")
        c = np.asarray(self.centre_m, dtype=float).reshape(-1)
        if c.size != 3 or not np.isfinite(c).all():
            raise ModelError(
                f"contact-point centre must be 3 finite numbers, got {self.centre_m!r}"
            )
        object.__setattr__(self, "intercondylar_distance_m", d)
        object.__setattr__(self, "centre_m", (float(c[0]), float(c[1]), float(c[2])))


def plateau_geometry(
    model: Model,
    *,
    joint: str = "knee_r",
    intercondylar_distance_m: float | None = None,
    centre_m: ArrayLike | None = None,
) -> PlateauGeometry:
    """Contact-point geometry for ``joint`` of a (scaled) model.

    Defaults: d = :data:`INTERCONDYLAR_DISTANCE_M` × s_z and C = (0, −:data:`PLATEAU_DEPTH_M`
    × s_y, 0), with (s_x, s_y, s_z) the scale factors of the knee's child body (the tibia) in
    ``model.metadata["scale_factors"]`` (written by :func:`msk.scaling.scale_model`; 1 for an
    unscaled model). Values given explicitly are used as they are (not scaled).
    """
    spec = next((j for j in model.joints if j.name == joint), None)
    if spec is None:
        raise ModelError(f"model {model.name}: no joint {joint!r}")
    factors = (model.metadata.get("scale_factors") or {}).get(spec.child)
    sf = np.ones(3) if factors is None else np.asarray(factors, dtype=float).reshape(-1)
    if sf.size == 1:
        sf = np.full(3, sf[0])
    if sf.size != 3 or not (np.isfinite(sf).all() and (sf > 0).all()):
        raise ModelError(f"model {model.name}: bad scale factors {factors!r} for {spec.child}")
    scaled = factors is not None
    parts = []
    if intercondylar_distance_m is None:
        d = INTERCONDYLAR_DISTANCE_M * sf[2]
        parts.append(
            f"d = {INTERCONDYLAR_DISTANCE_M * 1e3:g} mm" + (f" × {sf[2]:.4g}" if scaled else "")
        )
    else:
        d = float(intercondylar_distance_m)
        parts.append("d given")
    if centre_m is None:
        c = (0.0, -PLATEAU_DEPTH_M * sf[1], 0.0)
        parts.append(f"depth {PLATEAU_DEPTH_M * 1e3:g} mm" + (f" × {sf[1]:.4g}" if scaled else ""))
    else:
        v = np.asarray(centre_m, dtype=float).reshape(-1)
        if v.size != 3:
            raise ModelError(f"contact-point centre must be 3 numbers, got {centre_m!r}")
        c = (float(v[0]), float(v[1]), float(v[2]))
        parts.append("centre given")
    return PlateauGeometry(d, c, f"{spec.child}: " + ", ".join(parts))


@dataclass(frozen=True)
class MedialLateral:
    """Medial and lateral tibiofemoral contact forces over a trial (N, compressive > 0).

    Attributes:
        time: (N,) s.
        joint: the knee joint; ``side`` ``"right"`` or ``"left"``.
        medial, lateral: (N,) compartment forces F_M, F_L (N); F_M + F_L = ``normal``.
        normal: (N,) total compressive normal force N (N).
        frontal_moment: (N,) M_C,x, frontal-plane moment of the contact load about the
            midpoint C of the contact points, about the plateau's anterior (x) axis (N·m).
        geometry: the contact points used.
        body_weight_n: m g for :meth:`in_body_weights` (N).
    """

    time: Array
    joint: str
    side: Side
    medial: Array
    lateral: Array
    normal: Array
    frontal_moment: Array
    geometry: PlateauGeometry
    body_weight_n: float
    columns: tuple[str, ...] = ("medial_n", "lateral_n")

    @property
    def values(self) -> Array:
        """(N, 2) columns :attr:`columns` (medial, lateral) in N."""
        return np.stack([self.medial, self.lateral], axis=1)

    def in_body_weights(self) -> Array:
        """(N, 2) medial and lateral forces in body weights."""
        return self.values / self.body_weight_n


def _side_of(joint: str, side: str | None) -> Side:
    if side is None:
        low = joint.lower()
        if low.endswith(("_r", "_right")):
            return "right"
        if low.endswith(("_l", "_left")):
            return "left"
        raise ModelError(f"knee joint {joint!r}: cannot tell the side from its name; give side=")
    s = side.lower()
    if s in ("right", "r"):
        return "right"
    if s in ("left", "l"):
        return "left"
    raise ModelError(f"side must be 'right' or 'left', got {side!r}")


def split_medial_lateral(
    contact: KneeContact,
    geometry: PlateauGeometry | None = None,
    *,
    side: str | None = None,
) -> MedialLateral:
    """Medial and lateral compartment forces by the two-point model (module docstring;
    Winby et al. 2009 J Biomech 42:2294; Lerner et al. 2015 J Biomech 48:644).

    ``F_L = N/2 + M_C,x/d``, ``F_M = N/2 − M_C,x/d`` for a right knee (+z lateral), medial and
    lateral swapped for a left knee (+z medial), with ``M_C,x = M_O,x − c_y F_z + c_z F_y`` the
    frontal moment moved from the plateau-frame origin to the contact-point midpoint C.
    Vectorised over frames; NaN frames stay NaN.

    Args:
        contact: :func:`knee_contact_force` result (force and moment about its plateau-frame
            origin; ``geometry.centre_m`` is expressed in that same frame).
        geometry: contact points (default :class:`PlateauGeometry`: generic 40 mm, 22 mm deep;
            use :func:`plateau_geometry` for a scaled model).
        side: ``"right"`` / ``"left"`` (default: from the joint name suffix ``_r`` / ``_l``).
    """
    geo = PlateauGeometry() if geometry is None else geometry
    sd = _side_of(contact.joint, side)
    f = np.asarray(contact.force, dtype=float)
    m = np.asarray(contact.moment, dtype=float)
    if f.ndim != 2 or f.shape[1] != 3 or m.shape != f.shape:
        raise ShapeMismatchError(f"contact force {f.shape} / moment {m.shape} must be (N, 3)")
    _, cy, cz = geo.centre_m
    normal = -f[:, 1]
    m_c = m[:, 0] - cy * f[:, 2] + cz * f[:, 1]
    half = 0.5 * normal
    delta = m_c / geo.intercondylar_distance_m
    plus, minus = half + delta, half - delta  # forces at C + d/2 e_z and C − d/2 e_z
    medial, lateral = (minus, plus) if sd == "right" else (plus, minus)
    return MedialLateral(
        time=np.asarray(contact.time, dtype=float),
        joint=contact.joint,
        side=sd,
        medial=medial,
        lateral=lateral,
        normal=normal,
        frontal_moment=m_c,
        geometry=geo,
        body_weight_n=float(contact.body_weight_n),
    )
