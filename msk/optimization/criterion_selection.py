"""Choosing a muscle-force criterion across subjects by a rule fixed in advance (leave one out).

A criterion (e.g. Σ w_i a_i^p of static optimisation with another p or other w) is scored per
subject by any agreement with evidence the criterion did not see — typically the median over EMG
channels of Pearson r between predicted activation and EMG (:mod:`msk.muscles.emg_agreement`).
The rule: a candidate replaces the ``incumbent`` only when

1. its median score over the subjects is the highest and exceeds the incumbent's by at least
   ``margin``;
2. leave-one-subject-out, the candidate with the highest median score over the *other* subjects
   is that same candidate in every fold (the choice does not hinge on one subject); and
3. in a majority of the folds it beats the incumbent on the held-out subject (the choice
   generalises to a subject it was not chosen on).

Ties go to the incumbent, then to the earlier candidate: a change has to win, not draw. This is
the cross-validated model selection of Stone (1974, J R Stat Soc B 36:111) with subjects as the
folds.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["CriterionChoice", "choose_criterion"]


@dataclass(frozen=True)
class CriterionChoice:
    """``scores`` (S, C) of ``subjects`` × ``candidates``; ``pooled`` (C,) the median over the
    subjects; ``best`` the highest pooled; per fold (held-out subject, in ``subjects`` order)
    the pick of the other subjects (``fold_picks``) and its held-out score minus the
    incumbent's (``fold_gain``); ``chosen`` the candidate the rule adopts (None: keep the
    incumbent) and ``reason`` in words."""

    candidates: tuple[str, ...]
    subjects: tuple[str, ...]
    scores: NDArray[np.float64]
    pooled: NDArray[np.float64]
    incumbent: str
    best: str
    fold_picks: tuple[str, ...]
    fold_gain: NDArray[np.float64]
    chosen: str | None
    reason: str


def _argbest(values: NDArray[np.float64], order: list[int]) -> int:
    """Index of the highest value, ties to the earliest in ``order``."""
    top = max(values[i] for i in order)
    return next(i for i in order if values[i] == top)


def choose_criterion(
    scores: Mapping[str, Mapping[str, float]], incumbent: str, *, margin: float = 0.05
) -> CriterionChoice:
    """Apply the module's rule to ``scores`` (subject → candidate → score, higher better; the
    candidates every subject has are compared, in the first subject's order, the incumbent
    first)."""
    subjects = tuple(scores)
    if len(subjects) < 2:
        raise ValueError("leave-one-subject-out needs at least 2 subjects")
    first = list(scores[subjects[0]])
    cands = [c for c in first if all(c in scores[s] for s in subjects)]
    if incumbent not in cands:
        raise ValueError(f"incumbent {incumbent!r} is not scored on every subject")
    cands = [incumbent] + [c for c in cands if c != incumbent]
    s = np.array([[float(scores[sub][c]) for c in cands] for sub in subjects])
    if not np.isfinite(s).all():
        raise ValueError("every score must be finite")
    order = list(range(len(cands)))
    pooled = np.median(s, axis=0)
    best = _argbest(pooled, order)
    picks, gain = [], []
    for k in range(len(subjects)):
        rest = np.delete(s, k, axis=0)
        pick = _argbest(np.median(rest, axis=0), order)
        picks.append(cands[pick])
        gain.append(s[k, pick] - s[k, 0])
    gains = np.array(gain)
    lead = float(pooled[best] - pooled[0])
    wins = int(np.sum([g > 0 and p == cands[best] for p, g in zip(picks, gains)]))
    if best == 0:
        chosen, reason = None, f"the incumbent {incumbent!r} has the best median score"
    elif lead < margin:
        chosen, reason = None, f"{cands[best]!r} leads by {lead:.3f} < margin {margin:g}"
    elif any(p != cands[best] for p in picks):
        chosen, reason = None, f"leave-one-subject-out picks {sorted(set(picks))}, not only it"
    elif wins * 2 <= len(subjects):
        chosen = None
        reason = f"{cands[best]!r} beats the incumbent on {wins} of {len(subjects)} held-out"
    else:
        chosen = cands[best]
        reason = (
            f"{chosen!r} leads by {lead:.3f}, picked in every fold, better on {wins} of "
            f"{len(subjects)} held-out subjects"
        )
    return CriterionChoice(
        tuple(cands), subjects, s, pooled, incumbent, cands[best], tuple(picks), gains,
        chosen, reason,
    )  # fmt: skip
