"""Run OpenSim 4.6 in a separate process, for cross-checks and side-by-side benchmarks.

OpenSim's wheel bundles its own casadi, which clashes with the ``casadi`` package inside one
Python process (whichever is imported second fails with an undefined symbol). msk therefore
never imports ``opensim`` itself: a peer script runs in a child interpreter and returns JSON.

Usage::

    out = run_opensim_script('''
        import opensim as osim, json, sys
        m = osim.Model(ARGS["model"]); s = m.initSystem()
        RESULT["mass"] = m.getTotalMass(s)
    ''', model="gait2392.osim")
    out["mass"]
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
import tempfile
import textwrap
from typing import Any

from msk.exceptions import MskError

__all__ = ["POSE_PRELUDE", "opensim_available", "run_opensim_script"]

_PRELUDE = """
import json, sys
ARGS = json.loads(sys.argv[1])
RESULT = {}
"""
_EPILOGUE = """
sys.stdout.write("\\n@@MSK-RESULT@@" + json.dumps(RESULT))
"""


#: Peer-script prelude for pose sweeps: loads ``ARGS["model"]`` as ``m`` with state ``s``, unlocks
#: the coordinates ``ARGS["coords"]`` (a locked coordinate ignores ``setValue``) and defines
#: ``set_pose(q)``, which sets them, applies every enforced CoordinateCouplerConstraint
#: (dependent = scale · f(independent), which OpenSim does not update on ``setValue``; msk embeds
#: it exactly) and realises positions.
POSE_PRELUDE = """
import opensim as osim, time
m = osim.Model(ARGS["model"]); s = m.initSystem()
cs = m.getCoordinateSet()
coords = [cs.get(n) for n in ARGS["coords"]]
for c in coords:
    c.setLocked(s, False)
couplers = []
cset = m.getConstraintSet()
for i in range(cset.getSize()):
    cc = osim.CoordinateCouplerConstraint.safeDownCast(cset.get(i))
    if cc is not None and cc.get_isEnforced():
        couplers.append((cs.get(cc.getDependentCoordinateName()),
                         cs.get(cc.getIndependentCoordinateNames().get(0)), cc.getFunction(),
                         float(cc.getPropertyByName("scale_factor").toString())))


def set_pose(q):
    for c, v in zip(coords, q):
        c.setValue(s, v, False)
    for dep, ind, f, k in couplers:
        dep.setValue(s, k * f.calcValue(osim.Vector(1, ind.getValue(s))), False)
    m.realizePosition(s)
"""


def opensim_available() -> bool:
    """True when the optional ``opensim`` package is installed (it is never imported here)."""
    return importlib.util.find_spec("opensim") is not None


def run_opensim_script(body: str, *, timeout_s: float = 600.0, **args: Any) -> dict[str, Any]:
    """Run ``body`` in a fresh interpreter; it reads ``ARGS`` and fills the dict ``RESULT``.

    ``args`` must be JSON-serialisable. Returns ``RESULT`` (JSON round trip: arrays come back as
    lists). Raises :class:`MskError` with OpenSim's stderr tail when the script fails. The child
    runs in a temporary working directory (OpenSim drops ``opensim.log`` and tool by-products
    there), so pass absolute paths.
    """
    if not opensim_available():
        raise MskError("opensim is not installed: pip install 'msk[opensim]'")
    code = _PRELUDE + textwrap.dedent(body) + _EPILOGUE
    with tempfile.TemporaryDirectory(prefix="msk-opensim-") as cwd:
        proc = subprocess.run(
            [sys.executable, "-c", code, json.dumps(args)],
            capture_output=True,
            text=True,
            timeout=timeout_s,
            check=False,
            cwd=cwd,
        )
    marker = "@@MSK-RESULT@@"
    if proc.returncode != 0 or marker not in proc.stdout:
        tail = (proc.stderr or proc.stdout)[-2000:]
        raise MskError(f"OpenSim peer script failed (exit {proc.returncode}): {tail}")
    return json.loads(proc.stdout.rsplit(marker, 1)[1])
