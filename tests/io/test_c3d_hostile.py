"""msk.io.c3d: a C3D whose parameters have a shape the reader's checks do not foresee is one
C3DError line naming the file, never a traceback."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from msk.exceptions import C3DError
from msk.io.c3d import read_c3d

REPO = Path(__file__).resolve().parents[2]
GC5 = REPO / "data" / "gc5-PS" / "PS_ngait_og_ss1.c3d"


def test_a_3d_force_platform_channel_is_one_line(tmp_path):
    import ezc3d

    c = ezc3d.c3d(str(GC5))
    ch = np.asarray(c["parameters"]["FORCE_PLATFORM"]["CHANNEL"]["value"])
    c["parameters"]["FORCE_PLATFORM"]["CHANNEL"]["value"] = ch.reshape(*ch.shape, 1)
    c.write(str(tmp_path / "ch3d.c3d"))
    with pytest.raises(C3DError, match=r"ch3d\.c3d: FORCE_PLATFORM:CHANNEL has dims \(6, 3, 1\)"):
        read_c3d(tmp_path / "ch3d.c3d", isolate=False)


def test_every_unforeseen_error_of_the_reader_names_the_file():
    from msk.io.c3d import _one_line_errors

    for exc in (TypeError("t"), IndexError("i"), KeyError("k"), OverflowError("o")):

        def reader(path: object, exc: Exception = exc) -> None:
            raise exc

        with pytest.raises(C3DError, match=rf"f\.c3d: .*{type(exc).__name__}"):
            _one_line_errors(reader)("f.c3d")  # type: ignore[arg-type]


@pytest.mark.parametrize("rate", [0.01, 19_999.0])
def test_an_absurd_but_consistent_rate_is_a_reader_warning(tmp_path, rate):
    import ezc3d

    c = ezc3d.c3d(str(GC5))
    per_frame = (
        c["parameters"]["ANALOG"]["RATE"]["value"][0] / c["parameters"]["POINT"]["RATE"]["value"][0]
    )
    c["parameters"]["POINT"]["RATE"]["value"] = [rate]
    c["parameters"]["ANALOG"]["RATE"]["value"] = [rate * per_frame]
    c.write(str(tmp_path / "r.c3d"))
    tr = read_c3d(tmp_path / "r.c3d", isolate=False)
    (note,) = [w for w in tr.metadata["warnings"] if "point rate" in w]
    assert "outside the 1–5000 Hz" in note
    assert not [w for w in read_c3d(GC5, isolate=False).metadata.get("warnings", ()) if "rate" in w]


def test_byte_mutants_are_read_or_refused_with_one_line(tmp_path):
    """200 mutants of a real file (1–3 bytes of its parameter or data section replaced, fixed
    seed): each is read or refused with an MskError, never another exception."""
    from msk.exceptions import MskError
    from tests.support.c3d_mutants import parameters

    src = GC5.read_bytes()
    start, _, _ = parameters(src)
    n_param = src[start + 2] * 512
    rng = np.random.default_rng(38)
    other = []
    for k in range(200):
        d = bytearray(src)
        lo, hi = (start + 4, start + n_param) if k % 2 == 0 else (start + n_param, len(src))
        for _ in range(int(rng.integers(1, 4))):
            d[int(rng.integers(lo, hi))] = int(rng.integers(0, 256))
        f = tmp_path / "m.c3d"
        f.write_bytes(bytes(d))
        try:
            read_c3d(f, isolate=False)
        except MskError:
            pass
        except Exception as exc:  # the family this test guards
            other.append(f"mutant {k}: {type(exc).__name__}: {exc}")
    assert not other, other[:3]
