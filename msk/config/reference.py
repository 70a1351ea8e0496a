"""Text generated from the schema: :func:`config_reference` (every table and key with its type,
default, unit, allowed values and meaning: what ``msk print-config`` prints and
``docs/config.md`` holds) and :func:`render_config` (a loaded configuration, every key with its
value)."""

from __future__ import annotations

import json
import math
import re
import textwrap
from collections.abc import Mapping
from dataclasses import MISSING
from pathlib import Path
from typing import Any

from msk.config.options import SECTIONS, FesTrialConfig, SessionConfig
from msk.config.schema import Option, default_of, key_of, option_fields, type_name

__all__ = ["config_reference", "render_config", "toml_value"]

WIDTH = 99
_HEADER = """\
# msk session configuration: every table and key, generated from the options dataclasses of
# msk.config (msk.config.config_reference(); `msk print-config`). Each key: its type, unit,
# allowed values or range, and meaning, then `key = default`. A key without a default line is
# required, or optional when it says so (absent: what the meaning says). Units are SI unless
# stated; paths are relative to the configuration file.
"""
_BARE = re.compile(r"[A-Za-z0-9_-]+")


def toml_value(v: Any) -> str:
    """``v`` as a TOML literal (strings, numbers, booleans, paths, lists, inline tables).

    Args:
        v: the value.

    Returns:
        Its TOML text (``1.0``, ``"deg"``, ``{ RASI = 2.0 }``, ``["a", "b"]``, ``inf``).
    """
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return ("-inf" if v < 0 else "inf") if math.isinf(v) else repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str | Path):
        return json.dumps(str(v), ensure_ascii=False)
    if isinstance(v, Mapping):
        items = [
            f"{k if _BARE.fullmatch(k) else toml_value(k)} = {toml_value(x)}" for k, x in v.items()
        ]
        return "{ " + ", ".join(items) + " }" if items else "{}"
    if isinstance(v, tuple | list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    raise TypeError(f"no TOML literal for {v!r}")


def _describe(key: str, o: Option, tp: Any, default: Any) -> str:
    """``key (float, Hz, in (0, 500]): meaning.`` with "required" or "optional"."""
    parts = [type_name(tp)]
    if o.unit:
        parts.append(o.unit)
    if (allowed := o.allowed()) is not None:
        parts.append(" | ".join(allowed))
    if o.bounds is not None:
        b = o.bounds
        parts.append(("values " if "table" in parts[0] else "in " * (not b.half_open)) + b.text())
    if default is MISSING:
        parts.append("required")
    elif default is None:
        parts.append("optional")
    return f"{key} ({', '.join(parts)}): {o.meaning}"


def _comment(text: str, prefix: str = "# ") -> list[str]:
    return textwrap.wrap(
        text, WIDTH, initial_indent=prefix, subsequent_indent=prefix + "  ", break_on_hyphens=False
    )


def _keys(cls: type, lines: list[str], commented: bool = False) -> None:
    for f, o, tp in option_fields(cls):
        key, default = key_of(f, o), default_of(f)
        lines += _comment(_describe(key, o, tp, default))
        if default is not MISSING and default is not None:
            lines.append(("# " if commented else "") + f"{key} = {toml_value(default)}")


def config_reference() -> str:
    """The reference of the session configuration, generated from the options dataclasses.

    Every table, then every key with its type, unit, allowed values or range, whether it is
    required, its one-line meaning and ``key = default`` (a valid TOML line). The keys valid only
    with ``role = "fes"`` follow ``[[trials]]`` commented out. What ``msk print-config`` prints.

    Returns:
        The text (TOML with comments; ends with a newline).
    """
    lines = [_HEADER.rstrip("\n")]
    for sec in SECTIONS:
        lines.append("")
        lines += _comment(sec.note[0].upper() + sec.note[1:] + ".")
        lines.append(f"[[{sec.name}]]" if sec.array else f"[{sec.name}]")
        _keys(sec.options, lines)
        if sec.options.__name__ == "TrialConfig":
            lines.append('# --- valid only with role = "fes" (FES protocol recordings):')
            _keys(FesTrialConfig, lines, commented=True)
    return "\n".join(lines) + "\n"


def _values(obj: Any, lines: list[str], table: str) -> None:
    """The keys of ``obj`` (a table of more than three entries as a sub-table after them)."""
    subtables: list[str] = []
    cls: type = type(obj)
    for f, o, _ in option_fields(cls):
        key, value, default = key_of(f, o), getattr(obj, f.name), default_of(f)
        if value is None:
            lines.append(f"# {key}: absent")
            continue
        if isinstance(value, Mapping) and len(value) > 3:
            subtables += ["", f"[{table}.{key}]"]
            subtables += [f"{toml_value({k: v})[2:-2]}" for k, v in value.items()]
            continue
        if isinstance(value, tuple) and len(value) > 3:
            text = f"{key} = [\n" + "".join(f"    {toml_value(v)},\n" for v in value) + "]"
        else:
            text = f"{key} = {toml_value(value)}"
        if default is not MISSING and default is not None and value != default:
            text += f"   # default {toml_value(default)}"
        lines.append(text)
    lines += subtables


def render_config(cfg: SessionConfig) -> str:
    """A loaded configuration as TOML: every key with its value (defaults filled in, paths
    absolute, a non-default value followed by ``# default …``).

    :func:`~msk.config.load_config` of the text gives ``cfg`` again (but its ``path``).

    Args:
        cfg: a configuration from :func:`~msk.config.load_config`.

    Returns:
        The TOML text (ends with a newline).
    """
    lines = [f"# {cfg.path}: the configuration as msk reads it (every key, defaults filled in)"]
    for sec in SECTIONS:
        objs = getattr(cfg, sec.attr or "markers")
        for obj in objs if sec.array else [objs]:
            if obj is None:
                continue
            lines += ["", f"[[{sec.name}]]" if sec.array else f"[{sec.name}]"]
            _values(obj, lines, sec.name)
            if getattr(obj, "fes", None) is not None and sec.name == "trials":
                _values(obj.fes, lines, sec.name)
    return "\n".join(lines) + "\n"
