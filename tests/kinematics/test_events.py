"""msk.kinematics.events: plate edges, the Zeni et al. (2008) kinematic events, reconciliation with
a
file's events (a tiny two-leg model built in code)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from msk.datasets.models import two_leg_model
from msk.kinematics.events import GaitEvents, detect_gait_events, reconcile
from msk.trial import Event


def _kin(model, t, q):
    return SimpleNamespace(time=t, q=q)


def _standing(model, n):
    q = np.zeros((n, len(model.coordinate_names)))
    q[:, model.coordinate_names.index("pelvis_ty")] = 0.93
    return q


def test_plate_edges_give_strike_and_off_of_the_loaded_foot():
    model = two_leg_model()
    t = np.arange(200) / 100.0
    q = _standing(model, t.size)
    force = np.zeros((t.size, 1, 3))
    on = (t >= 0.5) & (t < 1.1)
    force[on, 0, 1] = 700.0
    loads = SimpleNamespace(bodies=("foot_r",), force=force)
    ev = detect_gait_events(model, _kin(model, t, q), loads)
    assert ev.foot_strike["right"] == pytest.approx((0.5,))
    assert ev.foot_off["right"] == pytest.approx((1.1,))
    assert ev.foot_strike["left"] == () and ev.source["right foot strike"] == "plates"


def test_zeni_heel_maxima_relative_to_pelvis():
    """Hip flexion θ = 0.4 sin(2π f t) with the knee straight: the heel is farthest ahead of
    the pelvis at θ's maxima, t = (1/4 + k)/f."""
    model = two_leg_model()
    f = 1.0
    t = np.arange(400) / 100.0
    q = _standing(model, t.size)
    q[:, model.coordinate_names.index("hip_flexion_r")] = 0.4 * np.sin(2 * np.pi * f * t)
    ev = detect_gait_events(model, _kin(model, t, q), None)
    expected = [(0.25 + k) / f for k in range(4) if 0.05 < (0.25 + k) / f < 3.95]
    assert ev.foot_strike["right"] == pytest.approx(expected, abs=0.011)
    assert ev.source["right foot strike"] == "kinematics"


def test_reconcile_keeps_agreeing_file_events_and_replaces_contradicting_ones():
    det = GaitEvents({"right": (0.50, 1.60)}, {"right": (1.10,)},
                     {"right foot strike": "plates", "right foot off": "plates"})  # fmt: skip
    agree = [Event("Foot Strike", "Right", 0.51), Event("Foot Strike", "Right", 1.61)]
    out = reconcile(agree, det)
    assert out.foot_strike["right"] == (0.51, 1.61) and out.source["right foot strike"] == "file"
    wrong = [Event("Foot Strike", "Right", 0.80)]
    out = reconcile(wrong, det)
    assert out.foot_strike["right"] == (0.50, 1.60)
    assert "contradict the plates" in out.notes[0] and "0.500" in out.notes[0]
    # a NaN event time is ignored, never used
    out = reconcile([Event("Foot Off", "Right", float("nan"))], det)
    assert out.foot_off["right"] == (1.10,)


def test_reconcile_completes_a_file_that_marks_only_some_events():
    """A file marking one stride's strike (the one over the plates) keeps its time there; the
    detected strikes a stride away complete the side, so its cycles exist."""
    det = GaitEvents({"right": (0.50, 1.60, 2.70)}, {},
                     {"right foot strike": "kinematics"})  # fmt: skip
    out = reconcile([Event("Foot Strike", "Right", 1.62)], det, plate_events=GaitEvents({}, {}, {}))
    assert out.foot_strike["right"] == (0.50, 1.62, 2.70)
    assert out.source["right foot strike"] == "file + kinematics"
    assert "2 detected (kinematics) added" in out.notes[-1]
