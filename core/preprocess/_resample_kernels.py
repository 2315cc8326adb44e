"""Numba kernels of :mod:`anatomesh.core.preprocess.resample`: one separable 1D resampling pass.

Each pass maps a C-contiguous float32 array ``src`` to ``dst`` along one axis with a small filter
per output sample: ``dst[.., o, ..] = sum_t w[o, t] * src[.., idx[o, t], ..]`` (``idx`` (O, T)
int64 already mirrored into range, ``w`` (O, T) float32). The loops run along the contiguous last
axis wherever they can, so the inner loop is a vectorised multiply-add over a row.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

_parallel = njit(cache=True, parallel=True, nogil=True)


@_parallel
def resample_axis0(src, idx, w, dst):  # pragma: no cover - numba
    """``dst[o, j, k] = sum_t w[o, t] src[idx[o, t], j, k]``; parallel over ``o``."""
    n_out, taps = idx.shape
    nj, nk = src.shape[1], src.shape[2]
    for o in prange(n_out):
        for j in range(nj):
            for k in range(nk):
                dst[o, j, k] = 0.0
        for t in range(taps):
            wt = w[o, t]
            if wt == 0.0:
                continue
            i = idx[o, t]
            for j in range(nj):
                for k in range(nk):
                    dst[o, j, k] += wt * src[i, j, k]


@_parallel
def resample_axis1(src, idx, w, dst):  # pragma: no cover - numba
    """``dst[i, o, k] = sum_t w[o, t] src[i, idx[o, t], k]``; parallel over ``i``."""
    n_out, taps = idx.shape
    ni, nk = src.shape[0], src.shape[2]
    for i in prange(ni):
        for o in range(n_out):
            for k in range(nk):
                dst[i, o, k] = 0.0
            for t in range(taps):
                wt = w[o, t]
                if wt == 0.0:
                    continue
                j = idx[o, t]
                for k in range(nk):
                    dst[i, o, k] += wt * src[i, j, k]


@_parallel
def resample_axis2(src, idx, w, dst):  # pragma: no cover - numba
    """``dst[i, j, o] = sum_t w[o, t] src[i, j, idx[o, t]]``; parallel over ``i``."""
    n_out, taps = idx.shape
    ni, nj = src.shape[0], src.shape[1]
    for i in prange(ni):
        for j in range(nj):
            for o in range(n_out):
                acc = np.float32(0.0)
                for t in range(taps):
                    acc += w[o, t] * src[i, j, idx[o, t]]
                dst[i, j, o] = acc
