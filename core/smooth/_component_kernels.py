"""Numba kernels of :mod:`anatomesh.core.smooth.components` (private to ``core/smooth``): the
connected components of every label's shell, found on the shared faces of a surface set, their
volumes, and the faces around chosen components."""
from __future__ import annotations

import numpy as np
from numba import njit



@njit(cache=True)
def _corner(faces, f, v):
    if faces[f, 0] == v:
        return 0
    return 1 if faces[f, 1] == v else 2


@njit(cache=True, inline="always")
def _link(parent, x, y):
    """Join the trees of ``x`` and ``y`` (Rem's union with splicing; Patwary, Blair & Manne
    2010, "Experiments on union-find algorithms for the disjoint-set data structure"): every
    entry keeps ``parent[x] <= x``, so each root is its tree's smallest entry."""
    while parent[x] != parent[y]:
        if parent[x] > parent[y]:
            if parent[x] == x:
                parent[x] = parent[y]
                return
            z = parent[x]
            parent[x] = parent[y]
            x = z
        else:
            if parent[y] == y:
                parent[y] = parent[x]
                return
            z = parent[y]
            parent[y] = parent[x]
            y = z


@njit(cache=True)
def union_shell_sides(faces, face_labels, background, vf_offsets, vf, copies, parent):
    """Union-find over the face sides (entry ``2 f + side``, ``parent`` (2M,) int32, set here):
    two sides are joined when they belong to the same label's shell and share a shell vertex
    there — the same set vertex with the same copy: ``copies`` (M,) uint32 holds in bits
    ``4 k .. 4 k + 3``, ``k = 3 side + corner``, the copy that corner uses in that side's shell
    (0: the shared vertex). Background sides stay alone. ``parent[e] <= e`` throughout."""
    for e in range(parent.shape[0]):
        parent[e] = e
    width = 2
    for v in range(vf_offsets.shape[0] - 1):
        width = max(width, 2 * (vf_offsets[v + 1] - vf_offsets[v]))
    key_label = np.empty(width, np.int64)
    key_copy = np.empty(width, np.int64)
    first = np.empty(width, np.int64)
    for v in range(vf_offsets.shape[0] - 1):
        k = 0
        for a in range(vf_offsets[v], vf_offsets[v + 1]):
            f = vf[a]
            for side in range(2):
                label = face_labels[f, side]
                if label == background:
                    continue
                cp = 0
                if copies[f] != 0:
                    cp = (copies[f] >> (4 * (3 * side + _corner(faces, f, v)))) & 15
                e = 2 * f + side
                j = 0
                while j < k and (key_label[j] != label or key_copy[j] != cp):
                    j += 1
                if j == k:
                    key_label[k], key_copy[k], first[k] = label, cp, e
                    k += 1
                else:
                    _link(parent, first[j], e)


@njit(cache=True)
def number_components(parent, face_labels, background):
    """Turn the union-find forest ``parent`` (2M,) int32 (``parent[e] <= e``, roots: each
    tree's smallest entry) into component ids numbered by their smallest entry, in place;
    background sides get −1. Returns the number of components."""
    for e in range(parent.shape[0]):
        parent[e] = parent[parent[e]]  # ascending: the parent's root is known already
    n = 0
    for e in range(parent.shape[0]):
        if face_labels[e >> 1, e & 1] == background:
            parent[e] = -1
        elif parent[e] == e:
            parent[e] = n
            n += 1
        else:
            parent[e] = parent[parent[e]]  # its root (< e) holds its id already
    return n


@njit(cache=True, inline="always")
def _tet(pos, faces, f, origin):
    """Signed volume (mm³) of the tetrahedron (origin, face ``f``) at ``pos``, in float64."""
    i, j, k = faces[f, 0], faces[f, 1], faces[f, 2]
    ax, ay, az = np.float64(pos[i, 0]), np.float64(pos[i, 1]), np.float64(pos[i, 2])
    e1x, e1y, e1z = pos[j, 0] - ax, pos[j, 1] - ay, pos[j, 2] - az
    e2x, e2y, e2z = pos[k, 0] - ax, pos[k, 1] - ay, pos[k, 2] - az
    nx = e1y * e2z - e1z * e2y
    ny = e1z * e2x - e1x * e2z
    nz = e1x * e2y - e1y * e2x
    return (nx * (ax - origin[0]) + ny * (ay - origin[1]) + nz * (az - origin[2])) / 6.0


@njit(cache=True)
def component_volumes(pos, faces, sides, origin, out):
    """Signed volume (mm³) of every component into ``out`` (C,) float64 (zeroed first): each
    face's tetrahedron (origin, face) added to the component on its side 0 and subtracted from
    the one on its side 1 (``sides`` (M, 2) int32, −1: none). ``pos`` (N, 3) float32 or float64,
    read in float64."""
    out[:] = 0.0
    for f in range(faces.shape[0]):
        a, b = sides[f, 0], sides[f, 1]
        if a < 0 and b < 0:
            continue
        t = _tet(pos, faces, f, origin)
        if a >= 0:
            out[a] += t
        if b >= 0:
            out[b] -= t


@njit(cache=True)
def component_volumes_pair(pos, rest, faces, sides, origin, out, out_rest):
    """:func:`component_volumes` at ``pos`` and at ``rest`` in one pass over the faces."""
    out[:] = 0.0
    out_rest[:] = 0.0
    for f in range(faces.shape[0]):
        a, b = sides[f, 0], sides[f, 1]
        if a < 0 and b < 0:
            continue
        t, r = _tet(pos, faces, f, origin), _tet(rest, faces, f, origin)
        if a >= 0:
            out[a] += t
            out_rest[a] += r
        if b >= 0:
            out[b] -= t
            out_rest[b] -= r


@njit(cache=True)
def faces_of(sides, chosen):
    """The faces (K,) int64, ascending, with a side in a ``chosen`` (C,) bool component."""
    keep = np.zeros(sides.shape[0], np.bool_)
    k = 0
    for f in range(sides.shape[0]):
        a, b = sides[f, 0], sides[f, 1]
        if (a >= 0 and chosen[a]) or (b >= 0 and chosen[b]):
            keep[f] = True
            k += 1
    out = np.empty(k, np.int64)
    k = 0
    for f in range(sides.shape[0]):
        if keep[f]:
            out[k] = f
            k += 1
    return out


@njit(cache=True)
def losers(sides, mark, priority):
    """(C,) bool: of every two ``mark``-ed components that share a face (one on each side), the
    one of lower ``priority`` (C,) (a tie: the larger id)."""
    out = np.zeros(mark.shape[0], np.bool_)
    for f in range(sides.shape[0]):
        a, b = sides[f, 0], sides[f, 1]
        if a >= 0 and b >= 0 and mark[a] and mark[b]:
            if priority[a] > priority[b] or (priority[a] == priority[b] and a < b):
                out[b] = True
            else:
                out[a] = True
    return out


@njit(cache=True)
def faces_around(faces, inner, vf_offsets, vf, n_faces):
    """The faces (K,) int64, ascending, with a corner among the vertices ``inner`` (the corners
    of the ``inner`` faces (L,) int64)."""
    keep = np.zeros(n_faces, np.bool_)
    for f in inner:
        for c in range(3):
            v = faces[f, c]
            for a in range(vf_offsets[v], vf_offsets[v + 1]):
                keep[vf[a]] = True
    return np.flatnonzero(keep)


@njit(cache=True)
def vertex_factors(faces, sides, t, n):
    """Per vertex of a face set (``faces`` (K, 3) local indices < n, ``sides`` (K, 2) local
    component ids, −1: none): the smallest blend factor ``t`` (C,) of the components it
    belongs to, 1 for a vertex of none. (n,) float64."""
    out = np.ones(n)
    for f in range(faces.shape[0]):
        for s in range(2):
            c = sides[f, s]
            if c >= 0:
                for k in range(3):
                    out[faces[f, k]] = min(out[faces[f, k]], t[c])
    return out
