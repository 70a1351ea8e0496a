"""The muscle-force criteria of :func:`msk.optimization.muscle_forces.solve_muscle_forces`: a base
class and a registry, one criterion per module of this package.

A criterion turns one block of frames of one left-out pattern (:class:`BlockProblem`: the kept
muscles' Jacobian, torques, force curves, weights and warm start) into forces, activations and
the batch solution its QP solver returned (None for a closed form). Register a new one with
:func:`register`; ``[optimization] method`` names it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from msk.exceptions import ConfigError

__all__ = ["CRITERIA", "BlockProblem", "Criterion", "criterion", "register"]


@dataclass(frozen=True)
class BlockProblem:
    """One solve call's data, all of one left-out pattern: ``jacobian`` (n, kept muscles, kept
    coordinates), ``torques`` (n, kept coordinates), the rigid-tendon force curves ``f_active``,
    ``f_passive`` (n, kept muscles), every muscle's ``f_iso`` (m,), the kept ``activation_weights``
    and ``reserve_optimal_force``, the warm start ``warm`` carried from the pattern's last call,
    the solver's shared keyword arguments ``common`` (time, names, KKT check, inequality rows);
    ``kept`` selects the kept muscles of an every-muscle array; ``emg_activation`` (n, m) the
    measured muscles' EMG activation (0 elsewhere) and ``measured`` (m,) which muscles have it —
    None for a criterion that reads no EMG; ``gains`` the fitted EMG gains of ``emg_assisted``."""

    jacobian: np.ndarray
    torques: np.ndarray
    f_active: np.ndarray
    f_passive: np.ndarray
    f_iso: np.ndarray
    activation_weights: np.ndarray | None
    reserve_optimal_force: np.ndarray
    warm: Any
    common: Mapping[str, Any]
    kept: Callable[[np.ndarray], np.ndarray]
    emg_activation: np.ndarray | None = None
    measured: np.ndarray | None = None
    gains: Any = None


class Criterion:
    """A muscle-force criterion. ``name`` is its ``[optimization] method``; ``reads_emg``: it
    needs the EMG stage; ``fits_emg_gains``: one EMG-to-activation gain per channel is fitted
    on the trial's torques first; ``quadratic``: a QP with reserves, KKT figures and optional
    inequality rows (False: a closed form)."""

    name: ClassVar[str]
    reads_emg: ClassVar[bool] = False
    fits_emg_gains: ClassVar[bool] = False
    quadratic: ClassVar[bool] = True

    def solve(
        self, problem: BlockProblem, options: Any
    ) -> tuple[np.ndarray, np.ndarray | None, Any]:
        """Forces (n, kept muscles), activations (n, kept muscles) and the batch solution."""
        raise NotImplementedError

    def describe(self, options: Any, *, gains_fitted: bool) -> str | None:
        """The criterion in words for the summary and the report (None: not stated)."""
        return None


#: every registered criterion by name
CRITERIA: dict[str, Criterion] = {}


def register(cls: type[Criterion]) -> type[Criterion]:
    """Class decorator: add ``cls()`` to :data:`CRITERIA` under ``cls.name``."""
    CRITERIA[cls.name] = cls()
    return cls


def criterion(name: str) -> Criterion:
    """The registered criterion ``name`` (:class:`ConfigError` naming the known ones)."""
    from msk.optimization import criteria  # noqa: F401  (registers the shipped criteria)

    try:
        return CRITERIA[name]
    except KeyError:
        known = ", ".join(sorted(CRITERIA))
        raise ConfigError(
            f"optimization.method: unknown criterion {name!r} (known: {known})"
        ) from None
