"""msk.io.c3d plausibility: a frame count the header and POINT:FRAMES disagree on, plates
declared but not described, plate forces a decade off, marker teleports — each read as far as
the file allows and said by a typed reader flag (``Trial.metadata["flags"]``), or refused with
one line naming the file and the values. Mutants of real files and synthetic known truths."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from msk.exceptions import C3DError
from msk.io import read_c3d
from msk.io.c3d import PlateSpec, _decode, write_c3d
from msk.io.marker_checks import find_teleports
from msk.io.plate_checks import scale_flags
from msk.quality import plate_scale_factor
from msk.trial import Subject
from tests.support.c3d_mutants import parameters, set_value

PS = "knee-grand-challenge-gc5/PS_ngait_og_ss1.c3d"  # 145 frames at 120 Hz, 3 type-2 plates


def _read(path: Path):
    return read_c3d(path, isolate=False)


def _flags(tr, quantity: str) -> list[dict]:
    return [f for f in tr.metadata.get("flags", ()) if f["quantity"] == quantity]


def _write(tmp_path: Path, data: bytes | bytearray, name: str = "mutant.c3d") -> Path:
    out = tmp_path / name
    out.write_bytes(bytes(data))
    return out


def _set_last_frame(data: bytearray, frames: int) -> None:
    """The header's last frame (word 5) set for ``frames`` frames from its first (word 4)."""
    _, proc, _ = parameters(bytes(data))
    fmt = ">H" if proc == 86 else "<H"
    (first,) = struct.unpack(fmt, bytes(data[6:8]))
    data[8:10] = struct.pack(fmt, first + frames - 1)


def _param(data: bytes, group: str, name: str) -> np.ndarray:
    _, proc, params = parameters(data)
    v = _decode(params[(group, name)], proc)
    assert v is not None
    return v


@pytest.fixture(scope="module")
def ps(real_dir):
    src = (real_dir / PS).read_bytes()
    return src, read_c3d(real_dir / PS, isolate=False)


# --- 1. frame count: header vs POINT:FRAMES vs the data present -----------------------------
def test_frames_parameter_disagreeing_reads_the_header_and_flags(ps, tmp_path):
    src, ref = ps
    d = bytearray(src)
    set_value(d, ("POINT", "FRAMES"), 99)
    tr = _read(_write(tmp_path, d))
    np.testing.assert_array_equal(tr.markers, ref.markers)  # the same numbers as the original
    (f,) = _flags(tr, "c3d_frame_count_mismatch")
    assert "header declares 145 frames, POINT:FRAMES = 99" in f["message"]
    assert "the header's 145 read" in f["message"]
    assert f["message"] in tr.metadata["warnings"]


def test_a_header_past_the_data_reads_point_frames(ps, tmp_path):
    src, ref = ps
    d = bytearray(src)
    _set_last_frame(d, 400)  # the header promises 400 frames, the data hold 145
    tr = _read(_write(tmp_path, d))
    assert tr.n_frames == 145
    np.testing.assert_array_equal(tr.markers, ref.markers)
    (f,) = _flags(tr, "c3d_frame_count_mismatch")
    assert "POINT:FRAMES's 145 read" in f["message"] and "400 frames" in f["message"]


def test_a_short_header_reads_its_frames_and_says_what_is_left(ps, tmp_path):
    src, ref = ps
    d = bytearray(src)
    _set_last_frame(d, 100)
    tr = _read(_write(tmp_path, d))
    assert tr.n_frames == 100
    np.testing.assert_array_equal(tr.markers, ref.markers[:100])
    (f,) = _flags(tr, "c3d_frame_count_mismatch")
    assert "45 frames after them are not read" in f["message"]


def test_irreconcilable_frame_counts_are_one_line(ps, tmp_path):
    src, _ = ps
    d = bytearray(src)
    set_value(d, ("POINT", "FRAMES"), 300)
    _set_last_frame(d, 400)
    msg = r"mutant\.c3d: the header declares 400 frames, POINT:FRAMES = 300, and the data"
    with pytest.raises(C3DError, match=msg + r" section holds 145 whole frames"):
        _read(_write(tmp_path, d))


def test_synthetic_frame_counts_known_truth(tmp_path):
    n = 80
    x = np.zeros((n, 2, 3))
    x[:, 0, 0] = (1 + np.arange(n)) * 1e-3  # the frame number, in mm
    x[:, 1] = [0.1, 0.2, 1.0]
    p = write_c3d(tmp_path / "s.c3d", markers=x, marker_labels=["A", "B"], rate_hz=100.0)
    d = bytearray(p.read_bytes())
    set_value(d, ("POINT", "FRAMES"), 50)
    tr = _read(_write(tmp_path, d))
    np.testing.assert_allclose(tr.markers[:, 0, 0], (1 + np.arange(n)) * 1e-3, atol=1e-7)
    assert _flags(tr, "c3d_frame_count_mismatch")
    assert not _read(p).metadata.get("flags")


# --- 2. plates declared but not described, or on channels the file lacks ---------------------
def test_a_plate_declared_but_not_described_is_dropped_and_flagged(ps, tmp_path):
    src, ref = ps
    d = bytearray(src)
    set_value(d, ("FORCE_PLATFORM", "USED"), 4)
    tr = _read(_write(tmp_path, d))
    assert [p.index for p in tr.plates] == [0, 1, 2]
    for a, b in zip(tr.plates, ref.plates):
        np.testing.assert_array_equal(a.force, b.force)
    (f,) = _flags(tr, "c3d_plate_missing")
    assert f["message"].startswith("force platform 4: FORCE_PLATFORM:USED = 4")


def test_a_plate_on_a_missing_channel_is_dropped_naming_plate_and_channel(ps, tmp_path):
    src, ref = ps
    d = bytearray(src)
    set_value(d, ("FORCE_PLATFORM", "CHANNEL"), 99, index=6 + 2)  # plate 2's Fz
    tr = _read(_write(tmp_path, d))
    assert [p.index for p in tr.plates] == [0, 2]
    np.testing.assert_array_equal(tr.plates[1].force, ref.plates[2].force)
    (f,) = _flags(tr, "c3d_plate_channel_missing")
    assert "force platform 2" in f["message"] and "analog channel 99" in f["message"]


def test_plates_described_while_used_is_zero_are_said(ps, tmp_path):
    src, _ = ps
    d = bytearray(src)
    set_value(d, ("FORCE_PLATFORM", "USED"), 0)
    tr = _read(_write(tmp_path, d))
    assert tr.plates == ()
    (f,) = _flags(tr, "c3d_plates_not_declared")
    assert f["value"] == 3 and "FORCE_PLATFORM:USED is 0" in f["message"]


# --- 3. plate forces a decade off ------------------------------------------------------------
def test_one_channel_scaled_by_ten_is_flagged_with_the_factor(ps, tmp_path):
    src, ref = ps
    assert not _flags(ref, "plate_force_scale")
    d = bytearray(src)
    fz = int(_param(src, "FORCE_PLATFORM", "CHANNEL")[2]) - 1  # plate 1's Fz channel
    scale = _param(src, "ANALOG", "SCALE")
    set_value(d, ("ANALOG", "SCALE"), 10.0 * float(scale[fz]), index=fz)
    tr = _read(_write(tmp_path, d))
    (f,) = _flags(tr, "plate_force_scale")
    assert f["value"] == 10.0 and f["message"].startswith("force platform 1 weighs")
    np.testing.assert_allclose(tr.plates[0].force[:, 2], ref.plates[0].force[:, 2] * 10, rtol=1e-6)


def test_gen_scale_by_ten_on_every_plate_is_flagged(ps, tmp_path):
    src, _ = ps
    d = bytearray(src)
    set_value(d, ("ANALOG", "GEN_SCALE"), 10.0 * float(_param(src, "ANALOG", "GEN_SCALE")[0]))
    tr = _read(_write(tmp_path, d))
    got = _flags(tr, "plate_force_scale")
    assert len(got) == 3 and {f["value"] for f in got} == {10.0}


def _stance_plate(tmp_path: Path, mass_kg: float, gain: float, subject_mass: float | None):
    """One plate under a walking stance of a ``mass_kg`` subject (double-hump vertical force
    with a mean of 0.85 body weight over 0.6 s), its channels × ``gain``."""
    rate, ratio = 100.0, 10
    n = 120
    ta = np.arange(n * ratio) / (rate * ratio)
    s = np.clip((ta - 0.2) / 0.6, 0.0, 1.0)
    shape = np.where((s > 0) & (s < 1), np.sin(np.pi * s) * (1.0 + 0.25 * np.cos(2 * np.pi * s)),
                     0.0)  # fmt: skip
    fz = shape * 0.85 * mass_kg * 9.81 / shape[shape > 0].mean()
    ch = np.zeros((n * ratio, 6))
    ch[:, 2] = -fz * gain  # a z-down plate: its Fz channel reads the reaction downwards
    x = np.tile(np.array([[[0.1, 0.2, 1.0]]]), (n, 1, 1))
    corners = np.array([[0.25, 0.25, 0], [-0.25, 0.25, 0], [-0.25, -0.25, 0], [0.25, -0.25, 0]])
    corners = corners @ np.diag([1.0, -1.0, -1.0])  # plate axes: z down
    plate = PlateSpec(channels=("Fx", "Fy", "Fz", "Mx", "My", "Mz"), corners_m=corners,
                      origin_m=np.array([0.0, 0.0, -0.04]))  # fmt: skip
    subject = Subject(mass_kg=subject_mass) if subject_mass else None
    return write_c3d(tmp_path / f"p{gain}.c3d", markers=x, marker_labels=["M"], rate_hz=rate,
                     analogs=ch, analog_labels=list(plate.channels), analog_ratio=ratio,
                     plates=[plate], subject=subject)  # fmt: skip


@pytest.mark.parametrize(("gain", "factor"), [(1.0, None), (10.0, 10.0), (0.1, 0.1)])
def test_synthetic_stance_weighs_the_known_mass(tmp_path, gain, factor):
    tr = _read(_stance_plate(tmp_path, 70.0, gain, subject_mass=70.0))
    got = _flags(tr, "plate_force_scale")
    assert [f["value"] for f in got] == ([] if factor is None else [factor])
    # without a mass a decade up is no human's weight; a decade down a toddler's (not said)
    no_mass = scale_flags(tr.plates, tr.up, None)
    assert [f["value"] for f in no_mass] == ([10.0] if gain == 10.0 else [])


def test_plate_scale_factor_of_the_pipeline():
    assert plate_scale_factor(700.0, 70.0) == 10.0
    assert plate_scale_factor(6.8, 70.0) == 0.1
    assert plate_scale_factor(75.0, 70.0) is None  # a wrong mass, not a decade
    assert plate_scale_factor(300.0, 70.0) is None


# --- 4. marker teleports ---------------------------------------------------------------------
def _smooth(n: int, rate: float, seed: int) -> np.ndarray:
    """Markers on a running gait: the foot swings at up to 10 m/s, ±1 mm noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate
    x = np.zeros((n, 4, 3))
    x[:, :, 0] = 4.0 * t[:, None]  # 4 m/s forward
    x[:, 0, 0] += 0.5 * np.sin(2 * np.pi * 1.4 * t)  # a foot: ±0.5 m at 1.4 Hz, ~ ±8.8 m/s
    x[:, 0, 2] = 0.1 + 0.1 * np.abs(np.sin(2 * np.pi * 1.4 * t))  # its heel strikes (a kink)
    x[:, 1:, 1] = [0.1, 0.2, 0.3]
    x[:, 1:, 2] = [0.5, 0.9, 1.3]
    return x + rng.normal(0.0, 1e-3, x.shape)


@pytest.mark.parametrize("rate", [100.0, 250.0])
def test_synthetic_teleports_recovered_and_no_false_alarm(rate):
    x = _smooth(int(3 * rate), rate, seed=3)
    labels = ["FOOT", "A", "B", "C"]
    assert find_teleports(x, labels, rate) == []
    y = x.copy()
    y[100, 0] += [0.0, 0.12, 0.0]  # one frame on a ghost 120 mm away
    y[200:205, 2] = y[200:205, 3]  # B swapped with C (400 mm) for 5 frames
    got = sorted((t.label, t.first, t.last) for t in find_teleports(y, labels, rate))
    assert got == [("B", 200, 204), ("FOOT", 100, 100)]


def test_a_teleport_in_a_real_trial_becomes_a_gap_and_a_flag(ps, tmp_path):
    import ezc3d

    src, ref = ps
    c = ezc3d.c3d(str(_write(tmp_path, src, "o.c3d")))
    labels = [s.strip() for s in c["parameters"]["POINT"]["LABELS"]["value"]]
    k = labels.index(ref.marker_labels[5])
    pts = c["data"]["points"]
    pts[1, k, 60:63] += 90.0  # mm: three frames 90 mm off
    c["data"]["points"] = pts
    c.write(str(tmp_path / "t.c3d"))
    tr = _read(tmp_path / "t.c3d")
    assert np.isnan(tr.markers[60:63, 5]).all()
    keep = np.ones(tr.n_frames, dtype=bool)
    keep[60:63] = False
    np.testing.assert_allclose(tr.markers[keep, 5], ref.markers[keep, 5], atol=1e-6)
    (f,) = _flags(tr, "marker_teleport_samples")
    assert f["value"] == 3 and f"{ref.marker_labels[5]} frames 61–63 (90 mm)" in f["message"]


def test_the_ghost_in_unipd_walking3(real_dir):
    tr = _read(real_dir / "motonms-testdata/UNIPD/Walking3.c3d")
    (f,) = _flags(tr, "marker_teleport_samples")
    assert "RHF frames 252–253 (153 mm)" in f["message"]
    assert np.isnan(tr.marker("RHF")[251:253]).all()


def test_plates_described_beyond_used_are_said(ps, tmp_path):
    src, ref = ps
    d = bytearray(src)
    set_value(d, ("FORCE_PLATFORM", "USED"), 2)
    tr = _read(_write(tmp_path, d))
    assert [p.index for p in tr.plates] == [0, 1]
    np.testing.assert_array_equal(tr.plates[1].force, ref.plates[1].force)
    (f,) = _flags(tr, "c3d_plates_not_declared")
    assert (
        "USED = 2" in f["message"] and "force platform(s) 3 on analog channels Fx3" in f["message"]
    )


def test_a_channel_used_twice_by_one_plate_is_one_line(ps, tmp_path):
    from msk.exceptions import ForcePlateError

    src, _ = ps
    d = bytearray(src)
    set_value(d, ("FORCE_PLATFORM", "CHANNEL"), 2, index=2)  # plate 1's Fz reads Fy1
    with pytest.raises(ForcePlateError, match=r"force platform 1 uses analog channel 2 \('Fy1'\) "
                       "for two of its components"):  # fmt: skip
        _read(_write(tmp_path, d))


@pytest.mark.parametrize(("index", "channel", "said"), [(2, 19, "'gracilis' as its Fz"),
                                                         (3, 6, "'Mz1' as its Mx")])  # fmt: skip
def test_a_plate_channel_pointing_at_another_signal_is_said(ps, tmp_path, index, channel, said):
    src, _ = ps
    d = bytearray(src)
    if channel == 6:  # Mx and Mz of plate 1 exchanged: no channel twice
        set_value(d, ("FORCE_PLATFORM", "CHANNEL"), 6, index=3)
        set_value(d, ("FORCE_PLATFORM", "CHANNEL"), 4, index=5)
    else:
        set_value(d, ("FORCE_PLATFORM", "CHANNEL"), channel, index=index)
    tr = _read(_write(tmp_path, d))
    (f,) = _flags(tr, "c3d_plate_channel_label")
    assert f["message"].startswith("force platform 1 reads") and said in f["message"]


def test_no_real_plate_channel_is_misread(real_dir):
    import glob

    for f in sorted(glob.glob(str(real_dir / "**/*.c3d"), recursive=True)):
        assert not _flags(_read(Path(f)), "c3d_plate_channel_label"), f
