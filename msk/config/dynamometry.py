"""The configuration of a dynamometry session (``kind = \"dynamometry\"``): one subject's
maximal isometric tests, how the dynamometer exports read, and each test's joint, posture and
lever arm (the file format is described in :mod:`msk.pipeline.dynamometry`)."""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from msk.exceptions import ConfigError, MskError
from msk.io.dynamometer import EMG_UNITS, FORCE_UNITS, TORQUE_UNITS

if TYPE_CHECKING:
    from msk.strength.isometric import IsometricSettings, IsometricTest

__all__ = [
    "KIND",
    "DynamometryConfig",
    "TestConfig",
    "is_dynamometry_config",
    "load_dynamometry_config",
]


KIND = "dynamometry"


@dataclass(frozen=True)
class TestConfig:
    """One ``[[tests]]`` table: the test and its file, and a given lever arm if any."""

    test: IsometricTest
    file: Path
    lever_arm_m: float | None
    lever_arm_sd_m: float
    #: a published band given by the configuration (low, high N·m/kg) and its source; None:
    #: the library's band of the action for the subject's age
    band_nm_per_kg: tuple[float, float] | None = None
    band_source: str = ""


@dataclass(frozen=True)
class DynamometryConfig:
    path: Path
    subject: Mapping[str, Any]
    model_source: Path
    reader: Mapping[str, Any]
    settings: IsometricSettings
    tests: tuple[TestConfig, ...]


def is_dynamometry_config(path: str | Path) -> bool:
    """Whether ``path`` is a TOML file with ``kind = "dynamometry"`` (False on anything else:
    the session loader reports the errors of other files)."""
    try:
        raw = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return False
    return raw.get("kind") == KIND


def _get(
    table: Mapping[str, Any],
    key: str,
    kind: type | tuple[type, ...],
    where: str,
    src: Path,
    default: Any = ...,
) -> Any:
    if key not in table:
        if default is ...:
            raise ConfigError(f"{src}: missing key {where}.{key}")
        return default
    v = table[key]
    if isinstance(v, bool) and bool not in (kind if isinstance(kind, tuple) else (kind,)):
        raise ConfigError(f"{src}: {where}.{key} = {v!r} should be {kind}")
    if kind is float and isinstance(v, int):
        v = float(v)
    if not isinstance(v, kind):
        raise ConfigError(f"{src}: {where}.{key} = {v!r} has the wrong type")
    if isinstance(v, float) and not math.isfinite(v):
        raise ConfigError(f"{src}: {where}.{key} = {v!r} is not finite")
    return v


def _check_keys(table: Mapping[str, Any], allowed: set[str], where: str, src: Path) -> None:
    extra = sorted(set(table) - allowed)
    if extra:
        raise ConfigError(
            f"{src}: unknown key {where}.{extra[0]}; allowed: {', '.join(sorted(allowed))}"
        )


def load_dynamometry_config(path: str | Path) -> DynamometryConfig:
    """Read and validate a ``kind = "dynamometry"`` configuration (module docstring);
    :class:`~msk.exceptions.ConfigError` naming the file and the key."""
    # on use: `msk run` of a gait session asks is_dynamometry_config without msk.strength
    from msk.strength.isometric import IsometricSettings, IsometricTest
    from msk.strength.joint_strength import ACTIONS

    src = Path(path).resolve()
    try:
        raw = tomllib.loads(src.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"config file not found: {src}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{src}: cannot read: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{src}: not valid TOML: {exc}") from None
    _check_keys(raw, {"kind", "subject", "model", "dynamometer", "tests"}, "", src)
    if raw.get("kind") != KIND:
        raise ConfigError(f"{src}: kind = {raw.get('kind')!r}, expected {KIND!r}")
    sub = raw.get("subject")
    if not isinstance(sub, dict):
        raise ConfigError(f"{src}: missing table [subject]")
    _check_keys(sub, {"name", "mass_kg", "height_m", "sex", "side", "age_years"}, "subject", src)
    mass = _get(sub, "mass_kg", float, "subject", src)
    height = _get(sub, "height_m", float, "subject", src)
    if not 20.0 <= mass <= 300.0:
        raise ConfigError(f"{src}: subject.mass_kg = {mass} is not a plausible body mass")
    if not 0.5 <= height <= 2.5:
        raise ConfigError(f"{src}: subject.height_m = {height}: not a height in metres")
    sex = _get(sub, "sex", str, "subject", src, None)
    if sex not in (None, "male", "female"):
        raise ConfigError(f"{src}: subject.sex = {sex!r}: 'male', 'female' or absent")
    side = _get(sub, "side", str, "subject", src, "right")
    if side not in ("left", "right"):
        raise ConfigError(f"{src}: subject.side = {side!r}: 'left' or 'right'")
    subject = {
        "name": _get(sub, "name", str, "subject", src, src.stem),
        "mass_kg": mass,
        "height_m": height,
        "sex": sex,
        "side": side,
        "age_years": _get(sub, "age_years", (int, float), "subject", src, None),
    }
    model = raw.get("model")
    if not isinstance(model, dict):
        raise ConfigError(f"{src}: missing table [model] (source = the generic model)")
    _check_keys(model, {"source"}, "model", src)
    from msk.model.files import model_file

    named = _get(model, "source", str, "model", src)
    try:
        model_source = model_file(named, base=src.parent)
    except MskError as exc:
        raise ConfigError(f"{src}: model.source = {named!r}: {exc}") from None
    dyn = raw.get("dynamometer", {})
    if not isinstance(dyn, dict):
        raise ConfigError(f"{src}: [dynamometer] should be a table")
    keys = {
        "time_column",
        "force_column",
        "force_unit",
        "torque_column",
        "torque_unit",
        "emg_unit",
        "emg",
        "capacity",
        "baseline",
        "baseline_window_s",
        "plateau_window_s",
        "zero_sd",
    }
    _check_keys(dyn, keys, "dynamometer", src)
    emg = dyn.get("emg", {})
    if not isinstance(emg, dict) or not all(isinstance(v, str) for v in emg.values()):
        raise ConfigError(f"{src}: [dynamometer.emg] should map channel label = column name")
    force_unit = _get(dyn, "force_unit", str, "dynamometer", src, "N")
    torque_unit = _get(dyn, "torque_unit", str, "dynamometer", src, "N.m")
    emg_unit = _get(dyn, "emg_unit", str, "dynamometer", src, "V")
    for key, val, table in (
        ("force_unit", force_unit, FORCE_UNITS),
        ("torque_unit", torque_unit, TORQUE_UNITS),
        ("emg_unit", emg_unit, EMG_UNITS),
    ):
        if val.replace("·", ".").replace("µ", "u") not in table:
            raise ConfigError(f"{src}: dynamometer.{key} = {val!r}; allowed: {', '.join(table)}")
    force_col = _get(dyn, "force_column", str, "dynamometer", src, None)
    torque_col = _get(dyn, "torque_column", str, "dynamometer", src, None)
    if (force_col is None) == (torque_col is None):
        raise ConfigError(
            f"{src}: give exactly one of dynamometer.force_column and dynamometer.torque_column"
        )
    to_si = (
        FORCE_UNITS[force_unit.replace("·", ".")]
        if force_col
        else TORQUE_UNITS[torque_unit.replace("·", ".")]
    )
    baseline = _get(dyn, "baseline", str, "dynamometer", src, "auto")
    if baseline not in ("auto", "pre_effort", "tared"):
        raise ConfigError(
            f"{src}: dynamometer.baseline = {baseline!r}; allowed: auto, pre_effort, tared"
        )
    cap = _get(dyn, "capacity", float, "dynamometer", src, None)
    zero = _get(dyn, "zero_sd", float, "dynamometer", src, 1.0 if force_unit == "kgf" else None)
    settings = IsometricSettings(
        baseline=baseline,
        zero_sd=(zero * to_si) if zero is not None else 0.02 * (cap * to_si if cap else 0.0),
        baseline_window_s=_get(dyn, "baseline_window_s", float, "dynamometer", src, 0.25),
        plateau_window_s=_get(dyn, "plateau_window_s", float, "dynamometer", src, 1.0),
        capacity=cap * to_si if cap is not None else None,
    )
    reader = {
        "time_column": _get(dyn, "time_column", str, "dynamometer", src, "time_s"),
        "force_column": force_col,
        "force_unit": force_unit,
        "torque_column": torque_col,
        "torque_unit": torque_unit,
        "emg_columns": dict(emg),
        "emg_unit": emg_unit,
    }
    raw_tests = raw.get("tests")
    if not isinstance(raw_tests, list) or not raw_tests:
        raise ConfigError(f"{src}: no [[tests]] given")
    tests = []
    tkeys = {
        "name",
        "file",
        "action",
        "angle_deg",
        "angle_range_deg",
        "posture_deg",
        "target",
        "antagonist",
        "sign",
        "segment",
        "lever_arm_m",
        "lever_arm_sd_m",
        "band_nm_per_kg",
        "band_source",
    }
    for i, t in enumerate(raw_tests):
        w = f"tests[{i}]"
        if not isinstance(t, dict):
            raise ConfigError(f"{src}: {w} should be a table")
        _check_keys(t, tkeys, w, src)
        action = _get(t, "action", str, w, src)
        if action not in ACTIONS:
            raise ConfigError(f"{src}: {w}.action = {action!r}; allowed: {', '.join(ACTIONS)}")
        posture = t.get("posture_deg", {})
        if not isinstance(posture, dict) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in posture.values()
        ):
            raise ConfigError(f"{src}: {w}.posture_deg should map coordinate stem = degrees")
        target = _get(t, "target", str, w, src, "")
        antagonist = _get(t, "antagonist", str, w, src, "")
        for key, ch in (("target", target), ("antagonist", antagonist)):
            if ch and ch not in emg:
                raise ConfigError(
                    f"{src}: {w}.{key} = {ch!r} is not a channel of "
                    f"[dynamometer.emg] ({', '.join(emg) or 'none'})"
                )
        segment = _get(t, "segment", str, w, src, "shank")
        if segment not in ("shank", "foot"):
            raise ConfigError(f"{src}: {w}.segment = {segment!r}; allowed: shank, foot")
        sign = _get(t, "sign", float, w, src, 1.0)
        if sign not in (1.0, -1.0):
            raise ConfigError(f"{src}: {w}.sign = {sign}: +1 or -1")
        lever = _get(t, "lever_arm_m", float, w, src, None)
        if lever is not None and not 0.01 <= lever <= 1.0:
            raise ConfigError(f"{src}: {w}.lever_arm_m = {lever}: not a lever arm in metres")
        test = IsometricTest(
            name=_get(t, "name", str, w, src),
            action=action,
            angle_deg=_get(t, "angle_deg", float, w, src),
            angle_range_deg=_get(t, "angle_range_deg", float, w, src, 0.0),
            posture_deg={k: float(v) for k, v in posture.items()},
            target=target,
            antagonist=antagonist,
            sign=sign,
            segment=segment,
        )
        file = (src.parent / _get(t, "file", str, w, src)).resolve()
        band = t.get("band_nm_per_kg")
        if band is not None and not (
            isinstance(band, list)
            and len(band) == 2
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in band)
            and 0.0 <= band[0] < band[1] <= 10.0
        ):
            raise ConfigError(
                f"{src}: {w}.band_nm_per_kg = {band!r}: [low, high] in N·m/kg, 0 ≤ low < high"
            )
        band_source = _get(t, "band_source", str, w, src, "")
        if band is not None and not band_source:
            raise ConfigError(f"{src}: {w}.band_nm_per_kg needs {w}.band_source (its citation)")
        tests.append(
            TestConfig(
                test,
                file,
                lever,
                _get(t, "lever_arm_sd_m", float, w, src, 0.01),
                (float(band[0]), float(band[1])) if band is not None else None,
                band_source,
            )
        )
    names = [tc.test.name for tc in tests]
    if len(set(names)) != len(names):
        raise ConfigError(f"{src}: test names must be unique, got {names}")
    return DynamometryConfig(src, subject, model_source, reader, settings, tuple(tests))
