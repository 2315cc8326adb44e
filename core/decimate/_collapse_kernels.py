"""Numba kernels of the collapse sweeps (private to :mod:`anatomesh.core.decimate`).

The driver is :func:`anatomesh.core.decimate.engine.collapse`; it sets the state up, picks each
sweep's cost threshold and grows the vertex → face lists between kernel calls.

Edges are collapsed in sweeps over the faces under a rising cost threshold, each vertex at most
once per sweep: a spread-out, nearly independent set of cheap edges per sweep (multiple-choice
decimation in memory order, Wu & Kobbelt 2002, "Fast mesh decimation by multiple-choice
techniques"; Forstmann's fast quadric simplification), approximating the cheapest-first order of
Garland & Heckbert 1997 ("Surface simplification using quadric error metrics").

The arrays travel in named tuples:

* :data:`State` — ``V`` (N, 3) float64 centred positions, mm; ``Q`` (N, 10) float64 quadrics
  and ``W`` (N,) float64 the number of input vertices merged into each; ``F`` (M, 3) int32
  faces; ``FD`` (M, 8) float64 face rows, one 64-byte cache line per face:
  columns 0-2 the collapse cost of the face's 3 edges (a refused, *parked* edge stores
  ``-1 - cost`` until a collapse next to it), 3-5 the unit normal, 6 the quality; ``falive``
  (M,) bool; ``flab`` (M, 2) int32 dense labels on the two sides; ``vclass`` (N,) int8 (0 free,
  1 feature, 2 locked); ``ver`` (N,) int32 (-1 once merged away); ``vstamp`` (N,) int32 (the
  sweep that last moved the vertex);
* :data:`Refs` — the vertex → face lists ``refs``, ``vstart``, ``vcount``
  (:mod:`._refs_kernels`);
* :data:`Budget` — ``final_faces`` (stop there), per dense label ``lab_count`` faces now,
  ``lab_target`` faces to keep (-1: none), ``lab_maxerr`` error bound, ``lab_listed`` whether
  the label's budget applies, ``lab_whole`` whether its bound is on the whole quadric cost
  rather than the cost per merged vertex (the conservative fallback of a label the estimate let
  off its bound: the whole cost bounds every merged plane's squared distance);
  ``budgets`` whether any per-label limit exists. Error bounds
  (mm²) are on ``cost / W``, the quadric cost per
  merged input vertex (the sum of squared plane distances grows with the number of planes
  merged, not with the distance);
* :data:`Log` — the collapse record of a progressive mesh (Hoppe 1996, "Progressive meshes"):
  ``keep``, ``drop`` (C,) int32, ``where`` (C, 3) float64, ``face_death`` (M,) int32 (zero-length
  arrays record nothing), ``stop``: end the run when the log is full;
* :data:`Options` — ``multi`` (labelled faces), ``cos_max`` (cosine of the largest normal turn),
  ``q_min`` (quality limit).

``stats`` (11,) float64: [largest quadric cost accepted, largest ``cost / w`` accepted,
candidates checked, refusals: locked, star too large, label face budget, error bound, not a
feature edge, link condition, geometry (flip, degenerate face or sliver), then the collapses
saved by an endpoint placement].
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit, prange

from ._guard_kernels import face_frame, geometry_ok, is_feature_edge, link_ok
from ._quadric_kernels import FAST, INF, plan, qeval
from ._refs_kernels import MAXF, add_label, gather, has

State = namedtuple("State", ["V", "Q", "W", "F", "FD", "falive", "flab", "vclass", "ver",
                             "vstamp"])
Refs = namedtuple("Refs", ["refs", "vstart", "vcount"])
Budget = namedtuple("Budget", ["final_faces", "lab_count", "lab_target", "lab_maxerr",
                               "lab_listed", "lab_whole", "budgets"])
Log = namedtuple("Log", ["keep", "drop", "where", "face_death", "stop"])
Options = namedtuple("Options", ["multi", "cos_max", "q_min"])

# kernel exit codes
DONE = 0           # face target reached
STEP = 1           # sweep finished
REFS_FULL = 3      # vertex -> face lists need compacting

# stats slots
(MAX_COST, MAX_ERROR, CANDIDATES, LOCKED, STAR, BUDGET, ERROR, NOT_FEATURE, LINK, GEOMETRY,
 ENDPOINT) = range(11)
#: names of the refusal slots LOCKED .. GEOMETRY, in order
REFUSALS = ("locked", "star_too_large", "label_budget", "error_bound", "not_feature_edge",
            "link_condition", "geometry")


@njit(cache=True, inline="always")
def _twin_entry(vclass, u, w, multi):
    """True for the entry (u, w), u > w, of an edge whose twin (w, u) is stored in the other
    face: in a single surface every edge at a free vertex (one closed, consistently oriented
    fan) has exactly one such twin. These entries hold INF, so each edge is tried once."""
    return not multi and u > w and (vclass[u] == 0 or vclass[w] == 0)


@njit(parallel=True, cache=True)
def edge_costs(V, Q, F, vclass, FD, multi):
    """FD[f, k] = collapse cost of edge (F[f, k], F[f, k+1]); each interior edge of a single
    surface is stored once (see :func:`_twin_entry`), junction/boundary/multi-label edges in
    every face that has them."""
    m = F.shape[0]
    chunk = 4096
    for c in prange((m + chunk - 1) // chunk):
        q = np.empty(10)
        for f in range(c * chunk, min(m, (c + 1) * chunk)):
            for k in range(3):
                u, w = F[f, k], F[f, (k + 1) % 3]
                if _twin_entry(vclass, u, w, multi):
                    FD[f, k] = INF
                else:
                    FD[f, k] = plan(V, Q, vclass, u, w, q)[0]


@njit(cache=True)
def sample_costs(FD, falive, step):
    """Every ``step``-th finite, unparked edge cost of the live faces (to pick a threshold)."""
    m = FD.shape[0]
    out = np.empty(3 * (m // max(step, 1) + 1))
    n = 0
    for f in range(0, m, step):
        if falive[f]:
            for k in range(3):
                e = FD[f, k]
                if 0.0 <= e < INF:
                    out[n] = e
                    n += 1
    return out[:n]


@njit(cache=True, fastmath=FAST)
def collapse_pass(st, rf, bud, log, opt, live, stamp, tau, start, counts, stats, mark):
    """One sweep over the faces ``live[start:]`` collapsing every allowed edge with cost <= tau.

    A vertex that received a collapse is stamped (``stamp``) and not touched again in this
    sweep; the costs of the edges around it are refreshed at once, so no stored cost is ever
    stale. ``counts`` = (faces alive, used length of ``rf.refs``, collapses logged); ``mark``
    (N,) int64 scratch of the link test. Returns ``(code, nalive, nref, next_face, collapsed,
    nlog)``: code DONE (``bud.final_faces`` reached, or the log full with ``log.stop``), STEP
    (sweep finished) or REFS_FULL (resume at ``live[next_face]`` after compacting).
    """
    # the helpers take plain arrays: a named tuple passed to a call costs a reference count
    # update per member, and this loop runs once per candidate edge
    V, Q, W, F, FD, falive, flab, vclass, ver, vstamp = st
    refs, vstart, vcount = rf
    final, lab_count, lab_target, lab_maxerr, lab_listed, lab_whole, budgets = bud
    log_keep, log_drop, log_where, face_death, log_stop = log
    nalive, nref, nlog = counts
    fa, fb = np.empty(MAXF, np.int32), np.empty(MAXF, np.int32)
    labs, other = np.empty(2 * MAXF, np.int32), np.empty(3 * MAXF, np.int32)
    q, costs = np.empty(10), np.empty(3 * MAXF)
    token = mark.max() + 1
    collapsed = 0
    for i0 in range(start, live.shape[0]):
        f0 = live[i0]
        if not falive[f0]:
            continue
        for k0 in range(3):
            e0 = FD[f0, k0]
            if e0 < 0.0 or e0 > tau or not falive[f0]:
                continue
            a, b = F[f0, k0], F[f0, (k0 + 1) % 3]
            if vstamp[a] == stamp or vstamp[b] == stamp:
                continue
            if nalive <= final or (log_stop and nlog >= log_keep.shape[0]):
                return DONE, nalive, nref, i0, collapsed, nlog
            if nref + 2 * MAXF > refs.shape[0]:
                return REFS_FULL, nalive, nref, i0, collapsed, nlog
            stats[CANDIDATES] += 1
            # the tests, cheapest first; ``why`` is the stats slot of a refusal
            cost, keep, drop, px, py, pz = plan(V, Q, vclass, a, b, q)
            na, nb, why = _stars(refs, vstart, vcount, falive, keep, drop, fa, fb, cost)
            nl = _labels_around(flab, fa, na, fb, nb, labs, why == 0 and (opt.multi or budgets))
            w = W[keep] + W[drop] if budgets else 1.0     # merged vertices: error bounds
            if why == 0:
                why = _budget(lab_count, lab_target, lab_maxerr, lab_listed, lab_whole, labs, nl,
                              cost, w)
            if why == 0:
                why, token = _topology(F, flab, vclass, opt.multi, fa, na, fb, nb, keep, drop,
                                       labs, nl, mark, token)
            if why == 0:
                why, cost, px, py, pz = _placement(V, F, FD, vclass, opt, fa, na, fb, nb, keep,
                                                   drop, cost, px, py, pz, tau, lab_maxerr,
                                                   lab_whole, w, labs, nl, q, stats)
            if why != 0:
                stats[why] += 1
                FD[f0, k0] = -1.0 - e0        # refused: parked until a collapse next to it
                continue
            stats[MAX_COST] = max(stats[MAX_COST], cost)
            stats[MAX_ERROR] = max(stats[MAX_ERROR], cost / w)
            _move(V, Q, W, keep, drop, px, py, pz, budgets)
            nalive -= _remove_faces(F, falive, flab, lab_count, face_death,
                                    nlog < log_keep.shape[0], nlog, keep, drop, fb, nb)
            first = nref
            nref = _append_refs(refs, vstart, vcount, falive, keep, fa, na, fb, nb, nref)
            ver[drop] = -1
            vstamp[keep] = stamp
            nlog = _record(log_keep, log_drop, log_where, nlog, keep, drop, px, py, pz)
            collapsed += 1
            _refresh_costs(V, Q, F, FD, vclass, refs, first, nref, keep, q, other, costs,
                           opt.multi)
    return STEP, nalive, nref, live.shape[0], collapsed, nlog


# ---------------------------------------------------------------------------------------------
# the tests of one edge
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _stars(refs, vstart, vcount, falive, keep, drop, fa, fb, cost):
    """The live faces of ``keep`` into ``fa`` and of ``drop`` into ``fb``: ``(na, nb, why)``,
    ``why`` LOCKED for an infinite cost (a locked endpoint), STAR when they are over ``MAXF``."""
    if cost == INF:
        return 0, 0, LOCKED
    na = gather(refs, vstart, vcount, falive, keep, fa)
    nb = gather(refs, vstart, vcount, falive, drop, fb)
    if na < 0 or nb < 0 or na + nb > MAXF:
        return 0, 0, STAR
    return na, nb, 0


@njit(cache=True)
def _labels_around(flab, fa, na, fb, nb, labs, wanted):
    """The distinct labels of the faces ``fa[:na]``, ``fb[:nb]`` into ``labs``; their count
    (0 when not ``wanted``)."""
    nl = 0
    for i in range(na + nb if wanted else 0):
        f = fa[i] if i < na else fb[i - na]
        for s in range(2):
            nl = add_label(labs, nl, flab[f, s])
    return nl


@njit(cache=True, inline="always")
def _over_error(lab_maxerr, lab_whole, lab, cost, w):
    """True when ``cost`` (``w`` input vertices merged) is over label ``lab``'s error bound: on
    ``cost / w``, or on the whole cost for a ``lab_whole`` label."""
    return cost > lab_maxerr[lab] * (1.0 if lab_whole[lab] else w)


@njit(cache=True, fastmath=FAST)
def _budget(lab_count, lab_target, lab_maxerr, lab_listed, lab_whole, labs, nl, cost, w):
    """ERROR when the error estimate ``cost / w`` (``w`` input vertices merged) is over the
    bound of a label around the edge; BUDGET unless some label around the edge is listed and
    none has reached its face target; else 0."""
    listed = nl == 0
    for j in range(nl):
        lab = labs[j]
        listed = listed or lab_listed[lab]
        if lab_count[lab] <= lab_target[lab]:
            return BUDGET
        if _over_error(lab_maxerr, lab_whole, lab, cost, w):
            return ERROR
    return 0 if listed else BUDGET


@njit(cache=True)
def _topology(F, flab, vclass, multi, fa, na, fb, nb, keep, drop, labs, nl, mark, token):
    """NOT_FEATURE for an edge joining two feature vertices off their feature curve, LINK when
    the link condition fails on a shell around the edge (one test for a single surface or two
    free vertices), else 0; and the next unused ``mark`` token."""
    if vclass[keep] == 1 and vclass[drop] == 1 and not is_feature_edge(F, flab, fb, nb, keep,
                                                                      multi):
        return NOT_FEATURE, token
    if not multi or (vclass[keep] == 0 and vclass[drop] == 0):
        token += 3
        return (0 if link_ok(F, flab, fa, na, fb, nb, keep, drop, -1, mark, token) else LINK), token
    for j in range(nl):
        token += 3
        if not link_ok(F, flab, fa, na, fb, nb, keep, drop, labs[j], mark, token):
            return LINK, token
    return 0, token


@njit(cache=True, fastmath=FAST)
def _placement(V, F, FD, vclass, opt, fa, na, fb, nb, keep, drop, cost, px, py, pz, tau,
               lab_maxerr, lab_whole, w, labs, nl, q, stats):
    """The geometric tests at the planned point; when it flips or slivers a face, the two
    endpoints are tried (subset placement, Garland & Heckbert 1997) while they cost no more than
    ``tau`` and stay within the labels' error bounds (``w`` merged vertices). Returns
    ``(why, cost, x, y, z)``, ``why`` GEOMETRY or 0."""
    cos_max, q_min = opt.cos_max, opt.q_min
    if geometry_ok(V, F, FD, fa, na, keep, drop, px, py, pz, cos_max, q_min) \
            and geometry_ok(V, F, FD, fb, nb, keep, drop, px, py, pz, cos_max, q_min):
        return 0, cost, px, py, pz
    if vclass[keep] != 0 or vclass[drop] != 0:
        return GEOMETRY, cost, px, py, pz
    for alt in range(2):
        u = keep if alt == 0 else drop
        x, y, z = V[u, 0], V[u, 1], V[u, 2]
        c2 = max(qeval(q, x, y, z), 0.0)
        if c2 > tau:
            continue
        within = True
        for j in range(nl):
            if _over_error(lab_maxerr, lab_whole, labs[j], c2, w):
                within = False
        if within and geometry_ok(V, F, FD, fa, na, keep, drop, x, y, z, cos_max, q_min) \
                and geometry_ok(V, F, FD, fb, nb, keep, drop, x, y, z, cos_max, q_min):
            stats[ENDPOINT] += 1
            return 0, c2, x, y, z
    return GEOMETRY, cost, px, py, pz


# ---------------------------------------------------------------------------------------------
# one collapse
# ---------------------------------------------------------------------------------------------
@njit(cache=True, fastmath=FAST)
def _move(V, Q, W, keep, drop, px, py, pz, counted):
    """``keep`` moves to (px, py, pz) and takes ``drop``'s quadric (and its merged-vertex count
    when ``counted``: error bounds are checked)."""
    V[keep, 0], V[keep, 1], V[keep, 2] = px, py, pz
    for i in range(10):
        Q[keep, i] += Q[drop, i]
    if counted:
        W[keep] += W[drop]


@njit(cache=True)
def _remove_faces(F, falive, flab, lab_count, face_death, record, nlog, keep, drop, fb, nb):
    """Of ``drop``'s faces ``fb[:nb]``, those on the edge die (``face_death`` = ``nlog`` when
    ``record``), the others take ``keep`` for ``drop``; returns the number removed."""
    removed = 0
    for i in range(nb):
        f = fb[i]
        if has(f, F, keep):
            falive[f] = False
            removed += 1
            if record and face_death.shape[0] > 0:
                face_death[f] = nlog
            lab_count[flab[f, 0]] -= 1
            lab_count[flab[f, 1]] -= 1
        else:
            for k in range(3):
                if F[f, k] == drop:
                    F[f, k] = keep
    return removed


@njit(cache=True)
def _append_refs(refs, vstart, vcount, falive, keep, fa, na, fb, nb, nref):
    """``keep``'s new face list (its live faces and ``drop``'s) appended at ``refs[nref:]``;
    returns the new used length."""
    first = nref
    for i in range(na + nb):
        f = fa[i] if i < na else fb[i - na]
        if falive[f]:
            refs[nref] = f
            nref += 1
    vstart[keep] = first
    vcount[keep] = nref - first
    return nref


@njit(cache=True)
def _record(log_keep, log_drop, log_where, nlog, keep, drop, px, py, pz):
    """Log collapse ``nlog`` while the log has room; returns the new count."""
    if nlog >= log_keep.shape[0]:
        return nlog
    log_keep[nlog] = keep
    log_drop[nlog] = drop
    if log_where.shape[0] > 0:
        log_where[nlog, 0], log_where[nlog, 1], log_where[nlog, 2] = px, py, pz
    return nlog + 1


@njit(cache=True, fastmath=FAST)
def _refresh_costs(V, Q, F, FD, vclass, refs, first, nref, keep, q, other, costs, multi):
    """New normals, qualities and edge costs of the faces ``refs[first:nref]`` around the merged
    vertex ``keep`` (each distinct edge planned once; ``other``, ``costs`` scratch); the edges
    opposite ``keep`` are un-parked (a refusal may no longer hold)."""
    nn = 0
    for i in range(first, nref):
        g = refs[i]
        face_frame(V, F, g, FD)
        for k in range(3):
            u, w = F[g, k], F[g, (k + 1) % 3]
            if u != keep and w != keep:
                if FD[g, k] < 0.0:
                    FD[g, k] = -1.0 - FD[g, k]
                continue
            o = w if u == keep else u
            found = False
            c = INF
            for j in range(nn):
                if other[j] == o:
                    c = costs[j]
                    found = True
                    break
            if not found:
                c = plan(V, Q, vclass, keep, o, q)[0]
                other[nn] = o
                costs[nn] = c
                nn += 1
            FD[g, k] = INF if _twin_entry(vclass, u, w, multi) else c
