"""msk.dynamics.plate_contact: a plate that reads nothing while a foot stands on it is a quality
flag."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.slow
@pytest.mark.realdata
def test_a_dead_plate_under_the_measured_leg_is_flagged(tmp_path):
    """gc5 PS with plate 1's channels zeroed (a dead amplifier): the left foot stands on it,
    unmeasured, for 0.78 s — flagged `plate_dead` (was: no flag); the clean run has none."""
    import ezc3d

    from msk.pipeline import run_session

    c = ezc3d.c3d(str(REPO / "data" / "gc5-PS" / "PS_ngait_og_ss1.c3d"))
    chan = np.asarray(c["parameters"]["FORCE_PLATFORM"]["CHANNEL"]["value"]) - 1
    a = c["data"]["analogs"]
    a[0, chan[:, 0], :] = 0.0
    c["data"]["analogs"] = a
    c.write(str(tmp_path / "dead.c3d"))
    gc5 = REPO / "pipelines" / "gc5_PS.toml"
    text = gc5.read_text(encoding="utf-8").replace('"../', f'"{REPO}/')
    text = text.replace(f'"{REPO}/data/gc5-PS/PS_ngait_og_ss1.c3d"', f'"{tmp_path}/dead.c3d"')
    (tmp_path / "dead.toml").write_text(text, encoding="utf-8")
    d = run_session(tmp_path / "dead.toml", tmp_path / "out").summary.to_dict()
    (flag,) = [f for f in d["quality"]["flags"] if f["quantity"] == "plate_dead"]
    assert "plate1" in flag["message"] and "calcn_l" in flag["message"]
    clean = run_session(gc5, tmp_path / "clean").summary.to_dict()
    assert not [f for f in clean["quality"]["flags"] if f["quantity"] == "plate_dead"]


def test_inside_a_shrunk_outline():
    from msk.dynamics.plate_contact import _inside, _plane_axes

    square = np.array([[0.0, 0.0], [0.6, 0.0], [0.6, 0.4], [0.0, 0.4]])
    pts = np.array([[0.3, 0.2], [0.01, 0.2], [0.7, 0.2]])
    assert _inside(pts, square, 0.02).tolist() == [True, False, False]
    axes = _plane_axes(np.array([0.0, 1.0, 0.0]))
    assert np.allclose(axes.T @ axes, np.eye(2)) and np.allclose(axes.T @ [0, 1, 0], 0)
