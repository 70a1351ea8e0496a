"""The session folder's ``opensim/`` files in OpenSim 4.6 (child process): on msk's exported
model (``model.osim``), OpenSim's inverse dynamics with msk's motion and msk's exported GRF +
ExternalLoads reproduces msk's joint torques and OpenSim places the markers where msk does;
OpenSim's legacy ``Storage`` reads every row of every ``.sto/.mot``.

Two sessions: the bundled Grand Challenge PS walk (gait2392 scaled by msk), and OpenSim's own
subject01 walk (Gait2392_Simbody example: ``subject01_simbody.osim`` imported and used as it is,
``scale = false``, with OpenSim's GRF and ExternalLoads).
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from msk.io.opensim_files import read_sto, read_trc
from msk.io.storage_twin import storage_twin
from msk.io.tables import read_csv_table

_SOLVE = """
import os
import numpy as np
import opensim as osim

m = osim.Model(ARGS["model"])
m.initSystem()
RESULT["mass"] = m.getTotalMass(m.initSystem())
el = osim.ExternalLoads(ARGS["xml"], True)
RESULT["bodies"] = [el.get(i).get_applied_to_body() for i in range(el.getSize())]
# OpenSim resolves the datafile against the working directory: the xml's folder
el.setDataFileName(os.path.join(os.path.dirname(ARGS["xml"]), el.getDataFileName()))
m.addModelComponent(el)
s = m.initSystem()
fs = m.getForceSet()
for i in range(fs.getSize()):  # only the ground reactions (and gravity) act: no muscle
    if osim.ExternalForce.safeDownCast(fs.get(i)) is None:
        fs.get(i).setAppliesForce(s, False)
cs = m.getCoordinateSet()
coords = [cs.get(n) for n in ARGS["names"]]
uidx = []  # each coordinate's index in the state's u
for c in coords:
    for d in coords:
        d.setSpeedValue(s, 0.0)
    c.setSpeedValue(s, 1.0)
    uidx.append(int(np.argmax(np.abs(s.getU().to_numpy()))))
solver = osim.InverseDynamicsSolver(m)
K = np.load(ARGS["kin"])
tau = []
for t, q, v, a in zip(K["t"], K["q"], K["v"], K["a"]):
    s.setTime(float(t))
    for c, qi, vi in zip(coords, q, v):
        c.setValue(s, float(qi), False)
        c.setSpeedValue(s, float(vi))
    m.realizeVelocity(s)
    ud = osim.Vector(s.getNU(), 0.0)
    for j, ai in zip(uidx, a):
        ud.set(j, float(ai))
    g = solver.solve(s, ud).to_numpy()
    tau.append([float(g[j]) for j in uidx])
RESULT["tau"] = tau
ms = m.getMarkerSet()
RESULT["marker_names"] = [ms.get(i).getName() for i in range(ms.getSize())]
RESULT["marker_pos"] = []
for f in ARGS["frames"]:
    for c, qi in zip(coords, K["q"][f]):
        c.setValue(s, float(qi), False)
    m.realizePosition(s)
    RESULT["marker_pos"].append(
        [[ms.get(i).getLocationInGround(s).get(k) for k in range(3)] for i in range(ms.getSize())]
    )
# OpenSim's InverseDynamicsTool on the written files (it differentiates q.mot itself)
tool = osim.InverseDynamicsTool()
m2 = osim.Model(ARGS["model"])  # a model without the loads added above
m2.initSystem()
tool.setModel(m2)
tool.setCoordinatesFileName(ARGS["q"])
tool.setExternalLoadsFileName(ARGS["xml"])
tool.setLowpassCutoffFrequency(-1)
ex = osim.ArrayStr()
ex.append("Muscles")
tool.setExcludedForces(ex)
qs = osim.Storage(ARGS["q"])
tool.setStartTime(qs.getFirstTime())
tool.setEndTime(qs.getLastTime())
tool.setResultsDir(ARGS["out"])
tool.setOutputGenForceFileName("id.sto")
os.chdir(os.path.dirname(ARGS["xml"]))
RESULT["tool_ok"] = bool(tool.run())
t = osim.TimeSeriesTable(os.path.join(ARGS["out"], "id.sto"))
RESULT["tool_labels"] = list(t.getColumnLabels())
RESULT["tool_time"] = list(t.getIndependentColumn())
RESULT["tool"] = t.getMatrix().to_numpy().tolist()
# the legacy Storage on every storage file msk wrote
RESULT["storage"] = {}
for p in ARGS["storage_files"]:
    st = osim.Storage(p)
    lab = st.getColumnLabels()
    last = st.getStateVector(st.getSize() - 1).getData()
    RESULT["storage"][p] = {
        "rows": st.getSize(),
        "labels": [lab.get(i) for i in range(lab.getSize())],
        "last": [last.get(i) for i in range(last.getSize())],
    }
mk = osim.TimeSeriesTableVec3(ARGS["trc"])
RESULT["trc_rows"] = mk.getNumRows()
RESULT["trc_labels"] = list(mk.getColumnLabels())
row = mk.getRowAtIndex(mk.getNumRows() // 2)
RESULT["trc_mid"] = [[row[i].get(k) for k in range(3)] for i in range(row.size())]
"""


REPO = Path(__file__).resolve().parents[2]


def _subject01_config(tmp_path: Path, real_dir: Path) -> Path:
    data = real_dir.parent.parent / "tools" / "opensim-peer" / "data" / "Pipelines"
    data = data / "Gait2392_Simbody"
    osim = data / "OutputReference" / "subject01_simbody.osim"
    if not osim.is_file():
        pytest.skip("OpenSim's Gait2392_Simbody example absent")
    cfg = tmp_path / "s01.toml"
    cfg.write_text(
        f'[subject]\nname = "subject01"\nmass_kg = 72.6\nheight_m = 1.8034\nside = "right"\n\n'
        f'[model]\nsource = "{osim}"\nscale = false\n\n'
        f'[[trials]]\nname = "walk"\nfile = "{data / "subject01_walk1.trc"}"\n'
        f'grf = "{data / "subject01_walk1_grf.mot"}"\n'
        f'external_loads = "{data / "subject01_walk1_grf.xml"}"\nrole = "task"\n',
        encoding="utf-8",
    )
    return cfg


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.opensim
@pytest.mark.parametrize("session", ["gc5_PS", "subject01"])
def test_opensim_reproduces_msk_inverse_dynamics_from_the_exported_files(
    session: str, tmp_path: Path, real_dir: Path, needs_opensim: None
) -> None:
    from msk._runtime.opensim_peer import run_opensim_script
    from msk.model.core import marker_positions
    from msk.pipeline import run_session, run_stages

    if session == "subject01":
        cfg = _subject01_config(tmp_path, real_dir)
    else:
        cfg = REPO / "pipelines" / f"{session}.toml"
    out = tmp_path / "out"
    res = run_session(cfg, out)
    rec = res.summary.to_dict()["opensim"]
    assert rec["files"] == [
        "opensim/markers.trc",
        "opensim/grf.mot",
        "opensim/external_loads.xml",
        "opensim/model.osim",
    ]
    assert rec["model_inertias"] == "mass-identified"
    # the motion, and the model with the inertias of the joint_torques table
    from msk.dynamics.identification import identified_model

    stages = run_stages(cfg, until="inverse_dynamics")
    kin = stages["kinematics"]
    table = read_csv_table(out / "tables" / "joint_torques.csv")
    assert list(table.columns) == list(kin.coordinate_names)
    msk_tau = table.data  # the joint torques msk wrote
    model = identified_model(stages["model"].model, stages["mass_identification"])
    np.savez(
        tmp_path / "kin.npz",
        t=np.asarray(kin.time),
        q=np.asarray(kin.q),
        v=np.asarray(kin.v),
        a=np.asarray(kin.a),
    )
    sto = sorted(str(p) for p in (out / "tables").glob("*.[sm][to][ot]"))
    sto.append(str(out / "opensim" / "grf.mot"))
    frames = [0, kin.time.size // 2, kin.time.size - 1]
    got = run_opensim_script(
        _SOLVE,
        model=str(out / "opensim" / "model.osim"),
        xml=str(out / "opensim" / "external_loads.xml"),
        q=str(out / "tables" / "q.mot"),
        trc=str(out / "opensim" / "markers.trc"),
        names=list(kin.coordinate_names),
        kin=str(tmp_path / "kin.npz"),
        out=str(tmp_path / "id"),
        storage_files=sto,
        frames=frames,
    )
    assert got["mass"] == pytest.approx(model.total_mass, rel=1e-12)
    # OpenSim places msk's markers where msk does (the scaled bodies, joints and placements)
    assert got["marker_names"] == [mk.name for mk in model.markers]
    want = marker_positions(model, np.asarray(kin.q)[frames])
    np.testing.assert_allclose(np.array(got["marker_pos"]), want, rtol=0, atol=1e-9)
    # and its muscles where msk has them (scaled paths): lengths and moment arms
    from msk.muscles.geometry import muscle_geometry
    from tests.support.opensim_geometry import opensim_geometry

    th = np.asarray(kin.q)[frames]
    leg = [kin.coordinate_names.index(c) for c in ("hip_flexion_r", "knee_angle_l")]
    every = list(range(len(model.muscles)))
    lengths, arms = opensim_geometry(out / "opensim" / "model.osim", model, th, every, leg)
    geo = muscle_geometry(model, th)
    np.testing.assert_allclose(lengths, geo.lengths, rtol=0, atol=1e-9)
    np.testing.assert_allclose(arms, geo.moment_arms[:, :, leg], rtol=0, atol=1e-9)
    assert got["bodies"] == [b["applied_to_body"] for b in rec["external_loads"]]
    assert set(got["bodies"]) == {"calcn_r", "calcn_l"}
    # OpenSim's ID solver, msk's motion, msk's exported model and loads: msk's torques table
    tau, ok = np.array(got["tau"]), np.isfinite(msk_tau)
    assert ok.mean() > 0.9
    np.testing.assert_allclose(tau[ok], msk_tau[ok], rtol=0, atol=1e-6)
    # OpenSim's ID tool on the written files runs; it differentiates q.mot by splines where msk
    # low-pass filters the accelerations, so only the feet (little mass below the joint: the
    # torque is the ground reaction's) agree closely (subject01: ankle 0.38 N·m RMS of 156)
    assert got["tool_ok"]
    tool = np.array(got["tool"])
    for c in ("ankle_angle_r", "ankle_angle_l", "subtalar_angle_r", "subtalar_angle_l"):
        j, k = kin.coordinate_names.index(c), got["tool_labels"].index(f"{c}_moment")
        a = np.interp(kin.time, got["tool_time"], tool[:, k])
        rms = float(np.sqrt(np.nanmean((a - msk_tau[:, j]) ** 2)))
        assert rms < 2.0, (c, rms)
    # Storage reads every row of every table twin and of the GRF file, to the last value
    for path, s in got["storage"].items():
        p = Path(path)
        if p.parent.name == "tables":
            csv = read_csv_table(p.with_suffix(".csv"))
            twin = storage_twin(csv).table
        else:
            twin = read_sto(p)
        assert s["rows"] == twin.time.size, p.name
        assert s["labels"] == ["time", *twin.columns], p.name
        want = twin.data[-1].copy()
        if p.name == "q.mot":
            want[[twin.columns.index(c) for c in res.summary.angle_columns]] *= 180 / np.pi
        np.testing.assert_allclose(s["last"], want, rtol=1e-12, atol=1e-12, err_msg=p.name)
    # the markers: every frame, msk's values in mm
    trc = read_trc(out / "opensim" / "markers.trc")
    assert got["trc_rows"] == trc.time.size == kin.time.size
    assert got["trc_labels"] == list(trc.labels)
    np.testing.assert_allclose(
        np.array(got["trc_mid"]), trc.markers[trc.time.size // 2] * 1e3, rtol=1e-12
    )


def test_export_step_writes_what_it_can_and_says_what_it_left_out(tmp_path: Path) -> None:
    """The step on a tiny model: only loaded bodies get an ExternalForce; a marker label a TRC
    cannot hold leaves the markers out (said in the record), not the run."""
    from msk.io.grf import read_external_loads_xml
    from msk.model.core import Axis as MAxis
    from msk.model.core import Body, Coordinate, Joint, Marker, Model
    from msk.pipeline.opensim_export import run, run_model

    mdl = Model(
        name="m",
        bodies=[Body("a", 2.0, np.zeros(3), np.eye(3) * 0.1), Body("b", 1.0)],
        joints=[
            Joint("j0", "ground", "a", axes=(MAxis("prismatic", (0, 1, 0), "ty"),)),
            Joint("j1", "a", "b", axes=(MAxis("revolute", (0, 0, 1), "rz"),)),
        ],
        coordinates=[Coordinate("ty", "translational"), Coordinate("rz")],
        markers=[Marker("M1", "a", (0.1, 0, 0)), Marker("M2", "b", (0, 0.1, 0))],
    )
    n = 5
    t = np.arange(n) / 100.0
    force = np.zeros((n, 2, 3))
    force[:, 0, 1] = 20.0
    point = np.full((n, 2, 3), np.nan)
    point[:, 0] = 0.0
    ext = SimpleNamespace(time=t, bodies=("a", "b"), force=force, moment=np.zeros((n, 2, 3)),
                          point=point)  # fmt: skip
    trial = SimpleNamespace(time=t, markers=np.ones((n, 2, 3)), point_rate_hz=100.0)
    built = SimpleNamespace(model=mdl, trial=trial, labels=("M1", ""))
    inputs = SimpleNamespace(cfg=SimpleNamespace(subject=SimpleNamespace(name="S")),
                             inertias_by_status=False)  # fmt: skip
    exp = run(inputs, built, None, SimpleNamespace(external=ext))  # type: ignore[arg-type]
    assert exp is not None
    assert exp.files == ("grf.mot", "external_loads.xml")
    assert exp.record["markers"].startswith("not written") and "label" in exp.record["markers"]
    assert [e["applied_to_body"] for e in exp.record["external_loads"]] == ["a"]
    written = exp.write(tmp_path)
    assert [p.name for p in written] == list(exp.files)
    spec = read_external_loads_xml(tmp_path / "opensim" / "external_loads.xml")
    assert [f.applied_to_body for f in spec.forces] == ["a"]
    assert read_sto(tmp_path / "opensim" / "grf.mot").column("a_force_vy").tolist() == [20.0] * n
    om = run_model(inputs, built, None)  # type: ignore[arg-type]
    assert om is not None and om.files == ("model.osim",)
    assert om.record["model_inertias"] == "scaled generic"
    om.write(tmp_path)
    assert (tmp_path / "opensim" / "model.osim").is_file()
