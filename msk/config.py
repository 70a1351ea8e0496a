"""Session configuration (TOML): subject, model, trials and their roles, markers, EMG, filters.

Every key is checked: an unknown key or a missing file raises :class:`~msk.exceptions.ConfigError`
naming the key path (``trials[2].role``) or the file. Relative paths are relative to the config
file. ``msk print-config`` writes :data:`TEMPLATE`, a commented example.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from msk.exceptions import ConfigError

TRIAL_ROLES = ("static", "mass_identification", "mvc", "task", "fes")
KNEE_VARIANTS = ("spline", "four_bar")
OPTIMIZATION_METHODS = ("static_optimization", "bounded_qp", "emg_weighted", "closed_form")

TEMPLATE = """\
# msk session configuration. Paths are relative to this file. Units are SI unless the key says.

[subject]
name = "PS"            # used in the report
mass_kg = 75.0         # body mass; the static trial's plates are checked against it
height_m = 1.70
sex = "male"           # "male" | "female": picks the anthropometric table rows
side = "left"          # side of interest (instrumented knee, affected limb)

[model]
source = "../models/gait2392.toml"   # an msk model file (.toml) or an OpenSim model (.osim)
knee = "spline"                      # "spline" (gait2392 knee) | "four_bar" (seed 004)
scale = true                         # scale to the static trial's marker distances

# One [[trials]] table per recording. role: static | mass_identification | mvc | task | fes
[[trials]]
name = "static"
file = "../data/gc5-PS/PS_static_for_scaling.trc"
role = "static"

[[trials]]
name = "gait1"
file = "../data/gc5-PS/PS_ngait_og_ss1.c3d"
role = "task"
contact_force = "../data/gc5-PS/PS_ngait_og_ss1_eTibia.csv"   # optional measured knee force

[markers]
# model marker name = lab label, when they differ
rename = {}
# IK weights by model marker name (default 1.0)
weights = {}

[emg]
# model muscle (or muscle group) = analog channel label
channels = { vasmed_l = "vasmed", vaslat_l = "vaslat", rect_fem_l = "rf" }
highpass_hz = 20.0
lowpass_hz = 6.0
electromechanical_delay_s = 0.04

[filters]
kinematics_cutoff_hz = 6.0
grf_cutoff_hz = 15.0

[optimization]
method = "static_optimization"   # static_optimization | bounded_qp | emg_weighted | closed_form
w_emg = 0.1                      # EMG weight of the EMG-weighted QP (seed 002 Eq. 18)
solver = "daqp"
"""


@dataclass(frozen=True)
class Subject:
    name: str
    mass_kg: float
    height_m: float | None = None
    sex: str = "male"
    side: str = "right"


@dataclass(frozen=True)
class ModelConfig:
    source: Path
    knee: str = "spline"
    scale: bool = True


@dataclass(frozen=True)
class TrialConfig:
    name: str
    file: Path
    role: str
    contact_force: Path | None = None


@dataclass(frozen=True)
class EmgConfig:
    channels: Mapping[str, str] = field(default_factory=dict)
    highpass_hz: float = 20.0
    lowpass_hz: float = 6.0
    electromechanical_delay_s: float = 0.0


@dataclass(frozen=True)
class FilterConfig:
    kinematics_cutoff_hz: float = 6.0
    grf_cutoff_hz: float = 15.0


@dataclass(frozen=True)
class OptimizationConfig:
    method: str = "static_optimization"
    w_emg: float = 0.1
    solver: str = "daqp"


@dataclass(frozen=True)
class SessionConfig:
    path: Path
    subject: Subject
    model: ModelConfig
    trials: tuple[TrialConfig, ...]
    marker_rename: Mapping[str, str] = field(default_factory=dict)
    marker_weights: Mapping[str, float] = field(default_factory=dict)
    emg: EmgConfig = field(default_factory=EmgConfig)
    filters: FilterConfig = field(default_factory=FilterConfig)
    optimization: OptimizationConfig = field(default_factory=OptimizationConfig)

    def trials_with_role(self, role: str) -> tuple[TrialConfig, ...]:
        return tuple(t for t in self.trials if t.role == role)


class _Section:
    """Reads one TOML table, remembering which keys were used; unknown keys are errors."""

    def __init__(self, table: Any, where: str, source: Path) -> None:
        if not isinstance(table, dict):
            raise ConfigError(f"{source}: [{where}] must be a table, got {type(table).__name__}")
        self.table, self.where, self.source, self.used = table, where, source, set()

    def get(self, key: str, kind: type | tuple[type, ...], default: Any = ...) -> Any:
        self.used.add(key)
        if key not in self.table:
            if default is ...:
                raise ConfigError(f"{self.source}: missing key {self.where}.{key}")
            return default
        value = self.table[key]
        if kind is float and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if not isinstance(value, kind):
            raise ConfigError(
                f"{self.source}: {self.where}.{key} = {value!r} should be "
                f"{getattr(kind, '__name__', kind)}"
            )
        return value

    def choice(self, key: str, choices: tuple[str, ...], default: str) -> str:
        value = self.get(key, str, default)
        if value not in choices:
            raise ConfigError(
                f"{self.source}: {self.where}.{key} = {value!r} is not one of {', '.join(choices)}"
            )
        return value

    def path(self, key: str, *, required: bool = True) -> Path | None:
        value = self.get(key, str, ... if required else None)
        if value is None:
            return None
        p = (self.source.parent / value).resolve()
        if not p.exists():
            raise ConfigError(f"{self.source}: {self.where}.{key}: file not found: {p}")
        return p

    def done(self) -> None:
        unknown = sorted(set(self.table) - self.used)
        if unknown:
            raise ConfigError(
                f"{self.source}: unknown key {self.where}.{unknown[0]}"
                + (f" (and {len(unknown) - 1} more)" if len(unknown) > 1 else "")
            )


def load_config(path: str | Path) -> SessionConfig:
    """Read and validate a session configuration file."""
    source = Path(path).resolve()
    try:
        raw = tomllib.loads(source.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"config file not found: {source}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: not valid TOML: {exc}") from None
    top = _Section(raw, "", source)

    s = _Section(top.get("subject", dict), "subject", source)
    mass = s.get("mass_kg", float)
    if not 10.0 <= mass <= 300.0:
        raise ConfigError(f"{source}: subject.mass_kg = {mass} is not a plausible body mass (kg)")
    height = s.get("height_m", float, None)
    if height is not None and not 0.5 <= height <= 2.5:
        raise ConfigError(f"{source}: subject.height_m = {height} is not a height in metres")
    subject = Subject(
        name=s.get("name", str, "subject"),
        mass_kg=mass,
        height_m=height,
        sex=s.choice("sex", ("male", "female"), "male"),
        side=s.choice("side", ("left", "right"), "right"),
    )
    s.done()

    m = _Section(top.get("model", dict), "model", source)
    model = ModelConfig(
        source=m.path("source"),  # type: ignore[arg-type]
        knee=m.choice("knee", KNEE_VARIANTS, "spline"),
        scale=m.get("scale", bool, True),
    )
    m.done()

    trials = []
    for i, t_raw in enumerate(top.get("trials", list)):
        t = _Section(t_raw, f"trials[{i}]", source)
        trials.append(
            TrialConfig(
                name=t.get("name", str),
                file=t.path("file"),  # type: ignore[arg-type]
                role=t.choice("role", TRIAL_ROLES, "task"),
                contact_force=t.path("contact_force", required=False),
            )
        )
        t.done()
    names = [t.name for t in trials]
    if len(set(names)) != len(names):
        raise ConfigError(f"{source}: trial names must be unique, got {names}")
    if not trials:
        raise ConfigError(f"{source}: no [[trials]] given")

    mk = _Section(top.get("markers", dict, {}), "markers", source)
    rename = dict(mk.get("rename", dict, {}))
    weights = {k: float(v) for k, v in mk.get("weights", dict, {}).items()}
    if any(w < 0 for w in weights.values()):
        raise ConfigError(f"{source}: markers.weights must be ≥ 0")
    mk.done()

    e = _Section(top.get("emg", dict, {}), "emg", source)
    emg = EmgConfig(
        channels=dict(e.get("channels", dict, {})),
        highpass_hz=e.get("highpass_hz", float, 20.0),
        lowpass_hz=e.get("lowpass_hz", float, 6.0),
        electromechanical_delay_s=e.get("electromechanical_delay_s", float, 0.0),
    )
    e.done()

    f = _Section(top.get("filters", dict, {}), "filters", source)
    filters = FilterConfig(
        kinematics_cutoff_hz=f.get("kinematics_cutoff_hz", float, 6.0),
        grf_cutoff_hz=f.get("grf_cutoff_hz", float, 15.0),
    )
    f.done()

    o = _Section(top.get("optimization", dict, {}), "optimization", source)
    optimization = OptimizationConfig(
        method=o.choice("method", OPTIMIZATION_METHODS, "static_optimization"),
        w_emg=o.get("w_emg", float, 0.1),
        solver=o.get("solver", str, "daqp"),
    )
    o.done()
    top.done()
    return SessionConfig(
        path=source,
        subject=subject,
        model=model,
        trials=tuple(trials),
        marker_rename=rename,
        marker_weights=weights,
        emg=emg,
        filters=filters,
        optimization=optimization,
    )
