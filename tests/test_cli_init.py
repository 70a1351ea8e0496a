"""``msk init``: a first session configuration from a lab's recordings that ``msk run`` runs
as written (Plug-in Gait on btkdata, the bundled Grand Challenge PS session)."""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from msk.cli.init import starter_config, task_plate_mass
from msk.config import load_config
from msk.datasets.shared import real_data_dir

REPO = Path(__file__).resolve().parents[1]
GC5 = [REPO / "data/gc5-PS/PS_ngait_og_ss1.c3d", REPO / "data/gc5-PS/PS_static_for_scaling.trc"]
PIG = [real_data_dir() / "btkdata/PiG_Motion3_FF.c3d",
       real_data_dir() / "btkdata/PiG_Calibration3_FF.c3d"]  # fmt: skip
MSK = [sys.executable, "-c", "import sys; from msk.cli import main; sys.exit(main())"]


def _write(tmp_path: Path, files: list[Path]) -> Path:
    out = tmp_path / "cfg" / "session.toml"
    out.parent.mkdir()
    out.write_text(starter_config(files, out), encoding="utf-8")
    return out


def test_gc5_config_recognises_roles_markers_emg_and_weighs_the_subject(tmp_path):
    out = _write(tmp_path, GC5)
    doc = tomllib.loads(out.read_text(encoding="utf-8"))
    roles = {Path(t["file"]).name: t["role"] for t in doc["trials"]}
    assert roles == {"PS_ngait_og_ss1.c3d": "task", "PS_static_for_scaling.trc": "static"}
    shipped = tomllib.loads((REPO / "pipelines/gc5_PS.toml").read_text(encoding="utf-8"))
    # the same pairs and foot markers moved as the hand-written session (Sternum's label is
    # the model's name: paired without a line)
    want = {k: v for k, v in shipped["markers"]["rename"].items() if k != v}
    assert doc["markers"]["rename"] == want
    assert set(doc["markers"]["move"]) == set(shipped["markers"]["move"])
    assert doc["emg"]["channels"]["vas_med_r"] == "vasmed"  # unsided labels: right assumed
    assert "name no side" in out.read_text(encoding="utf-8")
    # no file stores the mass and the static is a .trc: the task's plates weigh the subject
    assert doc["subject"]["mass_kg"] == pytest.approx(83.4, abs=0.1)
    cfg = load_config(out)  # a valid configuration, paths relative to it
    assert cfg.trials[0].file.resolve() == GC5[0].resolve()


def test_plugin_gait_config(tmp_path):
    out = _write(tmp_path, PIG)
    text = out.read_text(encoding="utf-8")
    doc = tomllib.loads(text)
    assert doc["subject"]["mass_kg"] == 74.0 and "Bodymass" in text
    assert doc["subject"]["height_m"] == pytest.approx(1.76)
    assert doc["markers"]["rename"]["R.ASIS"] == "RASI"
    assert "move" not in doc["markers"]  # one heel marker per foot: nothing to move
    assert "analog channel 'EMG1' names no gait2392 muscle" in text
    assert "not used (model output, not a marker): LFEO" in text
    load_config(out)


def test_task_plate_mass_known_truth():
    class P:
        rate_hz = 100.0

        def __init__(self, f):
            self.force = f

    class T:
        up = np.array([0.0, 0.0, 1.0])

    n = 300
    fz = np.zeros(n)
    fz[50:250] = 70.0 * 9.80665 * (1.0 + 0.2 * np.sin(np.linspace(0, 4 * np.pi, 200)))
    T.plates = [P(np.column_stack([np.zeros(n), np.zeros(n), fz]))]
    m, span = task_plate_mass(T)
    assert m == pytest.approx(70.0, rel=0.01) and span == pytest.approx(2.0)


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.parametrize(("files", "ik_mm"), [(GC5, 9.0), (PIG, 15.0)], ids=["gc5", "pig"])
def test_init_then_run(tmp_path, files, ik_mm):
    cfg = tmp_path / "session.toml"
    r = subprocess.run([*MSK, "init", *map(str, files), "--out", str(cfg)],
                       capture_output=True, text=True, timeout=300, check=False)  # fmt: skip
    assert r.returncode == 0, r.stderr
    r = subprocess.run([*MSK, "run", str(cfg), "--out", str(tmp_path / "out"), "--quiet"],
                       capture_output=True, text=True, timeout=900, check=False)  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    s = json.loads((tmp_path / "out" / "summary.json").read_text(encoding="utf-8"))
    assert s["quality"]["ik_marker_rms_mean_m"] < ik_mm / 1000
    assert (tmp_path / "out" / "report.html").is_file()
