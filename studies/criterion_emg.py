"""Static-optimisation criteria judged by the subjects' own EMG (issue 16: the criterion chosen by
evidence other than the measured contact force).

    python studies/criterion_emg.py [--subjects PS,DM,...] [--out table.md]

For every recording with lower-limb EMG — Grand Challenge PS (ss1/ss3/ss8, EMG in the C3D,
``pipelines/gc5_PS.toml``'s map), DM (og1/og3/og4, the envelopes of ``moissenet/*.mat`` read,
mapped and aligned as ``studies/dm_emg_assisted.py`` does), JW (og3, its C3D), UNIPD
(Walking1, its C3D), UWA (Fast_Walking, its C3D; channel map below) and the Rajagopal walk
(``electromyography.sto``, processed and max-normalised by its authors) — the shipped config is
run once up to the muscle geometry (only the task file swapped) and the muscle-force stage is
then re-solved with each criterion of :data:`VARIANTS`: Σ w_i a_i^p with p = 2 or 3 and w =
muscle volume (Happee 1994) or uniform (OpenSim), and the bounded stress² criterion Σ (F/F_iso)²
(``method = "bounded_qp"``, Crowninshield & Brand 1981 with p = 2). The config's other settings
(e.g. ``compartment_nonnegative``) are kept; PS's ``emg_assisted`` is replaced by static
optimisation (the question is the criterion for the muscles no EMG drives).

For each channel the predicted activation (mean over the muscles the channel drives) is compared
with the channel's EMG activation on the leg's solved frames (:mod:`msk.muscles.emg_agreement`):
Pearson r, Spearman ρ, on/off agreement (25 % of each signal's own peak); and in late stance
(the second half of the side's longest stance) the rectus femoris–gastrocnemius co-contraction
index (Falconer & Winter 1985) of the prediction against the EMG's.

Decision rule (fixed before any contact figure of a variant was looked at; printed at the end):
per subject, the score of a criterion is the median over its channels of the channel's Pearson
r (mean over the subject's trials). A criterion replaces the incumbent (p = 2, volume) when
(1) its median score over the subjects is the best and exceeds the incumbent's by ≥ 0.05,
(2) leave-one-subject-out, the best criterion on the other subjects is that criterion in every
fold, and (3) its score beats the incumbent's on the held-out subject in a majority of folds.
Otherwise nothing is shipped.
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import sys
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import contact_validation as cv

REAL = cv.REAL
#: criterion name → (method, activation_exponent, activation_weights)
VARIANTS: dict[str, tuple[str, float, str]] = {
    "p2 volume": ("static_optimization", 2.0, "volume"),
    "p2 uniform": ("static_optimization", 2.0, "uniform"),
    "p3 volume": ("static_optimization", 3.0, "volume"),
    "p3 uniform": ("static_optimization", 3.0, "uniform"),
    "stress2 (bounded_qp)": ("bounded_qp", 2.0, "uniform"),
}
INCUMBENT = "p2 volume"

#: DM's moissenet envelope → gait2392 right-leg muscles (studies/dm_emg_assisted.py reads it here)
DM_MAP = {
    "semimem": ["semimem_r", "semiten_r"],
    "bifem": ["bifemlh_r"],
    "vasmed": ["vas_med_r"],
    "vaslat": ["vas_lat_r"],
    "rf": ["rect_fem_r"],
    "medgas": ["med_gas_r"],
    "latgas": ["lat_gas_r"],
    "tfl": ["tfl_r"],
    "tibant": ["tib_ant_r"],
    "peronl": ["per_long_r", "per_brev_r"],
    "soleus": ["soleus_r"],
    "addmagnus": ["add_mag1_r", "add_mag2_r", "add_mag3_r"],
    "gmax": ["glut_max1_r", "glut_max2_r", "glut_max3_r"],
    "gmed": ["glut_med1_r", "glut_med2_r", "glut_med3_r"],
    "sartorius": ["sar_r"],
}
#: the Rajagopal walk's processed EMG columns → gait2392 right-leg muscles
RAJ_MAP = {
    "soleus": ["soleus_r"],
    "gastrocnemius": ["med_gas_r", "lat_gas_r"],
    "tibialis_anterior": ["tib_ant_r"],
    "medial_hamstrings": ["semimem_r", "semiten_r"],
    "biceps_femoris": ["bifemlh_r"],
    "vastus_lateralis": ["vas_lat_r"],
    "vastus_medius": ["vas_med_r"],
    "rectus_femoris": ["rect_fem_r"],
    "gluteus_maximus": ["glut_max1_r", "glut_max2_r", "glut_max3_r"],
    "gluteus_medius": ["glut_med1_r", "glut_med2_r", "glut_med3_r"],
}
#: UWA Fast_Walking's 16 EMG channels → gait2392 right-leg muscles (the config's side)
UWA_MAP = {
    "Vast Lat": ["vas_lat_r"],
    "Gluet Max": ["glut_max1_r", "glut_max2_r", "glut_max3_r"],
    "Gluet Med": ["glut_med1_r", "glut_med2_r", "glut_med3_r"],
    "TFL": ["tfl_r"],
    "Sart": ["sar_r"],
    "Add Magnus": ["add_mag1_r", "add_mag2_r", "add_mag3_r"],
    "Grac": ["grac_r"],
    "Rec Fem": ["rect_fem_r"],
    "Vast Med": ["vas_med_r"],
    "Biceps Fem": ["bifemlh_r"],
    "Semi Mem": ["semimem_r", "semiten_r"],
    "Lat Gas": ["lat_gas_r"],
    "Med Gas": ["med_gas_r"],
    "Soleus": ["soleus_r"],
    "Tib Ant": ["tib_ant_r"],
    "Peroneus longus": ["per_long_r", "per_brev_r"],
}
#: the channel names of the rectus femoris and the (medial) gastrocnemius per subject
COCON = {
    "PS": ("rf", "medgas"),
    "JW": ("rf", "medgas"),
    "DM": ("rf", "medgas"),
    "UNIPD": ("Right Rectus femoris", "Right Gastrocnemius medialis"),
    "UWA": ("Rec Fem", "Med Gas"),
    "RAJ": ("rectus_femoris", "gastrocnemius"),
}

#: subject → [(trial, config, task-file swap, config edit)]
Edit = Callable[[str], str] | None


def _uwa_emg(text: str) -> str:
    chans = ", ".join(f'{m} = "{c}"' for c, ms in UWA_MAP.items() for m in ms)
    return text + (
        f"\n[emg]\nchannels = {{ {chans} }}\nhighpass_hz = 20.0\nlowpass_hz = 6.0\n"
        "electromechanical_delay_s = 0.04\n"
    )


SESSIONS: dict[str, list[tuple[str, str, dict[str, str] | None, Edit]]] = {
    "PS": [
        ("ss1", "gc5_PS", None, None),
        ("ss3", "gc5_PS", {"PS_ngait_og_ss1": "PS_ngait_og_ss3"}, None),
        ("ss8", "gc5_PS", {"PS_ngait_og_ss1": "PS_ngait_og_ss8"}, None),
    ],
    "DM": [
        ("og1", "gc6_DM_og1", None, None),
        ("og3", "gc6_DM_og1", {"og1": "og3"}, None),
        ("og4", "gc6_DM_og1", {"og1": "og4"}, None),
    ],
    "JW": [("og3", "gc4_JW", None, None)],
    "UNIPD": [("walking1", "unipd_bts", None, None)],
    "UWA": [("fast_walking", "uwa_fast_walking", None, _uwa_emg)],
    "RAJ": [("walk", "opensim_rajagopal", None, None)],
}


def _offline_activation(time: np.ndarray, t_src: np.ndarray, x: np.ndarray) -> np.ndarray:
    """An envelope (any scale) divided by its peak, delayed 40 ms, put on ``time`` (NaN outside
    its span) and passed through first-order activation dynamics, as the pipeline's EMG stage
    does for a C3D channel."""
    from msk.muscles.activation import first_order_activation

    x = np.clip(np.asarray(x, float) / np.nanmax(x), 0, 1)
    xi = np.interp(time, t_src + 0.04, x, left=np.nan, right=np.nan)
    out = np.full_like(xi, np.nan)
    cov = np.isfinite(xi)
    if cov.sum() > 1:
        rate = 1.0 / float(np.median(np.diff(time)))
        out[cov] = first_order_activation(xi[cov][:, None], rate_hz=rate)[:, 0]
    return out


def _emg_channels(subject: str, trial: str, cfg: Any, r: dict[str, Any]) -> dict[str, Any]:
    """channel → (muscles, EMG activation on the kinematics' time)."""
    time = r["kinematics"].time
    out: dict[str, Any] = {}
    if subject == "DM":
        from scipy.io import loadmat

        from msk.io.contact_force import align_dm_trial

        dm = REAL / "knee-grand-challenge-gc6-DM"
        mat = dm / "moissenet" / f"DM_ngait_{trial}.mat"
        al = align_dm_trial(mat, dm / f"DM_ngait_{trial}_new.trc")
        emg = loadmat(mat, squeeze_me=True, struct_as_record=False)["Emg"]
        for ch, ms in DM_MAP.items():
            out[ch] = (ms, _offline_activation(time, al.time, getattr(emg, ch)))
        return out
    if subject == "RAJ":
        from msk.io import read_sto

        tab = read_sto(REAL / "opensim-rajagopal-walk" / "electromyography.sto")
        for ch, ms in RAJ_MAP.items():
            out[ch] = (ms, _offline_activation(time, tab.time, tab.column(ch)))
        return out
    emg = r["emg"]
    for ch in dict.fromkeys(cfg.emg.channels.values()):
        ms = [m for m, c in cfg.emg.channels.items() if c == ch and m in emg.muscles]
        cols = [emg.column(m) for m in ms if bool(emg.usable[emg.column(m)])]
        if cols:
            out[ch] = (ms, np.asarray(emg.activation)[:, cols[0]])
    return out


def _late_stance(r: dict[str, Any], side: str, within: np.ndarray) -> np.ndarray:
    """(N,) the second half of the side's longest stance (its foot grounded) among the frames
    ``within`` (those the EMG and the prediction both cover)."""
    contact = r["loads"].contact
    suffix = "_r" if side == "right" else "_l"
    cols = [i for i, f in enumerate(contact.feet) if str(f).endswith(suffix)]
    g = np.asarray(contact.grounded)[:, cols].any(axis=1) & within
    best, start = (0, 0), None
    for i, v in enumerate(np.append(g, False)):
        if v and start is None:
            start = i
        elif not v and start is not None:
            if i - start > best[1] - best[0]:
                best = (start, i)
            start = None
    late = np.zeros(g.size, dtype=bool)
    a, b = best
    late[(a + b) // 2 : b] = True
    return late


def _criterion_cfg(cfg: Any, method: str, p: float, w: str) -> Any:
    opt = dataclasses.replace(
        cfg.optimization, method=method, activation_exponent=p, activation_weights=w
    )
    return dataclasses.replace(cfg, optimization=opt)


def run_subject(subject: str, folder: Path) -> list[dict[str, Any]]:
    from msk.config import load_config
    from msk.muscles.emg_agreement import channel_agreement, cocontraction_index
    from msk.pipeline import run_stages
    from msk.pipeline import tension as tension_stage
    from msk.pipeline.inputs import session_inputs

    rows = []
    for trial, name, swap, edit in SESSIONS[subject]:
        cfg = load_config(cv._config(name, swap, "spline", folder, edit, f"{subject}{trial}"))
        r = run_stages(cfg, until="muscle_geometry")
        chans = _emg_channels(subject, trial, cfg, r)
        solvable = np.asarray(r["loads"].solvable)
        for label, (method, p, w) in VARIANTS.items():
            vcfg = _criterion_cfg(cfg, method, p, w)
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)
                    t = tension_stage.run(
                        session_inputs(vcfg),
                        model=r["model"],
                        kinematics=r["kinematics"],
                        loads=r["loads"],
                        mass_identification=r["mass_identification"],
                        inverse_dynamics=r["inverse_dynamics"],
                        muscle_geometry=r["muscle_geometry"],
                        emg=r["emg"],
                    )
            except Exception as exc:  # a criterion that does not run is a row, not a crash
                rows.append(dict(subject=subject, trial=trial, variant=label, error=str(exc)))
                print(f"{subject} {trial} {label}: not run: {exc}", flush=True)
                continue
            act = np.asarray(t.activations, float)
            names = list(t.muscles)
            pred, emg_a, keys = [], [], []
            for ch, (ms, e) in chans.items():
                idx = [names.index(m) for m in ms if m in names]
                if not idx or not np.isfinite(e).any():
                    continue
                with warnings.catch_warnings():  # a frame not solved: NaN in every muscle
                    warnings.simplefilter("ignore", RuntimeWarning)
                    a = np.nanmean(act[:, idx], axis=1)
                a = np.where(solvable, a, np.nan)
                pred.append(a)
                emg_a.append(np.where(np.isfinite(a), e, np.nan))
                keys.append(ch)
            P, E = np.column_stack(pred), np.column_stack(emg_a)
            ag = channel_agreement(P, E, keys)
            rf, gas = COCON[subject]
            ci_pred = ci_emg = rf_late = float("nan")
            if rf in keys and gas in keys:
                i, j = keys.index(rf), keys.index(gas)
                ok = np.isfinite(P[:, i]) & np.isfinite(E[:, i]) & np.isfinite(E[:, j])
                lo = _late_stance(r, cfg.subject.side, ok)
                if lo.sum() > 2:
                    ci_pred = cocontraction_index(
                        P[lo, i], P[lo, j], peak_a=np.max(P[ok, i]), peak_b=np.max(P[ok, j])
                    )
                    ci_emg = cocontraction_index(
                        E[lo, i], E[lo, j], peak_a=np.max(E[ok, i]), peak_b=np.max(E[ok, j])
                    )
                    rf_late = float(np.mean(P[lo, i]))
            rows.append(
                dict(
                    subject=subject,
                    trial=trial,
                    variant=label,
                    channels=keys,
                    r=ag.r,
                    rho=ag.rho,
                    on_off=ag.on_off,
                    frames=int(ag.frames.max()),
                    ci_pred=ci_pred,
                    ci_emg=ci_emg,
                    rf_late=rf_late,
                    infeasible=t.infeasible_frames,
                )
            )
            print(
                f"{subject} {trial} {label}: median r {ag.median_r():.2f}, "
                f"rho {np.nanmedian(ag.rho):.2f}, on/off {np.nanmedian(ag.on_off):.2f}, "
                f"CI late stance pred/EMG {ci_pred:.2f}/{ci_emg:.2f}, rf late {rf_late:.3f}, "
                f"frames {ag.frames.max()}, channels {len(keys)}",
                flush=True,
            )
            print(
                "   " + " ".join(f"{k}={v:.2f}" for k, v in zip(keys, ag.r)),
                flush=True,
            )
    return rows


def subject_scores(rows: list[dict[str, Any]], metric: str = "r") -> dict[str, dict[str, float]]:
    """subject → criterion → median over channels of the channel's trial-mean ``metric`` (``r``,
    ``rho`` or ``on_off``)."""
    acc: dict[tuple[str, str, str], list[float]] = {}
    for row in rows:
        if "error" in row:
            continue
        for ch, v in zip(row["channels"], row[metric]):
            acc.setdefault((row["subject"], row["variant"], ch), []).append(float(v))
    per: dict[tuple[str, str], list[float]] = {}
    for (s, v, _), vals in acc.items():
        m = float(np.nanmean(vals)) if np.isfinite(vals).any() else float("nan")
        per.setdefault((s, v), []).append(m)
    out: dict[str, dict[str, float]] = {}
    for (s, v), vals in per.items():
        out.setdefault(s, {})[v] = float(np.nanmedian(vals))
    return out


def decide(scores: dict[str, dict[str, float]]) -> list[str]:
    """The decision rule of the module docstring (:func:`msk.optimization.criterion_selection.
    choose_criterion`, margin 0.05), in lines."""
    from msk.optimization.criterion_selection import choose_criterion

    ch = choose_criterion(scores, INCUMBENT, margin=0.05)
    lines = ["median over subjects: " + ", ".join(
        f"{c} {v:.3f}" for c, v in zip(ch.candidates, ch.pooled)
    )]  # fmt: skip
    for sub, pick, gain in zip(ch.subjects, ch.fold_picks, ch.fold_gain):
        lines.append(f"held out {sub}: best on the others {pick} (held-out gain {gain:+.3f})")
    lines.append(f"winner: {ch.chosen or 'none, keep ' + INCUMBENT} ({ch.reason})")
    return lines


def markdown(rows: list[dict[str, Any]]) -> list[str]:
    out = [
        "| subject | trial | criterion | channels | median r | median ρ | median on/off "
        "| rf–gas CI late stance pred / EMG | rf activation late stance |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for row in rows:
        if "error" in row:
            out.append(
                f"| {row['subject']} | {row['trial']} | {row['variant']} | not run: "
                f"{row['error'][:120]} | | | | | |"
            )
            continue
        out.append(
            f"| {row['subject']} | {row['trial']} | {row['variant']} | {len(row['channels'])} "
            f"| {np.nanmedian(row['r']):.2f} | {np.nanmedian(row['rho']):.2f} "
            f"| {np.nanmedian(row['on_off']):.2f} | {row['ci_pred']:.2f} / {row['ci_emg']:.2f} "
            f"| {row['rf_late']:.3f} |"
        )
    return out


def _criterion_edit(method: str, p: float, w: str) -> Callable[[str], str]:
    def edit(text: str) -> str:
        text = re.sub(r'(?m)^method = ".*"$', f'method = "{method}"', text, count=1)
        text = re.sub(r'(?m)^activation_weights = ".*"$', f'activation_weights = "{w}"', text)
        text = re.sub(r"(?m)^activation_exponent = .*$", "", text)
        return text.replace("[optimization]\n", f"[optimization]\nactivation_exponent = {p}\n", 1)

    return edit


def contact_rows(subjects: list[str], folder: Path) -> list[str]:
    """The contact figures of every criterion variant (the whole pipeline, spline knee) on the
    subjects with a measured contact force: the consequence of a criterion, never its reason."""
    from msk.pipeline import run_task_trials

    rows = [
        "| subject | trial | criterion | total RMSE (BW) | total r | peak pred / meas (BW) "
        "| medial RMSE | medial r | lateral RMSE | lateral r |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for subject in subjects:
        for trial, name, swap, _ in SESSIONS[subject]:
            for label, (method, p, w) in VARIANTS.items():
                tag = f"{subject}{trial}{label}"
                edit = _criterion_edit(method, p, w)
                cfg = cv._config(name, swap, "spline", folder, edit, tag)
                out = folder / re.sub(r"[^A-Za-z0-9_]", "", tag)
                (res,) = run_task_trials(cfg, out)
                comp = res.summary["comparison"] or {}
                cells = []
                for part in ("", "_medial", "_lateral"):
                    c = comp.get(f"knee_contact_generic{part}")
                    cells += [f"{c['rms_bw']:.2f}", f"{c['pearson_r']:.2f}"] if c else ["—", "—"]
                    if part == "" and c:
                        cells.append(f"{c['peak_predicted_bw']:.2f} / {c['peak_measured_bw']:.2f}")
                rows.append(f"| {subject} | {trial} | {label} | " + " | ".join(cells) + " |")
                print(rows[-1], flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--subjects", default=",".join(SESSIONS))
    p.add_argument("--out", type=Path, help="write the markdown table and the decision here")
    p.add_argument(
        "--contact",
        action="store_true",
        help="instead: the knee contact figures of every criterion on PS, DM and JW",
    )
    args = p.parse_args(argv)
    folder = Path(tempfile.mkdtemp())
    if args.contact:
        subjects = [s for s in args.subjects.split(",") if s in ("PS", "DM", "JW")]
        text = "\n".join(contact_rows(subjects, folder))
        print(text)
        if args.out:
            args.out.write_text(text + "\n", encoding="utf-8")
        return 0
    rows: list[dict[str, Any]] = []
    for s in args.subjects.split(","):
        rows += run_subject(s.strip(), folder)
    lines = markdown(rows)
    for metric in ("r", "rho", "on_off"):
        scores = subject_scores(rows, metric)
        head = "THE RULE" if metric == "r" else "sensitivity only, not the rule"
        lines += [
            "",
            f"per-subject score, median over channels of the trial-mean {metric} ({head}):",
        ]
        for s, sc in scores.items():
            lines.append(f"  {s}: " + ", ".join(f"{c} {v:.3f}" for c, v in sc.items()))
        if len(scores) > 1:
            lines += decide(scores)
    text = "\n".join(lines)
    print(text)
    if args.out:
        args.out.write_text(text + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
