"""A results folder is untrusted input: planted symlinks, foreign leftovers, user tables,
forged cache entries and poisoned summaries (msk.results.folder, msk._runtime.cache, msk.report,
msk.results.cohort)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from msk._runtime.cache import StageCache
from msk._runtime.secure import MARKER, read_marker, write_marker
from msk.exceptions import FileFormatError
from msk.io.opensim_files import Table
from msk.report import render_html, write_report
from msk.results.folder import SessionResults, check_replaceable, read_session, write_session
from tests.support.summaries import BASE

DEAD = 2**22 + 12345  # above pid_max's default: no such process


def _results(**extra: object) -> SessionResults:
    t = np.linspace(0.0, 1.0, 11)
    q = Table(t, np.column_stack([np.sin(t)]), ("knee_angle_l",), "q")
    return SessionResults({"q": q}, {**BASE, **extra}, angle_columns=("knee_angle_l",))


def _tree(root: Path) -> dict[str, bytes | str]:
    """Every entry under ``root`` (links by target), to compare before/after."""
    out: dict[str, bytes | str] = {}
    for p in sorted(root.rglob("*")):
        rel = p.relative_to(root).as_posix()
        if p.is_symlink():
            out[rel] = "-> " + os.readlink(p)
        elif p.is_file():
            out[rel] = p.read_bytes()
        else:
            out[rel] = "dir"
    return out


# ----------------------------------------------------------------- planted symlinks
def test_report_never_writes_through_planted_symlinks(tmp_path, monkeypatch):
    import msk.report.html as h

    monkeypatch.setattr(h, "chromium_executable", lambda: None)  # the PDF then fails
    out = write_session(tmp_path / "s", _results())
    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "authorized_keys").write_text("ssh-ed25519 AAAA precious\n")
    (victim / "other").write_text("precious too\n")
    (out / ".report.html.tmp").symlink_to(victim / "authorized_keys")
    (out / "report.html").symlink_to(victim / "other")
    (out / "report.pdf").symlink_to(victim / "other")
    before = _tree(victim)
    write_report(read_session(out), out, figures={}, pdf=True)
    assert _tree(victim) == before
    assert not (out / "report.html").is_symlink() and (out / "report.html").is_file()
    # a failed PDF leaves no report.pdf of other results behind (the link removed, not its
    # target)
    assert not os.path.lexists(out / "report.pdf")
    # a folder the user names through a link of their own is written into
    (tmp_path / "via").symlink_to(out, target_is_directory=True)
    write_report(read_session(tmp_path / "via"), tmp_path / "via", figures={}, pdf=False)
    assert (out / "report.html").is_file() and _tree(victim) == before


def test_pdf_is_printed_privately_then_moved_over_a_planted_link(tmp_path, monkeypatch):
    import msk.report.html as h

    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    page = tmp_path / "r.html"
    page.write_text("<!DOCTYPE html><html><head></head><body>x</body></html>")
    (tmp_path / "r.pdf").symlink_to(victim)
    seen: list[str] = []

    def fake_chromium(cmd, **kw):
        target = next(a for a in cmd if a.startswith("--print-to-pdf=")).split("=", 1)[1]
        seen.append(target)
        Path(target).write_bytes(b"%PDF-1.4 fake")

    monkeypatch.setattr(h, "chromium_executable", lambda: "/bin/true")
    monkeypatch.setattr(h.subprocess, "run", fake_chromium)
    with pytest.warns(h.ChromiumSandboxWarning) if not h.sandbox_possible() else _nowarn():
        assert h.write_pdf(page, tmp_path / "r.pdf")
    assert victim.read_text() == "precious\n"
    assert not (tmp_path / "r.pdf").is_symlink()
    assert (tmp_path / "r.pdf").read_bytes() == b"%PDF-1.4 fake"
    assert seen and not seen[0].startswith(str(tmp_path))  # Chromium wrote elsewhere


class _nowarn:
    def __enter__(self) -> None:
        return None

    def __exit__(self, *a: object) -> None:
        return None


def test_a_cache_that_is_a_symlink_is_not_followed(tmp_path):
    out = write_session(tmp_path / "s", _results())
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / ".old.tmp").write_text("x")
    os.utime(elsewhere / ".old.tmp", (0, 0))  # what prune would remove as abandoned
    (out / ".cache").symlink_to(elsewhere, target_is_directory=True)
    before = _tree(elsewhere)
    cache = StageCache(out / ".cache")
    assert not cache.save("kinematics", "k", {"q": np.ones(3)})
    assert cache.load("kinematics", "k") == (False, None)
    cache.prune()
    assert _tree(elsewhere) == before
    # the next run does not carry the link over as its cache
    write_session(out, _results())
    assert not os.path.lexists(out / ".cache") and _tree(elsewhere) == before


# ----------------------------------------------------------------- what msk may delete
def test_sibling_folders_msk_did_not_create_are_never_removed(tmp_path):
    out = write_session(tmp_path / "s", _results())
    mine = [f".s.old-{DEAD}", f".s.tmp-{DEAD}-abc", f".s.old-{DEAD}-x", ".s.tmp-1-y"]
    for name in mine:
        (tmp_path / name).mkdir()
        (tmp_path / name / "thesis.docx").write_text("precious")
    # a forged marker (not made with this user's key) proves nothing
    forged = json.loads(json.dumps({"kind": "old", "target": "s", "pid": DEAD, "mac": "0" * 64}))
    (tmp_path / f".s.old-{DEAD}" / MARKER).write_text(json.dumps(forged))
    before = _tree(tmp_path)
    write_session(out, _results())
    after = _tree(tmp_path)
    for name in mine:
        assert {k: v for k, v in after.items() if k.startswith(name)} == {
            k: v for k, v in before.items() if k.startswith(name)
        }


def test_a_refused_run_removes_nothing(tmp_path):
    out = write_session(tmp_path / "s", _results())
    leftover = tmp_path / f".s.tmp-{DEAD}-abc"
    leftover.mkdir()
    write_marker(leftover, "tmp", "s", pid=DEAD)  # provably a dead msk writer's
    (out / "notes.txt").write_text("mine")  # makes the run refused
    with pytest.raises(FileFormatError, match="did not write"):
        check_replaceable(out)
    assert leftover.is_dir()
    (out / "notes.txt").unlink()
    check_replaceable(out)  # accepted: now the dead writer's folder goes
    assert not leftover.exists()


def test_a_writer_in_another_pid_namespace_or_boot_is_assumed_alive(tmp_path):
    out = write_session(tmp_path / "s", _results())
    for field, value in (("pid_ns", "pid:[1]"), ("boot_id", "another-boot"), ("host", "h2")):
        leftover = tmp_path / f".s.tmp-{DEAD}-{field}"
        leftover.mkdir()
        write_marker(leftover, "tmp", "s", pid=DEAD)
        rec = json.loads((leftover / MARKER).read_text())
        import msk._runtime.secure as sec

        rec[field] = value
        rec["mac"] = sec._marker_mac(rec)  # a genuine marker written elsewhere
        (leftover / MARKER).write_text(json.dumps(rec))
        assert read_marker(leftover, "tmp", "s") is not None
    write_session(out, _results())
    assert len([p for p in tmp_path.iterdir() if p.name.startswith(".s.tmp-")]) == 3


def test_user_files_in_tables_are_never_deleted(tmp_path):
    out = write_session(tmp_path / "s", _results())
    (out / "tables" / "my_analysis.csv").write_text("time,x\n0,1\n")
    (out / "tables" / "trial2.mot").write_text("precious")
    with pytest.raises(FileFormatError, match="did not write"):
        write_session(out, _results())
    assert (out / "tables" / "my_analysis.csv").read_text() == "time,x\n0,1\n"
    assert (out / "tables" / "trial2.mot").read_text() == "precious"
    # a symlink in place of a table msk wrote is not msk's either
    (out / "tables" / "my_analysis.csv").unlink()
    (out / "tables" / "trial2.mot").unlink()
    (out / "tables" / "q.csv").unlink()
    (out / "tables" / "q.csv").symlink_to(tmp_path / "x")
    with pytest.raises(FileFormatError, match="did not write"):
        write_session(out, _results())


# ----------------------------------------------------------------- forged cache entries
def test_a_forged_cache_entry_is_not_trusted(tmp_path, monkeypatch):
    cache = StageCache(tmp_path / ".cache")
    assert cache.save("kinematics", "k", {"q": np.zeros(3)})
    manifest, _ = cache.paths("kinematics", "k")
    # whoever wrote the folder recomputes the checksum from msk's own code: without the
    # user's key the forged entry does not authenticate
    import msk._runtime.secure as sec

    sec._user_key.cache_clear()
    sec._process_key.cache_clear()
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "attacker-home"))
    forger = StageCache(tmp_path / ".cache")
    assert forger.save("kinematics", "k", {"q": np.full(3, 0.2)})
    monkeypatch.undo()
    sec._user_key.cache_clear()
    hit, value = StageCache(tmp_path / ".cache").load("kinematics", "k")
    assert not hit and value is None and not manifest.exists()


def test_a_manifest_cannot_name_an_entry_point_or_private_module():
    import sys

    import msk._runtime.cache as c

    for ref in ("msk.cli.__main__:X", "msk.cli:Command", "msk.cli.batch:X", "msk._runtime.fork:X"):
        before = set(sys.modules)
        with pytest.raises(ValueError, match="library module"):
            c._msk_class(ref)
        assert set(sys.modules) == before  # nothing imported
    assert c._msk_class("msk.dynamics.loads:ExternalLoads").__name__ == "ExternalLoads"


# ----------------------------------------------------------------- poisoned summaries
HOSTILE = (
    '"><iframe src="file:///etc/passwd"></iframe><meta http-equiv="refresh" content="0;url=x">'
    "<style>body{display:none}</style><img src=http://x/y>"
)


def _assert_inert(html: str) -> None:
    low = html.lower()
    for tag in ("<iframe", '<meta http-equiv="refresh', "<img", "<style>body"):
        assert tag not in low, tag
    assert low.count("<style>") == 1  # the report's own


def test_every_summary_string_is_escaped(tmp_path):
    methods = {"plate_assignment": HOSTILE, "filtering": HOSTILE}
    res = _results(methods=methods, trial=HOSTILE, session=HOSTILE)
    html = render_html(res, figures={})
    _assert_inert(html)
    assert "&lt;iframe" in html


def test_the_csp_forbids_frames_loads_and_the_pdf_page_has_no_refresh():
    from msk.report.html import CONTENT_SECURITY_POLICY, without_scripts

    for rule in ("default-src 'none'", "frame-src 'none'", "script-src 'none'"):
        assert rule in CONTENT_SECURITY_POLICY
    page = without_scripts(
        '<html><head><META HTTP-EQUIV=Refresh content="0;url=about:blank"></head><p>x</html>'
    )
    assert "refresh" not in page.lower()


# ----------------------------------------------------------------- batch
def test_batch_never_overwrites_a_cohort_csv_it_did_not_write(tmp_path):
    from msk.exceptions import BatchError
    from msk.results.cohort import write_cohort_csv

    mine = tmp_path / "cohort.csv"
    mine.write_text("my own cohort table\n")
    with pytest.raises(BatchError, match="did not write"):
        write_cohort_csv(mine, [{"session": "a", "status": "ok"}])
    assert mine.read_text() == "my own cohort table\n"
    other = tmp_path / "b" / "cohort.csv"
    write_cohort_csv(other, [{"session": "a", "status": "ok"}])
    write_cohort_csv(other, [{"session": "a", "status": "failed"}])  # its own: replaced
    assert "failed" in other.read_text()
    (tmp_path / "c").mkdir()
    (tmp_path / "c" / "cohort.csv").symlink_to(mine)
    with pytest.raises(BatchError, match="did not write"):
        write_cohort_csv(tmp_path / "c" / "cohort.csv", [{"session": "a"}])
    assert mine.read_text() == "my own cohort table\n"


REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def gc5(tmp_path_factory):
    from msk.pipeline import run_session

    out = tmp_path_factory.mktemp("hostile") / "gc5"
    run_session(REPO / "pipelines" / "gc5_PS.toml", out)
    return read_session(out)


def _poison(x: object, keys: bool, depth: int = 0) -> object:
    """Every string (and, with ``keys``, every key of a nested map) followed by HOSTILE; the
    status words stay valid (they are checked, not shown as written)."""
    from msk.status import Status

    words = {s.value for s in Status}
    if isinstance(x, dict):
        return {
            (k + HOSTILE if keys and depth >= 2 and isinstance(k, str) else k): _poison(
                v, keys, depth + 1
            )
            for k, v in x.items()
        }
    if isinstance(x, list):
        return [_poison(v, keys, depth + 1) for v in x]
    if isinstance(x, str) and x not in words:
        return x + HOSTILE
    return x


def test_no_string_of_a_real_summary_can_inject_markup(gc5):
    """Every string of a real session's summary.json (and the keys of its nested maps, one
    section at a time) poisoned: the report stays inert."""
    from msk.exceptions import SummaryError
    from msk.results.summary import Summary

    d = gc5.summary.to_dict()
    variants = [_poison(d, False)]
    variants += [
        {**_poison(d, False), top: _poison(d[top], True, 1)}  # type: ignore[dict-item]
        for top in d
        if isinstance(d[top], (dict, list))
    ]
    rendered = 0
    for h in variants:
        assert isinstance(h, dict)
        h.update(format=d["format"], tables=d["tables"])
        try:
            s = Summary.from_json(json.dumps(h))
        except SummaryError:
            continue  # a poisoned schema key: refused, not rendered
        res = SessionResults(gc5.tables, s, gc5.path, gc5.angle_columns)
        _assert_inert(render_html(res, figures={}))
        rendered += 1
    assert rendered >= 10


@pytest.mark.parametrize(
    "poison",
    [
        lambda d: d["stages"].__setitem__(0, {**d["stages"][0], "status": "pwned\x1b[2J"}),
        lambda d: d["strength"]["groups"][0].__setitem__("status", "bogus"),
        lambda d: d["model"].__setitem__("static_window", {"still_below_m_s": "fast"}),
    ],
)
def test_msk_report_on_a_malformed_summary_is_one_line(gc5, tmp_path, capsys, poison):
    import shutil

    from msk.cli import main

    out = tmp_path / "s"
    shutil.copytree(gc5.path, out)
    d = json.loads((out / "summary.json").read_text())
    poison(d)
    (out / "summary.json").write_text(json.dumps(d))
    code = main(["report", str(out)])
    err = capsys.readouterr().err
    assert code in (0, 2)
    if code == 2:
        assert err.startswith("msk: error:") and err.count("\n") == 1 and "Traceback" not in err


def test_msk_report_on_a_very_deep_summary_is_one_line(tmp_path, capsys):
    from msk.cli import main

    out = tmp_path / "s"
    out.mkdir()
    (out / "summary.json").write_text("[" * 200_000 + "]" * 200_000)
    assert main(["report", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("msk: error:") and err.count("\n") == 1


@pytest.mark.slow
@pytest.mark.realdata
def test_a_received_folder_with_planted_links_and_forged_cache(tmp_path, monkeypatch, capsys):
    """The issue's end-to-end case on gc5: links planted in a results folder and a forged
    kinematics cache entry (its MAC made with another user's key, as whoever wrote the folder
    could): `msk run` and `msk report` write nothing outside the folder, and no forged value
    reaches a table."""
    import io
    import shutil

    import msk._runtime.cache as mc
    import msk._runtime.secure as sec
    from msk.cli import main
    from msk.pipeline import run_session

    cfg = REPO / "pipelines" / "gc5_PS.toml"
    out = tmp_path / "received"
    run_session(cfg, out)
    clean_q = (out / "tables" / "q.csv").read_bytes()
    # the forgery: every 2-D float array of the kinematics entry 0.2 off, MAC recomputed
    (manifest_path,) = (out / ".cache").glob("kinematics-*.json")
    manifest = json.loads(manifest_path.read_text())
    npz_path = out / ".cache" / manifest["payload"]
    with np.load(npz_path) as z:
        arrays = {k: z[k] + 0.2 if z[k].ndim == 2 and z[k].dtype.kind == "f" else z[k] for k in z}
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    payload = buf.getvalue()
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "attacker"))
    sec._user_key.cache_clear()
    manifest["mac"] = mc._digest(manifest, payload)
    monkeypatch.delenv("XDG_CACHE_HOME")
    sec._user_key.cache_clear()
    npz_path.write_bytes(payload)
    manifest_path.write_text(json.dumps(manifest))
    res = run_session(cfg, out)
    assert {r.name: r.status for r in res.stages}["kinematics"] == "computed"
    assert (out / "tables" / "q.csv").read_bytes() == clean_q
    # links planted where the report is written, pointing outside
    outside = tmp_path / "outside"
    outside.mkdir()
    for name in ("authorized_keys", "x.pdf", "y.html"):
        (outside / name).write_text(f"precious {name}\n")
    before = _tree(outside)
    (out / ".report.html.tmp").symlink_to(outside / "authorized_keys")
    (out / "report.pdf").unlink(missing_ok=True)
    (out / "report.pdf").symlink_to(outside / "x.pdf")
    (out / "report.html").unlink()
    (out / "report.html").symlink_to(outside / "y.html")
    received = _tree(out)
    assert main(["run", str(cfg), "--out", str(out), "--quiet"]) == 2  # refused: not msk's
    assert "did not write" in capsys.readouterr().err
    assert _tree(out) == received and _tree(outside) == before
    for argv in (["report", str(out)], ["report", str(out), "--pdf"]):
        code = main(argv)
        pdf = (out / "report.pdf").is_file() and not (out / "report.pdf").is_symlink()
        assert code == (0 if "--pdf" not in argv or pdf else 1)  # a PDF not printed is said
        assert _tree(outside) == before
    assert not (out / "report.html").is_symlink()
    shutil.rmtree(out)
