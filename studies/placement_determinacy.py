"""What a placement from the motion does not determine, and how far tiny noise moves it.

    python studies/placement_determinacy.py [--sd 1e-5] [--seeds 1,2,3] [--only gc6_DM_og1,...]

Issue 15, det pass (docs/validation.md). For each shipped session without a static trial, the
model stage is run (``msk.pipeline.run_stages``) once as shipped and once per seed with the
markers + N(0, ``sd``) per coordinate (exact-zero gaps kept) in its scaling and placement passes
only — injected as ``studies/placement_jitter.py`` injects its noise; the choice among
placements and the profile are judged on the unperturbed markers. Printed per run: the
profile's cost (mm), each leg coordinate's mean over the choice's frames (deg) and the
coordinates ``msk.personalise.determinacy`` reports as not determined; then each mean's spread (max
− min)
over the runs. Nothing is asserted: this is the cross-check of the profile's verdicts
(``tests/personalise/test_determinacy.py`` is the test).
"""

from __future__ import annotations

import argparse
import dataclasses
from typing import Any

import numpy as np

SESSIONS = ["gc6_DM_og1", "gc6_DM_ngait_tm_ss", "gc6_DM_crouch_tm", "uwa_fast_walking",
            "uwa_running", "opensim_rajagopal"]  # fmt: skip


def run_once(name: str, sd: float, seed: int | None) -> dict[str, Any]:
    """The model stage of ``name`` with the markers + N(0, ``sd``) (seed ``seed``; None: as
    shipped) in its scaling and placement passes; its ``model.placement_determinacy``."""
    from pathlib import Path

    import msk.personalise.personalise as pmodel
    from msk.pipeline import run_stages

    rng = None if seed is None else np.random.default_rng(seed)
    orig = pmodel.scale_and_place

    def scale_and_place(generic, static, task, opts, **kw):  # type: ignore[no-untyped-def]
        if rng is not None:
            m = np.asarray(task.markers, dtype=float)
            seen = ((m != 0.0).any(axis=-1) & np.isfinite(m).all(axis=-1))[..., None]
            task = dataclasses.replace(task, markers=m + seen * rng.normal(0.0, sd, m.shape))
        return orig(generic, static, task, opts, **kw)

    pmodel.scale_and_place = scale_and_place  # type: ignore[assignment]
    try:
        cfg = Path(__file__).resolve().parents[1] / "pipelines" / f"{name}.toml"
        r = run_stages(cfg, until="model")
    finally:
        pmodel.scale_and_place = orig  # type: ignore[assignment]
    return dict(r["model"].info["placement_determinacy"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sd", type=float, default=1e-5, help="marker noise SD (m)")
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--only", default=",".join(SESSIONS))
    a = ap.parse_args()
    seeds = [int(s) for s in a.seeds.split(",") if s]
    for name in a.only.split(","):
        means: dict[str, list[float]] = {}
        for seed in [None, *seeds]:
            d = run_once(name, a.sd, seed)
            row = {c: float(v["mean_deg"]) for c, v in d["coordinates"].items()}
            for c, v in row.items():
                means.setdefault(c, []).append(v)
            nd = ", ".join(d["not_determined"]) or "-"
            means_txt = ", ".join(f"{c} {v:.2f}" for c, v in row.items())
            print(f"{name} seed={seed}: cost {1000 * d['cost_m']:.3f} mm, means {means_txt}; "
                  f"not determined: {nd}", flush=True)  # fmt: skip
        spread = ", ".join(f"{c} {max(v) - min(v):.2f}" for c, v in means.items())
        print(f"{name} spread (deg): {spread}", flush=True)


if __name__ == "__main__":
    main()
