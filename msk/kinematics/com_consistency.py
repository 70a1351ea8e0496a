"""Coordinate accelerations made consistent with the low-passed centre of mass of every segment.

Inverse dynamics balances the ground reactions F, low-passed at f_c, against the segments'
inertial forces. The plates' filter is linear, so F is balanced exactly by a centre of mass low-
passed by the same filter (Kristianslund E, Krosshaug T, van den Bogert AJ (2012) J Biomech
45:666–671: filter the markers and the forces alike). msk low-passes the coordinates θ
(:func:`msk.kinematics.ik.filtered_derivatives`), and a segment's COM is a product of its chain's
rotations, not linear in θ: where segments turn fast (running) the COM acceleration of the
low-passed θ differs from the low-passed COM acceleration, and that difference is left in the
pelvis residual and the joint moments (13.3 % BW of residual force from the method alone on a known
running truth, 0.4–1.5 % on walks; docs/validation.md).

This module keeps the low-passed θ and θ̇ and changes θ̈ only along the root's translations,
which move every segment alike, so that the whole-body COM acceleration equals the low-passed
one of the unfiltered solution::

    ā_G = (1/M) Σ_b m_b d²/dt² LP_fc[c_b(θ_raw)]          (each body's world COM, filtered)
    a_G(θ̈) = (1/M) Σ_b m_b (β_b + J_b θ̈)                 (at θ_f, θ̇_f)
    θ̈*_t = θ̈_f,t + T⁺ (ā_G − a_G(θ̈_f)),   θ̈*_r = θ̈_f,r

with J_b the COM Jacobians, β_b the velocity-product accelerations, T the (identical) columns
of J_b of the root's translation coordinates t (the identity for a free-floating pelvis) and r
every other coordinate. Then M (a_G − g) − F = M (ā_G − g) − LP_fc[F_true + noise]: with a true
F the pelvis residual force keeps no artefact of the filter's domain, only the data's own
inconsistency. The joint angles' accelerations are the low-passed θ's: a joint torque changes
only by the inertial force m δ of the segments beyond it, δ = ā_G − a_G(θ̈_f) (UWA running,
generic model: hip 3–4, knee 1.2, lumbar 7 N·m RMS, against 22–27 N·m when every θ̈ is fitted
to every segment's low-passed COM, a fit that drives the feet's rotations to several hundred
rad/s² — tried, not shipped). The residual *moment* is not made consistent (the angular
momentum is not linear in θ either). The masses m_b are the model's own (in the pipeline the
generic model's, at the kinematics stage): with masses identified later the whole-body match
holds to the degree the two distributions move their COM alike.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from msk.dynamics.regressors import spatial_kinematics
from msk.kinematics.ik import Kinematics, filtered_derivatives
from msk.model.core import Model
from msk.units import Array

__all__ = [
    "com_accelerations",
    "com_consistent_kinematics",
    "low_passed_com_accelerations",
    "root_translation_coordinates",
]


#: frames per block (a long trial's per-frame joint placements and COM Jacobians, ~20 kB a frame
#: on gait2392, are never held whole)
BLOCK = 4096


def _blocks(rows: NDArray[np.intp]) -> list[NDArray[np.intp]]:
    return [rows[i : i + BLOCK] for i in range(0, rows.size, BLOCK)]


def _mass_bodies(model: Model) -> list[tuple[int, Array, float]]:
    """(joint id, COM in the joint frame, mass) of every body with mass on a moving joint."""
    out = []
    for b in model.bodies:
        jid = model.body_joint[b.name]
        if jid == 0 or b.mass <= 0:
            continue
        place = model.body_placement[b.name]
        out.append((jid, place.rotation @ b.com + place.translation, float(b.mass)))
    return out


def _world_coms(kin: Any, bodies: list[tuple[int, Array, float]]) -> Array:
    """(N, B, 3) world COM of each body from :func:`msk.dynamics.regressors.spatial_kinematics`."""
    return np.stack([kin.translation[j] + kin.rotation[j] @ c for j, c, _ in bodies], axis=1)


def root_translation_coordinates(model: Model) -> tuple[str, ...]:
    """The coordinates that drive a prismatic Pinocchio joint supporting every massive body (a
    free-floating pelvis: ``pelvis_tx, pelvis_ty, pelvis_tz``); each translates every segment
    alike."""
    pm = model.pin_model
    bodies = _mass_bodies(model)
    common = set.intersection(*(set(pm.supports[j]) for j, _, _ in bodies)) if bodies else set()
    names = []
    for j in sorted(common - {0}):
        if pm.joints[j].shortname().startswith("JointModelP"):
            k = model.coupling.coordinate[pm.joints[j].idx_v]
            if k >= 0:
                names.append(model.coordinate_names[k])
    return tuple(dict.fromkeys(names))


def low_passed_com_accelerations(
    model: Model, kinematics: Kinematics, *, filter_order: int = 4
) -> Array:
    """ā_b (N, B, 3): each massive body's world COM along the *unfiltered* solution
    (``kinematics.q_raw``) low-passed at ``kinematics.cutoff_hz`` and differentiated twice, over
    the solved window exactly as θ is (:func:`msk.kinematics.ik.filtered_derivatives`: same
    filter, padding and bridging). NaN where θ is. Bodies in :attr:`Model.bodies` order, those
    without mass or on the ground left out."""
    bodies = _mass_bodies(model)
    th = np.asarray(kinematics.q_raw, dtype=float)
    n = th.shape[0]
    ok = np.isfinite(th).all(axis=1)
    coms = np.full((n, len(bodies), 3), np.nan)
    for rows in _blocks(np.flatnonzero(ok)):
        q = model.coupling.q(th[rows])
        zero = np.zeros_like(q)
        coms[rows] = _world_coms(spatial_kinematics(model, q, zero, zero), bodies)
    _, _, acc = filtered_derivatives(
        np.asarray(kinematics.time, dtype=float),
        coms.reshape(n, -1),
        kinematics.cutoff_hz,
        filter_order,
    )
    return acc.reshape(n, len(bodies), 3)


def com_accelerations(
    model: Model,
    theta: Array,
    theta_dot: Array,
    theta_ddot: Array,
    *,
    columns: Sequence[int] | None = None,
) -> tuple[Array, Array]:
    """World COM accelerations a_b = β_b + J_b θ̈ of every massive body at (θ, θ̇, θ̈), (K, B, 3),
    and the COM Jacobians J_b (K, B, 3, n_coords) — only their ``columns`` (coordinate indices,
    in that order) when given."""
    bodies = _mass_bodies(model)
    q, v, a = model.coupling.embed(theta, theta_dot, theta_ddot)
    g = model.coupling.jacobian(theta)  # (K, nq, n)
    kin = spatial_kinematics(model, q, v, a)
    pm = model.pin_model
    gravity = np.asarray(pm.gravity.linear, dtype=float)  # the universe accelerates by −g
    coms = _world_coms(kin, bodies)
    k = theta.shape[0]
    acc = np.empty((k, len(bodies), 3))
    cols = range(theta.shape[1]) if columns is None else columns
    where = {int(c): p for p, c in enumerate(cols)}
    jac = np.zeros((k, len(bodies), 3, len(where)))
    dof_joint = {pm.joints[j].idx_v: j for j in range(1, pm.njoints)}
    for i, (jid, _, _) in enumerate(bodies):
        c = coms[:, i]
        vel, ac = kin.velocity[jid], kin.acceleration[jid]
        w = vel[:, 3:]
        v_c = vel[:, :3] + np.cross(w, c)
        acc[:, i] = ac[:, :3] + np.cross(ac[:, 3:], c) + np.cross(w, v_c) + gravity
        for dof, coord in enumerate(model.coupling.coordinate):
            j = dof_joint[dof]
            if coord not in where or j not in pm.supports[jid]:
                continue
            s = kin.subspace[j]
            col = where[coord]
            jac[:, i, :, col] += g[:, dof, coord, None] * (s[:, :3] + np.cross(s[:, 3:], c))
    return acc, jac


def com_consistent_kinematics(
    model: Model, kinematics: Kinematics, *, filter_order: int = 4
) -> Kinematics:
    """``kinematics`` with the root's translational θ̈ replaced by θ̈*_t of the module docstring
    (θ, θ̇ and every other θ̈ unchanged; frames whose θ̈ is NaN stay NaN). Without a cut-off
    (nothing is low-passed) or without a translating root the kinematics are returned as they
    are. ``metadata["acceleration_domain"]`` says what was applied."""
    trans = [model.coordinate_index(c) for c in root_translation_coordinates(model)]
    if kinematics.cutoff_hz is None or not trans:
        return kinematics
    masses = np.array([m for _, _, m in _mass_bodies(model)])
    target = low_passed_com_accelerations(model, kinematics, filter_order=filter_order)
    th, thd, thdd = (np.asarray(x, dtype=float) for x in (kinematics.q, kinematics.v, kinematics.a))
    ok = np.isfinite(th).all(axis=1) & np.isfinite(thd).all(axis=1)
    ok &= np.isfinite(thdd).all(axis=1) & np.isfinite(target).all(axis=(1, 2))
    a_new = thdd.copy()
    cols = np.asarray(trans, dtype=np.intp)
    for rows in _blocks(np.flatnonzero(ok)):
        acc, jac = com_accelerations(model, th[rows], thd[rows], thdd[rows], columns=trans)
        delta = np.einsum("kbi,b->ki", target[rows] - acc, masses) / masses.sum()  # ā_G − a_G
        # T (K, 3, n_t): the translations' columns, the same for every body
        step = (np.linalg.pinv(jac[:, 0]) @ delta[..., None])[..., 0]  # T⁺ (ā_G − a_G)
        a_new[np.ix_(rows, cols)] += step
    meta = {**dict(kinematics.metadata), "acceleration_domain": "segment_com"}
    return dataclasses.replace(kinematics, a=a_new, metadata=meta)
