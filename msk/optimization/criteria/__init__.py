"""Muscle-force criteria: a registry (:data:`CRITERIA`, :func:`criterion`, :func:`register`) and
one criterion per module."""

from msk.optimization.criteria import (
    bounded_qp,
    closed_form,
    emg_assisted,
    emg_weighted,
    static_optimization,
)
from msk.optimization.criteria.base import CRITERIA, BlockProblem, Criterion, criterion, register

__all__ = [
    "CRITERIA",
    "BlockProblem",
    "Criterion",
    "bounded_qp",
    "closed_form",
    "criterion",
    "emg_assisted",
    "emg_weighted",
    "register",
    "static_optimization",
]
