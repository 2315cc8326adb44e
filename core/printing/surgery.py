"""Local mesh surgery for the printable-part tools: refine a patch, split triangles along a level
set (a plane, a cylinder), find the loops a cut leaves, and stitch loops into tubes.

* :func:`refine_near` — red-green refinement (Bank, Sherman & Weiser 1983, "Refinement
  algorithms and data structures for regular local mesh refinement"): faces near a point are
  split 1:4 until their edges are short enough, neighbours are bisected so the mesh stays
  conforming (no T-junctions), closed and consistently oriented;
* :func:`split_by_level` — every triangle crossing the zero level of a per-vertex function is
  split at the crossing points (one new vertex per crossing edge, shared by both sides), as in
  marching triangles; returns which side each new face lies on;
* :func:`zipper` — stitch two closed loops running around one axis into a band of triangles,
  advancing on whichever loop is behind in angle (the greedy contour stitching of Fuchs, Kedem &
  Uselton 1977, "Optimal surface reconstruction from planar contours", with the angle as the
  parameter);
* :func:`ring`, :func:`fan` — a circle of new vertices around an axis and a disk closing a loop.

Vertices are float64 mm, faces int64; every function returns new arrays.
"""
from __future__ import annotations

from typing import Callable, Tuple

import numpy as np

from ..model.errors import AnatomeshError


# ---------------------------------------------------------------------------------------------
# refinement
# ---------------------------------------------------------------------------------------------
def _edges(f: np.ndarray, n: int) -> np.ndarray:
    """(M, 3) undirected edge keys of each face's edges (k, k+1)."""
    a, b = f, np.roll(f, -1, axis=1)
    return np.minimum(a, b) * n + np.maximum(a, b)


def split_faces(v: np.ndarray, f: np.ndarray, want: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split the faces ``want`` (M,) bool 1:4 at their edge midpoints; a neighbour with one split
    edge is bisected, one with two has its third edge split too (repeated until none has two).

    Only the faces touching a split edge's end are looked at (a third edge joins two such ends
    already), so a small patch costs little on a large mesh. Returns (vertices, faces, parent
    (M',) int64: the face each new face came from)."""
    n = len(v)
    split = np.unique(_edges(f[want], n))
    mark = np.zeros(n, bool)
    mark[split // n] = mark[split % n] = True
    touched = np.flatnonzero(mark[f].any(axis=1))  # the faces that may hold a split edge
    keys = _edges(f[touched], n)
    while True:
        two = np.isin(keys, split).sum(axis=1) == 2
        if not np.any(two):
            break
        split = np.union1d(split, keys[two].ravel())
    mid = n + np.arange(split.size)
    a, b = split // n, split % n
    nv = np.concatenate([v, 0.5 * (v[a] + v[b])])
    is_split = np.isin(keys, split)
    m_of = np.where(is_split, mid[np.clip(np.searchsorted(split, keys), 0, max(split.size - 1, 0))], -1)
    cnt_t = is_split.sum(axis=1)
    cnt = np.zeros(len(f), np.int64)
    cnt[touched] = cnt_t
    out, parent = [f[cnt == 0]], [np.flatnonzero(cnt == 0)]
    one = np.flatnonzero(cnt_t == 1)  # rows of the touched faces
    if one.size:
        k = np.argmax(is_split[one], axis=1)  # the split edge (k, k+1)
        g = f[touched[one]]
        r = np.arange(one.size)
        p0, p1, p2 = g[r, k], g[r, (k + 1) % 3], g[r, (k + 2) % 3]
        m = m_of[one, k]
        out += [np.stack([p0, m, p2], 1), np.stack([m, p1, p2], 1)]
        parent += [touched[one]] * 2
    three = np.flatnonzero(cnt_t == 3)
    if three.size:
        g, m3 = f[touched[three]], m_of[three]
        p0, p1, p2 = g[:, 0], g[:, 1], g[:, 2]
        m01, m12, m20 = m3[:, 0], m3[:, 1], m3[:, 2]
        out += [np.stack([p0, m01, m20], 1), np.stack([m01, p1, m12], 1),
                np.stack([m20, m12, p2], 1), np.stack([m01, m12, m20], 1)]
        parent += [touched[three]] * 4
    return nv, np.concatenate(out).astype(np.int64), np.concatenate(parent).astype(np.int64)


def refine_near(v: np.ndarray, f: np.ndarray, centre: np.ndarray, radius: float, max_edge: float,
                select: Callable = None, reach: float = 0.0, max_rounds: int = 12):
    """Refine the faces within ``radius`` mm of ``centre`` (by centroid, plus the face's own
    size) until their longest edge is at most ``max_edge`` mm; ``select(v, f)`` → (M,) bool may
    restrict which faces qualify, and is shown the faces with a vertex within ``max(radius,
    reach)`` mm of the centre plus twice the longest edge (every face whose centroid is within
    ``reach``). Returns (vertices, faces, parent) as :func:`split_faces`."""
    parent = np.arange(len(f))
    p = v[f]
    longest = float(np.linalg.norm(p - np.roll(p, -1, axis=1), axis=2).max()) if len(f) else 0.0
    del p  # refining only shortens edges: faces farther than this bound never qualify
    for _ in range(max_rounds):
        to_centre = np.linalg.norm(v - centre, axis=1)
        zone = np.flatnonzero(to_centre[f].min(axis=1) < max(radius, reach) + 2 * longest)
        p = v[f[zone]]
        size = np.max(np.linalg.norm(p - np.roll(p, -1, axis=1), axis=2), axis=1)
        near = np.linalg.norm(p.mean(axis=1) - centre, axis=1) < radius + size
        ok = near & (size > max_edge)
        if select is not None:
            ok &= select(v, f[zone])
        if not np.any(ok):
            break
        want = np.zeros(len(f), bool)
        want[zone[ok]] = True
        v, f, par = split_faces(v, f, want)
        parent = parent[par]
    return v, f, parent


# ---------------------------------------------------------------------------------------------
# splitting along a level set
# ---------------------------------------------------------------------------------------------
def split_by_level(v: np.ndarray, f: np.ndarray, phi: np.ndarray, root: Callable,
                   active: np.ndarray = None):
    """Split the triangles crossing the zero level of ``phi`` (N,) (a signed value per vertex).

    ``root(i, j)`` → (K, 3) the crossing points on edges from vertices ``i`` to ``j`` (K,) (for
    a plane the linear interpolation; for a curved level its exact root). ``active`` (M,) bool
    limits the split to those faces (others are kept whole, their side from their vertices'
    mean sign). Zero values count as positive. Returns (vertices, faces, positive (M',) bool:
    the face lies on the positive side, parent (M',) int64)."""
    phi = np.where(phi == 0, np.finfo(float).tiny, phi)
    pos = phi > 0
    n = len(v)
    act = np.ones(len(f), bool) if active is None else np.asarray(active, bool)
    s = pos[f]
    cross = act & (s.any(axis=1) & ~s.all(axis=1))
    keep = np.flatnonzero(~cross)
    faces = [f[keep]]
    side = [pos[f[keep]].sum(axis=1) >= 2]
    parent = [keep]
    ci = np.flatnonzero(cross)
    if ci.size == 0:
        return v, f.copy(), side[0], keep
    fc, sc = f[ci], s[ci]
    lone_is_pos = sc.sum(axis=1) == 1  # one positive vertex; else one negative
    k = np.argmax(sc == lone_is_pos[:, None], axis=1)  # index of the lone vertex
    a, b, c = fc[np.arange(ci.size), k], fc[np.arange(ci.size), (k + 1) % 3], fc[np.arange(ci.size), (k + 2) % 3]
    ek = np.concatenate([np.minimum(a, b) * n + np.maximum(a, b), np.minimum(a, c) * n + np.maximum(a, c)])
    uk, inv = np.unique(ek, return_inverse=True)
    i, j = uk // n, uk % n
    new_p = root(i, j)
    mab, mac = n + inv[:ci.size], n + inv[ci.size:]
    faces += [np.stack([a, mab, mac], 1), np.stack([mab, b, c], 1), np.stack([mab, c, mac], 1)]
    side += [lone_is_pos, ~lone_is_pos, ~lone_is_pos]
    parent += [ci, ci, ci]
    return (np.concatenate([v, new_p]), np.concatenate(faces).astype(np.int64),
            np.concatenate(side), np.concatenate(parent).astype(np.int64))


def plane_root(v: np.ndarray, phi: np.ndarray) -> Callable:
    """The ``root`` of :func:`split_by_level` for a linear ``phi`` (a plane): interpolation."""
    def root(i, j):
        t = phi[i] / (phi[i] - phi[j])
        return v[i] + t[:, None] * (v[j] - v[i])
    return root


def cylinder_root(v: np.ndarray, origin: np.ndarray, axis: np.ndarray, radius: float) -> Callable:
    """The ``root`` of :func:`split_by_level` for ``phi = distance to the axis − radius``: the
    exact crossing of each edge with the infinite cylinder (a quadratic in the edge parameter)."""
    def root(i, j):
        p, q = v[i] - origin, v[j] - origin
        p_perp = p - np.outer(p @ axis, axis)
        d = q - p
        d_perp = d - np.outer(d @ axis, axis)
        aa = np.einsum("ij,ij->i", d_perp, d_perp)
        bb = 2 * np.einsum("ij,ij->i", p_perp, d_perp)
        cc = np.einsum("ij,ij->i", p_perp, p_perp) - radius ** 2
        disc = np.sqrt(np.maximum(bb * bb - 4 * aa * cc, 0.0))
        aa = np.maximum(aa, 1e-300)
        t1, t2 = (-bb - disc) / (2 * aa), (-bb + disc) / (2 * aa)
        t = np.where((t1 >= 0) & (t1 <= 1), t1, t2)
        return v[i] + np.clip(t, 0, 1)[:, None] * d
    return root


# ---------------------------------------------------------------------------------------------
# loops and tubes
# ---------------------------------------------------------------------------------------------
def loop_angles(points: np.ndarray, origin: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Unwrapped angles (K,) of the points of a closed loop around ``axis`` through ``origin``,
    in loop order; a loop winding once around the axis spans ±2π."""
    e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    d = points - origin
    return np.unwrap(np.arctan2(d @ e2, d @ e1))


def around_axis(loop: np.ndarray, v: np.ndarray, origin: np.ndarray, axis: np.ndarray):
    """``loop`` (vertex indices) ordered to run counter-clockwise around ``axis`` from its point
    of smallest angle, and its angles; raises when the loop does not wind once around the axis."""
    ang = loop_angles(v[loop], origin, axis)
    turn = ang[-1] - ang[0] + (ang[0] - ang[-1] + np.pi) % (2 * np.pi) - np.pi
    if abs(abs(turn) - 2 * np.pi) > 0.5:
        raise AnatomeshError("a cut left a loop that does not go around the drilling axis; "
                             "choose another place or a smaller diameter")
    if turn < 0:
        loop, ang = loop[::-1], -ang[::-1]
    start = int(np.argmin(np.mod(ang, 2 * np.pi)))
    loop = np.roll(loop, -start)
    ang = np.mod(np.roll(ang, -start) - ang[start], 2 * np.pi)
    ang = np.unwrap(ang)
    ang = ang - ang[0]
    return loop, ang


def zipper(loop_a: np.ndarray, ang_a: np.ndarray, loop_b: np.ndarray, ang_b: np.ndarray) -> np.ndarray:
    """Triangles (K, 3) joining loops ``a`` and ``b``, both counter-clockwise around one axis from
    angle 0 (:func:`around_axis`): a closed band in which every loop edge is used once. Wound so
    that the band's edge ``a[i] → a[i+1]`` runs forward (flip the rows for the other side)."""
    na, nb = len(loop_a), len(loop_b)
    ta = np.r_[ang_a, 2 * np.pi]
    tb = np.r_[ang_b, 2 * np.pi]
    i = j = 0
    out = []
    while i < na or j < nb:
        adv_a = j >= nb or (i < na and ta[i + 1] <= tb[j + 1])
        if adv_a:
            out.append((loop_a[i % na], loop_a[(i + 1) % na], loop_b[j % nb]))
            i += 1
        else:
            out.append((loop_a[i % na], loop_b[(j + 1) % nb], loop_b[j % nb]))
            j += 1
    return np.array(out, np.int64)


def ring(centre: np.ndarray, axis: np.ndarray, radius: float, count: int) -> np.ndarray:
    """``count`` points (count, 3) on a circle around ``axis`` through ``centre``, counter-
    clockwise from angle 0 (the frame of :func:`loop_angles`)."""
    e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    t = np.arange(count) * 2 * np.pi / count
    return centre + radius * (np.outer(np.cos(t), e1) + np.outer(np.sin(t), e2))


def fan(loop: np.ndarray, centre_index: int) -> np.ndarray:
    """Triangles (K, 3) closing a loop with a fan around the vertex ``centre_index``, wound so
    that each edge ``loop[i] → loop[i+1]`` runs backward (the fan continues a surface whose
    boundary runs forward)."""
    return np.stack([np.roll(loop, -1), loop, np.full(len(loop), centre_index)], axis=1).astype(np.int64)
