"""``summary.json`` as a typed, frozen, versioned value: :class:`Summary`.

``msk run`` writes ``summary.json`` (:mod:`msk.results.folder`); every reader — the report, ``msk
batch``'s cohort table, ``msk compare`` — reads it through :class:`Summary`, whose nested frozen
dataclasses mirror the file's sections and keys. A section or key a session may lack is
``None`` (``Summary.strength`` is ``None`` without EMG, ``Summary.fes`` without FES trials);
open-ended tables keyed by data (per muscle, group, segment, coordinate, parameter) are
``Mapping[str, ...]``, not one field per name. Parts of the file that echo inputs rather than
results (``settings``: the validated session config; ``model.marker_set``,
``model.marker_placement``, ``model.scaling``, ``fes.options``) are kept as read-only JSON
objects (:data:`JsonObject`).

Numbers a run computed are ``float | None``: ``summary.json`` is strict JSON, so a non-finite
value is written as ``null``. Lists are tuples and objects read-only mappings.

Round trip: ``Summary.from_dict(d).to_dict() == d`` for every summary ``msk run`` writes — a key
that is absent stays absent (a ``None`` field that was not in the file is not written), keys
keep their order, and a key this schema version does not name is kept verbatim — so
``Summary.from_json(text).to_json() == text`` for a file written by
:func:`msk.results.folder.write_session`.

Versioning: the file's ``format`` key (``"msk-session-summary/<n>"``, :data:`SUMMARY_FORMAT`)
is the schema version :attr:`Summary.schema_version`. Reading a newer one raises
:class:`~msk.exceptions.SummaryVersionError`; a missing required key raises
:class:`~msk.exceptions.SummaryKeyError` and a value of the wrong JSON type
:class:`~msk.exceptions.SummaryError`, each naming the key (``strength.groups[2].factor``).
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar, Union

import numpy as np

from msk.exceptions import SummaryError, SummaryKeyError, SummaryVersionError

__all__ = [
    "SCHEMA_VERSION",
    "SUMMARY_FORMAT",
    "ActionGroupShare",
    "Anthropometry",
    "AnthropometrySegment",
    "Comparison",
    "ConfigRef",
    "ContactAgreement",
    "Event",
    "Fes",
    "FesParameter",
    "FesStep",
    "FesTrial",
    "Flag",
    "Frame",
    "Gait",
    "GaitParameter",
    "GenericVsIdentified",
    "Heading",
    "Identification",
    "InputFile",
    "JointStrength",
    "JsonObject",
    "Kkt",
    "KktFigure",
    "KneeLoads",
    "MarkerGap",
    "Methods",
    "ModelInfo",
    "NotAvailable",
    "Optimization",
    "PlateAssignment",
    "PooledStrength",
    "Quality",
    "Segment",
    "SpatiotemporalSide",
    "StageRecord",
    "Strength",
    "StrengthAction",
    "StrengthGroup",
    "Subject",
    "Summary",
    "as_summary",
    "json_default",
    "strict_json",
    "unknown_keys",
]

#: The schema version this msk writes and the newest it reads.
SCHEMA_VERSION = 1
#: ``summary.json`` ``format`` value (the version is bumped on incompatible changes).
SUMMARY_FORMAT = f"msk-session-summary/{SCHEMA_VERSION}"
_FORMAT_RE = re.compile(r"msk-session-summary/(\d+)")

#: A JSON object kept as read (read-only mappings and tuples inside).
JsonObject = Mapping[str, Any]

_R = TypeVar("_R", bound="_Record")


# ---------------------------------------------------------------------------------------------
# the generic (de)serialisation of a record: driven by the dataclass fields and their types
# ---------------------------------------------------------------------------------------------
def _freeze(v: Any) -> Any:
    """A JSON value with read-only containers (objects → mappingproxy, arrays → tuple)."""
    if isinstance(v, Mapping):
        return types.MappingProxyType({k: _freeze(x) for k, x in v.items()})
    if isinstance(v, (list, tuple)):
        return tuple(_freeze(x) for x in v)
    return v


def _dump(v: Any) -> Any:
    """The plain JSON value (dict, list, str, number, bool, None) of a record field."""
    if isinstance(v, _Record):
        return v.to_dict()
    if isinstance(v, Mapping):
        return {k: _dump(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_dump(x) for x in v]
    return v


_JSON_NAMES = {bool: "a boolean", int: "an integer", float: "a number", str: "a string"}


def _json_type(v: Any) -> str:
    if v is None:
        return "null"
    if isinstance(v, Mapping):
        return "an object"
    if isinstance(v, (list, tuple)):
        return "an array"
    return _JSON_NAMES.get(type(v), type(v).__name__)


def _wrong(path: str, expected: str, v: Any) -> SummaryError:
    return SummaryError(f"summary key {path!r}: expected {expected}, got {_json_type(v)}", key=path)


def _load(tp: Any, v: Any, path: str) -> Any:
    """``v`` (plain JSON) as the annotated type ``tp``."""
    if tp is Any:
        return _freeze(v)
    origin = typing.get_origin(tp)
    if origin in (Union, types.UnionType):
        args = typing.get_args(tp)
        if v is None and type(None) in args:
            return None
        (inner,) = [a for a in args if a is not type(None)]
        return _load(inner, v, path)
    if isinstance(tp, type) and issubclass(tp, _Record):
        if not isinstance(v, Mapping):
            raise _wrong(path, "an object", v)
        return tp._from(v, path)
    if origin is Mapping:
        if not isinstance(v, Mapping):
            raise _wrong(path, "an object", v)
        _, vt = typing.get_args(tp)
        return types.MappingProxyType({k: _load(vt, x, f"{path}.{k}") for k, x in v.items()})
    if origin is tuple:
        if not isinstance(v, (list, tuple)):
            raise _wrong(path, "an array", v)
        (et, _) = typing.get_args(tp)
        return tuple(_load(et, x, f"{path}[{i}]") for i, x in enumerate(v))
    if tp is float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise _wrong(path, "a number", v)
        return v  # kept as written (an integer stays an integer)
    if tp in (int, str, bool):
        if not isinstance(v, tp) or (tp is int and isinstance(v, bool)):
            raise _wrong(path, _JSON_NAMES[tp], v)
        return v
    raise TypeError(f"summary schema: unsupported annotation {tp!r} at {path}")  # a bug here


_HINTS: dict[type, dict[str, Any]] = {}


def _hints(cls: type) -> dict[str, Any]:
    """The resolved field types of a record class (cached)."""
    if cls not in _HINTS:
        _HINTS[cls] = typing.get_type_hints(cls)
    return _HINTS[cls]


def _json_key(f: dataclasses.Field[Any]) -> str:
    return str(f.metadata.get("json", f.name))


@dataclass(frozen=True, kw_only=True)
class _Record:
    """Base of the summary records: the generic ``from_dict`` / ``to_dict``.

    A record read from a mapping remembers its keys in order and the keys the schema does not
    name (``_keys``, ``_extra``: not fields, not compared), so that writing it back gives the
    mapping it was read from. A record built in code writes every field, in field order.
    """

    @classmethod
    def _from(cls: type[_R], d: Mapping[str, Any], path: str) -> _R:
        hints = _hints(cls)
        kwargs: dict[str, Any] = {}
        named = set()
        for f in dataclasses.fields(cls):
            key = _json_key(f)
            named.add(key)
            sub = f"{path}.{key}" if path else key
            if key in d:
                kwargs[f.name] = cls._load_field(f.name, hints[f.name], d[key], sub)
            elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                raise SummaryKeyError(f"summary: required key {sub!r} is missing", key=sub)
        obj = cls(**kwargs)
        object.__setattr__(obj, "_keys", tuple(d))
        extra = {k: _freeze(v) for k, v in d.items() if k not in named}
        object.__setattr__(obj, "_extra", types.MappingProxyType(extra))
        return obj

    @classmethod
    def _load_field(cls, name: str, tp: Any, v: Any, path: str) -> Any:
        return _load(tp, v, path)

    def _dump_field(self, name: str) -> Any:
        return _dump(getattr(self, name))

    @classmethod
    def from_dict(cls: type[_R], d: Mapping[str, Any]) -> _R:
        """The record of a plain JSON mapping (see the module docstring for the errors)."""
        if not isinstance(d, Mapping):
            raise _wrong(cls.__name__, "an object", d)
        return cls._from(d, "")

    def to_dict(self) -> dict[str, Any]:
        """The plain JSON mapping (``from_dict`` of it gives an equal record)."""
        by_key = {_json_key(f): f.name for f in dataclasses.fields(self)}
        keys: tuple[str, ...] | None = getattr(self, "_keys", None)
        extra: Mapping[str, Any] = getattr(self, "_extra", {})
        out: dict[str, Any] = {}
        for k in keys if keys is not None else tuple(by_key):
            out[k] = self._dump_field(by_key[k]) if k in by_key else _dump(extra[k])
        return out


# ---------------------------------------------------------------------------------------------
# the records, in the order of summary.json
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class ConfigRef(_Record):
    """``config``: the session configuration file and its sha256."""

    path: str
    sha256: str


@dataclass(frozen=True, kw_only=True)
class InputFile(_Record):
    """``inputs[*]``: an input file (``role``: task, static, model, contact_force…), size in
    bytes."""

    role: str
    path: str
    sha256: str
    bytes: int | None = None


@dataclass(frozen=True, kw_only=True)
class Subject(_Record):
    """``subject``: name, body mass (kg) and where it comes from (``mass_source``: ``config``,
    ``c3d_parameters``, ``static_plates`` or ``task_plates``, :mod:`msk.personalise.body_mass`;
    ``mass_detail``),
    height (m), sex, analysed side, body weight (N)."""

    name: str
    mass_kg: float | None = None
    mass_source: str | None = None
    mass_detail: str | None = None
    height_m: float | None = None
    sex: str | None = None
    side: str | None = None
    body_weight_n: float | None = None


@dataclass(frozen=True, kw_only=True)
class Heading(_Record):
    """``model.heading``: how the walking direction was found (yaw in degrees)."""

    source: str | None = None
    pelvis_yaw_deg: float | None = None
    progression_yaw_deg: float | None = None
    message: str | None = None


@dataclass(frozen=True, kw_only=True)
class ModelInfo(_Record):
    """``model``: the model file, generic and scaled mass (kg), muscles (count), what
    scaling and marker placement did (JSON objects as :mod:`msk.personalise.scaling` reports them),
    the
    femur : tibia split of a leg without knee or ankle markers (``leg_split``: side →
    :meth:`msk.personalise.leg_split.LegSplit.summary`, which split each side got and why), the
    part of the static trial used (``static_window``,
    :meth:`msk.personalise.static_window.StillWindow.summary`) and, without a static trial, which
    leg
    coordinates' means the placement from the motion does not determine
    (``placement_determinacy``, :meth:`msk.personalise.determinacy.PlacementProfile.summary`) and
    the
    ankles' means set by the prior "sole level at foot flat" instead (``sole_level``: ankle
    coordinate → :meth:`msk.personalise.sole_level.SoleLevel.summary`)."""

    source: str | None = None
    generic_mass_kg: float | None = None
    marker_set: JsonObject | None = None
    heading: Heading | None = None
    marker_placement: JsonObject | None = None
    scaling: JsonObject | None = None
    scale_ratios: JsonObject | None = None
    mass_kg: float | None = None
    name: str | None = None
    muscles: int | None = None
    static_window: JsonObject | None = None
    leg_split: JsonObject | None = None
    placement_determinacy: JsonObject | None = None
    sole_level: JsonObject | None = None
    #: the hip joint centres' method and where they moved (:mod:`msk.personalise.hip_centre`)
    hip_centre: JsonObject | None = None
    #: virtual markers built from others (the PSIS midpoint as the sacrum)
    virtual_markers: tuple[Any, ...] | None = None
    #: coordinate → [lower, upper] degrees: ranges widened to the physiological knee flexion
    widened_ranges_deg: JsonObject | None = None
    #: without a static trial: the placement chosen among the motion's candidates and why
    #: (:meth:`msk.personalise.placement.PlacementChoice.summary`)
    placement_choice: JsonObject | None = None
    #: the knee axis alignment from the static (:mod:`msk.model.alignment`)
    knee_alignment: JsonObject | None = None
    #: the static markers the task contradicts, re-placed from the task
    #: (:func:`msk.personalise.static_placement.place_from_task`)
    static_check: JsonObject | None = None
    #: why the static trial was not used, when it was refused
    static_rejected: str | None = None


@dataclass(frozen=True, kw_only=True)
class Frame(_Record):
    """``frame``: the lab → model rotation (3×3, rows) and the lab's up axis."""

    lab_to_model_rotation: tuple[tuple[float, ...], ...] | None = None
    lab_up: tuple[float, ...] | None = None


@dataclass(frozen=True, kw_only=True)
class Event(_Record):
    """``events[*]``: a gait event (``label`` foot strike/off, ``context`` side), time in s."""

    label: str
    context: str | None = None
    time: float | None = None


@dataclass(frozen=True, kw_only=True)
class MarkerGap(_Record):
    """``quality.marker_gaps[*]``."""

    marker: str
    missing_frames: int | None = None
    longest_gap_frames: int | None = None


@dataclass(frozen=True, kw_only=True)
class PlateAssignment(_Record):
    """``quality.plate_assignments[*]``: which body a plate loaded, from / to (s)."""

    plate: str | None = None
    body: str | None = None
    start_time: float | None = None
    end_time: float | None = None


@dataclass(frozen=True, kw_only=True)
class Flag(_Record):
    """``quality.flags[*]``: a raised quality gate (:class:`msk.quality.Flag`)."""

    trial: str | None = None
    quantity: str | None = None
    value: float | None = None
    threshold: float | None = None
    message: str | None = None


@dataclass(frozen=True, kw_only=True)
class Quality(_Record):
    """``quality``: the quality figures of the task trial (SI; ``_pct_bw`` in % body weight)
    and the raised gates (``flags``) with the thresholds they were checked against. Empty (all
    ``None``) in a session without a gait trial."""

    frames: int | None = None
    rate_hz: float | None = None
    marker_gaps: tuple[MarkerGap, ...] | None = None
    ik_failed_frames: int | None = None
    ik_marker_rms_mean_m: float | None = None
    ik_marker_rms_max_m: float | None = None
    ik_worst_marker: str | None = None
    contact_measured_frames: int | None = None
    observed_measured_frames: int | None = None
    unmeasured_contact_frames: int | None = None
    unmeasured_contact_frames_by_foot: Mapping[str, int | None] | None = None
    unmeasured_contact_raised_frames: int | None = None
    unmeasured_contact_inside_pct: float | None = None
    unmeasured_contact_inside_s: tuple[float, ...] | None = None
    unobserved_segment_frames: Mapping[str, int | None] | None = None
    residual_force_rms_n: float | None = None
    residual_force_rms_pct_bw: float | None = None
    residual_moment_rms_nm: float | None = None
    plate_assignments: tuple[PlateAssignment, ...] | None = None
    emg_flat_channels: tuple[str, ...] | None = None
    emg_warnings: tuple[str, ...] | None = None
    emg_normalisation: str | None = None
    optimization_infeasible_frames: int | None = None
    strength_fit_r2: float | None = None
    identification_condition_number: float | None = None
    plate_mass_kg: float | None = None
    flags: tuple[Flag, ...] | None = None
    thresholds: Mapping[str, float | None] | None = None
    held_coordinates: tuple[str, ...] | None = None


@dataclass(frozen=True, kw_only=True)
class GaitParameter(_Record):
    """``gait.spatiotemporal.<side>.parameters.<name>``: a spatiotemporal parameter (its unit in
    ``name``, :data:`msk.gait.spatiotemporal.PARAMETERS`): mean and sample SD over the strides,
    and each stride's value (``null``: not computable in that stride)."""

    mean: float | None = None
    sd: float | None = None
    values: tuple[float | None, ...] = ()


@dataclass(frozen=True, kw_only=True)
class SpatiotemporalSide(_Record):
    """``gait.spatiotemporal.<side>``: the side's strides (count, the foot strike starting each,
    s) and its parameters by name (:class:`msk.gait.spatiotemporal.Spatiotemporal`)."""

    n_strides: int | None = None
    stride_start_s: tuple[float | None, ...] = ()
    parameters: Mapping[str, GaitParameter]


@dataclass(frozen=True, kw_only=True)
class Gait(_Record):
    """``gait``: the gait analysis of the task trial (:mod:`msk.gait`).

    ``spatiotemporal``: side → :class:`SpatiotemporalSide`; ``heel_source``: where the heel
    positions of the spatiotemporal parameters come from; ``treadmill_speed_m_s``: the belt
    speed found on a treadmill (absent overground), relative to which strides are measured;
    ``variables``: the names of the normalised cycles' variables
    (``tables/gait_cycles_<side>.csv``, units in the names); ``cycles``: side → complete
    cycles; ``cycles_measured``: side → cycles whose stance the plates measured (the kinetic
    variables are known in those only); ``foot_off_pct``: side → mean foot off, % of the
    cycle; ``knee_adduction_moment``: how the external knee adduction moment was computed and
    its sign; ``not_modelled``: gait-lab variables the model has no degree of freedom for (not
    given); ``notes``: what was decided."""

    spatiotemporal: Mapping[str, SpatiotemporalSide] | None = None
    heel_source: str | None = None
    treadmill_speed_m_s: float | None = None
    variables: tuple[str, ...] | None = None
    cycles: Mapping[str, int] | None = None
    cycles_measured: Mapping[str, int] | None = None
    foot_off_pct: Mapping[str, float | None] | None = None
    knee_adduction_moment: str | None = None
    not_modelled: tuple[str, ...] | None = None
    notes: tuple[str, ...] | None = None


@dataclass(frozen=True, kw_only=True)
class Methods(_Record):
    """``methods``: the named methods the run used."""

    plate_assignment: str | None = None
    scaling_measurements: tuple[str, ...] | None = None
    task_trial: str | None = None
    filtering: str | None = None


@dataclass(frozen=True, kw_only=True)
class Segment(_Record):
    """``identification.segments[*]``: identified vs prior mass (kg) and COM (m, body frame),
    posterior std, and the :mod:`msk.status` word."""

    name: str
    mass_kg: float | None = None
    mass_std_kg: float | None = None
    prior_mass_kg: float | None = None
    com_m: tuple[float | None, ...] | None = None
    com_std_m: tuple[float | None, ...] | None = None
    prior_com_m: tuple[float | None, ...] | None = None
    flag: str | None = None
    status: str | None = None

    def status_word(self) -> str:
        """The :mod:`msk.status` word (``status``, or computed for older summaries)."""
        from msk.status import segment_status

        return segment_status(self.to_dict()).value


@dataclass(frozen=True, kw_only=True)
class Identification(_Record):
    """``identification``: the mass-distribution identification; ``applied_to_dynamics``: the
    segments whose identified inertia the dynamics downstream used (``[model] inertias``,
    :func:`msk.dynamics.identification.identified_model`), the others keeping the scaled
    model's."""

    segments: tuple[Segment, ...]
    condition_number: float | None = None
    n_frames: int | None = None
    advice: tuple[str, ...] | None = None
    applied_to_dynamics: tuple[str, ...] | None = None


@dataclass(frozen=True, kw_only=True)
class AnthropometrySegment(_Record):
    """``anthropometry.segments[<body>]``: the table's segment mass (kg) and its table."""

    mass_kg: float | None = None
    table: str | None = None


@dataclass(frozen=True, kw_only=True)
class Anthropometry(_Record):
    """``anthropometry``: generic segment masses from the anthropometric tables, per body."""

    segments: Mapping[str, AnthropometrySegment]
    table: str | None = None
    sex: str | None = None


@dataclass(frozen=True, kw_only=True)
class StrengthGroup(_Record):
    """``strength.groups[*]``: a muscle group's strength factor (× generic F_iso), its
    interval, F_iso (N) and status; ``gated`` = passed the correlation gate (``identified``:
    what older summaries had instead of ``status``)."""

    group: str
    muscles: tuple[str, ...] = ()
    factor: float | None = None
    ci_low: float | None = None
    ci_high: float | None = None
    ci_cov_low: float | None = None
    ci_cov_high: float | None = None
    f_iso_generic_n: float | None = None
    f_iso_n: float | None = None
    status: str | None = None
    identified: bool | None = None
    gated: bool | None = None
    #: the status's reason in plain words (:func:`msk.strength.diagnose`)
    reason: str | None = None
    #: fit r² of the group's own rows (the coordinates ``r2_coordinates`` its muscles cross)
    r2: float | None = None
    r2_coordinates: tuple[str, ...] = ()
    confounded_with: tuple[str, ...] = ()
    #: the test that would identify a group not identified
    #: (:meth:`msk.strength.TestProtocol.as_dict`)
    protocol: Mapping[str, Any] | None = None
    #: the group's maximal isometric moment (N·m; identified factor × the generic model's, at
    #: the posture of ``moment_test``) and its interval (the factor's bootstrap interval ×)
    moment_nm: float | None = None
    moment_low_nm: float | None = None
    moment_high_nm: float | None = None
    #: the action and posture of ``moment_nm`` (:attr:`msk.strength.TestProtocol.text`'s test)
    moment_test: str | None = None


@dataclass(frozen=True, kw_only=True)
class ActionGroupShare(_Record):
    """``strength.joint_strength.actions[*].groups[*]``: a group's share of the peak."""

    group: str
    share: float | None = None
    status: str | None = None


@dataclass(frozen=True, kw_only=True)
class StrengthAction(_Record):
    """``strength.joint_strength.actions[*]``: the maximal isometric moment curve (N·m) of an
    action, generic and identified, over the joint angle (deg)."""

    action: str
    coordinate: str | None = None
    angle_label: str | None = None
    posture_deg: Mapping[str, float | None] | None = None
    angles_deg: tuple[float | None, ...] = ()
    generic_nm: tuple[float | None, ...] = ()
    identified_nm: tuple[float | None, ...] = ()
    generic_peak_nm: float | None = None
    generic_peak_angle_deg: float | None = None
    identified_peak_nm: float | None = None
    identified_peak_angle_deg: float | None = None
    status: str | None = None
    groups: tuple[ActionGroupShare, ...] | None = None
    generic_share: float | None = None


@dataclass(frozen=True, kw_only=True)
class JointStrength(_Record):
    """``strength.joint_strength`` (:func:`msk.strength.joint_strength_summary`), or only
    ``error`` when the curves could not be computed."""

    error: str | None = None
    side: str | None = None
    mass_kg: float | None = None
    activation: float | None = None
    method: str | None = None
    status_share_min: float | None = None
    norms: Any = None
    norms_note: str | None = None
    actions: tuple[StrengthAction, ...] | None = None


@dataclass(frozen=True, kw_only=True)
class Strength(_Record):
    """``strength``: the strength identification (fit r², bounds, confidence, groups)."""

    groups: tuple[StrengthGroup, ...]
    r2: float | None = None
    r2_min: float | None = None
    status_codes: Mapping[str, int] | None = None
    status_meaning: Mapping[str, str] | None = None
    confidence: float | None = None
    bounds: tuple[float, ...] | None = None
    method: str | None = None
    #: the groups whose factor the subject-specific model takes (the identified ones; every
    #: other group keeps the generic F_iso: :meth:`msk.strength.StrengthProfile.applied_factors`)
    applied_groups: tuple[str, ...] | None = None
    joint_strength: JointStrength | None = None
    #: groups whose EMG channel failed a check (not in the regression): ``not determined``,
    #: the check as ``reason``, the test that would identify them as ``protocol``
    failed_channels: tuple[StrengthGroup, ...] = ()

    def group_status(self, group: StrengthGroup) -> str:
        """The :mod:`msk.status` word of one of the groups (its ``status``, or computed from
        the factor, interval, bounds and r² for older summaries). Reads only the record's
        ``bounds`` and ``r2``: the rest of the strength record (the joint curves) is not
        serialised."""
        from msk.status import group_status

        return group_status(group.to_dict(), {"bounds": self.bounds, "r2": self.r2}).value


@dataclass(frozen=True, kw_only=True)
class PooledStrength(Strength):
    """``pooled_strength``: the session's trials pooled into one strength identification
    (:func:`msk.strength.pooled.identify_pooled`, ``msk strength``): the fields of
    :class:`Strength` (``r2`` the fit r² of all rows; each group judged on its own rows) and
    the trials pooled, the EMG normalisation (``mvc``, ``session_peak``) and, for a
    session-peak normalisation, the bias it implies."""

    trials: tuple[str, ...] = ()
    normalisation_kind: str | None = None
    normalisation_bias: str | None = None
    #: the mass (kg) the moments are divided by for N·m/kg
    mass_kg: float | None = None


@dataclass(frozen=True, kw_only=True)
class GenericVsIdentified(_Record):
    """A figure with the generic and with the identified model."""

    generic: float | None = None
    identified: float | None = None


@dataclass(frozen=True, kw_only=True)
class ContactAgreement(_Record):
    """``comparison.knee_contact_<variant>[_medial|_lateral]``: predicted vs measured knee
    contact force (N, BW, %, correlation coefficients) over ``n_frames``; ``component`` the
    force compared (``axial total``: the measurement is axial, compared with the predicted
    axial force; ``magnitude total``; ``medial axial``…)."""

    component: str | None = None
    rms_n: float | None = None
    rms_bw: float | None = None
    nrmsd_pct: float | None = None
    pearson_r: float | None = None
    spearman_rho: float | None = None
    icc: float | None = None
    peak_difference_n: float | None = None
    peak_measured_bw: float | None = None
    peak_predicted_bw: float | None = None
    n_frames: int | None = None


@dataclass(frozen=True, kw_only=True)
class Comparison(_Record):
    """``comparison``: generic vs identified (per-coordinate torque RMS difference N·m, pelvis
    residuals) and the knee contact force against the measured one, per model variant."""

    torque_rms_difference_nm: Mapping[str, float | None] | None = None
    residual_force_rms_n: GenericVsIdentified | None = None
    residual_moment_rms_nm: GenericVsIdentified | None = None
    knee_contact_generic: ContactAgreement | None = None
    knee_contact_generic_medial: ContactAgreement | None = None
    knee_contact_generic_lateral: ContactAgreement | None = None
    knee_contact_subject_specific: ContactAgreement | None = None
    knee_contact_subject_specific_medial: ContactAgreement | None = None
    knee_contact_subject_specific_lateral: ContactAgreement | None = None
    strength_factor_minus_generic: Mapping[str, float | None] | None = None

    def knee_contact(self, variant: str, compartment: str = "total") -> ContactAgreement | None:
        """The agreement of a knee contact prediction: ``variant`` ``generic`` or
        ``subject_specific``, ``compartment`` ``total``, ``medial`` or ``lateral``."""
        key = f"knee_contact_{variant}" + ("" if compartment == "total" else f"_{compartment}")
        value = getattr(self, key, None)
        return value if isinstance(value, ContactAgreement) else None


@dataclass(frozen=True, kw_only=True)
class KneeLoads(_Record):
    """``knee_loads``: what the knee contact stage computed beyond the tibiofemoral force —
    the quadriceps' route (``patella``: ``"tendon"`` or ``"none"``, ``[contact] patella``) and,
    with the tendon, the peak patellofemoral contact force |F_PF| over the trial per model
    variant (``generic``, ``subject_specific``; :mod:`msk.contact.patella`), in N and in body
    weights of the configured mass."""

    joint: str | None = None
    patella: str | None = None
    peak_patellofemoral_n: Mapping[str, float | None] | None = None
    peak_patellofemoral_bw: Mapping[str, float | None] | None = None


@dataclass(frozen=True, kw_only=True)
class KktFigure(_Record):
    """``optimization.kkt.<figure>``: the largest value of a KKT figure over the frames the
    solver called optimal (scaled variables of the standard-form QP), the largest value
    relative to its scale (:func:`msk.optimization.kkt_scale`) and the frame (index on the
    trial's time base) and time (s) of that relative value."""

    max: float | None = None
    relative_max: float | None = None
    frame: int | None = None
    time_s: float | None = None


@dataclass(frozen=True, kw_only=True)
class Kkt(_Record):
    """``optimization.kkt``: the KKT check of the tension QPs (frames checked, the relative
    tolerance of the quality gate, the four figures)."""

    frames: int | None = None
    relative_tolerance: float | None = None
    stationarity: KktFigure | None = None
    primal_feasibility: KktFigure | None = None
    dual_feasibility: KktFigure | None = None
    complementarity: KktFigure | None = None


@dataclass(frozen=True, kw_only=True)
class Optimization(_Record):
    """``optimization``: the tension optimisation (method, criterion, EMG gains per channel
    and their status, infeasible frames, reserve torques RMS per coordinate N·m, the worst
    KKT figures of the frames solved optimal; ``frames_solved``: per leg (model side suffix
    ``r``/``l``) the frames whose muscle forces were solved — a leg is left out of a frame
    where its foot stands off the plates, the other one solved)."""

    method: str | None = None
    criterion: str | None = None
    emg_gains: Mapping[str, float | None] | None = None
    emg_gain_status: Mapping[str, str] | None = None
    infeasible_frames: int | None = None
    frames_solved: Mapping[str, int] | None = None
    reserve_torque_rms_nm: Mapping[str, float | None] | None = None
    kkt: Kkt | None = None
    #: the knee's frontal-plane reserve moments (:func:`msk.quality.frontal_reserve_figures`)
    frontal_reserve: JsonObject | None = None


@dataclass(frozen=True, kw_only=True)
class FesParameter(_Record):
    """``fes.parameters[<group>.<name>]``: an FES model parameter as the protocol estimated it
    (SI unit)."""

    value: float | None = None
    unit: str | None = None


@dataclass(frozen=True, kw_only=True)
class FesStep(_Record):
    """``fes.steps[<step>]``: the fit of a protocol step (% of range, % of RMS)."""

    nrmsd_pct: float | None = None
    nrmse_pct: float | None = None


@dataclass(frozen=True, kw_only=True)
class FesTrial(_Record):
    """``fes.trials[*]``: an FES trial and its protocol step."""

    name: str
    step: str | None = None
    file: str | None = None


@dataclass(frozen=True, kw_only=True)
class Fes(_Record):
    """``fes``: the protocol of Benoussaad et al. 2013 (parameters, initial values, step fits,
    ``k_s`` iterations N/m, solver status, seconds per pass, trials, options)."""

    parameters: Mapping[str, FesParameter]
    initial_parameters: Mapping[str, float | None] | None = None
    steps: Mapping[str, FesStep] | None = None
    k_s_history_n_per_m: tuple[float | None, ...] | None = None
    solver_status: str | None = None
    seconds: Mapping[str, float | None] | None = None
    trials: tuple[FesTrial, ...] | None = None
    options: JsonObject | None = None


@dataclass(frozen=True, kw_only=True)
class StageRecord(_Record):
    """``stages[*]``: a pipeline stage, its status (computed, cached, not requested, not
    available, failed), seconds, message and cache key."""

    name: str
    status: str
    seconds: float | None = None
    message: str | None = None
    key: str | None = None


@dataclass(frozen=True, kw_only=True)
class NotAvailable(_Record):
    """``not_available[*]``: a stage that was not available or failed, and why."""

    stage: str
    status: str | None = None
    reason: str | None = None


@dataclass(frozen=True, kw_only=True)
class Summary(_Record):
    """``summary.json`` of a session (see the module docstring).

    Required: ``format`` (→ :attr:`schema_version`), ``session``, ``created_utc``,
    ``versions``, ``config``, ``inputs``, ``settings``, ``subject``, ``quality``; every other
    section is ``None`` when the session lacks it.
    """

    session: str
    trial: str | None = None
    created_utc: str
    versions: Mapping[str, str]
    config: ConfigRef
    inputs: tuple[InputFile, ...]
    settings: JsonObject
    subject: Subject
    model: ModelInfo | None = None
    frame: Frame | None = None
    events: tuple[Event, ...] | None = None
    event_sources: JsonObject | None = None
    gait_cycle_s: tuple[float, ...] | None = None
    gait: Gait | None = None
    angle_columns: tuple[str, ...] | None = None
    quality: Quality
    methods: Methods | None = None
    identification: Identification | None = None
    anthropometry: Anthropometry | None = None
    #: each plate's standing surface (``surfaces``: height, its corners' height, ``source``
    #: corners / feet / config), the offsets removed and the plates ignored
    #: (:mod:`msk.dynamics.plate_surface`)
    plates: JsonObject | None = None
    strength: Strength | None = None
    #: the session's trials pooled (``msk strength CONFIG --out`` a folder of ``msk run``)
    pooled_strength: PooledStrength | None = None
    comparison: Comparison | None = None
    knee_loads: KneeLoads | None = None
    optimization: Optimization | None = None
    fes: Fes | None = None
    stages: tuple[StageRecord, ...] | None = None
    not_available: tuple[NotAvailable, ...] | None = None
    run_seconds: float | None = None
    #: the OpenSim files written (``files``) and what they hold (:mod:`msk.io.opensim_export`)
    opensim: JsonObject | None = None
    schema_version: int = dataclasses.field(default=SCHEMA_VERSION, metadata={"json": "format"})
    tables: tuple[str, ...] | None = None

    @classmethod
    def _load_field(cls, name: str, tp: Any, v: Any, path: str) -> Any:
        if name != "schema_version":
            return _load(tp, v, path)
        m = _FORMAT_RE.fullmatch(v) if isinstance(v, str) else None
        if m is None:
            raise SummaryError(
                f"summary key 'format': {v!r} is not an msk session summary "
                f"(expected {SUMMARY_FORMAT!r})",
                key="format",
            )
        version = int(m.group(1))
        if version > SCHEMA_VERSION:
            raise SummaryVersionError(
                f"summary key 'format': schema version {version} ({v!r}) is newer than this "
                f"msk reads ({SUMMARY_FORMAT!r}): update msk",
                key="format",
            )
        return version

    def _dump_field(self, name: str) -> Any:
        if name == "schema_version":
            return f"msk-session-summary/{self.schema_version}"
        return super()._dump_field(name)

    @classmethod
    def _from(cls, d: Mapping[str, Any], path: str) -> Summary:
        # the schema version first: a file of another kind or version names this key
        if "format" not in d:
            raise SummaryKeyError("summary: required key 'format' is missing", key="format")
        cls._load_field("schema_version", int, d["format"], "format")
        return super()._from(d, path)

    @classmethod
    def from_json(cls, text: str) -> Summary:
        """The summary of the text of a ``summary.json``."""
        try:
            d = json.loads(text)
        except json.JSONDecodeError as exc:
            raise SummaryError(f"summary: not valid JSON: {exc}") from None
        except RecursionError:
            raise SummaryError("summary: nested too deeply to be a session summary") from None
        return cls.from_dict(d)

    def to_json(self) -> str:
        """The text :func:`msk.results.folder.write_session` writes (strict JSON, 2-space indent,
        final newline)."""
        return json.dumps(self.to_dict(), indent=2, allow_nan=False) + "\n"


def json_default(obj: Any) -> Any:
    """``json.dumps(default=...)``: numpy scalars/arrays and paths as plain JSON values."""
    if isinstance(obj, np.ndarray):
        return [json_default(x) for x in obj.tolist()] if obj.ndim else json_default(obj.item())
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, (set, frozenset, tuple)):
        return list(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def strict_json(obj: Any) -> Any:
    """``obj`` with non-finite floats replaced by ``None`` (strict JSON), recursively; mapping
    keys as strings, tuples and arrays as lists."""
    if isinstance(obj, Mapping):
        return {str(k): strict_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [strict_json(v) for v in obj]
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.ndarray):
        return strict_json(obj.tolist())
    return obj


def unknown_keys(record: _Record, path: str = "") -> tuple[str, ...]:
    """The keys of ``record`` (read from a mapping) and of every record inside it that the
    schema does not name, as dotted paths (``quality.flag[2].valu``); ``()`` for a record built
    in code. Parts kept as JSON (:data:`JsonObject`) are not looked into."""
    out: list[str] = [f"{path}.{k}" if path else k for k in getattr(record, "_extra", {})]

    def visit(v: Any, sub: str) -> None:
        if isinstance(v, _Record):
            out.extend(unknown_keys(v, sub))
        elif isinstance(v, tuple):
            for i, x in enumerate(v):
                visit(x, f"{sub}[{i}]")
        elif isinstance(v, Mapping):
            for k, x in v.items():
                if isinstance(x, (_Record, tuple)):
                    visit(x, f"{sub}.{k}")

    for f in dataclasses.fields(record):
        visit(getattr(record, f.name), f"{path}.{_json_key(f)}" if path else _json_key(f))
    return tuple(out)


def as_summary(summary: Summary | Mapping[str, Any]) -> Summary:
    """``summary`` as a :class:`Summary`: a mapping (a summary being assembled by the
    pipeline, not yet written) is first made what its ``summary.json`` would hold — numpy
    values as plain JSON, non-finite numbers as ``None``, ``format`` the current one when
    absent — so a reader sees exactly what a reader of the written folder sees.

    Typed on write as on read: a key of an assembled mapping that the schema does not name
    (a misspelt optional key) raises :class:`~msk.exceptions.SummaryKeyError` naming it,
    where reading a file written by a newer msk keeps such keys verbatim.
    """
    if isinstance(summary, Summary):
        return summary
    d = json.loads(json.dumps(strict_json(summary), default=json_default, allow_nan=False))
    if isinstance(d, dict):
        d.setdefault("format", SUMMARY_FORMAT)
    s = Summary.from_dict(d)
    unknown = unknown_keys(s)
    if unknown:
        raise SummaryKeyError(
            f"summary: key {unknown[0]!r} is not in the schema of {SUMMARY_FORMAT!r} "
            f"(msk.results.summary)" + (f" (nor {list(unknown[1:])})" if unknown[1:] else ""),
            key=unknown[0],
        )
    return s
