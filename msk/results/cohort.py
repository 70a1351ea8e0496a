"""The cohort tables of many sessions, built from what their runs wrote.

:func:`cohort_row` turns one session's ``summary.json`` (:class:`msk.results.summary.Summary`)
into a row of ``cohort.csv`` (:data:`COHORT_COLUMNS`): key quality figures, the body mass and
its source, each side's spatiotemporal means, the strength groups per status word, the knee
contact's agreement with the measured force, the stages not available and the quality gates
raised; :func:`write_cohort_csv` writes the table (never replacing a file msk did not write).
:func:`compare_sessions` builds the table of generic against identified values across session
folders (``msk compare``) with the metrics of :mod:`msk.metrics`.
"""

from __future__ import annotations

import csv
import io
import os
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from msk.exceptions import BatchError
from msk.results.summary import Summary, as_summary

__all__ = [
    "COHORT_COLUMNS",
    "COMPARE_COLUMNS",
    "check_cohort_replaceable",
    "cohort_row",
    "compare_sessions",
    "write_cohort_csv",
]

#: Columns of ``cohort.csv`` (units in the names).
#: the spatiotemporal parameters of the cohort table (per side, mean over the session's strides)
_GAIT_COLUMNS = ("cycles", "walking_speed_m_s", "cadence_steps_per_min", "stride_length_m",
                 "stance_pct")  # fmt: skip

COHORT_COLUMNS: tuple[str, ...] = (
    "session",
    "config",
    "status",
    "error",
    "run_s",
    "mass_kg",
    "mass_source",
    "frames",
    "ik_marker_rms_mean_mm",
    "ik_failed_frames",
    "residual_force_rms_pct_bw",
    "residual_moment_rms_nm",
    "emg_flat_channels",
    "identified_mass_kg",
    "strength_fit_r2",
    "strength_groups_identified",
    "strength_groups_at_bound",
    "strength_groups_not_determined",
    "strength_group_status",
    "pooled_strength_group_status",
    "knee_contact_rms_bw",
    "knee_contact_icc",
    *(f"{p}_{side}" for side in ("left", "right") for p in _GAIT_COLUMNS),
    "stages_not_available",
    "quality_flags",
)


def _nan(x: float | None) -> float:
    """A summary number (``None`` where the run computed a non-finite one) as a float."""
    return float("nan") if x is None else x


def cohort_row(
    config: str,
    summary: Summary | Mapping[str, Any] | None,
    status: str,
    error: str,
    seconds: float,
) -> dict[str, Any]:
    """The cohort row (:data:`COHORT_COLUMNS`, empty strings where there is no value) of one
    session: ``config`` its configuration file, ``summary`` its ``summary.json`` (None for a
    failed session), ``status`` ``ok``/``failed``, ``error`` the one-line error, ``seconds``
    the run time. The strength columns count the groups per :mod:`msk.status` word and list
    each group's word; ``quality_flags`` counts the quality gates raised by quantity."""
    name = Path(config).stem
    row: dict[str, Any] = dict.fromkeys(COHORT_COLUMNS, "")
    row.update(session=name, config=config, status=status, error=error, run_s=round(seconds, 3))
    if not summary:
        return row
    s = as_summary(summary)
    q = s.quality
    row["session"] = s.session or name
    row["frames"] = "" if q.frames is None else q.frames
    if q.ik_marker_rms_mean_m is not None:
        row["ik_marker_rms_mean_mm"] = round(1000 * q.ik_marker_rms_mean_m, 3)
    row["ik_failed_frames"] = "" if q.ik_failed_frames is None else q.ik_failed_frames
    for k, v in (
        ("residual_force_rms_pct_bw", q.residual_force_rms_pct_bw),
        ("residual_moment_rms_nm", q.residual_moment_rms_nm),
        ("strength_fit_r2", q.strength_fit_r2),
    ):
        row[k] = "" if v is None else round(float(v), 4)
    row["emg_flat_channels"] = " ".join(q.emg_flat_channels or ())
    ident = s.identification
    if ident:
        row["identified_mass_kg"] = round(sum(_nan(g.mass_kg) for g in ident.segments), 3)
    st = s.strength
    if st:
        statuses = [(g.group, st.group_status(g)) for g in st.groups]
        for col, word in (
            ("strength_groups_identified", "identified"),
            ("strength_groups_at_bound", "at bound"),
            ("strength_groups_not_determined", "not determined"),
        ):
            row[col] = sum(s == word for _, s in statuses)
        row["strength_group_status"] = "; ".join(f"{n}: {s}" for n, s in statuses)
    ps = s.pooled_strength
    if ps:
        row["pooled_strength_group_status"] = "; ".join(
            f"{g.group}: {ps.group_status(g)}" for g in (*ps.groups, *ps.failed_channels)
        )
    comp = s.comparison and (
        s.comparison.knee_contact_subject_specific or s.comparison.knee_contact_generic
    )
    if comp:
        row["knee_contact_rms_bw"] = round(_nan(comp.rms_bw), 4)
        row["knee_contact_icc"] = round(_nan(comp.icc), 4)
    if s.subject.mass_kg is not None:
        row["mass_kg"] = round(float(s.subject.mass_kg), 2)
    row["mass_source"] = s.subject.mass_source or ""
    gait = s.gait
    for side in ("left", "right"):
        if gait is None:
            break
        row[f"cycles_{side}"] = (gait.cycles or {}).get(side, 0)
        params = (gait.spatiotemporal or {}).get(side)
        for p in _GAIT_COLUMNS[1:]:
            par = params.parameters.get(p) if params is not None else None
            if par is not None and par.mean is not None:
                row[f"{p}_{side}"] = round(float(par.mean), 4)
    row["stages_not_available"] = " ".join(i.stage for i in s.not_available or ())
    # the quality gates raised (what `msk run --strict` exits 3 for): the quantities, counted
    flags = [str(f.quantity) for f in q.flags or ()]
    row["quality_flags"] = " ".join(f"{k}×{flags.count(k)}" for k in dict.fromkeys(flags))
    return row


def check_cohort_replaceable(path: Path) -> None:
    """Refuse to replace ``path`` unless it is absent or a cohort table msk wrote: a regular
    file (not a symbolic link) whose header starts with :data:`COHORT_COLUMNS`' first four
    (a table of an msk with other columns is msk's too)."""
    if not os.path.lexists(path):
        return
    head = "session,config,status,error,"  # every msk's cohort table starts so
    ours = False
    if not path.is_symlink() and path.is_file():
        try:
            with open(path, encoding="utf-8", newline="") as fh:
                ours = fh.readline(4096).startswith(head)
        except (OSError, UnicodeDecodeError):
            ours = False
    if not ours:
        raise BatchError(
            f"{path}: exists and msk did not write it (not a cohort table of msk batch); "
            "refusing to replace it: move it or choose another --out"
        )


def write_cohort_csv(path: str | Path, rows: Sequence[Mapping[str, Any]]) -> Path:
    """The cohort table (one row per session, :data:`COHORT_COLUMNS`), written atomically;
    a ``cohort.csv`` msk did not write (or a symbolic link) is never replaced
    (:class:`~msk.exceptions.BatchError`)."""
    path = Path(path)
    check_cohort_replaceable(path)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(COHORT_COLUMNS), lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: r.get(k, "") for k in COHORT_COLUMNS})
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    with os.fdopen(fd, "w", encoding="utf-8", newline="") as fh:
        fh.write(buf.getvalue())
    os.chmod(tmp, 0o644)
    os.replace(tmp, path)
    return path


# ---------------------------------------------------------------------------------------------
# compare across session folders
# ---------------------------------------------------------------------------------------------
COMPARE_COLUMNS = (
    "session",
    "quantity",
    "item",
    "generic",
    "identified",
    "difference",
    "unit",
    "note",
)


def compare_sessions(folders: Sequence[str | Path]) -> list[dict[str, Any]]:
    """Generic vs identified, per session folder: segment masses (kg), strength factors (×),
    pelvis residuals (N, N·m) and the knee contact force against the measured one (RMS in BW,
    NRMSD %, Pearson r, ICC from :mod:`msk.metrics` on the ``knee_contact`` table). The
    ``note`` of a mass or strength row is its :mod:`msk.status` word (``identified``,
    ``at bound``, ``not determined``, ``prior``)."""
    from msk import metrics as compare
    from msk.results.folder import read_session

    rows: list[dict[str, Any]] = []

    def add(
        sess: str,
        qty: str,
        item: str,
        gen: float | None,
        ide: float | None,
        unit: str,
        note: str = "",
    ) -> None:
        gen, ide = _nan(gen), _nan(ide)
        rows.append(
            {
                "session": sess,
                "quantity": qty,
                "item": item,
                "generic": gen,
                "identified": ide,
                "difference": ide - gen,
                "unit": unit,
                "note": note,
            }
        )

    for folder in folders:
        res = read_session(folder)
        s = res.summary
        sess = str(s.session or Path(folder).name)
        ident = s.identification
        if ident:
            for seg in ident.segments:
                add(
                    sess,
                    "segment mass",
                    seg.name,
                    seg.prior_mass_kg,
                    seg.mass_kg,
                    "kg",
                    seg.status_word(),
                )
        st = s.strength
        if st:
            for grp in st.groups:
                add(
                    sess,
                    "strength factor",
                    grp.group,
                    1.0,
                    grp.factor,
                    "x generic",
                    st.group_status(grp),
                )
        ps = s.pooled_strength
        if ps:  # the session's trials pooled (msk strength)
            for grp in ps.groups:
                add(sess, "pooled strength factor", grp.group, 1.0, grp.factor, "x generic",
                    ps.group_status(grp))  # fmt: skip
        comp = s.comparison
        for key, unit, pair in (
            ("residual_force_rms_n", "N", comp.residual_force_rms_n if comp else None),
            ("residual_moment_rms_nm", "N·m", comp.residual_moment_rms_nm if comp else None),
        ):
            if pair is not None:
                add(
                    sess,
                    "pelvis residual RMS",
                    key.split("_rms")[0],
                    pair.generic,
                    pair.identified,
                    unit,
                )

        if res.has("knee_contact"):
            kc = res.table("knee_contact")
            if {"measured_total_bw", "generic_total_bw"} <= set(kc.columns):
                meas = kc.column("measured_total_bw")
                gen = kc.column("generic_total_bw")
                spec = (
                    kc.column("subject_specific_total_bw")
                    if "subject_specific_total_bw" in kc.columns
                    else None
                )
                m = np.isfinite(meas) & np.isfinite(gen)
                if spec is not None:
                    m &= np.isfinite(spec)
                if m.sum() >= 5:
                    for name, fn, unit in (
                        ("RMS error", compare.rms, "BW"),
                        ("NRMSD", compare.nrmsd, "%"),
                        ("Pearson r", compare.pearson_r, "1"),
                        ("ICC(2,1)", compare.icc, "1"),
                    ):
                        g = float(fn(meas[m], gen[m]))
                        i = float(fn(meas[m], spec[m])) if spec is not None else float("nan")
                        add(
                            sess,
                            "knee contact vs measured",
                            name,
                            g,
                            i,
                            unit,
                            f"{int(m.sum())} frames",
                        )
    return rows
