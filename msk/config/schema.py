"""The machinery of the config schema: :func:`opt` declares one TOML key on an options-dataclass
field (meaning, unit, range or allowed values; the type is the field's annotation, the default the
field's default), :func:`read_options` validates one TOML table into such a dataclass.

Every message is one line naming the file, the key (``trials[2].role``) and what is allowed.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import math
import types
import typing
from collections.abc import Callable, Iterable, Mapping
from dataclasses import MISSING, dataclass, field
from pathlib import Path
from typing import Any

from msk.exceptions import ConfigError, MskError

__all__ = ["OPTION", "Option", "Range", "check_keys", "opt", "option_fields", "read_options"]

#: the key of :class:`Option` in a field's ``metadata``
OPTION = "msk.option"


@dataclass(frozen=True)
class Range:
    """An interval of allowed numbers (finite only); ``hi = inf`` reads "≥ lo" (or "> lo")."""

    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False
    hi_open: bool = False

    def __contains__(self, v: float) -> bool:
        return (
            math.isfinite(v)
            and (v > self.lo if self.lo_open else v >= self.lo)
            and (v < self.hi if self.hi_open else v <= self.hi)
        )

    @property
    def half_open(self) -> bool:
        """True when only a lower bound is given (the message says "should be > 0")."""
        return math.isinf(self.hi)

    def text(self, unit: str = "") -> str:
        """``[0.01, 500] Hz``, ``(0, 1)``, ``> 0 N/m``, ``≥ 2``."""
        u = f" {unit}" if unit else ""
        if self.half_open:
            return f"{'>' if self.lo_open else '≥'} {self.lo:g}{u}"
        lo, hi = "(["[not self.lo_open], ")]"[not self.hi_open]
        return f"{lo}{self.lo:g}, {self.hi:g}{hi}{u}"


@dataclass(frozen=True)
class Option:
    """What a TOML key means and what it allows (stored in the field's metadata by :func:`opt`).

    Attributes:
        meaning: one line: what the key does (and what its absence means when it has no default).
        key: the TOML key ("" → the field name).
        unit: unit of a number ("" for dimensionless, text and paths); SI unless it says.
        bounds: allowed numbers (of the value, or of a table's values).
        choices: allowed strings, or a function returning them (registered solvers).
        hint: appended to an out-of-range message; a function of the value for ms→s style hints.
        item: what one value of a table or the items of a list are (for messages).
        named: for a path, the file a bare word names (no folder, no suffix: a shipped model);
            it raises :class:`msk.exceptions.MskError` when the word names nothing.
    """

    meaning: str
    key: str = ""
    unit: str = ""
    bounds: Range | None = None
    choices: tuple[str, ...] | Callable[[], tuple[str, ...]] | None = None
    hint: str | Callable[[float], str] = ""
    item: str = ""
    named: Callable[[str], Path] | None = None

    def allowed(self) -> tuple[str, ...] | None:
        """The allowed strings (None: any)."""
        return self.choices() if callable(self.choices) else self.choices


def opt(
    meaning: str,
    default: Any = MISSING,
    *,
    key: str = "",
    unit: str = "",
    bounds: Range | None = None,
    choices: tuple[str, ...] | Callable[[], tuple[str, ...]] | None = None,
    hint: str | Callable[[float], str] = "",
    item: str = "",
    named: Callable[[str], Path] | None = None,
) -> Any:
    """A dataclass field that is a TOML key. No ``default``: the key is required.

    Args:
        meaning: one line: what the key does.
        default: the value when the key is absent (a ``dict`` default is copied per instance).
        key: the TOML key when it differs from the field name.
        unit: unit of a number (SI unless it says).
        bounds: allowed interval of a number (or of a table's values).
        choices: allowed strings (or a function returning them).
        hint: appended to the out-of-range message (or a function of the value giving it).
        item: what a table's values / a list's items are, for messages.
        named: for a path, the file a bare word names (:attr:`Option.named`).

    Returns:
        A :func:`dataclasses.field` carrying the :class:`Option` in its metadata.
    """
    md = {OPTION: Option(meaning, key, unit, bounds, choices, hint, item, named)}
    if isinstance(default, dict):
        return field(default_factory=dict, metadata=md)
    return field(default=default, metadata=md)


@functools.cache
def option_fields(cls: type) -> tuple[tuple[dataclasses.Field[Any], Option, Any], ...]:
    """The fields of ``cls`` that are TOML keys, with their :class:`Option` and type.

    Args:
        cls: an options dataclass.

    Returns:
        ``(field, option, annotation)`` per key, in field order.
    """
    hints = typing.get_type_hints(cls)
    return tuple(
        (f, f.metadata[OPTION], hints[f.name])
        for f in dataclasses.fields(cls)
        if OPTION in f.metadata
    )


def key_of(f: dataclasses.Field[Any], o: Option) -> str:
    """The TOML key of field ``f``."""
    return o.key or f.name


def default_of(f: dataclasses.Field[Any]) -> Any:
    """The default of field ``f`` (``MISSING`` when the key is required)."""
    if f.default_factory is not MISSING:
        return f.default_factory()
    return f.default


def base_type(tp: Any) -> tuple[Any, bool]:
    """``X | None`` → ``(X, True)``; ``X`` → ``(X, False)``."""
    if isinstance(tp, types.UnionType) or typing.get_origin(tp) is typing.Union:
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        return args[0], len(args) < len(typing.get_args(tp))
    return tp, False


def type_name(tp: Any) -> str:
    """The name of a key's type in the reference: ``float``, ``path``, ``table of str``…"""
    tp, _ = base_type(tp)
    origin = typing.get_origin(tp)
    if origin is not None and issubclass(origin, Mapping):
        return f"table of {type_name(typing.get_args(tp)[1])}"
    if origin is tuple:
        return f"list of {type_name(typing.get_args(tp)[0])}"
    return "path" if tp is Path else tp.__name__


def _where(where: str, key: str) -> str:
    return f"{where}.{key}" if where else key


def _did_you_mean(word: str, candidates: Iterable[str], quote: bool = False) -> str:
    close = difflib.get_close_matches(word, list(candidates), n=1, cutoff=0.6)
    if not close:
        return ""
    return f" (did you mean {close[0]!r}?)" if quote else f" (did you mean {close[0]}?)"


def check_keys(table: Mapping[str, Any], allowed: Iterable[str], where: str, source: Path) -> None:
    """Raise on the first key of ``table`` not in ``allowed``, with a suggestion or the list."""
    allowed = list(allowed)
    unknown = [k for k in table if k not in allowed]
    if not unknown:
        return
    more = f" (and {len(unknown) - 1} more)" if len(unknown) > 1 else ""
    first = unknown[0]
    tip = _did_you_mean(first, allowed) or f"; allowed: {', '.join(allowed)}"
    raise ConfigError(f"{source}: unknown key {_where(where, first)}{more}{tip}")


def as_table(value: Any, where: str, source: Path) -> dict[str, Any]:
    """``value`` when it is a TOML table, else the one-line error."""
    if not isinstance(value, dict):
        raise ConfigError(f"{source}: [{where}] must be a table, got {type(value).__name__}")
    return value


def read_options(cls: type, table: Mapping[str, Any], where: str, source: Path) -> dict[str, Any]:
    """Validate the keys of ``cls`` found in ``table`` (unknown keys are not checked here).

    Args:
        cls: an options dataclass whose fields are declared with :func:`opt`.
        table: the TOML table.
        where: the key path of the table (``emg``, ``trials[2]``) for messages.
        source: the configuration file (for messages and relative paths).

    Returns:
        Field name → validated value, for the keys present (absent keys keep the dataclass
        default; a required key absent raises).
    """
    values: dict[str, Any] = {}
    for f, o, tp in option_fields(cls):
        key = key_of(f, o)
        if key not in table:
            if default_of(f) is MISSING:
                raise ConfigError(f"{source}: missing key {_where(where, key)}")
            continue
        values[f.name] = _value(o, tp, table[key], _where(where, key), source)
    return values


def _value(o: Option, tp: Any, value: Any, name: str, source: Path) -> Any:
    """One validated value of type ``tp``."""
    tp, _ = base_type(tp)
    origin = typing.get_origin(tp)
    if origin is not None and issubclass(origin, Mapping):
        if not isinstance(value, dict):
            raise ConfigError(f"{source}: {name} = {value!r} should be a table")
        vt = typing.get_args(tp)[1]
        return {str(k): _entry(o, vt, v, f"{name}.{k}", source) for k, v in value.items()}
    if origin is tuple:
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise ConfigError(f"{source}: {name} = {value!r} should be a list of {o.item}")
        return tuple(value)
    if tp is Path:
        text = _typed(str, value, name, source)
        if o.named is not None and _bare_word(text):
            try:
                return o.named(text)
            except MskError as exc:
                raise ConfigError(f"{source}: {name} = {text!r}: {exc}") from None
        return _path(text, name, source)
    value = _typed(tp, value, name, source)
    if tp in (int, float):
        _check_number(o, value, name, source)
        return tp(value)
    if tp is str and (allowed := o.allowed()) is not None and value not in allowed:
        raise ConfigError(
            f"{source}: {name} = {value!r} is not one of {', '.join(allowed)}"
            + _did_you_mean(value, allowed, quote=True)
        )
    return value


def _typed(tp: type, value: Any, name: str, source: Path) -> Any:
    """``value`` if it is a ``tp`` (an integer is a float; a boolean is no number)."""
    number = isinstance(value, int | float) and not isinstance(value, bool)
    if tp is float:
        ok = number
    elif tp is int:
        ok = number and isinstance(value, int)
    else:
        ok = isinstance(value, tp)
    if not ok:
        raise ConfigError(f"{source}: {name} = {value!r} should be {tp.__name__}")
    if tp is float:
        try:
            return float(value)
        except OverflowError:  # a 400-digit integer
            raise ConfigError(
                f"{source}: {name} = {str(value)[:20]}… ({len(str(value))} digits) is not a "
                "finite number"
            ) from None
    return value


def _check_number(o: Option, value: float, name: str, source: Path) -> None:
    if o.bounds is None or value in o.bounds:
        return
    u = f" {o.unit}" if o.unit else ""
    hint = o.hint(value) if callable(o.hint) else o.hint
    verb = "should be" if o.bounds.half_open else "is outside"
    raise ConfigError(f"{source}: {name} = {value!r}{u} {verb} {o.bounds.text(o.unit)}{hint}")


def _entry(o: Option, vt: Any, v: Any, name: str, source: Path) -> Any:
    """One value of a table: a non-empty string, or a finite number in ``o.bounds``."""
    if vt is str:
        if not isinstance(v, str) or not v.strip():
            raise ConfigError(f"{source}: {name} = {v!r} should be {o.item}")
        return v
    number = isinstance(v, int | float) and not isinstance(v, bool)
    if not number or (o.bounds is not None and v not in o.bounds) or not math.isfinite(v):
        rng = f" {o.bounds.text()}" if o.bounds is not None else ""
        raise ConfigError(f"{source}: {name} = {v!r} should be a finite number{rng} ({o.item})")
    return float(v)


def _file_kind(p: Path) -> str:
    """What a path that is not a regular file is (for the error message)."""
    from msk.io.validate import path_kind

    return path_kind(p)


def _bare_word(text: str) -> bool:
    """A name with no folder and no suffix (``"gait2392"``), not a path."""
    p = Path(text)
    return bool(text.strip()) and "\x00" not in text and not p.suffix and len(p.parts) == 1


def _path(value: str, name: str, source: Path) -> Path:
    """A regular file, relative to the configuration file."""
    if "\x00" in value:
        raise ConfigError(f"{source}: {name} = {value!r}: a path cannot hold a NUL character")
    try:
        p = (source.parent / value).resolve()
    except (RuntimeError, OSError) as exc:  # a symlink loop
        raise ConfigError(f"{source}: {name}: {value}: cannot be resolved ({exc})") from None
    if not p.exists():
        raise ConfigError(f"{source}: {name}: file not found: {p}")
    if not p.is_file():  # a FIFO or /dev/zero would hang the reader, a folder is no file
        raise ConfigError(f"{source}: {name}: {p} is {_file_kind(p)}, not a regular file")
    return p
