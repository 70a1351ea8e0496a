"""msk.io.storage_twin: the complete block of a table, which OpenSim's legacy Storage reads."""

from __future__ import annotations

import numpy as np
import pytest

from msk.exceptions import FileFormatError
from msk.io.opensim_files import read_sto, write_sto
from msk.io.storage_twin import index_ranges, storage_twin
from msk.io.tables import Table
from msk.results.folder import SessionResults, read_session, write_session

_SUMMARY = {
    "session": "S",
    "created_utc": "2026-01-01T00:00:00Z",
    "versions": {"msk": "0"},
    "config": {"path": "s.toml", "sha256": "0" * 64},
    "inputs": [],
    "settings": {},
    "subject": {"name": "S", "mass_kg": 70.0, "height_m": None, "side": "left"},
    "quality": {},
}


def _table() -> Table:
    """Rows missing at both ends and one inside (frames outside the analysed window, a frame
    the optimisation left out), a column missing outside a short cycle, one never computed."""
    rng = np.random.default_rng(5)
    t = np.arange(40) / 100.0
    x = rng.uniform(-2, 2, size=(40, 5))
    x[:4, :3] = np.nan
    x[35:, :3] = np.nan
    x[17, 1] = np.nan
    x[:30, 3] = np.nan  # measured on rows 30..39 only
    x[:, 4] = np.nan  # never computed
    return Table(t, x, ("a", "b", "c", "measured", "empty"), "tab")


def test_index_ranges():
    assert index_ranges([9, 0, 1, 2, 7, 10]) == "0-2,7,9-10"
    assert index_ranges([]) == "" and index_ranges([4]) == "4"


def test_complete_block_keeps_most_values_unchanged():
    tab = _table()
    twin = storage_twin(tab)
    assert twin.columns_left_out == ("measured", "empty")
    assert twin.table.columns == ("a", "b", "c")
    assert index_ranges(twin.rows_left_out) == "0-3,17,35-39"
    kept = np.setdiff1d(np.arange(40), twin.rows_left_out)
    np.testing.assert_array_equal(twin.table.time, tab.time[kept])
    np.testing.assert_array_equal(twin.table.data, tab.data[kept][:, :3])
    assert np.isfinite(twin.table.data).all()
    assert twin.header["msk_rows_left_out"] == "0-3,17,35-39"
    assert twin.header["msk_columns_left_out"] == "measured,empty"


def test_a_column_missing_on_few_rows_costs_rows_not_the_column():
    x = np.ones((10, 3))
    x[0, 2] = np.nan
    twin = storage_twin(Table(np.arange(10.0), x, ("a", "b", "c")))
    assert twin.table.columns == ("a", "b", "c") and list(twin.rows_left_out) == [0]


def test_a_complete_table_is_its_own_twin_without_header():
    tab = Table(np.arange(3.0), np.ones((3, 2)), ("a", "b"))
    twin = storage_twin(tab)
    assert twin.table is tab and twin.header == {} and twin.columns_left_out == ()
    nothing = storage_twin(Table(np.arange(3.0), np.full((3, 2), np.nan), ("a", "b")))
    assert nothing.table.data.shape == (0, 0) and nothing.columns_left_out == ("a", "b")


def test_a_row_repeating_the_previous_time_is_left_out():
    """Two gait cycles back to back: cycle 1's 100 % row is cycle 2's 0 % instant; Storage keeps
    one row per time, so the twin leaves the later one out and says so."""
    t = np.array([0.0, 0.5, 1.0, 1.0, 1.5, 2.0])
    tab = Table(t, np.arange(12.0).reshape(6, 2), ("cycle", "knee"))
    twin = storage_twin(tab)
    assert list(twin.rows_left_out) == [3] and twin.table.time.tolist() == [0, 0.5, 1, 1.5, 2]
    assert "repeating the previous row's time" in twin.header["msk_missing"]


def test_header_lines_round_trip_and_bad_keys_are_refused(tmp_path):
    twin = storage_twin(_table())
    p = write_sto(tmp_path / "t.sto", twin.table, header=twin.header)
    back = read_sto(p)
    assert back.metadata["msk_rows_left_out"] == "0-3,17,35-39"
    np.testing.assert_array_equal(back.data, twin.table.data)
    for bad in ({"nRows": "3"}, {"a=b": "c"}, {"k": "two\nlines"}):
        with pytest.raises(FileFormatError, match="invalid header line"):
            write_sto(tmp_path / "u.sto", twin.table, header=bad)


def test_session_twins_hold_the_complete_block_and_the_csv_every_row(tmp_path):
    tab = _table()
    out = write_session(
        tmp_path / "s",
        SessionResults({"knee_contact": tab}, _SUMMARY),
    )
    csv = read_session(out).table("knee_contact")
    np.testing.assert_array_equal(csv.data, tab.data)
    sto = read_sto(out / "tables" / "knee_contact.sto")
    assert sto.columns == ("a", "b", "c") and sto.time.size == 40 - 10
    assert sto.metadata["msk_columns_left_out"] == "measured,empty"


@pytest.mark.opensim
def test_opensim_storage_reads_every_row_of_every_twin(tmp_path, needs_opensim):
    """OpenSim 4.6 (child process): the legacy Storage and TimeSeriesTable read every row of
    the twins, with the same numbers as msk's table; a NaN file stops Storage (the reason)."""
    from msk._runtime.opensim_peer import run_opensim_script

    tab = _table()
    q = Table(
        tab.time, np.column_stack([np.sin(tab.time), 0.9 + tab.time]), ("knee_angle_r", "pelvis_ty")
    )
    res = SessionResults(
        {
            "q": q,
            "knee_contact": tab,
            "activations": Table(tab.time, tab.data[:, :3], ("a", "b", "c")),
        },
        _SUMMARY,
        angle_columns=("knee_angle_r",),
    )
    out = write_session(tmp_path / "s", res)
    write_sto(tmp_path / "raw.sto", tab)  # NaN cells as they are: what Storage cannot read
    got = run_opensim_script(
        """
        import opensim as osim
        def storage(path):
            s = osim.Storage(path)
            lab = s.getColumnLabels()
            rows = []
            for i in range(s.getSize()):
                v = s.getStateVector(i)
                d = v.getData()
                rows.append([v.getTime()] + [d.get(j) for j in range(d.getSize())])
            return {"labels": [lab.get(i) for i in range(lab.getSize())], "rows": rows}
        for name in ARGS["names"]:
            t = osim.TimeSeriesTable(ARGS["dir"] + "/" + name)
            s = storage(ARGS["dir"] + "/" + name)
            RESULT[name] = {"storage": s, "tst_rows": t.getNumRows()}
        RESULT["raw"] = storage(ARGS["raw"])["rows"]
        """,
        dir=str(out / "tables"),
        names=["q.mot", "knee_contact.sto", "activations.sto"],
        raw=str(tmp_path / "raw.sto"),
    )
    assert len(got["raw"]) < 5  # the reason for the twin: Storage stops at the first NaN
    for name, table, deg in (
        ("q.mot", q, True),
        ("knee_contact.sto", tab, False),
        ("activations.sto", res.tables["activations"], False),
    ):
        twin = storage_twin(table)
        s = got[name]["storage"]
        assert got[name]["tst_rows"] == twin.table.time.size == len(s["rows"]), name
        assert s["labels"] == ["time", *twin.table.columns]
        rows = np.array(s["rows"])
        np.testing.assert_allclose(rows[:, 0], twin.table.time, rtol=1e-15)
        want = twin.table.data.copy()
        if deg:
            want[:, 0] = np.rad2deg(want[:, 0])
        np.testing.assert_allclose(rows[:, 1:], want, rtol=1e-12)
