"""Which joint is the knee and which way its coordinate turns (msk.model.conventions)."""

from __future__ import annotations

import numpy as np
import pytest

from msk.datasets.models import two_leg_model
from msk.model.conventions import knee_joint, reference_sign, reference_signs
from msk.model.core import Model, frame_placements
from msk.model.files import load_model
from tests.support.knees import turned_knees


def _ankle_x_in_femur(model: Model, side: str, q_ref_deg: float, s: float) -> float:
    """The ankle joint centre's anterior coordinate in the femur frame at a knee of
    ``q_ref_deg`` in the reference convention (coordinate s · q_ref)."""
    q = model.default_coordinates()[None].copy()
    q[0, model.coordinate_index(f"knee_angle_{side}")] = s * np.radians(q_ref_deg)
    foot = next(j.child for j in model.joints if j.parent == f"tibia_{side}")
    rot, pos = frame_placements(model, q, [model.body_frame[f"femur_{side}"],
                                           model.body_frame[foot]])  # fmt: skip
    return float((rot[0, 0].T @ (pos[0, 1] - pos[0, 0]))[0])


@pytest.mark.parametrize("name", ["gait2392", "gait2392_fourbar", "rajagopal", "two_leg",
                                  "two_leg_turned"])  # fmt: skip
def test_reference_sign_makes_flexion_negative_on_every_knee(name: str) -> None:
    """Known truth from the geometry alone: in the reference convention, flexing the knee
    (q_ref from −20° to −60°) swings the ankle posterior in the femur frame (−x), on both
    sides of every model, whichever way the model's own coordinate turns."""
    if name.startswith("two_leg"):
        model = two_leg_model()
        model = turned_knees(model) if name.endswith("turned") else model
    else:
        model = load_model(name)
    for side in ("r", "l"):
        s = reference_sign(model, f"knee_angle_{side}")
        assert s in (1.0, -1.0)
        a, b = (_ankle_x_in_femur(model, side, d, s) for d in (-20.0, -60.0))
        assert b < a - 0.05
    turned = name in ("rajagopal", "two_leg_turned")
    assert reference_signs(model) == (
        {"knee_angle_r": -1.0, "knee_angle_l": -1.0} if turned else {}
    )
    assert reference_sign(model, "hip_flexion_r") == 1.0


def test_knee_joint_is_the_joint_of_the_tibia() -> None:
    assert knee_joint(load_model("rajagopal"), "r") == "walker_knee_r"
    assert knee_joint(load_model("rajagopal"), "_l") == "walker_knee_l"
    assert knee_joint(load_model("gait2392"), "l") == "knee_l"
    model = two_leg_model()
    assert knee_joint(model, "r") == "knee_r"
    assert knee_joint(model, "x") is None
