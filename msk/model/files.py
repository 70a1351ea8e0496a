"""msk's own model files: TOML data (never code), read and written without loss.

``save_model(model, path, header=...)`` writes every number with ``repr`` (shortest string that
round-trips a double), so ``load_model(save_model(m))`` reproduces bodies, joint offsets, axes
and their functions, coordinates, markers, muscles (paths, wraps, parameters, ``extra``), wrap
objects and simple metadata exactly.

Layout (one table per kind; every location in the frame of the body it is fixed to, SI)::

    [model]        name, format = "msk-model", format_version, gravity
    [metadata]     str / number / bool / lists / tables only
    [[coordinates]] name, kind, range, default, locked
    [[bodies]]     name, mass, com, inertia (3×3 about the COM, body frame)
    [[joints]]     name, parent, child, parent_offset / child_offset = {translation, rotation}
      [[joints.axes]] kind, axis, coordinate ("" = constant), function = {type = …}
    [[markers]]    name, body, offset
    [[wrap_objects]] name, body, kind, translation, xyz_body_rotation, radius, length, …
    [[muscles]]    name, kind, max_isometric_force, optimal_fiber_length, tendon_slack_length,
                   pennation_angle, max_contraction_velocity, extra = {…}
      [[muscles.points]] type, name, body, location (+ coordinate/range or coordinates/functions)
      [[muscles.wraps]]  wrap_object, method, range

Functions are inline tables with a ``type``: ``Constant {value}``, ``Linear {slope, intercept}``,
``Polynomial {coefficients}`` (highest order first), ``SimmSpline {x, y}``,
``PiecewiseLinear {x, y}``, ``Multiplier {function, scale}``, ``Composite {outer, inner}`` and
``FourBarTranslation {component, linkage = {femur_a, femur_b, tibia_c, tibia_d, theta_ref,
p_ref}}``.
"""

from __future__ import annotations

import difflib
import json
import math
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from msk.exceptions import FileFormatError, ModelError
from msk.model.core import Axis, Body, Coordinate, Joint, Marker, Model
from msk.model.joints import (
    Composite,
    Constant,
    CoordinateFunction,
    FourBarKnee,
    FourBarTranslation,
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

__all__ = [
    "FORMAT_VERSION",
    "function_from_dict",
    "function_to_dict",
    "load_model",
    "model_file",
    "save_model",
    "shipped_models",
]

FORMAT_VERSION = 1


def _shipped_dir() -> Path:
    """The folder of the models shipped inside the package (``msk/data/models``)."""
    return Path(__file__).resolve().parents[1] / "data" / "models"


def shipped_models() -> tuple[str, ...]:
    """The names of the models shipped with msk (``gait2392``, ``gait2392_fourbar``, …), sorted."""
    return tuple(sorted(p.stem for p in _shipped_dir().glob("*.toml")))


def model_file(name: str | Path, *, base: Path | None = None) -> Path:
    """The file of a model given by name (a shipped model: ``"gait2392"``) or by path.

    A bare word (no folder, no suffix) names a shipped model; anything else is a path, relative to
    ``base`` (the configuration file's folder) when given. A bare word that is no shipped model
    raises :class:`ModelError` listing the shipped names (with the closest one).
    """
    text = str(name)
    p = Path(text)
    if not p.suffix and len(p.parts) == 1 and text not in ("", ".", ".."):
        shipped = _shipped_dir() / f"{text}.toml"
        if shipped.is_file():
            return shipped
        names = shipped_models()
        close = difflib.get_close_matches(text, names, n=1, cutoff=0.6)
        tip = f" (did you mean {close[0]!r}?)" if close else ""
        raise ModelError(
            f"model {text!r} is neither a file nor a shipped model; shipped: "
            f"{', '.join(names)}{tip}"
        )
    return (base / p).resolve() if base is not None else p


# ------------------------------------------------------------------------------------------
# functions <-> dicts
# ------------------------------------------------------------------------------------------
def _fl(x: Any) -> list[float]:
    return [float(v) for v in np.asarray(x, dtype=float).reshape(-1)]


def function_to_dict(f: CoordinateFunction) -> dict[str, Any]:
    """A coordinate function as a plain dict with a ``type`` key (see module docstring)."""
    if isinstance(f, Constant):
        return {"type": "Constant", "value": float(f.value)}
    if isinstance(f, Linear):
        return {"type": "Linear", "slope": float(f.slope), "intercept": float(f.intercept)}
    if isinstance(f, Polynomial):
        return {"type": "Polynomial", "coefficients": _fl(f.coefficients)}
    if isinstance(f, SimmSpline):
        return {"type": "SimmSpline", "x": _fl(f.x), "y": _fl(f.y)}
    if isinstance(f, PiecewiseLinear):
        return {"type": "PiecewiseLinear", "x": _fl(f.x), "y": _fl(f.y)}
    if isinstance(f, Multiplier):
        return {
            "type": "Multiplier",
            "scale": float(f.scale),
            "function": function_to_dict(f.function),
        }
    if isinstance(f, Composite):
        return {
            "type": "Composite",
            "outer": function_to_dict(f.outer),
            "inner": function_to_dict(f.inner),
        }
    if isinstance(f, FourBarTranslation):
        k = f.linkage
        return {
            "type": "FourBarTranslation",
            "component": int(f.component),
            "linkage": {
                "femur_a": _fl(k.femur_a),
                "femur_b": _fl(k.femur_b),
                "tibia_c": _fl(k.tibia_c),
                "tibia_d": _fl(k.tibia_d),
                "theta_ref": float(k.theta_ref),
                "p_ref": _fl(k.p_ref),
            },
        }
    raise ModelError(f"cannot serialise coordinate function of type {type(f).__name__}")


def function_from_dict(d: Mapping[str, Any], where: str = "") -> CoordinateFunction:
    """Inverse of :func:`function_to_dict`; ``where`` names the place for error messages."""
    try:
        t = d["type"]
        if t == "Constant":
            return Constant(float(d["value"]))
        if t == "Linear":
            return Linear(float(d["slope"]), float(d["intercept"]))
        if t == "Polynomial":
            return Polynomial(tuple(float(v) for v in d["coefficients"]))
        if t == "SimmSpline":
            return SimmSpline(tuple(map(float, d["x"])), tuple(map(float, d["y"])))
        if t == "PiecewiseLinear":
            return PiecewiseLinear(tuple(map(float, d["x"])), tuple(map(float, d["y"])))
        if t == "Multiplier":
            return Multiplier(function_from_dict(d["function"], where), float(d["scale"]))
        if t == "Composite":
            return Composite(
                function_from_dict(d["outer"], where), function_from_dict(d["inner"], where)
            )
        if t == "FourBarTranslation":
            k = d["linkage"]
            pair = lambda v: (float(v[0]), float(v[1]))  # noqa: E731
            linkage = FourBarKnee(
                pair(k["femur_a"]),
                pair(k["femur_b"]),
                pair(k["tibia_c"]),
                pair(k["tibia_d"]),
                float(k.get("theta_ref", 0.0)),
                pair(k.get("p_ref", (0.0, 0.0))),
            )
            return FourBarTranslation(linkage, int(d["component"]))
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise FileFormatError(f"{where}: bad function {dict(d)!r}: {exc!r}") from exc
    raise FileFormatError(f"{where}: unknown function type {d.get('type')!r}")


# ------------------------------------------------------------------------------------------
# a small TOML writer (tables, arrays of tables, inline tables, arrays, scalars)
# ------------------------------------------------------------------------------------------
def _val(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int | np.integer):
        return str(int(v))
    if isinstance(v, float | np.floating):
        x = float(v)
        if math.isnan(x):
            return "nan"
        if math.isinf(x):
            return "inf" if x > 0 else "-inf"
        return repr(x)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, np.ndarray):
        return _val(v.tolist())
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{_key(k)} = {_val(x)}" for k, x in v.items()) + " }"
    if isinstance(v, Sequence):
        return "[" + ", ".join(_val(x) for x in v) + "]"
    raise ModelError(f"cannot write {type(v).__name__} to TOML: {v!r}")


def _key(k: str) -> str:
    if k and all(c.isalnum() or c in "_-" for c in k):
        return k
    return json.dumps(k, ensure_ascii=False)


def _table(lines: list[str], header: str, d: Mapping[str, Any]) -> None:
    """Scalars/inline values first, then sub arrays-of-tables (list of dicts under key '[]…')."""
    lines.append(header)
    subs = []
    for k, v in d.items():
        if isinstance(v, list) and v and all(isinstance(x, dict) for x in v) and k.startswith("@"):
            subs.append((k[1:], v))
            continue
        lines.append(f"{_key(k)} = {_val(v)}")
    base = header.strip("[]")
    for k, items in subs:
        for item in items:
            _table(lines, f"[[{base}.{k}]]", item)


def _plain(v: Any) -> Any:
    """Metadata value restricted to TOML types (None when it cannot be written)."""
    if isinstance(v, bool | int | float | str):
        return v
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, Mapping):
        out = {str(k): _plain(x) for k, x in v.items()}
        return {k: x for k, x in out.items() if x is not None}
    if isinstance(v, list | tuple | np.ndarray):
        items = [_plain(x) for x in v]
        return None if any(x is None for x in items) else items
    return None


# ------------------------------------------------------------------------------------------
# save
# ------------------------------------------------------------------------------------------
def _se3(x: pin.SE3) -> dict[str, Any]:
    return {"translation": _fl(x.translation), "rotation": np.asarray(x.rotation).tolist()}


def _point(p: PathPoint) -> dict[str, Any]:
    d: dict[str, Any] = {
        "type": type(p).__name__,
        "name": p.name,
        "body": p.body,
        "location": _fl(p.location),
    }
    if isinstance(p, ConditionalPathPoint):
        d["coordinate"] = p.coordinate
        d["range"] = _fl(p.range)
    if isinstance(p, MovingPathPoint):
        d["coordinates"] = [c or "" for c in p.coordinates]
        d["functions"] = [
            function_to_dict(f) if f is not None else {"type": "None"} for f in p.functions
        ]
    return d


def save_model(model: Model, path: str | Path, *, header: str = "") -> Path:
    """Write ``model`` as TOML (atomically: a temporary file renamed at the end).

    ``header`` is written as ``#`` comment lines at the top (cite the sources there).
    """
    path = Path(path)
    lines: list[str] = [f"# {line}".rstrip() for line in header.splitlines()]
    if lines:
        lines.append("")
    _table(
        lines,
        "[model]",
        {
            "name": model.name,
            "format": "msk-model",
            "format_version": FORMAT_VERSION,
            "gravity": _fl(model.gravity),
        },
    )
    meta = {
        k: _plain(v) for k, v in model.metadata.items() if k != "wrap_objects" and _plain(v) != {}
    }
    meta = {k: v for k, v in meta.items() if v is not None}
    if meta:
        lines.append("")
        _table(lines, "[metadata]", meta)
    for c in model.coordinates:
        lines.append("")
        _table(
            lines,
            "[[coordinates]]",
            {
                "name": c.name,
                "kind": c.kind,
                "range": _fl(c.range),
                "default": float(c.default),
                "locked": bool(c.locked),
            },
        )
    for b in model.bodies:
        lines.append("")
        _table(
            lines,
            "[[bodies]]",
            {
                "name": b.name,
                "mass": float(b.mass),
                "com": _fl(b.com),
                "inertia": np.asarray(b.inertia).tolist(),
            },
        )
    for j in model.joints:
        lines.append("")
        axes = [
            {
                "kind": a.kind,
                "axis": _fl(a.axis),
                "coordinate": a.coordinate or "",
                "function": function_to_dict(a.function),
            }
            for a in j.axes
        ]
        _table(
            lines,
            "[[joints]]",
            {
                "name": j.name,
                "parent": j.parent,
                "child": j.child,
                "parent_offset": _se3(j.parent_offset),
                "child_offset": _se3(j.child_offset),
                "@axes": axes,
            },
        )
    for mk in model.markers:
        lines.append("")
        _table(lines, "[[markers]]", {"name": mk.name, "body": mk.body, "offset": _fl(mk.offset)})
    for w in model.metadata.get("wrap_objects", ()):
        lines.append("")
        _table(
            lines,
            "[[wrap_objects]]",
            {
                "name": w.name,
                "body": w.body,
                "kind": w.kind,
                "translation": _fl(w.translation),
                "xyz_body_rotation": _fl(w.xyz_body_rotation),
                "radius": float(w.radius),
                "length": float(w.length),
                "dimensions": _fl(w.dimensions),
                "quadrant": w.quadrant,
                "active": bool(w.active),
            },
        )
    for m in model.muscles:
        if not isinstance(m, Muscle):
            raise ModelError(f"model {model.name}: muscle {m!r} is not a msk.muscles.path.Muscle")
        lines.append("")
        extra = _plain(dict(m.extra)) or {}
        _table(
            lines,
            "[[muscles]]",
            {
                "name": m.name,
                "kind": m.kind,
                "max_isometric_force": float(m.max_isometric_force),
                "optimal_fiber_length": float(m.optimal_fiber_length),
                "tendon_slack_length": float(m.tendon_slack_length),
                "pennation_angle": float(m.pennation_angle),
                "max_contraction_velocity": float(m.max_contraction_velocity),
                "extra": extra,
                "@points": [_point(p) for p in m.points],
                "@wraps": [
                    {"wrap_object": w.wrap_object, "method": w.method, "range": list(w.range)}
                    for w in m.wraps
                ],
            },
        )
    text = "\n".join(lines) + "\n"
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(path)
    return path


# ------------------------------------------------------------------------------------------
# load
# ------------------------------------------------------------------------------------------
def _arr(d: Mapping[str, Any], key: str, where: str, shape: tuple[int, ...]) -> np.ndarray:
    try:
        a = np.asarray(d[key], dtype=float)
    except (KeyError, TypeError, ValueError) as exc:
        raise FileFormatError(f"{where}: missing or bad {key!r}") from exc
    if a.shape != shape:
        raise FileFormatError(f"{where}: {key} must have shape {shape}, got {a.shape}")
    return a


def _se3_from(d: Mapping[str, Any] | None, where: str) -> pin.SE3:
    if d is None:
        return pin.SE3.Identity()
    r = _arr(d, "rotation", where, (3, 3))
    if not np.allclose(r @ r.T, np.eye(3), atol=1e-9) or np.linalg.det(r) < 0:
        raise FileFormatError(f"{where}: rotation is not a proper rotation matrix")
    return pin.SE3(r, _arr(d, "translation", where, (3,)))


def _point_from(d: Mapping[str, Any], where: str) -> PathPoint:
    t = d.get("type", "PathPoint")
    name, body = str(d.get("name", "")), str(d.get("body", ""))
    loc = _arr(d, "location", where, (3,))
    if t == "PathPoint":
        return PathPoint(name, body, loc)
    if t == "ConditionalPathPoint":
        r = _arr(d, "range", where, (2,))
        return ConditionalPathPoint(
            name, body, loc, coordinate=str(d["coordinate"]), range=(float(r[0]), float(r[1]))
        )
    if t == "MovingPathPoint":
        coords = tuple((c or None) for c in d["coordinates"])
        funs = tuple(
            None if f.get("type") == "None" else function_from_dict(f, f"{where} {name}")
            for f in d["functions"]
        )
        return MovingPathPoint(name, body, loc, coordinates=coords, functions=funs)  # type: ignore[arg-type]
    raise FileFormatError(f"{where}: unknown path point type {t!r}")


def load_model(path: str | Path) -> Model:
    """Read a model written by :func:`save_model` (or written by hand in the same layout); a bare
    name reads the shipped model of that name (:func:`model_file`: ``load_model("gait2392")``)."""
    path = model_file(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise FileFormatError(f"{path}: cannot read model file: {exc}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise FileFormatError(f"{path}: invalid TOML: {exc}") from exc
    head = doc.get("model")
    if not isinstance(head, dict) or head.get("format") != "msk-model":
        raise FileFormatError(f"{path}: not an msk model file (no [model] format = 'msk-model')")
    if int(head.get("format_version", 0)) > FORMAT_VERSION:
        raise FileFormatError(
            f"{path}: format_version {head.get('format_version')} is newer than {FORMAT_VERSION}"
        )
    try:
        coords = [
            Coordinate(
                c["name"],
                c.get("kind", "rotational"),
                (float(c["range"][0]), float(c["range"][1])),
                float(c.get("default", 0.0)),
                bool(c.get("locked", False)),
            )
            for c in doc.get("coordinates", [])
        ]
        bodies = [
            Body(
                b["name"],
                float(b["mass"]),
                _arr(b, "com", f"{path} body {b['name']}", (3,)),
                _arr(b, "inertia", f"{path} body {b['name']}", (3, 3)),
            )
            for b in doc.get("bodies", [])
        ]
        joints = []
        for j in doc.get("joints", []):
            where = f"{path} joint {j['name']}"
            axes = tuple(
                Axis(
                    a["kind"],
                    _arr(a, "axis", where, (3,)),
                    a.get("coordinate") or None,
                    function_from_dict(a["function"], where),
                )
                for a in j.get("axes", [])
            )
            joints.append(
                Joint(
                    j["name"],
                    j["parent"],
                    j["child"],
                    _se3_from(j.get("parent_offset"), where),
                    _se3_from(j.get("child_offset"), where),
                    axes,
                )
            )
        markers = [
            Marker(m["name"], m["body"], _arr(m, "offset", f"{path} marker {m['name']}", (3,)))
            for m in doc.get("markers", [])
        ]
        wraps = tuple(
            WrapObject(
                name=w["name"],
                body=w["body"],
                kind=w["kind"],
                translation=_arr(w, "translation", f"{path} wrap {w['name']}", (3,)),
                xyz_body_rotation=_arr(w, "xyz_body_rotation", f"{path} wrap {w['name']}", (3,)),
                radius=float(w.get("radius", 0.0)),
                length=float(w.get("length", 0.0)),
                dimensions=_arr(w, "dimensions", f"{path} wrap {w['name']}", (3,)),
                quadrant=str(w.get("quadrant", "all")),
                active=bool(w.get("active", True)),
            )
            for w in doc.get("wrap_objects", [])
        )
        muscles = []
        for m in doc.get("muscles", []):
            where = f"{path} muscle {m['name']}"
            muscles.append(
                Muscle(
                    name=m["name"],
                    points=tuple(_point_from(p, where) for p in m.get("points", [])),
                    max_isometric_force=float(m["max_isometric_force"]),
                    optimal_fiber_length=float(m["optimal_fiber_length"]),
                    tendon_slack_length=float(m["tendon_slack_length"]),
                    pennation_angle=float(m.get("pennation_angle", 0.0)),
                    max_contraction_velocity=float(m.get("max_contraction_velocity", 10.0)),
                    wraps=tuple(
                        PathWrap(
                            w["wrap_object"],
                            w.get("method", "hybrid"),
                            (int(w["range"][0]), int(w["range"][1])),
                        )
                        for w in m.get("wraps", [])
                    ),
                    kind=m.get("kind", "Muscle"),
                    extra=dict(m.get("extra", {})),
                )
            )
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise FileFormatError(f"{path}: missing or bad entry: {exc!r}") from exc
    metadata = dict(doc.get("metadata", {}))
    if wraps:
        metadata["wrap_objects"] = wraps
    try:
        return Model(
            name=str(head.get("name", path.stem)),
            bodies=bodies,
            joints=joints,
            coordinates=coords,
            markers=markers,
            muscles=muscles,
            gravity=head.get("gravity", (0.0, -9.80665, 0.0)),
            metadata=metadata,
        )
    except ModelError as exc:
        raise ModelError(f"{path}: {exc}") from exc
