"""Numba kernel turning a stack of DICOM slices into the Volume layout.

Private: called by :mod:`anatomesh.core.io.dicom`, which checks shapes and dtypes first.
"""
from __future__ import annotations

from numba import njit

_BLOCK = 8  # columns per strip: 8 output lines (one per column) filled along k stay in cache


@njit(cache=True, nogil=True)
def transpose_rescale(stack, slope, intercept, out, k0):
    """``out[i, j, k0 + k] = stack[k, j, i] * slope[k] + intercept[k]``, strip by strip.

    One image row j at a time, in strips of 8 columns: the reads are short contiguous runs
    of each slice's row, the writes fill 8 output lines ``out[i, j, :]`` in order. Serial: it
    is memory-bound, and a parallel region would cost more than it saves when other processes
    share the cores.

    Parameters
    ----------
    stack : (K, R, C) array, the raw stored pixel values, slice k, row j, column i.
    slope, intercept : (K,) int64 or float64, the per-slice modality rescale (int64 when every
        value is an integer, so that integer output is exact).
    out : (C, R, N) C-contiguous int16 or float32, N >= k0 + K; slices k0 .. k0 + K - 1 are
        filled in place (a block of slices at a time, or all at once with k0 = 0). The caller
        guarantees that the rescaled values fit its dtype.
    k0 : int, the first output slice.
    """
    n_k, n_r, n_c = stack.shape
    for j in range(n_r):
        for i0 in range(0, n_c, _BLOCK):
            i1 = min(n_c, i0 + _BLOCK)
            for k in range(n_k):
                s = slope[k]
                b = intercept[k]
                for i in range(i0, i1):
                    out[i, j, k0 + k] = stack[k, j, i] * s + b
