"""Where a live session's frames come from: a recorded trial replayed (:class:`ReplaySource`) or
a Lab Streaming Layer inlet (:class:`LslSource`, ``pylsl``; the ``live`` extra), and the LSL
outlet that publishes frames for such an inlet (:class:`LslInputOutlet`).

On the wire a frame is one LSL sample of ``float64`` channels (:class:`StreamLayout`): the
frame's time, the markers (M × 3, m), the plates' forces (P × 3, N) and moments about the lab
origin (P × 3, N·m), the EMG samples (C); the labels and counts travel in the stream's
description, so an inlet rebuilds the frames bit for bit.
"""

from __future__ import annotations

import time as _time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from msk.exceptions import FileFormatError, MissingDataError
from msk.live.session import LiveInput

__all__ = [
    "LslInputOutlet",
    "LslSource",
    "ReplaySource",
    "StreamLayout",
    "load_pylsl",
]


def load_pylsl() -> Any:
    """The ``pylsl`` module (:class:`MissingDataError` naming the ``live`` extra when it is not
    installed or its liblsl cannot be loaded)."""
    try:
        import pylsl
    except (ImportError, RuntimeError, OSError) as exc:
        raise MissingDataError(
            f"Lab Streaming Layer unavailable ({exc}): install msk's 'live' extra (pylsl)"
        ) from None
    return pylsl


@dataclass(frozen=True)
class StreamLayout:
    """The channels of one frame on the wire: ``[time, markers (M·3), plate forces (P·3),
    plate moments (P·3), emg (C)]``."""

    labels: tuple[str, ...]
    n_plates: int = 0
    emg_channels: tuple[str, ...] = ()

    @property
    def n_channels(self) -> int:
        return 1 + 3 * len(self.labels) + 6 * self.n_plates + len(self.emg_channels)

    def encode(self, frame: LiveInput, out: NDArray[np.float64]) -> NDArray[np.float64]:
        """``frame`` into the sample buffer ``out`` (:attr:`n_channels`,)."""
        m, p = 3 * len(self.labels), 3 * self.n_plates
        out[0] = frame.time
        out[1 : 1 + m] = frame.markers.ravel()
        out[1 + m : 1 + m + p] = frame.plate_force.ravel()
        out[1 + m + p : 1 + m + 2 * p] = frame.plate_moment.ravel()
        out[1 + m + 2 * p :] = frame.emg
        return out

    def decode(self, sample: Sequence[float] | NDArray[np.float64]) -> LiveInput:
        """The :class:`LiveInput` of one sample."""
        x = np.asarray(sample, dtype=float)
        m, p = 3 * len(self.labels), 3 * self.n_plates
        return LiveInput(
            time=float(x[0]),
            markers=x[1 : 1 + m].reshape(-1, 3),
            plate_force=x[1 + m : 1 + m + p].reshape(-1, 3),
            plate_moment=x[1 + m + p : 1 + m + 2 * p].reshape(-1, 3),
            emg=x[1 + m + 2 * p :],
        )


class ReplaySource:
    """A recorded trial (``.c3d`` or ``.trc``, :func:`msk.io.read_trial`) as a stream of
    :class:`LiveInput` frames, lab frame, at the marker rate: markers (exact zeros, a C3D's gaps,
    as NaN), each plate's wrench at the frame's time (:func:`msk.dynamics.loads.sample_plate`:
    the sign, the contact threshold and the resampling of the offline run, no low-pass), the
    analog ``emg_channels`` sampled likewise. ``grf`` (with its ExternalLoads ``.xml``): the
    plates of an OpenSim GRF file instead (a ``.trc``'s,
    :func:`msk.dynamics.loads.plates_from_grf_file`). ``realtime``: frames are given at the recorded
    rate (the iterator sleeps until each frame's time), else as fast as they are read."""

    def __init__(
        self,
        path: str | Path,
        *,
        grf: str | Path | None = None,
        external_loads: str | Path | None = None,
        emg_channels: Sequence[str] = (),
        realtime: bool = False,
        threshold_n: float = 20.0,
    ) -> None:
        from msk.dynamics.loads import (
            external_loads_assignment,
            plates_from_grf_file,
            plates_from_trial,
            sample_plate,
        )
        from msk.io import read_trial

        self.path = Path(path)
        trial = read_trial(self.path)
        if trial.n_frames < 2:
            raise FileFormatError(f"{self.path}: {trial.n_frames} marker frames, need 2")
        self.time = np.asarray(trial.time, dtype=float)
        self.rate_hz = float(trial.point_rate_hz)
        x = np.array(trial.markers, dtype=float)
        x[(x == 0.0).all(axis=2)] = np.nan
        self.markers = x
        self.labels = tuple(trial.marker_labels)
        up = np.asarray(trial.up, dtype=float)
        plates: tuple[Any, ...] = ()
        #: plate name → body of the GRF file's ExternalLoads ``.xml`` (empty without one)
        self.assignment: dict[str, str] = {}
        if grf is not None:
            plates = plates_from_grf_file(grf, external_loads)
            if external_loads is not None:
                self.assignment = dict(external_loads_assignment(external_loads, grf))
        elif trial.plates:
            plates = plates_from_trial(trial)
        sampled = [sample_plate(p, self.time, up, threshold_n=threshold_n) for p in plates]
        self.plate_names = tuple(p.name for p in plates)
        self.plate_force = np.stack([s.force for s in sampled], axis=1) if sampled else None
        self.plate_moment = np.stack([s.moment for s in sampled], axis=1) if sampled else None
        emg = []
        for name in emg_channels:
            if name not in trial.analog_labels:
                raise MissingDataError(f"{self.path}: no analog channel {name!r}")
            emg.append(np.interp(self.time, trial.analog_time, trial.analog(name)))
        self.emg = np.stack(emg, axis=1) if emg else np.zeros((self.time.size, 0))
        self.layout = StreamLayout(self.labels, len(plates), tuple(emg_channels))
        self.realtime = realtime

    def __len__(self) -> int:
        return int(self.time.size)

    def frame(self, k: int) -> LiveInput:
        """Frame ``k`` (time 0 at the trial's first frame as recorded)."""
        z = np.zeros((0, 3))
        return LiveInput(
            time=float(self.time[k]),
            markers=self.markers[k],
            plate_force=z if self.plate_force is None else self.plate_force[k],
            plate_moment=z if self.plate_moment is None else self.plate_moment[k],
            emg=self.emg[k],
        )

    def __iter__(self) -> Iterator[LiveInput]:
        start = _time.perf_counter()
        for k in range(len(self)):
            if self.realtime:
                wait = start + (self.time[k] - self.time[0]) - _time.perf_counter()
                if wait > 0:
                    _time.sleep(wait)
            yield self.frame(k)


class LslInputOutlet:
    """An LSL outlet publishing :class:`LiveInput` frames of ``layout`` (stream type
    ``"MoCap"``, ``float64`` channels, nominal rate ``rate_hz``; the labels, the plate and EMG
    channel counts in its description), for an :class:`LslSource` elsewhere."""

    def __init__(self, name: str, layout: StreamLayout, rate_hz: float) -> None:
        lsl = load_pylsl()
        info = lsl.StreamInfo(
            name, "MoCap", layout.n_channels, rate_hz, lsl.cf_double64, f"msk-{name}"
        )
        desc = info.desc()
        desc.append_child_value("labels", ",".join(layout.labels))
        desc.append_child_value("n_plates", str(layout.n_plates))
        desc.append_child_value("emg_channels", ",".join(layout.emg_channels))
        self.layout = layout
        self.outlet = lsl.StreamOutlet(info)
        self._buf = np.empty(layout.n_channels)

    def push(self, frame: LiveInput) -> None:
        self.outlet.push_sample(self.layout.encode(frame, self._buf))

    def wait_for_consumers(self, timeout_s: float) -> bool:
        return bool(self.outlet.wait_for_consumers(timeout_s))


class LslSource:
    """An LSL inlet of the stream named ``name`` (as :class:`LslInputOutlet` publishes) as
    :class:`LiveInput` frames. Iteration ends after ``idle_s`` seconds without a sample or
    after ``max_frames``."""

    def __init__(
        self, name: str, *, timeout_s: float = 10.0, idle_s: float = 2.0,
        max_frames: int | None = None,
    ) -> None:  # fmt: skip
        lsl = load_pylsl()
        found = lsl.resolve_byprop("name", name, 1, timeout_s)
        if not found:
            raise MissingDataError(f"no LSL stream named {name!r} within {timeout_s:g} s")
        self.inlet = lsl.StreamInlet(found[0], max_buflen=60, processing_flags=0)
        info = self.inlet.info(timeout_s)
        desc = info.desc()
        labels = desc.child_value("labels")
        emg = desc.child_value("emg_channels")
        self.layout = StreamLayout(
            tuple(labels.split(",")) if labels else (),
            int(desc.child_value("n_plates") or 0),
            tuple(emg.split(",")) if emg else (),
        )
        if self.layout.n_channels != info.channel_count():
            raise FileFormatError(
                f"LSL stream {name!r}: {info.channel_count()} channels, its description "
                f"announces {self.layout.n_channels}"
            )
        self.rate_hz = float(info.nominal_srate())
        self.idle_s, self.max_frames = idle_s, max_frames
        self.inlet.open_stream(timeout_s)

    def __iter__(self) -> Iterator[LiveInput]:
        n = 0
        while self.max_frames is None or n < self.max_frames:
            sample, _ = self.inlet.pull_sample(timeout=self.idle_s)
            if sample is None:
                return
            n += 1
            yield self.layout.decode(sample)
