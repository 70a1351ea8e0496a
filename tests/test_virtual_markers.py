"""The PSIS midpoint standing for a missing sacral marker (msk.virtual_markers)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from msk.model_files import load_model
from msk.virtual_markers import with_virtual_sacrum

ROOT = Path(__file__).resolve().parents[1]


@dataclasses.dataclass(frozen=True)
class _Trial:
    markers: np.ndarray
    marker_labels: tuple[str, ...]


def test_the_psis_midpoint_becomes_the_models_sacral_marker() -> None:
    model = load_model(ROOT / "models" / "gait2392.toml")
    rng = np.random.default_rng(0)
    x = rng.normal(size=(5, 4, 3))
    x[2, 3] = 0.0  # a gap (exact zeros) in LPSI
    tr = _Trial(x, ("RASI", "LASI", "RPSI", "LPSI"))
    out, note = with_virtual_sacrum(tr, model)
    assert out.marker_labels[-1] == "V.Sacral" and note is not None
    assert note["from"] == ["RPSI", "LPSI"]
    mid = out.markers[:, -1]
    ok = [0, 1, 3, 4]
    assert np.allclose(mid[ok], 0.5 * (x[ok, 2] + x[ok, 3]))
    assert np.isnan(mid[2]).all()
    assert np.array_equal(out.markers[:, :4], x)


def test_nothing_is_added_with_a_sacral_marker_or_one_psis() -> None:
    model = load_model(ROOT / "models" / "gait2392.toml")
    x = np.ones((3, 4, 3))
    for labels in (("RASI", "LASI", "RPSI", "SACR"), ("RASI", "LASI", "RPSI", "LTHI")):
        tr = _Trial(x, labels)
        out, note = with_virtual_sacrum(tr, model)
        assert out is tr and note is None
    # a model without a sacral marker: nothing to stand for
    bare = SimpleNamespace(markers=[m for m in model.markers if m.name != "V.Sacral"])
    tr = _Trial(x, ("RASI", "LASI", "RPSI", "LPSI"))
    assert with_virtual_sacrum(tr, bare) == (tr, None)
