"""take(frames) on every time-axis result equals slicing it field by field.

Each result is built with N frames (6–9) and every field that is not per-frame shorter than 6
on its first axis, so "a field whose first axis has N entries" is exactly "a per-frame field":
the expectation below is derived from the values, not from the class's own list of per-frame
fields.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msk.contact.knee import CompartmentMap, KneeContact, MedialLateral, PlateauGeometry
from msk.dynamics.inverse import JointReaction, JointTorques
from msk.dynamics.loads import ContactFlag, ExternalLoads
from msk.exceptions import ShapeMismatchError
from msk.kinematics.ik import Kinematics
from msk.muscles.contraction import ContractionState
from msk.muscles.emg import ChannelQuality, EmgEnvelopes
from msk.muscles.geometry import MuscleGeometry
from msk.muscles.hill import EquilibriumState, RigidTendonState
from msk.timeseries import FrameAxis, frame_indices

M = ("m1", "m2")  # two muscles / channels / bodies


def _kinematics(n: int, r: np.random.Generator) -> Kinematics:
    c = ("a", "b", "c")
    return Kinematics(
        time=r.random(n), q=r.random((n, 3)), v=r.random((n, 3)), a=r.random((n, 3)),
        coordinate_names=c, q_raw=r.random((n, 3)), status=r.integers(0, 3, n),
        marker_rms=r.random(n), marker_max=r.random(n),
        marker_max_name=tuple(f"mk{i}" for i in r.integers(0, 4, n)),
        marker_errors=r.random((n, 2)), marker_names=M, n_markers_used=r.integers(0, 9, n),
        iterations=r.integers(0, 9, n), cutoff_hz=6.0, solve_time_s=0.1,
        metadata={"note": r.random(3)},
    )  # fmt: skip


def _loads(n: int, r: np.random.Generator) -> ExternalLoads:
    flag = ContactFlag("plate1", "shared", 0.1, 0.2, M)
    return ExternalLoads(
        time=r.random(n), bodies=M, force=r.random((n, 2, 3)), moment=r.random((n, 2, 3)),
        point=r.random((n, 2, 3)), flags=(flag,), shared_contact=r.random(n) > 0.5,
        unassigned_contact=None, metadata={"rotation": r.random((3, 3))},
    )  # fmt: skip


def _torques(n: int, r: np.random.Generator) -> JointTorques:
    return JointTorques(
        time=r.random(n), tau=r.random((n, 3)), coordinate_names=("a", "b", "c"),
        residual_force=r.random((n, 3)), residual_moment=r.random((n, 3)),
        residual_point=r.random((n, 3)), root_coordinates=("a",), variant="full",
        tau_pin=r.random((n, 4)),
    )  # fmt: skip


def _reaction(n: int, r: np.random.Generator) -> JointReaction:
    return JointReaction(r.random(n), "knee_r", "tibia_r", r.random((n, 3)), r.random((n, 3)))


def _geometry(n: int, r: np.random.Generator) -> MuscleGeometry:
    return MuscleGeometry(
        M, ("a", "b", "c"), lengths=r.random((n, 2)), jacobian=r.random((n, 2, 3)),
        velocities=r.random((n, 2)) if r.random() > 0.3 else None,
        distal_wrenches={"knee_r": r.random((n, 2, 6)), "knee_l": r.random((n, 2, 6))},
    )  # fmt: skip


def _states(cls: Any, **extra: Any) -> Callable[[int, np.random.Generator], Any]:
    def make(n: int, r: np.random.Generator) -> Any:
        arrays = {
            f.name: r.random((n, 2))
            for f in dataclasses.fields(cls)
            if f.name not in ("names", "time", *extra)
        }
        time = {"time": r.random(n)} if "time" in {f.name for f in dataclasses.fields(cls)} else {}
        return cls(names=M, **time, **arrays, **extra)

    return make


def _emg(n: int, r: np.random.Generator) -> EmgEnvelopes:
    q = ChannelQuality(M, r.random(2) > 0.5, r.random(2) > 0.5, *(r.random(2) for _ in range(6)))
    return EmgEnvelopes(
        time=r.random(n), envelopes=r.random((n, 2)), muscle_names=M, muscle_sources=M,
        channel_labels=M, normalisation_source=("mvc", "session_peak"),
        normalisation_value=r.random(2), quality=q, delay_s=r.random(2), warnings=("w",),
    )  # fmt: skip


def _contact(n: int, r: np.random.Generator) -> KneeContact:
    return KneeContact(
        r.random(n), "knee_r", "tibia_r", r.random((n, 3)), r.random((n, 3)), r.random((n, 5)),
        700.0, True,
    )  # fmt: skip


def _medial_lateral(n: int, r: np.random.Generator) -> MedialLateral:
    return MedialLateral(
        r.random(n), "knee_r", "right", r.random(n), r.random(n), r.random(n), r.random(n),
        PlateauGeometry(), 700.0,
    )  # fmt: skip


def _compartment_map(n: int, r: np.random.Generator) -> CompartmentMap:
    return CompartmentMap(
        r.random(n), "knee_r", "right", r.random((n, 2)), r.random((n, 2, 3)), PlateauGeometry(),
        ("a", "b", "c"),
    )  # fmt: skip


FACTORIES: dict[str, Callable[[int, np.random.Generator], Any]] = {
    "Kinematics": _kinematics,
    "ExternalLoads": _loads,
    "JointTorques": _torques,
    "JointReaction": _reaction,
    "MuscleGeometry": _geometry,
    "RigidTendonState": _states(RigidTendonState),
    "EquilibriumState": _states(EquilibriumState, iterations=3),
    "ContractionState": _states(ContractionState, substeps=2),
    "EmgEnvelopes": _emg,
    "KneeContact": _contact,
    "MedialLateral": _medial_lateral,
    "CompartmentMap": _compartment_map,
}


def _sliced(v: Any, n: int, idx: np.ndarray) -> Any:
    """What slicing a field by hand gives: per-frame when its first axis has n entries."""
    if isinstance(v, np.ndarray) and v.ndim >= 1 and v.shape[0] == n:
        return v[idx]
    if isinstance(v, tuple) and len(v) == n:
        return tuple(v[i] for i in idx)
    if isinstance(v, Mapping) and v and all(np.shape(x)[:1] == (n,) for x in v.values()):
        return {k: x[idx] for k, x in v.items()}
    return v


def _assert_same(a: Any, b: Any, where: str) -> None:
    if isinstance(b, np.ndarray):
        assert isinstance(a, np.ndarray) and a.dtype == b.dtype, where
        np.testing.assert_array_equal(a, b, err_msg=where, strict=True)
    elif isinstance(b, Mapping):
        assert set(a) == set(b), where
        for k in b:
            _assert_same(a[k], b[k], f"{where}[{k}]")
    else:
        assert a is b or a == b, where


def test_every_time_axis_result_is_covered():
    """Every FrameAxis subclass msk defines has a factory here (a new one must be added)."""
    assert {c.__name__ for c in FrameAxis.__subclasses__()} == set(FACTORIES)


@settings(max_examples=60, deadline=None)
@given(
    name=st.sampled_from(sorted(FACTORIES)),
    n=st.integers(6, 9),
    seed=st.integers(0, 2**32 - 1),
    data=st.data(),
)
def test_take_equals_slicing_field_by_field(name, n, seed, data):
    r = np.random.default_rng(seed)
    res = FACTORIES[name](n, r)
    assert res.frame_count == n
    if data.draw(st.booleans(), label="mask"):
        frames: Any = np.array(data.draw(st.lists(st.booleans(), min_size=n, max_size=n)))
        idx = np.flatnonzero(frames)
    else:
        frames = data.draw(st.lists(st.integers(-n, n - 1), max_size=2 * n))
        idx = np.asarray(frames, dtype=np.intp)
    out = res.take(frames)
    assert type(out) is type(res)
    for f in dataclasses.fields(res):
        _assert_same(
            getattr(out, f.name), _sliced(getattr(res, f.name), n, idx), f"{name}.{f.name}"
        )
    assert out.frame_count == idx.size


def test_take_composes_and_a_full_take_is_an_equal_copy():
    r = np.random.default_rng(0)
    kin = _kinematics(7, r)
    twice = kin.take([6, 5, 1, 0, 2]).take(np.array([True, False, True, False, True]))
    once = kin.take([6, 1, 2])
    for f in dataclasses.fields(kin):
        _assert_same(getattr(twice, f.name), getattr(once, f.name), f.name)
    full = kin.take(np.ones(7, dtype=bool))
    assert full.q is not kin.q
    np.testing.assert_array_equal(full.q, kin.q)


@pytest.mark.parametrize(
    ("frames", "match"),
    [
        (np.ones(4, dtype=bool), "mask has 4 entries, expected 5"),
        ([0, 5], "frame index 5 outside 0..4"),
        ([-6], "frame index -6 outside"),
        ([0.0, 1.0], "must be integers"),
        (np.zeros((2, 2), dtype=int), "must be 1-D"),
        (3, "must be 1-D"),
    ],
)
def test_bad_frames_raise_a_shape_error_naming_the_result(frames, match):
    kin = _kinematics(5, np.random.default_rng(1))
    with pytest.raises(ShapeMismatchError, match=match) as err:
        kin.take(frames)
    assert str(err.value).startswith("Kinematics:")
    np.testing.assert_array_equal(frame_indices([], 5), np.zeros(0, dtype=np.intp))
