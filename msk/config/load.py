""":func:`load_config`: a TOML session configuration → :class:`SessionConfig`, validated by the
schema of :mod:`msk.config.options` plus the rules that tie keys together (trial roles and files,
the FES protocol, EMG MVC channels)."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path
from typing import Any

from msk.config.options import (
    FES_STEPS,
    FES_STEPS_NEEDED,
    SECTIONS,
    FesTrialConfig,
    MarkersConfig,
    ModelConfig,
    SessionConfig,
    TrialConfig,
)
from msk.config.schema import _file_kind, as_table, check_keys, key_of, option_fields, read_options
from msk.exceptions import ConfigError

__all__ = ["FES_TRIAL_KEYS", "load_config"]

#: Per-trial keys valid only with ``role = "fes"``.
FES_TRIAL_KEYS = tuple(key_of(f, o) for f, o, _ in option_fields(FesTrialConfig))
#: a trial name: it becomes a folder name under ``--out``
_PLAIN_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9._-]{0,99}")


def _keys(cls: type) -> list[str]:
    return [key_of(f, o) for f, o, _ in option_fields(cls)]


def _read_toml(source: Path) -> dict[str, Any]:
    if not source.exists():
        raise ConfigError(f"config file not found: {source}")
    if not source.is_file():
        raise ConfigError(f"{source}: is {_file_kind(source)}, not a configuration file")
    try:
        return tomllib.loads(source.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"config file not found: {source}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(
            f"{source}: not UTF-8 text (invalid byte 0x{exc.object[exc.start]:02x} at offset "
            f"{exc.start}); save the configuration as UTF-8"
        ) from None
    except OSError as exc:
        raise ConfigError(f"{source}: cannot read: {exc.strerror or exc}") from None
    except RecursionError:
        raise ConfigError(f"{source}: nested too deeply to be a session configuration") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: not valid TOML: {exc}") from None


def _table(cls: type, raw: Any, where: str, source: Path) -> Any:
    """An options dataclass from one TOML table (unknown keys are errors)."""
    table = as_table(raw, where, source)
    check_keys(table, _keys(cls), where, source)
    return cls(**read_options(cls, table, where, source))


def load_config(path: str | Path) -> SessionConfig:
    """Read and validate a session configuration file.

    Args:
        path: the TOML file; relative paths in it are relative to its folder.

    Returns:
        The validated :class:`SessionConfig`.

    Raises:
        ConfigError: one line naming the file, the key and what it allows.
    """
    source = Path(path).resolve()
    raw = _read_toml(source)
    check_keys(raw, [s.name for s in SECTIONS], "", source)
    for name in ("subject",):
        if name not in raw:
            raise ConfigError(f"{source}: missing table [{name}]")
    parts: dict[str, Any] = {}
    for sec in SECTIONS:
        if sec.name in ("trials", "model") or sec.name not in raw:
            continue
        parts[sec.name] = _table(sec.options, raw[sec.name], sec.name, source)

    raw_trials = raw.get("trials", [])
    if not isinstance(raw_trials, list):
        raise ConfigError(f"{source}: trials = {raw_trials!r} should be [[trials]] tables")
    trials = tuple(_trial(t, i, source) for i, t in enumerate(raw_trials))
    if not trials:
        raise ConfigError(f"{source}: no [[trials]] given")
    names = [t.name for t in trials]
    if len(set(names)) != len(names):
        raise ConfigError(f"{source}: trial names must be unique, got {names}")
    only_fes = all(tc.role == "fes" for tc in trials)
    model: ModelConfig | None = None
    if "model" in raw:
        model = _table(ModelConfig, raw["model"], "model", source)
    elif not only_fes:
        raise ConfigError(
            f"{source}: missing table [model]: trials of role "
            f"{', '.join(sorted({repr(t.role) for t in trials if t.role != 'fes'}))} need a model"
        )

    markers = parts.pop("markers", MarkersConfig())
    from msk.personalise.virtual_markers import parse_virtual

    for name, text in markers.virtual.items():
        try:
            parse_virtual(name, text)
        except ConfigError as exc:
            raise ConfigError(f"{source}: {exc}") from None
    emg = parts.get("emg")
    if emg is not None:
        for ch in emg.mvc:
            if ch not in emg.channels.values():
                raise ConfigError(
                    f"{source}: emg.mvc names channel {ch!r}, which no muscle in emg.channels uses"
                )
    strength = parts.get("strength")
    if strength is not None:
        roles = {t.name: t.role for t in trials}
        for name in strength.pool:
            if roles.get(name) not in ("task", "mvc"):
                raise ConfigError(
                    f"{source}: strength.pool names {name!r}, which is "
                    + ("no trial" if name not in roles else f"a trial of role {roles[name]!r}")
                    + "; it takes trials of role 'task' or 'mvc'"
                )
    fes_trials = [tc for tc in trials if tc.role == "fes"]
    if fes_trials:
        _check_fes_session(source, fes_trials, parts["subject"].height_m)
    return SessionConfig(
        path=source,
        model=model,
        trials=trials,
        marker_rename=markers.rename,
        marker_weights=markers.weights,
        marker_move=markers.move,
        marker_virtual=markers.virtual,
        **parts,
    )


def _trial(raw: Any, i: int, source: Path) -> TrialConfig:
    """One ``[[trials]]`` table (the ``role = "fes"`` keys only with that role)."""
    where = f"trials[{i}]"
    table = as_table(raw, where, source)
    check_keys(table, _keys(TrialConfig) + list(FES_TRIAL_KEYS), where, source)
    values = read_options(TrialConfig, table, where, source)
    role, name = values.get("role", "task"), values["name"]
    if not _PLAIN_NAME.fullmatch(name) or name in (".", ".."):
        raise ConfigError(
            f"{source}: {where}.name = {name!r} must be a plain name (letters, digits, "
            "'.', '_', '-'; no path separators): it names the trial's results folder"
        )
    if role == "fes":
        if "fes_step" not in table:
            raise ConfigError(
                f"{source}: missing key {where}.fes_step (role = 'fes' needs one of "
                f"{', '.join(FES_STEPS)})"
            )
        values["fes"] = FesTrialConfig(**read_options(FesTrialConfig, table, where, source))
    elif given := [k for k in FES_TRIAL_KEYS if k in table]:
        raise ConfigError(
            f"{source}: {where}.{given[0]} is only valid with role = 'fes' "
            f"(this trial has role = {role!r})"
        )
    tc = TrialConfig(**values)
    if tc.external_loads is not None and tc.grf is None:
        raise ConfigError(
            f"{source}: {where}.external_loads goes with {where}.grf (the GRF file "
            "whose force sets it assigns to bodies)"
        )
    if tc.grf is not None and role != "task":
        raise ConfigError(
            f"{source}: {where}.grf is only valid with role = 'task' "
            f"(this trial has role = {role!r})"
        )
    if tc.grf is not None and tc.file.suffix.lower() != ".trc":
        raise ConfigError(
            f"{source}: {where}.grf goes with a .trc trial file (a C3D has its own "
            f"plates, in its lab frame), got {tc.file.name}"
        )
    if role == "task" and tc.file.suffix.lower() == ".trc" and tc.grf is None:
        raise ConfigError(
            f"{source}: {where}.file is a .trc (markers only): give its ground "
            f"reactions as {where}.grf = an OpenSim GRF .mot"
        )
    return tc


def _check_fes_session(source: Path, fes_trials: list[TrialConfig], height: float | None) -> None:
    """A FES session needs every protocol step and the subject's height (geometry)."""
    if height is None:
        raise ConfigError(
            f"{source}: subject.height_m is needed by the FES trials "
            f"({fes_trials[0].name!r}…): the muscle geometry comes from the height"
        )
    counts = {s: 0 for s in FES_STEPS}
    for tc in fes_trials:
        assert tc.fes is not None
        counts[tc.fes.step] += 1
    for step, need in FES_STEPS_NEEDED.items():
        if counts[step] < need:
            raise ConfigError(
                f"{source}: the FES protocol needs at least {need} trial(s) with "
                f"fes_step = {step!r}, got {counts[step]}"
            )
    for step in ("static", "pendulum", "dynamic", "validation"):
        if counts[step] > 1:
            names = [tc.name for tc in fes_trials if tc.fes and tc.fes.step == step]
            raise ConfigError(f"{source}: more than one trial with fes_step = {step!r}: {names}")
