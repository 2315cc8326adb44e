"""Numba union-find for connected components (used by :mod:`anatomesh.core.model.mesh`)."""
import numpy as np
from numba import njit


@njit(cache=True)
def _find(parent, x):
    root = x
    while parent[root] != root:
        root = parent[root]
    while parent[x] != root:  # path compression
        nxt = parent[x]
        parent[x] = root
        x = nxt
    return root


@njit(cache=True)
def union_find_roots(a, b, n):
    """Root of each of ``n`` nodes for the graph with edges (a[i], b[i]); int64 (n,).

    Roots are the smallest node index of each component, so results are deterministic.
    """
    parent = np.arange(n)
    for i in range(a.shape[0]):
        ra = _find(parent, a[i])
        rb = _find(parent, b[i])
        if ra < rb:
            parent[rb] = ra
        elif rb < ra:
            parent[ra] = rb
    for x in range(n):
        parent[x] = _find(parent, x)
    return parent
