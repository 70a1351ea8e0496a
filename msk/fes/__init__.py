"""FES-driven knee: the quadriceps–shank model of Benoussaad et al. 2013 (and the implanted-FES
identification paper) and its identification protocol.

* :mod:`msk.fes.model` — parameters (frozen dataclasses), the Table 3 sets of
  Benoussaad et al. 2013, the implanted-FES identification paper's
  subject, recruitment functions;
* :mod:`msk.fes.stimulation` — pulse trains;
* :mod:`msk.fes.simulate` — casadi simulation (RK4 on the stimulation grid, or CVODES);
* :mod:`msk.fes.identify` — the identification steps, each with its NRMSD/NRMSE;
* :mod:`msk.fes.protocol` — session data, synthetic sessions, :func:`run_protocol`;
* :mod:`msk.fes.io` — CSV / C3D-analog inputs and result tables.
"""

from msk.fes.identify import (
    cross_validate,
    geometry_from_height,
    identify_force_length,
    identify_pendulum_linear,
    identify_pendulum_nonlinear,
    identify_recruitment_current,
    identify_recruitment_pw,
    identify_series_stiffness,
    identify_static_torque,
    shank_anthropometry,
)
from msk.fes.model import (
    SEED001_SUBJECT,
    TABLE3,
    CalciumParams,
    FesSubject,
    GeometryParams,
    KneeParams,
    MuscleParams,
    RecruitmentCurrent,
    RecruitmentPW,
)
from msk.fes.protocol import (
    FesSession,
    ProtocolResult,
    run_protocol,
    run_protocol_seed001,
    synthetic_session,
)
from msk.fes.simulate import FesTrajectory, simulate
from msk.fes.stimulation import Stimulation, pulse_train, stimulation_from_profile

__all__ = [
    "SEED001_SUBJECT",
    "TABLE3",
    "CalciumParams",
    "FesSession",
    "FesSubject",
    "FesTrajectory",
    "GeometryParams",
    "KneeParams",
    "MuscleParams",
    "ProtocolResult",
    "RecruitmentCurrent",
    "RecruitmentPW",
    "Stimulation",
    "cross_validate",
    "geometry_from_height",
    "identify_force_length",
    "identify_pendulum_linear",
    "identify_pendulum_nonlinear",
    "identify_recruitment_current",
    "identify_recruitment_pw",
    "identify_series_stiffness",
    "identify_static_torque",
    "pulse_train",
    "run_protocol",
    "run_protocol_seed001",
    "shank_anthropometry",
    "simulate",
    "stimulation_from_profile",
    "synthetic_session",
]
