"""The comparison stage compares a measured knee contact force with the like predicted
component and names it (msk.pipeline.comparison)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from msk.io.contact_force import MeasuredContact
from msk.pipeline import comparison
from msk.pipeline.records import ContactVariant, KneeContact

BW = 700.0


def _contact(side: str = "r") -> tuple[np.ndarray, KneeContact]:
    """A knee loaded 1–3 BW axially with a quarter of it as anterior shear and a tenth as
    medial–lateral shear, in the plateau frame (y proximal: the femur pushes the tibia down)."""
    t = np.linspace(0.0, 1.0, 101)
    axial = BW * (2.0 + np.sin(2 * np.pi * t))
    force = np.column_stack([0.25 * axial, -axial, 0.1 * axial * np.cos(3 * t)])
    sign = -1.0 if side == "l" else 1.0
    var = ContactVariant(force, np.linalg.norm(force, axis=1), 0.6 * axial, 0.4 * axial,
                         lateral_sign=sign)  # fmt: skip
    return t, KneeContact(f"knee_{side}", {"generic": var}, {}, None)


def test_components_of_a_tibial_contact_force():
    """axial = −F_y, AP shear = F_x, ML shear = F_z toward the lateral side (−F_z on a left
    knee, whose z points medially)."""
    _, kc = _contact("l")
    v = kc.variants["generic"]
    np.testing.assert_allclose(v.axial, -v.force[:, 1])
    np.testing.assert_allclose(v.shear_anterior, v.force[:, 0])
    np.testing.assert_allclose(v.shear_lateral, -v.force[:, 2])
    np.testing.assert_allclose(v.component("axial"), v.axial)
    np.testing.assert_allclose(v.component("magnitude"), v.total)
    assert (v.total > v.axial).all()


@pytest.mark.parametrize("component", ["axial", "magnitude"])
def test_a_measured_total_is_compared_with_the_like_component(component):
    """Load cells measuring the axial force (2 % noise) agree with the predicted axial force
    (RMSE ≈ the noise, r ≈ 1), not its magnitude, which is 3 % larger; a magnitude
    measurement is compared with the magnitude. The figure names the component."""
    t, kc = _contact()
    v = kc.variants["generic"]
    truth = v.axial if component == "axial" else v.total
    noisy = truth * (1.0 + 0.02 * np.random.default_rng(0).standard_normal(t.size))
    nan = np.full(t.size, np.nan)
    meas = MeasuredContact(noisy, nan, nan, time=t, source="test", component=component)
    kc = KneeContact(kc.joint, kc.variants, {}, meas)
    out = comparison.run(
        SimpleNamespace(sfx="_r", body_weight=BW),
        SimpleNamespace(usable=np.ones(t.size, bool)),
        SimpleNamespace(identified=None),
        kc,
        None,
        SimpleNamespace(measured_contact={"total": noisy}),
    )
    fig = out["knee_contact_generic"]
    assert fig["component"] == f"{component} total"
    assert fig["rms_bw"] < 0.06 and fig["pearson_r"] > 0.99
    other = v.total if component == "axial" else v.axial
    assert np.sqrt(np.mean((other - noisy) ** 2)) / BW > fig["rms_bw"] + 0.02
