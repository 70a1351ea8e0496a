"""The Grand Challenge (5th) subject PS chain of ``tests/test_validation_gc5.py`` (its module
docstring describes it): scaled gait2392, IK, loads, ID, geometry, static optimisation
variants, knee contact force against the eTibia, shared with the other GC5 real-data tests."""

from __future__ import annotations

import dataclasses
import functools
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from msk.contact.knee import G0, KneeContact, knee_contact_force
from msk.dynamics.inverse import inverse_dynamics
from msk.dynamics.loads import external_loads, plates_from_trial
from msk.io import read_c3d
from msk.io.opensim_files import read_trc
from msk.kinematics.ik import solve_kinematics
from msk.metrics import spearman
from msk.model.files import load_model
from msk.muscles.activation import first_order_activation
from msk.muscles.emg import envelopes_from_trial
from msk.muscles.geometry import muscle_geometry, muscle_parameters
from msk.muscles.hill import Thelen2003Curves, rigid_tendon_state
from msk.optimization import (
    emg_weight_sweep,
    solve_emg_assisted_batch,
    solve_emg_weighted_batch,
    solve_static_optimization_batch,
    solve_tension_batch,
)
from msk.personalise.scaling import DEFAULT_MEASUREMENTS, Measurement, place_markers, scale_model
from msk.pipeline import lab_to_model_rotation
from msk.strength import StrengthIdentifier, fit_emg_gains

ROOT = Path(__file__).resolve().parents[2]
MASS_KG = 75.0
BW = MASS_KG * G0
TRIALS = ("PS_ngait_og_ss1", "PS_ngait_og_ss3", "PS_ngait_og_ss8")

#: gait2392 marker → GC5 PS lab label (anatomical markers only; clusters are placed)
RENAME: dict[str, str] = {
    "Sternum": "Sternum",
    "R.ASIS": "RAsis",
    "L.ASIS": "LAsis",
    "V.Sacral": "Sacral",
    "R.Knee.Lat": "RKneeLateral",
    "R.Knee.Med": "RKneeMedial",
    "L.Knee.Lat": "LKneeLateral",
    "L.Knee.Med": "LKneeMedial",
    "R.Ankle.Lat": "RAnkleLateral",
    "R.Ankle.Med": "RankleMedial",  # sic in the data
    "L.Ankle.Lat": "LAnkleLateral",
    "L.Ankle.Med": "LAnkleMedial",
    "R.Heel": "RHeel",
    "L.Heel": "LHeel",
    "R.Toe.Tip": "RToe",
    "L.Toe.Tip": "LToe",
    "R.Toe.Lat": "RToeLateral",
    "L.Toe.Lat": "LToeLateral",
    "R.Toe.Med": "RToeMedial",
    "L.Toe.Med": "LToeMedial",
    "R.Midfoot.Lat": "RMidfootLateral",
    "L.Midfoot.Lat": "LMidfootLateral",
    "R.Midfoot.Sup": "RMidfootSuperior",
    "L.Midfoot.Sup": "LMidfootSuperior",
}

#: left-leg gait2392 muscle → GC5 EMG channel (gracilis and gmed are flat in these files)
EMG_CHANNELS: dict[str, str] = {
    "grac_l": "gracilis",
    "semimem_l": "semimem",
    "bifemlh_l": "bifeml",
    "vas_med_l": "vasmed",
    "vas_lat_l": "vaslat",
    "rect_fem_l": "rf",
    "med_gas_l": "medgas",
    "lat_gas_l": "latgas",
    "tfl_l": "tfl",
    "tib_ant_l": "tibant",
    "per_long_l": "peronl",
    "soleus_l": "soleus",
    "add_mag1_l": "addmag",
    "glut_max1_l": "gmax",
    "glut_med1_l": "gmed",
    "sar_l": "sartorius",
}
QUADRICEPS = ("vas_med_l", "vas_lat_l", "rect_fem_l")
#: W_emg values of the sweep (m²; seeds/002 Table I used 1 … 0.001 in its own units)
W_EMGS = (1e-1, 1e-2, 1e-3, 1e-4, 1e-5)


@functools.lru_cache(maxsize=1)
def marker_rename() -> dict[str, str]:
    """Model marker → lab label: ``pipelines/gc5_PS.toml`` ``[markers] rename``, else RENAME."""
    path = ROOT / "pipelines" / "gc5_PS.toml"
    if path.is_file():
        with path.open("rb") as fh:
            rename = tomllib.load(fh).get("markers", {}).get("rename")
        if rename:
            return {str(k): str(v) for k, v in rename.items()}
    return dict(RENAME)


def gc5_dir() -> Path:
    from msk.datasets.shared import real_data_dir

    return real_data_dir() / "knee-grand-challenge-gc5"


def plate_mass_kg() -> float:
    """Body mass from the plates: mean vertical GRF over Left Foot Strike → next Left Foot
    Strike (raw plates, which cover the whole cycle in all three trials) / g, averaged over the
    three trials. Independent of the eTibia force (docs/validation.md, mass identification)."""
    return _plate_mass_kg()


@functools.lru_cache(maxsize=1)
def _plate_mass_kg() -> float:
    masses = []
    for name in TRIALS:
        trial = read_c3d(gc5_dir() / f"{name}.c3d")
        up = np.asarray(trial.up, dtype=float)
        t = np.asarray(trial.analog_time, dtype=float)
        fs = [e.time for e in trial.events if e.label == "Foot Strike" and e.context == "Left"]
        sel = (t >= fs[0]) & (t <= fs[1])
        fz = sum(np.asarray(p.force, dtype=float) @ up for p in trial.plates)
        masses.append(float(np.mean(fz[sel])) / G0)
    return float(np.mean(masses))


@dataclasses.dataclass(frozen=True)
class Variant:
    """One configuration of the chain (docs/validation.md, table of variants).

    ``mass``: ``"assumed"`` (75 kg, the source's) or ``"plates"`` (:func:`plate_mass_kg`), used
    to scale the model's segment masses and for the body weight BW. ``move``: model markers
    moved to where the static trial puts them on their body (OpenSim's marker placement)
    instead of gait2392's generic positions. ``objective``: ``"so"`` (OpenSim SO, Σ a²),
    ``"so_volume"`` (Σ V_i a_i², V_i ∝ F_iso,i · l_opt,i), ``"stress"`` (Σ (f_i/F_iso,i)²,
    capacity F_iso f_l f_v), ``"so_cubic"`` (Σ a³), ``"emg_qp"`` (EMG-weighted QP, seeds/002
    Eq. 17, references g ê f_l f_v F_iso) or ``"emg_assisted"`` (EMG-assisted SO, torques
    exact); both EMG criteria take their gains from the two *other* trials
    (leave-one-trial-out, :func:`loto_gains`), never from the eTibia. ``reserves``: reserve
    actuators of optimal force 1 N·m on every actuated coordinate too (not only the pelvis
    residuals), so that frames beyond the generic muscles' strength stay optimal instead of
    taking the bounded least-squares point."""

    mass: str = "assumed"
    move: tuple[str, ...] = ()
    objective: str = "so"
    reserves: bool = False
    #: ``"emg_qp"``: W_emg (m²) of the EMG-weighted QP (seeds/002 Eq. 17) and the reading of
    #: its reference gains (``"groups"``: StrengthIdentifier gains of :data:`GAIN_GROUPS`,
    #: ``"channels"``: one gain per EMG channel)
    w_emg: float = 0.0
    gains: str = "groups"
    #: ``"emg_assisted"``: w of Σ V a² + w Σ_measured (a − g ê)², gains jointly fitted
    w_track: float = 1.0

    @property
    def mass_kg(self) -> float:
        return MASS_KG if self.mass == "assumed" else plate_mass_kg()

    @property
    def bw(self) -> float:
        return self.mass_kg * G0


BASELINE = Variant()
#: gait2392 foot markers mapped to lab foot markers. The lab does not put them where gait2392's
#: generic foot markers sit (midfoot lateral 6 cm, heel 3 cm away: IK RMS 21–22 mm); moved to
#: their static-trial positions on the scaled feet (OpenSim's marker placement), foot neutral
#: (ankle, subtalar, mtp at 0) in the static pose, as OpenSim's scale setups lock them.
FOOT_MARKERS: tuple[str, ...] = tuple(
    f"{side}.{m}"
    for side in "RL"
    for m in ("Heel", "Midfoot.Sup", "Midfoot.Lat", "Toe.Tip", "Toe.Lat", "Toe.Med")
)
#: the body mass of the plates and the lab's foot markers (kinematics fixed), OpenSim SO
MEASURED = Variant(mass="plates", move=FOOT_MARKERS)
#: the recommended variant: MEASURED with the volume-weighted criterion Σ V_i a_i²
RECOMMENDED = Variant(mass="plates", move=FOOT_MARKERS, objective="so_volume")
#: EMG-assisted SO (RECOMMENDED's kinematics and Σ V a², plus w Σ_measured (a − g ê)² with
#: w = 1: a measured muscle's deviation from its EMG costs as much as an average muscle's
#: effort; w chosen before any run), gains fitted on the two other trials' ID torques
EMG_ASSISTED = Variant(mass="plates", move=FOOT_MARKERS, objective="emg_assisted", w_track=1.0)
#: every variant reported in docs/validation.md (in its table's order)
VARIANTS: dict[str, Variant] = {
    "A  baseline: 75 kg, generic foot markers, SO Σa²": BASELINE,
    "B  plate mass": Variant(mass="plates"),
    "C  B + lab foot markers (MEASURED)": MEASURED,
    "D  C + sternum moved": Variant(mass="plates", move=(*FOOT_MARKERS, "Sternum")),
    "E  C + reserves on every coordinate": Variant(mass="plates", move=FOOT_MARKERS, reserves=True),
    "F  A, stress² Σ(f/F_iso)²": Variant(objective="stress"),
    "G  A, volume-weighted Σ V a²": Variant(objective="so_volume"),
    "H  A, Σ a³": Variant(objective="so_cubic"),
    "I  C, stress² Σ(f/F_iso)²": Variant(mass="plates", move=FOOT_MARKERS, objective="stress"),
    "J  C, volume-weighted Σ V a² (RECOMMENDED)": RECOMMENDED,
    "K  C, Σ a³": Variant(mass="plates", move=FOOT_MARKERS, objective="so_cubic"),
    "L  C, EMG-weighted QP, group gains (LOTO), W 1e-4": Variant(
        mass="plates", move=FOOT_MARKERS, objective="emg_qp", w_emg=1e-4, gains="groups"
    ),
    "M  C, EMG-weighted QP, channel gains (LOTO), W 1e-3": Variant(
        mass="plates", move=FOOT_MARKERS, objective="emg_qp", w_emg=1e-3, gains="channels"
    ),
    "N  C, EMG-assisted SO Σ V a² + Σ (a − g ê)², joint gains (LOTO), w 1": EMG_ASSISTED,
    "O  N with w 0.1": dataclasses.replace(EMG_ASSISTED, w_track=0.1),
    "P  N with w 10": dataclasses.replace(EMG_ASSISTED, w_track=10.0),
}


@functools.lru_cache(maxsize=8)
def scaled_model(mass: str = "assumed", move: tuple[str, ...] = ()) -> Any:
    """gait2392 scaled to the PS static trial (``Variant.mass``), with the static's own markers
    placed and the ``move`` markers moved to their static positions."""
    gen = load_model(ROOT / "msk" / "data" / "models" / "gait2392.toml")
    static = read_trc(gc5_dir() / "PS_static_for_scaling.trc")
    inv = {v: k for k, v in marker_rename().items()}
    labels = tuple(inv.get(lab, lab) for lab in static.labels)
    have = set(labels) & set(gen.marker_names)
    meas = [
        Measurement(n, pairs, bodies)
        for n, pairs, bodies in DEFAULT_MEASUREMENTS
        if all(a in have and b in have for a, b in pairs)
    ]
    markers = {lab: static.markers[:, i] for i, lab in enumerate(labels)}
    mass_kg = Variant(mass=mass).mass_kg
    model = scale_model(gen, markers, measurements=meas, body_mass=mass_kg)
    model, _ = place_markers(model, static.markers, labels, static.time, move=move)
    return model


@dataclasses.dataclass(frozen=True)
class Gc5Run:
    """Everything one trial's chain produced (time on axis 0, kinematics time)."""

    name: str
    variant: Variant
    trial: Any
    kin: Any
    loads: Any
    torques: Any
    geometry: Any
    f_active: np.ndarray
    so: Any
    contact: KneeContact
    activation: np.ndarray  # (N, n_muscles) EMG-driven activation, 0 where not measured
    measured: np.ndarray  # (n_muscles,) bool
    envelopes: Any
    foot_strikes: tuple[float, ...]
    foot_off: float
    etibia_total: np.ndarray  # (101,) N

    @property
    def cycle(self) -> tuple[float, float]:
        return self.foot_strikes[0], self.foot_strikes[1]

    def on_cycle(
        self, x: np.ndarray, start: float | None = None, end: float | None = None
    ) -> np.ndarray:
        a, b = self.cycle
        t = np.linspace(a if start is None else start, b if end is None else end, 101)
        return np.interp(t, self.kin.time, x)

    def actuated(self) -> list[int]:
        root = self.torques.root_coordinates
        return [i for i, c in enumerate(self.torques.coordinate_names) if c not in root]


def _tension_optimization(variant: Variant, geom: Any, jt: Any, params: Any, fa: Any, kin: Any):
    """Muscle forces of ``variant.objective`` (pelvis residual actuators of optimal force 1)."""
    root = jt.root_coordinates
    reserve = np.array([1.0 if c in root or variant.reserves else 0.0 for c in jt.coordinate_names])
    common = {
        "reserve_optimal_force": reserve,
        "muscle_names": params.names,
        "coordinate_names": jt.coordinate_names,
        "time": kin.time,
    }
    if variant.objective == "stress":
        return solve_tension_batch(
            geom.jacobian, jt.tau, f_iso=params.max_isometric_force, f_max=fa, **common
        )
    weights = None
    exponent = 2.0
    if variant.objective == "so_volume":
        vol = params.max_isometric_force * params.optimal_fiber_length
        weights = vol / vol.mean()
    elif variant.objective == "so_cubic":
        exponent = 3.0
    elif variant.objective != "so":
        raise ValueError(variant.objective)
    return solve_static_optimization_batch(
        geom.jacobian,
        jt.tau,
        f_active=fa,
        activation_min=0.01,
        activation_max=1.0,
        activation_weights=weights,
        activation_exponent=exponent,
        **common,
    )


@functools.lru_cache(maxsize=8)
def _chain(name: str, mass: str, move: tuple[str, ...]) -> dict[str, Any]:
    """IK → loads → ID → geometry → Hill state of one trial (shared by the criteria)."""
    model = scaled_model(mass, move)
    d = gc5_dir()
    trial = read_c3d(d / f"{name}.c3d")
    rot = lab_to_model_rotation(trial.up, -np.asarray(model.gravity, dtype=float), trial.markers)
    inv = {v: k for k, v in marker_rename().items()}
    labels = tuple(inv.get(lab, lab) for lab in trial.marker_labels)
    kin = solve_kinematics(model, trial.markers @ rot.T, labels, trial.time, cutoff_hz=6.0)
    plates = tuple(
        dataclasses.replace(
            p, force=p.force @ rot.T, cop=p.cop @ rot.T, free_moment=p.free_moment @ rot.T,
            corners=None,
        )
        for p in plates_from_trial(trial)
    )  # fmt: skip
    loads = external_loads(model, kin, plates)
    jt = inverse_dynamics(model, kin, loads)
    geom = muscle_geometry(model, kin.q, kin.v)
    params = muscle_parameters(model)
    state = rigid_tendon_state(
        params, geom.lengths, geom.velocities, curves=Thelen2003Curves.gait2392()
    )
    fs = tuple(e.time for e in trial.events if e.label == "Foot Strike" and e.context == "Left")
    return {
        "model": model, "trial": trial, "kin": kin, "loads": loads, "jt": jt, "geom": geom,
        "params": params, "state": state, "cycle": (fs[0], fs[1]),
    }  # fmt: skip


def emg_config() -> dict[str, Any]:
    with (ROOT / "pipelines" / "gc5_PS.toml").open("rb") as fh:
        return dict(tomllib.load(fh)["emg"])


def emg_options(cfg: dict[str, Any]) -> dict[str, Any]:
    return {
        "highpass_hz": float(cfg["highpass_hz"]),
        "lowpass_hz": float(cfg["lowpass_hz"]),
        "delay_s": float(cfg["electromechanical_delay_s"]),
    }


@functools.lru_cache(maxsize=1)
def session_peaks() -> dict[str, float]:
    """Per EMG channel, the peak envelope over the three trials: the common divisor that stands
    for the missing MVC (so that a gain fitted on two trials means the same on the third)."""
    cfg = emg_config()
    peaks: dict[str, float] = {}
    for name in TRIALS:
        trial = read_c3d(gc5_dir() / f"{name}.c3d")
        env = envelopes_from_trial(trial, muscles=cfg["channels"], **emg_options(cfg))
        for ch, v in zip(env.channel_labels, env.normalisation_value):
            peaks[ch] = max(peaks.get(ch, 0.0), float(v))
    return peaks


@functools.lru_cache(maxsize=8)
def emg_inputs(name: str, mass: str, move: tuple[str, ...]) -> dict[str, Any]:
    """EMG activation ê ``(N, M)`` of every muscle driven by a usable channel of
    ``pipelines/gc5_PS.toml`` ``[emg] channels`` (session-peak normalised, the session's filters
    and delay, first-order activation), the ``measured`` mask, each muscle's ``channel`` and the
    gait-cycle frames ``sel``."""
    c = _chain(name, mass, move)
    cfg = emg_config()
    names = c["params"].names
    env = envelopes_from_trial(
        c["trial"], muscles=cfg["channels"], mvc=session_peaks(), **emg_options(cfg)
    ).resampled(c["kin"].time)
    e = np.clip(np.nan_to_num(env.envelopes), 0.0, 1.0)
    a = first_order_activation(e, rate_hz=c["trial"].point_rate_hz)
    act = np.zeros((c["kin"].n_frames, len(names)))
    channel: list[str | None] = [None] * len(names)
    for k, m in enumerate(names):
        if m in env.muscle_names and env.usable[env.muscle_names.index(m)]:
            act[:, k] = a[:, env.muscle_names.index(m)]
            channel[k] = str(cfg["channels"][m])
    t0, t1 = c["cycle"]
    sel = (c["kin"].time >= t0) & (c["kin"].time <= t1)
    measured = np.array([ch is not None for ch in channel])
    return {"act": act, "measured": measured, "channel": tuple(channel), "sel": sel}


#: synergist groups sharing one gain in the StrengthIdentifier reading and the coordinates of
#: its regression (hip rotation and the foot joints left out: the measured groups explain
#: little of them); tests/strength/test_strength_wemg_realdata.py uses them too
GAIN_GROUPS: dict[str, tuple[str, ...]] = {
    "knee_extensors": ("vas_med_l", "vas_lat_l", "rect_fem_l"),
    "knee_flexors": ("semimem_l", "semiten_l", "bifemlh_l"),
    "plantar_flexors": ("med_gas_l", "lat_gas_l", "soleus_l"),
    "dorsiflexors": ("tib_ant_l",),
    "evertors": ("per_long_l", "per_brev_l"),
    "hip_extensors": ("glut_max1_l", "glut_max2_l", "glut_max3_l"),
    "adductors": ("add_mag1_l", "add_mag2_l", "add_mag3_l"),
    "hip_flexors": ("tfl_l", "sar_l"),
}
GAIN_COORDS = ("hip_flexion_l", "hip_adduction_l", "knee_angle_l", "ankle_angle_l")


def _channel_groups(name: str, variant: Variant) -> dict[str, tuple[str, ...]]:
    ins = emg_inputs(name, variant.mass, variant.move)
    names = _chain(name, variant.mass, variant.move)["params"].names
    chans = sorted({c for c in ins["channel"] if c is not None})
    return {c: tuple(n for n, ch in zip(names, ins["channel"]) if ch == c) for c in chans}


def _volume_weights(params: Any) -> np.ndarray:
    vol = params.max_isometric_force * params.optimal_fiber_length
    return vol / vol.mean()


@functools.lru_cache(maxsize=16)
def loto_gains(held_out: str, variant: Variant) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """EMG gains for ``held_out`` fitted on the gait cycles of the two other trials' ID torques
    (leave-one-trial-out; nothing of the eTibia): group names, group gains, muscle gains."""
    train = tuple(n for n in TRIALS if n != held_out)
    chains = [_chain(n, variant.mass, variant.move) for n in train]
    ins = [emg_inputs(n, variant.mass, variant.move) for n in train]
    params = chains[0]["params"]
    jac = np.concatenate([c["geom"].jacobian[i["sel"]] for c, i in zip(chains, ins)])
    tau = np.concatenate([c["jt"].tau[i["sel"]] for c, i in zip(chains, ins)])
    act = np.concatenate([i["act"][i["sel"]] for i in ins])
    cnames = chains[0]["jt"].coordinate_names
    if variant.objective == "emg_assisted":
        fa = np.concatenate(
            [c["state"].max_active_force_along_tendon[i["sel"]] for c, i in zip(chains, ins)]
        )
        root = chains[0]["jt"].root_coordinates
        fit = fit_emg_gains(
            jac, tau, f_active=fa, emg_activation=act,
            groups=_channel_groups(train[0], variant), muscle_names=params.names,
            w_track=variant.w_track, activation_weights=_volume_weights(params),
            activation_min=0.01, activation_max=1.0,
            reserve_optimal_force=np.array([1.0 if c in root else 0.0 for c in cnames]),
            coordinate_names=cnames, initial_gain=0.3, tol=1e-4,
        )  # fmt: skip
        return fit.group_names, fit.gains, fit.muscle_gains
    groups = GAIN_GROUPS if variant.gains == "groups" else _channel_groups(train[0], variant)
    windows = np.concatenate(
        [k * 5 + np.minimum(np.arange(i["sel"].sum()) * 5 // i["sel"].sum(), 4)
         for k, i in enumerate(ins)]
    )  # fmt: skip
    state = rigid_tendon_state(
        params,
        np.concatenate([c["geom"].lengths[i["sel"]] for c, i in zip(chains, ins)]),
        np.concatenate([c["geom"].velocities[i["sel"]] for c, i in zip(chains, ins)]),
        curves=Thelen2003Curves.gait2392(),
    )
    idf = StrengthIdentifier(
        groups, params, coordinates=GAIN_COORDS, bounds=(0.01, 5.0), n_bootstrap=50
    )
    prof = idf.fit(jac, act, tau, state, windows=windows, coordinate_names=cnames).profile_
    return prof.group_names, prof.factors, prof.muscle_factors


def _emg_optimization(name: str, variant: Variant, c: dict[str, Any]) -> Any:
    """Muscle forces of the EMG-informed criteria (``"emg_qp"``, ``"emg_assisted"``)."""
    jt, geom, params, kin = c["jt"], c["geom"], c["params"], c["kin"]
    fa = c["state"].max_active_force_along_tendon
    ins = emg_inputs(name, variant.mass, variant.move)
    gains = loto_gains(name, variant)[2]
    if variant.objective == "emg_qp":
        act = [i for i, n in enumerate(jt.coordinate_names) if n not in jt.root_coordinates]
        return solve_emg_weighted_batch(
            geom.jacobian[:, :, act], jt.tau[:, act], f_ref=ins["act"] * gains * fa,
            measured=ins["measured"], w_emg=variant.w_emg, f_max=fa, muscle_names=params.names,
            coordinate_names=tuple(jt.coordinate_names[i] for i in act), compute_kkt=False,
        )  # fmt: skip
    root = jt.root_coordinates
    return solve_emg_assisted_batch(
        geom.jacobian, jt.tau, f_active=fa, a_ref=ins["act"] * gains,
        measured=ins["measured"], w_track=variant.w_track,
        activation_weights=_volume_weights(params), activation_min=0.01, activation_max=1.0,
        reserve_optimal_force=np.array([1.0 if n in root else 0.0 for n in jt.coordinate_names]),
        muscle_names=params.names, coordinate_names=jt.coordinate_names, time=kin.time,
        compute_kkt=False,
    )  # fmt: skip


@functools.lru_cache(maxsize=64)
def run_trial(name: str, variant: Variant = BASELINE) -> Gc5Run:
    c = _chain(name, variant.mass, variant.move)
    trial, kin, loads, jt, geom, params = (
        c["trial"], c["kin"], c["loads"], c["jt"], c["geom"], c["params"]
    )  # fmt: skip
    fa = c["state"].max_active_force_along_tendon
    if variant.objective in ("emg_qp", "emg_assisted"):
        so = _emg_optimization(name, variant, c)
    else:
        so = _tension_optimization(variant, geom, jt, params, fa, kin)
    contact = knee_contact_force(
        c["model"], kin, loads, muscle_forces=so, joint="knee_l", body_mass_kg=variant.mass_kg
    )
    env = envelopes_from_trial(trial, muscles=EMG_CHANNELS).resampled(kin.time)
    e = np.clip(np.nan_to_num(env.envelopes), 0.0, 1.0)
    act_emg = first_order_activation(e, rate_hz=trial.point_rate_hz)
    measured = np.array(
        [
            n in env.muscle_names and bool(env.usable[env.muscle_names.index(n)])
            for n in params.names
        ]
    )
    act = np.zeros_like(fa)
    for k, n in enumerate(params.names):
        if measured[k]:
            act[:, k] = act_emg[:, env.muscle_names.index(n)]
    fs = tuple(e.time for e in trial.events if e.label == "Foot Strike" and e.context == "Left")
    fo = next(e.time for e in trial.events if e.label == "Foot Off" and e.context == "Left")
    et = np.loadtxt(gc5_dir() / f"{name}_eTibia.csv", delimiter=",", skiprows=1)
    return Gc5Run(
        name, variant, trial, kin, loads, jt, geom, fa, so, contact, act, measured, env, fs, fo,
        et[:, 3],
    )  # fmt: skip


def contact_metrics(
    run: Gc5Run, *, end: float | None = None, bw: float | None = None
) -> dict[str, float]:
    """Pearson r, RMSE (BW) and peak error (BW) of the predicted total contact force against
    the eTibia total over the 101 samples of [first Left Foot Strike, ``end``]; BW is the
    variant's body weight unless ``bw`` (N) is given."""
    bw = run.variant.bw if bw is None else bw
    pred = run.on_cycle(run.contact.total, end=end) / bw
    meas = run.etibia_total / bw
    return {
        "r": float(np.corrcoef(pred, meas)[0, 1]),
        "rmse_bw": float(np.sqrt(np.mean((pred - meas) ** 2))),
        "peak_error_bw": float(pred.max() - meas.max()),
        "peak_pred_bw": float(pred.max()),
        "peak_meas_bw": float(meas.max()),
        "stance_rmse_bw": float(np.sqrt(np.mean(((pred - meas) ** 2)[:60]))),
    }


def quadriceps_spearman(run: Gc5Run) -> dict[str, float]:
    """Spearman ρ between SO force and EMG envelope of each quadriceps muscle over the cycle."""
    a, b = run.cycle
    sel = (run.kin.time >= a) & (run.kin.time <= b)
    names = run.so.muscle_names
    return {
        m: float(spearman(run.so.forces[sel, names.index(m)], run.envelopes.column(m)[sel]))
        for m in QUADRICEPS
    }


def sweep(run: Gc5Run) -> Any:
    act = run.actuated()
    a, b = run.cycle
    sel = (run.kin.time >= a) & (run.kin.time <= b)
    return emg_weight_sweep(
        run.geometry.jacobian[sel][:, :, act],
        run.torques.tau[sel][:, act],
        f_ref=(run.activation * run.f_active)[sel],
        measured=run.measured,
        w_emgs=W_EMGS,
        f_max=run.f_active[sel],
        muscle_names=run.so.muscle_names,
        coordinate_names=tuple(run.torques.coordinate_names[i] for i in act),
    )


def emg_weighted_contact(run: Gc5Run, w_emg: float) -> dict[str, float]:
    """Knee contact force from the EMG-weighted QP (seeds/002 Eq. 17–18, references
    ``a_EMG · f_active``, ``f ≤ f_active``) on the actuated coordinates, against the eTibia."""
    act = run.actuated()
    sol = solve_emg_weighted_batch(
        run.geometry.jacobian[:, :, act],
        run.torques.tau[:, act],
        f_ref=run.activation * run.f_active,
        measured=run.measured,
        w_emg=w_emg,
        f_max=run.f_active,
        muscle_names=run.so.muscle_names,
        coordinate_names=tuple(run.torques.coordinate_names[i] for i in act),
        compute_kkt=False,
    )
    v = run.variant
    contact = knee_contact_force(
        scaled_model(v.mass, v.move), run.kin, run.loads, muscle_forces=sol, joint="knee_l"
    )
    pred = run.on_cycle(contact.total) / v.bw
    meas = run.etibia_total / v.bw
    return {
        "r": float(np.corrcoef(pred, meas)[0, 1]),
        "rmse_bw": float(np.sqrt(np.mean((pred - meas) ** 2))),
        "peak_error_bw": float(pred.max() - meas.max()),
    }


def need_data(real_dir: Path) -> None:
    if not (real_dir / "knee-grand-challenge-gc5").is_dir():
        pytest.skip("Grand Challenge GC5 data absent")
