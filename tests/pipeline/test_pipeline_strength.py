"""The strength stage's per-leg frames (:func:`msk.pipeline.strength.run`): where the foot of
the leg WITHOUT EMG stands off the plates, the EMG leg's frames are still identified from."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np

from msk.dynamics.inverse import coordinates_carrying
from msk.muscles.geometry import muscle_parameters
from msk.muscles.hill import rigid_tendon_state
from msk.pipeline import strength
from msk.strength import net_contribution
from tests.support.two_legs import muscled_two_legs, two_leg_trial

#: the right leg's EMG groups (one channel a muscle) and their true strength factors
TRUTH = {"vasti_r": 1.3, "hams_r": 0.8, "soleus_r": 1.15}


def _session(n: int = 300, seed: int = 0) -> Any:
    """A right leg whose three EMG muscles' strength is ``TRUTH``: its torques are Eq. 16's
    with those factors and every other muscle's passive force at generic strength, plus 1 %
    noise; the left foot is off the plates in frames 0–99 (its leg's torques NaN there)."""
    model = muscled_two_legs()
    kin, tq, geo = two_leg_trial(model, n)
    params = muscle_parameters(model)
    names = params.names
    t = kin.time
    act = np.zeros((n, len(names)))
    for k, m in enumerate(TRUTH):
        act[:, names.index(m)] = 0.3 + 0.25 * np.sin(2 * np.pi * (0.9 + 0.4 * k) * t + 2 * k)
    state = rigid_tendon_state(params, geo.lengths, geo.velocities)
    c = net_contribution(geo.jacobian, act, state, passive=True)  # (N, M, n) per N of F_iso
    s = np.array([TRUTH.get(m, 1.0) for m in names])
    tau_true = np.einsum("tmj,m->tj", c, params.max_isometric_force * s)
    rng = np.random.default_rng(seed)
    tau = tau_true + 0.01 * np.std(tau_true, axis=0) * rng.standard_normal(tau_true.shape)
    off = np.zeros(n, dtype=bool)
    off[:100] = True
    left = [c for c in coordinates_carrying(model, "foot_l") if c not in tq.root_coordinates]
    cols = [tq.coordinate_names.index(c) for c in left]
    tau[np.ix_(off, cols)] = np.nan
    unbalanced = np.zeros_like(tau, dtype=bool)
    unbalanced[np.ix_(off, cols)] = True
    usable = ~off  # every foot measured
    loads = SimpleNamespace(
        usable=usable, solvable=np.ones(n, dtype=bool),
        unbalanced_for=lambda names: unbalanced,
    )  # fmt: skip
    emg = SimpleNamespace(
        muscles=tuple(TRUTH), usable=np.ones(len(TRUTH), dtype=bool), sources=tuple(TRUTH),
        activation=np.stack([act[:, names.index(m)] for m in TRUTH], axis=1),
    )  # fmt: skip
    torques = type(tq)(**{**tq.__dict__, "tau": tau})
    return SimpleNamespace(
        model=SimpleNamespace(model=model), kinematics=kin, loads=loads,
        inverse_dynamics=SimpleNamespace(torques=torques), emg=emg, geometry=geo, off=off,
    )  # fmt: skip


#: the stage reads the session's EMG envelope cut-off (its gating windows' shortest length)
INPUTS = SimpleNamespace(cfg=SimpleNamespace(emg=SimpleNamespace(lowpass_hz=6.0)))


def _run(s: Any) -> Any:
    return strength.run(
        INPUTS, s.model, s.kinematics, s.loads, s.inverse_dynamics, s.emg, s.geometry
    )


def test_the_emg_leg_is_identified_on_its_own_frames() -> None:
    """The left foot off the plates in the first third: the right leg's strength is identified
    from every frame (its first frame is the trial's), each factor within 3 % of the truth;
    the left leg's coordinates on those frames are not regressed."""
    s = _session()
    out = _run(s)
    assert out.t0 == s.kinematics.time[0]
    prof = out.profile
    for g, name in enumerate(prof.group_names):
        assert abs(prof.factors[g] / TRUTH[name] - 1.0) < 0.03, (name, prof.factors[g])
    used = {c for c, r2 in zip(prof.coordinate_names, prof.r2_per_coordinate) if np.isfinite(r2)}
    assert used and all(c.endswith("_r") for c in used), used


def test_a_group_whose_leg_is_unbalanced_leaves_the_frame_out() -> None:
    """With the left leg's coordinates counted as crossed by an EMG group (a group on each
    leg), the frames whose left foot is off the plates are not used: the fit starts after
    them."""
    s = _session()
    left_hams = SimpleNamespace(
        muscles=(*s.emg.muscles, "hams_l"), usable=np.ones(4, dtype=bool),
        sources=(*s.emg.sources, "hams_l"),
        activation=np.column_stack([s.emg.activation, s.emg.activation[:, 1]]),
    )  # fmt: skip
    out = strength.run(
        INPUTS, s.model, s.kinematics, s.loads, s.inverse_dynamics, left_hams,
        s.geometry,
    )  # fmt: skip
    assert out.t0 == s.kinematics.time[np.flatnonzero(~s.off)[0]]
