"""Leave-one-EMG-channel-out check of the tension criterion on the Grand Challenge PS walks.

    python studies/emg_holdout.py

For each PS trial (ss1 bundled; ss3, ss8 from ``../shared/data/real/knee-grand-challenge-gc5``,
the shipped ``pipelines/gc5_PS.toml`` with only the task file swapped) and each EMG channel
``c`` of the config: EMG-assisted static optimisation is run with ``c`` removed from the EMG map
(its muscles are then solved like any unmeasured muscle), and the Pearson r between the
predicted activation of ``c``'s muscles (mean over them) and ``c``'s own EMG activation is
compared with volume-weighted static optimisation's. Evidence about the criterion that is not
the measured contact force: does tracking the other channels make an *unseen* muscle's
activation follow its EMG better? Prints one row per trial and channel, then the median r and
the number of channels where EMG-assisted is better.
"""

from __future__ import annotations

import dataclasses
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import contact_validation as cv


def _r(tension: object, muscles: list[str], emg_activation: np.ndarray) -> float:
    act = np.asarray(tension.activations)  # type: ignore[attr-defined]
    names = tension.muscles  # type: ignore[attr-defined]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        a = np.nanmean([act[:, names.index(m)] for m in muscles], axis=0)
    ok = np.isfinite(a) & np.isfinite(emg_activation)
    if ok.sum() < 3 or np.std(a[ok]) == 0 or np.std(emg_activation[ok]) == 0:
        return float("nan")
    return float(np.corrcoef(a[ok], emg_activation[ok])[0, 1])


def main() -> int:
    from msk.config import load_config
    from msk.pipeline import run_stages

    folder = Path(tempfile.mkdtemp())
    print("| trial | channel | r static optimisation | r EMG-assisted, channel held out |")
    print("| --- | --- | --- | --- |")
    for trial in ("ss1", "ss3", "ss8"):
        swap = None if trial == "ss1" else {"PS_ngait_og_ss1": f"PS_ngait_og_{trial}"}
        cfg = load_config(cv._config("gc5_PS", swap, "spline", folder, None, trial))
        opt = cfg.optimization
        so_cfg = dataclasses.replace(
            cfg, optimization=dataclasses.replace(opt, method="static_optimization")
        )
        base = run_stages(so_cfg, until="tension_optimization")
        emg, so = base["emg"], base["tension_optimization"]
        rows = []
        for ch in sorted(set(cfg.emg.channels.values())):
            held = [m for m, c in cfg.emg.channels.items() if c == ch]
            cols = [emg.column(m) for m in held if bool(emg.usable[emg.column(m)])]
            if not cols:
                continue  # a flat channel: nothing to compare with
            e = np.asarray(emg.activation)[:, cols[0]]
            rest = {m: c for m, c in cfg.emg.channels.items() if c != ch}
            ea_cfg = dataclasses.replace(
                cfg,
                emg=dataclasses.replace(cfg.emg, channels=rest),
                optimization=dataclasses.replace(opt, method="emg_assisted"),
            )
            ea = run_stages(ea_cfg, until="tension_optimization")["tension_optimization"]
            rows.append((_r(so, held, e), _r(ea, held, e)))
            print(f"| {trial} | {ch} | {rows[-1][0]:.2f} | {rows[-1][1]:.2f} |", flush=True)
        r = np.array(rows)
        print(
            f"{trial}: median r static optimisation {np.nanmedian(r[:, 0]):.2f}, EMG-assisted "
            f"(held out) {np.nanmedian(r[:, 1]):.2f}; EMG-assisted better on "
            f"{int(np.sum(r[:, 1] > r[:, 0]))} of {len(rows)} channels"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
