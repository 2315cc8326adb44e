"""Numba kernels for :mod:`anatomesh.core.geometry.intersections`: the triangle-triangle test
(Möller 1997) and the search for crossing face pairs over a uniform grid. Private: call the
wrappers in ``intersections.py`` (they validate inputs).
"""
import numpy as np
from numba import njit, prange

from .kernels import triangle_interval


# ---------------------------------------------------------------------------------------------
# triangle-triangle intersection (Möller 1997, "A fast triangle-triangle intersection test")
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@njit(cache=True)
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True)
def _orient(p, q, r):
    return (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])


@njit(cache=True)
def _seg_seg_2d(a0, a1, b0, b1):
    """2D segments a0a1 and b0b1 cross properly (orientation tests)."""
    orient = _orient
    o1 = orient(a0, a1, b0)
    o2 = orient(a0, a1, b1)
    o3 = orient(b0, b1, a0)
    o4 = orient(b0, b1, a1)
    if ((o1 > 0 and o2 < 0) or (o1 < 0 and o2 > 0)) and ((o3 > 0 and o4 < 0) or (o3 < 0 and o4 > 0)):
        return True
    return False


@njit(cache=True)
def _point_in_tri_2d(p, a, b, c):
    d1 = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
    d2 = (c[0] - b[0]) * (p[1] - b[1]) - (c[1] - b[1]) * (p[0] - b[0])
    d3 = (a[0] - c[0]) * (p[1] - c[1]) - (a[1] - c[1]) * (p[0] - c[0])
    neg = d1 < 0 or d2 < 0 or d3 < 0
    pos = d1 > 0 or d2 > 0 or d3 > 0
    return not (neg and pos)


@njit(cache=True)
def _coplanar(n, v0, v1, v2, u0, u1, u2):
    """Coplanar triangles overlap (proper edge crossings or containment), projected on the
    axis plane where the triangles have the largest area."""
    ax = np.abs(n)
    if ax[0] >= ax[1] and ax[0] >= ax[2]:
        i0, i1 = 1, 2
    elif ax[1] >= ax[2]:
        i0, i1 = 0, 2
    else:
        i0, i1 = 0, 1
    V = np.empty((3, 2))
    U = np.empty((3, 2))
    V[0, 0], V[0, 1], V[1, 0], V[1, 1], V[2, 0], V[2, 1] = v0[i0], v0[i1], v1[i0], v1[i1], v2[i0], v2[i1]
    U[0, 0], U[0, 1], U[1, 0], U[1, 1], U[2, 0], U[2, 1] = u0[i0], u0[i1], u1[i0], u1[i1], u2[i0], u2[i1]
    for a in range(3):
        for b in range(3):
            if _seg_seg_2d(V[a], V[(a + 1) % 3], U[b], U[(b + 1) % 3]):
                return True
    # containment: centroid of one strictly inside the other
    cv = (V[0] + V[1] + V[2]) / 3.0
    cu = (U[0] + U[1] + U[2]) / 3.0
    return _point_in_tri_2d(cv, U[0], U[1], U[2]) or _point_in_tri_2d(cu, V[0], V[1], V[2])


@njit(cache=True)
def tri_tri_intersect(v0, v1, v2, u0, u1, u2, rel_eps):
    """Do triangles V and U (each three (3,) float64 corners) intersect? Möller 1997.

    Plane distances smaller than ``rel_eps`` times the triangles' size count as zero (on the
    plane), so exactly touching triangles count as intersecting."""
    # work relative to v0 for precision with large patient coordinates
    o = v0.copy()
    v0 = v0 - o
    v1 = v1 - o
    v2 = v2 - o
    u0 = u0 - o
    u1 = u1 - o
    u2 = u2 - o
    size = 0.0
    for p in (v1, v2, u0, u1, u2):
        size = max(size, abs(p[0]) + abs(p[1]) + abs(p[2]))
    n1 = _cross(v1 - v0, v2 - v0)
    ln1 = np.sqrt(_dot(n1, n1))
    if ln1 == 0.0:
        return False
    d1 = -_dot(n1, v0)
    du0 = _dot(n1, u0) + d1
    du1 = _dot(n1, u1) + d1
    du2 = _dot(n1, u2) + d1
    eps1 = rel_eps * ln1 * size
    if abs(du0) < eps1:
        du0 = 0.0
    if abs(du1) < eps1:
        du1 = 0.0
    if abs(du2) < eps1:
        du2 = 0.0
    if du0 * du1 > 0.0 and du0 * du2 > 0.0:
        return False
    n2 = _cross(u1 - u0, u2 - u0)
    ln2 = np.sqrt(_dot(n2, n2))
    if ln2 == 0.0:
        return False
    d2 = -_dot(n2, u0)
    dv0 = _dot(n2, v0) + d2
    dv1 = _dot(n2, v1) + d2
    dv2 = _dot(n2, v2) + d2
    eps2 = rel_eps * ln2 * size
    if abs(dv0) < eps2:
        dv0 = 0.0
    if abs(dv1) < eps2:
        dv1 = 0.0
    if abs(dv2) < eps2:
        dv2 = 0.0
    if dv0 * dv1 > 0.0 and dv0 * dv2 > 0.0:
        return False
    if du0 == 0.0 and du1 == 0.0 and du2 == 0.0:
        return _coplanar(n1, v0, v1, v2, u0, u1, u2)
    dd = _cross(n1, n2)
    ad = np.abs(dd)
    k = 0
    if ad[1] > ad[k]:
        k = 1
    if ad[2] > ad[k]:
        k = 2
    a0, a1, cop = triangle_interval(v0[k], v1[k], v2[k], dv0, dv1, dv2)
    if cop:
        return _coplanar(n1, v0, v1, v2, u0, u1, u2)
    b0, b1, cop = triangle_interval(u0[k], u1[k], u2[k], du0, du1, du2)
    if cop:
        return _coplanar(n1, v0, v1, v2, u0, u1, u2)
    return not (a1 < b0 or b1 < a0)


# ---------------------------------------------------------------------------------------------
# all intersecting face pairs, through a uniform grid
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _cell_pairs(c, start, items, vertices, faces, wfaces, fmin, fmax, origin, h, dims,
                rel_eps, active, out, n_out):
    """Test the face pairs of cell c (each pair once: in the cell holding the low corner of the
    overlap of their boxes); faces sharing a (welded) vertex are skipped, and pairs with no
    ``active`` face when ``active`` has entries. Writes pairs into ``out`` from row ``n_out``
    when ``out`` has rows; returns the new count."""
    some = active.shape[0] > 0
    i0 = start[c]
    i1 = start[c + 1]
    ck = c % dims[2]
    cj = (c // dims[2]) % dims[1]
    ci = c // (dims[1] * dims[2])
    cell = (ci, cj, ck)
    for s in range(i0, i1):
        fa = items[s]
        for t in range(s + 1, i1):
            fb = items[t]
            if some and not active[fa] and not active[fb]:
                continue
            # boxes overlap?
            ok = True
            own = True
            for a in range(3):
                lo = max(fmin[fa, a], fmin[fb, a])
                hi = min(fmax[fa, a], fmax[fb, a])
                if lo > hi:
                    ok = False
                    break
                idx = int(np.floor((lo - origin[a]) / h))
                idx = min(max(idx, 0), dims[a] - 1)
                if idx != cell[a]:
                    own = False
            if not ok or not own:
                continue
            shared = False
            for x in range(3):
                for y in range(3):
                    if wfaces[fa, x] == wfaces[fb, y]:
                        shared = True
            if shared:
                continue
            if tri_tri_intersect(vertices[faces[fa, 0]], vertices[faces[fa, 1]],
                                 vertices[faces[fa, 2]], vertices[faces[fb, 0]],
                                 vertices[faces[fb, 1]], vertices[faces[fb, 2]], rel_eps):
                if out.shape[0] > 0:
                    out[n_out, 0] = min(fa, fb)
                    out[n_out, 1] = max(fa, fb)
                n_out += 1
    return n_out


@njit(cache=True, parallel=True)
def intersecting_pairs(vertices, faces, wfaces, origin, h, dims, start, items, rel_eps, active):
    """All pairs (K, 2) int64 of faces that intersect and share no welded vertex (cells in
    parallel: one pass counts, the second writes each cell's pairs at its offset); when
    ``active`` (M,) bool has entries, only pairs with an active face."""
    m = faces.shape[0]
    fmin = np.empty((m, 3))
    fmax = np.empty((m, 3))
    for f in prange(m):
        for a in range(3):
            x0 = vertices[faces[f, 0], a]
            x1 = vertices[faces[f, 1], a]
            x2 = vertices[faces[f, 2], a]
            fmin[f, a] = min(x0, min(x1, x2))
            fmax[f, a] = max(x0, max(x1, x2))
    keep = start[1:] - start[:-1] > 1  # cells with a pair (and an active face, if filtered)
    if active.shape[0] > 0:
        for c in prange(keep.shape[0]):
            if keep[c]:
                hit = False
                for s in range(start[c], start[c + 1]):
                    hit = hit or active[items[s]]
                keep[c] = hit
    busy = np.flatnonzero(keep)
    counts = np.zeros(busy.shape[0], np.int64)
    empty = np.zeros((0, 2), np.int64)
    for b in prange(busy.shape[0]):
        counts[b] = _cell_pairs(busy[b], start, items, vertices, faces, wfaces, fmin, fmax,
                                origin, h, dims, rel_eps, active, empty, 0)
    offs = np.zeros(busy.shape[0] + 1, np.int64)
    for b in range(busy.shape[0]):
        offs[b + 1] = offs[b] + counts[b]
    out = np.empty((offs[-1], 2), np.int64)
    for b in prange(busy.shape[0]):
        if counts[b] > 0:
            _cell_pairs(busy[b], start, items, vertices, faces, wfaces, fmin, fmax, origin, h,
                        dims, rel_eps, active, out, offs[b])
    return out
