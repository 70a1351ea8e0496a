"""Stage ``comparison``: subject-specific against generic — joint torques and pelvis residuals
with identified against generic inertias, predicted knee contact against the measured force
(:mod:`msk.metrics` figures), identified strength factors against 1."""

from __future__ import annotations

from typing import Any

import numpy as np

from msk.dynamics.inverse import InverseDynamics
from msk.metrics import root_mean_square as rms
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.records import GaitCycle, KneeContact, Loads, StrengthIdentification
from msk.pipeline.runner import StageUnavailable

__all__ = ["contact_agreement", "measured_component", "run"]


def measured_component(measured: Any) -> str:
    """What the measured total knee contact force is (``"axial"``, ``"magnitude"``,
    ``"unstated"``: :attr:`msk.io.contact_force.MeasuredContact.component`)."""
    return str(getattr(measured, "component", "unstated") or "unstated")


def contact_agreement(
    measured: np.ndarray, predicted: np.ndarray, bw: float, *, component: str | None = None
) -> dict[str, Any]:
    """Agreement figures (:mod:`msk.metrics`) of a predicted knee contact force with the
    measured one; ``bw`` body weight (N); ``component`` names the force compared (``axial``,
    ``magnitude``…), stated in the figures."""
    from msk import metrics as compare

    a, b = measured, predicted
    named = {} if component is None else {"component": component}
    return {
        **named,
        "rms_n": float(compare.rms(a, b)),
        "rms_bw": float(compare.rms(a, b)) / bw,
        "nrmsd_pct": float(compare.nrmsd(a, b)),
        "pearson_r": float(compare.pearson_r(a, b)),
        "spearman_rho": float(compare.spearman(a, b)),
        "icc": float(compare.icc(a, b)),
        "peak_difference_n": float(compare.peak_difference(b, a)),
        "peak_measured_bw": float(a.max() / bw),
        "peak_predicted_bw": float(b.max() / bw),
        "n_frames": int(a.size),
    }


def run(
    inputs: SessionInputs,
    loads: Loads,
    inverse_dynamics: InverseDynamics,
    knee_contact: KneeContact | None,
    strength_identification: StrengthIdentification | None,
    gait_cycle: GaitCycle | None,
) -> dict[str, Any]:
    from msk import metrics as compare

    out: dict[str, Any] = {}
    sfx, bw = inputs.sfx, inputs.body_weight
    if inverse_dynamics.identified is not None:
        g, s = inverse_dynamics.generic, inverse_dynamics.identified
        good = np.isfinite(g.tau).all(axis=1) & np.isfinite(s.tau).all(axis=1) & loads.usable
        leg = [i for i, c in enumerate(g.coordinate_names) if c.endswith(sfx)]
        out["torque_rms_difference_nm"] = {
            g.coordinate_names[i]: float(compare.rms(g.tau[good, i], s.tau[good, i])) for i in leg
        }
        out["residual_force_rms_n"] = {
            "generic": rms(g.residual_force[good]),
            "identified": rms(s.residual_force[good]),
        }
        out["residual_moment_rms_nm"] = {
            "generic": rms(g.residual_moment[good]),
            "identified": rms(s.residual_moment[good]),
        }
    measured = None if gait_cycle is None else gait_cycle.measured_contact
    if knee_contact is not None and measured:
        # the like component: a measured total is axial (load cells, medial + lateral) or a
        # magnitude (msk.io.contact_force.MeasuredContact.component); the compartments are axial
        total_is = measured_component(knee_contact.measured)
        for name, pred in knee_contact.variants.items():
            for comp, meas in measured.items():
                p = pred.component(total_is) if comp == "total" else getattr(pred, comp)
                m = np.isfinite(meas) & np.isfinite(p)
                if m.sum() < 5:
                    continue
                key = f"knee_contact_{name}" + ("" if comp == "total" else f"_{comp}")
                what = f"{total_is} total" if comp == "total" else f"{comp} axial"
                out[key] = contact_agreement(meas[m], p[m], bw, component=what)
    if strength_identification is not None:
        p = strength_identification.profile
        out["strength_factor_minus_generic"] = {
            n: float(f - 1.0) for n, f in zip(p.group_names, p.factors)
        }
    if not out:
        raise StageUnavailable("nothing to compare")
    return out
