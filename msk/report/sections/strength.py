"""Section ``strength``: the strength factor of each EMG channel's muscle group against the
generic model (Hayashibe et al. 2011, Eq. 12–16), identified groups first, with its interval and
status; why each other group is not identified and the test that would identify it; the joint
strength curves (maximal isometric moments)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from markupsafe import Markup

from msk.report.format import STATUS_COLOURS, finite, group_statuses, num, or_, status_html
from msk.report.sections.base import ReportContext, Section
from msk.results.summary import PooledStrength, Strength, StrengthGroup
from msk.status import STRENGTH_R2_MIN

__all__ = ["LITERATURE_FACTOR_RANGE", "StrengthSection"]

#: Plausible strength-factor range (× generic F_iso): the EMG-driven vs OpenSim thesis, Table 3.1.
LITERATURE_FACTOR_RANGE = (0.5, 2.0)
#: identified first, then at bound, not determined, prior
_RANK = {"identified": 0, "at bound": 1, "not determined": 2, "prior": 3}


def _next_tests(groups: Sequence[StrengthGroup], status: Sequence[str]) -> list[Markup]:
    items = []
    for g, word in zip(groups, status):
        if word == "identified":
            continue
        reason = g.reason or word
        text = g.protocol.get("text") if g.protocol else None
        nxt = (
            Markup(" <b>Next protocol:</b> {}.").format(text)
            if text
            else Markup(" No isometric test of the model's joint actions loads this group.")
        )
        items.append(Markup("<b>{}</b> ({}): {}.{}").format(g.group, word, reason, nxt))
    return items


def _joint_strength(st: Strength) -> dict[str, Any] | None:
    js = st.joint_strength
    if not js:
        return None
    if js.error:
        return {"error": js.error}
    mass = js.mass_kg
    per_kg = finite(mass) and mass > 0
    acts = js.actions or ()
    undetermined = [a.action for a in acts if a.status in ("at bound", "not determined")]
    rows = []
    for a in acts:
        word = or_(a.status, "prior")
        gp, ip = a.generic_peak_nm, a.identified_peak_nm
        gen = num(gp, ".0f", "N·m")
        if per_kg and mass and finite(gp):
            gen += f" ({num(gp / mass, '.2f', 'N·m/kg')})"
        gen += f" at {num(a.generic_peak_angle_deg, '.0f', '°')}"
        if word in ("at bound", "not determined"):
            ide = "not determined"
        elif word == "prior":
            ide = "= generic (no identified group carries this action)"
        else:
            ide = num(ip, ".0f", "N·m")
            if per_kg and mass and finite(ip):
                ide += f" ({num(ip / mass, '.2f', 'N·m/kg')})"
            ide += f" at {num(a.identified_peak_angle_deg, '.0f', '°')}"
        groups = ", ".join(
            f"{g.group} {100 * or_(g.share, np.nan):.0f} % ({g.status})" for g in a.groups or ()
        )
        posture = ", ".join(f"{k} {v:.0f}°" for k, v in (a.posture_deg or {}).items())
        angles = a.angles_deg
        rng = f"{a.angle_label} {angles[0]:.0f}–{angles[-1]:.0f}°" if angles else str(a.angle_label)
        rows.append(
            [
                a.action,
                rng + (f"; {posture}" if posture else ""),
                gen,
                ide,
                groups or "none (generic muscles only)",
                status_html(word),
            ]
        )
    return {
        "error": None,
        "undetermined": undetermined,
        "rows": rows,
        "side": or_(js.side, ""),
        "share": or_(js.status_share_min, 0.05),
        "mass": num(mass, ".1f", "kg"),
        "norms_note": or_(js.norms_note, ""),
    }


def _pooled(ps: PooledStrength) -> dict[str, Any]:
    """The session's pooled strength for a clinician: identified groups first (maximal
    moment N·m and N·m/kg, factor vs generic with its interval), then each group not
    identified with its reason and the test that would determine it — no estimated F_iso or
    moment for those."""
    status = group_statuses(ps)
    mass = ps.mass_kg
    pct = round(100 * or_(ps.confidence, 0.95))
    rows = []
    for g, word in zip(ps.groups, status):
        if word != "identified":
            continue
        mom = num(g.moment_nm, ".0f", "N·m")
        if finite(g.moment_low_nm) and finite(g.moment_high_nm):
            mom += f" [{num(g.moment_low_nm, '.0f')}–{num(g.moment_high_nm, '.0f')}]"
        per_kg = "—"
        if mass and finite(mass) and mass > 0 and finite(g.moment_nm):
            per_kg = num(or_(g.moment_nm, np.nan) / mass, ".2f", "N·m/kg")
            if finite(g.moment_low_nm) and finite(g.moment_high_nm):
                lo, hi = or_(g.moment_low_nm, np.nan) / mass, or_(g.moment_high_nm, np.nan) / mass
                per_kg += f" [{lo:.2f}–{hi:.2f}]"
        rows.append(
            [
                g.group,
                ", ".join(g.muscles),
                or_(g.moment_test, "—"),
                mom,
                per_kg,
                f"{num(g.factor, '.2f', '×')} [{num(g.ci_low, '.2f')}–{num(g.ci_high, '.2f')}]",
            ]
        )
    others = [(g, w) for g, w in zip(ps.groups, status) if w != "identified"]
    others += [(g, "not determined") for g in ps.failed_channels]
    return {
        "rows": rows,
        "head": [
            "group (EMG)",
            "muscles",
            "maximal isometric test",
            f"moment [{pct} % CI]",
            "per body mass",
            f"factor vs generic [{pct} % CI]",
        ],
        "next_tests": _next_tests([g for g, _ in others], [w for _, w in others]),
        "trials": ", ".join(ps.trials),
        "normalisation": or_(ps.normalisation_kind, "—"),
        "bias": ps.normalisation_bias,
        "n": len(status) + len(ps.failed_channels),
        "n_identified": len(rows),
        "mass": num(mass, ".1f", "kg"),
    }


class StrengthSection(Section):
    key = "strength"
    title = "Muscle strength"
    order = 70

    def context(self, ctx: ReportContext) -> dict[str, Any] | None:
        if not ctx.gait:
            return None
        res = ctx.res
        st = res.summary.strength
        ps = res.summary.pooled_strength
        pooled = None if ps is None else _pooled(ps)
        na = [i for i in res.summary.not_available or () if i.stage in
              ("strength_identification", "emg")][:1]  # fmt: skip
        if not st:
            return {"st": None, "na": na, "pooled": pooled}
        side = or_(res.summary.subject.side, "right")
        other = "right" if side == "left" else "left"
        status = group_statuses(st)
        ident = [g for g, w in zip(st.groups, status) if w == "identified"]
        weaker = [g.group for g in ident if finite(g.ci_high) and g.ci_high < 1.0]
        stronger = [g.group for g in ident if finite(g.ci_low) and g.ci_low > 1.0]
        counts = {w: status.count(w) for w in STATUS_COLOURS if status.count(w)}
        r2 = st.r2
        r2_min = or_(st.r2_min, STRENGTH_R2_MIN)
        bounds = st.bounds or ("—", "—")
        msg = (
            f"Strength of the {side} leg muscles measured with EMG, relative to a typical adult "
            f"(the generic model = 1.0). Of {len(status)} muscle groups, "
            + ", ".join(f"{c} {w}" for w, c in counts.items())
            + ". "
        )
        if not ident:
            msg += (
                "No group's strength is determined by this session's data: the values below "
                "must not be read as the subject's strength. "
            )
        else:
            msg += (
                f"Clearly below typical: {', '.join(weaker)}. "
                if weaker
                else "No identified group is clearly below typical. "
            )
            msg += f"Clearly above typical: {', '.join(stronger)}. " if stronger else ""
        msg += (
            f"The {other} leg was not measured with EMG, so no left/right comparison of strength "
            "is possible in this session."
        )
        pct = round(100 * or_(st.confidence, 0.95))
        rows = []
        order = sorted(range(len(status)), key=lambda k: (_RANK.get(status[k], 9), k))
        for k in order:
            g, word = st.groups[k], status[k]
            ci = (
                f"{num(g.ci_low, '.2f')}–{num(g.ci_high, '.2f')} ×"
                if word != "prior" and finite(g.ci_low) and finite(g.ci_high)
                else "—"
            )
            rows.append(
                [
                    g.group,
                    ", ".join(g.muscles),
                    "generic (kept)" if word == "prior" else num(g.factor, ".2f", "×"),
                    ci,
                    num(g.f_iso_generic_n, ".0f", "N"),
                    num(g.f_iso_n, ".0f", "N") if word == "identified" else "—",
                    status_html(word),
                ]
            )
        failed = tuple(st.failed_channels or ())
        no_mvc = any("no MVC" in w for w in res.summary.quality.emg_warnings or ())
        return {
            "st": st,
            "na": na,
            "msg": msg,
            "unreliable": not finite(r2) or r2 < r2_min,
            "r2": num(r2, ".2f"),
            "r2_3": num(r2, ".3f"),
            "r2_min": num(r2_min, ".2f"),
            "bounds": bounds,
            "no_mvc": no_mvc,
            "head": [
                "group (EMG)",
                f"muscles ({side})",
                "strength factor",
                f"{pct} % CI (bootstrap)",
                "generic F_iso",
                "estimated F_iso",
                "status",
            ],
            "rows": rows,
            "next_tests": _next_tests(
                (*st.groups, *failed), (*status, *("not determined",) * len(failed))
            ),
            "range": LITERATURE_FACTOR_RANGE,
            "other": other,
            "method": st.method,
            "joint": _joint_strength(st),
            "pooled": pooled,
        }
