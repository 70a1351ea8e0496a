"""Marker placement from the motion (no static trial) chosen among fixed candidates by the task's
inverse kinematics cost: the candidates' records, the frames they are judged on, the cost, the
continued placement of a split model and :func:`choose_placement`."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from msk._runtime.fork import Forked, spare_cpu
from msk.model.core import Model, ModelState
from msk.personalise.scaling import ScalingReport
from msk.trial import Trial

__all__ = [
    "CHOICE_MAX_FRAMES",
    "CHOICE_MISSING_MARKERS",
    "CHOICE_TOLERANCE_M",
    "DESCENT_MAX_ROUNDS",
    "DESCENT_REL_TOLERANCE",
    "Candidate",
    "CandidateCost",
    "PlacementCall",
    "PlacementChoice",
    "choice_frames",
    "choose_placement",
    "continued_placement",
    "placement_cost",
    "placement_fit",
    "placement_frames",
]

#: relative decrease of the task's IK cost per round below which :func:`choose_placement`
#: stops its descents: 2 % is 0.14–0.3 mm on the shipped walks (7–15 mm), as much as the
#: candidates' costs move under ``studies/placement_jitter.py``'s perturbations (0.15 mm)
#: and under :data:`CHOICE_TOLERANCE_M` — a smaller gain is not one the choice can tell from
#: those perturbations (an absolute 0.01 mm left DM og1 at a 12-round cap, still falling by
#: 0.06 mm per round)
DESCENT_REL_TOLERANCE = 2e-2

#: most rounds of a descent of :func:`choose_placement` (a safeguard, not the stopping rule)
DESCENT_MAX_ROUNDS = 30

#: how much worse (m) than the least task IK cost a candidate of :func:`choose_placement` may be
#: and still be preferred (the split before the leg factor, the pulled start before the other):
#: the candidates' costs move by up to 0.15 mm under ``studies/placement_jitter.py``'s
#: perturbations (DM og1), so that a choice by the bare minimum between candidates closer than
#: that flipped the femur and tibia factors from run to run
CHOICE_TOLERANCE_M = 0.0002

#: most task frames the choice among motion placements is judged on (:func:`choose_placement`,
#: :func:`placement_frames`): interleaved evenly over the trial's well-tracked frames
CHOICE_MAX_FRAMES = 120

#: a frame is well tracked (:func:`placement_frames`) when it misses at most this many more
#: markers than the best-tracked frame
CHOICE_MISSING_MARKERS = 2


@dataclass(frozen=True)
class PlacementCall:
    """How a motion placement was called
    (:func:`msk.personalise.scaling.place_markers_from_motion`): the model before placement,
    the markers ``(N, M, 3)`` m in the model frame (lab origin taken out), their
    labels in model names, the time (s) and the keywords."""

    model: Model
    markers: NDArray[np.float64]
    labels: tuple[str, ...]
    time: NDArray[np.float64]
    keywords: Mapping[str, Any]


@dataclass(frozen=True)
class Candidate:
    """A scaled and placed model: the model, what was done (``info``: ``summary.json``
    ``model``), the lab → model rotation, model marker → lab label (``rename``), the motion
    placement's call (None after a static placement), the scaling's workspace (the
    pose-matched IK reused when the same trial is scaled again) and its report."""

    model: Model
    info: dict[str, Any]
    rotation: NDArray[np.float64]
    rename: dict[str, str]
    call: PlacementCall | None
    workspace: dict[str, Any]
    scaling: ScalingReport | None = None

    @property
    def placement(self) -> dict[str, Any]:
        """The marker placement's record (``info["marker_placement"]``)."""
        return dict(self.info.get("marker_placement", {}))


@dataclass(frozen=True)
class CandidateCost:
    """One candidate of :func:`choose_placement`: split or not, its start (``"as before"``,
    ``"pulled"``, ``"pulled anew"``), its task IK cost (m; on every marker any candidate
    places), the descent's rounds and why it stopped, and its cost on the unsplit starts'
    markers when the marker set was widened (``descent_cost_m``)."""

    leg_split: bool
    start: str
    cost_m: float
    rounds: int
    stop: str
    descent_cost_m: float | None = None

    def summary(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "leg_split": self.leg_split,
            "start": self.start,
            "cost_m": self.cost_m,
            "rounds": self.rounds,
            "stop": self.stop,
        }
        if self.descent_cost_m is not None:
            out["descent_cost_m"] = self.descent_cost_m
        return out


@dataclass(frozen=True)
class PlacementChoice:
    """The record of :func:`choose_placement` (``summary.json`` ``model.placement_choice``):
    the objective, the frames it was judged on, the candidates and the index of the chosen
    one."""

    objective: str
    frames: int
    candidates: tuple[CandidateCost, ...]
    chosen: int

    @property
    def chosen_candidate(self) -> CandidateCost:
        return self.candidates[self.chosen]

    def summary(self) -> dict[str, Any]:
        return {
            "objective": self.objective,
            "frames": self.frames,
            "candidates": [c.summary() for c in self.candidates],
            "chosen": self.chosen,
        }


def continued_placement(
    call: PlacementCall, prev_model: Model, prev: Mapping[str, Any]
) -> tuple[Model, dict[str, Any]]:
    """One pass of :func:`msk.personalise.scaling.place_markers_from_motion` pulled towards
    neutral (``call``: the model before placement, the markers, labels, time and keywords it
    was placed with) continuing an earlier motion placement (``prev_model`` and its
    ``info["marker_placement"]``, possibly on a model scaled otherwise): its placed markers'
    state and its moved model markers' offsets (on the same body) are the pass's start;
    ``"regularized"`` is the earlier one's. Pulled for the reason the pulled start is (the weak
    pull resolves the flat directions of the anatomical markers' IK): unpulled, the first pass
    on UWA fast walking's split model (femur × 1.02–1.04) with the leg factors × (1 − 1e-4)
    lost the thigh clusters (task IK 74.6 mm against 8.96 mm pulled; the descent that follows
    is unpulled)."""
    from msk.personalise.scaling import place_markers_from_motion

    base = call.model
    was = {mk.name: mk for mk in prev_model.markers if mk.name in prev.get("moved", {})}
    own = [was[mk.name] if mk.name in was and was[mk.name].body == mk.body else mk
           for mk in base.markers]  # fmt: skip
    model, placed = place_markers_from_motion(
        base.with_markers(own), call.markers, call.labels, call.time, **call.keywords,
        regularize=True, iterations=1, start=prev["state"],
    )  # fmt: skip
    return model, {**placed, "regularized": prev["regularized"]}


def placement_frames(
    markers: NDArray[np.float64], max_frames: int = CHOICE_MAX_FRAMES
) -> NDArray[np.intp]:
    """Indices of at most ``max_frames`` frames of ``markers`` ((N, M, 3), NaN or exact zeros
    for gaps), interleaved evenly over the trial's well-tracked frames — those missing at most
    :data:`CHOICE_MISSING_MARKERS` more markers than the best-tracked frame, widened to the
    ``max_frames`` best-tracked when fewer — so that the frames span every phase of the gait
    cycles the trial holds and no marker's drop-out weighs on the choice. Deterministic:
    every candidate of :func:`choose_placement` is judged on the same frames."""
    x = np.asarray(markers)
    n = x.shape[0]
    if n == 0:
        return np.zeros(0, dtype=int)
    seen = (np.isfinite(x).all(axis=-1) & (x != 0.0).any(axis=-1)).sum(axis=1)
    m = min(max_frames, n)
    k = min(int(seen.max()) - CHOICE_MISSING_MARKERS, int(np.sort(seen)[-m]))
    well = np.flatnonzero(seen >= k)
    return well[np.round(np.linspace(0, well.size - 1, m)).astype(int)]


def choice_frames(
    trial: Trial, built: Candidate
) -> tuple[NDArray[np.float64], NDArray[np.float64], tuple[str, ...]]:
    """The frames the choice among motion placements is judged on (:func:`placement_frames`)
    in the model frame (exact zeros as gaps), their times and the labels in model names."""
    from msk.model.markersets import zeros_as_gaps

    idx = placement_frames(trial.markers)
    rot = np.asarray(built.rotation, dtype=float)
    x = zeros_as_gaps(np.asarray(trial.markers, dtype=float)[idx] @ rot.T)
    t = np.asarray(trial.time, dtype=float)[idx]
    inv = {v: k for k, v in built.rename.items()}
    return x, t, tuple(inv.get(lab, lab) for lab in trial.marker_labels)


@dataclass(frozen=True)
class _Frames:
    """Markers ``(N, M, 3)`` and time ``(N,)`` (:class:`msk.kinematics.trial.MarkerTrial`)."""

    markers: NDArray[np.float64]
    time: NDArray[np.float64]


def placement_fit(
    model: Model, x: NDArray[np.float64], time: NDArray[np.float64], labels: Sequence[str],
    weights: Mapping[str, float], markers: Sequence[str],
    loose: Mapping[str, tuple[str, Sequence[float]]] | None = None,
    initial_q: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], float]:  # fmt: skip
    """The task's inverse kinematics of a placed model on the frames ``x`` (model frame) and
    its cost (m): the kinematics stage's IK (:func:`msk.kinematics.trial.solve_trial`: the
    configured marker weights, the held foot coordinates, physiological knee ranges; no filter;
    ``initial_q`` its warm start), then the weighted RMS over ``markers`` of each frame's
    distances, averaged over the frames — the quantity the task's IK minimises, on one marker
    set for every candidate compared. A marker of ``markers`` the model does not carry (left
    out as too loose: ``loose``, name → (body, offset)) is measured at the pose the others
    give, so that dropping a marker does not lower the cost by itself. Returns the poses
    (``q_raw``, NaN rows for frames not solved) and the cost (inf when nothing is solved)."""
    from msk.kinematics.trial import solve_trial
    from msk.model.core import Marker, frame_placements
    from msk.personalise.coordinates import held_foot_coordinates, knee_flexion_to_physiological

    final, _ = knee_flexion_to_physiological(model)
    held = held_foot_coordinates(final, x, tuple(labels))
    kin = solve_trial(
        final, _Frames(x, time), tuple(labels), weights=weights,
        held=held, cutoff_hz=None, initial_q=initial_q,
    )  # fmt: skip
    extra = [Marker(k, b, np.asarray(o, dtype=float)) for k, (b, o) in (loose or {}).items()
             if k not in set(final.marker_names)]  # fmt: skip
    scored = final.with_markers([*final.markers, *extra]) if extra else final
    names = list(scored.marker_names)
    use = [m for m in markers if m in names and m in labels]
    q = np.asarray(kin.q_raw, dtype=float)
    ok = np.isfinite(q).all(axis=1)
    if not use or not ok.any():
        return q, float("inf")
    _, pos = frame_placements(scored, q[ok], [scored.marker_frame[m] for m in use])
    meas = x[ok][:, [list(labels).index(m) for m in use]]
    d2 = ((pos - meas) ** 2).sum(axis=2)
    w = np.array([float(weights.get(m, 1.0)) for m in use])[None, :] * np.isfinite(d2)
    den = w.sum(axis=1)
    fine = den > 0
    per_frame = np.sqrt(np.where(w > 0, np.nan_to_num(d2) * w, 0.0)[fine].sum(axis=1) / den[fine])
    return q, float(per_frame.mean()) if per_frame.size else float("inf")


def placement_cost(
    model: Model, x: NDArray[np.float64], time: NDArray[np.float64], labels: Sequence[str],
    weights: Mapping[str, float], markers: Sequence[str],
    loose: Mapping[str, tuple[str, Sequence[float]]] | None = None,
) -> float:  # fmt: skip
    """The task's inverse kinematics cost of a placed model (m): :func:`placement_fit`'s."""
    return placement_fit(model, x, time, labels, weights, markers, loose)[1]


#: (the split's femur and tibia factors, the placement continued) → the candidate scaled with
#: them and placed by continuing that placement (:func:`continued_placement`)
Rescale = Callable[[Mapping[str, float], tuple[Model, Mapping[str, Any]]], Candidate]


def _refined_state(
    refine: Callable[[Candidate], tuple[Model, dict[str, Any]]], c: Candidate
) -> tuple[ModelState, dict[str, Any]]:
    """``refine(c)`` with its model as plain data (:meth:`msk.model.core.Model.state`): what a
    forked child sends back."""
    model, info = refine(c)
    return model.state(), info


def choose_placement(
    built: Candidate, task: Trial, weights: Mapping[str, float], *,
    split_of: Callable[[Candidate], Mapping[str, float] | None] | None = None,
    rescale: Rescale | None = None,
) -> tuple[Candidate, PlacementChoice]:  # fmt: skip
    """The motion placement (no static trial) of least task IK cost (:func:`placement_cost`,
    one objective on one marker set and the same frames of ``task`` — :func:`placement_frames`,
    at most :data:`CHOICE_MAX_FRAMES` — for every candidate, ``weights`` the markers' IK
    weights) among a fixed set: the placement as it was (``built``: plain, pulled when plain is
    worse than :data:`msk.personalise.scaling.PLACEMENT_RETRY_RMS_M`) and the placement pulled
    towards neutral (``regularize=True`` of
    :func:`msk.personalise.scaling.place_markers_from_motion`, on the model ``built`` was
    scaled to; the same placement when ``built`` was itself pulled), each continued by
    :func:`msk.personalise.scaling.refine_placement_from_motion` (rounds of squared
    extrapolation of the passes, while a round lowers the cost by more than
    :data:`DESCENT_REL_TOLERANCE` of itself, at most :data:`DESCENT_MAX_ROUNDS` rounds); then,
    when ``split_of`` gives femur and tibia factors for the best of these (the functional leg
    split, :func:`msk.personalise.personalise.measured_leg_split`), each of the two descended
    placements continued on the model scaled with them (``rescale``, which continues the first
    placement; :func:`continued_placement` the other; then descended the same way) and the
    split model placed anew, pulled towards neutral (descended too). The candidates are then
    judged on every marker any of them places. The first candidate in order of preference —
    the split before the leg factor; the pulled start, then the other, then the split placed
    anew — within :data:`CHOICE_TOLERANCE_M` of the least cost is kept.

    The split placed anew and the wider marker set are there because the continued split
    placements keep the clusters an unsplit placement lost (UWA running with its legs at the
    stature's length: the left thigh and shank clusters 55–62 mm loose, judged on the unsplit
    starts' markers only, without them, at a lower cost). The split candidates continue the
    unsplit descents instead of starting again from the generic offsets (the femur and tibia
    change by a few per cent, the offsets by millimetres: 1–2 rounds instead of 6–12), the
    pulled start reuses the scaling, and the descents are accelerated.

    Why. The placement passes are a fixed-point iteration with several basins: which one a run
    landed in moved with perturbations no physical argument can care about (markers + 0.1 mm
    noise, one frame less, leg factors × (1 ± 1e-4): DM og1's task IK 8.5–9.5 mm, UWA fast
    walking's 9.2–10.8 mm; ``studies/placement_jitter.py``), and so did the plain/pulled and
    split/no-split choices made on the placement's own RMS, and the split's factors measured on
    that placement. The pulled start is unique (the pull resolves the flat directions of the
    anatomical markers' IK) and the descent from it ends where the markers alone put the
    placement; the split is measured on the best of the descended placements. The placement as
    it was is a candidate, so by this objective the choice is never worse than the route
    before it by more than :data:`CHOICE_TOLERANCE_M`.

    Returns the chosen candidate and the record of the choice (``summary.json``
    ``model.placement_choice``)."""
    from msk.personalise.scaling import place_markers_from_motion, refine_placement_from_motion

    x, t, labels = choice_frames(task, built)
    assert built.call is not None  # a motion placement

    def starts() -> list[tuple[dict[str, Any], Candidate]]:
        # the pulled start places on the model the start as before was scaled to (scaling does
        # not depend on the placement): the scaling is not run twice
        c = built.call
        assert c is not None
        if built.info["marker_placement"]["regularized"] is True:  # the route before pulled
            pulled = built.model, built.info["marker_placement"]
        else:
            pulled = place_markers_from_motion(
                c.model, c.markers, c.labels, c.time, **c.keywords, regularize=True, warm={}
            )
        info = {**built.info, "marker_placement": pulled[1]}
        return [
            ({"leg_split": False, "start": "as before"}, built),
            ({"leg_split": False, "start": "pulled"}, replace(built, model=pulled[0], info=info)),
        ]

    def split_starts(f: Mapping[str, float]) -> list[tuple[dict[str, Any], Candidate]]:
        # each start's descended placement continued on the split model (scaled once): the
        # femur and tibia change by a few per cent, the markers' offsets by millimetres
        assert rescale is not None
        prev = [(r.model, r.info["marker_placement"]) for r in results[:2]]
        split = rescale(f, prev[0])
        assert split.call is not None
        if prev[1][1] is prev[0][1]:  # the two starts were one (a pulled route before)
            model, placed = split.model, split.info["marker_placement"]
        else:
            model, placed = continued_placement(split.call, *prev[1])
        # and the split model placed anew, pulled towards neutral (unique, as the pulled start):
        # a continued placement keeps clusters the unsplit model had lost (UWA running, left
        # leg at the stature's length: thigh and shank clusters 55–62 mm loose, continued on
        # the split model as they were)
        c = split.call
        anew = place_markers_from_motion(
            c.model, c.markers, c.labels, c.time, **c.keywords, regularize=True, warm={}
        )
        return [
            ({"leg_split": True, "start": "as before"}, split),
            ({"leg_split": True, "start": "pulled"}, replace(split, model=model,
             info={**split.info, "marker_placement": placed})),
            ({"leg_split": True, "start": "pulled anew"}, replace(split, model=anew[0],
             info={**split.info, "marker_placement": anew[1]})),
        ]  # fmt: skip

    first = starts()
    # one marker set for all: every marker the two starts place, the model's own included (a
    # candidate that leaves one out as too loose is measured on it at its pose)
    union = set().union(*(set(c.model.marker_names) for _, c in first))
    markers = sorted(union & set(labels))

    def cost(model: Model, mp: Mapping[str, Any]) -> float:
        state = dict(mp.get("state", {}))
        loose = {k: (str(state[k][0]), state[k][2]) for k in mp.get("too_loose", {}) if k in state}
        return placement_cost(model, x, t, labels, weights, markers, loose)

    records: list[dict[str, Any]] = []
    results: list[Candidate] = []

    def refine(c: Candidate) -> tuple[Model, dict[str, Any]]:
        call = c.call
        assert call is not None
        return refine_placement_from_motion(
            call.model, call.markers, call.labels, call.time,
            (c.model, c.info["marker_placement"]), cost,
            max_rounds=DESCENT_MAX_ROUNDS, rel_tolerance=DESCENT_REL_TOLERANCE, **call.keywords,
        )  # fmt: skip

    def descend(cands: list[tuple[dict[str, Any], Candidate]]) -> None:
        # the descents are independent (each its own passes and warm starts, one fixed cost):
        # every one after the first runs in a forked child on a second CPU when there is one
        # (msk._runtime.fork; the same code on the same data: the same numbers)
        firsts = {
            id(c.info["marker_placement"]): i for i, (_, c) in reversed(list(enumerate(cands)))
        }
        forked = {
            i: Forked(_refined_state, refine, c)
            for i, (_, c) in enumerate(cands)
            if i and firsts[id(c.info["marker_placement"])] == i and spare_cpu()
        }  # fmt: skip
        done: list[tuple[Any, Candidate]] = []  # (start placement, descended result)
        for i, (spec, c) in enumerate(cands):
            mp = c.info["marker_placement"]
            same = [r for m, r in done if m is mp]  # the same start (a pulled route before)
            if same:
                got_model, got = same[0].model, same[0].info["marker_placement"]
            elif i in forked:
                state, got = forked[i].result()
                got_model = Model.from_state(state)
            else:
                got_model, got = refine(c)
            path = got["descent_cost_m"]
            results.append(replace(c, model=got_model,
                                   info={**c.info, "marker_placement": got}))  # fmt: skip
            done.append((mp, results[-1]))
            records.append({**spec, "cost_m": path[-1], "rounds": len(path) - 1,
                            "stop": got["descent_stop"]})  # fmt: skip

    def pick() -> int:
        costs = [r["cost_m"] for r in records]
        rank = {"pulled": 0, "as before": 1, "pulled anew": 2}
        order = sorted(range(len(records)), key=lambda i: (
            not records[i]["leg_split"], rank[records[i]["start"]]))  # fmt: skip
        return next(i for i in order if costs[i] <= min(costs) + CHOICE_TOLERANCE_M)

    descend(first)
    functional = split_of(results[pick()]) if split_of is not None else None
    if functional:
        descend(split_starts(functional))
    # judged on every marker any candidate places: a marker the unsplit starts left out as too
    # loose that a split candidate places again counts for all (measured at its pose where a
    # candidate left it out), so that losing a cluster does not lower a candidate's cost
    every = set().union(*(set(r.model.marker_names) for r in results)) & set(labels)
    if every - set(markers):
        markers[:] = sorted(every)
        for rec, res in zip(records, results, strict=True):
            rec["descent_cost_m"] = rec["cost_m"]
            rec["cost_m"] = cost(res.model, res.info["marker_placement"])
    best = pick()
    choice = PlacementChoice(
        objective="task IK (weights, held feet, no filter): weighted marker RMS over every "
        "marker a candidate places, mean over frames",
        frames=int(t.size),
        candidates=tuple(
            CandidateCost(
                leg_split=bool(r["leg_split"]),
                start=str(r["start"]),
                cost_m=r["cost_m"],
                rounds=int(r["rounds"]),
                stop=r["stop"],
                descent_cost_m=r.get("descent_cost_m"),
            )
            for r in records
        ),
        chosen=best,
    )
    return results[best], choice
