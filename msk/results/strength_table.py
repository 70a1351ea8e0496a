"""``tables/strength.csv`` of a dynamometry session and the cohort table of ``msk batch``: one
row per isometric test (:class:`msk.strength.isometric.TestStrength`)."""

from __future__ import annotations

import csv
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from msk.strength.isometric import TestStrength

__all__ = ["STRENGTH_COLUMNS", "strength_rows", "write_strength_csv"]


#: the columns of ``tables/strength.csv`` (and of the cohort table)
STRENGTH_COLUMNS = (
    "subject",
    "age_years",
    "mass_kg",
    "test",
    "action",
    "status",
    "torque_nm",
    "torque_ci_low_nm",
    "torque_ci_high_nm",
    "torque_per_kg",
    "torque_per_kg_ci_low",
    "torque_per_kg_ci_high",
    "measured_net_nm",
    "cocontraction_nm",
    "lever_arm_m",
    "lever_arm_sd_m",
    "lever_arm_kind",
    "model_nm",
    "factor",
    "factor_ci_low",
    "factor_ci_high",
    "reason",
)


def strength_rows(
    subject: str,
    results: Sequence[TestStrength],
    *,
    age_years: float | None = None,
    mass_kg: float | None = None,
) -> list[dict[str, Any]]:
    """The rows of ``tables/strength.csv`` (:data:`STRENGTH_COLUMNS`) of one subject (its age
    and body mass repeated on each row, empty when not given: the cohort table's covariates)."""
    who = {"age_years": "" if age_years is None else age_years,
           "mass_kg": "" if mass_kg is None else mass_kg}  # fmt: skip
    return [_row(subject, r) | who for r in results]


def write_strength_csv(path: str | Path, rows: Sequence[Mapping[str, Any]]) -> Path:
    """A strength table (:data:`STRENGTH_COLUMNS`, one row per subject and test)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=STRENGTH_COLUMNS, lineterminator="\n")
        w.writeheader()
        w.writerows({k: r.get(k, "") for k in STRENGTH_COLUMNS} for r in rows)
    return path


def _row(subject: str, r: TestStrength) -> dict[str, Any]:
    return {
        "subject": subject,
        "test": r.test,
        "action": r.action,
        "status": r.status,
        "torque_nm": round(r.torque_nm, 3),
        "torque_ci_low_nm": round(r.torque_ci_nm[0], 3),
        "torque_ci_high_nm": round(r.torque_ci_nm[1], 3),
        "torque_per_kg": round(r.torque_per_kg, 4),
        "torque_per_kg_ci_low": round(r.torque_per_kg_ci[0], 4),
        "torque_per_kg_ci_high": round(r.torque_per_kg_ci[1], 4),
        "measured_net_nm": round(r.measured_net_nm, 3),
        "cocontraction_nm": round(r.cocontraction_nm, 3),
        "lever_arm_m": round(r.lever_arm_m, 4),
        "lever_arm_sd_m": round(r.lever_arm_sd_m, 4),
        "lever_arm_kind": r.lever_arm_source.split(":")[0],
        "model_nm": round(r.model_nm, 3),
        "factor": round(r.factor, 4),
        "factor_ci_low": round(r.factor_ci[0], 4),
        "factor_ci_high": round(r.factor_ci[1], 4),
        "reason": r.reason,
    }
