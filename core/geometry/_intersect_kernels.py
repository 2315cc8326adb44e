"""Numba kernels for :mod:`anatomesh.core.geometry.intersections`: the search for crossing face
pairs over a uniform grid (each pair by the triangle-triangle test of ``kernels``). Private: call the
wrappers in ``intersections.py`` (they validate inputs).
"""
import numpy as np
from numba import njit, prange

from .kernels import tri_tri_intersect


# ---------------------------------------------------------------------------------------------
# all intersecting face pairs, through a uniform grid
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _cell_pairs(c, start, items, vertices, faces, wfaces, fmin, fmax, origin, h, dims,
                rel_eps, active, out, n_out):
    """Test the face pairs of cell c (each pair once: in the cell holding the low corner of the
    overlap of their boxes); faces sharing a (welded) vertex are skipped, and pairs with no
    ``active`` face when ``active`` has entries. Writes pairs into ``out`` from row ``n_out``
    when ``out`` has rows; returns the new count."""
    some = active.shape[0] > 0
    i0 = start[c]
    i1 = start[c + 1]
    ck = c % dims[2]
    cj = (c // dims[2]) % dims[1]
    ci = c // (dims[1] * dims[2])
    cell = (ci, cj, ck)
    for s in range(i0, i1):
        fa = items[s]
        for t in range(s + 1, i1):
            fb = items[t]
            if some and not active[fa] and not active[fb]:
                continue
            # boxes overlap?
            ok = True
            own = True
            for a in range(3):
                lo = max(fmin[fa, a], fmin[fb, a])
                hi = min(fmax[fa, a], fmax[fb, a])
                if lo > hi:
                    ok = False
                    break
                idx = int(np.floor((lo - origin[a]) / h))
                idx = min(max(idx, 0), dims[a] - 1)
                if idx != cell[a]:
                    own = False
            if not ok or not own:
                continue
            shared = False
            for x in range(3):
                for y in range(3):
                    if wfaces[fa, x] == wfaces[fb, y]:
                        shared = True
            if shared:
                continue
            if tri_tri_intersect(vertices[faces[fa, 0]], vertices[faces[fa, 1]],
                                 vertices[faces[fa, 2]], vertices[faces[fb, 0]],
                                 vertices[faces[fb, 1]], vertices[faces[fb, 2]], rel_eps):
                if out.shape[0] > 0:
                    out[n_out, 0] = min(fa, fb)
                    out[n_out, 1] = max(fa, fb)
                n_out += 1
    return n_out


@njit(cache=True, parallel=True)
def intersecting_pairs(vertices, faces, wfaces, origin, h, dims, start, items, rel_eps, active):
    """All pairs (K, 2) int64 of faces that intersect and share no welded vertex (cells in
    parallel: one pass counts, the second writes each cell's pairs at its offset); when
    ``active`` (M,) bool has entries, only pairs with an active face."""
    m = faces.shape[0]
    fmin = np.empty((m, 3))
    fmax = np.empty((m, 3))
    for f in prange(m):
        for a in range(3):
            x0 = vertices[faces[f, 0], a]
            x1 = vertices[faces[f, 1], a]
            x2 = vertices[faces[f, 2], a]
            fmin[f, a] = min(x0, min(x1, x2))
            fmax[f, a] = max(x0, max(x1, x2))
    keep = start[1:] - start[:-1] > 1  # cells with a pair (and an active face, if filtered)
    if active.shape[0] > 0:
        for c in prange(keep.shape[0]):
            if keep[c]:
                hit = False
                for s in range(start[c], start[c + 1]):
                    hit = hit or active[items[s]]
                keep[c] = hit
    busy = np.flatnonzero(keep)
    counts = np.zeros(busy.shape[0], np.int64)
    empty = np.zeros((0, 2), np.int64)
    for b in prange(busy.shape[0]):
        counts[b] = _cell_pairs(busy[b], start, items, vertices, faces, wfaces, fmin, fmax,
                                origin, h, dims, rel_eps, active, empty, 0)
    offs = np.zeros(busy.shape[0] + 1, np.int64)
    for b in range(busy.shape[0]):
        offs[b + 1] = offs[b] + counts[b]
    out = np.empty((offs[-1], 2), np.int64)
    for b in prange(busy.shape[0]):
        if counts[b] > 0:
            _cell_pairs(busy[b], start, items, vertices, faces, wfaces, fmin, fmax, origin, h,
                        dims, rel_eps, active, out, offs[b])
    return out
