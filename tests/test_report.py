"""msk.report: the self-contained HTML report, rendered in headless Chromium."""

from __future__ import annotations

import re
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

from msk.io.opensim_files import Table
from msk.pipeline import run_session
from msk.report import render_html, write_pdf
from msk.report.html import chromium_args, chromium_executable
from msk.results import SessionResults, read_session

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    out = tmp_path_factory.mktemp("report") / "gc5"
    run_session(REPO / "pipelines" / "gc5_PS.toml", out)
    return read_session(out)


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
    assert html.count("<svg") == 5  # strength, mass, joints, muscles, contact
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
    assert len(rows) == 1 + len(session.summary["strength"]["groups"])
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
    from msk.report.html import _strength_status

    assert _strength_status({"identified": True, "factor": 1.13}, [0.5, 2.0]) == "identified"
    assert _strength_status({"identified": True, "factor": 0.5}, [0.5, 2.0]).startswith("at bound")
    assert _strength_status({"identified": True, "factor": 2.0}, [0.5, 2.0]).startswith("at bound")
    assert _strength_status({"identified": False, "factor": 1.0}, [0.5, 2.0]) == "kept generic"
