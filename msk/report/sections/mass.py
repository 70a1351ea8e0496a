"""Section ``mass``: segment masses and mass centres identified from the motion and the ground
forces (base-link equations, Hayashibe et al. 2011, §II) against the scaled generic model and an
anthropometric table (Dumas et al. 2007), with each segment's status and, in words, the
parameter combinations the motion does not determine."""

from __future__ import annotations

import re
from typing import Any

from msk.report.format import STATUS_COLOURS, finite, num, status_html
from msk.report.sections.base import ReportContext, Section
from msk.results.summary import Summary

__all__ = ["MassSection", "anthropometry_masses", "weak_direction_words"]


def anthropometry_masses(s: Summary) -> dict[str, float | None]:
    """The anthropometric table's segment masses (kg) by segment name."""
    anth = s.anthropometry
    return {} if anth is None else {k: v.mass_kg for k, v in anth.segments.items()}


_SEGMENT_WORDS = {
    "pelvis": "pelvis",
    "torso": "torso (trunk, head and arms)",
    "femur": "thigh",
    "tibia": "shank",
    "talus": "ankle bone (talus)",
    "calcn": "foot (heel)",
    "toes": "toes",
}
_PARAMETER_WORDS = {
    "m": "mass",
    "mx": "mass-centre position (front–back)",
    "my": "mass-centre position (along the segment)",
    "mz": "mass-centre position (sideways)",
}


def _segment_words(name: str) -> str:
    both = "(+_l)" in name
    base = name.replace("(+_l)", "")
    stem, side = (base[:-2], base[-2:]) if base[-2:] in ("_r", "_l") else (base, "")
    word = _SEGMENT_WORDS.get(stem, stem)
    if both:
        plural = {"thigh": "thighs", "shank": "shanks", "foot (heel)": "feet (heel)"}.get(
            word, word.replace("ankle bone", "ankle bones")
        )
        return f"{plural} (left and right together)"
    return {"_r": f"right {word}", "_l": f"left {word}"}.get(side, word)


def weak_direction_words(text: str) -> str | None:
    """A weak direction of the mass identification (``msk.dynamics.identification`` advice line
    ``weak direction (…): -0.59·pelvis.my +0.31·torso.m …``) in words, or None when ``text``
    is not one."""
    m = re.match(r"weak direction \((.*?)\):\s*(.*)$", text.strip())
    if not m:
        return None
    how, comb = m.groups()
    terms = re.findall(r"([+-]\d*\.?\d+)·(\S+)\.(\w+)", comb)
    if not terms:
        return None
    phrases: dict[str, set[int]] = {}
    for coef, seg, par in terms:
        what = _PARAMETER_WORDS.get(par, "rotational inertia")
        phrases.setdefault(f"the {_segment_words(seg)} {what}", set()).add(
            1 if float(coef) > 0 else -1
        )
    names = list(phrases)
    signs = set().union(*phrases.values())
    listed = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
    if how.startswith("no data"):
        why = "this motion carries no information on this combination"
    else:
        r = re.search(r"([\d.]+(?:e[+-]?\d+)?)×", how)
        why = (
            f"the data are {r.group(1)} times less precise on this combination than the "
            "generic value's spread"
            if r
            else "the data barely inform this combination"
        )
    if len(names) == 1:
        return f"{listed[0].upper()}{listed[1:]} is not determined ({why})."
    if len(signs) > 1:
        return (
            f"The data cannot tell {listed} apart: only a weighted sum of them is determined, "
            f"not each one — shifting from one to the other fits the measurements equally well "
            f"({why})."
        )
    return (
        f"The data cannot tell the common level of {listed}: only their balance is determined "
        f"— raising or lowering them all together fits the measurements equally well ({why})."
    )


class MassSection(Section):
    key = "mass"
    title = "Mass distribution"
    order = 80

    def context(self, ctx: ReportContext) -> dict[str, Any] | None:
        if not ctx.gait:
            return None
        s = ctx.res.summary
        ident = s.identification
        na = [i for i in s.not_available or () if i.stage == "mass_identification"][:1]
        if not ident:
            return {"ident": None, "na": na}
        anth = anthropometry_masses(s)
        status = [g.status_word() for g in ident.segments]
        counts = {w: status.count(w) for w in STATUS_COLOURS if status.count(w)}
        rows = []
        for g, word in zip(ident.segments, status):
            n = g.name
            key = ("foot" + n[-2:]) if n.startswith("calcn") else n
            tab = anth.get(key)
            com = g.com_m or (None,) * 3
            prior = g.prior_mass_kg
            change = (
                100.0 * (g.mass_kg - prior) / prior
                if finite(prior) and prior > 0 and finite(g.mass_kg)
                else None
            )
            rows.append(
                [
                    n,
                    num(g.mass_kg, ".2f", "kg"),
                    num(g.mass_std_kg, ".2f", "kg"),
                    num(prior, ".2f", "kg"),
                    num(change, "+.0f", "%"),
                    num(tab, ".2f", "kg") if tab is not None else "—",
                    " ".join(num(c, "+.3f") for c in com) + " m",
                    status_html(word),
                ]
            )
        at_prior = [g.name for g, w in zip(ident.segments, status) if w == "prior"]
        advice = list(ident.advice or ())
        seen: list[str] = []
        for a in advice:
            words = weak_direction_words(a)
            if words and words not in seen:
                seen.append(words)
        return {
            "ident": ident,
            "na": na,
            "counts": ", ".join(f"{c} {w}" for w, c in counts.items()),
            "n_segments": len(status),
            "rows": rows,
            "condition": num(ident.condition_number, ".3g"),
            "n_frames": ident.n_frames,
            "not_excited": at_prior if any(a.startswith("not excited") for a in advice) else [],
            "weak": seen[:5],
            "other_advice": [
                a for a in advice if not a.startswith(("not excited", "weak direction"))
            ],
        }
