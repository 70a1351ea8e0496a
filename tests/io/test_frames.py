"""Lab → model frame: rotating a whole Trial (markers, plates, up) and the lab→model rotation."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msk.exceptions import ShapeMismatchError
from msk.io import (
    ForcePlate,
    GapReport,
    ModelOutputs,
    Subject,
    Trial,
    lab_to_model_rotation,
    read_c3d,
    rotation_between,
    to_model_frame,
)

GC5 = Path(__file__).resolve().parents[2] / "data" / "gc5-PS"


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    k = axis / np.linalg.norm(axis)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx


def _trial(seed: int, n: int = 7, m: int = 5, na: int = 21) -> Trial:
    """A Z-up trial with random markers and one plate whose moment about its origin is
    consistent with its COP, force and free moment: M_o = (c − o) × F + T."""
    rng = np.random.default_rng(seed)
    markers = rng.normal(0.0, 1.0, (n, m, 3))
    markers[2, 1] = np.nan  # a gap stays a gap
    centre = np.array([0.3, 0.2, 0.0])
    rot = np.diag([1.0, -1.0, -1.0])
    corners = centre + np.array([[0.3, -0.2, 0], [-0.3, -0.2, 0], [-0.3, 0.2, 0], [0.3, 0.2, 0]])
    force = rng.normal(0.0, 100.0, (na, 3))
    force[:, 2] = rng.uniform(100.0, 800.0, na)
    cop = centre + np.column_stack([rng.uniform(-0.2, 0.2, (na, 2)), np.zeros(na)])
    free = np.zeros((na, 3))
    free[:, 2] = rng.normal(0.0, 5.0, na)
    moment = np.cross(cop - centre, force) + free
    plate = ForcePlate(
        index=0, type=2, force=force, moment=moment, cop=cop, free_moment=free,
        corners=corners, origin=centre, rotation=rot, channels=("Fx1",), rate_hz=1000.0,
    )  # fmt: skip
    outputs = ModelOutputs(("LKneeAngles",), ("ANGLES",), ("rad",), rng.normal(size=(n, 1, 3)))
    return Trial(
        path=Path("synthetic.c3d"), point_rate_hz=100.0, time=np.arange(n) / 100.0,
        markers=markers, marker_labels=tuple(f"M{i}" for i in range(m)),
        gaps=GapReport(tuple(f"M{i}" for i in range(m)), np.zeros(m, int), np.zeros(m, int)),
        model_outputs=outputs, analog_rate_hz=1000.0, analog_time=np.arange(na) / 1000.0,
        analogs=np.zeros((na, 0)), analog_labels=(), analog_units=(), plates=(plate,),
        events=(), subject=Subject(), vertical_axis=2, up=np.array([0.0, 0.0, 1.0]),
    )  # fmt: skip


unit = st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: np.linalg.norm(v) > 0.1)


@settings(max_examples=40, deadline=None)
@given(axis=unit, angle=st.floats(-np.pi, np.pi), seed=st.integers(0, 1000))
def test_rotation_preserves_distances_and_moves_plate_wrenches_consistently(axis, angle, seed):
    tr = _trial(seed)
    r = _rotation(np.array(axis), angle)
    out = tr.rotated(r)
    # markers: rigid motion about the lab origin (distances, gaps), and x_new = R x
    np.testing.assert_allclose(out.markers, tr.markers @ r.T, atol=1e-12)
    d0 = np.linalg.norm(tr.markers[:, :, None] - tr.markers[:, None], axis=3)
    d1 = np.linalg.norm(out.markers[:, :, None] - out.markers[:, None], axis=3)
    np.testing.assert_allclose(d1, d0, atol=1e-9)
    assert np.isnan(out.markers[2, 1]).all()
    np.testing.assert_allclose(out.up, r @ tr.up, atol=1e-12)
    assert out.vertical_axis == int(np.argmax(np.abs(out.up)))
    # plate: the moment about the rotated origin is (R c − R o) × R F + R T
    p0, p = tr.plates[0], out.plates[0]
    np.testing.assert_allclose(
        p.moment, np.cross(p.cop - p.origin, p.force) + p.free_moment, atol=1e-9
    )
    np.testing.assert_allclose(p.moment, p0.moment @ r.T, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(p.force, axis=1), np.linalg.norm(p0.force, axis=1))
    np.testing.assert_allclose(p.corners, p0.corners @ r.T, atol=1e-12)
    np.testing.assert_allclose(p.normal, r @ p0.normal, atol=1e-12)
    np.testing.assert_allclose(p.rotation @ p.rotation.T, np.eye(3), atol=1e-12)
    # the moment about any point transforms alike: about the lab origin M_O = o × F + M_o
    m_o0 = np.cross(p0.origin, p0.force) + p0.moment
    m_o1 = np.cross(p.origin, p.force) + p.moment
    np.testing.assert_allclose(m_o1, m_o0 @ r.T, atol=1e-8)
    # model outputs live in segment frames: unchanged; R is recorded and composes
    np.testing.assert_array_equal(out.model_outputs.data, tr.model_outputs.data)
    np.testing.assert_allclose(out.metadata["lab_to_model_rotation"], r, atol=1e-12)
    back = out.rotated(r.T)
    np.testing.assert_allclose(back.markers, tr.markers, atol=1e-12)
    np.testing.assert_allclose(back.plates[0].moment, p0.moment, atol=1e-9)
    np.testing.assert_allclose(back.metadata["lab_to_model_rotation"], np.eye(3), atol=1e-12)
    assert tr.plates[0] is p0 and tr.markers is not out.markers  # the input is untouched


@settings(max_examples=40, deadline=None)
@given(a=unit, b=unit)
def test_rotation_between_takes_a_to_b(a, b):
    r = rotation_between(a, b)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-9)
    assert np.linalg.det(r) == pytest.approx(1.0)
    np.testing.assert_allclose(
        r @ (np.array(a) / np.linalg.norm(a)), np.array(b) / np.linalg.norm(b), atol=1e-9
    )


def test_to_model_frame_puts_up_on_y_and_the_walk_on_x():
    tr = _trial(0, n=20)
    t = np.linspace(0.0, 1.0, 20)
    walk = np.repeat(tr.markers[:1], 20, axis=0)  # a rigid marker set ...
    walk[..., 1] += -1.5 * t[:, None]  # ... walking along −y in a Z-up lab
    tr = dataclasses.replace(tr, markers=walk)
    out = to_model_frame(tr, up=(0.0, 1.0, 0.0))
    r = out.metadata["lab_to_model_rotation"]
    np.testing.assert_allclose(r @ [0, 0, 1.0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(r @ [0, -1.0, 0], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(out.up, [0, 1, 0], atol=1e-12)
    assert out.vertical_axis == 1
    # no heading when asked for none
    still = to_model_frame(tr, up=(0.0, 1.0, 0.0), forward=None)
    np.testing.assert_allclose(
        still.metadata["lab_to_model_rotation"], rotation_between([0, 0, 1], [0, 1, 0])
    )
    np.testing.assert_allclose(lab_to_model_rotation([0, 0, 1.0], [0, 1.0, 0], walk), r, atol=1e-12)


def test_bad_rotation_is_refused():
    tr = _trial(1)
    with pytest.raises(ShapeMismatchError, match=r"synthetic\.c3d: not a proper rotation"):
        tr.rotated(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ShapeMismatchError, match=r"synthetic\.c3d: .*\(3, 3\)"):
        tr.rotated(np.eye(2))
    with pytest.raises(ShapeMismatchError, match="non-zero"):
        rotation_between([0.0, 0.0, 0.0], [0.0, 1.0, 0.0])


def test_grand_challenge_walk_in_the_model_frame():
    """PS_ngait_og_ss1 (Z-up lab): after to_model_frame the plates push up along +y and the
    subject walks along +x; plate moments stay consistent with COP, force and free moment."""
    tr = read_c3d(GC5 / "PS_ngait_og_ss1.c3d")
    out = to_model_frame(tr, up=(0.0, 1.0, 0.0))
    for p in out.plates:
        loaded = np.linalg.norm(p.force, axis=1) > 100.0
        assert loaded.any() and (p.force[loaded, 1] > 0).all()
        ok = loaded & np.isfinite(p.cop).all(axis=1)
        m = np.cross(p.cop[ok] - p.origin, p.force[ok]) + p.free_moment[ok]
        np.testing.assert_allclose(m, p.moment[ok], atol=1e-6 * np.abs(p.moment).max() + 1e-6)
    with np.errstate(all="ignore"):
        c = np.nanmean(out.markers, axis=1)
    ok = np.isfinite(c).all(axis=1)
    d = c[ok][-1] - c[ok][0]
    assert d[0] > 0.3 and abs(d[2]) < 1e-9 * abs(d[0]) + 1e-9


def test_lab_to_model_rotation_ignores_frames_without_markers():
    from msk.io.frames import lab_to_model_rotation

    markers = np.full((5, 3, 3), np.nan)
    markers[2:, :, 0] = np.arange(3)[:, None] * 0.5 + np.array([0.0, 0.1, 0.2])
    markers[2:, :, 1] = 0.3
    markers[2:, :, 2] = 1.0
    r = lab_to_model_rotation((0, 0, 1), (0, 1, 0), markers)  # no warning, NaN frames skipped
    np.testing.assert_allclose(r @ np.array([1.0, 0.0, 0.0]), [1.0, 0.0, 0.0], atol=1e-12)


# ---------------------------------------------------------------------------------------------
# heading from the pelvis markers
# ---------------------------------------------------------------------------------------------
MODELS = Path(__file__).resolve().parents[2] / "msk" / "data" / "models"
REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"
_Y_TO_Z = rotation_between([0, 1.0, 0], [0, 0, 1.0])  # model (Y-up) → a Z-up lab


@pytest.fixture(scope="module")
def gait2392():
    from msk.model.files import load_model

    return load_model(MODELS / "gait2392.toml")


def _walk(model, yaw_deg, *, speed=1.2, n=120, turn_at=None, seed=0):
    """Z-up lab markers of gait2392 in its default pose, facing ``yaw_deg`` (about lab z, from
    lab +x), walking forward at ``speed`` (0: treadmill), pelvis yaw swinging ±5°, 2 mm noise;
    after frame ``turn_at`` the subject has turned round and walks back."""
    from msk.model.core import forward_kinematics

    data = model.create_data()
    forward_kinematics(model, data, model.default_coordinates())
    pos = np.array([data.oMf[model.marker_frame[n]].translation for n in model.marker_names])
    pos = pos @ _Y_TO_Z.T  # Z-up, facing lab +x
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 100.0
    out = np.empty((n, len(pos), 3))
    place = np.zeros(3)
    for k in range(n):
        heading = yaw_deg + (180.0 if turn_at is not None and k >= turn_at else 0.0)
        sway = 5.0 * np.sin(2 * np.pi * t[k])
        r = _rotation(np.array([0, 0, 1.0]), np.radians(heading + sway))
        if k:
            place += speed * 0.01 * _rotation(np.array([0, 0, 1.0]), np.radians(heading))[:, 0]
        out[k] = pos @ r.T + place
    return out + rng.normal(0.0, 0.002, out.shape)


def _faces(model, heading, markers):
    """Unit horizontal direction (model frame) the pelvis faces: sacrum → mid-ASIS."""
    names = model.marker_names
    x = markers @ heading.rotation.T
    mid = 0.5 * (x[:, names.index("R.ASIS")] + x[:, names.index("L.ASIS")])
    d = np.median(mid - x[:, names.index("V.Sacral")], axis=0)
    d[1] = 0.0
    return d / np.linalg.norm(d)


@pytest.mark.parametrize("yaw", [0.0, 37.0, 90.0, 180.0, -123.0])
def test_pelvis_heading_faces_the_model_forward_whatever_the_walking_direction(gait2392, yaw):
    from msk.io.frames import pelvis_heading_rotation

    x = _walk(gait2392, yaw)
    h = pelvis_heading_rotation((0, 0, 1), (0, 1, 0), x, gait2392.marker_names, gait2392)
    assert h.source == "pelvis markers"
    assert set(h.markers) == {"R.ASIS", "L.ASIS", "V.Sacral"}
    np.testing.assert_allclose(h.rotation @ [0, 0, 1.0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(_faces(gait2392, h, x), [1, 0, 0], atol=np.sin(np.radians(1.5)))
    assert h.pelvis_rms_m < 0.015  # the ±5° sway about the median yaw
    # the progression agrees (both ways of finding the heading)
    assert abs(((h.yaw_deg - h.progression_yaw_deg) + 180) % 360 - 180) < 2.0
    np.testing.assert_allclose(
        lab_to_model_rotation((0, 0, 1), (0, 1, 0), x), h.rotation, atol=np.radians(2.0)
    )


def test_pelvis_heading_on_a_treadmill_where_progression_gives_none(gait2392):
    from msk.io.frames import pelvis_heading_rotation

    x = _walk(gait2392, -90.0, speed=0.0)  # facing lab −y, not moving
    np.testing.assert_allclose(  # the centroid cannot tell: levelling only
        lab_to_model_rotation((0, 0, 1), (0, 1, 0), x), rotation_between([0, 0, 1], [0, 1, 0])
    )
    h = pelvis_heading_rotation((0, 0, 1), (0, 1, 0), x, gait2392.marker_names, gait2392)
    assert h.source == "pelvis markers" and np.isnan(h.progression_yaw_deg)
    np.testing.assert_allclose(_faces(gait2392, h, x), [1, 0, 0], atol=np.sin(np.radians(1.5)))


def test_pelvis_heading_when_the_subject_turns_round(gait2392):
    """Out 1.2 m and most of the way back: the progression points backwards (0.3 m net, the
    wrong way); the pelvis heading is the direction faced in most frames."""
    from msk.io.frames import pelvis_heading_rotation

    x = _walk(gait2392, 20.0, n=200, turn_at=80)
    h = pelvis_heading_rotation((0, 0, 1), (0, 1, 0), x, gait2392.marker_names, gait2392)
    assert h.source == "pelvis markers"
    np.testing.assert_allclose(_faces(gait2392, h, x[80:]), [1, 0, 0], atol=np.sin(np.radians(2)))


def test_heading_fallbacks_and_lab_labels(gait2392):
    from msk.io.frames import pelvis_heading_rotation

    names = list(gait2392.marker_names)
    x = _walk(gait2392, 60.0)
    # lab labels + rename (model marker → lab label)
    lab = [{"R.ASIS": "RASI", "L.ASIS": "LASI", "V.Sacral": "SACR"}.get(n, n) for n in names]
    h = pelvis_heading_rotation(
        (0, 0, 1), (0, 1, 0), x, lab, gait2392, rename={"R.ASIS": "RASI", "L.ASIS": "LASI"}
    )
    assert h.source == "pelvis markers" and set(h.markers) == {"R.ASIS", "L.ASIS"}
    np.testing.assert_allclose(_faces(gait2392, h, x), [1, 0, 0], atol=np.sin(np.radians(1.5)))
    # swapped ASIS (a mirror image no rotation fits) → the progression
    swapped = names.copy()
    i, j = swapped.index("R.ASIS"), swapped.index("L.ASIS")
    swapped[i], swapped[j] = swapped[j], swapped[i]
    h = pelvis_heading_rotation((0, 0, 1), (0, 1, 0), x, swapped, gait2392)
    assert h.source == "progression" and "fit" in h.message
    # no pelvis marker → the progression; standing still too → levelling only
    other = [n if n not in ("R.ASIS", "L.ASIS", "V.Sacral") else f"x{n}" for n in names]
    h = pelvis_heading_rotation((0, 0, 1), (0, 1, 0), x, other, gait2392)
    assert h.source == "progression"
    np.testing.assert_allclose(h.rotation, lab_to_model_rotation((0, 0, 1), (0, 1, 0), x))
    still = _walk(gait2392, 60.0, speed=0.0)
    h = pelvis_heading_rotation((0, 0, 1), (0, 1, 0), still, other, gait2392)
    assert h.source == "none" and "progression" in h.message
    np.testing.assert_allclose(h.rotation, rotation_between([0, 0, 1], [0, 1, 0]))


def test_pelvis_heading_on_real_walks(gait2392):
    """GC5 PS overground (Z-up c3d): pelvis and progression agree; DM on the treadmill (Y-up
    TRC, standing in place): only the pelvis can tell, and it faces the belt's direction."""
    from msk.io import read_trc_trial
    from msk.io.frames import pelvis_heading_rotation
    from msk.model.markersets import recognise

    tr = read_c3d(GC5 / "PS_ngait_og_ss1.c3d")
    m = recognise(tr.marker_labels, gait2392.marker_names)
    h = pelvis_heading_rotation(
        tr.up, (0, 1, 0), tr.markers, tr.marker_labels, gait2392, rename=m.rename
    )
    assert h.source == "pelvis markers"
    assert abs(((h.yaw_deg - h.progression_yaw_deg) + 180) % 360 - 180) < 5.0
    path = REAL / "knee-grand-challenge-gc6-DM" / "DM_ngait_tm_ss1_new.trc"
    if not path.exists():
        pytest.skip(f"{path} absent")
    tr = read_trc_trial(path)
    m = recognise(tr.marker_labels, gait2392.marker_names)
    h = pelvis_heading_rotation(
        tr.up, (0, 1, 0), tr.markers, tr.marker_labels, gait2392, rename=m.rename
    )
    assert h.source == "pelvis markers" and np.isnan(h.progression_yaw_deg)
    assert h.pelvis_rms_m < 0.03
    # the feet swing along the model's x: heel x-range ≫ z-range
    heel = tr.markers[:, tr.marker_labels.index("R_Heel")] @ h.rotation.T
    span = np.nanpercentile(heel, 95, axis=0) - np.nanpercentile(heel, 5, axis=0)
    assert span[0] > 3 * abs(span[2])


@pytest.mark.parametrize("k", [1, 2])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_up_from_ground_reactions_finds_the_axis_and_its_side(k, sign):
    """Markers standing on a plate in a lab whose up is ±axis k: the largest force axis and
    the markers' side of the COPs' surface give it; no loaded COP gives None."""
    from msk.io.frames import up_from_ground_reactions

    rng = np.random.default_rng(k)
    n = 50
    f = rng.normal(0.0, 20.0, (n, 3))
    f[:, k] = sign * (600.0 + rng.normal(0.0, 30.0, n))  # the reaction on the subject: up
    cop = rng.uniform(0.2, 0.8, (n, 3))
    cop[:, k] = 0.02 * sign
    markers = rng.uniform(0.0, 1.0, (n, 10, 3))
    markers[..., k] = sign * rng.uniform(0.05, 1.7, (n, 10))
    markers[3, 4] = np.nan
    up = up_from_ground_reactions(markers, [f], [cop])
    want = np.zeros(3)
    want[k] = sign
    assert up is not None and np.array_equal(up, want)
    # a lab with the action recorded (force down) still stands the subject on the plates
    assert np.array_equal(up_from_ground_reactions(markers, [-f], [cop]), want)
    assert up_from_ground_reactions(markers, [0.0 * f], [cop]) is None
