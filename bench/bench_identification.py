"""Mass-distribution identification from 10,000 frames: regressor stacking vs constrained solve.

The whole-body model of ``msk.datasets.models.whole_body_model`` (15 bodies, upper body lumped into
one link: 8 identified segments, 4 free with left/right symmetry... 50 scaled parameters), a
100 s trial at 100 Hz of sums of sines with 2 mm-marker-equivalent kinematic noise and 1 %
force-plate noise. Times (best of 5 wall-clock, same run):

- stacking: base-link regressor of all frames (vectorised over frames) and the per-row Gram
  matrices Y_kᵀY_k, Y_kᵀτ_k;
- solve: the physically consistent MAP problem (Clarabel, PSD cones), including the two noise
  re-estimation refits (3 solves);
- the Pinocchio frame-by-frame regressor (``method="pinocchio"``) for reference.

    .venv/bin/python bench/bench_identification.py

prints its figures (only ``bench/run_all.py`` writes figures into the docs).
"""

from __future__ import annotations

import argparse

from _timing import best_of

from msk.datasets.models import subject_bodies, whole_body_model
from msk.datasets.trials import identification_trial
from msk.dynamics.identification import InertialIdentifier, lump_subtrees
from msk.dynamics.regressors import base_link_regressor, regressor_layout


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.parse_args()
    truth = whole_body_model(subject_bodies("athlete"))
    lumped = lump_subtrees(whole_body_model(), ["torso"])
    trial = lumped.restrict_trial(identification_trial(truth, 100.4, 7))
    n = trial.n_frames
    model = lumped.model
    ident = InertialIdentifier(model, total_mass=truth.total_mass)
    ident.fit(trial)  # warm-up (imports, Clarabel)
    t_fit, _ = best_of(lambda: ident.fit(trial), 5)
    stacks, solves = [], []
    for _ in range(5):
        ident.fit(trial)
        stacks.append(ident.timing_["stacking_s"])
        solves.append(ident.timing_["solve_s"])
    stack, solve = min(stacks), min(solves)
    layout = regressor_layout(model)
    t_reg, _ = best_of(
        lambda: base_link_regressor(
            model, trial.theta, trial.theta_dot, trial.theta_ddot, layout=layout
        ),
        5,
    )
    t_pin, _ = best_of(
        lambda: base_link_regressor(
            model,
            trial.theta,
            trial.theta_dot,
            trial.theta_ddot,
            layout=layout,
            method="pinocchio",
        ),
        2,
    )
    n_x = ident.x_.size
    lines = [
        f"frames: {n}, bodies: {len(layout.body_names)}, scaled parameters: {n_x}, "
        f"solves per fit: {ident.timing_['solves']}",
        f"stacking (regressor + Gram): {stack * 1e3:.1f} ms "
        f"(regressor alone {t_reg * 1e3:.1f} ms; Pinocchio frame by frame {t_pin * 1e3:.0f} ms)",
        f"constrained solve (all refits): {solve * 1e3:.1f} ms "
        f"({solve / ident.timing_['solves'] * 1e3:.1f} ms per Clarabel solve)",
        f"total fit incl. uncertainty: {t_fit * 1e3:.1f} ms",
        f"ratio stacking / solve: {stack / solve:.2f}",
        f"vectorised / Pinocchio regressor speed-up: {t_pin / t_reg:.1f}x",
    ]
    print("\n".join(lines))


if __name__ == "__main__":
    main()
