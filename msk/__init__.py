"""msk: subject-specific musculoskeletal analysis of the lower limb on Pinocchio.

Data flows one way (see ``docs/architecture.md``)::

    read_trial -> Trial -> solve_kinematics -> Kinematics -> external_loads -> ExternalLoads
      -> InertialIdentifier.fit -> model.with_inertias -> inverse_dynamics -> JointTorques
      -> muscle_geometry -> solve_muscle_forces -> MuscleForces -> StrengthIdentifier.fit
      -> knee_contact_force -> comparison -> report

``run_session`` runs that chain on a session configuration and writes a results folder;
``read_session`` reads one back, typed. All quantities inside are SI (m, s, rad, N, N·m, kg);
time is axis 0. The names below are imported on first use, so ``import msk`` stays light.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from msk.exceptions import MskError

__version__ = "0.4.0"

#: the package's face: public name -> module that defines it
_NAMES = {
    "read_trial": "msk.io.readers",
    "read_dynamometer": "msk.io.dynamometer",
    "Trial": "msk.trial",
    "Model": "msk.model.core",
    "load_model": "msk.model.files",
    "load_osim": "msk.model.osim",
    "scale_model": "msk.personalise.scaling",
    "solve_kinematics": "msk.kinematics.ik",
    "external_loads": "msk.dynamics.loads",
    "inverse_dynamics": "msk.dynamics.inverse",
    "InertialIdentifier": "msk.dynamics.identification",
    "muscle_geometry": "msk.muscles.geometry",
    "solve_muscle_forces": "msk.optimization.muscle_forces",
    "StrengthIdentifier": "msk.strength.identification",
    "knee_contact_force": "msk.contact.knee",
    "load_config": "msk.config",
    "run_session": "msk.pipeline.session",
    "read_session": "msk.results.folder",
    "Summary": "msk.results.summary",
}

__all__ = [
    "InertialIdentifier",
    "Model",
    "MskError",
    "StrengthIdentifier",
    "Summary",
    "Trial",
    "__version__",
    "external_loads",
    "inverse_dynamics",
    "knee_contact_force",
    "load_config",
    "load_model",
    "load_osim",
    "muscle_geometry",
    "read_dynamometer",
    "read_session",
    "read_trial",
    "run_session",
    "scale_model",
    "solve_kinematics",
    "solve_muscle_forces",
]

if TYPE_CHECKING:
    from msk.config import load_config
    from msk.contact.knee import knee_contact_force
    from msk.dynamics.identification import InertialIdentifier
    from msk.dynamics.inverse import inverse_dynamics
    from msk.dynamics.loads import external_loads
    from msk.io.dynamometer import read_dynamometer
    from msk.io.readers import read_trial
    from msk.kinematics.ik import solve_kinematics
    from msk.model.core import Model
    from msk.model.files import load_model
    from msk.model.osim import load_osim
    from msk.muscles.geometry import muscle_geometry
    from msk.optimization.muscle_forces import solve_muscle_forces
    from msk.personalise.scaling import scale_model
    from msk.pipeline.session import run_session
    from msk.results.folder import read_session
    from msk.results.summary import Summary
    from msk.strength.identification import StrengthIdentifier
    from msk.trial import Trial


def __getattr__(name: str) -> Any:
    """Import a public name on first use (PEP 562)."""
    module = _NAMES.get(name)
    if module is None:
        raise AttributeError(f"module 'msk' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
