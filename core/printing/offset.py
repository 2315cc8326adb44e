"""The inner offset surface of a closed part: every point at a given distance inside it.

The distance to the surface is sampled on a regular grid of points inside the part (inside by
crossing parity along grid rows, distance by the exact closest-point query of
:class:`~anatomesh.core.geometry.spatial.TriangleGrid`), and the level ``distance = wall`` is
extracted by marching tetrahedra (Doi & Koide 1991, "An efficient method of triangulating
equi-valued surfaces by using tetrahedral cells"), each grid cell split into six tetrahedra
around its main diagonal (Freudenthal/Kuhn), so that neighbouring cells agree on their shared
faces: the result is closed and 2-manifold by construction. It lies ``wall`` inside the outer
surface up to the linear interpolation along grid edges, so it never crosses it; where the part
is thinner than twice the wall the offset simply has no surface (a solid region).
"""
from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

from ..geometry.spatial import TriangleGrid
from ..model.errors import AnatomeshError
from ..model.mesh import check_arrays

#: the six tetrahedra of a unit cell, as corner numbers (bit 0: +x, bit 1: +y, bit 2: +z),
#: all around the diagonal 0-7 (a path 0 → one axis → two axes → 7)
_TETS = np.array([[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]])
#: grid points at most this many (the spacing grows to keep to it)
_MAX_POINTS = 6_000_000


def inner_offset(vertices: np.ndarray, faces: np.ndarray, wall: float, spacing: Optional[float] = None,
                 grid: Optional[TriangleGrid] = None) -> Tuple[np.ndarray, np.ndarray, float]:
    """The surface ``wall`` mm inside a closed part, faces wound to face away from the part's
    material (toward the inside: the surface of a cavity).

    ``spacing`` (mm) of the sampling grid defaults to ``wall / 2`` (coarser for very large
    parts, at most :data:`_MAX_POINTS` points). Returns (vertices (N, 3) float64 mm, faces (M, 3)
    int64, the spacing used); empty arrays when the part is nowhere thicker than ``2 · wall``."""
    v, f = check_arrays(vertices, faces)
    v = v.astype(np.float64)
    if not (np.isfinite(wall) and wall > 0):
        raise AnatomeshError(f"the wall of a hollowed part must be a positive number of mm, got {wall}")
    g = grid if grid is not None else TriangleGrid(v, f)
    lo, hi = v.min(axis=0) + wall, v.max(axis=0) - wall
    if np.any(hi <= lo):
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64), 0.0
    h = float(spacing) if spacing else 0.5 * float(wall)
    h = max(h, float(np.prod(hi - lo + 2 * h) / _MAX_POINTS) ** (1 / 3))
    # a generic shift keeps grid rows off the part's vertices and edges (parity stays clean)
    lo = lo - h * np.array([1.1234, 1.2345, 1.3456])
    axes = [np.arange(lo[k], hi[k] + 2 * h, h) for k in range(3)]
    inside = _inside_rows(g, axes)
    field = np.full(inside.shape, -float(wall))
    idx = np.flatnonzero(inside)
    pts = _points(axes, idx, inside.shape)
    d, _, _ = g.closest(pts, max_distance=wall + 2 * h)
    field.ravel()[idx] = np.minimum(d, wall + 2 * h) - wall
    field[np.abs(field) < 0.1 * h] = -0.1 * h  # no sample on or near the level (no slivers): walls 0.1 h thicker at most
    vo, fo = _march(field, axes)
    return vo, fo, h


def _points(axes, flat_index: np.ndarray, shape) -> np.ndarray:
    i, j, k = np.unravel_index(flat_index, shape)
    return np.stack([axes[0][i], axes[1][j], axes[2][k]], axis=1)


def _inside_rows(g: TriangleGrid, axes) -> np.ndarray:
    """(nx, ny, nz) bool: grid points inside the closed surface, by the parity of the crossings
    along each row in +x (all crossings of a row found by casting again from each hit)."""
    xs, ys, zs = axes
    yy, zz = np.meshgrid(ys, zs, indexing="ij")
    n = yy.size
    start = xs[0] - 1.0
    origins = np.stack([np.full(n, start), yy.ravel(), zz.ravel()], axis=1)
    d = np.broadcast_to([1.0, 0.0, 0.0], origins.shape)
    hits = []
    t_from = np.zeros(n)
    live = np.arange(n)
    eps = 1e-9 * max(float(xs[-1] - xs[0]), 1.0)
    while live.size:
        o = origins[live].copy()
        o[:, 0] += t_from[live]
        t, _, _, _ = g.cast(o, d[:live.size], t_min=eps)
        ok = np.isfinite(t)
        live, t = live[ok], t[ok]
        t_from[live] += t
        hits.append(np.stack([live, start + t_from[live]], axis=1))
        t_from[live] += eps
    inside = np.zeros((len(xs), n), bool)
    if hits:
        h = np.concatenate(hits)
        h = h[np.lexsort((h[:, 1], h[:, 0]))]
        rows = h[:, 0].astype(np.int64)
        # crossings before each x: parity via cumulative counts per row
        cnt = np.zeros((len(xs) + 1, n), np.int64)
        pos = np.searchsorted(xs, h[:, 1])
        np.add.at(cnt, (pos, rows), 1)
        inside = (np.cumsum(cnt, axis=0)[:-1] % 2) == 1
    return inside.reshape(len(xs), len(ys), len(zs))


def _march(field: np.ndarray, axes) -> Tuple[np.ndarray, np.ndarray]:
    """Marching tetrahedra on ``field`` (nx, ny, nz), level 0; faces wound with their normals
    toward the positive side."""
    pos = field > 0
    nx, ny, nz = field.shape
    corner = [pos[(c & 1):nx - 1 + (c & 1), (c >> 1 & 1):ny - 1 + (c >> 1 & 1), (c >> 2 & 1):nz - 1 + (c >> 2 & 1)]
              for c in range(8)]
    anyp = np.any(corner, axis=0)
    allp = np.all(corner, axis=0)
    cells = np.flatnonzero(anyp & ~allp)
    if cells.size == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    ci, cj, ck = np.unravel_index(cells, (nx - 1, ny - 1, nz - 1))
    cid = np.stack([np.ravel_multi_index((ci + (c & 1), cj + (c >> 1 & 1), ck + (c >> 2 & 1)), field.shape)
                    for c in range(8)], axis=1)  # (C, 8) grid point ids
    tets = cid[:, _TETS].reshape(-1, 4)
    flat = field.ravel()
    s = flat[tets] > 0
    npos = s.sum(axis=1)
    tets, s, npos = tets[(npos > 0) & (npos < 4)], s[(npos > 0) & (npos < 4)], npos[(npos > 0) & (npos < 4)]
    tris = [_single(tets[npos == 1], s[npos == 1], True), _single(tets[npos == 3], s[npos == 3], False),
            *_double(tets[npos == 2], s[npos == 2])]
    edges = np.concatenate([t for t in tris if len(t)])  # (T, 3, 2) grid point pairs
    a, b = np.minimum(edges[..., 0], edges[..., 1]), np.maximum(edges[..., 0], edges[..., 1])
    key = a * flat.size + b
    uk, inv = np.unique(key.ravel(), return_inverse=True)
    pa, pb = uk // flat.size, uk % flat.size
    xa, xb = _points(axes, pa, field.shape), _points(axes, pb, field.shape)
    fa, fb = flat[pa], flat[pb]
    verts = xa + (fa / (fa - fb))[:, None] * (xb - xa)
    faces = inv.reshape(-1, 3).astype(np.int64)
    # wind each triangle so its normal points toward the positive corners of its edges
    nrm = np.cross(verts[faces[:, 1]] - verts[faces[:, 0]], verts[faces[:, 2]] - verts[faces[:, 0]])
    e = edges.reshape(-1, 3, 2)
    pos_pt = np.where(flat[e[..., 0]] > 0, e[..., 0], e[..., 1])
    neg_pt = np.where(flat[e[..., 0]] > 0, e[..., 1], e[..., 0])
    towards = (_points(axes, pos_pt.ravel(), field.shape) - _points(axes, neg_pt.ravel(), field.shape))
    towards = towards.reshape(-1, 3, 3).sum(axis=1)
    flip = np.einsum("ij,ij->i", nrm, towards) < 0
    faces[flip] = faces[flip][:, ::-1]
    return verts, faces


def _single(t: np.ndarray, s: np.ndarray, lone_positive: bool) -> np.ndarray:
    """One triangle per tetrahedron with one corner alone on its side: (T, 3, 2) edges."""
    if len(t) == 0:
        return np.zeros((0, 3, 2), np.int64)
    lone = np.argmax(s if lone_positive else ~s, axis=1)
    others = np.array([[j for j in range(4) if j != k] for k in range(4)])[lone]
    r = np.arange(len(t))[:, None]
    a = t[np.arange(len(t)), lone][:, None]
    return np.stack([np.broadcast_to(a, (len(t), 3)), t[r, others]], axis=2)


def _double(t: np.ndarray, s: np.ndarray):
    """Two triangles per tetrahedron split two and two: the quad of edges (a,c), (a,d), (b,d),
    (b,c) with a, b positive."""
    if len(t) == 0:
        return [np.zeros((0, 3, 2), np.int64)]
    order = np.argsort(~s, axis=1, kind="stable")  # positives first
    q = np.take_along_axis(t, order, axis=1)
    a, b, c, d = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    e_ac, e_ad, e_bd, e_bc = (np.stack(p, 1) for p in ((a, c), (a, d), (b, d), (b, c)))
    return [np.stack([e_ac, e_ad, e_bd], 1), np.stack([e_ac, e_bd, e_bc], 1)]
