"""msk.kinematics.observation: the frames whose leg segments the markers observe, on synthetic walks
of a
two-leg model built in code (known marker drop-outs, 1 mm noise)."""

from __future__ import annotations

import functools

import numpy as np

from msk.datasets.models import two_leg_model
from msk.datasets.trials import make_trial
from msk.kinematics.ik import solve_kinematics
from msk.kinematics.observation import observed_frames

MODEL = two_leg_model()
CUT_HZ = 6.0


@functools.cache
def _trial():
    return make_trial(MODEL, duration_s=1.5, rate_hz=100.0, analog_ratio=10)


def _markers(seed: int = 0) -> tuple[np.ndarray, list[str]]:
    tr = _trial()
    rng = np.random.default_rng(seed)
    return tr.markers + rng.normal(0.0, 0.001, tr.markers.shape), list(tr.marker_labels)


def _solve(x: np.ndarray, labels: list[str]):
    return solve_kinematics(MODEL, x, labels, _trial().time, cutoff_hz=CUT_HZ)


def test_complete_markers_exclude_no_frame():
    o = observed_frames(MODEL, _solve(*_markers()))
    assert o.observed.all()
    assert set(o.short.values()) == {0} and set(o.needed.values()) == {3}


def test_a_segment_losing_markers_is_unobserved_widened_by_the_filter_spread():
    x, labels = _markers()
    # skin offsets: with all four markers and with two the tibia is posed differently, so the
    # drop-out makes the knee angle jump and the filtered acceleration swing around it
    x[:, labels.index("RTIB")] += [0.03, 0.0, 0.0]
    x[:, labels.index("RANK")] += [-0.03, 0.0, 0.0]
    x[60:70, labels.index("RANK")] = np.nan
    x[60:70, labels.index("RANM")] = np.nan
    kin = _solve(x, labels)
    o = observed_frames(MODEL, kin)
    assert o.short == {**{b: 0 for b in o.short}, "tibia_r": 10}
    pad = round(1.0 / (4.0 * CUT_HZ) / 0.01)  # 1/(4 f_c) = 42 ms: 4 frames at 100 Hz
    assert o.pad_frames == pad
    assert np.array_equal(np.flatnonzero(~o.observed), np.arange(60 - pad, 70 + pad))
    # the known truth: the acceleration error peaks in the excluded frames, several times the
    # error of the same trial with its markers complete
    err = np.abs(kin.a - _trial().a).max(axis=1)
    ref = np.abs(_solve(*_markers(1)).a - _trial().a)[10:-10].max()
    assert err[~o.observed].max() > 3.0 * ref
    assert int(np.argmax(err)) in np.flatnonzero(~o.observed)
    assert err[~o.observed].max() > 1.5 * err[o.observed].max()
    assert o.excluded(np.ones_like(o.observed)) == 10 + 2 * pad


def test_a_segment_the_lab_marks_with_two_markers_needs_only_those_two():
    x, labels = _markers()
    for lab in ("RTIA", "RANM"):  # the right shank carries RTIB and RANK only
        x[:, labels.index(lab)] = np.nan
    for lab in ("LTIA", "LANM"):  # seen in 3 frames only: they do not raise the left's need
        x[np.r_[:5, 8:150], labels.index(lab)] = np.nan
    o = observed_frames(MODEL, _solve(x, labels))
    assert o.needed["tibia_r"] == 2 and o.needed["tibia_l"] == 2 and o.observed.all()
    x[100:105, labels.index("RANK")] = np.nan
    o = observed_frames(MODEL, _solve(x, labels))
    assert o.short["tibia_r"] == 5
    assert not o.observed[100:105].any() and o.observed[:90].all()


def test_frames_before_the_subject_enters_the_volume_widen_into_the_solved_window():
    x, labels = _markers()
    x[:20] = np.nan  # not solved: no marker in view
    kin = _solve(x, labels)
    o = observed_frames(MODEL, kin, pad_s=0.05)
    assert np.flatnonzero(o.observed)[0] == 25
    assert observed_frames(MODEL, kin, pad_s=0.0).observed[20:].all()
