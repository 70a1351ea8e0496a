"""Maximal isometric joint-moment curves: joint-level strength a clinician reads.

For one action (e.g. "knee extension") the swept coordinate θ takes each angle of a grid, the
other coordinates sit in a fixed test posture (below), and every muscle is fully activated
(a = ``activation``) with the rigid-tendon Hill state at zero velocity
(:func:`msk.muscles.hill.rigid_tendon_state`, the state the pipeline's strength stage uses)::

    F_i(θ)  = a · F_iso,i · f_l(l̃_f,i(θ)) · f_v(0) · cos α_i(θ)        (active fibre force along
                                                                         the tendon, N)
    M(θ)    = Σ_{i: s r_i(θ) > 0} s · r_i(θ) · F_i(θ),   r_i = −∂l_i/∂θ  (N·m)

with s = ±1 the sign of the action's direction in the coordinate's convention. Only agonists
count (muscles whose moment arm has the sign of the action at that angle): antagonists are
taken as silent in a maximal effort. Passive fibre forces are left out (a dynamometer's
gravity/passive correction is customary; active moment only). M is positive in the named
direction.

gait2392 sign conventions: ``knee_angle`` negative in flexion, ``ankle_angle`` positive in
dorsiflexion, ``hip_flexion`` positive in flexion, ``hip_adduction`` positive in adduction. The
angles of a curve are given in the clinical convention of its :attr:`MomentCurve.angle_label`
(knee flexion ≥ 0, ankle dorsiflexion, hip flexion, hip abduction).

Test postures (:data:`ACTIONS`; every coordinate not named sits at 0, the model's neutral):

* knee extension / flexion: hip 0°, ankle 0°, knee swept 0–90° flexion;
* ankle plantar- / dorsiflexion: hip 0°, knee 0° (extended, as in the usual dynamometry with
  the knee straight), ankle swept 30° plantarflexion to 20° dorsiflexion;
* hip flexion / extension / abduction: knee 60° flexion, ankle 0°, hip flexion swept −10–90°,
  abduction 0–40° (hip flexion 0°).

Published adult dynamometry norms are not included: no norm table has been typed from a
source we could cite with its table number (see :data:`NORMS_NOTE`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from msk.exceptions import ModelError
from msk.units import Array

__all__ = [
    "ACTIONS",
    "NORMS_NOTE",
    "STATUS_SHARE_MIN",
    "ActionSpec",
    "JointStrengthCurves",
    "MomentCurve",
    "action_status",
    "joint_strength_summary",
    "max_isometric_moment_curves",
]

#: Why the report shows no published norms beside the curves.
NORMS_NOTE = (
    "No published adult dynamometry norms are shown: no norm table for the subject's sex and "
    "age has been typed into msk from a source it can cite with its table number."
)
#: Smallest share of an action's peak moment (generic model) a strength group must carry for
#: its status to decide the status of the action's identified curve (dimensionless). A group
#: below it changes the curve by at most this share × |factor − 1| (≤ 5 % within the 0.5–2 ×
#: bounds).
STATUS_SHARE_MIN = 0.05


@dataclass(frozen=True)
class ActionSpec:
    """One joint action: swept coordinate stem (``knee_angle``), its angle in the clinical
    convention ``angle = coordinate_sign · θ`` (deg), the direction of the action
    (``direction``: +1 when the action turns θ positive), the default angle grid (deg) and the
    test posture of the other coordinates (stem → clinical angle in deg of that coordinate's
    own convention, i.e. the coordinate value in deg)."""

    name: str
    coordinate: str
    angle_label: str
    coordinate_sign: float
    direction: float
    angles_deg: tuple[float, ...]
    posture_deg: Mapping[str, float] = field(default_factory=dict)


def _grid(lo: float, hi: float, step: float = 5.0) -> tuple[float, ...]:
    return tuple(float(x) for x in np.arange(lo, hi + 0.5 * step, step))


_KNEE = _grid(0.0, 90.0)
_ANKLE = _grid(-30.0, 20.0)
_HIP = _grid(-10.0, 90.0)
_ABD = _grid(0.0, 40.0)
_K60 = {"knee_angle": -60.0}
#: The actions of the report, with their test postures (knee_angle −60° = 60° flexion).
ACTIONS: dict[str, ActionSpec] = {
    a.name: a
    for a in (
        ActionSpec("knee extension", "knee_angle", "knee flexion", -1.0, 1.0, _KNEE),
        ActionSpec("knee flexion", "knee_angle", "knee flexion", -1.0, -1.0, _KNEE),
        ActionSpec("ankle plantarflexion", "ankle_angle", "ankle dorsiflexion", 1.0, -1.0, _ANKLE),
        ActionSpec("ankle dorsiflexion", "ankle_angle", "ankle dorsiflexion", 1.0, 1.0, _ANKLE),
        ActionSpec("hip flexion", "hip_flexion", "hip flexion", 1.0, 1.0, _HIP, _K60),
        ActionSpec("hip extension", "hip_flexion", "hip flexion", 1.0, -1.0, _HIP, _K60),
        ActionSpec("hip abduction", "hip_adduction", "hip abduction", -1.0, -1.0, _ABD, _K60),
    )
}


@dataclass(frozen=True)
class MomentCurve:
    """Maximal isometric moment of one action over its angle grid.

    ``angles_deg`` (n,) in the clinical convention of ``angle_label``; ``moment_nm`` (n,) N·m,
    positive in the named direction; ``muscles`` the agonists (moment arm of the action's sign
    at some angle) and ``contributions_nm`` (n, len(muscles)) their share of ``moment_nm``
    (N·m, summing to it), or ``None`` when not kept; ``posture_deg`` the coordinates held
    (coordinate name → value in deg, the model's convention).
    """

    action: str
    coordinate: str
    angle_label: str
    angles_deg: Array
    moment_nm: Array
    muscles: tuple[str, ...]
    contributions_nm: Array | None
    posture_deg: Mapping[str, float]

    @property
    def peak_nm(self) -> float:
        return float(np.max(self.moment_nm)) if self.moment_nm.size else float("nan")

    @property
    def peak_angle_deg(self) -> float:
        if not self.moment_nm.size:
            return float("nan")
        return float(self.angles_deg[int(np.argmax(self.moment_nm))])


@dataclass(frozen=True)
class JointStrengthCurves:
    """Curves per action (:class:`MomentCurve`) of one model and side at ``activation``."""

    model_name: str
    side: str
    activation: float
    curves: Mapping[str, MomentCurve]

    def __getitem__(self, action: str) -> MomentCurve:
        try:
            return self.curves[action]
        except KeyError:
            raise KeyError(f"no action {action!r}; have {sorted(self.curves)}") from None

    @property
    def actions(self) -> tuple[str, ...]:
        return tuple(self.curves)

    def as_dict(self, mass_kg: float | None = None) -> dict[str, Any]:
        """JSON-serialisable record (lists; N·m/kg when ``mass_kg`` is given)."""
        out: dict[str, Any] = {
            "model": self.model_name,
            "side": self.side,
            "activation": self.activation,
            "actions": [],
        }
        for c in self.curves.values():
            rec: dict[str, Any] = {
                "action": c.action,
                "coordinate": c.coordinate,
                "angle_label": c.angle_label,
                "angles_deg": [float(x) for x in c.angles_deg],
                "moment_nm": [float(x) for x in c.moment_nm],
                "peak_nm": c.peak_nm,
                "peak_angle_deg": c.peak_angle_deg,
                "muscles": list(c.muscles),
                "posture_deg": dict(c.posture_deg),
            }
            if mass_kg:
                rec["moment_nm_per_kg"] = [float(x) / mass_kg for x in c.moment_nm]
                rec["peak_nm_per_kg"] = c.peak_nm / mass_kg
            out["actions"].append(rec)
        return out


def _suffix(side: str) -> str:
    s = side.lower().lstrip("_")
    if s in ("r", "right"):
        return "_r"
    if s in ("l", "left"):
        return "_l"
    raise ModelError(f"side must be 'right' or 'left', got {side!r}")


def max_isometric_moment_curves(
    model: Any,
    *,
    side: str,
    joints: Sequence[str] | None = None,
    angles_deg: Mapping[str, ArrayLike] | None = None,
    activation: float = 1.0,
    contributions: bool = True,
    posture_deg: Mapping[str, Mapping[str, float]] | None = None,
) -> JointStrengthCurves:
    """Maximal isometric moment–angle curves of ``model`` (module docstring for the maths).

    ``side``: ``"right"``/``"left"`` (or ``"r"``, ``"_r"``…). ``joints``: action names of
    :data:`ACTIONS` (default all), or joint stems (``"knee"``, ``"ankle"``, ``"hip"``) for all
    their actions. ``angles_deg``: per action, a grid replacing its default (clinical
    convention, deg). ``activation`` in (0, 1]. ``contributions``: keep per-muscle moments.
    ``posture_deg``: per action, the held coordinates (stem → deg, the coordinate's own
    convention) replacing its test posture.
    """
    from msk.muscles.geometry import muscle_geometry, muscle_parameters
    from msk.muscles.hill import rigid_tendon_state

    if not (0.0 < activation <= 1.0):
        raise ModelError(f"activation must be in (0, 1], got {activation}")
    sfx = _suffix(side)
    names: list[str] = []
    for j in joints if joints is not None else ACTIONS:
        hit = [a for a in ACTIONS if a == j or a.split()[0] == j]
        if not hit:
            raise ModelError(f"unknown joint action {j!r}; have {sorted(ACTIONS)}")
        names += [a for a in hit if a not in names]
    grids = dict(angles_deg or {})
    unknown = sorted(set(grids) - set(names))
    if unknown:
        raise ModelError(f"angles_deg for actions not computed: {unknown}")
    params = muscle_parameters(model)
    mnames = params.names
    base = np.asarray(model.default_coordinates(), dtype=float).copy()
    out: dict[str, MomentCurve] = {}
    cache: dict[tuple[Any, ...], tuple[Array, Array]] = {}
    for name in names:
        spec = ACTIONS[name]
        x = np.asarray(grids.get(name, spec.angles_deg), dtype=float).ravel()
        if x.size == 0 or not np.isfinite(x).all():
            raise ModelError(f"{name}: angles_deg must be finite and non-empty")
        coord = spec.coordinate + sfx
        k = model.coordinate_index(coord)
        # neutral posture: every rotational coordinate 0, the root where the model puts it
        theta = base.copy()
        for c in model.coordinates:
            if not c.name.endswith(("_tx", "_ty", "_tz")):
                theta[model.coordinate_index(c.name)] = 0.0
        posture = {}
        held = (posture_deg or {}).get(name, spec.posture_deg)
        for stem, deg in held.items():
            theta[model.coordinate_index(stem + sfx)] = np.deg2rad(deg)
            posture[stem + sfx] = float(deg)
        key = (coord, tuple(x), tuple(theta))
        if key not in cache:
            th = np.tile(theta, (x.size, 1))
            th[:, k] = np.deg2rad(spec.coordinate_sign * x)
            geo = muscle_geometry(model, th)
            cache[key] = (geo.lengths, geo.moment_arms[:, :, k])
        lengths, arms = cache[key]
        state = rigid_tendon_state(params, lengths)
        force = activation * state.max_active_force_along_tendon  # (n, M), f_v(0) = 1
        per = spec.direction * arms * force
        per = np.where(per > 0.0, per, 0.0)  # agonists only
        keep = np.flatnonzero((per > 0.0).any(axis=0))
        out[name] = MomentCurve(
            action=name,
            coordinate=coord,
            angle_label=spec.angle_label,
            angles_deg=x,
            moment_nm=per.sum(axis=1),
            muscles=tuple(mnames[i] for i in keep),
            contributions_nm=per[:, keep] if contributions else None,
            posture_deg=posture,
        )
    return JointStrengthCurves(
        model_name=str(getattr(model, "name", "")),
        side="right" if sfx == "_r" else "left",
        activation=float(activation),
        curves=out,
    )


def action_status(
    curve: MomentCurve,
    muscle_group: Mapping[str, str],
    group_status: Mapping[str, str],
    *,
    share_min: float = STATUS_SHARE_MIN,
) -> tuple[str, dict[str, float]]:
    """Status of the identified curve of an action (:mod:`msk.status` words) and each
    strength group's share of the action's peak moment (``curve`` of the generic model, with
    contributions; muscles outside every group count as ``""``, kept generic).

    ``not determined`` when a group carrying ≥ ``share_min`` of the peak is ``at bound`` or
    ``not determined`` (the identified curve must not be read as the subject's strength);
    else ``identified`` when such a group is identified; else ``prior`` (the curve is the
    generic model's).
    """
    if curve.contributions_nm is None:
        raise ModelError("action_status needs a curve with contributions")
    i = int(np.argmax(curve.moment_nm))
    total = float(curve.moment_nm[i])
    shares: dict[str, float] = {}
    for m, v in zip(curve.muscles, curve.contributions_nm[i]):
        g = muscle_group.get(m, "")
        shares[g] = shares.get(g, 0.0) + (float(v) / total if total > 0 else 0.0)
    big = [g for g, s in shares.items() if g and s >= share_min]
    words = [group_status.get(g, "prior") for g in big]
    if any(w in ("at bound", "not determined") for w in words):
        return "not determined", shares
    if "identified" in words:
        return "identified", shares
    return "prior", shares


def joint_strength_summary(
    model: Any,
    profile: Any,
    *,
    side: str,
    mass_kg: float | None = None,
    joints: Sequence[str] | None = None,
) -> dict[str, Any]:
    """The ``summary.json`` record ``strength.joint_strength``: per action the curves of the
    generic ``model`` and of the identified one (:func:`msk.strength.with_strength` with
    ``profile``, a :class:`msk.strength.StrengthProfile`), in N·m and N·m/kg (``mass_kg``, else
    the model's total mass), the status of the identified curve (:func:`action_status`) and
    each group's share of the peak. JSON-serialisable (lists, floats, strings)."""
    from msk.strength.identification import with_strength

    mass = float(mass_kg) if mass_kg else float(model.total_mass())
    gen = max_isometric_moment_curves(model, side=side, joints=joints)
    ident = max_isometric_moment_curves(with_strength(model, profile), side=side, joints=joints)
    muscle_group = {m: g for m, g in zip(profile.muscle_names, profile.muscle_groups) if g}
    status = dict(zip(profile.group_names, profile.statuses()))
    actions = []
    for a in gen.actions:
        g, i = gen[a], ident[a]
        word, shares = action_status(g, muscle_group, status)
        actions.append(
            {
                "action": a,
                "coordinate": g.coordinate,
                "angle_label": g.angle_label,
                "posture_deg": dict(g.posture_deg),
                "angles_deg": [float(x) for x in g.angles_deg],
                "generic_nm": [float(x) for x in g.moment_nm],
                "identified_nm": [float(x) for x in i.moment_nm],
                "generic_peak_nm": g.peak_nm,
                "generic_peak_angle_deg": g.peak_angle_deg,
                "identified_peak_nm": i.peak_nm,
                "identified_peak_angle_deg": i.peak_angle_deg,
                "status": word,
                "groups": [
                    {"group": k, "share": float(v), "status": status.get(k, "prior")}
                    for k, v in sorted(shares.items(), key=lambda kv: -kv[1])
                    if k
                ],
                "generic_share": float(shares.get("", 0.0)),
            }
        )
    return {
        "side": gen.side,
        "mass_kg": mass,
        "activation": gen.activation,
        "method": "maximal isometric moment: every agonist at full activation, rigid-tendon "
        "Hill state at zero velocity, active fibre force only, antagonists silent",
        "status_share_min": STATUS_SHARE_MIN,
        "norms": None,
        "norms_note": NORMS_NOTE,
        "actions": actions,
    }
