"""``msk strength``: the trials of a session pooled into one strength identification
(:func:`msk.strength.pooled.identify_pooled`; Hayashibe et al. 2011, §V–VI).

``msk run`` analyses each task trial into its own folder; strength is a property of the
session, which needs its trials together. For each trial of ``[strength] pool`` (default:
every task and MVC trial) the pipeline's own chain runs up to the muscle geometry
(:func:`msk.pipeline.session.run_stages`: model from the static, kinematics, loads, inverse
dynamics, EMG envelopes, moment arms) with the trial as the task — an MVC trial recorded on the
plates gets its joint torques by inverse dynamics of its (static) posture like any task (an
MVC against a strap or a dynamometer that no plate measures belongs in the session's MVC
trials but not in the pool: its inverse dynamics would miss that force). The
rows each contributes are those the strength stage uses (:func:`msk.pipeline.strength.\
regression_rows`). The EMG of every trial is normalised by ONE reference per channel, computed
from the raw recordings with the session's filters (:func:`msk.muscles.emg.mvc_peaks`): the
MVC trials' peak (every ``role = "mvc"`` trial of the session, pooled or not) where any
exists — when every MVC trial is pooled (its torque known), the plateau mean over its
highest-torque second with its standard error, carried into the intervals
(:func:`msk.strength.pooled.identify_pooled`) — else the peak over every pooled trial
(``session_peak``, stated with its bias); ``[emg] mvc`` values win. The folder gets
``strength.json`` (per group: factor, intervals, status, reason, its own rows' r², the test
that would identify it) and ``strength.txt``; when the folder holds the session ``msk run``
wrote for the same configuration, :func:`attach_to_session` adds the result to its
``summary.json`` (``pooled_strength``) and rebuilds its report.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from pathlib import Path
from typing import Any, NamedTuple, TextIO

import numpy as np

from msk.config import SessionConfig, load_config
from msk.exceptions import ConfigError

__all__ = ["attach_to_session", "pooled_summary", "pooled_trials", "run_pooled_strength"]


def pooled_trials(cfg: SessionConfig) -> list[Any]:
    """The trials ``[strength] pool`` names (default: every task and MVC trial), in its
    order."""
    names = list(cfg.strength.pool) or [t.name for t in cfg.trials if t.role in ("task", "mvc")]
    by_name = {t.name: t for t in cfg.trials}
    out = [by_name[n] for n in names if n in by_name]
    if not out:
        raise ConfigError(f"{cfg.path}: no task or MVC trial to pool for the strength")
    return out


def _reference(cfg: SessionConfig, trials: list[Any]) -> Any:
    """One EMG reference per configured channel from the raw recordings (module docstring)."""
    from msk.io import read_c3d
    from msk.muscles.emg import mvc_peaks
    from msk.strength.pooled import EmgReference

    chans = list(dict.fromkeys(str(c).strip() for c in cfg.emg.channels.values()))
    every = {t.name: t for t in (*trials, *cfg.trials_with_role("mvc"))}
    raw = {n: read_c3d(t.file) for n, t in every.items()}

    def peaks(ts: list[Any]) -> dict[str, float]:
        return mvc_peaks(
            [(raw[t.name].analogs, raw[t.name].analog_rate_hz, raw[t.name].analog_labels)
             for t in ts],
            highpass_hz=cfg.emg.highpass_hz, lowpass_hz=cfg.emg.lowpass_hz,
        )  # fmt: skip

    # every MVC trial of the session normalises (pooled or not: one whose torque no plate
    # measures — a seated MVC against a strap — sets the reference without entering the rows)
    mvc = list(cfg.trials_with_role("mvc"))
    from_mvc = peaks(mvc) if mvc else {}
    from_all = peaks(trials)
    given = {str(k).strip(): float(v) for k, v in cfg.emg.mvc.items()}
    values, sources, used = [], [], []
    for c in chans:
        if c in given:
            v, s = given[c], "given"
        elif from_mvc.get(c, 0.0) > 0:
            v, s = from_mvc[c], "mvc"
        else:
            v, s = from_all.get(c, math.nan), "session_peak"
        if math.isfinite(v) and v > 0:
            used.append(c)
            values.append(v)
            sources.append(s)
    return EmgReference(tuple(used), np.asarray(values), tuple(sources))


def _plateau_reference(cfg: SessionConfig, ref: Any, pooled: list[Any]) -> Any:
    """When every MVC trial of the session is pooled (its torques known), each MVC-normalised
    channel's reference becomes its plateau mean over the trial's highest-torque second, with
    its standard error (:func:`msk.strength.pooled.session_emg_reference`); an MVC trial whose
    torque no plate measures keeps the peak of the raw recordings (no standard error)."""
    from msk.strength.pooled import EmgReference, session_emg_reference

    mvc = [p for p in pooled if p.kind == "mvc"]
    every = {t.name for t in cfg.trials_with_role("mvc")}
    if not mvc or every - {p.name for p in mvc}:
        return ref
    plate = session_emg_reference(mvc)
    values = np.array(ref.value, dtype=float)
    errors = np.full(values.size, np.nan)
    for k, (c, src) in enumerate(zip(ref.channels, ref.source)):
        if src == "mvc" and c in plate.channels:
            j = plate.channels.index(c)
            if plate.source[j] == "mvc":
                values[k] = plate.value[j]
                errors[k] = float(np.asarray(plate.standard_error)[j])
    return EmgReference(ref.channels, values, ref.source, errors)


class _Rows(NamedTuple):
    trial: Any  # msk.strength.pooled.PooledTrial
    params: Any
    model: Any
    groups: dict[str, list[str]]
    failed: dict[str, list[str]]
    coordinates: tuple[str, ...]
    #: per failed channel, the EMG check lines that name it
    checks: dict[str, list[str]]


def _trial_rows(cfg: SessionConfig, tc: Any, ref: Any, progress: TextIO | None) -> _Rows:
    """One trial through the chain up to the muscle geometry, as a
    :class:`msk.strength.pooled.PooledTrial` (its usable rows and channel-unit envelopes)."""
    from msk.muscles.geometry import muscle_parameters
    from msk.pipeline.runner import StageUnavailable
    from msk.pipeline.session import run_stages
    from msk.pipeline.strength import regression_rows
    from msk.strength.pooled import PooledTrial

    task = dataclasses.replace(tc, role="task")
    keep = tuple(t for t in cfg.trials if t.role in ("static", "mass_identification"))
    emg = dataclasses.replace(cfg.emg, mvc=dict(zip(ref.channels, map(float, ref.value))))
    one = dataclasses.replace(cfg, trials=(*keep, task), emg=emg)
    if progress is not None:
        progress.write(f"strength: trial {tc.name} ({tc.role}) through the chain\n")
    res = run_stages(one, until="muscle_geometry")
    params = muscle_parameters(res["model"].model)
    em, geo = res.get("emg"), res.get("muscle_geometry")
    if em is None or geo is None:
        raise StageUnavailable(f"trial {tc.name}: no EMG or muscle geometry")
    groups, failed, good, tau = regression_rows(
        params, res["loads"], res["inverse_dynamics"], em, geo
    )
    chans = tuple(groups)
    env = np.empty((em.envelopes.shape[0], len(chans)))
    for k, c in enumerate(chans):
        col = em.sources.index(c)
        env[:, k] = em.envelopes[:, col] * float(ref.value[ref.channels.index(c)])
    t = np.asarray(res["kinematics"].time, dtype=float)
    rate = (t.size - 1) / float(t[-1] - t[0])
    trial = PooledTrial(
        tc.name, "mvc" if tc.role == "mvc" else "task", rate, chans, env, geo.jacobian,
        np.asarray(geo.lengths), np.asarray(geo.velocities), np.asarray(tau),
        frames=np.flatnonzero(good), movement=None,
    )  # fmt: skip
    coords = tuple(res["inverse_dynamics"].torques.coordinate_names)
    said = list(getattr(em, "warnings", ()))
    checks = {g: [w for w in said if f"'{g}'" in w and "no MVC" not in w] for g in failed}
    return _Rows(trial, params, res["model"].model, groups, failed, coords, checks)


def run_pooled_strength(
    config: str | Path | SessionConfig,
    out_dir: str | Path,
    *,
    progress: TextIO | None = None,
) -> dict[str, Any]:
    """Identify the strength of the session's pooled trials (module docstring) and write
    ``strength.json`` and ``strength.txt`` into ``out_dir``; returns the JSON record."""
    from msk.pipeline.strength import _protocols
    from msk.strength import diagnose
    from msk.strength.pooled import identify_pooled

    cfg = config if isinstance(config, SessionConfig) else load_config(config)
    if not cfg.emg.channels:
        raise ConfigError(f"{cfg.path}: strength needs [emg] channels")
    trials = pooled_trials(cfg)
    ref = _reference(cfg, trials)
    rows = [_trial_rows(cfg, tc, ref, progress) for tc in trials]
    params, model, coords = rows[0].params, rows[0].model, rows[0].coordinates
    # a channel enters when it is usable in every pooled trial (one normalisation, one group)
    usable = set.intersection(*(set(r.groups) for r in rows))
    failed = {g: m for r in rows for g, m in r.failed.items()}
    failed.update({g: m for r in rows for g, m in r.groups.items() if g not in usable})
    channels = {m: g for g, ms in rows[0].groups.items() if g in usable for m in ms}
    pooled = []
    for r in rows:
        keep = [k for k, c in enumerate(r.trial.channels) if c in usable]
        pooled.append(
            dataclasses.replace(
                r.trial,
                channels=tuple(r.trial.channels[k] for k in keep),
                envelopes=r.trial.envelopes[:, keep],
            )
        )
    ref = _plateau_reference(cfg, ref, pooled)
    profile = identify_pooled(
        pooled, channels, params, coordinate_names=coords, reference=ref,
        window_s=cfg.strength.window_s, n_bootstrap=200, random_state=0,
    )  # fmt: skip
    groups = {g: [m for m, c in channels.items() if c == g] for g in profile.group_names}
    # every group's best isometric test (its maximal moment for an identified group, the next
    # protocol for one that is not)
    protos = _protocols(model, None, {**groups, **failed})
    diag = diagnose(profile)

    def moment(i: int, g: str, scale: float) -> float | None:
        p = protos.get(g)
        if diag[i].status != "identified" or not p:
            return None
        return _num(scale * float(p["group_moment_nm"]))

    record: dict[str, Any] = {
        "config": str(cfg.path),
        "trials": profile.extra["trials"],
        "normalisation": profile.extra["normalisation"],
        "normalisation_kind": profile.extra["normalisation_kind"],
        "normalisation_bias": profile.extra.get("normalisation_bias"),
        "reference_uncertainty": profile.extra.get("reference_uncertainty"),
        "fit_r2_all_rows": _num(profile.r2),
        "confidence": float(profile.confidence),
        "bounds": list(profile.bounds),
        "mass_kg": cfg.subject.mass_kg,
        "groups": [
            {
                "group": g,
                "muscles": groups[g],
                "factor": _num(profile.factors[i]),
                "ci_bootstrap": [_num(profile.ci_low[i]), _num(profile.ci_high[i])],
                "ci_jackknife_t": [_num(profile.ci_cov_low[i]), _num(profile.ci_cov_high[i])],
                "f_iso_generic_n": _num(profile.f_iso_generic[i]),
                "status": d.status,
                "reason": d.reason + _bias_clause(profile, g),
                "r2_own_rows": _num(d.r2),
                "own_coordinates": list(d.coordinates),
                "protocol": protos.get(g) if d.status != "identified" else None,
                "moment_nm": moment(i, g, profile.factors[i]),
                "moment_ci_nm": [moment(i, g, profile.ci_low[i]), moment(i, g, profile.ci_high[i])],
                "moment_test": _test_words(protos.get(g)) if d.status == "identified" else None,
            }
            for i, (g, d) in enumerate(zip(profile.group_names, diag))
        ],
        "failed_channels": {
            g: {
                "muscles": m,
                "failed_in": {
                    r.trial.name: r.checks.get(g) or ["the channel was excluded by the EMG checks"]
                    for r in rows
                    if g in r.failed
                },
                "protocol": protos.get(g),
            }
            for g, m in failed.items()
        },
    }
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "strength.json").write_text(json.dumps(record, indent=1) + "\n")
    lines = [profile.table(), ""]
    lines += [f"{d.group}: {d.status} — {d.reason}" for d in diag]
    for g, v in record["failed_channels"].items():
        lines += [f"{g}: left out, its EMG channel failed a check in {t}: {'; '.join(w)}"
                  for t, w in v["failed_in"].items()]  # fmt: skip
    lines.append(f"EMG normalisation: {record['normalisation_kind']}")
    if record["normalisation_bias"]:
        lines.append(record["normalisation_bias"])
    (out / "strength.txt").write_text("\n".join(lines) + "\n")
    return record


def _test_words(p: Any) -> str | None:
    """``"knee extension at knee flexion 60°"``: where a group's maximal moment is taken."""
    if not p:
        return None
    return f"{p['action']} at {p['angle_label']} {p['angle_deg']:g}°"


def pooled_summary(record: dict[str, Any]) -> Any:
    """The ``summary.json`` ``pooled_strength`` record
    (:class:`msk.results.summary.PooledStrength`) of :func:`run_pooled_strength`'s record."""
    from msk.results.summary import PooledStrength, StrengthGroup

    groups = tuple(
        StrengthGroup(
            group=g["group"], muscles=tuple(g["muscles"]), factor=g["factor"],
            ci_low=g["ci_bootstrap"][0], ci_high=g["ci_bootstrap"][1],
            ci_cov_low=g["ci_jackknife_t"][0], ci_cov_high=g["ci_jackknife_t"][1],
            f_iso_generic_n=g["f_iso_generic_n"],
            f_iso_n=None if g["status"] != "identified" or g["factor"] is None
            or g["f_iso_generic_n"] is None else g["factor"] * g["f_iso_generic_n"],
            status=g["status"], reason=g["reason"], r2=g["r2_own_rows"],
            r2_coordinates=tuple(g["own_coordinates"]), protocol=g["protocol"],
            moment_nm=g["moment_nm"], moment_low_nm=g["moment_ci_nm"][0],
            moment_high_nm=g["moment_ci_nm"][1], moment_test=g["moment_test"],
        )
        for g in record["groups"]
    )  # fmt: skip
    failed = tuple(
        StrengthGroup(
            group=g, muscles=tuple(v["muscles"]), status="not determined",
            reason="its EMG channel failed a check: " + "; ".join(
                f"{t}: {' '.join(w)}" for t, w in v["failed_in"].items()),
            protocol=v["protocol"],
        )
        for g, v in record["failed_channels"].items()
    )  # fmt: skip
    return PooledStrength(
        groups=groups, failed_channels=failed, r2=record["fit_r2_all_rows"],
        confidence=record["confidence"], bounds=tuple(record["bounds"]),
        method="the session's trials pooled (msk strength), one EMG normalisation",
        trials=tuple(record["trials"]), normalisation_kind=record["normalisation_kind"],
        normalisation_bias=record["normalisation_bias"], mass_kg=record["mass_kg"],
    )  # fmt: skip


def attach_to_session(folder: str | Path, record: dict[str, Any]) -> list[Path]:
    """Add :func:`pooled_summary` of ``record`` to the ``summary.json`` of every task trial
    ``msk run`` wrote under ``folder`` and rebuild the session's report (the strength section
    shows it); returns the summaries rewritten — none when ``folder`` holds no ``msk run``
    session. :class:`~msk.exceptions.ConfigError` when that session was run with another
    configuration (its ``config.sha256``)."""
    from msk.report import write_report
    from msk.results.folder import read_task_trials
    from msk.results.summary import Summary

    root = Path(folder)
    paths = (
        [root / "summary.json"]
        if (root / "summary.json").is_file()
        else sorted(p / "summary.json" for p in root.iterdir() if (p / "summary.json").is_file())
    )
    if not paths:
        return []
    part = pooled_summary(record).to_dict()
    cfg_file = Path(record["config"])
    sha = hashlib.sha256(cfg_file.read_bytes()).hexdigest() if cfg_file.is_file() else None
    for path in paths:
        d = json.loads(path.read_text(encoding="utf-8"))
        if d.get("kind") is not None or "format" not in d:
            return []  # not an msk run session summary (e.g. a dynamometry folder)
        theirs = (d.get("config") or {}).get("sha256")
        if sha is not None and theirs and theirs != sha:
            raise ConfigError(
                f"{path}: a session of another configuration "
                f"({(d.get('config') or {}).get('path')}), not {cfg_file}: pooled strength not "
                "added to it"
            )
        d["pooled_strength"] = part
        text = json.dumps(Summary.from_dict(d).to_dict(), indent=2, allow_nan=False)
        path.write_text(text + "\n", encoding="utf-8")
    parts = read_task_trials(root)
    # every report that reads these summaries (each trial's and the session's), a printed
    # copy rebuilt when the folder had one (never left stale)
    if len(parts) > 1:
        for p in parts:
            if p.path is not None:
                write_report(p, p.path, pdf=(p.path / "report.pdf").is_file())
    write_report(parts[0], root, trials=parts, pdf=(root / "report.pdf").is_file())
    return paths


def _bias_clause(profile: Any, group: str) -> str:
    """The normalisation caveat of a group whose channel is normalised to the session's peak."""
    norm = profile.extra.get("normalisation", {}).get(group, {})
    if norm.get("source") != "session_peak":
        return ""
    return (
        "; its EMG is normalised to the session's peak, not an MVC: the activations are too "
        "high, so the factor is low — a lower bound on the strength, by the ratio of the MVC "
        "to the session's peak"
    )


def _num(x: Any) -> float | None:
    v = float(x)
    return v if math.isfinite(v) else None
