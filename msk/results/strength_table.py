"""``tables/strength.csv`` of a dynamometry session and the cohort table of ``msk batch``
(``strength_cohort.csv``): one row per subject and isometric test
(:class:`msk.strength.isometric.TestStrength`). Columns (:data:`STRENGTH_COLUMNS`):

* ``subject``, ``age_years``, ``mass_kg``: the subject (age and mass empty when not given);
* ``test``, ``action``: the test's name and the model action it loads;
* ``status``: ``identified`` or ``not determined`` (the reason in ``reason``);
* ``torque_nm``, ``torque_ci_low_nm``, ``torque_ci_high_nm``: the agonists' maximal isometric
  torque (N·m) with its 95 % interval (net torque + co-contraction);
* ``torque_nm_per_kg``, ``torque_nm_per_kg_ci_low``, ``torque_nm_per_kg_ci_high``: the same
  over the body mass (N·m/kg);
* ``measured_net_nm``: lever arm × plateau force (N·m); ``cocontraction_nm``: the antagonists'
  torque added back (N·m);
* ``lever_arm_m``, ``lever_arm_sd_m``: the lever arm and its standard deviation (m);
  ``lever_arm_kind``: ``anthropometric``, ``given by the configuration`` or ``not used`` (a
  torque export);
* ``model_nm``: the scaled generic model's agonist torque at the posture (N·m); ``factor``,
  ``factor_ci_low``, ``factor_ci_high``: torque over it with the interval;
* ``band_low_nm_per_kg``, ``band_high_nm_per_kg``: the published band of the action for the
  subject's age (empty: none); ``below_published_band``: 1 when the interval lies wholly below
  it (``msk.strength.isometric`` docstring);
* ``failed_checks``: the trial's failed checks (``;``-separated quantities of
  :data:`msk.strength.isometric.CHECKS_FAILING`; empty: every check passed);
* ``reason``: the status's reason in words.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from msk.strength.isometric import CHECKS_FAILING, TestStrength

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
    "torque_nm_per_kg",
    "torque_nm_per_kg_ci_low",
    "torque_nm_per_kg_ci_high",
    "measured_net_nm",
    "cocontraction_nm",
    "lever_arm_m",
    "lever_arm_sd_m",
    "lever_arm_kind",
    "model_nm",
    "factor",
    "factor_ci_low",
    "factor_ci_high",
    "band_low_nm_per_kg",
    "band_high_nm_per_kg",
    "below_published_band",
    "failed_checks",
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
        "torque_nm_per_kg": round(r.torque_nm_per_kg, 4),
        "torque_nm_per_kg_ci_low": round(r.torque_nm_per_kg_ci[0], 4),
        "torque_nm_per_kg_ci_high": round(r.torque_nm_per_kg_ci[1], 4),
        "measured_net_nm": round(r.measured_net_nm, 3),
        "cocontraction_nm": round(r.cocontraction_nm, 3),
        "lever_arm_m": round(r.lever_arm_m, 4),
        "lever_arm_sd_m": round(r.lever_arm_sd_m, 4),
        "lever_arm_kind": r.lever_arm_source.split(":")[0],
        "model_nm": round(r.model_nm, 3),
        "factor": round(r.factor, 4),
        "factor_ci_low": round(r.factor_ci[0], 4),
        "factor_ci_high": round(r.factor_ci[1], 4),
        "band_low_nm_per_kg": "" if math.isnan(r.band_nm_per_kg[0]) else r.band_nm_per_kg[0],
        "band_high_nm_per_kg": "" if math.isnan(r.band_nm_per_kg[1]) else r.band_nm_per_kg[1],
        "below_published_band": int(r.below_band),
        "failed_checks": ";".join(
            sorted({f.quantity for f in r.flags if f.quantity in CHECKS_FAILING})
        ),
        "reason": r.reason,
    }
