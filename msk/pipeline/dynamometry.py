"""A dynamometry session: one subject's maximal isometric tests → strength per targeted group.

The configuration is a TOML file with ``kind = "dynamometry"`` (``msk run`` recognises it and
runs :func:`run_dynamometry`); paths are relative to the file::

    kind = "dynamometry"
    [subject]                # name, mass_kg, height_m, sex ("male"/"female", optional), side
    [model]                  # source: the generic model scaled to the subject (stature, mass)
    [dynamometer]            # how the exports read: time_column, force_column + force_unit
                             # (or torque_column + torque_unit), emg_unit, capacity (in the
                             # force unit), baseline ("auto", "pre_effort", "tared"),
                             # baseline_window_s, plateau_window_s
    [dynamometer.emg]        # channel label = column name
    [[tests]]                # name, file, action (msk.strength.joint_strength.ACTIONS),
                             # angle_deg, angle_range_deg, posture_deg = {stem = deg}, target,
                             # antagonist, sign, segment ("shank"/"foot") or lever_arm_m
                             # (+ lever_arm_sd_m)

Another subject of the same protocol: change ``[subject]`` and the ``file`` of each test.

The folder written: ``summary.json`` (``kind = "dynamometry"``: subject, settings, per test the
strength record of :class:`msk.strength.isometric.TestStrength`, the EMG MVC amplitudes, the
flags), ``tables/strength.csv`` (one row per test) and ``report.html`` (the clinician's
section: N·m, N·m/kg, interval, factor vs the scaled generic model, status and reason).
"""

from __future__ import annotations

import csv
import html
import json
import math
import shutil
import tempfile
import time
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from msk import __version__
from msk.exceptions import ConfigError
from msk.io.dynamometer import EMG_UNITS, FORCE_UNITS, TORQUE_UNITS, read_dynamometer
from msk.strength.isometric import (
    IsometricSettings,
    IsometricTest,
    LeverArm,
    TestStrength,
    agonist_mvc,
    analyse_isometric,
    group_strength,
    lever_arm_from_height,
    model_isometric_torque,
    session_mvc,
    subject_model,
)

__all__ = [
    "KIND",
    "STRENGTH_COLUMNS",
    "DynamometryConfig",
    "DynamometryResult",
    "TestConfig",
    "is_dynamometry_config",
    "load_dynamometry_config",
    "run_dynamometry",
    "strength_rows",
    "write_strength_csv",
]

KIND = "dynamometry"
#: the columns of ``tables/strength.csv`` (and of the cohort table)
STRENGTH_COLUMNS = (
    "subject",
    "test",
    "action",
    "status",
    "torque_nm",
    "torque_ci_low_nm",
    "torque_ci_high_nm",
    "torque_per_kg",
    "torque_per_kg_ci_low",
    "torque_per_kg_ci_high",
    "measured_net_nm",
    "cocontraction_nm",
    "lever_arm_m",
    "lever_arm_sd_m",
    "lever_arm_kind",
    "model_nm",
    "factor",
    "factor_ci_low",
    "factor_ci_high",
    "reason",
)


@dataclass(frozen=True)
class TestConfig:
    """One ``[[tests]]`` table: the test and its file, and a given lever arm if any."""

    test: IsometricTest
    file: Path
    lever_arm_m: float | None
    lever_arm_sd_m: float


@dataclass(frozen=True)
class DynamometryConfig:
    path: Path
    subject: Mapping[str, Any]
    model_source: Path
    reader: Mapping[str, Any]
    settings: IsometricSettings
    tests: tuple[TestConfig, ...]


@dataclass(frozen=True)
class DynamometryResult:
    out_dir: Path
    summary: Mapping[str, Any]
    strengths: tuple[TestStrength, ...]
    seconds: float


def is_dynamometry_config(path: str | Path) -> bool:
    """Whether ``path`` is a TOML file with ``kind = "dynamometry"`` (False on anything else:
    the session loader reports the errors of other files)."""
    try:
        raw = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return False
    return raw.get("kind") == KIND


def _get(
    table: Mapping[str, Any],
    key: str,
    kind: type | tuple[type, ...],
    where: str,
    src: Path,
    default: Any = ...,
) -> Any:
    if key not in table:
        if default is ...:
            raise ConfigError(f"{src}: missing key {where}.{key}")
        return default
    v = table[key]
    if isinstance(v, bool) and bool not in (kind if isinstance(kind, tuple) else (kind,)):
        raise ConfigError(f"{src}: {where}.{key} = {v!r} should be {kind}")
    if kind is float and isinstance(v, int):
        v = float(v)
    if not isinstance(v, kind):
        raise ConfigError(f"{src}: {where}.{key} = {v!r} has the wrong type")
    if isinstance(v, float) and not math.isfinite(v):
        raise ConfigError(f"{src}: {where}.{key} = {v!r} is not finite")
    return v


def _check_keys(table: Mapping[str, Any], allowed: set[str], where: str, src: Path) -> None:
    extra = sorted(set(table) - allowed)
    if extra:
        raise ConfigError(
            f"{src}: unknown key {where}.{extra[0]}; allowed: {', '.join(sorted(allowed))}"
        )


def load_dynamometry_config(path: str | Path) -> DynamometryConfig:
    """Read and validate a ``kind = "dynamometry"`` configuration (module docstring);
    :class:`~msk.exceptions.ConfigError` naming the file and the key."""
    from msk.strength.joint_strength import ACTIONS

    src = Path(path).resolve()
    try:
        raw = tomllib.loads(src.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"config file not found: {src}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{src}: cannot read: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{src}: not valid TOML: {exc}") from None
    _check_keys(raw, {"kind", "subject", "model", "dynamometer", "tests"}, "", src)
    if raw.get("kind") != KIND:
        raise ConfigError(f"{src}: kind = {raw.get('kind')!r}, expected {KIND!r}")
    sub = raw.get("subject")
    if not isinstance(sub, dict):
        raise ConfigError(f"{src}: missing table [subject]")
    _check_keys(sub, {"name", "mass_kg", "height_m", "sex", "side", "age_years"}, "subject", src)
    mass = _get(sub, "mass_kg", float, "subject", src)
    height = _get(sub, "height_m", float, "subject", src)
    if not 20.0 <= mass <= 300.0:
        raise ConfigError(f"{src}: subject.mass_kg = {mass} is not a plausible body mass")
    if not 0.5 <= height <= 2.5:
        raise ConfigError(f"{src}: subject.height_m = {height}: not a height in metres")
    sex = _get(sub, "sex", str, "subject", src, None)
    if sex not in (None, "male", "female"):
        raise ConfigError(f"{src}: subject.sex = {sex!r}: 'male', 'female' or absent")
    side = _get(sub, "side", str, "subject", src, "right")
    if side not in ("left", "right"):
        raise ConfigError(f"{src}: subject.side = {side!r}: 'left' or 'right'")
    subject = {
        "name": _get(sub, "name", str, "subject", src, src.stem),
        "mass_kg": mass,
        "height_m": height,
        "sex": sex,
        "side": side,
        "age_years": _get(sub, "age_years", (int, float), "subject", src, None),
    }
    model = raw.get("model")
    if not isinstance(model, dict):
        raise ConfigError(f"{src}: missing table [model] (source = the generic model)")
    _check_keys(model, {"source"}, "model", src)
    model_source = (src.parent / _get(model, "source", str, "model", src)).resolve()
    dyn = raw.get("dynamometer", {})
    if not isinstance(dyn, dict):
        raise ConfigError(f"{src}: [dynamometer] should be a table")
    keys = {
        "time_column",
        "force_column",
        "force_unit",
        "torque_column",
        "torque_unit",
        "emg_unit",
        "emg",
        "capacity",
        "baseline",
        "baseline_window_s",
        "plateau_window_s",
        "zero_sd",
    }
    _check_keys(dyn, keys, "dynamometer", src)
    emg = dyn.get("emg", {})
    if not isinstance(emg, dict) or not all(isinstance(v, str) for v in emg.values()):
        raise ConfigError(f"{src}: [dynamometer.emg] should map channel label = column name")
    force_unit = _get(dyn, "force_unit", str, "dynamometer", src, "N")
    torque_unit = _get(dyn, "torque_unit", str, "dynamometer", src, "N.m")
    emg_unit = _get(dyn, "emg_unit", str, "dynamometer", src, "V")
    for key, val, table in (
        ("force_unit", force_unit, FORCE_UNITS),
        ("torque_unit", torque_unit, TORQUE_UNITS),
        ("emg_unit", emg_unit, EMG_UNITS),
    ):
        if val.replace("·", ".").replace("µ", "u") not in table:
            raise ConfigError(f"{src}: dynamometer.{key} = {val!r}; allowed: {', '.join(table)}")
    force_col = _get(dyn, "force_column", str, "dynamometer", src, None)
    torque_col = _get(dyn, "torque_column", str, "dynamometer", src, None)
    if (force_col is None) == (torque_col is None):
        raise ConfigError(
            f"{src}: give exactly one of dynamometer.force_column and dynamometer.torque_column"
        )
    to_si = (
        FORCE_UNITS[force_unit.replace("·", ".")]
        if force_col
        else TORQUE_UNITS[torque_unit.replace("·", ".")]
    )
    baseline = _get(dyn, "baseline", str, "dynamometer", src, "auto")
    if baseline not in ("auto", "pre_effort", "tared"):
        raise ConfigError(
            f"{src}: dynamometer.baseline = {baseline!r}; allowed: auto, pre_effort, tared"
        )
    cap = _get(dyn, "capacity", float, "dynamometer", src, None)
    zero = _get(dyn, "zero_sd", float, "dynamometer", src, 1.0 if force_unit == "kgf" else None)
    settings = IsometricSettings(
        baseline=baseline,
        zero_sd=(zero * to_si) if zero is not None else 0.02 * (cap * to_si if cap else 0.0),
        baseline_window_s=_get(dyn, "baseline_window_s", float, "dynamometer", src, 0.25),
        plateau_window_s=_get(dyn, "plateau_window_s", float, "dynamometer", src, 1.0),
        capacity=cap * to_si if cap is not None else None,
    )
    reader = {
        "time_column": _get(dyn, "time_column", str, "dynamometer", src, "time_s"),
        "force_column": force_col,
        "force_unit": force_unit,
        "torque_column": torque_col,
        "torque_unit": torque_unit,
        "emg_columns": dict(emg),
        "emg_unit": emg_unit,
    }
    raw_tests = raw.get("tests")
    if not isinstance(raw_tests, list) or not raw_tests:
        raise ConfigError(f"{src}: no [[tests]] given")
    tests = []
    tkeys = {
        "name",
        "file",
        "action",
        "angle_deg",
        "angle_range_deg",
        "posture_deg",
        "target",
        "antagonist",
        "sign",
        "segment",
        "lever_arm_m",
        "lever_arm_sd_m",
    }
    for i, t in enumerate(raw_tests):
        w = f"tests[{i}]"
        if not isinstance(t, dict):
            raise ConfigError(f"{src}: {w} should be a table")
        _check_keys(t, tkeys, w, src)
        action = _get(t, "action", str, w, src)
        if action not in ACTIONS:
            raise ConfigError(f"{src}: {w}.action = {action!r}; allowed: {', '.join(ACTIONS)}")
        posture = t.get("posture_deg", {})
        if not isinstance(posture, dict) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in posture.values()
        ):
            raise ConfigError(f"{src}: {w}.posture_deg should map coordinate stem = degrees")
        target = _get(t, "target", str, w, src, "")
        antagonist = _get(t, "antagonist", str, w, src, "")
        for key, ch in (("target", target), ("antagonist", antagonist)):
            if ch and ch not in emg:
                raise ConfigError(
                    f"{src}: {w}.{key} = {ch!r} is not a channel of "
                    f"[dynamometer.emg] ({', '.join(emg) or 'none'})"
                )
        segment = _get(t, "segment", str, w, src, "shank")
        if segment not in ("shank", "foot"):
            raise ConfigError(f"{src}: {w}.segment = {segment!r}; allowed: shank, foot")
        sign = _get(t, "sign", float, w, src, 1.0)
        if sign not in (1.0, -1.0):
            raise ConfigError(f"{src}: {w}.sign = {sign}: +1 or -1")
        lever = _get(t, "lever_arm_m", float, w, src, None)
        if lever is not None and not 0.01 <= lever <= 1.0:
            raise ConfigError(f"{src}: {w}.lever_arm_m = {lever}: not a lever arm in metres")
        test = IsometricTest(
            name=_get(t, "name", str, w, src),
            action=action,
            angle_deg=_get(t, "angle_deg", float, w, src),
            angle_range_deg=_get(t, "angle_range_deg", float, w, src, 0.0),
            posture_deg={k: float(v) for k, v in posture.items()},
            target=target,
            antagonist=antagonist,
            sign=sign,
            segment=segment,
        )
        file = (src.parent / _get(t, "file", str, w, src)).resolve()
        tests.append(TestConfig(test, file, lever, _get(t, "lever_arm_sd_m", float, w, src, 0.01)))
    names = [tc.test.name for tc in tests]
    if len(set(names)) != len(names):
        raise ConfigError(f"{src}: test names must be unique, got {names}")
    return DynamometryConfig(src, subject, model_source, reader, settings, tuple(tests))


def _lever(cfg: DynamometryConfig, tc: TestConfig) -> LeverArm:
    if tc.lever_arm_m is not None:
        return LeverArm(
            tc.lever_arm_m,
            tc.lever_arm_sd_m,
            f"given by the configuration: {tc.lever_arm_m:.3f} ± {tc.lever_arm_sd_m:.3f} m",
        )
    s = cfg.subject
    return lever_arm_from_height(tc.test.segment, s["height_m"], sex=s["sex"])


def strength_rows(subject: str, results: Sequence[TestStrength]) -> list[dict[str, Any]]:
    """The rows of ``tables/strength.csv`` (:data:`STRENGTH_COLUMNS`) of one subject."""
    return [_row(subject, r) for r in results]


def write_strength_csv(path: str | Path, rows: Sequence[Mapping[str, Any]]) -> Path:
    """A strength table (:data:`STRENGTH_COLUMNS`, one row per subject and test)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=STRENGTH_COLUMNS, lineterminator="\n")
        w.writeheader()
        w.writerows({k: r.get(k, "") for k in STRENGTH_COLUMNS} for r in rows)
    return path


def _row(subject: str, r: TestStrength) -> dict[str, Any]:
    return {
        "subject": subject,
        "test": r.test,
        "action": r.action,
        "status": r.status,
        "torque_nm": round(r.torque_nm, 3),
        "torque_ci_low_nm": round(r.torque_ci_nm[0], 3),
        "torque_ci_high_nm": round(r.torque_ci_nm[1], 3),
        "torque_per_kg": round(r.torque_per_kg, 4),
        "torque_per_kg_ci_low": round(r.torque_per_kg_ci[0], 4),
        "torque_per_kg_ci_high": round(r.torque_per_kg_ci[1], 4),
        "measured_net_nm": round(r.measured_net_nm, 3),
        "cocontraction_nm": round(r.cocontraction_nm, 3),
        "lever_arm_m": round(r.lever_arm_m, 4),
        "lever_arm_sd_m": round(r.lever_arm_sd_m, 4),
        "lever_arm_kind": r.lever_arm_source.split(":")[0],
        "model_nm": round(r.model_nm, 3),
        "factor": round(r.factor, 4),
        "factor_ci_low": round(r.factor_ci[0], 4),
        "factor_ci_high": round(r.factor_ci[1], 4),
        "reason": r.reason,
    }


def _check_folder(out: Path) -> None:
    if not out.exists():
        return
    if not out.is_dir():
        raise ConfigError(f"{out}: exists and is not a folder")
    entries = {p.name for p in out.iterdir()}
    if not entries:
        return
    summary = out / "summary.json"
    try:
        kind = json.loads(summary.read_text(encoding="utf-8")).get("kind")
    except (OSError, ValueError, AttributeError):
        kind = None
    if kind != KIND or not entries <= {"summary.json", "tables", "report.html"}:
        raise ConfigError(
            f"{out}: not empty and not a dynamometry results folder: refusing to replace it"
        )


def run_dynamometry(
    config: str | Path | DynamometryConfig, out_dir: str | Path, *, progress: Any = None
) -> DynamometryResult:
    """Run one subject's dynamometry session into ``out_dir`` (module docstring)."""
    from msk.model_files import load_model
    from msk.pipeline.runner import file_sha256

    t0 = time.perf_counter()
    cfg = config if isinstance(config, DynamometryConfig) else load_dynamometry_config(config)
    out = Path(out_dir).resolve()
    _check_folder(out)
    s = cfg.subject
    if not cfg.model_source.is_file():
        raise ConfigError(f"{cfg.path}: model.source {cfg.model_source} not found")
    model = subject_model(
        load_model(cfg.model_source), height_m=s["height_m"], mass_kg=s["mass_kg"]
    )
    trials = []
    for tc in cfg.tests:
        rec = read_dynamometer(tc.file, **cfg.reader)
        trials.append(analyse_isometric(rec, tc.test, settings=cfg.settings))
        if progress is not None:
            progress.write(f"read {tc.test.name}: {tc.file.name}\n")
    tests = [tc.test for tc in cfg.tests]
    mvc = session_mvc(trials)
    own = agonist_mvc(trials, tests)
    results = []
    records = []
    models = [model_isometric_torque(model, tc.test, side=s["side"]) for tc in cfg.tests]
    levers = [None if tr.is_torque else _lever(cfg, tc) for tc, tr in zip(cfg.tests, trials)]
    # the subject's own net torque per target channel: the antagonists' maximal torque
    own_torque: dict[str, tuple[str, float]] = {}
    for tc, tr, lv in zip(cfg.tests, trials, levers):
        net = tr.plateau_mean * (lv.value_m if lv is not None else 1.0)
        if tc.test.target and net > own_torque.get(tc.test.target, ("", 0.0))[1]:
            own_torque[tc.test.target] = (tc.test.name, net)
    for tc, tr, mt, lever in zip(cfg.tests, trials, models, levers):
        r = group_strength(
            tr,
            tc.test,
            lever=lever,
            model=mt,
            mass_kg=s["mass_kg"],
            mvc=mvc,
            own_mvc=own,
            own_torque_nm=own_torque,
        )
        results.append(r)
        rec_d = r.as_dict()
        rec_d.update(
            file=str(tc.file),
            sha256=file_sha256(tc.file),
            baseline=tr.baseline_n,
            baseline_source=tr.baseline_source,
            plateau_window_start_s=tr.window_start_s,
            plateau_held_s=tr.plateau_s,
            model_posture_deg=dict(mt.posture_deg),
            model_agonists=list(mt.muscles),
            model_antagonist_nm=mt.antagonist_nm,
            emg_plateau_v=dict(tr.emg_plateau),
        )
        records.append(rec_d)
    flags = [f.as_dict() for r in results for f in r.flags]
    summary = {
        "kind": KIND,
        "msk_version": __version__,
        "session": s["name"],
        "subject": dict(s),
        "config": str(cfg.path),
        "model": {
            "source": str(cfg.model_source),
            "scaled": "every body by the subject's "
            "stature over the model's, masses to the body mass, F_iso unchanged",
        },
        "settings": {k: getattr(cfg.settings, k) for k in cfg.settings.__dataclass_fields__},
        "emg_mvc_v": {"session_max": mvc, "own_test": own},
        "tests": records,
        "n_tests": len(results),
        "n_identified": sum(r.status == "identified" for r in results),
        "flags": flags,
        "run_seconds": time.perf_counter() - t0,
    }
    rows = strength_rows(s["name"], results)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        (tmp / "tables").mkdir()
        write_strength_csv(tmp / "tables" / "strength.csv", rows)
        (tmp / "summary.json").write_text(
            json.dumps(summary, indent=1, default=str) + "\n", encoding="utf-8"
        )
        (tmp / "report.html").write_text(report_html(summary, results), encoding="utf-8")
        if out.exists():
            shutil.rmtree(out)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if progress is not None:
        progress.write(f"wrote {out} in {time.perf_counter() - t0:.2f} s\n")
    return DynamometryResult(out, summary, tuple(results), time.perf_counter() - t0)


def report_html(summary: Mapping[str, Any], results: tuple[TestStrength, ...] | list[Any]) -> str:
    """The clinician's page: what was identified (torque, per kg, interval, factor vs the
    scaled generic model, lever arm), then what was not, each with its reason."""
    e = html.escape
    s = summary["subject"]
    sex = s.get("sex") or "not given"
    head = (
        f"<h1>Isometric strength — {e(str(s['name']))}</h1><p>Mass {s['mass_kg']:g} kg, "
        f"height {s['height_m']:.2f} m, sex {e(sex)}, side {e(s['side'])}. Maximal isometric "
        "torque of each test's targeted group: the best sustained "
        f"{summary['settings']['plateau_window_s']:g}-s mean of the dynamometer force above "
        "its baseline × the lever arm, plus the antagonists' co-contraction where their EMG "
        "allows; interval 95 % (plateau variability, lever arm, zero of the cell, "
        "co-contraction). Factor: against the generic model (gait2392) scaled to the "
        "subject's height and mass, every agonist fully active at the test posture.</p>"
    )

    def table(rows: list[Any], identified: bool) -> str:
        if not rows:
            return "<p>None.</p>"
        h = (
            "<tr><th>Test</th><th>Torque (N·m)</th><th>95 % interval</th><th>N·m/kg</th>"
            "<th>× scaled generic</th><th>Lever arm</th>"
            + ("" if identified else "<th>Why not determined</th>")
            + "</tr>"
        )
        body = []
        for r in rows:
            cells = [
                e(r.test),
                f"{r.torque_nm:.1f}",
                f"[{r.torque_ci_nm[0]:.1f}, {r.torque_ci_nm[1]:.1f}]",
                f"{r.torque_per_kg:.2f} [{r.torque_per_kg_ci[0]:.2f}, {r.torque_per_kg_ci[1]:.2f}]",
                f"{r.factor:.2f} [{r.factor_ci[0]:.2f}, {r.factor_ci[1]:.2f}]",
                f"{r.lever_arm_m * 100:.1f} ± {r.lever_arm_sd_m * 100:.1f} cm "
                f"({e(r.lever_arm_source.split(':')[0])})",
            ]
            if not identified:
                cells.append(e(r.reason))
            body.append("<tr>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>")
        return f"<table border='1' cellpadding='4'>{h}{''.join(body)}</table>"

    ident = [r for r in results if r.status == "identified"]
    nd = [r for r in results if r.status != "identified"]
    notes = "".join(
        f"<li>{e(r.test)}: lever arm {e(r.lever_arm_source)}; co-contraction: "
        f"{e(r.cocontraction_note)}</li>"
        for r in results
    )
    return (
        "<!doctype html><html><head><meta charset='utf-8'><title>Isometric strength</title>"
        f"</head><body>{head}<h2>Identified</h2>{table(ident, True)}"
        "<h2>Not determined</h2><p>The torque of a test that failed a check is shown for "
        "reference only: it is not the group's strength.</p>"
        f"{table(nd, False)}<h2>Assumptions</h2><ul>{notes}</ul></body></html>\n"
    )
