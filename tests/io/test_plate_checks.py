"""msk.io.plate_checks: a clipped (saturated) force-plate channel is said, a real one is not."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from msk.io.c3d import read_c3d
from msk.io.plate_checks import longest_run_at_extreme

REPO = Path(__file__).resolve().parents[2]
GC5 = REPO / "data" / "gc5-PS" / "PS_ngait_og_ss1.c3d"


def test_longest_run_at_extreme():
    x = np.array([0.0, 1.0, 5.0, 5.0, 5.0, 2.0, 5.0, -1.0, -1.0])
    assert longest_run_at_extreme(x) == (3, 5.0)
    assert longest_run_at_extreme(np.full(3, np.nan))[0] == 0


def _clipped(tmp_path: Path, fraction: float) -> Path:
    import ezc3d

    c = ezc3d.c3d(str(GC5))
    labels = [s.strip() for s in c["parameters"]["ANALOG"]["LABELS"]["value"]]
    chan = np.asarray(c["parameters"]["FORCE_PLATFORM"]["CHANNEL"]["value"]) - 1
    a = c["data"]["analogs"]
    k = int(chan[2, 0])  # plate 1's Fz channel (type 2: Fx Fy Fz Mx My Mz)
    x = a[0, k, :]
    peak = x.max() if abs(x.max()) > abs(x.min()) else x.min()
    a[0, k, :] = (
        np.clip(x, None, fraction * peak) if peak > 0 else np.clip(x, fraction * peak, None)
    )
    c["data"]["analogs"] = a
    f = tmp_path / f"clip{fraction:g}.c3d"
    c.write(str(f))
    assert labels[k]
    return f


def test_a_clipped_vertical_channel_is_a_reader_warning(tmp_path):
    tr = read_c3d(_clipped(tmp_path, 0.8), isolate=False)
    notes = [w for w in tr.metadata["warnings"] if "clipped" in w]
    assert len(notes) == 1 and notes[0].startswith("force platform 1: force z")


@pytest.mark.realdata
def test_the_real_plates_are_not_called_clipped():
    tr = read_c3d(GC5, isolate=False)
    assert not [w for w in tr.metadata.get("warnings", ()) if "clipped" in w]


def test_a_cop_far_off_the_plate_is_said_a_real_one_is_not():
    import dataclasses

    from msk.io.plate_checks import cop_warnings

    tr = read_c3d(GC5, isolate=False)
    assert all(cop_warnings(p) == [] for p in tr.plates)
    p = tr.plates[0]
    moved = dataclasses.replace(p, cop=p.cop + np.array([141.0, 0.0, 0.0]))
    (note,) = cop_warnings(moved)
    assert note.startswith("force platform 1: centre of pressure 141 m")


@pytest.mark.parametrize("which", ["all", "one"])
def test_a_negative_gain_is_said(tmp_path, which):
    """Every plate's channels negated (a negative gain: the reader's vertical turns upside
    down, the markers then lie below the floor) or one plate's (it pulls into the floor)."""
    import ezc3d

    c = ezc3d.c3d(str(GC5))
    chan = np.asarray(c["parameters"]["FORCE_PLATFORM"]["CHANNEL"]["value"]) - 1
    a = c["data"]["analogs"]
    cols = chan.ravel() if which == "all" else chan[:, 1]
    a[0, cols, :] *= -1.0
    c["data"]["analogs"] = a
    c.write(str(tmp_path / "neg.c3d"))
    notes = read_c3d(tmp_path / "neg.c3d", isolate=False).metadata["warnings"]
    if which == "all":
        assert any("upside down" in w for w in notes), notes
    else:
        assert any(w.startswith("force platform 2: its force points down") for w in notes), notes
