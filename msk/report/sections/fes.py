"""Section ``fes``: the FES knee model of Benoussaad et al. 2013 (Eq. 1–7, 10) identified from
the session's stimulation trials — its parameters with their status and the published ranges
(Table 3), the fit of each protocol step (NRMSD, Eq. 9; Table 2) and the cross-validation
trial."""

from __future__ import annotations

from typing import Any

import numpy as np

from msk.report.format import num, or_, status_html
from msk.report.sections.base import ReportContext, Section
from msk.status import FES_DETERMINED_BY_PROTOCOL, FES_NRMSD_MAX_PCT, fes_status

__all__ = ["FesSection"]

#: Meaning of the FES model parameters (Benoussaad et al. 2013, Eq. 1–7, 10).
_FES_MEANING = {
    "geometry.L_ext": "quadriceps muscle–tendon length at full extension",
    "geometry.r_q": "quadriceps moment arm",
    "knee.J": "shank + foot inertia about the knee",
    "knee.B": "knee viscous damping",
    "knee.K": "static torque (gravity + passive elasticity)",
    "muscle.F_cm": "maximal contractile force",
    "muscle.K_cm": "maximal contractile stiffness",
    "muscle.L_c0": "optimal contractile-element length",
    "muscle.b": "force–length width",
    "muscle.k_s": "series-element (tendon) stiffness",
    "muscle.L_s": "series-element slack length",
    "recruitment.c1": "recruitment sigmoid: maximum",
    "recruitment.c2": "recruitment sigmoid: slope",
    "recruitment.c3": "recruitment sigmoid: threshold (PW/PW_max)",
}
#: The protocol step whose fit identifies each FES parameter (the others are protocol priors).
_FES_PARAMETER_STEP = {
    "knee.K": "static_torque",
    "knee.J": "joint_mechanics",
    "knee.B": "joint_mechanics",
    "muscle.L_c0": "force_length",
    "muscle.b": "force_length",
    "muscle.F_cm": "recruitment",
    "recruitment.c1": "recruitment",
    "recruitment.c2": "recruitment",
    "recruitment.c3": "recruitment",
    "muscle.k_s": "nlp_ks",
}
_FES_STEPS = {
    "static_torque": "static torque (K)",
    "joint_mechanics": "joint mechanics, pendulum (J, B)",
    "force_length": "force–length (L_c0, b)",
    "recruitment": "recruitment (c1, c2, c3)",
    "nlp_ks": "NLP identification (k_s)",
    "cross_validation_initial": "cross-validation before k_s identification",
    "cross_validation": "cross-validation, identified model",
}


def _fes_references() -> tuple[dict[str, tuple[float, float]], dict[str, tuple[float, float]]]:
    """Parameter ranges (Table 3) and NRMSD ranges (Table 2) of the FES identification study
    Benoussaad et al. 2013 (literature, for context)."""
    from msk.fes.model import TABLE2_NRMSD_PCT, TABLE3

    t3 = {}
    for key in _FES_MEANING:
        grp, name = key.split(".")
        vals = [float(getattr(getattr(subj, grp), name)) for subj in TABLE3.values()]
        t3[key] = (min(vals), max(vals))
    t2 = {}
    for key, row in TABLE2_NRMSD_PCT.items():
        vals = [v for v in row if v is not None]
        t2[key] = (float(min(vals)), float(max(vals)))
    return t3, t2


class FesSection(Section):
    key = "fes"
    title = "FES knee model"
    order = 85

    def context(self, ctx: ReportContext) -> dict[str, Any] | None:
        s = ctx.res.summary
        na = [i for i in s.not_available or () if i.stage == "fes"][:1]
        fes = s.fes
        if not fes and not na:
            return None
        if not fes:
            return {"fes": None, "na": na}
        t3, t2 = _fes_references()
        steps = or_(fes.steps, {})
        cv_step = steps.get("cross_validation")
        from msk.fes.model import TABLE2_NRMSD_PCT

        seed_cv = [v for v in TABLE2_NRMSD_PCT["cross_validation"] if v is not None]
        rows = []
        initial = fes.initial_parameters or {}
        for key, item in fes.parameters.items():
            unit = or_(item.unit, "")
            r = t3.get(key)
            step = _FES_PARAMETER_STEP.get(key)
            fit = steps.get(step) if step else None
            word = fes_status(
                item.value,
                prior=initial.get(key),
                from_prior=step is None,
                nrmsd_pct=fit.nrmsd_pct if fit else None,
                determined=key in FES_DETERMINED_BY_PROTOCOL,
            ).value
            rows.append(
                [
                    key,
                    _FES_MEANING.get(key, ""),
                    num(item.value, ".4g"),
                    {"1": "dimensionless", "1 (PW/PW_max)": "PW/PW_max"}.get(unit, unit),
                    "—" if r is None else f"{r[0]:.4g} – {r[1]:.4g}",
                    status_html(word),
                ]
            )
        step_rows = []
        for key, label in _FES_STEPS.items():
            if key not in steps:
                continue
            r = t2.get(key)
            step_rows.append(
                [
                    label,
                    num(steps[key].nrmsd_pct, ".2f", "%"),
                    num(steps[key].nrmse_pct, ".2f", "%"),
                    "—" if r is None else f"{r[0]:.2f} – {r[1]:.2f} %",
                ]
            )
        return {
            "fes": fes,
            "na": na,
            "cv": num(cv_step.nrmsd_pct if cv_step else None, ".1f", "%"),
            "seed_median": f"{float(np.median(seed_cv)):.1f}",
            "seed_n": len(seed_cv),
            "rows": rows,
            "step_rows": step_rows,
            "nrmsd_max": f"{FES_NRMSD_MAX_PCT:g}",
        }
