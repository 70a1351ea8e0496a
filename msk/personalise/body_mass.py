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
4. otherwise a :class:`~msk.exceptions.ConfigError` says what was looked for.

A task trial's plates are not used: over a gait trial they measure only the stances on them.
The source is reported in ``summary.json`` ``subject.mass_source`` (and its details in
``subject.mass_detail``); a mass the configuration gives is then still checked against the
plates (the ``plate_mass_difference_pct`` flag).
"""

from __future__ import annotations

import dataclasses
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
        raise ConfigError(
            f"{cfg.path}: [subject] mass_kg is not given, no trial file stores the body mass "
            "(subject parameters) and no static trial has the subject standing still with "
            f"every foot on a plate (≥ {MIN_PLATES_LOADED} loaded plates): set "
            "subject.mass_kg"
        )
    lo, hi = _MASS_RANGE
    if not lo <= found.mass_kg <= hi:
        raise ConfigError(
            f"{cfg.path}: the body mass from {found.detail} is {found.mass_kg:.1f} kg, not a "
            f"plausible body mass ({lo:g}–{hi:g} kg): set subject.mass_kg"
        )
    subject = dataclasses.replace(cfg.subject, mass_kg=found.mass_kg)
    return dataclasses.replace(cfg, subject=subject), found
