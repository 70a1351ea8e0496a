"""Parameter recovery of the FES protocol on synthetic legs (Benoussaad et al. 2013, Table 3, the
implanted-FES identification paper).

One *recovery run* simulates the protocol's trials from a leg's published parameters (with
noise, :func:`msk.fes.protocol.synthetic_session`), identifies the leg with
:func:`msk.fes.protocol.run_protocol` under given priors and returns the relative error of every
identified parameter against the published one.  ``bench/fes_recovery.py`` runs it on all the
legs and writes the table of ``docs/fes.md``; ``tests/fes/test_fes_recovery.py`` asserts its
figures.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from msk.exceptions import IdentificationError
from msk.fes.model import TABLE3, FesSubject, RecruitmentPW
from msk.fes.priors import population_priors
from msk.fes.protocol import TABLE1, fibre_fraction, run_protocol, synthetic_session

__all__ = [
    "RECOVERY_PARAMS",
    "RecoveryRun",
    "parameter_errors",
    "recovery_run",
]

#: Parameters compared, in table order.  ``F_cm·α_max`` is ``F_cm α(PW_max)``: the force at
#: full recruitment, the identifiable product (the protocol normalises ``α(PW_max)`` to 1, so
#: ``c1`` and ``F_cm`` separately are off by the leg's own ``α(PW_max)``, e.g. S5L 0.87).
RECOVERY_PARAMS: tuple[str, ...] = (
    "L_ext",
    "r_q",
    "K",
    "J",
    "B",
    "L_c0",
    "L_s",
    "b",
    "F_cm",
    "F_cm·α_max",
    "K_cm",
    "k_s",
    "c1",
    "c2",
    "c3",
)


def _values(s: FesSubject) -> dict[str, float]:
    g, k, m, r = s.geometry, s.knee, s.muscle, s.recruitment
    out = {
        "L_ext": g.L_ext,
        "r_q": g.r_q,
        "K": k.K,
        "J": k.J,
        "B": k.B,
        "L_c0": m.L_c0,
        "L_s": m.L_s,
        "b": m.b,
        "F_cm": m.F_cm,
        "K_cm": m.K_cm,
        "k_s": m.k_s,
    }
    if isinstance(r, RecruitmentPW):
        out |= {"F_cm·α_max": m.F_cm * float(r(r.pw_max)), "c1": r.c1, "c2": r.c2, "c3": r.c3}
    return out


def parameter_errors(truth: FesSubject, identified: FesSubject) -> dict[str, float]:
    """Relative error ``identified/truth − 1`` of every :data:`RECOVERY_PARAMS` entry."""
    a, b = _values(truth), _values(identified)
    return {k: b[k] / a[k] - 1.0 for k in RECOVERY_PARAMS if k in a and k in b and a[k] != 0}


@dataclass(frozen=True)
class RecoveryRun:
    """One leg identified under one pair of priors; ``error`` is empty when it failed."""

    leg: str
    fibre_fraction: float
    stiffness_ratio: float
    prior_error: dict[str, float]
    error: dict[str, float] = field(default_factory=dict)
    failure: str = ""
    notes: tuple[str, ...] = ()
    nrmsd_cross_validation: float = float("nan")
    seconds: float = float("nan")

    @property
    def ok(self) -> bool:
        return not self.failure


def recovery_run(
    leg: str,
    *,
    fibre_fraction_prior: float | None = None,
    stiffness_ratio_prior: float | None = None,
    seed: int = 7,
    torque_noise: float = 0.01,
    angle_noise_deg: float = 0.5,
    identify_stiffness_ratio: bool = False,
) -> RecoveryRun:
    """Identify Table 3 leg ``leg`` from its synthetic, noisy protocol data.

    Priors default to the Table 3 means *without the leg's subject* (both its legs left out,
    :func:`msk.fes.priors.population_priors`), so the prior never contains the leg's own
    published values.  Noise: ``torque_noise`` × each trial's peak torque and
    ``angle_noise_deg`` on the goniometer (Gaussian, seeded by ``seed``).
    """
    truth = TABLE3[leg]
    pop = population_priors(exclude=[leg[:-1]])
    ff = pop.fibre_fraction if fibre_fraction_prior is None else fibre_fraction_prior
    ratio = pop.stiffness_ratio if stiffness_ratio_prior is None else stiffness_ratio_prior
    prior_error = {
        "fibre_fraction": ff / fibre_fraction(truth) - 1.0,
        "stiffness_ratio": ratio / (truth.muscle.K_cm / truth.muscle.F_cm) - 1.0,
    }
    h, m = TABLE1[int(leg[1:-1])]
    ses = synthetic_session(
        truth,
        height=h,
        body_mass=m,
        torque_noise=torque_noise,
        angle_noise_deg=angle_noise_deg,
        rng=np.random.default_rng(seed),
    )
    t0 = time.perf_counter()
    try:
        res = run_protocol(
            ses,
            fibre_fraction=ff,
            stiffness_ratio=ratio,
            identify_stiffness_ratio=identify_stiffness_ratio,
        )
    except IdentificationError as e:
        return RecoveryRun(leg, ff, ratio, prior_error, failure=str(e))
    return RecoveryRun(
        leg,
        ff,
        ratio,
        prior_error,
        parameter_errors(truth, res.subject),
        notes=res.notes,
        nrmsd_cross_validation=res.cross_validation.nrmsd,
        seconds=time.perf_counter() - t0,
    )
