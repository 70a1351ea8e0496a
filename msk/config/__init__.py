"""Session configuration (TOML): subject, model, trials and their roles, markers, EMG, filters.

The options dataclasses (:mod:`msk.config.options`) are the schema: each key declares its type,
default, unit, allowed range or values and meaning (:func:`msk.config.schema.opt`), and
:func:`load_config` validates a file by them: an unknown key (with a suggestion), a wrong type,
a number out of range (with its unit) or a value not allowed raises
:class:`~msk.exceptions.ConfigError`, one line naming the file, the key path
(``trials[2].role``) and what is allowed. Relative paths are relative to the config file.

:func:`config_reference` is the generated reference of every key (``msk print-config``,
``docs/config.md``); :func:`render_config` a loaded configuration with every value;
:data:`TEMPLATE` a commented example session.
"""

from msk.config.load import FES_TRIAL_KEYS, load_config
from msk.config.options import (
    ACTIVATION_WEIGHTS,
    FES_ANGLE_UNITS,
    FES_STEPS,
    FES_STEPS_NEEDED,
    FES_STIM_UNITS,
    KNEE_VARIANTS,
    MAX_CUTOFF_HZ,
    MAX_EMD_S,
    MIN_CUTOFF_HZ,
    OPTIMIZATION_METHODS,
    SECTIONS,
    TRIAL_ROLES,
    ContactConfig,
    EmgConfig,
    FesConfig,
    FesTrialConfig,
    FilterConfig,
    GaitConfig,
    LoadsConfig,
    MarkersConfig,
    ModelConfig,
    OptimizationConfig,
    Section,
    SessionConfig,
    StrengthConfig,
    Subject,
    TrialConfig,
)
from msk.config.reference import config_reference, render_config
from msk.config.template import TEMPLATE

__all__ = [
    "ACTIVATION_WEIGHTS",
    "FES_ANGLE_UNITS",
    "FES_STEPS",
    "FES_STEPS_NEEDED",
    "FES_STIM_UNITS",
    "FES_TRIAL_KEYS",
    "KNEE_VARIANTS",
    "MAX_CUTOFF_HZ",
    "MAX_EMD_S",
    "MIN_CUTOFF_HZ",
    "OPTIMIZATION_METHODS",
    "SECTIONS",
    "TEMPLATE",
    "TRIAL_ROLES",
    "ContactConfig",
    "EmgConfig",
    "FesConfig",
    "FesTrialConfig",
    "FilterConfig",
    "GaitConfig",
    "LoadsConfig",
    "MarkersConfig",
    "ModelConfig",
    "OptimizationConfig",
    "Section",
    "SessionConfig",
    "StrengthConfig",
    "Subject",
    "TrialConfig",
    "config_reference",
    "load_config",
    "render_config",
]
