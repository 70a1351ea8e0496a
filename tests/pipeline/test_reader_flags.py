"""A C3D the reader had to repair or doubt (a frame count the header and POINT:FRAMES disagree
on, a marker teleport made a gap) runs, and its typed reader flags reach ``summary.json`` with
their own quantity, so that ``msk run --strict`` exits 3 and a batch counts the session."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import ezc3d
import pytest

from tests.support.c3d_mutants import set_value

REPO = Path(__file__).resolve().parents[2]
MSK = [sys.executable, "-c", "import sys; from msk.cli import main; sys.exit(main())"]


@pytest.mark.slow
def test_reader_flags_reach_the_summary_and_strict_exits_3(tmp_path: Path) -> None:
    src = REPO / "data/gc5-PS/PS_ngait_og_ss1.c3d"
    c = ezc3d.c3d(str(src))
    pts = c["data"]["points"]
    labels = [s.strip() for s in c["parameters"]["POINT"]["LABELS"]["value"]]
    k = labels.index("L.Knee.Lat") if "L.Knee.Lat" in labels else labels.index("LAsis")
    pts[2, k, 70:72] += 120.0  # mm: two frames on a ghost 120 mm above
    c["data"]["points"] = pts
    mutant = tmp_path / "walk.c3d"
    c.write(str(mutant))
    data = bytearray(mutant.read_bytes())
    set_value(data, ("POINT", "FRAMES"), 99)
    mutant.write_bytes(bytes(data))
    text = (REPO / "pipelines/gc5_PS.toml").read_text(encoding="utf-8")
    text = text.replace('"../data/gc5-PS/PS_ngait_og_ss1.c3d"', json.dumps(str(mutant)))
    text = text.replace('"../', f'"{REPO}/')
    cfg = tmp_path / "s.toml"
    cfg.write_text(text, encoding="utf-8")
    out = tmp_path / "out"
    r = subprocess.run([*MSK, "run", str(cfg), "--out", str(out), "--quiet", "--strict"],
                       capture_output=True, text=True, timeout=900, check=False)  # fmt: skip
    assert r.returncode == 3, r.stderr[-2000:]
    flags = json.loads((out / "summary.json").read_text(encoding="utf-8"))["quality"]["flags"]
    by = {f["quantity"]: f for f in flags}
    assert "c3d_frame_count_mismatch" in by and "marker_teleport_samples" in by
    assert by["marker_teleport_samples"]["value"] == 2
    assert "frames 71–72 (120 mm)" in by["marker_teleport_samples"]["message"]
    assert not [f for f in flags if f["quantity"] == "input_file" and "teleport" in f["message"]]
