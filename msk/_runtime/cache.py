"""A stage cache that never runs code from the cache folder and is never stale.

:class:`StageCache` stores the value of a pipeline stage under ``(name, key)`` in a folder
(``<results folder>/.cache``) and gives it back on a later run with the same inputs.

Format (``FORMAT``)
    One entry is two files, ``<name>-<id>.npz`` and ``<name>-<id>.json``, where ``id`` is a
    sha256 of the stage name, the key and :func:`code_fingerprint` (first 32 hex digits).

    * the ``.npz`` holds every numpy array of the value (``a0``, ``a1``, …), written with
      :func:`numpy.savez` and read with ``numpy.load(..., allow_pickle=False)``; arrays of
      objects and structured arrays are refused on both sides;
    * the ``.json`` manifest holds the structure of the value as a tree of tagged nodes
      (``null``/``true``/``false``/integers/strings as themselves, ``{"f": float.hex()}``,
      ``{"c": [re, im]}``, ``{"l": [...]}`` list, ``{"t": [...]}`` tuple, ``{"d": [[k, v], ...]}``
      dict, ``{"s": [...]}``/``{"fs": [...]}`` set/frozenset, ``{"p": [kind, text]}`` path,
      ``{"nd": i}`` array, ``{"np": i}`` numpy scalar (a 0-d array), ``{"b": i}`` bytes,
      ``{"dc": ["module:QualName", [[attribute, node], ...]]}`` dataclass instance,
      ``{"en": ["module:QualName", member]}`` enum member), the stage name, the key, the code
      fingerprint, the indices of the read-only arrays and an HMAC-SHA256 over all of it and
      the bytes of the ``.npz``, keyed with this user's secret
      (:func:`msk._runtime.secure.user_key`,
      a file outside every results folder).

    Both files are written to a temporary file and moved into place (``os.replace``), the
    ``.npz`` first: the manifest is the commit record.

What can be stored
    ``None``, bool, int, float (nan, inf, −0.0), complex, str, bytes, :class:`pathlib.Path`,
    lists, tuples (kept apart), dicts (any storable hashable keys, order kept), sets, numpy
    arrays of bool/number/string/datetime dtypes (read-only flag kept) and numpy scalars,
    **dataclass instances and enum members of classes defined in ``msk`` modules**. A dataclass
    is stored as its instance attributes (every field, also ``field(init=False)`` ones, and any
    other instance attribute, as pickle would) and rebuilt without calling ``__init__`` or
    ``__post_init__`` (``object.__new__`` + ``object.__setattr__``), so the rebuilt object has
    exactly the state that was saved. Anything else — a :class:`msk.model.core.Model`, a Pinocchio
    or
    casadi object, an object array, a class from another package — makes :meth:`StageCache.save`
    return False: the stage is computed again next time. There is no pickle fallback. (The
    model stage stores its model's plain-data state, :class:`msk.model.core.ModelState`, and builds
    the model again from it: :func:`msk.pipeline.graph.model_to_cache`.)

Threat model
    A results folder may come from someone else (a colleague, a download). Loading its cache
    must not run their code: nothing is unpickled, and the only classes the loader touches are
    dataclasses and enums that ``msk`` itself defines — the module must be ``msk`` or
    ``msk.*``, a library module (no private ``_`` module, no ``__main__``, nothing of the
    command line ``msk.cli``: a manifest naming ``msk.cli.__main__`` cannot run the program;
    imported with :func:`importlib.import_module`), the attribute must be a class
    whose ``__module__``/``__qualname__`` are the ones named (no re-exports such as ``os`` in
    an ``msk`` module), and attribute names may not be dunders. Those classes are
    instantiated without running any of their methods. Every entry is authenticated with an
    HMAC under a key only this user can read (Krawczyk, Bellare and Canetti 1997): a flipped
    byte, a truncated write, two writers racing and an entry forged by whoever wrote the
    folder (its digest recomputed from msk's own code) all fail the check, and the entry is
    deleted and the stage recomputed — a received folder's cache is never trusted, only
    recomputed. A cache folder that is a symbolic link is not used (nothing is read, written or
    pruned through it). A huge forged file can still cost memory (denial of service is out of
    scope).

Staleness
    :func:`code_fingerprint` hashes the source of every ``msk/**/*.py`` file and the package
    data (``msk/data/**``), the versions of the numerical dependencies and the Python version;
    it is part of every entry's identity and checked on load, so any change to the code or to
    a dependency makes every entry a miss.
"""

from __future__ import annotations

import contextlib
import dataclasses
import enum
import functools
import hashlib
import hmac
import importlib
import importlib.metadata as _md
import io
import json
import os
import platform
import re
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path, PurePath, PurePosixPath, PureWindowsPath
from typing import Any

import numpy as np

from msk._runtime.secure import is_real_dir, mac

__all__ = [
    "DEPENDENCIES",
    "FORMAT",
    "NotStorable",
    "StageCache",
    "code_fingerprint",
    "decode",
    "dependency_versions",
    "encode",
    "source_fingerprint",
]

FORMAT = "msk-stage-cache/2"
DEPENDENCIES = (
    "numpy",
    "scipy",
    "pin",
    "casadi",
    "daqp",
    "osqp",
    "clarabel",
    "qpsolvers",
    "ezc3d",
    "matplotlib",
)
_MAX_DEPTH = 200
_MAX_MANIFEST_BYTES = 64 << 20
_ARRAY_KINDS = frozenset("biufcUSmM")  # no objects ("O"), no structured/void ("V")
_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]{0,99}")
_ENTRY = re.compile(r"(?P<name>[A-Za-z0-9_][A-Za-z0-9_.\-]*)-(?P<id>[0-9a-f]{32})")
_LEGACY = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]*-[0-9a-f]{24}\.pkl")
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_MODULE = re.compile(r"msk(\.[A-Za-z_][A-Za-z0-9_]*)*")
_ENTRY_POINTS = (["msk", "cli"],)  # packages whose import is a program, not a library
_ORPHAN_AGE_S = 600.0  # an .npz without manifest younger than this may be a write in progress
_TEMP_AGE_S = 3600.0
_CONTAINER_TAGS: dict[type, str] = {list: "l", tuple: "t", set: "s", frozenset: "fs"}
_PATHS: dict[str, type[PurePath]] = {
    "Path": Path,
    "PurePosixPath": PurePosixPath,
    "PureWindowsPath": PureWindowsPath,
}


# ---------------------------------------------------------------------------------------------
# fingerprint of the code
# ---------------------------------------------------------------------------------------------
def _update(h: Any, data: bytes) -> None:
    """Length-prefixed update: no two different sequences of parts hash alike."""
    h.update(len(data).to_bytes(8, "big"))
    h.update(data)


def _is_source(rel: PurePath) -> bool:
    if any(p == "__pycache__" or p.startswith(".") for p in rel.parts):
        return False
    return rel.suffix == ".py" or (len(rel.parts) > 1 and rel.parts[0] == "data")


def source_fingerprint(root: str | Path) -> str:
    """sha256 over the sorted relative paths and bytes of the ``*.py`` files under ``root``
    and of the files under ``root/data`` (``__pycache__`` and hidden files are skipped)."""
    root = Path(root)
    files = sorted(
        (p.relative_to(root).as_posix(), p)
        for p in root.rglob("*")
        if p.is_file() and _is_source(p.relative_to(root))
    )
    h = hashlib.sha256()
    for rel, p in files:
        _update(h, rel.encode("utf-8", "surrogateescape"))
        _update(h, p.read_bytes())
    return h.hexdigest()


def dependency_versions() -> dict[str, str]:
    """Versions of Python and of the numerical dependencies (``"not installed"`` if absent),
    read once per process (the package metadata: the code fingerprint and the summary ask)."""
    return dict(_dependency_versions())


@functools.cache
def _dependency_versions() -> tuple[tuple[str, str], ...]:
    out = {
        "python": platform.python_version(),
        "implementation": sys.implementation.name,
        "machine": platform.machine(),
    }
    for name in DEPENDENCIES:
        try:
            out[name] = _md.version(name)
        except _md.PackageNotFoundError:
            out[name] = "not installed"
    return tuple(out.items())


@functools.cache
def code_fingerprint() -> str:
    """sha256 of the ``msk`` sources (:func:`source_fingerprint` of the package folder), the
    cache format, :func:`dependency_versions`; computed once per process."""
    root = Path(__file__).resolve().parents[1]
    text = json.dumps(
        {"format": FORMAT, "source": source_fingerprint(root), "versions": dependency_versions()},
        sort_keys=True,
    )
    return hashlib.sha256(text.encode()).hexdigest()


# ---------------------------------------------------------------------------------------------
# structure encoder / decoder
# ---------------------------------------------------------------------------------------------
class NotStorable(TypeError):
    """The value holds something the cache does not store (it is then recomputed)."""


def _class_ref(cls: type) -> str:
    return f"{cls.__module__}:{cls.__qualname__}"


def _msk_class(ref: str) -> type:
    """The class ``module:QualName`` if it is defined by an ``msk`` module (see the threat
    model); raises ValueError otherwise. Imports only ``msk`` modules."""
    if not isinstance(ref, str) or ref.count(":") != 1:
        raise ValueError(f"bad class reference {ref!r}")
    module, qualname = ref.split(":")
    if not _MODULE.fullmatch(module):
        raise ValueError(f"class {ref!r} is not from an msk module")
    parts = qualname.split(".")
    if not all(_IDENT.fullmatch(p) and not p.startswith("__") for p in parts):
        raise ValueError(f"bad class name {ref!r}")
    parts_ = module.split(".")
    if any(p.startswith("_") for p in parts_) or parts_[:2] in _ENTRY_POINTS:
        # private modules, __main__ and the command line: importing them may run code
        raise ValueError(f"class {ref!r} is not from an msk library module")
    scope: Any = importlib.import_module(module)
    cls: type | None = None
    for p in parts:  # plain namespace look-ups: no descriptor, no module __getattr__ runs
        found = vars(scope).get(p)
        if not isinstance(found, type):
            raise ValueError(f"{ref!r} is not a class")
        scope = cls = found
    if cls is None or cls.__module__ != module or cls.__qualname__ != qualname:
        raise ValueError(f"{ref!r} is not a class defined there")
    return cls


def _storable_class(cls: type) -> bool:
    try:
        return _msk_class(_class_ref(cls)) is cls
    except Exception:
        return False


class _Encoder:
    def __init__(self) -> None:
        self.arrays: list[np.ndarray] = []
        self.read_only: list[int] = []
        self._index: dict[int, int] = {}

    def array(self, a: np.ndarray, where: str) -> int:
        i = self._index.get(id(a))
        if i is not None:
            return i
        if a.dtype.hasobject or a.dtype.kind not in _ARRAY_KINDS or a.dtype.names is not None:
            raise NotStorable(f"{where}: numpy array of dtype {a.dtype} is not storable")
        i = len(self.arrays)
        self.arrays.append(a)
        self._index[id(a)] = i
        if not a.flags.writeable:
            self.read_only.append(i)
        return i

    def node(self, x: Any, where: str, depth: int) -> Any:
        if depth > _MAX_DEPTH:
            raise NotStorable(f"{where}: nested deeper than {_MAX_DEPTH} levels")
        t = type(x)
        if x is None or t is bool or t is str:
            return x
        if t is int:
            return x
        if t is float:
            return {"f": x.hex()}
        if t is complex:
            return {"c": [x.real.hex(), x.imag.hex()]}
        if t is np.ndarray:
            return {"nd": self.array(x, where)}
        if isinstance(x, np.generic):
            return {"np": self.array(np.asarray(x), where)}
        if t is bytes:
            return {"b": self.array(np.frombuffer(x, dtype=np.uint8).copy(), where)}
        tag = _CONTAINER_TAGS.get(t)
        if tag is not None:
            items = sorted(x, key=repr) if t in (set, frozenset) else x
            return {tag: [self.node(v, f"{where}[{k}]", depth + 1) for k, v in enumerate(items)]}
        if t is dict:
            return {
                "d": [
                    [self.node(k, f"{where} key {k!r}", depth + 1),
                     self.node(v, f"{where}[{k!r}]", depth + 1)]
                    for k, v in x.items()
                ]
            }  # fmt: skip
        if isinstance(x, PurePath):
            kind = "Path" if isinstance(x, Path) else t.__name__
            if kind not in _PATHS or (kind != "Path" and t is not _PATHS[kind]):
                raise NotStorable(f"{where}: path type {t.__name__} is not storable")
            return {"p": [kind, str(x)]}
        if isinstance(x, enum.Enum):
            if not _storable_class(t):
                raise NotStorable(f"{where}: enum {_class_ref(t)} is not an msk enum")
            return {"en": [_class_ref(t), x.name]}
        if dataclasses.is_dataclass(x) and not isinstance(x, type):
            return {"dc": [_class_ref(t), self.attributes(x, where, depth)]}
        raise NotStorable(f"{where}: {t.__module__}.{t.__qualname__} is not storable")

    def attributes(self, x: Any, where: str, depth: int) -> list[list[Any]]:
        t = type(x)
        if not _storable_class(t):
            raise NotStorable(f"{where}: dataclass {_class_ref(t)} is not defined by msk")
        names = [f.name for f in dataclasses.fields(x)]
        state: dict[str, Any] = {n: getattr(x, n) for n in names if hasattr(x, n)}
        for n, v in getattr(x, "__dict__", {}).items():  # e.g. functools.cached_property
            state.setdefault(n, v)
        out = []
        for n, v in state.items():
            if not isinstance(n, str) or not _IDENT.fullmatch(n) or n.startswith("__"):
                raise NotStorable(f"{where}: attribute {n!r} is not storable")
            out.append([n, self.node(v, f"{where}.{n}", depth + 1)])
        return out


def encode(value: Any) -> tuple[Any, list[np.ndarray], list[int]]:
    """The JSON tree of ``value``, its arrays and the indices of the read-only ones.

    Raises:
        NotStorable: something in ``value`` is not storable (names where).
    """
    enc = _Encoder()
    tree = enc.node(value, "value", 0)
    return tree, enc.arrays, enc.read_only


def _float(text: Any) -> float:
    if not isinstance(text, str):
        raise ValueError(f"bad float {text!r}")
    return float.fromhex(text)


def decode(tree: Any, arrays: list[np.ndarray]) -> Any:
    """The value of an :func:`encode` tree (ValueError/TypeError/KeyError on a bad tree)."""
    return _decode(tree, arrays, 0)


def _decode(n: Any, arrays: list[np.ndarray], depth: int) -> Any:
    if depth > _MAX_DEPTH:
        raise ValueError("tree too deep")
    if n is None or type(n) in (bool, int, str):
        return n
    if type(n) is not dict or len(n) != 1:
        raise ValueError(f"bad node {str(n)[:80]}")
    ((tag, v),) = n.items()
    if tag == "f":
        return _float(v)
    if tag == "c":
        re_, im = v
        return complex(_float(re_), _float(im))
    if tag in ("nd", "np", "b"):
        if type(v) is not int or not 0 <= v < len(arrays):
            raise ValueError(f"bad array index {v!r}")
        a = arrays[v]
        if tag == "nd":
            return a
        if tag == "b":
            if a.dtype != np.uint8 or a.ndim != 1:
                raise ValueError("bad bytes array")
            return a.tobytes()
        if a.ndim != 0:
            raise ValueError("numpy scalar is not a 0-d array")
        return a[()]
    if tag in ("l", "t", "s", "fs"):
        if type(v) is not list:
            raise ValueError(f"bad {tag} node")
        items = [_decode(x, arrays, depth + 1) for x in v]
        return {"l": list, "t": tuple, "s": set, "fs": frozenset}[tag](items)
    if tag == "d":
        if type(v) is not list:
            raise ValueError("bad dict node")
        out: dict[Any, Any] = {}
        for pair in v:
            k, x = pair
            out[_decode(k, arrays, depth + 1)] = _decode(x, arrays, depth + 1)
        return out
    if tag == "p":
        kind, text = v
        if not isinstance(kind, str) or kind not in _PATHS or not isinstance(text, str):
            raise ValueError(f"bad path node {str(v)[:80]}")
        return _PATHS[kind](text)
    if tag == "en":
        ref, member = v
        cls = _msk_class(ref)
        if not issubclass(cls, enum.Enum) or not isinstance(member, str):
            raise ValueError(f"{ref!r} is not an enum")
        return cls.__members__[member]
    if tag == "dc":
        ref, attrs = v
        cls = _msk_class(ref)
        if not dataclasses.is_dataclass(cls) or issubclass(cls, enum.Enum):
            raise ValueError(f"{ref!r} is not a dataclass")
        if type(attrs) is not list:
            raise ValueError("bad dataclass node")
        obj = object.__new__(cls)
        seen: set[str] = set()
        for pair in attrs:
            name, x = pair
            if not isinstance(name, str) or not _IDENT.fullmatch(name) or name.startswith("__"):
                raise ValueError(f"bad attribute name {str(name)[:80]!r}")
            object.__setattr__(obj, name, _decode(x, arrays, depth + 1))
            seen.add(name)
        missing = [f.name for f in dataclasses.fields(cls) if f.init and f.name not in seen]
        if missing:
            raise ValueError(f"{ref}: missing fields {missing}")
        return obj
    raise ValueError(f"unknown node tag {tag!r}")


# ---------------------------------------------------------------------------------------------
# entries on disk
# ---------------------------------------------------------------------------------------------
def _digest(manifest: dict[str, Any], payload: bytes) -> str:
    """HMAC-SHA256 of the manifest (but its ``mac``) and the payload under the user's key."""
    body = {k: v for k, v in manifest.items() if k != "mac"}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return mac(FORMAT, text, payload)


def _read_arrays(payload: bytes, n: int) -> list[np.ndarray]:
    if n == 0:
        return []
    with np.load(io.BytesIO(payload), allow_pickle=False) as npz:
        names = [f"a{i}" for i in range(n)]
        if sorted(npz.files) != sorted(names):
            raise ValueError("the .npz does not hold the arrays the manifest names")
        out = [npz[k] for k in names]
    for a in out:
        if type(a) is not np.ndarray or a.dtype.hasobject or a.dtype.kind not in _ARRAY_KINDS:
            raise ValueError(f"array of dtype {a.dtype} in the .npz")
    return out


def _atomic_write(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


class StageCache:
    """Stage values under ``(name, key)`` in ``folder`` (see the module docstring).

    ``load`` → ``(True, value)`` on a hit, ``(False, None)`` on a miss or a bad entry (deleted;
    never raises for one). ``save`` → False when the value is not storable or cannot be
    written (the stage is computed again next time); it then removes the other entries of
    the stage and keeps the folder to the newest ``max_entries`` entries. ``last_reason`` says
    why the last ``load``/``save`` did not hit/store ("" otherwise).

    ``fingerprint`` (default :func:`code_fingerprint`) is part of every entry's identity.
    """

    def __init__(
        self, folder: str | Path, *, max_entries: int = 200, fingerprint: str | None = None
    ) -> None:
        if max_entries < 1:
            raise ValueError(f"max_entries must be ≥ 1, got {max_entries}")
        self.folder = Path(folder)
        self.max_entries = int(max_entries)
        self.fingerprint = code_fingerprint() if fingerprint is None else str(fingerprint)
        self.last_reason = ""

    # ------------------------------------------------------------------ naming
    def entry_id(self, name: str, key: str) -> str:
        """32 hex digits naming the entry of ``(name, key)`` under this fingerprint."""
        if not isinstance(name, str) or not _NAME.fullmatch(name):
            raise ValueError(f"bad stage name {name!r} (letters, digits, _ . -)")
        if not isinstance(key, str):
            raise TypeError(f"key must be a str, got {type(key).__name__}")
        h = hashlib.sha256()
        for part in (FORMAT, name, key, self.fingerprint):
            _update(h, part.encode("utf-8", "surrogatepass"))
        return h.hexdigest()[:32]

    def paths(self, name: str, key: str) -> tuple[Path, Path]:
        """The ``(.json manifest, .npz)`` files of the entry of ``(name, key)``."""
        stem = f"{name}-{self.entry_id(name, key)}"
        return self.folder / f"{stem}.json", self.folder / f"{stem}.npz"

    # ------------------------------------------------------------------ load / save
    def load(self, name: str, key: str) -> tuple[bool, Any]:
        manifest_path, npz_path = self.paths(name, key)
        self.last_reason = ""
        if os.path.lexists(self.folder) and not is_real_dir(self.folder):
            self.last_reason = f"{self.folder} is not a folder (a symbolic link?): not used"
            return False, None
        if not manifest_path.is_file():
            self.last_reason = "no entry"
            return False, None
        try:
            raw = manifest_path.read_bytes()
            if len(raw) > _MAX_MANIFEST_BYTES:
                raise ValueError("manifest too large")
            manifest = json.loads(raw)
            if type(manifest) is not dict:
                raise ValueError("manifest is not an object")
            expected = {
                "format": FORMAT,
                "name": name,
                "key": key,
                "fingerprint": self.fingerprint,
                "payload": npz_path.name,
            }
            for k, v in expected.items():
                if manifest.get(k) != v:
                    raise ValueError(f"manifest {k} mismatch")
            payload = npz_path.read_bytes()
            tag = manifest.get("mac")
            if not isinstance(tag, str) or not hmac.compare_digest(tag, _digest(manifest, payload)):
                raise ValueError("checksum (HMAC) mismatch: written elsewhere, or altered")
            n, read_only = manifest["arrays"], manifest["read_only"]
            if type(n) is not int or type(read_only) is not list:
                raise ValueError("bad array list")
            arrays = _read_arrays(payload, n)
            for i in read_only:
                arrays[i].setflags(write=False)
            value = decode(manifest["tree"], arrays)
        except Exception as exc:
            self.last_reason = f"bad cache entry {manifest_path.name} ({type(exc).__name__}: {exc})"
            self._remove(manifest_path.stem)
            return False, None
        with contextlib.suppress(OSError):
            os.utime(manifest_path)  # recently used: kept by prune
        return True, value

    def save(self, name: str, key: str, value: Any) -> bool:
        manifest_path, npz_path = self.paths(name, key)
        self.last_reason = ""
        stored = False
        try:
            tree, arrays, read_only = encode(value)
            buf = io.BytesIO()
            members: dict[str, Any] = {f"a{i}": a for i, a in enumerate(arrays)}
            np.savez(buf, **members)
            payload = buf.getvalue()
            manifest: dict[str, Any] = {
                "format": FORMAT,
                "name": name,
                "key": key,
                "fingerprint": self.fingerprint,
                "payload": npz_path.name,
                "arrays": len(arrays),
                "read_only": read_only,
                "tree": tree,
            }
            manifest["mac"] = _digest(manifest, payload)
            text = json.dumps(manifest, allow_nan=False, separators=(",", ":"))
            self.folder.mkdir(parents=True, exist_ok=True)
            if not is_real_dir(self.folder):
                raise NotStorable(f"{self.folder} is not a folder (a symbolic link?)")
            _atomic_write(npz_path, payload)
            _atomic_write(manifest_path, text.encode())
            stored = True
        except NotStorable as exc:
            self.last_reason = f"not cached: {exc}"
        except (OSError, ValueError, TypeError, RecursionError) as exc:
            self.last_reason = f"not cached: {type(exc).__name__}: {exc}"
            self._remove(manifest_path.stem)
        self._drop_stage(name, keep=manifest_path.stem if stored else None)
        self.prune()
        return stored

    # ------------------------------------------------------------------ housekeeping
    def _files(self) -> Iterator[Path]:
        if not is_real_dir(self.folder):
            return
        try:
            yield from (p for p in self.folder.iterdir() if p.is_file())
        except OSError:
            return

    def _remove(self, stem: str) -> None:
        for suffix in (".json", ".npz"):
            with contextlib.suppress(OSError):
                (self.folder / f"{stem}{suffix}").unlink(missing_ok=True)

    def _drop_stage(self, name: str, keep: str | None) -> None:
        """Remove the entries of stage ``name`` other than ``keep`` (stale keys)."""
        for p in self._files():
            m = _ENTRY.fullmatch(p.stem)
            if m and m["name"] == name and p.suffix in (".json", ".npz") and p.stem != keep:
                with contextlib.suppress(OSError):
                    p.unlink(missing_ok=True)

    def prune(self) -> int:
        """Keep the newest ``max_entries`` entries (by last use); remove ``.npz`` files without
        manifest, abandoned temporary files and the pickle files of the old cache. Returns the
        number of files removed."""
        now = time.time()
        manifests: list[tuple[float, str]] = []
        npz: dict[str, Path] = {}
        doomed: list[Path] = []
        for p in self._files():
            try:
                mtime = p.stat().st_mtime
            except OSError:
                continue
            if _ENTRY.fullmatch(p.stem) and p.suffix == ".json":
                manifests.append((mtime, p.stem))
            elif _ENTRY.fullmatch(p.stem) and p.suffix == ".npz":
                if now - mtime > _ORPHAN_AGE_S:
                    npz[p.stem] = p
            elif p.name.startswith(".") and p.name.endswith(".tmp"):
                if now - mtime > _TEMP_AGE_S:
                    doomed.append(p)
            elif _LEGACY.fullmatch(p.name):  # pickles: never loaded, never kept
                doomed.append(p)
        manifests.sort(reverse=True)
        live = {stem for _, stem in manifests[: self.max_entries]}
        for _, stem in manifests[self.max_entries :]:
            doomed += [self.folder / f"{stem}.json", self.folder / f"{stem}.npz"]
        doomed += [p for stem, p in npz.items() if stem not in live]
        removed = 0
        for p in doomed:
            try:
                if p.exists():
                    p.unlink()
                    removed += 1
            except OSError:
                pass
        return removed
