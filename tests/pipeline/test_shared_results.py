"""The shared pipeline results of ``tests/support/sessions.py``: computed once, read-only, the
nodes of a shallower ``until`` taken from a deeper run, never computed with a block size
patched."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from msk._runtime import blocks
from msk.datasets.trials import write_synthetic_session
from msk.pipeline import run_stages
from tests.support import sessions


def test_stages_are_computed_once_read_only_and_equal_a_fresh_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    cfg, _ = write_synthetic_session(tmp_path / "s")
    deep = sessions.stages(cfg, "inverse_dynamics")
    calls = []
    monkeypatch.setattr(sessions, "run_stages", lambda *a, **k: calls.append(a))
    shallow = sessions.stages(cfg, "kinematics")
    assert calls == []  # taken from the deeper run
    assert list(shallow) == list(deep)[: len(shallow)] and list(shallow)[-1] == "kinematics"
    assert shallow["kinematics"] is deep["kinematics"]
    q = shallow["kinematics"].q
    assert not q.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        q[0, 0] = 1.0
    with pytest.raises(TypeError):
        shallow["kinematics"] = None  # type: ignore[index]
    fresh = run_stages(cfg, until="kinematics")["kinematics"]
    np.testing.assert_array_equal(fresh.q, q)
    # asked for with a block size patched: refused (its results are the defaults')
    monkeypatch.setattr(blocks, "FRAME_BLOCK", 40)
    with pytest.raises(RuntimeError, match="FRAME_BLOCK"):
        sessions.stages(cfg, "kinematics")
