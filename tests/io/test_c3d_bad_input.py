"""Broken C3D files raise a typed MskError naming the file and the problem (never a crash)."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import ezc3d
import numpy as np
import pytest

from msk.exceptions import C3DError, ForcePlateError, MskError, UnitsError
from msk.io import read_c3d
from msk.io.c3d import _set_param


def _edit(src: Path, dst: Path, edit) -> Path:
    """Re-write ``src`` through ezc3d after ``edit(c)`` changed its parameters."""
    c = ezc3d.c3d(str(src))
    edit(c)
    c.write(str(dst))
    return dst


def test_missing_empty_and_directory(tmp_path):
    with pytest.raises(C3DError, match="no such file"):
        read_c3d(tmp_path / "nope.c3d")
    (tmp_path / "empty.c3d").write_bytes(b"")
    with pytest.raises(C3DError, match=r"empty\.c3d: empty file"):
        read_c3d(tmp_path / "empty.c3d")
    with pytest.raises(C3DError, match="directory"):
        read_c3d(tmp_path)
    (tmp_path / "short.c3d").write_bytes(b"\x02\x50" + b"\0" * 100)
    with pytest.raises(C3DError, match="too short"):
        read_c3d(tmp_path / "short.c3d")


def test_not_a_c3d(tmp_path):
    p = tmp_path / "notes.c3d"
    p.write_text("time,x\n" * 400)
    with pytest.raises(C3DError, match=r"notes\.c3d: not a C3D file \(byte 2 is 0x69"):
        read_c3d(p)


def test_bad_key_byte(synth, tmp_path):
    path, _ = synth()
    raw = bytearray(path.read_bytes())
    raw[1] = 0x51
    bad = tmp_path / "key.c3d"
    bad.write_bytes(bytes(raw))
    with pytest.raises(C3DError, match="byte 2 is 0x51"):
        read_c3d(bad)


@pytest.mark.parametrize("keep", [0.95, 0.6, 0.2])
def test_truncated(synth, tmp_path, keep):
    path, _ = synth()
    raw = path.read_bytes()
    bad = tmp_path / "cut.c3d"
    bad.write_bytes(raw[: int(len(raw) * keep)])
    with pytest.raises(C3DError, match=r"cut\.c3d: truncated"):
        read_c3d(bad)


def test_corrupt_parameter_section(synth, tmp_path):
    path, _ = synth()
    raw = bytearray(path.read_bytes())
    start = (raw[0] - 1) * 512
    raw[start + 4 : start + 200] = b"\xff" * 196
    bad = tmp_path / "params.c3d"
    bad.write_bytes(bytes(raw))
    with pytest.raises(C3DError, match=r"params\.c3d: corrupt parameter"):
        read_c3d(bad)
    raw[start + 3] = 99  # processor type
    bad.write_bytes(bytes(raw))
    with pytest.raises(C3DError, match="processor type"):
        read_c3d(bad)


def test_unknown_units(synth, tmp_path):
    path, _ = synth()
    bad = _edit(path, tmp_path / "units.c3d", lambda c: _set_param(c, "POINT", "UNITS", "in"))
    with pytest.raises(UnitsError, match=r"units\.c3d: POINT:UNITS 'in'"):
        read_c3d(bad)


def test_plate_with_channels_beyond_the_analogs(synth, tmp_path):
    path, _ = synth()

    def edit(c):
        _set_param(c, "FORCE_PLATFORM", "CHANNEL", np.array([[1], [2], [3], [4], [5], [99]]))

    bad = _edit(path, tmp_path / "chan.c3d", edit)
    tr = read_c3d(bad)  # the plate is dropped, said by a typed flag naming plate and channel
    assert tr.plates == ()
    (flag,) = [f for f in tr.metadata["flags"] if f["quantity"] == "c3d_plate_channel_missing"]
    assert flag["value"] == 99 and "force platform 1" in flag["message"]
    assert flag["message"] in tr.metadata["warnings"]


def test_unsupported_plate_type(synth, tmp_path):
    path, _ = synth()
    bad = _edit(
        path,
        tmp_path / "type.c3d",
        lambda c: _set_param(c, "FORCE_PLATFORM", "TYPE", np.array([7])),
    )
    with pytest.raises(ForcePlateError, match="type 7"):
        read_c3d(bad)


def test_no_points_no_analogs(tmp_path):
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    del c["data"]["rotations"]
    c.write(str(tmp_path / "void.c3d"))
    with pytest.raises(C3DError, match=r"void\.c3d: no point and no analog data"):
        read_c3d(tmp_path / "void.c3d")


def test_analog_only_file_is_valid(tmp_path):
    from msk.io import write_c3d

    p = write_c3d(
        tmp_path / "emg.c3d",
        markers=np.zeros((20, 0, 3)),
        marker_labels=[],
        rate_hz=100.0,
        analogs=np.random.default_rng(1).normal(size=(20, 2)),
        analog_labels=["EMG1", "EMG2"],
    )
    tr = read_c3d(p)
    assert tr.markers.shape[1] == 0 and tr.analogs.shape == (20, 2)


def test_random_corruption_never_crashes(synth, tmp_path):
    """Random byte damage in header/parameters: a C3DError or a clean read, never a signal."""
    path, _ = synth()
    raw = path.read_bytes()
    rng = np.random.default_rng(7)
    files = []
    for k in range(40):
        b = bytearray(raw)
        start = (b[0] - 1) * 512
        for pos in rng.integers(2, start + 1536, size=int(rng.integers(1, 12))):
            if pos not in (1,):
                b[pos] = int(rng.integers(0, 256))
        f = tmp_path / f"fuzz{k}.c3d"
        f.write_bytes(bytes(b))
        files.append(str(f))
    code = textwrap.dedent(
        """
        import json, sys
        from msk.io import read_c3d
        from msk.exceptions import MskError
        out = []
        for f in json.loads(sys.argv[1]):
            try:
                read_c3d(f)
                out.append("ok")
            except MskError as e:
                out.append("msk:" + type(e).__name__)
        print(json.dumps(out))
        """
    )
    proc = subprocess.run(
        [sys.executable, "-c", code, json.dumps(files)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    res = json.loads(proc.stdout.strip().splitlines()[-1])
    assert len(res) == len(files)
    assert all(r == "ok" or r.startswith("msk:") for r in res)
    assert any(r.startswith("msk:") for r in res)


def test_every_error_is_an_msk_error():
    assert issubclass(C3DError, MskError) and issubclass(UnitsError, MskError)
    assert issubclass(ForcePlateError, MskError)


def test_two_plates_sharing_a_channel(synth, tmp_path):
    path, _ = synth()

    def edit(c):
        c["parameters"]["FORCE_PLATFORM"]["USED"]["value"] = np.array([2])
        _set_param(c, "FORCE_PLATFORM", "TYPE", np.array([2, 2]))
        corners = np.repeat(c["parameters"]["FORCE_PLATFORM"]["CORNERS"]["value"], 2, axis=2)
        _set_param(c, "FORCE_PLATFORM", "CORNERS", corners)
        _set_param(c, "FORCE_PLATFORM", "ORIGIN", np.zeros((3, 2)))
        _set_param(
            c, "FORCE_PLATFORM", "CHANNEL", np.array([[1, 2, 3, 4, 5, 6], [6, 7, 8, 1, 2, 3]]).T
        )

    bad = _edit(path, tmp_path / "shared.c3d", edit)
    with pytest.raises(
        ForcePlateError, match=r"shared\.c3d: analog channel 6 \('Mz1'\) is used by .* 1 and 2"
    ):
        read_c3d(bad)


def test_negative_cop_threshold(synth):
    path, _ = synth()
    with pytest.raises(MskError, match="cop_threshold_n"):
        read_c3d(path, cop_threshold_n=-1.0)


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.parametrize(
    "name", ["btkdata/FunctionalStatic.c3d", "btkdata/Eb015pi.c3d", "btkdata/Gait.c3d"]
)
def test_truncated_real_files_dec_and_integer(real_dir, tmp_path, name):
    """DEC-float, PC-integer and DEC-integer files: one missing KB is detected."""
    raw = (real_dir / name).read_bytes()
    bad = tmp_path / "cut.c3d"
    bad.write_bytes(raw[:-1024])
    with pytest.raises(C3DError, match=r"cut\.c3d: truncated: the header promises"):
        read_c3d(bad)
