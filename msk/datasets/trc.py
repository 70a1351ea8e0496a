"""Synthetic task trials in OpenSim's file formats with a known subject: markers ``.trc``, ground
reactions ``.sto`` and their ExternalLoads ``.xml``, in a lab's own naming.

The Grand Challenge DM sessions are written so (``DM_<task>_new.trc``, ``DM_<task>_grf.sto``,
``DM_<task>_external_loads.xml``) and have no static trial: ``msk run`` scales the model and
places the lab's markers from the motion itself (:mod:`msk.personalise.scaling`,
:mod:`msk.personalise.personalise`). :mod:`msk.datasets.tasks` writes its tasks as C3D files of a
session's *own* placed model, which tests the later stages but not that scaling. Here the
subject is known and differs from what the session's model stage makes of its own walk:

* :func:`subject_model` — a placed model (e.g. the DM session's: gait2392 scaled and DM's markers
  placed from its walk) scaled again by known per-body factors and given a known mass (OpenSim's
  scaling, :func:`msk.personalise.scaling.apply_scale_factors`: joint offsets, centres of mass,
  inertias,
  muscle paths and the markers' offsets on their bodies scale together), so that its segment
  lengths relative to the generic model are the product of both factors (:attr:`TrcTask.
  scale_factors`);
* a motion of that subject — level walking (:func:`walk_motion`: the step-over-step generator of
  :func:`msk.datasets.tasks.stair_motion` on zero risers, its zero-moment-point balance
  included) or a two-leg squat (:func:`msk.datasets.tasks.squat_motion`) — and its ground
  reactions and joint torques (:func:`msk.datasets.tasks.task_reactions`,
  :func:`~msk.datasets.tasks.true_torques`);
* :func:`write_trc_task` — the trial in the format of a template trial: the template ``.trc``'s
  marker labels, rate and units (the subject's markers by forward kinematics + Gaussian noise;
  labels it does not carry written as DM writes a gap, 0 0 0, or — the lab's fixed axis markers
  — at the template's median), the template ``.sto``'s column names and order and its rate, one
  plate per measured foothold (force, centre of pressure and free moment about the vertical;
  exact zeros where unloaded, as DM's files), and the ExternalLoads ``.xml`` applying each plate
  to the foot standing on it (the template's identifiers).

:func:`trc_task` does all of it for a session config and a task kind. What is measured is only
the plates' feet: a walk's first and last footholds (the standing start and end) are on floor
no plate measures, as in DM's overground trials.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from msk.datasets.tasks import (
    FEET,
    FootReactions,
    TaskMotion,
    squat_motion,
    stair_motion,
    task_reactions,
    true_torques,
)
from msk.model.core import Model, marker_positions
from msk.personalise.scaling import apply_scale_factors
from msk.units import Array

__all__ = [
    "SUBJECT_FACTORS",
    "TrcTask",
    "subject_model",
    "trc_task",
    "walk_motion",
    "write_trc_task",
]

#: the synthetic subject's segments relative to the placed model it is made from: a longer
#: femur and shorter tibia than the session's (knee 3–4 cm lower on the thigh's side), a wider
#: pelvis, smaller feet and a shorter trunk — each differing from one whole-leg factor, so a
#: scaling that measured the leg as one segment is seen
SUBJECT_FACTORS: Mapping[str, float] = {
    "pelvis": 1.05,
    "femur_r": 1.07, "femur_l": 1.07,
    "tibia_r": 0.94, "tibia_l": 0.94,
    "talus_r": 0.96, "talus_l": 0.96,
    "calcn_r": 0.96, "calcn_l": 0.96,
    "toes_r": 0.96, "toes_l": 0.96,
    "torso": 0.97,
}  # fmt: skip


def subject_model(
    model: Model, factors: Mapping[str, float] = SUBJECT_FACTORS, *, mass_kg: float | None = None
) -> Model:
    """``model`` scaled by ``factors`` (body → isotropic factor; bodies not named keep theirs)
    with its segment masses scaled to ``mass_kg``
    (:func:`msk.personalise.scaling.apply_scale_factors`):
    markers move with their bodies."""
    return apply_scale_factors(model, {b: float(f) for b, f in factors.items()}, body_mass=mass_kg)


def walk_motion(
    model: Model,
    *,
    steps: int = 5,
    step_m: float = 0.45,
    swing_s: float = 0.4,
    double_s: float = 0.12,
    rate_hz: float = 120.0,
) -> TaskMotion:
    """Level walking from a standing start: :func:`msk.datasets.tasks.stair_motion` on risers
    of zero height (``steps`` steps of ``step_m``, each foot landing 2 × ``step_m`` ahead of
    where it left; ``swing_s`` swing, ``double_s`` double support: with the defaults 0.87 m/s,
    a 1.04 s stride, 62 % stance), its zero-moment-point balance included; the footholds
    ``floor_r``/``floor_l`` (the standing start) and ``step1`` … in order of landing, all on
    the floor. Posture: pelvis 3°, trunk 3° forward, the trailing heel rising 30° before
    lift-off, the pelvis 5 cm below its straight-leg height (or lower where the legs do not
    reach). A smooth synthetic walk, not a recorded gait pattern: no heel-strike transient, the
    stance knee flexed throughout."""
    return stair_motion(
        model, steps=steps, step_height_m=0.0, tread_m=step_m, swing_s=swing_s,
        double_s=double_s, rate_hz=rate_hz, tilt_deg=3.0, lean_deg=3.0, heel_deg=30.0,
        drop_m=0.05,
    )  # fmt: skip


@dataclass(frozen=True)
class TrcTask:
    """A task trial in OpenSim formats with its truth: the files (``trc``, ``grf``,
    ``external_loads`` — ``None`` when not written), the subject (``subject``, its ``mass_kg``,
    ``scale_factors``: body → factor relative to the generic model, the product of the session's
    and :data:`SUBJECT_FACTORS`), the ``motion``, ``reactions`` and true generalised forces
    ``tau`` (N, n) at the marker frames, ``unmeasured`` (N,) frames in which a foot stands on a
    surface no plate measures, the ``measured_surfaces``, the plates' feet (plate name →
    body) and ``time_offset_s`` (the files' time = the motion's + it)."""

    trc: Path
    grf: Path
    external_loads: Path | None
    subject: Model
    mass_kg: float
    scale_factors: Mapping[str, float]
    motion: TaskMotion
    reactions: FootReactions
    tau: Array
    unmeasured: NDArray[np.bool_]
    measured_surfaces: frozenset[str]
    plate_feet: Mapping[str, str]
    time_offset_s: float

    @property
    def path(self) -> Path:
        """The marker file (the trial's ``file``)."""
        return self.trc


def _template_sets(grf: Path) -> tuple[list[str], list[tuple[list[str], list[str], list[str]]]]:
    """The template ``.sto``'s columns and, per plate in file order, its force, point and
    torque column names (a torque component the file lacks: "")."""
    from msk.io import read_sto
    from msk.io.grf import grf_force_sets

    cols = [c for c in read_sto(grf).columns if c.lower() != "time"]
    sets = grf_force_sets(cols, source=str(grf))
    return cols, [(list(s.force), list(s.point), [c or "" for c in s.torque]) for s in sets]


def _template_rate(path: Path) -> float:
    from msk.io import read_sto

    t = np.asarray(read_sto(path).time, dtype=float)
    return float(round((t.size - 1) / (t[-1] - t[0])))


def write_trc_task(
    folder: str | Path,
    stem: str,
    motion: TaskMotion,
    reactions: FootReactions,
    *,
    template_trc: str | Path,
    template_grf: str | Path,
    rename: Mapping[str, str],
    lab_from_model: Array,
    lab_origin_m: Array,
    plates: Sequence[str],
    external_loads: bool = True,
    time_offset_s: float = 0.0,
    noise_m: float = 0.0015,
    force_noise_n: float = 2.0,
    cop_noise_m: float = 0.002,
    torque_noise_nm: float = 0.5,
    seed: int = 0,
) -> tuple[Path, Path, Path | None, dict[str, str]]:
    """Write ``motion`` as ``<stem>_new.trc``, ``<stem>_grf.sto`` and (``external_loads``)
    ``<stem>_external_loads.xml`` in ``folder``, in the format of the template trial (module
    docstring). ``plates``: the surface (foothold name) each of the template's plates measures,
    in its file order ("" for a plate left unloaded). ``rename``: model marker name → the lab's
    label; ``lab = R p + o`` places the model frame in the lab. Noise: markers ``noise_m``
    (each coordinate), and where a plate is loaded its force ``force_noise_n``, centre of
    pressure ``cop_noise_m`` and free moment ``torque_noise_nm``. Returns the three paths and
    the plates' feet (plate name → body; a plate whose foothold belongs to no foot → "")."""
    from msk.io import read_trc, write_sto, write_trc

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    rot = np.asarray(lab_from_model, dtype=float)
    org = np.asarray(lab_origin_m, dtype=float)
    model = motion.model
    # markers
    tmpl = read_trc(template_trc)
    labels = list(tmpl.labels)
    tpts = np.asarray(tmpl.markers, dtype=float)
    tpts[(tpts == 0).all(axis=2)] = np.nan
    n = motion.time.size
    mk = marker_positions(model, motion.q)
    lab_of = {rename.get(m.name, m.name): i for i, m in enumerate(model.markers)}
    out = np.zeros((n, len(labels), 3))
    for j, lab in enumerate(labels):
        if lab in lab_of:
            out[:, j] = mk[:, lab_of[lab]] @ rot.T + org + rng.normal(0.0, noise_m, (n, 3))
            continue
        tp = tpts[:, j]
        good = np.isfinite(tp).all(axis=1)
        # the lab's fixed markers (axes) where the template has them; others a gap (0 0 0)
        if good.any() and np.nanstd(tp[good], axis=0).max() < 0.005:
            out[:, j] = np.median(tp[good], axis=0)
    rate = float(tmpl.rate_hz)
    trc = write_trc(folder / f"{stem}_new.trc", time=motion.time + time_offset_s, markers=out,
                    labels=labels, units=str(tmpl.units_in_file), rate_hz=rate)  # fmt: skip
    # ground reactions
    cols, sets = _template_sets(Path(template_grf))
    g_rate = _template_rate(Path(template_grf))
    rt = reactions.time
    if abs(rt[1] - rt[0] - 1.0 / g_rate) > 1e-9:
        raise ValueError(f"reactions sampled at {1 / (rt[1] - rt[0]):.6g} Hz, the template's "
                         f"plates at {g_rate:.6g} Hz")  # fmt: skip
    data = np.zeros((rt.size, len(cols)))
    pos = {c: i for i, c in enumerate(cols)}
    feet: dict[str, str] = {}
    for k, (fc, pc, tc) in enumerate(sets):
        surf = plates[k] if k < len(plates) else ""
        f_lab = np.zeros((rt.size, 3))
        c_lab = np.zeros((rt.size, 3))
        t_lab = np.zeros((rt.size, 3))
        body = ""
        for j, foot in enumerate(FEET):
            on = (reactions.surface[:, j] == surf) & (surf != "")
            if not on.any():
                continue
            body = foot
            f_lab[on] = reactions.force[on, j] @ rot.T
            c_lab[on] = reactions.cop[on, j] @ rot.T + org
            t_lab[on] = reactions.free_moment[on, j] @ rot.T
        loaded = np.any(f_lab != 0.0, axis=1)
        m = int(loaded.sum())
        f_lab[loaded] += rng.normal(0.0, force_noise_n, (m, 3))
        up = int(np.argmax(np.abs(rot[:, 1])))  # the lab's up axis: the COP stays on the floor
        c_noise = rng.normal(0.0, cop_noise_m, (m, 3))
        c_noise[:, up] = 0.0
        c_lab[loaded] += c_noise
        t_lab[loaded, up] += rng.normal(0.0, torque_noise_nm, m)
        for a in range(3):
            data[:, pos[fc[a]]] = f_lab[:, a]
            data[:, pos[pc[a]]] = c_lab[:, a]
            if tc[a]:
                data[:, pos[tc[a]]] = t_lab[:, a]
        feet[f"plate{k + 1}"] = body
    grf = write_sto(folder / f"{stem}_grf.sto", time=rt + time_offset_s, data=data,
                    columns=cols, name=f"{stem}_grf")  # fmt: skip
    xml = None
    if external_loads:
        xml = _write_external_loads(folder / f"{stem}_external_loads.xml", grf.name, sets, feet)
    return trc, grf, xml, feet


def _write_external_loads(
    path: Path, datafile: str, sets: Sequence[tuple[list[str], list[str], list[str]]],
    feet: Mapping[str, str],
) -> Path:  # fmt: skip
    """An OpenSim ExternalLoads file: one ExternalForce per plate applied to its foot (a plate
    no foot stands on: the right foot's — it carries no load), forces and points in ground."""
    from msk.io.tables import write_text_atomic

    items = []
    for k, (fc, pc, tc) in enumerate(sets):
        body = feet.get(f"plate{k + 1}") or FEET[0]
        torque = next((c for c in tc if c), "")
        items.append(
            f'\t\t\t<ExternalForce name="FP{k + 1}">\n'
            f"\t\t\t\t<applied_to_body>{body}</applied_to_body>\n"
            "\t\t\t\t<force_expressed_in_body>ground</force_expressed_in_body>\n"
            "\t\t\t\t<point_expressed_in_body>ground</point_expressed_in_body>\n"
            f"\t\t\t\t<force_identifier>{fc[0][:-1]}</force_identifier>\n"
            f"\t\t\t\t<point_identifier>{pc[0][:-1]}</point_identifier>\n"
            f"\t\t\t\t<torque_identifier>{torque[:-1]}</torque_identifier>\n"
            "\t\t\t</ExternalForce>\n"
        )
    text = (
        '<?xml version="1.0" encoding="UTF-8" ?>\n<OpenSimDocument Version="40000">\n'
        "\t<ExternalLoads>\n\t\t<objects>\n" + "".join(items) + "\t\t</objects>\n"
        "\t\t<groups />\n" + f"\t\t<datafile>{datafile}</datafile>\n"
        "\t</ExternalLoads>\n</OpenSimDocument>\n"
    )
    return write_text_atomic(path, text)


def _unmeasured(motion: TaskMotion, measured: frozenset[str]) -> NDArray[np.bool_]:
    out = np.zeros(motion.time.size, dtype=bool)
    for fh in motion.footholds:
        if fh.surface not in measured:
            out |= (motion.time >= fh.t_on) & (motion.time <= fh.t_off)
    return out


def trc_task(
    config: str | Path,
    kind: str,
    folder: str | Path,
    *,
    placed: Any,
    factors: Mapping[str, float] = SUBJECT_FACTORS,
    mass_kg: float | None = None,
    seed: int = 0,
    noise_m: float = 0.0015,
    external_loads: bool | None = None,
    stem: str | None = None,
) -> TrcTask:
    """A ``kind`` ("walk" or "squat") trial of a synthetic subject in the OpenSim-format lab of
    the session ``config`` (a ``.trc`` task with a ``grf`` file): the subject is ``placed`` — the
    session's personalised model (:class:`msk.personalise.Personalisation`, what its model stage
    builds from its own task: scaled, the lab's markers placed) — scaled by
    ``factors`` to ``mass_kg`` (default: the config's subject mass); its task files are the
    templates; ``external_loads`` (default: when the session's task has one) writes the
    ExternalLoads file. The lab frame is the session's (its heading), the walk along the model's
    forward axis from the template's first pelvis position.

    Walk (:func:`walk_motion`): the template's plates measure the footholds ``step1``,
    ``step2`` … in order (DM overground: 3 plates, the first three steps after the standing
    start; treadmill files: 2); the standing start and end are unmeasured. Squat: the first
    plate under the right foot, the second under the left, any other unloaded."""
    from msk.config import load_config

    cfg = load_config(config)
    task_cfg = cfg.trials_with_role("task")[0]
    if task_cfg.grf is None or Path(task_cfg.file).suffix.lower() != ".trc":
        raise ValueError(f"{config}: its task is not a .trc with a GRF file")
    built = placed
    mass = float(mass_kg or cfg.subject.mass_kg or built.model.total_mass)
    subject = subject_model(built.model, factors, mass_kg=mass)
    from msk.io import read_trc

    tmpl = read_trc(task_cfg.file)
    rate = float(tmpl.rate_hz)
    if kind == "walk":
        motion = walk_motion(subject, rate_hz=rate)
    elif kind == "squat":
        motion = squat_motion(subject, rate_hz=rate)
    else:
        raise ValueError(f"kind {kind!r}: 'walk' or 'squat'")
    _, sets = _template_sets(Path(task_cfg.grf))
    if kind == "walk":
        plates = [f"step{k + 1}" for k in range(len(sets))]
    else:
        plates = ["plate_r", "plate_l"] + [""] * (len(sets) - 2)
    g_rate = _template_rate(Path(task_cfg.grf))
    reactions = task_reactions(motion, g_rate)
    tau = true_torques(motion, reactions, motion.time)
    rot = np.asarray(built.rotation, dtype=float).T  # lab = rotᵀ-of-(lab → model) · model
    pts = np.asarray(tmpl.markers, dtype=float)[0]
    pts = pts[np.isfinite(pts).all(axis=1) & (pts != 0).any(axis=1)]
    up = np.asarray(built.lab_up, dtype=float)
    org = np.median(pts, axis=0)
    org = org - (org @ up) * up  # on the lab's floor
    with_xml = task_cfg.external_loads is not None if external_loads is None else external_loads
    t0 = float(np.asarray(tmpl.time, dtype=float)[0])
    name = stem or f"synthetic_{kind}"
    trc, grf, xml, feet = write_trc_task(
        folder, name, motion, reactions, template_trc=task_cfg.file, template_grf=task_cfg.grf,
        rename=built.rename, lab_from_model=rot, lab_origin_m=org, plates=plates,
        external_loads=with_xml, time_offset_s=t0, noise_m=noise_m, seed=seed,
    )  # fmt: skip
    base = built.info["scaling"]["bodies"]
    truth = {b: float(base[b]["factors"][0]) * float(factors.get(b, 1.0)) for b in base}
    measured = frozenset(p for p in plates if p)
    return TrcTask(trc, grf, xml, subject, mass, truth, motion, reactions, tau,
                   _unmeasured(motion, measured), measured, feet, t0)  # fmt: skip
