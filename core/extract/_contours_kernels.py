"""Numba kernel for tiling contours: the minimum-area band between two closed contours (ear
clipping and the polygon tests are in :mod:`anatomesh.core.geometry.polygons`).

Private: called by :mod:`anatomesh.core.extract.contours`, which prepares the arrays.
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _area2(p, q, r):
    ux, uy, uz = q[0] - p[0], q[1] - p[1], q[2] - p[2]
    vx, vy, vz = r[0] - p[0], r[1] - p[1], r[2] - p[2]
    cx, cy, cz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
    return np.sqrt(cx * cx + cy * cy + cz * cz)


@njit(cache=True)
def band_dp(a, b):
    """Minimum-area triangulation of the band between closed contours ``a`` (m, 3) and ``b``
    (n, 3), both starting at corresponding points and running the same way (Fuchs, Kedem &
    Uselton 1977, "Optimal surface reconstruction from planar contours", with the start pair
    fixed). Returns (m + n, 3) int64 triangles: index i < m is a[i], m + j is b[j]; each triangle
    advances one step along a (a_i, a_i+1, b_j) or along b (a_i, b_j+1, b_j). The paths through
    (0, n) and (m, 0) are excluded: they would use the start rung (a_0, b_0) four times."""
    m, n = a.shape[0], b.shape[0]
    cost = np.full((m + 1, n + 1), np.inf)
    move = np.zeros((m + 1, n + 1), np.uint8)
    cost[0, 0] = 0.0
    for i in range(m + 1):
        for j in range(n + 1):
            if i == 0 and j == 0:
                continue
            best = np.inf
            if i > 0:
                c = cost[i - 1, j] + _area2(a[(i - 1) % m], a[i % m], b[j % n])
                if c < best:
                    best = c
                    move[i, j] = 1
            if j > 0:
                c = cost[i, j - 1] + _area2(a[i % m], b[j % n], b[(j - 1) % n])
                if c < best:
                    best = c
                    move[i, j] = 2
            if (i == 0 and j == n) or (i == m and j == 0):
                best = np.inf  # one point fanned to a whole contour: the start rung would repeat
            cost[i, j] = best
    out = np.empty((m + n, 3), np.int64)
    i, j, t = m, n, m + n - 1
    while i > 0 or j > 0:
        if move[i, j] == 1:
            out[t, 0], out[t, 1], out[t, 2] = (i - 1) % m, i % m, m + j % n
            i -= 1
        else:
            out[t, 0], out[t, 1], out[t, 2] = i % m, m + j % n, m + (j - 1) % n
            j -= 1
        t -= 1
    return out
