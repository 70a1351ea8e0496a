"""A streaming session: one frame of markers (+ plate wrenches, + EMG samples) in, the frame's
joint angles, torques, muscle forces, knee contact and quality out.

The chain of ``msk run`` made causal, each stage the library's own computation of one frame:

1. inverse kinematics of the newest frame, warm-started from the previous one
   (:class:`msk.kinematics.ik.FrameIK`: projected Levenberg–Marquardt on the marker residual with
   Pinocchio's world joint Jacobians, at most ``ik_iterations`` steps);
2. each loaded plate's wrench assigned to the foot (``calcn*``) whose origin is nearest to the
   plate's centre of pressure in the horizontal plane, where its vertical force exceeds
   ``contact_threshold_n`` (a causal rule; the offline run's
   :func:`msk.dynamics.loads.external_loads` assigns contact intervals with the whole trial in
   view);
3. θ and the feet's wrenches through one causal Butterworth low-pass
   (:class:`msk.signal.CausalLowpass`, the same filter on both so that kinematics and ground
   reactions keep the same delay — Kristianslund et al. 2012, J Biomech 45:666), θ̇ and θ̈ by
   the offline run's differences on the filtered samples (``np.gradient`` twice, centred two
   samples back; ``derivative_scheme="central"``: three-point, one sample back): every output
   describes the instant :attr:`LiveSession.lag_s` = τ + 2Δt (τ + Δt) before the newest input
   (τ the filter's group delay at DC); ``smoother="linear_phase"``: the offline run's zero-lag
   filter as a symmetric FIR instead (:class:`msk.signal.LinearPhaseLowpass`, τ = its half
   width, the same for every frequency);
4. inverse dynamics (:class:`msk.dynamics.inverse.FrameInverseDynamics`);
5. muscle–tendon lengths, velocities, moment arms and the knee's unit wrenches in one geometry
   pass (:class:`msk.muscles.geometry.FrameGeometry`, :meth:`GeometryPlan.evaluate
   <msk.muscles.geometry.GeometryPlan.evaluate>` of one frame; the plan's own evaluation for
   paths with wrapping surfaces);
6. static optimisation min Σ w_i a_i² + Σ r_j² with the rigid-tendon force curves
   (:class:`msk.optimization.FrameStaticOptimization`, the QP of
   :func:`msk.optimization.solve_static_optimization_batch` with DAQP warm-started from the
   previous frame's working set; an exponent p > 2 runs the batch's sequential QP on the frame);
7. the tibiofemoral contact force from the tibia free-body diagram
   (:class:`msk.contact.knee.FrameKneeContact`: RNEA's knee wrench of step 4, the muscles'
   pull, the plateau frame — :func:`msk.contact.knee.knee_contact_force` frame by frame) and
   its medial/lateral split (two-point model, Winby et al. 2009).

Allocation: the IK's marker buffers, the filter's state and outputs, the inverse dynamics'
torques, the muscle geometry of the frame (:class:`msk.muscles.geometry.FrameGeometry`), the
force curves (:class:`msk.muscles.hill.RigidTendonFrame`), the static optimisation's
constraint matrix and right-hand side, the contact's load are buffers written in place; the
Levenberg–Marquardt steps, the geometry's and the curves' intermediate products and the QP
solver's call still allocate small temporaries, and each :class:`LiveFrame` owns copies of its
arrays (the buffers are overwritten by the next frame).

Every frame is solved, including those where a foot stands on no plate (the offline run leaves
that leg out of the torques and the muscle forces there; a live frame cannot tell a foot on the
floor from a foot on an unmeasured surface before the contact ends): read the torques and
forces of a leg only while its foot is on a plate or in the air.

The set-up (:func:`live_model`) is done once; :func:`live_step` follows Pinocchio's
``algorithm(model, data, ...)`` style: :class:`LiveModel` holds what does not change,
:class:`LiveData` the buffers and the states carried from frame to frame (filter, warm starts).
"""

from __future__ import annotations

import time as _time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from msk.exceptions import ConfigError, ModelError, ShapeMismatchError
from msk.model.core import Model

__all__ = [
    "FOOT_RADIUS_M",
    "STAGES",
    "LiveData",
    "LiveFrame",
    "LiveInput",
    "LiveModel",
    "LiveOptions",
    "LiveSession",
    "live_data",
    "live_model",
    "live_step",
]

#: the timed stages of :func:`live_step`, in order (:attr:`LiveFrame.stage_s`)
STAGES = ("ik", "loads_filter", "inverse_dynamics", "geometry", "optimization", "knee_contact")


@dataclass(frozen=True)
class LiveOptions:
    """How a live session computes.

    ``cutoff_hz``, ``filter_order``, ``derivative_scheme``: the causal low-pass of θ and the
    feet's wrenches and its differences (:class:`msk.signal.CausalLowpass`; ``"gradient"``, the
    offline run's ``np.gradient`` twice, θ̈ from y_n − 2y_{n−2} + y_{n−4}: on gc5 PS and gc6 DM
    the torques agree with the offline run's by 0.3–4 points of peak more and the axial knee
    contact by 0.005–0.013 BW more than with the three-point ``"central"``, for one sample more
    of lag); ``smoother``: ``"butterworth"`` (that causal low-pass, the shortest lag) or
    ``"linear_phase"`` (:class:`msk.signal.LinearPhaseLowpass`: the offline run's zero-lag
    4th-order Butterworth as a symmetric FIR of half width ``fir_half_width_s``, 14 samples at
    120 Hz — every frequency delayed alike, lag 133 ms at 120 Hz; docs/validation.md, "Live
    mode against the offline run", gives what each agrees to); ``ik_iterations``: the most
    Levenberg–Marquardt steps per frame;
    ``ik_tolerance_rad``, ``ik_rel_tolerance``: a frame's IK stops after a step that
    moves no coordinate by more than ``ik_tolerance_rad`` or lowers the cost by at most
    ``ik_rel_tolerance`` of it (:func:`msk.kinematics.ik.solve_kinematics`' ``tolerance`` and
    ``rel_tolerance``; a frame starts from the previous ones extrapolated, so a step of 1e-3 rad
    = 0.06° is the end of its descent: on gc5 PS and gc6 DM the angles stay within 0.01° of the
    fully converged ones, 2.1 steps a frame instead of 3.5 at 1e-6); ``contact_threshold_n``: a
    plate whose vertical force is at most this loads no foot; ``knee_joint``: the knee whose
    contact force is computed (None: none); ``activation_weights`` ``"volume"`` (w_i = V_i,
    Happee 1994) or ``"none"``, ``activation_exponent``, ``solver``: the static optimisation's.
    """

    cutoff_hz: float = 6.0
    filter_order: int = 2
    derivative_scheme: str = "gradient"
    smoother: str = "butterworth"
    fir_half_width_s: float = 0.12
    ik_iterations: int = 10
    ik_tolerance_rad: float = 1e-3
    ik_rel_tolerance: float = 1e-6
    contact_threshold_n: float = 20.0
    knee_joint: str | None = None
    activation_weights: str = "volume"
    activation_exponent: float = 2.0
    solver: str = "daqp"


@dataclass(frozen=True)
class LiveInput:
    """One frame of a stream, lab frame, SI.

    ``markers`` (M, 3) in the session's label order (NaN: not seen); ``plate_force``,
    ``plate_moment`` (P, 3): each plate's ground reaction on the subject and its moment about
    the lab origin, M_O = c × F + T (``(0, 3)`` without plates); ``emg``
    (C,) the EMG samples of the frame (carried to the output, not used by static optimisation)."""

    time: float
    markers: NDArray[np.float64]
    plate_force: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    plate_moment: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    emg: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))


@dataclass(frozen=True)
class LiveFrame:
    """One frame's results (SI; the columns named by :class:`LiveModel`).

    ``time``: the newest input's time; ``q``, ``v``, ``a``, ``torques``, ``muscle_forces``,
    ``activations``, ``knee_force`` (3,) (tibia plateau frame, on the tibia) and
    ``knee_axial``, ``knee_medial``, ``knee_lateral`` (N) describe the instant
    ``time − lag_s`` (:attr:`LiveSession.lag_s`). Quality: ``marker_rms`` (m, of the newest
    frame's IK), ``ik_iterations``, ``ik_converged``, ``qp_status`` (0 optimal,
    :mod:`msk.optimization`'s codes); ``stage_s`` (len(:data:`STAGES`),) the wall time of each
    stage; ``emg`` the input's samples."""

    time: float
    q: NDArray[np.float64]
    v: NDArray[np.float64]
    a: NDArray[np.float64]
    torques: NDArray[np.float64]
    muscle_forces: NDArray[np.float64]
    activations: NDArray[np.float64]
    knee_force: NDArray[np.float64]
    knee_axial: float
    knee_medial: float
    knee_lateral: float
    marker_rms: float
    ik_iterations: int
    ik_converged: bool
    qp_status: int
    stage_s: NDArray[np.float64]
    emg: NDArray[np.float64]

    @property
    def latency_s(self) -> float:
        """The whole chain's wall time for this frame."""
        return float(self.stage_s.sum())


@dataclass(frozen=True)
class LiveModel:
    """What a live session does not change from frame to frame (:func:`live_model`)."""

    model: Model
    rate_hz: float
    labels: tuple[str, ...]
    rotation: NDArray[np.float64]
    options: LiveOptions
    weights: Mapping[str, float]
    held: Mapping[str, tuple[float, float]]
    ik_markers: tuple[str, ...]
    plan: Any
    params: Any
    feet: tuple[str, ...]
    foot_joints: NDArray[np.intp]
    up: NDArray[np.float64]
    actuated: NDArray[np.intp]
    muscle_names: tuple[str, ...]
    coordinate_names: tuple[str, ...]
    actuated_names: tuple[str, ...]
    activation_weights: NDArray[np.float64] | None
    plateau: Any
    body_weight_n: float
    plate_feet: tuple[int, ...] = ()

    @property
    def n_coords(self) -> int:
        return len(self.coordinate_names)


@dataclass
class LiveData:
    """The buffers and carried states of a live session (:func:`live_data`): the per-frame
    solvers of each stage (their buffers, Pinocchio data and warm starts are this session's)."""

    ik: Any
    dynamics: Any
    optimization: Any
    contact: Any
    theta: NDArray[np.float64]
    pin_data: Any
    markers: NDArray[np.float64]
    channels: NDArray[np.float64]
    filter: Any
    warm: Any
    force: NDArray[np.float64]
    moment: NDArray[np.float64]
    reserve_optimal: NDArray[np.float64]
    jacobian: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 0)))
    jac_keep: NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    jac_at: tuple[NDArray[np.intp], NDArray[np.intp]] = field(
        default_factory=lambda: (np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp))
    )
    geometry: Any = None
    tendon: Any = None
    f_active: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    plate_owner: NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    history: NDArray[np.float64] = field(default_factory=lambda: np.zeros((3, 0)))
    start: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    solved: int = 0
    frames: int = 0


def live_model(
    model: Model,
    labels: Sequence[str],
    rate_hz: float,
    *,
    rotation: NDArray[np.float64] | None = None,
    weights: Mapping[str, float] | None = None,
    held: Mapping[str, tuple[float, float]] | None = None,
    options: LiveOptions | None = None,
    plateau: Any = None,
    body_weight_n: float | None = None,
    plate_bodies: Sequence[str | None] = (),
) -> LiveModel:
    """Set a live session up for the subject's ``model`` (scaled, markers placed: e.g.
    :attr:`msk.personalise.Personalisation.model`) and a stream whose markers are
    ``labels`` (model marker names) at ``rate_hz``, lab frame rotated into the model's by
    ``rotation`` (:attr:`msk.personalise.Personalisation.rotation`). ``weights`` and ``held``:
    the IK's marker weights and coordinate tasks; ``plateau``: the knee's contact points
    (:func:`msk.contact.knee.plateau_geometry`, default from the model); ``plate_bodies``: the
    foot each plate of the stream (in its order) loads when the lab says so (an ExternalLoads
    ``.xml``, ``[loads] assign``; None: assigned per contact, :func:`live_step`)."""
    import msk.optimization as o
    from msk.contact.knee import plateau_geometry
    from msk.dynamics.inverse import _root_info
    from msk.dynamics.loads import _default_feet
    from msk.kinematics.ik import FrameIK
    from msk.muscles.geometry import geometry_plan, muscle_parameters

    opt = options or LiveOptions()
    if opt.smoother not in ("butterworth", "linear_phase"):
        raise ConfigError(f"live smoother {opt.smoother!r}: not 'butterworth' or 'linear_phase'")
    labels = tuple(labels)
    ik = FrameIK(model, labels, weights=weights, coordinate_tasks=dict(held or {}) or None)
    feet = _default_feet(model)
    unknown = [b for b in plate_bodies if b is not None and b not in feet]
    if unknown:
        raise ModelError(
            f"plate assigned to {unknown[0]!r}: not a foot of model {model.name} "
            f"(feet: {', '.join(feet)})"
        )
    plan = geometry_plan(model)
    params = muscle_parameters(model)
    root = set(_root_info(model)[1])
    names = tuple(model.coordinate_names)
    plan_cols = tuple(plan.coordinate_names)
    if plan_cols != names:
        raise ShapeMismatchError("the geometry plan's coordinates are not the model's")
    act = np.array([i for i, c in enumerate(names) if c not in root], dtype=np.intp)
    w = (
        o.volume_weights(params.max_isometric_force, params.optimal_fiber_length)
        if opt.activation_weights == "volume"
        else None
    )
    knee = opt.knee_joint
    if knee is not None and plateau is None:
        plateau = plateau_geometry(model, joint=knee)
    up = -np.asarray(model.gravity, dtype=float)
    up = up / np.linalg.norm(up)
    bw = (
        body_weight_n
        if body_weight_n is not None
        else model.total_mass * float(np.linalg.norm(model.gravity))
    )
    return LiveModel(
        model=model, rate_hz=float(rate_hz), labels=labels,
        rotation=np.eye(3) if rotation is None else np.asarray(rotation, dtype=float),
        options=opt, weights=dict(weights or {}), held=dict(held or {}), ik_markers=ik.used,
        plan=plan, params=params, feet=feet,
        foot_joints=np.array([model.body_joint[f] for f in feet], dtype=np.intp), up=up,
        actuated=act, muscle_names=tuple(params.names), coordinate_names=names,
        actuated_names=tuple(names[i] for i in act), activation_weights=w, plateau=plateau,
        body_weight_n=float(bw),
        plate_feet=tuple(-1 if b is None else feet.index(b) for b in plate_bodies),
    )  # fmt: skip


def live_data(lm: LiveModel, start: NDArray[np.float64] | None = None) -> LiveData:
    """Fresh buffers and states for ``lm``; IK starts from ``start`` (default: the model's
    default pose)."""
    import msk.optimization as o
    from msk.contact.knee import FrameKneeContact
    from msk.dynamics.inverse import FrameInverseDynamics
    from msk.kinematics.ik import FrameIK
    from msk.muscles.geometry import FrameGeometry
    from msk.muscles.hill import RigidTendonFrame
    from msk.signal import CausalLowpass, LinearPhaseLowpass

    n_c, n_f = lm.n_coords, len(lm.feet)
    opt = lm.options
    theta = lm.model.default_coordinates() if start is None else np.array(start, dtype=float)
    knee = opt.knee_joint
    # the actuated columns of the compact geometry Jacobian: which stored entries, where in the
    # (muscles × actuated) block (what msk.muscles.geometry.jacobian_frames gathers per call)
    mus, coord = np.divmod(lm.plan.jacobian_positions(), n_c)
    place = np.full(n_c, -1, dtype=np.intp)
    place[lm.actuated] = np.arange(lm.actuated.size)
    keep = np.flatnonzero(place[coord] >= 0)
    return LiveData(
        # coordinate-major, as jacobian_frames lays it out (the QP's products sum alike)
        jacobian=np.zeros((lm.actuated.size, len(lm.muscle_names))).T,
        jac_keep=keep,
        jac_at=(mus[keep], place[coord[keep]]),
        # wrap-free paths: the one-frame evaluator (else GeometryPlan.evaluate per frame)
        geometry=None
        if lm.plan.wraps
        else FrameGeometry(lm.plan, (knee,) if knee is not None else ()),
        tendon=RigidTendonFrame(lm.params),
        f_active=np.empty(len(lm.muscle_names)),
        ik=FrameIK(
            lm.model,
            lm.labels,
            weights=lm.weights,
            coordinate_tasks=dict(lm.held) or None,
            max_iterations=opt.ik_iterations,
            tolerance=opt.ik_tolerance_rad,
            rel_tolerance=opt.ik_rel_tolerance,
        ),
        dynamics=FrameInverseDynamics(lm.model, lm.feet),
        optimization=o.FrameStaticOptimization(
            lm.muscle_names,
            lm.actuated_names,
            activation_weights=lm.activation_weights,
            solver=opt.solver,
        )
        if opt.activation_exponent == 2.0
        else None,
        contact=None
        if knee is None
        else FrameKneeContact(lm.model, knee, bodies=lm.feet, geometry=lm.plateau),
        theta=theta,
        pin_data=lm.model.pin_model.createData(),
        markers=np.empty((len(lm.labels), 3)),
        channels=np.empty(n_c + 6 * n_f),
        filter=LinearPhaseLowpass(
            n_c + 6 * n_f,
            rate_hz=lm.rate_hz,
            cutoff_hz=opt.cutoff_hz,
            scheme=opt.derivative_scheme,
            half_width_s=opt.fir_half_width_s,
        )
        if opt.smoother == "linear_phase"
        else CausalLowpass(
            n_c + 6 * n_f,
            rate_hz=lm.rate_hz,
            cutoff_hz=opt.cutoff_hz,
            order=opt.filter_order,
            scheme=opt.derivative_scheme,
        ),
        warm=o.WarmStart(),
        force=np.empty((n_f, 3)),
        moment=np.empty((n_f, 3)),
        reserve_optimal=np.ones(lm.actuated.size),
        history=np.zeros((3, n_c)),
        start=np.empty(n_c),
    )


#: a plate's foot is kept while its origin stays this close to the plate's line of action
#: (horizontally; a foot is ~0.25 m long, its body origin at the heel), as
#: :func:`msk.dynamics.loads.external_loads`' ``cop_radius_m``
FOOT_RADIUS_M = 0.30


def _assign_plates(lm: LiveModel, ld: LiveData, frame: LiveInput) -> None:
    """The feet's wrenches (model frame, moment about the origin) into ``ld.force``/``moment``.

    A plate the set-up assigns to a foot (``plate_bodies``) loads that foot. Any other plate
    loaded above the threshold goes to the foot nearest to its line of action (horizontal
    distance from the foot body's origin, at the newest IK pose, to the point
    p₀ = F × M_O / |F|² of the line, which is the centre of pressure's horizontal position for a
    near-vertical F) when its contact starts, and stays that foot's while the foot stays within
    :data:`FOOT_RADIUS_M` of it (a swinging foot passes close to the other foot's centre of
    pressure; the other foot may land on the same plate before the first leaves it)."""
    ld.force[:] = 0.0
    ld.moment[:] = 0.0
    n_p = frame.plate_force.shape[0]
    if not n_p:
        return
    if ld.plate_owner.size != n_p:
        ld.plate_owner = np.full(n_p, -1, dtype=np.intp)
    r, up = lm.rotation, lm.up
    f = frame.plate_force @ r.T
    m = frame.plate_moment @ r.T
    loaded = (f @ up > lm.options.contact_threshold_n) & np.isfinite(m).all(axis=1)
    owner = ld.plate_owner
    owner[~loaded] = -1
    if not loaded.any():
        return
    fixed = lm.plate_feet
    feet = None
    for p in np.flatnonzero(loaded).tolist():
        k = fixed[p] if p < len(fixed) else -1
        if k < 0:
            if feet is None:
                prob = ld.ik.problem
                if prob._at is ld.theta:  # the IK's last placements are those of θ
                    omi = prob.data.oMi.tolist()
                else:
                    pin.forwardKinematics(
                        lm.model.pin_model, ld.pin_data, prob.coupling.q(ld.theta)
                    )
                    omi = ld.pin_data.oMi.tolist()
                feet = np.array([omi[j].translation for j in lm.foot_joints.tolist()])
            (f0, f1, f2), (m0, m1, m2) = f[p].tolist(), m[p].tolist()
            s2 = f0 * f0 + f1 * f1 + f2 * f2
            p0 = ((f1 * m2 - f2 * m1) / s2, (f2 * m0 - f0 * m2) / s2, (f0 * m1 - f1 * m0) / s2)
            d = feet - np.array(p0)
            d -= np.outer(d @ up, up)
            dist2 = np.einsum("ij,ij->i", d, d)
            k = int(owner[p])
            if k < 0 or dist2[k] > FOOT_RADIUS_M**2:
                k = owner[p] = int(np.argmin(dist2))
        ld.force[k] += f[p]
        ld.moment[k] += m[p]


def live_step(lm: LiveModel, ld: LiveData, frame: LiveInput) -> LiveFrame:
    """One frame through the chain (module docstring); ``ld`` carries the states."""
    import msk.optimization as o

    clock = _time.perf_counter
    stage = np.empty(len(STAGES))
    t0 = clock()
    x = ld.markers
    np.matmul(frame.markers, lm.rotation.T, out=x)
    # the start: the previous solutions extrapolated (constant acceleration, as the batch IK)
    h, n_h = ld.history, ld.solved
    start = ld.start
    if n_h >= 3:
        np.subtract(h[0], h[1], out=start)
        start *= 3.0
        start += h[2]
    elif n_h == 2:
        np.multiply(h[0], 2.0, out=start)
        start -= h[1]
    else:
        start[:] = ld.theta
    theta, iters, converged, rms = ld.ik.solve(start, x)
    if np.isfinite(rms):
        h[2] = h[1]
        h[1] = h[0]
        h[0] = theta
        ld.solved = min(n_h + 1, 3)
    else:
        ld.solved = 0
    ld.theta = theta
    t1 = clock()
    stage[0] = t1 - t0
    _assign_plates(lm, ld, frame)
    n_c, n_f = lm.n_coords, len(lm.feet)
    ch = ld.channels
    ch[:n_c] = theta
    ch[n_c : n_c + 3 * n_f] = ld.force.ravel()
    ch[n_c + 3 * n_f :] = ld.moment.ravel()
    filt = ld.filter
    filt.step(ch)
    q, v, a = filt.y[:n_c], filt.dy[:n_c], filt.ddy[:n_c]
    force = filt.y[n_c : n_c + 3 * n_f].reshape(n_f, 3)
    moment = filt.y[n_c + 3 * n_f :].reshape(n_f, 3)
    t2 = clock()
    stage[1] = t2 - t1
    tau = ld.dynamics.torques(q, v, a, force, moment)
    t3 = clock()
    stage[2] = t3 - t2
    knee = lm.options.knee_joint
    fg = ld.geometry
    if fg is not None:
        fg.evaluate(q, v)
        lengths, speeds, jl = fg.lengths, fg.velocities, fg.jacobian
        distal = fg.distal_wrenches
    else:
        geo = lm.plan.evaluate(
            q[None], v[None], distal_wrench_joints=(knee,) if knee else (), compact=True
        )
        lengths, speeds, jl = geo.lengths[0], geo.velocities[0], geo.jacobian.values[0]
        distal = {k: w[0] for k, w in geo.distal_wrenches.items()}
    t4 = clock()
    stage[3] = t4 - t3
    fmax, f_passive = ld.tendon(lengths, speeds)
    fa = ld.f_active
    np.maximum(fmax, 0.0, out=fa)
    jac = ld.jacobian  # its other entries stay 0
    jac[ld.jac_at] = jl[ld.jac_keep]
    opt = lm.options
    if ld.optimization is not None:
        forces, acts, status = ld.optimization.solve(jac, tau[lm.actuated], fa, f_passive)
    else:  # exponent > 2: the batch's sequential QP on this one frame
        sol = o.solve_static_optimization_batch(
            jac[None], tau[lm.actuated][None], f_active=fa[None],
            f_passive=f_passive[None], reserve_optimal_force=ld.reserve_optimal,
            activation_weights=lm.activation_weights, activation_exponent=opt.activation_exponent,
            solver=opt.solver, warm=ld.warm, compute_kkt=False, muscle_names=lm.muscle_names,
            coordinate_names=lm.actuated_names, time=np.array([frame.time]),
        )  # fmt: skip
        assert sol.activations is not None  # compute_kkt=False keeps the activations
        forces, acts, status = sol.forces[0], sol.activations[0], int(sol.status[0])
    t5 = clock()
    stage[4] = t5 - t4
    kf = np.full(3, np.nan)
    axial = medial = lateral = float("nan")
    if knee is not None and ld.contact is not None:
        axial, medial, lateral = ld.contact.contact(
            ld.dynamics.data, forces, distal[knee], force, moment
        )
        kf = ld.contact.force.copy()
    stage[5] = clock() - t5
    ld.frames += 1
    return LiveFrame(
        time=float(frame.time), q=q.copy(), v=v.copy(), a=a.copy(), torques=tau.copy(),
        muscle_forces=np.array(forces, dtype=float), activations=np.array(acts, dtype=float),
        knee_force=kf, knee_axial=axial, knee_medial=medial, knee_lateral=lateral,
        marker_rms=rms, ik_iterations=int(iters), ik_converged=bool(converged),
        qp_status=int(status), stage_s=stage, emg=np.asarray(frame.emg, dtype=float),
    )  # fmt: skip


class LiveSession:
    """A live session: :func:`live_model` once, then :meth:`step` per frame.

    ``lag_s``: how far behind the newest input the outputs are (the causal filter's group
    delay at DC plus the samples its differences look back:
    :attr:`msk.signal.CausalLowpass.lag_s`)."""

    def __init__(self, model: LiveModel, start: NDArray[np.float64] | None = None) -> None:
        self.model = model
        self.data = live_data(model, start)

    @property
    def lag_s(self) -> float:
        return float(self.data.filter.lag_s)

    def step(self, frame: LiveInput) -> LiveFrame:
        """One frame in, its results out (:func:`live_step`)."""
        return live_step(self.model, self.data, frame)
