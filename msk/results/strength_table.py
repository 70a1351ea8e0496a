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

``strength_cohort_summary.csv`` (:func:`cohort_summary_rows`, :data:`SUMMARY_COLUMNS`): one row
per test over the cohort — ``n_subjects``, ``n_identified``; the median and quartiles of
``torque_nm``, ``torque_nm_per_kg`` and ``factor`` over the *identified* tests only (a failed
test's torque is not a strength); the band; ``n_below_band_identified`` and ``n_below_band``
(all tests); ``not_identified_because``: each failed check (or ``interval too wide``) with its
count.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from msk.strength.isometric import CHECKS_FAILING, TestStrength

__all__ = [
    "STRENGTH_COLUMNS",
    "SUMMARY_COLUMNS",
    "cohort_summary_rows",
    "strength_rows",
    "write_strength_csv",
    "write_summary_csv",
]


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


#: the columns of ``strength_cohort_summary.csv`` (module docstring)
SUMMARY_COLUMNS = (
    "test",
    "action",
    "n_subjects",
    "n_identified",
    "torque_nm_median",
    "torque_nm_q1",
    "torque_nm_q3",
    "torque_nm_per_kg_median",
    "torque_nm_per_kg_q1",
    "torque_nm_per_kg_q3",
    "factor_median",
    "factor_q1",
    "factor_q3",
    "band_low_nm_per_kg",
    "band_high_nm_per_kg",
    "n_below_band_identified",
    "n_below_band",
    "not_identified_because",
)


def _quartiles(values: Sequence[float], nd: int) -> tuple[Any, Any, Any]:
    import numpy as np

    if not values:
        return "", "", ""
    q = np.percentile(np.asarray(values, dtype=float), [50.0, 25.0, 75.0])
    return round(float(q[0]), nd), round(float(q[1]), nd), round(float(q[2]), nd)


def cohort_summary_rows(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """One row per test (in first-seen order) of the strength rows of several subjects
    (:func:`strength_rows`): counts, the identified tests' median and quartiles, the band and
    the reasons the others were not identified (module docstring)."""
    tests: dict[str, list[Mapping[str, Any]]] = {}
    for r in rows:
        tests.setdefault(str(r["test"]), []).append(r)
    out = []
    for test, rs in tests.items():
        ident = [r for r in rs if r["status"] == "identified"]
        why: dict[str, int] = {}
        for r in rs:
            if r["status"] != "identified":
                key = str(r.get("failed_checks") or "interval too wide")
                why[key] = why.get(key, 0) + 1
        row: dict[str, Any] = {
            "test": test,
            "action": rs[0]["action"],
            "n_subjects": len(rs),
            "n_identified": len(ident),
            "band_low_nm_per_kg": rs[0].get("band_low_nm_per_kg", ""),
            "band_high_nm_per_kg": rs[0].get("band_high_nm_per_kg", ""),
            "n_below_band_identified": sum(int(r.get("below_published_band") or 0) for r in ident),
            "n_below_band": sum(int(r.get("below_published_band") or 0) for r in rs),
            "not_identified_because": "; ".join(
                f"{k}: {v}" for k, v in sorted(why.items(), key=lambda kv: -kv[1])
            ),
        }
        for key, nd in (("torque_nm", 1), ("torque_nm_per_kg", 3), ("factor", 3)):
            med, q1, q3 = _quartiles([float(r[key]) for r in ident], nd)
            row |= {f"{key}_median": med, f"{key}_q1": q1, f"{key}_q3": q3}
        out.append(row)
    return out


def write_summary_csv(path: str | Path, rows: Sequence[Mapping[str, Any]]) -> Path:
    """``strength_cohort_summary.csv`` (:data:`SUMMARY_COLUMNS`) of :func:`cohort_summary_rows`."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=SUMMARY_COLUMNS, lineterminator="\n")
        w.writeheader()
        w.writerows({k: r.get(k, "") for k in SUMMARY_COLUMNS} for r in rows)
    return path
