"""The options dataclasses: the schema of the TOML session configuration.

Each field that is a TOML key is declared with :func:`~msk.config.schema.opt` (meaning, unit,
range or allowed values); its type is the annotation and its default the field's default (none:
required). :data:`SECTIONS` lists the tables in the order of the reference.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from msk.config.schema import Range, opt

__all__ = [
    "ACCELERATION_DOMAINS",
    "ACTIVATION_WEIGHTS",
    "FES_ANGLE_UNITS",
    "FES_STEPS",
    "FES_STEPS_NEEDED",
    "FES_STIM_UNITS",
    "KNEE_VARIANTS",
    "MAX_CUTOFF_HZ",
    "MAX_EMD_S",
    "MIN_CUTOFF_HZ",
    "OPTIMIZATION_METHODS",
    "SECTIONS",
    "TRIAL_ROLES",
    "ContactConfig",
    "EmgConfig",
    "FesConfig",
    "FesTrialConfig",
    "FilterConfig",
    "GaitConfig",
    "LoadsConfig",
    "MarkersConfig",
    "ModelConfig",
    "OptimizationConfig",
    "Section",
    "SessionConfig",
    "StrengthConfig",
    "Subject",
    "TrialConfig",
]

TRIAL_ROLES = ("static", "mass_identification", "mvc", "task", "fes", "functional")
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
#: The step of the FES identification protocol a ``role = "fes"`` trial records
#: (Benoussaad et al. 2013, §2.3): passive static torques, pendulum drop, isometric trains at
#: several knee angles (force–length), isometric trains of increasing level at one angle
#: (recruitment), the dynamic trial of the ``k_s`` NLP, and the cross-validation trial.
FES_STEPS = ("static", "pendulum", "isometric", "recruitment", "dynamic", "validation")
FES_ANGLE_UNITS = ("deg", "rad")
#: ``us``/``s``: pulse-width modulation (Benoussaad et al. 2013); ``mA``/``A``: current modulation
#: (the implanted-FES identification paper).
FES_STIM_UNITS = ("us", "s", "mA", "A")
#: How many trials of each step a FES session needs (at least).
FES_STEPS_NEEDED = {
    "static": 1,
    "pendulum": 1,
    "isometric": 3,
    "recruitment": 3,
    "dynamic": 1,
    "validation": 1,
}

#: where the low-pass the plates also get is applied for the whole-body COM acceleration: to the
#: coordinates θ only, or to every segment's COM (:mod:`msk.kinematics.com_consistency`)
ACCELERATION_DOMAINS = ("coordinates", "segment_com")

#: filter cut-offs (Hz): above ~0.01 Hz (a smaller one is no filter: a constant) and at most
#: 500 Hz (the Nyquist frequency of a 1 kHz analog rate)
MIN_CUTOFF_HZ = 0.01
MAX_CUTOFF_HZ = 500.0
#: electromechanical delay (s): physiological values are 10–100 ms
MAX_EMD_S = 0.2
_CUTOFF = Range(MIN_CUTOFF_HZ, MAX_CUTOFF_HZ)
_EMG_CUTOFF = Range(0.0, MAX_CUTOFF_HZ, lo_open=True)
_POSITIVE = Range(0.0, math.inf, lo_open=True)


def _solvers() -> tuple[str, ...]:
    from msk.optimization import available_solvers

    return available_solvers()


def _shipped_model(name: str) -> Path:
    """The file of the shipped model ``name`` (:func:`msk.model.files.model_file`)."""
    from msk.model.files import model_file

    return model_file(name)


def _ms_hint(delay: float) -> str:
    """``40`` given as a delay in seconds: say it looks like milliseconds."""
    if math.isfinite(delay) and 0.2 < delay <= 200.0:
        return f" (milliseconds typed as seconds? {delay:g} ms is {delay / 1000:g} s)"
    return ""


@dataclass(frozen=True, kw_only=True)
class Subject:
    """``[subject]``: who was measured."""

    name: str = opt("the subject's name, used in the report", "subject")
    mass_kg: float | None = opt(
        "body mass; the static trial's plates are checked against it. Omitted: the C3D's "
        "subject parameters (Bodymass, MASS, WEIGHT), else the static trial's plates weighing "
        "the subject standing still; summary.json subject.mass_source says which",
        None,
        unit="kg",
        bounds=Range(20.0, 300.0),
        hint=": not a plausible body mass",
    )
    height_m: float | None = opt(
        "body height; needed by FES trials (their muscle geometry comes from it)",
        None,
        unit="m",
        bounds=Range(0.5, 2.5),
        hint=": not a height in metres (1680 mm is 1.68 m)",
    )
    sex: str = opt("picks the anthropometric table rows", "male", choices=("male", "female"))
    side: str = opt(
        "side of interest (instrumented knee, affected limb)", "right", choices=("left", "right")
    )


@dataclass(frozen=True, kw_only=True)
class ModelConfig:
    """``[model]``: the musculoskeletal model (optional when every trial has role = "fes")."""

    source: Path = opt(
        "a shipped model by name (gait2392, gait2392_fourbar, rajagopal), an msk model file "
        "(.toml) or an OpenSim model (.osim)",
        named=_shipped_model,
    )
    knee: str = opt(
        "knee joint: spline (the gait2392 knee) or four_bar (the crossed four-bar knee of the "
        "rehabilitation-robot lower-limb model paper)",
        "spline",
        choices=KNEE_VARIANTS,
    )
    scale: bool = opt("scale the model to the static trial's marker distances", True)
    knee_varus_deg: float = opt(
        "frontal alignment of the side of interest's knee, given (imaging, implant record, the "
        "subject's own model; never fitted): tibia varus after flexion, valgus < 0 "
        "(msk.model.alignment; Lerner et al. 2015); 0: the generic model's neutral alignment",
        0.0,
        unit="deg",
        bounds=Range(-20.0, 20.0),
    )
    knee_alignment: str = opt(
        "where the side of interest's knee alignment comes from: given (knee_varus_deg, "
        "knee_medial_shift_m) or from_markers (estimated from the static trial's epicondyle "
        "and malleolus markers against the scaled model's, ±2–3°: "
        "msk.model.alignment.knee_varus_from_markers; then knee_varus_deg and the shift must be 0)",
        "given",
        choices=("given", "from_markers"),
    )
    knee_medial_shift_m: float = opt(
        "medio-lateral offset of that knee's tibia on the femur, medial > 0, given as "
        "knee_varus_deg (msk.model.alignment)",
        0.0,
        unit="m",
        bounds=Range(-0.03, 0.03),
    )
    hip_centre: str = opt(
        "where the hip joints sit in the pelvis: model (the generic model's hips scaled with "
        "its pelvis: the default, see docs/validation.md), harrington (regression on the "
        "static's pelvic width and depth, Harrington et al. 2007: within 5 mm of MRI; here "
        "33-41 mm anterior of gait2392's, a better marker fit but in-vivo knee contact worse "
        "with the current muscle calibration), davis (Plug-in Gait's, Davis et al. 1991; leg "
        "length, ASIS-to-trochanter and inter-ASIS distances from the file's PROCESSING "
        "parameters where present, else the leg from the ASIS-to-malleolus markers), bell "
        "(Bell et al. 1990); a regression needs both ASIS and both PSIS or a sacral marker, in "
        "the static trial or, without one, in the task (their shape in the pelvis frame over "
        "the motion), else the model's, said in summary.json (msk.personalise.hip_centre); a "
        "trial of role "
        "functional (the hips moved through their range, with a static) replaces it by the "
        "functional centre (sphere fit of the thigh markers in the pelvis) when that fits both "
        "hips",
        "model",
        choices=("model", "harrington", "davis", "bell"),
    )
    inertias: str = opt(
        "which identified segment inertias the dynamics downstream of the mass identification "
        "use (joint torques of the identified model, muscle forces, knee contact, gait "
        "kinetics): all (every identified segment: the posterior mean of the identification, "
        "shrunk towards the scaled model where the data say little — the default, see "
        "docs/validation.md, 'Inertias by status') or by_status (a segment's identified "
        "inertia only where its status is identified, the scaled model's elsewhere); "
        "summary.json identification.applied_to_dynamics lists the segments used",
        "all",
        choices=("by_status", "all"),
    )
    markers: Path | None = opt(
        "an OpenSim marker set (.xml) for a model whose markers are kept apart (stock .osim)",
        None,
    )


@dataclass(frozen=True, kw_only=True)
class FesTrialConfig:
    """Keys of a ``[[trials]]`` table valid only with ``role = "fes"``: how to read one FES
    recording (CSV with a header row, or C3D analog channels)."""

    step: str = opt(
        "the FES protocol step this recording is (role = 'fes' needs it)",
        key="fes_step",
        choices=FES_STEPS,
    )
    time_column: str = opt("CSV time column (s); a C3D uses its analog time", "time")
    angle_channel: str = opt(
        "knee angle column / analog label (goniometer; 0 = full extension)", "knee_angle"
    )
    torque_channel: str = opt("dynamometer torque column / analog label (N·m)", "torque")
    stimulation_channel: str = opt("stimulation level column / analog label", "stimulation")
    angle_unit: str = opt("unit of the angle channel", "deg", choices=FES_ANGLE_UNITS)
    stimulation_unit: str = opt(
        "unit of the stimulation channel: us, s (pulse width) or mA, A (current)",
        "us",
        choices=FES_STIM_UNITS,
    )
    knee_angle_deg: float | None = opt(
        "isometric / recruitment: the dynamometer's knee angle when the file has no angle channel",
        None,
        unit="deg",
        bounds=Range(-30.0, 180.0),
        hint=": not a knee angle",
    )


@dataclass(frozen=True, kw_only=True)
class TrialConfig:
    """``[[trials]]``: one table per recording."""

    name: str = opt("the trial's name: its results folder (letters, digits, '.', '_', '-')")
    file: Path = opt(
        "the recording: C3D; OpenSim .trc (markers, +y up, with grf); CSV or C3D for FES"
    )
    role: str = opt(
        "what the recording is for",
        "task",
        choices=TRIAL_ROLES,
    )
    contact_force: Path | None = opt(
        "measured knee contact force (CSV, e.g. Grand Challenge eTibia) to compare with", None
    )
    #: the ``role = "fes"`` keys of the same table (None on any other role)
    fes: FesTrialConfig | None = None
    grf: Path | None = opt(
        "task .trc only: its OpenSim GRF .mot (force_v*, force_p*, torque_* per plate), in the "
        "frame of its markers",
        None,
    )
    external_loads: Path | None = opt(
        "OpenSim ExternalLoads .xml naming the body each force set of grf acts on", None
    )


@dataclass(frozen=True, kw_only=True)
class MarkersConfig:
    """``[markers]``: lab marker names, IK weights, technical clusters (flattened into
    :class:`SessionConfig` as ``marker_rename``, ``marker_weights``, ``marker_move``,
    ``marker_virtual``)."""

    rename: Mapping[str, str] = opt(
        "model marker name = lab label, when they differ", {}, item="a lab marker label (string)"
    )
    weights: Mapping[str, float] = opt(
        "IK weight by model marker name (absent: 1.0)",
        {},
        bounds=Range(0.0),
        item="dimensionless IK weight",
    )
    move: tuple[str, ...] = opt(
        "model markers moved to where the static trial puts them on their body (clusters)",
        (),
        item="marker names",
    )
    virtual: Mapping[str, str] = opt(
        "virtual markers made from the measured ones in every trial, name = mean(A, B, ...) "
        '(their centroid, e.g. "V.Sacral" = "mean(LPSI, RPSI)") or offset(O, X, P, dx, dy, '
        "dz) (the point at dx, dy, dz m in the frame origin O, x toward X, z normal to the plane "
        "O X P); a model marker's name makes it that marker (msk.personalise.virtual_markers)",
        {},
        item="mean(A, B, ...) or offset(O, X, P, dx, dy, dz)",
    )


@dataclass(frozen=True, kw_only=True)
class EmgConfig:
    """``[emg]``: EMG channels and their envelope."""

    channels: Mapping[str, str] = opt(
        "model muscle (or muscle group) = analog channel label; a label the task file "
        "lacks is an error when an unmapped label is close to it (a typo), else its muscle "
        "is left untracked and flagged (emg_channels_missing)",
        {},
        item="an analog channel label (string)",
    )
    highpass_hz: float = opt(
        "high-pass cut-off before rectification", 20.0, unit="Hz", bounds=_EMG_CUTOFF
    )
    lowpass_hz: float = opt(
        "low-pass cut-off of the rectified envelope", 6.0, unit="Hz", bounds=_EMG_CUTOFF
    )
    electromechanical_delay_s: float = opt(
        "delay of the force after the EMG (physiological: 0.01–0.1 s)",
        0.0,
        unit="s",
        bounds=Range(0.0, MAX_EMD_S),
        hint=_ms_hint,
    )
    mvc: Mapping[str, float] = opt(
        "channel label = MVC envelope peak (channel's analog units): activations relative to "
        "MVC; empty: to the session's own peak (or give role = 'mvc' trials)",
        {},
        bounds=_POSITIVE,
        item="the MVC envelope peak, in the channel's analog units",
    )


@dataclass(frozen=True, kw_only=True)
class FilterConfig:
    """``[filters]``: low-pass cut-offs (zero-lag Butterworth)."""

    kinematics_cutoff_hz: float = opt(
        "low-pass cut-off of the joint coordinates before differentiation",
        6.0,
        unit="Hz",
        bounds=_CUTOFF,
    )
    grf_cutoff_hz: float | None = opt(
        "low-pass cut-off of the ground reactions; absent: the kinematics' cut-off (one filter "
        "on the markers and the plates: a force filtered above the accelerations it balances "
        "leaves its impact peak in the residuals and joint moments; Kristianslund et al. 2012 "
        "J Biomech 45:666, OpenSim's recommended practice)",
        None,
        unit="Hz",
        bounds=_CUTOFF,
    )
    acceleration_domain: str = opt(
        "where the whole-body COM acceleration is low-passed: 'coordinates' (θ low-passed, then "
        "differentiated) or 'segment_com' (each segment's COM low-passed as the plates are, the "
        "difference taken by the root's translations; msk.kinematics.com_consistency): for "
        "fast segment "
        "rotations (running), where a COM of low-passed θ is not the low-passed COM",
        "coordinates",
        choices=ACCELERATION_DOMAINS,
    )

    @property
    def grf_cutoff_used_hz(self) -> float:
        """The ground reactions' low-pass cut-off: ``grf_cutoff_hz``, absent: the kinematics'
        (Kristianslund et al. 2012: the same cut-off on both)."""
        return float(
            self.kinematics_cutoff_hz if self.grf_cutoff_hz is None else self.grf_cutoff_hz
        )

    def description(self) -> str:
        """What was low-passed, in words (``summary.methods.filtering``)."""
        where = (
            "each segment's centre of mass low-passed like the plates for the whole-body "
            "acceleration (the difference taken by the pelvis translations; "
            "msk.kinematics.com_consistency)"
            if self.acceleration_domain == "segment_com"
            else "velocities and accelerations differentiated from the low-passed coordinates"
        )
        return (
            f"joint coordinates low-passed at {self.kinematics_cutoff_hz:g} Hz and ground "
            f"reactions at {self.grf_cutoff_used_hz:g} Hz (4th-order Butterworth run forward and "
            f"backward: zero lag); {where}"
        )


@dataclass(frozen=True, kw_only=True)
class OptimizationConfig:
    """``[optimization]``: how muscle forces are solved."""

    method: str = opt("muscle-force solution", "static_optimization", choices=OPTIMIZATION_METHODS)
    w_emg: float = opt(
        "emg_weighted: EMG weight of the QP (Hayashibe et al. 2011, Eq. 18)",
        0.1,
        bounds=Range(0.0, 1e6),
    )
    solver: str = opt("QP solver", "daqp", choices=_solvers)
    activation_weights: str = opt(
        "static_optimization, emg_assisted: weights w_i of Σ w_i a_i^p: uniform (OpenSim) or "
        "muscle volume (Happee)",
        "uniform",
        choices=ACTIVATION_WEIGHTS,
    )
    activation_exponent: float = opt(
        "static_optimization: p of Σ w_i a_i^p (OpenSim's activation_exponent)",
        2.0,
        bounds=Range(2.0),
    )
    w_track: float = opt(
        "emg_assisted: weight of the tracking term Σ (a_i − g_c ê_i)², gains fitted",
        1.0,
        bounds=_POSITIVE,
    )
    emg_gains: str = opt(
        "emg_assisted: one EMG-to-activation gain per channel, or one gain common to every "
        "channel (each envelope normalised per channel, by its MVC or session peak: the "
        "channels keep their relative levels, so antagonists' measured activity is tracked "
        "rather than fitted away; Lloyd & Besier 2003)",
        "per_channel",
        choices=("per_channel", "common"),
    )
    compartment_nonnegative: bool = opt(
        "static_optimization, emg_assisted, emg_weighted, bounded_qp: require the medial and "
        "lateral contact forces of the side's knee (the [contact] two-point split) to be ≥ 0 "
        "in every frame's QP, a frontal reserve moment (penalised like a coordinate reserve) "
        "taking what no muscle can; a compartment cannot pull",
        False,
    )


@dataclass(frozen=True, kw_only=True)
class LoadsConfig:
    """``[loads]``: which body each force plate pushes."""

    assign: Mapping[str, str] = opt(
        "plate name (plate1, plate2… in file order) = body name; empty: automatic",
        {},
        item="a body name (string)",
    )
    surface_height_m: Mapping[str, float] = opt(
        "plate name = height of its standing surface above its corners (a step or platform "
        "built on the plate); absent: inferred from the feet standing on it "
        "(msk.dynamics.plate_surface)",
        {},
        unit="m",
        bounds=Range(-0.5, 2.0),
        item="height above the plate's corners (m)",
    )
    ignore: tuple[str, ...] = opt(
        "plates whose force is not used (a plate under no foot, or a broken one)",
        (),
        item="plate names",
    )
    remove_baseline: bool = opt(
        "remove a plate's steady offset in its unloaded frames (e.g. 30 N with nothing on it; "
        "msk.dynamics.plate_surface.plate_baseline)",
        True,
    )


@dataclass(frozen=True, kw_only=True)
class ContactConfig:
    """``[contact]``: tibiofemoral contact-point geometry."""

    intercondylar_distance_m: float | None = opt(
        "medial–lateral distance of the two contact points; absent: 40 mm scaled by the model's "
        "tibia (Lerner et al. 2015)",
        None,
        unit="m",
        bounds=Range(0.01, 0.10),
        hint=" (adult knees: about 0.04 m)",
    )
    plateau_depth_m: float | None = opt(
        "depth of the contact points below the knee centre (tibia-frame origin), given (imaging, "
        "the implant's geometry); absent: 22 mm scaled by the model's tibia (msk.contact.knee)",
        None,
        unit="m",
        bounds=Range(0.0, 0.08),
    )
    patella: str = opt(
        'how the quadriceps load the tibia: along the model\'s own paths ("none") or through '
        "the patellar tendon at van Eijden et al. (1985)'s angle, with the quadriceps' knee "
        'moment ("tendon", msk.contact.patella; the default, chosen on the Grand Challenge walks: '
        "docs/validation.md)",
        "tendon",
        choices=("none", "tendon"),
    )


@dataclass(frozen=True, kw_only=True)
class GaitConfig:
    """``[gait]``: how the gait report's angles are defined."""

    angle_convention: str = opt(
        "the definition of the report's knee flexion: model (the model's knee coordinate) or "
        "plug_in_gait (Plug-in Gait's: its chord-function knee and ankle centres from the "
        "thigh and shank wands, the file's PROCESSING knee and ankle widths where present, "
        "msk.gait.plug_in_gait); the reported angles only, never the model's dynamics; the "
        "hip and pelvis angles are Plug-in Gait's frames in both",
        "model",
        choices=("model", "plug_in_gait"),
    )


@dataclass(frozen=True, kw_only=True)
class FesConfig:
    """``[fes]``: the FES identification protocol (:func:`msk.fes.protocol.run_protocol`)."""

    fibre_fraction: float | None = opt(
        "prior L_c0/(L_c0 + L_s); absent: the population mean of Benoussaad et al. (2013) "
        "Table 3 (msk.fes.priors)",
        None,
        bounds=Range(0.0, 1.0, lo_open=True, hi_open=True),
    )
    stiffness_ratio: float | None = opt(
        "prior K_cm/F_cm; absent: the Table 3 population mean", None, unit="1/m", bounds=_POSITIVE
    )
    k_s0: float = opt(
        "initial series stiffness of the NLP (literature value)", 5e3, unit="N/m", bounds=_POSITIVE
    )
    outer_iterations: int = opt(
        "fixed-point passes on k_s (1 = the seed's single pass)", 6, bounds=Range(1, 100)
    )
    frequency_hz: float = opt("stimulation frequency", 20.0, unit="Hz", bounds=_POSITIVE)
    steady_window_s: float = opt(
        "end-of-train window of the steady isometric torque", 0.5, unit="s", bounds=_POSITIVE
    )
    isometric_transients: bool = opt("refit on the torque time courses (short trains)", False)
    theta_rest_deg: float = opt(
        "knee angle of the hanging shank (rest)", 90.0, unit="deg", bounds=Range(0.0, 180.0)
    )


@dataclass(frozen=True, kw_only=True)
class StrengthConfig:
    """``[strength]``: the trials ``msk strength`` pools into one strength identification
    (:mod:`msk.strength.pooled`)."""

    pool: tuple[str, ...] = opt(
        "names of the task and MVC trials whose rows are identified together (an MVC trial "
        "only if the plates measure its external force); the EMG is normalised by every MVC "
        "trial's peak, else the pooled trials' peak; empty: every task and MVC trial",
        (),
        item="trial names",
    )
    window_s: float = opt(
        "length of the regression windows a task trial is cut into (an MVC trial is one): "
        "the jackknife's units; ≥ 3 correlation times of a 6-Hz envelope (≈ 0.17 s)",
        0.5,
        unit="s",
        bounds=_POSITIVE,
    )


@dataclass(frozen=True)
class SessionConfig:
    """A validated session configuration (:func:`msk.config.load_config`)."""

    path: Path
    subject: Subject
    model: ModelConfig | None
    trials: tuple[TrialConfig, ...]
    marker_rename: Mapping[str, str] = field(default_factory=dict)
    marker_weights: Mapping[str, float] = field(default_factory=dict)
    #: model markers moved to where the static trial puts them (technical clusters)
    marker_move: tuple[str, ...] = ()
    #: virtual markers: name → definition (msk.personalise.virtual_markers)
    marker_virtual: Mapping[str, str] = field(default_factory=dict)
    emg: EmgConfig = field(default_factory=EmgConfig)
    filters: FilterConfig = field(default_factory=FilterConfig)
    optimization: OptimizationConfig = field(default_factory=OptimizationConfig)
    fes: FesConfig = field(default_factory=FesConfig)
    loads: LoadsConfig = field(default_factory=LoadsConfig)
    contact: ContactConfig = field(default_factory=ContactConfig)
    gait: GaitConfig = field(default_factory=GaitConfig)
    strength: StrengthConfig = field(default_factory=StrengthConfig)

    def trials_with_role(self, role: str) -> tuple[TrialConfig, ...]:
        """The trials of ``role``, in file order."""
        return tuple(t for t in self.trials if t.role == role)

    @property
    def markers(self) -> MarkersConfig:
        """The ``[markers]`` table."""
        return MarkersConfig(
            rename=self.marker_rename, weights=self.marker_weights, move=self.marker_move,
            virtual=self.marker_virtual,
        )  # fmt: skip


@dataclass(frozen=True)
class Section:
    """One TOML table of the schema: its name, options dataclass and where it goes in
    :class:`SessionConfig` (``attr``; "" for ``[markers]``, flattened), with a one-line note."""

    name: str
    options: type
    attr: str
    note: str
    array: bool = False


#: the tables of a session configuration, in the order of the reference; the ``role = "fes"``
#: keys of ``[[trials]]`` are :class:`FesTrialConfig` (``TrialConfig.fes``)
SECTIONS = (
    Section("subject", Subject, "subject", "who was measured (required)"),
    Section(
        "model", ModelConfig, "model", "the model (required unless every trial has role = 'fes')"
    ),
    Section(
        "trials",
        TrialConfig,
        "trials",
        "one table per recording (at least one); several task trials: one results folder each",
        array=True,
    ),
    Section("markers", MarkersConfig, "", "lab marker names, IK weights, technical clusters"),
    Section("emg", EmgConfig, "emg", "EMG channels and their linear envelope"),
    Section("loads", LoadsConfig, "loads", "which body each force plate pushes"),
    Section("contact", ContactConfig, "contact", "tibiofemoral contact-point geometry"),
    Section("gait", GaitConfig, "gait", "the definition of the gait report's angles"),
    Section("filters", FilterConfig, "filters", "low-pass cut-offs (zero-lag Butterworth)"),
    Section("optimization", OptimizationConfig, "optimization", "how muscle forces are solved"),
    Section(
        "strength",
        StrengthConfig,
        "strength",
        "the trials `msk strength` identifies together (one EMG normalisation)",
    ),
    Section(
        "fes",
        FesConfig,
        "fes",
        "the FES knee-model identification (Benoussaad et al. 2013; role = 'fes' trials)",
    ),
)
