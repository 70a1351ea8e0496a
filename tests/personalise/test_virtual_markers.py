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


def test_configured_virtual_markers_mean_and_offset() -> None:
    """``mean(A, B)`` is the midpoint (NaN where a marker is missing, exact zeros included);
    ``offset(O, X, P, dx, dy, dz)`` the point at (dx, dy, dz) in the frame of O, X, P: known
    on a rotated, translated marker triad."""
    from msk.personalise.virtual_markers import parse_virtual, with_virtual_markers

    rng = np.random.default_rng(1)
    n = 6
    o = rng.normal(size=(n, 3))
    rot = [np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(n)]
    rot = [r * np.sign(np.linalg.det(r)) for r in rot]
    x_ax = np.array([r[:, 0] for r in rot])
    y_ax = np.array([r[:, 1] for r in rot])
    z_ax = np.array([r[:, 2] for r in rot])
    a = o + 0.2 * x_ax
    b = o + 0.1 * x_ax + 0.15 * y_ax  # in the x-y plane: z normal to it
    x = np.stack([o, a, b], axis=1)
    x[3, 1] = 0.0  # a gap in A
    tr = _Trial(x, ("O", "A", "B"))
    out, notes = with_virtual_markers(
        tr, {"MID": "mean(O, A)", "PT": "offset(O, A, B, 0.01, 0.02, -0.03)"}
    )
    assert out.marker_labels == ("O", "A", "B", "MID", "PT")
    mid, pt = out.markers[:, 3], out.markers[:, 4]
    ok = [0, 1, 2, 4, 5]
    assert np.allclose(mid[ok], 0.5 * (o[ok] + a[ok])) and np.isnan(mid[3]).all()
    want = o + 0.01 * x_ax + 0.02 * y_ax - 0.03 * z_ax
    assert np.allclose(pt[ok], want[ok], atol=1e-12) and np.isnan(pt[3]).all()
    assert notes[0]["from"] == ["O", "A"] and notes[1]["frames_missing"] == 1
    # an existing label is replaced, not duplicated
    again, _ = with_virtual_markers(out, {"MID": "mean(A, B)"})
    assert again.marker_labels == out.marker_labels
    from msk.exceptions import ConfigError, MissingDataError

    for bad in ("midpoint(A, B)", "mean(A)", "mean(A, A)", "offset(O, A, B, 1, 2)",
                "offset(O, A, B, x, 0, 0)", "offset(O, O, B, 0, 0, 0)"):  # fmt: skip
        with pytest.raises(ConfigError, match=r"markers\.virtual\.V"):
            parse_virtual("V", bad)
    with pytest.raises(MissingDataError, match="no marker Q"):
        with_virtual_markers(tr, {"V": "mean(O, Q)"})


def test_a_configuration_names_its_virtual_markers(tmp_path: Path) -> None:
    from msk.config import load_config
    from msk.exceptions import ConfigError

    base = (
        '[subject]\nname = "s"\nmass_kg = 70.0\nheight_m = 1.7\n'
        '[model]\nsource = "gait2392"\n'
        '[[trials]]\nname = "w"\nfile = "w.c3d"\nrole = "task"\n'
    )
    p = tmp_path / "c.toml"
    p.write_text(base + '[markers]\nvirtual = { "V.Sacral" = "mean(LPSI, RPSI)" }\n')
    (tmp_path / "w.c3d").write_bytes(b"")
    cfg = load_config(p)
    assert dict(cfg.marker_virtual) == {"V.Sacral": "mean(LPSI, RPSI)"}
    assert dict(cfg.markers.virtual) == {"V.Sacral": "mean(LPSI, RPSI)"}
    p.write_text(base + '[markers]\nvirtual = { "V.Sacral" = "middle(LPSI, RPSI)" }\n')
    with pytest.raises(ConfigError, match=r"markers\.virtual\.V\.Sacral"):
        load_config(p)
