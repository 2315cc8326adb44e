"""Small numba kernels shared across rooms: sorted search, face corners, union-find.

Public so that kernel modules of other rooms can call them inside their own kernels.
"""
import numpy as np
from numba import njit


@njit(cache=True)
def lower_bound(a, x):
    """First index of sorted ``a`` whose value is >= x (``np.searchsorted``, side="left")."""
    lo = 0
    hi = a.shape[0]
    while lo < hi:
        mid = (lo + hi) >> 1
        if a[mid] < x:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True)
def other_corners(faces, f, i):
    """The corners ``(j, k)`` of face ``f`` after its corner ``i``, in winding order, so the
    face reads (i, j, k)."""
    if faces[f, 0] == i:
        return faces[f, 1], faces[f, 2]
    if faces[f, 1] == i:
        return faces[f, 2], faces[f, 0]
    return faces[f, 0], faces[f, 1]


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
