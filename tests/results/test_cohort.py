"""msk.results.cohort: one cohort row per session from its summary, the table written."""

from __future__ import annotations

import csv
from pathlib import Path

from msk.results.cohort import COHORT_COLUMNS, cohort_row, write_cohort_csv
from tests.support.summaries import BASE


def test_the_cohort_row_says_which_quality_gates_were_raised() -> None:
    flag = {"trial": "t", "value": 1.0, "threshold": 0.0, "message": "m"}
    flags = [
        {**flag, "quantity": "emg_sample_faults"},
        {**flag, "quantity": "stage_failed"},
        {**flag, "quantity": "emg_sample_faults"},
    ]
    row = cohort_row("s.toml", {**BASE, "quality": {"flags": flags}}, "ok", "", 1.0)
    assert row["quality_flags"] == "emg_sample_faults×2 stage_failed×1"
    assert cohort_row("s.toml", {**BASE, "quality": {}}, "ok", "", 1.0)["quality_flags"] == ""


def test_a_session_row_and_a_failed_one_in_the_table(tmp_path: Path) -> None:
    """A summary's figures land in their columns (mass rounded to 10 g, IK RMS in mm, the
    identified segments' mass summed); a failed session keeps its error and nothing else."""
    quality = {"frames": 120, "ik_marker_rms_mean_m": 0.01234567, "ik_failed_frames": 2}
    ident = {
        "segments": [
            {"name": "femur_r", "mass_kg": 8.5, "prior_mass_kg": 8.0, "status": "identified"},
            {"name": "tibia_r", "mass_kg": 3.25, "prior_mass_kg": 3.5, "status": "prior"},
        ]
    }
    summary = {**BASE, "quality": quality, "identification": ident}
    summary["subject"] = {**BASE["subject"], "mass_kg": 70.004, "mass_source": "config"}
    ok = cohort_row("/x/s1.toml", summary, "ok", "", 12.34567)
    assert list(ok) == list(COHORT_COLUMNS)
    assert ok["session"] == "S1" and ok["config"] == "/x/s1.toml" and ok["run_s"] == 12.346
    assert ok["frames"] == 120 and ok["ik_marker_rms_mean_mm"] == 12.346
    assert ok["ik_failed_frames"] == 2 and ok["mass_kg"] == 70.0 and ok["mass_source"] == "config"
    assert ok["identified_mass_kg"] == 11.75 and ok["knee_contact_rms_bw"] == ""
    bad = cohort_row("/x/s2.toml", None, "failed", "C3DError: no markers", 0.5)
    assert bad["session"] == "s2" and bad["error"] == "C3DError: no markers"
    assert bad["frames"] == "" and bad["mass_kg"] == ""
    path = write_cohort_csv(tmp_path / "cohort.csv", [ok, bad])
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["status"] for r in rows] == ["ok", "failed"]
    assert list(rows[0]) == list(COHORT_COLUMNS) and rows[0]["identified_mass_kg"] == "11.75"
