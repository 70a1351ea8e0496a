"""The immutable msk model: a Pinocchio tree of 1-DOF joints driven by independent coordinates.

A :class:`Model` is built from plain specifications (bodies, joints as chains of 1-DOF axes,
coordinates, markers, muscles as data). Every axis is a Pinocchio revolute or prismatic joint
whose value is a scalar function of one coordinate (:mod:`msk.model.joints`), so OpenSim
CustomJoints,
the four-bar knee and the pelvis "free-flyer" (three translations and three rotations, as in
OpenSim) share one mechanism. Personalising returns a new model (``with_inertias``,
``with_bodies``…); the Pinocchio model inside is never modified after construction.

Frame conventions (as OpenSim): a joint has a frame fixed in the parent body
(``parent_offset``) and one fixed in the child body (``child_offset``); the joint transform
X(θ) = translation(Σ t_k axis_k) · R_1 R_2 R_3 (translations along parent-frame axes, then
body-fixed successive rotations) maps the child joint frame to the parent joint frame.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import ModelError
from msk.model.joints import Constant, CoordinateFunction, Coupling, Linear
from msk.units import G0, Array

__all__ = [
    "GROUND",
    "INERTIAL_PARAMETER_NAMES",
    "Axis",
    "Body",
    "Coordinate",
    "Joint",
    "JointState",
    "Marker",
    "Model",
    "ModelState",
    "forward_kinematics",
    "frame_placements",
    "marker_positions",
    "replace_body",
]

GROUND = "ground"

#: Pinocchio's standard inertial-parameter order (inertia at the body origin, first moments m·c).
INERTIAL_PARAMETER_NAMES: tuple[str, ...] = (
    "m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz",
)  # fmt: skip


def _as_vec3(x: ArrayLike, what: str) -> Array:
    v = np.asarray(x, dtype=float).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ModelError(f"{what} must be 3 finite numbers, got {x!r}")
    return v


def _se3(x: pin.SE3 | None) -> pin.SE3:
    return pin.SE3.Identity() if x is None else pin.SE3(x)


@dataclass(frozen=True)
class Coordinate:
    """An independent generalised coordinate θ_i (rad or m)."""

    name: str
    kind: Literal["rotational", "translational"] = "rotational"
    range: tuple[float, float] = (-np.pi, np.pi)
    default: float = 0.0
    locked: bool = False


@dataclass(frozen=True, eq=False)
class Body:
    """A rigid segment: mass (kg), centre of mass (m) and inertia about the COM (kg·m²), both in
    the body frame."""

    name: str
    mass: float
    com: Array = field(default_factory=lambda: np.zeros(3))
    inertia: Array = field(default_factory=lambda: np.zeros((3, 3)))

    def __post_init__(self) -> None:
        object.__setattr__(self, "com", _as_vec3(self.com, f"body {self.name} COM"))
        inertia = np.asarray(self.inertia, dtype=float)
        if inertia.shape != (3, 3) or not np.allclose(inertia, inertia.T, atol=1e-12):
            raise ModelError(f"body {self.name}: inertia must be a symmetric 3×3 matrix")
        object.__setattr__(self, "inertia", inertia)
        if not np.isfinite(self.mass) or self.mass < 0:
            raise ModelError(f"body {self.name}: mass must be ≥ 0, got {self.mass}")

    @property
    def pin_inertia(self) -> pin.Inertia:
        return pin.Inertia(float(self.mass), self.com, self.inertia)

    def parameters(self) -> Array:
        """Standard inertial parameters in :data:`INERTIAL_PARAMETER_NAMES` order."""
        return np.asarray(self.pin_inertia.toDynamicParameters(), dtype=float)

    @staticmethod
    def from_parameters(name: str, phi: ArrayLike) -> Body:
        inertia = pin.Inertia.FromDynamicParameters(np.asarray(phi, dtype=float))
        return Body(name, float(inertia.mass), inertia.lever.copy(), inertia.inertia.copy())


@dataclass(frozen=True, eq=False)
class Axis:
    """One 1-DOF transform axis of a joint: its unit axis (joint frame) and q = f(θ_coordinate).

    ``coordinate`` is ``None`` for a constant axis (then ``function`` must be a
    :class:`~msk.model.joints.Constant`).
    """

    kind: Literal["revolute", "prismatic"]
    axis: Array
    coordinate: str | None
    function: CoordinateFunction = field(default_factory=Linear)

    def __post_init__(self) -> None:
        ax = _as_vec3(self.axis, "joint axis")
        n = np.linalg.norm(ax)
        if n < 1e-12:
            raise ModelError("joint axis must not be zero")
        object.__setattr__(self, "axis", ax / n)


@dataclass(frozen=True, eq=False)
class Joint:
    """Articulation of ``child`` on ``parent``: translations first, then successive rotations.

    An empty ``axes`` tuple is a weld.
    """

    name: str
    parent: str
    child: str
    parent_offset: pin.SE3 = field(default_factory=pin.SE3.Identity)
    child_offset: pin.SE3 = field(default_factory=pin.SE3.Identity)
    axes: tuple[Axis, ...] = ()


@dataclass(frozen=True, eq=False)
class Marker:
    """A skin marker fixed in a body (offset in the body frame, m)."""

    name: str
    body: str
    offset: Array

    def __post_init__(self) -> None:
        object.__setattr__(self, "offset", _as_vec3(self.offset, f"marker {self.name} offset"))


def _offset_arrays(x: pin.SE3 | None) -> tuple[Array | None, Array | None]:
    return (None, None) if x is None else (x.rotation.copy(), x.translation.copy())


def _offset(rotation: Array | None, translation: Array | None) -> pin.SE3 | None:
    return None if rotation is None or translation is None else pin.SE3(rotation, translation)


@dataclass(frozen=True, eq=False)
class JointState:
    """A :class:`Joint` as plain arrays: each offset's rotation matrix and translation (both
    ``None`` for an offset given as ``None``, the identity)."""

    name: str
    parent: str
    child: str
    parent_rotation: Array | None
    parent_translation: Array | None
    child_rotation: Array | None
    child_translation: Array | None
    axes: tuple[Axis, ...]


@dataclass(frozen=True, eq=False)
class ModelState:
    """What a :class:`Model` is built from, as plain data (msk dataclasses, numpy arrays,
    strings, numbers): the form the stage cache (:mod:`msk._runtime.cache`, which stores no
    Pinocchio
    object) keeps of a model. :meth:`Model.from_state` builds the model again from it with the
    same specifications, entry for entry (an offset SE(3) from its stored rotation and
    translation), hence the same Pinocchio model."""

    name: str
    bodies: tuple[Body, ...]
    joints: tuple[JointState, ...]
    coordinates: tuple[Coordinate, ...]
    markers: tuple[Marker, ...]
    muscles: tuple[Any, ...]
    gravity: Array
    metadata: dict[str, Any]


def _axis_joint_model(ax: Axis) -> pin.JointModel:
    unit = ax.axis
    aligned = np.flatnonzero(np.abs(np.abs(unit) - 1.0) < 1e-12)
    if aligned.size == 1 and unit[aligned[0]] > 0:
        name = ("R" if ax.kind == "revolute" else "P") + "XYZ"[aligned[0]]
        return getattr(pin, f"JointModel{name}")()
    if ax.kind == "revolute":
        return pin.JointModelRevoluteUnaligned(unit)
    return pin.JointModelPrismaticUnaligned(unit)


class Model:
    """Immutable musculoskeletal model (see module docstring).

    Attributes:
        pin_model: the Pinocchio model (1-DOF joints, nq == nv); never modify it.
        coordinates: the independent coordinates θ, in order.
        coupling: the embedding θ → q_pin (:class:`~msk.model.joints.Coupling`).
        bodies, joints, markers: the specifications the model was built from.
        muscles: muscle data attached by importers (opaque here; see :mod:`msk.muscles`).
        body_frame: Pinocchio frame id of each body frame.
        marker_frame: Pinocchio frame id of each marker.
        body_joint: Pinocchio joint id that carries each body (0 = universe).
        root_joint: name of the joint whose child is attached to ground (the floating base).
    """

    def __init__(
        self,
        *,
        name: str,
        bodies: Sequence[Body],
        joints: Sequence[Joint],
        coordinates: Sequence[Coordinate],
        markers: Sequence[Marker] = (),
        muscles: Sequence[Any] = (),
        gravity: ArrayLike = (0.0, -G0, 0.0),
        metadata: Mapping[str, Any] | None = None,
    ) -> None:
        self.name = name
        self.bodies: tuple[Body, ...] = tuple(bodies)
        self.joints: tuple[Joint, ...] = tuple(joints)
        self.coordinates: tuple[Coordinate, ...] = tuple(coordinates)
        self.markers: tuple[Marker, ...] = tuple(markers)
        self.muscles: tuple[Any, ...] = tuple(muscles)
        self.gravity = _as_vec3(gravity, "gravity")
        self.metadata: dict[str, Any] = dict(metadata or {})
        self._build()

    # ---------------------------------------------------------------- construction
    def _build(self) -> None:
        body_by_name = {b.name: b for b in self.bodies}
        if len(body_by_name) != len(self.bodies):
            raise ModelError(f"model {self.name}: duplicate body names")
        coord_index = {c.name: i for i, c in enumerate(self.coordinates)}
        if len(coord_index) != len(self.coordinates):
            raise ModelError(f"model {self.name}: duplicate coordinate names")

        m = pin.Model()
        m.name = self.name
        m.gravity = pin.Motion(self.gravity, np.zeros(3))
        # placement of each body frame relative to the Pinocchio joint carrying it
        body_joint: dict[str, int] = {GROUND: 0}
        body_place: dict[str, pin.SE3] = {GROUND: pin.SE3.Identity()}
        body_frame: dict[str, int] = {}
        ground_frame = m.addFrame(
            pin.Frame(GROUND, 0, 0, pin.SE3.Identity(), pin.FrameType.OP_FRAME)
        )
        body_frame[GROUND] = ground_frame
        coupling_coord: list[int] = []
        coupling_fun: list[CoordinateFunction] = []

        pending = list(self.joints)
        while pending:
            progressed = False
            for joint in list(pending):
                if joint.parent not in body_joint:
                    continue
                if joint.child not in body_by_name:
                    raise ModelError(f"joint {joint.name}: unknown child body {joint.child!r}")
                if joint.child in body_joint:
                    raise ModelError(f"joint {joint.name}: body {joint.child!r} has two parents")
                parent_jid = body_joint[joint.parent]
                placement = body_place[joint.parent] * _se3(joint.parent_offset)
                jid = parent_jid
                for k, ax in enumerate(joint.axes):
                    jname = f"{joint.name}_{k}" if len(joint.axes) > 1 else joint.name
                    jid = m.addJoint(jid, _axis_joint_model(ax), placement, jname)
                    placement = pin.SE3.Identity()
                    if ax.coordinate is None:
                        if not isinstance(ax.function, Constant):
                            raise ModelError(f"joint {joint.name}: axis {k} has no coordinate")
                        coupling_coord.append(-1)
                    else:
                        if ax.coordinate not in coord_index:
                            raise ModelError(
                                f"joint {joint.name}: unknown coordinate {ax.coordinate!r}"
                            )
                        coupling_coord.append(coord_index[ax.coordinate])
                    coupling_fun.append(ax.function)
                bplace = placement * _se3(joint.child_offset).inverse()
                body = body_by_name[joint.child]
                m.appendBodyToJoint(jid, body.pin_inertia, bplace)
                body_frame[joint.child] = m.addFrame(
                    pin.Frame(
                        joint.child, jid, body_frame[joint.parent], bplace, pin.FrameType.BODY
                    )
                )
                body_joint[joint.child] = jid
                body_place[joint.child] = bplace
                pending.remove(joint)
                progressed = True
            if not progressed:
                names = ", ".join(f"{j.name} (parent {j.parent})" for j in pending)
                raise ModelError(f"model {self.name}: joints not connected to ground: {names}")
        missing = set(body_by_name) - set(body_joint)
        if missing:
            raise ModelError(f"model {self.name}: bodies without a joint: {sorted(missing)}")

        marker_frame: dict[str, int] = {}
        for mk in self.markers:
            if mk.body not in body_joint:
                raise ModelError(f"marker {mk.name}: unknown body {mk.body!r}")
            place = body_place[mk.body] * pin.SE3(np.eye(3), mk.offset)
            marker_frame[mk.name] = m.addFrame(
                pin.Frame(
                    mk.name,
                    body_joint[mk.body],
                    body_frame[mk.body],
                    place,
                    pin.FrameType.OP_FRAME,
                )
            )
        if m.nq != m.nv:
            raise ModelError("msk models use 1-DOF joints only (nq must equal nv)")
        roots = [j.name for j in self.joints if j.parent == GROUND]
        self.pin_model = m
        self.coupling = Coupling(tuple(coupling_coord), tuple(coupling_fun), len(self.coordinates))
        self.body_frame = body_frame
        self.body_joint = body_joint
        self.body_placement = body_place
        self.marker_frame = marker_frame
        self.root_joint = roots[0] if len(roots) == 1 else None

    # ---------------------------------------------------------------- queries
    @property
    def coordinate_names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.coordinates)

    @property
    def marker_names(self) -> tuple[str, ...]:
        return tuple(mk.name for mk in self.markers)

    @property
    def n_coords(self) -> int:
        return len(self.coordinates)

    @property
    def total_mass(self) -> float:
        return float(sum(b.mass for b in self.bodies))

    def coordinate_index(self, name: str) -> int:
        for i, c in enumerate(self.coordinates):
            if c.name == name:
                return i
        raise ModelError(f"model {self.name}: no coordinate {name!r}")

    def body(self, name: str) -> Body:
        for b in self.bodies:
            if b.name == name:
                return b
        raise ModelError(f"model {self.name}: no body {name!r}")

    def default_coordinates(self) -> Array:
        return np.array([c.default for c in self.coordinates])

    def coordinate_bounds(self) -> tuple[Array, Array]:
        lo = np.array([c.range[0] for c in self.coordinates])
        hi = np.array([c.range[1] for c in self.coordinates])
        return lo, hi

    def subtree(self, body: str) -> tuple[str, ...]:
        """``body`` and every body distal to it (depth-first order of the joint list)."""
        self.body(body)
        out = [body]
        changed = True
        while changed:
            changed = False
            for joint in self.joints:
                if joint.parent in out and joint.child not in out:
                    out.append(joint.child)
                    changed = True
        return tuple(out)

    def create_data(self) -> pin.Data:
        """A fresh Pinocchio workspace for this model."""
        return self.pin_model.createData()

    def root_dofs(self) -> NDArray[np.intp]:
        """Pinocchio DOF indices of the floating-base joint chain (the pelvis residuals)."""
        if self.root_joint is None:
            raise ModelError(f"model {self.name}: no unique root joint")
        joint = next(j for j in self.joints if j.name == self.root_joint)
        n = len(joint.axes)
        return np.arange(n)

    # ---------------------------------------------------------------- personalisation
    def _rebuilt(self, **changes: Any) -> Model:
        kwargs: dict[str, Any] = {
            "name": self.name,
            "bodies": self.bodies,
            "joints": self.joints,
            "coordinates": self.coordinates,
            "markers": self.markers,
            "muscles": self.muscles,
            "gravity": self.gravity,
            "metadata": self.metadata,
        }
        kwargs.update(changes)
        return Model(**kwargs)

    def with_bodies(self, bodies: Mapping[str, Body]) -> Model:
        """A new model with some bodies replaced (same names)."""
        unknown = set(bodies) - {b.name for b in self.bodies}
        if unknown:
            raise ModelError(f"model {self.name}: unknown bodies {sorted(unknown)}")
        return self._rebuilt(bodies=[bodies.get(b.name, b) for b in self.bodies])

    def with_inertias(self, parameters: Mapping[str, ArrayLike]) -> Model:
        """A new model whose bodies take the given standard inertial parameters (10 per body,
        :data:`INERTIAL_PARAMETER_NAMES` order, in the body frame)."""
        return self.with_bodies(
            {name: Body.from_parameters(name, phi) for name, phi in parameters.items()}
        )

    def with_markers(self, markers: Sequence[Marker]) -> Model:
        return self._rebuilt(markers=markers)

    def with_muscles(self, muscles: Sequence[Any]) -> Model:
        return self._rebuilt(muscles=muscles)

    def with_strength(self, factors: Mapping[str, float]) -> Model:
        """A new model whose named muscles have F_iso multiplied by their strength factor."""
        names = {m.name for m in self.muscles}
        unknown = sorted(set(factors) - names)
        if unknown:
            raise ModelError(f"model {self.name}: unknown muscles {unknown}")
        bad = {k: v for k, v in factors.items() if not (np.isfinite(v) and v > 0)}
        if bad:
            raise ModelError(f"model {self.name}: strength factors must be > 0, got {bad}")
        return self.with_muscles(
            [
                replace(m, max_isometric_force=m.max_isometric_force * float(factors[m.name]))
                if m.name in factors
                else m
                for m in self.muscles
            ]
        )

    def with_joints(self, joints: Mapping[str, Joint]) -> Model:
        """A new model with some joints replaced (e.g. the spline knee by a four-bar knee)."""
        unknown = set(joints) - {j.name for j in self.joints}
        if unknown:
            raise ModelError(f"model {self.name}: unknown joints {sorted(unknown)}")
        return self._rebuilt(joints=[joints.get(j.name, j) for j in self.joints])

    def with_coordinate_ranges(self, ranges: Mapping[str, tuple[float, float]]) -> Model:
        """A new model whose named coordinates take the given ranges (lower, upper)."""
        unknown = set(ranges) - {c.name for c in self.coordinates}
        if unknown:
            raise ModelError(f"model {self.name}: unknown coordinates {sorted(unknown)}")
        coords = [
            replace(c, range=(float(ranges[c.name][0]), float(ranges[c.name][1])))
            if c.name in ranges else c
            for c in self.coordinates
        ]  # fmt: skip
        return self._rebuilt(coordinates=coords)

    def with_metadata(self, **metadata: Any) -> Model:
        return self._rebuilt(metadata={**self.metadata, **metadata})

    # ---------------------------------------------------------------- plain-data form
    def state(self) -> ModelState:
        """The specifications of this model as plain data (:class:`ModelState`)."""
        joints = tuple(
            JointState(j.name, j.parent, j.child, *_offset_arrays(j.parent_offset),
                       *_offset_arrays(j.child_offset), tuple(j.axes))
            for j in self.joints
        )  # fmt: skip
        return ModelState(
            self.name, self.bodies, joints, self.coordinates, self.markers, self.muscles,
            self.gravity.copy(), dict(self.metadata),
        )  # fmt: skip

    @staticmethod
    def from_state(state: ModelState) -> Model:
        """The model whose :meth:`state` is ``state`` (built and checked as any model)."""
        joints = [
            Joint(j.name, j.parent, j.child, _offset(j.parent_rotation, j.parent_translation),
                  _offset(j.child_rotation, j.child_translation), tuple(j.axes))
            for j in state.joints
        ]  # fmt: skip
        return Model(
            name=state.name, bodies=state.bodies, joints=joints, coordinates=state.coordinates,
            markers=state.markers, muscles=state.muscles, gravity=state.gravity,
            metadata=state.metadata,
        )  # fmt: skip

    def __repr__(self) -> str:
        return (
            f"Model({self.name!r}: {len(self.bodies)} bodies, {self.n_coords} coordinates, "
            f"{len(self.markers)} markers, {len(self.muscles)} muscles)"
        )


def replace_body(body: Body, **changes: Any) -> Body:
    """``dataclasses.replace`` for bodies (keeps validation)."""
    return replace(body, **changes)


# ------------------------------------------------------------------------------------------
# kinematics helpers shared by IK, dynamics and muscle geometry
# ------------------------------------------------------------------------------------------
def forward_kinematics(model: Model, data: pin.Data, theta: ArrayLike) -> Array:
    """Run Pinocchio forward kinematics + frame placements at θ; returns q_pin."""
    q = model.coupling.q(np.asarray(theta, dtype=float))
    pin.framesForwardKinematics(model.pin_model, data, q)
    return q


def frame_placements(model: Model, theta: ArrayLike, frames: Sequence[int]) -> tuple[Array, Array]:
    """World rotations (N, K, 3, 3) and translations (N, K, 3) of the Pinocchio frames
    ``frames`` (ids: ``model.body_frame``, ``model.marker_frame``) for θ of shape (N, n_coords):
    the embedding g(θ) of every frame in one vectorised call, Pinocchio's joint placements
    per frame, then each frame's placement on its parent joint composed in one product
    (oMf = oMi · iMf). The same placements as :func:`forward_kinematics`'s ``data.oMf``,
    without its per-frame Python evaluation of the coupling."""
    th = np.atleast_2d(np.asarray(theta, dtype=float))
    pm = model.pin_model
    data = model.create_data()
    parents = [pm.frames[f].parentJoint for f in frames]
    joints = sorted(set(parents))
    which = [joints.index(j) for j in parents]
    fh = np.array([pm.frames[f].placement.homogeneous for f in frames]).reshape(-1, 4, 4)
    q = model.coupling.q(th)
    omi = data.oMi
    h = np.empty((th.shape[0], len(joints), 4, 4))
    for n in range(th.shape[0]):
        pin.forwardKinematics(pm, data, q[n])
        h[n] = [omi[j].homogeneous for j in joints]
    out = h[:, which] @ fh  # (N, K, 4, 4)
    return out[..., :3, :3], out[..., :3, 3]


def marker_positions(model: Model, theta: ArrayLike) -> Array:
    """World positions of every model marker, (N, n_markers, 3) for θ of shape (N, n_coords)."""
    th = np.atleast_2d(np.asarray(theta, dtype=float))
    data = model.create_data()
    ids = [model.marker_frame[mk.name] for mk in model.markers]
    out = np.empty((th.shape[0], len(ids), 3))
    for n in range(th.shape[0]):
        forward_kinematics(model, data, th[n])
        for j, fid in enumerate(ids):
            out[n, j] = data.oMf[fid].translation
    return out
