"""msk.report: the self-contained HTML report, rendered in headless Chromium."""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest

from msk.io.opensim_files import Table
from msk.report import render_html, write_pdf
from msk.report.html import chromium_args, chromium_executable
from msk.results.folder import SessionResults, read_session
from tests.support import sessions

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def session():
    # the bundled session's results folder, shared with the other tests that read it
    return read_session(sessions.session("gc5_PS.toml").out_dir)


@pytest.fixture(scope="module")
def chromium():
    exe = chromium_executable()
    if exe is None:
        pytest.skip("chromium is not installed")
    return exe


def _chromium(exe: str, *args: str) -> subprocess.CompletedProcess:
    with tempfile.TemporaryDirectory() as prof:
        return subprocess.run(
            [exe, *chromium_args(prof), *args],
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )


def test_html_is_self_contained(session):
    html = (session.path / "report.html").read_text()
    assert html.startswith("<!DOCTYPE html>")
    assert not re.search(r"""<(script|link|img)[^>]+(src|href)\s*=""", html)
    assert not re.search(r"""(href|src)\s*=\s*["']https?:|url\(\s*["']?https?:""", html)
    assert "<metadata>" not in html
    # kinematics, kinetics, knee contact, muscles, strength, joint strength, mass
    assert html.count("<svg") == 7
    for heading in (
        "Muscle strength",
        "Mass distribution",
        "gait cycle",
        "Knee contact force",
        "Data quality",
        "Methods",
    ):
        assert heading in html
    # units next to the numbers a clinician reads
    for unit in (
        " kg<",
        " N<",
        " BW<",
        " mm<",
        "×<",
        "(deg)",
        "(N·m/kg)",
        "(W/kg)",
        "(body weights)",
        "gait cycle (%)",
    ):
        assert unit in html, unit
    assert "gracilis" in html and "gmed" in html  # flat EMG channels reported


def test_rendered_in_chromium(session, chromium, tmp_path):
    url = (session.path / "report.html").resolve().as_uri()
    dom = _chromium(chromium, "--dump-dom", url).stdout
    table = re.search(r'<table class="strength">(.*?)</table>', dom, re.S)
    assert table, "strength table missing from the rendered DOM"
    rows = re.findall(r"<tr>(.*?)</tr>", table.group(1), re.S)
    assert len(rows) == 1 + len(session.summary.strength.groups)
    assert re.search(r"<td>vasmed</td>.*?<td>\d\.\d\d ×</td>", table.group(1), re.S)
    assert re.search(r"\d+ N</td>", table.group(1))
    shot = tmp_path / "shot.png"
    _chromium(chromium, f"--screenshot={shot}", "--window-size=1280,4000", url)
    import matplotlib.image as mpimg

    img = mpimg.imread(shot)[..., :3]
    assert img.shape[:2] == (4000, 1280)
    assert img.std() > 0.05  # not blank
    # every 500-px band of the page has content (figures, tables), not only the top
    assert all(img[k : k + 500].std() > 0.02 for k in range(0, 3500, 500))


def test_pdf(session, chromium, tmp_path):
    pdf = tmp_path / "r.pdf"
    assert write_pdf(session.path / "report.html", pdf)
    assert pdf.read_bytes()[:5] == b"%PDF-"


def test_missing_stages_are_visible():
    t = np.linspace(0, 1, 50)
    q = Table(
        t,
        np.column_stack([np.sin(t), -np.sin(t), 0 * t]),
        ("hip_flexion_l", "knee_angle_l", "ankle_angle_l"),
        "q",
    )
    summary = {
        **BASE_SUMMARY,
        "subject": {"name": "X", "mass_kg": 70.0, "height_m": 1.7, "side": "left"},
        "gait_cycle_s": None,
        "not_available": [
            {
                "stage": "strength_identification",
                "status": "not available",
                "reason": "msk.strength not available",
            },
            {"stage": "knee_contact", "status": "failed", "reason": "ModelError: no knee_l"},
        ],
        "stages": [{"name": "read", "status": "computed", "seconds": 0.1, "message": ""}],
        "quality": {},
    }
    html = render_html(SessionResults({"q": q}, summary))
    assert html.count("Not available") >= 2
    assert "msk.strength not available" in html and "ModelError: no knee_l" in html
    assert "time (s)" in html  # no gait events: curves against time
    assert "<svg" in html


def test_strength_status_flags_factors_on_the_regression_bounds():
    from msk.results.summary import Strength

    st = {"bounds": [0.5, 2.0], "r2": 0.8}

    def status(f, lo, hi, gated=True, **over):
        g = {"group": "g", "factor": f, "ci_low": lo, "ci_high": hi, "identified": gated}
        rec = Strength.from_dict({**st, **over, "groups": [g]})
        return rec.group_status(rec.groups[0])

    assert status(1.13, 0.9, 1.3) == "identified"
    assert status(0.5, 0.5, 0.6) == "at bound"
    assert status(0.4999999999999999, 0.5, 0.5) == "at bound"
    assert status(2.0, 1.5, 2.0) == "at bound"
    assert status(0.7, 0.5, 2.0) == "not determined"
    assert status(1.13, 0.9, 1.3, r2=-0.11) == "not determined"
    assert status(1.0, None, None, gated=False) == "prior"


#: the keys every summary.json has (msk.results.summary.Summary's required ones) besides subject,
# quality
BASE_SUMMARY = {
    "session": "X",
    "created_utc": "2026-01-01T00:00:00Z",
    "versions": {"msk": "0.1.0"},
    "config": {"path": "x.toml", "sha256": "0" * 64},
    "inputs": [],
    "settings": {},
}


def _summary(**extra):
    return {
        **BASE_SUMMARY,
        "subject": {"name": "X", "mass_kg": 70.0, "height_m": 1.7, "side": "left"},
        "gait_cycle_s": None,
        "not_available": [],
        "stages": [],
        "quality": {},
        **extra,
    }


def test_strings_from_the_data_are_shown_literally():
    """A `$` (matplotlib mathtext) or `<script>` in an EMG label or a summary field must not
    crash the report nor be interpreted: it is shown as written."""
    bad = "a$b$_<script>alert(1)</script>"
    strength = {
        "groups": [
            {
                "group": bad,
                "muscles": [bad],
                "factor": 1.2,
                "ci_low": 1.0,
                "ci_high": 1.4,
                "f_iso_generic_n": 100.0,
                "f_iso_n": 120.0,
                "identified": True,
            },
            {
                "group": "$\\alpha$",
                "muscles": ["m"],
                "factor": 0.5,
                "ci_low": 0.5,
                "ci_high": 0.5,
                "f_iso_generic_n": 100.0,
                "f_iso_n": 50.0,
                "identified": True,
            },
        ],
        "r2": 0.7,
        "confidence": 0.95,
        "bounds": [0.5, 2.0],
        "method": bad,
    }
    quality = {"emg_flat_channels": [bad], "emg_warnings": [f"channel '{bad}' is flat"]}
    t = np.linspace(0, 1, 20)
    mf = Table(t, np.column_stack([t, 2 * t]), (bad + "_l", "$x$_l"), "muscle_forces")
    summary = _summary(strength=strength, quality=quality, trial=bad)
    html = render_html(SessionResults({"muscle_forces": mf}, summary))
    assert "<script" not in html
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in html
    assert "could not be drawn" not in html  # the figures with "$" labels are drawn
    assert html.count("<svg") == 2  # strength, muscles
    # the labels reach the SVG text as written (no mathtext: "$" kept, no italic alpha)
    assert "a$b$_" in html and "$\\alpha$" in html
    # the group at the bound is not called identified; the other one is
    rows = re.findall(
        r"<tr>(.*?)</tr>",
        re.search(r'<table class="strength">(.*?)</table>', html, re.S).group(1),
        re.S,
    )
    assert "at bound" in rows[2] and "identified" not in rows[2]
    assert rows[1].rstrip().endswith("identified</span></td>")


def test_no_internal_document_names_and_a_reference_list(session):
    html = (session.path / "report.html").read_text()
    assert "seeds/" not in html
    refs = re.search(r'<ol class="refs">(.*?)</ol>', html, re.S).group(1)
    assert "Hayashibe M, Venture G, Ayusawa K, Nakamura Y" in refs
    assert "spinal cord injury" not in refs  # [2], the FES study, is not cited in gait reports
    assert "EMG-driven and OpenSim musculoskeletal model" in refs
    assert "control of rehabilitation robots" in refs
    # numbered 1, 2, 3 … in the order of first citation, every number in the list cited in the
    # text and every cited number in the list, each with its year
    text = html.split('<ol class="refs">')[0]
    numbers = [int(k) for k in re.findall(r'<li value="(\d+)">', refs)]
    assert numbers == list(range(1, len(numbers) + 1)) and len(numbers) >= 8
    cited = {int(k) for group in re.findall(r"\[(\d+(?:, \d+)*)\]", text)
             for k in group.split(", ")}  # fmt: skip
    assert cited == set(numbers)
    first = [int(m) for m in re.findall(r"\[(\d+)(?:, \d+)*\]", text)]
    assert [k for i, k in enumerate(first) if k not in first[:i]] == numbers  # first-cited order
    for item in re.findall(r"<li value=\"\d+\">(.*?)</li>", refs):
        assert re.search(r"\((19|20)\d\d\)", item) or "year not given" in item, item
    assert "Kutzner I" in refs and "Fregly BJ" in refs  # the in-vivo knee-load band's sources


def test_weak_directions_in_words():
    from msk.report.html import weak_direction_words

    w = weak_direction_words("weak direction (no data): -0.59·pelvis.m +0.41·torso.m")
    assert "pelvis mass" in w and "torso" in w and "not each one" in w and "·" not in w
    w = weak_direction_words("weak direction (data std 2.3× prior): +0.5·femur_r(+_l).my")
    assert w.startswith("The thighs (left and right together) mass-centre position")
    assert "2.3 times" in w
    assert weak_direction_words("not excited (estimate stays at the prior): toes_r") is None


def test_every_quality_figure_has_its_threshold_and_a_check(session):
    html = (session.path / "report.html").read_text()
    table = re.search(r'<table class="quality">(.*?)</table>', html, re.S).group(1)
    head = re.findall(r"<th>(.*?)</th>", table)
    assert head == ["figure", "value", "threshold", "check"]
    rows = {
        re.sub(r"<.*?>", "", r[0]): r[1:]
        for r in (
            re.findall(r"<td>(.*?)</td>", tr, re.S)
            for tr in re.findall(r"<tr>(.*?)</tr>", table, re.S)
        )
        if r
    }
    assert "≤ 20 mm" in rows["IK marker error, mean"][1]
    assert "ok" in rows["IK marker error, mean"][2]
    assert "≤ 5 % BW" in rows["pelvis residual force (RMS)"][1]
    r2 = rows["strength fit r² (EMG-driven model vs joint moments)"]
    assert "≥ 0.50" in r2[1] and "below threshold" in r2[2]  # the bundled session: r² −0.11


def _pdf_text(pdf: Path) -> str | None:
    import shutil

    exe = shutil.which("pdftotext")
    if exe is None:
        return None
    return subprocess.run(
        [exe, "-layout", str(pdf), "-"], capture_output=True, text=True, check=True, timeout=60
    ).stdout


def test_pdf_tables_are_not_cut_at_a4(session, chromium, tmp_path):
    """Printed at A4, every column of the strength and mass tables is on the page: the status
    column's header and words are in the PDF text."""
    pdf = tmp_path / "r.pdf"
    assert write_pdf(session.path / "report.html", pdf)
    text = _pdf_text(pdf)
    if text is None:
        pytest.skip("pdftotext (poppler-utils) is not installed")
    groups = session.summary.strength.groups
    for g in groups:  # one line per group, ending with its status word
        line = next(ln for ln in text.splitlines() if ln.split()[:1] == [g.group])
        assert g.status.split()[0] in line, line
    mass = text.split("Mass distribution", 1)[1].splitlines()  # after the section's heading
    for seg in session.summary.identification.segments:
        line = next(ln for ln in mass if ln.split()[:1] == [seg.name])
        assert seg.status.split()[0] in line, line
    assert "anthropometric" in text.replace("-\n", "") or "anthropome" in text
    assert "threshold" in text and "check" in text


def test_no_group_at_a_bound_is_called_identified_anywhere(tmp_path):
    """Issue 17, on the bundled session through `msk batch`: summary.json, strength.csv,
    cohort.csv, the report's DOM and its PDF text agree, and none calls a group whose factor
    sits on the 0.5–2.0 bound "identified"."""
    import csv

    from msk.pipeline.batch import run_batch
    from msk.status import STATUS_CODES, at_bound

    res = run_batch([REPO / "pipelines" / "gc5_PS.toml"], tmp_path, workers=1)
    assert not res.failed, res.failed
    folder = tmp_path / "gc5_PS"
    sess = read_session(folder)
    st = sess.summary.strength
    lo, hi = st.bounds
    words = {g.group: g.status for g in st.groups}
    bound = [g.group for g in st.groups if at_bound(g.factor, lo) or at_bound(g.factor, hi)]
    assert len(bound) >= 10  # the bundled session: 11 of 14 on the 0.5 / 2.0 bound
    # summary.json
    for g in st.groups:
        assert g.identified == (g.status == "identified")
        if g.group in bound:
            assert g.status == "at bound" and not g.identified
    assert st.status_codes == STATUS_CODES and st.r2_min is not None
    # every group has its reason, judged on its own rows; a group not identified, the test
    # that would identify it (computed from the subject's model)
    for g in st.groups:
        assert g.reason and g.r2_coordinates, g
        if g.status == "at bound":
            assert g.reason.startswith("at bound: the data ask for a factor")
        if g.status != "identified":
            assert g.protocol and g.protocol["test"] == "isometric MVC", g
            assert g.protocol["action"] in g.protocol["text"]
        if g.status == "identified":
            assert g.r2 >= st.r2_min
    # strength.csv: numeric status code per group
    tb = sess.table("strength")
    for name, word in words.items():
        assert int(tb.column(f"{name}.status_code")[0]) == STATUS_CODES[word]
    # cohort.csv
    with open(res.cohort_csv, newline="", encoding="utf-8") as fh:
        (row,) = list(csv.DictReader(fh))
    cohort = dict(item.split(": ") for item in row["strength_group_status"].split("; "))
    assert cohort == words
    assert int(row["strength_groups_identified"]) == sum(w == "identified" for w in words.values())
    assert int(row["strength_groups_at_bound"]) == len(bound)
    # msk compare
    from msk.results.cohort import compare_sessions

    notes = {
        r["item"]: r["note"]
        for r in compare_sessions([folder])
        if r["quantity"] == "strength factor"
    }
    assert notes == words
    # the report: rendered DOM when Chromium is there, else the HTML text
    html = (folder / "report.html").read_text()
    exe = chromium_executable()
    if exe is not None:
        html = _chromium(exe, "--dump-dom", (folder / "report.html").resolve().as_uri()).stdout
    table = re.search(r'<table class="strength">(.*?)</table>', html, re.S).group(1)
    for tr in re.findall(r"<tr>(.*?)</tr>", table, re.S)[1:]:
        cells = [re.sub(r"<.*?>", "", c) for c in re.findall(r"<td>(.*?)</td>", tr, re.S)]
        assert cells[-1] == words[cells[0]]
        if cells[0] in bound:
            assert "identified" not in " ".join(cells)
    plain = re.sub(r"<.*?>", " ", html.split('<table class="strength">')[0])
    # the caution on session-peak normalisation states the bias the right way round
    if "No maximal voluntary contraction" in plain:
        assert "it looks weak" in plain and "looks strong" not in plain
    after = html.split('<table class="strength">')[1]
    for g in st.groups:
        if g.status != "identified":
            assert f"<b>{g.group}</b> ({g.status})" in after, g.group
    # the groups whose channel failed a check (PS: gmed and gracilis flat) are listed too
    assert {g.group for g in st.failed_channels} == {"gmed", "gracilis"}
    for g in st.failed_channels:
        assert g.status == "not determined" and "failed a check" in g.reason and "flat" in g.reason
        assert g.protocol and f"<b>{g.group}</b> (not determined)" in after
    n_next = sum(w != "identified" for w in words.values()) + len(st.failed_channels)
    assert after.count("Next protocol:") == n_next
    for g in bound:
        assert not re.search(rf"identified[^.]*\b{re.escape(g)}\b", plain)
    # the PDF text
    pdf = tmp_path / "report.pdf"  # msk run prints it with --pdf: the same write_pdf
    text = _pdf_text(pdf) if exe is not None and write_pdf(folder / "report.html", pdf) else None
    if text is not None:
        for g in bound:
            line = next(ln for ln in text.splitlines() if ln.split()[:1] == [g])
            assert "at bound" in line and "identified" not in line, line


def test_chromium_sandbox_unless_root_and_no_javascript_for_the_pdf(monkeypatch):
    # issue 18: Chromium ran with --no-sandbox always and with JavaScript on during --pdf
    import msk.report.html as h

    assert "--no-sandbox" not in chromium_args("/p", sandbox=True)
    assert "--no-sandbox" in chromium_args("/p", sandbox=False)
    monkeypatch.setattr(h.os, "geteuid", lambda: 1000)
    assert h.sandbox_possible() and h.pdf_attempts() == [True, False]
    assert "--no-sandbox" not in chromium_args("/p")  # sandbox first
    monkeypatch.setattr(h.os, "geteuid", lambda: 0)
    assert not h.sandbox_possible() and h.pdf_attempts() == [False]  # root: cannot start
    assert "--no-sandbox" in chromium_args("/p")
    page = h.without_scripts("<!DOCTYPE html><html><head><title>x</title></head><body></body>")
    assert page.startswith('<!DOCTYPE html><html><head><meta http-equiv="Content-Security-Pol')
    assert "script-src 'none'" in page
    bare = h.without_scripts("<!DOCTYPE html><p>x<script>alert(1)</script>")
    assert bare.index("script-src 'none'") < bare.index("<script>")
    t = np.linspace(0, 1, 5)
    q = Table(t, np.column_stack([t]), ("knee_angle_l",), "q")
    summary = {
        **BASE_SUMMARY,
        "subject": {"name": "X"},
        "quality": {},
        "stages": [],
        "not_available": [],
    }
    assert "script-src 'none'" in render_html(SessionResults({"q": q}, summary))


def test_pdf_runs_no_script_of_the_page(chromium, tmp_path):
    exe_text = shutil.which("pdftotext")
    if exe_text is None:
        pytest.skip("pdftotext (poppler-utils) is not installed")
    page = tmp_path / "r.html"
    page.write_text(
        "<!DOCTYPE html><html><head><title>t</title></head><body><p id=x>static text</p>"
        "<script>document.getElementById('x').textContent='SCRIPT RAN'</script></body></html>",
        encoding="utf-8",
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the sandbox warning when run as root
        assert write_pdf(page, tmp_path / "r.pdf")
    text = _pdf_text(tmp_path / "r.pdf")
    assert text is not None and "static text" in text and "SCRIPT RAN" not in text


#: the sections of a gait report, in order (msk.report.sections), by their element id
GAIT_SECTIONS = (
    "session",
    "spatiotemporal",
    "kinematics",
    "kinetics",
    "knee-loads",
    "muscle-forces",
    "strength",
    "mass",
    "methods",
    "references",
)

_MEASURE = """<script>
const out = {scroll: document.documentElement.scrollWidth, width: innerWidth, wide: []};
for (const el of document.querySelectorAll("table, figure, svg, p, h2, h3, ul, ol")) {
  const r = el.getBoundingClientRect();
  if (r.right > innerWidth + 0.5 || el.scrollWidth > el.clientWidth + 1 && el.tagName == "TABLE")
    out.wide.push(el.tagName + "." + el.className + " " + Math.round(r.right));
}
const p = document.createElement("pre"); p.id = "measured";
p.textContent = JSON.stringify(out); document.body.appendChild(p);
</script>"""


def test_the_gait_report_in_chromium_at_1280_px(session, chromium, tmp_path):
    """Rendered by headless Chromium at 1280 px: every section in the clinical order, each
    figure and table present, nothing wider than the window (no horizontal scroll, no table
    in a scroll box)."""
    import json

    html = (session.path / "report.html").read_text(encoding="utf-8")
    # the report forbids scripts (its CSP): a copy without the policy runs the measurement
    page = tmp_path / "measure.html"
    page.write_text(
        re.sub(r'<meta http-equiv="Content-Security-Policy"[^>]*>', "", html).replace(
            "</body>", _MEASURE + "</body>"
        ),
        encoding="utf-8",
    )
    dom = _chromium(chromium, "--window-size=1280,900", "--dump-dom", page.as_uri()).stdout
    ids = re.findall(r'<section id="([\w-]+)"', dom)
    assert ids == list(GAIT_SECTIONS)
    numbers = re.findall(r"<h2>(\d+)\. ", dom)
    assert numbers == [str(k) for k in range(1, len(GAIT_SECTIONS) + 1)]
    for figure in ("kinematics", "kinetics", "knee contact force", "muscle forces",
                   "strength factors", "joint strength", "segment masses"):  # fmt: skip
        assert f'aria-label="{figure}"' in dom, figure
    for table in ("quality", "st", "contact", "strength", "mass", "stages", "inputs"):
        assert re.search(rf'<table class="{table}[" ]', dom), table
    measured = json.loads(re.search(r'<pre id="measured">(.*?)</pre>', dom, re.S).group(1))
    assert measured["width"] == 1280
    assert measured["scroll"] <= 1280, measured
    assert not measured["wide"], measured["wide"]
    assert "overflow-x:auto" not in html and "overflow:auto" not in html  # no scroll boxes
    # left red, right green; foot-off lines; the in-vivo knee-load band
    assert 'stroke="#c62828"' in dom and "left foot off" in dom
    assert "in-vivo walking peaks 2–3 BW" in dom
    assert "normative mean ± SD" in dom  # the shipped set, with its population and licence
    assert "licence: Apache-2.0" in dom


def test_pdf_keeps_every_heading_with_its_content(session, chromium, tmp_path):
    """Printed at A4, no page ends with a section or sub-section heading (print CSS:
    break-after: avoid, headings kept in a block with what follows them)."""
    pdf = tmp_path / "r.pdf"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the sandbox warning when run as root
        assert write_pdf(session.path / "report.html", pdf)
    text = _pdf_text(pdf)
    if text is None:
        pytest.skip("pdftotext (poppler-utils) is not installed")
    html = (session.path / "report.html").read_text(encoding="utf-8")
    headings = {
        " ".join(re.sub(r"<.*?>", "", h).split())
        for h in re.findall(r"<h[23]>(.*?)</h[23]>", html, re.S)
    }
    pages = [p for p in text.split("\f") if p.strip()]
    assert len(pages) >= 3
    for k, page in enumerate(pages[:-1]):
        last = " ".join(page.strip().splitlines()[-1].split())
        assert last not in headings, (k + 1, last)
        assert not any(
            h.startswith(last) or last.startswith(h) for h in headings if len(last) > 3
        ), (k + 1, last)
