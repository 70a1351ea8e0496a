"""A two-leg model with ten muscles a leg and a smooth movement of it (the tension and
strength stages' per-leg tests: ``tests/pipeline/test_pipeline_tension.py``,
``tests/pipeline/test_pipeline_strength.py``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from msk.datasets.models import two_leg_model
from msk.dynamics.inverse import inverse_dynamics
from msk.kinematics.ik import kinematics_from_coordinates
from msk.muscles.geometry import muscle_geometry
from msk.muscles.path import Muscle, PathPoint

#: muscle → (origin body, origin (m), insertion body, insertion (m)), each side (z mirrored)
_PATHS = {
    "iliacus": ("pelvis", (0.05, -0.05, 0.08), "femur", (0.02, -0.08, 0.0)),
    "glmax": ("pelvis", (-0.12, -0.02, 0.07), "femur", (-0.03, -0.10, 0.0)),
    "glmed": ("pelvis", (-0.02, 0.05, 0.12), "femur", (0.0, -0.05, 0.06)),
    "addlong": ("pelvis", (0.03, -0.08, 0.03), "femur", (0.0, -0.20, -0.02)),
    "recfem": ("pelvis", (0.04, -0.03, 0.09), "tibia", (0.05, -0.05, 0.0)),
    "vasti": ("femur", (0.03, -0.15, 0.0), "tibia", (0.05, -0.06, 0.0)),
    "hams": ("pelvis", (-0.10, -0.08, 0.06), "tibia", (-0.03, -0.05, 0.0)),
    "gastroc": ("femur", (-0.02, -0.38, 0.0), "foot", (-0.05, 0.0, 0.0)),
    "soleus": ("tibia", (-0.02, -0.15, 0.0), "foot", (-0.05, 0.0, 0.0)),
    "tibant": ("tibia", (0.03, -0.15, 0.0), "foot", (0.10, -0.01, 0.0)),
}


def muscled_two_legs() -> Any:
    """:func:`msk.datasets.models.two_leg_model` with ten muscles a leg, their tendon slack
    lengths such that every fibre is at its optimal length in the default pose."""
    model = two_leg_model()

    def build(slack: dict[str, float]) -> Any:
        muscles = []
        for side, s in (("r", 1.0), ("l", -1.0)):
            for name, (b0, p0, b1, p1) in _PATHS.items():
                n = f"{name}_{side}"
                pts = []
                for tag, body, xyz in (("o", b0, p0), ("i", b1, p1)):
                    seg = body if body == "pelvis" else f"{body}_{side}"
                    pts.append(PathPoint(f"{n}_{tag}", seg, np.array([xyz[0], xyz[1], s * xyz[2]])))
                muscles.append(Muscle(n, tuple(pts), 1500.0, 0.1, slack.get(n, 0.2), 0.0, 10.0))
        return model.with_muscles(muscles)

    first = build({})
    geo = muscle_geometry(first, first.default_coordinates()[None, :])
    length = dict(zip(geo.muscle_names, geo.lengths[0], strict=True))
    return build({n: float(v) - 0.1 for n, v in length.items()})


def two_leg_trial(model: Any, n: int = 40) -> tuple[Any, Any, Any]:
    """An ``n``-frame movement of both legs (smooth, 100 Hz), its torques (no external load:
    every torque finite) and its muscle geometry."""
    t = np.arange(n) / 100.0
    q0 = model.default_coordinates()
    q = np.repeat(q0[None, :], t.size, axis=0)
    names = list(model.coordinate_names)
    for k, c in enumerate(names):
        if c.startswith(("hip_", "knee_", "ankle_")):
            q[:, k] += 0.3 * np.sin(2 * np.pi * (1.0 + 0.1 * k) * t + k)
    kin = kinematics_from_coordinates(t, q, names, cutoff_hz=None, model=model)
    tq = inverse_dynamics(model, kin)
    geo = muscle_geometry(model, kin.q, kin.v)
    return kin, tq, geo
