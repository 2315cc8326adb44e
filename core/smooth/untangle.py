"""Undo smoothing where it made faces cross: no part may run into itself or into its neighbour.

Smoothing moves every vertex a little; where two sheets are a voxel apart (two organs separated by
one background voxel, or the two sides of a one-voxel-thick part), their moves can make faces cross,
although the unsmoothed surface-nets / marching-cubes surface has no crossing. A printer reads such a
model as broken and a renderer shows z-fighting. :func:`untangle` finds the crossing faces (Möller
1997, "A fast triangle-triangle intersection test") and pulls their vertices — with their 1-ring, so
the fix blends in — back toward the unsmoothed positions, halving the smoothing displacement each
round, until nothing crosses. On a conforming multi-label set all labels share one vertex array, so
one call fixes crossings inside a shell and between shells and seams stay shared; positions are
convex combinations of the smoothed and unsmoothed ones, so every box / ``max_deviation``
constraint the smoothing held still holds.

With every vertex kept in a box around its start (its voxel cell), only faces whose boxes' extents
overlap can cross: given the faces bucketed by those extents
(:class:`~anatomesh.core.geometry.face_pairs.FaceBoxes`, built once per surface), each round
tests only those pairs, and after the first round only the pairs with a face that moved. Without them,
every round searches all faces
(:func:`~anatomesh.core.geometry.intersections.self_intersections`).
"""
from __future__ import annotations

from typing import Dict, Optional, Tuple

import numpy as np

from ..geometry.face_pairs import FaceBoxes
from ..geometry.intersections import self_intersections
from ..geometry.neighbors import MeshStructure, structure as _structure
from ..model.errors import AnatomeshError


def untangle(vertices: np.ndarray, rest: np.ndarray, faces: np.ndarray, *, rounds: int = 8,
             shrink: float = 0.5, pairs: Optional[FaceBoxes] = None,
             structure: Optional[MeshStructure] = None,
             active: Optional[np.ndarray] = None, in_place: bool = False) -> Tuple[np.ndarray, Dict]:
    """Move the vertices of crossing faces back toward ``rest`` until no faces cross.

    ``vertices`` (N, 3) float, mm: the smoothed positions; ``rest`` (N, 3): the unsmoothed ones
    (expected free of crossings); ``faces`` (M, 3) int. Each round the displacement of the
    vertices of crossing faces and their 1-ring is multiplied by ``shrink``; after ``rounds``
    rounds the vertices still involved go back to ``rest`` exactly. ``pairs``: the faces'
    :class:`~anatomesh.core.geometry.face_pairs.FaceBoxes` when every vertex stays in its box
    (only the pairs that can cross are tested); None: search all faces. ``structure``:
    the faces' neighbourhoods, if built. ``active`` (M,) bool: only pairs with one of these
    faces are checked at the start (the faces around vertices moved since an untangled state;
    None: all). ``in_place``: move ``vertices`` themselves (a float array the caller gives up:
    no copy, memory). Returns ``(vertices, info)`` with ``info =
    {"crossing_pairs": found at the start, "moved_vertices": how many were pulled back,
    "rounds": rounds used, "crossings_left": pairs left (0 unless ``rest`` itself crosses)}``.
    """
    v = vertices if in_place and _writable_float(vertices) else np.array(vertices, copy=True)
    r = np.asarray(rest, dtype=v.dtype)
    f = np.asarray(faces)
    if r.shape != v.shape:
        raise AnatomeshError(f"untangle: rest positions {r.shape} do not match the vertices {v.shape}")
    info = {"crossing_pairs": 0, "moved_vertices": 0, "rounds": 0, "crossings_left": 0}
    if len(f) == 0:
        return v, info
    s = structure if structure is not None else _structure(f, len(v))

    def crossings(active=None):
        if pairs is not None:
            return pairs.crossings(v, active)
        return self_intersections(v, f, active=active)

    moved = np.zeros(len(v), bool)
    found = crossings(active)
    info["crossing_pairs"] = int(len(found))
    for k in range(rounds + 1):
        if len(found) == 0:
            break
        ring = one_ring_of(s, np.unique(f[found.ravel()]))
        moved[ring] = True
        t = 0.0 if k == rounds else shrink
        v[ring] = r[ring] + t * (v[ring] - r[ring])
        info["rounds"] = k + 1
        # every crossing face was moved: a pair can cross now only if one of its faces moved
        found = crossings(faces_around(s, ring))
    info["moved_vertices"] = int(moved.sum())
    info["crossings_left"] = int(len(found))
    return v, info


def _writable_float(a) -> bool:
    return isinstance(a, np.ndarray) and a.dtype in (np.float32, np.float64) and a.flags.writeable


def rows_of(offsets: np.ndarray, values: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The entries of CSR rows ``rows`` (concatenated)."""
    rows = np.asarray(rows, np.int64)
    counts = offsets[rows + 1] - offsets[rows]
    first = np.repeat(offsets[rows] - np.cumsum(counts) + counts, counts)
    return values[first + np.arange(counts.sum())]


def faces_around(s: MeshStructure, vertices: np.ndarray) -> np.ndarray:
    """(M,) bool: the faces with a corner among ``vertices`` (indices)."""
    active = np.zeros(s.n_faces, bool)
    active[rows_of(s.vf_offsets, s.vf, vertices)] = True
    return active


def one_ring_of(s: MeshStructure, seeds: np.ndarray) -> np.ndarray:
    """``seeds`` and every vertex sharing an edge with one of them (the corners of their
    faces: no 1-ring needed), sorted, unique."""
    return np.unique(np.concatenate([seeds, s.faces[rows_of(s.vf_offsets, s.vf, seeds)].ravel()]))
