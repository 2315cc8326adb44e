"""Planar polygons: area, the even-odd point test, nesting of closed loops (outer boundaries and
holes) and triangulation of a polygon with holes.

* :func:`nest` — which loops are holes (inside an odd number of the others) and the loop each
  lies directly in, the even-odd rule of scanline filling;
* :func:`triangulate` — ear clipping (Meisters 1975, "Polygons have ears"; Eberly 2002,
  "Triangulation by ear clipping") of an outer boundary with its holes bridged in (each hole's
  rightmost point joined to the closest point of the polygon so far that it sees).

Coordinates are (n, 2) float64 (mm in the polygon's plane); results index the points given.
Used to cap contours (:mod:`anatomesh.core.extract.contours`) and cut faces
(:mod:`anatomesh.core.printing.cut`).
"""
from __future__ import annotations

from typing import List, Sequence, Tuple

import numpy as np

from . import _polygon_kernels as K


def signed_area(uv: np.ndarray) -> float:
    """Signed area (mm²) of the closed polygon ``uv`` (n, 2): > 0 when counter-clockwise."""
    x, y = uv[:, 0], uv[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def points_in_polygon(points: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Even-odd test (PNPOLY) of ``points`` (k, 2) against the closed polygon ``uv`` (n, 2):
    (k,) bool."""
    p = np.asarray(points, np.float64)
    return K.points_in_polygon(np.ascontiguousarray(p[:, 0]), np.ascontiguousarray(p[:, 1]),
                               np.ascontiguousarray(uv[:, 0], np.float64),
                               np.ascontiguousarray(uv[:, 1], np.float64))


def nest(loops: Sequence[np.ndarray]) -> Tuple[List[bool], List[int]]:
    """For closed, mutually non-crossing loops (each (n, 2)): whether each is a hole (inside an
    odd number of the others) and its parent (the smallest loop around it, or -1)."""
    areas = [abs(signed_area(lp)) for lp in loops]
    holes, parents = [], []
    for k, lp in enumerate(loops):
        around = [o for o, other in enumerate(loops) if o != k and areas[o] > areas[k]
                  and bool(points_in_polygon(lp[:1], other)[0])]
        holes.append(len(around) % 2 == 1)
        parents.append(min(around, key=lambda o: areas[o]) if around else -1)
    return holes, parents


def triangulate(outer: np.ndarray, holes: Sequence[np.ndarray] = (), min_height: float = 0.0) -> np.ndarray:
    """Triangles (t, 3) int64 covering the polygon ``outer`` (n, 2) minus ``holes`` (each
    (m, 2), inside it, not crossing), wound as ``outer`` runs (counter-clockwise triangles for a
    counter-clockwise outer boundary). Indices run over the points of ``outer`` then of each hole
    in turn (``np.concatenate([outer, *holes])``). Ears less than ``min_height`` (mm) high over
    their base are clipped only when no other is left."""
    uv = np.asarray(outer, np.float64)
    ids = np.arange(len(uv))
    clockwise = signed_area(uv) < 0
    if clockwise:
        uv, ids = uv[::-1], ids[::-1]
    first = len(uv)
    pieces = []
    for h in holes:
        h = np.asarray(h, np.float64)
        hid = first + np.arange(len(h))
        first += len(h)
        pieces.append((h[::-1], hid[::-1]) if signed_area(h) > 0 else (h, hid))
    for huv, hid in sorted(pieces, key=lambda p: -p[0][:, 0].max()):
        m = int(np.argmax(huv[:, 0]))
        order = np.argsort(np.linalg.norm(uv - huv[m], axis=1))
        k = int(order[0])
        for cand in order[:64]:
            if not K.segment_hits_polygon(huv[m, 0], huv[m, 1], uv[cand, 0], uv[cand, 1],
                                          np.ascontiguousarray(uv[:, 0]), np.ascontiguousarray(uv[:, 1])):
                k = int(cand)
                break
        hid, huv = np.roll(hid, -m), np.roll(huv, -m, axis=0)
        ids = np.concatenate([ids[:k + 1], hid, hid[:1], ids[k:]])
        uv = np.concatenate([uv[:k + 1], huv, huv[:1], uv[k:]])
    local = K.ear_clip(np.ascontiguousarray(uv[:, 0]), np.ascontiguousarray(uv[:, 1]), float(min_height))
    tris = ids[local]
    return tris[:, ::-1].copy() if clockwise else tris


def delaunay_flips(points: np.ndarray, tris: np.ndarray, min_height: float = 0.0, passes: int = 100) -> np.ndarray:
    """``tris`` (K, 3) of a planar triangulation of ``points`` (N, 2) (counter-clockwise) flipped
    to the constrained Delaunay triangulation of its boundary (Lawson 1977, "Software for C1
    surface interpolation"): every edge shared by two triangles whose opposite corner lies inside
    the other's circumcircle, or one of which is lower than ``min_height`` over its longest edge,
    is flipped where the two make a convex quad. Boundary edges stay."""
    tris = np.array(tris, np.int64)
    n = np.int64(max(len(points), 1))
    for _ in range(passes):
        he = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
        owner = np.tile(np.arange(len(tris)), 3)
        key, rev = he[:, 0] * n + he[:, 1], he[:, 1] * n + he[:, 0]
        order = np.argsort(key)
        pos = np.clip(np.searchsorted(key[order], rev), 0, len(key) - 1)
        twin = np.where(key[order][pos] == rev, order[pos], -1)
        e = np.flatnonzero((twin >= 0) & (he[:, 0] < he[:, 1]))
        t1, t2 = owner[e], owner[twin[e]]
        a, b = he[e, 0], he[e, 1]
        k = tris[t1].sum(axis=1) - a - b
        x = tris[t2].sum(axis=1) - a - b
        want = _in_circle(points, a, b, k, x) | _flat(points, tris[t1], min_height) | _flat(points, tris[t2], min_height)
        want &= (_orient(points, a, x, k) > 0) & (_orient(points, x, b, k) > 0)
        touched = np.zeros(len(tris), bool)
        flipped = 0
        for m in np.flatnonzero(want):
            if touched[t1[m]] or touched[t2[m]]:
                continue
            tris[t1[m]] = (a[m], x[m], k[m])
            tris[t2[m]] = (x[m], b[m], k[m])
            touched[t1[m]] = touched[t2[m]] = True
            flipped += 1
        if not flipped:
            break
    return tris


def _orient(p, a, b, c) -> np.ndarray:
    return (p[b, 0] - p[a, 0]) * (p[c, 1] - p[a, 1]) - (p[b, 1] - p[a, 1]) * (p[c, 0] - p[a, 0])


def _in_circle(p, a, b, c, d) -> np.ndarray:
    """(K,) bool: ``d`` strictly inside the circumcircle of the counter-clockwise (a, b, c)."""
    rows = []
    for q in (a, b, c):
        dx, dy = p[q, 0] - p[d, 0], p[q, 1] - p[d, 1]
        rows.append((dx, dy, dx * dx + dy * dy))
    (ax, ay, aw), (bx, by, bw), (cx, cy, cw) = rows
    det = ax * (by * cw - bw * cy) - ay * (bx * cw - bw * cx) + aw * (bx * cy - by * cx)
    scale = (np.abs(aw) + np.abs(bw) + np.abs(cw)) ** 2
    return det > 1e-12 * scale


def _flat(p, tri, min_height: float) -> np.ndarray:
    """(K,) bool: triangles lower than ``min_height`` over their longest edge."""
    q = p[tri]
    d = np.roll(q, -1, axis=1) - q
    longest = np.linalg.norm(d, axis=2).max(axis=1)
    return _orient(p, tri[:, 0], tri[:, 1], tri[:, 2]) <= min_height * longest
