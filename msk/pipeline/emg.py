"""Stage ``emg``: EMG envelopes (high-pass, rectify, low-pass, electromechanical delay;
normalised by MVC trials or values, else by the session's peak) resampled on the kinematics and
turned into activations by first-order activation dynamics
(:func:`msk.muscles.emg.envelopes_from_trial`, :func:`msk.muscles.activation.\
first_order_activation`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from msk.exceptions import ConfigError
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.model import BuiltModel
from msk.pipeline.read import ReadResult
from msk.pipeline.runner import StageUnavailable, file_sha256

__all__ = ["EmgActivations", "run", "settings"]


@dataclass(frozen=True)
class EmgActivations:
    """Per model muscle with an EMG channel: ``envelopes`` and ``activation`` (N, m) on the
    kinematics' time base (activation NaN for unusable channels), the channel each muscle reads
    (``sources``), ``usable`` (m,), the normalisation used, the reader's warnings and the
    per-channel :class:`msk.muscles.emg.ChannelQuality` and the raw channels' single-sample
    faults (repaired or channel excluded)."""

    normalisation: str
    muscles: tuple[str, ...]
    sources: tuple[str, ...]
    envelopes: np.ndarray
    activation: np.ndarray
    usable: np.ndarray
    warnings: Sequence[str]
    quality: Any
    #: single-sample faults of the raw channels (msk.muscles.emg_faults.SampleFaults)
    sample_faults: tuple[Any, ...] = ()

    def column(self, muscle: str) -> int:
        """Index of ``muscle`` in :attr:`muscles`."""
        return self.muscles.index(muscle)


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
    inputs: SessionInputs, read: ReadResult, model: BuiltModel, kinematics: Any
) -> EmgActivations:
    cfg, trial = inputs.cfg, read.trial
    if not cfg.emg.channels:
        raise StageUnavailable("no [emg] channels in the configuration")
    from msk.io import read_c3d
    from msk.muscles.activation import first_order_activation
    from msk.muscles.emg import envelopes_from_trial, missing_channels

    unknown = sorted(set(cfg.emg.channels) - {m.name for m in model.model.muscles})
    if unknown:
        raise ConfigError(f"{cfg.path}: emg.channels: model has no muscle {unknown[0]!r}")
    assert inputs.task is not None  # a gait stage
    typos, absent = missing_channels(cfg.emg.channels, getattr(trial, "analog_labels", ()))
    if typos:
        ch, close = next(iter(typos.items()))
        raise ConfigError(
            f"{cfg.path}: emg.channels: {inputs.task.file.name} has no analog channel "
            f"{ch!r} (did you mean {close!r}?)"
        )
    # a channel this recording lacks (and nothing like it): its muscles are not tracked, the
    # quality flag emg_channels_missing says so (msk.pipeline.summary)
    channels = {m: c for m, c in cfg.emg.channels.items() if str(c).strip() not in absent}
    if not channels:
        raise StageUnavailable(
            f"{inputs.task.file.name} has none of the configured EMG channels ({', '.join(absent)})"
        )
    mvc = []
    for tc in inputs.mvc_trials:
        tr_m = read_c3d(tc.file)
        mvc.append((tr_m.analogs, tr_m.analog_rate_hz, tr_m.analog_labels))
    mvc_options: dict[str, Any] = {}
    if mvc:
        mvc_options["mvc_trials"] = mvc
    if cfg.emg.mvc:
        mvc_options["mvc"] = {k: float(v) for k, v in cfg.emg.mvc.items()}
    env = envelopes_from_trial(
        trial,
        muscles=channels,
        highpass_hz=cfg.emg.highpass_hz,
        lowpass_hz=cfg.emg.lowpass_hz,
        delay_s=cfg.emg.electromechanical_delay_s,
        time=kinematics.time,  # each channel resampled once processed (issue 18)
        **mvc_options,
    )
    env_k = env
    e = np.clip(np.nan_to_num(env_k.envelopes, nan=0.0), 0.0, 1.0)
    act = first_order_activation(e, rate_hz=trial.point_rate_hz)
    act[:, ~env_k.usable] = np.nan
    return EmgActivations(
        "MVC" if (mvc or cfg.emg.mvc) else "this session's peak (relative activations, not "
        "strength)",
        tuple(env_k.muscle_names), tuple(env_k.muscle_sources), env_k.envelopes, act,
        np.asarray(env_k.usable), list(env.warnings), env.quality, tuple(env.sample_faults),
    )  # fmt: skip
