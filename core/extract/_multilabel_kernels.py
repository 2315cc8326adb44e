"""Numba kernels for :func:`anatomesh.core.extract.multilabel.label_surfaces` (private).

All kernels work on ``P``: the cropped label map padded with one layer of background on every
side, ``uint8`` or ``uint16``, shape (n0, n1, n2). Lattice point (a, b, c) of ``P`` is the corner
shared by voxels (a-1..a, b-1..b, c-1..c); used points have a, b, c >= 1. Work is split by
lattice planes ``a`` (the outermost axis in C order): count per plane, prefix sums, then fill —
so the output does not depend on the number of threads. Only ``count`` and ``emit`` are parallel
(small maps run ``count_serial`` and one :func:`emit_run` on one thread instead);
the other passes are cheap (memory-bound or sparse) and starting a parallel region costs more
than it saves there when other processes share the cores.

Hot loops avoid short-circuit boolean chains, array views and non-inlined calls: in numba these
cost reference counting or a real call per element.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange


# ---------------------------------------------------------------------------------------------
# scan and crop
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def bounding_box(data, bg, lut, use_lut, box, out):
    """The inclusive index box (i0, i1, j0, j1, k0, k1) of the voxels that are not ``bg`` (or,
    when ``use_lut``, whose ``lut[value]`` is non-zero) into ``out`` (6,) int64; i0 > i1 when
    there are none. ``box`` is (n0, 4) int64 scratch (the arrays come from the caller: a kernel
    that allocates none compiles faster, the first run after install)."""
    n0, n1, n2 = data.shape
    for i in range(n0):
        j0, j1, k0, k1 = n1, -1, n2, -1
        for j in range(n1):
            row = data[i, j]
            hit = 0
            if use_lut:
                for k in range(n2):
                    hit += lut[row[k]]
            else:
                for k in range(n2):
                    hit += row[k] != bg
            if hit == 0:
                continue
            j0 = min(j0, j)
            j1 = j
            for k in range(n2):  # first and last hit: early exits, only in rows with labels
                if (lut[row[k]] != 0) if use_lut else (row[k] != bg):
                    k0 = min(k0, k)
                    break
            for k in range(n2 - 1, -1, -1):
                if (lut[row[k]] != 0) if use_lut else (row[k] != bg):
                    k1 = max(k1, k)
                    break
        box[i, 0] = j0
        box[i, 1] = j1
        box[i, 2] = k0
        box[i, 3] = k1
    out[0], out[1], out[2], out[3], out[4], out[5] = n0, -1, n1, -1, n2, -1
    for i in range(n0):
        if box[i, 1] >= 0:
            out[0] = min(out[0], i)
            out[1] = i
            out[2] = min(out[2], box[i, 0])
            out[3] = max(out[3], box[i, 1])
            out[4] = min(out[4], box[i, 2])
            out[5] = max(out[5], box[i, 3])


@njit(parallel=True, cache=True)
def crop_pad(data, i0, j0, k0, lut, use_lut, bg, out):
    """``out[1:-1, 1:-1, 1:-1] = data[i0:, j0:, k0:]``, through ``lut`` when ``use_lut``, and
    the border of ``out`` (one voxel) set to ``bg`` (of out's dtype); planes in parallel, so
    ``out`` can come from ``np.empty`` (its pages first touched here, by both threads)."""
    n0, n1, n2 = out.shape
    for p in prange(n0):
        i = np.int64(p)  # prange's index is unsigned
        for j in range(n1):
            dst = out[i, j]
            if i == 0 or i == n0 - 1 or j == 0 or j == n1 - 1:
                for k in range(n2):
                    dst[k] = bg
                continue
            dst[0], dst[n2 - 1] = bg, bg
            src = data[i0 + i - 1, j0 + j - 1]
            if use_lut:
                for k in range(1, n2 - 1):
                    dst[k] = lut[src[k0 + k - 1]]
            else:  # a loop, not a slice copy: numba compiles a slice copy's shape checks and
                for k in range(1, n2 - 1):  # their error messages, slowing the first run
                    dst[k] = src[k0 + k - 1]


@njit(parallel=True, cache=True)
def permute_columns(a, order):
    """``a[:] = a[:, order]`` for an (N, 3) array, in place (no copy), rows in parallel."""
    for r in prange(a.shape[0]):
        x, y, z = a[r, order[0]], a[r, order[1]], a[r, order[2]]
        a[r, 0], a[r, 1], a[r, 2] = x, y, z


# ---------------------------------------------------------------------------------------------
# pass 1: count vertices and faces per lattice plane
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _used(r00, r01, r10, r11, c):
    """Lattice point c of the 4 rows is used when its 8 voxels are not all equal.

    Written with bitwise ``|`` on purpose: short-circuit ``and``/``or`` chains make the loops
    around it much slower (branches keep numba from pruning the reference counting of the row
    views, and from vectorising)."""
    x = r11[c]
    return ((r00[c - 1] != x) | (r00[c] != x) | (r01[c - 1] != x) | (r01[c] != x)
            | (r10[c - 1] != x) | (r10[c] != x) | (r11[c - 1] != x))


@njit(cache=True, inline="always")
def _vertex_mask(P, a, b, mask):
    """``mask[c]`` = 1 where lattice point (a, b, c) is used, for c in 1..n2-1 (vectorisable)."""
    r00 = P[a - 1, b - 1]
    r01 = P[a - 1, b]
    r10 = P[a, b - 1]
    r11 = P[a, b]
    for c in range(1, P.shape[2]):
        mask[c] = _used(r00, r01, r10, r11, c)


@njit(cache=True, inline="always")
def _face_mask(P, a, b, mask):
    """``mask[c]`` bits 0, 1, 2: voxel (a, b, c) differs from its -x, -y, -z neighbour, i.e. the
    x-face on plane a and the y- and z-faces of slab a at (b, c) exist (vectorisable)."""
    r01 = P[a - 1, b]
    r10 = P[a, b - 1]
    r11 = P[a, b]
    for c in range(1, P.shape[2]):
        x = r11[c]
        mask[c] = (np.uint8(r01[c] != x) | (np.uint8(r10[c] != x) << 1)
                   | (np.uint8(r11[c - 1] != x) << 2))


@njit(cache=True)
def _count_plane(P, a, mv, mf):
    """Used lattice points and owned faces (quads) of plane a; ``mv``, ``mf``: uint8 scratch
    (n2,). Row masks first, then sums: both loops vectorise."""
    n0, n1, n2 = P.shape
    v = 0
    f = 0
    for b in range(1, n1):
        _vertex_mask(P, a, b, mv)
        _face_mask(P, a, b, mf)
        sv = 0
        sf = 0
        for c in range(n2):
            m = mf[c]
            sv += mv[c]
            sf += (m & 1) + ((m >> 1) & 1) + (m >> 2)
        v += sv
        f += sf
    return v, f


@njit(parallel=True, cache=True)
def count(P, nv, nf):
    """Per lattice plane a: used lattice points into ``nv[a]`` and faces owned into ``nf[a]``
    (quads), both (n0 + 1,) int64.

    Plane a owns the x-faces on it (between voxels a-1 and a) and the y- and z-faces of voxel
    slab a. Parallel over planes; :func:`count_serial` is the same on one thread.
    """
    n0, n1, n2 = P.shape
    for a in prange(1, n0):
        # int64 plane numbers (prange's are unsigned): count_serial's _count_plane serves both
        nv[a], nf[a] = _count_plane(P, np.int64(a), np.zeros(n2, np.uint8), np.zeros(n2, np.uint8))


@njit(cache=True)
def count_serial(P, nv, nf, masks):
    """:func:`count` on one thread, ``masks`` (2, n2) uint8 scratch: for small maps (no threads
    to start), and a kernel that compiles in a fraction of the parallel one's time (the first
    extraction after install)."""
    for a in range(1, P.shape[0]):
        nv[a], nf[a] = _count_plane(P, a, masks[0], masks[1])


# ---------------------------------------------------------------------------------------------
# pass 2: vertices and faces
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _plane_vertices(P, a, start, ids, mask, words, write, bg, needs, origin, M, offset,
                    vertices, lattice, complex_):
    """Number the used lattice points of plane a from ``start`` in (b, c) order into ``ids``
    (index b * n2 + c); when ``write``, also fill their vertex rows. ``mask`` is uint8 scratch
    whose length is a multiple of 8 and > n2, scanned 8 points at a time through ``words``, its
    uint64 view."""
    n0, n1, n2 = P.shape
    n = start
    for b in range(1, n1):
        _vertex_mask(P, a, b, mask)
        for w in range(words.size):
            if words[w] == 0:
                continue
            for c in range(8 * w, 8 * w + 8):
                if mask[c] == 0:
                    continue
                ids[b * n2 + c] = n
                if write:
                    for e in range(3):
                        vertices[n, e] = origin[e] + M[e, 0] * a + M[e, 1] * b + M[e, 2] * c
                    lattice[n, 0] = a - 1 + offset[0]
                    lattice[n, 1] = b - 1 + offset[1]
                    lattice[n, 2] = c - 1 + offset[2]
                    complex_[n] = _is_complex(P, a, b, c, bg, needs)
                n += 1


@njit(cache=True)
def _config(P, a, b, c, L):
    """8-bit mask of the voxels around padded lattice point (a, b, c) holding label L. An
    ordinary call: its caller :func:`_fan` runs at complex vertices only, and inlining it there
    twice would only add compile time."""
    r00 = P[a - 1, b - 1]
    r01 = P[a - 1, b]
    r10 = P[a, b - 1]
    r11 = P[a, b]
    return (np.int64(r00[c - 1] == L) | (np.int64(r10[c - 1] == L) << 1)
            | (np.int64(r01[c - 1] == L) << 2) | (np.int64(r11[c - 1] == L) << 3)
            | (np.int64(r00[c] == L) << 4) | (np.int64(r10[c] == L) << 5)
            | (np.int64(r01[c] == L) << 6) | (np.int64(r11[c] == L) << 7))


@njit(cache=True)
def _mask8(v0, v1, v2, v3, v4, v5, v6, v7, x):
    """8-bit mask of the values equal to x."""
    return (np.int64(v0 == x) | (np.int64(v1 == x) << 1) | (np.int64(v2 == x) << 2)
            | (np.int64(v3 == x) << 3) | (np.int64(v4 == x) << 4) | (np.int64(v5 == x) << 5)
            | (np.int64(v6 == x) << 6) | (np.int64(v7 == x) << 7))


@njit(cache=True)
def _next_label(v0, v1, v2, v3, v4, v5, v6, v7, covered, x):
    """The value of the lowest voxel not in ``covered`` (``x`` if all are): a select chain."""
    x = v7 if (covered & 128) == 0 else x
    x = v6 if (covered & 64) == 0 else x
    x = v5 if (covered & 32) == 0 else x
    x = v4 if (covered & 16) == 0 else x
    x = v3 if (covered & 8) == 0 else x
    x = v2 if (covered & 4) == 0 else x
    x = v1 if (covered & 2) == 0 else x
    return x


@njit(cache=True, inline="always")
def _is_complex(P, a, b, c, bg, needs):
    """1 when some label at lattice point (a, b, c) has a config that may need vertex copies.

    Hot (once per vertex): scalar loads, selects and bit masks only — no array views, which would
    cost numba reference counting per vertex. The scalar helpers are ordinary calls (numba's
    ``inline="always"`` runs no faster here and compiles slower)."""
    # local voxel q = u + 2 v + 4 w is voxel (a - 1 + u, b - 1 + v, c - 1 + w)
    v0 = P[a - 1, b - 1, c - 1]
    v1 = P[a, b - 1, c - 1]
    v2 = P[a - 1, b, c - 1]
    v3 = P[a, b, c - 1]
    v4 = P[a - 1, b - 1, c]
    v5 = P[a, b - 1, c]
    v6 = P[a - 1, b, c]
    v7 = P[a, b, c]
    c0 = _mask8(v0, v1, v2, v3, v4, v5, v6, v7, v0)
    y = _next_label(v0, v1, v2, v3, v4, v5, v6, v7, c0, v0)
    c1 = _mask8(v0, v1, v2, v3, v4, v5, v6, v7, y)
    result = ((v0 != bg) & (needs[c0] != 0)) | ((y != bg) & (needs[c1] != 0))
    covered = c0 | c1
    while covered != 255:  # a third label or more: rare on real maps
        x = _next_label(v0, v1, v2, v3, v4, v5, v6, v7, covered, v0)
        cfg = _mask8(v0, v1, v2, v3, v4, v5, v6, v7, x)
        covered |= cfg
        result |= (x != bg) & (needs[cfg] != 0)
    return np.uint8(result)


@njit(cache=True)
def _quad(faces, labels, t, q0, q1, q2, q3, inside, outside, forward):
    """Write quad (q0, q1, q2, q3) as triangles 2t, 2t+1 (diagonal q0-q2), reversed if not
    ``forward``."""
    if forward:
        faces[2 * t, 0] = q0; faces[2 * t, 1] = q1; faces[2 * t, 2] = q2
        faces[2 * t + 1, 0] = q0; faces[2 * t + 1, 1] = q2; faces[2 * t + 1, 2] = q3
    else:
        faces[2 * t, 0] = q0; faces[2 * t, 1] = q3; faces[2 * t, 2] = q2
        faces[2 * t + 1, 0] = q0; faces[2 * t + 1, 1] = q2; faces[2 * t + 1, 2] = q1
    labels[2 * t, 0] = inside; labels[2 * t, 1] = outside
    labels[2 * t + 1, 0] = inside; labels[2 * t + 1, 1] = outside


@njit(cache=True)
def _orient(lo, hi, bg, flip):
    """(inside, outside, forward): inside is the low-side label unless it is background."""
    if lo != bg:
        return np.int32(lo), np.int32(hi), flip == 0
    return np.int32(hi), np.int32(lo), flip != 0


@njit(parallel=True, cache=True)
def emit(P, bg, voff, qoff, origin, M, offset, flip, needs, nchunks,
         vertices, lattice, complex_, faces, labels):
    """Fill vertices (N, 3) float32 mm, lattice (N, 3) int32, complex_ (N,) uint8 flags,
    faces (2Q, 3) int32 and labels (2Q, 2) int32.

    A vertex at padded lattice point p is at ``origin + M @ p`` mm; its lattice coordinate in the
    full volume is ``p - 1 + offset``. Quad corners are ordered so the normal points from the
    inside label to the outside label in index space (reversed when ``flip``: a negative
    determinant affine mirrors space). Planes are processed in ``nchunks`` runs of consecutive
    planes, so each plane's vertex numbers are computed about once. Parallel over the runs;
    :func:`emit_run` with ``nchunks=1, ch=0`` is the same on one thread (same output).
    """
    n0, n1, n2 = P.shape
    for ch in prange(nchunks):  # an int64 run number (prange's is unsigned): one emit_run
        mask = np.zeros(8 * (n2 // 8 + 1), np.uint8)
        emit_run(P, bg, voff, qoff, origin, M, offset, flip, needs, nchunks, np.int64(ch),
                 vertices, lattice, complex_, faces, labels, np.empty((2, n1 * n2), np.int32),
                 mask, mask.view(np.uint64))


@njit(cache=True)
def emit_run(P, bg, voff, qoff, origin, M, offset, flip, needs, nchunks, ch,
             vertices, lattice, complex_, faces, labels, ids, mask, words):
    """Vertices and faces of run ``ch`` of :func:`emit`: planes a0 .. a1 - 1. Called from
    Python with ``nchunks=1, ch=0`` it is :func:`emit` on one thread, for small maps (no
    threads to start; and one kernel fewer to compile for the first extraction after install).
    Scratch: ``ids`` (2, n1 * n2) int32, ``mask`` zeros (8 * (n2 // 8 + 1),) uint8 and
    ``words``, its uint64 view."""
    n0, n1, n2 = P.shape
    a0 = 1 + ch * (n0 - 1) // nchunks
    a1 = 1 + (ch + 1) * (n0 - 1) // nchunks
    if a0 >= a1:
        return
    cur = ids[0]
    nxt = ids[1]
    write = a0 < a1  # True; a runtime bool, so numba compiles one _plane_vertices
    _plane_vertices(P, a0, voff[a0], cur, mask, words, write, bg, needs, origin, M, offset,
                    vertices, lattice, complex_)
    for a in range(a0, a1):
        if a + 1 < n0:
            _plane_vertices(P, a + 1, voff[a + 1], nxt, mask, words, a + 1 < a1, bg, needs, origin,
                            M, offset, vertices, lattice, complex_)
        _plane_faces(P, a, qoff[a], cur, nxt, mask, words, bg, flip, faces, labels)
        cur, nxt = nxt, cur


@njit(cache=True)
def _plane_faces(P, a, t, ida, idb, mask, words, bg, flip, faces, labels):
    """The quads owned by plane a, from quad number t, in the same order as :func:`count`;
    ``ida``/``idb``: vertex numbers of lattice planes a and a + 1; ``mask``: as in
    :func:`_plane_vertices`, ``words`` its uint64 view."""
    n0, n1, n2 = P.shape
    for b in range(1, n1):
        _face_mask(P, a, b, mask)
        r01 = P[a - 1, b]
        r10 = P[a, b - 1]
        r11 = P[a, b]
        for w in range(words.size):
            if words[w] == 0:
                continue
            for c in range(8 * w, 8 * w + 8):
                m = mask[c]
                if m == 0:
                    continue
                x = r11[c]
                if m & 1:  # x-face on plane a, between (a-1, b, c) and (a, b, c)
                    inside, outside, fwd = _orient(r01[c], x, bg, flip)
                    _quad(faces, labels, t, ida[b * n2 + c], ida[(b + 1) * n2 + c],
                          ida[(b + 1) * n2 + c + 1], ida[b * n2 + c + 1], inside, outside, fwd)
                    t += 1
                if m & 2:  # y-face between (a, b-1, c) and (a, b, c)
                    inside, outside, fwd = _orient(r10[c], x, bg, flip)
                    _quad(faces, labels, t, ida[b * n2 + c], ida[b * n2 + c + 1],
                          idb[b * n2 + c + 1], idb[b * n2 + c], inside, outside, fwd)
                    t += 1
                if m & 4:  # z-face between (a, b, c-1) and (a, b, c)
                    inside, outside, fwd = _orient(r11[c - 1], x, bg, flip)
                    _quad(faces, labels, t, ida[b * n2 + c], idb[b * n2 + c],
                          idb[(b + 1) * n2 + c], ida[(b + 1) * n2 + c], inside, outside, fwd)
                    t += 1


# ---------------------------------------------------------------------------------------------
# pass 3: vertex copies for per-label fans (see shell_table.py)
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _fan(P, a, b, c, L, face, cycle, joinable):
    """Fan index of block face ``face`` of label L around padded lattice point (a, b, c)."""
    cfg = _config(P, a, b, c, L)
    j = joinable[cfg]
    bits = 0
    if j:
        for h in range(6):
            if (j >> h) & 1:
                step = 2 * (h & 1) - 1
                d = h >> 1
                a2 = a + step * (d == 0)
                b2 = b + step * (d == 1)
                c2 = c + step * (d == 2)
                if (joinable[_config(P, a2, b2, c2, L)] >> (h ^ 1)) & 1:
                    bits |= 1 << h
    return cycle[cfg * 64 + bits, face]


@njit(cache=True)
def _quad_splits(P, bg, lattice, offset, faces, labels, complex_, cycle, joinable, q, out, n):
    """Split rows (face, side, corner, copy) of quad q (triangles 2q, 2q+1); written to ``out``
    from row n when ``out`` is not empty. Returns the new row count."""
    t0 = 2 * q
    t1 = 2 * q + 1
    v0 = faces[t0, 0]
    v2 = faces[t0, 2]
    # quad axis: the lattice coordinate shared by the diagonal corners v0 and v2
    d = 0
    for e in range(3):
        if lattice[v0, e] == lattice[v2, e]:
            d = e
    e1 = 1 if d == 0 else 0
    e2 = 1 if d == 2 else 2
    m1 = min(lattice[v0, e1], lattice[v2, e1])
    m2 = min(lattice[v0, e2], lattice[v2, e2])
    for k in range(4):
        # the quad's 4 vertices and the triangle corners each one occupies
        if k == 0:
            v = v0
        elif k == 1:
            v = faces[t0, 1]
        elif k == 2:
            v = v2
        else:
            v = faces[t1, 2]
        if complex_[v] == 0:
            continue
        s1 = 1 if lattice[v, e1] == m1 else 0
        s2 = 1 if lattice[v, e2] == m2 else 0
        face = d * 4 + s1 + 2 * s2
        a = lattice[v, 0] - offset[0] + 1
        b = lattice[v, 1] - offset[1] + 1
        c = lattice[v, 2] - offset[2] + 1
        for side in range(2):
            L = labels[t0, side]
            if L == bg:
                continue
            cyc = _fan(P, a, b, c, L, face, cycle, joinable)
            if cyc <= 0:
                continue
            # the triangle corners vertex k occupies: k = 0: t0's 0 and t1's 0; k = 1: t0's 1;
            # k = 2: t0's 2 and t1's 1; k = 3: t1's 2 (two call sites: each inlined copy of
            # _row costs compile time)
            n = _row(out, n, t0 if k < 3 else t1, side, min(k, 2), cyc)
            if k == 0 or k == 2:
                n = _row(out, n, t1, side, k // 2, cyc)
    return n


@njit(cache=True, inline="always")
def _row(out, n, face, side, corner, copy):
    if out.shape[0] > 0:
        out[n, 0] = face
        out[n, 1] = side
        out[n, 2] = corner
        out[n, 3] = copy
    return n + 1


@njit(cache=True, inline="always")
def _touches_complex(faces, complex_, q):
    return (complex_[faces[2 * q, 0]] | complex_[faces[2 * q, 1]] | complex_[faces[2 * q, 2]]
            | complex_[faces[2 * q + 1, 2]]) != 0


@njit(cache=True)
def splits(P, bg, lattice, offset, faces, labels, complex_, cycle, joinable, out):
    """The number S of split rows, and the rows into ``out`` int32 (S, 4) unless it is empty
    (call with a (0, 4) array to count, then with one of S rows to fill): (face, side, corner,
    copy) with copy >= 1, meaning: in the shell of label ``labels[face, side]``, corner
    ``corner`` of triangle ``face`` uses vertex copy ``copy`` of ``faces[face, corner]``.
    Ordered by quad, then corner (serial: cheap, since only quads touching a complex vertex do
    any work)."""
    n = np.int64(0)
    for q in range(faces.shape[0] // 2):
        if _touches_complex(faces, complex_, q):
            n = _quad_splits(P, bg, lattice, offset, faces, labels, complex_, cycle, joinable,
                             q, out, n)
    return n


@njit(cache=True)
def voxel_counts(faces, labels, lattice, flip, out):
    """Voxels of each label value added into ``out`` (int64, one bin per value), from the
    surface alone: by the divergence theorem with the field (x, 0, 0), a closed voxel surface
    encloses the sum over its x-faces of (plane index x outward normal sign) voxels. Exact
    integers."""
    for q in range(faces.shape[0] // 2):
        v0 = faces[2 * q, 0]
        v1 = faces[2 * q, 1]
        v2 = faces[2 * q, 2]
        if lattice[v0, 0] != lattice[v2, 0]:
            continue  # not an x-face
        # x component of (v1 - v0) x (v2 - v0): the sign of the face normal along x
        nx = ((lattice[v1, 1] - lattice[v0, 1]) * (lattice[v2, 2] - lattice[v0, 2])
              - (lattice[v1, 2] - lattice[v0, 2]) * (lattice[v2, 1] - lattice[v0, 1]))
        s = 1 if nx > 0 else -1
        if flip:
            s = -s
        x = np.int64(lattice[v0, 0])
        out[labels[2 * q, 0]] += s * x
        out[labels[2 * q, 1]] -= s * x
