"""Fuzz suite (issue 18): seeded mutants of real C3D/TRC/MOT files and of a session config.

Every outcome must be either a clean one-line :class:`~msk.exceptions.MskError` or an accepted
result whose values pass the plausibility checks (finite rates > 0, |coordinates| < 100 m,
|plate force| < 20 kN, unique labels without control characters, finite event times, strictly
increasing time) — never a traceback, a native crash or a hang.

The readers run in one persistent child process (a native crash there is reported as a failure of
the case that caused it, and the child is restarted), each case bounded by a timeout. The default
lane holds a few hundred cases; ``-m slow`` runs thousands more.
"""

from __future__ import annotations

import json
import os
import random
import selectors
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from msk.config import TEMPLATE
from msk.datasets.shared import real_data_dir
from tests.support.c3d_mutants import label_width, parameters, retype, set_dim, set_text, set_value

REAL = real_data_dir()
C3D_SOURCES = [
    "knee-grand-challenge-gc5/PS_ngait_og_ss1.c3d",  # float, 3 type-2 plates, EMG
    "btkdata/Gait.c3d",  # DEC floats, repeated labels
    "btkdata/Eb015pi.c3d",  # integer storage
    "ezc3d-testfiles/FP_Type3.c3d",  # Kistler type 3
    "btkdata/1123x01EMG.c3d",  # analogs only
]
TEXT_SOURCES = [
    "opensim-subject01-walk/subject01_walk.trc",
    "opensim-subject01-walk/subject01_walk_grf.mot",
    "opensim-rajagopal-walk/id_walk.sto",
]
CASE_TIMEOUT_S = 60.0

pytestmark = pytest.mark.skipif(not REAL.is_dir(), reason=f"real recordings absent: {REAL}")

# ---------------------------------------------------------------------------------------------
# the child that reads the mutants
# ---------------------------------------------------------------------------------------------
_CHILD = textwrap.dedent(
    r"""
    import json, math, re, sys, traceback
    import numpy as np
    from msk.exceptions import MskError

    CONTROL = re.compile(r"[\x00-\x1f\x7f]")

    def labels_ok(labels, what, bad):
        if len(set(labels)) != len(labels):
            bad.append(f"{what}: repeated labels")
        if any(CONTROL.search(x) for x in labels):
            bad.append(f"{what}: control characters")

    def check_time(t, bad):
        t = np.asarray(t, float)
        if t.size and not np.isfinite(t).all():
            bad.append("time not finite")
        elif t.size > 1 and not (np.diff(t) > 0).all():
            bad.append("time not strictly increasing")

    FINGERPRINT = [None, False]  # the last C3D read: its fingerprint, whether it said anything

    def fingerprint(t):  # what a mutant must read alike or flag: markers, plate forces
        import hashlib
        h = hashlib.sha256()
        h.update(np.nan_to_num(np.asarray(t.markers, float), nan=-7.0).tobytes())
        for p in t.plates:
            h.update(np.nan_to_num(np.asarray(p.force, float), nan=-7.0).tobytes())
        return h.hexdigest()

    def c3d(path):
        from msk.io import read_c3d
        t = read_c3d(path)
        bad = []
        if t.n_frames and not (math.isfinite(t.point_rate_hz) and t.point_rate_hz > 0):
            bad.append(f"point rate {t.point_rate_hz}")
        if t.analogs.shape[1] and not (math.isfinite(t.analog_rate_hz) and t.analog_rate_hz > 0):
            bad.append(f"analog rate {t.analog_rate_hz}")
        m = t.markers
        if np.isinf(m).any() or (np.abs(m[np.isfinite(m)]) >= 100).any():
            bad.append("marker coordinate beyond 100 m")
        for p in t.plates:
            f = p.force
            if np.isinf(f).any() or (np.abs(f[np.isfinite(f)]) >= 20000).any():
                bad.append(f"plate {p.index + 1} force beyond 20 kN")
        labels_ok(t.marker_labels, "markers", bad)
        FINGERPRINT[0] = fingerprint(t)
        FINGERPRINT[1] = bool(t.metadata.get("warnings"))
        if any(not math.isfinite(e.time) for e in t.events):
            bad.append("event time not finite")
        check_time(t.time, bad)
        return bad

    def trc(path):
        from msk.io.opensim_files import read_trc
        t = read_trc(path)
        bad = []
        if not (math.isfinite(t.rate_hz) and t.rate_hz > 0):
            bad.append(f"rate {t.rate_hz}")
        m = t.markers
        if np.isinf(m).any() or (np.abs(m[np.isfinite(m)]) >= 100).any():
            bad.append("marker coordinate beyond 100 m")
        check_time(t.time, bad)
        return bad

    def sto(path):
        from msk.io.opensim_files import read_sto
        t = read_sto(path)
        bad = []
        check_time(t.time, bad)
        if t.time.size > 1 and not (math.isfinite(t.rate_hz) and t.rate_hz > 0):
            bad.append(f"rate {t.rate_hz}")
        return bad

    def config(path):
        from msk.config import load_config
        c = load_config(path)
        bad = []
        nums = {
            "mass_kg": (c.subject.mass_kg, 20, 300),
            "kinematics_cutoff_hz": (c.filters.kinematics_cutoff_hz, 0.01, 500),
            "grf_cutoff_hz": (c.filters.grf_cutoff_hz or 6.0, 0.01, 500),
            "highpass_hz": (c.emg.highpass_hz, 1e-12, 500),
            "lowpass_hz": (c.emg.lowpass_hz, 1e-12, 500),
            "electromechanical_delay_s": (c.emg.electromechanical_delay_s, 0, 0.2),
        }
        for k, (v, lo, hi) in nums.items():
            if not (math.isfinite(v) and lo <= v <= hi):
                bad.append(f"{k} = {v}")
        if c.subject.height_m is not None and not 0.5 <= c.subject.height_m <= 2.5:
            bad.append(f"height_m = {c.subject.height_m}")
        for k, w in c.marker_weights.items():
            if not (math.isfinite(w) and w >= 0):
                bad.append(f"weight {k} = {w}")
        for tc in c.trials:
            if not tc.file.is_file():
                bad.append(f"trial file {tc.file} is not a regular file")
        return bad

    READERS = {"c3d": c3d, "trc": trc, "sto": sto, "config": config}
    for line in sys.stdin:
        kind, path = json.loads(line)
        try:
            FINGERPRINT[:] = [None, False]
            bad = READERS[kind](path)
            out = {"outcome": "accepted", "violations": bad, "fingerprint": FINGERPRINT[0],
                   "said": FINGERPRINT[1]}
        except MskError as exc:
            out = {"outcome": "error", "type": type(exc).__name__, "message": str(exc)}
        except BaseException as exc:
            out = {"outcome": "traceback", "message": "".join(traceback.format_exception(exc))}
        sys.stdout.write(json.dumps(out) + "\n")
        sys.stdout.flush()
    """
)


class Reader:
    """A persistent child process reading one mutant per request, with a timeout per case."""

    def __init__(self) -> None:
        self.proc: subprocess.Popen[str] | None = None

    def _start(self) -> subprocess.Popen[str]:
        env = {**os.environ, "PYTHONIOENCODING": "utf-8", "MSK_ISOLATE_C3D": "0"}
        return subprocess.Popen(
            [sys.executable, "-c", _CHILD],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
            env=env,
        )

    def read(self, kind: str, path: Path, timeout: float = CASE_TIMEOUT_S) -> dict:
        if self.proc is None or self.proc.poll() is not None:
            self.proc = self._start()
        proc = self.proc
        assert proc.stdin is not None and proc.stdout is not None
        proc.stdin.write(json.dumps([kind, str(path)]) + "\n")
        proc.stdin.flush()
        sel = selectors.DefaultSelector()
        sel.register(proc.stdout, selectors.EVENT_READ)
        ready = sel.select(timeout)
        sel.close()
        if not ready:
            self.close()
            return {"outcome": "hang", "message": f"no answer in {timeout:g} s"}
        line = proc.stdout.readline()
        if not line:
            code = proc.wait(10)
            self.proc = None
            return {"outcome": "crash", "message": f"reader died with status {code}"}
        return json.loads(line)

    def close(self) -> None:
        if self.proc is not None:
            self.proc.kill()
            self.proc.wait(10)
            self.proc = None


@pytest.fixture(scope="module")
def reader():
    r = Reader()
    yield r
    r.close()


#: parameter mutations the reader must read as the original or say (a reader warning/flag):
#: the frame count, the plates' declaration and channels
_SAID_OR_SAME = ("value:POINT:FRAMES", "value:FORCE_PLATFORM:USED", "value:FORCE_PLATFORM:CHANNEL")


def _judge(kind: str, name: str, out: dict, original: str | None = None) -> str | None:
    """None when the outcome is acceptable, else what went wrong."""
    o = out["outcome"]
    if o == "accepted":
        if out["violations"]:
            return f"{name}: accepted with {out['violations']}"
        silent = original is not None and out.get("fingerprint") != original and not out["said"]
        if silent and any(f" {k}=" in name for k in _SAID_OR_SAME):
            return f"{name}: read with other numbers than the original and nothing said"
        return None
    if o == "error":
        msg = out["message"]
        if "\n" in msg or not msg.strip():
            return f"{name}: {out['type']} is not one line: {msg!r}"
        return None
    return f"{name}: {o}: {out['message'][-1500:]}"


def _run_cases(
    reader: Reader, kind: str, cases, tmp_path: Path, original: str | None = None
) -> dict[str, int]:
    """Write every (name, bytes) mutant, read it, collect failures; returns outcome counts.
    ``original``: the source's fingerprint (markers and plate forces) a C3D mutant of the
    :data:`_SAID_OR_SAME` families must keep unless its reader says something."""
    failures: list[str] = []
    counts = {"accepted": 0, "error": 0}
    suffix = {"c3d": ".c3d", "trc": ".trc", "sto": ".mot", "config": ".toml"}[kind]
    for k, (name, data) in enumerate(cases):
        f = tmp_path / f"m{k}{suffix}"
        if isinstance(data, bytes | bytearray):
            f.write_bytes(bytes(data))
        else:
            f = data  # a path (special files)
        out = reader.read(kind, f)
        counts[out["outcome"]] = counts.get(out["outcome"], 0) + 1
        if (why := _judge(kind, name, out, original)) is not None:
            failures.append(why)
    assert not failures, f"{len(failures)} bad outcomes:\n" + "\n".join(failures[:10])
    return counts


# ---------------------------------------------------------------------------------------------
# mutants
# ---------------------------------------------------------------------------------------------
_NUMERIC = [
    ("POINT", "RATE"),
    ("POINT", "USED"),
    ("POINT", "SCALE"),
    ("POINT", "DATA_START"),
    ("POINT", "FRAMES"),
    ("ANALOG", "RATE"),
    ("ANALOG", "USED"),
    ("ANALOG", "GEN_SCALE"),
    ("ANALOG", "SCALE"),
    ("ANALOG", "OFFSET"),
    ("FORCE_PLATFORM", "USED"),
    ("FORCE_PLATFORM", "TYPE"),
    ("FORCE_PLATFORM", "CORNERS"),
    ("FORCE_PLATFORM", "ORIGIN"),
    ("FORCE_PLATFORM", "CHANNEL"),
    ("EVENT", "TIMES"),
    ("EVENT", "USED"),
]
_TEXT = [("POINT", "LABELS"), ("POINT", "UNITS"), ("ANALOG", "LABELS"), ("ANALOG", "UNITS")]
_VALUES = [0, -1, 1, 2, 5, 99, 255, 32767, -32768, 0.5, 1e-9, 1e9, 1e30, -1e30]
_FLOATS = [float("nan"), float("inf"), -float("inf"), 119.88, 1000.0, 1200.5, 0.999, 1.001]


def _flip(data: bytearray, rng: random.Random, lo: int, hi: int, n: int) -> None:
    for _ in range(n):
        i = rng.randrange(lo, min(hi, len(data)))
        data[i] ^= 1 << rng.randrange(8)


def c3d_mutant(src: bytes, rng: random.Random) -> tuple[str, bytearray]:
    """One seeded mutant of a C3D file (kind chosen at random)."""
    d = bytearray(src)
    start, _, params = parameters(src)
    pend = start + src[start + 2] * 512
    kind = rng.choice(
        ["header", "params", "anywhere", "truncate", "retype", "value", "dims", "label"]
    )
    try:
        if kind == "header":
            _flip(d, rng, 0, 512, rng.randint(1, 3))
        elif kind == "params":
            _flip(d, rng, start, pend, rng.randint(1, 4))
        elif kind == "anywhere":
            _flip(d, rng, 0, len(d), rng.randint(1, 16))
        elif kind == "truncate":
            d = d[: rng.randrange(0, len(d))]
        elif kind == "retype":
            if rng.random() < 0.7:
                key = rng.choice([k for k in _NUMERIC if k in params] or _TEXT)
                retype(d, key, rng.choice([-1, 1, 2, 4]))
            else:
                key = rng.choice([k for k in _TEXT if k in params])
                retype(d, key, rng.choice([1, 2, 4]))
            kind += ":" + ":".join(key)
        elif kind == "value":
            key = rng.choice([k for k in _NUMERIC if k in params and params[k].type != -1])
            p = params[key]
            n = max(1, len(p.data) // abs(p.type))
            v = rng.choice(_VALUES + (_FLOATS if p.type == 4 else []))
            set_value(d, key, v, rng.randrange(n))
            kind += f":{':'.join(key)}={v}"
        elif kind == "dims":
            key = rng.choice([k for k in params if params[k].dims])
            set_dim(d, key, rng.randrange(len(params[key].dims)), rng.randrange(0, 9))
            kind += ":" + ":".join(key)
        else:
            key = ("POINT", "LABELS") if ("POINT", "LABELS") in params else ("ANALOG", "LABELS")
            w = label_width(src, key)
            n = len(params[key].data) // w
            i, j = rng.randrange(n), rng.randrange(n)
            what = rng.choice(["duplicate", "control", "latin1", "blank"])
            if what == "duplicate":
                set_text(d, key, j * w, params[key].data[i * w : (i + 1) * w])
            elif what == "control":
                set_text(d, key, i * w + rng.randrange(w), bytes([rng.randrange(32)]))
            elif what == "latin1":
                set_text(d, key, i * w, bytes([rng.randrange(128, 256)]))
            else:
                set_text(d, key, i * w, b" " * w)
            kind += f":{what}"
    except (KeyError, IndexError, ValueError):
        _flip(d, rng, start, pend, 1)
        kind += ":fallback-flip"
    return kind, d


def _shorten(text: str, rows: int) -> str:
    """The header and the first ``rows`` data rows, with the row count of the header fixed."""
    lines = text.splitlines()
    if lines[0].startswith("PathFileType"):
        vals = lines[2].split("\t")
        keys = lines[1].split("\t")
        for name in ("NumFrames", "OrigNumFrames"):
            if name in keys:
                vals[keys.index(name)] = str(rows)
        lines[2] = "\t".join(vals)
        data = [ln for ln in lines[5:] if ln.strip()][:rows]
        return "\n".join(lines[:5] + data) + "\n"
    end = next(i for i, ln in enumerate(lines) if ln.strip().lower() == "endheader")
    head = [
        f"nRows={rows}"
        if ln.startswith("nRows=")
        else (f"datarows {rows}" if ln.startswith("datarows") else ln)
        for ln in lines[: end + 2]
    ]
    return "\n".join(head + lines[end + 2 : end + 2 + rows]) + "\n"


def text_mutant(src: str, rng: random.Random) -> tuple[str, bytes]:
    lines = src.splitlines()
    kind = rng.choice(["flip", "truncate", "header", "time", "cell", "rate"])
    head_n = (
        5
        if lines[0].startswith("PathFileType")
        else 1 + next(i for i, ln in enumerate(lines) if ln.strip().lower() == "endheader")
    )
    if kind == "flip":
        b = bytearray(src.encode())
        _flip(b, rng, 0, len(b), rng.randint(1, 8))
        return kind, bytes(b)
    if kind == "truncate":
        b = src.encode()
        return kind, b[: rng.randrange(len(b))]
    if kind == "header":
        i = rng.randrange(head_n)
        lines[i] = rng.choice(["", "nRows=0", "nRows=-3", "inDegrees=maybe", "\x00", "x" * 50])
    elif kind in ("time", "cell"):
        i = rng.randrange(head_n + 1, len(lines))
        parts = lines[i].split("\t")
        col = (1 if lines[0].startswith("PathFileType") else 0) if kind == "time" else None
        j = col if col is not None else rng.randrange(len(parts))
        new = rng.choice(["nan", "inf", "-inf", "1e300", "-0", "0", "x", "", "1e-300", "7"])
        if kind == "time" and rng.random() < 0.5 and i > head_n + 1:
            new = lines[i - 1].split("\t")[j]  # repeated time
        parts[j] = new
        lines[i] = "\t".join(parts)
        kind += f"={new}"
    else:  # rate (TRC DataRate) or a header value
        if lines[0].startswith("PathFileType"):
            vals = lines[2].split("\t")
            vals[0] = rng.choice(["0", "-100", "nan", "inf", "1e9", "abc"])
            lines[2] = "\t".join(vals)
            kind += f"={vals[0]}"
        else:
            lines.insert(1, rng.choice(["DataRate=0", "nColumns=-1", "version=abc"]))
    return kind, ("\n".join(lines) + "\n").encode()


_CONFIG_EDITS = [
    ("mass_kg = 75.0", ["mass_kg = 10.0", "mass_kg = nan", "mass_kg = -75", "mass_kg = 1e300",
                        'mass_kg = "75"', "mass_kg = 40.0", "mass_kg = inf"]),
    ("height_m = 1.70", ["height_m = 1700", "height_m = 0", "height_m = nan", "height_m = true"]),
    ("kinematics_cutoff_hz = 6.0", ["kinematics_cutoff_hz = 0", "kinematics_cutoff_hz = 1e-9",
                                    "kinematics_cutoff_hz = nan", "kinematics_cutoff_hz = -6",
                                    "kinematics_cutoff_hz = 6000", "kinematics_cutoff_hz = []"]),
    ("grf_cutoff_hz = 6.0", ["grf_cutoff_hz = inf", "grf_cutoff_hz = 0.0"]),
    ("electromechanical_delay_s = 0.04", ["electromechanical_delay_s = 40",
                                          "electromechanical_delay_s = -0.01",
                                          "electromechanical_delay_s = nan"]),
    ("highpass_hz = 20.0", ["highpass_hz = 0", "highpass_hz = 1e6"]),
    ("lowpass_hz = 6.0", ["lowpass_hz = -1", "lowpass_hz = nan"]),
    ("weights = {}", ['weights = { RASI = "high" }', "weights = { RASI = nan }",
                      "weights = { RASI = -2.0 }", "weights = { RASI = true }",
                      "weights = { RASI = [1] }", "weights = { RASI = 1e400 }"]),
    ("rename = {}", ["rename = { RASI = 1 }", 'rename = { RASI = "" }']),
    ('solver = "daqp"', ['solver = "dapq"', "solver = 3"]),
    ("w_emg = 0.1", ["w_emg = nan", "w_emg = -1"]),
    ('vas_med_l = "vasmed"', ["vas_med_l = 2", 'vas_med_l = ""']),
    ("activation_exponent = 2.0", ["activation_exponent = nan"]),
]  # fmt: skip


@pytest.fixture(scope="module")
def session_tree(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("lab")
    (root / "pipelines").mkdir()
    (root / "models").mkdir()
    (root / "data" / "gc5-PS").mkdir(parents=True)
    for rel in [
        "models/gait2392.toml",
        "data/gc5-PS/PS_static_for_scaling.trc",
        "data/gc5-PS/PS_ngait_og_ss1.c3d",
        "data/gc5-PS/PS_ngait_og_ss1_eTibia.csv",
    ]:
        (root / rel).write_text("")
    os.mkfifo(root / "data" / "pipe.c3d")
    return root


def config_mutant(rng: random.Random, root: Path) -> tuple[str, bytes]:
    text = TEMPLATE
    kind = rng.choice(["edit", "edit", "edit", "flip", "truncate", "special", "latin1"])
    if kind == "edit":
        for _ in range(rng.randint(1, 2)):
            old, news = rng.choice(_CONFIG_EDITS)
            text = text.replace(old, rng.choice(news), 1)
        return kind, text.encode()
    b = bytearray(text.encode())
    if kind == "flip":
        _flip(b, rng, 0, len(b), rng.randint(1, 6))
    elif kind == "truncate":
        b = b[: rng.randrange(len(b))]
    elif kind == "latin1":
        b = b.replace(b'"PS"', b'"M\xfcller"')
    else:
        target = rng.choice([str(root / "data" / "pipe.c3d"), "/dev/zero", str(root / "data")])
        b = bytearray(text.replace("../data/gc5-PS/PS_ngait_og_ss1.c3d", target).encode())
        kind += f":{target}"
    return kind, bytes(b)


# ---------------------------------------------------------------------------------------------
# the lanes
# ---------------------------------------------------------------------------------------------
def _c3d_cases(name: str, n: int, seed: int):
    src = (REAL / name).read_bytes()
    rng = random.Random(f"{seed}:{name}")
    for k in range(n):
        kind, d = c3d_mutant(src, rng)
        yield f"{name}#{k} {kind}", d


def _text_cases(name: str, n: int, seed: int, rows: int = 60):
    src = _shorten((REAL / name).read_text(encoding="utf-8"), rows)
    rng = random.Random(f"{seed}:{name}")
    for k in range(n):
        kind, d = text_mutant(src, rng)
        yield f"{name}#{k} {kind}", d


def _config_cases(root: Path, n: int, seed: int):
    rng = random.Random(f"{seed}:config")
    for k in range(n):
        kind, d = config_mutant(rng, root)
        yield f"config#{k} {kind}", d


def _original(reader: Reader, tmp_path: Path, name: str) -> str:
    f = tmp_path / "original.c3d"
    f.write_bytes((REAL / name).read_bytes())
    out = reader.read("c3d", f)
    assert out["outcome"] == "accepted", out
    return out["fingerprint"]


@pytest.mark.parametrize("name", C3D_SOURCES)
def test_c3d_mutants(reader, tmp_path, name):
    orig = _original(reader, tmp_path, name)
    counts = _run_cases(reader, "c3d", _c3d_cases(name, 50, seed=18), tmp_path, orig)
    assert counts["error"] > 0


def _declared_count_cases(name: str, n: int, seed: int):
    """Mutants of the :data:`_SAID_OR_SAME` families only: POINT:FRAMES, FORCE_PLATFORM:USED
    or one FORCE_PLATFORM:CHANNEL entry set to another count."""
    src = (REAL / name).read_bytes()
    _, _, params = parameters(src)
    family = (("POINT", "FRAMES"), ("FORCE_PLATFORM", "USED"), ("FORCE_PLATFORM", "CHANNEL"))
    keys = [k for k in family if k in params and params[k].type != -1]
    rng = random.Random(f"{seed}:{name}:declared")
    for k in range(n if keys else 0):
        d = bytearray(src)
        key = rng.choice(keys)
        p = params[key]
        v = rng.choice([0, 1, 2, 3, 4, 7, 99, 145, 500, 32767, -1])
        set_value(d, key, v, rng.randrange(max(1, len(p.data) // abs(p.type))))
        yield f"{name}#{k} value:{':'.join(key)}={v}", d


@pytest.mark.parametrize("name", C3D_SOURCES)
def test_declared_counts_are_read_alike_or_said(reader, tmp_path, name):
    """A frame count or a plate declaration changed in the parameters: the mutant is refused
    with one line, or read with the original's markers and plate forces, or the reader says
    what it did (issue: declared-but-missing plates, frame counts)."""
    orig = _original(reader, tmp_path, name)
    _run_cases(reader, "c3d", _declared_count_cases(name, 30, seed=38), tmp_path, orig)


@pytest.mark.parametrize("name", TEXT_SOURCES)
def test_text_mutants(reader, tmp_path, name):
    kind = "trc" if name.endswith(".trc") else "sto"
    _run_cases(reader, kind, _text_cases(name, 30, seed=18), tmp_path)


def test_config_mutants(reader, tmp_path, session_tree):
    tmp = session_tree / "pipelines"
    counts = _run_cases(reader, "config", _config_cases(session_tree, 60, seed=18), tmp)
    assert counts["error"] > 0 and counts["accepted"] > 0


def test_special_files_everywhere(reader, tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    for kind in ("c3d", "trc", "sto", "config"):
        for p in (fifo, Path("/dev/zero"), tmp_path):
            out = reader.read(kind, p, timeout=20)
            assert out["outcome"] == "error", (kind, p, out)
            assert "not a regular" in out["message"] or "not a configuration" in out["message"]


def test_the_unmutated_sources_are_accepted(reader, tmp_path):
    cases = [(n, (REAL / n).read_bytes()) for n in C3D_SOURCES]
    assert _run_cases(reader, "c3d", cases, tmp_path) == {"accepted": len(cases), "error": 0}
    for n in TEXT_SOURCES:
        kind = "trc" if n.endswith(".trc") else "sto"
        case = [(n, _shorten((REAL / n).read_text(encoding="utf-8"), 60).encode())]
        assert _run_cases(reader, kind, case, tmp_path) == {"accepted": 1, "error": 0}


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("name", C3D_SOURCES)
def test_c3d_mutants_slow(reader, tmp_path, name, seed):
    orig = _original(reader, tmp_path, name)
    _run_cases(reader, "c3d", _c3d_cases(name, 300, seed=seed), tmp_path, orig)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.parametrize("name", TEXT_SOURCES)
def test_text_mutants_slow(reader, tmp_path, name, seed):
    kind = "trc" if name.endswith(".trc") else "sto"
    _run_cases(reader, kind, _text_cases(name, 200, seed=seed), tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2])
def test_config_mutants_slow(reader, session_tree, seed):
    _run_cases(reader, "config", _config_cases(session_tree, 300, seed), session_tree / "pipelines")


# ---------------------------------------------------------------------------------------------
# the command line: one line on stderr, exit 2
# ---------------------------------------------------------------------------------------------
def _msk(*args: str, ascii_out: bool = False) -> subprocess.CompletedProcess[str]:
    env = {**os.environ}
    if ascii_out:
        env["PYTHONIOENCODING"] = "ascii"
    return subprocess.run(
        [sys.executable, "-c", "import sys; from msk.cli import main; sys.exit(main())", *args],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
        encoding="utf-8",
        errors="replace",
    )


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["batch", "a.toml", "--out", "o", "--workers", "-1"], "--workers: -1 should be"),
        (["batch", "a.toml", "--out", "o", "--workers", "two"], "'two' is not an integer"),
        (["batch", "a.toml", "--out", "o", "--scheduler", "tcp//host"], "not a Dask scheduler"),
        (["info"], "required: FILE"),
    ],
)
def test_cli_usage_errors_are_one_line(tmp_path, args, message):
    os.chdir(tmp_path)
    r = _msk(*args)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.startswith("msk: error: ") and message in r.stderr


def test_cli_info_on_a_strict_ascii_stdout(tmp_path):
    trc = _shorten((REAL / TEXT_SOURCES[0]).read_text(encoding="utf-8"), 5)
    lines = trc.splitlines()
    lines[3] = lines[3].replace("R.ASIS", "R.ASIS\u00e9", 1)
    f = tmp_path / "accent.trc"
    f.write_text("\n".join(lines) + "\n", encoding="utf-8")
    r = _msk("info", str(f), ascii_out=True)
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    assert "R.ASIS\\xe9" in r.stdout


# --- the named examples that the mutant lanes reach only by chance (issue 18) --------


def _trc_text(tmp_path: Path) -> str:
    import numpy as np

    from msk.io.opensim_files import write_trc

    t = np.arange(5) / 100.0
    x = np.zeros((5, 2, 3)) + np.array([0.1, 0.9, 0.2])
    return write_trc(
        tmp_path / "g.trc", time=t, markers=x, labels=["A", "B"], rate_hz=100.0
    ).read_text()


@pytest.mark.parametrize("rate", ["0", "-100"])
def test_trc_rate_zero_or_negative_is_refused(tmp_path, rate):
    from msk.exceptions import MskError
    from msk.io.opensim_files import read_trc

    lines = _trc_text(tmp_path).splitlines()
    vals = lines[2].split("\t")
    vals[0] = rate
    lines[2] = "\t".join(vals)
    (tmp_path / "r.trc").write_text("\n".join(lines) + "\n")
    with pytest.raises(MskError, match="DataRate"):
        read_trc(tmp_path / "r.trc")


@pytest.mark.parametrize("times", [(0.0, 0.02, 0.01), (0.0, 0.01, 0.01)], ids=["unsorted", "dup"])
def test_trc_and_mot_with_unsorted_or_duplicated_time_are_refused(tmp_path, times):
    import numpy as np

    from msk.exceptions import MskError
    from msk.io.opensim_files import read_sto, read_trc

    lines = _trc_text(tmp_path).splitlines()
    for k, t in enumerate(times):  # data rows start after the 5 header lines (+ blank)
        row = next(i for i, ln in enumerate(lines) if ln.startswith(f"{k + 1}\t"))
        vals = lines[row].split("\t")
        vals[1] = repr(t)
        lines[row] = "\t".join(vals)
    (tmp_path / "t.trc").write_text("\n".join(lines) + "\n")
    with pytest.raises(MskError, match="time"):
        read_trc(tmp_path / "t.trc")
    mot = tmp_path / "g.mot"
    rows = "\n".join(f"{t!r}\t{v:g}" for t, v in zip(times, np.arange(3.0)))
    mot.write_text(
        f"g\nversion=1\nnRows=3\nnColumns=2\ninDegrees=no\nendheader\ntime\tground_force_vy\n{rows}\n"
    )
    with pytest.raises(MskError, match="time"):
        read_sto(mot)


def test_trc_absurd_coordinate_is_refused(tmp_path):
    from msk.exceptions import MskError
    from msk.io.opensim_files import read_trc

    lines = _trc_text(tmp_path).splitlines()
    row = next(i for i, ln in enumerate(lines) if ln.startswith("3\t"))
    vals = lines[row].split("\t")
    vals[2] = "1e9"  # mm: 1000 km
    lines[row] = "\t".join(vals)
    (tmp_path / "a.trc").write_text("\n".join(lines) + "\n")
    with pytest.raises(MskError, match="beyond"):
        read_trc(tmp_path / "a.trc")


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (('rename = { "R.ASIS"', 'rename = { "R.ASIS" = "NoSuchMarker", "X.ASIS"'), "no marker"),
        (("weights = {}", "weights = { NoSuchMarker = 2.0 }"), "NoSuchMarker"),
    ],
    ids=["rename", "weights"],
)
def test_unknown_marker_names_in_rename_or_weights_exit_2(tmp_path, edit, match):
    repo = Path(__file__).resolve().parents[1]
    text = (repo / "pipelines" / "gc5_PS.toml").read_text(encoding="utf-8")
    text = text.replace('"../', f'"{repo}/')
    assert edit[0] in text
    cfg = tmp_path / "c.toml"
    cfg.write_text(text.replace(edit[0], edit[1], 1), encoding="utf-8")
    p = subprocess.run(
        [sys.executable, "-c", "import sys; from msk.cli import main; sys.exit(main())",
         "run", str(cfg), "--out", str(tmp_path / "o"), "--quiet"],
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert p.returncode == 2, p.stderr[-2000:]
    assert match in p.stderr and "Traceback" not in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1
