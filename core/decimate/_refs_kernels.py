"""Numba kernels of the vertex → faces lists (private to :mod:`anatomesh.core.decimate`).

Arrays only, no half-edges: the faces of vertex ``v`` are ``refs[vstart[v]:vstart[v] +
vcount[v]]`` (int32 face ids, some possibly dead: lazy deletion). A collapse appends the
survivor's new list at the end of ``refs`` (as in Forstmann's fast quadric simplification);
:func:`compact_refs` rewrites the lists when the array is full.
"""
from __future__ import annotations

import numpy as np
from numba import njit

MAXF = 96          # faces around an edge's two endpoints; larger stars are not collapsed


@njit(cache=True)
def initial_refs(F, n_vertices, extra):
    """The vertex → face lists of faces ``F`` (M, 3): ``(refs (S + extra,) int32, vstart (N,)
    int64, vcount (N,) int32, S)`` with S = 3M used entries and ``extra`` free ones."""
    m = F.shape[0]
    vcount = np.zeros(n_vertices, np.int32)
    for f in range(m):
        for k in range(3):
            vcount[F[f, k]] += 1
    vstart = np.zeros(n_vertices, np.int64)
    s = 0
    for v in range(n_vertices):
        vstart[v] = s
        s += vcount[v]
    refs = np.empty(s + extra, np.int32)
    fill = vstart.copy()
    for f in range(m):
        for k in range(3):
            v = F[f, k]
            refs[fill[v]] = f
            fill[v] += 1
    return refs, vstart, vcount, s


@njit(cache=True)
def compact_refs(refs, vstart, vcount, ver, falive, new_size):
    """Rewrite every live vertex's live faces contiguously into a new array of ``new_size``."""
    out = np.empty(new_size, np.int32)
    s = 0
    for v in range(vstart.shape[0]):
        if ver[v] < 0:
            vcount[v] = 0
            vstart[v] = s
            continue
        st = vstart[v]
        c = 0
        for i in range(vcount[v]):
            f = refs[st + i]
            if falive[f]:
                out[s + c] = f
                c += 1
        vstart[v] = s
        vcount[v] = c
        s += c
    return out, s


@njit(cache=True)
def gather(refs, vstart, vcount, falive, v, out):
    """The live faces of vertex ``v`` into ``out``; their count, or -1 when ``out`` is full."""
    n = 0
    st = vstart[v]
    for i in range(vcount[v]):
        f = refs[st + i]
        if falive[f]:
            if n >= out.shape[0]:
                return -1
            out[n] = f
            n += 1
    return n


@njit(cache=True)
def has(f, F, v):
    """Face ``f`` has corner ``v``."""
    return F[f, 0] == v or F[f, 1] == v or F[f, 2] == v


@njit(cache=True, inline="always")
def add_label(labs, nl, lab):
    """Append ``lab`` to ``labs[:nl]`` unless it is there already; returns the new count."""
    for j in range(nl):
        if labs[j] == lab:
            return nl
    labs[nl] = lab
    return nl + 1
