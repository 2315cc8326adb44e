"""Numba kernels behind :func:`anatomesh.core.geometry.topology.topology` (private).

Linear-time passes over a triangle mesh: per-face measures (area, enclosed volume, degenerate
faces), per-vertex edge and fan counts from the vertex → faces CSR, and connected components by
union-find, without sorting all 3M half-edges (``np.unique``/``argsort``), which is slow on
large meshes. Faces must not repeat a vertex (the caller checks with
:func:`face_measures` first).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from .kernels import find_root, other_corners, union, union_faces


@njit(cache=True, nogil=True)
def face_measures(vertices, faces, min_area):
    """``(area, volume, degenerate, repeated)`` of a triangle mesh.

    area : float64, total area (mm²); volume : float64, enclosed signed volume by the divergence
    theorem (mm³, positive for outward faces), vertices centred on the first face's first corner
    so large patient coordinates lose no precision; degenerate : faces with a repeated vertex
    index or area <= ``min_area``; repeated : faces with a repeated vertex index.
    """
    m = faces.shape[0]
    area = 0.0
    volume = 0.0
    degenerate = 0
    repeated = 0
    if m == 0:
        return area, volume, degenerate, repeated
    c = faces[0, 0]
    cx, cy, cz = np.float64(vertices[c, 0]), np.float64(vertices[c, 1]), np.float64(vertices[c, 2])
    for f in range(m):
        a, b, d = faces[f, 0], faces[f, 1], faces[f, 2]
        ax, ay, az = vertices[a, 0] - cx, vertices[a, 1] - cy, vertices[a, 2] - cz
        bx, by, bz = vertices[b, 0] - cx, vertices[b, 1] - cy, vertices[b, 2] - cz
        dx, dy, dz = vertices[d, 0] - cx, vertices[d, 1] - cy, vertices[d, 2] - cz
        ux, uy, uz = bx - ax, by - ay, bz - az
        wx, wy, wz = dx - ax, dy - ay, dz - az
        nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
        fa = 0.5 * np.sqrt(nx * nx + ny * ny + nz * nz)
        area += fa
        volume += ax * (by * dz - bz * dy) + ay * (bz * dx - bx * dz) + az * (bx * dy - by * dx)
        rep = a == b or b == d or a == d
        repeated += rep
        degenerate += rep or fa <= min_area
    return area, volume / 6.0, degenerate, repeated


@njit(parallel=True, cache=True, nogil=True)
def vertex_topology(faces, vf_offsets, vf):
    """Edge and fan counts, one vertex at a time (:func:`_vertex_counts`), in 16 parts of the
    vertices (parallel, each with its own scratch arrays and counts, summed at the end).

    Returns ``(edges, boundary, nonmanifold_edges, unoriented, pinch_vertices, used_vertices)``:
    undirected edges; edges with one face; with more than two; two-face edges not used once in
    each direction; vertices whose faces form more than one fan; vertices with a face.
    """
    n = vf_offsets.shape[0] - 1
    most = 0
    for i in range(n):
        most = max(most, vf_offsets[i + 1] - vf_offsets[i])
    parts = 16
    counts = np.zeros((parts, 6), np.int64)
    for p in prange(parts):
        spoke = np.empty(2 * most, np.int64)
        sign = np.empty(2 * most, np.int64)
        order = np.empty(2 * most, np.int64)
        parent = np.empty(most, np.int64)
        for i in range(p * n // parts, (p + 1) * n // parts):
            _vertex_counts(i, faces, vf_offsets, vf, spoke, sign, order, parent, counts[p])
    total = counts.sum(axis=0)
    return total[0], total[1], total[2], total[3], total[4], total[5]


@njit(cache=True)
def _vertex_counts(i, faces, vf_offsets, vf, spoke, sign, order, parent, out):
    """Add vertex i's counts to ``out`` (6,): edges (each counted at its smaller endpoint),
    boundary, non-manifold and unoriented edges, pinch, used.

    Around vertex i each incident face (i, j, k) gives two spokes: j (edge i→j, sign +1) and k
    (edge k→i, sign -1). Equal spokes are the faces sharing that edge. Faces sharing an edge at
    i are linked into fans."""
    lo, k = vf_offsets[i], vf_offsets[i + 1] - vf_offsets[i]
    if k == 0:
        return
    out[5] += 1
    for p in range(k):
        parent[p] = p
        j, l = other_corners(faces, vf[lo + p], i)
        spoke[2 * p], sign[2 * p] = j, 1
        spoke[2 * p + 1], sign[2 * p + 1] = l, -1
    _sort_order(spoke, 2 * k, order)
    fans = k
    t = 0
    while t < 2 * k:
        w = spoke[order[t]]
        u = t
        balance = 0
        while u < 2 * k and spoke[order[u]] == w:
            balance += sign[order[u]]
            if u > t:
                fans -= union(parent, order[u] // 2, order[t] // 2)
            u += 1
        if w > i:
            count = u - t
            out[0] += 1
            out[1] += count == 1
            out[2] += count > 2
            out[3] += count == 2 and balance != 0
        t = u
    out[4] += fans > 1


@njit(cache=True, nogil=True)
def face_components(faces, n_vertices):
    """Components of faces linked through shared vertices: ``(count, labels (M,) int64)``,
    numbered in the order of each component's smallest vertex index."""
    parent = union_faces(faces, n_vertices)
    label = np.full(n_vertices, -1, np.int64)
    for f in range(faces.shape[0]):
        label[find_root(parent, faces[f, 0])] = 0
    count = 0
    for v in range(n_vertices):  # roots are the smallest vertex of their component
        if label[v] == 0:
            label[v] = count + 1
            count += 1
    out = np.empty(faces.shape[0], np.int64)
    for f in range(faces.shape[0]):
        out[f] = label[parent[faces[f, 0]]] - 1
    return count, out


@njit(cache=True)
def _sort_order(keys, m, order):
    """``order[:m]`` sorts ``keys[:m]``: Shell sort (gaps 1, 4, 13, ...), insertion sort for the
    usual handful of spokes. Written out because ``np.argsort`` alone adds much to the
    first-run compilation of this kernel."""
    for t in range(m):
        order[t] = t
    gap = 1
    while gap < m // 3:
        gap = 3 * gap + 1
    while gap > 0:
        for t in range(gap, m):
            x = order[t]
            u = t
            while u >= gap and keys[order[u - gap]] > keys[x]:
                order[u] = order[u - gap]
                u -= gap
            order[u] = x
        gap //= 3


@njit(cache=True, nogil=True)
def weld_positions(bits, ids):
    """Number the distinct rows of ``bits`` (N, 3) uint32 (the float32 bit patterns of vertex
    positions, -0.0 already made 0.0) in order of first appearance into ``ids`` (N,) int64, with
    a hash table of linear probing; returns how many are distinct."""
    n = bits.shape[0]
    size = 1
    while size < 2 * n:
        size *= 2
    table = np.full(size, -1, np.int64)
    distinct = 0
    for i in range(n):
        h = np.uint64(bits[i, 0]) * np.uint64(0x9E3779B97F4A7C15)
        h ^= np.uint64(bits[i, 1]) * np.uint64(0xC2B2AE3D27D4EB4F)
        h ^= np.uint64(bits[i, 2]) * np.uint64(0x165667B19E3779F9)
        slot = np.int64((h ^ (h >> np.uint64(29))) & np.uint64(size - 1))
        while True:
            j = table[slot]
            if j < 0:
                table[slot] = i
                ids[i] = distinct
                distinct += 1
                break
            if bits[j, 0] == bits[i, 0] and bits[j, 1] == bits[i, 1] and bits[j, 2] == bits[i, 2]:
                ids[i] = ids[j]
                break
            slot = (slot + 1) & (size - 1)
    return distinct


@njit(cache=True)
def component_sums(pos, faces, labels, n, volumes, areas):
    """Per component (``labels`` (M,) of the faces, ``n`` components): the signed volume (n,)
    (divergence theorem, about the first corner of the component's first face, so large
    coordinates lose no precision) and the area (n,), into ``volumes`` and ``areas`` (float64,
    zeroed here). One pass over the faces."""
    ref = np.full(n, -1, np.int64)
    volumes[:] = 0.0
    areas[:] = 0.0
    for f in range(faces.shape[0]):
        c = labels[f]
        if ref[c] < 0:
            ref[c] = faces[f, 0]
        r = ref[c]
        ax, ay, az = pos[faces[f, 0], 0] - pos[r, 0], pos[faces[f, 0], 1] - pos[r, 1], pos[faces[f, 0], 2] - pos[r, 2]
        bx, by, bz = pos[faces[f, 1], 0] - pos[r, 0], pos[faces[f, 1], 1] - pos[r, 1], pos[faces[f, 1], 2] - pos[r, 2]
        cx, cy, cz = pos[faces[f, 2], 0] - pos[r, 0], pos[faces[f, 2], 1] - pos[r, 1], pos[faces[f, 2], 2] - pos[r, 2]
        volumes[c] += (ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)) / 6.0
        ux, uy, uz = bx - ax, by - ay, bz - az
        vx, vy, vz = cx - ax, cy - ay, cz - az
        nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        areas[c] += 0.5 * np.sqrt(nx * nx + ny * ny + nz * nz)
