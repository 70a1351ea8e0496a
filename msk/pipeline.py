"""The lab pipeline: one session configuration → the results contract (:mod:`msk.results`).

Composition only: every number comes from an msk library call; this module chains them, caches
them and records what happened. Stages (DESIGN.md "Architecture")::

    read → model (load, scale, place markers) → kinematics → loads → mass_identification
      → inverse_dynamics → emg → muscle_geometry → tension_optimization
      → strength_identification → knee_contact → comparison → fes → report

**FES.** The ``fes`` stage reads the ``role = "fes"`` trials (CSV with
:func:`msk.fes.io.read_fes_csv`, C3D analogs with :func:`msk.fes.io.recording_from_trial`),
builds the :class:`msk.fes.protocol.FesSession` and runs
:func:`msk.fes.protocol.run_protocol` (seeds/000 §2.3). A session may hold only FES trials: the
gait stages are then ``not requested`` and the report holds the FES section.

**Stage status.** ``computed`` / ``cached`` / ``not requested`` (the configuration has no
trial for it: no gait trial, no FES trial) / ``not available`` (the library piece is missing
or a prerequisite is: recorded with the reason, never replaced by made-up numbers) / ``failed``
(an analysis stage raised: recorded with its message — and the code location for an internal
error — and the run goes on). The core stages (read, model, kinematics, loads, inverse
dynamics, report) have no fallback: their errors end the run, and nothing is written.

**Cache.** A stage's key is the sha256 of its name, the code fingerprint (the source of msk
and the versions of its numerical dependencies), its settings and the keys
of the stages it reads (input files enter through their content hash), so a changed setting
recomputes exactly the stages downstream of it. Values are stored in ``<out>/.cache`` by
:mod:`msk.cache` (``.npz`` + JSON, checksummed, keyed on the source of msk; never pickled).

Each stage is one method of ``_Session``; what is left here is composition, caching, progress
and results writing. The algorithms live in the library:

* **Frames** (:func:`msk.io.lab_to_model_rotation`, :meth:`msk.io.Trial.rotated`): the lab
  frame of a C3D trial is rotated into the model frame (lab vertical → the model's up,
  −gravity) and about the vertical so that the walking direction is the model's +x (OpenSim's
  convention); the rotation is recorded in ``summary.json``.
* **Marker placement** (:func:`msk.scaling.place_markers`): lab markers that are not model
  markers (clusters, PSIS…) are placed on the scaled model from the static trial
  (``[markers] rename`` maps model names to lab labels).
* **Plate assignment** (:func:`msk.loads.external_loads`): each contact interval goes to the
  foot standing on the plate, judged on the plate outline.
* **Measured frames** (:func:`msk.loads.contact_measured`): pelvis residuals, identification
  equations, muscle forces and knee contact use only the frames whose every foot on the floor
  stands on a plate (a walkway's steps before and after the plates miss a ground reaction).
* **TRC + GRF**: a task trial may be an OpenSim ``.trc`` (:func:`msk.io.read_trc_trial`, +y up)
  with ``grf`` = an OpenSim GRF ``.mot``, whose plates are rotated with the markers.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import sys
import time as _time
import traceback
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Literal, TextIO, cast

import numpy as np

from msk import __version__
from msk.cache import StageCache, code_fingerprint, dependency_versions
from msk.config import FesTrialConfig, ModelConfig, SessionConfig, TrialConfig, load_config
from msk.exceptions import ConfigError, MissingDataError, ModelError, MskError
from msk.io.frames import lab_to_model_rotation
from msk.io.opensim_files import Table
from msk.results import SessionResults, check_replaceable, json_default, write_session

__all__ = [
    "CORE_STAGES",
    "DEFAULT_MEASUREMENTS",
    "PLATE_ASSIGNMENT",
    "STAGES",
    "RunResult",
    "StageRecord",
    "file_sha256",
    "lab_to_model_rotation",
    "place_markers",
    "run_session",
    "run_task_trials",
    "split_task_trials",
]

#: Every stage, in order.
STAGES: tuple[str, ...] = (
    "read",
    "model",
    "kinematics",
    "loads",
    "mass_identification",
    "inverse_dynamics",
    "emg",
    "muscle_geometry",
    "tension_optimization",
    "strength_identification",
    "knee_contact",
    "comparison",
    "fes",
    "report",
)
#: Stages without which there are no results: their errors end the run.
CORE_STAGES: frozenset[str] = frozenset(
    {"read", "model", "kinematics", "loads", "inverse_dynamics", "report"}
)
G0 = 9.80665
#: Frames per joint-reaction call in the knee-contact stage (moving path points per chunk).
#: How msk.loads assigns plate contacts to feet (recorded in summary.json, part of the cache key).
PLATE_ASSIGNMENT = (
    "msk.loads: the foot standing on the plate (inside the outline, near the floor, not "
    "swinging over it)"
)

#: Scaling measurements (model marker pairs → bodies), used where both markers exist in the
#: model and (after ``[markers] rename``) in the static trial.
#: a frame is solved by IK when it sees this fraction of the most model markers any frame sees
MIN_MARKER_FRACTION = 0.5

#: IK weight of the coordinate task holding an unobserved foot joint at 0 rad (weight per rad²,
#: markers per m²: 1° off costs as much as 17 mm of marker error)
HELD_COORDINATE_WEIGHT = 1.0

DEFAULT_MEASUREMENTS: tuple[tuple[str, tuple[tuple[str, str], ...], tuple[str, ...]], ...] = (
    ("pelvis", (("R.ASIS", "L.ASIS"),), ("pelvis",)),
    ("femur_r", (("R.ASIS", "R.Knee.Lat"),), ("femur_r",)),
    ("femur_l", (("L.ASIS", "L.Knee.Lat"),), ("femur_l",)),
    ("tibia_r", (("R.Knee.Lat", "R.Ankle.Lat"),), ("tibia_r",)),
    ("tibia_l", (("L.Knee.Lat", "L.Ankle.Lat"),), ("tibia_l",)),
    ("foot_r", (("R.Heel", "R.Toe.Tip"),), ("talus_r", "calcn_r", "toes_r")),
    ("foot_l", (("L.Heel", "L.Toe.Tip"),), ("talus_l", "calcn_l", "toes_l")),
    ("torso", (("V.Sacral", "Sternum"),), ("torso",)),
)


# ---------------------------------------------------------------------------------------------
# records
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class StageRecord:
    """What happened to one stage: ``status`` computed | cached | not requested |
    not available | failed."""

    name: str
    status: str
    seconds: float
    message: str = ""
    key: str = ""


@dataclass(frozen=True)
class RunResult:
    """A finished run: the session folder, its summary and the stage records."""

    out_dir: Path
    summary: Mapping[str, Any]
    stages: tuple[StageRecord, ...]
    seconds: float

    @property
    def not_available(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.stages if s.status in ("not available", "failed"))


class StageUnavailable(Exception):
    """Internal: a stage cannot run (missing library piece or prerequisite); not an error."""


def file_sha256(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _key(*parts: Any) -> str:
    text = json.dumps(parts, sort_keys=True, default=json_default)
    return hashlib.sha256(text.encode()).hexdigest()


def _versions() -> dict[str, str]:
    """msk, Python and the numerical dependencies (:func:`msk.cache.dependency_versions`)."""
    return {"msk": __version__, **dependency_versions()}


# ---------------------------------------------------------------------------------------------
# stage runner with content-hash cache
# ---------------------------------------------------------------------------------------------
class _Runner:
    def __init__(self, cache_dir: Path | None, progress: TextIO | None) -> None:
        self.cache_dir = cache_dir
        self.cache = StageCache(cache_dir) if cache_dir is not None else None
        self.progress = progress
        self.records: list[StageRecord] = []
        self.keys: dict[str, str] = {}

    def _say(self, rec: StageRecord) -> None:
        if self.progress is None:
            return
        k = STAGES.index(rec.name) + 1 if rec.name in STAGES else 0
        msg = f" — {rec.message}" if rec.message and rec.status != "computed" else ""
        self.progress.write(
            f"[{k:2d}/{len(STAGES)}] {rec.name:<24} {rec.seconds:7.2f} s  {rec.status}{msg}\n"
        )
        self.progress.flush()

    def skip(self, name: str, reason: str) -> None:
        """Record a stage the configuration does not ask for (not an error)."""
        rec = StageRecord(name, "not requested", 0.0, reason)
        self.records.append(rec)
        self._say(rec)

    def run(
        self,
        name: str,
        fn: Callable[[], Any],
        *,
        needs: Sequence[str] = (),
        settings: Any = None,
        cache: bool = True,
    ) -> Any:
        t0 = _time.perf_counter()
        missing = [n for n in needs if n not in self.keys]
        if missing:
            rec = StageRecord(name, "not available", 0.0, f"needs {', '.join(missing)}")
            self.records.append(rec)
            self._say(rec)
            return None
        # the key holds the source of msk and its numerical dependencies (msk.cache): a code
        # change recomputes; entries are .npz + JSON, checksummed, never unpickled
        key = _key(name, code_fingerprint(), settings, [self.keys[n] for n in needs])
        store = self.cache if cache else None
        if store is not None:
            hit, value = store.load(name, key)
            if hit:
                self.keys[name] = key
                rec = StageRecord(name, "cached", _time.perf_counter() - t0, "", key)
                self.records.append(rec)
                self._say(rec)
                return value
        try:
            value = fn()
        except StageUnavailable as exc:
            rec = StageRecord(name, "not available", _time.perf_counter() - t0, str(exc), key)
            self.records.append(rec)
            self._say(rec)
            return None
        except MskError as exc:
            # a configuration error is the user's to fix: the run ends with one line and a
            # non-zero exit, whatever the stage (an EMG channel typo is not a "failed stage")
            if name in CORE_STAGES or isinstance(exc, ConfigError):
                raise
            msg = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
            rec = StageRecord(name, "failed", _time.perf_counter() - t0, msg, key)
            self.records.append(rec)
            self._say(rec)
            return None
        except Exception as exc:
            # a bug in an analysis module must not cost the session its other results: the
            # stage is recorded as failed, with the error and where it happened
            if name in CORE_STAGES:
                raise
            tb = traceback.extract_tb(exc.__traceback__)
            where = f" ({Path(tb[-1].filename).name}:{tb[-1].lineno})" if tb else ""
            msg = f"internal error: {type(exc).__name__}: {' '.join(str(exc).split())}{where}"
            rec = StageRecord(name, "failed", _time.perf_counter() - t0, msg, key)
            self.records.append(rec)
            self._say(rec)
            return None
        note = ""
        if store is not None and not store.save(name, key, value):
            note = store.last_reason  # e.g. the model stage: a Model is not storable
        self.keys[name] = key
        rec = StageRecord(name, "computed", _time.perf_counter() - t0, note, key)
        self.records.append(rec)
        self._say(rec)
        return value


# ---------------------------------------------------------------------------------------------
# compatibility: the frame and marker-placement steps now live in the library
# ---------------------------------------------------------------------------------------------
def place_markers(
    model: Any, static_markers: np.ndarray, labels: Sequence[str], time: np.ndarray
) -> tuple[Any, dict[str, Any]]:
    """Kept for callers of ``msk.pipeline``: :func:`msk.scaling.place_markers`."""
    from msk.scaling import place_markers as place

    return place(model, static_markers, labels, time)


# ---------------------------------------------------------------------------------------------
# inputs
# ---------------------------------------------------------------------------------------------
def _settings(cfg: SessionConfig) -> dict[str, Any]:
    def plain(x: Any) -> Any:
        if dataclasses.is_dataclass(x):
            return {f.name: plain(getattr(x, f.name)) for f in dataclasses.fields(x)}
        if isinstance(x, Mapping):
            return {str(k): plain(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [plain(v) for v in x]
        if isinstance(x, Path):
            return str(x)
        return x

    return {
        "subject": plain(cfg.subject),
        "model": plain(cfg.model),
        "trials": plain(cfg.trials),
        "markers": {
            "rename": dict(cfg.marker_rename),
            "weights": dict(cfg.marker_weights),
            "move": list(cfg.marker_move),
        },
        "emg": plain(cfg.emg),
        "filters": plain(cfg.filters),
        "optimization": plain(cfg.optimization),
        "fes": plain(cfg.fes),
    }


def _read_markers(path: Path, up: np.ndarray) -> tuple[np.ndarray, tuple[str, ...], np.ndarray]:
    """Markers of a static trial in the model frame: a .trc is already in it; a .c3d is rotated
    (lab vertical → model ``up``, no heading: the subject stands still)."""
    if path.suffix.lower() == ".trc":
        from msk.io.opensim_files import read_trc

        t = read_trc(path)
        return t.markers, t.labels, t.time
    from msk.io import read_c3d, to_model_frame

    tr = to_model_frame(read_c3d(path), up=up, forward=None)
    return tr.markers, tr.marker_labels, tr.time


def _contact_measured(model: Any, kin: Any, loads: Any) -> np.ndarray:
    """:func:`msk.loads.contact_measured`: the frames whose ground contact the plates measure."""
    from msk.loads import contact_measured

    return contact_measured(model, kin, loads)


def _read_grf(path: Path, xml: Path | None) -> tuple[Any, ...]:
    """The plates of an OpenSim GRF file (:func:`msk.loads.plates_from_grf_file`: every common
    column naming; with an ExternalLoads ``xml``, its force sets)."""
    from msk.loads import plates_from_grf_file

    return plates_from_grf_file(path, xml)


def _rotated_plate(plate: Any, rot: np.ndarray) -> Any:
    """A :class:`msk.loads.PlateWrench` rotated by ``rot`` about the origin (force, COP,
    free moment, corners)."""
    r = np.asarray(rot, dtype=float)
    return dataclasses.replace(
        plate,
        force=np.asarray(plate.force) @ r.T,
        cop=np.asarray(plate.cop) @ r.T,
        free_moment=np.asarray(plate.free_moment) @ r.T,
        corners=None if plate.corners is None else np.asarray(plate.corners) @ r.T,
    )


def _model_source(cfg: SessionConfig) -> Path:
    if cfg.model is None:  # load_config requires [model] with a gait trial
        raise ConfigError(f"{cfg.path}: a gait trial (role 'task') needs a [model] table")
    src = cfg.model.source
    if cfg.model.knee == "four_bar" and "fourbar" not in src.stem:
        alt = src.with_name(f"{src.stem}_fourbar{src.suffix}")
        if not alt.is_file():
            raise ConfigError(
                f"{cfg.path}: model.knee = 'four_bar' but {src.name} has a spline knee and "
                f"{alt.name} does not exist"
            )
        return alt
    return src


def _fes_settings(tc: TrialConfig) -> FesTrialConfig:
    """The FES keys of a ``role = "fes"`` trial (``load_config`` always fills them)."""
    if tc.fes is None:
        raise ConfigError(f"trial {tc.name!r}: role 'fes' without its FES settings")
    return tc.fes


def _load_model(path: Path, markers: Path | None = None) -> Any:
    """An msk model file or an OpenSim ``.osim`` (with its marker-set ``.xml`` when given)."""
    if path.suffix.lower() == ".osim":
        from msk.osim import load_osim

        return load_osim(path, marker_set=markers)
    from msk.model_files import load_model

    model = load_model(path)
    if markers is not None:
        from msk.osim import read_marker_set

        model = read_marker_set(markers, model)
    return model


def _read_contact(path: Path, trial: Path, grf: Path | None) -> Any:
    """Measured knee contact force (:func:`msk.io.contact_force.read_measured_contact`): a CSV
    with a time column or cycle-normalised (Grand Challenge eTibia), or a Grand Challenge DM
    ``.mat`` aligned to the task trial by its markers."""
    from msk.io.contact_force import read_measured_contact

    mc = read_measured_contact(
        path,
        trial=trial if path.suffix.lower() == ".mat" else None,
        grf=grf if path.suffix.lower() == ".mat" else None,
    )
    if mc.n_frames < 2:
        raise MissingDataError(f"{path}: no contact-force samples")
    return mc


# ---------------------------------------------------------------------------------------------
# the session: one method per stage, each composing library calls through the cached runner
# ---------------------------------------------------------------------------------------------
class _Session:
    """The state of one run. Each stage method runs one stage through :class:`_Runner` (cache,
    status, progress), stores its value and returns it; ``None`` when not available / failed."""

    def __init__(self, cfg: SessionConfig, runner: _Runner, fail_stage: str | None = None) -> None:
        self.cfg = cfg
        self.runner = runner
        self.fail_stage = fail_stage
        self.side = cfg.subject.side
        self.sfx = "_l" if self.side == "left" else "_r"
        self.body_weight = cfg.subject.mass_kg * G0
        self.fes_trials = cfg.trials_with_role("fes")
        self.fes_ = None
        tasks = cfg.trials_with_role("task")
        if not tasks and not self.fes_trials:
            raise ConfigError(f"{cfg.path}: no trial with role 'task' (nor 'fes')")
        #: gait analysis requested (a task trial); a pure FES session has none
        self.gait = bool(tasks)
        if not self.gait:
            self.files = {f"fes:{tc.name}": tc.file for tc in self.fes_trials}
            self.hashes = {k: file_sha256(p) for k, p in self.files.items()}
            return
        self.task = tasks[0]
        statics = cfg.trials_with_role("static")
        self.static = statics[0] if statics else None
        self.idtrials = cfg.trials_with_role("mass_identification")
        self.inv_rename = {v: k for k, v in cfg.marker_rename.items()}  # lab label → model name
        files = {"task": self.task.file}
        if self.static is not None:
            files["static"] = self.static.file
        if self.task.contact_force is not None:
            files["contact_force"] = self.task.contact_force
        if self.task.grf is not None:
            files["grf"] = self.task.grf
        if self.task.external_loads is not None:
            files["external_loads"] = self.task.external_loads
        for tc in (*self.idtrials, *cfg.trials_with_role("mvc"), *self.fes_trials):
            files[f"{tc.role}:{tc.name}"] = tc.file
        self.model_src = _model_source(cfg)
        assert cfg.model is not None  # _model_source raised without a [model] table
        #: the [model] table (always there in a gait session)
        self.model_cfg: ModelConfig = cfg.model
        files["model"] = self.model_src
        if self.model_cfg.markers is not None:
            files["model_markers"] = self.model_cfg.markers
        self.files = files
        self.hashes = {k: file_sha256(p) for k, p in files.items()}

    def check(self, name: str) -> None:
        if self.fail_stage == name:
            raise RuntimeError(f"stage {name} failed on purpose (test hook)")

    def labels_of(self, labels: Sequence[str]) -> tuple[str, ...]:
        """Lab marker labels in model names (``[markers] rename``)."""
        return tuple(self.inv_rename.get(lab, lab) for lab in labels)

    # ------------------------------------------------------------------ read
    def read(self) -> dict[str, Any]:
        def do() -> dict[str, Any]:
            self.check("read")
            from msk.io import read_c3d, read_trc_trial

            out: dict[str, Any]
            if self.task.file.suffix.lower() == ".trc":  # OpenSim ground: +y up
                out = {"trial": read_trc_trial(self.task.file)}
            else:
                out = {"trial": read_c3d(self.task.file)}
            if self.task.grf is not None:
                out["grf"] = _read_grf(self.task.grf, self.task.external_loads)
                if self.task.external_loads is not None:
                    from msk.loads import external_loads_assignment

                    out["assignment"] = external_loads_assignment(
                        self.task.external_loads, self.task.grf
                    )
            if self.task.contact_force is not None:
                out["contact"] = _read_contact(
                    self.task.contact_force, self.task.file, self.task.grf
                )
            return out

        self.raw = self.runner.run("read", do, settings={"files": self.hashes}, cache=True)
        self.trial = self.raw["trial"]
        return self.raw

    # ------------------------------------------------------------------ model
    def build_model(self) -> Any:
        """Marker-set recognition, heading, scaling (static trial, else the motion, else the
        stature: the method of every body is reported) and marker placement."""
        cfg = self.cfg
        trial = self.trial

        def do() -> dict[str, Any]:
            self.check("model")
            from msk.io.frames import pelvis_heading_rotation
            from msk.markersets import recognise, zeros_as_gaps
            from msk.scaling import (
                place_markers,
                place_markers_from_motion,
                scale_from_motion,
                scale_from_static,
            )

            model = _load_model(self.model_src, self.model_cfg.markers)
            bodies = [b.name for b in model.bodies]
            info: dict[str, Any] = {
                "source": str(self.model_src),
                "generic_mass_kg": model.total_mass,
            }
            x_lab = zeros_as_gaps(trial.markers)
            match = recognise(
                trial.marker_labels, model.marker_names, rename=cfg.marker_rename,
                model_bodies=bodies, markers=x_lab,
            )  # fmt: skip
            # names in the configuration that match nothing are errors, not silently ignored
            up = -np.asarray(model.gravity, dtype=float)
            # the static trial, read once: its labels for the checks, its markers for scaling
            static_read = None if self.static is None else _read_markers(self.static.file, up)
            labels_all = set(trial.marker_labels)
            if static_read is not None:
                labels_all |= set(static_read[1])
            # (a lab label absent from these trials is a note: rename tables of a protocol
            # list variants a given session may not use)
            absent = sorted(set(cfg.marker_rename.values()) - labels_all)
            unknown = sorted(set(cfg.marker_rename) - set(model.marker_names))
            if unknown:
                raise ConfigError(
                    f"{cfg.path}: markers.rename: the model has no marker {unknown[0]!r}"
                )
            info["marker_set"] = {
                "protocol": match.protocol,
                "matched": dict(match.rename),
                "excluded": dict(match.excluded),
                "notes": list(match.notes)
                + ([f"markers.rename: labels in no trial: {', '.join(absent)}"] if absent else []),
            }
            # heading: the progression where it agrees with the pelvis markers (within 30°),
            # else the pelvis markers (treadmill, turning, short trials), else none
            head = pelvis_heading_rotation(
                trial.up, up, x_lab, trial.marker_labels, model, rename=match.rename
            )
            rot, source = head.rotation, head.source
            prog = head.progression_yaw_deg
            if prog is not None and (
                head.source != "pelvis markers"
                or abs((head.yaw_deg - prog + 180.0) % 360.0 - 180.0) <= 30.0
            ):
                rot, source = lab_to_model_rotation(trial.up, up, trial.markers), "progression"
            info["heading"] = {
                "source": source,
                "pelvis_yaw_deg": head.yaw_deg if head.source == "pelvis markers" else None,
                "progression_yaw_deg": prog,
                "message": head.message,
            }
            report = None
            if static_read is not None:
                sm, slabels_raw, stime = static_read
                smatch = recognise(
                    slabels_raw, model.marker_names, rename=cfg.marker_rename,
                    model_bodies=bodies, markers=zeros_as_gaps(sm),
                )  # fmt: skip
                sm, slabels = smatch.apply(sm, slabels_raw)
                if self.model_cfg.scale:
                    static = {lab: sm[:, i] for i, lab in enumerate(slabels)}
                    model, report = scale_from_static(
                        model, static, height_m=cfg.subject.height_m,
                        body_mass=cfg.subject.mass_kg,
                    )  # fmt: skip
                try:
                    model, placed = place_markers(
                        model, sm, slabels, stime, move=cfg.marker_move,
                        hints=smatch.body_hints([b.name for b in model.bodies]),
                    )  # fmt: skip
                except ModelError as exc:
                    raise ConfigError(f"{cfg.path}: markers.move: {exc}") from None
                info["marker_placement"] = placed
            else:
                # no static trial: the task trial's own markers scale and place (the segment
                # lengths are constant over a motion; msk.scaling.scale_from_motion)
                xm, mlabels = match.apply(trial.rotated(rot).markers, trial.marker_labels)
                if self.model_cfg.scale:
                    model, report = scale_from_motion(
                        model, xm, mlabels, trial.time, height_m=cfg.subject.height_m,
                        body_mass=cfg.subject.mass_kg,
                    )  # fmt: skip
                model, placed = place_markers_from_motion(
                    model, xm, mlabels, trial.time, move=cfg.marker_move
                )
                info["marker_placement"] = placed
            if report is not None:
                info["scaling"] = report.summary()
                info["scale_ratios"] = dict(model.metadata.get("scale_ratios", {}))
            info["mass_kg"] = model.total_mass
            return {"model": model, "info": info, "rotation": rot, "rename": dict(match.rename)}

        self.built = self.runner.run(
            "model",
            do,
            needs=("read",),
            settings={
                "model": self.hashes["model"],
                "model_markers": self.hashes.get("model_markers"),
                "static": self.hashes.get("static"),
                "scale": self.model_cfg.scale,
                "knee": self.model_cfg.knee,
                "mass": cfg.subject.mass_kg,
                "height": cfg.subject.height_m,
                "rename": dict(cfg.marker_rename),
                "move": list(cfg.marker_move),
            },
        )
        self.model = self.built["model"]
        unknown = sorted(
            set(cfg.marker_weights) - set(self.model.marker_names) - set(trial.marker_labels)
        )
        if unknown:
            raise ConfigError(f"{cfg.path}: markers.weights: no marker {unknown[0]!r}")
        # the task trial in the model frame (lab up → model up, heading as decided above);
        # exact-zero samples are gaps (TRC writers store missing markers as 0, 0, 0)
        from msk.markersets import zeros_as_gaps

        self.rot = self.built["rotation"]
        mtrial = trial.rotated(self.rot)
        self.mtrial = dataclasses.replace(mtrial, markers=zeros_as_gaps(mtrial.markers))
        inv = {v: k for k, v in self.built["rename"].items()}
        self.labels = tuple(inv.get(lab, lab) for lab in trial.marker_labels)
        # foot joints the markers cannot observe (fewer than 3 markers on the bodies distal to
        # the joint: e.g. Plug-in Gait's heel + toe) are held near neutral by an IK coordinate
        # task (OpenSim's IKCoordinateTask), reported, instead of wandering to −75°
        # (a marker counts when the trial tracks it in at least half of the frames it tracks
        # anything: metatarsal-head markers lost in most frames do not observe the subtalar)
        x = self.mtrial.markers
        vis = np.isfinite(x).all(axis=2)
        anyvis = vis.any(axis=1)
        frac = vis[anyvis].mean(axis=0) if anyvis.any() else np.zeros(len(self.labels))
        seen = {
            lab for k, lab in enumerate(self.labels)
            if lab in self.model.marker_names and frac[k] >= 0.5
        }  # fmt: skip
        body_of = {m.name: m.body for m in self.model.markers}
        self.held: dict[str, tuple[float, float]] = {}
        for sfx in ("_r", "_l"):
            for coord, child in (("subtalar_angle", "calcn"), ("mtp_angle", "toes")):
                name, body = coord + sfx, child + sfx
                if name not in self.model.coordinate_names or body not in self.model.body_joint:
                    continue
                sub = set(self.model.subtree(body))
                if sum(body_of.get(m) in sub for m in seen) < 3:
                    self.held[name] = (0.0, HELD_COORDINATE_WEIGHT)
        # plates of a GRF file (``grf``), in the frame of the trial's markers: rotated alike
        grf = self.raw.get("grf")
        self.grf_plates = None if grf is None else tuple(_rotated_plate(p, self.rot) for p in grf)
        return self.model

    # ------------------------------------------------------------------ kinematics, loads
    def _solve_kinematics(self, trial: Any, labels: Sequence[str]) -> Any:
        """IK of a trial; a frame that sees fewer than half of the model markers the trial
        tracks at best is not solved (a subject walking out of the capture volume leaves the
        acromia alone in view: IK there would give the legs any pose)."""
        from msk.kinematics import solve_kinematics

        names = set(self.model.marker_names)
        cols = [i for i, lab in enumerate(labels) if lab in names]
        seen = np.isfinite(trial.markers[:, cols]).all(axis=2)  # (N, used markers)
        # a frame where a leg segment carrying markers in this trial has none in view is not
        # solved either: its pose would come from the neighbours only (joint torques there
        # would be computed from a guessed pose)
        body_of = {m.name: m.body for m in self.model.markers}
        blind = np.zeros(trial.time.size, dtype=bool)
        for body in {body_of[labels[i]] for i in cols}:
            if body.startswith(("pelvis", "femur", "tibia", "calcn")):
                on = [k for k, i in enumerate(cols) if body_of[labels[i]] == body]
                blind |= ~seen[:, on].any(axis=1)
        markers = np.array(trial.markers, dtype=float, copy=True)
        markers[blind] = np.nan
        return solve_kinematics(
            self.model,
            markers,
            labels,
            trial.time,
            weights=dict(self.cfg.marker_weights) or None,
            coordinate_tasks=dict(self.held) or None,
            cutoff_hz=self.cfg.filters.kinematics_cutoff_hz,
            min_markers=max(3, int(np.ceil(MIN_MARKER_FRACTION * seen.sum(axis=1).max()))),
        )

    def _external_loads(self, trial: Any, kin: Any, plates: Any = None) -> Any:
        from msk.loads import external_loads, plates_from_trial

        plates = plates_from_trial(trial) if plates is None else plates
        # explicit assignment: the ExternalLoads .xml of a GRF file, then the config's [loads]
        assign = {**self.raw.get("assignment", {}), **self.cfg.loads.assign} or None
        return external_loads(
            self.model, kin, plates, assignment=assign, cutoff_hz=self.cfg.filters.grf_cutoff_hz
        )

    def kinematics(self) -> Any:
        def do() -> Any:
            self.check("kinematics")
            return self._solve_kinematics(self.mtrial, self.labels)

        self.kin = self.runner.run(
            "kinematics",
            do,
            needs=("read", "model"),
            settings={
                "weights": dict(self.cfg.marker_weights),
                "cut": self.cfg.filters.kinematics_cutoff_hz,
                "held": dict(self.held),
            },
        )
        return self.kin

    def loads(self) -> Any:
        def do() -> Any:
            self.check("loads")
            return self._external_loads(self.mtrial, self.kin, self.grf_plates)

        self.ext = self.runner.run(
            "loads",
            do,
            needs=("kinematics",),
            settings={
                "cut": self.cfg.filters.grf_cutoff_hz,
                "assignment": PLATE_ASSIGNMENT,
                "assign": dict(self.cfg.loads.assign),
            },
        )
        kin = self.kin
        # frames where a foot stands on the floor beside the plates miss a ground reaction:
        # no residual, identification equation or muscle force comes from them
        self.measured = _contact_measured(self.model, kin, self.ext)
        self.ok_frames = (
            np.isfinite(kin.q).all(axis=1) & np.isfinite(kin.a).all(axis=1) & self.measured
        )
        return self.ext

    # ------------------------------------------------------------------ mass identification
    def mass_identification(self) -> dict[str, Any] | None:
        cfg, kin = self.cfg, self.kin

        def do() -> dict[str, Any]:
            self.check("mass_identification")
            from msk.identification import IdentificationTrial as trial_cls
            from msk.identification import InertialIdentifier as ident_cls
            from msk.io import read_c3d, to_model_frame

            up = -np.asarray(self.model.gravity, dtype=float)
            runs = [(self.task.name, kin, self.ext, self.measured)]
            for tc in self.idtrials:  # dedicated exciting motions (seeds/002 §VI) + the task
                tr_i = to_model_frame(read_c3d(tc.file), up=up)
                k_i = self._solve_kinematics(tr_i, self.labels_of(tr_i.marker_labels))
                l_i = self._external_loads(tr_i, k_i)
                runs.append((tc.name, k_i, l_i, _contact_measured(self.model, k_i, l_i)))
            its = []
            for nm, k_i, l_i, m_i in runs:
                it = trial_cls.from_loads(self.model, k_i, l_i, name=nm)
                good = (
                    np.isfinite(it.tau_ext).all(axis=1)
                    & np.isfinite(it.theta_ddot).all(axis=1)
                    & m_i
                )
                its.append(
                    trial_cls(
                        it.theta[good],
                        it.theta_dot[good],
                        it.theta_ddot[good],
                        it.tau_ext[good],
                        nm,
                    )
                )
            est = ident_cls(
                self.model, total_mass=cfg.subject.mass_kg, symmetric=True, prior_weight="cv"
            ).fit(its)
            good = np.isfinite(kin.q).all(axis=1)
            return {
                "parameters": {k: np.asarray(v) for k, v in est.parameters_.items()},
                "segments": [_segment_summary(s) for s in est.segments_],
                "condition_number": float(est.condition_number_),
                "n_frames": int(est.n_frames_),
                "advice": list(est.advice()),
                "t0": float(kin.time[good][0]),
            }

        self.ident = self.runner.run(
            "mass_identification",
            do,
            needs=("loads",),
            settings={
                "trials": [file_sha256(t.file) for t in self.idtrials],
                "mass": cfg.subject.mass_kg,
            },
        )
        self.model_id = (
            self.model.with_inertias(self.ident["parameters"]) if self.ident else self.model
        )
        return self.ident

    # ------------------------------------------------------------------ inverse dynamics
    def inverse_dynamics(self) -> dict[str, Any]:
        def do() -> dict[str, Any]:
            self.check("inverse_dynamics")
            from msk.dynamics import inverse_dynamics

            out = {"generic": inverse_dynamics(self.model, self.kin, self.ext)}
            if self.ident is not None:
                out["identified"] = inverse_dynamics(self.model_id, self.kin, self.ext)
            return out

        self.tau = self.runner.run(
            "inverse_dynamics",
            do,
            needs=("loads",) + (("mass_identification",) if self.ident else ()),
        )
        self.jt = self.tau.get("identified", self.tau["generic"])
        return self.tau

    # ------------------------------------------------------------------ EMG
    def emg(self) -> dict[str, Any] | None:
        cfg, model, kin, trial = self.cfg, self.model, self.kin, self.trial

        def do() -> dict[str, Any]:
            self.check("emg")
            if not cfg.emg.channels:
                raise StageUnavailable("no [emg] channels in the configuration")
            from msk.muscles.activation import first_order_activation
            from msk.muscles.emg import envelopes_from_trial

            unknown = sorted(set(cfg.emg.channels) - {m.name for m in model.muscles})
            if unknown:
                raise ConfigError(f"{cfg.path}: emg.channels: model has no muscle {unknown[0]!r}")
            labels = {str(a).strip() for a in getattr(trial, "analog_labels", ())}
            missing = sorted({str(c).strip() for c in cfg.emg.channels.values()} - labels)
            if missing:
                raise ConfigError(
                    f"{cfg.path}: emg.channels: {self.task.file.name} has no analog channel "
                    f"{missing[0]!r}"
                )
            from msk.io import read_c3d

            mvc = []
            for tc in cfg.trials_with_role("mvc"):
                tr_m = read_c3d(tc.file)
                mvc.append((tr_m.analogs, tr_m.analog_rate_hz, tr_m.analog_labels))
            mvc_options: dict[str, Any] = {}
            if mvc:
                mvc_options["mvc_trials"] = mvc
            if cfg.emg.mvc:
                mvc_options["mvc"] = {k: float(v) for k, v in cfg.emg.mvc.items()}
            env = envelopes_from_trial(
                trial,
                muscles=dict(cfg.emg.channels),
                highpass_hz=cfg.emg.highpass_hz,
                lowpass_hz=cfg.emg.lowpass_hz,
                delay_s=cfg.emg.electromechanical_delay_s,
                **mvc_options,
            )
            env_k = env.resampled(kin.time)
            e = np.clip(np.nan_to_num(env_k.envelopes, nan=0.0), 0.0, 1.0)
            act = first_order_activation(e, rate_hz=trial.point_rate_hz)
            act[:, ~env_k.usable] = np.nan
            return {
                "normalisation": "MVC"
                if (mvc or cfg.emg.mvc)
                else "this session's peak (relative activations, not strength)",
                "muscles": env_k.muscle_names,
                "sources": env_k.muscle_sources,
                "envelopes": env_k.envelopes,
                "activation": act,
                "usable": env_k.usable,
                "warnings": list(env.warnings),
                "quality": env.quality,  # msk.muscles.emg.ChannelQuality
            }

        self.emg_ = self.runner.run(
            "emg",
            do,
            needs=("read", "kinematics"),
            settings={
                "channels": dict(cfg.emg.channels),
                "hp": cfg.emg.highpass_hz,
                "lp": cfg.emg.lowpass_hz,
                "emd": cfg.emg.electromechanical_delay_s,
                "mvc": [file_sha256(t.file) for t in cfg.trials_with_role("mvc")],
                "mvc_values": dict(cfg.emg.mvc),
            },
        )
        return self.emg_

    # ------------------------------------------------------------------ muscle geometry
    def muscle_geometry(self) -> Any:
        model, kin, ok = self.model, self.kin, self.ok_frames

        def do() -> Any:
            self.check("muscle_geometry")
            if not model.muscles:
                raise StageUnavailable(f"model {model.name} has no muscles")
            from msk.muscles.geometry import muscle_geometry

            q = np.where(ok[:, None], kin.q, model.default_coordinates()[None, :])
            v = np.where(ok[:, None], kin.v, 0.0)
            # the knee's unit wrenches ∂l/∂ξ for the contact stage, from this same pass
            knee = tuple(j.name for j in model.joints if j.name == f"knee{self.sfx}")
            return muscle_geometry(model, q, v, distal_wrench_joints=knee)

        self.geom = self.runner.run("muscle_geometry", do, needs=("kinematics",))
        root = tuple(self.jt.root_coordinates)
        self.act_idx = [i for i, c in enumerate(self.jt.coordinate_names) if c not in root]
        return self.geom

    def _muscle_state(self, mdl: Any) -> tuple[Any, Any]:
        from msk.muscles.geometry import muscle_parameters
        from msk.muscles.hill import rigid_tendon_state

        params = muscle_parameters(mdl)
        return params, rigid_tendon_state(params, self.geom.lengths, self.geom.velocities)

    # ------------------------------------------------------------------ tension optimisation
    def _optimise(self, mdl: Any, torques: Any) -> dict[str, Any]:
        """Muscle tensions of ``mdl`` for ``torques`` by the configured method (msk.optimization
        batch solvers) on the usable frames; NaN elsewhere."""
        import msk.optimization as o

        cfg, kin, emg, act_idx = self.cfg, self.kin, self.emg_, self.act_idx
        params, state = self._muscle_state(mdl)
        # a frame whose inputs cannot be posed (non-finite geometry or torques, negative
        # active force) is excluded and flagged, never allowed to abort the whole stage
        # a muscle shortening faster than its maximal velocity produces no active force: the
        # force–velocity curve's extrapolation below zero (noisy fibre velocities of short
        # trunk muscles) is clipped to 0 rather than costing the frame
        fa_all = np.where(
            state.max_active_force_along_tendon < 0, 0.0, state.max_active_force_along_tendon
        )
        fp_all = state.passive_force_along_tendon
        posable = (
            np.isfinite(self.geom.jacobian[:, :, act_idx]).all(axis=(1, 2))
            & np.isfinite(torques.tau[:, act_idx]).all(axis=1)
            & np.isfinite(fa_all).all(axis=1)
            & np.isfinite(fp_all).all(axis=1)
        )
        ok = self.ok_frames & posable
        excluded = int((self.ok_frames & ~posable).sum())
        jac = self.geom.jacobian[ok][:, :, act_idx]
        tq = torques.tau[ok][:, act_idx]
        cn = tuple(self.jt.coordinate_names[i] for i in act_idx)
        reserves = np.ones(len(act_idx))
        meth = cfg.optimization.method
        fa = fa_all[ok]
        fp = fp_all[ok]
        common = {"muscle_names": params.names, "coordinate_names": cn, "time": kin.time[ok]}
        solver = cfg.optimization.solver
        opt = cfg.optimization
        weights = (  # activation weights of static_optimization and emg_assisted
            o.volume_weights(params.max_isometric_force, params.optimal_fiber_length)
            if opt.activation_weights == "volume"
            else None
        )
        if meth == "static_optimization":
            sol = o.solve_static_optimization_batch(
                jac, tq, f_active=fa, f_passive=fp, reserve_optimal_force=reserves,
                activation_weights=weights, activation_exponent=opt.activation_exponent,
                solver=solver, **common,
            )  # fmt: skip
            forces, acts = sol.forces, sol.activations
        elif meth == "bounded_qp":
            sol = o.solve_tension_batch(
                jac, tq, f_iso=params.max_isometric_force, f_max=fa + fp,
                reserve_optimal_force=reserves, solver=solver, **common,
            )  # fmt: skip
            forces = sol.forces
            acts = np.clip(forces / np.maximum(fa, 1e-9), 0, None)
        elif meth in ("emg_weighted", "emg_assisted"):
            if emg is None:
                raise StageUnavailable(f"{meth} needs the EMG stage")
            meas = np.array(
                [
                    n in emg["muscles"] and bool(emg["usable"][emg["muscles"].index(n)])
                    for n in params.names
                ]
            )
            a = np.zeros_like(fa)
            for k, n in enumerate(params.names):
                if meas[k]:
                    a[:, k] = emg["activation"][ok, emg["muscles"].index(n)]
            if meth == "emg_weighted":
                sol = o.solve_emg_weighted_batch(
                    jac, tq, f_ref=a * fa, measured=meas, w_emg=cfg.optimization.w_emg,
                    f_max=fa + fp, solver=solver, **common,
                )  # fmt: skip
                forces = sol.forces
                acts = np.clip(forces / np.maximum(fa, 1e-9), 0, None)
            else:
                sol, gains = self._emg_assisted(
                    jac, tq, fa, a, meas, params.names, weights, reserves, common
                )
                forces, acts = sol.forces, sol.activations
        else:  # closed_form (seeds/004 Eq. 6, unbounded)
            lag = o.solve_lagrange_batch(
                jac, tq, area=params.max_isometric_force, muscle_names=params.names
            )
            forces = lag.forces
            acts = forces / np.maximum(fa, 1e-9)
            sol = None
        n = kin.time.size
        f_all = np.full((n, len(params.names)), np.nan)
        a_all = np.full_like(f_all, np.nan)
        f_all[ok], a_all[ok] = forces, acts
        out = {"forces": f_all, "activations": a_all, "muscles": params.names, "method": meth}
        out["excluded_frames"] = excluded
        if excluded:
            out["excluded_reason"] = "non-finite geometry, torque or muscle force curves"
        w = "V_i " if opt.activation_weights == "volume" else ""
        if meth == "static_optimization":
            out["criterion"] = f"min Σ {w}a_i^{opt.activation_exponent:g}"
        elif meth == "emg_assisted":
            out["criterion"] = (
                f"min Σ {w}a_i^2 + {opt.w_track:g} Σ (a_i − g_c ê_i)^2, gains g_c fitted on the "
                "trial's torques"
            )
            out["emg_gains"] = gains
        if sol is not None:
            out["infeasible_frames"] = int(sol.infeasible_frames.size)
            rt = np.full((n, len(act_idx)), np.nan)
            rt[ok] = sol.reserve_torques
            out["reserve_torques"] = rt
            out["reserve_coordinates"] = cn
        return out

    def _emg_assisted(
        self,
        jac: np.ndarray,
        tq: np.ndarray,
        fa: np.ndarray,
        emg_act: np.ndarray,
        measured: np.ndarray,
        names: tuple[str, ...],
        weights: np.ndarray | None,
        reserves: np.ndarray,
        common: dict[str, Any],
    ) -> tuple[Any, dict[str, float]]:
        """EMG-assisted static optimisation with one gain per EMG channel fitted jointly with
        the activations on this trial's torques (:func:`msk.strength.fit_emg_gains`), then
        solved once more with the final gains (KKT figures included)."""
        import msk.optimization as o
        from msk.strength import fit_emg_gains

        opt = self.cfg.optimization
        channels = self.cfg.emg.channels
        groups: dict[str, list[str]] = {}
        for k, n in enumerate(names):
            if measured[k]:
                groups.setdefault(channels[n], []).append(n)
        fit = fit_emg_gains(
            jac, tq, f_active=fa, emg_activation=emg_act, groups=groups,
            muscle_names=names, w_track=opt.w_track, activation_weights=weights,
            reserve_optimal_force=reserves, coordinate_names=common["coordinate_names"],
        )  # fmt: skip
        sol = o.solve_emg_assisted_batch(
            jac, tq, f_active=fa, a_ref=fit.reference(emg_act), measured=fit.measured,
            w_track=opt.w_track, activation_weights=weights, reserve_optimal_force=reserves,
            solver=opt.solver, **common,
        )  # fmt: skip
        return sol, dict(zip(fit.group_names, map(float, fit.gains)))

    def tension_optimization(self) -> dict[str, Any] | None:
        cfg = self.cfg
        needs = ("muscle_geometry", "inverse_dynamics") + (
            ("emg",) if cfg.optimization.method in ("emg_weighted", "emg_assisted") else ()
        )

        def do() -> dict[str, Any]:
            self.check("tension_optimization")
            return self._optimise(self.model_id, self.jt)

        self.sol = self.runner.run(
            "tension_optimization", do, needs=needs, settings=dataclasses.asdict(cfg.optimization)
        )
        return self.sol

    # ------------------------------------------------------------------ strength
    def strength_identification(self) -> dict[str, Any] | None:
        kin, jt, ok = self.kin, self.jt, self.ok_frames

        def do() -> dict[str, Any]:
            self.check("strength_identification")
            from msk.strength import StrengthIdentifier as ident_cls

            emg = self.emg_
            params, state = self._muscle_state(self.model)
            groups: dict[str, list[str]] = {}
            for k, m in enumerate(emg["muscles"]):
                if emg["usable"][k]:
                    groups.setdefault(emg["sources"][k], []).append(m)
            if not groups:
                raise StageUnavailable("no usable EMG channel")
            act = np.zeros((kin.time.size, len(params.names)))
            for k, m in enumerate(emg["muscles"]):
                if emg["usable"][k]:
                    act[:, params.names.index(m)] = emg["activation"][:, k]
            good = ok & np.isfinite(jt.tau).all(axis=1)
            est = ident_cls(groups, params, n_bootstrap=200, random_state=0)
            est.fit(
                self.geom.jacobian[good],
                act[good],
                jt.tau[good],
                _slice_state(state, good),
                coordinate_names=jt.coordinate_names,
            )
            return {
                "profile": est.profile_,
                "groups": {g: list(v) for g, v in groups.items()},
                "t0": float(kin.time[good][0]),
            }

        self.strength = self.runner.run(
            "strength_identification",
            do,
            needs=("muscle_geometry", "emg", "inverse_dynamics"),
        )
        return self.strength

    # ------------------------------------------------------------------ knee contact
    def knee_contact(self) -> dict[str, Any] | None:
        model, kin, ext, ok_frames = self.model, self.kin, self.ext, self.ok_frames

        def do() -> dict[str, Any]:
            self.check("knee_contact")
            from msk.contact import knee_contact_force, plateau_geometry, split_medial_lateral

            joint = f"knee{self.sfx}"
            if joint not in {j.name for j in model.joints}:
                raise StageUnavailable(f"model has no joint {joint!r}")
            res: dict[str, Any] = {"joint": joint}
            variants = {"generic": (model, self.sol)}
            if self.strength is not None:
                from msk.strength import with_strength

                m_spec = with_strength(self.model_id, self.strength["profile"])
                variants["subject_specific"] = (m_spec, self._optimise(m_spec, self.jt))
            n = kin.time.size
            for name, (mdl, s) in variants.items():
                # frames without muscle forces get no contact force (never zero muscle force)
                ok = np.flatnonzero(ok_frames & np.isfinite(s["forces"]).all(axis=1))
                # ∂l/∂ξ of the geometry stage (same paths and muscle order in both variants:
                # with_strength only scales F_iso)
                dw = getattr(self.geom, "distal_wrenches", {}).get(joint)
                contact = knee_contact_force(
                    mdl,
                    _frames(kin, ok, n),
                    _frames(ext, ok, n),
                    muscle_forces=s["forces"][ok],
                    muscle_names=tuple(s["muscles"]),
                    joint=joint,
                    distal_wrenches=None if dw is None else dw[ok],
                )
                force = np.full((n, 3), np.nan)
                force[ok] = contact.force
                # two-point medial/lateral split (Winby et al. 2009; Lerner et al. 2015)
                geo = plateau_geometry(
                    mdl, joint=joint,
                    intercondylar_distance_m=self.cfg.contact.intercondylar_distance_m,
                )  # fmt: skip
                ml = split_medial_lateral(contact, geo)
                medial = np.full(n, np.nan)
                lateral = np.full(n, np.nan)
                medial[ok], lateral[ok] = ml.medial, ml.lateral
                res[name] = {
                    "force": force,
                    "total": np.linalg.norm(force, axis=1),
                    "medial": medial,
                    "lateral": lateral,
                }
                res["plateau"] = {
                    "intercondylar_distance_m": geo.intercondylar_distance_m,
                    "centre_m": list(geo.centre_m),
                    "source": geo.source,
                }
            if "contact" in self.raw:
                res["measured"] = self.raw["contact"]
            return res

        self.contact = self.runner.run(
            "knee_contact",
            do,
            needs=("tension_optimization",)
            + (("strength_identification",) if self.strength is not None else ()),
            settings={
                "contact": self.hashes.get("contact_force"),
                "icd": self.cfg.contact.intercondylar_distance_m,
            },
        )
        return self.contact

    # ------------------------------------------------------------------ result tables
    def tables(self) -> dict[str, Table]:
        kin, jt, sol, contact = self.kin, self.jt, self.sol, self.contact
        from msk.events import detect_gait_events, reconcile

        # gait events: the file's where they agree with the plates, else detected from the
        # plates and the kinematics (Zeni et al. 2008); the notes say which
        self.gait_events = reconcile(
            self.trial.events,
            detect_gait_events(self.model, kin, self.ext, observed=self.measured),
        )
        self.events = self.gait_events.as_list()
        strikes = sorted(self.gait_events.foot_strike.get(self.side, ()))
        t = kin.time

        def on_plates(c: tuple[float, float]) -> float:
            sel = (t >= c[0]) & (t <= c[1])
            return float(self.measured[sel].mean()) if sel.any() else 0.0

        # the gait cycle of the report: the one the plates measure best (the first on a tie;
        # a walkway's plates often see the second cycle of the trial, not the first)
        cycles = list(itertools.pairwise(strikes))
        self.cycle = max(cycles, key=on_plates) if cycles else None
        bw = self.body_weight
        tables: dict[str, Table] = {
            "q": Table(t, kin.q, tuple(kin.coordinate_names), "q"),
            "joint_torques": Table(t, jt.tau, tuple(jt.coordinate_names), "joint_torques"),
            "residuals": Table(
                t,
                np.column_stack([jt.residual_force, jt.residual_moment]),
                ("force_x", "force_y", "force_z", "moment_x", "moment_y", "moment_z"),
                "residuals",
            ),
        }
        if sol is not None:
            names = tuple(sol["muscles"])
            tables["muscle_forces"] = Table(t, sol["forces"], names, "muscle_forces")
            tables["activations"] = Table(t, sol["activations"], names, "activations")
        self.measured_on_t = None
        if contact is not None:
            cols, data = [], []
            for name in ("generic", "subject_specific"):
                if name in contact:
                    c = contact[name]
                    cols += [f"{name}_{a}" for a in ("x", "y", "z")]
                    cols += [f"{name}_total", f"{name}_total_bw"]
                    data += [c["force"], c["total"][:, None], (c["total"] / bw)[:, None]]
                    for comp in ("medial", "lateral"):
                        cols += [f"{name}_{comp}", f"{name}_{comp}_bw"]
                        data += [c[comp][:, None], (c[comp] / bw)[:, None]]
            meas = contact.get("measured")
            if meas is not None and (meas.time is not None or self.cycle is not None):
                if meas.time is not None:
                    tm = np.asarray(meas.time, dtype=float)
                else:
                    assert self.cycle is not None  # the condition above
                    c0, c1 = self.cycle
                    tm = c0 + np.asarray(meas.cycle_fraction, dtype=float) * (c1 - c0)
                self.measured_on_t = {}
                for comp in ("total", "medial", "lateral"):
                    y = np.asarray(getattr(meas, comp), dtype=float)
                    if not np.isfinite(y).any():
                        continue
                    on_t = np.interp(t, tm, y, left=np.nan, right=np.nan)
                    self.measured_on_t[comp] = on_t
                    cols += [f"measured_{comp}", f"measured_{comp}_bw"]
                    data += [on_t[:, None], (on_t / bw)[:, None]]
            tables["knee_contact"] = Table(t, np.column_stack(data), tuple(cols), "knee_contact")
        if self.ident is not None:
            tables["inertial_parameters"] = _inertial_table(self.ident)
        if self.strength is not None:
            tables["strength"] = _strength_table(self.strength)
        self.tables_ = tables
        return tables

    # ------------------------------------------------------------------ comparison
    def comparison(self) -> dict[str, Any] | None:
        tau, contact, strength, sfx, bw = (
            self.tau, self.contact, self.strength, self.sfx, self.body_weight
        )  # fmt: skip
        measured_on_t, on_plates = self.measured_on_t, self.measured

        def do() -> dict[str, Any]:
            self.check("comparison")
            from msk import compare

            out: dict[str, Any] = {}
            if "identified" in tau:
                g, s = tau["generic"], tau["identified"]
                good = np.isfinite(g.tau).all(axis=1) & np.isfinite(s.tau).all(axis=1)
                good &= on_plates
                leg = [i for i, c in enumerate(g.coordinate_names) if c.endswith(sfx)]
                out["torque_rms_difference_nm"] = {
                    g.coordinate_names[i]: float(compare.rms(g.tau[good, i], s.tau[good, i]))
                    for i in leg
                }
                out["residual_force_rms_n"] = {
                    "generic": _rms(g.residual_force[good]),
                    "identified": _rms(s.residual_force[good]),
                }
                out["residual_moment_rms_nm"] = {
                    "generic": _rms(g.residual_moment[good]),
                    "identified": _rms(s.residual_moment[good]),
                }
            if contact is not None and measured_on_t:
                for name in ("generic", "subject_specific"):
                    if name not in contact:
                        continue
                    for comp, meas in measured_on_t.items():
                        pred = contact[name][comp]
                        m = np.isfinite(meas) & np.isfinite(pred)
                        if m.sum() < 5:
                            continue
                        key = f"knee_contact_{name}" + ("" if comp == "total" else f"_{comp}")
                        out[key] = _contact_agreement(meas[m], pred[m], bw)
            if strength is not None:
                p = strength["profile"]
                out["strength_factor_minus_generic"] = {
                    n: float(f - 1.0) for n, f in zip(p.group_names, p.factors)
                }
            if not out:
                raise StageUnavailable("nothing to compare")
            return out

        self.comparison_ = self.runner.run(
            "comparison",
            do,
            needs=("inverse_dynamics",),
            settings=[self.runner.keys.get(n) for n in ("knee_contact", "strength_identification")],
        )
        return self.comparison_

    # ------------------------------------------------------------------ FES
    def fes(self) -> dict[str, Any] | None:
        """seeds/000's identification protocol on the ``role = "fes"`` trials."""
        cfg = self.cfg
        if not self.fes_trials:
            self.runner.skip("fes", "no trial with role 'fes' in the configuration")
            return None

        def do() -> dict[str, Any]:
            self.check("fes")
            from msk.fes.protocol import run_protocol

            session = _fes_session(cfg, self.fes_trials)
            res = run_protocol(
                session,
                fibre_fraction=cfg.fes.fibre_fraction,
                stiffness_ratio=cfg.fes.stiffness_ratio,
                k_s0=cfg.fes.k_s0,
                outer_iterations=cfg.fes.outer_iterations,
                steady_window=cfg.fes.steady_window_s,
                isometric_transients=cfg.fes.isometric_transients,
            )
            return {"result": res}

        self.fes_ = self.runner.run(
            "fes",
            do,
            settings={
                "files": {tc.name: self.hashes[f"fes:{tc.name}"] for tc in self.fes_trials},
                "trials": [
                    {"name": tc.name, **dataclasses.asdict(_fes_settings(tc))}
                    for tc in self.fes_trials
                ],
                "options": dataclasses.asdict(cfg.fes),
                "height": cfg.subject.height_m,
                "mass": cfg.subject.mass_kg,
            },
        )
        return self.fes_

    def fes_tables(self) -> dict[str, Table]:
        return {} if self.fes_ is None else _fes_tables(self.fes_["result"])

    def fes_summary(self) -> dict[str, Any] | None:
        if self.fes_ is None:
            return None
        return _fes_summary(self.fes_["result"], self.cfg, self.fes_trials)

    # ------------------------------------------------------------------ summary
    def base_summary(self) -> dict[str, Any]:
        """The part of ``summary.json`` every session has (gait or FES only)."""
        cfg = self.cfg
        return {
            "session": cfg.subject.name,
            "trial": self.task.name if self.gait else None,
            "created_utc": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "versions": _versions(),
            "config": {"path": str(cfg.path), "sha256": file_sha256(cfg.path)},
            "inputs": [
                {
                    "role": k,
                    "path": str(p),
                    "sha256": self.hashes[k],
                    "bytes": Path(p).stat().st_size,
                }
                for k, p in self.files.items()
            ],
            "settings": _settings(cfg),
            "subject": {
                "name": cfg.subject.name,
                "mass_kg": cfg.subject.mass_kg,
                "height_m": cfg.subject.height_m,
                "sex": cfg.subject.sex,
                "side": self.side,
                "body_weight_n": self.body_weight,
            },
        }

    def summary(self) -> dict[str, Any]:
        cfg, model, sol, ident, strength = (
            self.cfg, self.model, self.sol, self.ident, self.strength
        )  # fmt: skip
        quality = _quality(
            self.trial, self.kin, self.jt, self.ext, self.emg_, sol, strength, ident,
            self.body_weight, self.measured,
        )  # fmt: skip
        from msk.quality import THRESHOLDS, body_mass_from_loads, gait_flags

        plate_mass = body_mass_from_loads(model, self.kin, self.ext, self.measured)
        quality["plate_mass_kg"] = plate_mass
        quality["flags"] = [
            f.as_dict()
            for f in gait_flags(
                self.task.name, quality=quality, model=model, kinematics=self.kin,
                joint_torques=self.jt, mass_kg=cfg.subject.mass_kg,
                height_m=cfg.subject.height_m, marker_labels=self.trial.marker_labels,
                optimization=sol, plate_mass_kg=plate_mass, held=tuple(self.held),
                scaling_methods={
                    b: v["method"]
                    for b, v in self.built["info"].get("scaling", {}).get("bodies", {}).items()
                },
                peak_external_force_n=float(np.nanmax(
                    np.linalg.norm(np.nansum(self.ext.force[self.measured], axis=1), axis=1),
                    initial=0.0)),
            )
        ]  # fmt: skip
        from msk.quality import swapped_sides

        for r, lft, dz in swapped_sides(model, self.kin, self.mtrial.markers, self.labels):
            quality["flags"].append(
                {"trial": self.task.name, "quantity": f"{r}/{lft}_swapped", "value": dz,
                 "threshold": 0.0,
                 "message": f"{r} is {-1000 * dz:.0f} mm left of {lft} in the pelvis frame: "
                 "their labels look swapped (a labelling error in the file, or the wrong "
                 "side in the config)"}
            )  # fmt: skip
        # what the reader noticed in the file (duplicate labels renamed, NaN plate samples…)
        for w in (self.trial.metadata or {}).get("warnings", ()):
            quality["flags"].append(
                {"trial": self.task.name, "quantity": "input_file", "value": 1.0,
                 "threshold": 0.0, "message": f"{self.task.file.name}: {w}"}
            )  # fmt: skip
        quality["thresholds"] = dict(THRESHOLDS)
        quality["held_coordinates"] = sorted(self.held)
        return {
            **self.base_summary(),
            "model": {**self.built["info"], "name": model.name, "muscles": len(model.muscles)},
            "frame": {"lab_to_model_rotation": self.rot, "lab_up": self.trial.up},
            "events": self.events,
            "event_sources": {
                **dict(self.gait_events.source),
                "notes": list(self.gait_events.notes),
            },
            "gait_cycle_s": list(self.cycle) if self.cycle else None,
            "angle_columns": [
                c for c in self.kin.coordinate_names if not c.endswith(("_tx", "_ty", "_tz"))
            ],
            "quality": quality,
            "methods": {
                "plate_assignment": PLATE_ASSIGNMENT,
                "scaling_measurements": [m[0] for m in DEFAULT_MEASUREMENTS],
                "task_trial": self.task.name,
            },
            "identification": None
            if ident is None
            else {k: ident[k] for k in ("segments", "condition_number", "n_frames", "advice")},
            "anthropometry": _anthropometry(cfg, model),
            "strength": None
            if strength is None
            else _strength_summary(
                strength, model=model, side=self.sfx, mass_kg=cfg.subject.mass_kg
            ),
            "comparison": self.comparison_,
            "optimization": None if sol is None else _optimization_summary(sol, self.sfx),
        }

    # ------------------------------------------------------------------ report figures
    def figures(self, summary: Mapping[str, Any]) -> dict[str, str] | None:
        from msk.report import build_figures

        tables = self.tables_

        def do() -> dict[str, str]:
            self.check("report")
            res = SessionResults(tables, summary, None, tuple(summary["angle_columns"]))
            return build_figures(res)

        key = _key(
            [
                (n, tb.columns, hashlib.sha256(np.ascontiguousarray(tb.data).tobytes()).hexdigest())
                for n, tb in tables.items()
            ],
            [
                summary.get(k)
                for k in (
                    "gait_cycle_s",
                    "subject",
                    "identification",
                    "strength",
                    "anthropometry",
                    "fes",
                )
            ],
        )
        return self.runner.run("report", do, settings=key)


def split_task_trials(cfg: SessionConfig) -> list[SessionConfig]:
    """One configuration per task trial, each keeping the session's other trials (static,
    mass identification, MVC, FES); a configuration with at most one task trial is returned
    as is."""
    tasks = cfg.trials_with_role("task")
    if len(tasks) <= 1:
        return [cfg]
    return [
        dataclasses.replace(cfg, trials=tuple(t for t in cfg.trials if t.role != "task" or t is k))
        for k in tasks
    ]


def run_task_trials(
    config: str | Path | SessionConfig,
    out_dir: str | Path,
    **options: Any,
) -> list[RunResult]:
    """:func:`run_session` for every task trial of the session: one task trial → ``out_dir``
    itself; several → ``out_dir/<trial name>/`` each (a complete results folder, whose report
    and tables are that trial's; ``msk compare`` reads them together). ``options`` as for
    :func:`run_session`. Every target folder is checked before anything is computed; a core
    stage failing on one trial raises after the trials before it were written."""
    cfg = config if isinstance(config, SessionConfig) else load_config(config)
    parts = split_task_trials(cfg)
    out = Path(out_dir).resolve()
    if len(parts) == 1:
        return [run_session(cfg, out, **options)]
    dirs = [out / t.name for t in cfg.trials_with_role("task")]
    for d in dirs:
        check_replaceable(d)
    return [run_session(c, d, **options) for c, d in zip(parts, dirs)]


def run_session(
    config: str | Path | SessionConfig,
    out_dir: str | Path,
    *,
    progress: TextIO | None = None,
    use_cache: bool = True,
    pdf: bool = False,
    _fail_stage: str | None = None,
) -> RunResult:
    """Run the whole chain for one session and write the results contract into ``out_dir``.

    ``progress`` gets one line per stage (status and seconds); ``use_cache=False`` recomputes
    every stage; ``pdf=True`` also prints ``report.pdf`` with headless Chromium (when installed).
    Raises :class:`MskError` when a core stage fails (nothing is written then).
    """
    t_start = _time.perf_counter()
    cfg = config if isinstance(config, SessionConfig) else load_config(config)
    tasks = cfg.trials_with_role("task")
    if len(tasks) > 1:
        names = ", ".join(t.name for t in tasks)
        raise ConfigError(
            f"{cfg.path}: {len(tasks)} task trials ({names}): run_session analyses one; "
            "run_task_trials (what `msk run` does) analyses each into its own folder"
        )
    out = Path(out_dir).resolve()
    check_replaceable(out)  # fail before computing, not after
    runner = _Runner(out / ".cache" if use_cache else None, progress)
    s = _Session(cfg, runner, _fail_stage)
    if s.gait:
        s.read()
        s.build_model()
        s.kinematics()
        s.loads()
        s.mass_identification()
        s.inverse_dynamics()
        s.emg()
        s.muscle_geometry()
        s.tension_optimization()
        s.strength_identification()
        s.knee_contact()
        tables = s.tables()
        s.comparison()
        summary = s.summary()
    else:
        for name in STAGES[: STAGES.index("fes")]:
            runner.skip(name, "no gait trial (role 'task') in the configuration")
        tables = {}
        summary = {**s.base_summary(), "angle_columns": [], "quality": {}}
    s.fes()
    tables.update(s.fes_tables())
    summary["fes"] = s.fes_summary()
    s.tables_ = tables
    figs = s.figures(summary)
    summary["stages"] = [dataclasses.asdict(r) for r in runner.records]
    summary["not_available"] = [
        {"stage": r.name, "status": r.status, "reason": r.message}
        for r in runner.records
        if r.status in ("not available", "failed")
    ]
    summary["run_seconds"] = _time.perf_counter() - t_start

    def report(res: SessionResults, folder: Path) -> None:
        from msk.report import write_report

        write_report(res, folder, figures=figs, pdf=pdf)

    angles = tuple(summary["angle_columns"])
    write_session(out, SessionResults(tables, summary, None, angles), report=report)
    if progress is not None:
        progress.write(f"wrote {out} in {_time.perf_counter() - t_start:.2f} s\n")
    return RunResult(out, summary, tuple(runner.records), _time.perf_counter() - t_start)


# ---------------------------------------------------------------------------------------------
# helpers (formatting only)
# ---------------------------------------------------------------------------------------------
def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2)))


def _contact_agreement(measured: np.ndarray, predicted: np.ndarray, bw: float) -> dict[str, Any]:
    """Agreement figures (msk.compare) of a predicted knee contact force with the measured."""
    from msk import compare

    a, b = measured, predicted
    return {
        "rms_n": float(compare.rms(a, b)),
        "rms_bw": float(compare.rms(a, b)) / bw,
        "nrmsd_pct": float(compare.nrmsd(a, b)),
        "pearson_r": float(compare.pearson_r(a, b)),
        "spearman_rho": float(compare.spearman(a, b)),
        "icc": float(compare.icc(a, b)),
        "peak_difference_n": float(compare.peak_difference(b, a)),
        "peak_measured_bw": float(a.max() / bw),
        "peak_predicted_bw": float(b.max() / bw),
        "n_frames": int(a.size),
    }


def _segment_summary(s: Any) -> dict[str, Any]:
    from msk.status import segment_status

    out = {
        "name": s.name,
        "mass_kg": s.mass,
        "mass_std_kg": s.mass_std,
        "prior_mass_kg": s.prior_mass,
        "com_m": s.com,
        "com_std_m": s.com_std,
        "prior_com_m": s.prior_com,
        "flag": s.flag,
    }
    # msk.status word: a segment that moved from its prior without becoming precise is
    # "not determined", never "prior" (issue 17)
    out["status"] = segment_status(out).value
    return out


def _inertial_table(ident: Mapping[str, Any]) -> Table:
    from msk.model import INERTIAL_PARAMETER_NAMES

    cols, vals = [], []
    for b, phi in ident["parameters"].items():
        cols += [f"{b}.{p}" for p in INERTIAL_PARAMETER_NAMES]
        vals += list(np.asarray(phi, dtype=float))
    return Table(np.array([ident["t0"]]), np.array([vals]), tuple(cols), "inertial_parameters")


def _strength_table(strength: Mapping[str, Any]) -> Table:
    """One row: per group factor, CI, F_iso and ``status_code`` (:data:`msk.status.STATUS_CODES`,
    listed in ``summary.json`` ``strength.status_codes``: the tables are numeric)."""
    from msk.status import STATUS_CODES

    p = strength["profile"]
    status = p.statuses()
    cols, vals = [], []
    for g, name in enumerate(p.group_names):
        for fig, arr in (
            ("factor", p.factors),
            ("ci_low", p.ci_low),
            ("ci_high", p.ci_high),
            ("f_iso_generic", p.f_iso_generic),
            ("f_iso", p.f_iso),
        ):
            cols.append(f"{name}.{fig}")
            vals.append(float(arr[g]))
        cols.append(f"{name}.status_code")
        vals.append(float(STATUS_CODES[status[g]]))
    return Table(np.array([strength["t0"]]), np.array([vals]), tuple(cols), "strength")


def _optimization_summary(sol: Mapping[str, Any], sfx: str) -> dict[str, Any]:
    from msk.status import gain_status

    return {
        "method": sol["method"],
        "criterion": sol.get("criterion"),
        "emg_gains": sol.get("emg_gains"),
        "emg_gain_status": None
        if not sol.get("emg_gains")
        else {c: gain_status(float(g)).value for c, g in sol["emg_gains"].items()},
        "infeasible_frames": sol.get("infeasible_frames"),
        "reserve_torque_rms_nm": None
        if "reserve_torques" not in sol
        else {
            c: float(np.sqrt(np.nanmean(sol["reserve_torques"][:, k] ** 2)))
            for k, c in enumerate(sol["reserve_coordinates"])
            if c.endswith(sfx)
        },
    }


def _slice_state(state: Any, mask: np.ndarray) -> Any:
    changes = {}
    for f in dataclasses.fields(state):
        v = getattr(state, f.name)
        if isinstance(v, np.ndarray) and v.ndim == 2:
            changes[f.name] = v[mask]
    return dataclasses.replace(state, **changes)


def _frames(obj: Any, idx: np.ndarray, n: int) -> Any:
    """A frozen result (Kinematics, ExternalLoads) restricted to the frames ``idx``: every
    array field whose first axis has the ``n`` frames is sliced."""
    changes = {}
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if isinstance(v, np.ndarray) and v.ndim >= 1 and v.shape[0] == n:
            changes[f.name] = v[idx]
    return dataclasses.replace(obj, **changes)


def _quality(
    trial: Any,
    kin: Any,
    jt: Any,
    loads: Any,
    emg: Any,
    sol: Any,
    strength: Any,
    ident: Any,
    body_weight: float,
    measured: np.ndarray,
) -> dict[str, Any]:
    """Data-quality figures; the residuals over the frames whose ground contact the plates
    measure (``measured``, :func:`msk.loads.contact_measured`), None when there is none."""
    ok = np.isfinite(jt.residual_force).all(axis=1) & measured
    res_f = _rms(jt.residual_force[ok]) if ok.any() else None
    gaps = [
        {"marker": lab, "missing_frames": int(n), "longest_gap_frames": int(g)}
        for lab, n, g in zip(trial.gaps.labels, trial.gaps.n_missing, trial.gaps.longest_gap)
        if n > 0
    ]
    q: dict[str, Any] = {
        "frames": int(kin.time.size),
        "rate_hz": float(trial.point_rate_hz),
        "marker_gaps": gaps,
        "ik_failed_frames": int(kin.failed_frames.size),
        "ik_marker_rms_mean_m": float(np.nanmean(kin.marker_rms)),
        "ik_marker_rms_max_m": float(np.nanmax(kin.marker_rms)),
        "ik_worst_marker": _mode(kin.marker_max_name),
        "contact_measured_frames": int(measured.sum()),
        "residual_force_rms_n": res_f,
        "residual_force_rms_pct_bw": None if res_f is None else 100 * res_f / body_weight,
        "residual_moment_rms_nm": _rms(jt.residual_moment[ok]) if ok.any() else None,
        "plate_assignments": [
            {k: getattr(a, k) for k in ("plate", "body", "start_time", "end_time") if hasattr(a, k)}
            for a in getattr(loads, "assignments", ())
        ],
    }
    if emg is not None:
        flat = [emg["sources"][k] for k in range(len(emg["muscles"])) if not emg["usable"][k]]
        q["emg_flat_channels"] = sorted(set(flat))
        q["emg_warnings"] = emg["warnings"]
        q["emg_normalisation"] = emg.get("normalisation")
    if sol is not None and "infeasible_frames" in sol:
        q["optimization_infeasible_frames"] = sol["infeasible_frames"]
    if strength is not None:
        q["strength_fit_r2"] = float(strength["profile"].r2)
    if ident is not None:
        q["identification_condition_number"] = ident["condition_number"]
    return q


def _mode(names: Sequence[str]) -> str:
    vals = [n for n in names if n]
    return max(set(vals), key=vals.count) if vals else ""


_ANTHRO_MAP = {
    "pelvis": ("pelvis",),
    "femur": ("thigh",),
    "tibia": ("shank",),
    "foot": ("foot",),
    "torso": ("head_neck", "thorax", "upper_arm", "forearm", "hand"),
}


def _anthropometry(cfg: SessionConfig, model: Any) -> dict[str, Any] | None:
    """Generic segment masses of the anthropometric table (Dumas 2007) mapped on the model's
    segments (the foot = talus + calcaneus + toes; the torso = trunk, head and arms)."""
    try:
        from msk.anthropometry import generic_segments

        # segment masses are fractions of body mass: the stature (default 1.75 m when the
        # config has none) only sets lengths and inertias, which are not reported
        # load_config accepts only "male" | "female" (SubjectConfig.sex is typed str)
        sex = cast(Literal["male", "female"], cfg.subject.sex)
        segs = generic_segments(cfg.subject.mass_kg, cfg.subject.height_m or 1.75, sex=sex)
    except (ImportError, MskError):
        return None
    out = {}
    for body in (b.name for b in model.bodies):
        base, _, sd = body.rpartition("_") if body.endswith(("_l", "_r")) else (body, "", "")
        key = "foot" if base in ("talus", "calcn", "toes") else base
        if key not in _ANTHRO_MAP:
            continue
        total = 0.0
        for s in _ANTHRO_MAP[key]:
            for name, seg in segs.items():
                stem = name[:-2] if name.endswith(("_l", "_r")) else name
                side_ok = not sd or not name.endswith(("_l", "_r")) or name.endswith("_" + sd)
                if stem == s and side_ok:
                    total += seg.mass
        label = f"{key}_{sd}" if sd else key
        out[label] = {"mass_kg": total, "table": "Dumas et al. 2007"}
    return {"segments": out, "table": "Dumas et al. 2007", "sex": cfg.subject.sex}


def _strength_summary(
    strength: Mapping[str, Any],
    *,
    model: Any = None,
    side: str = "_r",
    mass_kg: float | None = None,
) -> dict[str, Any]:
    """``identified`` = status "identified" (:mod:`msk.status`); ``gated`` = the group passed
    the correlation gate (what ``identified`` meant before issue 17). With the (generic, scaled)
    ``model``: ``joint_strength``, the maximal isometric moment curves of the generic and the
    identified model (:func:`msk.strength.joint_strength_summary`), N·m and N·m/kg."""
    from msk.status import STATUS_CODES, STATUS_MEANING, STRENGTH_R2_MIN

    p = strength["profile"]
    status = p.statuses()
    joint: dict[str, Any] | None = None
    if model is not None and model.muscles:
        from msk.strength import joint_strength_summary

        try:
            joint = joint_strength_summary(model, p, side=side, mass_kg=mass_kg)
        except Exception as exc:  # the curves must not cost the run its strength summary
            joint = {"error": f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}"}
    return {
        "groups": [
            {
                "group": n,
                "muscles": strength["groups"].get(n, []),
                "factor": float(p.factors[g]),
                "ci_low": float(p.ci_low[g]),
                "ci_high": float(p.ci_high[g]),
                "ci_cov_low": float(p.ci_cov_low[g]),
                "ci_cov_high": float(p.ci_cov_high[g]),
                "f_iso_generic_n": float(p.f_iso_generic[g]),
                "f_iso_n": float(p.f_iso[g]),
                "status": status[g],
                "identified": status[g] == "identified",
                "gated": bool(p.identified[g]),
            }
            for g, n in enumerate(p.group_names)
        ],
        "r2": float(p.r2),
        "r2_min": STRENGTH_R2_MIN,
        "status_codes": dict(STATUS_CODES),
        "status_meaning": dict(STATUS_MEANING),
        "confidence": float(p.confidence),
        "bounds": list(p.bounds),
        "method": p.method,
        "joint_strength": joint,
    }


# ---------------------------------------------------------------------------------------------
# CLI verbs: msk run, msk print-config, msk report
# ---------------------------------------------------------------------------------------------
#: Units of the identified FES parameters (``fes_parameters.csv`` columns, SI).
FES_PARAMETER_UNITS: dict[str, str] = {
    "geometry.L_ext": "m",
    "geometry.r_q": "m",
    "knee.J": "kg·m²",
    "knee.B": "N·m·s/rad",
    "knee.K": "N·m/rad",
    "muscle.F_cm": "N",
    "muscle.K_cm": "N/m",
    "muscle.L_c0": "m",
    "muscle.b": "1",
    "muscle.k_s": "N/m",
    "muscle.L_s": "m",
    "recruitment.c1": "1",
    "recruitment.c2": "1",
    "recruitment.c3": "1 (PW/PW_max)",
}
#: Protocol steps of ``fes_steps.csv`` (seeds/000 Table 2 rows) and the figures per step.
FES_STEP_FIGURES = ("nrmsd_pct", "nrmse_pct")


def _fes_recording(tc: Any) -> Any:
    """One FES trial file as a :class:`msk.fes.io.FesRecording` (SI)."""
    from msk.fes.io import read_fes_csv, recording_from_trial

    f = tc.fes
    chans = {
        "angle": f.angle_channel,
        "torque": f.torque_channel,
        "stimulation": f.stimulation_channel,
        "angle_unit": f.angle_unit,
        "stim_unit": f.stimulation_unit,
    }
    if tc.file.suffix.lower() == ".c3d":
        from msk.io import read_c3d

        trial = read_c3d(tc.file)
        have = set(trial.analog_labels)
        for k in ("angle", "torque", "stimulation"):
            if chans[k] not in have:
                chans[k] = None
        return recording_from_trial(trial, **chans)
    return read_fes_csv(tc.file, time=f.time_column, **chans)


def _fes_session(cfg: SessionConfig, trials: Sequence[Any]) -> Any:
    """The :class:`msk.fes.protocol.FesSession` of the ``role = "fes"`` trials."""
    from msk.fes.protocol import FesSession, StaticTrial

    opt = cfg.fes
    rest = np.deg2rad(opt.theta_rest_deg)
    by_step: dict[str, list[tuple[Any, Any]]] = {}
    for tc in trials:
        rec = _fes_recording(tc)
        if rec.stim_kind != "pw" and tc.fes.step not in ("static", "pendulum"):
            raise ConfigError(
                f"{cfg.path}: trial {tc.name!r}: stimulation_unit = {tc.fes.stimulation_unit!r} "
                "(current modulation): the seeds/000 protocol of msk run identifies "
                "pulse-width modulated sessions only"
            )
        by_step.setdefault(tc.fes.step, []).append((tc, rec))

    def iso(tc: Any, rec: Any) -> Any:
        if tc.fes.knee_angle_deg is not None:
            angle = float(np.deg2rad(tc.fes.knee_angle_deg))
        elif rec.knee_angle is not None:
            angle = float(np.median(rec.knee_angle))
        else:
            raise MissingDataError(
                f"{tc.file}: no angle channel {tc.fes.angle_channel!r} and no knee_angle_deg "
                f"for isometric trial {tc.name!r}"
            )
        return rec.isometric_trial(knee_angle=angle, frequency_hz=opt.frequency_hz)

    ((_, st),) = by_step["static"]
    if st.torque is None:
        tc0 = by_step["static"][0][0]
        raise MissingDataError(
            f"{tc0.file}: no torque channel {tc0.fes.torque_channel!r} in the static trial"
        )
    static = StaticTrial(st.theta_r(rest), st.torque)
    ((_, pd),) = by_step["pendulum"]
    ((_, dy),) = by_step["dynamic"]
    ((_, va),) = by_step["validation"]
    return FesSession(
        cfg.subject.name,
        float(cfg.subject.height_m),  # type: ignore[arg-type]
        cfg.subject.mass_kg,
        static,
        pd.pendulum_trial(theta_rest=rest),
        tuple(iso(tc, r) for tc, r in by_step["isometric"]),
        tuple(iso(tc, r) for tc, r in by_step["recruitment"]),
        dy.dynamic_trial(frequency_hz=opt.frequency_hz, theta_rest=rest),
        va.dynamic_trial(frequency_hz=opt.frequency_hz, theta_rest=rest),
        opt.frequency_hz,
    )


def _fes_parameters(res: Any) -> dict[str, float]:
    subj = res.subject
    return {
        name: float(getattr(getattr(subj, name.split(".")[0]), name.split(".")[1]))
        for name in FES_PARAMETER_UNITS
    }


def _fes_steps(res: Any) -> dict[str, dict[str, float]]:
    steps = {
        "static_torque": res.static,
        "joint_mechanics": res.pendulum,
        "force_length": res.force_length,
        "recruitment": res.recruitment,
        "nlp_ks": res.series_stiffness,
        "cross_validation_initial": res.cross_validation_initial,
        "cross_validation": res.cross_validation,
    }
    return {k: {"nrmsd_pct": float(v.nrmsd), "nrmse_pct": float(v.nrmse)} for k, v in steps.items()}


def _fes_tables(res: Any) -> dict[str, Table]:
    """``fes_parameters`` and ``fes_steps`` (one row, ``time`` = 0: the start of the data they
    were identified from) and ``fes_validation`` (a time series: measured and simulated knee
    angle of the cross-validation trial, rad)."""
    par = _fes_parameters(res)
    steps = _fes_steps(res)
    cols = tuple(f"{k}.{f}" for k in steps for f in FES_STEP_FIGURES)
    vals = [steps[k][f] for k in steps for f in FES_STEP_FIGURES]
    cv, cv0 = res.cross_validation, res.cross_validation_initial
    rest = res.subject.knee.theta_rest
    t0 = np.zeros(1)
    return {
        "fes_parameters": Table(t0, np.array([list(par.values())]), tuple(par), "fes_parameters"),
        "fes_steps": Table(t0, np.array([vals]), cols, "fes_steps"),
        "fes_validation": Table(
            np.asarray(cv.time, dtype=float),
            np.column_stack([rest - cv.theta_r, rest - cv.theta_r_sim, rest - cv0.theta_r_sim]),
            ("knee_angle_measured", "knee_angle_simulated", "knee_angle_simulated_k_s0"),
            "fes_validation",
        ),
    }


def _fes_summary(res: Any, cfg: SessionConfig, trials: Sequence[Any]) -> dict[str, Any]:
    par = _fes_parameters(res)
    return {
        "parameters": {k: {"value": v, "unit": FES_PARAMETER_UNITS[k]} for k, v in par.items()},
        "initial_parameters": {
            k: float(getattr(getattr(res.subject_initial, k.split(".")[0]), k.split(".")[1]))
            for k in FES_PARAMETER_UNITS
        },
        "steps": _fes_steps(res),
        "k_s_history_n_per_m": list(res.k_s_history),
        "solver_status": res.series_stiffness.solver_status,
        "seconds": dict(res.seconds),
        "trials": [{"name": tc.name, "step": tc.fes.step, "file": str(tc.file)} for tc in trials],
        "options": dataclasses.asdict(cfg.fes),
    }


def _cli() -> None:
    import argparse

    from msk.cli import command

    def run_args(p: argparse.ArgumentParser) -> None:
        p.add_argument("config", metavar="CONFIG", type=Path, help="session configuration (.toml)")
        p.add_argument("--out", required=True, type=Path, metavar="DIR", help="session folder")
        p.add_argument("--no-cache", action="store_true", help="recompute every stage")
        p.add_argument("--pdf", action="store_true", help="also print report.pdf (Chromium)")
        p.add_argument("--quiet", action="store_true", help="no progress lines")
        p.add_argument(
            "--strict", action="store_true", help="exit 3 when any quality gate is raised"
        )

    @command("run", help="run a session pipeline (C3D → results folder)", arguments=run_args)
    def _run(args: argparse.Namespace) -> int:
        raised = 0
        for res in run_task_trials(
            args.config,
            args.out,
            progress=None if args.quiet else sys.stderr,
            use_cache=not args.no_cache,
            pdf=args.pdf,
        ):
            missing = res.not_available
            if missing and not args.quiet:
                sys.stderr.write(f"{res.out_dir}: stages not available: {', '.join(missing)}\n")
            flags = (res.summary.get("quality") or {}).get("flags") or []
            raised += len(flags)
            for f in flags:
                sys.stderr.write(f"{res.out_dir}: quality flag: {f['message']}\n")
        return 3 if args.strict and raised else 0

    def pc_args(p: argparse.ArgumentParser) -> None:
        p.add_argument("--out", type=Path, metavar="FILE", help="write to FILE (default stdout)")

    @command("print-config", help="print the commented session-config template", arguments=pc_args)
    def _print_config(args: argparse.Namespace) -> int:
        from msk.config import TEMPLATE

        if args.out is None:
            sys.stdout.write(TEMPLATE)
        else:
            args.out.parent.mkdir(parents=True, exist_ok=True)
            args.out.write_text(TEMPLATE, encoding="utf-8")
        return 0

    def rep_args(p: argparse.ArgumentParser) -> None:
        p.add_argument("folder", metavar="DIR", type=Path, help="a session folder of msk run")
        p.add_argument("--pdf", action="store_true", help="also print report.pdf (Chromium)")

    @command("report", help="rebuild report.html of a session folder", arguments=rep_args)
    def _report(args: argparse.Namespace) -> int:
        from msk.report import write_report
        from msk.results import read_session

        path = write_report(read_session(args.folder), args.folder, pdf=args.pdf)
        sys.stdout.write(f"{path}\n")
        return 0


_cli()
