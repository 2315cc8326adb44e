"""Numba kernels for :class:`anatomesh.core.model.surfaceset.SurfaceSet` shell views (private)."""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def group_faces(face_labels, index, nlabels):
    """Faces of each label: ``(order, starts)`` with ``order`` int64 (2M,) entries ``2 f + side``
    grouped by ``index[face_labels[f, side]]`` (-1: skip), faces ascending within a group."""
    m = face_labels.shape[0]
    counts = np.zeros(nlabels + 1, np.int64)
    for f in range(m):
        for s in range(2):
            g = index[face_labels[f, s]]
            if g >= 0:
                counts[g + 1] += 1
    for g in range(nlabels):  # prefix sums in place (np.cumsum costs a compile of its own)
        counts[g + 1] += counts[g]
    starts = counts
    fill = starts[:-1].copy()
    order = np.empty(starts[-1], np.int64)
    for f in range(m):
        for s in range(2):
            g = index[face_labels[f, s]]
            if g >= 0:
                order[fill[g]] = 2 * f + s
                fill[g] += 1
    return order, starts


@njit(cache=True)
def shell(faces, entries, split_rows, split_copy, mark):
    """One label's shell from its entries ``2 f + side`` (side 1: reverse the triangle).

    ``split_rows`` int32 (S, 4) are the split rows of this label only, ordered by face (as
    ``entries``); ``split_copy`` int64 (S,) numbers the distinct (vertex, copy) pairs of the rows
    0, 1, ...: copy vertex ``split_copy[r]`` is appended after the shared vertices.
    ``mark`` is int64 scratch with one entry per SurfaceSet vertex, all -1 on entry and on return.
    Returns ``(shell_faces int32 (m, 3), vertex_ids int64 (n0,))``: the shared vertices used, in
    order of first use; copy vertices get indices n0 + split_copy.
    """
    m = entries.size
    out = np.empty((m, 3), np.int32)
    ids = np.empty(3 * m, np.int64)
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
    return out, ids[:nv].copy()
