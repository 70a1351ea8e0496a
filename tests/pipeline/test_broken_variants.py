"""A deliberately broken variant of every shipped session raises the flag that names the problem
(issue 15): the configured body mass 30 % low, the ASIS labels swapped, and every marker of the
right foot dropped from IK. Each variant is the shipped configuration as msk reads it
(:func:`msk.config.render_config`) with one field changed, so the same three breakages are
made the same way on every lab's session whatever its marker names.

The baseline figures of the shipped sessions are asserted by
``tests/pipeline/test_shipped_sessions.py``;
here only what the breakage must add. The three flags are raised from the model, the
kinematics and the loads (the plates' weight, the swapped-label pairs, the markers each
segment keeps), so each variant runs only the graph's nodes those flags and the summary need
(:data:`FLAG_NODES`): not the OpenSim export, mass identification, EMG, muscle, strength,
contact, gait-analysis, comparison, FES and table nodes, which none of the three reads (the
summary copes without them, as for a session without EMG).
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path
from typing import Any

import pytest
from threadpoolctl import threadpool_limits

from msk.config import load_config, render_config
from msk.model.markersets import parse_label
from msk.pipeline import CORE_STAGES, GRAPH, STAGES, run_stages, split_task_trials
from msk.pipeline.graph import run_graph
from msk.pipeline.inputs import session_inputs
from msk.pipeline.runner import Runner
from tests.support.recordings import recordings_present

REPO = Path(__file__).resolve().parents[2]
CONFIGS = sorted((REPO / "pipelines").glob("*.toml"))


def _present(cfg: Path) -> bool:
    return recordings_present(cfg)


#: the nodes a variant runs: the graph up to the summary, the nodes that read the model,
#: the kinematics and the loads to raise the asserted flags (module docstring) and those the
#: summary needs (inverse dynamics, gait cycle)
FLAG_NODES = (
    "read", "measured_contact", "model", "kinematics", "swapped_markers", "loads",
    "inverse_dynamics", "gait_cycle", "summary",
)  # fmt: skip


def _variant(cfg, folder: Path, **changes) -> dict[str, Any]:
    """The nodes :data:`FLAG_NODES` of the session's first task trial run with the
    configuration changed as given (without cache, nothing written: as
    :func:`msk.pipeline.run_stages`)."""
    path = folder / "variant.toml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(render_config(dataclasses.replace(cfg, **changes)), encoding="utf-8")
    first = split_task_trials(load_config(path))[0]
    graph = tuple(n for n in GRAPH if n.name in FLAG_NODES)
    runner = Runner(None, None, stages=STAGES, core=CORE_STAGES)
    with threadpool_limits(limits=1, user_api="blas"):
        return run_graph(session_inputs(first), runner, graph)


def test_flag_nodes_are_nodes_of_the_graph_in_its_order():
    names = [n.name for n in GRAPH]
    assert set(FLAG_NODES) <= set(names)
    assert sorted(FLAG_NODES, key=names.index) == list(FLAG_NODES)


def _flags(results: dict[str, Any]) -> dict[str, dict]:
    """The quality flags (quantity → flag) of a run: the summary stage's, the flags ``msk run``
    writes to summary.json."""
    return {f["quantity"]: f for f in results["summary"]["quality"]["flags"]}


def _asis_pair(matched: dict[str, str]) -> tuple[str, str]:
    """The model's right and left ASIS markers among those matched to lab labels."""
    side = {}
    for name in matched:
        p = parse_label(name)
        if p.side in ("R", "L") and p.landmark == "asis":
            side[p.side] = name
    if set(side) != {"R", "L"}:
        pytest.skip(f"no matched ASIS pair among {sorted(matched)}")
    return side["R"], side["L"]


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.parametrize("path", CONFIGS, ids=[c.stem for c in CONFIGS])
def test_broken_variants_raise_the_flag_that_names_the_problem(path: Path, tmp_path: Path):
    if not _present(path):
        pytest.skip(f"{path.stem}: recordings not here")
    cfg = load_config(path)
    # 1. the body mass typed 30 % low: the plates weigh someone else
    if cfg.subject.mass_kg is not None:
        light = dataclasses.replace(cfg.subject, mass_kg=0.7 * cfg.subject.mass_kg)
        light_run = _variant(cfg, tmp_path / "mass", subject=light)
        flags = _flags(light_run)
        assert "plate_mass_difference_pct" in flags, sorted(flags)
        # plates heavier than the configured mass (the value is their difference, % of it)
        assert flags["plate_mass_difference_pct"]["value"] > 5.0
        # the model's markers, their lab labels and bodies: the mass does not change them
        built = light_run["model"]
    else:
        built = run_stages(cfg, until="model")["model"]
    matched = dict(built.info["marker_set"]["matched"])

    # 2. the right and left ASIS labels swapped (a labelling error in the file)
    r, lft = _asis_pair(matched)
    swapped = {**cfg.marker_rename, r: matched[lft], lft: matched[r]}
    flags = _flags(_variant(cfg, tmp_path / "swap", marker_rename=swapped))
    assert f"{r}/{lft}_swapped" in flags, sorted(flags)

    # 3. every marker on the right foot dropped from IK: the foot is not observed, and a
    # gate says so (never a foot pose reported as if measured)
    mdl = built.model
    foot = set(mdl.subtree("calcn_r")) if "calcn_r" in mdl.body_frame else set()
    on_foot = [m.name for m in mdl.markers if m.body in foot]
    if not on_foot:
        pytest.skip("the model has no right-foot markers")
    weights = {**cfg.marker_weights, **dict.fromkeys(on_foot, 0.0)}
    flags = _flags(_variant(cfg, tmp_path / "foot", marker_weights=weights))
    named = " ".join(flags)
    assert re.search(r"calcn_r|toes_r|subtalar_angle_r|ankle_angle_r|mtp_angle_r", named), named
