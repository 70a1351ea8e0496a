"""Stage ``strength_identification``: one strength factor per EMG channel's muscle group from
the EMG activations, the moment-arm Jacobians and the joint torques, with bootstrap intervals
(:class:`msk.strength.StrengthIdentifier`; Hayashibe et al. 2011, §V, Eq. 12–16).

Frames per leg: the regression's rows are (frame, coordinate) pairs of Eq. 16, and a row of
coordinate j holds only the groups whose muscles cross j — the groups of one leg never share
a row with the other leg's coordinates. A frame where the OTHER foot stands on a surface no
plate measures leaves this leg's torques exact (RNEA's torque at a joint balances its distal
subtree, Featherstone 2008 §5.3), so the stage uses every frame in which no coordinate the
groups' muscles cross is unbalanced (:attr:`msk.pipeline.loads.Loads.unbalanced`): with EMG on
one leg, that leg's own frames (its foot measured or swinging); with EMG on both legs, the
frames where both are solvable. The unbalanced coordinates of such a frame (the other leg's,
crossed by no group) are not regressed."""

from __future__ import annotations

from typing import Any

import numpy as np

from msk.dynamics.inverse import InverseDynamics
from msk.exceptions import IdentificationError
from msk.muscles.emg import EmgActivations
from msk.personalise import Personalisation
from msk.pipeline.inputs import SessionInputs
from msk.pipeline.records import Loads, StrengthIdentification
from msk.pipeline.runner import StageUnavailable

__all__ = ["regression_rows", "run"]


def run(
    inputs: SessionInputs,
    model: Personalisation,
    kinematics: Any,
    loads: Loads,
    inverse_dynamics: InverseDynamics,
    emg: EmgActivations,
    muscle_geometry: Any,
) -> StrengthIdentification:
    from msk.muscles.geometry import muscle_parameters
    from msk.muscles.hill import RigidTendonStateBlocks
    from msk.strength import StrengthIdentifier
    from msk.strength.identification import envelope_window_s, gating_windows
    from msk.timeseries import FrameSparse

    jt = inverse_dynamics.torques
    params = muscle_parameters(model.model)
    groups, failed, good, tau = regression_rows(
        params, loads, inverse_dynamics, emg, muscle_geometry
    )
    frames = np.flatnonzero(good)
    # gating windows of ≥ 3 envelope correlation times that never straddle a gap, when the
    # identifier's equal chunks of a few solvable frames would be shorter (one stance on the
    # plates): the runs too short for one (swing between plates) are left out
    t = np.asarray(kinematics.time, dtype=float)
    rate = (t.size - 1) / float(t[-1] - t[0]) if t.size > 1 else 1.0
    keep, windows = gating_windows(frames, rate, envelope_window_s(inputs.cfg.emg.lowpass_hz))
    if windows is not None:
        good = good.copy()
        good[frames[~keep]] = False
        frames = frames[keep]
    # the Hill state of the frames used, computed block by block as the identifier needs it
    # (its ten (N, M) arrays are never held whole); the compact Jacobian of those frames only
    state = RigidTendonStateBlocks(
        params, muscle_geometry.lengths, muscle_geometry.velocities, frames
    )
    # the measured muscles' columns only (compact over the muscles: the others are 0, and a
    # long trial's (N, M) activation would be the stage's largest array)
    cols = sorted({params.names.index(m) for k, m in enumerate(emg.muscles) if emg.usable[k]})
    act = FrameSparse(
        np.zeros((frames.size, len(cols))), np.asarray(cols, dtype=np.intp), (len(params.names),)
    )
    for k, m in enumerate(emg.muscles):
        if emg.usable[k]:
            act.values[:, cols.index(params.names.index(m))] = emg.activation[good, k]
    est = StrengthIdentifier(groups, params, n_bootstrap=200, random_state=0)
    # the whole trial's compact Jacobian, its rows of the used frames read block by block
    jac = muscle_geometry.jacobian
    jac = jac if isinstance(jac, FrameSparse) else np.asarray(jac)
    try:
        est.fit(
            jac,
            act,
            tau[good],
            state,
            coordinate_names=jt.coordinate_names,
            frames=frames,
            windows=windows,
        )
    except IdentificationError as exc:
        # the measured frames do not determine any group (e.g. no window passes the
        # correlation gate on a trial with one stance on the plates): not available, said why
        raise StageUnavailable(
            f"the {int(good.sum())} solvable frames determine no strength: {exc}"
        ) from None
    return StrengthIdentification(
        est.profile_,
        {g: list(v) for g, v in groups.items()},
        float(kinematics.time[good][0]),
        _protocols(model.model, est.profile_, groups),
        _failed(model.model, emg, failed),
    )


def regression_rows(
    params: Any,
    loads: Loads,
    inverse_dynamics: InverseDynamics,
    emg: EmgActivations,
    muscle_geometry: Any,
) -> tuple[dict[str, list[str]], dict[str, list[str]], Any, Any]:
    """The groups (channel → muscles) of the usable EMG channels, those whose channel failed a
    check, the frames whose rows enter the regression (module docstring: no coordinate a
    group's muscles cross is unbalanced, finite torques) and the torques with the unbalanced
    coordinates set to 0 (not regressed). :class:`StageUnavailable` when no channel or no frame
    is usable."""
    from msk.muscles.geometry import moment_arm_pattern

    jt = inverse_dynamics.torques
    groups: dict[str, list[str]] = {}
    failed: dict[str, list[str]] = {}
    for k, m in enumerate(emg.muscles):
        (groups if emg.usable[k] else failed).setdefault(emg.sources[k], []).append(m)
    if not groups:
        raise StageUnavailable("no usable EMG channel")
    # per leg (module docstring): no coordinate a group's muscle crosses (has a moment arm
    # about in some frame) may be unbalanced; the others' torques (NaN where unbalanced) are
    # not regressed
    unbalanced = loads.unbalanced_for(jt.coordinate_names)
    grouped = [params.names.index(m) for v in groups.values() for m in v]
    crossed = moment_arm_pattern(muscle_geometry.jacobian)[grouped].any(axis=0)
    good = (
        loads.solvable
        & ~(unbalanced & crossed).any(axis=1)
        & (np.isfinite(jt.tau) | unbalanced).all(axis=1)
    )
    if not good.any():  # e.g. a trial no foot stands on a plate in: a reason, not a traceback
        raise StageUnavailable(
            "no frame in which the EMG groups' legs have their foot contact measured (or "
            "swing), every leg segment observed and finite joint torques"
        )
    return groups, failed, good, np.where(unbalanced, 0.0, jt.tau)


def _failed(model: Any, emg: EmgActivations, failed: dict[str, list[str]]) -> dict[str, Any]:
    """Per group whose channel failed a check: its muscles, the check (the EMG quality lines
    naming the channel) and the test that would identify it once recorded again."""
    quality = getattr(emg, "quality", None)
    lines = list(quality.summary()) if quality is not None else []
    lines += [w for w in getattr(emg, "warnings", ()) if w not in lines]
    out: dict[str, Any] = {}
    protos = _protocols(model, None, failed)
    for g, muscles in failed.items():
        said = [w for w in lines if f"'{g}'" in w and "no MVC" not in w]
        out[g] = {
            "muscles": list(muscles),
            "reason": "its EMG channel failed a check, so it is left out of the regression: "
            + ("; ".join(said) if said else "the channel was excluded by the EMG checks"),
            "protocol": protos.get(g),
        }
    return out


def _protocols(
    model: Any, profile: Any, groups: dict[str, list[str]]
) -> dict[str, dict[str, Any] | None]:
    """Per group not identified, the subject-model test that would identify it
    (:func:`msk.strength.recommend_tests`, per side of the group's muscles)."""
    from msk.exceptions import MskError
    from msk.strength import recommend_tests

    status = {} if profile is None else dict(zip(profile.group_names, profile.statuses()))
    todo = {g: v for g, v in groups.items() if status.get(g) != "identified"}
    out: dict[str, dict[str, Any] | None] = {}
    for sfx, side in (("_r", "right"), ("_l", "left")):
        these = {g: v for g, v in todo.items() if v and v[0].endswith(sfx)}
        try:
            found = recommend_tests(model, these, side=side)
        except MskError:  # a model without the tested joints: no protocol, not a failed stage
            found = dict.fromkeys(these)
        out.update({g: None if p is None else p.as_dict() for g, p in found.items()})
    return out
