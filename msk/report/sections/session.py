"""Section ``session``: the session at a glance — trials, gait events and where they came from,
the data-quality figures against their thresholds (Hicks et al. 2015), marker gaps and EMG
warnings."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from msk.report.format import check, finite, num, or_
from msk.report.sections.base import ReportContext, Section
from msk.status import STRENGTH_R2_MIN

__all__ = ["SessionSummary", "event_source_words"]

#: Quality-gate quantities shown as rows of the data-quality table.
_QUALITY_ROW_QUANTITIES = {
    "ik_marker_rms_mean_m",
    "ik_marker_max_mean_m",
    "residual_force_rms_pct_bw",
    "residual_moment_rms_pct_com_height_peak_force",
    "plate_mass_difference_pct",
    "optimization_infeasible_frames",
}
#: the thresholds the data-quality table prints
_THRESHOLDS_SHOWN = (
    "ik_marker_rms_mean_m",
    "ik_marker_max_mean_m",
    "observed_measured_frames_min_pct",
    "unmeasured_contact_inside_pct",
    "residual_force_rms_pct_bw",
    "residual_moment_rms_pct_com_height_peak_force",
    "body_mass_difference_pct",
)
#: ``summary.event_sources`` words → what a clinician reads
_SOURCE_WORDS = {
    "file": "C3D events",
    "plates": "force plates",
    "kinematics": "marker kinematics",
    "plates+kinematics": "force plates and marker kinematics",
    "none": "none found",
}


def event_source_words(sources: Any, side: str | None = None, kind: str = "foot strike") -> str:
    """Where the ``side``'s ``kind`` events came from (``summary.event_sources``), in words;
    with ``side`` None, every side and kind recorded."""
    src = sources if isinstance(sources, Mapping) else {}
    if side is not None:
        word = src.get(f"{side} {kind}")
        return _SOURCE_WORDS.get(str(word), str(word)) if word else "source not recorded"
    parts = [
        f"{k}: {_SOURCE_WORDS.get(str(v), str(v))}"
        for k, v in src.items()
        if k != "notes" and isinstance(v, str)
    ]
    return "; ".join(parts) if parts else "source not recorded"


class SessionSummary(Section):
    key = "session"
    title = "Session and data quality"
    order = 10

    def context(self, ctx: ReportContext) -> dict[str, Any] | None:
        if not ctx.gait:
            return None
        s = ctx.res.summary
        q = s.quality
        # the thresholds the run judged with (summary.quality.thresholds); msk's own for any
        # the summary lacks
        TH = {k: v for k, v in (q.thresholds or {}).items() if finite(v)}
        if not set(_THRESHOLDS_SHOWN) <= set(TH):
            from msk.quality import THRESHOLDS

            TH = {**THRESHOLDS, **TH}
        flags = q.flags or ()
        raised = {f.quantity for f in flags}

        def gate(quantity: str) -> bool | None:
            return (quantity in raised) if q.flags is not None else None

        plate = [f for f in flags if f.quantity == "plate_mass_difference_pct"]
        ik_mean, ik_max = q.ik_marker_rms_mean_m, q.ik_marker_rms_max_m
        rf = q.residual_force_rms_pct_bw
        flat = q.emg_flat_channels or ()
        st = s.strength
        r2_min = or_(st.r2_min, STRENGTH_R2_MIN) if st else STRENGTH_R2_MIN
        hicks = ctx.cite("hicks2015")
        rows: list[list[Any]] = [
            ["frames", f"{or_(q.frames, '—')} at {num(q.rate_hz, '.0f', 'Hz')}", "—", "—"],
            [
                "IK marker error, mean",
                num(1000 * ik_mean, ".1f", "mm") if finite(ik_mean) else "—",
                f"≤ {1000 * TH['ik_marker_rms_mean_m']:g} mm {hicks}",
                check(ik_mean, TH["ik_marker_rms_mean_m"], flagged=gate("ik_marker_rms_mean_m")),
            ],
            [
                "IK marker error, worst frame",
                num(1000 * ik_max, ".1f", "mm") if finite(ik_max) else "—",
                f"worst marker ≤ {1000 * TH['ik_marker_max_mean_m']:g} mm on average {hicks}",
                check(ik_max, TH["ik_marker_max_mean_m"], flagged=gate("ik_marker_max_mean_m")),
            ],
            ["marker most often worst", or_(q.ik_worst_marker, "—"), "—", "—"],
            ["IK failed frames", or_(q.ik_failed_frames, "—"), "0", check(q.ik_failed_frames, 0)],
            [
                "frames with all ground contact on plates (residuals, muscle forces)",
                f"{or_(q.contact_measured_frames, '—')} of {or_(q.frames, '—')}",
                "—",
                "—",
            ],
            [
                "of those, frames whose leg segments the markers observe (residuals, "
                "identification)",
                f"{or_(q.observed_measured_frames, '—')}",
                f"≥ {TH['observed_measured_frames_min_pct']:g} %",
                "—",
            ],
            [
                "frames with a foot on an unmeasured surface (that leg's torques not written)",
                f"{or_(q.unmeasured_contact_frames, '—')} "
                f"({num(q.unmeasured_contact_inside_pct, '.0f', '%')} of the measured span)",
                f"≤ {TH['unmeasured_contact_inside_pct']:g} % of the span",
                check(
                    q.unmeasured_contact_inside_pct,
                    TH["unmeasured_contact_inside_pct"],
                    flagged=gate("unmeasured_contact_inside_pct"),
                ),
            ],
            [
                "pelvis residual force (RMS)",
                f"{num(q.residual_force_rms_n, '.1f', 'N')} ({num(rf, '.1f', '% BW')})",
                f"≤ {TH['residual_force_rms_pct_bw']:g} % BW {hicks}",
                check(
                    rf, TH["residual_force_rms_pct_bw"], flagged=gate("residual_force_rms_pct_bw")
                ),
            ],
            [
                "pelvis residual moment (RMS)",
                num(q.residual_moment_rms_nm, ".1f", "N·m"),
                f"≤ {TH['residual_moment_rms_pct_com_height_peak_force']:g} % of COM height × "
                f"peak external force {hicks}",
                check(
                    q.residual_moment_rms_nm,
                    float("inf"),
                    flagged=gate("residual_moment_rms_pct_com_height_peak_force"),
                ),
            ],
            [
                "body mass weighed by the force plates vs configured",
                num(plate[0].value, "+.1f", "%") if plate else "—",
                f"within ±{TH['body_mass_difference_pct']:g} %",
                check(None, 0.0, flagged=gate("plate_mass_difference_pct"), needs_value=False),
            ],
            [
                "EMG channels flat / unusable",
                ", ".join(flat) or "none",
                "none",
                check(len(flat), 0) if q.emg_flat_channels is not None else "—",
            ],
            [
                "optimisation infeasible frames",
                or_(q.optimization_infeasible_frames, "—"),
                "0",
                check(
                    q.optimization_infeasible_frames,
                    0,
                    flagged=gate("optimization_infeasible_frames"),
                ),
            ],
        ]
        if st:
            rows.append(
                [
                    "strength fit r² (EMG-driven model vs joint moments)",
                    num(st.r2, ".2f"),
                    f"≥ {num(r2_min, '.2f')} for any group to be identified",
                    check(st.r2, r2_min, below=False),
                ]
            )
        warns = q.emg_warnings or ()
        no_mvc = [w.split("'")[1] for w in warns if "no MVC" in w and w.count("'") >= 2]
        events = [(e.label, e.context or "", num(e.time, ".3f", "s")) for e in (s.events or ())]
        notes = s.event_sources.get("notes") if isinstance(s.event_sources, Mapping) else ()
        trials = [
            i for t in (ctx.trials or (ctx.res,)) for i in t.summary.inputs if i.role == "task"
        ]
        static = [i for i in s.inputs if i.role == "static"]
        return {
            "trial": s.trial,
            "task_files": [i.path.replace("\\", "/").rsplit("/", 1)[-1] for i in trials],
            "static_files": [i.path.replace("\\", "/").rsplit("/", 1)[-1] for i in static],
            "events": events,
            "event_sources": event_source_words(s.event_sources),
            "event_notes": [str(n) for n in (notes or ()) if isinstance(n, str)],
            "rows": rows,
            "other_flags": [
                f for f in (q.flags or ()) if f.quantity not in _QUALITY_ROW_QUANTITIES
            ],
            "gaps": [
                [g.marker, or_(g.missing_frames, "—"), or_(g.longest_gap_frames, "—")]
                for g in (q.marker_gaps or ())
            ],
            "emg_warnings": [w for w in warns if "no MVC" not in w][:8],
            "no_mvc": no_mvc,
        }
