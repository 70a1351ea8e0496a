"""Recognising a lab's marker set: which lab label is which model marker.

Labs name the same bony landmark differently (``RKNE``, ``RKneeLateral``, ``R_Knee_Lateral``,
``R.Knee.Lat``, ``RLE``, ``JW:RKneeLateral``). :func:`recognise` reads every label as
*(side, landmark)* and pairs a lab label with a model marker only when both name the **same
anatomical landmark** on the same side. The label grammar:

1. a subject prefix ``XX:`` is dropped (Vicon Nexus writes ``JW:RAsis`` when a subject is
   named);
2. points that are not markers are *excluded* with a reason: Vicon's unlabelled trajectories
   (``*12``), model outputs (Plug-in Gait's virtual points ``PELO``, ``LFEA``…, angles, forces,
   moments, powers, computed joint centres ``LeftHipCenter``, ``RShoulderCenter``), the lab's
   axes / calibration markers (``Oglobal``, ``Xglobal``…), and arm or head markers when the
   model has no such segment;
3. the side is read from a ``Right``/``Left`` word, a ``R``/``L`` letter followed by a separator
   (``R_``, ``R.``, ``r ``), a trailing ``_R``, or a leading capital ``R``/``L`` glued to the
   name (``RAsis``, ``RKNE``, ``RankleMedial``, IOR/CAST's ``RLE``);
4. the rest, lower-cased without separators (``Knee_Lateral`` → ``kneelateral``), is looked up in
   a synonym table per landmark (:data:`LANDMARKS`, :data:`SIDED_SYNONYMS`,
   :data:`MIDLINE_SYNONYMS`).

Model marker names go through the same grammar (gait2392's ``R.Knee.Lat`` → (R, lateral femoral
epicondyle)); a model marker that names no landmark (technical markers such as gait2392's
``R.Thigh.Upper``) is only paired with a lab label of exactly its name (OpenSim subject01).

Where gait2392 puts its markers (``msk/data/models/gait2392.toml``, offsets in the calcaneus frame,
whose origin is at the back of the heel; the MTP joint is 0.18 m ahead) decided the foot:

* ``R.Heel`` (−0.02, 0.02, 0): back of the calcaneus = Plug-in Gait ``HEE``, ``CAL``, IOR ``CA``;
* ``R.Toe.Med`` / ``R.Toe.Lat`` (0.19, ·, ∓0.04/0.065): 1st / 5th metatarsal heads (``MT1``,
  ``IMH``, ``ToeMedial``; ``MT5``, ``VMH``, ``ToeLateral``);
* ``R.Toe.Tip`` (0.26, 0.005, 0): the tip of the toes, 7–8 cm ahead of the metatarsal heads.
  The Grand Challenge ``RToe`` is there (0.318 m from ``RHeel`` on PS's static, 5 cm ahead of
  ``RToeMedial``) and so are OpenSim's / Rajagopal's ``R.Toe`` (toes body, 9 cm ahead of the
  MTP joint). **Plug-in Gait's ``RTOE`` is not**: it sits on the 2nd metatarsal head, on the
  dorsum (Vicon Plug-in Gait marker placement), ~7 cm behind the toe tip; pairing it with
  ``R.Toe.Tip`` would shorten the foot to ~0.7 and tilt it in IK. An all-capitals ``TOE``
  (Plug-in Gait's code) is therefore read as the 2nd metatarsal head, which gait2392 lacks:
  it stays unmatched and is placed on the foot from the static trial (or the motion). So is the
  Helen Hayes set's ``R.Toe`` (Kadaba MP, Ramakrishnan HK, Wootten ME 1990 J Orthop Res
  8:383–392: over the 2nd metatarsal head) when the labels are that set (``V.Sacral`` with
  bare ``Knee``/``Ankle``/``Heel`` words, as Motion Analysis writes them).
* ``R.Midfoot.Sup`` / ``R.Midfoot.Lat``: the Grand Challenge's ``MidfootSuperior`` /
  ``MidfootLateral`` (same names, same protocol: the gait2392 set was drawn for it).

Knee and ankle: a bare ``KNE``/``Knee`` is the lateral femoral epicondyle (Plug-in Gait,
Rajagopal's ``R.Knee``), ``ANK``/``Ankle`` the lateral malleolus; ``LE``/``ME`` (IOR/CAST,
Cappozzo et al. 1995 Clin Biomech 10:171) the lateral/medial epicondyles, ``LM``/``MM`` the
malleoli. The landmark codes of Van Sint Jan (2007) *Color Atlas of Skeletal Landmark
Definitions* (Qualisys' IOR/CAST sets write them ``R_IAS``, ``L_FLE``…) are synonyms:
``IAS``/``IPS`` the iliac spines, ``FTC`` the greater trochanter, ``FLE``/``FME`` the
epicondyles, ``FAX`` the fibular head, ``TTC`` the tibial tuberosity, ``FAL``/``TAM`` the
malleoli, ``FCC`` the calcaneus, ``FM1``/``FM2``/``FM5`` the metatarsal heads, ``SAE`` the
acromion, ``CV7``, ``TV10``, ``LV5``, ``SJN``/``SXS`` the jugular notch / xiphoid.
Sternum: gait2392's ``Sternum`` is 0.14 m below the acromia, on the body of the
sternum, as the Grand Challenge ``Sternum``; Plug-in Gait's ``STRN`` and the Grand Challenge
``Xiphoid`` are on the xiphoid process, 0.15 m lower, and stay unmatched. Acromion: ``SHO``
(Plug-in Gait: acromio-clavicular joint), ``ACR``, IOR's ``A``; a "Shoulder" word marker
(Grand Challenge, Rajagopal) is not paired (7–9 cm from gait2392's ``R.Acromium`` after
scaling on PS's static): it is placed. Pelvis: ``SACR``,
``Sacral``, ``S2``, ``V.Sacral`` are the sacrum; ``L5`` (a lumbar spinous process) is not.
The greater trochanter, fibular head, tibial tuberosity, patella, 2nd metatarsal head, hindfoot,
medial midfoot and all thigh/shank cluster markers have no gait2392 marker: they are unmatched,
for marker placement (:func:`msk.personalise.scaling.place_markers`,
:func:`msk.personalise.scaling.place_markers_from_motion`).

Explicit renames (a session's ``[markers] rename``, model marker → lab label) override all of
this.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.exceptions import ShapeMismatchError

__all__ = [
    "KNEE_SEGMENTS",
    "LANDMARKS",
    "LANDMARK_BODIES",
    "MIDLINE_SYNONYMS",
    "SIDED_SYNONYMS",
    "MarkerSetMatch",
    "ParsedLabel",
    "as_read",
    "foot_markers",
    "is_knee_segment",
    "other_side",
    "parse_label",
    "pelvis_landmarks",
    "recognise",
    "reconstructed_markers",
    "shoulder_girdle_markers",
    "strip_subject_prefix",
    "zeros_as_gaps",
    "zeros_as_gaps_view",
]

#: landmark key → description (anatomical landmarks and marker kinds the grammar recognises)
LANDMARKS: Mapping[str, str] = {
    "asis": "anterior superior iliac spine",
    "psis": "posterior superior iliac spine",
    "sacrum": "sacrum (S2 spinous process / mid-PSIS)",
    "knee_lat": "lateral femoral epicondyle",
    "knee_med": "medial femoral epicondyle",
    "ankle_lat": "lateral malleolus",
    "ankle_med": "medial malleolus",
    "heel": "posterior calcaneus (heel)",
    "toe_tip": "tip of the toes (hallux)",
    "mt1": "1st metatarsal head",
    "mt2": "2nd metatarsal head (Plug-in Gait TOE)",
    "mt5": "5th metatarsal head",
    "midfoot_sup": "dorsum of the midfoot",
    "midfoot_lat": "lateral midfoot",
    "midfoot_med": "medial midfoot",
    "hindfoot": "hindfoot (lateral calcaneus)",
    "gt": "greater trochanter",
    "fib_head": "fibular head",
    "tib_tub": "tibial tuberosity",
    "patella": "patella",
    "acromion": "acromion",
    "clavicle": "clavicle",
    "sternum": "body of the sternum",
    "xiphoid": "xiphoid process",
    "jugular": "jugular notch",
    "c7": "C7 spinous process",
    "t10": "T10 spinous process",
    "spine": "thoracic / lumbar spine",
    "neck": "neck",
    "top_head": "vertex of the head",
    "thigh_cluster": "thigh technical marker",
    "shank_cluster": "shank technical marker",
    "foot_cluster": "foot technical marker",
    "arm": "arm marker",
    "head": "head marker",
}

#: landmark key → the body (gait2392 / OpenSim naming stem, side suffix added for sided
#: landmarks) the bony landmark belongs to: a placement hint for markers without a model marker
#: (a single static pose cannot tell a PSIS from the lumbar spine by distance alone)
LANDMARK_BODIES: Mapping[str, str] = {
    "asis": "pelvis",
    "psis": "pelvis",
    "sacrum": "pelvis",
    "gt": "femur",
    "knee_lat": "femur",
    "knee_med": "femur",
    "thigh_cluster": "femur",
    "fib_head": "tibia",
    "tib_tub": "tibia",
    "ankle_lat": "tibia",
    "ankle_med": "tibia",
    "shank_cluster": "tibia",
    "heel": "calcn",
    "hindfoot": "calcn",
    "midfoot_sup": "calcn",
    "midfoot_lat": "calcn",
    "midfoot_med": "calcn",
    "mt1": "calcn",
    "mt2": "calcn",
    "mt5": "calcn",
    "toe_tip": "toes",
    "c7": "torso",
    "t10": "torso",
    "spine": "torso",
    "sternum": "torso",
    "xiphoid": "torso",
    "jugular": "torso",
    "clavicle": "torso",
    "acromion": "torso",
}

#: the segments across the knee whose markers a label names unambiguously (:data:`LANDMARK_BODIES`:
#: a thigh cluster, the greater trochanter or a femoral epicondyle on the femur; a shank
#: cluster, the fibular head, the tibial tuberosity or a malleolus on the tibia). A knee no
#: marker pins lets a thigh marker look as rigid on the tibia as on the femur, so a placement
#: from the motion must not exchange them
KNEE_SEGMENTS = ("femur", "tibia")


#: normalised name (lower case, no separators, side removed) → landmark key, sided landmarks
SIDED_SYNONYMS: Mapping[str, str] = {
    **dict.fromkeys(("asis", "asi", "antsupiliacspine", "ias"), "asis"),
    **dict.fromkeys(("psis", "psi", "postsupiliacspine", "ips"), "psis"),
    **dict.fromkeys(
        (
            "kneelat",
            "kneelateral",
            "latknee",
            "lateralknee",
            "kne",
            "knee",
            "le",
            "lfe",
            "lke",
            "kneelatepicondyle",
            "latepicondyle",
            "lateralepicondyle",
            "lepi",
            "fle",
        ),
        "knee_lat",
    ),
    **dict.fromkeys(
        (
            "kneemed",
            "kneemedial",
            "medknee",
            "medialknee",
            "knm",
            "kneein",
            "knein",
            "mkne",
            "me",
            "mfe",
            "mke",
            "medepicondyle",
            "medialepicondyle",
            "mepi",
            "kneemedepicondyle",
            "fme",
        ),
        "knee_med",
    ),
    **dict.fromkeys(
        (
            "anklelat",
            "anklelateral",
            "latankle",
            "lateralankle",
            "ank",
            "ankle",
            "lm",
            "lmal",
            "latmal",
            "latmalleolus",
            "lateralmalleolus",
            "lma",
            "fal",
        ),
        "ankle_lat",
    ),
    **dict.fromkeys(
        (
            "anklemed",
            "anklemedial",
            "medankle",
            "medialankle",
            "mm",
            "mmal",
            "medmal",
            "mma",
            "med",
            "anm",
            "ankin",
            "mank",
            "sph",
            "medmalleolus",
            "medialmalleolus",
            "tam",
        ),
        "ankle_med",
    ),
    **dict.fromkeys(("heel", "hee", "ca", "cal", "calc", "calcaneus", "fcc"), "heel"),
    **dict.fromkeys(("toetip", "hallux", "halluxtip", "toe", "ttip"), "toe_tip"),
    **dict.fromkeys(
        ("toemed", "toemedial", "mt1", "mh1", "mfh1", "met1", "fm1", "imh", "mth1"), "mt1"
    ),
    **dict.fromkeys(("mt2", "mh2", "mfh2", "met2", "fm2", "iimh", "mth2"), "mt2"),
    **dict.fromkeys(
        ("toelat", "toelateral", "mt5", "mh5", "mfh5", "met5", "fm5", "vmh", "mth5"), "mt5"
    ),
    **dict.fromkeys(("midfootsup", "midfootsuperior"), "midfoot_sup"),
    **dict.fromkeys(("midfootlat", "midfootlateral"), "midfoot_lat"),
    **dict.fromkeys(("midfootmed", "midfootmedial"), "midfoot_med"),
    "hindfoot": "hindfoot",
    **dict.fromkeys(("gt", "gtr", "troch", "trochanter", "greatertrochanter", "ftc"), "gt"),
    **dict.fromkeys(("hf", "fibhead", "fibularhead", "fibulahead", "fax"), "fib_head"),
    **dict.fromkeys(("tt", "tibtub", "tibialtuberosity", "ttc"), "tib_tub"),
    **dict.fromkeys(("patella", "pat"), "patella"),
    **dict.fromkeys(("acromion", "acromium", "acr", "sho", "a", "ac", "sae"), "acromion"),
    **dict.fromkeys(("clavicle", "cla", "clav"), "clavicle"),
    **dict.fromkeys(("temple", "temp", "fhd", "bhd", "head"), "head"),
}

#: normalised whole label → landmark key, midline landmarks (no side)
MIDLINE_SYNONYMS: Mapping[str, str] = {
    **dict.fromkeys(("sacr", "sacral", "vsacral", "sacrum", "s2", "vsac", "sac", "ms2"), "sacrum"),
    **dict.fromkeys(("sternum", "str", "stern", "sternumbody"), "sternum"),
    **dict.fromkeys(("xiphoid", "xiph", "px", "strn", "sxs"), "xiphoid"),
    **dict.fromkeys(
        ("ij", "clav", "sup", "jugular", "jugularnotch", "suprasternal", "sjn"), "jugular"
    ),
    **dict.fromkeys(("c7", "cv7"), "c7"),
    **dict.fromkeys(("t10", "tv10"), "t10"),
    **dict.fromkeys(
        ("thoracic", "lumbar", "l5", "l3", "l1", "t8", "t12", "t6", "lv5", "lv3", "lv1", "tv8"),
        "spine",
    ),
    "neck": "neck",
    **dict.fromkeys(("tophead", "hv", "vertex", "headtop"), "top_head"),
    **dict.fromkeys(("occ", "sel", "lfhd", "rfhd", "lbhd", "rbhd"), "head"),
}

#: normalised (side removed) name patterns of technical cluster markers
_CLUSTERS: tuple[tuple[re.Pattern[str], str], ...] = (
    (re.compile(r"^(thigh\w*|th\d|thi|tha|thp|thl|tc\d|femur\w*|fem\d)$"), "thigh_cluster"),
    (re.compile(r"^(shank\w*|sh\d|sk\d|tb\d|tib|sha|tibia\w*|tib\d|shk\d|sc\d)$"), "shank_cluster"),
    (re.compile(r"^(foot\w*|ft\d|fc\d)$"), "foot_cluster"),
)
#: normalised (side removed) name patterns of arm markers
_ARM = re.compile(
    r"^(elbow\w*|elb|wrist\w*|wr[ab]|wri|wrs|fin|hand\w*|radius|ulna|rad|uln|upa|fra|ua\d|fa\d"
    r"|hn[ur]|car|ash|psh|biceps?|forearm|lhe|mhe|us|rs|shoulder(anterior|posterior)|upperarm"
    r"|humerus|hum\d?|arm\w*|mcp\d?|met3hand|hmh\d)$"
)
#: lab axes / calibration and reference markers (normalised whole label)
_AXES = re.compile(r"^([oxyz](global|lab|axis|ref)|origin|labx|laby|labz|ref\d*|wand\d*)$")
#: model outputs among the points (normalised whole label)
_OUTPUT = re.compile(
    r"(angles?v?|force|moment|power|grf|normalisedgrf|centre|center|jc|com|cog)$"
    r"|^(l|r|left|right)?(hjc|kjc|ajc|ejc|sjc|wjc)$"
)
_UNLABELLED = re.compile(r"^\*\d+$")
_SEP = re.compile(r"[\s._\-]+")


def zeros_as_gaps(markers: ArrayLike) -> NDArray[np.float64]:
    """(…, 3) positions with exact (0, 0, 0) samples set to NaN: TRC and some C3D writers mark
    a gap (or a static-only marker carried through a motion trial, as the Grand Challenge DM
    trials do for the knee and ankle markers) with zeros, which no real marker sits at."""
    x = np.array(markers, dtype=float)
    x[(x == 0.0).all(axis=-1)] = np.nan
    return x


def zeros_as_gaps_view(markers: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`zeros_as_gaps` without the copy where there is nothing to blank: a read-only view
    of ``markers`` (float) when no sample is exactly (0, 0, 0), else the blanked copy (a long
    trial's markers are not copied for reading)."""
    x = np.asarray(markers)
    if x.dtype != np.float64 or (x == 0.0).all(axis=-1).any():
        return zeros_as_gaps(x)
    view = x.view()
    view.flags.writeable = False
    return view


def _norm(s: str) -> str:
    return _SEP.sub("", s).lower()


@dataclass(frozen=True)
class ParsedLabel:
    """A label read by the grammar of the module docstring.

    ``side`` is ``"R"``, ``"L"`` or None (midline / unknown); ``landmark`` a :data:`LANDMARKS`
    key or None; ``kind`` one of ``"landmark"``, ``"unknown"``, ``"unlabelled"``,
    ``"model output"``, ``"lab axis"``, ``"not a marker"``."""

    label: str
    name: str
    side: str | None
    landmark: str | None
    kind: str


def _split_side(name: str) -> list[tuple[str, str]]:
    """Candidate (side, rest) splits of a label without prefix, most explicit first."""
    out = []
    m = re.match(r"^(right|left)[\s._\-]*(.+)$", name, re.IGNORECASE)
    if m:
        out.append((m.group(1)[0].upper(), m.group(2)))
    m = re.match(r"^([RLrl])[\s._\-]+(.+)$", name)
    if m:
        out.append((m.group(1).upper(), m.group(2)))
    m = re.match(r"^(.+?)[\s._\-]+([RLrl]|right|left|Right|Left)$", name)
    if m:
        out.append((m.group(2)[0].upper(), m.group(1)))
    m = re.match(r"^([RL])(.+)$", name)
    if m:
        out.append((m.group(1), m.group(2)))
    return out


def _sided_lookup(rest: str) -> str | None:
    """Landmark of a side-stripped name; Plug-in Gait's all-capitals ``TOE`` is the 2nd
    metatarsal head, any other "toe" the toe tip (module docstring)."""
    if rest.strip() == "TOE":
        return "mt2"
    n = _norm(rest)
    if n in SIDED_SYNONYMS:
        return SIDED_SYNONYMS[n]
    for pat, kind in _CLUSTERS:
        if pat.match(n):
            return kind
    if _ARM.match(n):
        return "arm"
    return None


def parse_label(label: str) -> ParsedLabel:
    """Side and landmark of one label (see the module docstring for the grammar)."""
    name = label.strip().rsplit(":", 1)[-1].strip()
    n = _norm(name)
    if not re.search(r"[A-Za-z]", name):
        kind = "unlabelled" if _UNLABELLED.match(name) else "not a marker"
        return ParsedLabel(label, name, None, None, kind)
    from msk.io.c3d import NON_MARKER_POINT

    if NON_MARKER_POINT.match(name) or _OUTPUT.search(n):
        return ParsedLabel(label, name, None, None, "model output")
    if _AXES.match(n):
        return ParsedLabel(label, name, None, None, "lab axis")
    if n in MIDLINE_SYNONYMS:
        return ParsedLabel(label, name, None, MIDLINE_SYNONYMS[n], "landmark")
    for side, rest in _split_side(name):
        lm = _sided_lookup(rest)
        if lm is not None:
            return ParsedLabel(label, name, side, lm, "landmark")
    return ParsedLabel(label, name, None, None, "unknown")


def pelvis_landmarks(model: Any, body: str = "pelvis") -> dict[str, Any]:
    """The model's markers on ``body`` that name the pelvis landmarks (:func:`parse_label`):
    ``asis_r``, ``asis_l``, ``psis_r``, ``psis_l``, ``sacrum`` → the first such marker (its
    ``name`` and ``offset`` in the body frame); absent keys are landmarks no marker names."""
    out: dict[str, Any] = {}
    for mk in getattr(model, "markers", ()):
        if mk.body != body:
            continue
        p = parse_label(mk.name)
        if p.kind != "landmark" or p.landmark not in ("asis", "psis", "sacrum"):
            continue
        key = "sacrum" if p.landmark == "sacrum" else f"{p.landmark}_{(p.side or '').lower()}"
        if key in ("asis_r", "asis_l", "psis_r", "psis_l", "sacrum"):
            out.setdefault(key, mk)
    return out


def strip_subject_prefix(labels: Sequence[str]) -> tuple[tuple[str, ...], str]:
    """The labels of one trial without their subject prefix, and that prefix (``""``: none).

    Vicon Nexus writes ``JW:LASI`` when a subject is named; the same lab's static may carry no
    prefix, or another one. A trial's prefix is dropped once, when the trial is read, so that
    every trial of a session names a marker alike: the prefix is the text up to the first ``:``
    shared by every label that has one (at least half of the labels; the others — a lab's axes,
    unnamed points — keep their name), dropped unless that would give two labels one name."""
    labs = [str(lab) for lab in labels]
    pre = {lab.split(":", 1)[0] for lab in labs if ":" in lab}
    with_pre = [lab for lab in labs if ":" in lab]
    if len(pre) != 1 or 2 * len(with_pre) < len(labs):
        return tuple(labs), ""
    prefix = next(iter(pre)) + ":"
    out = [lab[len(prefix) :] if lab.startswith(prefix) else lab for lab in labs]
    if len(set(out)) < len(set(labs)) or any(not lab.strip() for lab in out):
        return tuple(labs), ""
    return tuple(out), prefix


def as_read(label: str, labels: Sequence[str]) -> str:
    """``label`` as it is among ``labels`` — itself, or without its subject prefix when the
    trial's reader dropped it (:func:`strip_subject_prefix`: a configuration naming
    ``JW:RKneeLateral``)."""
    have = set(labels)
    if label in have or ":" not in label:
        return label
    bare = label.split(":", 1)[1]
    return bare if bare in have else label


def is_knee_segment(body: str) -> bool:
    """Whether the model body (or :data:`LANDMARK_BODIES` stem) ``body`` is a femur or a tibia
    (:data:`KNEE_SEGMENTS`: ``femur``, ``femur_r``, ``tibia_l``…)."""
    return body.startswith(KNEE_SEGMENTS)


def other_side(label: str, bodies: Sequence[str]) -> NDArray[np.bool_]:
    """(B,) whether each of ``bodies`` belongs to the other side than the lab label ``label``'s
    (:func:`parse_label`; sided bodies end in ``_r``/``_l``): none for an unsided label, never
    an unsided body."""
    side = parse_label(label).side
    if not side:
        return np.zeros(len(bodies), dtype=bool)
    other = "_l" if side.lower() == "r" else "_r"
    return np.array([b.endswith(other) for b in bodies], dtype=bool)


#: landmarks of the arm and of the head (excluded when the model has no such segment)
_ARM_LANDMARKS = frozenset({"arm"})
_HEAD_LANDMARKS = frozenset({"head"})
_ARM_BODY = re.compile(r"humerus|ulna|radius|hand|arm", re.IGNORECASE)
_HEAD_BODY = re.compile(r"head|skull|neck", re.IGNORECASE)


#: landmarks of the shoulder girdle (scapula, clavicle)
SHOULDER_GIRDLE_LANDMARKS = frozenset({"acromion", "clavicle"})
_SHOULDER_BODY = re.compile(r"scapula|clavic|humerus|shoulder", re.IGNORECASE)
_SHOULDER_WORD = re.compile(r"shoulder|acrom")


def shoulder_girdle_markers(labels: Sequence[str], model_bodies: Sequence[str]) -> tuple[str, ...]:
    """The labels of markers on the shoulder girdle (acromion, clavicle, a "Shoulder" word
    marker) when the model has no shoulder-girdle or arm segment (no scapula, clavicle or
    humerus body; gait2392 puts its acromion markers on the rigid torso).

    Such a marker follows the scapula, which elevates, protracts and rotates on the thorax
    with the arms (it moves ~8 cm between the arms-out static and the walk on OpenSim's
    subject01; gait2392 fits leave the acromia 55-65 mm off on the UWA and UNIPD walks, the
    worst markers by far): on a model whose torso is rigid it does not measure the trunk, and
    fitting it tilts the trunk and, through the lumbar joint, the pelvis. Empty when the model
    has such a segment.
    """
    if any(_SHOULDER_BODY.search(b) for b in model_bodies):
        return ()
    out = []
    for lab in labels:
        p = parse_label(lab)
        if p.landmark in SHOULDER_GIRDLE_LANDMARKS or (
            p.kind != "excluded" and p.landmark != "arm" and _SHOULDER_WORD.search(_norm(p.name))
        ):
            out.append(lab)
    return tuple(out)


#: landmarks on the foot (calcaneus, metatarsal heads, midfoot, toes)
FOOT_LANDMARKS: frozenset[str] = frozenset(
    (
        "heel",
        "toe_tip",
        "mt1",
        "mt2",
        "mt5",
        "midfoot_sup",
        "midfoot_lat",
        "midfoot_med",
        "hindfoot",
    )
)


def foot_markers(labels: Sequence[str]) -> tuple[str, ...]:
    """The labels naming a landmark of the foot (:data:`FOOT_LANDMARKS`: heel, metatarsal
    heads, midfoot, toe tip).

    Where a lab puts these is its own choice (height of the heel marker on the calcaneus,
    which metatarsal head, on the dorsum or on the side): without a static trial nothing else
    tells where they sit on the subject's foot, and a model's generic offsets leave them
    20–35 mm off through a walk (OpenSim's Rajagopal walk on gait2392: R.Toe.Lat 34.8 mm,
    heels 22–24 mm; UWA's calcaneus and metatarsal heads alike). The pipeline moves them
    (:func:`msk.personalise.scaling.place_markers_from_motion`, ``move``) when there is no static
    trial.
    """
    return tuple(lab for lab in labels if parse_label(lab).landmark in FOOT_LANDMARKS)


#: a distance between two measured markers varies by more than this through a motion: on the
#: walks of the shipped sessions the closest measured pairs vary by 0.25–0.9 mm SD (UWA tibia
#: cluster 0.38 mm, subject01 shank cluster 0.47 mm, Rajagopal PSIS–S2 0.25 mm, Plug-in Gait
#: heel–ankle 0.86 mm); reconstructed points keep 0.00–0.03 mm. Not for a still trial: in PS's
#: static, measured foot markers keep 0.03 mm
RECONSTRUCTED_DISTANCE_SD_M = 1e-4


def reconstructed_markers(
    markers: ArrayLike,
    labels: Sequence[str],
    *,
    sd_max_m: float = RECONSTRUCTED_DISTANCE_SD_M,
    min_frames: int = 10,
) -> tuple[str, ...]:
    """The labels of markers that the lab's software computes from other markers rather than
    measures: each keeps its distance to another marker constant to within ``sd_max_m``
    (standard deviation over the frames where both are tracked, at least ``min_frames``).

    Calibrated anatomical landmarks (CAST, Cappozzo et al. 1995 Clin Biomech 10:171): a point
    pointed at or seen in a static trial, stored in a technical cluster's frame and rebuilt from
    the cluster in every frame of the motion. Such a point moves rigidly with its cluster, so
    it carries the cluster's soft-tissue motion relative to the bone, which a standing static
    and a walk do not share. Through a motion, two measured markers, even on one rigid plate,
    did not keep their distance to < 0.1 mm on any shipped session (camera noise, skin motion:
    :data:`RECONSTRUCTED_DISTANCE_SD_M`); a still trial is no test (a standing subject's
    measured markers keep 0.03 mm). BTS/IOR's UNIPD walks: ASIS–PSIS of each side, GT,
    LE, ME of each thigh and HF, TT, LM, MM of each shank (0.00–0.03 mm); the Grand Challenge
    foot markers (0.000–0.002 mm). A point needs a partner rebuilt from the same cluster (or
    the cluster's marker its frame starts at, which is then found too).

    ``markers``: (N, n, 3) positions (NaN or exact zeros: gaps), ``labels``: their n names.
    """
    x = zeros_as_gaps_view(np.asarray(markers, dtype=float))  # read only
    if x.ndim != 3 or x.shape[1] != len(labels) or x.shape[2] != 3:
        raise ShapeMismatchError(
            f"markers of shape {x.shape} for {len(labels)} labels: expected (N, n, 3)"
        )
    seen: NDArray[np.bool_] = np.asarray(np.isfinite(x).all(axis=2))
    out: set[int] = set()
    for a in range(len(labels)):
        for b in range(a + 1, len(labels)):
            both = seen[:, a] & seen[:, b]
            if both.sum() < min_frames:
                continue
            d = np.linalg.norm(x[both, a] - x[both, b], axis=1)
            # one point under two labels is a duplicate, not a reconstruction
            if float(np.std(d)) <= sd_max_m and float(np.mean(d)) > 1e-3:
                out.update((a, b))
    return tuple(labels[i] for i in sorted(out))


@dataclass(frozen=True)
class MarkerSetMatch:
    """What :func:`recognise` found.

    Attributes:
        protocol: the marker protocol the labels look like (``"Plug-in Gait"``,
            ``"Grand Challenge"``, ``"UWA clusters"``, ``"IOR/CAST"``, ``"OpenSim"``,
            ``"unknown"``…), for the report.
        rename: model marker → lab label (as a session's ``[markers] rename``).
        unmatched_lab: lab labels kept as markers that no model marker names (clusters, PSIS…):
            for marker placement.
        excluded: lab label → why it is not a marker to use (lab axis, unlabelled, model
            output, arm/head marker without such a segment in the model).
        unmatched_model: model markers no lab label names.
        landmarks: lab label → landmark key (:data:`LANDMARKS`) of every recognised label.
        notes: ambiguities met (two lab labels for one landmark…).
    """

    protocol: str
    rename: Mapping[str, str]
    unmatched_lab: tuple[str, ...]
    excluded: Mapping[str, str]
    unmatched_model: tuple[str, ...] = ()
    landmarks: Mapping[str, str] = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    def body_hints(self, bodies: Sequence[str]) -> dict[str, str]:
        """Lab label → the model body its landmark belongs to (:data:`LANDMARK_BODIES`), for
        the recognised labels whose body (``<stem>_r``/``_l`` by the label's side, or the
        stem) is in ``bodies``."""
        have = set(bodies)
        out: dict[str, str] = {}
        for lab, lm in self.landmarks.items():
            stem = LANDMARK_BODIES.get(lm)
            if stem is None:
                continue
            side = parse_label(lab).side
            for cand in ((f"{stem}_{side.lower()}",) if side else ()) + (stem,):
                if cand in have:
                    out[lab] = cand
                    break
        return out

    @property
    def lab_to_model(self) -> dict[str, str]:
        """Lab label → model marker (the inverse of ``rename``)."""
        return {v: k for k, v in self.rename.items()}

    def model_labels(self, labels: Sequence[str]) -> tuple[str, ...]:
        """``labels`` in model names where matched (others unchanged, excluded ones too)."""
        inv = self.lab_to_model
        return tuple(inv.get(lab, lab) for lab in labels)

    def apply(
        self, markers: NDArray[np.float64], labels: Sequence[str]
    ) -> tuple[NDArray[np.float64], tuple[str, ...]]:
        """(N, M, 3) markers and labels without the excluded columns, labels in model names;
        exact-zero samples become NaN gaps (:func:`zeros_as_gaps`; the kept columns are the
        one copy made)."""
        x = zeros_as_gaps_view(np.asarray(markers, dtype=float))
        if x.ndim != 3 or x.shape[1] != len(labels):
            raise ShapeMismatchError(f"markers {x.shape} do not match {len(labels)} labels")
        keep = [i for i, lab in enumerate(labels) if lab not in self.excluded]
        names = self.model_labels([labels[i] for i in keep])
        return x[:, keep], names


def _helen_hayes(parsed: Sequence[ParsedLabel]) -> bool:
    """The labels are the Helen Hayes set (Kadaba et al. 1990; Motion Analysis): ``V.Sacral``
    with bare ``Knee``/``Ankle`` words and a ``Heel``."""
    raw = {_norm(p.name) for p in parsed}
    codes = {_norm(p.name)[1:] for p in parsed if p.side}
    return "vsacral" in raw and bool({"knee", "ankle"} & codes) and "heel" in codes


def _protocol(parsed: Sequence[ParsedLabel], exact: int, n_model: int) -> str:
    """A name for the marker protocol the labels look like (descriptive only)."""
    raw = {_norm(p.name) for p in parsed}
    sided = {(p.side, _norm(p.name)[1:]) for p in parsed if p.side}
    codes = {n for _, n in sided}

    def has(*names: str) -> bool:
        return all(n in codes for n in names)

    if n_model and exact >= max(3, n_model // 2):
        return "OpenSim (model marker names)"
    if has("asi") and ({"th1", "tb1"} & codes or {"th1", "tb1"} <= codes) and "cal" in codes:
        return "UWA clusters"
    if has("asi") and ({"kne", "ank", "thi", "tib"} & codes) and {"hee", "toe"} & codes:
        return "Plug-in Gait"
    if has("asis", "le") or has("asis", "lm") or {"lle", "rle"} & raw:
        return "IOR/CAST"
    if has("ias", "fle") or has("ias", "fal"):
        return "IOR/CAST (Van Sint Jan names)"
    if _helen_hayes(parsed):
        return "Helen Hayes"
    if any("thighsuperior" in n for n in raw) and any("asis" in n for n in raw):
        return "Grand Challenge"
    if any(n.endswith("th1") for n in raw) and any(n.endswith("asis") for n in raw):
        return "OpenSim clusters (Rajagopal)"
    lms = {p.landmark for p in parsed}
    if {"thigh_cluster", "shank_cluster"} <= lms:
        return "clusters + epicondyles" if {"knee_lat", "knee_med"} & lms else "clusters"
    return "unknown"


def recognise(
    labels: Sequence[str],
    model_marker_names: Sequence[str],
    *,
    rename: Mapping[str, str] | None = None,
    model_bodies: Sequence[str] = (),
    markers: ArrayLike | None = None,
) -> MarkerSetMatch:
    """Pair the lab's marker labels with the model's markers by anatomical landmark.

    A lab label is paired with a model marker when (in this order) the user's ``rename``
    says so, or the label (subject prefix dropped) is the model marker's name, or both name the
    same landmark on the same side (:func:`parse_label`). A landmark that two lab labels name
    is paired with the first and noted. Arm markers are excluded when ``model_bodies`` is given
    and has no arm body; head markers when it has no head body and no model marker names the
    top of the head.

    Args:
        labels: the lab's point labels (C3D ``POINT:LABELS`` or TRC header), any prefix.
        model_marker_names: the model's marker names.
        rename: explicit model marker → lab label pairs; they override everything.
        model_bodies: the model's body names (to exclude arm / head markers); empty: gait2392
            style (no arm, head on the torso), i.e. arm markers excluded, head markers kept.
        markers: (N, M, 3) data of ``labels``, optional: a label with no valid sample (all NaN
            or all exact zeros, :func:`zeros_as_gaps`) is excluded as never tracked.

    Returns:
        :class:`MarkerSetMatch`.
    """
    labels = tuple(labels)
    model_names = tuple(model_marker_names)
    # a configured label written with the subject prefix the trial's reader dropped
    # (strip_subject_prefix) names the same label
    explicit = {mk: as_read(lab, labels) for mk, lab in (rename or {}).items()}
    parsed = [parse_label(lab) for lab in labels]
    if _helen_hayes(parsed):  # its toe marker sits on the 2nd metatarsal head
        parsed = [replace(p, landmark="mt2") if p.landmark == "toe_tip" else p for p in parsed]
    model_parsed = {mk: parse_label(mk) for mk in model_names}
    has_arm = any(_ARM_BODY.search(b) for b in model_bodies)
    has_head = any(_HEAD_BODY.search(b) for b in model_bodies) or any(
        p.landmark == "top_head" for p in model_parsed.values()
    )
    excluded: dict[str, str] = {}
    landmarks: dict[str, str] = {}
    notes: list[str] = []
    used_labels = set(explicit.values())
    tracked: NDArray[np.bool_] = np.ones(len(labels), dtype=bool)
    if markers is not None:
        x = zeros_as_gaps(markers)
        if x.ndim != 3 or x.shape[1] != len(labels):
            raise ShapeMismatchError(f"markers {x.shape} do not match {len(labels)} labels")
        tracked = np.asarray(np.isfinite(x).all(axis=2).any(axis=0))
    for k, p in enumerate(parsed):
        if p.label in used_labels:
            continue
        if not tracked[k]:
            excluded[p.label] = "never tracked (no valid sample)"
        elif p.kind == "unlabelled":
            excluded[p.label] = "unlabelled trajectory"
        elif p.kind == "model output":
            excluded[p.label] = "model output, not a marker"
        elif p.kind == "lab axis":
            excluded[p.label] = "lab axis / reference marker"
        elif p.kind == "not a marker":
            excluded[p.label] = "not a marker label"
        elif p.landmark in _ARM_LANDMARKS and not has_arm:
            excluded[p.label] = "arm marker: the model has no arm segment"
        elif p.landmark in _HEAD_LANDMARKS and not has_head:
            excluded[p.label] = "head marker: the model has no head segment"
        elif p.landmark == "patella" and not any("patella" in b for b in model_bodies):
            # the patella glides over the femur as the knee flexes: fixed to femur or tibia it
            # would pull the knee angle (no patella body in the model)
            excluded[p.label] = "patella marker: the model has no patella segment"
        if p.landmark is not None:
            landmarks[p.label] = p.landmark

    out: dict[str, str] = {}
    for mk, lab in explicit.items():
        out[mk] = lab
    free = [p for p in parsed if p.label not in excluded and p.label not in used_labels]
    # same name (prefix dropped)
    by_name: dict[str, str] = {}
    for p in free:
        by_name.setdefault(p.name, p.label)
    exact = 0
    for mk in model_names:
        if mk not in out and mk in by_name and by_name[mk] not in out.values():
            out[mk] = by_name[mk]
            exact += 1
    taken = set(out.values())
    # same landmark, same side
    by_key: dict[tuple[str | None, str], list[str]] = {}
    for p in free:
        if p.label in taken or p.landmark is None:
            continue
        by_key.setdefault((p.side, p.landmark), []).append(p.label)
    for mk in model_names:
        mp = model_parsed[mk]
        if mk in out or mp.landmark is None or mp.landmark.endswith("cluster"):
            continue
        cands = list(dict.fromkeys(c for c in by_key.get((mp.side, mp.landmark), [])))
        cands = [c for c in cands if c not in taken]
        if not cands:
            continue
        if len(cands) > 1:
            notes.append(
                f"{mk}: lab labels {cands} all name {LANDMARKS[mp.landmark]}; used {cands[0]}"
            )
        out[mk] = cands[0]
        taken.add(cands[0])
    unmatched = tuple(p.label for p in parsed if p.label not in excluded and p.label not in taken)
    return MarkerSetMatch(
        protocol=_protocol(parsed, exact, len(model_names)),
        rename=out,
        unmatched_lab=unmatched,
        excluded=excluded,
        unmatched_model=tuple(mk for mk in model_names if mk not in out),
        landmarks=landmarks,
        notes=tuple(notes),
    )
