"""msk.personalise.static_window: the still, double-stance part of a static trial.

Synthetic statics with a known truth (quiet-stance sway + 0.5 mm marker noise, then a leg
lift or a weight shift at a known time), and the real statics: ``jw_1legstand1`` (double
stance, then the left leg lifted; slow) and the shipped statics that stand still throughout.
"""

from __future__ import annotations

import numpy as np
import pytest

from msk.exceptions import MissingDataError, StaticTrialError
from msk.personalise.static_window import STILL_SPEED_M_S, still_window

RATE = 120.0


def _standing(duration_s: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(N, 30, 3) markers of a subject standing quietly: an anterior–posterior sway of the
    whole body, 3 mm amplitude at 0.3 Hz (≤ 6 mm/s; scaled with height as an inverted
    pendulum) plus 0.5 mm white marker noise; and the time."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(duration_s * RATE)) / RATE
    base = rng.uniform([-0.2, 0.0, -0.2], [0.2, 1.6, 0.2], size=(30, 3))
    sway = 0.003 * np.sin(2 * np.pi * 0.3 * t)
    x = base[None] + np.zeros((t.size, 1, 1))
    x[:, :, 0] += sway[:, None] * (base[:, 1] / 1.0)[None]
    return x + rng.normal(0.0, 0.0005, x.shape), t


def _lift(x: np.ndarray, t: np.ndarray, t0: float, markers: slice) -> np.ndarray:
    """``markers`` raised 0.3 m over 1 s from ``t0`` (a leg lift: a minimum-jerk rise,
    peak speed ~0.56 m/s), held up after."""
    s = np.clip((t - t0) / 1.0, 0.0, 1.0)
    h = 0.3 * (10 * s**3 - 15 * s**4 + 6 * s**5)
    out = x.copy()
    out[:, markers, 1] += h[:, None]
    return out


def test_still_throughout_is_the_whole_trial() -> None:
    x, t = _standing(4.0)
    w = still_window(x, t)
    assert w.whole and w.frames == slice(0, t.size)
    assert w.speed_m_s < STILL_SPEED_M_S
    assert w.summary()["whole_trial"] is True and w.plates is None


def test_leg_lift_window_ends_before_the_lift() -> None:
    x, t = _standing(6.0, seed=1)
    x = _lift(x, t, 2.5, slice(0, 8))
    w = still_window(x, t)
    assert w.first == 0
    # the lift starts at 2.5 s; the filtered speed crosses 30 mm/s ~0.1 s after it starts
    assert 2.3 <= w.end_s <= 2.75
    assert not w.whole


def test_plates_exclude_a_still_single_leg_stance() -> None:
    # the leg is lifted (0.5–1.5 s) and held up, still, to the end: the markers alone would
    # take the long single-leg hold; the plates say one foot is off
    x, t = _standing(6.0, seed=2)
    x = _lift(x, t, 1.5, slice(0, 8))
    fz = np.zeros((t.size, 2))
    fz[:, 0] = np.where(t < 1.6, 350.0, 700.0)
    fz[:, 1] = np.where(t < 1.6, 350.0, 0.0)
    assert still_window(x, t).start_s > 2.0  # markers only: the single-leg hold
    w = still_window(x, t, plate_loads=fz)
    assert w.first == 0 and 1.3 <= w.end_s <= 1.6 and w.plates == 2


def test_longest_still_part_after_a_weight_shift() -> None:
    x, t = _standing(8.0, seed=3)
    # a 2-cm weight shift of the whole body over 0.4 s at 1.0 s (≥ 50 mm/s): the longer
    # still part after it is taken
    s = np.clip((t - 1.0) / 0.4, 0.0, 1.0)
    x[:, :, 2] += (0.02 * (10 * s**3 - 15 * s**4 + 6 * s**5))[:, None]
    w = still_window(x, t)
    assert 1.3 <= w.start_s <= 1.6 and w.stop == t.size


def test_no_still_window_is_a_typed_error() -> None:
    x, t = _standing(3.0, seed=4)
    # walking-like motion: every marker oscillates at 1 Hz, 0.1 m (0.6 m/s)
    x[:, :, 0] += (0.1 * np.sin(2 * np.pi * t))[:, None]
    with pytest.raises(StaticTrialError, match="no still window") as err:
        still_window(x, t)
    assert isinstance(err.value, MissingDataError)


def test_gaps_do_not_make_speed() -> None:
    x, t = _standing(3.0, seed=5)
    x[100:140, :5] = np.nan  # five markers lost for 1/3 s
    x[:, 5] = np.nan  # one never seen
    w = still_window(x, t)
    assert w.whole


@pytest.mark.slow
def test_jw_1legstand1_still_double_stance() -> None:
    """jw_1legstand1: quiet double stance, a weight shift from ~1.2 s, the left foot off the
    plate from ~2.4 s to ~8.7 s. The window must lie in the double stance, before the lift,
    and the knee goniometer (an independent measurement) must be steady in it."""
    from msk.datasets.shared import real_data_dir
    from msk.personalise.static_trial import read_static_trial

    path = real_data_dir() / "knee-grand-challenge-gc4" / "jw_1legstand1.c3d"
    if not path.exists():
        pytest.skip("Grand Challenge data not present")
    static = read_static_trial(path, np.array([0.0, 1.0, 0.0]))
    time, w = static.time, static.window
    assert w.plates == 2 and w.first == 0
    assert 0.5 <= w.end_s <= 2.4  # before the left foot leaves the plate
    assert time[w.stop - 1] == pytest.approx(w.end_s)
    from msk.io import read_trial

    tr = read_trial(path)
    gon = tr.analogs[:, list(tr.analog_labels).index("goniometer")]
    inside = (tr.analog_time >= w.start_s) & (tr.analog_time <= w.end_s)
    assert float(np.std(gon[inside])) < 0.5  # degrees


@pytest.mark.slow
@pytest.mark.parametrize(
    "rel",
    [
        "opensim-subject01-walk/subject01_static.trc",
        "motonms-testdata/UNIPD/Static1.c3d",
    ],
)
def test_still_statics_are_used_whole(rel: str) -> None:
    from msk.datasets.shared import real_data_dir
    from msk.personalise.static_trial import read_static_trial

    path = real_data_dir() / rel
    if not path.exists():
        pytest.skip(f"{rel} not present")
    w = read_static_trial(path, np.array([0.0, 1.0, 0.0])).window
    assert w.whole


@pytest.mark.slow
def test_gc4_JW_static_knee_offset_against_goniometer() -> None:
    """The shipped gc4_JW session (static: jw_1legstand1's still start, knee held at 0 there)
    against JW's knee electrogoniometer (an independent measurement, not the contact force):
    the mean IK − GON over the frames with measured ground reaction was −4.1° when the
    clusters were placed from the walk; it must stay within ±3°, with the static's window
    in the double stance (summary model.static_window)."""
    from msk.config import load_config
    from msk.datasets.shared import real_data_dir
    from msk.pipeline import run_stages

    root = real_data_dir() / "knee-grand-challenge-gc4"
    if not (root / "jw_1legstand1.c3d").exists():
        pytest.skip("Grand Challenge data not present")
    from pathlib import Path

    cfg = load_config(Path(__file__).resolve().parents[2] / "pipelines" / "gc4_JW.toml")
    r = run_stages(cfg, until="loads")
    win = r["model"].info["static_window"]
    assert win["plates_loaded"] == 2 and win["end_s"] < 2.4 and not win["whole_trial"]
    (task,) = [tc for tc in cfg.trials if tc.role == "task"]
    assert task.contact_force is not None
    cells = np.loadtxt(task.contact_force, delimiter=",", skiprows=1, usecols=range(7))
    kin, usable = r["kinematics"], r["loads"].usable
    gon = np.interp(kin.time, cells[:, 0], cells[:, 5])
    knee = -np.degrees(kin.q[:, list(kin.coordinate_names).index("knee_angle_r")])
    assert abs(float(np.mean((knee - gon)[usable]))) < 3.0
    assert np.corrcoef(gon, knee)[0, 1] > 0.95


def test_a_static_too_short_to_judge_is_used_whole() -> None:
    x, t = _standing(0.3, seed=6)
    x[:, :, 0] += (0.1 * np.sin(2 * np.pi * t))[:, None]  # moving, but 0.3 s cannot tell
    w = still_window(x, t)
    assert w.whole and np.isnan(w.speed_m_s)
    one = still_window(x[:1], t[:1])
    assert one.whole and one.n_frames == 1
    with pytest.raises(StaticTrialError):
        still_window(x[:0], t[:0])


def test_arm_markers_moving_do_not_refuse_a_static_the_model_can_use(tmp_path) -> None:
    """A subject standing still with the arms waving (1 Hz, 0.3 m: ≥ 0.6 m/s at the wrists):
    on all markers the static has no still window; on the markers gait2392 uses (no arm
    segment) it is still throughout, and the arm markers are listed as not judged."""
    from pathlib import Path

    from msk.io.opensim_files import write_trc
    from msk.model.files import load_model
    from msk.personalise.static_trial import judged_markers, read_static_trial

    legs = ["RASI", "LASI", "RPSI", "LPSI", "RTHI", "LTHI", "RKNE", "LKNE", "RTIB", "LTIB",
            "RANK", "LANK", "RHEE", "LHEE", "RTOE", "LTOE"]  # fmt: skip
    arms = ["RELB", "LELB", "RWRA", "LWRA", "RWRB", "LWRB", "RFIN", "LFIN", "RUPA", "LUPA",
            "RFRA", "LFRA"]  # fmt: skip
    x, t = _standing(3.0, seed=6)
    x = x[:, : len(legs) + len(arms)]
    x[:, len(legs) :, 0] += (0.3 * np.sin(2 * np.pi * t))[:, None]
    labels = legs + arms
    with pytest.raises(StaticTrialError):
        still_window(x, t)
    model = load_model(Path(__file__).resolve().parents[2] / "msk/data/models/gait2392.toml")
    judged = judged_markers(labels, model)
    assert set(judged) == set(legs)
    path = write_trc(tmp_path / "static.trc", time=t, markers=x, labels=labels)
    static = read_static_trial(path, np.array([0.0, 1.0, 0.0]), model=model)
    assert static.window.whole
    assert set(static.not_judged) == set(arms)
    with pytest.raises(StaticTrialError, match=r"static\.trc"):
        read_static_trial(path, np.array([0.0, 1.0, 0.0]))  # every marker judged
