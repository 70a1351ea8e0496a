"""Measured knee contact-force readers (msk.io.contact_force) and the DM conversion script."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from scipy.io import savemat

from msk.exceptions import FileFormatError, MissingDataError
from msk.io.contact_force import (
    DMAlignment,
    MeasuredContact,
    align_dm_trial,
    read_dm_mat,
    read_load_cells,
    read_measured_contact,
)
from msk.io.opensim_files import write_sto, write_trc

ROOT = Path(__file__).resolve().parents[2]
G0 = 9.80665


def _csv(path: Path, header: str, rows) -> Path:
    path.write_text(header + "\n" + "\n".join(",".join(map(str, r)) for r in rows) + "\n")
    return path


def test_time_csv_with_loose_column_names(tmp_path: Path) -> None:
    p = _csv(tmp_path / "a.csv", "time,F_med,Lateral_N", [[1.0, 10, 20], [1.5, 11, 21]])
    m = read_measured_contact(p)
    assert isinstance(m, MeasuredContact) and m.cycle_fraction is None
    np.testing.assert_allclose(m.time, [1.0, 1.5])
    np.testing.assert_allclose(m.medial, [10, 11])
    np.testing.assert_allclose(m.lateral, [20, 21])
    assert np.isnan(m.total).all()  # absent: NaN, never guessed
    assert m.n_frames == 2 and m.values.shape == (2, 3)
    np.testing.assert_allclose(m.in_body_weights(70.0)[:, 1], np.array([10, 11]) / (70 * G0))
    q = _csv(tmp_path / "b.csv", "time,total,medial (N),lateral", [[0.0, 3, 1, 2], [0.1, 4, 2, 2]])
    m = read_measured_contact(q)
    np.testing.assert_allclose(m.values, [[3, 1, 2], [4, 2, 2]])


def test_cycle_normalised_csv(tmp_path: Path) -> None:
    rows = [[x, 100 + x, 50, 160 + x] for x in range(0, 101, 10)]
    p = _csv(tmp_path / "c.csv", "percent,F_medial_N,F_lateral_N,F_total_magnitude_N", rows)
    m = read_measured_contact(p)
    assert m.time is None
    np.testing.assert_allclose(m.cycle_fraction, np.linspace(0.0, 1.0, 11))
    np.testing.assert_allclose(m.total, 160 + np.arange(0, 101, 10))
    assert "cycle-normalised" in m.source


def test_bundled_ps_etibia_csv() -> None:
    """data/gc5-PS: the Grand Challenge PS eTibia file (101 samples, medial/lateral/total)."""
    m = read_measured_contact(ROOT / "data" / "gc5-PS" / "PS_ngait_og_ss1_eTibia.csv")
    assert m.n_frames == 101 and m.cycle_fraction[50] == pytest.approx(0.5)
    assert m.medial[0] == pytest.approx(545.808907) and m.lateral[0] == pytest.approx(62.485397)
    assert m.total[0] == pytest.approx(630.007947)
    # the magnitude includes the shear: never below the sum of the axial compartment forces
    assert np.all(m.total >= m.medial + m.lateral - 1.0)


def test_bad_inputs(tmp_path: Path) -> None:
    two = _csv(tmp_path / "d.csv", "time,medial,F_medial_N", [[0, 1, 1], [1, 1, 1]])
    with pytest.raises(FileFormatError, match="several"):
        read_measured_contact(two)
    with pytest.raises(MissingDataError, match="no total"):
        read_measured_contact(_csv(tmp_path / "e.csv", "time,x,y", [[0, 1, 1], [1, 1, 1]]))
    m = read_measured_contact(
        _csv(tmp_path / "f.csv", "time,x,y", [[0, 1, 2], [1, 1, 2]]), medial="x", lateral="y"
    )
    np.testing.assert_allclose(m.lateral, [2, 2])
    with pytest.raises(MissingDataError, match="no column 'z'"):
        read_measured_contact(tmp_path / "f.csv", total="z")
    with pytest.raises(FileFormatError, match="not increasing"):
        read_measured_contact(_csv(tmp_path / "g.csv", "time,total", [[1, 1], [0, 1]]))
    with pytest.raises(FileFormatError, match="unknown"):
        read_measured_contact(_csv(tmp_path / "h.json", "{}", []))
    with pytest.raises(FileFormatError, match="no such file"):
        read_measured_contact(tmp_path / "missing.csv")
    with pytest.raises(FileFormatError, match="exactly one"):
        MeasuredContact(np.zeros(2), np.zeros(2), np.zeros(2))
    with pytest.raises(FileFormatError, match="shape"):
        MeasuredContact(np.zeros(2), np.zeros(3), np.zeros(2), time=np.arange(2.0))
    with pytest.raises(FileFormatError, match="MATLAB"):
        read_measured_contact(_csv(tmp_path / "i.mat", "not a mat file", []))


# ---------------------------------------------------------------------------------------------
# synthetic DM-like trial: known offset, markers with noise, a GRF at 10 × the marker rate
# ---------------------------------------------------------------------------------------------
def _synthetic_dm(tmp_path: Path, offset: int = 37, n: int = 60, noise: float = 0.002):
    rng = np.random.default_rng(7)
    rate = 120.0
    t_all = 1.25 + np.arange(200) / rate
    walk = np.stack([1.2 * t_all, 0.9 + 0.02 * np.sin(9 * t_all), 0.1 * np.cos(4 * t_all)], 1)
    offs = rng.normal(0.0, 0.15, (8, 3))
    markers = walk[:, None, :] + offs[None] + 0.03 * np.sin(6 * t_all[:, None, None] + offs)
    markers[150:160, 2] = np.nan  # a gap in one marker
    labels = [f"M{i}" for i in range(8)]
    write_trc(tmp_path / "trial.trc", time=t_all, markers=markers, labels=labels)
    win = markers[offset : offset + n]
    seg = lambda idx: {"rM": (win[:, idx] + rng.normal(0, noise, (n, len(idx), 3))).T}  # noqa: E731
    virtual = {"rM": (win[:, [1]] + np.array([0.0, -0.3, 0.0])).transpose(2, 1, 0)}
    # GRF: one plate at 1200 Hz, the .mat holds minus the plate reaction at 120 Hz
    t_g = 1.25 + np.arange(200 * 10) / (10 * rate)
    g = np.stack([30 * np.sin(5 * t_g), 700 * np.clip(np.sin(3 * t_g), 0, None), 0 * t_g], 1)
    write_sto(
        tmp_path / "grf.sto",
        time=t_g,
        data=np.column_stack([g, 0 * g]),
        columns=["p1_vx", "p1_vy", "p1_vz", "p1_px", "p1_py", "p1_pz"],
    )
    k0 = 10 * offset
    f_mat = -g[k0 : k0 + 10 * n : 10]
    medial = np.linspace(100.0, 700.0, n)
    mat = {
        "Force": {"KneeMedial": medial, "KneeLateral": 0.5 * medial},
        "f": rate,
        "n": n,
        "mass": 70,
        "Segment": np.array(
            [{"Q": np.zeros((12, n)), "rM": np.zeros((0,))}, seg([0, 1, 2]), seg([3, 4]), virtual],
            dtype=object,
        ),
        "Joint": {"F": f_mat.T, "M": np.zeros((3, n))},
    }
    savemat(tmp_path / "trial.mat", mat)
    return tmp_path / "trial.mat", tmp_path / "trial.trc", tmp_path / "grf.sto", t_all[offset]


def test_load_cell_csv_is_the_sum_in_pound_force(tmp_path: Path) -> None:
    """The JW re-export's layout (trailing commas included): total = Σ four cells × 4.448 N,
    time as in the file, medial/lateral NaN (not derivable from the cells alone)."""
    p = tmp_path / "jw_knee_forces.csv"
    p.write_text("Time(sec),PM,AM,AL,PL,GON,GRFz\n1.0,10,20,30,40,5.0,0.1,\n1.5,1,2,3,4,6.0,0.2,\n")
    for m in (read_measured_contact(p), read_load_cells(p)):
        np.testing.assert_allclose(m.total, [100 * 4.4482216152605, 10 * 4.4482216152605])
        np.testing.assert_allclose(m.time, [1.0, 1.5])
        assert np.isnan(m.medial).all() and np.isnan(m.lateral).all()
        assert "lbf" in m.source
    bad = tmp_path / "bad.csv"
    bad.write_text("Time(sec),PM,AM,AL\n1,2,3,4\n")
    with pytest.raises(FileFormatError, match="'PL'"):
        read_load_cells(bad)
    bad.write_text("Time(sec),PM,AM,AL,PL\n1,2,3,x,5\n2,1,1,1,1\n")
    with pytest.raises(FileFormatError, match=r"line 2: .*'x'"):
        read_measured_contact(bad)
    bad.write_text("Time(sec),PM,AM,AL,PL\n2,1,1,1,1\n1,1,1,1,1\n")
    with pytest.raises(FileFormatError, match="increasing"):
        read_measured_contact(bad)


@pytest.mark.realdata
@pytest.mark.slow
def test_jw_load_cells_in_pound_force_bound_the_inverse_dynamics_reaction(real_dir: Path) -> None:
    """The unit is established from the data: read in lbf, JW's load-cell sum is never below
    the knee's inverse-dynamics reaction without muscles (compressive contact ≥ that bound) on
    the measured frames of jw_ngait_og3, peaks at 2.3–2.7 BW; in N it would be below it."""
    from msk.config import load_config
    from msk.contact.knee import knee_contact_force
    from msk.pipeline import run_stages

    cfg = load_config(ROOT / "pipelines" / "gc4_JW.toml")
    (task,) = [t for t in cfg.trials if t.role == "task"]
    assert task.contact_force is not None and task.contact_force.name.endswith("forces.csv")
    r = run_stages(cfg, until="loads")
    kin, loads = r["kinematics"], r["loads"]
    reaction = knee_contact_force(r["model"].model, kin, loads.external, joint="knee_r")
    bound = np.linalg.norm(reaction.force, axis=1)[loads.usable]
    m = read_measured_contact(task.contact_force)
    total = np.interp(kin.time, m.time, m.total)[loads.usable]
    bw = cfg.subject.mass_kg * G0
    assert loads.usable.sum() > 100
    assert np.all(total >= bound)
    assert 2.3 < m.total.max() / bw < 2.7
    assert np.mean(total / 4.4482216152605 < bound) > 0.5


def test_dm_alignment_recovers_a_known_offset(tmp_path: Path) -> None:
    mat, trc, sto, t0 = _synthetic_dm(tmp_path)
    dm = read_dm_mat(mat)
    assert dm["markers"].shape == (60, 6, 3) and dm["marker_ids"][0] == (2, 1)
    al = align_dm_trial(mat, trc, grf=sto)
    assert isinstance(al, DMAlignment)
    assert al.offset_frames == 37 and al.start_time_s == pytest.approx(t0, abs=1e-6)
    assert len(al.matches) == 5  # the virtual point matches no marker
    assert [m[2] for m in al.matches] == ["M0", "M1", "M2", "M3", "M4"]
    assert al.marker_rms_m == pytest.approx(0.002 * np.sqrt(3), rel=0.25)
    assert al.neighbour_rms_m > 3 * al.marker_rms_m
    assert al.grf_plate == "p1" and al.grf_rms_n < 1e-3
    assert al.grf_start_time_s == pytest.approx(t0, abs=1e-6)
    m = read_measured_contact(mat, trial=trc, grf=sto)
    np.testing.assert_allclose(m.time, t0 + np.arange(60) / 120.0, atol=1e-6)
    np.testing.assert_allclose(m.total, 1.5 * m.medial)
    assert m.metadata["aligned"] and m.metadata["alignment"]["offset_frames"] == 37
    raw = read_measured_contact(mat)
    assert raw.metadata["aligned"] is False and raw.time[0] == 0.0
    with pytest.raises(MissingDataError, match="no marker matches"):
        align_dm_trial(mat, trc, max_marker_rms_m=1e-5)
    with pytest.raises(MissingDataError, match="agree"):
        align_dm_trial(mat, trc, min_markers=6)


# ---------------------------------------------------------------------------------------------
# real data
# ---------------------------------------------------------------------------------------------
DM_EXPECTED = {  # trial: (.trc row of frame 0, .trc time, GRF plate)
    "og1": (199, 2.408333, "ground_force_1"),
    "og3": (33, 2.475, "ground_force_2"),
    "og4": (103, 3.083333, "ground_force_2"),
}


@pytest.mark.realdata
def test_ps_etibia_csvs_read(real_dir: Path) -> None:
    for s in (1, 3, 8):
        m = read_measured_contact(
            real_dir / "knee-grand-challenge-gc5" / f"PS_ngait_og_ss{s}_eTibia.csv"
        )
        assert m.n_frames == 101 and np.isfinite(m.values).all()
        bw = m.values.max(axis=0) / (75.0 * G0)  # the source repo's 75 kg
        assert 2.1 < bw[0] < 2.5 and 1.5 < bw[1] < 1.8 and 0.9 < bw[2] < 1.1
        assert np.all(m.total >= m.medial + m.lateral - 1.0)


@pytest.mark.realdata
@pytest.mark.parametrize("trial", sorted(DM_EXPECTED))
def test_dm_trials_align_to_their_trc_by_the_markers(real_dir: Path, trial: str) -> None:
    d = real_dir / "knee-grand-challenge-gc6-DM"
    al = align_dm_trial(
        d / "moissenet" / f"DM_ngait_{trial}.mat",
        d / f"DM_ngait_{trial}_new.trc",
        grf=d / f"DM_ngait_{trial}_grf.sto",
    )
    row, t0, plate = DM_EXPECTED[trial]
    assert al.offset_frames == row and al.start_time_s == pytest.approx(t0, abs=1e-6)
    assert len(al.matches) == 12 and al.marker_rms_m < 0.003 < 0.008 < al.neighbour_rms_m
    # the ground reaction, matched independently at 1200 Hz, agrees within half a frame
    assert al.grf_plate == plate and al.grf_rms_n < 10.0
    assert abs(al.grf_start_time_s - al.start_time_s) < 0.5 / 120.0 + 1e-9
    m = read_measured_contact(
        d / "moissenet" / f"DM_ngait_{trial}.mat", trial=d / f"DM_ngait_{trial}_new.trc"
    )
    peaks = m.in_body_weights(70.0).max(axis=0)  # DM: 70 kg
    assert 2.4 < peaks[0] < 2.8 and 1.1 < peaks[1] < 1.45 and 1.3 < peaks[2] < 1.45


@pytest.mark.realdata
def test_conversion_script_regenerates_the_bundled_csv(real_dir: Path, tmp_path: Path) -> None:
    """studies/dm_contact_to_csv.py on og1: the CSV reads back aligned and equals the file
    bundled in data/gc6-DM (run in-process: ≈ 0.5 s)."""
    path = ROOT / "studies" / "dm_contact_to_csv.py"
    spec = importlib.util.spec_from_file_location("dm_contact_to_csv", path)
    assert spec is not None and spec.loader is not None
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    mat = real_dir / "knee-grand-challenge-gc6-DM" / "moissenet" / "DM_ngait_og1.mat"
    assert script.main([str(mat), "--out", str(tmp_path)]) == 0
    out = tmp_path / "DM_ngait_og1_contact.csv"
    m = read_measured_contact(out)
    assert m.cycle_fraction is None and m.time[0] == pytest.approx(2.408333)
    assert m.n_frames == 146 and np.allclose(np.diff(m.time), 1 / 120.0, atol=2e-6)
    src = read_dm_mat(mat)
    np.testing.assert_array_equal(m.medial, src["medial"])
    np.testing.assert_array_equal(m.lateral, src["lateral"])
    assert out.read_text() == (ROOT / "data" / "gc6-DM" / "DM_ngait_og1_contact.csv").read_text()


@pytest.mark.realdata
def test_dm_medial_lateral_are_one_fixed_linear_map_of_the_raw_implant_channels(
    real_dir: Path,
) -> None:
    """How DM's measured split is defined (docs/validation.md, medial/lateral contact, item 7):
    ``Force.KneeMedial``/``KneeLateral`` of the three trials are one fixed linear map of the
    source's ``Force.raw`` channels (F_SI, M_VV, F_ML) — fitted on og1, it reproduces og3 and
    og4 to rounding — i.e. a fixed geometry/calibration, not a per-trial or load-dependent
    split; medial + lateral is F_SI (coefficient 0.999), and the split is carried mostly by
    the channel named F_ML (0.876 per unit), hardly by M_VV (0.019 per unit)."""
    from scipy.io import loadmat

    def channels(trial: str) -> tuple[np.ndarray, np.ndarray]:
        d = loadmat(
            real_dir / "knee-grand-challenge-gc6-DM" / "moissenet" / f"DM_ngait_{trial}.mat",
            squeeze_me=True,
            struct_as_record=False,
        )["Force"]
        a = np.column_stack([d.raw.F_SI, d.raw.M_VV, d.raw.F_ML])
        return a, np.column_stack([d.KneeMedial, d.KneeLateral])

    a, y = channels("og1")
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    for trial in ("og3", "og4"):
        a2, y2 = channels(trial)
        assert np.abs(a2 @ coef - y2).max() < 1e-6  # N, against loads up to ~1 kN
    assert coef.sum(axis=1) == pytest.approx([0.999, 0.0, 0.0], abs=1e-3)
    assert coef[0] == pytest.approx([0.494, 0.505], abs=1e-3)
    assert coef[2] == pytest.approx([-0.876, 0.876], abs=1e-3)
    assert abs(coef[1, 0]) < 0.02 and coef[1, 0] == pytest.approx(-coef[1, 1])


def test_what_a_measured_total_measures():
    """A column named for a magnitude is a magnitude; a total equal to medial + lateral is the
    axial force; JW's load cells are axial; otherwise unstated."""
    import numpy as np

    from msk.io.contact_force import total_component

    m, lat = np.array([300.0, 500.0, 400.0]), np.array([200.0, 300.0, 100.0])
    assert total_component("F_total_magnitude_N", m + lat + 50, m, lat) == "magnitude"
    assert total_component("total_N", m + lat, m, lat) == "axial"
    assert total_component("total_N", m + lat + 50, m, lat) == "unstated"
    nan = np.full(3, np.nan)
    assert total_component("total", m, nan, nan) == "unstated"
    assert total_component("axial_force", m, nan, nan) == "axial"
