"""OpenSim GRF files in every common column naming, ExternalLoads xml, and the real files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from msk.exceptions import FileFormatError, ForcePlateError, MissingDataError, MskError
from msk.io import grf_force_sets, read_external_loads_xml, write_sto
from msk.loads import external_loads_assignment, plates_from_grf_file

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
