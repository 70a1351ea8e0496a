"""Muscle-strength identification (Hayashibe et al. 2011, §V) and EMG-driven calibration (the
EMG-driven vs OpenSim thesis).

* :class:`StrengthIdentifier` — regression on the net contribution matrix with correlation
  gating and confidence intervals → :class:`StrengthProfile`;
* :class:`EMGDrivenCalibration` — Hill + activation parameters calibrated to inverse-dynamics
  moments with casadi exact derivatives and multi-start;
* :func:`fit_emg_gains` — EMG-to-activation gains fitted jointly with EMG-assisted static
  optimisation on the inverse-dynamics torques → :class:`EMGGainFit`;
* :func:`identify_pooled` — a session's task and MVC trials in one identification, one EMG
  normalisation (:mod:`msk.strength.pooled`);
* :func:`max_isometric_moment_curves` — maximal isometric joint-moment curves per action
  (knee, ankle, hip) of a model → :class:`JointStrengthCurves`;
* :func:`w_emg_stability` and the comparison tables of :mod:`msk.strength.studies`;
* :mod:`msk.datasets.strength` — a synthetic leg with known strengths.
"""

from __future__ import annotations

from msk.strength.calibration import (
    CALIBRATION_BOUNDS,
    MUSCLE_CALIBRATION_PARAMETERS,
    CalibrationParameters,
    CalibrationResult,
    CalibrationTrial,
    EMGDrivenCalibration,
    FitMetrics,
    casadi_curves,
    emg_driven_forces,
    fractional_delay,
)
from msk.strength.diagnosis import GroupDiagnosis, diagnose
from msk.strength.emg_gains import EMGGainFit, fit_emg_gains
from msk.strength.identification import (
    STRENGTH_FACTOR_BOUNDS,
    StrengthIdentifier,
    StrengthProfile,
    expand_groups,
    group_contributions,
    net_contribution,
    with_strength,
)
from msk.strength.joint_strength import (
    ACTIONS,
    JointStrengthCurves,
    MomentCurve,
    action_status,
    joint_strength_summary,
    max_isometric_moment_curves,
)
from msk.strength.pooled import EmgReference, PooledTrial, identify_pooled, session_emg_reference
from msk.strength.protocol import TestProtocol, recommend_test, recommend_tests
from msk.strength.studies import (
    TABLE_I_W_EMG,
    MetricTable,
    WEmgStability,
    area_ratio_table,
    moment_fit_table,
    net_force_table,
    net_joint_force,
    w_emg_stability,
)

__all__ = [
    "ACTIONS",
    "CALIBRATION_BOUNDS",
    "MUSCLE_CALIBRATION_PARAMETERS",
    "STRENGTH_FACTOR_BOUNDS",
    "TABLE_I_W_EMG",
    "CalibrationParameters",
    "CalibrationResult",
    "CalibrationTrial",
    "EMGDrivenCalibration",
    "EMGGainFit",
    "EmgReference",
    "FitMetrics",
    "GroupDiagnosis",
    "JointStrengthCurves",
    "MetricTable",
    "MomentCurve",
    "PooledTrial",
    "StrengthIdentifier",
    "StrengthProfile",
    "TestProtocol",
    "WEmgStability",
    "action_status",
    "area_ratio_table",
    "casadi_curves",
    "diagnose",
    "emg_driven_forces",
    "expand_groups",
    "fit_emg_gains",
    "fractional_delay",
    "group_contributions",
    "identify_pooled",
    "joint_strength_summary",
    "max_isometric_moment_curves",
    "moment_fit_table",
    "net_contribution",
    "net_force_table",
    "net_joint_force",
    "recommend_test",
    "recommend_tests",
    "session_emg_reference",
    "w_emg_stability",
    "with_strength",
]
