"""Import of OpenSim ``.osim`` models (OpenSim 4.x ``<frames>`` format and the 3.x format).

``load_osim(path)`` returns an immutable :class:`msk.model.core.Model`; ``import_osim(path)``
returns
the model and an :class:`ImportReport` listing what the file uses that msk does not represent
(display geometry is ignored silently; actuators that are not muscles, contact geometry,
controllers, probes and unsupported functions are reported). With ``strict=True`` the first
unsupported feature that changes kinematics or muscle paths raises :class:`ModelError` naming
the element.

Mapping (OpenSim → msk):

* Body: ``mass``, ``mass_center`` and the inertia about the COM
  (``inertia`` = ``Ixx Iyy Izz Ixy Ixz Iyz`` in 4.x, ``inertia_xx`` … in 3.x), in the body frame.
* Joints: the parent and child frames (``PhysicalOffsetFrame``: translation, body-fixed XYZ
  ``orientation``; 3.x ``location_in_parent``/``orientation_in_parent`` and
  ``location``/``orientation``) become ``parent_offset`` / ``child_offset``. A CustomJoint's
  ``SpatialTransform`` becomes the axis chain of the model core, X(θ) =
  translation(Σ_k f_k(θ) t_k) · R(r_1, f_1(θ)) R(r_2, f_2(θ)) R(r_3, f_3(θ)) (Simbody's
  ``FunctionBased`` mobilizer: translations along the parent-frame axes, then body-fixed
  successive rotations). Axes whose function is a zero Constant are dropped. PinJoint = rotation
  about z, SliderJoint = translation along x, UniversalJoint = x then y, GimbalJoint and
  BallJoint = body-fixed x, y, z, PlanarJoint = translations x, y then rotation z, FreeJoint =
  translations x, y, z then body-fixed x, y, z, WeldJoint = no axis.
* Functions: Constant, LinearFunction, PolynomialFunction, SimmSpline, MultiplierFunction and
  PiecewiseLinearFunction (:class:`msk.model.joints.PiecewiseLinear`), all in
  :mod:`msk.model.joints`
  (``PiecewiseLinear`` and ``Composite`` are re-exported here). GCVSpline,
  NaturalCubicSpline, StepFunction, Sine… are reported (strict: ``ModelError``).
* CoordinateCouplerConstraint with one independent coordinate: the dependent coordinate is
  eliminated, every axis (and moving path point) it drives becomes f(c(θ_indep))
  (:class:`msk.model.joints.Composite`), which is exactly OpenSim's constrained kinematics.
* Muscles (every force with a ``GeometryPath`` whose class name contains ``Muscle``): path
  points (PathPoint, ConditionalPathPoint, MovingPathPoint) in their body frames, PathWrap uses,
  F_iso, l_opt, l_ts, α_opt, v_max; every other scalar property goes to ``Muscle.extra``. Wrap
  objects of the bodies (cylinders, ellipsoids, spheres, tori) are in
  ``model.metadata["wrap_objects"]`` as :class:`msk.muscles.path.WrapObject` records.
* Markers (``MarkerSet`` of the model, or an OpenSim marker-set file given as ``marker_set``),
  gravity, coordinate ranges, default values, ``locked``; ``clamped`` coordinates are listed in
  ``model.metadata["clamped"]``.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from msk.exceptions import FileFormatError, ModelError
from msk.model.core import GROUND, Axis, Body, Coordinate, Joint, Marker, Model
from msk.model.joints import (
    Composite,
    Constant,
    CoordinateFunction,
    Linear,
    Multiplier,
    PiecewiseLinear,
    Polynomial,
    SimmSpline,
)
from msk.muscles.path import (
    ConditionalPathPoint,
    MovingPathPoint,
    Muscle,
    PathPoint,
    PathWrap,
    WrapObject,
)
from msk.units import Array

__all__ = [
    "Composite",
    "ImportReport",
    "PiecewiseLinear",
    "body_fixed_xyz",
    "import_osim",
    "load_osim",
    "read_marker_set",
]


def body_fixed_xyz(angles: ArrayLike) -> Array:
    """R = Rx(a) Ry(b) Rz(c): OpenSim's body-fixed X-Y-Z ``orientation`` convention."""
    a, b, c = (float(v) for v in np.asarray(angles, dtype=float).reshape(3))
    return (
        pin.AngleAxis(a, np.array([1.0, 0, 0])).toRotationMatrix()
        @ pin.AngleAxis(b, np.array([0, 1.0, 0])).toRotationMatrix()
        @ pin.AngleAxis(c, np.array([0, 0, 1.0])).toRotationMatrix()
    )


# ------------------------------------------------------------------------------------------
# report
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ImportReport:
    """What an import met that msk does not represent (or represents approximately).

    ``unsupported``: features that change kinematics or muscle paths (strict mode raises on the
    first); ``ignored``: elements with no effect on what msk computes (non-muscle actuators,
    contact geometry, controllers, probes); ``notes``: transformations made (coupled coordinates
    eliminated…). Each entry names the element.
    """

    path: str
    unsupported: tuple[str, ...] = ()
    ignored: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        return not self.unsupported

    def __str__(self) -> str:
        lines = [f"import of {self.path}: {len(self.unsupported)} unsupported"]
        lines += [f"  UNSUPPORTED {u}" for u in self.unsupported]
        lines += [f"  ignored {u}" for u in self.ignored]
        lines += [f"  note {u}" for u in self.notes]
        return "\n".join(lines)


@dataclass
class _Log:
    path: str
    strict: bool
    unsupported: list[str] = field(default_factory=list)
    ignored: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def bad(self, msg: str) -> None:
        if self.strict:
            raise ModelError(f"{self.path}: unsupported {msg}")
        self.unsupported.append(msg)

    def report(self) -> ImportReport:
        return ImportReport(
            self.path, tuple(self.unsupported), tuple(self.ignored), tuple(self.notes)
        )


# ------------------------------------------------------------------------------------------
# XML helpers
# ------------------------------------------------------------------------------------------
def _txt(el: ET.Element | None, tag: str, default: str | None = None) -> str | None:
    if el is None:
        return default
    child = el.find(tag)
    if child is None or child.text is None:
        return default
    return child.text.strip()


def _floats(text: str | None, what: str, n: int | None = None) -> Array:
    try:
        v = np.array([float(t) for t in (text or "").split()], dtype=float)
    except ValueError as exc:
        raise FileFormatError(f"{what}: not numbers: {text!r}") from exc
    if n is not None and v.size != n:
        raise FileFormatError(f"{what}: expected {n} numbers, got {text!r}")
    return v


def _num(el: ET.Element | None, tag: str, default: float, what: str) -> float:
    t = _txt(el, tag)
    if t is None or t == "":
        return default
    return float(_floats(t, f"{what} <{tag}>", 1)[0])


def _bool(el: ET.Element | None, tag: str, default: bool = False) -> bool:
    t = _txt(el, tag)
    return default if t is None else t.lower() in ("true", "1")


def _vec3(el: ET.Element | None, tag: str, what: str) -> Array:
    t = _txt(el, tag)
    if t is None or t == "":
        return np.zeros(3)
    return _floats(t, f"{what} <{tag}>", 3)


def _objects(el: ET.Element | None) -> list[ET.Element]:
    if el is None:
        return []
    objs = el.find("objects")
    return list(objs) if objs is not None else []


def _last(path: str) -> str:
    return path.strip().rstrip("/").split("/")[-1]


# ------------------------------------------------------------------------------------------
# functions
# ------------------------------------------------------------------------------------------
_FUNCTION_TAGS = {
    "Constant",
    "LinearFunction",
    "PolynomialFunction",
    "SimmSpline",
    "MultiplierFunction",
    "PiecewiseLinearFunction",
    "GCVSpline",
    "NaturalCubicSpline",
    "StepFunction",
    "Sine",
    "PiecewiseConstantFunction",
    "LinearFunctionOfCoordinate",
}


def _find_function(el: ET.Element, wrapper: str = "function") -> ET.Element | None:
    """The function element of a TransformAxis / MultiplierFunction / coupler (4.x: a child with
    a function tag; 3.x: wrapped in ``<function>`` or ``wrapper``)."""
    for child in el:
        if child.tag in _FUNCTION_TAGS:
            return child
    for child in el:
        if child.tag == wrapper and len(child):
            return child[0]
    return None


def _parse_function(el: ET.Element, what: str, log: _Log) -> CoordinateFunction | None:
    tag = el.tag
    if tag == "Constant":
        return Constant(_num(el, "value", 0.0, what))
    if tag == "LinearFunction":
        c = _floats(_txt(el, "coefficients", "1 0"), f"{what} LinearFunction", 2)
        return Linear(float(c[0]), float(c[1]))
    if tag == "PolynomialFunction":
        c = _floats(_txt(el, "coefficients", "0"), f"{what} PolynomialFunction")
        return Polynomial(tuple(float(v) for v in c))
    if tag in ("SimmSpline", "PiecewiseLinearFunction"):
        x = _floats(_txt(el, "x", ""), f"{what} {tag} x")
        y = _floats(_txt(el, "y", ""), f"{what} {tag} y")
        if x.size == 1 and y.size == 1:
            return Constant(float(y[0]))
        try:
            if tag == "SimmSpline":
                return SimmSpline(tuple(x.tolist()), tuple(y.tolist()))
            return PiecewiseLinear(tuple(x.tolist()), tuple(y.tolist()))
        except ModelError as exc:
            raise ModelError(f"{log.path}: {what}: {exc}") from exc
    if tag == "MultiplierFunction":
        inner_el = _find_function(el)
        if inner_el is None:
            log.bad(f"{what}: MultiplierFunction without a function")
            return None
        inner = _parse_function(inner_el, what, log)
        if inner is None:
            return None
        scale = _num(el, "scale", 1.0, what)
        if isinstance(inner, Constant):
            return Constant(scale * inner.value)
        return Multiplier(inner, scale)
    log.bad(f"{what}: function {tag}")
    return None


# ------------------------------------------------------------------------------------------
# the importer
# ------------------------------------------------------------------------------------------
_MOTION_TYPES = {"rotational", "translational", "coupled"}


@dataclass
class _Frame:
    parent: str  # path of the parent frame (or a body name when resolved)
    se3: pin.SE3


class _Importer:
    def __init__(self, path: Path, strict: bool) -> None:
        self.path = path
        self.log = _Log(str(path), strict)
        try:
            tree = ET.parse(path)
        except (ET.ParseError, OSError) as exc:
            raise FileFormatError(f"{path}: cannot read OpenSim model: {exc}") from exc
        root = tree.getroot()
        model_el = root.find("Model") if root.tag == "OpenSimDocument" else root
        if model_el is None or model_el.tag != "Model":
            raise FileFormatError(f"{path}: no <Model> element")
        self.root = root
        self.m = model_el
        self.version = int(root.get("Version", "40000")) if root.tag == "OpenSimDocument" else 0
        self.bodies: list[Body] = []
        self.body_names: set[str] = {GROUND}
        self.joints: list[Joint] = []
        self.coords: dict[str, dict[str, Any]] = {}
        self.coord_order: list[str] = []
        self.rot_coords: set[str] = set()
        self.frames: dict[str, _Frame] = {}  # global frame paths
        self.wrap_objects: list[WrapObject] = []

    # -------------------------------------------------------------- frames
    def _resolve(self, path: str, local: dict[str, _Frame] | None = None) -> tuple[str, pin.SE3]:
        """(body, placement of the frame in the body) for a frame path."""
        p = (path or "").strip()
        seen = 0
        acc = pin.SE3.Identity()
        while True:
            seen += 1
            if seen > 50:
                raise ModelError(f"{self.path}: frame path cycle at {path!r}")
            name = _last(p)
            if local is not None and p in local:
                fr = local[p]
            elif p in self.frames:
                fr = self.frames[p]
            elif p in ("/ground", "ground"):
                return GROUND, acc
            elif name in self.body_names and (p.startswith("/bodyset/") or "/" not in p):
                return name, acc
            else:
                raise ModelError(f"{self.path}: cannot resolve frame {path!r}")
            acc = fr.se3 * acc
            p = fr.parent

    def _offset_frame(self, el: ET.Element, what: str) -> _Frame:
        t = _vec3(el, "translation", what)
        o = _vec3(el, "orientation", what)
        parent = _txt(el, "socket_parent", "") or ""
        return _Frame(parent, pin.SE3(body_fixed_xyz(o), t))

    def _collect_global_frames(self) -> None:
        """Offset frames owned by the model's ComponentSet or by bodies (``components``)."""
        for el in _objects(self.m.find("ComponentSet")):
            if el.tag == "PhysicalOffsetFrame":
                name = el.get("name", "")
                self.frames[f"/componentset/{name}"] = self._offset_frame(el, f"frame {name}")
        for b in _objects(self.m.find("BodySet")):
            for el in _objects_or_children(b.find("components")):
                if el.tag == "PhysicalOffsetFrame":
                    name = el.get("name", "")
                    self.frames[f"/bodyset/{b.get('name')}/{name}"] = self._offset_frame(
                        el, f"frame {name}"
                    )

    # -------------------------------------------------------------- bodies
    def _body(self, el: ET.Element) -> Body:
        name = el.get("name", "")
        what = f"body {name}"
        mass = _num(el, "mass", 0.0, what)
        com = _vec3(el, "mass_center", what)
        if el.find("inertia") is not None:
            ii = _floats(_txt(el, "inertia"), f"{what} <inertia>", 6)
        else:
            ii = np.array(
                [_num(el, f"inertia_{k}", 0.0, what) for k in ("xx", "yy", "zz", "xy", "xz", "yz")]
            )
        inertia = np.array([[ii[0], ii[3], ii[4]], [ii[3], ii[1], ii[5]], [ii[4], ii[5], ii[2]]])
        return Body(name, mass, com, inertia)

    def _wraps_of_body(self, body_el: ET.Element, body: str) -> None:
        for w in _objects(body_el.find("WrapObjectSet")):
            name = w.get("name", "")
            what = f"wrap object {name} on {body}"
            kinds = {
                "WrapCylinder": "cylinder",
                "WrapEllipsoid": "ellipsoid",
                "WrapSphere": "sphere",
                "WrapTorus": "torus",
            }
            if w.tag not in kinds:
                self.log.bad(f"{what}: {w.tag}")
                continue
            radius = _num(w, "radius", 0.0, what)
            dims = np.zeros(3)
            if w.tag == "WrapEllipsoid":
                dims = _vec3(w, "dimensions", what)
            if w.tag == "WrapTorus":
                radius = _num(w, "outer_radius", 0.0, what)
                dims = np.array([_num(w, "inner_radius", 0.0, what), radius, 0.0])
            frame = _txt(w, "socket_frame")
            trans = _vec3(w, "translation", what)
            rot = _vec3(w, "xyz_body_rotation", what)
            if frame and _last(frame) != body:
                self.log.bad(f"{what}: attached to frame {frame!r} (not the body)")
            self.wrap_objects.append(
                WrapObject(
                    name=name,
                    body=body,
                    kind=kinds[w.tag],
                    translation=trans,
                    xyz_body_rotation=rot,
                    radius=radius,
                    length=_num(w, "length", 0.0, what),
                    dimensions=dims,
                    quadrant=(_txt(w, "quadrant", "all") or "all").strip(),
                    active=_bool(w, "active", True),
                )
            )

    # -------------------------------------------------------------- coordinates
    def _coordinate(self, el: ET.Element, joint: str) -> None:
        name = el.get("name", "")
        what = f"coordinate {name} of joint {joint}"
        rng = _floats(_txt(el, "range", "-3.14159265 3.14159265"), f"{what} <range>", 2)
        motion = _txt(el, "motion_type")
        self.coords[name] = {
            "range": (float(rng[0]), float(rng[1])),
            "default": _num(el, "default_value", 0.0, what),
            "locked": _bool(el, "locked"),
            "clamped": _bool(el, "clamped"),
            "motion": motion if motion in _MOTION_TYPES else None,
            "joint": joint,
        }
        self.coord_order.append(name)
        if _bool(el, "prescribed"):
            self.log.bad(f"{what}: prescribed motion")

    # -------------------------------------------------------------- joints
    def _axes_of(self, jel: ET.Element, jname: str, coord_names: list[str]) -> tuple[Axis, ...]:
        tag = jel.tag
        lin = Linear()
        ex, ey, ez = np.eye(3)

        def need(n: int) -> list[str]:
            if len(coord_names) != n:
                raise ModelError(
                    f"{self.path}: {tag} {jname} needs {n} coordinates, has {coord_names}"
                )
            return coord_names

        if tag == "WeldJoint":
            return ()
        if tag == "PinJoint":
            (c,) = need(1)
            self.rot_coords.add(c)
            return (Axis("revolute", ez, c, lin),)
        if tag == "SliderJoint":
            (c,) = need(1)
            return (Axis("prismatic", ex, c, lin),)
        if tag == "UniversalJoint":
            c1, c2 = need(2)
            self.rot_coords.update((c1, c2))
            return (Axis("revolute", ex, c1, lin), Axis("revolute", ey, c2, lin))
        if tag in ("GimbalJoint", "BallJoint"):
            cs = need(3)
            self.rot_coords.update(cs)
            if tag == "BallJoint":
                self.log.notes.append(f"BallJoint {jname}: body-fixed x-y-z angles (no quaternion)")
            return tuple(Axis("revolute", a, c, lin) for a, c in zip((ex, ey, ez), cs))
        if tag == "PlanarJoint":
            rz, tx, ty = need(3)
            self.rot_coords.add(rz)
            return (
                Axis("prismatic", ex, tx, lin),
                Axis("prismatic", ey, ty, lin),
                Axis("revolute", ez, rz, lin),
            )
        if tag == "FreeJoint":
            rx, ry, rz, tx, ty, tz = need(6)
            self.rot_coords.update((rx, ry, rz))
            self.log.notes.append(f"FreeJoint {jname}: translations then body-fixed x-y-z angles")
            return (
                Axis("prismatic", ex, tx, lin),
                Axis("prismatic", ey, ty, lin),
                Axis("prismatic", ez, tz, lin),
                Axis("revolute", ex, rx, lin),
                Axis("revolute", ey, ry, lin),
                Axis("revolute", ez, rz, lin),
            )
        if tag == "CustomJoint":
            st = jel.find("SpatialTransform")
            if st is None:
                raise ModelError(f"{self.path}: CustomJoint {jname} has no SpatialTransform")
            by_name = {ta.get("name", ""): ta for ta in st.findall("TransformAxis")}
            trans: list[Axis] = []
            rots: list[Axis] = []
            for key in ("translation1", "translation2", "translation3", "rotation1", "rotation2",
                        "rotation3"):  # fmt: skip
                ta = by_name.get(key)
                if ta is None:
                    continue
                kind: Literal["revolute", "prismatic"] = (
                    "revolute" if key.startswith("rotation") else "prismatic"
                )
                what = f"CustomJoint {jname} {key}"
                names = (_txt(ta, "coordinates", "") or "").split()
                axis = _floats(_txt(ta, "axis", "0 0 0"), f"{what} <axis>", 3)
                fel = _find_function(ta)
                fun = _parse_function(fel, what, self.log) if fel is not None else None
                if fel is None and names:
                    fun = lin
                if fun is None:
                    continue
                if len(names) > 1:
                    self.log.bad(f"{what}: function of {len(names)} coordinates {names}")
                    continue
                if not names or isinstance(fun, Constant):
                    value = float(fun(0.0))
                    if value == 0.0:
                        continue
                    ax = Axis(kind, axis, None, Constant(value))
                else:
                    if names[0] not in self.coords:
                        raise ModelError(f"{self.path}: {what}: unknown coordinate {names[0]!r}")
                    if kind == "revolute":
                        self.rot_coords.add(names[0])
                    ax = Axis(kind, axis, names[0], fun)
                (rots if kind == "revolute" else trans).append(ax)
            return tuple(trans + rots)
        self.log.bad(f"joint {jname}: joint type {tag}")
        return ()

    def _joint4(self, jel: ET.Element) -> Joint | None:
        jname = jel.get("name", "")
        local: dict[str, _Frame] = {}
        for fr in _objects_or_children(jel.find("frames")):
            if fr.tag == "PhysicalOffsetFrame":
                local[fr.get("name", "")] = self._offset_frame(fr, f"joint {jname} frame")
        coord_names = []
        for cel in _objects_or_children(jel.find("coordinates")):
            if cel.tag == "Coordinate":
                self._coordinate(cel, jname)
                coord_names.append(cel.get("name", ""))
        pf = _txt(jel, "socket_parent_frame", "") or ""
        cf = _txt(jel, "socket_child_frame", "") or ""
        # frames local to the joint are also reachable by their absolute path
        for k, v in local.items():
            self.frames[f"/jointset/{jname}/{k}"] = v
        parent, p_off = self._resolve(pf, local)
        child, c_off = self._resolve(cf, local)
        if child == GROUND:
            self.log.bad(f"joint {jname}: ground as child (reversed joint)")
            return None
        axes = self._axes_of(jel, jname, coord_names)
        return Joint(jname, parent, child, p_off, c_off, axes)

    def _joint3(self, body_el: ET.Element) -> Joint | None:
        child = body_el.get("name", "")
        jwrap = body_el.find("Joint")
        if jwrap is None or not len(jwrap):
            return None
        jel = jwrap[0]
        jname = jel.get("name", "")
        parent = _txt(jel, "parent_body", GROUND) or GROUND
        if _bool(jel, "reverse"):
            self.log.bad(f"joint {jname}: reverse=true")
        what = f"joint {jname}"
        p_off = pin.SE3(
            body_fixed_xyz(_vec3(jel, "orientation_in_parent", what)),
            _vec3(jel, "location_in_parent", what),
        )
        c_off = pin.SE3(
            body_fixed_xyz(_vec3(jel, "orientation", what)), _vec3(jel, "location", what)
        )
        coord_names = []
        for cel in _objects(jel.find("CoordinateSet")):
            self._coordinate(cel, jname)
            coord_names.append(cel.get("name", ""))
        axes = self._axes_of(jel, jname, coord_names)
        return Joint(jname, GROUND if parent == "ground" else parent, child, p_off, c_off, axes)

    # -------------------------------------------------------------- constraints
    def _couplers(self) -> dict[str, tuple[str, CoordinateFunction]]:
        out: dict[str, tuple[str, CoordinateFunction]] = {}
        for c in _objects(self.m.find("ConstraintSet")):
            name = c.get("name", "")
            if c.tag != "CoordinateCouplerConstraint":
                self.log.bad(f"constraint {name}: {c.tag}")
                continue
            if not _bool(c, "isEnforced", True) or _txt(c, "isDisabled", "false") == "true":
                self.log.ignored.append(f"constraint {name} (not enforced)")
                continue
            indep = (_txt(c, "independent_coordinate_names", "") or "").split()
            dep = (_txt(c, "dependent_coordinate_name", "") or "").strip()
            fel = _find_function(c, "coupled_coordinates_function")
            if fel is None:
                fcf = c.find("coupled_coordinates_function")
                fel = fcf[0] if fcf is not None and len(fcf) else None
            if len(indep) != 1 or fel is None or dep not in self.coords:
                self.log.bad(f"constraint {name}: coupler of {indep} → {dep!r}")
                continue
            fun = _parse_function(fel, f"constraint {name}", self.log)
            if fun is None:
                continue
            scale = _num(c, "scale_factor", 1.0, f"constraint {name}")
            if scale != 1.0:
                fun = Multiplier(fun, scale)
            out[dep] = (indep[0], fun)
            self.log.notes.append(
                f"constraint {name}: coordinate {dep} eliminated, = f({indep[0]}) (embedded)"
            )
        return out

    # -------------------------------------------------------------- muscles
    def _point(self, el: ET.Element, muscle: str, coupled: dict) -> PathPoint | None:
        name = el.get("name", "")
        what = f"muscle {muscle} point {name}"
        frame = _txt(el, "socket_parent_frame") or _txt(el, "body") or ""
        body, place = self._resolve(frame if frame.startswith("/") else f"/bodyset/{frame}")
        loc = _vec3(el, "location", what)
        if el.tag == "PathPoint":
            return PathPoint(name, body, place.act(loc))
        if el.tag == "ConditionalPathPoint":
            cname = _last(_txt(el, "socket_coordinate") or _txt(el, "coordinate") or "")
            rng = _floats(_txt(el, "range", ""), f"{what} <range>", 2)
            if cname in coupled:
                self.log.bad(f"{what}: conditional on eliminated coordinate {cname}")
            return ConditionalPathPoint(
                name, body, place.act(loc), coordinate=cname, range=(float(rng[0]), float(rng[1]))
            )
        if el.tag == "MovingPathPoint":
            if not np.allclose(place.rotation, np.eye(3)) or np.any(place.translation != 0):
                self.log.bad(f"{what}: moving point in an offset frame {frame!r}")
            coords: list[str | None] = []
            funs: list[CoordinateFunction | None] = []
            for k, ax in enumerate("xyz"):
                cpath = _txt(el, f"socket_{ax}_coordinate") or _txt(el, f"{ax}_coordinate") or ""
                axis_cname = _last(cpath) if cpath else None
                fel_wrap = el.find(f"{ax}_location")
                fel = fel_wrap[0] if fel_wrap is not None and len(fel_wrap) else None
                fun = _parse_function(fel, f"{what} {ax}", self.log) if fel is not None else None
                if fun is None or axis_cname is None or isinstance(fun, Constant):
                    coords.append(None)
                    funs.append(None)
                    if fun is not None:
                        loc[k] = float(fun(0.0))
                    continue
                if axis_cname in coupled:
                    indep, cf = coupled[axis_cname]
                    axis_cname, fun = indep, Composite(fun, cf)
                coords.append(axis_cname)
                funs.append(fun)
                loc[k] = float(fun(self.coords.get(axis_cname, {}).get("default", 0.0)))
            return MovingPathPoint(
                name,
                body,
                loc,
                coordinates=(coords[0], coords[1], coords[2]),
                functions=tuple(funs),
            )
        self.log.bad(f"{what}: path point type {el.tag}")
        return None

    def _muscles(self, coupled: dict) -> list[Muscle]:
        muscles = []
        for f in _objects(self.m.find("ForceSet")):
            name = f.get("name", "")
            gp = f.find("GeometryPath")
            if gp is None or "Muscle" not in f.tag:
                self.log.ignored.append(f"force {name} ({f.tag})")
                continue
            pts = []
            for p in _objects(gp.find("PathPointSet")):
                pt = self._point(p, name, coupled)
                if pt is not None:
                    pts.append(pt)
            wraps = []
            for w in _objects(gp.find("PathWrapSet")):
                rng = _floats(_txt(w, "range", "-1 -1"), f"muscle {name} wrap range", 2)
                wraps.append(
                    PathWrap(
                        wrap_object=(_txt(w, "wrap_object", "") or "").strip(),
                        method=(_txt(w, "method", "hybrid") or "hybrid").strip(),
                        range=(int(rng[0]), int(rng[1])),
                    )
                )
            known = {
                "max_isometric_force",
                "optimal_fiber_length",
                "tendon_slack_length",
                "pennation_angle_at_optimal",
                "max_contraction_velocity",
            }
            extra: dict[str, Any] = {}
            for child in f:
                if child.tag in known or child.tag == "GeometryPath":
                    continue
                for sub in [child, *child.iter()] if len(child) else [child]:
                    if len(sub) or sub.text is None or not sub.text.strip():
                        continue
                    key = sub.tag if sub is child else f"{child.tag}.{sub.tag}"
                    extra[key] = _scalar(sub.text.strip())
            muscles.append(
                Muscle(
                    name=name,
                    points=tuple(pts),
                    max_isometric_force=_num(f, "max_isometric_force", 0.0, name),
                    optimal_fiber_length=_num(f, "optimal_fiber_length", 0.0, name),
                    tendon_slack_length=_num(f, "tendon_slack_length", 0.0, name),
                    pennation_angle=_num(f, "pennation_angle_at_optimal", 0.0, name),
                    max_contraction_velocity=_num(f, "max_contraction_velocity", 10.0, name),
                    wraps=tuple(wraps),
                    kind=f.tag,
                    extra=extra,
                )
            )
        return muscles

    # -------------------------------------------------------------- markers
    def _markers(self, elements: Iterable[ET.Element]) -> list[Marker]:
        out = []
        for mk in elements:
            name = mk.get("name", "")
            frame = _txt(mk, "socket_parent_frame") or _txt(mk, "body") or ""
            body, place = self._resolve(frame if frame.startswith("/") else f"/bodyset/{frame}")
            out.append(Marker(name, body, place.act(_vec3(mk, "location", f"marker {name}"))))
        return out

    # -------------------------------------------------------------- main
    def run(self, marker_set: str | Path | None) -> Model:
        bodyset = self.m.find("BodySet")
        body_els = [b for b in _objects(bodyset) if b.tag == "Body"]
        for b in body_els:
            name = b.get("name", "")
            if name == "ground":  # 3.x ground body
                self._wraps_of_body(b, GROUND)
                continue
            self.bodies.append(self._body(b))
            self.body_names.add(name)
            self._wraps_of_body(b, name)
        ground_el = self.m.find("Ground")
        if ground_el is not None:
            self._wraps_of_body(ground_el, GROUND)
        for b in _objects(bodyset):
            if b.tag != "Body":
                self.log.bad(f"body {b.get('name')}: {b.tag}")
        self._collect_global_frames()
        joints: list[Joint | None] = []
        if self.m.find("JointSet") is not None:
            for jel in _objects(self.m.find("JointSet")):
                joints.append(self._joint4(jel))
        else:
            for b in body_els:
                if b.get("name") != "ground":
                    joints.append(self._joint3(b))
        self.joints = [j for j in joints if j is not None]

        coupled = self._couplers()
        if coupled:
            new_joints = []
            for j in self.joints:
                axes = []
                for ax in j.axes:
                    if ax.coordinate in coupled:
                        indep, cf = coupled[ax.coordinate]
                        fun: CoordinateFunction = (
                            ax.function
                            if isinstance(cf, Linear) and cf.slope == 1.0 and cf.intercept == 0.0
                            else Composite(ax.function, cf)
                        )
                        ax = Axis(ax.kind, ax.axis, indep, fun)
                    axes.append(ax)
                new_joints.append(Joint(j.name, j.parent, j.child, j.parent_offset,
                                        j.child_offset, tuple(axes)))  # fmt: skip
            self.joints = new_joints

        coordinates = []
        for name in self.coord_order:
            if name in coupled:
                continue
            c = self.coords[name]
            kind = c["motion"]
            if kind is None or kind == "coupled":
                kind = "rotational" if name in self.rot_coords else "translational"
            coordinates.append(Coordinate(name, kind, c["range"], c["default"], c["locked"]))
        muscles = self._muscles(coupled)
        if marker_set is not None:
            markers = self._markers(_marker_elements(Path(marker_set)))
        else:
            markers = self._markers(
                m for m in _objects(self.m.find("MarkerSet")) if m.tag == "Marker"
            )
        gravity = _floats(_txt(self.m, "gravity", "0 -9.80665 0"), "model <gravity>", 3)
        for tag in ("ContactGeometrySet", "ControllerSet", "ProbeSet", "ComponentSet"):
            objs = _objects(self.m.find(tag))
            for o in objs:
                if tag == "ComponentSet" and o.tag == "PhysicalOffsetFrame":
                    continue
                self.log.ignored.append(f"{tag} {o.get('name')} ({o.tag})")
        metadata = {
            "source": str(self.path),
            "osim_version": self.version,
            "clamped": [n for n in self.coord_order if self.coords[n]["clamped"]],
            "coupled": {d: i for d, (i, _) in coupled.items()},
            "wrap_objects": tuple(self.wrap_objects),
            "credits": (_txt(self.m, "credits", "") or "")[:2000],
            "publications": (_txt(self.m, "publications", "") or "")[:2000],
        }
        return Model(
            name=self.m.get("name", self.path.stem),
            bodies=self.bodies,
            joints=self.joints,
            coordinates=coordinates,
            markers=markers,
            muscles=muscles,
            gravity=gravity,
            metadata=metadata,
        )


def _objects_or_children(el: ET.Element | None) -> list[ET.Element]:
    if el is None:
        return []
    objs = el.find("objects")
    return list(objs) if objs is not None else list(el)


def _scalar(text: str) -> Any:
    low = text.lower()
    if low in ("true", "false"):
        return low == "true"
    parts = text.split()
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        return text
    return vals[0] if len(vals) == 1 else vals


def _marker_elements(path: Path) -> list[ET.Element]:
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as exc:
        raise FileFormatError(f"{path}: cannot read marker set: {exc}") from exc
    return list(root.iter("Marker"))


def import_osim(
    path: str | Path, *, strict: bool = False, marker_set: str | Path | None = None
) -> tuple[Model, ImportReport]:
    """Read an OpenSim model; return the msk model and the report of what was not imported.

    ``marker_set``: an OpenSim ``MarkerSet`` XML file whose markers replace the model's.
    ``strict``: raise :class:`ModelError` at the first unsupported feature.
    """
    imp = _Importer(Path(path), strict)
    model = imp.run(marker_set)
    report = imp.log.report()
    return model.with_metadata(import_report=str(report)), report


def load_osim(
    path: str | Path, *, strict: bool = False, marker_set: str | Path | None = None
) -> Model:
    """:func:`import_osim` without the report (it is kept in ``metadata["import_report"]``)."""
    return import_osim(path, strict=strict, marker_set=marker_set)[0]


def read_marker_set(path: str | Path, model: Model) -> Model:
    """``model`` with the markers of an OpenSim marker-set file (bodies must exist)."""
    imp = _Importer.__new__(_Importer)
    imp.path = Path(path)
    imp.log = _Log(str(path), False)
    imp.frames = {}
    imp.body_names = {GROUND, *(b.name for b in model.bodies)}
    return model.with_markers(imp._markers(_marker_elements(Path(path))))
