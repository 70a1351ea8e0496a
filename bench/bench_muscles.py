"""Muscle-pipeline throughput: EMG envelopes, activation dynamics, rigid-tendon state, equilibrium.

Synthetic inputs of realistic size (gait2392's 92 muscles from the shared reference table when it
is present, otherwise 92 copies of a vastus-like muscle):

    .venv/bin/python bench/bench_muscles.py

Speed targets live here, never in tests.
"""

from __future__ import annotations

import platform

import numpy as np
from _timing import best_of

from msk.datasets.shared import reference_dir
from msk.muscles import (
    MuscleParameters,
    Thelen2003Curves,
    emg_to_activation,
    equilibrium,
    first_order_activation,
    process_emg,
    rigid_tendon_state,
)


def _params() -> MuscleParameters:
    table = reference_dir() / "opensim-models" / "gait2392_thelen2003muscle_muscles.csv"
    if table.is_file():
        return MuscleParameters.from_csv(table)
    m = 92
    return MuscleParameters(
        tuple(f"m{i}" for i in range(m)),
        np.full(m, 1800.0),
        np.full(m, 0.084),
        np.full(m, 0.157),
        np.full(m, 0.05),
    )


def main() -> None:
    rng = np.random.default_rng(0)
    p = _params()
    n = 1000
    phase = np.linspace(0, 2 * np.pi, n)[:, None]
    lmt = (p.tendon_slack_length + p.optimal_fiber_length) * (
        1 + 0.05 * np.sin(phase + rng.uniform(0, 6, p.n_muscles))
    )
    vmt = np.gradient(lmt, 0.01, axis=0)
    act = rng.uniform(0.02, 1.0, lmt.shape)
    curves = Thelen2003Curves.gait2392()

    rate, dur, c = 1200.0, 60.0, 16
    emg = rng.standard_normal((int(rate * dur), c)) * (
        1 + np.sin(np.arange(int(rate * dur)) / rate * 6)[:, None]
    )
    labels = [f"ch{i}" for i in range(c)]
    env = process_emg(emg, rate_hz=rate, labels=labels).envelopes

    rows = [
        (
            f"process_emg ({c} ch x {dur:.0f} s @ {rate:.0f} Hz)",
            best_of(lambda: process_emg(emg, rate_hz=rate, labels=labels))[0],
            env.shape[0],
        ),
        (
            f"first_order_activation thelen ({c} x {env.shape[0]})",
            best_of(lambda: first_order_activation(env, rate_hz=rate, form="thelen"))[0],
            env.shape[0],
        ),
        (
            f"emg_to_activation recursive ({c} x {env.shape[0]})",
            best_of(
                lambda: emg_to_activation(
                    env, gamma1=-0.9, gamma2=-0.9, shape_factor=-1.0, form="exponential"
                )
            )[0],
            env.shape[0],
        ),
        (
            f"rigid_tendon_state ({n} x {p.n_muscles})",
            best_of(lambda: rigid_tendon_state(p, lmt, vmt, curves=curves))[0],
            n,
        ),
        (
            f"equilibrium elastic tendon ({n} x {p.n_muscles})",
            best_of(lambda: equilibrium(p, lmt, act, curves=curves))[0],
            n,
        ),
    ]
    cpu = platform.processor() or platform.machine()
    print(f"# msk.muscles throughput ({cpu}, numpy {np.__version__})")
    for name, t, frames in rows:
        print(f"{name:55s} {1e3 * t:9.2f} ms  ({1e6 * t / frames:8.2f} us/frame)")


if __name__ == "__main__":
    main()
