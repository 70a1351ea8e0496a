"""Stage cache (msk._runtime.cache): exact round trips, no code from the cache folder ever runs, bad
entries are recomputed, code changes invalidate, old entries do not pile up."""

from __future__ import annotations

import builtins
import dataclasses
import enum
import importlib
import io
import json
import math
import os
import pickle
import re
import subprocess
import sys
import time
import types
from collections import OrderedDict
from pathlib import Path, PurePosixPath, PureWindowsPath
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import msk._runtime.cache as mc
from msk._runtime.cache import StageCache, code_fingerprint, decode, encode, source_fingerprint

DATA = Path(__file__).resolve().parents[2] / "data"
FP = "f" * 64  # a fixed fingerprint: the tests do not depend on the sources


@pytest.fixture
def cache(tmp_path: Path) -> StageCache:
    return StageCache(tmp_path / ".cache", fingerprint=FP)


# ---------------------------------------------------------------------------------------------
# exact equality: same types all the way down, arrays bitwise (dtype, shape, bytes, read-only)
# ---------------------------------------------------------------------------------------------
def same(a: Any, b: Any, where: str = "value") -> None:
    assert type(a) is type(b), f"{where}: {type(a)} != {type(b)}"
    if isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape, f"{where}: {a.dtype}{a.shape}"
        assert a.tobytes() == b.tobytes(), f"{where}: array bytes differ"
        if a.dtype.kind in "fc":
            assert np.array_equal(a, b, equal_nan=True), where
        assert a.flags.writeable == b.flags.writeable, f"{where}: read-only flag"
    elif isinstance(a, np.generic):
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), where
    elif isinstance(a, float):
        assert a.hex() == b.hex(), f"{where}: {a!r} != {b!r}"
    elif isinstance(a, complex):
        same(a.real, b.real, where)
        same(a.imag, b.imag, where)
    elif isinstance(a, list | tuple):
        assert len(a) == len(b), where
        for k, (x, y) in enumerate(zip(a, b)):
            same(x, y, f"{where}[{k}]")
    elif isinstance(a, dict):
        assert list(a) == list(b), f"{where}: keys {list(a)} != {list(b)}"
        for k in a:
            same(a[k], b[k], f"{where}[{k!r}]")
    elif dataclasses.is_dataclass(a):
        names = [f.name for f in dataclasses.fields(a) if hasattr(a, f.name)]
        names += [n for n in getattr(a, "__dict__", {}) if n not in names]
        for k in names:
            same(getattr(a, k), getattr(b, k), f"{where}.{k}")
        assert getattr(a, "__dict__", {}).keys() == getattr(b, "__dict__", {}).keys(), where
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


def round_trip(cache: StageCache, value: Any, name: str = "stage") -> Any:
    assert cache.save(name, "key", value), cache.last_reason
    ok, back = cache.load(name, "key")
    assert ok, cache.last_reason
    same(value, back)
    return back


# ---------------------------------------------------------------------------------------------
# every supported kind
# ---------------------------------------------------------------------------------------------
def test_every_supported_kind_round_trips_exactly(cache):
    shared = np.arange(6.0).reshape(2, 3)
    ro = np.linspace(0.0, 1.0, 5)
    ro.setflags(write=False)
    value = {
        "none": None,
        "bools": [True, False],
        "ints": (0, -1, 2**70, -(2**64)),
        "floats": [1.5, -0.0, 0.0, math.nan, math.inf, -math.inf, 5e-324, 1.7976931348623157e308],
        "complex": 1.5 - 2j,
        "str": "ünïcødé \udcff ∂l/∂θ",
        "bytes": b"\x00\xffabc",
        "paths": (Path("/data/PS.c3d"), PurePosixPath("a/b"), PureWindowsPath(r"C:\x\y.trc")),
        "tuple vs list": ((), [], ((1,), [2]), [(3.0,)]),
        "keys": {1: "int", (2, "a"): "tuple", 2.5: "float", None: "none", "s": "str"},
        "sets": ({1, 2, 3}, frozenset({"a", "b"})),
        "arrays": [
            np.array([1.0, np.nan, -0.0, np.inf]),
            np.arange(5, dtype=np.float32),
            np.array([-3, 4], dtype=np.int8),
            np.array([7], dtype=np.uint16),
            np.array([True, False]),
            np.array([1 + 2j], dtype=np.complex128),
            np.array(["ab", "cdé"]),
            np.array([b"x", b"yz"]),
            np.array(["2020-01-01"], dtype="datetime64[D]"),
            np.array(3.25),
            np.zeros((0, 3)),
            np.asfortranarray(np.arange(12.0).reshape(3, 4)),
            np.arange(20.0)[::3],
            np.array([1.0, 2.0], dtype=">f8"),
            ro,
        ],
        "scalars": (
            np.float64(2.5),
            np.float32(np.nan),
            np.int32(-7),
            np.bool_(True),
            np.str_("s"),
        ),
        "shared": (shared, shared),
    }
    back = round_trip(cache, value)
    assert back["shared"][0] is back["shared"][1]  # one array, stored once
    assert back["arrays"][11].flags.f_contiguous


def _json_scalars() -> st.SearchStrategy[Any]:
    return st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8)


def _arrays() -> st.SearchStrategy[np.ndarray]:
    dtypes = st.sampled_from([np.float64, np.float32, np.int64, np.int16, np.uint8, np.bool_])
    return hnp.arrays(dtypes, hnp.array_shapes(min_dims=0, max_dims=3, max_side=4))


VALUES = st.recursive(
    _json_scalars() | _arrays(),
    lambda inner: (
        st.lists(inner, max_size=4)
        | st.lists(inner, max_size=4).map(tuple)
        | st.dictionaries(st.text(max_size=6), inner, max_size=4)
    ),
    max_leaves=20,
)


@settings(max_examples=60, deadline=None)
@given(value=VALUES)
def test_property_nested_containers_of_floats_and_arrays_round_trip(value, tmp_path_factory):
    cache = StageCache(tmp_path_factory.mktemp("c"), fingerprint=FP)
    round_trip(cache, value)
    tree, arrays, _ = encode(value)
    same(value, decode(json.loads(json.dumps(tree)), arrays))


# ---------------------------------------------------------------------------------------------
# the project's stage values
# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def trial():
    from msk.io import read_c3d

    return read_c3d(DATA / "gc5-PS" / "PS_ngait_og_ss1.c3d")


@pytest.fixture(scope="module")
def synthetic():
    from msk.datasets.models import two_leg_model
    from msk.datasets.trials import make_trial
    from msk.dynamics.loads import external_loads
    from msk.kinematics.ik import solve_kinematics

    model = two_leg_model()
    tr = make_trial(model, duration_s=0.3, rate_hz=100.0, analog_ratio=2)
    kin = solve_kinematics(model, tr.markers, tr.marker_labels, tr.time, cutoff_hz=None)
    return model, tr, kin, external_loads(model, kin, tr.plates)


def test_read_stage_with_a_real_c3d_trial(cache, trial):
    from msk.trial import ForcePlate, Trial

    assert trial.plates and isinstance(trial.plates[0], ForcePlate)
    back = round_trip(cache, {"trial": trial}, "read")
    assert isinstance(back["trial"], Trial)
    np.testing.assert_array_equal(back["trial"].rotated(np.eye(3)).markers, trial.markers)


def test_kinematics_and_external_loads_with_assignments(cache, synthetic):
    from msk.dynamics.loads import Assignment, ExternalLoads
    from msk.kinematics.ik import Kinematics

    _, _, kin, ext = synthetic
    assert isinstance(kin, Kinematics) and isinstance(ext, ExternalLoads)
    assert ext.assignments and all(isinstance(a, Assignment) for a in ext.assignments)
    back = round_trip(cache, kin, "kinematics")
    assert back.coordinate_names == kin.coordinate_names
    back = round_trip(cache, ext, "loads")
    np.testing.assert_array_equal(back.flagged(), ext.flagged())


def test_inverse_dynamics_and_muscle_geometry_with_init_false_fields(cache, synthetic):
    from msk.datasets.models import leg_model
    from msk.dynamics.inverse import inverse_dynamics
    from msk.model.joints import SimmSpline
    from msk.muscles.geometry import MuscleGeometry, muscle_geometry
    from msk.muscles.path import MovingPathPoint, Muscle, PathPoint

    model, _, kin, ext = synthetic
    round_trip(cache, {"generic": inverse_dynamics(model, kin, ext)}, "inverse_dynamics")
    spline = SimmSpline((-2.0, -1.0, 0.0, 0.1), (0.02, 0.03, 0.04, 0.04))  # _b/_c/_d: init=False
    muscles = [
        Muscle(
            "rect_fem",
            (
                PathPoint("o", "pelvis", np.array([-0.03, -0.03, 0.097])),
                MovingPathPoint(
                    "p", "tibia", np.array([0.04, 0.02, 0.0015]),
                    coordinates=("knee_angle", None, None), functions=(spline, None, None),
                ),
            ),
            1000.0, 0.1, 0.2, 0.1, 10.0,
        )
    ]  # fmt: skip
    leg = leg_model().with_muscles(muscles)
    q = np.tile(leg.default_coordinates(), (4, 1))
    geo = muscle_geometry(leg, q, np.zeros_like(q))
    assert isinstance(geo, MuscleGeometry)
    round_trip(cache, geo, "muscle_geometry")
    back = round_trip(cache, muscles, "muscles")
    fn = back[0].points[1].functions[0]
    assert fn(-0.5) == spline(-0.5)  # rebuilt spline works (its init=False coefficients came back)


def test_measured_contact_strength_profile_and_tlem_read_only_arrays(cache):
    from msk.datasets.strength import gait_trial, synthetic_leg
    from msk.io.contact_force import MeasuredContact, read_measured_contact
    from msk.muscles.activation import emg_to_activation
    from msk.muscles.hill import rigid_tendon_state
    from msk.muscles.tlem import load_tlem2
    from msk.strength import StrengthIdentifier
    from msk.strength.identification import StrengthProfile

    contact = read_measured_contact(DATA / "gc6-DM" / "DM_ngait_og1_contact.csv")
    assert isinstance(contact, MeasuredContact)
    round_trip(cache, {"contact": contact}, "read")

    leg = synthetic_leg(0)
    tr = gait_trial(leg, n_cycles=4, seed=0)
    a = emg_to_activation(
        tr.emg, gamma1=-0.5, gamma2=-0.5, shape_factor=-1.0, delay_samples=4, form="exponential"
    )
    s = rigid_tendon_state(leg.params, tr.muscle_tendon_length, tr.lengthening_velocity)
    idf = StrengthIdentifier(leg.groups, leg.params, n_bootstrap=0)
    profile = idf.fit(tr.jacobian, a, tr.tau, s, windows=tr.cycle).profile_
    assert isinstance(profile, StrengthProfile)
    back = round_trip(cache, {"profile": profile, "groups": {"g": ["a"]}, "t0": 0.25}, "strength")
    assert back["profile"].table() == profile.table()

    tlem = load_tlem2()
    assert not tlem.pcsa.flags.writeable
    back = round_trip(cache, tlem, "tlem")
    assert not back.pcsa.flags.writeable


# ---------------------------------------------------------------------------------------------
# not storable → save returns False, nothing written, never a pickle
# ---------------------------------------------------------------------------------------------
class _Str(str):
    pass


@pytest.mark.parametrize(
    "value, culprit",
    [
        (lambda: {"model": _model(), "info": {"mass_kg": 70.0}}, "msk.model.core.Model"),
        (lambda: {"pin": pin.Model()}, "Model"),
        (lambda: [np.array([object()], dtype=object)], "dtype object"),
        (lambda: np.zeros(2, dtype=[("a", "f8")]), "not storable"),
        (lambda: {"x": _Str("s")}, "_Str"),
        (lambda: OrderedDict(a=1), "OrderedDict"),
        (lambda: {"synthetic": _synthetic_dataclass()}, "not defined by msk"),
        (lambda: {"casadi": _casadi()}, "casadi"),
        (lambda: {"f": print}, "builtin"),
        (lambda: np.ma.masked_array([1.0]), "MaskedArray"),
    ],
)
def test_values_that_are_not_storable_are_refused_without_a_pickle(cache, value, culprit):
    assert not cache.save("stage", "key", value())
    assert culprit in cache.last_reason
    assert not cache.folder.exists() or not any(cache.folder.iterdir())
    assert cache.load("stage", "key") == (False, None)


def _model() -> Any:
    from msk.datasets.models import two_leg_model

    return two_leg_model()


def _synthetic_dataclass() -> Any:
    from msk.datasets.trials import plate_corners
    from msk.dynamics.loads import PlateWrench

    @dataclasses.dataclass
    class Local:  # a dataclass of a test module, not of msk
        x: float

    return [PlateWrench("p", np.zeros(1), np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 3)),
                        plate_corners(np.zeros(3))), Local(1.0)]  # fmt: skip


def _casadi() -> Any:
    import casadi

    return casadi.SX.sym("x")


def test_a_cycle_is_not_storable(cache):
    x: list[Any] = []
    x.append(x)
    assert not cache.save("stage", "key", x)
    assert "deeper" in cache.last_reason


def test_save_to_an_unusable_folder_returns_false(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    assert not StageCache(blocker, fingerprint=FP).save("stage", "key", {"a": 1.0})


# ---------------------------------------------------------------------------------------------
# msk enums and dataclass variants (moved into a stand-in msk module by a fixture)
# ---------------------------------------------------------------------------------------------
class Colour(enum.Enum):
    RED = "red"
    BLUE = 2


@dataclasses.dataclass(frozen=True, slots=True)
class Slotted:
    a: float
    b: tuple[int, ...] = ()


@dataclasses.dataclass
class Mutable:
    x: np.ndarray
    derived: float = dataclasses.field(init=False)

    def __post_init__(self) -> None:
        self.derived = float(self.x.sum())
        self.posts = getattr(self, "posts", 0) + 1  # not a field: kept like pickle keeps it


@pytest.fixture
def msk_test_module(monkeypatch):
    mod = types.ModuleType("msk.cache_test_types")  # a library module's name (not private)
    for cls in (Colour, Slotted, Mutable):
        monkeypatch.setattr(cls, "__module__", mod.__name__)
        setattr(mod, cls.__qualname__, cls)
    monkeypatch.setitem(sys.modules, mod.__name__, mod)
    return mod


def test_msk_enums_slots_and_init_false_dataclasses_round_trip(cache, msk_test_module):
    m = Mutable(np.array([1.0, 2.0]))
    value = {"c": [Colour.RED, Colour.BLUE], "s": Slotted(1.5, (1, 2)), "m": m}
    back = round_trip(cache, value)
    assert back["c"][0] is Colour.RED
    assert back["m"].derived == 3.0 and back["m"].posts == 1  # __post_init__ did not run again


# ---------------------------------------------------------------------------------------------
# poisoned entries: never executed, deleted
# ---------------------------------------------------------------------------------------------
def forge(cache: StageCache, name: str, key: str, tree: Any, payload: bytes, n: int) -> Path:
    """Write an entry with a valid MAC, as an attacker holding the user's key could (the
    decoder's own defences, behind the MAC)."""
    manifest_path, npz_path = cache.paths(name, key)
    cache.folder.mkdir(parents=True, exist_ok=True)
    npz_path.write_bytes(payload)
    manifest: dict[str, Any] = {
        "format": mc.FORMAT,
        "name": name,
        "key": key,
        "fingerprint": cache.fingerprint,
        "payload": npz_path.name,
        "arrays": n,
        "read_only": [],
        "tree": tree,
    }
    manifest["mac"] = mc._digest(manifest, payload)
    manifest_path.write_text(json.dumps(manifest))
    return manifest_path


def _npz(**arrays: Any) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


class _Boom:
    """Unpickling this creates a folder: the proof that pickle ran."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple[Any, ...]:
        return (os.mkdir, (str(self.marker),))


@pytest.fixture
def spies(monkeypatch):
    """Spies on os.system, subprocess.Popen, eval and importlib.import_module. The msk modules
    the poisoned trees name are imported first: importing one runs Python's own eval (a
    NamedTuple's ``__new__``, ``typing.get_type_hints`` of the config dataclasses), which is
    not the loader's doing — a test run alone would otherwise import ``msk.pipeline`` under
    the spies and see those calls (the whole suite had imported it already)."""
    for module in sorted(set(re.findall(r'"(msk(?:\.[a-z_0-9]+)*):', json.dumps(POISON)))):
        importlib.import_module(module)
    calls: list[str] = []
    imported: list[str] = []
    real_import = importlib.import_module

    def spy(label: str) -> Any:
        def f(*args: Any, **kwargs: Any) -> Any:
            calls.append(label)
            raise AssertionError(f"{label} was called")

        return f

    def import_spy(name: str, package: str | None = None) -> Any:
        imported.append(name)
        return real_import(name, package)

    monkeypatch.setattr(os, "system", spy("os.system"))
    monkeypatch.setattr(subprocess, "Popen", spy("subprocess.Popen"))
    monkeypatch.setattr(builtins, "eval", spy("eval"))
    monkeypatch.setattr(importlib, "import_module", import_spy)
    return calls, imported


POISON = [
    {"dc": ["os:system", [["command", "touch /tmp/pwned"]]]},
    {"dc": ["builtins:eval", []]},
    {"dc": ["subprocess:Popen", [["args", ["touch", "/tmp/pwned"]]]]},
    {"dc": ["msk.model.core:Model", []]},  # an msk class, but not a dataclass
    {"dc": ["msk.io.c3d:Path", []]},  # a class an msk module imports from elsewhere
    {"dc": ["msk.pipeline:os.system", []]},  # through a module an msk module imports
    {"dc": ["msk.pipeline:subprocess.Popen", []]},
    {"dc": ["msk.trial:Event.__init__", []]},
    {"dc": ["mskevil:Thing", []]},
    {"dc": ["msk..io:Trial", []]},
    {"dc": ["msk.trial:Event", [["__class__", None]]]},  # dunder attribute
    {"dc": ["msk.trial:Event", [["label", "x"]]]},  # missing fields
    {"en": ["os:system", "x"]},
    {"en": ["msk.trial:Event", "label"]},
    {"l": [{"nd": 5}]},  # no such array
    {"x": 1},
    [1, 2],
]


@pytest.mark.parametrize("tree", POISON, ids=[json.dumps(t)[:40] for t in POISON])
def test_a_poisoned_manifest_is_never_executed_and_is_deleted(cache, spies, tree):
    calls, imported = spies
    manifest = forge(cache, "read", "k", tree, b"", 0)
    assert cache.load("read", "k") == (False, None)
    assert "bad cache entry" in cache.last_reason
    assert calls == []
    assert all(n == "msk" or n.startswith("msk.") for n in imported), imported
    assert not manifest.exists() and not manifest.with_suffix(".npz").exists()
    assert not Path("/tmp/pwned").exists()


def test_an_object_array_in_the_npz_is_never_unpickled(cache, tmp_path, spies):
    marker = tmp_path / "unpickled"
    payload = _npz(a0=np.array([_Boom(marker)], dtype=object))
    assert pickle.loads(pickle.dumps(_Boom(tmp_path / "check"))) is None  # the payload is live
    assert (tmp_path / "check").is_dir()
    forge(cache, "read", "k", {"nd": 0}, payload, 1)
    assert cache.load("read", "k") == (False, None)
    assert not marker.exists()
    assert not list(cache.folder.glob("read-*"))


def test_a_legacy_pickle_is_never_loaded_and_is_removed(cache, tmp_path):
    marker = tmp_path / "unpickled"
    cache.folder.mkdir(parents=True)
    legacy = cache.folder / f"read-{'0' * 24}.pkl"
    legacy.write_bytes(pickle.dumps(_Boom(marker)))
    assert cache.load("read", "k") == (False, None)
    assert cache.save("read", "k", {"a": 1.0})
    assert not legacy.exists() and not marker.exists()


# ---------------------------------------------------------------------------------------------
# corrupted entries are recomputed
# ---------------------------------------------------------------------------------------------
def _entry(cache: StageCache, value: Any) -> tuple[Path, Path]:
    assert cache.save("kinematics", "k", value)
    return cache.paths("kinematics", "k")


def test_a_flipped_byte_in_the_npz_is_a_miss_and_the_entry_is_deleted(cache):
    manifest, npz = _entry(cache, {"q": np.linspace(0.0, 1.0, 1000)})
    raw = bytearray(npz.read_bytes())
    raw[len(raw) // 2] ^= 0x01
    npz.write_bytes(bytes(raw))
    assert cache.load("kinematics", "k") == (False, None)
    assert "checksum" in cache.last_reason
    assert not manifest.exists() and not npz.exists()
    assert cache.save("kinematics", "k", {"q": np.zeros(3)})  # recomputed and stored again
    assert cache.load("kinematics", "k")[0]


def test_a_changed_number_in_the_manifest_is_caught_by_the_checksum(cache):
    manifest, _ = _entry(cache, {"mass_kg": 70.0, "q": np.zeros(3)})
    text = manifest.read_text()
    forged = text.replace((70.0).hex(), (71.0).hex())
    assert forged != text
    manifest.write_text(forged)
    assert cache.load("kinematics", "k") == (False, None)
    assert "checksum" in cache.last_reason


@pytest.mark.parametrize(
    "damage",
    [
        lambda m, n: n.unlink(),
        lambda m, n: n.write_bytes(n.read_bytes()[:50]),
        lambda m, n: m.write_text(m.read_text()[:-10]),
        lambda m, n: m.write_text("[]"),
        lambda m, n: m.write_bytes(b"\xff\xfe garbage"),
        lambda m, n: m.write_text(m.read_text().replace('"key":"k"', '"key":"other"')),
        lambda m, n: m.write_text(m.read_text().replace(FP, "0" * 64)),
    ],
)
def test_missing_truncated_or_mismatched_entries_are_misses(cache, damage):
    manifest, npz = _entry(cache, {"q": np.arange(4.0)})
    damage(manifest, npz)
    assert cache.load("kinematics", "k") == (False, None)
    assert not manifest.exists()


# ---------------------------------------------------------------------------------------------
# a source change invalidates
# ---------------------------------------------------------------------------------------------
def test_source_fingerprint_follows_the_sources_and_data_only(tmp_path):
    root = tmp_path / "pkg"
    (root / "sub").mkdir(parents=True)
    (root / "data").mkdir()
    (root / "__pycache__").mkdir()
    (root / "a.py").write_text("x = 1\n")
    (root / "sub" / "b.py").write_text("y = 2\n")
    (root / "data" / "table.csv").write_text("1,2\n")
    fp0 = source_fingerprint(root)
    assert source_fingerprint(root) == fp0

    (root / "__pycache__" / "a.cpython-311.pyc").write_bytes(b"\0")
    (root / "notes.txt").write_text("ignored")
    assert source_fingerprint(root) == fp0

    (root / "a.py").write_text("x = 2\n")
    fp1 = source_fingerprint(root)
    assert fp1 != fp0
    (root / "a.py").write_text("x = 1\n")
    assert source_fingerprint(root) == fp0  # content, not mtime

    (root / "data" / "table.csv").write_text("1,3\n")
    assert source_fingerprint(root) != fp0
    (root / "data" / "table.csv").write_text("1,2\n")
    (root / "sub" / "b.py").rename(root / "sub" / "c.py")
    assert source_fingerprint(root) != fp0
    (root / "sub" / "c.py").rename(root / "sub" / "b.py")
    (root / "new.py").write_text("")
    assert source_fingerprint(root) != fp0


def test_code_fingerprint_covers_the_msk_sources_and_versions(monkeypatch, tmp_path):
    fp = code_fingerprint()
    assert fp == code_fingerprint() and len(fp) == 64
    root = Path(mc.__file__).resolve().parents[1]
    seen: list[Path] = []

    def fake_source(r: Path) -> str:
        seen.append(Path(r))
        return "changed sources"

    code_fingerprint.cache_clear()
    try:
        monkeypatch.setattr(mc, "source_fingerprint", fake_source)
        changed = code_fingerprint()
        assert seen == [root] and changed != fp
        code_fingerprint.cache_clear()
        monkeypatch.setattr(mc, "source_fingerprint", source_fingerprint)
        monkeypatch.setattr(mc, "dependency_versions", lambda: {"numpy": "0.0"})
        assert code_fingerprint() not in (fp, changed)
    finally:
        code_fingerprint.cache_clear()
        monkeypatch.undo()
    assert code_fingerprint() == fp
    versions = mc.dependency_versions()
    assert set(mc.DEPENDENCIES) <= set(versions) and versions["numpy"] == np.__version__


def test_an_entry_of_other_code_is_a_miss(tmp_path):
    old = StageCache(tmp_path, fingerprint="old code")
    assert old.save("kinematics", "k", {"q": 1.0})
    new = StageCache(tmp_path, fingerprint="new code")
    assert new.load("kinematics", "k") == (False, None)
    assert StageCache(tmp_path).fingerprint == code_fingerprint()


# ---------------------------------------------------------------------------------------------
# housekeeping: old entries do not pile up
# ---------------------------------------------------------------------------------------------
def _age(cache: StageCache, name: str, key: str, seconds_ago: float) -> None:
    t = time.time() - seconds_ago
    for p in cache.paths(name, key):
        os.utime(p, (t, t))


def test_saving_a_new_key_drops_the_stale_keys_of_that_stage_only(cache):
    assert cache.save("kin", "k1", 1.0)
    assert cache.save("kin_x", "k1", 2.0)
    assert cache.save("kin-x", "k1", 3.0)
    assert cache.save("kin", "k2", 4.0)
    assert cache.load("kin", "k1") == (False, None)
    assert cache.load("kin", "k2") == (True, 4.0)
    assert cache.load("kin_x", "k1") == (True, 2.0)
    assert cache.load("kin-x", "k1") == (True, 3.0)
    assert len(list(cache.folder.glob("kin-*.json"))) == 1 + 1  # kin-<id> and kin-x-<id>
    assert not cache.save("kin", "k3", pin.Model())  # not storable: the stale entry goes too
    assert cache.load("kin", "k2") == (False, None)


def test_prune_keeps_the_newest_entries_by_last_use(tmp_path):
    cache = StageCache(tmp_path, max_entries=3, fingerprint=FP)
    for i in range(3):
        assert cache.save(f"s{i}", "k", float(i))
        _age(cache, f"s{i}", "k", 100.0 - i)
    assert cache.load("s0", "k") == (True, 0.0)  # used now: the newest
    assert cache.save("s3", "k", 3.0)  # prunes s1, the least recently used
    assert sorted(p.stem.split("-")[0] for p in tmp_path.glob("*.json")) == ["s0", "s2", "s3"]
    assert sorted(p.stem.split("-")[0] for p in tmp_path.glob("*.npz")) == ["s0", "s2", "s3"]


def test_prune_removes_orphans_and_abandoned_temporary_files(cache):
    assert cache.save("a", "k", np.zeros(2))
    orphan = cache.folder / f"b-{'1' * 32}.npz"
    fresh_orphan = cache.folder / f"c-{'2' * 32}.npz"  # maybe a write in progress: kept
    tmp_old = cache.folder / ".a-x.json.abc.tmp"
    tmp_new = cache.folder / ".a-y.json.def.tmp"
    other = cache.folder / "README.txt"  # not ours: kept
    for p in (orphan, fresh_orphan, tmp_old, tmp_new, other):
        p.write_bytes(b"x")
    old = time.time() - 2 * 3600
    os.utime(orphan, (old, old))
    os.utime(tmp_old, (old, old))
    assert cache.prune() == 2
    assert not orphan.exists() and not tmp_old.exists()
    assert fresh_orphan.exists() and tmp_new.exists() and other.exists()
    assert cache.load("a", "k")[0]


def test_bad_stage_names_are_refused(cache):
    for name in ("", "../x", "a/b", ".hidden", "a b"):
        with pytest.raises(ValueError, match="stage name"):
            cache.save(name, "k", 1.0)
    with pytest.raises(ValueError, match="max_entries"):
        StageCache(cache.folder, max_entries=0)
