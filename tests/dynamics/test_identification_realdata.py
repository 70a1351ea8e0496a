"""Mass-distribution identification (:class:`msk.dynamics.identification.InertialIdentifier`) on
real
C3D recordings with force plates (GitHub issue 5, "Show — real data").

Grand Challenge (5th) subject PS, three overground gait trials on 3 plates
    gait2392 (shipped as ``gait2392``) scaled to ``PS_static_for_scaling.trc`` at the 75 kg the
    data's source assumes (``tests.support.gc5.scaled_model``, marker names from
    ``pipelines/gc5_PS.toml`` ``[markers] rename`` via ``tests.support.gc5.marker_rename``) →
    msk IK → plate loads → identification model with the upper body (gait2392's torso = HAT)
    and each foot (talus + calcn + toes) lumped, left/right symmetric. Fit on two trials, score
    the pelvis (base-link) residuals on the third, for the three rotations.

    Kinematics and plate wrenches are low-passed at the same 6 Hz (zero-lag Butterworth) so that
    the accelerations and the forces of the base-link equations carry the same bandwidth.

    Frame selection (:func:`select_frames`): a foot is *grounded* at a frame when the slower of
    its heel and toe-tip markers moves at less than :data:`GROUNDED_SPEED_M_S`; a frame is kept
    when every grounded foot carries a plate load (> 20 N) — i.e. no foot stands on the floor
    off the plates. Grounded-but-unloaded runs shorter than :data:`MIN_OFF_PLATE_FRAMES` (the
    few frames around a plate's 20 N threshold at heel strike / toe off) are ignored; real
    off-plate contacts (the heel strike after the last plate) are dilated by
    :data:`GUARD_FRAMES` on each side (the 6 Hz filters smear them), and the first and last
    :data:`EDGE_FRAMES` frames (filter transients of θ̈) are dropped.

    Force-plate weight: mean vertical GRF (raw plate channels, vertical force > 20 N per plate)
    over the gait cycle (first Left Foot Strike → next Left Foot Strike, which the three plates
    cover in all three trials) divided by g.

Standing trials
    ``btkdata/FunctionalStatic.c3d`` (Plug-in Gait; 60 kg, 1.68 m in the file; both feet on
    plates; the file's trunk, arm and medial markers are empty) with the Plug-in Gait →
    gait2392 map ``pipelines/markersets/plug_in_gait_to_gait2392.toml``; gait2392 scaled to the
    trial itself at the file's mass; lumbar coordinates held at neutral (no trunk marker).
    ``knee-grand-challenge-gc4/jw_1legstand1.c3d`` (subject JW, double then single-leg stance,
    no mass in the file): same Grand Challenge labels as PS plus the shoulder markers as
    gait2392's acromia (the trunk orientation needs them); gait2392 at a 75 kg prior. A static
    trial identifies only the total mass and the horizontal position of the centre of mass:
    the test checks that the identifier's flags say so (no segment "well identified"), that the
    posterior std of the total mass and of the horizontal COM is small, that the horizontal COM
    lies over the mean centre of pressure, and that the vertical COM (informed only through the
    small sway accelerations) stays far less certain than the horizontal one.

Run as a script (``python tests/dynamics/test_identification_realdata.py``) to print the figures of
``docs/validation.md``.
"""

from __future__ import annotations

import dataclasses
import functools
import re
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from msk.dynamics.identification import (
    FLAGS,
    IdentificationTrial,
    InertialIdentifier,
    LumpedModel,
    base_residuals,
    lump_subtrees,
)
from msk.dynamics.loads import PlateWrench, external_loads, plates_from_trial
from msk.io import lab_to_model_rotation, read_c3d
from msk.kinematics.ik import solve_kinematics
from msk.model.anthropometry import is_physically_consistent
from msk.model.core import forward_kinematics
from msk.model.files import load_model
from msk.personalise.scaling import DEFAULT_MEASUREMENTS, Measurement, place_markers, scale_model

ROOT = Path(__file__).resolve().parents[2]
G = 9.80665
GC5_TRIALS = ("PS_ngait_og_ss1", "PS_ngait_og_ss3", "PS_ngait_og_ss8")
LUMPS = ("torso", "talus_r", "talus_l")
CUTOFF_HZ = 6.0
THRESHOLD_N = 20.0
EDGE_FRAMES = 6
GROUNDED_SPEED_M_S = 0.5
MIN_OFF_PLATE_FRAMES = 3
GUARD_FRAMES = 5
PIG_MAP = ROOT / "pipelines" / "markersets" / "plug_in_gait_to_gait2392.toml"
#: lab markers never attached to the model (lab axes, arms, head): they move independently
UNATTACHED = re.compile(
    r"global|Elbow|Wrist|Radius|Ulna|ShoulderCenter|^[LR](FIN|WR[AB]|ELB|FRA|UPA|FHD|BHD)$"
)
LUMBAR = ("lumbar_extension", "lumbar_bending", "lumbar_rotation")


# ------------------------------------------------------------------------------------------
# helpers
# ------------------------------------------------------------------------------------------
def _gc5() -> Any:
    from tests.support import gc5  # the PS model and marker mapping (shared, not copied)

    return gc5


def _up(model: Any) -> np.ndarray:
    g = np.asarray(model.gravity, dtype=float)
    return -g / np.linalg.norm(g)


def _rotate(p: PlateWrench, r: np.ndarray) -> PlateWrench:
    return dataclasses.replace(
        p, force=p.force @ r.T, cop=p.cop @ r.T, free_moment=p.free_moment @ r.T, corners=None
    )


def plate_weight_kg(
    plates: tuple[PlateWrench, ...], up: np.ndarray, start: float = -np.inf, end: float = np.inf
) -> float:
    """Mean total vertical GRF over [start, end) / g from the raw plate channels (a plate
    counts where its vertical force exceeds :data:`THRESHOLD_N`, which drops unloaded offsets)."""
    t = plates[0].time
    sel = (t >= start) & (t < end)
    total = np.zeros(int(sel.sum()))
    for p in plates:
        fv = np.nan_to_num(p.force[sel]) @ up
        total += np.where(fv > THRESHOLD_N, fv, 0.0)
    return float(total.mean() / G)


def select_frames(
    time: np.ndarray,
    markers: np.ndarray,
    labels: tuple[str, ...],
    loads: Any,
    feet: dict[str, tuple[str, ...]],
) -> np.ndarray:
    """Frames where every grounded foot stands on a plate (see the module docstring).

    ``feet``: foot body (as in ``loads.bodies``) → the model markers (heel, toe tip) whose
    speed decides whether it is grounded."""
    n = time.size
    dt = float(np.mean(np.diff(time)))
    keep = np.zeros(n, bool)
    keep[EDGE_FRAMES : n - EDGE_FRAMES] = True
    for body, names in feet.items():
        pts = markers[:, [labels.index(m) for m in names]]
        speed = np.linalg.norm(np.gradient(pts, dt, axis=0), axis=2)
        grounded = np.nanmin(np.where(np.isfinite(speed), speed, np.inf), axis=1)
        grounded = grounded < GROUNDED_SPEED_M_S
        fv = (
            loads.force[:, loads.body_index(body)] @ np.array([0.0, 1.0, 0.0])
            if body in loads.bodies
            else np.zeros(n)
        )
        off = grounded & (fv <= THRESHOLD_N)
        d = np.diff(np.concatenate([[0], off.astype(int), [0]]))
        for i0, i1 in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
            if i1 - i0 >= MIN_OFF_PLATE_FRAMES:
                keep[max(i0 - GUARD_FRAMES, 0) : i1 + GUARD_FRAMES] = False
    return keep


def _subset(trial: IdentificationTrial, idx: np.ndarray, name: str) -> IdentificationTrial:
    return IdentificationTrial(
        trial.theta[idx], trial.theta_dot[idx], trial.theta_ddot[idx], trial.tau_ext[idx], name
    )


# ------------------------------------------------------------------------------------------
# Grand Challenge PS gait
# ------------------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class GaitData:
    name: str
    ident: IdentificationTrial  # identification-model coordinates, selected frames
    full: IdentificationTrial  # source-model coordinates, selected frames
    plate_mass_kg: float  # mean vertical GRF over the gait cycle / g
    n_frames: int
    selected: np.ndarray  # (N,) bool
    time: np.ndarray
    marker_rms_m: float


@functools.lru_cache(maxsize=1)
def gc5_lumped() -> LumpedModel:
    return lump_subtrees(_gc5().scaled_model(), LUMPS)


@functools.lru_cache(maxsize=3)
def gc5_trial(name: str) -> GaitData:
    gc5 = _gc5()
    model = gc5.scaled_model()
    trial = read_c3d(gc5.gc5_dir() / f"{name}.c3d")
    up = _up(model)
    rot = lab_to_model_rotation(trial.up, up, trial.markers)
    inv = {v: k for k, v in gc5.marker_rename().items()}
    labels = tuple(inv.get(lab, lab) for lab in trial.marker_labels)
    x = trial.markers @ rot.T
    kin = solve_kinematics(model, x, labels, trial.time, cutoff_hz=CUTOFF_HZ)
    plates = tuple(_rotate(p, rot) for p in plates_from_trial(trial))
    loads = external_loads(model, kin, plates, cutoff_hz=CUTOFF_HZ, threshold_n=THRESHOLD_N)
    feet = {f"calcn_{s.lower()}": (f"{s}.Heel", f"{s}.Toe.Tip") for s in "RL"}
    keep = select_frames(kin.time, x, labels, loads, feet)
    strikes = trial.events_named("Foot Strike", "Left")
    mass = plate_weight_kg(plates, up, strikes[0], strikes[1])
    full = IdentificationTrial.from_loads(model, kin, loads, name=name)
    idx = np.flatnonzero(keep & np.isfinite(full.tau_ext).all(axis=1))
    lm = gc5_lumped()
    return GaitData(
        name,
        _subset(lm.restrict_trial(full), idx, name),
        _subset(full, idx, name),
        mass,
        kin.n_frames,
        keep,
        kin.time,
        float(np.nanmean(kin.marker_rms)),
    )


@dataclasses.dataclass(frozen=True)
class Fold:
    test: str
    ident: InertialIdentifier
    plate_mass_train_kg: float
    plate_mass_test_kg: float
    identified_mass_kg: float
    generic: Any  # BaseResiduals on the held-out trial, scaled gait2392 (75 kg)
    generic_at_plate_mass: Any  # same, all segment parameters × (plate mass / 75 kg)
    identified: Any  # identification model with the identified parameters
    generic_full: Any  # the musculoskeletal model (all coordinates) before/after
    identified_full: Any
    n_train: int
    n_test: int


@functools.lru_cache(maxsize=3)
def gc5_fold(test: str) -> Fold:
    lm = gc5_lumped()
    train = [gc5_trial(n) for n in GC5_TRIALS if n != test]
    held = gc5_trial(test)
    ident = InertialIdentifier(lm.model, symmetric=True).fit([t.ident for t in train])
    w = np.array([t.ident.n_frames for t in train], dtype=float)
    m_train = float(np.average([t.plate_mass_kg for t in train], weights=w))
    generic = {b.name: b.parameters() for b in lm.model.bodies}
    k = m_train / lm.model.total_mass
    identified_full = ident.to_model(lm)
    return Fold(
        test,
        ident,
        m_train,
        held.plate_mass_kg,
        float(sum(p[0] for p in ident.parameters_.values())),
        base_residuals(lm.model, held.ident),
        base_residuals(lm.model, held.ident, {n: k * p for n, p in generic.items()}),
        ident.score(held.ident),
        base_residuals(lm.source, held.full),
        base_residuals(identified_full, held.full),
        sum(t.ident.n_frames for t in train),
        held.ident.n_frames,
    )


# ------------------------------------------------------------------------------------------
# standing trials
# ------------------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class StandingResult:
    name: str
    file_mass_kg: float | None
    prior_mass_kg: float
    plate_mass_kg: float
    ident: InertialIdentifier
    identified_mass_kg: float
    total_mass_std_kg: float
    com_prior: np.ndarray  # (3,) whole-body COM of the generic model at the median pose (m)
    com_identified: np.ndarray
    com_std: np.ndarray  # (3,) posterior std of the identified COM
    com_prior_std: np.ndarray  # (3,) prior std of the COM
    cop: np.ndarray  # (3,) mean centre of pressure of the total GRF (m, on the floor)
    n_frames: int
    marker_rms_m: float


def _facing_x(trial: Any, labels: tuple[str, ...], up: np.ndarray) -> np.ndarray:
    """Lab → model rotation for a standing trial: lab up → model up, then the pelvis' forward
    direction (PSIS/sacrum → ASIS midpoint) → model +x (no walking progression to use)."""
    r0 = lab_to_model_rotation(trial.up, up, None)
    x = trial.markers @ r0.T

    def mean(names: tuple[str, ...]) -> np.ndarray:
        cols = [labels.index(n) for n in names if n in labels]
        cols = [c for c in cols if np.isfinite(x[:, c]).any()]
        return np.nanmean(x[:, cols], axis=(0, 1))

    fwd = mean(("R.ASIS", "L.ASIS")) - mean(("V.Sacral", "RPSI", "LPSI", "RPsis", "LPsis"))
    fwd -= (fwd @ up) * up
    fwd /= np.linalg.norm(fwd)
    ex = np.array([1.0, 0.0, 0.0])
    ez = np.cross(ex, up)
    return (np.outer(ex, fwd) + np.outer(up, up) + np.outer(ez, np.cross(fwd, up))) @ r0


def _com_and_jacobian(
    model: Any, names: list[str], theta: np.ndarray, phi: np.ndarray
) -> tuple[Any, Any]:
    """Whole-body COM c = Σ_b (m_b p_b + R_b h_b) / M at pose θ and ∂c/∂φ (3, 10·B), φ stacked
    per body in the order ``names`` (m, h = m c in the body frame first)."""
    data = model.create_data()
    forward_kinematics(model, data, theta)
    jh = np.zeros((3, 10 * len(names)))
    for b, name in enumerate(names):
        o = data.oMf[model.body_frame[name]]
        jh[:, 10 * b] = o.translation
        jh[:, 10 * b + 1 : 10 * b + 4] = o.rotation
    jm = np.zeros(10 * len(names))
    jm[0::10] = 1.0
    mass = float(jm @ phi)
    com = jh @ phi / mass
    return com, (jh - np.outer(com, jm)) / mass


@functools.lru_cache(maxsize=2)
def standing(which: str) -> StandingResult:
    from msk.datasets.shared import real_data_dir

    gen = load_model(ROOT / "msk" / "data" / "models" / "gait2392.toml")
    up = _up(gen)
    if which == "FunctionalStatic":
        path = real_data_dir() / "btkdata" / "FunctionalStatic.c3d"
        with PIG_MAP.open("rb") as fh:
            rename = dict(tomllib.load(fh)["markers"]["rename"])
        no_torso_scaling = False
    else:
        path = real_data_dir() / "knee-grand-challenge-gc4" / "jw_1legstand1.c3d"
        rename = {**_gc5().marker_rename(), "R.Acromium": "RShoulder", "L.Acromium": "LShoulder"}
        no_torso_scaling = True  # the Grand Challenge "Sternum" is higher than gait2392's
    trial = read_c3d(path)
    inv = {v: k for k, v in rename.items()}
    all_labels = tuple(inv.get(lab, lab) for lab in trial.marker_labels)
    rot = _facing_x(trial, all_labels, up)
    recorded = np.isfinite(trial.markers).all(axis=2).any(axis=0)
    keep = [i for i, lab in enumerate(all_labels) if recorded[i] and not UNATTACHED.search(lab)]
    labels = tuple(all_labels[i] for i in keep)
    frames = np.arange(0, trial.n_frames, 4)  # 30 Hz is plenty for a standing trial
    x = trial.markers[frames][:, keep] @ rot.T
    t = trial.time[frames]
    valid = {lab for i, lab in enumerate(labels) if np.isfinite(x[:, i]).all(axis=1).mean() > 0.5}
    have = valid & set(gen.marker_names)
    meas = [
        Measurement(n, pairs, bodies)
        for n, pairs, bodies in DEFAULT_MEASUREMENTS
        if all(a in have and b in have for a, b in pairs)
        and not (no_torso_scaling and n == "torso")
    ]
    plates = tuple(_rotate(p, rot) for p in plates_from_trial(trial))
    plate_mass = plate_weight_kg(plates, up)
    file_mass = trial.subject.mass_kg
    prior_mass = file_mass if file_mass else 75.0
    model = scale_model(
        gen, {lab: x[:, i] for i, lab in enumerate(labels)}, measurements=meas,
        body_mass=prior_mass,
    )  # fmt: skip
    # markers placed on the segments at the double-stance (first 2 s) pose
    stance = t < t[0] + 2.0
    model, _ = place_markers(model, x[stance], labels, t[stance])
    torso_markers = [m for m in model.markers if m.body == "torso" and m.name in valid]
    tasks = None if len(torso_markers) >= 3 else {c: (0.0, 10.0) for c in LUMBAR}
    kin = solve_kinematics(model, x, labels, t, cutoff_hz=CUTOFF_HZ, coordinate_tasks=tasks)
    loads = external_loads(model, kin, plates, cutoff_hz=CUTOFF_HZ, threshold_n=THRESHOLD_N)
    lm = lump_subtrees(model, LUMPS)
    full = IdentificationTrial.from_loads(model, kin, loads, name=path.stem)
    idx = np.arange(EDGE_FRAMES, kin.n_frames - EDGE_FRAMES)
    idx = idx[np.isfinite(full.tau_ext[idx]).all(axis=1)]
    # frames whose plate contact could not be given to one foot (msk.dynamics.loads flags them)
    # carry
    # no ground reaction: not equations of the base link
    idx = idx[~loads.flagged()[idx]]
    trial_id = _subset(lm.restrict_trial(full), idx, path.stem)
    ident = InertialIdentifier(lm.model, symmetric=True).fit(trial_id)
    # total mass and whole-body COM (posterior std by the delta method) at the median pose
    names = [p.removesuffix(".m") for p in ident.parameter_names_[::10]]
    prior = ident.prior_
    poses = trial_id.theta  # mean COM over the frames of the mean COP below
    com0 = np.mean([_com_and_jacobian(lm.model, names, th, prior)[0] for th in poses], axis=0)
    com1 = np.mean([_com_and_jacobian(lm.model, names, th, ident.phi_)[0] for th in poses], 0)
    _, jac = _com_and_jacobian(lm.model, names, np.median(poses, axis=0), ident.phi_)
    jm = np.zeros(prior.size)
    jm[0::10] = 1.0
    prior_cov = np.diag(ident.prior_std_**2)
    # centre of pressure of the total GRF: the feet's COPs weighted by their vertical forces
    fv = loads.force[idx, :, 1]
    cop = np.nansum(loads.point[idx] * fv[..., None], axis=1) / fv.sum(axis=1)[:, None]
    cop = cop.mean(axis=0)
    return StandingResult(
        path.stem,
        file_mass,
        prior_mass,
        plate_mass,
        ident,
        float(ident.phi_[0::10].sum()),
        float(np.sqrt(jm @ ident.covariance_ @ jm)),
        com0,
        com1,
        np.sqrt(np.diag(jac @ ident.covariance_ @ jac.T)),
        np.sqrt(np.diag(jac @ prior_cov @ jac.T)),
        cop,
        int(idx.size),
        float(np.nanmean(kin.marker_rms)),
    )


# ------------------------------------------------------------------------------------------
# tests
# ------------------------------------------------------------------------------------------
def _need(real_dir: Path, *files: str) -> None:
    for f in files:
        if not (real_dir / f).is_file():
            pytest.skip(f"{f} absent")


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.parametrize("test", GC5_TRIALS)
def test_gc5_two_trials_identify_the_plate_mass_and_lower_held_out_residuals(
    real_dir: Path, test: str
) -> None:
    _need(real_dir, *(f"knee-grand-challenge-gc5/{n}.c3d" for n in GC5_TRIALS))
    fold = gc5_fold(test)
    held = gc5_trial(test)
    ident = fold.ident
    print(
        f"\n{test} held out: train {fold.n_train} / test {fold.n_test} frames; plates "
        f"{fold.plate_mass_train_kg:.2f} kg (train) {fold.plate_mass_test_kg:.2f} kg (test), "
        f"identified {fold.identified_mass_kg:.2f} kg; pelvis residual force RMS "
        f"{fold.generic.force_rms_n:.1f} (75 kg) / {fold.generic_at_plate_mass.force_rms_n:.1f} "
        f"(× plate mass) → {fold.identified.force_rms_n:.1f} N, moment "
        f"{fold.generic.moment_rms_nm:.2f} / {fold.generic_at_plate_mass.moment_rms_nm:.2f} → "
        f"{fold.identified.moment_rms_nm:.2f} N·m; full model {fold.generic_full.force_rms_n:.1f}"
        f" → {fold.identified_full.force_rms_n:.1f} N\n{ident.summary()}"
    )
    # the selection keeps most of each trial
    assert held.selected.mean() > 0.8
    for name, phi in ident.parameters_.items():
        assert is_physically_consistent(phi), name
    assert set(ident.flags_.values()) <= set(FLAGS)
    assert np.isfinite(ident.condition_number_)
    # total mass: the plates say ≈ 83 kg, not the 75 kg the source assumes
    # (docs/validation.md: within 0.5 % of the training plates, 0.9 % of the held-out trial's)
    assert fold.identified_mass_kg == pytest.approx(fold.plate_mass_train_kg, rel=0.005)
    assert fold.identified_mass_kg == pytest.approx(fold.plate_mass_test_kg, rel=0.009)
    assert fold.plate_mass_test_kg > 1.05 * 75.0
    # held-out pelvis residuals, each against its baseline (docs/validation.md, figures reached
    # with a margin of ~1 point): the generic model at the 75 kg the source assumes (force
    # −61 … −67 %, moment −45 … −54 %), the generic model at the plate mass (force −10 … −29 %,
    # moment −52 … −60 %; that baseline's moment residual is larger than the 75 kg one's), and
    # the redistributed musculoskeletal model against the generic one at 75 kg
    assert fold.identified.force_rms_n < 0.40 * fold.generic.force_rms_n
    assert fold.identified.moment_rms_nm < 0.56 * fold.generic.moment_rms_nm
    assert fold.identified.force_rms_n < 0.91 * fold.generic_at_plate_mass.force_rms_n
    assert fold.identified.moment_rms_nm < 0.50 * fold.generic_at_plate_mass.moment_rms_nm
    assert fold.generic_at_plate_mass.moment_rms_nm > fold.generic.moment_rms_nm
    assert fold.identified_full.force_rms_n < 0.40 * fold.generic_full.force_rms_n
    assert fold.identified_full.moment_rms_nm < 0.57 * fold.generic_full.moment_rms_nm


def _check_standing(res: StandingResult) -> None:
    ident = res.ident
    print(
        f"\n{res.name}: file mass {res.file_mass_kg} kg, prior {res.prior_mass_kg:.1f} kg, "
        f"plates {res.plate_mass_kg:.2f} kg, identified {res.identified_mass_kg:.2f} ± "
        f"{res.total_mass_std_kg:.3f} kg ({res.n_frames} frames, IK marker RMS "
        f"{1000 * res.marker_rms_m:.1f} mm); COM generic {np.round(res.com_prior, 3)} → "
        f"identified {np.round(res.com_identified, 3)} ± {np.round(res.com_std, 4)} (prior ± "
        f"{np.round(res.com_prior_std, 4)}); mean COP {np.round(res.cop, 3)}\n{ident.summary()}"
    )
    for name, phi in ident.parameters_.items():
        assert is_physically_consistent(phi), name
    # what a static trial identifies: the total mass and the horizontal COM ...
    assert res.identified_mass_kg == pytest.approx(res.plate_mass_kg, rel=0.01)
    assert res.total_mass_std_kg < 0.005 * res.plate_mass_kg
    horizontal = [0, 2]  # x forward, z right (y up)
    assert np.all(res.com_std[horizontal] < 0.1 * res.com_prior_std[horizontal])
    np.testing.assert_allclose(res.com_identified[horizontal], res.cop[horizontal], atol=0.015)
    # ... and little else: the vertical COM (informed only through the small sway
    # accelerations) stays far less certain than the horizontal one, and no segment is
    # "well identified"
    assert res.com_std[1] > 5.0 * res.com_std[horizontal].max()
    assert "well identified" not in ident.flags_.values()
    assert ident.weak_directions_


@pytest.mark.slow
@pytest.mark.realdata
def test_functional_static_gives_body_weight_and_horizontal_com_only(real_dir: Path) -> None:
    _need(real_dir, "btkdata/FunctionalStatic.c3d")
    res = standing("FunctionalStatic")
    assert res.file_mass_kg == 60.0
    assert res.plate_mass_kg == pytest.approx(res.file_mass_kg, rel=0.03)
    _check_standing(res)
    # both feet stand still: the light distal segments are not informed at all
    assert all(res.ident.flags_[b] == "prior" for b in ("tibia_r", "talus_r", "tibia_l"))


@pytest.mark.slow
@pytest.mark.realdata
def test_single_leg_stance_gives_body_weight_and_horizontal_com_only(real_dir: Path) -> None:
    _need(real_dir, "knee-grand-challenge-gc4/jw_1legstand1.c3d")
    res = standing("jw_1legstand1")
    assert res.file_mass_kg is None  # the file states no mass: the prior is 75 kg
    assert abs(res.plate_mass_kg - res.prior_mass_kg) > 5.0  # a prior well off the truth
    _check_standing(res)


def main() -> None:  # pragma: no cover - a report, not a test
    for name in GC5_TRIALS:
        d = gc5_trial(name)
        drop = d.time[~d.selected]
        print(
            f"{name}: {d.selected.sum()}/{d.n_frames} frames kept, plates "
            f"{d.plate_mass_kg:.2f} kg, IK RMS {1000 * d.marker_rms_m:.1f} mm, dropped "
            f"{np.round(drop, 3)}"
        )
    for name in GC5_TRIALS:
        f = gc5_fold(name)
        print(
            f"held out {name}: identified {f.identified_mass_kg:.2f} kg (train plates "
            f"{f.plate_mass_train_kg:.2f}, test {f.plate_mass_test_kg:.2f}); force RMS "
            f"{f.generic.force_rms_n:.1f} / {f.generic_at_plate_mass.force_rms_n:.1f} → "
            f"{f.identified.force_rms_n:.1f} N; moment {f.generic.moment_rms_nm:.2f} / "
            f"{f.generic_at_plate_mass.moment_rms_nm:.2f} → {f.identified.moment_rms_nm:.2f} N·m;"
            f" full model {f.generic_full.force_rms_n:.1f} → {f.identified_full.force_rms_n:.1f}"
            f" N, {f.generic_full.moment_rms_nm:.2f} → {f.identified_full.moment_rms_nm:.2f} N·m;"
            f" per coordinate {dict(zip(f.generic.names, np.round(f.generic.rms, 1)))} → "
            f"{np.round(f.identified.rms, 1)}; cond {f.ident.condition_number_:.3g}"
        )
        print(f.ident.summary())
    for which in ("FunctionalStatic", "jw_1legstand1"):
        _check_standing(standing(which))


if __name__ == "__main__":  # pragma: no cover
    main()


# ------------------------------------------------------------------------------------------
# prior weight by cross-validation (issue 19)
# ------------------------------------------------------------------------------------------
@functools.lru_cache(maxsize=3)
def gc5_cv_fold(test: str) -> tuple[InertialIdentifier, Any, Any, float]:
    """Fit on the two other trials at their plate mass with ``prior_weight="cv"`` (leave one
    training trial out inside); held-out residuals of the fit and of the generic model at the
    plate mass (every segment × plate mass / model mass: the CV's "prior only")."""
    lm = gc5_lumped()
    train = [gc5_trial(n) for n in GC5_TRIALS if n != test]
    held = gc5_trial(test)
    w = np.array([t.ident.n_frames for t in train], dtype=float)
    mass = float(np.average([t.plate_mass_kg for t in train], weights=w))
    ident = InertialIdentifier(lm.model, total_mass=mass, symmetric=True, prior_weight="cv").fit(
        [t.ident for t in train]
    )
    k = mass / lm.model.total_mass
    generic = base_residuals(lm.model, held.ident, {b.name: k * b.parameters()
                                                   for b in lm.model.bodies})  # fmt: skip
    return ident, ident.score(held.ident), generic, mass


#: held-out trial → largest (force, moment) RMS ratio to the generic model at the plate mass:
#: the measured −9/−27/−27 % and −52/−59/−59 % plus 2 points
CV_REACHED = {
    "PS_ngait_og_ss1": (0.93, 0.50),
    "PS_ngait_og_ss3": (0.75, 0.43),
    "PS_ngait_og_ss8": (0.75, 0.43),
}


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.parametrize("test", GC5_TRIALS)
def test_gc5_cv_prior_weight_never_worse_than_generic_at_plate_mass(
    real_dir: Path, test: str
) -> None:
    _need(real_dir, *(f"knee-grand-challenge-gc5/{n}.c3d" for n in GC5_TRIALS))
    ident, got, generic, mass = gc5_cv_fold(test)
    cv = ident.cv_scores_
    assert cv is not None
    print(f"\n{test} held out, plates {mass:.2f} kg, λ = {ident.prior_weight_:g}: force "
          f"{generic.force_rms_n:.2f} → {got.force_rms_n:.2f} N, moment "
          f"{generic.moment_rms_nm:.2f} → {got.moment_rms_nm:.2f} N·m\n"
          + "\n".join(cv.table()) + f"\n{ident.excitation()}")  # fmt: skip
    assert len(cv.folds) == 2  # leave one training trial out
    assert sum(p[0] for p in ident.parameters_.values()) == pytest.approx(mass, rel=1e-6)
    # the issue-19 criterion: never worse than the generic model at the plate mass — here the
    # figures reached (README, docs/validation.md: force −9/−27/−27 %, moment −52/−59/−59 %)
    # with a margin of 2 points
    force_max, moment_max = CV_REACHED[test]
    assert got.force_rms_n <= force_max * generic.force_rms_n
    assert got.moment_rms_nm <= moment_max * generic.moment_rms_nm
    for phi in ident.parameters_.values():
        assert is_physically_consistent(phi)
