"""Session configuration (TOML): subject, model, trials and their roles, markers, EMG, filters.

Every key is checked: an unknown key or a missing file raises :class:`~msk.exceptions.ConfigError`
naming the key path (``trials[2].role``) or the file. Relative paths are relative to the config
file. ``msk print-config`` writes :data:`TEMPLATE`, a commented example.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from msk.exceptions import ConfigError

TRIAL_ROLES = ("static", "mass_identification", "mvc", "task", "fes")
KNEE_VARIANTS = ("spline", "four_bar")
OPTIMIZATION_METHODS = (
    "static_optimization",
    "bounded_qp",
    "emg_weighted",
    "emg_assisted",
    "closed_form",
)
#: static optimisation activation weights: uniform (OpenSim's Σ a^p) or muscle volume (Happee)
ACTIVATION_WEIGHTS = ("uniform", "volume")
#: The step of the FES identification protocol a ``role = "fes"`` trial records (seeds/000 §2.3):
#: passive static torques, pendulum drop, isometric trains at several knee angles (force–length),
#: isometric trains of increasing level at one angle (recruitment), the dynamic trial of the
#: ``k_s`` NLP, and the cross-validation trial.
FES_STEPS = ("static", "pendulum", "isometric", "recruitment", "dynamic", "validation")
FES_ANGLE_UNITS = ("deg", "rad")
#: ``us``/``s``: pulse-width modulation (seeds/000); ``mA``/``A``: current modulation (seeds/001).
FES_STIM_UNITS = ("us", "s", "mA", "A")
#: Per-trial keys valid only with ``role = "fes"`` (with their defaults).
FES_TRIAL_KEYS = (
    "fes_step",
    "time_column",
    "angle_channel",
    "torque_channel",
    "stimulation_channel",
    "angle_unit",
    "stimulation_unit",
    "knee_angle_deg",
)
#: How many trials of each step a FES session needs (at least).
FES_STEPS_NEEDED = {
    "static": 1,
    "pendulum": 1,
    "isometric": 3,
    "recruitment": 3,
    "dynamic": 1,
    "validation": 1,
}

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
# markers = "gait2392_Scale_MarkerSet.xml"   # OpenSim marker set of a .osim without markers

# One [[trials]] table per recording. role: static | mass_identification | mvc | task | fes
# (A session may hold only FES trials: [model] is then optional and the gait stages are skipped.)
# Several task trials: `msk run` analyses each into its own folder, <out>/<trial name>/.
[[trials]]
name = "static"
file = "../data/gc5-PS/PS_static_for_scaling.trc"
role = "static"

[[trials]]
name = "gait1"
file = "../data/gc5-PS/PS_ngait_og_ss1.c3d"
role = "task"
contact_force = "../data/gc5-PS/PS_ngait_og_ss1_eTibia.csv"   # optional measured knee force
# A task trial may be an OpenSim .trc (markers, +y up) with its forces in an OpenSim GRF .mot
# (ground_force_v*, ground_force_p*, ground_torque_* and 1_ground_… : one set per plate):
# file = "subject01_walk.trc"
# grf = "subject01_walk_grf.mot"   # same frame as the .trc (only with a .trc file)
# external_loads = "subject01_walk_grf.xml"   # OpenSim ExternalLoads: which body each force acts on

[markers]
# model marker name = lab label, when they differ
rename = {}
# IK weights by model marker name (default 1.0)
weights = {}
# model markers a lab places where it likes (thigh / shank clusters): moved to where the static
# trial puts them on their body (OpenSim's move_model_markers for these markers)
move = []

[emg]
# model muscle (or muscle group) = analog channel label
channels = { vasmed_l = "vasmed", vaslat_l = "vaslat", rect_fem_l = "rf" }
highpass_hz = 20.0
lowpass_hz = 6.0
electromechanical_delay_s = 0.04
# MVC envelope peak per channel (analog units): activations then relative to MVC, not to the
# session's own peak; or give MVC recordings as [[trials]] with role = "mvc"
# mvc = { vasmed = 0.31, vaslat = 0.29 }

[loads]
# explicit plate → body assignment (plates named plate1, plate2… in file order); default automatic
assign = {}

[contact]
# medial–lateral distance of the two tibiofemoral contact points (m); default: 40 mm scaled by
# the model's tibia (Lerner et al. 2015)
# intercondylar_distance_m = 0.04

[filters]
kinematics_cutoff_hz = 6.0
grf_cutoff_hz = 15.0

[optimization]
# static_optimization | bounded_qp | emg_weighted | emg_assisted | closed_form
method = "static_optimization"
w_emg = 0.1                      # EMG weight of the EMG-weighted QP (seed 002 Eq. 18)
w_track = 1.0                    # emg_assisted: weight of Σ (a_i − g_c ê_i)², gains fitted
solver = "daqp"
activation_weights = "uniform"   # static_optimization, emg_assisted: uniform | volume (Σ V a^p)
activation_exponent = 2.0        # static_optimization: p ≥ 2 (OpenSim's activation_exponent)

# FES knee-model identification (seeds/000): one [[trials]] table per recording with
# role = "fes" and fes_step = static | pendulum | isometric | recruitment | dynamic | validation
# (needs subject.height_m; at least 3 isometric and 3 recruitment trains). CSV files (header
# row) or C3D files (analog channels). The keys below are valid only with role = "fes".
# [[trials]]
# name = "fes_pendulum"
# file = "../data/fes/pendulum.csv"
# role = "fes"
# fes_step = "pendulum"
# time_column = "time"              # CSV only (s); a C3D uses its analog time
# angle_channel = "knee_angle"      # goniometer column / analog label (0 = full extension)
# torque_channel = "torque"         # dynamometer torque (N·m)
# stimulation_channel = "pw"        # stimulation level column / analog label
# angle_unit = "deg"                # deg | rad
# stimulation_unit = "us"           # us | s (pulse width) | mA | A (current)
# knee_angle_deg = 60.0             # isometric / recruitment: the dynamometer angle when the
#                                   # file has no angle channel

# [fes]
# fibre_fraction = 0.195    # prior L_c0/(L_c0 + L_s); default: the Table 3 population mean
# stiffness_ratio = 741.0   # prior K_cm/F_cm (1/m); default: the Table 3 population mean
#                           # (Benoussaad et al. 2013, Table 3: msk.fes.priors)
# k_s0 = 5000.0             # initial series stiffness of the NLP (N/m, literature value)
# outer_iterations = 6      # fixed-point passes on k_s (1 = the seed's single pass)
# frequency_hz = 20.0       # stimulation frequency
# steady_window_s = 0.5     # end-of-train window of the steady isometric torque
# isometric_transients = false   # refit on the torque time courses (short trains)
# theta_rest_deg = 90.0     # knee angle of the hanging shank (rest)
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
    #: an OpenSim marker-set ``.xml`` for a model whose markers are kept apart (stock ``.osim``)
    markers: Path | None = None


@dataclass(frozen=True)
class FesTrialConfig:
    """How to read one FES recording: its protocol step, channels and units."""

    step: str
    time_column: str = "time"
    angle_channel: str = "knee_angle"
    torque_channel: str = "torque"
    stimulation_channel: str = "stimulation"
    angle_unit: str = "deg"
    stimulation_unit: str = "us"
    knee_angle_deg: float | None = None


@dataclass(frozen=True)
class TrialConfig:
    name: str
    file: Path
    role: str
    contact_force: Path | None = None
    fes: FesTrialConfig | None = None
    #: OpenSim GRF ``.mot``/``.sto`` (``<prefix>force_v[xyz]``, ``force_p[xyz]``,
    #: ``torque_[xyz]`` per plate) of a ``.trc`` task trial, in the frame of its markers
    grf: Path | None = None
    #: OpenSim ExternalLoads ``.xml`` naming the body each force set of ``grf`` acts on
    external_loads: Path | None = None


@dataclass(frozen=True)
class FesConfig:
    """Options of the FES identification protocol (:func:`msk.fes.protocol.run_protocol`)."""

    #: priors of the identification; None: the population means of Benoussaad et al. (2013)
    #: Table 3 (:mod:`msk.fes.priors`), never a leg's own values
    fibre_fraction: float | None = None
    stiffness_ratio: float | None = None
    k_s0: float = 5e3
    outer_iterations: int = 6
    frequency_hz: float = 20.0
    steady_window_s: float = 0.5
    isometric_transients: bool = False
    theta_rest_deg: float = 90.0


@dataclass(frozen=True)
class EmgConfig:
    channels: Mapping[str, str] = field(default_factory=dict)
    highpass_hz: float = 20.0
    lowpass_hz: float = 6.0
    electromechanical_delay_s: float = 0.0
    #: channel label → MVC envelope peak in the channel's analog units (absolute activations);
    #: empty: each channel normalised to this session's peak (relative activations)
    mvc: Mapping[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class FilterConfig:
    kinematics_cutoff_hz: float = 6.0
    grf_cutoff_hz: float = 15.0


@dataclass(frozen=True)
class OptimizationConfig:
    method: str = "static_optimization"
    w_emg: float = 0.1
    solver: str = "daqp"
    #: static optimisation criterion Σ w_i a_i^p: weights ("uniform" | "volume") and p ≥ 2
    activation_weights: str = "uniform"
    activation_exponent: float = 2.0
    #: emg_assisted: weight of the EMG tracking term Σ (a_i − g_c ê_i)²
    w_track: float = 1.0


@dataclass(frozen=True)
class LoadsConfig:
    """``[loads]``: explicit plate → body assignment (plate names ``plate1``… in file order)."""

    assign: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class ContactConfig:
    """``[contact]``: tibiofemoral contact-point geometry (m); None: from the scaled model."""

    intercondylar_distance_m: float | None = None


@dataclass(frozen=True)
class SessionConfig:
    path: Path
    subject: Subject
    model: ModelConfig | None
    trials: tuple[TrialConfig, ...]
    marker_rename: Mapping[str, str] = field(default_factory=dict)
    marker_weights: Mapping[str, float] = field(default_factory=dict)
    #: model markers moved to where the static trial puts them (technical clusters)
    marker_move: tuple[str, ...] = ()
    emg: EmgConfig = field(default_factory=EmgConfig)
    filters: FilterConfig = field(default_factory=FilterConfig)
    optimization: OptimizationConfig = field(default_factory=OptimizationConfig)
    fes: FesConfig = field(default_factory=FesConfig)
    loads: LoadsConfig = field(default_factory=LoadsConfig)
    contact: ContactConfig = field(default_factory=ContactConfig)

    def trials_with_role(self, role: str) -> tuple[TrialConfig, ...]:
        return tuple(t for t in self.trials if t.role == role)


def _file_kind(p: Path) -> str:
    """What a path that is not a regular file is (for the error message)."""
    from msk.io.validate import path_kind

    return path_kind(p)


#: filter cut-offs (Hz): above ~0.01 Hz (a smaller one is no filter: a constant) and at most
#: 500 Hz (the Nyquist frequency of a 1 kHz analog rate)
MIN_CUTOFF_HZ = 0.01
MAX_CUTOFF_HZ = 500.0
#: electromechanical delay (s): physiological values are 10–100 ms
MAX_EMD_S = 0.2

#: a trial name: it becomes a folder name under ``--out``
_PLAIN_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9._-]{0,99}")


class _Section:
    """Reads one TOML table, remembering which keys were used; unknown keys are errors."""

    def __init__(self, table: Any, where: str, source: Path) -> None:
        if not isinstance(table, dict):
            raise ConfigError(f"{source}: [{where}] must be a table, got {type(table).__name__}")
        self.table, self.where, self.source = table, where, source
        self.used: set[str] = set()

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

    def number(
        self,
        key: str,
        default: Any,
        lo: float,
        hi: float,
        unit: str,
        *,
        lo_open: bool = False,
        hint: str = "",
    ) -> Any:
        """A finite float in ``[lo, hi]`` (``(lo, hi]`` with ``lo_open``), or ``default`` (which
        may be None: optional key) when absent; the message gives the unit and the range."""
        value = self.get(key, float, default)
        if value is None:
            return value
        low_ok = value > lo if lo_open else value >= lo
        if not (np.isfinite(value) and low_ok and value <= hi):
            rng = f"{'(' if lo_open else '['}{lo:g}, {hi:g}] {unit}"
            raise ConfigError(
                f"{self.source}: {self.where}.{key} = {value!r} {unit} is outside {rng}{hint}"
            )
        return float(value)

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
        if not p.is_file():  # a FIFO or /dev/zero would hang the reader, a folder is no file
            raise ConfigError(
                f"{self.source}: {self.where}.{key}: {p} is {_file_kind(p)}, not a regular file"
            )
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
    if not source.exists():
        raise ConfigError(f"config file not found: {source}")
    if not source.is_file():
        raise ConfigError(f"{source}: is {_file_kind(source)}, not a configuration file")
    try:
        raw = tomllib.loads(source.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"config file not found: {source}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(
            f"{source}: not UTF-8 text (invalid byte 0x{exc.object[exc.start]:02x} at offset "
            f"{exc.start}); save the configuration as UTF-8"
        ) from None
    except OSError as exc:
        raise ConfigError(f"{source}: cannot read: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: not valid TOML: {exc}") from None
    top = _Section(raw, "", source)

    s = _Section(top.get("subject", dict), "subject", source)
    mass = s.number("mass_kg", ..., 20.0, 300.0, "kg", hint=": not a plausible body mass")
    height = s.number(
        "height_m", None, 0.5, 2.5, "m", hint=": not a height in metres (1680 mm is 1.68 m)"
    )
    subject = Subject(
        name=s.get("name", str, "subject"),
        mass_kg=mass,
        height_m=height,
        sex=s.choice("sex", ("male", "female"), "male"),
        side=s.choice("side", ("left", "right"), "right"),
    )
    s.done()

    trials = []
    for i, t_raw in enumerate(top.get("trials", list)):
        t = _Section(t_raw, f"trials[{i}]", source)
        role = t.choice("role", TRIAL_ROLES, "task")
        name = t.get("name", str)
        if not _PLAIN_NAME.fullmatch(name) or name in (".", ".."):
            raise ConfigError(
                f"{source}: trials[{i}].name = {name!r} must be a plain name (letters, digits, "
                "'.', '_', '-'; no path separators): it names the trial's results folder"
            )
        tc = TrialConfig(
            name=name,
            file=t.path("file"),  # type: ignore[arg-type]
            role=role,
            contact_force=t.path("contact_force", required=False),
            fes=_fes_trial(t, role),
            grf=t.path("grf", required=False),
            external_loads=t.path("external_loads", required=False),
        )
        if tc.external_loads is not None and tc.grf is None:
            raise ConfigError(
                f"{source}: trials[{i}].external_loads goes with trials[{i}].grf (the GRF file "
                "whose force sets it assigns to bodies)"
            )
        if tc.grf is not None and role != "task":
            raise ConfigError(
                f"{source}: trials[{i}].grf is only valid with role = 'task' "
                f"(this trial has role = {role!r})"
            )
        if tc.grf is not None and tc.file.suffix.lower() != ".trc":
            raise ConfigError(
                f"{source}: trials[{i}].grf goes with a .trc trial file (a C3D has its own "
                f"plates, in its lab frame), got {tc.file.name}"
            )
        if role == "task" and tc.file.suffix.lower() == ".trc" and tc.grf is None:
            raise ConfigError(
                f"{source}: trials[{i}].file is a .trc (markers only): give its ground "
                f"reactions as trials[{i}].grf = an OpenSim GRF .mot"
            )
        trials.append(tc)
        t.done()
    only_fes = bool(trials) and all(tc.role == "fes" for tc in trials)

    model: ModelConfig | None = None
    if "model" in raw or not only_fes:
        m = _Section(top.get("model", dict), "model", source)
        model = ModelConfig(
            source=m.path("source"),  # type: ignore[arg-type]
            knee=m.choice("knee", KNEE_VARIANTS, "spline"),
            scale=m.get("scale", bool, True),
            markers=m.path("markers", required=False),
        )
        m.done()
    names = [t.name for t in trials]
    if len(set(names)) != len(names):
        raise ConfigError(f"{source}: trial names must be unique, got {names}")
    if not trials:
        raise ConfigError(f"{source}: no [[trials]] given")

    mk = _Section(top.get("markers", dict, {}), "markers", source)
    rename = dict(mk.get("rename", dict, {}))
    bad_r = [k for k, v in rename.items() if not isinstance(v, str) or not v.strip()]
    if bad_r:
        raise ConfigError(
            f"{source}: markers.rename.{bad_r[0]} = {rename[bad_r[0]]!r} should be a lab "
            "marker label (string)"
        )
    weights: dict[str, float] = {}
    for k, v in mk.get("weights", dict, {}).items():
        if isinstance(v, bool) or not isinstance(v, int | float) or not (np.isfinite(v) and v >= 0):
            raise ConfigError(
                f"{source}: markers.weights.{k} = {v!r} should be a finite number ≥ 0 "
                "(dimensionless IK weight)"
            )
        weights[k] = float(v)
    move = mk.get("move", list, [])
    if not all(isinstance(m, str) for m in move):
        raise ConfigError(f"{source}: markers.move = {move!r} should be a list of marker names")
    mk.done()

    e = _Section(top.get("emg", dict, {}), "emg", source)
    channels = dict(e.get("channels", dict, {}))
    bad_c = [k for k, v in channels.items() if not isinstance(v, str) or not v.strip()]
    if bad_c:
        raise ConfigError(
            f"{source}: emg.channels.{bad_c[0]} = {channels[bad_c[0]]!r} should be an analog "
            "channel label (string)"
        )
    delay = e.get("electromechanical_delay_s", float, 0.0)
    hint = ""
    if np.isfinite(delay) and 0.2 < delay <= 200.0:
        hint = f" (milliseconds typed as seconds? {delay:g} ms is {delay / 1000:g} s)"
    emg = EmgConfig(
        channels=channels,
        highpass_hz=e.number("highpass_hz", 20.0, 0.0, MAX_CUTOFF_HZ, "Hz", lo_open=True),
        lowpass_hz=e.number("lowpass_hz", 6.0, 0.0, MAX_CUTOFF_HZ, "Hz", lo_open=True),
        electromechanical_delay_s=e.number(
            "electromechanical_delay_s", 0.0, 0.0, MAX_EMD_S, "s", hint=hint
        ),
        mvc=dict(e.get("mvc", dict, {})),
    )
    for ch, v in emg.mvc.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or v <= 0:
            raise ConfigError(
                f"{source}: emg.mvc.{ch} = {v!r} should be a positive number (the MVC envelope "
                "peak, in the channel's analog units)"
            )
        if ch not in emg.channels.values():
            raise ConfigError(
                f"{source}: emg.mvc names channel {ch!r}, which no muscle in emg.channels uses"
            )
    e.done()

    f = _Section(top.get("filters", dict, {}), "filters", source)
    filters = FilterConfig(
        kinematics_cutoff_hz=f.number(
            "kinematics_cutoff_hz", 6.0, MIN_CUTOFF_HZ, MAX_CUTOFF_HZ, "Hz"
        ),
        grf_cutoff_hz=f.number("grf_cutoff_hz", 15.0, MIN_CUTOFF_HZ, MAX_CUTOFF_HZ, "Hz"),
    )
    f.done()

    o = _Section(top.get("optimization", dict, {}), "optimization", source)
    optimization = OptimizationConfig(
        method=o.choice("method", OPTIMIZATION_METHODS, "static_optimization"),
        w_emg=o.number("w_emg", 0.1, 0.0, 1e6, "(dimensionless)"),
        solver=_solver(o),
        activation_weights=o.choice("activation_weights", ACTIVATION_WEIGHTS, "uniform"),
        activation_exponent=o.get("activation_exponent", float, 2.0),
        w_track=o.get("w_track", float, 1.0),
    )
    o.done()
    if not (
        np.isfinite(optimization.activation_exponent) and optimization.activation_exponent >= 2
    ):
        raise ConfigError(
            f"{source}: optimization.activation_exponent = {optimization.activation_exponent} "
            "should be ≥ 2"
        )
    if not (np.isfinite(optimization.w_track) and optimization.w_track > 0):
        raise ConfigError(f"{source}: optimization.w_track = {optimization.w_track} should be > 0")

    fz = _Section(top.get("fes", dict, {}), "fes", source)
    fes = FesConfig(
        fibre_fraction=fz.get("fibre_fraction", float, None),
        stiffness_ratio=fz.get("stiffness_ratio", float, None),
        k_s0=fz.get("k_s0", float, 5e3),
        outer_iterations=fz.get("outer_iterations", int, 6),
        frequency_hz=fz.get("frequency_hz", float, 20.0),
        steady_window_s=fz.get("steady_window_s", float, 0.5),
        isometric_transients=fz.get("isometric_transients", bool, False),
        theta_rest_deg=fz.number("theta_rest_deg", 90.0, 0.0, 180.0, "deg"),
    )
    for key, lo, hi in (
        ("fibre_fraction", 0.0, 1.0),
        ("stiffness_ratio", 0.0, np.inf),
        ("k_s0", 0.0, np.inf),
        ("frequency_hz", 0.0, np.inf),
        ("steady_window_s", 0.0, np.inf),
    ):
        v = getattr(fes, key)
        if v is not None and not lo < v < hi:
            raise ConfigError(f"{source}: fes.{key} = {v} should be in ({lo}, {hi})")
    if not 1 <= fes.outer_iterations <= 100:
        raise ConfigError(
            f"{source}: fes.outer_iterations = {fes.outer_iterations} should be in 1–100"
        )
    fz.done()
    fes_trials = [tc for tc in trials if tc.role == "fes"]
    if fes_trials:
        _check_fes_session(source, fes_trials, height)
    ld = _Section(top.get("loads", dict, {}), "loads", source)
    assign = ld.get("assign", dict, {})
    bad = [k for k, v in assign.items() if not isinstance(v, str)]
    if bad:
        raise ConfigError(f"{source}: loads.assign.{bad[0]} should be a body name (string)")
    loads = LoadsConfig(assign=dict(assign))
    ld.done()
    ct = _Section(top.get("contact", dict, {}), "contact", source)
    icd = ct.get("intercondylar_distance_m", float, None)
    if icd is not None and not (np.isfinite(icd) and 0.01 <= icd <= 0.10):
        raise ConfigError(
            f"{source}: contact.intercondylar_distance_m = {icd!r} m should be in 0.01–0.10 m "
            "(adult knees: about 0.04 m)"
        )
    contact = ContactConfig(intercondylar_distance_m=icd)
    ct.done()
    top.done()

    return SessionConfig(
        path=source,
        subject=subject,
        model=model,
        trials=tuple(trials),
        marker_rename=rename,
        marker_weights=weights,
        marker_move=tuple(move),
        emg=emg,
        filters=filters,
        optimization=optimization,
        fes=fes,
        loads=loads,
        contact=contact,
    )


def _solver(o: _Section) -> str:
    """``optimization.solver``: one of the registered QP solvers (a typo is a config error,
    not a failed stage)."""
    from msk.optimization import available_solvers

    name = o.get("solver", str, "daqp")
    known = available_solvers()
    if name not in known:
        raise ConfigError(
            f"{o.source}: optimization.solver = {name!r} is not one of {', '.join(known)}"
        )
    return name


def _fes_trial(t: _Section, role: str) -> FesTrialConfig | None:
    """The ``role = "fes"`` keys of one trial; they are errors on any other role."""
    if role != "fes":
        given = [k for k in FES_TRIAL_KEYS if k in t.table]
        if given:
            raise ConfigError(
                f"{t.source}: {t.where}.{given[0]} is only valid with role = 'fes' "
                f"(this trial has role = {role!r})"
            )
        return None
    if "fes_step" not in t.table:
        raise ConfigError(
            f"{t.source}: missing key {t.where}.fes_step (role = 'fes' needs one of "
            f"{', '.join(FES_STEPS)})"
        )
    knee = t.get("knee_angle_deg", float, None)
    if knee is not None and not -30.0 <= knee <= 180.0:
        raise ConfigError(f"{t.source}: {t.where}.knee_angle_deg = {knee} is not a knee angle")
    return FesTrialConfig(
        step=t.choice("fes_step", FES_STEPS, "static"),
        time_column=t.get("time_column", str, "time"),
        angle_channel=t.get("angle_channel", str, "knee_angle"),
        torque_channel=t.get("torque_channel", str, "torque"),
        stimulation_channel=t.get("stimulation_channel", str, "stimulation"),
        angle_unit=t.choice("angle_unit", FES_ANGLE_UNITS, "deg"),
        stimulation_unit=t.choice("stimulation_unit", FES_STIM_UNITS, "us"),
        knee_angle_deg=knee,
    )


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
