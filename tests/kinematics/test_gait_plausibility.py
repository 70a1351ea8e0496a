"""The walking knee-contact gate (msk.kinematics.gait_plausibility) on gait events and kinematics
built
in code."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from msk.kinematics.events import GaitEvents
from msk.kinematics.gait_plausibility import (
    KNEE_CONTACT_WALKING_MAX_BW,
    PELVIS_TILT_WALKING_MAX_DEG,
    gait_mode,
    knee_contact_flags,
    pelvis_tilt_flags,
)

UP = np.array([0.0, 1.0, 0.0])


def _events(duty: float, period: float = 1.1, n: int = 3) -> GaitEvents:
    """Alternating steps: each foot on the ground ``duty`` of the cycle (> 0.5: walking with
    double support; < 0.5: running with a flight phase)."""
    rs = [k * period for k in range(n)]
    ls = [t + period / 2 for t in rs]
    return GaitEvents(
        foot_strike={"right": tuple(rs), "left": tuple(ls)},
        foot_off={"right": tuple(t + duty * period for t in rs),
                  "left": tuple(t + duty * period for t in ls)},
    )  # fmt: skip


def _kin(speed: float) -> SimpleNamespace:
    t = np.linspace(0.0, 2.0, 201)
    q = np.zeros((t.size, 4))
    q[:, 0] = speed * t  # forward
    q[:, 1] = 0.9 + 0.02 * np.sin(2 * np.pi * t)  # up: not counted
    return SimpleNamespace(
        time=t, q=q, coordinate_names=("pelvis_tx", "pelvis_ty", "pelvis_tz", "hip_flexion_r")
    )


def test_events_tell_a_walk_from_a_run() -> None:
    assert gait_mode(_events(0.62), _kin(5.0), UP)[0] == "walking"  # events win over speed
    mode, why = gait_mode(_events(0.35), _kin(1.0), UP)
    assert mode == "running" and "flight" in why


def test_without_events_of_both_sides_the_speed_decides() -> None:
    one = GaitEvents(foot_strike={"left": (0.1, 1.2)}, foot_off={"left": (0.8,)})
    mode, why = gait_mode(one, _kin(1.3), UP)
    assert mode == "walking" and "1.30 m/s" in why
    assert gait_mode(one, _kin(3.5), UP)[0] == "running"
    still = SimpleNamespace(time=np.zeros(1), q=np.zeros((1, 1)), coordinate_names=("x",))
    assert gait_mode(None, still, UP)[0] == "unknown"


def test_a_walking_peak_above_the_bound_is_flagged_with_its_reference() -> None:
    t = np.linspace(0.0, 1.0, 101)
    high = 1.0 + 5.5 * np.sin(np.pi * t) ** 4  # peaks at 6.5 BW
    ok = 1.0 + 1.5 * np.sin(np.pi * t) ** 4  # 2.5 BW, an in-vivo walking peak
    flags = knee_contact_flags("walk", {"generic": high, "subject_specific": ok}, "walking",
                               "the gait events show double support")  # fmt: skip
    (f,) = flags
    assert f.quantity == "knee_contact_peak_bw_generic"
    assert f.value == np.max(high) and f.threshold == KNEE_CONTACT_WALKING_MAX_BW
    assert "Kutzner et al. 2010" in f.message and "6.5 BW" in f.message
    # a run is not gated; NaN-only (no muscle forces) is not judged
    assert knee_contact_flags("run", {"generic": high}, "running", "flight") == []
    assert knee_contact_flags("walk", {"generic": np.full(5, np.nan)}, "walking", "") == []


def _tilted(mean_deg: float) -> SimpleNamespace:
    t = np.linspace(0.0, 2.0, 201)
    tilt = np.radians(mean_deg + 2.0 * np.sin(2 * np.pi * t))
    return SimpleNamespace(time=t, q=tilt[:, None], coordinate_names=("pelvis_tilt",))


def test_an_undetermined_pelvis_tilt_is_flagged_in_a_walk() -> None:
    (f,) = pelvis_tilt_flags("walk", _tilted(40.0), "walking", ("R.ASIS", "L.ASIS"))
    assert f.quantity == "pelvis_tilt_mean_deg" and abs(f.value - 40.0) < 0.1
    assert f.threshold == PELVIS_TILT_WALKING_MAX_DEG
    assert "R.ASIS, L.ASIS" in f.message and "Kadaba et al. 1990" in f.message
    (g,) = pelvis_tilt_flags("walk", _tilted(-35.0), "walking")
    assert g.threshold == -PELVIS_TILT_WALKING_MAX_DEG
    # a plausible walk, a run and a model without the coordinate are not flagged
    assert pelvis_tilt_flags("walk", _tilted(12.0), "walking") == []
    assert pelvis_tilt_flags("run", _tilted(40.0), "running") == []
    assert pelvis_tilt_flags("walk", _kin(1.0), "walking") == []


def test_the_gate_reads_the_reported_tilt_when_given() -> None:
    """The coordinate at 12° but the reported (Plug-in Gait frame) tilt at 30°: flagged on the
    reported tilt, its frame named; the reverse not flagged; NaN cycles ignored."""
    rep = np.concatenate([30.0 + np.sin(np.linspace(0, 6, 101)), np.full(101, np.nan)])
    (f,) = pelvis_tilt_flags("walk", _tilted(12.0), "walking", tilt_deg=rep, frame="ASIS–PSIS")
    assert abs(f.value - np.nanmean(rep)) < 1e-12
    assert "reported pelvis tilt (ASIS–PSIS)" in f.message
    assert pelvis_tilt_flags("walk", _tilted(40.0), "walking", tilt_deg=np.full(5, 12.0)) == []
    assert pelvis_tilt_flags("walk", _tilted(40.0), "walking", tilt_deg=np.full(5, np.nan)) == []
