"""Keeping the resident memory of a long run close to its live arrays.

glibc's allocator serves blocks below its mmap threshold from the process heap, and raises that
threshold (up to 32 MiB) each time a mapped block is freed. The per-frame arrays of a long trial
(a few MiB to tens of MiB) then land in the heap, where the freed temporaries of one stage and
the released results of earlier ones stay resident beside the next stage's arrays (measured on
the 30 000-frame bench: 849 MiB peak against 725 MiB with a fixed threshold).
:func:`map_large_blocks` fixes the threshold at 128 KiB (glibc's default starting value, as the
environment variable ``MALLOC_MMAP_THRESHOLD_=131072`` would): larger blocks are mapped and
unmapped, so a freed array leaves the resident set at once. Process-wide, once; a no-op where
the C library is not glibc. Nothing numerical changes.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools

__all__ = ["MMAP_THRESHOLD_BYTES", "map_large_blocks"]

#: blocks above this size are mapped by mmap (glibc's initial dynamic threshold)
MMAP_THRESHOLD_BYTES = 128 * 1024
_M_MMAP_THRESHOLD = -3  # glibc's mallopt parameter number (malloc.h)


@functools.cache
def map_large_blocks() -> bool:
    """Fix glibc's mmap threshold at :data:`MMAP_THRESHOLD_BYTES` for this process (once);
    False where the C library has no ``mallopt`` (not glibc) or refused it."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES))
