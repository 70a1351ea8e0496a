"""Byte-level C3D mutators for the validation and fuzz tests (no ezc3d involved: they write
what a broken writer or a damaged disk would, which ezc3d's own writer never produces)."""

from __future__ import annotations

import math
import struct
from pathlib import Path

from msk.io.c3d import _RawParam, _walk_parameters

Key = tuple[str, str]


def parameters(data: bytes) -> tuple[int, int, dict[Key, _RawParam]]:
    """(parameter section offset, processor byte, parameters by (GROUP, NAME))."""
    start = (data[0] - 1) * 512
    nblk, proc = data[start + 2], data[start + 3]
    endian = ">" if proc == 86 else "<"
    section = bytes(data[start : start + nblk * 512])
    return start, proc, _walk_parameters(Path("mutant"), section, endian)


def _where(data: bytearray, key: Key) -> tuple[int, _RawParam, int, int]:
    start, proc, params = parameters(bytes(data))
    p = params[key]
    type_at = start + p.offset + 4 + len(p.name)
    return proc, p, type_at, type_at + 2 + len(p.dims)


def retype(data: bytearray, key: Key, typ: int) -> None:
    """Change the stored data type of a parameter (-1 char, 1 byte, 2 int16, 4 float)."""
    _, _, type_at, _ = _where(data, key)
    data[type_at] = typ & 0xFF


def set_dim(data: bytearray, key: Key, k: int, value: int) -> None:
    """Change dimension ``k`` of a parameter (its data length changes with it)."""
    _, p, type_at, _ = _where(data, key)
    if k >= len(p.dims):
        raise KeyError(key)
    data[type_at + 2 + k] = value & 0xFF


def _encode(proc: int, typ: int, value: float) -> bytes:
    if typ == 4:
        if proc == 85:  # DEC float
            b = struct.pack("<f", value * 4.0)
            return bytes(b[i] for i in (2, 3, 0, 1))
        return struct.pack(">f" if proc == 86 else "<f", value)
    iv = int(value) if math.isfinite(value) else -1  # integers wrap as stored
    if typ == 2:
        return struct.pack(">h" if proc == 86 else "<h", (iv + 32768) % 65536 - 32768)
    return struct.pack("b", (iv + 128) % 256 - 128)


def set_value(data: bytearray, key: Key, value: float, index: int = 0) -> None:
    """Overwrite element ``index`` (file order) of a numeric parameter."""
    proc, p, _, d0 = _where(data, key)
    w = abs(p.type)
    if p.type == -1 or (index + 1) * w > len(p.data):
        raise KeyError(key)
    data[d0 + index * w : d0 + (index + 1) * w] = _encode(proc, p.type, value)


def set_text(data: bytearray, key: Key, offset: int, text: bytes) -> None:
    """Overwrite bytes of a character parameter."""
    _, p, _, d0 = _where(data, key)
    if p.type != -1 or offset + len(text) > len(p.data):
        raise KeyError(key)
    data[d0 + offset : d0 + offset + len(text)] = text


def label_width(data: bytes, key: Key) -> int:
    _, _, params = parameters(data)
    return params[key].dims[0]


def crashing_reader(conn, path, cop_threshold_n):  # pragma: no cover - runs in a child
    """Stands in for a reader that dies natively (as ezc3d does on some corrupt files)."""
    import os
    import signal

    os.kill(os.getpid(), signal.SIGSEGV)


def hanging_reader(conn, path, cop_threshold_n):  # pragma: no cover - runs in a child
    import time

    time.sleep(600)
