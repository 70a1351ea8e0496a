"""The subject's body mass when the configuration does not give ``subject.mass_kg``.

The mass scales the model's segments and is the body weight of every ``_bw`` figure, so it is
needed before anything is computed. In order:

1. ``config``: ``[subject] mass_kg``;
2. ``c3d_parameters``: the body mass the lab stored in a trial file (Vicon
   ``PROCESSING:Bodymass``, ``SUBJECTS:WEIGHT``/``MASS``: :class:`msk.trial.Subject`), the
   static trial's first, then the task trial's;
3. ``static_plates``: the plates weighing the subject standing still on them — the static
   trial's still, double-stance window (:func:`msk.personalise.static_window.still_window`) — by the
   static balance of the whole body, Σ_plates F·up = m g (the COM's vertical acceleration
   averages to zero over a still window; frame by frame the sway moves the sum by its SD,
   0.26 kg = 0.4 % on the Grand Challenge's ``jw_1legstand1``):

       m̂ = mean over the window of Σ_k F_k(t)·up / g₀,  g₀ = 9.80665 m/s².

   Only when every foot stands on a plate: the window must hold at least
   :data:`MIN_PLATES_LOADED` loaded plates (the still window's own plate count, a plate
   carrying ≥ 5 % of the load) — or a single plate carrying both feet, which the plates cannot
   tell from one foot on a plate and one off it, so one loaded plate is refused;
4. ``task_plates``: a walking trial whose plates catch two consecutive stances of the two feet
   whole (the second foot strikes while the first stands: double support), by the vertical
   momentum of steady walking, periodic over a stride T: the vertical impulse over a stride
   is m g T, and a stride holds one stance of each foot, so ::

       m̂ = (I₁ + I₂) / (g T),   I_k = ∫ F_k·up dt over stance k,   T = 2 (s₂ − s₁)

   (:func:`body_mass_from_task_plates`; s_k the stances' heel strikes, T two step times; the
   mean over every such pair of the trial, which averages a left–right step asymmetry). On the
   shared walks: Plug-in Gait 72.5 kg (file: 74), UNIPD Walking1 83.5 kg (the whole-body
   Newton balance with the kinematics: 83.3), Grand Challenge JW 66.5 kg (single-leg
   stance: 65.7); the mean force over the loaded span, m̂ = mean ΣF / g, gave 68.0, 76.4 and
   60.3 (the span holds single-support time with the other foot off the plates);
5. otherwise a :class:`~msk.exceptions.ConfigError` says what was looked for.

The source is reported in ``summary.json`` ``subject.mass_source`` (and its details in
``subject.mass_detail``); a mass the configuration gives is then still checked against the
plates (the ``plate_mass_difference_pct`` flag).
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from msk.config import SessionConfig
from msk.exceptions import ConfigError, MskError

__all__ = [
    "G0",
    "MIN_PLATES_LOADED",
    "BodyMass",
    "body_mass_from_static_plates",
    "body_mass_from_task_plates",
    "resolve_body_mass",
]

#: standard gravity (m/s²)
G0 = 9.80665
#: plates that must be loaded in the still window for the plates to weigh the whole body
MIN_PLATES_LOADED = 2
#: plausible adult/child body mass (kg), the configuration's own range
_MASS_RANGE = (20.0, 300.0)


@dataclass(frozen=True)
class BodyMass:
    """The body mass used (kg), where it comes from (``config``, ``c3d_parameters``,
    ``static_plates``) and a readable detail (file, window, plates)."""

    mass_kg: float
    source: str
    detail: str

    def summary(self) -> dict[str, Any]:
        return {"mass_source": self.source, "mass_detail": self.detail}


def body_mass_from_static_plates(trial: Any) -> tuple[float, str] | None:
    """``(m̂, detail)`` of a static trial's plates over its still window (module docstring,
    item 3), or None when the trial has no plates, no still window or fewer than
    :data:`MIN_PLATES_LOADED` loaded plates."""
    from msk.io.c3d import is_measured_marker
    from msk.model.markersets import zeros_as_gaps
    from msk.personalise.static_window import still_window

    if not trial.plates or not np.size(trial.analog_time):
        return None
    up = np.asarray(trial.up, dtype=float)
    loads = np.stack(
        [
            np.interp(trial.time, trial.analog_time, np.asarray(p.force, float) @ up)
            for p in trial.plates
        ],
        axis=1,
    )
    keep = [i for i, lab in enumerate(trial.marker_labels) if is_measured_marker(lab)]
    try:
        window = still_window(zeros_as_gaps(trial.markers)[:, keep], trial.time, plate_loads=loads)
    except MskError:
        return None
    if window.plates is None or window.plates < MIN_PLATES_LOADED:
        return None
    total = np.nansum(loads[window.frames], axis=1)
    if total.size == 0 or not np.isfinite(total).all():
        return None
    mass = float(np.mean(total) / G0)
    detail = (
        f"{Path(trial.path).name}: mean vertical force of {window.plates} loaded plates / g over "
        f"its still window {window.start_s:.2f}–{window.end_s:.2f} s "
        f"({window.stop - window.first} frames; SD {np.std(total) / G0:.2f} kg)"
    )
    return mass, detail


#: a plate is loaded above this vertical force (N); a stance is a loaded interval of one plate
#: that starts and ends inside the trial, lasts at least :data:`_MIN_STANCE_S` and peaks at half
#: the largest plate peak of the trial or more (a foot wholly on the plate)
_STANCE_N = 20.0
_MIN_STANCE_S = 0.3
#: consecutive stances of the two feet: the second starts and ends this much after the first
#: (a foot straddling two plates loads both at once)
_MIN_STEP_S = 0.2


def _stances(trial: Any) -> list[tuple[float, float, float]]:
    """(start s, end s, vertical impulse N·s) of every whole stance on one plate, by start."""
    up = np.asarray(trial.up, dtype=float)
    loads = [np.nan_to_num(np.asarray(p.force, dtype=float) @ up) for p in trial.plates]
    top = max((float(f.max()) for f in loads if f.size), default=0.0)
    out = []
    for p, fz in zip(trial.plates, loads, strict=True):
        rate = float(p.rate_hz)
        on = np.concatenate([[0], (fz > _STANCE_N).astype(np.int8), [0]])
        d = np.diff(on)
        for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=True):
            if a == 0 or b >= fz.size or (b - a) / rate < _MIN_STANCE_S:
                continue  # cut by the trial's ends, or a touch
            if fz[a:b].max() < 0.5 * top:
                continue  # part of a foot on the plate
            out.append((a / rate, b / rate, float(fz[a:b].sum()) / rate))
    return sorted(out)


def body_mass_from_task_plates(trial: Any) -> tuple[float, str] | None:
    """``(m̂, detail)`` of a walking trial's plates (module docstring, item 4), or None when
    no two consecutive stances of the two feet are wholly on plates."""
    if not getattr(trial, "plates", None):
        return None
    st = _stances(trial)
    est = [
        (i1 + i2) / (G0 * 2.0 * (s2 - s1))
        for (s1, e1, i1), (s2, e2, i2) in itertools.pairwise(st)
        if s1 + _MIN_STEP_S <= s2 < e1 and e2 >= e1 + _MIN_STEP_S
    ]
    if not est:
        return None
    mass = float(np.mean(est))
    detail = (
        f"{Path(trial.path).name}: vertical impulse of {len(est)} pair(s) of consecutive whole "
        f"stances / (g × stride), stride = two step times (per pair: "
        f"{', '.join(f'{m:.1f}' for m in est)} kg)"
    )
    return mass, detail


def resolve_body_mass(cfg: SessionConfig) -> tuple[SessionConfig, BodyMass]:
    """``cfg`` with ``subject.mass_kg`` set, and where that mass comes from (module docstring).

    Raises:
        ConfigError: no mass in the configuration, the trial files nor the static's plates,
            or a found mass outside 20–300 kg (names the source).
    """
    given = cfg.subject.mass_kg
    if given is not None:
        return cfg, BodyMass(float(given), "config", f"{cfg.path}: [subject] mass_kg")
    from msk.io import read_trial

    roles = ("static", "task", "fes", "mvc", "mass_identification")
    trials = [tc for role in roles for tc in cfg.trials_with_role(role)]
    read: dict[Path, Any] = {}
    found: BodyMass | None = None
    for tc in trials:
        try:
            tr = read.setdefault(tc.file, read_trial(tc.file))
        except MskError:
            continue  # the stage that reads it reports it
        m = tr.subject.mass_kg
        if m is not None and np.isfinite(m) and m > 0:
            found = BodyMass(float(m), "c3d_parameters", f"{tc.file.name}: subject parameters")
            break
    if found is None:
        for tc in cfg.trials_with_role("static"):
            tr = read.get(tc.file)
            got = None if tr is None else body_mass_from_static_plates(tr)
            if got is not None:
                found = BodyMass(got[0], "static_plates", got[1])
                break
    if found is None:
        for tc in cfg.trials_with_role("task"):
            tr = read.get(tc.file)
            got = None if tr is None else body_mass_from_task_plates(tr)
            if got is not None:
                found = BodyMass(got[0], "task_plates", got[1])
                break
    if found is None:
        raise ConfigError(
            f"{cfg.path}: [subject] mass_kg is not given, no trial file stores the body mass "
            "(subject parameters), no static trial has the subject standing still with "
            f"every foot on a plate (≥ {MIN_PLATES_LOADED} loaded plates) and no task's plates "
            "hold two consecutive whole stances of the two feet: set subject.mass_kg"
        )
    lo, hi = _MASS_RANGE
    if not lo <= found.mass_kg <= hi:
        raise ConfigError(
            f"{cfg.path}: the body mass from {found.detail} is {found.mass_kg:.1f} kg, not a "
            f"plausible body mass ({lo:g}–{hi:g} kg): set subject.mass_kg"
        )
    subject = dataclasses.replace(cfg.subject, mass_kg=found.mass_kg)
    return dataclasses.replace(cfg, subject=subject), found
