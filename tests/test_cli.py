"""The msk command: --version, info on C3D and OpenSim files, one-line errors with status 2."""

from __future__ import annotations

import argparse
import subprocess
import sys

import numpy as np
import pytest

from msk import __version__
from msk.cli import Command, build_parser, main
from msk.cli.info import flat_channels
from msk.exceptions import UnitsError
from msk.io import write_c3d
from msk.io.opensim_files import Table, write_sto, write_trc


@pytest.fixture
def small_c3d(tmp_path):
    rng = np.random.default_rng(0)
    t = np.arange(30)[:, None, None] / 100.0  # smooth paths (white noise is a teleport)
    x = rng.uniform(size=(1, 3, 3)) + 0.1 * np.sin(2 * np.pi * t + rng.uniform(0, 6, (1, 3, 3)))
    x[3:7, 2] = np.nan
    a = np.column_stack(
        [
            rng.normal(0, 1e-4, 300),
            np.zeros(300),
            rng.normal(0, 2e-4, 300),
            rng.normal(0, 1e-4, 300),
        ]
    )
    return write_c3d(
        tmp_path / "small.c3d",
        markers=x,
        marker_labels=["A", "B", "C"],
        rate_hz=100.0,
        point_units="mm",
        analogs=a,
        analog_labels=["EMG1", "EMG2", "EMG3", "EMG4"],
        analog_units=["V"] * 4,
        analog_ratio=10,
    )


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"msk {__version__}"


def test_info_c3d(small_c3d, capsys):
    assert main(["info", str(small_c3d)]) == 0
    out = capsys.readouterr().out
    assert "points: 100 Hz, 30 frames, 0.300 s" in out
    assert "markers: 3 (1 with gaps)" in out
    assert "gap C: 4 missing frames, longest 4" in out
    assert "analogs: 4 channels at 1000 Hz (0 force-plate, 4 other)" in out
    assert "EMG2 [V]  FLAT/UNUSED? (all zero)" in out
    assert "EMG1 [V]\n" in out
    assert "force platforms: 0" in out


def test_info_trc_and_sto(tmp_path, capsys):
    t = np.arange(11) / 50.0
    write_trc(tmp_path / "m.trc", time=t, markers=np.ones((11, 2, 3)), labels=["P", "Q"])
    assert main(["info", str(tmp_path / "m.trc")]) == 0
    out = capsys.readouterr().out
    assert "rate: 50 Hz, 11 frames, duration 0.200 s, units in file mm" in out
    assert "markers: 2 (0 with gaps)" in out
    write_sto(tmp_path / "q.sto", Table(time=t, data=np.zeros((11, 2)), columns=("a", "b")))
    assert main(["info", str(tmp_path / "q.sto")]) == 0
    out = capsys.readouterr().out
    assert "rate: 50 Hz, 11 rows, duration 0.200 s" in out
    assert "columns: 2\n  a\n  b\n" in out


def test_errors_are_one_line_with_status_2(tmp_path, capsys):
    bad = tmp_path / "bad.c3d"
    bad.write_text("not a c3d" * 200)
    assert main(["info", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("msk: error: ") and "bad.c3d" in err
    assert main(["info", str(tmp_path / "missing.c3d")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_console_script_never_prints_a_traceback(tmp_path):
    bad = tmp_path / "cut.c3d"
    bad.write_bytes(b"\x02\x50" + b"\0" * 2000)
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from msk.cli import main; sys.exit(main())",
            "info",
            str(bad),
        ],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert proc.stderr.startswith("msk: error: ")


def test_verbs_come_from_the_commands_of_the_verb_modules(capsys, monkeypatch):
    import types

    import msk.cli

    def _hello(args: argparse.Namespace) -> int:
        if args.who == "units":
            raise UnitsError("furlong\nis not a unit")
        print(f"hello {args.who}")
        return 0

    mod = types.ModuleType("msk_test_verbs")
    mod.COMMANDS = (  # type: ignore[attr-defined]
        Command("hello-test", "say hello", lambda p: p.add_argument("--who"), _hello),
    )
    monkeypatch.setitem(sys.modules, "msk_test_verbs", mod)
    monkeypatch.setattr(msk.cli, "VERB_MODULES", (*msk.cli.VERB_MODULES, "msk_test_verbs"))
    assert "hello-test" in build_parser().format_help()
    assert main(["hello-test", "--who", "lab"]) == 0
    assert capsys.readouterr().out == "hello lab\n"
    assert main(["hello-test", "--who", "units"]) == 2
    assert capsys.readouterr().err == "msk: error: furlong is not a unit\n"
    # a verb defined twice is a packaging error, not a silent override
    monkeypatch.setattr(msk.cli, "VERB_MODULES", ("msk_test_verbs", "msk_test_verbs"))
    with pytest.raises(RuntimeError, match="hello-test"):
        build_parser()


def test_help_imports_no_numerical_library():
    """``msk --help`` builds every verb's parser without importing Pinocchio, casadi,
    matplotlib or the pipeline (verb modules import the library in their handlers)."""
    code = (
        "import sys, contextlib, io\n"
        "from msk.cli import main\n"
        "with contextlib.suppress(SystemExit), contextlib.redirect_stdout(io.StringIO()):\n"
        "    main(['--help'])\n"
        "heavy = ('pinocchio', 'casadi', 'matplotlib', 'scipy', 'msk.pipeline', 'msk.model.core')\n"
        "print(' '.join(m for m in heavy if m in sys.modules))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert proc.stdout.strip() == ""


def test_flat_channels_rules():
    rng = np.random.default_rng(1)
    live = rng.normal(0, 0.1, size=(1000, 4))
    a = np.column_stack(
        [live, 1e-3 * rng.normal(size=1000), np.full(1000, np.nan), np.repeat([0.0, 1.0], 500)]
    )
    labs = ["a", "b", "c", "d", "floor", "nan", "switch"]
    flat = flat_channels(a, labs, ["V"] * 7)
    assert set(flat) == {"floor", "nan", "switch"}
    assert flat["nan"] == "all NaN" and flat["switch"] == "2 distinct values"


def test_info_names_the_recognised_markers_and_the_emg_muscles(capsys):
    from msk.cli.info import write_recognition

    out: list[str] = []
    labels = ["LASI", "RASI", "SACR", "LKNE", "LTHI", "RELB"]
    write_recognition(
        labels, None, ["LREC", "vasmed", "EMG1", "dud"], {"dud": "all zero"}, out.append
    )
    text = "".join(out)
    assert "; 4 of 39 gait2392 markers recognised\n" in text
    assert "  LASI -> L.ASIS\n" in text and "  LKNE -> L.Knee.Lat\n" in text
    assert "  LTHI  (no gait2392 marker: kept for marker placement)\n" in text
    assert "  RELB  (not used: arm marker" in text
    assert "  LREC -> rect_fem_l\n" in text
    assert "  vasmed -> vas_med_r  (the label names no side: right assumed)\n" in text
    assert "EMG1 ->" not in text and "dud ->" not in text
    assert '"L.ASIS" = "LASI"' in text and '"rect_fem_l" = "LREC"' in text


@pytest.mark.slow
@pytest.mark.realdata
def test_info_on_a_real_c3d_suggests_a_configuration_that_loads(real_dir, tmp_path, capsys):
    """Motion Analysis Gait.c3d: Helen-Hayes labels and three-letter EMG codes (LREC, RTIB)."""
    import tomllib

    from msk.config import load_config

    c3d = real_dir / "btkdata" / "Gait.c3d"
    assert main(["info", str(c3d)]) == 0
    out = capsys.readouterr().out
    for line in ("RASI -> R.ASIS", "LKNE -> L.Knee.Lat", "LREC -> rect_fem_l", "RSOL -> soleus_r"):
        assert f"  {line}\n" in out
    suggested = out.split("suggested session configuration")[1].split("\n", 1)[1]
    tables = tomllib.loads("\n".join(line.strip() for line in suggested.splitlines()))
    assert tables["emg"]["channels"]["tib_ant_r"] == "RTIB"
    assert tables["markers"]["rename"]["R.ASIS"] == "RASI"
    # the suggested tables make a session configuration that loads
    cfg = tmp_path / "s.toml"
    cfg.write_text(
        '[subject]\nname = "x"\nmass_kg = 70.0\nheight_m = 1.7\n'
        + suggested.replace("  [", "[").replace("\n  ", "\n").lstrip()
        + f'\n[[trials]]\nname = "walk"\nfile = "{c3d.as_posix()}"\nrole = "task"\n'
    )
    loaded = load_config(cfg)
    assert loaded.emg.channels == tables["emg"]["channels"]


@pytest.mark.slow
def test_run_of_the_bundled_session_imports_no_scipy_signal_nor_stats(tmp_path):
    """``msk run pipelines/gc5_PS.toml`` (every stage computed) takes the numpy Butterworth
    and scipy.special's quantiles: neither scipy.signal nor scipy.stats is imported (~1 s of a
    cold run)."""
    from pathlib import Path

    config = Path(__file__).resolve().parents[1] / "pipelines" / "gc5_PS.toml"
    code = (
        "import sys, contextlib, io\n"
        "from msk.cli import main\n"
        "with contextlib.redirect_stderr(io.StringIO()):\n"
        f"    code = main(['run', {str(config)!r}, '--out', {str(tmp_path / 'out')!r}, "
        "'--no-cache', '--quiet'])\n"
        "heavy = ('scipy.signal', 'scipy.stats')\n"
        "print(code, ' '.join(m for m in heavy if m in sys.modules))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=900, check=True
    )
    assert proc.stdout.strip() == "0"
