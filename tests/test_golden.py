"""The golden-output comparison itself (tests/support/golden.py) sees a change of 1e-8 and
ignores one of 1e-12, relative to a column's largest value."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np

from msk.io.opensim_files import Table
from msk.io.tables import write_csv_table
from tests.support import golden


def _folder(tmp_path: Path, bump: float) -> Path:
    f = tmp_path / f"run{bump:g}"
    (f / "tables").mkdir(parents=True)
    t = np.linspace(0.0, 1.0, 50)
    data = np.column_stack([np.sin(7 * t) * 300.0, np.cos(3 * t)])
    data[10, 1] = np.nan
    data[25, 0] *= 1.0 + bump
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
    configs = sorted((Path(__file__).resolve().parents[1] / "pipelines").glob("*.toml"))
    assert {c.stem for c in configs} <= {p.stem for p in golden.GOLDEN.glob("*.json")}
