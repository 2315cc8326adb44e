"""Numba kernels building compressed (CSR) neighbourhoods of a triangle mesh.

Serial on purpose, but for :func:`one_ring`, :func:`feature_rings` and the row packing they use
(millions of vertices in the largest maps' smoothing): each runs once per mesh in O(M), and
serial kernels compile much faster than parallel ones.

Private: call them through :mod:`anatomesh.core.geometry.neighbors`, which validates inputs. Every CSR is
a pair ``(offsets (n+1,) int64, indices (nnz,) int32)``: the neighbours of item ``i`` are
``indices[offsets[i]:offsets[i + 1]]``, sorted ascending, without repeats (Mönch et al. 2012).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from .kernels import find_root, other_corners, union, union_faces


@njit(cache=True)
def _sort_unique_segment(buf, start, stop):
    """Insertion-sort ``buf[start:stop]`` in place, drop repeats; returns the unique count."""
    for a in range(start + 1, stop):
        x = buf[a]
        b = a - 1
        while b >= start and buf[b] > x:
            buf[b + 1] = buf[b]
            b -= 1
        buf[b + 1] = x
    n = 0
    for a in range(start, stop):
        if n == 0 or buf[start + n - 1] != buf[a]:
            buf[start + n] = buf[a]
            n += 1
    return n


@njit(parallel=True, cache=True)
def _compact_rows(buf, upper_offsets, counts):
    """Pack the first ``counts[i]`` entries of each row of an over-allocated CSR (rows copied
    in parallel)."""
    n = counts.shape[0]
    offsets = np.zeros(n + 1, np.int64)
    for i in range(n):
        offsets[i + 1] = offsets[i] + counts[i]
    out = np.empty(offsets[n], np.int32)
    for i in prange(n):
        s = upper_offsets[i]
        d = offsets[i]
        for k in range(counts[i]):
            out[d + k] = buf[s + k]
    return offsets, out


@njit(cache=True, nogil=True)
def vertex_faces(faces, n_vertices):
    """Vertex → incident faces CSR (face ids ascending per vertex)."""
    m = faces.shape[0]
    offsets = np.zeros(n_vertices + 1, np.int64)
    for f in range(m):
        for k in range(3):
            offsets[faces[f, k] + 1] += 1
    for i in range(n_vertices):
        offsets[i + 1] += offsets[i]
    fill = offsets[:-1].copy()
    out = np.empty(offsets[n_vertices], np.int32)
    for f in range(m):
        for k in range(3):
            v = faces[f, k]
            out[fill[v]] = f
            fill[v] += 1
    return offsets, out


@njit(parallel=True, cache=True)
def one_ring(faces, n_vertices, vf_offsets, vf):
    """Vertex → 1-ring neighbours CSR (vertices sharing an edge), from the vertex→faces CSR.
    Parallel over vertices (every mesh structure starts with it, and the largest maps have
    millions of vertices)."""
    upper = np.zeros(n_vertices + 1, np.int64)
    for i in range(n_vertices):
        upper[i + 1] = upper[i] + 2 * (vf_offsets[i + 1] - vf_offsets[i])
    buf = np.empty(upper[n_vertices], np.int32)
    counts = np.zeros(n_vertices, np.int64)
    for i in prange(n_vertices):
        w = upper[i]
        for a in range(vf_offsets[i], vf_offsets[i + 1]):
            f = vf[a]
            for k in range(3):
                v = faces[f, k]
                if v != i:
                    buf[w] = v
                    w += 1
        counts[i] = _sort_unique_segment(buf, upper[i], w)
    return _compact_rows(buf, upper, counts)


@njit(cache=True)
def two_ring(offsets, nbr):
    """Vertex → 2-ring CSR: neighbours and neighbours of neighbours, without the vertex itself."""
    n = offsets.shape[0] - 1
    upper = np.zeros(n + 1, np.int64)
    for i in range(n):
        s = 0
        for a in range(offsets[i], offsets[i + 1]):
            j = nbr[a]
            s += 1 + offsets[j + 1] - offsets[j]
        upper[i + 1] = upper[i] + s
    buf = np.empty(upper[n], np.int32)
    counts = np.zeros(n, np.int64)
    for i in range(n):
        w = upper[i]
        for a in range(offsets[i], offsets[i + 1]):
            j = nbr[a]
            buf[w] = j
            w += 1
            for b in range(offsets[j], offsets[j + 1]):
                k = nbr[b]
                if k != i:
                    buf[w] = k
                    w += 1
        counts[i] = _sort_unique_segment(buf, upper[i], w)
    return _compact_rows(buf, upper, counts)


@njit(cache=True)
def face_ring(faces, vf_offsets, vf):
    """Face → faces sharing at least one vertex with it (itself included) CSR."""
    m = faces.shape[0]
    upper = np.zeros(m + 1, np.int64)
    for f in range(m):
        s = 0
        for k in range(3):
            v = faces[f, k]
            s += vf_offsets[v + 1] - vf_offsets[v]
        upper[f + 1] = upper[f] + s
    buf = np.empty(upper[m], np.int32)
    counts = np.zeros(m, np.int64)
    for f in range(m):
        w = upper[f]
        for k in range(3):
            v = faces[f, k]
            for a in range(vf_offsets[v], vf_offsets[v + 1]):
                buf[w] = vf[a]
                w += 1
        counts[f] = _sort_unique_segment(buf, upper[f], w)
    return _compact_rows(buf, upper, counts)


@njit(parallel=True, cache=True)
def feature_rings(faces, offsets, nbr, vf_offsets, vf, face_group):
    """Restrict each 1-ring to what a vertex may smooth with, given a group per face:
    ``face_group`` (M, 2) int32 pairs compared unordered (a label map's two side labels; ids
    given as (id, id)).

    An edge (i, j) is a *feature edge* when it has one incident face (an open boundary), more
    than two (a non-manifold pinch) or its incident faces do not all carry the same group (a
    junction where 3+ labels meet). A vertex
    with no feature edge keeps its whole 1-ring; a vertex with exactly two feature edges lies on
    a feature curve and keeps only those two neighbours (1D smoothing along the curve); any
    other vertex (curve end or a corner where curves meet) keeps none, so it stays fixed.

    Returns ``(offsets, indices, kind)`` with kind (n,) int8: 0 free, 1 on a curve, 2 fixed.
    Parallel over vertices (each marks its own ring entries, :func:`_mark_features`): the
    largest maps have millions of vertices, and one flag per ring entry is all it keeps.
    """
    n = offsets.shape[0] - 1
    is_feature = np.zeros(nbr.shape[0], np.bool_)  # per ring entry (i, j): edge ij is a feature
    nfeat = np.zeros(n, np.int64)
    most = 0
    for i in range(n):
        most = max(most, offsets[i + 1] - offsets[i])
    parts = 16
    for p in prange(parts):
        count = np.empty(most, np.int64)  # scratch per part: faces of each edge of the ring
        first = np.empty(most, np.int64)  # the first of them, -1 before it, -2 when groups differ
        for i in range(p * n // parts, (p + 1) * n // parts):
            nfeat[i] = _mark_features(i, faces, offsets, nbr, vf_offsets, vf, face_group,
                                      count, first, is_feature)
    counts = np.zeros(n, np.int64)
    kind = np.zeros(n, np.int8)
    for i in prange(n):
        if nfeat[i] == 0:
            counts[i] = offsets[i + 1] - offsets[i]
        elif nfeat[i] == 2:
            counts[i] = 2
            kind[i] = 1
        else:
            kind[i] = 2
    new_off = np.zeros(n + 1, np.int64)
    for i in range(n):
        new_off[i + 1] = new_off[i] + counts[i]
    out = np.empty(new_off[n], np.int32)
    for i in prange(n):
        w = new_off[i]
        for a in range(offsets[i], offsets[i + 1]):
            if kind[i] == 0 or (kind[i] == 1 and is_feature[a]):
                out[w] = nbr[a]
                w += 1
    return new_off, out, kind


@njit(cache=True, inline="always")
def _same_pair(pairs, a, b):
    """Faces a and b carry the same unordered pair (rows of ``pairs`` (M, 2))."""
    return min(pairs[a, 0], pairs[a, 1]) == min(pairs[b, 0], pairs[b, 1]) and \
        max(pairs[a, 0], pairs[a, 1]) == max(pairs[b, 0], pairs[b, 1])


@njit(cache=True)
def _mark_features(i, faces, offsets, nbr, vf_offsets, vf, face_group, count, first, is_feature):
    """Flag the feature edges among vertex i's ring entries in ``is_feature``; returns how many.
    ``count`` and ``first``: scratch of at least the ring's length."""
    lo, k = offsets[i], offsets[i + 1] - offsets[i]
    for a in range(k):
        count[a] = 0
        first[a] = -1
    for b in range(vf_offsets[i], vf_offsets[i + 1]):
        f = vf[b]
        for c in range(3):
            j = faces[f, c]
            if j == i or (c > 0 and j == faces[f, 0]) or (c == 2 and j == faces[f, 1]):
                continue  # a corner repeated in a degenerate face counts once
            a = 0
            while nbr[lo + a] != j:  # j is in i's ring: every face of i lists its ring
                a += 1
            count[a] += 1
            if first[a] == -1:
                first[a] = f
            elif first[a] >= 0 and not _same_pair(face_group, first[a], f):
                first[a] = -2
    n = 0
    for a in range(k):
        feature = count[a] != 2 or first[a] == -2
        is_feature[lo + a] = feature
        n += feature
    return n


@njit(parallel=True, cache=True)
def open_vertices(faces, vf_offsets, vf):
    """(N,) bool: the vertices with an edge that has one incident face (an open boundary) or
    more than two (a non-manifold pinch) — those :func:`feature_rings` gives a kind != 0 with
    no groups — from the vertex → faces CSR alone (no 1-ring)."""
    n = vf_offsets.shape[0] - 1
    out = np.zeros(n, np.bool_)
    for i in prange(n):
        for t in range(vf_offsets[i], vf_offsets[i + 1]):
            for c in range(3):
                j = faces[vf[t], c]
                if j != i and not out[i] and _faces_on_edge(faces, vf_offsets, vf, i, j) != 2:
                    out[i] = True
    return out


@njit(cache=True, inline="always")
def _faces_on_edge(faces, vf_offsets, vf, i, j):
    """How many faces around vertex i have j as a corner (a degenerate face once)."""
    n = 0
    for t in range(vf_offsets[i], vf_offsets[i + 1]):
        g = vf[t]
        if faces[g, 0] == j or faces[g, 1] == j or faces[g, 2] == j:
            n += 1
    return n


@njit(cache=True)
def components(faces, n):
    """Connected components of the mesh's edge graph (n vertices): (n,) int64 labels 0..C-1 in
    order of first vertex, by union-find over the faces' edges (no 1-ring: the root kept is a
    component's smallest vertex). Isolated vertices get their own label."""
    parent = union_faces(faces, n)
    label = np.empty(n, np.int64)
    c = 0
    for x in range(n):
        r = find_root(parent, x)
        if r == x:  # the component's first vertex
            label[x] = c
            c += 1
        else:
            label[x] = label[r]
    return label


@njit(cache=True)
def _chain_length(c, width, ext_width):
    """Helper columns a row of ``c > width`` neighbours needs (see :func:`padded_columns`)."""
    r = c - (width - 1)
    k = 1
    while r > ext_width:
        r -= ext_width - 1
        k += 1
    return k


@njit(cache=True)
def padded_columns(offsets, nbr, width, ext_width):
    """CSR → fixed-width columns (column-major ELLPACK) for branch-free neighbour loops.

    Returns ``(cols (width, n) uint32, inv_count (n,) float64, ext (ext_width, H) uint32,
    level_at (levels + 1,) int64)``. Column ``i`` of ``cols`` holds the neighbours of ``i`` then
    the pad index ``n`` (a zero column appended to the positions); ``inv_count[i]`` is
    ``1 / valence`` (0 for none). A row longer than ``width`` keeps ``width − 1`` neighbours
    and, last, the index ``n + 1 + h`` of a *helper column* ``h`` whose value is the sum of the
    rest: ``ext[:, h]`` lists them (padded with ``n``), chaining to a further helper when more
    than ``ext_width`` remain. Helpers are numbered by height (0: the end of a chain), so summing
    the levels ``level_at[l]:level_at[l + 1]`` in order fills each before it is read.
    """
    n = offsets.shape[0] - 1
    levels = 0
    for i in range(n):
        c = offsets[i + 1] - offsets[i]
        if c > width:
            levels = max(levels, _chain_length(c, width, ext_width))
    level_at = np.zeros(levels + 1, np.int64)
    for i in range(n):
        c = offsets[i + 1] - offsets[i]
        if c > width:
            for h in range(_chain_length(c, width, ext_width)):
                level_at[h + 1] += 1
    for h in range(levels):
        level_at[h + 1] += level_at[h]
    fill = level_at[:-1].copy()
    cols = np.full((width, n), n, np.uint32)  # unsigned: no negative-index wraparound
    ext = np.full((ext_width, level_at[-1]), n, np.uint32)
    inv_count = np.zeros(n, np.float64)
    for i in range(n):
        start, c = offsets[i], offsets[i + 1] - offsets[i]
        if c > 0:
            inv_count[i] = 1.0 / c
        if c <= width:
            for a in range(c):
                cols[a, i] = np.uint32(nbr[start + a])
            continue
        for a in range(width - 1):
            cols[a, i] = np.uint32(nbr[start + a])
        k = _chain_length(c, width, ext_width)
        h = fill[k - 1]
        fill[k - 1] += 1
        cols[width - 1, i] = np.uint32(n + 1 + h)
        at, rest = start + width - 1, c - (width - 1)
        for depth in range(k - 1, -1, -1):  # height of helper h
            take = rest if depth == 0 else ext_width - 1
            for a in range(take):
                ext[a, h] = np.uint32(nbr[at + a])
            at += take
            rest -= take
            if depth > 0:
                nxt = fill[depth - 1]
                fill[depth - 1] += 1
                ext[ext_width - 1, h] = np.uint32(n + 1 + nxt)
                h = nxt
    return cols, inv_count, ext, level_at


@njit(cache=True)
def fan_counts(faces, vf_offsets, vf):
    """Number of fans of faces around each vertex, (n,) int32: the incident faces linked when
    they share an edge at the vertex (the same other endpoint). A manifold vertex has one (a
    disk or a half-disk at a boundary), a pinch point more, an unused vertex none."""
    n = vf_offsets.shape[0] - 1
    out = np.zeros(n, np.int32)
    most = 0
    for i in range(n):
        most = max(most, vf_offsets[i + 1] - vf_offsets[i])
    parent = np.empty(most, np.int64)
    spoke = np.empty(2 * most, np.int64)  # the other endpoint of each face's two edges at i
    order = np.empty(2 * most, np.int64)
    for i in range(n):
        lo, k = vf_offsets[i], vf_offsets[i + 1] - vf_offsets[i]
        for p in range(k):
            parent[p] = p
            spoke[2 * p], spoke[2 * p + 1] = other_corners(faces, vf[lo + p], i)
        _sort_indices(spoke, 2 * k, order)  # equal spokes side by side: faces sharing that edge
        fans = k
        for t in range(1, 2 * k):
            if spoke[order[t]] == spoke[order[t - 1]]:
                fans -= union(parent, order[t] // 2, order[t - 1] // 2)
        out[i] = fans
    return out


@njit(cache=True)
def _sort_indices(keys, m, order):
    """``order[:m]`` = the indices sorting ``keys[:m]``: insertion sort for the usual handful
    (no allocation), numpy's sort for long lists."""
    if m > 32:
        order[:m] = np.argsort(keys[:m])
        return
    for t in range(m):
        order[t] = t
        u = t
        while u > 0 and keys[order[u - 1]] > keys[order[u]]:
            order[u - 1], order[u] = order[u], order[u - 1]
            u -= 1
