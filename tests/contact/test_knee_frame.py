"""FrameKneeContact: the knee contact force of one frame from that frame's RNEA equals
knee_contact_force's (and its two-point split split_medial_lateral's)."""

from __future__ import annotations

import numpy as np

from msk.contact.knee import FrameKneeContact, knee_contact_force, split_medial_lateral
from msk.datasets.trials import make_trial
from msk.dynamics.inverse import FrameInverseDynamics
from msk.dynamics.loads import external_loads
from msk.kinematics.ik import kinematics_from_coordinates
from msk.muscles.geometry import muscle_geometry
from tests.support.two_legs import muscled_two_legs


def test_frame_knee_contact_equals_the_batch():
    model = muscled_two_legs()
    tr = make_trial(model, duration_s=0.4, rate_hz=100.0)
    kin = kinematics_from_coordinates(tr.time, tr.q, model.coordinate_names, cutoff_hz=None)
    kin = type(kin)(**{**kin.__dict__, "v": tr.v, "a": tr.a})
    ext = external_loads(model, kin, tr.plates)
    geo = muscle_geometry(model, kin.q, kin.v, distal_wrench_joints=("knee_l",))
    rng = np.random.default_rng(0)
    forces = rng.uniform(0.0, 800.0, size=(tr.time.size, len(model.muscles)))
    names = tuple(m.name for m in model.muscles)
    w = geo.distal_wrenches["knee_l"]
    batch = knee_contact_force(
        model, kin, ext, muscle_forces=forces, muscle_names=names, joint="knee_l",
        distal_wrenches=w,
    )  # fmt: skip
    split = split_medial_lateral(batch)
    fid = FrameInverseDynamics(model, ext.bodies)
    frame = FrameKneeContact(model, "knee_l", bodies=ext.bodies, geometry=split.geometry)
    for k in range(0, tr.time.size, 5):
        fid.torques(tr.q[k], tr.v[k], tr.a[k], ext.force[k], ext.moment[k])
        axial, medial, lateral = frame.contact(fid.data, forces[k], w[k], ext.force[k],
                                               ext.moment[k])  # fmt: skip
        np.testing.assert_allclose(frame.force, batch.force[k], rtol=1e-9, atol=1e-7)
        np.testing.assert_allclose(frame.moment, batch.moment[k], rtol=1e-9, atol=1e-7)
        np.testing.assert_allclose(
            [axial, medial, lateral], [-batch.force[k, 1], split.medial[k], split.lateral[k]],
            rtol=1e-9, atol=1e-7,
        )  # fmt: skip
