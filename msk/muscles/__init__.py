"""Muscles: EMG processing, activation dynamics and Hill-type models (geometry lives beside them).

Submodules: :mod:`msk.muscles.emg`, :mod:`msk.muscles.activation`, :mod:`msk.muscles.hill`,
:mod:`msk.muscles.contraction` (elastic-tendon contraction dynamics over time)
(and, from another change, ``msk.muscles.geometry`` for paths, lengths and moment arms).
"""

from __future__ import annotations

from msk.muscles.activation import (
    emg_to_activation,
    first_order_activation,
    nonlinear_activation,
    piecewise_coefficients,
    recursive_filter,
    recursive_filter_coefficients,
)
from msk.muscles.contraction import ContractionState, contraction_dynamics
from msk.muscles.emg import (
    ChannelQuality,
    EmgEnvelopes,
    channel_quality,
    envelopes_from_trial,
    linear_envelope,
    mvc_peaks,
    process_emg,
)
from msk.muscles.hill import (
    MUSCLE_PARAMETER_ORDER,
    EquilibriumState,
    LloydBesierCurves,
    MuscleParameters,
    RigidTendonState,
    RigidTendonStateBlocks,
    Thelen2003Curves,
    equilibrium,
    fl_gaussian,
    fv_stroeve,
    pennation_constant_height,
    reference_force,
    rigid_tendon_state,
)

__all__ = [
    "MUSCLE_PARAMETER_ORDER",
    "ChannelQuality",
    "ContractionState",
    "EmgEnvelopes",
    "EquilibriumState",
    "LloydBesierCurves",
    "MuscleParameters",
    "RigidTendonState",
    "RigidTendonStateBlocks",
    "Thelen2003Curves",
    "channel_quality",
    "contraction_dynamics",
    "emg_to_activation",
    "envelopes_from_trial",
    "equilibrium",
    "first_order_activation",
    "fl_gaussian",
    "fv_stroeve",
    "linear_envelope",
    "mvc_peaks",
    "nonlinear_activation",
    "pennation_constant_height",
    "piecewise_coefficients",
    "process_emg",
    "recursive_filter",
    "recursive_filter_coefficients",
    "reference_force",
    "rigid_tendon_state",
]
