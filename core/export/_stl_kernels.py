"""Numba kernel filling binary STL facet records (private to :mod:`.mesh_files`)."""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def stl_facets(vertices, faces, out):
    """Facet normal and corners of each face, the 12 floats of an STL record.

    Parameters
    ----------
    vertices : (N, 3) float32, mm.
    faces : (M, 3) int32 or int64.
    out : (M, 12) float32, filled: unit normal from the winding (cross product in float32,
        normalised in float64; zero for a zero-area face), then the three corners.
    """
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        ux, uy, uz = vertices[b, 0] - vertices[a, 0], vertices[b, 1] - vertices[a, 1], vertices[b, 2] - vertices[a, 2]
        wx, wy, wz = vertices[c, 0] - vertices[a, 0], vertices[c, 1] - vertices[a, 1], vertices[c, 2] - vertices[a, 2]
        nx = np.float64(uy * wz - uz * wy)
        ny = np.float64(uz * wx - ux * wz)
        nz = np.float64(ux * wy - uy * wx)
        norm = np.sqrt(nx * nx + ny * ny + nz * nz)
        if norm == 0.0:
            norm = 1.0
        out[f, 0], out[f, 1], out[f, 2] = nx / norm, ny / norm, nz / norm
        for k in range(3):
            out[f, 3 + k] = vertices[a, k]
            out[f, 6 + k] = vertices[b, k]
            out[f, 9 + k] = vertices[c, k]
