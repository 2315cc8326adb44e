"""Numba kernels for :mod:`anatomesh.core.geometry.local_distance` (private: no input checks)."""
import math

import numpy as np
from numba import njit, prange

from ._spatial_kernels import closest_on_triangle


@njit(cache=True, inline="always")
def _distance2(px, py, pz, vertices, faces, f):
    """The squared distance (mm²) from (px, py, pz) to face f: a minimum over faces is taken
    on squares and its root drawn once (the root is monotone and correctly rounded, so the
    result is the same as the minimum of the roots)."""
    x, y, z, _ = closest_on_triangle(px, py, pz, vertices, faces[f, 0], faces[f, 1], faces[f, 2])
    return (x - px) ** 2 + (y - py) ** 2 + (z - pz) ** 2


@njit(cache=True, inline="always")
def _distance(px, py, pz, vertices, faces, f):
    return math.sqrt(_distance2(px, py, pz, vertices, faces, f))


@njit(parallel=True, cache=True)
def incident_distances(points, vertices, faces, vf_offsets, vf, out):
    """``out[t]``: distance from ``points[i]`` to face ``vf[t]`` (corners from ``vertices``),
    for every entry t of row i of the vertex → faces CSR."""
    for i in prange(points.shape[0]):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        for t in range(vf_offsets[i], vf_offsets[i + 1]):
            out[t] = _distance(px, py, pz, vertices, faces, vf[t])


@njit(parallel=True, cache=True)
def centroid_distances(points, vertices, faces, near, out):
    """``out[f]``: distance from the centroid of face f with corners from ``points`` to face f
    and the faces ``near[f]`` (entries < 0 skipped) with corners from ``vertices``."""
    for f in prange(faces.shape[0]):
        px, py, pz = _centroid(points, faces, f)
        d = _distance(px, py, pz, vertices, faces, f)
        for k in range(near.shape[1]):
            g = near[f, k]
            if g >= 0:
                d = min(d, _distance(px, py, pz, vertices, faces, g))
        out[f] = d


@njit(parallel=True, cache=True)
def edge_neighbours(faces, vf_offsets, vf, out):
    """``out[f, k]``: :func:`_across` each edge k of each face f."""
    for f in prange(faces.shape[0]):
        for k in range(3):
            out[f, k] = _across(faces, vf_offsets, vf, f, k)


@njit(parallel=True, cache=True)
def grouped_distances(after, rest, faces, vf_offsets, vf, groups, worst, total, count):
    """Both directions' samples (``after`` to the faces at ``rest``, and back), reduced per group
    without storing them: ``worst[k]`` (max), ``total[k]`` (sum) and ``count[k]`` (samples) of
    every vertex once per group around it (its nearest incident face of that group) and every
    face centroid once per group on its sides (to its face and the faces across its edges).
    ``groups`` (M, 2): the group on each side of a face, −1 none. In 16 parts (parallel), each
    with its own sums per direction, merged in order at the end."""
    parts, n, m, r = 16, vf_offsets.shape[0] - 1, faces.shape[0], worst.shape[0]
    w, s, c = np.zeros((parts, 2, r)), np.zeros((parts, 2, r)), np.zeros((parts, 2, r), np.int64)
    for p in prange(parts):
        seen, best = np.empty(64, np.int64), np.empty((2, 64))
        for i in range(p * n // parts, (p + 1) * n // parts):
            _vertex_samples(i, after, rest, faces, vf_offsets, vf, groups, seen, best,
                            w[p], s[p], c[p])
        for f in range(p * m // parts, (p + 1) * m // parts):
            _centroid_samples(f, after, rest, faces, vf_offsets, vf, groups, w[p], s[p], c[p])
    for d in range(2):
        for p in range(parts):
            for k in range(r):
                worst[k] = max(worst[k], w[p, d, k])
                total[k] += s[p, d, k]
                count[k] += c[p, d, k]


@njit(cache=True, inline="always")
def _vertex_samples(i, after, rest, faces, vf_offsets, vf, groups, seen, best, w, s, c):
    """Vertex i's two samples for each group around it (at most 64 groups)."""
    n = 0
    for t in range(vf_offsets[i], vf_offsets[i + 1]):
        g = vf[t]
        d0 = _distance2(after[i, 0], after[i, 1], after[i, 2], rest, faces, g)
        d1 = _distance2(rest[i, 0], rest[i, 1], rest[i, 2], after, faces, g)
        for side in range(2):
            k = groups[g, side]
            if k < 0:
                continue
            j = 0
            while j < n and seen[j] != k:
                j += 1
            if j == n:
                if n == 64:
                    continue
                seen[n], best[0, n], best[1, n] = k, d0, d1
                n += 1
            else:
                best[0, j], best[1, j] = min(best[0, j], d0), min(best[1, j], d1)
    for j in range(n):
        for d in range(2):
            _add(seen[j], math.sqrt(best[d, j]), w[d], s[d], c[d])


@njit(cache=True, inline="always")
def _centroid_samples(f, after, rest, faces, vf_offsets, vf, groups, w, s, c):
    """Face f's two centroid samples, each to the face and the faces across its edges."""
    px, py, pz = _centroid(after, faces, f)
    qx, qy, qz = _centroid(rest, faces, f)
    d0 = _distance2(px, py, pz, rest, faces, f)
    d1 = _distance2(qx, qy, qz, after, faces, f)
    for e in range(3):
        g = _across(faces, vf_offsets, vf, f, e)
        if g >= 0:
            d0 = min(d0, _distance2(px, py, pz, rest, faces, g))
            d1 = min(d1, _distance2(qx, qy, qz, after, faces, g))
    d0, d1 = math.sqrt(d0), math.sqrt(d1)
    for side in range(2):
        k = groups[f, side]
        if k >= 0:
            _add(k, d0, w[0], s[0], c[0])
            _add(k, d1, w[1], s[1], c[1])


@njit(cache=True, inline="always")
def _centroid(points, faces, f):
    a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
    return ((points[a, 0] + points[b, 0] + points[c, 0]) / 3.0,
            (points[a, 1] + points[b, 1] + points[c, 1]) / 3.0,
            (points[a, 2] + points[b, 2] + points[c, 2]) / 3.0)


@njit(cache=True, inline="always")
def _across(faces, vf_offsets, vf, f, k):
    """The other face on edge k (corners k, k + 1) of face f, −1 when there is none (the first
    one found on a non-manifold edge)."""
    a, b = faces[f, k], faces[f, (k + 1) % 3]
    for t in range(vf_offsets[a], vf_offsets[a + 1]):
        g = vf[t]
        if g != f and (faces[g, 0] == b or faces[g, 1] == b or faces[g, 2] == b):
            return g
    return -1


@njit(cache=True, inline="always")
def _add(k, d, worst, total, count):
    if d > worst[k]:
        worst[k] = d
    total[k] += d
    count[k] += 1
