"""Numba kernels of :mod:`anatomesh.core.extract.precise`: the trilinear interpolant of a volume
and Newton steps onto its level set, in voxel-index coordinates."""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(cache=True, inline="always")
def _cell(x, n):  # pragma: no cover - numba
    i = int(math.floor(x))
    if i < 0:
        i = 0
    if i > n - 2:
        i = n - 2
    return i, x - i


@njit(cache=True)
def trilinear(data, p, grad):  # pragma: no cover - numba
    """Value of the trilinear interpolant of ``data`` at index position ``p`` (3,); its
    gradient (per index unit) into ``grad`` (3,). ``p`` must lie in the grid."""
    i, u = _cell(p[0], data.shape[0])
    j, v = _cell(p[1], data.shape[1])
    k, w = _cell(p[2], data.shape[2])
    c000 = float(data[i, j, k])
    c100 = float(data[i + 1, j, k])
    c010 = float(data[i, j + 1, k])
    c110 = float(data[i + 1, j + 1, k])
    c001 = float(data[i, j, k + 1])
    c101 = float(data[i + 1, j, k + 1])
    c011 = float(data[i, j + 1, k + 1])
    c111 = float(data[i + 1, j + 1, k + 1])
    a00 = c000 + (c100 - c000) * u
    a10 = c010 + (c110 - c010) * u
    a01 = c001 + (c101 - c001) * u
    a11 = c011 + (c111 - c011) * u
    b0 = a00 + (a10 - a00) * v
    b1 = a01 + (a11 - a01) * v
    # d/du, d/dv, d/dw of the interpolant
    du0 = (c100 - c000) + ((c110 - c010) - (c100 - c000)) * v
    du1 = (c101 - c001) + ((c111 - c011) - (c101 - c001)) * v
    grad[0] = du0 + (du1 - du0) * w
    grad[1] = (a10 - a00) + ((a11 - a01) - (a10 - a00)) * w
    grad[2] = b1 - b0
    return b0 + (b1 - b0) * w


@njit(cache=True, parallel=True)
def project(data, starts, level, max_step, tolerance, points, grads, ok):  # pragma: no cover - numba
    """Newton steps along the gradient from each start (S, 3) onto ``value == level`` of the
    trilinear interpolant, staying within ``max_step`` voxels of the start and inside the grid;
    writes the end point into ``points``, the gradient there into ``grads`` and whether it
    converged (|value - level| / |gradient| < ``tolerance`` voxel) into ``ok``."""
    n0, n1, n2 = data.shape
    for s in prange(starts.shape[0]):
        x = starts[s].copy()
        g = np.zeros(3)
        good = False
        for _ in range(12):
            if (x[0] < 0.0 or x[0] > n0 - 1 or x[1] < 0.0 or x[1] > n1 - 1 or x[2] < 0.0
                    or x[2] > n2 - 1):
                break
            r = trilinear(data, x, g) - level
            gg = g[0] * g[0] + g[1] * g[1] + g[2] * g[2]
            if gg == 0.0:
                break
            if abs(r) < tolerance * math.sqrt(gg):
                good = True
                break
            for a in range(3):
                x[a] -= r * g[a] / gg
            d = 0.0
            for a in range(3):
                d += (x[a] - starts[s, a]) ** 2
            if d > max_step * max_step:
                break
        ok[s] = good
        for a in range(3):
            points[s, a] = x[a]
            grads[s, a] = g[a]
