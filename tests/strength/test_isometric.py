"""Isometric MVC analysis (msk.strength.isometric), the dynamometer reader (msk.io.dynamometer)
and the dynamometry session (msk.pipeline.dynamometry): a synthetic dynamometer trial of known
torque, lever arm, offset, noise and EMG recovered; every check fires on a trial made to fail
it; the shared 20-subject cohort through ``msk run``."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import numpy as np
import pytest

from msk.exceptions import FileFormatError, MissingDataError, MskError
from msk.io.dynamometer import DynamometerRecording, read_dynamometer
from msk.strength.isometric import (
    IsometricSettings,
    IsometricTest,
    LeverArm,
    ModelTorque,
    agonist_mvc,
    analyse_isometric,
    group_strength,
    lever_arm_from_height,
    relabel_quiet_channels,
    remove_envelope_rest,
    session_mvc,
)
from msk.units import G0 as G_STANDARD

RATE = 2000.0
LABELS = ("VL", "BF", "TA", "GL")
KNEE = IsometricTest(
    name="knee_extension", action="knee extension", angle_deg=90.0, target="VL", antagonist="BF"
)


def _trial(
    *,
    torque_nm: float = 120.0,
    lever_m: float = 0.35,
    offset_n: float = 40.0,
    noise_n: float = 2.0,
    seed: int = 0,
    rest_s: float = 1.0,
    hold_s: float = 3.0,
    amps: tuple[float, ...] = (300e-6, 30e-6, 20e-6, 20e-6),
    rest_amp: float = 5e-6,
    ramp_s: float = 0.5,
) -> DynamometerRecording:
    """Rest, a ramp to ``torque_nm / lever_m`` held ``hold_s``, relaxation; EMG: white noise
    whose amplitude follows the effort (channel amplitudes ``amps``), quantised to 2.44 µV."""
    rng = np.random.default_rng(seed)
    n = int((rest_s + ramp_s + hold_s + 1.0) * RATE)
    t = np.arange(n) / RATE
    f = torque_nm / lever_m
    shape = np.clip((t - rest_s) / ramp_s, 0.0, 1.0)
    shape[t > rest_s + ramp_s + hold_s] = 0.0
    force = offset_n + f * shape + noise_n * rng.standard_normal(n)
    a = np.asarray(amps)
    emg = (rest_amp + shape[:, None] * a[None, :]) * rng.standard_normal((n, a.size))
    emg = np.round(emg / 2.44e-6) * 2.44e-6
    return DynamometerRecording(Path("synthetic.csv"), t, force, None, emg, LABELS, RATE, "force")


def _model(nm: float = 150.0) -> ModelTorque:
    return ModelTorque((0.9 * nm, nm, 1.1 * nm), 80.0, {"knee_angle_r": -90.0}, ("vasti",))


def test_synthetic_trial_recovers_torque_offset_and_factor() -> None:
    errs = []
    for seed in range(20):
        rec = _trial(seed=seed)
        tr = analyse_isometric(rec, KNEE)
        assert tr.baseline_n == pytest.approx(40.0, abs=0.6)
        assert "pre-effort" in tr.baseline_source
        r = group_strength(
            tr,
            KNEE,
            lever=LeverArm(0.35, 0.01, "given"),
            model=_model(),
            mass_kg=75.0,
            mvc=session_mvc([tr]),
        )
        # antagonist BF at 100 % of its (only) session maximum: co-contraction = 80 N·m
        assert r.measured_net_nm == pytest.approx(120.0, rel=0.01)
        errs.append(r.measured_net_nm / 120.0 - 1.0)
        assert r.torque_ci_nm[0] < r.torque_nm < r.torque_ci_nm[1]
    assert abs(float(np.mean(errs))) < 0.005


def test_cocontraction_uses_the_antagonists_own_test() -> None:
    ext = analyse_isometric(_trial(amps=(300e-6, 30e-6, 20e-6, 20e-6)), KNEE)
    flex_test = IsometricTest(
        name="knee_flexion", action="knee flexion", angle_deg=90.0, target="BF", antagonist="VL"
    )
    flex = analyse_isometric(_trial(amps=(20e-6, 150e-6, 20e-6, 20e-6), seed=1), flex_test)
    own = agonist_mvc([ext, flex], [KNEE, flex_test])
    r = group_strength(
        ext,
        KNEE,
        lever=LeverArm(0.35, 0.01, "given"),
        model=_model(),
        mass_kg=75.0,
        mvc=session_mvc([ext, flex]),
        own_mvc=own,
    )
    # BF at ~20 % of its own test's plateau × 80 N·m antagonist torque
    assert r.cocontraction_nm == pytest.approx(0.2 * 80.0, rel=0.15)
    assert r.torque_nm == pytest.approx(r.measured_net_nm + r.cocontraction_nm)
    assert r.status == "identified", r.reason


def _as_envelope_output(rec: DynamometerRecording, j: int, rest_v: float) -> DynamometerRecording:
    """Channel j replaced by an amplifier's envelope output of it: its 100-ms moving RMS plus
    the amplifier's rest level ``rest_v``, quantised to 2.44 µV (non-negative, smooth)."""
    from dataclasses import replace

    x = rec.emg[:, j]
    rms = np.sqrt(np.convolve(x**2, np.ones(200) / 200, mode="same")) + rest_v
    emg = rec.emg.copy()
    emg[:, j] = np.round(rms / 2.44e-6) * 2.44e-6
    return replace(rec, emg=emg)


def test_an_envelope_channel_is_used_as_its_envelope_with_its_rest_level_removed() -> None:
    """Plantarflexion whose GL channel is an amplifier's envelope (the shared elderly data):
    not refused as flat, flagged ``emg_envelope_channel``, and — its amplifier rest level (the
    session's lowest) taken off — its plateau amplitude is the effort's RMS, the target of
    the test identified."""
    plantar = IsometricTest(
        name="ankle_plantarflexion", action="ankle plantarflexion", angle_deg=0.0,
        target="GL", antagonist="TA", segment="foot",
    )  # fmt: skip
    knee = _as_envelope_output(_trial(amps=(300e-6, 30e-6, 20e-6, 0.0)), 3, 25e-6)
    rec = _as_envelope_output(_trial(amps=(20e-6, 20e-6, 20e-6, 80e-6), seed=2), 3, 25e-6)
    raw = analyse_isometric(_trial(amps=(20e-6, 20e-6, 20e-6, 80e-6), seed=2), plantar)
    tr = analyse_isometric(rec, plantar)
    assert not tr.emg_flat["GL"]
    assert any(f.quantity == "emg_envelope_channel" for f in tr.flags)
    assert not any(f.quantity == "emg_one_sided" for f in tr.flags)
    assert not tr.failed, [f.message for f in tr.failed]
    trials = remove_envelope_rest([analyse_isometric(knee, KNEE), tr])
    # rest level 25 µV + the 5-µV rest noise's RMS: ≈ 30 µV read at rest, taken off
    assert trials[1].emg_plateau["GL"] == pytest.approx(85e-6 - 5e-6, rel=0.15)
    # the raw channel's linear envelope reads the mean |x| (√(2/π) of the RMS): same effort
    assert raw.emg_plateau["GL"] == pytest.approx(np.sqrt(2 / np.pi) * 85e-6, rel=0.1)


def test_tared_zero_used_when_the_recording_starts_mid_effort() -> None:
    rec = _trial(rest_s=0.0, ramp_s=0.01, offset_n=0.0)
    tr = analyse_isometric(rec, KNEE)
    assert "tared zero" in tr.baseline_source
    assert tr.plateau_mean == pytest.approx(120.0 / 0.35, rel=0.01)
    assert any(f.quantity == "effort_before_baseline_info" for f in tr.flags)
    pre = analyse_isometric(rec, KNEE, settings=IsometricSettings(baseline="pre_effort"))
    assert any(f.quantity == "effort_before_baseline" for f in pre.failed)


def _fails(rec: DynamometerRecording, quantity: str, **kw: object) -> None:
    settings = IsometricSettings(**kw)  # type: ignore[arg-type]
    tr = analyse_isometric(rec, KNEE, settings=settings)
    # the session's other test: every channel at 400 µV (the session maxima)
    other = analyse_isometric(_trial(amps=(400e-6,) * 4, seed=9), KNEE)
    r = group_strength(
        tr,
        KNEE,
        lever=LeverArm(0.35, 0.01, "given"),
        model=_model(),
        mass_kg=75.0,
        mvc=session_mvc([tr, other]),
    )
    hit = [f for f in r.flags if f.quantity == quantity]
    assert hit, [f.quantity for f in r.flags]
    assert r.status == "not determined"
    assert "knee_extension" in r.reason


def test_each_check_fires_on_a_bad_trial() -> None:
    good = _trial()
    tr = analyse_isometric(good, KNEE)
    assert not tr.failed, [f.message for f in tr.failed]
    # saturated: the cell's capacity reached
    _fails(good, "saturated", capacity=300.0)
    # clipped: the force flat on its maximum
    clip = _trial()
    assert clip.force is not None
    f = np.minimum(clip.force, 300.0)
    _fails(
        DynamometerRecording(clip.source, clip.time, f, None, clip.emg, LABELS, RATE, "f"),
        "saturated",
    )
    # too short a plateau
    _fails(_trial(hold_s=0.4), "plateau_short")
    # baseline drift in a pre-effort window
    drift = _trial()
    assert drift.force is not None
    d = drift.force.copy()
    d[: int(0.25 * RATE)] += np.linspace(0.0, 80.0, int(0.25 * RATE))
    _fails(
        DynamometerRecording(drift.source, drift.time, d, None, drift.emg, LABELS, RATE, "f"),
        "baseline_drift",
        baseline="pre_effort",
    )
    # target not the most active: VL quiet, TA loud
    _fails(_trial(amps=(20e-6, 30e-6, 300e-6, 20e-6)), "target_not_most_active")
    # dead target channel
    dead = _trial()
    e = dead.emg.copy()
    e[:, 0] = 2.44e-6 * np.round(np.random.default_rng(3).standard_normal(e.shape[0]) * 0.5)
    _fails(
        DynamometerRecording(dead.source, dead.time, dead.force, None, e, LABELS, RATE, "f"),
        "emg_flat_target",
    )
    # pulling the wrong way
    wrong = _trial()
    assert wrong.force is not None
    _fails(
        DynamometerRecording(
            wrong.source, wrong.time, 80.0 - wrong.force, None, wrong.emg, LABELS, RATE, "f"
        ),
        "wrong_direction",
    )


def test_lever_arm_from_height_says_which_and_scales_with_height() -> None:
    a = lever_arm_from_height("shank", 1.60)
    b = lever_arm_from_height("shank", 1.80, sex="male")
    assert a.source.startswith("anthropometric") and "both sexes" in a.source
    assert b.value_m == pytest.approx(434.0 / 1741.0 * 1.80 - 0.05)
    assert 0.30 < a.value_m < 0.40 and a.sd_m > 0
    foot = lever_arm_from_height("foot", 1.60)
    assert 0.08 < foot.value_m < 0.15
    with pytest.raises(MskError):
        lever_arm_from_height("arm", 1.6)


def test_reader_csv_gzip_tab_and_bad_cells(tmp_path: Path) -> None:
    text = "time_s,force_kgf,emg_VL_uV\n0,1.0,10\n0.0005,2.0,-10\n0.001,3.0,5\n"
    p = tmp_path / "a.csv.gz"
    p.write_bytes(gzip.compress(text.encode()))
    r = read_dynamometer(
        p,
        force_column="force_kgf",
        force_unit="kgf",
        emg_columns={"VL": "emg_VL_uV"},
        emg_unit="uV",
    )
    assert r.rate_hz == pytest.approx(2000.0)
    assert r.force is not None and r.force[1] == pytest.approx(2.0 * G_STANDARD)
    assert r.emg[0, 0] == pytest.approx(10e-6)
    q = tmp_path / "b.txt"
    q.write_text(text.replace(",", "\t"))
    r2 = read_dynamometer(q, torque_column="force_kgf", torque_unit="N.m")
    assert r2.torque is not None and r2.torque[2] == 3.0
    bad = tmp_path / "c.csv"
    bad.write_text(text.replace("2.0", "abc"))
    with pytest.raises(FileFormatError, match=r"row 3, column 'force_kgf': value 'abc'"):
        read_dynamometer(bad, force_column="force_kgf")
    with pytest.raises(MissingDataError, match="no force column 'F'"):
        read_dynamometer(p, force_column="F")
    with pytest.raises(MissingDataError, match="not found"):
        read_dynamometer(tmp_path / "none.csv", force_column="F")


MODEL = Path(__file__).resolve().parents[2] / "msk" / "data" / "models" / "gait2392.toml"


def _write_csv(path: Path, rec: DynamometerRecording) -> None:
    assert rec.force is not None
    lines = ["time_s\tforce_kgf\t" + "\t".join(f"emg_{c}_uV" for c in LABELS)]
    for i in range(rec.n_samples):
        emg = "\t".join(f"{v * 1e6:.4f}" for v in rec.emg[i])
        lines.append(f"{rec.time[i]:.4f}\t{rec.force[i] / G_STANDARD:.6f}\t{emg}")
    path.write_bytes(gzip.compress(("\n".join(lines) + "\n").encode()))


def _config(tmp: Path, files: dict[str, Path], extra: str = "", subject: str = "") -> Path:
    tests = {
        "knee_extension": ("knee extension", 90.0, "VL", "BF", "shank"),
        "knee_flexion": ("knee flexion", 90.0, "BF", "VL", "shank"),
    }
    text = f"""kind = "dynamometry"
[subject]
name = "synthetic"
mass_kg = 70.0
height_m = 1.70
{subject}
[model]
source = "{MODEL.as_posix()}"
[dynamometer]
force_column = "force_kgf"
force_unit = "kgf"
emg_unit = "uV"
{extra}
[dynamometer.emg]
VL = "emg_VL_uV"
BF = "emg_BF_uV"
TA = "emg_TA_uV"
GL = "emg_GL_uV"
"""
    for name, (action, angle, target, ant, seg) in tests.items():
        text += f"""
[[tests]]
name = "{name}"
file = "{files[name].name}"
action = "{action}"
angle_deg = {angle}
posture_deg = {{ hip_flexion = 90.0 }}
target = "{target}"
antagonist = "{ant}"
segment = "{seg}"
lever_arm_m = 0.35
lever_arm_sd_m = 0.005
"""
    p = tmp / "session.toml"
    p.write_text(text)
    return p


def test_msk_run_recovers_a_synthetic_session(tmp_path: Path) -> None:
    from msk.cli import main

    files = {"knee_extension": tmp_path / "ext.tsv.gz", "knee_flexion": tmp_path / "flex.tsv.gz"}
    _write_csv(files["knee_extension"], _trial(torque_nm=100.0, offset_n=50.0, seed=1))
    flex = _trial(torque_nm=40.0, offset_n=10.0, seed=2, amps=(10e-6, 200e-6, 20e-6, 20e-6))
    _write_csv(files["knee_flexion"], flex)
    cfg = _config(tmp_path, files)
    assert main(["run", str(cfg), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    by = {t["test"]: t for t in s["tests"]}
    ext, fl = by["knee_extension"], by["knee_flexion"]
    assert ext["measured_net_nm"] == pytest.approx(100.0, rel=0.02)
    assert fl["measured_net_nm"] == pytest.approx(40.0, rel=0.02)
    assert ext["status"] == "identified", ext["reason"]
    assert ext["lever_arm_source"].startswith("given")
    assert 50.0 < ext["model_nm"] < 300.0
    assert ext["factor"] == pytest.approx(ext["torque_nm"] / ext["model_nm"])
    # the antagonist BF at ~15 % of its own test's plateau: a co-contraction correction
    assert 0.0 < ext["cocontraction_nm"] < 0.3 * 100.0
    report = (tmp_path / "out" / "report.html").read_text()
    assert "knee_extension" in report and "N·m/kg" in report
    # every test's torque per kg: summary, table, report
    import csv

    rows = {r["test"]: r for r in csv.DictReader((tmp_path / "out/tables/strength.csv").open())}
    for t in s["tests"]:
        assert t["torque_nm_per_kg"] == pytest.approx(t["torque_nm"] / 70.0)
        lo, hi = t["torque_nm_per_kg_ci"]
        assert lo < t["torque_nm_per_kg"] < hi
        assert float(rows[t["test"]]["torque_nm_per_kg"]) == pytest.approx(
            t["torque_nm_per_kg"], abs=1e-4
        )
        assert f"{t['torque_nm_per_kg']:.2f} [" in report
    # no age given: no published band, no plausibility flag
    assert ext["band_nm_per_kg"] == [None, None] and not ext["below_published_band"]
    # same folder again: replaced
    assert main(["run", str(cfg), "--out", str(tmp_path / "out"), "--quiet"]) == 0


def test_a_torque_below_the_published_band_is_flagged_and_stays_identified(
    tmp_path: Path,
) -> None:
    """A 72-year-old's knee extension of 0.5 N·m/kg (band 1.40–2.16) passes every trial check:
    identified, with ``below_published_band`` naming the band, its source and the candidate
    causes; ``--strict`` exits 3; a knee flexion inside its band is not flagged."""
    from msk.cli import main

    files = {"knee_extension": tmp_path / "ext.tsv.gz", "knee_flexion": tmp_path / "flex.tsv.gz"}
    _write_csv(files["knee_extension"], _trial(torque_nm=35.0, offset_n=50.0, seed=1))
    flex = _trial(torque_nm=45.0, offset_n=10.0, seed=2, amps=(10e-6, 200e-6, 20e-6, 20e-6))
    _write_csv(files["knee_flexion"], flex)
    cfg = _config(tmp_path, files, subject="age_years = 72")
    out = tmp_path / "out"
    assert main(["run", str(cfg), "--out", str(out), "--quiet"]) == 0
    assert main(["run", str(cfg), "--out", str(out), "--quiet", "--strict"]) == 3
    s = json.loads((out / "summary.json").read_text())
    by = {t["test"]: t for t in s["tests"]}
    ext, fl = by["knee_extension"], by["knee_flexion"]
    assert ext["status"] == "identified" and ext["below_published_band"]
    assert ext["band_nm_per_kg"] == [1.40, 2.16] and "Šarabon" in ext["band_source"]
    flag = next(f for f in s["flags"] if f["quantity"] == "below_published_band")
    assert flag["trial"] == "knee_extension" and flag["threshold"] == 1.40
    assert "submaximal effort, strap slip or the lever-arm assumption" in flag["message"]
    assert not fl["below_published_band"], fl  # 0.64 N·m/kg, band 0.46–0.89
    assert s["n_below_published_band"] == 1
    rows = (out / "tables" / "strength.csv").read_text().splitlines()
    assert "below_published_band" in rows[0] and ",1.4,2.16,1,," in rows[1]
    report = (out / "report.html").read_text()
    assert "1.40–2.16 (below)" in report and "below the published band for age" in report
    # a band given by the configuration replaces the library's, with its source
    text = cfg.read_text().replace(
        'name = "knee_extension"',
        'name = "knee_extension"\nband_nm_per_kg = [0.3, 0.9]\nband_source = "lab norms"',
    )
    cfg.write_text(text)
    assert main(["run", str(cfg), "--out", str(out), "--quiet", "--strict"]) == 0
    ext = json.loads((out / "summary.json").read_text())["tests"][0]
    assert ext["band_nm_per_kg"] == [0.3, 0.9] and ext["band_source"].endswith("lab norms")


def test_config_errors_name_the_key(tmp_path: Path) -> None:
    from msk.pipeline.dynamometry import load_dynamometry_config

    files = {"knee_extension": tmp_path / "a.csv", "knee_flexion": tmp_path / "b.csv"}
    cfg = _config(tmp_path, files, extra="baseline = 'sometimes'\n")
    with pytest.raises(MskError, match=r"dynamometer.baseline = 'sometimes'"):
        load_dynamometry_config(cfg)
    text = _config(tmp_path, files).read_text().replace('target = "VL"', 'target = "XX"')
    (tmp_path / "session.toml").write_text(text)
    with pytest.raises(MskError, match=r"tests\[0\].target = 'XX'"):
        load_dynamometry_config(tmp_path / "session.toml")
    good = _config(tmp_path, files).read_text()
    for extra, msg in (
        ("band_nm_per_kg = [2.0, 1.0]", r"tests\[0\].band_nm_per_kg = \[2.0, 1.0\]"),
        ("band_nm_per_kg = [0.5, 1.0]", r"tests\[0\].band_nm_per_kg needs tests\[0\].band_source"),
    ):
        text = good.replace('name = "knee_extension"', f'name = "knee_extension"\n{extra}')
        (tmp_path / "session.toml").write_text(text)
        with pytest.raises(MskError, match=msg):
            load_dynamometry_config(tmp_path / "session.toml")


REAL = Path(__file__).resolve().parents[2] / "pipelines" / "dynamometry_elderly"


@pytest.mark.slow
@pytest.mark.realdata
def test_the_twenty_subjects_run_with_sane_figures(tmp_path: Path) -> None:
    from msk.cli import main

    configs = sorted(REAL.glob("S*.toml"))
    if len(configs) != 20:
        pytest.skip("dynamometry configs absent")
    data = Path("/work/shared/data/real/dynamometry-elderly")
    first = REAL / "../../../shared/data/real/dynamometry-elderly/S01_knee_extension.csv.gz"
    if not first.resolve().is_file() and not data.is_dir():
        pytest.skip("dynamometry-elderly data absent")
    knee_ext = []
    passed = plantar = 0
    assert main(["batch", *map(str, configs), "--out", str(tmp_path)]) == 0
    assert (tmp_path / "strength_cohort.csv").read_text().count("\n") == 1 + 4 * len(configs)
    import csv

    cohort = list(csv.DictReader((tmp_path / "strength_cohort.csv").open()))
    summary = list(csv.DictReader((tmp_path / "strength_cohort_summary.csv").open()))
    assert [r["test"] for r in summary] == [
        "knee_extension",
        "knee_flexion",
        "ankle_dorsiflexion",
        "ankle_plantarflexion",
    ]
    assert all(r["n_subjects"] == "20" for r in summary)
    # the covariates of a cohort comparison on every row (strength per kg vs age)
    assert all(64 <= float(r["age_years"]) <= 82 and float(r["mass_kg"]) > 30 for r in cohort)
    # every test's torque per kg and its published band (all subjects are ≥ 60 y)
    for r in cohort:
        assert float(r["torque_nm_per_kg"]) == pytest.approx(
            float(r["torque_nm"]) / float(r["mass_kg"]), abs=1e-3
        )
        assert float(r["band_low_nm_per_kg"]) < float(r["band_high_nm_per_kg"])
        below = float(r["torque_nm_per_kg_ci_high"]) < float(r["band_low_nm_per_kg"])
        assert r["below_published_band"] == str(int(below))
        assert (r["failed_checks"] == "") == (r["reason"] == "every check passed") or (
            r["status"] == "not determined" and "interval" in r["reason"]
        )
    for c in configs:
        out = tmp_path / c.stem
        s = json.loads((out / "summary.json").read_text())
        assert s["n_tests"] == 4
        passed += s["n_identified"]
        for t in s["tests"]:
            assert t["status"] in ("identified", "not determined")
            assert t["status"] == "identified" or t["reason"] != "every check passed"
            if t["test"] == "knee_extension" and t["status"] == "identified":
                knee_ext.append(t["torque_nm"])
            if t["test"] == "ankle_plantarflexion":
                plantar += t["status"] == "identified"
                # the GL channel is an amplifier's envelope in every file: used, said so
                gl = [f for f in s["flags"] if f["trial"] == "ankle_plantarflexion"]
                assert any(f["quantity"] == "emg_envelope_channel" for f in gl), gl
        assert (out / "tables" / "strength.csv").is_file()
        report = (out / "report.html").read_text()
        assert "Identified" in report and "Published band" in report
        assert "Trial and EMG checks" in report
    assert passed >= 20
    # GL read as the envelope it is: 8 of 20 plantarflexion tests identified (0 when it was
    # refused as a flat channel); the others fail a stated check
    assert plantar >= 6
    assert len(knee_ext) >= 8
    assert 30.0 < float(np.median(knee_ext)) < 200.0
    assert all(10.0 < x < 250.0 for x in knee_ext)


def test_model_torque_matches_the_joint_strength_curves() -> None:
    from msk.model.files import load_model
    from msk.strength.isometric import model_isometric_torque, subject_model
    from msk.strength.joint_strength import max_isometric_moment_curves

    gen = load_model(MODEL)
    small = subject_model(gen, height_m=1.60, mass_kg=60.0)
    # the posture of joint_strength's knee curves: hip 0, ankle 0, knee swept
    test = IsometricTest(name="k", action="knee extension", angle_deg=60.0, angle_range_deg=5.0)
    mt = model_isometric_torque(small, test, side="right")
    curve = max_isometric_moment_curves(
        small, side="right", joints=["knee extension"], angles_deg={"knee extension": [55, 60, 65]}
    )["knee extension"]
    assert mt.agonist_nm[1] == pytest.approx(curve.moment_nm[1], rel=1e-9)
    assert mt.antagonist_nm > 0.0
    # the same test on the generic (1.80 m) model: longer moment arms, more torque
    big = model_isometric_torque(gen, test, side="right")
    assert big.agonist_nm[1] > mt.agonist_nm[1]


def test_interval_covers_the_true_torque_when_the_lever_arm_is_uncertain() -> None:
    """True lever arms drawn from N(0.35, 0.02²) m; the analysis is told 0.35 ± 0.02 m."""
    rng = np.random.default_rng(42)
    hits = 0
    n = 100
    for seed in range(n):
        d_true = 0.35 + 0.02 * rng.standard_normal()
        force_n = 100.0 / 0.35
        rec = _trial(torque_nm=force_n * d_true, lever_m=d_true, seed=seed, hold_s=1.5)
        tr = analyse_isometric(rec, KNEE)
        r = group_strength(tr, KNEE, lever=LeverArm(0.35, 0.02, "given"), model=_model(),
                           mass_kg=75.0, mvc=session_mvc([tr]), own_mvc={})  # fmt: skip
        true = force_n * d_true
        hits += r.torque_ci_nm[0] <= true <= r.torque_ci_nm[1]
    assert hits / n >= 0.9


def test_a_torque_export_needs_no_lever_arm() -> None:
    rec = _trial(torque_nm=80.0, lever_m=1.0, offset_n=3.0, noise_n=0.5)
    tq = DynamometerRecording(rec.source, rec.time, None, rec.force, rec.emg, LABELS, RATE, "T")
    tr = analyse_isometric(tq, KNEE)
    assert tr.is_torque
    r = group_strength(tr, KNEE, lever=None, model=_model(), mass_kg=80.0, mvc=session_mvc([tr]),
                       own_mvc={})  # fmt: skip
    assert r.measured_net_nm == pytest.approx(80.0, rel=0.01)
    assert r.lever_arm_source.startswith("not used")
    assert r.torque_nm_per_kg == pytest.approx(r.torque_nm / 80.0)


def test_a_channel_quiet_in_one_test_and_active_in_another_is_not_called_dead() -> None:
    """TA at the noise floor during a knee extension but active in a dorsiflexion: a muscle at
    rest (``emg_quiet_other``); GL flat in both tests stays a dead channel."""
    dorsi = IsometricTest(
        name="ankle_dorsiflexion", action="ankle dorsiflexion", angle_deg=0.0,
        target="TA", antagonist="GL", segment="foot",
    )  # fmt: skip
    knee = analyse_isometric(_trial(amps=(300e-6, 30e-6, 0.0, 0.0), rest_amp=3e-6), KNEE)
    ta = analyse_isometric(_trial(amps=(20e-6, 20e-6, 300e-6, 0.0), rest_amp=3e-6, seed=3), dorsi)
    assert knee.emg_flat["TA"] and knee.emg_flat["GL"] and not ta.emg_flat["TA"]

    def flat(tr):
        return {f.message.split(": ")[1] for f in tr.flags if f.quantity == "emg_flat_other"}

    assert flat(knee) == {"EMG TA", "EMG GL"}
    out = relabel_quiet_channels([knee, ta])
    assert flat(out[0]) == {"EMG GL"}
    quiet = [f for f in out[0].flags if f.quantity == "emg_quiet_other"]
    assert len(quiet) == 1 and "EMG TA" in quiet[0].message
    assert "ankle_dorsiflexion" in quiet[0].message
    assert out[1].flags == ta.flags
    assert out[0].emg_flat == knee.emg_flat  # the analysis is unchanged


def test_the_published_band_applies_to_older_adults_and_to_the_whole_interval() -> None:
    from msk.strength.isometric import LITERATURE_BANDS, band_check, literature_band

    assert literature_band("knee extension", None) is None
    assert literature_band("knee extension", 45.0) is None
    band = literature_band("ankle plantarflexion", 70.0)
    assert band is LITERATURE_BANDS["ankle plantarflexion"]
    # below only when the interval's upper end is below the lower edge
    assert band_check("pf", band.low_nm_per_kg + 0.01, 0.3, band, "x: y") is None
    f = band_check("pf", band.low_nm_per_kg - 0.01, 0.3, band, "anthropometric: …")
    assert f is not None and f.quantity == "below_published_band" and f.value == 0.3
    for b in LITERATURE_BANDS.values():
        assert 0.0 < b.low_nm_per_kg < b.high_nm_per_kg < 3.0 and "(20" in b.source
