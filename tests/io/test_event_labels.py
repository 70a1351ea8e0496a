"""Gait events in every common naming (msk.io.event_labels), and the C3D reader's use of them."""

from __future__ import annotations

from pathlib import Path

import pytest

from msk.io.event_labels import gait_event, standard_events
from msk.trial import Event

PS = "knee-grand-challenge-gc5/PS_ngait_og_ss1.c3d"


@pytest.mark.parametrize(
    ("label", "context", "expected"),
    [
        ("Foot Strike", "Left", ("Foot Strike", "Left")),
        ("Foot Off", "right", ("Foot Off", "Right")),
        ("LHS", "", ("Foot Strike", "Left")),
        ("RHS", "General", ("Foot Strike", "Right")),
        ("LTO", "General", ("Foot Off", "Left")),
        ("RTO", "", ("Foot Off", "Right")),
        ("R_FS", "", ("Foot Strike", "Right")),
        ("Left Heel Strike", "General", ("Foot Strike", "Left")),
        ("Right Toe Off", "", ("Foot Off", "Right")),
        ("LIC", "", ("Foot Strike", "Left")),
        ("HS", "R", ("Foot Strike", "Right")),
        ("Event", "Right", None),
        ("LHS", "Right", None),  # contradictory side: not guessed
        ("Foot Strike", "General", None),  # no side
        ("Lunge", "", None),
    ],
)
def test_gait_event_namings(label: str, context: str, expected) -> None:
    assert gait_event(label, context) == expected


def test_standard_events_rewrites_and_keeps_the_rest_apart() -> None:
    evs = [Event("LHS", "", 1.0), Event("RTO", "General", 1.2), Event("Start", "General", 0.5)]
    ok, other = standard_events(evs)
    assert ok == (Event("Foot Strike", "Left", 1.0), Event("Foot Off", "Right", 1.2))
    assert other == (Event("Start", "General", 0.5),)


def _relabelled(real_dir: Path, tmp_path: Path, names: dict[str, str]) -> Path:
    """The PS walk with its EVENT labels renamed (Vicon → ``names``) and contexts blanked,
    byte for byte otherwise."""
    from tests.support.c3d_mutants import label_width, parameters, set_text

    src = real_dir / PS
    if not src.is_file():
        pytest.skip(f"{PS} absent")
    data = bytearray(src.read_bytes())
    _, _, params = parameters(bytes(data))
    w_lab = label_width(bytes(data), ("EVENT", "LABELS"))
    w_ctx = label_width(bytes(data), ("EVENT", "CONTEXTS"))
    raw = params[("EVENT", "LABELS")].data
    labels = [raw[i : i + w_lab].decode().strip() for i in range(0, len(raw), w_lab)]
    for k, lab in enumerate(labels):
        set_text(data, ("EVENT", "LABELS"), k * w_lab, names[lab].ljust(w_lab).encode())
        set_text(data, ("EVENT", "CONTEXTS"), k * w_ctx, b" " * w_ctx)
    out = tmp_path / "qualisys.c3d"
    out.write_bytes(bytes(data))
    return out


@pytest.mark.realdata
def test_qualisys_labels_are_read_as_the_vicon_events(real_dir: Path, tmp_path: Path) -> None:
    from msk.io import read_c3d

    f = _relabelled(real_dir, tmp_path, {"Foot Strike": "LHS", "Foot Off": "LTO"})
    original = read_c3d(real_dir / PS)
    renamed = read_c3d(f)
    assert original.events and renamed.events == original.events
    assert not renamed.metadata["warnings"]


@pytest.mark.realdata
def test_unrecognised_event_labels_are_said(real_dir: Path, tmp_path: Path) -> None:
    from msk.io import read_c3d

    f = _relabelled(real_dir, tmp_path, {"Foot Strike": "LHS", "Foot Off": "Peak"})
    tr = read_c3d(f)
    assert {e.label for e in tr.events} == {"Foot Strike", "Peak"}
    (msg,) = [w for w in tr.metadata["warnings"] if "event" in w]
    assert "'Peak'" in msg and "not read as a foot strike or foot off" in msg
