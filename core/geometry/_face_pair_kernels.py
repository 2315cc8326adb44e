"""Numba kernels for :mod:`anatomesh.core.geometry.face_pairs` (private: no input checks here).

* :func:`tri_tri` — Möller 1997 ("A fast triangle-triangle intersection test") on scalars, no
  temporary arrays: the same arithmetic, in the same order, as
  ``kernels.tri_tri_intersect`` (so the same answer bit for bit), without its array overhead.
* :func:`bucket_faces` — faces bucketed by the cell of their extent's low corner (columns
  (x, y) in a dense table, z sorted inside a column);
* :func:`sweep_csr` — a sweep over the buckets: the candidate pairs, or the crossing ones;
* :func:`active_crossings` — crossings around a few faces, both directions;
* :func:`test_pairs` — crossing test over listed candidate pairs.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .kernels import triangle_interval


# ---------------------------------------------------------------------------------------------
# triangle-triangle test on scalars (Möller 1997), the arithmetic of tri_tri_intersect
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _cross(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@njit(cache=True, inline="always")
def _dot(ax, ay, az, bx, by, bz):
    return ax * bx + ay * by + az * bz


@njit(cache=True, inline="always")
def _orient(px, py, qx, qy, rx, ry):
    return (qx - px) * (ry - py) - (qy - py) * (rx - px)


@njit(cache=True)
def _segments_cross(a0, a1, b0, b1, c0, c1, d0, d1):
    """2D segments (a, b) and (c, d) cross properly."""
    o1 = _orient(a0, a1, b0, b1, c0, c1)
    o2 = _orient(a0, a1, b0, b1, d0, d1)
    o3 = _orient(c0, c1, d0, d1, a0, a1)
    o4 = _orient(c0, c1, d0, d1, b0, b1)
    return ((o1 > 0 and o2 < 0) or (o1 < 0 and o2 > 0)) and \
        ((o3 > 0 and o4 < 0) or (o3 < 0 and o4 > 0))


@njit(cache=True)
def _inside_2d(p0, p1, T):
    """Point (p0, p1) in the 2D triangle T (3, 2), boundary included."""
    d1 = (T[1, 0] - T[0, 0]) * (p1 - T[0, 1]) - (T[1, 1] - T[0, 1]) * (p0 - T[0, 0])
    d2 = (T[2, 0] - T[1, 0]) * (p1 - T[1, 1]) - (T[2, 1] - T[1, 1]) * (p0 - T[1, 0])
    d3 = (T[0, 0] - T[2, 0]) * (p1 - T[2, 1]) - (T[0, 1] - T[2, 1]) * (p0 - T[2, 0])
    neg = d1 < 0 or d2 < 0 or d3 < 0
    pos = d1 > 0 or d2 > 0 or d3 > 0
    return not (neg and pos)


@njit(cache=True)
def _coplanar(nx, ny, nz, X, a0, a1, a2, b0, b1, b2):
    """Coplanar triangles (rows a*, b* of ``X``) overlap, projected on the axis plane where
    they have the largest area (rare: arrays allowed)."""
    V = np.empty((3, 3))
    U = np.empty((3, 3))
    for c in range(3):
        V[0, c], V[1, c], V[2, c] = X[a0, c], X[a1, c], X[a2, c]
        U[0, c], U[1, c], U[2, c] = X[b0, c], X[b1, c], X[b2, c]
    ax, ay, az = abs(nx), abs(ny), abs(nz)
    if ax >= ay and ax >= az:
        i0, i1 = 1, 2
    elif ay >= az:
        i0, i1 = 0, 2
    else:
        i0, i1 = 0, 1
    P = np.empty((3, 2))
    Q = np.empty((3, 2))
    o0, o1 = V[0, i0], V[0, i1]
    for k in range(3):  # relative to V's first corner, as tri_tri_intersect
        P[k, 0], P[k, 1] = V[k, i0] - o0, V[k, i1] - o1
        Q[k, 0], Q[k, 1] = U[k, i0] - o0, U[k, i1] - o1
    for a in range(3):
        for b in range(3):
            if _segments_cross(P[a, 0], P[a, 1], P[(a + 1) % 3, 0], P[(a + 1) % 3, 1],
                               Q[b, 0], Q[b, 1], Q[(b + 1) % 3, 0], Q[(b + 1) % 3, 1]):
                return True
    cp0 = (P[0, 0] + P[1, 0] + P[2, 0]) / 3.0
    cp1 = (P[0, 1] + P[1, 1] + P[2, 1]) / 3.0
    cq0 = (Q[0, 0] + Q[1, 0] + Q[2, 0]) / 3.0
    cq1 = (Q[0, 1] + Q[1, 1] + Q[2, 1]) / 3.0
    return _inside_2d(cp0, cp1, Q) or _inside_2d(cq0, cq1, P)


@njit(cache=True)
def _near_zero(x, eps):
    return 0.0 if abs(x) < eps else x


@njit(cache=True)
def tri_tri(X, a0, a1, a2, b0, b1, b2, rel_eps):
    """Do the triangles of rows (a0, a1, a2) and (b0, b1, b2) of ``X`` (N, 3) float64 or
    float32 intersect? Möller 1997; touching counts (plane distances below ``rel_eps`` times the
    size are zero). Coordinates relative to the first corner, as ``tri_tri_intersect``, in
    float64 (float32 positions convert exactly: the same decisions as their float64 copy)."""
    ox, oy, oz = np.float64(X[a0, 0]), np.float64(X[a0, 1]), np.float64(X[a0, 2])
    v0x, v0y, v0z = X[a0, 0] - ox, X[a0, 1] - oy, X[a0, 2] - oz
    v1x, v1y, v1z = X[a1, 0] - ox, X[a1, 1] - oy, X[a1, 2] - oz
    v2x, v2y, v2z = X[a2, 0] - ox, X[a2, 1] - oy, X[a2, 2] - oz
    u0x, u0y, u0z = X[b0, 0] - ox, X[b0, 1] - oy, X[b0, 2] - oz
    u1x, u1y, u1z = X[b1, 0] - ox, X[b1, 1] - oy, X[b1, 2] - oz
    u2x, u2y, u2z = X[b2, 0] - ox, X[b2, 1] - oy, X[b2, 2] - oz
    size = 0.0
    size = max(size, abs(v1x) + abs(v1y) + abs(v1z))
    size = max(size, abs(v2x) + abs(v2y) + abs(v2z))
    size = max(size, abs(u0x) + abs(u0y) + abs(u0z))
    size = max(size, abs(u1x) + abs(u1y) + abs(u1z))
    size = max(size, abs(u2x) + abs(u2y) + abs(u2z))
    n1x, n1y, n1z = _cross(v1x - v0x, v1y - v0y, v1z - v0z, v2x - v0x, v2y - v0y, v2z - v0z)
    ln1 = np.sqrt(_dot(n1x, n1y, n1z, n1x, n1y, n1z))
    if ln1 == 0.0:
        return False
    d1 = -_dot(n1x, n1y, n1z, v0x, v0y, v0z)
    eps1 = rel_eps * ln1 * size
    du0 = _near_zero(_dot(n1x, n1y, n1z, u0x, u0y, u0z) + d1, eps1)
    du1 = _near_zero(_dot(n1x, n1y, n1z, u1x, u1y, u1z) + d1, eps1)
    du2 = _near_zero(_dot(n1x, n1y, n1z, u2x, u2y, u2z) + d1, eps1)
    if du0 * du1 > 0.0 and du0 * du2 > 0.0:
        return False
    n2x, n2y, n2z = _cross(u1x - u0x, u1y - u0y, u1z - u0z, u2x - u0x, u2y - u0y, u2z - u0z)
    ln2 = np.sqrt(_dot(n2x, n2y, n2z, n2x, n2y, n2z))
    if ln2 == 0.0:
        return False
    d2 = -_dot(n2x, n2y, n2z, u0x, u0y, u0z)
    eps2 = rel_eps * ln2 * size
    dv0 = _near_zero(_dot(n2x, n2y, n2z, v0x, v0y, v0z) + d2, eps2)
    dv1 = _near_zero(_dot(n2x, n2y, n2z, v1x, v1y, v1z) + d2, eps2)
    dv2 = _near_zero(_dot(n2x, n2y, n2z, v2x, v2y, v2z) + d2, eps2)
    if dv0 * dv1 > 0.0 and dv0 * dv2 > 0.0:
        return False
    if du0 == 0.0 and du1 == 0.0 and du2 == 0.0:
        return _coplanar(n1x, n1y, n1z, X, a0, a1, a2, b0, b1, b2)
    k = _line_axis(n1x, n1y, n1z, n2x, n2y, n2z)
    s0, s1, cop = triangle_interval(_pick(k, v0x, v0y, v0z), _pick(k, v1x, v1y, v1z),
                            _pick(k, v2x, v2y, v2z), dv0, dv1, dv2)
    if cop:
        return _coplanar(n1x, n1y, n1z, X, a0, a1, a2, b0, b1, b2)
    t0, t1, cop = triangle_interval(_pick(k, u0x, u0y, u0z), _pick(k, u1x, u1y, u1z),
                            _pick(k, u2x, u2y, u2z), du0, du1, du2)
    if cop:
        return _coplanar(n1x, n1y, n1z, X, a0, a1, a2, b0, b1, b2)
    return not (s1 < t0 or t1 < s0)


@njit(cache=True, inline="always")
def _pick(k, x, y, z):
    return x if k == 0 else (y if k == 1 else z)


@njit(cache=True)
def _line_axis(n1x, n1y, n1z, n2x, n2y, n2z):
    """Axis of the largest component of the planes' common direction (first on ties)."""
    ddx, ddy, ddz = _cross(n1x, n1y, n1z, n2x, n2y, n2z)
    ad0, ad1, ad2 = abs(ddx), abs(ddy), abs(ddz)
    k = 0
    best = ad0
    if ad1 > best:
        k = 1
        best = ad1
    if ad2 > best:
        k = 2
    return k


# ---------------------------------------------------------------------------------------------
# static candidate pairs: buckets by the cell of each face's extent's low corner
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _extent(centres, faces, half, f, c):
    """Face f's extent along axis c, ``(lo, hi, cell, reach)``: the (min, max) of its corners'
    box centres ∓ ``half[c]``, the cell of ``lo`` (its floor, not shifted) and how far up (in
    cells) a partner's home may lie, ``ceil(hi) − 1 − floor(lo)``."""
    x0, x1, x2 = centres[faces[f, 0], c], centres[faces[f, 1], c], centres[faces[f, 2], c]
    lo, hi = min(x0, min(x1, x2)) - half[c], max(x0, max(x1, x2)) + half[c]
    cell = int(np.floor(lo))
    return lo, hi, cell, int(np.ceil(hi)) - 1 - cell


@njit(parallel=True, cache=True)
def homes(centres, faces, half):
    """Home cell of each face: the floor of its extent's low corner, shifted so the lowest is 0.
    Returns ``(home (M, 3) int32, back, dims (3,) int64)``: the largest reach (see
    :func:`_extent`) and the home cells per axis. In 16 parts of the faces (parallel), each
    with its own extremes, merged at the end."""
    m, parts = faces.shape[0], 16
    lowest = np.full((parts, 3), np.inf)
    for p in prange(parts):
        for f in range(p * m // parts, (p + 1) * m // parts):
            for c in range(3):
                lowest[p, c] = min(lowest[p, c], _extent(centres, faces, half, f, c)[0])
    origin = np.zeros(3, np.int64)
    for c in range(3):
        origin[c] = int(np.floor(lowest[:, c].min())) if m else 0
    home = np.empty((m, 3), np.int32)
    top, back = np.zeros((parts, 3), np.int64), np.zeros((parts, 3), np.int64)
    for p in prange(parts):
        for f in range(p * m // parts, (p + 1) * m // parts):
            for c in range(3):
                _, _, cell, reach = _extent(centres, faces, half, f, c)
                home[f, c] = cell - origin[c]
                top[p, c] = max(top[p, c], home[f, c])
                back[p, c] = max(back[p, c], reach)
    dims, most = np.zeros(3, np.int64), np.zeros(3, np.int64)
    for c in range(3):
        dims[c], most[c] = top[:, c].max() + 1, back[:, c].max()
    return home, most, dims


@njit(cache=True, inline="always")
def _down32(x):
    """The largest float32 <= x."""
    y = np.float32(x)
    if y > x:
        y = np.nextafter(y, np.float32(-np.inf))
    return y


@njit(cache=True, inline="always")
def _up32(x):
    """The smallest float32 >= x."""
    y = np.float32(x)
    if y < x:
        y = np.nextafter(y, np.float32(np.inf))
    return y


@njit(parallel=True, cache=True)
def bucket_rows(order, centres, faces, half, extents):
    """The faces in bucket ``order``, in parallel: extents ``(lo, hi)`` (M, 3) float32 rounded
    outwards (an extent only grows: a candidate is never lost; their floor and ceiling are those
    of the exact values; (0, 3) unless ``extents``) and reaches (M, 3) int16 (see
    :func:`_extent`; at most ``back``, checked by the caller). A row's home cell is its column
    and z; its corners are those of face ``order[row]``."""
    m = order.shape[0]
    rows = m if extents else 0
    lo2, hi2 = np.empty((rows, 3), np.float32), np.empty((rows, 3), np.float32)
    reach2 = np.empty((m, 3), np.int16)
    for k in prange(m):
        f = order[k]
        for c in range(3):
            lo, hi, _, reach = _extent(centres, faces, half, f, c)
            if extents:
                lo2[k, c], hi2[k, c] = _down32(lo), _up32(hi)
            reach2[k, c] = reach
    return lo2, hi2, reach2


@njit(cache=True)
def bucket_faces(home, dims):
    """Faces sorted by column ``(x, y)`` of their ``home`` cell (M, 3) int64 in [0, dims), then
    by z and index: ``(start (Dx*Dy + 1,) int64, order (M,) int32, z (M,) int32)``."""
    m = home.shape[0]
    ncol = dims[0] * dims[1]
    start = np.zeros(ncol + 1, np.int64)
    for f in range(m):
        start[home[f, 0] * dims[1] + home[f, 1] + 1] += 1
    for c in range(ncol):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(m, np.int32)
    for f in range(m):
        c = home[f, 0] * dims[1] + home[f, 1]
        order[fill[c]] = f
        fill[c] += 1
    z = np.empty(m, np.int32)
    for c in range(ncol):  # insertion sort by z (columns are short; equal z keep index order)
        for k in range(start[c], start[c + 1]):
            f = order[k]
            zf = home[f, 2]
            j = k
            while j > start[c] and z[j - 1] > zf:
                z[j] = z[j - 1]
                order[j] = order[j - 1]
                j -= 1
            z[j] = zf
            order[j] = f
    return start, order, z


@njit(cache=True, inline="always")
def _shares_vertex(faces, a, b):
    for x in range(3):
        for y in range(3):
            if faces[a, x] == faces[b, y]:
                return True
    return False


@njit(cache=True, inline="always")
def _overlap(lo, hi, a, b):
    """Extents a and b (rows of lo, hi) overlap with positive volume."""
    return lo[b, 0] < hi[a, 0] and lo[a, 0] < hi[b, 0] and lo[b, 1] < hi[a, 1] and \
        lo[a, 1] < hi[b, 1] and lo[b, 2] < hi[a, 2] and lo[a, 2] < hi[b, 2]


@njit(cache=True)
def _forward_columns(c, dims, back):
    """Neighbour columns of column c whose index is >= c (the forward half), with their
    offsets: (column, dx, dy) rows."""
    x, y = c // dims[1], c % dims[1]
    out = np.empty(((back[0] + 1) * (2 * back[1] + 1), 3), np.int64)
    n = 0
    for dx in range(0, back[0] + 1):
        for dy in range(-back[1], back[1] + 1):
            if (dx == 0 and dy < 0) or x + dx >= dims[0] or not 0 <= y + dy < dims[1]:
                continue
            out[n, 0], out[n, 1], out[n, 2] = (x + dx) * dims[1] + y + dy, dx, dy
            n += 1
    return out[:n]


@njit(cache=True)
def _column_sweep(c, B, X, box, rel_eps, offsets, out):
    """The pairs whose first face (bucket row) sits in column c: rows of the forward columns
    whose homes fall in its window (z by pointers that only move up), sharing no vertex. ``X``
    empty: those whose extents overlap with positive volume (the candidates); else those that
    cross at positions ``X`` (closed boxes ``box`` overlap, no corner at the same position,
    Möller; a crossing pair's extents overlap, the window holds every candidate). Counts into
    ``offsets[row + 1]`` or, when ``out`` has entries, writes partner rows from ``offsets[row]``
    (rows without partners skipped)."""
    start, z, lo, hi, reach, faces, fid = B.start, B.z, B.lo, B.hi, B.reach, B.faces, B.fid
    nb = _forward_columns(c, B.dims, B.back)
    ptr = np.empty(nb.shape[0], np.int64)
    for j in range(nb.shape[0]):
        ptr[j] = start[nb[j, 0]]
    fill, test = out.shape[0] > 0, X.shape[0] > 0
    for k in range(start[c], start[c + 1]):
        if fill and offsets[k + 1] == offsets[k]:
            continue
        if test:
            b = _box_row(box, k)
        n = 0
        for j in range(nb.shape[0]):
            c2, dx, dy = nb[j, 0], nb[j, 1], nb[j, 2]
            if dx > reach[k, 0] or dy > reach[k, 1]:
                continue
            while ptr[j] < start[c2 + 1] and z[ptr[j]] < z[k] - B.back[2]:
                ptr[j] += 1
            k2 = k + 1 if c2 == c else ptr[j]
            while k2 < start[c2 + 1] and z[k2] <= z[k] + reach[k, 2]:
                ok = False
                if test:
                    if _boxes_meet(box, k2, b):
                        if not _shares_vertex(faces, fid[k], fid[k2]):
                            ok = _cross_rest(X, faces, fid, k, k2, rel_eps)
                elif _overlap(lo, hi, k, k2):
                    ok = not _shares_vertex(faces, fid[k], fid[k2])
                if ok:
                    if fill:
                        out[offsets[k] + n] = k2
                    n += 1
                k2 += 1
        if not fill:
            offsets[k + 1] = n


#: the sweep's columns go to the threads in this many runs of about equal rows
SWEEP_PARTS = 64


@njit(cache=True)
def _row_parts(start, parts):
    """Column bounds (parts + 1,) int64 cutting the columns of the CSR ``start`` into ``parts``
    runs of about equal rows: a prange over the runs keeps the threads equally busy, where a
    prange over the columns gives each thread half of them (the faces are rarely spread evenly
    over the columns)."""
    ncol = start.shape[0] - 1
    bounds = np.empty(parts + 1, np.int64)
    c = 0
    for p in range(parts):
        while c < ncol and start[c] < start[ncol] * p // parts:
            c += 1
        bounds[p] = c
    bounds[parts] = ncol
    return bounds


@njit(parallel=True, cache=True)
def sweep_csr(B, X, box, rel_eps):
    """CSR over bucket rows ``(offsets (M + 1,), partner rows int32)`` of :func:`_column_sweep`
    over all columns: candidate pairs (``X`` empty) or crossing pairs (each pair once)."""
    m = B.fid.shape[0]
    runs = _row_parts(B.start, SWEEP_PARTS)
    offsets = np.zeros(m + 1, np.int64)  # memory: the counts, then (summed in place) offsets
    none = np.zeros(0, np.int32)
    for p in prange(SWEEP_PARTS):
        for c in range(runs[p], runs[p + 1]):
            if B.start[c + 1] > B.start[c]:
                _column_sweep(c, B, X, box, rel_eps, offsets, none)
    for k in range(m):
        offsets[k + 1] += offsets[k]
    partners = np.empty(offsets[m], np.int32)
    if offsets[m] == 0:
        return offsets, partners
    for p in prange(SWEEP_PARTS):
        for c in range(runs[p], runs[p + 1]):
            if offsets[B.start[c + 1]] > offsets[B.start[c]]:
                _column_sweep(c, B, X, box, rel_eps, offsets, partners)
    return offsets, partners


@njit(cache=True)
def _column_of(start, k):
    """The column holding bucket row k: the last c with ``start[c] <= k`` (binary search)."""
    lo, hi = 0, start.shape[0] - 1  # start[lo] <= k < start[hi]
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if start[mid] <= k:
            lo = mid
        else:
            hi = mid
    return lo


@njit(cache=True)
def _around(k, B, X, box, rel_eps, active, out, pos):
    """Crossing partners of bucket row k among all rows whose homes lie within ``back`` of its
    own (both directions); an active partner with a smaller row is left to that row. Writes
    partner rows at ``out[pos:]`` when ``out`` has entries; returns the count."""
    start, z, dims, back, faces, fid = B.start, B.z, B.dims, B.back, B.faces, B.fid
    column = _column_of(start, k)
    hx, hy = column // dims[1], column % dims[1]
    b = _box_row(box, k)
    n = 0
    for x in range(max(hx - back[0], 0), min(hx + back[0], dims[0] - 1) + 1):
        for y in range(max(hy - back[1], 0), min(hy + back[1], dims[1] - 1) + 1):
            c = x * dims[1] + y
            lo_k, hi_k = start[c], start[c + 1]
            while lo_k < hi_k:  # first row with z >= z_k − back
                mid = (lo_k + hi_k) >> 1
                if z[mid] < z[k] - back[2]:
                    lo_k = mid + 1
                else:
                    hi_k = mid
            for k2 in range(lo_k, start[c + 1]):
                if z[k2] > z[k] + back[2]:
                    break
                if k2 == k or (active[k2] and k2 < k):
                    continue
                if not _boxes_meet(box, k2, b) or _shares_vertex(faces, fid[k], fid[k2]):
                    continue
                if _cross_rest(X, faces, fid, k, k2, rel_eps):
                    if out.shape[0] > 0:
                        out[pos + n] = k2
                    n += 1
    return n


@njit(parallel=True, cache=True)
def active_crossings(rows, B, X, box, rel_eps, active):
    """Crossing pairs ``(row, partner row)`` (K, 2) with an active face: ``rows`` the active
    bucket rows, ``active`` (M,) bool over bucket rows."""
    counts = np.zeros(rows.shape[0], np.int64)
    none = np.zeros(0, np.int64)
    for i in prange(rows.shape[0]):
        counts[i] = _around(rows[i], B, X, box, rel_eps, active, none, 0)
    offsets = np.zeros(rows.shape[0] + 1, np.int64)
    for i in range(rows.shape[0]):
        offsets[i + 1] = offsets[i] + counts[i]
    partners = np.empty(offsets[-1], np.int64)
    for i in prange(rows.shape[0]):
        if counts[i]:
            _around(rows[i], B, X, box, rel_eps, active, partners, offsets[i])
    out = np.empty((offsets[-1], 2), np.int64)
    for i in range(rows.shape[0]):
        for t in range(offsets[i], offsets[i + 1]):
            out[t, 0], out[t, 1] = rows[i], partners[t]
    return out


# ---------------------------------------------------------------------------------------------
# crossing test over candidate pairs
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _welded(X, faces, a, b):
    """A corner of face a at exactly the position of a corner of face b."""
    for x in range(3):
        p = faces[a, x]
        for y in range(3):
            q = faces[b, y]
            if X[p, 0] == X[q, 0] and X[p, 1] == X[q, 1] and X[p, 2] == X[q, 2]:
                return True
    return False


#: face boxes are stored as 16-bit steps of a frame over the positions (12 bytes a face)
BOX_STEPS = 65535


@njit(cache=True, inline="always")
def _steps(x, origin, scale):
    """(x − origin) · scale, the position in box steps (monotone in x)."""
    return (x - origin) * scale


@njit(cache=True, inline="always")
def _box_of(X, faces, f, k, origin, scale, box):
    """Box of face f into row k: the steps of its corners' min (rounded down) and max (rounded
    up), clamped to [0, BOX_STEPS]. Monotone roundings of one monotone map: boxes that overlap
    in mm still overlap in steps (a pair is never wrongly taken apart), whatever the frame."""
    for c in range(3):
        x0, x1, x2 = X[faces[f, 0], c], X[faces[f, 1], c], X[faces[f, 2], c]
        lo = math.floor(_steps(min(x0, min(x1, x2)), origin[c], scale[c]))
        hi = math.ceil(_steps(max(x0, max(x1, x2)), origin[c], scale[c]))
        box[k, c] = min(max(lo, 0.0), BOX_STEPS)
        box[k, 3 + c] = min(max(hi, 0.0), BOX_STEPS)


@njit(parallel=True, cache=True)
def face_boxes(X, faces, fid, origin, scale, box):
    """Bounding box of the face of every bucket row (``fid``) into ``box`` (M, 6) uint16: min
    xyz, max xyz in steps of a frame spanning ``X`` (N ≥ 1, 3), rounded outwards (see
    :func:`_box_of`). The frame is written into ``origin`` (3,) float64 (mm, the least
    coordinates) and ``scale`` (3,) float64 (steps per mm) for :func:`face_boxes_of`."""
    for c in range(3):
        lo, hi = X[0, c], X[0, c]
        for i in range(1, X.shape[0]):
            lo, hi = min(lo, X[i, c]), max(hi, X[i, c])
        origin[c] = lo
        scale[c] = BOX_STEPS / (np.float64(hi) - lo) if hi > lo else 0.0
    for k in prange(fid.shape[0]):
        _box_of(X, faces, fid[k], k, origin, scale, box)


@njit(parallel=True, cache=True)
def face_boxes_of(X, faces, fid, rows, origin, scale, box):
    """:func:`face_boxes` for the bucket rows ``rows`` only."""
    for i in prange(rows.shape[0]):
        _box_of(X, faces, fid[rows[i]], rows[i], origin, scale, box)


@njit(cache=True, inline="always")
def _apart_at(X, faces, p, q):
    """The closed boxes of faces p and q at positions X, rounded outwards to float32, do not
    overlap: the exact test behind the 16-bit boxes, which only tell faces surely apart."""
    for c in range(3):
        lo_p = _down32(min(X[faces[p, 0], c], min(X[faces[p, 1], c], X[faces[p, 2], c])))
        hi_p = _up32(max(X[faces[p, 0], c], max(X[faces[p, 1], c], X[faces[p, 2], c])))
        lo_q = _down32(min(X[faces[q, 0], c], min(X[faces[q, 1], c], X[faces[q, 2], c])))
        hi_q = _up32(max(X[faces[q, 0], c], max(X[faces[q, 1], c], X[faces[q, 2], c])))
        if max(lo_p, lo_q) > min(hi_p, hi_q):
            return True
    return False


@njit(cache=True)
def _cross_rest(X, faces, fid, k, k2, rel_eps):
    """Bucket rows k and k2 (16-bit boxes overlapping, no shared corner) cross at positions X:
    closed boxes overlapping (:func:`_apart_at`), no corner at the same position, Möller's test
    with the smaller face id first (as the grid search orders them). Called only after the
    cheap checks, written inline in the loops (numba compiles those tighter than a helper)."""
    p, q = np.int64(fid[k]), np.int64(fid[k2])
    if _apart_at(X, faces, p, q) or _welded(X, faces, p, q):
        return False
    if q < p:
        p, q = q, p
    return tri_tri(X, faces[p, 0], faces[p, 1], faces[p, 2], faces[q, 0], faces[q, 1],
                   faces[q, 2], rel_eps)


@njit(cache=True, inline="always")
def _box_row(box, k):
    """Row k's 16-bit box as a tuple (lo xyz, hi xyz), read once for a loop over partners."""
    return box[k, 0], box[k, 1], box[k, 2], box[k, 3], box[k, 4], box[k, 5]


@njit(cache=True, inline="always")
def _boxes_meet(box, k2, b):
    """The closed 16-bit boxes of row k2 and ``b`` (row k's, :func:`_box_row`) overlap. No
    early exit: most candidates are apart, on any axis, and the branch predictor would miss
    the exits."""
    return (box[k2, 0] <= b[3]) & (b[0] <= box[k2, 3]) & (box[k2, 1] <= b[4]) & \
        (b[1] <= box[k2, 4]) & (box[k2, 2] <= b[5]) & (b[2] <= box[k2, 5])


@njit(parallel=True, cache=True)
def test_pairs(X, B, offsets, partners, rel_eps, box, hit):
    """``hit[t] = 1`` when candidate pair t (bucket row, ``partners[t]``) crosses."""
    faces, fid = B.faces, B.fid
    for k in prange(fid.shape[0]):
        b = _box_row(box, k)
        for t in range(offsets[k], offsets[k + 1]):
            k2 = partners[t]
            near = _boxes_meet(box, k2, b)
            if near:
                near = _cross_rest(X, faces, fid, k, k2, rel_eps)
            hit[t] = near
