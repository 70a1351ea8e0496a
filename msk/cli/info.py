"""``msk info FILE``: what a .c3d/.trc/.mot/.sto file holds (rates, markers and gaps, analog
channels with the flat or unused ones, plates, events, subject), which marker labels msk
recognises as which marker of the shipped gait2392 model, the EMG channels that name a muscle,
and the ``[markers]`` / ``[emg]`` tables a session configuration would start from."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from msk._runtime.terminal import terminal_safe
from msk.cli import Command

__all__ = [
    "COMMANDS",
    "Recognition",
    "flat_channels",
    "inline_table",
    "recognition",
    "write_recognition",
]

#: the model ``msk info`` recognises labels against (a session's default model)
INFO_MODEL = "gait2392"


def flat_channels(
    analogs: np.ndarray, labels: Sequence[str], units: Sequence[str], *, rel_std: float = 0.03
) -> dict[str, str]:
    """Channels that look flat or unused, with the reason.

    All NaN, all zero, at most three distinct values, or a standard deviation below ``rel_std``
    times the median standard deviation of the channels with the same unit (a channel at the
    amplifier's noise floor next to live EMG).
    """
    out: dict[str, str] = {}
    if analogs.size == 0:
        return out
    std = np.array([np.nanstd(c) if np.isfinite(c).any() else np.nan for c in analogs.T])
    for k, lab in enumerate(labels):
        col = analogs[:, k]
        fin = col[np.isfinite(col)]
        if fin.size == 0:
            out[lab] = "all NaN"
        elif not fin.any():
            out[lab] = "all zero"
        elif np.unique(fin).size <= 3:
            out[lab] = f"{np.unique(fin).size} distinct values"
        else:
            same = [j for j, u in enumerate(units) if u == units[k] and np.isfinite(std[j])]
            med = float(np.median(std[same])) if len(same) >= 3 else float("nan")
            if np.isfinite(med) and med > 0 and std[k] < rel_std * med:
                out[lab] = f"std {std[k]:.3g} {units[k]} is {100 * std[k] / med:.1f}% of median"
    return out


@dataclass(frozen=True)
class Recognition:
    """What msk recognises in a trial's labels: the marker-set match
    (:func:`msk.model.markersets.recognise`) against the model ``model_name``, the EMG channels
    naming one of its muscles (:func:`msk.muscles.emg.suggest_channels`: label → (muscle,
    whether the label names the side)), the ``[markers] rename`` pairs (model marker → lab
    label, the identical ones left out: msk pairs those itself) and the ``[emg] channels``
    pairs (muscle → label, flat channels left out)."""

    model_name: str
    model: Any
    match: Any
    emg: dict[str, tuple[str, bool]]
    rename: dict[str, str]
    channels: dict[str, str]


def recognition(
    labels: Sequence[str],
    markers: np.ndarray | None,
    analog_labels: Sequence[str],
    flat: dict[str, str],
    *,
    model_name: str = INFO_MODEL,
) -> Recognition:
    """:class:`Recognition` of a trial's marker and analog labels against ``model_name``."""
    from msk.model.files import load_model
    from msk.model.markersets import recognise, zeros_as_gaps
    from msk.muscles.emg import suggest_channels

    model = load_model(model_name)
    data = zeros_as_gaps(markers) if markers is not None and markers.size else None
    match = recognise(
        labels, model.marker_names, model_bodies=[b.name for b in model.bodies], markers=data
    )
    emg = suggest_channels(analog_labels, [m.name for m in model.muscles])
    rename = {mk: lab for mk, lab in match.rename.items() if mk != lab}
    usable = {muscle: lab for lab, (muscle, _) in emg.items() if lab not in flat}
    return Recognition(model_name, model, match, emg, rename, usable)


def write_recognition(
    labels: Sequence[str],
    markers: np.ndarray | None,
    analog_labels: Sequence[str],
    flat: dict[str, str],
    w: Callable[[str], object],
    *,
    model_name: str = INFO_MODEL,
) -> None:
    """Write which marker labels :func:`msk.model.markersets.recognise` pairs with which marker
    of the shipped model ``model_name``, the analog channels that name a muscle
    (:func:`msk.muscles.emg.suggest_channels`) and the ``[markers] rename`` / ``[emg] channels``
    tables a session configuration would start from (:func:`recognition`; ``msk init`` writes
    the whole configuration)."""
    rec = recognition(labels, markers, analog_labels, flat, model_name=model_name)
    match, model = rec.match, rec.model
    to_model = match.lab_to_model
    w(
        f"marker set: {match.protocol}; {len(match.rename)} of {len(model.marker_names)} "
        f"{model_name} markers recognised\n"
    )
    for lab in labels:
        if lab in to_model:
            w(f"  {lab} -> {to_model[lab]}\n")
        elif lab in match.excluded:
            w(f"  {lab}  (not used: {match.excluded[lab]})\n")
        else:
            w(f"  {lab}  (no {model_name} marker: kept for marker placement)\n")
    if match.unmatched_model:
        w(f"  {model_name} markers no label names: {', '.join(match.unmatched_model)}\n")
    for note in match.notes:
        w(f"  note: {note}\n")
    w(f"EMG channels naming a muscle: {len(rec.emg)}\n")
    for lab, (muscle, sided) in rec.emg.items():
        side = "" if sided else "  (the label names no side: right assumed)"
        state = f"  FLAT/UNUSED? ({flat[lab]})" if lab in flat else ""
        w(f"  {lab} -> {muscle}{side}{state}\n")
    w("suggested session configuration (check every pair; msk pairs the marker labels itself;"
      " msk init writes a whole one):\n")  # fmt: skip
    w("  [model]\n")
    w(f'  source = "{model_name}"\n')
    w("  [markers]\n")
    w(f"  rename = {inline_table(rec.rename)}\n")
    w("  [emg]\n")
    w(f"  channels = {inline_table(rec.channels)}\n")


def inline_table(pairs: dict[str, str]) -> str:
    """A TOML inline table (keys quoted: model marker names hold dots)."""
    return "{ " + ", ".join(f"{json.dumps(k)} = {json.dumps(v)}" for k, v in pairs.items()) + " }"


def _info_c3d(path: Path, out: TextIO) -> None:
    from msk.io.c3d import read_c3d

    tr = read_c3d(path)

    def w(text: str) -> None:
        # labels, events and names come from the file: no control character reaches the
        # terminal (msk._runtime.terminal), and one line stays one line
        body, end = (text[:-1], "\n") if text.endswith("\n") else (text, "")
        out.write(terminal_safe(body) + end)

    w(f"file: {path}\n")
    t0 = tr.time[0] if tr.n_frames else 0.0
    w(
        f"points: {tr.point_rate_hz:g} Hz, {tr.n_frames} frames, {tr.duration_s:.3f} s "
        f"(first frame {tr.metadata.get('first_frame', 0)}, t0 {t0:.3f} s), "
        f"units in file {tr.point_units_in_file or '-'}\n"
    )
    sign = "+" if tr.up[tr.vertical_axis] > 0 else "-"
    w(f"lab vertical axis: {sign}{'XYZ'[tr.vertical_axis]}\n")
    gapped = tr.gaps.with_gaps()
    w(f"markers: {len(tr.marker_labels)} ({len(gapped)} with gaps)\n")
    for lab in gapped:
        k = tr.gaps.labels.index(lab)
        w(f"  gap {lab}: {tr.gaps.n_missing[k]} missing frames, longest {tr.gaps.longest_gap[k]}\n")
    mo = tr.model_outputs
    if mo.labels:
        kinds = {k: mo.kinds.count(k) for k in dict.fromkeys(mo.kinds)}
        w(f"model outputs: {len(mo.labels)} ({', '.join(f'{k} {n}' for k, n in kinds.items())})\n")
    plate_ch = {c for p in tr.plates for c in p.channels}
    others = [k for k, lab in enumerate(tr.analog_labels) if lab not in plate_ch]
    w(
        f"analogs: {len(tr.analog_labels)} channels at {tr.analog_rate_hz:g} Hz "
        f"({len(plate_ch)} force-plate, {len(others)} other)\n"
    )
    labs = [tr.analog_labels[k] for k in others]
    units = [tr.analog_units[k] for k in others]
    flat = flat_channels(tr.analogs[:, others], labs, units)
    for lab, u in zip(labs, units):
        note = f"  FLAT/UNUSED? ({flat[lab]})" if lab in flat else ""
        w(f"  {lab} [{u or '-'}]{note}\n")
    w(f"force platforms: {len(tr.plates)}\n")
    for p in tr.plates:
        w(f"  plate {p.index + 1}: type {p.type}, peak force {p.peak_force_n:.1f} N\n")
    w(f"events: {len(tr.events)}\n")
    for e in tr.events:
        w(f"  {e.time:.3f} s  {e.context} {e.label}\n".replace("  \n", "\n"))
    s = tr.subject
    parts = []
    if s.name:
        parts.append(f"name {s.name}")
    if s.mass_kg is not None:
        parts.append(f"mass {s.mass_kg:g} kg")
    if s.height_m is not None:
        parts.append(f"height {s.height_m:g} m")
    w(f"subject: {', '.join(parts) if parts else '-'}\n")
    notes = list((tr.metadata or {}).get("warnings", ()))
    w(f"reader warnings: {len(notes)}\n")
    for note in notes:  # duplicate labels renamed, NaN plate samples, …
        w(f"  {' '.join(str(note).split())}\n")
    write_recognition(tr.marker_labels, tr.markers, labs, flat, w)


def _info_text(path: Path, out: TextIO) -> None:
    from msk.io.opensim_files import read_sto, read_trc

    w = out.write
    w(f"file: {path}\n")
    if path.suffix.lower() == ".trc":
        m = read_trc(path)
        n = m.time.size
        dur = (m.time[-1] - m.time[0]) if n > 1 else 0.0
        w(
            f"rate: {m.rate_hz:g} Hz, {n} frames, duration {dur:.3f} s, "
            f"units in file {m.units_in_file}\n"
        )
        miss = np.isnan(m.markers).any(axis=2).sum(axis=0)
        w(f"markers: {len(m.labels)} ({int((miss > 0).sum())} with gaps)\n")
        for lab, k in zip(m.labels, miss):
            w(f"  {lab}{f'  ({k} missing frames)' if k else ''}\n")
        write_recognition(m.labels, m.markers, (), {}, w)
        return
    t = read_sto(path)
    n = t.time.size
    dur = (t.time[-1] - t.time[0]) if n > 1 else 0.0
    w(f"rate: {t.rate_hz:.6g} Hz, {n} rows, duration {dur:.3f} s\n")
    w(f"inDegrees in file: {'yes' if t.in_degrees_in_file else 'no'}")
    w(f" ({len(t.angle_columns)} angle columns converted to rad)\n")
    w(f"columns: {len(t.columns)}\n")
    for c in t.columns:
        w(f"  {c}\n")


def _info_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", metavar="FILE", type=Path, help=".c3d, .trc, .mot or .sto file")


def _info(args: argparse.Namespace) -> int:
    path: Path = args.file
    if path.suffix.lower() in (".trc", ".mot", ".sto"):
        _info_text(path, sys.stdout)
    else:
        _info_c3d(path, sys.stdout)
    return 0


COMMANDS = (Command("info", "summarise a .c3d/.trc/.mot/.sto file", _info_arguments, _info),)
