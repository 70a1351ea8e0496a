"""FES parameter recovery on every seeds/000 Table 3 leg, with population priors and a prior
misspecification sweep; writes the tables of ``docs/fes.md`` and ``docs/figures/fes_recovery.png``.

Run: ``.venv/bin/python bench/fes_recovery.py`` (≈ 15 min on one core).  ``--only-docs``
rewrites the markdown and the figure from ``bench/fes_recovery.json`` without recomputing.

Every leg's protocol data are simulated from its published parameters (1 % torque noise,
0.5° goniometer noise, seed 7, :func:`msk.fes.protocol.synthetic_session`), then identified
with :func:`msk.fes.protocol.run_protocol`:

* *population*: priors = Table 3 means without the leg's subject (leave-subject-out);
* *population + K_cm*: the same, with ``identify_stiffness_ratio=True``;
* *sweep*: on :data:`SWEEP_LEGS`, one prior at a time set to truth × (1 + δ) for
  δ ∈ ±10, ±25, ±50 %, the other prior at the truth.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import re
from pathlib import Path

import numpy as np

from msk.fes.model import TABLE3
from msk.fes.priors import population_priors
from msk.fes.protocol import fibre_fraction
from msk.fes.recovery import RECOVERY_PARAMS, recovery_run

ROOT = Path(__file__).resolve().parents[1]
JSON = ROOT / "bench" / "fes_recovery.json"
DOC = ROOT / "docs" / "fes.md"
FIG = ROOT / "docs" / "figures" / "fes_recovery.png"
SWEEP_LEGS = ("S3L", "S6R", "S9L", "S10R")
DELTAS = (-0.5, -0.25, -0.1, 0.1, 0.25, 0.5)
BEGIN, END = "<!-- fes_recovery:begin -->", "<!-- fes_recovery:end -->"


def _run_all() -> dict[str, list[dict]]:
    out: dict[str, list[dict]] = {"population": [], "population_K_cm": [], "sweep": []}
    for leg in TABLE3:
        for key, joint in (("population", False), ("population_K_cm", True)):
            r = recovery_run(leg, identify_stiffness_ratio=joint)
            out[key].append(dataclasses.asdict(r))
            print(key, leg, "FAILED" if r.failure else f"{r.seconds:.1f} s", flush=True)
    for leg in SWEEP_LEGS:
        s = TABLE3[leg]
        ff, ratio = fibre_fraction(s), s.muscle.K_cm / s.muscle.F_cm
        for prior in ("fibre_fraction", "stiffness_ratio"):
            for d in DELTAS:
                kw = {
                    "fibre_fraction_prior": ff * (1 + d if prior == "fibre_fraction" else 1),
                    "stiffness_ratio_prior": ratio * (1 + d if prior == "stiffness_ratio" else 1),
                }
                r = recovery_run(leg, **kw)
                row = dataclasses.asdict(r) | {"prior": prior, "delta": d}
                out["sweep"].append(row)
                print("sweep", leg, prior, d, "FAILED" if r.failure else "ok", flush=True)
    return out


def _cell(v: float | None) -> str:
    return "—" if v is None or not np.isfinite(v) else f"{100 * v:+.1f}"


def _leg_table(rows: list[dict]) -> list[str]:
    head = ["leg", "prior err. ff / ratio %", *RECOVERY_PARAMS, "CV NRMSD %"]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        pe = r["prior_error"]
        prior = f"{100 * pe['fibre_fraction']:+.0f} / {100 * pe['stiffness_ratio']:+.0f}"
        if r["failure"]:
            cells = ["failed"] + [""] * (len(RECOVERY_PARAMS))
        else:
            cells = [_cell(r["error"].get(k)) for k in RECOVERY_PARAMS]
            cells.append(f"{r['nrmsd_cross_validation']:.1f}")
        mark = "*" if r["notes"] else ""
        out.append("| " + " | ".join([r["leg"] + mark, prior, *cells]) + " |")
    return out


def summary(rows: list[dict], tol: tuple[float, ...] = (0.02, 0.05, 0.10, 0.25)) -> list[str]:
    """Per parameter: number of legs within each tolerance and the median |error|."""
    n = len(rows)
    ok = [r for r in rows if not r["failure"]]
    head = ["parameter", *[f"within {100 * t:.0f} %" for t in tol], "median |err| %"]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for k in RECOVERY_PARAMS:
        e = np.array([abs(r["error"][k]) for r in ok if k in r["error"]])
        cnt = [f"{int(np.sum(e <= t))}/{n}" for t in tol]
        med = f"{100 * np.median(e):.1f}" if e.size else "—"
        out.append("| " + " | ".join([k, *cnt, med]) + " |")
    return out


def _sweep_table(rows: list[dict]) -> list[str]:
    params = ("L_c0", "b", "F_cm·α_max", "K_cm", "k_s", "c2", "c3")
    head = ["leg", "prior", "δ %", *params, "CV NRMSD %"]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        lead = [r["leg"] + ("*" if r["notes"] else ""), r["prior"], f"{100 * r['delta']:+.0f}"]
        if r["failure"]:
            out.append("| " + " | ".join([*lead, "failed", *[""] * len(params)]) + " |")
            continue
        cells = [_cell(r["error"].get(k)) for k in params]
        cells.append(f"{r['nrmsd_cross_validation']:.1f}")
        out.append("| " + " | ".join([*lead, *cells]) + " |")
    return out


def _figure(data: dict[str, list[dict]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(10, 4.2))
    legs = [r["leg"] for r in data["population"]]
    for i, (key, mk, lab) in enumerate(
        (("population", "o", "population priors"), ("population_K_cm", "^", "+ K_cm in NLP"))
    ):
        for j, k in enumerate(RECOVERY_PARAMS):
            e = [r["error"].get(k, np.nan) for r in data[key] if not r["failure"]]
            x = j + (i - 0.5) * 0.3 + np.zeros(len(e))
            ax.scatter(x, 100 * np.abs(e), marker=mk, s=14, c=f"C{i}", label=lab if j == 0 else "")
    ax.set_yscale("log")
    ax.set_ylim(0.01, 1e5)
    ax.axhline(5, color="0.5", lw=0.8, ls="--")
    ax.set_xticks(range(len(RECOVERY_PARAMS)), RECOVERY_PARAMS, rotation=45)
    ax.set_ylabel("|identified / published − 1|  (%)")
    ax.set_title(f"FES recovery on {len(legs)} seeds/000 Table 3 legs (failed runs not shown)")
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    FIG.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(FIG, dpi=110)


def write_docs(data: dict[str, list[dict]]) -> None:
    pop = population_priors()
    lines = [
        BEGIN,
        "",
        "Generated by `bench/fes_recovery.py` (do not edit by hand). Errors are "
        "`identified/published − 1` in %; `*` = a refinement pass failed and the last complete "
        "one was kept (`ProtocolResult.notes`); `failed` = `IdentificationError`.",
        "",
        f"Population priors over all 13 legs: fibre fraction {pop.fibre_fraction:.4f} "
        f"(SD {pop.sd['fibre_fraction']:.4f}), K_cm/F_cm {pop.stiffness_ratio:.0f} 1/m "
        f"(SD {pop.sd['stiffness_ratio']:.0f}); each leg below uses the means *without its "
        "subject*.",
        "",
        "### Population priors (default protocol)",
        "",
        *_leg_table(data["population"]),
        "",
        *summary(data["population"]),
        "",
        "### Population priors, K_cm identified with k_s (`identify_stiffness_ratio=True`)",
        "",
        *_leg_table(data["population_K_cm"]),
        "",
        *summary(data["population_K_cm"]),
        "",
        "### Prior misspecification sweep (one prior off by δ, the other exact)",
        "",
        *_sweep_table(data["sweep"]),
        "",
        END,
    ]
    text = DOC.read_text(encoding="utf-8") if DOC.exists() else f"# FES\n\n{BEGIN}\n{END}\n"
    block = "\n".join(lines)
    text = re.sub(re.escape(BEGIN) + ".*?" + re.escape(END), lambda _m: block, text, flags=re.S)
    DOC.write_text(text, encoding="utf-8")
    _figure(data)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--only-docs", action="store_true")
    args = ap.parse_args()
    if args.only_docs:
        data = json.loads(JSON.read_text(encoding="utf-8"))
    else:
        data = _run_all()
        JSON.write_text(json.dumps(data, indent=1, default=float), encoding="utf-8")
    write_docs(data)
    print(f"wrote {DOC.relative_to(ROOT)} and {FIG.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
