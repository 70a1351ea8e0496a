"""DM's recorded EMG in EMG-assisted static optimisation, against the shipped static optimisation.

    python studies/dm_emg_assisted.py

DM's EMG is not in its task files (``.trc``/``.sto``): the only envelopes are ``Emg.<muscle>``
of ``moissenet/DM_ngait_og*.mat``, one gait cycle per trial, placed in the ``.trc``'s time by
the markers (:func:`msk.io.contact_force.align_dm_trial`). Each envelope is divided by its
trial peak (the files' ``Mvc`` values are below the walking peaks for 8 of 15 muscles, so they
are not maximal: :mod:`msk.io.contact_force`), delayed by 40 ms, passed through first-order
activation dynamics and mapped to gait2392's right-leg muscles (one channel drives its
synergists, as in ``pipelines/gc4_JW.toml``). On the frames the EMG covers (and the plates
measure), the EMG gains are fitted on the trial's own torques (:func:`msk.strength.
fit_emg_gains`, w_track 1, volume weights, passive forces) and the EMG-assisted forces give the
knee contact; the shipped config's static-optimisation forces on the same frames are the
baseline. Prints RMSE (BW) / r of total, medial and lateral against the measured force.
"""

import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import contact_validation as cv
from criterion_emg import DM_MAP
from scipy.io import loadmat

import msk.optimization as o
from msk.config import load_config
from msk.contact.knee import knee_contact_force, plateau_geometry, split_medial_lateral
from msk.io.contact_force import align_dm_trial
from msk.muscles.activation import first_order_activation
from msk.muscles.geometry import jacobian_frames, muscle_parameters
from msk.muscles.hill import rigid_tendon_state
from msk.pipeline import run_stages
from msk.strength import fit_emg_gains

DM = cv.REAL / "knee-grand-challenge-gc6-DM"
MAP = DM_MAP  # DM's moissenet envelope → gait2392 right-leg muscles
folder = Path(tempfile.mkdtemp())
for trial, swap in (("og1", None), ("og3", {"og1": "og3"}), ("og4", {"og1": "og4"})):
    cfg = load_config(cv._config("gc6_DM_og1", swap, "spline", folder, None, trial))
    r = run_stages(cfg, until="tension_optimization")
    kin, loads, mdl = r["kinematics"], r["loads"], r["model"].model
    so = r["tension_optimization"]
    mat = DM / "moissenet" / f"DM_ngait_{trial}.mat"
    al = align_dm_trial(mat, DM / f"DM_ngait_{trial}_new.trc")
    emg = loadmat(mat, squeeze_me=True, struct_as_record=False)["Emg"]
    t_emg = al.time + 0.04  # electromechanical delay
    params = muscle_parameters(mdl)
    names = list(params.names)
    e = np.full((kin.time.size, len(names)), np.nan)
    meas = np.zeros(len(names), bool)
    for ch, ms in MAP.items():
        x = np.asarray(getattr(emg, ch), float)
        x = np.clip(x / np.nanmax(x), 0, 1)
        xi = np.interp(kin.time, t_emg, x, left=np.nan, right=np.nan)
        cov = np.isfinite(xi)
        a = np.full_like(xi, np.nan)
        a[cov] = first_order_activation(xi[cov][:, None], rate_hz=120.0)[:, 0]
        for m in ms:
            e[:, names.index(m)] = a
            meas[names.index(m)] = True
    cov = np.isfinite(e[:, meas]).all(1) & loads.usable
    fr = np.flatnonzero(cov)
    geom = r["muscle_geometry"]
    tq = r["inverse_dynamics"].torques
    act_idx = [i for i, c in enumerate(tq.coordinate_names) if c not in tuple(tq.root_coordinates)]
    cn = tuple(tq.coordinate_names[i] for i in act_idx)
    st = rigid_tendon_state(
        params, geom.lengths[fr], None if geom.velocities is None else geom.velocities[fr]
    )
    fa = np.where(st.max_active_force_along_tendon < 0, 0, st.max_active_force_along_tendon)
    fp = st.passive_force_along_tendon
    jac = jacobian_frames(geom.jacobian, fr, act_idx)
    tau = tq.tau[fr][:, act_idx]
    w = o.volume_weights(params.max_isometric_force, params.optimal_fiber_length)
    groups = {ch: ms for ch, ms in MAP.items()}
    fit = fit_emg_gains(
        jac,
        tau,
        f_active=fa,
        f_passive=fp,
        emg_activation=np.nan_to_num(e[fr]),
        groups=groups,
        muscle_names=names,
        w_track=1.0,
        activation_weights=w,
        reserve_optimal_force=np.ones(len(act_idx)),
        coordinate_names=cn,
    )
    sol = o.solve_emg_assisted_batch(
        jac,
        tau,
        f_active=fa,
        f_passive=fp,
        a_ref=fit.reference(np.nan_to_num(e[fr])),
        measured=fit.measured,
        w_track=1.0,
        activation_weights=w,
        reserve_optimal_force=np.ones(len(act_idx)),
        muscle_names=names,
        coordinate_names=cn,
    )
    mc = r["measured_contact"]
    geo = plateau_geometry(mdl, joint="knee_r")
    bw = cfg.subject.mass_kg * 9.80665
    res = {}
    for lab, forces in (("SO", so.forces[fr]), ("EA", sol.forces)):
        c = knee_contact_force(
            mdl,
            kin.take(fr),
            loads.external.take(fr),
            muscle_forces=forces,
            muscle_names=tuple(names),
            joint="knee_r",
        )
        ml = split_medial_lateral(c, geo)
        out = []
        for pred, meas_v in (
            (ml.medial + ml.lateral, mc.total),
            (ml.medial, mc.medial),
            (ml.lateral, mc.lateral),
        ):
            mi = np.interp(kin.time[fr], mc.time, meas_v, left=np.nan, right=np.nan)
            ok = np.isfinite(mi) & np.isfinite(pred)
            out.append(
                (
                    np.sqrt(np.mean((pred[ok] - mi[ok]) ** 2)) / bw,
                    np.corrcoef(pred[ok], mi[ok])[0, 1],
                    ok.sum(),
                )
            )
        res[lab] = out
    print(trial, "frames", fr.size, "gains", dict(zip(fit.group_names, np.round(fit.gains, 3))))
    for lab, out in res.items():
        print(
            "  ",
            lab,
            " ".join(f"{n} {x[0]:.2f}/{x[1]:.2f}" for n, x in zip(("tot", "med", "lat"), out)),
            "n",
            out[0][2],
        )
