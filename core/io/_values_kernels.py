"""Numba kernel counting the values of a flat integer array (private to :mod:`.values`)."""
from __future__ import annotations

import numpy as np
from numba import njit

#: up to this many bins, four interleaved histograms hide the store-to-load latency of runs of
#: equal values (a label map is mostly long runs of the background)
SPLIT_BINS = 65536


@njit(cache=True, nogil=True)
def add_counts(flat, offset, part):
    """``part[r, flat[i] - offset] += 1`` for every i, in place: the counts are ``part.sum(0)``.

    Parameters
    ----------
    flat : (N,) integer array (uint8, uint16, int32, int64 ...), contiguous.
    offset : int64, the smallest value (bin 0 counts it).
    part : (R, B) int64, B > max(flat) - offset (the caller guarantees the range); R = 4: four
        interleaved histograms, value i in row i % 4 (for B <= :data:`SPLIT_BINS`); R = 1: one.
        The caller allocates it (a kernel that allocates nothing compiles faster).
    """
    n = flat.size
    if part.shape[0] < 4:
        for i in range(n):
            part[0, np.int64(flat[i]) - offset] += 1
        return
    m = n - n % 4
    for i in range(0, m, 4):
        part[0, np.int64(flat[i]) - offset] += 1
        part[1, np.int64(flat[i + 1]) - offset] += 1
        part[2, np.int64(flat[i + 2]) - offset] += 1
        part[3, np.int64(flat[i + 3]) - offset] += 1
    for i in range(m, n):
        part[0, np.int64(flat[i]) - offset] += 1
