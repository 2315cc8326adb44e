"""Which faces can cross while every vertex stays in a box around its start: candidate pairs built
once, then tested as often as the vertices move.

Constrained smoothing keeps each vertex inside a box (its voxel cell, Gibson 1998, "Constrained
elastic surface nets"), so face ``f`` stays inside the *extent* of its corners' boxes (their
bounding box). Two faces can only cross if their extents overlap. :func:`candidate_pairs` finds
those pairs once (faces bucketed by the cell of their extent's low corner); afterwards
:func:`crossing_pairs_among` tests only them with Möller 1997 ("A fast triangle-triangle
intersection test") — the decisions of
:func:`~anatomesh.core.geometry.intersections.self_intersections` bit for bit (faces sharing a
vertex, or a corner at the same position, are not tested), with no grid and no weld per call.

Extents are compared with strict inequalities: faces whose extents only touch are left out, which
is exact when the boxes the vertices move in are a hair smaller than the ones given here (a
margin of a fraction of a voxel keeps the two sides of a shared cell face apart).

Example
-------
>>> pairs = candidate_pairs(faces, (lattice - 0.5), (0.5, 0.5, 0.5))  # index space, voxel cells
>>> crossing = crossing_pairs_among(smoothed_vertices, pairs)        # (K, 2) face indices
"""
from __future__ import annotations

from typing import Optional, Sequence, Tuple

import numpy as np

from . import _face_pair_kernels as _k
from ..model.errors import AnatomeshError
from .neighbors import check_faces


class FacePairs:
    """Candidate face pairs as CSR: the partners of face ``a`` are
    ``partners[offsets[a]:offsets[a + 1]]`` (each unordered pair listed once).

    Attributes
    ----------
    faces : (M, 3) int32
    offsets : (M + 1,) int64
    partners : (P,) int32
    """

    def __init__(self, faces: np.ndarray, offsets: np.ndarray, partners: np.ndarray):
        self.faces = faces
        self.offsets = offsets
        self.partners = partners
        self._hit = np.zeros(partners.shape[0], np.uint8)  # reused by every test
        self._box = np.zeros((faces.shape[0], 6))

    @property
    def n_pairs(self) -> int:
        return int(self.partners.shape[0])

    def as_array(self) -> np.ndarray:
        """All pairs (P, 2) int64, smaller face first."""
        rows = np.repeat(np.arange(self.faces.shape[0], dtype=np.int64), np.diff(self.offsets))
        b = self.partners.astype(np.int64)
        return np.stack([np.minimum(rows, b), np.maximum(rows, b)], axis=1)


def face_extents(faces: np.ndarray, centres: np.ndarray,
                 half: Sequence[float]) -> Tuple[np.ndarray, np.ndarray]:
    """``(lo, hi)`` (M, 3) float64: the bounding box of each face's corner boxes
    ``[centre − half, centre + half]`` (in the frame of ``centres``, e.g. voxel index)."""
    c = np.ascontiguousarray(centres, np.float64)
    if c.ndim != 2 or c.shape[1] != 3 or not np.all(np.isfinite(c)):
        raise AnatomeshError(f"box centres must be finite (N, 3) positions, got shape {c.shape}")
    h = np.ascontiguousarray(np.broadcast_to(np.asarray(half, np.float64), (3,)))
    if not np.all(h > 0):
        raise AnatomeshError(f"box half extents must be positive, got {half}")
    return _k.extents(c, check_faces(faces, c.shape[0]), h)


def candidate_pairs(faces: np.ndarray, centres: np.ndarray, half: Sequence[float]) -> FacePairs:
    """The pairs of faces that share no vertex and whose extents overlap with positive volume.

    Parameters
    ----------
    faces : (M, 3) int
    centres : (N, 3) float
        Centre of each vertex's box, in the box frame (voxel index space for voxel cells:
        ``lattice − 0.5`` for a label map's set, ``inv(affine) @ start`` otherwise).
    half : (3,) float
        Half extents of the boxes along the frame axes (0.5 = the voxel).

    Returns a :class:`FacePairs`: every pair of faces that can cross while each vertex stays
    strictly inside a box somewhat smaller than this one.
    """
    lo, hi = face_extents(faces, centres, half)
    f = check_faces(faces, len(centres))
    if f.shape[0] == 0:
        return FacePairs(f, np.zeros(1, np.int64), np.zeros(0, np.int32))
    home, reach = _k.homes(lo, hi)
    back = reach.max(axis=0)
    dims = home.max(axis=0) + 1
    start, order, z = _k.bucket_faces(home, dims)
    offsets, partners = _k.candidate_csr(*_k.permuted(order, lo, hi, reach, f), back, dims,
                                         order, start, z)
    return FacePairs(f, offsets, partners)


def crossing_pairs_among(vertices: np.ndarray, pairs: FacePairs,
                         active: Optional[np.ndarray] = None, rel_eps: float = 1e-9) -> np.ndarray:
    """The candidate pairs whose faces cross at these vertex positions, (K, 2) int64.

    ``vertices`` (N, 3) float, mm; ``active`` (M,) bool, optional: test only pairs with an
    active face (after moving a few vertices, the faces touching them). Same decisions as
    :func:`~anatomesh.core.geometry.intersections.self_intersections` on these pairs (faces with
    a corner at the same position do not count; touching counts)."""
    X = np.ascontiguousarray(vertices, np.float64)
    f = pairs.faces
    if X.ndim != 2 or X.shape[1] != 3 or (f.size and int(f.max()) >= X.shape[0]):
        raise AnatomeshError(f"vertices {X.shape} do not match the faces the pairs were built for")
    act = np.zeros(0, np.bool_) if active is None else np.ascontiguousarray(active, np.bool_)
    if act.size and act.shape != (f.shape[0],):
        raise AnatomeshError(f"active must hold one flag per face ({f.shape[0]}), got {act.shape}")
    if pairs.n_pairs == 0:
        return np.zeros((0, 2), np.int64)
    _k.face_boxes(X, f, pairs._box)
    _k.test_pairs(X, f, pairs.offsets, pairs.partners, act, float(rel_eps), pairs._box, pairs._hit)
    t = np.flatnonzero(pairs._hit)
    a = np.searchsorted(pairs.offsets, t, side="right") - 1
    b = pairs.partners[t].astype(np.int64)
    out = np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1)
    return out[np.lexsort((out[:, 1], out[:, 0]))]
