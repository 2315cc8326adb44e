"""Numba kernel of :func:`anatomesh.core.extract.edges.unique_edges`."""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def unique_edges(faces, n_vertices):  # pragma: no cover - numba
    """Edges (E, 2) int32 (lo, hi) in order of their lower vertex, and the edge of each corner
    (3M,) int32 (corner c of face f: edge from vertex c to vertex c + 1). The half-edges are
    bucketed by their lower vertex (counting sort), then deduplicated within each small bucket."""
    m = faces.shape[0]
    start = np.zeros(n_vertices + 1, np.int64)
    for f in range(m):
        for c in range(3):
            a, b = faces[f, c], faces[f, (c + 1) % 3]
            start[min(a, b) + 1] += 1
    for i in range(n_vertices):
        start[i + 1] += start[i]
    fill = start[:-1].copy()
    other = np.empty(3 * m, np.int32)
    corner = np.empty(3 * m, np.int64)
    for f in range(m):
        for c in range(3):
            a, b = faces[f, c], faces[f, (c + 1) % 3]
            k = fill[min(a, b)]
            fill[min(a, b)] += 1
            other[k] = max(a, b)
            corner[k] = 3 * f + c
    corner_edge = np.empty(3 * m, np.int32)
    edges = np.empty((3 * m, 2), np.int32)
    ne = 0
    for v in range(n_vertices):
        first = ne
        for k in range(start[v], start[v + 1]):
            found = -1
            for j in range(first, ne):
                if edges[j, 1] == other[k]:
                    found = j
                    break
            if found < 0:
                edges[ne, 0], edges[ne, 1] = v, other[k]
                found = ne
                ne += 1
            corner_edge[corner[k]] = found
    return edges[:ne], corner_edge
