"""Knee contact validation table: the shipped Grand Challenge session configs run on every trial
with a measured contact force, only the task files swapped, spline and four-bar knee.

    python studies/contact_validation.py [--out docs/contact_validation.md]

Trials: subject PS (``pipelines/gc5_PS.toml``: ss1 bundled, ss3 and ss8 from
``../shared/data/real/knee-grand-challenge-gc5``), subject DM (``pipelines/gc6_DM_og1.toml``:
og1, og3, og4, measured forces in ``data/gc6-DM``) and subject JW (``pipelines/gc4_JW.toml``:
og3, the total from the implant's load cells, no medial/lateral). Nothing is fitted to the
measured force: the configurations are the shipped ones. Prints a markdown table of RMSE (BW)
and Pearson r of the total, medial and lateral force per trial, knee model and variant:
``shipped`` (the config as it is) and the variants of :data:`VARIANTS`, each one edit of the
config (DM: the generic model's neutral knee alignment instead of DM.osim's, DM's given contact
points from ``p_DM.mat``; PS: static optimisation or the EMG-weighted criterion instead of the
shipped EMG-assisted one; JW: EMG-assisted; all three: the knee alignment estimated from the
subject's markers, ``knee_alignment = "from_markers"``, a "not run" row with the reason when
the markers are not there; ``compartments free``: ``compartment_nonnegative = false``, the
medial/lateral forces allowed to pull as before 2026-11-25).
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
REAL = REPO.parent / "shared" / "data" / "real"

TRIALS = {
    "gc5_PS": [
        ("ss1", None),
        ("ss3", {"PS_ngait_og_ss1": "PS_ngait_og_ss3"}),
        ("ss8", {"PS_ngait_og_ss1": "PS_ngait_og_ss8"}),
    ],
    "gc4_JW": [("og3", None)],
    "gc6_DM_og1": [
        ("og1", None),
        ("og3", {"og1": "og3"}),
        ("og4", {"og1": "og4"}),
    ],
}


def _neutral(text: str) -> str:
    return re.sub(r"(?m)^knee_(varus_deg|medial_shift_m) = .*$", "", text)


def _p_dm(text: str) -> str:
    # DM's contact points (fmoissenet/MSK_Delp_U_Ankle p_DM.mat, constant terms): ±18.6 mm,
    # 33.7 mm below the knee centre (mean of the four polynomials' y)
    return text + "\n[contact]\nintercondylar_distance_m = 0.0372\nplateau_depth_m = 0.0337\n"


def _from_markers(text: str) -> str:
    text = re.sub(r"(?m)^knee_(varus_deg|medial_shift_m) = .*$", "", text)
    return text.replace("[model]\n", '[model]\nknee_alignment = "from_markers"\n', 1)


def _compartments_free(text: str) -> str:
    # issue 16, seventh pass: the shipped configs hold the knee compartments ≥ 0 in the
    # muscle-force QP; this variant lets them pull (the configs before 2026-11-25)
    return re.sub(r"(?m)^compartment_nonnegative = .*$", "compartment_nonnegative = false", text)


def _method(name: str) -> Callable[[str], str]:
    return lambda text: re.sub(r'(?m)^method = ".*"$', f'method = "{name}"', text, count=1)


#: per config: (variant, edit of the config text, knee models it is run with)
VARIANTS: dict[str, list[tuple[str, Callable[[str], str] | None, tuple[str, ...]]]] = {
    "gc5_PS": [
        ("shipped (emg_assisted)", None, ("spline", "four_bar")),
        ("static_optimization", _method("static_optimization"), ("spline",)),
        ("emg_weighted", _method("emg_weighted"), ("spline",)),
        ("alignment from markers", _from_markers, ("spline",)),
        ("compartments free", _compartments_free, ("spline",)),
        (
            "static_optimization, compartments free",
            lambda t: _compartments_free(_method("static_optimization")(t)),
            ("spline",),
        ),
    ],
    "gc4_JW": [
        ("shipped", None, ("spline", "four_bar")),
        ("emg_assisted", _method("emg_assisted"), ("spline",)),
        ("compartments free", _compartments_free, ("spline",)),
        ("alignment from markers", _from_markers, ("spline",)),
    ],
    "gc6_DM_og1": [
        ("shipped (alignment given)", None, ("spline", "four_bar")),
        ("neutral alignment", _neutral, ("spline", "four_bar")),
        ("alignment + p_DM points", _p_dm, ("spline",)),
        ("alignment from markers", _from_markers, ("spline",)),
        ("compartments free", _compartments_free, ("spline",)),
    ],
}


def _config(
    name: str,
    swap: dict[str, str] | None,
    knee: str,
    folder: Path,
    edit: Callable[[str], str] | None = None,
    tag: str = "",
) -> Path:
    src = REPO / "pipelines" / f"{name}.toml"
    text = src.read_text(encoding="utf-8")
    # absolute paths, the task files swapped (a PS trial other than ss1 is in shared/)
    text = re.sub(r'(=\s*")(\.\.[^"]*)"', lambda m: f'{m[1]}{(src.parent / m[2]).resolve()}"', text)
    for a, b in (swap or {}).items():
        text = text.replace(a, b)
    if name == "gc5_PS" and swap:
        text = text.replace(str(REPO / "data" / "gc5-PS"), str(REAL / "knee-grand-challenge-gc5"))
        text = text.replace(
            str(REAL / "knee-grand-challenge-gc5" / "PS_static_for_scaling.trc"),
            str(REPO / "data" / "gc5-PS" / "PS_static_for_scaling.trc"),
        )
    text = text.replace('knee = "spline"', f'knee = "{knee}"')
    if "knee =" not in text:
        text = text.replace("[model]\n", f'[model]\nknee = "{knee}"\n', 1)
    if edit is not None:
        text = edit(text)
    out = folder / f"{name}_{knee}{re.sub(r'[^a-z_]', '', tag)}.toml"
    out.write_text(text, encoding="utf-8")
    return out


def main(argv: list[str] | None = None) -> int:
    from msk.exceptions import ConfigError
    from msk.pipeline import run_task_trials

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, help="write the markdown table here too")
    args = p.parse_args(argv)
    rows = [
        "| subject | trial | knee | variant | total RMSE (BW) | total r | peak pred / meas (BW) "
        "| medial RMSE | medial r | lateral RMSE | lateral r | IK (mm) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name, trials in TRIALS.items():
            for trial, swap in trials:
                for tag, edit, knees in VARIANTS[name]:
                    for knee in knees:
                        cfg = _config(name, swap, knee, folder, edit, tag)
                        out = folder / f"{name}_{trial}_{knee}_{re.sub(r'[^a-z_]', '', tag)}"
                        subject = name.split("_")[1]
                        head = f"| {subject} | {trial} | {knee} | {tag} | "
                        try:
                            (res,) = run_task_trials(cfg, out)
                        except ConfigError as exc:  # e.g. no markers for the alignment
                            rows.append(head + "not run: " + str(exc).split(": ", 1)[-1]
                                        + " |" * 8)  # fmt: skip
                            print(rows[-1], flush=True)
                            continue
                        comp = res.summary.to_dict()["comparison"] or {}
                        cells = []
                        for part in ("", "_medial", "_lateral"):
                            c = comp.get(f"knee_contact_generic{part}")
                            cells += (
                                [f"{c['rms_bw']:.2f}", f"{c['pearson_r']:.2f}"] if c else ["—", "—"]
                            )
                            if part == "" and c:
                                peaks = (
                                    f"{c['peak_predicted_bw']:.2f} / {c['peak_measured_bw']:.2f}"
                                )
                                cells.append(peaks)
                        ik = 1000 * res.summary.to_dict()["quality"]["ik_marker_rms_mean_m"]
                        row = head + " | ".join(cells)
                        rows.append(row + f" | {ik:.1f} |")
                        print(rows[-1], flush=True)
    text = "\n".join(rows) + "\n"
    if args.out:
        args.out.write_text(text, encoding="utf-8")
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
