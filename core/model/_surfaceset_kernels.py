"""Numba kernels for :class:`anatomesh.core.model.surfaceset.SurfaceSet` shell views (private)."""
from __future__ import annotations

from numba import njit, prange


@njit(cache=True)
def group_faces(face_labels, index, at, order):
    """Faces of each label as entries ``2 f + side`` grouped by ``index[face_labels[f, side]]``
    (-1: skip), faces ascending within a group. Two calls (the arrays come from the caller: a
    kernel that allocates none compiles faster, the first run after install): with ``order``
    empty, ``at`` (G + 1,) int64 zeros becomes the groups' starts; then with ``order`` int64
    (starts[-1],) and ``at`` a copy of ``starts[:-1]``, ``order`` is filled."""
    m = face_labels.shape[0]
    if order.size == 0:
        for f in range(m):
            for s in range(2):
                g = index[face_labels[f, s]]
                if g >= 0:
                    at[g + 1] += 1
        for g in range(at.size - 1):  # prefix sums in place (np.cumsum costs a compile of its own)
            at[g + 1] += at[g]
        return
    for f in range(m):
        for s in range(2):
            g = index[face_labels[f, s]]
            if g >= 0:
                order[at[g]] = 2 * f + s
                at[g] += 1


@njit(cache=True)
def shell(faces, entries, split_rows, split_copy, mark, out, ids):
    """One label's shell from its entries ``2 f + side`` (side 1: reverse the triangle).

    ``split_rows`` int32 (S, 4) are the split rows of this label only, ordered by face (as
    ``entries``); ``split_copy`` int64 (S,) numbers the distinct (vertex, copy) pairs of the rows
    0, 1, ...: copy vertex ``split_copy[r]`` is appended after the shared vertices.
    ``mark`` is int64 scratch with one entry per SurfaceSet vertex, all -1 on entry and on return.
    Fills ``out`` int32 (m, 3), the shell's faces, and ``ids[:n0]`` (``ids`` int64 (3 m,)): the
    shared vertices used, in order of first use; copy vertices get indices n0 + split_copy.
    Returns n0.
    """
    m = entries.size
    nv = 0
    r = 0
    nrows = split_rows.shape[0]
    for i in range(m):
        f = entries[i] >> 1
        for k in range(3):
            v = faces[f, k]
            if mark[v] < 0:
                mark[v] = nv
                ids[nv] = v
                nv += 1
            out[i, k] = mark[v]
        while r < nrows:
            if split_rows[r, 0] >= f:
                break
            r += 1
        while r < nrows:
            if split_rows[r, 0] != f:
                break
            out[i, split_rows[r, 2]] = -1 - split_copy[r]
            r += 1
        if entries[i] & 1:
            tmp = out[i, 1]
            out[i, 1] = out[i, 2]
            out[i, 2] = tmp
    for i in range(m):
        for k in range(3):
            if out[i, k] < 0:
                out[i, k] = nv - 1 - out[i, k]
    for u in range(nv):
        mark[ids[u]] = -1
    return nv


@njit(parallel=True, cache=True)
def mark_present(face_labels, seen):
    """``seen[v] = True`` for every value v in ``face_labels`` (M, 2), all in [0, len(seen)):
    which label values have faces, with no int64 copy of the labels (what ``np.bincount``
    makes). Threads may set the same flag: they all write True."""
    for f in prange(face_labels.shape[0]):
        seen[face_labels[f, 0]] = True
        seen[face_labels[f, 1]] = True
