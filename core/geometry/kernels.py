"""Small numba kernels shared across rooms: sorted search, face corners, union-find, a
triangle's cross product and the triangle-triangle intersection test (Möller 1997).

Public so that kernel modules of other rooms can call them inside their own kernels.
"""
import numpy as np
from numba import njit


@njit(cache=True)
def lower_bound(a, x):
    """First index of sorted ``a`` whose value is >= x (``np.searchsorted``, side="left")."""
    lo = 0
    hi = a.shape[0]
    while lo < hi:
        mid = (lo + hi) >> 1
        if a[mid] < x:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True)
def other_corners(faces, f, i):
    """The corners ``(j, k)`` of face ``f`` after its corner ``i``, in winding order, so the
    face reads (i, j, k)."""
    if faces[f, 0] == i:
        return faces[f, 1], faces[f, 2]
    if faces[f, 1] == i:
        return faces[f, 2], faces[f, 0]
    return faces[f, 0], faces[f, 1]


@njit(cache=True)
def find_root(parent, x):
    """Root of ``x`` in the union-find forest ``parent`` (int array, changed in place: path
    compression)."""
    root = x
    while parent[root] != root:
        root = parent[root]
    while parent[x] != root:  # path compression
        nxt = parent[x]
        parent[x] = root
        x = nxt
    return root


@njit(cache=True)
def union(parent, a, b):
    """Join the trees of ``a`` and ``b`` in the union-find forest ``parent`` under the smaller
    root (so every root is its component's smallest index); True when they were apart."""
    ra, rb = find_root(parent, a), find_root(parent, b)
    if ra == rb:
        return False
    parent[max(ra, rb)] = min(ra, rb)
    return True


@njit(cache=True)
def union_faces(faces, n):
    """Union-find forest (n,) int64 of the mesh's edge graph, from the faces' edges: every
    component's root is its smallest vertex (an isolated vertex is its own root)."""
    parent = np.arange(n)
    for f in range(faces.shape[0]):
        for c in range(2):
            union(parent, faces[f, c], faces[f, c + 1])
    return parent


@njit(cache=True)
def union_find_roots(a, b, n):
    """Root of each of ``n`` nodes for the graph with edges (a[i], b[i]); int64 (n,).

    Roots are the smallest node index of each component, so results are deterministic.
    """
    parent = np.arange(n)
    for i in range(a.shape[0]):
        union(parent, a[i], b[i])
    for x in range(n):
        parent[x] = find_root(parent, x)
    return parent


@njit(cache=True)
def triangle_interval(p0, p1, p2, d0, d1, d2):
    """Interval of a triangle on the line where two triangles' planes meet (Möller 1997, "A fast
    triangle-triangle intersection test"): its corners' projections ``p0..p2`` on the line and
    signed distances ``d0..d2`` to the other plane; returns ``(lo, hi, coplanar)``."""
    if d0 * d1 > 0.0:  # p2 alone on its side
        a = p2 + (p0 - p2) * d2 / (d2 - d0)
        b = p2 + (p1 - p2) * d2 / (d2 - d1)
    elif d0 * d2 > 0.0:  # p1 alone
        a = p1 + (p0 - p1) * d1 / (d1 - d0)
        b = p1 + (p2 - p1) * d1 / (d1 - d2)
    elif d1 * d2 > 0.0 or d0 != 0.0:  # p0 alone
        a = p0 + (p1 - p0) * d0 / (d0 - d1)
        b = p0 + (p2 - p0) * d0 / (d0 - d2)
    elif d1 != 0.0:
        a = p1 + (p0 - p1) * d1 / (d1 - d0)
        b = p1 + (p2 - p1) * d1 / (d1 - d2)
    elif d2 != 0.0:
        a = p2 + (p0 - p2) * d2 / (d2 - d0)
        b = p2 + (p1 - p2) * d2 / (d2 - d1)
    else:
        return 0.0, 0.0, True
    if a > b:
        a, b = b, a
    return a, b, False


@njit(cache=True, inline="always")
def triangle_cross(pos, a, b, c):
    """The unnormalised normal (b - a) x (c - a) of the triangle (a, b, c) of ``pos`` (N, 3):
    twice its area times its unit normal."""
    e1x, e1y, e1z = pos[b, 0] - pos[a, 0], pos[b, 1] - pos[a, 1], pos[b, 2] - pos[a, 2]
    e2x, e2y, e2z = pos[c, 0] - pos[a, 0], pos[c, 1] - pos[a, 1], pos[c, 2] - pos[a, 2]
    return e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x


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
