"""Numba kernels for :mod:`anatomesh.core.geometry.spatial`: a uniform grid over triangles, closest-point
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
@njit(cache=True)
def _on_segment(px, py, pz, ax, ay, az, bx, by, bz):
    """Closest point to p on segment ab: (x, y, z, t) with t in [0, 1] along ab."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    uu = ux * ux + uy * uy + uz * uz
    t = 0.0
    if uu > 0.0:
        t = min(1.0, max(0.0, ((px - ax) * ux + (py - ay) * uy + (pz - az) * uz) / uu))
    return ax + t * ux, ay + t * uy, az + t * uz, t


@njit(cache=True)
def closest_on_triangle(px, py, pz, vertices, ia, ib, ic):
    """Closest point to (px, py, pz) on the triangle of vertex rows ia, ib, ic: returns
    (x, y, z, feature) with feature = vertex 0-2, edge 3-5 (ab, bc, ca), interior 6. Ericson
    2004, §5.1.5. Scalar reads, no temporary arrays in the hot loop."""
    ax, ay, az = vertices[ia, 0], vertices[ia, 1], vertices[ia, 2]
    bx, by, bz = vertices[ib, 0], vertices[ib, 1], vertices[ib, 2]
    cx, cy, cz = vertices[ic, 0], vertices[ic, 1], vertices[ic, 2]
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return ax, ay, az, VERT_A
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return bx, by, bz, VERT_B
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        den = d1 - d3
        v = d1 / den if den != 0.0 else 0.0
        return ax + v * abx, ay + v * aby, az + v * abz, EDGE_AB
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return cx, cy, cz, VERT_C
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        den = d2 - d6
        w = d2 / den if den != 0.0 else 0.0
        return ax + w * acx, ay + w * acy, az + w * acz, EDGE_CA
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        den = (d4 - d3) + (d5 - d6)
        w = (d4 - d3) / den if den != 0.0 else 0.0
        return bx + w * (cx - bx), by + w * (cy - by), bz + w * (cz - bz), EDGE_BC
    den = va + vb + vc
    if not den > 0.0:  # degenerate triangle (a segment or a point): nearest of its edges
        x, y, z, t = _on_segment(px, py, pz, ax, ay, az, bx, by, bz)
        best = (x - px) ** 2 + (y - py) ** 2 + (z - pz) ** 2
        feat = EDGE_AB
        x2, y2, z2, t = _on_segment(px, py, pz, bx, by, bz, cx, cy, cz)
        d2 = (x2 - px) ** 2 + (y2 - py) ** 2 + (z2 - pz) ** 2
        if d2 < best:
            x, y, z, best, feat = x2, y2, z2, d2, EDGE_BC
        x2, y2, z2, t = _on_segment(px, py, pz, cx, cy, cz, ax, ay, az)
        d2 = (x2 - px) ** 2 + (y2 - py) ** 2 + (z2 - pz) ** 2
        if d2 < best:
            x, y, z, best, feat = x2, y2, z2, d2, EDGE_CA
        return x, y, z, feat
    v = vb / den
    w = vc / den
    return ax + abx * v + acx * w, ay + aby * v + acy * w, az + abz * v + acz * w, INTERIOR


@njit(cache=True)
def closest_xyz(px, py, pz, vertices, faces, origin, h, dims, start, items, max_d, skip_face):
    """Nearest point on the mesh to (px, py, pz) within ``max_d``, searching cells ring by ring
    and skipping cells farther than the best triangle so far; no allocations.

    Returns (dist, face, feature, qx, qy, qz); face -1 and dist inf when nothing is that near."""
    fx = (px - origin[0]) / h
    fy = (py - origin[1]) / h
    fz = (pz - origin[2]) / h
    cx = int(np.floor(fx))
    cy = int(np.floor(fy))
    cz = int(np.floor(fz))
    # rings needed to reach the grid at all
    r0 = 0
    for c0, d0 in ((cx, dims[0]), (cy, dims[1]), (cz, dims[2])):
        if c0 < 0:
            r0 = max(r0, -c0)
        elif c0 >= d0:
            r0 = max(r0, c0 - d0 + 1)
    best = max_d
    best2 = max_d * max_d
    best_f = -1
    best_feat = -1
    qx = np.nan
    qy = np.nan
    qz = np.nan
    rmax = max(abs(cx) + dims[0], max(abs(cy) + dims[1], abs(cz) + dims[2]))
    hh = h * h
    r = r0
    while r <= rmax:
        if (r - 1) * h > best:
            break
        for i in range(max(cx - r, 0), min(cx + r, dims[0] - 1) + 1):
            gx = max(0.0, max(i - fx, fx - (i + 1)))
            for j in range(max(cy - r, 0), min(cy + r, dims[1] - 1) + 1):
                gy = max(0.0, max(j - fy, fy - (j + 1)))
                edge = abs(i - cx) == r or abs(j - cy) == r
                step = 1 if (edge or r == 0) else 2 * r
                k = cz - r
                while k <= cz + r:
                    if 0 <= k < dims[2]:
                        gz = max(0.0, max(k - fz, fz - (k + 1)))
                        if (gx * gx + gy * gy + gz * gz) * hh <= best2:
                            c = (i * dims[1] + j) * dims[2] + k
                            for t in range(start[c], start[c + 1]):
                                f = items[t]
                                if skip_face.shape[0] > 0 and skip_face[f]:
                                    continue
                                x, y, z, feat = closest_on_triangle(
                                    px, py, pz, vertices, faces[f, 0], faces[f, 1], faces[f, 2])
                                d2 = (x - px) ** 2 + (y - py) ** 2 + (z - pz) ** 2
                                if d2 < best2 or (d2 == best2 and best_f >= 0 and f < best_f):
                                    best2 = d2
                                    best = np.sqrt(d2)
                                    best_f = f
                                    best_feat = feat
                                    qx = x
                                    qy = y
                                    qz = z
                    k += step
        if best_f >= 0 and best <= r * h:
            break
        r += 1
    if best_f < 0:
        return np.inf, -1, -1, np.nan, np.nan, np.nan
    return best, best_f, best_feat, qx, qy, qz


@njit(cache=True, parallel=True)
def closest_points(points, vertices, faces, origin, h, dims, start, items, max_d, skip_face):
    """For each point (P,3): distance, face (-1 if none within max_d), feature, closest point."""
    n = points.shape[0]
    dist = np.full(n, np.inf)
    face = np.full(n, -1, np.int64)
    feat = np.full(n, -1, np.int64)
    close = np.full((n, 3), np.nan)
    for i in prange(n):
        d, f, ft, qx, qy, qz = closest_xyz(points[i, 0], points[i, 1], points[i, 2], vertices,
                                           faces, origin, h, dims, start, items, max_d[i],
                                           skip_face)
        if f >= 0:
            dist[i] = d
            face[i] = f
            feat[i] = ft
            close[i, 0] = qx
            close[i, 1] = qy
            close[i, 2] = qz
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
def _cast_one(ox, oy, oz, dx, dy, dz, vertices, faces, origin, h, dims, start, items, tmin,
              tmax, skip_vertex, count_all, edge_tol):
    """Walk the grid along o + t d (Amanatides & Woo 1987), scalars only. Returns (first t,
    first face, number of crossings in (tmin, tmax), ambiguous)."""
    o = (ox, oy, oz)
    d = (dx, dy, dz)
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
    c0, s0, n0, e0 = _axis_setup(ox, dx, t0, origin[0], h, dims[0])
    c1, s1, n1, e1 = _axis_setup(oy, dy, t0, origin[1], h, dims[1])
    c2, s2, n2, e2 = _axis_setup(oz, dz, t0, origin[2], h, dims[2])
    best = np.inf
    best_f = -1
    ncross = 0
    amb = False
    tcell0 = t0
    while True:
        tcell1 = min(n0, min(n1, n2))
        c = (c0 * dims[1] + c1) * dims[2] + c2
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
        if n0 <= n1 and n0 <= n2:
            c0 += s0
            if c0 < 0 or c0 >= dims[0]:
                break
            tcell0 = n0
            n0 += e0
        elif n1 <= n2:
            c1 += s1
            if c1 < 0 or c1 >= dims[1]:
                break
            tcell0 = n1
            n1 += e1
        else:
            c2 += s2
            if c2 < 0 or c2 >= dims[2]:
                break
            tcell0 = n2
            n2 += e2
    return best, best_f, ncross, amb


@njit(cache=True, inline="always")
def _axis_setup(o, d, t0, lo, h, n):
    """Start cell, step, t of the next cell boundary and t per cell along one axis."""
    c = int(np.floor((o + t0 * d - lo) / h))
    c = min(max(c, 0), n - 1)
    if d > 0:
        return c, 1, (lo + (c + 1) * h - o) / d, h / d
    if d < 0:
        return c, -1, (lo + c * h - o) / d, -h / d
    return c, 0, np.inf, np.inf


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
        t, f, nc, am = _cast_one(origins[i, 0], origins[i, 1], origins[i, 2], dirs[i, 0],
                                 dirs[i, 1], dirs[i, 2], vertices, faces, origin, h, dims, start,
                                 items, tmin, tmax, sv, count_all, edge_tol)
        t_hit[i] = t
        f_hit[i] = f
        ncross[i] = nc
        amb[i] = am
    return t_hit, f_hit, ncross, amb


# ---------------------------------------------------------------------------------------------
# shrinking ball (Ma, Bae & Kobbelt 2012)
# ---------------------------------------------------------------------------------------------
@njit(cache=True, parallel=True)
def shrinking_ball(points, inward, r0, vertices, faces, origin, h, dims, start, items,
                   min_sep_cos, max_iter, tol):
    """Radius (P,) of the largest empty ball touching each surface point p with its centre on
    p + r * inward (unit inward directions (P, 3)), starting from radius r0 (P,).

    Each step finds the surface point q nearest to the centre; if it is inside the ball the radius
    shrinks to the ball through p and q: r = |p − q|² / (2 n·(q − p)). A q seen from the centre
    within the separation angle (cos > ``min_sep_cos``) of p is a neighbour of p on the same side
    (local curvature or a corner), not the opposite wall, and stops the shrinking."""
    n = points.shape[0]
    radius = r0.copy()
    empty = np.zeros(n, np.bool_)
    skip = np.zeros(0, np.bool_)
    for i in prange(n):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        nx, ny, nz = inward[i, 0], inward[i, 1], inward[i, 2]
        r = r0[i]
        if not np.isfinite(r) or r <= 0:
            continue
        for _ in range(max_iter):
            cx, cy, cz = px + r * nx, py + r * ny, pz + r * nz
            d, f, feat, qx, qy, qz = closest_xyz(cx, cy, cz, vertices, faces, origin, h, dims,
                                                 start, items, r * (1.0 - tol), skip)
            if f < 0 or d >= r * (1.0 - tol):
                empty[i] = True  # the ball is empty: an inscribed (medial) ball
                break
            ux, uy, uz = qx - px, qy - py, qz - pz
            proj = nx * ux + ny * uy + nz * uz
            if proj <= 0.0:
                break
            # separation angle at the centre between p and q
            ax, ay, az = px - cx, py - cy, pz - cz
            bx, by, bz = qx - cx, qy - cy, qz - cz
            den = np.sqrt((ax * ax + ay * ay + az * az) * (bx * bx + by * by + bz * bz))
            if den > 0 and (ax * bx + ay * by + az * bz) / den > min_sep_cos:
                break
            r_new = (ux * ux + uy * uy + uz * uz) / (2.0 * proj)
            if r_new >= r:
                break
            r = r_new
            if r <= 1e-9:
                break
        radius[i] = r
    return radius, empty


@njit(cache=True)
def cover_max(centres, radii, pad, points, origin, h, dims, start, items, out):
    """For each ball (centres (B, 3), radii (B,)), raise ``out[v]`` to the ball's diameter for
    every point v within radius + pad of its centre (Hildebrand & Rüegsegger 1997 local
    thickness: the largest inscribed ball containing the point). ``items`` index ``points``."""
    for b in range(centres.shape[0]):
        r = radii[b]
        reach = r + pad
        lo = np.empty(3, np.int64)
        hi = np.empty(3, np.int64)
        for a in range(3):
            lo[a] = max(int(np.floor((centres[b, a] - reach - origin[a]) / h)), 0)
            hi[a] = min(int(np.floor((centres[b, a] + reach - origin[a]) / h)), dims[a] - 1)
        for i in range(lo[0], hi[0] + 1):
            for j in range(lo[1], hi[1] + 1):
                for k in range(lo[2], hi[2] + 1):
                    c = (i * dims[1] + j) * dims[2] + k
                    for s in range(start[c], start[c + 1]):
                        v = items[s]
                        d2 = ((points[v, 0] - centres[b, 0]) ** 2 + (points[v, 1] - centres[b, 1]) ** 2
                              + (points[v, 2] - centres[b, 2]) ** 2)
                        if d2 <= reach * reach and 2.0 * r > out[v]:
                            out[v] = 2.0 * r
