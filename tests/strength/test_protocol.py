"""msk.strength.protocol: the isometric test that would identify a group, from the model."""

from __future__ import annotations

import numpy as np
import pytest

from msk.model.files import load_model
from msk.muscles.geometry import muscle_geometry, muscle_parameters
from msk.strength import TestProtocol as Protocol
from msk.strength import recommend_test, recommend_tests

VASTI = ("vas_med_r", "vas_int_r", "vas_lat_r")
QUADS = ("rect_fem_r", *VASTI)


@pytest.fixture(scope="module")
def model():
    return load_model("gait2392")


def _knee_arms(model, angles_deg, hip_deg):
    """Muscle geometry over knee flexion angles (deg) at a hip flexion (deg), and the knee's
    coordinate index."""
    th = np.tile(np.asarray(model.default_coordinates(), dtype=float), (len(angles_deg), 1))
    for c in model.coordinates:
        if not c.name.endswith(("_tx", "_ty", "_tz")):
            th[:, model.coordinate_index(c.name)] = 0.0
    k = model.coordinate_index("knee_angle_r")
    th[:, k] = -np.deg2rad(angles_deg)  # gait2392: knee_angle negative in flexion
    th[:, model.coordinate_index("hip_flexion_r")] = np.deg2rad(hip_deg)
    return muscle_geometry(model, th), k


def test_knee_extensors_get_a_knee_extension_test_at_a_large_quadriceps_moment_arm(model):
    p = recommend_test(model, "knee_extensors", QUADS, side="right")
    assert isinstance(p, Protocol)
    assert p.action == "knee extension" and p.coordinate == "knee_angle_r"
    assert p.share > 0.8 and p.group_moment_nm > 100.0
    # the quadriceps' summed moment arm there is near its largest over 0–90° of flexion
    names = muscle_parameters(model).names
    grid = np.arange(0.0, 91.0, 5.0)
    hip = float(p.posture_deg.get("hip_flexion_r", 0.0))
    geo, k = _knee_arms(model, grid, hip)
    cols = [names.index(m) for m in QUADS]
    arm = geo.moment_arms[:, cols, k].sum(axis=1)  # knee_angle positive: extension
    at = float(np.interp(p.angle_deg, grid, arm))
    assert at >= 0.8 * float(arm.max()), (p.angle_deg, at, arm.max())
    rec = p.as_dict()
    assert rec["test"] == "isometric MVC" and rec["action"] == "knee extension"
    assert "knee extension" in rec["text"]


def test_each_group_gets_the_action_it_dominates(model):
    got = recommend_tests(
        model,
        {
            "soleus": ("soleus_r",),
            "tibant": ("tib_ant_r",),
            "gmax": ("glut_max1_r", "glut_max2_r", "glut_max3_r"),
        },
        side="right",
    )
    assert got["soleus"].action == "ankle plantarflexion"
    # the knee flexed slackens the gastrocnemii: the soleus's share is largest there
    assert got["soleus"].posture_deg.get("knee_angle_r", 0.0) < -30.0
    assert got["tibant"].action == "ankle dorsiflexion"
    assert got["gmax"].action == "hip extension"
    assert recommend_tests(model, {}, side="right") == {}
