"""msk._runtime.terminal and the CLI: no control character of a data file reaches the terminal."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from msk._runtime.terminal import terminal_safe

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(
    ("raw", "shown"),
    [
        ("EMG\x1b[2J", "EMG\\x1b[2J"),
        ("a\x07b\rc", "a\\x07b\\x0dc"),
        ("csi\x9b31m", "csi\\x9b31m"),
        ("left\u202eright", "left\\u202eright"),
        ("line\nbreak", "line\\x0abreak"),
        ("knee 12.5° × 2 é", "knee 12.5° × 2 é"),
    ],
)
def test_controls_are_escaped_text_is_kept(raw, shown):
    assert terminal_safe(raw) == shown
    assert terminal_safe(raw + "\n", keep_newline=True).endswith("\n")


def test_msk_info_sanitises_labels_and_prints_the_readers_warnings(tmp_path, capsys):
    import ezc3d

    from msk.cli import main

    c = ezc3d.c3d(str(REPO / "data" / "gc5-PS" / "PS_ngait_og_ss1.c3d"))
    events = list(c["parameters"]["EVENT"]["LABELS"]["value"])
    events[1] = "Foot Off\x1b]0;pwned\x07"
    c["parameters"]["EVENT"]["LABELS"]["value"] = events
    c["parameters"]["SUBJECTS"]["NAMES"]["value"] = ["PS\x9b2J\u202e"]
    points = list(c["parameters"]["POINT"]["LABELS"]["value"])
    points[1] = points[0]  # a repeated label: the reader renames it and says so
    c["parameters"]["POINT"]["LABELS"]["value"] = points
    c.write(str(tmp_path / "t.c3d"))
    assert main(["info", str(tmp_path / "t.c3d")]) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and "\x07" not in out and "\x9b" not in out
    assert "Foot Off\\x1b]0;pwned\\x07" in out
    (line,) = [ln for ln in out.splitlines() if ln.startswith("reader warnings:")]
    assert int(line.split(":")[1]) >= 1 and "repeated labels" in out
    assert np.all([ln.isprintable() for ln in out.splitlines()])


def test_a_trc_number_with_an_underscore_is_not_read(tmp_path):
    """Python's float() reads "1_20" as 120: a TRC's DataRate or a coordinate of "1_20" is a
    malformed number, refused with one line."""
    from msk.exceptions import FileFormatError
    from msk.io.opensim_files import read_trc, write_trc

    x = np.random.default_rng(2).uniform(-1, 1, size=(8, 2, 3))
    t = np.arange(8) / 120.0
    good = write_trc(tmp_path / "g.trc", time=t, markers=x, labels=["A", "B"], rate_hz=120.0)
    lines = good.read_text().splitlines()
    vals = lines[2].split("\t")
    vals[0] = "1_20"
    (tmp_path / "h.trc").write_text("\n".join([*lines[:2], "\t".join(vals), *lines[3:]]) + "\n")
    with pytest.raises(FileFormatError, match="1_20"):
        read_trc(tmp_path / "h.trc")
    row = lines[6].split("\t")
    row[2] = "0_5"
    (tmp_path / "r.trc").write_text("\n".join([*lines[:6], "\t".join(row), *lines[7:]]) + "\n")
    with pytest.raises(FileFormatError, match="0_5"):
        read_trc(tmp_path / "r.trc")


def test_filter_messages_say_what_is_wrong():
    """An infinite sample was reported as "NaN samples" (or filtered into NaN silently); a
    time column in ms gets a hint, not a bare Nyquist error."""
    from msk.exceptions import MissingDataError, MskError
    from msk.signal import filtfilt_butter, lowpass_filtfilt_numpy

    x = np.sin(np.linspace(0, 10, 500))
    x[123] = np.inf
    for f in (filtfilt_butter, lowpass_filtfilt_numpy):
        with pytest.raises(MissingDataError, match=r"infinite samples \(first inf at index \(123"):
            f(x, rate_hz=100.0, cutoff_hz=6.0)
    x[123] = np.nan
    with pytest.raises(MissingDataError, match="NaN samples"):
        filtfilt_butter(x, rate_hz=100.0, cutoff_hz=6.0)
    with pytest.raises(MskError, match="milliseconds"):
        filtfilt_butter(np.zeros(50), rate_hz=0.1, cutoff_hz=6.0)
