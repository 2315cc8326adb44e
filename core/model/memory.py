"""Handing freed memory back to the operating system.

glibc's ``malloc`` keeps freed blocks smaller than its mmap threshold (adaptive, up to 32 MB) in
its heap, where they still count in the process's resident set until reused. After a one-shot
step frees its arrays, the next step's arrays of other sizes often cannot reuse those holes, so
the peak grows by what the earlier step left behind. ``malloc_trim(0)`` returns every free
page of every arena (glibc 2.8 and later): :func:`release_free_memory`. A process of our own
(the command line, a batch worker) can also keep large blocks out of the heap altogether:
:func:`return_large_blocks`. On other C libraries and platforms both do nothing.
"""
from __future__ import annotations

import ctypes
import sys
from functools import lru_cache
from typing import Callable, Optional


#: glibc's ``mallopt`` parameter number of ``M_MMAP_THRESHOLD`` (malloc.h)
_M_MMAP_THRESHOLD = -3


@lru_cache(maxsize=1)
def _libc() -> Optional[ctypes.CDLL]:
    """The process's C library where it is glibc-like (Linux), else None."""
    return ctypes.CDLL(None) if sys.platform.startswith("linux") else None


@lru_cache(maxsize=1)
def _malloc_trim() -> Optional[Callable[[int], int]]:
    """glibc's ``malloc_trim``, or None where there is none (looked up once)."""
    try:
        trim = _libc().malloc_trim
    except (OSError, AttributeError):  # not Linux, musl and other C libraries
        return None
    trim.argtypes, trim.restype = [ctypes.c_size_t], ctypes.c_int
    return trim


def release_free_memory() -> bool:
    """Give the free pages of the C heap back to the operating system; True if it could (glibc).
    Cheap: call it where a step has just freed large arrays."""
    trim = _malloc_trim()
    if trim is None:
        return False
    trim(0)
    return True


def return_large_blocks(threshold: int = 1 << 20) -> bool:
    """Have ``malloc`` give every block of ``threshold`` bytes or more its own mapping, handed
    back to the system the moment it is freed (glibc ``mallopt(M_MMAP_THRESHOLD)``; a fixed
    threshold also stops glibc raising it, up to 32 MB, after the first large block is freed).
    Process-wide: for processes of our own (the command line, batch workers), not inside
    Blender. It lowers the peak memory of ``anatomesh mesh`` without slowing it. True if it
    could (glibc)."""
    try:
        mallopt = _libc().mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, int(threshold)))
