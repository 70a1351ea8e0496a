"""Muscle lengths and moment arms of an ``.osim`` model computed by OpenSim 4.6 in a child
process (:func:`msk._runtime.opensim_peer.run_opensim_script`), for cross-checks."""

from __future__ import annotations

from typing import Any

import numpy as np

from msk._runtime.opensim_peer import POSE_PRELUDE

__all__ = ["OPENSIM_GEOMETRY", "OPENSIM_TENDON_ARM", "opensim_geometry", "opensim_tendon_arm"]

OPENSIM_GEOMETRY = (
    POSE_PRELUDE
    + """
muscles = [m.getMuscles().get(n) for n in ARGS["muscles"]]
macs = [cs.get(n) for n in ARGS["ma_coords"]]
L, R = [], []
t0 = time.perf_counter()
for q in ARGS["q"]:
    set_pose(q)
    L.append([mu.getLength(s) for mu in muscles])
    R.append([[mu.computeMomentArm(s, c) for c in macs] for mu in muscles])
RESULT["seconds"] = time.perf_counter() - t0
RESULT["L"] = L
RESULT["R"] = R
"""
)


def opensim_geometry(
    path: Any, model: Any, theta: Any, muscles: Any, coords: Any
) -> tuple[Any, Any]:
    """Lengths (N, m) and moment arms (N, m, c) of ``muscles`` about ``coords`` at ``theta``."""
    from msk._runtime.opensim_peer import run_opensim_script

    out = run_opensim_script(
        OPENSIM_GEOMETRY,
        model=str(path),
        coords=list(model.coordinate_names),
        q=np.asarray(theta).tolist(),
        muscles=[model.muscles[k].name for k in muscles],
        ma_coords=[model.coordinate_names[i] for i in coords],
    )
    return np.asarray(out["L"]), np.asarray(out["R"])


#: the moment arm on ``ARGS["knee"]`` of the straight line from a muscle's last-but-one path
#: point (on the patella) to its last (on the tibia) — Rajagopal et al. (2016)'s patellar
#: tendon, the quadriceps' path from the patella to the tibial tuberosity — with the patella
#: held to the femur at each pose (the tendon's pull on the tibia about the knee: one PathSpring
#: per pose from the femur-fixed point where the patella point is to the tibial point)
OPENSIM_TENDON_ARM = (
    POSE_PRELUDE
    + """
mu = osim.Muscle.safeDownCast(m.getMuscles().get(ARGS["muscle"]))
pp = mu.getGeometryPath().getPathPointSet()
a = osim.PathPoint.safeDownCast(pp.get(pp.getSize() - 2))
b = osim.PathPoint.safeDownCast(pp.get(pp.getSize() - 1))
A = [a.get_location().get(i) for i in range(3)]
B = [b.get_location().get(i) for i in range(3)]
names = [a.getParentFrame().getName(), b.getParentFrame().getName()]
femur = m.getBodySet().get(ARGS["femur"])
P = []
for q in ARGS["q"]:
    set_pose(q)
    p = a.getParentFrame().findStationLocationInAnotherFrame(s, a.get_location(), femur)
    P.append([p.get(i) for i in range(3)])
m_posed = m
m = osim.Model(ARGS["model"])
for k, p in enumerate(P):
    ps = osim.PathSpring(f"tendon{k}", 0.05, 1.0, 0.0)
    ps.updGeometryPath().appendNewPathPoint("p", m.getBodySet().get(ARGS["femur"]), osim.Vec3(*p))
    ps.updGeometryPath().appendNewPathPoint("t", m.getBodySet().get(names[1]), osim.Vec3(*B))
    m.addForce(ps)
s = m.initSystem()
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
R = []
for k, q in enumerate(ARGS["q"]):
    set_pose(q)
    ps = osim.PathSpring.safeDownCast(m.getForceSet().get(f"tendon{k}"))
    R.append(ps.getGeometryPath().computeMomentArm(s, cs.get(ARGS["knee"])))
RESULT["R"] = R
RESULT["points"] = [[names[0], A], [names[1], B]]
"""
)


def opensim_tendon_arm(
    path: Any, model: Any, theta: Any, muscle: str, knee: str, femur: str
) -> tuple[Any, list[Any]]:
    """OpenSim 4.6's moment arm (N,) on ``knee`` at ``theta`` of the line between the last
    two path points of ``muscle``, the patella held to ``femur`` (:data:`OPENSIM_TENDON_ARM`),
    and those two points ``[[body, location], ...]``."""
    from msk._runtime.opensim_peer import run_opensim_script

    out = run_opensim_script(
        OPENSIM_TENDON_ARM, model=str(path), coords=list(model.coordinate_names),
        q=np.asarray(theta).tolist(), muscle=muscle, knee=knee, femur=femur,
    )  # fmt: skip
    return np.asarray(out["R"]), out["points"]
