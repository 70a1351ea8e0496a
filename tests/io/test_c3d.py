"""read_c3d / write_c3d on synthetic trials with known content."""

from __future__ import annotations

import dataclasses

import ezc3d
import numpy as np
import pytest

from msk.exceptions import MissingDataError
from msk.io import read_c3d


@pytest.mark.parametrize("units", ["mm", "m", "cm"])
def test_markers_round_trip_in_any_unit(synth, units):
    path, truth = synth(units=units)
    tr = read_c3d(path)
    assert tr.point_units_in_file == units
    assert tr.marker_labels == tuple(truth["labels"])
    assert tr.markers.shape == truth["markers"].shape
    gap = np.isnan(truth["markers"])
    np.testing.assert_array_equal(np.isnan(tr.markers), gap)
    # C3D stores float32: relative precision ~6e-8
    np.testing.assert_allclose(tr.markers[~gap], truth["markers"][~gap], rtol=2e-7, atol=1e-9)
    np.testing.assert_allclose(tr.time, truth["time"], atol=1e-12)
    assert tr.point_rate_hz == truth["rate"]
    np.testing.assert_array_equal(tr.marker("RASI"), tr.markers[:, 1])


def test_gap_report(synth):
    path, _ = synth()
    g = read_c3d(path).gaps
    assert g.labels == ("LASI", "RASI", "LKNE", "RKNE")
    np.testing.assert_array_equal(g.n_missing, [0, 5, 0, 3])
    np.testing.assert_array_equal(g.longest_gap, [0, 4, 0, 3])
    assert g.with_gaps() == ("RASI", "RKNE")


def test_analogs_round_trip_and_point_rate(synth):
    path, truth = synth(ratio=10)
    tr = read_c3d(path)
    assert tr.analog_rate_hz == truth["rate"] * 10
    assert tr.analog_labels == tuple(truth["analog_labels"])
    assert tr.analog_units == tuple(truth["analog_units"])
    np.testing.assert_allclose(tr.analogs, truth["analogs"], rtol=2e-7, atol=1e-10)
    emg = tr.analog("EMG_VL")
    low = tr.to_point_rate(emg)
    assert low.shape == (tr.n_frames,)
    np.testing.assert_allclose(low, emg.reshape(-1, 10).mean(axis=1))
    np.testing.assert_allclose(tr.analog_time[::10], tr.time)
    # a non-integer ratio interpolates onto the point times
    odd = dataclasses.replace(tr, analog_rate_hz=1234.0, analog_time=np.arange(emg.size) / 1234.0)
    lin = odd.to_point_rate(np.arange(emg.size, dtype=float))
    np.testing.assert_allclose(lin[:40], tr.time[:40] * 1234.0)


def test_missing_channel_errors_name_file_and_label(synth):
    path, _ = synth()
    tr = read_c3d(path)
    with pytest.raises(MissingDataError, match=rf"{path.name}.*'LHEE'"):
        tr.marker("LHEE")
    with pytest.raises(MissingDataError, match=rf"{path.name}.*'EMG_XX'"):
        tr.analog("EMG_XX")


@pytest.mark.parametrize("units", ["mm", "m"])
def test_type2_plate_recovers_known_wrench(synth, units):
    """Channels built from a known lab wrench (force, COP, free moment) come back in SI."""
    path, truth = synth(units=units)
    tr = read_c3d(path, cop_threshold_n=20.0)
    (p,) = tr.plates
    assert p.type == 2 and p.rate_hz == tr.analog_rate_hz
    np.testing.assert_allclose(p.force, truth["force"], atol=1e-3)
    np.testing.assert_allclose(p.rotation, truth["rot"], atol=1e-12)
    np.testing.assert_allclose(p.origin, truth["centre"], atol=1e-7)
    loaded = np.abs(truth["force"] @ truth["rot"][:, 2]) >= 20.0
    assert 0 < loaded.sum() < loaded.size
    assert np.isnan(p.cop[~loaded]).all()
    np.testing.assert_allclose(p.cop[loaded], truth["cop"][loaded], atol=2e-5)
    tz = p.free_moment @ p.normal
    np.testing.assert_allclose(tz[loaded], truth["tz"][loaded], atol=2e-3)
    np.testing.assert_array_equal(p.free_moment[~loaded], 0.0)
    # moment about the surface centre = (cop - c) x F + T n
    m_c = np.cross(truth["cop"] - truth["centre"], truth["force"]) + truth["tz"][:, None] * p.normal
    np.testing.assert_allclose(p.moment, m_c, atol=2e-3)
    assert tr.vertical_axis == 2 and tr.up.tolist() == [0.0, 0.0, 1.0]
    assert p.peak_force_n == pytest.approx(np.linalg.norm(truth["force"], axis=1).max(), rel=1e-5)


def test_y_up_lab_is_detected(synth, plate_rot_yup):
    path, truth = synth(rot=plate_rot_yup)
    tr = read_c3d(path)
    assert tr.vertical_axis == 1 and tr.up.tolist() == [0.0, 1.0, 0.0]
    np.testing.assert_allclose(tr.plates[0].force, truth["force"], atol=1e-3)


def test_plates_agree_with_ezc3d_extraction(synth):
    path, _ = synth()
    tr = read_c3d(path)
    ref = ezc3d.c3d(str(path), extract_forceplat_data=True)["data"]["platform"][0]
    p = tr.plates[0]
    np.testing.assert_allclose(p.force, ref["force"].T, atol=1e-9)
    np.testing.assert_allclose(p.moment * 1e3, ref["moment"].T, atol=1e-6)
    ok = np.isfinite(p.cop[:, 0])
    np.testing.assert_allclose(p.cop[ok] * 1e3, ref["center_of_pressure"].T[ok], atol=1e-6)
    np.testing.assert_allclose(p.free_moment[ok] * 1e3, ref["Tz"].T[ok], atol=1e-6)


def test_events_sorted_and_subject(synth):
    path, _ = synth()
    tr = read_c3d(path)
    assert [(e.time, e.context, e.label) for e in tr.events] == [
        (pytest.approx(0.05), "Left", "Foot Strike"),
        (pytest.approx(0.12), "Right", "Foot Strike"),
        (pytest.approx(0.31), "Left", "Foot Off"),
    ]
    assert tr.events_named("Foot Strike", "Left") == (pytest.approx(0.05),)
    assert tr.subject.name == "Synth"
    assert tr.subject.mass_kg == pytest.approx(71.5)
    assert tr.subject.height_m == pytest.approx(1.78)


def test_first_frame_offsets_time(synth, tmp_path):
    from msk.io import write_c3d

    x = np.ones((5, 1, 3))
    p = write_c3d(
        tmp_path / "ff.c3d", markers=x, marker_labels=["A"], rate_hz=50.0, first_frame=100
    )
    tr = read_c3d(p)
    np.testing.assert_allclose(tr.time, (100 + np.arange(5)) / 50.0)
    assert tr.duration_s == pytest.approx(0.1)


def test_trial_is_frozen(synth):
    path, _ = synth()
    tr = read_c3d(path)
    with pytest.raises(dataclasses.FrozenInstanceError):
        tr.markers = None  # type: ignore[misc]


def test_type4_calibration_matrix_is_applied(tmp_path):
    """Type 4: channels are raw signals; wrench = CAL_MATRIX @ channels (plate axes)."""
    from msk.io import PlateSpec, write_c3d

    rng = np.random.default_rng(5)
    n, ratio = 20, 4
    na = n * ratio
    wrench = np.column_stack(
        [rng.normal(0, 10, (na, 2)), 600 + rng.normal(0, 50, na), rng.normal(0, 5e4, (na, 3))]
    )
    cal = np.eye(6) * rng.uniform(0.5, 2.0, 6) + 0.01 * rng.normal(size=(6, 6))
    raw = wrench @ np.linalg.inv(cal).T
    corners = np.array([[0.6, 0.4, 0.0], [0.0, 0.4, 0.0], [0.0, 0.0, 0.0], [0.6, 0.0, 0.0]])
    labels = [f"C{k}" for k in range(6)]
    p = write_c3d(
        tmp_path / "t4.c3d",
        markers=np.ones((n, 1, 3)),
        marker_labels=["A"],
        rate_hz=100.0,
        point_units="mm",
        analogs=raw,
        analog_labels=labels,
        analog_ratio=ratio,
        plates=[PlateSpec(tuple(labels), corners, np.zeros(3), type=4, cal_matrix=cal)],
    )
    (plate,) = read_c3d(p).plates
    assert plate.type == 4
    # corners give x = +X, y = +Y, z = +Z: plate axes are the lab axes
    np.testing.assert_allclose(plate.rotation, np.eye(3), atol=1e-12)
    # channels are stored as float32 and the cross-talk terms cancel: ~1e-4 N round-off
    np.testing.assert_allclose(plate.force, wrench[:, :3], rtol=1e-5, atol=1e-3)
    np.testing.assert_allclose(plate.moment, wrench[:, 3:] * 1e-3, rtol=1e-5, atol=1e-4)
    ref = ezc3d.c3d(str(p), extract_forceplat_data=True)["data"]["platform"][0]
    np.testing.assert_allclose(plate.force, ref["force"].T, atol=1e-9)
    np.testing.assert_allclose(plate.moment * 1e3, ref["moment"].T, atol=1e-6)


def test_subject_parameters_whatever_their_case(synth, tmp_path):
    """UWA's pipeline writes ``PROCESSING:BodyMass`` where Vicon writes ``Bodymass``: the mass
    is read either way; a zero or negative mass is none."""
    import ezc3d

    from msk.io.c3d import _set_param

    path, _ = synth()
    c = ezc3d.c3d(str(path))
    c["parameters"]["PROCESSING"].pop("Bodymass", None)
    _set_param(c, "PROCESSING", "BodyMass", [67.0])
    _set_param(c, "PROCESSING", "HEIGHT", [1820.0])
    c.write(str(tmp_path / "uwa.c3d"))
    s = read_c3d(tmp_path / "uwa.c3d").subject
    assert s.mass_kg == pytest.approx(67.0) and s.height_m == pytest.approx(1.82)
    _set_param(c, "PROCESSING", "BodyMass", [0.0])
    c.write(str(tmp_path / "zero.c3d"))
    assert read_c3d(tmp_path / "zero.c3d").subject.mass_kg is None


def test_plug_in_gait_hip_parameters_are_read(synth, tmp_path):
    """Plug-in Gait's hip-centre inputs (``PROCESSING:RLegLength``…, mm): read in m per side;
    a zero (Vicon's "not measured") is none."""
    import ezc3d

    from msk.io.c3d import _set_param

    path, _ = synth()
    c = ezc3d.c3d(str(path))
    _set_param(c, "PROCESSING", "RLegLength", [920.0])
    _set_param(c, "PROCESSING", "LLegLength", [915.0])
    _set_param(c, "PROCESSING", "RAsisTrocanterDistance", [69.9])
    _set_param(c, "PROCESSING", "LAsisTrocanterDistance", [0.0])
    _set_param(c, "PROCESSING", "InterAsisDistance", [245.2])
    c.write(str(tmp_path / "pig.c3d"))
    s = read_c3d(tmp_path / "pig.c3d").subject
    assert s.leg_lengths_m == pytest.approx({"R": 0.92, "L": 0.915})
    assert s.asis_trochanter_m == pytest.approx({"R": 0.0699})
    assert s.inter_asis_m == pytest.approx(0.2452)
