"""The recordable test that would identify a strength group: computed from the subject's model.

For a group G that the session did not identify, every joint action of
:data:`msk.strength.joint_strength.ACTIONS` is evaluated on the subject's (scaled) model at each
angle of its grid, every agonist fully activated at zero velocity
(:func:`msk.strength.joint_strength.max_isometric_moment_curves`)::

    M_G(θ)   = Σ_{i ∈ G} s r_i(θ) F_iso,i f_l(l̃_i(θ)) cos α_i(θ)      (the group's moment, N·m)
    share(θ) = M_G(θ) / M(θ)                                         (of the action's moment)
    score(θ) = M_G(θ) · share(θ)

The recommended test is the isometric maximal voluntary contraction (MVC) of the action and
angle of largest score: the group's moment arm × force–length is large there and its synergists'
share small, so the measured torque at that posture is mostly the group's. With an MVC-
normalised EMG of the group, Hayashibe et al. (2011, §VI.A) identify its factor from such
trials; the expected share says how much of the measured torque the group's factor scales.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from msk.exceptions import ModelError
from msk.strength.joint_strength import (
    ACTIONS,
    JointStrengthCurves,
    max_isometric_moment_curves,
)

__all__ = ["CANDIDATE_POSTURES", "TestProtocol", "recommend_test", "recommend_tests"]

#: Postures of the coordinates held while an action's coordinate is swept (swept coordinate stem
#: → held stem → deg in the model's convention; gait2392: ``knee_angle`` negative in flexion).
#: The dynamometer positions clinics use: knee extended or flexed for ankle tests (the knee
#: flexed slackens the gastrocnemii: soleus isolated), hip extended, flexed 45° (supine or
#: reclined) or 90° (seated) for knee tests (the hip flexed slackens the rectus femoris, the
#: hip extended the hamstrings), knee extended or flexed 60°/90° for hip tests.
CANDIDATE_POSTURES: tuple[dict[str, dict[str, float]], ...] = (
    {"ankle_angle": {}, "knee_angle": {}, "hip_flexion": {"knee_angle": -60.0},
     "hip_adduction": {"knee_angle": -60.0}},
    {"ankle_angle": {"knee_angle": -90.0}, "knee_angle": {"hip_flexion": 90.0},
     "hip_flexion": {"knee_angle": 0.0}, "hip_adduction": {"knee_angle": 0.0}},
    {"ankle_angle": {"knee_angle": -45.0}, "knee_angle": {"hip_flexion": 45.0},
     "hip_flexion": {"knee_angle": -90.0}, "hip_adduction": {"knee_angle": -90.0}},
)  # fmt: skip


@dataclass(frozen=True)
class TestProtocol:
    """An isometric MVC test: ``action`` (e.g. ``"knee extension"``) about ``coordinate`` at
    ``angle_deg`` (clinical convention ``angle_label``), the other coordinates held at
    ``posture_deg`` (the model's convention, deg); ``group_moment_nm`` the group's expected
    maximal moment there on the generic model, ``total_moment_nm`` the action's, ``share`` the
    group's share, ``synergists`` the other muscles carrying ≥ 5 % of it."""

    group: str
    action: str
    coordinate: str
    angle_label: str
    angle_deg: float
    posture_deg: Mapping[str, float]
    group_moment_nm: float
    total_moment_nm: float
    share: float
    synergists: tuple[str, ...]

    @property
    def score(self) -> float:
        """M_G · share (N·m): what the choice maximises (module docstring)."""
        return self.group_moment_nm * self.share

    @property
    def text(self) -> str:
        """One sentence for the report."""
        held = ", ".join(f"{k} {v:g}°" for k, v in self.posture_deg.items())
        return (
            f"isometric MVC of {self.action} at {self.angle_label} {self.angle_deg:g}°"
            + (f" ({held})" if held else "")
            + f", with the group's EMG: the model expects {self.group_moment_nm:.0f} N·m from "
            f"this group, {100 * self.share:.0f} % of the {self.total_moment_nm:.0f} N·m maximal "
            "moment"
        )

    def as_dict(self) -> dict[str, Any]:
        """JSON record (``summary.json`` ``strength.groups[*].protocol``)."""
        return {
            "test": "isometric MVC",
            "action": self.action,
            "coordinate": self.coordinate,
            "angle_label": self.angle_label,
            "angle_deg": self.angle_deg,
            "posture_deg": dict(self.posture_deg),
            "group_moment_nm": self.group_moment_nm,
            "total_moment_nm": self.total_moment_nm,
            "share": self.share,
            "synergists": list(self.synergists),
            "text": self.text,
        }


def _best(curves: JointStrengthCurves, group: str, muscles: Sequence[str]) -> TestProtocol | None:
    members = set(muscles)
    best: tuple[float, TestProtocol] | None = None
    for c in curves.curves.values():
        if c.contributions_nm is None:
            continue
        cols = [k for k, m in enumerate(c.muscles) if m in members]
        if not cols:
            continue
        mg = c.contributions_nm[:, cols].sum(axis=1)
        total = np.asarray(c.moment_nm, dtype=float)
        share = np.where(total > 0, mg / np.where(total > 0, total, 1.0), 0.0)
        score = mg * share
        i = int(np.argmax(score))
        if score[i] <= 0:
            continue
        others = [
            m
            for k, m in enumerate(c.muscles)
            if m not in members and total[i] > 0 and c.contributions_nm[i, k] >= 0.05 * total[i]
        ]
        proto = TestProtocol(
            group=group,
            action=c.action,
            coordinate=c.coordinate,
            angle_label=c.angle_label,
            angle_deg=float(c.angles_deg[i]),
            posture_deg=dict(c.posture_deg),
            group_moment_nm=float(mg[i]),
            total_moment_nm=float(total[i]),
            share=float(share[i]),
            synergists=tuple(others),
        )
        if best is None or score[i] > best[0]:
            best = (float(score[i]), proto)
    return None if best is None else best[1]


def recommend_test(
    model: Any, group: str, muscles: Sequence[str], *, side: str
) -> TestProtocol | None:
    """The isometric MVC of ``model`` (module docstring) that best isolates ``muscles`` (the
    group ``group``) on ``side``; None when no action of
    :data:`msk.strength.joint_strength.ACTIONS` loads them."""
    return recommend_tests(model, {group: muscles}, side=side).get(group)


def recommend_tests(
    model: Any, groups: Mapping[str, Sequence[str]], *, side: str
) -> dict[str, TestProtocol | None]:
    """:func:`recommend_test` for every group (the moment curves computed once)."""
    if not groups:
        return {}
    best: dict[str, tuple[float, TestProtocol]] = {}
    for held in CANDIDATE_POSTURES:
        postures = {a: dict(held[ACTIONS[a].coordinate]) for a in ACTIONS}
        try:
            curves = max_isometric_moment_curves(
                model, side=side, contributions=True, posture_deg=postures
            )
        except (KeyError, ValueError) as exc:  # a model without the actions' coordinates
            raise ModelError(f"no joint action of the model to test strength on: {exc}") from None
        for g, m in groups.items():
            p = _best(curves, g, m)
            if p is not None and (g not in best or p.score > best[g][0]):
                best[g] = (p.score, p)
    return {g: best[g][1] if g in best else None for g in groups}
