"""Cylinder wrapping ("via cylinders", seed 004 §2.1; OpenSim WrapCylinder): the path is the
geodesic — checked against a direct numerical minimisation over the tangent points."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize

from msk.exceptions import ModelError
from msk.muscles.geometry import wrap_cylinder

R = 0.03


def _path_length(params, a, b, r, sense):
    """a → T1 → helix (sense = ±1 around z) → T2 → b, T = (r cos φ, r sin φ, z)."""
    p1, z1, p2, z2 = params
    t1 = np.array([r * np.cos(p1), r * np.sin(p1), z1])
    t2 = np.array([r * np.cos(p2), r * np.sin(p2), z2])
    dphi = np.mod(sense * (p2 - p1), 2 * np.pi)
    return np.linalg.norm(t1 - a) + np.hypot(r * dphi, z2 - z1) + np.linalg.norm(b - t2)


def _segment_clearance(p, q):
    """Smallest distance to the z axis along the segment p–q, minus R (≥ 0: outside)."""
    d = q[:2] - p[:2]
    t = np.clip(-(p[:2] @ d) / max(d @ d, 1e-300), 0.0, 1.0)
    return np.linalg.norm(p[:2] + t * d) - R


def _numerical_shortest(a, b, r, t1, t2):
    """Minimise the length over the tangent points (φ1, z1, φ2, z2), both senses, subject to
    the straight parts staying outside the cylinder (SLSQP from perturbed starts)."""

    def point(phi, z):
        return np.array([r * np.cos(phi), r * np.sin(phi), z])

    cons = [
        {"type": "ineq", "fun": lambda x: _segment_clearance(a, point(x[0], x[1])) + 1e-12},
        {"type": "ineq", "fun": lambda x: _segment_clearance(point(x[2], x[3]), b) + 1e-12},
    ]
    rng = np.random.default_rng(1)
    best = np.inf
    for sense in (1.0, -1.0):
        for _ in range(3):
            x0 = np.array(
                [np.arctan2(t1[1], t1[0]), t1[2], np.arctan2(t2[1], t2[0]), t2[2]]
            ) + rng.normal(scale=[0.2, 0.01, 0.2, 0.01])
            res = minimize(
                _path_length, x0, args=(a, b, r, sense), method="SLSQP", constraints=cons,
                options={"ftol": 1e-15, "maxiter": 500},
            )  # fmt: skip
            if res.success and min(c["fun"](res.x) for c in cons) > -1e-9:
                best = min(best, res.fun)
    return best


def test_geodesic_equals_numerical_minimum_and_is_tangent():
    rng = np.random.default_rng(0)
    n_wrapped = 0
    for _ in range(12):
        # points on opposite sides of the cylinder so that the straight line crosses it
        ang = rng.uniform(0, 2 * np.pi)
        a = np.array([0.1 * np.cos(ang), 0.1 * np.sin(ang), rng.uniform(-0.05, 0.05)])
        b = np.array(
            [-0.08 * np.cos(ang + 0.2), -0.08 * np.sin(ang + 0.2), rng.uniform(-0.05, 0.05)]
        )
        wraps, t1, t2, arc, mand = wrap_cylinder(a, b, R)
        if not wraps:
            continue
        n_wrapped += 1
        assert mand
        total = np.linalg.norm(t1 - a) + arc + np.linalg.norm(b - t2)
        assert total == pytest.approx(_numerical_shortest(a, b, R, t1, t2), abs=1e-8)
        assert total > np.linalg.norm(b - a)
        for t, p in ((t1, a), (t2, b)):
            assert np.hypot(t[0], t[1]) == pytest.approx(R, abs=1e-14)
            d = (t - p) / np.linalg.norm(t - p)
            radial = np.array([t[0], t[1], 0.0]) / R
            assert abs(d @ radial) < 1e-12  # the straight part meets the surface tangentially
    assert n_wrapped >= 8


@settings(max_examples=60, deadline=None)
@given(
    st.floats(0.0, 2 * np.pi), st.floats(0.035, 0.2), st.floats(-0.1, 0.1),
    st.floats(0.0, 2 * np.pi), st.floats(0.035, 0.2), st.floats(-0.1, 0.1),
)  # fmt: skip
def test_wrapped_path_is_never_shorter_than_the_straight_line(pa, ra, za, pb, rb, zb):
    a = np.array([ra * np.cos(pa), ra * np.sin(pa), za])
    b = np.array([rb * np.cos(pb), rb * np.sin(pb), zb])
    for quadrant in ("all", "+x", "-y"):
        wraps, t1, t2, arc, _ = wrap_cylinder(a, b, R, quadrant=quadrant)
        straight = np.linalg.norm(b - a)
        total = np.linalg.norm(t1 - a) + arc + np.linalg.norm(b - t2) if wraps else straight
        assert total >= straight - 1e-12
        if not wraps:
            assert arc == 0.0


def test_unconstrained_cylinder_wraps_only_when_crossed():
    a = np.array([0.1, 0.05, 0.0])
    b = np.array([-0.1, 0.05, 0.02])  # passes 5 cm from the axis: misses a 3 cm cylinder
    wraps, t1, _, arc, _ = wrap_cylinder(a, b, R)
    assert not wraps and arc == 0.0
    np.testing.assert_allclose(t1, b)
    wraps, _, _, arc, mand = wrap_cylinder(a, b * [1, -1, 1], R)  # now through the axis
    assert wraps and mand and arc > 0
    # a segment ending before it reaches the cylinder does not wrap
    assert not wrap_cylinder(a, np.array([0.05, 0.0, 0.0]), R)[0]


def test_quadrant_forces_the_path_around_the_active_side():
    # both points on the -x side, line far from the cylinder: "+x" forces a wrap around +x
    a = np.array([-0.05, 0.1, 0.0])
    b = np.array([-0.05, -0.1, 0.0])
    assert not wrap_cylinder(a, b, R)[0]
    wraps, t1, t2, _, mand = wrap_cylinder(a, b, R, quadrant="+x")
    assert wraps and not mand
    mid = 0.5 * (np.arctan2(t1[1], t1[0]) + np.arctan2(t2[1], t2[0]))
    assert np.cos(mid) > 0.9  # the arc passes through +x
    # crossing line: "-x" keeps the wrap on the -x side, "+x" on the +x side
    a = np.array([0.0, 0.1, 0.0])
    b = np.array([0.001, -0.1, 0.0])
    for q, sign in (("-x", -1), ("+x", 1)):
        wraps, t1, t2, _, _ = wrap_cylinder(a, b, R, quadrant=q)
        assert wraps
        assert sign * (t1[0] + t2[0]) > 0


def test_no_wrap_inside_the_radius_or_beyond_the_cylinder_ends():
    assert not wrap_cylinder([0.01, 0.0, 0.0], [-0.1, 0.0, 0.0], R)[0]
    a, b = np.array([0.1, 0.0, 0.2]), np.array([-0.1, 0.0, 0.25])
    assert wrap_cylinder(a, b, R)[0]
    assert not wrap_cylinder(a, b, R, length=0.1)[0]  # tangent points at z ≈ 0.22 > 0.05
    assert wrap_cylinder(a, b, R, length=0.6)[0]


def test_vectorised_over_leading_axes_and_bad_quadrant():
    rng = np.random.default_rng(3)
    a = rng.normal(scale=0.1, size=(4, 5, 3))
    b = rng.normal(scale=0.1, size=(4, 5, 3))
    wraps, t1, _, arc, _ = wrap_cylinder(a, b, R, quadrant="-y")
    assert wraps.shape == (4, 5) and t1.shape == (4, 5, 3) and arc.shape == (4, 5)
    one = wrap_cylinder(a[2, 3], b[2, 3], R, quadrant="-y")
    assert one[0] == wraps[2, 3] and one[3] == pytest.approx(arc[2, 3])
    with pytest.raises(ModelError, match="quadrant 'z'"):
        wrap_cylinder(a, b, R, quadrant="z")


def test_several_cylinders_at_once_equal_one_at_a_time():
    """The wraps of one round (several cylinders, quadrants and lengths in one array call) give
    what each cylinder gives alone."""
    from msk.muscles.geometry import _QUADRANTS, _wrap_cylinder

    rng = np.random.default_rng(8)
    specs = [(0.02, "all", 0.1), (0.03, "-x", np.inf), (0.025, "+y", 0.08), (0.015, "-y", 0.2),
             (0.02, "x", 0.05)]  # fmt: skip
    a = rng.normal(0.0, 0.05, (len(specs), 7, 3))
    b = rng.normal(0.0, 0.05, (len(specs), 7, 3))
    shape = (len(specs), 1)
    r = np.array([s[0] for s in specs]).reshape(shape)
    axis = np.array([_QUADRANTS[s[1]][0] for s in specs]).reshape(shape)
    sign = np.array([_QUADRANTS[s[1]][1] for s in specs]).reshape(shape)
    half = 0.5 * np.array([s[2] for s in specs]).reshape(shape)
    together = _wrap_cylinder(a, b, r, axis, sign, half)
    assert together[0].any() and not together[0].all()
    for k, (radius, quadrant, length) in enumerate(specs):
        alone = wrap_cylinder(a[k], b[k], radius, quadrant=quadrant, length=length)
        for x, y in zip(together, alone):
            np.testing.assert_array_equal(x[k], y)


# --------------------------------------------------------------------------------------------
# two overlapping cylinders on one path: the wraps can alternate between two paths (2-cycle)
# --------------------------------------------------------------------------------------------
def _overlapping_cylinders_model():
    """The test leg with a gastrocnemius over a condyle cylinder (femur, unconstrained) and a
    shank cylinder (tibia, quadrant +x) that overlap near the knee: at some poses a tangent
    point of one wrap lies inside the other cylinder and the wrap rules have no consistent
    path (as Rajagopal 2016's gastrocnemii over the subject01 walk)."""
    from msk.datasets.models import leg_model
    from msk.muscles.path import Muscle, PathPoint, PathWrap, WrapObject

    condyles = WrapObject(
        "condyles", "femur", "cylinder", np.array([-0.005, -0.41, 0.0]),
        np.array([0.05, 0.02, 0.0]), radius=0.025, length=0.1,
    )  # fmt: skip
    shank = WrapObject(
        "shank", "tibia", "cylinder", np.array([-0.02, -0.07, 0.0]), np.zeros(3),
        radius=0.045, length=0.1, quadrant="+x",
    )  # fmt: skip
    points = (
        PathPoint("o", "femur", np.array([-0.019, -0.393, -0.024])),
        PathPoint("v", "femur", np.array([-0.030, -0.402, -0.026])),
        PathPoint("i", "foot", np.array([-0.05, 0.03, -0.005])),
    )
    gas = Muscle("gas", points, 1000.0, 0.1, 0.2, 0.1, 10.0,
                 wraps=(PathWrap("condyles"), PathWrap("shank")))  # fmt: skip
    one = [Muscle(f"gas_{w}", points, 1000.0, 0.1, 0.2, 0.1, 10.0, wraps=(PathWrap(w),))
           for w in ("condyles", "shank")]  # fmt: skip
    return leg_model().with_muscles([gas, *one]).with_metadata(wrap_objects=[condyles, shank])


def _poses(model, n, seed):
    rng = np.random.default_rng(seed)
    th = rng.uniform(-0.6, 0.6, (n, model.n_coords))
    th[:, :3] = rng.uniform(-0.5, 0.5, (n, 3))
    th[:, model.coordinate_index("knee_angle")] = rng.uniform(-2.0, 0.1, n)
    return th


def test_two_wrap_cycles_resolve_to_a_fixed_point_with_an_exact_jacobian(monkeypatch):
    """Where the two wraps alternate between two paths, the path returned is the fixed point
    of one wrap alone (one wrap position off, iterated to convergence): its length is that of
    the same muscle with that one wrap, it does not depend on the pass limit's parity nor on
    the extrapolation, and the analytic Jacobian equals central differences."""
    from msk.muscles import geometry
    from msk.muscles.geometry import GeometryPlan

    model = _overlapping_cylinders_model()
    th = _poses(model, 120, seed=1)
    plan = GeometryPlan(model)
    seen = []
    orig = GeometryPlan._resolve_cycles

    def spy(self, st, rot, trans, wr, cycled):
        seen.append(np.flatnonzero(cycled[0]))
        return orig(self, st, rot, trans, wr, cycled)

    monkeypatch.setattr(GeometryPlan, "_resolve_cycles", spy)
    geo = plan.evaluate(th)
    monkeypatch.setattr(GeometryPlan, "_resolve_cycles", orig)
    assert len(seen) == 1 and seen[0].size >= 5  # the 2-cycle is met
    cyc = seen[0]
    lengths = geo.lengths
    # the single-wrap paths; at a cycle frame the two-wrap path is one of them
    single = lengths[:, 1:]
    assert np.all(np.min(np.abs(single[cyc] - lengths[cyc, :1]), axis=1) < 1e-12)
    # independent of the pass limit's parity and of Aitken's extrapolation
    monkeypatch.setattr(geometry, "_MAX_WRAP_PASSES", geometry._MAX_WRAP_PASSES + 1)
    np.testing.assert_allclose(plan.evaluate(th).lengths, lengths, rtol=0, atol=1e-13)
    monkeypatch.setattr(geometry, "_AITKEN", False)
    plain = plan.evaluate(th)
    np.testing.assert_allclose(plain.lengths, lengths, rtol=0, atol=1e-13)
    np.testing.assert_allclose(plain.jacobian, geo.jacobian, rtol=0, atol=1e-10)
    monkeypatch.undo()
    # envelope theorem at the fixed point: analytic Jacobian = central differences
    h = 1e-6
    fd = np.empty_like(geo.jacobian[cyc])
    for i in range(model.n_coords):
        e = np.zeros(model.n_coords)
        e[i] = h
        fd[..., i] = (plan.evaluate(th[cyc] + e).lengths - plan.evaluate(th[cyc] - e).lengths) / (
            2 * h
        )
    err = np.linalg.norm(geo.jacobian[cyc] - fd, axis=-1)
    assert np.all(err < 1e-6 * np.maximum(np.linalg.norm(fd, axis=-1), 1e-3))
