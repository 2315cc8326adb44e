"""Numba kernels for planar contours: even-odd scanline filling and the self-intersection test.

Private: called by :mod:`anatomesh.core.io.rtstruct` and :mod:`anatomesh.core.io.rtstruct_raster`,
which validate the arrays first.
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def even_odd_fill(u, v, starts, nx, ny, out):
    """Fill ``out[i, j]`` (uint8, (nx, ny)) by the even-odd rule over every polygon (XOR).

    ``u``, ``v``: float64 vertex coordinates in pixel-index units (pixel (i, j) has its centre at
    (i, j)); polygon p is ``u[starts[p]:starts[p + 1]]`` (closed implicitly). A pixel centre is
    inside when a ray toward +u crosses an odd number of edges (Franklin's PNPOLY rule, half-open
    in v), so a contour inside a contour is a hole.
    """
    xs = np.empty(u.size + 2, np.float64)
    for j in range(ny):
        yj = float(j)
        n = 0
        for p in range(starts.size - 1):
            a, b = starts[p], starts[p + 1]
            for e in range(a, b):
                f = e + 1 if e + 1 < b else a
                v0, v1 = v[e], v[f]
                if (v0 > yj) != (v1 > yj):
                    xs[n] = u[e] + (yj - v0) * (u[f] - u[e]) / (v1 - v0)
                    n += 1
        if n < 2:
            continue
        s = np.sort(xs[:n])
        for m in range(0, n - 1, 2):
            lo = int(np.ceil(s[m]))
            hi = int(np.ceil(s[m + 1]))
            lo = max(lo, 0)
            hi = min(hi, nx)
            for i in range(lo, hi):
                out[i, j] ^= 1


@njit(cache=True)
def _orient(ax, ay, bx, by, cx, cy):
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


@njit(cache=True)
def first_self_crossing(x, y, eps):
    """Index pair (e, f) of the first two non-adjacent edges of the closed polygon (x, y) that
    cross or touch (within ``eps`` in the orientation test), or (-1, -1). Bounding boxes prune."""
    n = x.size
    for e in range(n):
        e1 = (e + 1) % n
        ax, ay, bx, by = x[e], y[e], x[e1], y[e1]
        xmin, xmax = min(ax, bx), max(ax, bx)
        ymin, ymax = min(ay, by), max(ay, by)
        for f in range(e + 2, n):
            f1 = (f + 1) % n
            if f1 == e:
                continue
            cx, cy, dx, dy = x[f], y[f], x[f1], y[f1]
            if max(cx, dx) < xmin or min(cx, dx) > xmax or max(cy, dy) < ymin or min(cy, dy) > ymax:
                continue
            o1 = _orient(ax, ay, bx, by, cx, cy)
            o2 = _orient(ax, ay, bx, by, dx, dy)
            o3 = _orient(cx, cy, dx, dy, ax, ay)
            o4 = _orient(cx, cy, dx, dy, bx, by)
            if ((o1 > eps and o2 < -eps) or (o1 < -eps and o2 > eps)) and \
                    ((o3 > eps and o4 < -eps) or (o3 < -eps and o4 > eps)):
                return e, f
    return -1, -1
