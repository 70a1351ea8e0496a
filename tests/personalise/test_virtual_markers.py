"""The PSIS midpoint standing for a missing sacral marker (msk.personalise.virtual_markers)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from msk.model.files import load_model
from msk.personalise.virtual_markers import with_virtual_sacrum

ROOT = Path(__file__).resolve().parents[2]


@dataclasses.dataclass(frozen=True)
class _Trial:
    markers: np.ndarray
    marker_labels: tuple[str, ...]


def test_the_psis_midpoint_becomes_the_models_sacral_marker() -> None:
    model = load_model(ROOT / "msk" / "data" / "models" / "gait2392.toml")
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
    model = load_model(ROOT / "msk" / "data" / "models" / "gait2392.toml")
    x = np.ones((3, 4, 3))
    for labels in (("RASI", "LASI", "RPSI", "SACR"), ("RASI", "LASI", "RPSI", "LTHI")):
        tr = _Trial(x, labels)
        out, note = with_virtual_sacrum(tr, model)
        assert out is tr and note is None
    # a model without a sacral marker: nothing to stand for
    bare = SimpleNamespace(markers=[m for m in model.markers if m.name != "V.Sacral"])
    tr = _Trial(x, ("RASI", "LASI", "RPSI", "LPSI"))
    assert with_virtual_sacrum(tr, bare) == (tr, None)


def _pig_config(real_dir: Path, folder: Path, static: bool) -> Path:
    trials = ""
    if static:
        trials = (
            f'[[trials]]\nname = "static"\n'
            f'file = "{real_dir}/btkdata/PiG_Calibration3_FF.c3d"\nrole = "static"\n'
        )
    p = folder / f"pig_{static}.toml"
    p.write_text(
        f'[subject]\nname = "s"\nmass_kg = 74.0\nheight_m = 1.76\nside = "right"\n'
        f'[model]\nsource = "{ROOT / "msk" / "data" / "models" / "gait2392.toml"}"\n{trials}'
        f'[[trials]]\nname = "walk"\nfile = "{real_dir}/btkdata/PiG_Motion3_FF.c3d"\n'
        'role = "task"\n',
        encoding="utf-8",
    )
    return p


@pytest.mark.slow
@pytest.mark.realdata
def test_a_walk_without_its_static_keeps_the_pelvis_tilt_of_the_static(
    real_dir: Path, tmp_path: Path
) -> None:
    """PiG_Motion3_FF (ASIS + PSIS, no sacral marker) without its static: the PSIS midpoint
    as the sacral marker pins the pelvis tilt near the one the static gives (11.2° before,
    against 2.4° with the static)."""
    from msk.pipeline.session import run_stages

    if not (real_dir / "btkdata" / "PiG_Calibration3_FF.c3d").is_file():
        pytest.skip("btkdata PiG files absent")
    tilt = {}
    for static in (False, True):
        r = run_stages(_pig_config(real_dir, tmp_path, static), until="kinematics")
        kin = r["kinematics"]
        j = list(kin.coordinate_names).index("pelvis_tilt")
        tilt[static] = float(np.degrees(np.nanmean(kin.q[:, j])))
        if not static:
            (v,) = r["model"].info["virtual_markers"]
            assert v["marker"] == "V.Sacral" and v["from"] == ["RPSI", "LPSI"]
    assert abs(tilt[False] - tilt[True]) < 4.0, tilt
