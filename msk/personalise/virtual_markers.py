"""Virtual markers: points a lab did not mark, made from the markers it did.

The pelvis of a marker set with two ASIS and two PSIS markers and no sacral marker (a common
set: Rajagopal et al. 2016's, CAST, IOR) has, in a model whose pelvis carries ASIS and sacral
markers (gait2392), only the two ASIS to pose it when there is no static trial: the PSIS
markers are not the model's and are placed from the motion like any lab marker, so the
pelvis' rotation about the inter-ASIS axis (its tilt) is left to the legs' markers (tilt
11° against 1° in the reference IK of Rajagopal et al.'s walk). The midpoint of the two PSIS
is where a sacral marker sits (on the sacrum between the PSIS: Davis et al. 1991; Plug-in Gait
takes it so, "SACR = (LPSI + RPSI)/2", Vicon Plug-in Gait reference guide), and it pins the
tilt to the model's own ASIS–sacrum geometry: :func:`with_virtual_sacrum` adds it to a trial.

A lab names its own virtual markers in the configuration (``[markers] virtual``, marker name →
definition; :func:`parse_virtual`, :func:`with_virtual_markers`), in two forms over its
measured markers:

* ``mean(A, B, …)`` — the centroid of the named markers (``mean(LPSI, RPSI)``: the sacral
  point of Davis et al. 1991);
* ``offset(O, X, P, dx, dy, dz)`` — the point at (dx, dy, dz) m in the frame of three markers:
  origin O, x̂ = (X − O)/‖X − O‖, ẑ = x̂ × (P − O) normalised (normal to the plane O, X, P),
  ŷ = ẑ × x̂ (a marker a given distance from a named one, rigidly with the segment the three
  are on).

A frame where a named marker is missing (NaN or exact zeros) gives NaN.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping
from typing import Any

import numpy as np

from msk.exceptions import ConfigError, MissingDataError

__all__ = ["VirtualMarker", "parse_virtual", "with_virtual_markers", "with_virtual_sacrum"]

_FORM = re.compile(r"^\s*(mean|offset)\s*\((.*)\)\s*$", re.IGNORECASE)


@dataclasses.dataclass(frozen=True)
class VirtualMarker:
    """One virtual marker: ``name``, ``kind`` (``mean`` or ``offset``), the measured markers
    it is made from (``mean``: two or more; ``offset``: origin, x-axis and plane markers) and,
    for ``offset``, the point in their frame (m)."""

    name: str
    kind: str
    markers: tuple[str, ...]
    offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def positions(self, x: np.ndarray, labels: tuple[str, ...] | list[str]) -> np.ndarray:
        """(N, 3) the marker in every frame of ``x`` (N, M, 3), NaN where one of its markers
        is missing (NaN or exact zeros).

        Raises:
            MissingDataError: ``labels`` lack one of its markers.
        """
        labs = list(labels)
        absent = [m for m in self.markers if m not in labs]
        if absent:
            raise MissingDataError(
                f"virtual marker {self.name!r}: the trial has no marker {', '.join(absent)}"
            )
        pts = [np.asarray(x[:, labs.index(m)], dtype=float).copy() for m in self.markers]
        for p in pts:
            p[(p == 0.0).all(axis=-1)] = np.nan
        if self.kind == "mean":
            return np.asarray(np.mean(pts, axis=0), dtype=float)
        o, a, b = pts
        with np.errstate(invalid="ignore", divide="ignore"):
            ex = (a - o) / np.linalg.norm(a - o, axis=-1, keepdims=True)
            ez = np.cross(ex, b - o)
            ez /= np.linalg.norm(ez, axis=-1, keepdims=True)
            ey = np.cross(ez, ex)
        d = self.offset_m
        return np.asarray(o + d[0] * ex + d[1] * ey + d[2] * ez, dtype=float)


def parse_virtual(name: str, text: str) -> VirtualMarker:
    """``mean(A, B, …)`` or ``offset(O, X, P, dx, dy, dz)`` (module docstring) → the marker.

    Raises:
        ConfigError: another form, too few markers, a non-numeric offset or one marker twice.
    """
    m = _FORM.match(str(text))
    if m is None:
        raise ConfigError(
            f"markers.virtual.{name} = {text!r}: expected mean(A, B, ...) or "
            "offset(O, X, P, dx, dy, dz)"
        )
    kind = m.group(1).lower()
    args = [a.strip() for a in m.group(2).split(",")]
    if any(not a for a in args):
        raise ConfigError(f"markers.virtual.{name} = {text!r}: an empty argument")
    if kind == "mean":
        if len(args) < 2 or len(set(args)) < len(args):
            raise ConfigError(
                f"markers.virtual.{name} = {text!r}: mean() needs two or more distinct markers"
            )
        return VirtualMarker(name, kind, tuple(args))
    if len(args) != 6:
        raise ConfigError(
            f"markers.virtual.{name} = {text!r}: offset() takes three markers and three "
            "distances in metres"
        )
    try:
        d = tuple(float(v) for v in args[3:])
    except ValueError:
        raise ConfigError(
            f"markers.virtual.{name} = {text!r}: the offsets {args[3:]} are not numbers (m)"
        ) from None
    if len(set(args[:3])) < 3 or not all(np.isfinite(d)):
        raise ConfigError(
            f"markers.virtual.{name} = {text!r}: three distinct markers and finite offsets"
        )
    return VirtualMarker(name, kind, tuple(args[:3]), (d[0], d[1], d[2]))


def with_virtual_markers(trial: Any, specs: Mapping[str, str]) -> tuple[Any, list[dict[str, Any]]]:
    """``trial`` (a dataclass with ``markers`` (N, M, 3) and ``marker_labels`` — or ``labels``,
    :class:`msk.personalise.static_trial.StaticTrial`) with the virtual markers ``specs``
    (name → definition, :func:`parse_virtual`) appended, a name the trial already has
    replaced; and a note per marker for ``summary.json``.

    Raises:
        ConfigError: a definition does not parse.
        MissingDataError: the trial lacks a marker a definition names.
    """
    if not specs:
        return trial, []
    x = np.asarray(trial.markers, dtype=float)
    key = "marker_labels" if hasattr(trial, "marker_labels") else "labels"  # a StaticTrial's
    labels = list(getattr(trial, key))
    notes = []
    for name, text in specs.items():
        vm = parse_virtual(name, text)
        try:
            p = vm.positions(x, labels)
        except MissingDataError as exc:
            where = getattr(getattr(trial, "path", None), "name", None)
            raise MissingDataError(f"{where + ': ' if where else ''}{exc}") from None
        if name in labels:
            x = x.copy()
            x[:, labels.index(name)] = p
        else:
            x = np.concatenate([x, p[:, None]], axis=1)
            labels.append(name)
        notes.append({"marker": name, "definition": str(text), "from": list(vm.markers),
                      "frames_missing": int((~np.isfinite(p).all(axis=-1)).sum())})  # fmt: skip
    return dataclasses.replace(trial, **{"markers": x, key: tuple(labels)}), notes


def with_virtual_sacrum(trial: Any, model: Any) -> tuple[Any, dict[str, Any] | None]:
    """``trial`` (:class:`msk.trial.Trial`) with the model's sacral marker added as the
    midpoint of the trial's two PSIS markers (NaN where either is missing or an exact zero),
    when the model has one sacral marker on its pelvis and the trial has no sacral marker but
    both PSIS; and a note for ``summary.json`` (None when nothing was added)."""
    from msk.model.markersets import parse_label

    sacral = [
        mk.name for mk in model.markers
        if mk.body == "pelvis" and parse_label(mk.name).landmark == "sacrum"
    ]  # fmt: skip
    labels = list(trial.marker_labels)
    parsed = {lab: parse_label(lab) for lab in labels}
    if len(sacral) != 1 or sacral[0] in labels:
        return trial, None
    if any(p.landmark == "sacrum" for p in parsed.values()):
        return trial, None
    psis = {p.side: lab for lab, p in parsed.items() if p.landmark == "psis" and p.side}
    if set(psis) != {"R", "L"}:
        return trial, None
    x = np.asarray(trial.markers, dtype=float)
    r, left = (x[:, labels.index(psis[s])] for s in ("R", "L"))
    gap = (r == 0.0).all(axis=-1) | (left == 0.0).all(axis=-1)
    mid = 0.5 * (r + left)
    mid[gap] = np.nan
    markers = np.concatenate([x, mid[:, None]], axis=1)
    out = dataclasses.replace(trial, markers=markers, marker_labels=(*labels, sacral[0]))
    return out, {
        "marker": sacral[0],
        "from": [psis["R"], psis["L"]],
        "why": "no sacral marker: the PSIS midpoint stands for it (pelvis tilt)",
    }
