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


def triangulate(outer: np.ndarray, holes: Sequence[np.ndarray] = ()) -> np.ndarray:
    """Triangles (t, 3) int64 covering the polygon ``outer`` (n, 2) minus ``holes`` (each
    (m, 2), inside it, not crossing), wound as ``outer`` runs (counter-clockwise triangles for a
    counter-clockwise outer boundary). Indices run over the points of ``outer`` then of each hole
    in turn (``np.concatenate([outer, *holes])``)."""
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
    local = K.ear_clip(np.ascontiguousarray(uv[:, 0]), np.ascontiguousarray(uv[:, 1]))
    tris = ids[local]
    return tris[:, ::-1].copy() if clockwise else tris
