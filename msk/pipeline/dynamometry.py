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
                             # (+ lever_arm_sd_m), band_nm_per_kg = [low, high] +
                             # band_source (else the library's older-adult band of the
                             # action when subject.age_years ≥ 60)

Another subject of the same protocol: change ``[subject]`` and the ``file`` of each test.

The folder written: ``summary.json`` (``kind = "dynamometry"``: subject, settings, per test the
strength record of :class:`msk.strength.isometric.TestStrength`, the EMG MVC amplitudes, the
flags), ``tables/strength.csv`` (one row per test) and ``report.html`` (the clinician's
section: N·m, N·m/kg, interval, factor vs the scaled generic model, status and reason).
"""

from __future__ import annotations

import json
import shutil
import tempfile
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from msk import __version__
from msk.config.dynamometry import (
    KIND,
    DynamometryConfig,
    TestConfig,
    is_dynamometry_config,
    load_dynamometry_config,
)
from msk.exceptions import ConfigError
from msk.io.dynamometer import read_dynamometer
from msk.report.dynamometry import report_html
from msk.results.strength_table import STRENGTH_COLUMNS, strength_rows, write_strength_csv
from msk.strength.isometric import (
    LeverArm,
    LiteratureBand,
    TestStrength,
    agonist_mvc,
    analyse_isometric,
    group_strength,
    lever_arm_from_height,
    literature_band,
    model_isometric_torque,
    relabel_quiet_channels,
    remove_envelope_rest,
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


@dataclass(frozen=True)
class DynamometryResult:
    out_dir: Path
    summary: Mapping[str, Any]
    strengths: tuple[TestStrength, ...]
    seconds: float


def _lever(cfg: DynamometryConfig, tc: TestConfig) -> LeverArm:
    if tc.lever_arm_m is not None:
        return LeverArm(
            tc.lever_arm_m,
            tc.lever_arm_sd_m,
            f"given by the configuration: {tc.lever_arm_m:.3f} ± {tc.lever_arm_sd_m:.3f} m",
        )
    s = cfg.subject
    return lever_arm_from_height(tc.test.segment, s["height_m"], sex=s["sex"])


def _band(cfg: DynamometryConfig, tc: TestConfig) -> LiteratureBand | None:
    if tc.band_nm_per_kg is not None:
        lo, hi = tc.band_nm_per_kg
        return LiteratureBand(lo, hi, f"given by the configuration: {tc.band_source}")
    return literature_band(tc.test.action, cfg.subject.get("age_years"))


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
    from msk.model.files import load_model
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
    trials = relabel_quiet_channels(remove_envelope_rest(trials))
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
            band=_band(cfg, tc),
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
        "n_below_published_band": sum(r.below_band for r in results),
        "flags": flags,
        "run_seconds": time.perf_counter() - t0,
    }
    rows = strength_rows(s["name"], results, age_years=s.get("age_years"), mass_kg=s.get("mass_kg"))
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
