"""Measured tibiofemoral contact forces (instrumented knee prostheses) as one small record.

:func:`read_measured_contact` reads

* a CSV whose first column is ``time`` (s), e.g. the output of ``studies/dm_contact_to_csv.py``;
* a cycle-normalised CSV such as the Grand Challenge PS eTibia files (first column a 0..100
  sample index or percentage, columns ``F_medial_N``, ``F_lateral_N``, ``F_total_magnitude_N``):
  column names are matched loosely (``total`` / ``medial`` / ``lateral``, with or without an
  ``F_`` prefix, a ``_N`` suffix or ``_magnitude``);
* the implant load cells of the Grand Challenge 4th edition subject JW as re-exported by
  AnyBody/knee-grand-challenge-4th (``*_knee_forces.csv``: ``Time(sec), PM, AM, AL, PL, GON,
  GRFz``, units not stated; :func:`read_load_cells`);
* the MATLAB files of the Grand Challenge 6th edition subject DM as distributed by
  fmoissenet/MSK_Delp_U_Ankle (``DM_ngait_og*.mat``: ``Force.KneeMedial``,
  ``Force.KneeLateral`` in N, ``f`` = 120 Hz, ``n`` frames and **no time vector**).

Forces are in N, compressive positive, NaN where a quantity is absent. Fregly BJ et al. (2012)
Grand challenge competition to predict in vivo knee loads. J Orthop Res 30(4):503–513.

**Time of the DM .mat files, established from the data** (:func:`align_dm_trial`). The .mat
holds, besides the forces, the source's inverse-dynamics input: ``Segment(k).Q`` (natural
coordinates u, r_P, r_D, w of foot, shank, thigh, pelvis; ``Segment(1)`` is the force plate,
whose r_P is the centre of pressure), ``Segment(k).rM`` (3 × markers × n: the segment's
markers in m, in the same lab frame as the OpenSim ``.trc``/``.sto`` of
opensim-jam-org/jam-resources) and ``Joint(1).F`` (the ground reaction, with the opposite sign
of the ``.sto``'s ``ground_force_*_v``). Each .mat marker is matched against every ``.trc``
marker at every whole-frame offset (RMS distance); 12 of the 16 .mat markers match a ``.trc``
marker (R_Heel, R_ToeLateral, R_ToeMedial, R_Shank_Superior/Lateral/Inferior,
R_Thigh_Superior/Lateral/Inferior, R_Asis, L_Asis, Sacral) at one common offset, the other
four are virtual (anatomical) points. Results, .mat frame 0 ↔ ``.trc`` time:

=====  ======  ===============  ================  ==============================
trial  frames  .trc offset      marker RMS        GRF check (``.sto``, 1200 Hz)
=====  ======  ===============  ================  ==============================
og1    146     199 → 2.40833 s  2.59 mm (±1: 11)  plate 1, 2.40500 s, RMS 4.9 N
og3    155     33 → 2.47500 s   2.51 mm (±1: 11)  plate 2, 2.47583 s, RMS 7.1 N
og4    149     103 → 3.08333 s  2.64 mm (±1: 11)  plate 2, 3.07917 s, RMS 4.8 N
=====  ======  ===============  ================  ==============================

The minimum is sharp (the neighbouring offsets give ≈ 11 mm); a sub-frame shift does not
lower the marker residual (best shift 0 ms in ±10 ms), and a 6 Hz low-pass of the ``.trc``
lowers it to 1.5–1.7 mm (the source's markers are smoothed). The ground reaction, matched
independently at the ``.sto``'s 1200 Hz against the right-foot plate, agrees within half a
frame (≤ 4.2 ms). Each trial is one right-leg gait cycle from heel strike (the right plate's
load rises from ≈ 20 N at frame 0 and ends at 60–63 % of the frames).

**The DM EMG fields** (for MVC normalisation; established from og1/og3/og4):
``Emg.<m>_raw`` is already an envelope at 120 Hz (non-negative apart from ≤ 2.6 % slightly
negative samples of filter overshoot; raw EMG would be bipolar and sampled at ≥ 1200 Hz);
``Emg.<m>`` is a zero-lag low-pass of it **in the same units, not normalised**: a 2nd-order
Butterworth at ≈ 8 Hz applied to ``_raw`` reproduces it with gain 0.99–1.00 and 9–13 %
relative RMS residual, mean(Emg)/mean(raw) = 0.95–1.06, cross-correlation lag 0. ``Mvc.<m>``
is one scalar per muscle, identical in the three trials and in the same units as ``Emg``
(e.g. vaslat: Mvc 0.286, peak Emg 0.29–0.33): %MVC is therefore ``Emg.<m> / Mvc.<m>``, but
these ratios reach 9.5 (addmagnus) and 11.3 (gmax) in normal walking and 1.02–1.83 for
semimem, vasmed, vaslat, rf, tfl and soleus, so the Mvc values are not maximal for every
muscle: check before using them as activations (cap, or normalise by the session peak).

**Peak measured forces** (body weight 70 kg × g): og1 medial 1.20, lateral 1.41, total 2.58 BW;
og3 1.19, 1.32, 2.50 BW; og4 1.38, 1.36, 2.75 BW. ``total`` for these files is
medial + lateral, the axial (superior–inferior) force: it equals the source's raw
``Force.raw.F_SI`` within 1.9 N; the 3-D magnitude is not available (no anterior shear).
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from msk.exceptions import FileFormatError, MissingDataError
from msk.io.opensim_files import read_sto, read_trc
from msk.io.tables import read_csv_table
from msk.units import G0, Array

__all__ = [
    "DMAlignment",
    "MeasuredContact",
    "align_dm_trial",
    "read_dm_mat",
    "read_load_cells",
    "read_measured_contact",
    "total_component",
]


@dataclass(frozen=True)
class MeasuredContact:
    """Measured tibiofemoral contact force (N, compressive positive, NaN where absent).

    Exactly one of ``time`` (s, in the motion files' time base) and ``cycle_fraction``
    (0..1 over the normalised interval) is set.

    Attributes:
        total, medial, lateral: (N,) forces in N.
        time: (N,) s, or ``None``.
        cycle_fraction: (N,) 0..1, or ``None``.
        source: where the values come from (file, columns, alignment).
        metadata: extra facts (e.g. the :class:`DMAlignment` as a dict).
        component: what ``total`` measures: ``"axial"`` (along the tibia's long axis, the
            plateau normal: an implant's load cells, medial + lateral), ``"magnitude"`` (the
            3-D force's magnitude: the eTibia's "total") or ``"unstated"`` (compared as a
            magnitude); :func:`total_component` decides it for a file.
    """

    total: Array
    medial: Array
    lateral: Array
    time: Array | None = None
    cycle_fraction: Array | None = None
    source: str = ""
    metadata: Mapping[str, Any] = field(default_factory=dict)
    component: str = "unstated"

    def __post_init__(self) -> None:
        if (self.time is None) == (self.cycle_fraction is None):
            raise FileFormatError(
                f"{self.source}: measured contact needs exactly one of time / cycle_fraction"
            )
        axis = self.time if self.time is not None else self.cycle_fraction
        n = np.asarray(axis).shape[0]
        for name in ("total", "medial", "lateral"):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != (n,):
                raise FileFormatError(f"{self.source}: {name} has shape {v.shape}, expected ({n},)")

    @property
    def n_frames(self) -> int:
        return int(np.asarray(self.total).shape[0])

    @property
    def values(self) -> Array:
        """(N, 3) columns total, medial, lateral (N)."""
        return np.stack([self.total, self.medial, self.lateral], axis=1)

    def in_body_weights(self, mass_kg: float) -> Array:
        """(N, 3) total, medial, lateral divided by ``mass_kg`` × g."""
        if not (np.isfinite(mass_kg) and mass_kg > 0):
            raise MissingDataError(f"body mass must be > 0 kg, got {mass_kg!r}")
        return self.values / (mass_kg * G0)


# ---------------------------------------------------------------------------------------------
# CSV
# ---------------------------------------------------------------------------------------------
_ROLE_NAMES = {
    "total": ("total", "total_magnitude", "magnitude", "resultant", "total_force"),
    "medial": ("medial", "med", "medial_force"),
    "lateral": ("lateral", "lat", "lateral_force"),
}


def _normalise(name: str) -> str:
    s = name.strip().lower()
    s = re.sub(r"\s*\((n|newton|newtons)\)$", "", s)
    s = re.sub(r"^f_|^force_", "", s)
    s = re.sub(r"_(n|newton|newtons)$", "", s)
    return s


def _find(columns: Sequence[str], role: str, given: str | None, path: Path) -> int | None:
    if given is not None:
        if given not in columns:
            raise MissingDataError(f"{path}: no column {given!r} (has {list(columns)})")
        return columns.index(given)
    hits = [i for i, c in enumerate(columns) if _normalise(c) in _ROLE_NAMES[role]]
    if len(hits) > 1:
        raise FileFormatError(
            f"{path}: several {role} columns {[columns[i] for i in hits]}; name one explicitly"
        )
    return hits[0] if hits else None


#: pound-force in newtons
LBF_N = 4.4482216152605
#: the four load cells of the Grand Challenge eTibia (posteromedial, anteromedial, anterolateral,
#: posterolateral)
LOAD_CELLS = ("PM", "AM", "AL", "PL")


def read_load_cells(path: str | Path) -> MeasuredContact:
    """The total axial tibial force of the Grand Challenge 4th edition subject JW: the sum of the
    eTibia's four load cells ``PM + AM + AL + PL`` of a ``*_knee_forces.csv`` (time column
    ``Time(sec)``, the C3D's time base), in **pound-force**, converted to N.

    The file states no unit; pound-force is established from the data (jw_ngait_og3): the sum
    never falls below the inverse-dynamics knee reaction without muscles (a lower bound of the
    compressive contact force: muscles only add to it) on any frame whose ground reaction is
    measured, and peaks at 2.48 BW in stance and 0.2–0.4 BW in swing in lbf (in N it would be
    0.06 BW, below the bound everywhere; in kgf 5.5 BW). The file's ``GON`` is the knee
    goniometer in degrees (r 0.996 with the C3D's ``goniometer`` channel, same time base).
    Medial and lateral are NaN: they need the load cells' and condyles' positions, which the
    file does not give (a force on one condyle loads all four cells)."""
    path = Path(path)
    tab = read_csv_table(path, time_column="Time(sec)")
    missing = [c for c in LOAD_CELLS if c not in tab.columns]
    if missing:
        raise FileFormatError(f"{path}: no column {missing[0]!r} (load-cell file: {tab.columns})")
    if tab.time.size < 2:
        raise MissingDataError(f"{path}: no load-cell samples")
    t = tab.time
    if not (np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)):
        raise FileFormatError(f"{path}: Time(sec) is not increasing")
    total = tab.data[:, [tab.columns.index(c) for c in LOAD_CELLS]].sum(axis=1) * LBF_N
    nan = np.full(t.size, np.nan)
    return MeasuredContact(
        total, nan, nan.copy(), time=t,
        source=f"{path.name} (PM+AM+AL+PL load cells, lbf → N)", component="axial",
    )  # fmt: skip


def _is_load_cell_file(path: Path) -> bool:
    with path.open(encoding="utf-8", errors="replace") as fh:
        head = {c.strip() for c in fh.readline().split(",")}
    return set(LOAD_CELLS) <= head


def _read_csv(
    path: Path, total: str | None, medial: str | None, lateral: str | None
) -> MeasuredContact:
    if (total, medial, lateral) == (None, None, None) and _is_load_cell_file(path):
        return read_load_cells(path)
    tab = read_csv_table(path, time_column=None)
    if tab.time.size < 2:
        raise MissingDataError(f"{path}: no contact-force samples")
    head = path.read_text(encoding="utf-8").splitlines()[0].split(",")[0].strip()
    cols = list(tab.columns)
    idx = {
        r: _find(cols, r, g, path)
        for r, g in (("total", total), ("medial", medial), ("lateral", lateral))
    }
    if all(i is None for i in idx.values()):
        raise MissingDataError(
            f"{path}: no total / medial / lateral column among {cols} (name them explicitly)"
        )
    nan = np.full(tab.time.size, np.nan)
    vals = {r: (tab.data[:, i].copy() if i is not None else nan.copy()) for r, i in idx.items()}
    used = ", ".join(f"{r}={cols[i]}" for r, i in idx.items() if i is not None)
    comp = total_component(
        None if idx["total"] is None else cols[idx["total"]], vals["total"], vals["medial"],
        vals["lateral"],
    )  # fmt: skip
    x = tab.time
    if re.fullmatch(r"(?i)time(_s)?", head):
        if not np.all(np.diff(x) > 0):
            raise FileFormatError(f"{path}: time column is not increasing")
        return MeasuredContact(
            vals["total"],
            vals["medial"],
            vals["lateral"],
            time=x.copy(),
            source=f"{path.name} ({used})",
            component=comp,
        )
    if not np.all(np.diff(x) > 0):
        raise FileFormatError(f"{path}: first column {head!r} is not increasing")
    frac = (x - x[0]) / (x[-1] - x[0])
    return MeasuredContact(
        vals["total"],
        vals["medial"],
        vals["lateral"],
        cycle_fraction=frac,
        source=f"{path.name} (cycle-normalised by {head!r}; {used})",
        component=comp,
    )


# ---------------------------------------------------------------------------------------------
# DM .mat files (Grand Challenge 6, fmoissenet/MSK_Delp_U_Ankle)
# ---------------------------------------------------------------------------------------------
def _loadmat(path: Path) -> dict[str, Any]:
    from scipy.io import loadmat

    if not path.is_file():
        raise FileFormatError(f"{path}: no such file")
    try:
        return loadmat(path, squeeze_me=True, struct_as_record=False)
    except Exception as exc:  # scipy raises several types for non-MAT input
        raise FileFormatError(f"{path}: not a readable MATLAB file: {exc}") from None


def read_dm_mat(path: str | Path) -> dict[str, Any]:
    """The fields of a DM ``.mat`` file this module uses: ``medial``, ``lateral`` (N,) N,
    ``rate_hz``, ``n``, ``mass_kg``, ``markers`` (n, K, 3) m (all ``Segment(k).rM``),
    ``marker_ids`` ((segment, index) per column) and ``grf`` (n, 3) N (``Joint(1).F``)."""
    path = Path(path)
    d = _loadmat(path)
    try:
        force = d["Force"]
        medial = np.asarray(force.KneeMedial, dtype=float).reshape(-1)
        lateral = np.asarray(force.KneeLateral, dtype=float).reshape(-1)
        rate = float(d["f"])
        n = int(d["n"])
    except (KeyError, AttributeError) as exc:
        raise FileFormatError(f"{path}: not a DM contact-force file (missing {exc})") from None
    if medial.shape != (n,) or lateral.shape != (n,):
        raise FileFormatError(f"{path}: Force.KneeMedial/KneeLateral are not {n} frames long")
    markers, ids = [], []
    for k, seg in enumerate(np.atleast_1d(d.get("Segment", []))):
        rm = np.asarray(getattr(seg, "rM", np.zeros(0)), dtype=float)
        if rm.ndim == 2 and rm.shape[0] == 3:
            rm = rm[:, None, :]
        if rm.ndim != 3 or rm.shape[0] != 3 or rm.shape[2] != n:
            continue
        for j in range(rm.shape[1]):
            markers.append(rm[:, j, :].T)
            ids.append((k + 1, j + 1))  # MATLAB indices
    grf = None
    joint = d.get("Joint")
    if joint is not None:
        first = np.atleast_1d(joint)[0]
        f = np.asarray(getattr(first, "F", np.zeros(0)), dtype=float)
        if f.shape == (3, n):
            grf = f.T
    return {
        "medial": medial,
        "lateral": lateral,
        "rate_hz": rate,
        "n": n,
        "mass_kg": float(d["mass"]) if "mass" in d else float("nan"),
        "markers": np.stack(markers, axis=1) if markers else np.zeros((n, 0, 3)),
        "marker_ids": tuple(ids),
        "grf": grf,
    }


@dataclass(frozen=True)
class DMAlignment:
    """Time of a DM ``.mat`` file in the time base of its ``.trc``, found by its markers.

    Attributes:
        start_time_s: ``.trc`` time of the .mat's frame 0 (s).
        offset_frames: ``.trc`` row of the .mat's frame 0.
        rate_hz, n_frames: the .mat's sampling (``time = start + k / rate``).
        marker_rms_m: RMS distance of the matched markers at that offset (m).
        neighbour_rms_m: the same at offset ± 1 frame (the smaller): sharpness of the match.
        matches: (segment, marker index (MATLAB, 1-based), ``.trc`` label, RMS m) per matched
            .mat marker.
        time: (n,) ``.trc`` time of each .mat frame (s).
        grf_start_time_s, grf_rms_n, grf_plate: independent check against the ``.sto``
            ground reaction (``Joint(1).F`` vs the best plate, at the ``.sto``'s rate), or NaN.
    """

    start_time_s: float
    offset_frames: int
    rate_hz: float
    n_frames: int
    marker_rms_m: float
    neighbour_rms_m: float
    matches: tuple[tuple[int, int, str, float], ...]
    time: Array
    grf_start_time_s: float = float("nan")
    grf_rms_n: float = float("nan")
    grf_plate: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {
            "start_time_s": self.start_time_s,
            "offset_frames": self.offset_frames,
            "rate_hz": self.rate_hz,
            "n_frames": self.n_frames,
            "marker_rms_m": self.marker_rms_m,
            "neighbour_rms_m": self.neighbour_rms_m,
            "matches": [list(m) for m in self.matches],
            "grf_start_time_s": self.grf_start_time_s,
            "grf_rms_n": self.grf_rms_n,
            "grf_plate": self.grf_plate,
        }


def _window_rms(x: Array, y: Array) -> tuple[Array, Array]:
    """RMS distance between ``y`` (n, 3) and every length-n window of every marker of ``x``
    (T, M, 3; NaN = missing): (O, M) RMS and (O, M) number of frames compared."""
    n = y.shape[0]
    w = np.asarray(np.isfinite(x).all(axis=2))
    x0 = np.where(w[..., None], x, 0.0)
    wf = w.astype(float)
    sx = sliding_window_view(x0, n, axis=0)  # (O, M, 3, n)
    sw = sliding_window_view(wf, n, axis=0)  # (O, M, n)
    yy = np.sum(y * y, axis=1)  # (n,)
    cnt = sw.sum(axis=2)
    xx = sliding_window_view(np.sum(x0 * x0, axis=2), n, axis=0).sum(axis=2)
    xy = np.einsum("omak,ka->om", sx, y)
    ssq = xx - 2.0 * xy + np.einsum("omk,k->om", sw, yy)
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt(np.maximum(ssq, 0.0) / cnt)
    rms[cnt < 0.8 * n] = np.inf
    return rms, cnt


def align_dm_trial(
    mat: str | Path,
    trc: str | Path,
    *,
    grf: str | Path | None = None,
    max_marker_rms_m: float = 0.010,
    min_markers: int = 3,
) -> DMAlignment:
    """Find where a DM ``.mat`` file sits in the time base of its ``.trc`` (module docstring).

    Every .mat marker (``Segment(k).rM``) is compared with every ``.trc`` marker at every
    whole-frame offset; markers whose best match is within ``max_marker_rms_m`` vote for their
    offset, the most voted offset wins (at least ``min_markers`` votes) and the reported
    residual is the RMS over the voting markers. With ``grf`` (the trial's ``.sto``) the
    ground reaction ``Joint(1).F`` is matched too, at the ``.sto``'s rate, against each plate
    (``*_vx/_vy/_vz`` columns), as an independent check.

    Raises:
        MissingDataError: no consistent marker match.
    """
    mat, trc = Path(mat), Path(trc)
    dm = read_dm_mat(mat)
    tab = read_trc(trc)
    if not np.isclose(tab.rate_hz, dm["rate_hz"], rtol=1e-3):
        raise MissingDataError(
            f"{trc}: {tab.rate_hz} Hz, but {mat.name} is sampled at {dm['rate_hz']} Hz"
        )
    x = np.array(tab.markers, dtype=float)
    x[np.all(x == 0.0, axis=2)] = np.nan  # TRC writers put 0 0 0 for a missing marker
    n = dm["n"]
    if x.shape[0] < n:
        raise MissingDataError(f"{trc}: {x.shape[0]} frames, fewer than the .mat's {n}")
    y_all = dm["markers"]
    best = []
    for j in range(y_all.shape[1]):
        y = y_all[:, j]
        if not np.isfinite(y).all():
            continue
        rms, _ = _window_rms(x, y)
        o, m = np.unravel_index(int(np.argmin(rms)), rms.shape)
        best.append((j, int(o), int(m), float(rms[o, m])))
    good = [b for b in best if b[3] <= max_marker_rms_m]
    if not good:
        raise MissingDataError(
            f"{mat.name}: no marker matches {trc.name} within {max_marker_rms_m * 1e3:g} mm"
        )
    offsets, votes = np.unique([b[1] for b in good], return_counts=True)
    off = int(offsets[np.argmax(votes)])
    chosen = [b for b in good if b[1] == off]
    if len(chosen) < min_markers:
        raise MissingDataError(
            f"{mat.name}: only {len(chosen)} markers agree on an offset into {trc.name} "
            f"(need {min_markers}; votes {dict(zip(offsets.tolist(), votes.tolist()))})"
        )

    def rms_at(o: int) -> float:
        if o < 0 or o + n > x.shape[0]:
            return float("inf")
        e = [x[o : o + n, m] - y_all[:, j] for j, _, m, _ in chosen]
        d2 = np.concatenate([np.sum(v * v, axis=1) for v in e])
        return float(np.sqrt(np.nanmean(d2)))

    ids = dm["marker_ids"]
    matches = tuple((ids[j][0], ids[j][1], tab.labels[m], r) for j, _, m, r in chosen)
    grf_t, grf_rms, plate = float("nan"), float("nan"), ""
    if grf is not None and dm["grf"] is not None:
        grf_t, grf_rms, plate = _match_grf(Path(grf), dm["grf"], dm["rate_hz"])
    return DMAlignment(
        start_time_s=float(tab.time[off]),
        offset_frames=off,
        rate_hz=dm["rate_hz"],
        n_frames=n,
        marker_rms_m=rms_at(off),
        neighbour_rms_m=min(rms_at(off - 1), rms_at(off + 1)),
        matches=matches,
        time=np.array(tab.time[off : off + n], dtype=float),
        grf_start_time_s=grf_t,
        grf_rms_n=grf_rms,
        grf_plate=plate,
    )


def _match_grf(path: Path, f_mat: Array, rate_hz: float) -> tuple[float, float, str]:
    """Best (start time, RMS N, plate prefix) of ``−Joint(1).F`` against the ``.sto`` plates."""
    sto = read_sto(path)
    step = round(sto.rate_hz / rate_hz)
    if step < 1 or not np.isclose(sto.rate_hz, step * rate_hz, rtol=1e-3):
        raise MissingDataError(f"{path}: {sto.rate_hz:.6g} Hz is not a multiple of {rate_hz} Hz")
    prefixes = sorted({c[:-3] for c in sto.columns if re.search(r"_v[xyz]$", c)})
    n = f_mat.shape[0]
    span = step * (n - 1) + 1
    out = (float("nan"), float("inf"), "")
    for p in prefixes:
        try:
            g = np.stack([sto.column(f"{p}_v{a}") for a in "xyz"], axis=1)
        except MissingDataError:
            continue
        if g.shape[0] < span:
            continue
        win = sliding_window_view(np.nan_to_num(g), span, axis=0)[:, :, ::step]  # (L, 3, n)
        err = win + f_mat.T[None]  # the .mat's Joint(1).F is minus the plate's reaction
        rms = np.sqrt(np.mean(np.sum(err * err, axis=1), axis=1))
        k = int(np.argmin(rms))
        if rms[k] < out[1]:
            out = (float(sto.time[k]), float(rms[k]), p)
    return out


def _read_mat(path: Path, trial: Path | None, grf: Path | None) -> MeasuredContact:
    dm = read_dm_mat(path)
    medial, lateral = dm["medial"], dm["lateral"]
    total = medial + lateral
    meta: dict[str, Any] = {"mass_kg": dm["mass_kg"], "total_kind": "axial (medial + lateral)"}
    if trial is None:
        meta["aligned"] = False
        return MeasuredContact(
            total,
            medial,
            lateral,
            time=np.arange(dm["n"]) / dm["rate_hz"],
            source=f"{path.name} (NOT aligned: time from the file's first frame)",
            metadata=meta,
            component="axial",
        )
    al = align_dm_trial(path, trial, grf=grf)
    meta.update(aligned=True, alignment=al.as_dict())
    return MeasuredContact(
        total,
        medial,
        lateral,
        time=al.time,
        source=(
            f"{path.name} aligned to {Path(trial).name} by {len(al.matches)} markers: "
            f"frame 0 = {al.start_time_s:.6g} s, RMS {al.marker_rms_m * 1e3:.2f} mm"
        ),
        metadata=meta,
        component="axial",
    )


def total_component(name: str | None, total: Array, medial: Array, lateral: Array) -> str:
    """What a file's total contact force measures (:attr:`MeasuredContact.component`): a
    column named for a magnitude or resultant is ``"magnitude"``; one named axial, or equal to
    medial + lateral (within 1 % of its peak on every frame that has the three) — the axial
    force the two compartments' load cells share — is ``"axial"``; otherwise ``"unstated"``."""
    n = "" if name is None else _normalise(name)
    if "magnitude" in n or "resultant" in n:
        return "magnitude"
    if "axial" in n:
        return "axial"
    t, m, lat = (np.asarray(x, dtype=float) for x in (total, medial, lateral))
    ok = np.isfinite(t) & np.isfinite(m) & np.isfinite(lat)
    if ok.sum() >= 2 and np.abs(t[ok]).max() > 0:
        if np.abs(t[ok] - m[ok] - lat[ok]).max() <= 0.01 * np.abs(t[ok]).max():
            return "axial"
    return "unstated"


def read_measured_contact(
    path: str | Path,
    *,
    trial: str | Path | None = None,
    grf: str | Path | None = None,
    total: str | None = None,
    medial: str | None = None,
    lateral: str | None = None,
) -> MeasuredContact:
    """Read a measured knee contact force (module docstring).

    Args:
        path: a ``.csv`` (first column ``time`` in s, or a cycle index/percentage) or a DM
            ``.mat``.
        trial: for a ``.mat``: the trial's ``.trc``; the time then comes from
            :func:`align_dm_trial`. Without it the time runs from 0 at the file's first frame
            and ``metadata["aligned"]`` is False.
        grf: for a ``.mat`` with ``trial``: the trial's ``.sto`` ground reaction (a check of the
            alignment, in ``metadata["alignment"]``).
        total, medial, lateral: CSV column names when the loose matching is not enough.
    """
    p = Path(path)
    if not p.is_file():
        raise FileFormatError(f"{p}: no such file")
    if p.suffix.lower() == ".mat":
        return _read_mat(
            p, None if trial is None else Path(trial), None if grf is None else Path(grf)
        )
    if p.suffix.lower() in (".csv", ".txt"):
        return _read_csv(p, total, medial, lateral)
    raise FileFormatError(f"{p}: unknown measured-contact format {p.suffix!r} (csv or mat)")
