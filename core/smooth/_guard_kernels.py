"""Numba kernels of the guards run after a filter (private to ``core/smooth``): the fold guard
and the volume step (face terms, region sums, offsets along face normals)."""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..geometry.kernels import triangle_cross
from ._filter_kernels import FAST


@njit(cache=True, inline="always")
def _cross64(pos, a, b, c):
    """:func:`~anatomesh.core.geometry.kernels.triangle_cross` in float64 whatever the dtype of
    ``pos``: float32 positions are read exactly, so the answer is that of their float64 copy."""
    ax, ay, az = np.float64(pos[a, 0]), np.float64(pos[a, 1]), np.float64(pos[a, 2])
    e1x, e1y, e1z = pos[b, 0] - ax, pos[b, 1] - ay, pos[b, 2] - az
    e2x, e2y, e2z = pos[c, 0] - ax, pos[c, 1] - ay, pos[c, 2] - az
    return e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x


@njit(cache=True)
def _fold_check(pos, start, faces, eps, f):
    a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
    nx, ny, nz = _cross64(pos, a, b, c)
    rx, ry, rz = triangle_cross(start, a, b, c)  # memory: computed, not an (M, 3) array
    r2 = rx * rx + ry * ry + rz * rz
    return r2 > 0.0 and nx * rx + ny * ry + nz * rz <= eps * r2


@njit(parallel=True, cache=True)
def folded(pos, start, faces, eps):
    """Faces whose normal (unnormalised) has turned by 90° or more from their normal at
    ``start``, or collapsed: ``n · n_start <= eps |n_start|²``. Faces with a zero normal at
    ``start`` never count. ``pos`` float32 or float64 (checked in float64 alike)."""
    m = faces.shape[0]
    out = np.zeros(m, np.bool_)
    for f in prange(m):
        out[f] = _fold_check(pos, start, faces, eps, f)
    return out


@njit(cache=True)
def unfold_rounds(pos, start, faces, eps, vf_offsets, vf, bad, rounds, touched):
    """The fold guard's rounds, in place: move every vertex of a folded face (``bad``: the
    faces folded now) halfway back to ``start``, ``rounds`` times, then straight back until none
    is folded (at most 100 times); after each move only the faces around moved vertices are
    checked again. Marks moved vertices in ``touched`` (N,) bool; returns faces left folded."""
    n = pos.shape[0]
    mark = np.zeros(n, np.bool_)
    seen = np.zeros(faces.shape[0], np.bool_)
    for r in range(rounds + 100):
        if bad.shape[0] == 0:
            break
        halve = r < rounds
        moved = np.empty(3 * bad.shape[0], np.int64)
        k = 0
        for f in bad:
            for c in range(3):
                i = faces[f, c]
                if not mark[i]:
                    mark[i] = True
                    moved[k] = i
                    k += 1
        nxt = np.empty(0, np.int64)
        cand = []
        for j in range(k):
            i = moved[j]
            mark[i] = False
            touched[i] = True
            for c in range(3):
                pos[i, c] = 0.5 * (pos[i, c] + start[i, c]) if halve else start[i, c]
            for a in range(vf_offsets[i], vf_offsets[i + 1]):
                f = vf[a]
                if not seen[f]:
                    seen[f] = True
                    cand.append(f)
        for f in cand:
            seen[f] = False
        keep = [f for f in cand if _fold_check(pos, start, faces, eps, f)]
        nxt = np.array(keep, np.int64) if len(keep) else nxt
        bad = nxt
    return bad.shape[0]


@njit(parallel=True, cache=True)
def face_terms(pos, faces, origin, areas, tet):
    """Area (mm²) and the signed volume of the tetrahedron (origin, face) (mm³) of every face."""
    for f in prange(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        nx, ny, nz = triangle_cross(pos, a, b, c)
        areas[f] = 0.5 * math.sqrt(nx * nx + ny * ny + nz * nz)
        cx = (pos[a, 0] + pos[b, 0] + pos[c, 0]) / 3.0 - origin[0]
        cy = (pos[a, 1] + pos[b, 1] + pos[c, 1]) / 3.0 - origin[1]
        cz = (pos[a, 2] + pos[b, 2] + pos[c, 2]) / 3.0 - origin[2]
        tet[f] = 0.5 * (nx * cx + ny * cy + nz * cz) / 3.0


@njit(cache=True)
def region_terms(inside, outside, areas, tet, volume, diag, between, touching):
    """Per region: enclosed volume (inside faces count +, outside −), shell area (``diag``) and,
    when regions ``touching``, the area it shares with each other region (``between`` (R, R),
    inside row) — zeroed first."""
    volume[:] = 0.0
    diag[:] = 0.0
    if touching:
        between[:, :] = 0.0
    for f in range(inside.shape[0]):
        a, b = inside[f], outside[f]
        if a >= 0:
            volume[a] += tet[f]
            diag[a] += areas[f]
        if b >= 0:
            volume[b] -= tet[f]
            diag[b] += areas[f]
        if touching and a >= 0 and b >= 0:
            between[a, b] += areas[f]


@njit(parallel=True, fastmath=FAST, cache=True)
def vertex_moves(src, dst, faces, vf_offsets, vf, areas, lam, inside, outside, gain):
    """Each vertex by the area-weighted mean of its faces' moves, a face moving by
    ``t = lam[inside] − lam[outside]`` along its unit normal n (``lam`` (R + 1,), its last entry
    0: background, −1): ``p' = p + Σ A_f t_f n_f / Σ A_f``, times the gain. ``A_f n_f`` is half
    the face's cross product at ``src`` and ``areas`` its areas there (memory: no per-face
    normals or moves are stored)."""
    has_gain = gain.shape[0] > 0
    for i in prange(src.shape[0]):
        sx = 0.0
        sy = 0.0
        sz = 0.0
        sa = 0.0
        for a in range(vf_offsets[i], vf_offsets[i + 1]):
            f = vf[a]
            t = 0.5 * (lam[inside[f]] - lam[outside[f]])
            nx, ny, nz = triangle_cross(src, faces[f, 0], faces[f, 1], faces[f, 2])
            sx += t * nx
            sy += t * ny
            sz += t * nz
            sa += areas[f]
        px, py, pz = src[i, 0], src[i, 1], src[i, 2]
        if sa > 0.0:
            k = 1.0 / sa
            if has_gain:
                k *= gain[i]
            px, py, pz = px + k * sx, py + k * sy, pz + k * sz
        dst[i, 0] = px
        dst[i, 1] = py
        dst[i, 2] = pz


@njit(cache=True)
def solve_spd(m, b):
    """``m x = b`` by Cholesky (``m`` (R, R) symmetric positive definite float64); NaNs when a
    pivot is not positive (the caller falls back to least squares)."""
    r = m.shape[0]
    low = np.zeros((r, r))
    x = np.full(r, np.nan)
    for j in range(r):
        d = m[j, j] - np.sum(low[j, :j] ** 2)
        if not d > 1e-12 * max(abs(m[j, j]), 1e-300):
            return x
        low[j, j] = np.sqrt(d)
        for i in range(j + 1, r):
            low[i, j] = (m[i, j] - np.sum(low[i, :j] * low[j, :j])) / low[j, j]
    y = np.empty(r)
    for i in range(r):
        y[i] = (b[i] - np.sum(low[i, :i] * y[:i])) / low[i, i]
    for i in range(r - 1, -1, -1):
        x[i] = (y[i] - np.sum(low[i + 1:, i] * x[i + 1:])) / low[i, i]
    return x
