"""Tests of msk.muscles.tlem: the TLEM 2.0 muscle dataset (Carbone et al. 2015) in SI."""

from __future__ import annotations

import math
import re
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from msk.exceptions import FileFormatError, MissingDataError
from msk.muscles.tlem import (
    DEFAULT_SPECIFIC_TENSION,
    TLEM_BONES,
    TLEM_CYLINDER_MUSCLES,
    load_tlem2,
)

DATA = Path(__file__).resolve().parent.parent / "msk" / "data" / "tlem2"


@pytest.fixture(scope="module")
def tlem():  # type: ignore[no-untyped-def]
    return load_tlem2()


def test_counts(tlem) -> None:  # type: ignore[no-untyped-def]
    assert len(tlem.elements) == 166
    assert len(set(tlem.element_names)) == 166
    assert len(tlem.muscles) == 55
    assert sum(len(m.elements) for m in tlem.muscles) == 166
    assert len(tlem.cylinders) == 4
    for arr in (tlem.optimal_fiber_length, tlem.pcsa, tlem.max_isometric_force):
        assert arr.shape == (166,)
        assert not arr.flags.writeable


def test_units_and_ranges(tlem) -> None:  # type: ignore[no-untyped-def]
    assert np.all((tlem.optimal_fiber_length >= 0.01) & (tlem.optimal_fiber_length <= 0.50))
    assert np.all((tlem.tendon_slack_length > 0) & (tlem.tendon_slack_length <= 0.50))
    assert np.all((tlem.pennation_angle >= 0) & (tlem.pennation_angle < math.radians(45)))
    assert np.all((tlem.pcsa > 1e-5) & (tlem.pcsa < 5e-3))  # 0.1 .. 50 cm² per element
    assert tlem.max_isometric_force == pytest.approx(DEFAULT_SPECIFIC_TENSION * tlem.pcsa)
    assert DEFAULT_SPECIFIC_TENSION == pytest.approx(37.0 / 1e-4)  # 37 N/cm² in Pa
    for e in tlem.elements:
        assert e.origin.kind == "origin" and e.insertion.kind == "insertion"
        assert all(p.kind == "via" for p in e.via_points)
        for p in e.points:
            assert p.bone in TLEM_BONES
            if p.is_located:  # bone-local coordinates in metres: well inside half a metre
                assert np.all(np.abs(p.location) < 0.5), (e.name, p)
    for c in tlem.cylinders:
        assert np.linalg.norm(c.axis) == pytest.approx(1.0)
        assert 0.01 < c.radius < 0.1


def test_specific_entries_against_the_csv(tlem) -> None:  # type: ignore[no-untyped-def]
    e = tlem.element("AdductorBrevisDistal1")
    assert e.label == "Adductor Brevis Distal 1" and e.muscle == "Adductor Brevis Distal"
    assert e.optimal_fiber_length == pytest.approx(11.101025869139566e-2, rel=1e-14)
    assert e.tendon_slack_length == pytest.approx(1.6738031239263624e-2, rel=1e-14)
    assert e.pcsa == pytest.approx(0.9008176467545782e-4, rel=1e-14)
    assert e.max_isometric_force == pytest.approx(37.0 * 0.9008176467545782, rel=1e-12)
    assert [(p.kind, p.bone) for p in e.points] == [("origin", "pelvis"), ("insertion", "femur")]
    assert e.origin.location == pytest.approx([0.02319, -0.03086, -0.07468])
    assert e.insertion.location == pytest.approx([-0.00172, 0.22554, 0.02503])
    assert e.cylinder is None

    b = tlem.element("BicepsFemorisCaputLongum1")
    assert b.pennation_angle == pytest.approx(0.42992890508924503)
    assert b.tendon_slack_length == pytest.approx(0.3365949174624355)

    g = tlem.element("GastrocnemiusMedialis1")
    kinds = [(p.kind, p.bone) for p in g.points]
    assert kinds == [("origin", "femur"), ("via", "femur")] + [("via", "tibia")] * 6 + [
        ("insertion", "foot")
    ]
    assert g.cylinder == "Gastrocnemius"

    cyl = tlem.cylinder("Iliopsoas")
    assert cyl.bone == "femur" and cyl.radius == pytest.approx(0.0275)
    assert cyl.center == pytest.approx([-0.014918624554361, 0.388966513443324, -0.035039316948254])
    assert tlem.muscle("Psoas Major").cylinder == "Iliopsoas"
    assert set(cyl.muscles) == set(TLEM_CYLINDER_MUSCLES["Iliopsoas"])

    vm = tlem.muscle("Vastus Medialis Superior")
    assert vm.elements == tuple(f"VastusMedialisSuperior{i}" for i in range(1, 5))
    assert vm.path_type == "WS" and vm.mass == pytest.approx(0.11072985781990522)


def test_psoas_origin_on_the_spine_is_unlocated(tlem) -> None:  # type: ignore[no-untyped-def]
    for e in tlem.elements_of("Psoas Major"):
        assert e.origin.bone == "spine" and not e.origin.is_located
        assert np.all(np.isnan(e.origin.location))
        assert e.insertion.is_located
    assert math.isnan(tlem.muscle("Psoas Major").mass)


def test_rectus_femoris_names_and_repaired_tibialis_posterior(tlem) -> None:  # type: ignore[no-untyped-def]
    lat, med = tlem.elements_of("Rectus Femoris")
    assert (lat.name, lat.label) == ("RectusFemorisLateralis1", "Rectus Femoris 1")
    assert (med.name, med.label) == ("RectusFemorisMedialis1", "Rectus Femoris 2")
    assert lat.insertion.location[2] > 0 > med.insertion.location[2]
    tp3 = tlem.element("TibialisPosteriorMedialis3")
    tp2 = tlem.element("TibialisPosteriorMedialis2")
    assert tp3.insertion.bone == "foot"
    assert tp3.insertion.location == pytest.approx(tp2.insertion.location)


def test_wrapping_cylinders_match_path_types(tlem) -> None:  # type: ignore[no-untyped-def]
    for m in tlem.muscles:
        assert (m.path_type == "WS") == (m.cylinder is not None), m.name
        for e in tlem.elements_of(m.name):
            assert e.cylinder == m.cylinder


def test_volume_equals_pcsa_times_fibre_length(tlem) -> None:  # type: ignore[no-untyped-def]
    """Independent check across tables: Table 1 volume = Σ PCSA · l_f over the A7 elements."""
    checked = 0
    for m in tlem.muscles:
        if math.isnan(m.volume):
            continue
        v = sum(e.pcsa * e.optimal_fiber_length for e in tlem.elements_of(m.name))
        assert v == pytest.approx(m.volume, abs=0.6e-6), m.name  # table rounding, < 0.6 ml
        checked += 1
    assert checked >= 50


def test_specific_tension_is_configurable() -> None:
    d = load_tlem2(specific_tension=25e4)
    assert d.specific_tension == 25e4
    assert d.max_isometric_force == pytest.approx(25e4 * d.pcsa)
    with pytest.raises(FileFormatError, match="specific_tension"):
        load_tlem2(specific_tension=-1.0)


def _xlsx_rows(path: Path) -> list[list[str]]:
    """Minimal .xlsx reader (first sheet, shared strings and numbers)."""
    with zipfile.ZipFile(path) as z:
        strings = [
            re.sub(r"<[^>]+>", "", s)
            for s in re.findall(r"<si>.*?</si>", z.read("xl/sharedStrings.xml").decode(), re.S)
        ]
        sheet = z.read("xl/worksheets/sheet1.xml").decode()
    rows = []
    for body in re.findall(r"<row [^>]*>(.*?)</row>", sheet, re.S):
        cells = re.findall(
            r"<c r=\"[A-Z]+\d+\"([^>]*?)(?:/>|>(?:<f>.*?</f>)?(?:<v>(.*?)</v>)?)", body
        )
        rows.append([strings[int(v)] if 't="s"' in a and v else v for a, v in cells])
    return rows


def test_architecture_matches_the_original_xlsx(tlem, ref_dir: Path) -> None:  # type: ignore[no-untyped-def]
    rows = _xlsx_rows(ref_dir / "tlem2" / "Table_A7_Muscle-tendon_architecture.xlsx")
    by_name = {r[0]: r for r in rows[1:] if r and r[0]}
    assert set(by_name) == set(tlem.element_names)
    for e in tlem.elements:
        r = by_name[e.name]
        assert e.optimal_fiber_length == pytest.approx(float(r[1]) / 100, rel=1e-12)
        assert e.tendon_slack_length == pytest.approx(float(r[2]) / 100, rel=1e-12)
        assert e.pennation_angle == pytest.approx(float(r[3]), rel=1e-12, abs=0)
        assert e.pcsa == pytest.approx(float(r[4]) * 1e-4, rel=1e-12)


# ---------------------------------------------------------------------------------------------
# malformed tables


def _copy(tmp_path: Path) -> Path:
    for f in DATA.glob("*.csv"):
        shutil.copy(f, tmp_path / f.name)
    return tmp_path


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text(encoding="utf-8")
    assert old in text
    path.write_text(text.replace(old, new, 1), encoding="utf-8")


def test_copy_of_the_tables_loads(tmp_path: Path) -> None:
    assert len(load_tlem2(directory=_copy(tmp_path)).elements) == 166


@pytest.mark.parametrize(
    ("file", "old", "new", "match"),
    [
        (
            "Table_A3_Muscle-tendon_lines-of-action.csv",
            "Pelvis,0.02319,-0.03086",
            "Pelvis,0.02319,abc",
            r"lines-of-action\.csv: line 2: .*'abc'",
        ),
        (
            "Table_A3_Muscle-tendon_lines-of-action.csv",
            ",,Insertion,Femur,-0.00172",
            ",,Insertion,Humerus,-0.00172",
            "line 3: unknown bone 'Humerus'",
        ),
        (
            "Table_A3_Muscle-tendon_lines-of-action.csv",
            ",,Insertion,Femur,-0.00172",
            ",,Origin,Femur,-0.00172",
            "Adductor Brevis Distal 1.*unexpected 'Origin'",
        ),
        (
            "Table_A3_Muscle-tendon_lines-of-action.csv",
            ",,Insertion,Patella,0.00145,0.01251,-0.01563",
            ",,Via,Patella,0.00145,0.01251,-0.01563",
            "'Vastus Medialis Superior 1' .*has no insertion",
        ),
        (
            "Table_A7_Muscle-tendon_architecture.csv",
            "AdductorBrevisDistal1,11.101025869139566",
            "AdductorBrevisDistal1,-11.1",
            "line 2: AdductorBrevisDistal1: fibre length -11.1 cm",
        ),
        (
            "Table_A7_Muscle-tendon_architecture.csv",
            "AdductorBrevisDistal1,",
            "AdductorBrevisDistalX,",
            "AdductorBrevisDistal1",
        ),
        (
            "Table_1_Muscle_list.csv",
            "Adductor Longus,6,",
            "Adductor Longus,5,",
            "'Adductor Longus' has 5 elements",
        ),
        (
            "Table_1_Muscle_list.csv",
            "Gracilis,2,S,",
            "Gracilis,2,WS,",
            "'Gracilis' path type 'WS' but cylinder None",
        ),
        (
            "Table_A5_Wrapping_Surfaces.csv",
            ",0.0275,",
            ",-0.0275,",
            "'Iliopsoas': radius -0.0275",
        ),
    ],
)
def test_malformed_rows_raise_named_errors(
    tmp_path: Path, file: str, old: str, new: str, match: str
) -> None:
    d = _copy(tmp_path)
    _edit(d / file, old, new)
    with pytest.raises(FileFormatError, match=match):
        load_tlem2(directory=d)


def test_missing_table(tmp_path: Path) -> None:
    d = _copy(tmp_path)
    (d / "Table_A5_Wrapping_Surfaces.csv").unlink()
    with pytest.raises(MissingDataError, match="Table_A5"):
        load_tlem2(directory=d)


def test_lookup_errors(tlem) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(MissingDataError, match="Biceps Brachii"):
        tlem.muscle("Biceps Brachii")
    with pytest.raises(MissingDataError, match="Foo1"):
        tlem.element("Foo1")
