"""msk.fes.simulate and msk.fes.stimulation against independent references."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from msk.exceptions import ConfigError, ModelError
from msk.fes.identify import calcium_gain, force_length_factor
from msk.fes.model import SEED001_SUBJECT, TABLE3
from msk.fes.simulate import simulate
from msk.fes.stimulation import Stimulation, calcium_pi, pulse_train, sample_on_grid


def test_calcium_pi_eq12_shape() -> None:
    t = np.array([0.0, 0.01, 0.029, 0.035, 0.045, 0.051, 0.2])
    pi = calcium_pi(t, np.array([0.0]), 0.030, 0.020, left=False)
    assert pi[:3] == pytest.approx([1, 1, 1])
    assert pi[3] == pytest.approx(0.75)  # 5 ms into the 20 ms transition
    assert pi[4] == pytest.approx(0.25)
    assert pi[5:] == pytest.approx([0, 0])
    # a new pulse restarts the contraction phase; zero-level pulses are no pulses
    st = Stimulation(np.array([0.0, 0.05, 0.1]), np.array([1e-4, 0.0, 1e-4]))
    w = sample_on_grid(st, 60, 2e-3, 0.030, 0.020)
    assert w[1, 25] == pytest.approx(0.0)  # t = 50 ms: previous transition ended, no pulse
    assert w[1, 50] == pytest.approx(1.0)  # t = 100 ms: pulse


def test_rk4_matches_cvodes() -> None:
    s = TABLE3["S3L"]
    st = pulse_train(350e-6, duration=0.6, t_start=0.1)
    a = simulate(s, st, duration=0.8)
    b = simulate(s, st, duration=0.8, method="cvodes")
    assert np.max(np.abs(a.theta_r - b.theta_r)) < 1e-4  # rad
    assert np.max(np.abs(a.F_c - b.F_c)) < 1e-3 * np.max(b.F_c)


def test_passive_pendulum_matches_scipy() -> None:
    s = TABLE3["S6R"]
    x0 = np.array([0.6, 0.0, 0.0, 0.0])
    empty = Stimulation(np.zeros(0), np.zeros(0))
    tr = simulate(s, empty, duration=3.0, x0=x0)
    k = s.knee

    def f(_t: float, y: np.ndarray) -> list[float]:
        return [y[1], -(k.B * y[1] + k.K * np.sin(y[0])) / k.J]

    ref = solve_ivp(f, (0, 3.0), x0[:2], t_eval=tr.time, rtol=1e-10, atol=1e-12)
    assert np.max(np.abs(ref.y[0] - tr.theta_r)) < 1e-6
    assert np.all(tr.F_c == 0.0)


def test_isometric_steady_state_is_kappa_alpha_fcm_fl() -> None:
    """Steady isometric force = κ α F_cm Fl(ε_c), κ from the calcium ODE alone (Eq. 1, 11)."""
    s = TABLE3["S10R"]
    angle = np.deg2rad(60)
    st = pulse_train(380e-6, duration=4.0)
    tr = simulate(s, st, duration=4.0, isometric_angle=angle)
    f_ss = tr.F_c[-500:].mean()
    fl = force_length_factor(s, angle, f_ss)
    kappa = calcium_gain(s.calcium, 20.0)
    assert kappa == pytest.approx(0.922, abs=2e-3)
    assert f_ss == pytest.approx(kappa * s.recruitment(380e-6) * s.muscle.F_cm * fl, rel=3e-3)
    assert np.all(tr.theta_r == tr.theta_r[0])


def test_fused_stimulation_seed001() -> None:
    assert calcium_gain(SEED001_SUBJECT.calcium, 31.25) == pytest.approx(1.0)
    st = pulse_train(3e-3, duration=1.0, frequency_hz=31.25, kind="current")
    tr = simulate(SEED001_SUBJECT, st, duration=1.5)
    assert np.rad2deg(tr.theta_r.max()) > 10  # the stimulated quadriceps extends the knee
    with pytest.raises(ModelError, match="current"):
        simulate(TABLE3["S3L"], st)


def test_bad_stimulation_is_typed() -> None:
    with pytest.raises(ConfigError):
        Stimulation(np.array([0.1, 0.0]), np.array([1e-4, 1e-4]))
    with pytest.raises(ConfigError):
        Stimulation(np.array([0.0]), np.array([-1.0]))
