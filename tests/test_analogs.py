"""``msk.analogs.StoredAnalogs`` (the session's C3D read: analogs as stored, scaled per
channel when read) against the float64 read of the same file: bit-identical values, less held."""

from __future__ import annotations

import numpy as np
import pytest

from msk.analogs import StoredAnalogs
from msk.datasets.shared import real_data_dir
from msk.io.c3d import PlateSpec, read_c3d, write_c3d
from msk.muscles.emg import process_emg

_REAL = real_data_dir()
C3D_FILES = sorted(_REAL.rglob("*.c3d")) if _REAL.is_dir() else []


def _equal_routes(path) -> None:
    eager = read_c3d(path, plate_channels=False)
    held = read_c3d(path, plate_channels=False, stored_analogs=True)
    a = np.asarray(eager.analogs)
    assert held.analog_labels == eager.analog_labels
    np.testing.assert_array_equal(np.asarray(held.analogs), a, strict=True)
    if isinstance(held.analogs, StoredAnalogs) and a.shape[1]:
        assert held.analogs.raw.itemsize < 8
        assert held.analogs.shape == a.shape
        for k in range(a.shape[1]):
            np.testing.assert_array_equal(held.analogs[:, k], a[:, k], strict=True)
            np.testing.assert_array_equal(held.analog(held.analog_labels[k]), a[:, k])
        rows = slice(3, a.shape[0] // 2)
        np.testing.assert_array_equal(held.analogs[rows, [0, -1]], a[rows][:, [0, -1]])
        np.testing.assert_array_equal(held.analogs[rows], a[rows])
    np.testing.assert_array_equal(held.markers, eager.markers)


@pytest.mark.realdata
@pytest.mark.parametrize("path", C3D_FILES, ids=[p.name for p in C3D_FILES])
def test_stored_analogs_equal_the_float64_read_on_every_real_c3d(path) -> None:
    _equal_routes(path)


def _file(tmp_path, seed: int = 0):
    rng = np.random.default_rng(seed)
    n = 60
    markers = rng.normal(size=(n, 2, 3))
    analogs = 100.0 * rng.normal(size=(n * 5, 8))
    analogs[:, 2] += 700.0
    corners = np.array([[0.5, 0.3, 0], [-0.5, 0.3, 0], [-0.5, -0.3, 0], [0.5, -0.3, 0]])
    path = tmp_path / "t.c3d"
    write_c3d(
        path,
        markers=markers,
        marker_labels=["A", "B"],
        rate_hz=100.0,
        analogs=analogs,
        analog_labels=["Fx", "Fy", "Fz", "Mx", "My", "Mz", "EMG1", "EMG2"],
        analog_ratio=5,
        plates=(PlateSpec(("Fx", "Fy", "Fz", "Mx", "My", "Mz"), corners, np.zeros(3)),),
    )
    return path, analogs


def test_stored_analogs_synthetic_file_and_isolated_reader(tmp_path) -> None:
    path, analogs = _file(tmp_path)
    _equal_routes(path)
    here = read_c3d(path, plate_channels=False, stored_analogs=True)
    assert isinstance(here.analogs, StoredAnalogs)
    assert here.analogs.raw.dtype == np.float32  # written as floats: held as float32
    assert here.analogs.nbytes < np.asarray(here.analogs).nbytes
    child = read_c3d(path, plate_channels=False, stored_analogs=True, isolate=True)
    assert isinstance(child.analogs, StoredAnalogs)
    np.testing.assert_array_equal(np.asarray(child.analogs), np.asarray(here.analogs))
    np.testing.assert_allclose(np.asarray(here.analogs), analogs[:, 6:], rtol=1e-6)


@pytest.mark.parametrize("kind", ["<i2", ">i2", "<u2", "<f4", ">f4"])
def test_stored_analogs_index_as_the_whole_scaled_array(kind: str) -> None:
    """Integer (signed, unsigned), float32 and big-endian storage: each index's values are the
    rows of the whole array scaled at once, bit for bit."""
    rng = np.random.default_rng(1)
    raw = rng.integers(0, 30000, size=(50, 4)).astype(kind)
    if kind.endswith("f4"):
        raw = (rng.normal(size=(50, 4)) * 1e3).astype(kind)
    off = rng.normal(size=4) * 10
    fac = rng.uniform(1e-4, 2e-3, size=4)
    s = StoredAnalogs(raw, off, fac)
    whole = (raw.astype(np.float64) - off) * fac
    np.testing.assert_array_equal(np.asarray(s), whole, strict=True)
    assert np.asarray(s, dtype=np.float32).dtype == np.float32
    np.testing.assert_array_equal(s[:, 2], whole[:, 2], strict=True)
    np.testing.assert_array_equal(s[5:9, [1, 3]], whole[5:9][:, [1, 3]], strict=True)
    np.testing.assert_array_equal(s[7], whole[7], strict=True)
    assert s.shape == (50, 4) and s.ndim == 2 and len(s) == 50 and s.dtype == np.float64


def test_process_emg_on_stored_analogs_is_bit_identical() -> None:
    rng = np.random.default_rng(2)
    raw = (rng.normal(size=(3000, 3)) * 2e3).astype(np.float32)
    s = StoredAnalogs(raw, np.array([1.5, -2.0, 0.0]), np.array([1e-6, 2e-6, 5e-7]))
    labels = ("a", "b", "c")
    mine = process_emg(s, rate_hz=1000.0, labels=labels, muscles={"m1": "a", "m2": "c"})
    ref = process_emg(np.asarray(s), rate_hz=1000.0, labels=labels, muscles={"m1": "a", "m2": "c"})
    np.testing.assert_array_equal(mine.envelopes, ref.envelopes, strict=True)
    np.testing.assert_array_equal(mine.time, ref.time)
