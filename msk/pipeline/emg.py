"""Stage ``emg``: EMG envelopes (high-pass, rectify, low-pass, electromechanical delay;
normalised by MVC trials or values, else by the session's peak) resampled on the kinematics and
turned into activations by first-order activation dynamics
(:func:`msk.muscles.emg.envelopes_from_trial`, :func:`msk.muscles.activation.\
first_order_activation`)."""

from __future__ import annotations

from typing import Any

from msk.exceptions import ConfigError
from msk.muscles.emg import EmgActivations
from msk.personalise import Personalisation
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.records import ReadResult
from msk.pipeline.runner import StageUnavailable, file_sha256

__all__ = ["run", "settings"]


def settings(inputs: SessionInputs) -> Any:
    e = inputs.cfg.emg
    return {
        "channels": dict(e.channels),
        "hp": e.highpass_hz,
        "lp": e.lowpass_hz,
        "emd": e.electromechanical_delay_s,
        "mvc": [file_sha256(t.file) for t in inputs.mvc_trials],
        "mvc_values": dict(e.mvc),
    }


def run(
    inputs: SessionInputs, read: ReadResult, model: Personalisation, kinematics: Any
) -> EmgActivations:
    cfg, trial = inputs.cfg, read.trial
    if not cfg.emg.channels:
        raise StageUnavailable("no [emg] channels in the configuration")
    from msk.io import read_c3d
    from msk.muscles.emg import emg_activations, missing_channels, unknown_muscles

    unknown = unknown_muscles(cfg.emg.channels, [m.name for m in model.model.muscles])
    if unknown:
        key, close = next(iter(unknown.items()))
        tip = f" (did you mean {close!r}?)" if close else ""
        raise ConfigError(
            f"{cfg.path}: emg.channels.{key}: model {model.model.name} has no muscle {key!r}{tip}"
        )
    assert inputs.task is not None  # a gait stage
    typos, absent = missing_channels(cfg.emg.channels, getattr(trial, "analog_labels", ()))
    if typos:
        ch, close = next(iter(typos.items()))
        raise ConfigError(
            f"{cfg.path}: emg.channels: {inputs.task.file.name} has no analog channel "
            f"{ch!r} (did you mean {close!r}?)"
        )
    # a channel this recording lacks (and nothing like it): its muscles are not tracked, the
    # quality flag emg_channels_missing says so (msk.quality.trial_flags)
    channels = {m: c for m, c in cfg.emg.channels.items() if str(c).strip() not in absent}
    if not channels:
        raise StageUnavailable(
            f"{inputs.task.file.name} has none of the configured EMG channels ({', '.join(absent)})"
        )
    mvc = []
    for tc in inputs.mvc_trials:
        tr_m = read_c3d(tc.file)
        mvc.append((tr_m.analogs, tr_m.analog_rate_hz, tr_m.analog_labels))
    return emg_activations(
        trial, muscles=channels, highpass_hz=cfg.emg.highpass_hz, lowpass_hz=cfg.emg.lowpass_hz,
        delay_s=cfg.emg.electromechanical_delay_s, time=kinematics.time, mvc_trials=mvc,
        mvc=cfg.emg.mvc,
    )  # fmt: skip
