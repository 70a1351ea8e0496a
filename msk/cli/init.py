"""``msk init TRIAL... --out session.toml``: a first session configuration for a lab's own
recordings, every guessed value commented.

The trials are read (:func:`msk.io.read_trial`); a static trial is the one whose name says so
(``static``, ``cal``…) or, else, the one whose markers stay still (the median marker's path
spans less than :data:`STILL_SPAN_M`); the others are tasks. Their marker and analog labels
are matched to the model as ``msk info`` matches them (:func:`msk.cli.info.recognition`): the
``[markers] rename`` table, the ``[emg] channels`` suggestions, with a "did you mean" for an
analog label close to a muscle name. The mass and height come from the C3D's subject
parameters when stored; else ``mass_kg`` is left out when the run can weigh the subject on the
static trial's plates or on two consecutive whole stances of the task's
(:mod:`msk.personalise.body_mass`), else the task's plates' mean loaded force gives it. The side
of interest comes from the sides the EMG channels name. The written configuration runs with
``msk run`` as it is; its comments say what to check.
"""

from __future__ import annotations

import argparse
import difflib
import json
import os
import re
import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from msk.cli import Command

__all__ = ["COMMANDS", "STILL_SPAN_M", "starter_config", "task_plate_mass"]

#: a trial whose median marker moves less than this (m, largest extent of its path) is still
STILL_SPAN_M = 0.15
_STATIC_NAME = re.compile(r"static|standing|calib|^cal|neutral", re.IGNORECASE)
#: model markers on the feet: ``move``d to the static's positions (a lab's foot markers sit
#: where its protocol puts them, rarely where the generic model's do)
_FOOT_BODIES = ("calcn_r", "calcn_l", "toes_r", "toes_l")


def _still_span(markers: np.ndarray) -> float:
    """The median over markers of the largest extent (m) of each one's path."""
    x = np.asarray(markers, dtype=float)
    if x.size == 0:
        return 0.0
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        ext = np.nanmax(x, axis=0) - np.nanmin(x, axis=0)  # (M, 3)
        spans = np.nanmax(ext, axis=1)
    spans = spans[np.isfinite(spans)]
    return float(np.median(spans)) if spans.size else 0.0


def task_plate_mass(
    trial: Any, *, g: float = 9.80665, min_s: float = 0.5
) -> tuple[float, float] | None:
    """(mass kg, seconds) the plates weigh the subject at over the longest span in which
    their summed vertical force stays loaded (above 5 % of its peak: every foot on a plate),
    m̂ = mean ΣF_z / g — the whole-body vertical balance with the momentum at both ends
    alike (heel strike to toe off); None without such a span of ``min_s``."""
    if not trial.plates:
        return None
    up = np.asarray(trial.up, dtype=float)
    fz = sum(np.nan_to_num(np.asarray(p.force, dtype=float) @ up) for p in trial.plates)
    fz = np.asarray(fz, dtype=float)
    top = float(fz.max()) if fz.size else 0.0
    if not top > 100.0:
        return None
    on = np.concatenate([[0], (fz > 0.05 * top).astype(np.int8), [0]])
    d = np.diff(on)
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    k = int(np.argmax(ends - starts))
    rate = float(trial.plates[0].rate_hz)
    span = (ends[k] - starts[k]) / rate
    if span < min_s:
        return None
    return float(np.mean(fz[starts[k] : ends[k]])) / g, span


def _static_mass(trial: Any) -> float | None:
    """The mass (kg) the run would weigh on this static's plates
    (:func:`msk.personalise.body_mass.body_mass_from_static_plates`: a still window with every
    foot on a plate), None when they cannot weigh the subject."""
    from msk.personalise.body_mass import body_mass_from_static_plates

    got = body_mass_from_static_plates(trial)
    return None if got is None or not 20.0 <= got[0] <= 300.0 else got[0]


def _stride_mass(trial: Any) -> float | None:
    """The mass (kg) the run would weigh on this task's plates
    (:func:`msk.personalise.body_mass.body_mass_from_task_plates`), None when they cannot."""
    from msk.personalise.body_mass import body_mass_from_task_plates

    got = body_mass_from_task_plates(trial)
    return None if got is None or not 20.0 <= got[0] <= 300.0 else got[0]


def _name(path: Path, taken: set[str]) -> str:
    base = re.sub(r"[^A-Za-z0-9._-]+", "_", path.stem).strip("._-") or "trial"
    name, k = base, 2
    while name in taken:
        name, k = f"{base}_{k}", k + 1
    taken.add(name)
    return name


def _rel(path: Path, out_dir: Path) -> str:
    try:
        return Path(os.path.relpath(path.resolve(), out_dir.resolve())).as_posix()
    except ValueError:  # another drive (Windows)
        return path.resolve().as_posix()


def starter_config(
    files: list[Path],
    out: Path,
    *,
    static: Path | None = None,
    model_name: str = "gait2392",
) -> str:
    """The text of a session configuration for ``files`` (module docstring), with paths
    relative to the folder of ``out``."""
    from msk.cli.info import flat_channels, inline_table, recognition
    from msk.exceptions import ConfigError
    from msk.io import read_trial

    trials = [(Path(f), read_trial(f)) for f in files]
    if static is not None:
        trials.insert(0, (Path(static), read_trial(static)))
    why: dict[Path, str] = {}
    roles: dict[Path, str] = {}
    for f, tr in trials:
        if static is not None:
            roles[f] = "static" if f == Path(static) else "task"
            why[f] = "given with --static" if f == Path(static) else "not the static"
            continue
        span = _still_span(tr.markers)
        if _STATIC_NAME.search(f.stem):
            roles[f], why[f] = "static", "its name says static"
        elif span < STILL_SPAN_M and tr.markers.size:
            roles[f] = "static"
            why[f] = f"its markers stay within {100 * span:.0f} cm"
        else:
            roles[f], why[f] = "task", f"its markers move {span:.2f} m"
    statics = [f for f, _ in trials if roles[f] == "static"]
    for extra in statics[1:]:  # one static: the first; the others are tasks
        roles[extra], why[extra] = "task", "a second still trial, kept as a task"
    tasks = [(f, tr) for f, tr in trials if roles[f] == "task"]
    if not tasks:
        raise ConfigError(
            f"{', '.join(str(f) for f, _ in trials)}: every trial looks still (a static): "
            "give at least one task trial (walking, a squat…)"
        )
    task_file, task = tasks[0]
    plate_ch = {c for p in task.plates for c in p.channels}
    others = [k for k, lab in enumerate(task.analog_labels) if lab not in plate_ch]
    labs = [task.analog_labels[k] for k in others]
    units = [task.analog_units[k] for k in others] if task.analog_units else [""] * len(labs)
    analogs = np.asarray(task.analogs[:, others]) if others else np.zeros((0, 0))
    flat = flat_channels(analogs, labs, units) if others else {}
    # the static holds every marker (a task often drops the knee and ankle markers): the
    # marker labels are recognised on it when there is one
    ref = next((tr for f, tr in trials if roles[f] == "static"), task)
    rec = recognition(ref.marker_labels, ref.markers, labs, flat, model_name=model_name)
    match, model = rec.match, rec.model
    out_dir = Path(out).parent

    # --- subject
    subj_src = next((tr.subject for _, tr in trials if tr.subject.mass_kg), task.subject)
    name = next((tr.subject.name for _, tr in trials if tr.subject.name), None)
    sides = [m.rsplit("_", 1)[-1] for m, lab in rec.channels.items() if rec.emg[lab][1]]
    n_l, n_r = sides.count("l"), sides.count("r")
    side = "left" if n_l > n_r else "right"
    side_why = (
        f"the EMG channels name the {side} leg ({max(n_l, n_r)} of {len(sides)})"
        if sides
        else "a guess: no EMG channel names a side; set the leg of interest"
    )
    unsided = [lab for lab in rec.channels.values() if not rec.emg[lab][1]]
    lines = [
        f"# msk session written by `msk init` from {', '.join(f.name for f, _ in trials)}.",
        "# Every guessed value is commented: check them, then `msk run THIS.toml --out DIR`.",
        "# Keys and defaults: `msk print-config`; paths are relative to this file.",
        "",
        "[subject]",
        f"name = {json.dumps(name or task_file.stem)}"
        + ("  # from the C3D's subject parameters" if name else "  # the task file's name"),
    ]
    mass = subj_src.mass_kg
    if mass is not None and 20.0 <= mass <= 300.0:
        lines.append(f"mass_kg = {mass:.1f}  # from the C3D's subject parameters (Bodymass)")
    elif (
        static_mass := next(
            (got for f, tr in trials if roles[f] == "static" and (got := _static_mass(tr))),
            None,
        )
    ) is not None:
        lines.append(
            f"# mass_kg: not stored in the files: the run weighs the subject on the static "
            f"trial's plates ({static_mass:.1f} kg; summary.json subject.mass_source says so)"
        )
    elif (
        strides := next((got for _, tr in tasks if (got := _stride_mass(tr)) is not None), None)
    ) is not None:
        lines.append(
            f"# mass_kg: not stored in the files: the run weighs the subject on the task's "
            f"plates ({strides:.1f} kg: the vertical impulse of two consecutive whole stances "
            "over a stride; summary.json subject.mass_source says so)"
        )
    elif (weighed := task_plate_mass(task)) is not None and 20.0 <= weighed[0] <= 300.0:
        lines.append(
            f"mass_kg = {weighed[0]:.1f}  # not stored in the files: the task's plates weigh "
            f"the subject over the {weighed[1]:.2f} s its feet stand on them (mean vertical "
            "force / g); the run flags a difference above 5 %"
        )
    else:
        lines.append(
            "# mass_kg = ...  # not stored in the files and no plate weighs the subject: set it"
        )
    h = subj_src.height_m
    if h is not None and 0.5 <= h <= 2.5:
        lines.append(f"height_m = {h:.3f}  # from the C3D's subject parameters")
    lines += [
        'sex = "male"  # a guess: picks the anthropometric table rows',
        f'side = "{side}"  # {side_why}',
        "",
        "[model]",
        f'source = "{model_name}"',
        "",
    ]
    # --- trials
    taken: set[str] = set()
    for f, tr in trials:
        role = roles[f]
        lines += [
            "[[trials]]",
            f'name = "{_name(f, taken)}"',
            f"file = {json.dumps(_rel(f, out_dir))}",
            f'role = "{role}"  # {why[f]}',
        ]
        if role == "task":
            ev = [e for e in tr.events if e.label in ("Foot Strike", "Foot Off")]
            lines.append(
                f"# {tr.n_frames} frames at {tr.point_rate_hz:g} Hz, {len(tr.plates)} force "
                f"plate(s), {len(ev)} gait event(s) in the file"
                + ("" if ev else " (msk finds them from the plates and the kinematics)")
            )
            if f.suffix.lower() == ".trc":
                lines.append('# a .trc task needs its ground reactions: grf = "….mot"')
        lines.append("")
    # --- markers
    lines.append("[markers]")
    lines.append(
        f"# marker set: {match.protocol}; {len(match.rename)} of {len(model.marker_names)} "
        f"{model_name} markers recognised (model marker = lab label; identical names are "
        "paired without a line here)"
    )
    lines.append(f"rename = {inline_table(rec.rename)}")
    if match.unmatched_model:
        lines.append(f"# {model_name} markers no label names: {', '.join(match.unmatched_model)}")
    kept = [lab for lab in ref.marker_labels if lab in match.unmatched_lab]
    if kept:
        lines.append(
            f"# labels no {model_name} marker names, kept and placed from the static: "
            + ", ".join(kept)
        )
    by_reason: dict[str, list[str]] = {}
    for lab, reason in match.excluded.items():
        by_reason.setdefault(str(reason), []).append(lab)
    for reason, group in by_reason.items():
        lines.append(f"# not used ({reason}): {', '.join(group)}")
    for note in match.notes:
        lines.append(f"# note: {note}")
    body = {m.name: m.body for m in model.markers}
    foot = [mk for mk in match.rename if body.get(mk) in _FOOT_BODIES]
    # a foot's markers are moved together, when at least 3 of them define where the foot is
    # (one heel marker moved alone turns the foot about the others: the ankle at its bound)
    sided = {s: [mk for mk in foot if str(body[mk]).endswith(s)] for s in ("_r", "_l")}
    foot = [mk for mk in foot if len(sided[str(body[mk])[-2:]]) >= 3]
    if statics and foot:
        lines.append(
            "# the foot markers sit where the lab's protocol puts them, rarely where the "
            "generic model's do: moved to their static-trial positions on the scaled feet "
            "(a foot with 3 recognised markers or more)"
        )
        lines.append(f"move = {json.dumps(foot)}")
    lines.append("")
    # --- EMG
    muscles = [m.name for m in model.muscles]
    unknown = [lab for lab in labs if lab not in rec.emg and lab not in flat]
    if rec.channels or unknown:
        lines.append("[emg]")
        lines.append("# model muscle = analog channel (guessed from the channel names: check)")
        if unsided:
            lines.append(
                f"# {len(unsided)} channel label(s) name no side: the right leg's muscles "
                "assumed; for EMG on the left leg write _l for _r"
            )
        lines.append(f"channels = {inline_table(rec.channels)}")
        for lab in labs:
            if lab in rec.emg and lab in flat:
                lines.append(f"# {lab} -> {rec.emg[lab][0]} left out: flat or unused ({flat[lab]})")
        for lab in unknown:
            key = re.sub(r"[^a-z]+", "_", lab.lower()).strip("_")
            close = difflib.get_close_matches(key, muscles, n=2, cutoff=0.6)
            hint = f" (did you mean {' or '.join(close)}?)" if close else ""
            lines.append(f"# analog channel {lab!r} names no {model_name} muscle{hint}")
        lines.append("")
    return "\n".join(lines) + "\n"


def _init_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("files", nargs="+", metavar="TRIAL", type=Path,
                   help="the session's recordings (.c3d, a static may be .trc)")  # fmt: skip
    p.add_argument("--out", required=True, type=Path, metavar="FILE",
                   help="the session configuration to write (.toml)")  # fmt: skip
    p.add_argument("--static", type=Path, metavar="FILE", help="the static trial (else guessed)")
    p.add_argument("--model", default="gait2392", help="a shipped model (default gait2392)")
    p.add_argument("--force", action="store_true", help="overwrite an existing FILE")


def _init(args: argparse.Namespace) -> int:
    from msk.exceptions import ConfigError

    out: Path = args.out
    if out.exists() and not args.force:
        raise ConfigError(f"{out}: exists (give --force to overwrite it)")
    text = starter_config(list(args.files), out, static=args.static, model_name=args.model)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, out)
    sys.stdout.write(f"{out}\n")
    return 0


COMMANDS = (
    Command("init", "write a first session configuration for your recordings (every guess "
            "commented)", _init_args, _init),
)  # fmt: skip
