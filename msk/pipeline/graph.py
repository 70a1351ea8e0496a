"""The stage graph: every node of a session run, its upstream nodes, in one place.

A node is a function ``run(inputs, **upstream)`` of the :class:`~msk.pipeline.inputs.SessionInputs`
and of the results of the nodes it names as parameters; ``needs`` are the upstream nodes without
which it cannot run (``not available`` otherwise), ``reads`` the optional ones (passed as
``None`` when they did not run). Recorded nodes are the stages of ``summary.json`` ``stages``
(status, seconds, cache); unrecorded ones are cheap derivations (events and cycle, tables,
summary). Adding a stage = one module with ``run`` (and ``settings`` when options enter its
cache key) + one line below. ``measured_contact`` (unrecorded, right after ``read``) hands the
measured knee contact force on, so that no stage after the EMG stage reads ``read``: with
``keep`` (:func:`run_graph`) the trial's analog-rate arrays are released there, and parts of
``read`` are dropped earlier, after their last reader (:data:`TRIMS`: the markers after the
model stage, the plates after the loads stage; the model's own markers after the step
``opensim_export``, which writes them with the loads for OpenSim, after ``swapped_markers``,
which takes the summary's swapped-label pairs right after the kinematics)::

    read ─ model ─ kinematics ─ swapped_markers* ─ loads ─ opensim_export* ─┬─ mass_identif…─┐
                                                  (mass_identification ─ opensim_model*)
      ┌──────────────────────────────────────────────────────┘   inverse_dynamics ──┤
      ├─ emg ───────────────────────────────────────────────────────────────────────┤
      └─ muscle_geometry ─ tension_optimization ────────────────────────────────────┤
         strength_identification (emg, geometry, torques) ─ knee_contact ─ gait_cycle*
         ─ gait_analysis* ─ joint_strength* ─ comparison ─ fes ─ tables* ─ summary* ─ report
                                                                              (* unrecorded)

A node's result is kept in the stage cache (:mod:`msk._runtime.cache`) as it is, or in the form its
``to_cache`` gives and ``from_cache`` reads back (the model stage: :func:`model_to_cache`);
an unrecorded node with ``cached`` is kept too (``joint_strength``, the summary's curves).
"""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass
from typing import Any, cast

from msk._runtime.blocks import FRAME_BLOCK
from msk.model.core import Model, ModelState
from msk.personalise import Personalisation
from msk.pipeline import (
    comparison,
    contact,
    cycle,
    dynamics,
    emg,
    fes,
    gait_analysis,
    geometry,
    kinematics,
    loads,
    mass_identification,
    model,
    opensim_export,
    read,
    report,
    strength,
    summary,
    tables,
    tension,
)
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.runner import Runner

__all__ = [
    "CORE_STAGES",
    "GRAPH",
    "STAGES",
    "TRIMS",
    "Node",
    "last_readers",
    "model_from_cache",
    "model_to_cache",
    "run_graph",
]

#: why a gait node does not run in a session without a task trial
NO_GAIT = "no gait trial (role 'task') in the configuration"


@dataclass(frozen=True)
class Node:
    """One node of the graph (see the module docstring)."""

    name: str
    run: Callable[..., Any]
    needs: tuple[str, ...] | Callable[[SessionInputs], tuple[str, ...]] = ()
    reads: tuple[str, ...] = ()
    settings: Callable[..., Any] | None = None
    recorded: bool = True
    core: bool = False
    gait: bool = True
    requested: Callable[[SessionInputs], str | None] | None = None
    to_cache: Callable[[Any], Any] | None = None
    from_cache: Callable[[Any], Any] | None = None
    cached: bool = False

    @property
    def parameters(self) -> tuple[str, ...]:
        """The upstream nodes ``run`` takes (its parameters after ``inputs``)."""
        return tuple(inspect.signature(self.run).parameters)[1:]

    @property
    def reads_results(self) -> tuple[str, ...]:
        """The upstream nodes whose results ``run`` or ``settings`` take."""
        extra: tuple[str, ...] = ()
        if self.settings is not None:
            extra = tuple(inspect.signature(self.settings).parameters)[1:]
        return tuple(dict.fromkeys(self.parameters + extra))

    def needs_of(self, inputs: SessionInputs) -> tuple[str, ...]:
        return self.needs(inputs) if callable(self.needs) else self.needs


def model_to_cache(built: Personalisation) -> Personalisation:
    """The model stage's result as the stage cache keeps it: its :class:`msk.model.core.Model` as
    plain data (:meth:`msk.model.core.Model.state`; the cache stores no Pinocchio object). A trial
    of more than :data:`~msk._runtime.blocks.FRAME_BLOCK` frames is given as it is, not
    storable: its model-frame markers are not written to the cache (the memory bound of long
    trials), the stage is computed again next time."""
    if len(built.trial.time) > FRAME_BLOCK:
        return built
    # the cache's form: the model's plain-data state in the model's place
    return dataclasses.replace(built, model=cast(Model, built.model.state()))


def model_from_cache(stored: Personalisation) -> Personalisation:
    """The model stage's result from what :func:`model_to_cache` kept (the model built again
    from its specifications: :meth:`msk.model.core.Model.from_state`)."""
    state = cast(ModelState, stored.model)  # model_to_cache's form
    return dataclasses.replace(stored, model=Model.from_state(state))


_ALL = ("model", "kinematics", "loads")
GRAPH: tuple[Node, ...] = (
    Node("read", read.run, settings=read.settings, core=True),
    Node("measured_contact", read.measured_contact, ("read",), recorded=False),
    Node("model", model.run, ("read",), settings=model.settings, core=True,
         to_cache=model_to_cache, from_cache=model_from_cache),
    Node("kinematics", kinematics.run, ("model",), settings=kinematics.settings, core=True),
    Node("swapped_markers", summary.swapped_markers, ("model", "kinematics"), recorded=False),
    Node("loads", loads.run, ("read", "model", "kinematics"), settings=loads.settings, core=True),
    Node("opensim_export", opensim_export.run, (), _ALL, recorded=False),
    Node("mass_identification", mass_identification.run, ("read", *_ALL),
         settings=mass_identification.settings),
    Node("opensim_model", opensim_export.run_model, ("model",), ("mass_identification",),
         recorded=False),
    Node("inverse_dynamics", dynamics.run, _ALL, ("mass_identification",), core=True),
    Node("emg", emg.run, ("read", "model", "kinematics"), settings=emg.settings),
    Node("muscle_geometry", geometry.run, _ALL),
    Node("tension_optimization", tension.run, tension.needs, ("mass_identification", "emg"),
         settings=tension.settings),
    Node("strength_identification", strength.run,
         (*_ALL, "inverse_dynamics", "emg", "muscle_geometry")),
    Node("knee_contact", contact.run,
         (*_ALL, "inverse_dynamics", "muscle_geometry", "tension_optimization"),
         ("mass_identification", "emg", "strength_identification", "measured_contact"),
         settings=contact.settings),
    Node("gait_cycle", cycle.run, _ALL, ("knee_contact",), recorded=False),
    Node("gait_analysis", gait_analysis.run, (*_ALL, "gait_cycle"),
         ("inverse_dynamics", "mass_identification"), recorded=False),
    Node("joint_strength", summary.joint_strength, (), ("model", "strength_identification"),
         settings=summary.joint_strength_settings, recorded=False, cached=True),
    Node("comparison", comparison.run, ("loads", "inverse_dynamics"),
         ("knee_contact", "strength_identification", "gait_cycle")),
    Node("fes", fes.run, settings=fes.settings, gait=False, requested=fes.requested),
    Node("tables", tables.run, (),
         ("kinematics", "inverse_dynamics", "mass_identification", "tension_optimization",
          "strength_identification", "knee_contact", "gait_cycle", "fes", "gait_analysis"),
         recorded=False, gait=False),
    Node("summary", summary.run, (),
         (*_ALL, "mass_identification", "inverse_dynamics", "emg",
          "tension_optimization", "strength_identification", "gait_cycle", "comparison", "fes",
          "swapped_markers", "joint_strength", "knee_contact", "gait_analysis"),
         recorded=False, gait=False),
    Node("report", report.run, ("tables", "summary"), settings=report.settings, core=True,
         gait=False),
)  # fmt: skip

#: (after node, result, trim): once ``after`` has run, ``result`` is replaced by ``trim`` of it —
#: the part no later node reads dropped (:func:`run_graph` with ``keep``): the task's markers
#: are read by the model stage alone (later stages read the model's own copy in the model
#: frame), the plates by the loads stage alone (the mass identification reads the assignment,
#: the EMG stage the analog channels); the model's own model-frame markers by the kinematics
#: stage, the step ``swapped_markers``, the step ``opensim_export`` (the markers' ``.trc``)
#: and the step ``gait_analysis`` (Plug-in Gait's knee centres from the thigh and shank
#: wands, ``[gait] angle_convention``) alone (the summary reads that step's pairs, the
#: marker labels and gaps). For scale: a long trial's read result is ~4.9 kB/frame, its
#: model-frame markers 1.2 kB/frame more.
TRIMS: tuple[tuple[str, str, Callable[[Any], Any]], ...] = (
    ("model", "read", read.without_markers),
    ("loads", "read", read.without_plates),
    ("gait_analysis", "model", model.without_markers),
)

#: Every recorded stage, in order (``summary.json`` ``stages``, progress lines).
STAGES: tuple[str, ...] = tuple(n.name for n in GRAPH if n.recorded)
#: Stages without which there are no results: their errors end the run.
CORE_STAGES: frozenset[str] = frozenset(n.name for n in GRAPH if n.core)


def _check(graph: tuple[Node, ...]) -> None:
    """Every parameter of a node's ``run`` is an earlier node named in its needs or reads."""
    seen: set[str] = set()
    for node in graph:
        declared = set(node.reads) | (set() if callable(node.needs) else set(node.needs))
        if callable(node.needs):
            declared |= set(node.parameters)  # checked against ``seen`` below
        for p in node.parameters:
            if p not in declared or p not in seen:
                raise RuntimeError(f"graph: {node.name}.run takes {p!r}: not an earlier node")
        seen.add(node.name)


_check(GRAPH)


def _call(fn: Callable[..., Any], inputs: SessionInputs, results: Mapping[str, Any]) -> Any:
    names = tuple(inspect.signature(fn).parameters)[1:]
    return fn(inputs, **{n: results.get(n) for n in names})


def last_readers(graph: tuple[Node, ...]) -> dict[str, int]:
    """Node name → position in ``graph`` of the last node whose ``run`` or ``settings`` takes
    its result (absent: no node reads it)."""
    last: dict[str, int] = {}
    for i, node in enumerate(graph):
        for name in node.reads_results:
            last[name] = i
    return last


def run_graph(
    inputs: SessionInputs,
    runner: Runner,
    graph: tuple[Node, ...] = GRAPH,
    *,
    keep: Collection[str] | None = None,
    trims: tuple[tuple[str, str, Callable[[Any], Any]], ...] = TRIMS,
) -> dict[str, Any]:
    """Run every node in order; node name → its result (None when not requested, not
    available or failed).

    ``keep``: the nodes whose results the caller wants back; every other result is released
    as soon as the last node reading it has run (:func:`last_readers`), and ``trims`` (default
    :data:`TRIMS`) drop the parts of a result no later node reads, so that a long trial's
    arrays are not all held to the end of the run. ``None`` keeps every result
    whole."""
    results: dict[str, Any] = {}
    last = last_readers(graph) if keep is not None else {}
    for i, node in enumerate(graph):
        if keep is not None:
            # results read by no later node (and not kept) are dropped before the next one runs
            for name in [n for n in results if n not in keep and last.get(n, -1) < i]:
                del results[name]
            # and the parts of a result that no node after the previous one reads
            done = graph[i - 1].name if i else None
            for after, name, trim in trims:
                if after == done and name not in keep and results.get(name) is not None:
                    results[name] = trim(results[name])
        results[node.name] = None
        reason = NO_GAIT if node.gait and not inputs.gait else None
        if reason is None and node.requested is not None:
            reason = node.requested(inputs)
        if reason is not None:
            if node.recorded:
                runner.skip(node.name, reason)
            continue
        needs = node.needs_of(inputs)

        def call(node: Node = node) -> Any:
            return _call(node.run, inputs, results)

        ready = all(n in runner.keys for n in needs)  # else the runner says "not available"
        settings = None
        if node.settings is not None and ready:
            settings = _call(node.settings, inputs, results)
        if not node.recorded:
            results[node.name] = runner.derive(
                node.name, call, needs + node.reads, settings=settings, cache=node.cached
            )
            continue
        results[node.name] = runner.run(
            node.name, call, needs=needs, reads=node.reads, settings=settings,
            to_cache=node.to_cache, from_cache=node.from_cache,
        )  # fmt: skip
    if keep is not None:
        return {n: v for n, v in results.items() if n in keep}
    return results
