"""OpenSim GRF files in every common column naming, ExternalLoads xml, and the real files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from msk.dynamics.loads import external_loads_assignment, plates_from_grf_file
from msk.exceptions import (
    FileFormatError,
    ForcePlateError,
    MissingDataError,
    MskError,
    UnitsError,
)
from msk.io import grf_force_sets, read_external_loads_xml, write_sto
from msk.io.grf import header_length_unit

T = np.linspace(0.0, 1.0, 11)
# two known wrenches: force (N), COP (m), free moment (N·m)
TRUTH = [
    (np.array([10.0, 700.0, 5.0]), np.array([0.3, 0.0, 0.1]), np.array([0.0, 2.0, 0.0])),
    (np.array([-8.0, 650.0, -3.0]), np.array([0.9, 0.0, -0.2]), np.array([0.0, -1.5, 0.0])),
]


_STYLES = {  # force-identifier templates ({s}: r/l, {k}: 1, 2); point: v → p, torque below
    "single": "ground_force_v",
    "side_suffix": "ground_force_{s}_v",
    "side_prefix": "{s}_ground_force_v",
    "number_suffix": "ground_force_{k}_v",
    "number_prefix": "{k}_ground_force_v",
    "moment": "ground_force_{k}_v",
}


def _names(style: str, k: int) -> tuple[str, str, str]:
    """Force, point and torque identifiers of set k (0-based) in a naming style."""
    if style == "opensim_example":  # subject01_walk_grf.mot: ground_… then 1_ground_…
        pre = "" if k == 0 else "1_"
        return f"{pre}ground_force_v", f"{pre}ground_force_p", f"{pre}ground_torque_"
    fid = _STYLES[style].format(s="rl"[k], k=k + 1)
    word = "moment" if style == "moment" else "torque"
    return fid, fid[:-1] + "p", fid[:-1].replace("force", word)


def _write(path: Path, style: str, *, order: str = "grouped", torque: str = "all") -> Path:
    n_sets = 1 if style == "single" else 2
    cols: list[str] = []
    data: list[np.ndarray] = []
    late: list[tuple[str, np.ndarray]] = []
    for k in range(n_sets):
        fid, pid, tid = _names(style, k)
        f, c, tq = TRUTH[k]
        for ax, v in zip("xyz", f):
            cols.append(fid + ax)
            data.append(np.full(T.size, v))
        for ax, v in zip("xyz", c):
            cols.append(pid + ax)
            data.append(np.full(T.size, v))
        tcols = [(tid + ax, np.full(T.size, v)) for ax, v in zip("xyz", tq)]
        if torque == "none":
            continue
        if torque == "y_only":
            tcols = [tcols[1]]
        if order == "scattered":  # like the Grand Challenge DM files: z here, x and y at the end
            cols.append(tcols[-1][0])
            data.append(tcols[-1][1])
            late += tcols[:-1]
        else:
            cols += [c for c, _ in tcols]
            data += [d for _, d in tcols]
    cols += [c for c, _ in late]
    data += [d for _, d in late]
    return write_sto(path, time=T, data=np.column_stack(data), columns=cols)


@pytest.mark.parametrize(
    "style",
    ["single", "opensim_example", "side_suffix", "side_prefix", "number_suffix", "number_prefix",
     "moment"],
)  # fmt: skip
@pytest.mark.parametrize("order", ["grouped", "scattered"])
def test_every_naming_recovers_the_known_wrenches(tmp_path, style, order):
    path = _write(tmp_path / f"{style}.mot", style, order=order)
    plates = plates_from_grf_file(path)
    assert [p.name for p in plates] == [f"plate{k + 1}" for k in range(len(plates))]
    assert len(plates) == (1 if style == "single" else 2)
    for p, (f, c, tq) in zip(plates, TRUTH):
        assert p.corners is None
        np.testing.assert_allclose(p.force, np.tile(f, (T.size, 1)))
        np.testing.assert_allclose(p.cop, np.tile(c, (T.size, 1)))
        np.testing.assert_allclose(p.free_moment, np.tile(tq, (T.size, 1)))
        np.testing.assert_allclose(p.moment_about_origin()[0], np.cross(c, f) + tq)


def test_missing_torque_columns_are_zero(tmp_path):
    none = plates_from_grf_file(_write(tmp_path / "a.sto", "number_suffix", torque="none"))
    assert all(np.all(p.free_moment == 0.0) for p in none)
    part = plates_from_grf_file(_write(tmp_path / "b.sto", "number_suffix", torque="y_only"))
    np.testing.assert_allclose(part[0].free_moment[0], [0.0, 2.0, 0.0])


def test_force_sets_are_named_in_file_order_and_errors_name_the_file(tmp_path):
    cols = ["time", "r_ground_force_vx", "r_ground_force_vy", "r_ground_force_vz"]
    full = ["time"] + [f"{a}_ground_force_{w}{x}" for a in "ba" for w in "vp" for x in "xyz"]
    sets = grf_force_sets(full, source="x")
    assert [(s.name, s.force_identifier) for s in sets] == [
        ("plate1", "b_ground_force_v"),
        ("plate2", "a_ground_force_v"),
    ]
    with pytest.raises(MissingDataError, match=r"grf\.mot: point identifier 'r_ground_force_p'"):
        grf_force_sets(cols, source="grf.mot")
    with pytest.raises(MissingDataError, match=r"bad\.sto: no ground-reaction columns"):
        grf_force_sets(["time", "knee_angle_r"], source="bad.sto")


XML = """<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40000">
  <ExternalLoads name="x">
    <objects>
      <ExternalForce name="{n1}">
        <applied_to_body>calcn_r</applied_to_body>
        <force_expressed_in_body>{frame}</force_expressed_in_body>
        <point_expressed_in_body>ground</point_expressed_in_body>
        <force_identifier>{fid}</force_identifier>
        <point_identifier>ground_force_2_p</point_identifier>
        <torque_identifier>ground_torque_2_</torque_identifier>
      </ExternalForce>
      <ExternalForce name="FP1">
        <applied_to_body>calcn_l</applied_to_body>
        <force_identifier>ground_force_1_v</force_identifier>
        <point_identifier>ground_force_1_p</point_identifier>
        <torque_identifier>ground_torque_1_</torque_identifier>
      </ExternalForce>
      <ExternalForce name="off">
        <appliesForce>false</appliesForce>
        <applied_to_body>pelvis</applied_to_body>
        <force_identifier>nothing_v</force_identifier>
        <point_identifier>nothing_p</point_identifier>
      </ExternalForce>
    </objects>
    <datafile>{datafile}</datafile>
  </ExternalLoads>
</OpenSimDocument>
"""


def _xml(path: Path, **kw: str) -> Path:
    values = {"n1": "FP2", "frame": "ground", "fid": "ground_force_2_v", "datafile": "grf.sto"}
    path.write_text(XML.format(**{**values, **kw}))
    return path


def test_external_loads_xml_maps_plate_names_to_bodies(tmp_path):
    _write(tmp_path / "grf.sto", "number_suffix", order="scattered")
    xml = _xml(tmp_path / "el.xml")
    spec = read_external_loads_xml(xml)
    assert [f.name for f in spec.forces] == ["FP2", "FP1"]  # the disabled one is left out
    assert spec.datafile == tmp_path / "grf.sto"
    # plate names follow the file's column order, not the xml's
    assert external_loads_assignment(xml) == {"plate2": "calcn_r", "plate1": "calcn_l"}
    # the plates an xml names are the same plates, with the same names
    a = plates_from_grf_file(tmp_path / "grf.sto", external_loads_xml=xml)
    b = plates_from_grf_file(tmp_path / "grf.sto")
    assert sorted(p.name for p in a) == [p.name for p in b]
    for p in a:
        q = next(x for x in b if x.name == p.name)
        np.testing.assert_array_equal(p.moment_about_origin(), q.moment_about_origin())
    # grf_path overrides the datafile
    _write(tmp_path / "other.mot", "number_suffix")
    assert external_loads_assignment(xml, tmp_path / "other.mot")["plate1"] == "calcn_l"


def test_external_loads_xml_errors_name_file_and_element(tmp_path):
    _write(tmp_path / "grf.sto", "number_suffix")
    bad_frame = r"el\.xml: <ExternalForce name='FP2'> <force_expressed_in_body>calcn_r"
    with pytest.raises(ForcePlateError, match=bad_frame):
        read_external_loads_xml(_xml(tmp_path / "el.xml", frame="calcn_r"))
    with pytest.raises(MissingDataError, match=r"<ExternalForce name='FP9'>.*'ground_force_9_v'"):
        external_loads_assignment(_xml(tmp_path / "el.xml", n1="FP9", fid="ground_force_9_v"))
    with pytest.raises(
        MissingDataError, match=r"el\.xml: GRF data file .*nope\.sto does not exist"
    ):
        external_loads_assignment(_xml(tmp_path / "el.xml", datafile="nope.sto"))
    (tmp_path / "bad.xml").write_text("<OpenSimDocument><ExternalLoads>")
    with pytest.raises(FileFormatError, match=r"bad\.xml: not a valid XML file"):
        read_external_loads_xml(tmp_path / "bad.xml")
    (tmp_path / "empty.xml").write_text("<OpenSimDocument><Model/></OpenSimDocument>")
    with pytest.raises(FileFormatError, match=r"empty\.xml: no <ExternalLoads>"):
        read_external_loads_xml(tmp_path / "empty.xml")
    assert issubclass(FileFormatError, MskError) and issubclass(ForcePlateError, MskError)


@pytest.mark.realdata
def test_every_real_grf_file_reads(real_dir):
    """Every GRF .mot/.sto of the real data: the sets, their rates, a body-weight-sized peak."""
    expect = {
        "opensim-subject01-walk/subject01_walk_grf.mot": 2,
        "opensim-rajagopal-walk/grf_walk.mot": 2,
        "knee-grand-challenge-gc5/PS_ngait_og_ss1_kinetics.mot": 3,
    }
    dm = sorted((real_dir / "knee-grand-challenge-gc6-DM").glob("*.sto"))
    assert len(dm) == 7
    for p in dm:
        expect[str(p.relative_to(real_dir))] = 2 if "_tm" in p.name else 3
    for rel, n in expect.items():
        plates = plates_from_grf_file(real_dir / rel)
        assert [p.name for p in plates] == [f"plate{k + 1}" for k in range(n)], rel
        for p in plates:
            peak = np.nanmax(p.force[:, 1])
            assert 600.0 < peak < 1100.0, (rel, p.name, peak)  # Y up, N, one person
            loaded = p.force[:, 1] > 100.0
            assert np.isfinite(p.cop[loaded]).all(), (rel, p.name)
            assert np.abs(p.cop[loaded, 1]).max() < 0.02  # on the floor, in metres
    # DM: torque columns scattered (…_1_z with the forces, _x/_y at the end): read by name
    dm_dir = real_dir / "knee-grand-challenge-gc6-DM"
    tm = plates_from_grf_file(dm_dir / "DM_ngait_tm_ss1_grf_filt.sto")
    assert np.abs(tm[0].free_moment[:, 1]).max() > 0.0


@pytest.mark.realdata
def test_every_real_external_loads_xml(real_dir):
    got = {
        str(x.relative_to(real_dir)): external_loads_assignment(x)
        for x in sorted(real_dir.rglob("*.xml"))
        if "external_loads" in x.name or x.name.endswith("_grf.xml") or x.name == "grf_walk.xml"
    }
    dm_r = {"plate1": "calcn_r", "plate2": "calcn_l", "plate3": "calcn_l"}
    dm_l = {"plate1": "calcn_l", "plate2": "calcn_r", "plate3": "calcn_r"}
    assert got == {
        "knee-grand-challenge-gc6-DM/DM_bouncy5_external_loads.xml": dm_r,
        "knee-grand-challenge-gc6-DM/DM_ngait_og1_external_loads.xml": dm_r,
        "knee-grand-challenge-gc6-DM/DM_ngait_og3_external_loads.xml": dm_l,
        "knee-grand-challenge-gc6-DM/DM_ngait_og4_external_loads.xml": dm_l,
        "knee-grand-challenge-gc6-DM/DM_smooth1_external_loads.xml": dm_r,
        "opensim-rajagopal-walk/grf_walk.xml": {"plate1": "calcn_r", "plate2": "calcn_l"},
        "opensim-subject01-walk/subject01_walk_grf.xml": {"plate1": "calcn_r", "plate2": "calcn_l"},
    }


# --- per-plate vector columns (OpenSim's C3DFileAdapter, flattened): f1_1 … p1_1 … m1_1 …


def _plate_wrenches(up: int, rng: np.random.Generator, n: int = 200):
    """Two plates' known ground reactions: force (N), COP on the floor (m), free moment
    (N·m, about the vertical ``up``): a stance rolling 0.25 m heel to toe with noise."""
    out = []
    s = np.linspace(0.0, 1.0, n)
    for k, (x0, y0) in enumerate([(0.9, 0.6), (0.3, 0.6)]):
        f = np.zeros((n, 3))
        f[:, up] = 700.0 * np.sin(np.pi * s) + 5.0 * rng.standard_normal(n) + 30.0
        h = [a for a in range(3) if a != up]
        f[:, h[0]] = 80.0 * np.sin(2 * np.pi * s) + rng.standard_normal(n)
        f[:, h[1]] = -20.0 * np.sin(np.pi * s) + rng.standard_normal(n)
        c = np.zeros((n, 3))
        c[:, h[0]] = x0 - 0.12 + 0.25 * s + 0.002 * rng.standard_normal(n) + 0.1 * k
        c[:, h[1]] = y0 + 0.01 * np.sin(3 * s) + 0.002 * rng.standard_normal(n)
        tq = np.zeros((n, 3))
        tq[:, up] = 4.0 * np.sin(2 * np.pi * s) + 0.1 * rng.standard_normal(n)
        out.append((f, c, tq))
    return np.linspace(0.0, 1.0, n), out


def _write_vector(path: Path, time, wrenches, *, at: str, unit: float, suffix: str = "123",
                  origins=((0.9186, 0.6111, 0.0), (0.3048, 0.6096, 0.0)), up: int = 2,
                  header: str | None = None) -> Path:  # fmt: skip
    """A C3DFileAdapter-style file: ``at`` "origin" (point = the plate origin, moment about
    it) or "cop" (point = COP, free moment); lengths in ``unit`` metres (moments N·unit)."""
    cols, data = [], []
    for k, ((f, c, tq), o) in enumerate(zip(wrenches, origins)):
        o3 = np.zeros(3)
        o3[[a for a in range(3) if a != up]] = [o[0], o[1]]
        if at == "origin":
            p = np.tile(o3, (f.shape[0], 1))
            m = np.cross(c - p, f) + tq  # M_P = (c − P) × F + T n
        else:
            p, m = c, tq
        for kind, v in (("f", f), ("p", p / unit), ("m", m / unit)):
            for a in range(3):
                cols.append(f"{kind}{k + 1}_{suffix[a]}")
                data.append(v[:, a])
    path = write_sto(path, time=time, data=np.column_stack(data), columns=cols)
    if header is not None:  # an extra header line before endheader
        text = path.read_text(encoding="utf-8").replace("endheader", f"{header}\nendheader", 1)
        path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("at", ["origin", "cop"])
@pytest.mark.parametrize("unit", [1.0, 1e-3])
@pytest.mark.parametrize("up,suffix", [(2, "123"), (1, "123"), (2, "xyz")])
def test_vector_columns_round_trip_the_known_wrenches(tmp_path, at, unit, up, suffix):
    """Known wrenches written as a plate-origin or a COP file, in metres or millimetres (no
    units header: decided from the data), z or y up: the COP to 1e-9 m, the free moment to
    1e-9 N·m, the force exactly."""
    rng = np.random.default_rng(7)
    time, truth = _plate_wrenches(up, rng)
    path = _write_vector(tmp_path / "grfs.sto", time, truth, at=at, unit=unit, up=up,
                         suffix=suffix)  # fmt: skip
    plates = plates_from_grf_file(path)
    assert [p.name for p in plates] == ["plate1", "plate2"]
    for p, (f, c, tq) in zip(plates, truth):
        np.testing.assert_allclose(p.force, f, rtol=0, atol=1e-9)
        np.testing.assert_allclose(p.cop, c, rtol=0, atol=1e-9)
        np.testing.assert_allclose(p.free_moment, tq, rtol=0, atol=1e-9)
        np.testing.assert_allclose(p.moment_about_origin(), np.cross(c, f) + tq, atol=1e-7)


def test_vector_columns_units_from_the_header_and_ambiguous_units_raise(tmp_path):
    rng = np.random.default_rng(3)
    time, truth = _plate_wrenches(2, rng)
    # a short sway near the lab origin, in mm: the largest loaded COP coordinate (~70 mm)
    # lies between 20 and 100 — metres or millimetres is not decided by the data
    near = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    close = [(f, 0.2 * (c - c.mean(axis=0)) + [0.04, 0.02, 0.0], tq) for f, c, tq in truth]
    bad = _write_vector(tmp_path / "near_mm.sto", time, close, at="cop", unit=1e-3,
                        origins=near)  # fmt: skip
    with pytest.raises(UnitsError, match=r"near_mm\.sto: units of the points .* \(p\d_\d\)"):
        plates_from_grf_file(bad)
    # the same file with a units header reads
    ok = _write_vector(tmp_path / "near_mm_units.sto", time, close, at="cop", unit=1e-3,
                       origins=near, header="Units=mm")  # fmt: skip
    for p, (_f, c, _tq) in zip(plates_from_grf_file(ok), close):
        np.testing.assert_allclose(p.cop, c, atol=1e-9)
    assert header_length_unit(ok) == 1e-3
    wrong = _write_vector(tmp_path / "furlong.sto", time, truth, at="cop", unit=1.0,
                          header="Units=furlong")  # fmt: skip
    with pytest.raises(UnitsError, match=r"furlong\.sto: header Units='furlong'"):
        plates_from_grf_file(wrong)


def test_vector_columns_missing_point_names_the_plate(tmp_path):
    cols = ["f1_1", "f1_2", "f1_3", "p1_1", "p1_2"]
    with pytest.raises(MissingDataError, match=r"plate 1's point needs .* missing \['p1_3'\]"):
        grf_force_sets(["time", *cols], source="x.sto")


@pytest.mark.realdata
def test_opensim_c3d_adapter_files_agree_with_each_other_and_with_the_c3d(real_dir):
    """opensim-core's walking2 GRFs as OpenSim wrote them at the plate origins (mm, N·mm,
    no units header) and at the COP: the same loads — COP within 1e-9 m and free moment within
    1e-8 N·m over the loaded samples (vertical > 100 N; measured 5e-11 m, 1.4e-9 N·m: the
    files' 8 decimals) — and the same as msk's own extraction of walking2.c3d at those samples
    (force within 1e-7 N, COP 1e-9 m, free moment 1e-8 N·m)."""
    from msk.io import read_c3d

    d = real_dir / "opensim-core-c3d"
    origin = plates_from_grf_file(d / "std_walking2_grfs.sto")
    cop = plates_from_grf_file(d / "std_cop_walking2_grfs.sto")
    trial = read_c3d(d / "walking2.c3d")
    assert len(origin) == len(cop) == len(trial.plates) == 2
    for a, b, c in zip(origin, cop, trial.plates):
        loaded = a.force[:, 2] > 100.0
        assert loaded.sum() >= 9
        np.testing.assert_allclose(a.force, b.force, atol=1e-7)
        np.testing.assert_allclose(a.cop[loaded], b.cop[loaded], rtol=0, atol=1e-9)
        np.testing.assert_allclose(a.free_moment[loaded], b.free_moment[loaded], atol=1e-8)
        idx = np.searchsorted(trial.analog_time, a.time - 1e-9)  # the 20 Hz subsample
        np.testing.assert_allclose(a.force, c.force[idx], rtol=0, atol=1e-7)
        np.testing.assert_allclose(a.cop[loaded], c.cop[idx][loaded], rtol=0, atol=1e-9)
        np.testing.assert_allclose(a.free_moment[loaded], c.free_moment[idx][loaded], atol=1e-8)
        # on the plate: the COP inside the C3D's outline
        lo, hi = c.corners.min(axis=0), c.corners.max(axis=0)
        assert ((a.cop[loaded, :2] >= lo[:2]) & (a.cop[loaded, :2] <= hi[:2])).all()
