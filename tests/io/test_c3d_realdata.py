"""Every real C3D loads; specific facts from the data README; plates vs ezc3d and OpenSim."""

from __future__ import annotations

from pathlib import Path

import ezc3d
import numpy as np
import pytest

from msk.cli import main
from msk.datasets.shared import real_data_dir
from msk.io import read_c3d
from msk.io.opensim_files import read_sto

pytestmark = [pytest.mark.slow, pytest.mark.realdata]

_REAL = real_data_dir()
C3D_FILES = sorted(_REAL.rglob("*.c3d")) if _REAL.is_dir() else []
G = 9.80665


@pytest.mark.parametrize("path", C3D_FILES, ids=lambda p: str(p.relative_to(_REAL)))
def test_every_real_c3d_loads_and_agrees_with_ezc3d(real_dir, path, capsys):
    tr = read_c3d(path)
    assert tr.point_rate_hz > 0 and tr.markers.shape[0] == tr.n_frames
    assert tr.markers.shape[2] == 3 and len(tr.marker_labels) == tr.markers.shape[1]
    assert tr.analogs.shape[1] == len(tr.analog_labels) == len(tr.analog_units)
    # positions in metres: a lab is a few metres wide
    assert np.nanmax(np.abs(tr.markers), initial=0.0) < 20.0
    ref = ezc3d.c3d(str(path), extract_forceplat_data=True)["data"]["platform"]
    assert len(ref) == len(tr.plates)
    for p, q in zip(tr.plates, ref):
        np.testing.assert_allclose(p.force, q["force"].T, atol=1e-6, equal_nan=True)
        ok = np.isfinite(p.cop[:, 0])
        if p.type == 1:
            # type 1 (COP + free moment channels): ezc3d reports the moment of −F about the
            # centre; msk keeps M = (c − o) × F + T, the same wrench as F at the COP
            np.testing.assert_allclose(p.moment * 1e3, -q["moment"].T, atol=1e-4)
            m = np.cross(p.cop[ok] - p.origin, p.force[ok]) + p.free_moment[ok]
            np.testing.assert_allclose(p.moment[ok], m, atol=1e-9)
        else:
            np.testing.assert_allclose(p.moment * 1e3, q["moment"].T, atol=1e-4, equal_nan=True)
        np.testing.assert_allclose(p.cop[ok] * 1e3, q["center_of_pressure"].T[ok], atol=1e-4)
        tz_ref = q["Tz"].T[ok] @ p.normal
        np.testing.assert_allclose(p.free_moment[ok] @ p.normal * 1e3, tz_ref, atol=2.0)
        np.testing.assert_allclose(p.corners, q["corners"].T * 1e-3, atol=1e-9)
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert f"{tr.point_rate_hz:g} Hz, {tr.n_frames} frames" in out
    assert f"markers: {len(tr.marker_labels)} " in out
    assert f"force platforms: {len(tr.plates)}" in out
    for p in tr.plates:
        assert f"plate {p.index + 1}: type {p.type}, peak force {p.peak_force_n:.1f} N" in out


def test_grand_challenge_ps(real_dir, capsys):
    path = real_dir / "knee-grand-challenge-gc5" / "PS_ngait_og_ss1.c3d"
    tr = read_c3d(path)
    assert tr.point_rate_hz == 120.0 and tr.analog_rate_hz == 1200.0
    assert len(tr.plates) == 3 and [p.type for p in tr.plates] == [2, 2, 2]
    np.testing.assert_allclose(
        [p.peak_force_n for p in tr.plates], [847.5, 863.9, 908.5], atol=0.06
    )
    plate_ch = {c for p in tr.plates for c in p.channels}
    others = [lab for lab in tr.analog_labels if lab not in plate_ch]
    assert len(others) == 18 and {"load cell", "goniometer"} <= set(others)
    emg = [lab for lab in others if lab not in ("load cell", "goniometer")]
    assert len(emg) == 16 and "gracilis" in emg and "sartorius" in emg
    assert all(tr.analog_units[tr.analog_labels.index(lab)] == "V" for lab in emg)
    assert tr.vertical_axis == 2
    assert [e.label for e in tr.events] == ["Foot Strike", "Foot Off", "Foot Strike"]
    assert all(e.context == "Left" for e in tr.events)
    assert tr.time[0] <= tr.events[0].time <= tr.time[-1]
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "gracilis [V]  FLAT/UNUSED?" in out  # the README's flat channel
    assert "vaslat [V]\n" in out


def test_bts_is_y_up(real_dir):
    tr = read_c3d(real_dir / "ezc3d-testfiles" / "BTS.c3d")
    assert tr.vertical_axis == 1 and tr.up.tolist() == [0.0, 1.0, 0.0]
    assert len(tr.plates) == 6
    loaded = [p for p in tr.plates if p.peak_force_n > 100]
    assert len(loaded) == 3
    for p in loaded:  # the reaction is upward along +Y where the plate is loaded
        assert np.nanmax(p.force[:, 1]) > 500


def test_eb015pi_integer_format(real_dir):
    path = real_dir / "btkdata" / "Eb015pi.c3d"
    assert path.read_bytes()[0] >= 2
    tr = read_c3d(path)
    assert tr.point_rate_hz == 50.0 and tr.analog_rate_hz == 200.0
    assert tr.n_frames == 450 and len(tr.marker_labels) == 26
    np.testing.assert_allclose([p.peak_force_n for p in tr.plates], [839.8, 837.2], atol=0.06)
    assert tr.subject.mass_kg == pytest.approx(82.7, abs=0.01)


def test_fp_type3_kistler(real_dir):
    tr = read_c3d(real_dir / "ezc3d-testfiles" / "FP_Type3.c3d")
    assert [p.type for p in tr.plates] == [3, 3]
    assert all(len(p.channels) == 8 for p in tr.plates)
    assert tr.plates[0].peak_force_n == pytest.approx(886.7, abs=0.06)


def test_functional_static_subject_and_body_weight(real_dir):
    tr = read_c3d(real_dir / "btkdata" / "FunctionalStatic.c3d")
    assert tr.subject.mass_kg == pytest.approx(60.0)
    assert tr.subject.height_m == pytest.approx(1.68)
    assert len(tr.plates) == 3 and len(tr.model_outputs.labels) == 12
    assert set(tr.model_outputs.kinds) == {"ANGLES"}
    total = sum(p.force for p in tr.plates) @ tr.up
    # quiet standing on the plates: the summed vertical reaction is the body weight
    assert np.median(total) == pytest.approx(60.0 * G, rel=0.03)


def test_plug_in_gait_outputs_are_not_markers(real_dir):
    tr = read_c3d(real_dir / "btkdata" / "PiG_Motion3_FF.c3d")
    mo = tr.model_outputs
    assert len(tr.marker_labels) == 61 and len(mo.labels) == 36
    assert not set(mo.labels) & set(tr.marker_labels)
    assert "LKneeMoment" in mo.labels and "LKneeMoment" not in tr.marker_labels
    knee = mo.get("LKneeAnglesV")
    assert mo.units[mo.labels.index("LKneeAnglesV")] == "rad"
    assert 0.5 < np.nanmax(knee[:, 0]) < 1.6  # peak swing knee flexion 30-90 deg
    assert mo.units[mo.labels.index("LKneeMoment")] == "N.m"


def test_emg_only_file_has_zero_markers(real_dir):
    tr = read_c3d(real_dir / "btkdata" / "1123x01EMG.c3d")
    assert tr.markers.shape == (4564, 0, 3)
    assert tr.analogs.shape == (4564, 8) and tr.analog_rate_hz == 1000.0
    assert "Right Rectus Femoris" in tr.analog_labels
    assert tr.duration_s == pytest.approx(4.564)


@pytest.mark.parametrize("ref", ["std_walking2_grfs.sto", "std_cop_walking2_grfs.sto"])
def test_walking2_plates_match_opensim_reference(real_dir, ref):
    """OpenSim's C3DFileAdapter output for walking2.c3d (forces N, points mm, moments N·mm)."""
    d = real_dir / "opensim-core-c3d"
    tr = read_c3d(d / "walking2.c3d")
    s = read_sto(d / ref)
    idx = np.round((s.time - tr.analog_time[0]) * tr.analog_rate_hz).astype(int)
    for k, p in enumerate(tr.plates, start=1):
        f, pt, m = (
            s.data[:, [s.columns.index(f"{q}{k}_{j}") for j in (1, 2, 3)]] for q in ("f", "p", "m")
        )
        np.testing.assert_allclose(p.force[idx], f, atol=1e-6)
        if ref.startswith("std_cop"):
            ok = np.isfinite(p.cop[idx, 0])
            assert ok.sum() >= 10
            np.testing.assert_allclose(p.cop[idx][ok] * 1e3, pt[ok], atol=1e-5)
            np.testing.assert_allclose(p.free_moment[idx][ok] * 1e3, m[ok], atol=1e-4)
        else:
            np.testing.assert_allclose(np.tile(p.origin * 1e3, (idx.size, 1)), pt, atol=1e-4)
            np.testing.assert_allclose(p.moment[idx] * 1e3, m, atol=1e-4)


def test_walking2_markers_match_opensim_trc(real_dir):
    from msk.io.opensim_files import read_trc

    d = real_dir / "opensim-core-c3d"
    tr = read_c3d(d / "walking2.c3d")
    ref = read_trc(d / "std_walking2_markers.trc")
    idx = np.round(ref.time * tr.point_rate_hz).astype(int)
    for lab in ref.labels[:20]:
        a, b = tr.marker(lab)[idx], ref.marker(lab)
        both = np.isfinite(a).all(1) & np.isfinite(b).all(1)
        assert both.sum() > 50
        # the TRC keeps 5 significant digits in mm
        np.testing.assert_allclose(a[both], b[both], atol=6e-5, rtol=0)


def test_path_is_recorded(real_dir):
    p = real_dir / "btkdata" / "Gait.c3d"
    assert read_c3d(p).path == Path(p)
