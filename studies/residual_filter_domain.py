"""Where a session's pelvis residual force comes from: the low-pass's domain, the plates, flight.

    python studies/residual_filter_domain.py [config ...]   (default: pipelines/uwa_running.toml;
    docs/validation.md ran it on the eleven shipped configs, issue 15's run-15 pass)

In every frame the pelvis residual force of inverse dynamics is Newton's law for the whole body,

    R = Σ_b m_b a_b − M g − F = M (a_G − g) − F,

a_b the acceleration of segment b's centre of mass from the low-passed coordinates θ, a_G the
whole body's, F the low-passed plate force applied to the feet. The plates' low-pass is linear,
so the filtered force balances the filtered COM acceleration exactly (Kristianslund et al. 2012,
J Biomech 45:666: one cut-off for the kinematics and the forces). msk low-passes θ instead
(``msk.kinematics.ik``), and the COM is not linear in θ (a segment's position is a product of its
chain's rotations): ``a_G(filter(θ))`` differs from ``filter(a_G(θ))`` where segments turn fast.
Printed per session, at the pipeline's own kinematics, loads and masses (generic, identified):

1. the residual force RMS (% BW; the summary's frames: measured and observed) in all of them,
   per axis (model frame: x forward, y up, z right), in stance (a plate load applied) and in
   flight (none, no foot on an unmeasured surface: those frames are not measured);
2. the same with the **whole** low-passed plate force, its ripples outside the thresholded
   contact included (``msk.dynamics.loads`` applies it only where the filtered vertical force
   exceeds the
   threshold), and with it zeroed where the raw plate is under its threshold;
3. **the COM low-passed as the plates are**: the COM of the unfiltered IK (``Kinematics.q_raw``)
   low-passed at the kinematics' cut-off (the same reflected ends, ``msk.kinematics.ik.
   kinematics_from_coordinates``), M (a_G − g) − F with the whole filtered plate force;
4. in flight runs of at least 20 frames: the COM of the unfiltered IK fitted by a parabola
   (its acceleration must be g: no external force), and each segment's share m_b (a_b − g).

5. a known truth: the unfiltered IK low-passed at 20 Hz taken as the true motion θ_s, plates
   reading exactly F = M (a_G(θ_s) − g); the pipeline's method, θ_s and F both low-passed at the
   cut-off, leaves a residual where the truth has none: the share of the filter's domain alone.

Diagnosis only: nothing here is chosen on these figures.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

REPO = Path(__file__).resolve().parent.parent
THRESHOLD_N = 20.0  # msk.dynamics.loads' default contact threshold
MIN_FLIGHT = 20  # frames of a flight run fitted by a parabola
TRUTH_HZ = 20.0  # the known-truth motion: the unfiltered IK low-passed at this cut-off


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of the True runs of ``mask``."""
    x = np.concatenate([[0], mask.astype(int), [0]])
    d = np.diff(x)
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _segment_coms(model: Any, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(N, J, 3) world COM of each Pinocchio joint's inertia, (J,) masses and joint names."""
    pm = model.pin_model
    data = pm.createData()
    out = np.full((theta.shape[0], pm.njoints, 3), np.nan)
    for k in np.flatnonzero(np.isfinite(theta).all(axis=1)):
        pin.forwardKinematics(pm, data, model.coupling.q(theta[k][None])[0])
        for j in range(1, pm.njoints):
            out[k, j] = data.oMi[j].act(pm.inertias[j].lever)
    mass = np.array([pm.inertias[j].mass for j in range(pm.njoints)])
    return out, mass, list(pm.names)


def _pct(x: np.ndarray, bw: float) -> str:
    """RMS over all the components, and per axis, in % of body weight."""
    if x.size == 0:
        return "—"
    per = 100 * np.sqrt(np.mean(x**2, axis=0)) / bw
    tot = 100 * np.sqrt(np.mean(x**2)) / bw
    return f"{tot:5.2f} (x {per[0]:.1f}, y {per[1]:.1f}, z {per[2]:.1f})"


def known_truth(model: Any, kin: Any) -> np.ndarray:
    """(N, 3) residual force of the pipeline's method on a known truth (item 5 of the module
    docstring): zero but for low-passing θ instead of the COM."""
    from msk.kinematics.ik import kinematics_from_coordinates as wrap

    t, names, cut = kin.time, kin.coordinate_names, kin.cutoff_hz
    g = np.asarray(model.gravity, dtype=float)
    xyz = ("x", "y", "z")

    def com(theta: np.ndarray) -> np.ndarray:
        coms, mass, _ = _segment_coms(model, theta)
        out = np.einsum("njk,j->nk", np.nan_to_num(coms), mass) / mass.sum()
        out[~np.isfinite(theta).all(axis=1)] = np.nan
        return out

    mass = sum(model.pin_model.inertias[j].mass for j in range(model.pin_model.njoints))
    theta_s = wrap(t, kin.q_raw, names, cutoff_hz=TRUTH_HZ).q
    force = mass * (wrap(t, com(theta_s), xyz, cutoff_hz=None).a - g)
    force_f = wrap(t, force, xyz, cutoff_hz=cut).q
    a_theta = wrap(t, com(wrap(t, theta_s, names, cutoff_hz=cut).q), xyz, cutoff_hz=None).a
    return mass * (a_theta - g) - force_f


def report(config: Path) -> None:
    from msk.config import load_config
    from msk.dynamics.identification import identified_model
    from msk.dynamics.loads import sample_plate
    from msk.kinematics.ik import kinematics_from_coordinates
    from msk.pipeline.inputs import session_inputs
    from msk.pipeline.loads import rotated_plate
    from msk.pipeline.read import run as read_stage
    from msk.pipeline.session import run_stages

    cfg = load_config(config)
    res = run_stages(cfg, until="inverse_dynamics")
    built, kin, loads = res["model"], res["kinematics"], res["loads"]
    ident, dyn = res["mass_identification"], res["inverse_dynamics"]
    plates = read_stage(session_inputs(cfg)).plates or ()
    t, cut = kin.time, kin.cutoff_hz
    g = np.asarray(built.model.gravity, dtype=float)
    up = -g / np.linalg.norm(g)
    bw = float(cfg.subject.mass_kg) * float(np.linalg.norm(g))
    f_all = np.zeros((t.size, 3))  # the whole low-passed plate force
    raw_on = np.zeros(t.size, dtype=bool)  # a plate's raw vertical force over its threshold
    for p in plates:
        sp = sample_plate(rotated_plate(p, built.rotation), t, up, threshold_n=THRESHOLD_N,
                          cutoff_hz=cut)  # fmt: skip
        f_all += sp.force
        raw_on |= np.abs(sp.fv_recorded) > THRESHOLD_N
    ext = loads.external
    f_app = ext.force.sum(axis=1)
    ok = loads.measured_observed & np.isfinite(dyn.generic.residual_force).all(axis=1)
    stance = ok & (f_app @ up > THRESHOLD_N)
    flight = ok & ~stance & ~(np.abs(ext.force_recorded @ up) > THRESHOLD_N)
    print(f"\n== {config.name}: {ok.sum()} frames (stance {stance.sum()}, flight {flight.sum()}), "
          f"θ cut-off {cut} Hz, BW {bw:.0f} N")  # fmt: skip
    r_truth = known_truth(built.model, kin)
    fin = ok & np.isfinite(r_truth).all(axis=1)
    print(f"  known truth (θ_s = IK at {TRUTH_HZ:.0f} Hz, generic masses), θ_s and F low-passed: "
          f"{_pct(r_truth[fin], bw)} (truth 0)")  # fmt: skip
    models = [("generic", built.model, dyn.generic)]
    if dyn.identified is not None and ident is not None:
        models.append(("identified", identified_model(built.model, ident), dyn.identified))
    for name, model, jt in models:
        r = jt.residual_force
        r_all = r + f_app - f_all
        r_raw = r + f_app - f_all * raw_on[:, None]
        coms, mass, names = _segment_coms(model, kin.q_raw)
        com = np.einsum("njk,j->nk", np.nan_to_num(coms), mass) / mass.sum()
        com[~np.isfinite(kin.q_raw).all(axis=1)] = np.nan
        a_com = kinematics_from_coordinates(t, com, ("x", "y", "z"), cutoff_hz=cut).a
        r_com = mass.sum() * (a_com - g) - f_all
        fin = ok & np.isfinite(r_com).all(axis=1)
        print(f"  {name} (M {mass.sum():.1f} kg)")
        print(f"    pipeline            all {_pct(r[ok], bw)}")
        print(f"                        stance {_pct(r[stance], bw)}  flight {_pct(r[flight], bw)}")
        print(f"    whole filtered F    all {_pct(r_all[ok], bw)}")
        print(f"    zero where raw < thr all {_pct(r_raw[ok], bw)}")
        print(f"    COM low-passed      all {_pct(r_com[fin], bw)}")
        print(f"                        stance {_pct(r_com[fin & stance], bw)}  "
              f"flight {_pct(r_com[fin & flight], bw)}")  # fmt: skip
        # segment by segment: m_b a_b of the low-passed θ (central differences) against m_b a_b
        # of the segment's COM low-passed (the same filter as the plates)
        coms_f, _, _ = _segment_coms(model, kin.q)
        parts = []
        for j in range(1, len(names)):
            if mass[j] < 0.5:
                continue
            a_theta = kinematics_from_coordinates(
                t, coms_f[:, j], ("x", "y", "z"), cutoff_hz=None
            ).a
            a_lin = kinematics_from_coordinates(t, coms[:, j], ("x", "y", "z"), cutoff_hz=cut).a
            dj = mass[j] * (a_theta - a_lin)
            fj = ok & np.isfinite(dj).all(axis=1)
            parts.append(f"{names[j]} {100 * np.sqrt(np.mean(dj[fj] ** 2)) / bw:.1f}")
        print(f"    θ low-passed − COM low-passed, m_b Δa_b (% BW): {', '.join(parts)}")
        for a, b in _runs(flight):
            if b - a < MIN_FLIGHT:
                continue
            tt = t[a:b] - t[a:b].mean()
            basis = np.stack([np.ones_like(tt), tt, tt**2], axis=1)
            acc = 2 * np.linalg.lstsq(basis, com[a:b], rcond=None)[0][2]
            span = f"{t[a]:.3f}–{t[b - 1]:.3f} s"
            fit = f"({acc[0]:.2f}, {acc[1]:.2f}, {acc[2]:.2f}) m/s² (g = {g[1]:.2f})"
            print(f"    flight {span}, unfiltered IK's COM parabola: a = {fit}")
            for j in range(1, len(names)):
                if mass[j] < 0.5:
                    continue
                aj = 2 * np.linalg.lstsq(basis, coms[a:b, j], rcond=None)[0][2]
                share = mass[j] * (aj - g)
                print(f"      {names[j]:<16} {mass[j]:5.2f} kg  m(a − g) = ({share[0]:6.0f}, "
                      f"{share[1]:6.0f}, {share[2]:6.0f}) N")  # fmt: skip


def main(argv: list[str]) -> None:
    configs = [Path(a) for a in argv] or [REPO / "pipelines" / "uwa_running.toml"]
    for c in configs:
        report(c)


if __name__ == "__main__":
    main(sys.argv[1:])
