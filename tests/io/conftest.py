"""Synthetic C3D trials with known content (markers, analogs, a plate with a known wrench)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from msk.io.c3d import PlateSpec, write_c3d
from msk.trial import Event, Subject

# AMTI-like plate: x along lab x, y along -lab y, z down (into the plate)
PLATE_ROT = np.diag([1.0, -1.0, -1.0])
PLATE_CENTRE = np.array([0.3, 0.2, 0.0])
# Y-up lab: plate z along -Y
PLATE_ROT_YUP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
PLATE_ORIGIN = np.array([0.002, -0.001, -0.040])  # transducer offset, plate axes (m)


def plate_corners(rot: np.ndarray, centre: np.ndarray, a: float = 0.3, b: float = 0.2):
    """Corners in C3D order so that x = c0 - c1, y = c0 - c3 are the plate axes ``rot``."""
    ex, ey = rot[:, 0], rot[:, 1]
    return np.array(
        [
            centre + a * ex + b * ey,
            centre - a * ex + b * ey,
            centre - a * ex - b * ey,
            centre + a * ex - b * ey,
        ]
    )


def plate_channels(force, cop, tz, *, rot, centre, origin, length_scale):
    """Analog channels (N, N·unit) of a type-2 plate measuring a known lab wrench.

    ``force`` (Na,3) lab, ``cop`` (Na,3) lab on the surface, ``tz`` (Na,) free moment about
    the plate normal. Returns (Na, 6) channels in plate axes with moments about the transducer.
    """
    normal = rot[:, 2]
    m_c = np.cross(cop - centre, force) + tz[:, None] * normal  # about the surface centre, lab
    f_raw = force @ rot
    m_raw = m_c @ rot
    m_t = m_raw - np.cross(f_raw, origin)  # C3D: M_c = M_t + F x o
    return np.column_stack([f_raw, m_t / length_scale])


@pytest.fixture
def plate_rot_yup() -> np.ndarray:
    return PLATE_ROT_YUP.copy()


@pytest.fixture
def synth(tmp_path: Path):
    """Factory: write a synthetic trial; returns (path, truth dict)."""

    def make(*, units: str = "mm", n: int = 60, ratio: int = 10, rot=PLATE_ROT, seed: int = 0):
        rng = np.random.default_rng(seed)
        rate = 100.0
        t = np.arange(n) / rate
        labels = ["LASI", "RASI", "LKNE", "RKNE"]
        # smooth trajectories (a marker's path, not noise: white noise of 1 m a frame is a
        # teleport every frame for the reader, msk.io.marker_checks)
        amp = rng.uniform(0.1, 0.5, size=(1, 4, 3))
        phase = rng.uniform(0.0, 2 * np.pi, size=(1, 4, 3))
        offset = rng.uniform(-0.5, 0.5, size=(1, 4, 3)) + np.array([0.0, 0.0, 1.0])
        markers = offset + amp * np.sin(2 * np.pi * t[:, None, None] + phase)
        markers[5:9, 1] = np.nan  # 4-frame gap
        markers[20, 1] = np.nan  # 1-frame gap
        markers[30:33, 3] = np.nan  # 3-frame gap
        na = n * ratio
        ta = np.arange(na) / (rate * ratio)
        fz = 700.0 * np.sin(np.pi * ta / ta[-1]) ** 2  # unloaded at both ends
        force = np.column_stack([30 * np.sin(5 * ta), -20 * np.cos(3 * ta), fz])
        centre = PLATE_CENTRE
        if rot is not PLATE_ROT:
            centre = np.array([0.3, 0.0, 0.2])
        u = rot[:, 0] * (0.1 * np.sin(2 * ta))[:, None] + rot[:, 1] * (0.05 * np.cos(ta))[:, None]
        cop = centre + u
        # a vertical force along the lab "up" = -normal for z-down plates
        up = -rot[:, 2]
        force = force[:, [0]] * rot[:, 0] + force[:, [1]] * rot[:, 1] + fz[:, None] * up
        tz = 3.0 * np.sin(4 * ta)
        scale = {"m": 1.0, "mm": 1e-3, "cm": 1e-2}[units]
        ch = plate_channels(
            force, cop, tz, rot=rot, centre=centre, origin=PLATE_ORIGIN, length_scale=scale
        )
        emg = rng.normal(0, 1e-4, size=(na, 2))
        analogs = np.column_stack([ch, emg])
        alabels = ["Fx1", "Fy1", "Fz1", "Mx1", "My1", "Mz1", "EMG_VL", "EMG_TA"]
        aunits = ["N", "N", "N", "Nmm", "Nmm", "Nmm", "V", "V"]
        plate = PlateSpec(
            channels=tuple(alabels[:6]),
            corners_m=plate_corners(rot, centre),
            origin_m=PLATE_ORIGIN,
        )
        events = [
            Event("Foot Off", "Left", 0.31),
            Event("Foot Strike", "Right", 0.12),
            Event("Foot Strike", "Left", 0.05),
        ]
        path = tmp_path / f"synth_{units}.c3d"
        write_c3d(
            path,
            markers=markers,
            marker_labels=labels,
            rate_hz=rate,
            point_units=units,
            analogs=analogs,
            analog_labels=alabels,
            analog_units=aunits,
            analog_ratio=ratio,
            plates=[plate],
            events=events,
            subject=Subject(name="Synth", mass_kg=71.5, height_m=1.78),
        )
        truth = dict(
            time=t,
            markers=markers,
            labels=labels,
            analogs=analogs,
            analog_labels=alabels,
            analog_units=aunits,
            force=force,
            cop=cop,
            tz=tz,
            centre=centre,
            rot=rot,
            events=events,
            rate=rate,
            ratio=ratio,
            up=up,
        )
        return path, truth

    return make
