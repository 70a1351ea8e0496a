"""The Rajagopal walk (``opensim-rajagopal-walk`` on ``subject_walk_scaled.osim``) of the
real-data strength tests: muscle → EMG electrode mapping, synergist groups, and the model, ID
and EMG tables with the muscle geometry along the recorded coordinates."""

from __future__ import annotations

import numpy as np

RATE_HZ = 100.0
# muscle → EMG column (seeds/003 §3.2.1: VI = mean of VM and VL; BFSH from BFLH; SM, ST from
# the medial hamstrings electrode; both gastrocnemii from one electrode)
EMG_MAP = {
    "recfem_r": ("rectus_femoris",),
    "vaslat_r": ("vastus_lateralis",),
    "vasmed_r": ("vastus_medius",),
    "vasint_r": ("vastus_lateralis", "vastus_medius"),
    "bflh_r": ("biceps_femoris",),
    "bfsh_r": ("biceps_femoris",),
    "semimem_r": ("medial_hamstrings",),
    "semiten_r": ("medial_hamstrings",),
    "gasmed_r": ("gastrocnemius",),
    "gaslat_r": ("gastrocnemius",),
    "soleus_r": ("soleus",),
    "tibant_r": ("tibialis_anterior",),
}
GROUPS = {
    "knee_extensors": ("recfem_r", "vaslat_r", "vasmed_r", "vasint_r"),
    "knee_flexors": ("bflh_r", "bfsh_r", "semimem_r", "semiten_r"),
    "plantar_flexors": ("gasmed_r", "gaslat_r", "soleus_r"),
    "dorsiflexors": ("tibant_r",),
}
COORDS = ("knee_angle_r", "ankle_angle_r")


def rajagopal_walk(real_dir, ref_dir):
    """The Rajagopal walk on ``subject_walk_scaled.osim`` at RATE_HZ over 0.45–1.80 s: the model,
    the ID and EMG tables, the time grid and the muscle geometry along the recorded coordinates."""
    from msk.io.opensim_files import read_sto
    from msk.muscles.geometry import muscle_geometry
    from msk.osim import load_osim

    d = real_dir / "opensim-rajagopal-walk"
    model = load_osim(ref_dir / "opensim-core" / "subject_walk_scaled.osim")
    coords = read_sto(d / "coordinates.sto")
    ids = read_sto(d / "id_walk.sto")
    emg = read_sto(d / "electromyography.sto")
    t = np.arange(0.45, 1.80 + 1e-9, 1.0 / RATE_HZ)
    by_name = {c.split("/")[-2]: i for i, c in enumerate(coords.columns) if c.endswith("/value")}
    q = np.column_stack(
        [
            np.interp(t, coords.time, coords.data[:, by_name[n]]) if n in by_name else 0 * t
            for n in model.coordinate_names
        ]
    )
    return model, ids, emg, t, muscle_geometry(model, q, np.gradient(q, 1.0 / RATE_HZ, axis=0))
