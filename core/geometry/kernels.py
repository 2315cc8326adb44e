"""Small numba kernels shared across rooms: sorted search, face corners, union-find, a
triangle's cross product, the triangle interval of the triangle-triangle test, and a marker
that keeps a loop scalar.

Public so that kernel modules of other rooms can call them inside their own kernels.
"""
import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic, overload


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
def find_root(parent, x):
    """Root of ``x`` in the union-find forest ``parent`` (int array, changed in place: path
    compression)."""
    root = x
    while parent[root] != root:
        root = parent[root]
    while parent[x] != root:  # path compression
        nxt = parent[x]
        parent[x] = root
        x = nxt
    return root


@njit(cache=True)
def union(parent, a, b):
    """Join the trees of ``a`` and ``b`` in the union-find forest ``parent`` under the smaller
    root (so every root is its component's smallest index); True when they were apart."""
    ra, rb = find_root(parent, a), find_root(parent, b)
    if ra == rb:
        return False
    parent[max(ra, rb)] = min(ra, rb)
    return True


@njit(cache=True)
def union_faces(faces, n):
    """Union-find forest (n,) int64 of the mesh's edge graph, from the faces' edges: every
    component's root is its smallest vertex (an isolated vertex is its own root)."""
    parent = np.arange(n)
    for f in range(faces.shape[0]):
        for c in range(2):
            union(parent, faces[f, c], faces[f, c + 1])
    return parent


@njit(cache=True)
def union_find_roots(a, b, n):
    """Root of each of ``n`` nodes for the graph with edges (a[i], b[i]); int64 (n,).

    Roots are the smallest node index of each component, so results are deterministic.
    """
    parent = np.arange(n)
    for i in range(a.shape[0]):
        union(parent, a[i], b[i])
    for x in range(n):
        parent[x] = find_root(parent, x)
    return parent


@njit(cache=True)
def triangle_interval(p0, p1, p2, d0, d1, d2):
    """Interval of a triangle on the line where two triangles' planes meet (Möller 1997, "A fast
    triangle-triangle intersection test"): its corners' projections ``p0..p2`` on the line and
    signed distances ``d0..d2`` to the other plane; returns ``(lo, hi, coplanar)``."""
    if d0 * d1 > 0.0:  # p2 alone on its side
        a = p2 + (p0 - p2) * d2 / (d2 - d0)
        b = p2 + (p1 - p2) * d2 / (d2 - d1)
    elif d0 * d2 > 0.0:  # p1 alone
        a = p1 + (p0 - p1) * d1 / (d1 - d0)
        b = p1 + (p2 - p1) * d1 / (d1 - d2)
    elif d1 * d2 > 0.0 or d0 != 0.0:  # p0 alone
        a = p0 + (p1 - p0) * d0 / (d0 - d1)
        b = p0 + (p2 - p0) * d0 / (d0 - d2)
    elif d1 != 0.0:
        a = p1 + (p0 - p1) * d1 / (d1 - d0)
        b = p1 + (p2 - p1) * d1 / (d1 - d2)
    elif d2 != 0.0:
        a = p2 + (p0 - p2) * d2 / (d2 - d0)
        b = p2 + (p1 - p2) * d2 / (d2 - d1)
    else:
        return 0.0, 0.0, True
    if a > b:
        a, b = b, a
    return a, b, False


@njit(cache=True, inline="always")
def triangle_cross(pos, a, b, c):
    """The unnormalised normal (b - a) x (c - a) of the triangle (a, b, c) of ``pos`` (N, 3):
    twice its area times its unit normal."""
    e1x, e1y, e1z = pos[b, 0] - pos[a, 0], pos[b, 1] - pos[a, 1], pos[b, 2] - pos[a, 2]
    e2x, e2y, e2z = pos[c, 0] - pos[a, 0], pos[c, 1] - pos[a, 1], pos[c, 2] - pos[a, 2]
    return e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x


def scalar_loop():
    """Keep the loop this is called in scalar (call it first in the loop body): in a kernel it
    is an empty volatile ``asm`` statement, no instruction, which LLVM's loop vectorizer cannot
    vectorize; outside numba it does nothing.

    For loops that gather neighbours' coordinates through an index array: vectorized, each
    gather is an AVX-512 ``vgatherqpd``, and on this machine's CPU (AMD Zen 4) those run slower
    than the scalar loads they replace. Measured on the chest CT's 1M-triangle bone surface:
    40 uniform umbrella passes 140-154 → 91-112 ms (with the voxel box: 154-169 → 112-124 ms);
    the volume step's vertex moves 17.5-18 → 14-16 ms a call. A pass along one axis (one
    gather per neighbour) ran slower scalar: 86-91 → 116-129 ms for 42 passes."""


@intrinsic
def _empty_volatile_asm(typingctx):
    def codegen(context, builder, signature, args):
        builder.asm(ir.FunctionType(ir.VoidType(), []), "", "", [], True)
        return context.get_dummy_value()

    return types.none(), codegen


overload(scalar_loop)(lambda: lambda: _empty_volatile_asm())
