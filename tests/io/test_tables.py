"""CSV result tables: first column time, atomic writes, typed errors on bad input."""

from __future__ import annotations

import numpy as np
import pytest

from msk.exceptions import FileFormatError
from msk.io import Table, read_csv_table, write_csv_table


def test_round_trip_with_nan(tmp_path):
    t = np.array([0.0, 0.01, 0.02])
    x = np.array([[1.0, np.nan], [1e-300, -2.5], [3.0, 1e300]])
    p = write_csv_table(tmp_path / "tables" / "q.csv", time=t, data=x, columns=["hip", "knee"])
    assert p.read_text().splitlines()[0] == "time,hip,knee"
    back = read_csv_table(p)
    assert back.columns == ("hip", "knee") and back.name == "q"
    np.testing.assert_array_equal(back.time, t)
    np.testing.assert_array_equal(back.data, x)


def test_bad_tables(tmp_path):
    with pytest.raises(FileFormatError, match="no such file"):
        read_csv_table(tmp_path / "none.csv")
    p = tmp_path / "b.csv"
    p.write_text("")
    with pytest.raises(FileFormatError, match="empty"):
        read_csv_table(p)
    p.write_text("t,a\n0,1\n")
    with pytest.raises(FileFormatError, match="expected 'time'"):
        read_csv_table(p)
    p.write_text("time,a\n0,1\n1,2,3\n")
    with pytest.raises(FileFormatError, match="line 3 has 3 values"):
        read_csv_table(p)
    p.write_text("time,a\n0,x\n")
    with pytest.raises(FileFormatError, match="line 2"):
        read_csv_table(p)
    with pytest.raises(FileFormatError, match="invalid CSV column names"):
        write_csv_table(tmp_path / "c.csv", time=[0.0], data=[[1.0]], columns=["a,b"])
    with pytest.raises(FileFormatError, match="2 data columns but 1 names"):
        write_csv_table(tmp_path / "c.csv", time=[0.0], data=[[1.0, 2.0]], columns=["a"])


def test_failed_write_leaves_old_file_intact(tmp_path, monkeypatch):
    p = write_csv_table(tmp_path / "r.csv", Table(np.arange(2.0), np.ones((2, 1)), ("a",)))
    before = p.read_text()

    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr("os.replace", boom)
    with pytest.raises(OSError, match="disk full"):
        write_csv_table(p, Table(np.arange(3.0), np.zeros((3, 1)), ("a",)))
    assert p.read_text() == before
    assert [f.name for f in tmp_path.iterdir()] == ["r.csv"]


def test_first_column_other_than_time(tmp_path):
    """A cycle-percentage CSV (the Grand Challenge eTibia file): ``time_column`` names the
    first column, ``None`` takes any; the default still insists on ``time``."""
    p = tmp_path / "etibia.csv"
    p.write_text("sample_0_to_100,F_medial_N,F_total_magnitude_N\n0,1.5,2\n1,2.5,3\n2,3,4.25\n")
    tab = read_csv_table(p, time_column="sample_0_to_100")
    np.testing.assert_array_equal(tab.time, [0.0, 1.0, 2.0])
    assert tab.columns == ("F_medial_N", "F_total_magnitude_N")
    np.testing.assert_array_equal(tab.data[:, 1], [2.0, 3.0, 4.25])
    assert read_csv_table(p, time_column=None).columns == tab.columns
    with pytest.raises(
        FileFormatError, match=r"first column is 'sample_0_to_100', expected 'time'"
    ):
        read_csv_table(p)
    with pytest.raises(FileFormatError, match=r"expected 'percent'"):
        read_csv_table(p, time_column="percent")


def test_one_trailing_empty_field_is_not_a_value(tmp_path):
    """A lab export with a comma after the last value of every data row (the Grand Challenge 4
    ``*_knee_forces.csv``) reads as its header says; a non-empty extra field, or two, does not."""
    p = tmp_path / "cells.csv"
    p.write_text("time,a,b\n0,1,2,\n1,3,4,\n")
    tab = read_csv_table(p)
    np.testing.assert_array_equal(tab.data, [[1.0, 2.0], [3.0, 4.0]])
    for row in ("1,3,4,5", "1,3,4,,"):
        p.write_text(f"time,a,b\n0,1,2,\n{row}\n")
        with pytest.raises(FileFormatError, match="line 3 has"):
            read_csv_table(p)


def test_format_rows_is_the_text_of_numpy_char_mod(monkeypatch):
    """Each value as ``np.char.mod("%.17g", ·)`` writes it (round-trip precision, nan, ±inf,
    −0, subnormals, huge and tiny magnitudes), joined by the separator, across blocks."""
    import msk.io.tables as tables

    rng = np.random.default_rng(7)
    special = [np.nan, np.inf, -np.inf, -0.0, 0.0, 5e-324, 1e-310, 1.7976931348623157e308,
               0.1, 1 / 3, 100.0, 1e16, 123456789012345678.0]  # fmt: skip
    values = rng.normal(size=3000) * 10.0 ** rng.integers(-300, 300, size=3000)
    data = np.resize(np.concatenate([special, values]), (301, 10))
    time = np.arange(301) / 120.0
    monkeypatch.setattr(tables, "FORMAT_BLOCK", 64)
    for sep in (",", "\t"):
        want = [sep.join(r) for r in np.char.mod("%.17g", np.column_stack([time, data]))]
        assert tables.format_rows(time, data, sep) == want
    assert tables.format_rows(np.zeros(0), np.zeros((0, 3)), ",") == []
