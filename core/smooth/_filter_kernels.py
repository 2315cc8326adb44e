"""Numba kernels of the smoothing filters (private to ``core/smooth``: no input checks here).

Conventions shared by every kernel
----------------------------------
* positions are float64 (N, 3) in mm; a pass reads ``src`` and writes ``dst`` (Jacobi update,
  Mönch et al. 2012, "Interactive mesh smoothing for medical applications"), so every vertex
  sees its neighbours' positions of the previous pass;
* neighbourhoods are CSR ``(offsets (N+1,) int64, nbr (R,) int32)``;
* ``gain`` (N,) scales each vertex's displacement (distance-aware damping); empty = 1 everywhere;
* ``axis`` (3, 3) maps a displacement before it is applied (``use_axis``), e.g. a projector onto
  the slice axis for staircase smoothing;
* the constraint, applied by :func:`constrain_all` after every pass: ``kind`` 0 none, 1 box, 2
  diamond (L1 ball); the box or diamond is centred on ``center[i]`` and expressed in a
  normalised linear frame: ``u = frame @ (p − c)`` must satisfy ``max |u_k| <= 1`` (box) or
  ``sum |u_k| <= 1`` (diamond); a point outside is moved to the nearest point of the set in u
  coordinates and mapped back with ``frame_inv``. Then, when ``radius`` is finite,
  ``|p − start[i]| <= radius`` is enforced by pulling the point straight towards ``start[i]``
  (both sets are convex and contain their centre, so the result satisfies both when
  ``center == start``).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..geometry.kernels import lower_bound, other_corners, triangle_cross

#: fast-math without "no NaN / no Inf" assumptions (an infinite radius means "no cap")
FAST = {"nsz", "arcp", "contract", "afn", "reassoc"}

WEIGHT_UNIFORM = 0
WEIGHT_INVERSE_LENGTH = 1
WEIGHT_GIVEN = 2


@njit(cache=True, inline="always")
def project_l1(w0, w1, w2):
    """Euclidean projection of (w0, w1, w2) onto the unit L1 ball (Duchi et al. 2008)."""
    a0, a1, a2 = abs(w0), abs(w1), abs(w2)
    if a0 + a1 + a2 <= 1.0:
        return w0, w1, w2
    # sort magnitudes descending
    s0, s1, s2 = a0, a1, a2
    if s0 < s1:
        s0, s1 = s1, s0
    if s1 < s2:
        s1, s2 = s2, s1
    if s0 < s1:
        s0, s1 = s1, s0
    theta = s0 - 1.0
    if s1 > (s0 + s1 - 1.0) / 2.0:
        theta = (s0 + s1 - 1.0) / 2.0
        if s2 > (s0 + s1 + s2 - 1.0) / 3.0:
            theta = (s0 + s1 + s2 - 1.0) / 3.0
    r0 = max(a0 - theta, 0.0)
    r1 = max(a1 - theta, 0.0)
    r2 = max(a2 - theta, 0.0)
    return math.copysign(r0, w0), math.copysign(r1, w1), math.copysign(r2, w2)


@njit(cache=True, inline="always")
def constrain_one(i, px, py, pz, kind, center, frame, frame_inv, radius, start):
    if kind != 0:
        cx, cy, cz = center[i, 0], center[i, 1], center[i, 2]
        dx, dy, dz = px - cx, py - cy, pz - cz
        u0 = frame[0, 0] * dx + frame[0, 1] * dy + frame[0, 2] * dz
        u1 = frame[1, 0] * dx + frame[1, 1] * dy + frame[1, 2] * dz
        u2 = frame[2, 0] * dx + frame[2, 1] * dy + frame[2, 2] * dz
        inside = True
        if kind == 1:
            if u0 > 1.0 or u0 < -1.0 or u1 > 1.0 or u1 < -1.0 or u2 > 1.0 or u2 < -1.0:
                inside = False
                u0 = min(1.0, max(-1.0, u0))
                u1 = min(1.0, max(-1.0, u1))
                u2 = min(1.0, max(-1.0, u2))
        elif abs(u0) + abs(u1) + abs(u2) > 1.0:
            inside = False
            u0, u1, u2 = project_l1(u0, u1, u2)
        if not inside:
            px = cx + frame_inv[0, 0] * u0 + frame_inv[0, 1] * u1 + frame_inv[0, 2] * u2
            py = cy + frame_inv[1, 0] * u0 + frame_inv[1, 1] * u1 + frame_inv[1, 2] * u2
            pz = cz + frame_inv[2, 0] * u0 + frame_inv[2, 1] * u1 + frame_inv[2, 2] * u2
    if radius < np.inf:
        sx, sy, sz = start[i, 0], start[i, 1], start[i, 2]
        dx, dy, dz = px - sx, py - sy, pz - sz
        d2 = dx * dx + dy * dy + dz * dz
        if d2 > radius * radius:
            s = radius / math.sqrt(d2)
            px, py, pz = sx + dx * s, sy + dy * s, sz + dz * s
    return px, py, pz


@njit(parallel=True, fastmath=FAST, cache=True)
def constrain_all(pos, kind, center, frame, frame_inv, radius, start):
    """Apply the constraint to every vertex in place (after every smoothing pass)."""
    for i in prange(pos.shape[0]):
        px, py, pz = constrain_one(i, pos[i, 0], pos[i, 1], pos[i, 2], kind, center, frame,
                                frame_inv, radius, start)
        pos[i, 0] = px
        pos[i, 1] = py
        pos[i, 2] = pz


@njit(parallel=True, cache=True)
def lattice_centres(lattice, affine, out):
    """``out[i]`` (N, 3) float64 mm: ``affine`` (4, 4) applied to ``lattice[i] − 0.5`` (the
    centre of the voxel cell of lattice corner i), summed in the order ``x, y, z, translation``
    (the bits of ``(lattice − 0.5) @ A.T + t``), in one pass without (N, 3) temporaries."""
    for i in prange(lattice.shape[0]):
        x, y, z = lattice[i, 0] - 0.5, lattice[i, 1] - 0.5, lattice[i, 2] - 0.5
        for r in range(3):
            out[i, r] = affine[r, 0] * x + affine[r, 1] * y + affine[r, 2] * z + affine[r, 3]


@njit(parallel=True, fastmath=FAST, cache=True)
def umbrella_pass(src, dst, offsets, nbr, weights, mode, factor, gain, axis, use_axis):
    """One Laplacian (umbrella) pass: ``dst_i = src_i + factor * Σ w_ij (src_j − src_i) / Σ w_ij``.

    ``mode`` picks the weights: 0 uniform, 1 inverse edge length (Fujiwara
    1995), 2 ``weights`` per CSR entry (e.g. cotangents, Desbrun et al. 1999).
    A vertex with an empty ring, or whose weights sum to <= 0, does not move.
    """
    n = src.shape[0]
    has_gain = gain.shape[0] > 0
    for i in prange(n):
        x, y, z = src[i, 0], src[i, 1], src[i, 2]
        a0, a1 = offsets[i], offsets[i + 1]
        sx = 0.0
        sy = 0.0
        sz = 0.0
        sw = 0.0
        if mode == 0:
            for a in range(a0, a1):
                j = nbr[a]
                sx += src[j, 0]
                sy += src[j, 1]
                sz += src[j, 2]
            sw = a1 - a0
            sx -= sw * x
            sy -= sw * y
            sz -= sw * z
        elif mode == 1:
            for a in range(a0, a1):
                j = nbr[a]
                dx = src[j, 0] - x
                dy = src[j, 1] - y
                dz = src[j, 2] - z
                ln = math.sqrt(dx * dx + dy * dy + dz * dz)
                w = 1.0 / ln if ln > 1e-12 else 0.0
                sx += w * dx
                sy += w * dy
                sz += w * dz
                sw += w
        else:
            for a in range(a0, a1):
                j = nbr[a]
                w = weights[a]
                sx += w * (src[j, 0] - x)
                sy += w * (src[j, 1] - y)
                sz += w * (src[j, 2] - z)
                sw += w
        if sw <= 0.0:
            dst[i, 0] = x
            dst[i, 1] = y
            dst[i, 2] = z
            continue
        f = factor / sw
        if has_gain:
            f *= gain[i]
        dx, dy, dz = f * sx, f * sy, f * sz
        if use_axis:
            ex = axis[0, 0] * dx + axis[0, 1] * dy + axis[0, 2] * dz
            ey = axis[1, 0] * dx + axis[1, 1] * dy + axis[1, 2] * dz
            ez = axis[2, 0] * dx + axis[2, 1] * dy + axis[2, 2] * dz
            dx, dy, dz = ex, ey, ez
        dst[i, 0] = x + dx
        dst[i, 1] = y + dy
        dst[i, 2] = z + dz


@njit(parallel=True, fastmath=FAST, cache=True)
def hc_pass_a(q, orig, p, b, offsets, nbr, lam, alpha):
    """HC step 1 (Vollmer et al. 1999): Laplacian ``p = q + lam (mean(q_j) − q)`` and the
    difference ``b = p − (alpha o + (1 − alpha) q)`` to the original/previous positions."""
    for i in prange(q.shape[0]):
        s0, s1 = offsets[i], offsets[i + 1]
        x, y, z = q[i, 0], q[i, 1], q[i, 2]
        px, py, pz = x, y, z
        if s1 > s0:
            sx = 0.0
            sy = 0.0
            sz = 0.0
            for a in range(s0, s1):
                j = nbr[a]
                sx += q[j, 0]
                sy += q[j, 1]
                sz += q[j, 2]
            k = 1.0 / (s1 - s0)
            px = x + lam * (sx * k - x)
            py = y + lam * (sy * k - y)
            pz = z + lam * (sz * k - z)
        p[i, 0] = px
        p[i, 1] = py
        p[i, 2] = pz
        b[i, 0] = px - (alpha * orig[i, 0] + (1.0 - alpha) * x)
        b[i, 1] = py - (alpha * orig[i, 1] + (1.0 - alpha) * y)
        b[i, 2] = pz - (alpha * orig[i, 2] + (1.0 - alpha) * z)


@njit(parallel=True, fastmath=FAST, cache=True)
def hc_pass_b(q, p, b, dst, offsets, nbr, beta, gain):
    """HC step 2: push back ``p − (beta b_i + (1 − beta) mean(b_j))``; then the gain."""
    has_gain = gain.shape[0] > 0
    for i in prange(q.shape[0]):
        s0, s1 = offsets[i], offsets[i + 1]
        if s1 == s0:
            dst[i, 0] = q[i, 0]
            dst[i, 1] = q[i, 1]
            dst[i, 2] = q[i, 2]
            continue
        sx = 0.0
        sy = 0.0
        sz = 0.0
        for a in range(s0, s1):
            j = nbr[a]
            sx += b[j, 0]
            sy += b[j, 1]
            sz += b[j, 2]
        k = (1.0 - beta) / (s1 - s0)
        vx = p[i, 0] - (beta * b[i, 0] + k * sx)
        vy = p[i, 1] - (beta * b[i, 1] + k * sy)
        vz = p[i, 2] - (beta * b[i, 2] + k * sz)
        if has_gain:
            g = gain[i]
            vx = q[i, 0] + g * (vx - q[i, 0])
            vy = q[i, 1] + g * (vy - q[i, 1])
            vz = q[i, 2] + g * (vz - q[i, 2])
        dst[i, 0] = vx
        dst[i, 1] = vy
        dst[i, 2] = vz


@njit(cache=True)
def _cot(ax, ay, az, bx, by, bz):
    """Cotangent of the angle between vectors a and b."""
    dot = ax * bx + ay * by + az * bz
    cx = ay * bz - az * by
    cy = az * bx - ax * bz
    cz = ax * by - ay * bx
    cr = math.sqrt(cx * cx + cy * cy + cz * cz)
    return dot / max(cr, 1e-12)


@njit(parallel=True, fastmath=FAST, cache=True)
def cotan_weights(pos, faces, offsets, nbr, vf_offsets, vf, out):
    """Cotangent weights per 1-ring entry: ``w_ij = (cot α_ij + cot β_ij) / 2``, clipped at 0.

    α, β are the angles opposite edge (i, j) in its two faces (Pinkall & Polthier 1993;
    Desbrun et al. 1999). Negative weights (obtuse opposite angles) are clipped to 0 so the
    explicit step stays a convex combination (stable for factors in (0, 1]).
    """
    for i in prange(offsets.shape[0] - 1):
        s0, s1 = offsets[i], offsets[i + 1]
        for a in range(s0, s1):
            out[a] = 0.0
        for t in range(vf_offsets[i], vf_offsets[i + 1]):
            f = vf[t]
            j, k = other_corners(faces, f, i)  # the face reads (i, j, k)
            # angle at k, opposite edge (i, j)
            ck = _cot(pos[i, 0] - pos[k, 0], pos[i, 1] - pos[k, 1], pos[i, 2] - pos[k, 2],
                      pos[j, 0] - pos[k, 0], pos[j, 1] - pos[k, 1], pos[j, 2] - pos[k, 2])
            # angle at j, opposite edge (i, k)
            cj = _cot(pos[i, 0] - pos[j, 0], pos[i, 1] - pos[j, 1], pos[i, 2] - pos[j, 2],
                      pos[k, 0] - pos[j, 0], pos[k, 1] - pos[j, 1], pos[k, 2] - pos[j, 2])
            for a in range(s0, s1):
                if nbr[a] == j:
                    out[a] += 0.5 * ck
                elif nbr[a] == k:
                    out[a] += 0.5 * cj
        for a in range(s0, s1):
            if out[a] < 0.0:
                out[a] = 0.0


@njit(parallel=True, fastmath=FAST, cache=True)
def face_normals_areas(pos, faces, normals, areas, centroids):
    """Unit normal, area (mm²) and centroid of each face; a zero-area face gets normal 0."""
    for f in prange(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        nx, ny, nz = triangle_cross(pos, a, b, c)
        ln = math.sqrt(nx * nx + ny * ny + nz * nz)
        areas[f] = 0.5 * ln
        if ln > 0.0:
            normals[f, 0] = nx / ln
            normals[f, 1] = ny / ln
            normals[f, 2] = nz / ln
        else:
            normals[f, 0] = 0.0
            normals[f, 1] = 0.0
            normals[f, 2] = 0.0
        for c3 in range(3):
            centroids[f, c3] = (pos[a, c3] + pos[b, c3] + pos[c, c3]) / 3.0


@njit(parallel=True, fastmath=FAST, cache=True)
def mean_filter_normals(normals, areas, fr_offsets, fr, out):
    """Yagou et al. 2002 mean filter: area-weighted mean of the normals of the faces sharing a
    vertex with each face, normalised (a zero mean keeps the face's own normal)."""
    for f in prange(normals.shape[0]):
        mx = 0.0
        my = 0.0
        mz = 0.0
        for a in range(fr_offsets[f], fr_offsets[f + 1]):
            g = fr[a]
            mx += areas[g] * normals[g, 0]
            my += areas[g] * normals[g, 1]
            mz += areas[g] * normals[g, 2]
        ln = math.sqrt(mx * mx + my * my + mz * mz)
        if ln > 0.0:
            out[f, 0] = mx / ln
            out[f, 1] = my / ln
            out[f, 2] = mz / ln
        else:
            out[f, 0] = normals[f, 0]
            out[f, 1] = normals[f, 1]
            out[f, 2] = normals[f, 2]


@njit(parallel=True, fastmath=FAST, cache=True)
def median_filter_normals(normals, fr_offsets, fr, out):
    """Yagou et al. 2002 median filter: among the normals of the faces sharing a vertex with
    each face, the one whose summed angle to all the others is smallest (first on ties)."""
    for f in prange(normals.shape[0]):
        s0, s1 = fr_offsets[f], fr_offsets[f + 1]
        best = np.inf
        bg = -1
        for a in range(s0, s1):
            g = fr[a]
            tot = 0.0
            for b in range(s0, s1):
                h = fr[b]
                d = (normals[g, 0] * normals[h, 0] + normals[g, 1] * normals[h, 1]
                     + normals[g, 2] * normals[h, 2])
                tot += math.acos(min(1.0, max(-1.0, d)))
            if tot < best - 1e-12:
                best = tot
                bg = g
        if bg < 0:
            bg = fr[s0] if s1 > s0 else 0
        out[f, 0] = normals[bg, 0]
        out[f, 1] = normals[bg, 1]
        out[f, 2] = normals[bg, 2]


@njit(parallel=True, fastmath=FAST, cache=True)
def normal_vertex_update(src, dst, vf_offsets, vf, fnormals, areas, centroids, factor, gain,
                         movable):
    """Move each vertex towards the planes of its faces with the filtered normals:
    ``p' = p + factor * Σ A_f m_f (m_f · (c_f − p)) / Σ A_f`` (Yagou et al. 2002; Taubin 2001).
    Vertices with ``movable[i] == 0`` stay."""
    has_gain = gain.shape[0] > 0
    for i in prange(src.shape[0]):
        x, y, z = src[i, 0], src[i, 1], src[i, 2]
        if movable[i] == 0:
            dst[i, 0] = x
            dst[i, 1] = y
            dst[i, 2] = z
            continue
        sx = 0.0
        sy = 0.0
        sz = 0.0
        sa = 0.0
        for t in range(vf_offsets[i], vf_offsets[i + 1]):
            f = vf[t]
            mx, my, mz = fnormals[f, 0], fnormals[f, 1], fnormals[f, 2]
            d = (mx * (centroids[f, 0] - x) + my * (centroids[f, 1] - y)
                 + mz * (centroids[f, 2] - z))
            sx += areas[f] * mx * d
            sy += areas[f] * my * d
            sz += areas[f] * mz * d
            sa += areas[f]
        if sa <= 0.0:
            dst[i, 0] = x
            dst[i, 1] = y
            dst[i, 2] = z
            continue
        k = factor / sa
        if has_gain:
            k *= gain[i]
        dst[i, 0] = x + k * sx
        dst[i, 1] = y + k * sy
        dst[i, 2] = z + k * sz


# ---------------------------------------------------------------------------------------------
# distance to other structures (Mönch et al. 2010a): a uniform grid hash
# ---------------------------------------------------------------------------------------------
@njit(parallel=True, cache=True)
def nearest_other_group(points, groups, cell, origin, dims, sorted_keys, order):
    """Distance (mm) from each point to the nearest point of another group, capped at ``cell``.

    Points are hashed into cubic cells of edge ``cell`` (key ``(ix·dims1 + iy)·dims2 + iz`` from
    ``origin``; ``sorted_keys``/``order`` = the keys sorted and the argsort); a point only looks
    at its 27 surrounding cells, which hold every point within ``cell`` of it. Points with
    group < 0 are neither searched nor found (result ``cell``).
    """
    n = points.shape[0]
    out = np.full(n, cell)
    for i in prange(n):
        gi = groups[i]
        if gi < 0:
            continue
        ix = int((points[i, 0] - origin[0]) / cell)
        iy = int((points[i, 1] - origin[1]) / cell)
        iz = int((points[i, 2] - origin[2]) / cell)
        best2 = cell * cell
        for ddx in range(-1, 2):
            for ddy in range(-1, 2):
                for ddz in range(-1, 2):
                    key = ((ix + ddx) * dims[1] + (iy + ddy)) * dims[2] + (iz + ddz)
                    a = lower_bound(sorted_keys, key)
                    while a < n and sorted_keys[a] == key:
                        j = order[a]
                        a += 1
                        gj = groups[j]
                        if gj < 0 or gj == gi:
                            continue
                        dx = points[j, 0] - points[i, 0]
                        dy = points[j, 1] - points[i, 1]
                        dz = points[j, 2] - points[i, 2]
                        d2 = dx * dx + dy * dy + dz * dz
                        if d2 < best2:
                            best2 = d2
        out[i] = math.sqrt(best2)
    return out
