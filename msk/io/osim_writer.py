"""Write an msk :class:`~msk.model.core.Model` as an OpenSim 4 ``.osim`` (bodies, joints,
coordinates, markers, muscles, wrap objects): the subject's scaled model for OpenSim's inverse
kinematics and dynamics, static optimisation and the GUI.

The inverse of the import mapping of :mod:`msk.model.osim`:

* Body: ``mass``, ``mass_center``, ``inertia`` = ``Ixx Iyy Izz Ixy Ixz Iyz`` about the COM in
  the body frame.
* Joint: ``parent_offset`` / ``child_offset`` become ``PhysicalOffsetFrame`` s on the parent
  and child (translation, body-fixed X-Y-Z ``orientation``: R = Rx(a) Ry(b) Rz(c), so
  b = asin(R₀₂), a = atan2(−R₁₂, R₂₂), c = atan2(−R₀₁, R₀₀)); the axis chain X(θ) =
  translation(Σ_k f_k(θ) t_k) · R(r₁, f₁) R(r₂, f₂) R(r₃, f₃) becomes a ``CustomJoint``'s
  ``SpatialTransform`` (Simbody's ``FunctionBased`` mobilizer: the same composition); the
  unused transform axes get a zero ``Constant`` along axes completing an independent set
  (their value is 0: no motion). A joint without axes is a ``WeldJoint``.
* Functions: :class:`~msk.model.joints.Linear` → ``LinearFunction``, ``Constant``,
  ``PolynomialFunction``, ``SimmSpline``, ``MultiplierFunction``, ``PiecewiseLinearFunction``.
* Coordinates: owned by the first joint whose axes use them (range, default, locked; not
  clamped).
* Markers: ``location`` in their body.

* Muscles: of their source class (``kind``, e.g. ``Thelen2003Muscle``; else
  ``Thelen2003Muscle``) with F_iso, l_opt, l_ts, α_opt, v_max and the source's other scalar
  properties (``extra``); path points (``PathPoint``, ``ConditionalPathPoint``,
  ``MovingPathPoint``: an axis msk holds fixed gets a ``Constant``) and ``PathWrap`` uses; the
  bodies' wrap objects (``model.metadata["wrap_objects"]``: cylinder, ellipsoid, sphere,
  torus).

A model whose axes or moving points use a function OpenSim has no element for
(:class:`~msk.model.joints.Composite`: a coupler-eliminated coordinate, the four-bar knee) or whose
axis is driven by another joint's coordinate raises :class:`~msk.exceptions.ModelError`.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape, quoteattr

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import ModelError
from msk.io.tables import write_text_atomic
from msk.model.core import GROUND
from msk.model.joints import Constant, Linear, Multiplier, PiecewiseLinear, Polynomial, SimmSpline
from msk.muscles.path import ConditionalPathPoint, MovingPathPoint

__all__ = ["body_fixed_xyz_angles", "osim_text", "write_osim"]

Array = NDArray[np.float64]


def body_fixed_xyz_angles(rotation: ArrayLike) -> Array:
    """(a, b, c) with R = Rx(a) Ry(b) Rz(c) (OpenSim's ``orientation``; module docstring)."""
    r = np.asarray(rotation, dtype=float).reshape(3, 3)
    b = float(np.arcsin(np.clip(r[0, 2], -1.0, 1.0)))
    if abs(r[0, 2]) < 1.0 - 1e-12:
        a = float(np.arctan2(-r[1, 2], r[2, 2]))
        c = float(np.arctan2(-r[0, 1], r[0, 0]))
    else:  # gimbal lock: c = 0, a from the remaining block
        a = float(np.arctan2(r[2, 1], r[1, 1]))
        c = 0.0
    return np.array([a, b, c])


def _num(x: float) -> str:
    return repr(float(x))


def _vec(v: ArrayLike) -> str:
    return " ".join(_num(x) for x in np.asarray(v, dtype=float).reshape(-1))


def _el(tag: str, body: str, name: str | None = None) -> str:
    """``<tag name="…">body</tag>``."""
    attr = "" if name is None else f" name={quoteattr(name)}"
    return f"<{tag}{attr}>{body}</{tag}>"


def _function(f: Any, what: str, name: str = "function") -> str:
    if isinstance(f, Linear):
        return _el("LinearFunction", _el("coefficients", _vec([f.slope, f.intercept])), name)
    if isinstance(f, Constant):
        return _el("Constant", _el("value", _num(f.value)), name)
    if isinstance(f, Polynomial):
        return _el("PolynomialFunction", _el("coefficients", _vec(f.coefficients)), name)
    if isinstance(f, SimmSpline):
        return _el("SimmSpline", _el("x", _vec(f.x)) + _el("y", _vec(f.y)), name)
    if isinstance(f, PiecewiseLinear):
        return _el("PiecewiseLinearFunction", _el("x", _vec(f.x)) + _el("y", _vec(f.y)), name)
    if isinstance(f, Multiplier):
        inner = _el("function", _function(f.function, what, name=""))
        return _el("MultiplierFunction", inner + _el("scale", _num(f.scale)), name)
    raise ModelError(
        f"{what}: function {type(f).__name__} has no OpenSim element: no .osim written"
    )


def _complete(used: list[Array]) -> list[Array]:
    """``used`` (≤ 3 axes) completed to three independent axes."""
    out = [np.asarray(a, dtype=float) for a in used]
    for e in np.eye(3):
        if len(out) == 3:
            break
        m = np.array([*out, e])
        if np.linalg.matrix_rank(m, tol=1e-6) == len(out) + 1:
            out.append(e)
    return out


def _frame(name: str, parent: str, pose: Any) -> str:
    body = (
        _el("socket_parent", escape(parent))
        + _el("translation", _vec(pose.translation))
        + _el("orientation", _vec(body_fixed_xyz_angles(pose.rotation)))
    )
    return _el("PhysicalOffsetFrame", body, name)


_WRAP_TAGS = {
    "cylinder": "WrapCylinder",
    "ellipsoid": "WrapEllipsoid",
    "sphere": "WrapSphere",
    "torus": "WrapTorus",
}
_TAG = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def _wrap_object(w: Any) -> str:
    body = (
        _el("xyz_body_rotation", _vec(w.xyz_body_rotation))
        + _el("translation", _vec(w.translation))
        + _el("quadrant", escape(w.quadrant))
        + _el("active", "true" if w.active else "false")
    )
    if w.kind == "cylinder":
        body += _el("radius", _num(w.radius)) + _el("length", _num(w.length))
    elif w.kind == "ellipsoid":
        body += _el("dimensions", _vec(w.dimensions))
    elif w.kind == "sphere":
        body += _el("radius", _num(w.radius))
    elif w.kind == "torus":
        body += _el("inner_radius", _num(w.dimensions[0])) + _el("outer_radius", _num(w.radius))
    else:
        raise ModelError(f"wrap object {w.name}: kind {w.kind!r} has no OpenSim element")
    return _el(_WRAP_TAGS[w.kind], body, w.name)


def _coordinate_path(name: str, owner: dict[str, str]) -> str:
    if name not in owner:
        raise ModelError(f"coordinate {name!r} drives a path point but no joint: no .osim written")
    return f"/jointset/{owner[name]}/{name}"


def _path_point(p: Any, muscle: str, owner: dict[str, str]) -> str:
    what = f"muscle {muscle} point {p.name}"
    head = _el("socket_parent_frame", _path(p.body)) + _el("location", _vec(p.location))
    if isinstance(p, ConditionalPathPoint):
        body = head + _el("socket_coordinate", _coordinate_path(p.coordinate, owner))
        return _el("ConditionalPathPoint", body + _el("range", _vec(p.range)), p.name)
    if isinstance(p, MovingPathPoint):
        body = _el("socket_parent_frame", _path(p.body))
        for k, ax in enumerate("xyz"):
            c, f = p.coordinates[k], p.functions[k]
            if c is None or f is None:  # fixed along this axis at location[k]
                c = next((x for x in p.coordinates if x is not None), None)
                f = Constant(float(p.location[k]))
            if c is None:
                raise ModelError(f"{what}: a moving point driven by no coordinate")
            body += _el(f"socket_{ax}_coordinate", _coordinate_path(c, owner))
            body += _el(f"{ax}_location", _function(f, f"{what} {ax}"))
        return _el("MovingPathPoint", body, p.name)
    return _el("PathPoint", head, p.name)


def _muscle(mu: Any, owner: dict[str, str]) -> str:
    points = "".join(_path_point(p, mu.name, owner) for p in mu.points)
    wraps = "".join(
        _el(
            "PathWrap",
            _el("wrap_object", escape(w.wrap_object))
            + _el("method", escape(w.method))
            + _el("range", f"{int(w.range[0])} {int(w.range[1])}"),
        )
        for w in mu.wraps
    )
    path = _el(
        "GeometryPath",
        _el("PathPointSet", _el("objects", points)) + _el("PathWrapSet", _el("objects", wraps)),
        "geometrypath",
    )
    props = (
        _el("max_isometric_force", _num(mu.max_isometric_force))
        + _el("optimal_fiber_length", _num(mu.optimal_fiber_length))
        + _el("tendon_slack_length", _num(mu.tendon_slack_length))
        + _el("pennation_angle_at_optimal", _num(mu.pennation_angle))
        + _el("max_contraction_velocity", _num(mu.max_contraction_velocity))
    )
    for key, value in (mu.extra or {}).items():  # the source's other scalar properties
        if not _TAG.match(str(key)):
            continue
        text = ("true" if value else "false") if isinstance(value, bool) else str(value)
        props += _el(str(key), escape(text))
    kind = (
        mu.kind if _TAG.match(mu.kind or "") and mu.kind.endswith("Muscle") else "Thelen2003Muscle"
    )
    return _el(kind, path + props, mu.name)


def _path(body: str) -> str:
    return "/ground" if body == GROUND else f"/bodyset/{body}"


def osim_text(model: Any, *, name: str | None = None) -> str:
    """The ``.osim`` document of ``model`` (module docstring)."""
    coords = {c.name: c for c in model.coordinates}
    owner: dict[str, str] = {}
    for j in model.joints:
        for ax in j.axes:
            if ax.coordinate is not None:
                owner.setdefault(ax.coordinate, j.name)
                if owner[ax.coordinate] != j.name:
                    raise ModelError(
                        f"joint {j.name}: axis driven by {ax.coordinate!r}, a coordinate of joint "
                        f"{owner[ax.coordinate]}: no .osim written (OpenSim needs a coupler)"
                    )
    wrap_objects = list((getattr(model, "metadata", None) or {}).get("wrap_objects", ()))
    bodies = []
    for b in model.bodies:
        i = np.asarray(b.inertia, dtype=float)
        inertia = [i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2]]
        wraps = "".join(_wrap_object(w) for w in wrap_objects if w.body == b.name)
        bodies.append(
            f"<Body name={quoteattr(b.name)}><mass>{_num(b.mass)}</mass>"
            f"<mass_center>{_vec(b.com)}</mass_center><inertia>{_vec(inertia)}</inertia>"
            + (_el("WrapObjectSet", _el("objects", wraps)) if wraps else "")
            + "</Body>"
        )
    joints = []
    for j in model.joints:
        what = f"joint {j.name}"
        frames = _frame(f"{j.parent}_offset", _path(j.parent), j.parent_offset) + _frame(
            f"{j.child}_offset", _path(j.child), j.child_offset
        )
        sockets = (
            f"<socket_parent_frame>{j.parent}_offset</socket_parent_frame>"
            f"<socket_child_frame>{j.child}_offset</socket_child_frame>"
        )
        if not j.axes:
            joints.append(_el("WeldJoint", sockets + _el("frames", frames), j.name))
            continue
        rot = [a for a in j.axes if a.kind == "revolute"]
        trans = [a for a in j.axes if a.kind == "prismatic"]
        kinds = [a.kind for a in j.axes]
        if len(rot) > 3 or len(trans) > 3 or kinds != sorted(kinds, key=lambda k: k == "revolute"):
            raise ModelError(f"{what}: axes {kinds} are not ≤ 3 translations then ≤ 3 rotations")
        mine = [c for c, o in owner.items() if o == j.name]
        cxml = "".join(
            _el(
                "Coordinate",
                _el("default_value", _num(coords[c].default))
                + _el("range", _vec(coords[c].range))
                + _el("clamped", "false")
                + _el("locked", "true" if coords[c].locked else "false"),
                c,
            )
            for c in mine
        )
        axes = []
        for kind, used in (("rotation", rot), ("translation", trans)):
            full = _complete([a.axis for a in used])
            for k, vec in enumerate(full):
                if k < len(used):
                    ax = used[k]
                    cn = ax.coordinate or ""
                    fun = _function(ax.function, f"{what} {kind}{k + 1}")
                else:
                    cn, fun = "", _function(Constant(0.0), what)
                axes.append(
                    f'<TransformAxis name="{kind}{k + 1}"><coordinates>{escape(cn)}</coordinates>'
                    f"<axis>{_vec(vec)}</axis>{fun}</TransformAxis>"
                )
        joints.append(
            f"<CustomJoint name={quoteattr(j.name)}>{sockets}<coordinates>{cxml}</coordinates>"
            f"<frames>{frames}</frames><SpatialTransform>{''.join(axes)}</SpatialTransform>"
            "</CustomJoint>"
        )
    markers = "".join(
        f"<Marker name={quoteattr(m.name)}><socket_parent_frame>{_path(m.body)}"
        f"</socket_parent_frame><location>{_vec(m.offset)}</location><fixed>false</fixed></Marker>"
        for m in model.markers
    )
    forces = "".join(_muscle(mu, owner) for mu in getattr(model, "muscles", ()))
    ground_wraps = "".join(_wrap_object(w) for w in wrap_objects if w.body == GROUND)
    title = name or getattr(model, "name", "") or "msk"
    doc = (
        '<?xml version="1.0" encoding="UTF-8" ?>\n<OpenSimDocument Version="40000">\n'
        f"<Model name={quoteattr(title)}>"
        "<credits>msk (msk.io.osim_writer): bodies, joints, coordinates, markers, muscles"
        "</credits><length_units>meters</length_units><force_units>N</force_units>"
        f"<gravity>{_vec(model.gravity)}</gravity>"
        + (
            f'<Ground name="ground">{_el("WrapObjectSet", _el("objects", ground_wraps))}</Ground>'
            if ground_wraps
            else '<Ground name="ground" />'
        )
        + f'<BodySet name="bodyset"><objects>{"".join(bodies)}</objects></BodySet>'
        f'<JointSet name="jointset"><objects>{"".join(joints)}</objects></JointSet>'
        f'<ForceSet name="forceset"><objects>{forces}</objects></ForceSet>'
        f'<MarkerSet name="markerset"><objects>{markers}</objects></MarkerSet>'
        "</Model>\n</OpenSimDocument>\n"
    )
    return doc


def write_osim(path: str | Path, model: Any, *, name: str | None = None) -> Path:
    """Write :func:`osim_text` of ``model`` to ``path`` (atomic)."""
    return write_text_atomic(path, osim_text(model, name=name))
