"""The gait analysis of one task trial: its normalised cycles (:mod:`msk.gait.cycles`, with the
variables of :mod:`msk.gait.variables`) and its spatiotemporal parameters
(:mod:`msk.gait.spatiotemporal`), from the gait events, the kinematics, the joint torques and
the ground reactions; and the ``summary.json`` ``gait`` section of them
(:class:`msk.results.summary.Gait`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from msk.gait.cycles import SIDES, GaitCycles
from msk.gait.spatiotemporal import Spatiotemporal, spatiotemporal, surface_velocity
from msk.gait.variables import GaitVariables, gait_cycles, segment_poses
from msk.units import Array

__all__ = ["GaitAnalysis", "analyse_gait"]


@dataclass(frozen=True)
class GaitAnalysis:
    """The cycles, the spatiotemporal parameters, and what the variables are (the knee
    adduction moment's method, the variables the model has no degree of freedom for);
    ``treadmill_speed_m_s``: the belt speed found (0 overground,
    :func:`msk.gait.spatiotemporal.surface_velocity`)."""

    cycles: GaitCycles
    spatiotemporal: Spatiotemporal
    variables: GaitVariables
    treadmill_speed_m_s: float = 0.0

    def pelvis_tilt_deg(self) -> tuple[Array | None, str]:
        """The reported pelvis tilt of every cycle of both sides (deg, flattened; None without
        cycles) and the frame it is in (the cycles' notes)."""
        c = self.cycles
        if "pelvis_tilt_deg" not in c.variables:
            return None, ""
        k = c.index("pelvis_tilt_deg")
        vals = [np.asarray(c.side(s).values, dtype=float)[:, :, k].ravel() for s in SIDES]
        tilt = np.concatenate(vals)
        frame = next((n[len("pelvis angles in ") :] for n in c.notes
                      if n.startswith("pelvis angles in ")), "")  # fmt: skip
        return (tilt if np.isfinite(tilt).any() else None), frame

    def summary(self) -> dict[str, Any]:
        """The ``summary.json`` ``gait`` section (:class:`msk.results.summary.Gait`)."""
        c = self.cycles

        def mean_off(s: str) -> float | None:
            x = c.side(s).mean_foot_off_pct()
            return float(x) if np.isfinite(x) else None

        return {
            "spatiotemporal": self.spatiotemporal.to_summary(),
            "heel_source": self.spatiotemporal.source,
            "treadmill_speed_m_s": self.treadmill_speed_m_s or None,
            "variables": list(c.variables),
            "cycles": {s: c.side(s).n_cycles for s in SIDES},
            "cycles_measured": {s: int(np.sum(c.side(s).measured)) for s in SIDES},
            "foot_off_pct": {s: mean_off(s) for s in SIDES},
            "knee_adduction_moment": self.variables.knee_adduction_moment or None,
            "not_modelled": list(self.variables.not_modelled),
            "notes": list(dict.fromkeys(c.notes + self.spatiotemporal.notes)),
        }


def analyse_gait(
    model: Any,
    kinematics: Any,
    foot_strike: Mapping[str, Sequence[float]],
    foot_off: Mapping[str, Sequence[float]],
    *,
    mass_kg: float,
    torques: Any = None,
    loads: Any = None,
    dynamics_model: Any = None,
    trial: str = "",
    angle_convention: str = "model",
    markers: Any = None,
) -> GaitAnalysis:
    """Every complete cycle of both legs (:func:`msk.gait.variables.gait_cycles`) and the
    spatiotemporal parameters from the feet's body origins (:func:`spatiotemporal`), one
    forward-kinematics pass shared by both. ``angle_convention`` ``"plug_in_gait"``: the knee
    flexion as Plug-in Gait measures it (:func:`msk.gait.plug_in_gait.
    plug_in_gait_knee_flexion`, from ``markers``: the task trial in the model's frame, with its
    ``subject``), else the model's knee coordinate."""
    poses = segment_poses(model, kinematics)
    angles: dict[str, dict[str, Array]] = {}
    angle_notes: list[str] = []
    if angle_convention == "plug_in_gait":
        from msk.gait.plug_in_gait import plug_in_gait_knee_flexion

        for s in SIDES:
            flex, how = (None, "no marker trial") if markers is None else (
                plug_in_gait_knee_flexion(model, kinematics, markers, s))  # fmt: skip
            if flex is not None:
                angles[s] = {"knee_flexion_deg": flex}
                angle_notes.append(f"{s} knee flexion as Plug-in Gait measures it: {how}")
            else:
                angle_notes.append(f"{s} knee flexion: the model's knee coordinate ({how})")
    t = np.asarray(kinematics.time, dtype=float)
    # a treadmill's belt (zero overground): strides and progression are measured relative to it
    surface = surface_velocity(
        t, poses.heel, foot_strike, foot_off, pelvis=poses.pelvis_origin, up=poses.up
    )
    cycles, variables = gait_cycles(
        model, kinematics, foot_strike, foot_off, torques=torques, loads=loads, mass_kg=mass_kg,
        dynamics_model=dynamics_model, poses=poses, trial=trial, surface=surface,
        angles=angles, angle_notes=angle_notes,
    )  # fmt: skip
    feet = ", ".join(poses.foot_body[s] for s in SIDES if s in poses.foot_body)
    st = spatiotemporal(
        t, poses.heel, foot_strike, foot_off, up=poses.up, source=f"model: origin of {feet}",
        surface=surface,
    )  # fmt: skip
    return GaitAnalysis(cycles, st, variables, float(np.linalg.norm(surface)))
