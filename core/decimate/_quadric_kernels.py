"""Numba kernels of the quadric error metric (private to :mod:`anatomesh.core.decimate`).

Garland & Heckbert 1997, "Surface simplification using quadric error metrics" (SIGGRAPH): each
vertex carries ``Q`` (10,) float64 = ``[a², ab, ac, ad, b², bc, bd, c², cd, d²]``, the sum of
the squared-distance forms of planes ``a x + b y + c z + d = 0`` (unit normals, mm); an edge's
cost is the summed form at the placement that minimises it. Positions are centred on the
bounding box first (:func:`bounds`), so ``d`` stays small and the forms keep their precision.
"""
from __future__ import annotations

import numpy as np
from numba import njit

#: fast-math flags for the geometry of the collapse loop: reassociation, FMA contraction and
#: reciprocals, but inf/NaN kept IEEE (costs use INF); results stay deterministic
FAST = {"nsz", "arcp", "contract", "afn", "reassoc"}
INF = np.inf


@njit(cache=True)
def _add_plane(Q, v, nx, ny, nz, d, w):
    Q[v, 0] += w * nx * nx
    Q[v, 1] += w * nx * ny
    Q[v, 2] += w * nx * nz
    Q[v, 3] += w * nx * d
    Q[v, 4] += w * ny * ny
    Q[v, 5] += w * ny * nz
    Q[v, 6] += w * ny * d
    Q[v, 7] += w * nz * nz
    Q[v, 8] += w * nz * d
    Q[v, 9] += w * d * d


@njit(cache=True)
def build_quadrics(V, F, cons_a, cons_b, cons_f):
    """Per-vertex quadrics (N, 10): the unit-weight plane of every face at its 3 vertices, plus
    for each feature edge ``(cons_a[i], cons_b[i])`` a constraint plane through the edge,
    perpendicular to face ``cons_f[i]`` (keeps junction curves and boundaries in place, in mm)."""
    n = V.shape[0]
    Q = np.zeros((n, 10))
    for f in range(F.shape[0]):
        i, j, k = F[f, 0], F[f, 1], F[f, 2]
        ux, uy, uz = V[j, 0] - V[i, 0], V[j, 1] - V[i, 1], V[j, 2] - V[i, 2]
        wx, wy, wz = V[k, 0] - V[i, 0], V[k, 1] - V[i, 1], V[k, 2] - V[i, 2]
        nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
        ln = np.sqrt(nx * nx + ny * ny + nz * nz)
        if ln <= 1e-30:
            continue
        nx, ny, nz = nx / ln, ny / ln, nz / ln
        d = -(nx * V[i, 0] + ny * V[i, 1] + nz * V[i, 2])
        _add_plane(Q, i, nx, ny, nz, d, 1.0)
        _add_plane(Q, j, nx, ny, nz, d, 1.0)
        _add_plane(Q, k, nx, ny, nz, d, 1.0)
    for e in range(cons_a.shape[0]):
        a, b, f = cons_a[e], cons_b[e], cons_f[e]
        i, j, k = F[f, 0], F[f, 1], F[f, 2]
        ux, uy, uz = V[j, 0] - V[i, 0], V[j, 1] - V[i, 1], V[j, 2] - V[i, 2]
        wx, wy, wz = V[k, 0] - V[i, 0], V[k, 1] - V[i, 1], V[k, 2] - V[i, 2]
        nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
        ex, ey, ez = V[b, 0] - V[a, 0], V[b, 1] - V[a, 1], V[b, 2] - V[a, 2]
        mx, my, mz = ey * nz - ez * ny, ez * nx - ex * nz, ex * ny - ey * nx
        lm = np.sqrt(mx * mx + my * my + mz * mz)
        if lm <= 1e-30:
            continue
        mx, my, mz = mx / lm, my / lm, mz / lm
        d = -(mx * V[a, 0] + my * V[a, 1] + mz * V[a, 2])
        _add_plane(Q, a, mx, my, mz, d, 1.0)
        _add_plane(Q, b, mx, my, mz, d, 1.0)
    return Q


@njit(cache=True, fastmath=FAST)
def qeval(q, x, y, z):
    return (q[0] * x * x + 2 * q[1] * x * y + 2 * q[2] * x * z + 2 * q[3] * x
            + q[4] * y * y + 2 * q[5] * y * z + 2 * q[6] * y
            + q[7] * z * z + 2 * q[8] * z + q[9])


@njit(cache=True, fastmath=FAST)
def plan(V, Q, vclass, a, b, q):
    """Where to put the merged vertex of edge (a, b) and what it costs.

    Returns ``(cost, keep, drop, x, y, z)``; cost is ``inf`` for a forbidden edge. ``q`` is a
    scratch (10,) array receiving Q[a] + Q[b].
    """
    ca, cb = vclass[a], vclass[b]
    if ca == 2 or cb == 2:
        return INF, a, b, 0.0, 0.0, 0.0
    for i in range(10):
        q[i] = Q[a, i] + Q[b, i]
    if ca == 1 and cb == 0:          # free vertex b slides into fixed feature vertex a
        x, y, z = V[a, 0], V[a, 1], V[a, 2]
        return max(qeval(q, x, y, z), 0.0), a, b, x, y, z
    if cb == 1 and ca == 0:
        x, y, z = V[b, 0], V[b, 1], V[b, 2]
        return max(qeval(q, x, y, z), 0.0), b, a, x, y, z
    if ca == 1:
        # along a junction curve (or open boundary): stay at the cheaper endpoint, so junction
        # vertices remain points of the original junction polyline
        ca_ = max(qeval(q, V[a, 0], V[a, 1], V[a, 2]), 0.0)
        cb_ = max(qeval(q, V[b, 0], V[b, 1], V[b, 2]), 0.0)
        if ca_ <= cb_:
            return ca_, a, b, V[a, 0], V[a, 1], V[a, 2]
        return cb_, b, a, V[b, 0], V[b, 1], V[b, 2]
    keep, drop = (a, b) if a < b else (b, a)
    ax, ay, az = V[a, 0], V[a, 1], V[a, 2]
    dx, dy, dz = V[b, 0] - ax, V[b, 1] - ay, V[b, 2] - az
    # optimal placement: solve A p = -b (3x3, Cramer) when well conditioned
    a00, a01, a02, a11, a12, a22 = q[0], q[1], q[2], q[4], q[5], q[7]
    b0, b1, b2 = -q[3], -q[6], -q[8]
    c00 = a11 * a22 - a12 * a12
    c01 = a02 * a12 - a01 * a22
    c02 = a01 * a12 - a02 * a11
    det = a00 * c00 + a01 * c01 + a02 * c02
    tr = (a00 + a11 + a22) / 3.0
    if abs(det) > 1e-3 * tr * tr * tr:
        c11 = a00 * a22 - a02 * a02
        c12 = a01 * a02 - a00 * a12
        c22 = a00 * a11 - a01 * a01
        x = (c00 * b0 + c01 * b1 + c02 * b2) / det
        y = (c01 * b0 + c11 * b1 + c12 * b2) / det
        z = (c02 * b0 + c12 * b1 + c22 * b2) / det
        # stay near the edge: a far optimum signals a near-singular system
        mx, my, mz = x - (ax + 0.5 * dx), y - (ay + 0.5 * dy), z - (az + 0.5 * dz)
        if mx * mx + my * my + mz * mz <= 4.0 * (dx * dx + dy * dy + dz * dz):
            return max(qeval(q, x, y, z), 0.0), keep, drop, x, y, z
    # ill conditioned: minimise along the segment a + t (b - a), t in [0, 1]
    adx = q[0] * dx + q[1] * dy + q[2] * dz
    ady = q[1] * dx + q[4] * dy + q[5] * dz
    adz = q[2] * dx + q[5] * dy + q[7] * dz
    dad = adx * dx + ady * dy + adz * dz
    t = 0.5
    if dad > 1e-300:
        t = -(adx * ax + ady * ay + adz * az + q[3] * dx + q[6] * dy + q[8] * dz) / dad
        t = min(1.0, max(0.0, t))
    x, y, z = ax + t * dx, ay + t * dy, az + t * dz
    return max(qeval(q, x, y, z), 0.0), keep, drop, x, y, z


@njit(cache=True)
def bounds(V):
    """Bounding box of (N, 3) positions in one pass: (lo (3,), hi (3,), all finite)."""
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    finite = True
    for i in range(V.shape[0]):
        for j in range(3):
            x = V[i, j]
            if not np.isfinite(x):
                finite = False
            if x < lo[j]:
                lo[j] = x
            if x > hi[j]:
                hi[j] = x
    return lo, hi, finite
