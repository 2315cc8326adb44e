"""Numba kernels of :mod:`anatomesh.core.smooth.shell_measures` (private to ``core/smooth``):
per-face measures of a surface set and their sums per label."""
from __future__ import annotations

import math

import numpy as np
from numba import get_thread_id, njit, prange

from ..geometry.kernels import triangle_cross, union


@njit(cache=True, inline="always")
def _angle(ax, ay, az, bx, by, bz):
    cx = ay * bz - az * by
    cy = az * bx - ax * bz
    cz = ax * by - ay * bx
    return math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), ax * bx + ay * by + az * bz)


@njit(parallel=True, cache=True)
def face_measures(pos, faces, origin, rest, table, angles):
    """Per face f at ``pos`` (N, 3) float64, into column f of ``table`` (7, ≥ M) float64: area
    (mm²), signed volume of the tetrahedron (origin, face) (mm³), turned over against its
    normal at ``rest`` (N, 3) (n · n_rest < 0: 1, else 0), degenerate (a repeated corner or zero
    area: 1), the smallest interior angle (degrees; 0 unless ``angles``), that angle below 10°
    (1), and 1 (the face count)."""
    for f in prange(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        e1x, e1y, e1z = pos[b, 0] - pos[a, 0], pos[b, 1] - pos[a, 1], pos[b, 2] - pos[a, 2]
        e2x, e2y, e2z = pos[c, 0] - pos[a, 0], pos[c, 1] - pos[a, 1], pos[c, 2] - pos[a, 2]
        nx = e1y * e2z - e1z * e2y
        ny = e1z * e2x - e1x * e2z
        nz = e1x * e2y - e1y * e2x
        area = 0.5 * math.sqrt(nx * nx + ny * ny + nz * nz)
        table[0, f] = area
        table[1, f] = (nx * (pos[a, 0] - origin[0]) + ny * (pos[a, 1] - origin[1])
                       + nz * (pos[a, 2] - origin[2])) / 6.0
        rx, ry, rz = triangle_cross(rest, a, b, c)  # memory: computed, not an (M, 3) array
        table[2, f] = 1.0 if nx * rx + ny * ry + nz * rz < 0.0 else 0.0
        table[3, f] = 1.0 if a == b or b == c or a == c or area <= 0.0 else 0.0
        table[6, f] = 1.0
        t = 0.0
        if angles:
            t = math.degrees(_smallest_angle(e1x, e1y, e1z, e2x, e2y, e2z, pos[c, 0] - pos[b, 0],
                                             pos[c, 1] - pos[b, 1], pos[c, 2] - pos[b, 2]))
        table[4, f] = t
        table[5, f] = 1.0 if t < 10.0 else 0.0


@njit(cache=True, inline="always")
def _smallest_angle(e1x, e1y, e1z, e2x, e2y, e2z, e3x, e3y, e3z):
    """The smallest interior angle (radians) of the triangle with edges ab = e1, ac = e2,
    bc = e3: the one facing the shortest edge."""
    l1 = e1x * e1x + e1y * e1y + e1z * e1z
    l2 = e2x * e2x + e2y * e2y + e2z * e2z
    l3 = e3x * e3x + e3y * e3y + e3z * e3z
    if l3 <= l1 and l3 <= l2:  # edge bc: the angle at a
        return _angle(e1x, e1y, e1z, e2x, e2y, e2z)
    if l2 <= l1:  # edge ca: the angle at b
        return _angle(-e1x, -e1y, -e1z, e3x, e3y, e3z)
    return _angle(-e2x, -e2y, -e2z, -e3x, -e3y, -e3z)  # edge ab: the angle at c


@njit(cache=True)
def label_sums(sides, table, signed, out):
    """``out[k, j]`` += ``table[j, f]`` for each side of face f (in order) with label index
    ``k = sides[f, side] >= 0``, negated on the outside when ``signed[j]``."""
    for f in range(sides.shape[0]):
        for side in range(2):
            k = sides[f, side]
            if k < 0:
                continue
            for j in range(table.shape[0]):
                x = table[j, f]
                out[k, j] += -x if (signed[j] and side == 1) else x


@njit(cache=True)
def label_max_displacement(sides, faces, after, rest, out):
    """``out[k]``: the largest displacement (mm) from ``rest`` to ``after`` (N, 3) float64 of a
    corner of the faces with label index k on a side (memory: no (N,) table)."""
    out[:] = 0.0
    for f in range(sides.shape[0]):
        x = max(_moved(after, rest, faces[f, 0]),
                max(_moved(after, rest, faces[f, 1]), _moved(after, rest, faces[f, 2])))
        for side in range(2):
            k = sides[f, side]
            if k >= 0 and x > out[k]:
                out[k] = x


@njit(cache=True, inline="always")
def _moved(after, rest, i):
    dx, dy, dz = after[i, 0] - rest[i, 0], after[i, 1] - rest[i, 1], after[i, 2] - rest[i, 2]
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True)
def faces_by_label(sides, labels):
    """The faces with each label index on a side, in face order (a counting sort):
    ``(faces (K,) int32, starts (labels + 1,) int64)``, label k's from ``starts[k]``."""
    starts = np.zeros(labels + 1, np.int64)
    for f in range(sides.shape[0]):
        for side in range(2):
            if sides[f, side] >= 0:
                starts[sides[f, side] + 1] += 1
    for k in range(labels):
        starts[k + 1] += starts[k]
    fill = starts[:-1].copy()
    faces = np.empty(starts[labels], np.int32)
    for f in range(sides.shape[0]):
        for side in range(2):
            k = sides[f, side]
            if k >= 0:
                faces[fill[k]] = f
                fill[k] += 1
    return faces, starts


@njit(cache=True)
def _around(faces, vf_offsets, vf, a, spoke, sign, parent):
    """Edges and fans at vertex a: ``(edges (a, b > a), one face, > 2 faces, 2 faces used in
    one direction, fans)``. Each face gives two spokes, its corner after a (+1, edge a → b) and
    before a (−1); faces sharing a spoke are in one fan."""
    k = vf_offsets[a + 1] - vf_offsets[a]
    for p in range(k):
        f = vf[vf_offsets[a] + p]
        c = 0 if faces[f, 0] == a else (1 if faces[f, 1] == a else 2)
        spoke[2 * p], sign[2 * p] = faces[f, (c + 1) % 3], 1
        spoke[2 * p + 1], sign[2 * p + 1] = faces[f, (c + 2) % 3], -1
        parent[p] = p
    edges, one, many, same, fans = 0, 0, 0, 0, k
    for t in range(2 * k):
        b = spoke[t]
        first = True
        count, balance = 0, 0
        for u in range(2 * k):
            if spoke[u] == b:
                count += 1
                balance += sign[u]
                if u < t:
                    first = False
                elif u > t:  # link the faces of t and u
                    fans -= union(parent, t // 2, u // 2)
        if first and b > a:
            edges += 1
            if count == 1:
                one += 1
            elif count > 2:
                many += 1
            elif balance != 0:
                same += 1
    return edges, one, many, same, fans


@njit(parallel=True, cache=True)
def vertex_stats(faces, vf_offsets, vf, out, scratch):
    """Per vertex: ``out[a] = (edges (a, b > a), boundary edges, non-manifold edges, edges two
    faces use in one direction, fans)`` of :func:`_around`; ``scratch`` (threads, 5 x most
    faces at a vertex) int64."""
    most = scratch.shape[1] // 5
    for a in prange(vf_offsets.shape[0] - 1):
        row = scratch[get_thread_id()]
        out[a, 0], out[a, 1], out[a, 2], out[a, 3], out[a, 4] = _around(
            faces, vf_offsets, vf, a, row[:2 * most], row[2 * most:4 * most], row[4 * most:])
