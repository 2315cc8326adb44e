"""Numba kernels of the tests a collapse must pass (private to :mod:`anatomesh.core.decimate`).

* topology: the link condition (Dey, Edelsbrunner, Guha & Nekhayev 1999, "Topology preserving
  edge contraction"), per label shell, plus no shell fan below 3 faces (:func:`link_ok`);
* junctions: an edge between two feature vertices must lie on the feature curve
  (:func:`is_feature_edge`);
* geometry: no face normal turning by more than the allowed angle, no degenerate face, no new
  sliver under the quality limit (:func:`geometry_ok`). Quality is ``2√3·|n| / Σl²`` (1 for an
  equilateral triangle, 0 for a degenerate one; ``n`` the cross product of two edges, ``l`` the
  edge lengths), kept with the unit normal per face in the face rows ``FD`` (:func:`face_frame`).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from ._quadric_kernels import FAST
from ._refs_kernels import has


@njit(cache=True)
def _in_shell(flab, f, lab):
    return lab < 0 or flab[f, 0] == lab or flab[f, 1] == lab


@njit(cache=True)
def link_ok(F, flab, fa, na, fb, nb, a, b, lab, mark, token):
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
        if has(f, F, a):
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
def face_frame(V, F, f, FD):
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
    :func:`face_frame`), edge costs zero (filled by :func:`edge_costs`)."""
    m = F.shape[0]
    FD = np.zeros((m, 8))
    for f in prange(m):
        face_frame(V, F, f, FD)
    return FD


@njit(cache=True, fastmath=FAST)
def geometry_ok(V, F, FD, fl, nf, keep, drop, px, py, pz, cos_max, q_min):
    """No face flips by more than acos(cos_max), none becomes degenerate, none becomes a sliver
    with quality 2√3|n|/Σl² (1 = equilateral) below min(q_min, its quality before).
    ``FD[:, 3:7]``: the faces' current unit normals and qualities."""
    for i in range(nf):
        f = fl[i]
        if has(f, F, keep) and has(f, F, drop):
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
def is_feature_edge(F, flab, fb, nb, a, multi):
    """An edge on a junction curve (its faces carry 3+ labels) or an open boundary."""
    cnt = 0
    l0 = -1
    l1 = -1
    n_extra = 0
    for i in range(nb):
        f = fb[i]
        if not has(f, F, a):
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
