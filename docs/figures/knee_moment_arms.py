"""Knee moment arms of the quadriceps and hamstrings: gait2392 spline knee vs four-bar knee.

    .venv/bin/python docs/figures/knee_moment_arms.py   # writes docs/figures/knee_moment_arms.png

The scaled gait2392 of the OpenSim subject01 example (``msk.model.osim.load_osim``); the four-bar
(the rehabilitation-robot lower-limb model paper, §2.1) is fitted to the model's own knee
translation splines over 0–120° flexion (``msk.model.fourbar_fit.fit_four_bar_to_joint``) and
swapped in for ``knee_r``. Moment arms are r = −∂l/∂θ_knee from
:func:`msk.muscles.geometry.muscle_geometry` (the four-bar's rolling–gliding p'(θ) enters through G
= ∂q/∂θ), hip at 0, ankle at 0. The grey band is the in-vivo quadriceps range 4–6 cm cited by
Benoussaad et al. 2013 (from its ref. [3]).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from msk.datasets.shared import shared_dir
from msk.model.core import Model
from msk.muscles.geometry import muscle_geometry

QUADRICEPS = ("rect_fem_r", "vas_med_r", "vas_int_r", "vas_lat_r")
HAMSTRINGS = ("semimem_r", "semiten_r", "bifemlh_r", "bifemsh_r")
MODEL = (
    shared_dir()
    / "tools/opensim-peer/data/Pipelines/Gait2392_Simbody/OutputReference/subject01_simbody.osim"
)
OUT = Path(__file__).with_suffix(".png")


def knee_models(path: Path = MODEL) -> dict[str, Model]:
    """The spline-knee gait2392 and the same model with a fitted four-bar right knee."""
    from msk.model.fourbar_fit import fit_four_bar_to_joint, four_bar_joint
    from msk.model.osim import load_osim

    spline = load_osim(path)
    knee = next(j for j in spline.joints if j.name == "knee_r")
    fit = fit_four_bar_to_joint(knee, flexion=(0.0, -np.deg2rad(120.0)))
    return {
        "spline knee": spline,
        "four-bar knee": spline.with_joints({"knee_r": four_bar_joint(knee, fit.knee)}),
    }


def knee_moment_arms(model: Model, flexion_deg: np.ndarray) -> dict[str, np.ndarray]:
    """Knee moment arm (m, extension positive) of each quadriceps and hamstring muscle."""
    th = np.tile(model.default_coordinates(), (flexion_deg.size, 1))
    for name in ("hip_flexion_r", "hip_adduction_r", "hip_rotation_r", "ankle_angle_r"):
        th[:, model.coordinate_index(name)] = 0.0
    k = model.coordinate_index("knee_angle_r")
    th[:, k] = -np.deg2rad(flexion_deg)  # gait2392: knee_angle negative in flexion
    geo = muscle_geometry(model, th)
    return {m: geo.moment_arms[:, geo.muscle_index(m), k] for m in QUADRICEPS + HAMSTRINGS}


def plot(out: Path = OUT) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    flexion = np.linspace(0.0, 120.0, 121)
    models = knee_models()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    for ax, group, title in (
        (axes[0], QUADRICEPS, "quadriceps"),
        (axes[1], HAMSTRINGS, "hamstrings"),
    ):
        if group is QUADRICEPS:
            ax.axhspan(4.0, 6.0, color="0.85", label="in-vivo 4–6 cm (seed 000, its ref. [3])")
        for (label, model), style in zip(models.items(), ("-", "--")):
            arms = knee_moment_arms(model, flexion)
            for i, m in enumerate(group):
                ax.plot(flexion, 100 * np.abs(arms[m]), style, color=f"C{i}",
                        label=f"{m} ({label})")  # fmt: skip
        ax.set_title(f"{title}: |moment arm| about knee_angle_r")
        ax.set_xlabel("knee flexion (deg)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6.5, ncol=2)
    axes[0].set_ylabel("moment arm (cm)")
    fig.suptitle("gait2392 subject01: spline knee (solid) vs fitted four-bar knee (dashed)")
    fig.tight_layout()
    fig.savefig(out, dpi=130)
    plt.close(fig)
    return out


if __name__ == "__main__":
    print(plot())
