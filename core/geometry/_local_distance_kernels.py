"""Numba kernels for :mod:`anatomesh.core.geometry.local_distance` (private: no input checks)."""
import math

from numba import njit, prange

from ._spatial_kernels import closest_on_triangle


@njit(cache=True, inline="always")
def _distance(px, py, pz, vertices, faces, f):
    x, y, z, _ = closest_on_triangle(px, py, pz, vertices, faces[f, 0], faces[f, 1], faces[f, 2])
    return math.sqrt((x - px) ** 2 + (y - py) ** 2 + (z - pz) ** 2)


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
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        px = (points[a, 0] + points[b, 0] + points[c, 0]) / 3.0
        py = (points[a, 1] + points[b, 1] + points[c, 1]) / 3.0
        pz = (points[a, 2] + points[b, 2] + points[c, 2]) / 3.0
        d = _distance(px, py, pz, vertices, faces, f)
        for k in range(near.shape[1]):
            g = near[f, k]
            if g >= 0:
                d = min(d, _distance(px, py, pz, vertices, faces, g))
        out[f] = d


@njit(parallel=True, cache=True)
def edge_neighbours(faces, vf_offsets, vf, out):
    """``out[f, k]``: the other face on edge k (corners k, k + 1) of face f, −1 when there is
    none (first one found on a non-manifold edge)."""
    for f in prange(faces.shape[0]):
        for k in range(3):
            a, b = faces[f, k], faces[f, (k + 1) % 3]
            out[f, k] = -1
            for t in range(vf_offsets[a], vf_offsets[a + 1]):
                g = vf[t]
                if g != f and (faces[g, 0] == b or faces[g, 1] == b or faces[g, 2] == b):
                    out[f, k] = g
                    break
