"""msk.results.folder: the session-folder contract (tables + OpenSim twins + summary), atomic
writes."""

from __future__ import annotations

import dataclasses
import json
import re
import types
import typing
from collections.abc import Mapping
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from msk.exceptions import (
    FileFormatError,
    MissingDataError,
    SummaryError,
    SummaryKeyError,
    SummaryVersionError,
)
from msk.io.opensim_files import Table, read_sto
from msk.results.folder import SUMMARY_FORMAT, SessionResults, read_session, write_session
from msk.results.summary import SCHEMA_VERSION, Summary, _Record, as_summary, unknown_keys

#: the required keys of a summary (msk.results.summary.Summary) but ``format``
BASE = {
    "session": "S1",
    "created_utc": "2026-01-01T00:00:00Z",
    "versions": {"msk": "0.1.0"},
    "config": {"path": "s.toml", "sha256": "0" * 64},
    "inputs": [{"role": "task", "path": "t.c3d", "sha256": "1" * 64, "bytes": 10}],
    "settings": {"subject": {"name": "S1"}},
    "subject": {"name": "S1", "mass_kg": 70.0, "height_m": None, "side": "left"},
    "quality": {},
}


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
        **BASE,
        "quality": {"ik_marker_rms_mean_m": float("nan"), "ik_marker_rms_max_m": np.float64(2.5)},
        "frame": {"lab_to_model_rotation": np.eye(3)},
    }
    return SessionResults(tab, summary, angle_columns=("knee_angle_l",))


def test_round_trip(tmp_path):
    out = write_session(tmp_path / "s1", _results())
    back = read_session(out)
    assert isinstance(back.summary, Summary) and back.summary.schema_version == SCHEMA_VERSION
    written = json.loads((out / "summary.json").read_text())
    assert written["format"] == SUMMARY_FORMAT and back.summary.to_dict() == written
    # strict JSON: NaN → null
    assert written["quality"] == {"ik_marker_rms_mean_m": None, "ik_marker_rms_max_m": 2.5}
    assert written["frame"]["lab_to_model_rotation"] == np.eye(3).tolist()
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
    # soleus_l is NaN on every row: left out of the twin (OpenSim's Storage cannot read NaN)
    mf = read_sto(out / "tables" / "muscle_forces.sto")
    assert mf.columns == ("vas_med_l",) and mf.time.size == 11
    assert mf.metadata["msk_columns_left_out"] == "soleus_l"
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

    changed = SessionResults(_results().tables, {**BASE, "session": "S2"})
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
    from msk._runtime.opensim_peer import run_opensim_script

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
    assert mf["labels"] == ["vas_med_l"]
    assert mf["first"][0] == pytest.approx(10.0)


# ---------------------------------------------------------------------------------------------
# the typed summary (msk.results.summary): exact round trip, versioned, errors name the key
# ---------------------------------------------------------------------------------------------
_JSON = st.recursive(
    st.none()
    | st.booleans()
    | st.integers()
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=4),
    lambda inner: (
        st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=4), inner, max_size=3)
    ),
    max_leaves=6,
)


def _strategy(tp: Any) -> st.SearchStrategy[Any]:
    """Plain JSON values of the annotated type of a summary field."""
    if tp is Any:
        return _JSON
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        (inner,) = [a for a in args if a is not type(None)]
        return st.none() | _strategy(inner)
    if isinstance(tp, type) and issubclass(tp, _Record):
        return st.deferred(lambda: _record(tp))
    if origin is Mapping:
        return st.dictionaries(st.text(max_size=6), _strategy(args[1]), max_size=2)
    if origin is tuple:
        return st.lists(_strategy(args[0]), max_size=2)
    if tp is float:
        return st.floats(allow_nan=False, allow_infinity=False) | st.integers()
    return st.from_type(tp)


@st.composite
def _record_dict(draw: st.DrawFn, cls: type) -> dict[str, Any]:
    hints = typing.get_type_hints(cls)
    names = set()
    items = []
    for f in dataclasses.fields(cls):
        key = f.metadata.get("json", f.name)
        names.add(key)
        required = f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        if key == "format":
            items.append((key, f"msk-session-summary/{draw(st.integers(1, SCHEMA_VERSION))}"))
        elif required or draw(st.booleans()):
            items.append((key, draw(_strategy(hints[f.name]))))
    extra = draw(st.dictionaries(st.text(min_size=1, max_size=6), _JSON, max_size=2))
    items += [(k, v) for k, v in extra.items() if k not in names]
    return dict(draw(st.permutations(items)))  # any key order


def _record(cls: type) -> st.SearchStrategy[dict[str, Any]]:
    return _record_dict(cls)


# a summary is a deep tree: generating one is slow on a loaded machine, and 60 trees cover it
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_record(Summary))
def test_summary_round_trip_is_exact(d: dict[str, Any]) -> None:
    """Any summary of the schema — optional keys absent or null, keys in any order, keys the
    schema does not name — gives back the same mapping and the same JSON text."""
    s = Summary.from_dict(d)
    assert s.to_dict() == d
    text = json.dumps(d, indent=2) + "\n"
    assert Summary.from_json(text).to_json() == text
    assert Summary.from_json(s.to_json()) == s


def _summary_dict() -> dict[str, Any]:
    return {
        **json.loads(json.dumps(BASE)),
        "strength": {"groups": [{"group": "vasmed", "factor": 1.2}], "r2": 0.8},
        "format": SUMMARY_FORMAT,
    }


def test_summary_fields_are_typed_and_frozen() -> None:
    s = Summary.from_dict(_summary_dict())
    assert s.subject.side == "left" and s.quality.flags is None and s.fes is None
    assert s.strength is not None and s.strength.groups[0].factor == 1.2
    assert s.strength.group_status(s.strength.groups[0]) == "not determined"  # no interval
    assert s.inputs[0].bytes == 10 and isinstance(s.inputs, tuple)
    with pytest.raises(AttributeError):
        s.session = "other"  # type: ignore[misc]
    with pytest.raises(TypeError):
        s.versions["msk"] = "9"  # type: ignore[index]
    # a summary built in code writes every field (None as null), "format" from the version
    built = Summary.from_dict(
        Summary(**{f: getattr(s, f) for f in s.__dataclass_fields__}).to_dict()
    )
    assert built == s and built.to_dict()["format"] == SUMMARY_FORMAT


def test_summary_newer_version_is_refused_naming_the_key() -> None:
    d = _summary_dict()
    d["format"] = f"msk-session-summary/{SCHEMA_VERSION + 1}"
    with pytest.raises(SummaryVersionError, match=r"'format'.*newer") as exc:
        Summary.from_dict(d)
    assert exc.value.key == "format" and isinstance(exc.value, FileFormatError)
    d["format"] = "other/1"
    with pytest.raises(SummaryError, match="not an msk session summary"):
        Summary.from_dict(d)


@pytest.mark.parametrize(
    ("path", "key"),
    [
        (("format",), "format"),
        (("quality",), "quality"),
        (("subject", "name"), "subject.name"),
        (("strength", "groups", 0, "group"), "strength.groups[0].group"),
    ],
)
def test_summary_missing_required_key_is_named(path: tuple[Any, ...], key: str) -> None:
    d = _summary_dict()
    parent: Any = d
    for p in path[:-1]:
        parent = parent[p]
    del parent[path[-1]]
    with pytest.raises(SummaryKeyError, match=re.escape(f"required key '{key}' is missing")) as exc:
        Summary.from_dict(d)
    assert exc.value.key == key


def test_summary_wrong_type_is_named() -> None:
    d = _summary_dict()
    d["strength"]["groups"][0]["factor"] = "1.2"
    with pytest.raises(SummaryError, match=r"'strength\.groups\[0\]\.factor': expected a number"):
        Summary.from_dict(d)
    d = _summary_dict()
    d["quality"] = []
    with pytest.raises(SummaryError, match="'quality': expected an object, got an array"):
        Summary.from_dict(d)


def test_an_assembled_summary_with_a_misspelt_key_is_refused_on_write() -> None:
    """Typed on write: the pipeline's mapping may only hold keys the schema names (a file
    read keeps unknown keys verbatim, test_summary_round_trip_is_exact)."""
    assert unknown_keys(as_summary(_summary_dict())) == ()
    d = _summary_dict()
    d["strength"]["groups"][0]["factr"] = 1.0
    d["subject"]["mas_kg"] = 70.0
    assert unknown_keys(Summary.from_dict(d)) == ("subject.mas_kg", "strength.groups[0].factr")
    with pytest.raises(SummaryKeyError, match=r"'subject\.mas_kg' is not in the schema") as exc:
        as_summary(d)
    assert exc.value.key == "subject.mas_kg"


def test_read_session_names_the_file_and_the_key(tmp_path):
    out = write_session(tmp_path / "s", _results())
    d = json.loads((out / "summary.json").read_text())
    del d["subject"]
    (out / "summary.json").write_text(json.dumps(d))
    with pytest.raises(SummaryKeyError, match=r"summary\.json: summary: required key 'subject'"):
        read_session(out)
    d["subject"] = BASE["subject"]
    d["format"] = "msk-session-summary/99"
    (out / "summary.json").write_text(json.dumps(d))
    with pytest.raises(SummaryVersionError, match="schema version 99"):
        read_session(out)


def _killed_between_renames(monkeypatch, out):
    """Write ``out`` again with the process "killed" right after its first rename (out →
    .out.old-<pid>): os.replace raises there, and the except clause that a SIGKILL would skip
    is bypassed too (the temporary folder and the old copy stay as a kill leaves them)."""
    import os

    import msk.results.folder as results

    real = os.replace
    calls = []

    class Killed(BaseException):
        pass

    def replace(src, dst):
        real(src, dst)
        calls.append((str(src), str(dst)))
        if ".old-" in str(dst):
            raise Killed

    monkeypatch.setattr(results.os, "replace", replace)
    monkeypatch.setattr(results.shutil, "rmtree", lambda *a, **k: None)  # no cleanup: killed
    with pytest.raises(Killed):
        write_session(out, _results())
    monkeypatch.undo()


def _fake_dead_pid(parent, name):
    """Rename the leftovers of this process to those of a process that no longer exists."""
    import os

    from msk._runtime.secure import write_marker

    dead = 2**22 + 12345  # above pid_max's default: no such process
    for p in parent.iterdir():
        for kind in ("old", "tmp"):
            prefix = f".{name}.{kind}-{os.getpid()}"
            if p.name.startswith(prefix):
                p = p.rename(parent / p.name.replace(prefix, f".{name}.{kind}-{dead}"))
                write_marker(p, kind, name, pid=dead)  # as the dead writer had marked it


def test_kill_between_the_two_renames_is_recovered_on_the_next_run(tmp_path, monkeypatch):
    # issue 18: a kill between write_session's two renames left --out absent and the hidden
    # copies behind; the next run restores the previous results (with the stage cache) and
    # removes the leftovers
    out = tmp_path / "s"
    write_session(out, _results())
    (out / ".cache").mkdir()
    (out / ".cache" / "entry.json").write_text("{}")
    before = (out / "tables" / "q.csv").read_bytes()
    _killed_between_renames(monkeypatch, out)
    assert not out.exists()
    hidden = sorted(p.name for p in tmp_path.iterdir())
    assert any(".s.old-" in n for n in hidden) and any(".s.tmp-" in n for n in hidden)
    _fake_dead_pid(tmp_path, "s")
    from msk.results.folder import check_replaceable, recover_interrupted_write

    check_replaceable(out)  # what `msk run` does before computing
    assert (out / "tables" / "q.csv").read_bytes() == before
    assert (out / ".cache" / "entry.json").exists()  # the cache came back from the tmp folder
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s"]
    assert recover_interrupted_write(out) == []  # nothing left to do
    write_session(out, _results())  # and the next write works as usual
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s"]


def test_stale_leftovers_are_removed_but_a_live_writers_are_kept(tmp_path):
    import os

    from msk._runtime.secure import write_marker
    from msk.results.folder import recover_interrupted_write

    out = write_session(tmp_path / "s", _results())
    dead = 2**22 + 12345
    (tmp_path / f".s.old-{dead}").mkdir()  # swap completed, old copy not removed
    write_marker(tmp_path / f".s.old-{dead}", "old", "s", pid=dead)
    (tmp_path / f".s.tmp-{dead}-abc").mkdir()  # unfinished temporary folder
    (tmp_path / f".s.tmp-{dead}-abc" / "summary.json").write_text("{}")
    write_marker(tmp_path / f".s.tmp-{dead}-abc", "tmp", "s", pid=dead)
    parent_pid = os.getppid()  # alive: its leftovers may be in use
    (tmp_path / f".s.tmp-{parent_pid}-xyz").mkdir()
    write_marker(tmp_path / f".s.tmp-{parent_pid}-xyz", "tmp", "s", pid=parent_pid)
    (tmp_path / ".s.tmp-notapid").mkdir()  # no marker: not provably msk's, untouched
    (tmp_path / f".s.old-{dead}-user").mkdir()  # msk's naming but no marker: untouched
    msgs = recover_interrupted_write(out)
    assert len(msgs) == 2
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == sorted(
        ["s", f".s.tmp-{parent_pid}-xyz", ".s.tmp-notapid", f".s.old-{dead}-user"]
    )
    assert (out / "summary.json").exists()
