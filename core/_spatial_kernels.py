"""Numba kernels for :mod:`anatomesh.core.spatial`: a uniform grid over triangles, closest-point
queries and ray casting. Private: call the wrappers in ``spatial.py`` (they validate inputs).

Grid layout: ``origin`` (3,) float64 mm, cell size ``h`` mm, ``dims`` (3,) int64; cell
``(i, j, k)`` has flat index ``(i * dims[1] + j) * dims[2] + k`` and holds the triangles
``items[start[c]:start[c + 1]]`` whose bounding boxes overlap it.
"""
import numpy as np
from numba import njit, prange

# closest-point feature codes (Ericson 2004, "Real-Time Collision Detection", §5.1.5)
VERT_A, VERT_B, VERT_C, EDGE_AB, EDGE_BC, EDGE_CA, INTERIOR = 0, 1, 2, 3, 4, 5, 6


# ---------------------------------------------------------------------------------------------
# grid construction
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _cell_range(lo, hi, origin, h, dims, out):
    for a in range(3):
        i0 = int(np.floor((lo[a] - origin[a]) / h))
        i1 = int(np.floor((hi[a] - origin[a]) / h))
        out[a, 0] = min(max(i0, 0), dims[a] - 1)
        out[a, 1] = min(max(i1, 0), dims[a] - 1)


@njit(cache=True)
def build_grid(vertices, faces, origin, h, dims):
    """Bin triangles into cells by bounding box; returns (start (C+1,) int64, items int32)."""
    m = faces.shape[0]
    ncell = dims[0] * dims[1] * dims[2]
    counts = np.zeros(ncell + 1, np.int64)
    rng = np.empty((3, 2), np.int64)
    lo = np.empty(3)
    hi = np.empty(3)
    for f in range(m):
        for a in range(3):
            x0 = vertices[faces[f, 0], a]
            x1 = vertices[faces[f, 1], a]
            x2 = vertices[faces[f, 2], a]
            lo[a] = min(x0, min(x1, x2))
            hi[a] = max(x0, max(x1, x2))
        _cell_range(lo, hi, origin, h, dims, rng)
        for i in range(rng[0, 0], rng[0, 1] + 1):
            for j in range(rng[1, 0], rng[1, 1] + 1):
                for k in range(rng[2, 0], rng[2, 1] + 1):
                    counts[(i * dims[1] + j) * dims[2] + k + 1] += 1
    start = np.cumsum(counts)
    fill = start[:-1].copy()
    items = np.empty(start[-1], np.int32)
    for f in range(m):
        for a in range(3):
            x0 = vertices[faces[f, 0], a]
            x1 = vertices[faces[f, 1], a]
            x2 = vertices[faces[f, 2], a]
            lo[a] = min(x0, min(x1, x2))
            hi[a] = max(x0, max(x1, x2))
        _cell_range(lo, hi, origin, h, dims, rng)
        for i in range(rng[0, 0], rng[0, 1] + 1):
            for j in range(rng[1, 0], rng[1, 1] + 1):
                for k in range(rng[2, 0], rng[2, 1] + 1):
                    c = (i * dims[1] + j) * dims[2] + k
                    items[fill[c]] = f
                    fill[c] += 1
    return start, items


# ---------------------------------------------------------------------------------------------
# point-triangle distance
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _sub(a, b):
    return a[0] - b[0], a[1] - b[1], a[2] - b[2]


@njit(cache=True, inline="always")
def _dot3(x0, x1, x2, y0, y1, y2):
    return x0 * y0 + x1 * y1 + x2 * y2


@njit(cache=True)
def closest_on_triangle(p, a, b, c):
    """Closest point to ``p`` on triangle abc (each (3,) float64): returns (x, y, z, feature) with
    feature = vertex 0-2, edge 3-5 (ab, bc, ca), interior 6. Ericson 2004, §5.1.5. Scalar code:
    no temporary arrays in the hot loop."""
    abx, aby, abz = _sub(b, a)
    acx, acy, acz = _sub(c, a)
    apx, apy, apz = _sub(p, a)
    d1 = _dot3(abx, aby, abz, apx, apy, apz)
    d2 = _dot3(acx, acy, acz, apx, apy, apz)
    if d1 <= 0.0 and d2 <= 0.0:
        return a[0], a[1], a[2], VERT_A
    bpx, bpy, bpz = _sub(p, b)
    d3 = _dot3(abx, aby, abz, bpx, bpy, bpz)
    d4 = _dot3(acx, acy, acz, bpx, bpy, bpz)
    if d3 >= 0.0 and d4 <= d3:
        return b[0], b[1], b[2], VERT_B
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        den = d1 - d3
        v = d1 / den if den != 0.0 else 0.0
        return a[0] + v * abx, a[1] + v * aby, a[2] + v * abz, EDGE_AB
    cpx, cpy, cpz = _sub(p, c)
    d5 = _dot3(abx, aby, abz, cpx, cpy, cpz)
    d6 = _dot3(acx, acy, acz, cpx, cpy, cpz)
    if d6 >= 0.0 and d5 <= d6:
        return c[0], c[1], c[2], VERT_C
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        den = d2 - d6
        w = d2 / den if den != 0.0 else 0.0
        return a[0] + w * acx, a[1] + w * acy, a[2] + w * acz, EDGE_CA
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        den = (d4 - d3) + (d5 - d6)
        w = (d4 - d3) / den if den != 0.0 else 0.0
        return b[0] + w * (c[0] - b[0]), b[1] + w * (c[1] - b[1]), b[2] + w * (c[2] - b[2]), EDGE_BC
    den = va + vb + vc
    if den == 0.0:  # degenerate triangle: fall back to the first vertex
        return a[0], a[1], a[2], VERT_A
    v = vb / den
    w = vc / den
    return (a[0] + abx * v + acx * w, a[1] + aby * v + acy * w, a[2] + abz * v + acz * w,
            INTERIOR)


@njit(cache=True, inline="always")
def _axis_gap(x, lo, h):
    if x < lo:
        return lo - x
    if x > lo + h:
        return x - lo - h
    return 0.0


@njit(cache=True)
def _cell_box_dist2(p, origin, h, i, j, k):
    gx = _axis_gap(p[0], origin[0] + i * h, h)
    gy = _axis_gap(p[1], origin[1] + j * h, h)
    gz = _axis_gap(p[2], origin[2] + k * h, h)
    return gx * gx + gy * gy + gz * gz


@njit(cache=True)
def _closest_one(p, vertices, faces, origin, h, dims, start, items, max_d, skip_face, q):
    """Nearest point on the mesh to ``p`` within ``max_d``; returns (dist, face, feature)."""
    ci = np.empty(3, np.int64)
    for a in range(3):
        ci[a] = int(np.floor((p[a] - origin[a]) / h))
    # rings needed to reach the grid at all
    r0 = 0
    for a in range(3):
        if ci[a] < 0:
            r0 = max(r0, -ci[a])
        elif ci[a] >= dims[a]:
            r0 = max(r0, ci[a] - dims[a] + 1)
    best = max_d
    best2 = max_d * max_d
    best_f = -1
    best_feat = -1
    rmax = 0
    for a in range(3):
        rmax = max(rmax, abs(ci[a]) + dims[a])
    r = r0
    while r <= rmax:
        if (r - 1) * h > best:
            break
        for di in range(-r, r + 1):
            i = ci[0] + di
            if i < 0 or i >= dims[0]:
                continue
            for dj in range(-r, r + 1):
                j = ci[1] + dj
                if j < 0 or j >= dims[1]:
                    continue
                edge = abs(di) == r or abs(dj) == r
                step = 1 if edge else 2 * r
                if r == 0:
                    step = 1
                dk = -r
                while dk <= r:
                    k = ci[2] + dk
                    if 0 <= k < dims[2]:
                        if _cell_box_dist2(p, origin, h, i, j, k) <= best2:
                            c = (i * dims[1] + j) * dims[2] + k
                            for t in range(start[c], start[c + 1]):
                                f = items[t]
                                if skip_face.shape[0] > 0 and skip_face[f]:
                                    continue
                                x, y, z, feat = closest_on_triangle(p, vertices[faces[f, 0]],
                                                                    vertices[faces[f, 1]],
                                                                    vertices[faces[f, 2]])
                                d2 = (x - p[0]) ** 2 + (y - p[1]) ** 2 + (z - p[2]) ** 2
                                if d2 < best2 or (d2 == best2 and best_f >= 0 and f < best_f):
                                    best2 = d2
                                    best = np.sqrt(d2)
                                    best_f = f
                                    best_feat = feat
                                    q[0] = x
                                    q[1] = y
                                    q[2] = z
                    dk += step
        if best_f >= 0 and best <= r * h:
            break
        r += 1
    if best_f < 0:
        return np.inf, -1, -1
    return best, best_f, best_feat


@njit(cache=True)
def closest_points(points, vertices, faces, origin, h, dims, start, items, max_d, skip_face):
    """For each point (P,3): distance, face (-1 if none within max_d), feature, closest point."""
    n = points.shape[0]
    dist = np.full(n, np.inf)
    face = np.full(n, -1, np.int64)
    feat = np.full(n, -1, np.int64)
    close = np.full((n, 3), np.nan)
    for i in range(n):
        q = np.empty(3)
        p = points[i].copy()
        d, f, ft = _closest_one(p, vertices, faces, origin, h, dims, start, items, max_d[i],
                                skip_face, q)
        if f >= 0:
            dist[i] = d
            face[i] = f
            feat[i] = ft
            close[i] = q
    return dist, face, feat, close


# ---------------------------------------------------------------------------------------------
# rays
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _ray_tri_idx(o, d, vertices, ia, ib, ic, edge_tol):
    """Möller & Trumbore 1997 ray-triangle test on vertex rows ia, ib, ic (scalar reads, no array
    views); returns (t, ambiguous) with t = inf on a miss.

    ``ambiguous`` is True when the hit lies within ``edge_tol`` (barycentric) of an edge, where
    parity counting could see the same crossing twice."""
    ax, ay, az = vertices[ia, 0], vertices[ia, 1], vertices[ia, 2]
    e1x, e1y, e1z = vertices[ib, 0] - ax, vertices[ib, 1] - ay, vertices[ib, 2] - az
    e2x, e2y, e2z = vertices[ic, 0] - ax, vertices[ic, 1] - ay, vertices[ic, 2] - az
    px = d[1] * e2z - d[2] * e2y
    py = d[2] * e2x - d[0] * e2z
    pz = d[0] * e2y - d[1] * e2x
    det = e1x * px + e1y * py + e1z * pz
    scale = (abs(e1x) + abs(e1y) + abs(e1z)) * (abs(e2x) + abs(e2y) + abs(e2z))
    if abs(det) <= 1e-14 * scale:
        return np.inf, False
    inv = 1.0 / det
    tx, ty, tz = o[0] - ax, o[1] - ay, o[2] - az
    u = (tx * px + ty * py + tz * pz) * inv
    if u < -edge_tol or u > 1.0 + edge_tol:
        return np.inf, False
    qx = ty * e1z - tz * e1y
    qy = tz * e1x - tx * e1z
    qz = tx * e1y - ty * e1x
    v = (d[0] * qx + d[1] * qy + d[2] * qz) * inv
    if v < -edge_tol or u + v > 1.0 + edge_tol:
        return np.inf, False
    t = (e2x * qx + e2y * qy + e2z * qz) * inv
    amb = u < edge_tol or v < edge_tol or u + v > 1.0 - edge_tol
    return t, amb


@njit(cache=True)
def _cast_one(o, d, vertices, faces, origin, h, dims, start, items, tmin, tmax, skip_vertex,
              count_all, edge_tol):
    """Walk the grid along o + t d (Amanatides & Woo 1987). Returns (first t, first face,
    number of crossings in (tmin, tmax), ambiguous)."""
    # clip to the grid box
    t0 = tmin
    t1 = tmax
    for a in range(3):
        lo = origin[a]
        hi = origin[a] + dims[a] * h
        if d[a] == 0.0:
            if o[a] < lo or o[a] > hi:
                return np.inf, -1, 0, False
        else:
            ta = (lo - o[a]) / d[a]
            tb = (hi - o[a]) / d[a]
            if ta > tb:
                ta, tb = tb, ta
            t0 = max(t0, ta)
            t1 = min(t1, tb)
    if t0 > t1:
        return np.inf, -1, 0, False
    cell = np.empty(3, np.int64)
    step = np.empty(3, np.int64)
    tnext = np.empty(3)
    tdelta = np.empty(3)
    for a in range(3):
        x = o[a] + t0 * d[a]
        c = int(np.floor((x - origin[a]) / h))
        cell[a] = min(max(c, 0), dims[a] - 1)
        if d[a] > 0:
            step[a] = 1
            tnext[a] = (origin[a] + (cell[a] + 1) * h - o[a]) / d[a]
            tdelta[a] = h / d[a]
        elif d[a] < 0:
            step[a] = -1
            tnext[a] = (origin[a] + cell[a] * h - o[a]) / d[a]
            tdelta[a] = -h / d[a]
        else:
            step[a] = 0
            tnext[a] = np.inf
            tdelta[a] = np.inf
    best = np.inf
    best_f = -1
    ncross = 0
    amb = False
    tcell0 = t0
    while True:
        tcell1 = min(tnext[0], min(tnext[1], tnext[2]))
        c = (cell[0] * dims[1] + cell[1]) * dims[2] + cell[2]
        for s in range(start[c], start[c + 1]):
            f = items[s]
            if skip_vertex >= 0 and (faces[f, 0] == skip_vertex or faces[f, 1] == skip_vertex
                                     or faces[f, 2] == skip_vertex):
                continue
            t, am = _ray_tri_idx(o, d, vertices, faces[f, 0], faces[f, 1], faces[f, 2], edge_tol)
            if t <= tmin or t > tmax:
                continue
            # count each crossing once: in the cell where the hit point lies
            if t < tcell0 or t >= tcell1:
                if not (tcell1 >= t1 and t >= tcell0 and t <= t1):
                    continue
            ncross += 1
            if am:
                amb = True
            if t < best:
                best = t
                best_f = f
        if not count_all and best <= tcell1:
            break
        if tcell1 >= t1:
            break
        # step to the next cell
        a = 0
        if tnext[1] < tnext[a]:
            a = 1
        if tnext[2] < tnext[a]:
            a = 2
        cell[a] += step[a]
        if cell[a] < 0 or cell[a] >= dims[a]:
            break
        tcell0 = tnext[a]
        tnext[a] += tdelta[a]
    return best, best_f, ncross, amb


@njit(cache=True, parallel=True)
def cast_rays(origins, dirs, vertices, faces, origin, h, dims, start, items, tmin, tmax,
              skip_vertex, count_all, edge_tol):
    """First hit (t, face) and crossing count of each ray; ``dirs`` need not be unit (t scales)."""
    n = origins.shape[0]
    t_hit = np.full(n, np.inf)
    f_hit = np.full(n, -1, np.int64)
    ncross = np.zeros(n, np.int64)
    amb = np.zeros(n, np.bool_)
    for i in prange(n):
        sv = skip_vertex[i] if skip_vertex.shape[0] > 0 else -1
        t, f, nc, am = _cast_one(origins[i].copy(), dirs[i].copy(), vertices, faces, origin, h,
                                 dims, start, items, tmin, tmax, sv, count_all, edge_tol)
        t_hit[i] = t
        f_hit[i] = f
        ncross[i] = nc
        amb[i] = am
    return t_hit, f_hit, ncross, amb
