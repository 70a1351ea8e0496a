"""C3D trials: markers, model outputs, analogs, force platforms, events, subject data.

msk reads the file itself: header and parameter section checked first (:func:`_check_bytes`),
the parameters decoded as ezc3d's Python binding gives them, the data section read block by
block (float or integer storage; Intel, DEC and MIPS processors; analog samples as
``(raw - OFFSET) * SCALE * GEN_SCALE``, unsigned when ``ANALOG:FORMAT`` says so), so that a
long trial never holds more than its outputs and one block; ``tests/io`` checks
every real C3D against ezc3d. ezc3d writes (:func:`write_c3d`).

Everything is converted to SI once, here: positions m, forces N, moments N·m, time s, angles rad,
mass kg, height m. Time is axis 0 of every array.

Force platforms (C3D ``FORCE_PLATFORM`` types 1, 2, 3 and 4) are computed from the analog channels
in vectorised numpy with the conventions of ezc3d's ``ForcePlatforms`` module (ezc3d's own
extraction loops over frames in Python and is ~10x slower; ``tests/io`` checks that both agree):

* plate axes ``R = [x̂ ŷ ẑ]`` from the corners: ``x = c0 - c1``, ``y = c0 - c3``, ``z = x × y``;
* ``ORIGIN`` (the transducer offset, flipped so that its z is ≤ 0) moves the measured moment to
  the centre of the working surface: ``M_c = M_t + F × o``;
* COP in plate axes ``(-M_c,y / F_z, M_c,x / F_z, 0)``; free moment ``T = M_c + F × p_cop``
  (only its plate-normal component is non-zero);
* everything is then rotated to the lab: ``F_lab = R F``, ``M_lab = R M_c``, ``cop = R p + c̄``.

Type 1 plates (channels ``Fx Fy Fz Px Py Mz``, e.g. BTS systems) record the COP and the free
moment directly: ``(Px, Py, 0)`` is the COP in plate axes about the centre of the working surface
(ezc3d and MOtoNMS read it so; ``ORIGIN`` is not used), ``Mz`` the free moment along the plate
normal, in N·<point units>; ``M_c = p × F + (0, 0, Mz)``.

The force is the ground reaction on the subject (upward when loaded), as ezc3d and OpenSim's
C3DFileAdapter report it.
"""

from __future__ import annotations

import functools
import math
import os
import re
import struct
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.analogs import StoredAnalogs
from msk.exceptions import C3DError, ForcePlateError, MskError, UnitsError
from msk.io.plate_checks import (
    cop_warnings,
    direction_warnings,
    saturation_warnings,
    scale_flags,
)
from msk.io.validate import MAX_ABS_COORDINATE_M, MAX_ABS_FORCE_N, check_regular_file
from msk.trial import Event, ForcePlate, GapReport, ModelOutputs, Subject, Trial

__all__ = [
    "LENGTH_UNITS_M",
    "MODEL_OUTPUT_KINDS",
    "NON_MARKER_POINT",
    "PlateSpec",
    "is_measured_marker",
    "plate_axes",
    "read_c3d",
    "write_c3d",
]

#: Length units accepted in ``POINT:UNITS`` and their value in metres.
LENGTH_UNITS_M: Mapping[str, float] = {"m": 1.0, "mm": 1e-3, "cm": 1e-2}
#: ``POINT`` parameters listing model-output points (Plug-in Gait and alike), never markers.
MODEL_OUTPUT_KINDS: tuple[str, ...] = ("ANGLES", "FORCES", "MOMENTS", "POWERS", "REACTIONS")
#: Point labels that are not measured markers although C3D writers put them among the markers:
#: Vicon's unlabelled trajectories (``*1``, ``*12``: the same label is another point in another
#: trial) and Plug-in Gait's virtual segment points (origin / anterior / lateral / proximal of
#: each PiG segment: ``PELO``, ``LFEA``, ``RTIL``, ``HEDP``, ``TRXO``…), outputs of its model.
NON_MARKER_POINT = re.compile(r"^\*\d+$|^(PEL|HED|TRX|[LR](FE|TI|FO|TO|CL|HU|RA|HN))[OALP]$")


def is_measured_marker(label: str) -> bool:
    """False for an unlabelled trajectory or a Plug-in Gait virtual point
    (:data:`NON_MARKER_POINT`): not something to fix on a model body."""
    return NON_MARKER_POINT.match(label.strip()) is None


_AXES = "XYZ"


# ---------------------------------------------------------------------------------------------
# header guard: refuse a corrupt header or parameter section before the data are read
# ---------------------------------------------------------------------------------------------
def _check_bytes(path: Path) -> _Layout:
    """Sanity checks of the header and parameter section before the data section is read; the
    file's layout as checked."""
    check_regular_file(path, C3DError, "C3D file")
    size = path.stat().st_size
    if size == 0:
        raise C3DError(f"{path}: empty file")
    if size < 1024:
        raise C3DError(f"{path}: {size} bytes is too short for a C3D file (header + parameters)")
    with path.open("rb") as fh:
        head = fh.read(512)
        if head[1] != 0x50:
            raise C3DError(f"{path}: not a C3D file (byte 2 is 0x{head[1]:02x}, expected 0x50)")
        param_block = head[0]
        if param_block < 2 or (param_block - 1) * 512 + 4 > size:
            raise C3DError(f"{path}: corrupt header (parameter block {param_block})")
        fh.seek((param_block - 1) * 512)
        phead = fh.read(4)
        n_param_blocks, proc = phead[2], phead[3]
        if proc not in (84, 85, 86):
            raise C3DError(f"{path}: corrupt parameter section (processor type byte {proc})")
        params_end = (param_block - 1 + n_param_blocks) * 512
        if n_param_blocks == 0 or params_end > size:
            raise C3DError(
                f"{path}: truncated or corrupt parameter section "
                f"({n_param_blocks} blocks announced, file has {size} bytes)"
            )
        fh.seek((param_block - 1) * 512)
        params = fh.read(n_param_blocks * 512)
    endian = ">" if proc == 86 else "<"
    raw_params = _walk_parameters(path, params, endian)
    w = struct.unpack(endian + "12H", head[:24])
    n_points, n_analog_words, first, last = w[1], w[2], w[3], w[4]
    # scale factor (words 7-8): its sign says integer (>0) or float (<0) storage
    if proc == 85:  # DEC: sign bit is the top bit of the first 16-bit word
        is_float = bool(head[13] & 0x80)
    elif proc == 86:
        is_float = bool(head[12] & 0x80)
    else:
        is_float = bool(head[15] & 0x80)
    data_block = w[8]
    word = 4 if is_float else 2
    n_frames = last - first + 1 if last >= first else 0
    long_first = _long_first_frame(raw_params, proc, last)
    if long_first is not None:  # more than 65 535 frames: the header's last frame saturates
        first, n_frames = long_first
    if data_block < 2 and (n_points or n_analog_words):
        raise C3DError(f"{path}: corrupt header (data block {data_block})")
    frame_bytes = (4 * n_points + n_analog_words) * word
    frames_flag: dict[str, Any] | None = None
    if long_first is None:
        n_frames, frames_flag = _frame_count(
            path, raw_params, proc, n_frames, size, (data_block - 1) * 512, frame_bytes
        )
    expected = (data_block - 1) * 512 + n_frames * frame_bytes
    if n_frames and size < expected:
        raise C3DError(
            f"{path}: truncated: the header promises {n_frames} frames "
            f"({expected} bytes) but the file has {size} bytes"
        )
    if proc == 85:
        a = bytes(head[20:24][i] for i in (2, 3, 0, 1))
        hdr_rate = struct.unpack("<f", a)[0] / 4.0
    else:
        hdr_rate = struct.unpack(endian + "f", head[20:24])[0]
    _check_parameters(
        path,
        raw_params,
        proc,
        {
            "n_points": n_points,
            "n_analog_words": n_analog_words,
            "n_frames": n_frames,
            "point_rate": hdr_rate,
            "analog_per_frame": w[9],
        },
    )
    if proc == 85:
        a = bytes(head[12:16][i] for i in (2, 3, 0, 1))
        scale = struct.unpack("<f", a)[0] / 4.0
    else:
        scale = struct.unpack(endian + "f", head[12:16])[0]
    return _Layout(
        proc=proc,
        is_float=is_float,
        scale=scale,
        n_points=n_points,
        n_analog_words=n_analog_words,
        analog_per_frame=w[9],
        first_frame=first,
        n_frames=n_frames,
        data_start=(data_block - 1) * 512,
        point_rate=hdr_rate,
        params=raw_params,
        flags=() if frames_flag is None else (frames_flag,),
    )


def _frame_count(
    path: Path,
    params: Mapping[tuple[str, str], _RawParam],
    proc: int,
    header_frames: int,
    size: int,
    data_start: int,
    frame_bytes: int,
) -> tuple[int, dict[str, Any] | None]:
    """The number of frames to read when the header's frames (last − first + 1) and
    ``POINT:FRAMES`` disagree, and the reader flag saying so (None when they agree).

    The C3D header is the reference (C3D User Guide, Motion Lab Systems 2008, "The header
    section"; ezc3d and BTK read its frames): its frames are read when the data section holds
    them; otherwise ``POINT:FRAMES``'s when the data section holds those (a corrupt header
    word). When neither count is present in the file the two disagree irreconcilably and the
    file is refused (:class:`C3DError` naming both counts and the frames present). Nothing is
    read past the data, nothing dropped unsaid: a data section holding more whole frames than
    the count read is said in the flag."""
    p = params.get(("POINT", "FRAMES"))
    if p is None or p.type not in (1, 2, 4):
        return header_frames, None
    v = _decode(p, proc)
    if v is None or v.size == 0 or not math.isfinite(float(v[0])):
        return header_frames, None
    declared = int(v[0])
    if p.type == 2 and declared < 0:  # an unsigned 16-bit count stored as int16
        declared %= 65536
    if declared == header_frames or declared < 0 or not frame_bytes:
        return header_frames, None
    present = max(0, size - data_start) // frame_bytes
    if 0 < header_frames <= present:
        n, which = header_frames, "the header's"
    elif 0 < declared <= present:
        n, which = declared, "POINT:FRAMES's"
    else:
        raise C3DError(
            f"{path}: the header declares {header_frames} frames, POINT:FRAMES = {declared}, "
            f"and the data section holds {present} whole frames: truncated or corrupt"
        )
    extra = present - n
    # a data section is padded to whole 512-byte blocks: more than that is unread data
    beyond = extra * frame_bytes >= 512 and extra > 0
    msg = (
        f"frame count: the header declares {header_frames} frames, POINT:FRAMES = "
        f"{declared}; the data section holds {present} whole frames: {which} {n} read"
        + (f" ({extra} frames after them are not read)" if beyond else "")
    )
    return n, {"quantity": "c3d_frame_count_mismatch", "value": float(declared),
               "threshold": float(n), "message": msg}  # fmt: skip


@dataclass(frozen=True)
class _Layout:
    """Where and how a C3D stores its data (header and parameters as :func:`_check_bytes`
    checked them): processor type (84 Intel, 85 DEC, 86 MIPS), float or integer storage and
    the header's scale factor, points and analog words per frame, analog samples per frame,
    the first frame number (1-based) and the number of frames, the data section's byte
    offset, the header's point rate, the parameter records and the reader flags raised while
    checking them (:func:`_frame_count`)."""

    proc: int
    is_float: bool
    scale: float
    n_points: int
    n_analog_words: int
    analog_per_frame: int
    first_frame: int
    n_frames: int
    data_start: int
    point_rate: float
    params: Mapping[tuple[str, str], _RawParam]
    flags: tuple[dict[str, Any], ...] = ()


def _long_first_frame(
    params: Mapping[tuple[str, str], _RawParam], proc: int, header_last: int
) -> tuple[int, int] | None:
    """(first frame, number of frames) of a file of more than 65 535 frames: the header's last
    frame saturates at 65 535 and ``TRIAL:ACTUAL_START_FIELD`` / ``ACTUAL_END_FIELD`` hold the
    frame numbers as two unsigned 16-bit words, low word first (C3D User Guide, C3D.org 2008,
    "The TRIAL group"); None for any other file (the header's frames hold)."""
    start, end = (
        params.get(("TRIAL", "ACTUAL_START_FIELD")),
        params.get(("TRIAL", "ACTUAL_END_FIELD")),
    )
    if header_last != 65535 or start is None or end is None or start.type != 2 or end.type != 2:
        return None
    endian = ">" if proc == 86 else "<"
    s = np.frombuffer(start.data, dtype=endian + "u2").astype(np.int64)
    e = np.frombuffer(end.data, dtype=endian + "u2").astype(np.int64)
    if s.size < 2 or e.size < 2:
        return None
    first, last = int(s[0] + 65536 * s[1]), int(e[0] + 65536 * e[1])
    if last <= 65535 or last < first:
        return None
    return first, last - first + 1


@dataclass(frozen=True)
class _RawParam:
    """One parameter record as stored: data type (-1 char, 1 byte, 2 int16, 4 float), dims and
    data bytes, and where the record starts in the parameter section."""

    group: str
    name: str
    type: int
    dims: tuple[int, ...]
    data: bytes
    offset: int


def _walk_parameters(path: Path, buf: bytes, endian: str) -> dict[tuple[str, str], _RawParam]:
    """Walk the parameter records, check every length and pointer stays inside the section and
    return the parameters by ``(GROUP, NAME)`` as stored (ezc3d looks names up by case)."""
    pos = 4
    n = len(buf)
    count = 0
    groups: dict[int, str] = {}
    raw: list[tuple[int, str, int, tuple[int, ...], bytes, int]] = []
    while pos < n:
        nchar = abs(struct.unpack_from("b", buf, pos)[0])
        if nchar == 0:
            break
        gid = struct.unpack_from("b", buf, pos + 1)[0]
        name = buf[pos + 2 : pos + 2 + nchar]
        if pos + 4 + nchar > n or not all(c >= 32 and c != 127 for c in name):
            raise C3DError(f"{path}: corrupt parameter section at byte {pos}: bad name {name!r}")
        (offset,) = struct.unpack_from(endian + "H", buf, pos + 2 + nchar)
        body = pos + 4 + nchar
        end = body  # where the description length byte sits
        if gid > 0:  # a parameter: type, dims, data, description
            if body + 2 > n:
                raise C3DError(f"{path}: corrupt parameter section at byte {pos}")
            typ, ndim = struct.unpack_from("bB", buf, body)
            if typ not in (-1, 1, 2, 4):
                raise C3DError(
                    f"{path}: corrupt parameter {name.decode('latin-1')!r}: unknown data type {typ}"
                )
            dims = tuple(buf[body + 2 : body + 2 + ndim])
            length = abs(typ) * math.prod(dims) if ndim else abs(typ)
            end = body + 2 + ndim + length
            if end <= n:
                raw.append((gid, name.decode("latin-1"), typ, dims, buf[end - length : end], pos))
        elif gid < 0:
            groups.setdefault(-gid, name.decode("latin-1"))
        if end + 1 > n:
            raise C3DError(
                f"{path}: corrupt parameter {name.decode('latin-1')!r}: its data overrun "
                "the parameter section"
            )
        rec_end = end + 1 + buf[end]
        if rec_end > n or (offset and rec_end > pos + 2 + nchar + offset):
            raise C3DError(
                f"{path}: corrupt parameter {name.decode('latin-1')!r}: its length "
                f"({rec_end - pos} bytes) disagrees with its pointer to the next record"
            )
        if offset == 0:
            break
        nxt = pos + 2 + nchar + offset
        if nxt <= pos or nxt > n:
            raise C3DError(
                f"{path}: corrupt parameter section at byte {pos}: next record at {nxt} "
                f"is outside the section ({n} bytes)"
            )
        pos = nxt
        count += 1
        if count > 100_000:
            raise C3DError(f"{path}: corrupt parameter section (no end found)")
    out: dict[tuple[str, str], _RawParam] = {}
    for gid, pname, typ, dims, data, at in raw:
        group = groups.get(gid, f"#{gid}")
        out[(group, pname)] = _RawParam(group, pname, typ, dims, data, at)  # the last, as ezc3d
    return out


def _decode(p: _RawParam, proc: int) -> NDArray[np.float64] | None:
    """Numeric values of a parameter (flat, file order); None for a character parameter."""
    if p.type == -1:
        return None
    endian = ">" if proc == 86 else "<"
    if p.type == 4:
        b = p.data
        if proc == 85:  # DEC floats: swap the 16-bit words, exponent bias off by 2
            a = np.frombuffer(b, dtype=np.uint8).reshape(-1, 4)[:, [2, 3, 0, 1]]
            return np.frombuffer(a.tobytes(), dtype="<f4").astype(float) / 4.0
        return np.frombuffer(b, dtype=endian + "f4").astype(float)
    if p.type == 2:
        return np.frombuffer(p.data, dtype=endian + "i2").astype(float)
    return np.frombuffer(p.data, dtype="i1").astype(float)


def _parameter_values(
    params: Mapping[tuple[str, str], _RawParam], proc: int
) -> dict[str, dict[str, dict[str, Any]]]:
    """The parameters as ``{GROUP: {NAME: {"type", "value"}}}``, values as ezc3d's Python
    binding gives them: numbers as an array of the parameter's dims (first dim fastest, int
    for integer and byte types, float for floats); text with one dim as one string, with more
    dims as ``dims[0]``-character strings over the other dims, trailing blanks removed."""
    out: dict[str, dict[str, dict[str, Any]]] = {}
    for (group, name), p in params.items():
        value: Any
        if p.type == -1:  # NUL characters dropped (ezc3d reads text as C strings)
            text = p.data.decode("latin-1")
            if len(p.dims) <= 1:
                value = [text.replace("\0", "").rstrip(" ")] if p.dims != (0,) else []
            else:
                w, count = p.dims[0], math.prod(p.dims[1:])
                value = [
                    text[k * w : (k + 1) * w].replace("\0", "").rstrip(" ") for k in range(count)
                ]
        else:
            v = _decode(p, proc)
            assert v is not None
            if p.type != 4:
                v = v.astype(np.int64)
            value = v.reshape(p.dims, order="F") if len(p.dims) > 1 else v
        out.setdefault(group, {})[name] = {"type": p.type, "value": value}
    return out


#: frames per block of the data section read at once (bounded temporaries on long trials)
_READ_BLOCK = 4096


def _data_words(lay: _Layout, raw: NDArray[Any]) -> NDArray[np.float64]:
    """A block of the data section's words as numbers (float storage: the processor's floats;
    integer storage: signed 16-bit integers)."""
    if not lay.is_float:
        return raw.astype(np.float64)
    if lay.proc == 85:  # DEC: 16-bit words swapped, exponent 2 higher than IEEE's
        w = np.ascontiguousarray(raw).view(np.uint16).reshape(-1, 2)[:, ::-1]
        return np.ascontiguousarray(w).view("<f4").reshape(raw.shape).astype(np.float64) / 4.0
    return raw.astype(np.float64)


def _read_data(
    path: Path,
    lay: _Layout,
    analog_columns: Sequence[int] | NDArray[np.int64],
    *,
    points: bool = True,
    stored: bool = False,
) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.float64] | StoredAnalogs]:
    """Points ``(N, P, 3)`` (file units; integer storage times ``|POINT:SCALE|``), their
    invalid flags ``(N, P)`` (negative residual word) and the analog ``analog_columns``
    ``(N * samples, C)`` scaled as ``(raw - OFFSET) * SCALE * GEN_SCALE``, read from the data
    section block by block (:data:`_READ_BLOCK` frames): only the outputs are held whole.
    ``stored``: the analogs as a :class:`msk.analogs.StoredAnalogs` (the stored samples,
    scaled when indexed: the same values) unless the file is a DEC one."""
    endian = ">" if lay.proc == 86 else "<"
    dtype = np.dtype(endian + ("f4" if lay.is_float else "i2"))
    n, n_pts, samples = lay.n_frames, lay.n_points, lay.analog_per_frame
    n_ana = lay.n_analog_words // samples if samples else 0
    if n_ana * samples != lay.n_analog_words and samples:
        raise C3DError(
            f"{path}: {lay.n_analog_words} analog words per frame is not a whole number of "
            f"channels x {samples} samples"
        )
    per_frame = 4 * n_pts + lay.n_analog_words
    cols = np.asarray(analog_columns, dtype=np.int64)
    vals = _parameter_values(
        {k: v for k, v in lay.params.items() if k[0] in ("POINT", "ANALOG")}, lay.proc
    )
    point_scale = abs(lay.scale)
    ps = vals.get("POINT", {}).get("SCALE", {}).get("value")
    if ps is not None and np.size(ps):
        point_scale = abs(float(np.ravel(ps)[0]))
    ana = vals.get("ANALOG", {})
    gen = float(np.ravel(ana["GEN_SCALE"]["value"])[0]) if "GEN_SCALE" in ana else 1.0
    scale = np.ones(n_ana)
    offset = np.zeros(n_ana)
    if n_ana and "SCALE" in ana:
        scale = np.asarray(ana["SCALE"]["value"], dtype=float).ravel()[:n_ana]
    fmt = ana.get("FORMAT", {}).get("value") or [""]
    unsigned = str(fmt[0]).strip().upper() == "UNSIGNED"
    if n_ana and "OFFSET" in ana:
        offset = np.asarray(ana["OFFSET"]["value"], dtype=float).ravel()[:n_ana]
        if unsigned:  # C3D User Guide: offsets (and integer samples) are then unsigned
            offset = np.mod(offset, 65536.0)
    factor = scale[cols] * gen if cols.size else np.zeros(0)
    off = offset[cols] if cols.size else np.zeros(0)
    xyz = np.empty((n if points else 0, n_pts, 3))
    invalid = np.zeros((n if points else 0, n_pts), dtype=bool)
    lazy = stored and lay.proc != 85
    if lazy:
        kind = "f4" if lay.is_float else ("u2" if unsigned else "i2")
        held = np.empty((n * samples, cols.size), dtype=np.dtype(kind))
    else:
        held = np.empty((n * samples, cols.size))
    analogs: NDArray[np.float64] | StoredAnalogs = (
        StoredAnalogs(held, off, factor) if lazy else held
    )
    if not n or not per_frame:
        return xyz, invalid, analogs
    with path.open("rb") as fh:
        fh.seek(lay.data_start)
        for a in range(0, n, _READ_BLOCK):
            b = min(n, a + _READ_BLOCK)
            raw = np.fromfile(fh, dtype=dtype, count=(b - a) * per_frame)
            if raw.size != (b - a) * per_frame:
                raise C3DError(f"{path}: truncated: the data section ends before frame {b}")
            raw = raw.reshape(b - a, per_frame)
            if points and n_pts:
                pw = _data_words(lay, raw[:, : 4 * n_pts]).reshape(b - a, n_pts, 4)
                invalid[a:b] = pw[:, :, 3] < 0
                xyz[a:b] = pw[:, :, :3] if lay.is_float else pw[:, :, :3] * point_scale
            if cols.size:
                aw = raw[:, 4 * n_pts :].reshape((b - a) * samples, n_ana)[:, cols]
                if unsigned and not lay.is_float:
                    aw = aw.view(np.dtype(endian + "u2"))
                if lazy:  # exact: the same numbers in the native byte order
                    held[a * samples : b * samples] = aw
                else:
                    held[a * samples : b * samples] = (_data_words(lay, aw) - off) * factor
    return xyz, invalid, analogs


#: numeric parameters ezc3d reads as numbers (a character value there crashes it natively);
#: the ``True`` ones are scalars it dereferences (they must hold at least one value)
_NUMERIC_PARAMS: Mapping[tuple[str, str], bool] = {
    ("POINT", "USED"): True,
    ("POINT", "RATE"): True,
    ("POINT", "SCALE"): True,
    ("POINT", "DATA_START"): True,
    ("POINT", "FRAMES"): True,
    ("ANALOG", "USED"): True,
    ("ANALOG", "RATE"): True,
    ("ANALOG", "GEN_SCALE"): True,
    ("ANALOG", "SCALE"): False,
    ("ANALOG", "OFFSET"): False,
    ("FORCE_PLATFORM", "USED"): True,
    ("FORCE_PLATFORM", "TYPE"): False,
    ("FORCE_PLATFORM", "ZERO"): False,
    ("FORCE_PLATFORM", "CORNERS"): False,
    ("FORCE_PLATFORM", "ORIGIN"): False,
    ("FORCE_PLATFORM", "CHANNEL"): False,
    ("FORCE_PLATFORM", "CAL_MATRIX"): False,
    ("EVENT", "USED"): True,
    ("EVENT", "TIMES"): False,
    ("TRIAL", "ACTUAL_START_FIELD"): False,
    ("TRIAL", "ACTUAL_END_FIELD"): False,
}
#: character parameters ezc3d reads as strings
_TEXT_PARAMS = (
    ("POINT", "LABELS"),
    ("POINT", "DESCRIPTIONS"),
    ("POINT", "UNITS"),
    ("ANALOG", "LABELS"),
    ("ANALOG", "DESCRIPTIONS"),
    ("ANALOG", "UNITS"),
    ("EVENT", "LABELS"),
    ("EVENT", "CONTEXTS"),
)
#: relative disagreement tolerated between a rate in the header and in the parameters
_RATE_RTOL = 1e-3


def _check_parameters(
    path: Path,
    params: Mapping[tuple[str, str], _RawParam],
    proc: int,
    header: Mapping[str, float],
) -> None:
    """Types and sizes of the parameters ezc3d dereferences, header/parameter consistency of
    rates and counts, force-platform parameter shapes and finite values."""
    vals: dict[tuple[str, str], NDArray[np.float64]] = {}
    for key, scalar in _NUMERIC_PARAMS.items():
        p = params.get(key)
        if p is None:
            continue
        v = _decode(p, proc)
        if v is None:
            raise C3DError(
                f"{path}: parameter {key[0]}:{key[1]} is stored as text (type char); "
                "it must be a number"
            )
        if scalar and v.size == 0:
            raise C3DError(f"{path}: parameter {key[0]}:{key[1]} holds no value (dims {p.dims})")
        if not np.isfinite(v).all():
            k = int(np.flatnonzero(~np.isfinite(v))[0])
            raise C3DError(f"{path}: parameter {key[0]}:{key[1]}[{k}] is {v[k]} (not finite)")
        vals[key] = v
    for key in _TEXT_PARAMS:
        p = params.get(key)
        if p is not None and p.type != -1:
            raise C3DError(
                f"{path}: parameter {key[0]}:{key[1]} is stored as numbers (type {p.type}); "
                "it must be text"
            )

    def first(group: str, name: str) -> float | None:
        v = vals.get((group, name))
        return float(v[0]) if v is not None and v.size else None

    def count(group: str, name: str) -> int | None:
        v = first(group, name)
        if v is None:
            return None
        p = params[(group, name)]
        # counts are unsigned 16-bit integers in practice (POINT:USED 40000 is stored as -25536)
        return int(v) % 65536 if p.type == 2 and v < 0 else int(v)

    n_points, n_frames = int(header["n_points"]), int(header["n_frames"])
    hdr_rate, samples = float(header["point_rate"]), int(header["analog_per_frame"])
    n_analog_words = int(header["n_analog_words"])
    used = count("POINT", "USED")
    if used is not None and used != n_points:
        raise C3DError(
            f"{path}: POINT:USED = {used} but the header declares {n_points} points per frame"
        )
    rate = first("POINT", "RATE")
    if rate is not None and (n_points or n_frames):
        if not rate > 0:
            raise C3DError(f"{path}: POINT:RATE = {rate:g} Hz is not positive")
        if not hdr_rate > 0 or abs(rate - hdr_rate) > _RATE_RTOL * hdr_rate:
            raise C3DError(
                f"{path}: POINT:RATE = {rate:g} Hz disagrees with the header's point rate "
                f"{hdr_rate:g} Hz"
            )
    elif n_points and not (hdr_rate > 0 and math.isfinite(hdr_rate)):
        raise C3DError(f"{path}: the header's point rate {hdr_rate:g} Hz is not positive")
    a_used = count("ANALOG", "USED")
    if a_used is not None and n_analog_words:
        if samples <= 0 or a_used * samples != n_analog_words:
            raise C3DError(
                f"{path}: ANALOG:USED = {a_used} channels x {samples} samples per frame "
                f"disagrees with the header's {n_analog_words} analog words per frame"
            )
    a_rate = first("ANALOG", "RATE")
    if a_rate is not None and n_analog_words and a_used:
        if not a_rate > 0:
            raise C3DError(f"{path}: ANALOG:RATE = {a_rate:g} Hz is not positive")
        expected = hdr_rate * samples
        if expected > 0 and abs(a_rate - expected) > _RATE_RTOL * expected:
            raise C3DError(
                f"{path}: ANALOG:RATE = {a_rate:g} Hz disagrees with the header "
                f"({samples} samples per frame at {hdr_rate:g} Hz = {expected:g} Hz)"
            )
    if a_used and n_analog_words:  # ezc3d indexes these per channel without a bound check
        for name in ("GEN_SCALE", "SCALE", "OFFSET"):
            v = vals.get(("ANALOG", name))
            need = 1 if name == "GEN_SCALE" else a_used
            if v is None or v.size < need:
                have = "is missing" if v is None else f"holds {v.size} values"
                raise C3DError(
                    f"{path}: ANALOG:{name} {have}; ANALOG:USED = {a_used} channels need {need}"
                )
    if (gs := first("ANALOG", "GEN_SCALE")) is not None and gs == 0 and a_used:
        raise C3DError(f"{path}: ANALOG:GEN_SCALE is 0: every analog value would be 0")
    _check_plate_params(path, params, vals, count("FORCE_PLATFORM", "USED"), a_used)


def _check_plate_params(
    path: Path,
    params: Mapping[tuple[str, str], _RawParam],
    vals: Mapping[tuple[str, str], NDArray[np.float64]],
    used: int | None,
    n_analog: int | None,
) -> None:
    """FORCE_PLATFORM parameter shapes: TYPE, CORNERS (3x4 per plate), ORIGIN (3 per plate)
    and CHANNEL (channels x plates) hold whole plates. Fewer plates described than
    ``FORCE_PLATFORM:USED`` declares, or a plate's channel outside the analogs, is no error
    here: :func:`_plates` drops that plate with a reader flag."""
    if not used:
        return
    if used > 64:
        raise C3DError(f"{path}: FORCE_PLATFORM:USED = {used} is not a number of plates")
    fp = "FORCE_PLATFORM"
    for name, per_plate in (("TYPE", 1), ("CORNERS", 12), ("ORIGIN", 3)):
        v = vals.get((fp, name))
        dims = params[(fp, name)].dims if (fp, name) in params else ()
        lead = {"CORNERS": (3, 4), "ORIGIN": (3,)}.get(name, ())
        shaped = len(dims) <= len(lead) or tuple(dims[: len(lead)]) == lead
        if v is not None and (v.size % per_plate or not shaped):
            raise ForcePlateError(
                f"{path}: {fp}:{name} holds {v.size} values (dims {params[(fp, name)].dims}); "
                f"{used} plates need {per_plate} each"
            )
    chan = vals.get((fp, "CHANNEL"))
    if chan is None:
        return
    dims = params[(fp, "CHANNEL")].dims
    if len(dims) > 2:
        raise C3DError(f"{path}: {fp}:CHANNEL has dims {dims}; it must be channels x plates")
    rows = dims[0] if len(dims) == 2 else (chan.size if used == 1 else chan.size // used)
    if chan.size and (rows == 0 or (len(dims) < 2 and chan.size % used)):
        raise ForcePlateError(
            f"{path}: {fp}:CHANNEL holds {chan.size} values (dims {dims}): "
            f"not a whole number of channels for {used} plates"
        )


# ---------------------------------------------------------------------------------------------
# parameter helpers
# ---------------------------------------------------------------------------------------------
def _param(params: Mapping[str, Any], group: str, name: str, default: Any = None) -> Any:
    try:
        return params[group][name]["value"]
    except (KeyError, TypeError):
        return default


def _labels(
    params: Mapping[str, Any], group: str, key: str, n: int, prefix: str | None
) -> list[str]:
    """``key``, ``key2``, ``key3``… concatenated, cut or padded to ``n``; blanks become
    ``prefix<k>`` (kept blank when ``prefix`` is None)."""
    out: list[str] = []
    vals = _param(params, group, key) or []
    out.extend(str(v).strip() for v in vals)
    i = 2
    while (more := _param(params, group, f"{key}{i}")) is not None:
        out.extend(str(v).strip() for v in more)
        i += 1
    out = out[:n] + [""] * max(0, n - len(out))
    if prefix is None:
        return out
    return [lab if lab else f"{prefix}{k + 1}" for k, lab in enumerate(out)]


def _first_number(params: Mapping[str, Any], group: str, names: Sequence[str]) -> float | None:
    """The first of ``names`` in ``group`` holding a finite number; names match whatever their
    case (Vicon writes ``PROCESSING:Bodymass``, UWA's pipeline ``BodyMass``)."""
    try:
        keys = {str(k).lower(): k for k in params[group]}
    except (KeyError, TypeError):
        return None
    for name in names:
        v = _param(params, group, keys.get(name.lower(), name))
        if v is not None and len(v) and isinstance(v, np.ndarray) and np.isfinite(v.flat[0]):
            return float(v.flat[0])
    return None


def _subject(params: Mapping[str, Any]) -> Subject:
    mass = None
    height = None
    for group in ("PROCESSING", "SUBJECTS", "SUBJECT"):
        if mass is None:
            mass = _first_number(params, group, ("Bodymass", "WEIGHT", "MASS"))
        if height is None:
            height = _first_number(params, group, ("Height",))
    if mass is not None and mass <= 0:
        mass = None
    if height is not None:
        # stored in mm by Vicon (1680), in m by some older systems (1.63)
        height = height / 1000.0 if height > 3.0 else height
        height = height if height > 0 else None
    name = None
    for group, key in (("SUBJECTS", "NAMES"), ("SUBJECT", "NAME")):
        v = _param(params, group, key)
        if v and str(v[0]).strip():
            name = str(v[0]).strip()
            break
    widths: dict[str, float] = {}
    for side, long in (("R", "Right"), ("L", "Left")):
        for joint, key in (("knee", "KneeWidth"), ("ankle", "AnkleWidth")):
            w = _first_number(params, "PROCESSING", (f"{side}{key}", f"{long}{key}"))
            if w is not None and w > 0:
                widths[f"{side}.{joint}"] = w / 1000.0  # Vicon stores mm
    # Plug-in Gait's hip-centre parameters (mm in the file; 0 = not measured)
    legs: dict[str, float] = {}
    troch: dict[str, float] = {}
    for side, long in (("R", "Right"), ("L", "Left")):
        for out, key in ((legs, "LegLength"), (troch, "AsisTrocanterDistance")):
            v = _first_number(params, "PROCESSING", (f"{side}{key}", f"{long}{key}"))
            if v is not None and v > 0:
                out[side] = v / 1000.0
    ia = _first_number(params, "PROCESSING", ("InterAsisDistance",))
    md = _first_number(params, "PROCESSING", ("MarkerDiameter",))
    return Subject(
        name=name, mass_kg=mass, height_m=height, widths_m=widths,
        marker_diameter_m=md / 1000.0 if md is not None and md > 0 else None,
        leg_lengths_m=legs, asis_trochanter_m=troch,
        inter_asis_m=ia / 1000.0 if ia is not None and ia > 0 else None,
    )  # fmt: skip


def _events(params: Mapping[str, Any]) -> tuple[Event, ...]:
    times = _param(params, "EVENT", "TIMES")
    labels = _param(params, "EVENT", "LABELS") or []
    contexts = _param(params, "EVENT", "CONTEXTS") or []
    if times is None or not len(labels):
        return ()
    t = np.asarray(times, dtype=float)
    secs = 60.0 * t[0] + t[1] if t.ndim == 2 and t.shape[0] == 2 else t.ravel()
    out = []
    for k, lab in enumerate(labels):
        if k >= secs.size:
            break
        ctx = str(contexts[k]).strip() if k < len(contexts) else ""
        out.append(Event(label=str(lab).strip(), context=ctx, time=float(secs[k])))
    return tuple(sorted(out, key=lambda e: (e.time, e.context, e.label)))


def _gait_events(events: tuple[Event, ...]) -> tuple[tuple[Event, ...], str]:
    """The events with every foot strike/off naming read as Vicon's (``LHS`` → ``Foot Strike``
    ``Left``…, :func:`msk.io.event_labels.standard_events`), the others kept as they are; and a
    message naming the labels not read as gait events ("" when every one was)."""
    from msk.io.event_labels import standard_events

    ok, other = standard_events(events)
    out = tuple(sorted((*ok, *other), key=lambda e: (e.time, e.context, e.label)))
    # Vicon's generic, deliberately unnamed events ("Event", "General Event") are no gait
    # events by design: not reported
    other = tuple(e for e in other if e.label.strip().lower() not in ("event", "general event"))
    if not other:
        return out, ""
    names = sorted({f"{e.context} {e.label!r}".strip() for e in other})
    return out, (
        f"{len(other)} event(s) not read as a foot strike or foot off of a side: "
        f"{', '.join(names)} (read: Vicon's 'Foot Strike'/'Foot Off' with a Left/Right context, "
        "LHS/RHS/LTO/RTO and the like: msk.io.event_labels); the gait events are taken from "
        "the plates and the kinematics where the file has none"
    )


# ---------------------------------------------------------------------------------------------
# force platforms (vectorised)
# ---------------------------------------------------------------------------------------------
def _apply(x: NDArray[np.float64], mat: NDArray[np.float64]) -> NDArray[np.float64]:
    """``x @ mat.T`` for tall ``x`` and a tiny matrix, as broadcast products.

    (numpy's matmul on (100000, 3) @ (3, 3) goes through BLAS and is ~20x slower.)
    """
    out = x[:, 0:1] * mat[:, 0]
    for j in range(1, mat.shape[1]):
        out = out + x[:, j : j + 1] * mat[:, j]
    return out


def _plates(
    path: Path,
    params: Mapping[str, Any],
    columns: Callable[[NDArray[np.int64]], NDArray[np.float64]],
    n_ch: int,
    analog_labels: Sequence[str],
    pos_scale: float,
    rate_hz: float,
    cop_threshold_n: float,
    flags: list[dict[str, Any]] | None = None,
) -> tuple[ForcePlate, ...]:
    """The force platforms of a C3D (conventions: the module docstring). A plate that
    ``FORCE_PLATFORM:USED`` declares but the other FORCE_PLATFORM parameters do not describe,
    or whose channel is outside the analogs, is dropped and said in ``flags`` (a
    :class:`ForcePlateError` when ``flags`` is None); plates described while ``USED`` is 0 or
    absent are said there too."""
    used_v = _param(params, "FORCE_PLATFORM", "USED")
    used = int(np.asarray(used_v).flat[0]) if used_v is not None and len(used_v) else 0
    fu = _param(params, "FORCE_PLATFORM", "UNITS")
    if used > 0 and fu and str(fu[0]).strip() not in ("N", ""):
        raise UnitsError(f"{path}: FORCE_PLATFORM:UNITS {fu[0]!r} is not supported (expected N)")
    types = np.atleast_1d(np.asarray(_param(params, "FORCE_PLATFORM", "TYPE", []), dtype=int))
    corners_all = np.asarray(_param(params, "FORCE_PLATFORM", "CORNERS", []), dtype=float)
    origin_all = np.asarray(_param(params, "FORCE_PLATFORM", "ORIGIN", []), dtype=float)
    chan = np.asarray(_param(params, "FORCE_PLATFORM", "CHANNEL", []), dtype=int)
    cal = _param(params, "FORCE_PLATFORM", "CAL_MATRIX")
    cal = np.asarray(cal, dtype=float) if cal is not None else np.empty(0)
    poly = _param(params, "FORCE_PLATFORM", "FPCOPPOLY")
    poly = np.asarray(poly, dtype=float).ravel(order="F") if poly is not None else np.empty(0)
    corners_all = corners_all.reshape(3, 4, -1, order="F") if corners_all.size else corners_all
    origin_all = origin_all.reshape(3, -1, order="F") if origin_all.size else origin_all
    if chan.ndim == 1 and chan.size:
        cols = used if used > 0 and chan.size % used == 0 else max(1, types.size)
        cols = cols if chan.size % cols == 0 else 1
        chan = chan.reshape(-1, cols, order="F")
    elif chan.ndim != 2:
        chan = np.zeros((0, 0), dtype=int)
    described = min(
        types.size,
        corners_all.shape[2] if corners_all.ndim == 3 else 0,
        origin_all.shape[1] if origin_all.ndim == 2 else 0,
        chan.shape[1],
    )
    undeclared = [
        p
        for p in range(max(used, 0), described)
        if chan.shape[0] and (chan[:, p] >= 1).all() and (chan[:, p] <= n_ch).all()
    ]
    if undeclared and used > 0 and flags is not None:
        on = "; ".join(
            ", ".join(analog_labels[int(i) - 1] for i in chan[:6, p]) for p in undeclared[:3]
        )
        flags.append(
            _reader_flag(
                "c3d_plates_not_declared",
                len(undeclared),
                used,
                f"FORCE_PLATFORM:USED = {used} but TYPE, CORNERS, ORIGIN and CHANNEL describe "
                f"{described} plates: force platform(s) "
                f"{', '.join(str(p + 1) for p in undeclared)} on analog channels {on} not read",
            )
        )
    if used <= 0:
        found = [
            p
            for p in range(described)
            if chan.shape[0] and (chan[:, p] >= 1).all() and (chan[:, p] <= n_ch).all()
        ]
        if found and flags is not None:
            on = "; ".join(
                ", ".join(analog_labels[int(i) - 1] for i in chan[:6, p]) for p in found[:3]
            )
            state = used if used_v is not None else "absent"
            flags.append(
                _reader_flag(
                    "c3d_plates_not_declared",
                    len(found),
                    0,
                    f"FORCE_PLATFORM describes {len(found)} plate(s) on analog channels {on} "
                    f"but FORCE_PLATFORM:USED is {state}: no plate read, no ground reaction",
                )
            )
        return ()
    plates: list[ForcePlate] = []
    used_by: dict[int, int] = {}
    for p in range(used):
        if p >= described:
            if flags is not None:
                flags.append(
                    _reader_flag("c3d_plate_missing", p + 1, described,
                                f"force platform {p + 1}: FORCE_PLATFORM:USED = {used} declares "
                                f"it but TYPE, CORNERS, ORIGIN and CHANNEL describe {described} "
                                "plate(s): it is not read")
                )  # fmt: skip
            continue
        typ = int(types[p])
        nchan = {1: 6, 2: 6, 4: 6, 3: 8}.get(typ)
        if nchan is None:
            raise ForcePlateError(
                f"{path}: force platform {p + 1} has type {typ}; msk reads types 1, 2, 3 and 4"
            )
        if chan.shape[0] < nchan:
            raise ForcePlateError(
                f"{path}: force platform {p + 1} (type {typ}) needs {nchan} channels, "
                f"FORCE_PLATFORM:CHANNEL has shape {chan.shape}"
            )
        idx = chan[:nchan, p] - 1
        if idx.min() < 0 or idx.max() >= n_ch:
            bad = [int(i) + 1 for i in idx if i < 0 or i >= n_ch]
            if flags is None:
                raise ForcePlateError(
                    f"{path}: force platform {p + 1} uses analog channel {bad[0]} but the file "
                    f"has {n_ch} analog channels"
                )
            flags.append(
                _reader_flag("c3d_plate_channel_missing", bad[0], n_ch,
                            f"force platform {p + 1} (type {typ}) uses analog channel "
                            f"{', '.join(map(str, bad))} (FORCE_PLATFORM:CHANNEL) but the file "
                            f"has {n_ch} analog channels: the plate is not read")
            )  # fmt: skip
            continue
        twice = [int(i) for i in set(idx.tolist()) if int((idx == i).sum()) > 1]
        if twice:
            raise ForcePlateError(
                f"{path}: force platform {p + 1} uses analog channel {twice[0] + 1} "
                f"({analog_labels[twice[0]]!r}) for two of its components "
                f"(FORCE_PLATFORM:CHANNEL {[int(i) + 1 for i in idx]})"
            )
        if flags is not None:
            flags.extend(_channel_label_flags(p, typ, [analog_labels[int(i)] for i in idx]))
        for i in idx:
            if used_by.setdefault(int(i), p) != p:
                raise ForcePlateError(
                    f"{path}: analog channel {i + 1} ({analog_labels[i]!r}) is used by force "
                    f"platforms {used_by[int(i)] + 1} and {p + 1}"
                )
        c = corners_all[:, :, p].T  # (4, 3) file units
        o = origin_all[:, p].copy()
        if o[2] > 0:
            o = -o
        try:
            rot = plate_axes(c)
        except ValueError:
            raise ForcePlateError(
                f"{path}: force platform {p + 1} has degenerate corners {c.tolist()}"
            ) from None
        centre = c.mean(axis=0)
        ch = columns(idx)  # (Na, nchan) file units
        if typ == 1:
            # Fx Fy Fz, COP (Px, Py) on the surface about its centre, free moment Mz: all in the
            # plate axes; the moment about the centre is c x F + (0, 0, Mz)
            f_raw = ch[:, :3]
            fz = f_raw[:, 2]
            loaded = np.abs(fz) >= cop_threshold_n
            cop_raw = np.column_stack([ch[:, 3], ch[:, 4], np.zeros_like(fz)])
            t_raw = np.column_stack([np.zeros_like(fz), np.zeros_like(fz), ch[:, 5]])
            m_raw = np.cross(cop_raw, f_raw) + t_raw
            cop_raw[~loaded] = np.nan
            t_raw[~loaded] = 0.0
        else:
            if typ == 3:
                a, b, az0 = o
                f_raw = np.column_stack(
                    [ch[:, 0] + ch[:, 1], ch[:, 2] + ch[:, 3], ch[:, 4:8].sum(1)]
                )
                m_raw = np.column_stack(
                    [
                        b * (ch[:, 4] + ch[:, 5] - ch[:, 6] - ch[:, 7]),
                        a * (ch[:, 5] + ch[:, 6] - ch[:, 4] - ch[:, 7]),
                        b * (ch[:, 1] - ch[:, 0]) + a * (ch[:, 2] - ch[:, 3]),
                    ]
                )
                m_raw = m_raw + np.cross(f_raw, np.array([0.0, 0.0, az0]))
            else:
                data = ch
                if typ == 4:
                    if cal.ndim == 3 and cal.shape[2] > p:
                        data = _apply(ch, cal[:6, :6, p])
                    elif cal.size and not (cal.ndim == 3 and cal.shape[2] > p):
                        raise ForcePlateError(
                            f"{path}: force platform {p + 1} (type 4) has no 6x6 CAL_MATRIX "
                            f"(CAL_MATRIX shape {cal.shape})"
                        )
                f_raw = data[:, :3]
                m_raw = data[:, 3:6] + np.cross(data[:, :3], o)
            fz = f_raw[:, 2]
            with np.errstate(divide="ignore", invalid="ignore"):
                cop_raw = np.column_stack([-m_raw[:, 1] / fz, m_raw[:, 0] / fz, np.zeros_like(fz)])
            if typ == 3 and poly.size >= 12 * (p + 1):
                k = poly[12 * p : 12 * (p + 1)]
                x, y = cop_raw[:, 0].copy(), cop_raw[:, 1].copy()
                dx = (k[0] * y**4 + k[1] * y**2 + k[2]) * x**3 + (
                    k[3] * y**4 + k[4] * y**2 + k[5]
                ) * x
                dy = (k[6] * x**4 + k[7] * x**2 + k[8]) * y**3 + (
                    k[9] * x**4 + k[10] * x**2 + k[11]
                ) * y
                cop_raw[:, 0] = x - dx
                cop_raw[:, 1] = y - dy
            loaded = np.abs(fz) >= cop_threshold_n
            cop_raw[~loaded] = np.nan
            t_raw = m_raw + np.cross(f_raw, np.nan_to_num(cop_raw))
            t_raw[~loaded] = 0.0
            t_raw[:, :2] = 0.0  # zero by construction of the COP (type 3: normal part only)
        plates.append(
            ForcePlate(
                index=p,
                type=typ,
                force=_apply(f_raw, rot),
                moment=_apply(m_raw, rot) * pos_scale,
                cop=(_apply(cop_raw, rot) + centre) * pos_scale,
                free_moment=_apply(t_raw, rot) * pos_scale,
                corners=c * pos_scale,
                origin=centre * pos_scale,
                rotation=rot,
                channels=tuple(analog_labels[i] for i in idx),
                rate_hz=rate_hz,
            )
        )
    return tuple(plates)


#: the component each channel of a plate of types 1, 2 and 4 carries, in C3D order
_PLATE_COMPONENTS = {
    1: ("fx", "fy", "fz", "px", "py", "mz"),
    2: ("fx", "fy", "fz", "mx", "my", "mz"),
    4: ("fx", "fy", "fz", "mx", "my", "mz"),
}
_COMPONENT_NAMES = frozenset({"fx", "fy", "fz", "mx", "my", "mz", "px", "py"})


def _channel_label_flags(p: int, typ: int, labels: Sequence[str]) -> list[dict[str, Any]]:
    """A plate whose channels are labelled by component (``Fx1``, ``FZ2``, ``PF1Mx``,
    ``F1X``: the letters of the label end with the component) but one of which names another
    component or none (``Fy1`` where Fz is read, ``gracilis``): ``FORCE_PLATFORM:CHANNEL``
    points at another signal. Judged only when at least 4 of its 6 labels name a component."""
    want = _PLATE_COMPONENTS.get(typ)
    if want is None or len(labels) != len(want):
        return []
    comp = [re.sub(r"[^a-z]", "", lab.lower())[-2:] for lab in labels]
    if sum(c in _COMPONENT_NAMES for c in comp) < 4:
        return []
    bad = [(k, labels[k]) for k in range(len(want)) if comp[k] != want[k]]
    if not bad:
        return []
    said = ", ".join(f"{lab!r} as its {want[k][0].upper()}{want[k][1]}" for k, lab in bad)
    return [
        _reader_flag(
            "c3d_plate_channel_label",
            len(bad),
            0,
            f"force platform {p + 1} reads {said} (its channels: {', '.join(labels)}): "
            "FORCE_PLATFORM:CHANNEL points at another signal",
        )
    ]


def _reader_flag(quantity: str, value: float, threshold: float, message: str) -> dict[str, Any]:
    return {"quantity": quantity, "value": float(value), "threshold": float(threshold),
            "message": message}  # fmt: skip


def _vertical(
    params: Mapping[str, Any], plates: Sequence[ForcePlate]
) -> tuple[int, NDArray[np.float64]]:
    """Vertical lab axis from the plate normals (sign from the loaded reaction), else Y_SCREEN."""
    if plates:
        normals = np.abs(np.array([p.normal for p in plates])).sum(axis=0)
        axis = int(np.argmax(normals))
        fv = np.concatenate([p.force[:, axis] for p in plates])
        s = np.nansum(fv)
        sign = 1.0 if (not np.isfinite(s) or s >= 0) else -1.0
    else:
        ys = _param(params, "POINT", "Y_SCREEN")
        ys = str(ys[0]).strip().upper() if ys else ""
        if len(ys) == 2 and ys[1] in _AXES and ys[0] in "+-":
            # only the axis: the sign of Y_SCREEN is a display choice (FP_Type3.c3d says -Z)
            axis, sign = _AXES.index(ys[1]), 1.0
        else:
            axis, sign = 2, 1.0
    up = np.zeros(3)
    up[axis] = sign
    return axis, up


# ---------------------------------------------------------------------------------------------
# plausibility of what was read
# ---------------------------------------------------------------------------------------------
#: largest point and analog rates accepted (Hz): anything above is a corrupt header
MAX_POINT_RATE_HZ = 20_000.0
MAX_ANALOG_RATE_HZ = 1_000_000.0
#: point rates of motion capture (Hz): outside, a reader warning (a corrupted or wrong rate)
PLAUSIBLE_POINT_RATE_HZ = (1.0, 5_000.0)
_CONTROL = re.compile(r"[\x00-\x1f\x7f]")


def _check_rates(path: Path, point_rate: float, n_pts: int, analog_rate: float, n_ana: int) -> None:
    if n_pts and not (0 < point_rate <= MAX_POINT_RATE_HZ):
        raise C3DError(
            f"{path}: point rate {point_rate:g} Hz is not plausible "
            f"(expected 0 < rate <= {MAX_POINT_RATE_HZ:g} Hz)"
        )
    if n_ana and not (0 < analog_rate <= MAX_ANALOG_RATE_HZ):
        raise C3DError(
            f"{path}: analog rate {analog_rate:g} Hz is not plausible "
            f"(expected 0 < rate <= {MAX_ANALOG_RATE_HZ:g} Hz)"
        )


def _check_labels(
    path: Path, what: str, labels: list[str], warnings: list[str], *, rename: bool = True
) -> list[str]:
    """Labels with control characters are refused; a repeated label keeps its name on its first
    occurrence and (``rename``) becomes ``LABEL#2``, ``LABEL#3``… after, with a warning."""
    for k, lab in enumerate(labels):
        if _CONTROL.search(lab):
            raise C3DError(f"{path}: {what}[{k + 1}] = {lab!r} holds control characters")
    seen: dict[str, int] = {}
    out = []
    renamed: list[str] = []
    for lab in labels:
        n = seen.get(lab, 0) + 1
        seen[lab] = n
        if n > 1 and rename:
            new = f"{lab}#{n}"
            while new in seen:
                n += 1
                new = f"{lab}#{n}"
            seen[new] = 1
            renamed.append(f"{lab} -> {new}")
            out.append(new)
        else:
            out.append(lab)
    dup = [lab for lab, n in seen.items() if n > 1]
    if dup:
        how = (
            f"the first keeps the name, the others are renamed ({', '.join(renamed)})"
            if rename
            else "a look-up by name finds the first"
        )
        warnings.append(f"{what}: repeated labels {', '.join(dup)}: {how}")
    return out


def _check_coordinates(
    path: Path, markers: NDArray[np.float64], labels: Sequence[str], time: NDArray[np.float64]
) -> None:
    """Marker coordinates beyond :data:`msk.io.validate.MAX_ABS_COORDINATE_M` are corrupt."""
    if not markers.size:
        return
    with np.errstate(invalid="ignore"):
        bad = np.abs(markers) > MAX_ABS_COORDINATE_M
    bad |= np.isinf(markers)
    if bad.any():
        f, m, a = (int(i[0]) for i in np.nonzero(bad))
        t = f" (t = {time[f]:.3f} s)" if f < time.size else ""
        raise C3DError(
            f"{path}: marker {labels[m]!r} has {_AXES[a]} = {markers[f, m, a]:.6g} m at frame "
            f"{f + 1}{t}: beyond {MAX_ABS_COORDINATE_M:g} m from the lab origin"
        )


def _drop_teleports(
    markers: NDArray[np.float64],
    labels: Sequence[str],
    rate_hz: float,
    flags: list[dict[str, Any]],
) -> int | None:
    """Marker samples on a teleport (:func:`msk.io.marker_checks.find_teleports`: a trajectory
    jumping away and back, a swapped or ghost label) made gaps in ``markers`` (in place) and
    said by one ``marker_teleport_samples`` flag naming the markers, frames (1-based) and
    distances; the number of samples dropped, None when there is none."""
    from msk.io.marker_checks import MAX_MARKER_ACCELERATION, find_teleports

    found = find_teleports(markers, labels, rate_hz)
    if not found:
        return None
    col = {lab: k for k, lab in enumerate(labels)}
    n = 0
    for t in found:
        markers[t.first : t.last + 1, col[t.label]] = np.nan
        n += t.last - t.first + 1
    thr = max(0.05, MAX_MARKER_ACCELERATION / rate_hz**2)
    where = "; ".join(
        f"{t.label} frame{'s' if t.last > t.first else ''} {t.first + 1}"
        + (f"–{t.last + 1}" if t.last > t.first else "")
        + f" ({1000 * t.distance_m:.0f} mm)"
        for t in found[:5]
    ) + (f"; and {len(found) - 5} more" if len(found) > 5 else "")
    flags.append(
        _reader_flag("marker_teleport_samples", n, thr,
                    f"{len(found)} marker teleport(s) (the trajectory jumps more than "
                    f"{1000 * thr:.0f} mm off its path and back: a swapped or ghost label): "
                    f"{where}; those {n} samples are gaps")
    )  # fmt: skip
    return n


def _check_plate_forces(
    path: Path, plates: Sequence[ForcePlate], time: NDArray[np.float64], warnings: list[str]
) -> None:
    """Infinite forces or forces beyond :data:`msk.io.validate.MAX_ABS_FORCE_N` are refused
    (naming plate, channel, sample and value); NaN samples are missing data (a warning), and
    so is a clipped channel (:func:`msk.io.plate_checks.saturation_warnings`)."""
    for p in plates:
        f = p.force
        with np.errstate(invalid="ignore"):
            bad = np.isinf(f) | (np.abs(f) > MAX_ABS_FORCE_N)
        if bad.any():
            i, a = (int(x[0]) for x in np.nonzero(bad))
            ch = p.channels[a] if p.type != 3 and a < len(p.channels) else "/".join(p.channels)
            t = f" (t = {time[i]:.4f} s)" if i < time.size else ""
            raise ForcePlateError(
                f"{path}: force platform {p.index + 1} reads F{_AXES[a].lower()} = "
                f"{f[i, a]:.6g} N at sample {i + 1}{t} (channels {ch}): beyond "
                f"{MAX_ABS_FORCE_N:g} N, not a ground reaction"
            )
        nan = ~np.isfinite(f).all(axis=1)
        if nan.any():
            warnings.append(
                f"force platform {p.index + 1}: {int(nan.sum())} of {nan.size} samples are NaN "
                "(missing)"
            )
        warnings.extend(saturation_warnings(p))  # a clipped channel (msk.io.plate_checks)
        warnings.extend(cop_warnings(p))  # a COP far off the plate


# ---------------------------------------------------------------------------------------------
# reading
# ---------------------------------------------------------------------------------------------
#: environment switch: ``MSK_ISOLATE_C3D=1`` reads every C3D in a child process (batch workers
#: set it), ``MSK_C3D_TIMEOUT_S`` bounds the child's time (default 300 s)
ISOLATE_ENV = "MSK_ISOLATE_C3D"
TIMEOUT_ENV = "MSK_C3D_TIMEOUT_S"


def _child_read(
    conn: Any,
    path: str,
    cop_threshold_n: float,
    plate_channels: bool = True,
    stored_analogs: bool = False,
) -> None:  # pragma: no cover
    """Body of the isolated reader (runs in a spawned child)."""
    try:
        out: Any = (
            "ok",
            read_c3d(
                path,
                cop_threshold_n=cop_threshold_n,
                isolate=False,
                plate_channels=plate_channels,
                stored_analogs=stored_analogs,
            ),
        )
    except MskError as exc:
        out = ("error", type(exc).__name__, str(exc))
    except Exception as exc:
        out = ("error", "C3DError", f"{path}: msk cannot read it: {type(exc).__name__}: {exc}")
    conn.send(out)
    conn.close()


def _reader_context() -> Any:
    """Start method of the isolated reader: a fork of a server process that has imported this
    module once (``forkserver``: ~10 ms a file instead of a fresh interpreter importing numpy
    and ezc3d, ~0.15 s, every time; the child still shares no state with the caller), or
    ``spawn`` where there is no ``forkserver``."""
    import multiprocessing as mp

    if "forkserver" not in mp.get_all_start_methods():  # pragma: no cover - Windows
        return mp.get_context("spawn")
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload([__name__])
    return ctx


def _read_isolated(
    path: Path,
    cop_threshold_n: float,
    timeout_s: float,
    target: Any = None,
    *,
    plate_channels: bool = True,
    stored_analogs: bool = False,
) -> Trial:
    """:func:`read_c3d` in a spawned child: a native crash or a hang of the reader costs this
    file (a :class:`C3DError`), never the calling process or its pool. (A daemonic process,
    e.g. a Dask worker, may not have children: it reads in-process.)"""
    import multiprocessing as mp

    from msk import exceptions

    if mp.current_process().daemon:
        return read_c3d(
            path,
            cop_threshold_n=cop_threshold_n,
            isolate=False,
            plate_channels=plate_channels,
            stored_analogs=stored_analogs,
        )
    ctx = _reader_context()
    recv, send = ctx.Pipe(duplex=False)
    args = (send, str(path), cop_threshold_n) + (
        () if plate_channels and not stored_analogs else (plate_channels, stored_analogs)
    )
    proc = ctx.Process(target=target or _child_read, args=args, daemon=True)
    proc.start()
    send.close()
    try:
        if not recv.poll(timeout_s):
            proc.kill()
            proc.join(5)
            if proc.exitcode is not None and proc.exitcode != -9:
                raise C3DError(f"{path}: the C3D reader {_death(proc.exitcode)}")
            raise C3DError(f"{path}: the C3D reader did not finish in {timeout_s:g} s")
        try:
            out = recv.recv()
        except EOFError:
            proc.join(5)
            raise C3DError(f"{path}: the C3D reader {_death(proc.exitcode)}") from None
    finally:
        recv.close()
        proc.join(5)
        if proc.is_alive():
            proc.kill()
    if out[0] == "ok":
        return out[1]
    cls = getattr(exceptions, out[1], C3DError)
    raise (cls if isinstance(cls, type) and issubclass(cls, MskError) else C3DError)(out[2])


def _death(code: int | None) -> str:
    import signal

    if code is not None and code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        return f"crashed ({name}): the file is corrupt in a way msk does not detect"
    return f"exited with status {code} without an answer"


def plate_axes(corners: ArrayLike) -> NDArray[np.float64]:
    """A force plate's axes in the lab from its four ``FORCE_PLATFORM:CORNERS`` (4, 3) (C3D User
    Guide, Motion Lab Systems 2008, "The FORCE_PLATFORM group"; corners numbered around the
    plate, the first in the plate's +x +y quadrant): x along c₀ − c₁, z = x × (c₀ − c₃), y = z × x;
    returned as the columns of a rotation (3, 3).

    Raises:
        ValueError: degenerate corners (coincident or collinear).
    """
    c = np.asarray(corners, dtype=float)
    ax = c[0] - c[1]
    az = np.cross(ax, c[0] - c[3])
    nx, nz = float(np.linalg.norm(ax)), float(np.linalg.norm(az))
    if nx == 0 or nz == 0:
        raise ValueError(f"degenerate force-plate corners {c.tolist()}")
    ay = np.cross(az, ax)
    return np.column_stack([ax / nx, ay / np.linalg.norm(ay), az / nz])


def _one_line_errors(reader: Callable[..., Trial]) -> Callable[..., Trial]:
    """A malformed file the reader's checks did not foresee (a parameter of an unexpected
    shape or type: TypeError, IndexError, ValueError, KeyError, OverflowError,
    ZeroDivisionError, RecursionError) raises a :class:`~msk.exceptions.C3DError` naming the
    file and the error, never a traceback."""

    @functools.wraps(reader)
    def read(path: str | Path, *args: Any, **kwargs: Any) -> Trial:
        try:
            return reader(path, *args, **kwargs)
        except MskError:
            raise
        except (
            TypeError, IndexError, ValueError, KeyError, OverflowError, ZeroDivisionError,
            RecursionError,
        ) as exc:  # fmt: skip
            what = " ".join(str(exc).split())[:300]
            raise C3DError(
                f"{path}: inconsistent C3D content ({type(exc).__name__}: {what})"
            ) from exc

    return read


@_one_line_errors
def read_c3d(
    path: str | Path,
    *,
    cop_threshold_n: float = 20.0,
    isolate: bool | None = None,
    plate_channels: bool = True,
    stored_analogs: bool = False,
) -> Trial:
    """Read a C3D file into a :class:`Trial` (SI units, time on axis 0).

    Raises :class:`C3DError` for a missing, empty, truncated, corrupt or non-C3D file and for a
    file with neither points nor analogs; :class:`UnitsError` for unknown ``POINT:UNITS``;
    :class:`ForcePlateError` for inconsistent force-platform parameters.

    msk reads the file itself (header and parameters checked first, :func:`_check_bytes`; the
    data section block by block, float or integer storage, Intel, DEC and MIPS processors); a
    file of more than 65 535 frames is read whole when ``TRIAL:ACTUAL_START_FIELD`` /
    ``ACTUAL_END_FIELD`` give its frames (the header's last frame saturates; ezc3d 1.7 reads
    the first 65 535 or ``POINT:FRAMES``). ``stored_analogs=True`` (with
    ``plate_channels=False``) holds the kept channels as stored (:class:`msk.analogs.
    StoredAnalogs`: int16 or float32, scaled per channel when indexed, the same float64 values;
    a DEC file's as float64). ``plate_channels=False`` leaves the force
    platforms' analog channels out of :attr:`Trial.analogs` (the plates are computed from them,
    one plate at a time): what a session keeps of a long trial.

    ``isolate`` (default: ``MSK_ISOLATE_C3D=1`` in the environment) reads in a child process
    bounded by ``MSK_C3D_TIMEOUT_S`` (300 s): a crash or hang of the reader becomes a
    :class:`C3DError` (batch workers use it, so a bad file costs one session).
    """
    path = Path(path)
    if not cop_threshold_n >= 0:
        raise MskError(f"{path}: cop_threshold_n must be >= 0 N, got {cop_threshold_n}")
    lay = _check_bytes(path)
    if isolate is None:
        isolate = os.environ.get(ISOLATE_ENV, "") == "1"
    if isolate:
        try:
            timeout_s = float(os.environ.get(TIMEOUT_ENV, "300"))
        except ValueError:
            timeout_s = 300.0
        timeout_s = timeout_s if math.isfinite(timeout_s) and timeout_s > 0 else 300.0
        return _read_isolated(
            path,
            cop_threshold_n,
            timeout_s,
            plate_channels=plate_channels,
            stored_analogs=stored_analogs,
        )
    params = _parameter_values(lay.params, lay.proc)
    n_pts, n_frames, samples = lay.n_points, lay.n_frames, lay.analog_per_frame
    n_ana = lay.n_analog_words // samples if samples else 0
    if n_pts == 0 and (n_ana == 0 or n_frames * samples == 0):
        raise C3DError(f"{path}: no point and no analog data")
    point_rate = float(lay.point_rate)
    analog_rate = point_rate * samples if n_ana else 0.0
    if n_pts and not point_rate > 0:
        raise C3DError(f"{path}: point rate {point_rate} Hz is not positive")
    first = lay.first_frame - 1  # 0-based, as ezc3d reports it
    flags: list[dict[str, Any]] = list(lay.flags)  # typed reader flags (metadata["flags"])
    analog_labels = tuple(_labels(params, "ANALOG", "LABELS", n_ana, "ANALOG"))
    analog_units = tuple(_labels(params, "ANALOG", "UNITS", n_ana, None))
    if plate_channels:
        pts, invalid, all_analogs = _read_data(path, lay, range(n_ana))
        analogs = np.asarray(all_analogs)
        plate_used: set[int] = set()

        def columns(idx: NDArray[np.int64]) -> NDArray[np.float64]:
            return analogs[:, idx]
    else:
        plate_used = set()

        def columns(idx: NDArray[np.int64]) -> NDArray[np.float64]:
            plate_used.update(int(i) for i in idx)
            return np.asarray(_read_data(path, lay, idx, points=False)[2])

    # --- units
    # --- units
    units_v = _param(params, "POINT", "UNITS") or []
    unit = str(units_v[0]).strip() if len(units_v) else ""
    if unit in LENGTH_UNITS_M:
        pos_scale = LENGTH_UNITS_M[unit]
    elif unit == "" and n_pts == 0:
        pos_scale, unit = 1e-3, "mm"  # no points: plate geometry is conventionally mm
    else:
        raise UnitsError(
            f"{path}: POINT:UNITS {unit!r} is not a known length unit "
            f"(expected one of {sorted(LENGTH_UNITS_M)})"
        )

    # --- points: markers vs model outputs
    labels = _labels(params, "POINT", "LABELS", n_pts, "POINT")
    kind_of: dict[str, str] = {}
    for kind in MODEL_OUTPUT_KINDS:
        for lab in _param(params, "POINT", kind) or []:
            kind_of.setdefault(str(lab).strip(), kind)
    is_out = np.array([lab in kind_of for lab in labels], dtype=bool)
    if not plate_channels:  # plates first, one at a time; then the points and other channels
        plates = _plates(
            path,
            params,
            columns,
            n_ana,
            analog_labels,
            pos_scale,
            analog_rate,
            cop_threshold_n,
            flags,
        )
        keep = [i for i in range(n_ana) if i not in plate_used]
        pts, invalid, kept = _read_data(path, lay, keep, stored=stored_analogs)
        analog_labels = tuple(analog_labels[i] for i in keep)
        analog_units = tuple(analog_units[i] for i in keep)
    xyz = pts if n_pts else np.zeros((n_frames, 0, 3))
    mk = xyz[:, ~is_out] if is_out.any() else xyz
    missing = invalid[:, ~is_out] if n_pts else np.zeros(mk.shape[:2], dtype=bool)
    missing |= np.isnan(mk).any(axis=2) | (mk == 0).all(axis=2)
    markers = mk  # a copy of the points when some are model outputs, else the points
    markers *= pos_scale
    markers[missing] = np.nan
    marker_labels = tuple(lab for lab, o in zip(labels, is_out) if not o)
    gaps = GapReport.from_missing(marker_labels, missing)
    out_labels = tuple(lab for lab, o in zip(labels, is_out) if o)
    out_kinds = tuple(kind_of[lab] for lab in out_labels)
    out_data = xyz[:, is_out] if n_pts else np.zeros((n_frames, 0, 3))
    if n_pts:
        out_data[invalid[:, is_out]] = np.nan
    del pts, xyz, mk
    out_units = []
    unit_params = {
        "ANGLES": "ANGLE_UNITS",
        "MOMENTS": "MOMENT_UNITS",
        "FORCES": "FORCE_UNITS",
        "REACTIONS": "FORCE_UNITS",
    }
    for k, kind in enumerate(out_kinds):
        u = _param(params, "POINT", unit_params.get(kind, "POWER_UNITS")) or [""]
        u = str(u[0]).strip()
        if kind == "ANGLES":
            if u.lower() in ("deg", "degree", "degrees", ""):
                out_data[:, k] = np.deg2rad(out_data[:, k])
            u = "rad"
        elif kind == "MOMENTS" and u.lower() in ("nmm", "n.mm", "n·mm"):
            out_data[:, k] *= 1e-3
            u = "N.m"
        out_units.append(u)
    model_outputs = ModelOutputs(out_labels, out_kinds, tuple(out_units), out_data)

    # --- analogs
    held: NDArray[np.float64] | StoredAnalogs = analogs if plate_channels else kept
    if not n_ana:
        held = np.zeros((n_frames * samples, 0))
    t0 = first / point_rate if point_rate > 0 else 0.0
    time = t0 + np.arange(n_frames) / point_rate if point_rate > 0 else np.zeros(0)
    analog_time = t0 + np.arange(n_frames * samples) / analog_rate if analog_rate else np.zeros(0)

    warnings: list[str] = []
    _check_rates(path, point_rate, n_pts, analog_rate, n_ana)
    lo, hi = PLAUSIBLE_POINT_RATE_HZ
    if n_pts and not lo <= point_rate <= hi:  # readable, but no motion capture runs so
        warnings.append(
            f"point rate {point_rate:g} Hz is outside the {lo:g}–{hi:g} Hz of motion capture: "
            "check the header's frame rate (every time, velocity and filter depends on it)"
        )
    labels_ok = [*_check_labels(path, "POINT:LABELS", list(marker_labels), warnings)]
    if labels_ok != list(marker_labels):
        marker_labels = tuple(labels_ok)
        gaps = GapReport(
            labels=marker_labels, n_missing=gaps.n_missing, longest_gap=gaps.longest_gap
        )
    # a subject prefix (``JW:LASI``) dropped once, here, for every trial alike
    from msk.model.markersets import strip_subject_prefix

    marker_labels, label_prefix = strip_subject_prefix(marker_labels)
    if label_prefix:
        gaps = GapReport(
            labels=marker_labels, n_missing=gaps.n_missing, longest_gap=gaps.longest_gap
        )
    _check_labels(path, "ANALOG:LABELS", list(analog_labels), warnings, rename=False)
    _check_coordinates(path, markers, marker_labels, time)
    teleported = _drop_teleports(markers, marker_labels, point_rate, flags)
    if teleported is not None:
        gaps = GapReport.from_missing(marker_labels, np.asarray(np.isnan(markers).any(axis=2)))
    if plate_channels:
        plates = _plates(
            path,
            params,
            columns,
            n_ana,
            analog_labels,
            pos_scale,
            analog_rate,
            cop_threshold_n,
            flags,
        )
    _check_plate_forces(path, plates, analog_time, warnings)
    events = _events(params)
    bad_ev = [e for e in events if not math.isfinite(e.time)]
    if bad_ev:
        raise C3DError(
            f"{path}: event {bad_ev[0].context} {bad_ev[0].label!r} has time {bad_ev[0].time} "
            "(EVENT:TIMES not finite)"
        )
    events, unknown_ev = _gait_events(events)
    if unknown_ev:
        warnings.append(unknown_ev)
    vertical_axis, up = _vertical(params, plates)
    warnings.extend(direction_warnings(plates, up, markers))  # a negative gain
    subject = _subject(params)
    flags.extend(scale_flags(plates, up, subject.mass_kg))
    warnings.extend(f["message"] for f in flags)
    meta = {
        "first_frame": first,
        "manufacturer": str((_param(params, "MANUFACTURER", "COMPANY") or [""])[0]).strip(),
        "warnings": tuple(warnings),
        "flags": tuple(flags),
        "label_prefix": label_prefix,
    }
    return Trial(
        path=path,
        point_rate_hz=point_rate,
        time=time,
        markers=markers,
        marker_labels=marker_labels,
        gaps=gaps,
        model_outputs=model_outputs,
        analog_rate_hz=analog_rate,
        analog_time=analog_time,
        analogs=held,
        analog_labels=analog_labels,
        analog_units=analog_units,
        plates=plates,
        events=events,
        subject=subject,
        vertical_axis=vertical_axis,
        up=up,
        point_units_in_file=unit,
        metadata=meta,
    )


# ---------------------------------------------------------------------------------------------
# writing (synthetic trials, round trips, benchmarks)
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PlateSpec:
    """A force platform to declare in a written C3D.

    ``channels`` are analog labels (6 for types 1/2/4, 8 for type 3) in C3D order (type 1:
    Fx Fy Fz Px Py Mz, the COP about the centre of the surface in point units); ``corners_m``
    ``(4, 3)`` and ``origin_m`` (transducer offset, plate axes) are in metres and written in the
    file's point units. Moment channels must already be in N·<point units>.
    """

    channels: tuple[str, ...]
    corners_m: NDArray[np.float64]
    origin_m: NDArray[np.float64]
    type: int = 2
    cal_matrix: NDArray[np.float64] | None = None


def _set_param(c: Any, group: str, name: str, value: Any) -> None:
    p = c["parameters"]
    if group not in p:
        p[group] = {"__METADATA__": {"DESCRIPTION": "", "IS_LOCKED": False}}
    if isinstance(value, str):
        value = [value]
    val: Any
    if isinstance(value, list | tuple) and value and isinstance(value[0], str):
        typ, val = -1, [str(v) for v in value]
    else:
        arr = np.atleast_1d(np.asarray(value))
        typ = 2 if np.issubdtype(arr.dtype, np.integer) else 4
        val = arr.astype(int) if typ == 2 else arr.astype(float)
    p[group][name] = {"type": typ, "description": "", "is_locked": False, "value": val}


def write_c3d(
    path: str | Path,
    *,
    markers: ArrayLike,
    marker_labels: Sequence[str],
    rate_hz: float,
    point_units: str = "m",
    residuals: ArrayLike | None = None,
    analogs: ArrayLike | None = None,
    analog_labels: Sequence[str] = (),
    analog_units: Sequence[str] | None = None,
    analog_ratio: int = 1,
    plates: Sequence[PlateSpec] = (),
    events: Sequence[Event] = (),
    subject: Subject | None = None,
    first_frame: int = 0,
) -> Path:
    """Write a C3D with ezc3d from arrays: markers ``(N, M, 3)`` in metres (NaN = gap), written
    in ``point_units``; analogs ``(N * analog_ratio, C)`` written as given.

    Used for synthetic ground-truth trials, round-trip tests and benchmarks.
    """
    import ezc3d

    if point_units not in LENGTH_UNITS_M:
        raise UnitsError(f"{path}: point units {point_units!r} not in {sorted(LENGTH_UNITS_M)}")
    scale = LENGTH_UNITS_M[point_units]
    x = np.asarray(markers, dtype=float)
    n, m = x.shape[0], x.shape[1]
    if len(marker_labels) != m:
        raise MskError(f"{path}: {len(marker_labels)} marker labels for {m} markers")
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [float(rate_hz)]
    c["parameters"]["POINT"]["LABELS"]["value"] = list(marker_labels)
    c["parameters"]["ANALOG"]["RATE"]["value"] = [float(rate_hz * analog_ratio)]
    _set_param(c, "POINT", "UNITS", point_units)
    pts = np.ones((4, m, n))
    pts[:3] = np.transpose(x / scale, (2, 1, 0))
    gap = np.isnan(x).any(axis=2).T
    pts[:3, gap] = 0.0
    c["data"]["points"] = pts
    res = np.zeros((1, m, n)) if residuals is None else np.asarray(residuals, float).T[None]
    res = res.copy()
    res[0, gap] = -1.0
    c["data"]["meta_points"]["residuals"] = res
    c["data"]["meta_points"]["camera_masks"] = np.zeros((7, m, n), dtype=bool)
    a = np.zeros((n * analog_ratio, 0)) if analogs is None else np.asarray(analogs, dtype=float)
    c["parameters"]["ANALOG"]["LABELS"]["value"] = list(analog_labels)
    if a.shape[0] != n * analog_ratio:
        raise MskError(
            f"{path}: {a.shape[0]} analog samples for {n} frames x analog_ratio {analog_ratio}"
        )
    c["data"]["analogs"] = a.T[None].copy()
    if a.shape[1]:
        if analog_units is not None:
            _set_param(c, "ANALOG", "UNITS", list(analog_units))
    if plates:
        lab = list(analog_labels)
        nch = max(8 if p.type == 3 else 6 for p in plates)
        chan = np.zeros((nch, len(plates)), dtype=int)
        corners = np.zeros((3, 4, len(plates)))
        origins = np.zeros((3, len(plates)))
        cal = np.zeros((6, 6, len(plates)))
        for k, p in enumerate(plates):
            chan[: len(p.channels), k] = [lab.index(ch) + 1 for ch in p.channels]
            corners[:, :, k] = np.asarray(p.corners_m, float).T / scale
            origins[:, k] = np.asarray(p.origin_m, float) / scale
            cal[:, :, k] = np.eye(6) if p.cal_matrix is None else p.cal_matrix
        _set_param(c, "FORCE_PLATFORM", "USED", [len(plates)])
        _set_param(c, "FORCE_PLATFORM", "TYPE", np.array([p.type for p in plates]))
        _set_param(c, "FORCE_PLATFORM", "ZERO", np.array([1, 0]))
        _set_param(c, "FORCE_PLATFORM", "CORNERS", corners)
        _set_param(c, "FORCE_PLATFORM", "ORIGIN", origins)
        _set_param(c, "FORCE_PLATFORM", "CHANNEL", chan)
        if any(p.type == 4 for p in plates):
            _set_param(c, "FORCE_PLATFORM", "CAL_MATRIX", cal)
    for e in events:
        c.add_event([0.0, float(e.time)], context=e.context, label=e.label)
    if subject is not None:
        if subject.mass_kg is not None:
            _set_param(c, "PROCESSING", "Bodymass", [float(subject.mass_kg)])
        if subject.height_m is not None:
            _set_param(c, "PROCESSING", "Height", [float(subject.height_m) * 1000.0])
        if subject.name:
            _set_param(c, "SUBJECTS", "NAMES", [subject.name])
    c["header"]["points"]["first_frame"] = int(first_frame)
    path = Path(path)
    if n <= _MAX_HEADER_FRAMES:
        c.write(str(path))
        return path
    # more frames than the header holds (ezc3d 1.7 writes the first 65 535): ezc3d writes the
    # header and parameters with one frame, msk the whole data section in its format
    start, end = first_frame + 1, first_frame + n
    _set_param(c, "TRIAL", "ACTUAL_START_FIELD", np.array([start % 65536, start // 65536]))
    _set_param(c, "TRIAL", "ACTUAL_END_FIELD", np.array([end % 65536, end // 65536]))
    c["data"]["points"] = pts[:, :, :1].copy()
    c["data"]["meta_points"]["residuals"] = res[:, :, :1].copy()
    c["data"]["meta_points"]["camera_masks"] = np.zeros((7, m, 1), dtype=bool)
    c["data"]["analogs"] = a[:analog_ratio].T[None].copy()
    c.write(str(path))
    _write_long_data(path, pts, res[0], a)
    return path


#: the largest frame number a C3D header holds (16-bit)
_MAX_HEADER_FRAMES = 65535


def _write_long_data(
    path: Path, pts: NDArray[np.float64], res: NDArray[np.float64], analogs: NDArray[np.float64]
) -> None:
    """Replace the one-frame data section ezc3d wrote in ``path`` (Intel floats) by all the
    frames of ``pts`` ``(4, M, N)``, ``res`` ``(M, N)`` and ``analogs`` ``(N * ratio, C)``;
    the header's last frame saturates at 65 535 and ``POINT:FRAMES`` is set to 65 535 (the
    frames are in ``TRIAL:ACTUAL_*_FIELD``). Frame by frame in blocks: x, y, z, residual per
    point, then the analog samples, each a float32."""
    with path.open("r+b") as fh:
        head = bytearray(fh.read(512))
        words = list(struct.unpack("<12H", head[:24]))
        fh.seek((head[0] - 1) * 512)
        params = fh.read((words[8] - head[0]) * 512)
        frames = _walk_parameters(path, params, "<").get(("POINT", "FRAMES"))
        if frames is None or frames.type != 2:
            raise MskError(f"{path}: ezc3d wrote no integer POINT:FRAMES")
        nchar = abs(struct.unpack_from("b", params, frames.offset)[0])
        at = frames.offset + 2 + nchar + 2 + 2 + len(frames.dims)
        fh.seek((head[0] - 1) * 512 + at)
        fh.write(struct.pack("<H", _MAX_HEADER_FRAMES))
        words[4] = _MAX_HEADER_FRAMES
        fh.seek(0)
        fh.write(struct.pack("<12H", *words))
        fh.seek((words[8] - 1) * 512)
        fh.truncate()
        n, m = pts.shape[2], pts.shape[1]
        ratio = analogs.shape[0] // n if n else 0
        scale = abs(struct.unpack("<f", bytes(head[12:16]))[0]) or 1.0
        for a in range(0, n, _READ_BLOCK):
            b = min(n, a + _READ_BLOCK)
            block = np.empty((b - a, 4 * m + ratio * analogs.shape[1]), dtype="<f4")
            p4 = np.transpose(pts[:, :, a:b], (2, 1, 0)).copy()
            r = res[:, a:b].T
            # ezc3d's residual word: the residual over |scale|, truncated, in the upper byte
            p4[:, :, 3] = np.where(r < 0, -1.0, (np.trunc(r / scale).astype(np.int64) & 255) * 256)
            block[:, : 4 * m] = p4.reshape(b - a, 4 * m)
            block[:, 4 * m :] = analogs[a * ratio : b * ratio].reshape(b - a, -1)
            fh.write(block.tobytes())
