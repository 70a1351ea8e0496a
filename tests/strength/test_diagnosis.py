"""msk.strength.diagnosis: each group's status judged on its own rows, with a reason."""

from __future__ import annotations

import numpy as np
import pytest

from msk.datasets.strength import LEG_GROUPS, gait_trial, synthetic_leg
from msk.muscles.activation import emg_to_activation
from msk.muscles.hill import rigid_tendon_state
from msk.strength import StrengthIdentifier, diagnose
from msk.strength.diagnosis import group_r2

# the simulation's activation dynamics (known to the identifier)
ACT = {
    "gamma1": -0.5,
    "gamma2": -0.5,
    "shape_factor": -1.0,
    "delay_samples": 4,
    "form": "exponential",
}


@pytest.fixture(scope="module")
def leg():
    return synthetic_leg(0)


def _fit(leg, groups, tr):
    a = emg_to_activation(tr.emg, **ACT)
    s = rigid_tendon_state(leg.params, tr.muscle_tendon_length, tr.lengthening_velocity)
    return (
        StrengthIdentifier(groups, leg.params, n_bootstrap=100, random_state=0)
        .fit(tr.jacobian, a, tr.tau, s, windows=tr.cycle, coordinate_names=tr.coordinate_names)
        .profile_
    )


def test_an_unexcited_group_is_never_identified_and_says_why(leg):
    """Hip flexors silent (baseline EMG only) in 12 noisy gait cycles: ``not determined``,
    "never excited"; the excited groups identified, with their own rows' r²."""
    tr = gait_trial(leg, n_cycles=12, seed=1, silent_groups=("hip_flexors",))
    p = _fit(leg, leg.groups, tr)
    d = {x.group: x for x in diagnose(p)}
    assert d["hip_flexors"].status == "not determined"
    assert d["hip_flexors"].reason.startswith("never excited"), d["hip_flexors"].reason
    assert p.statuses()[p.group_names.index("hip_flexors")] == "not determined"
    for g in ("knee_extensors", "knee_flexors", "plantar_flexors"):
        assert d[g].status == "identified", d[g].reason
        assert d[g].reason.startswith("identified")
    # the plantar flexors' own rows are the knee and ankle, not the hip
    pf = d["plantar_flexors"]
    assert pf.coordinates == ("knee_flexion", "ankle_dorsiflexion")
    j = [p.coordinate_names.index(c) for c in pf.coordinates]
    assert pf.r2 == pytest.approx(float(np.mean(p.r2_per_coordinate[j])))
    assert pf.r2 == group_r2(p, p.group_names.index("plantar_flexors"))


def test_confounded_groups_are_named_and_never_identified(leg):
    """The knee extensors' electrode split into VL and VM+VI (one EMG, near-proportional
    knee moment columns): neither is identified, each names the other as confounded, and a
    factor on a bound reads "at bound"."""
    groups = {k: v for k, v in LEG_GROUPS.items() if k != "knee_extensors"}
    groups |= {"vl": ("VL",), "vm_vi": ("VM", "VI"), "rf": ("RF",)}
    p = _fit(leg, groups, gait_trial(leg, n_cycles=12, seed=2))
    d = {x.group: x for x in diagnose(p)}
    for g, other in (("vl", "vm_vi"), ("vm_vi", "vl")):
        assert d[g].status != "identified", d[g].reason
        assert other in d[g].confounded_with
        assert f"confounded with {other}" in d[g].reason
        assert abs(d[g].correlation[d[g].confounded_with.index(other)]) >= 0.9
    for x in d.values():
        if x.status == "at bound":
            assert x.reason.startswith("at bound: the data ask for a factor")
    # groups with their own electrode are not called confounded
    assert d["knee_flexors"].confounded_with == ()


def test_a_group_at_a_bound_is_at_bound_whatever_its_own_fit(leg):
    """Knee extensors simulated at 3× generic (outside the 0.5–2 bounds): their factor sits on
    the upper bound — ``at bound`` with the reason, never ``identified``."""
    f = {g: 1.0 for g in LEG_GROUPS} | {"knee_extensors": 3.0}
    p = _fit(leg, leg.groups, gait_trial(leg, n_cycles=12, seed=3, factors=f))
    d = {x.group: x for x in diagnose(p)}
    ke = d["knee_extensors"]
    assert ke.status == "at bound", ke.reason
    assert "above the plausible range" in ke.reason
