"""Numba kernels for :mod:`anatomesh.core.measure` (private: no input checks here)."""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ._search_kernels import lower_bound

FAST = {"nsz", "arcp", "contract", "afn", "reassoc"}


# ---------------------------------------------------------------------------------------------
# exact point–triangle distance (Ericson 2004, "Real-Time Collision Detection", §5.1.5)
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _seg_d2(px, py, pz, ax, ay, az, bx, by, bz):
    ux, uy, uz = bx - ax, by - ay, bz - az
    wx, wy, wz = px - ax, py - ay, pz - az
    uu = ux * ux + uy * uy + uz * uz
    t = 0.0
    if uu > 0.0:
        t = min(1.0, max(0.0, (wx * ux + wy * uy + wz * uz) / uu))
    dx, dy, dz = wx - t * ux, wy - t * uy, wz - t * uz
    return dx * dx + dy * dy + dz * dz


@njit(cache=True)
def point_triangle_d2(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Squared distance from point p to triangle abc (Voronoi-region test; degenerate safe)."""
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return apx * apx + apy * apy + apz * apz
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return bpx * bpx + bpy * bpy + bpz * bpz
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return cpx * cpx + cpy * cpy + cpz * cpz
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        return _seg_d2(px, py, pz, ax, ay, az, bx, by, bz)
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        return _seg_d2(px, py, pz, ax, ay, az, cx, cy, cz)
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        return _seg_d2(px, py, pz, bx, by, bz, cx, cy, cz)
    den = va + vb + vc
    if not den > 0.0:  # degenerate triangle: nearest of its edges
        return min(_seg_d2(px, py, pz, ax, ay, az, bx, by, bz),
                   min(_seg_d2(px, py, pz, ax, ay, az, cx, cy, cz),
                       _seg_d2(px, py, pz, bx, by, bz, cx, cy, cz)))
    v = vb / den
    w = vc / den
    qx = ax + abx * v + acx * w
    qy = ay + aby * v + acy * w
    qz = az + abz * v + acz * w
    dx, dy, dz = px - qx, py - qy, pz - qz
    return dx * dx + dy * dy + dz * dz


# ---------------------------------------------------------------------------------------------
# uniform grid of triangles (sparse: sorted cell keys)
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def triangle_cells(v, faces, origin, cell, dims):
    """Every (cell key, triangle) pair for the cells each triangle's bounding box overlaps.

    Returns ``(keys (T,) int64, tris (T,) int32)``, unsorted; key = ``(ix·dims1 + iy)·dims2 + iz``.
    """
    m = faces.shape[0]
    lo = np.empty((m, 3), np.int64)
    hi = np.empty((m, 3), np.int64)
    total = 0
    for f in range(m):
        n = 1
        for c in range(3):
            a = min(v[faces[f, 0], c], min(v[faces[f, 1], c], v[faces[f, 2], c]))
            b = max(v[faces[f, 0], c], max(v[faces[f, 1], c], v[faces[f, 2], c]))
            lo[f, c] = int((a - origin[c]) / cell)
            hi[f, c] = min(int((b - origin[c]) / cell), dims[c] - 1)
            n *= hi[f, c] - lo[f, c] + 1
        total += n
    keys = np.empty(total, np.int64)
    tri = np.empty(total, np.int32)
    w = 0
    for f in range(m):
        for ix in range(lo[f, 0], hi[f, 0] + 1):
            for iy in range(lo[f, 1], hi[f, 1] + 1):
                for iz in range(lo[f, 2], hi[f, 2] + 1):
                    keys[w] = (ix * dims[1] + iy) * dims[2] + iz
                    tri[w] = f
                    w += 1
    return keys, tri


@njit(parallel=True, fastmath=FAST, cache=True)
def points_to_triangles(points, v, faces, origin, cell, dims, ukeys, starts, tris):
    """Exact distance (mm) from each point to the nearest triangle, by ring search in the grid.

    Rings of cells (Chebyshev radius r = 0, 1, ...) around the point's cell are searched until the
    best distance found is no larger than the distance from the point to the outside of the
    searched block of cells, so the answer is exact.
    """
    n = points.shape[0]
    out = np.empty(n)
    rmax = max(dims[0], max(dims[1], dims[2]))
    for i in prange(n):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        fx = (px - origin[0]) / cell
        fy = (py - origin[1]) / cell
        fz = (pz - origin[2]) / cell
        ix, iy, iz = int(math.floor(fx)), int(math.floor(fy)), int(math.floor(fz))
        best = np.inf
        r = 0
        while True:
            for dx in range(-r, r + 1):
                cx = ix + dx
                if cx < 0 or cx >= dims[0]:
                    continue
                for dy in range(-r, r + 1):
                    cy = iy + dy
                    if cy < 0 or cy >= dims[1]:
                        continue
                    for dz in range(-r, r + 1):
                        if max(abs(dx), max(abs(dy), abs(dz))) != r:
                            continue
                        cz = iz + dz
                        if cz < 0 or cz >= dims[2]:
                            continue
                        # skip a cell whose box is no nearer than the best triangle so far
                        gx = max(0.0, max(cx - fx, fx - (cx + 1)))
                        gy = max(0.0, max(cy - fy, fy - (cy + 1)))
                        gz = max(0.0, max(cz - fz, fz - (cz + 1)))
                        if (gx * gx + gy * gy + gz * gz) * cell * cell >= best:
                            continue
                        key = (cx * dims[1] + cy) * dims[2] + cz
                        c = lower_bound(ukeys, key)
                        if c >= ukeys.shape[0] or ukeys[c] != key:
                            continue
                        for a in range(starts[c], starts[c + 1]):
                            f = tris[a]
                            d2 = point_triangle_d2(
                                px, py, pz,
                                v[faces[f, 0], 0], v[faces[f, 0], 1], v[faces[f, 0], 2],
                                v[faces[f, 1], 0], v[faces[f, 1], 1], v[faces[f, 1], 2],
                                v[faces[f, 2], 0], v[faces[f, 2], 1], v[faces[f, 2], 2])
                            if d2 < best:
                                best = d2
            # distance from p to the outside of the searched (2r+1)^3 block
            gx = min(fx - (ix - r), (ix + r + 1) - fx)
            gy = min(fy - (iy - r), (iy + r + 1) - fy)
            gz = min(fz - (iz - r), (iz + r + 1) - fz)
            g = min(gx, min(gy, gz)) * cell
            if best <= g * g or r > rmax + abs(ix) + abs(iy) + abs(iz):
                break
            r += 1
        out[i] = math.sqrt(best)
    return out


# ---------------------------------------------------------------------------------------------
# curvature (Meyer, Desbrun, Schröder & Barr 2003) and triangle angles
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _angle(ax, ay, az, bx, by, bz):
    dot = ax * bx + ay * by + az * bz
    cx = ay * bz - az * by
    cy = az * bx - ax * bz
    cz = ax * by - ay * bx
    return math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), dot)


@njit(cache=True)
def vertex_curvatures(v, faces, vf_offsets, vf, H, K, A):
    """Per vertex: mean curvature H (1/mm, > 0 convex), Gaussian curvature K (1/mm²) and the
    mixed Voronoi area A (mm²) of Meyer et al. 2003.

    ``K_vec = Σ (cot α_ij + cot β_ij)(x_i − x_j) / (2 A)``, ``H = K_vec · n / 2`` with n the
    area-weighted vertex normal; ``K = (2π − Σ θ_j) / A`` (angle deficit).
    """
    n = v.shape[0]
    for i in range(n):
        lx = 0.0
        ly = 0.0
        lz = 0.0
        nx = 0.0
        ny = 0.0
        nz = 0.0
        area = 0.0
        angles = 0.0
        for t in range(vf_offsets[i], vf_offsets[i + 1]):
            f = vf[t]
            if faces[f, 0] == i:
                j, k = faces[f, 1], faces[f, 2]
            elif faces[f, 1] == i:
                j, k = faces[f, 2], faces[f, 0]
            else:
                j, k = faces[f, 0], faces[f, 1]
            eij = (v[j, 0] - v[i, 0], v[j, 1] - v[i, 1], v[j, 2] - v[i, 2])
            eik = (v[k, 0] - v[i, 0], v[k, 1] - v[i, 1], v[k, 2] - v[i, 2])
            ejk = (v[k, 0] - v[j, 0], v[k, 1] - v[j, 1], v[k, 2] - v[j, 2])
            ti = _angle(eij[0], eij[1], eij[2], eik[0], eik[1], eik[2])
            tj = _angle(-eij[0], -eij[1], -eij[2], ejk[0], ejk[1], ejk[2])
            tk = math.pi - ti - tj
            cx = eij[1] * eik[2] - eij[2] * eik[1]
            cy = eij[2] * eik[0] - eij[0] * eik[2]
            cz = eij[0] * eik[1] - eij[1] * eik[0]
            fa = 0.5 * math.sqrt(cx * cx + cy * cy + cz * cz)
            nx += cx
            ny += cy
            nz += cz
            angles += ti
            if fa <= 0.0:
                continue
            cotj = math.cos(tj) / max(math.sin(tj), 1e-12)
            cotk = math.cos(tk) / max(math.sin(tk), 1e-12)
            lij = eij[0] ** 2 + eij[1] ** 2 + eij[2] ** 2
            lik = eik[0] ** 2 + eik[1] ** 2 + eik[2] ** 2
            # (x_i - x_j) weighted by the cotangent of the angle opposite edge ij (at k), etc.
            lx -= cotk * eij[0] + cotj * eik[0]
            ly -= cotk * eij[1] + cotj * eik[1]
            lz -= cotk * eij[2] + cotj * eik[2]
            half_pi = 0.5 * math.pi
            if ti <= half_pi and tj <= half_pi and tk <= half_pi:
                area += (lij * cotk + lik * cotj) / 8.0
            elif ti > half_pi:
                area += fa / 2.0
            else:
                area += fa / 4.0
        A[i] = area
        if area > 0.0:
            ln = math.sqrt(nx * nx + ny * ny + nz * nz)
            hn = 0.0
            if ln > 0.0:
                hn = (lx * nx + ly * ny + lz * nz) / ln
            H[i] = hn / (2.0 * area) / 2.0
            K[i] = (2.0 * math.pi - angles) / area
        else:
            H[i] = 0.0
            K[i] = 0.0


@njit(cache=True)
def triangle_angles(v, faces, out):
    """Interior angles (radians) of each triangle, (M, 3) at its three corners."""
    for f in range(faces.shape[0]):
        for c in range(3):
            a = faces[f, c]
            b = faces[f, (c + 1) % 3]
            d = faces[f, (c + 2) % 3]
            out[f, c] = _angle(v[b, 0] - v[a, 0], v[b, 1] - v[a, 1], v[b, 2] - v[a, 2],
                               v[d, 0] - v[a, 0], v[d, 1] - v[a, 1], v[d, 2] - v[a, 2])
