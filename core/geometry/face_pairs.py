"""Which faces can cross while every vertex stays in a box around its start: candidate pairs built
once, then tested as often as the vertices move.

Constrained smoothing keeps each vertex inside a box (its voxel cell, Gibson 1998, "Constrained
elastic surface nets"), so face ``f`` stays inside the *extent* of its corners' boxes (their
bounding box). Two faces can only cross if their extents overlap. :class:`FaceBoxes` buckets the
faces once by the cell of their extent's low corner; testing then visits only those pairs, with
Möller 1997 ("A fast triangle-triangle intersection test") — the decisions of
:func:`~anatomesh.core.geometry.intersections.self_intersections` bit for bit (faces sharing a
vertex, or a corner at the same position, are not tested), with no grid and no weld per call.

Extents are compared with strict inequalities: faces whose extents only touch are left out, which
is exact when the boxes the vertices move in are a hair smaller than the ones given here (a
margin of a fraction of a voxel keeps the two sides of a shared cell face apart).

Example
-------
>>> boxes = FaceBoxes(faces, lattice - 0.5, (0.5, 0.5, 0.5))  # index space, voxel cells
>>> boxes.crossings(smoothed_vertices)                          # (K, 2) face indices
>>> boxes.materialize()                                         # list the pairs: faster tests
"""
from __future__ import annotations

from typing import NamedTuple, Optional, Sequence, Tuple

import numpy as np

from . import _face_pair_kernels as _k
from ..model.errors import AnatomeshError
from .neighbors import check_faces


class Buckets(NamedTuple):
    """Faces in bucket order (by column (x, y) of their home cell, then z): the arrays of the
    kernels, rows in bucket order."""
    start: np.ndarray   #: (Dx * Dy + 1,) int64: rows of each column
    z: np.ndarray       #: (M,) int32: home z of each row
    lo: np.ndarray      #: (M, 3) float32: extent, low corner (rounded down); (0, 3): not kept
    hi: np.ndarray      #: (M, 3) float32: extent, high corner (rounded up); (0, 3): not kept
    reach: np.ndarray   #: (M, 3) int16: how far up a partner's home can be
    faces: np.ndarray   #: (M, 3) int32: the faces, in face order (a row's: ``faces[fid[row]]``)
    fid: np.ndarray     #: (M,) int32: face index of each row
    dims: np.ndarray    #: (3,) int64: home cells per axis
    back: np.ndarray    #: (3,) int64: how far down a partner's home can be


class FaceBoxes:
    """The faces of a mesh whose vertices each stay inside a box around their start, bucketed once
    by the extent of their corners' boxes.

    Parameters
    ----------
    faces : (M, 3) int
    centres : (N, 3) float
        Centre of each vertex's box, in the box frame (voxel index space for voxel cells:
        ``lattice − 0.5`` for a label map's set, ``inv(affine) @ start`` otherwise).
    half : (3,) float
        Half extents of the boxes along the frame axes (0.5 = the voxel).
    listing : bool
        Keep the faces' extents, which :meth:`materialize` needs to list the pairs; False
        (one-shot runs, memory: 24 bytes a face): only :meth:`crossings` by the sweep.

    :meth:`crossings` tests the faces that can cross — every pair whose extents overlap with
    positive volume, sharing no vertex — at given positions: by a sweep over the buckets, or
    over the pairs listed once by :meth:`materialize` (faster when testing many times).
    """

    def __init__(self, faces: np.ndarray, centres: np.ndarray, half: Sequence[float],
                 listing: bool = True):
        c = np.asarray(centres, np.float64)
        if c.ndim != 2 or c.shape[1] != 3 or not np.all(np.isfinite(c)):
            raise AnatomeshError(f"box centres must be finite (N, 3) positions, got shape {c.shape}")
        f = check_faces(faces, len(c))
        h = np.broadcast_to(np.asarray(half, np.float64), (3,))
        if not np.all(h > 0):
            raise AnatomeshError(f"box half extents must be positive, got {half}")
        # columns along the two axes the faces' order varies slowest in, rows sorted along the
        # fastest: bucket order then follows the face order (cheap to sort and to gather)
        axes = np.argsort(np.abs(np.diff(c[f[::max(1, len(f) // 4096), 0]], axis=0)).mean(axis=0)) \
            if len(f) > 1 else np.arange(3)
        c, h = np.ascontiguousarray(c[:, axes]), np.ascontiguousarray(h[axes])
        home, back, dims = _k.homes(c, f, h)
        if back.max(initial=0) > np.iinfo(np.int16).max:
            raise AnatomeshError(f"faces span up to {back.max()} boxes; at most "
                                 f"{np.iinfo(np.int16).max} are supported: use larger boxes")
        start, order, z = _k.bucket_faces(home, dims)
        del home  # memory: the rows are built in bucket order straight from the centres
        rows = _k.bucket_rows(order, c, f, h, bool(listing))
        self.faces, self.listing = f, bool(listing)
        self.buckets = Buckets(start, z, *rows, f, order, dims, back)
        self._box = np.empty((len(f), 6), np.uint16)  # memory: 12 bytes a face (face_boxes)
        self._frame = (np.zeros(3), np.zeros(3))  # the boxes' steps: origin (mm), steps per mm
        self._pairs: Optional[Tuple[np.ndarray, np.ndarray]] = None
        self._hit = np.zeros(0, np.uint8)
        self._boxed = None  # face boxes computed (for vertices of this shape)

    def materialize(self) -> "FaceBoxes":
        """List the candidate pairs once (CSR over bucket rows); returns self."""
        if not self.listing:
            raise AnatomeshError("these face boxes were built without their extents "
                                 "(listing=False): build them with listing=True to list pairs")
        if self._pairs is None:
            self._pairs = _k.sweep_csr(self.buckets, np.zeros((0, 3)), self._box, 0.0)
            self._hit = np.zeros(self._pairs[1].shape[0], np.uint8)
        return self

    @property
    def n_pairs(self) -> int:
        """Number of candidate pairs (listing them if not done yet)."""
        return int(self.materialize()._pairs[1].shape[0])

    def as_array(self) -> np.ndarray:
        """All candidate pairs (P, 2) int64 of face indices, smaller first, sorted."""
        offsets, partners = self.materialize()._pairs
        fid = self.buckets.fid
        a = fid[_csr_rows(offsets)]
        return _sorted_pairs(a, fid[partners])

    def crossings(self, vertices: np.ndarray, active: Optional[np.ndarray] = None,
                  rel_eps: float = 1e-9) -> np.ndarray:
        """The candidate pairs whose faces cross at these positions, (K, 2) int64, smaller face
        first, sorted. ``active`` (M,) bool, optional: only pairs with an active face — the
        faces around the vertices moved since the previous call on these positions (the boxes
        of the other faces are kept from it). Same decisions as
        :func:`~anatomesh.core.geometry.intersections.self_intersections` (faces with a corner
        at the same position do not count; touching counts)."""
        v = np.asarray(vertices)  # memory: float32 positions are tested as they are, no copy
        X = np.ascontiguousarray(v, np.float32 if v.dtype == np.float32 else np.float64)
        f, B = self.faces, self.buckets
        if X.ndim != 2 or X.shape[1] != 3 or (f.size and int(f.max()) >= X.shape[0]):
            raise AnatomeshError(f"vertices {X.shape} do not match the faces the boxes were built for")
        if f.shape[0] == 0:
            return np.zeros((0, 2), np.int64)
        if active is not None:
            act = np.ascontiguousarray(active, np.bool_)
            if act.shape != (f.shape[0],):
                raise AnatomeshError(f"active must hold one flag per face ({f.shape[0]}), "
                                     f"got {act.shape}")
            act = act[B.fid]
            rows = np.flatnonzero(act)
            if self._boxed == X.shape:  # the other faces did not move: their boxes hold
                _k.face_boxes_of(X, B.faces, B.fid, rows, *self._frame, self._box)
            else:
                self._face_boxes(X)
            pairs = _k.active_crossings(rows, B, X, self._box, rel_eps, act)
            return _sorted_pairs(B.fid[pairs[:, 0]], B.fid[pairs[:, 1]])
        self._face_boxes(X)
        if self._pairs is None:
            offsets, partners = _k.sweep_csr(B, X, self._box, float(rel_eps))
            rows = _csr_rows(offsets)
            return _sorted_pairs(B.fid[rows], B.fid[partners])
        offsets, partners = self._pairs
        _k.test_pairs(X, B, offsets, partners, float(rel_eps), self._box, self._hit)
        t = np.flatnonzero(self._hit.view(np.bool_))  # speed: 0/1 bytes; numpy scans bools fast
        rows = np.searchsorted(offsets, t, side="right") - 1
        return _sorted_pairs(B.fid[rows], B.fid[partners[t]])

    def _face_boxes(self, X: np.ndarray) -> None:
        """The boxes of every face at positions ``X``, in 16-bit steps of a frame spanning
        them (~0.005 mm on a 300 mm scan): they tell faces surely apart, the pairs left are
        checked with exact boxes before Möller's test. Later calls with ``active`` update the
        moved faces in the same frame."""
        _k.face_boxes(X, self.buckets.faces, self.buckets.fid, *self._frame, self._box)
        self._boxed = X.shape


def _csr_rows(offsets: np.ndarray) -> np.ndarray:
    """The row of every entry of a CSR with these (M + 1,) offsets, (offsets[-1],) int64; only
    the rows with entries are listed (memory: a crossing sweep has a few among millions)."""
    nz = np.flatnonzero(offsets[1:] != offsets[:-1])
    return np.repeat(nz, offsets[nz + 1] - offsets[nz])


def _sorted_pairs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1).astype(np.int64)
    return out[np.lexsort((out[:, 1], out[:, 0]))]


def candidate_pairs(faces: np.ndarray, centres: np.ndarray, half: Sequence[float]) -> FaceBoxes:
    """:class:`FaceBoxes` of these faces with the candidate pairs listed (:meth:`~FaceBoxes.
    materialize`): every pair of faces that can cross while each vertex stays strictly inside a
    box somewhat smaller than ``half``."""
    return FaceBoxes(faces, centres, half).materialize()


def crossing_pairs_among(vertices: np.ndarray, boxes: FaceBoxes,
                         active: Optional[np.ndarray] = None, rel_eps: float = 1e-9) -> np.ndarray:
    """``boxes.crossings(vertices, active, rel_eps)``: the candidate pairs that cross, (K, 2)."""
    return boxes.crossings(vertices, active, rel_eps)
