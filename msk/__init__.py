"""msk: subject-specific musculoskeletal analysis of the lower limb on Pinocchio.

Data flows one way (see ``docs/architecture.md``)::

    read_c3d -> Trial -> solve_kinematics -> Kinematics -> external_loads -> ExternalLoads
      -> InertialIdentifier.fit -> model.with_inertias -> inverse_dynamics -> JointTorques
      -> muscle geometry -> tension optimisation -> MuscleForces -> StrengthIdentifier.fit
      -> joint contact forces -> comparison -> report

All quantities inside are SI (m, s, rad, N, N·m, kg); time is axis 0.
"""

__version__ = "0.4.0"

from msk.exceptions import MskError

__all__ = ["MskError", "__version__"]
