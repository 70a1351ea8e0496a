"""The shared pipeline results of ``tests/support/sessions.py``: computed once, read-only, the
nodes of a shallower ``until`` taken from a deeper run, never computed with a block size
patched."""

from __future__ import annotations

from pathlib import Path

import pytest

from msk._runtime import blocks
from msk.datasets.trials import write_synthetic_session
from tests.support import sessions


def test_stages_are_computed_once_and_read_only(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    cfg, _ = write_synthetic_session(tmp_path / "s")
    deep = sessions.stages(cfg, "kinematics")
    calls: list[object] = []
    monkeypatch.setattr(sessions, "run_stages", lambda *a, **k: calls.append(a))
    shallow = sessions.stages(cfg, "model")
    assert calls == []  # taken from the deeper run
    assert sessions.stages(cfg, "kinematics") is not deep  # a new read-only view …
    assert sessions.stages(cfg, "kinematics")["kinematics"] is deep["kinematics"]  # … of one run
    assert calls == []
    assert list(shallow) == list(deep)[: len(shallow)] and list(shallow)[-1] == "model"
    assert shallow["model"] is deep["model"] and "kinematics" not in shallow
    q = deep["kinematics"].q
    assert not q.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        q[0, 0] = 1.0
    with pytest.raises(TypeError):
        deep["kinematics"] = None  # type: ignore[index]
    # asked for with a block size patched: refused (its results are the defaults')
    monkeypatch.setattr(blocks, "FRAME_BLOCK", 40)
    with pytest.raises(RuntimeError, match="FRAME_BLOCK"):
        sessions.stages(cfg, "kinematics")
