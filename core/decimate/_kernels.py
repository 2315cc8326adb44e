"""Numba kernels for quadric edge-collapse decimation (private).

The public wrapper is :mod:`anatomesh.core.decimate.qem`; it validates inputs, classifies vertices and
owns the Python loop that grows arrays and reports progress between kernel calls.

Data layout (arrays only, no half-edges):

* ``V`` (N, 3) float64 positions (centred), ``Q`` (N, 10) float64 quadrics
  ``[a², ab, ac, ad, b², bc, bd, c², cd, d²]`` (Garland & Heckbert 1997);
* ``F`` (M, 3) int32 faces, ``falive`` (M,) bool, ``flab`` (M, 2) int32 labels on the two sides;
* vertex → faces with lazy deletion: the faces of vertex ``v`` are
  ``refs[vstart[v]:vstart[v] + vcount[v]]`` (some may be dead); a collapse appends the survivor's
  new list at the end of ``refs`` (Forstmann-style), compacted when full;
* ``FD`` (M, 8) float64, one 64-byte row per face (one cache line: the collapse loop touches
  a face's costs, normal and quality together): columns 0-2 the collapse cost of the face's 3
  edges (a refused, *parked* edge stores ``-1 - cost`` until a collapse next to it), 3-5 the
  unit normal, 6 the quality; costs are refreshed around every merged vertex and sweeps over the
  faces collapse the edges under a rising threshold.

``vclass``: 0 free, 1 feature (junction of 3+ labels, or open boundary: moves only along its
curve), 2 locked (never moves, no edge touching it collapses).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

MAXF = 96          # faces around an edge's two endpoints; larger stars are not collapsed
#: fast-math flags for the geometry of the collapse loop: reassociation, FMA contraction and
#: reciprocals, but inf/NaN kept IEEE (costs use INF); results stay deterministic
FAST = {"nsz", "arcp", "contract", "afn", "reassoc"}
INF = np.inf

# kernel exit codes
DONE = 0           # face target reached
STEP = 1           # sweep finished
REFS_FULL = 3      # vertex -> face lists need compacting


@njit(cache=True, inline="always")
def _add_label(labs, nl, lab):
    """Append ``lab`` to ``labs[:nl]`` unless it is there already; returns the new count."""
    for j in range(nl):
        if labs[j] == lab:
            return nl
    labs[nl] = lab
    return nl + 1


# ---------------------------------------------------------------------------------------------
# quadrics
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _add_plane(Q, v, nx, ny, nz, d, w):
    Q[v, 0] += w * nx * nx
    Q[v, 1] += w * nx * ny
    Q[v, 2] += w * nx * nz
    Q[v, 3] += w * nx * d
    Q[v, 4] += w * ny * ny
    Q[v, 5] += w * ny * nz
    Q[v, 6] += w * ny * d
    Q[v, 7] += w * nz * nz
    Q[v, 8] += w * nz * d
    Q[v, 9] += w * d * d


@njit(cache=True)
def build_quadrics(V, F, cons_a, cons_b, cons_f):
    """Per-vertex quadrics: the unit-weight plane of every face at its 3 vertices, plus for each
    feature edge ``(cons_a[i], cons_b[i])`` a constraint plane through the edge, perpendicular to
    face ``cons_f[i]`` (keeps junction curves and boundaries in place, in mm)."""
    n = V.shape[0]
    Q = np.zeros((n, 10))
    for f in range(F.shape[0]):
        i, j, k = F[f, 0], F[f, 1], F[f, 2]
        ux, uy, uz = V[j, 0] - V[i, 0], V[j, 1] - V[i, 1], V[j, 2] - V[i, 2]
        wx, wy, wz = V[k, 0] - V[i, 0], V[k, 1] - V[i, 1], V[k, 2] - V[i, 2]
        nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
        ln = np.sqrt(nx * nx + ny * ny + nz * nz)
        if ln <= 1e-30:
            continue
        nx, ny, nz = nx / ln, ny / ln, nz / ln
        d = -(nx * V[i, 0] + ny * V[i, 1] + nz * V[i, 2])
        _add_plane(Q, i, nx, ny, nz, d, 1.0)
        _add_plane(Q, j, nx, ny, nz, d, 1.0)
        _add_plane(Q, k, nx, ny, nz, d, 1.0)
    for e in range(cons_a.shape[0]):
        a, b, f = cons_a[e], cons_b[e], cons_f[e]
        i, j, k = F[f, 0], F[f, 1], F[f, 2]
        ux, uy, uz = V[j, 0] - V[i, 0], V[j, 1] - V[i, 1], V[j, 2] - V[i, 2]
        wx, wy, wz = V[k, 0] - V[i, 0], V[k, 1] - V[i, 1], V[k, 2] - V[i, 2]
        nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
        ex, ey, ez = V[b, 0] - V[a, 0], V[b, 1] - V[a, 1], V[b, 2] - V[a, 2]
        mx, my, mz = ey * nz - ez * ny, ez * nx - ex * nz, ex * ny - ey * nx
        lm = np.sqrt(mx * mx + my * my + mz * mz)
        if lm <= 1e-30:
            continue
        mx, my, mz = mx / lm, my / lm, mz / lm
        d = -(mx * V[a, 0] + my * V[a, 1] + mz * V[a, 2])
        _add_plane(Q, a, mx, my, mz, d, 1.0)
        _add_plane(Q, b, mx, my, mz, d, 1.0)
    return Q


@njit(cache=True, fastmath=FAST)
def _qeval(q, x, y, z):
    return (q[0] * x * x + 2 * q[1] * x * y + 2 * q[2] * x * z + 2 * q[3] * x
            + q[4] * y * y + 2 * q[5] * y * z + 2 * q[6] * y
            + q[7] * z * z + 2 * q[8] * z + q[9])


@njit(cache=True, fastmath=FAST)
def _plan(V, Q, vclass, a, b, q):
    """Where to put the merged vertex of edge (a, b) and what it costs.

    Returns ``(cost, keep, drop, x, y, z)``; cost is ``inf`` for a forbidden edge. ``q`` is a
    scratch (10,) array receiving Q[a] + Q[b].
    """
    ca, cb = vclass[a], vclass[b]
    if ca == 2 or cb == 2:
        return INF, a, b, 0.0, 0.0, 0.0
    for i in range(10):
        q[i] = Q[a, i] + Q[b, i]
    if ca == 1 and cb == 0:          # free vertex b slides into fixed feature vertex a
        x, y, z = V[a, 0], V[a, 1], V[a, 2]
        return max(_qeval(q, x, y, z), 0.0), a, b, x, y, z
    if cb == 1 and ca == 0:
        x, y, z = V[b, 0], V[b, 1], V[b, 2]
        return max(_qeval(q, x, y, z), 0.0), b, a, x, y, z
    if ca == 1:
        # along a junction curve (or open boundary): stay at the cheaper endpoint, so junction
        # vertices remain points of the original junction polyline
        ca_ = max(_qeval(q, V[a, 0], V[a, 1], V[a, 2]), 0.0)
        cb_ = max(_qeval(q, V[b, 0], V[b, 1], V[b, 2]), 0.0)
        if ca_ <= cb_:
            return ca_, a, b, V[a, 0], V[a, 1], V[a, 2]
        return cb_, b, a, V[b, 0], V[b, 1], V[b, 2]
    keep, drop = (a, b) if a < b else (b, a)
    ax, ay, az = V[a, 0], V[a, 1], V[a, 2]
    dx, dy, dz = V[b, 0] - ax, V[b, 1] - ay, V[b, 2] - az
    # optimal placement: solve A p = -b (3x3, Cramer) when well conditioned
    a00, a01, a02, a11, a12, a22 = q[0], q[1], q[2], q[4], q[5], q[7]
    b0, b1, b2 = -q[3], -q[6], -q[8]
    c00 = a11 * a22 - a12 * a12
    c01 = a02 * a12 - a01 * a22
    c02 = a01 * a12 - a02 * a11
    det = a00 * c00 + a01 * c01 + a02 * c02
    tr = (a00 + a11 + a22) / 3.0
    if abs(det) > 1e-3 * tr * tr * tr:
        c11 = a00 * a22 - a02 * a02
        c12 = a01 * a02 - a00 * a12
        c22 = a00 * a11 - a01 * a01
        x = (c00 * b0 + c01 * b1 + c02 * b2) / det
        y = (c01 * b0 + c11 * b1 + c12 * b2) / det
        z = (c02 * b0 + c12 * b1 + c22 * b2) / det
        # stay near the edge: a far optimum signals a near-singular system
        mx, my, mz = x - (ax + 0.5 * dx), y - (ay + 0.5 * dy), z - (az + 0.5 * dz)
        if mx * mx + my * my + mz * mz <= 4.0 * (dx * dx + dy * dy + dz * dz):
            return max(_qeval(q, x, y, z), 0.0), keep, drop, x, y, z
    # ill conditioned: minimise along the segment a + t (b - a), t in [0, 1]
    adx = q[0] * dx + q[1] * dy + q[2] * dz
    ady = q[1] * dx + q[4] * dy + q[5] * dz
    adz = q[2] * dx + q[5] * dy + q[7] * dz
    dad = adx * dx + ady * dy + adz * dz
    t = 0.5
    if dad > 1e-300:
        t = -(adx * ax + ady * ay + adz * az + q[3] * dx + q[6] * dy + q[8] * dz) / dad
        t = min(1.0, max(0.0, t))
    x, y, z = ax + t * dx, ay + t * dy, az + t * dz
    return max(_qeval(q, x, y, z), 0.0), keep, drop, x, y, z


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
                nl = _add_label(labs, nl, flab[f, s])
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


# ---------------------------------------------------------------------------------------------
# refs (vertex -> faces)
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def initial_refs(F, n_vertices, extra):
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


# ---------------------------------------------------------------------------------------------
# collapse checks
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _gather(refs, vstart, vcount, falive, v, out):
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
def _has(f, F, v):
    return F[f, 0] == v or F[f, 1] == v or F[f, 2] == v


@njit(cache=True)
def _in_shell(flab, f, lab):
    return lab < 0 or flab[f, 0] == lab or flab[f, 1] == lab


@njit(cache=True)
def _link_ok(F, flab, fa, na, fb, nb, a, b, lab, mark, token):
    """Link condition (Dey et al. 1999) on the shell of label ``lab`` (all faces if lab < 0):
    the vertices adjacent to both a and b are exactly the apexes of the faces on edge ab; plus
    the shell keeps >= 3 faces at the merged vertex (no tetrahedron collapse).

    ``mark`` (N,) int64 scratch, ``token`` a value never used in it before (and token + 1, + 2):
    neighbours of a get token, common neighbours token + 1, apexes of ab token + 2 — O(degree).
    """
    t_a, t_common, t_apex = token, token + 1, token + 2
    sa = 0
    for i in range(na):
        f = fa[i]
        if not _in_shell(flab, f, lab):
            continue
        sa += 1
        for k in range(3):
            v = F[f, k]
            if v != a and v != b:
                mark[v] = t_a
    sb = 0
    nab = 0
    napex = 0
    common = 0
    for i in range(nb):
        f = fb[i]
        if not _in_shell(flab, f, lab):
            continue
        sb += 1
        if _has(f, F, a):
            nab += 1
            for k in range(3):
                v = F[f, k]
                if v != a and v != b:
                    if mark[v] == t_apex:
                        return False          # two faces on ab with the same apex
                    if mark[v] == t_common:
                        common -= 1           # counted as common before; recount below
                    elif mark[v] != t_a:
                        return False          # apex not a neighbour of a: broken fan
                    mark[v] = t_apex
                    napex += 1
                    common += 1
        else:
            for k in range(3):
                v = F[f, k]
                if v != a and v != b and mark[v] == t_a:
                    mark[v] = t_common
                    common += 1
    if sa == 0 or sb == 0:
        return True          # only one endpoint on this shell: a plain vertex move for it
    if nab == 0 or nab > 2:
        return False         # endpoints on the shell but not joined by a manifold shell edge
    if common != napex:
        return False
    return sa + sb - 2 * nab >= 3


@njit(cache=True, fastmath=FAST)
def _corner(V, v, keep, drop, px, py, pz, use_p):
    if use_p and (v == keep or v == drop):
        return px, py, pz
    return V[v, 0], V[v, 1], V[v, 2]


@njit(cache=True, fastmath=FAST)
def _tri_normal(V, F, f, keep, drop, px, py, pz, use_p):
    """Unnormalised normal of face f and its summed squared edge lengths, with ``keep`` and
    ``drop`` moved to p when ``use_p``."""
    x0, y0, z0 = _corner(V, F[f, 0], keep, drop, px, py, pz, use_p)
    x1, y1, z1 = _corner(V, F[f, 1], keep, drop, px, py, pz, use_p)
    x2, y2, z2 = _corner(V, F[f, 2], keep, drop, px, py, pz, use_p)
    ux, uy, uz = x1 - x0, y1 - y0, z1 - z0
    wx, wy, wz = x2 - x0, y2 - y0, z2 - z0
    vx, vy, vz = x2 - x1, y2 - y1, z2 - z1
    nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
    l2 = ux * ux + uy * uy + uz * uz + wx * wx + wy * wy + wz * wz + vx * vx + vy * vy + vz * vz
    return nx, ny, nz, l2


@njit(cache=True, fastmath=FAST)
def _face_frame(V, F, f, FD):
    """Store the unit normal (FD[f, 3:6]) and quality 2√3|n|/Σl² (FD[f, 6]) of face f (zeros
    when degenerate)."""
    nx, ny, nz, l2 = _tri_normal(V, F, f, -1, -1, 0.0, 0.0, 0.0, False)
    a = np.sqrt(nx * nx + ny * ny + nz * nz)
    if a > 0.0 and l2 > 0.0:
        FD[f, 3], FD[f, 4], FD[f, 5] = nx / a, ny / a, nz / a
        FD[f, 6] = 3.4641016151377544 * a / l2
    else:
        FD[f, 3], FD[f, 4], FD[f, 5] = 0.0, 0.0, 0.0
        FD[f, 6] = 0.0


@njit(parallel=True, cache=True)
def face_frames(V, F):
    """The face rows FD (M, 8): unit normals and qualities of all faces (see
    :func:`_face_frame`), edge costs zero (filled by :func:`edge_costs`)."""
    m = F.shape[0]
    FD = np.zeros((m, 8))
    for f in prange(m):
        _face_frame(V, F, f, FD)
    return FD


@njit(cache=True, fastmath=FAST)
def _geometry_ok(V, F, FD, fl, nf, keep, drop, px, py, pz, cos_max, q_min):
    """No face flips by more than acos(cos_max), none becomes degenerate, none becomes a sliver
    with quality 2√3|n|/Σl² (1 = equilateral) below min(q_min, its quality before).
    ``FD[:, 3:7]``: the faces' current unit normals and qualities."""
    for i in range(nf):
        f = fl[i]
        if _has(f, F, keep) and _has(f, F, drop):
            continue          # removed by the collapse
        n1x, n1y, n1z, l1 = _tri_normal(V, F, f, keep, drop, px, py, pz, True)
        a1 = np.sqrt(n1x * n1x + n1y * n1y + n1z * n1z)
        if a1 <= 1e-12 * l1 or l1 <= 0.0:
            return False
        q0 = FD[f, 6]
        if FD[f, 3] * n1x + FD[f, 4] * n1y + FD[f, 5] * n1z < cos_max * a1 and q0 > 0.0:
            return False
        q1 = 3.4641016151377544 * a1 / l1
        if q1 < q_min and q1 < q0:
            return False
    return True


@njit(cache=True)
def _is_feature_edge(F, flab, fb, nb, a, multi):
    """An edge on a junction curve (its faces carry 3+ labels) or an open boundary."""
    cnt = 0
    l0 = -1
    l1 = -1
    n_extra = 0
    for i in range(nb):
        f = fb[i]
        if not _has(f, F, a):
            continue
        cnt += 1
        if multi:
            for s in range(2):
                lab = flab[f, s]
                if l0 < 0 or lab == l0:
                    l0 = lab
                elif l1 < 0 or lab == l1:
                    l1 = lab
                else:
                    n_extra += 1
    return cnt != 2 or n_extra > 0


# ---------------------------------------------------------------------------------------------
# edge costs and the collapse passes
# ---------------------------------------------------------------------------------------------
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
                    FD[f, k] = _plan(V, Q, vclass, u, w, q)[0]


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
def collapse_pass(live, V, Q, F, falive, flab, vclass, ver, refs, vstart, vcount, nref, FD, vstamp,
                  stamp, tau, start, nalive, final_faces, lab_count, lab_target, lab_maxcost,
                  lab_listed, budgets, multi, cos_max, q_min, log_a, log_b, log_p, fdeath, log_stop,
                  nlog, stats, mark):
    """One sweep over the faces ``live[start:]`` collapsing every allowed edge with cost <= tau.

    A vertex that received a collapse is stamped and not touched again in this sweep, so one
    sweep collapses a spread-out, nearly independent set of cheap edges (multiple-choice
    decimation in memory order, after Wu & Kobbelt 2002 / Forstmann's fast QEM); thresholds rise
    from sweep to sweep, approximating the cheapest-first order. Costs of the edges around a
    merged vertex are refreshed at once, so no stored cost is ever stale.

    Per label (dense index): ``lab_count`` faces now, ``lab_target`` faces to keep, ``lab_maxcost``
    quadric bound, ``lab_listed`` whether the label's budget applies (an edge collapses only if a
    label around it is listed and none is exhausted). Returns ``(code, nalive, nref, next_face,
    collapsed, nlog)``: code DONE (``final_faces`` reached), STEP (sweep finished) or REFS_FULL
    (resume at live[next_face] after compacting). ``FD`` holds the edge costs (negative:
    parked, refused until a collapse next to it), unit normals and qualities of the faces;
    ``mark`` is scratch for the link test.
    Collapse log (levels of detail, :mod:`anatomesh.core.decimate.progressive`): while room lasts, collapse ``i``
    (``i = nlog``) is recorded as ``log_a[i] = keep``, ``log_b[i] = drop``, ``log_p[i]`` = the
    merged vertex's new position, and every face it removes gets ``fdeath[face] = i`` (pass
    zero-length arrays to record nothing). With ``log_stop`` the pass returns DONE once the log is
    full (the state after exactly ``len(log_a)`` collapses). ``stats`` (9,) float64 = [largest
    quadric cost accepted, candidates checked, then refusals: forbidden (locked), star too large,
    label budget, not a junction edge, link condition, all refusals at the link/geometry stage,
    and last the collapses saved by an endpoint placement].
    """
    fa = np.empty(MAXF, np.int32)
    fb = np.empty(MAXF, np.int32)
    buf_a = np.empty(3 * MAXF, np.int32)
    labs = np.empty(2 * MAXF, np.int32)
    costs = np.empty(3 * MAXF)
    token = mark.max() + 1
    q = np.empty(10)
    cap_r = refs.shape[0]
    m = live.shape[0]
    collapsed = 0
    for i0 in range(start, m):
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
            if nalive <= final_faces or (log_stop and nlog >= log_a.shape[0]):
                return DONE, nalive, nref, i0, collapsed, nlog
            if nref + 2 * MAXF > cap_r:
                return REFS_FULL, nalive, nref, i0, collapsed, nlog
            stats[1] += 1
            cost, keep, drop, px, py, pz = _plan(V, Q, vclass, a, b, q)
            if cost == INF:
                stats[2] += 1
                FD[f0, k0] = -1.0 - e0
                continue
            na = _gather(refs, vstart, vcount, falive, keep, fa)
            nb = _gather(refs, vstart, vcount, falive, drop, fb)
            if na < 0 or nb < 0 or na + nb > MAXF:
                stats[3] += 1
                FD[f0, k0] = -1.0 - e0
                continue
            # per-label budgets: every label on the faces around the edge must still allow it
            nl = 0
            for i in range(na + nb if (multi or budgets) else 0):
                f = fa[i] if i < na else fb[i - na]
                for s in range(2):
                    nl = _add_label(labs, nl, flab[f, s])
            blocked = False
            listed = nl == 0
            for j in range(nl):
                lab = labs[j]
                listed = listed or lab_listed[lab]
                if lab_count[lab] <= lab_target[lab] or cost > lab_maxcost[lab]:
                    blocked = True
                    break
            if blocked or not listed:
                stats[4] += 1
                FD[f0, k0] = -1.0 - e0
                continue
            if vclass[keep] == 1 and vclass[drop] == 1:
                if not _is_feature_edge(F, flab, fb, nb, keep, multi):
                    stats[5] += 1
                    FD[f0, k0] = -1.0 - e0
                    continue
            # topology first (O(degree) with marks), then geometry (normals and qualities)
            ok = True
            if not multi or (vclass[keep] == 0 and vclass[drop] == 0):
                token += 3
                ok = _link_ok(F, flab, fa, na, fb, nb, keep, drop, -1, mark, token)
            else:
                for j in range(nl):
                    token += 3
                    if not _link_ok(F, flab, fa, na, fb, nb, keep, drop, labs[j], mark, token):
                        ok = False
                        break
            if not ok:
                stats[6] += 1
            else:
                ok = _geometry_ok(V, F, FD, fa, na, keep, drop, px, py, pz, cos_max, q_min) \
                    and _geometry_ok(V, F, FD, fb, nb, keep, drop, px, py, pz, cos_max, q_min)
                if not ok and vclass[keep] == 0 and vclass[drop] == 0:
                    # the optimal point flips or slivers a face: try the two endpoints (subset
                    # placement, Garland & Heckbert 1997) while they cost no more than allowed
                    for alt in range(2):
                        w = keep if alt == 0 else drop
                        x, y, z = V[w, 0], V[w, 1], V[w, 2]
                        c2 = max(_qeval(q, x, y, z), 0.0)
                        if c2 > tau:
                            continue
                        within = True
                        for j in range(nl):
                            if c2 > lab_maxcost[labs[j]]:
                                within = False
                        if within and _geometry_ok(V, F, FD, fa, na, keep, drop, x, y, z, cos_max,
                                                   q_min) \
                                and _geometry_ok(V, F, FD, fb, nb, keep, drop, x, y, z, cos_max,
                                                 q_min):
                            ok = True
                            cost, px, py, pz = c2, x, y, z
                            stats[8] += 1
                            break
            if not ok:
                stats[7] += 1
                # refused: parked until a collapse next to it un-parks it
                FD[f0, k0] = -1.0 - e0
                continue
            # --- collapse drop -> keep
            stats[0] = max(stats[0], cost)
            V[keep, 0], V[keep, 1], V[keep, 2] = px, py, pz
            for i in range(10):
                Q[keep, i] += Q[drop, i]
            record = nlog < log_a.shape[0]
            for i in range(nb):
                f = fb[i]
                if _has(f, F, keep):
                    falive[f] = False
                    nalive -= 1
                    if record and fdeath.shape[0] > 0:
                        fdeath[f] = nlog
                    lab_count[flab[f, 0]] -= 1
                    lab_count[flab[f, 1]] -= 1
                else:
                    for k in range(3):
                        if F[f, k] == drop:
                            F[f, k] = keep
            first = nref
            for i in range(na):
                if falive[fa[i]]:
                    refs[nref] = fa[i]
                    nref += 1
            for i in range(nb):
                if falive[fb[i]]:
                    refs[nref] = fb[i]
                    nref += 1
            vstart[keep] = first
            vcount[keep] = nref - first
            ver[drop] = -1
            vstamp[keep] = stamp
            collapsed += 1
            if record:
                log_a[nlog] = keep
                log_b[nlog] = drop
                if log_p.shape[0] > 0:
                    log_p[nlog, 0], log_p[nlog, 1], log_p[nlog, 2] = px, py, pz
                nlog += 1
            # refresh the costs of the edges at the merged vertex (each distinct edge once)
            nn = 0
            for i in range(first, nref):
                g = refs[i]
                _face_frame(V, F, g, FD)
                for k in range(3):
                    u, w = F[g, k], F[g, (k + 1) % 3]
                    if u != keep and w != keep:
                        # the edge opposite the merged vertex: its cost is unchanged, but a
                        # refusal may no longer hold; un-park it
                        if FD[g, k] < 0.0:
                            FD[g, k] = -1.0 - FD[g, k]
                        continue
                    o = w if u == keep else u
                    found = False
                    c = INF
                    for j in range(nn):
                        if buf_a[j] == o:
                            c = costs[j]
                            found = True
                            break
                    if not found:
                        c = _plan(V, Q, vclass, keep, o, q)[0]
                        buf_a[nn] = o
                        costs[nn] = c
                        nn += 1
                    FD[g, k] = INF if _twin_entry(vclass, u, w, multi) else c
    return STEP, nalive, nref, m, collapsed, nlog


# ---------------------------------------------------------------------------------------------
# levels of detail: replaying a prefix of the collapse log
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def replay_collapses(keep, drop, where, count, V):
    """The vertex map and positions after the first ``count`` logged collapses.

    ``keep``/``drop`` (C,) int32 and ``where`` (C, 3) float64: collapse ``i`` merged ``drop``
    into ``keep`` and moved ``keep`` to ``where[i]``. ``V`` (N, 3) float64 positions before any
    collapse. Returns ``rep`` (N,) int64 — the vertex each input vertex has become (itself when
    it survives) — and the positions (N, 3) float64 (exactly the values the collapse run stored).
    """
    n = V.shape[0]
    rep = np.arange(n)
    P = V.copy()
    for i in range(count):
        k = keep[i]
        P[k, 0], P[k, 1], P[k, 2] = where[i, 0], where[i, 1], where[i, 2]
    # backwards: when drop[i] merged into keep[i], keep[i] was alive; its own fate is decided by
    # later collapses, already resolved
    for i in range(count - 1, -1, -1):
        rep[drop[i]] = rep[keep[i]]
    return rep, P


@njit(cache=True)
def bounds(V):
    """Bounding box of (N, 3) positions in one pass: (lo (3,), hi (3,), all finite)."""
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    finite = True
    for i in range(V.shape[0]):
        for j in range(3):
            x = V[i, j]
            if not np.isfinite(x):
                finite = False
            if x < lo[j]:
                lo[j] = x
            if x > hi[j]:
                hi[j] = x
    return lo, hi, finite
