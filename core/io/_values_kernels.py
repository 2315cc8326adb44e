"""Numba kernel counting the values of a flat integer array (private to :mod:`.values`)."""
from __future__ import annotations

import numpy as np
from numba import njit

#: up to this many bins, four interleaved histograms hide the store-to-load latency of runs of
#: equal values (a label map is mostly long runs of the background)
_SPLIT_BINS = 65536


@njit(cache=True, nogil=True)
def add_counts(flat, offset, counts):
    """``counts[flat[i] - offset] += 1`` for every i, in place.

    Parameters
    ----------
    flat : (N,) integer array (uint8, uint16, int32, int64 ...), contiguous.
    offset : int64, the smallest value (``counts[0]`` counts it).
    counts : (B,) int64, B > max(flat) - offset; the caller guarantees the range.
    """
    n = flat.size
    nb = counts.size
    if nb > _SPLIT_BINS:
        for i in range(n):
            counts[np.int64(flat[i]) - offset] += 1
        return
    part = np.zeros((4, nb), np.int64)
    m = n - n % 4
    for i in range(0, m, 4):
        part[0, np.int64(flat[i]) - offset] += 1
        part[1, np.int64(flat[i + 1]) - offset] += 1
        part[2, np.int64(flat[i + 2]) - offset] += 1
        part[3, np.int64(flat[i + 3]) - offset] += 1
    for i in range(m, n):
        part[0, np.int64(flat[i]) - offset] += 1
    for b in range(nb):
        counts[b] += part[0, b] + part[1, b] + part[2, b] + part[3, b]
