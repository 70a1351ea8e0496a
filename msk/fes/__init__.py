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

from __future__ import annotations

import importlib
from typing import Any

#: public name → the submodule that defines it: imported on first use (PEP 562), so that a
#: module of the package (:mod:`msk.fes.io`'s tables for the results folder) does not import
#: casadi, ``scipy.optimize`` and ``scipy.signal`` with the whole package
_NAMES = {
    "cross_validate": "msk.fes.identify",
    "geometry_from_height": "msk.fes.identify",
    "identify_force_length": "msk.fes.identify",
    "identify_pendulum_linear": "msk.fes.identify",
    "identify_pendulum_nonlinear": "msk.fes.identify",
    "identify_recruitment_current": "msk.fes.identify",
    "identify_recruitment_pw": "msk.fes.identify",
    "identify_series_stiffness": "msk.fes.identify",
    "identify_static_torque": "msk.fes.identify",
    "shank_anthropometry": "msk.fes.identify",
    "SEED001_SUBJECT": "msk.fes.model",
    "TABLE3": "msk.fes.model",
    "CalciumParams": "msk.fes.model",
    "FesSubject": "msk.fes.model",
    "GeometryParams": "msk.fes.model",
    "KneeParams": "msk.fes.model",
    "MuscleParams": "msk.fes.model",
    "RecruitmentCurrent": "msk.fes.model",
    "RecruitmentPW": "msk.fes.model",
    "FesSession": "msk.fes.protocol",
    "ProtocolResult": "msk.fes.protocol",
    "run_protocol": "msk.fes.protocol",
    "run_protocol_seed001": "msk.fes.protocol",
    "synthetic_session": "msk.fes.protocol",
    "FesTrajectory": "msk.fes.simulate",
    "simulate": "msk.fes.simulate",
    "Stimulation": "msk.fes.stimulation",
    "pulse_train": "msk.fes.stimulation",
    "stimulation_from_profile": "msk.fes.stimulation",
}


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


def __getattr__(name: str) -> Any:
    """Import a public name on first use (PEP 562)."""
    module = _NAMES.get(name)
    if module is None:
        raise AttributeError(f"module 'msk.fes' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
