"""Numba kernel turning a stack of DICOM slices into the Volume layout.

Private: called by :mod:`anatomesh.core.io.dicom`, which checks shapes and dtypes first.
"""
from __future__ import annotations

from numba import njit, prange

_BLOCK = 16  # tile edge: 16 columns x 16 slices keeps both the reads and the writes in cache


@njit(parallel=True, cache=True)
def transpose_rescale(stack, slope, intercept, out):
    """``out[i, j, k] = stack[k, j, i] * slope[k] + intercept[k]``, tiled for cache locality.

    Parameters
    ----------
    stack : (K, R, C) array, the raw stored pixel values, slice k, row j, column i.
    slope, intercept : (K,) int64 or float64, the per-slice modality rescale (int64 when every
        value is an integer, so that integer output is exact).
    out : (C, R, K) C-contiguous int16 or float32, filled in place. The caller guarantees that
        the rescaled values fit its dtype.
    """
    n_k, n_r, n_c = stack.shape
    n_tiles = (n_c + _BLOCK - 1) // _BLOCK
    for tile in prange(n_tiles):
        i0 = tile * _BLOCK
        i1 = min(n_c, i0 + _BLOCK)
        for j in range(n_r):
            for k0 in range(0, n_k, _BLOCK):
                k1 = min(n_k, k0 + _BLOCK)
                for k in range(k0, k1):
                    s = slope[k]
                    b = intercept[k]
                    for i in range(i0, i1):
                        out[i, j, k] = stack[k, j, i] * s + b
