"""The dynamometry strength tables (msk.results.strength_table): one row per subject and test
with every column, and the per-test cohort summary over the identified tests only."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

from msk.quality import Flag
from msk.results.strength_table import (
    STRENGTH_COLUMNS,
    SUMMARY_COLUMNS,
    cohort_summary_rows,
    strength_rows,
    write_strength_csv,
    write_summary_csv,
)
from msk.strength import isometric as iso


def _result(
    test: str, torque: float, status: str, flags: tuple[Flag, ...] = ()
) -> iso.TestStrength:
    band = (1.40, 2.16) if test == "knee_extension" else (math.nan, math.nan)
    return iso.TestStrength(
        test=test,
        action=test.replace("_", " "),
        status=status,
        reason="every check passed" if status == "identified" else "x: target not most active",
        torque_nm=torque,
        torque_ci_nm=(0.9 * torque, 1.1 * torque),
        torque_nm_per_kg=torque / 70.0,
        torque_nm_per_kg_ci=(0.9 * torque / 70.0, 1.1 * torque / 70.0),
        measured_net_nm=torque,
        cocontraction_nm=0.0,
        cocontraction_note="",
        lever_arm_m=0.35,
        lever_arm_sd_m=0.02,
        lever_arm_source="anthropometric: …",
        model_nm=150.0,
        model_range_nm=(150.0, 150.0),
        factor=torque / 150.0,
        factor_ci=(0.8 * torque / 150.0, 1.2 * torque / 150.0),
        flags=flags,
        band_nm_per_kg=band,
        band_source="a source" if test == "knee_extension" else "",
    )


def _below(test: str) -> Flag:
    return Flag(test, "below_published_band", 0.5, 1.4, "below")


def test_rows_and_cohort_summary(tmp_path: Path) -> None:
    rows = []
    for i, (tq, st) in enumerate([(35.0, "identified"), (70.0, "identified"), (10.0, "nd")]):
        status = "identified" if st == "identified" else "not determined"
        flags = [_below("knee_extension")] if tq < 90.0 else []
        if status != "identified":
            flags.append(Flag("knee_extension", "target_not_most_active", 0.1, 0.4, "x"))
        ke = _result("knee_extension", tq, status, tuple(flags))
        kf = _result("knee_flexion", 30.0 + i, "identified")
        rows += strength_rows(f"S{i}", [ke, kf], age_years=70, mass_kg=70.0)
    p = write_strength_csv(tmp_path / "strength_cohort.csv", rows)
    read = list(csv.DictReader(p.open()))
    assert tuple(read[0]) == STRENGTH_COLUMNS and len(read) == 6
    assert read[0]["torque_nm_per_kg"] == "0.5" and read[0]["band_low_nm_per_kg"] == "1.4"
    assert read[1]["band_low_nm_per_kg"] == "" and read[1]["below_published_band"] == "0"
    assert read[4]["failed_checks"] == "target_not_most_active"
    summ = cohort_summary_rows(rows)
    ke = next(r for r in summ if r["test"] == "knee_extension")
    # the distribution over the identified tests only: 35 and 70 N·m, not the failed 10
    assert ke["n_subjects"] == 3 and ke["n_identified"] == 2
    assert ke["torque_nm_median"] == pytest.approx(52.5)
    assert ke["torque_nm_per_kg_q1"] == pytest.approx(round((35 + 0.25 * 35) / 70.0, 3))
    assert ke["n_below_band_identified"] == 2 and ke["n_below_band"] == 3
    assert ke["not_identified_because"] == "target_not_most_active: 1"
    kf = next(r for r in summ if r["test"] == "knee_flexion")
    assert kf["n_identified"] == 3 and kf["not_identified_because"] == ""
    q = write_summary_csv(tmp_path / "summary.csv", summ)
    assert tuple(next(csv.reader(q.open()))) == SUMMARY_COLUMNS
