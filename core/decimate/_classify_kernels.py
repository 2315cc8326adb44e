"""Numba kernels classifying the vertices of the input (private to :mod:`anatomesh.core.decimate`).

``vclass`` (N,) int8: 0 free, 1 feature (a junction vertex, where faces of 3+ labels meet, or on
an open boundary: it moves only along its curve), 2 locked (never moves, no edge touching it
collapses: pinch points, non-manifold or open shell edges of a label, stars over ``MAXF``).
Feature edges also get constraint planes (:func:`feature_constraints`), the boundary quadrics
of Garland & Heckbert 1997 ("Surface simplification using quadric error metrics").
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from ._refs_kernels import MAXF, add_label


@njit(cache=True)
def _root(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit(cache=True)
def _edge_kind(F, flab, refs, st, c, u, multi):
    """Faces of vertex list refs[st:st+c] containing u: (count, carries 3+ labels)."""
    cnt = 0
    l0 = -1
    l1 = -1
    extra = False
    for i in range(c):
        g = refs[st + i]
        if F[g, 0] == u or F[g, 1] == u or F[g, 2] == u:
            cnt += 1
            if multi:
                for s in range(2):
                    lab = flab[g, s]
                    if l0 < 0 or lab == l0:
                        l0 = lab
                    elif l1 < 0 or lab == l1:
                        l1 = lab
                    else:
                        extra = True
    return cnt, extra


@njit(parallel=True, cache=True)
def classify(F, flab, refs, vstart, vcount, multi):
    """Vertex classes of the input mesh from its vertex -> faces lists, (N,) int8.

    1 (feature): a junction vertex (incident faces carry 3+ labels) or on an open boundary /
    junction edge; 2 (locked): some label's shell is not one closed manifold fan around it
    (pinch points, open or non-manifold shell edges), an edge with 3+ faces that is not a
    junction, or more than MAXF faces. Each vertex decides its own class (parallel, no races).
    """
    n = vstart.shape[0]
    vclass = np.zeros(n, np.int8)
    chunk = 2048
    for ch in prange((n + chunk - 1) // chunk):
        labs = np.empty(2 * MAXF, np.int32)
        sel = np.empty(MAXF, np.int32)
        parent = np.empty(MAXF, np.int32)
        for v in range(ch * chunk, min(n, (ch + 1) * chunk)):
            if multi:
                vclass[v] = _classify_vertex(F, flab, refs, vstart[v], vcount[v], v, multi, labs,
                                             sel, parent)
            else:
                vclass[v] = _classify_plain(F, refs, vstart[v], vcount[v], v, sel, parent)
    return vclass


@njit(cache=True)
def _classify_plain(F, refs, st, c, v, u1, u2):
    """Class of vertex v of a single surface: walk its fan (faces (v, u1, u2) counter-clockwise).
    0: one closed, consistently oriented fan; 1: one open fan (boundary); 2: anything else."""
    if c == 0:
        return 0
    if c > MAXF:
        return 2
    for i in range(c):
        f = refs[st + i]
        k = 0 if F[f, 0] == v else (1 if F[f, 1] == v else 2)
        u1[i] = F[f, (k + 1) % 3]
        u2[i] = F[f, (k + 2) % 3]
    nb = 0
    for i in range(c):
        # u2[i] must start exactly one face (as its u1) unless it is a boundary edge
        n_next = 0
        n_same = 0
        for j in range(c):
            if u1[j] == u2[i]:
                n_next += 1
            if j != i and u2[j] == u2[i]:
                n_same += 1
        if n_next > 1 or n_same > 0:
            return 2
        if n_next == 0:
            nb += 1
        n_prev = 0
        for j in range(c):
            if u2[j] == u1[i]:
                n_prev += 1
        if n_prev == 0:
            nb += 1
    if nb > 2:
        return 2
    # following u2 -> the face whose u1 it is must visit all c faces: one fan
    i = 0
    if nb == 2:           # open fan: start at the face whose u1 has no predecessor
        for j in range(c):
            has_prev = False
            for k in range(c):
                if u2[k] == u1[j]:
                    has_prev = True
                    break
            if not has_prev:
                i = j
                break
        first = i
        for step in range(c):
            nxt = -1
            for j in range(c):
                if u1[j] == u2[i]:
                    nxt = j
                    break
            if nxt < 0:
                return 1 if step == c - 1 else 2     # one open fan (boundary vertex)
            i = nxt
            if i == first:
                return 2
        return 2
    for step in range(c):
        nxt = -1
        for j in range(c):
            if u1[j] == u2[i]:
                nxt = j
                break
        i = nxt
        if i == 0:
            return 0 if step == c - 1 else 2
    return 2


@njit(cache=True)
def _classify_vertex(F, flab, refs, st, c, v, multi, labs, sel, parent):
    """Class of vertex v (see :func:`classify`) from its c faces refs[st:st+c]."""
    if c == 0:
        return 0
    if c > MAXF:
        return 2
    cls = 0
    nl = 0
    if multi:
        for i in range(c):
            f = refs[st + i]
            for s in range(2):
                nl = add_label(labs, nl, flab[f, s])
        if nl >= 3:
            cls = 1
    # edges at v: open boundary or junction -> feature; 3+ faces without junction -> locked
    for i in range(c if multi else 0):
        f = refs[st + i]
        for k in range(3):
            u = F[f, k]
            if u == v:
                continue
            cnt, extra = _edge_kind(F, flab, refs, st, c, u, multi)
            if cnt == 1 or extra:
                cls = max(cls, 1)
            elif cnt > 2:
                cls = 2
    # per shell: the faces of each label around v must form one fan, closed for labels
    for li in range(max(nl, 1)):
        lab = labs[li] if multi else -1
        ns = 0
        for i in range(c):
            f = refs[st + i]
            if lab < 0 or flab[f, 0] == lab or flab[f, 1] == lab:
                sel[ns] = i
                parent[ns] = ns
                ns += 1
        bad = False
        for x in range(ns):
            fx = refs[st + sel[x]]
            for k in range(3):
                u = F[fx, k]
                if u == v:
                    continue
                cnt = 0
                for y in range(ns):
                    fy = refs[st + sel[y]]
                    if F[fy, 0] == u or F[fy, 1] == u or F[fy, 2] == u:
                        cnt += 1
                        ry, rx = _root(parent, y), _root(parent, x)
                        if ry != rx:
                            parent[ry] = rx
                if cnt > 2 or (cnt == 1 and multi):
                    bad = True
                elif cnt == 1:
                    cls = max(cls, 1)       # open boundary of a single surface
        roots = 0
        for x in range(ns):
            if _root(parent, x) == x:
                roots += 1
        if bad or roots > 1:
            cls = 2
    return cls


@njit(cache=True)
def feature_constraints(F, flab, refs, vstart, vcount, vclass, multi):
    """(edge a, edge b, face) for every face on a feature edge (open boundary or junction): the
    constraint planes of :func:`build_quadrics`. Only feature vertices are visited (rare)."""
    cap = 1024
    ca = np.empty(cap, np.int32)
    cb = np.empty(cap, np.int32)
    cf = np.empty(cap, np.int32)
    nc = 0
    for v in range(vstart.shape[0]):
        if vclass[v] == 0 or vcount[v] > MAXF:
            continue
        c = vcount[v]
        st = vstart[v]
        for i in range(c):
            f = refs[st + i]
            for k in range(3):
                u = F[f, k]
                if u <= v:
                    continue
                cnt, extra = _edge_kind(F, flab, refs, st, c, u, multi)
                if not (cnt == 1 or extra):
                    continue
                # this edge is seen once per face containing it: emit only for face f itself
                if nc >= cap:
                    cap *= 2
                    ca2 = np.empty(cap, np.int32)
                    cb2 = np.empty(cap, np.int32)
                    cf2 = np.empty(cap, np.int32)
                    ca2[:nc] = ca[:nc]
                    cb2[:nc] = cb[:nc]
                    cf2[:nc] = cf[:nc]
                    ca, cb, cf = ca2, cb2, cf2
                ca[nc], cb[nc], cf[nc] = v, u, f
                nc += 1
    return ca[:nc], cb[:nc], cf[:nc]
