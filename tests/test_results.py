"""msk.results: the session-folder contract (tables + OpenSim twins + summary), atomic writes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from msk.exceptions import FileFormatError, MissingDataError
from msk.io.opensim_files import Table, read_sto
from msk.results import SUMMARY_FORMAT, SessionResults, read_session, write_session


def _results() -> SessionResults:
    t = np.linspace(0.0, 1.0, 11)
    q = np.column_stack([np.sin(t), 0.9 + 0.01 * t])
    tab = {
        "q": Table(t, q, ("knee_angle_l", "pelvis_ty"), "q"),
        "muscle_forces": Table(
            t,
            np.column_stack([100 * t, np.full(11, np.nan)]),
            ("vas_med_l", "soleus_l"),
            "muscle_forces",
        ),
        "strength": Table(
            np.array([0.0]),
            np.array([[1.2, 0.9, 1.5]]),
            ("vasmed.factor", "vasmed.ci_low", "vasmed.ci_high"),
            "strength",
        ),
    }
    summary = {
        "session": "S1",
        "quality": {"x": float("nan"), "y": np.float64(2.5)},
        "frame": {"rotation": np.eye(3)},
    }
    return SessionResults(tab, summary, angle_columns=("knee_angle_l",))


def test_round_trip(tmp_path):
    out = write_session(tmp_path / "s1", _results())
    back = read_session(out)
    assert back.summary["format"] == SUMMARY_FORMAT
    assert back.summary["quality"] == {"x": None, "y": 2.5}  # strict JSON: NaN → null
    assert back.summary["frame"]["rotation"] == np.eye(3).tolist()
    for name, tab in _results().tables.items():
        got = back.table(name)
        assert got.columns == tab.columns
        np.testing.assert_array_equal(got.time, tab.time)
        np.testing.assert_array_equal(got.data, tab.data)  # %.17g: exact, NaN kept
    # OpenSim twins: q.mot in degrees for the angle columns only, the others .sto in SI
    mot = read_sto(out / "tables" / "q.mot")
    assert mot.in_degrees_in_file and mot.angle_columns == ("knee_angle_l",)
    np.testing.assert_allclose(mot.data, _results().tables["q"].data, rtol=1e-13)
    raw = (out / "tables" / "q.mot").read_text().splitlines()
    row = raw[raw.index("endheader") + 2].split("\t")
    assert float(row[1]) == pytest.approx(np.rad2deg(np.sin(0.0)))
    assert float(row[2]) == pytest.approx(0.9)
    assert read_sto(out / "tables" / "muscle_forces.sto").columns == ("vas_med_l", "soleus_l")
    with pytest.raises(MissingDataError, match="activations"):
        back.table("activations")
    # ordinary permissions, no temporary leftovers
    assert oct((out / "summary.json").stat().st_mode & 0o777) in ("0o644", "0o640", "0o600")
    assert [p.name for p in tmp_path.iterdir()] == ["s1"]


def test_failure_leaves_previous_folder_and_cache(tmp_path):
    out = write_session(tmp_path / "s", _results())
    (out / ".cache").mkdir()
    (out / ".cache" / "k.pkl").write_bytes(b"x")
    before = (out / "summary.json").read_bytes()

    def bad_report(res, folder):
        (folder / "report.html").write_text("<html>half")
        raise RuntimeError("report crashed")

    changed = SessionResults(_results().tables, {"session": "S2"})
    with pytest.raises(RuntimeError, match="report crashed"):
        write_session(out, changed, report=bad_report)
    assert (out / "summary.json").read_bytes() == before
    assert not (out / "report.html").exists()
    assert (out / ".cache" / "k.pkl").read_bytes() == b"x"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s"]
    # a successful rewrite keeps the cache and replaces the rest
    write_session(out, changed, report=lambda r, f: (f / "report.html").write_text("<html/>"))
    assert json.loads((out / "summary.json").read_text())["session"] == "S2"
    assert (out / ".cache" / "k.pkl").is_file() and (out / "report.html").is_file()


def test_never_replaces_a_foreign_folder(tmp_path):
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "thesis.docx").write_text("precious")
    with pytest.raises(FileFormatError, match="not an msk session folder"):
        write_session(tmp_path / "mine", _results())
    assert (tmp_path / "mine" / "thesis.docx").read_text() == "precious"
    (tmp_path / "empty").mkdir()
    write_session(tmp_path / "empty", _results())  # an empty folder is fine
    write_session(tmp_path / "empty", _results())  # and so is a session folder


def test_read_rejects_non_session(tmp_path):
    with pytest.raises(FileFormatError, match=r"summary\.json"):
        read_session(tmp_path)
    (tmp_path / "summary.json").write_text('{"format": "other/1"}')
    with pytest.raises(FileFormatError, match="format"):
        read_session(tmp_path)
    (tmp_path / "summary.json").write_text("{not json")
    with pytest.raises(FileFormatError, match="JSON"):
        read_session(tmp_path)


@pytest.mark.opensim
def test_twins_open_in_opensim(tmp_path, needs_opensim):
    """OpenSim 4.6 (in a child process) reads the .mot/.sto twins with the same numbers."""
    from msk.opensim_peer import run_opensim_script

    out = write_session(tmp_path / "s1", _results())
    got = run_opensim_script(
        """
        import opensim as osim
        for name in ("q.mot", "muscle_forces.sto"):
            t = osim.TimeSeriesTable(ARGS["dir"] + "/" + name)
            RESULT[name] = {
                "labels": list(t.getColumnLabels()),
                "rows": t.getNumRows(),
                "first": [t.getDependentColumnAtIndex(k)[1] for k in range(t.getNumColumns())],
                "degrees": t.getTableMetaDataAsString("inDegrees"),
            }
        s = osim.Storage(ARGS["dir"] + "/q.mot")
        RESULT["storage_in_degrees"] = s.isInDegrees()
        """,
        dir=str(out / "tables"),
    )
    q = got["q.mot"]
    assert q["labels"] == ["knee_angle_l", "pelvis_ty"] and q["rows"] == 11
    assert q["degrees"] == "yes" and got["storage_in_degrees"]
    assert q["first"][0] == pytest.approx(np.rad2deg(np.sin(0.1)), rel=1e-12)
    assert q["first"][1] == pytest.approx(0.9 + 0.001, rel=1e-12)
    mf = got["muscle_forces.sto"]
    assert mf["labels"] == ["vas_med_l", "soleus_l"]
    assert mf["first"][0] == pytest.approx(10.0)
