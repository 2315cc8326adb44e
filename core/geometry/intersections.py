"""Crossing triangles: which faces of one or several surfaces intersect each other.

Möller 1997, "A fast triangle-triangle intersection test", over a uniform grid
(:class:`~anatomesh.core.geometry.spatial.TriangleGrid`). Faces that share a vertex are not
tested against each other; vertices at identical positions count as shared ("welded"), so parts
that touch along a seam (each with its own copy of the seam vertices) do not count as crossing.
"""
from __future__ import annotations

from typing import NamedTuple, Optional, Sequence, Tuple

import numpy as np

from ..model.errors import AnatomeshError
from ..model.mesh import check_arrays, weld_ids
from . import _intersect_kernels as _k
from .spatial import TriangleGrid


class Crossings(NamedTuple):
    """Result of :func:`crossing_pairs` over several parts stacked in order.

    ``vertices`` (N, 3) float64 and ``faces`` (M, 3) int64 of all parts together (None when there
    are no faces), ``part`` (M,) the part of each face, ``face_offsets`` (P + 1,) where each part's
    faces start, ``pairs`` (K, 2) int64 crossing faces (global indices, smaller first)."""

    vertices: Optional[np.ndarray]
    faces: Optional[np.ndarray]
    part: np.ndarray
    face_offsets: np.ndarray
    pairs: np.ndarray


def crossing_pairs(parts: Sequence[Tuple[np.ndarray, np.ndarray]], rel_eps: float = 1e-9,
                   active: Optional[np.ndarray] = None) -> Crossings:
    """Crossing face pairs of all ``parts`` ((vertices mm, faces) each) together.

    ``active`` (M,) bool over all parts' faces in order, optional: test only pairs with an active
    face (after moving a few vertices, the faces touching them: no other pair can have changed).
    ``rel_eps`` is the coplanarity tolerance relative to the triangles' size."""
    offs_v = np.cumsum([0] + [len(v) for v, _ in parts])
    offs_f = np.cumsum([0] + [len(f) for _, f in parts])
    if offs_f[-1] == 0:
        return Crossings(None, None, np.zeros(0, np.int64), offs_f, np.zeros((0, 2), np.int64))
    v = np.concatenate([p[0] for p in parts]).astype(np.float64)
    f = np.concatenate([p[1].astype(np.int64) + o for p, o in zip(parts, offs_v[:-1])])
    part = np.repeat(np.arange(len(parts)), np.diff(offs_f))
    wf = np.ascontiguousarray(weld_ids(v)[f])
    g = TriangleGrid(v, np.ascontiguousarray(f, np.int32))
    act = np.zeros(0, np.bool_) if active is None else np.ascontiguousarray(active, np.bool_)
    if act.size and act.shape != (len(f),):
        raise AnatomeshError(f"active must hold one flag per face ({len(f)}), got {act.shape}")
    pairs = _k.intersecting_pairs(g.vertices, g.faces, wf, g.origin, g.cell_size, g.dims, g.start,
                                  g.items, rel_eps, act)
    return Crossings(v, f, part, offs_f, pairs)


def self_intersections(vertices: np.ndarray, faces: np.ndarray,
                       active: Optional[np.ndarray] = None) -> np.ndarray:
    """Pairs of faces (K, 2) int64 of one surface that cross each other, among faces sharing no
    vertex (vertices at identical positions count as shared). ``active``: as in
    :func:`crossing_pairs`."""
    v, f = check_arrays(vertices, faces)
    return crossing_pairs([(v, f)], active=active).pairs
