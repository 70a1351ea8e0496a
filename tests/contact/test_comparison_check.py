"""msk.contact.comparison_check: a configured measured contact force that is not compared says
why (a quality flag), never vanishes silently."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from msk.contact.comparison_check import comparison_flags

REPO = Path(__file__).resolve().parents[2]
T = np.linspace(0.0, 1.0, 11)


def _flags(contact: str | None = "implant.csv", comparison=None, **kw):
    """The flags of trial ``walk`` (left side) with measured force file ``contact``."""
    kw = {"cycle": (0.1, 0.9), "foot_strikes": (0.1, 0.9), **kw}
    file = None if contact is None else Path(contact)
    return comparison_flags("walk", file, comparison, T, side="left", **kw)


def test_compared_or_not_configured_is_no_flag():
    assert _flags(None) == []
    done = {"knee_contact_generic": {"rms_bw": 0.2}}
    assert _flags(comparison=done, measured={"total": T}) == []


@pytest.mark.parametrize(
    ("kw", "why"),
    [
        ({"cycle": None, "foot_strikes": (0.3,)}, "no gait cycle of the left side"),
        ({"measured": None}, "knee_contact stage gave no measured force"),
        ({"measured": {"total": np.full(11, np.nan)}}, "overlaps, placed on the gait cycle"),
        ({"cycle_ran": False}, "gait cycle step did not run"),
    ],
)
def test_each_reason_is_said(kw, why):
    (flag,) = _flags(comparison={"residual_force_rms_n": {}}, **kw)
    assert flag.trial == "walk" and flag.quantity == "contact_comparison_not_available"
    assert "implant.csv not compared" in flag.message and why in flag.message
    assert flag.threshold == 5.0


@pytest.mark.slow
@pytest.mark.realdata
def test_a_moved_first_frame_is_said_not_silent(tmp_path):
    """gc5 PS with the C3D header's first frame moved by 3000: the file's events no longer
    fall in the trial; the implant comparison is not made — and a flag says why."""
    import ezc3d

    from msk.pipeline import run_session

    c = ezc3d.c3d(str(REPO / "data" / "gc5-PS" / "PS_ngait_og_ss1.c3d"))
    c["header"]["points"]["first_frame"] = c["header"]["points"]["first_frame"] + 3000
    c.write(str(tmp_path / "ff.c3d"))
    gc5 = REPO / "pipelines" / "gc5_PS.toml"
    text = gc5.read_text(encoding="utf-8").replace('"../', f'"{REPO}/')
    text = text.replace(f'"{REPO}/data/gc5-PS/PS_ngait_og_ss1.c3d"', f'"{tmp_path}/ff.c3d"')
    (tmp_path / "ff.toml").write_text(text, encoding="utf-8")
    d = run_session(tmp_path / "ff.toml", tmp_path / "out").summary.to_dict()
    compared = any(k.startswith("knee_contact") for k in d["comparison"])
    flags = [f for f in d["quality"]["flags"] if f["quantity"].startswith("contact_comparison")]
    assert compared != bool(flags)  # compared, or said why not: never silently dropped
    assert all("PS_ngait_og_ss1_eTibia.csv not compared" in f["message"] for f in flags)
