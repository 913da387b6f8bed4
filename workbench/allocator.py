"""glibc's allocator told to keep the freed memory of a long take's arrays for reuse.

A 10-minute take's whole-take arrays are 40-160 MB each, and a clean makes and frees
dozens of them. glibc serves every allocation above its mmap threshold (at most 32 MiB,
however it adapts) with fresh pages from the kernel and hands them back when freed, so
each new array pays a page fault per 4 kB it touches. With the threshold and the heap's
trim threshold at :data:`KEPT_BYTES`, freed arrays stay in the heap and the next ones
reuse them. Measured on the 10-minute take (``workbench bench --long``'s, 2-core Xeon,
``angular:0.5+gaps:0.01``), ``ebd>ebf``, three runs each way: the clean 7.1-7.3 s ->
6.5-6.6 s, system time 1.7-2.2 s -> 0.9-1.3 s, peak memory of the command 0.84-0.85 ->
0.93-0.94 GB (the heap's freed blocks are not all reused).
"""

from __future__ import annotations

import ctypes
import sys

__all__ = ["KEPT_BYTES", "keep_freed_arrays"]

#: allocations up to this size come from the heap, and up to this much free memory at its
#: top is kept, not trimmed (bytes)
KEPT_BYTES = 128 << 20
#: mallopt's parameter numbers (malloc.h)
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3


def keep_freed_arrays() -> bool:
    """Set glibc's mmap and trim thresholds to :data:`KEPT_BYTES` for this process.
    Returns whether it did: False where the C library has no ``mallopt`` or refuses
    (not Linux, or not glibc), which leaves the allocator as it was."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return mallopt(_M_MMAP_THRESHOLD, KEPT_BYTES) == 1 and mallopt(_M_TRIM_THRESHOLD, KEPT_BYTES) == 1
