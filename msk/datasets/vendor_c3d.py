"""Real recordings rewritten as other labs' systems name things, for ``msk init`` → ``msk run``
tests on the kinds of files a new lab brings.

The shared recordings hold Vicon Plug-in Gait (btkdata ``PiG_*_FF``) and a BTS lab's IOR/CAST
walk (MOtoNMS UNIPD). Each writer below reads one of them with :func:`msk.io.read_c3d` and
writes a copy (:func:`msk.io.write_c3d`, markers in mm, plates as type 2 with plate-frame
channels in N and N·mm) whose values are the recording's, cropped to ``frames``, under another
vendor's names:

* :func:`qualisys_ior` — Qualisys Track Manager with the IOR/CAST anatomical set named after
  Van Sint Jan (2007) *Color Atlas of Skeletal Landmark Definitions* (``R_IAS``, ``R_IPS``,
  ``R_FTC``, ``R_FLE``, ``R_FME``, ``R_FAX``, ``R_TTC``, ``R_FAL``, ``R_TAM``, ``R_FCC``,
  ``R_FM1``, ``R_FM2``, ``R_FM5``, ``CV7``, ``LV5``, ``R_SAE``), events ``RHS``/``RTO`` with
  the context ``General``, EMG channels named after muscles (``R Tibialis Anterior``), no
  subject parameters;
* :func:`motion_analysis` — Motion Analysis Cortex with the Helen Hayes set (Kadaba et al.
  1990: ``R.ASIS``, ``V.Sacral``, ``R.Thigh``, ``R.Knee``, ``R.Tibia``, ``R.Ankle``,
  ``R.Heel``, ``R.Toe``), six force plates of which three are stepped on (the other three
  hold amplifier noise), EMG codes ``RREC``…, events ``Right Heel Strike``/``Right Toe Off``,
  no subject parameters and no model outputs;
* :func:`vicon_delsys` — Vicon Nexus Plug-in Gait with a Delsys Trigno: subject-prefixed
  markers (``flatFoot:LASI``), analog labels ``<sensor>.EMG<k>`` of which the first eight name
  a muscle (``R Rectus Femoris.EMG1``) and the others keep the default ``Sensor 9.EMG9``;
* :func:`clusters_epicondyles` — a cluster protocol: four-marker thigh and shank plates moved
  rigidly with Plug-in Gait's own femur and tibia frames (``RFEO``/``RFEA``/``RFEL``/``RFEP``),
  the femoral epicondyles and malleoli on the static only (the medial one mirrored through
  Plug-in Gait's joint centre), pelvis and foot landmarks.

Each returns a :class:`VendorSession` (the static and the task written into ``out``). The
values are real; only the names, the crop and the extra plates are this module's.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from msk.datasets.shared import real_data_dir
from msk.trial import Event, Subject, Trial

__all__ = [
    "VendorSession",
    "clusters_epicondyles",
    "motion_analysis",
    "qualisys_ior",
    "vicon_delsys",
]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class VendorSession:
    """A static and a task trial written under one vendor's names."""

    kind: str
    static: Path
    task: Path


def _src(rel: str) -> Path:
    return real_data_dir() / rel


def _plate_channels(
    trial: Trial, a: slice, k0: int = 1
) -> tuple[list[Array], list[str], list[str], list[object]]:
    """Type-2 channels (plate frame, N and N·mm about the surface centre) of the trial's plates
    over the analog samples ``a``."""
    from msk.io import PlateSpec

    chans: list[Array] = []
    labels: list[str] = []
    units: list[str] = []
    specs: list[object] = []
    for k, p in enumerate(trial.plates):
        f = np.nan_to_num(np.asarray(p.force[a], dtype=float))
        m = np.nan_to_num(np.asarray(p.moment[a], dtype=float))
        rot = np.asarray(p.rotation, dtype=float)
        names = [f"{c}{k + k0}" for c in ("Fx", "Fy", "Fz", "Mx", "My", "Mz")]
        chans.append(np.column_stack([f @ rot, m @ rot * 1000.0]))
        labels += names
        units += ["N", "N", "N", "Nmm", "Nmm", "Nmm"]
        specs.append(PlateSpec(channels=tuple(names), corners_m=np.asarray(p.corners),
                               origin_m=np.zeros(3)))  # fmt: skip
    return chans, labels, units, specs


def _write(
    path: Path,
    trial: Trial,
    markers: Array,
    labels: list[str],
    frames: slice,
    *,
    emg: dict[str, str] | None = None,
    events: list[Event] | None = None,
    subject: Subject | None = None,
    extra_plates: int = 0,
    seed: int = 0,
) -> Path:
    """``trial`` cropped to ``frames`` with ``markers``/``labels`` (already cropped) and its
    plates; ``emg`` maps the trial's non-plate analog labels kept → the label written."""
    from msk.io import PlateSpec, write_c3d

    ratio = round(trial.analog_rate_hz / trial.point_rate_hz)
    start, stop = frames.start or 0, frames.stop if frames.stop is not None else trial.n_frames
    a = slice(start * ratio, stop * ratio)
    chans, alabels, units, specs = _plate_channels(trial, a)
    rng = np.random.default_rng(seed)
    n_a = stop * ratio - start * ratio
    for j in range(extra_plates):  # unloaded plates beyond the walkway: amplifier noise only
        k = len(trial.plates) + j + 1
        names = [f"{c}{k}" for c in ("Fx", "Fy", "Fz", "Mx", "My", "Mz")]
        chans.append(rng.normal(0.0, [0.5, 0.5, 1.0, 200.0, 200.0, 50.0], size=(n_a, 6)))
        alabels += names
        units += ["N", "N", "N", "Nmm", "Nmm", "Nmm"]
        c0 = np.asarray(trial.plates[-1].corners, dtype=float)
        shift = np.array([0.0, 1.2 * (j + 1), 0.0])
        shift = shift if trial.vertical_axis == 2 else np.array([0.0, 0.0, 1.2 * (j + 1)])
        specs.append(PlateSpec(channels=tuple(names), corners_m=c0 + shift, origin_m=np.zeros(3)))
    if emg:
        idx = [trial.analog_labels.index(lab) for lab in emg]
        chans.append(np.asarray(trial.analogs[a][:, idx], dtype=float))
        alabels += list(emg.values())
        units += ["V"] * len(idx)
    t0 = float(trial.time[start])
    evs = [e for e in (trial.events if events is None else events) if e.time >= t0 - 1e-9]
    first = int(trial.metadata.get("first_frame", 1)) + start
    return write_c3d(
        path,
        markers=markers,
        marker_labels=labels,
        rate_hz=trial.point_rate_hz,
        point_units="mm",
        analogs=np.hstack(chans) if chans else None,
        analog_labels=alabels,
        analog_units=units,
        analog_ratio=ratio,
        plates=specs,  # type: ignore[arg-type]
        events=evs,
        subject=subject,
        first_frame=first,
    )


def _relabel(trial: Trial, names: dict[str, str], frames: slice) -> tuple[Array, list[str]]:
    idx = [trial.marker_labels.index(lab) for lab in names]
    return np.asarray(trial.markers[frames][:, idx], dtype=float), list(names.values())


def _sided(pairs: dict[str, str], lab: str, new: str) -> dict[str, str]:
    """``pairs`` with ``lab`` → ``new`` for both sides (``{s}`` in the templates)."""
    for s_old, s_new in (("R", "R"), ("L", "L")):
        pairs[lab.format(s=s_old)] = new.format(s=s_new)
    return pairs


def qualisys_ior(out: Path, *, frames: slice = slice(60, 288)) -> VendorSession:
    """UNIPD's static and Walking1 (BTS, IOR/CAST) as a Qualisys export (module docstring)."""
    from msk.io import read_c3d

    names: dict[str, str] = {"C7": "CV7", "L5": "LV5"}
    for old, new in (("A", "SAE"), ("PSIS", "IPS"), ("ASIS", "IAS"), ("GT", "FTC"),
                     ("LE", "FLE"), ("ME", "FME"), ("HF", "FAX"), ("TT", "TTC"), ("LM", "FAL"),
                     ("MM", "TAM"), ("CA", "FCC"), ("VMH", "FM5"), ("IMH", "FM1"),
                     ("IIT", "FM2")):  # fmt: skip
        _sided(names, "{s}" + old, "{s}_" + new)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for fname, crop in (("Static1.c3d", slice(None)), ("Walking1.c3d", frames)):
        tr = read_c3d(_src(f"motonms-testdata/UNIPD/{fname}"))
        mk, labs = _relabel(tr, names, crop)
        plate_ch = {c for p in tr.plates for c in p.channels}
        emg = {
            lab: lab.replace("Right ", "R ").replace("Left ", "L ").title()
            for lab in tr.analog_labels
            if lab not in plate_ch
        }
        evs = [
            Event(f"{e.context[0]}{'HS' if e.label == 'Foot Strike' else 'TO'}", "General", e.time)
            for e in tr.events
        ]
        written.append(
            _write(out / f"qtm_{fname}", tr, mk, labs, crop, emg=emg, events=evs, subject=None)
        )
    return VendorSession("qualisys", written[0], written[1])


#: Plug-in Gait label stem → Helen Hayes (Motion Analysis) label stem
_HELEN_HAYES = {"ASI": "ASIS", "THI": "Thigh", "KNE": "Knee", "TIB": "Tibia", "ANK": "Ankle",
                "HEE": "Heel", "TOE": "Toe"}  # fmt: skip
_MA_EMG = ("RREC", "LREC", "RVAS", "LVAS", "RBIC", "LBIC", "RTIB", "LTIB", "RSOL", "LSOL",
           "RGAS", "LGAS")  # fmt: skip


def _pig(fname: str) -> Trial:
    from msk.io import read_c3d

    return read_c3d(_src(f"btkdata/{fname}"))


def motion_analysis(out: Path, *, frames: slice = slice(0, 200)) -> VendorSession:
    """btkdata's Plug-in Gait static and walk as a Motion Analysis Cortex export with the Helen
    Hayes set and six plates (module docstring)."""
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for fname, crop in (("PiG_Calibration3_FF.c3d", slice(None)), ("PiG_Motion3_FF.c3d", frames)):
        tr = _pig(fname)
        names: dict[str, str] = {}
        for old, new in _HELEN_HAYES.items():
            _sided(names, "{s}" + old, "{s}." + new)
        mk, labs = _relabel(tr, names, crop)
        psis = [tr.marker_labels.index(lab) for lab in ("LPSI", "RPSI")]
        sacral = np.asarray(tr.markers[crop][:, psis], dtype=float).mean(axis=1)
        mk = np.concatenate([mk, sacral[:, None]], axis=1)
        labs.append("V.Sacral")
        plate_ch = {c for p in tr.plates for c in p.channels}
        others = [lab for lab in tr.analog_labels if lab not in plate_ch]
        emg = dict(zip(others, _MA_EMG, strict=False))
        evs = [
            Event(
                f"{e.context} {'Heel Strike' if e.label == 'Foot Strike' else 'Toe Off'}",
                "",
                e.time,
            )
            for e in tr.events
        ]
        extra = 6 - len(tr.plates) if tr.plates else 0
        written.append(_write(out / f"ma_{fname}", tr, mk, labs, crop, emg=emg, events=evs,
                              extra_plates=extra))  # fmt: skip
    return VendorSession("motion_analysis", written[0], written[1])


_DELSYS_MUSCLES = ("R Rectus Femoris", "R Vastus Lateralis", "R Biceps Femoris",
                   "R Semitendinosus", "R Tibialis Anterior", "R Gastrocnemius Medialis",
                   "R Soleus", "R Gluteus Medius")  # fmt: skip


def vicon_delsys(out: Path, *, frames: slice = slice(0, 170)) -> VendorSession:
    """btkdata's Plug-in Gait static and walk as Vicon Nexus writes them with a Delsys Trigno
    (module docstring)."""
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for fname, crop in (("PiG_Calibration3_FF.c3d", slice(None)), ("PiG_Motion3_FF.c3d", frames)):
        tr = _pig(fname)
        keep = [lab for lab in tr.marker_labels if not lab.startswith("*")]
        names = {lab: f"{tr.subject.name}:{lab}" for lab in keep}
        mk, labs = _relabel(tr, names, crop)
        plate_ch = {c for p in tr.plates for c in p.channels}
        others = [lab for lab in tr.analog_labels if lab not in plate_ch]
        emg = {
            lab: (
                f"{_DELSYS_MUSCLES[k]}.EMG{k + 1}"
                if k < len(_DELSYS_MUSCLES)
                else f"Sensor {k + 1}.EMG{k + 1}"
            )
            for k, lab in enumerate(others)
        }
        written.append(_write(out / f"nexus_{fname}", tr, mk, labs, crop, emg=emg,
                              subject=tr.subject))  # fmt: skip
    return VendorSession("vicon_delsys", written[0], written[1])


def _frame(tr: Trial, stem: str, crop: slice) -> tuple[Array, Array]:
    """Origin (N, 3) and rotation (N, 3, 3), columns anterior, lateral, proximal, of a Plug-in
    Gait segment from its virtual points ``<stem>O/A/L/P``."""
    get = {c: np.asarray(tr.marker(f"{stem}{c}")[crop], dtype=float) for c in "OALP"}
    o = get["O"]
    p = get["P"] - o
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    a = get["A"] - o
    a -= np.einsum("ni,ni->n", a, p)[:, None] * p
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    lat = np.cross(p, a)
    return o, np.stack([a, lat, p], axis=2)


#: cluster marker offsets (m) in the segment frame (anterior, lateral, proximal) from the
#: distal joint centre: a rigid 4-marker plate on the lateral side of the thigh / shank
_CLUSTER = np.array([[0.03, 0.09, 0.14], [0.03, 0.09, 0.22], [-0.03, 0.09, 0.14],
                     [-0.03, 0.09, 0.22]])  # fmt: skip


def clusters_epicondyles(out: Path, *, frames: slice = slice(0, 170)) -> VendorSession:
    """btkdata's Plug-in Gait static and walk as a cluster protocol with epicondyles and
    malleoli on the static (module docstring)."""
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for fname, crop in (("PiG_Calibration3_FF.c3d", slice(None)), ("PiG_Motion3_FF.c3d", frames)):
        static = "Calibration" in fname
        tr = _pig(fname)
        names = {"RASI": "RASIS", "LASI": "LASIS", "RPSI": "RPSIS", "LPSI": "LPSIS",
                 "RHEE": "RHeel", "LHEE": "LHeel", "RTOE": "RMT2", "LTOE": "LMT2"}  # fmt: skip
        mk, labs = _relabel(tr, names, crop)
        cols = [mk]
        for s in ("R", "L"):
            for seg, name, centre_lat in (("FE", "Thigh", "KNE"), ("TI", "Shank", "ANK")):
                o, rot = _frame(tr, f"{s}{seg}", crop)
                lat_pt = np.asarray(tr.marker(f"{s}{centre_lat}")[crop], dtype=float)
                # the frame's lateral axis points to the subject's left on both legs: mirror
                sign = np.sign(np.nanmedian(np.einsum("ni,ni->n", lat_pt - o, rot[:, :, 1])))
                off = _CLUSTER * np.array([1.0, sign, 1.0])
                cl = o[:, None, :] + np.einsum("nij,kj->nki", rot, off)
                cols.append(cl)
                labs += [f"{s}{name}{k + 1}" for k in range(len(off))]
                if static:
                    which = "Epicondyle" if seg == "FE" else "Malleolus"
                    cols.append(np.stack([lat_pt, 2.0 * o - lat_pt], axis=1))
                    labs += [f"{s}Lat{which}", f"{s}Med{which}"]
        written.append(_write(out / f"cluster_{fname}", tr, np.concatenate(cols, axis=1), labs,
                              crop, emg={}, subject=tr.subject))  # fmt: skip
    return VendorSession("clusters_epicondyles", written[0], written[1])
