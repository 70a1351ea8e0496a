"""msk.io.opensim_export: the markers .trc, GRF .mot and ExternalLoads .xml an OpenSim user goes
on from — the same wrench per body, read back by msk's own OpenSim readers."""

from __future__ import annotations

import numpy as np

from msk.io.grf import external_force_sets, read_external_loads_xml
from msk.io.opensim_export import (
    grf_table,
    write_external_loads_xml,
    write_grf_mot,
    write_markers_trc,
)
from msk.io.opensim_files import read_sto, read_trc

BODIES = ("calcn_r", "calcn_l")


def _wrenches(n: int = 30, seed: int = 0):
    """Per body a force, a COP on the floor (y = 0) and a free moment about y, the moment about
    the origin M_O = p × F + T; the left foot unloaded (no COP) on the first 10 frames, a
    frame whose load is unknown (NaN force) at 20."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 100.0
    f = rng.normal([0.0, 700.0, 0.0], [50.0, 100.0, 50.0], size=(n, 2, 3))
    p = rng.uniform(-1, 1, size=(n, 2, 3))
    p[..., 1] = 0.0
    tq = np.zeros((n, 2, 3))
    tq[..., 1] = rng.normal(0, 3, size=(n, 2))
    f[:10, 1] = 0.0
    tq[:10, 1] = 0.0
    p[:10, 1] = np.nan
    m = np.cross(np.nan_to_num(p), f) + tq
    f[20, 0] = np.nan
    return t, f, m, p, tq


def test_grf_columns_carry_the_same_wrench():
    t, f, m, p, tq = _wrenches()
    tab = grf_table(t, BODIES, f, m, p)
    assert tab.columns[:9] == (
        *(f"calcn_r_force_v{a}" for a in "xyz"),
        *(f"calcn_r_force_p{a}" for a in "xyz"),
        *(f"calcn_r_torque_{a}" for a in "xyz"),
    )
    x = tab.data.reshape(t.size, 2, 3, 3)  # body, (force, point, torque), axis
    ok = np.isfinite(f).all(axis=2)
    # F at p plus T is the wrench M_O about the origin
    rebuilt = np.cross(x[:, :, 1], x[:, :, 0]) + x[:, :, 2]
    np.testing.assert_allclose(rebuilt[ok], m[ok], atol=1e-9)
    # where the COP is defined it is written, with the free moment
    np.testing.assert_allclose(x[10:, 1, 1], p[10:, 1], rtol=1e-15)
    np.testing.assert_allclose(x[10:20, 0, 2], tq[10:20, 0], atol=1e-9)
    # unloaded: origin and zero torque, not NaN
    assert (x[:10, 1] == 0.0).all()


def test_grf_mot_leaves_out_unknown_frames_and_msk_reads_it_back(tmp_path):
    t, f, m, p, _ = _wrenches()
    path, written = write_grf_mot(tmp_path / "grf.mot", grf_table(t, BODIES, f, m, p))
    back = read_sto(path)
    assert back.time.size == t.size - 1 and 20 not in np.round(back.time * 100)
    assert back.metadata["msk_rows_left_out"] == "20"
    np.testing.assert_array_equal(back.data, written.data)
    xml = write_external_loads_xml(tmp_path / "external_loads.xml", "grf.mot", BODIES)
    spec = read_external_loads_xml(xml)
    assert [e.applied_to_body for e in spec.forces] == list(BODIES)
    assert spec.datafile == tmp_path / "grf.mot"
    sets = external_force_sets(spec, ("time", *back.columns))
    assert [s.body for s in sets] == list(BODIES)
    assert sets[1].force == ("calcn_l_force_vx", "calcn_l_force_vy", "calcn_l_force_vz")
    assert sets[0].torque == ("calcn_r_torque_x", "calcn_r_torque_y", "calcn_r_torque_z")


def test_markers_trc_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    x = rng.uniform(-1, 1, size=(12, 3, 3))
    x[3, 1] = np.nan
    x[4, 2] = 0.0  # a C3D gap
    path = write_markers_trc(tmp_path / "m.trc", np.arange(12) / 100.0, x, ["A", "B", "C"])
    back = read_trc(path)
    assert back.units_in_file == "mm" and back.labels == ("A", "B", "C")
    assert np.isnan(back.markers[3, 1]).all() and np.isnan(back.markers[4, 2]).all()
    ok = np.isfinite(x).all(axis=2) & ~(x == 0).all(axis=2)
    np.testing.assert_allclose(back.markers[ok], x[ok], rtol=1e-12, atol=1e-15)
