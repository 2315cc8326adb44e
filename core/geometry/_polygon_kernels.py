"""Numba kernels for planar polygons: ear clipping of a (weakly simple) polygon, the even-odd
point test, segment crossing.

Private: called by :mod:`anatomesh.core.geometry.polygons`.
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _cross(ax, ay, bx, by, cx, cy):
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


@njit(cache=True)
def ear_clip(x, y, min_height=0.0):
    """Triangulate the closed polygon (x, y) by ear clipping (Meisters 1975; Eberly 2002,
    "Triangulation by ear clipping"), keeping its orientation. Weakly simple polygons (holes joined
    by a bridge: repeated points) work: points at a candidate ear's corners do not block it. A corner
    whose sine is below 1e-9 (collinear up to rounding, e.g. a cut across a flat face) is not an
    ear, nor one less than ``min_height`` from the chord of its neighbours (a sliver that rounding
    to float32 would flatten), so no such triangle is made while a proper ear remains.
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
        # convex by more than rounding: (nearly) collinear corners are never clipped alone
        span = np.hypot(x[i] - x[p], y[i] - y[p]) * np.hypot(x[q] - x[i], y[q] - y[i])
        chord = np.hypot(x[q] - x[p], y[q] - y[p])
        ear = s * _cross(x[p], y[p], x[i], y[i], x[q], y[q]) > max(1e-9 * span, min_height * chord)
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
