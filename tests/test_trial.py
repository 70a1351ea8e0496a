"""msk.trial: the Trial type and its records, apart from the readers; old import paths kept."""

from __future__ import annotations

import ast
import importlib.util
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from msk.trial import GapReport


def _msk_imports(module: str) -> set[str]:
    """Every msk module ``module`` imports: at top level, lazily or under TYPE_CHECKING."""
    spec = importlib.util.find_spec(module)
    assert spec is not None and spec.origin is not None
    out: set[str] = set()
    for node in ast.walk(ast.parse(Path(spec.origin).read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("msk"):
            out.add(node.module)
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("msk")}
    return out


def test_no_import_cycle_between_the_c3d_reader_the_frames_and_the_trial():
    assert "msk.io.frames" not in _msk_imports("msk.io.c3d")
    assert "msk.io.c3d" not in _msk_imports("msk.io.frames")
    assert not {m for m in _msk_imports("msk.trial") if m.startswith("msk.io")}
    assert "msk.io.opensim_files" not in _msk_imports("msk.io.tables")


def test_public_paths_of_moved_types_still_work():
    import msk.io
    import msk.io.c3d
    import msk.io.opensim_files
    import msk.io.tables
    import msk.model.joints
    import msk.model.osim
    import msk.trial

    for name in ("Trial", "ForcePlate", "Event", "Subject", "GapReport", "ModelOutputs"):
        assert getattr(msk.io, name) is getattr(msk.trial, name)
        assert getattr(msk.io.c3d, name) is getattr(msk.trial, name)
        assert getattr(msk.trial, name).__module__ == "msk.trial"
    assert msk.io.Table is msk.io.opensim_files.Table is msk.io.tables.Table
    assert msk.io.tables.Table.__module__ == "msk.io.tables"
    for name in ("PiecewiseLinear", "Composite"):
        assert getattr(msk.model.osim, name) is getattr(msk.model.joints, name)
        assert getattr(msk.model.joints, name).__module__ == "msk.model.joints"


def _longest_by_hand(col: np.ndarray) -> int:
    best = run = 0
    for x in col:
        run = run + 1 if x else 0
        best = max(best, run)
    return best


@settings(max_examples=80, deadline=None)
@given(
    missing=st.integers(0, 12).flatmap(
        lambda n: st.integers(0, 4).flatmap(
            lambda m: arrays(np.bool_, (n, m), elements=st.booleans())
        )
    )
)
def test_gap_report_counts_and_longest_runs(missing):
    labels = tuple(f"M{k}" for k in range(missing.shape[1]))
    g = GapReport.from_missing(labels, missing)
    assert g.labels == labels
    np.testing.assert_array_equal(g.n_missing, missing.sum(axis=0))
    assert g.n_missing.dtype == np.int64 and g.longest_gap.dtype == np.int64
    np.testing.assert_array_equal(
        g.longest_gap, [_longest_by_hand(missing[:, k]) for k in range(missing.shape[1])]
    )
    assert g.with_gaps() == tuple(lab for lab, n in zip(labels, g.n_missing) if n)
