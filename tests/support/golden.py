"""Golden outputs of the shipped sessions: a fingerprint of every table a run writes and the
report's section headings, stored in ``tests/golden/<config>.json``.

A fingerprint keeps, per table, its columns and row count and, per column, the maximum
absolute value, the sum, the sum of absolute values and the values at up to nine evenly spaced
rows (NaN as ``null``). :func:`compare` accepts differences up to ``rtol`` times the column's
maximum absolute value (issue 14: outputs equal to today's to 1e-9) — a change of one value
anywhere moves the sums by as much —, and never less than the round-off of the table's values
(rows × ε × the table's largest value): a column that is round-off around zero (a muscle that
does not work, |a| ~ 1e-16) is not compared to 1e-9 of its own noise (issue 20: solving each
leg's QP apart moves such values by ~1e-16). Refresh after an
intended change of the numbers with ``MSK_UPDATE_GOLDEN=1 pytest tests/test_shipped_sessions.py``
and say in the CHANGELOG why they changed.
"""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

GOLDEN = Path(__file__).resolve().parents[1] / "golden"
RTOL = 1e-9
N_SAMPLES = 9


def _num(x: float) -> float | None:
    return None if not math.isfinite(x) else float(x)


def fingerprint(folder: Path) -> dict[str, Any]:
    """Fingerprint of the results folder ``folder`` (``tables/*.csv`` and ``report.html``)."""
    tables: dict[str, Any] = {}
    for f in sorted((folder / "tables").glob("*.csv")):
        header = f.read_text(encoding="utf-8").splitlines()[0].split(",")
        x = np.atleast_2d(np.genfromtxt(f, delimiter=",", skip_header=1))
        rows = np.unique(np.linspace(0, x.shape[0] - 1, min(N_SAMPLES, x.shape[0])).astype(int))
        cols = {}
        for k, name in enumerate(header):
            c = x[:, k]
            fin = c[np.isfinite(c)]
            cols[name] = {
                "max_abs": _num(float(np.max(np.abs(fin)))) if fin.size else None,
                "sum": _num(float(fin.sum())),
                "sum_abs": _num(float(np.abs(fin).sum())),
                "n_finite": int(fin.size),
                "samples": [_num(float(c[r])) for r in rows],
            }
        tables[f.stem] = {"rows": int(x.shape[0]), "columns": cols}
    html = (folder / "report.html").read_text(encoding="utf-8")
    sections = re.findall(r"<h[12][^>]*>(.*?)</h[12]>", html)
    return {"tables": tables, "report_sections": sections}


def _close(a: float | None, b: float | None, scale: float, floor: float = 0.0) -> bool:
    if a is None or b is None:
        return a is b
    return abs(a - b) <= max(RTOL * scale, floor) + 1e-300


def compare(expected: dict[str, Any], actual: dict[str, Any]) -> list[str]:
    """Differences of ``actual`` from ``expected`` beyond :data:`RTOL` (empty when equal)."""
    out: list[str] = []
    if expected["report_sections"] != actual["report_sections"]:
        out.append(f"report sections {expected['report_sections']} → {actual['report_sections']}")
    et, at = expected["tables"], actual["tables"]
    if set(et) != set(at):
        out.append(f"tables {sorted(et)} → {sorted(at)}")
    for name in sorted(set(et) & set(at)):
        e, a = et[name], at[name]
        if e["rows"] != a["rows"] or list(e["columns"]) != list(a["columns"]):
            out.append(f"{name}: shape or columns changed")
            continue
        largest = max((c["max_abs"] or 0.0 for c in e["columns"].values()), default=0.0)
        floor = e["rows"] * float(np.finfo(float).eps) * largest  # round-off of the table
        for col, ec in e["columns"].items():
            ac = a["columns"][col]
            scale = ec["max_abs"] or 0.0
            ok = ec["n_finite"] == ac["n_finite"]
            ok = ok and _close(ec["max_abs"], ac["max_abs"], scale, floor)
            ok = ok and _close(ec["sum"], ac["sum"], scale, floor)
            ok = ok and _close(ec["sum_abs"], ac["sum_abs"], scale, floor)
            ok = ok and all(
                _close(u, v, scale, floor) for u, v in zip(ec["samples"], ac["samples"])
            )
            if not ok:
                out.append(f"{name}.{col}: {ec} → {ac}")
    return out


def check(config_stem: str, folder: Path) -> list[str]:
    """Compare ``folder`` with the golden file of ``config_stem`` (write it under
    ``MSK_UPDATE_GOLDEN=1``)."""
    path = GOLDEN / f"{config_stem}.json"
    actual = fingerprint(folder)
    if os.environ.get("MSK_UPDATE_GOLDEN") == "1":
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(actual, separators=(",", ":")) + "\n", encoding="utf-8")
        return []
    if not path.is_file():
        return [f"no golden file {path.name}: run with MSK_UPDATE_GOLDEN=1"]
    return compare(json.loads(path.read_text(encoding="utf-8")), actual)
