"""Undo smoothing where it made faces cross: no part may run into itself or into its neighbour.

Smoothing moves every vertex a little; where two sheets are a voxel apart (two organs separated by
one background voxel, or the two sides of a one-voxel-thick part), their moves can make faces cross,
although the unsmoothed surface-nets / marching-cubes surface has no crossing. A printer reads such a
model as broken and a renderer shows z-fighting. :func:`untangle` finds the crossing faces (Möller
1997 triangle–triangle tests over a grid, :func:`anatomesh.core.geometry.intersections.self_intersections`) and
pulls their vertices — with their 1-ring, so the fix blends in — back toward the unsmoothed positions,
halving the smoothing displacement each round, until nothing crosses. On a conforming multi-label
set all labels share one vertex array, so one call fixes crossings inside a shell and between shells
and seams stay shared; positions are convex combinations of the smoothed and unsmoothed ones, so
every box / ``max_deviation`` constraint the smoothing held still holds.
"""
from __future__ import annotations

from typing import Dict, Tuple

import numpy as np

from ..model.errors import AnatomeshError


def untangle(vertices: np.ndarray, rest: np.ndarray, faces: np.ndarray, *, rounds: int = 8,
             shrink: float = 0.5) -> Tuple[np.ndarray, Dict]:
    """Move the vertices of crossing faces back toward ``rest`` until no faces cross.

    ``vertices`` (N, 3) float, mm: the smoothed positions; ``rest`` (N, 3): the unsmoothed ones
    (expected free of crossings); ``faces`` (M, 3) int. Each round the displacement of the vertices
    of crossing faces and their 1-ring is multiplied by ``shrink``; after ``rounds`` rounds the
    vertices still involved go back to ``rest`` exactly. Returns ``(vertices, info)`` with
    ``info = {"crossing_pairs": found at the start, "moved_vertices": how many were pulled back,
    "rounds": rounds used, "crossings_left": pairs left (0 unless ``rest`` itself crosses)}``.
    """
    from ..geometry.intersections import self_intersections

    v = np.array(vertices, copy=True)
    r = np.asarray(rest, dtype=v.dtype)
    f = np.asarray(faces)
    if r.shape != v.shape:
        raise AnatomeshError(f"untangle: rest positions {r.shape} do not match the vertices {v.shape}")
    info = {"crossing_pairs": 0, "moved_vertices": 0, "rounds": 0, "crossings_left": 0}
    if len(f) == 0:
        return v, info
    moved = np.zeros(len(v), bool)
    pairs = self_intersections(v, f)
    info["crossing_pairs"] = int(len(pairs))
    for k in range(rounds + 1):
        if len(pairs) == 0:
            break
        ring = _ring(f, np.unique(f[pairs.ravel()]), len(v))
        moved |= ring
        t = 0.0 if k == rounds else shrink
        v[ring] = r[ring] + t * (v[ring] - r[ring])
        info["rounds"] = k + 1
        # every crossing face was moved: a pair can cross now only if one of its faces moved
        pairs = self_intersections(v, f, active=ring[f].any(axis=1))
    info["moved_vertices"] = int(moved.sum())
    info["crossings_left"] = int(len(pairs))
    return v, info


def _ring(faces: np.ndarray, seeds: np.ndarray, n: int) -> np.ndarray:
    """Mask (n,) of ``seeds`` and every vertex sharing a face with one of them."""
    mask = np.zeros(n, bool)
    mask[seeds] = True
    touching = mask[faces].any(axis=1)
    mask[faces[touching].ravel()] = True
    return mask
