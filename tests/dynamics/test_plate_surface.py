"""Steps on force plates: the surface from the feet standing on it, a plate's unloaded offset,
a plate left out (msk.dynamics.plate_surface)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from msk.datasets.models import two_leg_model
from msk.datasets.trials import make_trial
from msk.dynamics.loads import PlateWrench, external_loads
from msk.dynamics.plate_surface import (
    plate_baseline,
    prepared_plates,
    without_baseline,
)
from msk.exceptions import ForcePlateError
from msk.kinematics.ik import kinematics_from_coordinates

MODEL = two_leg_model()
TRIAL = make_trial(MODEL, duration_s=1.0, rate_hz=100.0, analog_ratio=10)
KIN = dataclasses.replace(
    kinematics_from_coordinates(TRIAL.time, TRIAL.q, MODEL.coordinate_names, cutoff_hz=None),
    v=TRIAL.v,
    a=TRIAL.a,
)
UP = np.array([0.0, 1.0, 0.0])


def _wrench(pl: PlateWrench, force: np.ndarray, moment: np.ndarray, h: float) -> PlateWrench:
    """The plate recording the wrench (force, moment about the origin) with its COP on the plane
    at height ``h`` (as a plate computes it on its own top)."""
    fv = force @ UP
    with np.errstate(divide="ignore", invalid="ignore"):
        m_h = moment - np.cross(h * UP, force)
        cop = h * UP + np.cross(UP, m_h) / fv[:, None]
        free = moment - np.cross(cop, force)
    bad = ~np.isfinite(cop).all(axis=1)
    cop[bad], free[bad] = np.nan, 0.0
    return dataclasses.replace(pl, force=force, cop=cop, free_moment=free)


def _under_a_step(pl: PlateWrench, step_m: float) -> PlateWrench:
    """``pl`` with a step of ``step_m`` built on it: the same wrench, the plate's top (its
    corners and the COP it records) ``step_m`` below the surface the foot stands on."""
    assert pl.corners is not None
    low = dataclasses.replace(pl, corners=pl.corners - step_m * UP)
    h = float(np.mean(low.corners @ UP))
    return _wrench(low, pl.force, pl.moment_about_origin(), h)


def test_a_step_on_a_plate_takes_its_surface_from_the_foot_standing_on_it():
    """A 0.40 m step stands on plate1 (its corners and COP at the floor, 0.40 m below the foot):
    the surface is found within 3 cm of the truth (the foot's sole height less the clearance
    measured on plate2, whose corners are its surface: this toy trial's lowest foot points move
    ±6 cm while loaded, their medians 2.4 cm apart between the feet), the contact is assigned
    to the foot as without the step and the wrench is the same; without the inference the
    contact is left unassigned; a surface given in the config is used as given."""
    truth = float(np.mean(TRIAL.plates[0].corners @ UP))
    stepped = [_under_a_step(TRIAL.plates[0], 0.40), TRIAL.plates[1]]
    ref = external_loads(MODEL, KIN, TRIAL.plates)
    got = external_loads(MODEL, KIN, stepped)
    surf = {s["plate"]: s for s in got.metadata["surfaces"]}
    assert surf["plate1"]["source"] == "feet" and surf["plate2"]["source"] == "corners"
    assert surf["plate1"]["height_m"] == pytest.approx(truth, abs=0.03)
    assert surf["plate1"]["corners_height_m"] == pytest.approx(truth - 0.40, abs=1e-9)
    assert got.metadata["surface_heights_m"]["plate1"] == surf["plate1"]["height_m"]
    assert [(a.plate, a.body) for a in got.assignments] == [
        (a.plate, a.body) for a in ref.assignments
    ]
    np.testing.assert_allclose(got.force, ref.force, atol=1e-6)
    np.testing.assert_allclose(got.moment, ref.moment, atol=1e-6)
    assert not got.unassigned_contact.any()
    # the COP on the step's surface, not on the plate's top
    b = got.body_index("foot_r")
    assert np.nanmedian(got.point[:, b] @ UP) == pytest.approx(truth, abs=0.03)
    with pytest.raises(ForcePlateError, match="no foot over the plate"):
        external_loads(MODEL, KIN, stepped, infer_surface=False, on_unassigned="raise")
    given = external_loads(MODEL, KIN, stepped, surface_heights={"plate1": 0.38})
    g = {s["plate"]: s for s in given.metadata["surfaces"]}["plate1"]
    assert g["source"] == "config" and g["height_m"] == pytest.approx(truth - 0.02, abs=1e-9)
    assert not given.unassigned_contact.any()


def test_a_plate_above_the_feet_is_not_lowered_to_them():
    """A plate whose corners lie 0.5 m above the feet (wrong corners, not a step) keeps its
    corners' surface and its contact stays unassigned (the inference only raises a surface)."""
    pl = TRIAL.plates[0]
    high = _under_a_step(pl, -0.5)
    got = external_loads(MODEL, KIN, [high])
    assert got.metadata["surfaces"][0]["source"] == "corners"
    assert got.unassigned_contact.any()


def _quiet(pl: PlateWrench, t0: float, t1: float) -> PlateWrench:
    off = (pl.time > t0) & (pl.time < t1)
    f, c, m = pl.force.copy(), pl.cop.copy(), pl.free_moment.copy()
    f[off], c[off], m[off] = 0.0, np.nan, 0.0
    return dataclasses.replace(pl, force=f, cop=c, free_moment=m)


def _offset(pl: PlateWrench, f0: np.ndarray, noise_n: float = 1.0) -> PlateWrench:
    """``pl`` reading ``f0`` more at its centre (an amplifier not zeroed), with noise."""
    assert pl.corners is not None
    centre = pl.corners.mean(axis=0)
    rng = np.random.default_rng(3)
    f = pl.force + f0 + rng.normal(0.0, noise_n, pl.force.shape)
    m = pl.moment_about_origin() + np.cross(centre, f0)
    return _wrench(pl, f, m, float(centre @ UP))


def test_a_plate_offset_is_found_in_its_quiet_frames_and_removed():
    """A 30 N (and 4 N sideways) offset under 1 N noise on a plate unloaded from 0.3 to 0.7 s is
    found within 1 N and removed: the assignment and the wrench are those of the plate without
    offset (to the noise); a 15 N offset (under the 20 N contact threshold) and a plate loaded
    throughout are left alone; an ignored plate is left out."""
    clean = _quiet(TRIAL.plates[1], 0.3, 0.7)
    f0 = np.array([4.0, 30.0, 0.0])
    dirty = _offset(clean, f0)
    b = plate_baseline(dirty, UP)
    assert b is not None and b.plate == "plate2" and b.quiet_s >= 0.3
    np.testing.assert_allclose(b.force_n, f0, atol=1.0)
    fixed = without_baseline(dirty, b, UP)
    loaded = np.abs(clean.force[:, 1]) > 50.0
    np.testing.assert_allclose(fixed.force[loaded], clean.force[loaded], atol=5.0)
    np.testing.assert_allclose(
        fixed.moment_about_origin()[loaded], clean.moment_about_origin()[loaded], atol=2.0
    )
    found: list = []
    plates = list(prepared_plates([TRIAL.plates[0], dirty], UP, found=found))
    assert [x.plate for x in found] == ["plate2"]
    ref = external_loads(MODEL, KIN, [TRIAL.plates[0], clean])
    got = external_loads(MODEL, KIN, plates)
    assert [(a.plate, a.body) for a in got.assignments] == [
        (a.plate, a.body) for a in ref.assignments
    ]
    np.testing.assert_allclose(got.force, ref.force, atol=5.0)
    assert plate_baseline(_offset(clean, np.array([0.0, 15.0, 0.0])), UP) is None
    assert plate_baseline(TRIAL.plates[1], UP) is None  # loaded throughout: no quiet frames
    kept = list(prepared_plates([TRIAL.plates[0], dirty], UP, ignore=("plate2",)))
    assert [p.name for p in kept] == ["plate1"]
