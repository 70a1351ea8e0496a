"""Inverse dynamics against Vicon Plug-in Gait's joint moments (GitHub issue 4, "Show").

Two BTKData walking trials carry Plug-in Gait (PiG) kinetic outputs as C3D points
(``LHipMoment``, ``RKneeMoment``, ``LAnkleMoment``…, ``POINT:MOMENT_UNITS = Nmm``, normalised by
body mass: N·mm/kg, read by :func:`msk.io.read_c3d` as N·m/kg). msk's chain on the same markers
and plates is compared with them, sagittal hip, knee and ankle, over every stance phase
(events of the file: Foot Strike → next Foot Off of that side) whose foot stands on a plate.

Chain (both files): gait2392 (``msk/data/models/gait2392.toml``) →
:func:`msk.personalise.scaling.scale_model`
(:data:`msk.personalise.scaling.DEFAULT_MEASUREMENTS` where both markers exist; the feet, which
have no
usable pair — PiG's toe marker is not gait2392's toe tip — take the mean tibia factor) →
:func:`msk.personalise.scaling.place_markers` (THI/TIB wands, PSIS, toe, C7…) → lab → model frame
(:func:`msk.io.lab_to_model_rotation`: lab up → model up, walking along +x) →
:func:`msk.kinematics.ik.solve_kinematics` → :func:`msk.dynamics.loads.plates_from_trial` /
:func:`msk.dynamics.loads.external_loads` → :func:`msk.dynamics.inverse.inverse_dynamics`, moments ÷
body mass.
Marker names: the Plug-in Gait → gait2392 map ``pipelines/markersets/plug_in_gait_to_gait2392
.toml`` (read, not copied). PiG's own virtual segment points (``PELO``, ``LFEO``…, ``*1``…)
are model outputs of the reference, not measurements: they are not used.

``PiG_Motion3_FF.c3d``: static ``PiG_Calibration3_FF.c3d`` for scaling and marker placement,
74 kg (file). ``PlugInC3D.c3d``: no static trial and no mass in the file. Scale factors are the
median over the walking frames of the per-frame measured factors (one
:func:`msk.personalise.scaling.measure_scale_factors` call per frame: a walking trial's *mean*
marker
positions mean nothing); the non-model markers are placed from one frame (right mid-stance);
the mass is the one PiG normalised by: median over stance frames of |plate force| /
|PiG ``GroundReactionForce``| (N / (N/kg)) — the same ratio gives 74.0 kg on PiG_Motion3_FF,
the mass in that file.

Convention mapping (determined from the data: ``PigResult.raw_r``, the pooled Pearson r of
msk against PiG's unsigned X component): X is the sagittal component, and
``PiG X = −τ_hip_flexion, +τ_knee_angle, −τ_ankle_angle`` (per kg), τ being gait2392's
generalised forces (internal: hip_flexion + flexion, knee_angle − in flexion so +τ extends,
ankle_angle + dorsiflexion). So PiG's X is the **external** moment in the sense of PiG's own
angles (hip flexion, knee flexion, ankle dorsiflexion positive) — the same numbers as the
internal moment with extensor / extensor / plantarflexor positive (a sign alone cannot tell
these readings apart). Vicon documents the first: "an external moment and force
description", components in the axes of the distal segment (Nexus 2.10 "Plug-in Gait lower
body forces and moments"). The frame changes the sagittal component only through the
out-of-plane angles.

Run as a script (``python tests/test_validation_plugin_gait.py``) to print the figures of
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

from msk.dynamics.inverse import inverse_dynamics
from msk.dynamics.loads import external_loads, plates_from_trial
from msk.io import lab_to_model_rotation, read_c3d
from msk.kinematics.ik import solve_kinematics
from msk.metrics import pearson_r
from msk.model.core import forward_kinematics
from msk.model.files import load_model
from msk.personalise.scaling import (
    DEFAULT_MEASUREMENTS,
    Measurement,
    measure_scale_factors,
    place_markers,
    scale_model,
)
from msk.signal import filtfilt_butter

ROOT = Path(__file__).resolve().parents[1]
PIG_MAP = ROOT / "pipelines" / "markersets" / "plug_in_gait_to_gait2392.toml"
FILES = ("PiG_Motion3_FF", "PlugInC3D")
STATIC = {"PiG_Motion3_FF": "PiG_Calibration3_FF", "PlugInC3D": None}
CUTOFF_HZ = 6.0
THRESHOLD_N = 20.0
JOINTS = ("hip", "knee", "ankle")
COORD = {"hip": "hip_flexion", "knee": "knee_angle", "ankle": "ankle_angle"}
PIG_LABEL = {"hip": "HipMoment", "knee": "KneeMoment", "ankle": "AnkleMoment"}
#: PiG X (external; flexion / flexion / dorsiflexion +) → sign of gait2392's generalised force
EXPECTED_SIGN = {"hip": -1.0, "knee": 1.0, "ankle": -1.0}
#: floors on Pearson r against PiG low-passed like msk (sagittal, each stance); lowest
#: reached on the two files: hip 0.96, knee 0.84, ankle 0.99
R_FLOOR = {"hip": 0.90, "knee": 0.75, "ankle": 0.95}
#: ceilings on the RMS difference (N·m/kg) against PiG low-passed like msk (each stance);
#: highest reached: hip 0.19, knee 0.27, ankle 0.20
RMS_CEILING = {"hip": 0.25, "knee": 0.35, "ankle": 0.25}
#: floor on Pearson r against PiG as in the file, on PiG_Motion3_FF (100 Hz, smooth outputs;
#: PlugInC3D's 60 Hz left-side outputs carry PiG's unfiltered noise): lowest reached 0.86
R_FLOOR_RAW_MOTION3 = 0.80
#: Plug-in Gait virtual segment points (origin / anterior / lateral / proximal of each
#: segment) and unlabelled points: outputs of the reference model, not measurements
PIG_VIRTUAL = re.compile(r"^(PEL|[LR](FE|TI|FO|TO|HU|RA|HN))[OALP]$|^\*\d+$")
LUMBAR = ("lumbar_extension", "lumbar_bending", "lumbar_rotation")


@dataclasses.dataclass(frozen=True)
class JointComparison:
    """One joint, one stance: msk vs PiG sagittal moment (N·m/kg), PiG sign applied."""

    file: str
    side: str  # "R" | "L"
    joint: str
    stance: tuple[float, float]  # s
    time: np.ndarray
    msk: np.ndarray  # gait2392 generalised force / mass
    pig: np.ndarray  # PiG X component × EXPECTED_SIGN, as in the file
    pig_lp: np.ndarray  # the same, low-passed like msk's (CUTOFF_HZ, zero lag)
    rms: float  # N·m/kg, against ``pig``
    r: float
    rms_lp: float  # against ``pig_lp``
    r_lp: float
    bias_lp: float  # mean(msk − pig_lp), N·m/kg
    pig_peak: float  # max |pig_lp| over the stance, N·m/kg

    @property
    def rms_pct_peak(self) -> float:
        return 100.0 * self.rms / self.pig_peak

    @property
    def rms_lp_pct_peak(self) -> float:
        return 100.0 * self.rms_lp / self.pig_peak


@dataclasses.dataclass(frozen=True)
class PigResult:
    name: str
    mass_kg: float
    mass_source: str
    scale_ratios: dict[str, float]
    marker_rms_m: float
    comparisons: tuple[JointComparison, ...]
    raw_r: dict[str, float]  # joint → pooled r of msk vs the UNSIGNED PiG X component
    plates: tuple[tuple[str, str, float, float], ...]  # plate, body, start, end
    model: Any = dataclasses.field(repr=False, default=None)  # scaled, markers placed
    kinematics: Any = dataclasses.field(repr=False, default=None)
    trial: Any = dataclasses.field(repr=False, default=None)  # in the model frame


def _rename() -> dict[str, str]:
    with PIG_MAP.open("rb") as fh:
        return dict(tomllib.load(fh)["markers"]["rename"])


def _btk(name: str) -> Path:
    from msk.datasets.shared import real_data_dir

    return real_data_dir() / "btkdata" / f"{name}.c3d"


def _physical(trial: Any) -> tuple[np.ndarray, tuple[str, ...]]:
    """Markers (N, M, 3) and labels (model names where the PiG map has one) without PiG's
    virtual points."""
    inv = {v: k for k, v in _rename().items()}
    keep = [i for i, lab in enumerate(trial.marker_labels) if not PIG_VIRTUAL.search(lab)]
    labels = tuple(inv.get(trial.marker_labels[i], trial.marker_labels[i]) for i in keep)
    return trial.markers[:, keep], labels


def _measurements(labels: set[str], model: Any) -> list[Measurement]:
    have = labels & set(model.marker_names)
    return [
        Measurement(n, pairs, bodies)
        for n, pairs, bodies in DEFAULT_MEASUREMENTS
        if all(a in have and b in have for a, b in pairs)
    ]


def _with_feet(factors: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Feet (no usable marker pair) scaled by the mean tibia factor."""
    tib = [factors[b] for b in ("tibia_r", "tibia_l") if b in factors]
    out = dict(factors)
    if tib:
        f = np.mean(tib, axis=0)
        for s in "rl":
            for b in (f"talus_{s}", f"calcn_{s}", f"toes_{s}"):
                out.setdefault(b, f)
    return out


def lowpass_finite(x: np.ndarray, rate_hz: float) -> np.ndarray:
    """Zero-lag low-pass (:data:`CUTOFF_HZ`, :func:`msk.signal.filtfilt_butter`) of each
    contiguous finite run of ``x`` (N,) longer than 12 samples; NaN elsewhere."""
    out = np.full_like(x, np.nan)
    ok = np.isfinite(x)
    d = np.diff(np.concatenate([[0], ok.astype(int), [0]]))
    for i0, i1 in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
        if i1 - i0 > 12:
            out[i0:i1] = filtfilt_butter(x[i0:i1], rate_hz=rate_hz, cutoff_hz=CUTOFF_HZ)
    return out


def plate_mass_kg(trial: Any, side_of_plate: dict[str, str]) -> float:
    """Mass Plug-in Gait normalised by: median over loaded frames of |plate force| / |PiG
    GroundReactionForce| of the side standing on the plate (N / (N/kg))."""
    ratios = []
    for p in plates_from_trial(trial):
        side = side_of_plate.get(p.name)
        if side is None:
            continue
        f = np.linalg.norm(trial.to_point_rate(np.nan_to_num(p.force)), axis=1)
        g = np.linalg.norm(trial.model_outputs.get(f"{side}GroundReactionForce"), axis=1)
        ok = np.isfinite(g) & (g > 3.0) & (f > 200.0)
        ratios.append(f[ok] / g[ok])
    return float(np.median(np.concatenate(ratios)))


def side_of_plate_from_events(trial: Any) -> dict[str, str]:
    """Plate name → side ("R"/"L") whose Foot Strike event is nearest the plate's first
    loaded sample (PiG's events, independent of msk's own assignment)."""
    strikes = [(e.time, e.context[0]) for e in trial.events if e.label == "Foot Strike"]
    out = {}
    for p in plates_from_trial(trial):
        on = np.flatnonzero(np.abs(np.nan_to_num(p.force) @ trial.up) > THRESHOLD_N)
        if on.size:
            t0 = p.time[on[0]]
            out[p.name] = min(strikes, key=lambda s, t0=t0: abs(s[0] - t0))[1]
    return out


def _stances(trial: Any, side: str) -> list[tuple[float, float]]:
    ctx = {"R": "Right", "L": "Left"}[side]
    strikes = sorted(trial.events_named("Foot Strike", ctx))
    offs = sorted(trial.events_named("Foot Off", ctx))
    out = []
    for s in strikes:
        after = [o for o in offs if o > s]
        if after:
            out.append((s, after[0]))
    return out


@functools.lru_cache(maxsize=2)
def pig_comparison(name: str) -> PigResult:
    gen = load_model(ROOT / "msk" / "data" / "models" / "gait2392.toml")
    g = np.asarray(gen.gravity, dtype=float)
    up = -g / np.linalg.norm(g)
    trial = read_c3d(_btk(name))
    # frames with no marker at all are left out: msk.io.lab_to_model_rotation warns ("Mean of
    # empty slice") on them, an error under pytest; the rotation is the same without them
    seen = np.isfinite(trial.markers).all(axis=2).any(axis=1)
    rot = lab_to_model_rotation(trial.up, up, trial.markers[seen])
    mtrial = trial.rotated(rot)
    x, labels = _physical(mtrial)

    if STATIC[name] is not None:
        static = read_c3d(_btk(STATIC[name]))
        # standing still: lab up → model up, then the motion trial's heading (same lab)
        sx, slabels = _physical(static.rotated(rot))
        meas = _measurements(set(slabels), gen)
        factors, ratios = measure_scale_factors(
            gen, {lab: sx[:, i] for i, lab in enumerate(slabels)}, meas
        )
        place_x, place_t, place_labels = sx, static.time, slabels
    else:
        # walking only: per-frame factors, median over the frames where all pairs are seen
        meas = _measurements(set(labels), gen)
        per: dict[str, list[np.ndarray]] = {}
        per_ratio: dict[str, list[float]] = {}
        for i in range(0, trial.n_frames, 2):
            frame = {lab: x[i, k] for k, lab in enumerate(labels) if np.isfinite(x[i, k]).all()}
            if not all(a in frame and b in frame for m in meas for a, b in m.marker_pairs):
                continue
            f_i, r_i = measure_scale_factors(gen, frame, meas)
            for k, v in f_i.items():
                per.setdefault(k, []).append(v)
            for k, v in r_i.items():
                per_ratio.setdefault(k, []).append(v)
        factors = {k: np.median(v, axis=0) for k, v in per.items()}
        ratios = {k: float(np.median(v)) for k, v in per_ratio.items()}
        # one frame, right mid-stance, with every marker seen
        rs = _stances(trial, "R")[0]
        complete = np.isfinite(x).all(axis=2).all(axis=1)
        cand = np.flatnonzero(complete & (trial.time > rs[0]) & (trial.time < rs[1]))
        mid = cand[np.argmin(np.abs(trial.time[cand] - 0.5 * (rs[0] + rs[1])))]
        place_x, place_t, place_labels = x[[mid]], trial.time[[mid]], labels

    if trial.subject.mass_kg:
        mass, source = float(trial.subject.mass_kg), "file (PROCESSING:Bodymass)"
    else:
        mass = plate_mass_kg(trial, side_of_plate_from_events(trial))
        source = "plate force / PiG GRF per kg"
    model = scale_model(gen, scale_factors=_with_feet(factors), body_mass=mass)
    model, _ = place_markers(model, place_x, place_labels, place_t)
    torso = [m for m in model.markers if m.body == "torso" and m.name in labels]
    tasks = None if len(torso) >= 3 else {c: (0.0, 10.0) for c in LUMBAR}
    kin = solve_kinematics(model, x, labels, trial.time, cutoff_hz=CUTOFF_HZ,
                           coordinate_tasks=tasks)  # fmt: skip
    plates = plates_from_trial(mtrial)
    loads = external_loads(model, kin, plates, cutoff_hz=CUTOFF_HZ, threshold_n=THRESHOLD_N)
    tau = inverse_dynamics(model, kin, loads)

    comps = []
    pooled: dict[str, tuple[list[np.ndarray], list[np.ndarray]]] = {j: ([], []) for j in JOINTS}
    for side in "RL":
        foot = f"calcn_{side.lower()}"
        on_plate = [a for a in loads.assignments if a.body == foot]
        for st in _stances(trial, side):
            # a stance counts when one plate carries this foot over all of it
            if not any(a.start_time <= st[0] + 0.05 and a.end_time >= st[1] - 0.05
                       for a in on_plate):  # fmt: skip
                continue
            sel = (kin.time >= st[0]) & (kin.time <= st[1])
            for j in JOINTS:
                ours = tau.coordinate(f"{COORD[j]}_{side.lower()}")[sel] / mass
                px_all = trial.model_outputs.get(f"{side}{PIG_LABEL[j]}")[:, 0]
                px = px_all[sel]
                lp = lowpass_finite(px_all, trial.point_rate_hz)[sel]
                ok = np.isfinite(ours) & np.isfinite(px) & np.isfinite(lp)
                if ok.sum() < 10:
                    continue
                pooled[j][0].append(ours[ok])
                pooled[j][1].append(px[ok])
                o, theirs, theirs_lp = (
                    ours[ok],
                    EXPECTED_SIGN[j] * px[ok],
                    EXPECTED_SIGN[j] * lp[ok],
                )
                comps.append(
                    JointComparison(
                        name, side, j, st, kin.time[sel][ok], o, theirs, theirs_lp,
                        float(np.sqrt(np.mean((o - theirs) ** 2))),
                        float(pearson_r(o, theirs)),
                        float(np.sqrt(np.mean((o - theirs_lp) ** 2))),
                        float(pearson_r(o, theirs_lp)),
                        float(np.mean(o - theirs_lp)),
                        float(np.max(np.abs(theirs_lp))),
                    )
                )  # fmt: skip
    raw_r = {
        j: float(pearson_r(np.concatenate(a), np.concatenate(b)))
        for j, (a, b) in pooled.items()
        if a
    }
    return PigResult(
        name,
        mass,
        source,
        {k: float(v) for k, v in ratios.items()},
        float(np.nanmean(kin.marker_rms)),
        tuple(comps),
        raw_r,
        tuple((a.plate, a.body, a.start_time, a.end_time) for a in loads.assignments),
        model,
        kin,
        mtrial,
    )


def centre_offsets_mm(res: PigResult) -> dict[tuple[str, str], np.ndarray]:
    """Mean position (mm, over the compared stance frames) of PiG's knee and ankle joint
    centres — its femur and tibia origins ``<S>FEO`` / ``<S>TIO`` (virtual points in the
    file) — in the frame of gait2392's tibia / talus (origin = msk's knee / ankle centre;
    x anterior, y up, z right for the right leg)."""
    model, kin, tr = res.model, res.kinematics, res.trial
    data = model.create_data()
    out = {}
    for side in "RL":
        frames = sorted(
            {
                int(np.argmin(np.abs(kin.time - t)))
                for c in res.comparisons
                if c.side == side and c.joint == "knee"
                for t in c.time
            }
        )
        for joint, body, pig in (("knee", "tibia", "FEO"), ("ankle", "talus", "TIO")):
            xs = tr.marker(f"{side}{pig}")
            d = []
            for i in frames:
                forward_kinematics(model, data, kin.q[i])
                d.append(data.oMf[model.body_frame[f"{body}_{side.lower()}"]].actInv(xs[i]))
            out[(side, joint)] = 1000.0 * np.nanmean(np.asarray(d), axis=0)
    return out


# ------------------------------------------------------------------------------------------
# tests
# ------------------------------------------------------------------------------------------
def _need(real_dir: Path, name: str) -> None:
    for n in (name, STATIC[name]):
        if n and not (real_dir / "btkdata" / f"{n}.c3d").is_file():
            pytest.skip(f"btkdata/{n}.c3d absent")


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.parametrize("name", FILES)
def test_plug_in_gait_sagittal_moments_map_by_sign_and_agree_with_msk(
    real_dir: Path, name: str
) -> None:
    _need(real_dir, name)
    res = pig_comparison(name)
    print(report(res))
    # every plate-borne stance compared, both sides where plates allow
    sides = {c.side for c in res.comparisons}
    assert sides == {"R", "L"}, sides
    # the sign that makes PiG agree with msk is the external-moment mapping, for every joint
    for j in JOINTS:
        assert np.sign(res.raw_r[j]) == EXPECTED_SIGN[j], (j, res.raw_r[j])
    for c in res.comparisons:
        where = (c.side, c.joint, c.stance)
        assert c.r_lp >= R_FLOOR[c.joint], (*where, c.r_lp)
        # not a shape-only agreement: the magnitudes agree too
        assert c.rms_lp <= RMS_CEILING[c.joint], (*where, c.rms_lp)
        if name == "PiG_Motion3_FF":
            assert c.r >= R_FLOOR_RAW_MOTION3, (*where, c.r)


@pytest.mark.slow
@pytest.mark.realdata
def test_plate_over_pig_grf_recovers_the_file_mass(real_dir: Path) -> None:
    """The mass recovery used for PlugInC3D (no mass in its file), checked where the file
    has one: PiG_Motion3_FF (74 kg)."""
    _need(real_dir, "PiG_Motion3_FF")
    res = pig_comparison("PiG_Motion3_FF")
    trial = read_c3d(_btk("PiG_Motion3_FF"))
    sides = side_of_plate_from_events(trial)
    # the events' plate sides are msk's own assignments
    assert sides == {p: b[-1].upper() for p, b, *_ in res.plates}
    assert plate_mass_kg(trial, sides) == pytest.approx(74.0, abs=0.5)


def report(res: PigResult) -> str:
    lines = [
        f"{res.name}: mass {res.mass_kg:.1f} kg ({res.mass_source}); IK marker RMS "
        f"{1000 * res.marker_rms_m:.1f} mm; scale ratios "
        + ", ".join(f"{k} {v:.3f}" for k, v in res.scale_ratios.items()),
        "plates: " + "; ".join(f"{p}→{b} {s:.2f}–{e:.2f} s" for p, b, s, e in res.plates),
        "pooled r vs unsigned PiG X: " + ", ".join(f"{j} {r:+.2f}" for j, r in res.raw_r.items()),
        "| side | stance (s) | joint | PiG peak, 6 Hz (N·m/kg) | RMS (N·m/kg) | RMS % peak | r "
        f"| RMS, PiG {CUTOFF_HZ:g} Hz | % peak | r, PiG {CUTOFF_HZ:g} Hz | mean msk − PiG |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    off = centre_offsets_mm(res)
    lines.insert(
        3,
        "PiG joint centre in msk's tibia / talus frame (mm, x anterior, y up): "
        + "; ".join(f"{s} {j} x {v[0]:+.0f} y {v[1]:+.0f}" for (s, j), v in off.items()),
    )
    for c in res.comparisons:
        lines.append(
            f"| {c.side} | {c.stance[0]:.2f}–{c.stance[1]:.2f} | {c.joint} | {c.pig_peak:.2f} "
            f"| {c.rms:.2f} | {c.rms_pct_peak:.0f} | {c.r:.2f} | {c.rms_lp:.2f} "
            f"| {c.rms_lp_pct_peak:.0f} | {c.r_lp:.2f} | {c.bias_lp:+.2f} |"
        )
    return "\n".join(lines)


def main() -> None:  # pragma: no cover - a report, not a test
    for name in FILES:
        print(report(pig_comparison(name)))
        print()


if __name__ == "__main__":  # pragma: no cover
    main()
