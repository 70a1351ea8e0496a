"""The lab pipeline: one session configuration → the results contract (:mod:`msk.results`).

Composition only: every number comes from an msk library call; this module chains them, caches
them and records what happened. Stages (DESIGN.md "Architecture")::

    read → model (load, scale, place markers) → kinematics → loads → mass_identification
      → inverse_dynamics → emg → muscle_geometry → tension_optimization
      → strength_identification → knee_contact → comparison → report

**Stage status.** ``computed`` / ``cached`` / ``not available`` (the library piece is missing
or a prerequisite is: recorded with the reason, never replaced by made-up numbers) / ``failed``
(an analysis stage raised: recorded with its message — and the code location for an internal
error — and the run goes on). The core stages (read, model, kinematics, loads, inverse
dynamics, report) have no fallback: their errors end the run, and nothing is written.

**Cache.** A stage's key is the sha256 of its name, the msk version, its settings and the keys
of the stages it reads (input files enter through their content hash), so a changed setting
recomputes exactly the stages downstream of it. Values are pickled in ``<out>/.cache``.

**Frames.** The lab frame of a C3D trial is rotated into the model frame (lab vertical → the
model's up, −gravity) and about the vertical so that the walking direction is the model's +x
(OpenSim's convention); the rotation is recorded in ``summary.json``.

**Marker placement.** Lab markers that are not model markers (clusters, PSIS…) are placed on
the scaled model from the static trial: the static pose is solved with the markers both share
(``[markers] rename`` maps model names to lab labels) and every other static marker is fixed to
the body whose bone segment is nearest, at its measured position (OpenSim's MarkerPlacer idea).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import pickle
import platform
import sys
import tempfile
import time as _time
import traceback
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from importlib import metadata as _md
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from msk import __version__
from msk.config import SessionConfig, load_config
from msk.exceptions import ConfigError, MissingDataError, MskError
from msk.io.opensim_files import Table
from msk.results import SessionResults, check_replaceable, json_default, write_session

__all__ = [
    "CONTACT_CHUNK_FRAMES",
    "CORE_STAGES",
    "DEFAULT_MEASUREMENTS",
    "STAGES",
    "RunResult",
    "StageRecord",
    "file_sha256",
    "lab_to_model_rotation",
    "place_markers",
    "run_session",
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
    "report",
)
#: Stages without which there are no results: their errors end the run.
CORE_STAGES: frozenset[str] = frozenset(
    {"read", "model", "kinematics", "loads", "inverse_dynamics", "report"}
)
_DEPENDENCIES = (
    "numpy",
    "scipy",
    "pin",
    "casadi",
    "ezc3d",
    "matplotlib",
    "daqp",
    "osqp",
    "clarabel",
    "qpsolvers",
)
G0 = 9.80665
#: Frames per joint-reaction call in the knee-contact stage (moving path points per chunk).
CONTACT_CHUNK_FRAMES = 6

#: Scaling measurements (model marker pairs → bodies), used where both markers exist in the
#: model and (after ``[markers] rename``) in the static trial.
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
    """What happened to one stage: ``status`` computed | cached | not available | failed."""

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
    out = {"msk": __version__, "python": platform.python_version()}
    for name in _DEPENDENCIES:
        try:
            out[name] = _md.version(name)
        except _md.PackageNotFoundError:
            out[name] = "not installed"
    return out


# ---------------------------------------------------------------------------------------------
# stage runner with content-hash cache
# ---------------------------------------------------------------------------------------------
class _Runner:
    def __init__(self, cache_dir: Path | None, progress: TextIO | None) -> None:
        self.cache_dir = cache_dir
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
        key = _key(name, __version__, settings, [self.keys[n] for n in needs])
        path = self.cache_dir / f"{name}-{key[:24]}.pkl" if self.cache_dir and cache else None
        if path is not None and path.is_file():
            try:
                with open(path, "rb") as fh:
                    value = pickle.load(fh)
            except Exception:  # a corrupt cache entry is recomputed
                value = None
            else:
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
            if name in CORE_STAGES:
                raise
            msg = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
            rec = StageRecord(name, "failed", _time.perf_counter() - t0, msg, key)
            self.records.append(rec)
            self._say(rec)
            return None
        except (AttributeError, TypeError, NotImplementedError) as exc:
            # an analysis module still being written (its API differs from what this pipeline
            # calls): recorded, visibly, as not available rather than ending the session
            if name in CORE_STAGES:
                raise
            msg = f"library API mismatch: {type(exc).__name__}: {' '.join(str(exc).split())}"
            rec = StageRecord(name, "not available", _time.perf_counter() - t0, msg, key)
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
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
            try:
                with os.fdopen(fd, "wb") as fh:
                    pickle.dump(value, fh, protocol=pickle.HIGHEST_PROTOCOL)
                os.replace(tmp, path)
            except BaseException:
                Path(tmp).unlink(missing_ok=True)
                raise
        self.keys[name] = key
        rec = StageRecord(name, "computed", _time.perf_counter() - t0, "", key)
        self.records.append(rec)
        self._say(rec)
        return value


def _need(module: str, *names: str) -> Any:
    """Import ``module`` and return its attributes; StageUnavailable if it is not there yet."""
    import importlib

    try:
        mod = importlib.import_module(module)
    except ImportError as exc:
        raise StageUnavailable(f"{module} not available ({exc})") from None
    if not names:
        return mod
    out = []
    for n in names:
        if not hasattr(mod, n):
            raise StageUnavailable(f"{module}.{n} not available")
        out.append(getattr(mod, n))
    return out[0] if len(out) == 1 else tuple(out)


# ---------------------------------------------------------------------------------------------
# glue: frames and marker placement
# ---------------------------------------------------------------------------------------------
def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotation taking unit vector ``a`` to unit vector ``b`` (Rodrigues)."""
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    v = np.cross(a, b)
    c = float(a @ b)
    if c < -1 + 1e-12:  # opposite: half turn about any axis normal to a
        n = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(n) < 1e-6:
            n = np.cross(a, [0.0, 1.0, 0.0])
        n /= np.linalg.norm(n)
        return 2 * np.outer(n, n) - np.eye(3)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1 + c)


def lab_to_model_rotation(
    up_lab: np.ndarray, up_model: np.ndarray, markers: np.ndarray | None = None
) -> np.ndarray:
    """Rotation R (x_model = R x_lab): lab up → model up, then about the vertical so that the
    horizontal progression of the marker centroid (when > 0.3 m) points along model +x."""
    r = _rotation_between(np.asarray(up_lab, float), np.asarray(up_model, float))
    if markers is None or markers.size == 0:
        return r
    with np.errstate(all="ignore"):
        c = np.nanmean(markers @ r.T, axis=1)
    ok = np.isfinite(c).all(axis=1)
    if ok.sum() < 2:
        return r
    d = c[ok][-1] - c[ok][0]
    u = np.asarray(up_model, float) / np.linalg.norm(up_model)
    d = d - (d @ u) * u
    if np.linalg.norm(d) < 0.3:
        return r
    x = np.array([1.0, 0.0, 0.0])
    x = x - (x @ u) * u
    d, x = d / np.linalg.norm(d), x / np.linalg.norm(x)
    phi = math.atan2(float(u @ np.cross(d, x)), float(d @ x))  # about the vertical u
    k = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    heading = np.eye(3) + math.sin(phi) * k + (1 - math.cos(phi)) * k @ k
    return heading @ r


def _rotate_plate(p: Any, r: np.ndarray) -> Any:
    """A plate in the model frame. Its outline is dropped: msk.loads then assigns each contact
    to the foot nearest the COP (the outline test projects a swinging foot onto the plate too,
    which fails on overground gait where the other foot swings over the plate)."""
    return dataclasses.replace(
        p, force=p.force @ r.T, cop=p.cop @ r.T, free_moment=p.free_moment @ r.T, corners=None
    )


def _segments(model: Any, data: Any) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """Bone segments per body: origin → each child body origin (leaf: origin → 2 × COM)."""
    out = []
    for b in model.bodies:
        o = data.oMf[model.body_frame[b.name]]
        kids = [j.child for j in model.joints if j.parent == b.name]
        ends = [data.oMf[model.body_frame[c]].translation for c in kids]
        if not ends:
            ends = [o.act(2.0 * np.asarray(b.com, dtype=float))]
        out.extend((b.name, o.translation.copy(), e.copy()) for e in ends)
    return out


def _point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    d = b - a
    t = float(np.clip((p - a) @ d / max(float(d @ d), 1e-12), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * d)))


def place_markers(
    model: Any, static_markers: np.ndarray, labels: Sequence[str], time: np.ndarray
) -> tuple[Any, dict[str, Any]]:
    """Add the static trial's non-model markers to ``model`` (see the module docstring);
    ``labels`` are already in model names where a model marker matches."""
    from msk.kinematics import solve_kinematics
    from msk.model import Marker, forward_kinematics

    n = static_markers.shape[0]
    frames = np.unique(np.linspace(0, n - 1, min(n, 9)).round().astype(int))
    kin = solve_kinematics(
        model, static_markers[frames], labels, time[frames], cutoff_hz=None, min_markers=3
    )
    ok = np.isfinite(kin.q).all(axis=1)
    if not ok.any():
        raise MissingDataError("static trial: no frame could be solved for marker placement")
    theta = np.median(kin.q[ok], axis=0)
    data = model.create_data()
    forward_kinematics(model, data, theta)
    segs = _segments(model, data)
    with np.errstate(all="ignore"):
        mean = np.nanmean(static_markers, axis=0)
    known = set(model.marker_names)
    added = []
    placed: dict[str, str] = {}
    for i, lab in enumerate(labels):
        if lab in known or not np.isfinite(mean[i]).all():
            continue
        body = min(segs, key=lambda s, p=mean[i]: _point_segment_distance(p, s[1], s[2]))[0]
        local = data.oMf[model.body_frame[body]].actInv(mean[i])
        added.append(Marker(lab, body, np.asarray(local, dtype=float)))
        placed[lab] = body
    info = {
        "static_marker_rms_m": float(np.nanmean(kin.marker_rms[ok])),
        "placed": placed,
    }
    return model.with_markers([*model.markers, *added]), info


# ---------------------------------------------------------------------------------------------
# the run
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
        "markers": {"rename": dict(cfg.marker_rename), "weights": dict(cfg.marker_weights)},
        "emg": plain(cfg.emg),
        "filters": plain(cfg.filters),
        "optimization": plain(cfg.optimization),
    }


def _read_markers(path: Path) -> tuple[np.ndarray, tuple[str, ...], np.ndarray, Any]:
    """Markers of a static trial (.trc in the model frame, or .c3d)."""
    if path.suffix.lower() == ".trc":
        from msk.io.opensim_files import read_trc

        t = read_trc(path)
        return t.markers, t.labels, t.time, None
    from msk.io.c3d import read_c3d

    tr = read_c3d(path)
    return tr.markers, tr.marker_labels, tr.time, tr


def _model_source(cfg: SessionConfig) -> Path:
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


def _load_model(path: Path) -> Any:
    if path.suffix.lower() == ".osim":
        from msk.osim import load_osim

        return load_osim(path)
    from msk.model_files import load_model

    return load_model(path)


def _kinematics_and_loads(
    cfg: SessionConfig, model: Any, trial: Any, labels: Sequence[str]
) -> tuple[Any, Any]:
    """IK and plate loads of one C3D trial in the model frame (same settings as the task)."""
    from msk.kinematics import solve_kinematics
    from msk.loads import external_loads, plates_from_trial

    rot = lab_to_model_rotation(trial.up, -np.asarray(model.gravity, dtype=float), trial.markers)
    kin = solve_kinematics(
        model,
        trial.markers @ rot.T,
        labels,
        trial.time,
        weights=dict(cfg.marker_weights) or None,
        cutoff_hz=cfg.filters.kinematics_cutoff_hz,
    )
    plates = tuple(_rotate_plate(p, rot) for p in plates_from_trial(trial))
    return kin, external_loads(model, kin, plates, cutoff_hz=cfg.filters.grf_cutoff_hz)


def _gait_cycle(events: Sequence[Mapping[str, Any]], side: str) -> tuple[float, float] | None:
    ctx = side.capitalize()
    strikes = sorted(
        e["time"] for e in events if e["label"] == "Foot Strike" and e["context"] == ctx
    )
    return (strikes[0], strikes[1]) if len(strikes) >= 2 else None


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
    out = Path(out_dir).resolve()
    check_replaceable(out)  # fail before computing, not after
    runner = _Runner(out / ".cache" if use_cache else None, progress)
    side = cfg.subject.side
    sfx = "_l" if side == "left" else "_r"
    tasks = cfg.trials_with_role("task")
    if not tasks:
        raise ConfigError(f"{cfg.path}: no trial with role 'task'")
    task = tasks[0]
    statics = cfg.trials_with_role("static")
    static = statics[0] if statics else None
    idtrials = cfg.trials_with_role("mass_identification")

    def check(name: str) -> None:
        if _fail_stage == name:
            raise RuntimeError(f"stage {name} failed on purpose (test hook)")

    # ------------------------------------------------------------------ read
    files = {"task": task.file}
    if static is not None:
        files["static"] = static.file
    if task.contact_force is not None:
        files["contact_force"] = task.contact_force
    for tc in (*idtrials, *cfg.trials_with_role("mvc")):
        files[f"{tc.role}:{tc.name}"] = tc.file
    model_src = _model_source(cfg)
    files["model"] = model_src
    hashes = {k: file_sha256(p) for k, p in files.items()}

    def do_read() -> dict[str, Any]:
        check("read")
        from msk.io.c3d import read_c3d

        tr = read_c3d(task.file)
        out = {"trial": tr}
        if task.contact_force is not None:
            out["contact"] = _read_contact_csv(task.contact_force)
        return out

    raw = runner.run("read", do_read, settings={"files": hashes}, cache=True)
    trial = raw["trial"]

    # ------------------------------------------------------------------ model
    def do_model() -> dict[str, Any]:
        check("model")
        model = _load_model(model_src)
        info: dict[str, Any] = {"source": str(model_src), "generic_mass_kg": model.total_mass}
        rename = dict(cfg.marker_rename)  # model name -> lab label
        inv = {v: k for k, v in rename.items()}
        if static is not None:
            sm, slabels, stime, st_trial = _read_markers(static.file)
            if st_trial is not None:  # a C3D static trial: lab vertical → model up
                r_st = _rotation_between(st_trial.up, -np.asarray(model.gravity, dtype=float))
                sm = sm @ r_st.T
            slabels = tuple(inv.get(lab, lab) for lab in slabels)
        if cfg.model.scale:
            from msk.scaling import Measurement, scale_model

            meas = []
            if static is not None:
                have = set(slabels) & set(model.marker_names)
                meas = [
                    Measurement(n, pairs, bodies)
                    for n, pairs, bodies in DEFAULT_MEASUREMENTS
                    if all(a in have and b in have for a, b in pairs)
                ]
            model = scale_model(
                model,
                {lab: sm[:, i] for i, lab in enumerate(slabels)} if static is not None else None,
                measurements=meas,
                body_mass=cfg.subject.mass_kg,
            )
            info["scale_ratios"] = dict(model.metadata.get("scale_ratios", {}))
        if static is not None:
            model, placed = place_markers(model, sm, slabels, stime)
            info["marker_placement"] = placed
        info["mass_kg"] = model.total_mass
        return {"model": model, "info": info}

    built = runner.run(
        "model",
        do_model,
        needs=("read",),
        settings={
            "model": hashes["model"],
            "static": hashes.get("static"),
            "scale": cfg.model.scale,
            "knee": cfg.model.knee,
            "mass": cfg.subject.mass_kg,
            "rename": dict(cfg.marker_rename),
        },
    )
    model = built["model"]
    up_model = -np.asarray(model.gravity, dtype=float)
    rot = lab_to_model_rotation(trial.up, up_model, trial.markers)
    inv = {v: k for k, v in cfg.marker_rename.items()}

    def labels_of(tr: Any) -> tuple[str, ...]:
        return tuple(inv.get(lab, lab) for lab in tr.marker_labels)

    labels = labels_of(trial)

    # ------------------------------------------------------------------ kinematics
    def do_kin() -> Any:
        check("kinematics")
        from msk.kinematics import solve_kinematics

        return solve_kinematics(
            model,
            trial.markers @ rot.T,
            labels,
            trial.time,
            weights=dict(cfg.marker_weights) or None,
            cutoff_hz=cfg.filters.kinematics_cutoff_hz,
        )

    kin = runner.run(
        "kinematics",
        do_kin,
        needs=("read", "model"),
        settings={"weights": dict(cfg.marker_weights), "cut": cfg.filters.kinematics_cutoff_hz},
    )

    # ------------------------------------------------------------------ loads
    def do_loads() -> Any:
        check("loads")
        from msk.loads import external_loads, plates_from_trial

        plates = tuple(_rotate_plate(p, rot) for p in plates_from_trial(trial))
        return external_loads(model, kin, plates, cutoff_hz=cfg.filters.grf_cutoff_hz)

    loads = runner.run(
        "loads", do_loads, needs=("kinematics",), settings={"cut": cfg.filters.grf_cutoff_hz}
    )
    ok_frames = np.isfinite(kin.q).all(axis=1) & np.isfinite(kin.a).all(axis=1)

    # ------------------------------------------------------------------ mass identification
    def do_ident() -> dict[str, Any]:
        check("mass_identification")
        ident_cls, trial_cls = _need(
            "msk.identification", "InertialIdentifier", "IdentificationTrial"
        )
        runs = [(task.name, kin, loads)]
        for tc in idtrials:  # dedicated exciting motions (seeds/002 §VI), plus the task trial
            from msk.io.c3d import read_c3d

            tr_i = read_c3d(tc.file)
            k_i, l_i = _kinematics_and_loads(cfg, model, tr_i, labels_of(tr_i))
            runs.append((tc.name, k_i, l_i))
        its = []
        for nm, k_i, l_i in runs:
            it = trial_cls.from_loads(model, k_i, l_i, name=nm)
            good = np.isfinite(it.tau_ext).all(axis=1) & np.isfinite(it.theta_ddot).all(axis=1)
            its.append(
                trial_cls(
                    it.theta[good], it.theta_dot[good], it.theta_ddot[good], it.tau_ext[good], nm
                )
            )
        est = ident_cls(model, total_mass=cfg.subject.mass_kg, symmetric=True).fit(its)
        good = np.isfinite(kin.q).all(axis=1)
        segs = [
            {
                "name": s.name,
                "mass_kg": s.mass,
                "mass_std_kg": s.mass_std,
                "prior_mass_kg": s.prior_mass,
                "com_m": s.com,
                "com_std_m": s.com_std,
                "prior_com_m": s.prior_com,
                "flag": s.flag,
            }
            for s in est.segments_
        ]
        return {
            "parameters": {k: np.asarray(v) for k, v in est.parameters_.items()},
            "segments": segs,
            "condition_number": float(est.condition_number_),
            "n_frames": int(est.n_frames_),
            "advice": list(est.advice()),
            "t0": float(kin.time[good][0]),
        }

    ident = runner.run(
        "mass_identification",
        do_ident,
        needs=("loads",),
        settings={"trials": [file_sha256(t.file) for t in idtrials], "mass": cfg.subject.mass_kg},
    )
    model_id = model.with_inertias(ident["parameters"]) if ident else model

    # ------------------------------------------------------------------ inverse dynamics
    def do_id() -> dict[str, Any]:
        check("inverse_dynamics")
        from msk.dynamics import inverse_dynamics

        out = {"generic": inverse_dynamics(model, kin, loads)}
        if ident is not None:
            out["identified"] = inverse_dynamics(model_id, kin, loads)
        return out

    tau = runner.run(
        "inverse_dynamics",
        do_id,
        needs=("loads",) + (("mass_identification",) if ident else ()),
    )
    jt = tau.get("identified", tau["generic"])

    # ------------------------------------------------------------------ EMG
    def do_emg() -> dict[str, Any]:
        check("emg")
        if not cfg.emg.channels:
            raise StageUnavailable("no [emg] channels in the configuration")
        envelopes_from_trial = _need("msk.muscles.emg", "envelopes_from_trial")
        first_order_activation = _need("msk.muscles.activation", "first_order_activation")
        muscles = (
            set(model.muscle_names)
            if hasattr(model, "muscle_names")
            else {m.name for m in model.muscles}
        )
        unknown = sorted(set(cfg.emg.channels) - muscles)
        if unknown:
            raise ConfigError(f"{cfg.path}: emg.channels: model has no muscle {unknown[0]!r}")
        mvc = []
        for tc in cfg.trials_with_role("mvc"):
            from msk.io.c3d import read_c3d

            tr_m = read_c3d(tc.file)
            mvc.append((tr_m.analogs, tr_m.analog_rate_hz, tr_m.analog_labels))
        env = envelopes_from_trial(
            trial,
            muscles=dict(cfg.emg.channels),
            highpass_hz=cfg.emg.highpass_hz,
            lowpass_hz=cfg.emg.lowpass_hz,
            delay_s=cfg.emg.electromechanical_delay_s,
            **({"mvc_trials": mvc} if mvc else {}),
        )
        env_k = env.resampled(kin.time)
        e = np.clip(np.nan_to_num(env_k.envelopes, nan=0.0), 0.0, 1.0)
        act = first_order_activation(e, rate_hz=trial.point_rate_hz)
        act[:, ~env_k.usable] = np.nan
        return {
            "muscles": env_k.muscle_names,
            "sources": env_k.muscle_sources,
            "envelopes": env_k.envelopes,
            "activation": act,
            "usable": env_k.usable,
            "warnings": list(env.warnings),
            "quality": _plain_quality(env.quality),
        }

    emg = runner.run(
        "emg",
        do_emg,
        needs=("read", "kinematics"),
        settings={
            "channels": dict(cfg.emg.channels),
            "hp": cfg.emg.highpass_hz,
            "lp": cfg.emg.lowpass_hz,
            "emd": cfg.emg.electromechanical_delay_s,
            "mvc": [file_sha256(t.file) for t in cfg.trials_with_role("mvc")],
        },
    )

    # ------------------------------------------------------------------ geometry
    def do_geom() -> Any:
        check("muscle_geometry")
        if not model.muscles:
            raise StageUnavailable(f"model {model.name} has no muscles")
        muscle_geometry = _need("msk.muscles.geometry", "muscle_geometry")
        q = np.where(ok_frames[:, None], kin.q, model.default_coordinates()[None, :])
        v = np.where(ok_frames[:, None], kin.v, 0.0)
        return muscle_geometry(model, q, v)

    geom = runner.run("muscle_geometry", do_geom, needs=("kinematics",))
    root = tuple(jt.root_coordinates)
    act_idx = [i for i, c in enumerate(jt.coordinate_names) if c not in root]

    def muscle_state(mdl: Any) -> tuple[Any, Any]:
        from msk.muscles.geometry import muscle_parameters
        from msk.muscles.hill import rigid_tendon_state

        params = muscle_parameters(mdl)
        return params, rigid_tendon_state(params, geom.lengths, geom.velocities)

    def optimise(mdl: Any, torques: Any) -> dict[str, Any]:
        o = _need("msk.optimization")
        params, state = muscle_state(mdl)
        jac = geom.jacobian[ok_frames][:, :, act_idx]
        tq = torques.tau[ok_frames][:, act_idx]
        cn = tuple(jt.coordinate_names[i] for i in act_idx)
        reserves = np.ones(len(act_idx))
        meth = cfg.optimization.method
        fa = state.max_active_force_along_tendon[ok_frames]
        fp = state.passive_force_along_tendon[ok_frames]
        common = {"muscle_names": params.names, "coordinate_names": cn, "time": kin.time[ok_frames]}
        if meth == "static_optimization":
            sol = o.solve_static_optimization_batch(
                jac,
                tq,
                f_active=fa,
                f_passive=fp,
                reserve_optimal_force=reserves,
                solver=cfg.optimization.solver,
                **common,
            )
            forces, acts = sol.forces, sol.activations
        elif meth == "bounded_qp":
            sol = o.solve_tension_batch(
                jac,
                tq,
                f_iso=params.max_isometric_force,
                f_max=fa + fp,
                reserve_optimal_force=reserves,
                solver=cfg.optimization.solver,
                **common,
            )
            forces = sol.forces
            acts = np.clip(forces / np.maximum(fa, 1e-9), 0, None)
        elif meth == "emg_weighted":
            if emg is None:
                raise StageUnavailable("emg_weighted needs the EMG stage")
            meas = np.array(
                [
                    n in emg["muscles"] and bool(emg["usable"][emg["muscles"].index(n)])
                    for n in params.names
                ]
            )
            a = np.zeros_like(fa)
            for k, n in enumerate(params.names):
                if meas[k]:
                    a[:, k] = emg["activation"][ok_frames, emg["muscles"].index(n)]
            sol = o.solve_emg_weighted_batch(
                jac,
                tq,
                f_ref=a * fa,
                measured=meas,
                w_emg=cfg.optimization.w_emg,
                f_max=fa + fp,
                solver=cfg.optimization.solver,
                **common,
            )
            forces = sol.forces
            acts = np.clip(forces / np.maximum(fa, 1e-9), 0, None)
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
        f_all[ok_frames], a_all[ok_frames] = forces, acts
        out = {"forces": f_all, "activations": a_all, "muscles": params.names, "method": meth}
        if sol is not None:
            out["infeasible_frames"] = int(sol.infeasible_frames.size)
            rt = np.full((n, len(act_idx)), np.nan)
            rt[ok_frames] = sol.reserve_torques
            out["reserve_torques"] = rt
            out["reserve_coordinates"] = cn
        return out

    # ------------------------------------------------------------------ tension optimisation
    opt_settings = dataclasses.asdict(cfg.optimization)
    opt_needs = ("muscle_geometry", "inverse_dynamics") + (
        ("emg",) if cfg.optimization.method == "emg_weighted" else ()
    )

    def do_opt() -> dict[str, Any]:
        check("tension_optimization")
        return optimise(model_id, jt)

    sol = runner.run("tension_optimization", do_opt, needs=opt_needs, settings=opt_settings)

    # ------------------------------------------------------------------ strength
    def do_strength() -> dict[str, Any]:
        check("strength_identification")
        ident_cls = _need("msk.strength", "StrengthIdentifier")
        params, state = muscle_state(model)
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
        good = ok_frames & np.isfinite(jt.tau).all(axis=1)
        est = ident_cls(groups, params, n_bootstrap=200, random_state=0)
        sub = _slice_state(state, good)
        est.fit(
            geom.jacobian[good],
            act[good],
            jt.tau[good],
            sub,
            coordinate_names=jt.coordinate_names,
        )
        p = est.profile_
        return {
            "profile": p,
            "groups": {g: list(v) for g, v in groups.items()},
            "t0": float(kin.time[good][0]),
        }

    strength = runner.run(
        "strength_identification",
        do_strength,
        needs=("muscle_geometry", "emg", "inverse_dynamics"),
    )

    # ------------------------------------------------------------------ knee contact
    def do_contact() -> dict[str, Any]:
        check("knee_contact")
        from msk.dynamics import joint_reaction

        joint = f"knee{sfx}"
        if joint not in {j.name for j in model.joints}:
            raise StageUnavailable(f"model has no joint {joint!r}")
        res: dict[str, Any] = {"joint": joint}
        variants = {"generic": (model, sol)}
        if strength is not None:
            from msk.strength import with_strength

            m_spec = with_strength(model_id, strength["profile"])
            variants["subject_specific"] = (m_spec, optimise(m_spec, jt))
        n = kin.time.size
        # muscle paths are fixed points per call: evaluate moving / conditional points at the
        # mean posture of short chunks of frames (CONTACT_CHUNK_FRAMES)
        chunks = [
            np.arange(i, min(i + CONTACT_CHUNK_FRAMES, n))
            for i in range(0, n, CONTACT_CHUNK_FRAMES)
        ]
        for name, (mdl, s) in variants.items():
            f = np.nan_to_num(s["forces"], nan=0.0)
            force = np.full((n, 3), np.nan)
            for idx in chunks:
                ok = idx[ok_frames[idx]]
                if ok.size == 0:
                    continue
                paths = _muscle_paths(mdl, np.mean(kin.q[ok], axis=0), kin.coordinate_names)
                jr = joint_reaction(
                    mdl,
                    _frames(kin, ok, n),
                    _frames(loads, ok, n),
                    joint=joint,
                    frame="child",
                    muscle_forces=f[ok],
                    muscle_paths=paths,
                )
                force[ok] = jr.force
            res[name] = {"force": force, "total": np.linalg.norm(force, axis=1)}
        if "contact" in raw:
            res["measured"] = raw["contact"]
        return res

    contact = runner.run(
        "knee_contact",
        do_contact,
        needs=("tension_optimization",)
        + (("strength_identification",) if strength is not None else ()),
        settings={"contact": hashes.get("contact_force")},
    )

    # ------------------------------------------------------------------ tables and comparison
    events = [{"label": e.label, "context": e.context, "time": e.time} for e in trial.events]
    cycle = _gait_cycle(events, side)
    body_weight = cfg.subject.mass_kg * G0
    tables: dict[str, Table] = {}
    t = kin.time
    tables["q"] = Table(t, kin.q, tuple(kin.coordinate_names), "q")
    tables["joint_torques"] = Table(t, jt.tau, tuple(jt.coordinate_names), "joint_torques")
    tables["residuals"] = Table(
        t,
        np.column_stack([jt.residual_force, jt.residual_moment]),
        ("force_x", "force_y", "force_z", "moment_x", "moment_y", "moment_z"),
        "residuals",
    )
    if sol is not None:
        tables["muscle_forces"] = Table(t, sol["forces"], tuple(sol["muscles"]), "muscle_forces")
        tables["activations"] = Table(t, sol["activations"], tuple(sol["muscles"]), "activations")
    measured_on_t = None
    if contact is not None:
        cols, data = [], []
        for name in ("generic", "subject_specific"):
            if name in contact:
                c = contact[name]
                cols += [f"{name}_{a}" for a in ("x", "y", "z")] + [
                    f"{name}_total",
                    f"{name}_total_bw",
                ]
                data += [c["force"], c["total"][:, None], (c["total"] / body_weight)[:, None]]
        if "measured" in contact and cycle is not None:
            meas = contact["measured"]
            tm = cycle[0] + meas["fraction"] * (cycle[1] - cycle[0])
            measured_on_t = np.interp(t, tm, meas["total"], left=np.nan, right=np.nan)
            cols += ["measured_total", "measured_total_bw"]
            data += [measured_on_t[:, None], (measured_on_t / body_weight)[:, None]]
        tables["knee_contact"] = Table(t, np.column_stack(data), tuple(cols), "knee_contact")
    if ident is not None:
        from msk.model import INERTIAL_PARAMETER_NAMES

        cols, vals = [], []
        for b, phi in ident["parameters"].items():
            cols += [f"{b}.{p}" for p in INERTIAL_PARAMETER_NAMES]
            vals += list(np.asarray(phi, dtype=float))
        tables["inertial_parameters"] = Table(
            np.array([ident["t0"]]), np.array([vals]), tuple(cols), "inertial_parameters"
        )
    if strength is not None:
        p = strength["profile"]
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
        tables["strength"] = Table(
            np.array([strength["t0"]]), np.array([vals]), tuple(cols), "strength"
        )

    def do_compare() -> dict[str, Any]:
        check("comparison")
        from msk import compare

        out: dict[str, Any] = {}
        if "identified" in tau:
            g, s = tau["generic"], tau["identified"]
            good = np.isfinite(g.tau).all(axis=1) & np.isfinite(s.tau).all(axis=1)
            leg = [i for i, c in enumerate(g.coordinate_names) if c.endswith(sfx)]
            out["torque_rms_difference_nm"] = {
                g.coordinate_names[i]: float(compare.rms(g.tau[good, i], s.tau[good, i]))
                for i in leg
            }
            out["residual_force_rms_n"] = {
                "generic": float(np.sqrt(np.mean(g.residual_force[good] ** 2))),
                "identified": float(np.sqrt(np.mean(s.residual_force[good] ** 2))),
            }
            out["residual_moment_rms_nm"] = {
                "generic": float(np.sqrt(np.mean(g.residual_moment[good] ** 2))),
                "identified": float(np.sqrt(np.mean(s.residual_moment[good] ** 2))),
            }
        if contact is not None and measured_on_t is not None:
            sel = np.isfinite(measured_on_t)
            for name in ("generic", "subject_specific"):
                if name not in contact:
                    continue
                pred = contact[name]["total"]
                m = sel & np.isfinite(pred)
                if m.sum() < 5:
                    continue
                a, b = measured_on_t[m], pred[m]
                out[f"knee_contact_{name}"] = {
                    "rms_n": float(compare.rms(a, b)),
                    "rms_bw": float(compare.rms(a, b)) / body_weight,
                    "nrmsd_pct": float(compare.nrmsd(a, b)),
                    "pearson_r": float(compare.pearson_r(a, b)),
                    "spearman_rho": float(compare.spearman(a, b)),
                    "icc": float(compare.icc(a, b)),
                    "peak_difference_n": float(compare.peak_difference(b, a)),
                    "peak_measured_bw": float(a.max() / body_weight),
                    "peak_predicted_bw": float(b.max() / body_weight),
                    "n_frames": int(m.sum()),
                }
        if strength is not None:
            p = strength["profile"]
            out["strength_factor_minus_generic"] = {
                n: float(f - 1.0) for n, f in zip(p.group_names, p.factors)
            }
        if not out:
            raise StageUnavailable("nothing to compare")
        return out

    comparison = runner.run(
        "comparison",
        do_compare,
        needs=("inverse_dynamics",),
        settings=[runner.keys.get(n) for n in ("knee_contact", "strength_identification")],
    )

    # ------------------------------------------------------------------ summary
    quality = _quality(trial, kin, jt, loads, emg, sol, strength, ident, body_weight)
    settings = _settings(cfg)
    summary: dict[str, Any] = {
        "session": cfg.subject.name,
        "created_utc": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "versions": _versions(),
        "config": {"path": str(cfg.path), "sha256": file_sha256(cfg.path)},
        "inputs": [
            {"role": k, "path": str(p), "sha256": hashes[k], "bytes": Path(p).stat().st_size}
            for k, p in files.items()
        ],
        "settings": settings,
        "subject": {
            "name": cfg.subject.name,
            "mass_kg": cfg.subject.mass_kg,
            "height_m": cfg.subject.height_m,
            "sex": cfg.subject.sex,
            "side": side,
            "body_weight_n": body_weight,
        },
        "model": {**built["info"], "name": model.name, "muscles": len(model.muscles)},
        "frame": {"lab_to_model_rotation": rot, "lab_up": trial.up},
        "events": events,
        "gait_cycle_s": list(cycle) if cycle else None,
        "angle_columns": [c for c in kin.coordinate_names if not c.endswith(("_tx", "_ty", "_tz"))],
        "quality": quality,
        "methods": {
            "contact_path_update_frames": CONTACT_CHUNK_FRAMES,
            "plate_assignment": "foot nearest the centre of pressure (msk.loads, no outline)",
            "scaling_measurements": [m[0] for m in DEFAULT_MEASUREMENTS],
            "task_trial": task.name,
        },
        "identification": None
        if ident is None
        else {k: ident[k] for k in ("segments", "condition_number", "n_frames", "advice")},
        "anthropometry": _anthropometry(cfg, model),
        "strength": None if strength is None else _strength_summary(strength),
        "comparison": comparison,
        "optimization": None
        if sol is None
        else {
            "method": sol["method"],
            "infeasible_frames": sol.get("infeasible_frames"),
            "reserve_torque_rms_nm": None
            if "reserve_torques" not in sol
            else {
                c: float(np.sqrt(np.nanmean(sol["reserve_torques"][:, k] ** 2)))
                for k, c in enumerate(sol["reserve_coordinates"])
                if c.endswith(sfx)
            },
        },
    }

    # ------------------------------------------------------------------ report + write
    from msk.report import build_figures, write_report

    def figures() -> dict[str, str]:
        check("report")
        res = SessionResults(tables, summary, None, tuple(summary["angle_columns"]))
        return build_figures(res)

    fig_key = _key(
        [
            (n, tb.columns, hashlib.sha256(np.ascontiguousarray(tb.data).tobytes()).hexdigest())
            for n, tb in tables.items()
        ],
        [
            summary[k]
            for k in ("gait_cycle_s", "subject", "identification", "strength", "anthropometry")
        ],
    )
    figs = runner.run("report", figures, settings=fig_key)
    total = _time.perf_counter() - t_start
    summary["stages"] = [dataclasses.asdict(r) for r in runner.records]
    summary["not_available"] = [
        {"stage": r.name, "status": r.status, "reason": r.message}
        for r in runner.records
        if r.status in ("not available", "failed")
    ]
    summary["run_seconds"] = total

    def report(res: SessionResults, folder: Path) -> None:
        write_report(res, folder, figures=figs, pdf=pdf)

    write_session(
        out, SessionResults(tables, summary, None, tuple(summary["angle_columns"])), report=report
    )
    if progress is not None:
        progress.write(f"wrote {out} in {_time.perf_counter() - t_start:.2f} s\n")
    return RunResult(out, summary, tuple(runner.records), _time.perf_counter() - t_start)


# ---------------------------------------------------------------------------------------------
# helpers (formatting only)
# ---------------------------------------------------------------------------------------------
def _read_contact_csv(path: Path) -> dict[str, np.ndarray]:
    """Measured knee contact force over one gait cycle: a CSV with a cycle-fraction column
    (``sample_0_to_100`` or ``percent``…) and ``F_total_magnitude_N`` (or the last column)."""
    lines = [ln for ln in path.read_text(encoding="utf-8").splitlines() if ln.strip()]
    if len(lines) < 3:
        raise MissingDataError(f"{path}: no contact-force samples")
    head = [c.strip() for c in lines[0].split(",")]
    try:
        arr = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])
    except ValueError as exc:
        raise ConfigError(f"{path}: not a numeric CSV: {exc}") from None
    col = head.index("F_total_magnitude_N") if "F_total_magnitude_N" in head else len(head) - 1
    x = arr[:, 0]
    frac = (x - x[0]) / (x[-1] - x[0])
    return {"fraction": frac, "total": arr[:, col], "column": head[col]}


def _slice_state(state: Any, mask: np.ndarray) -> Any:
    changes = {}
    for f in dataclasses.fields(state):
        v = getattr(state, f.name)
        if isinstance(v, np.ndarray) and v.ndim == 2:
            changes[f.name] = v[mask]
    return dataclasses.replace(state, **changes)


def _muscle_paths(
    model: Any, theta: np.ndarray, coordinate_names: Sequence[str]
) -> list[list[tuple[str, np.ndarray]]]:
    """Path points per muscle at the posture ``theta``, as ``(body, point in body)`` pairs for
    :func:`msk.dynamics.joint_reaction`: moving points evaluated at ``theta``, conditional
    points kept only while their coordinate is in range (as the geometry does)."""
    names = list(coordinate_names)
    paths = []
    for m in model.muscles:
        pts = []
        for p in m.points:
            loc = np.asarray(p.location, dtype=float).copy()
            coords = getattr(p, "coordinates", None)
            funcs = getattr(p, "functions", None)
            if coords is not None and funcs is not None:
                for k in range(3):
                    if coords[k] is not None and funcs[k] is not None:
                        loc[k] = float(np.asarray(funcs[k](theta[names.index(coords[k])])))
            cond = getattr(p, "coordinate", "")
            if cond and cond in names:
                lo, hi = p.range
                if not lo <= theta[names.index(cond)] <= hi:
                    continue
            pts.append((p.body, loc))
        paths.append(pts)
    return paths


def _frames(obj: Any, idx: np.ndarray, n: int) -> Any:
    """A frozen result (Kinematics, ExternalLoads) restricted to the frames ``idx``: every
    array field whose first axis has the ``n`` frames is sliced."""
    changes = {}
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if isinstance(v, np.ndarray) and v.ndim >= 1 and v.shape[0] == n:
            changes[f.name] = v[idx]
    return dataclasses.replace(obj, **changes)


def _plain_quality(q: Any) -> dict[str, Any]:
    if q is None:
        return {}
    out = {}
    for f in dataclasses.fields(q):
        v = getattr(q, f.name)
        out[f.name] = v.tolist() if isinstance(v, np.ndarray) else v
    return out


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
) -> dict[str, Any]:
    ok = np.isfinite(jt.residual_force).all(axis=1)
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
        "residual_force_rms_n": float(np.sqrt(np.mean(jt.residual_force[ok] ** 2))),
        "residual_force_rms_pct_bw": float(
            100 * np.sqrt(np.mean(jt.residual_force[ok] ** 2)) / body_weight
        ),
        "residual_moment_rms_nm": float(np.sqrt(np.mean(jt.residual_moment[ok] ** 2))),
        "plate_assignments": [
            {k: getattr(a, k) for k in ("plate", "body", "start_time", "end_time") if hasattr(a, k)}
            for a in getattr(loads, "assignments", ())
        ],
    }
    if emg is not None:
        flat = [emg["sources"][k] for k in range(len(emg["muscles"])) if not emg["usable"][k]]
        q["emg_flat_channels"] = sorted(set(flat))
        q["emg_warnings"] = emg["warnings"]
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
        segs = generic_segments(
            cfg.subject.mass_kg, cfg.subject.height_m or 1.75, sex=cfg.subject.sex
        )
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


def _strength_summary(strength: Mapping[str, Any]) -> dict[str, Any]:
    p = strength["profile"]
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
                "identified": bool(p.identified[g]),
            }
            for g, n in enumerate(p.group_names)
        ],
        "r2": float(p.r2),
        "confidence": float(p.confidence),
        "bounds": list(p.bounds),
        "method": p.method,
    }


# ---------------------------------------------------------------------------------------------
# CLI verbs: msk run, msk print-config, msk report
# ---------------------------------------------------------------------------------------------
def _cli() -> None:
    import argparse

    from msk.cli import command

    def run_args(p: argparse.ArgumentParser) -> None:
        p.add_argument("config", metavar="CONFIG", type=Path, help="session configuration (.toml)")
        p.add_argument("--out", required=True, type=Path, metavar="DIR", help="session folder")
        p.add_argument("--no-cache", action="store_true", help="recompute every stage")
        p.add_argument("--pdf", action="store_true", help="also print report.pdf (Chromium)")
        p.add_argument("--quiet", action="store_true", help="no progress lines")

    @command("run", help="run a session pipeline (C3D → results folder)", arguments=run_args)
    def _run(args: argparse.Namespace) -> int:
        res = run_session(
            args.config,
            args.out,
            progress=None if args.quiet else sys.stderr,
            use_cache=not args.no_cache,
            pdf=args.pdf,
        )
        missing = res.not_available
        if missing and not args.quiet:
            sys.stderr.write(f"stages not available: {', '.join(missing)}\n")
        return 0

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
