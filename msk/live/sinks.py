"""Where a live session's results go: a callback (:class:`CallbackSink`), an LSL outlet
(:class:`LslSink`), or kept for the tables of a results folder (:class:`FrameRecorder`)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from msk.live.session import STAGES, LiveFrame, LiveModel

__all__ = ["CallbackSink", "FrameRecorder", "LslSink", "result_channels"]


class CallbackSink:
    """Calls ``fn(frame)`` with each :class:`msk.live.session.LiveFrame`."""

    def __init__(self, fn: Callable[[LiveFrame], Any]) -> None:
        self.fn = fn

    def __call__(self, frame: LiveFrame) -> None:
        self.fn(frame)


def result_channels(lm: LiveModel) -> tuple[str, ...]:
    """The channels :class:`LslSink` publishes, in order: the time, every coordinate's angle
    and torque, every muscle's force, the knee's axial, medial and lateral contact force, the
    RMS marker error and the QP status."""
    return (
        "time",
        *(f"q_{c}" for c in lm.coordinate_names),
        *(f"tau_{c}" for c in lm.coordinate_names),
        *(f"force_{m}" for m in lm.muscle_names),
        "knee_axial", "knee_medial", "knee_lateral", "marker_rms", "qp_status",
    )  # fmt: skip


class LslSink:
    """An LSL outlet (stream type ``"msk"``, ``float64``) publishing each frame's results as
    :func:`result_channels` orders them (their names in the stream's description)."""

    def __init__(self, name: str, lm: LiveModel) -> None:
        from msk.live.sources import load_pylsl

        lsl = load_pylsl()
        self.channels = result_channels(lm)
        info = lsl.StreamInfo(
            name, "msk", len(self.channels), lm.rate_hz, lsl.cf_double64, f"msk-{name}"
        )
        info.desc().append_child_value("channels", ",".join(self.channels))
        self.outlet = lsl.StreamOutlet(info)
        self._buf = np.empty(len(self.channels))
        self._n_c, self._n_m = lm.n_coords, len(lm.muscle_names)

    def __call__(self, frame: LiveFrame) -> None:
        b, n_c, n_m = self._buf, self._n_c, self._n_m
        b[0] = frame.time
        b[1 : 1 + n_c] = frame.q
        b[1 + n_c : 1 + 2 * n_c] = frame.torques
        b[1 + 2 * n_c : 1 + 2 * n_c + n_m] = frame.muscle_forces
        b[-5:] = (
            frame.knee_axial, frame.knee_medial, frame.knee_lateral, frame.marker_rms,
            frame.qp_status,
        )  # fmt: skip
        self.outlet.push_sample(b)


class FrameRecorder:
    """Keeps every frame, for the tables of a results folder (:meth:`tables`) and the latency
    distribution (:meth:`latency_percentiles`)."""

    def __init__(self, lm: LiveModel) -> None:
        self.model = lm
        self.frames: list[LiveFrame] = []

    def __call__(self, frame: LiveFrame) -> None:
        self.frames.append(frame)

    def stage_seconds(self) -> NDArray[np.float64]:
        """(N, len(STAGES)) each frame's stage times, s."""
        return np.array([f.stage_s for f in self.frames]).reshape(-1, len(STAGES))

    def latency_percentiles(self, skip: int = 0) -> dict[str, tuple[float, float]]:
        """Stage (and ``"chain"``) → (p50, p99) in seconds over the frames after ``skip``."""
        s = self.stage_seconds()[skip:]
        out = {name: (float(np.percentile(s[:, k], 50)), float(np.percentile(s[:, k], 99)))
               for k, name in enumerate(STAGES)}  # fmt: skip
        chain = s.sum(axis=1)
        out["chain"] = (float(np.percentile(chain, 50)), float(np.percentile(chain, 99)))
        return out

    def tables(self, body_weight_n: float) -> dict[str, Any]:
        """The streamed results as :class:`msk.io.tables.Table` (time axis 0), named like the
        offline run's: ``q``, ``joint_torques``, ``muscle_forces``, ``activations``,
        ``knee_contact`` (``live_`` columns: axial, medial, lateral with their ``_bw``) and
        ``live_quality`` (RMS marker error, IK iterations, QP status, each stage's seconds)."""
        from msk.io.tables import Table

        lm, fr = self.model, self.frames
        t = np.array([f.time for f in fr])

        def stack(name: str) -> NDArray[np.float64]:
            return np.array([getattr(f, name) for f in fr], dtype=float)

        knee = np.column_stack([stack("knee_axial"), stack("knee_medial"), stack("knee_lateral")])
        cols = ("live_axial", "live_medial", "live_lateral")
        quality = np.column_stack([
            stack("marker_rms"), stack("ik_iterations"), stack("ik_converged"),
            stack("qp_status"), self.stage_seconds(),
        ])  # fmt: skip
        knee_cols = (*cols, *(f"{c}_bw" for c in cols))
        quality_cols = (
            "marker_rms", "ik_iterations", "ik_converged", "qp_status",
            *(f"{s}_s" for s in STAGES),
        )  # fmt: skip
        contact = np.column_stack([knee, knee / body_weight_n])
        return {
            "q": Table(t, stack("q"), lm.coordinate_names, "q"),
            "joint_torques": Table(t, stack("torques"), lm.coordinate_names, "joint_torques"),
            "muscle_forces": Table(t, stack("muscle_forces"), lm.muscle_names, "muscle_forces"),
            "activations": Table(t, stack("activations"), lm.muscle_names, "activations"),
            "knee_contact": Table(t, contact, knee_cols, "knee_contact"),
            "live_quality": Table(t, quality, quality_cols, "live_quality"),
        }

    def write(self, folder: str | Path, body_weight_n: float) -> list[Path]:
        """Each table of :meth:`tables` as ``folder/tables/<name>.csv``."""
        from msk.io.tables import write_csv_table

        tdir = Path(folder) / "tables"
        tdir.mkdir(parents=True, exist_ok=True)
        out = []
        for name, tab in self.tables(body_weight_n).items():
            path = tdir / f"{name}.csv"
            write_csv_table(path, tab)
            out.append(path)
        return out
