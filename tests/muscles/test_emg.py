"""EMG processing: envelope recovery, MVC normalisation, quality flags, delay, mapping, real EMG."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal as sps

from msk.exceptions import EmgError, MissingDataError
from msk.muscles.emg import (
    channel_quality,
    envelopes_from_trial,
    linear_envelope,
    missing_channels,
    mvc_peaks,
    process_emg,
    unknown_muscles,
)

RATE = 2000.0


def _noise(n: int, rng: np.random.Generator, band=(20.0, 450.0)) -> np.ndarray:
    sos = sps.butter(4, band, btype="bandpass", fs=RATE, output="sos")
    x = sps.sosfilt(sos, rng.standard_normal(n + 2000))[2000:]
    return x / x.std()


def _truth(t: np.ndarray) -> np.ndarray:
    """A smooth, gait-like activation pattern in [0.05, 1]."""
    return 0.05 + 0.95 * (
        np.exp(-((((t % 1.0) - 0.3) / 0.08) ** 2)) * 0.9
        + 0.5 * np.exp(-((((t % 1.0) - 0.7) / 0.1) ** 2))
    ).clip(0, 1)


def _session(seed: int = 0, dur: float = 4.0):
    rng = np.random.default_rng(seed)
    t = np.arange(int(dur * RATE)) / RATE
    env = _truth(t)
    x = np.column_stack([env * _noise(t.size, rng) * 1e-3 for _ in range(3)])
    return t, env, x


def test_envelope_recovers_the_modulating_signal():
    _, env, x = _session()
    e = linear_envelope(x, rate_hz=RATE, highpass_hz=20.0, lowpass_hz=6.0)
    inner = slice(1000, -1000)
    for j in range(3):
        r = np.corrcoef(e[inner, j], env[inner])[0, 1]
        assert r > 0.95
    # amplitude: the mean of |gaussian| is sqrt(2/pi) sigma
    ratio = np.median(e[inner, 0] / (env[inner] * 1e-3))
    assert ratio == pytest.approx(np.sqrt(2 / np.pi), rel=0.1)


def test_mvc_normalisation_is_exact():
    _, _, x = _session(1)
    mvc_trial = 2.0 * x  # same electrodes, twice the drive
    peaks = mvc_peaks([(mvc_trial, RATE, ["a", "b", "c"])])
    res = process_emg(x, rate_hz=RATE, labels=["a", "b", "c"], mvc=peaks)
    assert res.normalisation_source == ("mvc", "mvc", "mvc")
    ref = linear_envelope(x, rate_hz=RATE)
    k = round(RATE / 6.0)
    # linear filters + |·| are positively homogeneous: the session peak is exactly half the MVC
    for j in range(3):
        assert res.envelopes[k:-k, j].max() == pytest.approx(0.5, rel=1e-9)
        np.testing.assert_allclose(res.envelopes[:, j], np.clip(ref[:, j] / peaks["abc"[j]], 0, 1))
    assert not any("MVC" in w for w in res.warnings)
    via_trials = process_emg(
        x, rate_hz=RATE, labels=["a", "b", "c"], mvc_trials=[(mvc_trial, RATE, ["a", "b", "c"])]
    )
    np.testing.assert_array_equal(via_trials.envelopes, res.envelopes)
    np.testing.assert_allclose(via_trials.normalisation_value, [peaks[c] for c in "abc"])
    # the peak over several trials is taken
    peaks2 = mvc_peaks([(x, RATE, ["a", "b", "c"]), (mvc_trial, RATE, ["a", "b", "c"])])
    assert peaks2 == pytest.approx(peaks)


def test_session_peak_fallback_is_recorded_and_clipping_warned():
    _, _, x = _session(2)
    res = process_emg(x, rate_hz=RATE, labels=["a", "b", "c"], mvc={"a": 1e-9})
    assert res.normalisation_source == ("mvc", "session_peak", "session_peak")
    assert any("'b'" in w and "session's peak" in w for w in res.warnings)
    assert any("'a'" in w and "clipped" in w for w in res.warnings)
    assert np.nanmax(res.envelopes) <= 1.0 and np.nanmin(res.envelopes) >= 0.0
    assert res.envelopes[:, 1].max() == pytest.approx(1.0)
    with pytest.raises(EmgError, match=r"'a'.*MVC.*-1"):
        process_emg(x, rate_hz=RATE, labels=["a", "b", "c"], mvc={"a": -1.0})


def _quantise(x: np.ndarray, lsb: float = 10.0 / 65536) -> np.ndarray:
    return np.round(x / lsb) * lsb


def test_flat_and_saturated_channels_are_flagged_with_figures():
    rng = np.random.default_rng(3)
    t, env, _ = _session(3)
    good = _quantise(env * _noise(t.size, rng) * 0.3)
    dead = _quantise(-0.1 + 0.0015 * rng.standard_normal(t.size))  # noise floor, ~10 LSB
    unmodulated = _quantise(0.05 * _noise(t.size, rng))  # stationary noise, plenty of LSB
    constant = np.full(t.size, 0.2)
    raw = env * _noise(t.size, rng) * 0.3
    clip_level = 0.5 * np.abs(raw).max()
    clipped = _quantise(np.clip(raw, -clip_level, clip_level))
    x = np.column_stack([good, dead, unmodulated, constant, clipped, good[::-1]])
    labels = ["good", "dead", "unmod", "const", "clipped", "good2"]
    q = channel_quality(x, rate_hz=RATE, labels=labels)
    assert q.flat.tolist() == [False, True, True, True, False, False]
    assert q.saturated.tolist() == [False, False, False, False, True, False]
    assert q.clipped_fraction[4] > 0.002 and q.clipped_fraction[0] < 0.001
    assert q.rms_lsb[1] < 20 < q.rms_lsb[2]
    assert q.modulation[2] < 1.6 < q.modulation[0]
    lines = q.summary()
    assert any("'dead' is flat" in s and "LSB" in s for s in lines)
    assert any("'clipped' is saturated" in s for s in lines)
    res = process_emg(x, rate_hz=RATE, labels=labels)
    assert res.usable.tolist() == [True, False, False, False, True, True]
    assert any("'dead' is flat" in w for w in res.warnings)
    with pytest.raises(EmgError, match="'dead' is flat"):
        process_emg(x, rate_hz=RATE, labels=labels, bad_channel="raise")
    kept = process_emg(x, rate_hz=RATE, labels=labels, bad_channel="keep")
    assert kept.usable.all()


def test_delay_shifts_by_the_right_number_of_samples():
    _, _, x = _session(4)
    labels = ["a", "b", "c"]
    base = process_emg(x, rate_hz=RATE, labels=labels)
    res = process_emg(x, rate_hz=RATE, labels=labels, delay_s={"b": 0.040})
    s = round(0.040 * RATE)
    assert s == 80
    np.testing.assert_array_equal(res.envelopes[s:, 1], base.envelopes[:-s, 1])
    np.testing.assert_array_equal(res.envelopes[:s, 1], base.envelopes[0, 1])
    np.testing.assert_array_equal(res.envelopes[:, 0], base.envelopes[:, 0])
    assert res.delay_s.tolist() == [0.0, 0.04, 0.0]
    with pytest.raises(EmgError, match="unknown muscles"):
        process_emg(x, rate_hz=RATE, labels=labels, delay_s={"zz": 0.01})


def test_mapping_and_synergists():
    _, _, x = _session(5)
    labels = ["VM", "VL", "RF"]
    muscles = {"vasmed_r": "VM", "vaslat_r": "VL", "recfem_r": "RF"}
    res = process_emg(
        x,
        rate_hz=RATE,
        labels=labels,
        muscles=muscles,
        synergists={"vasint_r": ["vasmed_r", "vaslat_r"]},
    )
    assert res.muscle_names == ("vasmed_r", "vaslat_r", "recfem_r", "vasint_r")
    assert res.muscle_sources[-1] == "VM+VL"
    np.testing.assert_allclose(
        res.column("vasint_r"), 0.5 * (res.column("vasmed_r") + res.column("vaslat_r"))
    )
    assert res.time[1] - res.time[0] == pytest.approx(1 / RATE)
    with pytest.raises(MissingDataError, match=r"'GRA'.*'gracilis_r'.*\['VM', 'VL', 'RF'\]"):
        process_emg(x, rate_hz=RATE, labels=labels, muscles={"gracilis_r": "GRA"})
    with pytest.raises(MissingDataError, match="vasint_r"):
        process_emg(x, rate_hz=RATE, labels=labels, muscles=muscles, synergists={"vasint_r": ["x"]})
    with pytest.raises(EmgError, match="transpose"):
        process_emg(x.T, rate_hz=RATE, labels=labels)
    r2 = res.resampled(np.arange(0.5, 1.0, 0.01))
    assert r2.envelopes.shape == (50, 4)


@pytest.mark.slow
@pytest.mark.realdata
def test_grand_challenge_emg(real_dir):
    ezc3d = pytest.importorskip("ezc3d")
    c = ezc3d.c3d(str(real_dir / "knee-grand-challenge-gc5" / "PS_ngait_og_ss1.c3d"))
    labels = [s.strip() for s in c["parameters"]["ANALOG"]["LABELS"]["value"]]
    rate = float(c["parameters"]["ANALOG"]["RATE"]["value"][0])
    analogs = c["data"]["analogs"][0].T  # (N, C)
    emg_labels = labels[labels.index("gracilis") : labels.index("sartorius") + 1]
    x = analogs[:, [labels.index(s) for s in emg_labels]]
    res = process_emg(
        x,
        rate_hz=rate,
        labels=emg_labels,
        synergists={"vasint": ["vasmed", "vaslat"]},
        delay_s=0.03,
    )
    flat = {lab for lab, f in zip(res.quality.labels, res.quality.flat) if f}
    assert "gracilis" in flat
    assert {"semimem", "bifeml", "vasmed", "vaslat", "rf", "tibant", "soleus"}.isdisjoint(flat)
    assert not res.quality.saturated.any()
    assert np.isnan(res.column("gracilis")).all()
    ok = res.envelopes[:, res.usable]
    assert ok.min() >= 0 and ok.max() <= 1
    assert res.usable[res.muscle_names.index("vasint")]
    assert all(s == "session_peak" for s in res.normalisation_source)
    assert res.time.size == x.shape[0] and res.rate_hz == pytest.approx(1200.0)
    # the same through msk.io.read_c3d (SI trial) when that reader is present
    import msk.io as io

    trial = io.read_c3d(real_dir / "knee-grand-challenge-gc5" / "PS_ngait_og_ss1.c3d")
    via = envelopes_from_trial(trial, channels=emg_labels, delay_s=0.03)
    np.testing.assert_allclose(via.envelopes, res.envelopes[:, : len(emg_labels)], atol=1e-9)


def test_trial_adapter_uses_analog_time_and_labels():
    from types import SimpleNamespace

    _, _, x = _session(6)
    trial = SimpleNamespace(
        analogs=np.column_stack([np.zeros(len(x)), x]),
        analog_labels=("Fz1", "VM", "VL", "RF"),
        analog_rate_hz=RATE,
        analog_time=2.5 + np.arange(len(x)) / RATE,
    )
    res = envelopes_from_trial(trial, muscles={"vasmed_r": "VM", "recfem_r": "RF"}, delay_s=0.01)
    ref = process_emg(x[:, [0, 2]], rate_hz=RATE, labels=["VM", "RF"], delay_s=0.01)
    np.testing.assert_array_equal(res.envelopes, ref.envelopes)
    assert res.time[0] == 2.5 and res.channel_labels == ("VM", "RF")
    with pytest.raises(EmgError, match="muscles"):
        envelopes_from_trial(trial)


@pytest.mark.slow
@pytest.mark.realdata
def test_grand_challenge_4_dud_and_dead_first_channel(real_dir):
    ezc3d = pytest.importorskip("ezc3d")
    c = ezc3d.c3d(str(real_dir / "knee-grand-challenge-gc4" / "jw_ngait_og3.c3d"))
    labels = [s.strip() for s in c["parameters"]["ANALOG"]["LABELS"]["value"]]
    rate = float(c["parameters"]["ANALOG"]["RATE"]["value"][0])
    emg_labels = labels[labels.index("semimem") : labels.index("sartorius") + 1]
    x = c["data"]["analogs"][0].T[:, [labels.index(s) for s in emg_labels]]
    q = channel_quality(x, rate_hz=rate, labels=emg_labels)
    flat = {lab for lab, f in zip(q.labels, q.flat) if f}
    # the README: a "dud" channel and a flat first EMG channel (semimem)
    assert {"dud", "semimem"} <= flat
    assert {"bifeml", "vaslat", "rf", "medgas", "latgas", "tibant", "soleus"}.isdisjoint(flat)
    assert not q.saturated.any()


def test_missing_channels_tells_a_typo_from_a_channel_the_trial_lacks():
    labels = ["vasmed", "vaslat", " rectfem ", "Pedal", "GON"]
    channels = {"vas_med_l": "vasmedX", "vas_lat_l": "vaslat", "rect_fem_l": "rectfem",
                "semimem_l": "semimem", "bifemlh_l": "vaslatt"}  # fmt: skip
    typos, absent = missing_channels(channels, labels)
    # one extra character next to an unmapped label is a typo; "vaslatt" is close to "vaslat",
    # but that label is mapped already (its own muscle), so it is absent, not a typo
    assert typos == {"vasmedX": "vasmed"}
    assert absent == ("semimem", "vaslatt")
    assert missing_channels({"a": "vasmed"}, labels) == ({}, ())


def test_a_misspelt_muscle_of_the_emg_channels_gets_the_closest_model_muscle(tmp_path):
    from types import SimpleNamespace

    from msk.exceptions import ConfigError
    from msk.model.files import load_model
    from msk.pipeline import emg as stage

    gait2392 = load_model("gait2392")
    names = [m.name for m in gait2392.muscles]
    channels = {"rectfem_r": "rf", "VasLat_r": "vl", "soleus_r": "sol", "quadriceps": "q"}
    assert unknown_muscles(channels, names) == {
        "VasLat_r": "vas_lat_r",
        "quadriceps": None,
        "rectfem_r": "rect_fem_r",
    }
    assert unknown_muscles({"soleus_r": "sol"}, names) == {}
    # the EMG stage: a ConfigError naming the file, the key and the suggestion
    emg = SimpleNamespace(channels={"rectfem_r": "rf"})
    inputs = SimpleNamespace(cfg=SimpleNamespace(path=tmp_path / "s.toml", emg=emg))
    with pytest.raises(ConfigError, match=r"s\.toml: emg\.channels\.rectfem_r: .*'rect_fem_r'\?"):
        stage.run(inputs, SimpleNamespace(trial=None), SimpleNamespace(model=gait2392), None)


def test_suggest_channels_reads_the_muscle_and_side_of_common_emg_labels():
    from msk.muscles.emg import suggest_channels

    muscles = [f"{m}_{s}" for m in ("rect_fem", "vas_med", "tib_ant", "lat_gas", "soleus")
               for s in "rl"]  # fmt: skip
    labels = ["Left Rectus femoris", "RTIB", "vasmed", "Right Gastrocnemius Lateralis",
              "Voltage.SOL_L", "EMG1", "LeftFootSwitch", "goniometer", "rf"]  # fmt: skip
    assert suggest_channels(labels, muscles) == {
        "Left Rectus femoris": ("rect_fem_l", True),
        "RTIB": ("tib_ant_r", True),
        "vasmed": ("vas_med_r", False),
        "Right Gastrocnemius Lateralis": ("lat_gas_r", True),
        "Voltage.SOL_L": ("soleus_l", True),
        "rf": ("rect_fem_r", False),  # no side in the label: the default side
    }
    assert suggest_channels(["vasmed"], muscles, side="l") == {"vasmed": ("vas_med_l", False)}
    assert suggest_channels(["rf", "RF_R"], ["rect_fem_r"]) == {"rf": ("rect_fem_r", False)}
    # the Rajagopal model's own names
    raj = ["recfem_r", "vaslat_l", "bflh_r", "gasmed_r", "tibant_r", "sart_r", "soleus_r"]
    assert suggest_channels(
        ["R Rectus Femoris.EMG1", "L Vastus Lateralis", "RBIC", "RGAS", "R Tibialis Anterior",
         "R Sartorius", "RSOL"], raj,
    ) == {
        "R Rectus Femoris.EMG1": ("recfem_r", True), "L Vastus Lateralis": ("vaslat_l", True),
        "RBIC": ("bflh_r", True), "RGAS": ("gasmed_r", True),
        "R Tibialis Anterior": ("tibant_r", True), "R Sartorius": ("sart_r", True),
        "RSOL": ("soleus_r", True),
    }  # fmt: skip


def test_a_channel_bursting_once_per_stride_is_not_flat():
    """A muscle bursting once per 1.1 s stride (a 0.15 s burst, 20 % over the noise floor:
    99th/10th percentile ratio < 1.6, a few LSB) is kept; stationary noise of the same level
    stays flat; the figures say why."""
    rng = np.random.default_rng(11)
    t = np.arange(int(6.0 * RATE)) / RATE
    floor = 0.002 * _noise(t.size, rng)
    burst = 1.0 + 0.6 * np.exp(-((((t % 1.1) - 0.4) / 0.07) ** 2))
    bursting = _quantise(floor * burst)
    noise = _quantise(0.002 * _noise(t.size, rng))
    good = _quantise(_truth(t) * _noise(t.size, rng) * 0.3)
    x = np.column_stack([bursting, noise, good])
    plain = channel_quality(x, rate_hz=RATE, labels=["burst", "noise", "good"],
                            flat_cycle_correlation=np.inf)  # fmt: skip
    assert plain.flat.tolist() == [True, True, False]  # flat by modulation or LSB alone
    q = channel_quality(x, rate_hz=RATE, labels=["burst", "noise", "good"])
    assert q.flat.tolist() == [False, True, False]
    assert q.cycle_correlation[0] >= 0.6 > q.cycle_correlation[1]
    assert q.cycle_period_s[0] == pytest.approx(1.1, abs=0.03)
    assert q.cycle_period_s[2] == pytest.approx(1.0, abs=0.03)
    assert any("'noise' is flat" in s and "autocorrelation" in s for s in q.summary())


def test_a_record_shorter_than_two_strides_has_no_cycle_figure():
    rng = np.random.default_rng(12)
    x = _quantise(0.002 * _noise(int(0.9 * RATE), rng))
    q = channel_quality(x[:, None], rate_hz=RATE, labels=["a"])
    assert np.isnan(q.cycle_correlation[0]) and q.flat[0]


def _amplifier_envelope(seed: int = 0, rest_v: float = 30e-6, amp_v: float = 60e-6):
    """An amplifier's RMS output of a 2-kHz EMG: rest level + an effort, 100-ms moving RMS,
    quantised to 2.44 µV (a 12-bit converter's step)."""
    from msk.signal import filtfilt_butter

    rng = np.random.default_rng(seed)
    rate = 2000.0
    t = np.arange(int(10 * rate)) / rate
    level = rest_v + amp_v * np.clip((t - 1.0) / 0.5, 0, 1) * (t < 8.0)
    raw = level * rng.standard_normal(t.size)
    rms = np.sqrt(np.convolve(raw**2, np.ones(200) / 200, mode="same"))
    rms = filtfilt_butter(rms, rate_hz=rate, cutoff_hz=10.0)
    return rate, raw, np.round(np.maximum(rms, 0) / 2.44e-6) * 2.44e-6


def test_envelope_channel_recognises_an_amplifier_envelope_not_raw_or_dead_emg():
    from msk.muscles.emg import envelope_channel

    rate, raw, env = _amplifier_envelope()
    got = envelope_channel(env, rate_hz=rate, highpass_hz=20.0, lowpass_hz=6.0)
    assert got is not None
    assert got.hp_rms_lsb <= 3.0 and got.lp_sd_lsb >= 1.0
    assert got.lsb == pytest.approx(2.44e-6)
    # the effort's level read back: √(30² + 60²) ≈ 67 µV RMS
    assert float(np.median(got.envelope[6000:14000])) == pytest.approx(
        np.hypot(30e-6, 60e-6), rel=0.35
    )
    raw_q = np.round(raw / 2.44e-6) * 2.44e-6
    assert envelope_channel(raw_q, rate_hz=rate, highpass_hz=20.0) is None  # raw EMG
    assert envelope_channel(np.abs(raw_q), rate_hz=rate, highpass_hz=20.0) is None  # rectified
    rng = np.random.default_rng(1)
    dead = np.round((25e-6 + 0.5e-6 * rng.standard_normal(20000)) / 2.44e-6) * 2.44e-6
    assert envelope_channel(dead, rate_hz=rate, highpass_hz=20.0) is None  # an offset, still
