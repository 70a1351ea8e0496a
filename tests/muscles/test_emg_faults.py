"""msk.muscles.emg_faults: one bad EMG sample never changes a result silently."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from msk.muscles.emg import mvc_peaks, process_emg
from msk.muscles.emg_faults import fault_flags, find_sample_faults, repair_sample_faults

RATE = 1000.0
REPO = Path(__file__).resolve().parents[2]


def _emg(seed: int, n: int = 4000, *, laplace: bool = False) -> np.ndarray:
    """Raw EMG (V): noise modulated by three bursts of activity (0.3 mV rest, 1 mV burst),
    quantised to 1 µV, with an offset."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / RATE
    amp = 3e-5 + 1e-3 * sum(
        np.exp(-0.5 * ((t - c) / 0.08) ** 2) for c in rng.uniform(0.3, n / RATE - 0.3, 3)
    )
    noise = rng.laplace(size=n) if laplace else rng.normal(size=n)
    return np.round((2e-4 + amp * noise) / 1e-6) * 1e-6


@pytest.mark.parametrize("seed", range(12))
def test_clean_emg_has_no_fault(seed):
    x = _emg(seed, laplace=seed % 2 == 1)
    bad, _ = find_sample_faults(x, rate_hz=RATE)
    assert not bad.any()
    y, faults = repair_sample_faults(x, rate_hz=RATE)
    assert faults is None and y is not None and np.array_equal(y, x)


@pytest.mark.parametrize("value", [1e20, np.inf, -np.inf, np.nan, 50.0])
def test_one_bad_sample_is_repaired_and_said(value):
    x = np.column_stack([_emg(1), _emg(2)])
    bad = x.copy()
    bad[1234, 0] = value
    kw = dict(rate_hz=RATE, labels=("vasmed", "rf"), highpass_hz=20.0, lowpass_hz=6.0)
    clean = process_emg(x, **kw)
    got = process_emg(bad, **kw)
    # the envelopes (session-peak normalised) are those of the clean recording
    np.testing.assert_allclose(got.envelopes, clean.envelopes, atol=2e-3)
    np.testing.assert_allclose(got.normalisation_value, clean.normalisation_value, rtol=2e-3)
    assert got.usable.all()
    (f,) = got.sample_faults
    assert f.channel == "vasmed" and f.count == 1 and f.first_index == 1234 and f.repaired
    assert f.first_time_s == pytest.approx(1.234)
    (flag,) = fault_flags("walk", got.sample_faults)
    assert flag.quantity == "emg_sample_faults" and "'vasmed'" in flag.message
    assert flag.trial == "walk" and flag.value == 1.0 and flag.threshold == 0.0
    assert any("vasmed" in w and "1.2340 s" in w for w in got.warnings)


def test_a_long_run_of_bad_samples_excludes_the_channel():
    x = np.column_stack([_emg(3), _emg(4)])
    x[1000:1100, 1] = np.nan  # 100 ms lost: not a glitch to interpolate
    got = process_emg(x, rate_hz=RATE, labels=("a", "b"), bad_channel="keep")
    assert got.usable.tolist() == [True, False]
    (f,) = got.sample_faults
    assert not f.repaired and f.count == 100 and "run of 100" in f.reason
    assert fault_flags("walk", got.sample_faults)[0].quantity == "emg_channel_excluded"


def test_a_spike_in_an_mvc_trial_does_not_set_the_mvc():
    x = _emg(5)[:, None]
    spiked = x.copy()
    spiked[2000, 0] = 50.0
    clean = mvc_peaks([(x, RATE, ["vasmed"])])
    got = mvc_peaks([(spiked, RATE, ["vasmed"])])
    assert got["vasmed"] == pytest.approx(clean["vasmed"], rel=2e-3)


@pytest.mark.slow
@pytest.mark.realdata
def test_one_bad_sample_in_a_real_recording_is_flagged_and_changes_nothing(tmp_path):
    """gc5 PS: one sample of vasmed set to 1e20 (was: knee contact error vs the implant
    0.224 → 0.295 BW without a flag) or inf (was: EMG, muscle forces, strength and contact
    "not available" with exit 0)."""
    import ezc3d

    from msk.pipeline import run_session

    gc5 = REPO / "pipelines" / "gc5_PS.toml"
    rms = {}
    for tag, value in (("clean", None), ("big", 1e20), ("inf", np.inf)):
        c = ezc3d.c3d(str(REPO / "data" / "gc5-PS" / "PS_ngait_og_ss1.c3d"))
        labels = [s.strip() for s in c["parameters"]["ANALOG"]["LABELS"]["value"]]
        a = c["data"]["analogs"]
        if value is not None:
            a[0, labels.index("vasmed"), a.shape[2] // 2] = value
        c["data"]["analogs"] = a
        c.write(str(tmp_path / f"{tag}.c3d"))
        text = gc5.read_text(encoding="utf-8").replace('"../', f'"{REPO}/')
        text = text.replace(f'"{REPO}/data/gc5-PS/PS_ngait_og_ss1.c3d"', f'"{tmp_path}/{tag}.c3d"')
        (tmp_path / f"{tag}.toml").write_text(text, encoding="utf-8")
        d = run_session(tmp_path / f"{tag}.toml", tmp_path / tag).summary.to_dict()
        assert d["not_available"] == []
        flags = [f for f in d["quality"]["flags"] if f["quantity"] == "emg_sample_faults"]
        assert len(flags) == (0 if value is None else 1)
        if value is not None:
            assert re.search(r"'vasmed'.*1 faulty sample", flags[0]["message"])
        rms[tag] = d["comparison"]["knee_contact_subject_specific"]["rms_bw"]
    assert rms["big"] == pytest.approx(rms["clean"], abs=2e-3)
    assert rms["inf"] == pytest.approx(rms["clean"], abs=2e-3)


@pytest.mark.slow
@pytest.mark.realdata
def test_a_failed_stage_is_a_quality_flag(tmp_path, capsys):
    """A stage that failed (its results "not available") raises a quality flag, so that
    ``msk run --strict`` exits 3 and a batch sees it."""
    from msk.pipeline import run_session

    res = run_session(
        REPO / "pipelines" / "gc5_PS.toml", tmp_path / "o", _fail_stage="strength_identification"
    )
    d = res.summary.to_dict()
    (flag,) = [f for f in d["quality"]["flags"] if f["quantity"] == "stage_failed"]
    assert "strength_identification" in flag["message"]
