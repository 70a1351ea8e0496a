"""OpenSim .trc/.mot/.sto: real files, write→read identity, and OpenSim 4.6 opens what we write."""

from __future__ import annotations

import string

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from msk.exceptions import FileFormatError, MissingDataError, UnitsError
from msk.io.opensim_files import (
    Table,
    is_angle_column,
    read_mot,
    read_sto,
    read_trc,
    write_mot,
    write_sto,
    write_trc,
)
from msk.io.tables import read_csv_table, write_csv_table

_names = st.text(alphabet=string.ascii_letters + string.digits + "_/.", min_size=1, max_size=12)
_finite = st.floats(-1e6, 1e6, allow_nan=False, width=64)


@st.composite
def tables(draw):
    n = draw(st.integers(1, 12))
    k = draw(st.integers(1, 6))
    cols = draw(
        st.lists(_names, min_size=k, max_size=k, unique=True).filter(lambda c: "time" not in c)
    )
    t = np.cumsum(draw(arrays(float, n, elements=st.floats(1e-3, 1.0))))
    x = draw(arrays(float, (n, k), elements=_finite))
    return Table(time=t, data=x, columns=tuple(cols), name="prop")


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(tab=tables(), ext=st.sampled_from([".sto", ".mot"]), deg=st.booleans())
def test_sto_mot_round_trip_is_identity(tmp_path, tab, ext, deg):
    path = tmp_path / f"t{ext}"
    angles = tab.columns[:1] if deg else ()
    write_sto(path, tab, in_degrees=deg, angle_columns=angles)
    back = read_sto(path, angle_columns=angles if deg else None)
    assert back.columns == tab.columns
    assert back.in_degrees_in_file is deg
    np.testing.assert_array_equal(back.time, tab.time)
    if deg:
        assert back.angle_columns == angles
        np.testing.assert_allclose(back.data, tab.data, rtol=1e-15, atol=1e-300)
    else:
        np.testing.assert_array_equal(back.data, tab.data)


def test_a_trc_header_rate_its_time_column_contradicts_yields_to_the_column(tmp_path):
    """A TRC subsampled without its header updated (opensim-core's std_walking2_markers.trc:
    250 Hz declared, 25 Hz rows): the Time column's rate is used and the contradiction is
    reported as the trial's input warning; a consistent header is kept silently."""
    from msk.io import read_trc_trial

    x = np.random.default_rng(2).uniform(-1, 1, size=(8, 2, 3))
    t = np.arange(8) / 25.0
    bad = write_trc(tmp_path / "b.trc", time=t, markers=x, labels=["A", "B"], rate_hz=250.0)
    table = read_trc(bad)
    assert table.rate_hz == pytest.approx(25.0)
    assert len(table.warnings) == 1 and "250 Hz" in table.warnings[0]
    assert "25 Hz" in table.warnings[0]
    trial = read_trc_trial(bad)
    assert trial.point_rate_hz == pytest.approx(25.0)
    assert trial.metadata["warnings"] == table.warnings
    good = write_trc(tmp_path / "g.trc", time=t, markers=x, labels=["A", "B"], rate_hz=25.0)
    assert read_trc(good).warnings == () and read_trc_trial(good).metadata == {}


@settings(
    max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    n=st.integers(1, 10),
    m=st.integers(1, 5),
    units=st.sampled_from(["mm", "m", "cm"]),
    seed=st.integers(0, 2**31 - 1),
)
def test_trc_round_trip_is_identity(tmp_path, n, m, units, seed):
    rng = np.random.default_rng(seed)
    x = rng.uniform(-3, 3, size=(n, m, 3))
    x[rng.random((n, m)) < 0.2] = np.nan
    t = np.arange(n) / 100.0
    labels = [f"M{k}" for k in range(m)]
    path = write_trc(
        tmp_path / "m.trc", time=t, markers=x, labels=labels, units=units, rate_hz=100.0
    )
    back = read_trc(path)
    assert back.labels == tuple(labels) and back.units_in_file == units and back.rate_hz == 100.0
    np.testing.assert_array_equal(back.time, t)
    np.testing.assert_allclose(back.markers, x, rtol=1e-15, atol=1e-15)
    np.testing.assert_array_equal(back.frame_numbers, np.arange(1, n + 1))


def test_trc_as_a_markers_only_trial(tmp_path):
    """read_trc_trial: the TRC's markers, time and gaps in a Trial with no analogs or plates;
    up = +y unless told."""
    from msk.io import read_trc_trial

    rng = np.random.default_rng(1)
    x = rng.uniform(-1, 1, size=(6, 3, 3))
    x[2:5, 1] = np.nan
    t = np.arange(6) / 50.0
    path = write_trc(tmp_path / "w.trc", time=t, markers=x, labels=["A", "B", "C"], rate_hz=50.0)
    tr = read_trc_trial(path)
    assert tr.marker_labels == ("A", "B", "C") and tr.point_rate_hz == 50.0
    np.testing.assert_allclose(tr.markers, x, atol=1e-12)
    np.testing.assert_array_equal(tr.time, t)
    assert tr.gaps.with_gaps() == ("B",) and int(tr.gaps.longest_gap[1]) == 3
    assert tr.plates == () and tr.analogs.shape[1] == 0 and tr.events == ()
    np.testing.assert_array_equal(tr.up, [0.0, 1.0, 0.0])
    assert tr.vertical_axis == 1
    z = read_trc_trial(path, up=(0, 0, 2))
    np.testing.assert_array_equal(z.up, [0.0, 0.0, 1.0])
    with pytest.raises(FileFormatError, match="up must be"):
        read_trc_trial(path, up=(0, 0, 0))


@settings(
    max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(tab=tables())
def test_csv_table_round_trip_is_identity(tmp_path, tab):
    path = write_csv_table(tmp_path / "r.csv", tab)
    back = read_csv_table(path)
    assert back.columns == tab.columns
    np.testing.assert_array_equal(back.time, tab.time)
    np.testing.assert_array_equal(back.data, tab.data)
    assert path.read_text().splitlines()[0].startswith("time,")


def test_degrees_flag_converts_only_angles(tmp_path):
    p = tmp_path / "ik.mot"
    p.write_text(
        "Coordinates\nversion=1\nnRows=2\nnColumns=4\ninDegrees=yes\nendheader\n"
        "time\tknee_angle_r\tpelvis_tx\tground_force_vy\n0\t90\t1.5\t700\n0.01\t45\t1.6\t710\n"
    )
    t = read_mot(p)
    assert t.in_degrees_in_file and t.angle_columns == ("knee_angle_r",)
    np.testing.assert_allclose(t.column("knee_angle_r"), [np.pi / 2, np.pi / 4])
    np.testing.assert_allclose(t.column("pelvis_tx"), [1.5, 1.6])
    np.testing.assert_allclose(t.column("ground_force_vy"), [700, 710])
    assert t.rate_hz == pytest.approx(100.0)
    assert is_angle_column("/jointset/hip_r/hip_flexion_r/value")
    assert not is_angle_column("/jointset/ground_pelvis/pelvis_ty/value")


def test_old_header_style(tmp_path):
    p = tmp_path / "old.sto"
    p.write_text(
        "name old\ndatacolumns 3\ndatarows 2\nrange 0 1\nendheader\n"
        "time f1_1 f1_2\n0 1.5 2.5\n1 3.5 4.5\n"
    )
    t = read_sto(p)
    assert t.name == "old" and t.columns == ("f1_1", "f1_2")
    np.testing.assert_array_equal(t.data, [[1.5, 2.5], [3.5, 4.5]])


def test_malformed_files(tmp_path):
    p = tmp_path / "bad.sto"
    with pytest.raises(FileFormatError, match="no such file"):
        read_sto(p)
    p.write_text("")
    with pytest.raises(FileFormatError, match=r"bad\.sto: empty"):
        read_sto(p)
    p.write_text("version=1\nnRows=1\ntime\ta\n0\t1\n")
    with pytest.raises(FileFormatError, match="endheader"):
        read_sto(p)
    p.write_text("version=1\nnRows=3\nendheader\ntime\ta\n0\t1\n1\t2\n")
    with pytest.raises(FileFormatError, match="announces 3 rows"):
        read_sto(p)
    p.write_text("version=1\nendheader\ntime\ta\n0\tabc\n")
    with pytest.raises(FileFormatError, match="line 4"):
        read_sto(p)
    p.write_text("version=1\nendheader\nframe\ta\n0\t1\n")
    with pytest.raises(FileFormatError, match="expected 'time'"):
        read_sto(p)
    q = tmp_path / "bad.trc"
    q.write_text("PathFileType\t4\nDataRate\tUnits\tNumMarkers\n100\tinch\t1\nFrame#\tTime\tA\n\n")
    with pytest.raises(UnitsError, match="inch"):
        read_trc(q)
    q.write_text("hello\n" * 6)
    with pytest.raises(FileFormatError, match="not a TRC"):
        read_trc(q)
    with pytest.raises(MissingDataError):
        read_sto(_write_small(tmp_path), angle_columns=["nope"])


def _write_small(tmp_path):
    p = tmp_path / "deg.mot"
    p.write_text("x\nversion=1\ninDegrees=yes\nendheader\ntime\ta\n0\t1\n")
    return p


def test_atomic_write_leaves_no_temp_file(tmp_path):
    tab = Table(time=np.arange(3.0), data=np.ones((3, 1)), columns=("a",))
    write_sto(tmp_path / "x.sto", tab)
    with pytest.raises(FileFormatError):
        write_sto(tmp_path / "y.sto", time=[0.0], data=[[1.0, 2.0]], columns=["a"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.sto"]
    write_mot(tmp_path / "z.mot", time=[0.0, 0.1], data=[[1.0], [2.0]], columns=["a"])
    assert read_mot(tmp_path / "z.mot").columns == ("a",)


# ---------------------------------------------------------------------------------------------
# real OpenSim files
# ---------------------------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.realdata
def test_real_opensim_files(real_dir):
    ik = read_mot(real_dir / "opensim-subject01-walk" / "subject01_walk_IK.mot")
    assert ik.in_degrees_in_file and "knee_angle_r" in ik.angle_columns
    assert "pelvis_tx" not in ik.angle_columns and ik.time.size == 151
    raw_first = float(
        (real_dir / "opensim-subject01-walk" / "subject01_walk_IK.mot")
        .read_text()
        .splitlines()[11]
        .split()[ik.columns.index("knee_angle_r") + 1]
    )
    assert ik.column("knee_angle_r")[0] == pytest.approx(np.deg2rad(raw_first))
    grf = read_mot(real_dir / "opensim-subject01-walk" / "subject01_walk_grf.mot")
    assert grf.angle_columns == () and grf.data.shape == (1501, 18)
    assert np.max(grf.column("ground_force_vy")) > 700
    id_ = read_sto(real_dir / "opensim-rajagopal-walk" / "id_walk.sto")
    assert not id_.in_degrees_in_file and id_.rate_hz == pytest.approx(1000.0)
    coords = read_sto(real_dir / "opensim-rajagopal-walk" / "coordinates.sto")
    assert coords.metadata["version"] == "3" and coords.data.shape == (1350, 31)
    old = read_sto(real_dir / "opensim-core-c3d" / "std_walking2_grfs.sto")
    assert old.name == "ds_std_walking2_grfs.sto" and old.data.shape == (101, 18)
    trc = read_trc(real_dir / "opensim-rajagopal-walk" / "markers_walk.trc")
    assert trc.markers.shape == (238, 41, 3) and trc.rate_hz == 100.0
    static = read_trc(real_dir / "opensim-subject01-walk" / "subject01_static.trc")
    assert static.markers.shape == (300, 49, 3) and static.units_in_file == "mm"
    assert 0.5 < np.nanmax(np.abs(static.markers)) < 3.0  # metres


@pytest.mark.slow
@pytest.mark.realdata
def test_peer_tool_files(real_dir):
    root = real_dir.parent.parent / "tools" / "opensim-peer" / "data"
    if not root.is_dir():
        pytest.skip("opensim-peer data absent")
    files = sorted(root.rglob("*.trc")) + sorted(root.rglob("*.mot")) + sorted(root.rglob("*.sto"))
    assert len(files) >= 10
    for f in files:
        t = read_trc(f) if f.suffix == ".trc" else read_sto(f)
        assert t.time.size > 10 and np.isfinite(t.time).all()


# ---------------------------------------------------------------------------------------------
# OpenSim 4.6 opens what msk writes
# ---------------------------------------------------------------------------------------------
@pytest.mark.opensim
def test_opensim_reads_what_we_write(tmp_path, needs_opensim):
    from msk._runtime.opensim_peer import run_opensim_script

    rng = np.random.default_rng(3)
    t = np.arange(25) / 50.0
    x = rng.uniform(-1, 1, size=(25, 3, 3))
    x[4:6, 1] = np.nan
    write_trc(tmp_path / "m.trc", time=t, markers=x, labels=["A", "B", "C"], units="mm")
    q = rng.normal(size=(25, 3))
    tab = Table(time=t, data=q, columns=("knee_angle_r", "pelvis_tx", "hip_flexion_r"))
    write_sto(tmp_path / "q.sto", tab)
    write_mot(
        tmp_path / "q.mot", tab, in_degrees=True, angle_columns=("knee_angle_r", "hip_flexion_r")
    )
    out = run_opensim_script(
        """
        import opensim as osim
        d = ARGS["dir"]
        m = osim.TimeSeriesTableVec3(d + "/m.trc")
        RESULT["trc_labels"] = list(m.getColumnLabels())
        RESULT["trc_units"] = m.getTableMetaDataAsString("Units")
        RESULT["trc_rows"] = m.getNumRows()
        v = m.getRowAtIndex(0)
        RESULT["trc_b0"] = [v[1].get(0), v[1].get(1), v[1].get(2)]
        s = osim.TimeSeriesTable(d + "/q.sto")
        RESULT["sto_labels"] = list(s.getColumnLabels())
        RESULT["sto_time"] = list(s.getIndependentColumn())
        RESULT["sto_col0"] = [s.getDependentColumnAtIndex(0)[i] for i in range(s.getNumRows())]
        st = osim.Storage(d + "/q.mot")
        RESULT["mot_degrees"] = st.isInDegrees()
        RESULT["mot_rows"] = st.getSize()
        lab = st.getColumnLabels()
        RESULT["mot_labels"] = [lab.get(i) for i in range(lab.getSize())]
        dc = osim.ArrayDouble()
        st.getDataColumn("knee_angle_r", dc)
        RESULT["mot_knee"] = [dc.get(i) for i in range(dc.getSize())]
        """,
        dir=str(tmp_path),
    )
    assert out["trc_labels"] == ["A", "B", "C"] and out["trc_units"] == "mm"
    assert out["trc_rows"] == 25
    np.testing.assert_allclose(out["trc_b0"], x[0, 1] * 1e3, rtol=1e-12)
    assert out["sto_labels"] == list(tab.columns)
    np.testing.assert_allclose(out["sto_time"], t, rtol=1e-15)
    np.testing.assert_allclose(out["sto_col0"], q[:, 0], rtol=1e-15)
    assert out["mot_degrees"] is True and out["mot_rows"] == 25
    assert out["mot_labels"] == ["time", *tab.columns]
    np.testing.assert_allclose(out["mot_knee"], np.rad2deg(q[:, 0]), rtol=1e-12)
