"""The session-config schema (issue 14): the options dataclasses of :mod:`msk.config` are the
schema; validation, ``msk print-config`` and ``docs/config.md`` are generated from them.

Every shipped ``pipelines/*.toml`` loads into the same dataclasses as before the schema was
declared (``tests/golden/config/<config>.json``, written by the previous hand-written reader;
``MSK_UPDATE_GOLDEN=1`` refreshes them after an intended change).
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pytest

from msk.config import (
    SECTIONS,
    TEMPLATE,
    FesTrialConfig,
    SessionConfig,
    config_reference,
    load_config,
    render_config,
)
from msk.config.schema import OPTION, Option
from msk.exceptions import ConfigError

REPO = Path(__file__).resolve().parents[1]
CONFIGS = sorted((REPO / "pipelines").glob("*.toml"))
GOLDEN = REPO / "tests" / "golden" / "config"


def plain(x: Any) -> Any:
    """A loaded configuration as JSON values, with its types (paths relative to the repo)."""
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        fields = {f.name: plain(getattr(x, f.name)) for f in dataclasses.fields(x)}
        return {"__type__": type(x).__name__, **fields}
    if isinstance(x, Mapping):
        return {str(k): plain(v) for k, v in x.items()}
    if isinstance(x, tuple | list):
        return [plain(v) for v in x]
    if isinstance(x, Path):
        # the shared data may be a symlink beside the clone: relative to its resolved root
        shared = (REPO.parent / "shared").resolve()
        rx = Path(x).resolve()
        if rx.is_relative_to(shared):
            return {"path": os.path.join("..", "shared", os.path.relpath(rx, shared))}
        return {"path": os.path.relpath(rx, REPO.resolve())}
    if isinstance(x, float):
        return {"float": repr(x)}
    return x


@pytest.mark.parametrize("config", CONFIGS, ids=[c.stem for c in CONFIGS])
def test_shipped_configs_load_unchanged(config: Path) -> None:
    try:
        got = plain(load_config(config))
    except ConfigError as exc:
        if "file not found" in str(exc):
            pytest.skip(f"{config.name}: its recordings are not here")
        raise
    golden = GOLDEN / f"{config.stem}.json"
    if os.environ.get("MSK_UPDATE_GOLDEN") == "1":
        golden.write_text(json.dumps(got, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    assert got == json.loads(golden.read_text(encoding="utf-8"))


# --- the reference is generated from the dataclasses and agrees with load_config -------------
_DESC = re.compile(r"^# (\w+) \(")
_LINE = re.compile(r"^(# )?(\w+) = (.*)$")
_FES_MARK = '# --- valid only with role = "fes"'


def reference_keys() -> dict[tuple[str, str], str | None]:
    """(table, key) → the default's TOML text (None: no default line) of the reference; the
    ``role = "fes"`` trial keys are in table ``fes_trial``."""
    keys: dict[tuple[str, str], str | None] = {}
    table = ""
    for line in config_reference().splitlines():
        if m := re.fullmatch(r"\[\[?(\w+)\]\]?", line):
            table = m.group(1)
        elif line.startswith(_FES_MARK):
            table = "fes_trial"
        elif m := _DESC.match(line):
            keys[(table, m.group(1))] = None
        elif (m := _LINE.match(line)) and (table, m.group(2)) in keys:
            keys[(table, m.group(2))] = m.group(3)
    return keys


def _options(cls: type) -> list[tuple[dataclasses.Field, Option]]:
    return [(f, f.metadata[OPTION]) for f in dataclasses.fields(cls) if OPTION in f.metadata]


def test_every_field_of_every_options_dataclass_is_in_the_reference() -> None:
    keys = reference_keys()
    tables = {(s.name if s.options is not FesTrialConfig else "fes_trial") for s in SECTIONS}
    seen = 0
    for table, cls in [(s.name, s.options) for s in SECTIONS] + [("fes_trial", FesTrialConfig)]:
        assert table in tables | {"fes_trial"}
        for f in dataclasses.fields(cls):
            if OPTION not in f.metadata:  # a nested table of keys (TrialConfig.fes)
                assert dataclasses.is_dataclass(typing.get_type_hints(cls)[f.name].__args__[0])
                continue
            o = f.metadata[OPTION]
            key = o.key or f.name
            assert (table, key) in keys, (cls.__name__, f.name)
            assert o.meaning and not o.meaning.endswith(".")
            seen += 1
    assert seen == len(keys)
    # every SessionConfig field but its path is a table (markers: flattened)
    attrs = {s.attr for s in SECTIONS} | {
        "marker_rename", "marker_weights", "marker_move", "marker_virtual",
    }  # fmt: skip
    assert {f.name for f in dataclasses.fields(SessionConfig)} - attrs == {"path"}


def _defaults_of(cls: type) -> dict[str, Any]:
    out = {}
    for f, o in _options(cls):
        if f.default_factory is not dataclasses.MISSING:
            out[o.key or f.name] = f.default_factory()
        elif f.default is not dataclasses.MISSING:
            out[o.key or f.name] = f.default
    return out


@pytest.fixture()
def tree(tmp_path: Path) -> Path:
    """A session folder: a model file, a static and a task recording (empty files)."""
    for name in ("model.toml", "static.trc", "walk.c3d"):
        (tmp_path / name).write_text("")
    return tmp_path


_BASE = {
    "subject": "mass_kg = 70.0\nheight_m = 1.75\n",
    "model": 'source = "model.toml"\n',
    "trials": 'name = "walk"\nfile = "walk.c3d"\n',
}


def _session(tables: dict[str, str]) -> str:
    """A config with the base keys plus ``tables`` (table name → its key lines)."""
    text = ""
    for name in ["subject", "model", "trials"] + [t for t in tables if t not in _BASE]:
        given = {line.split(" = ")[0] for line in tables.get(name, "").splitlines()}
        base = _BASE.get(name, "").splitlines(True)
        base = [ln for ln in base if ln.split(" = ")[0] not in given]
        body = "".join(base) + tables.get(name, "")
        text += f"[[{name}]]\n{body}\n" if name == "trials" else f"[{name}]\n{body}\n"
    return text


def _fes_session(tree: Path, extra: str = "") -> str:
    """A FES-only session (every protocol step); ``extra`` lines go in its first trial."""
    steps = (
        ["static", "pendulum", "dynamic", "validation"] + ["isometric"] * 3 + ["recruitment"] * 3
    )
    text = "[subject]\nmass_kg = 70.0\nheight_m = 1.75\n\n"
    for k, step in enumerate(steps):
        (tree / f"f{k}.csv").write_text("time\n0\n")
        text += f'[[trials]]\nname = "f{k}"\nfile = "f{k}.csv"\nrole = "fes"\n'
        text += f'fes_step = "{step}"\n' + (extra if k == 0 else "") + "\n"
    return text


def _load(tree: Path, text: str) -> SessionConfig:
    path = tree / "s.toml"
    path.write_text(text, encoding="utf-8")
    return load_config(path)


def _loaded(cfg: SessionConfig, table: str) -> Any:
    if table == "fes_trial":
        return cfg.trials[0].fes
    if table == "trials":
        return cfg.trials[0]
    if table == "markers":
        return cfg.markers
    return getattr(cfg, table)


def test_every_key_of_the_reference_is_accepted_with_its_default(tree: Path) -> None:
    classes = {s.name: s.options for s in SECTIONS} | {"fes_trial": FesTrialConfig}
    with_default = {k: v for k, v in reference_keys().items() if v is not None}
    assert len(with_default) == 50  # plateau_depth_m, grf_cutoff_hz have no default
    for (table, key), literal in with_default.items():
        line = f"{key} = {literal}\n"
        if table == "fes_trial":
            cfg = _load(tree, _fes_session(tree, line))
        else:
            cfg = _load(tree, _session({table: line}))
        f = next(f for f, o in _options(classes[table]) if (o.key or f.name) == key)
        assert getattr(_loaded(cfg, table), f.name) == _defaults_of(classes[table])[key]


def test_a_config_written_from_the_reference_defaults_loads(tree: Path) -> None:
    """The reference, with its required keys given, is a configuration; every key it sets loads
    as the dataclass default."""
    required = {
        ("model", "source"): '"model.toml"',
        ("trials", "name"): '"walk"',
        ("trials", "file"): '"walk.c3d"',
    }
    lines, table = [], ""
    for line in config_reference().splitlines():
        lines.append(line)
        if m := re.fullmatch(r"\[\[?(\w+)\]\]?", line):
            table = m.group(1)
        if (m := _DESC.match(line)) and (table, m.group(1)) in required:
            lines.append(f"{m.group(1)} = {required[(table, m.group(1))]}")
    cfg = _load(tree, "\n".join(lines) + "\n")
    for sec in SECTIONS:
        defaults = _defaults_of(sec.options)
        got = _loaded(cfg, sec.name)
        for f, o in _options(sec.options):
            if (o.key or f.name) in defaults:
                assert getattr(got, f.name) == defaults[o.key or f.name], (sec.name, f.name)
    # the commented role = "fes" keys, uncommented in a FES trial, load too
    fes_lines = [
        line[2:]
        for line in config_reference().split(_FES_MARK)[1].split("\n\n")[0].splitlines()[1:]
        if _LINE.match(line)
    ]
    assert len(fes_lines) == 6
    cfg = _load(tree, _fes_session(tree, "\n".join(fes_lines) + "\n"))
    assert cfg.trials[0].fes == FesTrialConfig(step="static")


def _bad_value(tp: Any, o: Option) -> tuple[str, str]:
    """A value of the wrong kind or out of range for a key, and the text its message has."""
    if o.bounds is not None and not typing.get_origin(tp):
        value = -(10**9) if o.bounds.half_open else 10**9
        return (str(value if tp is int else float(value)), o.bounds.text(o.unit))
    if (allowed := o.allowed()) is not None:
        return ('"bogus"', "is not one of " + ", ".join(allowed))
    return ("{ a = { b = 1 } }", "should be")


@pytest.mark.parametrize(
    ("table", "cls"),
    [(s.name, s.options) for s in SECTIONS] + [("fes_trial", FesTrialConfig)],
    ids=[s.name for s in SECTIONS] + ["fes_trial"],
)
def test_every_key_refuses_a_bad_value_in_one_line(tree: Path, table: str, cls: type) -> None:
    """A wrong type, an out-of-range number (with its unit) or a value not allowed (listing the
    allowed ones): one line naming the file and the key."""
    hints = typing.get_type_hints(cls)
    for f, o in _options(cls):
        key = o.key or f.name
        value, expected = _bad_value(hints[f.name], o)
        line = f"{key} = {value}\n"
        text = _fes_session(tree, line) if table == "fes_trial" else _session({table: line})
        if table == "fes_trial" and key == "fes_step":
            text = text.replace('fes_step = "static"\n', "", 1)
        with pytest.raises(ConfigError) as exc:
            _load(tree, text)
        msg = str(exc.value)
        where = {"fes_trial": "trials[0]", "trials": "trials[0]"}.get(table, table)
        assert "\n" not in msg and msg.startswith(str(tree / "s.toml")), msg
        assert f"{where}.{key}" in msg and expected in msg, msg


def test_unknown_keys_name_a_suggestion_or_the_allowed_keys(tree: Path) -> None:
    with pytest.raises(ConfigError, match=r"unknown key emg\.lowpas_hz \(did you mean lowpass_hz"):
        _load(tree, _session({"emg": "lowpas_hz = 6.0\n"}))
    allowed = r"allowed: kinematics_cutoff_hz, grf_cutoff_hz, acceleration_domain$"
    with pytest.raises(ConfigError, match=allowed):
        _load(tree, _session({"filters": "colour = 3\n"}))
    with pytest.raises(ConfigError, match=r"unknown key optimisation \(did you mean optimization"):
        _load(tree, _session({"optimisation": "w_emg = 0.2\n"}))


def test_render_config_round_trips(tree: Path) -> None:
    """The resolved configuration loads back to the same dataclasses (shipped configs too)."""
    text = _session({"emg": 'channels = { "vas med" = "VM" }\nmvc = { VM = 2 }\nlowpass_hz = 8\n'})
    cfg = _load(tree, text)
    out = render_config(cfg)
    assert "lowpass_hz = 8.0   # default 6.0" in out and "# height_m" not in out
    again = _load(tree, out)
    assert again == cfg
    for config in CONFIGS:
        try:
            cfg = load_config(config)
        except ConfigError:
            continue
        assert dataclasses.replace(_load(tree, render_config(cfg)), path=cfg.path) == cfg


DOC = REPO / "docs" / "config.md"
_DOC_HEAD = """\
# Session configuration reference

Generated from the options dataclasses of `msk.config` by `msk.config.config_reference()`; `msk
print-config` prints the same text. Do not edit by hand: `MSK_UPDATE_DOCS=1 pytest
tests/test_config_schema.py` rewrites it after a change of the schema (a test checks it matches).
A commented example session is `msk.config.TEMPLATE`; the shipped sessions are in `pipelines/`.

"""


def test_docs_config_md_is_the_reference() -> None:
    text = _DOC_HEAD + "```toml\n" + config_reference() + "```\n"
    if os.environ.get("MSK_UPDATE_DOCS") == "1":
        DOC.write_text(text, encoding="utf-8")
    assert DOC.read_text(encoding="utf-8") == text, "docs/config.md: MSK_UPDATE_DOCS=1 rewrites it"


def test_template_keys_are_schema_keys() -> None:
    """Every key the commented example names, commented out or not, is a key of the schema."""
    keys = {k for _, k in reference_keys()}
    table_keys = {s.name for s in SECTIONS}
    for line in TEMPLATE.splitlines():
        m = re.match(r"^(?:# )?(\w+) = ", line)
        if m and not line.startswith("#   "):
            assert m.group(1) in keys or m.group(1) in table_keys, line
