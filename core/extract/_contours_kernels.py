"""Numba kernels for tiling contours: the minimum-area band between two closed contours and ear
clipping of a (weakly simple) polygon.

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


@njit(cache=True)
def _cross(ax, ay, bx, by, cx, cy):
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


@njit(cache=True)
def ear_clip(x, y):
    """Triangulate the closed polygon (x, y) by ear clipping (Meisters 1975; Eberly 2002,
    "Triangulation by ear clipping"), keeping its orientation. Weakly simple polygons (holes joined
    by a bridge: repeated points) work: points at a candidate ear's corners do not block it.
    Returns (n - 2, 3) int64 indices."""
    n = x.size
    area = 0.0
    for i in range(n):
        j = (i + 1) % n
        area += x[i] * y[j] - x[j] * y[i]
    s = 1.0 if area >= 0 else -1.0
    prv = np.empty(n, np.int64)
    nxt = np.empty(n, np.int64)
    for i in range(n):
        prv[i], nxt[i] = (i - 1) % n, (i + 1) % n
    out = np.empty((max(n - 2, 0), 3), np.int64)
    t, left, i, tries = 0, n, 0, 0
    while left > 3:
        p, q = prv[i], nxt[i]
        ear = s * _cross(x[p], y[p], x[i], y[i], x[q], y[q]) > 0
        if ear:
            k = nxt[q]
            while k != p:
                same = (x[k] == x[p] and y[k] == y[p]) or (x[k] == x[i] and y[k] == y[i]) or \
                    (x[k] == x[q] and y[k] == y[q])
                if not same and s * _cross(x[p], y[p], x[i], y[i], x[k], y[k]) >= 0 and \
                        s * _cross(x[i], y[i], x[q], y[q], x[k], y[k]) >= 0 and \
                        s * _cross(x[q], y[q], x[p], y[p], x[k], y[k]) >= 0:
                    ear = False
                    break
                k = nxt[k]
        if ear or tries > left:  # no ear after a full turn: clip anyway (degenerate input)
            out[t, 0], out[t, 1], out[t, 2] = p, i, q
            t += 1
            nxt[p], prv[q] = q, p
            left -= 1
            i, tries = q, 0
        else:
            i = q
            tries += 1
    if left == 3:
        out[t, 0], out[t, 1], out[t, 2] = prv[i], i, nxt[i]
        t += 1
    return out[:t]


@njit(cache=True)
def points_in_polygon(px, py, x, y):
    """Even-odd test (PNPOLY) of points (px, py) against the closed polygon (x, y): bool (k,)."""
    out = np.zeros(px.size, np.bool_)
    n = x.size
    for k in range(px.size):
        inside = False
        for e in range(n):
            f = (e + 1) % n
            if (y[e] > py[k]) != (y[f] > py[k]):
                xc = x[e] + (py[k] - y[e]) * (x[f] - x[e]) / (y[f] - y[e])
                if px[k] < xc:
                    inside = not inside
        out[k] = inside
    return out


@njit(cache=True)
def segment_hits_polygon(ax, ay, bx, by, x, y):
    """True when the open segment (a, b) properly crosses an edge of the closed polygon (x, y)."""
    n = x.size
    for e in range(n):
        f = (e + 1) % n
        o1 = _cross(ax, ay, bx, by, x[e], y[e])
        o2 = _cross(ax, ay, bx, by, x[f], y[f])
        o3 = _cross(x[e], y[e], x[f], y[f], ax, ay)
        o4 = _cross(x[e], y[e], x[f], y[f], bx, by)
        if o1 * o2 < 0 and o3 * o4 < 0:
            return True
    return False
