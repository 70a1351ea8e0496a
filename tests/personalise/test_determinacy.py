"""msk.personalise.determinacy: the profile of a motion placement's fit along a joint's gauge."""

from __future__ import annotations

import numpy as np
import pytest

from msk.datasets.models import leg_model
from msk.exceptions import ModelError
from msk.kinematics.ik import solve_kinematics
from msk.model.core import marker_positions
from msk.personalise.determinacy import gauge_shifted_markers, placement_profile

#: the placement's cost resolution the pipeline uses (msk.personalise.placement.CHOICE_TOLERANCE_M)
TOL_M = 2e-4


def _walk(model, n=60, noise_m=0.001, seed=3):
    """Markers of a known motion of ``leg_model`` (knee 5–65° of flexion, hip ±25°) + noise."""
    t = np.linspace(0.0, 1.2, n)
    ph = 2 * np.pi * t / 1.2
    q = np.tile(model.default_coordinates(), (n, 1))
    q[:, model.coordinate_index("pelvis_tx")] = 1.2 * t
    q[:, model.coordinate_index("hip_flexion")] = np.radians(10 + 25 * np.sin(ph))
    q[:, model.coordinate_index("knee_angle")] = -np.radians(35 + 30 * np.sin(ph + 1.0))
    x = marker_positions(model, q)
    x = x + np.random.default_rng(seed).normal(0.0, noise_m, x.shape)
    return x, t, q


def _fit(labels, x, t):
    def fit(model, q0):
        kin = solve_kinematics(model, x, labels, t, cutoff_hz=None, initial_q=q0)
        q = np.asarray(kin.q_raw, dtype=float)
        ok = np.isfinite(q).all(axis=1)
        pos = marker_positions(model, q[ok])
        cols = [labels.index(m) for m in model.marker_names]
        d2 = ((pos - x[ok][:, cols]) ** 2).sum(axis=2)
        return q, float(np.sqrt(d2.mean(axis=1)).mean())

    return fit


def test_gauge_move_keeps_the_markers_at_the_reference_pose():
    model = leg_model()
    pose = model.default_coordinates()
    pose[model.coordinate_index("knee_angle")] = -0.6
    moved = gauge_shifted_markers(model, "knee_angle", 0.1, pose, ["TIB", "ANK", "THI"])
    shifted = pose.copy()
    shifted[model.coordinate_index("knee_angle")] += 0.1
    before = marker_positions(model, pose)[0]
    after = marker_positions(moved, shifted)[0]
    names = list(model.marker_names)
    for m in ("TIB", "ANK"):  # distal and free: kept in place
        assert np.allclose(after[names.index(m)], before[names.index(m)], atol=1e-12)
    for m in ("HEE", "TOE"):  # distal, not free: carried by the shifted knee
        assert np.linalg.norm(after[names.index(m)] - before[names.index(m)]) > 0.02
    # proximal (THI is free but on the femur, above the knee): untouched
    assert np.allclose(moved.markers[names.index("THI")].offset, model.markers[2].offset)
    with pytest.raises(ModelError, match="no revolute joint axis"):
        gauge_shifted_markers(model, "pelvis_tx", 0.1, pose, ["TIB"])


def test_profile_finds_the_knee_gauge_only_when_every_distal_marker_is_free():
    """Every marker below the knee placed from the motion (a shank cluster and foot markers,
    no malleolus held at its anatomical offset): the knee's mean is a near-gauge (exact for a
    hinge; here the knee's coupled translations break it by < 0.2 mm) — a placement with the
    mean knee flexion 5° away fits the noisy markers as well. With the ankle marker held (an
    anatomical landmark the placement does not move) the same shift costs centimetres: no flat
    direction. The mean itself is the truth's (IK of the true model) in both."""
    model = leg_model()
    x, t, q_true = _walk(model)
    labels = list(model.marker_names)
    fit = _fit(labels, x, t)
    knee = model.coordinate_index("knee_angle")
    truth = float(np.mean(q_true[:, knee]))

    free = placement_profile(model, fit, ["TIB", "ANK", "HEE", "TOE"], labels,
                             tolerance_m=TOL_M, stems=("knee_angle",))  # fmt: skip
    (c,) = free.coordinates
    assert c.coordinate == "knee_angle" and (c.free_markers, c.fixed_markers) == (4, 0)
    assert abs(c.mean_rad - truth) < np.radians(0.5)
    assert np.allclose(np.degrees(c.mean_change_rad), (5.0, -5.0), atol=0.5)
    assert max(abs(v) for v in c.cost_change_m) < TOL_M
    assert [p.coordinate for p in free.not_determined()] == ["knee_angle"]
    summary = free.summary()
    assert summary["not_determined"] == ["knee_angle"]
    assert summary["coordinates"]["knee_angle"]["status"] == "not determined"
    # a stated prior that sets the mean: status "prior", no longer "not determined"
    prior = free.summary({"knee_angle": "a test prior"})
    assert prior["not_determined"] == [] and free.not_determined({"knee_angle": "x"}) == ()
    assert prior["coordinates"]["knee_angle"]["status"] == "prior"
    assert prior["coordinates"]["knee_angle"]["prior"] == "set by prior: a test prior"

    held = placement_profile(model, fit, ["TIB", "HEE", "TOE"], labels,
                             tolerance_m=TOL_M, stems=("knee_angle",))  # fmt: skip
    (c,) = held.coordinates
    assert (c.free_markers, c.fixed_markers) == (3, 1)
    assert abs(c.mean_rad - truth) < np.radians(0.5)
    assert min(c.cost_change_m) > 10 * TOL_M
    assert held.not_determined() == ()
    assert held.summary()["coordinates"]["knee_angle"]["status"] == "no flat direction found"


def test_profile_of_a_hip_whose_thigh_and_knee_markers_are_anatomical():
    """The hip with its thigh markers held (THI, KNE at their offsets) is determined; a
    coordinate of the model without a marker distal to its joint is left out."""
    model = leg_model()
    x, t, _ = _walk(model, n=40)
    labels = list(model.marker_names)
    prof = placement_profile(model, _fit(labels, x, t), ["TIB", "HEE", "TOE"], labels,
                             tolerance_m=TOL_M, stems=("hip_flexion", "no_such"))  # fmt: skip
    assert [c.coordinate for c in prof.coordinates] == ["hip_flexion"]
    assert prof.not_determined() == ()


# --- the pelvis first: a subject marked with two ASIS and two PSIS, no sacral marker --------

_LEG = ("Thigh.Upper", "Thigh.Front", "Thigh.Rear", "Knee.Lat", "Shank.Upper", "Shank.Front",
        "Shank.Rear", "Ankle.Lat", "Heel", "Toe.Tip")  # fmt: skip


def _asis_psis_subject(n=40, noise_m=0.0015, sacral_shift_m=0.0, seed=5):
    """gait2392 as the subject (known pelvis and hips), walking (pelvis tilt 8 ± 2°, hips
    −15…+25°, knees 5–60°), marked with both ASIS, both PSIS (45 mm either side of the
    model's sacral point, raised by ``sacral_shift_m`` on the pelvis) and leg markers; no
    sacral marker. Returns the model, markers (N, M, 3) + noise, labels, time and the truth q."""
    from msk.model.core import Marker
    from msk.model.files import load_model

    model = load_model("gait2392")
    sac = next(mk for mk in model.markers if mk.name == "V.Sacral")
    up = np.array([0.0, sacral_shift_m, 0.0])
    psis = [Marker("RPSI", "pelvis", sac.offset + up + [0.0, 0.0, 0.045]),
            Marker("LPSI", "pelvis", sac.offset + up + [0.0, 0.0, -0.045])]  # fmt: skip
    names = ["R.ASIS", "L.ASIS", *(f"{s}.{m}" for s in "RL" for m in _LEG)]
    subject = model.with_markers([*(mk for mk in model.markers if mk.name in names), *psis])
    t = np.linspace(0.0, 1.2, n)
    ph = 2 * np.pi * t / 1.2
    q = np.tile(model.default_coordinates(), (n, 1))
    c = model.coordinate_index
    q[:, c("pelvis_tx")] = 1.2 * t
    q[:, c("pelvis_ty")] = 0.95
    q[:, c("pelvis_tilt")] = np.radians(8.0 + 2.0 * np.sin(2 * ph))
    for s, lag in (("r", 0.0), ("l", np.pi)):
        q[:, c(f"hip_flexion_{s}")] = np.radians(5.0 + 20.0 * np.sin(ph + lag))
        q[:, c(f"knee_angle_{s}")] = -np.radians(32.0 + 27.0 * np.sin(ph + lag + 1.0))
    x = marker_positions(subject, q)
    x = x + np.random.default_rng(seed).normal(0.0, noise_m, x.shape)
    return model, x, list(subject.marker_names), t, q


def test_pelvis_marked_with_asis_and_psis_only_is_flagged_unless_posed():
    """The pelvis check comes first (``placement_determinacy.pelvis``): with the two ASIS at
    the model's offsets and the PSIS placed from the motion (free), the rotation about the
    inter-ASIS line — the pelvis tilt — is left to the legs: not determined, and flagged; with
    the PSIS midpoint standing for the sacral marker three fixed markers pose it."""
    from msk.personalise.determinacy import PlacementProfile, pelvis_determinacy
    from msk.quality import model_flags

    model, _, labels, _, _ = _asis_psis_subject(n=2)
    legs = [lab for lab in labels if lab not in ("R.ASIS", "L.ASIS", "RPSI", "LPSI")]
    free = ["RPSI", "LPSI", *legs]  # a marker set placed from the motion, no static
    p = pelvis_determinacy(model, free, labels)
    assert p.body == "pelvis" and p.fixed == ("R.ASIS", "L.ASIS")
    assert p.not_determined == ("pelvis_tilt",) and p.spread_m == 0.0
    prof = PlacementProfile(0.1, 2e-4, 10, 0.01, (), pelvis=p)
    det = prof.summary()
    assert det["pelvis"]["status"] == "not determined"
    (flag,) = model_flags("t", {"placement_determinacy": det}, [])
    assert flag.quantity == "placement_not_determined_pelvis" and "pelvis_tilt" in flag.message
    posed = pelvis_determinacy(model, free, [*labels, "V.Sacral"])
    assert posed.not_determined == () and posed.spread_m > 0.05
    assert model_flags("t", {"placement_determinacy": PlacementProfile(
        0.1, 2e-4, 10, 0.01, (), pelvis=posed).summary()}, []) == []  # fmt: skip
    # one fixed marker: every rotation of the root joint is free
    assert set(pelvis_determinacy(model, [*free, "L.ASIS"], labels).not_determined) == {
        "pelvis_tilt", "pelvis_list", "pelvis_rotation"}  # fmt: skip


@pytest.mark.parametrize(("shift_m", "tilt_tol_deg"), [(0.0, 3.0), (0.015, 5.0)])
def test_asis_psis_subject_recovers_its_pelvis_and_hips_through_the_psis_midpoint(
    shift_m, tilt_tol_deg
):
    """A known subject marked with ASIS + PSIS only (1.5 mm noise): the PSIS midpoint as the
    model's sacral marker (:func:`msk.personalise.virtual_markers.with_virtual_sacrum`)
    recovers the pelvis tilt within 3° and both hip centres within 10 mm. The tilt is then
    the model's ASIS–sacrum geometry's: a subject whose PSIS sit 15 mm higher on the pelvis
    than the model's sacral point reads a biased tilt (−2.1° here; the fixed leg markers hold
    the hips and resist part of it), within the gate but not noise — the bias a static
    trial removes."""
    import dataclasses

    from msk.model.core import forward_kinematics
    from msk.personalise.virtual_markers import with_virtual_sacrum

    model, x, labels, t, q_true = _asis_psis_subject(sacral_shift_m=shift_m)

    @dataclasses.dataclass(frozen=True)
    class _T:
        markers: np.ndarray
        marker_labels: tuple[str, ...]

    tr, note = with_virtual_sacrum(_T(x, tuple(labels)), model)
    assert note is not None and note["marker"] == "V.Sacral"
    kin = solve_kinematics(model, tr.markers, list(tr.marker_labels), t, cutoff_hz=None)
    q = np.asarray(kin.q_raw, dtype=float)
    tilt = model.coordinate_index("pelvis_tilt")
    err = np.degrees(q[:, tilt] - q_true[:, tilt])
    assert abs(float(np.mean(err))) < tilt_tol_deg, np.mean(err)
    if shift_m:
        assert abs(float(np.mean(err))) > 1.0  # the geometry's bias, not noise
        return
    data, true = model.create_data(), model.create_data()
    for k in range(q.shape[0]):
        forward_kinematics(model, data, q[k])
        forward_kinematics(model, true, q_true[k])
        for s in "rl":
            f = model.body_frame[f"femur_{s}"]
            d = np.linalg.norm(data.oMf[f].translation - true.oMf[f].translation)
            assert d < 0.010, (k, s, d)
