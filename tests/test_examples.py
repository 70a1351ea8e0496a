"""The runnable examples in ``examples/`` (Python-API scripts) run to completion, and the
figures they print equal the pipeline's: ``msk run`` on the same session (its summary.json
and tables), ``read_c3d`` for the loading example."""

from __future__ import annotations

import csv
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((REPO / "examples").glob("*.py"))
#: examples that run a whole session (slow lane); the others run in the fast lane
SESSION_EXAMPLES = {"02_ik_id", "03_static_optimization", "04_identify_mass"}
#: session examples run (in a fresh folder, checked by ``_run``) and compared with ``msk run``
#: by :func:`test_examples_print_msk_runs_figures`: not run a second time on their own
COMPARED_EXAMPLES = {"02_ik_id", "03_static_optimization"}
MSK = [sys.executable, "-c", "import sys; from msk.cli import main; sys.exit(main())"]


def _run(script: Path, *args: str) -> str:
    proc = subprocess.run(
        [sys.executable, str(script), *args], cwd=REPO, capture_output=True, text=True,
        timeout=900, check=False,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip()
    return proc.stdout


@pytest.mark.slow
@pytest.mark.parametrize(
    "script",
    [p for p in EXAMPLES if p.stem in SESSION_EXAMPLES - COMPARED_EXAMPLES],
    ids=[p.stem for p in EXAMPLES if p.stem in SESSION_EXAMPLES - COMPARED_EXAMPLES],
)
def test_session_example_runs(script: Path, tmp_path: Path) -> None:
    if script.stem == "04_identify_mass":
        _run(script)
    else:
        _run(script, str(tmp_path / "out"))


def test_every_session_example_is_run() -> None:
    """Each session example runs in one slow test: on its own, or compared with ``msk run``."""
    assert COMPARED_EXAMPLES <= SESSION_EXAMPLES
    assert SESSION_EXAMPLES <= {p.stem for p in EXAMPLES}


def test_loading_example_prints_the_readers_figures() -> None:
    from msk.io import read_c3d

    out = _run(REPO / "examples/01_load_c3d.py")
    tr = read_c3d(REPO / "data/gc5-PS/PS_ngait_og_ss1.c3d")
    assert f"{tr.n_frames} frames at {tr.point_rate_hz:g} Hz" in out
    for p in tr.plates:
        peak = float(np.nanmax(np.linalg.norm(p.force, axis=1)))
        assert f"plate {p.index + 1}: peak |F| {peak:.0f} N" in out


def _column_max(path: Path, column: str) -> float:
    with path.open(encoding="utf-8") as fh:
        vals = [float(r[column]) for r in csv.DictReader(fh) if r[column] not in ("", "nan")]
    return max(vals)


@pytest.mark.slow
@pytest.mark.realdata
def test_examples_print_msk_runs_figures(tmp_path: Path) -> None:
    """Examples 02 and 03 (the one-call API) print what ``msk run`` writes for the same
    session in another folder: IK RMS 8.5 mm, peak knee contact 2.37 BW (generic)."""
    ref = tmp_path / "cli"
    cmd = [*MSK, "run", str(REPO / "pipelines/gc5_PS.toml"), "--out", str(ref), "--quiet"]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=900, check=False)
    assert r.returncode == 0, r.stderr[-2000:]
    summary = json.loads((ref / "summary.json").read_text(encoding="utf-8"))
    ex = tmp_path / "example"
    out02 = _run(REPO / "examples/02_ik_id.py", str(ex))
    ik = float(re.search(r"IK marker RMS ([\d.]+) mm", out02).group(1))  # type: ignore[union-attr]
    assert ik == round(1000 * summary["quality"]["ik_marker_rms_mean_m"], 1)
    assert ik == pytest.approx(8.5, abs=0.3)
    tau = ref / "tables" / "joint_torques.csv"
    with tau.open(encoding="utf-8") as fh:
        knee = [float(r["knee_angle_l"]) for r in csv.DictReader(fh) if r["knee_angle_l"]]
    knee_a = np.asarray(knee)
    assert f"{np.nanmin(knee_a):.0f}…{np.nanmax(knee_a):.0f} N·m" in out02
    out03 = _run(REPO / "examples/03_static_optimization.py", str(ex))
    contact = ref / "tables" / "knee_contact.csv"
    for variant in ("generic", "subject_specific", "measured"):
        total = _column_max(contact, f"{variant}_total_bw")
        assert f"{variant}: peak knee contact {total:.2f} BW" in out03
    assert "generic: peak knee contact 2.37 BW" in out03
