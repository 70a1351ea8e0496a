"""msk's own C3D data-section reader (``msk.io.c3d._read_data``, ``_parameter_values``) against
ezc3d on every real C3D, block boundaries, ``plate_channels=False`` and files of more than
65 535 frames (``TRIAL:ACTUAL_*_FIELD``)."""

from __future__ import annotations

from pathlib import Path

import ezc3d
import numpy as np
import pytest

from msk.datasets.shared import real_data_dir
from msk.io import c3d as c3d_mod
from msk.io.c3d import PlateSpec, read_c3d, write_c3d

_REAL = real_data_dir()
C3D_FILES = sorted(_REAL.rglob("*.c3d")) if _REAL.is_dir() else []
#: float32 rounding, relative to each channel's (or the points') largest magnitude
RTOL = 1e-6


def _same_values(mine: object, theirs: object) -> bool:
    if isinstance(theirs, list) or isinstance(mine, list):
        return list(mine) == list(theirs)  # type: ignore[call-overload]
    a, b = np.asarray(mine), np.asarray(theirs)
    return a.shape == b.shape and np.allclose(a, b, rtol=RTOL, atol=0.0, equal_nan=True)


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.parametrize("path", C3D_FILES, ids=lambda p: str(p.relative_to(_REAL)))
def test_data_and_parameters_equal_ezc3d(path: Path) -> None:
    lay = c3d_mod._check_bytes(path)
    ref = ezc3d.c3d(str(path))
    vals = c3d_mod._parameter_values(lay.params, lay.proc)
    for group, params in ref["parameters"].items():
        for name, p in params.items():
            if name == "__METADATA__" or name not in vals.get(group, {}):
                continue  # ezc3d's defaults for parameters the file does not have
            assert _same_values(vals[group][name]["value"], p["value"]), (group, name)
    n_ana = lay.n_analog_words // lay.analog_per_frame if lay.analog_per_frame else 0
    xyz, invalid, analogs = c3d_mod._read_data(path, lay, range(n_ana))
    pts = np.asarray(ref["data"]["points"])
    if lay.n_points:
        their = np.transpose(pts[:3], (2, 1, 0))
        their_invalid = np.asarray(ref["data"]["meta_points"]["residuals"])[0].T < 0
        np.testing.assert_array_equal(invalid, their_invalid)
        ok = ~invalid
        scale = np.abs(their[ok]).max(initial=1.0)
        np.testing.assert_allclose(xyz[ok], their[ok], rtol=0, atol=RTOL * scale)
    if n_ana:
        their_a = np.asarray(ref["data"]["analogs"])[0].T
        assert analogs.shape == their_a.shape
        np.testing.assert_array_equal(np.isnan(analogs), np.isnan(their_a))  # missing samples
        peak = np.nan_to_num(np.nanmax(np.abs(their_a), axis=0, initial=0.0))
        diff = np.nan_to_num(np.nanmax(np.abs(analogs - their_a), axis=0, initial=0.0))
        assert (diff <= RTOL * peak).all()
    hdr = ref["header"]
    assert lay.first_frame - 1 == hdr["points"]["first_frame"]
    assert lay.point_rate == pytest.approx(hdr["points"]["frame_rate"])


@pytest.mark.realdata
@pytest.mark.parametrize(
    "name",
    [
        "knee-grand-challenge-gc5/PS_ngait_og_ss1.c3d",  # Intel floats, 3 type-2 plates, EMG
        "btkdata/Gait.c3d",  # DEC, integer storage
        "btkdata/FunctionalStatic.c3d",  # DEC floats, ANALOG:FORMAT UNSIGNED
        "ezc3d-testfiles/FP_Type3.c3d",  # Kistler type 3
    ],
)
def test_blocks_and_plate_channels_change_nothing(name: str, monkeypatch) -> None:
    path = _REAL / name
    if not path.is_file():
        pytest.skip(f"absent: {path}")
    whole = read_c3d(path)
    monkeypatch.setattr(c3d_mod, "_READ_BLOCK", 7)
    blocks = read_c3d(path)
    light = read_c3d(path, plate_channels=False)
    np.testing.assert_array_equal(blocks.markers, whole.markers)
    np.testing.assert_array_equal(blocks.analogs, whole.analogs)
    plate_ch = {c for p in whole.plates for c in p.channels}
    keep = [i for i, lab in enumerate(whole.analog_labels) if lab not in plate_ch]
    assert light.analog_labels == tuple(whole.analog_labels[i] for i in keep)
    np.testing.assert_array_equal(light.analogs, whole.analogs[:, keep])
    np.testing.assert_array_equal(light.markers, whole.markers)
    assert len(light.plates) == len(whole.plates) > 0
    for a, b in zip(light.plates, whole.plates, strict=True):
        for field in ("force", "moment", "cop", "free_moment"):
            np.testing.assert_array_equal(getattr(a, field), getattr(b, field))


def _synthetic(n: int, path: Path, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    # still markers with 1 mm of noise (white-noise positions would jump metres a frame: the
    # reader makes such teleports gaps, msk.io.marker_checks)
    markers = rng.normal(size=(1, 3, 3)) + 1e-3 * rng.normal(size=(n, 3, 3))
    markers[5, 1] = np.nan
    analogs = 100.0 * rng.normal(size=(n * 4, 7))
    analogs[:, 2] += 700.0  # loaded plate
    corners = np.array([[0.5, 0.3, 0], [-0.5, 0.3, 0], [-0.5, -0.3, 0], [0.5, -0.3, 0]])
    write_c3d(
        path,
        markers=markers,
        marker_labels=["A", "B", "C"],
        rate_hz=100.0,
        point_units="mm",
        residuals=np.abs(rng.normal(size=(n, 3))) * 3,
        analogs=analogs,
        analog_labels=["Fx", "Fy", "Fz", "Mx", "My", "Mz", "EMG"],
        analog_ratio=4,
        plates=(PlateSpec(("Fx", "Fy", "Fz", "Mx", "My", "Mz"), corners, np.zeros(3)),),
        first_frame=7,
    )
    return markers, analogs


def test_long_data_section_is_ezc3d_s_format(tmp_path, monkeypatch) -> None:
    """The data section msk writes after ezc3d's header (files of more than 65 535 frames) is
    byte for byte the one ezc3d writes (here forced on 50 frames)."""
    a, b = tmp_path / "ezc3d.c3d", tmp_path / "msk.c3d"
    _synthetic(50, a)
    monkeypatch.setattr(c3d_mod, "_MAX_HEADER_FRAMES", 10)
    _synthetic(50, b)
    la, lb = c3d_mod._check_bytes(a), c3d_mod._check_bytes(b)
    theirs, mine = a.read_bytes()[la.data_start :], b.read_bytes()[lb.data_start :]
    assert len(mine) == 50 * (3 * 4 + 4 * 7) * 4
    assert theirs[: len(mine)] == mine


@pytest.mark.slow
def test_more_than_65535_frames_round_trip(tmp_path) -> None:
    path = tmp_path / "long.c3d"
    markers, analogs = _synthetic(70_000, path)
    lay = c3d_mod._check_bytes(path)
    assert (lay.first_frame, lay.n_frames) == (8, 70_000)
    tr = read_c3d(path)
    assert tr.markers.shape == (70_000, 3, 3)
    np.testing.assert_array_equal(np.isnan(tr.markers), np.isnan(markers))
    np.testing.assert_allclose(tr.markers, markers, rtol=0, atol=1e-6, equal_nan=True)
    np.testing.assert_allclose(tr.analogs[:, 6], analogs[:, 6], rtol=1e-6)
    assert tr.time[0] == pytest.approx(0.07) and tr.time[-1] == pytest.approx(0.07 + 69_999 / 100)
    assert tr.plates[0].force.shape == (280_000, 3)
    # ezc3d 1.7 reads such a file only to POINT:FRAMES (65 535)
    assert np.asarray(ezc3d.c3d(str(path))["data"]["points"]).shape[2] == 65_535


def test_isolated_reader_passes_plate_channels(tmp_path) -> None:
    path = tmp_path / "t.c3d"
    _synthetic(40, path)
    here = read_c3d(path, plate_channels=False)
    child = read_c3d(path, plate_channels=False, isolate=True)
    assert child.analog_labels == here.analog_labels == ("EMG",)
    np.testing.assert_array_equal(child.analogs, here.analogs)
    np.testing.assert_array_equal(child.plates[0].force, here.plates[0].force)
