"""The golden-output comparison itself (tests/support/golden.py) sees a change of 1e-8 and
ignores one of 1e-12, relative to a column's largest value; on another machine or other
packages than the golden's it takes 0.1 % and sees 10 %."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np

from msk.io.opensim_files import Table
from msk.io.tables import write_csv_table
from tests.support import golden


def _folder(tmp_path: Path, bump: float, scale: float = 1.0) -> Path:
    f = tmp_path / f"run{bump:g}_{scale:g}"
    (f / "tables").mkdir(parents=True)
    t = np.linspace(0.0, 1.0, 50)
    data = np.column_stack([np.sin(7 * t) * 300.0, np.cos(3 * t)])
    data[10, 1] = np.nan
    data[25, 0] *= 1.0 + bump
    data[:, 0] *= scale  # every row: a change a reader would see
    write_csv_table(f / "tables" / "q.csv", Table(t, data, ("a", "b"), "q"))
    (f / "report.html").write_text("<h1>msk</h1><h2>Kinematics</h2>", encoding="utf-8")
    return f


def test_golden_compare_sees_1e_8_not_1e_12(tmp_path):
    ref = golden.fingerprint(_folder(tmp_path, 0.0))
    assert golden.compare(ref, golden.fingerprint(_folder(tmp_path, 1e-12))) == []
    diff = golden.compare(ref, golden.fingerprint(_folder(tmp_path, 1e-8)))
    assert diff and diff[0].startswith("q.a")
    other = copy.deepcopy(ref)
    other["report_sections"].append("Strength")
    assert golden.compare(other, ref)


def test_every_shipped_config_has_a_golden_file():
    configs = sorted((Path(__file__).resolve().parents[2] / "pipelines").glob("*.toml"))
    assert {c.stem for c in configs} <= {p.stem for p in golden.GOLDEN.glob("*.json")}


def test_portable_compare_takes_round_off_not_a_change(tmp_path):
    ref = golden.fingerprint(_folder(tmp_path, 0.0))
    bumped = golden.fingerprint(_folder(tmp_path, 1e-3))
    assert golden.compare(ref, bumped, exact=False) == []
    assert golden.compare(ref, bumped)  # the exact comparison sees it
    diff = golden.compare(ref, golden.fingerprint(_folder(tmp_path, 0.0, 1.1)), exact=False)
    assert diff and diff[0].startswith("q.a")


def test_check_is_exact_only_in_the_goldens_environment(tmp_path, monkeypatch):
    monkeypatch.setattr(golden, "GOLDEN", tmp_path / "golden")
    monkeypatch.setenv("MSK_UPDATE_GOLDEN", "1")
    assert golden.check("s", _folder(tmp_path, 0.0)) == []
    monkeypatch.delenv("MSK_UPDATE_GOLDEN")
    bumped = _folder(tmp_path, 1e-3)
    assert golden.check("s", bumped)  # same environment: 1e-9
    stored = json.loads((tmp_path / "golden" / "s.json").read_text())
    assert stored["environment"] == golden.environment()
    stored["environment"] = {**stored["environment"], "blas": "another CPU's kernels"}
    (tmp_path / "golden" / "s.json").write_text(json.dumps(stored))
    assert golden.check("s", bumped) == []
    assert golden.check("s", _folder(tmp_path, 0.0, 1.1))
