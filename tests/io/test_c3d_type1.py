"""C3D force platform type 1 (channels Fx Fy Fz Px Py Mz: COP and free moment recorded).

Synthetic round trip (a known wrench in a Y-up lab, plate rotated 180° about the vertical like
the second UNIPD plate) and the real UNIPD/BTS files of the MOtoNMS test data.
"""

from __future__ import annotations

import numpy as np
import pytest

from msk.io import PlateSpec, read_c3d, write_c3d

# Y-up lab, plate z down: x along +X, y along +Z (the first UNIPD plate) ...
PLATE_ROT_YUP = np.column_stack([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
# ... and turned 180° about the vertical: x along −X, y along −Z (the second)
ROT = np.column_stack([[-1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, -1.0, 0.0]])


def plate_corners(rot: np.ndarray, centre: np.ndarray, a: float, b: float) -> np.ndarray:
    """Corners in C3D order (x = c0 − c1, y = c0 − c3 along the plate axes ``rot``)."""
    ex, ey = rot[:, 0], rot[:, 1]
    return np.array(
        [centre + a * ex + b * ey, centre - a * ex + b * ey, centre - a * ex - b * ey,
         centre + a * ex - b * ey]
    )  # fmt: skip


@pytest.mark.parametrize("rot", [PLATE_ROT_YUP, ROT], ids=["yup", "turned"])
def test_type1_round_trip_recovers_force_cop_and_free_moment(tmp_path, rot):
    rng = np.random.default_rng(1)
    n, ratio = 30, 10
    na = n * ratio
    centre = np.array([0.4, 0.0, 0.9])
    corners = plate_corners(rot, centre, a=0.2, b=0.3)
    # truth in the lab: reaction force (up), COP on the surface, free moment about the vertical
    f = np.column_stack([rng.normal(20, 5, na), 700 + rng.normal(0, 40, na), rng.normal(0, 8, na)])
    cop = centre + np.column_stack(
        [rng.uniform(-0.15, 0.15, na), np.zeros(na), rng.uniform(-0.25, 0.25, na)]
    )
    tz = rng.normal(0, 3.0, na)  # N·m about +Y
    f[:5] = 0.0  # unloaded samples
    # channels in the plate axes, mm and N·mm
    f_p = f @ rot
    c_p = (cop - centre) @ rot * 1e3
    m_p = np.outer(tz, [0.0, 1.0, 0.0]) @ rot * 1e3
    chans = np.column_stack([f_p, c_p[:, :2], m_p[:, 2]])
    chans[:5, 3:] = 0.0
    labels = ["Fx1", "Fy1", "Fz1", "Px1", "Py1", "Mz1"]
    path = write_c3d(
        tmp_path / "t1.c3d",
        markers=np.ones((n, 1, 3)),
        marker_labels=["A"],
        rate_hz=100.0,
        point_units="mm",
        analogs=chans,
        analog_labels=labels,
        analog_units=["N", "N", "N", "mm", "mm", "Nmm"],
        analog_ratio=ratio,
        plates=[PlateSpec(tuple(labels), corners, np.zeros(3), type=1)],
    )
    tr = read_c3d(path)
    (pl,) = tr.plates
    assert pl.type == 1 and pl.channels == tuple(labels)
    np.testing.assert_allclose(pl.rotation, rot, atol=1e-6)
    np.testing.assert_allclose(pl.force, f, rtol=1e-5, atol=1e-3)  # float32 channels
    ok = slice(5, None)
    assert np.isnan(pl.cop[:5]).all() and np.all(pl.free_moment[:5] == 0.0)
    np.testing.assert_allclose(pl.cop[ok], cop[ok], atol=1e-6)
    np.testing.assert_allclose(pl.free_moment[ok, 1], tz[ok], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(pl.free_moment[ok][:, [0, 2]], 0.0, atol=1e-9)
    # moment about the centre of the surface: the same wrench as F at the COP plus T
    m = np.cross(cop[ok] - centre, f[ok]) + np.outer(tz[ok], [0, 1, 0])
    np.testing.assert_allclose(pl.moment[ok], m, rtol=1e-5, atol=1e-3)
    assert tr.vertical_axis == 1
    # through msk.dynamics.loads: the plate wrench at its COP
    from msk.dynamics.loads import plates_from_trial

    (pw,) = plates_from_trial(tr)
    mo = np.cross(cop[ok], f[ok]) + np.outer(tz[ok], [0, 1, 0])
    np.testing.assert_allclose(pw.moment_about_origin()[ok], mo, rtol=1e-5, atol=1e-2)


@pytest.mark.slow
@pytest.mark.realdata
def test_unipd_bts_type1_plates(real_dir):
    """MOtoNMS UNIPD (BTS, Bertec 4060-08, type 1): the walks load each plate once with the
    COP inside its outline; the static trial's plate channels are all zero (the subject did
    not stand on the plates), so its weight is estimated from the walks: stance impulse over
    the step time (heel strike on plate 1 → heel strike on plate 2), 808–857 N."""
    base = real_dir / "motonms-testdata" / "UNIPD"
    static = read_c3d(base / "Static1.c3d")
    assert [p.type for p in static.plates] == [1, 1]
    assert all(np.all(p.force == 0.0) and np.isnan(p.cop).all() for p in static.plates)
    for name, peaks in (
        ("Walking1", (940.9, 994.6)),
        ("Walking2", (907.0, 942.7)),
        ("Walking3", (920.8, 969.8)),
    ):
        tr = read_c3d(base / f"{name}.c3d")
        assert tr.vertical_axis == 1 and [p.type for p in tr.plates] == [1, 1]
        np.testing.assert_allclose([p.force[:, 1].max() for p in tr.plates], peaks, atol=0.1)
        t = tr.analog_time
        strikes, impulses = [], []
        for p in tr.plates:
            on = np.flatnonzero(p.force[:, 1] > 20.0)
            assert np.ptp(on) == on.size - 1  # one contact
            lo, hi = p.corners.min(axis=0), p.corners.max(axis=0)
            c = p.cop[on]
            assert np.all((c[:, [0, 2]] >= lo[[0, 2]]) & (c[:, [0, 2]] <= hi[[0, 2]]))
            assert np.abs(c[:, 1]).max() < 0.003  # on the surface (corners at y ≈ 0)
            strikes.append(t[on[0]])
            impulses.append(p.force[on, 1].sum() * (t[1] - t[0]))
        bw = np.array(impulses) / (strikes[1] - strikes[0])
        assert np.all((bw > 800.0) & (bw < 860.0)), bw
